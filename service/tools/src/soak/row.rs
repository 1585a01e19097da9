//! One run of a campaign as one row: the figures `rig soak` reads from its `report.json`
//! and `plant-report.json`.
//!
//! The reports are read as JSON values, field by field, so that a report this build
//! cannot read — absent, torn, or of another shape — becomes a row that says why
//! ([`RunRow::outcome`] is `Err`), never a panic. A figure the service writes as `null`
//! (a `/proc` file it could not read) stays `None`.

use serde_json::Value;
use std::path::{Path, PathBuf};

/// What one run's reports say.
#[derive(Debug, Clone, PartialEq)]
pub struct RunFigures {
    /// The smallest suppression over the report's tones, dB; `None` when the report has
    /// no tone, or a tone was not measured.
    pub min_suppression_db: Option<f64>,
    /// Samples past start-up that never reached the service, over the samples past
    /// start-up (`stats.lost_past_startup / stats.samples_past_startup`; 0 without any).
    pub lost_share: f64,
    /// Inputs past start-up the plant held or replaced by its safe output, over the
    /// samples past start-up (`stats.held_past_startup / stats.samples_past_startup`).
    pub held_share: f64,
    /// Samples the service caught up (observed, not answered): `stats.caught_up`.
    pub caught_up: u64,
    /// `verdict.ok`.
    pub verdict_ok: bool,
    /// `verdict.failures`, in order.
    pub failures: Vec<String>,
    /// `latency.response.p99`, ns.
    pub response_p99_ns: u64,
    /// `latency.wakeup.p99`, ns.
    pub wakeup_p99_ns: u64,
    /// `scheduling.rt_thread.run_queue_wait_ns`.
    pub run_queue_wait_ns: Option<u64>,
    /// `scheduling.rt_thread.involuntary_switches`.
    pub involuntary_switches: Option<u64>,
    /// Steal time over the run on all CPUs, s (`scheduling.steal.all_cpus_s`): the time
    /// the hypervisor did not run this VM's CPUs although they had work.
    pub steal_s: Option<f64>,
    /// The plant's clock slips (`plant-report.json` → `clock_slips`); `None` without a
    /// readable plant report.
    pub plant_clock_slips: Option<u64>,
    /// The plant's misses that reached it as a held or safe input
    /// (`plant-report.json` → `misses_held_or_safe`).
    pub plant_held_or_safe: Option<u64>,
}

impl RunFigures {
    /// The first failure line of the verdict, if any.
    pub fn first_failure(&self) -> Option<&str> {
        self.failures.first().map(String::as_str)
    }
}

/// One run of the campaign.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// Its controller's label ([`super::ControllerArm::label`]).
    pub controller: String,
    /// Its wait mode.
    pub wait: String,
    /// Its condition's name.
    pub condition: String,
    /// Its round, from 1.
    pub round: usize,
    /// Its position in the campaign, from 1.
    pub seq: usize,
    /// Its run folder's name (under the campaign's folder).
    pub folder: String,
    /// The acceptance criterion it is judged by (`service.report.min-suppression-db`).
    pub criterion_db: Option<f64>,
    /// What its reports say, or why they could not be read.
    pub outcome: Result<RunFigures, RowError>,
    /// Why `rig launch` failed, when it did (a failed verdict is one such failure).
    pub launch_error: Option<String>,
}

/// Why a run of the soak has no figures: its report cannot be read or lacks a field
/// (naming the file and the field), or it did not run. Messages of the system and of the
/// JSON parser are kept as text, so that a row compares and clones.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RowError {
    /// The run has not been made yet.
    #[error("")]
    Pending,
    /// The run could not be started (why).
    #[error("not run: {0}")]
    NotRun(String),
    /// `report.json` cannot be read.
    #[error("{}: cannot be read: {message}", path.display())]
    Unreadable {
        /// The report.
        path: PathBuf,
        /// The system's message.
        message: String,
    },
    /// What is wrong inside `report.json`.
    #[error("{}: {error}", path.display())]
    In {
        /// The report.
        path: PathBuf,
        /// What.
        error: Box<RowError>,
    },
    /// The report is not JSON (the parser's message).
    #[error("report.json is not JSON: {0}")]
    NotJson(String),
    /// A field is missing.
    #[error("field '{0}' is missing")]
    Missing(String),
    /// A field is not a non-negative integer.
    #[error("field '{0}' is not a non-negative integer")]
    NotCount(String),
    /// A field is not a boolean.
    #[error("field '{0}' is not a boolean")]
    NotBool(&'static str),
    /// A field is not a list.
    #[error("field '{0}' is not a list")]
    NotList(&'static str),
}

impl RunRow {
    /// True when the run met its criterion: its smallest suppression is at least the
    /// criterion. `None` when it has no criterion; `Some(false)` for an unreadable run
    /// or one whose tones were not all measured.
    pub fn met_criterion(&self) -> Option<bool> {
        let c = self.criterion_db?;
        Some(match &self.outcome {
            Ok(f) => f.min_suppression_db.is_some_and(|m| m >= c),
            Err(_) => false,
        })
    }
}

fn at<'a>(v: &'a Value, pointer: &str) -> Result<&'a Value, RowError> {
    v.pointer(pointer)
        .ok_or_else(|| RowError::Missing(field_name(pointer)))
}

fn field_name(pointer: &str) -> String {
    pointer.trim_start_matches('/').replace('/', ".")
}

fn u64_at(v: &Value, pointer: &str) -> Result<u64, RowError> {
    at(v, pointer)?
        .as_u64()
        .ok_or_else(|| RowError::NotCount(field_name(pointer)))
}

/// A field that may be `null` (or absent): `None` then, an error for another type.
fn opt_u64_at(v: &Value, pointer: &str) -> Result<Option<u64>, RowError> {
    match v.pointer(pointer) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => x
            .as_u64()
            .map(Some)
            .ok_or_else(|| RowError::NotCount(field_name(pointer))),
    }
}

fn share(n: u64, d: u64) -> f64 {
    if d == 0 { 0.0 } else { n as f64 / d as f64 }
}

/// The smallest suppression over `tones.tones[].suppression_db`; `None` without tones or
/// when one was not measured (`null`, or not a number).
fn min_suppression(report: &Value) -> Option<f64> {
    let tones = report.pointer("/tones/tones")?.as_array()?;
    if tones.is_empty() {
        return None;
    }
    let mut min = f64::INFINITY;
    for t in tones {
        let db = t.get("suppression_db")?.as_f64()?;
        if db.is_nan() {
            return None;
        }
        min = min.min(db);
    }
    Some(min)
}

/// The figures of a run from the text of its `report.json` and, when there is one, its
/// `plant-report.json` (a plant report that cannot be read leaves the plant's figures
/// `None`).
///
/// # Errors
///
/// The report is not JSON, or a field of [`RunFigures`] is missing or of another type
/// (the message names it).
pub fn parse_reports(report: &str, plant: Option<&str>) -> Result<RunFigures, RowError> {
    let r: Value = serde_json::from_str(report).map_err(|e| RowError::NotJson(e.to_string()))?;
    let samples = u64_at(&r, "/stats/samples_past_startup")?;
    let lost = u64_at(&r, "/stats/lost_past_startup")?;
    let held = u64_at(&r, "/stats/held_past_startup")?;
    let verdict_ok = at(&r, "/verdict/ok")?
        .as_bool()
        .ok_or(RowError::NotBool("verdict.ok"))?;
    let failures = at(&r, "/verdict/failures")?
        .as_array()
        .ok_or(RowError::NotList("verdict.failures"))?
        .iter()
        .map(|f| {
            f.as_str()
                .map(str::to_string)
                .unwrap_or_else(|| f.to_string())
        })
        .collect();
    let p: Option<Value> = plant.and_then(|t| serde_json::from_str(t).ok());
    let plant_u64 = |name: &str| p.as_ref().and_then(|p| p.get(name)).and_then(Value::as_u64);
    Ok(RunFigures {
        min_suppression_db: min_suppression(&r),
        lost_share: share(lost, samples),
        held_share: share(held, samples),
        caught_up: u64_at(&r, "/stats/caught_up")?,
        verdict_ok,
        failures,
        response_p99_ns: u64_at(&r, "/latency/response/p99")?,
        wakeup_p99_ns: u64_at(&r, "/latency/wakeup/p99")?,
        run_queue_wait_ns: opt_u64_at(&r, "/scheduling/rt_thread/run_queue_wait_ns")?,
        involuntary_switches: opt_u64_at(&r, "/scheduling/rt_thread/involuntary_switches")?,
        steal_s: r
            .pointer("/scheduling/steal/all_cpus_s")
            .and_then(Value::as_f64),
        plant_clock_slips: plant_u64("clock_slips"),
        plant_held_or_safe: plant_u64("misses_held_or_safe"),
    })
}

/// The figures of the run in `folder` (its `report.json` and `plant-report.json`).
///
/// # Errors
///
/// `report.json` cannot be read or parsed ([`parse_reports`]); the message names the file.
pub fn read_run(folder: &Path) -> Result<RunFigures, RowError> {
    let path = folder.join("report.json");
    let report = std::fs::read_to_string(&path).map_err(|e| RowError::Unreadable {
        path: path.clone(),
        message: e.to_string(),
    })?;
    let plant = std::fs::read_to_string(folder.join("plant-report.json")).ok();
    parse_reports(&report, plant.as_deref()).map_err(|e| RowError::In {
        path,
        error: Box::new(e),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A made-up `report.json` with the fields `rig soak` reads (and a few it does not).
    pub(crate) fn report(min_db: &str, ok: bool, failures: &[&str]) -> String {
        let failures: Vec<String> = failures.iter().map(|f| format!("{f:?}")).collect();
        format!(
            r#"{{
  "rig": "acoustic-rig",
  "verdict": {{"ok": {ok}, "failures": [{}], "warnings": ["3 samples lost"]}},
  "stats": {{"samples_past_startup": 72000, "lost_past_startup": 36,
             "held_past_startup": 18, "skipped": 36, "caught_up": 5, "received": 79964}},
  "tones": {{"source": "scenario", "window_s": 0.5, "samples": [4000, 4000], "error": null,
             "tones": [
               {{"hz": 800.0, "channel": 0, "open": 0.5, "closed": 0.0001, "suppression_db": 73.9}},
               {{"hz": 900.0, "channel": 0, "open": 0.5, "closed": 0.0004, "suppression_db": {min_db}}}
             ]}},
  "latency": {{"wakeup": {{"p50": 9000, "p99": 21000}},
               "response": {{"p50": 15000, "p99": 42000, "over_budget": 2}}}},
  "scheduling": {{"rt_core": 1, "loop_s": 10.0,
                  "rt_thread": {{"on_cpu_ns": 2000000000, "run_queue_wait_ns": 3500000,
                                 "involuntary_switches": 12, "voluntary_switches": 80000,
                                 "timeslices": 80012}},
                  "steal": {{"rt_core_s": 0.01, "all_cpus_s": 0.03}}}}
}}"#,
            failures.join(", ")
        )
    }

    #[test]
    fn a_report_becomes_a_row() {
        let plant = r#"{"rig": "acoustic-rig", "clock_slips": 2, "misses_held_or_safe": 18}"#;
        let f = parse_reports(&report("61.25", true, &[]), Some(plant)).unwrap();
        assert_eq!(f.min_suppression_db, Some(61.25));
        assert_eq!(f.lost_share, 36.0 / 72000.0);
        assert_eq!(f.held_share, 18.0 / 72000.0);
        assert_eq!(f.caught_up, 5);
        assert!(f.verdict_ok);
        assert_eq!(f.first_failure(), None);
        assert_eq!(f.response_p99_ns, 42000);
        assert_eq!(f.wakeup_p99_ns, 21000);
        assert_eq!(f.run_queue_wait_ns, Some(3_500_000));
        assert_eq!(f.involuntary_switches, Some(12));
        assert_eq!(f.steal_s, Some(0.03));
        assert_eq!(f.plant_clock_slips, Some(2));
        assert_eq!(f.plant_held_or_safe, Some(18));
    }

    #[test]
    fn failures_unmeasured_tones_and_unknown_figures_are_kept_as_such() {
        let text = report(
            "null",
            false,
            &["SUPPRESSION BELOW 60 dB (service.report.min-suppression-db): 900 Hz not measured"],
        )
        .replace(
            "\"run_queue_wait_ns\": 3500000",
            "\"run_queue_wait_ns\": null",
        );
        let f = parse_reports(&text, None).unwrap();
        assert_eq!(f.min_suppression_db, None);
        assert!(!f.verdict_ok);
        assert!(f.first_failure().unwrap().starts_with("SUPPRESSION BELOW"));
        assert_eq!(f.run_queue_wait_ns, None);
        assert_eq!(f.plant_clock_slips, None);
    }

    #[test]
    fn an_unreadable_report_is_an_error_naming_why() {
        assert!(
            parse_reports("{ torn", None)
                .unwrap_err()
                .to_string()
                .contains("not JSON")
        );
        let no_stats = report("61.0", true, &[]).replace("\"caught_up\": 5,", "");
        assert_eq!(
            parse_reports(&no_stats, None).unwrap_err().to_string(),
            "field 'stats.caught_up' is missing"
        );
        let dir = std::env::temp_dir().join(format!("soak-row-{}", std::process::id()));
        let e = read_run(&dir).unwrap_err().to_string();
        assert!(e.contains("report.json: cannot be read"), "{e}");
    }
}
