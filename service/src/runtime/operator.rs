//! Operator commands inside the loop: what the RT thread takes from the operator thread,
//! and what it gives back.
//!
//! The operator thread ([`crate::operator`]) receives requests over iceoryx2, checks them
//! against the configuration (a declared tunable, its bounds) and queues each as a
//! [`Queued`] command in a wait-free ring. [`LoopCore`](super::LoopCore) takes the queued
//! commands at a sample boundary (before it handles the next sample, or while the plant is
//! silent), applies each ([`LoopCore::apply_command`](super::LoopCore::apply_command)),
//! records it for `service replay` and queues an [`Applied`] result back. Nothing here
//! allocates, locks or blocks; both rings are sized before the loop starts.

use ipc_types::operator::command;

/// A command as the loop applies it, already checked by the operator thread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Stop the controller's adaptation ([`control::Controller::set_adaptation`]).
    FreezeAdaptation,
    /// Resume it.
    ResumeAdaptation,
    /// Hold the loop in its safe state.
    EnterSafeState,
    /// Release the operator's hold and the deadline monitor's latch.
    LeaveSafeState,
    /// End the run.
    StopRun,
    /// Set tunable `index` of the controller's [`control::Controller::tunables`].
    SetTunable {
        /// Its index.
        index: usize,
        /// The new value (within the declared bounds).
        value: f64,
    },
}

impl Command {
    /// The wire code ([`ipc_types::operator::command`]).
    pub fn code(self) -> u32 {
        match self {
            Command::FreezeAdaptation => command::FREEZE_ADAPTATION,
            Command::ResumeAdaptation => command::RESUME_ADAPTATION,
            Command::EnterSafeState => command::ENTER_SAFE_STATE,
            Command::LeaveSafeState => command::LEAVE_SAFE_STATE,
            Command::StopRun => command::STOP_RUN,
            Command::SetTunable { .. } => command::SET_TUNABLE,
        }
    }

    /// The command of a wire code; `index` and `value` are used by `set-tunable` only.
    pub fn from_code(code: u32, index: usize, value: f64) -> Option<Self> {
        Some(match code {
            command::FREEZE_ADAPTATION => Command::FreezeAdaptation,
            command::RESUME_ADAPTATION => Command::ResumeAdaptation,
            command::ENTER_SAFE_STATE => Command::EnterSafeState,
            command::LEAVE_SAFE_STATE => Command::LeaveSafeState,
            command::STOP_RUN => Command::StopRun,
            command::SET_TUNABLE => Command::SetTunable { index, value },
            _ => return None,
        })
    }

    /// Its name (`"freeze-adaptation"`, …).
    pub fn name(self) -> &'static str {
        command::name(self.code()).unwrap_or("unknown")
    }
}

/// A command waiting for the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Queued {
    /// The request's id (echoed in the reply).
    pub request_id: u64,
    /// The command.
    pub command: Command,
}

/// What the loop did with a command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Applied {
    /// The command as queued.
    pub queued: Queued,
    /// `None`: applied; `Some(reason)`: refused, nothing changed.
    pub refused: Option<&'static str>,
    /// It took effect before the handling of the sample with this index.
    pub before_seq: u64,
    /// For `set-tunable`: the tunable's value in force after the command (NaN otherwise).
    pub value: f64,
}

/// The loop's end of the two rings.
#[derive(Debug)]
pub struct OperatorInbox {
    pub(super) commands: rtrb::Consumer<Queued>,
    pub(super) results: rtrb::Producer<Applied>,
}

/// The operator thread's end of the two rings.
#[derive(Debug)]
pub struct OperatorOutbox {
    /// Where checked commands go to the loop.
    pub commands: rtrb::Producer<Queued>,
    /// Where the loop's results come back.
    pub results: rtrb::Consumer<Applied>,
}

/// Commands in flight at most (the rings' capacity): more are refused by the operator
/// thread as busy.
pub const MAX_IN_FLIGHT: usize = 64;

/// The two rings, allocated once before the loop starts.
pub fn channel() -> (OperatorOutbox, OperatorInbox) {
    let (command_tx, command_rx) = rtrb::RingBuffer::new(MAX_IN_FLIGHT);
    let (result_tx, result_rx) = rtrb::RingBuffer::new(MAX_IN_FLIGHT);
    (
        OperatorOutbox {
            commands: command_tx,
            results: result_rx,
        },
        OperatorInbox {
            commands: command_rx,
            results: result_tx,
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_command_round_trips_through_its_wire_code() {
        let all = [
            Command::FreezeAdaptation,
            Command::ResumeAdaptation,
            Command::EnterSafeState,
            Command::LeaveSafeState,
            Command::StopRun,
            Command::SetTunable {
                index: 2,
                value: 0.5,
            },
        ];
        for c in all {
            assert_eq!(Command::from_code(c.code(), 2, 0.5), Some(c));
        }
        assert_eq!(Command::from_code(99, 0, 0.0), None);
        assert_eq!(Command::StopRun.name(), "stop-run");
    }
}
