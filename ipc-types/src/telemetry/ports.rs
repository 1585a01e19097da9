//! The telemetry services' ports: the service's [`TelemetryPublisher`] and a watcher's
//! [`TelemetryReader`].
//!
//! Both sides open the services with the same settings (`open_or_create`), so either may
//! start first. Everything here allocates: it runs on the service's telemetry thread and in
//! watchers, never on the real-time thread.

use super::{MAX_READERS, TelemetryFrame, TelemetryInfo};
use crate::ports::{ConnectError, SERVICE_PREFIX, ipc_err, service_name, valid_rig};
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;

/// Frames a reader's queue holds: 16 frames, about 0.8 s.
pub const READER_BUFFER: usize = 16;

/// The telemetry service names of rig `rig`: `(frames, info)`.
pub fn telemetry_service_names(rig: &str) -> Result<(String, String), ConnectError> {
    valid_rig(rig)?;
    Ok((
        format!("{SERVICE_PREFIX}/{rig}/telemetry"),
        format!("{SERVICE_PREFIX}/{rig}/telemetry-info"),
    ))
}

fn node(name: &str) -> Result<Node<ipc::Service>, ConnectError> {
    set_log_level(LogLevel::Error);
    crate::ports::create_node(name)
}

fn open<T: core::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    history: usize,
    buffer: usize,
) -> Result<PubSubFactory<ipc::Service, T, ()>, ConnectError> {
    node.service_builder(&service_name(name)?)
        .publish_subscribe::<T>()
        .max_publishers(1)
        .max_subscribers(MAX_READERS)
        .history_size(history)
        .subscriber_max_buffer_size(buffer)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| ipc_err("opening the telemetry service", name, e))
}

/// The service's side: publishes frames and the run's info.
pub struct TelemetryPublisher {
    frames: Publisher<ipc::Service, TelemetryFrame, ()>,
    info: Publisher<ipc::Service, TelemetryInfo, ()>,
    _services: (
        PubSubFactory<ipc::Service, TelemetryFrame, ()>,
        PubSubFactory<ipc::Service, TelemetryInfo, ()>,
    ),
    _node: Node<ipc::Service>,
}

impl core::fmt::Debug for TelemetryPublisher {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TelemetryPublisher")
    }
}

impl TelemetryPublisher {
    /// Opens rig `rig`'s telemetry services and takes their one publisher slot.
    ///
    /// # Errors
    ///
    /// An invalid rig name, an iceoryx2 failure (naming the service), or another process
    /// already publishing telemetry for this rig.
    pub fn create(rig: &str) -> Result<Self, ConnectError> {
        let (frames_name, info_name) = telemetry_service_names(rig)?;
        // A service that died leaves its publisher slot registered: free it first.
        crate::ports::cleanup_dead_nodes();
        let node = node("adaptive-rig-telemetry")?;
        let frames_service = open::<TelemetryFrame>(&node, &frames_name, 0, READER_BUFFER)?;
        let info_service = open::<TelemetryInfo>(&node, &info_name, 1, 2)?;
        let frames = frames_service
            .publisher_builder()
            .create()
            .map_err(|e| ipc_err("creating the telemetry publisher", &frames_name, e))?;
        let info = info_service
            .publisher_builder()
            .create()
            .map_err(|e| ipc_err("creating the telemetry publisher", &info_name, e))?;
        Ok(Self {
            frames,
            info,
            _services: (frames_service, info_service),
            _node: node,
        })
    }

    /// Publishes `frame`; returns whether it was sent (a failure loses this frame only).
    ///
    /// It also connects the info publisher to the readers that subscribed since the last
    /// call: iceoryx2 delivers a publisher's history to a new subscriber only when the
    /// publisher updates its connections, which the info publisher (it sends once per run)
    /// would otherwise never do, and a reader that came after the info would never get it.
    pub fn publish(&self, frame: &TelemetryFrame) -> bool {
        let _ = self.info.update_connections();
        match self.frames.loan_uninit() {
            Ok(s) => s.write_payload(*frame).send().is_ok(),
            Err(_) => false,
        }
    }

    /// Publishes the run's `info` (kept as history for readers that come later).
    pub fn publish_info(&self, info: &TelemetryInfo) -> bool {
        match self.info.loan_uninit() {
            Ok(s) => s.write_payload(*info).send().is_ok(),
            Err(_) => false,
        }
    }
}

/// A watcher's side: receives frames and the run's info.
pub struct TelemetryReader {
    frames: Subscriber<ipc::Service, TelemetryFrame, ()>,
    info: Subscriber<ipc::Service, TelemetryInfo, ()>,
    _services: (
        PubSubFactory<ipc::Service, TelemetryFrame, ()>,
        PubSubFactory<ipc::Service, TelemetryInfo, ()>,
    ),
    _node: Node<ipc::Service>,
}

impl core::fmt::Debug for TelemetryReader {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("TelemetryReader")
    }
}

impl TelemetryReader {
    /// Opens rig `rig`'s telemetry services (creating them when no service runs yet) and
    /// subscribes to both.
    ///
    /// # Errors
    ///
    /// An invalid rig name, an iceoryx2 failure, or [`MAX_READERS`] readers already
    /// subscribed.
    pub fn open(rig: &str) -> Result<Self, ConnectError> {
        let (frames_name, info_name) = telemetry_service_names(rig)?;
        let node = node("adaptive-rig-telemetry-reader")?;
        let frames_service = open::<TelemetryFrame>(&node, &frames_name, 0, READER_BUFFER)?;
        let info_service = open::<TelemetryInfo>(&node, &info_name, 1, 2)?;
        let frames = frames_service
            .subscriber_builder()
            .buffer_size(READER_BUFFER)
            .create()
            .map_err(|e| ipc_err("subscribing to the telemetry", &frames_name, e))?;
        let info = info_service
            .subscriber_builder()
            .buffer_size(2)
            .create()
            .map_err(|e| ipc_err("subscribing to the telemetry", &info_name, e))?;
        Ok(Self {
            frames,
            info,
            _services: (frames_service, info_service),
            _node: node,
        })
    }

    /// Calls `each` with every frame received since the last call, oldest first; returns
    /// how many.
    pub fn frames(&self, mut each: impl FnMut(&TelemetryFrame)) -> usize {
        let mut n = 0;
        while let Ok(Some(s)) = self.frames.receive() {
            each(&s);
            n += 1;
        }
        n
    }

    /// The newest info received since the last call, if any (boxed: it is 66 KiB).
    pub fn info(&self) -> Option<Box<TelemetryInfo>> {
        let mut newest = None;
        while let Ok(Some(s)) = self.info.receive() {
            newest = Some(Box::new(*s));
        }
        newest
    }
}
