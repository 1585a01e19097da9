//! Helpers for the closed-loop integration tests in `tests/tests/`: finding the built
//! binaries, reading the TOML fixtures of `tests/fixtures/` ([`fixture`]) and the
//! repository's scenarios ([`scenario_text`]), writing scenario files into a fresh folder,
//! starting `service` and `plant-proxy` as real processes, and watching what they print.
//!
//! The tests run the two processes in lockstep where the result must not depend on timing,
//! and give every test its own rig name so that they can run in parallel.

pub mod full_disk;
pub mod python;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The path of a workspace binary built next to the test executable
/// (`target/<profile>/<name>`); `cargo test --workspace` builds them.
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let dir = exe
        .parent()
        .and_then(|d| d.parent())
        .expect("target/<profile>");
    let p = dir.join(name);
    assert!(
        p.exists(),
        "{} is not built; run the tests with `cargo test --workspace` (it builds every binary)",
        p.display()
    );
    p
}

/// A fresh folder for one test, removed when dropped unless the test failed.
pub struct TestDir {
    /// Its path.
    pub path: PathBuf,
}

impl TestDir {
    /// Creates `target/test-runs/<name>-<pid>`.
    pub fn new(name: &str) -> Self {
        let exe = std::env::current_exe().expect("test executable path");
        let base = exe
            .parent()
            .and_then(|d| d.parent())
            .and_then(|d| d.parent())
            .expect("target dir")
            .join("test-runs");
        let path = base.join(format!("{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path).expect("create test dir");
        Self { path }
    }

    /// Writes `text` into `file` inside the folder and returns its path.
    pub fn write(&self, file: &str, text: &str) -> PathBuf {
        let p = self.path.join(file);
        std::fs::write(&p, text).expect("write test file");
        p
    }
}

impl Drop for TestDir {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}

/// Starts `service run <scenario> --run-folder <folder>` as the process `name`.
pub fn start_service(name: &str, scenario: &Path, folder: &Path) -> Proc {
    Proc::start(
        name,
        &bin("service"),
        &[
            "run",
            scenario.to_str().expect("UTF-8 path"),
            "--run-folder",
            folder.to_str().expect("UTF-8 path"),
        ],
    )
}

/// Starts `service run <scenario> --exit-with-plant --run-folder <folder>` as the process
/// `service`: the service that ends with the plant's last sample, for a plant process
/// started next (plant-proxy or a DAQ process in any language).
pub fn start_service_until_plant_ends(scenario: &Path, folder: &Path) -> Proc {
    Proc::start(
        "service",
        &bin("service"),
        &[
            "run",
            scenario.to_str().expect("UTF-8 path"),
            "--exit-with-plant",
            "--run-folder",
            folder.to_str().expect("UTF-8 path"),
        ],
    )
}

/// Starts `rig launch <scenario> <extra…> --run-folder <folder>` as the process `rig`: the
/// service and the plant as the launcher's children, the way the README's main job runs.
pub fn start_launch(scenario: &Path, folder: &Path, extra: &[&str]) -> Proc {
    let mut args = vec!["launch", scenario.to_str().expect("UTF-8 path")];
    args.extend_from_slice(extra);
    args.extend(["--run-folder", folder.to_str().expect("UTF-8 path")]);
    Proc::start("rig", &bin("rig"), &args)
}

/// Starts `plant-proxy run <scenario> --mode lockstep --steps <steps> <extra…>` as the
/// process `name`.
pub fn start_lockstep_plant(name: &str, scenario: &Path, steps: u64, extra: &[&str]) -> Proc {
    let steps = steps.to_string();
    let mut args = vec![
        "run",
        scenario.to_str().expect("UTF-8 path"),
        "--mode",
        "lockstep",
        "--steps",
        &steps,
    ];
    args.extend_from_slice(extra);
    Proc::start(name, &bin("plant-proxy"), &args)
}

/// The index of column `name` in a CSV header; panics naming the header when absent.
pub fn column(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// A running process whose stderr lines are collected.
pub struct Proc {
    /// The child.
    pub child: Child,
    lines: Arc<Mutex<Vec<String>>>,
    rx: Receiver<String>,
    name: String,
}

impl Proc {
    /// Starts `program args…` with stdout and stderr captured.
    pub fn start(name: &str, program: &Path, args: &[&str]) -> Self {
        let mut command = Command::new(program);
        command.args(args);
        Self::spawn(name, command)
    }

    /// Starts `command` (its program, arguments and environment as set) with stdin empty
    /// and stdout and stderr captured.
    pub fn spawn(name: &str, mut command: Command) -> Self {
        let mut child = command
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| {
                panic!(
                    "starting {} ({name}): {e}",
                    command.get_program().to_string_lossy()
                )
            });
        let lines = Arc::new(Mutex::new(Vec::new()));
        let (tx, rx) = channel();
        for stream in [
            Box::new(child.stderr.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stdout.take().unwrap()),
        ] {
            let lines = lines.clone();
            let tx = tx.clone();
            let tag = name.to_string();
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    eprintln!("  [{tag}] {line}");
                    lines.lock().unwrap().push(line.clone());
                    let _ = tx.send(line);
                }
            });
        }
        Self {
            child,
            lines,
            rx,
            name: name.to_string(),
        }
    }

    /// Waits until a printed line contains `needle`; panics after `timeout`.
    pub fn wait_for_line(&self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        if let Some(l) = self
            .lines
            .lock()
            .unwrap()
            .iter()
            .find(|l| l.contains(needle))
        {
            return l.clone();
        }
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.rx.recv_timeout(left) {
                Ok(l) if l.contains(needle) => return l,
                Ok(_) => {}
                Err(_) => panic!(
                    "{} did not print '{needle}' within {:.1} s; it printed:\n{}",
                    self.name,
                    timeout.as_secs_f64(),
                    self.output()
                ),
            }
        }
    }

    /// Everything printed so far.
    pub fn output(&self) -> String {
        self.lines.lock().unwrap().join("\n")
    }

    /// Waits for the process to exit; panics after `timeout` (and kills it).
    pub fn wait(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(st) = self.child.try_wait().expect("try_wait") {
                // Let the reader threads catch the last lines.
                std::thread::sleep(Duration::from_millis(50));
                return st;
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                panic!(
                    "{} did not exit within {:.1} s; it printed:\n{}",
                    self.name,
                    timeout.as_secs_f64(),
                    self.output()
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Waits for the process to exit (see [`Self::wait`]) and asserts that it succeeded,
    /// showing what it printed when it did not.
    pub fn wait_success(&mut self, timeout: Duration) {
        let ok = self.wait(timeout).success();
        assert!(ok, "{} failed:\n{}", self.name, self.output());
    }

    /// Waits for the process to exit (see [`Self::wait`]), asserts that it failed, and
    /// returns what it printed.
    pub fn wait_failure(&mut self, timeout: Duration) -> String {
        let ok = self.wait(timeout).success();
        assert!(!ok, "{} succeeded:\n{}", self.name, self.output());
        self.output()
    }

    /// Sends a signal (e.g. `libc::SIGKILL`, `libc::SIGTERM`).
    pub fn signal(&self, sig: i32) {
        // SAFETY: kill with a pid we own and a valid signal number.
        unsafe { libc::kill(self.child.id() as i32, sig) };
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Reads `path`, panicking with its name when it cannot.
fn read_text(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

/// A fixture of the tests: the file `name` in `tests/fixtures/` (TOML tables that tests
/// put together into scenario files, e.g. `service-tables.toml`).
pub fn fixture(name: &str) -> String {
    read_text(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fixtures")
            .join(name),
    )
}

/// The controller most tests close the loop with: the static gain `u = −2 y`
/// (`scenarios/lti/static-gain.toml`, the controller file the examples of `ipc-types` run
/// the service with).
pub fn static_gain_controller() -> String {
    scenario_text("lti/static-gain.toml")
}

/// The service and log tables used by the tests (`fixtures/service-tables.toml`: no RT
/// privileges asked, the tests share two cores with the harness; blocking wait; quick
/// silence detection) with the lines `extra_service` added to `[service]`, then the
/// `controller` tables.
pub fn test_service_tables(extra_service: &str, controller: &str) -> String {
    format!(
        "\n{}{extra_service}\n\n{controller}\n",
        fixture("service-tables.toml")
    )
}

/// The tone plant of `scenarios/rcac-tone.toml` at 1 kHz under rig `rig`, with RCAC's
/// gradient update (`fixtures/rcac-gradient-tone-1khz-controller.toml`) whose `α` an
/// operator may set within [0.1, 1.0]: the run of the operator and monitor tests, written
/// into `dir` as `scenario.toml`.
pub fn operator_tone_scenario(dir: &TestDir, rig: &str) -> PathBuf {
    let plant = with_rig_name(&scenario_text("rcac-tone.toml"), rig)
        .replace("sample-period = 0.01\n", "sample-period = 0.001\n");
    let text = plant
        + &test_service_tables(
            "[service.operator]\ntunables = { alpha = [0.1, 1.0] }\n",
            &fixture("rcac-gradient-tone-1khz-controller.toml"),
        );
    dir.write("scenario.toml", &text)
}

/// A scenario file from the repository's `scenarios/` folder.
pub fn scenario_text(name: &str) -> String {
    read_text(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("scenarios")
            .join(name),
    )
}

/// The main job's scenario (`scenarios/acoustic-rig.toml`) under the rig name
/// [`rig_name`]`(test)`, with its target model named by absolute path, so that it runs from
/// a test folder.
pub fn acoustic_rig_scenario(test: &str) -> String {
    with_rig_name(&scenario_text("acoustic-rig.toml"), &rig_name(test)).replace(
        "target-model-file = \"rcac/acoustic-target.toml\"",
        &format!(
            "target-model-file = \"{}\"",
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../scenarios/rcac/acoustic-target.toml")
                .display()
        ),
    )
}

/// Replaces the rig name of a scenario text (so parallel tests do not share services).
pub fn with_rig_name(text: &str, rig: &str) -> String {
    let mut out = String::new();
    let mut in_rig = false;
    for line in text.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            in_rig = t == "[rig]";
        }
        if in_rig && t.starts_with("name") && t.contains('=') {
            out += &format!("name = \"{rig}\"\n");
        } else {
            out += line;
            out.push('\n');
        }
    }
    out
}

/// A unique rig name for one test.
pub fn rig_name(test: &str) -> String {
    format!("t-{test}-{}", std::process::id())
}

/// Reads a CSV file into its header and rows of numbers (non-numbers become NaN).
pub fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = read_text(path);
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(|s| s.to_string())
        .collect();
    let rows = lines
        .filter(|l| !l.is_empty())
        .map(|l| {
            l.split(',')
                .map(|v| v.parse::<f64>().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    (header, rows)
}

/// Runs `rig-design <args…>`; whether it succeeded, and what it printed (standard output,
/// then standard error).
pub fn rig_design(args: &[&str]) -> (bool, String) {
    let out = Command::new(bin("rig-design"))
        .args(args)
        .output()
        .expect("run rig-design");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.success(), text)
}

/// Reads a JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&read_text(path)).expect("valid JSON")
}

/// Runs the service (`run --exit-with-plant`) against plant-proxy in lockstep for `steps`
/// samples of `scenario`, plant-proxy getting `plant_extra` arguments too; asserts that both
/// exit successfully (plant within 300 s, service 60 s after) and returns the service's
/// run folder (`<dir>/service-run`).
pub fn run_lockstep_pair(
    dir: &TestDir,
    scenario: &Path,
    steps: u64,
    plant_extra: &[&str],
) -> PathBuf {
    run_lockstep_pair_into(dir, "service-run", scenario, steps, plant_extra, &[])
}

/// [`run_lockstep_pair`] into the run folder `<dir>/<folder>`, the service getting
/// `service_extra` arguments too.
pub fn run_lockstep_pair_into(
    dir: &TestDir,
    folder: &str,
    scenario: &Path,
    steps: u64,
    plant_extra: &[&str],
    service_extra: &[&str],
) -> PathBuf {
    let run_folder = dir.path.join(folder);
    let mut args = vec![
        "run",
        scenario.to_str().expect("UTF-8 path"),
        "--exit-with-plant",
        "--run-folder",
        run_folder.to_str().expect("UTF-8 path"),
    ];
    args.extend_from_slice(service_extra);
    let mut service = Proc::start("service", &bin("service"), &args);
    let mut plant = start_lockstep_plant("plant", scenario, steps, plant_extra);
    plant.wait_success(Duration::from_secs(300));
    service.wait_success(Duration::from_secs(60));
    run_folder
}

/// Amplitude of the tone at `w` rad/sample in `x[start..start + n]` (sample index `start`
/// first), by projection on sin/cos; exact for a whole number of periods.
pub fn tone_amplitude(x: &[f64], start: usize, n: usize, w: f64) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (i, v) in x[start..start + n].iter().enumerate() {
        let t = w * (start + i) as f64;
        s += v * t.sin();
        c += v * t.cos();
    }
    2.0 / n as f64 * (s * s + c * c).sqrt()
}
