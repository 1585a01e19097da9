//! `study`: reproduces the numerical studies of the dissertation.
//!
//! ```text
//! cargo run --release -p rig-tools --bin study -- forgetting [--runs 1000] [--out DIR] [--seed S]
//! cargo run --release -p rig-tools --bin study -- rcac-siso [--out DIR] [--points 47] [--update gradient|rls|both] [--no-sensitivity]
//! cargo run --release -p rig-tools --bin study -- rcac-miso [--out DIR] [--points 50] [--update gradient|rls|both] [--no-sensitivity]
//! cargo run --release -p rig-tools --bin study -- pcac-truss [--out DIR] [--duration 100] [--experiments all] [--settings both] [--no-sensitivity]
//! cargo run --release -p rig-tools --bin study -- sampling-arm [--grid 10] [--out DIR] [--quick] [--no-sensitivity] [--sensitivity-grid 4] [--results FILE]
//! cargo run --release -p rig-tools --bin study -- mrac [--example 1|2|3|all] [--command step|two|four|all] [--grid 15] [--out DIR] [--results FILE] [--no-sensitivity]
//! cargo run --release -p rig-tools --bin study -- all [--out DIR] [--quick] [--jobs N] [--results FILE]
//! cargo run --release -p rig-tools --bin study -- <study> … --shard I/N
//! cargo run --release -p rig-tools --bin study -- merge DIR… [--out DIR]
//! ```
//!
//! `--shard I/N` (or a Slurm array's or Kubernetes Indexed Job's environment) runs shard
//! `I` of `N` of any study, `all` included, into `DIR/shards/I-of-N/`; `merge` checks the
//! shards and writes what the study run whole writes (`rig_tools::study::shard`,
//! `docs/studies.md`).
//!
//! `all` runs every study into `DIR/<study>/` and writes the reproduction report
//! `DIR/reproduction.md`; see the `all` module for the table of studies.
//!
//! `mrac` is the chapter 4 study of APPC against RC-MRAC over the plant's pole plane
//! (§4.5–4.7, Figures 4.2–4.14); see the `mrac` module for the settings and the files.
//!
//! `rcac-siso` and `rcac-miso` are the chapter 3 studies of RCAC with dereverberated
//! target models (§3.3.1 on the structure (3.50), Figures 3.5–3.10; §3.3.2 on a 4-mode
//! MISO structure, Figures 3.11–3.17); see the `rig_tools::study::rcac`
//! modules for the equations, the settings and what they write.
//!
//! `pcac-truss` is the chapter 6 study of PCAC on the 4-bay truss under harmonic and
//! broadband disturbances, with and without aliasing (§6.2, Figures 6.2–6.10), from the
//! scenarios `scenarios/truss/*.toml`; see the `pcac_truss` module.
//!
//! `forgetting` is the chapter 5 study of RLS with F-test variable-rate forgetting
//! (RLS/FTVRF, Algorithm 1) against constant-rate forgetting (RLS/CRF, `λ = 0.99`) and
//! RMS-ratio forgetting (RLS/RMSVRF) on the time-varying mass-spring-damper (5.8), in the
//! three cases of §5.3 (noiseless, noisy, non-persistent input); see the
//! `rig_tools::study::forgetting` module for the plant and the files it writes.

#![warn(missing_docs)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};

use rig_tools::file_error::{FileError, FileOp};
use rig_tools::study::arm::ArmError;
use rig_tools::study::mrac::MracError;
use rig_tools::study::rcac::{RcacError, common, driver, miso, siso};
use rig_tools::study::shard::manifest::{COMMIT, Manifest};
use rig_tools::study::shard::merge::Shards;
use rig_tools::study::shard::{Runs, ShardError, Slice};
use rig_tools::study::{all, forgetting, mrac, pcac_truss};

/// Command line.
#[derive(Debug, Parser)]
#[command(name = "study", about = "Numerical studies of the dissertation")]
struct Cli {
    /// The study to run.
    #[command(subcommand)]
    study: Study,
    /// Run shard I of N (0 ≤ I < N) of the study's runs into `--out`/shards/I-of-N/, or
    /// `none` for the whole study; when not given, a Slurm array's or Kubernetes Indexed
    /// Job's environment names the shard (docs/studies.md).
    #[arg(long, global = true, value_name = "I/N")]
    shard: Option<String>,
}

/// The `--update` option of the RCAC studies.
#[derive(Debug, clap::Args)]
struct UpdateArg {
    /// RCAC update law: gradient (μ_Exp, the dissertation's α and R), rls, or both.
    #[arg(long, default_value = "both")]
    update: String,
}

/// Available studies.
#[derive(Debug, Subcommand)]
enum Study {
    /// Chapter 5: RLS with F-test variable-rate forgetting.
    Forgetting {
        /// Number of Monte Carlo runs per case and method.
        #[arg(long, default_value_t = 1000)]
        runs: usize,
        /// Output directory.
        #[arg(long, default_value = "runs/study-forgetting")]
        out: PathBuf,
        /// Master seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Chapter 3, §3.3.1: RCAC with dereverberated target models on the SISO structure
    /// (3.50), disturbance frequency swept from 4π to 50π rad/s (Figures 3.5–3.10).
    RcacSiso {
        /// Output directory.
        #[arg(long, default_value = "runs/study-rcac-siso")]
        out: PathBuf,
        /// Disturbance frequencies per case (4π … 50π rad/s, equally spaced).
        #[arg(long, default_value_t = 47)]
        points: usize,
        #[command(flatten)]
        update: UpdateArg,
        /// Skip the sensitivity of the claims to the settings §3.3 leaves open (run
        /// length, window, tone phase, sensor noise).
        #[arg(long)]
        no_sensitivity: bool,
    },
    /// Chapter 3, §3.3.2: RCAC on a 4-mode 2-input 1-output structure whose damping is
    /// swept from 0.01 to 0.5, target models from the ζ = 0.1 model (Figures 3.11–3.17).
    RcacMiso {
        /// Output directory.
        #[arg(long, default_value = "runs/study-rcac-miso")]
        out: PathBuf,
        /// Number of damping values (0.01 … 0.5, equally spaced).
        #[arg(long, default_value_t = 50)]
        points: usize,
        #[command(flatten)]
        update: UpdateArg,
        /// Skip the sensitivity of the claims to the settings §3.3 leaves open (run
        /// length, window, tone phase, sensor noise, the windowed average's β).
        #[arg(long)]
        no_sensitivity: bool,
    },
    /// Chapter 6, §6.2: PCAC on the 4-bay truss under harmonic and broadband disturbances,
    /// with and without aliasing (Figures 6.2–6.10), open and closed loop.
    PcacTruss {
        /// Output directory.
        #[arg(long, default_value = "runs/study-pcac-truss")]
        out: PathBuf,
        /// Simulated duration of each run, s.
        #[arg(long, default_value_t = pcac_truss::DURATION_S)]
        duration: f64,
        /// Experiments: all, or a comma-separated list of harmonic, broadband-25hz,
        /// broadband-50hz-aliasing.
        #[arg(long, default_value = "all")]
        experiments: String,
        /// PCAC settings: both, printed (§6.2 as printed, y in 10·mm) or metres (the same, y in 10·m).
        #[arg(long, default_value = "both")]
        settings: String,
        /// Skip the sensitivity of the convergence claims to the choices §6.2 leaves open
        /// (seed, tone amplitudes and phases, broadband RMS, SNR, P_0, the convergence rule).
        #[arg(long)]
        no_sensitivity: bool,
    },
    /// Chapter 4, §4.5–4.7: APPC against RC-MRAC over the plant's pole plane (ρ, ν), with
    /// the step, two- and four-harmonic commands, and Example 3's harmonic rejection
    /// (Figures 4.2–4.14).
    Mrac {
        /// Examples: all, or a comma-separated list of 1, 2, 3.
        #[arg(long, default_value = "all")]
        example: String,
        /// Commands: all, or a comma-separated list of step, two, four (Example 3: step).
        #[arg(long, default_value = "all")]
        command: String,
        /// N of the N × N grid of pole radii and angles.
        #[arg(long, default_value_t = mrac::DEFAULT_GRID)]
        grid: usize,
        /// Output directory.
        #[arg(long, default_value = "runs/study-mrac")]
        out: PathBuf,
        /// Also write the summary as Markdown into this file (e.g. docs/results/mrac.md).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Claim 4.4's outward reading: the largest pole radius of the outward grid (1 < R ≤ 10).
        #[arg(long, default_value_t = mrac::outward::DEFAULT_OUTWARD_RHO)]
        outward_rho: f64,
        /// N of the outward reading's N × N grid (0: no outward reading).
        #[arg(long, default_value_t = mrac::outward::DEFAULT_OUTWARD_GRID)]
        outward_grid: usize,
        /// Skip the sensitivity of the claims to the settings §4.5–4.7 leave open (grid,
        /// divergence limit, run length, convergence rule, Example 3's disturbance, R_θ).
        #[arg(long)]
        no_sensitivity: bool,
    },
    /// Chapter 7, §7.3: the spacecraft sampling arm's force control, the robust controller
    /// alone against the PCAC-augmented one, over linear and Hunt–Crossley surface grids,
    /// in the single runs and the double maneuvers (Figures 7.3–7.8).
    SamplingArm {
        /// N of the N × N log-spaced surface grids (default 10; 2 with --quick).
        #[arg(long)]
        grid: Option<usize>,
        /// Output directory.
        #[arg(long, default_value = "runs/study-sampling-arm")]
        out: PathBuf,
        /// Reduced size for a quick check (a 2 × 2 grid; not the reproduction).
        #[arg(long)]
        quick: bool,
        /// Also write the summary as Markdown into this file (e.g. docs/results/sampling-arm.md).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Skip the sensitivity record of claims 7.2–7.6 to the settings §7.2–7.3 leave open
        /// (run by default, on 4 × 4 grids: about 30 s of the study's wall time on 2 cores).
        #[arg(long)]
        no_sensitivity: bool,
        /// Points per axis of the sensitivity record's grids (default 4: every third point
        /// of the 10 × 10 grid, whose runs the study's own row reuses).
        #[arg(long)]
        sensitivity_grid: Option<usize>,
    },
    /// Checks the shards of one study (or of `study all`) in each DIR (a shard's folder,
    /// the shards' `--out`, or a folder of shards) and writes what the study run whole
    /// writes.
    Merge {
        /// The shards' folders, or the `--out` they were run with.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Output directory (default: the shards' own `--out`, as they were given it).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Every study of the dissertation, each into `--out/<study>/`, several at a time, and
    /// one reproduction report `--out/reproduction.md` of the chapters' claims.
    All {
        /// Output directory.
        #[arg(long, default_value = "runs/study-all")]
        out: PathBuf,
        /// Reduced sizes for a quick check (not the reproduction).
        #[arg(long)]
        quick: bool,
        /// Studies at a time (default: the number of cores; each gets cores/jobs threads).
        #[arg(long)]
        jobs: Option<usize>,
        /// Also write the report into this file (e.g. docs/results/reproduction.md).
        #[arg(long)]
        results: Option<PathBuf>,
    },
}

impl Study {
    /// The subcommand's name.
    fn name(&self) -> &'static str {
        match self {
            Study::Forgetting { .. } => "forgetting",
            Study::RcacSiso { .. } => "rcac-siso",
            Study::RcacMiso { .. } => "rcac-miso",
            Study::PcacTruss { .. } => "pcac-truss",
            Study::Mrac { .. } => "mrac",
            Study::SamplingArm { .. } => "sampling-arm",
            Study::Merge { .. } => "merge",
            Study::All { .. } => "all",
        }
    }

    /// The study's `--out`, to change.
    fn out_mut(&mut self) -> Option<&mut PathBuf> {
        match self {
            Study::Forgetting { out, .. }
            | Study::RcacSiso { out, .. }
            | Study::RcacMiso { out, .. }
            | Study::PcacTruss { out, .. }
            | Study::Mrac { out, .. }
            | Study::SamplingArm { out, .. }
            | Study::All { out, .. } => Some(out),
            Study::Merge { .. } => None,
        }
    }
}

/// The command line after `study`, without `--shard`.
fn args_without_shard() -> Vec<String> {
    let mut args = Vec::new();
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        if a == "--shard" {
            it.next();
        } else if !a.starts_with("--shard=") {
            args.push(a);
        }
    }
    args
}

fn main() -> ExitCode {
    let mut cli = Cli::parse();
    let out = cli
        .study
        .out_mut()
        .map_or(PathBuf::from("."), |o| o.clone());
    let runs = match (&cli.study, cli.shard.as_deref()) {
        (Study::Merge { .. }, Some(s)) => {
            eprintln!("study: --shard {s}: merge reads shards; it is not one");
            return ExitCode::FAILURE;
        }
        (Study::Merge { .. }, None) => Ok(Runs::whole()),
        (study, option) => Slice::resolve(option, |k| std::env::var(k).ok())
            .map_err(ShardError::from)
            .and_then(|slice| match slice {
                None => Ok(Runs::whole()),
                Some(slice) => Manifest::new(
                    study.name(),
                    args_without_shard(),
                    &format!("{study:?}"),
                    slice,
                    &out,
                )
                .and_then(Runs::shard),
            }),
    };
    let result = match runs {
        Ok(runs) => {
            let r = match cli.study {
                Study::Merge { dirs, out } => merge(&dirs, out),
                study => run_study(study, &runs, None),
            };
            if let Some(line) = runs.shard_done() {
                println!("{line}");
                return ExitCode::SUCCESS;
            }
            r
        }
        Err(e) => Err(e.into()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("study: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `study merge`: finds and checks the shards in `dirs`, then runs their study again from
/// their command line (with `out` for its `--out` if given) on their recorded runs.
fn merge(dirs: &[PathBuf], out: Option<PathBuf>) -> Result<(), Box<dyn std::error::Error>> {
    let shards = Shards::find(dirs)?;
    for note in shards.binary_notes() {
        eprintln!("study merge: {note}");
    }
    let m = shards.manifest().clone();
    if m.commit != COMMIT {
        return Err(format!(
            "{}: the shards ran commit {}, this binary is commit {}: merge with a binary of the shards' commit",
            shards.folders()[0].display(),
            m.commit,
            COMMIT
        )
        .into());
    }
    let cli = Cli::try_parse_from(std::iter::once("study".to_string()).chain(m.args.clone()))
        .map_err(|e| {
            format!(
                "{}: its command line `study {}` does not parse: {e}",
                shards.folders()[0].display(),
                m.args.join(" ")
            )
        })?;
    let mut study = cli.study;
    let all_from = shards.folders()[0]
        .parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf);
    if let (Some(o), Some(slot)) = (out, study.out_mut()) {
        *slot = o;
    }
    if let Study::All { .. } = study {
        let from = all_from.ok_or_else(|| "the shards' folder has no parent".to_string())?;
        let command = std::iter::once("study".to_string())
            .chain(m.args.iter().cloned())
            .collect::<Vec<_>>()
            .join(" ");
        return run_study(study, &Runs::whole(), Some((from, command)));
    }
    run_study(study, &Runs::merge(shards), None)
}

/// Runs `study` with its runs handed to `runs`; `study all` with `all_from` = (folder,
/// command line): merges the shards of every study found under `folder/<study>/`, and
/// reports the shards' command line.
fn run_study(
    study: Study,
    runs: &Runs,
    all_from: Option<(PathBuf, String)>,
) -> Result<(), Box<dyn std::error::Error>> {
    match study {
        Study::Forgetting { runs: n, out, seed } => {
            forgetting::run(runs, n, &out, seed).map_err(Into::into)
        }
        Study::RcacSiso {
            out,
            points,
            update,
            no_sensitivity,
        } => rcac(siso::run, runs, &out, points, &update, !no_sensitivity).map_err(Into::into),
        Study::RcacMiso {
            out,
            points,
            update,
            no_sensitivity,
        } => rcac(miso::run, runs, &out, points, &update, !no_sensitivity).map_err(Into::into),
        Study::PcacTruss {
            out,
            duration,
            experiments,
            settings,
            no_sensitivity,
        } => pcac_truss::Experiment::parse_set(&experiments)
            .and_then(|experiments| {
                pcac_truss::Setting::parse_set(&settings).and_then(|settings| {
                    pcac_truss::run(
                        runs,
                        &out,
                        &pcac_truss::Options {
                            duration,
                            experiments,
                            settings,
                            sensitivity: !no_sensitivity,
                        },
                    )
                })
            })
            .map_err(Into::into),
        Study::Mrac {
            example,
            command,
            grid,
            out,
            results,
            outward_rho,
            outward_grid,
            no_sensitivity,
        } => mrac_study(
            runs,
            &example,
            &command,
            (grid, outward_rho, outward_grid, !no_sensitivity),
            &out,
            results.as_deref(),
        )
        .map_err(Into::into),
        Study::SamplingArm {
            grid,
            out,
            quick,
            results,
            no_sensitivity,
            sensitivity_grid,
        } => sampling_arm(
            runs,
            grid,
            quick,
            (!no_sensitivity).then_some(sensitivity_grid),
            &out,
            results.as_deref(),
        )
        .map_err(Into::into),
        Study::Merge { dirs, out } => merge(&dirs, out),
        Study::All {
            out,
            quick,
            jobs,
            results,
        } => {
            let (sharding, command) = match (all_from, runs.slice()) {
                (Some((from, command)), _) => (all::Sharding::Merge(from), command),
                (None, slice) => (
                    if slice.is_some() {
                        all::Sharding::Shard(runs)
                    } else {
                        all::Sharding::Whole
                    },
                    std::iter::once("study".to_string())
                        .chain(args_without_shard())
                        .collect::<Vec<_>>()
                        .join(" "),
                ),
            };
            all::command(
                &out,
                if quick {
                    all::Size::Quick
                } else {
                    all::Size::Full
                },
                jobs,
                results.as_deref(),
                command,
                &sharding,
            )
            .map_err(Into::into)
        }
    }
}

/// Runs the RCAC study `run` into `out` with `points` sweep points, the update laws of
/// `update` and, when `sensitivity`, the sensitivity table.
fn rcac(
    run: fn(&Runs, &Path, &driver::Options) -> Result<(), RcacError>,
    runs: &Runs,
    out: &Path,
    points: usize,
    update: &UpdateArg,
    sensitivity: bool,
) -> Result<(), RcacError> {
    let updates = common::Update::parse_set(&update.update)?;
    run(
        runs,
        out,
        &driver::Options {
            points,
            updates,
            sensitivity,
        },
    )
}

/// `study mrac`: runs, prints the summary, writes `--results` if given.
fn mrac_study(
    runs: &Runs,
    example: &str,
    command: &str,
    (grid, outward_rho, outward_grid, sensitivity): (usize, f64, usize, bool),
    out: &Path,
    results: Option<&Path>,
) -> Result<(), MracError> {
    let t0 = Instant::now();
    let mut options =
        mrac::Options::parse(example, command, grid)?.with_outward(outward_rho, outward_grid)?;
    options.sensitivity = sensitivity;
    let line = format!(
        "study mrac --example {example} --command {command} --grid {grid} --outward-rho {outward_rho} --outward-grid {outward_grid}{}",
        if sensitivity { "" } else { " --no-sensitivity" }
    );
    let report = mrac::run(runs, &options, out, &line)?;
    print!("{}", report.markdown);
    println!(
        "\n{} cases, {} threads, {:.2} s; files in {}",
        report.stats.len(),
        rayon::current_num_threads(),
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    if let Some(path) = results {
        mrac::write_results(path, &report)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// `study sampling-arm`: runs, prints the summary, writes `--results` if given.
fn sampling_arm(
    runs: &Runs,
    grid: Option<usize>,
    quick: bool,
    sensitivity: Option<Option<usize>>,
    out: &Path,
    results: Option<&Path>,
) -> Result<(), ArmError> {
    use rig_tools::study::arm;
    let n = grid.unwrap_or(if quick {
        arm::QUICK_GRID
    } else {
        arm::DEFAULT_GRID
    });
    // The sensitivity grid: as given, else SENSITIVITY_GRID (at most the study's own).
    let m = sensitivity.map(|m| m.unwrap_or(arm::sensitivity::SENSITIVITY_GRID.min(n)));
    let line = match m {
        Some(m) => format!("study sampling-arm --grid {n} --sensitivity-grid {m}"),
        None => format!("study sampling-arm --grid {n} --no-sensitivity"),
    };
    let report = arm::run(runs, n, m, out, &line)?;
    print!("{}", report.markdown);
    println!(
        "\n{} threads, {:.2} s; files in {}",
        rayon::current_num_threads(),
        report.wall,
        out.display()
    );
    if let Some(path) = results {
        ipc_types::files::write_atomic(path, report.markdown.as_bytes())
            .map_err(|source| FileError::new(FileOp::Results, path, source))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
