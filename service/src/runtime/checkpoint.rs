//! Checkpoints: what the controller learned, kept across a service restart.
//!
//! A checkpoint is `checkpoint.json` in the run folder: the controller's learned blocks
//! ([`control::learned`]: for RCAC `θ_k` and the RLS covariance of (2.13)–(2.14), for
//! PCAC the identified model's `θ` and `P` of (2.30)–(2.32)), the sample and plant session
//! they were taken at, the rig, the controller kind and a fingerprint of the
//! `[controller]` table. The real-time loop copies the blocks every
//! `service.checkpoint-every` seconds of samples through a [`CheckpointSlot`] (a `memcpy`,
//! no allocation); the supervising thread writes the file atomically
//! ([`ipc_types::files::write_atomic`]), so a killed service leaves the last whole
//! checkpoint. At the end of a run the final state is written the same way.
//!
//! `service run --warm-start <checkpoint.json>` (and `rig launch --warm-start`) builds the
//! controller from the scenario and then takes the checkpoint's blocks
//! ([`Controller::restore_learned`]), which are checked first: the rig and the controller
//! kind must match, the block names and lengths must be the ones this configuration has,
//! every value finite and a covariance positive definite within its guard. Anything else is
//! refused before the loop starts, naming the file and the block. A checkpoint of a
//! `[controller]` table that differs in a value that keeps the shapes (a forgetting
//! setting, a weight) is taken, with a warning in the run report. The data history
//! (regressor, filters) is not in a checkpoint: the new run fills it from its own samples,
//! as after a new plant session.

use super::checkpoint_slot::{CheckpointMark, CheckpointSlot};
use crate::config::ServiceConfig;
use control::Controller;
use control::learned::Learned;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The `format` of the files this version writes and reads.
pub const FORMAT: &str = "adaptive-rig checkpoint 1";

/// One named block of learned values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Block {
    /// The controller's name for it (`theta`, `Q`, …).
    pub name: String,
    /// Its values.
    pub values: Vec<f64>,
}

/// The contents of `checkpoint.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// [`FORMAT`].
    pub format: String,
    /// The rig it was taken on.
    pub rig: String,
    /// The controller kind (`rcac`, `pcac`).
    pub controller: String,
    /// Fingerprint of the `[controller]` table ([`controller_fingerprint`]).
    pub controller_fingerprint: String,
    /// Sequence number of the last sample the controller had taken in.
    pub seq: u64,
    /// Plant sessions begun by then in that run.
    pub plant_session: u64,
    /// Wall-clock time it was taken at (Unix seconds).
    pub written_unix_s: f64,
    /// The learned blocks, in the controller's order.
    pub blocks: Vec<Block>,
}

/// A 64-bit FNV-1a hash of the `[controller]` table as parsed, in hex: equal tables give
/// equal fingerprints within one build of the service.
pub fn controller_fingerprint(cfg: &ServiceConfig) -> String {
    let text = format!("{:?}", cfg.controller);
    let hash = text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{hash:016x}")
}

impl Checkpoint {
    /// A checkpoint of `blocks` taken at `mark` for the run configured by `cfg`.
    pub fn new(
        cfg: &ServiceConfig,
        kind: &str,
        mark: CheckpointMark,
        blocks: Vec<(String, Vec<f64>)>,
    ) -> Self {
        Self {
            format: FORMAT.into(),
            rig: cfg.rig.clone(),
            controller: kind.into(),
            controller_fingerprint: controller_fingerprint(cfg),
            seq: mark.seq,
            plant_session: mark.plant_session,
            written_unix_s: std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64()),
            blocks: blocks
                .into_iter()
                .map(|(name, values)| Block { name, values })
                .collect(),
        }
    }

    /// Writes the checkpoint to `path` atomically (the old file or the whole new one).
    ///
    /// # Errors
    ///
    /// The write's error, naming the file.
    pub fn write(&self, path: &Path) -> Result<(), String> {
        let text = serde_json::to_string(self).map_err(|e| format!("{}: {e}", path.display()))?;
        ipc_types::files::write_atomic(path, text.as_bytes()).map_err(|e| e.to_string())
    }

    /// Reads a checkpoint file.
    ///
    /// # Errors
    ///
    /// An unreadable file, JSON that is not a checkpoint, or another format, naming the file.
    pub fn read(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let c: Checkpoint = serde_json::from_str(&text)
            .map_err(|e| format!("{}: not a checkpoint: {e}", path.display()))?;
        if c.format != FORMAT {
            return Err(format!(
                "{}: format '{}', this service reads '{FORMAT}'",
                path.display(),
                c.format
            ));
        }
        Ok(c)
    }
}

/// What a warm start took, for the run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WarmStart {
    /// The checkpoint file.
    pub path: String,
    /// The sample it was taken at.
    pub seq: u64,
    /// Its `[controller]` table had the fingerprint of this run's.
    pub same_controller_table: bool,
}

/// Takes the checkpoint at `path` into `controller`, just built from `cfg` (see the
/// module docs for what is checked).
///
/// # Errors
///
/// What does not match or is not acceptable, naming the file and the block; the controller
/// is then in its initial state.
pub fn warm_start(
    path: &Path,
    cfg: &ServiceConfig,
    controller: &mut dyn Controller,
) -> Result<WarmStart, String> {
    let c = Checkpoint::read(path)?;
    let at = |m: String| format!("{}: {m}", path.display());
    if c.rig != cfg.rig {
        return Err(at(format!(
            "taken on rig '{}', this run is rig '{}'",
            c.rig, cfg.rig
        )));
    }
    if c.controller != controller.kind() {
        return Err(at(format!(
            "taken with a {} controller, this run has a {} controller",
            c.controller,
            controller.kind()
        )));
    }
    let layout = CheckpointSlot::new(controller).layout().to_vec();
    let saved: Vec<(&str, usize)> = c
        .blocks
        .iter()
        .map(|b| (b.name.as_str(), b.values.len()))
        .collect();
    if saved != layout {
        let describe = |l: &[(&str, usize)]| {
            l.iter()
                .map(|(n, len)| format!("{n}[{len}]"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        return Err(at(format!(
            "its blocks are {}, this configuration's are {}: the controller's dimensions \
             differ",
            describe(&saved),
            describe(&layout)
        )));
    }
    let blocks: Vec<(String, Vec<f64>)> =
        c.blocks.into_iter().map(|b| (b.name, b.values)).collect();
    controller
        .restore_learned(&Learned::new(&blocks))
        .map_err(at)?;
    Ok(WarmStart {
        path: path.display().to_string(),
        seq: c.seq,
        same_controller_table: c.controller_fingerprint == controller_fingerprint(cfg),
    })
}
