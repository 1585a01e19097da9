//! # logging: signal logs out of the RT thread
//!
//! Each control cycle the RT thread may fill one fixed-size, `Copy` [`LogRecord`]
//! (sequence number, sample timestamp, status, flags, the signals `y`, `z`, `u` and up to
//! [`MAX_INTERNALS`] controller internals) and push it into a bounded lock-free queue.
//! A non-RT thread drains the queue into a CSV file.
//!
//! ## Design
//!
//! ```text
//!  RT thread                        non-RT thread ("log-writer")
//!  LogProducer::push ──► rtrb SPSC ring ──► LogWriter thread ──► RecordFile (CSV)
//!   decimation counter   (capacity fixed     drains, formats,
//!   full → drop + count   at channel())      sleeps ~1 ms when empty
//! ```
//!
//! - **Set-up allocates, the loop does not.** [`channel`] allocates the ring of
//!   `capacity` records and the shared counters; [`LogProducer::push`] is a decimation
//!   check, a wait-free `try-push` (a copy of the record into the ring) and a relaxed
//!   atomic store. It never allocates, locks, blocks, does I/O or panics.
//! - **Full queue: drop and count.** If the writer falls behind and the ring is full, the
//!   record is dropped and counted; the RT thread never waits. The counts live in an
//!   `Arc` of atomics created by [`channel`], readable from anywhere through
//!   [`LogCounters`] (the run report) and returned in [`LogStats`].
//! - **Decimation on the RT side.** With [`LogLayout::decimation`] `= N` only every N-th
//!   record offered is pushed (the first, the (N+1)-th, …): a counter decrement, no
//!   division, and skipped records never touch the queue.
//! - **Writer thread.** [`LogWriter::spawn`] creates the file and writes the header at
//!   once (so a bad path is reported at start-up), then a helper thread (with the default
//!   scheduling policy, even if spawned from an RT thread) drains the ring, formats rows
//!   and writes them in whole rows through a [`RecordFile`], sleeping about 1 ms
//!   whenever the ring is empty. [`LogWriterHandle::finish`] (called on SIGINT/SIGTERM and at the end of a
//!   run) raises a stop flag; the thread drains everything pushed before that, flushes
//!   and exits, and `finish` joins it.
//! - **Full disk, I/O errors: whole rows, reported, counted, never blocking.** Rows go
//!   through a [`RecordFile`]: they are buffered whole and written on row boundaries;
//!   when a write fails the file is cut back to its last complete row, the failure is
//!   reported once on standard error (`[service] writing <path>: <OS error>; …`), and the
//!   writer keeps draining the queue, counting the rows it cannot write
//!   ([`LogStats::lost_to_disk`], distinct from the queue's [`LogStats::dropped`]) and
//!   trying again every [`RETRY_EVERY`]; if a retry succeeds (space was freed) writing
//!   resumes. The RT thread never waits on any of this. [`LogWriterHandle::finish`]
//!   returns the failure in [`LogStats`] (`lost_to_disk`, `write_failures`,
//!   `first_error`, `intact`) instead of an error, so the run report can show it.
//! - **CSV format.** Header `seq,t_sample_ns,status,flags,y0,…,z0,…,u0,…,<internal
//!   names>` with only the channels in use ([`LogLayout`]). Floating-point values are
//!   written in Rust's shortest round-trip form (plain decimal, or exponent notation for
//!   very large and very small magnitudes), so parsing them back gives the same bits;
//!   non-finite values are written `NaN`, `inf`, `-inf`.
//!
//! ## Example
//!
//! ```
//! use service::logging::{self, LogLayout, LogRecord};
//!
//! let layout = LogLayout {
//!     n_y: 1,
//!     n_z: 1,
//!     n_u: 1,
//!     internal_names: vec!["theta0".into()],
//!     decimation: 1,
//! };
//! layout.validate().unwrap();
//! let (mut producer, writer) = logging::channel(4096, layout);
//! let path = std::env::temp_dir().join(format!("logging-doc-{}.csv", std::process::id()));
//! let handle = writer.spawn(path.clone()).unwrap();
//!
//! // RT thread, once per cycle:
//! let mut rec = LogRecord::ZERO;
//! for k in 0..100u64 {
//!     rec.seq = k;
//!     rec.y[0] = 0.1 * k as f64;
//!     producer.push(&rec);
//! }
//!
//! let stats = handle.finish().unwrap();
//! assert_eq!(stats.written + stats.dropped, 100);
//! let text = std::fs::read_to_string(&path).unwrap();
//! assert!(text.starts_with("seq,t_sample_ns,status,flags,y0,z0,u0,theta0\n"));
//! # std::fs::remove_file(&path).unwrap();
//! ```

mod record_file;
mod whole_rows;
mod writer;

#[cfg(test)]
mod disk_failure_tests;
#[cfg(test)]
pub(crate) mod full_disk;
#[cfg(test)]
mod tests;

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use ipc_types::{MAX_U, MAX_Y, MAX_Z};
use rtrb::{Consumer, Producer, RingBuffer};

pub use record_file::{RecordFile, RecordTarget, WriteHealth};
pub use whole_rows::whole_rows;
pub(crate) use writer::drop_realtime_priority;
pub use writer::{LogStats, LogWriter, LogWriterHandle, RETRY_EVERY};

/// Capacity of [`LogRecord::internals`]: controller internals (parameter estimates,
/// covariance trace, forgetting factor, …) logged per cycle.
pub const MAX_INTERNALS: usize = 16;

/// One cycle's log entry: fixed size and `Copy`, so pushing it is a plain copy.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct LogRecord {
    /// Sequence number `k` of the sample.
    pub seq: u64,
    /// Sample timestamp (monotonic ns, plant clock).
    pub t_sample_ns: u64,
    /// Loop status code of the cycle.
    pub status: u32,
    /// Event flags of the cycle (bit set defined by the runtime).
    pub flags: u32,
    /// Measurements `y_k`; the first [`LogLayout::n_y`] are logged.
    pub y: [f64; MAX_Y],
    /// Performance variables `z_k`; the first [`LogLayout::n_z`] are logged.
    pub z: [f64; MAX_Z],
    /// Actuation `u_k`; the first [`LogLayout::n_u`] are logged.
    pub u: [f64; MAX_U],
    /// Controller internals; the first `internal_names.len()` are logged.
    pub internals: [f64; MAX_INTERNALS],
}

impl LogRecord {
    /// A record with every field zero.
    pub const ZERO: LogRecord = LogRecord {
        seq: 0,
        t_sample_ns: 0,
        status: 0,
        flags: 0,
        y: [0.0; MAX_Y],
        z: [0.0; MAX_Z],
        u: [0.0; MAX_U],
        internals: [0.0; MAX_INTERNALS],
    };

    /// A record with every field zero (same as [`LogRecord::ZERO`]).
    pub const fn zeroed() -> Self {
        Self::ZERO
    }
}

impl Default for LogRecord {
    fn default() -> Self {
        Self::ZERO
    }
}

/// Which columns the log has and how often a record is kept.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LogLayout {
    /// Number of measurement channels logged (≤ `MAX_Y`).
    pub n_y: usize,
    /// Number of performance channels logged (≤ `MAX_Z`).
    pub n_z: usize,
    /// Number of actuation channels logged (≤ `MAX_U`).
    pub n_u: usize,
    /// Column names of the logged internals, in order (≤ [`MAX_INTERNALS`]).
    pub internal_names: Vec<String>,
    /// Keep every N-th record (1 = all; 0 is treated as 1).
    pub decimation: u32,
}

/// Why a [`LogLayout`] was rejected by [`LogLayout::validate`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LogLayoutError {
    /// More channels of one kind than a [`LogRecord`] holds.
    TooManyChannels {
        /// `"y"`, `"z"`, `"u"` or `"internals"`.
        kind: &'static str,
        /// Number requested.
        requested: usize,
        /// Capacity of the record.
        capacity: usize,
    },
    /// An internal's name is empty, contains a line break, or repeats another column
    /// name.
    BadInternalName {
        /// Position in `internal_names`.
        index: usize,
        /// The offending name.
        name: String,
    },
}

impl fmt::Display for LogLayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LogLayoutError::TooManyChannels {
                kind,
                requested,
                capacity,
            } => write!(
                f,
                "log layout asks for {requested} {kind} columns, a log record holds {capacity}"
            ),
            LogLayoutError::BadInternalName { index, name } => write!(
                f,
                "log layout internal #{index} has an unusable column name {name:?} \
                 (empty, contains a line break, or duplicates another column)"
            ),
        }
    }
}

impl std::error::Error for LogLayoutError {}

impl LogLayout {
    /// Checks the channel counts against the record's capacities and the internal names
    /// (non-empty, no line breaks, distinct from each other and from the fixed columns).
    /// Call it when reading the configuration; [`channel`] itself clamps out-of-range
    /// counts instead of failing.
    pub fn validate(&self) -> Result<(), LogLayoutError> {
        for (kind, requested, capacity) in [
            ("y", self.n_y, MAX_Y),
            ("z", self.n_z, MAX_Z),
            ("u", self.n_u, MAX_U),
            ("internals", self.internal_names.len(), MAX_INTERNALS),
        ] {
            if requested > capacity {
                return Err(LogLayoutError::TooManyChannels {
                    kind,
                    requested,
                    capacity,
                });
            }
        }
        let fixed = self.signal_column_names();
        for (index, name) in self.internal_names.iter().enumerate() {
            let bad = name.is_empty()
                || name.contains(['\n', '\r'])
                || fixed.iter().any(|f| f == name)
                || self.internal_names[..index].contains(name);
            if bad {
                return Err(LogLayoutError::BadInternalName {
                    index,
                    name: name.clone(),
                });
            }
        }
        Ok(())
    }

    /// The columns before the internals: `seq,t_sample_ns,status,flags,y0..,z0..,u0..`.
    fn signal_column_names(&self) -> Vec<String> {
        let mut names: Vec<String> = ["seq", "t_sample_ns", "status", "flags"]
            .iter()
            .map(|s| (*s).to_owned())
            .collect();
        names.extend((0..self.n_y).map(|i| format!("y{i}")));
        names.extend((0..self.n_z).map(|i| format!("z{i}")));
        names.extend((0..self.n_u).map(|i| format!("u{i}")));
        names
    }

    /// The layout with every count clamped to the record's capacities and decimation ≥ 1.
    fn clamped(mut self) -> Self {
        self.n_y = self.n_y.min(MAX_Y);
        self.n_z = self.n_z.min(MAX_Z);
        self.n_u = self.n_u.min(MAX_U);
        self.internal_names.truncate(MAX_INTERNALS);
        self.decimation = self.decimation.max(1);
        self
    }
}

/// Counters shared by the producer, the writer and whoever writes the run report.
#[derive(Debug, Default)]
struct Counters {
    pushed: AtomicU64,
    dropped: AtomicU64,
    decimated: AtomicU64,
    /// Written by the writer thread only.
    lost_to_disk: AtomicU64,
}

/// A cloneable read-only view of the log queue's counters, for the run report.
#[derive(Clone, Debug)]
pub struct LogCounters(Arc<Counters>);

impl LogCounters {
    /// Records pushed into the queue so far.
    pub fn pushed(&self) -> u64 {
        self.0.pushed.load(Ordering::Relaxed)
    }

    /// Records dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.0.dropped.load(Ordering::Relaxed)
    }

    /// Records skipped by decimation (not an error).
    pub fn decimated(&self) -> u64 {
        self.0.decimated.load(Ordering::Relaxed)
    }

    /// Records the writer could not write to the file so far (full disk, I/O error);
    /// updated after every drain of the queue.
    pub fn lost_to_disk(&self) -> u64 {
        self.0.lost_to_disk.load(Ordering::Relaxed)
    }
}

/// What [`LogProducer::push`] did with a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushOutcome {
    /// The record is in the queue.
    Pushed,
    /// The record was skipped by decimation.
    Decimated,
    /// The queue was full: the record was dropped and counted.
    Dropped,
}

/// Creates the RT-side producer and the writer of a signal log.
///
/// `capacity` is the number of records the queue holds (at least 1; each record is
/// about 470 bytes, so 8192 records ≈ 3.7 MiB ≈ 1 s at 8 kHz). Counts in `layout` beyond
/// the record's capacities are clamped (use [`LogLayout::validate`] to reject them
/// instead); a decimation of 0 is treated as 1. Allocates: call it before the RT thread
/// starts.
pub fn channel(capacity: usize, layout: LogLayout) -> (LogProducer, LogWriter) {
    let layout = layout.clamped();
    let (tx, rx): (Producer<LogRecord>, Consumer<LogRecord>) = RingBuffer::new(capacity.max(1));
    let counters = Arc::new(Counters::default());
    let producer = LogProducer {
        tx,
        decimation: layout.decimation,
        countdown: 0,
        pushed: 0,
        dropped: 0,
        decimated: 0,
        counters: Arc::clone(&counters),
    };
    let writer = LogWriter::new(rx, layout, counters);
    (producer, writer)
}

/// The RT thread's end of the log queue.
///
/// [`push`](Self::push) never allocates, locks, blocks, does I/O or panics.
pub struct LogProducer {
    tx: Producer<LogRecord>,
    decimation: u32,
    /// Records still to skip before the next one is kept.
    countdown: u32,
    pushed: u64,
    dropped: u64,
    decimated: u64,
    counters: Arc<Counters>,
}

impl LogProducer {
    /// Offers one record: skips it if decimation says so, otherwise tries to push a copy
    /// into the queue and, if the queue is full, drops it and counts the drop.
    #[inline]
    pub fn push(&mut self, rec: &LogRecord) -> PushOutcome {
        if self.countdown > 0 {
            self.countdown -= 1;
            self.decimated = self.decimated.wrapping_add(1);
            self.counters
                .decimated
                .store(self.decimated, Ordering::Relaxed);
            return PushOutcome::Decimated;
        }
        self.countdown = self.decimation.saturating_sub(1);
        match self.tx.push(*rec) {
            Ok(()) => {
                self.pushed = self.pushed.wrapping_add(1);
                self.counters.pushed.store(self.pushed, Ordering::Relaxed);
                PushOutcome::Pushed
            }
            Err(_) => {
                self.dropped = self.dropped.wrapping_add(1);
                self.counters.dropped.store(self.dropped, Ordering::Relaxed);
                PushOutcome::Dropped
            }
        }
    }

    /// Records dropped so far because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Records pushed into the queue so far.
    pub fn pushed(&self) -> u64 {
        self.pushed
    }

    /// Records skipped by decimation so far.
    pub fn decimated(&self) -> u64 {
        self.decimated
    }

    /// A view of the counters for the run report (clones an `Arc`: call it at set-up).
    pub fn counters(&self) -> LogCounters {
        LogCounters(Arc::clone(&self.counters))
    }
}
