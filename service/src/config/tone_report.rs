//! `[service.report]`: the per-tone suppression of `z` in the run report, and the window
//! of the model-following error norm (4.85).
//!
//! ```toml
//! [service.report]
//! tones-hz = [800.0, 900.0]       # default: the tones of [plant.disturbance], if any
//! window = 0.5                    # s: the end of the open-loop phase against the end of the run
//! error-window = [101, 200]       # samples (seq, inclusive) of ‖e‖ (4.85) for a controller
//!                                 # that follows a reference model (APPC, RC-MRAC); default:
//!                                 # the whole run only
//! ```
//!
//! Every tone must lie strictly between 0 and the Nyquist frequency; at most 64 tones, and
//! at most 2²⁰ samples in a window. When the session
//! starts open loop (`service.open-loop`), the open-loop window is at most the second half
//! of that phase, so that the start's transient is not measured.

use super::bounds::{self, MAX_DURATION_S, MAX_REPORT_TONES, MAX_REPORT_WINDOW_CYCLES};
use super::values::seconds;
use super::{ConfigError, ErrFn};
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
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawReport {
    tones_hz: Option<Vec<f64>>,
    window: Option<f64>,
    error_window: Option<[u64; 2]>,
}

/// The tones (given, or those of `[plant.disturbance]`) and the window, which must fit in
/// the open-loop phase when there is one.
pub(super) fn parse(
    raw: RawReport,
    plant: Option<&toml::Value>,
    period: f64,
    open_loop_cycles: u64,
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
    Ok(ToneReportConfig {
        tones_hz,
        source,
        window_cycles,
        error_window,
    })
}

/// The distinct `frequency-hz` of `[[plant.disturbance.tones]]`, in order.
fn plant_tones(plant: Option<&toml::Value>) -> Vec<f64> {
    let tones = plant
        .and_then(|p| p.get("disturbance"))
        .and_then(|d| d.get("tones"))
        .and_then(|t| t.as_array());
    let mut hz = Vec::new();
    for t in tones.into_iter().flatten() {
        if let Some(f) = t
            .get("frequency-hz")
            .and_then(|f| f.as_float().or(f.as_integer().map(|i| i as f64)))
            && !hz.contains(&f)
        {
            hz.push(f);
        }
    }
    hz
}
