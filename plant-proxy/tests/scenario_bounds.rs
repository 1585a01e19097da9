//! The bounds of the plant half of a scenario (issue 14): oversized or meaningless values
//! are refused naming the field, by the loader and by `plant-proxy check`, and the
//! command-line `--duration` and `--steps` are checked as `rig.duration` is.

use plant_proxy::scenario::{self, MAX_DURATION_S};
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_plant-proxy");

fn scenario_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name)
}

fn text(name: &str) -> String {
    std::fs::read_to_string(scenario_path(name)).unwrap()
}

/// For each `(from, to, field)`: `from` occurs in the scenario `name`; with its first
/// occurrence replaced by `to` the plant half is refused naming `field`.
fn assert_refused(name: &str, cases: &[(&str, &str, &str)]) {
    let base = text(name);
    for (from, to, field) in cases {
        assert!(base.contains(from), "{name}: '{from}'");
        let e =
            scenario::parse(&base.replacen(from, to, 1), "bad.toml").expect_err("must be refused");
        assert_eq!(e.field(), Some(*field), "{from} → {to}: {e}");
        assert!(
            e.to_string()
                .starts_with(&format!("bad.toml: field '{field}': ")),
            "{e}"
        );
    }
}

#[test]
fn scenario_oversized_and_meaningless_values_are_refused_naming_the_field() {
    assert_refused(
        "acoustic-rig.toml",
        &[
            ("duration = 10.0", "duration = 1e300", "rig.duration"),
            ("duration = 10.0", "duration = nan", "rig.duration"),
            ("duration = 10.0", "duration = 604801.0", "rig.duration"),
            ("y-std = 0.0035", "y-std = 1e300", "plant.noise.y-std[0]"),
            (
                "sample-period = 1.25e-4",
                "sample-period = 1e-9",
                "rig.sample-period",
            ),
            (
                "disturbances = ",
                "disturbances = 1000000000000 #",
                "plant.disturbances",
            ),
        ],
    );
}

#[test]
fn scenario_the_empty_modes_list_and_the_state_bound() {
    let base = text("acoustic-rig.toml");
    let start = base.find("modes = [").unwrap();
    let end = start + base[start..].find("\n]").unwrap() + 2;
    let empty = format!("{}modes = []{}", &base[..start], &base[end..]);
    let e = scenario::parse(&empty, "bad.toml").unwrap_err();
    assert_eq!(e.field(), Some("plant.modal.modes"), "{e}");
    assert!(e.to_string().contains("has 0 modes"), "{e}");
}

#[test]
fn scenario_command_line_durations_are_checked_as_the_file_is() {
    let s = scenario::load(&scenario_path("first-order-lockstep.toml")).unwrap();
    for bad in [
        -1.0,
        0.0,
        f64::NAN,
        f64::INFINITY,
        1e300,
        MAX_DURATION_S * 2.0,
    ] {
        let e = s.clone().with_duration(bad).unwrap_err();
        assert_eq!(e.field(), Some("rig.duration"), "{e}");
        assert!(e.to_string().contains("--duration"), "{e}");
    }
    let ok = s.clone().with_duration(2.5).unwrap();
    assert_eq!(ok.rig.duration, 2.5);
    assert_eq!(
        ok.run_steps(None).unwrap(),
        (2.5 / s.rig.sample_period).round() as u64
    );
    assert_eq!(s.run_steps(Some(7)).unwrap(), 7);
    for bad in [0, u64::MAX] {
        let e = s.run_steps(Some(bad)).unwrap_err();
        assert_eq!(e.field(), Some("rig.duration"), "{e}");
        assert!(e.to_string().contains("--steps"), "{e}");
    }
}

fn plant_proxy(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(BIN).args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn scenario_check_prints_ok_or_refuses_with_exit_code_2() {
    for name in ["acoustic-rig.toml", "truss/harmonic.toml", "siso-3-50.toml"] {
        let p = scenario_path(name);
        let (code, out, err) = plant_proxy(&["check", p.to_str().unwrap()]);
        assert_eq!(code, Some(0), "{name}: {err}");
        assert!(
            out.contains(": ok (rig '") && out.contains("states"),
            "{out}"
        );
    }
    let dir = std::env::temp_dir().join(format!("scenario-bounds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        text("first-order-lockstep.toml").replacen("[rig]", "[proxy]\ndeadline = 1.5\n[rig]", 1),
    )
    .unwrap();
    let (code, _, err) = plant_proxy(&["check", bad.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("bad.toml") && err.contains("field 'proxy.deadline'"),
        "{err}"
    );
    std::fs::write(
        &bad,
        text("first-order-lockstep.toml").replacen("duration = 2.0", "duration = 1e300", 1),
    )
    .unwrap();
    let (code, _, _) = plant_proxy(&["check", bad.to_str().unwrap()]);
    assert_eq!(code, Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn scenario_run_refuses_a_negative_duration_and_zero_steps_before_starting() {
    let p = scenario_path("first-order-lockstep.toml");
    let p = p.to_str().unwrap();
    for args in [
        vec!["run", p, "--duration=-1"],
        vec!["run", p, "--duration", "1e300"],
        vec!["run", p, "--steps", "0"],
    ] {
        let (code, _, err) = plant_proxy(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains("field 'rig.duration'"), "{args:?}: {err}");
    }
}
