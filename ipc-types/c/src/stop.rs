//! The process-wide stop request: what a C signal handler calls to end the waits of every
//! handle ([`ar_request_stop`]).

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by [`ar_request_stop`]; every handle's waits read it.
pub static STOP: AtomicBool = AtomicBool::new(false);

/// Asks every wait of this process to end: `ar_plant_open` and `ar_controller_open` waiting
/// for the peer, `ar_plant_take` waiting in lockstep or until a time, `ar_controller_receive`;
/// they return `AR_STOPPED`. One atomic store: async-signal-safe, callable from a signal
/// handler (SIGINT, SIGTERM). Stays set until [`ar_clear_stop`].
#[unsafe(no_mangle)]
pub extern "C" fn ar_request_stop() {
    STOP.store(true, Ordering::Relaxed);
}

/// Withdraws a stop request (for a process that starts a new run afterwards).
#[unsafe(no_mangle)]
pub extern "C" fn ar_clear_stop() {
    STOP.store(false, Ordering::Relaxed);
}

/// Whether a stop was requested: 1 or 0.
#[unsafe(no_mangle)]
pub extern "C" fn ar_stop_requested() -> i32 {
    i32::from(STOP.load(Ordering::Relaxed))
}
