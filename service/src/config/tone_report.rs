//! `[service.report]`: the per-tone suppression of `z` in the run report, the window of
//! the model-following error norm (4.85), and the force regulation of a contact phase
//! (chapter 7).
//!
//! ```toml
//! [service.report]
//! tones-hz = [800.0, 900.0]       # default: the tones of [plant.disturbance], if any
//! window = 0.5                    # s: the end of the open-loop phase against the end of the run
//! error-window = [101, 200]       # samples (seq, inclusive) of ‖e‖ (4.85) for a controller
//!                                 # that follows a reference model (APPC, RC-MRAC); default:
//!                                 # the whole run only
//! min-suppression-db = 60.0       # the acceptance criterion: a run in which a tone is
//!                                 # suppressed by less (or not measured) fails its verdict;
//!                                 # default: none. It is the scenario's controller's: a
//!                                 # controller file (`--controller`) replaces it by its
//!                                 # own [service.report] min-suppression-db, or by none
//! force-regulation = { measured = 6, set-point = 0, band = 0.05 }
//!                                 # y channel of the measured force, r channel of its
//!                                 # set-point, the ± band of the settling time (a fraction
//!                                 # of the set-point); default: no force report
//! ```
//!
//! Every tone must lie strictly between 0 and the Nyquist frequency; at most 64 tones, and
//! at most 2²⁰ samples in a window. When the session
//! starts open loop (`service.open-loop`), the open-loop window is at most the second half
//! of that phase, so that the start's transient is not measured.

use super::bounds::{self, MAX_DURATION_S, MAX_REPORT_TONES, MAX_REPORT_WINDOW_CYCLES};
use super::values::seconds;
use super::{ConfigError, ErrFn};
use rig_scenario::plant_outline::PlantOutline;
use serde::Deserialize;

/// What the run report measures tone by tone (`[service.report]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ToneReportConfig {
    /// Tone frequencies in Hz (empty: no tone report).
    pub tones_hz: Vec<f64>,
    /// Where they came from (`service.report.tones-hz` or `plant.disturbance`).
    pub source: String,
    /// Samples in each window (the open-loop window ends when the controller starts; the
    /// closed-loop window is the end of the run).
    pub window_cycles: u64,
    /// The samples `[first, last]` (sequence numbers, inclusive) over which the run report
    /// gives the model-following error norm (4.85); `None`: the whole run only.
    pub error_window: Option<(u64, u64)>,
    /// The force regulation report (`service.report.force-regulation`), when configured.
    pub force_regulation: Option<ForceRegulationConfig>,
    /// The acceptance criterion `service.report.min-suppression-db`: every tone must be
    /// suppressed by at least this much for the run to pass.
    pub min_suppression_db: Option<f64>,
}

/// Which channels hold a regulated force and its set-point, for the run report's contact
/// phases ([`crate::runtime::force_regulation`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceRegulationConfig {
    /// The `y` channel of the measured force.
    pub measured: usize,
    /// The `r` channel of the set-point; a phase lasts while it is positive.
    pub set_point: usize,
    /// The settling band, a fraction of the set-point (the chapter's target: 0.05).
    pub band: f64,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawForceRegulation {
    measured: usize,
    set_point: usize,
    band: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawReport {
    tones_hz: Option<Vec<f64>>,
    window: Option<f64>,
    error_window: Option<[u64; 2]>,
    force_regulation: Option<RawForceRegulation>,
    min_suppression_db: Option<f64>,
}

/// The tones (given, or those of `[plant.disturbance]`) and the window, which must fit in
/// the open-loop phase when there is one.
pub(super) fn parse(
    raw: RawReport,
    plant: Option<&toml::Value>,
    period: f64,
    open_loop_cycles: u64,
    counts: (usize, usize),
    err: &ErrFn<'_>,
) -> Result<ToneReportConfig, ConfigError> {
    let nyquist = 0.5 / period;
    let (tones_hz, source) = match raw.tones_hz {
        Some(t) => (t, "service.report.tones-hz".to_string()),
        None => (plant_tones(plant), "plant.disturbance".to_string()),
    };
    if tones_hz.len() > MAX_REPORT_TONES {
        return Err(err(
            "service.report.tones-hz",
            format!("{} tones, at most {MAX_REPORT_TONES}", tones_hz.len()),
        ));
    }
    for f in &tones_hz {
        if !(f.is_finite() && *f > 0.0 && *f < nyquist) {
            return Err(err(
                "service.report.tones-hz",
                format!("{f} Hz is not between 0 and the Nyquist frequency {nyquist} Hz"),
            ));
        }
    }
    let field = "service.report.window";
    let window = seconds(raw.window.unwrap_or(0.5), false, MAX_DURATION_S, field, err)?;
    let mut window_cycles = bounds::cycles(window, period).max(1);
    if window_cycles > MAX_REPORT_WINDOW_CYCLES {
        return Err(err(
            field,
            format!("{window} s is {window_cycles} samples, at most {MAX_REPORT_WINDOW_CYCLES}"),
        ));
    }
    if open_loop_cycles > 0 {
        window_cycles = window_cycles.min(open_loop_cycles / 2).max(1);
    }
    let error_window = match raw.error_window {
        Some([first, last]) if first > last => {
            return Err(err(
                "service.report.error-window",
                format!("[{first}, {last}]: the first sample comes after the last"),
            ));
        }
        Some([first, last]) => Some((first, last)),
        None => None,
    };
    let force_regulation = match raw.force_regulation {
        None => None,
        Some(f) => Some(force_regulation(f, counts, err)?),
    };
    let min_suppression_db = match raw.min_suppression_db {
        Some(d) if !d.is_finite() => {
            return Err(err(
                "service.report.min-suppression-db",
                format!("{d} must be a finite number of dB"),
            ));
        }
        Some(_) if tones_hz.is_empty() => {
            return Err(err(
                "service.report.min-suppression-db",
                "there is no tone to judge: give service.report.tones-hz or \
                 [plant.disturbance] tones"
                    .into(),
            ));
        }
        Some(_) if open_loop_cycles == 0 => {
            return Err(err(
                "service.report.min-suppression-db",
                "suppression is measured against the open-loop phase: service.open-loop must \
                 be positive"
                    .into(),
            ));
        }
        d => d,
    };
    Ok(ToneReportConfig {
        tones_hz,
        source,
        window_cycles,
        error_window,
        force_regulation,
        min_suppression_db,
    })
}

/// `service.report.force-regulation`: channels that exist (`counts` = `(n_y, n_r)`), a
/// band in `(0, 1)`.
fn force_regulation(
    raw: RawForceRegulation,
    (n_y, n_r): (usize, usize),
    err: &ErrFn<'_>,
) -> Result<ForceRegulationConfig, ConfigError> {
    if raw.measured >= n_y {
        return Err(err(
            "service.report.force-regulation.measured",
            format!(
                "y channel {} does not exist: the rig has {n_y}",
                raw.measured
            ),
        ));
    }
    if raw.set_point >= n_r {
        return Err(err(
            "service.report.force-regulation.set-point",
            format!(
                "r channel {} does not exist: the rig has {n_r}",
                raw.set_point
            ),
        ));
    }
    let band = raw.band.unwrap_or(0.05);
    if !(band.is_finite() && band > 0.0 && band < 1.0) {
        return Err(err(
            "service.report.force-regulation.band",
            format!("{band} must lie strictly between 0 and 1"),
        ));
    }
    Ok(ForceRegulationConfig {
        measured: raw.measured,
        set_point: raw.set_point,
        band,
    })
}

/// The distinct `frequency-hz` of `[[plant.disturbance.tones]]`, in order.
fn plant_tones(plant: Option<&toml::Value>) -> Vec<f64> {
    plant.map_or_else(Vec::new, |p| PlantOutline::new(p).tone_frequencies_hz())
}
