//! One thread per rig that subscribes to the rig's telemetry and fills its
//! [`RigState`](super::state::RigState).
//!
//! The thread polls every [`POLL`] (frames come every 50 ms; the reader's queue holds
//! 0.8 s of them). It survives the service: when subscribing fails it says why in the
//! rig's state and tries again every [`OPEN_RETRY`]; when no frame came for
//! [`REOPEN_AFTER`] it subscribes afresh, so that a service that restarted (or a stale
//! iceoryx2 port of one that died) does not keep the monitor blind. Frames are copied out
//! of shared memory, taken into the state under its lock, then handed to the
//! [`FrameObserver`]s (the Foxglove bridge) outside it.

use super::placement;
use super::state::Hub;
use ipc_types::telemetry::ports::TelemetryReader;
use ipc_types::telemetry::{TelemetryFrame, TelemetryInfo};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How often a reader looks for frames.
pub const POLL: Duration = Duration::from_millis(10);
/// How long a reader waits before it tries again to subscribe after a failure.
pub const OPEN_RETRY: Duration = Duration::from_secs(1);
/// A reader that got no frame for this long subscribes afresh.
pub const REOPEN_AFTER: Duration = Duration::from_secs(5);

/// Something that wants every frame and info of every rig as it arrives.
pub trait FrameObserver: Send + Sync + 'static {
    /// Frame `frame` of rig number `rig` (its index in the hub) arrived.
    fn on_frame(&self, rig: usize, frame: &TelemetryFrame);
    /// Info `info` of rig number `rig` arrived.
    fn on_info(&self, rig: usize, info: &TelemetryInfo);
}

/// Starts the reader thread of rig number `rig` of `hub`; it runs until `stop` is set.
///
/// # Errors
///
/// The thread could not be started.
pub fn spawn(
    hub: Arc<Hub>,
    rig: usize,
    stop: Arc<AtomicBool>,
    observers: Vec<Arc<dyn FrameObserver>>,
    keep_off_rt: bool,
) -> std::io::Result<JoinHandle<()>> {
    let name = format!("monitor-{}", hub.names()[rig]);
    std::thread::Builder::new()
        .name(name.chars().take(15).collect())
        .spawn(move || run(&hub, rig, &stop, &observers, keep_off_rt))
}

/// How often the real-time cores of a service not yet placed are looked for.
const PLACE_EVERY: Duration = Duration::from_secs(1);

/// Moves the monitor off the real-time cores of the service `pid` of rig `i`, once they
/// are known; true once done (or there was nothing to do for a service without them).
fn place(hub: &Hub, i: usize, pid: u32) -> bool {
    let cores = placement::real_time_cores(pid);
    if cores.is_empty() {
        return false;
    }
    let text = match placement::keep_off(&cores) {
        placement::Placement::Already => format!("off the service's real-time cores {cores:?}"),
        placement::Placement::Moved(left) => {
            format!("moved to cores {left:?}, off the service's real-time cores {cores:?}")
        }
        placement::Placement::Stayed(why) => {
            format!("stays on the service's real-time cores {cores:?}: {why}")
        }
    };
    eprintln!("[monitor] rig '{}': {text}", hub.names()[i]);
    hub.lock(i).placement = Some(text);
    true
}

fn run(
    hub: &Hub,
    i: usize,
    stop: &AtomicBool,
    observers: &[Arc<dyn FrameObserver>],
    keep_off_rt: bool,
) {
    let rig = hub.names()[i].clone();
    let mut placed_pid: Option<u32> = None;
    let mut next_place = Instant::now();
    let mut reader: Option<TelemetryReader> = None;
    let mut next_try = Instant::now();
    // The newest frame, or the subscription when none came since.
    let mut last_activity = Instant::now();
    let mut frames: Vec<Box<TelemetryFrame>> = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let now = Instant::now();
        if reader.is_none() && now >= next_try {
            match TelemetryReader::open(&rig) {
                Ok(r) => {
                    reader = Some(r);
                    last_activity = now;
                    let mut s = hub.lock(i);
                    s.reader_opens += 1;
                    s.reader_error = None;
                }
                Err(e) => {
                    hub.lock(i).reader_error =
                        Some(format!("rig '{rig}': subscribing to its telemetry: {e}"));
                    next_try = now + OPEN_RETRY;
                }
            }
        }
        if let Some(r) = &reader {
            if let Some(info) = r.info() {
                for o in observers {
                    o.on_info(i, &info);
                }
                hub.lock(i).on_info(info);
            }
            r.frames(|f| frames.push(Box::new(*f)));
            if !frames.is_empty() {
                last_activity = now;
                let mut s = hub.lock(i);
                for f in &frames {
                    s.on_frame(f, now);
                }
            }
            for f in frames.drain(..) {
                for o in observers {
                    o.on_frame(i, &f);
                }
            }
            let pid = hub.lock(i).info.as_ref().map(|info| info.service_pid);
            if let Some(pid) = pid.filter(|p| keep_off_rt && *p != 0 && placed_pid != Some(*p))
                && now >= next_place
            {
                next_place = now + PLACE_EVERY;
                if place(hub, i, pid) {
                    placed_pid = Some(pid);
                }
            }
            if now.saturating_duration_since(last_activity) > REOPEN_AFTER {
                reader = None;
                next_try = now;
            }
        }
        std::thread::sleep(POLL);
    }
}
