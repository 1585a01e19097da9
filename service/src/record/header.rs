//! The header of a record file: magic, format version, and a JSON description of the run
//! (channel counts, plan length, rig, controller, the configuration it was built from).

use super::layout::RecordLayout;
use ipc_types::ChannelCounts;
use serde::{Deserialize, Serialize};

/// The first 8 bytes of a record file.
pub const MAGIC: &[u8; 8] = b"ARRECORD";

/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 2;

/// What a record says about its run: enough to rebuild the loop that wrote it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordHeader {
    /// The service version that wrote it.
    pub service_version: String,
    /// Rig name.
    pub rig: String,
    /// Controller kind (`lti`, `rcac`, …).
    pub controller: String,
    /// Fingerprint of the `[controller]` table as parsed
    /// ([`controller_fingerprint`](crate::runtime::checkpoint::controller_fingerprint)).
    pub controller_fingerprint: String,
    /// Fingerprint of everything in the configuration that decides the loop's outputs
    /// ([`config_fingerprint`]).
    pub config_fingerprint: String,
    /// Recorded channels of `y`.
    pub n_y: u16,
    /// Recorded channels of `z`.
    pub n_z: u16,
    /// Recorded channels of `r`.
    pub n_r: u16,
    /// Recorded channels of `u`.
    pub n_u: u16,
    /// Plan rows recorded per actuation.
    pub plan_length: usize,
    /// The timing the loop ran (`compute-first`, `answer-first`, `send-ahead`).
    pub timing: String,
    /// Sample period, ns.
    pub sample_period_ns: u64,
    /// The configuration's origin (file names) as errors gave it.
    pub config_origin: String,
    /// The folder relative file names of the configuration were resolved from (absolute).
    pub config_base_dir: String,
    /// The configuration text the loop was built from (after a `--controller` merge).
    pub config_text: String,
    /// The warm-start checkpoint, copied into the run folder under this name, if any.
    pub warm_start: Option<String>,
}

impl RecordHeader {
    /// The entry layout of the record.
    pub fn layout(&self) -> RecordLayout {
        RecordLayout::new(
            ChannelCounts {
                n_y: self.n_y,
                n_z: self.n_z,
                n_r: self.n_r,
                n_u: self.n_u,
            },
            self.plan_length,
        )
    }

    /// The header's bytes: magic, version, JSON length (`u32` LE), JSON.
    pub fn encode(&self) -> Vec<u8> {
        // A struct of strings and numbers always serializes.
        let json = serde_json::to_vec(self).unwrap_or_default();
        let mut out = Vec::with_capacity(16 + json.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(&json);
        out
    }
}

/// A 64-bit FNV-1a hash, in hex, of everything in `cfg` that decides what the loop
/// publishes: the controller, the channels, the period, the deadline and silence policy,
/// the measurement limits, the safe input, the open-loop phase and the timing. Equal
/// configurations give equal fingerprints within one build of the service; the file
/// names, the RT set-up, the logs and the reports do not count.
pub fn config_fingerprint(cfg: &crate::config::ServiceConfig) -> String {
    let text = format!(
        "{:?}|{:?}|{}|{:?}|{:?}|{:?}|{}|{:?}",
        cfg.controller,
        cfg.counts,
        cfg.sample_period_ns,
        cfg.policy,
        cfg.limits,
        cfg.safe_input,
        cfg.open_loop_cycles,
        cfg.answer,
    );
    let hash = text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    });
    format!("{hash:016x}")
}

impl RecordHeader {
    /// The header of a run of `cfg` whose loop runs `timing` with plans of `plan_length`,
    /// started from the checkpoint copied into the run folder as `warm_start`.
    pub fn for_run(
        cfg: &crate::config::ServiceConfig,
        controller_kind: &str,
        timing: ipc_types::Timing,
        plan_length: usize,
        warm_start: Option<String>,
    ) -> Self {
        let base = &cfg.source.base_dir;
        let base = if base.as_os_str().is_empty() {
            std::env::current_dir().unwrap_or_default()
        } else {
            std::fs::canonicalize(base).unwrap_or_else(|_| base.clone())
        };
        Self {
            service_version: env!("CARGO_PKG_VERSION").to_string(),
            rig: cfg.rig.clone(),
            controller: controller_kind.to_string(),
            controller_fingerprint: crate::runtime::checkpoint::controller_fingerprint(cfg),
            config_fingerprint: config_fingerprint(cfg),
            n_y: cfg.counts.n_y,
            n_z: cfg.counts.n_z,
            n_r: cfg.counts.n_r,
            n_u: cfg.counts.n_u,
            plan_length,
            timing: timing.name().to_string(),
            sample_period_ns: cfg.sample_period_ns,
            config_origin: cfg.origin.clone(),
            config_base_dir: base.display().to_string(),
            config_text: cfg.source.text.clone(),
            warm_start,
        }
    }
}
