//! The real-time plant's sample clock, and what it does when the plant itself wakes late.
//!
//! Samples are due at `t_k = t_0 + kT` on `CLOCK_MONOTONIC`. When the plant process wakes
//! from its sleep until `t_k` more than one period late (the machine did not schedule it),
//! the samples it missed were never taken by anyone: a simulated plant that was not running
//! cannot have advanced its physics. `proxy.overrun` says what the clock does then:
//!
//! - `"slip"` ([`Overrun::Slip`], the default): the clock is re-based, `t_0 += lateness`,
//!   so sample `k` is taken now and the later ones follow at `T` from it. The slip is counted
//!   ([`SampleClock::slips`], [`SampleClock::slipped_ns`]) and reported once, at the end of the
//!   run. The simulation still advances exactly `T` per sample.
//! - `"catch-up"` ([`Overrun::CatchUp`]): the schedule is kept; the overdue samples are
//!   published back to back, with no time for the service to answer them (each counts as
//!   the service's miss).
//!
//! A wake-up less than a period late is ordinary jitter and changes nothing.

use ipc_types::clock::{monotonic_ns, sleep_until_ns};
use serde::{Deserialize, Serialize};

/// What the real-time plant does when it wakes more than a period late (`proxy.overrun`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Overrun {
    /// Re-base the clock: take the sample now, the next ones at `T` from it.
    #[default]
    Slip,
    /// Keep the schedule: publish the overdue samples back to back.
    CatchUp,
}

impl Overrun {
    /// The name used in the configuration (`"slip"`, `"catch-up"`).
    pub const fn name(self) -> &'static str {
        match self {
            Overrun::Slip => "slip",
            Overrun::CatchUp => "catch-up",
        }
    }
}

/// The schedule `t_k = t_0 + kT` with its slips. See the [module documentation](self).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleClock {
    t0_ns: u64,
    period_ns: u64,
    overrun: Overrun,
    slips: u64,
    slipped_ns: u64,
}

impl SampleClock {
    /// A clock whose sample 0 is due at `t0_ns`, one sample every `period_ns`.
    pub const fn new(t0_ns: u64, period_ns: u64, overrun: Overrun) -> Self {
        Self {
            t0_ns,
            period_ns,
            overrun,
            slips: 0,
            slipped_ns: 0,
        }
    }

    /// When sample `k` is due, ns.
    pub const fn due(&self, k: u64) -> u64 {
        self.t0_ns.saturating_add(k.saturating_mul(self.period_ns))
    }

    /// The sample time of sample `k` for a plant that woke at `now_ns` to take it: the due
    /// time, or, under [`Overrun::Slip`] when `now_ns` is more than a period past it, `now_ns`
    /// itself (the clock is re-based and the slip counted).
    pub fn woke(&mut self, k: u64, now_ns: u64) -> u64 {
        let due = self.due(k);
        let late = now_ns.saturating_sub(due);
        if self.overrun == Overrun::Slip && late > self.period_ns {
            self.t0_ns = self.t0_ns.saturating_add(late);
            self.slips += 1;
            self.slipped_ns = self.slipped_ns.saturating_add(late);
            self.due(k)
        } else {
            due
        }
    }

    /// Sleeps until sample `k` is due and returns its sample time ([`SampleClock::woke`]).
    pub fn wait(&mut self, k: u64) -> u64 {
        sleep_until_ns(self.due(k));
        self.woke(k, monotonic_ns())
    }

    /// How many times the clock was re-based.
    pub const fn slips(&self) -> u64 {
        self.slips
    }

    /// The total time it was re-based by, ns.
    pub const fn slipped_ns(&self) -> u64 {
        self.slipped_ns
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 1_000;

    #[test]
    fn a_wake_up_more_than_a_period_late_rebases_the_clock_under_slip() {
        let mut c = SampleClock::new(10_000, T, Overrun::Slip);
        assert_eq!(c.woke(0, 10_000), 10_000);
        // Jitter up to one period changes nothing.
        assert_eq!(c.woke(1, 11_000 + T), 11_000);
        // 3.5 periods late at sample 2: sample 2 is taken now, 3 follows at T from it.
        assert_eq!(c.woke(2, 12_000 + 3_500), 15_500);
        assert_eq!(c.due(3), 16_500);
        assert_eq!((c.slips(), c.slipped_ns()), (1, 3_500));
        assert_eq!(c.woke(3, 16_500), 16_500);
    }

    #[test]
    fn catch_up_keeps_the_schedule() {
        let mut c = SampleClock::new(10_000, T, Overrun::CatchUp);
        assert_eq!(c.woke(2, 12_000 + 3_500), 12_000);
        assert_eq!(c.due(3), 13_000);
        assert_eq!((c.slips(), c.slipped_ns()), (0, 0));
    }

    #[test]
    fn the_schedule_saturates_instead_of_overflowing() {
        let mut c = SampleClock::new(u64::MAX - 10, T, Overrun::Slip);
        assert_eq!(c.due(u64::MAX), u64::MAX);
        assert_eq!(c.woke(5, u64::MAX), u64::MAX);
    }
}
