//! Steal time: how long the hypervisor ran something else while a virtual CPU wanted to
//! run, from the per-CPU `cpuN` lines of `/proc/stat`.
//!
//! A `cpuN` line holds `user nice system idle iowait irq softirq steal guest guest_nice`
//! in `USER_HZ` ticks (`sysconf(_SC_CLK_TCK)`, 100 on Linux); `steal` is the 8th value.
//! On bare metal it stays 0. A steal interval on the RT core is an interval in which the
//! RT thread could not run, whatever its priority.

/// The steal counter of every CPU at one moment, in ticks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StealTicks {
    /// `(cpu, steal ticks)` for each `cpuN` line, in file order.
    pub per_cpu: Vec<(usize, u64)>,
}

/// The steal counters of a `/proc/stat` text; `None` when it has no `cpuN` line with a
/// steal value.
pub fn parse_proc_stat(text: &str) -> Option<StealTicks> {
    let per_cpu: Vec<(usize, u64)> = text
        .lines()
        .filter_map(|l| {
            let mut f = l.split_whitespace();
            let cpu: usize = f.next()?.strip_prefix("cpu")?.parse().ok()?;
            let steal: u64 = f.nth(7)?.parse().ok()?;
            Some((cpu, steal))
        })
        .collect();
    (!per_cpu.is_empty()).then_some(StealTicks { per_cpu })
}

/// `USER_HZ`, the unit of `/proc/stat` and of a task's `utime`/`stime`.
pub fn user_hz() -> u64 {
    // SAFETY: sysconf only reads a constant.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if hz > 0 { hz as u64 } else { 100 }
}

impl StealTicks {
    /// This machine's counters now; `None` when `/proc/stat` cannot be read.
    pub fn read() -> Option<Self> {
        parse_proc_stat(&std::fs::read_to_string("/proc/stat").ok()?)
    }

    /// Steal seconds from `earlier` to `self` on `core` (`None`: no such CPU in both,
    /// or no core) and summed over every CPU in both readings, at `hz` ticks a second.
    pub fn since(&self, earlier: &StealTicks, core: Option<usize>, hz: u64) -> StealOver {
        let hz = hz.max(1) as f64;
        let delta = |cpu: usize| {
            let now = self.per_cpu.iter().find(|(c, _)| *c == cpu)?.1;
            let then = earlier.per_cpu.iter().find(|(c, _)| *c == cpu)?.1;
            Some(now.saturating_sub(then))
        };
        let total: u64 = self.per_cpu.iter().filter_map(|(c, _)| delta(*c)).sum();
        StealOver {
            rt_core_s: core.and_then(delta).map(|t| t as f64 / hz),
            all_cpus_s: Some(total as f64 / hz),
        }
    }
}

/// Steal time over an interval, s; `None`: unknown.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct StealOver {
    /// On the RT core.
    pub rt_core_s: Option<f64>,
    /// Summed over all CPUs.
    pub all_cpus_s: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    const START: &str = "cpu  109227 0 14286 4798801 510 0 100 1305 0 0\n\
        cpu0 55201 0 6055 2400633 126 0 13 609 0 0\n\
        cpu1 54026 0 8230 2398167 384 0 86 696 0 0\n\
        intr 123 4 5\nctxt 99\n";
    const END: &str = "cpu  109300 0 14300 4798900 510 0 100 1330 0 0\n\
        cpu0 55250 0 6060 2400700 126 0 13 614 0 0\n\
        cpu1 54050 0 8240 2398200 384 0 86 716 0 0\n";

    #[test]
    fn the_eighth_value_of_each_cpu_line_is_its_steal() {
        let s = parse_proc_stat(START).unwrap();
        assert_eq!(s.per_cpu, vec![(0, 609), (1, 696)]);
        assert_eq!(parse_proc_stat("cpu  1 2 3 4 5 6 7 8\nintr 1\n"), None);
        assert_eq!(parse_proc_stat("cpu0 1 2 3\n"), None);
        assert_eq!(parse_proc_stat(""), None);
    }

    #[test]
    fn steal_over_a_run_is_the_difference_in_seconds() {
        let (a, b) = (
            parse_proc_stat(START).unwrap(),
            parse_proc_stat(END).unwrap(),
        );
        let s = b.since(&a, Some(1), 100);
        assert_eq!(s.rt_core_s, Some(0.2));
        assert_eq!(s.all_cpus_s, Some(0.25));
        assert_eq!(b.since(&a, Some(7), 100).rt_core_s, None);
        assert_eq!(b.since(&a, None, 100).rt_core_s, None);
    }
}
