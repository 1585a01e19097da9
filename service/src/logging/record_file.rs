//! A file that only ever holds complete records, and keeps going when the disk does not.
//!
//! See [`RecordFile`].

use std::fs::File;
use std::io::{self, Seek, SeekFrom, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;

/// Where a [`RecordFile`] writes: a byte sink that can also be cut back to a length.
/// Implemented for [`File`]; tests implement it for a simulated full disk.
pub trait RecordTarget: Write {
    /// Cuts the target back to its first `len` bytes and makes the next write start
    /// there.
    fn truncate_to(&mut self, len: u64) -> io::Result<()>;

    /// Flushes written data to the device (`fsync`), so that delayed write errors show.
    fn sync(&mut self) -> io::Result<()>;
}

impl RecordTarget for File {
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        self.set_len(len)?;
        self.seek(SeekFrom::Start(len)).map(|_| ())
    }

    fn sync(&mut self) -> io::Result<()> {
        self.sync_data()
    }
}

impl<T: RecordTarget + ?Sized> RecordTarget for Box<T> {
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        (**self).truncate_to(len)
    }

    fn sync(&mut self) -> io::Result<()> {
        (**self).sync()
    }
}

/// What a [`RecordFile`] did: for the run report.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WriteHealth {
    /// The file.
    pub path: String,
    /// Records that are in the file, complete.
    pub records_written: u64,
    /// Records that could not be written because writing the file failed (full disk,
    /// I/O error), including those offered while it was failing.
    pub records_lost: u64,
    /// Failed writes: one per failure episode, plus one per failed retry and per failed
    /// final sync.
    pub failures: u64,
    /// The first failure: `writing <path>: <OS error>`; `None` if every write succeeded.
    pub first_error: Option<String>,
    /// `true` unless a cut-back after a failure failed too, so that the file may end in
    /// a torn record.
    pub intact: bool,
}

impl WriteHealth {
    /// A healthy record of `path` with nothing written yet.
    pub fn new(path: impl Into<String>) -> Self {
        Self {
            path: path.into(),
            intact: true,
            ..Self::default()
        }
    }

    /// Whether any write of this file failed.
    pub fn failed(&self) -> bool {
        self.failures > 0
    }
}

/// Whether the file takes records now.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Writing normally.
    Healthy,
    /// The last write failed; records are dropped until `retry_at`, then tried again.
    Failing { retry_at: Instant },
    /// The file could not be cut back after a failure: nothing more is written.
    Broken,
}

/// A buffered file of whole records: the output stage of the non-RT log writers
/// (`signals.csv`, the `.hlog` interval logs). Records (a CSV row, an interval-log
/// line) are formatted into its buffer whole; the buffer goes to the file when it is
/// full or on [`flush`](RecordFile::flush), always ending on a record boundary. When a
/// write fails (`ENOSPC`, `EIO`, …):
///
/// - the file is cut back (`set_len` and seek) to the end of the last record that reached
///   it completely, so it never ends in a torn record;
/// - the failure is reported at once, on one line of standard error naming the file and
///   the OS error (`[service] writing <path>: <OS error>; …`); failed retries are not
///   reported again (only counted), and a new failure after writing had resumed is
///   reported on a shorter line (`[service] writing <path> failed again …`);
/// - the records that did not reach the file are counted as lost to the disk
///   ([`WriteHealth::records_lost`]), and so is every record offered while the file is
///   failing; the caller never waits and never sees an error;
/// - after [`RecordFile::retry_every`] (1 s for the service's files) the next records
///   are tried again: if the write succeeds (space was freed), writing resumes, and that
///   is reported on one line too. The rows in between are missing from the file (the
///   `seq` column shows the gap).
///
/// If the cut-back itself fails, the file may end in a torn record: this is reported,
/// [`WriteHealth::intact`] becomes `false` and nothing more is written to the file.
pub struct RecordFile<T: RecordTarget> {
    target: T,
    /// Complete records not yet written.
    buf: Vec<u8>,
    /// End offset in `buf` of each record in it.
    ends: Vec<usize>,
    /// The buffer is written when it holds at least this many bytes.
    flush_at: usize,
    /// Length of the file: the end of its last complete record.
    committed_len: u64,
    retry_every: Duration,
    state: State,
    /// Records lost since the current failure episode began (for the resume message).
    lost_in_episode: u64,
    /// Failure episodes so far (a failure after a successful write starts one).
    episodes: u64,
    health: WriteHealth,
}

impl RecordFile<File> {
    /// Creates (truncates) the file at `path`. The error names the file.
    pub fn create(path: &Path, flush_at: usize, retry_every: Duration) -> io::Result<Self> {
        let file = File::create(path)
            .map_err(|e| io::Error::new(e.kind(), format!("creating {}: {e}", path.display())))?;
        Ok(Self::new(
            file,
            path.display().to_string(),
            flush_at,
            retry_every,
        ))
    }
}

impl<T: RecordTarget> RecordFile<T> {
    /// Wraps an empty `target`; `name` (the path) is used in messages and in
    /// [`WriteHealth::path`]. The buffer is written whenever it holds `flush_at` bytes or
    /// more; after a failure, records are tried again after `retry_every`.
    pub fn new(target: T, name: String, flush_at: usize, retry_every: Duration) -> Self {
        Self {
            target,
            buf: Vec::with_capacity(flush_at.saturating_mul(2).max(4096)),
            ends: Vec::with_capacity(1024),
            flush_at: flush_at.max(1),
            committed_len: 0,
            retry_every,
            state: State::Healthy,
            lost_in_episode: 0,
            episodes: 0,
            health: WriteHealth::new(name),
        }
    }

    /// The file's name, as used in messages.
    pub fn name(&self) -> &str {
        &self.health.path
    }

    /// How often records are tried again after a failure.
    pub fn retry_every(&self) -> Duration {
        self.retry_every
    }

    /// What happened so far (records still in the buffer are in neither count).
    pub fn health(&self) -> &WriteHealth {
        &self.health
    }

    /// Writes `bytes` (a file header, not a record) to the file at once. Meant for the
    /// start, before any record: an error is returned, naming the file, and the file is
    /// cut back to where it was.
    pub fn write_preamble(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.flush();
        let result = self
            .target
            .write_all(bytes)
            .and_then(|()| self.target.flush());
        match result {
            Ok(()) => {
                self.committed_len += bytes.len() as u64;
                Ok(())
            }
            Err(e) => {
                let _ = self.target.truncate_to(self.committed_len);
                Err(io::Error::new(
                    e.kind(),
                    format!("writing {}: {e}", self.health.path),
                ))
            }
        }
    }

    /// Whether a record offered now would be kept (buffered) rather than dropped: the
    /// file is healthy, or failing and due for a retry. Reads the clock when failing.
    pub fn accepting(&self) -> bool {
        match self.state {
            State::Healthy => true,
            State::Failing { retry_at } => Instant::now() >= retry_at,
            State::Broken => false,
        }
    }

    /// Offers one record: `format` appends it, complete, to the buffer it is given. If the
    /// file is failing (and not due for a retry) the record is not formatted but counted
    /// as lost. Writes the buffer when it is full enough.
    pub fn push_with(&mut self, format: impl FnOnce(&mut Vec<u8>)) {
        if !self.accepting() {
            self.lose(1);
            return;
        }
        format(&mut self.buf);
        self.ends.push(self.buf.len());
        if self.buf.len() >= self.flush_at {
            self.flush();
        }
    }

    /// Offers one complete record given as bytes (see [`push_with`](Self::push_with)).
    pub fn push(&mut self, record: &[u8]) {
        self.push_with(|buf| buf.extend_from_slice(record));
    }

    /// Counts `n` records as lost to the disk without offering them.
    pub fn lose(&mut self, n: u64) {
        self.health.records_lost = self.health.records_lost.saturating_add(n);
        self.lost_in_episode = self.lost_in_episode.saturating_add(n);
    }

    /// Writes the buffered records to the file. On failure the file is cut back to its
    /// last complete record, the failure is reported (once per episode) and counted, and
    /// the records that did not reach the file are counted as lost.
    pub fn flush(&mut self) {
        if self.ends.is_empty() {
            return;
        }
        let (done, error) = write_some(&mut self.target, &self.buf);
        match error {
            None => {
                self.committed_len += done as u64;
                self.health.records_written += self.ends.len() as u64;
                if let State::Failing { .. } = self.state {
                    eprintln!(
                        "[service] writing {} resumed; {} records were lost to the failure",
                        self.health.path, self.lost_in_episode
                    );
                    self.state = State::Healthy;
                }
            }
            Some(e) => {
                // Keep the records that reached the file whole, cut off the rest.
                let whole = self.ends.partition_point(|&end| end <= done);
                let keep = if whole == 0 { 0 } else { self.ends[whole - 1] };
                self.health.records_written += whole as u64;
                let lost = (self.ends.len() - whole) as u64;
                let cut = self.committed_len + keep as u64;
                match self.target.truncate_to(cut) {
                    Ok(()) => self.committed_len = cut,
                    Err(cut_error) => {
                        eprintln!(
                            "[service] {}: cannot cut the file back to its last complete \
                             record ({cut_error}); it may end in a torn record, and nothing \
                             more is written to it",
                            self.health.path
                        );
                        self.health.intact = false;
                    }
                }
                self.fail(&e);
                self.lose(lost);
                if !self.health.intact {
                    self.state = State::Broken;
                }
            }
        }
        self.buf.clear();
        self.ends.clear();
    }

    /// Records a failed write: counts it, reports it if it starts an episode, and
    /// schedules the retry.
    fn fail(&mut self, e: &io::Error) {
        self.health.failures += 1;
        let message = format!("writing {}: {e}", self.health.path);
        if self.state == State::Healthy {
            self.lost_in_episode = 0;
            self.episodes += 1;
            if self.episodes == 1 {
                eprintln!(
                    "[service] {message}; its records are dropped (and counted) until a \
                     write succeeds, retried every {:.1} s",
                    self.retry_every.as_secs_f64()
                );
            } else {
                eprintln!(
                    "[service] writing {} failed again (failure episode {}): {e}",
                    self.health.path, self.episodes
                );
            }
        }
        if self.health.first_error.is_none() {
            self.health.first_error = Some(message);
        }
        self.state = State::Failing {
            retry_at: Instant::now() + self.retry_every,
        };
    }

    /// Ends the file: writes what is buffered (one last try even if the file is
    /// failing), syncs it to the device and returns what happened. A failed sync counts
    /// as a failure (the data written may not be on the device).
    pub fn finish(mut self) -> WriteHealth {
        if let State::Failing { .. } = self.state {
            // One last try for what is buffered.
            self.state = State::Failing {
                retry_at: Instant::now(),
            };
        }
        self.flush();
        if self.state != State::Broken
            && let Err(e) = self.target.sync()
        {
            self.fail(&e);
        }
        self.health
    }
}

/// Writes as much of `bytes` as the target takes. Returns the number of bytes written
/// and the error that stopped it, if any.
fn write_some<W: Write>(w: &mut W, bytes: &[u8]) -> (usize, Option<io::Error>) {
    let mut done = 0;
    while done < bytes.len() {
        match w.write(&bytes[done..]) {
            Ok(0) => return (done, Some(io::ErrorKind::WriteZero.into())),
            Ok(n) => done += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return (done, Some(e)),
        }
    }
    match w.flush() {
        Ok(()) => (done, None),
        Err(e) => (done, Some(e)),
    }
}
