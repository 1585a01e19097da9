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
//! Ending: each child gets `SIGTERM` if this process dies (`PR_SET_PDEATHSIG`), so neither
//! is left running alone. A `SIGINT` or `SIGTERM` to the launcher is passed to the service
//! (which flushes its logs and reports) and then to the plant. A plant that ends on its own
//! leaves the service 1.5 s to end by itself before it is stopped; a service that ends
//! leaves the plant 2 s. The launch fails (exit code 1) when the service fails, or when
//! the plant did not end cleanly and the launcher was not asked to stop; a refused
//! configuration exits with 2 before anything starts.

use service::config::ServiceConfig;
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
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
    /// `busy-poll` or `block`, passed to `service run --wait`.
    pub wait: Option<String>,
    /// The service's RT core, passed to `service run --core`.
    pub core: Option<usize>,
    /// A file whose `[controller]` (and `[log]`) replace the scenario's.
    pub controller: Option<PathBuf>,
}

/// Why a launch failed.
#[derive(Debug)]
pub enum LaunchError {
    /// The configuration was refused (exit code 2).
    Config(String),
    /// A process could not be started, or the run failed (exit code 1).
    Run(String),
}

impl std::fmt::Display for LaunchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LaunchError::Config(m) => write!(f, "configuration refused: {m}"),
            LaunchError::Run(m) => f.write_str(m),
        }
    }
}

/// What a finished launch left.
#[derive(Debug, Clone)]
pub struct Launched {
    /// The run folder.
    pub folder: PathBuf,
    /// The figure, when one was drawn.
    pub figure: Option<PathBuf>,
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

/// Starts `cmd` so that it gets `SIGTERM` when this process dies.
fn spawn_tied(cmd: &mut Command, name: &str) -> Result<Child, LaunchError> {
    // SAFETY: the closure runs in the child between fork and exec and only calls prctl,
    // which is async-signal-safe, with valid arguments.
    unsafe {
        cmd.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.spawn()
        .map_err(|e| LaunchError::Run(format!("starting {name}: {e}")))
}

fn terminate(child: &Child) {
    // SAFETY: kill with our own child's pid and a valid signal.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
}

/// Waits up to `grace` for `child` to end.
fn wait_within(child: &mut Child, grace: Duration) -> Option<ExitStatus> {
    let deadline = Instant::now() + grace;
    loop {
        if let Ok(Some(st)) = child.try_wait() {
            return Some(st);
        }
        if Instant::now() >= deadline {
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs the main job (see the module docs); `stop` set by a signal handler asks it to end.
pub fn launch(opts: &LaunchOptions, stop: Arc<AtomicBool>) -> Result<Launched, LaunchError> {
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
    eprintln!(
        "[launch] rig '{}': plant-proxy ({}) and the service, run folder {}",
        cfg.rig,
        opts.mode,
        folder.display()
    );
    let mut plant = spawn_tied(&mut plant, &plant_bin.display().to_string())?;
    let mut service = match spawn_tied(&mut service, &service_bin.display().to_string()) {
        Ok(s) => s,
        Err(e) => {
            terminate(&plant);
            let _ = plant.wait();
            return Err(e);
        }
    };

    let (mut plant_status, mut service_status) = (None, None);
    let mut signalled = false;
    while service_status.is_none() {
        if stop.load(Ordering::Relaxed) && !signalled {
            signalled = true;
            terminate(&service);
        }
        if plant_status.is_none() {
            plant_status = plant.try_wait().ok().flatten();
            if plant_status.is_some() && !signalled {
                // The plant ended (its last sample, or an error): the service ends with it;
                // if it does not within 1.5 s, stop it.
                service_status = wait_within(&mut service, Duration::from_millis(1500));
                if service_status.is_none() {
                    terminate(&service);
                }
            }
        }
        if service_status.is_none() {
            service_status = service.try_wait().ok().flatten();
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    if plant_status.is_none() {
        plant_status = wait_within(&mut plant, Duration::from_secs(2));
        if plant_status.is_none() {
            terminate(&plant);
            plant_status = plant.wait().ok();
        }
    }
    let service_ok = service_status.is_some_and(|s| s.success());
    let plant_ok = plant_status.is_some_and(|s| s.success());
    if !service_ok {
        return Err(LaunchError::Run(format!(
            "the service did not end cleanly ({})",
            describe(service_status)
        )));
    }
    let figure = if cfg.log.enabled {
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
    if !plant_ok && !signalled {
        return Err(LaunchError::Run(format!(
            "plant-proxy did not end cleanly ({})",
            describe(plant_status)
        )));
    }
    Ok(Launched { folder, figure })
}

fn describe(st: Option<ExitStatus>) -> String {
    match st {
        Some(s) => s.to_string(),
        None => "status unknown".into(),
    }
}
