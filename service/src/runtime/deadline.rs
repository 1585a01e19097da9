//! The deadline policy: what counts as a miss, when the safe state is entered and left.
//!
//! Per answered sample `k` (cycle `c ≥ 1` of its connection, see [`super::session`]):
//!
//! - **Late** (service-measured): the plant gave a deadline `D_k > 0`, the sample time is
//!   possible (see [`Answer::timestamp_ok`]) and the response time
//!   `t_publish − t_sample,k > D_k`. Every late answer is counted.
//! - **Plant-reported**: sample `k` carries `PREVIOUS_ACTUATION_MISSED` (the plant's verdict
//!   on actuation `k − 1`) and `c > 1`; on the first sample of a connection the flag speaks
//!   of an actuation of before the connection and is ignored. Every report is counted.
//! - **Plan-covered**: a plant-reported miss that also carries `PLAN_APPLIED`: the plant
//!   applied the entry of the service's latest plan for that sample, the input the
//!   controller had planned for it, rather than a held or safe input. Counted.
//! - **Miss** (what the safe state listens to): the actuation could not be published, or,
//!   by `service.miss-source`, the plant reported a miss that no plan covered (`plant`, the
//!   default) or the answer was late (`response-time`). A plan-covered report neither
//!   extends nor ends a run of misses: the plan carries the loop through a stall, and only
//!   when it runs out do the held or safe inputs count toward the safe state.
//!
//! **Protected cycles** are the grace period of a connection (`c ≤ G`,
//! `G = service.grace-periods`) and the open-loop phase of a plant session
//! (`service.open-loop`): a miss there is counted but neither extends the run of
//! consecutive misses nor enters the safe state (start-up costs — page faults, cold caches,
//! a plant warming up — are not a controller out of time).
//!
//! With `m` the number of consecutive misses outside protected cycles (reset to 0 by a
//! non-miss, a protected cycle and a new connection) and `N = service.max-consecutive-misses`:
//!
//! - **entered**: at an unprotected miss with `m ≥ N`.
//! - **left**: with `M = service.recover-after` and `K = service.recover-tolerance`, when
//!   the last `M` answers given in the safe state hold at most `K` misses (`K = 0`: `M` good
//!   answers in a row). Without `M` (`recover-after` absent or 0) the safe state is kept
//!   for the rest of the plant session.
//! - **a new plant session** re-evaluates it: the safe state, the run of misses and the
//!   recovery window start afresh, as for a plant never seen before
//!   ([`DeadlineMonitor::new_session`]).
//!
//! A new connection of the same session (a stall resumed) resets `m` but neither the safe
//! state nor its recovery window. In the safe state the loop sends the safe input and the
//! controller only observes; what happens to its learned state on leaving is the business
//! of [`super::reset`]. The monitor reads no clock: times come in as arguments. Its only
//! buffer, the recovery window (`M` bits), is allocated by [`DeadlineMonitor::new`].

use crate::config::{DeadlinePolicy, MissSource};

/// A change of the safe state decided by [`DeadlineMonitor::on_answer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SafeStateChange {
    /// No change.
    Unchanged,
    /// The safe state was entered after `misses` consecutive misses.
    Entered {
        /// Consecutive misses counted.
        misses: u64,
    },
    /// The safe state was left.
    Left,
}

/// The facts about one answer, known after publishing it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Answer {
    /// The sample's cycle in its connection, from 1.
    pub cycle: u64,
    /// The sample lies in the open-loop phase of its plant session.
    pub open_loop: bool,
    /// The actuation was published.
    pub published: bool,
    /// The sample time is possible (not 0, not after its receipt, not before the previous
    /// sample's), so `response_ns` means something.
    pub timestamp_ok: bool,
    /// Publish time minus sample time, ns.
    pub response_ns: u64,
    /// The plant's deadline for it, ns after the sample time; 0 when it gave none.
    pub deadline_ns: u64,
}

/// What the deadline policy made of one answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verdict {
    /// The answer was late by the service's measurement.
    pub late: bool,
    /// The answer counts as a miss (module docs).
    pub missed: bool,
    /// What happened to the safe state.
    pub change: SafeStateChange,
}

/// Miss counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DeadlineCounts {
    /// Late answers by the service's measurement.
    pub late: u64,
    /// Misses the plant reported.
    pub plant_reported: u64,
    /// Of those, the ones the plant covered with an entry of the service's plan.
    pub plan_covered: u64,
    /// Misses in protected cycles (grace period, open-loop phase).
    pub protected_misses: u64,
    /// The longest run of consecutive (unprotected) misses.
    pub max_consecutive: u64,
    /// Entries into the safe state.
    pub safe_state_entries: u64,
}

/// The last `M` verdicts given in the safe state, one bit each (1: a miss).
#[derive(Debug, Clone)]
struct RecoveryWindow {
    bits: Box<[u64]>,
    len: u64,
    filled: u64,
    misses: u64,
}

impl RecoveryWindow {
    fn new(len: u64) -> Self {
        Self {
            bits: vec![0; len.div_ceil(64) as usize].into_boxed_slice(),
            len,
            filled: 0,
            misses: 0,
        }
    }

    fn clear(&mut self) {
        self.bits.iter_mut().for_each(|w| *w = 0);
        self.filled = 0;
        self.misses = 0;
    }

    /// Adds a verdict; returns the misses among the last `len` once `len` are there.
    fn push(&mut self, missed: bool) -> Option<u64> {
        if self.len == 0 {
            return None;
        }
        let i = self.filled % self.len;
        let (word, bit) = ((i / 64) as usize, 1u64 << (i % 64));
        if self.filled >= self.len && self.bits[word] & bit != 0 {
            self.misses -= 1;
        }
        if missed {
            self.bits[word] |= bit;
            self.misses += 1;
        } else {
            self.bits[word] &= !bit;
        }
        self.filled += 1;
        (self.filled >= self.len).then_some(self.misses)
    }
}

/// The policy of the module docs; plain data, O(1) per call.
#[derive(Debug, Clone)]
pub struct DeadlineMonitor {
    grace_cycles: u64,
    max_consecutive_misses: u64,
    recover_tolerance: u64,
    source: MissSource,
    in_safe_state: bool,
    consecutive: u64,
    window: Option<RecoveryWindow>,
    /// On-time answers in a row in the safe state, and the longest such run since entry.
    clean_run: u64,
    longest_clean_run: u64,
    plant_reported: bool,
    /// The plant's report was a miss covered by a plan entry.
    covered: bool,
    counts: DeadlineCounts,
}

impl DeadlineMonitor {
    /// A monitor applying `policy`, out of the safe state.
    pub fn new(policy: &DeadlinePolicy) -> Self {
        Self {
            grace_cycles: policy.grace_cycles,
            max_consecutive_misses: policy.max_consecutive_misses,
            recover_tolerance: policy.recover_tolerance,
            source: policy.miss_source,
            in_safe_state: false,
            consecutive: 0,
            window: policy.recover_after.map(RecoveryWindow::new),
            clean_run: 0,
            longest_clean_run: 0,
            plant_reported: false,
            covered: false,
            counts: DeadlineCounts::default(),
        }
    }

    /// True while cycle `cycle` of a connection is in the grace period (`cycle ≤ G`).
    pub fn in_grace(&self, cycle: u64) -> bool {
        cycle <= self.grace_cycles
    }

    /// True in the safe state.
    pub fn in_safe_state(&self) -> bool {
        self.in_safe_state
    }

    /// Takes in the plant's report carried by the sample about to be answered, cycle
    /// `cycle` of its connection; `previous_missed` is its `PREVIOUS_ACTUATION_MISSED` flag
    /// and `plan_applied` its `PLAN_APPLIED` flag. Returns whether it counts as a
    /// plant-reported miss (it is then used by the next [`DeadlineMonitor::on_answer`]).
    pub fn on_sample(&mut self, previous_missed: bool, plan_applied: bool, cycle: u64) -> bool {
        self.plant_reported = previous_missed && cycle > 1;
        self.covered = self.plant_reported && plan_applied;
        if self.plant_reported {
            self.counts.plant_reported += 1;
        }
        if self.covered {
            self.counts.plan_covered += 1;
        }
        self.plant_reported
    }

    /// Judges the answer to the sample last given to [`DeadlineMonitor::on_sample`].
    pub fn on_answer(&mut self, a: Answer) -> Verdict {
        let late =
            ipc_types::timing_rules::answer_late(a.timestamp_ok, a.deadline_ns, a.response_ns);
        if late {
            self.counts.late += 1;
        }
        let missed = !a.published
            || match self.source {
                MissSource::Plant => self.plant_reported && !self.covered,
                MissSource::ResponseTime => late,
            };
        // A miss the plan covered neither extends nor ends a run of misses.
        let covered_only = !missed && self.source == MissSource::Plant && self.covered;
        let mut change = SafeStateChange::Unchanged;
        if a.open_loop || self.in_grace(a.cycle) {
            self.consecutive = 0;
            if missed {
                self.counts.protected_misses += 1;
            }
        } else if missed {
            self.consecutive += 1;
            self.counts.max_consecutive = self.counts.max_consecutive.max(self.consecutive);
            if !self.in_safe_state && self.consecutive >= self.max_consecutive_misses {
                self.in_safe_state = true;
                self.counts.safe_state_entries += 1;
                self.clean_run = 0;
                self.longest_clean_run = 0;
                if let Some(w) = self.window.as_mut() {
                    w.clear();
                }
                change = SafeStateChange::Entered {
                    misses: self.consecutive,
                };
                return Verdict {
                    late,
                    missed,
                    change,
                };
            }
        } else if !covered_only {
            self.consecutive = 0;
        }
        if self.in_safe_state {
            self.clean_run = if missed { 0 } else { self.clean_run + 1 };
            self.longest_clean_run = self.longest_clean_run.max(self.clean_run);
        }
        if self.in_safe_state
            && let Some(w) = self.window.as_mut()
            && w.push(missed).is_some_and(|m| m <= self.recover_tolerance)
        {
            self.in_safe_state = false;
            change = SafeStateChange::Left;
        }
        Verdict {
            late,
            missed,
            change,
        }
    }

    /// A new connection began: the run of consecutive misses starts again.
    pub fn new_connection(&mut self) {
        self.consecutive = 0;
    }

    /// A new plant session began: everything but the counters starts afresh. Returns true
    /// when this left the safe state.
    pub fn new_session(&mut self) -> bool {
        let was = self.in_safe_state;
        self.in_safe_state = false;
        self.consecutive = 0;
        if let Some(w) = self.window.as_mut() {
            w.clear();
        }
        was
    }

    /// The operator releases the safe state ([`crate::runtime::operator`]): as at a new
    /// session, the latch, the run of misses and the recovery window start afresh; the
    /// counters stay. Returns true when this left the safe state.
    pub fn release(&mut self) -> bool {
        self.new_session()
    }

    /// The longest run of on-time answers since the safe state was last entered.
    pub fn longest_clean_run(&self) -> u64 {
        self.longest_clean_run
    }

    /// The current run of consecutive misses.
    pub fn consecutive_misses(&self) -> u64 {
        self.consecutive
    }

    /// The counters.
    pub fn counts(&self) -> DeadlineCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const D: u64 = 500_000;

    /// The fixture's policy (`tests/loop-core.toml`) with the fields under test replaced;
    /// no misses tolerated in the recovery window.
    fn policy(
        grace: u64,
        n: u64,
        recover_after: Option<u64>,
        source: MissSource,
    ) -> DeadlinePolicy {
        tolerant(grace, n, recover_after, 0, source)
    }

    /// [`policy`] with `tolerance` misses allowed in the recovery window.
    fn tolerant(
        grace: u64,
        n: u64,
        recover_after: Option<u64>,
        tolerance: u64,
        source: MissSource,
    ) -> DeadlinePolicy {
        let cfg = crate::config::ServiceConfig::parse(
            include_str!("loop_core/tests/loop-core.toml"),
            "loop-core.toml",
        )
        .expect("the fixture is valid");
        DeadlinePolicy {
            grace_cycles: grace,
            max_consecutive_misses: n,
            recover_after,
            recover_tolerance: tolerance,
            miss_source: source,
            ..cfg.policy
        }
    }

    /// One answered cycle: `P` the plant reported a miss, `C` one it covered with a plan
    /// entry, `L` the answer was late, `U` it
    /// could not be published, `.` on time, `o`/`O` on time/plant-reported miss in the
    /// open-loop phase; `|` a new connection and `#` a new plant session (not cycles).
    fn run(p: &DeadlinePolicy, script: &str) -> (Vec<SafeStateChange>, DeadlineMonitor) {
        let mut m = DeadlineMonitor::new(p);
        let mut cycle = 0;
        let mut changes = Vec::new();
        for c in script.chars() {
            match c {
                '|' => m.new_connection(),
                '#' => {
                    m.new_session();
                }
                _ => {}
            }
            if c == '|' || c == '#' {
                cycle = 0;
                continue;
            }
            cycle += 1;
            m.on_sample(c == 'P' || c == 'O' || c == 'C', c == 'C', cycle);
            let v = m.on_answer(Answer {
                cycle,
                open_loop: c == 'o' || c == 'O',
                published: c != 'U',
                timestamp_ok: true,
                response_ns: if c == 'L' { D + 1 } else { D },
                deadline_ns: D,
            });
            changes.push(v.change);
        }
        (changes, m)
    }

    /// The cycles (from 1 over the whole script) where the safe state was entered (`+`)
    /// and left (`-`).
    fn transitions(changes: &[SafeStateChange]) -> Vec<(usize, char)> {
        changes
            .iter()
            .enumerate()
            .filter_map(|(i, c)| match c {
                SafeStateChange::Unchanged => None,
                SafeStateChange::Entered { .. } => Some((i + 1, '+')),
                SafeStateChange::Left => Some((i + 1, '-')),
            })
            .collect()
    }

    /// A row of the policy table: what it shows, the policy, the script of [`run`], and the
    /// expected [`transitions`].
    type Case = (
        &'static str,
        DeadlinePolicy,
        &'static str,
        &'static [(usize, char)],
    );

    #[test]
    fn safe_state_transitions_follow_the_policy_table() {
        use MissSource::{Plant, ResponseTime};
        #[rustfmt::skip]
        let table: &[Case] = &[
            ("exactly N consecutive misses enter",
                policy(0, 3, None, Plant), "..PPP..", &[(5, '+')]),
            ("N − 1 misses do not",
                policy(0, 3, None, Plant), "..PP.PP.", &[]),
            ("the plant's flag on the first cycle of the run is ignored",
                policy(0, 2, None, Plant), "PPP", &[(3, '+')]),
            ("a streak broken by one on-time answer starts again",
                policy(0, 3, None, Plant), "PP.PP.PPP", &[(9, '+')]),
            ("misses a plan covered never enter",
                policy(0, 2, None, Plant), "..CCCCCC..", &[]),
            ("a plan-covered miss neither extends nor ends a streak",
                policy(0, 3, None, Plant), ".PCPCP", &[(6, '+')]),
            ("an uncovered miss after the plan ran out counts",
                policy(0, 2, None, Plant), ".CCCCPP", &[(7, '+')]),
            ("misses in the grace period cannot enter",
                policy(4, 2, None, Plant), "PPPP....", &[]),
            ("nor extend the streak: N misses after the grace period are needed",
                policy(4, 2, None, Plant), "PPPPPP", &[(6, '+')]),
            ("misses in the open-loop phase neither enter nor extend the streak",
                policy(0, 2, None, Plant), "OOOOOP.PP", &[(9, '+')]),
            ("the flag on the first sample of a connection is ignored",
                policy(0, 2, None, Plant), "P.|PPP", &[(5, '+')]),
            ("a new connection resets the streak",
                policy(0, 3, None, ResponseTime), ".LL|LL", &[]),
            ("latched without recover-after",
                policy(0, 2, None, Plant), ".PP..........", &[(3, '+')]),
            ("recover-after = 3 leaves after three good answers",
                policy(0, 2, Some(3), Plant), ".PP...", &[(3, '+'), (6, '-')]),
            ("a miss in the safe state restarts the good count",
                policy(0, 2, Some(3), Plant), ".PP..P...", &[(3, '+'), (9, '-')]),
            ("an empty recovery window keeps the safe state",
                policy(0, 2, Some(0), Plant), ".PPP.....", &[(3, '+')]),
            ("a recovery window may hold up to K misses",
                tolerant(0, 2, Some(4), 1, Plant), ".PP.P..", &[(3, '+'), (7, '-')]),
            ("with K = 0 the window must be clean",
                tolerant(0, 2, Some(4), 0, Plant), ".PP.P....", &[(3, '+'), (9, '-')]),
            ("more than K misses in the window keep the safe state",
                tolerant(0, 2, Some(4), 1, Plant), ".PP.P.P.P.P", &[(3, '+')]),
            ("the safe state can be entered again",
                policy(0, 2, Some(1), Plant), ".PP.PP", &[(3, '+'), (4, '-'), (6, '+')]),
            ("the safe state survives a new connection",
                policy(0, 2, Some(2), Plant), ".PP|..", &[(3, '+'), (5, '-')]),
            ("a latched safe state survives a new connection",
                policy(0, 2, None, Plant), ".PP|.....", &[(3, '+')]),
            ("a new plant session starts out of the safe state, grace and streak afresh",
                policy(0, 2, None, Plant), ".PP#..PP", &[(3, '+'), (7, '+')]),
            ("plant source ignores late answers",
                policy(0, 2, None, Plant), ".LLLL", &[]),
            ("response-time source counts late answers",
                policy(0, 2, None, ResponseTime), ".LL", &[(3, '+')]),
            ("response-time source ignores the plant's reports",
                policy(0, 2, None, ResponseTime), ".PPPP", &[]),
            ("an unpublished answer is a miss (plant source)",
                policy(0, 2, None, Plant), ".UU", &[(3, '+')]),
            ("an unpublished answer is a miss (response-time source)",
                policy(0, 2, None, ResponseTime), ".UU", &[(3, '+')]),
        ];
        for (what, p, script, expected) in table {
            let (changes, _) = run(p, script);
            assert_eq!(transitions(&changes), *expected, "{what}: {script}");
        }
    }

    #[test]
    fn every_miss_is_counted_whatever_the_source() {
        let (changes, m) = run(&policy(0, 3, None, MissSource::Plant), ".PLPC.LLP|P");
        assert!(changes.iter().all(|c| *c == SafeStateChange::Unchanged));
        assert_eq!(
            m.counts(),
            DeadlineCounts {
                late: 3,
                plant_reported: 4,
                plan_covered: 1,
                protected_misses: 0,
                max_consecutive: 1,
                safe_state_entries: 0,
            }
        );
    }

    #[test]
    fn the_entry_reports_the_streak_length_and_the_longest_streak_is_kept() {
        let (changes, m) = run(&policy(3, 2, None, MissSource::Plant), ".PPPPPP...");
        assert_eq!(changes[4], SafeStateChange::Entered { misses: 2 });
        assert!(m.in_safe_state());
        assert_eq!(m.consecutive_misses(), 0);
        assert_eq!(m.counts().max_consecutive, 4);
        assert_eq!(m.counts().protected_misses, 2);
        assert_eq!(m.counts().safe_state_entries, 1);
    }

    #[test]
    fn a_new_session_reports_whether_it_left_the_safe_state() {
        let (_, mut m) = run(&policy(0, 1, None, MissSource::Plant), ".P");
        assert!(m.in_safe_state());
        assert!(m.new_session());
        assert!(!m.in_safe_state());
        assert!(!m.new_session());
    }

    #[test]
    fn an_impossible_sample_time_is_never_late() {
        let mut m = DeadlineMonitor::new(&policy(0, 1, None, MissSource::ResponseTime));
        m.on_sample(false, false, 2);
        let v = m.on_answer(Answer {
            cycle: 2,
            open_loop: false,
            published: true,
            timestamp_ok: false,
            response_ns: u64::MAX,
            deadline_ns: 1,
        });
        assert_eq!((v.late, v.missed, m.counts().late), (false, false, 0));
    }

    #[test]
    fn a_missing_deadline_is_never_late() {
        let mut m = DeadlineMonitor::new(&policy(0, 1, None, MissSource::ResponseTime));
        m.on_sample(false, false, 1);
        let v = m.on_answer(Answer {
            cycle: 1,
            open_loop: false,
            published: true,
            timestamp_ok: true,
            response_ns: u64::MAX,
            deadline_ns: 0,
        });
        assert_eq!(
            v,
            Verdict {
                late: false,
                missed: false,
                change: SafeStateChange::Unchanged
            }
        );
    }

    #[test]
    fn the_grace_period_covers_cycles_one_to_g() {
        let m = DeadlineMonitor::new(&policy(2, 1, None, MissSource::Plant));
        assert_eq!([1, 2, 3].map(|c| m.in_grace(c)), [true, true, false]);
    }
}
