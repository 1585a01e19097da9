//! `rig launch` ends as its children did: each child's exit status is recorded as its own
//! stop reason (one `[launch] <child>: …` line each on stderr, and `launch.json` in the run
//! folder), and the launch exits non-zero when a peer died or refused, or when the
//! service's run verdict failed; the children do not outlive a killed launcher
//! (`PR_SET_PDEATHSIG`). Also: a lockstep plant that gives up still reports.
//!
//! Every test runs `target/<profile>/rig launch` (built by `cargo build --release
//! --workspace`) on the first-order rig in lockstep, with its own rig name; the faults are
//! signals and configurations, and no test asserts a timing.

use rig_tests::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const LONG: Duration = Duration::from_secs(120);

/// The first-order lockstep scenario with the tests' service tables (`extra_service` added
/// to `[service]`), the static gain controller, then `extra`.
fn scenario(dir: &TestDir, test: &str, extra_service: &str, extra: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &test_service_tables(extra_service, &static_gain_controller())
        + extra;
    dir.write("scenario.toml", &text)
}

/// Starts `rig launch <sc> --mode lockstep --run-folder <dir>/run <extra…>`; returns the
/// process and the run folder.
fn launch(dir: &TestDir, sc: &Path, extra: &[&str]) -> (Proc, PathBuf) {
    let run = dir.path.join("run");
    let mut args = vec![
        "launch",
        sc.to_str().unwrap(),
        "--mode",
        "lockstep",
        "--run-folder",
        run.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    (Proc::start("rig", &bin("rig"), &args), run)
}

/// `launch.json` of a run folder.
fn record(run: &Path) -> Value {
    read_json(&run.join("launch.json"))
}

/// Fields 3.. of `/proc/<pid>/stat` (after the command name), and the command name.
fn stat(pid: u32) -> Option<(String, Vec<String>)> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let open = text.find('(')?;
    let close = text.rfind(')')?;
    let comm = text[open + 1..close].to_string();
    let rest = text[close + 1..]
        .split_whitespace()
        .map(str::to_string)
        .collect();
    Some((comm, rest))
}

/// The pid of the child of `parent` whose command name is `comm`, once it exists.
fn child_named(parent: u32, comm: &str, timeout: Duration) -> u32 {
    let deadline = Instant::now() + timeout;
    loop {
        for entry in std::fs::read_dir("/proc").expect("/proc").flatten() {
            let Some(pid) = entry.file_name().to_str().and_then(|s| s.parse().ok()) else {
                continue;
            };
            if let Some((c, rest)) = stat(pid)
                && c == comm
                && rest.get(1).and_then(|p| p.parse::<u32>().ok()) == Some(parent)
            {
                return pid;
            }
        }
        assert!(
            Instant::now() < deadline,
            "no child '{comm}' of pid {parent} appeared"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A process by its pid and start time (field 22 of its stat), so that a reused pid is not
/// taken for it.
struct Watched {
    pid: u32,
    started: String,
}

impl Watched {
    fn new(pid: u32) -> Self {
        let (_, rest) = stat(pid).unwrap_or_else(|| panic!("pid {pid} is not running"));
        Self {
            pid,
            started: rest[19].clone(),
        }
    }

    /// Still running: it exists, is not a zombie, and is the same process.
    fn running(&self) -> bool {
        match stat(self.pid) {
            Some((_, rest)) => rest[0] != "Z" && rest[0] != "X" && rest[19] == self.started,
            None => false,
        }
    }
}

#[test]
fn a_normal_lockstep_launch_exits_0_and_records_both_children_exiting_0() {
    let dir = TestDir::new("launch-ok");
    let sc = scenario(&dir, "launch-ok", "", "");
    let (mut rig, run) = launch(&dir, &sc, &["--duration", "0.2"]);
    let st = rig.wait(LONG);
    assert_eq!(st.code(), Some(0), "{}", rig.output());
    let out = rig.output();
    assert!(out.contains("[launch] service: exit 0"), "{out}");
    assert!(out.contains("[launch] plant-proxy: exit 0"), "{out}");
    let r = record(&run);
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["exit_code"], 0, "{r}");
    assert_eq!(r["failure"], Value::Null, "{r}");
    assert_eq!(r["launcher_signal"], Value::Null, "{r}");
    for name in ["service", "plant-proxy"] {
        let c = &r["children"][name];
        assert_eq!(c["exit_code"], 0, "{name}: {r}");
        assert_eq!(c["signal"], Value::Null, "{name}: {r}");
        assert_eq!(c["stopped_by_launcher"], false, "{name}: {r}");
        assert_eq!(c["clean"], true, "{name}: {r}");
    }
    // The service ended with the plant, at its last sample.
    let report = read_json(&run.join("report.json"));
    assert_eq!(report["stop_reason"], "plant-ended", "{report}");
    assert_eq!(read_json(&run.join("plant-report.json"))["samples"], 200);
    // The system check is part of every report, one finding per check.
    let system = report["system"].as_array().expect("system findings");
    assert_eq!(system.len(), 10, "{report}");
    assert_eq!(system[0]["check"], "preemption", "{report}");
}

#[test]
fn a_plant_that_refuses_its_configuration_fails_the_launch_with_the_plants_reason() {
    let dir = TestDir::new("launch-refused");
    // The plant half is invalid (proxy.deadline must be below 1); the service half is
    // valid, so the launcher starts both and the plant refuses.
    let sc = scenario(&dir, "launch-refused", "", "\n[proxy]\ndeadline = 1.5\n");
    let (mut rig, run) = launch(&dir, &sc, &["--duration", "0.2"]);
    let st = rig.wait(LONG);
    assert_eq!(st.code(), Some(1), "{}", rig.output());
    let out = rig.output();
    // The plant's own reason, naming the field, then the launcher's account of it.
    assert!(out.contains("proxy.deadline"), "{out}");
    assert!(
        out.contains("[launch] plant-proxy: exit 2 (refused its configuration)"),
        "{out}"
    );
    assert!(
        out.contains("rig: plant-proxy did not end cleanly: exit 2"),
        "{out}"
    );
    let r = record(&run);
    assert_eq!(r["ok"], false, "{r}");
    assert_eq!(r["exit_code"], 1, "{r}");
    let plant = &r["children"]["plant-proxy"];
    assert_eq!(plant["exit_code"], 2, "{r}");
    assert_eq!(plant["stopped_by_launcher"], false, "{r}");
    // The service, waiting for a plant that never came, was stopped by the launcher.
    let service = &r["children"]["service"];
    assert_eq!(service["stopped_by_launcher"], true, "{r}");
    assert!(
        service["stop_reason"]
            .as_str()
            .unwrap()
            .contains("the plant ended"),
        "{r}"
    );
    assert!(
        service["signal"].is_null(),
        "the service ended by itself: {r}"
    );
}

#[test]
fn an_invalid_duration_is_refused_by_the_plant_and_fails_the_launch() {
    let dir = TestDir::new("launch-bad-duration");
    let sc = scenario(&dir, "launch-bad-duration", "", "");
    let (mut rig, run) = launch(&dir, &sc, &["--duration=-1"]);
    let st = rig.wait(LONG);
    assert_eq!(st.code(), Some(1), "{}", rig.output());
    let out = rig.output();
    assert!(out.contains("duration"), "{out}");
    let r = record(&run);
    assert_eq!(r["children"]["plant-proxy"]["exit_code"], 2, "{r}");
    assert_eq!(r["ok"], false, "{r}");
}

#[test]
fn a_plant_killed_with_sigkill_mid_run_fails_the_launch_and_the_record_names_its_signal() {
    let dir = TestDir::new("launch-kill-plant");
    let sc = scenario(&dir, "launch-kill-plant", "", "");
    // An hour of plant time: the run is still going when the plant is killed.
    let (mut rig, run) = launch(&dir, &sc, &["--duration", "3600"]);
    rig.wait_for_line("plant connected", LONG);
    let plant = child_named(rig.child.id(), "plant-proxy", LONG);
    // SAFETY: kill with the pid of a process of this test and a valid signal.
    unsafe { libc::kill(plant as i32, libc::SIGKILL) };
    let st = rig.wait(LONG);
    assert_eq!(st.code(), Some(1), "{}", rig.output());
    let out = rig.output();
    assert!(
        out.contains("[launch] plant-proxy: killed by signal 9 (SIGKILL), not by the launcher"),
        "{out}"
    );
    let r = record(&run);
    let p = &r["children"]["plant-proxy"];
    assert_eq!(p["pid"], plant, "{r}");
    assert_eq!(p["signal"], 9, "{r}");
    assert_eq!(p["signal_name"], "SIGKILL", "{r}");
    assert_eq!(p["exit_code"], Value::Null, "{r}");
    assert_eq!(p["stopped_by_launcher"], false, "{r}");
    assert_eq!(r["ok"], false, "{r}");
    assert!(
        r["failure"].as_str().unwrap().contains("plant-proxy"),
        "{r}"
    );
    // The service would wait for a new plant: the launcher stopped it, and it ended by
    // itself on that SIGTERM, with its report.
    let s = &r["children"]["service"];
    assert_eq!(s["stopped_by_launcher"], true, "{r}");
    assert!(s["exit_code"].is_number(), "{r}");
    assert_eq!(read_json(&run.join("report.json"))["stop_reason"], "signal");
}

#[test]
fn killing_the_launcher_with_sigkill_leaves_no_orphan_children() {
    let dir = TestDir::new("launch-kill-launcher");
    let sc = scenario(&dir, "launch-kill-launcher", "", "");
    let (mut rig, run) = launch(&dir, &sc, &["--duration", "3600"]);
    rig.wait_for_line("plant connected", LONG);
    let launcher = rig.child.id();
    let plant = Watched::new(child_named(launcher, "plant-proxy", LONG));
    let service = Watched::new(child_named(launcher, "service", LONG));
    rig.signal(libc::SIGKILL);
    let st = rig.wait(LONG);
    assert_eq!(st.code(), None, "the launcher was killed");
    // PR_SET_PDEATHSIG: each child gets SIGTERM when the launcher dies.
    let deadline = Instant::now() + Duration::from_secs(30);
    while (plant.running() || service.running()) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    let orphans: Vec<u32> = [&plant, &service]
        .iter()
        .filter(|w| w.running())
        .map(|w| w.pid)
        .collect();
    for pid in &orphans {
        // SAFETY: kill with the pid of a process this test started, and a valid signal.
        unsafe { libc::kill(*pid as i32, libc::SIGKILL) };
    }
    assert!(
        orphans.is_empty(),
        "children still running after the launcher died: {orphans:?}\n{}",
        rig.output()
    );
    // The SIGTERM let the service stop cleanly: its report says so.
    let report = read_json(&run.join("report.json"));
    assert_eq!(report["stop_reason"], "signal", "{report}");
}

#[test]
fn a_service_whose_run_verdict_fails_makes_the_launch_exit_1() {
    let dir = TestDir::new("launch-verdict");
    // Every y of the plant (x from 1 towards 0) is below y-min = 2: every measurement is
    // rejected, the controller never runs although every sample is answered, and the
    // verdict fails (service/src/runtime/verdict.rs).
    let sc = scenario(&dir, "launch-verdict", "y-min = 2.0", "");
    let (mut rig, run) = launch(&dir, &sc, &["--duration", "0.2"]);
    let st = rig.wait(LONG);
    assert_eq!(st.code(), Some(1), "{}", rig.output());
    let report = read_json(&run.join("report.json"));
    assert_eq!(report["verdict"]["ok"], false, "{report}");
    assert!(
        report["verdict"]["failures"][0]
            .as_str()
            .unwrap()
            .contains("the controller never ran"),
        "{report}"
    );
    let r = record(&run);
    assert_eq!(r["children"]["service"]["exit_code"], 1, "{r}");
    assert_eq!(
        r["children"]["service"]["stopped_by_launcher"], false,
        "{r}"
    );
    assert_eq!(r["children"]["plant-proxy"]["exit_code"], 0, "{r}");
    assert_eq!(r["ok"], false, "{r}");
    assert!(
        r["failure"]
            .as_str()
            .unwrap()
            .starts_with("the service did not end cleanly: exit 1"),
        "{r}"
    );
    assert!(
        rig.output().contains("[launch] service: exit 1 (failed)"),
        "{}",
        rig.output()
    );
}

#[test]
fn a_lockstep_plant_that_gives_up_prints_its_counters_writes_its_report_saying_so_and_exits_1() {
    let dir = TestDir::new("launch-give-up");
    // Watchdog after 5 × 20 ms, then 2 s for a service to come back.
    let sc = scenario(
        &dir,
        "launch-give-up",
        "",
        &(fixture("proxy-safe-output.toml") + "peer-timeout = 2.0\n"),
    );
    let service = start_service("service", &sc, &dir.path.join("s"));
    service.wait_for_line("waiting for the plant", LONG);
    let report = dir.path.join("plant-report.json");
    let mut plant = start_lockstep_plant(
        "plant",
        &sc,
        100_000_000,
        &["--report", report.to_str().unwrap()],
    );
    service.wait_for_line("plant connected", LONG);
    service.signal(libc::SIGKILL);
    let st = plant.wait(LONG);
    assert_eq!(st.code(), Some(1), "{}", plant.output());
    let out = plant.output();
    assert!(out.contains("[plant-proxy] gave up: "), "{out}");
    assert!(out.contains("actuations applied"), "{out}");
    assert!(out.contains("foreign actuation(s) refused"), "{out}");
    let r = read_json(&report);
    let why = r["gave_up"].as_str().unwrap_or_else(|| panic!("{r}"));
    assert!(why.contains("giving up in lockstep"), "{r}");
    assert!(r["watchdog_trips"].as_u64().unwrap() >= 1, "{r}");
    assert!(r["samples"].as_u64().unwrap() >= 1, "{r}");
}

/// `rig launch --warm-start` hands the checkpoint to the service, which checks it before
/// its loop starts: a missing file is refused naming it, the service exits 1 and so does
/// the launch. (A warm start that is taken: `rcac_loop.rs`.)
#[test]
fn a_warm_start_the_service_refuses_fails_the_launch_naming_the_file() {
    let dir = TestDir::new("launch-warm-start");
    let sc = scenario(&dir, "launch-warm-start", "", "");
    let missing = dir.path.join("no-such-checkpoint.json");
    let (mut rig, run) = launch(&dir, &sc, &["--warm-start", missing.to_str().unwrap()]);
    let st = rig.wait(LONG);
    let out = rig.output();
    assert_eq!(st.code(), Some(1), "{out}");
    assert!(out.contains("warm start refused"), "{out}");
    assert!(out.contains("no-such-checkpoint.json"), "{out}");
    assert_eq!(record(&run)["children"]["service"]["exit_code"], 1);
}
