//! A shard's run log (`runs.jsonl` in its folder): one line per finished run, appended
//! as the run ends, so a shard that is stopped and started again finds the
//! runs it already has.
//!
//! A line is `{"stage": S, "index": i, "key": K, "record": B}`: the stage's name, the
//! run's index in it, the hash of the run's item (what the run was asked) and the run's
//! result, postcard-encoded (every `f64` bit for bit, NaN and infinities included) and
//! base64'd. A last line cut short by a stop is dropped when the log is opened again.

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use super::ShardError;
use crate::file_error::{FileError, FileOp};

/// The run log's file name in a shard's folder.
pub const RUN_LOG_FILE: &str = "runs.jsonl";

/// One recorded run.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Line {
    /// The stage's name.
    pub stage: String,
    /// The run's index in its stage.
    pub index: usize,
    /// The hash of the run's item.
    pub key: String,
    /// The result, postcard then base64.
    pub record: String,
}

impl Line {
    /// The result's postcard bytes.
    pub fn bytes(&self, path: &Path) -> Result<Vec<u8>, ShardError> {
        STANDARD
            .decode(&self.record)
            .map_err(|e| ShardError::Record {
                path: path.to_path_buf(),
                stage: self.stage.clone(),
                index: self.index,
                why: e.to_string(),
            })
    }
}

/// The recorded runs of one log, by `(stage, index)`.
pub type Recorded = HashMap<(String, usize), Line>;

/// Reads the log at `path` (none yet: empty). A last line without its newline is left
/// out and reported as `true` (cut short); any other unreadable line is an error naming
/// the file and line.
pub fn read(path: &Path) -> Result<(Recorded, bool), ShardError> {
    let text = match std::fs::read_to_string(path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok((Recorded::new(), false));
        }
        Err(e) => return Err(FileError::new(FileOp::Reading, path, e).into()),
    };
    let cut = !text.is_empty() && !text.ends_with('\n');
    let whole = if cut {
        &text[..text.rfind('\n').map_or(0, |i| i + 1)]
    } else {
        &text[..]
    };
    let mut runs = Recorded::new();
    for (n, l) in whole.lines().enumerate() {
        let line: Line = serde_json::from_str(l).map_err(|e| ShardError::LogLine {
            path: path.to_path_buf(),
            line: n + 1,
            why: e.to_string(),
        })?;
        runs.insert((line.stage.clone(), line.index), line);
    }
    Ok((runs, cut))
}

/// The log a shard appends to.
#[derive(Debug)]
pub struct RunLog {
    path: PathBuf,
    file: Mutex<File>,
}

impl RunLog {
    /// Opens `path` for appending, first cutting a last line left short by a stop.
    pub fn open(path: &Path) -> Result<Self, ShardError> {
        let fail = |e| ShardError::from(FileError::new(FileOp::Writing, path, e));
        if let Ok(text) = std::fs::read(path)
            && !text.is_empty()
            && !text.ends_with(b"\n")
        {
            let keep = text.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
            let f = OpenOptions::new().write(true).open(path).map_err(fail)?;
            f.set_len(keep as u64).map_err(fail)?;
        }
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(fail)?;
        Ok(Self {
            path: path.to_path_buf(),
            file: Mutex::new(file),
        })
    }

    /// Appends one run, as one write of the whole line (unbuffered: a stopped process
    /// loses no finished run; the disk's own cache is left to the system).
    pub fn append(
        &self,
        stage: &str,
        index: usize,
        key: &str,
        bytes: &[u8],
    ) -> Result<(), ShardError> {
        let line = Line {
            stage: stage.to_string(),
            index,
            key: key.to_string(),
            record: STANDARD.encode(bytes),
        };
        let mut text = serde_json::to_string(&line).map_err(|e| ShardError::Record {
            path: self.path.clone(),
            stage: stage.to_string(),
            index,
            why: e.to_string(),
        })?;
        text.push('\n');
        let fail = |e| ShardError::from(FileError::new(FileOp::Writing, &self.path, e));
        let mut file = self.file.lock().map_err(|_| ShardError::Poisoned)?;
        file.write_all(text.as_bytes()).map_err(fail)
    }
}
