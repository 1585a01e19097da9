//! The settings §4.5–4.7 leave open, and the chapter's claims (4.1–4.8) under each
//! alternative: the sensitivity table of `study mrac`.
//!
//! The chapter prints the plants (4.83)/(4.88), the reference models (4.84)/(4.89), the
//! controllers (`H`, `F`, `n`, `n_s`, `θ̂_0 = 0`, `R_θ = 10⁻⁵ I`, `λ = 1`), the commands,
//! the run length (200 steps, §4.5) and the metric (4.85), but not the grid of its maps,
//! what "became unstable" means, how "convergence" is read, or Example 3's disturbance
//! beyond its frequency. Each [`Change`] moves one of the study's choices (`*` below) to
//! an alternative, all else as the study runs it ([`RunSettings::STUDY`]):
//!
//! | choice | study | alternatives | why open | claims |
//! | --- | --- | --- | --- | --- |
//! | pole grid `N × N` | 15 × 15 | ⌈N/2⌉, 2N | "various values of ρ and ν" (§4.5–4.7); the figures' grid is not printed | 4.1–4.3, 4.5–4.8 |
//! | divergence limit on `\|y\|` | 10⁶ | 10⁴, 10⁸ | "became unstable" (Figures 4.8a–4.10a) has no rule | 4.1–4.7 |
//! | run length (instability and θ̂'s final value) | 200 steps | 1000 steps, (4.85) kept on 101–200 | 200 steps are printed (§4.5), but whether a run "became unstable" or converged may show only later | 4.1–4.8 |
//! | metric window | 101–200 | 1–200, 151–200 | printed (4.85); moved to show how much the medians rest on it | 4.1–4.3, 4.6, 4.7 |
//! | Example 3's disturbance `a cos(0.35k + φ)` | `a = 1`, `φ = 0` | `a = 0.5`, `a = 2`, `φ = −π/2` (a sine) | the frequency only (§4.7) | 4.5, 4.6 |
//! | band of θ̂'s settling | 10 % of its largest excursion | 5 %, 20 %, 10 % of `‖θ̂_K‖` | "convergence" (§4.6.2) is read off the θ̂ panels | 4.8 |
//! | what converges | θ̂ | `e_k` within 10 % of its largest excursion, within 10⁻³, within 10⁻⁶; ‖e‖ (4.85) itself | the same: "convergence" may be of the controller or of the error | 4.8 |
//! | where it is read | the grid's median | the b panels' pole `ρ = 0.5`, `ν = π/4` | the text speaks of Figure 4.11a and b together | 4.8 |
//! | `R_θ` | `10⁻⁵ I` | `10⁻¹ I`, `I`, `10 I`, `10² I`, `10⁵ I` (the last: `R_θ` read as `P_0`) | printed (`P_0 = R_θ⁻¹`, §2.2); moved to explain claim 4.8 (below) | 4.1–4.3, 4.5–4.8 |
//!
//! Each claim is judged by its own criterion ([`crate::study::mrac::summary`]) on the
//! statistics of the runs under the alternative (claim 4.4 only where the outward reading
//! is run again: the divergence limit and the run length). The criterion changes
//! (settling band, signal, ‖e‖ ratio) apply to the same runs; every other change runs
//! the grid again.
//!
//! # Why claim 4.8 fails, and the last rows
//!
//! With the printed `R_θ = 10⁻⁵ I` (`P_0 = 10⁵ I`) and no noise, RLS identifies the
//! ideal controller within a few steps on either plant (a few more than its `2n + n_s + 1`
//! coefficients): θ̂ is constant from about step 6 in Examples 1 and 2 alike, so no band,
//! reference or signal can make Example 2's convergence twice as slow. The `R_θ` rows ask
//! whether a slower estimator would show the chapter's "much slower": they are the
//! experiment that says which setting the chapter's figures would need, not a reading of
//! the printed one. (In the run of this change: from `R_θ = I` on, Example 2's θ̂ settles
//! two to four times later than Example 1's with the step, as Figure 4.11 says, but
//! earlier with the four-harmonic command at every `R_θ` tried, against Figure 4.13; so
//! no `R_θ` gives the three commands together. `docs/studies.md` has the numbers.)

use std::f64::consts::PI;

use rayon::prelude::*;

use crate::study::mrac::empty_squares::Reading as Squares;
use crate::study::mrac::grid::{self, Grid, GridPoint, PointRun, Sweep, SweepPlan};
use crate::study::mrac::outward::{self, OutwardPlan};
use crate::study::mrac::run_settings::{RunSettings, Signal};
use crate::study::mrac::setup::{CommandKind, Example, Method};
use crate::study::mrac::summary::{self, Claim, SweepStats, Verdict as MracVerdict, find};
use crate::study::mrac::theta_settling::Band;
use crate::study::mrac::{MracError, Options, SINGLE_POLE};
use crate::study::reproduction::sensitivity::{Alternative, Reading};

/// One alternative choice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Change {
    /// The study's choices.
    Study,
    /// An `N × N` pole grid ([`Grid::new`]).
    Grid(usize),
    /// Claim 4.8 read at the b panels' pole only ([`SINGLE_POLE`]).
    SinglePole,
    /// `|y_k|` above this marks a run as diverged.
    DivergenceLimit(f64),
    /// Runs this many steps ((4.85) kept on 101–200).
    RunLength(usize),
    /// (4.85) over `e_from … e_to`.
    MetricWindow(usize, usize),
    /// Example 3's disturbance amplitude.
    DisturbanceAmplitude(f64),
    /// Example 3's disturbance phase, rad.
    DisturbancePhase(f64),
    /// θ̂ settles within this band.
    ThetaBand(Band),
    /// Claim 4.8 read on the settling of `e_k` within this band.
    ErrorBand(Band),
    /// Claim 4.8 read on the median ‖e‖ (4.85) itself: Example 2's at least twice (step,
    /// four harmonics) or above (two) Example 1's.
    ErrorNorm,
    /// `R_θ = r · I` for every controller.
    RTheta(f64),
}

/// Every claim of the chapter.
const ALL: &[&str] = &["4.1", "4.2", "4.3", "4.4", "4.5", "4.6", "4.7", "4.8"];

impl Change {
    /// The choice it moves, as the table names it.
    pub fn choice(self) -> &'static str {
        match self {
            Change::Study => "the study's choices",
            Change::Grid(_) => "pole grid",
            Change::SinglePole => "where 4.8's convergence is read",
            Change::DivergenceLimit(_) => "divergence limit on |y|",
            Change::RunLength(_) => "run length",
            Change::MetricWindow(..) => "metric window (4.85)",
            Change::DisturbanceAmplitude(_) => "Example 3 disturbance amplitude",
            Change::DisturbancePhase(_) => "Example 3 disturbance phase",
            Change::ThetaBand(_) => "θ̂ settling band",
            Change::ErrorBand(_) | Change::ErrorNorm => "what converges (4.8)",
            Change::RTheta(_) => "R_θ",
        }
    }

    /// Why §4.5–4.7 leave it open.
    pub fn why_open(self) -> &'static str {
        match self {
            Change::Study => "",
            Change::Grid(_) => "\"various values of ρ and ν\": the figures' grid is not printed",
            Change::SinglePole => "the text reads Figure 4.11a and b together",
            Change::DivergenceLimit(_) => "\"became unstable\" (Figures 4.8a–4.10a) has no rule",
            Change::RunLength(_) => {
                "200 steps printed (§4.5); instability and convergence may show only later"
            }
            Change::MetricWindow(..) => "printed (4.85); moved to show the margin",
            Change::DisturbanceAmplitude(_) | Change::DisturbancePhase(_) => {
                "only the frequency is given (§4.7)"
            }
            Change::ThetaBand(_) | Change::ErrorBand(_) | Change::ErrorNorm => {
                "\"convergence\" (§4.6.2) has no rule"
            }
            Change::RTheta(_) => "printed (P_0 = R_θ⁻¹); moved to explain claim 4.8",
        }
    }

    /// The study's value of the choice it moves, with the study's grid `n`.
    pub fn ours(self, n: usize) -> String {
        let s = RunSettings::STUDY;
        match self {
            Change::Study => "–".into(),
            Change::Grid(_) => format!("{n} × {n}"),
            Change::SinglePole => "the grid's median".into(),
            Change::DivergenceLimit(_) => format!("{:e}", s.divergence_limit),
            Change::RunLength(_) => format!("{} steps", s.steps),
            Change::MetricWindow(..) => format!("{}–{}", s.metric_from, s.metric_to),
            Change::DisturbanceAmplitude(_) => format!("{}", s.disturbance.0),
            Change::DisturbancePhase(_) => format!("{} rad", s.disturbance.1),
            Change::ThetaBand(_) => s.settle_band.text(),
            Change::ErrorBand(_) | Change::ErrorNorm => {
                format!("{} within {}", s.settle_signal.name(), s.settle_band.text())
            }
            Change::RTheta(_) => format!("{:e} I", s.r_theta),
        }
    }

    /// Its value, as text.
    pub fn value(self) -> String {
        match self {
            Change::Study => "–".into(),
            Change::Grid(m) => format!("{m} × {m}"),
            Change::SinglePole => "ρ = 0.5, ν = π/4".into(),
            Change::DivergenceLimit(l) => format!("{l:e}"),
            Change::RunLength(k) => format!("{k} steps"),
            Change::MetricWindow(a, b) => format!("{a}–{b}"),
            Change::DisturbanceAmplitude(a) => format!("{a}"),
            Change::DisturbancePhase(p) => format!("{p:.4} rad"),
            Change::ThetaBand(b) => b.text(),
            Change::ErrorBand(b) => format!("{} within {}", Signal::Error.name(), b.text()),
            Change::ErrorNorm => "‖e‖ (4.85)".into(),
            Change::RTheta(r) => format!("{r:e} I"),
        }
    }

    /// The claims it bears on (module documentation).
    pub fn claims(self) -> &'static [&'static str] {
        match self {
            Change::Study => ALL,
            Change::Grid(_) | Change::RTheta(_) => {
                &["4.1", "4.2", "4.3", "4.5", "4.6", "4.7", "4.8"]
            }
            Change::DivergenceLimit(_) => &["4.1", "4.2", "4.3", "4.4", "4.5", "4.6", "4.7"],
            Change::RunLength(_) => ALL,
            Change::MetricWindow(..) => &["4.1", "4.2", "4.3", "4.6", "4.7"],
            Change::DisturbanceAmplitude(_) | Change::DisturbancePhase(_) => &["4.5", "4.6"],
            Change::SinglePole
            | Change::ThetaBand(_)
            | Change::ErrorBand(_)
            | Change::ErrorNorm => &["4.8"],
        }
    }

    /// The run settings under this change.
    pub fn settings(self) -> RunSettings {
        let s = RunSettings::STUDY;
        match self {
            Change::Study | Change::Grid(_) | Change::SinglePole | Change::ErrorNorm => s,
            Change::DivergenceLimit(l) => RunSettings {
                divergence_limit: l,
                ..s
            },
            Change::RunLength(k) => RunSettings { steps: k, ..s },
            Change::MetricWindow(a, b) => RunSettings {
                metric_from: a,
                metric_to: b,
                ..s
            },
            Change::DisturbanceAmplitude(a) => RunSettings {
                disturbance: (a, s.disturbance.1),
                ..s
            },
            Change::DisturbancePhase(p) => RunSettings {
                disturbance: (s.disturbance.0, p),
                ..s
            },
            Change::ThetaBand(b) => RunSettings {
                settle_band: b,
                ..s
            },
            Change::ErrorBand(b) => RunSettings {
                settle_signal: Signal::Error,
                settle_band: b,
                ..s
            },
            Change::RTheta(r) => RunSettings { r_theta: r, ..s },
        }
    }

    /// The pole grid under this change, the study's being `n × n`.
    pub fn grid(self, n: usize) -> Result<Grid, MracError> {
        match self {
            Change::Grid(m) => Ok(Grid::new(m)?),
            Change::SinglePole => Ok(Grid {
                rho: vec![SINGLE_POLE.0],
                nu: vec![SINGLE_POLE.1],
            }),
            _ => Ok(Grid::new(n)?),
        }
    }

    /// Whether claim 4.4's outward reading runs again under it.
    fn reruns_outward(self) -> bool {
        matches!(self, Change::DivergenceLimit(_) | Change::RunLength(_))
    }

    /// Whether it is read on the study's own runs (no simulation).
    fn reads_the_study(self) -> bool {
        matches!(self, Change::Study | Change::ErrorNorm)
    }
}

/// The alternatives for the study's grid `n × n` (module documentation).
pub fn alternatives(n: usize) -> Vec<Change> {
    vec![
        Change::Study,
        Change::Grid(n.div_ceil(2)),
        Change::Grid(2 * n),
        Change::DivergenceLimit(1e4),
        Change::DivergenceLimit(1e8),
        Change::RunLength(1000),
        Change::MetricWindow(1, 200),
        Change::MetricWindow(151, 200),
        Change::DisturbanceAmplitude(0.5),
        Change::DisturbanceAmplitude(2.0),
        Change::DisturbancePhase(-PI / 2.0),
        Change::ThetaBand(Band::OfExcursion(0.05)),
        Change::ThetaBand(Band::OfExcursion(0.2)),
        Change::ThetaBand(Band::OfFinal(0.1)),
        Change::ErrorBand(Band::OfExcursion(0.1)),
        Change::ErrorBand(Band::Absolute(1e-3)),
        Change::ErrorBand(Band::Absolute(1e-6)),
        Change::ErrorNorm,
        Change::SinglePole,
        Change::RTheta(1e-1),
        Change::RTheta(1e0),
        Change::RTheta(1e1),
        Change::RTheta(1e2),
        Change::RTheta(1e5),
    ]
}

/// What the study found under its own choices: the input of the study's row and of the
/// criterion changes read on its runs.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Per case, the grid statistics.
    pub stats: Vec<SweepStats>,
    /// The empty squares inside the unit circle.
    pub inside: Option<Squares>,
    /// The empty squares of the outward reading, when run.
    pub outward: Option<Squares>,
    /// The claims.
    pub claims: Vec<Claim>,
}

/// One row of the sensitivity table: a change and what the study's claims say under it.
#[derive(Debug, Clone)]
pub struct Row {
    /// The change from the study's choices.
    pub change: Change,
    /// What the runs under it gave.
    pub evaluation: Evaluation,
}

/// The pairs `(APPC, RC-MRAC)` of Example 2 among `sweeps`, per command.
fn example_2_pairs(sweeps: &[Sweep]) -> Vec<(&Sweep, &Sweep)> {
    CommandKind::ALL
        .iter()
        .filter_map(|&c| {
            let get = |m| {
                sweeps
                    .iter()
                    .find(|s| s.example == Example::Two && s.command == c && s.method == m)
            };
            Some((get(Method::Appc)?, get(Method::RcMrac)?))
        })
        .collect()
}

/// The cases `change` needs among those of `options`: claim 4.8 alone needs RC-MRAC on
/// Examples 1 and 2.
fn cases(change: Change, options: &Options) -> Vec<(Example, CommandKind, Method)> {
    let only_4_8 = change.claims() == ["4.8"];
    options
        .cases()
        .into_iter()
        .filter(|&(e, _, m)| {
            !only_4_8 || (m == Method::RcMrac && matches!(e, Example::One | Example::Two))
        })
        .collect()
}

/// The runs of one change: its sweeps and, for 4.4, the outward reading again.
#[derive(Debug, Clone, PartialEq)]
pub struct ChangeRuns {
    /// The sweeps inside the unit circle.
    pub inside: Vec<SweepPlan>,
    /// The outward reading, when it runs again.
    pub outward: Option<Vec<OutwardPlan>>,
}

impl ChangeRuns {
    /// The runs of `change` (its grid, settings and, for 4.4, the outward reading).
    pub fn of(change: Change, options: &Options) -> Result<Self, MracError> {
        let grid = change.grid(options.grid)?;
        let settings = change.settings();
        let inside = cases(change, options)
            .into_iter()
            .map(|(e, c, m)| SweepPlan {
                settings,
                ..SweepPlan::chapter(e, c, m, &grid)
            })
            .collect();
        let outward = match options.outward {
            Some(o) if change.reruns_outward() && options.examples.contains(&Example::Two) => {
                let commands: Vec<CommandKind> = CommandKind::ALL
                    .into_iter()
                    .filter(|c| options.commands.contains(c))
                    .collect();
                Some(outward::plans(&o, &commands, &settings))
            }
            _ => None,
        };
        Ok(Self { inside, outward })
    }

    /// The sweep plans, inside then outward.
    fn sweep_plans(&self) -> Vec<SweepPlan> {
        let mut v = self.inside.clone();
        if let Some(o) = &self.outward {
            v.extend(outward::sweep_plans(o));
        }
        v
    }

    /// Every run, in order.
    pub fn items(&self) -> Vec<PointRun> {
        grid::items(&self.sweep_plans())
    }

    /// The claims checked on the runs' `results` (in the order of [`Self::items`]).
    pub fn evaluation(
        &self,
        mut results: Vec<Result<GridPoint, String>>,
    ) -> Result<Evaluation, MracError> {
        let n_inside = grid::items(&self.inside).len();
        let rest = results.split_off(n_inside.min(results.len()));
        let sweeps = grid::assemble(&self.inside, results)?;
        let stats: Vec<SweepStats> = sweeps.iter().map(SweepStats::of).collect();
        let inside = Squares::of("inside the unit circle", &example_2_pairs(&sweeps))?;
        let outward = match &self.outward {
            Some(plans) => {
                let sw = outward::assemble(plans, rest)?;
                let only: Vec<Sweep> = sw.into_iter().map(|s| s.sweep).collect();
                let pairs: Vec<(&Sweep, &Sweep)> = only
                    .chunks(2)
                    .filter_map(|p| match p {
                        [a, r] => Some((a, r)),
                        _ => None,
                    })
                    .collect();
                Some(Squares::of("outward", &pairs)?)
            }
            None => None,
        };
        let claims = summary::claims(&stats, Some(&inside), outward.as_ref());
        Ok(Evaluation {
            stats,
            inside: Some(inside),
            outward,
            claims,
        })
    }
}

/// One alternative of [`alternatives`] and its runs (`None`: read on the study's own
/// runs).
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// The change.
    pub change: Change,
    /// Its runs.
    pub runs: Option<ChangeRuns>,
}

/// The alternatives of [`alternatives`] for `options`, with their runs.
pub fn plan(options: &Options) -> Result<Vec<Plan>, MracError> {
    alternatives(options.grid)
        .into_iter()
        .map(|change| {
            Ok(Plan {
                change,
                runs: if change.reads_the_study() {
                    None
                } else {
                    Some(ChangeRuns::of(change, options)?)
                },
            })
        })
        .collect()
}

/// Every run of `plans`, one alternative after the other (the items of the study's
/// `sensitivity` stage).
pub fn items(plans: &[Plan]) -> Vec<PointRun> {
    plans
        .iter()
        .filter_map(|p| p.runs.as_ref())
        .flat_map(ChangeRuns::items)
        .collect()
}

/// The rows of `plans` from their runs' `results` (in the order of [`items`]), the
/// study's own row and the criterion changes read on `study`, what the study found.
pub fn rows(
    plans: &[Plan],
    results: Vec<Result<GridPoint, String>>,
    study: &Evaluation,
) -> Result<Vec<Row>, MracError> {
    let mut results = results.into_iter();
    plans
        .iter()
        .map(|p| {
            let evaluation = match &p.runs {
                None => study.clone(),
                Some(r) => {
                    let n = r.items().len();
                    r.evaluation(results.by_ref().take(n).collect())?
                }
            };
            Ok(Row {
                change: p.change,
                evaluation,
            })
        })
        .collect()
}

/// Runs `change` here (its grid, settings and, for 4.4, the outward reading) and checks
/// the claims on it.
#[cfg(test)]
fn evaluate(change: Change, options: &Options) -> Result<Evaluation, MracError> {
    let runs = ChangeRuns::of(change, options)?;
    let results = runs.items().par_iter().map(PointRun::record).collect();
    runs.evaluation(results)
}

/// Runs every alternative of [`alternatives`] for `options` here (the study's own row and
/// the criterion changes read on `study`, what the study found).
pub fn run(options: &Options, study: &Evaluation) -> Result<Vec<Row>, MracError> {
    let plans = plan(options)?;
    let results = items(&plans).par_iter().map(PointRun::record).collect();
    rows(&plans, results, study)
}

/// `log₁₀` value for text: `inf` for `+∞`.
fn lg(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "inf".into()
    }
}

/// A median settling step for text: `never` for `+∞`.
fn step(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "never".into()
    }
}

/// The medians of `method` on `example` per command, if all were run.
fn medians(stats: &[SweepStats], example: Example, method: Method) -> Option<Vec<f64>> {
    CommandKind::ALL
        .iter()
        .map(|&c| find(stats, example, c, method).map(|s| s.median))
        .collect()
}

/// Claim 4.8 on the median ‖e‖ (4.85): per command whether Example 2's is slower by the
/// claim's factor, and the ratios as text; `None` when a case was not run.
pub fn error_norm_reading(stats: &[SweepStats]) -> Option<(bool, String)> {
    let mut ok = true;
    let mut parts = Vec::new();
    for c in CommandKind::ALL {
        let n = find(stats, Example::Two, c, Method::RcMrac)?;
        let m = find(stats, Example::One, c, Method::RcMrac)?;
        let (a, b) = (10f64.powf(n.median), 10f64.powf(m.median));
        ok &= summary::is_slower(a, b, c);
        parts.push(format!("{} {:.2}", c.name(), a / b));
    }
    Some((
        ok,
        format!("‖e‖ Example 2 / Example 1: {}", parts.join(", ")),
    ))
}

/// The numbers behind claim `id` under `row`, short.
fn measured(id: &str, row: &Row) -> String {
    let ev = &row.evaluation;
    let st = &ev.stats;
    let spread = |e, m| {
        medians(st, e, m).map_or("-".into(), |v| {
            let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
            lg(hi - lo)
        })
    };
    let versus = |e: Example, commands: &[CommandKind]| {
        commands
            .iter()
            .map(|&c| {
                let m = |method| find(st, e, c, method).map_or(f64::NAN, |s| s.median);
                format!(
                    "{} {} vs {}",
                    c.name(),
                    lg(m(Method::RcMrac)),
                    lg(m(Method::Appc))
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    match id {
        "4.1" => format!(
            "spread RC-MRAC vs APPC: Ex. 1 {} vs {}, Ex. 2 {} vs {}",
            spread(Example::One, Method::RcMrac),
            spread(Example::One, Method::Appc),
            spread(Example::Two, Method::RcMrac),
            spread(Example::Two, Method::Appc)
        ),
        "4.2" => format!(
            "RC-MRAC vs APPC: {}",
            versus(Example::One, &CommandKind::ALL)
        ),
        "4.3" => format!(
            "RC-MRAC vs APPC: {}",
            versus(Example::Two, &[CommandKind::Step, CommandKind::Two])
        ),
        "4.4" => {
            let only = |r: &Option<Squares>| {
                r.as_ref().map_or("-".into(), |r| {
                    r.commands
                        .iter()
                        .map(|c| c.appc_only.to_string())
                        .collect::<Vec<_>>()
                        .join("/")
                })
            };
            format!(
                "APPC-only unstable step/two/four: inside {}, outward {}",
                only(&ev.inside),
                only(&ev.outward)
            )
        }
        "4.5" => {
            let rc = st.iter().filter(|s| s.method == Method::RcMrac);
            let (u, p) = rc.fold((0, 0), |a, s| (a.0 + s.unstable, a.1 + s.points));
            format!("RC-MRAC unstable {u} of {p}")
        }
        "4.6" => {
            let get = |m| find(st, Example::Three, CommandKind::Step, m);
            match (get(Method::RcMrac), get(Method::RcMracPlain)) {
                (Some(r), Some(p)) => format!(
                    "n=4 {} (unstable {}) vs n=2 {}",
                    lg(r.median),
                    r.unstable,
                    lg(p.median)
                ),
                _ => "-".into(),
            }
        }
        "4.7" => [Example::One, Example::Two]
            .iter()
            .map(|&e| {
                medians(st, e, Method::Appc).map_or("-".into(), |v| {
                    format!(
                        "Ex. {} {}",
                        e.number(),
                        v.iter().map(|x| lg(*x)).collect::<Vec<_>>().join(" > ")
                    )
                })
            })
            .collect::<Vec<_>>()
            .join("; "),
        "4.8" if row.change == Change::ErrorNorm => {
            error_norm_reading(st).map_or("-".into(), |(_, t)| t)
        }
        "4.8" => {
            let parts: Vec<String> = CommandKind::ALL
                .iter()
                .map(|&c| {
                    let s = |e| find(st, e, c, Method::RcMrac).map_or(f64::NAN, |s| s.theta_settle);
                    format!(
                        "{} {} vs {}",
                        c.name(),
                        step(s(Example::Two)),
                        step(s(Example::One))
                    )
                })
                .collect();
            format!("median settling step Ex. 2 vs 1: {}", parts.join(", "))
        }
        _ => String::new(),
    }
}

/// The verdict of claim `id` under `row` by its own criterion (`None`: not checked, its
/// runs were not made).
fn verdict(id: &str, row: &Row) -> Option<bool> {
    if id == "4.8" && row.change == Change::ErrorNorm {
        return error_norm_reading(&row.evaluation.stats).map(|(ok, _)| ok);
    }
    // Claim 4.4 under an alternative only where its outward reading ran again.
    if id == "4.4" && row.change != Change::Study && row.evaluation.outward.is_none() {
        return None;
    }
    let number: u8 = id.strip_prefix("4.")?.parse().ok()?;
    let c = row.evaluation.claims.iter().find(|c| c.number == number)?;
    match c.verdict {
        MracVerdict::Pass => Some(true),
        MracVerdict::Fail => Some(false),
        MracVerdict::NotChecked => None,
    }
}

/// The sensitivity rows of the study ([`crate::study::reproduction::sensitivity`]), the
/// study's grid being `n × n`: each alternative with the verdicts of the claims it bears
/// on (those whose runs were made).
pub fn record(rows: &[Row], n: usize) -> Vec<Alternative> {
    rows.iter()
        .map(|row| {
            let readings = row
                .change
                .claims()
                .iter()
                .filter_map(|id| verdict(id, row).map(|ok| Reading::of(id, ok, measured(id, row))))
                .collect();
            Alternative::new(
                row.change.choice(),
                row.change.why_open(),
                row.change.ours(n),
                row.change.value(),
                readings,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn options(grid: usize) -> Options {
        let mut o = Options::parse("all", "all", grid).expect("valid");
        o.outward = None;
        o.figures = false;
        o
    }

    #[test]
    fn each_alternative_moves_one_setting_and_the_studys_row_moves_none() {
        let v = alternatives(15);
        assert_eq!(v[0], Change::Study);
        assert_eq!(v.iter().filter(|c| **c == Change::Study).count(), 1);
        assert!(v.contains(&Change::Grid(8)) && v.contains(&Change::Grid(30)));
        for c in &v {
            let s = c.settings();
            let moved = [
                s.steps != RunSettings::STUDY.steps,
                (s.metric_from, s.metric_to)
                    != (RunSettings::STUDY.metric_from, RunSettings::STUDY.metric_to),
                s.divergence_limit != RunSettings::STUDY.divergence_limit,
                (s.settle_signal, s.settle_band)
                    != (
                        RunSettings::STUDY.settle_signal,
                        RunSettings::STUDY.settle_band,
                    ),
                s.r_theta != RunSettings::STUDY.r_theta,
                s.disturbance != RunSettings::STUDY.disturbance,
            ]
            .iter()
            .filter(|m| **m)
            .count();
            let criterion_or_grid = matches!(
                c,
                Change::Study | Change::Grid(_) | Change::SinglePole | Change::ErrorNorm
            );
            assert_eq!(moved, usize::from(!criterion_or_grid), "{c:?}");
            if *c != Change::Study {
                assert_ne!(c.value(), c.ours(15), "{c:?}");
            }
            assert!(!c.claims().is_empty());
        }
        assert_eq!(Change::Study.value(), Change::Study.ours(15));
    }

    #[test]
    fn a_change_reaches_the_runs_and_the_claims_are_read_on_them() {
        // A 2 × 2 grid, no outward reading: a divergence limit of 1 stops every run whose
        // |y| passes 1 (the commands' responses do), and the claims see it.
        let o = options(2);
        let study = evaluate(Change::Study, &o).expect("runs");
        let low = evaluate(Change::DivergenceLimit(1.0), &o).expect("runs");
        let unstable = |e: &Evaluation| e.stats.iter().map(|s| s.unstable).sum::<usize>();
        assert_eq!(unstable(&study), 0);
        assert!(unstable(&low) > 0);
        let row = Row {
            change: Change::DivergenceLimit(1.0),
            evaluation: low,
        };
        assert_eq!(verdict("4.5", &row), Some(false));
        assert!(measured("4.5", &row).starts_with("RC-MRAC unstable "));
        assert!(!measured("4.5", &row).starts_with("RC-MRAC unstable 0 "));
        // No outward reading: claim 4.4 is not read.
        let rec = record(std::slice::from_ref(&row), 2);
        assert!(rec[0].readings.iter().all(|r| r.claim != "4.4"));
        // The study's row: 4.5 holds, 0 unstable of 14 cases × 4 points.
        let row = Row {
            change: Change::Study,
            evaluation: study,
        };
        assert_eq!(verdict("4.5", &row), Some(true));
        assert_eq!(measured("4.5", &row), "RC-MRAC unstable 0 of 28");
    }

    #[test]
    fn the_criterion_changes_read_claim_4_8_with_their_own_rule() {
        let o = options(2);
        let theta = evaluate(Change::Study, &o).expect("runs");
        let error = evaluate(Change::ErrorBand(Band::Absolute(1e-6)), &o).expect("runs");
        // Only the RC-MRAC cases of Examples 1 and 2 run for a 4.8-only change.
        assert_eq!(error.stats.len(), 6);
        assert!(error.stats.iter().all(|s| s.method == Method::RcMrac));
        let settle = |e: &Evaluation| {
            find(&e.stats, Example::One, CommandKind::Step, Method::RcMrac)
                .expect("run")
                .theta_settle
        };
        // e_k to within 1e-6 settles later than θ̂ to within 10 % of its excursion.
        assert!(
            settle(&error) > settle(&theta),
            "{} {}",
            settle(&error),
            settle(&theta)
        );
        // The ‖e‖ reading is the ratio of the medians of (4.85).
        let (_, text) = error_norm_reading(&theta.stats).expect("all cases");
        let m = |e| {
            find(&theta.stats, e, CommandKind::Step, Method::RcMrac)
                .expect("run")
                .median
        };
        let ratio = 10f64.powf(m(Example::Two) - m(Example::One));
        assert!(text.contains(&format!("step {ratio:.2}")), "{text}");
        let single = evaluate(Change::SinglePole, &o).expect("runs");
        assert!(single.stats.iter().all(|s| s.points == 1));
    }
}
