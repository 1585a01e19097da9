//! The load of a condition: a `SCHED_OTHER` busy loop pinned to one core, in a child
//! process that lives exactly as long as its guard.
//!
//! [`Hog::start`] runs `/bin/sh -c 'while :; do :; done'` with its affinity set to the one
//! core (`sched_setaffinity` between fork and exec) and its policy set to `SCHED_OTHER`
//! (whatever this process runs at). Dropping the [`Hog`] kills it (`SIGKILL`) and reaps
//! it, on every path out of a run: its end, an error, a panic that unwinds, the campaign
//! asked to stop. Should this process die without unwinding, the child gets `SIGKILL`
//! from the kernel (`PR_SET_PDEATHSIG`).

use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};

/// A busy loop pinned to one core; killed and reaped on drop.
#[derive(Debug)]
pub struct Hog {
    child: Child,
    core: usize,
}

impl Hog {
    /// Starts a busy loop on `core`.
    ///
    /// # Errors
    ///
    /// The shell could not be started, or the core refused (`sched_setaffinity`: no such
    /// core, or not in this process's cpuset).
    pub fn start(core: usize) -> std::io::Result<Hog> {
        if core >= libc::CPU_SETSIZE as usize {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("core {core} is past CPU_SETSIZE"),
            ));
        }
        let parent = std::process::id() as libc::pid_t;
        let mut cmd = Command::new("/bin/sh");
        cmd.args(["-c", "while :; do :; done"])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        // SAFETY: the closure runs in the child between fork and exec and only calls
        // sched_setaffinity, sched_setscheduler, prctl, getppid and _exit (system calls,
        // async-signal-safe) on a cpu_set_t and a sched_param on its own stack; it does
        // not allocate.
        unsafe {
            cmd.pre_exec(move || {
                let mut set: libc::cpu_set_t = std::mem::zeroed();
                libc::CPU_SET(core, &mut set);
                if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                let param = libc::sched_param { sched_priority: 0 };
                if libc::sched_setscheduler(0, libc::SCHED_OTHER, &param) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // This process died before the setting took effect: no signal will come.
                if libc::getppid() != parent {
                    libc::_exit(1);
                }
                Ok(())
            });
        }
        let child = cmd.spawn()?;
        Ok(Hog { child, core })
    }

    /// The busy loop's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// The core it is pinned to.
    pub fn core(&self) -> usize {
        self.core
    }
}

impl Drop for Hog {
    fn drop(&mut self) {
        // Both fail only when it has already ended (and then `wait` reaps it).
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alive(pid: u32) -> bool {
        // SAFETY: signal 0 only checks that the process exists.
        unsafe { libc::kill(pid as libc::pid_t, 0) == 0 }
    }

    #[test]
    fn a_hog_runs_on_its_core_and_is_gone_once_dropped() {
        let hog = Hog::start(0).expect("a shell on core 0");
        let pid = hog.pid();
        assert_eq!(hog.core(), 0);
        assert!(alive(pid));
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
        let allowed = status
            .lines()
            .find_map(|l| l.strip_prefix("Cpus_allowed_list:"))
            .map(str::trim)
            .unwrap_or_default()
            .to_string();
        drop(hog);
        assert!(!alive(pid), "pid {pid} still exists after the drop");
        assert!(!std::path::Path::new(&format!("/proc/{pid}")).exists());
        // `spawn` returns once the shell has been exec'ed, so the affinity was set.
        assert_eq!(allowed, "0");
    }

    #[test]
    fn a_core_past_the_set_is_refused() {
        assert!(Hog::start(libc::CPU_SETSIZE as usize).is_err());
    }
}
