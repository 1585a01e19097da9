//! Whether the process behind an iceoryx2 node (or port) still exists, robust to pid reuse.
//!
//! iceoryx2 ids carry the pid and the creation time (`CLOCK_MONOTONIC`) of the process that
//! made them. `kill(pid, 0)` alone says whether *some* process has that pid: after a crash
//! the pid may belong to another process by now, typically in a container, where every run
//! starts the same processes in the same order and gets the same pids. A stale node whose
//! pid was reused then looks alive for ever, its resources are never removed, and a peer
//! that needs its slot (or a service of the same name) waits in vain. So a process counts
//! as the node's only if it started no later than the node was created: its start time
//! (`/proc/<pid>/stat`, in clock ticks on `CLOCK_BOOTTIME`) is compared with the node's
//! creation time moved onto `CLOCK_BOOTTIME` by the current offset between the two clocks
//! (time spent suspended). That offset only grows, so the moved creation time is never
//! earlier than the true one: the test can call a dead node alive (and leave it), never a
//! live node dead (and remove a live peer's resources).
//!
//! A process that has exited but was not reaped yet (a zombie, state `Z` or `X` in
//! `/proc/<pid>/stat`) is dead: it holds no mapping and will never touch its ports again.
//! An orphan is reaped by whoever adopts it, and in a container that is often a PID 1 that
//! never reaps; `kill(pid, 0)` succeeds on a zombie, so without this test a killed peer's
//! resources would stay for as long as the container runs.

use iceoryx2::identifiers::UniqueNodeId;
use iceoryx2::prelude::ipc;

/// Slack for clock granularity (clock ticks of 10 ms, whole seconds in the id).
const SLACK_NS: u64 = 1_500_000_000;

/// Whether the process that created `node` is alive.
pub(crate) fn node_alive(node: &UniqueNodeId) -> bool {
    let Ok(pid) = node.pid::<ipc::Service>() else {
        return false;
    };
    let pid = pid.value();
    if !pid_alive(pid) {
        return false;
    }
    let (Ok(created), Some(started)) = (
        node.creation_time::<ipc::Service>(),
        process_start_boottime_ns(pid),
    ) else {
        return true;
    };
    let created_ns = created.seconds() * 1_000_000_000 + u64::from(created.nanoseconds());
    let offset = clock_ns(libc::CLOCK_BOOTTIME).saturating_sub(clock_ns(libc::CLOCK_MONOTONIC));
    started <= created_ns + offset + SLACK_NS
}

/// Whether a process with this id exists (`kill(pid, 0)`: 0, or `EPERM` for another
/// user's process).
pub(crate) fn pid_alive(pid: i32) -> bool {
    if pid <= 0 {
        return false;
    }
    // SAFETY: signal 0 performs the existence and permission check only.
    let r = unsafe { libc::kill(pid, 0) };
    let exists = r == 0 || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM);
    exists && !exited(pid)
}

/// Whether process `pid` has exited and waits to be reaped (state `Z` or `X`).
fn exited(pid: i32) -> bool {
    let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return false;
    };
    // The state is the first field after the command name, which ends at the last ')'.
    let state = stat
        .rfind(')')
        .and_then(|i| stat[i + 1..].split_whitespace().next());
    matches!(state, Some("Z" | "X"))
}

fn clock_ns(clock: libc::clockid_t) -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec given.
    unsafe { libc::clock_gettime(clock, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The start time of process `pid` since boot, ns (field 22 of `/proc/<pid>/stat`).
fn process_start_boottime_ns(pid: i32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) may contain spaces and parentheses: fields after the last ')'.
    let rest = &stat[stat.rfind(')')? + 1..];
    let ticks: u64 = rest.split_whitespace().nth(19)?.parse().ok()?;
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if hz <= 0 {
        return None;
    }
    Some(ticks * (1_000_000_000 / hz as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_started_before_now_and_exists() {
        let me = std::process::id() as i32;
        assert!(pid_alive(me));
        let started = process_start_boottime_ns(me).expect("/proc/self/stat");
        assert!(started <= clock_ns(libc::CLOCK_BOOTTIME));
        assert!(!pid_alive(0) && !pid_alive(-1));
    }

    #[test]
    fn a_zombie_is_dead() {
        let mut child = std::process::Command::new("true")
            .spawn()
            .expect("starting true");
        let pid = child.id() as i32;
        // Not reaped yet: a zombie once it has exited.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while !exited(pid) && std::time::Instant::now() < deadline {
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert!(exited(pid), "'true' did not exit within 10 s");
        // SAFETY: signal 0 performs the existence check only.
        assert_eq!(
            unsafe { libc::kill(pid, 0) },
            0,
            "a zombie still has its pid"
        );
        assert!(!pid_alive(pid));
        child.wait().expect("reaping true");
        assert!(!pid_alive(pid));
    }

    #[test]
    fn a_node_of_this_process_is_alive() {
        use iceoryx2::prelude::*;
        let node = NodeBuilder::new().create::<ipc::Service>().unwrap();
        assert!(node_alive(node.id()));
    }
}
