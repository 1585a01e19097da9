//! A sound card under JACK as the acoustic rig's DAQ, tested through a real audio server:
//! Debian's `jackd` with its dummy backend (the server's real period scheduling, no card),
//! `plant-jack room` playing the room and `plant-jack run` as the plant side, against the
//! unmodified `service` over iceoryx2.
//!
//! - The design path through the server: an identification run in lockstep (the server
//!   freewheels), the frequency response and the FIR target from its log, reproduce
//!   `scenarios/jack/acoustic-target.toml` exactly, with the delays the server adds.
//! - RCAC with that target suppresses the seven tones through the server (lockstep).
//! - A missing server, a wrong port count, a missing port, a sample rate or a period that
//!   differs from the scenario's: refused before the run, naming the server, field and port.
//! - In real time, an xrun and a stalled service are survived (plan, then hold, then the
//!   watchdog's safe output, then recovery) and reported.

use control::target::TargetModel;
use rig_tests::*;
use service::config::TargetModelFile;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// A JACK server with the dummy backend, stopped when dropped.
///
/// Each test's server has a fixed name (no process id): JACK keeps at most 8 servers in
/// its registry and reclaims the entry of a server that died without unregistering only
/// for a new server of the same name, so a name used once and killed would hold its entry
/// until the machine restarts. For the same reason it is stopped with `SIGTERM` (jackd
/// unregisters), not killed.
struct JackServer {
    name: String,
    proc: Proc,
}

impl Drop for JackServer {
    fn drop(&mut self) {
        self.proc.signal(libc::SIGTERM);
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.proc.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl JackServer {
    /// Starts `jackd -n <name> -d dummy -r <rate> -p <frames>` (real-time scheduling with
    /// `realtime`) and waits until it answers.
    fn start(name: &str, rate: u32, frames: u32, realtime: bool) -> Self {
        let mut cmd = Command::new("jackd");
        cmd.args(["-n", name]);
        cmd.arg(if realtime { "-R" } else { "-r" });
        cmd.args([
            "-d",
            "dummy",
            "-r",
            &rate.to_string(),
            "-p",
            &frames.to_string(),
        ]);
        // jackd comes with Debian's jackd2 (installed by .ci/run).
        let proc = Proc::spawn(&format!("jackd {name}"), cmd);
        let server = Self {
            name: name.to_string(),
            proc,
        };
        // Until it answers, or has ended (JACK allows a few servers at once, and says so).
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            let up = Command::new("jack_wait")
                .args(["-s", name, "-c"])
                .output()
                .expect("jack_wait (Debian's jackd2) runs");
            if String::from_utf8_lossy(&up.stdout).contains("running")
                && !String::from_utf8_lossy(&up.stdout).contains("not running")
            {
                break;
            }
            let ended = server.proc.output().contains("Failed to open server");
            assert!(
                !ended && Instant::now() < deadline,
                "the JACK server {name} did not start:\n{}",
                server.proc.output()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        server
    }
}

/// The scenario `scenarios/jack/acoustic-rig.toml` for one test: its own rig and server
/// names, its target model by absolute path, `replace` applied (pairs of old, new text).
fn jack_scenario(dir: &TestDir, test: &str, server: &str, replace: &[(&str, &str)]) -> PathBuf {
    let target =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/jack/acoustic-target.toml");
    let mut text = with_rig_name(&scenario_text("jack/acoustic-rig.toml"), &rig_name(test))
        .replace(
            "target-model-file = \"acoustic-target.toml\"",
            &format!("target-model-file = \"{}\"", target.display()),
        )
        .replace(
            "server = \"adaptive-rig\"",
            &format!("server = \"{server}\""),
        );
    for (old, new) in replace {
        assert!(text.contains(old), "the JACK scenario has no '{old}'");
        text = text.replace(old, new);
    }
    dir.write("scenario.toml", &text)
}

/// The server name of one test (see [`JackServer`]).
fn server_name(test: &str) -> String {
    format!("rig-test-{test}")
}

/// Starts `plant-jack room <scenario> <extra…>` and waits until its ports are registered.
fn start_room(scenario: &Path, extra: &[&str]) -> Proc {
    let mut args = vec!["room", scenario.to_str().unwrap()];
    args.extend_from_slice(extra);
    let room = Proc::start("room", &bin("plant-jack"), &args);
    room.wait_for_line("as JACK client 'room'", Duration::from_secs(20));
    room
}

/// Starts `plant-jack run <scenario> <extra…> --report <folder>/plant-report.json`.
fn start_plant_jack(scenario: &Path, folder: &Path, extra: &[&str]) -> Proc {
    let report = folder.join("plant-report.json");
    let mut args = vec!["run", scenario.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend(["--report", report.to_str().unwrap()]);
    Proc::start("plant-jack", &bin("plant-jack"), &args)
}

/// Runs the service and the JACK plant side (with the room) on `scenario` for `duration`
/// seconds in `mode`, the service with `service_extra`; returns the run folder, the plant's
/// report and whether the service succeeded.
fn run_through_jack(
    dir: &TestDir,
    scenario: &Path,
    mode: &str,
    duration: &str,
    service_extra: &[&str],
) -> (PathBuf, serde_json::Value, bool) {
    let folder = dir.path.join("run");
    std::fs::create_dir_all(&folder).unwrap();
    let mut room = start_room(scenario, &[]);
    let mut args = vec![
        "run",
        scenario.to_str().unwrap(),
        "--exit-with-plant",
        "--run-folder",
        folder.to_str().unwrap(),
    ];
    args.extend_from_slice(service_extra);
    let mut service = Proc::start("service", &bin("service"), &args);
    let mut plant = start_plant_jack(scenario, &folder, &["--mode", mode, "--duration", duration]);
    plant.wait_success(Duration::from_secs(300));
    let service_ok = service.wait(Duration::from_secs(60)).success();
    room.signal(libc::SIGTERM);
    room.wait_success(Duration::from_secs(10));
    let report = read_json(&folder.join("plant-report.json"));
    (folder, report, service_ok)
}

/// Runs `rig-design <args…>` and asserts that it succeeded; what it printed.
fn design(args: &[&str]) -> String {
    let (ok, text) = rig_design(args);
    assert!(ok, "rig-design {args:?} failed:\n{text}");
    text
}

/// The first 264 Markov parameters of a target-model file, in order.
fn markov(path: &Path) -> Vec<f64> {
    TargetModel::load(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .markov(264)
        .iter()
        .flat_map(|h| h.iter().copied().collect::<Vec<_>>())
        .collect()
}

#[test]
fn the_design_path_through_the_server_reproduces_the_committed_target_model() {
    let test = "jack-design";
    let dir = TestDir::new(test);
    let server = JackServer::start(&server_name(test), 8000, 64, false);
    let scenario = jack_scenario(&dir, test, &server.name, &[]);
    let excitation =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/identify/excitation.toml");
    let (folder, report, service_ok) = run_through_jack(
        &dir,
        &scenario,
        "lockstep",
        "20",
        &["--controller", excitation.to_str().unwrap()],
    );
    assert!(service_ok, "the identification run's service failed");
    // Every sample answered, through a freewheeling server, with the period it adds.
    assert_eq!(report["samples"], 160_000);
    assert_eq!(report["actuations_applied"], 160_000);
    assert_eq!(report["jack"]["freewheel"], true);
    assert_eq!(report["jack"]["period_frames"], 64);
    assert_eq!(report["jack"]["added_delay_frames"], 64);
    assert_eq!(report["rt_allocations"]["system_on_rt_thread"], 0);

    let frf = dir.path.join("frf");
    let printed = design(&[
        "frf",
        folder.join("signals.csv").to_str().unwrap(),
        "--inputs",
        "u0,u1",
        "--outputs",
        "y0",
        "--scenario",
        scenario.to_str().unwrap(),
        "--out",
        frf.to_str().unwrap(),
    ]);
    // The room's 9 and 16 samples plus the period of the loop through the server.
    assert!(printed.contains("delays found [73, 80]"), "{printed}");
    let fir = dir.path.join("fir");
    design(&[
        "dtf",
        frf.join("frf.csv").to_str().unwrap(),
        "--method",
        "fir",
        "--count",
        "264",
        "--out",
        fir.to_str().unwrap(),
    ]);
    let made = markov(&fir.join("target-model.toml"));
    let committed = markov(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/jack/acoustic-target.toml"),
    );
    assert_eq!(made.len(), 264 * 2);
    assert_eq!(
        made, committed,
        "the design path through the server no longer gives scenarios/jack/acoustic-target.toml"
    );
}

#[test]
fn rcac_suppresses_the_tones_through_the_server() {
    let test = "jack-rcac";
    let dir = TestDir::new(test);
    let server = JackServer::start(&server_name(test), 8000, 64, false);
    let scenario = jack_scenario(&dir, test, &server.name, &[]);
    let (folder, report, service_ok) = run_through_jack(&dir, &scenario, "lockstep", "10", &[]);
    assert!(service_ok, "the service's verdict failed (see its report)");
    assert_eq!(report["misses"], 0);
    let run = read_json(&folder.join("report.json"));
    let tones = run["tones"]["tones"]
        .as_array()
        .unwrap_or_else(|| panic!("report.json has no tones: {run}"));
    assert_eq!(tones.len(), 7);
    for t in tones {
        let db = t["suppression_db"].as_f64().unwrap();
        assert!(db >= 60.0, "tone {t} suppressed by only {db} dB");
    }
}

#[test]
fn refusals_name_the_server_the_field_and_the_port() {
    let test = "jack-refusals";
    let dir = TestDir::new(test);
    let refused = |scenario: &Path| {
        let mut p = Proc::start(
            "plant-jack",
            &bin("plant-jack"),
            &["run", scenario.to_str().unwrap(), "--duration", "1"],
        );
        assert_eq!(
            p.wait(Duration::from_secs(60)).code(),
            Some(2),
            "{}",
            p.output()
        );
        p.output()
    };
    // No server of that name.
    let absent = server_name("jack-absent");
    let out = refused(&jack_scenario(&dir, test, &absent, &[]));
    assert!(
        out.contains(&format!("no JACK server named '{absent}' is running")),
        "{out}"
    );
    // One port for two loudspeakers: refused from the file alone.
    let out = refused(&jack_scenario(
        &dir,
        test,
        &absent,
        &[(
            "u = [\"room:speaker-u0\", \"room:speaker-u1\"]",
            "u = [\"room:speaker-u0\"]",
        )],
    ));
    assert!(
        out.contains("field 'jack.u': 1 port(s) (room:speaker-u0) for a plant of n_u = 2"),
        "{out}"
    );

    let server = JackServer::start(&server_name(test), 8000, 64, false);
    // A port that is not there (no room is running): the field and the port.
    let out = refused(&jack_scenario(&dir, test, &server.name, &[]));
    assert!(
        out.contains("field 'jack.y[0]'") && out.contains("has no port 'room:mic-y0'"),
        "{out}"
    );
    // Another period than the scenario's.
    let out = refused(&jack_scenario(
        &dir,
        test,
        &server.name,
        &[("period-frames = 64", "period-frames = 16")],
    ));
    assert!(
        out.contains("runs with periods of 64 frames") && out.contains("jack.period-frames is 16"),
        "{out}"
    );
    // An input port where a measurement is read.
    let room_scenario = jack_scenario(&dir, test, &server.name, &[]);
    let mut room = start_room(&room_scenario, &[]);
    let out = refused(&jack_scenario(
        &dir,
        test,
        &server.name,
        &[("y = [\"room:mic-y0\"]", "y = [\"room:speaker-u0\"]")],
    ));
    assert!(
        out.contains("field 'jack.y[0]'") && out.contains("'room:speaker-u0' is an input"),
        "{out}"
    );
    room.signal(libc::SIGTERM);
    room.wait_success(Duration::from_secs(10));
    drop(server);

    // Another sample rate than the scenario's.
    let fast = JackServer::start(&server_name("jack-16k"), 16000, 64, false);
    let out = refused(&jack_scenario(&dir, test, &fast.name, &[]));
    assert!(
        out.contains(&format!("JACK server '{}' runs at 16000 Hz", fast.name))
            && out.contains("is 8000 Hz"),
        "{out}"
    );
}

#[test]
fn an_xrun_and_a_stalled_service_are_survived_and_reported() {
    let test = "jack-faults";
    let dir = TestDir::new(test);
    let server = JackServer::start(&server_name(test), 8000, 64, true);
    let scenario = jack_scenario(&dir, test, &server.name, &[]);
    let folder = dir.path.join("run");
    std::fs::create_dir_all(&folder).unwrap();
    // The room sleeps three periods at 1.5 s of its time: an xrun every client is told of.
    let mut room = start_room(&scenario, &["--xrun-at", "1.5"]);
    let mut service = Proc::start(
        "service",
        &bin("service"),
        &[
            "run",
            scenario.to_str().unwrap(),
            "--exit-with-plant",
            "--run-folder",
            folder.to_str().unwrap(),
        ],
    );
    let mut plant = start_plant_jack(&scenario, &folder, &["--duration", "5"]);
    plant.wait_for_line("connected to JACK server", Duration::from_secs(60));
    // The service stops answering for 0.2 s (1600 samples, 20 times the watchdog's 80).
    std::thread::sleep(Duration::from_millis(2500));
    service.signal(libc::SIGSTOP);
    let stopped = Instant::now();
    std::thread::sleep(Duration::from_millis(200));
    service.signal(libc::SIGCONT);
    eprintln!(
        "service stopped for {:.3} s",
        stopped.elapsed().as_secs_f64()
    );
    plant.wait_success(Duration::from_secs(60));
    let _ = service.wait(Duration::from_secs(60));
    room.signal(libc::SIGTERM);
    room.wait_success(Duration::from_secs(10));

    let r = read_json(&folder.join("plant-report.json"));
    let n = |k: &str| r[k].as_u64().unwrap_or_else(|| panic!("no {k} in {r}"));
    // Every sample decided: published, or lost to a skipped period (an xrun).
    let lost = r["jack"]["samples_lost"].as_u64().unwrap();
    assert_eq!(n("samples") + lost, 40_000, "{r}");
    // The stall: the plan first, then the held input, then the safe output, then the
    // service's answers again.
    assert!(n("plan_entries_applied") >= 64, "{r}");
    assert!(n("misses_held_or_safe") > 0, "{r}");
    assert!(
        n("watchdog_trips") >= 1 && n("watchdog_recoveries") >= 1,
        "{r}"
    );
    assert!(n("safe_output_samples") > 0, "{r}");
    assert!(
        n("actuations_applied") + n("misses") == 40_000 && n("actuations_applied") > 30_000,
        "the loop went on after the faults: {r}"
    );
    let out = plant.output();
    assert!(
        out.contains("WATCHDOG") && out.contains("leaving the safe output"),
        "{out}"
    );
    // The xrun: the server told the plant side, and the room went on with the server's clock.
    assert!(r["jack"]["xruns"].as_u64().unwrap() >= 1, "{r}");
    assert!(room.output().contains("(1 injected)"), "{}", room.output());
    assert_eq!(r["jack"]["freewheel"], false);
    let thread = r["jack"]["thread"].as_str().unwrap_or_default();
    assert!(
        thread.contains("SCHED_FIFO"),
        "the server (-R) raised the callback's thread: {r}"
    );
}

#[test]
fn the_jack_scenario_plays_the_acoustic_rig_of_the_main_job() {
    // scenarios/jack/acoustic-rig.toml says its plant is the main job's: hold it to that
    // (the [plant] tables, comments and all, from their heading to the end of the file).
    let plant = |text: &str| text[text.find("\n[plant]\n").expect("a [plant] table")..].to_string();
    assert_eq!(
        plant(&scenario_text("jack/acoustic-rig.toml")),
        plant(&scenario_text("acoustic-rig.toml"))
    );
}
