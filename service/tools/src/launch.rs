//! The main job: the service against the simulated plant, as two real processes over
//! shared memory, then the run's figure.
//!
//! [`launch`] reads the scenario's service half (for the run folder, the sample period and
//! whether signals are logged), then starts `plant-proxy run` and `service run
//! --exit-with-plant` from the folder of this executable, both on the same scenario and
//! with the same run folder. The service prints its run report on its own standard
//! output; the plant writes `plant-report.json` into the run folder. When the service has
//! ended cleanly and logged its signals, [`launch`] draws `run.png` there
//! ([`crate::figures::run_folder_figure`]).
//!
//! Ending: each child gets `SIGTERM` if this process dies (`PR_SET_PDEATHSIG`, set by the
//! thread that starts them, which is the one that waits for them; a child whose parent
//! died before the setting took effect ends at once), so neither is left running alone. A
//! `SIGINT` or `SIGTERM` to the launcher is passed to the service (which flushes its logs
//! and reports) and, once the service has ended, to the plant. A plant that ends on its
//! own leaves the service 1.5 s to end by itself before it is stopped; a service that ends
//! leaves the plant 2 s. A child that the launcher stopped with `SIGTERM` and that is still
//! running 10 s later is killed (`SIGKILL`).
//!
//! Each child's end is its own stop reason: its exit code or the signal that ended it, and
//! whether the launcher stopped it and why. [`launch`] prints one line per child on
//! standard error (`[launch] service: exit 0`, `[launch] plant-proxy: killed by signal 9
//! (SIGKILL), not by the launcher`) and writes them, with the launch's outcome, into
//! `launch.json` in the run folder ([`LaunchRecord`], written atomically).
//!
//! The launch fails (exit code 1) when the service did not end cleanly — it died, refused
//! its configuration, or its run verdict failed (the service's exit status 1: it ended in
//! the safe state, spent more than `service.max-safe-state-share` of its closed-loop cycles
//! in it, its controller never ran, or the plant applied foreign inputs) — or when the
//! plant did not end cleanly (it died, refused its configuration or gave up) and the
//! launcher was not asked to stop. A configuration the launcher itself refuses exits with
//! 2 before anything starts.

use serde::Serialize;
use service::config::ServiceConfig;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// What [`launch`] runs.
#[derive(Debug, Clone, Default)]
pub struct LaunchOptions {
    /// The scenario (plant and service tables).
    pub config: PathBuf,
    /// The run folder (default: `<service.run-dir>/<rig>-<unix time>`).
    pub run_folder: Option<PathBuf>,
    /// Plant pacing, `real-time` or `lockstep` (passed to `plant-proxy run --mode`).
    pub mode: String,
    /// Seconds of plant time (default: the scenario's `rig.duration`).
    pub duration: Option<f64>,
    /// `sleep-poll`, `busy-poll` or `block`, passed to `service run --wait`.
    pub wait: Option<String>,
    /// The service's RT core, passed to `service run --core`.
    pub core: Option<usize>,
    /// A file whose `[controller]` (and `[log]`) replace the scenario's.
    pub controller: Option<PathBuf>,
    /// A `checkpoint.json` the controller starts from (`service run --warm-start`).
    pub warm_start: Option<PathBuf>,
    /// Have the plant write its per-sample trace (`plant-trace.csv` in the run folder:
    /// `k`, `t`, `y`, `z`, the applied `u`, the measurement's flags and the status of the
    /// actuation applied, `4294967295` for a miss).
    pub plant_trace: bool,
    /// Do not draw `run.png`.
    pub skip_figure: bool,
    /// Send the children's standard output and error into [`SERVICE_LOG_FILE`] and
    /// [`PLANT_LOG_FILE`] in the run folder instead of this process's (the run report is
    /// in `report.json` either way).
    pub child_logs: bool,
}

/// The service's standard output and error with [`LaunchOptions::child_logs`].
pub const SERVICE_LOG_FILE: &str = "service.log";
/// plant-proxy's standard output and error with [`LaunchOptions::child_logs`].
pub const PLANT_LOG_FILE: &str = "plant-proxy.log";

/// `cmd`'s standard output and error into the file `path`.
fn output_into(cmd: &mut Command, path: &Path) -> Result<(), LaunchError> {
    let err = |e: std::io::Error| LaunchError::Run(format!("creating {}: {e}", path.display()));
    let out = std::fs::File::create(path).map_err(err)?;
    let copy = out.try_clone().map_err(err)?;
    cmd.stdout(out).stderr(copy);
    Ok(())
}

/// The plant's per-sample trace in a run folder ([`LaunchOptions::plant_trace`]).
pub const PLANT_TRACE_FILE: &str = "plant-trace.csv";

/// Why a launch failed.
#[derive(Debug, thiserror::Error)]
pub enum LaunchError {
    /// The configuration was refused (exit code 2).
    #[error("configuration refused: {0}")]
    Config(String),
    /// A process could not be started, or the run failed (exit code 1): what failed, with
    /// the process or the file.
    #[error("{0}")]
    Run(String),
    /// The launch record could not be written (exit code 1).
    #[error("recording how the children ended: {0}")]
    Record(#[source] ipc_types::files::AtomicWriteError),
}

/// What a finished launch left.
#[derive(Debug, Clone)]
pub struct Launched {
    /// The run folder.
    pub folder: PathBuf,
    /// The figure, when one was drawn.
    pub figure: Option<PathBuf>,
    /// How each child ended (also in `launch.json`).
    pub record: LaunchRecord,
}

/// The file [`launch`] writes into the run folder: how each child ended, and the outcome.
pub const LAUNCH_RECORD_FILE: &str = "launch.json";

/// The children of a launch in `launch.json`.
#[derive(Debug, Clone, Serialize)]
pub struct LaunchChildren {
    /// `service run --exit-with-plant`.
    pub service: ChildEnd,
    /// `plant-proxy run`.
    #[serde(rename = "plant-proxy")]
    pub plant_proxy: ChildEnd,
}

/// `launch.json`: what was launched, how each child ended, and the launch's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct LaunchRecord {
    /// The rig name.
    pub rig: String,
    /// The scenario file.
    pub scenario: PathBuf,
    /// The plant's pacing (`real-time` or `lockstep`).
    pub mode: String,
    /// The run folder.
    pub run_folder: PathBuf,
    /// The signal the launcher itself got (`SIGINT`, `SIGTERM`), if any: it then stopped
    /// the children.
    pub launcher_signal: Option<String>,
    /// How each child ended.
    pub children: LaunchChildren,
    /// True when the launch succeeded (exit code 0).
    pub ok: bool,
    /// The launcher's exit code (0 or 1).
    pub exit_code: i32,
    /// Why the launch failed, when it did.
    pub failure: Option<String>,
}

/// How one child of a launch ended: its own stop reason.
#[derive(Debug, Clone, Serialize)]
pub struct ChildEnd {
    /// `service` or `plant-proxy`.
    pub name: String,
    /// Its process id (`None`: it could not be started).
    pub pid: Option<u32>,
    /// Its exit code, when it exited.
    pub exit_code: Option<i32>,
    /// The signal that ended it, when one did.
    pub signal: Option<i32>,
    /// The signal's name (`SIGKILL`, …).
    pub signal_name: Option<String>,
    /// Whether it dumped core.
    pub core_dumped: bool,
    /// Whether the launcher sent it `SIGTERM` (and `SIGKILL` if it would not end).
    pub stopped_by_launcher: bool,
    /// Why the launcher stopped it, when it did.
    pub stop_reason: Option<String>,
    /// True when it exited with code 0.
    pub clean: bool,
    /// One line: `exit 0`, `exit 2 (refused its configuration)`, `killed by signal 9
    /// (SIGKILL), not by the launcher`, …
    pub summary: String,
}

impl ChildEnd {
    /// The end of child `name` (pid `pid`) from its exit status (`None`: unknown, or it
    /// could not be started, as `not_started` says), and the launcher's stop reason if it
    /// stopped it.
    pub fn new(
        name: &str,
        pid: Option<u32>,
        status: Option<ExitStatus>,
        stop_reason: Option<String>,
        not_started: Option<String>,
    ) -> Self {
        let exit_code = status.and_then(|s| s.code());
        let signal = status.and_then(|s| s.signal());
        let by_launcher = match &stop_reason {
            Some(r) => format!("stopped by the launcher: {r}"),
            None => "not by the launcher".into(),
        };
        let summary = match (exit_code, signal, &not_started) {
            (_, _, Some(why)) => format!("not started: {why}"),
            (Some(c), _, _) => {
                let meaning = match c {
                    0 => String::new(),
                    1 => " (failed)".into(),
                    2 => " (refused its configuration)".into(),
                    _ => String::new(),
                };
                match &stop_reason {
                    Some(r) => format!("exit {c}{meaning} (stopped by the launcher: {r})"),
                    None => format!("exit {c}{meaning}"),
                }
            }
            (None, Some(s), _) => format!(
                "killed by signal {s} ({}){}, {by_launcher}",
                signal_name(s),
                if status.is_some_and(|st| st.core_dumped()) {
                    ", core dumped"
                } else {
                    ""
                }
            ),
            (None, None, _) => format!("status unknown, {by_launcher}"),
        };
        Self {
            name: name.to_string(),
            pid,
            exit_code,
            signal,
            signal_name: signal.map(|s| signal_name(s).to_string()),
            core_dumped: status.is_some_and(|s| s.core_dumped()),
            stopped_by_launcher: stop_reason.is_some(),
            stop_reason,
            clean: exit_code == Some(0),
            summary,
        }
    }
}

/// The name of signal `sig` (`SIGKILL`, …; `unknown signal` for others).
pub fn signal_name(sig: i32) -> &'static str {
    match sig {
        libc::SIGHUP => "SIGHUP",
        libc::SIGINT => "SIGINT",
        libc::SIGQUIT => "SIGQUIT",
        libc::SIGILL => "SIGILL",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGKILL => "SIGKILL",
        libc::SIGUSR1 => "SIGUSR1",
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGUSR2 => "SIGUSR2",
        libc::SIGPIPE => "SIGPIPE",
        libc::SIGALRM => "SIGALRM",
        libc::SIGTERM => "SIGTERM",
        libc::SIGXCPU => "SIGXCPU",
        libc::SIGXFSZ => "SIGXFSZ",
        libc::SIGSYS => "SIGSYS",
        _ => "unknown signal",
    }
}

/// A sibling executable of this one (`target/<profile>/<name>`).
fn sibling(name: &str) -> Result<PathBuf, LaunchError> {
    std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(|d| d.join(name)))
        .filter(|p| p.exists())
        .ok_or_else(|| {
            LaunchError::Run(format!(
                "{name} was not found next to this executable; build the workspace first \
                 (cargo build --release)"
            ))
        })
}

/// Starts `cmd` so that it gets `SIGTERM` when this thread's process dies.
fn spawn_tied(cmd: &mut Command, name: &str) -> Result<Child, LaunchError> {
    let me = std::process::id() as libc::pid_t;
    // SAFETY: the closure runs in the child between fork and exec and only calls prctl,
    // getppid and _exit, which are async-signal-safe, with valid arguments.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // The launcher died before the setting took effect: no signal will come.
            if libc::getppid() != me {
                libc::_exit(1);
            }
            Ok(())
        });
    }
    cmd.spawn()
        .map_err(|e| LaunchError::Run(format!("starting {name}: {e}")))
}

/// How long a child stopped with `SIGTERM` has before it is killed.
const KILL_AFTER: Duration = Duration::from_secs(10);
/// How long the service has to end by itself after the plant ended.
const SERVICE_GRACE: Duration = Duration::from_millis(1500);
/// How long the plant has to end by itself after the service ended.
const PLANT_GRACE: Duration = Duration::from_secs(2);

/// One child under supervision.
struct Supervised {
    name: &'static str,
    child: Child,
    status: Option<ExitStatus>,
    ended_at: Option<Instant>,
    /// Why and when the launcher sent `SIGTERM`.
    stopped: Option<(String, Instant)>,
    killed: bool,
}

impl Supervised {
    fn new(name: &'static str, child: Child) -> Self {
        Self {
            name,
            child,
            status: None,
            ended_at: None,
            stopped: None,
            killed: false,
        }
    }

    /// True once it has ended.
    fn poll(&mut self) -> bool {
        if self.status.is_none()
            && let Ok(Some(st)) = self.child.try_wait()
        {
            self.status = Some(st);
            self.ended_at = Some(Instant::now());
        }
        self.status.is_some()
    }

    fn signal(&self, sig: i32) {
        // SAFETY: kill with our own child's pid (not reaped yet) and a valid signal.
        unsafe { libc::kill(self.child.id() as i32, sig) };
    }

    /// Sends `SIGTERM` once, recording `why`.
    fn stop(&mut self, why: impl Into<String>) {
        if self.poll() || self.stopped.is_some() {
            return;
        }
        self.stopped = Some((why.into(), Instant::now()));
        self.signal(libc::SIGTERM);
    }

    /// Kills it when it was stopped more than [`KILL_AFTER`] ago and still runs.
    fn escalate(&mut self) {
        let due = self
            .stopped
            .as_ref()
            .is_some_and(|(_, at)| at.elapsed() >= KILL_AFTER);
        if due && !self.killed && !self.poll() {
            self.killed = true;
            self.signal(libc::SIGKILL);
        }
    }

    fn end(&self) -> ChildEnd {
        let reason = self.stopped.as_ref().map(|(why, _)| {
            if self.killed {
                format!(
                    "{why}; SIGKILL after it did not end within {} s of SIGTERM",
                    KILL_AFTER.as_secs()
                )
            } else {
                why.clone()
            }
        });
        ChildEnd::new(self.name, Some(self.child.id()), self.status, reason, None)
    }
}

/// Runs the main job (see the module docs). `stop` is set by a signal handler to the
/// number of the signal that asks it to end (0: none), e.g. with
/// `signal_hook::flag::register_usize`.
pub fn launch(opts: &LaunchOptions, stop: Arc<AtomicUsize>) -> Result<Launched, LaunchError> {
    let cfg = ServiceConfig::load_scenario(&opts.config, opts.controller.as_deref())
        .map_err(|e| LaunchError::Config(e.to_string()))?;
    let plant_bin = sibling("plant-proxy")?;
    let service_bin = sibling("service")?;
    let folder = opts.run_folder.clone().unwrap_or_else(|| {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        cfg.run_dir.join(format!("{}-{secs}", cfg.rig))
    });
    std::fs::create_dir_all(&folder)
        .map_err(|e| LaunchError::Run(format!("creating {}: {e}", folder.display())))?;

    let mut plant = Command::new(&plant_bin);
    plant
        .arg("run")
        .arg(&opts.config)
        .args(["--mode", &opts.mode])
        .arg("--report")
        .arg(folder.join("plant-report.json"))
        .stdin(Stdio::null());
    if let Some(d) = opts.duration {
        // plant-proxy validates it like `rig.duration` and refuses a bad value by name.
        plant.args(["--duration", &d.to_string()]);
    }
    if opts.plant_trace {
        plant.arg("--trace").arg(folder.join(PLANT_TRACE_FILE));
    }
    let mut service = Command::new(&service_bin);
    service
        .arg("run")
        .arg(&opts.config)
        .arg("--run-folder")
        .arg(&folder)
        .arg("--exit-with-plant")
        .stdin(Stdio::null());
    if let Some(w) = &opts.wait {
        service.args(["--wait", w]);
    }
    if let Some(c) = opts.core {
        service.args(["--core", &c.to_string()]);
    }
    if let Some(c) = &opts.controller {
        service.arg("--controller").arg(c);
    }
    if let Some(c) = &opts.warm_start {
        service.arg("--warm-start").arg(c);
    }
    if opts.child_logs {
        output_into(&mut service, &folder.join(SERVICE_LOG_FILE))?;
        output_into(&mut plant, &folder.join(PLANT_LOG_FILE))?;
    }
    eprintln!(
        "[launch] rig '{}': plant-proxy ({}) and the service, run folder {}",
        cfg.rig,
        opts.mode,
        folder.display()
    );
    let record = |service: ChildEnd, plant: ChildEnd, signal: Option<String>| LaunchRecord {
        rig: cfg.rig.clone(),
        scenario: opts.config.clone(),
        mode: opts.mode.clone(),
        run_folder: folder.clone(),
        launcher_signal: signal,
        children: LaunchChildren {
            service,
            plant_proxy: plant,
        },
        ok: false,
        exit_code: 1,
        failure: None,
    };
    let plant_child = spawn_tied(&mut plant, &plant_bin.display().to_string())?;
    let mut plant = Supervised::new("plant-proxy", plant_child);
    let service_child = match spawn_tied(&mut service, &service_bin.display().to_string()) {
        Ok(s) => s,
        Err(e) => {
            plant.stop("the service could not be started");
            while !plant.poll() {
                plant.escalate();
                std::thread::sleep(Duration::from_millis(20));
            }
            let not_started = ChildEnd::new("service", None, None, None, Some(e.to_string()));
            let mut r = record(not_started, plant.end(), None);
            for c in [&r.children.service, &r.children.plant_proxy] {
                eprintln!("[launch] {}: {}", c.name, c.summary);
            }
            r.failure = Some(e.to_string());
            let _ = finish_record(&r, &folder);
            return Err(e);
        }
    };
    let mut service = Supervised::new("service", service_child);

    let mut launcher_signal: Option<String> = None;
    loop {
        let service_done = service.poll();
        let plant_done = plant.poll();
        if service_done && plant_done {
            break;
        }
        let sig = stop.load(Ordering::Relaxed);
        if sig != 0 && launcher_signal.is_none() {
            let name = signal_name(sig as i32).to_string();
            service.stop(format!("the launcher got {name}"));
            launcher_signal = Some(name);
        }
        if let Some(name) = &launcher_signal {
            if service_done {
                plant.stop(format!(
                    "the launcher got {name}; the plant is stopped after the service"
                ));
            }
        } else if service_done {
            if service.ended_at.is_some_and(|t| t.elapsed() >= PLANT_GRACE) {
                plant.stop(format!(
                    "the service ended and the plant did not end within {} s",
                    PLANT_GRACE.as_secs_f64()
                ));
            }
        } else if plant_done && plant.ended_at.is_some_and(|t| t.elapsed() >= SERVICE_GRACE) {
            // The plant ended (its last sample, or an error): the service ends with it; if
            // it does not within 1.5 s, stop it.
            service.stop(format!(
                "the plant ended and the service did not end within {} s",
                SERVICE_GRACE.as_secs_f64()
            ));
        }
        service.escalate();
        plant.escalate();
        std::thread::sleep(Duration::from_millis(20));
    }

    let mut r = record(service.end(), plant.end(), launcher_signal.clone());
    for c in [&r.children.service, &r.children.plant_proxy] {
        eprintln!("[launch] {}: {}", c.name, c.summary);
    }
    let service_ok = r.children.service.clean;
    let plant_ok = r.children.plant_proxy.clean;
    let failure = if !service_ok {
        Some(format!(
            "the service did not end cleanly: {}",
            r.children.service.summary
        ))
    } else if !plant_ok && launcher_signal.is_none() {
        Some(format!(
            "plant-proxy did not end cleanly: {}",
            r.children.plant_proxy.summary
        ))
    } else {
        None
    };
    r.ok = failure.is_none();
    r.exit_code = if r.ok { 0 } else { 1 };
    r.failure = failure.clone();
    let written = finish_record(&r, &folder);
    // The figure of a service that ended cleanly, whatever the plant did.
    let figure = if service_ok && cfg.log.enabled && !opts.skip_figure {
        match crate::figures::run_folder_figure(&folder) {
            Ok(path) => Some(path),
            Err(e) => {
                eprintln!("rig: no figure: {e}");
                None
            }
        }
    } else {
        None
    };
    if let Some(f) = failure {
        return Err(LaunchError::Run(f));
    }
    written?;
    Ok(Launched {
        folder,
        figure,
        record: r,
    })
}

/// Writes `record` as [`LAUNCH_RECORD_FILE`] into `folder` (atomically); a failure is
/// printed and returned.
fn finish_record(record: &LaunchRecord, folder: &Path) -> Result<(), LaunchError> {
    let path = folder.join(LAUNCH_RECORD_FILE);
    let text = serde_json::to_string_pretty(record).expect("a launch record is plain data");
    ipc_types::files::write_atomic(&path, format!("{text}\n")).map_err(|e| {
        let e = LaunchError::Record(e);
        eprintln!("[launch] {e}");
        e
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(raw: i32) -> Option<ExitStatus> {
        Some(ExitStatus::from_raw(raw))
    }

    #[test]
    fn a_child_end_names_its_exit_code_or_its_signal_and_who_stopped_it() {
        let ok = ChildEnd::new("service", Some(7), status(0), None, None);
        assert!(ok.clean && ok.exit_code == Some(0) && ok.signal.is_none());
        assert_eq!(ok.summary, "exit 0");

        let refused = ChildEnd::new("plant-proxy", Some(8), status(2 << 8), None, None);
        assert!(!refused.clean);
        assert_eq!(refused.summary, "exit 2 (refused its configuration)");

        let killed = ChildEnd::new("plant-proxy", Some(8), status(libc::SIGKILL), None, None);
        assert_eq!(killed.signal, Some(9));
        assert_eq!(killed.signal_name.as_deref(), Some("SIGKILL"));
        assert!(!killed.stopped_by_launcher && !killed.clean);
        assert_eq!(
            killed.summary,
            "killed by signal 9 (SIGKILL), not by the launcher"
        );

        let stopped = ChildEnd::new(
            "service",
            Some(7),
            status(0),
            Some("the plant ended".into()),
            None,
        );
        assert!(stopped.clean && stopped.stopped_by_launcher);
        assert_eq!(
            stopped.summary,
            "exit 0 (stopped by the launcher: the plant ended)"
        );

        let none = ChildEnd::new("service", None, None, None, Some("no such file".into()));
        assert_eq!(none.summary, "not started: no such file");
        assert!(!none.clean);
    }
}
