//! `service`: the adaptive real-time control service.
//!
//! ```text
//! service run <scenario.toml> [--run-folder DIR] [--exit-with-plant] [--max-cycles N] [--wait busy-poll|block] [--core N]
//! service launch <scenario.toml> [--mode real-time|lockstep] [--duration S] [--wait ...]
//! service check <scenario.toml>
//! service plot <run-folder>
//! ```
//!
//! `run` is the service alone, against whatever plant process serves the rig (plant-proxy or
//! a DAQ I/O process). `launch` is the main job: it starts plant-proxy (found next to this
//! executable) as a second process on the same scenario, runs the service until the plant
//! ends, and prints the run report. `check` validates a configuration and exits.

use clap::{Parser, Subcommand};
use service::config::{ServiceConfig, WaitMode};
use service::rt_alloc::RtAwareAllocator;
use service::runtime::{RunOptions, run};
use std::path::{Path, PathBuf};
use std::process::{Command as Process, ExitCode, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

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
    },
    /// The main job: start plant-proxy on the same scenario and run the service against it.
    Launch {
        #[command(flatten)]
        common: Common,
        /// Plant pacing: real-time (default) or lockstep.
        #[arg(long, default_value = "real-time")]
        mode: String,
        /// Seconds of plant time (default: rig.duration).
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Draw run.png (z open and closed loop, u, ‖θ‖, PSDs) from a run folder.
    Plot {
        /// A run folder (holds signals.csv and report.json).
        run_folder: PathBuf,
    },
    /// Validate the configuration and exit.
    Check {
        /// Scenario / configuration TOML file.
        config: PathBuf,
    },
}

fn parse_wait(s: &str) -> Result<WaitMode, String> {
    match s {
        "busy-poll" => Ok(WaitMode::BusyPoll),
        "block" => Ok(WaitMode::Block),
        _ => Err(format!("'{s}' is not busy-poll or block")),
    }
}

fn load(path: &Path, controller: Option<&Path>) -> Result<ServiceConfig, ExitCode> {
    match controller {
        Some(c) => ServiceConfig::load_with_controller(path, c),
        None => ServiceConfig::load(path),
    }
    .map_err(|e| {
        eprintln!("service: configuration refused: {e}");
        ExitCode::from(2)
    })
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
        Command::Check { config } => match load(&config, None) {
            Ok(c) => {
                println!(
                    "{}: ok (rig '{}', {} Hz, channels y={} z={} r={} u={})",
                    config.display(),
                    c.rig,
                    1e9 / c.sample_period_ns as f64,
                    c.counts.n_y,
                    c.counts.n_z,
                    c.counts.n_r,
                    c.counts.n_u
                );
                ExitCode::SUCCESS
            }
            Err(code) => code,
        },
        Command::Run {
            common,
            exit_with_plant,
            max_cycles,
        } => {
            let cfg = match load(&common.config, common.controller.as_deref()) {
                Ok(c) => c,
                Err(code) => return code,
            };
            let opts = RunOptions {
                run_folder: common.run_folder,
                exit_with_plant,
                max_cycles,
                wait: common.wait,
                core: common.core,
            };
            match run(&cfg, &opts, shutdown_flag()) {
                Ok(report) => {
                    println!("{}", report.render());
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("service: {e}");
                    ExitCode::FAILURE
                }
            }
        }
        Command::Launch {
            common,
            mode,
            duration,
        } => launch(common, &mode, duration),
        Command::Plot { run_folder } => match service::figures::run_folder_figure(&run_folder) {
            Ok(path) => {
                println!("wrote {}", path.display());
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("service: plot: {e}");
                ExitCode::FAILURE
            }
        },
    }
}

fn launch(common: Common, mode: &str, duration: Option<f64>) -> ExitCode {
    let cfg = match load(&common.config, common.controller.as_deref()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    let exe = std::env::current_exe().ok();
    let plant_bin = exe
        .as_ref()
        .and_then(|e| e.parent())
        .map(|d| d.join("plant-proxy"));
    let Some(plant_bin) = plant_bin.filter(|p| p.exists()) else {
        eprintln!(
            "service: plant-proxy was not found next to this executable; build the workspace first \
             (cargo build --release)"
        );
        return ExitCode::FAILURE;
    };
    let folder = common.run_folder.clone().unwrap_or_else(|| {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        cfg.run_dir.join(format!("{}-{secs}", cfg.rig))
    });
    if let Err(e) = std::fs::create_dir_all(&folder) {
        eprintln!("service: creating {}: {e}", folder.display());
        return ExitCode::FAILURE;
    }
    let mut plant = Process::new(&plant_bin);
    plant
        .arg("run")
        .arg(&common.config)
        .args(["--mode", mode])
        .arg("--report")
        .arg(folder.join("plant-report.json"))
        .stdin(Stdio::null());
    if let Some(d) = duration {
        let steps = (d * 1e9 / cfg.sample_period_ns as f64).round() as u64;
        plant.args(["--steps", &steps.to_string()]);
    }
    eprintln!(
        "[launch] rig '{}': plant-proxy ({mode}) and the service, run folder {}",
        cfg.rig,
        folder.display()
    );
    let mut child = match plant.spawn() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("service: starting {}: {e}", plant_bin.display());
            return ExitCode::FAILURE;
        }
    };
    let plant_pid = child.id() as i32;
    let shutdown = shutdown_flag();
    // If the plant exits on its own (error or end), stop the service shortly after, so that a
    // plant that failed before connecting does not leave the service waiting.
    let child_status = Arc::new(std::sync::Mutex::new(None));
    let watcher = {
        let shutdown = shutdown.clone();
        let status = child_status.clone();
        std::thread::spawn(move || {
            let st = child.wait();
            *status.lock().unwrap() = st.ok();
            std::thread::sleep(Duration::from_millis(1500));
            shutdown.store(true, Ordering::Relaxed);
        })
    };
    let opts = RunOptions {
        run_folder: Some(folder.clone()),
        exit_with_plant: true,
        max_cycles: None,
        wait: common.wait,
        core: common.core,
    };
    let result = run(&cfg, &opts, shutdown.clone());
    shutdown.store(true, Ordering::Relaxed);
    // The plant normally ends by itself (its last sample ended the service). If it has not
    // within 2 s (the service failed, or was stopped by a signal), stop it too.
    let deadline = std::time::Instant::now() + Duration::from_secs(2);
    while child_status.lock().unwrap().is_none()
        && std::time::Instant::now() < deadline
        && !watcher.is_finished()
    {
        std::thread::sleep(Duration::from_millis(20));
    }
    if child_status.lock().unwrap().is_none() {
        // SAFETY: kill with our child's pid and a valid signal.
        unsafe { libc::kill(plant_pid, libc::SIGTERM) };
    }
    let _ = watcher.join();
    let plant_ok = child_status.lock().unwrap().is_some_and(|s| s.success());
    let stopped_by_signal =
        matches!(&result, Ok(r) if r.stop_reason == service::runtime::StopReason::Signal);
    match result {
        Ok(report) => {
            println!("{}", report.render());
            if cfg.log.enabled {
                match service::figures::run_folder_figure(&folder) {
                    Ok(path) => println!("figure: {}", path.display()),
                    Err(e) => eprintln!("service: no figure: {e}"),
                }
            }
            if !plant_ok && !stopped_by_signal {
                eprintln!("service: plant-proxy did not end cleanly");
                return ExitCode::FAILURE;
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("service: {e}");
            ExitCode::FAILURE
        }
    }
}
