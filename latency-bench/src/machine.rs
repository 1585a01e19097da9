//! Facts about the machine that the figures depend on: cores, CPU model, kernel and its
//! preemption model, RT throttling, boot parameters that isolate cores, and what the OS
//! granted the bench's real-time threads.

use serde::Serialize;

/// What the machine is and what it granted.
#[derive(Debug, Clone, Serialize)]
pub struct MachineFacts {
    /// Online cores.
    pub cores: usize,
    /// CPU model name from `/proc/cpuinfo`.
    pub cpu_model: String,
    /// `uname`: system, release, version, machine.
    pub kernel: String,
    /// `PREEMPT_RT`, `PREEMPT_DYNAMIC`, `PREEMPT` or unknown, from `uname -v` and
    /// `/sys/kernel/realtime`.
    pub preemption: String,
    /// `/proc/sys/kernel/sched_rt_runtime_us` / `sched_rt_period_us`.
    pub rt_throttling: String,
    /// Kernel command-line parameters that affect latency (`isolcpus`, `nohz_full`, …).
    pub latency_boot_params: Vec<String>,
    /// `/proc/loadavg` when the facts were collected: other work on the machine moves
    /// every figure.
    pub load_average: String,
    /// Outcome of pinning, `SCHED_FIFO` and `mlockall` for the plant-side thread of the
    /// bench (parent process), one line.
    pub plant_rt_setup: String,
    /// True when the plant-side thread got everything it asked for.
    pub plant_rt_granted: bool,
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_string())
}

/// The 1, 5 and 15 minute load averages, from `/proc/loadavg`.
pub fn load_average() -> String {
    read("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

/// `uname -srvm`.
pub fn uname() -> String {
    // SAFETY: utsname is plain data and uname only writes into it.
    let mut u: libc::utsname = unsafe { core::mem::zeroed() };
    // SAFETY: `u` is a valid, writable utsname.
    if unsafe { libc::uname(&mut u) } != 0 {
        return "unknown".into();
    }
    let field = |f: &[libc::c_char]| {
        let bytes: Vec<u8> = f
            .iter()
            .take_while(|c| **c != 0)
            .map(|c| *c as u8)
            .collect();
        String::from_utf8_lossy(&bytes).into_owned()
    };
    format!(
        "{} {} {} {}",
        field(&u.sysname),
        field(&u.release),
        field(&u.version),
        field(&u.machine)
    )
}

/// Collects the facts; `plant_rt` is the outcome of the parent's RT set-up.
pub fn collect(plant_rt: &ipc_types::rt::RtSetup) -> MachineFacts {
    // SAFETY: sysconf only reads a system parameter.
    let cores = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) }.max(1) as usize;
    let cpu_model = read("/proc/cpuinfo")
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into());
    let kernel = uname();
    let preemption =
        if read("/sys/kernel/realtime").as_deref() == Some("1") || kernel.contains("PREEMPT_RT") {
            "PREEMPT_RT".to_string()
        } else if kernel.contains("PREEMPT_DYNAMIC") {
            let mode = read("/sys/kernel/debug/sched/preempt").unwrap_or_default();
            if mode.is_empty() {
                "PREEMPT_DYNAMIC (no PREEMPT_RT)".into()
            } else {
                format!("PREEMPT_DYNAMIC, mode {mode} (no PREEMPT_RT)")
            }
        } else if kernel.contains("PREEMPT") {
            "PREEMPT (no PREEMPT_RT)".into()
        } else {
            "unknown (no PREEMPT_RT)".into()
        };
    let rt_throttling = match (
        read("/proc/sys/kernel/sched_rt_runtime_us"),
        read("/proc/sys/kernel/sched_rt_period_us"),
    ) {
        (Some(r), Some(p)) if r == "-1" => format!("off (runtime -1 of {p} µs)"),
        (Some(r), Some(p)) => format!("RT tasks may use {r} of every {p} µs"),
        _ => "unknown".into(),
    };
    let latency_boot_params = read("/proc/cmdline")
        .map(|c| {
            c.split_whitespace()
                .filter(|p| {
                    [
                        "isolcpus",
                        "nohz_full",
                        "rcu_nocbs",
                        "irqaffinity",
                        "idle=",
                        "processor.max_cstate",
                        "intel_idle",
                        "threadirqs",
                        "preempt=",
                    ]
                    .iter()
                    .any(|k| p.starts_with(k))
                })
                .map(str::to_string)
                .collect()
        })
        .unwrap_or_default();
    MachineFacts {
        cores,
        cpu_model,
        kernel,
        preemption,
        rt_throttling,
        latency_boot_params,
        load_average: load_average(),
        plant_rt_setup: plant_rt.describe(),
        plant_rt_granted: !plant_rt.any_refused(),
    }
}

impl MachineFacts {
    /// The lines printed above the table.
    pub fn render(&self) -> String {
        let boot = if self.latency_boot_params.is_empty() {
            "none".to_string()
        } else {
            self.latency_boot_params.join(" ")
        };
        format!(
            "machine: {} cores, {}; load average {}\nkernel:  {}\npreemption: {}; RT throttling: {}; latency boot parameters: {}\nplant thread (parent): {}\n",
            self.cores,
            self.cpu_model,
            self.load_average,
            self.kernel,
            self.preemption,
            self.rt_throttling,
            boot,
            self.plant_rt_setup
        )
    }
}
