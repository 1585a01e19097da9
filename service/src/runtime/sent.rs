//! What the service published for the last few samples, and so what the plant applies.
//!
//! The loop needs it three times per sample: to know whether an input for sample `k` was
//! already sent ahead ([`SentLog::contains`]), to compare the plant's report of the input it
//! applied after sample `k − 1` with what was sent for it ([`SentLog::input_for`]), and to
//! tell an ahead controller which input the plant applies for a sample it takes in
//! ([`SentLog::expected_input`]): the input sent for that sample, else the entry of the
//! newest plan that covers it (what a plant with `late-policy = "plan"` applies), else the
//! newest input sent before it (what a holding plant applies): the rule
//! [`timing_rules::expected_input`]. The plant's own report in
//! the next sample corrects the guess when it differs. Fixed capacity, no allocation.

use ipc_types::timing_rules::{self, Expected};
use ipc_types::{Actuation, MAX_U};

/// Inputs remembered, by sample.
const SLOTS: usize = 8;

/// One published input: the sample it is for, its status bits and the input.
#[derive(Debug, Clone, Copy)]
struct Slot {
    seq: u64,
    status: u32,
    u: [f64; MAX_U],
}

/// The last eight inputs the service published and the newest actuation whole (for its
/// plan); see the module docs.
#[derive(Debug, Clone)]
pub struct SentLog {
    slots: [Option<Slot>; SLOTS],
    newest: Option<Actuation>,
}

impl Default for SentLog {
    fn default() -> Self {
        Self {
            slots: [None; SLOTS],
            newest: None,
        }
    }
}

impl SentLog {
    /// Records a published actuation (an input: not a stall acknowledgement).
    pub fn record(&mut self, act: &Actuation) {
        let slot = Slot {
            seq: act.seq,
            status: act.status,
            u: act.u,
        };
        let i = (act.seq % SLOTS as u64) as usize;
        if let Some(s) = self.slots.get_mut(i) {
            *s = Some(slot);
        }
        if self.newest.is_none_or(|n| act.seq >= n.seq) {
            self.newest = Some(*act);
        }
    }

    fn slot(&self, seq: u64) -> Option<&Slot> {
        self.slots
            .get((seq % SLOTS as u64) as usize)
            .and_then(|s| s.as_ref())
            .filter(|s| s.seq == seq)
    }

    /// True when an input for sample `seq` was published.
    pub fn contains(&self, seq: u64) -> bool {
        self.slot(seq).is_some()
    }

    /// The input published for sample `seq` and its status bits.
    pub fn input_for(&self, seq: u64) -> Option<(&[f64; MAX_U], u32)> {
        self.slot(seq).map(|s| (&s.u, s.status))
    }

    /// Writes into `out` (length `n_u`) what the plant applies for sample `seq`, as far as
    /// the service knows (module docs); `fallback` (the safe input) when nothing was sent
    /// ([`timing_rules::expected_input`]).
    pub fn expected_input(&self, seq: u64, fallback: &[f64], out: &mut [f64]) {
        let n = out.len();
        let newest = self.newest.as_ref();
        let rule = timing_rules::expected_input(
            self.slot(seq).is_some(),
            newest.map(|a| (a.seq, a.plan_len)),
            seq,
        );
        let source = match (rule, self.slot(seq), newest) {
            (Expected::Sent, Some(s), _) => &s.u[..],
            (Expected::PlanRow(j), _, Some(a)) => &a.plan[j][..],
            (Expected::Held, _, Some(a)) => &a.u[..],
            _ => fallback,
        };
        out.copy_from_slice(&source[..n]);
    }

    /// Forgets everything (a new plant session).
    pub fn clear(&mut self) {
        *self = Self::default();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ipc_types::ChannelCounts;

    fn act(seq: u64, u: f64, plan: &[f64]) -> Actuation {
        let mut a = Actuation::zeroed(ChannelCounts::new(1, 1, 0, 1).unwrap());
        a.seq = seq;
        a.u[0] = u;
        for (j, p) in plan.iter().enumerate() {
            a.plan[j][0] = *p;
        }
        a.plan_len = plan.len() as u32;
        a
    }

    #[test]
    fn the_expected_input_is_the_one_sent_else_the_newest_plan_entry_else_the_newest_input() {
        let mut log = SentLog::default();
        let mut out = [0.0];
        log.expected_input(5, &[-1.0], &mut out);
        assert_eq!(out, [-1.0], "nothing sent: the safe input");
        log.record(&act(5, 1.0, &[2.0, 3.0]));
        log.expected_input(5, &[-1.0], &mut out);
        assert_eq!(out, [1.0]);
        log.expected_input(7, &[-1.0], &mut out);
        assert_eq!(out, [3.0], "the plan's entry for 7");
        log.expected_input(8, &[-1.0], &mut out);
        assert_eq!(out, [1.0], "past the plan: held");
        assert!(log.contains(5) && !log.contains(6));
        assert_eq!(log.input_for(5).map(|(u, _)| u[0]), Some(1.0));
    }

    #[test]
    fn an_older_slot_overwritten_by_a_newer_sample_is_forgotten() {
        let mut log = SentLog::default();
        log.record(&act(1, 1.0, &[]));
        log.record(&act(1 + SLOTS as u64, 2.0, &[]));
        assert!(!log.contains(1));
        assert!(log.contains(1 + SLOTS as u64));
        log.clear();
        assert!(!log.contains(1 + SLOTS as u64));
    }
}
