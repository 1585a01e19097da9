//! The bounds of every size, count and duration of the service's tables, checked when the
//! file is read (the table of `docs/configuration.md` lists them with their reasons).
//! A value beyond its bound is refused naming the field, so that no configuration makes
//! the service panic, abort on an allocation or run forever.
//!
//! Durations within a run are bounded by the longest run, [`MAX_DURATION_S`] (the scenario
//! schema's bound of `rig.duration`); counts of cycles by the cycles of that run at the rig's rate.

pub use rig_scenario::bounds::{MAX_DURATION_S, MAX_SAMPLE_PERIOD_S, MIN_SAMPLE_PERIOD_S};

/// The longest wait, s (one day): `service.peer-timeout`, `service.histogram-interval`.
pub const MAX_WAIT_S: f64 = 86_400.0;

/// The number of CPUs a `cpu_set_t` holds (`CPU_SETSIZE`): `service.core` and `--core`
/// must be below it.
pub const MAX_CORES: usize = 1024;

/// The most samples in each tone-report window (`service.report.window` over the period):
/// two windows of `(1 + n_z)` values each are allocated before the loop.
pub const MAX_REPORT_WINDOW_CYCLES: u64 = 1 << 20;

/// The most tones in `service.report.tones-hz`.
pub const MAX_REPORT_TONES: usize = 64;

/// The largest `log.decimation`.
pub const MAX_LOG_DECIMATION: u64 = 1_000_000;

/// The largest `log.queue-capacity`, in records (each record holds every channel of one
/// sample and is allocated when the queue is made).
pub const MAX_LOG_QUEUE_CAPACITY: u64 = 1 << 19;

/// The smallest `log.queue-capacity`, in records.
pub const MIN_LOG_QUEUE_CAPACITY: u64 = 16;

/// The largest RCAC controller order `nc`.
pub const MAX_RCAC_NC: u64 = 1000;

/// The largest `l_θ` of RCAC with `update = "rls"`, whose covariance `P` is `l_θ × l_θ`
/// (128 MiB at the bound).
pub const MAX_RCAC_RLS_THETA: usize = 4096;

/// The largest PCAC model order `n-hat`.
pub const MAX_PCAC_N_HAT: u64 = 200;

/// The largest PCAC horizon `horizon`.
pub const MAX_PCAC_HORIZON: u64 = 200;

/// The largest `qp-max-iterations` of PCAC.
pub const MAX_QP_ITERATIONS: u64 = 1_000_000;

/// The largest window `tau-n`, `tau-d` of a forgetting rule, in samples.
pub const MAX_FORGETTING_WINDOW: u64 = 1_000_000;

/// The most Markov parameters of a target model (`form = "markov"`).
pub const MAX_TARGET_MARKOV: usize = 4096;

/// The largest order of a channel of a transfer-function target model (its `num` and
/// `den` have at most one more coefficient); the poles are computed at load time.
pub const MAX_TARGET_TF_ORDER: usize = 64;

/// The most states of an LTI controller (`[controller.ss]` or the realization of
/// `[controller.tf]`): its matrices are dense and every step multiplies them.
pub const MAX_LTI_STATES: usize = 1000;

/// The largest magnitude of an entry of `theta0` (RCAC and PCAC).
pub const MAX_THETA0: f64 = 1e6;

/// The cycles of the longest run at the sample period `period` (s): the bound of a count
/// of cycles.
pub fn max_cycles(period: f64) -> u64 {
    (MAX_DURATION_S / period).ceil() as u64
}

/// `seconds` over the sample period `period`, rounded, as cycles; `seconds` and `period`
/// are within their bounds, so the result fits.
pub fn cycles(seconds: f64, period: f64) -> u64 {
    (seconds / period).round() as u64
}

/// Largest plant order `n` of APPC and RC-MRAC (`controller.n`), and the largest degree of
/// their polynomials.
pub const MAX_MRAC_ORDER: u64 = 64;
