//! The report of one run: its types, the human-readable rendering, and `report.json`.

use super::checkpoint::WarmStart;
use super::tones::ToneReport;
use super::{LoopEvent, LoopStats, ServiceError, StopReason};
use super::{force_regulation, model_following, verdict};
use crate::record::RecordStats;
use crate::telemetry::TelemetrySummary;
use serde::Serialize;
use std::path::Path;

/// The report of one run, written as `report.json` into the run folder and printed.
#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    /// Rig name.
    pub rig: String,
    /// Configuration file.
    pub config: String,
    /// The run folder.
    pub run_folder: String,
    /// Controller kind.
    pub controller: String,
    /// Wait mode used.
    pub wait: String,
    /// The timing that ran (`compute-first`, `answer-first`, `send-ahead`).
    pub timing: String,
    /// Plan entries per answer (0: none).
    pub plan_length: usize,
    /// What the plans held, when the controller sent any.
    pub plan_source: Option<String>,
    /// Outcome of the real-time set-up, one line.
    pub rt_setup: String,
    /// True when any RT set-up step was refused.
    pub rt_degraded: bool,
    /// Conditions that qualify the figures: an incomplete real-time set-up, and every
    /// anomaly the loop counted ([`verdict`]).
    pub warnings: Vec<String>,
    /// Whether the run did what it was started for ([`verdict`]); the exit status follows.
    pub verdict: verdict::RunVerdict,
    /// Why the loop stopped.
    pub stop_reason: StopReason,
    /// Counters.
    pub stats: LoopStats,
    /// Every event, in order.
    pub events: Vec<LoopEvent>,
    /// RMS of each performance channel over the run.
    pub z_rms: Vec<f64>,
    /// RMS of each performance channel after `service.rms-settle` seconds.
    pub z_rms_settled: Vec<f64>,
    /// Latency histograms.
    pub latency: TelemetrySummary,
    /// Signal log records written and dropped.
    pub log_written: u64,
    /// Signal log records dropped because the queue was full.
    pub log_dropped: u64,
    /// Signal log records the writer could not write (full disk, I/O error).
    pub log_lost_to_disk: u64,
    /// The first write failure of the signal log, naming the file; `None` when there was none.
    pub log_first_error: Option<String>,
    /// `record.bin` ([`crate::record`]): entries offered, written, dropped, lost to the
    /// disk, and whether it is complete; `None` with `log.record = false`.
    pub record: Option<RecordStats>,
    /// Response-time budget used for "over budget" (the sample period), ns.
    pub budget_ns: u64,
    /// Sample period, s.
    pub sample_period_s: f64,
    /// Open-loop phase at the start of each session, s (`service.open-loop`).
    pub open_loop_s: f64,
    /// Allocations on the RT thread during the loop: served by its pool (iceoryx2's
    /// per-sample loan state) and from the system allocator (should be 0).
    pub rt_allocations: crate::rt_alloc::RtAllocStats,
    /// What the pacer's awake-share cap did ([`super::pacing`]).
    pub pacing: super::pacing::PacingReport,
    /// Per-tone amplitudes of `z` at the end of the open-loop phase and at the end of the
    /// run (`[service.report]`), when tones are known.
    pub tones: Option<ToneReport>,
    /// The model-following error norm (4.85), for a controller that follows a reference
    /// model (`service.report.error-window`).
    pub model_following: Option<model_following::ModelFollowingReport>,
    /// The contact phases' force regulation (`service.report.force-regulation`).
    pub force_regulation: Option<force_regulation::ForceRegulationReport>,
    /// What the box does to a real-time loop, for the RT core of this run
    /// ([`crate::system_check`]).
    pub system: Vec<crate::system_check::Finding>,
    /// Checkpoints of what the controller learned ([`checkpoint`](super::checkpoint)); `None` for a
    /// controller that learns nothing.
    pub checkpoint: Option<CheckpointReport>,
    /// Why samples were lost: the RT thread's scheduling over the loop, steal time, and
    /// the other tasks on the RT core ([`crate::scheduling`]).
    pub scheduling: crate::scheduling::SchedulingReport,
    /// What the controller counted over the run ([`Controller::counters`](control::controller::Controller::counters)), e.g. PCAC's
    /// solved, infeasible and unsolved QPs.
    pub controller_counters: Vec<(String, u64)>,
    /// How often an adaptive controller's update ran in closed loop and why it did not
    /// ([`Controller::adaptation`](control::controller::Controller::adaptation)); `None` for a controller that does not adapt.
    pub adaptation: Option<AdaptationReport>,
    /// Every operator command of the run and what became of it ([`crate::operator`]).
    pub operator_commands: Vec<crate::operator::CommandRecord>,
    /// CPU time of the telemetry thread (histogram logs and the live view), s.
    pub telemetry_cpu_s: f64,
}

/// An adaptive controller's closed-loop updates, for the run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdaptationReport {
    /// Steps whose update ran.
    pub updated: u64,
    /// Steps whose update was suspended, per cause.
    pub suspended: Vec<(String, u64)>,
    /// Steps whose update the operator froze (not suspensions).
    pub frozen: u64,
}

impl From<control::Adaptation> for AdaptationReport {
    fn from(a: control::Adaptation) -> Self {
        Self {
            updated: a.updated,
            suspended: a
                .suspended
                .into_iter()
                .map(|(c, n)| (c.to_string(), n))
                .collect(),
            frozen: a.frozen,
        }
    }
}

/// The checkpoints of a run, for its report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckpointReport {
    /// The file (`checkpoint.json` in the run folder).
    pub path: String,
    /// Checkpoints written (the periodic ones and the final one).
    pub written: u64,
    /// Writes that failed.
    pub failures: u64,
    /// The first failure, naming the file.
    pub first_error: Option<String>,
    /// Sample of the last checkpoint written.
    pub last_seq: Option<u64>,
    /// The checkpoint this run started from, if any.
    pub warm_start: Option<WarmStart>,
}

impl RunReport {
    /// The human-readable report.
    pub fn render(&self) -> String {
        let s = &self.stats;
        let mut out = String::new();
        out += &format!(
            "=== run report: rig '{}', controller {}, wait {} ===\n",
            self.rig, self.controller, self.wait
        );
        out += &format!("run folder: {}\n", self.run_folder);
        out += &format!(
            "timing: {}{}\n",
            self.timing,
            match &self.plan_source {
                Some(src) => format!(", plans of {} inputs ({src})", self.plan_length),
                None => ", no plans".to_string(),
            }
        );
        out += &format!(
            "real-time set-up: {}{}\n",
            self.rt_setup,
            if self.rt_degraded {
                "  (DEGRADED: latency figures are not those of an RT setup)"
            } else {
                ""
            }
        );
        out += &format!("{}\n", self.pacing.line(&self.wait));
        for w in &self.warnings {
            out += &format!("WARNING: {w}\n");
        }
        out += &format!("stopped: {:?}\n", self.stop_reason);
        out += &format!(
            "samples: {} received, {} answered, {} controller steps, {} caught up, {} lost{}\n",
            s.received,
            s.published,
            s.controller_steps,
            s.caught_up,
            s.skipped,
            if s.stalls_acknowledged > 0 {
                format!(", {} of injected stalls", s.stalls_acknowledged)
            } else {
                String::new()
            }
        );
        out += &format!(
            "past start-up: {} samples, {} lost ({:.2} %), {} inputs held or safe at the \
             plant ({:.2} %); {} closed-loop inputs off the safe input\n",
            s.samples_past_startup,
            s.lost_past_startup,
            100.0 * verdict::lost_share(s),
            s.held_past_startup,
            100.0 * verdict::held_share(s),
            s.inputs_off_safe
        );
        if let Some(a) = &self.adaptation {
            let total = a.updated + a.suspended.iter().map(|(_, n)| n).sum::<u64>();
            let causes: Vec<String> = a
                .suspended
                .iter()
                .map(|(c, n)| format!("{n} for {c}"))
                .collect();
            let frozen = if a.frozen > 0 {
                format!("; {} more frozen by the operator", a.frozen)
            } else {
                String::new()
            };
            out += &format!(
                "adaptation: {} of {total} closed-loop steps updated; suspended: {}{frozen}\n",
                a.updated,
                causes.join(", ")
            );
        }
        out += &format!(
            "telemetry thread: {:.3} s CPU{}\n",
            self.telemetry_cpu_s,
            self.scheduling
                .loop_s
                .filter(|l| *l > 0.0)
                .map(|l| format!(
                    " ({:.2} % of the loop's {l:.1} s)",
                    100.0 * self.telemetry_cpu_s / l
                ))
                .unwrap_or_default()
        );
        if !self.operator_commands.is_empty() {
            let lines: Vec<String> = self
                .operator_commands
                .iter()
                .map(|c| {
                    let what = match &c.tunable {
                        Some((name, v)) => format!("{} {name} = {v}", c.command),
                        None => c.command.clone(),
                    };
                    match (c.before_seq, &c.message) {
                        (Some(k), _) => format!("{what} applied before seq {k}"),
                        (None, Some(m)) => format!("{what} {}: {m}", c.outcome),
                        (None, None) => format!("{what} {}", c.outcome),
                    }
                })
                .collect();
            out += &format!("operator: {}\n", lines.join("; "));
        }
        out += &format!(
            "deadline: {} misses (service-measured), {} reported by the plant ({} covered by \
             the plan, {} held or safe), longest run {}, safe state entered {}× ({} cycles)\n",
            s.deadline_misses,
            s.plant_reported_misses,
            s.plan_covered_misses,
            s.plant_reported_misses
                .saturating_sub(s.plan_covered_misses),
            s.max_consecutive_misses,
            s.safe_state_entries,
            s.safe_state_cycles
        );
        out += &format!(
            "rejected measurements: {} non-finite, {} out of range, {} contract; refused \
             sequence numbers: {} duplicate, {} backward, {} unexplained jump\n",
            s.rejected_non_finite,
            s.rejected_out_of_range,
            s.rejected_contract,
            s.rejected_duplicate,
            s.rejected_backward,
            s.rejected_jump
        );
        out += &format!(
            "plant silent {}×, resumed {}×; controller faults {}, saturated cycles {}, fallback cycles {}\n",
            s.plant_silent_events,
            s.plant_resumes,
            s.controller_faults,
            s.saturated_cycles,
            s.fallback_cycles
        );
        if !self.controller_counters.is_empty() {
            let list = self
                .controller_counters
                .iter()
                .map(|(name, v)| format!("{name} {v}"))
                .collect::<Vec<_>>()
                .join(", ");
            out += &format!("{}: {list}\n", self.controller);
        }
        let to_fix: Vec<&str> = self
            .system
            .iter()
            .filter(|f| f.verdict == crate::system_check::Verdict::Fix)
            .map(|f| f.check)
            .collect();
        if !to_fix.is_empty() {
            out += &format!(
                "system: {} of {} checks to fix ({}); `service check-system` gives the fixes\n",
                to_fix.len(),
                self.system.len(),
                to_fix.join(", ")
            );
        }
        if let Some(c) = &self.checkpoint {
            if let Some(w) = &c.warm_start {
                out += &format!("warm start: {} (taken at sample {})\n", w.path, w.seq);
            }
            out += &format!(
                "checkpoints: {} written to {}{}{}\n",
                c.written,
                c.path,
                c.last_seq
                    .map(|s| format!(", the last at sample {s}"))
                    .unwrap_or_default(),
                if c.failures > 0 {
                    format!(", {} failed", c.failures)
                } else {
                    String::new()
                }
            );
        }
        let fmt_v = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.4e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out += &format!(
            "RMS of z: [{}] (whole run), [{}] (after settling)\n",
            fmt_v(&self.z_rms),
            fmt_v(&self.z_rms_settled)
        );
        out += &format!(
            "signal log: {} records written, {} dropped (queue full), {} lost to the disk{}\n",
            self.log_written,
            self.log_dropped,
            self.log_lost_to_disk,
            self.log_first_error
                .as_deref()
                .map(|e| format!(" ({e})"))
                .unwrap_or_default()
        );
        if let Some(r) = &self.record {
            out += &format!(
                "record: {} entries written to {}, {} dropped (queue full), {} lost to the disk: {}\n",
                r.written,
                r.path,
                r.dropped,
                r.lost_to_disk,
                if r.complete {
                    "complete"
                } else {
                    "INCOMPLETE (a replay stops at the first gap)"
                }
            );
        }
        let a = &self.rt_allocations;
        if a.installed && !a.counted {
            out += "RT-thread allocations: not counted (the RT thread has no pool)\n";
        } else if a.installed {
            out += &format!(
                "RT-thread allocations: {} from the system allocator, {} served by the RT pool (iceoryx2 sample loans)\n",
                a.system_on_rt_thread, a.pool_served
            );
        }
        if let Some(t) = &self.tones {
            out += &t.render();
        }
        if let Some(f) = &self.model_following {
            out += &f.line();
        }
        if let Some(f) = &self.force_regulation {
            out += &f.lines();
        }
        out += &self.scheduling.lines();
        out += &self.latency.render_table(self.budget_ns);
        out += &self.verdict.headline();
        out.push('\n');
        out
    }
}

impl RunReport {
    /// Writes the report as `report.json` into its run folder, atomically (a temporary file
    /// renamed over it): the file is the whole report or absent. Print the report first
    /// ([`RunReport::render`]), so that a full disk cannot take it from the user.
    pub fn write_json(&self) -> Result<(), ServiceError> {
        let path = Path::new(&self.run_folder).join("report.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| ServiceError::Io {
            what: "serializing the run report".into(),
            error: std::io::Error::other(e),
        })?;
        ipc_types::files::write_atomic(&path, text.as_bytes()).map_err(|e| ServiceError::Io {
            what: "the run report".into(),
            error: e.into(),
        })
    }
}
