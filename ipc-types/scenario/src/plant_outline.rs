//! What a controller side may read of a simulated plant's `[plant]` table without the
//! simulator: its channel counts, its measurement noise and its disturbance tones. The
//! service takes from it the channel counts when `[service.channels]` is absent, the tones
//! of its report when `service.report.tones-hz` is absent, and checks the noise against
//! its accepted ranges. The table itself (the model and everything else) is the plant
//! side's; a test of plant-proxy holds this outline against the plant it builds from each
//! scenario.

use ipc_types::ChannelCounts;
use std::f64::consts::TAU;

/// A view of a `[plant]` table (see the module docs).
#[derive(Debug, Clone, Copy)]
pub struct PlantOutline<'a> {
    table: &'a toml::Value,
}

/// A TOML number (integer or float) as `f64`.
fn number(v: &toml::Value) -> Option<f64> {
    v.as_float().or(v.as_integer().map(|n| n as f64))
}

impl<'a> PlantOutline<'a> {
    /// The outline of the `[plant]` table `table`.
    pub fn new(table: &'a toml::Value) -> Self {
        Self { table }
    }

    /// The channel counts `y, z, r, u` from `outputs-y`, `outputs-z`, `commands` (default
    /// 0) and `inputs`.
    ///
    /// # Errors
    ///
    /// A missing or negative count, naming it; counts beyond the contract's capacities.
    pub fn channel_counts(&self) -> Result<ChannelCounts, String> {
        let get = |k: &str, default: Option<i64>| -> Result<usize, String> {
            match self.table.get(k).and_then(|v| v.as_integer()).or(default) {
                Some(n) if n >= 0 => Ok(n as usize),
                Some(n) => Err(format!("plant.{k} = {n} is negative")),
                None => Err(format!(
                    "plant.{k} is missing, and [service.channels] is not given"
                )),
            }
        };
        ChannelCounts::new(
            get("outputs-y", None)?,
            get("outputs-z", None)?,
            get("commands", Some(0))?,
            get("inputs", None)?,
        )
    }

    /// The standard deviation of the measurement noise of channel `i` of `signal` (`"y"`
    /// or `"z"`): `[plant.noise] <signal>-std`, a scalar for every channel or one value
    /// each; `None` when the table gives none for it.
    pub fn noise_std(&self, signal: &str, i: usize) -> Option<f64> {
        let v = self.table.get("noise")?.get(format!("{signal}-std"))?;
        number(v.as_array().map_or(Some(v), |a| a.get(i))?)
    }

    /// The distinct frequencies of `[[plant.disturbance.tones]]` in Hz, in order: each
    /// tone's `frequency-hz`, or its `frequency-rad-s` over `2π`.
    pub fn tone_frequencies_hz(&self) -> Vec<f64> {
        let tones = self
            .table
            .get("disturbance")
            .and_then(|d| d.get("tones"))
            .and_then(|t| t.as_array());
        let mut hz = Vec::new();
        let hz_of = |t: &toml::Value| {
            let rad_s = || t.get("frequency-rad-s").and_then(number).map(|w| w / TAU);
            t.get("frequency-hz").and_then(number).or_else(rad_s)
        };
        for f in tones.into_iter().flatten().filter_map(hz_of) {
            if !hz.contains(&f) {
                hz.push(f);
            }
        }
        hz
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outline(text: &str) -> toml::Value {
        toml::Value::Table(toml::from_str(text).unwrap())
    }

    #[test]
    fn counts_noise_and_tones_are_read_from_the_table() {
        let t = outline(
            "inputs = 2\noutputs-y = 1\noutputs-z = 1\n[noise]\ny-std = [0.1]\nz-std = 0.2\n\
             [disturbance]\ntones = [{ frequency-hz = 800 }, { frequency-hz = 900.0 }, \
             { frequency-hz = 800.0 }, { frequency-rad-s = 6283.185307179586 }]",
        );
        let o = PlantOutline::new(&t);
        let c = o.channel_counts().unwrap();
        assert_eq!((c.n_y, c.n_z, c.n_r, c.n_u), (1, 1, 0, 2));
        assert_eq!(
            (o.noise_std("y", 0), o.noise_std("y", 1)),
            (Some(0.1), None)
        );
        assert_eq!(o.noise_std("z", 3), Some(0.2));
        let hz = o.tone_frequencies_hz();
        assert_eq!(hz[..2], [800.0, 900.0]);
        assert!(hz.len() == 3 && (hz[2] - 1000.0).abs() < 1e-9, "{hz:?}");
    }

    #[test]
    fn a_missing_or_negative_count_is_named() {
        let t = outline("inputs = -1\noutputs-y = 1\noutputs-z = 1");
        assert!(
            PlantOutline::new(&t)
                .channel_counts()
                .unwrap_err()
                .contains("plant.inputs")
        );
        let t = outline("inputs = 1\noutputs-z = 1");
        assert!(
            PlantOutline::new(&t)
                .channel_counts()
                .unwrap_err()
                .contains("plant.outputs-y")
        );
    }
}
