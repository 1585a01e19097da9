//! The soak campaign: how the main job holds real time under load, measured in one
//! sitting.
//!
//! `rig soak SCENARIO` runs the scenario as the main job does ([`crate::launch`], real
//! time, the two processes over shared memory) for every combination of a controller
//! (`--controller FILE`, repeatable; the word `scenario` stands for the scenario's own
//! `[controller]`, the default), a wait mode (`--wait`, repeatable; default the
//! scenario's `service.wait`) and a condition (`--conditions`):
//!
//! | condition | extra load during the run |
//! | --- | --- |
//! | `idle` | none |
//! | `hog-rt` | a `SCHED_OTHER` busy loop pinned to the service's RT core (`service.core`) |
//! | `hog-plant` | one on the plant's core (`proxy.core`) |
//! | `hog-both` | one on each |
//!
//! A busy loop ([`hog::Hog`]) starts 0.2 s before its run and is killed and reaped right
//! after it, whatever happened (kill on drop; a `SIGINT` or `SIGTERM` stops the run in
//! progress as it stops `rig launch` and is left out of the tables, then the campaign
//! ends). Round `r` runs every combination
//! once, forwards or backwards in an ABBA pattern ([`order`]), so that a slow drift of the
//! machine weighs on all of them alike; each run goes into
//! `OUT/<controller>-<wait>-<condition>-<r>/` (rounds from 1), without its figure, with
//! the children's output in `service.log` and `plant-proxy.log` there; 1 s separates two
//! runs.
//!
//! Every run becomes a row ([`row`]): its smallest tone suppression, lost and held shares
//! past start-up, caught-up samples, verdict and first failure, response and wake-up p99,
//! the RT thread's run-queue wait and involuntary switches, and the plant's clock slips.
//! A run whose report cannot be read is a row that says so. Per combination the
//! [`summary`] counts the runs that met the acceptance criterion (smallest suppression at
//! least `service.report.min-suppression-db` of the scenario, or of the controller file),
//! and checks that every run below it failed its verdict with a failure line naming
//! `SUPPRESSION`; per controller and wait mode it sets each load against idle. The
//! results file ([`markdown`]) states the command and the machine ([`machine`]).

pub mod hog;
pub mod machine;
pub mod markdown;
pub mod order;
pub mod row;
pub mod summary;

use crate::launch::{LaunchOptions, launch};
use crate::scenario_toml;
use hog::Hog;
use machine::Machine;
use row::{RowError, RunRow};
use service::config::ServiceConfig;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;
use summary::{CellSummary, LoadRatio};

/// How long a hog runs before its run starts.
pub const HOG_LEAD: Duration = Duration::from_millis(200);
/// The pause between two runs.
pub const PAUSE: Duration = Duration::from_secs(1);
/// The word of `--controller` for the scenario's own `[controller]`.
pub const SCENARIO_CONTROLLER: &str = "scenario";
/// The wait modes `--wait` takes.
pub const WAIT_MODES: [&str; 3] = ["sleep-poll", "busy-poll", "block"];

/// The load of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Condition {
    /// No extra load.
    Idle,
    /// A busy loop on the service's RT core.
    HogRt,
    /// A busy loop on the plant's core.
    HogPlant,
    /// A busy loop on each.
    HogBoth,
}

impl Condition {
    /// Every condition, in the default order.
    pub const ALL: [Condition; 4] = [
        Condition::Idle,
        Condition::HogRt,
        Condition::HogPlant,
        Condition::HogBoth,
    ];

    /// `idle`, `hog-rt`, `hog-plant`, `hog-both`.
    pub fn name(self) -> &'static str {
        match self {
            Condition::Idle => "idle",
            Condition::HogRt => "hog-rt",
            Condition::HogPlant => "hog-plant",
            Condition::HogBoth => "hog-both",
        }
    }

    /// The condition named `s`.
    pub fn parse(s: &str) -> Option<Condition> {
        Condition::ALL.into_iter().find(|c| c.name() == s)
    }

    /// Whether it loads the RT core.
    pub fn loads_rt(self) -> bool {
        matches!(self, Condition::HogRt | Condition::HogBoth)
    }

    /// Whether it loads the plant's core.
    pub fn loads_plant(self) -> bool {
        matches!(self, Condition::HogPlant | Condition::HogBoth)
    }
}

/// Why a campaign did not run.
#[derive(Debug, Clone, PartialEq)]
pub enum SoakError {
    /// A refused option or configuration, naming the option, file and field (exit code 2).
    Usage(String),
    /// Something failed outside the runs (the campaign's folder) (exit code 1).
    Run(String),
}

impl std::fmt::Display for SoakError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SoakError::Usage(m) | SoakError::Run(m) => f.write_str(m),
        }
    }
}

/// What `rig soak` was asked for, before it is checked.
#[derive(Debug, Clone, Default)]
pub struct SoakOptions {
    /// The scenario.
    pub scenario: PathBuf,
    /// `--controller`: files, or [`SCENARIO_CONTROLLER`]; empty: the scenario's own.
    pub controllers: Vec<PathBuf>,
    /// `--runs`: rounds.
    pub runs: usize,
    /// `--conditions`: names; empty: all four.
    pub conditions: Vec<String>,
    /// `--wait`: wait modes; empty: the scenario's.
    pub waits: Vec<String>,
    /// `--duration`: seconds of each run (default: the scenario's `rig.duration`).
    pub duration: Option<f64>,
    /// `--out`: the campaign's folder.
    pub out: PathBuf,
}

/// One controller of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerArm {
    /// `scenario`, or the controller file's name without `.toml` (`acoustic-rls`).
    pub label: String,
    /// The controller file (`None`: the scenario's own `[controller]`).
    pub file: Option<PathBuf>,
    /// Its acceptance criterion, `service.report.min-suppression-db`.
    pub criterion_db: Option<f64>,
}

/// One combination of a campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct Combination {
    /// Index into [`SoakPlan::arms`].
    pub arm: usize,
    /// The wait mode.
    pub wait: String,
    /// The condition.
    pub condition: Condition,
}

/// A checked campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct SoakPlan {
    /// The scenario.
    pub scenario: PathBuf,
    /// The controllers.
    pub arms: Vec<ControllerArm>,
    /// The wait modes.
    pub waits: Vec<String>,
    /// The conditions.
    pub conditions: Vec<Condition>,
    /// Rounds.
    pub runs: usize,
    /// Seconds of each run (`None`: the scenario's `rig.duration`).
    pub duration: Option<f64>,
    /// The scenario's `rig.duration`, s, when it states one.
    pub scenario_duration: Option<f64>,
    /// The campaign's folder.
    pub out: PathBuf,
    /// The service's RT core (`service.core`).
    pub rt_core: Option<usize>,
    /// The plant's core (`proxy.core`).
    pub plant_core: Option<usize>,
}

impl SoakPlan {
    /// The combinations in their natural order: controller, then wait mode, then condition.
    pub fn combinations(&self) -> Vec<Combination> {
        let mut v = Vec::new();
        for arm in 0..self.arms.len() {
            for wait in &self.waits {
                for &condition in &self.conditions {
                    v.push(Combination {
                        arm,
                        wait: wait.clone(),
                        condition,
                    });
                }
            }
        }
        v
    }

    /// The run folder's name of `c` in round `round` (from 1).
    pub fn folder_name(&self, c: &Combination, round: usize) -> String {
        format!(
            "{}-{}-{}-{round}",
            self.arms[c.arm].label,
            c.wait,
            c.condition.name()
        )
    }

    /// The cores a run of `condition` loads.
    pub fn hog_cores(&self, condition: Condition) -> Vec<usize> {
        let mut v = Vec::new();
        if condition.loads_rt() {
            v.extend(self.rt_core);
        }
        if condition.loads_plant() {
            v.extend(self.plant_core);
        }
        v
    }
}

fn dedup(v: Vec<String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for s in v {
        if !out.contains(&s) {
            out.push(s);
        }
    }
    out
}

/// A core of `table.field` in the scenario's TOML, if set.
fn core_of(
    t: &toml::Table,
    table: &str,
    field: &str,
    file: &Path,
) -> Result<Option<usize>, SoakError> {
    match t.get(table).and_then(|v| v.get(field)) {
        None => Ok(None),
        Some(v) => v
            .as_integer()
            .and_then(|c| usize::try_from(c).ok())
            .map(Some)
            .ok_or_else(|| {
                SoakError::Usage(format!(
                    "{}: field '{table}.{field}' is not a core number",
                    file.display()
                ))
            }),
    }
}

/// Checks `opts` against the scenario, its controller files and this machine.
///
/// # Errors
///
/// [`SoakError::Usage`], naming the option or the file and field: a scenario or
/// controller file the service refuses, two controller files of one name, an unknown
/// condition or wait mode, no rounds, a bad duration, a hog condition whose core is not
/// set or not on this machine, an `--out` folder that is not empty.
pub fn plan(opts: &SoakOptions) -> Result<SoakPlan, SoakError> {
    let usage = |m: String| SoakError::Usage(m);
    let scenario = &opts.scenario;
    if opts.runs == 0 {
        return Err(usage("--runs: at least one round is needed".into()));
    }
    if let Some(d) = opts.duration
        && !(d.is_finite() && d > 0.0)
    {
        return Err(usage(format!(
            "--duration: {d} is not a positive number of seconds"
        )));
    }
    let table = scenario_toml::read(scenario).map_err(|e| usage(e.to_string()))?;
    let base = ServiceConfig::load(scenario).map_err(|e| usage(e.to_string()))?;

    let files: Vec<PathBuf> = if opts.controllers.is_empty() {
        vec![PathBuf::from(SCENARIO_CONTROLLER)]
    } else {
        opts.controllers.clone()
    };
    let mut arms: Vec<ControllerArm> = Vec::new();
    for f in files {
        let own = f.as_os_str() == SCENARIO_CONTROLLER;
        let file = (!own).then_some(f);
        let cfg = ServiceConfig::load_scenario(scenario, file.as_deref())
            .map_err(|e| usage(e.to_string()))?;
        let label = match &file {
            None => SCENARIO_CONTROLLER.to_string(),
            Some(p) => p
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| p.display().to_string()),
        };
        if arms.iter().any(|a| a.label == label) {
            return Err(usage(format!(
                "--controller: two controllers named '{label}' (each run folder is named \
                 after its controller's file name)"
            )));
        }
        arms.push(ControllerArm {
            label,
            file,
            criterion_db: cfg.tone_report.min_suppression_db,
        });
    }

    let waits = if opts.waits.is_empty() {
        vec![base.wait.name().to_string()]
    } else {
        dedup(opts.waits.clone())
    };
    if let Some(w) = waits.iter().find(|w| !WAIT_MODES.contains(&w.as_str())) {
        return Err(usage(format!(
            "--wait: '{w}' is not one of {}",
            WAIT_MODES.join(", ")
        )));
    }
    let names = if opts.conditions.is_empty() {
        Condition::ALL
            .iter()
            .map(|c| c.name().to_string())
            .collect()
    } else {
        dedup(opts.conditions.clone())
    };
    let mut conditions = Vec::new();
    for n in &names {
        conditions.push(Condition::parse(n.trim()).ok_or_else(|| {
            usage(format!(
                "--conditions: '{n}' is not one of {}",
                Condition::ALL.map(|c| c.name()).join(", ")
            ))
        })?);
    }

    // SAFETY: sysconf only reads a system setting.
    let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize;
    let rt_core = base.rt.core;
    let plant_core = core_of(&table, "proxy", "core", scenario)?;
    for (needed, core, field) in [
        (
            conditions.iter().any(|c| c.loads_rt()),
            rt_core,
            "service.core",
        ),
        (
            conditions.iter().any(|c| c.loads_plant()),
            plant_core,
            "proxy.core",
        ),
    ] {
        if !needed {
            continue;
        }
        match core {
            None => {
                return Err(usage(format!(
                    "{}: field '{field}' is not set, and the conditions need that core to load it",
                    scenario.display()
                )));
            }
            Some(c) if c >= online => {
                return Err(usage(format!(
                    "{}: field '{field}' = {c}, but this machine has {online} CPUs online",
                    scenario.display()
                )));
            }
            Some(_) => {}
        }
    }
    if std::fs::read_dir(&opts.out).is_ok_and(|mut d| d.next().is_some()) {
        return Err(usage(format!(
            "--out: {} exists and is not empty (a campaign writes into a folder of its own)",
            opts.out.display()
        )));
    }
    let scenario_duration = table
        .get("rig")
        .and_then(|r| r.get("duration"))
        .and_then(|d| d.as_float().or_else(|| d.as_integer().map(|i| i as f64)));
    Ok(SoakPlan {
        scenario: scenario.clone(),
        arms,
        waits,
        conditions,
        runs: opts.runs,
        duration: opts.duration,
        scenario_duration,
        out: opts.out.clone(),
        rt_core,
        plant_core,
    })
}

/// A campaign that ran (to its end, or until it was asked to stop).
#[derive(Debug, Clone)]
pub struct Campaign {
    /// What was run.
    pub plan: SoakPlan,
    /// The command line, as the results file states it.
    pub command: String,
    /// The machine.
    pub machine: Machine,
    /// One row per run, in the order they ran.
    pub rows: Vec<RunRow>,
    /// Why it stopped before its end, if it did.
    pub interrupted: Option<String>,
}

impl Campaign {
    /// One paragraph: what ran, where, and on which cores the hogs ran.
    pub fn description(&self) -> String {
        let p = &self.plan;
        let n = p.combinations().len();
        let secs = p
            .duration
            .or(p.scenario_duration)
            .map_or("the scenario's duration".to_string(), |d| format!("{d} s"));
        let core = |c: Option<usize>| c.map_or("not set".to_string(), |c| c.to_string());
        format!(
            "Campaign: scenario `{}`, {} round(s) × {n} combination(s) = {} runs of {secs} \
             in real time ({} ran), in `{}`; controllers {}; wait {}; conditions {}. Hogs: \
             `SCHED_OTHER` busy loops on the RT core {} (`service.core`) and the plant's core \
             {} (`proxy.core`). Rounds alternate forwards and backwards (ABBA).",
            p.scenario.display(),
            p.runs,
            p.runs * n,
            self.rows.len(),
            p.out.display(),
            p.arms
                .iter()
                .map(|a| match (&a.file, a.criterion_db) {
                    (None, Some(c)) => format!("`{}` (the scenario's, ≥ {c} dB)", a.label),
                    (None, None) => format!("`{}` (the scenario's, no criterion)", a.label),
                    (Some(f), Some(c)) => format!("`{}` ({}, ≥ {c} dB)", a.label, f.display()),
                    (Some(f), None) => format!("`{}` ({}, no criterion)", a.label, f.display()),
                })
                .collect::<Vec<_>>()
                .join(", "),
            p.waits.join(", "),
            p.conditions
                .iter()
                .map(|c| c.name())
                .collect::<Vec<_>>()
                .join(", "),
            core(p.rt_core),
            core(p.plant_core),
        )
    }

    fn rows_of(&self, arm: &str, wait: &str, condition: &str) -> Vec<&RunRow> {
        self.rows
            .iter()
            .filter(|r| r.controller == arm && r.wait == wait && r.condition == condition)
            .collect()
    }

    /// One summary per combination that ran, in the combinations' order.
    pub fn summaries(&self) -> Vec<CellSummary> {
        self.plan
            .combinations()
            .iter()
            .filter_map(|c| {
                let (arm, cond) = (&self.plan.arms[c.arm].label, c.condition.name());
                let rows = self.rows_of(arm, &c.wait, cond);
                (!rows.is_empty()).then(|| summary::summarize(arm, &c.wait, cond, &rows))
            })
            .collect()
    }

    /// Each loaded condition against idle, per controller and wait mode (where both ran).
    pub fn load_ratios(&self) -> Vec<LoadRatio> {
        let mut v = Vec::new();
        for c in self.plan.combinations() {
            if c.condition == Condition::Idle {
                continue;
            }
            let arm = &self.plan.arms[c.arm].label;
            let idle = self.rows_of(arm, &c.wait, Condition::Idle.name());
            let loaded = self.rows_of(arm, &c.wait, c.condition.name());
            if idle.is_empty() || loaded.is_empty() {
                continue;
            }
            v.push(LoadRatio {
                controller: arm.clone(),
                wait: c.wait.clone(),
                condition: c.condition.name().to_string(),
                idle: summary::medians(&idle),
                loaded: summary::medians(&loaded),
            });
        }
        v
    }

    /// The summary and the loaded-over-idle tables, as printed.
    pub fn summary_text(&self) -> String {
        let ratios = self.load_ratios();
        let mut out = markdown::summary_table(&self.summaries());
        if !ratios.is_empty() {
            out += "\n";
            out += &markdown::ratio_table(&ratios);
        }
        out
    }

    /// The results file ([`markdown::render`]).
    pub fn render_markdown(&self) -> String {
        markdown::render(self, &self.summaries(), &self.load_ratios())
    }
}

/// `args` as one shell command line (arguments that need it single-quoted).
pub fn command_line(args: impl IntoIterator<Item = String>) -> String {
    args.into_iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c));
            if plain {
                a
            } else {
                format!("'{}'", a.replace('\'', "'\\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Runs the campaign of `plan` (see the module docs), printing one line per run on
/// standard error. `stop` is set by a signal handler to the number of the signal that asks
/// it to end (0: none): the run in progress is stopped as `rig launch` stops, and no other
/// starts.
///
/// # Errors
///
/// [`SoakError::Run`] when the campaign's folder cannot be made. A run that fails, or
/// whose hog cannot start, is a row, not an error.
pub fn run(plan: SoakPlan, command: String, stop: Arc<AtomicUsize>) -> Result<Campaign, SoakError> {
    std::fs::create_dir_all(&plan.out)
        .map_err(|e| SoakError::Run(format!("creating {}: {e}", plan.out.display())))?;
    let machine = Machine::now();
    let combos = plan.combinations();
    let order = order::campaign_order(combos.len(), plan.runs);
    let total = order.len();
    eprintln!(
        "[soak] {total} runs ({} rounds × {} combinations) into {}",
        plan.runs,
        combos.len(),
        plan.out.display()
    );
    let mut rows = Vec::new();
    let mut interrupted = None;
    for (i, (round, c)) in order.into_iter().enumerate() {
        if let Some(sig) = signalled(&stop) {
            interrupted = Some(format!("{sig} before run {} of {total}", i + 1));
            break;
        }
        if i > 0 {
            std::thread::sleep(PAUSE);
        }
        let combo = &combos[c];
        let arm = &plan.arms[combo.arm];
        let name = plan.folder_name(combo, round + 1);
        let folder = plan.out.join(&name);
        let mut row = RunRow {
            controller: arm.label.clone(),
            wait: combo.wait.clone(),
            condition: combo.condition.name().to_string(),
            round: round + 1,
            seq: i + 1,
            folder: name.clone(),
            criterion_db: arm.criterion_db,
            outcome: Err(RowError::Pending),
            launch_error: None,
        };
        eprintln!("[soak] run {}/{total}: {name}", i + 1);
        let hogs: Result<Vec<Hog>, String> = plan
            .hog_cores(combo.condition)
            .into_iter()
            .map(|core| Hog::start(core).map_err(|e| format!("the hog on core {core}: {e}")))
            .collect();
        match hogs {
            Err(e) => {
                row.outcome = Err(RowError::NotRun(e));
            }
            Ok(hogs) => {
                if !hogs.is_empty() {
                    std::thread::sleep(HOG_LEAD);
                }
                let opts = LaunchOptions {
                    config: plan.scenario.clone(),
                    run_folder: Some(folder.clone()),
                    mode: "real-time".into(),
                    duration: plan.duration,
                    wait: Some(combo.wait.clone()),
                    controller: arm.file.clone(),
                    skip_figure: true,
                    child_logs: true,
                    ..Default::default()
                };
                let done = launch(&opts, stop.clone());
                drop(hogs);
                row.launch_error = done.err().map(|e| e.to_string());
                row.outcome = row::read_run(&folder);
            }
        }
        if let Some(sig) = signalled(&stop) {
            // A run cut short says nothing about real time: it is left out.
            interrupted = Some(format!(
                "{sig} during run {} of {total} ({name}, stopped and left out of the tables)",
                i + 1
            ));
            break;
        }
        eprintln!("[soak]   {}", progress(&row));
        rows.push(row);
    }
    let mut machine = machine;
    machine.load_end = machine::load_average();
    Ok(Campaign {
        plan,
        command,
        machine,
        rows,
        interrupted,
    })
}

fn signalled(stop: &AtomicUsize) -> Option<&'static str> {
    match stop.load(Ordering::Relaxed) {
        0 => None,
        s => Some(crate::launch::signal_name(s as i32)),
    }
}

/// The line printed after a run.
fn progress(r: &RunRow) -> String {
    match &r.outcome {
        Ok(f) => format!(
            "min suppression {}, lost {:.3} %, held {:.3} %, response p99 {:.1} µs, verdict {}",
            f.min_suppression_db
                .map_or("not measured".to_string(), |d| format!("{d:.1} dB")),
            100.0 * f.lost_share,
            100.0 * f.held_share,
            f.response_p99_ns as f64 / 1e3,
            match f.first_failure() {
                None => "OK".to_string(),
                Some(l) => format!("FAILED: {l}"),
            }
        ),
        Err(e) => format!("RUN FAILED, NO REPORT: {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conditions_by_name_and_the_cores_they_load() {
        assert_eq!(Condition::parse("hog-both"), Some(Condition::HogBoth));
        assert_eq!(Condition::parse("hog"), None);
        let p = SoakPlan {
            scenario: "s.toml".into(),
            arms: vec![ControllerArm {
                label: "scenario".into(),
                file: None,
                criterion_db: Some(60.0),
            }],
            waits: vec!["sleep-poll".into(), "block".into()],
            conditions: vec![Condition::Idle, Condition::HogRt],
            runs: 2,
            duration: Some(3.0),
            scenario_duration: Some(10.0),
            out: "/tmp/x".into(),
            rt_core: Some(1),
            plant_core: Some(0),
        };
        assert!(p.hog_cores(Condition::Idle).is_empty());
        assert_eq!(p.hog_cores(Condition::HogRt), vec![1]);
        assert_eq!(p.hog_cores(Condition::HogPlant), vec![0]);
        assert_eq!(p.hog_cores(Condition::HogBoth), vec![1, 0]);
        let c = p.combinations();
        assert_eq!(c.len(), 4);
        assert_eq!(p.folder_name(&c[3], 2), "scenario-block-hog-rt-2");
        assert_eq!(p.folder_name(&c[0], 1), "scenario-sleep-poll-idle-1");
    }

    #[test]
    fn the_command_line_quotes_what_needs_it() {
        let args = [
            "rig",
            "soak",
            "a b.toml",
            "--conditions",
            "idle,hog-rt",
            "it's",
        ];
        assert_eq!(
            command_line(args.map(String::from)),
            "rig soak 'a b.toml' --conditions idle,hog-rt 'it'\\''s'"
        );
    }

    #[test]
    fn bad_options_are_refused_by_name() {
        let opts = |f: &dyn Fn(&mut SoakOptions)| {
            let mut o = SoakOptions {
                scenario: "../../scenarios/acoustic-rig.toml".into(),
                runs: 1,
                out: std::env::temp_dir().join(format!("soak-plan-{}", std::process::id())),
                ..Default::default()
            };
            f(&mut o);
            plan(&o)
        };
        let ok = opts(&|_| {}).unwrap();
        assert_eq!(ok.arms[0].label, "scenario");
        assert_eq!(ok.arms[0].criterion_db, Some(60.0));
        assert_eq!(ok.waits, vec!["sleep-poll"]);
        assert_eq!(ok.conditions, Condition::ALL.to_vec());
        assert_eq!((ok.rt_core, ok.plant_core), (Some(1), Some(0)));

        let rls = opts(&|o| {
            o.controllers = vec![
                "scenario".into(),
                "../../scenarios/rcac/acoustic-rls.toml".into(),
            ]
        })
        .unwrap();
        assert_eq!(rls.arms[1].label, "acoustic-rls");
        assert_eq!(rls.arms[1].criterion_db, Some(40.0));

        let err = |f: &dyn Fn(&mut SoakOptions)| match opts(f) {
            Err(SoakError::Usage(m)) => m,
            other => panic!("not a usage error: {other:?}"),
        };
        assert!(err(&|o| o.runs = 0).starts_with("--runs"));
        assert!(err(&|o| o.duration = Some(-1.0)).starts_with("--duration"));
        assert!(err(&|o| o.waits = vec!["spin".into()]).starts_with("--wait: 'spin'"));
        assert!(err(&|o| o.conditions = vec!["hog".into()]).starts_with("--conditions: 'hog'"));
        assert!(err(&|o| o.scenario = "no-such.toml".into()).contains("no-such.toml"));
        let dup = err(&|o| {
            o.controllers = vec![
                "../../scenarios/rcac/acoustic-rls.toml".into(),
                "../../scenarios/rcac/acoustic-rls.toml".into(),
            ]
        });
        assert!(
            dup.contains("two controllers named 'acoustic-rls'"),
            "{dup}"
        );
    }
}
