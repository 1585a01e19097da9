//! `ar_controller_t`: the service side of the contract for a controller written in C (for
//! completeness: the Rust service is the product's controller). It connects as the rig's
//! service, receives the pinned plant's measurements one at a time, oldest first, and
//! publishes actuations with a notification.

use crate::args;
use crate::guard;
use crate::status::{AR_ERR_IO, AR_ERR_TIMEOUT, AR_STOPPED, ArStatus, Failure};
use crate::stop::STOP;
use ipc_types::clock::monotonic_ns;
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, ServicePorts, Side};
use ipc_types::{Actuation, CONTRACT_VERSION, ChannelCounts, Measurement, Timing};
use std::ffi::c_char;
use std::sync::atomic::Ordering;
use std::time::Duration;

/// `ar_controller_t`: one connected service side. Opaque to C.
pub struct ArController {
    ports: ServicePorts,
    counts: ChannelCounts,
    timing: Timing,
}

// SAFETY: iceoryx2's `ipc::Service` ports are `!Send` only because they share their state
// through non-atomic `Rc`s (its `SingleThreaded` policy; it keeps no thread-local state and
// no thread identity). Every clone of those `Rc`s lives inside this handle (its node, its
// services, its ports; no sample is held between calls), so the handle moves between
// threads as a whole and its reference counts are only ever touched by the one thread that
// holds it, which is the contract the header states (one thread at a time).
unsafe impl Send for ArController {}

/// Connects to the plant of rig `rig` as its service: `counts` channels, `period_ns`,
/// answering with `timing` (`AR_TIMING_*`); waits up to `peer_timeout_s` for the plant.
/// Errors as `ar_plant_open` (`AR_ERR_MISMATCH` naming each difference, `AR_ERR_IN_USE`
/// when the rig is already served, ...). `*out` is set only on success.
///
/// # Safety
/// `rig` is null or a NUL-terminated string; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_controller_open(
    rig: *const c_char,
    counts: ChannelCounts,
    period_ns: u64,
    timing: u32,
    peer_timeout_s: f64,
    out: *mut *mut ArController,
) -> ArStatus {
    const F: &str = "ar_controller_open";
    guard::call(F, || {
        // SAFETY: null or NUL-terminated, by this function's contract.
        let rig = unsafe { args::text(rig, F, "rig") }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        let counts = args::counts(counts, F, "counts")?;
        if period_ns == 0 {
            return Err(Failure::invalid(format!(
                "{F}: period_ns: the sample period must be positive"
            )));
        }
        let timing = Timing::from_wire(timing).ok_or_else(|| {
            Failure::invalid(format!(
                "{F}: timing: {timing} is none of AR_TIMING_COMPUTE_FIRST, AR_TIMING_ANSWER_FIRST, AR_TIMING_SEND_AHEAD"
            ))
        })?;
        let peer_timeout = args::seconds(peer_timeout_s, F, "peer_timeout_s")?;
        let own = ContractInfo::new(Side::Service, counts, period_ns).with_timing(timing);
        let opts = ConnectOptions::new(peer_timeout)
            .with_listener(true)
            .with_shutdown(&STOP);
        let ports: ServicePorts =
            ipc_types::ports::connect(rig, own, "adaptive-rig-c-controller", opts)?;
        *out = Box::into_raw(Box::new(ArController {
            ports,
            counts,
            timing,
        }));
        Ok(())
    })
}

/// The controller behind a handle.
///
/// # Safety
/// `ctrl` is null or a live handle used by no other thread.
unsafe fn controller<'a>(
    ctrl: *mut ArController,
    function: &str,
) -> Result<&'a mut ArController, Failure> {
    // SAFETY: null or a live handle used by this thread only, by the caller's contract.
    unsafe { args::write(ctrl, function, "ctrl") }
}

/// Receives the oldest pending measurement of the pinned plant into `*out`, waiting up to
/// `timeout_ns` for one (0: do not wait). Samples of any other publisher are refused (a
/// restarted plant, which can only appear once the old one is gone, is pinned instead).
/// `AR_ERR_TIMEOUT` when none came, `AR_STOPPED` on `ar_request_stop`.
///
/// # Safety
/// `ctrl` is null or a live handle used by this thread only; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_controller_receive(
    ctrl: *mut ArController,
    out: *mut Measurement,
    timeout_ns: u64,
) -> ArStatus {
    const F: &str = "ar_controller_receive";
    guard::call(F, || {
        // SAFETY: by this function's contract.
        let c = unsafe { controller(ctrl, F) }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        let deadline = monotonic_ns().saturating_add(timeout_ns);
        loop {
            loop {
                match c.ports.subscriber.receive() {
                    Ok(Some(sample)) => match c.ports.admit(sample.origin()) {
                        Origin::Peer | Origin::NewPeer => {
                            *out = *sample;
                            return Ok(());
                        }
                        Origin::Foreign => {}
                    },
                    Ok(None) => break,
                    Err(e) => {
                        return Err(Failure::new(
                            AR_ERR_IO,
                            format!("{F}: receiving a measurement: {e:?}"),
                        ));
                    }
                }
            }
            if STOP.load(Ordering::Relaxed) {
                return Err(Failure::new(
                    AR_STOPPED,
                    format!("{F}: stopped (ar_request_stop)"),
                ));
            }
            let now = monotonic_ns();
            if now >= deadline {
                return Err(Failure::new(
                    AR_ERR_TIMEOUT,
                    format!("{F}: no measurement within {timeout_ns} ns"),
                ));
            }
            // At least 1 ms: a zero time-out means "for ever" to iceoryx2's wait; at most
            // 10 ms so that a stop request is seen.
            let wait = Duration::from_nanos(deadline - now)
                .clamp(Duration::from_millis(1), Duration::from_millis(10));
            match &c.ports.listener {
                Some(l) => {
                    let _ = l.timed_wait(|_| {}, wait);
                }
                None => std::thread::sleep(wait),
            }
        }
    })
}

/// Fills `*out` with an empty actuation of this controller: contract version, counts and
/// timing set, everything else zero.
///
/// # Safety
/// `ctrl` is null or a live handle; `out` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_controller_actuation_init(
    ctrl: *const ArController,
    out: *mut Actuation,
) -> ArStatus {
    const F: &str = "ar_controller_actuation_init";
    guard::call(F, || {
        // SAFETY: null or a live handle, by this function's contract.
        let c = unsafe { args::read(ctrl, F, "ctrl") }?;
        // SAFETY: null or writable, by this function's contract.
        let out = unsafe { args::write(out, F, "out") }?;
        let mut a = Actuation::zeroed(c.counts);
        a.timing = c.timing.wire();
        *out = a;
        Ok(())
    })
}

/// Publishes `*act` (its `t_publish_ns` stamped now) and notifies the plant. Refuses an
/// actuation of another contract version or other counts than the controller's
/// (`AR_ERR_INVALID_ARGUMENT`; start from `ar_controller_actuation_init`).
///
/// # Safety
/// `ctrl` is null or a live handle used by this thread only; `act` is null or points to a
/// valid `ar_actuation_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_controller_send(
    ctrl: *mut ArController,
    act: *const Actuation,
) -> ArStatus {
    const F: &str = "ar_controller_send";
    guard::call(F, || {
        // SAFETY: by this function's contract.
        let c = unsafe { controller(ctrl, F) }?;
        // SAFETY: null or a valid actuation, by this function's contract.
        let act = unsafe { args::read(act, F, "act") }?;
        if act.contract_version != CONTRACT_VERSION {
            return Err(Failure::invalid(format!(
                "{F}: act->contract_version: {} is not this contract's {CONTRACT_VERSION}",
                act.contract_version
            )));
        }
        if act.counts != c.counts {
            return Err(Failure::invalid(format!(
                "{F}: act->counts: {}",
                c.counts
                    .differences("controller", &act.counts, "actuation")
                    .join("; ")
            )));
        }
        let mut a = *act;
        a.t_publish_ns = monotonic_ns();
        c.ports
            .publisher
            .send_copy(a)
            .map_err(|e| Failure::new(AR_ERR_IO, format!("{F}: publishing: {e:?}")))?;
        c.ports
            .notifier
            .notify()
            .map_err(|e| Failure::new(AR_ERR_IO, format!("{F}: notifying: {e:?}")))?;
        Ok(())
    })
}

/// Disconnects and frees the handle (a null handle is ignored).
///
/// # Safety
/// `ctrl` is null or a live handle from `ar_controller_open`, not used afterwards.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn ar_controller_close(ctrl: *mut ArController) -> ArStatus {
    guard::call("ar_controller_close", || {
        if !ctrl.is_null() {
            // SAFETY: a live handle from Box::into_raw in ar_controller_open, given back once.
            drop(unsafe { Box::from_raw(ctrl) });
        }
        Ok(())
    })
}
