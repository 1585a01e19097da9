//! The command-line checks' tests shared by the service's (`service check`) and the
//! tools' (`rig check`) tests (`#[path]`-included): a scenario of `scenarios/` edited for a
//! refusal, and the acceptance of the unedited ones.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the program `bin` with `args`: its exit code, stdout and stderr.
pub fn run(bin: &str, args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(bin).args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The scenario `name` of the repository's `scenarios/`.
pub fn scenario_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .ancestors()
        .find(|d| d.join("scenarios").is_dir() && d.join("Cargo.lock").is_file())
        .expect("the repository root")
        .join("scenarios")
        .join(name)
}

/// A temporary copy of the scenario `name` with `from` replaced by `to`, next to the
/// original (so that relative file names still resolve).
pub struct Edited(PathBuf);

impl Edited {
    /// The copy of `name` with `from` replaced by `to`.
    pub fn new(name: &str, from: &str, to: &str) -> Self {
        let src = scenario_path(name);
        let text = std::fs::read_to_string(&src).unwrap();
        assert!(text.contains(from), "{name}: '{from}'");
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = src.with_file_name(format!("config-cli-{}-{n}.toml", std::process::id()));
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
        Self(path)
    }

    /// The copy's path.
    pub fn path(&self) -> &str {
        self.0.to_str().unwrap()
    }
}

impl Drop for Edited {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

/// `<bin> check` accepts each scenario of `names` (and the first with the controller file
/// `rcac/acoustic-rls.toml`), printing `ok` with the rig and `summary`; a scenario without
/// a `[controller]` table is refused naming it, with exit code 2.
pub fn assert_check_accepts(bin: &str, names: &[&str], summary: &str) {
    for name in names {
        let (code, out, err) = run(bin, &["check", scenario_path(name).to_str().unwrap()]);
        assert_eq!(code, Some(0), "{name}: {err}");
        assert!(
            out.contains(": ok (rig '") && out.contains(summary),
            "{name}: {out}"
        );
    }
    let (code, out, err) = run(
        bin,
        &[
            "check",
            scenario_path(names[0]).to_str().unwrap(),
            "--controller",
            scenario_path("rcac/acoustic-rls.toml").to_str().unwrap(),
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("controller rcac"), "{out}");
    let plant_only = scenario_path("first-order-lockstep.toml");
    let (code, _, err) = run(bin, &["check", plant_only.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("field 'controller'"), "{err}");
}
