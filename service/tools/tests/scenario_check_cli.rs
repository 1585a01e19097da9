//! `rig check` validates both halves of a scenario and the two against each other: a
//! refusal names the file and the field and exits with code 2.

#[path = "../../tests/support/edited_scenario.rs"]
mod edited_scenario;

use edited_scenario::Edited;

const BIN: &str = env!("CARGO_BIN_EXE_rig");

fn rig(args: &[&str]) -> (Option<i32>, String, String) {
    edited_scenario::run(BIN, args)
}

#[test]
fn rig_check_accepts_every_scenario_and_summarizes_both_halves() {
    edited_scenario::assert_check_accepts(
        BIN,
        &[
            "acoustic-rig.toml",
            "truss/harmonic.toml",
            "truss/broadband-25hz.toml",
            "truss/broadband-50hz-aliasing.toml",
        ],
        "; plant ",
    );
}

#[test]
fn rig_check_refuses_the_plant_half_naming_the_field() {
    let bad = Edited::new("acoustic-rig.toml", "duration = 10.0", "duration = 1e300");
    let (code, _, err) = rig(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(bad.path()) && err.contains("field 'rig.duration'"),
        "{err}"
    );
    let bad = Edited::new("acoustic-rig.toml", "deadline = 0.0", "deadline = 2.0");
    let (code, _, err) = rig(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("field 'proxy.deadline'"), "{err}");
    // The halves must meet: a plant that latches its inputs at the sample instant needs a
    // service that sends them ahead.
    let bad = Edited::new(
        "acoustic-rig.toml",
        "timing = \"send-ahead\"",
        "timing = \"answer-first\"",
    );
    let (code, _, err) = rig(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("field 'proxy.deadline'") && err.contains("only a service that sends ahead"),
        "{err}"
    );
}
