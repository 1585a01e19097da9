//! Figures of adaptive-control runs, in the manner of Figures 3.7, 3.10, 3.14 and 3.17 of
//! the dissertation, from [`Trace`]s of [`crate::simulate`], and `run.png` of a run of the
//! service ([`run_folder_figure`], see [`run`]).
//!
//! [`adaptive_run_figure`] draws four panels:
//!
//! - (a) the performance variables `z` over time, open loop and closed loop;
//! - (b) the control inputs `u` of the closed loop;
//! - (c) the controller's coefficients: any set of series ([`theta_series`] for every
//!   entry of `θ` recorded in [`Trace::theta`], [`internal_series`] for a logged internal
//!   such as `theta_norm` when only `‖θ‖` is available);
//! - (d) the Welch PSD ([`crate::analysis::psd`]) of `z`, open and closed loop, on a
//!   logarithmic axis, over the part of each run after a given time (the settled part).
//!
//! [`run_folder_figure`] draws `run.png` of a service run from its run folder
//! (`signals.csv` and `report.json`): the data preparation is the pure
//! [`run::prepare`] (plant time by sequence number, the open-loop phase and the controller
//! start, PSD windows of equal length, the shaded safe-state, silence and watchdog
//! intervals, the verdict), the drawing [`run::draw`].
//!
//! Long traces are reduced to at most [`MAX_LINE_POINTS`] points per series by keeping
//! the minimum and the maximum of each bucket of samples ([`envelope`], [`envelope_xy`]),
//! so a tone keeps its envelope instead of aliasing.

pub mod report;
pub mod run;
pub mod timeline;

use std::path::Path;

use plotters::style::RGBColor;

use crate::analysis;
use crate::analysis::PsdError;
use crate::plot::{Mark, PALETTE, Panel, PlotError, Series, VLine, figure};
use crate::simulate::Trace;

/// Largest number of points a time series is drawn with.
pub const MAX_LINE_POINTS: usize = 8000;

/// Color of open-loop curves.
pub const OPEN_COLOR: RGBColor = RGBColor(150, 150, 150);

/// The coefficients panel (c): a title, a y label and any series over time (s).
#[derive(Debug, Clone, Default)]
pub struct Coefficients {
    /// Panel caption.
    pub title: String,
    /// Label of the y axis.
    pub y_label: String,
    /// The series, x in seconds.
    pub series: Vec<Series>,
}

/// What [`adaptive_run_figure`] draws.
#[derive(Debug, Clone)]
pub struct AdaptiveRun<'a> {
    /// Figure title.
    pub title: String,
    /// The open-loop run (same plant and disturbance, `u ≡ 0`), if there is one.
    pub open: Option<&'a Trace>,
    /// The closed-loop run.
    pub closed: &'a Trace,
    /// Panel (c).
    pub coefficients: Coefficients,
    /// The PSDs use the samples from this time on, s.
    pub psd_from: f64,
    /// The open-loop PSD uses the samples of the open trace from this time on instead
    /// (s), when the open loop is a phase of the same run (a real-time run that starts
    /// open loop) rather than a run of its own.
    pub open_psd_from: Option<f64>,
    /// Welch segment length, samples.
    pub psd_segment: usize,
    /// Time at which the controller starts acting, s (drawn as a dashed line in (a) and
    /// (b)), if any.
    pub start: Option<f64>,
}

/// `(t, x)` of `x` sampled every `dt` s from `t0`, reduced to at most `max_points` points:
/// each bucket of samples contributes its minimum and its maximum, in time order.
pub fn envelope(x: &[f64], t0: f64, dt: f64, max_points: usize) -> Vec<(f64, f64)> {
    envelope_by(x, |k| t0 + k as f64 * dt, max_points)
}

/// `(t[k], x[k])` reduced to at most `max_points` points as [`envelope`] does, for samples
/// at any times `t` (increasing; the shorter of `t` and `x` sets the length).
pub fn envelope_xy(t: &[f64], x: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = t.len().min(x.len());
    envelope_by(&x[..n], |k| t[k], max_points)
}

/// The envelope of `x` with the time of sample `k` given by `time`.
fn envelope_by(x: &[f64], time: impl Fn(usize) -> f64, max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len();
    if n <= max_points.max(2) {
        return x.iter().enumerate().map(|(k, v)| (time(k), *v)).collect();
    }
    let buckets = (max_points / 2).max(1);
    let size = n.div_ceil(buckets);
    let mut out = Vec::with_capacity(2 * buckets);
    for start in (0..n).step_by(size) {
        let end = (start + size).min(n);
        let (mut kmin, mut kmax) = (start, start);
        for k in start..end {
            // A non-finite sample never wins over a finite one.
            if x[k] < x[kmin] || !x[kmin].is_finite() {
                kmin = k;
            }
            if x[k] > x[kmax] || !x[kmax].is_finite() {
                kmax = k;
            }
        }
        let (a, b) = (kmin.min(kmax), kmin.max(kmax));
        out.push((time(a), x[a]));
        if b != a {
            out.push((time(b), x[b]));
        }
    }
    out
}

/// One unlabelled line per entry of `θ` in `trace.theta`, recorded every `every`
/// samples, colored in turn from the palette.
pub fn theta_series(trace: &Trace, every: usize) -> Vec<Series> {
    let len = trace.theta.first().map_or(0, Vec::len);
    let dt = trace.sample_period * every.max(1) as f64;
    (0..len)
        .map(|i| {
            let x: Vec<f64> = trace.theta.iter().map(|th| th[i]).collect();
            Series {
                label: String::new(),
                points: envelope(&x, 0.0, dt, MAX_LINE_POINTS),
                color: PALETTE[i % (PALETTE.len() - 1)],
                mark: Mark::Line,
            }
        })
        .collect()
}

/// The internal signal `name` of `trace` (e.g. `theta_norm`) as a line labelled `label`,
/// or `None` when the controller did not log it.
pub fn internal_series(trace: &Trace, name: &str, label: &str, color: RGBColor) -> Option<Series> {
    let i = trace.internal_names.iter().position(|n| n == name)?;
    Some(Series {
        label: label.into(),
        points: envelope(
            &trace.internals[i],
            0.0,
            trace.sample_period,
            MAX_LINE_POINTS,
        ),
        color,
        mark: Mark::Line,
    })
}

/// A time-series line of `x` (sample period `dt`).
fn line(label: &str, x: &[f64], dt: f64, color: RGBColor) -> Series {
    Series {
        label: label.into(),
        points: envelope(x, 0.0, dt, MAX_LINE_POINTS),
        color,
        mark: Mark::Line,
    }
}

/// A figure of an adaptive run that cannot be made: a PSD of too few samples, or the
/// drawing.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// A PSD cannot be estimated.
    #[error(transparent)]
    Psd(#[from] PsdError),
    /// The figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

message_from!(FigureError);

/// PSD series of every `z` channel of `t` from time `from` on (an error when fewer than 8
/// samples are left).
fn psd_series(
    t: &Trace,
    from: f64,
    segment: usize,
    what: &str,
    color: impl Fn(usize) -> RGBColor,
) -> Result<Vec<Series>, FigureError> {
    let k0 = ((from / t.sample_period).round() as usize).min(t.len());
    let mut out = Vec::new();
    for (c, z) in t.z.iter().enumerate() {
        let p = analysis::psd(&z[k0..], 1.0 / t.sample_period, segment)?;
        let points = p
            .freq_hz
            .iter()
            .zip(&p.density)
            .filter(|(_, d)| **d > 0.0)
            .map(|(f, d)| (*f, *d))
            .collect();
        out.push(Series {
            label: format!("{what} z{c}"),
            points,
            color: color(c),
            mark: Mark::Line,
        });
    }
    Ok(out)
}

/// Writes the four-panel figure of an adaptive run (see the module docs) into the PNG
/// `path`.
pub fn adaptive_run_figure(path: &Path, run: &AdaptiveRun<'_>) -> Result<(), FigureError> {
    let c = run.closed;
    let dt = c.sample_period;
    let closed_color = |i: usize| PALETTE[i % (PALETTE.len() - 1)];
    // (a) z, open and closed.
    let mut za = Vec::new();
    if let Some(o) = run.open {
        for (i, z) in o.z.iter().enumerate() {
            za.push(line(
                &format!("open loop z{i}"),
                z,
                o.sample_period,
                OPEN_COLOR,
            ));
        }
    }
    for (i, z) in c.z.iter().enumerate() {
        za.push(line(&format!("closed loop z{i}"), z, dt, closed_color(i)));
    }
    // (b) u.
    let ub: Vec<Series> =
        c.u.iter()
            .enumerate()
            .map(|(i, u)| line(&format!("u{i}"), u, dt, closed_color(i)))
            .collect();
    let start: Vec<VLine> = run
        .start
        .map(|x| VLine {
            label: format!("controller starts, {x:.2} s"),
            x,
            color: RGBColor(0, 0, 0),
        })
        .into_iter()
        .collect();
    // (d) PSDs.
    let mut pd = Vec::new();
    if let Some(o) = run.open {
        pd.extend(psd_series(
            o,
            run.open_psd_from.unwrap_or(run.psd_from),
            run.psd_segment,
            "open loop",
            |_| OPEN_COLOR,
        )?);
    }
    pd.extend(psd_series(
        c,
        run.psd_from,
        run.psd_segment,
        "closed loop",
        closed_color,
    )?);
    let panels = [
        Panel {
            title: "(a) performance z".into(),
            x_label: "time (s)".into(),
            y_label: "z (plant units)".into(),
            series: za,
            vlines: start.clone(),
            ..Default::default()
        },
        Panel {
            title: "(b) control input u".into(),
            x_label: "time (s)".into(),
            y_label: "u (plant units)".into(),
            series: ub,
            vlines: start,
            ..Default::default()
        },
        Panel {
            title: format!("(c) {}", run.coefficients.title),
            x_label: "time (s)".into(),
            y_label: run.coefficients.y_label.clone(),
            series: run.coefficients.series.clone(),
            ..Default::default()
        },
        Panel {
            title: match run.open_psd_from {
                Some(o) if run.open.is_some() => format!(
                    "(d) PSD of z: open loop from {o:.2} s, closed loop from {:.2} s",
                    run.psd_from
                ),
                _ => format!("(d) PSD of z from {:.1} s on", run.psd_from),
            },
            x_label: "frequency (Hz)".into(),
            y_label: "PSD ((plant units)²/Hz)".into(),
            y_log: true,
            series: pd,
            ..Default::default()
        },
    ];
    Ok(figure(path, &run.title, (2, 2), (1500, 1000), &panels)?)
}

/// Writes `run.png` into the run folder `folder` of a service run (see [`run`]) and
/// returns its path. Errors name the file at fault: no `report.json` or `signals.csv`
/// (logging off), a report without a sample period, a log without `seq` or `z`, a bad
/// sequence number.
pub fn run_folder_figure(folder: &Path) -> Result<std::path::PathBuf, run::RunFigureError> {
    run::write(folder)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_envelope_keeps_the_extremes_of_every_bucket_and_short_series_whole() {
        let x: Vec<f64> = (0..10_000).map(|k| ((k as f64) * 2.9).sin()).collect();
        let e = envelope(&x, 1.0, 0.5, 100);
        assert!(e.len() <= 100 && e.len() >= 98, "{}", e.len());
        assert!(e.windows(2).all(|w| w[1].0 >= w[0].0));
        let hi = e.iter().fold(f64::MIN, |a, p| a.max(p.1));
        assert!(hi > 0.999);
        let short = envelope(&x[..50], 0.0, 1.0, 100);
        assert_eq!(short.len(), 50);
        assert_eq!(short[7], (7.0, x[7]));
    }

    #[test]
    fn a_run_figure_is_written_with_any_coefficient_series() {
        let n = 3000;
        let ts = 0.01;
        let tone = |a: f64| -> Vec<f64> { (0..n).map(|k| a * (0.7 * k as f64).sin()).collect() };
        let open = Trace {
            sample_period: ts,
            z: vec![tone(1.0)],
            u: vec![vec![0.0; n]],
            y: vec![tone(1.0)],
            ..Default::default()
        };
        let closed = Trace {
            sample_period: ts,
            z: vec![tone(0.01)],
            u: vec![tone(0.5)],
            y: vec![tone(0.01)],
            internal_names: vec!["theta_norm".into()],
            internals: vec![(0..n).map(|k| k as f64 / n as f64).collect()],
            theta: (0..n / 10).map(|k| vec![k as f64, -(k as f64)]).collect(),
        };
        let dir = std::env::temp_dir().join(format!("figures-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for coefficients in [
            Coefficients {
                title: "θ".into(),
                y_label: "θ".into(),
                series: theta_series(&closed, 10),
            },
            Coefficients {
                title: "‖θ‖".into(),
                y_label: "‖θ‖".into(),
                series: vec![internal_series(&closed, "theta_norm", "‖θ‖", PALETTE[0]).unwrap()],
            },
        ] {
            let path = dir.join("run.png");
            adaptive_run_figure(
                &path,
                &AdaptiveRun {
                    title: "test".into(),
                    open: Some(&open),
                    closed: &closed,
                    coefficients,
                    psd_from: 10.0,
                    open_psd_from: None,
                    psd_segment: 512,
                    start: Some(1.0),
                },
            )
            .unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[1..4], b"PNG");
        }
        assert!(internal_series(&closed, "mu", "μ", PALETTE[0]).is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
