//! Operator commands at a sample boundary ([`super::super::operator`]).

use super::super::LoopEvent;
use super::super::operator::{Applied, Command, Queued};
use super::super::reset::ResetCause;
use super::LoopCore;

impl LoopCore {
    /// Applies every queued operator command, in order, and queues each result back; called
    /// by the RT loop before it handles a sample and while the plant is silent. Without an
    /// operator inbox it does nothing. Never allocates, locks or blocks.
    #[inline]
    pub fn take_commands(&mut self) {
        let Some(inbox) = self.operator.as_mut() else {
            return;
        };
        let Ok(q) = inbox.commands.pop() else {
            return;
        };
        let mut next = Some(q);
        while let Some(q) = next {
            let applied = self.apply_command(q);
            let Some(inbox) = self.operator.as_mut() else {
                return;
            };
            // The result ring holds as many as the command ring: it cannot be full while
            // the operator thread keeps at most that many in flight.
            let _ = inbox.results.push(applied);
            next = inbox.commands.pop().ok();
        }
    }

    /// Applies one command before the next sample (recorded for `service replay`, which
    /// calls this with the recorded commands) and returns what happened. A refused command
    /// changes nothing.
    pub fn apply_command(&mut self, q: Queued) -> Applied {
        if let Some(r) = self.recorder.as_mut() {
            r.operator(&q);
        }
        let before_seq = self.session.last_seq().map_or(0, |s| s + 1);
        let mut value = f64::NAN;
        let refused = match q.command {
            Command::FreezeAdaptation | Command::ResumeAdaptation => {
                let on = q.command == Command::ResumeAdaptation;
                if self.controller.set_adaptation(on) {
                    self.adaptation_frozen = !on;
                    None
                } else {
                    Some("this controller does not adapt")
                }
            }
            Command::EnterSafeState => {
                self.operator_safe = true;
                None
            }
            Command::LeaveSafeState => {
                self.operator_safe = false;
                if self.deadline.release() {
                    self.reset_controller_if(ResetCause::LeftSafeState);
                    self.event(LoopEvent::SafeStateLeft { seq: before_seq });
                }
                None
            }
            Command::StopRun => {
                self.stop_requested = true;
                None
            }
            Command::SetTunable { index, value: v } => {
                if self.controller.set_tunable(index, v) {
                    value = self.controller.tunable(index).unwrap_or(f64::NAN);
                    None
                } else {
                    Some("this controller does not use that tunable")
                }
            }
        };
        if refused.is_none() {
            self.stats.commands_applied += 1;
        } else {
            self.stats.commands_refused += 1;
        }
        self.event(LoopEvent::Operator {
            before_seq,
            command: q.command.name(),
            refused,
        });
        self.push_live_state();
        Applied {
            queued: q,
            refused,
            before_seq,
            value,
        }
    }

    /// The operator asked the run to end.
    pub fn stop_requested(&self) -> bool {
        self.stop_requested
    }

    /// The operator holds the loop in its safe state.
    pub fn operator_safe(&self) -> bool {
        self.operator_safe
    }
}
