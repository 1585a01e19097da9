//! # Atomic file writes: a reader sees the old file or the whole new one, never a part
//!
//! [`write_atomic`] (and [`write_atomic_with`] for content produced by a writer) replace
//! a file the way a crash, a full disk or an I/O error cannot tear:
//!
//! 1. the content goes into a new temporary file in the *same folder* (so the rename
//!    below stays inside one filesystem), named `.<file name>.<pid>.<n>.tmp`;
//! 2. the temporary file is flushed to the device (`fsync`);
//! 3. it is renamed over the target (`rename(2)` is atomic within a filesystem);
//! 4. the folder is synced, so that the rename itself survives a power loss.
//!
//! If any step fails, the temporary file is removed and the target is left as it was (the
//! previous content, or no file at all): a full disk gives an error, never an empty or
//! truncated file. The error ([`AtomicWriteError`]) names the target, the step that failed
//! and the OS error.
//!
//! Both processes use it: the service for `report.json` and the `.hgrm` percentile files,
//! plant-proxy for `plant-report.json`.
//!
//! ```
//! let dir = std::env::temp_dir().join(format!("files-doc-{}", std::process::id()));
//! std::fs::create_dir_all(&dir).unwrap();
//! let path = dir.join("report.json");
//! ipc_types::files::write_atomic(&path, b"{\"ok\": true}\n").unwrap();
//! assert_eq!(std::fs::read(&path).unwrap(), b"{\"ok\": true}\n");
//!
//! // A missing folder: the error names the file and the OS error.
//! let err = ipc_types::files::write_atomic(dir.join("no/such/report.json"), b"x").unwrap_err();
//! assert!(err.to_string().contains("no/such/report.json"), "{err}");
//! # std::fs::remove_dir_all(&dir).unwrap();
//! ```

use std::fmt;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Distinguishes the temporary files of concurrent writes from one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// The step of an atomic write that failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AtomicWriteStep {
    /// The target path has no file name (it is empty, `/`, or ends in `..`).
    NoFileName,
    /// Creating the temporary file in the target's folder.
    Create,
    /// Writing the content into the temporary file (a full disk fails here).
    Write,
    /// Flushing the temporary file to the device (`fsync`; delayed I/O errors appear here).
    Sync,
    /// Renaming the temporary file over the target.
    Rename,
    /// Syncing the folder after the rename. The new content is in place, but the rename
    /// might not survive a power loss.
    SyncFolder,
}

impl AtomicWriteStep {
    /// What the step does, for messages.
    pub const fn describe(self) -> &'static str {
        match self {
            AtomicWriteStep::NoFileName => "the path has no file name",
            AtomicWriteStep::Create => "creating the temporary file",
            AtomicWriteStep::Write => "writing the temporary file",
            AtomicWriteStep::Sync => "flushing the temporary file to disk",
            AtomicWriteStep::Rename => "renaming the temporary file over it",
            AtomicWriteStep::SyncFolder => "syncing the folder after the rename",
        }
    }
}

/// An atomic write that did not happen. Unless [`step`](Self::step) is
/// [`AtomicWriteStep::SyncFolder`], the target is unchanged and no temporary file is
/// left behind.
#[derive(Debug)]
pub struct AtomicWriteError {
    path: PathBuf,
    step: AtomicWriteStep,
    source: io::Error,
}

impl AtomicWriteError {
    /// The file that was to be written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The step that failed.
    pub fn step(&self) -> AtomicWriteStep {
        self.step
    }

    /// The OS error (its kind is [`io::ErrorKind::StorageFull`] on a full disk).
    pub fn io_error(&self) -> &io::Error {
        &self.source
    }

    /// The OS error's kind.
    pub fn kind(&self) -> io::ErrorKind {
        self.source.kind()
    }
}

impl fmt::Display for AtomicWriteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "writing {}: {}: {}",
            self.path.display(),
            self.step.describe(),
            self.source
        )
    }
}

impl std::error::Error for AtomicWriteError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

impl From<AtomicWriteError> for io::Error {
    /// An `io::Error` of the same kind whose message is the whole
    /// [`AtomicWriteError`] (file, step, OS error).
    fn from(e: AtomicWriteError) -> Self {
        io::Error::new(e.source.kind(), e.to_string())
    }
}

/// Replaces the file at `path` with `contents` atomically (see the [module
/// documentation](self)): afterwards the file holds either its previous content (or does
/// not exist) or exactly `contents`.
pub fn write_atomic(
    path: impl AsRef<Path>,
    contents: impl AsRef<[u8]>,
) -> Result<(), AtomicWriteError> {
    write_atomic_with(path, |w| w.write_all(contents.as_ref()))
}

/// Like [`write_atomic`], with the content produced by `fill` writing into a buffered
/// writer on the temporary file. If `fill` returns an error, nothing is replaced and the
/// error is returned as a [`AtomicWriteStep::Write`] failure.
pub fn write_atomic_with<F>(path: impl AsRef<Path>, fill: F) -> Result<(), AtomicWriteError>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let path = path.as_ref();
    let fail = |step, source| AtomicWriteError {
        path: path.to_path_buf(),
        step,
        source,
    };
    let Some(name) = path.file_name() else {
        return Err(fail(
            AtomicWriteStep::NoFileName,
            io::Error::new(io::ErrorKind::InvalidInput, "no file name"),
        ));
    };
    let folder = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut temp_name = std::ffi::OsString::from(".");
    temp_name.push(name);
    temp_name.push(format!(".{}.{n}.tmp", std::process::id()));
    let temp = folder.join(temp_name);

    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temp)
        .map_err(|e| fail(AtomicWriteStep::Create, e))?;
    // From here on, every failure removes the temporary file.
    let outcome = fill_and_sync(file, fill)
        .and_then(|()| fs::rename(&temp, path).map_err(|e| (AtomicWriteStep::Rename, e)));
    if let Err((step, e)) = outcome {
        let _ = fs::remove_file(&temp);
        return Err(fail(step, e));
    }
    sync_folder(folder).map_err(|e| fail(AtomicWriteStep::SyncFolder, e))
}

/// Writes the content through a buffer, flushes it and syncs the file.
fn fill_and_sync<F>(file: File, fill: F) -> Result<(), (AtomicWriteStep, io::Error)>
where
    F: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let mut w = BufWriter::new(file);
    fill(&mut w).map_err(|e| (AtomicWriteStep::Write, e))?;
    let file = w
        .into_inner()
        .map_err(|e| (AtomicWriteStep::Write, e.into_error()))?;
    file.sync_all().map_err(|e| (AtomicWriteStep::Sync, e))
}

/// Syncs a folder so that a rename inside it is durable. Filesystems that cannot sync a
/// folder (`EINVAL`) are not an error.
fn sync_folder(folder: &Path) -> io::Result<()> {
    match File::open(folder).and_then(|d| d.sync_all()) {
        Err(e) if e.raw_os_error() == Some(libc::EINVAL) => Ok(()),
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh, empty scratch folder for one test.
    fn scratch_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("ipc-types-files-{}-{}", name, std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Names of the files in `dir`, sorted.
    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_new_file_gets_exactly_the_content_and_no_temporary_file_is_left() {
        let dir = scratch_dir("new");
        let path = dir.join("report.json");
        write_atomic(&path, "{\n  \"a\": 1\n}\n").unwrap();
        assert_eq!(fs::read_to_string(&path).unwrap(), "{\n  \"a\": 1\n}\n");
        assert_eq!(listing(&dir), ["report.json"]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn an_existing_file_is_replaced_whole() {
        let dir = scratch_dir("replace");
        let path = dir.join("plant-report.json");
        fs::write(&path, "old content that is longer than the new one").unwrap();
        write_atomic(&path, b"new").unwrap();
        assert_eq!(fs::read(&path).unwrap(), b"new");
        write_atomic_with(&path, |w| {
            for i in 0..10_000 {
                writeln!(w, "line {i}")?;
            }
            Ok(())
        })
        .unwrap();
        let text = fs::read_to_string(&path).unwrap();
        assert_eq!(text.lines().count(), 10_000);
        assert!(text.ends_with("line 9999\n"));
        assert_eq!(listing(&dir), ["plant-report.json"]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failing_producer_leaves_the_old_file_and_no_temporary_file() {
        let dir = scratch_dir("producer-fails");
        let path = dir.join("report.json");
        fs::write(&path, "previous").unwrap();
        let err = write_atomic_with(&path, |w| {
            w.write_all(b"half of the new con")?;
            Err(io::Error::from_raw_os_error(libc::ENOSPC))
        })
        .unwrap_err();
        assert_eq!(err.step(), AtomicWriteStep::Write);
        assert_eq!(err.kind(), io::ErrorKind::StorageFull);
        assert_eq!(err.path(), path);
        let msg = err.to_string();
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(msg.contains("No space left on device"), "{msg}");
        assert_eq!(fs::read_to_string(&path).unwrap(), "previous");
        assert_eq!(listing(&dir), ["report.json"]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_missing_folder_is_an_error_naming_the_file() {
        let dir = scratch_dir("missing");
        let path = dir.join("absent").join("report.json");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert_eq!(err.step(), AtomicWriteStep::Create);
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!("writing {}: ", path.display())),
            "{msg}"
        );
        let as_io: io::Error = err.into();
        assert_eq!(as_io.kind(), io::ErrorKind::NotFound);
        assert!(as_io.to_string().contains("absent/report.json"));
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_failed_rename_removes_the_temporary_file_and_keeps_the_target() {
        let dir = scratch_dir("rename");
        // A non-empty folder cannot be replaced by a file.
        let path = dir.join("occupied");
        fs::create_dir_all(path.join("inside")).unwrap();
        let err = write_atomic(&path, b"x").unwrap_err();
        assert_eq!(err.step(), AtomicWriteStep::Rename);
        assert!(path.join("inside").is_dir());
        assert_eq!(listing(&dir), ["occupied"]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_path_without_a_file_name_is_refused() {
        let err = write_atomic("/", b"x").unwrap_err();
        assert_eq!(err.step(), AtomicWriteStep::NoFileName);
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
    }
}
