//! The session tracker: what a sequence number says about the plant on the other side.
//!
//! The plant is the clock master and numbers its samples `k = 0, 1, 2, …`, stamping each
//! with its sample time `t_k` (CLOCK_MONOTONIC, ns). From the sequence numbers, the sample
//! times, the receive times and the peer's identity alone (no clock is read here: times
//! come in as arguments), the tracker classifies every received sample `k` against the last
//! accepted one, `k_last` at `t_last`. With `g = k − k_last − 1` the samples skipped and
//! `ĝ = 2 ⌊(t_k − t_last) / T⌋ + 8` the most the elapsed plant time can explain (`ĝ = 8` when
//! `t_k ≤ t_last`). A lockstep sample ([`ipc_types::measurement_flags::LOCKSTEP`]) is
//! stamped with the plant's wall clock while it waits for every answer, not with its plant
//! time: a lockstep plant skips the samples it was told to lose in no time at all, so for it
//! `ĝ = max(2 ⌊(t_k − t_last) / T⌋ + 8, 2¹⁶)`, the longest list of injected faults:
//!
//! | condition (first that holds)                      | [`Arrival`]                              | lost |
//! | ------------------------------------------------- | ---------------------------------------- | ---- |
//! | no sample accepted before                         | `First`                                  | 0    |
//! | the peer's identity changed (a new publisher)     | `NewSession { cause: NewPeer }`          | 0    |
//! | silent, and `k ≤ k_last` or `g > ĝ`               | `NewSession { cause: RestartAfterSilence }` | 0 |
//! | silent, `k > k_last`, `g ≤ ĝ`                     | `Resumed` (a stall)                      | `g`  |
//! | not silent, `k > k_last`, `g ≤ ĝ`                 | `Next`                                   | `g`  |
//! | not silent, `k = k_last`                          | `Refused(Duplicate)`                     | —    |
//! | not silent, `k < k_last`                          | `Refused(Backward)`                      | —    |
//! | not silent, `g > ĝ`                               | `Refused(ImplausibleJump)`               | —    |
//!
//! **Refused samples** are counted and never reach the controller; `k_last` stays. A
//! duplicate, a backward number or a jump that the plant's own clock cannot explain, from
//! the same peer while it is talking, is a fault of the stream, not a new plant.
//!
//! **Resynchronisation.** A plant that really restarted its numbering without going silent
//! would otherwise be refused for ever. When `R = resync_after` refused samples in a row
//! form a run `k, k + 1, …, k + R − 1`, the last of them begins a new session
//! (`NewSession { cause: Resynchronized }`). A single stray number never does.
//!
//! **Silence.** The plant is declared silent when, while idle at time `t` with no sample
//! waiting, the last answered sample was received at `t_recv,last` with
//! `t − t_recv,last > silent_periods · T` ([`SessionTracker::idle`]); it stays silent until
//! the next sample arrives. The caller must look for waiting samples *after* reading `t`,
//! so that a service that was itself stopped never takes its own stall for a silent plant.
//!
//! **Stall or new plant.** A sequence that continues after silence is the same plant whose
//! samples stopped for a while: a timing fault. Its session goes on: the samples between
//! are counted as lost and handed to the controller as a gap, the session's cycle count
//! (open-loop phase, tone windows) continues. A new session (a new peer, a restart after
//! silence, a resynchronisation) starts the session's cycle count again at 1.
//!
//! **Connection.** A resume and a new session start a new *connection*: its cycle count
//! starts again at 1, and the receive-time history used for the period jitter and the
//! silence timeout is forgotten. The deadline policy's grace period is counted in
//! connection cycles.
//!
//! Whether the controller keeps what it learned is not decided here (see
//! [`super::reset`]). Every method is O(1) and plain arithmetic.

/// Why a sample was refused (see the table in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SequenceFault {
    /// `k = k_last`.
    Duplicate,
    /// `k < k_last`.
    Backward,
    /// `k > k_last`, by more than the elapsed plant time explains.
    ImplausibleJump,
}

/// Why a new plant session began.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum NewSessionCause {
    /// Another publisher (a restarted or replaced plant process) sends the samples.
    NewPeer,
    /// After silence the sequence did not continue: the plant restarted.
    RestartAfterSilence,
    /// The same peer's refused numbers formed a consistent run of `resync_after` samples.
    Resynchronized,
}

impl NewSessionCause {
    /// Kebab-case name, for events and reports.
    pub fn name(self) -> &'static str {
        match self {
            NewSessionCause::NewPeer => "new-peer",
            NewSessionCause::RestartAfterSilence => "restart-after-silence",
            NewSessionCause::Resynchronized => "resynchronized",
        }
    }
}

/// What a received sample means for the session (see the table in the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// The first sample the service has accepted.
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
    /// A new plant session begins with this sample.
    NewSession {
        /// The last accepted sequence number of the previous session.
        from: u64,
        /// Why.
        cause: NewSessionCause,
    },
    /// The sample is refused: it must not reach the controller.
    Refused(SequenceFault),
}

impl Arrival {
    /// Samples lost just before this one, as the controller must be told
    /// (`StepInput::lost`).
    pub fn lost(&self) -> u64 {
        match *self {
            Arrival::Next { lost } | Arrival::Resumed { lost } => lost,
            Arrival::First | Arrival::NewSession { .. } | Arrival::Refused(_) => 0,
        }
    }

    /// True unless the sample was refused.
    pub fn accepted(&self) -> bool {
        !matches!(self, Arrival::Refused(_))
    }
}

/// What [`SessionTracker::idle`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Idle {
    /// The plant is not silent.
    Active,
    /// The plant has just been declared silent.
    WentSilent {
        /// The last sequence number accepted.
        last_seq: u64,
    },
    /// The plant was already silent.
    Silent,
}

/// Session counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SessionCounts {
    /// Samples received (accepted or refused, answered or not).
    pub received: u64,
    /// Samples never received: the gaps in the sequence within a session.
    pub lost: u64,
    /// Times the plant was declared silent.
    pub silences: u64,
    /// Times a sample arrived after silence (a stall resumed or a new session after it).
    pub resumes: u64,
    /// New plant sessions after the first.
    pub new_sessions: u64,
    /// Samples refused as duplicates.
    pub duplicates: u64,
    /// Samples refused for a backward sequence number.
    pub backward: u64,
    /// Samples refused for a forward jump the plant's clock cannot explain.
    pub implausible_jumps: u64,
}

/// Tracks sequence numbers, silence and the cycle counts of the session and connection.
#[derive(Debug, Clone)]
pub struct SessionTracker {
    silent_ns: u64,
    period_ns: u64,
    resync_after: u64,
    last_seq: Option<u64>,
    last_t_sample_ns: u64,
    last_answer_ns: Option<u64>,
    silent: bool,
    /// The next number of the current run of refused samples and its length.
    refused_run: Option<(u64, u64)>,
    session_cycles: u64,
    connection_cycles: u64,
    counts: SessionCounts,
}

/// Skipped samples allowed beyond twice the elapsed periods (`ĝ` of the module docs).
const JUMP_SLACK: u64 = 8;

/// The least `ĝ` of a lockstep sample: a plant's fault lists hold at most 65 536 entries.
const LOCKSTEP_JUMP_MAX: u64 = 1 << 16;

impl SessionTracker {
    /// A tracker that declares the plant silent after `silent_periods` periods of
    /// `period_ns` without a sample, and resynchronises after `resync_after` (at least 1)
    /// consistently numbered refused samples.
    pub fn new(silent_periods: u64, period_ns: u64, resync_after: u64) -> Self {
        Self {
            silent_ns: silent_periods.saturating_mul(period_ns),
            period_ns: period_ns.max(1),
            resync_after: resync_after.max(1),
            last_seq: None,
            last_t_sample_ns: 0,
            last_answer_ns: None,
            silent: false,
            refused_run: None,
            session_cycles: 0,
            connection_cycles: 0,
            counts: SessionCounts::default(),
        }
    }

    /// `ĝ` of the module docs for a sample stamped `t_sample_ns` (of a lockstep plant when
    /// `lockstep`).
    fn plausible_gap(&self, t_sample_ns: u64, lockstep: bool) -> u64 {
        let elapsed = t_sample_ns.saturating_sub(self.last_t_sample_ns) / self.period_ns;
        let by_time = elapsed.saturating_mul(2).saturating_add(JUMP_SLACK);
        if lockstep {
            by_time.max(LOCKSTEP_JUMP_MAX)
        } else {
            by_time
        }
    }

    /// Takes in received sample `seq` stamped `t_sample_ns` (answered or only observed);
    /// `new_peer` is true when it is the first sample of another publisher than the
    /// previous sample's, and `lockstep` when the sample carries the lockstep flag.
    /// Classifies it (module docs).
    pub fn arrive(
        &mut self,
        seq: u64,
        t_sample_ns: u64,
        new_peer: bool,
        lockstep: bool,
    ) -> Arrival {
        self.counts.received += 1;
        let arrival = match self.last_seq {
            None => Arrival::First,
            Some(from) if new_peer => Arrival::NewSession {
                from,
                cause: NewSessionCause::NewPeer,
            },
            Some(last) => {
                let forward =
                    seq > last && seq - last - 1 <= self.plausible_gap(t_sample_ns, lockstep);
                match (forward, self.silent) {
                    (true, true) => Arrival::Resumed {
                        lost: seq - last - 1,
                    },
                    (true, false) => Arrival::Next {
                        lost: seq - last - 1,
                    },
                    (false, true) => Arrival::NewSession {
                        from: last,
                        cause: NewSessionCause::RestartAfterSilence,
                    },
                    (false, false) => self.refuse_or_resync(seq, last),
                }
            }
        };
        if let Arrival::Refused(fault) = arrival {
            match fault {
                SequenceFault::Duplicate => self.counts.duplicates += 1,
                SequenceFault::Backward => self.counts.backward += 1,
                SequenceFault::ImplausibleJump => self.counts.implausible_jumps += 1,
            }
            return arrival;
        }
        self.refused_run = None;
        if self.silent {
            self.silent = false;
            self.counts.resumes += 1;
        }
        self.counts.lost += arrival.lost();
        match arrival {
            Arrival::First | Arrival::Next { .. } | Arrival::Refused(_) => {}
            Arrival::Resumed { .. } => self.new_connection(),
            Arrival::NewSession { .. } => {
                self.counts.new_sessions += 1;
                self.new_connection();
                self.session_cycles = 0;
            }
        }
        self.last_seq = Some(seq);
        self.last_t_sample_ns = t_sample_ns;
        self.session_cycles += 1;
        self.connection_cycles += 1;
        arrival
    }

    /// A sample of the talking peer that does not follow `last`: refused, unless it
    /// completes a consistent run of `resync_after` refused samples.
    fn refuse_or_resync(&mut self, seq: u64, last: u64) -> Arrival {
        let run = match self.refused_run {
            Some((next, len)) if next == seq => len + 1,
            _ => 1,
        };
        if run >= self.resync_after {
            return Arrival::NewSession {
                from: last,
                cause: NewSessionCause::Resynchronized,
            };
        }
        self.refused_run = Some((seq.wrapping_add(1), run));
        Arrival::Refused(if seq == last {
            SequenceFault::Duplicate
        } else if seq < last {
            SequenceFault::Backward
        } else {
            SequenceFault::ImplausibleJump
        })
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

    /// Called at time `now_ns` after finding no sample waiting (looked for after reading
    /// `now_ns`): declares the plant silent when the last answered sample is more than
    /// `silent_periods` periods old.
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

    /// The sequence number of the last accepted sample (`None` before any).
    pub fn last_seq(&self) -> Option<u64> {
        self.last_seq
    }

    /// The sample time of the last accepted sample, ns (0 before any).
    pub fn last_sample_time_ns(&self) -> u64 {
        self.last_t_sample_ns
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

    /// One step of a scripted plant: a sample `seq` stamped `t` arrives (from another
    /// publisher for `FromNewPeer`) and is answered at `t`, or the service is idle at `t`.
    #[derive(Clone, Copy)]
    enum Step {
        Sample { seq: u64, t: u64 },
        FromNewPeer { seq: u64, t: u64 },
        Idle { t: u64 },
    }

    /// What the tracker said at one step: the arrival or idle verdict, and the session and
    /// connection cycles after it.
    #[derive(Debug, PartialEq, Eq)]
    enum Said {
        Arrived(Arrival, u64, u64),
        Idle(Idle),
    }

    fn run_with(
        silent_periods: u64,
        resync_after: u64,
        steps: &[Step],
    ) -> (Vec<Said>, SessionTracker) {
        let mut s = SessionTracker::new(silent_periods, T, resync_after);
        let said = steps
            .iter()
            .map(|step| {
                let (seq, t, new_peer) = match *step {
                    Step::Sample { seq, t } => (seq, t, false),
                    Step::FromNewPeer { seq, t } => (seq, t, true),
                    Step::Idle { t } => return Said::Idle(s.idle(t)),
                };
                let a = s.arrive(seq, t, new_peer, false);
                if a.accepted() {
                    s.answered(t);
                }
                Said::Arrived(a, s.session_cycle(), s.connection_cycle())
            })
            .collect();
        (said, s)
    }

    fn run(silent_periods: u64, steps: &[Step]) -> (Vec<Said>, SessionTracker) {
        run_with(silent_periods, 1000, steps)
    }

    /// Samples `from..to`, each answered at its own sample time.
    fn samples(from: u64, to: u64) -> impl Iterator<Item = Step> {
        (from..to).map(|seq| Sample { seq, t: seq * T })
    }

    use Step::{FromNewPeer, Idle as Wait, Sample};

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
                ..SessionCounts::default()
            }
        );
    }

    #[test]
    fn a_gap_the_plant_clock_explains_is_lost_samples_not_a_fault() {
        // The service was stopped for 6400 periods while the plant went on.
        let (said, s) = run(
            20,
            &[
                Sample { seq: 10, t: 10 * T },
                Sample {
                    seq: 6411,
                    t: 6411 * T,
                },
            ],
        );
        assert_eq!(said[1], Said::Arrived(Arrival::Next { lost: 6400 }, 2, 2));
        assert_eq!(s.counts().lost, 6400);
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
        let mut steps: Vec<Step> = samples(0, 3).collect();
        steps.push(Wait { t: 10 * T });
        steps.extend(samples(12, 14));
        let (said, s) = run(2, &steps);
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
        assert_eq!(s.counts().new_sessions, 0);
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
                        cause: NewSessionCause::RestartAfterSilence
                    },
                    1,
                    1
                ),
                Said::Arrived(Arrival::Next { lost: 0 }, 2, 2),
            ]
        );
        assert_eq!(
            (s.counts().resumes, s.counts().new_sessions, s.counts().lost),
            (1, 1, 0)
        );
    }

    #[test]
    fn duplicate_backward_and_unexplained_numbers_of_a_talking_peer_are_refused_and_counted() {
        let cases: [(&str, u64, SequenceFault); 4] = [
            ("duplicate", 5, SequenceFault::Duplicate),
            ("backward jump", 3, SequenceFault::Backward),
            ("restart from 0", 0, SequenceFault::Backward),
            ("jump far ahead", 1 << 40, SequenceFault::ImplausibleJump),
        ];
        for (what, stray, fault) in cases {
            let (said, s) = run(
                100,
                &[
                    Sample { seq: 4, t: 4 * T },
                    Sample { seq: 5, t: 5 * T },
                    Sample {
                        seq: stray,
                        t: 6 * T,
                    },
                    Sample { seq: 6, t: 6 * T },
                ],
            );
            assert_eq!(
                said[2],
                Said::Arrived(Arrival::Refused(fault), 2, 2),
                "{what}"
            );
            // The stream goes on from the last accepted number, nothing lost or reset.
            assert_eq!(
                said[3],
                Said::Arrived(Arrival::Next { lost: 0 }, 3, 3),
                "{what}"
            );
            let c = s.counts();
            assert_eq!(
                (
                    c.duplicates + c.backward + c.implausible_jumps,
                    c.new_sessions,
                    c.lost
                ),
                (1, 0, 0),
                "{what}"
            );
        }
    }

    #[test]
    fn a_restarted_numbering_without_silence_is_taken_after_a_consistent_run() {
        let mut steps: Vec<Step> = samples(100, 103).collect();
        steps.extend(samples(0, 4));
        let (said, s) = run_with(100, 3, &steps);
        assert_eq!(
            said[3],
            Said::Arrived(Arrival::Refused(SequenceFault::Backward), 3, 3)
        );
        assert_eq!(
            said[4],
            Said::Arrived(Arrival::Refused(SequenceFault::Backward), 3, 3)
        );
        assert_eq!(
            said[5],
            Said::Arrived(
                Arrival::NewSession {
                    from: 102,
                    cause: NewSessionCause::Resynchronized
                },
                1,
                1
            )
        );
        assert_eq!(said[6], Said::Arrived(Arrival::Next { lost: 0 }, 2, 2));
        assert_eq!((s.counts().backward, s.counts().new_sessions), (2, 1));
    }

    #[test]
    fn stray_numbers_between_good_samples_never_resynchronise() {
        let mut steps = Vec::new();
        for k in 10..40 {
            steps.push(Sample { seq: k, t: k * T });
            steps.push(Sample { seq: 0, t: k * T });
        }
        let (said, s) = run_with(100, 2, &steps);
        assert!(
            said.iter()
                .all(|x| !matches!(x, Said::Arrived(Arrival::NewSession { .. }, ..)))
        );
        assert_eq!((s.counts().backward, s.counts().new_sessions), (30, 0));
    }

    #[test]
    fn a_new_publisher_begins_a_new_session_even_when_its_numbers_continue() {
        let (said, s) = run(
            100,
            &[
                Sample { seq: 0, t: 0 },
                Sample { seq: 1, t: T },
                FromNewPeer { seq: 2, t: 2 * T },
            ],
        );
        assert_eq!(
            said[2],
            Said::Arrived(
                Arrival::NewSession {
                    from: 1,
                    cause: NewSessionCause::NewPeer
                },
                1,
                1
            )
        );
        assert_eq!(s.counts().new_sessions, 1);
    }

    #[test]
    fn a_new_connection_forgets_the_receive_time_of_the_previous_one() {
        let mut s = SessionTracker::new(2, T, 10);
        s.arrive(0, 0, false, false);
        assert_eq!(s.answered(0), None);
        s.arrive(1, T, false, false);
        assert_eq!(s.answered(T + 5), Some(T + 5));
        assert_eq!(s.idle(10 * T), Idle::WentSilent { last_seq: 1 });
        s.arrive(2, 2 * T, false, false);
        // Neither a jitter across the silence nor a second silence before an answer.
        assert_eq!(s.idle(100 * T), Idle::Active);
        assert_eq!(s.answered(100 * T), None);
    }

    #[test]
    fn the_largest_sequence_number_does_not_overflow_the_gap() {
        let mut s = SessionTracker::new(10, T, 10);
        assert_eq!(s.arrive(u64::MAX - 1, 5 * T, false, false), Arrival::First);
        assert_eq!(
            s.arrive(u64::MAX, 6 * T, false, false),
            Arrival::Next { lost: 0 }
        );
        assert_eq!(
            s.arrive(u64::MAX, 7 * T, false, false),
            Arrival::Refused(SequenceFault::Duplicate)
        );
    }

    #[test]
    fn a_lockstep_plant_may_skip_a_burst_in_no_time_a_real_time_one_may_not() {
        // 16 samples lost between two samples stamped 1 µs apart: the plant's time cannot
        // explain them in real time (ĝ = 8), a lockstep plant skips them without waiting.
        for (lockstep, expected) in [
            (true, Arrival::Next { lost: 16 }),
            (false, Arrival::Refused(SequenceFault::ImplausibleJump)),
        ] {
            let mut s = SessionTracker::new(10, T, 10);
            s.arrive(100, 50 * T, false, lockstep);
            assert_eq!(s.arrive(117, 50 * T + 1_000, false, lockstep), expected);
        }
        // A lockstep jump beyond the longest fault list is still refused.
        let mut s = SessionTracker::new(10, T, 10);
        s.arrive(0, T, false, true);
        assert_eq!(
            s.arrive(1 + LOCKSTEP_JUMP_MAX + 1, T + 1_000, false, true),
            Arrival::Refused(SequenceFault::ImplausibleJump)
        );
    }
}
