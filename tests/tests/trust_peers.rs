//! Only the connected peers drive the loop: one publisher and one subscriber per service, a
//! second service or plant on a rig is refused naming the process that holds it, a foreign
//! process can neither publish actuations nor take the service's place silently, and a
//! lockstep plant whose service is gone gives up instead of waiting for hours.
//!
//! Every test runs real processes (service, plant-proxy, and `trust-probe`, the foreign
//! process built from `tests/src/bin/trust-probe.rs`) in lockstep, with generous
//! timeouts; none asserts a timing.

use rig_tests::*;
use std::path::{Path, PathBuf};
use std::time::Duration;

const LONG: Duration = Duration::from_secs(60);

fn scenario(dir: &TestDir, test: &str, extra: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &test_service_tables("", &static_gain_controller())
        + extra;
    dir.write("scenario.toml", &text)
}

fn plant(name: &str, sc: &Path, steps: &str, extra: &[&str]) -> Proc {
    let mut args = vec![
        "run",
        sc.to_str().unwrap(),
        "--mode",
        "lockstep",
        "--steps",
        steps,
    ];
    args.extend_from_slice(extra);
    Proc::start(name, &bin("plant-proxy"), &args)
}

fn probe(name: &str, mode: &str, rig: &str, secs: &str) -> Proc {
    Proc::start(name, &bin("trust-probe"), &[mode, rig, secs])
}

#[test]
fn a_second_service_on_a_served_rig_is_refused_naming_the_pid_that_serves_it() {
    let dir = TestDir::new("trust-second-service");
    let sc = scenario(&dir, "trust-second-service", "");
    let _plant = plant("plant", &sc, "100000000", &[]);
    let first = start_service("service-1", &sc, &dir.path.join("s1"));
    first.wait_for_line("plant connected", LONG);
    let mut second = start_service("service-2", &sc, &dir.path.join("s2"));
    let st = second.wait(LONG);
    assert!(!st.success(), "the second service must be refused");
    let out = second.output();
    assert!(
        out.contains(&format!("is already served by pid {}", first.child.id())),
        "{out}"
    );
    assert!(out.contains("refusing to start a second service"), "{out}");
}

#[test]
fn a_second_plant_on_a_rig_is_refused_naming_the_first_plant() {
    let dir = TestDir::new("trust-second-plant");
    let sc = scenario(&dir, "trust-second-plant", "");
    let first = plant("plant-1", &sc, "100", &[]);
    first.wait_for_line("waiting for the service", LONG);
    let mut second = plant("plant-2", &sc, "100", &[]);
    assert!(!second.wait(LONG).success());
    let out = second.output();
    assert!(
        out.contains(&format!("already has a plant: pid {}", first.child.id())),
        "{out}"
    );
}

#[test]
fn a_rogue_publisher_cannot_publish_actuations_and_the_loop_stays_closed() {
    let dir = TestDir::new("trust-rogue-pub");
    let rig = rig_name("trust-rogue-pub");
    let sc = scenario(&dir, "trust-rogue-pub", "");
    let trace = dir.path.join("trace.csv");
    let report = dir.path.join("plant-report.json");
    let mut plant = plant(
        "plant",
        &sc,
        "100000000",
        &[
            "--trace",
            trace.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
        ],
    );
    let service = start_service("service", &sc, &dir.path.join("s"));
    service.wait_for_line("plant connected", LONG);
    let mut rogue = probe("rogue", "publish", &rig, "1");
    assert_eq!(rogue.wait(LONG).code(), Some(3), "{}", rogue.output());
    assert!(
        rogue.output().contains("ExceedsMaxSupportedPublishers"),
        "{}",
        rogue.output()
    );
    std::thread::sleep(Duration::from_millis(200));
    plant.signal(libc::SIGTERM);
    assert!(plant.wait(LONG).success(), "{}", plant.output());
    let r = read_json(&report);
    assert_eq!(r["foreign_discarded"], 0, "{r}");
    assert_eq!(r["new_services"], 0, "{r}");
    assert_eq!(r["service_pid"], service.child.id(), "{r}");
    let (_, rows) = read_csv(&trace);
    assert!(!rows.is_empty());
    // Every applied input is the service's u = −2 y: nothing of the rogue's u = 50.
    assert!(rows.iter().all(|row| (row[4] + 2.0 * row[2]).abs() < 1e-12));
}

#[test]
fn a_rogue_subscriber_in_the_service_slot_makes_the_service_refuse_naming_it() {
    let dir = TestDir::new("trust-rogue-sub");
    let rig = rig_name("trust-rogue-sub");
    let sc = scenario(&dir, "trust-rogue-sub", "");
    let plant = plant("plant", &sc, "100", &[]);
    plant.wait_for_line("waiting for the service", LONG);
    let rogue = probe("rogue", "subscribe", &rig, "120");
    rogue.wait_for_line("trust-probe: subscribed", LONG);
    let mut service = start_service("service", &sc, &dir.path.join("s"));
    assert!(!service.wait(LONG).success());
    let out = service.output();
    assert!(
        out.contains(&format!(
            "/measurement' admits one subscriber, the service's, and pid {}",
            rogue.child.id()
        )),
        "{out}"
    );
    assert!(out.contains("node 'trust-probe'"), "{out}");
    assert!(!out.contains("ExceedsMaxSupportedSubscribers"), "{out}");
}

#[test]
fn a_lockstep_plant_whose_service_is_gone_gives_up_after_its_watchdog_with_a_failure_status() {
    let dir = TestDir::new("trust-give-up");
    // Watchdog after 5 × 20 ms, then 2 s for a service to come back.
    let sc = scenario(
        &dir,
        "trust-give-up",
        &(fixture("proxy-safe-output.toml") + "peer-timeout = 2.0\n"),
    );
    // The service first: the plant waits only proxy.peer-timeout = 2 s for it.
    let service = start_service("service", &sc, &dir.path.join("s"));
    service.wait_for_line("waiting for the plant", LONG);
    let mut plant = plant("plant", &sc, "100000000", &[]);
    service.wait_for_line("plant connected", LONG);
    std::thread::sleep(Duration::from_millis(200));
    service.signal(libc::SIGKILL);
    plant.wait_for_line("WATCHDOG", LONG);
    let st = plant.wait(LONG);
    assert!(!st.success(), "{}", plant.output());
    let out = plant.output();
    assert!(out.contains("giving up in lockstep"), "{out}");
    assert!(out.contains("the service is gone"), "{out}");
}

#[test]
fn a_plant_of_another_user_is_refused_with_permission_denied() {
    // Needs root to act as another user; elsewhere there is nothing to show.
    // SAFETY: getuid has no preconditions.
    if unsafe { libc::getuid() } != 0 || !Path::new("/usr/bin/setpriv").exists() {
        eprintln!("skipped: needs root and setpriv to run a process as another user");
        return;
    }
    let dir = TestDir::new("trust-other-user");
    let sc = scenario(&dir, "trust-other-user", "");
    // This test's own service makes sure root's iceoryx2 folders exist.
    let _service = start_service("service", &sc, &dir.path.join("s"));
    _service.wait_for_line("waiting for the plant", LONG);
    // TestDir is root's; the scenario must be readable by nobody.
    let shared = std::env::temp_dir().join(format!("trust-other-user-{}.toml", std::process::id()));
    std::fs::copy(&sc, &shared).unwrap();
    let plant_bin = bin("plant-proxy");
    let mut p = Proc::start(
        "plant-as-nobody",
        Path::new("/usr/bin/setpriv"),
        &[
            "--reuid=65534",
            "--regid=65534",
            "--clear-groups",
            plant_bin.to_str().unwrap(),
            "run",
            shared.to_str().unwrap(),
            "--mode",
            "lockstep",
            "--steps",
            "10",
        ],
    );
    let st = p.wait(LONG);
    let _ = std::fs::remove_file(&shared);
    assert!(!st.success());
    let out = p.output();
    assert!(out.contains("permission denied"), "{out}");
    assert!(!out.contains("iceoryx2 failure"), "{out}");
}
