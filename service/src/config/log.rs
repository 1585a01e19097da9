//! `[log]`: the CSV signal log written off the real-time thread.
//!
//! ```toml
//! [log]
//! enabled = true                  # default true
//! decimation = 1                  # keep every N-th sample (1 to 10⁶)
//! queue-capacity = 65536          # records in the lock-free queue out of the RT thread
//!                                 # (16 to 2¹⁹)
//! record = true                   # default true: record.bin, what the loop saw and sent,
//!                                 # for `service replay` (crate::record)
//! ```

use super::bounds::{MAX_LOG_DECIMATION, MAX_LOG_QUEUE_CAPACITY, MIN_LOG_QUEUE_CAPACITY};
use super::values::count;
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
    /// Write `record.bin`, every input and output of the loop at full precision, for
    /// `service replay` ([`crate::record`]); its queue holds `queue_capacity` samples.
    pub record: bool,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub(super) struct RawLog {
    enabled: Option<bool>,
    decimation: Option<u64>,
    queue_capacity: Option<u64>,
    record: Option<bool>,
}

/// The table with its defaults filled in, each count within its bound.
pub(super) fn parse(raw: RawLog, err: &ErrFn<'_>) -> Result<LogConfig, ConfigError> {
    let decimation = count(
        raw.decimation.unwrap_or(1),
        1,
        MAX_LOG_DECIMATION,
        "log.decimation",
        err,
    )?;
    let queue_capacity = count(
        raw.queue_capacity.unwrap_or(65536),
        MIN_LOG_QUEUE_CAPACITY,
        MAX_LOG_QUEUE_CAPACITY,
        "log.queue-capacity",
        err,
    )?;
    Ok(LogConfig {
        enabled: raw.enabled.unwrap_or(true),
        decimation: decimation as u32,
        queue_capacity: queue_capacity as usize,
        record: raw.record.unwrap_or(true),
    })
}
