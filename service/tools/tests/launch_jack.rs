//! `rig launch --plant jack-room`: the whole loop through a real JACK server without a
//! card. The launcher starts a dummy server and the simulated room, runs `plant-jack run`
//! (lockstep: the server freewheels) against the service, then stops the room and the
//! server and records all four; and it refuses, before starting anything, a scenario whose
//! server already runs.
//!
//! Needs Debian's jackd2 (`jackd`, `jack_lsp`) and the workspace's binaries next to `rig`
//! (`service`, `plant-jack`: `cargo test --release --workspace` builds them). Each test has
//! its own rig and server names, so the tests run in parallel with each other and with
//! other JACK servers on the machine. The server names are fixed (no process id): JACK keeps
//! at most 8 servers in its registry and reclaims the entry of one that died without
//! unregistering only for a new server of the same name.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const RIG: &str = env!("CARGO_BIN_EXE_rig");
/// Far longer than a launch of one second of lockstep takes (about 2 s).
const LAUNCH_WITHIN: Duration = Duration::from_secs(120);

/// The repository's root.
fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Panics, saying what to install or build, when the test cannot run here.
fn needs_jack_and_the_binaries() {
    for tool in ["jackd", "jack_lsp"] {
        assert!(
            rig_tools::launch::jack::on_path(tool).is_some(),
            "{tool} is not on PATH: these tests need Debian's jackd2 (apt-get install jackd2)"
        );
    }
    let dir = Path::new(RIG).parent().expect("rig's folder");
    for b in ["service", "plant-jack"] {
        assert!(
            dir.join(b).exists(),
            "{} is not built: run `cargo build --release --workspace` (or the tests with \
             `cargo test --release --workspace`)",
            dir.join(b).display()
        );
    }
}

/// A fresh folder, removed when dropped unless the test failed.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let d = std::env::temp_dir().join(format!("launch-jack-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("test folder");
        Self(d)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The acoustic rig (scenarios/acoustic-rig.toml) renamed `rig`, with the service blocking
/// on its measurements (`wait = "block"`) and a `[jack]` table that wires the plant side to
/// the room on the server `server`.
fn scenario(dir: &Path, rig: &str, server: &str) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("scenarios/acoustic-rig.toml"))
        .expect("scenarios/acoustic-rig.toml");
    let mut replaced = [0; 3];
    let mut out: String = text
        .lines()
        .map(|l| {
            if l.starts_with("name = \"acoustic-rig\"") {
                replaced[0] += 1;
                format!("name = \"{rig}\"")
            } else if l.starts_with("wait = ") {
                replaced[1] += 1;
                "wait = \"block\"".to_string()
            } else if let Some(rest) = l.strip_prefix("target-model-file = \"") {
                // The copy lives elsewhere: the target model by its full path.
                replaced[2] += 1;
                let file = rest.trim_end_matches('"');
                format!(
                    "target-model-file = \"{}\"",
                    repo().join("scenarios").join(file).display()
                )
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    assert_eq!(
        replaced,
        [1, 1, 1],
        "scenarios/acoustic-rig.toml changed: the rig name, service.wait and the target \
         model file are each expected once"
    );
    out.push_str(&format!(
        "\n\n[jack]\nserver = \"{server}\"\ny = [\"room:mic-y0\"]\nz = [\"room:mic-z0\"]\n\
         u = [\"room:speaker-u0\", \"room:speaker-u1\"]\ny-full-scale = [10.0]\n\
         z-full-scale = [10.0]\nu-full-scale = [40.0, 40.0]\n"
    ));
    let path = dir.join("scenario.toml");
    std::fs::write(&path, out).expect("write the scenario");
    path
}

/// What `rig` left: its exit code and its standard error.
struct Ran {
    code: Option<i32>,
    stderr: String,
}

/// Runs `rig launch SCENARIO --plant jack-room --mode lockstep --duration 1 --controller
/// scenarios/identify/excitation.toml --run-folder RUN`; a launch that does not end within
/// [`LAUNCH_WITHIN`] is stopped as a user would (`SIGTERM`: the launcher stops its
/// children in order) and fails the test.
fn launch(dir: &Path, scenario: &Path, run: &Path) -> Ran {
    let err_file = dir.join("rig.stderr");
    let mut rig = Command::new(RIG)
        .arg("launch")
        .arg(scenario)
        .args([
            "--plant",
            "jack-room",
            "--mode",
            "lockstep",
            "--duration",
            "1",
        ])
        .arg("--controller")
        .arg(repo().join("scenarios/identify/excitation.toml"))
        .arg("--run-folder")
        .arg(run)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(dir.join("rig.stdout")).expect("stdout file"))
        .stderr(std::fs::File::create(&err_file).expect("stderr file"))
        .spawn()
        .expect("starting rig launch");
    let deadline = Instant::now() + LAUNCH_WITHIN;
    let status = loop {
        if let Some(st) = rig.try_wait().expect("waiting for rig") {
            break st;
        }
        if Instant::now() >= deadline {
            // SAFETY: kill on our own child, not reaped yet.
            unsafe { libc::kill(rig.id() as i32, libc::SIGTERM) };
            let _ = rig.wait();
            panic!(
                "rig launch did not end within {} s; its stderr:\n{}",
                LAUNCH_WITHIN.as_secs(),
                std::fs::read_to_string(&err_file).unwrap_or_default()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    Ran {
        code: status.code(),
        stderr: std::fs::read_to_string(&err_file).unwrap_or_default(),
    }
}

fn read_json(path: &Path) -> Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Whether a JACK server named `server` answers.
fn server_runs(server: &str) -> bool {
    Command::new("jack_lsp")
        .args(["-s", server])
        .env("JACK_NO_START_SERVER", "1")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// A dummy JACK server of the test's own, stopped when dropped (also when the test fails).
struct Jackd(Child);

impl Jackd {
    /// Starts `jackd -n NAME --no-realtime -d dummy -r 8000 -p 32` and waits until it
    /// answers.
    fn start(name: &str, log: &Path) -> Self {
        let out = std::fs::File::create(log).expect("jackd log");
        let err = out.try_clone().expect("jackd log");
        let child = Command::new("jackd")
            .args([
                "-n",
                name,
                "--no-realtime",
                "-d",
                "dummy",
                "-r",
                "8000",
                "-p",
                "32",
            ])
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .expect("starting jackd");
        let mut server = Self(child);
        let deadline = Instant::now() + Duration::from_secs(10);
        while !server_runs(name) {
            if let Ok(Some(st)) = server.0.try_wait() {
                panic!(
                    "the test's jackd ended ({st}): {}",
                    std::fs::read_to_string(log).unwrap_or_default()
                );
            }
            assert!(
                Instant::now() < deadline,
                "the test's JACK server '{name}' did not answer within 10 s"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        server
    }
}

impl Drop for Jackd {
    fn drop(&mut self) {
        // SAFETY: kill on our own child, not reaped yet.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_jack_room_launch_runs_the_loop_through_a_dummy_server_and_stops_the_room_and_the_server() {
    needs_jack_and_the_binaries();
    let dir = TempDir::new("room");
    let pid = std::process::id();
    // A fixed name (see `Jackd`): JACK reclaims a dead server's entry only for its name.
    let server = "rig-launch-test-room".to_string();
    let sc = scenario(&dir.0, &format!("launch-jack-{pid}"), &server);
    let run = dir.0.join("run");
    let ran = launch(&dir.0, &sc, &run);
    assert_eq!(ran.code, Some(0), "rig launch failed:\n{}", ran.stderr);

    let r = read_json(&run.join("launch.json"));
    assert_eq!(r["ok"], true, "{r}");
    assert_eq!(r["plant"], "jack-room", "{r}");
    assert_eq!(r["jack"]["server"], server.as_str(), "{r}");
    let children = &r["children"];
    assert_eq!(children["service"]["exit_code"], 0, "{r}");
    assert_eq!(children["plant"]["name"], "plant-jack", "{r}");
    assert_eq!(children["plant"]["exit_code"], 0, "{r}");
    assert!(children.get("plant-proxy").is_none(), "{r}");
    for fixture in ["room", "jackd"] {
        let c = &children[fixture];
        assert_eq!(c["name"], fixture, "{r}");
        assert_eq!(c["stopped_by_launcher"], true, "{fixture}: {r}");
        assert_eq!(
            c["stop_reason"], "the service and the plant ended",
            "{fixture}: {r}"
        );
    }
    assert!(
        !server_runs(&server),
        "the launcher's JACK server '{server}' still runs after the launch"
    );
    let room_log = std::fs::read_to_string(run.join("room.log")).expect("room.log");
    assert!(room_log.contains("[room] rig '"), "room.log: {room_log}");
    assert!(run.join("jackd.log").exists());

    let p = read_json(&run.join("plant-report.json"));
    assert_eq!(p["samples"], 8000, "{p}");
    assert_eq!(p["actuations_applied"], p["samples"], "{p}");
    assert_eq!(p["jack"]["freewheel"], true, "{p}");
    assert_eq!(p["jack"]["server"], server.as_str(), "{p}");
    // The dummy server's one period of playback latency: what the card would add.
    assert_eq!(p["jack"]["added_delay_frames"], 32, "{p}");
}

#[test]
fn a_jack_room_launch_is_refused_with_2_when_its_server_already_runs() {
    needs_jack_and_the_binaries();
    let dir = TempDir::new("busy");
    let pid = std::process::id();
    let server = "rig-launch-test-busy".to_string();
    let _jackd = Jackd::start(&server, &dir.0.join("jackd.log"));
    let sc = scenario(&dir.0, &format!("launch-jack-busy-{pid}"), &server);
    let run = dir.0.join("run");
    let ran = launch(&dir.0, &sc, &run);
    assert_eq!(ran.code, Some(2), "{}", ran.stderr);
    assert!(
        ran.stderr
            .contains(&format!("JACK server named '{server}' is already running")),
        "{}",
        ran.stderr
    );
    assert!(
        !run.exists(),
        "a refused launch made its run folder {}",
        run.display()
    );
    assert!(server_runs(&server), "the test's own server was stopped");
}
