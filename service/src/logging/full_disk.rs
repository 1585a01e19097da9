//! Test support: a [`RecordTarget`] in memory that behaves like a disk of limited size.

use std::io::{self, Write};
use std::sync::{Arc, Mutex};

use super::RecordTarget;

/// What the simulated disk holds and how it fails; shared, so a test can look at the
/// content and change the capacity while a writer thread owns the target.
#[derive(Debug, Default)]
pub(crate) struct DiskState {
    /// The file's bytes.
    pub data: Vec<u8>,
    /// Bytes the file may hold; a write beyond fails with `ENOSPC` after writing what
    /// fits (as a real full disk does).
    pub capacity: usize,
    /// Every write fails with `EIO`, writing nothing.
    pub io_error: bool,
    /// Cutting back fails with `EIO`.
    pub truncate_fails: bool,
}

/// An `io::Write` that fails with `ENOSPC` once it holds `capacity` bytes.
#[derive(Clone, Debug)]
pub(crate) struct FullDisk(pub Arc<Mutex<DiskState>>);

impl FullDisk {
    /// An empty file on a disk with room for `capacity` bytes.
    pub fn with_capacity(capacity: usize) -> Self {
        Self(Arc::new(Mutex::new(DiskState {
            capacity,
            ..DiskState::default()
        })))
    }

    /// A copy of the file's content.
    pub fn content(&self) -> Vec<u8> {
        self.0.lock().unwrap().data.clone()
    }

    /// The file's content as text.
    pub fn text(&self) -> String {
        String::from_utf8(self.content()).unwrap()
    }

    /// Changes the disk's capacity (frees or takes space).
    pub fn set_capacity(&self, capacity: usize) {
        self.0.lock().unwrap().capacity = capacity;
    }

    /// Makes every write fail with `EIO` (or stops doing so).
    pub fn set_io_error(&self, on: bool) {
        self.0.lock().unwrap().io_error = on;
    }

    /// Makes cutting back fail (or stops doing so).
    pub fn set_truncate_fails(&self, on: bool) {
        self.0.lock().unwrap().truncate_fails = on;
    }
}

impl Write for FullDisk {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let mut s = self.0.lock().unwrap();
        if s.io_error {
            return Err(io::Error::from_raw_os_error(libc::EIO));
        }
        let room = s.capacity.saturating_sub(s.data.len());
        if room == 0 && !buf.is_empty() {
            return Err(io::Error::from_raw_os_error(libc::ENOSPC));
        }
        let n = room.min(buf.len());
        s.data.extend_from_slice(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl RecordTarget for FullDisk {
    fn truncate_to(&mut self, len: u64) -> io::Result<()> {
        let mut s = self.0.lock().unwrap();
        if s.truncate_fails {
            return Err(io::Error::from_raw_os_error(libc::EIO));
        }
        let len = usize::try_from(len).unwrap();
        assert!(len <= s.data.len(), "cut back beyond the end");
        s.data.truncate(len);
        Ok(())
    }

    fn sync(&mut self) -> io::Result<()> {
        Ok(())
    }
}
