//! The session tracker: what a sequence number says about the plant on the other side.
//!
//! The plant is the clock master and numbers its samples `k = 0, 1, 2, …`. From the
//! sequence numbers and the receive times alone (no wall-clock guesses, no clock read here:
//! times come in as arguments), the tracker classifies every received sample `k` against
//! the last one received, `k_last`:
//!
//! | condition                         | [`Arrival`]               | samples lost          |
//! | --------------------------------- | ------------------------- | --------------------- |
//! | no sample before                  | `First`                   | 0                     |
//! | not silent, `k > k_last`          | `Next`                    | `k − k_last − 1`      |
//! | silent, `k > k_last`              | `Resumed` (a stall)       | `k − k_last − 1`      |
//! | `k ≤ k_last`, silent or not       | `NewSession`              | 0                     |
//!
//! **Silence.** The plant is declared silent when, while idle at time `t`, the last
//! answered sample was received at `t_last` with `t − t_last > silent_periods · T`
//! ([`SessionTracker::idle`]); it stays silent until the next sample arrives.
//!
//! **Stall or new plant.** A sequence that continues after silence (`k > k_last`) is the
//! same plant whose samples stopped for a while (the plant process or the path to it
//! stalled): a timing fault, not a new plant. Its session goes on: the samples between
//! are counted as lost and handed to the controller as a gap, the session's cycle count
//! (open-loop phase, tone windows) continues. A sequence number that does not advance
//! (`k ≤ k_last`: a plant restarted from 0, with or without silence before) is a genuinely
//! new plant session: the session's cycle count starts again at 1. A duplicate (`k =
//! k_last`) falls in that case too.
//!
//! **Connection.** Both a resume and a new session start a new *connection*: its cycle
//! count starts again at 1, and the receive-time history used for the period jitter and
//! the silence timeout is forgotten. The deadline policy's grace period is counted in
//! connection cycles.
//!
//! Whether the controller keeps what it learned is not decided here (see
//! [`super::reset`]). Every method is O(1) and plain arithmetic.

/// What a received sample means for the session (see the table in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// The first sample the service has received.
    First,
    /// The next sample of the running session, `lost` samples after the previous one.
    Next {
        /// Samples never received between the previous one and this one.
        lost: u64,
    },
    /// The first sample after silence, continuing the sequence: the plant stalled and came
    /// back; the session goes on.
    Resumed {
        /// Samples never received between the last one before the silence and this one.
        lost: u64,
    },
    /// A sequence number that did not advance: a new plant session begins.
    NewSession {
        /// The last sequence number of the previous session.
        from: u64,
        /// The plant had been declared silent before.
        after_silence: bool,
    },
}

impl Arrival {
    /// Samples lost just before this one, as the controller must be told
    /// (`StepInput::lost`).
    pub fn lost(&self) -> u64 {
        match *self {
            Arrival::Next { lost } | Arrival::Resumed { lost } => lost,
            Arrival::First | Arrival::NewSession { .. } => 0,
        }
    }
}

/// What [`SessionTracker::idle`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Idle {
    /// The plant is not silent.
    Active,
    /// The plant has just been declared silent.
    WentSilent {
        /// The last sequence number received.
        last_seq: u64,
    },
    /// The plant was already silent.
    Silent,
}

/// Session counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SessionCounts {
    /// Samples received (answered or not).
    pub received: u64,
    /// Samples never received: the gaps in the sequence within a session.
    pub lost: u64,
    /// Times the plant was declared silent.
    pub silences: u64,
    /// Times a sample arrived after silence (a stall resumed or a new session after it).
    pub resumes: u64,
}

/// Tracks sequence numbers, silence and the cycle counts of the session and connection.
#[derive(Debug, Clone)]
pub struct SessionTracker {
    silent_ns: u64,
    last_seq: Option<u64>,
    last_answer_ns: Option<u64>,
    silent: bool,
    session_cycles: u64,
    connection_cycles: u64,
    counts: SessionCounts,
}

impl SessionTracker {
    /// A tracker that declares the plant silent after `silent_periods` periods of
    /// `period_ns` without a sample.
    pub fn new(silent_periods: u64, period_ns: u64) -> Self {
        Self {
            silent_ns: silent_periods.saturating_mul(period_ns),
            last_seq: None,
            last_answer_ns: None,
            silent: false,
            session_cycles: 0,
            connection_cycles: 0,
            counts: SessionCounts::default(),
        }
    }

    /// Takes in received sample `seq` (answered or only observed) and classifies it.
    pub fn arrive(&mut self, seq: u64) -> Arrival {
        self.counts.received += 1;
        let arrival = match self.last_seq {
            None => Arrival::First,
            Some(last) if seq <= last => Arrival::NewSession {
                from: last,
                after_silence: self.silent,
            },
            Some(last) if self.silent => Arrival::Resumed {
                lost: seq - last - 1,
            },
            Some(last) => Arrival::Next {
                lost: seq - last - 1,
            },
        };
        if self.silent {
            self.silent = false;
            self.counts.resumes += 1;
        }
        self.counts.lost += arrival.lost();
        match arrival {
            Arrival::First | Arrival::Next { .. } => {}
            Arrival::Resumed { .. } => self.new_connection(),
            Arrival::NewSession { .. } => {
                self.new_connection();
                self.session_cycles = 0;
            }
        }
        self.last_seq = Some(seq);
        self.session_cycles += 1;
        self.connection_cycles += 1;
        arrival
    }

    fn new_connection(&mut self) {
        self.connection_cycles = 0;
        self.last_answer_ns = None;
    }

    /// Records that the current sample, received at `t_recv_ns`, is being answered;
    /// returns the time since the previous answered sample of this connection.
    pub fn answered(&mut self, t_recv_ns: u64) -> Option<u64> {
        let since = self
            .last_answer_ns
            .map(|prev| t_recv_ns.saturating_sub(prev));
        self.last_answer_ns = Some(t_recv_ns);
        since
    }

    /// Called while no sample is pending at time `now_ns`: declares the plant silent when
    /// the last answered sample is more than `silent_periods` periods old.
    pub fn idle(&mut self, now_ns: u64) -> Idle {
        if self.silent {
            return Idle::Silent;
        }
        if let (Some(last), Some(seq)) = (self.last_answer_ns, self.last_seq)
            && now_ns.saturating_sub(last) > self.silent_ns
        {
            self.silent = true;
            self.counts.silences += 1;
            return Idle::WentSilent { last_seq: seq };
        }
        Idle::Active
    }

    /// The index of the current sample in its plant session, from 1 (0 before any).
    pub fn session_cycle(&self) -> u64 {
        self.session_cycles
    }

    /// The index of the current sample since the first sample, the last resume or the last
    /// new session, from 1 (0 before any).
    pub fn connection_cycle(&self) -> u64 {
        self.connection_cycles
    }

    /// True while the plant is declared silent.
    pub fn is_silent(&self) -> bool {
        self.silent
    }

    /// The counters.
    pub fn counts(&self) -> SessionCounts {
        self.counts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: u64 = 1_000_000;

    /// One step of a scripted plant: a sample arrives (and is answered at `t`), or the
    /// service is idle at `t`.
    #[derive(Clone, Copy)]
    enum Step {
        Sample { seq: u64, t: u64 },
        Idle { t: u64 },
    }

    /// What the tracker said at one step: the arrival or idle verdict, and the session and
    /// connection cycles after it.
    #[derive(Debug, PartialEq, Eq)]
    enum Said {
        Arrived(Arrival, u64, u64),
        Idle(Idle),
    }

    fn run(silent_periods: u64, steps: &[Step]) -> (Vec<Said>, SessionTracker) {
        let mut s = SessionTracker::new(silent_periods, T);
        let said = steps
            .iter()
            .map(|step| match *step {
                Step::Sample { seq, t } => {
                    let a = s.arrive(seq);
                    s.answered(t);
                    Said::Arrived(a, s.session_cycle(), s.connection_cycle())
                }
                Step::Idle { t } => Said::Idle(s.idle(t)),
            })
            .collect();
        (said, s)
    }

    use Step::{Idle as Wait, Sample};

    #[test]
    fn consecutive_samples_continue_the_session_and_gaps_count_as_lost() {
        let (said, s) = run(
            10,
            &[
                Sample { seq: 0, t: 0 },
                Sample { seq: 1, t: T },
                Sample { seq: 4, t: 4 * T },
                Sample { seq: 5, t: 5 * T },
            ],
        );
        assert_eq!(
            said,
            [
                Said::Arrived(Arrival::First, 1, 1),
                Said::Arrived(Arrival::Next { lost: 0 }, 2, 2),
                Said::Arrived(Arrival::Next { lost: 2 }, 3, 3),
                Said::Arrived(Arrival::Next { lost: 0 }, 4, 4),
            ]
        );
        assert_eq!(
            s.counts(),
            SessionCounts {
                received: 4,
                lost: 2,
                silences: 0,
                resumes: 0
            }
        );
    }

    #[test]
    fn silence_is_declared_after_more_than_n_periods_and_only_once() {
        let (said, s) = run(
            3,
            &[
                Wait { t: 100 * T },
                Sample { seq: 7, t: 0 },
                Wait { t: 3 * T },
                Wait { t: 3 * T + 1 },
                Wait { t: 10 * T },
            ],
        );
        assert_eq!(
            said,
            [
                Said::Idle(Idle::Active),
                Said::Arrived(Arrival::First, 1, 1),
                Said::Idle(Idle::Active),
                Said::Idle(Idle::WentSilent { last_seq: 7 }),
                Said::Idle(Idle::Silent),
            ]
        );
        assert!(s.is_silent());
        assert_eq!(s.counts().silences, 1);
    }

    #[test]
    fn a_sequence_continuing_after_silence_is_a_stall_of_the_same_session() {
        let (said, s) = run(
            2,
            &[
                Sample { seq: 0, t: 0 },
                Sample { seq: 1, t: T },
                Sample { seq: 2, t: 2 * T },
                Wait { t: 10 * T },
                Sample { seq: 12, t: 12 * T },
                Sample { seq: 13, t: 13 * T },
            ],
        );
        assert_eq!(
            said[3..],
            [
                Said::Idle(Idle::WentSilent { last_seq: 2 }),
                Said::Arrived(Arrival::Resumed { lost: 9 }, 4, 1),
                Said::Arrived(Arrival::Next { lost: 0 }, 5, 2),
            ]
        );
        assert!(!s.is_silent());
        assert_eq!((s.counts().resumes, s.counts().lost), (1, 9));
    }

    #[test]
    fn a_sequence_restarting_from_zero_after_silence_is_a_new_session() {
        let (said, s) = run(
            2,
            &[
                Sample { seq: 40, t: 0 },
                Sample { seq: 41, t: T },
                Wait { t: 10 * T },
                Sample { seq: 0, t: 50 * T },
                Sample { seq: 1, t: 51 * T },
            ],
        );
        assert_eq!(
            said[2..],
            [
                Said::Idle(Idle::WentSilent { last_seq: 41 }),
                Said::Arrived(
                    Arrival::NewSession {
                        from: 41,
                        after_silence: true
                    },
                    1,
                    1
                ),
                Said::Arrived(Arrival::Next { lost: 0 }, 2, 2),
            ]
        );
        assert_eq!((s.counts().resumes, s.counts().lost), (1, 0));
    }

    #[test]
    fn duplicate_backward_and_restarted_sequence_numbers_start_a_new_session_without_silence() {
        let cases: [(&str, u64, u64); 3] = [
            ("duplicate", 5, 5),
            ("backward jump", 5, 3),
            ("restart from 0", 5, 0),
        ];
        for (what, last, next) in cases {
            let (said, s) = run(
                100,
                &[
                    Sample {
                        seq: last - 1,
                        t: 0,
                    },
                    Sample { seq: last, t: T },
                    Sample {
                        seq: next,
                        t: 2 * T,
                    },
                ],
            );
            assert_eq!(
                said[2],
                Said::Arrived(
                    Arrival::NewSession {
                        from: last,
                        after_silence: false
                    },
                    1,
                    1
                ),
                "{what}"
            );
            assert_eq!(s.counts().resumes, 0, "{what}");
        }
    }

    #[test]
    fn a_new_connection_forgets_the_receive_time_of_the_previous_one() {
        let mut s = SessionTracker::new(2, T);
        s.arrive(0);
        assert_eq!(s.answered(0), None);
        s.arrive(1);
        assert_eq!(s.answered(T + 5), Some(T + 5));
        assert_eq!(s.idle(10 * T), Idle::WentSilent { last_seq: 1 });
        s.arrive(2);
        // Neither a jitter across the silence nor a second silence before an answer.
        assert_eq!(s.idle(100 * T), Idle::Active);
        assert_eq!(s.answered(100 * T), None);
    }

    #[test]
    fn the_largest_sequence_number_does_not_overflow_the_gap() {
        let (said, _) = run(
            10,
            &[
                Sample {
                    seq: u64::MAX - 1,
                    t: 0,
                },
                Sample {
                    seq: u64::MAX,
                    t: T,
                },
            ],
        );
        assert_eq!(said[1], Said::Arrived(Arrival::Next { lost: 0 }, 2, 2));
    }
}
