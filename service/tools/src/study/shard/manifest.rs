//! A shard's manifest (`manifest.json` in its folder): which study, with which options,
//! from which commit and binary, which slice, and whether its runs are all done.
//!
//! A shard writes it when it starts (`complete: false`) and again when its last run is
//! recorded (`complete: true`, with the hash of the study's whole list of runs). A
//! restarted shard and `study merge` compare manifests: the study, the options' hash and
//! the commit must be equal; the binary's hash is recorded and a difference reported.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use super::ShardError;
use super::slice::Slice;
use crate::file_error::{FileError, FileOp};

/// The manifest's file name in a shard's folder.
pub const MANIFEST_FILE: &str = "manifest.json";

/// The commit the binary was built from (`git rev-parse HEAD` at build time; `unknown`
/// outside a git checkout).
pub const COMMIT: &str = env!("RIG_TOOLS_COMMIT");

/// A shard's manifest.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    /// The `study` subcommand (`sampling-arm`, …, `all`).
    pub study: String,
    /// The command line after `study`, without `--shard`: what `study merge` runs again.
    pub args: Vec<String>,
    /// SHA-256 of the study's parsed options (the same for any spelling of the same
    /// command line).
    pub config_hash: String,
    /// The commit the binary was built from.
    pub commit: String,
    /// SHA-256 of the binary that ran the shard.
    pub binary_sha256: String,
    /// Which shard.
    pub slice: Slice,
    /// The folder the study writes into (`--out`): the merge's default.
    pub out: PathBuf,
    /// SHA-256 of the study's list of runs (stages and each run's item), once complete.
    pub grid_hash: Option<String>,
    /// The study's runs, all shards together, once complete.
    pub runs_total: Option<usize>,
    /// This shard's runs recorded so far.
    pub runs_recorded: usize,
    /// True when every run of the shard is recorded.
    pub complete: bool,
}

impl Manifest {
    /// A new shard's manifest (nothing recorded yet).
    pub fn new(
        study: &str,
        args: Vec<String>,
        config: &str,
        slice: Slice,
        out: &Path,
    ) -> Result<Self, ShardError> {
        Ok(Self {
            study: study.to_string(),
            args,
            config_hash: sha256_hex(config.as_bytes()),
            commit: COMMIT.to_string(),
            binary_sha256: binary_sha256()?,
            slice,
            out: out.to_path_buf(),
            grid_hash: None,
            runs_total: None,
            runs_recorded: 0,
            complete: false,
        })
    }

    /// Reads `dir/manifest.json`.
    pub fn read(dir: &Path) -> Result<Self, ShardError> {
        let path = dir.join(MANIFEST_FILE);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| FileError::new(FileOp::Reading, &path, e))?;
        serde_json::from_str(&text).map_err(|e| ShardError::Manifest {
            path,
            why: e.to_string(),
        })
    }

    /// Writes `dir/manifest.json` atomically.
    pub fn write(&self, dir: &Path) -> Result<(), ShardError> {
        let path = dir.join(MANIFEST_FILE);
        let text = serde_json::to_string_pretty(self).map_err(|e| ShardError::Manifest {
            path: path.clone(),
            why: e.to_string(),
        })?;
        ipc_types::files::write_atomic(&path, text + "\n")
            .map_err(|source| FileError::new(FileOp::Writing, &path, source.into()))?;
        Ok(())
    }

    /// The first of study, options and commit in which `other` differs from `self`, as
    /// `(field, self's, other's)`.
    pub fn differs(&self, other: &Manifest) -> Option<(&'static str, String, String)> {
        if self.study != other.study {
            return Some(("study", self.study.clone(), other.study.clone()));
        }
        if self.config_hash != other.config_hash {
            return Some((
                "options",
                self.args.join(" "),
                format!("{} (config hash differs)", other.args.join(" ")),
            ));
        }
        if self.commit != other.commit {
            return Some(("commit", self.commit.clone(), other.commit.clone()));
        }
        None
    }
}

/// SHA-256 of `bytes`, in hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// Lower-case hex of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of the running executable.
fn binary_sha256() -> Result<String, ShardError> {
    let exe = std::env::current_exe().map_err(ShardError::Executable)?;
    let mut file =
        std::fs::File::open(&exe).map_err(|e| FileError::new(FileOp::Reading, &exe, e))?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = file
            .read(&mut buf)
            .map_err(|e| FileError::new(FileOp::Reading, &exe, e))?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hex(&hasher.finalize()))
}
