//! The reporter's files: the four interval logs (`<name>.hlog`) written during the run,
//! and the four percentile distributions (`<name>.hgrm`) written at its end.
//!
//! - **Interval logs** go through a [`RecordFile`]: each interval is one line per file,
//!   serialized whole before it is buffered, so a log only ever holds whole lines. A
//!   failed write (full disk, I/O error) cuts the file back to its last whole line, is
//!   reported once on standard error, and the intervals that could not be written are
//!   counted ([`WriteHealth::records_lost`]); writing is tried again every
//!   [`RETRY_EVERY`]. The totals and the summary are not affected.
//! - **Percentile distributions** are written with [`ipc_types::files::write_atomic_with`]
//!   (temporary file, fsync, rename): a `.hgrm` file is complete or absent. A failure is
//!   reported on standard error and listed like the logs' failures, with
//!   `records_lost = 1` (the file).

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use hdrhistogram::serialization::V2DeflateSerializer;
use hdrhistogram::serialization::interval_log::{IntervalLogWriterBuilder, Tag};

use super::histograms::{HistogramKind, LoopHistograms};
use super::report::{TICKS_PER_HALF_DISTANCE, write_percentile_distribution};
use crate::logging::{RETRY_EVERY, RecordFile, RecordTarget, WriteHealth};

/// Buffered interval lines are written when they reach this many bytes; the reporter
/// also flushes after every poll that drained something.
const BUFFER_BYTES: usize = 1 << 14;

/// What an interval log writes into.
pub(super) type LogTarget = Box<dyn RecordTarget + Send>;

/// The output files of a reporter with an output folder.
pub(super) struct IntervalLogs {
    dir: PathBuf,
    files: [RecordFile<LogTarget>; 4],
    serializer: V2DeflateSerializer,
    /// One serialized interval line.
    line: Vec<u8>,
}

fn to_io<E: std::fmt::Debug>(e: E) -> io::Error {
    io::Error::other(format!("{e:?}"))
}

/// The path of the interval log of `kind` in `dir`.
fn hlog_path(dir: &Path, kind: HistogramKind) -> PathBuf {
    dir.join(format!("{}.hlog", kind.name()))
}

impl IntervalLogs {
    /// Creates `dir` and the four interval logs with their headers. Errors name the file
    /// or folder.
    pub(super) fn open(dir: &Path, anchor_wall: SystemTime) -> io::Result<Self> {
        std::fs::create_dir_all(dir)
            .map_err(|e| io::Error::new(e.kind(), format!("creating {}: {e}", dir.display())))?;
        let open = |kind: HistogramKind| -> io::Result<LogTarget> {
            let path = hlog_path(dir, kind);
            let file = File::create(&path).map_err(|e| {
                io::Error::new(e.kind(), format!("creating {}: {e}", path.display()))
            })?;
            Ok(Box::new(file))
        };
        let targets = [
            open(HistogramKind::Wakeup)?,
            open(HistogramKind::Compute)?,
            open(HistogramKind::Response)?,
            open(HistogramKind::Jitter)?,
        ];
        Self::with_targets(dir, anchor_wall, targets, RETRY_EVERY)
    }

    /// Like [`open`](Self::open), writing into the given targets (in
    /// [`HistogramKind::ALL`] order) instead of files in `dir`; `dir` is still where the
    /// `.hgrm` files go.
    pub(super) fn with_targets(
        dir: &Path,
        anchor_wall: SystemTime,
        targets: [LogTarget; 4],
        retry_every: Duration,
    ) -> io::Result<Self> {
        let mut targets = targets.into_iter();
        let files = HistogramKind::ALL.map(|kind| {
            let target = targets.next().expect("one target per kind");
            RecordFile::new(
                target,
                hlog_path(dir, kind).display().to_string(),
                BUFFER_BYTES,
                retry_every,
            )
        });
        let mut logs = Self {
            dir: dir.to_path_buf(),
            files,
            serializer: V2DeflateSerializer::new(),
            line: Vec::with_capacity(4096),
        };
        for kind in HistogramKind::ALL {
            let mut header = Vec::new();
            IntervalLogWriterBuilder::new()
                .add_comment(&format!(
                    "service telemetry: {} latency, values in ns, tag={}",
                    kind.name(),
                    kind.name()
                ))
                .add_comment("[Histogram log format version 1.3]")
                .with_start_time(anchor_wall)
                .with_base_time(anchor_wall)
                .begin_log_with(&mut header, &mut logs.serializer)?;
            header.extend_from_slice(
                b"\"StartTimestamp\",\"Interval_Length\",\"Interval_Max\",\"Interval_Compressed_Histogram\"\n",
            );
            logs.files[kind.index()].write_preamble(&header)?;
        }
        Ok(logs)
    }

    /// The output folder.
    pub(super) fn dir(&self) -> &Path {
        &self.dir
    }

    /// Appends one interval (`start` relative to the logs' start time, `length`) of each
    /// histogram of `b` to its log. Write failures are handled by the files (see the
    /// [module documentation](self)); the only error is a histogram that cannot be
    /// serialized (it is then counted as lost, too).
    pub(super) fn write_interval(
        &mut self,
        b: &LoopHistograms,
        start: Duration,
        length: Duration,
    ) -> io::Result<()> {
        let mut result = Ok(());
        for kind in HistogramKind::ALL {
            let file = &mut self.files[kind.index()];
            if !file.accepting() {
                file.lose(1);
                continue;
            }
            self.line.clear();
            let serialized = IntervalLogWriterBuilder::new()
                .begin_log_with(&mut self.line, &mut self.serializer)
                .map_err(to_io)
                .and_then(|mut w| {
                    w.write_histogram(b.histogram(kind), start, length, Tag::new(kind.name()))
                        .map_err(to_io)
                });
            match serialized {
                Ok(()) => file.push(&self.line),
                Err(e) => {
                    file.lose(1);
                    if result.is_ok() {
                        result = Err(io::Error::new(
                            e.kind(),
                            format!("serializing an interval for {}: {e}", file.name()),
                        ));
                    }
                }
            }
        }
        result
    }

    /// Writes the buffered lines of every log to its file.
    pub(super) fn flush(&mut self) {
        for f in &mut self.files {
            f.flush();
        }
    }

    /// The files that have failed so far.
    pub(super) fn failures(&self) -> Vec<WriteHealth> {
        self.files
            .iter()
            .map(|f| f.health())
            .filter(|h| h.failed())
            .cloned()
            .collect()
    }

    /// Ends the interval logs (last write, fsync) and writes the percentile distribution
    /// of each histogram of `totals` (values in µs) atomically. Returns every file that
    /// failed; never stops half-way.
    pub(super) fn finish(self, totals: &LoopHistograms) -> Vec<WriteHealth> {
        let mut failed: Vec<WriteHealth> = self
            .files
            .into_iter()
            .map(RecordFile::finish)
            .filter(WriteHealth::failed)
            .collect();
        for kind in HistogramKind::ALL {
            let path = self.dir.join(format!("{}.hgrm", kind.name()));
            let written = ipc_types::files::write_atomic_with(&path, |w| {
                let mut w = w;
                write_percentile_distribution(
                    totals.histogram(kind),
                    &mut w,
                    TICKS_PER_HALF_DISTANCE,
                    1_000.0,
                )
            });
            if let Err(e) = written {
                eprintln!("[service] {e}; the file was not written");
                failed.push(WriteHealth {
                    records_lost: 1,
                    failures: 1,
                    first_error: Some(e.to_string()),
                    ..WriteHealth::new(path.display().to_string())
                });
            }
        }
        failed
    }
}
