//! The run's watch on the RT core: the readings the RT thread takes at the start and the
//! end of its loop, and the sampler thread that scans the other tasks on its core.
//!
//! [`RunWatch::start`] is called by `runtime::run` after the helper threads were moved off
//! the RT core, so the sampler thread runs on the other cores at normal priority. Every
//! [`SCAN_EVERY`] it scans `/proc` ([`super::core_tasks`]): during its first
//! [`crate::system_check::SHARED_CORE_WINDOW`] for the start-up check (one warning line
//! when the core is shared), and while the RT loop runs for the run's figures. The RT
//! thread calls [`RtProbe::register`] first (so it is never counted as another task), and
//! [`RtProbe::loop_starts`] / [`RtProbe::loop_ends`] around its loop, outside it: each reads
//! its own `schedstat` and `status` and the machine's `/proc/stat`. [`RunWatch::finish`]
//! stops the sampler and gives the [`SchedulingReport`].

use super::core_tasks::{CoreTasks, TaskStat, scan_tasks};
use super::steal::{StealTicks, user_hz};
use super::thread_sched::ThreadSched;
use super::{CoreTaskShare, CoreTasksReport, SchedulingReport};
use crate::system_check::{self, Finding, SystemRoot, Verdict};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Time between two scans of `/proc`.
pub const SCAN_EVERY: Duration = Duration::from_millis(100);

/// Tasks of the RT core reported (those with the most CPU time).
pub const TOP_TASKS: usize = 16;

/// The calling thread's id.
pub fn current_tid() -> u32 {
    // SAFETY: gettid has no preconditions.
    unsafe { libc::gettid() as u32 }
}

/// CPU time of the calling thread, ns.
pub fn thread_cpu_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec to write into.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// One reading at the start or the end of the loop.
#[derive(Debug, Clone)]
struct Mark {
    at: Instant,
    thread: ThreadSched,
    steal: Option<StealTicks>,
}

impl Mark {
    fn now() -> Self {
        Self {
            at: Instant::now(),
            thread: ThreadSched::of_current_thread(),
            steal: StealTicks::read(),
        }
    }
}

#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    rt_tid: AtomicU32,
    looping: AtomicBool,
    marks: Mutex<(Option<Mark>, Option<Mark>)>,
}

/// The RT thread's side of the watch.
#[derive(Debug, Clone)]
pub struct RtProbe(Arc<Shared>);

impl RtProbe {
    /// Names the calling thread as the RT thread (it is never counted as another task).
    pub fn register(&self) {
        self.0.rt_tid.store(current_tid(), Ordering::Release);
    }

    /// The loop is about to start: reads the thread's counters and the steal time.
    pub fn loop_starts(&self) {
        let m = Mark::now();
        if let Ok(mut g) = self.0.marks.lock() {
            g.0 = Some(m);
        }
        self.0.looping.store(true, Ordering::Release);
    }

    /// The loop has ended: reads them again.
    pub fn loop_ends(&self) {
        self.0.looping.store(false, Ordering::Release);
        let m = Mark::now();
        if let Ok(mut g) = self.0.marks.lock() {
            g.1 = Some(m);
        }
    }
}

/// What the sampler thread hands back.
#[derive(Debug, Default)]
struct Sampled {
    run: Option<CoreTasks>,
    startup: Option<Finding>,
    scans: u64,
    scan_cpu_ns_total: u64,
    scan_cpu_ns_max: u64,
    failed: bool,
}

/// The run's watch (see the module docs).
#[derive(Debug)]
pub struct RunWatch {
    core: Option<usize>,
    shared: Arc<Shared>,
    sampler: Option<JoinHandle<Sampled>>,
}

impl RunWatch {
    /// Starts watching RT core `core` (no sampler without one). Call it on a thread that
    /// is off the RT core: the sampler inherits its affinity and priority.
    pub fn start(core: Option<usize>) -> Self {
        let shared = Arc::new(Shared::default());
        let sampler = core.and_then(|core| {
            let s = shared.clone();
            std::thread::Builder::new()
                .name("core-watch".into())
                .spawn(move || sample(&s, core))
                .map_err(|e| eprintln!("[service] the core-watch thread did not start: {e}"))
                .ok()
        });
        Self {
            core,
            shared,
            sampler,
        }
    }

    /// The handle the RT thread takes.
    pub fn probe(&self) -> RtProbe {
        RtProbe(self.shared.clone())
    }

    /// Stops the sampler and reports.
    pub fn finish(mut self) -> SchedulingReport {
        self.shared.stop.store(true, Ordering::Release);
        let sampled = self.sampler.take().and_then(|h| {
            h.thread().unpark();
            h.join().ok()
        });
        let (start, end) = match self.shared.marks.lock() {
            Ok(g) => (g.0.clone(), g.1.clone()),
            Err(_) => (None, None),
        };
        let hz = user_hz();
        let (loop_s, rt_thread, steal) = match (&start, &end) {
            (Some(a), Some(b)) => (
                Some(b.at.duration_since(a.at).as_secs_f64()),
                b.thread.since(&a.thread),
                match (&a.steal, &b.steal) {
                    (Some(x), Some(y)) => y.since(x, self.core, hz),
                    _ => Default::default(),
                },
            ),
            _ => (None, ThreadSched::default(), Default::default()),
        };
        let core_tasks = sampled.as_ref().and_then(|s| {
            let run = s.run.as_ref()?;
            Some(core_tasks_report(s, run, loop_s, hz))
        });
        SchedulingReport {
            rt_core: self.core,
            loop_s,
            rt_thread,
            steal,
            core_tasks,
            startup_check: sampled.and_then(|s| s.startup),
        }
    }
}

fn core_tasks_report(
    s: &Sampled,
    run: &CoreTasks,
    loop_s: Option<f64>,
    hz: u64,
) -> CoreTasksReport {
    let secs = |ticks: u64| ticks as f64 / hz.max(1) as f64;
    let share = |ticks: u64| loop_s.filter(|l| *l > 0.0).map(|l| secs(ticks) / l);
    let (all, user) = run.total_ticks();
    CoreTasksReport {
        scans: run.scans(),
        scan_every_ms: SCAN_EVERY.as_millis() as u64,
        scan_cpu_mean_ms: (s.scans > 0).then(|| s.scan_cpu_ns_total as f64 * 1e-6 / s.scans as f64),
        scan_cpu_max_ms: (s.scans > 0).then_some(s.scan_cpu_ns_max as f64 * 1e-6),
        proc_unreadable: s.failed,
        other_cpu_s: secs(all),
        other_user_cpu_s: secs(user),
        other_share: share(all),
        top: run
            .top()
            .into_iter()
            .map(|t| CoreTaskShare {
                pid: t.pid,
                tid: t.tid,
                comm: t.comm,
                kernel_thread: t.kernel_thread,
                samples: t.samples,
                cpu_s: secs(t.ticks),
                share: share(t.ticks),
            })
            .collect(),
    }
}

/// The sampler thread.
fn sample(shared: &Shared, core: usize) -> Sampled {
    let me = current_tid();
    let proc_dir = Path::new("/proc");
    let mut startup = CoreTasks::new(core, TOP_TASKS);
    let mut run: Option<CoreTasks> = None;
    let mut out = Sampled::default();
    let mut tasks: Vec<TaskStat> = Vec::new();
    let began = Instant::now();
    let mut startup_open = true;
    while !shared.stop.load(Ordering::Acquire) {
        let c0 = thread_cpu_ns();
        let ok = scan_tasks(proc_dir, &mut tasks);
        let cost = thread_cpu_ns().saturating_sub(c0);
        // After the scan: an RT thread that registered during it is excluded.
        let rt = shared.rt_tid.load(Ordering::Acquire);
        out.scans += 1;
        out.scan_cpu_ns_total += cost;
        out.scan_cpu_ns_max = out.scan_cpu_ns_max.max(cost);
        out.failed |= !ok;
        for c in std::iter::once(&mut startup).chain(run.as_mut()) {
            c.exclude(me);
            if rt != 0 {
                c.exclude(rt);
            }
        }
        if startup_open {
            startup.observe(&tasks);
            if began.elapsed() >= system_check::SHARED_CORE_WINDOW {
                startup_open = false;
                let sys = SystemRoot::live();
                let f = if ok {
                    system_check::shared_core_finding(
                        core,
                        system_check::core_isolated(&sys, core),
                        &startup,
                        began.elapsed(),
                        std::process::id(),
                    )
                } else {
                    system_check::shared_core_unreadable()
                };
                if f.verdict == Verdict::Fix {
                    eprintln!(
                        "[service] WARNING: {} ({})",
                        f.found,
                        f.fix.as_deref().unwrap_or("")
                    );
                }
                out.startup = Some(f);
            }
        }
        if shared.looping.load(Ordering::Acquire) {
            let r = run.get_or_insert_with(|| {
                let mut c = CoreTasks::new(core, TOP_TASKS);
                c.exclude(me);
                if rt != 0 {
                    c.exclude(rt);
                }
                c
            });
            r.observe(&tasks);
        }
        std::thread::park_timeout(SCAN_EVERY);
    }
    out.run = run;
    out
}
