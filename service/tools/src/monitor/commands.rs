//! Operator commands as the monitor and `rig command` send them: a command by name
//! ([`CommandRequest`], the body of `POST /api/command`) checked and turned into an
//! [`OperatorRequest`] ([`CommandRequest::to_request`]), sent over the rig's operator
//! service ([`send`]), and the service's [`OperatorReply`] as JSON ([`CommandReply`]).
//!
//! The monitor checks only the form of a command (a known name; for `set-tunable` a name
//! that fits and a finite value); whether it applies is the service's to say (a tunable
//! out of bounds, adaptation of a controller that does not adapt, …).

use ipc_types::operator::{
    OperatorClient, OperatorError, OperatorReply, OperatorRequest, command, outcome,
};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// How long the monitor and `rig command` wait for a reply by default: the loop applies a
/// command at its next sample boundary.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(2);

/// Bytes a tunable's name may have (the contract's field holds 31 and a NUL).
pub const TUNABLE_NAME_MAX: usize = 31;

/// A command by name, as `POST /api/command` takes it.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandRequest {
    /// The rig (one of the monitor's `--rig`).
    pub rig: String,
    /// A command name: `freeze-adaptation`, `resume-adaptation`, `enter-safe-state`,
    /// `leave-safe-state`, `stop-run` or `set-tunable`.
    pub command: String,
    /// For `set-tunable`: the tunable's name.
    #[serde(default)]
    pub tunable: Option<String>,
    /// For `set-tunable`: the new value.
    #[serde(default)]
    pub value: Option<f64>,
}

/// The names of the commands, comma-separated, for messages.
pub fn command_names() -> String {
    command::ALL
        .iter()
        .map(|(_, n)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A request id unique within this process and unlikely to repeat across processes.
pub fn next_request_id() -> u64 {
    (u64::from(std::process::id()) << 32) | (NEXT_ID.fetch_add(1, Ordering::Relaxed) & 0xffff_ffff)
}

impl CommandRequest {
    /// The operator request of this command, or why it is malformed.
    ///
    /// # Errors
    ///
    /// An unknown command, `set-tunable` without a tunable name (or one too long) or
    /// without a finite value, or a tunable or value given to another command.
    pub fn to_request(&self, request_id: u64) -> Result<OperatorRequest, String> {
        let code = command::from_name(&self.command).ok_or_else(|| {
            format!(
                "unknown command '{}' (one of: {})",
                self.command,
                command_names()
            )
        })?;
        if code != command::SET_TUNABLE {
            if self.tunable.is_some() || self.value.is_some() {
                return Err(format!(
                    "'{}' takes no tunable or value (only set-tunable does)",
                    self.command
                ));
            }
            return Ok(OperatorRequest::new(code, request_id));
        }
        let name = match self.tunable.as_deref() {
            Some(n) if !n.is_empty() => n,
            _ => return Err("set-tunable needs the tunable's name ('tunable')".into()),
        };
        if name.len() > TUNABLE_NAME_MAX || name.contains('\0') {
            return Err(format!(
                "tunable name '{name}' is longer than {TUNABLE_NAME_MAX} bytes or holds a NUL"
            ));
        }
        let value = match self.value {
            Some(v) if v.is_finite() => v,
            Some(v) => return Err(format!("set-tunable needs a finite value, not {v}")),
            None => return Err("set-tunable needs a value ('value')".into()),
        };
        Ok(OperatorRequest::set_tunable(name, value, request_id))
    }
}

/// Sends `request` to rig `rig`'s service and waits up to `timeout` for its reply
/// (blocking: call it off an async executor).
///
/// # Errors
///
/// No service of the rig serves commands, the request could not be sent, or no reply
/// came in time.
pub fn send(
    rig: &str,
    request: &OperatorRequest,
    timeout: Duration,
) -> Result<OperatorReply, OperatorError> {
    OperatorClient::open(rig)?.send(request, timeout)
}

/// A reply as JSON (`POST /api/command`'s answer).
#[derive(Debug, Clone, Serialize)]
pub struct CommandReply {
    /// The rig.
    pub rig: String,
    /// The command's name.
    pub command: String,
    /// The request's id.
    pub request_id: u64,
    /// `applied`, `refused`, `not-enabled`, `run-ended` or `bad-request`.
    pub outcome: &'static str,
    /// Whether the loop applied it.
    pub applied: bool,
    /// The service's reason when it did not.
    pub message: String,
    /// The command took effect before the sample with this index (`null` when it did not
    /// apply).
    pub applied_before_seq: Option<u64>,
    /// For `set-tunable`: the value in force after the command.
    pub value: Option<f64>,
}

impl CommandReply {
    /// The view of `reply` to `request` sent to `rig`.
    pub fn of(rig: &str, request: &OperatorRequest, reply: &OperatorReply) -> Self {
        let applied = reply.outcome == outcome::APPLIED;
        Self {
            rig: rig.to_string(),
            command: command::name(request.command)
                .unwrap_or("unknown")
                .to_string(),
            request_id: reply.request_id,
            outcome: outcome::name(reply.outcome),
            applied,
            message: reply.message().to_string(),
            applied_before_seq: applied.then_some(reply.applied_before_seq),
            value: reply.value.is_finite().then_some(reply.value),
        }
    }

    /// One line for a terminal.
    pub fn line(&self) -> String {
        let mut s = format!("{}: {}: {}", self.rig, self.command, self.outcome);
        if let Some(k) = self.applied_before_seq {
            s += &format!(" before sample {k}");
        }
        if let Some(v) = self.value {
            s += &format!(", value {v}");
        }
        if !self.message.is_empty() {
            s += &format!(": {}", self.message);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(command: &str, tunable: Option<&str>, value: Option<f64>) -> CommandRequest {
        CommandRequest {
            rig: "r".into(),
            command: command.into(),
            tunable: tunable.map(Into::into),
            value,
        }
    }

    #[test]
    fn commands_are_checked_for_form() {
        let r = req("freeze-adaptation", None, None).to_request(3).unwrap();
        assert_eq!((r.command, r.request_id), (command::FREEZE_ADAPTATION, 3));
        let r = req("set-tunable", Some("alpha"), Some(0.3))
            .to_request(4)
            .unwrap();
        assert_eq!((r.tunable(), r.value), ("alpha", 0.3));
        assert!(
            req("reboot", None, None)
                .to_request(1)
                .unwrap_err()
                .contains("unknown command 'reboot'")
        );
        assert!(req("set-tunable", None, Some(1.0)).to_request(1).is_err());
        assert!(req("set-tunable", Some("a"), None).to_request(1).is_err());
        assert!(
            req("set-tunable", Some("a"), Some(f64::NAN))
                .to_request(1)
                .is_err()
        );
        assert!(
            req("set-tunable", Some(&"x".repeat(32)), Some(1.0))
                .to_request(1)
                .is_err()
        );
        assert!(req("stop-run", None, Some(1.0)).to_request(1).is_err());
    }

    #[test]
    fn a_reply_says_its_outcome_and_where_it_applied() {
        let request = OperatorRequest::set_tunable("alpha", 0.3, 9);
        let mut reply = OperatorReply::new(9, outcome::APPLIED, "");
        reply.applied_before_seq = 1200;
        reply.value = 0.3;
        let v = CommandReply::of("r", &request, &reply);
        assert!(v.applied);
        assert_eq!(
            v.line(),
            "r: set-tunable: applied before sample 1200, value 0.3"
        );
        let reply = OperatorReply::new(9, outcome::REFUSED, "out of bounds");
        let v = CommandReply::of("r", &request, &reply);
        assert_eq!((v.applied, v.applied_before_seq), (false, None));
        assert_eq!(v.line(), "r: set-tunable: refused: out of bounds");
    }
}
