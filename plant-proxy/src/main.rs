//! `plant-proxy`: the simulated plant process.
//!
//! ```text
//! plant-proxy run <scenario.toml> [--mode lockstep|real-time] [--steps N] [--trace out.csv] [--report out.json]
//! plant-proxy describe <scenario.toml>
//! ```

use clap::{Parser, Subcommand};
use plant_proxy::runtime::{Mode, PlantRunOptions, ProxyConfig, run_plant};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

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
        /// Scenario TOML file ([rig], [plant], optional [proxy]).
        scenario: PathBuf,
        /// Override proxy.mode.
        #[arg(long, value_parser = parse_mode)]
        mode: Option<Mode>,
        /// Number of samples (default: rig.duration / sample period).
        #[arg(long)]
        steps: Option<u64>,
        /// Write a CSV trace of y, z and the applied u.
        #[arg(long)]
        trace: Option<PathBuf>,
        /// Write the run report as JSON.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Print less.
        #[arg(long)]
        quiet: bool,
    },
    /// Print the discretized model of a scenario (state space and transfer functions) as JSON.
    Describe {
        /// Scenario TOML file.
        scenario: PathBuf,
    },
}

fn parse_mode(s: &str) -> Result<Mode, String> {
    match s {
        "lockstep" => Ok(Mode::Lockstep),
        "real-time" | "realtime" => Ok(Mode::RealTime),
        _ => Err(format!("'{s}' is not lockstep or real-time")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Describe { scenario } => {
            let sc = match plant_proxy::scenario::load(&scenario) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("plant-proxy: {e}");
                    return ExitCode::from(2);
                }
            };
            match plant_proxy::sim::PlantSim::new(&sc.plant, sc.rig.sample_period) {
                Ok(sim) => {
                    println!(
                        "{}",
                        serde_json::to_string_pretty(&sim.describe()).expect("JSON")
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("plant-proxy: {}: {e}", scenario.display());
                    ExitCode::from(2)
                }
            }
        }
        Command::Run {
            scenario,
            mode,
            steps,
            trace,
            report,
            quiet,
        } => {
            let sc = match plant_proxy::scenario::load(&scenario) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("plant-proxy: {e}");
                    return ExitCode::from(2);
                }
            };
            let text = std::fs::read_to_string(&scenario).unwrap_or_default();
            let n_u = sc.plant.n_u();
            let mut proxy = match ProxyConfig::parse(&text, &scenario.display().to_string(), n_u) {
                Ok(p) => p,
                Err(e) => {
                    eprintln!("plant-proxy: {e}");
                    return ExitCode::from(2);
                }
            };
            if let Some(m) = mode {
                proxy.mode = m;
            }
            let shutdown = Arc::new(AtomicBool::new(false));
            for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
                let _ = signal_hook::flag::register(sig, shutdown.clone());
            }
            let opts = PlantRunOptions {
                steps,
                trace,
                verbose: !quiet,
            };
            match run_plant(&sc, &proxy, &opts, &shutdown) {
                Ok(r) => {
                    eprintln!(
                        "[plant-proxy] done: {} samples, {} actuations applied, {} misses ({} late, {} invalid), watchdog trips {}, recoveries {}, z RMS {:?}",
                        r.samples,
                        r.actuations_applied,
                        r.misses,
                        r.late_discarded,
                        r.invalid_discarded,
                        r.watchdog_trips,
                        r.watchdog_recoveries,
                        r.z_rms
                    );
                    if let Some(p) = report {
                        let text = serde_json::to_string_pretty(&r).expect("JSON");
                        if let Err(e) = std::fs::write(&p, text) {
                            eprintln!("plant-proxy: writing {}: {e}", p.display());
                            return ExitCode::FAILURE;
                        }
                    }
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("plant-proxy: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
