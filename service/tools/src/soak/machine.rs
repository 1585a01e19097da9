//! The machine a campaign ran on, as its results file states it: CPUs, kernel, RT
//! throttling and the load average at the start and at the end.

/// What `/proc` says about the machine; a file that cannot be read is `None` (printed as
/// `unknown`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Machine {
    /// Online CPUs (`sysconf(_SC_NPROCESSORS_ONLN)`, as `nproc` without a cpuset).
    pub nproc: Option<usize>,
    /// `/proc/sys/kernel/osrelease`.
    pub kernel: Option<String>,
    /// `/proc/sys/kernel/sched_rt_runtime_us` (`-1`: RT throttling off).
    pub sched_rt_runtime_us: Option<String>,
    /// The 1, 5 and 15 min load averages at the start (`/proc/loadavg`).
    pub load_start: Option<String>,
    /// The same at the end.
    pub load_end: Option<String>,
}

fn read_trimmed(path: &str) -> Option<String> {
    std::fs::read_to_string(path)
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
}

/// The three load averages of `/proc/loadavg`'s text.
pub fn parse_loadavg(text: &str) -> Option<String> {
    let v: Vec<&str> = text.split_whitespace().take(3).collect();
    (v.len() == 3).then(|| v.join(" "))
}

/// The load averages now.
pub fn load_average() -> Option<String> {
    read_trimmed("/proc/loadavg").and_then(|t| parse_loadavg(&t))
}

impl Machine {
    /// The machine now (the load at the start; [`Machine::load_end`] is filled later).
    pub fn now() -> Self {
        // SAFETY: sysconf only reads a system setting.
        let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
        Self {
            nproc: usize::try_from(n).ok().filter(|n| *n > 0),
            kernel: read_trimmed("/proc/sys/kernel/osrelease"),
            sched_rt_runtime_us: read_trimmed("/proc/sys/kernel/sched_rt_runtime_us"),
            load_start: load_average(),
            load_end: None,
        }
    }

    /// One Markdown paragraph.
    pub fn line(&self) -> String {
        let u = |v: &Option<String>| v.clone().unwrap_or_else(|| "unknown".into());
        format!(
            "Machine: {} CPUs online, kernel {}, `sched_rt_runtime_us` = {}; load average \
             (1, 5, 15 min) {} at the start, {} at the end.",
            self.nproc.map_or("unknown".to_string(), |n| n.to_string()),
            u(&self.kernel),
            u(&self.sched_rt_runtime_us),
            u(&self.load_start),
            u(&self.load_end)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn load_average_and_the_line() {
        assert_eq!(
            parse_loadavg("0.52 0.40 0.31 2/411 12345\n").as_deref(),
            Some("0.52 0.40 0.31")
        );
        assert_eq!(parse_loadavg("0.5"), None);
        let m = Machine {
            nproc: Some(2),
            kernel: Some("6.1.0".into()),
            sched_rt_runtime_us: Some("950000".into()),
            load_start: Some("0.52 0.40 0.31".into()),
            load_end: None,
        };
        assert_eq!(
            m.line(),
            "Machine: 2 CPUs online, kernel 6.1.0, `sched_rt_runtime_us` = 950000; load \
             average (1, 5, 15 min) 0.52 0.40 0.31 at the start, unknown at the end."
        );
    }
}
