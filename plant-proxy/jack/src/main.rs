//! `plant-jack`: a sound card under JACK as the rig's DAQ.
//!
//! ```text
//! plant-jack run <scenario.toml> [--mode lockstep|real-time] [--steps N | --duration S] [--report out.json] [--quiet]
//! plant-jack room <scenario.toml> [--duration S] [--xrun-at S]...
//! plant-jack check <scenario.toml>
//! ```
//!
//! `run` is the plant side (the JACK client `jack.client`, ports `y0…`, `z0…`, `u0…`,
//! connected as `[jack]` lists); `room` is the scenario's simulated plant as the JACK client
//! `jack.room.client` (ports `speaker-u0…`, `mic-y0…`, `mic-z0…`), until `--duration` or a
//! signal; `check` validates the plant half and the `[jack]` table without a server.
//!
//! Exit codes: 2 for a refusal before the run (the scenario, no JACK server, a rate or
//! period that differs from the scenario's, a missing port, no service), naming the file,
//! field, server or port; 1 for a run that failed (the server went away, the plant side
//! gave up), after printing and writing its report; 0 otherwise.

use clap::{Parser, Subcommand};
use plant_jack::daq::{self, DaqRun};
use plant_jack::jack_config::{Channels, JackConfig};
use plant_jack::jack_report::JackPlantReport;
use plant_proxy::run_args::{ResolvedRun, RunArgs};
use plant_proxy::runtime::ProxyConfig;
use plant_proxy::scenario::Scenario;
use plant_proxy::sim::PlantSim;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The RT-aware allocator: the process thread's allocations (iceoryx2's per-sample loan
/// state) come from a private pool, with no lock and no system call.
#[global_allocator]
static ALLOCATOR: ipc_types::rt_alloc::RtAwareAllocator = ipc_types::rt_alloc::RtAwareAllocator;

#[derive(Parser)]
#[command(
    name = "plant-jack",
    version,
    about = "A sound card under JACK as the rig's DAQ, and a simulated room as a JACK client"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the plant side through the JACK server against the control service.
    Run {
        #[command(flatten)]
        args: RunArgs,
    },
    /// Run the scenario's simulated plant as a JACK client (the room), until --duration or
    /// a signal.
    Room {
        /// Scenario TOML file ([rig], [plant], [jack]).
        scenario: PathBuf,
        /// Seconds of wall time to run (default: until SIGINT or SIGTERM).
        #[arg(long)]
        duration: Option<f64>,
        /// Inject an xrun at this simulated second (the callback sleeps three periods).
        #[arg(long)]
        xrun_at: Vec<f64>,
    },
    /// Validate the plant half of a scenario and its [jack] table; print `ok` and a summary.
    Check {
        /// Scenario TOML file.
        scenario: PathBuf,
    },
}

/// Prints a refusal and gives exit code 2.
fn refused(message: impl std::fmt::Display) -> ExitCode {
    eprintln!("plant-jack: {message}");
    ExitCode::from(2)
}

/// The scenario, its simulation (for the channel counts and the room), its `[proxy]` and
/// `[jack]` tables.
fn load(path: &Path) -> Result<(Scenario, PlantSim, ProxyConfig, JackConfig), String> {
    let sc = plant_proxy::scenario::load(path).map_err(|e| e.to_string())?;
    let origin = path.display().to_string();
    let sim = PlantSim::new(&sc.plant, sc.rig.sample_period)
        .map_err(|e| format!("{origin}: field 'plant': {e}"))?;
    let text = std::fs::read_to_string(path).map_err(|e| format!("{origin}: {e}"))?;
    let proxy = ProxyConfig::parse(&text, &origin, sim.n_u()).map_err(|e| e.to_string())?;
    let jack = JackConfig::parse(&text, &origin, channels(&sim)).map_err(|e| e.to_string())?;
    Ok((sc, sim, proxy, jack))
}

/// The channels a `[jack]` table is checked against: the simulation's.
fn channels(sim: &PlantSim) -> Channels {
    Channels {
        n_y: sim.n_y(),
        n_z: sim.n_z(),
        n_r: sim.n_r(),
        n_u: sim.n_u(),
    }
}

/// A process-wide stop flag set by SIGINT and SIGTERM.
fn stop_flag() -> &'static AtomicBool {
    let flag: &'static Arc<AtomicBool> = Box::leak(Box::new(Arc::new(AtomicBool::new(false))));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(sig, Arc::clone(flag));
    }
    flag
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Check { scenario } => match load(&scenario) {
            Ok((sc, sim, proxy, jack)) => {
                println!(
                    "{}: ok (rig '{}', {} Hz, channels y={} z={} u={}, proxy {:?}, inputs applied {}, late policy {}; JACK server '{}', client '{}', budget {} of a period, ports y {:?} z {:?} u {:?}, room '{}')",
                    scenario.display(),
                    sc.rig.name,
                    1.0 / sc.rig.sample_period,
                    sim.n_y(),
                    sim.n_z(),
                    sim.n_u(),
                    proxy.plant.mode,
                    proxy.applies().name(),
                    proxy.describe_late_policy(),
                    plant_jack::jack_server::server_name(jack.server.as_deref()),
                    jack.client,
                    jack.budget,
                    jack.y,
                    jack.z,
                    jack.u,
                    jack.room.client
                );
                ExitCode::SUCCESS
            }
            Err(m) => refused(m),
        },
        Command::Room {
            scenario,
            duration,
            xrun_at,
        } => room(&scenario, duration, &xrun_at),
        Command::Run { args } => run(&args),
    }
}

fn room(scenario: &Path, duration: Option<f64>, xrun_at: &[f64]) -> ExitCode {
    let (sc, sim, _, jack) = match load(scenario) {
        Ok(t) => t,
        Err(m) => return refused(m),
    };
    if let Some(d) = duration
        && !(d.is_finite() && d > 0.0)
    {
        return refused(format!(
            "--duration {d} is not a positive number of seconds"
        ));
    }
    if let Some(s) = xrun_at.iter().find(|s| !(s.is_finite() && **s >= 0.0)) {
        return refused(format!("--xrun-at {s} is not a time in seconds"));
    }
    let ts = sc.rig.sample_period;
    let stalls: Vec<u64> = xrun_at.iter().map(|s| (s / ts).round() as u64).collect();
    let stop = stop_flag();
    let origin = scenario.display().to_string();
    let (active, counters) = match plant_jack::room::start(sim, &jack, &origin, &stalls) {
        Ok(r) => r,
        Err(m) => return refused(m),
    };
    let name = active.as_client().name().to_string();
    eprintln!(
        "[room] rig '{}' as JACK client '{name}' at {} Hz, {} frames per period: ports {}",
        sc.rig.name,
        active.as_client().sample_rate(),
        active.as_client().buffer_size(),
        active
            .as_client()
            .ports(Some(&format!("^{name}:")), None, jack::PortFlags::empty())
            .join(", ")
    );
    let started = Instant::now();
    let limit = duration.map(Duration::from_secs_f64);
    while !stop.load(Ordering::Relaxed)
        && !counters.failed.load(Ordering::Acquire)
        && limit.is_none_or(|l| started.elapsed() < l)
    {
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = active.deactivate();
    let samples = counters.samples.load(Ordering::Relaxed);
    eprintln!(
        "[room] done: {samples} samples ({:.3} s simulated) in {:.3} s, {} xruns ({} injected), {} frames simulated with silent loudspeakers after them, {} not simulated, {} microphone samples clipped",
        samples as f64 * ts,
        started.elapsed().as_secs_f64(),
        counters.xruns.load(Ordering::Relaxed),
        counters.stalls.load(Ordering::Relaxed),
        counters.frames_caught_up.load(Ordering::Relaxed),
        counters.frames_dropped.load(Ordering::Relaxed),
        counters.clipped.load(Ordering::Relaxed)
    );
    match counters.failure.lock().ok().and_then(|f| f.clone()) {
        Some(why) => {
            eprintln!("plant-jack room: {why}");
            ExitCode::FAILURE
        }
        None => ExitCode::SUCCESS,
    }
}

fn run(args: &RunArgs) -> ExitCode {
    let scenario = &args.scenario;
    let ResolvedRun {
        scenario: sc,
        steps,
        proxy,
        text,
    } = match args.resolve() {
        Ok(r) => r,
        Err(m) => return refused(m),
    };
    let origin = scenario.display().to_string();
    let sim = match PlantSim::new(&sc.plant, sc.rig.sample_period) {
        Ok(s) => s,
        Err(e) => return refused(format!("{origin}: field 'plant': {e}")),
    };
    let jack = match JackConfig::parse(&text, &origin, channels(&sim)) {
        Ok(j) => j,
        Err(e) => return refused(e),
    };
    let counts = match ipc_types::ChannelCounts::new(sim.n_y(), sim.n_z(), 0, sim.n_u()) {
        Ok(c) => c,
        Err(e) => return refused(format!("{origin}: {e}")),
    };
    if proxy.plant.overrun != plant_proxy::runtime::Overrun::Slip {
        eprintln!(
            "[plant-jack] note: proxy.overrun is not used: the JACK server's clock paces the samples"
        );
    }
    let stop = stop_flag();
    let outcome = match daq::run(
        DaqRun {
            origin: &origin,
            rig: &sc.rig.name,
            counts,
            period_ns: (sc.rig.sample_period * 1e9).round() as u64,
            policy: proxy.plant.clone(),
            jack,
            steps,
            verbose: !args.quiet,
        },
        stop,
    ) {
        Ok(o) => o,
        Err(m) => return refused(m),
    };
    let done = if outcome.failure.is_some() {
        "failed"
    } else {
        "done"
    };
    eprintln!("[plant-jack] {done}: {}", outcome.plant.summary_line());
    eprintln!("[plant-jack] {}", outcome.jack.summary_line());
    let mut code = ExitCode::SUCCESS;
    if let Some(p) = &args.report {
        let r = JackPlantReport {
            plant: &outcome.plant,
            jack: &outcome.jack,
        };
        let text = serde_json::to_string_pretty(&r).expect("a plant report is plain data");
        if let Err(e) = ipc_types::files::write_atomic(p, text.as_bytes()) {
            eprintln!("plant-jack: {e}");
            code = ExitCode::FAILURE;
        }
    }
    if let Some(f) = outcome.failure {
        eprintln!("plant-jack: {f}");
        code = ExitCode::FAILURE;
    }
    code
}
