//! `study sampling-arm`: chapter 7's experiments (§7.3) in one command — the robust
//! controller alone against the PCAC-augmented controller (Algorithm 3) on the
//! spacecraft sampling arm, on grids of linear (7.27) and Hunt–Crossley (7.28) surfaces,
//! in the single runs of Figures 7.4 and 7.6, and in the double maneuvers of Figures 7.7
//! and 7.8.
//!
//! Every run is the real controller (built from `scenarios/arm/{robust,pcac}.toml` by the
//! service's configuration) on the real simulated plant (plant-proxy's `PlantSim`), in
//! the service's loop order ([`run`]). The single runs, the grid runs and the sensitivity
//! record's runs are independent: they are the study's sharded stages
//! ([`crate::study::shard`]: `maneuvers`, `grid`, `sensitivity`, run in parallel with
//! rayon when the study runs whole), whose results the rest of the study reads.
//!
//! # Outputs (in `--out`)
//!
//! - `grid.csv` ([`grid::write_csv`]); `fig7_3_{robust,augmented}.png`,
//!   `fig7_5_{robust,augmented}.png`: the heat maps of the median contact force.
//! - `fig7_4.png`, `fig7_6.png`, `fig7_7.png`, `fig7_8.png` with the runs' signals in
//!   `fig7_<n>_<controller>.csv` ([`write_trace_csv`]).
//! - `summary.md`, and `claims.json` ([`crate::study::arm::claims`]).
//! - `sensitivity.csv` ([`sensitivity`]), also `claims.json`'s `sensitivity` list and the
//!   summary's table: each setting §7.2–7.3 leave open (the robust gain — the
//!   minimum-gain and LQR designs of `rig-design robust-gain --objective …`, described by
//!   [`gain_sensitivity`] —, the mapping of `c_r` to damping, the sign of `ẏ_0`, the
//!   Hunt–Crossley exponent, the grids' spacing, the link inertias, the linearization's
//!   model, sensor noise, torque limits, PCAC's move bounds, the band of "reaches 25 N")
//!   moved to alternatives, with the verdicts of claims 7.2–7.6 under each on
//!   [`sensitivity::SENSITIVITY_GRID`]-point grids. The claims' verdicts stay the study's
//!   own readings; their "ours" ends with the tally. Skipped with `--no-sensitivity`
//!   (`run`'s `sensitivity: None`).
//!
//! Its runs ([`crate::study::shard`]): three sharded stages whose items follow from the
//! options alone: `maneuvers` (Figures 7.4, 7.6, 7.7, 7.8 under both controllers, with
//! their traces), `grid` (both surface grids under both controllers) and `sensitivity`
//! (the alternatives' runs the study's own do not already give; [`sensitivity::Plan`]
//! tells them apart from the grid's definition). After
//! [`crate::study::shard::Runs::gather`] come the designs' summaries, the aggregation, the
//! files and the claims.

pub mod claims;
pub mod closed_loop;
pub mod figures;
pub mod gain_sensitivity;
pub mod grid;
pub mod restitution;
pub mod sensitivity;

use crate::file_error::{AtomicFileError, FileError, FileOp};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::plot::PlotError;
use crate::study::reproduction::{self, Claims, ClaimsError, Verdict};
use claims::{DoubleEvidence, Evidence};
use closed_loop::{ContactStats, Law, Model, Outcome, Record, Setup, Trace};
use grid::{Grid, GridPoint};

/// Why `study sampling-arm` failed, naming the file, the surface or the controller at
/// fault.
#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    /// The study's runs could not be sharded or merged, or (not a failure) its shard is done.
    #[error(transparent)]
    Shard(#[from] crate::study::shard::ShardError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// A file that could not be written atomically.
    #[error(transparent)]
    Written(#[from] AtomicFileError),
    /// A scenario of the study cannot be read.
    #[error("{}: {source}", path.display())]
    Scenario {
        /// The scenario file.
        path: PathBuf,
        /// Why.
        #[source]
        source: plant_proxy::scenario::ScenarioError,
    },
    /// The service's configuration with a controller file cannot be read.
    #[error(transparent)]
    Config(#[from] service::config::ConfigError),
    /// A controller file is not the sampling arm's.
    #[error("{file}: kind {kind} is not sampling-arm")]
    Kind {
        /// The controller file.
        file: &'static str,
        /// Its kind.
        kind: &'static str,
    },
    /// The single maneuver's scenario is not the sampling arm's.
    #[error("linear.toml: not a sampling-arm plant")]
    NotArm,
    /// A surface of the grids is refused.
    #[error("{} surface k_s = {k_s}, {} = {c}: {source}", model.name(), model.second())]
    Surface {
        /// Its contact model.
        model: Model,
        /// Its stiffness.
        k_s: f64,
        /// Its damping or restitution.
        c: f64,
        /// Why.
        #[source]
        source: plant_proxy::arm::SurfaceError,
    },
    /// The simulation of a scenario cannot be built.
    #[error("{origin}: {source}")]
    Sim {
        /// The scenario.
        origin: String,
        /// Why.
        #[source]
        source: plant_proxy::sim::SimError,
    },
    /// A controller's parameters are refused.
    #[error("{file}: {}: {}", source.path(), source.message)]
    Controller {
        /// The controller file.
        file: &'static str,
        /// Why: the parameter and what is wrong.
        source: control::ParamError,
    },
    /// A robust gain file of the sensitivity runs cannot be read.
    #[error("{file}: {message}")]
    Gain {
        /// The gain file.
        file: String,
        /// Why.
        message: String,
    },
    /// `--grid` below 2.
    #[error("--grid {0}: give at least 2 points per axis")]
    Grid(usize),
    /// A single run is missing.
    #[error("missing run")]
    MissingRun,
    /// A single or double maneuver's run failed (the error's message: a sharded run's
    /// result).
    #[error("{0}")]
    Run(String),
    /// `summary.md` cannot be written.
    #[error("summary.md: {0}")]
    Summary(#[source] std::io::Error),
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The claims cannot be written.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
}

message_from!(ArmError);

/// The chapter's grid size (at least 10 × 10).
pub const DEFAULT_GRID: usize = 10;

/// The grid size of `--quick`.
pub const QUICK_GRID: usize = 2;

/// What the study ran and found.
#[derive(Debug, Clone)]
pub struct Report {
    /// The summary, Markdown.
    pub markdown: String,
    /// The claims as written to `claims.json`.
    pub claims: Claims,
    /// Wall time, s.
    pub wall: f64,
}

/// A single run of both controllers: `(figure, title, scenario label, robust, augmented)`.
struct Pair {
    figure: &'static str,
    title: String,
    robust: Outcome,
    augmented: Outcome,
}

/// Writes a run's signals as CSV: `t, r, force, xd, yd, tau1, tau2, lambda, trace_p,
/// theta_0 … theta_34` (the `Θ̃` columns only with PCAC).
pub fn write_trace_csv(path: &Path, t: &Trace) -> Result<(), ArmError> {
    let nth = t.theta.first().map_or(0, Vec::len);
    let mut s = String::from("t,r,force,xd,yd,tau1,tau2,lambda,trace_p");
    for i in 0..nth {
        let _ = write!(s, ",theta_{i}");
    }
    s.push('\n');
    for k in 0..t.t.len() {
        let _ = write!(
            s,
            "{:.4},{},{:.6},{:.6e},{:.6e},{:.6e},{:.6e},{:.8},{:.6e}",
            t.t[k],
            t.r[k],
            t.force[k],
            t.xd[k],
            t.yd[k],
            t.tau1[k],
            t.tau2[k],
            t.lambda[k],
            t.trace_p[k]
        );
        if let Some(th) = t.theta.get(k) {
            for v in th {
                let _ = write!(s, ",{v:.6e}");
            }
        }
        s.push('\n');
    }
    std::fs::write(path, s).map_err(|source| FileError::new(FileOp::Access, path, source).into())
}

fn first(o: &Outcome) -> ContactStats {
    o.contacts.first().copied().unwrap_or(ContactStats {
        first: 0,
        samples: 0,
        median: f64::NAN,
        settling: f64::NAN,
    })
}

fn secs(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3}")
    } else if v.is_nan() {
        "-".into()
    } else {
        "never".into()
    }
}

/// The median table of one model and law, `k_s` rows, `c` columns.
fn table(md: &mut String, grid: &Grid, points: &[&GridPoint]) {
    let n = grid.c.len();
    let _ = write!(md, "| k_s \\ {} |", grid.model.second());
    for c in &grid.c {
        let _ = write!(md, " {c:.3e} |");
    }
    let _ = writeln!(md);
    let _ = writeln!(md, "|---|{}", "---:|".repeat(n));
    for (i, k) in grid.k_s.iter().enumerate() {
        let _ = write!(md, "| {k:.3e} |");
        for p in &points[i * n..(i + 1) * n] {
            if p.failed() {
                let _ = write!(md, " failed |");
            } else {
                let _ = write!(md, " {:.2} |", p.median);
            }
        }
        let _ = writeln!(md);
    }
}

/// Runs the study with an `n × n` grid into `out`, and its sensitivity record with
/// `sensitivity = Some(m)` points per grid axis (`None`: not run); `line` is the command
/// for the report.
pub fn run(
    runs: &crate::study::shard::Runs,
    n: usize,
    sensitivity: Option<usize>,
    out: &Path,
    line: &str,
) -> Result<Report, ArmError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Out, out.to_path_buf(), source))?;
    let setup = Setup::load(&closed_loop::scenario_dir())?;
    let grids = [
        Grid::new(Model::Linear, n)?,
        Grid::new(Model::HuntCrossley, n)?,
    ];

    // The single and double runs, in parallel with each other, then the grids.
    let singles: Vec<(&'static str, String, closed_loop::Maneuver)> = vec![
        (
            "fig7_4",
            "Figure 7.4: linear surface k_s = 2e5 N/m, c_s = 5 N s/m".into(),
            closed_loop::Maneuver::Single(Model::Linear, 2.0e5, 5.0),
        ),
        (
            "fig7_6",
            "Figure 7.6: Hunt–Crossley surface k_s = 2e5, c_r = 0.9".into(),
            closed_loop::Maneuver::Single(Model::HuntCrossley, 2.0e5, 0.9),
        ),
        (
            "fig7_7",
            "Figure 7.7: double maneuver, linear 2e5/5 then 200/500 (+0.5 kg)".into(),
            closed_loop::Maneuver::DoubleLinear,
        ),
        (
            "fig7_8",
            "Figure 7.8: double maneuver, Hunt–Crossley 2e5/0.9 then 300/0.2 (+0.5 kg)".into(),
            closed_loop::Maneuver::DoubleHuntCrossley,
        ),
    ];
    // Every run, as the sharded stages of the study (their items depend on the options
    // alone): the single and double maneuvers, the grids, the sensitivity record's runs
    // that the study does not have. Then their results, in the merge or the whole study.
    let t_single = Instant::now();
    let jobs: Vec<(closed_loop::Maneuver, Law)> = singles
        .iter()
        .flat_map(|s| Law::ALL.map(|l| (s.2, l)))
        .collect();
    let maneuvers = runs.map("maneuvers", &jobs, |&(m, law)| {
        setup
            .scenario(m)
            .and_then(|sc| closed_loop::run(&setup, &sc, law, Record::Everything))
            .map_err(|e| e.to_string())
    })?;
    let wall_single = t_single.elapsed().as_secs_f64();
    let t_grid = Instant::now();
    let grid_jobs = grid::jobs(&grids);
    let grid_stage = runs.map("grid", &grid_jobs, |j| grid::run_point(&setup, j))?;
    let wall_grid = t_grid.elapsed().as_secs_f64();
    let t_sens = Instant::now();
    let dir = closed_loop::scenario_dir();
    let plan = match sensitivity {
        Some(m) => Some(sensitivity::Plan::new(&setup, &dir, &grid_jobs, m)?),
        None => None,
    };
    let sens_stage = match &plan {
        Some(p) => Some(runs.map("sensitivity", p.items(), |item| p.run(item))?),
        None => None,
    };
    let wall_sens_runs = t_sens.elapsed().as_secs_f64();
    runs.gather()?;

    let mut outs = maneuvers.into_vec()?.into_iter();
    let mut pairs = Vec::new();
    for (figure, title, _) in &singles {
        let mut next = || -> Result<Outcome, ArmError> {
            outs.next()
                .ok_or(ArmError::MissingRun)?
                .map_err(ArmError::Run)
        };
        let robust = next()?;
        let augmented = next()?;
        pairs.push(Pair {
            figure,
            title: title.clone(),
            robust,
            augmented,
        });
    }
    let points = grid_stage.into_vec()?;

    // Files.
    grid::write_csv(&out.join("grid.csv"), &points)?;
    for (g, fig) in grids.iter().zip(["fig7_3", "fig7_5"]) {
        for law in Law::ALL {
            let ps: Vec<&GridPoint> = points
                .iter()
                .filter(|p| p.model == g.model && p.law == law)
                .collect();
            figures::heat_map(
                &out.join(format!("{fig}_{}.png", law.name())),
                &format!(
                    "{}: median contact force (N), {} model, {n}×{n} grid",
                    law.label(),
                    g.model.name()
                ),
                g,
                &ps,
            )?;
        }
    }
    let empty = Trace::default();
    for p in &pairs {
        let rt = p.robust.trace.as_ref().unwrap_or(&empty);
        let at = p.augmented.trace.as_ref().unwrap_or(&empty);
        write_trace_csv(&out.join(format!("{}_robust.csv", p.figure)), rt)?;
        write_trace_csv(&out.join(format!("{}_augmented.csv", p.figure)), at)?;
        let path = out.join(format!("{}.png", p.figure));
        let double = p.figure == "fig7_7" || p.figure == "fig7_8";
        figures::run_figure(&path, &p.title, (rt, at), double)?;
    }

    // Claims.
    let doubles: Vec<DoubleEvidence> = pairs[2..]
        .iter()
        .map(|p| {
            let t = p.augmented.trace.as_ref().unwrap_or(&empty);
            DoubleEvidence {
                name: p.figure,
                contacts: p.augmented.contacts.clone(),
                lambda: t.lambda.as_slice(),
                trace_p: t.trace_p.as_slice(),
            }
        })
        .collect();
    let evidence = Evidence {
        grid: &points,
        fig_7_4: (first(&pairs[0].robust), first(&pairs[0].augmented)),
        fig_7_6: (first(&pairs[1].robust), first(&pairs[1].augmented)),
        doubles,
    };
    let mut claims = Claims {
        study: "sampling-arm".into(),
        chapter: 7,
        run: line.to_string(),
        claims: crate::study::reproduction::with_figures(
            claims::claims(&evidence),
            claims::FIGURES,
        ),
        sensitivity: Vec::new(),
    };

    // The sensitivity record: claims 7.2–7.6 under each alternative of the open settings.
    let t_sens = Instant::now();
    let designs = gain_sensitivity::designs(&dir)?;
    if let (Some(m), Some(plan), Some(stage)) = (sensitivity, &plan, sens_stage) {
        let study = sensitivity::StudyRuns {
            grid: &points,
            fig_7_4: (
                pairs[0].robust.trace.as_ref().unwrap_or(&empty),
                pairs[0].augmented.trace.as_ref().unwrap_or(&empty),
            ),
            fig_7_6: (
                pairs[1].robust.trace.as_ref().unwrap_or(&empty),
                pairs[1].augmented.trace.as_ref().unwrap_or(&empty),
            ),
            ts: setup.single.rig.sample_period,
        };
        let outcomes = plan.outcomes(&study, stage.into_vec()?)?;
        claims.sensitivity = sensitivity::record(&outcomes, m);
        sensitivity::write_csv(&out.join("sensitivity.csv"), &claims.sensitivity)?;
        for c in claims.claims.iter_mut() {
            c.ours += &sensitivity::reading(&c.id, &claims.sensitivity);
        }
    }
    let wall_sens = wall_sens_runs + t_sens.elapsed().as_secs_f64();
    let wall = t0.elapsed().as_secs_f64();

    // Summary.
    let mut md = String::new();
    let _ = writeln!(md, "# Chapter 7: the spacecraft sampling arm (§7.3)\n");
    let _ = writeln!(
        md,
        "Command: `{line}`. {} threads; wall time {wall:.1} s (single and double runs {wall_single:.1} s, \
         grids {wall_grid:.1} s for {} runs, the sensitivity record {wall_sens:.1} s).\n",
        rayon::current_num_threads(),
        points.len()
    );
    let _ = writeln!(
        md,
        "The controllers are built from `scenarios/arm/robust.toml` (robust only) and `scenarios/arm/pcac.toml` \
         (PCAC-augmented, Algorithm 3) by the service's configuration and run in process on plant-proxy's \
         simulation of the arm (`scenarios/arm/linear.toml` with the surface replaced, and the double-*.toml \
         scenarios). The robust gain in use (`scenarios/arm/robust-gain.toml`) is the LMI design for the decay \
         rate λ = 0.025 /s, not the chapter's 0.05: with an exact zero-order hold 0.05 is not certifiable over \
         the whole box (docs/design-tools.md). \"Reaches 25 N\" means a median contact force within 25 N ± 5 %; \
         the settling time is the time from the contact phase's first sample after which the force stays within \
         25 N ± 5 % to the phase's end.\n"
    );
    for g in &grids {
        for law in Law::ALL {
            let ps: Vec<&GridPoint> = points
                .iter()
                .filter(|p| p.model == g.model && p.law == law)
                .collect();
            let failed = ps.iter().filter(|p| p.failed()).count();
            let _ = writeln!(
                md,
                "## {} model, {}: median contact force (N) over the contact phase ({failed} failed run(s))\n",
                g.model.name(),
                law.label()
            );
            table(&mut md, g, &ps);
            let _ = writeln!(md);
        }
    }
    let _ = writeln!(md, "## Single and double runs\n");
    let _ = writeln!(
        md,
        "| run | controller | contact | median (N) | settling (s) | failure |"
    );
    let _ = writeln!(md, "|---|---|---:|---:|---:|---|");
    for p in &pairs {
        for (law, o) in [(Law::Robust, &p.robust), (Law::Augmented, &p.augmented)] {
            for (i, c) in o.contacts.iter().enumerate() {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {:.2} | {} | {} |",
                    p.title,
                    law.name(),
                    i + 1,
                    c.median,
                    secs(c.settling),
                    o.failure.as_deref().unwrap_or("")
                );
            }
            if o.contacts.is_empty() {
                let _ = writeln!(
                    md,
                    "| {} | {} | - | - | - | {} |",
                    p.title,
                    law.name(),
                    o.failure.as_deref().unwrap_or("")
                );
            }
        }
    }
    let _ = writeln!(md);
    md += &gain_sensitivity::markdown(&designs);
    if let Some(m) = sensitivity {
        let _ = writeln!(
            md,
            "## Sensitivity of claims 7.2–7.6 to the settings §7.2–7.3 leave open ({m} × {m} grids)\n"
        );
        reproduction::report::sensitivity_table(&mut md, &claims.sensitivity);
    }
    let _ = writeln!(
        md,
        "## The chapter's claims\n\n{} PASS, {} FAIL, {} NOT CHECKED.\n",
        claims.count(Verdict::Pass),
        claims.count(Verdict::Fail),
        claims.count(Verdict::NotChecked)
    );
    let _ = writeln!(md, "| id | source | claim | criterion | ours | verdict |");
    let _ = writeln!(md, "|---|---|---|---|---|---|");
    for c in &claims.claims {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} |",
            c.id,
            c.source,
            c.claim.replace('|', "\\|"),
            c.criterion.replace('|', "\\|"),
            c.ours.replace('|', "\\|"),
            c.verdict.word()
        );
    }
    std::fs::write(out.join("summary.md"), &md).map_err(ArmError::Summary)?;
    reproduction::write(out, &claims)?;
    Ok(Report {
        markdown: md,
        claims,
        wall,
    })
}
