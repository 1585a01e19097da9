//! `[rig]`: which rig, and its sampling period, read by the scenario schema's reader
//! ([`rig_scenario::rig`]: the name gives the iceoryx2 service names, the period is
//! `sample-period` or `1 / sample-rate-hz`, strictly between 0.1 µs and 100 s; the
//! duration, the plant's, is checked when given and not used here).

use super::{ConfigError, ErrFn};
pub(super) use rig_scenario::rig::RawRig;
use rig_scenario::rig::RigTable;

/// The `[rig]` table, validated.
pub(super) struct Rig {
    /// The rig name.
    pub name: String,
    /// The sampling period in s.
    pub period: f64,
}

/// Checks the name (it must give valid service names) and the sampling period.
pub(super) fn parse(raw: RawRig, err: &ErrFn<'_>) -> Result<Rig, ConfigError> {
    let t = RigTable::parse(raw).map_err(|e| err(&e.field, e.problem))?;
    Ok(Rig {
        name: t.name,
        period: t.sample_period,
    })
}
