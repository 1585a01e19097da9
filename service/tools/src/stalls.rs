//! The stall study: what a stall of the service costs the plant under each timing and late
//! policy, measured deterministically in lockstep.
//!
//! A scenario runs as the main job does (the two real processes over shared memory), in
//! lockstep, once per case, with the same seed. In every case but the baselines the plant
//! injects stalls of the service (`[proxy.faults] stalls`): stalls of 1, 2, 4, 16, 48 and
//! 80 periods at 4, 5, 6, 7, 8 and 9 s of a 10 s run, far enough apart for the lightly
//! damped enclosure to settle in between. At 8 kHz the last two are 6 ms and 10 ms: the
//! stalls a shared VM inflicts on a `SCHED_FIFO` thread (cyclictest's maximum on an idle
//! 2-core VM; docs/deployment.md). A stalled sample reaches the service as one that came
//! too late: it takes it in without answering, and the plant applies for it the input it
//! already holds (sent ahead before the stall) or its late policy:
//!
//! | case | timing | plant's late policy |
//! | --- | --- | --- |
//! | compute-first, hold | `compute-first` | hold the last input |
//! | compute-first, safe | `compute-first` | the safe input (0 V) |
//! | send-ahead, hold | `send-ahead` | hold the last input |
//! | send-ahead, safe | `send-ahead` | the safe input (0 V) |
//! | send-ahead, plan `H` | `send-ahead`, plans of `H` entries | the plan's entry, then hold |
//!
//! The plan case runs once per plan length `H` asked for, so that a stall longer than one
//! plan and shorter than another shows what the longer plan buys.
//!
//! Lockstep is bit-for-bit repeatable, so a case and its baseline (the same timing, no
//! stall) differ only by what the stalls did. The cost of a stall of `n` periods at sample
//! `k_s` is the energy of that difference in `z` over the window `[k_s, k_s + W)`
//! (`W` = 0.25 s), in dB relative to the baseline's own `z` energy over the window (the
//! residual the controller leaves):
//!
//! ```text
//! cost = 10 log10( Σ_W (z_k − z_k^base)² / Σ_W (z_k^base)² )
//! ```
//!
//! so 0 dB is a disturbance as large as the whole residual, and −∞ none at all. The plant's
//! trace gives, per stall, the samples it applied a held or safe input for and those it
//! applied a plan entry for.

use crate::design::csvlog;
use crate::file_error::{FileError, FileOp};
use crate::launch::{LaunchError, LaunchOptions, PLANT_TRACE_FILE, launch};
use crate::scenario_toml::{self, ScenarioTomlError};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

/// Why the stall study failed, naming the scenario, the run's folder or the file at fault.
#[derive(Debug, thiserror::Error)]
pub enum StallsError {
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The scenario file cannot be read or lacks the sample period.
    #[error(transparent)]
    ScenarioFile(#[from] ScenarioTomlError),
    /// A run's scenario cannot be written as TOML.
    #[error("writing the scenario: {0}")]
    Scenario(#[source] toml::ser::Error),
    /// A run failed.
    #[error("{case} ({}): {source}", folder.display())]
    Run {
        /// The case.
        case: String,
        /// Its run folder.
        folder: PathBuf,
        /// Why.
        #[source]
        source: LaunchError,
    },
    /// A run's plant trace cannot be read, or lacks a column.
    #[error(transparent)]
    Log(#[from] csvlog::LogError),
    /// A case's timing has no baseline run.
    #[error("no baseline")]
    NoBaseline,
}

message_from!(StallsError);

/// The injected stalls: (time of the first stalled sample in s, periods).
pub const STALLS: [(f64, u64); 6] = [
    (4.0, 1),
    (5.0, 2),
    (6.0, 4),
    (7.0, 16),
    (8.0, 48),
    (9.0, 80),
];
/// Length of the run, s.
pub const DURATION_S: f64 = 10.0;
/// The window over which a stall's cost is measured, s.
pub const WINDOW_S: f64 = 0.25;

/// One case of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Case {
    /// `service.timing`.
    pub timing: &'static str,
    /// `proxy.late-policy`.
    pub late_policy: &'static str,
    /// `service.plan-length` (0 unless the late policy is `"plan"`).
    pub plan_length: usize,
}

impl Case {
    /// "send-ahead, hold" or "send-ahead, plan 32".
    pub fn name(&self) -> String {
        if self.late_policy == "plan" {
            format!("{}, plan {}", self.timing, self.plan_length)
        } else {
            format!("{}, {}", self.timing, self.late_policy)
        }
    }
}

/// The cases of the module docs without plans, in order; [`run`] adds one plan case per
/// plan length.
pub const CASES: [Case; 4] = [
    Case {
        timing: "compute-first",
        late_policy: "hold",
        plan_length: 0,
    },
    Case {
        timing: "compute-first",
        late_policy: "safe",
        plan_length: 0,
    },
    Case {
        timing: "send-ahead",
        late_policy: "hold",
        plan_length: 0,
    },
    Case {
        timing: "send-ahead",
        late_policy: "safe",
        plan_length: 0,
    },
];

/// What one stall cost in one case.
#[derive(Debug, Clone, Serialize)]
pub struct StallCost {
    /// The case.
    pub case: Case,
    /// Periods stalled.
    pub periods: u64,
    /// The first stalled sample.
    pub at: u64,
    /// Samples the plant applied a held or safe input for.
    pub held_or_safe: u64,
    /// Samples it applied a plan entry for.
    pub plan_entries: u64,
    /// The cost of the module docs, dB (−∞: none).
    pub cost_db: f64,
    /// The largest `|z_k − z_k^base|` over the window, Pa.
    pub peak_pa: f64,
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct StallStudy {
    /// The scenario.
    pub scenario: PathBuf,
    /// Plan entries per answer, one plan case each.
    pub plan_lengths: Vec<usize>,
    /// The RMS of `z` over the last 2 s of each baseline (no stall), by timing, Pa.
    pub baseline_rms: Vec<(String, f64)>,
    /// One row per case and stall.
    pub costs: Vec<StallCost>,
}

/// Runs the study on `scenario` with one plan case per entry of `plan_lengths`, every run
/// in a folder under `runs`.
///
/// # Errors
///
/// A run that failed (naming its folder) or a log that could not be read.
pub fn run(
    scenario: &Path,
    plan_lengths: &[usize],
    runs: &Path,
) -> Result<StallStudy, StallsError> {
    let base = scenario_toml::read(scenario)?;
    let period = scenario_toml::sample_period(&base, scenario)?;
    let stalls: Vec<(u64, u64)> = STALLS
        .iter()
        .map(|(t, n)| ((t / period).round() as u64, *n))
        .collect();
    let window = (WINDOW_S / period).round() as usize;
    let dir = scenario.parent().unwrap_or(Path::new("."));
    let mut baselines = Vec::new();
    for timing in ["compute-first", "send-ahead"] {
        let case = Case {
            timing,
            late_policy: "hold",
            plan_length: 0,
        };
        let folder = one_run(&base, dir, runs, case, &[], "baseline")?;
        baselines.push((timing, z_of(&folder)?));
    }
    let mut costs = Vec::new();
    let plans = plan_lengths.iter().map(|&plan_length| Case {
        timing: "send-ahead",
        late_policy: "plan",
        plan_length,
    });
    for case in CASES.into_iter().chain(plans) {
        let folder = one_run(&base, dir, runs, case, &stalls, "stalls")?;
        let z = z_of(&folder)?;
        let trace = csvlog::read(&folder.join(PLANT_TRACE_FILE))?;
        let (flags, status) = (trace.column("flags")?, trace.column("actuation_status")?);
        let z_base = &baselines
            .iter()
            .find(|(t, _)| *t == case.timing)
            .ok_or(StallsError::NoBaseline)?
            .1;
        for &(at, periods) in &stalls {
            let k0 = at as usize;
            let range = k0..(k0 + window).min(z.len()).min(z_base.len());
            let (mut diff, mut resid, mut peak) = (0.0, 0.0, 0.0_f64);
            for k in range {
                let d = z[k] - z_base[k];
                diff += d * d;
                resid += z_base[k] * z_base[k];
                peak = peak.max(d.abs());
            }
            // A miss for sample k shows as status u32::MAX in its row, and a plan entry
            // as PLAN_APPLIED in the next row's flags.
            let (mut held, mut planned) = (0, 0);
            for k in k0..k0 + periods as usize + 2 {
                if status.get(k).copied() != Some(u32::MAX as f64) {
                    continue;
                }
                let next = flags.get(k + 1).copied().unwrap_or(0.0) as u32;
                if next & ipc_types::measurement_flags::PLAN_APPLIED != 0 {
                    planned += 1;
                } else {
                    held += 1;
                }
            }
            costs.push(StallCost {
                case,
                periods,
                at,
                held_or_safe: held,
                plan_entries: planned,
                cost_db: 10.0 * (diff / resid).log10(),
                peak_pa: peak,
            });
        }
    }
    let last = (2.0 / period).round() as usize;
    let baseline_rms = baselines
        .iter()
        .map(|(t, z)| {
            let tail = &z[z.len().saturating_sub(last)..];
            let ms = tail.iter().map(|v| v * v).sum::<f64>() / tail.len().max(1) as f64;
            (t.to_string(), ms.sqrt())
        })
        .collect();
    Ok(StallStudy {
        scenario: scenario.to_path_buf(),
        plan_lengths: plan_lengths.to_vec(),
        baseline_rms,
        costs,
    })
}

/// One lockstep run of `case` on the scenario `base` (whose relative file names resolve
/// from `dir`) with `stalls` (first sample, periods); returns its folder.
fn one_run(
    base: &toml::Table,
    dir: &Path,
    runs: &Path,
    case: Case,
    stalls: &[(u64, u64)],
    what: &str,
) -> Result<PathBuf, StallsError> {
    let mut t = base.clone();
    let table = |t: &toml::Table, name: &str| -> toml::Table {
        t.get(name)
            .and_then(|v| v.as_table())
            .cloned()
            .unwrap_or_default()
    };
    // A rig name of its own, so that the study runs beside a main job of the same rig.
    let mut rig = table(&t, "rig");
    let name = rig.get("name").and_then(|v| v.as_str()).unwrap_or("rig");
    let name = format!("{name}-stalls-{}", std::process::id());
    rig.insert("name".into(), name.into());
    t.insert("rig".into(), rig.into());
    let mut service = table(&t, "service");
    service.insert("timing".into(), case.timing.into());
    service.insert("plan-length".into(), (case.plan_length as i64).into());
    t.insert("service".into(), service.into());
    let mut proxy = table(&t, "proxy");
    proxy.insert("mode".into(), "lockstep".into());
    proxy.insert("late-policy".into(), case.late_policy.into());
    proxy.remove("plan-fallback");
    let deadline = if case.timing == "send-ahead" {
        0.0
    } else {
        0.8
    };
    proxy.insert("deadline".into(), deadline.into());
    let mut faults = proxy
        .get("faults")
        .and_then(|v| v.as_table())
        .cloned()
        .unwrap_or_default();
    let list: Vec<toml::Value> = stalls
        .iter()
        .map(|(at, n)| {
            let mut s = toml::Table::new();
            s.insert("at".into(), (*at as i64).into());
            s.insert("periods".into(), (*n as i64).into());
            s.into()
        })
        .collect();
    faults.insert("stalls".into(), list.into());
    proxy.insert("faults".into(), faults.into());
    t.insert("proxy".into(), proxy.into());
    let slug = match (stalls.is_empty(), case.late_policy) {
        (true, _) => format!("{what}-{}-none", case.timing),
        (false, "plan") => format!("{what}-{}-plan-{}", case.timing, case.plan_length),
        (false, policy) => format!("{what}-{}-{policy}", case.timing),
    };
    // The edited scenario goes into the temporary folder, its relative file names resolved
    // from the original's folder first.
    let mut controller = table(&t, "controller");
    crate::gaps::resolve_files(&mut controller, dir);
    t.insert("controller".into(), controller.into());
    let file = std::env::temp_dir().join(format!("rig-stalls-{slug}-{}.toml", std::process::id()));
    let text = toml::to_string(&t).map_err(StallsError::Scenario)?;
    std::fs::write(&file, text)
        .map_err(|source| FileError::new(FileOp::Access, file.clone(), source))?;
    let folder = runs.join(&slug);
    let opts = LaunchOptions {
        config: file.clone(),
        run_folder: Some(folder.clone()),
        mode: "lockstep".into(),
        duration: Some(DURATION_S),
        plant_trace: true,
        skip_figure: true,
        ..Default::default()
    };
    let done = launch(&opts, Arc::new(AtomicUsize::new(0)));
    let _ = std::fs::remove_file(&file);
    done.map_err(|source| StallsError::Run {
        case: case.name(),
        folder: folder.clone(),
        source,
    })?;
    Ok(folder)
}

/// `z0` of every sample of a run, from the plant's trace (the service's log has no row for
/// a stalled sample).
fn z_of(folder: &Path) -> Result<Vec<f64>, StallsError> {
    let trace = csvlog::read(&folder.join(PLANT_TRACE_FILE))?;
    Ok(trace.column("z0")?.to_vec())
}

/// The study as a Markdown section: the cases, the per-stall table, and how it was made.
pub fn render_markdown(s: &StallStudy, command: &str) -> String {
    let mut out = String::new();
    out += &format!(
        "Command: `{command}` (lockstep, deterministic: every run of it gives these numbers).\n\n"
    );
    out += "Residual RMS of z over the last 2 s without a stall: ";
    out += &s
        .baseline_rms
        .iter()
        .map(|(t, r)| format!("{t} {r:.3e} Pa"))
        .collect::<Vec<_>>()
        .join(", ");
    out += &format!(
        ".\n\nCost of each stall: the energy of the change it made to z over {WINDOW_S} s \
         from its start, in dB relative to the residual over the same window \
         (0 dB: as large as the whole residual). A plan case names its plan length.\n\n"
    );
    out += "| case | stall (periods) | held or safe inputs | plan entries | cost dB | peak change Pa |\n";
    out += "| --- | --- | --- | --- | --- | --- |\n";
    for c in &s.costs {
        let db = if c.cost_db.is_finite() {
            format!("{:.1}", c.cost_db)
        } else {
            "−∞ (none)".into()
        };
        out += &format!(
            "| {} | {} | {} | {} | {db} | {:.2e} |\n",
            c.case.name(),
            c.periods,
            c.held_or_safe,
            c.plan_entries,
            c.peak_pa
        );
    }
    out
}
