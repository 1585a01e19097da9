//! How the RT thread waits for the next sample: the [`Pacer`].
//!
//! The plant is the clock master: sample `k + 1` is due one period `T` after sample `k`,
//! whose sample time `t_k` it publishes (`t_sample_ns`, `CLOCK_MONOTONIC` on the same
//! box). Three ways to wait ([`WaitMode`]):
//!
//! | mode | between samples | preempts `SCHED_OTHER` work on its core | RT throttling |
//! | --- | --- | --- | --- |
//! | `sleep-poll` (default) | sleeps until `t_k + T − w`, then polls for at most `w + T/2`; an overdue plant is looked for every `T/8` | yes (at `SCHED_FIFO`: the timer wakes it) | kept off it by the awake-share cap below |
//! | `busy-poll` | polls | only at `SCHED_FIFO` | a `SCHED_FIFO` poller is stalled `1 − runtime/period` of each second (50 ms of 1 s by default) |
//! | `block` | sleeps on the plant's iceoryx2 event | yes (at `SCHED_FIFO`) | never reached |
//!
//! `w` is `service.poll-window` (default 40 µs, at most `T/3`): it must cover the timer's
//! wake-up latency on the box (`cyclictest` measures it), so that the thread is polling
//! when the sample comes. With `sleep-poll` the loop wakes about `w` before the sample
//! instead of after the plant's notification (`block`), and, unlike `busy-poll` at
//! `SCHED_FIFO`, the core is given back to other work for `T − w − (the plant's publish
//! latency) − (the step)` of every period.
//!
//! **The awake-share cap.** That give-back shrinks when the plant publishes late (a loaded
//! plant core) or the step is long: the thread then polls until the sample comes, and at
//! `SCHED_FIFO` with RT throttling on (`ρ = sched_rt_runtime_us / sched_rt_period_us`,
//! 0.95 by default) a second in which it is awake more than `ρ` of the time ends in a stall
//! of `(1 − ρ)` s — 400 lost samples at 8 kHz. So a throttled `SCHED_FIFO` sleep-poller
//! caps its awake share at `c = ρ − 0.10` ([`AWAKE_MARGIN`]): over each window of
//! [`AWAKE_WINDOW`] samples it measures the share `a` of wall time it was not asleep; when
//! `a > c` it starts polling `(a − c) · T` later (the lead `w` shrinks, and may go past the
//! due time down to `t_k + T + T/4`, [`MAX_LATE_START`]), and when `a < c − 0.05` it gives
//! back `T/256` of lead per window. A sample that comes before the thread polls is found
//! when it wakes, later by at most the cut: the price of not being stalled for 50 ms. The
//! figures (peak share, windows over the cap, the deepest cut) go into the run report
//! ([`PacingReport`]).
//!
//! A lockstep plant (`LOCKSTEP` flag) publishes its next sample as soon as it has the
//! answer, not on a clock: `sleep-poll` then waits on the plant's event, as `block` does,
//! so that a lockstep run goes as fast as the two processes can.
//!
//! The anchor of the next due time is `t_k` when it is plausible (at or before the receipt
//! and less than two periods before it), else the receipt time: a plant whose clock is not
//! this box's `CLOCK_MONOTONIC` is still paced, one publish latency later.
//!
//! The pacer is plain data: [`Pacer::next`] says what to do from the time it is given,
//! and the RT loop does it; so the policy is tested without a clock.

use crate::config::WaitMode;
use core::time::Duration;
use serde::Serialize;

/// Samples per window of the awake-share measurement (32 ms at 8 kHz).
pub const AWAKE_WINDOW: u32 = 256;

/// The cap sits this far under the throttling budget `ρ`.
pub const AWAKE_MARGIN: f64 = 0.10;

/// Below `c − AWAKE_HYSTERESIS` the lead is given back.
pub const AWAKE_HYSTERESIS: f64 = 0.05;

/// The latest the poll may start, as a fraction of `T` past the due time.
pub const MAX_LATE_START: f64 = 0.25;

/// What the RT loop does next while no sample is waiting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitStep {
    /// Look for a sample again now (spin).
    Poll,
    /// Sleep until this `CLOCK_MONOTONIC` time (ns), then look.
    SleepUntil(u64),
    /// Sleep on the plant's event for at most this long, then look.
    Block(Duration),
}

/// The waiting policy of the module docs for one RT loop.
#[derive(Debug, Clone)]
pub struct Pacer {
    mode: WaitMode,
    period_ns: u64,
    /// `w`: polling starts this long before the sample is due.
    lead_ns: u64,
    /// Polling stops this long after the sample was due.
    overdue_ns: u64,
    /// Between looks for an overdue sample.
    nap_ns: u64,
    block_timeout: Duration,
    /// `t_k + T` of the last sample, once there is one.
    next_due_ns: Option<u64>,
    /// The last sample came from a lockstep plant.
    lockstep: bool,
    /// The awake-share cap `c` (module docs), when it applies.
    cap: Option<f64>,
    /// How much later than `t_k + T − w` the poll starts now, ns (0 ..= w + T/4).
    cut_ns: u64,
    /// The current measurement window: its start, its samples, the time asleep in it.
    window_start_ns: Option<u64>,
    window_samples: u32,
    asleep_ns: u64,
    /// What the report shows.
    report: PacingReport,
}

/// What the awake-share cap did over a run (module docs), for the run report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PacingReport {
    /// The cap `c` (share of wall time), `None` when it did not apply (not `SCHED_FIFO`,
    /// throttling off, `busy-poll` or `block`).
    pub awake_cap: Option<f64>,
    /// The configured lead `w`, µs.
    pub poll_window_us: f64,
    /// The shortest lead it came to, µs (negative: polling started after the due time).
    pub least_lead_us: f64,
    /// Windows of [`AWAKE_WINDOW`] samples measured (lockstep samples are not paced).
    pub windows: u64,
    /// The largest awake share of a window.
    pub peak_awake_share: f64,
    /// Windows whose awake share was over the cap.
    pub windows_over_cap: u64,
    /// Of those, the windows in which the poll already started as late as allowed.
    pub windows_over_cap_at_limit: u64,
}

impl PacingReport {
    /// A warning when the thread stayed over the cap with its poll already as late as
    /// allowed: the step (or the plant's lateness) alone keeps it near the throttling
    /// budget, and the kernel may have stalled it.
    pub fn throttling_risk(&self) -> Option<String> {
        let cap = self.awake_cap?;
        (self.windows_over_cap_at_limit > 0).then(|| {
            format!(
                "RT THROTTLING RISK: in {} of {} windows the RT thread was awake more than its cap \
                 of {:.0} % (peak {:.1} %) with its poll already starting {:.1} µs after the due \
                 time; the kernel's RT throttling stalls it for the rest of a second in which it \
                 reaches the budget (a shorter step, a less loaded plant core, or \
                 sched_rt_runtime_us = -1 on an isolated core)",
                self.windows_over_cap_at_limit,
                self.windows,
                100.0 * cap,
                100.0 * self.peak_awake_share,
                -self.least_lead_us
            )
        })
    }

    /// One line for the run report.
    pub fn line(&self, wait: &str) -> String {
        let Some(cap) = self.awake_cap else {
            return format!(
                "pacing: {wait}, poll window {:.1} µs, no awake-share cap (not SCHED_FIFO with RT throttling on, or not sleep-poll)",
                self.poll_window_us
            );
        };
        format!(
            "pacing: {wait}, awake-share cap {:.0} % (RT budget less {:.0} %); poll window {:.1} µs, \
             least lead {:.1} µs; awake share peak {:.1} % over {} windows of {AWAKE_WINDOW} samples, \
             {} over the cap ({} with the poll already as late as allowed)",
            100.0 * cap,
            100.0 * AWAKE_MARGIN,
            self.poll_window_us,
            self.least_lead_us,
            100.0 * self.peak_awake_share,
            self.windows,
            self.windows_over_cap,
            self.windows_over_cap_at_limit
        )
    }
}

impl Pacer {
    /// The pacer of `mode` at sample period `period_ns` with the poll window `window_ns`
    /// (clamped to `[0, T/3]`).
    pub fn new(mode: WaitMode, period_ns: u64, window_ns: u64) -> Self {
        let period_ns = period_ns.max(1);
        let lead_ns = window_ns.min(period_ns / 3);
        Self {
            mode,
            period_ns,
            lead_ns,
            overdue_ns: period_ns / 2,
            nap_ns: (period_ns / 8).max(1),
            block_timeout: Duration::from_nanos(period_ns.clamp(50_000, 100_000_000)),
            next_due_ns: None,
            lockstep: false,
            cap: None,
            cut_ns: 0,
            window_start_ns: None,
            window_samples: 0,
            asleep_ns: 0,
            report: PacingReport {
                poll_window_us: lead_ns as f64 * 1e-3,
                least_lead_us: lead_ns as f64 * 1e-3,
                ..Default::default()
            },
        }
    }

    /// Caps the awake share under the throttling budget `rho` (module docs); `None` (RT
    /// throttling off, or the thread is not `SCHED_FIFO`) leaves it uncapped. Only
    /// `sleep-poll` has a share to cap.
    pub fn with_throttling_budget(mut self, rho: Option<f64>) -> Self {
        self.cap = rho
            .filter(|r| r.is_finite() && *r > AWAKE_MARGIN && self.mode == WaitMode::SleepPoll)
            .map(|r| r - AWAKE_MARGIN);
        self.report.awake_cap = self.cap;
        self
    }

    /// The throttling budget `ρ` of this box when `fifo` (the thread runs at
    /// `SCHED_FIFO`) and RT throttling is on; else `None`.
    pub fn throttling_budget(fifo: bool) -> Option<f64> {
        let (runtime, period) = ipc_types::rt::rt_throttling()?;
        (fifo && period > 0).then(|| runtime as f64 / period as f64)
    }

    /// What the cap did so far.
    pub fn report(&self) -> PacingReport {
        self.report
    }

    /// The thread slept (or blocked) from `from_ns` to `to_ns`.
    #[inline]
    pub fn slept(&mut self, from_ns: u64, to_ns: u64) {
        self.asleep_ns = self.asleep_ns.saturating_add(to_ns.saturating_sub(from_ns));
    }

    /// The largest cut: the poll starts at most `T/4` after the due time.
    fn max_cut_ns(&self) -> u64 {
        self.lead_ns + (MAX_LATE_START * self.period_ns as f64) as u64
    }

    /// Closes a measurement window at `now_ns` when it is full, and moves the cut.
    fn measure(&mut self, now_ns: u64) {
        let Some(cap) = self.cap else { return };
        let Some(start) = self.window_start_ns else {
            self.window_start_ns = Some(now_ns);
            self.window_samples = 0;
            self.asleep_ns = 0;
            return;
        };
        self.window_samples += 1;
        if self.window_samples < AWAKE_WINDOW {
            return;
        }
        let wall = now_ns.saturating_sub(start).max(1);
        let share = 1.0 - (self.asleep_ns.min(wall) as f64 / wall as f64);
        let max_cut = self.max_cut_ns();
        let r = &mut self.report;
        r.windows += 1;
        r.peak_awake_share = r.peak_awake_share.max(share);
        if share > cap {
            r.windows_over_cap += 1;
            if self.cut_ns >= max_cut {
                r.windows_over_cap_at_limit += 1;
            }
            let more = ((share - cap) * self.period_ns as f64) as u64;
            self.cut_ns = (self.cut_ns + more.max(1)).min(max_cut);
        } else if share < cap - AWAKE_HYSTERESIS {
            self.cut_ns = self.cut_ns.saturating_sub((self.period_ns / 256).max(1));
        }
        let lead = self.lead_ns as f64 - self.cut_ns as f64;
        r.least_lead_us = r.least_lead_us.min(lead * 1e-3);
        self.window_start_ns = Some(now_ns);
        self.window_samples = 0;
        self.asleep_ns = 0;
    }

    /// The mode it paces.
    pub fn mode(&self) -> WaitMode {
        self.mode
    }

    /// A sample with sample time `t_sample_ns` was received at `t_recv_ns`: the next is due
    /// one period after it (module docs, the anchor); `lockstep`: its plant runs in lockstep.
    pub fn on_sample(&mut self, t_sample_ns: u64, t_recv_ns: u64, lockstep: bool) {
        self.lockstep = lockstep;
        let plausible = t_sample_ns <= t_recv_ns
            && t_recv_ns - t_sample_ns < 2 * self.period_ns
            && t_sample_ns > 0;
        let anchor = if plausible { t_sample_ns } else { t_recv_ns };
        self.next_due_ns = Some(anchor.saturating_add(self.period_ns));
        if lockstep {
            // Not paced: a window would mix lockstep ping-pong with real time.
            self.window_start_ns = None;
        } else {
            self.measure(t_recv_ns);
        }
    }

    /// What to do at `now_ns` with no sample waiting; `has_listener`: the plant's event can
    /// be waited on.
    pub fn next(&self, now_ns: u64, has_listener: bool) -> WaitStep {
        match self.mode {
            WaitMode::BusyPoll => WaitStep::Poll,
            WaitMode::Block if has_listener => WaitStep::Block(self.block_timeout),
            WaitMode::Block => WaitStep::SleepUntil(now_ns.saturating_add(self.nap_ns)),
            WaitMode::SleepPoll if self.lockstep && has_listener => {
                WaitStep::Block(self.block_timeout)
            }
            WaitMode::SleepPoll if self.lockstep => WaitStep::Poll,
            WaitMode::SleepPoll => match self.next_due_ns {
                None => WaitStep::SleepUntil(now_ns.saturating_add(self.nap_ns)),
                Some(due) => {
                    let start = (due + self.cut_ns).saturating_sub(self.lead_ns);
                    if now_ns < start {
                        WaitStep::SleepUntil(start)
                    } else if now_ns < due.saturating_add(self.overdue_ns) {
                        WaitStep::Poll
                    } else {
                        WaitStep::SleepUntil(now_ns.saturating_add(self.nap_ns))
                    }
                }
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 125_000;

    #[test]
    fn sleep_poll_sleeps_until_the_window_before_the_next_sample_then_polls() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000);
        p.on_sample(1_000_000, 1_020_000, false);
        let due = 1_000_000 + T;
        assert_eq!(p.next(1_030_000, false), WaitStep::SleepUntil(due - 40_000));
        assert_eq!(p.next(due - 40_000, false), WaitStep::Poll);
        assert_eq!(p.next(due + T / 2 - 1, false), WaitStep::Poll);
    }

    #[test]
    fn an_overdue_sample_is_looked_for_in_naps_not_by_spinning() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000);
        p.on_sample(1_000_000, 1_010_000, false);
        let late = 1_000_000 + T + T / 2;
        assert_eq!(p.next(late, false), WaitStep::SleepUntil(late + T / 8));
        assert_eq!(
            p.next(late + 10 * T, true),
            WaitStep::SleepUntil(late + 10 * T + T / 8)
        );
    }

    #[test]
    fn before_the_first_sample_it_naps() {
        let p = Pacer::new(WaitMode::SleepPoll, T, 40_000);
        assert_eq!(p.next(5, false), WaitStep::SleepUntil(5 + T / 8));
    }

    #[test]
    fn an_implausible_sample_time_anchors_on_the_receipt() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 0);
        // A plant clock from another time base (far in the past, or in the future).
        p.on_sample(10, 9_000_000, false);
        assert_eq!(
            p.next(9_000_001, false),
            WaitStep::SleepUntil(9_000_000 + T)
        );
        p.on_sample(50_000_000, 9_000_000, false);
        assert_eq!(
            p.next(9_000_001, false),
            WaitStep::SleepUntil(9_000_000 + T)
        );
    }

    #[test]
    fn the_window_is_at_most_a_third_of_the_period() {
        let p = Pacer::new(WaitMode::SleepPoll, T, 1_000_000);
        assert_eq!(p.report().poll_window_us, (T / 3) as f64 * 1e-3);
        assert_eq!(
            p.next(0, false),
            WaitStep::SleepUntil(T / 8),
            "no sample yet: it naps"
        );
    }

    #[test]
    fn a_lockstep_plant_is_waited_for_on_its_event() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000);
        p.on_sample(1_000_000, 1_010_000, true);
        assert_eq!(
            p.next(1_010_001, true),
            WaitStep::Block(Duration::from_micros(125))
        );
        assert_eq!(p.next(1_010_001, false), WaitStep::Poll);
    }

    /// Feeds `windows` full windows of samples, one per period from `t0`, with the thread
    /// asleep `asleep` of each period; returns the time after them.
    fn feed(p: &mut Pacer, t0: u64, windows: u32, asleep: u64) -> u64 {
        let mut t = t0;
        for _ in 0..windows * AWAKE_WINDOW + 1 {
            p.on_sample(t, t + 1_000, false);
            p.slept(t + 1_000, t + 1_000 + asleep);
            t += T;
        }
        t
    }

    #[test]
    fn over_the_awake_cap_the_poll_starts_later_by_the_excess() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000).with_throttling_budget(Some(0.95));
        assert_eq!(p.report().awake_cap, Some(0.85));
        // Asleep 5 % of each period: awake 95 %, 10 % over the cap of 85 %.
        let t = feed(&mut p, 1_000_000, 1, T / 20);
        let r = p.report();
        assert_eq!((r.windows, r.windows_over_cap), (1, 1));
        assert!((r.peak_awake_share - 0.95).abs() < 0.01, "{r:?}");
        // The cut is the excess times the period: 0.1 · 125 µs = 12.5 µs (± the window's
        // rounding).
        let due = t - T + T;
        match p.next(t - T + 1_001, false) {
            WaitStep::SleepUntil(start) => {
                let lead = due - start;
                assert!((26_500..=28_500).contains(&lead), "lead {lead} ns");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_cut_stops_a_quarter_period_after_the_due_time_and_counts_windows_at_the_limit() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000).with_throttling_budget(Some(0.95));
        let t = feed(&mut p, 1_000_000, 40, 0);
        let r = p.report();
        assert_eq!(r.windows, 40);
        assert_eq!(r.windows_over_cap, 40);
        assert!(r.windows_over_cap_at_limit > 0, "{r:?}");
        assert!(r.throttling_risk().unwrap().contains("RT THROTTLING RISK"));
        assert!((r.least_lead_us + 31.25).abs() < 1e-6, "{r:?}");
        let due = t;
        assert_eq!(
            p.next(t - T + 2_000, false),
            WaitStep::SleepUntil(due + T / 4)
        );
    }

    #[test]
    fn under_the_cap_the_lead_comes_back_slowly() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000).with_throttling_budget(Some(0.95));
        let t = feed(&mut p, 1_000_000, 1, T / 20);
        let cut = p.cut_ns;
        assert!(cut > 0);
        // Asleep half of each period: well under the cap; T/256 back per window.
        let _ = feed(&mut p, t, 2, T / 2);
        assert_eq!(p.cut_ns, cut - 2 * (T / 256));
        let r = p.report();
        assert_eq!((r.windows, r.windows_over_cap), (3, 1));
        assert_eq!(r.throttling_risk(), None);
    }

    #[test]
    fn no_cap_without_throttling_or_for_other_waits_and_lockstep_is_not_measured() {
        let mut p = Pacer::new(WaitMode::SleepPoll, T, 40_000).with_throttling_budget(None);
        let _ = feed(&mut p, 1_000_000, 3, 0);
        assert_eq!((p.report().windows, p.cut_ns), (0, 0));
        let b = Pacer::new(WaitMode::BusyPoll, T, 40_000).with_throttling_budget(Some(0.95));
        assert_eq!(b.report().awake_cap, None);
        let mut l = Pacer::new(WaitMode::SleepPoll, T, 40_000).with_throttling_budget(Some(0.95));
        let mut t = 1_000_000;
        for _ in 0..3 * AWAKE_WINDOW {
            l.on_sample(t, t + 1_000, true);
            t += T;
        }
        assert_eq!(l.report().windows, 0);
        assert!(l.report().line("SleepPoll").contains("cap 85 %"));
    }

    #[test]
    fn busy_poll_polls_and_block_blocks_on_the_event_when_there_is_one() {
        let p = Pacer::new(WaitMode::BusyPoll, T, 40_000);
        assert_eq!(p.next(0, true), WaitStep::Poll);
        let b = Pacer::new(WaitMode::Block, T, 40_000);
        assert_eq!(b.next(0, true), WaitStep::Block(Duration::from_micros(125)));
        assert_eq!(b.next(7, false), WaitStep::SleepUntil(7 + T / 8));
    }
}
