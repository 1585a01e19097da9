//! `run.png`: the figure of a service run, from its run folder (`report.json` and
//! `signals.csv`).
//!
//! The figure is drawn in two steps. [`prepare`] is a pure function of the report and the
//! log that decides everything the figure says, into a plain [`RunFigure`]:
//!
//! - **plant time** of every row and event ([`super::timeline`]): `seq × T` from the first
//!   logged sample, so lost samples never shift anything;
//! - the **open-loop phase** of each plant session and the **controller start**: the
//!   first sample after the last one with the `OPEN_LOOP` actuation status of the
//!   session (where `service.open-loop` ended), compared with the report's
//!   `open_loop_s`; without any `OPEN_LOOP` row it is placed from `open_loop_s`;
//! - the **PSD windows**: the last `W` seconds of the open-loop phase and the last `W`
//!   seconds of the run, `W` the report's tone window (`tones.window_s`), the same number
//!   of samples `N = W / T` in both (both shortened to the open-loop phase when it is
//!   shorter), with one Welch segment length `L = clamp(N / 4, 64, 8192)` for both;
//! - the **shaded intervals**: safe state, plant silence, plant watchdog, lost samples
//!   (gaps in `seq`) and missed answers (`PREVIOUS_ACTUATION_MISSED`), and the starts of
//!   new plant sessions;
//! - the **channels** `z0…`, `u0…` in column order, each drawn in a panel of its own;
//! - the **verdict** line: the report's verdict (`OK`, or `FAILED` and its first failure
//!   line), and `FAILED` whenever the log ends in the safe state.
//!
//! [`draw`] then only draws the [`RunFigure`]: the verdict and notes under the title; on
//! the left one panel per `z` channel (open loop grey, closed loop in color) and one per
//! `u` channel; on the right `‖θ‖` (the logged `theta_norm`) and one PSD panel per `z`
//! channel, in dB re 1 (plant unit)²/Hz. Time-domain panels share the time axis and
//! carry the shaded intervals and the dashed controller start. The scenario names no
//! units, so signals are in "plant units".

use std::ops::Range;
use std::path::{Path, PathBuf};

use ipc_types::actuation_status;
use plotters::style::RGBColor;

use super::report::{Event, ReportView};
use super::timeline::{Interval, IntervalKind, Timeline};
use super::{MAX_LINE_POINTS, OPEN_COLOR, envelope_xy};
use crate::analysis::{self, PsdError};
use crate::design::csvlog::{Log, LogError};
use crate::plot::{Band, Mark, Note, PALETTE, Panel, PlotError, Series, VLine, column_figure};

/// A run folder whose figure cannot be made, naming the file at fault (the report or the
/// signal log) and, for the log, the row.
#[derive(Debug, thiserror::Error)]
pub enum RunFigureError {
    /// `report.json` cannot be read.
    #[error("{origin}: cannot read the run report: {source}")]
    ReadReport {
        /// The report file.
        origin: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// `report.json` is not a run report.
    #[error("{origin}: not a run report this figure can read: {source}")]
    Report {
        /// The report file.
        origin: String,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// The report gives no sample period.
    #[error("{origin}: no sample period (a positive sample_period_s or budget_ns)")]
    NoSamplePeriod {
        /// The report file.
        origin: String,
    },
    /// The signal log cannot be read, or lacks a column.
    #[error(transparent)]
    Log(#[from] LogError),
    /// The signal log has no rows.
    #[error("{origin}: the log has no rows")]
    NoRows {
        /// The log.
        origin: String,
    },
    /// A sample period that is not positive.
    #[error("{origin}: sample period {period} s is not positive")]
    SamplePeriod {
        /// The log.
        origin: String,
        /// The period, s.
        period: f64,
    },
    /// A sequence number that is not a sample number.
    #[error("{origin}: data row {row}: sequence number `{value}` is not a sample number")]
    Sequence {
        /// The log.
        origin: String,
        /// The data row, from 1.
        row: usize,
        /// The value.
        value: f64,
    },
    /// No performance column.
    #[error("{origin}: no performance column z0…; the columns are: {columns}")]
    NoPerformance {
        /// The log.
        origin: String,
        /// Its columns, comma-separated.
        columns: String,
    },
    /// A PSD cannot be estimated.
    #[error(transparent)]
    Psd(#[from] PsdError),
    /// The figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

message_from!(RunFigureError);

/// Window of the PSDs when the report has no tone window, s.
pub const DEFAULT_WINDOW_S: f64 = 0.5;

/// Fewest samples a PSD window may have.
pub const MIN_WINDOW_SAMPLES: usize = 16;

/// Most samples a PSD window may have (a report's window is not trusted further).
pub const MAX_WINDOW_SAMPLES: usize = 1 << 22;

/// Unit label of the plant's signals: the scenario does not name units.
pub const PLANT_UNITS: &str = "plant units";

/// One logged channel: its column name and its value at every row.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// Column name (`z0`, `u1`, …).
    pub name: String,
    /// One value per row of the log.
    pub values: Vec<f64>,
}

/// The open-loop phase and the closed loop of one plant session.
#[derive(Debug, Clone, PartialEq)]
pub struct Phase {
    /// Index of the session in [`Timeline::sessions`].
    pub session: usize,
    /// Rows of the open-loop phase (empty without one).
    pub open_rows: Range<usize>,
    /// Rows after it, the controller acting (or the safe state, shaded).
    pub closed_rows: Range<usize>,
    /// Plant time of the controller start (the first row of `closed_rows`), s; `None`
    /// when the session ended in its open-loop phase.
    pub controller_start_s: Option<f64>,
    /// True when the phase comes from the `OPEN_LOOP` status bits, false when it was
    /// placed from the report's `open_loop_s`.
    pub from_status: bool,
}

/// One PSD window: `samples` consecutive samples of plant time `[from_s, to_s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct PsdWindow {
    /// Start, s.
    pub from_s: f64,
    /// End (exclusive), s.
    pub to_s: f64,
    /// Samples in the window (on the log's sample grid, missing ones held).
    pub samples: usize,
    /// Of those, the samples present in the log.
    pub logged: usize,
    /// The window of every `z` channel, `samples` values each.
    pub z: Vec<Vec<f64>>,
}

/// The two PSD windows and how they were chosen.
#[derive(Debug, Clone, PartialEq)]
pub struct PsdPlan {
    /// Window asked for, s.
    pub window_s: f64,
    /// Where the window came from.
    pub source: String,
    /// Samples in each window (the same for both).
    pub samples: usize,
    /// Sample rate of the windows, Hz (`1 / T`, divided by the log's decimation).
    pub sample_rate_hz: f64,
    /// Welch segment length, samples (the same for both).
    pub segment: usize,
    /// The last window of the open-loop phase.
    pub open: Option<PsdWindow>,
    /// The last window of the run.
    pub closed: Option<PsdWindow>,
}

/// What the figure says of the run's outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The report's verdict is OK and the log does not end in the safe state.
    Ok,
    /// The verdict failed, or the log ends in the safe state.
    Failed,
    /// The report has no verdict (an older service) and nothing failed visibly.
    Unknown,
}

/// Everything [`draw`] draws, decided by [`prepare`].
#[derive(Debug, Clone, PartialEq)]
pub struct RunFigure {
    /// Figure title (rig, controller, outcome).
    pub title: String,
    /// The outcome.
    pub outcome: Outcome,
    /// The verdict line (`verdict: OK`, `verdict: FAILED: <first failure>`).
    pub verdict_line: String,
    /// Further lines under the title (tones, windows, lost samples, …).
    pub notes: Vec<String>,
    /// The time axis.
    pub timeline: Timeline,
    /// Plant time of the last logged sample, s.
    pub end_s: f64,
    /// One phase per plant session.
    pub phases: Vec<Phase>,
    /// The controller start of the first session that has one, s.
    pub controller_start_s: Option<f64>,
    /// The `z` channels.
    pub z: Vec<Channel>,
    /// The `u` channels.
    pub u: Vec<Channel>,
    /// The logged `theta_norm`, one value per row, if the controller logs it.
    pub theta_norm: Option<Vec<f64>>,
    /// Intervals to shade.
    pub intervals: Vec<Interval>,
    /// Starts of new plant sessions, s.
    pub new_sessions: Vec<f64>,
    /// The PSD windows.
    pub psd: PsdPlan,
}

/// The columns named `prefix` and digits (`z0`, `z1`, …), in channel order.
fn channels(log: &Log, prefix: char) -> Result<Vec<Channel>, RunFigureError> {
    let mut named: Vec<(u32, &String)> = log
        .names
        .iter()
        .filter_map(|n| {
            let digits = n.strip_prefix(prefix)?;
            (!digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit()))
                .then(|| digits.parse().ok().map(|k| (k, n)))
                .flatten()
        })
        .collect();
    named.sort();
    named
        .into_iter()
        .map(|(_, n)| {
            Ok(Channel {
                name: n.clone(),
                values: log.column(n)?.to_vec(),
            })
        })
        .collect()
}

/// Splits `text` into lines of at most about `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut out = vec![String::new()];
    for word in text.split(' ') {
        let cur = out.last_mut().map_or(0, |l| l.chars().count());
        if cur > 0 && cur + 1 + word.chars().count() > width {
            out.push(format!("    {word}"));
        } else if let Some(l) = out.last_mut() {
            if !l.is_empty() {
                l.push(' ');
            }
            l.push_str(word);
        }
    }
    out
}

/// The open-loop phase of every session (see the module docs) and notes on it.
fn phases(
    tl: &Timeline,
    status: Option<&[f64]>,
    events: &[Event],
    open_loop_s: f64,
    notes: &mut Vec<String>,
) -> Vec<Phase> {
    let ts = tl.sample_period;
    let open_bit = |r: usize| {
        status
            .and_then(|c| c.get(r))
            .is_some_and(|v| (*v as u32) & actuation_status::OPEN_LOOP != 0)
    };
    let first_sample = events.iter().find_map(|e| match e {
        Event::FirstSample { seq } => Some(*seq),
        _ => None,
    });
    let mut out = Vec::with_capacity(tl.sessions.len());
    let mut noted = false;
    for (k, ss) in tl.sessions.iter().enumerate() {
        // The first sample of the session as the service saw it (the log may start later).
        let start_seq = match ss.opened_by.and_then(|i| events.get(i)) {
            Some(Event::NewPlantSession { to, .. }) => *to,
            _ if k == 0 => first_sample.filter(|s| *s <= ss.seq0).unwrap_or(ss.seq0),
            _ => ss.seq0,
        };
        let nominal = ss.time_of(start_seq, ts) + open_loop_s;
        let last_open = ss.rows.clone().rev().find(|&r| open_bit(r));
        let (boundary, from_status) = match last_open {
            Some(lo) => (lo + 1, true),
            None if open_loop_s > 0.0 => {
                let b = ss.rows.clone().find(|&r| tl.t[r] >= nominal - 0.5 * ts);
                (b.unwrap_or(ss.rows.end), false)
            }
            None => (ss.rows.start, false),
        };
        let start = (boundary < ss.rows.end).then(|| tl.t[boundary]);
        if !noted && open_loop_s > 0.0 {
            if !from_status {
                notes.push(format!(
                    "no sample of session {} has the OPEN_LOOP status: its open-loop phase \
                     is placed from service.open-loop = {open_loop_s:.3} s",
                    k + 1
                ));
                noted = true;
            } else if let Some(s) = start
                && (s - nominal).abs() > 1.5 * ts * tl.stride as f64
            {
                notes.push(format!(
                    "the status bits put the controller start at {s:.3} s; service.open-loop \
                     = {open_loop_s:.3} s after the first sample gives {nominal:.3} s (the \
                     phase counts received samples: samples lost in it lengthen it)"
                ));
                noted = true;
            }
        }
        out.push(Phase {
            session: k,
            open_rows: ss.rows.start..boundary,
            closed_rows: boundary..ss.rows.end,
            controller_start_s: start,
            from_status,
        });
    }
    out
}

/// The `n` samples of session `session` at `seq = first, first + stride, …`, every `z`
/// channel, missing samples and non-finite values holding the previous value.
fn window(tl: &Timeline, session: usize, first: u64, n: usize, z: &[Channel]) -> PsdWindow {
    let ts = tl.sample_period;
    let stride = tl.stride;
    let ss = &tl.sessions[session];
    let mut logged = 0;
    let rows: Vec<Option<usize>> = (0..n as u64)
        .map(|i| {
            let seq = first + i * stride;
            let r = tl.row_at_or_before(session, seq);
            if r.is_some_and(|r| tl.seq[r] == seq) {
                logged += 1;
            }
            r
        })
        .collect();
    let z = z
        .iter()
        .map(|c| {
            let mut last = rows
                .iter()
                .flatten()
                .map(|&r| c.values[r])
                .find(|v| v.is_finite())
                .unwrap_or(0.0);
            rows.iter()
                .map(|r| {
                    if let Some(v) = r.map(|r| c.values[r]).filter(|v| v.is_finite()) {
                        last = v;
                    }
                    last
                })
                .collect()
        })
        .collect();
    PsdWindow {
        from_s: ss.time_of(first, ts),
        to_s: ss.time_of(first + n as u64 * stride, ts),
        samples: n,
        logged,
        z,
    }
}

/// The PSD windows of the module docs.
fn psd_plan(
    tl: &Timeline,
    phases: &[Phase],
    report: &ReportView,
    z: &[Channel],
    notes: &mut Vec<String>,
) -> PsdPlan {
    let step = tl.sample_period * tl.stride as f64;
    let (window_s, source) = match report
        .tones
        .as_ref()
        .and_then(|t| t.window_s)
        .filter(|w| w.is_finite() && *w > 0.0)
    {
        Some(w) => (w, "the report's tone window (tones.window_s)".to_string()),
        None => (
            DEFAULT_WINDOW_S,
            "the default window: the report has no tone window".to_string(),
        ),
    };
    let asked = ((window_s / step).round() as usize).clamp(1, MAX_WINDOW_SAMPLES);
    let stride = tl.stride;
    // (session, first seq of the phase, seq just after it)
    let open = phases
        .iter()
        .rev()
        .find(|p| !p.open_rows.is_empty())
        .map(|p| {
            let begin = tl.seq[p.open_rows.start];
            let end = if p.closed_rows.is_empty() {
                tl.seq[p.open_rows.end - 1] + stride
            } else {
                tl.seq[p.closed_rows.start]
            };
            (p.session, begin, end)
        });
    let closed = phases
        .last()
        .filter(|p| !p.closed_rows.is_empty())
        .map(|p| {
            (
                p.session,
                tl.seq[p.closed_rows.start],
                tl.seq[p.closed_rows.end - 1] + stride,
            )
        });
    let avail = |w: &Option<(usize, u64, u64)>| w.map(|(_, a, b)| ((b - a) / stride) as usize);
    let n = [Some(asked), avail(&open), avail(&closed)]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(0);
    if n < asked {
        notes.push(format!(
            "the PSD windows are shortened from {window_s:.3} s to {:.3} s: the {} is shorter",
            n as f64 * step,
            if avail(&open) == Some(n) {
                "open-loop phase"
            } else {
                "closed loop"
            }
        ));
    }
    let make = |w: Option<(usize, u64, u64)>| {
        w.filter(|_| n >= MIN_WINDOW_SAMPLES)
            .map(|(s, _, end)| window(tl, s, end - n as u64 * stride, n, z))
    };
    let (open, closed) = (make(open), make(closed));
    if open.is_none() {
        notes.push("no open-loop PSD: the run has no open-loop phase long enough".into());
    }
    if closed.is_none() {
        notes.push("no closed-loop PSD: the controller never acted long enough".into());
    }
    PsdPlan {
        window_s,
        source,
        samples: n,
        sample_rate_hz: 1.0 / step,
        segment: (n / 4).clamp(64, 8192).min(n),
        open,
        closed,
    }
}

/// Decides what the figure of a run says (see the module docs) from its report
/// (`report_origin` names the file in errors) and its signal log. Errors: no sample
/// period in the report, a log without `seq` or without any `z` column, bad sequence
/// numbers.
pub fn prepare(
    report: &ReportView,
    report_origin: &str,
    log: &Log,
) -> Result<RunFigure, RunFigureError> {
    let ts = report
        .sample_period()
        .ok_or_else(|| RunFigureError::NoSamplePeriod {
            origin: report_origin.into(),
        })?;
    let seq = log.column("seq")?;
    let t_ns = log.column("t_sample_ns").ok();
    let status = log.column("status").ok();
    let flags = log.column("flags").ok();
    let tl = Timeline::new(seq, t_ns, &report.events, ts, &log.origin)?;
    let z = channels(log, 'z')?;
    if z.is_empty() {
        return Err(RunFigureError::NoPerformance {
            origin: log.origin.clone(),
            columns: log.names.join(", "),
        });
    }
    let u = channels(log, 'u')?;
    let theta_norm = log.column("theta_norm").ok().map(<[f64]>::to_vec);
    let open_loop_s = report
        .open_loop_s
        .filter(|v| v.is_finite() && *v >= 0.0)
        .unwrap_or(0.0);
    let end_s = tl.end();
    let mut notes = Vec::new();
    let phases = phases(&tl, status, &report.events, open_loop_s, &mut notes);
    let controller_start_s = phases.iter().find_map(|p| p.controller_start_s);
    let intervals = tl.intervals(&report.events, status, flags);
    let new_sessions = tl.markers();
    let psd = psd_plan(&tl, &phases, report, &z, &mut notes);

    // The verdict.
    let last_safe = status
        .and_then(|c| c.last())
        .is_some_and(|v| (*v as u32) & actuation_status::SAFE_STATE != 0);
    let safe_since = intervals
        .iter()
        .rfind(|i| i.kind == IntervalKind::SafeState)
        .map_or(end_s, |i| i.from_s);
    let ended_safe = last_safe.then(|| {
        format!("signals.csv ends in the safe state (since {safe_since:.2} s): the last window is open loop")
    });
    let (outcome, verdict_line) = match (&report.verdict, ended_safe) {
        (Some(v), safe) if !v.ok => {
            let first = v
                .failures
                .first()
                .cloned()
                .or(safe)
                .unwrap_or_else(|| "no failure line".into());
            let more = match v.failures.len() {
                0 | 1 => String::new(),
                k => format!(" (and {} more)", k - 1),
            };
            (Outcome::Failed, format!("verdict: FAILED: {first}{more}"))
        }
        (Some(_), Some(safe)) => (
            Outcome::Failed,
            format!("verdict: FAILED: report.json says OK, but {safe}"),
        ),
        (Some(v), None) => (
            Outcome::Ok,
            match v.warnings.len() {
                0 => "verdict: OK".to_string(),
                k => format!(
                    "verdict: OK, {k} warning{}: {}",
                    if k == 1 { "" } else { "s" },
                    v.warnings.join("; ")
                ),
            },
        ),
        (None, Some(safe)) => (
            Outcome::Failed,
            format!("verdict: FAILED: {safe} (report.json has no verdict)"),
        ),
        (None, None) => (
            Outcome::Unknown,
            "verdict: unknown (report.json has no verdict)".to_string(),
        ),
    };
    let title = format!(
        "{}: {}: run {}",
        if report.rig.is_empty() {
            "run"
        } else {
            &report.rig
        },
        if report.controller.is_empty() {
            "controller ?"
        } else {
            &report.controller
        },
        match outcome {
            Outcome::Ok => "OK",
            Outcome::Failed => "FAILED",
            Outcome::Unknown => "(verdict unknown)",
        }
    );

    // Notes: the controller start, the tones, the windows, lost samples.
    let mut lines = Vec::new();
    lines.push(match phases.first() {
        Some(p) if !p.open_rows.is_empty() => match p.controller_start_s {
            Some(s) => format!(
                "open loop {:.3}–{s:.3} s (grey); the controller starts at {s:.3} s ({}; \
                 service.open-loop = {open_loop_s:.3} s)",
                tl.t[p.open_rows.start],
                if p.from_status {
                    "first sample after the OPEN_LOOP status"
                } else {
                    "placed from service.open-loop"
                }
            ),
            None => "the run ended in its open-loop phase: the controller never started".into(),
        },
        _ => "no open-loop phase: the controller acts from the first sample".into(),
    });
    if let Some(tones) = &report.tones {
        let db: Vec<f64> = tones
            .tones
            .iter()
            .filter_map(|t| t.suppression_db)
            .filter(|d| d.is_finite())
            .collect();
        if !db.is_empty() {
            let lo = db.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = db.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            lines.push(format!(
                "tones (report.json, fits over windows of {:.3} s): suppression {lo:.1} to \
                 {hi:.1} dB over {} tone{}{}",
                tones.window_s.unwrap_or(f64::NAN),
                db.len(),
                if db.len() == 1 { "" } else { "s" },
                if outcome == Outcome::Failed {
                    ", in a run that FAILED"
                } else {
                    ""
                }
            ));
        } else if let Some(e) = &tones.error {
            lines.push(format!("tones: could not be measured: {e}"));
        }
    }
    match (&psd.open, &psd.closed) {
        (o, c) if o.is_some() || c.is_some() => {
            let span = |w: &Option<PsdWindow>, what: &str| {
                w.as_ref()
                    .map(|w| format!("{what} {:.3}–{:.3} s", w.from_s, w.to_s))
            };
            let spans: Vec<String> = [span(o, "open loop"), span(c, "closed loop")]
                .into_iter()
                .flatten()
                .collect();
            lines.push(format!(
                "PSDs over equal windows of {} samples ({:.3} s, {}): {}; Welch, Hann \
                 segments of {} samples, 50 % overlap",
                psd.samples,
                psd.samples as f64 / psd.sample_rate_hz,
                psd.source,
                spans.join(", "),
                psd.segment
            ));
        }
        _ => {}
    }
    if tl.missing > 0 || report.log_dropped > 0 {
        lines.push(format!(
            "signals.csv: {} samples missing inside sessions (lost, not answered, or {} log \
             records dropped); every sample is placed at seq × T",
            tl.missing, report.log_dropped
        ));
    }
    if tl.stride > 1 {
        lines.push(format!(
            "signals.csv is decimated: one row every {} samples",
            tl.stride
        ));
    }
    lines.append(&mut notes);
    Ok(RunFigure {
        title,
        outcome,
        verdict_line,
        notes: lines,
        end_s,
        timeline: tl,
        phases,
        controller_start_s,
        z,
        u,
        theta_norm,
        intervals,
        new_sessions,
        psd,
    })
}

/// Reads `report.json` and `signals.csv` of the run folder `folder` and [`prepare`]s its
/// figure. Errors name the file at fault.
pub fn read(folder: &Path) -> Result<RunFigure, RunFigureError> {
    let report_path = folder.join("report.json");
    let origin = report_path.display().to_string();
    let text = match std::fs::read_to_string(&report_path) {
        Ok(text) => text,
        Err(source) => return Err(RunFigureError::ReadReport { origin, source }),
    };
    let report = ReportView::parse(&text, &origin)?;
    let log = crate::design::csvlog::read(&folder.join("signals.csv"))?;
    prepare(&report, &origin, &log)
}

/// Color of the shading of `kind`.
fn band_color(kind: IntervalKind) -> RGBColor {
    match kind {
        IntervalKind::SafeState => RGBColor(230, 0, 0),
        IntervalKind::PlantSilent => RGBColor(255, 160, 0),
        IntervalKind::PlantWatchdog => RGBColor(150, 60, 200),
        IntervalKind::SamplesLost => RGBColor(0, 90, 255),
        IntervalKind::AnswerMissed => RGBColor(255, 0, 200),
    }
}

/// Color of the PSD-window shading.
const WINDOW_COLOR: RGBColor = RGBColor(0, 170, 120);

/// Color of the new-session markers.
const SESSION_COLOR: RGBColor = RGBColor(150, 60, 200);

/// Color of channel `i` of all channels (z first, then u).
fn channel_color(i: usize) -> RGBColor {
    PALETTE[i % (PALETTE.len() - 1)]
}

/// Row ranges of `rows` split where `seq` jumps by more than 100 strides (silence, a
/// new session), so that no line is drawn across them; at most 64 pieces.
fn pieces(fig: &RunFigure, rows: Range<usize>) -> Vec<Range<usize>> {
    let tl = &fig.timeline;
    let gap = 100.0 * tl.sample_period * tl.stride as f64;
    let mut out = Vec::new();
    let mut start = rows.start;
    for r in rows.start + 1..rows.end {
        if tl.t[r] - tl.t[r - 1] > gap && out.len() < 63 {
            out.push(start..r);
            start = r;
        }
    }
    if start < rows.end {
        out.push(start..rows.end);
    }
    out
}

/// Lines of `values` over the row ranges `parts`, the first labelled `label`.
fn lines_of(
    fig: &RunFigure,
    values: &[f64],
    parts: &[Range<usize>],
    label: &str,
    color: RGBColor,
) -> Vec<Series> {
    let n = parts.len().max(1);
    let mut out = Vec::new();
    for r in parts {
        for piece in pieces(fig, r.clone()) {
            let points = envelope_xy(
                &fig.timeline.t[piece.clone()],
                &values[piece],
                (MAX_LINE_POINTS / n).max(200),
            );
            out.push(Series {
                label: if out.is_empty() {
                    label.to_string()
                } else {
                    String::new()
                },
                points,
                color,
                mark: Mark::Line,
            });
        }
    }
    out
}

/// A time-domain panel: the common time axis, the shaded intervals, the markers;
/// `windows` adds the PSD windows.
fn time_panel(fig: &RunFigure, title: String, y_label: String, windows: bool) -> Panel {
    let mut bands = Vec::new();
    let mut seen: Vec<IntervalKind> = Vec::new();
    for i in &fig.intervals {
        bands.push(Band {
            label: if seen.contains(&i.kind) {
                String::new()
            } else {
                seen.push(i.kind);
                i.kind.label().into()
            },
            from: i.from_s,
            to: i.to_s,
            color: band_color(i.kind),
        });
    }
    if windows {
        let ws: Vec<&PsdWindow> = [&fig.psd.open, &fig.psd.closed]
            .into_iter()
            .flatten()
            .collect();
        for (k, w) in ws.iter().enumerate() {
            bands.push(Band {
                label: if k == 0 {
                    format!("PSD windows ({:.3} s)", w.to_s - w.from_s)
                } else {
                    String::new()
                },
                from: w.from_s,
                to: w.to_s,
                color: WINDOW_COLOR,
            });
        }
    }
    let mut vlines = Vec::new();
    for (k, s) in fig
        .phases
        .iter()
        .filter(|p| !p.open_rows.is_empty())
        .filter_map(|p| p.controller_start_s)
        .enumerate()
    {
        vlines.push(VLine {
            label: if k == 0 {
                format!("controller starts, {s:.3} s")
            } else {
                String::new()
            },
            x: s,
            color: RGBColor(0, 0, 0),
        });
    }
    for (k, s) in fig.new_sessions.iter().enumerate() {
        vlines.push(VLine {
            label: if k == 0 {
                "new plant session".into()
            } else {
                String::new()
            },
            x: *s,
            color: SESSION_COLOR,
        });
    }
    let end = if fig.end_s > 0.0 {
        fig.end_s
    } else {
        fig.timeline.sample_period
    };
    Panel {
        title,
        x_label: "time (s)".into(),
        y_label,
        x_range: Some((0.0, end)),
        bands,
        vlines,
        ..Default::default()
    }
}

/// The PSD series, dB re 1 unit²/Hz, of channel `c` over `w`.
fn psd_series(
    fig: &RunFigure,
    w: &PsdWindow,
    c: usize,
    label: String,
    color: RGBColor,
) -> Result<Series, RunFigureError> {
    let p = analysis::psd(&w.z[c], fig.psd.sample_rate_hz, fig.psd.segment)?;
    Ok(Series {
        label,
        points: p
            .freq_hz
            .iter()
            .zip(&p.density)
            .filter(|(_, d)| **d > 0.0 && d.is_finite())
            .map(|(f, d)| (*f, 10.0 * d.log10()))
            .collect(),
        color,
        mark: Mark::Line,
    })
}

/// The [`time_panel`] of the channel `ch`, titled `({letter}) {what} {name}{note}` and
/// labelled with its name and the plant's units.
fn channel_panel(
    fig: &RunFigure,
    letter: Option<char>,
    (what, note): (&str, &str),
    ch: &Channel,
    windows: bool,
) -> Panel {
    time_panel(
        fig,
        format!("({}) {what} {}{note}", letter.unwrap_or('?'), ch.name),
        format!("{} ({PLANT_UNITS})", ch.name),
        windows,
    )
}

/// Draws `fig` into the PNG `path` (see the module docs).
pub fn draw(fig: &RunFigure, path: &Path) -> Result<(), RunFigureError> {
    let mut letter = (b'a'..=b'z').map(|c| c as char).cycle();
    let mut left = Vec::new();
    let n_z = fig.z.len();
    for (i, ch) in fig.z.iter().enumerate() {
        let color = channel_color(i);
        let mut p = channel_panel(
            fig,
            letter.next(),
            ("performance", ": open loop grey, closed loop in color"),
            ch,
            true,
        );
        let open: Vec<Range<usize>> = fig.phases.iter().map(|p| p.open_rows.clone()).collect();
        let closed: Vec<Range<usize>> = fig.phases.iter().map(|p| p.closed_rows.clone()).collect();
        for (rows, phase, c) in [
            (&open, "open loop", OPEN_COLOR),
            (&closed, "closed loop", color),
        ] {
            let label = format!("{} {phase}", ch.name);
            p.series.extend(lines_of(fig, &ch.values, rows, &label, c));
        }
        left.push(p);
    }
    let whole = 0..fig.timeline.t.len();
    let all = std::slice::from_ref(&whole);
    for (j, ch) in fig.u.iter().enumerate() {
        let mut p = channel_panel(
            fig,
            letter.next(),
            (
                "control input",
                " (the safe input in the open loop and the safe state)",
            ),
            ch,
            false,
        );
        p.series = lines_of(fig, &ch.values, all, &ch.name, channel_color(n_z + j));
        left.push(p);
    }
    let mut right = Vec::new();
    let mut theta = time_panel(
        fig,
        match &fig.theta_norm {
            Some(_) => format!(
                "({}) controller coefficients ‖θ‖",
                letter.next().unwrap_or('?')
            ),
            None => format!(
                "({}) controller coefficients: not logged by this controller",
                letter.next().unwrap_or('?')
            ),
        },
        "‖θ‖ (controller units)".into(),
        false,
    );
    if let Some(th) = &fig.theta_norm {
        theta.series = lines_of(fig, th, all, "‖θ‖", RGBColor(0, 0, 0));
    }
    right.push(theta);
    for (i, ch) in fig.z.iter().enumerate() {
        let mut series = Vec::new();
        if let Some(w) = &fig.psd.open {
            series.push(psd_series(
                fig,
                w,
                i,
                format!("open loop {:.2}–{:.2} s", w.from_s, w.to_s),
                OPEN_COLOR,
            )?);
        }
        if let Some(w) = &fig.psd.closed {
            series.push(psd_series(
                fig,
                w,
                i,
                format!("closed loop {:.2}–{:.2} s", w.from_s, w.to_s),
                channel_color(i),
            )?);
        }
        // At most 140 dB below the highest peak: a noise-free simulation has bins at
        // -300 dB that would flatten the rest.
        let (lo, hi) = series
            .iter()
            .flat_map(|s| s.points.iter().map(|p| p.1))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                (a.min(v), b.max(v))
            });
        let y_range = (hi.is_finite() && hi - lo > 140.0).then_some((hi - 140.0, hi + 5.0));
        right.push(Panel {
            y_range,
            title: format!(
                "({}) PSD of {}: equal windows of {:.3} s ({} samples), Welch L = {}",
                letter.next().unwrap_or('?'),
                ch.name,
                fig.psd.samples as f64 / fig.psd.sample_rate_hz,
                fig.psd.samples,
                fig.psd.segment
            ),
            x_label: "frequency (Hz)".into(),
            y_label: format!("PSD (dB re 1 ({PLANT_UNITS})²/Hz)"),
            x_range: Some((0.0, fig.psd.sample_rate_hz / 2.0)),
            series,
            ..Default::default()
        });
    }
    let verdict_color = match fig.outcome {
        Outcome::Ok => RGBColor(0, 120, 0),
        Outcome::Failed => RGBColor(200, 0, 0),
        Outcome::Unknown => RGBColor(160, 100, 0),
    };
    let mut notes: Vec<Note> = wrap(&fig.verdict_line, 170)
        .into_iter()
        .map(|text| Note {
            text,
            color: verdict_color,
        })
        .collect();
    for n in &fig.notes {
        notes.extend(wrap(n, 170).into_iter().map(|text| Note {
            text,
            color: RGBColor(0, 0, 0),
        }));
    }
    let rows = left.len().max(right.len()) as u32;
    let height = (60 + 22 * notes.len() as u32 + 300 * rows).clamp(1000, 4000);
    Ok(column_figure(
        path,
        &fig.title,
        &notes,
        &[left, right],
        (1600, height),
    )?)
}

/// Writes `run.png` into the run folder `folder` ([`read`], then [`draw`]) and returns
/// its path.
pub fn write(folder: &Path) -> Result<PathBuf, RunFigureError> {
    let fig = read(folder)?;
    let path = folder.join("run.png");
    draw(&fig, &path)?;
    Ok(path)
}
