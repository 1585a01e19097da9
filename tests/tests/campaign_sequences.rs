//! The fault campaign of issue 14, what the plant side sends (docs/faults.md): malformed
//! sequence numbers, a foreign actuation reported by the plant, and a run that ends in
//! the safe state.
//!
//! The plant side is `scripted_plant` (`tests/src/bin/scripted_plant.rs`): it sends exactly
//! the samples of a script in lockstep and writes which ones were answered. The controller
//! is an integrator that does not act (`x⁺ = x + y`, `u = −2 y`): its state `x0` in
//! `signals.csv` is the sum of every `y` it has seen since its last reset, so it tells
//! exactly which samples reached it and whether it was reset. No test asserts a timing.

use ipc_types::actuation_status::SAFE_STATE;
use rig_tests::*;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::time::Duration;

/// `[log]` and `[service]` of the campaign (see campaign_stalls.rs); `service_extra` adds
/// `[service]` keys.
fn service_tables(service_extra: &str) -> String {
    format!(
        "\n{}{service_extra}\n",
        fixture("campaign-service-tables.toml")
    )
}

/// One run of the service (`--exit-with-plant`) against `scripted_plant` with `script`.
struct ScriptedRun {
    /// The service's run folder.
    run_folder: PathBuf,
    /// The service's exit status.
    status: ExitStatus,
    /// What the service printed on stderr (events).
    stderr: String,
    /// What it printed on stdout (the run report).
    stdout: String,
    /// `report.json`.
    report: serde_json::Value,
    /// The scripted plant's account: which samples were answered.
    plant: serde_json::Value,
}

/// Runs the service on the first-order rig with `service_extra` against the scripted plant
/// playing `script`; both must end by themselves.
fn scripted_run(dir: &TestDir, test: &str, service_extra: &str, script: &str) -> ScriptedRun {
    let rig = rig_name(test);
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig)
        + &service_tables(service_extra)
        + &fixture("integrator-controller.toml");
    let sc = dir.write("scenario.toml", &text);
    let script = dir.write("script.txt", script);
    let run_folder = dir.path.join("service-run");
    let stdout_path = dir.path.join("service-stdout.txt");
    // Through `sh -c 'exec …'` so that the report on stdout lands in a file of its own
    // while the events on stderr are watched; the pid is the service's.
    let cmd = format!(
        "exec '{}' run '{}' --run-folder '{}' --exit-with-plant > '{}'",
        bin("service").display(),
        sc.display(),
        run_folder.display(),
        stdout_path.display()
    );
    let mut svc = Proc::start("service", Path::new("/bin/sh"), &["-c", &cmd]);
    svc.wait_for_line("waiting for the plant", Duration::from_secs(30));
    let plant_out = dir.path.join("plant.json");
    let mut plant = Proc::start(
        "scripted-plant",
        Path::new(env!("CARGO_BIN_EXE_scripted_plant")),
        &[&rig, script.to_str().unwrap(), plant_out.to_str().unwrap()],
    );
    plant.wait_success(Duration::from_secs(120));
    let status = svc.wait(Duration::from_secs(60));
    let stdout = std::fs::read_to_string(&stdout_path).expect("the service's stdout");
    ScriptedRun {
        report: read_json(&run_folder.join("report.json")),
        plant: read_json(&plant_out),
        run_folder,
        status,
        stderr: svc.output(),
        stdout,
    }
}

fn stat(report: &serde_json::Value, name: &str) -> u64 {
    report["stats"][name]
        .as_u64()
        .unwrap_or_else(|| panic!("no stats.{name} in the report"))
}

/// The `seq`, `y0` and `x0` columns of `signals.csv`.
fn logged(run_folder: &Path) -> Vec<(f64, f64, f64)> {
    let (header, rows) = read_csv(&run_folder.join("signals.csv"));
    let (seq, y0, x0) = (
        column(&header, "seq"),
        column(&header, "y0"),
        column(&header, "x0"),
    );
    rows.iter().map(|r| (r[seq], r[y0], r[x0])).collect()
}

/// Whether the service's exit status says the run failed (status 1). The service sets it
/// from the verdict (service/src/main.rs).
fn assert_exit_status_1(run: &ScriptedRun) {
    assert_eq!(
        run.status.code(),
        Some(1),
        "a failed verdict must give exit status 1; the service exited with {:?}",
        run.status
    );
}

#[test]
fn duplicate_backward_and_far_jumping_sequence_numbers_are_refused_unanswered_and_counted_and_the_stream_goes_on_without_a_reset()
 {
    let dir = TestDir::new("campaign-malformed-seq");
    // Every refused sample says y = 1000: had one reached the controller, its state would
    // show it. The plant waits only 150 ms for an answer to those; silence would take 2 s.
    let mut script = String::new();
    let mut expected: Vec<(u64, bool)> = Vec::new(); // (seq, refused)
    let good = |script: &mut String, expected: &mut Vec<(u64, bool)>, a: u64, b: u64| {
        script.push_str(&format!("{a}..{b}\n"));
        expected.extend((a..b).map(|k| (k, false)));
    };
    let bad = |script: &mut String, expected: &mut Vec<(u64, bool)>, k: u64, why: &str| {
        script.push_str(&format!("{k} y=1000 wait=150 # {why}\n"));
        expected.push((k, true));
    };
    good(&mut script, &mut expected, 0, 51);
    bad(&mut script, &mut expected, 50, "duplicate");
    good(&mut script, &mut expected, 51, 60);
    bad(&mut script, &mut expected, 55, "backward");
    good(&mut script, &mut expected, 60, 70);
    bad(
        &mut script,
        &mut expected,
        1_000_000_069,
        "a jump the clock cannot explain",
    );
    // seq 0 every 20 samples (the rogue of issue 14 reset RCAC eleven times so).
    for block in 0..6 {
        let a = 70 + 20 * block;
        good(&mut script, &mut expected, a, a + 20);
        bad(&mut script, &mut expected, 0, "seq 0 again");
    }
    good(&mut script, &mut expected, 190, 299);
    script.push_str("299 last\n");
    expected.push((299, false));

    let run = scripted_run(&dir, "malformed", "silent-periods = 2000", &script);

    // The plant's side: exactly the refused samples went unanswered.
    let samples = run.plant["samples"].as_array().expect("samples");
    assert_eq!(samples.len(), expected.len());
    for (s, (seq, refused)) in samples.iter().zip(&expected) {
        assert_eq!(s["seq"].as_u64(), Some(*seq));
        assert_eq!(
            s["answered"].as_bool(),
            Some(!refused),
            "sample {seq} (refused expected: {refused}): {s}"
        );
    }
    // The service's side: each refused sample counted by its fault.
    let r = &run.report;
    assert_eq!(stat(r, "rejected_duplicate"), 1, "{r}");
    assert_eq!(stat(r, "rejected_backward"), 7, "{r}");
    assert_eq!(stat(r, "rejected_jump"), 1, "{r}");
    assert_eq!(stat(r, "received"), 309, "{r}");
    assert_eq!(stat(r, "published"), 300, "{r}");
    assert_eq!(stat(r, "new_sessions"), 0, "{r}");
    assert_eq!(stat(r, "plant_silent_events"), 0, "{r}");
    assert!(!run.stderr.contains("NEW PLANT SESSION"), "{}", run.stderr);
    // The stream went on: every good sample answered in order, to the last one.
    let rows = logged(&run.run_folder);
    let seqs: Vec<f64> = rows.iter().map(|r| r.0).collect();
    assert_eq!(seqs, (0..300).map(|k| k as f64).collect::<Vec<_>>());
    assert!(
        rows.iter().all(|r| r.1 == 1.0),
        "a refused sample was logged"
    );
    // The controller saw the 300 good samples and nothing else, and was never reset.
    assert_eq!(rows.last().unwrap().2, 300.0, "integrator state at the end");
    assert_eq!(samples.last().unwrap()["u"].as_f64(), Some(-2.0));
    assert_eq!(
        run.report["verdict"]["ok"], true,
        "{}",
        run.report["verdict"]
    );
}

#[test]
fn a_plant_that_reports_applying_an_input_the_service_did_not_send_raises_foreign_actuation_and_fails_the_run()
 {
    let dir = TestDir::new("campaign-foreign-u");
    // From sample 100 on, the plant says it applied the service's input plus 0.5.
    let run = scripted_run(
        &dir,
        "foreign-u",
        "",
        "0..100\n100..200 u-offset=0.5 last\n",
    );
    let alarms = run
        .stderr
        .lines()
        .filter(|l| l.contains("FOREIGN ACTUATION at seq"))
        .collect::<Vec<_>>();
    assert_eq!(
        alarms.len(),
        1,
        "one alarm for the run of mismatches: {alarms:?}"
    );
    assert!(alarms[0].contains("at seq 100"), "{}", alarms[0]);
    let r = &run.report;
    assert_eq!(stat(r, "foreign_actuations"), 100, "{r}");
    assert_eq!(r["verdict"]["ok"], false, "{}", r["verdict"]);
    let failures = r["verdict"]["failures"].as_array().unwrap();
    assert!(
        failures
            .iter()
            .any(|f| f.as_str().unwrap().starts_with("FOREIGN ACTUATION")),
        "{failures:?}"
    );
    assert!(run.stdout.contains("verdict: FAILED"), "{}", run.stdout);
    assert_exit_status_1(&run);
}

#[test]
fn a_run_that_ends_in_the_safe_state_fails_its_verdict_and_says_so_last() {
    let dir = TestDir::new("campaign-ends-safe");
    // From sample 100 on the plant reports every actuation missed; 5 in a row enter the
    // safe state, and without recover-after it is kept for the session.
    let run = scripted_run(
        &dir,
        "ends-safe",
        "max-consecutive-misses = 5",
        "0..100\n100..300 missed last\n",
    );
    assert!(run.stderr.contains("SAFE STATE at seq"), "{}", run.stderr);
    let samples = run.plant["samples"].as_array().unwrap();
    let last = samples.last().unwrap();
    assert_eq!(
        last["status"].as_u64().unwrap() & u64::from(SAFE_STATE),
        u64::from(SAFE_STATE),
        "{last}"
    );
    assert_eq!(last["u"].as_f64(), Some(0.0), "the safe input: {last}");
    let v = &run.report["verdict"];
    assert_eq!(v["ok"], false, "{v}");
    let first = v["failures"][0].as_str().unwrap_or("");
    assert!(first.starts_with("ENDED IN SAFE STATE"), "{v}");
    let last_line = run
        .stdout
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    assert!(
        last_line.starts_with("verdict: FAILED"),
        "the printed report ends with: {last_line}\n{}",
        run.stdout
    );
    assert!(last_line.contains("ENDED IN SAFE STATE"), "{last_line}");
    assert_exit_status_1(&run);
}
