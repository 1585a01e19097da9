//! Reading a record file back, entry by entry, with errors that name the file and the
//! byte offset at fault.

use super::entry::{Entry, decode};
use super::header::{FORMAT_VERSION, MAGIC, RecordHeader};
use super::layout::{EntryKind, RecordLayout};
use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Why a record could not be read (further).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RecordError {
    /// The file could not be opened or read.
    Io {
        /// The file.
        path: String,
        /// The OS error.
        error: String,
    },
    /// It is not a record file (no magic), or its header is not valid.
    NotARecord {
        /// The file.
        path: String,
        /// What is wrong.
        why: String,
    },
    /// Another format version than this build reads.
    Version {
        /// The file.
        path: String,
        /// Its version.
        found: u32,
    },
    /// The file ends inside an entry (a killed service, a full disk that could not be cut
    /// back): the entries before `offset` are whole.
    Truncated {
        /// The file.
        path: String,
        /// Byte offset of the incomplete entry.
        offset: u64,
        /// Its index (the number of entries before it).
        index: u64,
        /// Bytes the entry needs.
        needed: usize,
        /// Bytes the file still has.
        found: usize,
    },
    /// A byte that is no entry kind where an entry begins.
    UnknownKind {
        /// The file.
        path: String,
        /// Byte offset.
        offset: u64,
        /// The byte.
        kind: u8,
    },
    /// The file ends without the end mark: the service did not finish (killed, or the
    /// disk failed at the end); entries after `offset` may be missing.
    Unfinished {
        /// The file.
        path: String,
        /// Byte offset of the end of the file.
        offset: u64,
        /// Entries read.
        entries: u64,
    },
    /// Entries are missing (the queue was full, or the disk failed): the next entry in the
    /// file is not the next the loop offered.
    Gap {
        /// The file.
        path: String,
        /// Byte offset of the entry after the gap.
        offset: u64,
        /// The index expected.
        expected: u64,
        /// The index found.
        found: u64,
    },
}

impl RecordError {
    /// True for a record that is readable but incomplete ([`RecordError::Truncated`],
    /// [`RecordError::Gap`], [`RecordError::Unfinished`]).
    pub fn is_incomplete(&self) -> bool {
        matches!(
            self,
            RecordError::Truncated { .. }
                | RecordError::Gap { .. }
                | RecordError::Unfinished { .. }
        )
    }
}

impl fmt::Display for RecordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordError::Io { path, error } => write!(f, "{path}: {error}"),
            RecordError::NotARecord { path, why } => write!(f, "{path}: not a record file: {why}"),
            RecordError::Version { path, found } => write!(
                f,
                "{path}: record format version {found}, this service reads versions 1 to {FORMAT_VERSION}"
            ),
            RecordError::Truncated {
                path,
                offset,
                index,
                needed,
                found,
            } => write!(
                f,
                "{path}: truncated at byte offset {offset}: entry {index} needs {needed} bytes, \
                 the file has {found} more"
            ),
            RecordError::Unfinished {
                path,
                offset,
                entries,
            } => write!(
                f,
                "{path}: ends at byte offset {offset} after {entries} entries without its end \
                 mark: the service did not finish, later entries may be missing"
            ),
            RecordError::UnknownKind { path, offset, kind } => write!(
                f,
                "{path}: byte offset {offset}: {kind} is no entry kind (the file is damaged)"
            ),
            RecordError::Gap {
                path,
                offset,
                expected,
                found,
            } => write!(
                f,
                "{path}: gap at byte offset {offset}: entries {expected} to {} are missing \
                 (dropped by a full queue or lost to the disk)",
                found.saturating_sub(1)
            ),
        }
    }
}

impl std::error::Error for RecordError {}

/// An entry, where it was in the file.
#[derive(Debug, Clone, Copy)]
pub struct Located {
    /// Its index: the number of entries the loop offered before it.
    pub index: u64,
    /// Byte offset in the file.
    pub offset: u64,
    /// The entry.
    pub entry: Entry,
}

/// A record file opened for reading: its header, then its entries in order
/// ([`RecordReader::next_entry`], [`RecordReader::peek`]).
pub struct RecordReader {
    path: PathBuf,
    input: BufReader<File>,
    header: RecordHeader,
    layout: RecordLayout,
    offset: u64,
    next_index: u64,
    peeked: Option<Result<Option<Located>, RecordError>>,
    buf: Vec<u8>,
    /// The end mark was read.
    ended: bool,
}

impl RecordReader {
    /// Opens `path` and reads its header.
    ///
    /// # Errors
    ///
    /// An unreadable file, no magic, another format version, a bad header; naming the
    /// file.
    pub fn open(path: &Path) -> Result<Self, RecordError> {
        let name = path.display().to_string();
        let io = |e: std::io::Error| RecordError::Io {
            path: name.clone(),
            error: e.to_string(),
        };
        let not = |why: String| RecordError::NotARecord {
            path: name.clone(),
            why,
        };
        let mut input = BufReader::with_capacity(1 << 16, File::open(path).map_err(io)?);
        let mut head = [0u8; 16];
        let got = read_full(&mut input, &mut head).map_err(io)?;
        if got < 16 || &head[..8] != MAGIC {
            return Err(not(format!(
                "it does not begin with {:?} and a 16-byte preamble",
                String::from_utf8_lossy(MAGIC)
            )));
        }
        let version = u32::from_le_bytes([head[8], head[9], head[10], head[11]]);
        // Version 1 is version 2 without operator entries.
        if !(1..=FORMAT_VERSION).contains(&version) {
            return Err(RecordError::Version {
                path: name,
                found: version,
            });
        }
        let len = u32::from_le_bytes([head[12], head[13], head[14], head[15]]) as usize;
        let mut json = vec![0u8; len];
        let got = read_full(&mut input, &mut json).map_err(io)?;
        if got < len {
            return Err(RecordError::Truncated {
                path: name,
                offset: 16,
                index: 0,
                needed: len,
                found: got,
            });
        }
        let header: RecordHeader = serde_json::from_slice(&json)
            .map_err(|e| not(format!("its header (bytes 16 to {}): {e}", 16 + len)))?;
        let layout = header.layout();
        Ok(Self {
            path: path.to_path_buf(),
            input,
            buf: vec![0u8; layout.max_entry_bytes()],
            header,
            layout,
            offset: 16 + len as u64,
            next_index: 0,
            peeked: None,
            ended: false,
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Its header.
    pub fn header(&self) -> &RecordHeader {
        &self.header
    }

    /// Its entry layout.
    pub fn layout(&self) -> &RecordLayout {
        &self.layout
    }

    /// The next entry without taking it.
    ///
    /// # Errors
    ///
    /// As [`RecordReader::next_entry`].
    pub fn peek(&mut self) -> Result<Option<&Located>, RecordError> {
        if self.peeked.is_none() {
            self.peeked = Some(self.read_entry());
        }
        match self.peeked.as_ref() {
            Some(Ok(l)) => Ok(l.as_ref()),
            Some(Err(e)) => Err(e.clone()),
            None => Ok(None),
        }
    }

    /// The next entry, `None` at the end mark.
    ///
    /// # Errors
    ///
    /// A read error, a truncated entry, an unknown kind, a gap in the indices (also
    /// before the end mark: entries lost at the end), a file without the end mark; each
    /// names the file and the byte offset. The same error is returned again by later
    /// calls.
    pub fn next_entry(&mut self) -> Result<Option<Located>, RecordError> {
        let r = match self.peeked.take() {
            Some(r) => r,
            None => self.read_entry(),
        };
        if let Err(e) = &r {
            self.peeked = Some(Err(e.clone()));
        }
        r
    }

    fn read_entry(&mut self) -> Result<Option<Located>, RecordError> {
        if self.ended {
            return Ok(None);
        }
        let path = self.path.display().to_string();
        let offset = self.offset;
        let io = |e: std::io::Error| RecordError::Io {
            path: path.clone(),
            error: format!("byte offset {offset}: {e}"),
        };
        let mut first = [0u8; 1];
        if read_full(&mut self.input, &mut first).map_err(io)? == 0 {
            return Err(RecordError::Unfinished {
                path,
                offset,
                entries: self.next_index,
            });
        }
        let Some(kind) = EntryKind::from_byte(first[0]) else {
            return Err(RecordError::UnknownKind {
                path,
                offset,
                kind: first[0],
            });
        };
        let size = self.layout.entry_bytes(kind);
        self.buf[0] = first[0];
        let got = read_full(&mut self.input, &mut self.buf[1..size]).map_err(io)?;
        if got < size - 1 {
            return Err(RecordError::Truncated {
                path,
                offset,
                index: self.next_index,
                needed: size,
                found: got + 1,
            });
        }
        let (index, entry) = decode(&self.layout, kind, &self.buf[..size]);
        if index != self.next_index {
            return Err(RecordError::Gap {
                path,
                offset,
                expected: self.next_index,
                found: index,
            });
        }
        self.offset += size as u64;
        if kind == EntryKind::End {
            self.ended = true;
            return Ok(None);
        }
        self.next_index += 1;
        Ok(Some(Located {
            index,
            offset,
            entry,
        }))
    }
}

/// Reads until `buf` is full or the input ends; returns the bytes read.
fn read_full(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match input.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}
