//! # Why a real-time run lost samples: the scheduling of the RT thread
//!
//! A loaded box costs a pinned RT thread its samples in three ways, each of which the
//! kernel counts:
//!
//! - another task on the RT core (a `SCHED_OTHER` process the scheduler puts there, a
//!   per-CPU kernel thread) takes turns with it: the RT thread is **preempted**
//!   (involuntary context switches) and **waits on the run queue**;
//! - RT throttling (`sched_rt_runtime_us`) stops a `SCHED_FIFO` busy-poller for the rest of
//!   each period: the same two counters grow;
//! - a virtual machine's host runs something else on the physical CPU: **steal time**.
//!
//! This module reads them over the RT loop of a run, for the run report's `scheduling`
//! section:
//!
//! | figure | read from | where |
//! | --- | --- | --- |
//! | RT thread on-CPU time, run-queue wait, timeslices | `/proc/thread-self/schedstat` | [`thread_sched`] |
//! | voluntary and involuntary context switches | `/proc/thread-self/status` | [`thread_sched`] |
//! | steal time, RT core and all CPUs | `cpuN` lines of `/proc/stat` | [`steal`] |
//! | other tasks on the RT core | `/proc/[pid]/task/[tid]/stat` | [`core_tasks`] |
//!
//! The RT thread reads its own files right before and right after its loop, never inside
//! it; a sampler thread off the RT core scans the tasks ([`watch`]). Every parser is a pure
//! function of a file's text; a file that cannot be read gives `unknown`, never a guess.

pub mod core_tasks;
pub mod steal;
pub mod thread_sched;
pub mod watch;

pub use watch::{RtProbe, RunWatch};

use crate::system_check::Finding;
use serde::Serialize;
use steal::StealOver;
use thread_sched::ThreadSched;

/// A task seen on the RT core during the loop, for the report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoreTaskShare {
    /// Process id.
    pub pid: u32,
    /// Thread id.
    pub tid: u32,
    /// Its name.
    pub comm: String,
    /// A kernel thread.
    pub kernel_thread: bool,
    /// Scans in which it was runnable on the core or had gained CPU time there.
    pub samples: u64,
    /// CPU time it gained while last on the core, s (`USER_HZ` resolution).
    pub cpu_s: f64,
    /// `cpu_s` over the loop's length; `None` when the length is unknown.
    pub share: Option<f64>,
}

/// What the scans of `/proc` saw on the RT core during the loop.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoreTasksReport {
    /// Scans during the loop.
    pub scans: u64,
    /// Time between scans, ms.
    pub scan_every_ms: u64,
    /// CPU time of one scan, mean over all the sampler's scans, ms.
    pub scan_cpu_mean_ms: Option<f64>,
    /// CPU time of the costliest scan, ms.
    pub scan_cpu_max_ms: Option<f64>,
    /// `/proc` could not be listed in some scan.
    pub proc_unreadable: bool,
    /// CPU time all other tasks gained on the RT core, s.
    pub other_cpu_s: f64,
    /// Of which user-space tasks (not kernel threads), s.
    pub other_user_cpu_s: f64,
    /// `other_cpu_s` over the loop's length.
    pub other_share: Option<f64>,
    /// The tasks with the most CPU time there (at most [`watch::TOP_TASKS`]).
    pub top: Vec<CoreTaskShare>,
}

/// The run report's `scheduling` section (see the module docs). Differences over the loop;
/// `None` where a file could not be read, or the loop never ran.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SchedulingReport {
    /// The RT core (`None`: the RT thread was not pinned).
    pub rt_core: Option<usize>,
    /// Wall time between the readings at the loop's start and end, s.
    pub loop_s: Option<f64>,
    /// The RT thread's counters over the loop.
    pub rt_thread: ThreadSched,
    /// Steal time over the loop.
    pub steal: StealOver,
    /// The other tasks on the RT core (`None` without an RT core or without a scan
    /// during the loop).
    pub core_tasks: Option<CoreTasksReport>,
    /// The start-up check of the RT core (the `shared rt core` finding of
    /// [`crate::system_check`], over the service's first 200 ms).
    pub startup_check: Option<Finding>,
}

fn secs(v: Option<f64>) -> String {
    v.map_or("unknown".into(), |s| format!("{s:.3} s"))
}

fn ns_secs(v: Option<u64>) -> String {
    secs(v.map(|n| n as f64 * 1e-9))
}

fn count(v: Option<u64>) -> String {
    v.map_or("unknown".into(), |n| n.to_string())
}

fn pct(v: Option<f64>) -> String {
    v.map_or("?%".into(), |s| format!("{:.1}%", 100.0 * s))
}

impl SchedulingReport {
    /// The report's lines.
    pub fn lines(&self) -> String {
        let core = self
            .rt_core
            .map_or("not pinned".to_string(), |c| format!("core {c}"));
        let mut out = format!(
            "scheduling of the RT thread ({core}, loop {}):\n",
            secs(self.loop_s)
        );
        let t = &self.rt_thread;
        out += &format!(
            "  RT thread: {} on CPU, {} waiting on the run queue, {} involuntary context \
             switches (preempted), {} voluntary, {} timeslices\n",
            ns_secs(t.on_cpu_ns),
            ns_secs(t.run_queue_wait_ns),
            count(t.involuntary_switches),
            count(t.voluntary_switches),
            count(t.timeslices),
        );
        out += &format!(
            "  steal time: {} on the RT core, {} on all CPUs\n",
            secs(self.steal.rt_core_s),
            secs(self.steal.all_cpus_s)
        );
        match &self.core_tasks {
            Some(c) => {
                out += &format!(
                    "  other tasks on the RT core: {:.2} s of CPU ({} of the loop; {:.2} s \
                     user-space), {} tasks listed; {} scans every {} ms, {} CPU each (max {}){}\n",
                    c.other_cpu_s,
                    pct(c.other_share),
                    c.other_user_cpu_s,
                    c.top.len(),
                    c.scans,
                    c.scan_every_ms,
                    c.scan_cpu_mean_ms
                        .map_or("?".into(), |m| format!("{m:.2} ms")),
                    c.scan_cpu_max_ms
                        .map_or("?".into(), |m| format!("{m:.2} ms")),
                    if c.proc_unreadable {
                        "; /proc was unreadable in some scans"
                    } else {
                        ""
                    }
                );
                for t in c.top.iter().take(8) {
                    out += &format!(
                        "    {} (pid {}{}{}): {} of the loop ({:.2} s), seen in {} of {} scans\n",
                        t.comm,
                        t.pid,
                        if t.tid != t.pid {
                            format!(", tid {}", t.tid)
                        } else {
                            String::new()
                        },
                        if t.kernel_thread {
                            ", kernel thread"
                        } else {
                            ""
                        },
                        pct(t.share),
                        t.cpu_s,
                        t.samples,
                        c.scans
                    );
                }
                if c.top.len() > 8 {
                    out += &format!("    … {} more in report.json\n", c.top.len() - 8);
                }
            }
            None => out += "  other tasks on the RT core: not scanned\n",
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_figures_say_unknown_and_tasks_are_listed_with_their_share() {
        let r = SchedulingReport {
            rt_core: Some(1),
            loop_s: Some(3.0),
            rt_thread: ThreadSched {
                on_cpu_ns: Some(2_400_000_000),
                run_queue_wait_ns: None,
                timeslices: Some(10),
                voluntary_switches: Some(2),
                involuntary_switches: Some(1500),
            },
            steal: StealOver {
                rt_core_s: Some(0.01),
                all_cpus_s: None,
            },
            core_tasks: Some(CoreTasksReport {
                scans: 60,
                scan_every_ms: 50,
                scan_cpu_mean_ms: Some(1.5),
                scan_cpu_max_ms: Some(3.0),
                proc_unreadable: false,
                other_cpu_s: 0.6,
                other_user_cpu_s: 0.59,
                other_share: Some(0.2),
                top: vec![CoreTaskShare {
                    pid: 77,
                    tid: 77,
                    comm: "sh".into(),
                    kernel_thread: false,
                    samples: 58,
                    cpu_s: 0.59,
                    share: Some(0.59 / 3.0),
                }],
            }),
            startup_check: None,
        };
        let text = r.lines();
        assert!(text.contains("2.400 s on CPU, unknown waiting"), "{text}");
        assert!(text.contains("1500 involuntary"), "{text}");
        assert!(
            text.contains("0.010 s on the RT core, unknown on all CPUs"),
            "{text}"
        );
        assert!(
            text.contains("sh (pid 77): 19.7% of the loop (0.59 s), seen in 58 of 60 scans"),
            "{text}"
        );
        let none = SchedulingReport {
            rt_core: None,
            loop_s: None,
            rt_thread: ThreadSched::default(),
            steal: StealOver::default(),
            core_tasks: None,
            startup_check: None,
        };
        let text = none.lines();
        assert!(
            text.contains("not pinned") && text.contains("not scanned"),
            "{text}"
        );
        assert!(!text.contains("NaN"), "{text}");
    }
}
