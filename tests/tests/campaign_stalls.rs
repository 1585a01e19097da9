//! The fault campaign of issue 14, stalls (docs/faults.md): a SIGSTOP of either side is a
//! timing fault, not a new plant. The service stopped for 0.8 s against a real-time plant
//! finds the samples that came meanwhile, counts the ones it never saw as lost and does not
//! call the plant silent; a plant stopped long enough to fall silent comes back as a stall
//! of the same session. Neither resets what the controller learned.
//!
//! The controller is an integrator that does not act (`x⁺ = x + y`, `u = −2 y`): its state
//! `x0`, logged in `signals.csv`, is the sum of every `y` it has seen, and it only grows
//! because `y > 0` on this plant. A reset would bring it back to 0, so a decreasing `x0`
//! shows one. No test asserts a timing.

use rig_tests::*;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;
use std::time::{Duration, Instant};

/// `[log]` and `[service]` of the campaign: no RT privileges asked (the tests share two
/// cores), blocking wait, a short grace period; `service_extra` adds `[service]` keys.
fn service_tables(service_extra: &str) -> String {
    format!(
        "\n{}{service_extra}\n",
        fixture("campaign-service-tables.toml")
    )
}

/// The first-order plant of `scenarios/first-order-lockstep.toml` (T = 1 ms, y > 0) with
/// the campaign's service tables, the integrator and `extra` tables.
fn scenario(dir: &TestDir, test: &str, service_extra: &str, extra: &str) -> PathBuf {
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(test))
        + &service_tables(service_extra)
        + &fixture("integrator-controller.toml")
        + extra;
    dir.write("scenario.toml", &text)
}

/// `service run <sc> --run-folder <folder> [--exit-with-plant]`.
fn service(sc: &Path, folder: &Path, exit_with_plant: bool) -> Proc {
    let mut args = vec![
        "run",
        sc.to_str().unwrap(),
        "--run-folder",
        folder.to_str().unwrap(),
    ];
    if exit_with_plant {
        args.push("--exit-with-plant");
    }
    Proc::start("service", &bin("service"), &args)
}

/// Waits up to `timeout` for `p` to exit; if it has not, sends SIGTERM and waits again.
fn exit_or_term(p: &mut Proc, timeout: Duration) -> ExitStatus {
    let until = Instant::now() + timeout;
    while Instant::now() < until {
        if let Some(st) = p.child.try_wait().expect("try_wait") {
            std::thread::sleep(Duration::from_millis(50));
            return st;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    p.signal(libc::SIGTERM);
    p.wait(Duration::from_secs(30))
}

/// The `x0` column of `signals.csv` (the integrator's state after each answered sample);
/// asserts that it never decreases, i.e. that the controller was never reset.
fn assert_integrator_never_reset(run_folder: &Path) -> Vec<f64> {
    let (header, rows) = read_csv(&run_folder.join("signals.csv"));
    let (seq, x0) = (column(&header, "seq"), column(&header, "x0"));
    assert!(!rows.is_empty(), "signals.csv has rows");
    for w in rows.windows(2) {
        assert!(
            w[1][x0] >= w[0][x0],
            "the controller's state went back from {} (seq {}) to {} (seq {}): it was reset",
            w[0][x0],
            w[0][seq],
            w[1][x0],
            w[1][seq]
        );
    }
    rows.iter().map(|r| r[x0]).collect()
}

/// The kebab-case names of the report's events.
fn event_names(report: &serde_json::Value) -> Vec<String> {
    report["events"]
        .as_array()
        .expect("events")
        .iter()
        .map(|e| e["event"].as_str().unwrap_or("").to_string())
        .collect()
}

fn stat(report: &serde_json::Value, name: &str) -> u64 {
    report["stats"][name]
        .as_u64()
        .unwrap_or_else(|| panic!("no stats.{name} in the report"))
}

/// A stall of the service against a real-time plant (proxy.mode defaults to real-time)
/// at 1 kHz for `steps` samples, without RT privileges: `stall` runs 0.5 s after the plant
/// connected. Silence would take 300 periods (0.3 s), so a service that took its own
/// stall of 0.8 s for silence would say so. Asserts the rules that hold whatever the
/// stall's timing — no `PLANT SILENT`, no new session, the controller never reset, the
/// service ends with the plant (or fails its verdict on the misses) — and returns the
/// report.
fn stall_the_service(
    test: &str,
    service_extra: &str,
    proxy_extra: &str,
    steps: &str,
    stall: impl FnOnce(&Proc),
) -> serde_json::Value {
    let dir = TestDir::new(&format!("campaign-{test}"));
    let sc = scenario(
        &dir,
        test,
        &format!("silent-periods = 300\n{service_extra}"),
        &format!("\n[proxy]\nfifo-priority = 0\nmlockall = false\n{proxy_extra}\n"),
    );
    let run_folder = dir.path.join("service-run");
    let mut svc = service(&sc, &run_folder, true);
    svc.wait_for_line("waiting for the plant", Duration::from_secs(30));
    let mut plant = Proc::start(
        "plant",
        &bin("plant-proxy"),
        &["run", sc.to_str().unwrap(), "--steps", steps],
    );
    svc.wait_for_line("plant connected", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(500));
    stall(&svc);
    plant.wait_success(Duration::from_secs(60));
    let st = exit_or_term(&mut svc, Duration::from_secs(30));

    let out = svc.output();
    assert!(
        !out.contains("PLANT SILENT"),
        "the service took its own stall for a silent plant:\n{out}"
    );
    assert!(!out.contains("NEW PLANT SESSION"), "{out}");
    let report = read_json(&run_folder.join("report.json"));
    assert_eq!(stat(&report, "plant_silent_events"), 0, "{report}");
    assert_eq!(stat(&report, "new_sessions"), 0, "{report}");
    let events = event_names(&report);
    assert!(
        !events
            .iter()
            .any(|e| e == "new-plant-session" || e == "plant-silent"),
        "{events:?}"
    );
    assert_integrator_never_reset(&run_folder);
    assert!(
        st.success() || st.code() == Some(1),
        "service: {st:?}\n{out}"
    );
    report
}

#[test]
fn a_service_stopped_for_0_8_s_against_a_real_time_plant_counts_the_samples_it_missed_as_lost_and_neither_calls_the_plant_silent_nor_resets_the_controller()
 {
    let report = stall_the_service("stop-svc", "", "", "4000", |svc| {
        svc.signal(libc::SIGSTOP);
        std::thread::sleep(Duration::from_millis(800));
        svc.signal(libc::SIGCONT);
    });
    // About 800 samples came while the service was stopped; the subscriber buffer kept a
    // few, the rest were never seen and are counted as lost.
    assert!(
        stat(&report, "skipped") > 0,
        "no sample counted as lost: {report}"
    );
}

/// Spins for `how_long` on `core` at `SCHED_FIFO` priority 99 on a thread of this test:
/// a CPU hog that takes the core from every normal-priority thread pinned there (with RT
/// throttling on, they get its 5 % remainder). Panics when the OS refuses the priority.
fn hog(core: usize, how_long: Duration) {
    std::thread::spawn(move || {
        // SAFETY: plain libc calls on this thread, with valid arguments.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(core, &mut set);
            assert_eq!(
                libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set),
                0,
                "pinning the hog to core {core}"
            );
            let param = libc::sched_param { sched_priority: 99 };
            assert_eq!(
                libc::sched_setscheduler(0, libc::SCHED_FIFO, &param),
                0,
                "SCHED_FIFO 99 for the hog (the test needs root)"
            );
        }
        let until = Instant::now() + how_long;
        while Instant::now() < until {
            std::hint::spin_loop();
        }
    })
    .join()
    .expect("the hog thread");
}

/// A CPU hog on the service's RT core (`SCHED_FIFO` 99 for 0.8 s on core 1, where the
/// service runs pinned at normal priority) against a real-time plant on the other core:
/// for the loop it is a stopped service, so the rules of [`stall_the_service`] hold
/// whatever the hog's timing. How many samples were lost or late depends on the machine
/// and is not asserted.
#[test]
fn a_cpu_hog_on_the_rt_core_is_a_stall_of_the_service_and_neither_silences_the_plant_nor_resets_the_controller()
 {
    let report = stall_the_service("hog", "core = 1", "core = 0", "3000", |_| {
        hog(1, Duration::from_millis(800));
    });
    eprintln!(
        "hog: {} lost, {} caught up, {} misses reported by the plant",
        stat(&report, "skipped"),
        stat(&report, "caught_up"),
        stat(&report, "plant_reported_misses")
    );
}

#[test]
fn a_plant_stopped_until_it_falls_silent_resumes_as_a_stall_of_the_same_session_without_a_controller_reset()
 {
    let dir = TestDir::new("campaign-stop-plant");
    // Lockstep, silence after 100 periods (0.1 s); the plant is stopped for 1 s.
    let sc = scenario(&dir, "stop-plant", "silent-periods = 100", "");
    let run_folder = dir.path.join("service-run");
    let mut svc = service(&sc, &run_folder, false);
    let _plant = start_lockstep_plant("plant", &sc, 100_000_000, &[]);
    svc.wait_for_line("plant connected", Duration::from_secs(30));
    std::thread::sleep(Duration::from_millis(300));
    _plant.signal(libc::SIGSTOP);
    svc.wait_for_line("PLANT SILENT", Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(700));
    _plant.signal(libc::SIGCONT);
    svc.wait_for_line("plant resumed", Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(300));
    svc.signal(libc::SIGTERM);
    svc.wait_success(Duration::from_secs(30));

    let out = svc.output();
    assert!(
        !out.contains("NEW PLANT SESSION"),
        "a stall was taken for a new plant:\n{out}"
    );
    let report = read_json(&run_folder.join("report.json"));
    assert!(stat(&report, "plant_silent_events") >= 1, "{report}");
    assert!(stat(&report, "plant_resumes") >= 1, "{report}");
    assert_eq!(stat(&report, "new_sessions"), 0, "{report}");
    let events = event_names(&report);
    assert!(events.iter().any(|e| e == "plant-resumed"), "{events:?}");
    assert!(
        !events.iter().any(|e| e == "new-plant-session"),
        "{events:?}"
    );
    // The stall lost nothing: the plant waited in lockstep.
    assert_eq!(stat(&report, "skipped"), 0, "{report}");
    let x0 = assert_integrator_never_reset(&run_folder);
    // What it learned before the stall is still there at the end: more than the first
    // sample's y = 1 (a reset controller on a plant near 0 would hold about 0).
    assert!(*x0.last().unwrap() > 1.0, "{:?}", x0.last());
}
