//! `study`: reproduces the numerical studies of the dissertation.
//!
//! ```text
//! cargo run --release -p rig-tools --bin study -- forgetting [--runs 1000] [--out DIR] [--seed S]
//! cargo run --release -p rig-tools --bin study -- rcac-siso [--out DIR] [--points 47] [--update gradient|rls|both]
//! cargo run --release -p rig-tools --bin study -- rcac-miso [--out DIR] [--points 50] [--update gradient|rls|both]
//! cargo run --release -p rig-tools --bin study -- pcac-truss [--out DIR] [--duration 100] [--experiments all] [--settings both]
//! cargo run --release -p rig-tools --bin study -- mrac [--example 1|2|3|all] [--command step|two|four|all] [--grid 15] [--out DIR] [--results FILE]
//! cargo run --release -p rig-tools --bin study -- all [--out DIR] [--quick] [--jobs N] [--results FILE]
//! ```
//!
//! `all` runs every study into `DIR/<study>/` and writes the reproduction report
//! `DIR/reproduction.md`; see the `all` module for the table of studies.
//!
//! `mrac` is the chapter 4 study of APPC against RC-MRAC over the plant's pole plane
//! (§4.5–4.7, Figures 4.2–4.14); see the `mrac` module for the settings and the files.
//!
//! `rcac-siso` and `rcac-miso` are the chapter 3 studies of RCAC with dereverberated
//! target models (§3.3.1 on the structure (3.50), Figures 3.5–3.10; §3.3.2 on a 4-mode
//! MISO structure, Figures 3.11–3.17); see the `rcac_siso`, `rcac_miso` and `rcac_common`
//! modules for the equations, the settings and what they write.
//!
//! `pcac-truss` is the chapter 6 study of PCAC on the 4-bay truss under harmonic and
//! broadband disturbances, with and without aliasing (§6.2, Figures 6.2–6.10), from the
//! scenarios `scenarios/truss/*.toml`; see the `pcac_truss` module.
//!
//! `forgetting` is the chapter 5 study of RLS with F-test variable-rate forgetting
//! (RLS/FTVRF, Algorithm 1) against constant-rate forgetting (RLS/CRF, `λ = 0.99`) and
//! RMS-ratio forgetting (RLS/RMSVRF) on the time-varying mass-spring-damper (5.8), in the
//! three cases of §5.3 (noiseless, noisy, non-persistent input). It writes, into `--out`:
//!
//! - `case{c}_{case}_{method}.csv`: one run (`k, θ_k, true θ, tr(P_k), λ_k, e_k`);
//! - `case{c}_{case}_{method}_mc.csv`: 5th/50th/95th percentile bands over the Monte Carlo;
//! - `case{c}_{case}_ftvrf_vs_crf.png`, `case2_noisy_ftvrf_vs_rmsvrf.png`: single runs in
//!   the manner of Figures 5.1, 5.3, 5.5, 5.7;
//! - `case{c}_{case}_{method}_mc.png`: bands in the manner of Figures 5.2, 5.4, 5.6, 5.8;
//! - `summary.txt`: the printed summary table;
//! - `claims.json`: the chapter's claims checked on the Monte Carlo
//!   (`rig_tools::study::reproduction_forgetting`).
//!
//! The plant derivation is documented in the `plant` module.

#![warn(missing_docs)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use plotters::style::RGBColor;

use rig_tools::study::experiment::{Case, Method, run, run_seed};
use rig_tools::study::montecarlo::{Summary, monte_carlo};
use rig_tools::study::plant::{Msd, PRINTED, Plant, SAMPLE_PERIOD};
use rig_tools::study::{
    experiment, mrac, output, pcac_truss, plant, rcac_common, rcac_miso, rcac_siso, rcac_study,
};

/// Command line.
#[derive(Debug, Parser)]
#[command(name = "study", about = "Numerical studies of the dissertation")]
struct Cli {
    /// The study to run.
    #[command(subcommand)]
    study: Study,
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.study {
        Study::Forgetting { runs, out, seed } => forgetting(runs, &out, seed),
        Study::RcacSiso {
            out,
            points,
            update,
        } => rcac(rcac_siso::run, &out, points, &update),
        Study::RcacMiso {
            out,
            points,
            update,
        } => rcac(rcac_miso::run, &out, points, &update),
        Study::PcacTruss {
            out,
            duration,
            experiments,
            settings,
        } => pcac_truss::Experiment::parse_set(&experiments).and_then(|experiments| {
            pcac_truss::Setting::parse_set(&settings).and_then(|settings| {
                pcac_truss::run(
                    &out,
                    &pcac_truss::Options {
                        duration,
                        experiments,
                        settings,
                    },
                )
            })
        }),
        Study::Mrac {
            example,
            command,
            grid,
            out,
            results,
        } => mrac_study(&example, &command, grid, &out, results.as_deref()),
        Study::SamplingArm {
            grid,
            out,
            quick,
            results,
        } => sampling_arm(grid, quick, &out, results.as_deref()),
        Study::All {
            out,
            quick,
            jobs,
            results,
        } => rig_tools::study::all::command(
            &out,
            if quick {
                rig_tools::study::all::Size::Quick
            } else {
                rig_tools::study::all::Size::Full
            },
            jobs,
            results.as_deref(),
            std::iter::once("study".to_string())
                .chain(std::env::args().skip(1))
                .collect::<Vec<_>>()
                .join(" "),
        ),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("study: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs the RCAC study `run` into `out` with `points` sweep points and the update laws of
/// `update`.
fn rcac(
    run: fn(&Path, &rcac_study::Options) -> Result<(), String>,
    out: &Path,
    points: usize,
    update: &UpdateArg,
) -> Result<(), String> {
    let updates = rcac_common::Update::parse_set(&update.update)?;
    run(out, &rcac_study::Options { points, updates })
}

/// Formats a settling statistic (`+∞` as "never").
fn steps(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.0}")
    } else {
        "never".into()
    }
}

/// Prints the (5.8) derivation and returns the discretized plant.
fn derive_plant(report: &mut String) -> Result<Plant, String> {
    let _ = writeln!(
        report,
        "Plant (5.8): ZOH discretization at T = {SAMPLE_PERIOD} s of G(s) = 1/(s^2 + (C/M) s + K/M) = M/(M s^2 + C s + K)"
    );
    for (i, (num, den)) in PRINTED.iter().enumerate() {
        let inv = Msd::from_discrete(*num, *den, SAMPLE_PERIOD);
        let m = Msd::chapter(i == 1);
        let (n, d) = m.discretize(SAMPLE_PERIOD)?;
        let _ = writeln!(
            report,
            "  {}: solved from (5.8): C/M = {:.5}, K/M = {:.5}, gain = {:.4}; used M = 5, C = {}, K = {} \
             (C/M = {}, K/M = {}, gain 1)",
            if i == 0 { "k <  100" } else { "k >= 100" },
            inv.c_over_m,
            inv.k_over_m,
            inv.gain,
            m.c_over_m * plant::MASS,
            m.k_over_m * plant::MASS,
            m.c_over_m,
            m.k_over_m
        );
        let _ = writeln!(
            report,
            "    printed (5.8): ({:.4} q + {:.4}) / (q^2 {:+.4} q {:+.4})",
            num[0], num[1], den[1], den[2]
        );
        let _ = writeln!(
            report,
            "    c2d_zoh:       ({:.4} q + {:.4}) / (q^2 {:+.4} q {:+.4})   [b0 = {:.1e}]",
            n[1], n[2], d[1], d[2], n[0]
        );
    }
    let p = Plant::chapter()?;
    let round = |v: [f64; 5]| v.map(|x| (x * 1e6).round() / 1e6);
    let _ = writeln!(report, "  true theta, k <  100: {:?}", round(p.before));
    let _ = writeln!(report, "  true theta, k >= 100: {:?}", round(p.after));
    Ok(p)
}

/// The methods compared in a case's single-run figure(s).
fn comparisons(case: Case) -> Vec<(Method, Method)> {
    match case {
        Case::Noisy => vec![
            (Method::Ftvrf, Method::Crf),
            (Method::Ftvrf, Method::Rmsvrf),
        ],
        _ => vec![(Method::Ftvrf, Method::Crf)],
    }
}

/// Median color of a method's band plot (red for FTVRF and blue for RMSVRF, as in the
/// chapter).
fn band_color(m: Method) -> RGBColor {
    match m {
        Method::Ftvrf => RGBColor(200, 0, 0),
        Method::Crf => RGBColor(0, 120, 0),
        Method::Rmsvrf => RGBColor(0, 70, 200),
    }
}

/// The chapter 5 study.
fn forgetting(runs: usize, out: &Path, seed: u64) -> Result<(), String> {
    let t_start = Instant::now();
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    output::register_font()?;
    let mut report = String::new();
    let plant = derive_plant(&mut report)?;
    let _ = writeln!(
        report,
        "RLS: theta0 = 0, P0 = 100 I, tau_n = {}, tau_d = {}, eta = {}, alpha = {}, CRF lambda = {}, noise variance {}",
        experiment::TAU_N,
        experiment::TAU_D,
        experiment::ETA,
        experiment::ALPHA,
        experiment::LAMBDA_CRF,
        experiment::NOISE_VAR
    );
    print!("{report}");

    let mut table = String::new();
    let _ = writeln!(
        table,
        "\nMonte Carlo: {runs} runs per case and method, seed {seed}. settle = steps after k = 100 until \
         ||theta_k - theta_true|| / ||theta_true|| stays < 1 % to the end of the run\n\
         (never = not below at the end; 10%: the same with a 10 % threshold);\n\
         forget k<100 = runs with lambda_k < 1 for {} <= k < 100.",
        experiment::TAU_D + 1
    );
    let _ = writeln!(
        table,
        "{:<15} {:<11} {:>6} {:>13} {:>10} {:>7} {:>14} {:>13} {:>12} {:>12} {:>13}",
        "case",
        "method",
        "steps",
        "settle median",
        "settle p95",
        "never",
        "10%: med/p95",
        "forget k<100",
        "max trP med",
        "max trP max",
        "final trP med"
    );
    let mut mc_time = 0.0;
    let mut results = Vec::new();
    for case in Case::ALL {
        let n_steps = case.steps();
        let stem = format!("case{}_{}", case.number(), case.name());
        // One run per method (run 0 of the Monte Carlo's seeds).
        let mut singles = Vec::new();
        for method in Method::ALL {
            let (_, trace) = run(&plant, case, method, n_steps, run_seed(seed, case, 0), true)?;
            let trace = trace.ok_or("no trace recorded")?;
            output::write_trace_csv(&out.join(format!("{stem}_{}.csv", method.name())), &trace)?;
            singles.push((method, trace));
        }
        for (a, b) in comparisons(case) {
            let ta = &singles.iter().find(|s| s.0 == a).ok_or("missing run")?.1;
            let tb = &singles.iter().find(|s| s.0 == b).ok_or("missing run")?.1;
            output::plot_runs(
                &out.join(format!("{stem}_{}_vs_{}.png", a.name(), b.name())),
                &format!("Case {} ({}), one run", case.number(), case.name()),
                &[(a.label(), ta), (b.label(), tb)],
            )?;
        }
        for method in Method::ALL {
            let t0 = Instant::now();
            let mc = monte_carlo(&plant, case, method, n_steps, runs, seed, true)?;
            mc_time += t0.elapsed().as_secs_f64();
            let s: Summary = mc.summary;
            results.push((case, method, s));
            output::write_bands_csv(
                &out.join(format!("{stem}_{}_mc.csv", method.name())),
                &mc.bands,
            )?;
            output::plot_bands(
                &out.join(format!("{stem}_{}_mc.png", method.name())),
                &format!(
                    "Case {} ({}), {}: median, 5th/95th percentiles of {} runs",
                    case.number(),
                    case.name(),
                    method.label(),
                    runs
                ),
                &mc.bands,
                band_color(method),
            )?;
            let _ = writeln!(
                table,
                "{:<15} {:<11} {:>6} {:>13} {:>10} {:>6.1}% {:>14} {:>12.1}% {:>12.3e} {:>12.3e} {:>13.3e}",
                format!("{} {}", case.number(), case.name()),
                method.label(),
                n_steps,
                steps(s.settle_median),
                steps(s.settle_p95),
                100.0 * s.never_fraction,
                format!(
                    "{}/{}",
                    steps(s.settle_loose_median),
                    steps(s.settle_loose_p95)
                ),
                100.0 * s.early_forget_fraction,
                s.max_trace_median,
                s.max_trace_max,
                s.final_trace_median
            );
            if s.resets > 0 {
                let _ = writeln!(table, "    ({} guard resets)", s.resets);
            }
        }
    }
    let _ = writeln!(
        table,
        "\nMonte Carlo time (simulation and bands, {} threads): {:.2} s; total {:.2} s; files in {}",
        rayon::current_num_threads(),
        mc_time,
        t_start.elapsed().as_secs_f64(),
        out.display()
    );
    print!("{table}");
    report.push_str(&table);
    std::fs::write(out.join("summary.txt"), report).map_err(|e| e.to_string())?;
    // The chapter's claims, for `study all`.
    use rig_tools::study::{reproduction, reproduction_forgetting};
    reproduction::write(
        out,
        &reproduction::Claims {
            study: "forgetting".into(),
            chapter: 5,
            run: format!("study forgetting --runs {runs} --seed {seed}"),
            claims: reproduction_forgetting::claims(&results),
        },
    )
}

/// `study mrac`: runs, prints the summary, writes `--results` if given.
fn mrac_study(
    example: &str,
    command: &str,
    grid: usize,
    out: &Path,
    results: Option<&Path>,
) -> Result<(), String> {
    let t0 = Instant::now();
    let options = mrac::Options::parse(example, command, grid)?;
    let line = format!("study mrac --example {example} --command {command} --grid {grid}");
    let report = mrac::run(&options, out, &line)?;
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
    grid: Option<usize>,
    quick: bool,
    out: &Path,
    results: Option<&Path>,
) -> Result<(), String> {
    use rig_tools::study::arm;
    let n = grid.unwrap_or(if quick {
        arm::QUICK_GRID
    } else {
        arm::DEFAULT_GRID
    });
    let line = format!("study sampling-arm --grid {n}");
    let report = arm::run(n, out, &line)?;
    print!("{}", report.markdown);
    println!(
        "\n{} threads, {:.2} s; files in {}",
        rayon::current_num_threads(),
        report.wall,
        out.display()
    );
    if let Some(path) = results {
        ipc_types::files::write_atomic(path, report.markdown.as_bytes())
            .map_err(|e| format!("--results {}: {e}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
