//! Who holds the one port slot of a contract service, so that a refusal names the process.
//!
//! Every service of the contract admits one publisher, one subscriber, one notifier and
//! one listener ([`super::connect`]). When a slot is taken, iceoryx2 says only
//! `ExceedsMaxSupported…`; this module reads the service's port list (each port's node id
//! carries the pid of the process that created it) and the service's node list (for the
//! node's name), and tells a live holder (a second service, a second plant, a foreign
//! process) from a stale entry of a dead process, which [`super::cleanup_dead_nodes`]
//! removes. Set-up code: it allocates.

use iceoryx2::identifiers::UniqueNodeId;
use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use std::fmt;

/// The process behind one port of a service.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Holder {
    /// Its pid, when iceoryx2 can tell.
    pub pid: Option<i32>,
    /// The name of its iceoryx2 node, when it is listed.
    pub node: Option<String>,
    /// Whether the process still exists.
    pub alive: bool,
}

impl fmt::Display for Holder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.pid {
            Some(p) => write!(f, "pid {p}")?,
            None => write!(f, "a process of unknown pid")?,
        }
        if let Some(n) = &self.node {
            write!(f, " (node '{n}')")?;
        }
        if !self.alive {
            write!(f, ", which is dead")?;
        }
        Ok(())
    }
}

/// All holders, "pid 1 (node 'a') and pid 2", or "nobody visible".
pub(crate) fn describe(holders: &[Holder]) -> String {
    if holders.is_empty() {
        return "a process that is no longer listed".into();
    }
    holders
        .iter()
        .map(Holder::to_string)
        .collect::<Vec<_>>()
        .join(" and ")
}

/// The holders of the ports whose node ids are `ids`, named from `factory`'s node list.
pub(crate) fn holders<F: PortFactory<Service = ipc::Service>>(
    factory: &F,
    ids: &[UniqueNodeId],
) -> Vec<Holder> {
    let mut names: Vec<(UniqueNodeId, String)> = Vec::new();
    let _ = factory.nodes(|state| {
        let (id, details) = match &state {
            NodeState::Alive(v) => (*v.id(), v.details().clone()),
            NodeState::Dead(v) => (*v.id(), v.details().clone()),
            _ => return CallbackProgression::Continue,
        };
        if let Some(d) = details {
            names.push((id, d.name().as_str().to_string()));
        }
        CallbackProgression::Continue
    });
    ids.iter()
        .map(|id| {
            let pid = id.pid::<ipc::Service>().ok().map(|p| p.value());
            Holder {
                pid,
                node: names
                    .iter()
                    .find(|(n, _)| n == id)
                    .map(|(_, name)| name.clone()),
                alive: super::liveness::node_alive(id),
            }
        })
        .collect()
}

/// The node ids of the publishers of a publish-subscribe service.
pub(crate) fn publisher_nodes<T: fmt::Debug + ZeroCopySend + 'static>(
    f: &iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
) -> Vec<UniqueNodeId> {
    let mut out = Vec::new();
    f.dynamic_config().list_publishers(|d| {
        out.push(d.node_id);
        CallbackProgression::Continue
    });
    out
}

/// The node ids of the subscribers of a publish-subscribe service.
pub(crate) fn subscriber_nodes<T: fmt::Debug + ZeroCopySend + 'static>(
    f: &iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
) -> Vec<UniqueNodeId> {
    let mut out = Vec::new();
    f.dynamic_config().list_subscribers(|d| {
        out.push(d.node_id);
        CallbackProgression::Continue
    });
    out
}

/// The node ids of the notifiers of an event service.
pub(crate) fn notifier_nodes(
    f: &iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
) -> Vec<UniqueNodeId> {
    let mut out = Vec::new();
    f.dynamic_config().list_notifiers(|d| {
        out.push(d.node_id);
        CallbackProgression::Continue
    });
    out
}

/// The node ids of the listeners of an event service.
pub(crate) fn listener_nodes(
    f: &iceoryx2::service::port_factory::event::PortFactory<ipc::Service>,
) -> Vec<UniqueNodeId> {
    let mut out = Vec::new();
    f.dynamic_config().list_listeners(|d| {
        out.push(d.node_id);
        CallbackProgression::Continue
    });
    out
}
