//! The non-RT end of the record queue: a thread that drains the byte ring, cuts it into
//! whole entries and writes them, and the end mark when the run ends, to `record.bin`
//! through a
//! [`RecordFile`](crate::logging::RecordFile) (whole entries only; a full disk is reported,
//! counted and retried, never waited on).

use super::entry::encode_marker;
use super::layout::{ENTRY_HEAD_BYTES, EntryKind, RecordLayout};
use super::recorder::Counters;
use crate::logging::{RETRY_EVERY, RecordFile, RecordTarget, WriteHealth};
use serde::Serialize;
use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// Sleep of the writer thread when the ring is empty.
const IDLE_SLEEP: Duration = Duration::from_millis(1);
/// While idle, flush buffered entries at most this often.
const IDLE_FLUSH_EVERY: Duration = Duration::from_millis(200);
/// Buffered entries are written when they reach this many bytes.
const BUFFER_BYTES: usize = 1 << 18;

/// The non-RT end of a record queue, not yet writing; see [`RecordWriter::spawn`].
pub struct RecordWriter {
    pub(super) rx: rtrb::Consumer<u8>,
    pub(super) layout: RecordLayout,
    pub(super) header: Vec<u8>,
    pub(super) counters: Arc<Counters>,
}

/// What a finished record writer did, for the run report.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RecordStats {
    /// The file.
    pub path: String,
    /// Entries the loop offered.
    pub entries: u64,
    /// Entries in the file, complete (the end mark not counted).
    pub written: u64,
    /// Entries dropped because the queue was full.
    pub dropped: u64,
    /// Entries that could not be written (full disk, I/O error).
    pub lost_to_disk: u64,
    /// The first write failure, naming the file.
    pub first_error: Option<String>,
    /// Every entry the loop offered is in the file: a replay can compare the whole run.
    pub complete: bool,
}

/// A running record writer; [`RecordWriterHandle::finish`] stops it.
pub struct RecordWriterHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<WriteHealth>>,
    counters: Arc<Counters>,
    path: PathBuf,
}

impl RecordWriter {
    /// Creates (truncates) the file at `path`, writes the header, and spawns the
    /// `record-writer` thread. Errors creating the file or writing the header name it.
    pub fn spawn(self, path: &Path) -> io::Result<RecordWriterHandle> {
        let file = RecordFile::<File>::create(path, BUFFER_BYTES, RETRY_EVERY)?;
        self.spawn_into(file, path)
    }

    /// [`RecordWriter::spawn`] into any [`RecordTarget`].
    pub fn spawn_into<T: RecordTarget + Send + 'static>(
        self,
        mut file: RecordFile<T>,
        path: &Path,
    ) -> io::Result<RecordWriterHandle> {
        file.write_preamble(&self.header)?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let mut rx = self.rx;
        let layout = self.layout;
        let counters = Arc::clone(&self.counters);
        let thread = thread::Builder::new()
            .name("record-writer".to_owned())
            .spawn(move || {
                crate::logging::drop_realtime_priority();
                let mut pending = Vec::new();
                let mut last_flush = Instant::now();
                loop {
                    let stopping = thread_stop.load(Ordering::Acquire);
                    let n = drain(&mut rx, &mut pending, &layout, &mut file);
                    if stopping {
                        // The loop has stopped: the end mark carries the entries it offered.
                        let mut end = [0u8; ENTRY_HEAD_BYTES];
                        let offered = counters.offered.load(Ordering::Relaxed);
                        let n = encode_marker(EntryKind::End, offered, None, &mut end);
                        file.push(&end[..n]);
                        break;
                    }
                    if n == 0 {
                        if last_flush.elapsed() >= IDLE_FLUSH_EVERY {
                            file.flush();
                            last_flush = Instant::now();
                        }
                        thread::sleep(IDLE_SLEEP);
                    }
                }
                file.finish()
            })
            .map_err(|e| {
                io::Error::new(
                    e.kind(),
                    format!("starting the writer thread of {}: {e}", path.display()),
                )
            })?;
        Ok(RecordWriterHandle {
            stop,
            thread: Some(thread),
            counters: self.counters,
            path: path.to_path_buf(),
        })
    }
}

/// Moves everything in the ring to `pending`, then every whole entry of `pending` to the
/// file; returns the bytes taken from the ring.
fn drain<T: RecordTarget>(
    rx: &mut rtrb::Consumer<u8>,
    pending: &mut Vec<u8>,
    layout: &RecordLayout,
    file: &mut RecordFile<T>,
) -> usize {
    let n = rx.slots();
    if n > 0
        && let Ok(chunk) = rx.read_chunk(n)
    {
        let (a, b) = chunk.as_slices();
        pending.extend_from_slice(a);
        pending.extend_from_slice(b);
        chunk.commit_all();
    }
    let mut at = 0;
    while at < pending.len() {
        let Some(kind) = EntryKind::from_byte(pending[at]) else {
            // Cannot happen (the recorder writes whole entries of known kinds); the rest is
            // unreadable, so it is counted as lost rather than written.
            file.lose(1);
            at = pending.len();
            break;
        };
        let size = layout.entry_bytes(kind);
        if at + size > pending.len() {
            break;
        }
        file.push(&pending[at..at + size]);
        at += size;
    }
    pending.drain(..at);
    n
}

impl RecordWriterHandle {
    /// Stops the writer: everything offered before is written (or counted as lost), the
    /// file flushed and synced, the thread joined. The only error is a writer thread that
    /// panicked.
    pub fn finish(mut self) -> io::Result<RecordStats> {
        self.stop.store(true, Ordering::Release);
        let health = match self.thread.take() {
            Some(t) => t.join().map_err(|_| {
                io::Error::other(format!(
                    "the writer thread of {} panicked",
                    self.path.display()
                ))
            })?,
            None => WriteHealth::new(self.path.display().to_string()),
        };
        let entries = self.counters.offered.load(Ordering::Relaxed);
        let dropped = self.counters.dropped.load(Ordering::Relaxed);
        Ok(RecordStats {
            path: self.path.display().to_string(),
            entries,
            written: health.records_written.saturating_sub(1).min(entries),
            dropped,
            lost_to_disk: health.records_lost,
            complete: dropped == 0
                && health.records_lost == 0
                && health.intact
                && health.records_written == entries + 1,
            first_error: health.first_error,
        })
    }
}

impl Drop for RecordWriterHandle {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
