//! Keeping the monitor off the service's real-time core.
//!
//! On a box whose RT core is isolated (`isolcpus=`, a cpuset) nothing else is placed there
//! and this does nothing. On a box where it is not, the scheduler may run the monitor's
//! threads (HTTP, Foxglove, the readers) on the service's RT core, where each preemption by
//! the RT thread is cheap for the service but every wake-up of a monitor thread there is a
//! context switch the RT thread may meet. So, unless `--any-core`, when a rig's telemetry
//! names its service's pid, the monitor finds the cores of that process's real-time threads
//! (`SCHED_FIFO` or `SCHED_RR`, read from `/proc/<pid>/task/<tid>/stat`, their affinity
//! from `sched_getaffinity`) and moves every one of its own threads
//! (`/proc/self/task`) off them; threads started later inherit the mask. When that would
//! leave it no core, it stays where it is and says so.

use std::collections::BTreeSet;

/// The scheduling policy (field 41) of a `/proc/<pid>/task/<tid>/stat` line.
pub fn policy_of_stat(stat: &str) -> Option<u32> {
    // The command name (field 2) is in parentheses and may hold spaces and ')': the fields
    // after the last ')' start with field 3.
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(41 - 3)?.parse().ok()
}

/// `SCHED_FIFO` or `SCHED_RR`.
fn is_real_time(policy: u32) -> bool {
    policy == libc::SCHED_FIFO as u32 || policy == libc::SCHED_RR as u32
}

/// The CPUs thread `tid` may run on (`sched_getaffinity`); `None` when it cannot be read.
fn affinity(tid: libc::pid_t) -> Option<BTreeSet<usize>> {
    // SAFETY: a zeroed cpu_set_t is a valid empty set.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    // SAFETY: `set` is a valid cpu_set_t of the size given.
    let rc =
        unsafe { libc::sched_getaffinity(tid, std::mem::size_of::<libc::cpu_set_t>(), &mut set) };
    if rc != 0 {
        return None;
    }
    let n = 8 * std::mem::size_of::<libc::cpu_set_t>();
    // SAFETY: `cpu < n`, within the set.
    Some(
        (0..n)
            .filter(|&cpu| unsafe { libc::CPU_ISSET(cpu, &set) })
            .collect(),
    )
}

/// The thread ids of process `pid` (`"self"` for this one).
fn threads(pid: &str) -> Vec<libc::pid_t> {
    std::fs::read_dir(format!("/proc/{pid}/task"))
        .map(|d| {
            d.filter_map(Result::ok)
                .filter_map(|e| e.file_name().to_str()?.parse().ok())
                .collect()
        })
        .unwrap_or_default()
}

/// The cores the real-time threads of process `pid` are pinned to (a thread allowed on
/// every core pins nothing and is left out).
pub fn real_time_cores(pid: u32) -> BTreeSet<usize> {
    let all = affinity(0).map_or(0, |s| s.len());
    let mut cores = BTreeSet::new();
    for tid in threads(&pid.to_string()) {
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/task/{tid}/stat")) else {
            continue;
        };
        if !policy_of_stat(&stat).is_some_and(is_real_time) {
            continue;
        }
        if let Some(set) = affinity(tid).filter(|s| s.len() < all.max(2)) {
            cores.extend(set);
        }
    }
    cores
}

/// `allowed` without `avoid`; `None` when nothing would be left.
pub fn without(allowed: &BTreeSet<usize>, avoid: &BTreeSet<usize>) -> Option<BTreeSet<usize>> {
    let left: BTreeSet<usize> = allowed.difference(avoid).copied().collect();
    (!left.is_empty()).then_some(left)
}

/// What [`keep_off`] did.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Placement {
    /// Already off those cores.
    Already,
    /// Every thread moved to these cores.
    Moved(BTreeSet<usize>),
    /// Moving would leave no core (or the mask could not be read or set): stayed.
    Stayed(String),
}

/// Moves every thread of this process off `cores` (module docs).
pub fn keep_off(cores: &BTreeSet<usize>) -> Placement {
    let Some(allowed) = affinity(0) else {
        return Placement::Stayed("its own affinity could not be read".into());
    };
    if allowed.is_disjoint(cores) {
        return Placement::Already;
    }
    let Some(left) = without(&allowed, cores) else {
        return Placement::Stayed(format!(
            "it may only run on {allowed:?}, all of them real-time cores of the service"
        ));
    };
    // SAFETY: a zeroed cpu_set_t is a valid empty set; CPU_SET within its size.
    let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    for &cpu in &left {
        // SAFETY: `cpu` came from a set of this size.
        unsafe { libc::CPU_SET(cpu, &mut set) };
    }
    for tid in threads("self") {
        // SAFETY: `set` is a valid cpu_set_t of the size given.
        let rc =
            unsafe { libc::sched_setaffinity(tid, std::mem::size_of::<libc::cpu_set_t>(), &set) };
        if rc != 0 {
            return Placement::Stayed(format!(
                "thread {tid}: sched_setaffinity: {}",
                std::io::Error::last_os_error()
            ));
        }
    }
    Placement::Moved(left)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stat line of a thread named `comm` with `policy` in field 41.
    fn stat(comm: &str, policy: u32) -> String {
        let mut fields: Vec<String> = (3..=52).map(|i| i.to_string()).collect();
        fields[41 - 3] = policy.to_string();
        format!("1234 ({comm}) {}", fields.join(" "))
    }

    #[test]
    fn the_policy_is_field_41_whatever_the_command_name_holds() {
        assert_eq!(policy_of_stat(&stat("service", 1)), Some(1));
        assert_eq!(policy_of_stat(&stat("a (b) c)", 0)), Some(0));
        assert_eq!(policy_of_stat("garbage"), None);
    }

    #[test]
    fn the_cores_left_are_the_allowed_less_the_real_time_ones() {
        let set = |v: &[usize]| v.iter().copied().collect::<BTreeSet<_>>();
        assert_eq!(without(&set(&[0, 1]), &set(&[1])), Some(set(&[0])));
        assert_eq!(without(&set(&[1]), &set(&[1])), None);
        assert_eq!(without(&set(&[0, 2]), &set(&[1])), Some(set(&[0, 2])));
    }

    #[test]
    fn a_process_without_real_time_threads_pins_nothing() {
        assert!(real_time_cores(std::process::id()).is_empty());
    }

    #[test]
    fn the_core_of_a_real_time_process_is_found() {
        if affinity(0).is_none_or(|s| !s.contains(&1)) {
            eprintln!("SKIPPED: core 1 is not available to this test");
            return;
        }
        // A SCHED_FIFO process pinned to core 1 (chrt and taskset, from util-linux).
        let mut child = match std::process::Command::new("taskset")
            .args(["-c", "1", "chrt", "-f", "10", "sleep", "5"])
            .stderr(std::process::Stdio::null())
            .spawn()
        {
            Ok(c) => c,
            Err(e) => {
                eprintln!("SKIPPED: taskset: {e}");
                return;
            }
        };
        let pid = child.id();
        let mut cores = BTreeSet::new();
        for _ in 0..200 {
            cores = real_time_cores(pid);
            if !cores.is_empty() || child.try_wait().ok().flatten().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let refused = child.try_wait().ok().flatten();
        let _ = child.kill();
        let _ = child.wait();
        if let Some(status) = refused {
            eprintln!("SKIPPED: chrt -f was refused ({status}); this test needs CAP_SYS_NICE");
            return;
        }
        assert_eq!(cores, BTreeSet::from([1]));
    }
}
