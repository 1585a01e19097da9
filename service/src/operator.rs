//! # operator: the thread that serves operator commands
//!
//! The service's operator thread holds the server of `adaptive-rig/<rig>/operator`
//! ([`ipc_types::operator`]). For each request it checks what it can without the loop —
//! the contract version, the command code, whether this configuration accepts commands
//! (`service.operator.commands`), a `set-tunable`'s name among the declared tunables and
//! its value within their bounds (`service.operator.tunables`) — and answers a request it
//! refuses at once. A valid command goes to the RT loop through a wait-free ring
//! ([`crate::runtime::operator`]), which applies it at the next sample boundary; the
//! loop's result becomes the reply. Every request, answered by this thread or by the
//! loop, is kept for the run report ([`CommandRecord`]).
//!
//! A request still waiting when the run ends gets [`outcome::RUN_ENDED`].

use crate::config::{DeclaredTunable, ServiceConfig};
use crate::runtime::operator::{Applied, Command, MAX_IN_FLIGHT, OperatorOutbox, Queued};
use ipc_types::operator::{
    OPERATOR_VERSION, OperatorReply, OperatorRequest, OperatorServer, PendingCommand, command,
    outcome,
};
use serde::Serialize;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// One operator request and what became of it, for the run report (in the order the
/// requests were answered).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CommandRecord {
    /// The request's id.
    pub request_id: u64,
    /// The command's name (or its unknown code).
    pub command: String,
    /// For `set-tunable`: the tunable and the value asked for.
    pub tunable: Option<(String, f64)>,
    /// [`ipc_types::operator::outcome`]'s name: `applied`, `refused`, ….
    pub outcome: String,
    /// Why, when not applied.
    pub message: Option<String>,
    /// It took effect before the sample with this index (applied commands).
    pub before_seq: Option<u64>,
}

/// A request answered without the loop: its outcome code and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refusal {
    /// An [`ipc_types::operator::outcome`] code.
    pub outcome: u32,
    /// Why.
    pub message: String,
}

/// Checks `r` against the configuration; the command to queue, or why it is refused.
pub fn check(
    r: &OperatorRequest,
    commands_enabled: bool,
    tunables: &[DeclaredTunable],
    origin: &str,
) -> Result<Command, Refusal> {
    let refuse = |outcome, message: String| Err(Refusal { outcome, message });
    if r.version != OPERATOR_VERSION {
        return refuse(
            outcome::BAD_REQUEST,
            format!(
                "operator contract version {}, this service speaks version {OPERATOR_VERSION}",
                r.version
            ),
        );
    }
    if command::name(r.command).is_none() {
        return refuse(
            outcome::BAD_REQUEST,
            format!("unknown command code {}", r.command),
        );
    }
    if !commands_enabled {
        return refuse(
            outcome::NOT_ENABLED,
            format!("{origin} sets service.operator.commands = false"),
        );
    }
    if r.command != command::SET_TUNABLE {
        return match Command::from_code(r.command, 0, 0.0) {
            Some(c) => Ok(c),
            None => refuse(
                outcome::BAD_REQUEST,
                format!("unknown command code {}", r.command),
            ),
        };
    }
    let name = r.tunable();
    let Some(t) = tunables.iter().find(|t| t.name == name) else {
        let declared: Vec<&str> = tunables.iter().map(|t| t.name.as_str()).collect();
        return refuse(
            outcome::REFUSED,
            format!(
                "'{name}' is not a declared tunable (service.operator.tunables in {origin} \
                 declares {})",
                if declared.is_empty() {
                    "none".to_string()
                } else {
                    declared.join(", ")
                }
            ),
        );
    };
    if !(r.value >= t.min && r.value <= t.max) {
        return refuse(
            outcome::REFUSED,
            format!(
                "{} is outside [{}, {}], the bounds of service.operator.tunables.{name} in \
                 {origin}",
                r.value, t.min, t.max
            ),
        );
    }
    Ok(Command::SetTunable {
        index: t.index,
        value: r.value,
    })
}

fn record_of(r: &OperatorRequest, reply: &OperatorReply) -> CommandRecord {
    CommandRecord {
        request_id: r.request_id,
        command: command::name(r.command)
            .map(str::to_string)
            .unwrap_or_else(|| format!("code {}", r.command)),
        tunable: (r.command == command::SET_TUNABLE).then(|| (r.tunable().to_string(), r.value)),
        outcome: outcome::name(reply.outcome).to_string(),
        message: (!reply.message().is_empty()).then(|| reply.message().to_string()),
        before_seq: (reply.outcome == outcome::APPLIED).then_some(reply.applied_before_seq),
    }
}

fn reply_of(a: &Applied) -> OperatorReply {
    let mut reply = match a.refused {
        None => OperatorReply::new(a.queued.request_id, outcome::APPLIED, ""),
        Some(why) => OperatorReply::new(a.queued.request_id, outcome::REFUSED, why),
    };
    if a.refused.is_none() {
        reply.applied_before_seq = a.before_seq;
    }
    reply.value = a.value;
    reply
}

/// The run's handle on the operator thread.
#[derive(Debug)]
pub struct OperatorThread {
    stop: Arc<AtomicBool>,
    handle: std::thread::JoinHandle<Vec<CommandRecord>>,
}

impl OperatorThread {
    /// Starts the thread serving rig `cfg.rig`'s operator service with `outbox` (the
    /// loop's rings). When the server cannot be created (another service holds it), it
    /// says so once and serves nothing.
    pub fn spawn(cfg: &ServiceConfig, mut outbox: OperatorOutbox) -> std::io::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = stop.clone();
        let rig = cfg.rig.clone();
        let enabled = cfg.live.commands;
        let tunables = cfg.live.tunables.clone();
        let origin = cfg.origin.clone();
        let handle = std::thread::Builder::new()
            .name("operator".into())
            .spawn(move || {
                let mut records = Vec::new();
                let server = match OperatorServer::create(&rig) {
                    Ok(s) => s,
                    Err(e) => {
                        eprintln!("[service] WARNING: operator commands not served: {e}");
                        return records;
                    }
                };
                let mut waiting: HashMap<u64, (OperatorRequest, PendingCommand)> = HashMap::new();
                let mut next_id = 0u64;
                let mut answer = |p: PendingCommand, r: &OperatorRequest, reply: &OperatorReply| {
                    records.push(record_of(r, reply));
                    let _ = p.reply(reply);
                };
                while !thread_stop.load(Ordering::Acquire) {
                    while let Some(p) = server.receive() {
                        let r = p.request();
                        match check(&r, enabled, &tunables, &origin) {
                            Err(no) => {
                                let reply =
                                    OperatorReply::new(r.request_id, no.outcome, &no.message);
                                answer(p, &r, &reply);
                            }
                            Ok(_) if waiting.len() >= MAX_IN_FLIGHT => {
                                let reply = OperatorReply::new(
                                    r.request_id,
                                    outcome::REFUSED,
                                    "too many commands waiting for the loop",
                                );
                                answer(p, &r, &reply);
                            }
                            Ok(c) => {
                                // Ids of the loop's own, so that two clients' equal ids
                                // cannot mix their replies.
                                next_id += 1;
                                let queued = Queued {
                                    request_id: next_id,
                                    command: c,
                                };
                                if outbox.commands.push(queued).is_ok() {
                                    waiting.insert(next_id, (r, p));
                                }
                            }
                        }
                    }
                    while let Ok(a) = outbox.results.pop() {
                        if let Some((r, p)) = waiting.remove(&a.queued.request_id) {
                            let mut reply = reply_of(&a);
                            reply.request_id = r.request_id;
                            answer(p, &r, &reply);
                        }
                    }
                    std::thread::sleep(Duration::from_millis(2));
                }
                while let Ok(a) = outbox.results.pop() {
                    if let Some((r, p)) = waiting.remove(&a.queued.request_id) {
                        let mut reply = reply_of(&a);
                        reply.request_id = r.request_id;
                        answer(p, &r, &reply);
                    }
                }
                for (_, (r, p)) in waiting.drain() {
                    let reply = OperatorReply::new(
                        r.request_id,
                        outcome::RUN_ENDED,
                        "the run ended before the loop took the command",
                    );
                    answer(p, &r, &reply);
                }
                // In the order they were answered (the loop answers in the order it applied).
                records
            })?;
        Ok(Self { stop, handle })
    }

    /// Answers what is left and returns every request of the run.
    pub fn finish(self) -> Vec<CommandRecord> {
        self.stop.store(true, Ordering::Release);
        self.handle.join().unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alpha() -> Vec<DeclaredTunable> {
        vec![DeclaredTunable {
            name: "alpha".into(),
            index: 0,
            min: 0.1,
            max: 0.9,
            initial: 0.5,
        }]
    }

    #[test]
    fn a_tunable_within_its_bounds_is_queued_by_index() {
        let r = OperatorRequest::set_tunable("alpha", 0.3, 1);
        assert_eq!(
            check(&r, true, &alpha(), "s.toml"),
            Ok(Command::SetTunable {
                index: 0,
                value: 0.3
            })
        );
    }

    #[test]
    fn a_value_out_of_bounds_or_an_undeclared_name_is_refused_naming_the_field() {
        let r = OperatorRequest::set_tunable("alpha", 0.95, 1);
        let e = check(&r, true, &alpha(), "s.toml").unwrap_err();
        assert_eq!(e.outcome, outcome::REFUSED);
        assert!(e.message.contains("service.operator.tunables.alpha"));
        let r = OperatorRequest::set_tunable("alpha", f64::NAN, 1);
        assert!(check(&r, true, &alpha(), "s.toml").is_err());
        let r = OperatorRequest::set_tunable("lambda", 0.5, 1);
        let e = check(&r, true, &alpha(), "s.toml").unwrap_err();
        assert!(e.message.contains("'lambda' is not a declared tunable"));
    }

    #[test]
    fn commands_off_and_bad_requests_are_answered_without_the_loop() {
        let r = OperatorRequest::new(command::STOP_RUN, 4);
        let e = check(&r, false, &[], "s.toml").unwrap_err();
        assert_eq!(e.outcome, outcome::NOT_ENABLED);
        assert!(e.message.contains("s.toml"));
        let mut r = OperatorRequest::new(command::STOP_RUN, 5);
        r.version = 99;
        assert_eq!(
            check(&r, true, &[], "s.toml").unwrap_err().outcome,
            outcome::BAD_REQUEST
        );
        let r = OperatorRequest::new(77, 6);
        assert_eq!(
            check(&r, true, &[], "s.toml").unwrap_err().outcome,
            outcome::BAD_REQUEST
        );
    }
}
