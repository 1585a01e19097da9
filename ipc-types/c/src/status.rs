//! The return codes of the C interface (`ar_status_t`) and the failures behind them.
//!
//! Every function of the interface that can fail returns an [`ArStatus`]: [`AR_OK`] (0) on
//! success, [`AR_STOPPED`] (positive: not a failure of the call) when a wait was abandoned
//! because [`ar_request_stop`](crate::stop::ar_request_stop) was called, and a negative
//! `AR_ERR_*` code otherwise, whose message [`ar_last_error`](crate::last_error::ar_last_error)
//! gives.

use ipc_types::ports::ConnectError;
use plant_side::PlantError;
use std::ffi::{CStr, c_char};

/// `ar_status_t`: the result of a call (`int32_t` in C).
pub type ArStatus = i32;

/// The call succeeded.
pub const AR_OK: ArStatus = 0;
/// A wait (connect, a lockstep answer, a controller's receive) was abandoned because
/// [`ar_request_stop`](crate::stop::ar_request_stop) was called; nothing was decided.
pub const AR_STOPPED: ArStatus = 1;
/// A null pointer, a count past the contract's capacity, a string that is not UTF-8, a
/// value outside its range; the message names the argument.
pub const AR_ERR_INVALID_ARGUMENT: ArStatus = -1;
/// Connecting to the peer failed in iceoryx2 (shared memory, node, ports).
pub const AR_ERR_CONNECT: ArStatus = -2;
/// The peer states another contract (version, channel counts, period, timing, payload
/// layout); the message names each difference.
pub const AR_ERR_MISMATCH: ArStatus = -3;
/// The peer did not appear, or no sample arrived, within the time allowed.
pub const AR_ERR_TIMEOUT: ArStatus = -4;
/// Lockstep: no service answered for `peer_timeout_s` after the watchdog tripped; the plant
/// gave up.
pub const AR_ERR_GAVE_UP: ArStatus = -5;
/// An I/O failure (a send or receive of iceoryx2 during the run).
pub const AR_ERR_IO: ArStatus = -6;
/// A panic inside the library was caught at the boundary; the handle concerned must only
/// be closed.
pub const AR_ERR_PANIC: ArStatus = -7;
/// Another live process already holds this side of the rig (a second plant, a second
/// service) or a port slot of the contract.
pub const AR_ERR_IN_USE: ArStatus = -8;
/// iceoryx2's shared-memory files belong to another user.
pub const AR_ERR_PERMISSION: ArStatus = -9;
/// The caller's buffer is too small; the length needed was written.
pub const AR_ERR_BUFFER_TOO_SMALL: ArStatus = -10;

/// Every code with its C name, for [`ar_status_name`] and the header test.
pub const ALL: [(ArStatus, &CStr); 12] = [
    (AR_OK, c"AR_OK"),
    (AR_STOPPED, c"AR_STOPPED"),
    (AR_ERR_INVALID_ARGUMENT, c"AR_ERR_INVALID_ARGUMENT"),
    (AR_ERR_CONNECT, c"AR_ERR_CONNECT"),
    (AR_ERR_MISMATCH, c"AR_ERR_MISMATCH"),
    (AR_ERR_TIMEOUT, c"AR_ERR_TIMEOUT"),
    (AR_ERR_GAVE_UP, c"AR_ERR_GAVE_UP"),
    (AR_ERR_IO, c"AR_ERR_IO"),
    (AR_ERR_PANIC, c"AR_ERR_PANIC"),
    (AR_ERR_IN_USE, c"AR_ERR_IN_USE"),
    (AR_ERR_PERMISSION, c"AR_ERR_PERMISSION"),
    (AR_ERR_BUFFER_TOO_SMALL, c"AR_ERR_BUFFER_TOO_SMALL"),
];

/// The name of a status code (`"AR_ERR_MISMATCH"`), or `"AR_UNKNOWN_STATUS"`. The string is
/// static; never null. Does not touch [`ar_last_error`](crate::last_error::ar_last_error).
#[unsafe(no_mangle)]
pub extern "C" fn ar_status_name(status: ArStatus) -> *const c_char {
    ALL.iter()
        .find(|(code, _)| *code == status)
        .map_or(c"AR_UNKNOWN_STATUS".as_ptr(), |(_, name)| name.as_ptr())
}

/// A failed (or stopped) call: its code and the message for
/// [`ar_last_error`](crate::last_error::ar_last_error).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Failure {
    /// The code returned.
    pub status: ArStatus,
    /// The message.
    pub message: String,
}

impl Failure {
    /// A failure of code `status` with `message`.
    pub fn new(status: ArStatus, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }

    /// [`AR_ERR_INVALID_ARGUMENT`] with `message` (which names the argument).
    pub fn invalid(message: impl Into<String>) -> Self {
        Self::new(AR_ERR_INVALID_ARGUMENT, message)
    }
}

impl From<ConnectError> for Failure {
    fn from(e: ConnectError) -> Self {
        let status = match &e {
            ConnectError::InvalidRigName { .. } => AR_ERR_INVALID_ARGUMENT,
            ConnectError::Mismatch { .. }
            | ConnectError::IncompatibleType { .. }
            | ConnectError::NotAContractService { .. }
            | ConnectError::NotExclusive { .. } => AR_ERR_MISMATCH,
            ConnectError::PeerTimeout { .. } => AR_ERR_TIMEOUT,
            ConnectError::Interrupted => AR_STOPPED,
            ConnectError::AlreadyRunning { .. } | ConnectError::SlotTaken { .. } => AR_ERR_IN_USE,
            ConnectError::PermissionDenied { .. } => AR_ERR_PERMISSION,
            ConnectError::Ipc { .. } => AR_ERR_CONNECT,
        };
        // The text the Rust processes print for the same failure.
        Failure::new(status, e.to_string())
    }
}

impl From<PlantError> for Failure {
    fn from(e: PlantError) -> Self {
        match e {
            PlantError::Config(m) => Failure::invalid(m),
            PlantError::Connect(c) => c.into(),
            PlantError::Io(m) => Failure::new(AR_ERR_IO, m),
            PlantError::GaveUp { message, .. } => Failure::new(AR_ERR_GAVE_UP, message),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn every_code_has_its_name_and_unknown_codes_say_so() {
        for (code, name) in ALL {
            // SAFETY: ar_status_name returns a static NUL-terminated string.
            let got = unsafe { CStr::from_ptr(ar_status_name(code)) };
            assert_eq!(got, name);
        }
        // SAFETY: as above.
        let unknown = unsafe { CStr::from_ptr(ar_status_name(42)) };
        assert_eq!(unknown, c"AR_UNKNOWN_STATUS");
        let mut codes: Vec<_> = ALL.iter().map(|(c, _)| *c).collect();
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), ALL.len(), "codes are distinct");
    }

    #[test]
    fn connect_failures_map_to_their_codes_with_the_rust_message() {
        let mismatch = ConnectError::Mismatch {
            service: "adaptive-rig/x/actuation".into(),
            holder: ipc_types::ports::Side::Service,
            differences: vec!["measurement channels (y): service uses 1, plant uses 2".into()],
        };
        let text = mismatch.to_string();
        let f = Failure::from(PlantError::Connect(mismatch));
        assert_eq!(f.status, AR_ERR_MISMATCH);
        assert_eq!(f.message, text);
        let timeout = ConnectError::PeerTimeout {
            service: "s".into(),
            waited: Duration::from_secs(1),
        };
        assert_eq!(Failure::from(timeout).status, AR_ERR_TIMEOUT);
        assert_eq!(Failure::from(ConnectError::Interrupted).status, AR_STOPPED);
        assert_eq!(
            Failure::from(PlantError::Config("deadline: 2".into())).status,
            AR_ERR_INVALID_ARGUMENT
        );
    }
}
