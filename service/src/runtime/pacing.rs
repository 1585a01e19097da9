//! How the RT thread waits for the next sample: the [`Pacer`].
//!
//! The plant is the clock master: sample `k + 1` is due one period `T` after sample `k`,
//! whose sample time `t_k` it publishes (`t_sample_ns`, `CLOCK_MONOTONIC` on the same
//! box). Three ways to wait ([`WaitMode`]):
//!
//! | mode | between samples | preempts `SCHED_OTHER` work on its core | RT throttling |
//! | --- | --- | --- | --- |
//! | `sleep-poll` (default) | sleeps until `t_k + T − w`, then polls for at most `w + T/2`; an overdue plant is looked for every `T/8` | yes (at `SCHED_FIFO`: the timer wakes it) | never reached: it polls at most `(w + T/2) / T` of each period |
//! | `busy-poll` | polls | only at `SCHED_FIFO` | a `SCHED_FIFO` poller is stalled `1 − runtime/period` of each second (50 ms of 1 s by default) |
//! | `block` | sleeps on the plant's iceoryx2 event | yes (at `SCHED_FIFO`) | never reached |
//!
//! `w` is `service.poll-window` (default 40 µs, at most `T/3`): it must cover the timer's
//! wake-up latency on the box (`cyclictest` measures it), so that the thread is polling
//! when the sample comes. With `sleep-poll` the loop wakes about `w` before the sample
//! instead of after the plant's notification (`block`), and, unlike `busy-poll` at
//! `SCHED_FIFO`, it never spends the throttling budget: the core is given back to other
//! work for `T − w − (the plant's publish latency) − (the step)` of every period.
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
}

impl Pacer {
    /// The pacer of `mode` at sample period `period_ns` with the poll window `window_ns`
    /// (clamped to `[0, T/3]`).
    pub fn new(mode: WaitMode, period_ns: u64, window_ns: u64) -> Self {
        let period_ns = period_ns.max(1);
        Self {
            mode,
            period_ns,
            lead_ns: window_ns.min(period_ns / 3),
            overdue_ns: period_ns / 2,
            nap_ns: (period_ns / 8).max(1),
            block_timeout: Duration::from_nanos(period_ns.clamp(50_000, 100_000_000)),
            next_due_ns: None,
            lockstep: false,
        }
    }

    /// The mode it paces.
    pub fn mode(&self) -> WaitMode {
        self.mode
    }

    /// The largest share of a period it polls (`sleep-poll`; 1 for `busy-poll`, 0 for
    /// `block`).
    pub fn poll_share(&self) -> f64 {
        match self.mode {
            WaitMode::BusyPoll => 1.0,
            WaitMode::Block => 0.0,
            WaitMode::SleepPoll => {
                ((self.lead_ns + self.overdue_ns) as f64 / self.period_ns as f64).min(1.0)
            }
        }
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
                    let start = due.saturating_sub(self.lead_ns);
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
    fn the_window_is_at_most_a_third_of_the_period_and_bounds_the_polled_share() {
        let p = Pacer::new(WaitMode::SleepPoll, T, 1_000_000);
        let share = p.poll_share();
        assert!(
            (share - (T / 3 + T / 2) as f64 / T as f64).abs() < 1e-12,
            "{share}"
        );
        assert!(
            share < 0.95,
            "must stay inside the default throttling budget"
        );
        assert_eq!(Pacer::new(WaitMode::BusyPoll, T, 0).poll_share(), 1.0);
        assert_eq!(Pacer::new(WaitMode::Block, T, 0).poll_share(), 0.0);
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

    #[test]
    fn busy_poll_polls_and_block_blocks_on_the_event_when_there_is_one() {
        let p = Pacer::new(WaitMode::BusyPoll, T, 40_000);
        assert_eq!(p.next(0, true), WaitStep::Poll);
        let b = Pacer::new(WaitMode::Block, T, 40_000);
        assert_eq!(b.next(0, true), WaitStep::Block(Duration::from_micros(125)));
        assert_eq!(b.next(7, false), WaitStep::SleepUntil(7 + T / 8));
    }
}
