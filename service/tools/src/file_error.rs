//! A file or folder that a tool could not read, write or make: which one, what was being
//! done (it heads the message, as the option that named it does), and why.

use std::path::PathBuf;

/// What was being done to a file, as the message says it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FileOp {
    /// Any access; the message is `{path}: {why}`.
    Access,
    /// Reading: `reading {path}: {why}`.
    Reading,
    /// Writing: `writing {path}: {why}`.
    Writing,
    /// Making a folder: `creating {path}: {why}`.
    Creating,
    /// Making the folder of `--out`: `--out {path}: {why}`.
    Out,
    /// Writing the file of `--results`: `--results {path}: {why}`.
    Results,
}

impl FileOp {
    /// The words before the path in the message.
    fn prefix(self) -> &'static str {
        match self {
            FileOp::Access => "",
            FileOp::Reading => "reading ",
            FileOp::Writing => "writing ",
            FileOp::Creating => "creating ",
            FileOp::Out => "--out ",
            FileOp::Results => "--results ",
        }
    }
}

/// A file or folder that could not be read, written or made (`E`: the system's error, or
/// an atomic write's).
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {source}", op.prefix(), path.display())]
pub struct FileError<E: std::error::Error + 'static = std::io::Error> {
    /// What was being done.
    pub op: FileOp,
    /// The file or folder.
    pub path: PathBuf,
    /// Why it failed.
    #[source]
    pub source: E,
}

impl<E: std::error::Error + 'static> FileError<E> {
    /// `op` on `path` failed with `source`.
    pub fn new(op: FileOp, path: impl Into<PathBuf>, source: E) -> Self {
        Self {
            op,
            path: path.into(),
            source,
        }
    }
}

/// A file written atomically (`ipc_types::files::write_atomic`) that could not be.
pub type AtomicFileError = FileError<ipc_types::files::AtomicWriteError>;

message_from!(FileError, AtomicFileError);
