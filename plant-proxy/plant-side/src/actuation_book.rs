//! The plant's book of actuations: which input it applies for each sample.
//!
//! The service's answers do not arrive one per sample in order. A service that sends ahead
//! ([`ipc_types::Timing::SendAhead`]) publishes the input for sample `k + 1` as soon as it has taken
//! measurement `k` in, so it reaches the plant before measurement `k + 1` exists; an answer
//! can also come after its deadline, or carry a plan for the samples after its own
//! ([`Actuation::plan`]). The book keeps what the plant needs of them, and decides the
//! input of each sample:
//!
//! - [`ActuationBook::offer`] takes one received actuation while the plant is at sample
//!   `k` (the sample whose input it decides next). A valid actuation for sample `k` or a later
//!   one is **kept** (at most `N` of them, allocation-free; when full, the one received
//!   earliest is dropped: the newest are kept); one for an earlier sample is **late**
//!   (refused as an input, counted by the caller), but its plan may still cover later
//!   samples; an invalid one is refused; a stall acknowledgement is never an input.
//! - [`ActuationBook::decide`] gives the input for sample `k`: the actuation with `seq = k`
//!   if it has been offered (whenever it arrived), else a miss resolved by the
//!   [`MissPolicy`]: the newest plan's entry for `k`, or hold, or safe.
//! - [`ActuationBook::answers`] tells whether the service has answered (or acknowledged)
//!   measurement `k`: the lockstep plant waits for that before it publishes `k + 1`.
//!
//! **Valid** means [`timing_rules::actuation_valid`]; what an arriving actuation is,
//! [`timing_rules::arrival`]; which plan a miss uses, [`timing_rules::plan_supersedes`] and
//! [`timing_rules::plan_row`]; what it then applies, [`timing_rules::on_miss`]; which
//! measurement an actuation answers, [`timing_rules::answered_measurement`]. The book keeps
//! the state those rules need and calls them. Whether the actuation comes from the pinned service is the caller's check
//! ([`ipc_types::ports::Ports::admit`]) before it offers it.
//!
//! The book is pure: no IPC, no clock, no allocation after [`ActuationBook::new`], no panic.
//! It is what a DAQ process needs of the contract's timing besides its own clock.
//!
//! ```
//! use ipc_types::{Actuation, ChannelCounts, Timing};
//! use plant_side::actuation_book::{ActuationBook, Decision, Offer};
//! use plant_side::late_policy::{MissPolicy, PlanFallback};
//!
//! let counts = ChannelCounts::new(1, 1, 0, 1).unwrap();
//! let mut book = ActuationBook::<4>::new(1, MissPolicy::Plan(PlanFallback::Hold));
//! // Sent ahead: the input for sample 5 (with a plan for 6), answering measurement 4.
//! let mut a = Actuation::zeroed(counts);
//! (a.seq, a.reply_to, a.timing) = (5, 4, Timing::SendAhead.wire());
//! (a.u[0], a.plan_len, a.plan[0][0]) = (0.5, 1, 0.25);
//! assert_eq!(book.offer(&a, 4), Offer::Kept);
//! assert!(book.answers(4) && !book.answers(5));
//! assert!(matches!(book.decide(4), Decision::Hold)); // nothing for sample 4
//! assert!(matches!(book.decide(5), Decision::Answered { u, .. } if u[0] == 0.5));
//! assert!(matches!(book.decide(6), Decision::Plan { u, from_seq: 5, .. } if u[0] == 0.25));
//! ```

use crate::late_policy::MissPolicy;
use ipc_types::timing_rules::{self, Arrival, MissInput};
use ipc_types::{Actuation, MAX_U};

/// The capacity plant-proxy gives its book: actuations held for the current and later
/// samples. A service that sends ahead holds one or two there; more is a service running
/// far ahead of the plant, whose oldest entries are dropped.
pub const AHEAD_CAPACITY: usize = 8;

/// What [`ActuationBook::offer`] did with an actuation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offer {
    /// Kept as the input for its sample (the current one or a later one), replacing one
    /// received earlier for the same sample.
    Kept,
    /// Kept, and to make room the book dropped the actuation it had received earliest of
    /// those it held (for sample `dropped_seq`).
    KeptDropping {
        /// The sample of the dropped actuation.
        dropped_seq: u64,
    },
    /// For a sample whose input is already decided: refused as an input (a late answer).
    /// Its plan may still cover later samples.
    Late,
    /// Refused: another contract version, another `n_u`, `plan_len` past the capacity, or a
    /// non-finite `u` or plan entry (for an acknowledgement: version or `n_u`).
    Invalid,
    /// A stall acknowledgement ([`ipc_types::actuation_status::STALL_ACK`]): it ends the lockstep
    /// plant's wait for its `reply_to`; never an input.
    StallAck,
}

/// The input of one sample, from [`ActuationBook::decide`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decision {
    /// The actuation for the sample arrived in time: apply its `u`.
    Answered {
        /// The input (entries past `n_u` are zero).
        u: [f64; MAX_U],
        /// The actuation's [`Actuation::status`].
        status: u32,
        /// The actuation's [`Actuation::timing`] (wire value).
        timing: u32,
    },
    /// A miss covered by a plan: apply the newest plan's entry for the sample.
    Plan {
        /// The input (entries past `n_u` are zero).
        u: [f64; MAX_U],
        /// The `seq` of the actuation whose plan it is.
        from_seq: u64,
        /// The plan row (`k − from_seq − 1`).
        row: usize,
    },
    /// A miss: hold the input applied for the previous sample.
    Hold,
    /// A miss: apply the safe input.
    Safe,
}

impl Decision {
    /// True unless the actuation for the sample was there ([`Decision::Answered`]).
    pub const fn is_miss(&self) -> bool {
        !matches!(self, Decision::Answered { .. })
    }

    /// The miss's input by [`timing_rules::on_miss`]; `None` for [`Decision::Answered`].
    pub const fn miss_input(&self) -> Option<MissInput> {
        match self {
            Decision::Answered { .. } => None,
            Decision::Plan { row, .. } => Some(MissInput::PlanRow(*row)),
            Decision::Hold => Some(MissInput::Hold),
            Decision::Safe => Some(MissInput::Safe),
        }
    }
}

/// The actuations a plant holds for the current and later samples, the newest plan, and how
/// far the service has answered; `N` is the capacity for actuations held ahead (at least 1,
/// checked at compile time). See the [module documentation](self).
#[derive(Debug, Clone)]
pub struct ActuationBook<const N: usize> {
    n_u: usize,
    policy: MissPolicy,
    held: [Option<Actuation>; N],
    /// Arrival stamp of each held actuation (larger is newer).
    arrival: [u64; N],
    arrivals: u64,
    /// The newest valid actuation for an already decided sample: the plan on a miss.
    plan_source: Option<Actuation>,
    /// The latest measurement a valid actuation answered.
    answered: Option<u64>,
    /// The latest measurement a stall acknowledgement acknowledged.
    acknowledged: Option<u64>,
    /// The newest valid actuation's timing sends ahead (`lead` ≥ 1).
    sends_ahead: bool,
}

impl<const N: usize> ActuationBook<N> {
    /// An empty book for a plant with `n_u` inputs (clamped to [`MAX_U`]) deciding misses by
    /// `policy`.
    pub fn new(n_u: usize, policy: MissPolicy) -> Self {
        const { assert!(N > 0, "an ActuationBook holds at least one actuation") };
        Self {
            n_u: n_u.min(MAX_U),
            policy,
            held: [None; N],
            arrival: [0; N],
            arrivals: 0,
            plan_source: None,
            answered: None,
            acknowledged: None,
            sends_ahead: false,
        }
    }

    /// The policy of a miss.
    pub const fn policy(&self) -> MissPolicy {
        self.policy
    }

    /// Forgets everything: the held actuations, the plan and how far the service answered
    /// (a new service took over; what the old one sent is not the new one's).
    pub fn clear(&mut self) {
        self.held = [None; N];
        self.plan_source = None;
        self.answered = None;
        self.acknowledged = None;
        self.sends_ahead = false;
    }

    /// Takes the actuation `a` received while the plant is at sample `k` (the sample whose
    /// input [`ActuationBook::decide`] gives next). See [`Offer`].
    pub fn offer(&mut self, a: &Actuation, k: u64) -> Offer {
        let arrival = timing_rules::arrival(a, self.n_u, k);
        match arrival {
            Arrival::StallAck => {
                self.acknowledged = self.acknowledged.max(Some(a.reply_to));
                return Offer::StallAck;
            }
            Arrival::Invalid => return Offer::Invalid,
            Arrival::Late | Arrival::InTime => {}
        }
        let answered = timing_rules::answered_measurement(a.seq, a.reply_to, a.timing);
        self.answered = self.answered.max(Some(answered));
        self.sends_ahead = a.timing().is_some_and(|t| t.lead() > 0);
        if arrival == Arrival::Late {
            self.consider_plan(a);
            return Offer::Late;
        }
        self.arrivals += 1;
        let slot = self
            .held
            .iter()
            .position(|h| h.is_some_and(|h| h.seq == a.seq))
            .or_else(|| self.held.iter().position(Option::is_none));
        let (i, outcome) = match slot {
            Some(i) => (i, Offer::Kept),
            None => {
                // Full: drop the one received earliest.
                let mut oldest = 0;
                for i in 1..N {
                    if self.arrival[i] < self.arrival[oldest] {
                        oldest = i;
                    }
                }
                let dropped_seq = self.held[oldest].map_or(0, |h| h.seq);
                (oldest, Offer::KeptDropping { dropped_seq })
            }
        };
        self.held[i] = Some(*a);
        self.arrival[i] = self.arrivals;
        outcome
    }

    /// The input for sample `k`: the actuation with `seq = k` if it was offered, else the
    /// miss policy's answer. Call it once per sample, with `k` increasing; held actuations
    /// for earlier samples are retired (they become plan candidates).
    pub fn decide(&mut self, k: u64) -> Decision {
        let mut answer = None;
        for i in 0..N {
            let Some(h) = self.held[i] else { continue };
            if h.seq <= k {
                self.held[i] = None;
                self.consider_plan(&h);
                if h.seq == k {
                    answer = Some(h);
                }
            }
        }
        if let Some(a) = answer {
            return Decision::Answered {
                u: self.used(&a.u),
                status: a.status,
                timing: a.timing,
            };
        }
        let row = self
            .plan_source
            .as_ref()
            .and_then(|p| timing_rules::plan_row(p.seq, p.plan_len, k));
        match (timing_rules::on_miss(self.policy, row), &self.plan_source) {
            (MissInput::PlanRow(j), Some(p)) => Decision::Plan {
                u: self.used(&p.plan[j]),
                from_seq: p.seq,
                row: j,
            },
            (MissInput::Safe, _) => Decision::Safe,
            _ => Decision::Hold,
        }
    }

    /// True when the service has answered measurement `k` (a valid actuation that answers
    /// it or a later one) or acknowledged it as a stall ([`Offer::StallAck`] with
    /// `reply_to ≥ k`).
    ///
    /// The measurement an actuation answers is its [`Actuation::reply_to`], or
    /// `seq − lead` of its timing (`lead` = 1 for send-ahead, else 0) when that is larger;
    /// the two agree for a service that follows the contract, and the second keeps a service
    /// that leaves `reply_to` at 0 from stalling a lockstep plant.
    pub fn answers(&self, k: u64) -> bool {
        self.answered.is_some_and(|a| a >= k) || self.acknowledged.is_some_and(|a| a >= k)
    }

    /// True when the newest valid actuation came from a service that sends each input one
    /// sample ahead ([`ipc_types::Timing::SendAhead`]).
    pub fn sends_ahead(&self) -> bool {
        self.sends_ahead
    }

    /// True when the book holds an actuation for sample `seq`.
    pub fn holds(&self, seq: u64) -> bool {
        self.held.iter().any(|h| h.is_some_and(|h| h.seq == seq))
    }

    /// How many actuations the book holds for the current and later samples.
    pub fn len(&self) -> usize {
        self.held.iter().filter(|h| h.is_some()).count()
    }

    /// True when it holds none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `seq` of the actuation whose plan a miss would use now, if any.
    pub fn plan_seq(&self) -> Option<u64> {
        self.plan_source.as_ref().map(|p| p.seq)
    }

    fn consider_plan(&mut self, a: &Actuation) {
        if timing_rules::plan_supersedes(self.plan_source.map(|p| p.seq), a.seq) {
            self.plan_source = Some(*a);
        }
    }

    fn used(&self, u: &[f64; MAX_U]) -> [f64; MAX_U] {
        let mut out = [0.0; MAX_U];
        out[..self.n_u].copy_from_slice(&u[..self.n_u]);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::late_policy::PlanFallback;
    use ipc_types::ChannelCounts;
    use ipc_types::{CONTRACT_VERSION, MAX_PLAN, Timing, actuation_status};

    fn act(seq: u64, reply_to: u64, u: f64, plan: &[f64]) -> Actuation {
        let mut a = Actuation::zeroed(ChannelCounts::new(1, 1, 0, 1).unwrap());
        a.seq = seq;
        a.reply_to = reply_to;
        a.timing = Timing::SendAhead.wire();
        a.u[0] = u;
        a.plan_len = plan.len() as u32;
        for (e, v) in a.plan.iter_mut().zip(plan) {
            e[0] = *v;
        }
        a
    }

    fn book(policy: MissPolicy) -> ActuationBook<4> {
        ActuationBook::new(1, policy)
    }

    fn answered(d: Decision) -> Option<f64> {
        match d {
            Decision::Answered { u, .. } => Some(u[0]),
            _ => None,
        }
    }

    fn planned(d: Decision) -> Option<(f64, u64)> {
        match d {
            Decision::Plan { u, from_seq, .. } => Some((u[0], from_seq)),
            _ => None,
        }
    }

    #[test]
    fn an_actuation_received_ahead_is_applied_at_its_sample() {
        let mut b = book(MissPolicy::Hold);
        // Received while the plant is at sample 3: the inputs for 4 and 5.
        assert_eq!(b.offer(&act(4, 3, 4.0, &[]), 3), Offer::Kept);
        assert_eq!(b.offer(&act(5, 3, 5.0, &[]), 3), Offer::Kept);
        assert!(b.holds(4) && b.holds(5) && !b.holds(3));
        assert_eq!(b.decide(3), Decision::Hold, "nothing for sample 3");
        assert_eq!(answered(b.decide(4)), Some(4.0));
        assert_eq!(answered(b.decide(5)), Some(5.0));
        assert!(b.is_empty());
        assert_eq!(b.decide(6), Decision::Hold);
    }

    #[test]
    fn an_answer_keeps_its_status_and_timing() {
        let mut b = book(MissPolicy::Hold);
        let mut a = act(2, 2, 1.5, &[]);
        a.status = actuation_status::SATURATED;
        b.offer(&a, 2);
        assert_eq!(
            b.decide(2),
            Decision::Answered {
                u: [1.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                status: actuation_status::SATURATED,
                timing: Timing::SendAhead.wire(),
            }
        );
    }

    #[test]
    fn a_late_actuation_is_refused_as_late_and_never_applied() {
        let mut b = book(MissPolicy::Safe);
        assert_eq!(b.offer(&act(6, 6, 6.0, &[]), 7), Offer::Late);
        assert!(b.is_empty());
        assert_eq!(b.decide(7), Decision::Safe);
        // The same actuation offered in time is kept.
        assert_eq!(b.offer(&act(8, 8, 8.0, &[]), 8), Offer::Kept);
        assert_eq!(answered(b.decide(8)), Some(8.0));
    }

    #[test]
    fn with_plan_a_miss_takes_the_newest_plans_entry() {
        let mut b = book(MissPolicy::Plan(PlanFallback::Hold));
        b.offer(&act(10, 9, 10.0, &[11.0, 12.0, 13.0]), 10);
        assert_eq!(answered(b.decide(10)), Some(10.0));
        assert_eq!(planned(b.decide(11)), Some((11.0, 10)));
        // A late answer for 11 is newer than the plan of 10: its plan takes over.
        assert_eq!(b.offer(&act(11, 10, 99.0, &[22.0]), 12), Offer::Late);
        assert_eq!(b.plan_seq(), Some(11));
        assert_eq!(planned(b.decide(12)), Some((22.0, 11)));
        // An older one never replaces a newer plan.
        assert_eq!(
            b.offer(&act(9, 8, 9.0, &[0.0, 0.0, 0.0, 0.0, 0.0]), 13),
            Offer::Late
        );
        assert_eq!(b.plan_seq(), Some(11));
    }

    #[test]
    fn beyond_plan_len_a_miss_falls_back_to_hold_or_safe() {
        for (fallback, expected) in [
            (PlanFallback::Hold, Decision::Hold),
            (PlanFallback::Safe, Decision::Safe),
        ] {
            let mut b = book(MissPolicy::Plan(fallback));
            // No plan yet: the fallback.
            assert_eq!(b.decide(0), expected);
            b.offer(&act(1, 0, 1.0, &[2.0]), 1);
            assert_eq!(answered(b.decide(1)), Some(1.0));
            assert_eq!(planned(b.decide(2)), Some((2.0, 1)));
            assert_eq!(b.decide(3), expected, "plan_len 1 covers sample 2 only");
        }
    }

    #[test]
    fn hold_and_safe_never_use_a_plan() {
        for (policy, expected) in [
            (MissPolicy::Hold, Decision::Hold),
            (MissPolicy::Safe, Decision::Safe),
        ] {
            let mut b = book(policy);
            b.offer(&act(1, 1, 1.0, &[2.0, 3.0]), 1);
            b.decide(1);
            assert_eq!(b.decide(2), expected);
        }
    }

    #[test]
    fn stall_acknowledgements_are_never_inputs_nor_plans() {
        let mut b = book(MissPolicy::Plan(PlanFallback::Safe));
        let mut ack = act(5, 5, 5.0, &[6.0, 7.0]);
        ack.status = actuation_status::STALL_ACK;
        assert!(!b.answers(5));
        assert_eq!(b.offer(&ack, 5), Offer::StallAck);
        assert!(
            b.answers(5) && !b.answers(6),
            "it acknowledges measurement 5"
        );
        assert!(b.is_empty() && b.plan_seq().is_none());
        assert_eq!(b.decide(5), Decision::Safe);
        assert_eq!(b.decide(6), Decision::Safe);
        // Even a non-finite payload: an acknowledgement carries no input.
        ack.u[0] = f64::NAN;
        ack.reply_to = 7;
        assert_eq!(b.offer(&ack, 7), Offer::StallAck);
    }

    #[test]
    fn the_book_knows_which_measurement_the_service_answered() {
        let mut b = book(MissPolicy::Hold);
        assert!(!b.answers(0));
        // Send-ahead: A{k} reply_to k (nothing was sent ahead), then A{k+1} reply_to k.
        b.offer(&act(0, 0, 0.0, &[]), 0);
        assert!(b.answers(0) && !b.answers(1));
        b.offer(&act(1, 0, 1.0, &[]), 0);
        assert!(
            !b.answers(1),
            "the input for 1 is not the answer to measurement 1"
        );
        // Compute-first: seq = reply_to. A service that leaves reply_to at 0 still answers
        // the measurement of its seq.
        let mut cf = act(3, 0, 3.0, &[]);
        cf.timing = Timing::ComputeFirst.wire();
        b.offer(&cf, 3);
        assert!(b.answers(3) && !b.answers(4));
    }

    #[test]
    fn a_full_book_keeps_the_newest_and_says_what_it_dropped() {
        let mut b = book(MissPolicy::Hold);
        for s in 1..=4 {
            assert_eq!(b.offer(&act(s, 0, s as f64, &[]), 0), Offer::Kept);
        }
        assert_eq!(b.len(), 4);
        assert_eq!(
            b.offer(&act(5, 0, 5.0, &[]), 0),
            Offer::KeptDropping { dropped_seq: 1 }
        );
        assert!(!b.holds(1) && (2..=5).all(|s| b.holds(s)));
        // A second answer for a held sample replaces it, taking no more room.
        assert_eq!(b.offer(&act(3, 0, 33.0, &[]), 0), Offer::Kept);
        assert_eq!(b.len(), 4);
        assert_eq!(b.decide(1), Decision::Hold, "dropped");
        assert_eq!(answered(b.decide(2)), Some(2.0));
        assert_eq!(answered(b.decide(3)), Some(33.0));
        // Made room by the decisions: no more drops.
        assert_eq!(b.offer(&act(6, 3, 6.0, &[]), 3), Offer::Kept);
        assert_eq!(b.offer(&act(7, 3, 7.0, &[]), 3), Offer::Kept);
        assert_eq!(b.len(), 4);
    }

    #[test]
    fn actuations_for_skipped_samples_are_retired_into_the_plan() {
        let mut b = book(MissPolicy::Plan(PlanFallback::Hold));
        b.offer(&act(2, 1, 2.0, &[3.0, 4.0, 5.0]), 1);
        // Sample 2 is never decided (the caller skipped it): at 4 its actuation is retired
        // and its plan covers 4.
        assert_eq!(planned(b.decide(4)), Some((4.0, 2)));
        assert!(b.is_empty());
    }

    #[test]
    fn invalid_actuations_and_non_finite_plan_entries_are_refused() {
        let mut b = book(MissPolicy::Plan(PlanFallback::Hold));
        let good = act(3, 2, 3.0, &[4.0, 5.0]);
        let mut bad = Vec::new();
        let mut a = good;
        a.u[0] = f64::INFINITY;
        bad.push(("non-finite u", a));
        let mut a = good;
        a.plan[1][0] = f64::NAN;
        bad.push(("non-finite plan entry", a));
        let mut a = good;
        a.contract_version = CONTRACT_VERSION - 1;
        bad.push(("old contract", a));
        let mut a = good;
        a.counts.n_u = 2;
        bad.push(("other n_u", a));
        let mut a = good;
        a.plan_len = MAX_PLAN as u32 + 1;
        bad.push(("plan past the capacity", a));
        for (what, a) in bad {
            assert_eq!(b.offer(&a, 3), Offer::Invalid, "{what}");
            assert!(b.is_empty() && !b.answers(2), "{what}");
        }
        // A non-finite value past plan_len or past n_u is not an entry: still valid.
        let mut a = good;
        a.plan[2][0] = f64::NAN;
        a.plan[0][1] = f64::NAN;
        a.u[1] = f64::NAN;
        assert_eq!(b.offer(&a, 3), Offer::Kept);
        assert_eq!(answered(b.decide(3)), Some(3.0));
        assert_eq!(planned(b.decide(4)), Some((4.0, 3)));
    }

    #[test]
    fn clearing_forgets_the_old_services_actuations() {
        let mut b = book(MissPolicy::Plan(PlanFallback::Safe));
        b.offer(&act(1, 1, 1.0, &[2.0]), 1);
        b.offer(&act(2, 1, 2.0, &[3.0]), 1);
        b.decide(1);
        b.clear();
        assert!(b.is_empty() && b.plan_seq().is_none() && !b.answers(1));
        assert_eq!(b.decide(2), Decision::Safe);
    }
}
