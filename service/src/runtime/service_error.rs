//! Why the service could not run, naming the file, field or process at fault.

use std::fmt;

/// Why the service could not run.
#[derive(Debug)]
pub enum ServiceError {
    /// The run folder could not be created or written.
    Io {
        /// What was being done.
        what: String,
        /// The OS error.
        error: std::io::Error,
    },
    /// The controller could not be built.
    Controller(String),
    /// `require-rt` is set and the OS refused a real-time set-up step.
    RtRefused(String),
    /// The plant could not be connected.
    Connect(ipc_types::ports::ConnectError),
    /// The RT thread ended abnormally.
    RtThread(String),
    /// The warm-start checkpoint was refused (the message names the file and the block).
    Checkpoint(String),
}

impl fmt::Display for ServiceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ServiceError::Io { what, error } => write!(f, "{what}: {error}"),
            ServiceError::Controller(m) => write!(f, "controller: {m}"),
            ServiceError::RtRefused(m) => write!(
                f,
                "real-time set-up refused and service.require-rt is true: {m}"
            ),
            ServiceError::Connect(e) => write!(f, "{e}"),
            ServiceError::RtThread(m) => write!(f, "RT thread: {m}"),
            ServiceError::Checkpoint(m) => write!(f, "warm start refused: {m}"),
        }
    }
}

impl std::error::Error for ServiceError {}
