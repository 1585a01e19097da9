//! # What the box does to a real-time loop: the system check
//!
//! [`check_system`] reads what the kernel exposes under `/proc` and `/sys` and says, for
//! each thing that moves the wake-up latency of a pinned `SCHED_FIFO` thread, what it
//! found and how to fix it:
//!
//! | check | good | read from |
//! | --- | --- | --- |
//! | `preemption` | a `PREEMPT_RT` kernel | `/sys/kernel/realtime`, `uname -v` |
//! | `isolated core` | the RT core in `isolcpus` (or `/sys/devices/system/cpu/isolated`), `nohz_full` and `rcu_nocbs` | `/proc/cmdline`, `/sys/devices/system/cpu/{isolated,nohz_full}` |
//! | `rt throttling` | off (`sched_rt_runtime_us = -1`) on an isolated core | `/proc/sys/kernel/sched_rt_*` |
//! | `cpu governor` | `performance` on the RT core | `/sys/devices/system/cpu/cpuN/cpufreq/scaling_governor` |
//! | `smt sibling` | the RT core has no hyper-thread sibling, or it is isolated too | `…/cpuN/topology/thread_siblings_list` |
//! | `irq affinity` | no interrupt may run on the RT core | `/proc/irq/*/smp_affinity_list` |
//! | `swap` | none, or `mlockall` (the service locks its memory) | `/proc/swaps` |
//! | `transparent huge pages` | `madvise` or `never` (no compaction stalls) | `/sys/kernel/mm/transparent_hugepage/enabled` |
//! | `privileges` | `CAP_SYS_NICE` and `CAP_IPC_LOCK`, or the rlimits `RTPRIO` and `MEMLOCK` | `/proc/self/status`, `getrlimit` |
//! | `shared rt core` | no user-space task ran on the RT core during a [`SHARED_CORE_WINDOW`] sample (per-CPU kernel threads are named, not faulted) | `/proc/[pid]/task/[tid]/stat` ([`crate::scheduling::core_tasks`]) |
//!
//! A check that cannot read its file says "unknown" (a virtual machine has no cpufreq, a
//! container may hide `/proc/irq`) rather than guessing. The paths are read under a root
//! folder ([`SystemRoot`]), so that the tests can give a made-up machine.
//!
//! `shared rt core` is the one check that watches rather than reads: it scans the tasks
//! every [`crate::scheduling::watch::SCAN_EVERY`] for [`SystemRoot::sample_window`]
//! ([`SHARED_CORE_WINDOW`] on the box) and names those that were runnable on the RT core or
//! gained CPU time there. The service runs the same check over its first 200 ms and prints
//! one warning line when the core is shared.

use crate::scheduling::core_tasks::{CoreTasks, scan_tasks};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How long the `shared rt core` check watches the RT core.
pub const SHARED_CORE_WINDOW: Duration = Duration::from_millis(200);

/// What a check concluded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// As a real-time box should be.
    Good,
    /// Costs latency; the finding says how to fix it.
    Fix,
    /// The file could not be read.
    Unknown,
}

/// One check's result.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Finding {
    /// The check (first column of the module table).
    pub check: &'static str,
    /// What it concluded.
    pub verdict: Verdict,
    /// What was found, for a person.
    pub found: String,
    /// How to fix it, when [`Verdict::Fix`].
    pub fix: Option<String>,
}

impl Finding {
    fn good(check: &'static str, found: String) -> Self {
        Self {
            check,
            verdict: Verdict::Good,
            found,
            fix: None,
        }
    }
    fn fix(check: &'static str, found: String, fix: String) -> Self {
        Self {
            check,
            verdict: Verdict::Fix,
            found,
            fix: Some(fix),
        }
    }
    fn unknown(check: &'static str, found: String) -> Self {
        Self {
            check,
            verdict: Verdict::Unknown,
            found,
            fix: None,
        }
    }

    /// One line: `check: found` and, when there is one, `— fix: …`.
    pub fn render(&self) -> String {
        let mark = match self.verdict {
            Verdict::Good => "ok  ",
            Verdict::Fix => "FIX ",
            Verdict::Unknown => "??  ",
        };
        match &self.fix {
            Some(f) => format!("{mark}{}: {} — fix: {f}", self.check, self.found),
            None => format!("{mark}{}: {}", self.check, self.found),
        }
    }
}

/// Where the kernel's files are read: `/` on the box, a made-up tree in the tests.
#[derive(Debug, Clone)]
pub struct SystemRoot {
    root: PathBuf,
    /// `uname -v` (the kernel's version string, which names `PREEMPT_RT`).
    pub kernel_version: String,
    /// The process's effective capabilities (`CapEff` of `/proc/self/status`), read at
    /// [`SystemRoot::live`].
    pub cap_eff: Option<u64>,
    /// `RLIMIT_RTPRIO` and `RLIMIT_MEMLOCK` (soft limits; `u64::MAX` is unlimited).
    pub rlimits: Option<(u64, u64)>,
    /// How long the `shared rt core` check watches ([`SHARED_CORE_WINDOW`] on the box;
    /// zero for a made-up machine: one scan).
    pub sample_window: Duration,
}

impl SystemRoot {
    /// This machine and this process.
    pub fn live() -> Self {
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        let cap_eff = status
            .lines()
            .find_map(|l| l.strip_prefix("CapEff:"))
            .and_then(|v| u64::from_str_radix(v.trim(), 16).ok());
        let limit = |r| {
            let mut l = libc::rlimit {
                rlim_cur: 0,
                rlim_max: 0,
            };
            // SAFETY: getrlimit writes into a valid rlimit.
            (unsafe { libc::getrlimit(r, &mut l) } == 0).then_some(l.rlim_cur)
        };
        let rlimits = limit(libc::RLIMIT_RTPRIO).zip(limit(libc::RLIMIT_MEMLOCK));
        Self {
            root: PathBuf::from("/"),
            kernel_version: kernel_version(),
            cap_eff,
            rlimits,
            sample_window: SHARED_CORE_WINDOW,
        }
    }

    /// A made-up machine under `root` (for tests).
    pub fn at(root: &Path, kernel_version: &str) -> Self {
        Self {
            root: root.to_path_buf(),
            kernel_version: kernel_version.into(),
            cap_eff: None,
            rlimits: None,
            sample_window: Duration::ZERO,
        }
    }

    fn read(&self, path: &str) -> Option<String> {
        std::fs::read_to_string(self.root.join(path.trim_start_matches('/')))
            .ok()
            .map(|s| s.trim().to_string())
    }

    fn list(&self, path: &str) -> Vec<String> {
        std::fs::read_dir(self.root.join(path.trim_start_matches('/')))
            .map(|d| {
                d.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default()
    }
}

/// `uname -v`.
fn kernel_version() -> String {
    // SAFETY: utsname is plain data and uname only writes into it.
    let mut u: libc::utsname = unsafe { core::mem::zeroed() };
    // SAFETY: `u` is a valid, writable utsname.
    if unsafe { libc::uname(&mut u) } != 0 {
        return String::new();
    }
    let bytes: Vec<u8> = u
        .version
        .iter()
        .take_while(|c| **c != 0)
        .map(|c| *c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

/// The CPUs of a kernel CPU list (`0-3,8,10-11`); `None` when it does not parse.
pub fn parse_cpu_list(list: &str) -> Option<Vec<usize>> {
    let mut cpus = Vec::new();
    for part in list.trim().split(',').filter(|p| !p.is_empty()) {
        // A flag prefix of isolcpus (`domain,managed_irq,2-3`) is not a CPU.
        if part.chars().all(|c| c.is_ascii_alphabetic() || c == '_') {
            continue;
        }
        match part.split_once('-') {
            Some((a, b)) => {
                let (a, b): (usize, usize) = (a.parse().ok()?, b.parse().ok()?);
                if b < a || b - a > 4096 {
                    return None;
                }
                cpus.extend(a..=b);
            }
            None => cpus.push(part.parse().ok()?),
        }
    }
    Some(cpus)
}

/// The value of boot parameter `key=` in a kernel command line.
fn boot_param<'a>(cmdline: &'a str, key: &str) -> Option<&'a str> {
    cmdline
        .split_whitespace()
        .find_map(|p| p.strip_prefix(key)?.strip_prefix('='))
}

/// Runs every check of the module table for the RT core `core` (`None`: the service is not
/// pinned, which is itself a finding).
pub fn check_system(sys: &SystemRoot, core: Option<usize>) -> Vec<Finding> {
    vec![
        preemption(sys),
        isolation(sys, core),
        throttling(sys),
        governor(sys, core),
        smt(sys, core),
        irqs(sys, core),
        swap(sys),
        huge_pages(sys),
        privileges(sys),
        shared_core(sys, core),
    ]
}

fn preemption(sys: &SystemRoot) -> Finding {
    const C: &str = "preemption";
    if sys.read("sys/kernel/realtime").as_deref() == Some("1")
        || sys.kernel_version.contains("PREEMPT_RT")
    {
        return Finding::good(C, "PREEMPT_RT kernel".into());
    }
    let model = if sys.kernel_version.contains("PREEMPT_DYNAMIC") {
        "PREEMPT_DYNAMIC"
    } else if sys.kernel_version.contains("PREEMPT") {
        "PREEMPT"
    } else {
        "no PREEMPT"
    };
    Finding::fix(
        C,
        format!("{model} kernel, not PREEMPT_RT: wake-ups can wait for kernel sections"),
        "boot a PREEMPT_RT kernel (Debian: apt-get install linux-image-rt-amd64)".into(),
    )
}

/// Whether `core` is isolated (`isolcpus` or `/sys/devices/system/cpu/isolated`); `None`
/// when neither can be read.
pub fn core_isolated(sys: &SystemRoot, core: usize) -> Option<bool> {
    let cmdline = sys.read("proc/cmdline");
    let sysfs = sys.read("sys/devices/system/cpu/isolated");
    if cmdline.is_none() && sysfs.is_none() {
        return None;
    }
    let has = |list: Option<&str>| {
        list.and_then(parse_cpu_list)
            .is_some_and(|c| c.contains(&core))
    };
    Some(has(cmdline.as_deref().and_then(|c| boot_param(c, "isolcpus"))) || has(sysfs.as_deref()))
}

fn isolation(sys: &SystemRoot, core: Option<usize>) -> Finding {
    const C: &str = "isolated core";
    let Some(core) = core else {
        return Finding::fix(
            C,
            "the RT thread is not pinned (service.core unset)".into(),
            "set service.core to a core of its own".into(),
        );
    };
    let Some(cmdline) = sys.read("proc/cmdline") else {
        return Finding::unknown(C, "/proc/cmdline unreadable".into());
    };
    let has = |list: Option<String>| {
        list.and_then(|l| parse_cpu_list(&l))
            .is_some_and(|c| c.contains(&core))
    };
    let isolated = has(boot_param(&cmdline, "isolcpus").map(str::to_string))
        || has(sys.read("sys/devices/system/cpu/isolated"));
    let nohz = has(boot_param(&cmdline, "nohz_full").map(str::to_string))
        || has(sys.read("sys/devices/system/cpu/nohz_full"));
    let rcu = has(boot_param(&cmdline, "rcu_nocbs").map(str::to_string));
    let missing: Vec<&str> = [
        ("isolcpus", isolated),
        ("nohz_full", nohz),
        ("rcu_nocbs", rcu),
    ]
    .iter()
    .filter(|(_, ok)| !ok)
    .map(|(n, _)| *n)
    .collect();
    if missing.is_empty() {
        Finding::good(
            C,
            format!("core {core} is in isolcpus, nohz_full and rcu_nocbs"),
        )
    } else {
        Finding::fix(
            C,
            format!("core {core} is not in {}", missing.join(", ")),
            format!(
                "add {} to the kernel command line",
                missing
                    .iter()
                    .map(|p| format!("{p}={core}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            ),
        )
    }
}

fn throttling(sys: &SystemRoot) -> Finding {
    const C: &str = "rt throttling";
    let runtime = sys.read("proc/sys/kernel/sched_rt_runtime_us");
    let period = sys.read("proc/sys/kernel/sched_rt_period_us");
    match (runtime.as_deref(), period) {
        (Some("-1"), _) => Finding::good(C, "off (sched_rt_runtime_us = -1)".into()),
        (Some(r), Some(p)) => Finding::fix(
            C,
            format!(
                "on: SCHED_FIFO threads may run {r} of every {p} µs; a busy-polling RT thread is \
                 stalled for the rest"
            ),
            "on a box with an isolated RT core: sysctl -w kernel.sched_rt_runtime_us=-1; \
             otherwise service.wait = \"sleep-poll\" (the default) or \"block\", never a \
             SCHED_FIFO busy-poll"
                .into(),
        ),
        _ => Finding::unknown(C, "/proc/sys/kernel/sched_rt_* unreadable".into()),
    }
}

fn governor(sys: &SystemRoot, core: Option<usize>) -> Finding {
    const C: &str = "cpu governor";
    let core = core.unwrap_or(0);
    match sys.read(&format!(
        "sys/devices/system/cpu/cpu{core}/cpufreq/scaling_governor"
    )) {
        Some(g) if g == "performance" => Finding::good(C, format!("core {core}: performance")),
        Some(g) => Finding::fix(
            C,
            format!("core {core}: {g} (the clock ramps up after each wake-up)"),
            format!("cpupower -c {core} frequency-set -g performance"),
        ),
        None => Finding::unknown(
            C,
            format!("core {core}: no cpufreq (a virtual machine, or fixed by the firmware)"),
        ),
    }
}

fn smt(sys: &SystemRoot, core: Option<usize>) -> Finding {
    const C: &str = "smt sibling";
    let Some(core) = core else {
        return Finding::unknown(C, "the RT thread is not pinned".into());
    };
    let Some(siblings) = sys
        .read(&format!(
            "sys/devices/system/cpu/cpu{core}/topology/thread_siblings_list"
        ))
        .and_then(|l| parse_cpu_list(&l))
    else {
        return Finding::unknown(C, format!("core {core}: no topology"));
    };
    let others: Vec<usize> = siblings.into_iter().filter(|c| *c != core).collect();
    if others.is_empty() {
        return Finding::good(C, format!("core {core} has no hyper-thread sibling"));
    }
    let isolated = sys
        .read("sys/devices/system/cpu/isolated")
        .and_then(|l| parse_cpu_list(&l))
        .unwrap_or_default();
    if others.iter().all(|c| isolated.contains(c)) {
        Finding::good(
            C,
            format!("core {core}: its siblings {others:?} are isolated too"),
        )
    } else {
        Finding::fix(
            C,
            format!("core {core} shares its execution units with {others:?}"),
            format!(
                "isolate the siblings {others:?} as well, or turn SMT off \
                 (echo off > /sys/devices/system/cpu/smt/control, or nosmt on the command line)"
            ),
        )
    }
}

fn irqs(sys: &SystemRoot, core: Option<usize>) -> Finding {
    const C: &str = "irq affinity";
    let Some(core) = core else {
        return Finding::unknown(C, "the RT thread is not pinned".into());
    };
    let irqs = sys.list("proc/irq");
    if irqs.is_empty() {
        return Finding::unknown(C, "/proc/irq unreadable".into());
    }
    let mut on_core: Vec<u32> = irqs
        .iter()
        .filter_map(|i| i.parse::<u32>().ok())
        .filter(|i| {
            sys.read(&format!("proc/irq/{i}/smp_affinity_list"))
                .and_then(|l| parse_cpu_list(&l))
                .is_some_and(|c| c.contains(&core))
        })
        .collect();
    on_core.sort_unstable();
    if on_core.is_empty() {
        Finding::good(C, format!("no interrupt may run on core {core}"))
    } else {
        let shown: Vec<String> = on_core.iter().take(8).map(u32::to_string).collect();
        Finding::fix(
            C,
            format!(
                "{} interrupts may run on core {core} (IRQ {}{})",
                on_core.len(),
                shown.join(", "),
                if on_core.len() > 8 { ", …" } else { "" }
            ),
            format!(
                "boot with irqaffinity= set to the other cores, or write them to \
                 /proc/irq/N/smp_affinity_list (keep only the DAQ card's on core {core} if it \
                 must be)"
            ),
        )
    }
}

fn swap(sys: &SystemRoot) -> Finding {
    const C: &str = "swap";
    match sys.read("proc/swaps") {
        Some(t) => {
            let n = t.lines().skip(1).filter(|l| !l.trim().is_empty()).count();
            if n == 0 {
                Finding::good(C, "no swap".into())
            } else {
                Finding::fix(
                    C,
                    format!("{n} swap area(s): pages of unlocked processes can be swapped out"),
                    "keep service.mlockall = true (the default) for the service and the DAQ \
                     process, or swapoff -a"
                        .into(),
                )
            }
        }
        None => Finding::unknown(C, "/proc/swaps unreadable".into()),
    }
}

fn huge_pages(sys: &SystemRoot) -> Finding {
    const C: &str = "transparent huge pages";
    match sys.read("sys/kernel/mm/transparent_hugepage/enabled") {
        Some(t) if t.contains("[always]") => Finding::fix(
            C,
            "always: page faults can stall on compaction".into(),
            "echo madvise > /sys/kernel/mm/transparent_hugepage/enabled (or \
             transparent_hugepage=madvise on the command line)"
                .into(),
        ),
        Some(t) => Finding::good(C, t),
        None => Finding::unknown(C, "not readable".into()),
    }
}

fn privileges(sys: &SystemRoot) -> Finding {
    const C: &str = "privileges";
    const CAP_IPC_LOCK: u64 = 1 << 14;
    const CAP_SYS_NICE: u64 = 1 << 23;
    let caps = sys.cap_eff.unwrap_or(0);
    let (rtprio, memlock) = sys.rlimits.unwrap_or((0, 0));
    let nice = caps & CAP_SYS_NICE != 0 || rtprio >= 99;
    let lock = caps & CAP_IPC_LOCK != 0 || memlock == u64::MAX;
    if sys.cap_eff.is_none() && sys.rlimits.is_none() {
        return Finding::unknown(C, "capabilities and limits unreadable".into());
    }
    if nice && lock {
        return Finding::good(
            C,
            "SCHED_FIFO and mlockall are allowed (CAP_SYS_NICE or RLIMIT_RTPRIO, CAP_IPC_LOCK \
             or an unlimited RLIMIT_MEMLOCK)"
                .into(),
        );
    }
    let mut missing = Vec::new();
    if !nice {
        missing.push(format!(
            "SCHED_FIFO (no CAP_SYS_NICE, RLIMIT_RTPRIO {rtprio})"
        ));
    }
    if !lock {
        missing.push(format!(
            "mlockall of everything (no CAP_IPC_LOCK, RLIMIT_MEMLOCK {memlock} bytes)"
        ));
    }
    Finding::fix(
        C,
        format!("not allowed: {}", missing.join("; ")),
        "in the systemd unit: LimitRTPRIO=99 and LimitMEMLOCK=infinity (or \
         AmbientCapabilities=CAP_SYS_NICE CAP_IPC_LOCK)"
            .into(),
    )
}

const SHARED: &str = "shared rt core";

/// The `shared rt core` finding when `/proc` cannot be listed.
pub fn shared_core_unreadable() -> Finding {
    Finding::unknown(
        SHARED,
        "/proc unreadable: the tasks cannot be listed".into(),
    )
}

/// The `shared rt core` finding from what `tasks` saw on `core` over `window`; `isolated`
/// says whether the core is isolated (`None`: unknown). Fix when a user-space task of
/// another process was seen there, naming it; per-CPU kernel threads, and the threads of
/// process `own_pid` (the service itself: its helper threads before they moved off the
/// core), are named apart and alone leave it Good.
pub fn shared_core_finding(
    core: usize,
    isolated: Option<bool>,
    tasks: &CoreTasks,
    window: Duration,
    own_pid: u32,
) -> Finding {
    let (own, top): (Vec<_>, Vec<_>) = tasks
        .top()
        .into_iter()
        .partition(|t| t.pid == own_pid && !t.kernel_thread);
    let own_note = if own.is_empty() {
        String::new()
    } else {
        let names: Vec<&str> = own.iter().map(|t| t.comm.as_str()).collect();
        format!("; the service's own threads: {}", names.join(", "))
    };
    let name = |t: &crate::scheduling::core_tasks::CoreTask| {
        format!(
            "{} (pid {}, seen in {} of {} scans)",
            t.comm,
            t.pid,
            t.samples,
            tasks.scans()
        )
    };
    let users: Vec<String> = top.iter().filter(|t| !t.kernel_thread).map(name).collect();
    let kernel: Vec<String> = top
        .iter()
        .filter(|t| t.kernel_thread)
        .map(|t| t.comm.clone())
        .collect();
    let ms = window.as_millis();
    let isolation = match isolated {
        Some(true) => "isolated",
        Some(false) => "not isolated",
        None => "isolation unknown",
    };
    if users.is_empty() {
        let kernel_note = if kernel.is_empty() {
            String::new()
        } else {
            format!(" (per-CPU kernel threads only: {})", kernel.join(", "))
        };
        return Finding::good(
            SHARED,
            format!(
                "core {core} ({isolation}): no other user-space task ran there in {ms} ms{kernel_note}{own_note}"
            ),
        );
    }
    let pids: Vec<String> = {
        let mut p: Vec<u32> = top
            .iter()
            .filter(|t| !t.kernel_thread)
            .map(|t| t.pid)
            .collect();
        p.sort_unstable();
        p.dedup();
        p.iter().map(u32::to_string).collect()
    };
    let fix = if isolated == Some(true) {
        format!(
            "something is pinned to the isolated core {core}: move it off (taskset -apc <other cores> {})",
            pids.join(" ")
        )
    } else {
        format!(
            "isolate core {core} (isolcpus={core} nohz_full={core} rcu_nocbs={core}, or a cpuset), or move them off it (taskset -apc <other cores> {})",
            pids.join(" ")
        )
    };
    Finding::fix(
        SHARED,
        format!(
            "the RT core {core} ({isolation}) is shared: {} other task(s) ran there in {ms} ms: {}{own_note}",
            users.len(),
            users.join(", ")
        ),
        fix,
    )
}

fn shared_core(sys: &SystemRoot, core: Option<usize>) -> Finding {
    let Some(core) = core else {
        return Finding::unknown(SHARED, "the RT thread is not pinned".into());
    };
    let step = crate::scheduling::watch::SCAN_EVERY;
    let scans = 1 + (sys.sample_window.as_nanos() / step.as_nanos().max(1)) as usize;
    let mut tasks = CoreTasks::new(core, crate::scheduling::watch::TOP_TASKS);
    tasks.exclude(crate::scheduling::watch::current_tid());
    let proc_dir = sys.root.join("proc");
    let mut seen = Vec::new();
    let began = std::time::Instant::now();
    for i in 0..scans {
        if i > 0 {
            std::thread::sleep(step);
        }
        if !scan_tasks(&proc_dir, &mut seen) {
            return shared_core_unreadable();
        }
        tasks.observe(&seen);
    }
    shared_core_finding(
        core,
        core_isolated(sys, core),
        &tasks,
        began.elapsed(),
        std::process::id(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A made-up machine: `files` are `(path, content)` under a fresh folder.
    fn machine(name: &str, files: &[(&str, &str)]) -> PathBuf {
        let root = std::env::temp_dir().join(format!("syscheck-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (path, text) in files {
            let p = root.join(path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        }
        root
    }

    /// A task's `stat` line: state `state`, kernel thread or not, last on `cpu`.
    fn stat_line(tid: u32, comm: &str, state: char, kthread: bool, cpu: usize) -> String {
        let mut f: Vec<String> = (3..=52).map(|_| "0".to_string()).collect();
        f[0] = state.to_string();
        f[9 - 3] = if kthread { "2129984" } else { "4194560" }.into();
        f[39 - 3] = cpu.to_string();
        format!("{tid} ({comm}) {}\n", f.join(" "))
    }

    #[test]
    fn the_rt_core_is_shared_when_a_user_task_runs_there_and_not_for_kernel_threads() {
        let files = |hog_cpu: usize| {
            vec![
                ("proc/cmdline".to_string(), "root=/dev/vda1\n".to_string()),
                // The per-CPU kernel thread of core 2, runnable there.
                (
                    "proc/12/task/12/stat".into(),
                    stat_line(12, "ksoftirqd/2", 'R', true, 2),
                ),
                // A busy loop of a shell, on `hog_cpu`.
                (
                    "proc/300/task/300/stat".into(),
                    stat_line(300, "sh", 'R', false, hog_cpu),
                ),
                // A sleeping thread last on core 2: not counted.
                (
                    "proc/300/task/301/stat".into(),
                    stat_line(301, "worker", 'S', false, 2),
                ),
            ]
        };
        let check = |name: &str, hog_cpu: usize| {
            let f = files(hog_cpu);
            let f: Vec<(&str, &str)> = f.iter().map(|(a, b)| (a.as_str(), b.as_str())).collect();
            let root = machine(name, &f);
            let finding = shared_core(&SystemRoot::at(&root, ""), Some(2));
            let _ = std::fs::remove_dir_all(&root);
            finding
        };
        let shared = check("shared", 2);
        assert_eq!(shared.verdict, Verdict::Fix, "{shared:?}");
        assert!(
            shared
                .found
                .contains("core 2 (not isolated) is shared: 1 other task(s)")
                && shared.found.contains("sh (pid 300, seen in 1 of 1 scans)")
                && !shared.found.contains("worker"),
            "{}",
            shared.found
        );
        assert!(
            shared
                .fix
                .as_deref()
                .unwrap()
                .contains("taskset -apc <other cores> 300")
        );
        let alone = check("alone", 0);
        assert_eq!(alone.verdict, Verdict::Good, "{alone:?}");
        assert!(
            alone.found.contains("kernel threads only: ksoftirqd/2"),
            "{}",
            alone.found
        );
        // No /proc to list: unknown, and an unpinned service cannot be checked.
        let root = machine("noproc", &[("sys/x", "")]);
        assert_eq!(
            shared_core(&SystemRoot::at(&root, ""), Some(2)).verdict,
            Verdict::Unknown
        );
        assert_eq!(
            shared_core(&SystemRoot::at(&root, ""), None).verdict,
            Verdict::Unknown
        );
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn the_services_own_threads_are_named_apart_and_never_in_the_taskset_fix() {
        use crate::scheduling::core_tasks::TaskStat;
        let task = |pid: u32, tid: u32, comm: &str| TaskStat {
            pid,
            tid,
            comm: comm.into(),
            state: 'R',
            kernel_thread: false,
            ticks: 5,
            processor: 1,
        };
        let finding = |tasks: &[TaskStat]| {
            let mut c = CoreTasks::new(1, 8);
            c.observe(tasks);
            shared_core_finding(1, Some(false), &c, Duration::from_millis(200), 40)
        };
        // Only the service's own helper thread: nothing to fix, but it is named.
        let own = finding(&[task(40, 41, "histograms")]);
        assert_eq!(own.verdict, Verdict::Good, "{own:?}");
        assert!(
            own.found.contains("the service's own threads: histograms"),
            "{}",
            own.found
        );
        // With a foreign task: the fix names the foreign pid, never the service's.
        let both = finding(&[task(40, 41, "histograms"), task(77, 77, "sh")]);
        assert_eq!(both.verdict, Verdict::Fix, "{both:?}");
        assert!(
            both.found.contains("1 other task(s)") && both.found.contains("sh (pid 77"),
            "{}",
            both.found
        );
        let fix = both.fix.unwrap();
        assert!(fix.ends_with("taskset -apc <other cores> 77)"), "{fix}");
    }

    #[test]
    fn an_isolated_core_with_a_task_pinned_to_it_says_to_move_the_task() {
        let hog = stat_line(55, "stress", 'R', false, 3);
        let root = machine(
            "isolated",
            &[
                ("proc/cmdline", "isolcpus=3\n"),
                ("proc/55/task/55/stat", &hog),
            ],
        );
        let sys = SystemRoot::at(&root, "");
        assert_eq!(core_isolated(&sys, 3), Some(true));
        assert_eq!(core_isolated(&sys, 2), Some(false));
        let f = shared_core(&sys, Some(3));
        assert_eq!(f.verdict, Verdict::Fix);
        assert!(f.found.contains("(isolated)"), "{}", f.found);
        assert!(f.fix.as_deref().unwrap().starts_with("something is pinned"));
        let _ = std::fs::remove_dir_all(&root);
    }

    fn verdicts(f: &[Finding]) -> Vec<(&'static str, Verdict)> {
        f.iter().map(|f| (f.check, f.verdict)).collect()
    }

    #[test]
    fn cpu_lists_parse_as_the_kernel_writes_them() {
        assert_eq!(parse_cpu_list("0-2,5,7-8"), Some(vec![0, 1, 2, 5, 7, 8]));
        assert_eq!(parse_cpu_list("domain,managed_irq,3"), Some(vec![3]));
        assert_eq!(parse_cpu_list(""), Some(vec![]));
        assert_eq!(parse_cpu_list("3-1"), None);
        assert_eq!(parse_cpu_list("x7"), None);
    }

    #[test]
    fn a_tuned_box_passes_every_check() {
        let root = machine(
            "tuned",
            &[
                ("sys/kernel/realtime", "1\n"),
                (
                    "proc/cmdline",
                    "BOOT_IMAGE=/vmlinuz isolcpus=managed_irq,domain,2-3 nohz_full=2-3 rcu_nocbs=2-3\n",
                ),
                ("proc/sys/kernel/sched_rt_runtime_us", "-1\n"),
                ("proc/sys/kernel/sched_rt_period_us", "1000000\n"),
                (
                    "sys/devices/system/cpu/cpu2/cpufreq/scaling_governor",
                    "performance\n",
                ),
                (
                    "sys/devices/system/cpu/cpu2/topology/thread_siblings_list",
                    "2-3\n",
                ),
                ("sys/devices/system/cpu/isolated", "2-3\n"),
                ("proc/irq/24/smp_affinity_list", "0-1\n"),
                ("proc/irq/25/smp_affinity_list", "0\n"),
                ("proc/swaps", "Filename Type Size Used Priority\n"),
                (
                    "sys/kernel/mm/transparent_hugepage/enabled",
                    "always [madvise] never\n",
                ),
            ],
        );
        let mut sys = SystemRoot::at(&root, "#1 SMP PREEMPT_RT");
        sys.cap_eff = Some(1 << 23 | 1 << 14);
        let f = check_system(&sys, Some(2));
        assert!(f.iter().all(|f| f.verdict == Verdict::Good), "{f:#?}");
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn a_shared_vm_gets_a_fix_for_each_finding_and_unknown_where_it_cannot_tell() {
        let hog = stat_line(4321, "hog", 'R', false, 1);
        let root = machine(
            "vm",
            &[
                (
                    "proc/cmdline",
                    "BOOT_IMAGE=/vmlinuz root=/dev/vda1 nohz_full=1\n",
                ),
                ("proc/sys/kernel/sched_rt_runtime_us", "950000\n"),
                ("proc/sys/kernel/sched_rt_period_us", "1000000\n"),
                (
                    "sys/devices/system/cpu/cpu1/topology/thread_siblings_list",
                    "0-1\n",
                ),
                ("proc/irq/1/smp_affinity_list", "0-1\n"),
                ("proc/irq/9/smp_affinity_list", "1\n"),
                ("proc/irq/11/smp_affinity_list", "0\n"),
                (
                    "proc/swaps",
                    "Filename Type Size Used Priority\n/swapfile file 1048576 0 -2\n",
                ),
                (
                    "sys/kernel/mm/transparent_hugepage/enabled",
                    "[always] madvise never\n",
                ),
                ("proc/4321/task/4321/stat", &hog),
            ],
        );
        let mut sys = SystemRoot::at(&root, "#1 SMP PREEMPT_DYNAMIC");
        sys.rlimits = Some((0, 8 << 20));
        let f = check_system(&sys, Some(1));
        use Verdict::*;
        assert_eq!(
            verdicts(&f),
            [
                ("preemption", Fix),
                ("isolated core", Fix),
                ("rt throttling", Fix),
                ("cpu governor", Unknown),
                ("smt sibling", Fix),
                ("irq affinity", Fix),
                ("swap", Fix),
                ("transparent huge pages", Fix),
                ("privileges", Fix),
                ("shared rt core", Fix),
            ]
        );
        assert!(f[9].found.contains("hog (pid 4321"), "{}", f[9].found);
        assert!(f[9].fix.as_deref().unwrap().contains("isolcpus=1"));
        assert!(
            f.iter()
                .filter(|f| f.verdict == Fix)
                .all(|f| f.fix.is_some())
        );
        assert!(f[0].found.contains("PREEMPT_DYNAMIC"), "{}", f[0].found);
        assert_eq!(
            f[1].fix.as_deref(),
            Some("add isolcpus=1 rcu_nocbs=1 to the kernel command line")
        );
        assert!(
            f[5].found
                .starts_with("2 interrupts may run on core 1 (IRQ 1, 9)"),
            "{}",
            f[5].found
        );
        assert!(f[8].found.contains("RLIMIT_RTPRIO 0"), "{}", f[8].found);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn an_unpinned_service_is_a_finding_and_this_machine_can_be_checked() {
        let f = check_system(&SystemRoot::live(), None);
        assert_eq!(f.len(), 10);
        assert_eq!((f[1].check, f[1].verdict), ("isolated core", Verdict::Fix));
        // Every finding renders on one line naming its check.
        for x in &f {
            let line = x.render();
            assert!(line.contains(x.check) && !line.contains('\n'), "{line}");
        }
    }
}
