//! The bounds of the `[rig]` table, which both sides check: the sample period and the
//! length of a run. Counts and durations inside a run are bounded by these (the service's
//! `config::bounds`, plant-proxy's scenario bounds).

/// The longest run, s (7 days): the bound of `rig.duration`, of `--duration` and of every
/// duration inside a run.
pub const MAX_DURATION_S: f64 = 7.0 * 86_400.0;

/// The shortest sample period, s (10 MHz): `rig.sample-period` must be above it.
pub const MIN_SAMPLE_PERIOD_S: f64 = 1e-7;

/// The longest sample period, s: `rig.sample-period` must be below it.
pub const MAX_SAMPLE_PERIOD_S: f64 = 100.0;
