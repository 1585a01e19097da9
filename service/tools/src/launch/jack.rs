//! The JACK side of `rig launch --plant jack` and `--plant jack-room`: what the scenario
//! asks of the JACK server, the commands that start a dummy server and the simulated room,
//! and the probes that tell when each is ready.
//!
//! With `--plant jack-room` the launcher runs the whole loop through a real audio server
//! without a sound card. Before the plant and the service it starts
//!
//! ```text
//! jackd -n SERVER -R -P PRIO -d dummy -r RATE -p FRAMES      (output: RUN/jackd.log)
//! plant-jack room SCENARIO                                    (output: RUN/room.log)
//! ```
//!
//! where `SERVER` is the scenario's `jack.server` (else `$JACK_DEFAULT_SERVER`, else
//! `default`: [`plant_jack::jack_server::server_name`]), `RATE = round(1 /
//! rig.sample-period)`, `FRAMES` is `jack.period-frames` (else
//! [`DEFAULT_PERIOD_FRAMES`]) and `PRIO` is `proxy.fifo-priority` (70 unless set;
//! `fifo-priority = 0` gives `--no-realtime`). `jackd` is pinned to `proxy.core` when set,
//! as the plant side pins its JACK thread there. It refuses before anything starts when
//! `jackd` or `jack_lsp` is not on `PATH` (Debian's jackd2 brings both) or when a server of
//! that name already runs: the launcher starts its own server and would not share one.
//!
//! Ready means: the server answers `jack_lsp -s SERVER` (within [`READY_WITHIN`]); then
//! the room has printed the line of an active client into its log and its ports
//! (`ROOM:speaker-u0…`, `ROOM:mic-y0…`, `ROOM:mic-z0…`) are on the server (within
//! [`READY_WITHIN`] again). A server or room that ends before it is ready, or is not ready
//! in time, fails the launch, naming it and its log.
//!
//! Both run in their own process group, so that a terminal's `Ctrl-C` reaches the launcher
//! and not them: the launcher stops them itself, after the service and the plant, room
//! first (`SIGTERM`, then `SIGKILL` after 10 s). Like every child of the launcher they get
//! `SIGTERM` if the launcher dies.

use super::{ChildEnd, LaunchError, Supervised, signal_name, spawn_tied, stop_and_wait};
use plant_jack::jack_config::{Channels, JackConfig};
use plant_proxy::runtime::{Mode, ProxyConfig};
use std::io::Read;
use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// The dummy server's period, frames, when the scenario's `jack.period-frames` is not set.
pub const DEFAULT_PERIOD_FRAMES: u32 = 32;
/// How long the launcher waits for the dummy server to answer, and then for the room.
pub const READY_WITHIN: Duration = Duration::from_secs(10);
/// How long one `jack_lsp` may take before the server is taken for stuck.
const PROBE_WITHIN: Duration = Duration::from_secs(5);
/// How often readiness is probed.
const PROBE_EVERY: Duration = Duration::from_millis(100);
/// jackd's standard output and error, in the run folder (always, with `--plant jack-room`).
pub const JACKD_LOG_FILE: &str = "jackd.log";
/// The room's standard output and error, in the run folder (always, with `--plant
/// jack-room`).
pub const ROOM_LOG_FILE: &str = "room.log";
/// The start of the line `plant-jack room` prints once its client is active.
const ROOM_ACTIVE_LINE: &str = "[room] rig '";

/// What a JACK launch takes from the scenario: the server and, for `--plant jack-room`,
/// how to start a dummy one and which ports the room registers.
#[derive(Debug, Clone, PartialEq)]
pub struct JackSetup {
    /// The server's name (`jack.server`, else `$JACK_DEFAULT_SERVER`, else `default`).
    pub server: String,
    /// The room's client name (`jack.room.client`).
    pub room_client: String,
    /// The sample rate, Hz: `round(1 / rig.sample-period)`.
    pub rate: u32,
    /// Frames per period: `jack.period-frames`, else [`DEFAULT_PERIOD_FRAMES`].
    pub period_frames: u32,
    /// The server's `SCHED_FIFO` priority: `proxy.fifo-priority` (70 unless set; `None`
    /// when the scenario disables it with 0).
    pub fifo_priority: Option<i32>,
    /// The core the plant side pins its JACK thread to (`proxy.core`), where the server
    /// is pinned too.
    pub core: Option<usize>,
    /// The ports the room registers, full names (`room:speaker-u0`, …, `room:mic-y0`, …,
    /// `room:mic-z0`, …).
    pub room_ports: Vec<String>,
    /// The ports the plant side connects to (`jack.y`, `jack.z`, `jack.u`).
    pub plant_peers: Vec<String>,
}

impl JackSetup {
    /// Reads the scenario file `path` for a plant that runs in `mode` (the launcher's
    /// `--mode`, when it is one plant-jack knows).
    ///
    /// # Errors
    ///
    /// [`LaunchError::Config`] naming the file and the field.
    pub fn load(path: &Path, mode: Option<Mode>) -> Result<Self, LaunchError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| LaunchError::Config(format!("{origin}: {e}")))?;
        Self::parse(&text, &origin, mode).map_err(LaunchError::Config)
    }

    /// [`JackSetup::load`] of a scenario's text; `origin` names it in a refusal.
    ///
    /// # Errors
    ///
    /// The refusal of the `[rig]`, `[plant]`, `[proxy]` or `[jack]` table, or a sample
    /// period that is not a whole number of hertz.
    pub fn parse(text: &str, origin: &str, mode: Option<Mode>) -> Result<Self, String> {
        let scenario = plant_proxy::scenario::parse(text, origin).map_err(|e| e.to_string())?;
        let p = &scenario.plant;
        let ch = Channels {
            n_y: p.n_y(),
            n_z: p.n_z(),
            n_r: p.n_r(),
            n_u: p.n_u(),
        };
        let jack = JackConfig::parse(text, origin, ch).map_err(|e| e.to_string())?;
        let proxy =
            ProxyConfig::parse_with_mode(text, origin, ch.n_u, mode).map_err(|e| e.to_string())?;
        let period = scenario.rig.sample_period;
        let rate = (1.0 / period).round();
        // plant-jack compares the periods in whole nanoseconds (jack_server::check_timing).
        let period_ns = (period * 1e9).round() as u64;
        let whole = rate >= 1.0
            && rate <= f64::from(u32::MAX)
            && (1_000_000_000 + rate as u64 / 2) / rate as u64 == period_ns;
        if !whole {
            return Err(format!(
                "{origin}: field 'rig.sample-period': {period} s is not the period of a whole \
                 number of hertz, which a JACK server runs at"
            ));
        }
        if let Some(c) = proxy.plant.rt.core
            && c >= libc::CPU_SETSIZE as usize
        {
            return Err(format!(
                "{origin}: field 'proxy.core': {c} is not a core this launcher can pin to"
            ));
        }
        let room = &jack.room.client;
        let room_ports = (0..ch.n_u)
            .map(|j| format!("{room}:speaker-u{j}"))
            .chain((0..ch.n_y).map(|j| format!("{room}:mic-y{j}")))
            .chain((0..ch.n_z).map(|j| format!("{room}:mic-z{j}")))
            .collect();
        Ok(Self {
            server: plant_jack::jack_server::server_name(jack.server.as_deref()),
            room_client: room.clone(),
            rate: rate as u32,
            period_frames: jack.period_frames.unwrap_or(DEFAULT_PERIOD_FRAMES),
            fifo_priority: proxy.plant.rt.fifo_priority,
            core: proxy.plant.rt.core,
            room_ports,
            plant_peers: jack
                .y
                .iter()
                .chain(&jack.z)
                .chain(&jack.u)
                .cloned()
                .collect(),
        })
    }

    /// True when the plant side connects to at least one of the room's ports.
    pub fn plant_hears_the_room(&self) -> bool {
        self.plant_peers.iter().any(|p| self.room_ports.contains(p))
    }
}

/// The plant's pacing for plant-jack's `--mode`, when `mode` is one it knows (`None`: the
/// plant refuses it by itself).
pub fn mode_of(mode: &str) -> Option<Mode> {
    match mode {
        "lockstep" => Some(Mode::Lockstep),
        "real-time" | "realtime" => Some(Mode::RealTime),
        _ => None,
    }
}

/// The JACK tools the launcher runs, found on `PATH`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JackTools {
    /// The server.
    pub jackd: PathBuf,
    /// Lists a server's ports: whether it answers, and whether the room's ports are there.
    pub jack_lsp: PathBuf,
}

impl JackTools {
    /// Finds `jackd` and `jack_lsp` on `PATH`.
    ///
    /// # Errors
    ///
    /// [`LaunchError::Config`] naming the missing program and the package.
    pub fn find() -> Result<Self, LaunchError> {
        let find = |name: &str| {
            on_path(name).ok_or_else(|| {
                LaunchError::Config(format!(
                    "--plant jack-room starts a JACK server, but {name} is not on PATH: \
                     install Debian's jackd2 (apt-get install jackd2)"
                ))
            })
        };
        Ok(Self {
            jackd: find("jackd")?,
            jack_lsp: find("jack_lsp")?,
        })
    }
}

/// The executable file `name` in a folder of `$PATH`.
pub fn on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| {
            std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        })
}

/// The dummy server's command line, `jackd -n SERVER -R -P PRIO -d dummy -r RATE -p
/// FRAMES` (`--no-realtime` instead of `-R -P PRIO` when the scenario disables
/// `SCHED_FIFO`); its output, pinning and process group are the caller's.
pub fn jackd_command(jackd: &Path, setup: &JackSetup) -> Command {
    let mut cmd = Command::new(jackd);
    cmd.args(["-n", &setup.server]);
    match setup.fifo_priority {
        Some(p) => cmd.args(["-R", "-P", &p.to_string()]),
        None => cmd.arg("--no-realtime"),
    };
    cmd.args(["-d", "dummy", "-r", &setup.rate.to_string()])
        .args(["-p", &setup.period_frames.to_string()])
        .stdin(Stdio::null());
    cmd
}

/// The room's command line, `plant-jack room SCENARIO` (until `SIGTERM`).
pub fn room_command(plant_jack: &Path, scenario: &Path) -> Command {
    let mut cmd = Command::new(plant_jack);
    cmd.arg("room").arg(scenario).stdin(Stdio::null());
    cmd
}

/// The command line of `cmd`, words separated by spaces (for the record).
pub fn command_line(cmd: &Command) -> Vec<String> {
    std::iter::once(cmd.get_program())
        .chain(cmd.get_args())
        .map(|w| w.to_string_lossy().into_owned())
        .collect()
}

/// The ports of the JACK server `server` (`jack_lsp -s SERVER`, never starting one), or
/// `None` when no server of that name answers.
///
/// # Errors
///
/// `jack_lsp` could not be run, or did not end within 5 s.
pub fn server_ports(jack_lsp: &Path, server: &str) -> Result<Option<Vec<String>>, String> {
    let mut child = Command::new(jack_lsp)
        .args(["-s", server])
        .env("JACK_NO_START_SERVER", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("running {}: {e}", jack_lsp.display()))?;
    let mut out = child.stdout.take().expect("stdout is piped");
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = out.read_to_string(&mut text);
        text
    });
    let deadline = Instant::now() + PROBE_WITHIN;
    let status = loop {
        match child.try_wait() {
            Ok(Some(st)) => break st,
            Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(10)),
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!(
                    "`jack_lsp -s {server}` did not end within {} s (is the server stuck?)",
                    PROBE_WITHIN.as_secs()
                ));
            }
            Err(e) => return Err(format!("waiting for jack_lsp: {e}")),
        }
    };
    let text = reader.join().unwrap_or_default();
    Ok(status
        .success()
        .then(|| text.lines().map(str::to_string).collect()))
}

/// Pins what `cmd` starts to `core` (`sched_setaffinity` between fork and exec).
fn pin_to(cmd: &mut Command, core: usize) {
    // SAFETY: a zeroed cpu_set_t is the empty set; `core` is below CPU_SETSIZE (checked by
    // JackSetup::parse), so CPU_SET stays within it.
    let set = unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(core, &mut set);
        set
    };
    // SAFETY: the closure runs in the child between fork and exec and only calls
    // sched_setaffinity (a system call, async-signal-safe) on itself with a valid set.
    unsafe {
        cmd.pre_exec(move || {
            if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

/// One of the launch's fixtures (the dummy server, the room): a child with its log.
pub(super) struct Fixture {
    /// The child.
    pub sup: Supervised,
    /// Its output.
    pub log: PathBuf,
    /// How messages name it, in full.
    pub what: String,
    /// How a stop reason names it (`the room`, `the JACK server`).
    pub short: &'static str,
}

impl Fixture {
    fn started(
        name: &'static str,
        short: &'static str,
        what: String,
        mut cmd: Command,
        log: PathBuf,
    ) -> Result<Self, String> {
        super::output_into(&mut cmd, &log).map_err(|e| e.to_string())?;
        // Its own process group: a terminal's Ctrl-C is the launcher's to pass on, in order.
        cmd.process_group(0);
        let child = spawn_tied(&mut cmd, name).map_err(|e| format!("{what}: {e}"))?;
        Ok(Self {
            sup: Supervised::new(name, child),
            log,
            what,
            short,
        })
    }
}

/// Why starting the fixtures did not succeed.
pub(super) enum StartFailure {
    /// One could not be started or was not ready: the message names it and its log.
    Failed(String),
    /// The launcher got this signal meanwhile.
    Signal(String),
}

/// The fixtures of a `--plant jack-room` launch, each once started.
#[derive(Default)]
pub(super) struct Fixtures {
    /// The dummy JACK server.
    pub jackd: Option<Fixture>,
    /// The simulated room.
    pub room: Option<Fixture>,
}

impl Fixtures {
    /// Starts the dummy server and waits until it answers, then the room and waits until
    /// its ports are on the server. On failure what was started stays here for the caller
    /// to stop ([`Fixtures::stop_all`]).
    pub fn start(
        &mut self,
        setup: &JackSetup,
        tools: &JackTools,
        plant_jack: &Path,
        scenario: &Path,
        folder: &Path,
        stop: &AtomicUsize,
    ) -> Result<(), StartFailure> {
        let server = &setup.server;
        let mut jackd = jackd_command(&tools.jackd, setup);
        let what = match setup.core {
            Some(c) => {
                pin_to(&mut jackd, c);
                format!("jackd (JACK server '{server}', pinned to core {c}: proxy.core)")
            }
            None => format!("jackd (JACK server '{server}')"),
        };
        let jackd = Fixture::started(
            "jackd",
            "the JACK server",
            what,
            jackd,
            folder.join(JACKD_LOG_FILE),
        )
        .map_err(StartFailure::Failed)?;
        let jackd = self.jackd.insert(jackd);
        let lsp = &tools.jack_lsp;
        wait_ready(jackd, stop, "its server did not answer", || {
            Ok(server_ports(lsp, server)?.is_some())
        })?;
        eprintln!(
            "[launch] JACK server '{server}' is up (jackd pid {}, output in {})",
            jackd.sup.child.id(),
            jackd.log.display()
        );

        let what = format!(
            "the room (plant-jack room, JACK client '{}')",
            setup.room_client
        );
        let room = Fixture::started(
            "room",
            "the room",
            what,
            room_command(plant_jack, scenario),
            folder.join(ROOM_LOG_FILE),
        )
        .map_err(StartFailure::Failed)?;
        let room = self.room.insert(room);
        let log = room.log.clone();
        let mut missing = setup.room_ports.clone();
        wait_ready(
            room,
            stop,
            "its client was not active with all its ports on the server",
            || {
                let active = std::fs::read_to_string(&log)
                    .is_ok_and(|t| t.lines().any(|l| l.starts_with(ROOM_ACTIVE_LINE)));
                let ports = server_ports(lsp, server)?.unwrap_or_default();
                missing.retain(|p| !ports.contains(p));
                Ok(active && missing.is_empty())
            },
        )?;
        eprintln!(
            "[launch] the room is on '{server}' (pid {}, output in {}): {}",
            room.sup.child.id(),
            room.log.display(),
            setup.room_ports.join(", ")
        );
        Ok(())
    }

    /// The first fixture that ended without the launcher stopping it: its short name and
    /// the message that names it, how it ended and its log.
    pub fn ended_on_its_own(&mut self) -> Option<(&'static str, String)> {
        [&mut self.room, &mut self.jackd]
            .into_iter()
            .flatten()
            .find_map(|f| (f.sup.poll() && f.sup.stopped.is_none()).then_some(&*f))
            .map(|f| {
                let m = format!(
                    "{} ended before the launcher stopped it: {}; see {}",
                    f.what,
                    f.sup.end().summary,
                    f.log.display()
                );
                (f.short, m)
            })
    }

    /// Stops the room, then the server (`SIGTERM`, `SIGKILL` if one does not end), and
    /// waits for each.
    pub fn stop_all(&mut self, why: &str) {
        for f in [&mut self.room, &mut self.jackd].into_iter().flatten() {
            stop_and_wait(&mut f.sup, why);
        }
    }

    /// How the room and the server ended (`None`: not started).
    pub fn ends(&self) -> (Option<ChildEnd>, Option<ChildEnd>) {
        (
            self.room.as_ref().map(|f| f.sup.end()),
            self.jackd.as_ref().map(|f| f.sup.end()),
        )
    }
}

/// Waits until `ready` says so, at most [`READY_WITHIN`]; fails when the fixture ended,
/// when `ready` fails, or when the launcher got a signal.
fn wait_ready(
    f: &mut Fixture,
    stop: &AtomicUsize,
    not_ready: &str,
    mut ready: impl FnMut() -> Result<bool, String>,
) -> Result<(), StartFailure> {
    let deadline = Instant::now() + READY_WITHIN;
    loop {
        let sig = stop.load(Ordering::Relaxed);
        if sig != 0 {
            return Err(StartFailure::Signal(signal_name(sig as i32).to_string()));
        }
        if f.sup.poll() {
            return Err(StartFailure::Failed(format!(
                "{} ended before it was ready: {}; see {}",
                f.what,
                f.sup.end().summary,
                f.log.display()
            )));
        }
        let fail = |why: String| {
            StartFailure::Failed(format!("{}: {why}; see {}", f.what, f.log.display()))
        };
        if ready().map_err(fail)? {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(fail(format!(
                "{not_ready} within {} s",
                READY_WITHIN.as_secs()
            )));
        }
        std::thread::sleep(PROBE_EVERY);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plant with the acoustic rig's channels (u 2, y 1, z 1) at 8 kHz, with `proxy` and
    /// `jack` tables.
    fn scenario(proxy: &str, jack: &str) -> String {
        format!(
            "[rig]\nname = \"t\"\nsample-period = 1.25e-4\nduration = 1.0\n\
             [plant]\nkind = \"transfer-function\"\ninputs = 2\ndisturbances = 0\n\
             outputs-y = 1\noutputs-z = 1\n[plant.tf]\n\
             yu = [[{{ num = [1.0], den = [1.0, 5.0] }}, {{ num = [1.0], den = [1.0, 5.0] }}]]\n\
             zu = [[{{ num = [1.0], den = [1.0, 5.0] }}, {{ num = [1.0], den = [1.0, 5.0] }}]]\n\
             [proxy]\n{proxy}\n[jack]\n{jack}\n"
        )
    }

    fn setup(proxy: &str, jack: &str) -> JackSetup {
        JackSetup::parse(&scenario(proxy, jack), "t.toml", Some(Mode::Lockstep))
            .unwrap_or_else(|e| panic!("{e}"))
    }

    fn words(cmd: &Command) -> Vec<String> {
        command_line(cmd)
    }

    #[test]
    fn the_dummy_server_runs_at_the_scenarios_rate_period_and_priority() {
        let s = setup(
            "core = 0\nfifo-priority = 65",
            "server = \"lab\"\nperiod-frames = 64\nu = [\"room:speaker-u0\", \"room:speaker-u1\"]",
        );
        assert_eq!(s.server, "lab");
        assert_eq!((s.rate, s.period_frames), (8000, 64));
        assert_eq!((s.fifo_priority, s.core), (Some(65), Some(0)));
        assert_eq!(
            words(&jackd_command(Path::new("/usr/bin/jackd"), &s)),
            [
                "/usr/bin/jackd",
                "-n",
                "lab",
                "-R",
                "-P",
                "65",
                "-d",
                "dummy",
                "-r",
                "8000",
                "-p",
                "64"
            ]
        );
        assert!(s.plant_hears_the_room());
    }

    #[test]
    fn the_dummy_server_defaults_to_32_frames_and_priority_70_and_no_realtime_on_0() {
        let s = setup("", "server = \"lab\"");
        assert_eq!(
            (s.period_frames, s.fifo_priority, s.core),
            (32, Some(70), None)
        );
        assert!(!s.plant_hears_the_room());
        let off = setup("fifo-priority = 0", "server = \"lab\"");
        assert_eq!(off.fifo_priority, None);
        let w = words(&jackd_command(Path::new("jackd"), &off));
        assert_eq!(w[..4], ["jackd", "-n", "lab", "--no-realtime"]);
        assert_eq!(w[4..], ["-d", "dummy", "-r", "8000", "-p", "32"]);
    }

    #[test]
    fn the_rooms_ports_follow_its_client_name_and_the_plants_channels() {
        let s = setup("", "server = \"lab\"\n[jack.room]\nclient = \"box\"");
        assert_eq!(s.room_client, "box");
        assert_eq!(
            s.room_ports,
            [
                "box:speaker-u0",
                "box:speaker-u1",
                "box:mic-y0",
                "box:mic-z0"
            ]
        );
        assert_eq!(
            words(&room_command(
                Path::new("/x/plant-jack"),
                Path::new("/s/rig.toml")
            )),
            ["/x/plant-jack", "room", "/s/rig.toml"]
        );
    }

    #[test]
    fn a_period_that_is_not_a_whole_number_of_hertz_is_refused_naming_the_field() {
        let text = scenario("", "server = \"lab\"").replace("1.25e-4", "3.0e-4");
        let e = JackSetup::parse(&text, "t.toml", None).unwrap_err();
        assert!(
            e.contains("t.toml") && e.contains("rig.sample-period"),
            "{e}"
        );
    }

    #[test]
    fn a_bad_jack_table_is_refused_naming_the_field() {
        let text = scenario("", "server = \"lab\"\nperiod-frames = 0");
        let e = JackSetup::parse(&text, "t.toml", None).unwrap_err();
        assert!(e.contains("jack.period-frames"), "{e}");
    }

    #[test]
    fn the_mode_names_are_plant_jacks() {
        assert_eq!(mode_of("lockstep"), Some(Mode::Lockstep));
        assert_eq!(mode_of("real-time"), Some(Mode::RealTime));
        assert_eq!(mode_of("fast"), None);
    }

    #[test]
    fn a_program_is_found_on_path_only_when_executable() {
        assert!(on_path("sh").is_some());
        assert!(on_path("no-such-program-for-rig-launch").is_none());
    }
}
