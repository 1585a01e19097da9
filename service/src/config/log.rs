//! `[log]`: the CSV signal log written off the real-time thread.
//!
//! ```toml
//! [log]
//! enabled = true                  # default true
//! decimation = 1                  # keep every N-th sample (0 is read as 1)
//! queue-capacity = 65536          # records in the lock-free queue out of the RT thread (≥ 16)
//! ```

use super::{ConfigError, ErrFn};
use serde::Deserialize;

/// Signal logging.
#[derive(Debug, Clone, PartialEq)]
pub struct LogConfig {
    /// Write the CSV signal log.
    pub enabled: bool,
    /// Keep every N-th sample.
    pub decimation: u32,
    /// Capacity of the lock-free queue out of the RT thread, in records.
    pub queue_capacity: usize,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawLog {
    enabled: Option<bool>,
    decimation: Option<u32>,
    queue_capacity: Option<usize>,
}

/// The table with its defaults filled in.
pub(super) fn parse(raw: RawLog, err: &ErrFn<'_>) -> Result<LogConfig, ConfigError> {
    let log = LogConfig {
        enabled: raw.enabled.unwrap_or(true),
        decimation: raw.decimation.unwrap_or(1).max(1),
        queue_capacity: raw.queue_capacity.unwrap_or(65536),
    };
    if log.queue_capacity < 16 {
        return Err(err("log.queue-capacity", "must be at least 16".into()));
    }
    Ok(log)
}
