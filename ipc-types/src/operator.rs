//! # Operator commands: act on a running loop, from outside it
//!
//! An operator (the `rig monitor` page, `rig command`, a script) sends an
//! [`OperatorRequest`] to the service on the request-response service
//! `adaptive-rig/N/operator` and gets one [`OperatorReply`]. The service's operator thread
//! receives it, the real-time loop applies it at a sample boundary (before the next sample
//! it handles, or while the plant is silent), and the reply says what happened and before
//! which sample it took effect. Every command is written to the run report and to
//! `record.bin`, so that `service replay` applies it at the same place.
//!
//! | command ([`command`])  | effect                                                       |
//! |------------------------|--------------------------------------------------------------|
//! | `freeze-adaptation`    | the controller keeps computing its law with what it learned, and stops learning |
//! | `resume-adaptation`    | it learns again                                              |
//! | `enter-safe-state`     | the loop answers with the safe input until told to leave      |
//! | `leave-safe-state`     | releases the operator's hold and the deadline monitor's latch |
//! | `stop-run`             | the run ends as on SIGTERM, with its report                  |
//! | `set-tunable`          | sets a declared tunable ([`crate::telemetry::TunableInfo`]) within its bounds |
//!
//! A command that cannot apply (adaptation of a controller that does not adapt, a value
//! out of bounds, an unknown tunable) is refused with a reason and changes nothing.
//!
//! ## Who may send
//!
//! iceoryx2 keeps its services in files of the user that runs the service
//! (`/dev/shm`, `/tmp/iceoryx2`), readable and writable by that user only: only a process
//! of the same user (or root) can open the operator service. The service applies the
//! commands only when its configuration says so (`service.operator.commands`, default on);
//! docs/live-contract.md describes the trust model.

use crate::ports::{ConnectError, SERVICE_PREFIX, ipc_err, service_name, valid_rig};
use crate::telemetry::{fixed_text, set_fixed_text};
use core::time::Duration;
use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::client::Client;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::request_response::PortFactory as RequestResponseFactory;
use std::time::Instant;

/// Version of the operator contract, carried in every request and reply.
pub const OPERATOR_VERSION: u32 = 1;
/// Clients the operator service admits at once.
pub const MAX_CLIENTS: usize = 4;

/// The command codes of [`OperatorRequest::command`].
pub mod command {
    /// Stop the controller's adaptation; it keeps its law.
    pub const FREEZE_ADAPTATION: u32 = 1;
    /// Resume the controller's adaptation.
    pub const RESUME_ADAPTATION: u32 = 2;
    /// Hold the loop in its safe state.
    pub const ENTER_SAFE_STATE: u32 = 3;
    /// Leave the safe state (the operator's hold and the deadline monitor's latch).
    pub const LEAVE_SAFE_STATE: u32 = 4;
    /// End the run.
    pub const STOP_RUN: u32 = 5;
    /// Set a declared tunable.
    pub const SET_TUNABLE: u32 = 6;
    /// Every command with its name, in code order.
    pub const ALL: [(u32, &str); 6] = [
        (FREEZE_ADAPTATION, "freeze-adaptation"),
        (RESUME_ADAPTATION, "resume-adaptation"),
        (ENTER_SAFE_STATE, "enter-safe-state"),
        (LEAVE_SAFE_STATE, "leave-safe-state"),
        (STOP_RUN, "stop-run"),
        (SET_TUNABLE, "set-tunable"),
    ];

    /// The name of a command code.
    pub fn name(code: u32) -> Option<&'static str> {
        ALL.iter().find(|(c, _)| *c == code).map(|(_, n)| *n)
    }

    /// The code of a command name.
    pub fn from_name(name: &str) -> Option<u32> {
        ALL.iter().find(|(_, n)| *n == name).map(|(c, _)| *c)
    }
}

/// The outcome codes of [`OperatorReply::outcome`].
pub mod outcome {
    /// The loop applied the command.
    pub const APPLIED: u32 = 0;
    /// The loop refused it; the message says why; nothing changed.
    pub const REFUSED: u32 = 1;
    /// This service does not accept commands (`service.operator.commands = false`).
    pub const NOT_ENABLED: u32 = 2;
    /// The run ended before the command could apply.
    pub const RUN_ENDED: u32 = 3;
    /// Another contract version or an unknown command code.
    pub const BAD_REQUEST: u32 = 4;

    /// The name of an outcome code.
    pub fn name(code: u32) -> &'static str {
        match code {
            APPLIED => "applied",
            REFUSED => "refused",
            NOT_ENABLED => "not-enabled",
            RUN_ENDED => "run-ended",
            BAD_REQUEST => "bad-request",
            _ => "unknown",
        }
    }
}

/// A command to the service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("adaptive_rig::OperatorRequest.v1")]
pub struct OperatorRequest {
    /// [`OPERATOR_VERSION`].
    pub version: u32,
    /// A [`command`] code.
    pub command: u32,
    /// Chosen by the sender and echoed in the reply.
    pub request_id: u64,
    /// The new value, for [`command::SET_TUNABLE`].
    pub value: f64,
    /// The tunable's name, for [`command::SET_TUNABLE`] (NUL-terminated).
    pub tunable: [u8; 32],
}

impl OperatorRequest {
    /// A request of `command` (a [`command`] code).
    pub fn new(command: u32, request_id: u64) -> Self {
        Self {
            version: OPERATOR_VERSION,
            command,
            request_id,
            value: 0.0,
            tunable: [0; 32],
        }
    }

    /// A [`command::SET_TUNABLE`] request.
    pub fn set_tunable(name: &str, value: f64, request_id: u64) -> Self {
        let mut r = Self::new(command::SET_TUNABLE, request_id);
        r.value = value;
        set_fixed_text(&mut r.tunable, name);
        r
    }

    /// The tunable's name.
    pub fn tunable(&self) -> &str {
        fixed_text(&self.tunable)
    }
}

/// The service's answer to one [`OperatorRequest`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("adaptive_rig::OperatorReply.v1")]
pub struct OperatorReply {
    /// [`OPERATOR_VERSION`].
    pub version: u32,
    /// An [`outcome`] code.
    pub outcome: u32,
    /// The request's id.
    pub request_id: u64,
    /// The command took effect before the handling of the sample with this index (the
    /// newest sample's index + 1 when it applied while the plant was silent); 0 when it
    /// did not apply.
    pub applied_before_seq: u64,
    /// For [`command::SET_TUNABLE`]: the tunable's value in force after the command.
    pub value: f64,
    /// Why, for an outcome other than [`outcome::APPLIED`] (NUL-terminated).
    pub message: [u8; 256],
}

impl OperatorReply {
    /// A reply to `request_id` with `outcome` and `message`.
    pub fn new(request_id: u64, outcome: u32, message: &str) -> Self {
        let mut r = Self {
            version: OPERATOR_VERSION,
            outcome,
            request_id,
            applied_before_seq: 0,
            value: f64::NAN,
            message: [0; 256],
        };
        set_fixed_text(&mut r.message, message);
        r
    }

    /// The message.
    pub fn message(&self) -> &str {
        fixed_text(&self.message)
    }
}

/// The operator service name of rig `rig`.
pub fn operator_service_name(rig: &str) -> Result<String, ConnectError> {
    valid_rig(rig)?;
    Ok(format!("{SERVICE_PREFIX}/{rig}/operator"))
}

type Factory = RequestResponseFactory<ipc::Service, OperatorRequest, (), OperatorReply, ()>;

fn open_service(node_name: &str, rig: &str) -> Result<(Node<ipc::Service>, Factory), ConnectError> {
    let name = operator_service_name(rig)?;
    set_log_level(LogLevel::Error);
    let node = crate::ports::create_node(node_name)?;
    let service = node
        .service_builder(&service_name(&name)?)
        .request_response::<OperatorRequest, OperatorReply>()
        .max_servers(1)
        .max_clients(MAX_CLIENTS)
        .max_active_requests_per_client(4)
        .max_response_buffer_size(2)
        .open_or_create()
        .map_err(|e| ipc_err("opening the operator service", &name, e))?;
    Ok((node, service))
}

/// A received request waiting for its reply ([`OperatorServer::receive`]).
pub struct PendingCommand {
    active: ActiveRequest<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
}

impl core::fmt::Debug for PendingCommand {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PendingCommand")
            .field("request", &*self.active)
            .finish()
    }
}

impl PendingCommand {
    /// The request.
    pub fn request(&self) -> OperatorRequest {
        *self.active
    }

    /// Sends `reply`; returns whether it was sent (the client may have gone).
    pub fn reply(self, reply: &OperatorReply) -> bool {
        self.active.send_copy(*reply).is_ok()
    }
}

/// The service's side: receives requests (on its operator thread).
pub struct OperatorServer {
    server: Server<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
    _service: Factory,
    _node: Node<ipc::Service>,
}

impl core::fmt::Debug for OperatorServer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("OperatorServer")
    }
}

impl OperatorServer {
    /// Opens rig `rig`'s operator service and takes its one server slot.
    ///
    /// # Errors
    ///
    /// An invalid rig name, an iceoryx2 failure, or another server on this rig.
    pub fn create(rig: &str) -> Result<Self, ConnectError> {
        // A service that died leaves its server slot registered: free it first.
        crate::ports::cleanup_dead_nodes();
        let (node, service) = open_service("adaptive-rig-operator", rig)?;
        let server = service
            .server_builder()
            .create()
            .map_err(|e| ipc_err("creating the operator server", rig, e))?;
        Ok(Self {
            server,
            _service: service,
            _node: node,
        })
    }

    /// The next request waiting, if any.
    pub fn receive(&self) -> Option<PendingCommand> {
        match self.server.receive() {
            Ok(Some(active)) => Some(PendingCommand { active }),
            _ => None,
        }
    }
}

/// Why a command got no reply.
#[derive(Debug)]
pub enum OperatorError {
    /// The operator service could not be opened.
    Connect(ConnectError),
    /// No service of this rig serves operator commands now.
    NoService {
        /// The rig.
        rig: String,
    },
    /// The request could not be sent.
    Send(String),
    /// No reply came within the time given.
    Timeout {
        /// The time waited.
        waited: Duration,
    },
}

impl core::fmt::Display for OperatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            OperatorError::Connect(e) => write!(f, "{e}"),
            OperatorError::NoService { rig } => write!(
                f,
                "no service of rig '{rig}' takes operator commands now (is it running?)"
            ),
            OperatorError::Send(e) => write!(f, "the command could not be sent: {e}"),
            OperatorError::Timeout { waited } => write!(
                f,
                "no reply within {:.1} s: the loop applies commands at a sample boundary; is \
                 it stalled?",
                waited.as_secs_f64()
            ),
        }
    }
}

impl std::error::Error for OperatorError {}

/// An operator's side: sends requests and waits for their replies.
pub struct OperatorClient {
    rig: String,
    client: Client<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
    _service: Factory,
    _node: Node<ipc::Service>,
}

impl core::fmt::Debug for OperatorClient {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("OperatorClient")
            .field("rig", &self.rig)
            .finish()
    }
}

impl OperatorClient {
    /// Opens rig `rig`'s operator service as a client.
    ///
    /// # Errors
    ///
    /// An invalid rig name, an iceoryx2 failure, or [`MAX_CLIENTS`] clients already.
    pub fn open(rig: &str) -> Result<Self, OperatorError> {
        let (node, service) =
            open_service("adaptive-rig-operator-client", rig).map_err(OperatorError::Connect)?;
        let client = service
            .client_builder()
            .create()
            .map_err(|e| OperatorError::Connect(ipc_err("creating the operator client", rig, e)))?;
        Ok(Self {
            rig: rig.to_string(),
            client,
            _service: service,
            _node: node,
        })
    }

    /// Sends `request` and waits up to `timeout` for its reply.
    ///
    /// # Errors
    ///
    /// No service serving, a failed send, or no reply in time.
    pub fn send(
        &self,
        request: &OperatorRequest,
        timeout: Duration,
    ) -> Result<OperatorReply, OperatorError> {
        let start = Instant::now();
        let pending = loop {
            let pending = self
                .client
                .send_copy(*request)
                .map_err(|e| OperatorError::Send(format!("{e:?}")))?;
            if pending.number_of_server_connections() > 0 {
                break pending;
            }
            // A server that started a moment ago is connected at the next send.
            if start.elapsed() >= timeout.min(Duration::from_millis(500)) {
                return Err(OperatorError::NoService {
                    rig: self.rig.clone(),
                });
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        loop {
            if let Ok(Some(reply)) = pending.receive() {
                return Ok(*reply);
            }
            if !pending.is_connected() {
                return Err(OperatorError::NoService {
                    rig: self.rig.clone(),
                });
            }
            if start.elapsed() >= timeout {
                return Err(OperatorError::Timeout { waited: timeout });
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn command_names_and_codes_round_trip() {
        for (code, name) in command::ALL {
            assert_eq!(command::from_name(name), Some(code));
            assert_eq!(command::name(code), Some(name));
        }
        assert_eq!(command::from_name("reboot"), None);
    }

    #[test]
    fn a_set_tunable_request_carries_its_name_and_value() {
        let r = OperatorRequest::set_tunable("alpha", 0.25, 7);
        assert_eq!(r.tunable(), "alpha");
        assert_eq!(r.value, 0.25);
        assert_eq!(r.command, command::SET_TUNABLE);
        assert_eq!(r.request_id, 7);
    }
}
