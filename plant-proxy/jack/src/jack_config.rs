//! The `[jack]` table of a scenario: which JACK server and ports the plant side uses, how
//! a port's samples map to the contract's units, and how much of a period the plant side
//! may spend on the service's answers.
//!
//! ```toml
//! [jack]
//! server = "adaptive-rig"       # jackd -n NAME (default: $JACK_DEFAULT_SERVER, else "default")
//! client = "adaptive-rig-daq"   # the plant side's client name
//! budget = 0.5                  # share of a JACK period the process callback may wait for answers
//! period-frames = 32            # optional: refuse a server whose period differs
//! y = ["system:capture_1"]      # the port each measured output y_i is read from (n_y ports or none)
//! z = ["system:capture_2"]      # the port each performance variable z_i is read from (n_z or none)
//! u = ["system:playback_1", "system:playback_2"]   # the port each input u_i drives (n_u or none)
//! y-full-scale = [10.0]         # y_i at a JACK sample of 1.0 (Pa at the ADC's full scale)
//! z-full-scale = [10.0]
//! u-full-scale = [40.0, 40.0]   # u_i at a JACK sample of 1.0 (V at the DAC's full scale)
//!
//! [jack.room]                   # the simulated room (`plant-jack room`), for tests without a card
//! client = "room"
//! converter-delay = 0           # frames of delay the room adds to each loudspeaker (a card's converters)
//! ```
//!
//! A JACK audio sample is a 32-bit float, nominally within `[−1, 1]` (the converters' full
//! scale). The plant side publishes `y_i = y-full-scale_i · s` for a sample `s` of the port
//! of `y_i` (the same for `z`), and writes `u_i / u-full-scale_i` to the port of `u_i`,
//! clipped to `[−1, 1]` as a card's DAC clips; the clipped value is the input it reports as
//! applied. The room converts back with the same scales, so a loop through the room is the
//! scenario's plant in the scenario's units.

use serde::Deserialize;
use std::fmt;

/// The default name of the plant side's JACK client.
pub const DEFAULT_CLIENT: &str = "adaptive-rig-daq";
/// The default name of the room's JACK client.
pub const DEFAULT_ROOM_CLIENT: &str = "room";

/// The `[jack]` table (see the module documentation).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct JackConfig {
    /// The JACK server's name; `None`: `$JACK_DEFAULT_SERVER`, else `default`.
    #[serde(default)]
    pub server: Option<String>,
    /// The plant side's client name.
    #[serde(default = "default_client")]
    pub client: String,
    /// The share of a period the process callback may wait for the service's answers.
    #[serde(default = "default_budget")]
    pub budget: f64,
    /// The period, frames, the scenario was designed for; `None`: any.
    #[serde(default)]
    pub period_frames: Option<u32>,
    /// The ports the measured outputs are read from (empty: connect none).
    #[serde(default)]
    pub y: Vec<String>,
    /// The ports the performance variables are read from (empty: connect none).
    #[serde(default)]
    pub z: Vec<String>,
    /// The ports the inputs drive (empty: connect none).
    #[serde(default)]
    pub u: Vec<String>,
    /// `y_i` at a JACK sample of 1.0 (empty: 1.0 each).
    #[serde(default)]
    pub y_full_scale: Vec<f64>,
    /// `z_i` at a JACK sample of 1.0 (empty: 1.0 each).
    #[serde(default)]
    pub z_full_scale: Vec<f64>,
    /// `u_i` at a JACK sample of 1.0 (empty: 1.0 each).
    #[serde(default)]
    pub u_full_scale: Vec<f64>,
    /// The simulated room.
    #[serde(default)]
    pub room: RoomConfig,
}

/// The `[jack.room]` table: the simulated room as a JACK client.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename_all = "kebab-case")]
pub struct RoomConfig {
    /// The room's client name.
    #[serde(default = "default_room_client")]
    pub client: String,
    /// Frames of delay added to each loudspeaker's signal (a sound card's converters).
    #[serde(default)]
    pub converter_delay: u32,
}

impl Default for RoomConfig {
    fn default() -> Self {
        Self {
            client: default_room_client(),
            converter_delay: 0,
        }
    }
}

fn default_client() -> String {
    DEFAULT_CLIENT.to_string()
}

fn default_room_client() -> String {
    DEFAULT_ROOM_CLIENT.to_string()
}

fn default_budget() -> f64 {
    0.5
}

/// A refused `[jack]` table: `"<file>: field 'jack.<field>': <what>"`.
#[derive(Debug, Clone, PartialEq)]
pub struct JackConfigError(pub String);

impl fmt::Display for JackConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for JackConfigError {}

/// The channel counts a `[jack]` table is checked against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Channels {
    /// Measured outputs.
    pub n_y: usize,
    /// Performance variables.
    pub n_z: usize,
    /// Commands (the JACK plant side has none).
    pub n_r: usize,
    /// Inputs.
    pub n_u: usize,
}

impl JackConfig {
    /// Reads the `[jack]` table of the scenario text `text` (from `origin`) and checks it
    /// against the plant's channels; a missing table gives the defaults (no connections,
    /// unit scales).
    pub fn parse(text: &str, origin: &str, ch: Channels) -> Result<Self, JackConfigError> {
        let refuse = |field: &str, what: String| {
            JackConfigError(format!("{origin}: field 'jack{field}': {what}"))
        };
        let doc: toml::Table =
            toml::from_str(text).map_err(|e| JackConfigError(format!("{origin}: {e}")))?;
        let cfg: JackConfig = match doc.get("jack") {
            None => toml::from_str("").expect("an empty [jack] table has defaults"),
            Some(v) => v
                .clone()
                .try_into()
                .map_err(|e: toml::de::Error| refuse("", e.message().to_string()))?,
        };
        if ch.n_r > 0 {
            return Err(JackConfigError(format!(
                "{origin}: the plant has {} command channel(s) r; the JACK plant side reads only y and z from ports",
                ch.n_r
            )));
        }
        if !(cfg.budget > 0.0 && cfg.budget <= 1.0) {
            return Err(refuse(
                ".budget",
                format!(
                    "{} is not in (0, 1] (the share of a JACK period the plant side may wait for the service)",
                    cfg.budget
                ),
            ));
        }
        if cfg.period_frames == Some(0) {
            return Err(refuse(".period-frames", "0 frames".into()));
        }
        for (name, ports, n) in [
            ("y", &cfg.y, ch.n_y),
            ("z", &cfg.z, ch.n_z),
            ("u", &cfg.u, ch.n_u),
        ] {
            if !ports.is_empty() && ports.len() != n {
                return Err(refuse(
                    &format!(".{name}"),
                    format!(
                        "{} port(s) ({}) for a plant of n_{name} = {n}: give one port per channel, or none",
                        ports.len(),
                        ports.join(", ")
                    ),
                ));
            }
            if let Some(p) = ports.iter().find(|p| !p.contains(':')) {
                return Err(refuse(
                    &format!(".{name}"),
                    format!("'{p}' is not a full port name (client:port, e.g. system:capture_1)"),
                ));
            }
        }
        for (name, scales, n) in [
            ("y-full-scale", &cfg.y_full_scale, ch.n_y),
            ("z-full-scale", &cfg.z_full_scale, ch.n_z),
            ("u-full-scale", &cfg.u_full_scale, ch.n_u),
        ] {
            if !scales.is_empty() && scales.len() != n {
                return Err(refuse(
                    &format!(".{name}"),
                    format!("{} value(s) for {n} channel(s)", scales.len()),
                ));
            }
            if let Some(s) = scales.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
                return Err(refuse(
                    &format!(".{name}"),
                    format!("{s} is not a positive finite scale"),
                ));
            }
        }
        for (field, name) in [(".client", &cfg.client), (".room.client", &cfg.room.client)] {
            if name.is_empty() || name.contains(':') {
                return Err(refuse(
                    field,
                    format!("'{name}' is not a JACK client name (not empty, no ':')"),
                ));
            }
        }
        if cfg.client == cfg.room.client {
            return Err(refuse(
                ".room.client",
                format!("'{}' is also the plant side's client name", cfg.client),
            ));
        }
        Ok(cfg)
    }

    /// The scale of channel `i` of a list (1.0 when the list is empty).
    pub fn scale(scales: &[f64], i: usize) -> f64 {
        scales.get(i).copied().unwrap_or(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CH: Channels = Channels {
        n_y: 1,
        n_z: 1,
        n_r: 0,
        n_u: 2,
    };

    fn parse(table: &str) -> Result<JackConfig, JackConfigError> {
        JackConfig::parse(&format!("[rig]\nname = \"x\"\n{table}"), "s.toml", CH)
    }

    #[test]
    fn a_missing_table_gives_the_defaults() {
        let c = parse("").unwrap();
        assert_eq!(c.client, DEFAULT_CLIENT);
        assert_eq!(c.room.client, DEFAULT_ROOM_CLIENT);
        assert_eq!(c.budget, 0.5);
        assert!(c.y.is_empty() && c.u.is_empty());
        assert_eq!(JackConfig::scale(&c.u_full_scale, 1), 1.0);
    }

    #[test]
    fn a_full_table_is_read() {
        let c = parse(
            "[jack]\nserver = \"rig\"\nbudget = 0.25\nperiod-frames = 32\ny = [\"room:mic-y0\"]\nu = [\"room:speaker-u0\", \"room:speaker-u1\"]\nu-full-scale = [40.0, 20.0]\n[jack.room]\nconverter-delay = 3\n",
        )
        .unwrap();
        assert_eq!(c.server.as_deref(), Some("rig"));
        assert_eq!(c.budget, 0.25);
        assert_eq!(c.period_frames, Some(32));
        assert_eq!(c.u[1], "room:speaker-u1");
        assert_eq!(JackConfig::scale(&c.u_full_scale, 1), 20.0);
        assert_eq!(c.room.converter_delay, 3);
    }

    #[test]
    fn refusals_name_the_file_and_the_field() {
        for (table, field, what) in [
            (
                "[jack]\nu = [\"system:playback_1\"]\n",
                "jack.u",
                "1 port(s) (system:playback_1) for a plant of n_u = 2",
            ),
            (
                "[jack]\ny = [\"capture_1\"]\n",
                "jack.y",
                "not a full port name",
            ),
            ("[jack]\nbudget = 0.0\n", "jack.budget", "is not in (0, 1]"),
            ("[jack]\nbudget = 1.5\n", "jack.budget", "is not in (0, 1]"),
            (
                "[jack]\nperiod-frames = 0\n",
                "jack.period-frames",
                "0 frames",
            ),
            (
                "[jack]\nu-full-scale = [1.0]\n",
                "jack.u-full-scale",
                "1 value(s) for 2",
            ),
            (
                "[jack]\ny-full-scale = [-1.0]\n",
                "jack.y-full-scale",
                "not a positive",
            ),
            (
                "[jack]\nclient = \"a:b\"\n",
                "jack.client",
                "not a JACK client name",
            ),
            (
                "[jack]\nclient = \"room\"\n",
                "jack.room.client",
                "also the plant side's",
            ),
            ("[jack]\nperiod = 3\n", "jack'", "unknown field `period`"),
        ] {
            let e = parse(table).unwrap_err().0;
            assert!(e.starts_with("s.toml: field '"), "{e}");
            assert!(e.contains(field) && e.contains(what), "{table}: {e}");
        }
    }

    #[test]
    fn a_plant_with_commands_is_refused() {
        let ch = Channels { n_r: 1, ..CH };
        let e = JackConfig::parse("", "s.toml", ch).unwrap_err().0;
        assert!(e.contains("1 command channel(s) r"), "{e}");
    }
}
