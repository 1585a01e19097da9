//! The driver of the two RCAC studies of chapter 3 (`rcac-siso`, §3.3.1, and `rcac-miso`,
//! §3.3.2): both design dereverberated target models, sweep a family of plants in
//! parallel, draw one error-plane figure per method and update law (Figures 3.5/3.8 and
//! 3.12/3.15), and show one single run per method and update law with its Bode plot
//! (Figures 3.6/3.7, 3.9/3.10, 3.13/3.14 and 3.16/3.17).
//!
//! A study ([`RcacStudy`]) says only what is its own: its plants and where the sweep goes
//! ([`RcacStudy::setup`]), its designs, texts, figures and summary. [`run`] does the rest in
//! this order:
//!
//! 1. the header and the designs (written to the report by the study; deterministic and
//!    cheap, so every shard of a sharded study makes them again);
//! 2. the runs, handed to [`Runs`] in stages whose items ([`PointRun`]) depend only on the
//!    options:
//!    - `sweep-gradient` and/or `sweep-rls`: every sweep point
//!      ([`RcacStudy::sweep_points`]) with that update law: the open loop, then per DTM the
//!      error `G_f / G_{zu,d}` at each tone (`θ_j` of channel `j`, [`tone_errors`]) and one
//!      closed-loop run ([`run_closed`]), recorded as [`Measured`];
//!    - unless `--no-sensitivity`, `sensitivity` ([`sensitivity_items`]): a coarse subset
//!      of the sweep ([`RcacStudy::sensitivity_points`]) and the single runs' point, with
//!      the gradient update, under each alternative of [`RcacStudy::sensitivity_changes`];
//! 3. [`Runs::gather`] (a shard ends here, having written nothing but its run log); then
//!    the designs' files, the sweep's [`Row`]s (per point, method and update law), the CSV
//!    files, the error-plane figures, the single runs (run here, with their traces);
//! 4. the study's summary; unless `--no-sensitivity`, the sensitivity table
//!    ([`sensitivity`]): the claims checked under each alternative ([`sensitivity_table`]),
//!    written to `sensitivity.csv` and the report;
//! 5. the time taken, the report printed and written to `summary.txt`;
//! 6. the chapter's claims ([`RcacStudy::claims`]) written to `claims.json`
//!    ([`crate::study::reproduction`]), with the sensitivity rows.
//!
//! `N` is the number of tones, one per input channel: the tone `θ_j` of channel `j`
//! (output 0, input `j`) is measured in `z_0`.

use crate::file_error::{FileError, FileOp};
use crate::study::rcac::RcacError;
use std::borrow::Cow;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use crate::design::C64;
use crate::design::model::DiscreteModel;
use crate::design::target_response::TargetResponse;
use crate::plot::{Panel, figure};
use crate::study::common::files::write;
use crate::study::rcac::common::{
    Dtm, Method, Point, RUN_SECONDS, TS, Update, Window, model_error, rcac_params, run_closed,
    run_open, single_run_figure,
};
use crate::study::rcac::sensitivity::{self, Change};
use crate::study::reproduction::sensitivity::Alternative;
use crate::study::reproduction::{self, Claim};
use crate::study::shard::{Runs, ShardError};
use control::tones::suppression_db;
use plant_proxy::scenario::Scenario;
use serde::{Deserialize, Serialize};

const PI: f64 = std::f64::consts::PI;

/// Options of a study.
#[derive(Debug, Clone)]
pub struct Options {
    /// Sweep points: per case (`rcac-siso`), or damping values (`rcac-miso`).
    pub points: usize,
    /// Update laws to run.
    pub updates: Vec<Update>,
    /// Run the sensitivity table ([`sensitivity`]; `--no-sensitivity` turns it off).
    pub sensitivity: bool,
}

/// One point of a study: the plant that runs, the model the errors of `G_f` are taken
/// against, the target models and the tones.
#[derive(Debug, Clone)]
pub struct Setup<'d, const N: usize> {
    /// The scenario that runs (plant and disturbance).
    pub scenario: Scenario,
    /// `G_{zu,d}` of the plant that runs.
    pub model: Cow<'d, DiscreteModel>,
    /// The target models RCAC runs with, one per method.
    pub dtms: &'d [(Method, Dtm)],
    /// The tone of each input channel, rad/sample.
    pub thetas: [f64; N],
}

/// One sweep point with one DTM and one update law.
#[derive(Debug, Clone)]
pub struct Row<At, const N: usize> {
    /// Where in the sweep.
    pub at: At,
    /// The method of the target model.
    pub method: Method,
    /// The update law.
    pub update: Update,
    /// Per input channel `j`: `(magnitude error dB, phase error °)` of `G_f` at `θ_j`.
    pub error: [(f64, f64); N],
    /// Open-loop amplitude of each tone in `z`.
    pub open_amp: [f64; N],
    /// Closed-loop amplitude of each tone on the last window (NaN when diverged).
    pub closed_amp: [f64; N],
    /// The same on the window before.
    pub closed_amp_prev: [f64; N],
    /// Open-loop peak `|z|` on the window.
    pub open_peak: f64,
    /// Closed-loop peak `|z|` on the last window (NaN when diverged).
    pub closed_peak: f64,
    /// Stayed finite, bounded, no guard reset.
    pub finite: bool,
    /// Settling time after RCAC starts, s (see `common::Point::settle`).
    pub settle: Option<f64>,
}

impl<At, const N: usize> Row<At, N> {
    /// Suppression of tone `j`, dB (−∞ when diverged).
    pub fn suppression(&self, j: usize) -> f64 {
        if self.finite {
            suppression_db(self.open_amp[j], self.closed_amp[j])
        } else {
            f64::NEG_INFINITY
        }
    }

    /// The smallest suppression over the tones, dB (−∞ when diverged).
    pub fn worst_suppression(&self) -> f64 {
        (1..N).fold(self.suppression(0), |m, j| m.min(self.suppression(j)))
    }

    /// Whether the row is a run with the DTM of `method` and the update law `update`.
    pub fn is(&self, method: Method, update: Update) -> bool {
        self.method == method && self.update == update
    }

    /// Suppression of the peak `|z|` on the window, dB (−∞ when diverged).
    pub fn peak_suppression(&self) -> f64 {
        if self.finite {
            suppression_db(self.open_peak, self.closed_peak)
        } else {
            f64::NEG_INFINITY
        }
    }
}

/// The dissertation's figure numbers of one method in chapter 3: the error plane (its
/// number within the chapter), then the Bode plot and the single run, which follow it.
#[derive(Debug, Clone, Copy)]
pub struct FigureNumbers {
    /// The error plane's number within chapter 3 (5 for Figure 3.5).
    pub plane_number: u8,
}

impl FigureNumbers {
    /// The error plane over the sweep (e.g. "3.5").
    pub fn plane(self) -> String {
        format!("3.{}", self.plane_number)
    }

    /// The Bode plot of `G_{zu,d}` and `G_f` (e.g. "3.6").
    pub fn bode(self) -> String {
        format!("3.{}", self.plane_number + 1)
    }

    /// The single run (e.g. "3.7").
    pub fn run(self) -> String {
        format!("3.{}", self.plane_number + 2)
    }
}

/// What a study's error-plane figures say beside their panels: the parts of the title
/// (`{structure}, {DTM with β}{dtm_from}, RCAC {update}: {shows}`), the panel layout and
/// the size.
#[derive(Debug, Clone, Copy)]
pub struct PlaneFigure {
    /// The plant structure, first in the title (`(3.50)`).
    pub structure: &'static str,
    /// What follows the DTM in the title (` from ζ = 0.1`, or nothing).
    pub dtm_from: &'static str,
    /// What the panels show, last in the title.
    pub shows: &'static str,
    /// `(rows, columns)` of panels.
    pub layout: (usize, usize),
    /// `(width, height)`, pixels.
    pub size: (u32, u32),
}

impl PlaneFigure {
    /// The title of the figure of `method` and `update`.
    pub fn title(&self, method: Method, update: Update) -> String {
        format!(
            "{}, {}{}, RCAC {}: {}",
            self.structure,
            method.label_with_beta(),
            self.dtm_from,
            update.name(),
            self.shows
        )
    }
}

/// The responses of a Bode plot of the single runs, channel by channel
/// (`[channel][frequency]`).
#[derive(Debug, Clone, Copy)]
pub struct Bode<'a> {
    /// The method of the target model.
    pub method: Method,
    /// The target model.
    pub dtm: &'a Dtm,
    /// The frequencies, Hz.
    pub hz: &'a [f64],
    /// `G_{zu,d}` of the single runs' plant.
    pub g: &'a [Vec<C64>],
    /// `G_f` of the target model.
    pub gf: &'a [Vec<C64>],
    /// `G_f / G_{zu,d}`.
    pub ratio: &'a [Vec<C64>],
}

/// What a single run measured, for its report line and figure title.
#[derive(Debug, Clone, Copy)]
pub struct SingleRun<'a, const N: usize> {
    /// The method of the target model.
    pub method: Method,
    /// The update law.
    pub update: Update,
    /// Per input channel: `(magnitude error dB, phase error °)` of `G_f` at its tone.
    pub error: [(f64, f64); N],
    /// Suppression of each tone, dB (−∞ where it was not measured).
    pub suppression: [f64; N],
    /// The closed loop's measurements on the late windows.
    pub closed: &'a Window,
    /// Settling time after RCAC starts, s.
    pub settle: Option<f64>,
}

/// What a single run achieved, for the claims.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleOutcome<const N: usize> {
    /// The method of the target model.
    pub method: Method,
    /// The update law.
    pub update: Update,
    /// Stayed finite, bounded, no guard reset.
    pub finite: bool,
    /// Suppression of each tone, dB (−∞ when diverged).
    pub suppression: [f64; N],
}

/// What one RCAC study of chapter 3 has of its own; [`run`] drives it.
pub trait RcacStudy<const N: usize>: Sync {
    /// Where a sweep point lies (a case and a tone frequency, a damping ratio); its `Debug`
    /// text names the point (a sharded run's identity, [`PointRun`]).
    type At: Copy + Send + Sync + std::fmt::Debug;
    /// The target models and whatever else is designed once before the sweep.
    type Designs: Sync;

    /// The study's `study` subcommand.
    const NAME: &'static str;
    /// The figures of each claim ([`crate::study::reproduction::with_figures`]).
    const CLAIM_FIGURES: crate::study::reproduction::Figures;
    /// Step factor `α` of `μ_Exp` (3.63).
    const ALPHA: f64;
    /// Whether the time line of the report gives the time of the designs.
    const REPORTS_DESIGN_TIME: bool;
    /// The number within chapter 3 of the error-plane figure of the windowed-average and of
    /// the optimization DTM (in the order of [`Method::ALL`]; [`FigureNumbers`]).
    const FIGURES: [u8; 2];
    /// The error-plane figures' titles, layout and size.
    const PLANE: PlaneFigure;

    /// Writes the report's first lines: the study and its settings.
    fn header(&self, points: usize, report: &mut String);

    /// Designs the target models (and writes them to the report). Deterministic and cheap:
    /// every shard designs them again before its runs.
    fn design(&self, report: &mut String) -> Result<Self::Designs, RcacError>;

    /// Writes the files of the designs into `out` (after the runs are gathered: a shard
    /// writes no output).
    fn write_design(&self, out: &Path) -> Result<(), RcacError> {
        let _ = out;
        Ok(())
    }

    /// The sweep of `points` points (per case).
    fn sweep_points(&self, points: usize) -> Vec<Self::At>;

    /// The plant, model, target models and tones of the sweep point `at`.
    fn setup<'d>(
        &self,
        designs: &'d Self::Designs,
        at: Self::At,
    ) -> Result<Setup<'d, N>, RcacError>;

    /// The sweep point of the single runs.
    fn single_at(&self) -> Self::At;

    /// Writes the sweep's CSV files into `out`.
    fn write_csv(&self, out: &Path, rows: &[Row<Self::At, N>]) -> Result<(), RcacError>;

    /// The panels of the error-plane figure of `method` and `update` over the sweep (see
    /// `common::error_plane_panel`).
    fn plane_panels(
        &self,
        designs: &Self::Designs,
        rows: &[Row<Self::At, N>],
        method: Method,
        update: Update,
    ) -> Result<Vec<Panel>, RcacError>;

    /// The report line of the single runs' open loop.
    fn single_open_line(&self, open: &Window) -> String;

    /// Draws the Bode plot of the single runs' plant and a target model into `path`.
    fn bode_figure(&self, path: &Path, bode: &Bode<'_>) -> Result<(), RcacError>;

    /// What the report says of a single run after its method and update law.
    fn single_line(&self, run: &SingleRun<'_, N>) -> String;

    /// The title of a single run's figure.
    fn single_title(&self, run: &SingleRun<'_, N>) -> String;

    /// Writes the sweep's summary tables to the report.
    fn summary(&self, rows: &[Row<Self::At, N>], updates: &[Update], report: &mut String);

    /// The coarse subset of the sweep the sensitivity table reads the sweep claims on.
    fn sensitivity_points(&self) -> Vec<Self::At>;

    /// The alternatives of the sensitivity table ([`sensitivity::shared`] unless the study
    /// has its own).
    fn sensitivity_changes(&self) -> Vec<Change> {
        sensitivity::shared()
    }

    /// The chapter's claims checked on the sweep `rows` and the single runs `singles`.
    fn claims(
        &self,
        rows: &[Row<Self::At, N>],
        singles: &[SingleOutcome<N>],
        updates: &[Update],
    ) -> Vec<Claim>;
}

/// Samples per run and per measurement window under the study's choices.
fn steps_and_window() -> (usize, usize) {
    Change::Study.steps_and_window()
}

/// The figure numbers of `method` in study `S`.
fn figure_numbers<S: RcacStudy<N>, const N: usize>(method: Method) -> FigureNumbers {
    match method {
        Method::Average => FigureNumbers {
            plane_number: S::FIGURES[0],
        },
        Method::Optimize => FigureNumbers {
            plane_number: S::FIGURES[1],
        },
    }
}

/// RCAC with `dtm` and `update` (step factor `alpha`) against the plant of `s`, measured
/// against the open-loop peak `reference`, `(steps, window)` samples; `every > 0` keeps the
/// trace with `θ` recorded every that many samples.
fn rcac_run<const N: usize>(
    s: &Setup<'_, N>,
    dtm: &Dtm,
    (update, alpha): (Update, f64),
    reference: f64,
    (steps, window): (usize, usize),
    every: usize,
) -> Result<Point, RcacError> {
    run_closed(
        &s.scenario,
        &rcac_params(&dtm.target, update, alpha),
        steps,
        window,
        &s.thetas,
        reference,
        every > 0,
        every,
    )
}

/// `(magnitude error dB, phase error °)` of `G_f` against `model` for each channel
/// `j = 0 … N−1` (output 0, input `j`) at its tone `thetas[j]` (rad/sample).
pub fn tone_errors<const N: usize>(
    model: &DiscreteModel,
    dtm: &Dtm,
    thetas: &[f64; N],
) -> Result<[(f64, f64); N], RcacError> {
    let g = model.frf(thetas)?;
    let gf = dtm.target.frf(thetas);
    Ok(std::array::from_fn(|j| {
        model_error(g.response[j][j], gf.response[j][j])
    }))
}

/// The study (see the module docs); writes into `out` and prints the summary. Its runs
/// are handed to `runs` in stages whose items depend only on `opts` ([`PointRun`]): one
/// stage of the sweep per update law (`sweep-gradient`, `sweep-rls`) and, unless
/// `--no-sensitivity`, the sensitivity table's runs (`sensitivity`); the designs are made
/// before them (by every shard), the single runs and everything written after
/// [`Runs::gather`].
pub fn run<S: RcacStudy<N>, const N: usize>(
    study: &S,
    runs: &Runs,
    out: &Path,
    opts: &Options,
) -> Result<(), RcacError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out).map_err(|source| FileError::new(FileOp::Access, out, source))?;
    let mut report = String::new();
    study.header(opts.points, &mut report);
    let designs = study.design(&mut report)?;
    let t_design = t0.elapsed().as_secs_f64();
    let sweep = study.sweep_points(opts.points);
    let t1 = Instant::now();
    let sweep_stages = opts
        .updates
        .iter()
        .map(|&update| {
            let items: Vec<PointRun<S::At>> = sweep
                .iter()
                .map(|&at| PointRun {
                    at,
                    update,
                    change: Change::Study,
                })
                .collect();
            runs.map(&format!("sweep-{}", update.name()), &items, |r| {
                point_runs(study, &designs, r)
            })
        })
        .collect::<Result<Vec<_>, ShardError>>()?;
    let t_sweep = t1.elapsed().as_secs_f64();
    let t_sens_runs = Instant::now();
    let sensitivity_items = if opts.sensitivity {
        sensitivity_items(study)
    } else {
        Vec::new()
    };
    let sensitivity_stage = if opts.sensitivity {
        Some(runs.map("sensitivity", &sensitivity_items, |r| {
            point_runs(study, &designs, r)
        })?)
    } else {
        None
    };
    let t_sens_runs = t_sens_runs.elapsed().as_secs_f64();
    runs.gather()?;
    study.write_design(out)?;
    let per_update = sweep_stages
        .into_iter()
        .map(|stage| stage.into_vec())
        .collect::<Result<Vec<_>, ShardError>>()?;
    let rows = sweep_rows(&sweep, &opts.updates, per_update)?;
    study.write_csv(out, &rows)?;
    let t2 = Instant::now();
    for method in Method::ALL {
        for &update in &opts.updates {
            let panels = study.plane_panels(&designs, &rows, method, update)?;
            figure(
                &out.join(format!(
                    "figure-{}-{}-{}.png",
                    figure_numbers::<S, N>(method).plane(),
                    method.name(),
                    update.name()
                )),
                &S::PLANE.title(method, update),
                S::PLANE.layout,
                S::PLANE.size,
                &panels,
            )?;
        }
    }
    let singles = single_runs(study, out, &designs, &opts.updates, &mut report)?;
    let t_fig = t2.elapsed().as_secs_f64();
    study.summary(&rows, &opts.updates, &mut report);
    let t3 = Instant::now();
    let sensitivity_rows = if let Some(stage) = sensitivity_stage {
        let rows = sensitivity_table(study, &sensitivity_items, stage.into_vec()?)?;
        write(
            &out.join("sensitivity.csv"),
            &reproduction::sensitivity::csv(&rows),
        )?;
        report_sensitivity(&rows, &mut report);
        rows
    } else {
        Vec::new()
    };
    let t_sens = t_sens_runs + t3.elapsed().as_secs_f64();
    let designs_time = if S::REPORTS_DESIGN_TIME {
        format!("designs {t_design:.1} s, ")
    } else {
        String::new()
    };
    let _ = writeln!(
        report,
        "\ntime: {designs_time}sweep {t_sweep:.1} s ({} runs of {} steps, {} threads), figures and single runs {t_fig:.1} s, sensitivity {t_sens:.1} s, total {:.1} s; files in {}",
        sweep.len() * (1 + Method::ALL.len() * opts.updates.len()),
        (RUN_SECONDS / TS).round(),
        rayon::current_num_threads(),
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    print!("{report}");
    write(&out.join("summary.txt"), &report)?;
    let update = match opts.updates.as_slice() {
        [one] => one.name(),
        _ => "both",
    };
    Ok(reproduction::write(
        out,
        &reproduction::Claims {
            study: S::NAME.into(),
            chapter: 3,
            run: format!(
                "study {} --points {} --update {update}{}",
                S::NAME,
                opts.points,
                if opts.sensitivity {
                    ""
                } else {
                    " --no-sensitivity"
                }
            ),
            claims: {
                let mut c = reproduction::with_figures(
                    study.claims(&rows, &singles, &opts.updates),
                    S::CLAIM_FIGURES,
                );
                reproduction::sensitivity::annotate(&mut c, &sensitivity_rows);
                c
            },
            sensitivity: sensitivity_rows,
        },
    )?)
}

/// The runs of the sensitivity table ([`sensitivity`]): per alternative of the study
/// ([`RcacStudy::sensitivity_changes`]), the sweep's coarse subset
/// ([`RcacStudy::sensitivity_points`]) and then the single runs' point, with the gradient
/// update.
pub fn sensitivity_items<S: RcacStudy<N>, const N: usize>(study: &S) -> Vec<PointRun<S::At>> {
    let points = study.sensitivity_points();
    let single_at = study.single_at();
    study
        .sensitivity_changes()
        .into_iter()
        .flat_map(|change| {
            points
                .iter()
                .copied()
                .chain(std::iter::once(single_at))
                .map(move |at| PointRun {
                    at,
                    update: Update::Gradient,
                    change,
                })
        })
        .collect()
}

/// The sensitivity table ([`sensitivity`]) from the runs `measured` of `items`
/// ([`sensitivity_items`]): per alternative, the claims checked on the sweep's coarse subset
/// and the single runs.
pub fn sensitivity_table<S: RcacStudy<N>, const N: usize>(
    study: &S,
    items: &[PointRun<S::At>],
    measured: Vec<Recorded>,
) -> Result<Vec<Alternative>, RcacError> {
    let gradient = [Update::Gradient];
    // Per alternative: the subset's points, then the single runs' point.
    let per_change = study.sensitivity_points().len() + 1;
    let measured = measured
        .into_iter()
        .collect::<Result<Vec<_>, String>>()
        .map_err(RcacError::Run)?;
    items
        .chunks(per_change)
        .zip(measured.chunks(per_change))
        .map(|(items, measured)| {
            let mut rows: Vec<Vec<Row<S::At, N>>> = items
                .iter()
                .zip(measured)
                .map(|(r, m)| m.iter().map(|m| m.row(r.at, r.update)).collect::<Vec<_>>())
                .collect();
            let change = items[0].change;
            let single = rows.pop().unwrap_or_default();
            let singles: Vec<SingleOutcome<N>> = single
                .iter()
                .map(|r| SingleOutcome {
                    method: r.method,
                    update: r.update,
                    finite: r.finite,
                    suppression: std::array::from_fn(|j| r.suppression(j)),
                })
                .collect();
            let rows: Vec<Row<S::At, N>> = rows.into_iter().flatten().collect();
            Ok(sensitivity::row(
                change,
                &study.claims(&rows, &singles, &gradient),
            ))
        })
        .collect()
}

/// The sensitivity table in the report: one line per alternative and claim, then per
/// claim how many alternatives keep it.
fn report_sensitivity(rows: &[Alternative], report: &mut String) {
    let _ = writeln!(
        report,
        "\nsensitivity (sensitivity.csv; gradient update, single runs and a coarse subset of the sweep):"
    );
    for row in rows {
        for r in &row.readings {
            let _ = writeln!(
                report,
                "  {:<32} {:<12} {:<4} {:<4} {}",
                row.setting,
                row.shown_value(),
                r.claim,
                r.verdict.word(),
                r.measured
            );
        }
    }
    let _ = writeln!(
        report,
        "  PASS over the alternatives (the study's own row not counted): {}",
        reproduction::sensitivity::tally_text(rows)
    );
}

/// One sharded run set's item: a sweep point, run with one update law under one change
/// ([`Change::Study`] for the study's own). Its `Debug` text is the run's identity.
#[derive(Debug, Clone, Copy)]
pub struct PointRun<At> {
    /// Where in the sweep.
    pub at: At,
    /// The update law.
    pub update: Update,
    /// The study's choices or an alternative.
    pub change: Change,
}

/// What the runs of a [`PointRun`] measured with the DTM of one method: a [`Row`] without
/// its point and update law (the item's), per tone as a list (what a shard records).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Measured {
    /// The method of the target model.
    pub method: Method,
    /// [`Row::error`].
    pub error: Vec<(f64, f64)>,
    /// [`Row::open_amp`].
    pub open_amp: Vec<f64>,
    /// [`Row::closed_amp`].
    pub closed_amp: Vec<f64>,
    /// [`Row::closed_amp_prev`].
    pub closed_amp_prev: Vec<f64>,
    /// [`Row::open_peak`].
    pub open_peak: f64,
    /// [`Row::closed_peak`].
    pub closed_peak: f64,
    /// [`Row::finite`].
    pub finite: bool,
    /// [`Row::settle`].
    pub settle: Option<f64>,
}

/// A [`PointRun`]'s result: per method what it measured, or why it failed (the message).
pub type Recorded = Result<Vec<Measured>, String>;

impl Measured {
    /// The row of this method at `at` with `update`.
    pub fn row<At, const N: usize>(&self, at: At, update: Update) -> Row<At, N> {
        let per_tone = |v: &[f64]| -> [f64; N] {
            std::array::from_fn(|j| v.get(j).copied().unwrap_or(f64::NAN))
        };
        Row {
            at,
            method: self.method,
            update,
            error: std::array::from_fn(|j| {
                self.error.get(j).copied().unwrap_or((f64::NAN, f64::NAN))
            }),
            open_amp: per_tone(&self.open_amp),
            closed_amp: per_tone(&self.closed_amp),
            closed_amp_prev: per_tone(&self.closed_amp_prev),
            open_peak: self.open_peak,
            closed_peak: self.closed_peak,
            finite: self.finite,
            settle: self.settle,
        }
    }
}

/// Runs the sweep point of `r` under its change with its update law: the open loop and one
/// closed loop per method.
pub fn point_runs<S: RcacStudy<N>, const N: usize>(
    study: &S,
    designs: &S::Designs,
    r: &PointRun<S::At>,
) -> Recorded {
    point_runs_of(study, designs, r).map_err(|e| e.to_string())
}

fn point_runs_of<S: RcacStudy<N>, const N: usize>(
    study: &S,
    designs: &S::Designs,
    &PointRun { at, update, change }: &PointRun<S::At>,
) -> Result<Vec<Measured>, RcacError> {
    let mut s = study.setup(designs, at)?;
    change.apply(&mut s.scenario);
    let (steps, window) = change.steps_and_window();
    let (open, _) = run_open(&s.scenario, steps, window, &s.thetas)?;
    let per_tone = |v: &[f64]| -> Vec<f64> {
        (0..N)
            .map(|j| v.get(j).copied().unwrap_or(f64::NAN))
            .collect()
    };
    let mut measured = Vec::new();
    for (method, dtm) in s.dtms {
        let dtm = change.dtm(*method, dtm);
        let error = tone_errors(&s.model, &dtm, &s.thetas)?;
        let p = rcac_run(&s, &dtm, (update, S::ALPHA), open.peak, (steps, window), 0)?;
        let finite = p.finite();
        let w = p.closed.unwrap_or_default();
        measured.push(Measured {
            method: *method,
            error: error.to_vec(),
            open_amp: per_tone(&open.amp),
            closed_amp: per_tone(&w.amp),
            closed_amp_prev: per_tone(&w.amp_prev),
            open_peak: open.peak,
            closed_peak: if finite { w.peak } else { f64::NAN },
            finite,
            settle: p.settle,
        });
    }
    Ok(measured)
}

/// The sweep's rows from the runs of each update law (`per_update[u][point]`, in the order
/// of `updates`): per point, per method, per update law.
fn sweep_rows<At: Copy, const N: usize>(
    sweep: &[At],
    updates: &[Update],
    per_update: Vec<Vec<Recorded>>,
) -> Result<Vec<Row<At, N>>, RcacError> {
    let per_update = per_update
        .into_iter()
        .map(|runs| runs.into_iter().collect::<Result<Vec<_>, String>>())
        .collect::<Result<Vec<_>, String>>()
        .map_err(RcacError::Run)?;
    let mut rows = Vec::new();
    for (p, &at) in sweep.iter().enumerate() {
        let methods = per_update.first().map_or(0, |u| u[p].len());
        for m in 0..methods {
            for (runs, &update) in per_update.iter().zip(updates) {
                rows.push(runs[p][m].row(at, update));
            }
        }
    }
    Ok(rows)
}

/// Runs one sweep point under `change` ([`Change::Study`] for the study's own): the open
/// loop and every method × update, as the sweep's rows.
pub fn sweep_point<S: RcacStudy<N>, const N: usize>(
    study: &S,
    designs: &S::Designs,
    at: S::At,
    updates: &[Update],
    change: Change,
) -> Result<Vec<Row<S::At, N>>, RcacError> {
    let per_update = updates
        .iter()
        .map(|&update| vec![point_runs(study, designs, &PointRun { at, update, change })])
        .collect();
    sweep_rows(&[at], updates, per_update)
}

/// The single runs at [`RcacStudy::single_at`]: per method the Bode plot, per update law
/// the run's report line and figure; returns what each achieved.
fn single_runs<S: RcacStudy<N>, const N: usize>(
    study: &S,
    out: &Path,
    designs: &S::Designs,
    updates: &[Update],
    report: &mut String,
) -> Result<Vec<SingleOutcome<N>>, RcacError> {
    let mut outcomes = Vec::new();
    let s = study.setup(designs, study.single_at())?;
    let (steps, window) = steps_and_window();
    let (open_w, open) = run_open(&s.scenario, steps, window, &s.thetas)?;
    let _ = writeln!(report, "{}", study.single_open_line(&open_w));
    let grid: Vec<f64> = crate::design::grid(1e-3 * PI, PI, 2000, true)?;
    let hz: Vec<f64> = grid.iter().map(|t| t / (2.0 * PI * TS)).collect();
    let g = s.model.frf(&grid)?;
    for (method, dtm) in s.dtms {
        let gf = dtm.target.frf(&grid);
        let ratio: Vec<Vec<C64>> = (0..N)
            .map(|j| {
                gf.response[j]
                    .iter()
                    .zip(&g.response[j])
                    .map(|(a, b)| a / b)
                    .collect()
            })
            .collect();
        let numbers = figure_numbers::<S, N>(*method);
        study.bode_figure(
            &out.join(format!(
                "figure-{}-{}-bode.png",
                numbers.bode(),
                method.name()
            )),
            &Bode {
                method: *method,
                dtm,
                hz: &hz,
                g: &g.response,
                gf: &gf.response,
                ratio: &ratio,
            },
        )?;
        let error = tone_errors(&s.model, dtm, &s.thetas)?;
        for &update in updates {
            let every = 10;
            let p = rcac_run(
                &s,
                dtm,
                (update, S::ALPHA),
                open_w.peak,
                steps_and_window(),
                every,
            )?;
            let Some(closed) = p.trace.as_ref().filter(|_| p.finite()) else {
                outcomes.push(SingleOutcome {
                    method: *method,
                    update,
                    finite: false,
                    suppression: [f64::NEG_INFINITY; N],
                });
                let _ = writeln!(
                    report,
                    "  {:<22} {:<8}: diverged (no figure)",
                    method.label(),
                    update.name()
                );
                continue;
            };
            let w = p.closed.clone().unwrap_or_default();
            let run = SingleRun {
                method: *method,
                update,
                error,
                suppression: std::array::from_fn(|j| {
                    w.amp
                        .get(j)
                        .map_or(f64::NEG_INFINITY, |a| suppression_db(open_w.amp[j], *a))
                }),
                closed: &w,
                settle: p.settle,
            };
            outcomes.push(SingleOutcome {
                method: *method,
                update,
                finite: true,
                suppression: run.suppression,
            });
            let _ = writeln!(
                report,
                "  {:<22} {:<8}: {}",
                method.label(),
                update.name(),
                study.single_line(&run)
            );
            single_run_figure(
                &out.join(format!(
                    "figure-{}-{}-{}.png",
                    numbers.run(),
                    method.name(),
                    update.name()
                )),
                study.single_title(&run),
                &open,
                closed,
                every,
            )?;
        }
    }
    Ok(outcomes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::rcac::miso::Miso;
    use crate::study::rcac::siso::{Siso, SweepAt};

    #[test]
    fn each_change_reaches_the_runs_of_a_sweep_point() {
        let study = Siso;
        let designs = study.design(&mut String::new()).expect("designs");
        let at = SweepAt {
            case: 0,
            wd: 10.0 * PI,
        };
        let g = [Update::Gradient];
        let rows = |c| sweep_point(&study, &designs, at, &g, c).expect("runs");
        let study_rows = rows(Change::Study);
        assert_eq!(study_rows.len(), Method::ALL.len());
        for c in sensitivity::shared().into_iter().skip(1) {
            let moved = rows(c);
            // Every change moves the measured closed-loop tone of the average DTM's run.
            assert_ne!(moved[0].closed_amp[0], study_rows[0].closed_amp[0], "{c:?}");
        }
        // The noise reaches the open loop as well.
        let noisy = rows(Change::Noise(0.1));
        assert_ne!(noisy[0].open_amp[0], study_rows[0].open_amp[0]);
    }

    #[test]
    fn a_recorded_run_reads_back_bit_for_bit_and_rows_go_per_point_method_and_update() {
        let m = |method, x: f64| Measured {
            method,
            error: vec![(x, -x)],
            open_amp: vec![1.0],
            closed_amp: vec![f64::NAN],
            closed_amp_prev: vec![f64::INFINITY],
            open_peak: 2.0,
            closed_peak: f64::NAN,
            finite: false,
            settle: Some(0.1 + 0.2),
        };
        let runs =
            |x: f64| -> Recorded { Ok(vec![m(Method::Average, x), m(Method::Optimize, x + 0.5)]) };
        let recorded = vec![runs(1.0), Err("a failed run".to_string())];
        let back: Vec<Recorded> =
            postcard::from_bytes(&postcard::to_stdvec(&recorded).expect("encodes"))
                .expect("decodes");
        assert_eq!(format!("{back:?}"), format!("{recorded:?}"));
        let Ok(b) = &back[0] else { panic!("a run") };
        assert_eq!(
            b[0].settle.map(f64::to_bits),
            Some((0.1_f64 + 0.2).to_bits())
        );
        assert!(b[0].closed_amp[0].is_nan());
        // Two points, two update laws: per point, per method, per update law.
        let updates = [Update::Gradient, Update::Rls];
        let per_update = vec![vec![runs(1.0), runs(2.0)], vec![runs(10.0), runs(20.0)]];
        let rows: Vec<Row<u8, 1>> = sweep_rows(&[7, 8], &updates, per_update).expect("rows");
        let got: Vec<(u8, Method, Update, f64)> = rows
            .iter()
            .map(|r| (r.at, r.method, r.update, r.error[0].0))
            .collect();
        use Method::{Average as A, Optimize as O};
        use Update::{Gradient as G, Rls as R};
        assert_eq!(
            got,
            vec![
                (7, A, G, 1.0),
                (7, A, R, 10.0),
                (7, O, G, 1.5),
                (7, O, R, 10.5),
                (8, A, G, 2.0),
                (8, A, R, 20.0),
                (8, O, G, 2.5),
                (8, O, R, 20.5),
            ]
        );
        // A failed run's message is the study's error.
        let failed = sweep_rows::<u8, 1>(&[7, 8], &[G], vec![recorded]);
        assert_eq!(
            failed.err().map(|e| e.to_string()).as_deref(),
            Some("a failed run")
        );
    }

    #[test]
    fn the_sensitivity_runs_are_per_alternative_the_subset_then_the_single_point() {
        let study = Miso;
        let items = sensitivity_items(&study);
        let per = study.sensitivity_points().len() + 1;
        assert_eq!(items.len(), study.sensitivity_changes().len() * per);
        for (chunk, change) in items.chunks(per).zip(study.sensitivity_changes()) {
            assert!(
                chunk
                    .iter()
                    .all(|r| r.change == change && r.update == Update::Gradient)
            );
            assert_eq!(chunk[per - 1].at, study.single_at());
        }
    }

    #[test]
    fn the_average_dtms_beta_moves_only_the_average_dtm() {
        let study = Miso;
        let designs = study.design(&mut String::new()).expect("designs");
        let s = study.setup(&designs, 0.1).expect("setup");
        for (method, dtm) in s.dtms {
            let moved = Change::AverageBeta(0.8).dtm(*method, dtm);
            let e0 = tone_errors(&s.model, dtm, &s.thetas).expect("errors");
            let e1 = tone_errors(&s.model, &moved, &s.thetas).expect("errors");
            match method {
                // 20 log10(0.8) dB on every channel's magnitude error, the phase kept.
                Method::Average => {
                    for j in 0..2 {
                        assert!((e1[j].0 - e0[j].0 - 20.0 * 0.8_f64.log10()).abs() < 1e-9);
                        assert!((e1[j].1 - e0[j].1).abs() < 1e-9);
                    }
                }
                Method::Optimize => assert_eq!(e0, e1),
            }
        }
    }
}
