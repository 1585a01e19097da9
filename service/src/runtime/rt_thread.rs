//! The RT thread: real-time set-up (pinning, `SCHED_FIFO`, `mlockall`, the CPU wake-up
//! latency), the connection to the plant, and the loop that waits for each measurement,
//! takes in what it missed and hands each sample to [`LoopCore`].

use super::pacing::{Pacer, WaitStep};
use super::{LoopCore, Outbox, ServiceError};
use crate::config::{ServiceConfig, WaitMode};
use ipc_types::clock::monotonic_ns;
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, ServicePorts, Side};
use ipc_types::rt::RtSetup;
use ipc_types::{Actuation, ChannelCounts, Measurement, measurement_flags};
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Why the loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// SIGINT or SIGTERM.
    Signal,
    /// The plant sent its last sample.
    PlantEnded,
    /// The configured maximum number of cycles was reached.
    MaxCycles,
    /// An operator sent `stop-run` ([`crate::runtime::operator`]).
    Operator,
}

/// Blocks in the RT thread's allocation pool (iceoryx2 holds at most a few at once).
pub const RT_POOL_BLOCKS: usize = 256;

type RtResult = Result<(LoopCore, RtSetup, StopReason), ServiceError>;

pub(super) fn rt_thread_main(
    cfg: ServiceConfig,
    mut core: LoopCore,
    shutdown: Arc<AtomicBool>,
    max_cycles: Option<u64>,
    exit_with_plant: bool,
    probe: &crate::scheduling::RtProbe,
) -> RtResult {
    let setup = ipc_types::rt::setup_current_thread(&cfg.rt);
    if setup.any_refused() {
        eprintln!(
            "[service] WARNING: real-time set-up incomplete: {}",
            setup.describe()
        );
        if cfg.require_rt {
            return Err(ServiceError::RtRefused(setup.describe()));
        }
    }
    if setup.fifo == ipc_types::rt::StepOutcome::Done
        && let Some(w) = cfg.throttled_busy_poll()
    {
        eprintln!("[service] WARNING: {w}");
        if cfg.require_rt {
            return Err(ServiceError::RtRefused(w));
        }
    }
    let own = ContractInfo::new(Side::Service, cfg.counts, cfg.sample_period_ns)
        .with_timing(core.timing());
    let waiting = format!("[service] waiting for the plant on rig '{}' ...", cfg.rig);
    let opts = ConnectOptions::new(cfg.peer_timeout)
        .with_shutdown(&shutdown)
        .with_listener(cfg.wait != WaitMode::BusyPoll)
        .with_waiting_message(waiting.as_str());
    let ports: ServicePorts =
        match ipc_types::ports::connect(&cfg.rig, own, "adaptive-rig-service", opts) {
            Ok(p) => p,
            Err(ipc_types::ports::ConnectError::Interrupted) => {
                return Ok((core, setup, StopReason::Signal));
            }
            Err(e) => return Err(ServiceError::Connect(e)),
        };
    eprintln!(
        "[service] connected to the plant; running ({:?}, {})",
        cfg.wait,
        core.timing().name()
    );
    core.prepare_controller_thread();
    crate::rt_alloc::enter_rt_thread(RT_POOL_BLOCKS);
    let before = crate::rt_alloc::thread_stats();
    crate::rt_alloc::outside_rt(|| probe.loop_starts());
    let fifo = setup.fifo == ipc_types::rt::StepOutcome::Done;
    let mut pacer = Pacer::new(cfg.wait, cfg.sample_period_ns, cfg.poll_window_ns)
        .with_throttling_budget(Pacer::throttling_budget(fifo));
    let stop = rt_loop(
        &ports,
        &mut core,
        &shutdown,
        &mut pacer,
        max_cycles,
        exit_with_plant,
    );
    core.rt_allocations = crate::rt_alloc::thread_stats().since(&before);
    core.pacing = pacer.report();
    crate::rt_alloc::outside_rt(|| probe.loop_ends());
    Ok((core, setup, stop))
}

/// Measurements kept per wake-up: the subscriber's whole queue
/// ([`ipc_types::ports::SUBSCRIBER_BUFFER`]), so none is dropped here.
const PENDING: usize = ipc_types::ports::SUBSCRIBER_BUFFER;

/// Takes every pending measurement of the pinned plant, oldest first, into the ring
/// `pending` (with `new_peer[i]` true for the first sample of a plant that replaced the
/// pinned one); returns how many were taken (only the newest `PENDING` are kept when more
/// arrived). Samples of any other publisher are refused and counted by the pin
/// ([`ipc_types::peer`]).
#[inline]
fn take_pending(
    ports: &ServicePorts,
    pending: &mut [Measurement; PENDING],
    new_peer: &mut [bool; PENDING],
) -> usize {
    let mut n = 0;
    while let Ok(Some(sample)) = ports.subscriber.receive() {
        let first_of_new_peer = match ports.admit(sample.origin()) {
            Origin::Peer => false,
            Origin::NewPeer => true,
            Origin::Foreign => continue,
        };
        pending[n % PENDING] = *sample;
        new_peer[n % PENDING] = first_of_new_peer;
        n += 1;
    }
    n
}

/// The service's [`Outbox`]: its iceoryx2 publisher and notifier.
pub struct PortsOutbox<'a>(pub &'a ServicePorts);

impl Outbox for PortsOutbox<'_> {
    #[inline]
    fn publish(&mut self, act: &mut Actuation) -> (bool, u64) {
        let ports = self.0;
        let ok = match ports.publisher.loan_uninit() {
            Ok(sample) => {
                act.t_publish_ns = monotonic_ns();
                let sample = sample.write_payload(*act);
                sample.send().is_ok()
            }
            Err(_) => false,
        };
        let t_pub = monotonic_ns();
        let _ = ports.notifier.notify();
        (ok, t_pub)
    }
}

/// One pass of the RT loop: wait, process, publish. Public so that the allocation test and
/// the latency bench run exactly this code.
pub fn rt_loop(
    ports: &ServicePorts,
    core: &mut LoopCore,
    shutdown: &AtomicBool,
    pacer: &mut Pacer,
    max_cycles: Option<u64>,
    exit_with_plant: bool,
) -> StopReason {
    let mut pending = [Measurement::zeroed(ChannelCounts::default()); PENDING];
    let mut new_peer = [false; PENDING];
    let mut out = PortsOutbox(ports);
    let mut spins: u32 = 0;
    let mut last_cleanup_ns = 0u64;
    let mut last_rx_ns = 0u64;
    let period_ns = core.period_ns;
    let late_ns = period_ns.saturating_add(period_ns / 2);
    let wait = pacer.mode();
    let mut left_fifo = false;
    loop {
        if shutdown.load(Ordering::Relaxed) {
            return StopReason::Signal;
        }
        let n = take_pending(ports, &mut pending, &mut new_peer);
        core.stats.foreign_samples = ports.foreign_samples();
        if n > 0 {
            let t_recv = monotonic_ns();
            last_rx_ns = t_recv;
            // Operator commands take effect at this sample boundary, before the samples.
            core.take_commands();
            if core.stop_requested() {
                return StopReason::Operator;
            }
            // Late samples first (a newer one is waiting): observed, not answered.
            let first = n.saturating_sub(PENDING);
            if (first..n).any(|i| new_peer[i % PENDING]) {
                // A replacing plant whose samples came before the loop took its ports in
                // while idle: iceoryx2 allocates when it connects to the new subscriber, so
                // connect now, outside the counted real-time work, before answering it.
                crate::rt_alloc::outside_rt(|| ports.update_connections());
            }
            for i in first..n - 1 {
                if new_peer[i % PENDING] {
                    core.note_new_peer();
                }
                core.observe(&pending[i % PENDING], &mut out);
            }
            if new_peer[(n - 1) % PENDING] {
                core.note_new_peer();
            }
            let m = &pending[(n - 1) % PENDING];
            if m.flags & measurement_flags::LOCKSTEP != 0 && !left_fifo {
                // A lockstep plant has no deadline: leave SCHED_FIFO once (a system call,
                // outside the counted real-time work), so that the ping-pong of a
                // lockstep run does not starve the normal tasks of the RT core.
                left_fifo = true;
                crate::rt_alloc::outside_rt(ipc_types::rt::leave_fifo);
            }
            pacer.on_sample(
                m.t_sample_ns,
                t_recv,
                m.flags & measurement_flags::LOCKSTEP != 0,
            );
            let d = core.handle(m, t_recv, &mut out);
            if d.last_sample && exit_with_plant {
                return StopReason::PlantEnded;
            }
            if max_cycles.is_some_and(|n| core.stats.received >= n) {
                return StopReason::MaxCycles;
            }
            continue;
        }
        let asked = monotonic_ns();
        let slept = match (pacer.next(asked, ports.listener.is_some()), &ports.listener) {
            (WaitStep::Block(timeout), Some(listener)) => {
                let _ = listener.timed_wait(|_| {}, timeout);
                true
            }
            (WaitStep::SleepUntil(t), _) => {
                ipc_types::clock::sleep_until_ns(t);
                true
            }
            _ => {
                core::hint::spin_loop();
                spins = spins.wrapping_add(1);
                if !spins.is_multiple_of(256) {
                    continue;
                }
                false
            }
        };
        // The time first, then the look for waiting samples: had this thread itself been
        // stopped in between, the samples that came meanwhile are found and it does not
        // take its own stall for a silent plant.
        let now = monotonic_ns();
        if slept {
            // The awake share of the pacer's cap counts this as time given back.
            pacer.slept(asked, now);
        }
        if now.saturating_sub(last_rx_ns) > late_ns {
            // The plant is late by half a period: there is nothing to answer now. A plant
            // that replaces the last one connects while the old one is gone, and iceoryx2
            // allocates when it takes in the new ports; take them in here, outside the
            // counted real-time work, rather than in the receive or publish of the new
            // plant's first sample. Without a change this allocates nothing.
            crate::rt_alloc::outside_rt(|| ports.update_connections());
        }
        core.take_commands();
        if core.stop_requested() {
            return StopReason::Operator;
        }
        // A failing look counts as "none waiting": the silence check must stay reachable,
        // or a dead plant would never be declared silent and never cleaned up after.
        if matches!(ports.subscriber.has_samples(), Ok(true)) {
            continue;
        }
        if core.on_idle(now) && now.saturating_sub(last_cleanup_ns) > 100_000_000 {
            // Silent plant: not controlling anything now, so housekeeping is allowed here.
            last_cleanup_ns = now;
            let n = crate::rt_alloc::outside_rt(|| {
                let n = ipc_types::ports::cleanup_dead_nodes();
                ports.update_connections();
                n
            });
            core.note_cleanup(n);
            if wait == WaitMode::BusyPoll {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
    }
}
