//! Facts about the machine that the figures depend on: cores, CPU model, kernel, the
//! service's system check for the RT core ([`service::system_check`]: preemption model,
//! isolation, RT throttling, governor, SMT, IRQs, swap, huge pages, privileges), the load,
//! and what the OS granted the bench's real-time threads.

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
    /// The system check for the RT core: what moves the wake-up latency, with fixes.
    pub system: Vec<service::system_check::Finding>,
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

/// Collects the facts; `plant_rt` is the outcome of the parent's RT set-up, `rt_core` the
/// core the system check looks at.
pub fn collect(plant_rt: &ipc_types::rt::RtSetup, rt_core: usize) -> MachineFacts {
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
    MachineFacts {
        cores,
        cpu_model,
        kernel: uname(),
        system: service::system_check::check_system(
            &service::system_check::SystemRoot::live(),
            Some(rt_core),
        ),
        load_average: load_average(),
        plant_rt_setup: plant_rt.describe(),
        plant_rt_granted: !plant_rt.any_refused(),
    }
}

impl MachineFacts {
    /// The lines printed above the table.
    pub fn render(&self) -> String {
        let mut out = format!(
            "machine: {} cores, {}; load average {}\nkernel:  {}\n",
            self.cores, self.cpu_model, self.load_average, self.kernel
        );
        for f in &self.system {
            out += &format!("system: {}\n", f.render());
        }
        out += &format!("plant thread (parent): {}\n", self.plant_rt_setup);
        out
    }
}

/// A real-time thread of another process that was running on a core.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RtThread {
    /// Its process.
    pub pid: u32,
    /// The process's command name.
    pub process: String,
    /// The thread id.
    pub tid: u32,
    /// The thread's name.
    pub thread: String,
    /// `SCHED_FIFO` or `SCHED_RR`.
    pub policy: &'static str,
    /// Its real-time priority.
    pub priority: u32,
}

impl std::fmt::Display for RtThread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "pid {} ({}), thread {} '{}', {} {}",
            self.pid, self.process, self.tid, self.thread, self.policy, self.priority
        )
    }
}

/// The command name and the fields after it of a `/proc/…/stat` line.
fn stat_fields(text: &str) -> Option<(String, Vec<&str>)> {
    let open = text.find('(')?;
    let close = text.rfind(')')?;
    let comm = text.get(open + 1..close)?.to_string();
    Some((comm, text[close + 1..].split_whitespace().collect()))
}

/// The runnable `SCHED_FIFO` / `SCHED_RR` threads of user processes other than this one
/// whose last core was `core` (`/proc/<pid>/task/<tid>/stat`: state, processor, priority
/// and policy). A thread of the bench's real-time set-up cannot run on a core where such a
/// thread of equal or higher priority spins: a service child left running by an earlier
/// bench that was killed is one (it busy-polls at `SCHED_FIFO` 80 and would never end by
/// itself), and every later service child pinned there then never connects.
pub fn rt_threads_on_core(core: usize) -> Vec<RtThread> {
    let me = std::process::id();
    let mut found = Vec::new();
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return found;
    };
    for p in procs.flatten() {
        let Some(pid) = p.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
            continue;
        };
        // Kernel threads (per-core migration and interrupt threads) have no command line.
        if pid == me || std::fs::read(p.path().join("cmdline")).map_or(true, |c| c.is_empty()) {
            continue;
        }
        let process = std::fs::read_to_string(p.path().join("stat"))
            .ok()
            .and_then(|t| stat_fields(&t).map(|(c, _)| c))
            .unwrap_or_default();
        let Ok(tasks) = std::fs::read_dir(p.path().join("task")) else {
            continue;
        };
        for t in tasks.flatten() {
            let Some(tid) = t.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
                continue;
            };
            let Ok(text) = std::fs::read_to_string(t.path().join("stat")) else {
                continue;
            };
            let Some((thread, f)) = stat_fields(&text) else {
                continue;
            };
            // Fields 3 (state), 39 (processor), 40 (rt_priority), 41 (policy).
            let (Some(state), Some(cpu), Some(prio), Some(policy)) =
                (f.first(), f.get(36), f.get(37), f.get(38))
            else {
                continue;
            };
            let policy = match *policy {
                "1" => "SCHED_FIFO",
                "2" => "SCHED_RR",
                _ => continue,
            };
            if *state == "R" && cpu.parse::<usize>().ok() == Some(core) {
                found.push(RtThread {
                    pid,
                    process: process.clone(),
                    tid,
                    thread,
                    policy,
                    priority: prio.parse().unwrap_or(0),
                });
            }
        }
    }
    found
}

/// `""`, or a sentence naming the real-time threads of other processes running on `core`
/// ([`rt_threads_on_core`]) but those of the processes `except` (the bench's own child), for
/// error messages and warnings.
pub fn core_occupancy_note(core: usize, except: &[u32]) -> String {
    let mut found = rt_threads_on_core(core);
    found.retain(|t| !except.contains(&t.pid));
    if found.is_empty() {
        return String::new();
    }
    let list: Vec<String> = found.iter().map(ToString::to_string).collect();
    let pids: Vec<String> = {
        let mut p: Vec<u32> = found.iter().map(|t| t.pid).collect();
        p.dedup();
        p.iter().map(u32::to_string).collect()
    };
    format!(
        "core {core} is taken by real-time thread(s) of other processes: {}; a bench thread of \
         the same or a lower priority cannot run there (a service child left running by an \
         earlier bench that was killed looks like this: stop it, e.g. kill {}, and run again)",
        list.join("; "),
        pids.join(" ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stat_line_is_split_after_the_command_name_even_with_spaces_in_it() {
        let (comm, f) = stat_fields("42 (rt loop) R 1 42 42 0 -1").unwrap();
        assert_eq!(comm, "rt loop");
        assert_eq!(f[0], "R");
        assert_eq!(f[1], "1");
    }

    #[test]
    fn this_process_is_never_reported() {
        let me = std::process::id();
        for core in 0..4 {
            assert!(rt_threads_on_core(core).iter().all(|t| t.pid != me));
        }
    }
}
