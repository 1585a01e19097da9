//! The events the RT loop reports (plant connected, silent, resumed, a new plant session,
//! foreign actuation, the safe state entered and left): carried out of the loop through a
//! lock-free queue and printed by the supervising thread.

use super::session::NewSessionCause;
use serde::Serialize;
use std::fmt;

/// Something the RT loop reports; carried out of it through a lock-free queue.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "kebab-case")]
pub enum LoopEvent {
    /// The first sample of a plant session arrived.
    FirstSample {
        /// Its sequence number.
        seq: u64,
    },
    /// No sample for the configured number of periods.
    PlantSilent {
        /// The last sequence number received.
        last_seq: u64,
        /// Periods waited.
        periods: u64,
    },
    /// Samples came back after silence (a stall resumed, or a new plant session, which is
    /// then also reported as [`LoopEvent::NewPlantSession`]).
    PlantResumed {
        /// The first sequence number received again.
        seq: u64,
    },
    /// A new plant session begins: another publisher, a sequence restarted after silence,
    /// or a consistent new numbering (see [`session`](super::session)).
    NewPlantSession {
        /// The last sequence number of the previous session.
        from: u64,
        /// The first of the new one.
        to: u64,
        /// Why.
        cause: NewSessionCause,
        /// The safe state of the previous session was cleared.
        left_safe_state: bool,
    },
    /// The plant reported applying an input the service did not send (beyond
    /// `service.u-applied-tolerance`) for an actuation it says came in time: another
    /// process drives the actuators, or the plant alters the inputs. Reported at the first
    /// mismatch of a run of them.
    ForeignActuation {
        /// The sample that carried the report.
        seq: u64,
        /// The largest `|u_applied − u_sent|`.
        difference: f64,
    },
    /// Too many consecutive deadline misses: the safe input is applied.
    SafeStateEntered {
        /// Sequence number at which it happened.
        seq: u64,
        /// Consecutive misses counted.
        misses: u64,
    },
    /// The safe state was left after enough good answers.
    SafeStateLeft {
        /// Sequence number at which it happened.
        seq: u64,
    },
    /// The plant said this was its last sample.
    PlantEnded {
        /// Its sequence number.
        seq: u64,
    },
    /// Stale resources of dead iceoryx2 nodes were removed.
    DeadNodesCleaned {
        /// How many nodes.
        count: u64,
    },
    /// An operator command was applied or refused ([`crate::runtime::operator`]).
    Operator {
        /// It took effect before the sample with this index.
        before_seq: u64,
        /// The command's name.
        command: &'static str,
        /// Why it was refused; `None`: applied.
        refused: Option<&'static str>,
    },
}

impl fmt::Display for LoopEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoopEvent::FirstSample { seq } => write!(f, "plant connected: first sample seq {seq}"),
            LoopEvent::PlantSilent { last_seq, periods } => write!(
                f,
                "PLANT SILENT: no sample for {periods} periods after seq {last_seq}; waiting for it to come back"
            ),
            LoopEvent::PlantResumed { seq } => write!(f, "plant resumed at seq {seq}"),
            LoopEvent::NewPlantSession {
                from,
                to,
                cause,
                left_safe_state,
            } => write!(
                f,
                "NEW PLANT SESSION ({}): sequence {from} -> {to}{}",
                cause.name(),
                if *left_safe_state {
                    "; the safe state of the previous session is cleared"
                } else {
                    ""
                }
            ),
            LoopEvent::ForeignActuation { seq, difference } => write!(
                f,
                "FOREIGN ACTUATION at seq {seq}: the plant applied an input the service did not \
                 send (|u_applied − u_sent| = {difference:.3e}); is another process publishing \
                 on this rig?"
            ),
            LoopEvent::SafeStateEntered { seq, misses } => write!(
                f,
                "SAFE STATE at seq {seq}: {misses} consecutive deadline misses; applying the safe input"
            ),
            LoopEvent::SafeStateLeft { seq } => write!(f, "safe state left at seq {seq}"),
            LoopEvent::PlantEnded { seq } => write!(f, "plant ended its run at seq {seq}"),
            LoopEvent::Operator {
                before_seq,
                command,
                refused: None,
            } => write!(f, "OPERATOR: {command} applied before seq {before_seq}"),
            LoopEvent::Operator {
                before_seq,
                command,
                refused: Some(why),
            } => write!(
                f,
                "OPERATOR: {command} refused before seq {before_seq}: {why}"
            ),
            LoopEvent::DeadNodesCleaned { count } => {
                write!(
                    f,
                    "removed stale resources of {count} dead iceoryx2 node(s)"
                )
            }
        }
    }
}
