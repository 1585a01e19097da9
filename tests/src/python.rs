//! The Python environment of the cross-language tests (`tests/tests/python_peers.rs`): an
//! interpreter with `iceoryx2==0.10.0` and `numpy`, and the package `adaptive_rig` of
//! `ipc-types/python` on its path.
//!
//! The interpreter is `$RIG_PYTHON` when set (it must import both packages). Otherwise the
//! tests make a virtual environment at `<target dir>/py-venv` once (`python3 -m venv`, then
//! `pip install iceoryx2==0.10.0 numpy` from PyPI), under a file lock
//! (`<target dir>/py-venv.lock`, `flock`) so that two test binaries do not build it at the
//! same time; a complete environment is found by its marker file and reused. A failure is
//! a test failure with pip's output, never a skip. The package itself is not installed: every
//! Python process gets `PYTHONPATH=ipc-types/python`, so the tests run the source tree.

use crate::Proc;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

/// What the tests install from PyPI.
pub const REQUIREMENTS: [&str; 2] = ["iceoryx2==0.10.0", "numpy"];

/// The check that an interpreter has what the tests need.
const IMPORT_CHECK: &str = "import importlib.metadata as m, numpy, iceoryx2; \
     v = m.version('iceoryx2'); assert v == '0.10.0', 'iceoryx2 ' + v + ' is installed, 0.10.0 is needed'";

/// `ipc-types/python`: the package's folder.
pub fn package_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("ipc-types")
        .join("python")
}

/// `ipc-types/python/examples/<name>`.
pub fn example(name: &str) -> PathBuf {
    package_dir().join("examples").join(name)
}

/// The target folder the test executable runs from (`target/<profile>/deps/<test>` → `target`).
fn target_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    exe.ancestors()
        .nth(3)
        .expect("target/<profile>/deps/<test>")
        .to_path_buf()
}

/// Runs `command`, returning its combined output, or a message naming `what` on failure.
fn run(what: &str, command: &mut Command) -> Result<String, String> {
    let out = command
        .output()
        .map_err(|e| format!("{what}: could not start {:?}: {e}", command.get_program()))?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if out.status.success() {
        Ok(text)
    } else {
        Err(format!("{what} failed ({}):\n{text}", out.status))
    }
}

/// Checks that `python` imports iceoryx2 0.10.0 and numpy.
fn check(python: &Path, origin: &str) -> Result<(), String> {
    run(
        &format!("{origin}: {} -c <import check>", python.display()),
        Command::new(python).args(["-c", IMPORT_CHECK]),
    )
    .map(|_| ())
}

/// An exclusive `flock` on `path`, released when the returned file is dropped.
fn lock(path: &Path) -> Result<std::fs::File, String> {
    use std::os::unix::io::AsRawFd;
    let f = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(path)
        .map_err(|e| format!("opening the lock file {}: {e}", path.display()))?;
    // SAFETY: flock on a file descriptor this process owns; it blocks until granted.
    if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } != 0 {
        return Err(format!(
            "locking {}: {}",
            path.display(),
            std::io::Error::last_os_error()
        ));
    }
    Ok(f)
}

/// Makes (or finds) the virtual environment at `<target>/py-venv`; returns its python.
fn make_venv() -> Result<PathBuf, String> {
    let target = target_dir();
    let venv = target.join("py-venv");
    let python = venv.join("bin").join("python");
    let marker = venv.join(".adaptive-rig-ready");
    let _guard = lock(&target.join("py-venv.lock"))?;
    let wanted = REQUIREMENTS.join(" ");
    if std::fs::read_to_string(&marker).is_ok_and(|m| m == wanted)
        && check(&python, "the venv").is_ok()
    {
        return Ok(python);
    }
    // Built beside, then renamed into place: a half-made environment is never found.
    let tmp = target.join(format!("py-venv.tmp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    run(
        "python3 -m venv (is python3 with its venv module installed?)",
        Command::new("python3").arg("-m").arg("venv").arg(&tmp),
    )?;
    let tmp_python = tmp.join("bin").join("python");
    run(
        &format!("pip install {wanted} into {}", tmp.display()),
        Command::new(&tmp_python)
            .args([
                "-m",
                "pip",
                "install",
                "--quiet",
                "--disable-pip-version-check",
            ])
            .args(REQUIREMENTS),
    )?;
    let _ = std::fs::remove_dir_all(&venv);
    std::fs::rename(&tmp, &venv)
        .map_err(|e| format!("renaming {} to {}: {e}", tmp.display(), venv.display()))?;
    std::fs::write(&marker, &wanted).map_err(|e| format!("writing {}: {e}", marker.display()))?;
    check(&python, "the new venv")?;
    Ok(python)
}

/// The interpreter of the tests (see the module docs); panics with the reason when there is
/// none, so that a test without Python fails rather than passes unseen.
pub fn python() -> PathBuf {
    static PYTHON: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let found = PYTHON.get_or_init(|| match std::env::var_os("RIG_PYTHON") {
        Some(p) => {
            let p = PathBuf::from(p);
            check(&p, "RIG_PYTHON").map(|()| p)
        }
        None => make_venv(),
    });
    match found {
        Ok(p) => p.clone(),
        Err(e) => panic!(
            "no Python environment for the cross-language tests: {e}\n(set RIG_PYTHON to an \
             interpreter with {} installed, or let the tests make <target>/py-venv: they need \
             python3 with venv and access to PyPI)",
            REQUIREMENTS.join(" and ")
        ),
    }
}

/// A command running `python <args…>` with the package on `PYTHONPATH`.
pub fn command(args: &[&str]) -> Command {
    let mut c = Command::new(python());
    c.args(args)
        .env("PYTHONPATH", package_dir())
        .env("PYTHONUNBUFFERED", "1");
    c
}

/// Starts the example script `script` with `args` as the process `name`.
pub fn start_example(name: &str, script: &str, args: &[&str]) -> Proc {
    let path = example(script);
    let path = path.to_str().expect("UTF-8 path");
    let mut all = vec![path];
    all.extend_from_slice(args);
    Proc::spawn(name, command(&all))
}
