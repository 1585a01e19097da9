//! # shard: a study's runs split over a cluster's job array, and merged into the same result
//!
//! A study is a set of independent closed-loop runs (the grid points, the Monte Carlo
//! seeds, the experiments) followed by what it makes of them: statistics, CSV files,
//! figures, claims. [`Runs`] is where a study hands its runs over:
//!
//! - `runs.map(stage, items, f)` is `items.par_iter().map(f).collect()` when the study
//!   runs whole; on a shard it runs only the shard's slice of the items and appends each
//!   result to the shard's run log ([`run_log`]); in a merge it runs nothing and reads
//!   every result back from the shards' logs;
//! - `runs.gather()` comes after the study's last sharded stage and before it uses any
//!   result. On a shard it ends the study there ([`ShardError::ShardDone`]: the shard's
//!   part is done, its manifest says so); whole or in a merge it returns, and
//!   [`Stage::into_vec`] hands back every result in the items' order.
//!
//! What the study then writes is computed from the runs' own values (postcard keeps every
//! `f64` bit for bit), in the same order, by the same code: a merge writes byte for byte
//! what the study run whole writes, timing lines aside, and every statistic is computed
//! from the raw runs, never pooled from per-shard summaries. Work that depends on a
//! stage's results (a stage whose items are chosen from another's results, the
//! aggregation) runs after `gather`, in the merge.
//!
//! ## The slice
//!
//! The runs are numbered across the stages in the order the study calls `map`:
//! `g = 0 … R−1`. Shard `I` of `N` ([`Slice`]) runs those with `g mod N = I`: every run
//! goes to exactly one shard, the shards' counts differ by at most one, and a grid's
//! cheap and expensive corners are dealt round-robin to all shards. The numbering depends
//! only on the study's options, so every shard must be given identical arguments (the
//! manifest's hash of the parsed options checks it).
//!
//! ## A shard's folder
//!
//! `--out DIR` is shared by the shards (one command line for the whole array); shard `I`
//! of `N` writes `DIR/shards/I-of-N/`: [`manifest::MANIFEST_FILE`] (study, command line,
//! options' hash, commit, binary hash, slice, and once done the hash of the list of runs)
//! and [`run_log::RUN_LOG_FILE`]. Run again with the same arguments, a shard keeps the
//! runs its log has (checked against the item's hash) and runs only the rest.
//!
//! ## The merge
//!
//! `study merge DIR…` ([`merge`]) finds the shards, checks that they are of one study,
//! one set of options and one commit, that each of `0 … N−1` is there once and complete,
//! then runs the study again from their manifest's command line with [`Runs`] reading the
//! logs: each run must be in the log of the shard that owns it, for the same item, and
//! the list of runs must hash as the shards' did.

pub mod manifest;
pub mod merge;
pub mod run_log;
pub mod slice;

use std::collections::HashSet;
use std::fmt;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use serde::Serialize;
use serde::de::DeserializeOwned;
use sha2::{Digest, Sha256};

use crate::file_error::{FileError, FileOp};
use manifest::Manifest;
pub use slice::{Slice, SliceError};

/// The folder under `--out` that holds the shards' folders.
pub const SHARDS_DIR: &str = "shards";

/// Why sharding or merging failed; and [`ShardError::ShardDone`], a shard's normal end.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    /// Not a failure: the shard recorded its runs, and the study stops before using them.
    #[error("{0}")]
    ShardDone(String),
    /// Which shard this is could not be told.
    #[error(transparent)]
    Slice(#[from] SliceError),
    /// A file or folder that could not be read, written or made.
    #[error(transparent)]
    File(#[from] FileError),
    /// The running executable cannot be found.
    #[error("the study executable: {0}")]
    Executable(#[source] std::io::Error),
    /// A manifest that cannot be read.
    #[error("{}: not a shard manifest: {why}", path.display())]
    Manifest {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// An unreadable line in a run log.
    #[error("{}:{line}: not a run record: {why}", path.display())]
    LogLine {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// Why.
        why: String,
    },
    /// A record that cannot be encoded or decoded.
    #[error("{}: the run {stage} #{index}: {why}", path.display())]
    Record {
        /// The log.
        path: PathBuf,
        /// The stage.
        stage: String,
        /// The run's index in it.
        index: usize,
        /// Why.
        why: String,
    },
    /// A shard folder that holds another run's shard.
    #[error(
        "{}: holds shard {slice} of another run ({field}: {here} there, {now} now); remove the folder or give another --out",
        dir.display()
    )]
    Foreign {
        /// The folder.
        dir: PathBuf,
        /// Its slice.
        slice: Slice,
        /// The first field that differs.
        field: &'static str,
        /// Its value in the folder.
        here: String,
        /// Its value now.
        now: String,
    },
    /// A recorded run whose item is not the study's.
    #[error(
        "{}: the run {stage} #{index} was recorded for another item than this study's (key {recorded}, expected {expected}): the study's runs changed; rerun the shard in a fresh --out",
        path.display()
    )]
    KeyMismatch {
        /// The log.
        path: PathBuf,
        /// The stage.
        stage: String,
        /// The run's index in it.
        index: usize,
        /// The key in the log.
        recorded: String,
        /// The item's key.
        expected: String,
    },
    /// A stage name used twice by one study.
    #[error("the study names two stages '{0}' (a study's stage names must differ)")]
    RepeatedStage(String),
    /// A stage's results asked for before [`Runs::gather`], or on a shard.
    #[error("the results of stage '{0}' were used before the study gathered its runs")]
    NotGathered(String),
    /// A lock poisoned by a panicking run.
    #[error("a run panicked while recording its result")]
    Poisoned,
    /// Merge: no shard in the folders given.
    #[error("{}: no shard (no {} here or in {}/*/)", .0.display(), manifest::MANIFEST_FILE, SHARDS_DIR)]
    NoShards(PathBuf),
    /// Merge: a shard of another study, options or commit than the first's.
    #[error(
        "{}: a shard of another run than {} ({field}: {here} there, {first} in the first)",
        path.display(), first_path.display()
    )]
    Mixed {
        /// The odd shard's manifest.
        path: PathBuf,
        /// The first shard's manifest.
        first_path: PathBuf,
        /// The field that differs.
        field: &'static str,
        /// Its value in the odd shard.
        here: String,
        /// Its value in the first.
        first: String,
    },
    /// Merge: two folders hold the same shard.
    #[error("shard {slice} is given twice: {} and {}", a.display(), b.display())]
    Duplicate {
        /// The shard.
        slice: Slice,
        /// One folder.
        a: PathBuf,
        /// The other.
        b: PathBuf,
    },
    /// Merge: shards missing.
    #[error(
        "{} of {count} shards missing: {} (looked in {})",
        missing.len(),
        missing.iter().map(|i| format!("{i}-of-{count}")).collect::<Vec<_>>().join(", "),
        looked.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    Missing {
        /// The count.
        count: usize,
        /// The missing indices.
        missing: Vec<usize>,
        /// The folders searched.
        looked: Vec<PathBuf>,
    },
    /// Merge: a shard whose runs are not all recorded.
    #[error(
        "{}: shard {slice} is not complete ({recorded} runs recorded): run it again with the same arguments to finish it",
        dir.display()
    )]
    Unfinished {
        /// Its folder.
        dir: PathBuf,
        /// The shard.
        slice: Slice,
        /// Its runs so far.
        recorded: usize,
    },
    /// Merge: a run missing from the log of the shard that owns it.
    #[error("{}: the run {stage} #{index} is missing from this shard's log", path.display())]
    RunMissing {
        /// The owner's log.
        path: PathBuf,
        /// The stage.
        stage: String,
        /// The run's index in it.
        index: usize,
    },
    /// Merge: a log holding runs its shard does not own, or none of the study's.
    #[error("{}: holds {count} run(s) that are not this shard's part of the study (first: {first})", path.display())]
    Stray {
        /// The log.
        path: PathBuf,
        /// How many.
        count: usize,
        /// The first one, `stage #index`.
        first: String,
    },
    /// Merge: the study's list of runs does not hash as the shards' did.
    #[error(
        "{}: the shards ran another list of runs ({recorded} runs, hash {recorded_hash}) than this merge enumerates ({now} runs, hash {now_hash})",
        path.display()
    )]
    GridChanged {
        /// A shard's manifest.
        path: PathBuf,
        /// Its count.
        recorded: usize,
        /// Its hash.
        recorded_hash: String,
        /// The merge's count.
        now: usize,
        /// The merge's hash.
        now_hash: String,
    },
}

message_from!(ShardError);

/// The results of one stage, in the items' order ([`Stage::into_vec`] after
/// [`Runs::gather`]).
#[derive(Debug)]
pub struct Stage<R> {
    name: String,
    values: Option<Vec<R>>,
}

impl<R> Stage<R> {
    /// Every result, in the items' order; an error on a shard (whose study ends at
    /// `gather`).
    pub fn into_vec(self) -> Result<Vec<R>, ShardError> {
        self.values.ok_or(ShardError::NotGathered(self.name))
    }
}

/// A shard being run.
#[derive(Debug)]
struct ShardRun {
    dir: PathBuf,
    manifest: Mutex<Manifest>,
    log: run_log::RunLog,
    log_path: PathBuf,
    earlier: run_log::Recorded,
    recorded: AtomicUsize,
    reused: AtomicUsize,
}

/// The runs' numbering so far, and their hash.
#[derive(Debug, Default)]
struct Numbering {
    next: usize,
    stages: HashSet<String>,
    grid: Sha256,
}

/// How the runs are run.
#[derive(Debug)]
enum Mode {
    Whole,
    Shard(Box<ShardRun>),
    Merge(merge::Shards),
}

/// Where a study hands its runs over (see the [module documentation](self)).
#[derive(Debug)]
pub struct Runs {
    mode: Mode,
    numbering: Mutex<Numbering>,
    done: Mutex<Option<String>>,
}

impl Default for Runs {
    fn default() -> Self {
        Self::whole()
    }
}

/// The key of an item: the SHA-256 of its `Debug` text (first 16 bytes, hex).
fn key_of<T: fmt::Debug>(item: &T) -> String {
    manifest::hex(&Sha256::digest(format!("{item:?}").as_bytes())[..16])
}

impl Runs {
    /// Every run, here.
    pub fn whole() -> Self {
        Self {
            mode: Mode::Whole,
            numbering: Mutex::new(Numbering::default()),
            done: Mutex::new(None),
        }
    }

    /// The shard that `manifest` describes ([`Manifest::new`]: its study, command line,
    /// options, slice and `--out`), writing into `out/shards/I-of-N/`; resumes the runs an
    /// earlier attempt recorded there.
    pub fn shard(mut manifest: Manifest) -> Result<Self, ShardError> {
        let slice = manifest.slice;
        let dir = manifest.out.join(SHARDS_DIR).join(slice.folder_name());
        std::fs::create_dir_all(&dir).map_err(|e| FileError::new(FileOp::Creating, &dir, e))?;
        let log_path = dir.join(run_log::RUN_LOG_FILE);
        let mut earlier = run_log::Recorded::new();
        if dir.join(manifest::MANIFEST_FILE).exists() {
            let old = Manifest::read(&dir)?;
            if let Some((field, here, now)) = old.differs(&manifest) {
                return Err(ShardError::Foreign {
                    dir,
                    slice,
                    field,
                    here,
                    now,
                });
            }
            if old.slice != slice {
                return Err(ShardError::Foreign {
                    dir,
                    slice: old.slice,
                    field: "shard",
                    here: old.slice.to_string(),
                    now: slice.to_string(),
                });
            }
            earlier = run_log::read(&log_path)?.0;
        } else if log_path.exists() {
            return Err(ShardError::Manifest {
                path: dir.join(manifest::MANIFEST_FILE),
                why: format!("missing beside the run log {}", log_path.display()),
            });
        }
        manifest.runs_recorded = earlier.len();
        manifest.write(&dir)?;
        let log = run_log::RunLog::open(&log_path)?;
        Ok(Self {
            mode: Mode::Shard(Box::new(ShardRun {
                dir,
                manifest: Mutex::new(manifest),
                log,
                log_path,
                recorded: AtomicUsize::new(earlier.len()),
                earlier,
                reused: AtomicUsize::new(0),
            })),
            numbering: Mutex::new(Numbering::default()),
            done: Mutex::new(None),
        })
    }

    /// Reads every run from the checked `shards` ([`merge::Shards::find`]).
    pub fn merge(shards: merge::Shards) -> Self {
        Self {
            mode: Mode::Merge(shards),
            numbering: Mutex::new(Numbering::default()),
            done: Mutex::new(None),
        }
    }

    /// The slice, when this is a shard.
    pub fn slice(&self) -> Option<Slice> {
        match &self.mode {
            Mode::Shard(s) => s.manifest.lock().ok().map(|m| m.slice),
            _ => None,
        }
    }

    /// When this shard ended at [`Runs::gather`]: what it did, in one line.
    pub fn shard_done(&self) -> Option<String> {
        self.done.lock().ok().and_then(|d| d.clone())
    }

    /// Replaces the line [`Runs::shard_done`] gives, once the shard has ended (`study all`
    /// says what its shard did in its own words).
    pub fn describe_done(&self, line: String) {
        if let Ok(mut d) = self.done.lock()
            && d.is_some()
        {
            *d = Some(line);
        }
    }

    /// Numbers the stage `name`'s `items`: its first run number, and each item's key.
    fn number<T: fmt::Debug>(
        &self,
        name: &str,
        items: &[T],
    ) -> Result<(usize, Vec<String>), ShardError> {
        let mut n = self.numbering.lock().map_err(|_| ShardError::Poisoned)?;
        if !n.stages.insert(name.to_string()) {
            return Err(ShardError::RepeatedStage(name.to_string()));
        }
        let g0 = n.next;
        n.next += items.len();
        if matches!(self.mode, Mode::Whole) {
            return Ok((g0, Vec::new()));
        }
        let keys: Vec<String> = items.iter().map(key_of).collect();
        n.grid
            .update(format!("{name}\n{}\n", items.len()).as_bytes());
        for k in &keys {
            n.grid.update(k.as_bytes());
            n.grid.update(b"\n");
        }
        Ok((g0, keys))
    }

    /// Runs `f` on each of the stage `name`'s `items` (in parallel), as the mode says:
    /// all of them here, the shard's slice recorded in its log, or none (read from the
    /// shards). The results are [`Stage::into_vec`]'s after [`Runs::gather`].
    pub fn map<T, R, F>(&self, name: &str, items: &[T], f: F) -> Result<Stage<R>, ShardError>
    where
        T: Sync + fmt::Debug,
        R: Send + Serialize + DeserializeOwned,
        F: Fn(&T) -> R + Sync + Send,
    {
        let (g0, keys) = self.number(name, items)?;
        let values = match &self.mode {
            Mode::Whole => Some(items.par_iter().map(f).collect()),
            Mode::Shard(s) => {
                let slice = s.manifest.lock().map_err(|_| ShardError::Poisoned)?.slice;
                let owned: Vec<usize> = (0..items.len()).filter(|i| slice.owns(g0 + i)).collect();
                owned.par_iter().try_for_each(|&i| {
                    if let Some(line) = s.earlier.get(&(name.to_string(), i)) {
                        if line.key != keys[i] {
                            return Err(ShardError::KeyMismatch {
                                path: s.log_path.clone(),
                                stage: name.to_string(),
                                index: i,
                                recorded: line.key.clone(),
                                expected: keys[i].clone(),
                            });
                        }
                        s.reused.fetch_add(1, Ordering::Relaxed);
                        return Ok(());
                    }
                    let r = f(&items[i]);
                    let bytes = postcard::to_stdvec(&r).map_err(|e| ShardError::Record {
                        path: s.log_path.clone(),
                        stage: name.to_string(),
                        index: i,
                        why: e.to_string(),
                    })?;
                    s.log.append(name, i, &keys[i], &bytes)?;
                    s.recorded.fetch_add(1, Ordering::Relaxed);
                    Ok(())
                })?;
                None
            }
            Mode::Merge(shards) => Some(
                (0..items.len())
                    .into_par_iter()
                    .map(|i| shards.take(name, i, g0 + i, &keys[i]))
                    .collect::<Result<Vec<R>, ShardError>>()?,
            ),
        };
        Ok(Stage {
            name: name.to_string(),
            values,
        })
    }

    /// The end of the study's sharded stages: on a shard, marks its manifest complete and
    /// ends the study with [`ShardError::ShardDone`]; in a merge, checks that the study's
    /// list of runs is the shards' and that every recorded run was used.
    pub fn gather(&self) -> Result<(), ShardError> {
        let (total, hash) = {
            let n = self.numbering.lock().map_err(|_| ShardError::Poisoned)?;
            (n.next, manifest::hex(&n.grid.clone().finalize()))
        };
        match &self.mode {
            Mode::Whole => Ok(()),
            Mode::Merge(shards) => shards.finish(total, &hash),
            Mode::Shard(s) => {
                let mut m = s.manifest.lock().map_err(|_| ShardError::Poisoned)?;
                m.grid_hash = Some(hash);
                m.runs_total = Some(total);
                m.runs_recorded = s.recorded.load(Ordering::Relaxed);
                m.complete = true;
                m.write(&s.dir)?;
                let owned = (0..total).filter(|&g| m.slice.owns(g)).count();
                let line = format!(
                    "shard {} of study {}: {} of the study's {} runs recorded in {} ({} from an earlier attempt); when every shard is done: study merge {}",
                    m.slice,
                    m.study,
                    owned,
                    total,
                    s.dir.display(),
                    s.reused.load(Ordering::Relaxed),
                    m.out.display()
                );
                if let Ok(mut d) = self.done.lock() {
                    *d = Some(line.clone());
                }
                Err(ShardError::ShardDone(line))
            }
        }
    }
}
