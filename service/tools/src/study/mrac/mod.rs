//! `study mrac`: chapter 4, APPC against RC-MRAC on the examples of §4.5–4.7 (Figures
//! 4.2–4.14), with the kernels of `control::mrac` on plant-proxy's difference equations.
//!
//! For each example, command and method ([`crate::study::mrac::setup`]) it sweeps the
//! plant poles over the grid of [`crate::study::mrac::grid`] (one 200-step run per point,
//! [`crate::study::mrac::closed_loop`]), runs the response at `ρ = 0.5`, `ν = π/4`, and checks the
//! chapter's claims ([`crate::study::mrac::summary`]). It writes into `--out`:
//!
//! - `grid.csv`: `example, command, method, rho, nu, e_norm, unstable, diverged_at,
//!   peak_y` ([`grid::write_csv`]);
//! - `single-ex{e}-{command}-{method}.csv`: `k, r, y, y_m, e, u` and `θ̂_k` (named as
//!   [`crate::study::mrac::setup::theta_names`]) of the run at `ρ = 0.5`, `ν = π/4`;
//! - `map-ex{e}-{command}-{method}.png`: the heat map ([`figures::heat_map`]);
//! - `single-ex{e}-{command}-{method}.png`: the four panels
//!   ([`figures::single_run`]);
//! - with Example 2 and the outward reading on (the default; [`outward`]):
//!   `grid-outward.csv` (the outward grid past the unit circle and the patch around the
//!   zero, [`outward::write_csv`]) and `map-outward-ex2-{command}-{method}.png`;
//! - `summary.md`: the summary table, the single runs, the outward reading, the claims
//!   and the sensitivity table;
//! - `sensitivity.csv`: the sensitivity of the claims to each setting the chapter leaves
//!   open ([`sensitivity`], unless `--no-sensitivity`): one line per alternative and
//!   claim, `setting, ours, value, claim, verdict, measured`
//!   ([`crate::study::reproduction::sensitivity::csv`]);
//! - `claims.json`: the claims in the reproduction's record ([`claims`]), with the
//!   sensitivity rows.
//!
//! Its runs ([`crate::study::shard`]): three sharded stages whose items (one run at one
//! pole, naming example, command, method, `ρ`, `ν` and the run's settings) follow from the
//! options alone: `grid` (every case over the grid), `outward` (the outward reading) and
//! `sensitivity` (every simulated alternative). After [`crate::study::shard::Runs::gather`]
//! come the single runs at `ρ = 0.5`, `ν = π/4`, the files and the claims.

pub mod claims;
pub mod closed_loop;
pub mod empty_squares;
pub mod figures;
pub mod grid;
pub mod outward;
pub mod run_settings;
pub mod sensitivity;
pub mod setup;
pub mod summary;
pub mod theta_settling;

use crate::file_error::{AtomicFileError, FileError, FileOp};
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

use crate::plot::PlotError;
use crate::study::reproduction::{self, ClaimsError};
use closed_loop::RunTrace;
use empty_squares::{Reading, ReadingError};
use grid::{Grid, PointRun, Sweep, SweepPlan};
use outward::{OutwardOptions, OutwardSweep, Region};
use run_settings::RunSettings;
use setup::{CommandKind, Example, Method, theta_names};
use summary::{Claim, SweepStats};

/// A refused option of `study mrac`, naming it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArgError {
    /// A name that is not one of the option's.
    #[error("{option}: {value:?} is not {known}")]
    Unknown {
        /// The option (`--example`).
        option: &'static str,
        /// What was given.
        value: String,
        /// What it may be.
        known: &'static str,
    },
    /// `--grid 0`.
    #[error("--grid: 0 points; give at least 1")]
    NoGrid,
    /// `--outward-rho` not in `(1, 10]`.
    #[error(
        "--outward-rho: {0} is not a pole radius in (1, 10] (the outward grid must reach past the unit circle)"
    )]
    OutwardRho(f64),
    /// `--outward-grid 0` where a grid is wanted.
    #[error("--outward-grid: 0 points; give at least 1")]
    NoOutwardGrid,
    /// No example and command to run.
    #[error("--example/--command: nothing to run (Example 3 runs with the step only)")]
    NothingToRun,
}

/// Why `study mrac` failed, naming the option, the case or the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum MracError {
    /// The study's runs could not be sharded or merged, or (not a failure) its shard is done.
    #[error(transparent)]
    Shard(#[from] crate::study::shard::ShardError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A file that could not be written atomically.
    #[error(transparent)]
    Written(#[from] AtomicFileError),
    /// A refused option.
    #[error(transparent)]
    Arg(#[from] ArgError),
    /// The example's plant at a pole location is refused.
    #[error("Example {} at rho = {rho}, nu = {nu}: {source}", example.number())]
    Plant {
        /// The example.
        example: Example,
        /// The pole radius.
        rho: f64,
        /// The pole angle.
        nu: f64,
        /// Why.
        #[source]
        source: plant_proxy::mrac_examples::MracExampleError,
    },
    /// A pole of the outward grid that is no pole (`ρ ≤ 0`, `ν` outside `[0, π]`, or not
    /// finite).
    #[error("Example {} outward grid: rho = {rho}, nu = {nu} is not a pole (rho finite and > 0, nu in [0, pi])", example.number())]
    OutwardPole {
        /// The example.
        example: Example,
        /// The pole radius.
        rho: f64,
        /// The pole angle.
        nu: f64,
    },
    /// The controller's parameters are refused.
    #[error("{} on Example {}: {source}", method.label(*example), example.number())]
    Controller {
        /// The example.
        example: Example,
        /// The method.
        method: Method,
        /// Why.
        #[source]
        source: control::ParamError,
    },
    /// A run's error, as a shard recorded it.
    #[error("{0}")]
    Recorded(String),
    /// The single run recorded no trace.
    #[error("the single run was not recorded")]
    NotRecorded,
    /// The empty squares cannot be counted.
    #[error(transparent)]
    Reading(#[from] ReadingError),
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The claims cannot be written.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
}

message_from!(ArgError, MracError);

/// The pole of the single runs (the b panels): `ρ = 0.5`, `ν = π/4`.
pub const SINGLE_POLE: (f64, f64) = (0.5, PI / 4.0);

/// The default grid size `N` (`N × N` points).
pub const DEFAULT_GRID: usize = 15;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    /// The examples.
    pub examples: Vec<Example>,
    /// The commands (Example 3 runs only with the step).
    pub commands: Vec<CommandKind>,
    /// `N` of the `N × N` grid.
    pub grid: usize,
    /// Draw the PNG figures.
    pub figures: bool,
    /// The outward reading of Figures 4.8a–4.10a (run when Example 2 is), or `None`.
    pub outward: Option<OutwardOptions>,
    /// Run the [`sensitivity`] table (`--no-sensitivity` turns it off).
    pub sensitivity: bool,
}

impl Options {
    /// Parses `--example` (`all`, or a comma-separated list of 1, 2, 3) and `--command`
    /// (`all`, or a list of step, two, four).
    pub fn parse(examples: &str, commands: &str, grid: usize) -> Result<Self, ArgError> {
        let examples = if examples.trim() == "all" {
            Example::ALL.to_vec()
        } else {
            examples
                .split(',')
                .map(Example::parse)
                .collect::<Result<_, _>>()?
        };
        let commands = if commands.trim() == "all" {
            CommandKind::ALL.to_vec()
        } else {
            commands
                .split(',')
                .map(CommandKind::parse)
                .collect::<Result<_, _>>()?
        };
        Grid::new(grid)?;
        Ok(Self {
            examples,
            commands,
            grid,
            figures: true,
            outward: Some(OutwardOptions::default()),
            sensitivity: true,
        })
    }

    /// Sets the outward reading: `--outward-rho R --outward-grid N` (see
    /// [`OutwardOptions::new`]); `N = 0` turns it off.
    pub fn with_outward(mut self, rho_max: f64, grid: usize) -> Result<Self, ArgError> {
        self.outward = if grid == 0 {
            None
        } else {
            Some(OutwardOptions::new(rho_max, grid)?)
        };
        Ok(self)
    }

    /// The `(example, command, method)` triples to run, in order.
    pub fn cases(&self) -> Vec<(Example, CommandKind, Method)> {
        let mut v = Vec::new();
        for &e in &Example::ALL {
            if !self.examples.contains(&e) {
                continue;
            }
            for &c in e.commands() {
                if !self.commands.contains(&c) {
                    continue;
                }
                for &m in e.methods() {
                    v.push((e, c, m));
                }
            }
        }
        v
    }
}

/// The single run at [`SINGLE_POLE`] of one case.
#[derive(Debug, Clone)]
pub struct SingleRun {
    /// The example.
    pub example: Example,
    /// The command.
    pub command: CommandKind,
    /// The method.
    pub method: Method,
    /// ‖e‖ (4.85) (`+∞` if it diverged).
    pub e_norm: f64,
}

/// What the study found.
#[derive(Debug, Clone)]
pub struct MracReport {
    /// Per case, the grid statistics.
    pub stats: Vec<SweepStats>,
    /// Per case, the single run.
    pub singles: Vec<SingleRun>,
    /// The claims.
    pub claims: Vec<Claim>,
    /// The summary as Markdown (also `summary.md`).
    pub markdown: String,
}

/// The file stem of a case: `ex{e}-{command}-{method}`.
fn stem(e: Example, c: CommandKind, m: Method) -> String {
    format!("ex{}-{}-{}", e.number(), c.name(), m.name())
}

/// Runs the study into `out` (created if missing); `command` is the command line shown in
/// the summary.
pub fn run(
    runs: &crate::study::shard::Runs,
    options: &Options,
    out: &Path,
    command: &str,
) -> Result<MracReport, MracError> {
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Out, out.to_path_buf(), source))?;
    let grid = Grid::new(options.grid)?;
    let cases = options.cases();
    if cases.is_empty() {
        return Err(ArgError::NothingToRun.into());
    }
    // The sharded stages: every grid run of every case, the outward reading, the
    // sensitivity table's runs (each run one item; all of them chosen by the options).
    let plans: Vec<SweepPlan> = cases
        .iter()
        .map(|&(e, c, m)| SweepPlan::chapter(e, c, m, &grid))
        .collect();
    let grid_stage = runs.map("grid", &grid::items(&plans), PointRun::record)?;
    let outward_plans = match options.outward {
        Some(o) if options.examples.contains(&Example::Two) => {
            let commands: Vec<CommandKind> = CommandKind::ALL
                .into_iter()
                .filter(|c| options.commands.contains(c))
                .collect();
            Some((o, outward::plans(&o, &commands, &RunSettings::STUDY)))
        }
        _ => None,
    };
    let outward_items = match &outward_plans {
        Some((_, p)) => grid::items(&outward::sweep_plans(p)),
        None => Vec::new(),
    };
    let outward_stage = runs.map("outward", &outward_items, PointRun::record)?;
    let sensitivity_plans = if options.sensitivity {
        sensitivity::plan(options)?
    } else {
        Vec::new()
    };
    let sensitivity_stage = runs.map(
        "sensitivity",
        &sensitivity::items(&sensitivity_plans),
        PointRun::record,
    )?;
    runs.gather()?;

    let sweeps = grid::assemble(&plans, grid_stage.into_vec()?)?;
    let mut singles = Vec::new();
    let mut traces: Vec<RunTrace> = Vec::new();
    for &(e, c, m) in &cases {
        let single = closed_loop::run(e, c, m, SINGLE_POLE, true)?;
        let trace = single.trace.ok_or(MracError::NotRecorded)?;
        write_single_csv(
            &out.join(format!("single-{}.csv", stem(e, c, m))),
            e,
            m,
            &trace,
        )?;
        singles.push(SingleRun {
            example: e,
            command: c,
            method: m,
            e_norm: single.e_norm,
        });
        traces.push(trace);
    }
    grid::write_csv(&out.join("grid.csv"), &sweeps)?;
    let stats: Vec<SweepStats> = sweeps.iter().map(SweepStats::of).collect();
    if options.figures {
        let range = color_range(&sweeps);
        for ((sw, single), trace) in sweeps.iter().zip(&singles).zip(&traces) {
            let (e, c, m) = (sw.example, sw.command, sw.method);
            let name = format!("Example {}, {}, {}", e.number(), m.label(e), c.label());
            figures::heat_map(
                &out.join(format!("map-{}.png", stem(e, c, m))),
                &format!(
                    "{name}: log10 ‖e‖ (4.85) over the plant poles ρe^(±jν), {n}×{n} grid",
                    n = options.grid
                ),
                sw,
                &grid,
                range,
            )?;
            figures::single_run(
                &out.join(format!("single-{}.png", stem(e, c, m))),
                &format!("{name}, ρ = 0.5, ν = π/4: ‖e‖ = {:.3e}", single.e_norm),
                e,
                m,
                trace,
            )?;
        }
    }
    let pairs = |sw: &[&Sweep]| -> Vec<(Sweep, Sweep)> {
        CommandKind::ALL
            .iter()
            .filter_map(|&c| {
                let get = |m| {
                    sw.iter()
                        .find(|s| s.example == Example::Two && s.command == c && s.method == m)
                };
                Some((
                    (*get(Method::Appc)?).clone(),
                    (*get(Method::RcMrac)?).clone(),
                ))
            })
            .collect()
    };
    let inside_pairs = pairs(&sweeps.iter().collect::<Vec<_>>());
    let inside = Reading::of(
        &format!(
            "inside the unit circle ({n} × {n}, ρ < 1)",
            n = options.grid
        ),
        &inside_pairs.iter().map(|(a, r)| (a, r)).collect::<Vec<_>>(),
    )?;
    let outward_results = outward_stage.into_vec()?;
    let outward_sweeps = match outward_plans {
        Some((o, p)) => {
            let sw = outward::assemble(&p, outward_results)?;
            outward::write_csv(&out.join("grid-outward.csv"), &sw)?;
            if options.figures {
                draw_outward_maps(out, &o, &sw)?;
            }
            Some((o, sw))
        }
        None => None,
    };
    let outward_reading = match &outward_sweeps {
        Some((o, sw)) => {
            let all: Vec<(&Sweep, &Sweep)> = sw
                .chunks(2)
                .filter_map(|p| match p {
                    [a, r] => Some((&a.sweep, &r.sweep)),
                    _ => None,
                })
                .collect();
            Some(Reading::of(
                &format!(
                    "outward ({n} × {n} to ρ = {r}, and {z} × {z} around the zero 1.5)",
                    n = o.grid,
                    r = o.rho_max,
                    z = o.near_zero
                ),
                &all,
            )?)
        }
        None => None,
    };
    let claims = summary::claims(&stats, Some(&inside), outward_reading.as_ref());
    let sensitivity_rows = if options.sensitivity {
        let study = sensitivity::Evaluation {
            stats: stats.clone(),
            inside: Some(inside.clone()),
            outward: outward_reading.clone(),
            claims: claims.clone(),
        };
        let rows = sensitivity::rows(&sensitivity_plans, sensitivity_stage.into_vec()?, &study)?;
        sensitivity::record(&rows, options.grid)
    } else {
        Vec::new()
    };
    if options.sensitivity {
        let path = out.join("sensitivity.csv");
        std::fs::write(&path, reproduction::sensitivity::csv(&sensitivity_rows))
            .map_err(|source| FileError::new(FileOp::Access, &path, source))?;
    }
    let preamble = format!(
        "Command: `{command}` (deterministic: every run of it gives these numbers).\n\n\
         Grid: {n} × {n} plants, ρ = i/{n1} (i = 1…{n}), ν = (j − 1/2)π/{n} (j = 1…{n}); \
         200 steps each; ‖e‖ (4.85) over steps 101–200; a run is unstable when y or u is \
         not finite, |y| > {lim:e} or the controller faults. Median over all points \
         (an unstable point counts as +∞), worst over the stable points.\n",
        n = options.grid,
        n1 = options.grid + 1,
        lim = closed_loop::DIVERGENCE_LIMIT
    );
    let mut markdown = summary::render_markdown(&stats, &claims, &preamble);
    let _ = writeln!(
        markdown,
        "\nSingle runs at ρ = 0.5, ν = π/4 (the b panels):\n"
    );
    let _ = writeln!(markdown, "| example | command | method | ‖e‖ |");
    let _ = writeln!(markdown, "| --- | --- | --- | --- |");
    for s in &singles {
        let _ = writeln!(
            markdown,
            "| {} | {} | {} | {:.3e} |",
            s.example.number(),
            s.command.label(),
            s.method.label(s.example),
            s.e_norm
        );
    }
    if let Some((o, sw)) = &outward_sweeps {
        markdown.push_str(&outward_markdown(o, sw));
    }
    if !sensitivity_rows.is_empty() {
        markdown.push_str(&sensitivity_markdown(&sensitivity_rows));
    }
    let path = out.join("summary.md");
    std::fs::write(&path, &markdown)
        .map_err(|source| FileError::new(FileOp::Access, &path, source))?;
    reproduction::write(
        out,
        &reproduction::Claims {
            study: "mrac".into(),
            chapter: 4,
            run: command.into(),
            claims: {
                let mut c = reproduction::with_figures(claims::claims(&claims), claims::FIGURES);
                reproduction::sensitivity::annotate(&mut c, &sensitivity_rows);
                c
            },
            sensitivity: sensitivity_rows,
        },
    )?;
    Ok(MracReport {
        stats,
        singles,
        claims,
        markdown,
    })
}

/// The sensitivity table as Markdown: per alternative the verdicts of the claims it bears
/// on ([`sensitivity`]), then per claim how many alternatives keep it.
fn sensitivity_markdown(rows: &[reproduction::sensitivity::Alternative]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nSensitivity (`sensitivity.csv`): each setting the chapter leaves open moved to \
         alternatives, all else as above; the verdicts of the claims it bears on, by their own criteria.\n"
    );
    let _ = writeln!(
        s,
        "| setting | ours | alternative | claim | verdict | measured |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
    for row in rows {
        for r in &row.readings {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} |",
                row.setting,
                row.ours,
                row.shown_value(),
                r.claim,
                r.verdict.word(),
                r.measured.replace('|', "\\|")
            );
        }
    }
    let _ = writeln!(
        s,
        "\nPASS over the alternatives (the study's own row not counted): {}.",
        reproduction::sensitivity::tally_text(rows)
    );
    s
}

/// The maps of the outward grid (not the patch), on their own common color scale.
fn draw_outward_maps(
    out: &Path,
    o: &OutwardOptions,
    sweeps: &[OutwardSweep],
) -> Result<(), MracError> {
    let outer: Vec<&OutwardSweep> = sweeps
        .iter()
        .filter(|s| s.region == Region::Outward)
        .collect();
    let range = color_range(&outer.iter().map(|s| s.sweep.clone()).collect::<Vec<_>>());
    for s in outer {
        let (e, c, m) = (s.sweep.example, s.sweep.command, s.sweep.method);
        // The patch's unstable points join the map as empty squares (its stable points
        // are too fine to draw as cells of this grid).
        let mut drawn = s.sweep.clone();
        drawn.points.extend(
            sweeps
                .iter()
                .filter(|z| {
                    z.region == Region::NearZero && z.sweep.command == c && z.sweep.method == m
                })
                .flat_map(|z| z.sweep.points.iter().filter(|p| p.unstable()).copied()),
        );
        figures::heat_map(
            &out.join(format!("map-outward-{}.png", stem(e, c, m))),
            &format!(
                "Example 2, {}, {}: log10 ‖e‖ (4.85) to ρ = {}, {n}×{n} grid; □ unstable (with the patch at 1.5)",
                m.label(e),
                c.label(),
                o.rho_max,
                n = o.grid
            ),
            &drawn,
            &s.grid,
            range,
        )?;
    }
    Ok(())
}

/// The outward reading as Markdown: per region, command and method the unstable points
/// (of them, with `ρ ≥ 1`), the smallest unstable `ρ`, the median `log₁₀‖e‖` and the
/// median θ̂ settling step.
fn outward_markdown(o: &OutwardOptions, sweeps: &[OutwardSweep]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nOutward reading of Figures 4.8a–4.10a (Example 2; `grid-outward.csv`): the \
         {n} × {n} grid ρ = i·{r}/{n} (i = 1…{n}), ν = (j − 1/2)π/{n}, and the {z} × {z} \
         patch around the zero, ρ in 1.5 ± {w}, ν in (0, {nz}); plants with ρ ≥ 1 are \
         open-loop unstable.\n",
        n = o.grid,
        r = o.rho_max,
        z = o.near_zero,
        w = outward::NEAR_ZERO_HALF_WIDTH,
        nz = outward::NEAR_ZERO_NU_MAX
    );
    let _ = writeln!(
        s,
        "| region | command | method | unstable | unstable with ρ ≥ 1 | smallest unstable ρ | median log10‖e‖ | median θ̂ settling step |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- | --- |");
    for w in sweeps {
        let st = SweepStats::of(&w.sweep);
        let outside = w.sweep.points.iter().filter(|p| p.rho >= 1.0).count();
        let unstable_outside = w
            .sweep
            .points
            .iter()
            .filter(|p| p.rho >= 1.0 && p.unstable())
            .count();
        let smallest = w
            .sweep
            .points
            .iter()
            .filter(|p| p.unstable())
            .map(|p| p.rho)
            .fold(f64::INFINITY, f64::min);
        let _ = writeln!(
            s,
            "| {} | {} | {} | {}/{} | {}/{} | {} | {} | {} |",
            w.region.name(),
            w.sweep.command.label(),
            w.sweep.method.label(w.sweep.example),
            st.unstable,
            st.points,
            unstable_outside,
            outside,
            if smallest.is_finite() {
                format!("{smallest:.3}")
            } else {
                "-".into()
            },
            if st.median.is_finite() {
                format!("{:.2}", st.median)
            } else {
                "inf".into()
            },
            st.theta_settle
        );
    }
    s
}

/// The common color scale of the heat maps: the range of the finite `log₁₀‖e‖` over
/// every sweep (`(0, 1)` when none is finite).
fn color_range(sweeps: &[Sweep]) -> (f64, f64) {
    let logs = sweeps
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| !p.unstable() && p.e_norm > 0.0)
        .map(|p| p.e_norm.log10());
    let (lo, hi) = logs.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if lo.is_finite() && hi.is_finite() {
        (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
    } else {
        (0.0, 1.0)
    }
}

/// Writes a single run: `k, r, y, y_m, e, u`, then `θ̂_k` by name.
fn write_single_csv(
    path: &Path,
    example: Example,
    method: Method,
    t: &RunTrace,
) -> Result<(), MracError> {
    let mut s = String::from("k,r,y,y_m,e,u");
    for n in theta_names(example, method) {
        let _ = write!(s, ",{n}");
    }
    s.push('\n');
    for k in 0..t.e.len() {
        let _ = write!(
            s,
            "{k},{:.10e},{:.10e},{:.10e},{:.10e},{:.10e}",
            t.r[k], t.y[k], t.y_m[k], t.e[k], t.u[k]
        );
        for v in &t.theta[k] {
            let _ = write!(s, ",{v:.10e}");
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

/// Writes the results file (`--results`, e.g. `docs/results/mrac.md`): a header saying
/// where it comes from, then the summary.
pub fn write_results(path: &Path, report: &MracReport) -> Result<(), MracError> {
    let text = crate::results_page::head(
        "Chapter 4 study: APPC and RC-MRAC",
        "study mrac",
        "service/tools/src/study/mrac/mod.rs",
        "[studies.md](../studies.md#chapter-4-appc-and-rc-mrac)",
    ) + &report.markdown;
    ipc_types::files::write_atomic(path, text.as_bytes())
        .map_err(|source| FileError::new(FileOp::Results, path.to_path_buf(), source).into())
}
