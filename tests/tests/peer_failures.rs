//! A crashed peer is detected and survived; bad configurations and mismatched contracts are
//! refused with messages that say what is wrong.

use rig_tests::*;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn scenario(dir: &TestDir, test: &str, extra_service: &str, extra: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &test_service_tables(extra_service, &static_gain_controller())
        + extra;
    dir.write("scenario.toml", &text)
}

#[test]
fn killing_the_plant_is_detected_and_a_new_plant_is_served() {
    let dir = TestDir::new("kill-plant");
    let sc = scenario(&dir, "kill-plant", "", "");
    let run_folder = dir.path.join("service-run");
    let mut service = start_service("service", &sc, &run_folder);
    let plant1 = start_lockstep_plant("plant-1", &sc, 100_000_000, &[]);
    service.wait_for_line("plant connected", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    plant1.signal(libc::SIGKILL);
    // 100 silent periods of 1 ms: detected well within the timeout.
    service.wait_for_line("PLANT SILENT", Duration::from_secs(20));

    let trace = dir.path.join("trace-2.csv");
    let mut plant2 =
        start_lockstep_plant("plant-2", &sc, 500, &["--trace", trace.to_str().unwrap()]);
    service.wait_for_line("plant resumed", Duration::from_secs(30));
    plant2.wait_success(Duration::from_secs(60));
    let (_, rows) = read_csv(&trace);
    // The new plant was controlled: every sample got the controller's answer u = −2 y.
    assert!(rows.iter().all(|r| (r[4] + 2.0 * r[2]).abs() < 1e-12));
    assert!(
        plant2.output().contains("500 actuations applied"),
        "{}",
        plant2.output()
    );

    service.signal(libc::SIGTERM);
    service.wait_success(Duration::from_secs(20));
    let report = read_json(&run_folder.join("report.json"));
    assert!(report["stats"]["plant_silent_events"].as_u64().unwrap() >= 1);
    assert!(report["stats"]["plant_resumes"].as_u64().unwrap() >= 1);
    assert_eq!(report["stop_reason"], "signal");
    // SIGTERM flushed everything logged so far: every received sample is in the CSV.
    let (_, log) = read_csv(&run_folder.join("signals.csv"));
    assert_eq!(log.len() as u64, report["log_written"].as_u64().unwrap());
    assert_eq!(
        log.len() as u64,
        report["stats"]["received"].as_u64().unwrap()
    );
}

#[test]
fn killing_the_service_puts_the_plant_into_its_safe_output_and_a_restarted_service_resumes_control()
{
    let dir = TestDir::new("kill-service");
    // fixtures/proxy-safe-output.toml: safe input 0.25 after 5 silent periods.
    let sc = scenario(&dir, "kill-service", "", &fixture("proxy-safe-output.toml"));
    let trace = dir.path.join("trace.csv");
    let report_path = dir.path.join("plant-report.json");
    let mut plant = start_lockstep_plant(
        "plant",
        &sc,
        100_000_000,
        &[
            "--trace",
            trace.to_str().unwrap(),
            "--report",
            report_path.to_str().unwrap(),
        ],
    );
    let service1 = start_service("service-1", &sc, &dir.path.join("s1"));
    service1.wait_for_line("plant connected", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    service1.signal(libc::SIGKILL);
    plant.wait_for_line("WATCHDOG", Duration::from_secs(20));

    let service2 = start_service("service-2", &sc, &dir.path.join("s2"));
    plant.wait_for_line("leaving the safe output", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(200));
    plant.signal(libc::SIGTERM);
    plant.wait_success(Duration::from_secs(30));
    drop(service2);

    let report = read_json(&report_path);
    assert!(report["watchdog_trips"].as_u64().unwrap() >= 1, "{report}");
    assert!(
        report["watchdog_recoveries"].as_u64().unwrap() >= 1,
        "{report}"
    );
    let (_, rows) = read_csv(&trace);
    let safe_rows = rows.iter().filter(|r| r[4] == 0.25).count() as u64;
    assert!(safe_rows >= report["safe_output_samples"].as_u64().unwrap());
    // After the recovery the loop is closed again: the last rows have u = −2 y.
    let tail = &rows[rows.len() - 20..];
    assert!(
        tail.iter().all(|r| (r[4] + 2.0 * r[2]).abs() < 1e-12),
        "control resumed"
    );
}

/// Runs `<program> <command> <path>` to its end and asserts that it refused, with exit
/// code 2; returns what it printed.
fn refused(program: &str, command: &str, path: &Path) -> String {
    let mut p = Proc::start(program, &bin(program), &[command, path.to_str().unwrap()]);
    assert_eq!(
        p.wait(Duration::from_secs(20)).code(),
        Some(2),
        "{}",
        p.output()
    );
    p.output()
}

#[test]
fn a_malformed_configuration_is_refused_naming_the_file_and_the_field() {
    let dir = TestDir::new("bad-config");
    let bad = scenario(&dir, "bad-config", "wait = \"sometimes\"", "");
    let out = refused("service", "check", &bad);
    assert!(
        out.contains("scenario.toml") && out.contains("sometimes"),
        "{out}"
    );

    let bad_num = scenario(&dir, "bad-config", "max-consecutive-misses = 0", "");
    let out = refused("service", "run", &bad_num);
    assert!(
        out.contains("field 'service.max-consecutive-misses'"),
        "{out}"
    );

    let bad_proxy = scenario(&dir, "bad-config", "", "[proxy]\ndeadline = 1.5\n");
    let out = refused("plant-proxy", "run", &bad_proxy);
    assert!(out.contains("proxy.deadline"), "{out}");

    let missing = dir.path.join("does-not-exist.toml");
    let out = refused("service", "check", &missing);
    assert!(out.contains("does-not-exist.toml"), "{out}");
}

/// The service expects two inputs; the plant has one.
fn mismatched_scenario(dir: &TestDir, test: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &test_service_tables(
            "channels = { y = 1, z = 1, u = 2 }",
            &fixture("two-input-static-gain-controller.toml"),
        );
    dir.write("scenario.toml", &text)
}

/// Waits until `first` prints `waiting`, then starts `second` with `start`, and asserts that
/// `second` refuses the contract of `first`, saying `mismatch`.
fn assert_second_refused(
    first: &Proc,
    waiting: &str,
    start: impl FnOnce() -> Proc,
    mismatch: &str,
) {
    first.wait_for_line(waiting, Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(200));
    let out = start().wait_failure(Duration::from_secs(30));
    assert!(out.contains("contract mismatch"), "{out}");
    assert!(out.contains(mismatch), "{out}");
}

#[test]
fn a_service_that_expects_other_channel_counts_than_the_running_plant_is_refused() {
    let dir = TestDir::new("mismatch-a");
    let sc = mismatched_scenario(&dir, "mismatch-a");
    let plant = start_lockstep_plant("plant", &sc, 100, &[]);
    assert_second_refused(
        &plant,
        "waiting for the service",
        || start_service("service", &sc, &dir.path.join("s")),
        "actuation channels (u): plant uses 1, service uses 2",
    );
}

#[test]
fn a_plant_with_other_channel_counts_than_the_running_service_is_refused() {
    let dir = TestDir::new("mismatch-b");
    let sc = mismatched_scenario(&dir, "mismatch-b");
    let service = start_service("service", &sc, &dir.path.join("s"));
    assert_second_refused(
        &service,
        "waiting for the plant",
        || start_lockstep_plant("plant", &sc, 100, &[]),
        "actuation channels (u): service uses 2, plant uses 1",
    );
}

#[test]
fn require_rt_makes_a_refused_real_time_set_up_fatal() {
    let dir = TestDir::new("require-rt");
    // Core 1000 does not exist here: pinning is refused, and require-rt turns that into an
    // error.
    let sc = scenario(&dir, "require-rt", "require-rt = true\ncore = 1000", "");
    let out =
        start_service("service", &sc, &dir.path.join("s")).wait_failure(Duration::from_secs(30));
    assert!(
        out.contains("require-rt") && out.contains("core 1000 does not exist"),
        "{out}"
    );
}
