//! `service check` validates the service's half of a scenario, and the command-line values of
//! `service run` are checked as the file's values are: a refusal names the file and the
//! field and exits with code 2, before anything starts.

#[path = "support/edited_scenario.rs"]
mod edited_scenario;

use edited_scenario::{Edited, scenario_path};

const BIN: &str = env!("CARGO_BIN_EXE_service");

fn service(args: &[&str]) -> (Option<i32>, String, String) {
    edited_scenario::run(BIN, args)
}

#[test]
fn config_check_accepts_every_scenario_and_summarizes_the_service_half() {
    edited_scenario::assert_check_accepts(
        BIN,
        &["acoustic-rig.toml", "truss/harmonic.toml"],
        "the service half",
    );
}

#[test]
fn config_check_refuses_the_service_half_naming_the_field() {
    let bad = Edited::new(
        "acoustic-rig.toml",
        "timing = \"send-ahead\"",
        "timing = \"sideways\"",
    );
    let (code, _, err) = service(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains(bad.path()) && err.contains("field 'service.timing'"),
        "{err}"
    );
    // The [rig] table is both halves': the schema's reader refuses it here too.
    let bad = Edited::new("acoustic-rig.toml", "duration = 10.0", "duration = 1e300");
    let (code, _, err) = service(&["check", bad.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("field 'rig.duration'"), "{err}");
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
