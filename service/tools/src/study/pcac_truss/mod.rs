//! `study pcac-truss`: predictive cost adaptive control of the 4-bay truss of chapter 6
//! under harmonic and broadband disturbances, §6.2, Figures 6.2–6.10.
//!
//! ## The experiments
//!
//! The plant is plant-proxy's `kind = "truss"` model of §6.2 ((6.1)–(6.3); see
//! `plant-proxy/MODELS.md`): `u` = the x-forces at nodes 3 and 4 (N, limited to 10 N),
//! `w` = the x-force at node 1, `y` = `10·δx` of nodes 5–8 (`δx` in mm) with sensor noise (40 dB SNR
//! at node 8 for a 0.1 Hz, 1 N tone), `z` = the same without noise. The three scenarios
//! `scenarios/truss/*.toml` ([`Experiment`]) hold the plant and the controller:
//!
//! | experiment | §     | disturbance w at node 1                 | T_s    | figures        |
//! |------------|-------|-----------------------------------------|--------|----------------|
//! | harmonic   | 6.2.1 | tones at 0.354, 1, 1.55 Hz (1 N each)   | 0.02 s | 6.2, 6.3, 6.4  |
//! | broadband  | 6.2.2 | white noise, 25 Hz Butterworth, 1 N RMS | 0.02 s | 6.5, 6.6, 6.7  |
//! | aliasing   | 6.2.3 | white noise, 50 Hz Butterworth, 1 N RMS | 0.1 s  | 6.8, 6.9, 6.10 |
//!
//! PCAC ([`control::pcac::Pcac`]) identifies the MIMO input–output model (2.24)
//!
//! ```text
//! y_k = −Σ_{i=1}^{n̂} F̂_i y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i u_{k−i},   θ = vec[F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]
//! ```
//!
//! by RLS with F-test variable-rate forgetting (2.28)–(2.35), realizes it in block-observable
//! form (2.36)–(2.42) and solves at every step the receding-horizon QP (2.43)–(2.51)
//!
//! ```text
//! min_U  Y_tᵀ Q Y_t + ΔUᵀ R ΔU,   Y_t = [C_t ŷ_{1|k}; …; C_t ŷ_{ℓ|k}],  −10 N ≤ u_{i|k} ≤ 10 N
//! ```
//!
//! with the §6.2 settings: `n̂ = 25`, `θ_0 = 10⁻¹⁰·1_600`, `P_0 = I_600`, `η = 0.1`,
//! `τ_n = 40`, `τ_d = 200`, `α = 0.001`, `ℓ = 40`, `C_t = [0 0 0 1]` (node 8),
//! `Q = 10⁶ I_40`, `R = I_80` (the text's `I_160` are dimension typos: `Y_t` has `ℓ p_t = 40`
//! entries and `ΔU` has `ℓ m = 80`), no output constraints (`C_c = 0`, `𝒟 = 0` make (2.49)
//! read `0 ≤ 0`), and the dissertation's timing (2.36): `u_{1|k}` computed at `k` is applied
//! at `k + 1` (`timing = "next-step"`).
//!
//! ## Two controller settings ([`Setting`])
//!
//! - [`Setting::Printed`]: the scenario as it is, the values above, with `y = 10·δx` in
//!   millimetres. The text gives the sensor gain 10 but no unit; in millimetres the
//!   measurements are of order 1, the scale at which the printed `P_0 = I` and
//!   `Q/R = 10⁶` are meaningful.
//! - [`Setting::Metres`]: the same controller on the same plant with `y = 10·δx` in
//!   metres. RLS minimizes `Σ |y_i − θᵀψ_i|² + (θ − θ_0)ᵀ P_0⁻¹ (θ − θ_0)`, so the prior
//!   `P_0 = I` only means something relative to the size of the signals: with
//!   `y ≈ 6·10⁻⁴` the data of a 100 s run carry less information than the prior,
//!   `tr P_k` stays near `tr P_0 = 600`, and PCAC barely acts (or, in the broadband case,
//!   acts on a wrong model). A user must scale `P_0` (about `I/σ_y²`) or the signals.
//!
//! Each experiment runs the open loop (`u ≡ 0`) and the closed loop of each setting from
//! the same scenario, hence the same seed and the same disturbance and noise realizations,
//! for [`Options::duration`] seconds (default [`DURATION_S`]), through
//! [`crate::simulate::closed_loop`] (the plant is sampled, `u_k` is computed and held over
//! `[kT_s, (k+1)T_s)`, the plant advances exactly under the ZOH).
//!
//! ## What is measured ([`Outcome`])
//!
//! - **Reduction per node** after convergence: over the late window (the last
//!   [`LATE_FRACTION`] of the run, i.e. its second half),
//!   `20 log10(RMS(z_OL) / RMS(z_CL))` of the noise-free `z` of each node.
//! - **Per-tone reduction at node 8** (harmonic case): the amplitudes of the three tones in
//!   `z` of node 8 over the late window, fitted jointly by least squares
//!   ([`control::tones::tone_amplitudes`]), open over closed, in dB.
//! - **Time to converge** ([`convergence_time`]): the trailing RMS of `z_CL` at node 8 over
//!   [`RMS_WINDOW_S`] seconds, `r_k = √(mean of z² over samples k−W+1 … k)`; the time to
//!   converge is the first `t_k` after which `r_j ≤ 2 · RMS_late(z_CL)` for every `j ≥ k`
//!   (the end of the first trailing window from which on the level stays within twice its
//!   final value).
//! - **Input bound**: `max |u|` of the closed loop, which must not exceed 10 N.
//! - **QP outcomes**: [`control::pcac::PcacCounters`] (fallbacks by cause,
//!   identification resets).
//! - `‖θ_k‖` and `tr P_k` (Figures 6.4/6.7/6.10) from the controller's logged internals
//!   `theta_norm`, `trace_p` (the trace of the full 600×600 `P_k`).
//! - For the aliasing case, the truss modes above the 5 Hz Nyquist frequency and the
//!   frequency each folds to ([`aliases`]).
//! - When ‖θ_k‖ and tr P_k settle ([`settling`]), the reductions PSD peak by peak and in-band
//!   mode by mode ([`spectral`]).
//! - The **sensitivity** of node 8's convergence to each choice §6.2 leaves open (seed,
//!   tone amplitudes and phases, broadband RMS, sensor SNR, `P_0`, the convergence rule;
//!   [`sensitivity`]), printed setting, unless `--no-sensitivity`.
//!
//! ## Its runs ([`crate::study::shard`])
//!
//! The simulations are three sharded stages whose runs follow from the options alone:
//! `open-loop` (one per experiment), `closed-loop` (one per experiment and setting) and
//! `sensitivity` (one [`sensitivity::Probe`] per experiment and simulated alternative,
//! which returns only its rows). What follows them (the outcomes, figures, tables and
//! claims) runs once, whole or in `study merge`. An experiment's "s of computation" in the
//! summary is the sum of its runs' times.
//!
//! ## What it writes
//!
//! Into the output folder, per experiment `<name>` (`harmonic`, `broadband-25hz`,
//! `broadband-50hz-aliasing`) and setting `<setting>` (`printed`, `metres`):
//!
//! - `figure-6.2-harmonic-<setting>-response.png` (6.5, 6.8): `z` of nodes 5–8, OL and CL,
//!   2×2 panels in the dissertation's order (top left node 5, then clockwise: 6, 7, 8);
//! - `figure-6.3-harmonic-<setting>-psd.png` (6.6, 6.9): the Welch PSDs of the same over the
//!   late window, log scale;
//! - `figure-6.4-harmonic-<setting>-identification.png` (6.7, 6.10): `‖θ_k‖` and `tr P_k`;
//! - `<name>-<setting>-trace.csv`: `t`, `z` OL and CL of the four nodes, `u`, the internals;
//! - `reductions.csv`: one row per experiment, setting and node (RMS OL, RMS CL, dB);
//! - `sensitivity.csv`: one row per experiment and alternative choice (node 8's time to
//!   converge and reduction);
//! - `summary.txt`: the printed summary;
//! - `claims.json`: the chapter's claims checked on these measurements
//!   ([`claims`]).

pub mod claims;
pub mod sensitivity;
pub mod settling;
pub mod spectral;

use crate::file_error::{FileError, FileOp};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::analysis::PsdError;
use crate::figures::{OPEN_COLOR, envelope};
use crate::plot::{Panel, PlotError, Series, figure};
use crate::simulate::{self, SimulateError, Trace};
pub use crate::study::common::convergence::convergence_time;
use crate::study::common::convergence::rms;
use control::pcac::{Pcac, PcacCounters, PcacParams};
use control::tones::{suppression_db, tone_amplitudes};
use plant_proxy::scenario::{self, Scenario};
use plotters::style::RGBColor;
use serde::{Deserialize, Serialize};
use service::config::{ControllerConfig, ServiceConfig};

use crate::study::common::files::write;
use crate::study::reproduction::{self, ClaimsError};

/// Why `study pcac-truss` failed, naming the option, the scenario file or the step at
/// fault.
#[derive(Debug, thiserror::Error)]
pub enum TrussError {
    /// The study's runs could not be sharded or merged, or (not a failure) its shard is done.
    #[error(transparent)]
    Shard(#[from] crate::study::shard::ShardError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// `--experiments` names an unknown experiment.
    #[error(
        "unknown experiment '{0}'; use all or a list of harmonic, broadband-25hz, \
         broadband-50hz-aliasing"
    )]
    Experiment(String),
    /// `--settings` names an unknown setting.
    #[error("unknown setting '{0}'; use both, printed or metres")]
    Setting(String),
    /// The scenario has not the eight sensor gains the `metres` setting divides.
    #[error("{}: expected the eight sensor gains '{GAIN_MM}'", .0.display())]
    Gains(PathBuf),
    /// The scenario's plant does not parse.
    #[error(transparent)]
    Scenario(#[from] plant_proxy::scenario::ScenarioError),
    /// The scenario's service configuration does not parse.
    #[error(transparent)]
    Config(#[from] service::config::ConfigError),
    /// The scenario's controller is not PCAC.
    #[error("{}: the controller is not kind = \"pcac\"", .0.display())]
    NotPcac(PathBuf),
    /// A scenario is not TOML.
    #[error("{}: {source}", path.display())]
    Toml {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: toml::de::Error,
    },
    /// The scenario has no truss.
    #[error("no [plant.truss] table")]
    NoTruss,
    /// The truss cannot be built.
    #[error(transparent)]
    Truss(#[from] plant_proxy::truss::TrussError),
    /// The scenario has no sample period.
    #[error("no rig.sample-period")]
    NoSamplePeriod,
    /// `--duration` too short for the late window.
    #[error("{0} s is too short: the late window must hold two RMS windows")]
    TooShort(f64),
    /// A run cannot be simulated.
    #[error(transparent)]
    Simulate(#[from] SimulateError),
    /// PCAC's parameters are refused.
    #[error(transparent)]
    Controller(#[from] control::ParamError),
    /// The tone amplitudes cannot be fitted (`control::tones`' message).
    #[error("{0}")]
    Tones(String),
    /// The controller does not log an internal a figure shows.
    #[error("the controller does not log {0}")]
    NotLogged(String),
    /// A PSD cannot be estimated.
    #[error(transparent)]
    Psd(#[from] PsdError),
    /// A figure cannot be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// The claims cannot be written.
    #[error(transparent)]
    Claims(#[from] ClaimsError),
    /// A run of a sharded stage failed: its error's message, as the run (perhaps a
    /// shard's) recorded it.
    #[error("{0}")]
    Run(String),
}

message_from!(TrussError);

/// Default simulated duration of each run, s.
pub const DURATION_S: f64 = 100.0;

/// The late window ("after convergence") is the last this fraction of the run.
pub const LATE_FRACTION: f64 = 0.5;

/// Length of the trailing RMS window of [`convergence_time`], s (longer than the period
/// of the slowest tone, 1/0.354 Hz = 2.8 s).
pub const RMS_WINDOW_S: f64 = 3.0;

/// The actuator force limit of §6.2, N.
pub const FORCE_LIMIT: f64 = 10.0;

/// The measured nodes, in the order of `y` and `z`.
pub const NODES: [usize; 4] = [5, 6, 7, 8];

/// Largest number of points a time series is drawn with.
const LINE_POINTS: usize = 4000;

/// Closed-loop color.
const CLOSED_COLOR: RGBColor = RGBColor(200, 30, 30);

/// One experiment of §6.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Experiment {
    /// §6.2.1: three tones, 50 Hz.
    Harmonic,
    /// §6.2.2: 25 Hz band-limited noise, 50 Hz.
    Broadband,
    /// §6.2.3: 50 Hz band-limited noise, 10 Hz (aliasing and spillover).
    Aliasing,
}

impl Experiment {
    /// All three, in the order of the chapter.
    pub const ALL: [Experiment; 3] = [
        Experiment::Harmonic,
        Experiment::Broadband,
        Experiment::Aliasing,
    ];

    /// The scenario's file stem (under `scenarios/truss/`).
    pub fn name(self) -> &'static str {
        match self {
            Experiment::Harmonic => "harmonic",
            Experiment::Broadband => "broadband-25hz",
            Experiment::Aliasing => "broadband-50hz-aliasing",
        }
    }

    /// Section and a short description.
    pub fn label(self) -> &'static str {
        match self {
            Experiment::Harmonic => "§6.2.1 harmonic disturbance (0.354, 1, 1.55 Hz), 50 Hz",
            Experiment::Broadband => "§6.2.2 25 Hz band-limited broadband disturbance, 50 Hz",
            Experiment::Aliasing => {
                "§6.2.3 50 Hz band-limited broadband disturbance, 10 Hz (aliasing)"
            }
        }
    }

    /// The dissertation's figure numbers: response, PSD, identification.
    pub fn figures(self) -> [&'static str; 3] {
        match self {
            Experiment::Harmonic => ["6.2", "6.3", "6.4"],
            Experiment::Broadband => ["6.5", "6.6", "6.7"],
            Experiment::Aliasing => ["6.8", "6.9", "6.10"],
        }
    }

    /// Parses `all` or a comma-separated list of [`Experiment::name`]s.
    pub fn parse_set(s: &str) -> Result<Vec<Experiment>, TrussError> {
        if s == "all" {
            return Ok(Self::ALL.to_vec());
        }
        s.split(',')
            .map(|n| {
                Self::ALL
                    .iter()
                    .copied()
                    .find(|e| e.name() == n.trim())
                    .ok_or_else(|| TrussError::Experiment(n.into()))
            })
            .collect()
    }

    /// The scenario file.
    pub fn path(self) -> PathBuf {
        scenarios_dir()
            .join("truss")
            .join(format!("{}.toml", self.name()))
    }
}

/// Which PCAC settings run (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Setting {
    /// The §6.2 values as printed (`P_0 = I_600`), the scenario as it is (`y` in 10·mm).
    Printed,
    /// The same controller on the same plant with the sensors in metres (`y = 10·δx` in
    /// m, 1000 times smaller): what the printed `P_0 = I` does when the data are small.
    Metres,
}

impl Setting {
    /// Both, printed first.
    pub const ALL: [Setting; 2] = [Setting::Printed, Setting::Metres];

    /// Name used in file names and tables.
    pub fn name(self) -> &'static str {
        match self {
            Setting::Printed => "printed",
            Setting::Metres => "metres",
        }
    }

    /// Short description.
    pub fn label(self) -> &'static str {
        match self {
            Setting::Printed => "PCAC as printed (P_0 = I), y in 10·mm",
            Setting::Metres => "PCAC as printed (P_0 = I), y in 10·m",
        }
    }

    /// The factor from this setting's output unit to the scenario's (10·mm): the closed
    /// loop's `y` and `z` are converted so that they compare with the open loop.
    pub fn to_millimetres(self) -> f64 {
        match self {
            Setting::Printed => 1.0,
            Setting::Metres => 1e3,
        }
    }

    /// Parses `both` or one [`Setting::name`].
    pub fn parse_set(s: &str) -> Result<Vec<Setting>, TrussError> {
        match s {
            "both" | "all" => Ok(Self::ALL.to_vec()),
            "printed" => Ok(vec![Setting::Printed]),
            "metres" => Ok(vec![Setting::Metres]),
            other => Err(TrussError::Setting(other.into())),
        }
    }
}

/// `scenarios/` of the workspace.
fn scenarios_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios")
}

/// The sensor gain of the scenario files (10 per mm of `δx`, per metre) and the one of
/// [`Setting::Metres`] (10 per m).
const GAIN_MM: &str = "gain = 10000.0";
const GAIN_M: &str = "gain = 10.0";

/// The plant and the PCAC parameters of an experiment with a setting, read as the
/// service reads them (`rig launch <scenario>`); [`Setting::Metres`] reads the same
/// text with the eight sensor gains divided by 1000.
pub fn load(exp: Experiment, setting: Setting) -> Result<(Scenario, PcacParams), TrussError> {
    let path = exp.path();
    let mut text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(source) => return Err(FileError::new(FileOp::Reading, path, source).into()),
    };
    if setting == Setting::Metres {
        if text.matches(GAIN_MM).count() != 8 {
            return Err(TrussError::Gains(path));
        }
        text = text.replace(GAIN_MM, GAIN_M);
    }
    let origin = path.display().to_string();
    let sc = scenario::parse(&text, &origin)?;
    let cfg = ServiceConfig::parse(&text, &origin)?;
    match cfg.controller {
        ControllerConfig::Pcac { params } => Ok((sc, *params)),
        _ => Err(TrussError::NotPcac(path)),
    }
}

/// Options of the study.
#[derive(Debug, Clone)]
pub struct Options {
    /// Simulated duration of each run, s.
    pub duration: f64,
    /// The experiments to run.
    pub experiments: Vec<Experiment>,
    /// The controller settings to run.
    pub settings: Vec<Setting>,
    /// Run the [`sensitivity`] of the convergence claims (printed setting).
    pub sensitivity: bool,
}

/// [`PcacCounters`] as serde sees them (the `control` crate has no serde): a closed loop
/// is a sharded run's result.
#[derive(Serialize, Deserialize)]
#[serde(remote = "PcacCounters")]
struct CountersDef {
    steps: u64,
    solved: u64,
    fast_path: u64,
    infeasible: u64,
    max_iterations: u64,
    numerical_error: u64,
    refused: u64,
    fallbacks: u64,
    id_resets: u64,
    hessians_built: u64,
    factorizations_kept: u64,
    bridged: u64,
    observed: u64,
}

/// The closed loop of one setting and its measurements.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Closed {
    /// The setting.
    pub setting: Setting,
    /// The run.
    pub trace: Trace,
    /// RMS of `z` per node over the late window.
    pub rms: [f64; 4],
    /// Harmonic case: the amplitude of each tone in `z` of node 8 over the late window.
    pub tone_amps: Vec<f64>,
    /// [`convergence_time`] of node 8, s (`None`: the level is above twice its final value
    /// at the end).
    pub converge: Option<f64>,
    /// Largest `|u|`, N (`+∞` when an input is not finite).
    pub max_input: f64,
    /// The controller's counters at the end.
    #[serde(with = "CountersDef")]
    pub counters: PcacCounters,
    /// `tr P_k` at the end (the full covariance).
    pub final_trace_p: f64,
    /// `‖θ_k‖` at the end.
    pub final_theta_norm: f64,
}

/// The runs and measurements of one experiment.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Which experiment.
    pub experiment: Experiment,
    /// Sample period, s.
    pub ts: f64,
    /// The open-loop run.
    pub open: Trace,
    /// First sample of the late window.
    pub late_start: usize,
    /// RMS of `z` per node over the late window, open loop.
    pub rms_open: [f64; 4],
    /// RMS of the measurement `y` at node 8 over the whole open loop (the data scale).
    pub rms_y_open: f64,
    /// Harmonic case: the tone frequencies (Hz) and their open-loop amplitudes in `z` of
    /// node 8 over the late window.
    pub tones: Vec<(f64, f64)>,
    /// The truss modes below the Nyquist frequency, Hz ([`in_band_modes`]).
    pub in_band_modes: Vec<f64>,
    /// The closed loops, one per setting run.
    pub closed: Vec<Closed>,
    /// Node 8's convergence under each alternative of the choices §6.2 leaves open
    /// ([`sensitivity`]; empty when not run).
    pub sensitivity: Vec<sensitivity::Row>,
}

impl Outcome {
    /// Reduction of `closed` at node index `i` (0 = node 5 … 3 = node 8), dB.
    pub fn reduction(&self, closed: &Closed, i: usize) -> f64 {
        suppression_db(self.rms_open[i], closed.rms[i])
    }

    /// The closed loop of `setting`, if it ran.
    #[cfg_attr(not(test), allow(dead_code))]
    pub fn of(&self, setting: Setting) -> Option<&Closed> {
        self.closed.iter().find(|c| c.setting == setting)
    }
}

/// The scenario file as a TOML table.
fn scenario_table(path: &Path) -> Result<toml::Table, TrussError> {
    let text = std::fs::read_to_string(path)
        .map_err(|source| FileError::new(FileOp::Access, path.to_path_buf(), source))?;
    toml::from_str(&text).map_err(|source| TrussError::Toml {
        path: path.to_path_buf(),
        source,
    })
}

/// The tone frequencies (Hz) of the scenario's disturbance (empty for broadband).
fn tone_frequencies(table: &toml::Table) -> Vec<f64> {
    let tones = table
        .get("plant")
        .and_then(|p| p.get("disturbance"))
        .and_then(|d| d.get("tones"))
        .and_then(|t| t.as_array());
    tones
        .into_iter()
        .flatten()
        .filter_map(|t| t.get("frequency-hz").and_then(|f| f.as_float()))
        .collect()
}

/// The truss modes (Hz) of an experiment's scenario above its Nyquist frequency, each with
/// the frequency it folds to under sampling: `|f − k f_s|` for the nearest integer `k`.
pub fn aliases(exp: Experiment) -> Result<Vec<(f64, f64)>, TrussError> {
    let (modes, fs) = modes_and_rate(exp)?;
    Ok(modes
        .into_iter()
        .filter(|f| *f > 0.5 * fs)
        .map(|f| (f, (f - (f / fs).round() * fs).abs()))
        .collect())
}

/// The truss modes (Hz) of an experiment's scenario below its Nyquist frequency: the modes
/// inside the control bandwidth.
pub fn in_band_modes(exp: Experiment) -> Result<Vec<f64>, TrussError> {
    let (modes, fs) = modes_and_rate(exp)?;
    Ok(modes.into_iter().filter(|f| *f < 0.5 * fs).collect())
}

/// The truss modes (Hz) of an experiment's scenario and its sample rate (Hz).
fn modes_and_rate(exp: Experiment) -> Result<(Vec<f64>, f64), TrussError> {
    let table = scenario_table(&exp.path())?;
    let truss = table
        .get("plant")
        .and_then(|p| p.get("truss"))
        .ok_or(TrussError::NoTruss)?;
    let dims = plant_proxy::lti::generalized::ChannelDims {
        n_u: 2,
        n_w: 1,
        n_y: 4,
        n_z: 4,
    };
    let tp = plant_proxy::truss::from_toml(truss, dims)?;
    let ts = table
        .get("rig")
        .and_then(|r| r.get("sample-period"))
        .and_then(|v| v.as_float())
        .ok_or(TrussError::NoSamplePeriod)?;
    Ok((tp.modes.frequencies_hz(), 1.0 / ts))
}

/// Runs one experiment for `duration` s: the open loop, the closed loop of each of
/// `settings`, and the measurements.
pub fn run_experiment(
    exp: Experiment,
    settings: &[Setting],
    duration: f64,
) -> Result<Outcome, TrussError> {
    run_experiment_with(exp, settings, duration, &|_, _| {})
}

/// [`run_experiment`] with `change` applied to each loaded scenario and controller (the
/// open loop's too) before it runs ([`sensitivity`]).
pub fn run_experiment_with(
    exp: Experiment,
    settings: &[Setting],
    duration: f64,
    change: &(dyn Fn(&mut Scenario, &mut PcacParams) + Sync),
) -> Result<Outcome, TrussError> {
    let open = open_run(exp, duration, change)?;
    let closed = settings
        .iter()
        .map(|&setting| closed_run(exp, setting, duration, change))
        .collect::<Result<Vec<_>, _>>()?;
    assemble(exp, open, closed)
}

/// An experiment's sampling for `duration` s: the sample period (s), the number of
/// samples and the first sample of the late window.
#[derive(Debug, Clone, Copy)]
struct Frame {
    ts: f64,
    steps: usize,
    late_start: usize,
}

/// The printed scenario of `exp` with `change` applied, and its [`Frame`] for `duration` s
/// ([`TrussError::TooShort`] when the late window cannot hold two RMS windows).
fn frame(
    exp: Experiment,
    duration: f64,
    change: &(dyn Fn(&mut Scenario, &mut PcacParams) + Sync),
) -> Result<(Scenario, Frame), TrussError> {
    let (mut sc, mut unused) = load(exp, Setting::Printed)?;
    change(&mut sc, &mut unused);
    let ts = sc.rig.sample_period;
    let steps = (duration / ts).round() as usize;
    if steps < 4 * (RMS_WINDOW_S / ts).round() as usize {
        return Err(TrussError::TooShort(duration));
    }
    let late_start = ((1.0 - LATE_FRACTION) * steps as f64).round() as usize;
    Ok((
        sc,
        Frame {
            ts,
            steps,
            late_start,
        },
    ))
}

/// The tone frequencies of `exp`'s disturbance (Hz) and their angular frequencies per
/// sample at `ts`.
fn tones_of(exp: Experiment, ts: f64) -> Result<(Vec<f64>, Vec<f64>), TrussError> {
    let hz = tone_frequencies(&scenario_table(&exp.path())?);
    let omegas = hz
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f * ts)
        .collect();
    Ok((hz, omegas))
}

/// RMS of `z` per node of `t` over the late window.
fn per_node(t: &Trace, late_start: usize) -> [f64; 4] {
    std::array::from_fn(|i| rms(&t.z[i][late_start..]))
}

/// The amplitudes of the tones `omegas` in `z` of node 8 of `t` over the late window
/// (none for broadband).
fn amps(t: &Trace, late_start: usize, omegas: &[f64]) -> Result<Vec<f64>, TrussError> {
    if omegas.is_empty() {
        return Ok(Vec::new());
    }
    tone_amplitudes(&t.z[3][late_start..], late_start, omegas).map_err(TrussError::Tones)
}

/// The open loop of an experiment and what is measured on it alone.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Open {
    ts: f64,
    late_start: usize,
    open: Trace,
    rms_open: [f64; 4],
    rms_y_open: f64,
    tones: Vec<(f64, f64)>,
}

/// Runs the open loop of `exp` for `duration` s with `change` applied.
fn open_run(
    exp: Experiment,
    duration: f64,
    change: &(dyn Fn(&mut Scenario, &mut PcacParams) + Sync),
) -> Result<Open, TrussError> {
    let (sc, f) = frame(exp, duration, change)?;
    let open = simulate::open_loop(&sc.plant, f.ts, f.steps)?;
    let rms_open = per_node(&open, f.late_start);
    let (hz, omegas) = tones_of(exp, f.ts)?;
    let tones = hz
        .iter()
        .copied()
        .zip(amps(&open, f.late_start, &omegas)?)
        .collect();
    Ok(Open {
        ts: f.ts,
        late_start: f.late_start,
        rms_y_open: rms(&open.y[3]),
        open,
        rms_open,
        tones,
    })
}

/// Runs the closed loop of `exp` under `setting` for `duration` s with `change` applied,
/// and measures it.
fn closed_run(
    exp: Experiment,
    setting: Setting,
    duration: f64,
    change: &(dyn Fn(&mut Scenario, &mut PcacParams) + Sync),
) -> Result<Closed, TrussError> {
    let (
        _,
        Frame {
            ts,
            steps,
            late_start,
        },
    ) = frame(exp, duration, change)?;
    let (_, omegas) = tones_of(exp, ts)?;
    let (mut sc, mut params) = load(exp, setting)?;
    change(&mut sc, &mut params);
    let p = &sc.plant;
    let mut pcac = Pcac::new(&params, simulate::plant_dimensions(p))?;
    let mut trace = simulate::closed_loop(p, ts, Some(&mut pcac), steps, None)?;
    // Compare in the open loop's unit (10·mm): the controller saw its own.
    let to_mm = setting.to_millimetres();
    for v in trace.y.iter_mut().chain(trace.z.iter_mut()).flatten() {
        *v *= to_mm;
    }
    let rms_closed = per_node(&trace, late_start);
    let window = (RMS_WINDOW_S / ts).round() as usize;
    let max_input = trace.u.iter().flatten().fold(0.0_f64, |a, v| {
        if v.is_finite() {
            a.max(v.abs())
        } else {
            f64::INFINITY
        }
    });
    let last = |name: &str| {
        trace
            .internal_names
            .iter()
            .position(|n| n == name)
            .and_then(|i| trace.internals[i].last().copied())
            .unwrap_or(f64::NAN)
    };
    Ok(Closed {
        setting,
        rms: rms_closed,
        tone_amps: amps(&trace, late_start, &omegas)?,
        converge: convergence_time(&trace.z[3], ts, window, rms_closed[3]),
        max_input,
        counters: pcac.counts_of(),
        final_trace_p: last("trace_p"),
        final_theta_norm: last("theta_norm"),
        trace,
    })
}

/// The [`Outcome`] of `exp` from its open loop and its closed loops (no sensitivity).
fn assemble(exp: Experiment, open: Open, closed: Vec<Closed>) -> Result<Outcome, TrussError> {
    Ok(Outcome {
        experiment: exp,
        ts: open.ts,
        rms_y_open: open.rms_y_open,
        open: open.open,
        late_start: open.late_start,
        rms_open: open.rms_open,
        tones: open.tones,
        in_band_modes: in_band_modes(exp)?,
        closed,
        sensitivity: Vec::new(),
    })
}

/// No change to the scenario or the controller.
fn as_is(_: &mut Scenario, _: &mut PcacParams) {}

/// A run of the study's sharded stages: its outcome (or its error's message) and how long
/// it took, s.
#[derive(Debug, Serialize, Deserialize)]
struct Timed<T> {
    secs: f64,
    result: Result<T, String>,
}

impl<T> Timed<T> {
    /// Runs `f`, timed.
    fn run(f: impl FnOnce() -> Result<T, TrussError>) -> Self {
        let t = Instant::now();
        let result = f().map_err(|e| e.to_string());
        Self {
            secs: t.elapsed().as_secs_f64(),
            result,
        }
    }

    /// The outcome, or the run's error.
    fn get(self) -> Result<T, TrussError> {
        self.result.map_err(TrussError::Run)
    }
}

/// A run of the stage `open-loop`: an experiment's open loop, `duration_s` long.
#[derive(Debug)]
struct OpenLoop {
    experiment: Experiment,
    duration_s: f64,
}

/// A run of the stage `closed-loop`: an experiment's closed loop under a setting,
/// `duration_s` long.
#[derive(Debug)]
struct ClosedLoop {
    experiment: Experiment,
    setting: Setting,
    duration_s: f64,
}

/// The study (see the module docs); writes into `out` and prints the summary.
pub fn run(runs: &crate::study::shard::Runs, out: &Path, opts: &Options) -> Result<(), TrussError> {
    let t0 = Instant::now();
    std::fs::create_dir_all(out)
        .map_err(|source| FileError::new(FileOp::Access, out.to_path_buf(), source))?;
    let mut report = String::new();
    let _ = writeln!(
        report,
        "study pcac-truss: PCAC on the truss of chapter 6, open and closed loop from the same seed, {} s per run\n\
         PCAC (§6.2): n_hat = 25, theta_0 = 1e-10 (600 entries), eta = 0.1, tau_n = 40, tau_d = 200, alpha = 0.001, \
         l = 40, C_t = [0 0 0 1], Q = 1e6 I_40, R = I_80, |u| <= 10 N, u_(1|k) applied at k+1\n\
         settings: printed = the §6.2 values on scenarios/truss/*.toml (y = 10·δx in mm); metres = the same with y = 10·δx in m\n\
         reduction = 20 log10(RMS z_OL / RMS z_CL) of the noise-free z over the late window (the last {:.0} % of the run);\n\
         converges = end of the first trailing {RMS_WINDOW_S} s window of z_CL at node 8 from which on its RMS stays within 2x of the late-window RMS",
        opts.duration,
        100.0 * LATE_FRACTION
    );
    // Every experiment's sampling first: a duration too short fails here, before any run
    // (and on every shard).
    for &exp in &opts.experiments {
        frame(exp, opts.duration, &as_is)?;
    }
    let open_runs: Vec<OpenLoop> = opts
        .experiments
        .iter()
        .map(|&experiment| OpenLoop {
            experiment,
            duration_s: opts.duration,
        })
        .collect();
    let closed_runs: Vec<ClosedLoop> = opts
        .experiments
        .iter()
        .flat_map(|&experiment| {
            opts.settings.iter().map(move |&setting| ClosedLoop {
                experiment,
                setting,
                duration_s: opts.duration,
            })
        })
        .collect();
    let probes: Vec<Vec<sensitivity::Probe>> = opts
        .experiments
        .iter()
        .map(|&exp| {
            if opts.sensitivity {
                sensitivity::probes(exp, opts.duration)
            } else {
                Vec::new()
            }
        })
        .collect();
    let all_probes: Vec<sensitivity::Probe> = probes.iter().flatten().cloned().collect();
    let open_stage = runs.map("open-loop", &open_runs, |r| {
        Timed::run(|| open_run(r.experiment, r.duration_s, &as_is))
    })?;
    let closed_stage = runs.map("closed-loop", &closed_runs, |r| {
        Timed::run(|| closed_run(r.experiment, r.setting, r.duration_s, &as_is))
    })?;
    let probe_stage = runs.map("sensitivity", &all_probes, |p| {
        Timed::run(|| sensitivity::run_probe(p))
    })?;
    runs.gather()?;
    let mut opens = open_stage.into_vec()?.into_iter();
    let mut closeds = closed_stage.into_vec()?.into_iter();
    let mut probed = probe_stage.into_vec()?.into_iter();
    let mut outcomes = Vec::new();
    for (&exp, probes) in opts.experiments.iter().zip(&probes) {
        let open = opens
            .next()
            .ok_or(TrussError::Run("an open loop is missing".into()))?;
        let mut secs = open.secs;
        let open = open.get()?;
        let mut closed = Vec::new();
        for _ in &opts.settings {
            let c = closeds
                .next()
                .ok_or(TrussError::Run("a closed loop is missing".into()))?;
            secs += c.secs;
            closed.push(c.get()?);
        }
        let mut o = assemble(exp, open, closed)?;
        let mut rows = Vec::new();
        for _ in probes {
            let p = probed
                .next()
                .ok_or(TrussError::Run("a sensitivity run is missing".into()))?;
            secs += p.secs;
            rows.extend(p.get()?);
        }
        o.sensitivity = sensitivity::in_order(exp, rows);
        summarize(&o, secs, &mut report)?;
        if !o.sensitivity.is_empty() {
            let within = claims::within_s(exp);
            let alternatives = o.sensitivity.iter().filter(|r| {
                !matches!(
                    r.change,
                    sensitivity::Change::Study | sensitivity::Change::Settled(_)
                )
            });
            let meets = alternatives
                .clone()
                .filter(|r| r.meets(within, claims::SUPPRESSED_DB))
                .count();
            let _ = writeln!(
                report,
                "  sensitivity (node 8, printed setting; sensitivity.csv): within {within} s under {meets} of {} alternatives; the earliest: {}",
                alternatives.count(),
                sensitivity::earliest(&o.sensitivity, claims::SUPPRESSED_DB)
                    .unwrap_or_else(|| "none converges".into())
            );
        }
        for c in &o.closed {
            write_trace_csv(
                &out.join(format!("{}-{}-trace.csv", exp.name(), c.setting.name())),
                &o,
                c,
            )?;
            response_figure(out, &o, c)?;
            psd_figure(out, &o, c)?;
            identification_figure(out, &o, c)?;
        }
        outcomes.push(o);
    }
    write_reductions_csv(&out.join("reductions.csv"), &outcomes)?;
    if opts.sensitivity {
        write_sensitivity_csv(&out.join("sensitivity.csv"), &outcomes)?;
    }
    table(&outcomes, &mut report);
    let _ = writeln!(
        report,
        "\ntotal {:.1} s; files in {}",
        t0.elapsed().as_secs_f64(),
        out.display()
    );
    print!("{report}");
    write(&out.join("summary.txt"), &report)?;
    let names = |v: Vec<&str>| v.join(",");
    let rows = sensitivity::record(&outcomes, claims::SUPPRESSED_DB);
    Ok(reproduction::write(
        out,
        &reproduction::Claims {
            study: "pcac-truss".into(),
            chapter: 6,
            run: format!(
                "study pcac-truss --duration {} --experiments {} --settings {}",
                opts.duration,
                names(opts.experiments.iter().map(|e| e.name()).collect()),
                if opts.settings.len() == Setting::ALL.len() {
                    "both".into()
                } else {
                    names(opts.settings.iter().map(|s| s.name()).collect())
                }
            ),
            claims: {
                let mut c = reproduction::with_figures(claims::claims(&outcomes), claims::FIGURES);
                reproduction::sensitivity::annotate(&mut c, &rows);
                c
            },
            sensitivity: rows,
        },
    )?)
}

fn summarize(o: &Outcome, secs: f64, report: &mut String) -> Result<(), TrussError> {
    let n = o.open.len();
    let _ = writeln!(
        report,
        "\n{} ({} s, {} samples; late window {:.1}-{:.1} s; RMS of y at node 8 in open loop {:.2e}; {:.2} s of computation)",
        o.experiment.label(),
        n as f64 * o.ts,
        n,
        o.late_start as f64 * o.ts,
        n as f64 * o.ts,
        o.rms_y_open,
        secs
    );
    for c in &o.closed {
        let _ = writeln!(report, "  {}:", c.setting.label());
        for (i, node) in NODES.iter().enumerate() {
            let _ = writeln!(
                report,
                "    node {}: RMS z open {:.4e}, closed {:.4e}, reduction {:.1} dB",
                node,
                o.rms_open[i],
                c.rms[i],
                o.reduction(c, i)
            );
        }
        for ((f, a), b) in o.tones.iter().zip(&c.tone_amps) {
            let _ = writeln!(
                report,
                "    node 8, tone {f} Hz: amplitude open {a:.4e}, closed {b:.4e}, reduction {:.1} dB",
                suppression_db(*a, *b)
            );
        }
        let k = &c.counters;
        let _ = writeln!(
            report,
            "    converges at {}; max |u| = {:.3} N; at the end ||theta|| = {:.3e}, tr P = {:.4e}\n    \
             MPC steps {}, fallbacks {} (infeasible {}, iteration cap {}, numerical {}, refused {}), identification resets {}",
            converge_text(o, c),
            c.max_input,
            c.final_theta_norm,
            c.final_trace_p,
            k.steps,
            k.fallbacks,
            k.infeasible,
            k.max_iterations,
            k.numerical_error,
            k.refused,
            k.id_resets
        );
    }
    let al = aliases(o.experiment)?;
    let list: Vec<String> = al.iter().map(|(f, a)| format!("{f:.2}->{a:.2}")).collect();
    let _ = writeln!(
        report,
        "  sampling: at f_s = {:.0} Hz, {} of the 16 truss modes lie above the {:.0} Hz Nyquist frequency and fold into \
         0-{:.0} Hz (mode Hz -> alias Hz): {}",
        1.0 / o.ts,
        al.len(),
        0.5 / o.ts,
        0.5 / o.ts,
        list.join(", ")
    );
    if o.experiment == Experiment::Aliasing {
        let _ = writeln!(
            report,
            "  aliasing: the 50 Hz disturbance band excites all of them, and the 10 Hz ZOH input excites them too (spillover)."
        );
        for c in &o.closed {
            let bounded = c.max_input <= FORCE_LIMIT && c.rms.iter().all(|r| r.is_finite());
            let worst = (0..4)
                .map(|i| o.reduction(c, i))
                .fold(f64::INFINITY, f64::min);
            let _ = writeln!(
                report,
                "    {}: the closed loop {}, {} (reductions {:.1} to {:.1} dB). The identified model sees the aliased \
                 modes as modes of the sampled plant; what lies between the samples is not measured here.",
                c.setting.label(),
                if bounded {
                    "stays bounded with |u| <= 10 N"
                } else {
                    "is NOT bounded"
                },
                if worst >= 1.0 {
                    "the sampled z of every node is reduced"
                } else {
                    "the sampled z is NOT reduced at every node"
                },
                worst,
                (0..4)
                    .map(|i| o.reduction(c, i))
                    .fold(f64::NEG_INFINITY, f64::max)
            );
        }
    }
    Ok(())
}

/// The time to converge as text: `n/a` when node 8 is not reduced by 1 dB (the level it
/// "converges" to is then the open loop's), `never` when it does not settle.
fn converge_text(o: &Outcome, c: &Closed) -> String {
    if o.reduction(c, 3) < 1.0 {
        return "n/a".into();
    }
    c.converge.map_or("never".into(), |t| format!("{t:.1} s"))
}

fn table(outcomes: &[Outcome], report: &mut String) {
    let _ = writeln!(
        report,
        "\nreduction of z after convergence (dB, late window), time to converge at node 8, fallbacks, max |u|"
    );
    let _ = writeln!(
        report,
        "{:<24} {:<9} {:>7} {:>7} {:>7} {:>7} {:>9} {:>9} {:>8}",
        "experiment",
        "setting",
        "node 5",
        "node 6",
        "node 7",
        "node 8",
        "converge",
        "fallbacks",
        "max |u|"
    );
    for o in outcomes {
        for c in &o.closed {
            let _ = writeln!(
                report,
                "{:<24} {:<9} {:>7.1} {:>7.1} {:>7.1} {:>7.1} {:>9} {:>9} {:>8.2}",
                o.experiment.name(),
                c.setting.name(),
                o.reduction(c, 0),
                o.reduction(c, 1),
                o.reduction(c, 2),
                o.reduction(c, 3),
                converge_text(o, c),
                c.counters.fallbacks,
                c.max_input
            );
        }
    }
}

fn write_trace_csv(path: &Path, o: &Outcome, c: &Closed) -> Result<(), TrussError> {
    let mut s = String::from("t");
    for n in NODES {
        let _ = write!(s, ",z_ol_node{n}");
    }
    for n in NODES {
        let _ = write!(s, ",z_cl_node{n}");
    }
    s.push_str(",u_node3,u_node4");
    for name in &c.trace.internal_names {
        let _ = write!(s, ",{name}");
    }
    s.push('\n');
    for k in 0..c.trace.len() {
        let _ = write!(s, "{:.4}", k as f64 * o.ts);
        for z in &o.open.z {
            let _ = write!(s, ",{:.6e}", z[k]);
        }
        for z in &c.trace.z {
            let _ = write!(s, ",{:.6e}", z[k]);
        }
        for u in &c.trace.u {
            let _ = write!(s, ",{:.6e}", u[k]);
        }
        for v in &c.trace.internals {
            let _ = write!(s, ",{:.6e}", v[k]);
        }
        s.push('\n');
    }
    Ok(write(path, &s)?)
}

/// `sensitivity.csv`: one row per experiment and alternative ([`sensitivity`]).
fn write_sensitivity_csv(path: &Path, outcomes: &[Outcome]) -> Result<(), TrussError> {
    let mut s = String::from(
        "experiment,choice,value,node8_converge_s,node8_reduction_db,theta_norm_settles_s,trace_p_settles_s\n",
    );
    for o in outcomes {
        for r in &o.sensitivity {
            let _ = writeln!(
                s,
                "{},{},{},{},{:.2},{},{}",
                o.experiment.name(),
                r.change.choice(),
                r.change.value(),
                r.converge.map_or("never".into(), |t| format!("{t:.2}")),
                r.reduction_db,
                r.theta_settles.map_or("-".into(), |t| format!("{t:.2}")),
                r.p_settles.map_or("-".into(), |t| format!("{t:.2}"))
            );
        }
    }
    Ok(write(path, &s)?)
}

fn write_reductions_csv(path: &Path, outcomes: &[Outcome]) -> Result<(), TrussError> {
    let mut s = String::from(
        "experiment,setting,node,sample_period_s,late_window_start_s,late_window_end_s,rms_open,rms_closed,reduction_db,converge_node8_s,fallbacks,max_abs_u\n",
    );
    for o in outcomes {
        let end = o.open.len() as f64 * o.ts;
        for c in &o.closed {
            for (i, node) in NODES.iter().enumerate() {
                let _ = writeln!(
                    s,
                    "{},{},{},{},{:.2},{:.2},{:.6e},{:.6e},{:.3},{},{},{:.4}",
                    o.experiment.name(),
                    c.setting.name(),
                    node,
                    o.ts,
                    o.late_start as f64 * o.ts,
                    end,
                    o.rms_open[i],
                    c.rms[i],
                    o.reduction(c, i),
                    c.converge.map_or("never".into(), |t| format!("{t:.2}")),
                    c.counters.fallbacks,
                    c.max_input
                );
            }
        }
    }
    Ok(write(path, &s)?)
}

/// Panel order of the dissertation: top left node 5, then clockwise (6 top right, 7
/// bottom right, 8 bottom left); the grid fills row by row.
const PANEL_NODE: [usize; 4] = [0, 1, 3, 2];

/// A line of `x` sampled every `ts` s from 0, reduced to [`LINE_POINTS`] points.
fn time_line(label: &str, x: &[f64], ts: f64, color: RGBColor) -> Series {
    Series {
        points: envelope(x, 0.0, ts, LINE_POINTS),
        ..Series::line(label, &[], &[], color)
    }
}

/// Writes Figure `fig` of the closed loop `c` of `o` into `figure-{fig}-{experiment}-{setting}-{what}.png`
/// under the title "Figure {fig}: {experiment}, {setting}: {caption}".
fn outcome_figure(
    out: &Path,
    (fig, what): (&str, &str),
    (o, c): (&Outcome, &Closed),
    caption: &str,
    (layout, size): ((usize, usize), (u32, u32)),
    panels: &[Panel],
) -> Result<(), PlotError> {
    figure(
        &out.join(format!(
            "figure-{fig}-{}-{}-{what}.png",
            o.experiment.name(),
            c.setting.name()
        )),
        &format!(
            "Figure {fig}: {}, {}: {caption}",
            o.experiment.label(),
            c.setting.label()
        ),
        layout,
        size,
        panels,
    )
}

fn response_figure(out: &Path, o: &Outcome, c: &Closed) -> Result<(), PlotError> {
    let [fig, _, _] = o.experiment.figures();
    let panels: Vec<Panel> = PANEL_NODE
        .iter()
        .map(|&i| Panel {
            title: format!(
                "node {} ({:.1} dB after convergence)",
                NODES[i],
                o.reduction(c, i)
            ),
            x_label: "time, s".into(),
            y_label: format!("y_{} = 10 δx_{} (δx in mm)", i + 1, NODES[i]),
            series: vec![
                time_line("OL", &o.open.z[i], o.ts, OPEN_COLOR),
                time_line("CL", &c.trace.z[i], o.ts, CLOSED_COLOR),
            ],
            ..Default::default()
        })
        .collect();
    outcome_figure(
        out,
        (fig, "response"),
        (o, c),
        "open (OL) and closed (CL) loop",
        ((2, 2), (1600, 1000)),
        &panels,
    )
}

fn psd_figure(out: &Path, o: &Outcome, c: &Closed) -> Result<(), TrussError> {
    let [_, fig, _] = o.experiment.figures();
    let segment = spectral::segment(o.open.len() - o.late_start);
    let fs = 1.0 / o.ts;
    let mut panels = Vec::new();
    for &i in &PANEL_NODE {
        let a = spectral::late_psd(&o.open.z[i], o.late_start, fs)?;
        let b = spectral::late_psd(&c.trace.z[i], o.late_start, fs)?;
        // The DC bin has the mean removed: leave it out of a log axis.
        panels.push(Panel {
            title: format!("node {}", NODES[i]),
            x_label: "frequency, Hz".into(),
            y_label: "PSD of z (10·mm)²/Hz".into(),
            x_log: true,
            y_log: true,
            series: vec![
                Series::line("OL", &a.freq_hz[1..], &a.density[1..], OPEN_COLOR),
                Series::line("CL", &b.freq_hz[1..], &b.density[1..], CLOSED_COLOR),
            ],
            ..Default::default()
        });
    }
    Ok(outcome_figure(
        out,
        (fig, "psd"),
        (o, c),
        &format!(
            "Welch PSD of z over {:.0}-{:.0} s (segments of {segment})",
            o.late_start as f64 * o.ts,
            o.open.len() as f64 * o.ts
        ),
        ((2, 2), (1600, 1000)),
        &panels,
    )?)
}

fn identification_figure(out: &Path, o: &Outcome, c: &Closed) -> Result<(), TrussError> {
    let [_, _, fig] = o.experiment.figures();
    let series = |name: &str| -> Result<Series, TrussError> {
        let i = c
            .trace
            .internal_names
            .iter()
            .position(|n| n == name)
            .ok_or_else(|| TrussError::NotLogged(name.into()))?;
        Ok(time_line(
            "",
            &c.trace.internals[i],
            o.ts,
            RGBColor(31, 119, 180),
        ))
    };
    let panels = vec![
        Panel {
            title: "‖θ_k‖".into(),
            x_label: "time, s".into(),
            y_label: "‖θ_k‖".into(),
            series: vec![series("theta_norm")?],
            ..Default::default()
        },
        Panel {
            title: "tr P_k (the full 600 × 600 covariance)".into(),
            x_label: "time, s".into(),
            y_label: "tr P_k".into(),
            // A log axis only when the trace spans more than a decade (it has no tick
            // inside a single decade).
            y_log: {
                let t = &series("trace_p")?.points;
                let (lo, hi) = t
                    .iter()
                    .filter(|p| p.1 > 0.0)
                    .fold((f64::INFINITY, 0.0_f64), |(l, h), p| {
                        (l.min(p.1), h.max(p.1))
                    });
                hi > 10.0 * lo
            },
            series: vec![series("trace_p")?],
            ..Default::default()
        },
    ];
    Ok(outcome_figure(
        out,
        (fig, "identification"),
        (o, c),
        "identification",
        ((1, 2), (1600, 600)),
        &panels,
    )?)
}
#[cfg(test)]
mod tests {
    use super::*;
    use control::Controller;
    use control::StepInput;
    use control::forgetting::ForgettingRule;
    use control::mpc::condense::Weight;
    use control::pcac::PcacTiming;

    /// The scenario files hold the PCAC of §6.2: n̂ = 25, p = 4, m = 2 (600 coefficients,
    /// all 1e-10), P_0 = I_600 (tr P_0 = 600: the full covariance), the F-test with
    /// τ_n = 40, τ_d = 200, η = 0.1, α = 0.001, ℓ = 40, C_t = [0 0 0 1], Q = 1e6 per tracked
    /// output (Q = 1e6 I_40), R = 1 per input (R = I_80), |u| ≤ 10 N, no move bounds, no
    /// output constraints, next-step timing; the metres setting has the same controller.
    /// The QP has ℓ·m = 80 unknowns and no inequality rows.
    #[test]
    fn the_truss_scenarios_parse_into_the_pcac_of_section_6_2() {
        for exp in Experiment::ALL {
            let (sc, printed) = load(exp, Setting::Printed).unwrap();
            let (metres_plant, metres) = load(exp, Setting::Metres).unwrap();
            let m = &printed.model;
            assert_eq!((m.n_hat, m.p, m.m), (25, 4, 2), "{exp:?}");
            assert_eq!(m.n_hat * m.p * (m.p + m.m), 600);
            assert_eq!(m.theta0, vec![1e-10; 600]);
            assert_eq!(m.p0, 1.0);
            assert_eq!(
                m.rule,
                ForgettingRule::FTest {
                    tau_n: 40,
                    tau_d: 200,
                    eta: 0.1,
                    alpha: 0.001
                }
            );
            let q = &printed.mpc;
            assert_eq!(q.horizon, 40);
            assert_eq!((q.n_inputs, q.n_outputs, q.n_tracked), (2, 4, 1));
            assert_eq!(q.tracking, vec![0.0, 0.0, 0.0, 1.0]);
            assert_eq!(q.q, Weight::PerChannel(vec![1e6]));
            assert_eq!(q.r, Weight::PerChannel(vec![1.0, 1.0]));
            assert_eq!(q.u_min, vec![-FORCE_LIMIT; 2]);
            assert_eq!(q.u_max, vec![FORCE_LIMIT; 2]);
            assert!(q.move_bounds.is_none() && q.output_constraints.is_none());
            assert_eq!(printed.timing, PcacTiming::NextStep);
            // The metres setting: the same controller, the plant's outputs 1000 times smaller.
            assert_eq!(metres, printed);
            assert_ne!(metres_plant.plant, sc.plant);
            // The built controller: tr P_0 of the full 600 × 600 covariance, an 80-unknown QP.
            let counts = ipc_types::ChannelCounts {
                n_y: 4,
                n_z: 4,
                n_r: 0,
                n_u: 2,
            };
            assert_eq!(sc.plant.n_y(), 4);
            let mut pcac = Pcac::new(&printed, service::wire::dimensions(counts)).unwrap();
            assert_eq!(pcac.model().coefficients().len(), 600);
            assert_eq!(pcac.model().trace_p(), 600.0);
            let mut u = [0.0; 2];
            pcac.step(
                &StepInput {
                    y: &[1e-4, 2e-4, 3e-4, 4e-4],
                    z: &[0.0; 4],
                    ..Default::default()
                },
                &mut u,
            );
            let qp = pcac.last_problem();
            assert_eq!(qp.f.len(), 80);
            assert!(qp.h.is_empty());
        }
    }

    /// Checks shared by the three experiments; returns the outcome.
    fn check(exp: Experiment, node8_db: f64, every_node_db: f64) -> Outcome {
        let o = run_experiment(exp, &Setting::ALL, DURATION_S).unwrap();
        for c in &o.closed {
            assert!(
                c.max_input <= FORCE_LIMIT,
                "{exp:?} {:?}: |u| reached {} N",
                c.setting,
                c.max_input
            );
            assert_eq!(c.counters.fallbacks, 0, "{exp:?} {:?}", c.setting);
            assert_eq!(c.counters.id_resets, 0, "{exp:?} {:?}", c.setting);
            assert_eq!(c.counters.steps as usize, o.open.len());
        }
        let printed = o.of(Setting::Printed).unwrap();
        let metres = o.of(Setting::Metres).unwrap();
        // In metres the data hardly inform the estimate: tr P stays near tr P_0 = 600.
        assert!(
            metres.final_trace_p > 0.9 * 600.0,
            "{exp:?}: tr P fell to {}",
            metres.final_trace_p
        );
        assert!(
            o.reduction(metres, 3) < 1.0,
            "{exp:?}: in metres node 8 was reduced by {} dB",
            o.reduction(metres, 3)
        );
        // As printed: node 8 and every node reduced, and the level settles.
        let r8 = o.reduction(printed, 3);
        eprintln!(
            "{exp:?}: node 8 reduction {r8:.1} dB, converges {:?}",
            printed.converge
        );
        assert!(r8 >= node8_db, "{exp:?}: node 8 reduced by {r8} dB");
        for (i, node) in NODES.iter().enumerate() {
            assert!(
                o.reduction(printed, i) >= every_node_db,
                "{exp:?}: node {} reduced by {} dB",
                node,
                o.reduction(printed, i)
            );
        }
        let t = printed.converge.expect("node 8 settles");
        assert!(t < 40.0, "{exp:?}: converges at {t} s");
        o
    }

    /// §6.2.1: measured 37.1 dB at node 8 (37.0 at node 7, 24.4 at nodes 5, 6), tones
    /// 33.2, 42.8, 31.9 dB, converged at 36.5 s, no fallback, |u| ≤ 10 N. Thresholds
    /// about 4 dB below. In metres: no reduction (u stays below 0.6 N).
    #[test]
    fn pcac_as_printed_suppresses_the_three_tones_at_node_8() {
        let o = check(Experiment::Harmonic, 33.0, 20.0);
        let c = o.of(Setting::Printed).unwrap();
        assert_eq!(o.tones.len(), 3);
        for ((f, a), b) in o.tones.iter().zip(&c.tone_amps) {
            let db = suppression_db(*a, *b);
            assert!(db >= 28.0, "tone {f} Hz reduced by {db} dB");
        }
    }

    /// §6.2.2: measured 19.4 dB at nodes 7, 8 (17.3 and 18.0 at nodes 5, 6), converged at
    /// 5.2 s. In metres the little the model learns is wrong: node 8 is amplified by
    /// 6.2 dB and the inputs saturate.
    #[test]
    fn pcac_as_printed_suppresses_the_25_hz_broadband_disturbance() {
        let o = check(Experiment::Broadband, 16.0, 14.0);
        let metres = o.of(Setting::Metres).unwrap();
        assert!(o.reduction(metres, 3) < -5.0);
    }

    /// §6.2.3: measured 13.2 and 13.3 dB at nodes 7, 8 (9.7 and 9.8 at nodes 5, 6),
    /// converged at 13.5 s, despite 14 of the 16 modes aliasing at 10 Hz. In metres u stays
    /// at 0.
    #[test]
    fn pcac_as_printed_suppresses_the_aliased_broadband_disturbance() {
        check(Experiment::Aliasing, 10.0, 6.5);
        let al = aliases(Experiment::Aliasing).unwrap();
        assert_eq!(al.len(), 14);
        assert!(al.iter().all(|(f, a)| *f > 5.0 && (0.0..=5.0).contains(a)));
    }

    /// The study writes its figures, traces, table and summary.
    #[test]
    fn the_study_writes_every_figure_and_table() {
        let dir = std::env::temp_dir().join(format!("pcac-truss-{}", std::process::id()));
        run(
            &crate::study::shard::Runs::whole(),
            &dir,
            &Options {
                duration: 30.0,
                experiments: vec![Experiment::Aliasing],
                settings: Setting::ALL.to_vec(),
                sensitivity: true,
            },
        )
        .unwrap();
        let sens = std::fs::read_to_string(dir.join("sensitivity.csv")).unwrap();
        assert_eq!(
            sens.lines().count(),
            1 + sensitivity::alternatives(Experiment::Aliasing).len(),
            "{sens}"
        );
        for setting in ["printed", "metres"] {
            for (fig, what) in [
                ("6.8", "response"),
                ("6.9", "psd"),
                ("6.10", "identification"),
            ] {
                let f = dir.join(format!(
                    "figure-{fig}-broadband-50hz-aliasing-{setting}-{what}.png"
                ));
                let bytes = std::fs::read(&f).unwrap();
                assert_eq!(&bytes[1..4], b"PNG", "{}", f.display());
            }
            assert!(
                dir.join(format!("broadband-50hz-aliasing-{setting}-trace.csv"))
                    .exists()
            );
        }
        let csv = std::fs::read_to_string(dir.join("reductions.csv")).unwrap();
        assert_eq!(csv.lines().count(), 1 + 2 * 4);
        let summary = std::fs::read_to_string(dir.join("summary.txt")).unwrap();
        assert!(summary.contains("fold into"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
