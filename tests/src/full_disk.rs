//! A real full filesystem for the tests of what the run folder's writers do when the disk
//! fills: a small tmpfs mounted for the test (as root), and checks that a file holds only
//! whole records.
//!
//! Mounting needs root (CI runs as root). Where mounting is not permitted the tests that
//! use it fail with a loud message, unless `OUTPUTS_ALLOW_NO_MOUNT=1` is set: then they
//! say so and pass without running.

use hdrhistogram::serialization::interval_log::{IntervalLogIterator, LogEntry};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Set to 1 to let the full-disk tests pass without running where mounting is refused.
pub const ALLOW_NO_MOUNT_VAR: &str = "OUTPUTS_ALLOW_NO_MOUNT";

/// A tmpfs of `size` mounted on a fresh folder; unmounted and removed on drop (also when
/// the test panics).
pub struct Tmpfs {
    /// The mount point.
    pub dir: PathBuf,
}

impl Tmpfs {
    /// Mounts the tmpfs, or returns why it could not.
    pub fn mount(name: &str, size: &str) -> Result<Tmpfs, String> {
        let dir =
            std::env::temp_dir().join(format!("outputs-full-disk-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(&dir)
            .output()
            .map_err(|e| format!("running mount: {e}"));
        match out {
            Ok(o) if o.status.success() => Ok(Tmpfs { dir }),
            Ok(o) => {
                let _ = std::fs::remove_dir(&dir);
                Err(format!(
                    "mount -t tmpfs -o size={size} tmpfs {} failed ({}, euid {}): {}",
                    dir.display(),
                    o.status,
                    // SAFETY: geteuid has no preconditions and cannot fail.
                    unsafe { libc::geteuid() },
                    String::from_utf8_lossy(&o.stderr).trim()
                ))
            }
            Err(e) => {
                let _ = std::fs::remove_dir(&dir);
                Err(e)
            }
        }
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let ok = Command::new("umount")
            .arg(&self.dir)
            .status()
            .is_ok_and(|s| s.success());
        if !ok {
            // Something still holds it open: detach it lazily.
            let _ = Command::new("umount").arg("-l").arg(&self.dir).status();
        }
        let _ = std::fs::remove_dir(&self.dir);
    }
}

/// Mounts a tmpfs or, when that is not permitted, fails loudly, or returns `None` when
/// `OUTPUTS_ALLOW_NO_MOUNT=1` allows skipping.
pub fn mount_or_skip(name: &str, size: &str) -> Option<Tmpfs> {
    match Tmpfs::mount(name, size) {
        Ok(t) => Some(t),
        Err(why) => {
            let banner = "!".repeat(78);
            eprintln!(
                "{banner}\nFULL-DISK TEST NOT RUN: cannot mount a tmpfs: {why}\n\
                 This test needs root (or CAP_SYS_ADMIN). Set {ALLOW_NO_MOUNT_VAR}=1 to \
                 skip it knowingly.\n{banner}"
            );
            if std::env::var(ALLOW_NO_MOUNT_VAR).as_deref() == Ok("1") {
                eprintln!("{ALLOW_NO_MOUNT_VAR}=1: skipping the full-disk test");
                None
            } else {
                panic!("cannot mount a tmpfs for the full-disk test: {why}");
            }
        }
    }
}

/// The `seq` column of the `signals.csv` at `path`, whose rows must all be whole
/// ([`service::logging::whole_rows`]).
pub fn whole_rows(path: &Path) -> Vec<u64> {
    let text = std::fs::read_to_string(path).unwrap();
    service::logging::whole_rows(&text).unwrap_or_else(|e| panic!("{} {e}", path.display()))
}

/// An interval log parses completely and ends with a line end; returns its intervals.
pub fn whole_log(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.ends_with(b"\n"),
        "{} ends in a torn line",
        path.display()
    );
    IntervalLogIterator::new(&bytes)
        .filter(|e| {
            matches!(
                e.as_ref()
                    .unwrap_or_else(|e| panic!("{}: {e:?}", path.display())),
                LogEntry::Interval(_)
            )
        })
        .count()
}
