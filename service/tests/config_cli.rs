//! `service check` validates both halves of a scenario, and the command-line values of
//! `service run` are checked as the file's values are: a refusal names the file and the
//! field and exits with code 2, before anything starts.

use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_service");

fn scenario_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name)
}

fn service(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(BIN).args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A temporary copy of the scenario `name` with `from` replaced by `to`, next to the
/// original (so that relative file names still resolve).
struct Edited(PathBuf);

impl Edited {
    fn new(name: &str, from: &str, to: &str) -> Self {
        let src = scenario_path(name);
        let text = std::fs::read_to_string(&src).unwrap();
        assert!(text.contains(from), "{name}: '{from}'");
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = src.with_file_name(format!("config-cli-{}-{n}.toml", std::process::id()));
        std::fs::write(&path, text.replacen(from, to, 1)).unwrap();
        Self(path)
    }

    fn path(&self) -> &str {
        self.0.to_str().unwrap()
    }
}

impl Drop for Edited {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[test]
fn config_check_accepts_every_scenario_and_summarizes_both_halves() {
    for name in [
        "acoustic-rig.toml",
        "truss/harmonic.toml",
        "truss/broadband-25hz.toml",
        "truss/broadband-50hz-aliasing.toml",
    ] {
        let (code, out, err) = service(&["check", scenario_path(name).to_str().unwrap()]);
        assert_eq!(code, Some(0), "{name}: {err}");
        assert!(
            out.contains(": ok (rig '") && out.contains("; plant "),
            "{name}: {out}"
        );
    }
    // With a controller file.
    let (code, out, err) = service(&[
        "check",
        scenario_path("acoustic-rig.toml").to_str().unwrap(),
        "--controller",
        scenario_path("rcac/acoustic-rls.toml").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("controller rcac"), "{out}");
    // A plant-only scenario has no service half.
    let (code, _, err) = service(&[
        "check",
        scenario_path("first-order-lockstep.toml").to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("field 'controller'"), "{err}");
}

#[test]
fn config_check_refuses_the_plant_half_naming_the_field() {
    let bad = Edited::new("acoustic-rig.toml", "duration = 10.0", "duration = 1e300");
    let (code, _, err) = service(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(bad.path()) && err.contains("field 'rig.duration'"),
        "{err}"
    );
    let bad = Edited::new("acoustic-rig.toml", "deadline = 0.0", "deadline = 2.0");
    let (code, _, err) = service(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("field 'proxy.deadline'"), "{err}");
    // The halves must meet: a plant that latches its inputs at the sample instant needs a
    // service that sends them ahead.
    let bad = Edited::new(
        "acoustic-rig.toml",
        "timing = \"send-ahead\"",
        "timing = \"answer-first\"",
    );
    let (code, _, err) = service(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("field 'proxy.deadline'") && err.contains("only a service that sends ahead"),
        "{err}"
    );
}

#[test]
fn config_run_checks_command_line_values_before_starting() {
    let p = scenario_path("acoustic-rig.toml");
    let p = p.to_str().unwrap();
    for (args, field) in [
        (vec!["run", p, "--max-cycles", "0"], "--max-cycles"),
        (
            vec!["run", p, "--max-cycles", "18446744073709551615"],
            "--max-cycles",
        ),
        (vec!["run", p, "--core", "100000"], "service.core"),
    ] {
        let (code, _, err) = service(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains(&format!("field '{field}'")), "{args:?}: {err}");
    }
}

/// `service check-system` prints one line per check for the RT core of a scenario (or
/// `--core`), each naming its check and marked ok, FIX (with its fix) or ?? (unreadable),
/// and exits 0; a refused scenario is refused as `check` refuses it.
#[test]
fn check_system_prints_one_line_per_check_and_its_fix() {
    let acoustic = scenario_path("acoustic-rig.toml");
    for args in [
        vec!["check-system", acoustic.to_str().unwrap()],
        vec!["check-system", "--core", "0"],
    ] {
        let (code, out, err) = service(&args);
        assert_eq!(code, Some(0), "{args:?}: {err}");
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), 10, "{out}");
        for (line, check) in lines.iter().zip([
            "preemption",
            "isolated core",
            "rt throttling",
            "cpu governor",
            "smt sibling",
            "irq affinity",
            "swap",
            "transparent huge pages",
            "privileges",
            "shared rt core",
        ]) {
            assert!(line.contains(&format!("{check}: ")), "{line}");
            let fix = line.starts_with("FIX ");
            assert!(
                fix || line.starts_with("ok ") || line.starts_with("?? "),
                "{line}"
            );
            assert_eq!(fix, line.contains(" — fix: "), "{line}");
        }
    }
    let (code, _, err) = service(&["check-system", "/no/such/scenario.toml"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("/no/such/scenario.toml"), "{err}");
}
