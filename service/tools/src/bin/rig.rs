//! `rig`: the main job and its figure.
//!
//! ```text
//! rig launch <scenario.toml> [--mode real-time|lockstep] [--duration S] [--run-folder DIR]
//!            [--wait sleep-poll|busy-poll|block] [--core N] [--controller FILE] [--warm-start FILE]
//!            [--plant-trace] [--plant proxy|jack|jack-room]
//! rig plot <run-folder>
//! rig stalls <scenario.toml> [--plan-length H] [--runs DIR] [--results FILE] [--json FILE]
//! rig soak <scenario.toml> [--controller FILE|scenario]... [--runs N] [--conditions LIST]
//!          [--wait MODE]... [--duration S] [--out DIR] [--results FILE.md]
//! rig gaps <scenario.toml> [--rls FILE] [--rules R,R,…] [--jobs N] [--runs DIR]
//!          [--results FILE] [--json FILE]
//! rig check <scenario.toml> [--controller FILE]
//! rig monitor --rig NAME [--rig NAME ...] [--listen 127.0.0.1:9187] [--allow-commands]
//!             [--foxglove 127.0.0.1:8765]
//! rig command --rig NAME <command> [--tunable NAME --value X] [--timeout S]
//! ```
//!
//! `launch` starts the plant and `service run` (found next to this executable) on the same
//! scenario, as processes over shared memory; the service prints its run report; then
//! `run.png` is drawn in the run folder (see `rig_tools::launch`). The plant is `--plant
//! proxy` (default: `plant-proxy run`, the simulated plant), `--plant jack` (`plant-jack
//! run` on the user's running JACK server: a sound card as the DAQ) or `--plant jack-room`
//! (`plant-jack run` on a dummy JACK server the launcher starts, `jackd -d dummy`, against
//! the simulated plant as the JACK client `plant-jack room`; their output goes into
//! `jackd.log` and `room.log` in the run folder, and they are stopped after the service
//! and the plant). How each child ended is printed (`[launch] service: exit 0`) and written
//! into `launch.json` in the run folder. Exit status: 0 when the children ended cleanly; 1
//! when the service did not (it died, or its run verdict failed), the plant did not and the
//! launcher was not asked to stop, or the room or the dummy server ended on its own or was
//! not ready; 2 when the configuration was refused before anything started (among others:
//! `--plant-trace` with a JACK plant, `--plant jack` without the scenario's JACK server
//! running, `--plant jack-room` with it already running or without `jackd`). `plot` draws
//! `run.png` from a run folder (signals.csv and report.json) of any earlier run. `stalls`
//! runs the stall study of `rig_tools::stalls` (seven lockstep runs of the scenario) and
//! writes its table. `soak` runs the scenario in real time under each load, N rounds of
//! every combination of controller, wait mode and condition (`rig_tools::soak`), prints the
//! summary and writes the results file (default `OUT/soak.md`); it exits with 0 when the
//! campaign ran, whatever the runs' verdicts, 2 on a refused option or configuration, 1
//! when it was interrupted or its results could not be written. `gaps` runs the gap campaign of `rig_tools::gaps` (RCAC's suppression
//! against the share of samples lost, per gap rule, in lockstep) and writes its tables.
//! `check` validates both halves of a scenario and the two against each other
//! (`rig_tools::scenario_check`): exit 0 when accepted, 2 when refused, naming the file and
//! the field. `monitor` watches running rigs (`rig_tools::monitor`, docs/monitor.md): it
//! prints `rig monitor: listening on http://ADDR/` (and `rig monitor: foxglove on
//! ws://ADDR`) once it serves, and runs until SIGINT or SIGTERM; exit 2 when an option is
//! refused, 1 when the server fails. `command` sends one operator command to a rig's
//! service and prints its reply: exit 0 when applied, 1 when refused or unanswered, 2 on a
//! malformed command.

use clap::{Parser, Subcommand};
use rig_tools::launch::{LaunchError, LaunchOptions, PlantKind, launch};
use rig_tools::scenario_check::ScenarioCheck;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

#[derive(Parser)]
#[command(
    name = "rig",
    version,
    about = "The adaptive rig's main job and its figure"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// The main job: the plant and the service on one scenario, then run.png.
    Launch {
        /// Scenario / configuration TOML file.
        config: PathBuf,
        /// Plant pacing: real-time (default) or lockstep.
        #[arg(long, default_value = "real-time")]
        mode: String,
        /// Seconds of plant time (default: rig.duration).
        #[arg(long)]
        duration: Option<f64>,
        /// Folder for this run's artifacts (default: `<service.run-dir>/<rig>-<time>`).
        #[arg(long)]
        run_folder: Option<PathBuf>,
        /// Override service.wait (sleep-poll, busy-poll or block).
        #[arg(long)]
        wait: Option<String>,
        /// Override service.core (the RT core).
        #[arg(long)]
        core: Option<usize>,
        /// Replace the scenario's `[controller]` (and `[log]`) table by this file's.
        #[arg(long)]
        controller: Option<PathBuf>,
        /// Start the controller from what an earlier run learned (its checkpoint.json).
        #[arg(long)]
        warm_start: Option<PathBuf>,
        /// Have the plant write its per-sample trace (plant-trace.csv in the run folder;
        /// plant-proxy only).
        #[arg(long)]
        plant_trace: bool,
        /// The plant. jack and jack-room wire plant-jack as the scenario's `[jack]` table
        /// lists; jack-room starts `jackd -n <jack.server> -d dummy` (Debian's jackd2; no
        /// server of that name may be running) and the room, their output in jackd.log and
        /// room.log of the run folder, and stops them after the run.
        #[arg(long, value_enum, default_value_t = PlantKind::Proxy)]
        plant: PlantKind,
    },
    /// The stall study: what stalls of 1 to 80 periods cost under each timing and late
    /// policy, in lockstep (one run of the scenario per case and baseline).
    Stalls {
        /// Scenario / configuration TOML file.
        config: PathBuf,
        /// Plan entries per answer of a plan case; repeat it for one plan case per length.
        #[arg(long = "plan-length", default_values_t = [32usize, 64])]
        plan_lengths: Vec<usize>,
        /// Folder for the runs (default: `runs/stalls-<unix time>`).
        #[arg(long)]
        runs: Option<PathBuf>,
        /// Write the table as Markdown into this file (e.g. docs/results/stall-policies.md).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Write the study as JSON into this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Real time under load: N rounds of every combination of controller, wait mode and
    /// condition (idle, a busy loop on the RT core, on the plant's core, on both), in real
    /// time, one sitting; writes a summary and a per-run table.
    Soak {
        /// Scenario / configuration TOML file.
        config: PathBuf,
        /// A controller file (as for `rig launch --controller`), or `scenario` for the
        /// scenario's own; repeatable (default: the scenario's own).
        #[arg(long)]
        controller: Vec<PathBuf>,
        /// Rounds: each runs every combination once.
        #[arg(long, default_value_t = 10)]
        runs: usize,
        /// Conditions, comma-separated: idle, hog-rt, hog-plant, hog-both.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "idle,hog-rt,hog-plant,hog-both"
        )]
        conditions: Vec<String>,
        /// A wait mode (sleep-poll, busy-poll, block); repeatable (default: service.wait).
        #[arg(long)]
        wait: Vec<String>,
        /// Seconds of each run (default: rig.duration).
        #[arg(long)]
        duration: Option<f64>,
        /// The campaign's folder, empty or new (default: `runs/soak-<unix time>`).
        #[arg(long)]
        out: Option<PathBuf>,
        /// The results file, Markdown (default: `<out>/soak.md`).
        #[arg(long)]
        results: Option<PathBuf>,
    },
    /// The gap campaign: RCAC's suppression against the share of samples lost (0 to 10 %,
    /// bursts of 1, 4 and 16) for each gap rule, in lockstep.
    Gaps {
        /// Scenario / configuration TOML file (its controller is the "gradient" variant).
        config: PathBuf,
        /// A controller file for the second variant ("rls"), e.g.
        /// scenarios/rcac/acoustic-rls.toml.
        #[arg(long)]
        rls: Option<PathBuf>,
        /// The gap rules, `gap-rule[:pause]`, comma-separated.
        #[arg(long, default_value = "suspend,resume-hold,resume-plan")]
        rules: String,
        /// Runs at a time.
        #[arg(long, default_value_t = 1)]
        jobs: usize,
        /// Folder for the runs (default: `runs/gaps-<unix time>`).
        #[arg(long)]
        runs: Option<PathBuf>,
        /// Write the tables as Markdown into this file (e.g. docs/results/gap-rule.md).
        #[arg(long)]
        results: Option<PathBuf>,
        /// Write the campaign as JSON into this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Draw run.png (the verdict, z open and closed loop, u, ‖θ‖, shaded safe-state and
    /// watchdog intervals, PSDs over equal windows) from a run folder.
    Plot {
        /// A run folder (holds signals.csv and report.json).
        run_folder: PathBuf,
    },
    /// Watch running rigs: a web page with a live scope, JSON, Prometheus metrics and
    /// optionally Foxglove (docs/monitor.md).
    Monitor {
        /// A rig to watch; repeatable.
        #[arg(long = "rig", required = true)]
        rigs: Vec<String>,
        /// HTTP address (port 0: any free port; loopback unless you mean otherwise).
        #[arg(long, default_value = rig_tools::monitor::DEFAULT_LISTEN)]
        listen: String,
        /// Forward operator commands from the page and Foxglove to the services.
        #[arg(long)]
        allow_commands: bool,
        /// Also serve Foxglove's WebSocket protocol on this address (e.g. 127.0.0.1:8765).
        #[arg(long)]
        foxglove: Option<String>,
        /// Stay on any core: do not move off the services' real-time cores (by default the
        /// monitor moves its threads off them once a service's telemetry names its pid).
        #[arg(long)]
        any_core: bool,
    },
    /// Send one operator command to a rig's service and print its reply.
    #[command(name = "command")]
    Operator {
        /// The rig.
        #[arg(long)]
        rig: String,
        /// freeze-adaptation, resume-adaptation, enter-safe-state, leave-safe-state,
        /// stop-run or set-tunable.
        command: String,
        /// For set-tunable: the tunable's name.
        #[arg(long)]
        tunable: Option<String>,
        /// For set-tunable: the new value.
        #[arg(long, allow_negative_numbers = true)]
        value: Option<f64>,
        /// Seconds to wait for the reply.
        #[arg(long, default_value_t = 2.0)]
        timeout: f64,
    },
    /// Validate the whole scenario, both halves (the service's tables as `service check`
    /// reads them and plant-proxy's rig, plant and proxy tables, when the file has a plant
    /// table) and the two against each other, and exit (2 when refused).
    Check {
        /// Scenario / configuration TOML file.
        config: PathBuf,
        /// Replace the scenario's controller (and log) table by this file's.
        #[arg(long)]
        controller: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Launch {
            config,
            mode,
            duration,
            run_folder,
            wait,
            core,
            controller,
            warm_start,
            plant_trace,
            plant,
        } => {
            // The number of the signal that asks the launch to stop (0: none).
            let stop = Arc::new(AtomicUsize::new(0));
            for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
                let _ = signal_hook::flag::register_usize(sig, stop.clone(), sig as usize);
            }
            let opts = LaunchOptions {
                config,
                run_folder,
                mode,
                duration,
                wait,
                core,
                controller,
                warm_start,
                plant_trace,
                plant,
                ..Default::default()
            };
            match launch(&opts, stop) {
                Ok(done) => {
                    if let Some(f) = done.figure {
                        println!("figure: {}", f.display());
                    }
                    ExitCode::SUCCESS
                }
                Err(e @ LaunchError::Config(_)) => {
                    eprintln!("rig: {e}");
                    ExitCode::from(2)
                }
                Err(e) => {
                    eprintln!("rig: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::Stalls {
            config,
            plan_lengths,
            runs,
            results,
            json,
        } => {
            let runs =
                runs.unwrap_or_else(|| PathBuf::from(format!("runs/stalls-{}", unix_secs())));
            let study = match rig_tools::stalls::run(&config, &plan_lengths, &runs) {
                Ok(s) => s,
                Err(e) => {
                    eprintln!("rig: stalls: {e}");
                    return ExitCode::FAILURE;
                }
            };
            let lengths: String = plan_lengths
                .iter()
                .map(|h| format!(" --plan-length {h}"))
                .collect();
            let command = format!("rig stalls {}{lengths}", config.display());
            let table = rig_tools::stalls::render_markdown(&study, &command);
            println!("{table}");
            let page = rig_tools::results_page::head(
                "Stall study",
                "rig stalls",
                "service/tools/src/stalls.rs",
                "[timing-protocol.md](../timing-protocol.md#plans-and-the-late-policy)",
            ) + &table;
            write_campaign("stalls", results.map(|p| (p, page)), json, &study)
        }
        Command::Soak {
            config,
            controller,
            runs,
            conditions,
            wait,
            duration,
            out,
            results,
        } => soak(
            rig_tools::soak::SoakOptions {
                scenario: config,
                controllers: controller,
                runs,
                conditions,
                waits: wait,
                duration,
                out: out.unwrap_or_else(|| PathBuf::from(format!("runs/soak-{}", unix_secs()))),
            },
            results,
        ),
        Command::Gaps {
            config,
            rls,
            rules,
            jobs,
            runs,
            results,
            json,
        } => {
            let parsed: Result<Vec<_>, _> =
                rules.split(',').map(rig_tools::gaps::Rule::parse).collect();
            let parsed = match parsed {
                Ok(r) => r,
                Err(e) => {
                    eprintln!("rig: gaps: --rules {e}");
                    return ExitCode::from(2);
                }
            };
            let mut variants = vec![rig_tools::gaps::Variant {
                name: "gradient".into(),
                controller: None,
            }];
            if let Some(f) = &rls {
                variants.push(rig_tools::gaps::Variant {
                    name: "rls".into(),
                    controller: Some(f.clone()),
                });
            }
            let runs = runs.unwrap_or_else(|| PathBuf::from(format!("runs/gaps-{}", unix_secs())));
            let campaign = match rig_tools::gaps::run(&config, &variants, &parsed, &runs, jobs) {
                Ok(c) => c,
                Err(e) => {
                    eprintln!("rig: gaps: {e}");
                    return ExitCode::FAILURE;
                }
            };
            let mut command = format!("rig gaps {}", config.display());
            if let Some(f) = &rls {
                command += &format!(" --rls {}", f.display());
            }
            command += &format!(" --rules {rules}");
            let table = rig_tools::gaps::render_markdown(&campaign, &command);
            println!("{table}");
            let page = rig_tools::results_page::head(
                "Gap campaign",
                "rig gaps",
                "service/tools/src/gaps.rs",
                "[rcac.md](../rcac.md#lost-samples-and-the-gap-rule)",
            ) + &table;
            write_campaign("gaps", results.map(|p| (p, page)), json, &campaign)
        }
        Command::Plot { run_folder } => match rig_tools::figures::run_folder_figure(&run_folder) {
            Ok(path) => {
                println!("wrote {}", path.display());
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("rig: plot: {e}");
                ExitCode::FAILURE
            }
        },
        Command::Monitor {
            rigs,
            listen,
            allow_commands,
            foxglove,
            any_core,
        } => monitor(rig_tools::monitor::MonitorOptions {
            rigs,
            listen,
            allow_commands,
            foxglove,
            any_core,
            ..Default::default()
        }),
        Command::Operator {
            rig,
            command,
            tunable,
            value,
            timeout,
        } => send_command(rig, command, tunable, value, timeout),
        Command::Check { config, controller } => {
            let checked = ScenarioCheck::load(&config, controller.as_deref())
                .and_then(|c| c.service.check_this_machine().map(|()| c));
            match checked {
                Ok(c) => {
                    println!("{}: ok ({})", config.display(), c.summary());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("rig: configuration refused: {e}");
                    ExitCode::from(2)
                }
            }
        }
    }
}

/// `rig monitor`: starts it, says where it listens, and runs until a signal.
fn monitor(opts: rig_tools::monitor::MonitorOptions) -> ExitCode {
    use std::io::Write;
    let mut m = match rig_tools::monitor::Monitor::start(&opts) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("rig: monitor: {e}");
            return ExitCode::from(2);
        }
    };
    let commands = if opts.allow_commands {
        "commands allowed"
    } else {
        "commands disabled"
    };
    println!(
        "rig monitor: listening on http://{}/ (rigs: {}; {commands})",
        m.http_addr(),
        opts.rigs.join(", ")
    );
    if let Some(a) = m.foxglove_addr() {
        println!("rig monitor: foxglove on ws://{a}");
    }
    if opts.allow_commands && !m.http_addr().ip().is_loopback() {
        eprintln!(
            "rig monitor: warning: commands are allowed and {} is not a loopback address: \
             anyone who reaches it can stop the run",
            m.http_addr()
        );
    }
    let _ = std::io::stdout().flush();
    let waited = m.wait_for_signal();
    m.shutdown();
    match waited {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rig: monitor: {e}");
            ExitCode::FAILURE
        }
    }
}

/// `rig command`: sends one command, prints the reply; 0 only when it applied.
fn send_command(
    rig: String,
    command: String,
    tunable: Option<String>,
    value: Option<f64>,
    timeout: f64,
) -> ExitCode {
    use rig_tools::monitor::commands::{self, CommandReply, CommandRequest};
    if !(timeout.is_finite() && timeout > 0.0 && timeout <= 3600.0) {
        eprintln!("rig: command: --timeout {timeout}: give seconds in (0, 3600]");
        return ExitCode::from(2);
    }
    let req = CommandRequest {
        rig: rig.clone(),
        command,
        tunable,
        value,
    };
    let request = match req.to_request(commands::next_request_id()) {
        Ok(r) => r,
        Err(e) => {
            eprintln!("rig: command: {e}");
            return ExitCode::from(2);
        }
    };
    match commands::send(&rig, &request, std::time::Duration::from_secs_f64(timeout)) {
        Ok(reply) => {
            let view = CommandReply::of(&rig, &request, &reply);
            println!("{}", view.line());
            if view.applied {
                ExitCode::SUCCESS
            } else {
                ExitCode::FAILURE
            }
        }
        Err(e) => {
            eprintln!("rig: command: rig '{rig}': {}: {e}", req.command);
            ExitCode::FAILURE
        }
    }
}

/// Seconds since the Unix epoch (0 if the clock is before it).
fn unix_secs() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

/// `rig soak`: checks the options, runs the campaign, prints its summary and writes the
/// Writes what a campaign (`rig {name}`) was asked to: its results page (`--results`: the
/// file and its text) and its record as JSON (`--json`). A file that cannot be written is
/// reported as `rig: {name}: {file}: {error}` and the others are still written; the exit
/// code is a failure if any was not.
fn write_campaign(
    name: &str,
    results: Option<(PathBuf, String)>,
    json: Option<PathBuf>,
    record: &impl serde::Serialize,
) -> ExitCode {
    let json = json.map(|p| (p, serde_json::to_string_pretty(record).unwrap_or_default()));
    let mut ok = true;
    for (path, text) in results.into_iter().chain(json) {
        if let Err(e) = ipc_types::files::write_atomic(&path, text.as_bytes()) {
            eprintln!("rig: {name}: {}: {e}", path.display());
            ok = false;
        }
    }
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}

/// results file.
fn soak(opts: rig_tools::soak::SoakOptions, results: Option<PathBuf>) -> ExitCode {
    use rig_tools::soak::{self, SoakError};
    let plan = match soak::plan(&opts) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("rig: soak: {e}");
            return ExitCode::from(match e {
                SoakError::Usage(_) => 2,
                SoakError::Run(_) => 1,
            });
        }
    };
    let stop = Arc::new(AtomicUsize::new(0));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register_usize(sig, stop.clone(), sig as usize);
    }
    let results = results.unwrap_or_else(|| plan.out.join("soak.md"));
    let command = soak::command_line(std::env::args());
    let campaign = match soak::run(plan, command, stop) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("rig: soak: {e}");
            return ExitCode::FAILURE;
        }
    };
    println!("{}", campaign.summary_text());
    let mut ok = campaign.interrupted.is_none();
    if let Some(why) = &campaign.interrupted {
        eprintln!("rig: soak: interrupted: {why}");
    }
    match ipc_types::files::write_atomic(&results, campaign.render_markdown().as_bytes()) {
        Ok(()) => println!("results: {}", results.display()),
        Err(e) => {
            eprintln!("rig: soak: {}: {e}", results.display());
            ok = false;
        }
    }
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
