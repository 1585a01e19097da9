//! Connecting the two sides of the contract over iceoryx2.
//!
//! Each side creates (or reopens) the publish-subscribe service it publishes on, defining
//! the attributes of its [`ContractInfo`], then waits for the peer's service, reads the
//! peer's attributes and refuses to connect when they differ, naming every difference:
//!
//! | service (rig `N`)              | pattern           | payload         | created by |
//! |--------------------------------|-------------------|-----------------|------------|
//! | `adaptive-rig/N/measurement`   | publish-subscribe | [`Measurement`] | plant      |
//! | `adaptive-rig/N/actuation`     | publish-subscribe | [`Actuation`]   | service    |
//! | `adaptive-rig/N/measurement`   | event             | —               | either     |
//! | `adaptive-rig/N/actuation`     | event             | —               | either     |
//!
//! The payload types are checked by iceoryx2 itself (type name, size, alignment). A process
//! that died leaves stale shared-memory resources behind; [`cleanup_dead_nodes`] removes
//! them so that a restarted peer can connect again.
//!
//! ## Only the connected peers
//!
//! Every service admits **one port of each kind**: one publisher (the side that creates
//! it), one subscriber (the peer), one notifier, one listener; [`connect`] creates them so
//! and refuses a service of the same name that admits more. A second service (or plant) on
//! a rig, or a foreign process that took a slot, is refused with a message naming the
//! process that holds the slot ([`ConnectError::AlreadyRunning`],
//! [`ConnectError::SlotTaken`]); a permission failure of iceoryx2 says so
//! ([`ConnectError::PermissionDenied`]). At connect each side pins the peer's publisher
//! ([`Ports::pin`], [`crate::peer`]); the receive path asks [`Ports::admit`] where each
//! sample came from, so a sample of anything but the peer is refused and counted, and a
//! restarted peer is recognized as a new one.
//!
//! Everything here allocates and may block: it is set-up code, run before a real-time loop
//! starts or while it is idle, never inside a control step.

mod liveness;
mod slots;

use crate::peer::{Origin, PeerPin};
use crate::{Actuation, CONTRACT_VERSION, ChannelCounts, Measurement, Timing};
use core::fmt;
use core::time::Duration;
use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerCreateError};
use iceoryx2::port::notifier::{Notifier, NotifierCreateError};
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::{Subscriber, SubscriberCreateError};
use iceoryx2::prelude::*;
use iceoryx2::service::builder::publish_subscribe::{
    PublishSubscribeCreateError, PublishSubscribeOpenError,
};
use iceoryx2::service::port_factory::event::PortFactory as EventFactory;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use slots::Holder;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Prefix of every service name of this product.
pub const SERVICE_PREFIX: &str = "adaptive-rig";

/// Samples a subscriber's queue holds (both services, both sides): 256 periods, 32 ms at
/// 8 kHz. A receiver that was kept off its core for less than that (a virtual machine's
/// host takes a vCPU for 6–10 ms a few times a minute) takes every sample in late
/// ("caught up", its data exact) instead of losing the oldest; with safe overflow the
/// publisher never blocks, and past 256 the oldest sample is lost. A peer that creates a
/// service (the plant its measurement service, in any language) must create it with at
/// least this depth, or the other side's open is refused by iceoryx2.
pub const SUBSCRIBER_BUFFER: usize = 256;

/// Which side of the contract a process is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The plant process (plant-proxy or a DAQ I/O process): the clock master.
    Plant,
    /// The control service.
    Service,
}

impl Side {
    /// The name used in attributes and messages.
    pub fn name(self) -> &'static str {
        match self {
            Side::Plant => "plant",
            Side::Service => "service",
        }
    }
    fn peer(self) -> Side {
        match self {
            Side::Plant => Side::Service,
            Side::Service => Side::Plant,
        }
    }
}

/// When a plant applies the input of sample `k`, stated in its `timing` attribute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applies {
    /// At the sample instant `kT` (deadline 0): the input must be there before the sample is
    /// taken, which only a service that sends ahead ([`Timing::SendAhead`]) can meet.
    AtSample,
    /// At `kT + dT`, a deadline offset inside the period.
    AtDeadline,
    /// In lockstep: the plant waits for each answer.
    Lockstep,
}

impl Applies {
    /// The attribute value (`"at-sample"`, `"at-deadline"`, `"lockstep"`).
    pub const fn name(self) -> &'static str {
        match self {
            Applies::AtSample => "at-sample",
            Applies::AtDeadline => "at-deadline",
            Applies::Lockstep => "lockstep",
        }
    }

    /// The application of an attribute value given by [`Applies::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        [Applies::AtSample, Applies::AtDeadline, Applies::Lockstep]
            .into_iter()
            .find(|a| a.name() == name)
    }
}

/// What one side states about itself when it connects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ContractInfo {
    /// The side that states it.
    pub side: Side,
    /// Its contract version ([`CONTRACT_VERSION`] for this build).
    pub version: u32,
    /// The channel counts it uses.
    pub counts: ChannelCounts,
    /// The sampling period it runs at (the plant) or was designed for (the service), in ns.
    pub period_ns: u64,
    /// The service's timing (its `timing` attribute); `None` when unstated.
    pub timing: Option<Timing>,
    /// When the plant applies an input (its `timing` attribute); `None` when unstated.
    pub applies: Option<Applies>,
}

impl ContractInfo {
    /// Info of this build's contract version, with no timing stated.
    pub fn new(side: Side, counts: ChannelCounts, period_ns: u64) -> Self {
        Self {
            side,
            version: CONTRACT_VERSION,
            counts,
            period_ns,
            timing: None,
            applies: None,
        }
    }

    /// States the service's timing (the `timing` attribute of a service).
    pub fn with_timing(mut self, timing: Timing) -> Self {
        self.timing = Some(timing);
        self
    }

    /// States when the plant applies an input (the `timing` attribute of a plant).
    pub fn with_applies(mut self, applies: Applies) -> Self {
        self.applies = Some(applies);
        self
    }

    fn specifier(&self) -> Result<AttributeSpecifier, ConnectError> {
        let kv = [
            ("contract-version", self.version.to_string()),
            ("n-y", self.counts.n_y.to_string()),
            ("n-z", self.counts.n_z.to_string()),
            ("n-r", self.counts.n_r.to_string()),
            ("n-u", self.counts.n_u.to_string()),
            ("period-ns", self.period_ns.to_string()),
            ("role", self.side.name().to_string()),
        ];
        let timing = match (self.side, self.timing, self.applies) {
            (Side::Service, Some(t), _) => Some(("timing", t.name().to_string())),
            (Side::Plant, _, Some(a)) => Some(("timing", a.name().to_string())),
            _ => None,
        };
        let mut spec = AttributeSpecifier::new();
        for (k, v) in kv.into_iter().chain(timing) {
            let key = k.try_into().map_err(|e| ipc_err("attribute key", k, e))?;
            let value = v
                .as_str()
                .try_into()
                .map_err(|e| ipc_err("attribute value", k, e))?;
            spec = spec
                .define(&key, &value)
                .map_err(|e| ipc_err("attribute", k, e))?;
        }
        Ok(spec)
    }

    fn from_attributes(set: &AttributeSet, service: &str) -> Result<Self, ConnectError> {
        let get = |k: &str| -> Result<String, ConnectError> {
            let key = k.try_into().map_err(|e| ipc_err("attribute key", k, e))?;
            set.key_value(&key, 0)
                .map(|v| v.to_string())
                .ok_or_else(|| ConnectError::NotAContractService {
                    service: service.to_string(),
                    detail: format!("it has no attribute '{k}'"),
                })
        };
        let num = |k: &str| -> Result<u64, ConnectError> {
            let v = get(k)?;
            v.parse().map_err(|_| ConnectError::NotAContractService {
                service: service.to_string(),
                detail: format!("attribute '{k}' = '{v}' is not a number"),
            })
        };
        let side = match get("role")?.as_str() {
            "plant" => Side::Plant,
            "service" => Side::Service,
            other => {
                return Err(ConnectError::NotAContractService {
                    service: service.to_string(),
                    detail: format!("attribute 'role' = '{other}' is neither plant nor service"),
                });
            }
        };
        // Optional: a peer of an older contract has none, and is refused for its version.
        let (mut timing, mut applies) = (None, None);
        if let Ok(v) = get("timing") {
            let unknown = || ConnectError::NotAContractService {
                service: service.to_string(),
                detail: format!(
                    "attribute 'timing' = '{v}' is not a timing of a {}",
                    side.name()
                ),
            };
            match side {
                Side::Service => timing = Some(Timing::from_name(&v).ok_or_else(unknown)?),
                Side::Plant => applies = Some(Applies::from_name(&v).ok_or_else(unknown)?),
            }
        }
        Ok(Self {
            timing,
            applies,
            side,
            version: num("contract-version")? as u32,
            counts: ChannelCounts {
                n_y: num("n-y")? as u16,
                n_z: num("n-z")? as u16,
                n_r: num("n-r")? as u16,
                n_u: num("n-u")? as u16,
            },
            period_ns: num("period-ns")?,
        })
    }

    /// Every difference between `self` and `other` that makes them incompatible, one line
    /// each, naming each side by its role.
    pub fn differences(&self, other: &ContractInfo) -> Vec<String> {
        let (me, them) = (self.side.name(), other.side.name());
        let mut out = Vec::new();
        if self.version != other.version {
            out.push(format!(
                "contract version: {them} has {}, {me} has {}",
                other.version, self.version
            ));
        }
        out.extend(self.counts.differences(me, &other.counts, them));
        if self.period_ns != other.period_ns {
            out.push(format!(
                "sample period: {them} runs at {} ns ({:.3} Hz), {me} at {} ns ({:.3} Hz)",
                other.period_ns,
                1e9 / other.period_ns.max(1) as f64,
                self.period_ns,
                1e9 / self.period_ns.max(1) as f64
            ));
        }
        let (plant, service) = match self.side {
            Side::Plant => (self, other),
            Side::Service => (other, self),
        };
        if plant.side != service.side
            && let (Some(applies), Some(t)) = (plant.applies, service.timing)
            && !crate::timing_rules::timings_meet(applies, t)
        {
            out.push(format!(
                "timing: the plant applies each input at its sample instant (its deadline is 0), \
                 which only a service that sends ahead can meet; the service answers {} \
                 (set service.timing = \"send-ahead\", or give the plant a deadline inside the \
                 period)",
                t.name()
            ));
        }
        out
    }
}

/// Why a connection could not be made. Every variant names the service at fault.
#[derive(Debug)]
pub enum ConnectError {
    /// The rig name cannot be used in a service name.
    InvalidRigName {
        /// The name given.
        rig: String,
        /// What is wrong with it.
        detail: String,
    },
    /// The peer states another contract; each difference is listed.
    Mismatch {
        /// The service whose attributes differ.
        service: String,
        /// Whose attributes they are.
        holder: Side,
        /// One line per difference.
        differences: Vec<String>,
    },
    /// iceoryx2 refused the payload type: another layout or type name was compiled in.
    IncompatibleType {
        /// The service concerned.
        service: String,
    },
    /// A service with this name exists but does not carry this contract's attributes.
    NotAContractService {
        /// The service concerned.
        service: String,
        /// What is missing or malformed.
        detail: String,
    },
    /// The peer's service did not appear within the time allowed.
    PeerTimeout {
        /// The service waited for.
        service: String,
        /// How long was waited.
        waited: Duration,
    },
    /// A shutdown was requested while waiting.
    Interrupted,
    /// Another live process of the same side already holds this rig: it owns the one
    /// publisher of this side's service (a second service on a served rig, or a second
    /// plant).
    AlreadyRunning {
        /// The rig.
        rig: String,
        /// The side that was to be started.
        side: Side,
        /// This side's service, whose publisher slot is taken.
        service: String,
        /// The process that holds it ("pid 1234 (node 'adaptive-rig-service')").
        holder: String,
    },
    /// A port slot that the contract reserves for one side is held by another process (a
    /// second peer, or a foreign process).
    SlotTaken {
        /// The service concerned.
        service: String,
        /// Which port: "subscriber", "notifier" or "listener".
        port: &'static str,
        /// The side the slot is for.
        reserved_for: Side,
        /// The process that holds it.
        holder: String,
    },
    /// A service of the contract's name admits more ports than the contract allows: it was
    /// created by an older build or by a foreign process.
    NotExclusive {
        /// The service concerned.
        service: String,
        /// What it admits.
        detail: String,
    },
    /// iceoryx2 was refused access to its shared-memory files or folders: they belong to
    /// another user (see the deployment model in `docs/deployment.md`).
    PermissionDenied {
        /// What was being done.
        what: String,
        /// The service or item concerned.
        item: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// Any other iceoryx2 failure.
    Ipc {
        /// What was being done.
        what: String,
        /// The service or item concerned.
        item: String,
        /// iceoryx2's error.
        detail: String,
    },
}

/// An iceoryx2 failure. Every iceoryx2 error enum names an access failure
/// `InsufficientPermissions` (nested ones too: `EventOpenError(InsufficientPermissions)`),
/// and node creation reports a folder it may not write as `InternalError`; both become
/// [`ConnectError::PermissionDenied`] (the latter only when the iceoryx2 folder is not
/// writable by this process, see [`iceoryx2_folder_denied`]).
pub(crate) fn ipc_err(what: &str, item: &str, e: impl fmt::Debug) -> ConnectError {
    let detail = format!("{e:?}");
    if detail.contains("InsufficientPermissions") || detail.contains("PermissionDenied") {
        ConnectError::PermissionDenied {
            what: what.to_string(),
            item: item.to_string(),
            detail,
        }
    } else {
        ConnectError::Ipc {
            what: what.to_string(),
            item: item.to_string(),
            detail,
        }
    }
}

/// A node creation failure: `InternalError` is what iceoryx2 0.10 reports when it cannot
/// create its files in a folder of another user, so it is checked against the folders.
pub(crate) fn node_err(node_name: &str, e: impl fmt::Debug) -> ConnectError {
    match (
        ipc_err("creating the node", node_name, &e),
        iceoryx2_folder_denied(),
    ) {
        (ConnectError::Ipc { what, item, detail }, Some(folder)) => {
            ConnectError::PermissionDenied {
                what,
                item,
                detail: format!("{detail}; {folder}"),
            }
        }
        (other, _) => other,
    }
}

/// The first iceoryx2 folder this process may not write into, described, if any.
fn iceoryx2_folder_denied() -> Option<String> {
    use std::os::unix::ffi::OsStrExt;
    let root = Config::global_config()
        .global
        .root_path()
        .as_string()
        .to_string();
    let root = std::path::PathBuf::from(root);
    let mut folders = vec![root.clone()];
    if let Ok(dir) = std::fs::read_dir(&root) {
        folders.extend(dir.flatten().map(|e| e.path()).filter(|p| p.is_dir()));
    }
    folders.push("/dev/shm".into());
    for f in folders {
        let Ok(c) = std::ffi::CString::new(f.as_os_str().as_bytes()) else {
            continue;
        };
        // SAFETY: access() only reads the NUL-terminated path.
        if unsafe { libc::access(c.as_ptr(), libc::W_OK | libc::X_OK) } != 0
            && std::io::Error::last_os_error().raw_os_error() == Some(libc::EACCES)
        {
            use std::os::unix::fs::MetadataExt;
            let owner = std::fs::metadata(&f).map(|m| m.uid()).ok();
            return Some(format!(
                "{} is not writable by this user (uid {}){}",
                f.display(),
                // SAFETY: getuid has no preconditions.
                unsafe { libc::getuid() },
                owner
                    .map(|o| format!(", it belongs to uid {o}"))
                    .unwrap_or_default()
            ));
        }
    }
    None
}

impl fmt::Display for ConnectError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConnectError::InvalidRigName { rig, detail } => {
                write!(f, "invalid rig name '{rig}': {detail}")
            }
            ConnectError::Mismatch {
                service,
                holder,
                differences,
            } => {
                write!(
                    f,
                    "contract mismatch on '{service}' (defined by the {}), refusing to connect:",
                    holder.name()
                )?;
                for d in differences {
                    write!(f, "\n  - {d}")?;
                }
                Ok(())
            }
            ConnectError::IncompatibleType { service } => write!(
                f,
                "'{service}' carries another payload type (type name, size or alignment differ): \
                 the peer was built against another contract layout; rebuild it against \
                 contract version {CONTRACT_VERSION}"
            ),
            ConnectError::NotAContractService { service, detail } => {
                write!(
                    f,
                    "'{service}' is not an adaptive-rig contract service: {detail}"
                )
            }
            ConnectError::PeerTimeout { service, waited } => write!(
                f,
                "no peer: '{service}' did not appear within {:.1} s (is the other process running \
                 with the same rig name?)",
                waited.as_secs_f64()
            ),
            ConnectError::Interrupted => write!(f, "interrupted while connecting"),
            ConnectError::AlreadyRunning {
                rig,
                side,
                service,
                holder,
            } => {
                let what = match side {
                    Side::Service => format!("rig '{rig}' is already served by {holder}"),
                    Side::Plant => format!("rig '{rig}' already has a plant: {holder}"),
                };
                write!(
                    f,
                    "{what}, which holds the one publisher of '{service}'; refusing to start a \
                     second {}",
                    side.name()
                )
            }
            ConnectError::SlotTaken {
                service,
                port,
                reserved_for,
                holder,
            } => write!(
                f,
                "'{service}' admits one {port}, the {}'s, and {holder} holds it: another {} runs \
                 on this rig, or a foreign process occupies the slot; refusing to connect",
                reserved_for.name(),
                reserved_for.name()
            ),
            ConnectError::NotExclusive { service, detail } => write!(
                f,
                "'{service}' {detail}, the contract allows one of each: it was created by an \
                 older build or by a foreign process; refusing to connect (stop the processes \
                 that use it)"
            ),
            ConnectError::PermissionDenied { what, item, detail } => write!(
                f,
                "permission denied while {what} '{item}' ({detail}): the iceoryx2 files of this \
                 machine belong to another user; run the service and the plant process as the \
                 same dedicated user (docs/deployment.md, \"Trust and deployment model\")"
            ),
            ConnectError::Ipc { what, item, detail } => {
                write!(f, "iceoryx2 failure while {what} '{item}': {detail}")
            }
        }
    }
}

impl std::error::Error for ConnectError {}

/// The service names of one rig.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RigServiceNames {
    /// `adaptive-rig/<rig>/measurement`.
    pub measurement: String,
    /// `adaptive-rig/<rig>/actuation`.
    pub actuation: String,
}

/// Service names derived from a rig name, so that several rigs run side by side. A rig name
/// is 1 to 64 characters of ASCII letters, digits, `-` and `_`.
pub fn service_names(rig: &str) -> Result<RigServiceNames, ConnectError> {
    valid_rig(rig)?;
    Ok(RigServiceNames {
        measurement: format!("{SERVICE_PREFIX}/{rig}/measurement"),
        actuation: format!("{SERVICE_PREFIX}/{rig}/actuation"),
    })
}

/// Refuses a rig name that is not 1 to 64 characters of ASCII letters, digits, `-` and `_`.
pub(crate) fn valid_rig(rig: &str) -> Result<(), ConnectError> {
    let bad = |detail: &str| ConnectError::InvalidRigName {
        rig: rig.into(),
        detail: detail.into(),
    };
    if rig.is_empty() || rig.len() > 64 {
        return Err(bad("it must have 1 to 64 characters"));
    }
    if !rig
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(bad("only ASCII letters, digits, '-' and '_' are allowed"));
    }
    Ok(())
}

/// Removes the stale resources of every dead iceoryx2 node on this machine, and returns
/// how many dead nodes were cleaned up.
pub fn cleanup_dead_nodes() -> usize {
    let mut n = 0;
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::<ipc::Service>::Dead(view) = state {
            // A node whose process is alive is not dead: it is being created (its monitor
            // file exists, its lock is not taken yet) or being dropped. Removing it then
            // would take the services of a live peer away (seen under load as a peer whose
            // service never appears). Only a node whose process is gone is cleaned up.
            // The pid must also not have been reused by a newer process (see liveness.rs).
            let alive = liveness::node_alive(view.id());
            if !alive && view.try_remove_stale_resources().is_ok() {
                n += 1;
            }
        }
        CallbackProgression::Continue
    });
    n
}

/// The ports of one side: publishes `Out`, subscribes to `In`, notifies after each send and
/// listens for the peer's notifications.
pub struct Ports<Out: fmt::Debug + ZeroCopySend + 'static, In: fmt::Debug + ZeroCopySend + 'static>
{
    /// Publisher of this side's samples.
    pub publisher: Publisher<ipc::Service, Out, ()>,
    /// Subscriber to the peer's samples.
    pub subscriber: Subscriber<ipc::Service, In, ()>,
    /// Notifier signalled after each published sample.
    pub notifier: Notifier<ipc::Service>,
    /// Listener woken by the peer's notifier; only created when asked for, so that a peer
    /// that busy-polls pays no system call for notifications nobody waits on.
    pub listener: Option<Listener<ipc::Service>>,
    /// What the peer stated when the connection was made.
    pub peer: ContractInfo,
    /// The peer's publisher, pinned at connect; see [`Ports::admit`].
    pub pin: PeerPin,
    _own_event: iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
    _peer_event: iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
    _own_service: PubSubFactory<ipc::Service, Out, ()>,
    _peer_service: PubSubFactory<ipc::Service, In, ()>,
    _node: Node<ipc::Service>,
}

/// The plant's ports: publishes [`Measurement`], receives [`Actuation`].
pub type PlantPorts = Ports<Measurement, Actuation>;
/// The service's ports: publishes [`Actuation`], receives [`Measurement`].
pub type ServicePorts = Ports<Actuation, Measurement>;

/// Options for [`connect`], made by [`ConnectOptions::new`] with the peer timeout and the
/// defaults below, then changed by the `with_` methods (the fields are public as well):
///
/// | field             | default | set by                                    |
/// |-------------------|---------|-------------------------------------------|
/// | `peer_timeout`    | —       | [`ConnectOptions::new`]                   |
/// | `shutdown`        | `None`  | [`ConnectOptions::with_shutdown`]         |
/// | `listen`          | `false` | [`ConnectOptions::with_listener`]         |
/// | `waiting_message` | `None`  | [`ConnectOptions::with_waiting_message`]  |
///
/// ```
/// use core::time::Duration;
/// use ipc_types::ports::ConnectOptions;
/// use std::sync::atomic::AtomicBool;
///
/// let stop = AtomicBool::new(false);
/// let opts = ConnectOptions::new(Duration::from_secs(5))
///     .with_shutdown(&stop)
///     .with_listener(true);
/// assert_eq!(opts.peer_timeout, Duration::from_secs(5));
/// assert!(opts.shutdown.is_some() && opts.listen && opts.waiting_message.is_none());
/// ```
#[derive(Debug, Clone, Copy)]
pub struct ConnectOptions<'a> {
    /// How long to wait for the peer's service to appear.
    pub peer_timeout: Duration,
    /// Set from a signal handler to abandon the wait.
    pub shutdown: Option<&'a AtomicBool>,
    /// Create a listener on the peer's event service (for blocking waits).
    pub listen: bool,
    /// Printed to stderr once this side's own service exists and the wait for the peer
    /// begins (so that a person or a test knows the peer can be started now).
    pub waiting_message: Option<&'a str>,
}

impl<'a> ConnectOptions<'a> {
    /// Waits up to `peer_timeout` for the peer; no shutdown flag, no listener, no waiting
    /// message.
    pub const fn new(peer_timeout: Duration) -> Self {
        Self {
            peer_timeout,
            shutdown: None,
            listen: false,
            waiting_message: None,
        }
    }

    /// Abandons the wait for the peer once `shutdown` is set (from a signal handler).
    pub const fn with_shutdown(mut self, shutdown: &'a AtomicBool) -> Self {
        self.shutdown = Some(shutdown);
        self
    }

    /// Creates a listener on the peer's event service when `listen` is true (for blocking
    /// waits on the peer's notifications).
    pub const fn with_listener(mut self, listen: bool) -> Self {
        self.listen = listen;
        self
    }

    /// Prints `message` (a `&str`, or `None` for no message) to stderr when the wait for
    /// the peer begins.
    pub fn with_waiting_message(mut self, message: impl Into<Option<&'a str>>) -> Self {
        self.waiting_message = message.into();
        self
    }
}

/// Opens this side's own publish-subscribe service (creating it with `own`'s attributes if
/// it does not exist, verifying them if it does), waits for the peer's service, verifies the
/// peer's attributes against `own`, and creates the ports.
pub fn connect<Out, In>(
    rig: &str,
    own: ContractInfo,
    node_name: &str,
    opts: ConnectOptions<'_>,
) -> Result<Ports<Out, In>, ConnectError>
where
    Out: fmt::Debug + ZeroCopySend + 'static,
    In: fmt::Debug + ZeroCopySend + 'static,
{
    let names = service_names(rig)?;
    let (own_name, peer_name) = match own.side {
        Side::Plant => (names.measurement.clone(), names.actuation.clone()),
        Side::Service => (names.actuation.clone(), names.measurement.clone()),
    };
    set_log_level(LogLevel::Error);
    cleanup_dead_nodes();
    let node = create_node(node_name)?;

    let own_service = open_own::<Out>(&node, &own_name, &own, &opts)?;
    // This side's publisher first, before waiting for the peer: the one publisher slot is
    // what makes this process the rig's only plant (or service); a second one is refused
    // here, naming the process that holds the slot.
    let publisher = exclusive_port(
        || {
            own_service
                .publisher_builder()
                .max_loaned_samples(2)
                .create()
        },
        |e| matches!(e, PublisherCreateError::ExceedsMaxSupportedPublishers),
        || slots::holders(&own_service, &slots::publisher_nodes(&own_service)),
        |holder| ConnectError::AlreadyRunning {
            rig: rig.to_string(),
            side: own.side,
            service: own_name.clone(),
            holder,
        },
        ("creating the publisher of", &own_name),
    )?;
    if let Some(msg) = opts.waiting_message {
        eprintln!("{msg}");
    }
    let (peer_service, peer) = match open_peer::<In>(&node, &peer_name, &own, &opts) {
        Ok(p) => p,
        Err(e @ ConnectError::Mismatch { .. }) => {
            // Keep this side's service up a moment, so that a peer polling for it also
            // finds it and reports the same mismatch, instead of seeing it vanish and
            // timing out with "no peer".
            let until = Instant::now() + MISMATCH_LINGER;
            while Instant::now() < until
                && !opts.shutdown.is_some_and(|s| s.load(Ordering::Relaxed))
            {
                std::thread::sleep(Duration::from_millis(10));
            }
            drop(publisher);
            drop(own_service);
            return Err(e);
        }
        Err(e) => return Err(e),
    };

    let own_event = open_event(&node, &own_name)?;
    let peer_event = open_event(&node, &peer_name)?;
    let notifier = exclusive_port(
        || own_event.notifier_builder().create(),
        |e| matches!(e, NotifierCreateError::ExceedsMaxSupportedNotifiers),
        || slots::holders(&own_event, &slots::notifier_nodes(&own_event)),
        |holder| ConnectError::SlotTaken {
            service: format!("{own_name} (event)"),
            port: "notifier",
            reserved_for: own.side,
            holder,
        },
        ("creating the notifier of", &own_name),
    )?;
    let listener = if opts.listen {
        Some(exclusive_port(
            || peer_event.listener_builder().create(),
            |e| matches!(e, ListenerCreateError::ExceedsMaxSupportedListeners),
            || slots::holders(&peer_event, &slots::listener_nodes(&peer_event)),
            |holder| ConnectError::SlotTaken {
                service: format!("{peer_name} (event)"),
                port: "listener",
                reserved_for: own.side,
                holder,
            },
            ("creating the listener of", &peer_name),
        )?)
    } else {
        None
    };
    // The subscriber comes last: a peer that sees it knows this side's listener exists.
    let subscriber = exclusive_port(
        || peer_service.subscriber_builder().create(),
        |e| matches!(e, SubscriberCreateError::ExceedsMaxSupportedSubscribers),
        || slots::holders(&peer_service, &slots::subscriber_nodes(&peer_service)),
        |holder| ConnectError::SlotTaken {
            service: peer_name.clone(),
            port: "subscriber",
            reserved_for: own.side,
            holder,
        },
        ("creating the subscriber of", &peer_name),
    )?;
    // Pin the peer: the one live publisher of its service. A publisher left by a killed
    // peer can still be listed until its node is cleaned up; pinning it would leave this
    // side waiting for samples that never come (and, on the plant's side, take the stale
    // subscriber for the service's), so it is skipped and its resources removed.
    let start = Instant::now();
    let (peer_publisher, peer_node) = loop {
        let mut found = None;
        let mut stale = false;
        peer_service.dynamic_config().list_publishers(|d| {
            if liveness::node_alive(&d.node_id) {
                found = Some((d.publisher_id, d.node_id));
                CallbackProgression::Stop
            } else {
                stale = true;
                CallbackProgression::Continue
            }
        });
        if let Some(f) = found {
            break f;
        }
        if stale {
            cleanup_dead_nodes();
        }
        wait_a_little(start, &peer_name, &opts)?;
    };
    let peer_pid = peer_node
        .pid::<ipc::Service>()
        .ok()
        .map(|p| p.value() as u32);
    // Wait until the peer has subscribed to this side's samples, so that the first sample
    // sent after connect() is not lost (lockstep runs depend on it). The subscriber must be
    // the pinned peer's: a foreign process in the slot is refused by name.
    let start = Instant::now();
    loop {
        let subscribers = slots::subscriber_nodes(&own_service);
        if subscribers.contains(&peer_node) {
            break;
        }
        if !subscribers.is_empty() && start.elapsed() >= opts.peer_timeout {
            let holders = slots::holders(&own_service, &subscribers);
            return Err(ConnectError::SlotTaken {
                service: own_name.clone(),
                port: "subscriber",
                reserved_for: own.side.peer(),
                holder: slots::describe(&holders),
            });
        }
        wait_a_little(start, &own_name, &opts)?;
    }
    let ports = Ports {
        publisher,
        subscriber,
        notifier,
        listener,
        peer,
        pin: PeerPin::new(peer_publisher.value(), peer_pid, true),
        _own_event: own_event,
        _peer_event: peer_event,
        _own_service: own_service,
        _peer_service: peer_service,
        _node: node,
    };
    ports.update_connections();
    Ok(ports)
}

/// How long [`exclusive_port`] keeps retrying a slot held by a dead process (whose stale
/// port [`cleanup_dead_nodes`] removes).
const STALE_SLOT_RETRY: Duration = Duration::from_secs(2);

/// Creates a port whose slot is exclusive: when iceoryx2 says the slot is taken (`full`),
/// asks who holds it (`holders`); a dead holder's stale port is cleaned up and the creation
/// retried, a live holder is refused with `refuse(description)`.
fn exclusive_port<P, E: fmt::Debug>(
    mut create: impl FnMut() -> Result<P, E>,
    full: impl Fn(&E) -> bool,
    holders: impl Fn() -> Vec<Holder>,
    refuse: impl Fn(String) -> ConnectError,
    (what, item): (&str, &str),
) -> Result<P, ConnectError> {
    let start = Instant::now();
    loop {
        match create() {
            Ok(p) => return Ok(p),
            Err(e) if full(&e) => {
                let h = holders();
                if h.iter().any(|h| h.alive) {
                    let live: Vec<Holder> = h.into_iter().filter(|h| h.alive).collect();
                    return Err(refuse(slots::describe(&live)));
                }
                if start.elapsed() >= STALE_SLOT_RETRY {
                    return Err(refuse(format!(
                        "{} (its stale port could not be removed)",
                        slots::describe(&h)
                    )));
                }
                cleanup_dead_nodes();
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => return Err(ipc_err(what, item, e)),
        }
    }
}

impl<Out: fmt::Debug + ZeroCopySend + 'static, In: fmt::Debug + ZeroCopySend + 'static>
    Ports<Out, In>
{
    /// Establishes the shared-memory connections to the peer's current ports now. iceoryx2
    /// otherwise does it lazily on the first send, receive or notify, which allocates; call
    /// this in set-up code (connect() already does) and after a peer has been replaced.
    pub fn update_connections(&self) {
        use iceoryx2::port::update_connections::UpdateConnections;
        let _ = self.publisher.update_connections();
        let _ = self.subscriber.update_connections();
        let _ = self.notifier.update_connections();
    }

    /// Where a received sample came from: the pinned peer, a new peer that replaced it (the
    /// pin moves to it: start a new session), or a foreign publisher (refuse the sample; it
    /// is counted in [`Ports::foreign_samples`]). Pass `sample.origin()`:
    ///
    /// ```ignore
    /// while let Ok(Some(sample)) = ports.subscriber.receive() {
    ///     match ports.admit(sample.origin()) {
    ///         Origin::Peer => use_it(&*sample),
    ///         Origin::NewPeer => { new_session(); use_it(&*sample) }
    ///         Origin::Foreign => {} // refused and counted
    ///     }
    /// }
    /// ```
    ///
    /// A few integer compares: no allocation, no lock, no system call, no panic; for the
    /// real-time receive path. See [`crate::peer`] for why a publisher other than the pinned
    /// one is the new peer (the slot admits one publisher).
    #[inline]
    pub fn admit(&self, origin: iceoryx2::identifiers::UniquePublisherId) -> Origin {
        self.pin.admit(origin)
    }

    /// Samples refused as foreign so far.
    pub fn foreign_samples(&self) -> u64 {
        self.pin.foreign_samples()
    }

    /// The pid of the pinned peer's process, when known (after a re-pin, once
    /// [`Ports::refresh_peer`] has run).
    pub fn peer_pid(&self) -> Option<u32> {
        self.pin.peer_pid()
    }

    /// Reads the peer service's publisher list (set-up or idle code: it allocates) and tells
    /// whether the pinned peer is still there; records the pid of a pinned peer whose pid
    /// was not known yet (after [`Origin::NewPeer`]), and establishes the connections to
    /// a new publisher so that its first samples do not allocate in the receive path.
    pub fn refresh_peer(&self) -> PeerPresence {
        let mut pinned_there = None;
        let mut other = None;
        self._peer_service.dynamic_config().list_publishers(|d| {
            let pid = d.node_id.pid::<ipc::Service>().ok().map(|p| p.value());
            if d.publisher_id.value() == self.pin.pinned() {
                pinned_there = Some((pid, liveness::node_alive(&d.node_id)));
            } else {
                other = Some(pid);
            }
            CallbackProgression::Continue
        });
        self.update_connections();
        match (pinned_there, other) {
            (Some((pid, alive)), _) => {
                let pid = pid.map(|p| p as u32);
                if let Some(p) = pid {
                    self.pin.set_pid(p);
                }
                if alive {
                    PeerPresence::Present { pid }
                } else {
                    PeerPresence::Gone
                }
            }
            (None, Some(pid)) => PeerPresence::Replaced {
                pid: pid.map(|p| p as u32),
            },
            (None, None) => PeerPresence::Gone,
        }
    }
}

/// What [`Ports::refresh_peer`] found on the peer's service.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PeerPresence {
    /// The pinned publisher is registered and its process lives.
    Present {
        /// Its pid, when known.
        pid: Option<u32>,
    },
    /// The pinned publisher is gone (or its process died) and no other publisher is there.
    Gone,
    /// Another publisher holds the slot: its first sample will be [`Origin::NewPeer`].
    Replaced {
        /// Its pid, when known.
        pid: Option<u32>,
    },
}

/// Creates this process's iceoryx2 node `node_name` (signal handling left to the caller).
pub(crate) fn create_node(node_name: &str) -> Result<Node<ipc::Service>, ConnectError> {
    NodeBuilder::new()
        .name(
            &node_name
                .try_into()
                .map_err(|e| ipc_err("naming the node", node_name, e))?,
        )
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| node_err(node_name, e))
}

pub(crate) fn service_name(name: &str) -> Result<ServiceName, ConnectError> {
    ServiceName::new(name).map_err(|e| ipc_err("naming the service", name, e))
}

/// Opens (or creates) the event service `name`: one notifier (the side that publishes on
/// `name`) and one listener (its peer, when it blocks). A service that admits more is
/// refused.
fn open_event(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<EventFactory<ipc::Service>, ConnectError> {
    let f = node
        .service_builder(&service_name(name)?)
        .event()
        .max_notifiers(1)
        .max_listeners(1)
        .open_or_create()
        .map_err(|e| ipc_err("opening the event service", name, e))?;
    let c = f.static_config();
    if c.max_notifiers() != 1 || c.max_listeners() != 1 {
        return Err(ConnectError::NotExclusive {
            service: format!("{name} (event)"),
            detail: format!(
                "admits {} notifiers and {} listeners",
                c.max_notifiers(),
                c.max_listeners()
            ),
        });
    }
    Ok(f)
}

/// Refuses a publish-subscribe service that admits more than one publisher or subscriber.
fn verify_exclusive<T: fmt::Debug + ZeroCopySend + 'static>(
    f: &PubSubFactory<ipc::Service, T, ()>,
    name: &str,
) -> Result<(), ConnectError> {
    let c = f.static_config();
    if c.max_publishers() != 1 || c.max_subscribers() != 1 {
        return Err(ConnectError::NotExclusive {
            service: name.to_string(),
            detail: format!(
                "admits {} publishers and {} subscribers",
                c.max_publishers(),
                c.max_subscribers()
            ),
        });
    }
    Ok(())
}

fn pubsub_builder<T: fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<iceoryx2::service::builder::publish_subscribe::Builder<T, (), ipc::Service>, ConnectError>
{
    Ok(node
        .service_builder(&service_name(name)?)
        .publish_subscribe::<T>()
        .max_publishers(1)
        .max_subscribers(1)
        .subscriber_max_buffer_size(SUBSCRIBER_BUFFER)
        .history_size(0)
        .enable_safe_overflow(true))
}

fn verify(existing: &ContractInfo, own: &ContractInfo, service: &str) -> Result<(), ConnectError> {
    let differences = own.differences(existing);
    if differences.is_empty() {
        Ok(())
    } else {
        Err(ConnectError::Mismatch {
            service: service.to_string(),
            holder: existing.side,
            differences,
        })
    }
}

fn open_own<T: fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    own: &ContractInfo,
    opts: &ConnectOptions<'_>,
) -> Result<PubSubFactory<ipc::Service, T, ()>, ConnectError> {
    let start = Instant::now();
    loop {
        match pubsub_builder::<T>(node, name)?.open() {
            Ok(f) => {
                let existing = ContractInfo::from_attributes(f.attributes(), name)?;
                // The service may survive a crash of this side, held open by the peer.
                let existing = ContractInfo {
                    side: own.side,
                    ..existing
                };
                verify(&existing, own, name)?;
                verify_exclusive(&f, name)?;
                return Ok(f);
            }
            Err(PublishSubscribeOpenError::DoesNotExist)
            | Err(PublishSubscribeOpenError::IsMarkedForDestruction) => {}
            Err(PublishSubscribeOpenError::IncompatibleTypes) => {
                return Err(ConnectError::IncompatibleType {
                    service: name.to_string(),
                });
            }
            Err(e) => return Err(ipc_err("opening", name, e)),
        }
        match pubsub_builder::<T>(node, name)?.create_with_attributes(&own.specifier()?) {
            Ok(f) => return Ok(f),
            Err(PublishSubscribeCreateError::AlreadyExists)
            | Err(PublishSubscribeCreateError::IsBeingCreatedByAnotherInstance) => {}
            Err(e) => return Err(ipc_err("creating", name, e)),
        }
        wait_a_little(start, name, opts)?;
    }
}

fn open_peer<T: fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    own: &ContractInfo,
    opts: &ConnectOptions<'_>,
) -> Result<(PubSubFactory<ipc::Service, T, ()>, ContractInfo), ConnectError> {
    let start = Instant::now();
    let mut last_cleanup = start;
    loop {
        match pubsub_builder::<T>(node, name)?.open() {
            Ok(f) => {
                let peer = ContractInfo::from_attributes(f.attributes(), name)?;
                if peer.side != own.side.peer() {
                    return Err(ConnectError::NotAContractService {
                        service: name.to_string(),
                        detail: format!(
                            "it was created by a {}, expected the {}",
                            peer.side.name(),
                            own.side.peer().name()
                        ),
                    });
                }
                verify(&peer, own, name)?;
                verify_exclusive(&f, name)?;
                return Ok((f, peer));
            }
            Err(PublishSubscribeOpenError::DoesNotExist)
            | Err(PublishSubscribeOpenError::IsMarkedForDestruction) => {}
            // A service left half-created by a crashed peer: remove the dead node's
            // resources, at most once a second (a cleanup lists every node of the machine).
            Err(PublishSubscribeOpenError::HangsInCreation) => {
                if last_cleanup.elapsed() >= Duration::from_secs(1) {
                    cleanup_dead_nodes();
                    last_cleanup = Instant::now();
                }
            }
            Err(PublishSubscribeOpenError::IncompatibleTypes) => {
                return Err(ConnectError::IncompatibleType {
                    service: name.to_string(),
                });
            }
            Err(e) => return Err(ipc_err("opening", name, e)),
        }
        wait_a_little(start, name, opts)?;
    }
}

/// How long a side that refuses a peer for a contract mismatch keeps its own service up,
/// so that the peer can read it and refuse too.
const MISMATCH_LINGER: Duration = Duration::from_secs(3);

fn wait_a_little(
    start: Instant,
    name: &str,
    opts: &ConnectOptions<'_>,
) -> Result<(), ConnectError> {
    if opts.shutdown.is_some_and(|s| s.load(Ordering::Relaxed)) {
        return Err(ConnectError::Interrupted);
    }
    if start.elapsed() >= opts.peer_timeout {
        return Err(ConnectError::PeerTimeout {
            service: name.to_string(),
            waited: start.elapsed(),
        });
    }
    std::thread::sleep(Duration::from_millis(5));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(side: Side, n_y: u16, n_u: u16, period_ns: u64) -> ContractInfo {
        ContractInfo::new(
            side,
            ChannelCounts {
                n_y,
                n_z: n_y,
                n_r: 0,
                n_u,
            },
            period_ns,
        )
    }

    #[test]
    fn service_names_are_derived_from_the_rig_name() {
        let n = service_names("bench-7").unwrap();
        assert_eq!(n.measurement, "adaptive-rig/bench-7/measurement");
        assert_eq!(n.actuation, "adaptive-rig/bench-7/actuation");
        assert!(service_names("a/b").is_err());
        assert!(service_names("").is_err());
    }

    #[test]
    fn differences_name_each_field_and_each_side() {
        let plant = info(Side::Plant, 1, 2, 125_000);
        let mut service = info(Side::Service, 2, 2, 10_000_000);
        service.version = 7;
        let d = service.differences(&plant);
        assert_eq!(d.len(), 4, "{d:?}");
        assert!(
            d[0].contains(&format!(
                "contract version: plant has {CONTRACT_VERSION}, service has 7"
            )),
            "{}",
            d[0]
        );
        assert!(
            d.iter()
                .any(|l| l.contains("measurement channels (y): plant uses 1, service uses 2"))
        );
        assert!(d.iter().any(|l| l.contains("sample period")));
        assert!(
            plant
                .differences(&info(Side::Service, 1, 2, 125_000))
                .is_empty()
        );
    }

    #[test]
    fn connect_options_name_only_what_differs_from_the_defaults() {
        let stop = AtomicBool::new(false);
        let plain = ConnectOptions::new(Duration::from_millis(250));
        assert_eq!(plain.peer_timeout, Duration::from_millis(250));
        assert!(plain.shutdown.is_none() && !plain.listen && plain.waiting_message.is_none());
        let full = plain
            .with_shutdown(&stop)
            .with_listener(true)
            .with_waiting_message("waiting");
        assert!(full.shutdown.is_some_and(|s| core::ptr::eq(s, &stop)));
        assert!(full.listen);
        assert_eq!(full.waiting_message, Some("waiting"));
        assert_eq!(full.with_waiting_message(None).waiting_message, None);
    }

    #[test]
    fn a_peer_with_other_counts_is_refused_at_connect_time() {
        let rig = format!("unit-mismatch-{}", std::process::id());
        let plant = info(Side::Plant, 1, 2, 1_000_000);
        let service = info(Side::Service, 1, 1, 1_000_000);
        let rig2 = rig.clone();
        // The service is up first and waits; the plant that then arrives with other counts
        // sees the service's attributes and refuses, naming the difference.
        let t = std::thread::spawn(move || {
            let opts = ConnectOptions::new(Duration::from_secs(2));
            connect::<Actuation, Measurement>(&rig2, service, "unit-service", opts).map(|_| ())
        });
        std::thread::sleep(Duration::from_millis(300));
        let opts = ConnectOptions::new(Duration::from_secs(5));
        let err = connect::<Measurement, Actuation>(&rig, plant, "unit-plant", opts)
            .err()
            .expect("the mismatch must be refused");
        let msg = err.to_string();
        assert!(msg.contains("contract mismatch"), "{msg}");
        assert!(
            msg.contains("actuation channels (u): service uses 1, plant uses 2"),
            "{msg}"
        );
        assert!(
            t.join().unwrap().is_err(),
            "the service never gets a compatible plant"
        );
    }

    #[test]
    fn a_plant_that_applies_at_the_sample_refuses_a_service_that_does_not_send_ahead() {
        let plant = info(Side::Plant, 1, 1, 125_000).with_applies(Applies::AtSample);
        for t in [Timing::ComputeFirst, Timing::AnswerFirst] {
            let service = info(Side::Service, 1, 1, 125_000).with_timing(t);
            let d = plant.differences(&service);
            assert_eq!(d.len(), 1, "{d:?}");
            assert!(d[0].contains("only a service that sends ahead"), "{}", d[0]);
            assert!(d[0].contains(t.name()), "{}", d[0]);
            assert_eq!(service.differences(&plant), d, "the same from either side");
        }
        let ahead = info(Side::Service, 1, 1, 125_000).with_timing(Timing::SendAhead);
        assert!(plant.differences(&ahead).is_empty());
        for applies in [Applies::AtDeadline, Applies::Lockstep] {
            let p = info(Side::Plant, 1, 1, 125_000).with_applies(applies);
            for t in Timing::ALL {
                let s = info(Side::Service, 1, 1, 125_000).with_timing(t);
                assert!(p.differences(&s).is_empty(), "{applies:?} {t:?}");
            }
        }
        // Unstated timings are not compared (the versions are).
        assert!(
            plant
                .differences(&info(Side::Service, 1, 1, 125_000))
                .is_empty()
        );
    }

    #[test]
    fn the_timing_attributes_are_read_back_as_written_and_a_mismatch_is_refused_at_connect() {
        let rig = format!("unit-timing-{}", std::process::id());
        let plant = info(Side::Plant, 1, 1, 1_000_000).with_applies(Applies::AtSample);
        let service = info(Side::Service, 1, 1, 1_000_000).with_timing(Timing::ComputeFirst);
        let rig2 = rig.clone();
        let t = std::thread::spawn(move || {
            let opts = ConnectOptions::new(Duration::from_secs(2));
            connect::<Actuation, Measurement>(&rig2, service, "unit-timing-service", opts)
                .map(|_| ())
        });
        std::thread::sleep(Duration::from_millis(300));
        let opts = ConnectOptions::new(Duration::from_secs(5));
        let err = connect::<Measurement, Actuation>(&rig, plant, "unit-timing-plant", opts)
            .err()
            .expect("the timing mismatch must be refused");
        let msg = err.to_string();
        assert!(msg.contains("contract mismatch"), "{msg}");
        assert!(
            msg.contains("the service answers compute-first"),
            "the service's attribute was read back: {msg}"
        );
        assert!(t.join().unwrap().is_err());
    }

    #[test]
    fn a_second_plant_is_refused_naming_the_first_and_a_restarted_plant_is_a_new_peer() {
        use std::sync::Arc;
        let rig = format!("unit-pin-{}", std::process::id());
        let plant = info(Side::Plant, 1, 1, 1_000_000);
        let service = info(Side::Service, 1, 1, 1_000_000);
        let done = Arc::new(AtomicBool::new(false));
        let (rig2, done2) = (rig.clone(), done.clone());
        // The service: records where each sample came from until it saw seq 2.
        let t = std::thread::spawn(move || {
            let opts = ConnectOptions::new(Duration::from_secs(10));
            let ports = connect::<Actuation, Measurement>(&rig2, service, "unit-pin-service", opts)
                .unwrap();
            let first_pid = ports.peer_pid();
            let mut seen = Vec::new();
            let start = Instant::now();
            while !seen.contains(&(2, Origin::Peer)) {
                while let Ok(Some(s)) = ports.subscriber.receive() {
                    let origin = ports.admit(s.origin());
                    if !seen.contains(&(s.seq, origin)) {
                        seen.push((s.seq, origin));
                    }
                }
                assert!(start.elapsed() < Duration::from_secs(20), "{seen:?}");
                std::thread::sleep(Duration::from_millis(1));
            }
            done2.store(true, Ordering::Relaxed);
            let presence = ports.refresh_peer();
            (first_pid, seen, ports.foreign_samples(), presence)
        });
        let send_until = |ports: &PlantPorts, seq: u64, stop: &dyn Fn() -> bool| {
            let mut m = Measurement::zeroed(plant.counts);
            m.seq = seq;
            let start = Instant::now();
            while !stop() {
                ports.publisher.send_copy(m).unwrap();
                std::thread::sleep(Duration::from_millis(2));
                assert!(start.elapsed() < Duration::from_secs(20));
            }
        };
        let opts = ConnectOptions::new(Duration::from_secs(10));
        let p1 = connect::<Measurement, Actuation>(&rig, plant, "unit-pin-plant", opts).unwrap();
        let err = connect::<Measurement, Actuation>(&rig, plant, "unit-pin-plant-2", opts)
            .err()
            .expect("a second plant must be refused");
        let msg = err.to_string();
        assert!(matches!(err, ConnectError::AlreadyRunning { .. }), "{msg}");
        assert!(
            msg.contains(&format!(
                "rig '{rig}' already has a plant: pid {} (node 'unit-pin-plant')",
                std::process::id()
            )),
            "{msg}"
        );
        let sent = Instant::now();
        send_until(&p1, 1, &|| sent.elapsed() > Duration::from_millis(100));
        drop(p1);
        let p2 = connect::<Measurement, Actuation>(&rig, plant, "unit-pin-plant-3", opts).unwrap();
        send_until(&p2, 2, &|| done.load(Ordering::Relaxed));
        let (first_pid, seen, foreign, presence) = t.join().unwrap();
        assert_eq!(first_pid, Some(std::process::id()));
        assert_eq!(
            seen,
            [(1, Origin::Peer), (2, Origin::NewPeer), (2, Origin::Peer)]
        );
        assert_eq!(foreign, 0);
        assert_eq!(
            presence,
            PeerPresence::Present {
                pid: Some(std::process::id())
            }
        );
    }

    #[test]
    fn matching_sides_connect_and_exchange_a_sample() {
        let rig = format!("unit-match-{}", std::process::id());
        let plant = info(Side::Plant, 2, 1, 1_000_000);
        let service = info(Side::Service, 2, 1, 1_000_000);
        let opts = ConnectOptions::new(Duration::from_secs(5));
        let rig2 = rig.clone();
        let t = std::thread::spawn(move || {
            let ports =
                connect::<Measurement, Actuation>(&rig2, plant, "unit-plant2", opts).unwrap();
            let mut m = Measurement::zeroed(plant.counts);
            m.seq = 42;
            m.y[1] = 3.5;
            let start = Instant::now();
            loop {
                ports.publisher.send_copy(m).unwrap();
                if let Some(a) = ports.subscriber.receive().unwrap() {
                    return (a.seq, a.u[0]);
                }
                assert!(start.elapsed() < Duration::from_secs(5), "no answer");
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        let ports =
            connect::<Actuation, Measurement>(&rig, service, "unit-service2", opts).unwrap();
        assert_eq!(ports.peer.side, Side::Plant);
        let start = Instant::now();
        loop {
            if let Some(m) = ports.subscriber.receive().unwrap() {
                let mut a = Actuation::zeroed(service.counts);
                a.seq = m.seq;
                a.u[0] = -m.y[1];
                ports.publisher.send_copy(a).unwrap();
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(5), "no measurement");
            std::thread::sleep(Duration::from_millis(1));
        }
        // keep answering until the plant thread has read it
        let (seq, u) = t.join().unwrap();
        assert_eq!((seq, u), (42, -3.5));
    }
}
