//! What the scheduler did to one thread: `/proc/thread-self/schedstat` and the context
//! switches of `/proc/thread-self/status`.
//!
//! `schedstat` holds three numbers: the time the thread ran on a CPU (ns), the time it
//! waited on a run queue while runnable (ns), and the number of timeslices it ran. The
//! `status` file counts `voluntary_ctxt_switches` (the thread blocked or yielded) and
//! `nonvoluntary_ctxt_switches` (it was preempted while it wanted to run). The parsers are
//! pure functions of the files' text; a file that is absent or does not parse gives `None`
//! for its figures, never a guess.

use serde::Serialize;

/// One reading of a thread's scheduling counters; `None`: the file could not be read or
/// parsed (a kernel without `CONFIG_SCHED_INFO` has no `schedstat`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ThreadSched {
    /// Time on a CPU, ns.
    pub on_cpu_ns: Option<u64>,
    /// Time runnable but waiting on a run queue, ns.
    pub run_queue_wait_ns: Option<u64>,
    /// Timeslices run.
    pub timeslices: Option<u64>,
    /// Voluntary context switches (blocked, slept or yielded).
    pub voluntary_switches: Option<u64>,
    /// Involuntary context switches (preempted while runnable).
    pub involuntary_switches: Option<u64>,
}

/// The three numbers of a `schedstat` file: on-CPU ns, run-queue wait ns, timeslices.
pub fn parse_schedstat(text: &str) -> Option<(u64, u64, u64)> {
    let mut it = text.split_whitespace().map(|v| v.parse::<u64>().ok());
    let on_cpu = it.next()??;
    let wait = it.next()??;
    let slices = it.next()??;
    Some((on_cpu, wait, slices))
}

/// `voluntary_ctxt_switches` and `nonvoluntary_ctxt_switches` of a `status` file.
pub fn parse_context_switches(status: &str) -> (Option<u64>, Option<u64>) {
    let field = |key: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))
            .and_then(|v| v.trim().parse().ok())
    };
    (
        field("voluntary_ctxt_switches"),
        field("nonvoluntary_ctxt_switches"),
    )
}

impl ThreadSched {
    /// The reading given the text of `schedstat` and `status` (`None`: unreadable).
    pub fn parse(schedstat: Option<&str>, status: Option<&str>) -> Self {
        let s = schedstat.and_then(parse_schedstat);
        let (voluntary, involuntary) = status.map_or((None, None), parse_context_switches);
        Self {
            on_cpu_ns: s.map(|s| s.0),
            run_queue_wait_ns: s.map(|s| s.1),
            timeslices: s.map(|s| s.2),
            voluntary_switches: voluntary,
            involuntary_switches: involuntary,
        }
    }

    /// The calling thread's counters now (reads two files: not for the RT loop itself).
    pub fn of_current_thread() -> Self {
        let read = |p: &str| std::fs::read_to_string(p).ok();
        Self::parse(
            read("/proc/thread-self/schedstat").as_deref(),
            read("/proc/thread-self/status").as_deref(),
        )
    }

    /// What accumulated from `earlier` to `self`: each figure is `None` when either
    /// reading lacks it or it went backwards.
    pub fn since(&self, earlier: &ThreadSched) -> ThreadSched {
        let d = |a: Option<u64>, b: Option<u64>| a?.checked_sub(b?);
        ThreadSched {
            on_cpu_ns: d(self.on_cpu_ns, earlier.on_cpu_ns),
            run_queue_wait_ns: d(self.run_queue_wait_ns, earlier.run_queue_wait_ns),
            timeslices: d(self.timeslices, earlier.timeslices),
            voluntary_switches: d(self.voluntary_switches, earlier.voluntary_switches),
            involuntary_switches: d(self.involuntary_switches, earlier.involuntary_switches),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const STATUS: &str = "Name:\trt-loop\nState:\tR (running)\nTgid:\t4242\n\
        voluntary_ctxt_switches:\t12\nnonvoluntary_ctxt_switches:\t3456\n";

    #[test]
    fn schedstat_and_status_parse_as_the_kernel_writes_them() {
        assert_eq!(
            parse_schedstat("2410000000 583000000 1234\n"),
            Some((2_410_000_000, 583_000_000, 1234))
        );
        assert_eq!(parse_schedstat("12 x 3"), None);
        assert_eq!(parse_schedstat("12 34"), None);
        assert_eq!(parse_context_switches(STATUS), (Some(12), Some(3456)));
        assert_eq!(parse_context_switches("Name:\tx\n"), (None, None));
    }

    #[test]
    fn an_unreadable_file_gives_unknown_figures_and_differences_stay_unknown() {
        let start = ThreadSched::parse(Some("100 10 1"), None);
        let end = ThreadSched::parse(Some("900 60 9"), Some(STATUS));
        assert_eq!(start.voluntary_switches, None);
        let d = end.since(&start);
        assert_eq!(
            d,
            ThreadSched {
                on_cpu_ns: Some(800),
                run_queue_wait_ns: Some(50),
                timeslices: Some(8),
                voluntary_switches: None,
                involuntary_switches: None,
            }
        );
        // A counter that went backwards is not a figure.
        assert_eq!(start.since(&end).on_cpu_ns, None);
        assert_eq!(ThreadSched::parse(None, None), ThreadSched::default());
    }

    #[test]
    fn this_thread_can_be_read() {
        let a = ThreadSched::of_current_thread();
        // Present on any Linux with /proc; the figures only grow.
        if a.on_cpu_ns.is_some() {
            let b = ThreadSched::of_current_thread();
            assert!(b.since(&a).on_cpu_ns.is_some());
        }
    }
}
