//! The main job: the service against a plant, as real processes over shared memory, then
//! the run's figure.
//!
//! [`launch`] reads the scenario's service half (for the run folder, the sample period and
//! whether signals are logged), then starts the plant and `service run --exit-with-plant`
//! from the folder of this executable, both on the same scenario and with the same run
//! folder. The plant is [`LaunchOptions::plant`]:
//!
//! - [`PlantKind::Proxy`] (`--plant proxy`, the default): `plant-proxy run`, the scenario's
//!   simulated plant.
//! - [`PlantKind::Jack`] (`--plant jack`): `plant-jack run`, the plant side as a JACK
//!   client on the user's running JACK server (a sound card as the DAQ), wired as the
//!   scenario's `[jack]` table lists; in lockstep the server freewheels.
//! - [`PlantKind::JackRoom`] (`--plant jack-room`): the whole loop through a real audio
//!   server without a card. Before the plant and the service the launcher starts a dummy
//!   JACK server (`jackd -n SERVER -R -P PRIO -d dummy -r RATE -p FRAMES`, output in
//!   `jackd.log`) and the scenario's simulated plant as the JACK client `plant-jack room`
//!   (output in `room.log`), and waits, bounded, until each is ready; see [`jack`] for
//!   where `SERVER`, `RATE`, `FRAMES` and `PRIO` come from and when it refuses. After the
//!   service and the plant have ended it stops the room, then the server.
//!
//! The service prints its run report on its own standard output; the plant writes
//! `plant-report.json` into the run folder (plant-jack's has a `jack` object besides the
//! contract's counters). When the service has ended cleanly and logged its signals,
//! [`launch`] draws `run.png` there ([`crate::figures::run_folder_figure`]).
//!
//! Ending: each child gets `SIGTERM` if this process dies (`PR_SET_PDEATHSIG`, set by the
//! thread that starts them, which is the one that waits for them; a child whose parent
//! died before the setting took effect ends at once), so none is left running alone. A
//! `SIGINT` or `SIGTERM` to the launcher is passed to the service (which flushes its logs
//! and reports) and, once the service has ended, to the plant, then to the room and the
//! server. A plant that ends on its own leaves the service 1.5 s to end by itself before it
//! is stopped; a service that ends leaves the plant 2 s. A child that the launcher stopped
//! with `SIGTERM` and that is still running 10 s later is killed (`SIGKILL`). A room or
//! server that ends on its own during the run has the launcher stop the service and the
//! plant as on a signal.
//!
//! Each child's end is its own stop reason: its exit code or the signal that ended it, and
//! whether the launcher stopped it and why. [`launch`] prints one line per child on
//! standard error (`[launch] service: exit 0`, `[launch] plant-proxy: killed by signal 9
//! (SIGKILL), not by the launcher`) and writes them, with the launch's outcome, into
//! `launch.json` in the run folder ([`LaunchRecord`], written atomically).
//!
//! The launch fails (exit code 1) when a room or JACK server it started ended before the
//! launcher stopped it, or could not be started or made ready (the message names it and
//! its log); when the service did not end cleanly — it died, refused its configuration, or
//! its run verdict failed (the service's exit status 1: it ended in the safe state, spent
//! more than `service.max-safe-state-share` of its closed-loop cycles in it, its controller
//! never ran, or the plant applied foreign inputs) — or when the plant did not end cleanly
//! (it died, refused its configuration or gave up) and the launcher was not asked to stop.
//! A configuration the launcher itself refuses exits with 2 before anything starts: the
//! scenario, `--plant-trace` with a JACK plant (plant-jack writes no trace), a `[jack]`
//! table plant-jack would refuse, `--plant jack` without a running JACK server of the
//! scenario's name, `--plant jack-room` with one already running or without `jackd`.

pub mod jack;

use serde::Serialize;
use serde::ser::SerializeMap;
use service::config::ServiceConfig;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// Which plant [`launch`] runs against the service (`rig launch --plant`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum PlantKind {
    /// `plant-proxy run`: the scenario's simulated plant.
    #[default]
    Proxy,
    /// `plant-jack run` on the user's running JACK server: a sound card as the DAQ.
    Jack,
    /// `plant-jack run` on a dummy JACK server the launcher starts, against the scenario's
    /// simulated plant as the JACK client `plant-jack room`.
    JackRoom,
}

impl PlantKind {
    /// The name on the command line (`proxy`, `jack`, `jack-room`).
    pub const fn name(self) -> &'static str {
        match self {
            PlantKind::Proxy => "proxy",
            PlantKind::Jack => "jack",
            PlantKind::JackRoom => "jack-room",
        }
    }

    /// The plant's executable, next to this one (`plant-proxy`, `plant-jack`).
    pub const fn program(self) -> &'static str {
        match self {
            PlantKind::Proxy => "plant-proxy",
            PlantKind::Jack | PlantKind::JackRoom => "plant-jack",
        }
    }

    /// The plant's output file in the run folder with [`LaunchOptions::child_logs`]
    /// ([`PLANT_LOG_FILE`], [`JACK_PLANT_LOG_FILE`]).
    pub const fn log_file(self) -> &'static str {
        match self {
            PlantKind::Proxy => PLANT_LOG_FILE,
            PlantKind::Jack | PlantKind::JackRoom => JACK_PLANT_LOG_FILE,
        }
    }
}

/// What [`launch`] runs.
#[derive(Debug, Clone, Default)]
pub struct LaunchOptions {
    /// The scenario (plant and service tables).
    pub config: PathBuf,
    /// The run folder (default: `<service.run-dir>/<rig>-<unix time>`).
    pub run_folder: Option<PathBuf>,
    /// Plant pacing, `real-time` or `lockstep` (passed to the plant's `run --mode`).
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
    /// actuation applied, `4294967295` for a miss). plant-proxy only: refused with a JACK
    /// plant.
    pub plant_trace: bool,
    /// Do not draw `run.png`.
    pub skip_figure: bool,
    /// Send the service's and the plant's standard output and error into
    /// [`SERVICE_LOG_FILE`] and the plant's file ([`PlantKind::log_file`]) in the run
    /// folder instead of this process's (the run report is in `report.json` either way).
    /// The room's and the dummy server's always go into [`jack::ROOM_LOG_FILE`] and
    /// [`jack::JACKD_LOG_FILE`].
    pub child_logs: bool,
    /// The plant (default: plant-proxy).
    pub plant: PlantKind,
}

/// The service's standard output and error with [`LaunchOptions::child_logs`].
pub const SERVICE_LOG_FILE: &str = "service.log";
/// plant-proxy's standard output and error with [`LaunchOptions::child_logs`].
pub const PLANT_LOG_FILE: &str = "plant-proxy.log";
/// plant-jack's (`plant-jack run`) standard output and error with
/// [`LaunchOptions::child_logs`].
pub const JACK_PLANT_LOG_FILE: &str = "plant-jack.log";

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

/// The children of a launch in `launch.json`: `service`, the plant under
/// [`LaunchChildren::plant_key`], and with `--plant jack-room` also `room` and `jackd`.
#[derive(Debug, Clone)]
pub struct LaunchChildren {
    /// `service run --exit-with-plant`.
    pub service: ChildEnd,
    /// The plant: `plant-proxy run` or `plant-jack run` (its [`ChildEnd::name`] says
    /// which).
    pub plant: ChildEnd,
    /// `plant-jack room` (`--plant jack-room`; `None`: not started).
    pub room: Option<ChildEnd>,
    /// The dummy JACK server (`--plant jack-room`; `None`: not started).
    pub jackd: Option<ChildEnd>,
}

impl LaunchChildren {
    /// The plant's key in `launch.json`: `plant-proxy` for plant-proxy (as before there
    /// were other plants), `plant` for the others.
    pub fn plant_key(&self) -> &'static str {
        if self.plant.name == "plant-proxy" {
            "plant-proxy"
        } else {
            "plant"
        }
    }

    /// Every child that has an entry, in the order they are stopped.
    pub fn all(&self) -> impl Iterator<Item = &ChildEnd> {
        [Some(&self.service), Some(&self.plant)]
            .into_iter()
            .chain([self.room.as_ref(), self.jackd.as_ref()])
            .flatten()
    }
}

impl Serialize for LaunchChildren {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut map = s.serialize_map(None)?;
        map.serialize_entry("service", &self.service)?;
        map.serialize_entry(self.plant_key(), &self.plant)?;
        if let Some(r) = &self.room {
            map.serialize_entry("room", r)?;
        }
        if let Some(j) = &self.jackd {
            map.serialize_entry("jackd", j)?;
        }
        map.end()
    }
}

/// The JACK server of a JACK launch, in `launch.json`.
#[derive(Debug, Clone, Serialize)]
pub struct JackRecord {
    /// The server's name.
    pub server: String,
    /// The command line of the dummy server the launcher started (`--plant jack-room`;
    /// `None`: the user's server).
    pub jackd_command: Option<Vec<String>>,
    /// The room's JACK client (`--plant jack-room`).
    pub room_client: Option<String>,
}

/// `launch.json`: what was launched, how each child ended, and the launch's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct LaunchRecord {
    /// The rig name.
    pub rig: String,
    /// The scenario file.
    pub scenario: PathBuf,
    /// The plant (`proxy`, `jack`, `jack-room`).
    pub plant: PlantKind,
    /// The plant's pacing (`real-time` or `lockstep`).
    pub mode: String,
    /// The run folder.
    pub run_folder: PathBuf,
    /// The JACK server of a JACK launch (absent for plant-proxy).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub jack: Option<JackRecord>,
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
    /// `service`, `plant-proxy`, `plant-jack`, `room` or `jackd`.
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

/// The plant's command line: `plant-proxy run SCENARIO --mode M --report
/// RUN/plant-report.json [--duration D] [--trace RUN/plant-trace.csv]`, or the same with
/// `plant-jack run` for a JACK plant (which writes no trace); `program` is the plant's
/// executable ([`PlantKind::program`]), `folder` the run folder.
pub fn plant_command(program: &Path, opts: &LaunchOptions, folder: &Path) -> Command {
    let mut plant = Command::new(program);
    plant
        .arg("run")
        .arg(&opts.config)
        .args(["--mode", &opts.mode])
        .arg("--report")
        .arg(folder.join("plant-report.json"))
        .stdin(Stdio::null());
    if let Some(d) = opts.duration {
        // The plant validates it like `rig.duration` and refuses a bad value by name.
        plant.args(["--duration", &d.to_string()]);
    }
    if opts.plant_trace && opts.plant == PlantKind::Proxy {
        plant.arg("--trace").arg(folder.join(PLANT_TRACE_FILE));
    }
    plant
}

/// The service's command line: `service run SCENARIO --run-folder RUN --exit-with-plant
/// [--wait W] [--core C] [--controller FILE] [--warm-start FILE]`.
pub fn service_command(program: &Path, opts: &LaunchOptions, folder: &Path) -> Command {
    let mut service = Command::new(program);
    service
        .arg("run")
        .arg(&opts.config)
        .arg("--run-folder")
        .arg(folder)
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
    service
}

/// Refuses a JACK launch whose server is not as it needs: `--plant jack-room` starts its
/// own server, so none of that name may run; `--plant jack` runs on the user's, so one
/// must (checked when `jack_lsp` is on `PATH`).
fn check_server(
    plant: PlantKind,
    setup: &jack::JackSetup,
    tools: Option<&jack::JackTools>,
) -> Result<(), LaunchError> {
    let server = &setup.server;
    let lsp = match (plant, tools) {
        (PlantKind::JackRoom, Some(t)) => t.jack_lsp.clone(),
        (PlantKind::Jack, _) => match jack::on_path("jack_lsp") {
            Some(p) => p,
            None => return Ok(()),
        },
        _ => return Ok(()),
    };
    let running = jack::server_ports(&lsp, server)
        .map_err(|e| LaunchError::Config(format!("checking the JACK server '{server}': {e}")))?
        .is_some();
    match (plant, running) {
        (PlantKind::JackRoom, true) => Err(LaunchError::Config(format!(
            "a JACK server named '{server}' is already running: --plant jack-room starts its \
             own dummy server and does not share one; stop it (its jackd), set another \
             jack.server in the scenario, or use --plant jack to run on it"
        ))),
        (PlantKind::Jack, false) => Err(LaunchError::Config(format!(
            "no JACK server named '{server}' is running: --plant jack runs on yours (start it \
             with the card, e.g. `jackd -n {server} -R -d alsa -r {} -p {}`), or use --plant \
             jack-room for a dummy server and the simulated room",
            setup.rate, setup.period_frames
        ))),
        _ => Ok(()),
    }
}

/// Stops `s` (`SIGTERM`, then `SIGKILL`) and waits until it has ended.
fn stop_and_wait(s: &mut Supervised, why: &str) {
    s.stop(why);
    while !s.poll() {
        s.escalate();
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs the main job (see the module docs). `stop` is set by a signal handler to the
/// number of the signal that asks it to end (0: none), e.g. with
/// `signal_hook::flag::register_usize`.
pub fn launch(opts: &LaunchOptions, stop: Arc<AtomicUsize>) -> Result<Launched, LaunchError> {
    let cfg = ServiceConfig::load_scenario(&opts.config, opts.controller.as_deref())
        .map_err(|e| LaunchError::Config(e.to_string()))?;
    if opts.plant_trace && opts.plant != PlantKind::Proxy {
        return Err(LaunchError::Config(format!(
            "--plant-trace needs --plant proxy: plant-jack (--plant {}) writes no per-sample \
             trace (the service's signals.csv has y, z and u of every sample)",
            opts.plant.name()
        )));
    }
    let setup = match opts.plant {
        PlantKind::Proxy => None,
        PlantKind::Jack | PlantKind::JackRoom => Some(jack::JackSetup::load(
            &opts.config,
            jack::mode_of(&opts.mode),
        )?),
    };
    let tools = match opts.plant {
        PlantKind::JackRoom => Some(jack::JackTools::find()?),
        PlantKind::Proxy | PlantKind::Jack => None,
    };
    if let Some(s) = &setup {
        check_server(opts.plant, s, tools.as_ref())?;
    }
    let plant_bin = sibling(opts.plant.program())?;
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

    let mut plant = plant_command(&plant_bin, opts, &folder);
    let mut service = service_command(&service_bin, opts, &folder);
    if opts.child_logs {
        output_into(&mut service, &folder.join(SERVICE_LOG_FILE))?;
        output_into(&mut plant, &folder.join(opts.plant.log_file()))?;
    }
    let plant_name = opts.plant.program();
    match (&setup, &tools) {
        (Some(s), Some(_)) => eprintln!(
            "[launch] rig '{}': a dummy JACK server '{}' ({} Hz, {} frames per period), the \
             room '{}', {plant_name} ({}) and the service, run folder {}",
            cfg.rig,
            s.server,
            s.rate,
            s.period_frames,
            s.room_client,
            opts.mode,
            folder.display()
        ),
        (Some(s), None) => eprintln!(
            "[launch] rig '{}': {plant_name} ({}) on JACK server '{}' and the service, run \
             folder {}",
            cfg.rig,
            opts.mode,
            s.server,
            folder.display()
        ),
        _ => eprintln!(
            "[launch] rig '{}': {plant_name} ({}) and the service, run folder {}",
            cfg.rig,
            opts.mode,
            folder.display()
        ),
    }
    let jack_record = setup.as_ref().map(|s| JackRecord {
        server: s.server.clone(),
        jackd_command: tools
            .as_ref()
            .map(|t| jack::command_line(&jack::jackd_command(&t.jackd, s))),
        room_client: tools.as_ref().map(|_| s.room_client.clone()),
    });
    let record = |children: LaunchChildren, signal: Option<String>| LaunchRecord {
        rig: cfg.rig.clone(),
        scenario: opts.config.clone(),
        plant: opts.plant,
        mode: opts.mode.clone(),
        run_folder: folder.clone(),
        jack: jack_record.clone(),
        launcher_signal: signal,
        children,
        ok: false,
        exit_code: 1,
        failure: None,
    };
    let print = |children: &LaunchChildren| {
        for c in children.all() {
            eprintln!("[launch] {}: {}", c.name, c.summary);
        }
    };
    // Ends a launch before its run: stops the plant if it was started, then the room and
    // the server, records the children (the service and a plant not started, with
    // `service_not_started`, `why`) and fails with `failure`.
    let abandon = |fixtures: &mut jack::Fixtures,
                   plant: Option<&mut Supervised>,
                   why: &str,
                   service_not_started: String,
                   failure: String,
                   signal: Option<String>| {
        let plant = match plant {
            Some(p) => {
                stop_and_wait(p, why);
                p.end()
            }
            None => ChildEnd::new(plant_name, None, None, None, Some(why.to_string())),
        };
        fixtures.stop_all(why);
        let (room, jackd) = fixtures.ends();
        let service = ChildEnd::new("service", None, None, None, Some(service_not_started));
        let mut r = record(
            LaunchChildren {
                service,
                plant,
                room,
                jackd,
            },
            signal,
        );
        print(&r.children);
        r.failure = Some(failure.clone());
        let _ = finish_record(&r, &folder);
        LaunchError::Run(failure)
    };

    let mut fixtures = jack::Fixtures::default();
    if let (Some(s), Some(t)) = (&setup, &tools) {
        if !s.plant_hears_the_room() {
            eprintln!(
                "[launch] note: the scenario's jack.y, jack.z and jack.u name none of the \
                 room's ports ({}): the plant side will not be wired to the room",
                s.room_ports.join(", ")
            );
        }
        if let Err(f) = fixtures.start(s, t, &plant_bin, &opts.config, &folder, &stop) {
            let (why, failure, signal) = match f {
                jack::StartFailure::Failed(m) => {
                    let which = if fixtures.room.is_some() {
                        "the room was not ready"
                    } else {
                        "the JACK server was not ready"
                    };
                    (which.to_string(), m, None)
                }
                jack::StartFailure::Signal(n) => (
                    format!("the launcher got {n}"),
                    format!("the launcher got {n} while starting the JACK server and the room"),
                    Some(n),
                ),
            };
            return Err(abandon(
                &mut fixtures,
                None,
                &why,
                why.clone(),
                failure,
                signal,
            ));
        }
    }

    let mut plant = match spawn_tied(&mut plant, &plant_bin.display().to_string()) {
        Ok(child) => Supervised::new(plant_name, child),
        Err(e) => {
            let why = format!("{plant_name} could not be started");
            return Err(abandon(
                &mut fixtures,
                None,
                &why,
                why.clone(),
                e.to_string(),
                None,
            ));
        }
    };
    let mut service = match spawn_tied(&mut service, &service_bin.display().to_string()) {
        Ok(s) => Supervised::new("service", s),
        Err(e) => {
            return Err(abandon(
                &mut fixtures,
                Some(&mut plant),
                "the service could not be started",
                e.to_string(),
                e.to_string(),
                None,
            ));
        }
    };

    let mut launcher_signal: Option<String> = None;
    // A room or server that ended on its own: why the launch fails.
    let mut fixture_ended: Option<String> = None;
    // Why the launcher stops the service, then the plant: a signal or a fixture's end.
    let mut stopping: Option<String> = None;
    loop {
        let service_done = service.poll();
        let plant_done = plant.poll();
        if fixture_ended.is_none()
            && let Some((name, message)) = fixtures.ended_on_its_own()
        {
            eprintln!("[launch] {message}");
            stopping.get_or_insert_with(|| format!("{name} ended on its own"));
            fixture_ended = Some(message);
        }
        if service_done && plant_done {
            break;
        }
        let sig = stop.load(Ordering::Relaxed);
        if sig != 0 && launcher_signal.is_none() {
            let name = signal_name(sig as i32).to_string();
            stopping.get_or_insert_with(|| format!("the launcher got {name}"));
            launcher_signal = Some(name);
        }
        if let Some(why) = &stopping {
            if service.stopped.is_none() {
                service.stop(why.clone());
            }
            if service_done {
                plant.stop(format!("{why}; the plant is stopped after the service"));
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
    // The room and the server last, once the service and the plant have ended.
    let fixture_ended = fixture_ended.or_else(|| fixtures.ended_on_its_own().map(|(_, m)| m));
    fixtures.stop_all(&match &launcher_signal {
        Some(name) => format!("the launcher got {name}; stopped after the service and the plant"),
        None => "the service and the plant ended".to_string(),
    });
    let (room, jackd) = fixtures.ends();

    let mut r = record(
        LaunchChildren {
            service: service.end(),
            plant: plant.end(),
            room,
            jackd,
        },
        launcher_signal.clone(),
    );
    print(&r.children);
    let service_ok = r.children.service.clean;
    let plant_ok = r.children.plant.clean;
    let failure = if let Some(f) = fixture_ended {
        Some(f)
    } else if !service_ok {
        Some(format!(
            "the service did not end cleanly: {}",
            r.children.service.summary
        ))
    } else if !plant_ok && launcher_signal.is_none() {
        Some(format!(
            "{plant_name} did not end cleanly: {}",
            r.children.plant.summary
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

    fn words(cmd: &Command) -> Vec<String> {
        jack::command_line(cmd)
    }

    fn options(plant: PlantKind) -> LaunchOptions {
        LaunchOptions {
            config: "/s/rig.toml".into(),
            mode: "lockstep".into(),
            duration: Some(1.5),
            plant,
            ..Default::default()
        }
    }

    #[test]
    fn plant_proxy_runs_the_scenario_with_its_report_and_trace_in_the_run_folder() {
        let mut o = options(PlantKind::Proxy);
        o.plant_trace = true;
        let cmd = plant_command(Path::new("/b/plant-proxy"), &o, Path::new("/run"));
        assert_eq!(
            words(&cmd),
            [
                "/b/plant-proxy",
                "run",
                "/s/rig.toml",
                "--mode",
                "lockstep",
                "--report",
                "/run/plant-report.json",
                "--duration",
                "1.5",
                "--trace",
                "/run/plant-trace.csv"
            ]
        );
    }

    #[test]
    fn plant_jack_runs_the_scenario_with_its_report_and_no_trace() {
        for kind in [PlantKind::Jack, PlantKind::JackRoom] {
            let mut o = options(kind);
            o.duration = None;
            assert_eq!(kind.program(), "plant-jack");
            assert_eq!(kind.log_file(), "plant-jack.log");
            let cmd = plant_command(Path::new("/b/plant-jack"), &o, Path::new("/run"));
            assert_eq!(
                words(&cmd),
                [
                    "/b/plant-jack",
                    "run",
                    "/s/rig.toml",
                    "--mode",
                    "lockstep",
                    "--report",
                    "/run/plant-report.json"
                ]
            );
        }
        assert_eq!(PlantKind::Proxy.log_file(), PLANT_LOG_FILE);
    }

    #[test]
    fn the_service_runs_until_the_plant_ends_with_the_launchers_overrides() {
        let mut o = options(PlantKind::JackRoom);
        o.wait = Some("block".into());
        o.core = Some(1);
        o.controller = Some("/c.toml".into());
        o.warm_start = Some("/w.json".into());
        let cmd = service_command(Path::new("/b/service"), &o, Path::new("/run"));
        assert_eq!(
            words(&cmd),
            [
                "/b/service",
                "run",
                "/s/rig.toml",
                "--run-folder",
                "/run",
                "--exit-with-plant",
                "--wait",
                "block",
                "--core",
                "1",
                "--controller",
                "/c.toml",
                "--warm-start",
                "/w.json"
            ]
        );
    }

    #[test]
    fn a_jack_plant_with_a_trace_is_refused_before_anything_starts() {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let run = std::env::temp_dir().join(format!("launch-trace-{}", std::process::id()));
        let mut o = options(PlantKind::Jack);
        o.config = repo.join("scenarios/first-order-lockstep.toml");
        o.controller = Some(repo.join("scenarios/lti/static-gain.toml"));
        o.plant_trace = true;
        o.run_folder = Some(run.clone());
        let e = launch(&o, Arc::new(AtomicUsize::new(0))).unwrap_err();
        assert!(
            matches!(&e, LaunchError::Config(m) if m.contains("--plant-trace")),
            "{e}"
        );
        assert!(!run.exists(), "a refused launch made {}", run.display());
    }

    #[test]
    fn launch_json_keeps_the_plant_proxy_key_and_names_a_jack_plant_plant() {
        let end = |name: &str| ChildEnd::new(name, Some(1), status(0), None, None);
        let proxy = LaunchChildren {
            service: end("service"),
            plant: end("plant-proxy"),
            room: None,
            jackd: None,
        };
        let v = serde_json::to_value(&proxy).unwrap();
        let mut keys: Vec<_> = v.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        assert_eq!(keys, ["plant-proxy", "service"]);
        assert_eq!(v["plant-proxy"]["name"], "plant-proxy");

        let room = LaunchChildren {
            service: end("service"),
            plant: end("plant-jack"),
            room: Some(end("room")),
            jackd: Some(end("jackd")),
        };
        let v = serde_json::to_value(&room).unwrap();
        let mut keys: Vec<_> = v.as_object().unwrap().keys().cloned().collect();
        keys.sort();
        assert_eq!(keys, ["jackd", "plant", "room", "service"]);
        assert_eq!(v["plant"]["name"], "plant-jack");
        let order: Vec<_> = room.all().map(|c| c.name.as_str()).collect();
        assert_eq!(order, ["service", "plant-jack", "room", "jackd"]);
        assert_eq!(
            serde_json::to_value(PlantKind::JackRoom).unwrap(),
            "jack-room"
        );
    }
}
