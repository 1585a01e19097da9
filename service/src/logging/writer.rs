//! The non-RT end of the log queue: a thread that drains it into a CSV file.
//!
//! Rows go through a [`RecordFile`]: the file only ever holds whole rows, a failed write
//! (full disk, I/O error) is reported once on standard error and counted, and the thread
//! keeps draining the queue (dropping and counting rows while the file fails, retrying
//! every [`RETRY_EVERY`]), so the RT thread never notices.

use std::fs::File;
use std::io::{self, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use rtrb::Consumer;

use super::record_file::{RecordFile, RecordTarget, WriteHealth};
use super::{Counters, LogCounters, LogLayout, LogRecord};

/// Sleep of the writer thread when the queue is empty.
const IDLE_SLEEP: Duration = Duration::from_millis(1);
/// While idle, flush buffered rows to the file at most this often.
const IDLE_FLUSH_EVERY: Duration = Duration::from_millis(200);
/// Buffered rows are written when they reach this many bytes.
const BUFFER_BYTES: usize = 1 << 16;
/// After a failed write, rows are dropped (and counted) for this long, then tried again.
pub const RETRY_EVERY: Duration = Duration::from_secs(1);

/// The non-RT end of a log queue, not yet writing. Turn it into a running writer with
/// [`spawn`](Self::spawn).
pub struct LogWriter {
    rx: Consumer<LogRecord>,
    layout: LogLayout,
    counters: Arc<Counters>,
}

/// What a finished writer did.
///
/// Rows can be missing from the file for two distinct reasons: the queue was full
/// ([`dropped`](Self::dropped), the writer fell behind) or writing the file failed
/// ([`lost_to_disk`](Self::lost_to_disk), a full disk or an I/O error; then
/// [`first_error`](Self::first_error) says why). In both cases the file still holds only
/// whole rows (unless [`intact`](Self::intact) is `false`), and
/// `written + dropped + lost_to_disk` is every record that was not decimated.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogStats {
    /// Rows written to the file, complete.
    pub written: u64,
    /// Records the producer pushed into the queue.
    pub pushed: u64,
    /// Records the producer dropped because the queue was full.
    pub dropped: u64,
    /// Records the producer skipped by decimation.
    pub decimated: u64,
    /// Records the writer took from the queue but could not write to the file (full
    /// disk, I/O error).
    pub lost_to_disk: u64,
    /// Failed writes of the file (0 on a healthy run); see [`WriteHealth::failures`].
    pub write_failures: u64,
    /// The first write failure, `writing <path>: <OS error>`; `None` if there was none.
    pub first_error: Option<String>,
    /// `false` only if the file could not be cut back to its last complete row after a
    /// failure, so that it may end in a torn row.
    pub intact: bool,
    /// The CSV file.
    pub path: PathBuf,
}

/// A running writer thread. Call [`finish`](Self::finish) to stop it; dropping the
/// handle also stops and joins the thread (draining and flushing), but discards the
/// outcome.
pub struct LogWriterHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<WriteHealth>>,
    counters: Arc<Counters>,
    path: PathBuf,
}

impl LogWriter {
    pub(super) fn new(rx: Consumer<LogRecord>, layout: LogLayout, counters: Arc<Counters>) -> Self {
        Self {
            rx,
            layout,
            counters,
        }
    }

    /// The column layout of this log.
    pub fn layout(&self) -> &LogLayout {
        &self.layout
    }

    /// A view of the queue's counters for the run report.
    pub fn counters(&self) -> LogCounters {
        LogCounters(Arc::clone(&self.counters))
    }

    /// Creates (truncates) the CSV file at `path`, writes the header, and spawns the
    /// `log-writer` thread that drains the queue into it. Errors creating the file or
    /// writing the header are returned here, naming the file. Later write errors do not
    /// stop the thread: they are reported on standard error when they happen, the rows
    /// that could not be written are counted, and [`LogWriterHandle::finish`] returns
    /// them in [`LogStats`].
    ///
    /// The thread resets its own scheduling policy to `SCHED_OTHER`, so it does not keep
    /// a real-time priority inherited from its parent.
    pub fn spawn(self, path: PathBuf) -> io::Result<LogWriterHandle> {
        let file = RecordFile::<File>::create(&path, BUFFER_BYTES, RETRY_EVERY)?;
        self.spawn_with(file, path)
    }

    /// [`spawn`](Self::spawn) into any [`RecordTarget`] (tests inject a failing one).
    #[cfg(test)]
    pub(crate) fn spawn_into<T: RecordTarget + Send + 'static>(
        self,
        target: T,
        path: PathBuf,
        retry_every: Duration,
    ) -> io::Result<LogWriterHandle> {
        let file = RecordFile::new(
            target,
            path.display().to_string(),
            BUFFER_BYTES,
            retry_every,
        );
        self.spawn_with(file, path)
    }

    fn spawn_with<T: RecordTarget + Send + 'static>(
        self,
        file: RecordFile<T>,
        path: PathBuf,
    ) -> io::Result<LogWriterHandle> {
        let mut sink = CsvSink::new(file, self.layout);
        sink.write_header()?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let thread_counters = Arc::clone(&self.counters);
        let mut rx = self.rx;
        let thread = thread::Builder::new()
            .name("log-writer".to_owned())
            .spawn(move || {
                drop_realtime_priority();
                run(&mut rx, &mut sink, &thread_stop, &thread_counters);
                let health = sink.out.finish();
                thread_counters
                    .lost_to_disk
                    .store(health.records_lost, Ordering::Relaxed);
                health
            })
            .map_err(|e| {
                io::Error::new(
                    e.kind(),
                    format!("starting the writer thread of {}: {e}", path.display()),
                )
            })?;
        Ok(LogWriterHandle {
            stop,
            thread: Some(thread),
            counters: self.counters,
            path,
        })
    }
}

/// The writer loop: drain, and when empty either stop (if asked) or sleep.
fn run<T: RecordTarget>(
    rx: &mut Consumer<LogRecord>,
    sink: &mut CsvSink<T>,
    stop: &AtomicBool,
    counters: &Counters,
) {
    let mut last_flush = Instant::now();
    loop {
        // Read the flag *before* draining: everything pushed before `finish` raised it is
        // then visible to the drain below, which is the last one.
        let stopping = stop.load(Ordering::Acquire);
        let n = drain(rx, sink);
        counters
            .lost_to_disk
            .store(sink.out.health().records_lost, Ordering::Relaxed);
        if stopping {
            break;
        }
        if n == 0 {
            if last_flush.elapsed() >= IDLE_FLUSH_EVERY {
                sink.out.flush();
                last_flush = Instant::now();
            }
            thread::sleep(IDLE_SLEEP);
        }
    }
}

fn drain<T: RecordTarget>(rx: &mut Consumer<LogRecord>, sink: &mut CsvSink<T>) -> u64 {
    let mut n = 0;
    while let Ok(rec) = rx.pop() {
        sink.write_row(&rec);
        n += 1;
    }
    n
}

/// Puts the calling thread under the default time-sharing policy (a no-op unless it
/// inherited a real-time one). Lowering one's own priority needs no privilege.
pub(crate) fn drop_realtime_priority() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: `pthread_self()` is the calling thread, `param` is a valid sched_param for
    // SCHED_OTHER (priority 0); the call has no other preconditions.
    unsafe {
        libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_OTHER, &param);
    }
}

impl LogWriterHandle {
    /// The CSV file being written.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }

    /// A view of the queue's counters for the run report.
    pub fn counters(&self) -> LogCounters {
        LogCounters(Arc::clone(&self.counters))
    }

    /// Stops the writer: everything pushed before this call is written (or counted as
    /// lost to the disk), the file is flushed and synced and the thread joined. Returns
    /// the counts, write failures included. A failing disk is *not* an error here (see
    /// [`LogStats::first_error`]); the only error is a writer thread that panicked.
    pub fn finish(mut self) -> io::Result<LogStats> {
        let health = self.stop_and_join()?;
        Ok(LogStats {
            written: health.records_written,
            pushed: self.counters.pushed.load(Ordering::Relaxed),
            dropped: self.counters.dropped.load(Ordering::Relaxed),
            decimated: self.counters.decimated.load(Ordering::Relaxed),
            lost_to_disk: health.records_lost,
            write_failures: health.failures,
            first_error: health.first_error,
            intact: health.intact,
            path: self.path.clone(),
        })
    }

    fn stop_and_join(&mut self) -> io::Result<WriteHealth> {
        self.stop.store(true, Ordering::Release);
        match self.thread.take() {
            Some(t) => t.join().map_err(|_| {
                io::Error::other(format!(
                    "the writer thread of {} panicked",
                    self.path.display()
                ))
            }),
            None => Ok(WriteHealth::new(self.path.display().to_string())),
        }
    }
}

impl Drop for LogWriterHandle {
    fn drop(&mut self) {
        let _ = self.stop_and_join();
    }
}

/// Formats records as CSV rows into a [`RecordFile`].
struct CsvSink<T: RecordTarget> {
    out: RecordFile<T>,
    layout: LogLayout,
}

impl<T: RecordTarget> CsvSink<T> {
    fn new(out: RecordFile<T>, layout: LogLayout) -> Self {
        Self { out, layout }
    }

    fn write_header(&mut self) -> io::Result<()> {
        let mut w = Vec::new();
        w.extend_from_slice(b"seq,t_sample_ns,status,flags");
        for i in 0..self.layout.n_y {
            write!(w, ",y{i}")?;
        }
        for i in 0..self.layout.n_z {
            write!(w, ",z{i}")?;
        }
        for i in 0..self.layout.n_u {
            write!(w, ",u{i}")?;
        }
        for name in &self.layout.internal_names {
            w.extend_from_slice(b",");
            write_csv_field(&mut w, name)?;
        }
        w.extend_from_slice(b"\n");
        self.out.write_preamble(&w)
    }

    fn write_row(&mut self, r: &LogRecord) {
        let layout = &self.layout;
        self.out.push_with(|w| format_row(w, layout, r));
    }
}

/// Appends one CSV row (with its line end) to `w`.
fn format_row(w: &mut Vec<u8>, layout: &LogLayout, r: &LogRecord) {
    // Writing into a Vec cannot fail.
    let _ = write!(w, "{},{},{},{}", r.seq, r.t_sample_ns, r.status, r.flags);
    let n_internals = layout.internal_names.len();
    for v in r.y[..layout.n_y]
        .iter()
        .chain(&r.z[..layout.n_z])
        .chain(&r.u[..layout.n_u])
        .chain(&r.internals[..n_internals])
    {
        w.push(b',');
        let _ = write_f64(w, *v);
    }
    w.push(b'\n');
}

/// Writes `v` so that parsing it back gives the same bits: Rust's shortest round-trip
/// representation, in plain decimal for moderate magnitudes and in exponent notation
/// (`1.5e-9`, `2e300`) otherwise, to keep rows short.
pub(super) fn write_f64<W: Write>(w: &mut W, v: f64) -> io::Result<()> {
    let a = v.abs();
    if v == 0.0 || !v.is_finite() || (1e-5..1e16).contains(&a) {
        write!(w, "{v}")
    } else {
        write!(w, "{v:e}")
    }
}

/// Writes a header field, quoted (RFC 4180) if it contains a comma or a quote.
fn write_csv_field<W: Write>(w: &mut W, s: &str) -> io::Result<()> {
    if s.contains([',', '"', '\n', '\r']) {
        write!(w, "\"{}\"", s.replace('"', "\"\""))
    } else {
        w.write_all(s.as_bytes())
    }
}
