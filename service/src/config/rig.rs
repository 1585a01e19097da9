//! `[rig]`: which rig, and its sampling period.
//!
//! ```toml
//! [rig]
//! name = "acoustic-rig"           # the iceoryx2 service names derive from it
//! sample-period = 1.25e-4         # s, or sample-rate-hz = 8000 (one of the two)
//! duration = 10.0                 # read by the plant proxy; ignored here
//! ```
//!
//! The period must be finite and between 0.1 µs and 100 s.

use super::bounds::{MAX_SAMPLE_PERIOD_S, MIN_SAMPLE_PERIOD_S};
use super::{ConfigError, ErrFn};
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(super) struct RawRig {
    name: String,
    sample_period: Option<f64>,
    sample_rate_hz: Option<f64>,
    #[allow(dead_code)]
    duration: Option<f64>,
}

/// The `[rig]` table, validated.
pub(super) struct Rig {
    /// The rig name.
    pub name: String,
    /// The sampling period in s.
    pub period: f64,
}

/// Checks the name (it must give valid service names) and the sampling period.
pub(super) fn parse(raw: RawRig, err: &ErrFn<'_>) -> Result<Rig, ConfigError> {
    if let Err(e) = ipc_types::ports::service_names(&raw.name) {
        return Err(err("rig.name", e.to_string()));
    }
    let period = match (raw.sample_period, raw.sample_rate_hz) {
        (Some(t), None) => t,
        (None, Some(f)) if f > 0.0 => 1.0 / f,
        (None, Some(f)) => {
            return Err(err("rig.sample-rate-hz", format!("{f} is not positive")));
        }
        (Some(_), Some(_)) => {
            return Err(err(
                "rig",
                "give sample-period or sample-rate-hz, not both".into(),
            ));
        }
        (None, None) => return Err(err("rig.sample-period", "missing".into())),
    };
    if !(period.is_finite() && period > MIN_SAMPLE_PERIOD_S && period < MAX_SAMPLE_PERIOD_S) {
        return Err(err(
            "rig.sample-period",
            format!("{period} s is not a usable period"),
        ));
    }
    Ok(Rig {
        name: raw.name,
        period,
    })
}
