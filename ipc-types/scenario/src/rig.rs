//! The `[rig]` table: which rig, its sample period and the length of its default run.
//! Both sides read it through [`RigTable::parse`].
//!
//! ```toml
//! [rig]
//! name = "acoustic-rig"     # 1 to 64 of [A-Za-z0-9_-]: the iceoryx2 service names derive from it
//! sample-period = 1.25e-4   # s; or sample-rate-hz = 8000.0 (exactly one of the two)
//! duration = 10.0           # s of the default run (the plant side needs it)
//! ```
//!
//! The period `T_s` is given directly or as `1 / f_s`; it must lie strictly between
//! [`MIN_SAMPLE_PERIOD_S`] and [`MAX_SAMPLE_PERIOD_S`]. The duration, when given, is
//! positive, finite and at most [`MAX_DURATION_S`].

use crate::FieldError;
use crate::bounds::{MAX_DURATION_S, MAX_SAMPLE_PERIOD_S, MIN_SAMPLE_PERIOD_S};
use serde::Deserialize;

/// The `[rig]` table as written; an unknown key is refused by the TOML reader.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct RawRig {
    name: Option<String>,
    sample_period: Option<f64>,
    sample_rate_hz: Option<f64>,
    duration: Option<f64>,
}

/// The `[rig]` table, validated.
#[derive(Debug, Clone, PartialEq)]
pub struct RigTable {
    /// The rig name, a valid root of the contract's service names.
    pub name: String,
    /// The sample period `T_s`, s.
    pub sample_period: f64,
    /// The duration of the default run, s, when the table gives one.
    pub duration: Option<f64>,
}

impl RigTable {
    /// Validates the table as written.
    ///
    /// # Errors
    ///
    /// The first field at fault: a missing or invalid name, no period or two, a period out
    /// of bounds, a duration out of bounds.
    pub fn parse(raw: RawRig) -> Result<Self, FieldError> {
        let name = raw
            .name
            .ok_or_else(|| FieldError::new("rig.name", "is missing"))?;
        if let Err(e) = ipc_types::ports::service_names(&name) {
            return Err(FieldError::new("rig.name", e.to_string()));
        }
        let positive = |v: f64, field: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(v)
            } else {
                Err(FieldError::new(
                    field,
                    format!("{v} is not positive and finite"),
                ))
            }
        };
        let sample_period = match (raw.sample_period, raw.sample_rate_hz) {
            (Some(t), None) => positive(t, "rig.sample-period")?,
            (None, Some(f)) => 1.0 / positive(f, "rig.sample-rate-hz")?,
            (Some(_), Some(_)) => {
                return Err(FieldError::new(
                    "rig.sample-period",
                    "give sample-period or sample-rate-hz, not both",
                ));
            }
            (None, None) => {
                return Err(FieldError::new(
                    "rig.sample-period",
                    "is missing (or give rig.sample-rate-hz)",
                ));
            }
        };
        if !(sample_period > MIN_SAMPLE_PERIOD_S && sample_period < MAX_SAMPLE_PERIOD_S) {
            let field = match raw.sample_rate_hz {
                Some(_) => "rig.sample-rate-hz",
                None => "rig.sample-period",
            };
            return Err(FieldError::new(
                field,
                format!(
                    "a period of {sample_period} s is not between {MIN_SAMPLE_PERIOD_S} s and \
                     {MAX_SAMPLE_PERIOD_S} s"
                ),
            ));
        }
        let duration = raw.duration.map(|d| check_duration(d, "")).transpose()?;
        Ok(Self {
            name,
            sample_period,
            duration,
        })
    }
}

/// A run duration: positive, finite and at most [`MAX_DURATION_S`]; `how` says where a
/// value that did not come from the file came from (e.g. ` (--duration)`).
///
/// # Errors
///
/// Any other value, naming `rig.duration`.
pub fn check_duration(d: f64, how: &str) -> Result<f64, FieldError> {
    if d.is_finite() && d > 0.0 && d <= MAX_DURATION_S {
        Ok(d)
    } else {
        Err(FieldError::new(
            "rig.duration",
            format!("{d} s{how} is not a duration in (0, {MAX_DURATION_S}] s (7 days)"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<RigTable, FieldError> {
        RigTable::parse(toml::from_str(text).expect("TOML"))
    }

    #[test]
    fn a_rate_or_a_period_gives_the_period() {
        let t = parse("name = \"r\"\nsample-rate-hz = 8000.0\nduration = 2.0").unwrap();
        assert_eq!((t.sample_period, t.duration), (1.25e-4, Some(2.0)));
        let t = parse("name = \"r\"\nsample-period = 0.01").unwrap();
        assert_eq!((t.sample_period, t.duration), (0.01, None));
    }

    #[test]
    fn each_bad_field_is_named() {
        for (text, field) in [
            ("sample-period = 0.01", "rig.name"),
            ("name = \"a b\"\nsample-period = 0.01", "rig.name"),
            ("name = \"r\"", "rig.sample-period"),
            (
                "name = \"r\"\nsample-period = 0.01\nsample-rate-hz = 100.0",
                "rig.sample-period",
            ),
            ("name = \"r\"\nsample-rate-hz = 1e9", "rig.sample-rate-hz"),
            ("name = \"r\"\nsample-period = -1.0", "rig.sample-period"),
            (
                "name = \"r\"\nsample-period = 0.01\nduration = 1e300",
                "rig.duration",
            ),
            (
                "name = \"r\"\nsample-period = 0.01\nduration = 0.0",
                "rig.duration",
            ),
        ] {
            assert_eq!(parse(text).unwrap_err().field, field, "{text}");
        }
    }

    #[test]
    fn an_unknown_key_is_refused() {
        let e = toml::from_str::<RawRig>("name = \"r\"\nsample-perod = 0.01").unwrap_err();
        assert!(e.to_string().contains("sample-perod"), "{e}");
    }
}
