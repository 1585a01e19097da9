//! `service`: the adaptive real-time control service.
//!
//! ```text
//! service run <scenario.toml> [--run-folder DIR] [--exit-with-plant] [--max-cycles N] [--wait sleep-poll|busy-poll|block] [--core N] [--warm-start checkpoint.json]
//! service check <scenario.toml> [--controller FILE]
//! service check-system [scenario.toml] [--core N]
//! service replay RUN_FOLDER [--controller FILE] [--scenario FILE] [--comparison FILE]
//! ```
//!
//! `run` is the service alone, against whatever plant process serves the rig (plant-proxy or
//! a DAQ I/O process); it prints the run report and leaves the run folder. `check`
//! validates the service's half of a scenario (`[rig]`, `[service]`, `[controller]`,
//! `[log]`) and exits (the plant half is `plant-proxy check`'s, both against each other
//! `rig check`'s); a refused configuration or
//! command-line value exits with code 2, naming the file and the field. The main job (plant-proxy and the service started
//! together, then the figure) is `rig launch` of the offline tools: this binary runs next
//! to the hardware and links no plotting. `replay` re-runs the loop offline on a run
//! folder's `record.bin` and compares its outputs with the logged ones bit for bit (exit 0
//! equal, 1 different, 2 cannot replay, 3 incomplete record), or with `--controller` /
//! `--scenario` compares another configuration open loop (docs/replay.md).

use clap::{Parser, Subcommand};
use service::config::{ConfigError, ServiceConfig, WaitMode};
use service::rt_alloc::RtAwareAllocator;
use service::runtime::{RunOptions, run};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

#[global_allocator]
static ALLOCATOR: RtAwareAllocator = RtAwareAllocator;

#[derive(Parser)]
#[command(
    name = "service",
    version,
    about = "Adaptive real-time control service"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args, Clone)]
struct Common {
    /// Scenario / configuration TOML file.
    config: PathBuf,
    /// Folder for this run's artifacts (default: <service.run-dir>/<rig>-<time>).
    #[arg(long)]
    run_folder: Option<PathBuf>,
    /// Override service.wait.
    #[arg(long, value_parser = parse_wait)]
    wait: Option<WaitMode>,
    /// Override service.core (the RT core).
    #[arg(long)]
    core: Option<usize>,
    /// Replace the scenario's [controller] (and [log]) table by this file's, e.g. an
    /// identification run with `kind = "excitation"`.
    #[arg(long)]
    controller: Option<PathBuf>,
}

#[derive(Subcommand)]
enum Command {
    /// Run the service against the rig's plant process.
    Run {
        #[command(flatten)]
        common: Common,
        /// Stop when the plant sends its last sample.
        #[arg(long)]
        exit_with_plant: bool,
        /// Stop after this many samples.
        #[arg(long)]
        max_cycles: Option<u64>,
        /// Start the controller from what an earlier run learned: its checkpoint.json
        /// (same rig, controller kind and dimensions; checked before the loop starts).
        #[arg(long)]
        warm_start: Option<PathBuf>,
    },
    /// Check what this box does to a real-time loop (PREEMPT_RT, the RT core's isolation,
    /// RT throttling, governor, SMT sibling, IRQs, swap, huge pages, privileges) and print
    /// the fix for each finding; exits 0 (the findings are advice).
    CheckSystem {
        /// A scenario whose `service.core` is the RT core (else --core, else none).
        config: Option<PathBuf>,
        /// The RT core to check.
        #[arg(long)]
        core: Option<usize>,
    },
    /// Re-run the loop offline on a run folder's record.bin and compare its outputs with
    /// the logged ones bit for bit; with --controller or --scenario, compare another
    /// configuration open loop and write a comparison CSV.
    Replay {
        /// The run folder.
        run_folder: PathBuf,
        /// Replace the recorded [controller] (and [log]) table by this file's.
        #[arg(long)]
        controller: Option<PathBuf>,
        /// Rebuild from this scenario instead of the recorded configuration.
        #[arg(long)]
        scenario: Option<PathBuf>,
        /// The open-loop comparison CSV (default <run folder>/replay-comparison.csv).
        #[arg(long)]
        comparison: Option<PathBuf>,
    },
    /// Validate the service's half of a scenario ([rig], [service], [controller], [log]) and
    /// exit; `plant-proxy check` validates the plant half, `rig check` both together.
    Check {
        /// Scenario / configuration TOML file.
        config: PathBuf,
        /// Replace the scenario's [controller] (and [log]) table by this file's.
        #[arg(long)]
        controller: Option<PathBuf>,
    },
}

fn parse_wait(s: &str) -> Result<WaitMode, String> {
    [WaitMode::SleepPoll, WaitMode::BusyPoll, WaitMode::Block]
        .into_iter()
        .find(|w| w.name() == s)
        .ok_or_else(|| format!("'{s}' is not sleep-poll, busy-poll or block"))
}

/// Prints a refused configuration and gives exit code 2.
fn refused(e: ConfigError) -> ExitCode {
    eprintln!("service: configuration refused: {e}");
    ExitCode::from(2)
}

fn load(path: &Path, controller: Option<&Path>) -> Result<ServiceConfig, ExitCode> {
    ServiceConfig::load_scenario(path, controller).map_err(refused)
}

fn shutdown_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(sig, flag.clone());
    }
    flag
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::CheckSystem { config, core } => {
            let core = match (core, config) {
                (Some(c), _) => Some(c),
                (None, Some(path)) => match load(&path, None) {
                    Ok(cfg) => cfg.rt.core,
                    Err(code) => return code,
                },
                (None, None) => None,
            };
            let findings = service::system_check::check_system(
                &service::system_check::SystemRoot::live(),
                core,
            );
            for f in &findings {
                println!("{}", f.render());
            }
            ExitCode::SUCCESS
        }
        Command::Replay {
            run_folder,
            controller,
            scenario,
            comparison,
        } => {
            let opts = service::replay::ReplayOptions {
                run_folder,
                controller,
                scenario,
                comparison,
            };
            match service::replay::replay(&opts) {
                Ok(summary) => {
                    print!("{}", summary.render());
                    ExitCode::from(summary.exit_code())
                }
                Err(e) => {
                    eprintln!("service replay: {e}");
                    ExitCode::from(2)
                }
            }
        }
        Command::Check { config, controller } => {
            let checked = ServiceConfig::load_scenario(&config, controller.as_deref())
                .and_then(|c| c.check_this_machine().map(|()| c));
            match checked {
                Ok(c) => {
                    println!(
                        "{}: ok ({}; the service half: `plant-proxy check` checks the plant \
                         half, `rig check` both against each other)",
                        config.display(),
                        c.summary()
                    );
                    ExitCode::SUCCESS
                }
                Err(e) => refused(e),
            }
        }
        Command::Run {
            common,
            exit_with_plant,
            max_cycles,
            warm_start,
        } => {
            let cfg = match load(&common.config, common.controller.as_deref()) {
                Ok(c) => c,
                Err(code) => return code,
            };
            if let Err(e) = cfg.check_run_options(common.core, max_cycles) {
                return refused(e);
            }
            let opts = RunOptions {
                run_folder: common.run_folder,
                exit_with_plant,
                max_cycles,
                wait: common.wait,
                core: common.core,
                warm_start,
            };
            match run(&cfg, &opts, shutdown_flag()) {
                Ok(report) => {
                    // The report reaches stdout before any file is written: a full disk
                    // cannot take it away.
                    println!("{}", report.render());
                    if let Err(e) = report.write_json() {
                        eprintln!("service: {e}");
                        return ExitCode::FAILURE;
                    }
                    if report.verdict.ok {
                        ExitCode::SUCCESS
                    } else {
                        ExitCode::FAILURE
                    }
                }
                Err(e) => {
                    eprintln!("service: {e}");
                    ExitCode::FAILURE
                }
            }
        }
    }
}
