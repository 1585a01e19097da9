//! `study forgetting`: chapter 5, RLS with F-test variable-rate forgetting (FTVRF) against
//! constant-rate (CRF) and RMS-based variable-rate forgetting (RMSVRF) on the time-varying
//! mass-spring-damper (5.8), one seeded run per case and method and a Monte Carlo over
//! seeded runs (Figures 5.1–5.8).
//!
//! - [`plant`]: the plant (5.8) derived from the mass-spring-damper and discretized.
//! - [`experiment`]: the three cases of §5.3, the three estimators and one run.
//! - [`montecarlo`]: the Monte Carlo's seeded runs (items of the sharded stages), percentile
//!   bands, summary statistics.
//! - [`output`]: the CSV files and the PNG figures.
//! - [`excitation`]: the singular values of the regressor matrix over a stretch of steps.
//! - [`slow_runs`]: per noiseless RLS/FTVRF run, its settling, excitation after the change
//!   and the F-test's response; which runs are slow and what they have in common.
//! - [`readings`]: the readings of §5.3.1's "converge in less than 20 steps" and the
//!   slowest run under each.
//! - [`claims`]: the chapter's claims checked on the Monte Carlo statistics.
//! - [`sensitivity`]: the settings §5.3 leaves open, moved to alternatives, and the claims'
//!   verdicts under each (the report's sensitivity table).
//!
//! Its runs ([`crate::study::shard`]): four sharded stages of seeded runs whose items
//! follow from `--runs` and `--seed` alone: `montecarlo` (each case, method and seed),
//! `slow-runs` (the noiseless RLS/FTVRF runs, reduced to their features), `settings`
//! (α = 0.01 and τ_n/τ_d = 5/50) and `sensitivity` (each alternative's runs). After
//! [`crate::study::shard::Runs::gather`] come the single runs of the figures, the bands and
//! statistics from the raw runs, the files and the claims.
//!
//! It writes, into `--out`:
//!
//! - `case{c}_{case}_{method}.csv`: one run (`k, θ_k, true θ, tr(P_k), λ_k, e_k`);
//! - `case{c}_{case}_{method}_mc.csv`: 5th/50th/95th percentile bands over the Monte Carlo;
//! - `case{c}_{case}_ftvrf_vs_crf.png`, `case2_noisy_ftvrf_vs_rmsvrf.png`: single runs in
//!   the manner of Figures 5.1, 5.3, 5.5, 5.7;
//! - `case{c}_{case}_{method}_mc.png`: bands in the manner of Figures 5.2, 5.4, 5.6, 5.8;
//! - `case1_noiseless_ftvrf_runs.csv`: per noiseless RLS/FTVRF run its seed, settling
//!   under each reading, excitation and forgetting ([`slow_runs`]);
//! - `case1_noiseless_ftvrf_settle_vs_excitation.png`: settling (1 %) against `σ_min` of the
//!   regressor matrix over the 20 steps after the change, one point per run;
//! - `summary.txt`: the printed summary table, the slow runs and the readings;
//! - `claims.json`: the chapter's claims checked on the Monte Carlo ([`claims`]), with the
//!   sensitivity rows ([`sensitivity`]).

pub mod claims;
pub mod excitation;
pub mod experiment;
pub mod montecarlo;
pub mod output;
pub mod plant;
pub mod readings;
pub mod sensitivity;
pub mod slow_runs;

use crate::file_error::{FileError, FileOp};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use plotters::style::RGBColor;

use crate::plot::PlotError;
use crate::study::reproduction::{self, ClaimsError};
use experiment::{Case, Method, RunSummary, Variant, run_seed};
use montecarlo::{SeededRun, Summary};
use plant::{Msd, PRINTED, Plant, SAMPLE_PERIOD};

/// Why `study forgetting` failed.
#[derive(Debug, thiserror::Error)]
pub enum ForgettingError {
    /// The study's runs could not be sharded or merged, or (not a failure) its shard is done.
    #[error(transparent)]
    Shard(#[from] crate::study::shard::ShardError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The mass-spring-damper cannot be discretized (`plant_proxy::lti`).
    #[error(transparent)]
    Lti(#[from] plant_proxy::lti::LtiError),
    /// The discretized plant is not of second order.
    #[error("unexpected orders: num {num:?}, den {den:?}")]
    Orders {
        /// Its numerator.
        num: Vec<f64>,
        /// Its denominator.
        den: Vec<f64>,
    },
    /// The estimator's settings are refused (`control::rls`).
    #[error("{0}")]
    Rls(String),
    /// A single run recorded no trace.
    #[error("no trace recorded")]
    NoTrace,
    /// A seeded run of a stage failed (the message of its error).
    #[error("{0}")]
    Run(String),
    /// A method of a comparison figure has no single run.
    #[error("missing run")]
    MissingRun(Method),
    /// `summary.txt` cannot be written (the message is the system's alone).
    #[error("{source}")]
    Summary {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The claims cannot be written.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
}

message_from!(ForgettingError);

/// Formats a settling statistic (`+∞` as "never").
fn steps(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.0}")
    } else {
        "never".into()
    }
}

/// Prints the (5.8) derivation and returns the discretized plant.
fn derive_plant(report: &mut String) -> Result<Plant, ForgettingError> {
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

/// Every result of a stage, or the first run's error (its message).
fn all_ok<T>(results: Vec<Result<T, String>>) -> Result<Vec<T>, ForgettingError> {
    results
        .into_iter()
        .collect::<Result<_, _>>()
        .map_err(ForgettingError::Run)
}

/// `study forgetting`: the chapter 5 study, `n_runs` Monte Carlo runs per case and method
/// from the master seed `seed`, into `out` (the files above); prints the summary.
///
/// The seeded runs are handed to `runs` in four stages, all issued before any result is
/// used: `montecarlo` (every case and method, with the series of the bands), `slow-runs`
/// (the noiseless RLS/FTVRF runs' features, [`slow_runs`]), `settings` (the unprinted
/// forgetting settings, [`readings`]) and `sensitivity` (the alternatives,
/// [`sensitivity`]). After the gather, the single runs of the figures, the bands, the
/// statistics and every file are made from the runs' results.
pub fn run(
    runs: &crate::study::shard::Runs,
    n_runs: usize,
    out: &Path,
    seed: u64,
) -> Result<(), ForgettingError> {
    let t_start = Instant::now();
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Access, out.to_path_buf(), source))?;
    crate::plot::register_font()?;
    let mut report = String::new();
    let plant = derive_plant(&mut report)?;

    // The seeded runs, stage by stage; their items depend only on the options.
    let t_mc = Instant::now();
    let mc_items: Vec<SeededRun> = Case::ALL
        .iter()
        .flat_map(|&case| {
            Method::ALL.iter().flat_map(move |&method| {
                SeededRun::all(
                    case,
                    method,
                    Variant::STUDY,
                    case.steps(),
                    n_runs,
                    seed,
                    true,
                )
            })
        })
        .collect();
    let mc_stage = runs.map("montecarlo", &mc_items, |item| item.simulate(&plant))?;
    let mut mc_time = t_mc.elapsed().as_secs_f64();
    let t_slow = Instant::now();
    let slow_items = slow_runs::items(n_runs, seed);
    let slow_stage = runs.map("slow-runs", &slow_items, |item| {
        slow_runs::features_of(&plant, item)
    })?;
    let setting_items = readings::setting_items(n_runs, seed);
    let setting_stage = runs.map("settings", &setting_items, |item| {
        readings::settle_under(&plant, item)
    })?;
    let slow_time = t_slow.elapsed().as_secs_f64();
    let sensitivity_items = sensitivity::items(n_runs, seed);
    let sensitivity_stage = runs.map("sensitivity", &sensitivity_items, |item| {
        item.simulate(&plant).map(|r| r.summary)
    })?;
    runs.gather()?;
    let mc_runs = all_ok(mc_stage.into_vec()?)?;
    let features = all_ok(slow_stage.into_vec()?)?;
    let settles = all_ok(setting_stage.into_vec()?)?;
    let sensitivity_runs: Vec<RunSummary> = all_ok(sensitivity_stage.into_vec()?)?;

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
        "\nMonte Carlo: {n_runs} runs per case and method, seed {seed}. settle = steps after k = 100 until \
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
    let mut results = Vec::new();
    let mut noiseless_bands = None;
    let mut mc_chunks = mc_runs.chunks(n_runs.max(1));
    for case in Case::ALL {
        let n_steps = case.steps();
        let stem = format!("case{}_{}", case.number(), case.name());
        // One run per method (run 0 of the Monte Carlo's seeds), recorded whole for the
        // figures: nine cheap runs, made here after the gather.
        let mut singles = Vec::new();
        for method in Method::ALL {
            let (_, trace) =
                experiment::run(&plant, case, method, n_steps, run_seed(seed, case, 0), true)?;
            let trace = trace.ok_or(ForgettingError::NoTrace)?;
            output::write_trace_csv(&out.join(format!("{stem}_{}.csv", method.name())), &trace)?;
            singles.push((method, trace));
        }
        for (a, b) in comparisons(case) {
            let ta = &singles
                .iter()
                .find(|s| s.0 == a)
                .ok_or(ForgettingError::MissingRun(a))?
                .1;
            let tb = &singles
                .iter()
                .find(|s| s.0 == b)
                .ok_or(ForgettingError::MissingRun(b))?
                .1;
            output::plot_runs(
                &out.join(format!("{stem}_{}_vs_{}.png", a.name(), b.name())),
                &format!("Case {} ({}), one run", case.number(), case.name()),
                &[(a.label(), ta), (b.label(), tb)],
            )?;
        }
        for method in Method::ALL {
            let t0 = Instant::now();
            let mc = montecarlo::aggregate(&plant, n_steps, mc_chunks.next().unwrap_or(&[]), true);
            mc_time += t0.elapsed().as_secs_f64();
            let s: Summary = mc.summary;
            results.push((case, method, s));
            if (case, method) == (Case::Noiseless, Method::Ftvrf) {
                noiseless_bands = Some(mc.bands.clone());
            }
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
                    n_runs
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
    // Claim 5.1: which noiseless RLS/FTVRF runs are slow, why, and the readings of
    // "converge in less than 20 steps".
    let t_slow = Instant::now();
    slow_runs::write_csv(&out.join("case1_noiseless_ftvrf_runs.csv"), &features)?;
    output::plot_settle_vs_excitation(
        &out.join("case1_noiseless_ftvrf_settle_vs_excitation.png"),
        &features,
    )?;
    let mut why = String::new();
    if let Some(c) = slow_runs::contrast(&features, 10) {
        table.push_str(&slow_runs::report(&c, n_runs));
        why = slow_runs::why(&c);
    }
    let mut all_readings =
        readings::measurement_readings(&features, &noiseless_bands.unwrap_or_default());
    all_readings.extend(readings::setting_readings(n_runs, &settles));
    table.push_str(&readings::table(&all_readings));
    let _ = writeln!(
        table,
        "(slow runs and readings: {:.2} s)",
        slow_time + t_slow.elapsed().as_secs_f64()
    );
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
    let summary = out.join("summary.txt");
    std::fs::write(&summary, report).map_err(|source| ForgettingError::Summary {
        path: summary,
        source,
    })?;
    // The chapter's claims, for `study all`, with the sensitivity of each.
    let mut claims = reproduction::with_figures(
        claims::claims(&results, &all_readings, &why),
        claims::FIGURES,
    );
    let sensitivity =
        sensitivity::record(n_runs, &sensitivity_runs, &results, &claims, &all_readings);
    reproduction::sensitivity::annotate(&mut claims, &sensitivity);
    Ok(reproduction::write(
        out,
        &reproduction::Claims {
            study: "forgetting".into(),
            chapter: 5,
            run: format!("study forgetting --runs {n_runs} --seed {seed}"),
            claims,
            sensitivity,
        },
    )?)
}
