//! The service's configuration: the `[rig]`, `[service]`, `[controller]` and `[log]` tables
//! of a scenario TOML file, read once at start-up, validated, and turned into typed
//! parameters. Nothing in the real-time loop reads a string or a map.
//!
//! A bad file or value is refused before anything starts, with the file, the field and
//! what is wrong ([`ConfigError`]). The tables read by plant-proxy (`[plant]`, `[proxy]`)
//! may share the file; the service only reads the channel counts from `[plant]` when
//! `[service.channels]` is absent.
//!
//! ```toml
//! [rig]
//! name = "acoustic-rig"
//! sample-period = 1.25e-4        # or sample-rate-hz = 8000
//!
//! [service]
//! core = 1                        # pin the RT thread (omit: no pinning)
//! fifo-priority = 80              # SCHED_FIFO priority (0: stay SCHED_OTHER)
//! mlockall = true
//! require-rt = false              # true: refuse to run when the OS refuses any of the above
//! wait = "busy-poll"              # or "block"
//! grace-periods = 800             # start-up cycles whose misses do not count toward the limit
//! max-consecutive-misses = 10     # then go to the safe state
//! miss-source = "plant"           # misses the plant reports, or "response-time" (measured here)
//! recover-after = 0               # 0: the safe state latches; N: leave it after N good cycles
//! silent-periods = 400            # no sample for this many periods: the plant is silent
//! peer-timeout = 30.0             # s to wait for the plant at start
//! safe-input = [0.0, 0.0]
//! y-min = -10.0                   # scalar or one per channel; measurements outside are rejected
//! y-max = 10.0
//! histogram-interval = 1.0        # s between interval-log entries
//! run-dir = "runs"
//! rms-settle = 2.0                # s after which the "settled" RMS of z starts
//! open-loop = 1.0                 # s of each session run open loop (u = safe-input) before
//!                                 # the controller acts; it observes those samples
//! [service.report]                # per-tone suppression of z in the run report
//! tones-hz = [800.0, 900.0]       # default: the tones of [plant.disturbance], if any
//! window = 0.5                    # s: the end of the open-loop phase against the end of the run
//! [service.channels]              # optional; default from [plant]
//! y = 1
//! z = 1
//! r = 0
//! u = 2
//!
//! [controller]
//! kind = "lti"
//! input = "y"                     # "y", "error" (r − y) or "y-and-r"
//! u-min = -1.0                    # optional saturation, scalar or per input
//! u-max = 1.0
//! [controller.ss]                 # discrete state space …
//! a = [[0.5]]
//! b = [[1.0]]
//! c = [[-0.2]]
//! d = [[0.0]]
//! # … or [controller.tf] entries = [[{ num = [..], den = [..] }]]  (discrete, in z, n_u × n_e)
//!
//! # or retrospective cost adaptive control (controller::Rcac, (2.15)–(2.23), (3.51)–(3.63)):
//! # [controller]
//! # kind = "rcac"
//! # update = "rls"                # or "gradient"
//! # input = "y"                   # the only input RCAC takes
//! # nc = 50                       # controller order n_c (≥ 1)
//! # kw = 100                      # u = 0, no update for the first kw steps (default: nc plus
//! #                               # the largest lag of G_f)
//! # rz = 1.0                      # R_z: scalar (times I) or l_z×l_z matrix, positive definite
//! # ru = 0.0                      # R_u: scalar or l_u×l_u matrix, ≥ 0 (default 0)
//! # theta0 = [...]                # optional, l_θ = l_u nc (l_u + l_y) values (default 0)
//! # u-min = -1.0                  # optional saturation, scalar or per input
//! # u-max = 1.0
//! # target-model-file = "target-model.toml"   # relative to this file's folder, or inline:
//! # # [controller.target-model] with the fields of design::target (form, sample-period, …)
//! # # update = "rls":
//! # p0 = 1.0                      # P_0 = p0 I (R_θ = I / p0), required
//! # lambda = 0.999                # constant forgetting (default 1), or a table:
//! # # [controller.forgetting] rule = "f-test" (tau-n, tau-d, eta, alpha) | "rms-ratio"
//! # #   (tau-n, tau-d, eta) | "constant" (lambda)
//! # trace-limit = 1e9             # tr P above this resets θ, P (default 10⁶ l_θ p0)
//! # # update = "gradient":
//! # # step-size = "exp"           # "opt" (3.57), "sigma" (3.60), "frobenius" (3.61), "exp" (3.63)
//! # # alpha = 0.5                 # in (0, 1], required
//! # # r = 0.0                     # R = r I ≥ 0 (default 0)
//! #
//! # or predictive cost adaptive control (controller::pcac::Pcac, (2.24)–(2.51)); the
//! # fields are listed in the `pcac` submodule's docs:
//! # [controller]
//! # kind = "pcac"
//! # n-hat = 25
//! # p0 = 1.0
//! # horizon = 40
//! # tracking = [[0.0, 0.0, 0.0, 1.0]]
//! # q = 1e6
//! # r = 1.0
//! # u-min = -10.0
//! # u-max = 10.0
//! #
//! # or, for an identification run, independent white Gaussian inputs:
//! # [controller]
//! # kind = "excitation"
//! # std = [2.0, 2.0]              # per input (or one scalar)
//! # seed = 1
//!
//! [log]
//! enabled = true
//! decimation = 1
//! queue-capacity = 65536
//! ```

mod pcac;
mod target_model_file;

pub use target_model_file::TargetModelFile;

use control::forgetting::ForgettingRule;
use control::pcac::{Pcac, PcacParams};
use control::target::TargetModel;
use control::{
    Controller, ControllerInput, ExcitationSource, LtiController, OutputLimits, Rcac, RcacParams,
    RcacUpdate, StepSize,
};
use ipc_types::ChannelCounts;
use ipc_types::rt::RtRequest;
use nalgebra::{DMatrix, DVector};
use serde::Deserialize;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Top-level tables a scenario file may contain.
pub const KNOWN_TABLES: &[&str] = &["rig", "plant", "proxy", "service", "controller", "log"];

/// A refused configuration: the file, the field and what is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    /// The file read (or the origin given to [`ServiceConfig::parse`]).
    pub file: String,
    /// The dotted field path, empty when the whole file is at fault.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.field.is_empty() {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(f, "{}: field '{}': {}", self.file, self.field, self.message)
        }
    }
}

impl std::error::Error for ConfigError {}

/// How the RT thread waits for the next measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WaitMode {
    /// Spin on the subscriber (lowest latency; burns the pinned core).
    BusyPoll,
    /// Sleep on the plant's iceoryx2 event (spares the core; adds a wake-up).
    Block,
}

/// Which misses count toward the safe-state limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MissSource {
    /// The plant's own verdict, carried in the next sample (`PREVIOUS_ACTUATION_MISSED`):
    /// the plant is the clock master and applies `u` at its deadline, so it decides.
    Plant,
    /// The service's measurement: publish time − sample time > the deadline. Stricter: it
    /// also counts the plant process's own lateness in waking up.
    ResponseTime,
}

/// The deadline and silence policy.
#[derive(Debug, Clone, PartialEq)]
pub struct DeadlinePolicy {
    /// Cycles after (re)connection whose misses do not count toward the limit.
    pub grace_cycles: u64,
    /// Consecutive misses that send the service to its safe state.
    pub max_consecutive_misses: u64,
    /// Good cycles after which the safe state is left; `None` latches it.
    pub recover_after: Option<u64>,
    /// Periods without a sample after which the plant is declared silent.
    pub silent_periods: u64,
    /// Reset the controller when a silent plant comes back.
    pub reset_on_resume: bool,
    /// Which misses count toward `max_consecutive_misses`.
    pub miss_source: MissSource,
}

/// Accepted range of each measurement channel.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementLimits {
    /// Lower bounds of `y`.
    pub y_min: Vec<f64>,
    /// Upper bounds of `y`.
    pub y_max: Vec<f64>,
    /// Lower bounds of `z`.
    pub z_min: Vec<f64>,
    /// Upper bounds of `z`.
    pub z_max: Vec<f64>,
}

/// Signal logging.
#[derive(Debug, Clone, PartialEq)]
pub struct LogConfig {
    /// Write the CSV signal log.
    pub enabled: bool,
    /// Keep every N-th sample.
    pub decimation: u32,
    /// Capacity of the lock-free queue out of the RT thread, in records.
    pub queue_capacity: usize,
}

/// The controller as configured (validated, not yet built).
#[derive(Debug, Clone, PartialEq)]
pub enum ControllerConfig {
    /// A discrete LTI controller.
    Lti {
        /// State-space matrices.
        a: DMatrix<f64>,
        /// Input matrix.
        b: DMatrix<f64>,
        /// Output matrix.
        c: DMatrix<f64>,
        /// Feedthrough.
        d: DMatrix<f64>,
        /// Initial state.
        x0: Option<DVector<f64>>,
        /// What feeds it.
        input: ControllerInput,
        /// Output saturation.
        limits: Option<OutputLimits>,
    },
    /// Independent white Gaussian inputs for identification ([`ExcitationSource`]).
    Excitation {
        /// Standard deviation per input.
        std: Vec<f64>,
        /// Generator seed.
        seed: u64,
        /// Output saturation.
        limits: Option<OutputLimits>,
    },
    /// Retrospective cost adaptive control ([`Rcac`]).
    Rcac {
        /// The validated parameters.
        params: Box<RcacParams>,
    },
    /// Predictive cost adaptive control ([`Pcac`]).
    Pcac {
        /// The validated parameters.
        params: Box<PcacParams>,
    },
}

impl ControllerConfig {
    /// Builds the controller (allocating; before the RT thread starts).
    pub fn build(&self, counts: ChannelCounts) -> Result<Box<dyn Controller>, String> {
        match self {
            ControllerConfig::Lti {
                a,
                b,
                c,
                d,
                x0,
                input,
                limits,
            } => {
                let mut ctl = LtiController::new(
                    a.clone(),
                    b.clone(),
                    c.clone(),
                    d.clone(),
                    *input,
                    crate::wire::dimensions(counts),
                    limits.clone(),
                )?;
                if let Some(x0) = x0 {
                    ctl = ctl.with_initial_state(x0.clone())?;
                }
                Ok(Box::new(ctl))
            }
            ControllerConfig::Excitation { std, seed, limits } => {
                Ok(Box::new(ExcitationSource::new(
                    crate::wire::dimensions(counts),
                    std.clone(),
                    *seed,
                    limits.clone(),
                )?))
            }
            ControllerConfig::Rcac { params } => Ok(Box::new(Rcac::new(
                params,
                crate::wire::dimensions(counts),
            )?)),
            ControllerConfig::Pcac { params } => Ok(Box::new(Pcac::new(
                params,
                crate::wire::dimensions(counts),
            )?)),
        }
    }
}

/// The validated configuration of the service.
#[derive(Debug, Clone, PartialEq)]
pub struct ServiceConfig {
    /// The file it came from.
    pub origin: String,
    /// Rig name (service names derive from it).
    pub rig: String,
    /// Sampling period the controller was designed for, in ns.
    pub sample_period_ns: u64,
    /// Channels the service reads and writes.
    pub counts: ChannelCounts,
    /// Real-time set-up of the loop thread.
    pub rt: RtRequest,
    /// Refuse to run when any RT set-up step is refused.
    pub require_rt: bool,
    /// How the loop waits.
    pub wait: WaitMode,
    /// Deadline and silence policy.
    pub policy: DeadlinePolicy,
    /// Accepted measurement ranges.
    pub limits: MeasurementLimits,
    /// Input applied in the safe state and before the first controller output.
    pub safe_input: Vec<f64>,
    /// How long to wait for the plant at start.
    pub peer_timeout: Duration,
    /// Cycles per histogram interval.
    pub histogram_interval_cycles: u64,
    /// Response-time budget for the "over budget" count, in ns (the sample period).
    pub budget_ns: u64,
    /// Signal logging.
    pub log: LogConfig,
    /// Folder under which each run gets its own folder.
    pub run_dir: PathBuf,
    /// The controller.
    pub controller: ControllerConfig,
    /// Cycles after which the "settled" RMS of `z` starts accumulating.
    pub rms_settle_cycles: u64,
    /// Cycles at the start of each session run open loop (`u` = safe input) while the
    /// controller only observes.
    pub open_loop_cycles: u64,
    /// The per-tone suppression report.
    pub tone_report: ToneReportConfig,
}

/// What the run report measures tone by tone (`[service.report]`).
#[derive(Debug, Clone, PartialEq)]
pub struct ToneReportConfig {
    /// Tone frequencies in Hz (empty: no tone report).
    pub tones_hz: Vec<f64>,
    /// Where they came from (`service.report.tones-hz` or `plant.disturbance`).
    pub source: String,
    /// Samples in each window (the open-loop window ends when the controller starts; the
    /// closed-loop window is the end of the run).
    pub window_cycles: u64,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case")]
struct RawFile {
    rig: Option<RawRig>,
    service: Option<RawService>,
    controller: Option<toml::Value>,
    log: Option<RawLog>,
    plant: Option<toml::Value>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case")]
struct RawRig {
    name: String,
    sample_period: Option<f64>,
    sample_rate_hz: Option<f64>,
    #[allow(dead_code)]
    duration: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawChannels {
    y: usize,
    z: usize,
    #[serde(default)]
    r: usize,
    u: usize,
}

/// A scalar or one value per channel.
#[derive(Deserialize, Clone)]
#[serde(untagged)]
enum ScalarOrVec {
    Scalar(f64),
    Vec(Vec<f64>),
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawService {
    core: Option<usize>,
    fifo_priority: Option<i32>,
    mlockall: Option<bool>,
    require_rt: Option<bool>,
    wait: Option<WaitMode>,
    grace_periods: Option<u64>,
    max_consecutive_misses: Option<u64>,
    recover_after: Option<u64>,
    silent_periods: Option<u64>,
    reset_on_resume: Option<bool>,
    miss_source: Option<MissSource>,
    peer_timeout: Option<f64>,
    safe_input: Option<ScalarOrVec>,
    y_min: Option<ScalarOrVec>,
    y_max: Option<ScalarOrVec>,
    z_min: Option<ScalarOrVec>,
    z_max: Option<ScalarOrVec>,
    histogram_interval: Option<f64>,
    run_dir: Option<PathBuf>,
    rms_settle: Option<f64>,
    open_loop: Option<f64>,
    report: Option<RawReport>,
    channels: Option<RawChannels>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawReport {
    tones_hz: Option<Vec<f64>>,
    window: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawLog {
    enabled: Option<bool>,
    decimation: Option<u32>,
    queue_capacity: Option<usize>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawLti {
    kind: String,
    input: Option<String>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    ss: Option<RawSs>,
    tf: Option<RawTfMatrix>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawSs {
    a: Vec<Vec<f64>>,
    b: Vec<Vec<f64>>,
    c: Vec<Vec<f64>>,
    d: Vec<Vec<f64>>,
    x0: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawTfMatrix {
    entries: Vec<Vec<RawTfEntry>>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum RawTfEntry {
    Zero(i64),
    Tf { num: Vec<f64>, den: Vec<f64> },
}

impl ServiceConfig {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: origin.clone(),
            field: String::new(),
            message: format!("cannot read the file: {e}"),
        })?;
        Self::parse(&text, &origin)
    }

    /// Reads a scenario file whose `[controller]` table (and `[log]` table, if present) is
    /// replaced by those of `controller_file`: the same rig, plant and service, another
    /// controller (for example an identification run with `kind = "excitation"`). Errors
    /// in the replaced tables name `controller_file`; a relative target-model file in it is
    /// found from `controller_file`'s folder.
    pub fn load_with_controller(path: &Path, controller_file: &Path) -> Result<Self, ConfigError> {
        let read = |p: &Path| -> Result<toml::Table, ConfigError> {
            let origin = p.display().to_string();
            let e = |message: String| ConfigError {
                file: origin.clone(),
                field: String::new(),
                message,
            };
            let text =
                std::fs::read_to_string(p).map_err(|x| e(format!("cannot read the file: {x}")))?;
            toml::from_str(&text).map_err(|x| e(format!("not valid TOML: {x}")))
        };
        let mut base = read(path)?;
        let over = read(controller_file)?;
        let origin = format!(
            "{} (controller from {})",
            path.display(),
            controller_file.display()
        );
        for key in over.keys() {
            if key != "controller" && key != "log" {
                return Err(ConfigError {
                    file: controller_file.display().to_string(),
                    field: key.clone(),
                    message: "a controller file may hold only [controller] and [log]".into(),
                });
            }
        }
        if !over.contains_key("controller") {
            return Err(ConfigError {
                file: controller_file.display().to_string(),
                field: "controller".into(),
                message: "the [controller] table is missing".into(),
            });
        }
        for (k, v) in over {
            base.insert(k, v);
        }
        let text = toml::to_string(&base).map_err(|e| ConfigError {
            file: origin.clone(),
            field: String::new(),
            message: format!("cannot merge the tables: {e}"),
        })?;
        let base_dir = controller_file
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        Self::parse_in(&text, &origin, &base_dir)
    }

    /// Validates the text of a scenario file; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let base_dir = Path::new(origin)
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_default();
        Self::parse_in(text, origin, &base_dir)
    }

    /// [`ServiceConfig::parse`] with relative file names in the controller table (a
    /// target-model file) resolved from `base_dir`.
    fn parse_in(text: &str, origin: &str, base_dir: &Path) -> Result<Self, ConfigError> {
        let err = |field: &str, message: String| ConfigError {
            file: origin.to_string(),
            field: field.to_string(),
            message,
        };
        let table: toml::Table =
            toml::from_str(text).map_err(|e| err("", format!("not valid TOML: {e}")))?;
        for key in table.keys() {
            if !KNOWN_TABLES.contains(&key.as_str()) {
                return Err(err(
                    key,
                    format!(
                        "unknown table; the known ones are {}",
                        KNOWN_TABLES.join(", ")
                    ),
                ));
            }
        }
        let raw: RawFile = toml::from_str(text).map_err(|e| err("", e.to_string()))?;
        let rig = raw
            .rig
            .ok_or_else(|| err("rig", "the [rig] table is missing".into()))?;
        if let Err(e) = ipc_types::ports::service_names(&rig.name) {
            return Err(err("rig.name", e.to_string()));
        }
        let period = match (rig.sample_period, rig.sample_rate_hz) {
            (Some(t), None) => t,
            (None, Some(f)) if f > 0.0 => 1.0 / f,
            (None, Some(f)) => {
                return Err(err("rig.sample-rate-hz", format!("{f} is not positive")));
            }
            (Some(_), Some(_)) => {
                return Err(err(
                    "rig",
                    "give sample-period or sample-rate-hz, not both".into(),
                ));
            }
            (None, None) => return Err(err("rig.sample-period", "missing".into())),
        };
        if !(period.is_finite() && period > 1e-7 && period < 100.0) {
            return Err(err(
                "rig.sample-period",
                format!("{period} s is not a usable period"),
            ));
        }
        let sample_period_ns = (period * 1e9).round() as u64;
        let s = raw.service.unwrap_or_default();

        let counts =
            match &s.channels {
                Some(c) => ChannelCounts::new(c.y, c.z, c.r, c.u)
                    .map_err(|m| err("service.channels", m))?,
                None => channels_from_plant(raw.plant.as_ref())
                    .map_err(|m| err("service.channels", m))?,
            };
        let n_y = counts.n_y as usize;
        let n_z = counts.n_z as usize;
        let n_u = counts.n_u as usize;
        if n_u == 0 {
            return Err(err(
                "service.channels.u",
                "the service needs at least one input u".into(),
            ));
        }

        let fifo_priority = ipc_types::rt::fifo_priority_from_config(s.fifo_priority, 80)
            .map_err(|m| err("service.fifo-priority", m))?;
        let rt = RtRequest {
            core: s.core,
            fifo_priority,
            mlockall: s.mlockall.unwrap_or(true),
            prefault_stack_bytes: 256 * 1024,
        };
        let policy = DeadlinePolicy {
            grace_cycles: s.grace_periods.unwrap_or(100),
            max_consecutive_misses: positive(
                s.max_consecutive_misses.unwrap_or(10),
                "service.max-consecutive-misses",
                &err,
            )?,
            recover_after: s.recover_after.filter(|n| *n > 0),
            silent_periods: positive(
                s.silent_periods.unwrap_or(400),
                "service.silent-periods",
                &err,
            )?,
            reset_on_resume: s.reset_on_resume.unwrap_or(true),
            miss_source: s.miss_source.unwrap_or(MissSource::Plant),
        };
        let limits = MeasurementLimits {
            y_min: per_channel(&s.y_min, n_y, f64::NEG_INFINITY, "service.y-min", &err)?,
            y_max: per_channel(&s.y_max, n_y, f64::INFINITY, "service.y-max", &err)?,
            z_min: per_channel(&s.z_min, n_z, f64::NEG_INFINITY, "service.z-min", &err)?,
            z_max: per_channel(&s.z_max, n_z, f64::INFINITY, "service.z-max", &err)?,
        };
        for (i, (lo, hi)) in limits.y_min.iter().zip(&limits.y_max).enumerate() {
            if lo.is_nan() || hi.is_nan() || lo >= hi {
                return Err(err(
                    "service.y-min",
                    format!("channel {i}: y-min {lo} must be below y-max {hi}"),
                ));
            }
        }
        for (i, (lo, hi)) in limits.z_min.iter().zip(&limits.z_max).enumerate() {
            if lo.is_nan() || hi.is_nan() || lo >= hi {
                return Err(err(
                    "service.z-min",
                    format!("channel {i}: z-min {lo} must be below z-max {hi}"),
                ));
            }
        }
        let safe_input = per_channel(&s.safe_input, n_u, 0.0, "service.safe-input", &err)?;
        if safe_input.iter().any(|v| !v.is_finite()) {
            return Err(err("service.safe-input", "must be finite".into()));
        }
        let peer_timeout =
            positive_seconds(s.peer_timeout.unwrap_or(30.0), "service.peer-timeout", &err)?;
        let interval = positive_seconds(
            s.histogram_interval.unwrap_or(1.0),
            "service.histogram-interval",
            &err,
        )?;
        let histogram_interval_cycles = ((interval / period).round() as u64).max(1);
        let l = raw.log.unwrap_or_default();
        let log = LogConfig {
            enabled: l.enabled.unwrap_or(true),
            decimation: l.decimation.unwrap_or(1).max(1),
            queue_capacity: l.queue_capacity.unwrap_or(65536),
        };
        if log.queue_capacity < 16 {
            return Err(err("log.queue-capacity", "must be at least 16".into()));
        }
        let open_loop = s.open_loop.unwrap_or(0.0);
        if !(open_loop.is_finite() && open_loop >= 0.0) {
            return Err(err(
                "service.open-loop",
                format!("{open_loop} s is not a duration ≥ 0"),
            ));
        }
        let open_loop_cycles = (open_loop / period).round() as u64;
        let tone_report = tone_report(
            s.report.unwrap_or_default(),
            raw.plant.as_ref(),
            period,
            open_loop_cycles,
            &err,
        )?;
        let controller_value = raw
            .controller
            .ok_or_else(|| err("controller", "the [controller] table is missing".into()))?;
        let controller = parse_controller(controller_value, counts, period, base_dir, &err)?;

        Ok(ServiceConfig {
            origin: origin.to_string(),
            rig: rig.name,
            sample_period_ns,
            counts,
            rt,
            require_rt: s.require_rt.unwrap_or(false),
            wait: s.wait.unwrap_or(WaitMode::BusyPoll),
            policy,
            limits,
            safe_input,
            peer_timeout: Duration::from_secs_f64(peer_timeout),
            histogram_interval_cycles,
            budget_ns: sample_period_ns,
            log,
            run_dir: s.run_dir.unwrap_or_else(|| PathBuf::from("runs")),
            controller,
            rms_settle_cycles: (s.rms_settle.unwrap_or(0.0).max(0.0) / period).round() as u64,
            open_loop_cycles,
            tone_report,
        })
    }
}

/// `[service.report]`: the tones (given, or those of `[plant.disturbance]`) and the
/// window, which must fit in the open-loop phase when there is one.
fn tone_report(
    raw: RawReport,
    plant: Option<&toml::Value>,
    period: f64,
    open_loop_cycles: u64,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ToneReportConfig, ConfigError> {
    let nyquist = 0.5 / period;
    let (tones_hz, source) = match raw.tones_hz {
        Some(t) => (t, "service.report.tones-hz".to_string()),
        None => {
            let tones = plant
                .and_then(|p| p.get("disturbance"))
                .and_then(|d| d.get("tones"))
                .and_then(|t| t.as_array());
            let mut hz = Vec::new();
            for t in tones.into_iter().flatten() {
                if let Some(f) = t
                    .get("frequency-hz")
                    .and_then(|f| f.as_float().or(f.as_integer().map(|i| i as f64)))
                    && !hz.contains(&f)
                {
                    hz.push(f);
                }
            }
            (hz, "plant.disturbance".to_string())
        }
    };
    for f in &tones_hz {
        if !(f.is_finite() && *f > 0.0 && *f < nyquist) {
            return Err(err(
                "service.report.tones-hz",
                format!("{f} Hz is not between 0 and the Nyquist frequency {nyquist} Hz"),
            ));
        }
    }
    let window = positive_seconds(raw.window.unwrap_or(0.5), "service.report.window", err)?;
    let mut window_cycles = ((window / period).round() as u64).max(1);
    if open_loop_cycles > 0 {
        // The open-loop window is the second half of the open-loop phase at most, so that
        // the transient of the start is not measured.
        window_cycles = window_cycles.min(open_loop_cycles / 2).max(1);
    }
    Ok(ToneReportConfig {
        tones_hz,
        source,
        window_cycles,
    })
}

/// A duration in seconds that must be finite and positive.
fn positive_seconds(
    v: f64,
    field: &str,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<f64, ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(err(field, format!("{v} s is not positive")))
    }
}

fn positive(
    v: u64,
    field: &str,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<u64, ConfigError> {
    if v == 0 {
        Err(err(field, "must be at least 1".into()))
    } else {
        Ok(v)
    }
}

fn channels_from_plant(plant: Option<&toml::Value>) -> Result<ChannelCounts, String> {
    let plant = plant.ok_or(
        "neither [service.channels] nor a [plant] table says how many channels the rig has",
    )?;
    let get = |k: &str, default: Option<i64>| -> Result<usize, String> {
        match plant.get(k).and_then(|v| v.as_integer()).or(default) {
            Some(n) if n >= 0 => Ok(n as usize),
            Some(n) => Err(format!("plant.{k} = {n} is negative")),
            None => Err(format!(
                "plant.{k} is missing, and [service.channels] is not given"
            )),
        }
    };
    ChannelCounts::new(
        get("outputs-y", None)?,
        get("outputs-z", None)?,
        get("commands", Some(0))?,
        get("inputs", None)?,
    )
}

fn matrix(rows: &[Vec<f64>], cols_if_empty: usize, field: &str) -> Result<DMatrix<f64>, String> {
    if rows.is_empty() {
        return Ok(DMatrix::zeros(0, cols_if_empty));
    }
    let n = rows[0].len();
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != n) {
        return Err(format!(
            "{field}: row {i} has {} entries, row 0 has {n}",
            r.len()
        ));
    }
    Ok(DMatrix::from_fn(rows.len(), n, |i, j| rows[i][j]))
}

const CONTROLLER_KINDS: &str = "lti, excitation, rcac, pcac";

fn parse_controller(
    value: toml::Value,
    counts: ChannelCounts,
    period: f64,
    base_dir: &Path,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ControllerConfig, ConfigError> {
    let kind = value.get("kind").and_then(|v| v.as_str()).unwrap_or("");
    match kind {
        "lti" => {}
        "excitation" => return parse_excitation(value, counts, err),
        "rcac" => return parse_rcac(value, counts, period, base_dir, err),
        "pcac" => {
            return pcac::parse_pcac(value, counts, err).map(|params| ControllerConfig::Pcac {
                params: Box::new(params),
            });
        }
        "" => {
            return Err(err(
                "controller.kind",
                format!("missing; known kinds: {CONTROLLER_KINDS}"),
            ));
        }
        other => {
            return Err(err(
                "controller.kind",
                format!("unknown controller '{other}'; known kinds: {CONTROLLER_KINDS}"),
            ));
        }
    }
    let raw: RawLti = value
        .try_into()
        .map_err(|e: toml::de::Error| err("controller", e.to_string()))?;
    debug_assert_eq!(raw.kind, "lti");
    let input = match raw.input.as_deref().unwrap_or("y") {
        "y" => ControllerInput::Y,
        "error" => ControllerInput::Error,
        "y-and-r" => ControllerInput::YAndR,
        other => {
            return Err(err(
                "controller.input",
                format!("'{other}' is not one of y, error, y-and-r"),
            ));
        }
    };
    let n_u = counts.n_u as usize;
    let n_e = match input {
        ControllerInput::YAndR => (counts.n_y + counts.n_r) as usize,
        _ => counts.n_y as usize,
    };
    let limits = output_limits(&raw.u_min, &raw.u_max, n_u, err)?;
    let (a, b, c, d, x0) = match (raw.ss, raw.tf) {
        (Some(ss), None) => {
            let a = matrix(&ss.a, 0, "a").map_err(|m| err("controller.ss.a", m))?;
            let n = a.nrows();
            let b = matrix(&ss.b, n_e, "b").map_err(|m| err("controller.ss.b", m))?;
            let c = if ss.c.is_empty() || (n == 0 && ss.c.iter().all(|r| r.is_empty())) {
                DMatrix::zeros(n_u, n)
            } else {
                matrix(&ss.c, n, "c").map_err(|m| err("controller.ss.c", m))?
            };
            let d = matrix(&ss.d, n_e, "d").map_err(|m| err("controller.ss.d", m))?;
            (a, b, c, d, ss.x0.map(DVector::from_vec))
        }
        (None, Some(tf)) => {
            let (a, b, c, d) = realize_tf_entries(&tf.entries, n_u, n_e)
                .map_err(|m| err("controller.tf.entries", m))?;
            (a, b, c, d, None)
        }
        (Some(_), Some(_)) => {
            return Err(err(
                "controller",
                "give [controller.ss] or [controller.tf], not both".into(),
            ));
        }
        (None, None) => {
            return Err(err(
                "controller",
                "an lti controller needs [controller.ss] or [controller.tf]".into(),
            ));
        }
    };
    let cfg = ControllerConfig::Lti {
        a,
        b,
        c,
        d,
        x0,
        input,
        limits,
    };
    // Build once now so that size errors are reported at load time, naming the table.
    cfg.build(counts).map_err(|m| err("controller", m))?;
    Ok(cfg)
}

/// A scalar (for every channel) or `n` values, `default` when absent; refused naming
/// `field` otherwise.
fn per_channel(
    v: &Option<ScalarOrVec>,
    n: usize,
    default: f64,
    field: &str,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<Vec<f64>, ConfigError> {
    match v {
        None => Ok(vec![default; n]),
        Some(ScalarOrVec::Scalar(x)) => Ok(vec![*x; n]),
        Some(ScalarOrVec::Vec(xs)) if xs.len() == n => Ok(xs.clone()),
        Some(ScalarOrVec::Vec(xs)) => Err(err(
            field,
            format!(
                "has {} values, expected {n} (one per channel) or a scalar",
                xs.len()
            ),
        )),
    }
}

/// The optional `u-min`/`u-max` pair of a controller table (scalar or one per input).
fn output_limits(
    lo: &Option<ScalarOrVec>,
    hi: &Option<ScalarOrVec>,
    n_u: usize,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<Option<OutputLimits>, ConfigError> {
    if lo.is_none() && hi.is_none() {
        return Ok(None);
    }
    Ok(Some(OutputLimits {
        min: per_channel(lo, n_u, f64::NEG_INFINITY, "controller.u-min", err)?,
        max: per_channel(hi, n_u, f64::INFINITY, "controller.u-max", err)?,
    }))
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawExcitation {
    #[allow(dead_code)]
    kind: String,
    std: ScalarOrVec,
    seed: Option<u64>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
}

/// `kind = "excitation"`: white Gaussian identification inputs.
fn parse_excitation(
    value: toml::Value,
    counts: ChannelCounts,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ControllerConfig, ConfigError> {
    let raw: RawExcitation = value
        .try_into()
        .map_err(|e: toml::de::Error| err("controller", e.to_string()))?;
    let n_u = counts.n_u as usize;
    let std = match raw.std {
        ScalarOrVec::Scalar(x) => vec![x; n_u],
        ScalarOrVec::Vec(v) => v,
    };
    let cfg = ControllerConfig::Excitation {
        std,
        seed: raw.seed.unwrap_or(1),
        limits: output_limits(&raw.u_min, &raw.u_max, n_u, err)?,
    };
    cfg.build(counts).map_err(|m| err("controller.std", m))?;
    Ok(cfg)
}

/// A scalar (times the identity) or a square matrix.
#[derive(Deserialize)]
#[serde(untagged)]
enum ScalarOrMatrix {
    Scalar(f64),
    Matrix(Vec<Vec<f64>>),
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawRcac {
    #[allow(dead_code)]
    kind: String,
    update: Option<String>,
    input: Option<String>,
    nc: Option<usize>,
    kw: Option<usize>,
    target_model: Option<toml::Value>,
    target_model_file: Option<String>,
    rz: Option<ScalarOrMatrix>,
    ru: Option<ScalarOrMatrix>,
    theta0: Option<Vec<f64>>,
    u_min: Option<ScalarOrVec>,
    u_max: Option<ScalarOrVec>,
    p0: Option<f64>,
    lambda: Option<f64>,
    forgetting: Option<RawForgetting>,
    trace_limit: Option<f64>,
    step_size: Option<String>,
    alpha: Option<f64>,
    r: Option<f64>,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawForgetting {
    rule: String,
    lambda: Option<f64>,
    tau_n: Option<usize>,
    tau_d: Option<usize>,
    eta: Option<f64>,
    alpha: Option<f64>,
}

/// `n × n` weight from a scalar (times I) or a matrix; `None` gives `default · I`.
fn weight(
    v: &Option<ScalarOrMatrix>,
    n: usize,
    default: f64,
    field: &str,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<DMatrix<f64>, ConfigError> {
    match v {
        None => Ok(DMatrix::identity(n, n) * default),
        Some(ScalarOrMatrix::Scalar(x)) => Ok(DMatrix::identity(n, n) * *x),
        Some(ScalarOrMatrix::Matrix(rows)) => {
            let m = matrix(rows, 0, field).map_err(|m| err(field, m))?;
            if m.nrows() != n || m.ncols() != n {
                return Err(err(
                    field,
                    format!("is {}×{}, expected {n}×{n}", m.nrows(), m.ncols()),
                ));
            }
            Ok(m)
        }
    }
}

/// `kind = "rcac"`: retrospective cost adaptive control.
fn parse_rcac(
    value: toml::Value,
    counts: ChannelCounts,
    period: f64,
    base_dir: &Path,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ControllerConfig, ConfigError> {
    let raw: RawRcac = value
        .try_into()
        .map_err(|e: toml::de::Error| err("controller", e.to_string()))?;
    let (n_y, n_z, n_u) = (
        counts.n_y as usize,
        counts.n_z as usize,
        counts.n_u as usize,
    );
    match raw.input.as_deref().unwrap_or("y") {
        "y" => {}
        other => {
            return Err(err(
                "controller.input",
                format!("'{other}': RCAC takes input = \"y\" only"),
            ));
        }
    }
    let nc = raw
        .nc
        .ok_or_else(|| err("controller.nc", "missing (the controller order n_c)".into()))?;
    if nc == 0 {
        return Err(err(
            "controller.nc",
            "0: the controller order n_c must be at least 1".into(),
        ));
    }
    let ltheta = n_u * nc * (n_u + n_y);
    let target = match (raw.target_model, raw.target_model_file) {
        (Some(v), None) => {
            const TAG: &str = "@inline";
            TargetModel::from_value(v, TAG).map_err(|m| {
                let m = m
                    .strip_prefix(&format!("{TAG}: "))
                    .unwrap_or(&m)
                    .to_string();
                match m.split_once(": ") {
                    Some((field, rest)) if field.starts_with("target-model") => {
                        err(&format!("controller.{field}"), rest.to_string())
                    }
                    _ => err("controller.target-model", m),
                }
            })?
        }
        (None, Some(f)) => {
            let p = Path::new(&f);
            let path = if p.is_relative() {
                base_dir.join(p)
            } else {
                p.to_path_buf()
            };
            if !path.is_file() {
                return Err(err(
                    "controller.target-model-file",
                    format!(
                        "'{f}' resolves to {}, which is not a readable file",
                        path.display()
                    ),
                ));
            }
            TargetModel::load(&path).map_err(|m| err("controller.target-model-file", m))?
        }
        (Some(_), Some(_)) => {
            return Err(err(
                "controller.target-model",
                "give [controller.target-model] or target-model-file, not both".into(),
            ));
        }
        (None, None) => {
            return Err(err(
                "controller.target-model",
                "missing: give [controller.target-model] or target-model-file".into(),
            ));
        }
    };
    if target.outputs != n_z || target.inputs != n_u {
        return Err(err(
            "controller.target-model",
            format!(
                "has {} outputs and {} inputs; the rig has l_z = {n_z} performance \
                 variables and l_u = {n_u} inputs",
                target.outputs, target.inputs
            ),
        ));
    }
    if (target.sample_period - period).abs() > 1e-9 * period {
        return Err(err(
            "controller.target-model.sample-period",
            format!(
                "{} s differs from the rig's sample period {period} s",
                target.sample_period
            ),
        ));
    }
    let rz = weight(&raw.rz, n_z, 1.0, "controller.rz", err)?;
    let ru = weight(&raw.ru, n_u, 0.0, "controller.ru", err)?;
    let update = match raw.update.as_deref().unwrap_or("rls") {
        "rls" => {
            for (given, name) in [
                (raw.step_size.is_some(), "step-size"),
                (raw.alpha.is_some(), "alpha"),
                (raw.r.is_some(), "r"),
            ] {
                if given {
                    return Err(err(
                        &format!("controller.{name}"),
                        "only for update = \"gradient\"".into(),
                    ));
                }
            }
            let p0 = positive_p0(raw.p0, "for update = \"rls\"", err)?;
            let rule = forgetting_rule(raw.lambda, raw.forgetting.as_ref(), err)?;
            let trace_limit = raw.trace_limit.unwrap_or(1e6 * ltheta as f64 * p0);
            if trace_limit.is_nan() || trace_limit <= ltheta as f64 * p0 {
                return Err(err(
                    "controller.trace-limit",
                    format!(
                        "{trace_limit} must exceed tr(P_0) = l_θ p0 = {}",
                        ltheta as f64 * p0
                    ),
                ));
            }
            RcacUpdate::Rls {
                p0,
                rule,
                trace_limit,
            }
        }
        "gradient" => {
            for (given, name) in [
                (raw.p0.is_some(), "p0"),
                (raw.lambda.is_some(), "lambda"),
                (raw.forgetting.is_some(), "forgetting"),
                (raw.trace_limit.is_some(), "trace-limit"),
            ] {
                if given {
                    return Err(err(
                        &format!("controller.{name}"),
                        "only for update = \"rls\"".into(),
                    ));
                }
            }
            let step_size = match raw.step_size.as_deref().unwrap_or("exp") {
                "opt" => StepSize::Opt,
                "sigma" => StepSize::Sigma,
                "frobenius" => StepSize::Frobenius,
                "exp" => StepSize::Exp,
                other => {
                    return Err(err(
                        "controller.step-size",
                        format!("'{other}' is not one of opt, sigma, frobenius, exp"),
                    ));
                }
            };
            let alpha = raw.alpha.ok_or_else(|| {
                err(
                    "controller.alpha",
                    "missing (the step-size factor α ∈ (0, 1])".into(),
                )
            })?;
            if !(alpha > 0.0 && alpha <= 1.0) {
                return Err(err(
                    "controller.alpha",
                    format!("{alpha} is outside (0, 1]"),
                ));
            }
            let r = raw.r.unwrap_or(0.0);
            if !(r >= 0.0 && r.is_finite()) {
                return Err(err("controller.r", format!("{r} must be finite and ≥ 0")));
            }
            RcacUpdate::Gradient {
                step_size,
                alpha,
                r,
            }
        }
        other => {
            return Err(err(
                "controller.update",
                format!("'{other}' is not \"rls\" or \"gradient\""),
            ));
        }
    };
    let limits = output_limits(&raw.u_min, &raw.u_max, n_u, err)?;
    let params = RcacParams {
        nc,
        kw: raw.kw,
        target,
        rz,
        ru,
        theta0: raw.theta0,
        update,
        limits,
        sample_period: period,
    };
    // Build once now so that every remaining check (R_z definite, R_u semidefinite, the
    // target model's poles and feedthrough, θ_0, forgetting windows) reports at load time.
    Rcac::new(&params, crate::wire::dimensions(counts)).map_err(|m| {
        let field = if m.starts_with("rz") {
            "controller.rz"
        } else if m.starts_with("ru") {
            "controller.ru"
        } else if m.starts_with("theta0") {
            "controller.theta0"
        } else if m.starts_with("forgetting") {
            "controller.forgetting"
        } else if m.starts_with("output limits") {
            "controller.u-min"
        } else if m.starts_with("target model") {
            "controller.target-model"
        } else {
            "controller"
        };
        err(field, m)
    })?;
    Ok(ControllerConfig::Rcac {
        params: Box::new(params),
    })
}

/// `p0` of `P_0 = p0 I`: required, positive and finite (`when` says for which setting).
fn positive_p0(
    p0: Option<f64>,
    when: &str,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<f64, ConfigError> {
    let p0 = p0.ok_or_else(|| err("controller.p0", format!("missing (P_0 = p0 I) {when}")))?;
    if !(p0 > 0.0 && p0.is_finite()) {
        return Err(err(
            "controller.p0",
            format!("{p0} must be positive and finite"),
        ));
    }
    Ok(p0)
}

/// The forgetting of an RLS: `lambda` (constant, default 1) or a `[controller.forgetting]`
/// table, not both.
fn forgetting_rule(
    lambda: Option<f64>,
    table: Option<&RawForgetting>,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ForgettingRule, ConfigError> {
    match (lambda, table) {
        (Some(_), Some(_)) => Err(err(
            "controller.lambda",
            "give lambda or [controller.forgetting], not both".into(),
        )),
        (l, None) => {
            let lambda = l.unwrap_or(1.0);
            if !(lambda > 0.0 && lambda <= 1.0) {
                return Err(err(
                    "controller.lambda",
                    format!("{lambda} is outside (0, 1]"),
                ));
            }
            Ok(ForgettingRule::Constant { lambda })
        }
        (None, Some(f)) => parse_forgetting(f, err),
    }
}

/// The `[controller.forgetting]` table of an RLS update.
fn parse_forgetting(
    f: &RawForgetting,
    err: &dyn Fn(&str, String) -> ConfigError,
) -> Result<ForgettingRule, ConfigError> {
    let need = |v: Option<f64>, name: &str| {
        v.ok_or_else(|| {
            err(
                &format!("controller.forgetting.{name}"),
                format!("missing for rule = \"{}\"", f.rule),
            )
        })
    };
    let need_n = |v: Option<usize>, name: &str| {
        v.ok_or_else(|| {
            err(
                &format!("controller.forgetting.{name}"),
                format!("missing for rule = \"{}\"", f.rule),
            )
        })
    };
    match f.rule.as_str() {
        "constant" => Ok(ForgettingRule::Constant {
            lambda: need(f.lambda, "lambda")?,
        }),
        "f-test" => Ok(ForgettingRule::FTest {
            tau_n: need_n(f.tau_n, "tau-n")?,
            tau_d: need_n(f.tau_d, "tau-d")?,
            eta: need(f.eta, "eta")?,
            alpha: need(f.alpha, "alpha")?,
        }),
        "rms-ratio" => Ok(ForgettingRule::RmsRatio {
            tau_n: need_n(f.tau_n, "tau-n")?,
            tau_d: need_n(f.tau_d, "tau-d")?,
            eta: need(f.eta, "eta")?,
        }),
        other => Err(err(
            "controller.forgetting.rule",
            format!("'{other}' is not one of constant, f-test, rms-ratio"),
        )),
    }
}

/// Realizes an `n_u × n_e` matrix of discrete transfer functions with plant-proxy's
/// realization code.
fn realize_tf_entries(
    entries: &[Vec<RawTfEntry>],
    n_u: usize,
    n_e: usize,
) -> Result<(DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>), String> {
    use plant_proxy::lti::{Tf, realize_tf_matrix};
    if entries.len() != n_u {
        return Err(format!(
            "{} rows, expected one per input u ({n_u})",
            entries.len()
        ));
    }
    let mut m = Vec::with_capacity(n_u);
    for (i, row) in entries.iter().enumerate() {
        if row.len() != n_e {
            return Err(format!(
                "row {i} has {} entries, expected one per controller input ({n_e})",
                row.len()
            ));
        }
        let mut r = Vec::with_capacity(n_e);
        for (j, e) in row.iter().enumerate() {
            r.push(match e {
                RawTfEntry::Zero(0) => None,
                RawTfEntry::Zero(v) => {
                    return Err(format!("[{i}][{j}] = {v}: an entry is 0 or {{ num, den }}"));
                }
                RawTfEntry::Tf { num, den } => Some(
                    Tf::new(num.clone(), den.clone()).map_err(|e| format!("[{i}][{j}]: {e}"))?,
                ),
            });
        }
        m.push(r);
    }
    let ss = realize_tf_matrix(&m).map_err(|e| e.to_string())?;
    Ok((ss.a, ss.b, ss.c, ss.d))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
[rig]
name = "unit"
sample-period = 0.001
[service]
channels = { y = 1, z = 1, u = 1 }
y-min = -5.0
y-max = 5.0
[controller]
kind = "lti"
[controller.ss]
a = []
b = []
c = []
d = [[-2.0]]
"#;

    #[test]
    fn a_good_file_gives_typed_parameters() {
        let c = ServiceConfig::parse(GOOD, "good.toml").unwrap();
        assert_eq!(c.sample_period_ns, 1_000_000);
        assert_eq!(
            c.counts,
            ChannelCounts {
                n_y: 1,
                n_z: 1,
                n_r: 0,
                n_u: 1
            }
        );
        assert_eq!(c.limits.y_max, vec![5.0]);
        assert_eq!(c.wait, WaitMode::BusyPoll);
    }

    fn refused(text: &str) -> String {
        ServiceConfig::parse(text, "bad.toml")
            .expect_err("must be refused")
            .to_string()
    }

    #[test]
    fn bad_values_are_refused_naming_file_and_field() {
        let m = refused(&GOOD.replace("y-max = 5.0", "y-max = -6.0"));
        assert!(m.starts_with("bad.toml: field 'service.y-min'"), "{m}");
        let m = refused(&GOOD.replace("d = [[-2.0]]", "d = [[-2.0, 1.0]]"));
        assert!(
            m.contains("field 'controller'") && m.contains("d is 1×2, expected 1×1"),
            "{m}"
        );
        let m = refused(&GOOD.replace("kind = \"lti\"", "kind = \"pid\""));
        assert!(m.contains("controller.kind") && m.contains("pid"), "{m}");
        let m = refused(&GOOD.replace("[service]", "[service]\nwiat = \"block\""));
        assert!(m.contains("wiat"), "{m}");
        let m = refused(&GOOD.replace("[rig]", "[rigg]\n[rig]"));
        assert!(
            m.contains("field 'rigg'") && m.contains("unknown table"),
            "{m}"
        );
        let m = refused(&GOOD.replace("sample-period = 0.001", "sample-period = -1.0"));
        assert!(m.contains("rig.sample-period"), "{m}");
        let m = refused(&GOOD.replace("name = \"unit\"", "name = \"a/b\""));
        assert!(m.contains("rig.name"), "{m}");
        let m = refused("[rig\nname=");
        assert!(m.starts_with("bad.toml: not valid TOML"), "{m}");
    }

    #[test]
    fn channel_counts_come_from_the_plant_table_when_not_given() {
        let text = GOOD.replace("channels = { y = 1, z = 1, u = 1 }", "")
            + "\n[plant]\nkind = \"transfer-function\"\ninputs = 1\noutputs-y = 1\noutputs-z = 1\ndisturbances = 0\n";
        let c = ServiceConfig::parse(&text, "x.toml").unwrap();
        assert_eq!(c.counts.n_u, 1);
    }

    const RCAC: &str = r#"
[rig]
name = "unit"
sample-period = 0.01
[service]
channels = { y = 1, z = 1, u = 2 }
[controller]
kind = "rcac"
update = "rls"
nc = 4
p0 = 10.0
u-min = -1.0
u-max = 1.0
lambda = 0.999
[controller.target-model]
form = "transfer-function"
sample-period = 0.01
outputs = 1
inputs = 2
beta = 0.8
[[controller.target-model.channel]]
output = 0
input = 0
delay = 1
num = [0.5]
den = [1.0, -0.5]
[[controller.target-model.channel]]
output = 0
input = 1
delay = 3
num = [0.2]
den = [1.0]
"#;

    #[test]
    fn an_rcac_controller_is_read_with_an_inline_target_model_and_built() {
        let c = ServiceConfig::parse(RCAC, "rcac.toml").unwrap();
        let ControllerConfig::Rcac { params } = &c.controller else {
            panic!("not rcac: {:?}", c.controller);
        };
        assert_eq!(params.nc, 4);
        assert_eq!(params.target.inputs, 2);
        assert_eq!(
            params.update,
            RcacUpdate::Rls {
                p0: 10.0,
                rule: ForgettingRule::Constant { lambda: 0.999 },
                trace_limit: 1e6 * 24.0 * 10.0,
            }
        );
        let ctl = c.controller.build(c.counts).unwrap();
        assert_eq!(ctl.kind(), "rcac");
        assert_eq!(ctl.internal_names().len(), 7);
        // The gradient variant, and the forgetting table.
        let g = RCAC
            .replace("update = \"rls\"", "update = \"gradient\"")
            .replace(
                "p0 = 10.0\n",
                "step-size = \"sigma\"\nalpha = 0.3\nr = 0.01\n",
            )
            .replace("lambda = 0.999\n", "");
        let c = ServiceConfig::parse(&g, "rcac.toml").unwrap();
        let ControllerConfig::Rcac { params } = &c.controller else {
            panic!()
        };
        assert_eq!(
            params.update,
            RcacUpdate::Gradient {
                step_size: StepSize::Sigma,
                alpha: 0.3,
                r: 0.01
            }
        );
        let f = RCAC.replace(
            "lambda = 0.999",
            "[controller.forgetting]\nrule = \"f-test\"\ntau-n = 10\ntau-d = 80\neta = 0.5\nalpha = 0.01",
        );
        let c = ServiceConfig::parse(&f, "rcac.toml");
        assert!(c.is_ok(), "{c:?}");
    }

    #[test]
    fn a_target_model_file_is_found_next_to_the_scenario() {
        let dir = std::env::temp_dir().join(format!("rcac-config-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let (head, tm) = RCAC.split_once("[controller.target-model]").unwrap();
        let tm = format!(
            "[target-model]{}",
            tm.replace("controller.target-model.", "target-model.")
        );
        std::fs::write(dir.join("sub/tm.toml"), tm).unwrap();
        let text = head.replace(
            "kind = \"rcac\"",
            "kind = \"rcac\"\ntarget-model-file = \"sub/tm.toml\"",
        );
        let origin = dir.join("scenario.toml").display().to_string();
        let c = ServiceConfig::parse(&text, &origin).unwrap();
        assert!(matches!(c.controller, ControllerConfig::Rcac { .. }));
        // A controller file elsewhere: relative to its own folder.
        std::fs::write(
            dir.join("scenario.toml"),
            GOOD.replace("u = 1", "u = 2").replace("0.001", "0.01"),
        )
        .unwrap();
        std::fs::write(
            dir.join("sub/ctl.toml"),
            text.split_once("[controller]")
                .unwrap()
                .1
                .replace("sub/tm.toml", "tm.toml")
                .replace("kind", "[controller]\nkind"),
        )
        .unwrap();
        let c = ServiceConfig::load_with_controller(
            &dir.join("scenario.toml"),
            &dir.join("sub/ctl.toml"),
        );
        assert!(
            matches!(
                c,
                Ok(ServiceConfig {
                    controller: ControllerConfig::Rcac { .. },
                    ..
                })
            ),
            "{c:?}"
        );
        // A Markov (FIR) model as the design tools write it (TargetModel::save), as is.
        let fir = TargetModel {
            sample_period: 0.01,
            outputs: 1,
            inputs: 2,
            beta: 0.9,
            source: "rig-design markov".into(),
            form: control::target::TargetForm::Markov(vec![
                DMatrix::zeros(1, 2),
                DMatrix::from_row_slice(1, 2, &[0.05, 0.0]),
                DMatrix::from_row_slice(1, 2, &[0.0, -0.02]),
            ]),
        };
        fir.save(&dir.join("sub/fir.toml")).unwrap();
        let c = ServiceConfig::parse(&text.replace("sub/tm.toml", "sub/fir.toml"), &origin);
        assert!(
            matches!(&c, Ok(ServiceConfig { controller: ControllerConfig::Rcac { params }, .. })
                if params.target == fir),
            "{c:?}"
        );
        // Not there: the field is named.
        let m = ServiceConfig::parse(&text.replace("sub/tm.toml", "nope.toml"), &origin)
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("field 'controller.target-model-file'") && m.contains("nope.toml"),
            "{m}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_rcac_settings_are_refused_naming_file_and_field() {
        let cases: &[(&str, &str, &str)] = &[
            ("nc = 4", "nc = 0", "controller.nc"),
            ("outputs = 1", "outputs = 2", "controller.target-model"),
            (
                "sample-period = 0.01\noutputs",
                "sample-period = 0.001\noutputs",
                "controller.target-model.sample-period",
            ),
            ("beta = 0.8", "beta = 1.8", "controller.target-model.beta"),
            (
                "lambda = 0.999",
                "lambda = 0.999\nrz = -1.0",
                "controller.rz",
            ),
            (
                "lambda = 0.999",
                "lambda = 0.999\nrz = [[1.0, 0.0]]",
                "controller.rz",
            ),
            (
                "lambda = 0.999",
                "lambda = 0.999\nru = [[1.0, 2.0], [2.0, 1.0]]",
                "controller.ru",
            ),
            ("lambda = 0.999", "lambda = 1.5", "controller.lambda"),
            ("p0 = 10.0\n", "", "controller.p0"),
            (
                "lambda = 0.999",
                "lambda = 0.999\nalpha = 0.5",
                "controller.alpha",
            ),
            (
                "lambda = 0.999",
                "lambda = 0.999\ntheta0 = [1.0, 2.0]",
                "controller.theta0",
            ),
            ("update = \"rls\"", "update = \"lms\"", "controller.update"),
            (
                "kind = \"rcac\"",
                "kind = \"rcac\"\ninput = \"error\"",
                "controller.input",
            ),
            (
                "den = [1.0, -0.5]",
                "den = [1.0, -1.5]",
                "controller.target-model",
            ),
            (
                "delay = 1\nnum = [0.5]",
                "delay = 0\nnum = [0.5, 0.1]",
                "controller.target-model",
            ),
            ("u-max = 1.0", "u-max = -1.5", "controller.u-min"),
            (
                "lambda = 0.999",
                "[controller.forgetting]\nrule = \"rms-ratio\"\ntau-n = 10\neta = 1.0",
                "controller.forgetting.tau-d",
            ),
            (
                "lambda = 0.999",
                "[controller.forgetting]\nrule = \"rms-ratio\"\ntau-n = 10\ntau-d = 5\neta = 1.0",
                "controller.forgetting",
            ),
            (
                "lambda = 0.999",
                "[controller.forgetting]\nrule = \"newton\"",
                "controller.forgetting.rule",
            ),
            (
                "kind = \"rcac\"",
                "kind = \"rcac\"\ntarget-model-file = \"x.toml\"",
                "controller.target-model",
            ),
        ];
        for (from, to, field) in cases {
            let text = RCAC.replacen(from, to, 1);
            assert_ne!(text, RCAC, "{from}");
            let m = ServiceConfig::parse(&text, "bad.toml")
                .err()
                .unwrap_or_else(|| panic!("accepted: {to}"))
                .to_string();
            eprintln!("{m}");
            assert!(
                m.starts_with(&format!("bad.toml: field '{field}'")),
                "{to}: {m}"
            );
        }
        let grad = RCAC
            .replace("update = \"rls\"", "update = \"gradient\"")
            .replace("p0 = 10.0\n", "alpha = 0.5\n")
            .replace("lambda = 0.999\n", "");
        for (from, to, field) in [
            ("alpha = 0.5", "alpha = 1.5", "controller.alpha"),
            ("alpha = 0.5", "alpha = 0.0", "controller.alpha"),
            ("alpha = 0.5", "", "controller.alpha"),
            (
                "alpha = 0.5",
                "alpha = 0.5\nstep-size = \"fast\"",
                "controller.step-size",
            ),
            ("alpha = 0.5", "alpha = 0.5\nr = -1.0", "controller.r"),
            (
                "alpha = 0.5",
                "alpha = 0.5\nlambda = 0.9",
                "controller.lambda",
            ),
        ] {
            let text = grad.replacen(from, to, 1);
            assert_ne!(text, grad, "{from}");
            let m = ServiceConfig::parse(&text, "bad.toml")
                .err()
                .unwrap_or_else(|| panic!("accepted: {to}"))
                .to_string();
            eprintln!("{m}");
            assert!(
                m.starts_with(&format!("bad.toml: field '{field}'")),
                "{to}: {m}"
            );
        }
    }
}
