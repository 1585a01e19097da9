//! `study merge`: finding a study's shards, checking that they make one whole, and handing
//! their recorded runs to the study run again ([`super::Runs::merge`]).

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::de::DeserializeOwned;

use super::manifest::{MANIFEST_FILE, Manifest};
use super::run_log::{self, RUN_LOG_FILE, Recorded};
use super::{SHARDS_DIR, ShardError};
use crate::file_error::{FileError, FileOp};

/// One shard's folder, manifest and recorded runs.
#[derive(Debug)]
struct Source {
    dir: PathBuf,
    manifest: Manifest,
    log: PathBuf,
    runs: Recorded,
    used: Mutex<HashSet<(String, usize)>>,
}

/// The checked shards of one study: one study, options and commit; each of `0 … N−1`
/// once, complete.
#[derive(Debug)]
pub struct Shards {
    by_index: Vec<Source>,
}

/// The shard folders that `dir` names: itself when it holds a manifest, else those of
/// `dir/shards/*/`, else those of `dir/*/`.
fn shard_folders(dir: &Path) -> Result<Vec<PathBuf>, ShardError> {
    if dir.join(MANIFEST_FILE).is_file() {
        return Ok(vec![dir.to_path_buf()]);
    }
    let base = if dir.join(SHARDS_DIR).is_dir() {
        dir.join(SHARDS_DIR)
    } else {
        dir.to_path_buf()
    };
    let entries =
        std::fs::read_dir(&base).map_err(|e| FileError::new(FileOp::Reading, &base, e))?;
    let mut found = Vec::new();
    for e in entries {
        let e = e.map_err(|e| FileError::new(FileOp::Reading, &base, e))?;
        let p = e.path();
        if p.join(MANIFEST_FILE).is_file() {
            found.push(p);
        }
    }
    if found.is_empty() {
        return Err(ShardError::NoShards(dir.to_path_buf()));
    }
    found.sort();
    Ok(found)
}

impl Shards {
    /// Finds the shards in `dirs` (each a shard's folder, a study's `--out` or a folder of
    /// shards) and checks them; the error names the file at fault.
    pub fn find(dirs: &[PathBuf]) -> Result<Shards, ShardError> {
        let mut folders = Vec::new();
        for d in dirs {
            folders.extend(shard_folders(d)?);
        }
        let first_dir = folders
            .first()
            .cloned()
            .ok_or_else(|| ShardError::NoShards(PathBuf::from(".")))?;
        let first = Manifest::read(&first_dir)?;
        let count = first.slice.count;
        let mut slots: Vec<Option<Source>> = (0..count).map(|_| None).collect();
        for dir in folders {
            let manifest = Manifest::read(&dir)?;
            let path = dir.join(MANIFEST_FILE);
            let mixed = |field: &'static str, here: String, first: String| ShardError::Mixed {
                path: path.clone(),
                first_path: first_dir.join(MANIFEST_FILE),
                field,
                here,
                first,
            };
            if let Some((field, first_v, here)) = first.differs(&manifest) {
                return Err(mixed(field, here, first_v));
            }
            if manifest.slice.count != count {
                return Err(mixed(
                    "shard count",
                    manifest.slice.count.to_string(),
                    count.to_string(),
                ));
            }
            if !manifest.complete {
                return Err(ShardError::Unfinished {
                    dir,
                    slice: manifest.slice,
                    recorded: manifest.runs_recorded,
                });
            }
            if manifest.grid_hash != first.grid_hash || manifest.runs_total != first.runs_total {
                return Err(mixed(
                    "list of runs",
                    format!("{:?}", manifest.grid_hash),
                    format!("{:?}", first.grid_hash),
                ));
            }
            let i = manifest.slice.index;
            if let Some(other) = &slots[i] {
                return Err(ShardError::Duplicate {
                    slice: manifest.slice,
                    a: other.dir.clone(),
                    b: dir,
                });
            }
            let log = dir.join(RUN_LOG_FILE);
            let (runs, cut) = run_log::read(&log)?;
            if cut {
                return Err(ShardError::LogLine {
                    path: log,
                    line: runs.len() + 1,
                    why:
                        "the last line is cut short, though the manifest says the shard is complete"
                            .into(),
                });
            }
            slots[i] = Some(Source {
                dir,
                manifest,
                log,
                runs,
                used: Mutex::new(HashSet::new()),
            });
        }
        let missing: Vec<usize> = (0..count).filter(|&i| slots[i].is_none()).collect();
        if !missing.is_empty() {
            return Err(ShardError::Missing {
                count,
                missing,
                looked: dirs.to_vec(),
            });
        }
        Ok(Shards {
            by_index: slots.into_iter().flatten().collect(),
        })
    }

    /// The first shard's manifest (the study, its command line, its `--out`).
    pub fn manifest(&self) -> &Manifest {
        &self.by_index[0].manifest
    }

    /// The shards' folders, in index order.
    pub fn folders(&self) -> Vec<&Path> {
        self.by_index.iter().map(|s| s.dir.as_path()).collect()
    }

    /// Shards whose binary differs from shard 0's, as lines to print (allowed: one commit
    /// built on different machines).
    pub fn binary_notes(&self) -> Vec<String> {
        let first = &self.by_index[0].manifest.binary_sha256;
        self.by_index
            .iter()
            .filter(|s| &s.manifest.binary_sha256 != first)
            .map(|s| {
                format!(
                    "note: shard {} ran another binary of commit {} ({} against {})",
                    s.manifest.slice, s.manifest.commit, s.manifest.binary_sha256, first
                )
            })
            .collect()
    }

    /// The recorded result of the run `stage` #`index` (run number `g`, item key `key`),
    /// from the shard that owns it.
    pub(super) fn take<R: DeserializeOwned>(
        &self,
        stage: &str,
        index: usize,
        g: usize,
        key: &str,
    ) -> Result<R, ShardError> {
        let owner = &self.by_index[g % self.by_index.len()];
        let line =
            owner
                .runs
                .get(&(stage.to_string(), index))
                .ok_or_else(|| ShardError::RunMissing {
                    path: owner.log.clone(),
                    stage: stage.to_string(),
                    index,
                })?;
        if line.key != key {
            return Err(ShardError::KeyMismatch {
                path: owner.log.clone(),
                stage: stage.to_string(),
                index,
                recorded: line.key.clone(),
                expected: key.to_string(),
            });
        }
        let bytes = line.bytes(&owner.log)?;
        let value = postcard::from_bytes(&bytes).map_err(|e| ShardError::Record {
            path: owner.log.clone(),
            stage: stage.to_string(),
            index,
            why: e.to_string(),
        })?;
        owner
            .used
            .lock()
            .map_err(|_| ShardError::Poisoned)?
            .insert((stage.to_string(), index));
        Ok(value)
    }

    /// After the study's last stage: its `total` runs hashing to `hash` are the shards',
    /// and every recorded run was used.
    pub(super) fn finish(&self, total: usize, hash: &str) -> Result<(), ShardError> {
        let m = self.manifest();
        if m.runs_total != Some(total) || m.grid_hash.as_deref() != Some(hash) {
            return Err(ShardError::GridChanged {
                path: self.by_index[0].dir.join(MANIFEST_FILE),
                recorded: m.runs_total.unwrap_or(0),
                recorded_hash: m.grid_hash.clone().unwrap_or_default(),
                now: total,
                now_hash: hash.to_string(),
            });
        }
        for s in &self.by_index {
            let used = s.used.lock().map_err(|_| ShardError::Poisoned)?;
            let mut stray: Vec<&(String, usize)> =
                s.runs.keys().filter(|k| !used.contains(*k)).collect();
            stray.sort();
            if let Some((stage, i)) = stray.first() {
                return Err(ShardError::Stray {
                    path: s.log.clone(),
                    count: stray.len(),
                    first: format!("{stage} #{i}"),
                });
            }
        }
        Ok(())
    }
}
