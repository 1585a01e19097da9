//! `plant-proxy`: the simulated plant process.
//!
//! ```text
//! plant-proxy run <scenario.toml> [--mode lockstep|real-time] [--steps N | --duration S] [--trace out.csv] [--report out.json]
//! plant-proxy describe <scenario.toml>
//! plant-proxy check <scenario.toml>
//! ```
//!
//! A refused scenario or command-line value exits with code 2, naming the file and the
//! field; `--steps` and `--duration` are checked as `rig.duration` is. A run that fails
//! exits with code 1; a lockstep plant that gave up (no service answered after its
//! watchdog tripped) still prints its counters and writes its report (`--report`), whose
//! `gave_up` says why.

use clap::{Parser, Subcommand};
use plant_proxy::run_args::{ResolvedRun, RunArgs};
use plant_proxy::runtime::{PlantError, PlantReport, PlantRunOptions, ProxyConfig, run_plant};
use plant_proxy::scenario::Scenario;
use plant_proxy::sim::PlantSim;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// The RT-aware allocator: the loop thread's allocations (iceoryx2's per-sample loan state)
/// come from a private pool, with no lock and no system call.
#[global_allocator]
static ALLOCATOR: ipc_types::rt_alloc::RtAwareAllocator = ipc_types::rt_alloc::RtAwareAllocator;

#[derive(Parser)]
#[command(
    name = "plant-proxy",
    version,
    about = "The simulated plant behind the adaptive-rig contract"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run the plant of a scenario against the control service.
    Run {
        #[command(flatten)]
        args: RunArgs,
        /// Write a CSV trace of y, z and the applied u.
        #[arg(long)]
        trace: Option<PathBuf>,
    },
    /// Print the discretized model of a scenario (state space and transfer functions) as JSON.
    Describe {
        /// Scenario TOML file.
        scenario: PathBuf,
    },
    /// Validate the plant half of a scenario ([rig], [plant], [proxy]) without starting
    /// anything; print `ok` and a summary.
    Check {
        /// Scenario TOML file.
        scenario: PathBuf,
    },
}

/// The plant half of a scenario, validated as `run` would use it: the scenario, its
/// discretization and the `[proxy]` table; the message of a refusal otherwise.
fn load_plant_half(
    scenario: &std::path::Path,
) -> Result<(Scenario, PlantSim, ProxyConfig), String> {
    let sc = plant_proxy::scenario::load(scenario).map_err(|e| e.to_string())?;
    let sim = PlantSim::new(&sc.plant, sc.rig.sample_period)
        .map_err(|e| format!("{}: field 'plant': {e}", scenario.display()))?;
    let text = std::fs::read_to_string(scenario).unwrap_or_default();
    let proxy = ProxyConfig::parse(&text, &scenario.display().to_string(), sc.plant.n_u())
        .map_err(|e| e.to_string())?;
    Ok((sc, sim, proxy))
}

/// Prints a refusal and gives exit code 2.
fn refused(message: impl std::fmt::Display) -> ExitCode {
    eprintln!("plant-proxy: {message}");
    ExitCode::from(2)
}

/// Writes the run report `r` to `path` as JSON, atomically (the file is the whole report
/// or absent); a failure is printed, naming the file.
fn write_report(path: Option<&std::path::Path>, r: &PlantReport) -> Result<(), ()> {
    let Some(p) = path else {
        return Ok(());
    };
    let text = serde_json::to_string_pretty(r).expect("a plant report is plain data");
    ipc_types::files::write_atomic(p, text.as_bytes()).map_err(|e| eprintln!("plant-proxy: {e}"))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Describe { scenario } => {
            let sc = match plant_proxy::scenario::load(&scenario) {
                Ok(s) => s,
                Err(e) => return refused(e),
            };
            match PlantSim::new(&sc.plant, sc.rig.sample_period) {
                Ok(sim) => {
                    println!(
                        "{}",
                        serde_json::to_string_pretty(&sim.describe()).expect("JSON")
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => refused(format!("{}: {e}", scenario.display())),
            }
        }
        Command::Check { scenario } => match load_plant_half(&scenario) {
            Ok((sc, _, proxy)) => {
                let p = &sc.plant;
                println!(
                    "{}: ok (rig '{}', {} Hz, {} s, plant {} with {} states, channels y={} z={} r={} u={} w={}, proxy {:?}, inputs applied {}, late policy {}, overrun {}, {} stall(s) injected)",
                    scenario.display(),
                    sc.rig.name,
                    1.0 / sc.rig.sample_period,
                    sc.rig.duration,
                    p.kind.name(),
                    p.n_x(),
                    p.n_y(),
                    p.n_z(),
                    p.n_r(),
                    p.n_u(),
                    p.n_w(),
                    proxy.plant.mode,
                    proxy.applies().name(),
                    proxy.describe_late_policy(),
                    proxy.plant.overrun.name(),
                    proxy.faults.stalls.len()
                );
                ExitCode::SUCCESS
            }
            Err(m) => refused(m),
        },
        Command::Run { args, trace } => {
            let ResolvedRun {
                scenario: sc,
                steps,
                proxy,
                ..
            } = match args.resolve() {
                Ok(r) => r,
                Err(e) => return refused(e),
            };
            let (report, quiet) = (args.report, args.quiet);
            let shutdown = Arc::new(AtomicBool::new(false));
            for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
                let _ = signal_hook::flag::register(sig, shutdown.clone());
            }
            let opts = PlantRunOptions {
                steps: Some(steps),
                trace,
                verbose: !quiet,
            };
            match run_plant(&sc, &proxy, &opts, &shutdown) {
                Ok(r) => {
                    eprintln!("[plant-proxy] done: {}", r.summary_line());
                    match write_report(report.as_deref(), &r) {
                        Ok(()) => ExitCode::SUCCESS,
                        Err(()) => ExitCode::FAILURE,
                    }
                }
                Err(PlantError::GaveUp { message, report: r }) => {
                    // The counters and the report still say what the run did, and that it
                    // gave up; the reason (with the trust counters) comes last.
                    eprintln!("[plant-proxy] gave up: {}", r.summary_line());
                    let _ = write_report(report.as_deref(), &r);
                    eprintln!("plant-proxy: {message}");
                    ExitCode::FAILURE
                }
                Err(e) => {
                    eprintln!("plant-proxy: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
