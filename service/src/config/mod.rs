//! The service's configuration: the `[rig]`, `[service]`, `[controller]` and `[log]` tables
//! of a scenario TOML file, read once at start-up, validated, and turned into typed
//! parameters. Nothing in the real-time loop reads a string or a map.
//!
//! A bad file or value is refused before anything starts, with the file, the field and
//! what is wrong ([`ConfigError`]). The tables read by plant-proxy (`[plant]`, `[proxy]`)
//! may share the file; the service only reads the channel counts from `[plant]` when
//! `[service.channels]` is absent, and the tones of `[plant.disturbance]` for the report.
//!
//! Each table's fields, defaults and checks are listed in the module that reads it (the
//! types are re-exported here):
//!
//! | table | module | result |
//! |---|---|---|
//! | `[rig]` | [`rig`] | [`ServiceConfig::rig`], [`ServiceConfig::sample_period_ns`] |
//! | `[service]`, `[service.channels]` | [`service_table`] | [`RtRequest`], [`WaitMode`], [`DeadlinePolicy`], [`MeasurementLimits`], … |
//! | `service.timing`, `service.plan-length` | [`answer_timing`] | [`AnswerTiming`] |
//! | `[service.report]` | [`tone_report`] | [`ToneReportConfig`] |
//! | `[service.telemetry]`, `[service.operator]` | [`live`] | [`LiveConfig`] |
//! | `[log]` | [`log`] | [`LogConfig`] |
//! | `[controller]` | [`controller`] (the `kind` dispatch) | [`ControllerConfig`] |
//! | `kind = "lti"` | [`lti`] | [`ControllerConfig::Lti`] |
//! | `kind = "excitation"` | [`excitation`] | [`ControllerConfig::Excitation`] |
//! | `kind = "rcac"` | [`rcac`], [`forgetting`], [`target_model_file`] | [`ControllerConfig::Rcac`] |
//! | `kind = "pcac"` | [`pcac`], [`forgetting`] | [`ControllerConfig::Pcac`] |
//! | `kind = "appc"`, `kind = "rc-mrac"` | [`mrac`], [`forgetting`] | [`ControllerConfig::Appc`], [`ControllerConfig::RcMrac`] |
//! | `kind = "sampling-arm"` | [`arm`], [`pcac`], [`robust_gain_file`] | [`ControllerConfig::SamplingArm`] |
//!
//! The shared value shapes (a scalar or one value per channel, a scalar or a matrix,
//! bounded durations and counts, "one of" names) are in `values`; the bound of every size,
//! count and duration is in [`bounds`]. What both sides read of the file (`[rig]`, the
//! spacecraft table, the facts of `[plant]` used here, the LTI realization) is read by the
//! scenario schema, the `rig-scenario` crate; the check of both halves against each other
//! is `rig check` of the tools, which link the simulator this crate does not.
//!
//! A minimal file:
//!
//! ```toml
//! [rig]
//! name = "acoustic-rig"
//! sample-period = 1.25e-4
//!
//! [service]
//! channels = { y = 1, z = 1, u = 1 }
//!
//! [controller]
//! kind = "lti"
//! [controller.ss]
//! a = []
//! b = []
//! c = []
//! d = [[-2.0]]
//! ```
//!
//! [`ServiceConfig::load_with_controller`] replaces the `[controller]` (and `[log]`)
//! tables of a scenario by those of another file; the scenario's acceptance criterion
//! (`service.report.min-suppression-db`) and its tunables (`service.operator.tunables`),
//! stated for its own controller, are dropped, and the keys of the file's own
//! `[service.report]` and `[service.operator]`, if it has them, replace the scenario's.

pub mod answer_timing;
pub mod arm;
pub mod bounds;
pub mod controller;
pub mod excitation;
pub mod forgetting;
pub mod live;
pub mod log;
pub mod lti;
pub mod mrac;
pub mod pcac;
pub mod rcac;
#[cfg(test)]
mod refusal_cases;
pub mod rig;
pub mod robust_gain_file;
pub mod service_table;
pub mod target_model_file;
pub mod tone_report;
mod values;

pub use answer_timing::AnswerTiming;
pub use controller::ControllerConfig;
pub use live::{DeclaredTunable, LiveConfig};
pub use log::LogConfig;
pub use robust_gain_file::RobustGainFile;
pub use service_table::{
    DeadlinePolicy, MeasurementLimits, MissSource, TimingFaultReset, WaitMode,
};
pub use target_model_file::TargetModelFile;
pub use tone_report::{ForceRegulationConfig, ToneReportConfig};

use ipc_types::ChannelCounts;
use ipc_types::rt::RtRequest;
use serde::Deserialize;
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Top-level tables a scenario file may contain (`jack` is the JACK plant side's,
/// `plant-jack`; the service does not read it).
pub const KNOWN_TABLES: &[&str] = &[
    "rig",
    "plant",
    "proxy",
    "service",
    "controller",
    "log",
    "jack",
];

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

/// Makes the [`ConfigError`] of the file being read from a field path and a message.
type ErrFn<'a> = dyn Fn(&str, String) -> ConfigError + 'a;

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
    /// `service.poll-window` in ns: how long before a sample is due `sleep-poll` polls.
    pub poll_window_ns: u64,
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
    /// The live view and the operator's commands (`[service.telemetry]`,
    /// `[service.operator]`).
    pub live: LiveConfig,
    /// Cycles between checkpoints of what the controller learned (`service.checkpoint-every`;
    /// 0: only at the end of the run).
    pub checkpoint_every_cycles: u64,
    /// When the service answers and how long its plans are (`service.timing`,
    /// `service.plan-length`).
    pub answer: AnswerTiming,
    /// The text this configuration was parsed from (after a `--controller` merge) and the
    /// folder its relative file names were resolved from: what `record.bin` keeps so that
    /// `service replay` rebuilds the same configuration ([`ServiceConfig::parse_in`]).
    pub source: ConfigSource,
}

/// The text a [`ServiceConfig`] was parsed from and the folder of its relative file names.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ConfigSource {
    /// The TOML text.
    pub text: String,
    /// The folder relative file names (a target-model file, a robust-gain file) were
    /// resolved from.
    pub base_dir: PathBuf,
}

#[derive(Deserialize)]
#[serde(rename_all = "kebab-case")]
struct RawFile {
    rig: Option<rig::RawRig>,
    service: Option<service_table::RawService>,
    controller: Option<toml::Value>,
    log: Option<log::RawLog>,
    plant: Option<toml::Value>,
}

/// The tables of the TOML file at `path`.
fn read_table(p: &Path) -> Result<toml::Table, ConfigError> {
    let origin = p.display().to_string();
    let e = |message: String| ConfigError {
        file: origin.clone(),
        field: String::new(),
        message,
    };
    let text = std::fs::read_to_string(p).map_err(|x| e(format!("cannot read the file: {x}")))?;
    toml::from_str(&text).map_err(|x| e(format!("not valid TOML: {x}")))
}

/// The text of the scenario file at `path` and its name as errors give it.
pub(crate) fn read_scenario(path: &Path) -> Result<(String, String), ConfigError> {
    let origin = path.display().to_string();
    match std::fs::read_to_string(path) {
        Ok(text) => Ok((text, origin)),
        Err(e) => Err(ConfigError {
            file: origin,
            field: String::new(),
            message: format!("cannot read the file: {e}"),
        }),
    }
}

impl ServiceConfig {
    /// Reads and validates a scenario file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (text, origin) = read_scenario(path)?;
        Self::parse(&text, &origin)
    }

    /// [`ServiceConfig::load`], or [`ServiceConfig::load_with_controller`] when a controller
    /// file is given (the `--controller` option of `service run` and `rig launch`).
    pub fn load_scenario(path: &Path, controller_file: Option<&Path>) -> Result<Self, ConfigError> {
        match controller_file {
            Some(c) => Self::load_with_controller(path, c),
            None => Self::load(path),
        }
    }

    /// Reads a scenario file whose `[controller]` table (and `[log]` table, if present) is
    /// replaced by those of `controller_file`: the same rig, plant and service, another
    /// controller (for example an identification run with `kind = "excitation"`). Errors
    /// in the replaced tables name `controller_file`; a relative target-model file in it is
    /// found from `controller_file`'s folder.
    pub fn load_with_controller(path: &Path, controller_file: &Path) -> Result<Self, ConfigError> {
        let base = read_table(path)?;
        Self::with_controller_tables(base, &path.display().to_string(), controller_file)
    }

    /// [`ServiceConfig::load_with_controller`] on a scenario given as text: the
    /// `[controller]` (and `[log]`) tables of `text` (named `origin` in errors) replaced by
    /// those of `controller_file` (`service replay --controller`).
    pub fn parse_with_controller(
        text: &str,
        origin: &str,
        controller_file: &Path,
    ) -> Result<Self, ConfigError> {
        let base: toml::Table = toml::from_str(text).map_err(|x| ConfigError {
            file: origin.to_string(),
            field: String::new(),
            message: format!("not valid TOML: {x}"),
        })?;
        Self::with_controller_tables(base, origin, controller_file)
    }

    fn with_controller_tables(
        mut base: toml::Table,
        base_origin: &str,
        controller_file: &Path,
    ) -> Result<Self, ConfigError> {
        let over = read_table(controller_file)?;
        let origin = format!(
            "{base_origin} (controller from {})",
            controller_file.display()
        );
        let mut over = over;
        // Of [service], a controller file may hold what belongs to its controller: its
        // acceptance criterion ([service.report]) and its tunables ([service.operator]).
        let own_tables = match over.remove("service") {
            None => Vec::new(),
            Some(toml::Value::Table(mut service)) => {
                let own: Vec<(&str, toml::Value)> = ["report", "operator"]
                    .into_iter()
                    .filter_map(|k| service.remove(k).map(|v| (k, v)))
                    .collect();
                if let Some(key) = service.keys().next() {
                    return Err(ConfigError {
                        file: controller_file.display().to_string(),
                        field: format!("service.{key}"),
                        message: "of [service], a controller file may hold only \
                                  [service.report] (the controller's acceptance criterion) \
                                  and [service.operator] (its tunables)"
                            .into(),
                    });
                }
                own
            }
            Some(_) => Vec::new(),
        };
        for key in over.keys() {
            if key != "controller" && key != "log" {
                return Err(ConfigError {
                    file: controller_file.display().to_string(),
                    field: key.clone(),
                    message: "a controller file may hold only [controller], [log], \
                              [service.report] and [service.operator]"
                        .into(),
                });
            }
        }
        // The scenario's acceptance criterion and tunables were stated for its own
        // controller: another controller is judged by its own file's and offers its own
        // file's tunables (none when it states none). The other keys of the controller
        // file's tables replace the scenario's, key by key.
        if let Some(toml::Value::Table(service)) = base.get_mut("service") {
            for (table, key) in [("report", "min-suppression-db"), ("operator", "tunables")] {
                if let Some(toml::Value::Table(t)) = service.get_mut(table) {
                    t.remove(key);
                }
            }
        }
        if let Some(toml::Value::Table(service)) = base.get_mut("service") {
            for (name, table) in own_tables {
                let entry = service
                    .entry(name)
                    .or_insert_with(|| toml::Value::Table(toml::Table::new()));
                if let (toml::Value::Table(base_table), toml::Value::Table(t)) = (entry, table) {
                    for (k, v) in t {
                        base_table.insert(k, v);
                    }
                }
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

    /// One line: the rig, its rate, the channels and the controller.
    pub fn summary(&self) -> String {
        format!(
            "rig '{}', {} Hz, channels y={} z={} r={} u={}, controller {}",
            self.rig,
            1e9 / self.sample_period_ns as f64,
            self.counts.n_y,
            self.counts.n_z,
            self.counts.n_r,
            self.counts.n_u,
            self.controller.kind_name()
        )
    }

    /// The reason this configuration will not hold real time on this machine, if it is a
    /// `SCHED_FIFO` thread that busy-polls while the kernel's RT throttling is on: the
    /// kernel then stalls it for `1 − runtime/period` of every second
    /// ([`ipc_types::rt::busy_poll_throttling_warning`]). `service check` refuses such a
    /// configuration and a run of it fails its verdict.
    pub fn throttled_busy_poll(&self) -> Option<String> {
        (self.wait == WaitMode::BusyPoll && self.rt.fifo_priority.is_some())
            .then(ipc_types::rt::busy_poll_throttling_warning)
            .flatten()
    }

    /// The refusal `service check` and `rig check` give a configuration that cannot hold
    /// real time on this machine ([`ServiceConfig::throttled_busy_poll`]), naming
    /// `service.wait`.
    ///
    /// # Errors
    ///
    /// The throttled busy-poll, as a refusal of `service.wait`.
    pub fn check_this_machine(&self) -> Result<(), ConfigError> {
        match self.throttled_busy_poll() {
            Some(message) => Err(ConfigError {
                file: self.origin.clone(),
                field: "service.wait".into(),
                message,
            }),
            None => Ok(()),
        }
    }

    /// Checks the command-line overrides of `service run` as the file's values are
    /// checked: `--core` as `service.core`, `--max-cycles` from 1 to the cycles of the
    /// longest run ([`bounds::MAX_DURATION_S`]).
    ///
    /// # Errors
    ///
    /// The refused value, naming the field (`service.core`) or the option
    /// (`--max-cycles`).
    pub fn check_run_options(
        &self,
        core: Option<usize>,
        max_cycles: Option<u64>,
    ) -> Result<(), ConfigError> {
        let err = |field: &str, message: String| ConfigError {
            file: self.origin.clone(),
            field: field.to_string(),
            message,
        };
        service_table::check_core(core, "service.core", " (--core)", &err)?;
        if let Some(n) = max_cycles {
            let max = bounds::max_cycles(self.sample_period_ns as f64 * 1e-9);
            values::count(n, 1, max, "--max-cycles", &err)?;
        }
        Ok(())
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
    /// target-model file) resolved from `base_dir` (`service replay` rebuilds a recorded
    /// configuration with it).
    pub fn parse_in(text: &str, origin: &str, base_dir: &Path) -> Result<Self, ConfigError> {
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
        let rig = rig::parse(
            raw.rig
                .ok_or_else(|| err("rig", "the [rig] table is missing".into()))?,
            &err,
        )?;
        let period = rig.period;
        let sample_period_ns = (period * 1e9).round() as u64;
        let mut raw_service = raw.service.unwrap_or_default();
        let s = service_table::parse(&raw_service, raw.plant.as_ref(), period, &err)?;
        let log = log::parse(raw.log.unwrap_or_default(), &err)?;
        let tone_report = tone_report::parse(
            raw_service.report.take().unwrap_or_default(),
            raw.plant.as_ref(),
            period,
            s.open_loop_cycles,
            (s.counts.n_y as usize, s.counts.n_r as usize),
            &err,
        )?;
        let controller_value = raw
            .controller
            .ok_or_else(|| err("controller", "the [controller] table is missing".into()))?;
        let rig_of_controller = controller::Rig {
            counts: s.counts,
            period,
            base_dir,
        };
        let controller = controller::parse(controller_value, &rig_of_controller, &err)?;
        let live = live::parse(
            raw_service.telemetry.take().unwrap_or_default(),
            raw_service.operator.take().unwrap_or_default(),
            period,
            &controller,
            s.counts,
            &err,
        )?;
        let answer = answer_timing::parse(
            raw_service.timing.as_deref(),
            raw_service.plan_length,
            &controller,
            &err,
        )?;

        Ok(ServiceConfig {
            origin: origin.to_string(),
            rig: rig.name,
            sample_period_ns,
            counts: s.counts,
            rt: s.rt,
            require_rt: s.require_rt,
            wait: s.wait,
            poll_window_ns: s.poll_window_ns,
            policy: s.policy,
            limits: s.limits,
            safe_input: s.safe_input,
            peer_timeout: s.peer_timeout,
            histogram_interval_cycles: s.histogram_interval_cycles,
            budget_ns: sample_period_ns,
            log,
            run_dir: s.run_dir,
            controller,
            rms_settle_cycles: s.rms_settle_cycles,
            open_loop_cycles: s.open_loop_cycles,
            tone_report,
            live,
            checkpoint_every_cycles: s.checkpoint_every_cycles,
            answer,
            source: ConfigSource {
                text: text.to_string(),
                base_dir: base_dir.to_path_buf(),
            },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::refusal_cases::assert_refused_naming_fields;
    use super::*;

    const GOOD: &str = include_str!("../../../tests/fixtures/config/lti-static-gain.toml");

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
        assert_eq!(c.wait, WaitMode::SleepPoll);
    }

    fn refused(text: &str) -> String {
        ServiceConfig::parse(text, "bad.toml")
            .expect_err("must be refused")
            .to_string()
    }

    #[test]
    fn bad_values_are_refused_naming_file_and_field() {
        let cases = include_str!("../../../tests/fixtures/refusals/service-basics.toml");
        assert_refused_naming_fields(GOOD, "bad.toml", cases);
        let m = refused(&GOOD.replace("d = [[-2.0]]", "d = [[-2.0, 1.0]]"));
        assert!(m.contains("d is 1×2, expected 1×1"), "{m}");
        let m = refused(&GOOD.replace("kind = \"lti\"", "kind = \"pid\""));
        assert!(m.contains("pid"), "{m}");
        let m = refused(&GOOD.replace("[rig]", "[rigg]\n[rig]"));
        assert!(m.contains("unknown table"), "{m}");
        let m = refused(&GOOD.replace("[service]", "[service]\nwiat = \"block\""));
        assert!(m.contains("wiat"), "{m}");
        let m = refused("[rig\nname=");
        assert!(m.starts_with("bad.toml: not valid TOML"), "{m}");
    }

    #[test]
    fn another_controller_file_drops_the_scenarios_tunables_with_its_acceptance_criterion() {
        let scenarios = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
        let main = ServiceConfig::load(&scenarios.join("acoustic-rig.toml")).unwrap();
        assert_eq!(main.live.tunables.len(), 1);
        assert_eq!(main.live.tunables[0].name, "alpha");
        assert_eq!(
            (main.live.tunables[0].min, main.live.tunables[0].max),
            (0.01, 0.2)
        );
        // Full-RLS RCAC has no α: the scenario's declaration goes with its controller.
        let rls = ServiceConfig::load_with_controller(
            &scenarios.join("acoustic-rig.toml"),
            &scenarios.join("rcac/acoustic-rls.toml"),
        )
        .unwrap();
        assert!(rls.live.tunables.is_empty());
        assert_eq!(rls.tone_report.min_suppression_db, Some(40.0));
    }

    #[test]
    fn channel_counts_come_from_the_plant_table_when_not_given() {
        let text = GOOD.replace("channels = { y = 1, z = 1, u = 1 }", "")
            + "\n[plant]\nkind = \"transfer-function\"\ninputs = 1\noutputs-y = 1\noutputs-z = 1\ndisturbances = 0\n";
        let c = ServiceConfig::parse(&text, "x.toml").unwrap();
        assert_eq!(c.counts.n_u, 1);
    }

    #[test]
    fn a_timing_fault_keeps_what_the_controller_learned_unless_configured() {
        use crate::config::TimingFaultReset;
        let c = ServiceConfig::parse(GOOD, "good.toml").unwrap();
        assert_eq!(c.policy.on_timing_fault, TimingFaultReset::KeepLearned);
        let text = GOOD.replace(
            "[service]",
            "[service]\non-timing-fault = \"reset-controller\"",
        );
        let c = ServiceConfig::parse(&text, "x.toml").unwrap();
        assert_eq!(c.policy.on_timing_fault, TimingFaultReset::ResetController);
        let m = refused(&GOOD.replace("[service]", "[service]\non-timing-fault = \"forget\""));
        assert!(m.contains("on-timing-fault") || m.contains("forget"), "{m}");
    }
}
