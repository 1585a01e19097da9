//! `rig-design`: the offline design tools, from a model or a measured log to the RCAC
//! target model (section 3.2 of the dissertation).
//!
//! ```text
//! rig-design model-frf SCENARIO [--output y|z] [--points N] [--out DIR]
//! rig-design markov    SCENARIO [--output y|z] (--count N | --first-nonzero) [--beta B] [--out DIR]
//! rig-design frf       LOG --inputs u0,u1 --outputs y0 (--sample-period T | --scenario S)
//!                      [--segment L] [--overlap F] [--compare] [--out DIR]
//! rig-design dtf       FRF.csv --method average|optimize [--delta-hz D] [--order N] [--zeros M]
//!                      [--n-max N] [--beta B] [--out DIR]
//! rig-design identify  LOG --inputs … --outputs … [frf options] --method … [dtf options]
//! rig-design compare     TARGET.toml SCENARIO --hz F1,F2,… [--output y|z]
//! rig-design example-3-41 [--out DIR]
//! rig-design robust-gain [--decay-rate λ] [--force-scale E0] [--grid N] [--out FILE]
//!                        [--objective margin|min-gain|lqr] [--state-weight WX,WY,WE]
//!                        [--input-weight R]
//! ```
//!
//! Each writes its results into `--out` (CSV, TOML, PNG) and prints a summary; the
//! `target-model.toml` files are what RCAC's configuration reads. `identify` is the whole
//! path of a measured rig: log → H1 frequency response and coherence → pure delays →
//! dereverberated transfer function per channel → target model (3.49).
//!
//! `robust-gain` solves the sampling arm's normalized (7.41) (crate feature `sdp`), checks
//! its gain independently (spectral radii at the box's vertices and over a grid) and writes
//! the gain file the arm controller reads (`scenarios/arm/robust-gain.toml` by default).
//! `--objective min-gain` or `lqr` designs another gain over the same decay-rate
//! inequalities (7.40) (`rig_tools::design::robust_gain_objective`) and writes it to
//! `scenarios/arm/robust-gain-<objective>.toml` unless `--out` says otherwise.

#![warn(missing_docs)]

use clap::{Args, Parser, Subcommand, ValueEnum};
use control::target::{TargetChannel, TargetForm, TargetModel};
use rig_tools::design::csvlog;
use rig_tools::design::dtf;
use rig_tools::design::frf_file::{FrfFile, FrfFileError};
use rig_tools::design::markov::{FirTarget, MarkovError};
use rig_tools::design::model::{DiscreteModel, ModelError, OutputSet};
use rig_tools::design::plots::{Curve, PoleZero, bode_figure, coherence_figure};
use rig_tools::design::target_response::TargetResponse;
use rig_tools::design::welch::{self, WelchOptions};
use rig_tools::design::{C64, Frf, GridError, grid};
use rig_tools::file_error::{FileError, FileOp};
use rig_tools::plot::PlotError;
use service::config::TargetModelFile;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "rig-design",
    version,
    about = "Offline design tools: frequency responses, Markov parameters, dereverberated target models"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum Output {
    /// The measurements y.
    Y,
    /// The performance outputs z.
    Z,
}

impl From<Output> for OutputSet {
    fn from(o: Output) -> Self {
        match o {
            Output::Y => OutputSet::Y,
            Output::Z => OutputSet::Z,
        }
    }
}

#[derive(Clone, Copy, ValueEnum, PartialEq)]
enum Method {
    /// Complex windowed average (3.40), then a fixed-order stable fit.
    Average,
    /// Log-frequency optimization over real poles and zeros (3.44)–(3.47).
    Optimize,
    /// No dereverberation: the FIR target (3.39) from the first `--count` samples of the
    /// measured impulse response (exact phase, `count` coefficients per channel).
    Fir,
}

#[derive(Args, Clone)]
struct FrfArgs {
    /// Columns of the log holding the inputs, comma separated (e.g. u0,u1).
    #[arg(long, value_delimiter = ',', required = true)]
    inputs: Vec<String>,
    /// Columns of the log holding the outputs, comma separated (e.g. y0).
    #[arg(long, value_delimiter = ',', required = true)]
    outputs: Vec<String>,
    /// Sample period, s (or give --scenario).
    #[arg(long)]
    sample_period: Option<f64>,
    /// The rig's scenario: its sample period, and with --compare its model.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Welch segment length, samples.
    #[arg(long, default_value_t = 2048)]
    segment: usize,
    /// Segment overlap, fraction.
    #[arg(long, default_value_t = 0.5)]
    overlap: f64,
    /// Draw and compare the model response of --scenario's plant with the estimate.
    #[arg(long, requires = "scenario")]
    compare: bool,
}

#[derive(Args, Clone)]
struct DtfArgs {
    /// Dereverberation method.
    #[arg(long, value_enum)]
    method: Method,
    /// Half-width Δ of the averaging window (3.40), Hz.
    #[arg(long)]
    delta_hz: Option<f64>,
    /// Order n̂ of the fitted DTF (average).
    #[arg(long, default_value_t = 2)]
    order: usize,
    /// Number of zeros m̂ (default: order − 1 for average; chosen ≤ n̂ for optimize).
    #[arg(long)]
    zeros: Option<usize>,
    /// Largest order n̂_max (optimize).
    #[arg(long, default_value_t = 2)]
    n_max: usize,
    /// β of (3.49), in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    beta: f64,
    /// Number of Markov parameters of the FIR target (fir).
    #[arg(long, default_value_t = 200)]
    count: usize,
    /// Lowest frequency of the fit, Hz (default: the first nonzero bin).
    #[arg(long)]
    from_hz: Option<f64>,
}

#[derive(Subcommand)]
enum Command {
    /// The frequency response of a scenario's plant, discretized as plant-proxy runs it.
    ModelFrf {
        /// Scenario TOML file.
        scenario: PathBuf,
        /// Outputs.
        #[arg(long, value_enum, default_value = "y")]
        output: Output,
        /// Grid points (linear in θ over [0, π]).
        #[arg(long, default_value_t = 4097)]
        points: usize,
        /// Output folder.
        #[arg(long, default_value = "runs/design/model-frf")]
        out: PathBuf,
    },
    /// Markov parameters of a scenario's plant and the FIR target model (3.39).
    Markov {
        /// Scenario TOML file.
        scenario: PathBuf,
        /// Outputs.
        #[arg(long, value_enum, default_value = "z")]
        output: Output,
        /// Number of Markov parameters H_0 … H_{N−1} kept.
        #[arg(long, conflicts_with = "first_nonzero")]
        count: Option<usize>,
        /// Keep only each channel's first nonzero Markov parameter (minimum-phase plants).
        #[arg(long)]
        first_nonzero: bool,
        /// β of the target model, in (0, 1].
        #[arg(long, default_value_t = 1.0)]
        beta: f64,
        /// Output folder.
        #[arg(long, default_value = "runs/design/markov")]
        out: PathBuf,
    },
    /// H1 frequency response, coherence and pure delays from a CSV log (Welch).
    Frf {
        /// CSV log (the service's signals.csv or any DAQ's).
        log: PathBuf,
        #[command(flatten)]
        frf: FrfArgs,
        /// Output folder.
        #[arg(long, default_value = "runs/design/frf")]
        out: PathBuf,
    },
    /// Dereverberated transfer function per channel and the target model (3.49).
    Dtf {
        /// Frequency-response file from `frf` or `model-frf`.
        frf_file: PathBuf,
        #[command(flatten)]
        dtf: DtfArgs,
        /// Output folder.
        #[arg(long, default_value = "runs/design/dtf")]
        out: PathBuf,
    },
    /// The whole path: log → FRF → delays → DTF → target model.
    Identify {
        /// CSV log.
        log: PathBuf,
        #[command(flatten)]
        frf: FrfArgs,
        #[command(flatten)]
        dtf: DtfArgs,
        /// Output folder.
        #[arg(long, default_value = "runs/design/identify")]
        out: PathBuf,
    },
    /// Magnitude and phase error of a target model against a scenario's plant at given
    /// frequencies (what decides RCAC's performance at a tone, Figures 3.5 and 3.8).
    Compare {
        /// Target-model file.
        target: PathBuf,
        /// Scenario TOML file.
        scenario: PathBuf,
        /// Frequencies, Hz, comma separated.
        #[arg(long, value_delimiter = ',', required = true)]
        hz: Vec<f64>,
        /// Outputs of the plant the target model stands for.
        #[arg(long, value_enum, default_value = "z")]
        output: Output,
    },
    /// The checks of sections 3.2.1.1 and 3.2.2.1: DTFs of (3.41) beside (3.43), (3.48).
    #[command(name = "example-3-41")]
    Example341 {
        /// Output folder.
        #[arg(long, default_value = "runs/design/example-3-41")]
        out: PathBuf,
    },
    /// The sampling arm's robust gain K of (7.39)–(7.41): the normalized SDP over the
    /// chapter's box of surface stiffness and damping, its independent check and the gain
    /// file (needs the crate feature `sdp`).
    RobustGain {
        /// Decay rate λ (1/s) to certify (default: the chapter's 0.05).
        #[arg(long)]
        decay_rate: Option<f64>,
        /// Force scale e_0 (N s/m) of the scaled state [ẋ, ẏ, e/e_0] (default: the one
        /// that maximizes the margin s).
        #[arg(long)]
        force_scale: Option<f64>,
        /// Grid points per axis (log-spaced) of the independent check.
        #[arg(long, default_value_t = 60)]
        grid: usize,
        /// The gain file to write (default: `scenarios/arm/robust-gain.toml` for the
        /// margin objective, `scenarios/arm/robust-gain-<objective>.toml` otherwise).
        #[arg(long)]
        out: Option<PathBuf>,
        /// What the design optimizes over the decay-rate inequalities (7.40): the margin
        /// s (the committed design), the gain's norm, or an LQR cost bound.
        #[arg(long, value_enum, default_value_t = GainObjective::Margin)]
        objective: GainObjective,
        /// LQR state weights on [ẋ, ẏ, e] in (s/m)², (s/m)², 1/N² (`--objective lqr`;
        /// default Bryson's rule with 0.1 m/s, 0.1 m/s and 25 N).
        #[arg(long, value_delimiter = ',')]
        state_weight: Option<Vec<f64>>,
        /// LQR input weight on each input (`--objective lqr`; default 0.01).
        #[arg(long)]
        input_weight: Option<f64>,
    },
}

/// The objective of `rig-design robust-gain`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum GainObjective {
    /// Maximize the margin s under s I ⪯ Q ⪯ I (the committed gain).
    Margin,
    /// Minimize the bound t ≥ ‖K̃‖² with Q ⪰ I.
    MinGain,
    /// Minimize the trace of an LQR cost bound.
    Lqr,
}

impl GainObjective {
    fn name(self) -> &'static str {
        match self {
            GainObjective::Margin => "margin",
            GainObjective::MinGain => "min-gain",
            GainObjective::Lqr => "lqr",
        }
    }
}

/// The options of `rig-design robust-gain` beyond the box (read only with the `sdp`
/// feature).
#[cfg_attr(not(feature = "sdp"), allow(dead_code))]
struct GainOptions {
    objective: GainObjective,
    state_weight: Option<Vec<f64>>,
    input_weight: Option<f64>,
}

/// Why a command of `rig-design` failed: a library step's own error (naming the file, the
/// step or the channel), or a refusal of the command itself (naming the option).
#[derive(Debug, thiserror::Error)]
enum CommandError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The command line asks for what cannot be done (the message names the option).
    #[error("{0}")]
    Usage(String),
    /// A designed gain failed a check (the message says which).
    #[cfg(feature = "sdp")]
    #[error("{0}")]
    Refused(String),
    /// A scenario cannot be read.
    #[error(transparent)]
    Scenario(#[from] plant_proxy::scenario::ScenarioError),
    /// The plant cannot be modelled.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A frequency grid cannot be made.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// Markov parameters cannot be taken.
    #[error(transparent)]
    Markov(#[from] MarkovError),
    /// A DTF cannot be designed.
    #[error(transparent)]
    Dtf(#[from] dtf::DtfError),
    /// A frequency-response file cannot be read or written.
    #[error(transparent)]
    FrfFile(#[from] FrfFileError),
    /// A signal log cannot be read.
    #[error(transparent)]
    Log(#[from] csvlog::LogError),
    /// The Welch estimate of a log failed.
    #[error("{}: {source}", log.display())]
    Welch {
        /// The log.
        log: PathBuf,
        /// Why.
        #[source]
        source: welch::WelchError,
    },
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A target-model file cannot be read, checked or written (the service's message).
    #[error("{0}")]
    Target(String),
    /// A robust gain file cannot be read or written.
    #[error(transparent)]
    RobustGainFile(#[from] rig_tools::design::robust_gain_file::RobustGainFileError),
    /// The robust gain cannot be designed.
    #[cfg(feature = "sdp")]
    #[error(transparent)]
    RobustGain(#[from] rig_tools::design::robust_gain::RobustGainError),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::ModelFrf {
            scenario,
            output,
            points,
            out,
        } => model_frf(&scenario, output, points, &out),
        Command::Markov {
            scenario,
            output,
            count,
            first_nonzero,
            beta,
            out,
        } => markov(&scenario, output, count, first_nonzero, beta, &out),
        Command::Frf { log, frf, out } => measured_frf(&log, &frf, &out).map(|_| ()),
        Command::Dtf { frf_file, dtf, out } => FrfFile::load(&frf_file)
            .map_err(CommandError::from)
            .and_then(|f| design_dtf(&f, &dtf, &out, &frf_file.display().to_string())),
        Command::Identify { log, frf, dtf, out } => measured_frf(&log, &frf, &out)
            .and_then(|f| design_dtf(&f, &dtf, &out, &log.display().to_string())),
        Command::Compare {
            target,
            scenario,
            hz,
            output,
        } => compare(&target, &scenario, &hz, output),
        Command::Example341 { out } => example_3_41(&out),
        Command::RobustGain {
            decay_rate,
            force_scale,
            grid,
            out,
            objective,
            state_weight,
            input_weight,
        } => {
            let out = out.unwrap_or_else(|| match objective {
                GainObjective::Margin => PathBuf::from("scenarios/arm/robust-gain.toml"),
                o => PathBuf::from(format!("scenarios/arm/robust-gain-{}.toml", o.name())),
            });
            let opts = GainOptions {
                objective,
                state_weight,
                input_weight,
            };
            robust_gain(decay_rate, force_scale, grid, &out, &opts)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rig-design: {e}");
            ExitCode::FAILURE
        }
    }
}

fn out_dir(out: &Path) -> Result<(), CommandError> {
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Creating, out, source).into())
}

fn load_model(scenario: &Path, output: Output) -> Result<DiscreteModel, CommandError> {
    let sc = plant_proxy::scenario::load(scenario)?;
    Ok(DiscreteModel::from_scenario(&sc, output.into())?)
}

fn channel_name(f: &Frf, c: usize) -> String {
    format!("output {} ← input {}", c / f.n_inputs, c % f.n_inputs)
}

fn model_frf(
    scenario: &Path,
    output: Output,
    points: usize,
    out: &Path,
) -> Result<(), CommandError> {
    out_dir(out)?;
    let model = load_model(scenario, output)?;
    let theta = grid(0.0, std::f64::consts::PI, points, false)?;
    let frf = model.frf(&theta)?;
    let file = FrfFile {
        frf,
        delays: model.delays.clone(),
        coherence: None,
        source: format!("model of {}", scenario.display()),
    };
    file.save(&out.join("model-frf.csv"))?;
    let hz = file.frf.hz();
    for c in 0..file.frf.response.len() {
        let name = channel_name(&file.frf, c);
        let curves = [Curve::new("G_d", &file.frf.response[c])];
        bode_figure(
            &out.join(format!("model-frf-{c}.png")),
            &format!("model response, {name}"),
            &hz,
            &curves,
            &[],
        )?;
    }
    println!(
        "model of {}: {} states, {} outputs × {} inputs, delays {:?} samples at T_s = {} s; wrote {}",
        scenario.display(),
        model.ss.n_states(),
        model.n_outputs(),
        model.n_inputs(),
        model.delays,
        model.ts,
        out.join("model-frf.csv").display()
    );
    Ok(())
}

fn markov(
    scenario: &Path,
    output: Output,
    count: Option<usize>,
    first_nonzero: bool,
    beta: f64,
    out: &Path,
) -> Result<(), CommandError> {
    out_dir(out)?;
    let model = load_model(scenario, output)?;
    let fir = match (count, first_nonzero) {
        (_, true) => FirTarget::first_nonzero_per_channel(&model, 1e-9)?,
        (Some(n), false) if n >= 1 => FirTarget::from_model(&model, n - 1),
        _ => {
            return Err(CommandError::Usage(
                "give --count N (N ≥ 1) or --first-nonzero".into(),
            ));
        }
    };
    let (p, m) = (model.n_outputs(), model.n_inputs());
    let mut csv = String::from("i");
    for o in 0..p {
        for j in 0..m {
            csv += &format!(",h_{o}_{j}");
        }
    }
    csv.push('\n');
    for (i, h) in fir.markov.iter().enumerate() {
        csv += &i.to_string();
        for o in 0..p {
            for j in 0..m {
                csv += &format!(",{}", h[(o, j)]);
            }
        }
        csv.push('\n');
    }
    let csv_path = out.join("markov.csv");
    rig_tools::study::common::files::write(&csv_path, &csv)?;
    let target = TargetModel {
        sample_period: model.ts,
        outputs: p,
        inputs: m,
        beta,
        source: format!(
            "rig-design markov {} ({} Markov parameters)",
            scenario.display(),
            fir.markov.len()
        ),
        form: TargetForm::Markov(fir.markov.clone()),
    };
    let tm_path = out.join("target-model.toml");
    // Validate what is written by reading it back.
    TargetModel::parse(&target.to_toml(), &tm_path.display().to_string())
        .map_err(CommandError::Target)?;
    target.save(&tm_path).map_err(CommandError::Target)?;
    let first = fir
        .markov
        .iter()
        .position(|h| h.iter().any(|v| *v != 0.0))
        .unwrap_or(0);
    println!(
        "{} Markov parameters of {}; first nonzero: H_{first} = {}; wrote {} and {}",
        fir.markov.len(),
        scenario.display(),
        format_matrix(&fir.markov[first]),
        csv_path.display(),
        tm_path.display()
    );
    Ok(())
}

fn format_matrix(h: &nalgebra::DMatrix<f64>) -> String {
    let rows: Vec<String> = (0..h.nrows())
        .map(|r| {
            let v: Vec<String> = h.row(r).iter().map(|x| format!("{x:.6e}")).collect();
            format!("[{}]", v.join(", "))
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

/// The sample period: `--sample-period`, or `rig.sample-period` of `--scenario`. (The
/// log's `t_sample_ns` column is wall-clock time, which a lockstep run compresses.)
fn sample_period(a: &FrfArgs) -> Result<f64, CommandError> {
    match (a.sample_period, &a.scenario) {
        (Some(t), _) if t > 0.0 && t.is_finite() => Ok(t),
        (Some(t), _) => Err(CommandError::Usage(format!(
            "--sample-period {t} is not a period"
        ))),
        (None, Some(s)) => Ok(plant_proxy::scenario::load(s)?.rig.sample_period),
        (None, None) => Err(CommandError::Usage(
            "give --sample-period T or --scenario FILE (for rig.sample-period)".into(),
        )),
    }
}

fn names(v: &[String]) -> Vec<&str> {
    v.iter().map(|s| s.as_str()).collect()
}

fn measured_frf(log_path: &Path, a: &FrfArgs, out: &Path) -> Result<FrfFile, CommandError> {
    out_dir(out)?;
    let log = csvlog::read(log_path)?;
    let ts = sample_period(a)?;
    let u = log.select(&names(&a.inputs))?;
    let y = log.select(&names(&a.outputs))?;
    let opts = WelchOptions {
        segment: a.segment,
        overlap: a.overlap,
        ..WelchOptions::default()
    };
    let est = welch::estimate(&u, &y, ts, &opts).map_err(|source| CommandError::Welch {
        log: log_path.to_path_buf(),
        source,
    })?;
    for w in &est.warnings {
        eprintln!("rig-design: warning: {w}");
    }
    let file = FrfFile {
        frf: est.frf.clone(),
        delays: est.delays.clone(),
        coherence: Some(est.coherence.clone()),
        source: format!("H1 of {}", log_path.display()),
    };
    let path = out.join("frf.csv");
    file.save(&path)?;
    let hz = file.frf.hz();
    coherence_figure(
        &out.join("coherence.png"),
        "multiple coherence of the estimate",
        &hz,
        &est.coherence,
    )?;
    let model = match (&a.scenario, a.compare) {
        (Some(s), true) => {
            let sc = plant_proxy::scenario::load(s)?;
            Some((
                DiscreteModel::from_scenario(&sc, OutputSet::Y)?.frf(&file.frf.theta)?,
                sc.plant.input_delays.clone(),
            ))
        }
        _ => None,
    };
    println!(
        "{}: {} samples at T_s = {ts} s, {} segments of {}; delays found {:?} samples",
        log_path.display(),
        log.len(),
        est.segments,
        a.segment,
        est.delays
    );
    for (o, c) in est.coherence.iter().enumerate() {
        let mut s = c[1..].to_vec();
        s.sort_by(f64::total_cmp);
        println!(
            "  output {} ({}): coherence median {:.3}, 10th percentile {:.3}",
            o,
            a.outputs[o],
            s[s.len() / 2],
            s[s.len() / 10]
        );
    }
    for c in 0..file.frf.response.len() {
        let name = format!(
            "{} ← {}",
            a.outputs[c / file.frf.n_inputs],
            a.inputs[c % file.frf.n_inputs]
        );
        let mut curves = vec![Curve::new("H1 estimate", &file.frf.response[c])];
        if let Some((m, delays)) = &model {
            curves.push(Curve::new("model", &m.response[c]).dashed());
            let o = c / file.frf.n_inputs;
            let coh = &est.coherence[o];
            let mut rel: Vec<f64> = (1..coh.len())
                .filter(|&k| coh[k] > 0.9)
                .map(|k| {
                    (file.frf.response[c][k] - m.response[c][k]).norm() / m.response[c][k].norm()
                })
                .collect();
            rel.sort_by(f64::total_cmp);
            if !rel.is_empty() {
                println!(
                    "  {name}: relative error against the model on the {} bins with coherence > 0.9: median {:.2} %, 90th percentile {:.2} %; model delay {}",
                    rel.len(),
                    100.0 * rel[rel.len() / 2],
                    100.0 * rel[rel.len() * 9 / 10],
                    delays[c % file.frf.n_inputs]
                );
            }
        }
        bode_figure(
            &out.join(format!("frf-{c}.png")),
            &format!("H1 estimate, {name}"),
            &hz,
            &curves,
            &[],
        )?;
    }
    println!("wrote {}", path.display());
    Ok(file)
}

/// Builds the DTF of every channel of `f` (delays removed) and writes the target model.
fn design_dtf(f: &FrfFile, a: &DtfArgs, out: &Path, origin: &str) -> Result<(), CommandError> {
    out_dir(out)?;
    let frf = welch::remove_delays(&f.frf, &f.delays);
    let ts = frf.ts;
    let lo = match a.from_hz {
        Some(h) => h * 2.0 * std::f64::consts::PI * ts,
        None => frf.theta.iter().copied().find(|t| *t > 0.0).unwrap_or(0.0),
    };
    let keep: Vec<usize> = (0..frf.theta.len())
        .filter(|&k| frf.theta[k] >= lo)
        .collect();
    let theta: Vec<f64> = keep.iter().map(|&k| frf.theta[k]).collect();
    let hz: Vec<f64> = theta
        .iter()
        .map(|t| t / (2.0 * std::f64::consts::PI * ts))
        .collect();
    let mut channels = Vec::new();
    for c in 0..frf.response.len() {
        let (o, i) = (c / frf.n_inputs, c % frf.n_inputs);
        let g: Vec<C64> = keep.iter().map(|&k| frf.response[c][k]).collect();
        let (fit, averaged) = match a.method {
            Method::Average => {
                let delta_hz = a.delta_hz.ok_or_else(|| {
                    CommandError::Usage(
                        "--method average needs --delta-hz (half-width Δ of the window, Hz)".into(),
                    )
                })?;
                let delta = delta_hz * 2.0 * std::f64::consts::PI * ts;
                // The window needs the whole response from 0 to π; the fit uses the band.
                let full = dtf::windowed_average(&frf.theta, &frf.response[c], delta)?;
                let avg: Vec<C64> = keep.iter().map(|&k| full[k]).collect();
                let m = a.zeros.unwrap_or(a.order.saturating_sub(1));
                (dtf::fit(&theta, &avg, None, a.order, m)?, Some(avg))
            }
            Method::Optimize => {
                let zeros = match a.zeros {
                    Some(m) => dtf::ZeroCount::Fixed(m),
                    None => dtf::ZeroCount::Choose,
                };
                let opt = dtf::optimize_all(&theta, &g, a.n_max, zeros)?;
                let tried: Vec<String> = opt
                    .candidates
                    .iter()
                    .map(|c| format!("({},{}) {:.4}", c.poles, c.zeros, c.relative_cost))
                    .collect();
                println!(
                    "output {o} ← input {i}: optimization (3.44), relative cost per structure (n̂,m̂): {}; chosen {:.4}",
                    tried.join(", "),
                    opt.relative_cost,
                );
                (opt.best, None)
            }
            Method::Fir => return measured_fir(f, a, out, origin),
        };
        let resp = fit.response(&theta);
        let err: Vec<C64> = g.iter().zip(&resp).map(|(x, y)| x - y).collect();
        let mut curves = vec![Curve::new("G_d (delay removed)", &g)];
        if let Some(avg) = &averaged {
            curves.push(Curve::new("windowed average", avg).dashed());
        }
        curves.push(Curve::new("DTF Ĝ_d", &resp));
        curves.push(
            Curve::new("error G_d − Ĝ_d", &err)
                .dashed()
                .magnitude_only(),
        );
        let poles = fit.poles()?;
        let zeros = fit.zeros()?;
        bode_figure(
            &out.join(format!("dtf-{c}.png")),
            &format!("dereverberated transfer function, output {o} ← input {i}"),
            &hz,
            &curves,
            &[PoleZero {
                label: "DTF",
                poles: &poles,
                zeros: &zeros,
            }],
        )?;
        println!(
            "output {o} ← input {i}: delay {} samples; Ĝ_d(z) = ({}) / ({}); poles {}",
            f.delays[i],
            dtf::format_poly(&fit.num),
            dtf::format_poly(&fit.den),
            dtf::format_roots(&poles)
        );
        channels.push(TargetChannel {
            output: o,
            input: i,
            delay: f.delays[i],
            num: fit.num.clone(),
            den: fit.den.clone(),
        });
    }
    let target = TargetModel {
        sample_period: ts,
        outputs: frf.n_outputs,
        inputs: frf.n_inputs,
        beta: a.beta,
        source: format!(
            "rig-design dtf --method {} of {origin}",
            if a.method == Method::Average {
                "average"
            } else {
                "optimize"
            }
        ),
        form: TargetForm::TransferFunction(channels),
    };
    let path = out.join("target-model.toml");
    TargetModel::parse(&target.to_toml(), &path.display().to_string())
        .map_err(CommandError::Target)?;
    target.save(&path).map_err(CommandError::Target)?;
    println!("wrote {} (β = {})", path.display(), a.beta);
    Ok(())
}

/// The FIR target model (3.39) from the measured impulse response.
fn measured_fir(f: &FrfFile, a: &DtfArgs, out: &Path, origin: &str) -> Result<(), CommandError> {
    let fir = FirTarget::from_measured(&f.frf, &f.delays, a.count)?;
    let target = TargetModel {
        sample_period: f.frf.ts,
        outputs: f.frf.n_outputs,
        inputs: f.frf.n_inputs,
        beta: a.beta,
        source: format!(
            "rig-design dtf --method fir --count {} of {origin}",
            a.count
        ),
        form: TargetForm::Markov(fir.markov),
    };
    let path = out.join("target-model.toml");
    TargetModel::parse(&target.to_toml(), &path.display().to_string())
        .map_err(CommandError::Target)?;
    target.save(&path).map_err(CommandError::Target)?;
    let theta: Vec<f64> = f.frf.theta.iter().copied().filter(|t| *t > 0.0).collect();
    let skip = f.frf.theta.len() - theta.len();
    let hz: Vec<f64> = theta
        .iter()
        .map(|t| t / (2.0 * std::f64::consts::PI * f.frf.ts))
        .collect();
    let gf = target.frf(&theta);
    for c in 0..f.frf.response.len() {
        let g = &f.frf.response[c][skip..];
        let gf_c: Vec<C64> = gf.response[c].iter().map(|v| v / a.beta).collect();
        let err: Vec<C64> = g.iter().zip(&gf_c).map(|(x, y)| x - y).collect();
        bode_figure(
            &out.join(format!("fir-{c}.png")),
            &format!(
                "FIR target ({} Markov parameters), {}",
                a.count,
                channel_name(&f.frf, c)
            ),
            &hz,
            &[
                Curve::new("G_d (measured)", g),
                Curve::new("FIR Σ H_i z^-i", &gf_c).dashed(),
                Curve::new("error", &err).dashed().magnitude_only(),
            ],
            &[],
        )?;
    }
    println!(
        "FIR target from the measured impulse response: {} Markov parameters per channel, delays {:?} kept as zeros; wrote {} (β = {})",
        a.count,
        f.delays,
        path.display(),
        a.beta
    );
    Ok(())
}

/// A Bode figure of `curves` over `hz` beside the poles and zeros of each labelled DTF of
/// `sets`.
fn dtf_figure(
    path: &Path,
    title: &str,
    hz: &[f64],
    curves: &[Curve<'_>],
    sets: &[(&str, &dtf::Dtf)],
) -> Result<(), CommandError> {
    let roots = sets
        .iter()
        .map(|(l, d)| Ok((*l, d.poles()?, d.zeros()?)))
        .collect::<Result<Vec<_>, CommandError>>()?;
    let pz: Vec<PoleZero<'_>> = roots
        .iter()
        .map(|(label, poles, zeros)| PoleZero {
            label,
            poles,
            zeros,
        })
        .collect();
    Ok(bode_figure(path, title, hz, curves, &pz)?)
}

fn compare(target: &Path, scenario: &Path, hz: &[f64], output: Output) -> Result<(), CommandError> {
    let tm = TargetModel::load(target).map_err(CommandError::Target)?;
    let model = load_model(scenario, output)?;
    if (tm.outputs, tm.inputs) != (model.n_outputs(), model.n_inputs()) {
        return Err(CommandError::Usage(format!(
            "{} is {}×{} but the plant of {} is {}×{}",
            target.display(),
            tm.outputs,
            tm.inputs,
            scenario.display(),
            model.n_outputs(),
            model.n_inputs()
        )));
    }
    let nyquist = 0.5 / model.ts;
    if let Some(f) = hz.iter().find(|f| !(**f > 0.0 && **f < nyquist)) {
        return Err(CommandError::Usage(format!(
            "--hz {f} is outside (0, {nyquist}) Hz"
        )));
    }
    let theta: Vec<f64> = hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f * model.ts)
        .collect();
    let (g, gf) = (model.frf(&theta)?, tm.frf(&theta));
    println!(
        "{:>10} {:>8} {:>12} {:>12} {:>12}",
        "Hz", "channel", "|G_f/G| dB", "phase err °", "|G| dB"
    );
    for (k, f) in hz.iter().enumerate() {
        for c in 0..g.response.len() {
            let r = gf.response[c][k] / g.response[c][k];
            println!(
                "{f:>10.2} {:>8} {:>12.2} {:>12.1} {:>12.2}",
                format!("{}←{}", c / g.n_inputs, c % g.n_inputs),
                20.0 * r.norm().log10(),
                r.arg().to_degrees(),
                20.0 * g.response[c][k].norm().log10()
            );
        }
    }
    Ok(())
}

fn example_3_41(out: &Path) -> Result<(), CommandError> {
    out_dir(out)?;
    let ex = dtf::example_3_41()?;
    let report = ex.report();
    print!("{report}");
    let path = out.join("summary.txt");
    rig_tools::study::common::files::write(&path, &report)?;
    let hz = |th: &[f64]| {
        th.iter()
            .map(|t| t / (2.0 * std::f64::consts::PI * ex.ts))
            .collect::<Vec<_>>()
    };
    // Figure 3.3: G_d, the windowed average and the DTF, with poles and zeros.
    let th = &ex.linear_grid;
    let (gd, avg, fit, printed) = (
        ex.gd.response(th),
        &ex.averaged_response,
        ex.averaged.response(th),
        ex.printed_3_43.response(th),
    );
    dtf_figure(
        &out.join("figure-3.3-windowed-average.png"),
        "(3.41): complex windowed average DTF, Δ = 10π rad/s, n̂ = 2",
        &hz(th),
        &[
            Curve::new("G_d", &gd),
            Curve::new("windowed average Ḡ_d", avg).dashed(),
            Curve::new("DTF Ĝ_d (this code)", &fit),
            Curve::new("printed (3.43)", &printed).dashed(),
        ],
        &[
            ("G_d", &ex.gd),
            ("DTF", &ex.averaged),
            ("(3.43)", &ex.printed_3_43),
        ],
    )?;
    // Figure 3.4: G_d and the optimization DTF.
    let th = &ex.log_grid;
    let (gd, opt, printed) = (
        ex.gd.response(th),
        ex.optimized.response(th),
        ex.printed_3_48.response(th),
    );
    dtf_figure(
        &out.join("figure-3.4-optimization.png"),
        "(3.41): optimization DTF, n̂_max = 1",
        &hz(th),
        &[
            Curve::new("G_d", &gd),
            Curve::new("DTF Ĝ_d (this code)", &opt),
            Curve::new("printed (3.48)", &printed).dashed(),
        ],
        &[
            ("G_d", &ex.gd),
            ("DTF", &ex.optimized),
            ("(3.48)", &ex.printed_3_48),
        ],
    )?;
    println!("wrote {} and the figures", path.display());
    Ok(())
}

/// `rig-design robust-gain` without the SDP solver.
#[cfg(not(feature = "sdp"))]
fn robust_gain(
    _: Option<f64>,
    _: Option<f64>,
    _: usize,
    _: &Path,
    _: &GainOptions,
) -> Result<(), CommandError> {
    Err(CommandError::Usage(
        "robust-gain needs the SDP solver: build rig-tools with `--features sdp` (it links \
         the system's OpenBLAS: apt-get install libopenblas-dev)"
            .into(),
    ))
}

/// `rig-design robust-gain`: solve, report, check, write.
#[cfg(feature = "sdp")]
fn robust_gain(
    decay_rate: Option<f64>,
    force_scale: Option<f64>,
    grid: usize,
    out: &Path,
    opts: &GainOptions,
) -> Result<(), CommandError> {
    use control::arm::robust::RobustBox;
    use rig_tools::design::robust_gain::{self as rg, MARGIN_TOLERANCE};
    use rig_tools::design::robust_gain_file::RobustGainFile;
    use rig_tools::design::robust_gain_objective::{self as obj, LqrWeights, Objective};
    use std::fmt::Write;

    let chapter = RobustBox::CHAPTER_7;
    let design = RobustBox {
        decay_rate: decay_rate.unwrap_or(chapter.decay_rate),
        ..chapter
    };
    design
        .validate()
        .map_err(|e| CommandError::Usage(format!("--decay-rate: {e}")))?;
    if grid < 2 {
        return Err(CommandError::Usage(format!(
            "--grid {grid}: at least 2 points per axis"
        )));
    }
    let objective = match opts.objective {
        GainObjective::Margin | GainObjective::MinGain
            if opts.state_weight.is_some() || opts.input_weight.is_some() =>
        {
            return Err(CommandError::Usage(format!(
                "--state-weight and --input-weight are for --objective lqr, not {}",
                opts.objective.name()
            )));
        }
        GainObjective::Margin => Objective::Margin,
        GainObjective::MinGain => Objective::MinGain,
        GainObjective::Lqr => {
            let mut w = LqrWeights::BRYSON;
            if let Some(v) = &opts.state_weight {
                w.state = match v.as_slice() {
                    [a, b, c] => [*a, *b, *c],
                    _ => {
                        return Err(CommandError::Usage(format!(
                            "--state-weight {v:?}: give three weights, on ẋ, ẏ and e"
                        )));
                    }
                };
            }
            if let Some(r) = opts.input_weight {
                w.input = r;
            }
            w.validate()
                .map_err(|e| CommandError::Usage(format!("--state-weight/--input-weight: {e}")))?;
            Objective::Lqr(w)
        }
    };
    let margin_sol = match force_scale {
        Some(e) => rg::solve(&design, e)?,
        None => rg::best_force_scale(&design)?,
    };
    // λ* with the scale of a certified design: this one, or the best at λ = 0.
    let star_scale = match (margin_sol.margin() > MARGIN_TOLERANCE, force_scale) {
        (true, _) => margin_sol.force_scale,
        (false, Some(e)) => e,
        (false, None) => {
            rg::best_force_scale(&RobustBox {
                decay_rate: 0.0,
                ..design
            })?
            .force_scale
        }
    };
    let star = rg::largest_certified_decay(&design, star_scale)?;
    // Another objective: solved at the margin design's e_0 and certified at λ.
    let alternative = match objective {
        Objective::Margin => None,
        o if margin_sol.margin() > MARGIN_TOLERANCE => {
            Some(obj::solve(&design, margin_sol.force_scale, o)?)
        }
        _ => None,
    };
    let sol = match &alternative {
        Some(a) => a.certified.clone(),
        None => margin_sol.clone(),
    };
    let command: Vec<String> = std::env::args().skip(1).collect();
    let mut r = String::new();
    let w = |r: &mut String, line: String| {
        let _ = writeln!(r, "{line}");
    };
    w(
        &mut r,
        "The robust state feedback τ_f = K χ of §7.2.2, (7.39)–(7.41), χ = [ẋ, ẏ, e].".into(),
    );
    w(&mut r, "Produced from the repository root by".into());
    w(
        &mut r,
        format!(
            "  cargo run --release -p rig-tools --features sdp --bin rig-design -- {}",
            command.join(" ")
        ),
    );
    w(
        &mut r,
        format!(
            "Box: T_s = {} s, λ = {} /s, k_s ∈ [{}, {}] N/m, c_s ∈ [{}, {}] N s/m.",
            design.sample_period,
            design.decay_rate,
            design.stiffness[0],
            design.stiffness[1],
            design.damping[0],
            design.damping[1]
        ),
    );
    w(
        &mut r,
        format!(
            "Normalized (7.41): max s s.t. the 4 vertex LMIs, Q ⪰ sI, Q ⪯ I on [ẋ, ẏ, e/e_0], e_0 = {:.4e} N s/m.",
            sol.force_scale
        ),
    );
    w(
        &mut r,
        format!(
            "{}: s = {:.4e}, cond(Q) = {:.4e}.",
            margin_sol.solver,
            margin_sol.margin(),
            margin_sol.condition()
        ),
    );
    if let Some(a) = &alternative {
        let k = a.gain();
        w(
            &mut r,
            match a.objective {
                Objective::MinGain => format!(
                    "Objective min-gain (rig_tools::design::robust_gain_objective): min t s.t. (7.40) at the 4 vertices at λ_p = {} λ, Q ⪰ I, [[t I, Y], [Yᵀ, Q]] ⪰ 0 (‖K̃‖₂² ≤ t), same e_0.",
                    obj::RATE_MARGIN
                ),
                Objective::Lqr(wt) => format!(
                    "Objective lqr (rig_tools::design::robust_gain_objective): min γ s.t. the LQR cost-bound LMI (J ≤ γ χ̃ᵀQ⁻¹χ̃) at the 4 vertices with W = diag({:e}, {:e}, {:e}) on [ẋ, ẏ, e], R = {:e} I, and the normalized (7.41) with s = σ = {} s* (σ I ⪯ Q ⪯ I), same e_0.",
                    wt.state[0],
                    wt.state[1],
                    wt.state[2],
                    wt.input,
                    obj::LQR_MARGIN_FRACTION
                ),
                Objective::Margin => String::new(),
            },
        );
        w(
            &mut r,
            format!(
                "{}: objective {:.6e}; the gain certified at λ (normalized (7.41) with Y = K̃ Q, max over Q, s): {}: s = {:.4e}, cond(Q) = {:.4e}.",
                a.solver,
                a.value,
                a.certified.solver,
                a.certified.margin(),
                a.certified.condition()
            ),
        );
        if !a.certified.certified() {
            w(
                &mut r,
                format!(
                    "Its K = [[{:.6e}, {:.6e}, {:.6e}], [{:.6e}, {:.6e}, {:.6e}]], worst spectral radius over the {grid}×{grid} grid {:.9} (bound {:.9}).",
                    k[(0, 0)],
                    k[(0, 1)],
                    k[(0, 2)],
                    k[(1, 0)],
                    k[(1, 1)],
                    k[(1, 2)],
                    design.check_gain(&k, grid).worst_grid.radius,
                    design.contraction()
                ),
            );
        }
    }
    w(
        &mut r,
        match star {
            Some(l) => format!(
                "Largest decay rate certified over the box (s > {MARGIN_TOLERANCE:e}): λ* ≈ {l:.4} /s."
            ),
            None => "Not even λ = 0 (robust stability) is certified over the box.".into(),
        },
    );
    if let Some(a) = alternative.as_ref().filter(|_| !sol.certified()) {
        print!("{r}");
        return Err(CommandError::Refused(format!(
            "the {} design's gain is not certified at λ = {} /s: the normalized (7.41) with Y = K̃ Q has s = {:.3e} ≤ {MARGIN_TOLERANCE:e} \
             ({}; the margin design is certified: --objective margin)",
            a.objective.name(),
            design.decay_rate,
            sol.margin(),
            if a.full_accuracy {
                "the program was solved to full accuracy"
            } else {
                "the program stopped at clarabel's reduced accuracy (AlmostSolved)"
            }
        )));
    }
    if !sol.certified() {
        print!("{r}");
        return Err(CommandError::Refused(format!(
            "λ = {} /s is not certified over the box: the normalized (7.41) has s = {:.3e} ≤ {MARGIN_TOLERANCE:e} \
             (no common quadratic Lyapunov function gives that decay at every (k_s, c_s)); {}",
            design.decay_rate,
            sol.margin(),
            match (star, force_scale) {
                (Some(l), _) => format!("rerun with --decay-rate at most {l:.4}"),
                (None, Some(e)) => format!(
                    "not even λ = 0 reaches the margin at --force-scale {e}: try another scale, \
                     or leave it to the search"
                ),
                (None, None) => "not even λ = 0 does: the box is too wide".into(),
            }
        )));
    }
    let m = sol.margins();
    let l = sol.lyapunov_margins();
    w(
        &mut r,
        format!(
            "LMI smallest eigenvalues at the solution: vertices {:.3e} {:.3e} {:.3e} {:.3e}, Q − sI {:.3e}, I − Q {:.3e}; (7.40) (s = 0) {:.3e}.",
            m.vertices[0],
            m.vertices[1],
            m.vertices[2],
            m.vertices[3],
            m.lower,
            m.upper,
            l.vertices.iter().copied().fold(f64::INFINITY, f64::min)
        ),
    );
    let k = sol.gain;
    w(
        &mut r,
        format!(
            "K = [[{:.6e}, {:.6e}, {:.6e}], [{:.6e}, {:.6e}, {:.6e}]]",
            k[(0, 0)],
            k[(0, 1)],
            k[(0, 2)],
            k[(1, 0)],
            k[(1, 1)],
            k[(1, 2)]
        ),
    );
    let check = design.check_gain(&k, grid);
    w(
        &mut r,
        format!(
            "Check: spectral radius of A_d + B_d K against e^(−λ T_s) = {:.9}:",
            check.bound
        ),
    );
    for v in &check.vertices {
        w(
            &mut r,
            format!(
                "  vertex (k_s, c_s) = ({:e}, {:e}): ρ = {:.9}",
                v.stiffness, v.damping, v.radius
            ),
        );
    }
    let g = check.worst_grid;
    w(
        &mut r,
        format!(
            "  worst over the {grid}×{grid} log grid: ρ = {:.9} at ({:e}, {:e})",
            g.radius, g.stiffness, g.damping
        ),
    );
    w(
        &mut r,
        format!(
            "  slowest decay of a frozen (k_s, c_s): −ln ρ / T_s = {:.4} /s (asked: {} /s)",
            -g.radius.ln() / design.sample_period,
            design.decay_rate
        ),
    );
    w(
        &mut r,
        format!("  {}", if check.passed() { "passed" } else { "FAILED" }),
    );
    print!("{r}");
    if !check.passed() {
        return Err(CommandError::Refused(format!(
            "the gain fails the independent check: worst radius {:.9} ≥ {:.9}",
            check.worst_grid.radius.max(check.worst_vertex.radius),
            check.bound
        )));
    }
    let file = RobustGainFile {
        gain: k,
        design,
        margin: sol.margin(),
    };
    if objective != Objective::Margin && alternative.is_none() {
        return Err(CommandError::Refused(format!(
            "λ = {} /s is not certified over the box: no {} design",
            design.decay_rate,
            opts.objective.name()
        )));
    }
    file.save(out, &r)?;
    if RobustGainFile::load(out)? != file {
        return Err(CommandError::Refused(format!(
            "{} does not read back as written",
            out.display()
        )));
    }
    println!("wrote {}", out.display());
    Ok(())
}
