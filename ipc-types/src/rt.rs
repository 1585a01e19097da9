//! Real-time thread set-up shared by both sides of the contract: pin to a core, request
//! `SCHED_FIFO`, lock memory (`mlockall`), prefault the stack, and hold the CPUs' wake-up
//! latency down ([`crate::cpu_latency`]).
//!
//! On a stock kernel without `CAP_SYS_NICE` or with RT throttling the OS may refuse some of
//! these. Each step's outcome is recorded in an [`RtSetup`] so that the process can warn
//! loudly at start-up, put it in its run report, or refuse to run when configured so.

use core::fmt;

/// What the real-time set-up asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RtRequest {
    /// Core to pin the thread to, or `None` to leave the affinity alone.
    pub core: Option<usize>,
    /// `SCHED_FIFO` priority 1–99, or `None` to stay `SCHED_OTHER`.
    pub fifo_priority: Option<i32>,
    /// Lock all current and future pages in RAM.
    pub mlockall: bool,
    /// Bytes of stack to touch so that the pages are mapped before the loop starts.
    pub prefault_stack_bytes: usize,
    /// The CPU wake-up latency to hold for the life of the process, µs
    /// ([`crate::cpu_latency::hold`]), or `None` to leave it to the kernel.
    pub cpu_latency_us: Option<u32>,
}

/// The outcome of one set-up step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StepOutcome {
    /// Not requested.
    Skipped,
    /// Done.
    Done,
    /// The OS refused; the message says why.
    Refused(String),
}

impl StepOutcome {
    /// True when the step was requested and refused.
    pub fn refused(&self) -> bool {
        matches!(self, StepOutcome::Refused(_))
    }
}

impl fmt::Display for StepOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StepOutcome::Skipped => write!(f, "not requested"),
            StepOutcome::Done => write!(f, "ok"),
            StepOutcome::Refused(why) => write!(f, "REFUSED: {why}"),
        }
    }
}

/// Reads a configured `SCHED_FIFO` priority: absent → `default`, 0 → none (stay
/// `SCHED_OTHER`), 1–99 → that priority; anything else is refused with the reason.
pub fn fifo_priority_from_config(value: Option<i32>, default: i32) -> Result<Option<i32>, String> {
    match value {
        None => Ok(Some(default)),
        Some(0) => Ok(None),
        Some(p) if (1..=99).contains(&p) => Ok(Some(p)),
        Some(p) => Err(format!("{p} is not in 1..=99 (0 disables)")),
    }
}

/// What the set-up achieved, step by step.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtSetup {
    /// Pinning to the requested core.
    pub affinity: StepOutcome,
    /// `SCHED_FIFO` at the requested priority.
    pub fifo: StepOutcome,
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)`.
    pub mlockall: StepOutcome,
    /// The CPU wake-up latency request.
    pub cpu_latency: StepOutcome,
}

impl RtSetup {
    /// True when any requested step was refused.
    pub fn any_refused(&self) -> bool {
        self.affinity.refused()
            || self.fifo.refused()
            || self.mlockall.refused()
            || self.cpu_latency.refused()
    }

    /// One line per step, for the start-up banner and the run report.
    pub fn describe(&self) -> String {
        let latency = match crate::cpu_latency::held() {
            Some(us) if self.cpu_latency == StepOutcome::Done => format!(" ≤ {us} µs"),
            _ => String::new(),
        };
        format!(
            "core affinity: {}; SCHED_FIFO: {}; mlockall: {}; cpu wake-up latency{latency}: {}",
            self.affinity, self.fifo, self.mlockall, self.cpu_latency
        )
    }
}

/// Applies `req` to the calling thread (and, for `mlockall`, to the whole process).
pub fn setup_current_thread(req: &RtRequest) -> RtSetup {
    let affinity = match req.core {
        None => StepOutcome::Skipped,
        Some(core) => pin_current_thread(core),
    };
    let fifo = match req.fifo_priority {
        None => StepOutcome::Skipped,
        Some(prio) => set_fifo(prio),
    };
    let mlockall = if req.mlockall {
        lock_memory()
    } else {
        StepOutcome::Skipped
    };
    let cpu_latency = match req.cpu_latency_us {
        None => StepOutcome::Skipped,
        Some(us) => crate::cpu_latency::hold(us),
    };
    if req.prefault_stack_bytes > 0 {
        prefault_stack(req.prefault_stack_bytes);
    }
    RtSetup {
        affinity,
        fifo,
        mlockall,
        cpu_latency,
    }
}

/// Pins the calling thread to `core`. The core must be online; the calling thread's
/// current affinity mask does not matter (a thread spawned by a process that kept itself
/// off the RT core can still pin itself onto it).
pub fn pin_current_thread(core: usize) -> StepOutcome {
    // SAFETY: sysconf has no preconditions.
    let online = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize;
    if core >= online {
        return StepOutcome::Refused(format!(
            "core {core} does not exist on this machine ({online} cores online)"
        ));
    }
    if core_affinity::set_for_current(core_affinity::CoreId { id: core }) {
        StepOutcome::Done
    } else {
        StepOutcome::Refused(format!(
            "sched_setaffinity to core {core} failed: {}",
            std::io::Error::last_os_error()
        ))
    }
}

/// Restricts the calling thread to every core except `rt_core`, and to `SCHED_OTHER`, so
/// that helper threads never compete with the real-time thread.
pub fn keep_off_core(rt_core: Option<usize>) {
    // SAFETY: cpu_set_t is plain data; the calls only read it and act on the calling thread.
    unsafe {
        let mut set: libc::cpu_set_t = core::mem::zeroed();
        let n = libc::sysconf(libc::_SC_NPROCESSORS_ONLN).max(1) as usize;
        let mut any = false;
        for c in 0..n {
            if Some(c) != rt_core {
                libc::CPU_SET(c, &mut set);
                any = true;
            }
        }
        if any {
            libc::sched_setaffinity(0, core::mem::size_of::<libc::cpu_set_t>(), &set);
        }
        let param = libc::sched_param { sched_priority: 0 };
        libc::sched_setscheduler(0, libc::SCHED_OTHER, &param);
    }
}

/// Returns the calling thread to `SCHED_OTHER` (its affinity unchanged): a loop whose
/// plant runs in lockstep has no deadline, and a `SCHED_FIFO` thread ping-ponging with it
/// would starve every normal task on its core. Returns whether the kernel accepted it.
pub fn leave_fifo() -> bool {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: `param` is valid; pid 0 is the calling thread.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) == 0 }
}

fn set_fifo(prio: i32) -> StepOutcome {
    let param = libc::sched_param {
        sched_priority: prio,
    };
    // SAFETY: `param` is valid; pid 0 is the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        StepOutcome::Done
    } else {
        StepOutcome::Refused(format!(
            "sched_setscheduler(SCHED_FIFO, {prio}): {} (needs root or CAP_SYS_NICE and an RT \
             runtime budget)",
            std::io::Error::last_os_error()
        ))
    }
}

fn lock_memory() -> StepOutcome {
    // SAFETY: mlockall takes flags only.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        StepOutcome::Done
    } else {
        StepOutcome::Refused(format!(
            "mlockall: {} (raise RLIMIT_MEMLOCK or run with CAP_IPC_LOCK)",
            std::io::Error::last_os_error()
        ))
    }
}

/// The kernel's real-time throttling budget: `Some((runtime_us, period_us))` when it is
/// active (`/proc/sys/kernel/sched_rt_runtime_us` is not -1), `None` when it is off or
/// unreadable. With throttling on, `SCHED_FIFO` threads together may run at most
/// `runtime_us` of every `period_us`; a thread that busy-polls at `SCHED_FIFO` uses all of
/// it and is then stalled for the rest of the period (50 ms every second by default).
pub fn rt_throttling() -> Option<(i64, i64)> {
    let read = |f: &str| -> Option<i64> {
        std::fs::read_to_string(format!("/proc/sys/kernel/{f}"))
            .ok()?
            .trim()
            .parse()
            .ok()
    };
    let runtime = read("sched_rt_runtime_us")?;
    let period = read("sched_rt_period_us")?;
    (runtime >= 0 && runtime < period).then_some((runtime, period))
}

/// A warning for a thread that will spin at `SCHED_FIFO` while throttling is active.
pub fn busy_poll_throttling_warning() -> Option<String> {
    rt_throttling().map(|(runtime, period)| {
        format!(
            "RT throttling is on (sched_rt_runtime_us = {runtime} of {period}): a SCHED_FIFO thread \
             that busy-polls is stalled for {} ms every {} ms. Use wait = \"sleep-poll\" (the \
             default: it sleeps until shortly before each sample) or \"block\", or disable \
             throttling on a box with an isolated RT core (echo -1 > \
             /proc/sys/kernel/sched_rt_runtime_us)",
            (period - runtime) / 1000,
            period / 1000
        )
    })
}

#[inline(never)]
fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 16 * 1024;
    fn touch(remaining: usize) {
        let mut buf = [0u8; CHUNK];
        // Volatile writes so the pages are really touched.
        for i in (0..CHUNK).step_by(4096) {
            // SAFETY: `i` is within `buf`.
            unsafe { core::ptr::write_volatile(buf.as_mut_ptr().add(i), 1) };
        }
        core::hint::black_box(&buf);
        if remaining > CHUNK {
            touch(remaining - CHUNK);
        }
    }
    touch(bytes);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_skipped_request_changes_nothing_and_reports_skipped() {
        let s = setup_current_thread(&RtRequest {
            core: None,
            fifo_priority: None,
            mlockall: false,
            prefault_stack_bytes: 64 * 1024,
            cpu_latency_us: None,
        });
        assert_eq!(s.affinity, StepOutcome::Skipped);
        assert!(!s.any_refused());
    }

    #[test]
    fn pinning_to_a_core_that_does_not_exist_is_refused_with_a_reason() {
        let s = pin_current_thread(100_000);
        assert!(s.refused());
        assert!(s.to_string().contains("does not exist"));
    }
}
