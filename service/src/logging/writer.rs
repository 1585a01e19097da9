//! The non-RT end of the log queue: a thread that drains it into a CSV file.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use rtrb::Consumer;

use super::{Counters, LogCounters, LogLayout, LogRecord};

/// Sleep of the writer thread when the queue is empty.
const IDLE_SLEEP: Duration = Duration::from_millis(1);
/// While idle, flush buffered rows to the file at most this often.
const IDLE_FLUSH_EVERY: Duration = Duration::from_millis(200);
/// Size of the file buffer.
const BUFFER_BYTES: usize = 1 << 16;

/// The non-RT end of a log queue, not yet writing. Turn it into a running writer with
/// [`spawn`](Self::spawn).
pub struct LogWriter {
    rx: Consumer<LogRecord>,
    layout: LogLayout,
    counters: Arc<Counters>,
}

/// What a finished writer did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogStats {
    /// Rows written to the file.
    pub written: u64,
    /// Records the producer pushed into the queue.
    pub pushed: u64,
    /// Records the producer dropped because the queue was full.
    pub dropped: u64,
    /// Records the producer skipped by decimation.
    pub decimated: u64,
    /// The CSV file.
    pub path: PathBuf,
}

/// A running writer thread. Call [`finish`](Self::finish) to stop it; dropping the
/// handle also stops and joins the thread (draining and flushing), but discards the
/// outcome.
pub struct LogWriterHandle {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<io::Result<u64>>>,
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
    /// `log-writer` thread that drains the queue into it. File-creation and header errors
    /// are returned here; later write errors end the thread and are returned by
    /// [`LogWriterHandle::finish`] (the producer then just counts drops).
    ///
    /// The thread resets its own scheduling policy to `SCHED_OTHER`, so it does not keep
    /// a real-time priority inherited from its parent.
    pub fn spawn(self, path: PathBuf) -> io::Result<LogWriterHandle> {
        let mut sink = CsvSink::new(File::create(&path)?, self.layout);
        sink.write_header()?;
        sink.out.flush()?;
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let mut rx = self.rx;
        let thread = thread::Builder::new()
            .name("log-writer".to_owned())
            .spawn(move || {
                drop_realtime_priority();
                run(&mut rx, &mut sink, &thread_stop)
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
fn run(rx: &mut Consumer<LogRecord>, sink: &mut CsvSink, stop: &AtomicBool) -> io::Result<u64> {
    let mut last_flush = Instant::now();
    loop {
        // Read the flag *before* draining: everything pushed before `finish` raised it is
        // then visible to the drain below, which is the last one.
        let stopping = stop.load(Ordering::Acquire);
        let n = drain(rx, sink)?;
        if stopping {
            break;
        }
        if n == 0 {
            if last_flush.elapsed() >= IDLE_FLUSH_EVERY {
                sink.out.flush()?;
                last_flush = Instant::now();
            }
            thread::sleep(IDLE_SLEEP);
        }
    }
    sink.out.flush()?;
    Ok(sink.written)
}

fn drain(rx: &mut Consumer<LogRecord>, sink: &mut CsvSink) -> io::Result<u64> {
    let mut n = 0;
    while let Ok(rec) = rx.pop() {
        sink.write_row(&rec)?;
        n += 1;
    }
    Ok(n)
}

/// Puts the calling thread under the default time-sharing policy (a no-op unless it
/// inherited a real-time one). Lowering one's own priority needs no privilege.
fn drop_realtime_priority() {
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

    /// Stops the writer: everything pushed before this call is written, the file is
    /// flushed and the thread joined. Returns the counts, or the first I/O error the
    /// thread met.
    pub fn finish(mut self) -> io::Result<LogStats> {
        let written = self.stop_and_join()?;
        Ok(LogStats {
            written,
            pushed: self.counters.pushed.load(Ordering::Relaxed),
            dropped: self.counters.dropped.load(Ordering::Relaxed),
            decimated: self.counters.decimated.load(Ordering::Relaxed),
            path: self.path.clone(),
        })
    }

    fn stop_and_join(&mut self) -> io::Result<u64> {
        self.stop.store(true, Ordering::Release);
        match self.thread.take() {
            Some(t) => t
                .join()
                .unwrap_or_else(|_| Err(io::Error::other("log writer thread panicked"))),
            None => Ok(0),
        }
    }
}

impl Drop for LogWriterHandle {
    fn drop(&mut self) {
        let _ = self.stop_and_join();
    }
}

/// Formats records as CSV rows.
struct CsvSink {
    out: BufWriter<File>,
    layout: LogLayout,
    written: u64,
}

impl CsvSink {
    fn new(file: File, layout: LogLayout) -> Self {
        Self {
            out: BufWriter::with_capacity(BUFFER_BYTES, file),
            layout,
            written: 0,
        }
    }

    fn write_header(&mut self) -> io::Result<()> {
        let w = &mut self.out;
        w.write_all(b"seq,t_sample_ns,status,flags")?;
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
            w.write_all(b",")?;
            write_csv_field(w, name)?;
        }
        w.write_all(b"\n")
    }

    fn write_row(&mut self, r: &LogRecord) -> io::Result<()> {
        let w = &mut self.out;
        write!(w, "{},{},{},{}", r.seq, r.t_sample_ns, r.status, r.flags)?;
        let n_internals = self.layout.internal_names.len();
        for v in r.y[..self.layout.n_y]
            .iter()
            .chain(&r.z[..self.layout.n_z])
            .chain(&r.u[..self.layout.n_u])
            .chain(&r.internals[..n_internals])
        {
            w.write_all(b",")?;
            write_f64(w, *v)?;
        }
        w.write_all(b"\n")?;
        self.written += 1;
        Ok(())
    }
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
