//! The second process of the two-process measurements.
//!
//! The bench re-executes its own binary (`std::env::current_exe()`) with a hidden
//! subcommand that selects the child's role: the real service ([`run_service_child`]) or a
//! raw iceoryx2 echo (`crate::roundtrip::run_echo_child`). The child is started from the
//! parent's main thread, which is never pinned nor given a real-time policy, so the child
//! starts with default scheduling and all cores and does its own real-time set-up, exactly
//! as a deployed service does. Its standard output and error go to a log file next to its
//! results. [`ChildProc`] terminates the child (SIGTERM, then SIGKILL) if it is still
//! running when the parent gives up on it, and the child gets SIGTERM when the bench dies
//! (`PR_SET_PDEATHSIG`): a service child busy-polls at `SCHED_FIFO` on the RT core and
//! never ends by itself without its plant, so one left behind by a killed bench would keep
//! that core from every later bench's service child, which then never connects (see
//! [`crate::machine::rt_threads_on_core`]). [`drive`] runs the parent's measuring thread
//! while watching the child; its errors say whether the child still ran or how it ended,
//! with the end of its log. [`repin_rt_thread`] checks, inside the service child,
//! that the service's RT thread really runs on its core. On the parent side,
//! [`spawn_service`] ([`spawn_service_with`]) writes a service configuration and starts the
//! service child on it, and [`read_report`] reads the run report it leaves.

use crate::cli::Settings;
use crate::configs::{self, Channels};
use serde_json::Value;
use service::config::{ServiceConfig, WaitMode};
use service::runtime::{RunOptions, run};
use std::fs::File;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

/// A running child process of the bench.
pub struct ChildProc {
    child: Child,
    /// The file that receives its standard output and error.
    pub log: PathBuf,
    /// What it is, for messages.
    pub what: String,
    /// The core its real-time thread is pinned to, when it has one: a failure then also
    /// names the real-time threads of other processes running there.
    pub rt_core: Option<usize>,
    exited: Option<ExitStatus>,
    /// Set when it did not end even after SIGKILL.
    unkillable: bool,
}

/// How long [`ChildProc::terminate`] waits after SIGTERM, then after SIGKILL.
const TERM_GRACE: Duration = Duration::from_secs(2);
const KILL_GRACE: Duration = Duration::from_secs(5);

impl ChildProc {
    /// Starts `program` (`None`: this executable again) with `args`, output to `log`.
    pub fn spawn(
        program: Option<&Path>,
        args: &[String],
        log: &Path,
        what: &str,
    ) -> Result<Self, String> {
        let exe = match program {
            Some(p) => p.to_path_buf(),
            None => std::env::current_exe()
                .map_err(|e| format!("cannot find the bench executable: {e}"))?,
        };
        let out = File::create(log).map_err(|e| format!("creating {}: {e}", log.display()))?;
        let err = out
            .try_clone()
            .map_err(|e| format!("{}: {e}", log.display()))?;
        let mut cmd = Command::new(&exe);
        cmd.args(args).stdin(Stdio::null()).stdout(out).stderr(err);
        let parent = std::process::id() as libc::pid_t;
        // SAFETY: the closure runs in the child between fork and exec and only calls prctl,
        // getppid and _exit, which are async-signal-safe, with valid arguments.
        unsafe {
            cmd.pre_exec(move || {
                // SIGTERM when the thread that started it (the bench's main thread) dies: a
                // service child stops its loop on it and removes its iceoryx2 resources.
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // The bench died before the setting took effect: no signal will come.
                if libc::getppid() != parent {
                    libc::_exit(1);
                }
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .map_err(|e| format!("starting the {what} child ({}): {e}", exe.display()))?;
        Ok(Self {
            child,
            log: log.to_path_buf(),
            what: what.to_string(),
            rt_core: None,
            exited: None,
            unkillable: false,
        })
    }

    /// `Err` with the end of its log when the child has already exited.
    pub fn check_alive(&mut self) -> Result<(), String> {
        if let Some(st) = self.poll() {
            return Err(format!(
                "the {} child exited early ({st}): {}",
                self.what,
                self.log_tail(1500)
            ));
        }
        Ok(())
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// How it stands, for messages: `exited (exit status: 3)`, `is still running (pid 12)`,
    /// `is still running (pid 12) even after SIGKILL: …`.
    pub fn state(&mut self) -> String {
        match self.poll() {
            Some(st) => format!("exited ({st})"),
            None if self.unkillable => format!(
                "is still running (pid {}) even after SIGKILL: one of its threads cannot be \
                 scheduled",
                self.pid()
            ),
            None => format!("is still running (pid {})", self.pid()),
        }
    }

    /// What a failure message says about the child: its state, what runs on its RT core
    /// when something else does, and the end of its log.
    pub fn diagnosis(&mut self) -> String {
        let state = self.state();
        let pid = self.pid();
        let core = self
            .rt_core
            .map(|c| crate::machine::core_occupancy_note(c, &[pid]))
            .filter(|n| !n.is_empty())
            .map(|n| format!("; {n}"))
            .unwrap_or_default();
        format!(
            "the {} child {state}{core}: {}",
            self.what,
            self.log_tail(1500)
        )
    }

    /// Its exit status, once it has exited.
    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.exited.is_none() {
            self.exited = self.child.try_wait().ok().flatten();
        }
        self.exited
    }

    /// Waits up to `timeout` for the child to exit; terminates it and fails if it does not.
    /// A non-zero exit status is an error carrying the end of its log.
    pub fn wait(&mut self, timeout: Duration) -> Result<(), String> {
        let start = Instant::now();
        loop {
            if let Some(st) = self.poll() {
                return if st.success() {
                    Ok(())
                } else {
                    Err(format!(
                        "the {} child failed ({st}): {}",
                        self.what,
                        self.log_tail(1500)
                    ))
                };
            }
            if start.elapsed() > timeout {
                self.terminate();
                return Err(format!(
                    "did not exit within {:.0} s and was terminated; {}",
                    timeout.as_secs_f64(),
                    self.diagnosis()
                ));
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// SIGTERM, up to 2 s of grace, then SIGKILL and up to 5 s more. Never waits longer:
    /// a child one of whose threads cannot be scheduled (a real-time thread pinned to a
    /// core another real-time thread holds) does not end even on SIGKILL, and is then
    /// reported as such ([`ChildProc::state`]).
    pub fn terminate(&mut self) {
        if self.poll().is_some() {
            return;
        }
        for (sig, grace) in [(libc::SIGTERM, TERM_GRACE), (libc::SIGKILL, KILL_GRACE)] {
            // SAFETY: kill only sends a signal to our own child's pid (not reaped yet).
            unsafe { libc::kill(self.child.id() as libc::pid_t, sig) };
            let start = Instant::now();
            while start.elapsed() < grace {
                if self.poll().is_some() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        self.unkillable = true;
    }

    /// The last `n` bytes of the child's log.
    pub fn log_tail(&self, n: usize) -> String {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        let mut start = text.len().saturating_sub(n);
        while !text.is_char_boundary(start) {
            start += 1;
        }
        let tail = text[start..].trim();
        if tail.is_empty() {
            format!("(empty log {})", self.log.display())
        } else {
            format!("\n--- end of {} ---\n{tail}", self.log.display())
        }
    }
}

impl Drop for ChildProc {
    fn drop(&mut self) {
        self.terminate();
    }
}

/// A flag set by SIGINT or SIGTERM, so a child asked to stop ends its loop and cleans up
/// its iceoryx2 resources.
pub fn shutdown_flag() -> Arc<AtomicBool> {
    let flag = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let _ = signal_hook::flag::register(sig, flag.clone());
    }
    flag
}

/// The service child: parses `config` with `ServiceConfig::parse(text, "bench")` and runs
/// the real service loop (`service::runtime::run`) in `wait` mode with its RT thread on
/// `core`, writing into `run_folder`, until the plant sends its last sample. Prints the run
/// report (also in `run_folder/report.json`). Returns the process exit code.
pub fn run_service_child(config: &Path, wait: WaitMode, core: usize, run_folder: &Path) -> i32 {
    let text = match std::fs::read_to_string(config) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("[bench child] reading {}: {e}", config.display());
            return 2;
        }
    };
    let cfg = match ServiceConfig::parse(&text, "bench") {
        Ok(c) => c,
        Err(e) => {
            eprintln!("[bench child] {e}");
            return 2;
        }
    };
    let opts = RunOptions {
        exit_with_plant: true,
        wait: Some(wait),
        core: Some(core),
        run_folder: Some(run_folder.to_path_buf()),
        ..Default::default()
    };
    let pinner = repin_rt_thread(core, run_folder.to_path_buf());
    let result = run(&cfg, &opts, shutdown_flag());
    let _ = pinner.join();
    match result {
        Ok(report) => {
            println!("{}", report.render());
            match report.write_json() {
                Ok(()) => 0,
                Err(e) => {
                    eprintln!("[bench child] {e}");
                    1
                }
            }
        }
        Err(e) => {
            eprintln!("[bench child] service failed: {e}");
            1
        }
    }
}

/// Runs `work` on a new thread set up with `rt` (the plant side of a two-process
/// measurement) while the calling thread watches `child`: if the child exits before `work`
/// is done, the flag handed to `work` is raised so that it stops waiting, and the error
/// carries the end of the child's log. Returns `work`'s result and the thread's RT set-up.
///
/// If `work` has not finished after `limit`, the flag is raised and the child is
/// terminated: a plant thread that cannot run (for instance because a real-time thread of
/// the child landed on its core and never yields) then gets its core back and returns.
pub fn drive<T: Send>(
    child: &mut ChildProc,
    rt: ipc_types::rt::RtRequest,
    limit: Duration,
    work: impl FnOnce(&AtomicBool) -> Result<T, String> + Send,
) -> Result<(T, ipc_types::rt::RtSetup), String> {
    use std::sync::atomic::Ordering;
    let abort = AtomicBool::new(false);
    let started = Instant::now();
    let mut timed_out = false;
    let (result, setup) = std::thread::scope(|s| {
        let handle = std::thread::Builder::new()
            .name("bench-plant".into())
            .spawn_scoped(s, || {
                let setup = ipc_types::rt::setup_current_thread(&rt);
                (work(&abort), setup)
            })
            .expect("spawning the plant thread");
        while !handle.is_finished() {
            if child.poll().is_some() {
                abort.store(true, Ordering::Relaxed);
            }
            if !timed_out && started.elapsed() > limit {
                timed_out = true;
                abort.store(true, Ordering::Relaxed);
                child.terminate();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        handle.join().unwrap_or_else(|_| {
            let skipped = ipc_types::rt::StepOutcome::Skipped;
            let setup = ipc_types::rt::RtSetup {
                affinity: skipped.clone(),
                fifo: skipped.clone(),
                mlockall: skipped.clone(),
                cpu_latency: skipped,
            };
            (Err("the plant thread panicked".into()), setup)
        })
    });
    match result {
        Ok(v) => Ok((v, setup)),
        Err(e) if timed_out => Err(format!(
            "{e}; the measurement did not finish within {:.0} s and the child was terminated; {}",
            limit.as_secs_f64(),
            child.diagnosis()
        )),
        // The child exited early (the flag was raised for it), or the measurement failed
        // while it still ran (a connection that timed out): say which, with its log.
        Err(e) => Err(format!("{e}; {}", child.diagnosis())),
    }
}

/// Name the service gives its real-time thread.
pub const RT_THREAD_NAME: &str = "rt-loop";

/// File in the run folder where the child notes that it re-pinned the service's RT thread.
pub const REPIN_NOTE: &str = "bench-repin.txt";

/// Guard, on the child side, against a service whose RT thread is not on its core.
///
/// A bench whose service RT thread busy-polls on the plant's core measures nothing useful
/// and can even stall (two `SCHED_FIFO` spinners of equal priority on one core). This
/// happened while the bench was written: `service::runtime::run` restricts the calling
/// thread to every core but the RT core (`keep_off_core`) before it starts the RT thread,
/// which inherits that mask, and `ipc_types::rt::pin_current_thread` then looked the core
/// up among the cores of the thread's *current* mask (`core_affinity::get_core_ids`), did
/// not find it and refused ("core N does not exist on this machine").
///
/// This helper thread, started before `run`, waits for the thread named
/// [`RT_THREAD_NAME`] to appear, and if its affinity is not exactly `{core}` sets it
/// (`sched_setaffinity` on its thread id) and writes [`REPIN_NOTE`] into the run folder,
/// which the bench reports. When the service pins correctly it finds the mask right and
/// does nothing.
pub fn repin_rt_thread(core: usize, run_folder: PathBuf) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(30) {
            if let Some(tid) = find_thread(RT_THREAD_NAME) {
                // Let the thread finish its own set-up first.
                std::thread::sleep(Duration::from_millis(5));
                match ensure_affinity(tid, core) {
                    Ok(false) => {}
                    Ok(true) => {
                        let msg = format!(
                            "the service's {RT_THREAD_NAME} thread (tid {tid}) was not pinned to core {core}; \
                             latency-bench re-pinned it"
                        );
                        eprintln!("[bench child] {msg}");
                        let _ = std::fs::write(run_folder.join(REPIN_NOTE), format!("{msg}\n"));
                    }
                    Err(e) => eprintln!("[bench child] could not re-pin the RT thread: {e}"),
                }
                return;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    })
}

fn find_thread(name: &str) -> Option<libc::pid_t> {
    for entry in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let comm = std::fs::read_to_string(entry.path().join("comm")).unwrap_or_default();
        if comm.trim() == name {
            return entry.file_name().to_str()?.parse().ok();
        }
    }
    None
}

/// Makes the affinity of thread `tid` exactly `{core}`; true when it had to be changed.
fn ensure_affinity(tid: libc::pid_t, core: usize) -> Result<bool, String> {
    // SAFETY: cpu_set_t is plain data; the calls only read or write the set given.
    unsafe {
        let mut current: libc::cpu_set_t = core::mem::zeroed();
        if libc::sched_getaffinity(tid, core::mem::size_of::<libc::cpu_set_t>(), &mut current) != 0
        {
            return Err(format!(
                "sched_getaffinity({tid}): {}",
                std::io::Error::last_os_error()
            ));
        }
        let mut wanted: libc::cpu_set_t = core::mem::zeroed();
        libc::CPU_SET(core, &mut wanted);
        if libc::CPU_EQUAL(&current, &wanted) {
            return Ok(false);
        }
        if libc::sched_setaffinity(tid, core::mem::size_of::<libc::cpu_set_t>(), &wanted) != 0 {
            return Err(format!(
                "sched_setaffinity({tid}, {{{core}}}): {}",
                std::io::Error::last_os_error()
            ));
        }
    }
    Ok(true)
}

/// Writes a service configuration for `rig` into `dir` (the 2-state LTI loop controller of
/// [`configs::loop_controller`], one channel each) and starts the service child on it,
/// waiting in mode `wait` (`busy-poll` or `block`) on the RT core.
pub fn spawn_service(s: &Settings, dir: &Path, rig: &str, wait: &str) -> Result<ChildProc, String> {
    let text = configs::service_toml(
        rig,
        Channels { y: 1, z: 1, u: 1 },
        &configs::loop_controller(),
        s.service_log,
    );
    spawn_service_with(s, dir, &text, wait)
}

/// Writes the service configuration `text` into `dir/config.toml` and starts the service
/// child on it, waiting in mode `wait` (`busy-poll` or `block`) on the RT core and writing
/// its run folder into `dir`.
pub fn spawn_service_with(
    s: &Settings,
    dir: &Path,
    text: &str,
    wait: &str,
) -> Result<ChildProc, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let config = dir.join("config.toml");
    std::fs::write(&config, text).map_err(|e| format!("writing {}: {e}", config.display()))?;
    let args = vec![
        "child-service".to_string(),
        "--config".into(),
        config.display().to_string(),
        "--wait".into(),
        wait.into(),
        "--core".into(),
        s.rt_core.to_string(),
        "--run-folder".into(),
        dir.display().to_string(),
    ];
    let mut child = ChildProc::spawn(
        s.child_exe.as_deref(),
        &args,
        &dir.join("child.log"),
        &format!("service ({wait})"),
    )?;
    child.rt_core = Some(s.rt_core);
    Ok(child)
}

/// The service's run report (`dir/report.json`), with the note of [`REPIN_NOTE`] added as
/// `latency_bench_repin` when the child had to re-pin the RT thread.
pub fn read_report(dir: &Path) -> Result<Value, String> {
    let path = dir.join("report.json");
    let text =
        std::fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    let mut report: Value =
        serde_json::from_str(&text).map_err(|e| format!("parsing {}: {e}", path.display()))?;
    if let (Ok(note), Some(obj)) = (
        std::fs::read_to_string(dir.join(REPIN_NOTE)),
        report.as_object_mut(),
    ) {
        obj.insert(
            "latency_bench_repin".into(),
            Value::String(note.trim().to_string()),
        );
    }
    Ok(report)
}

/// The service's RT set-up as its report states it, and whether the bench had to re-pin
/// its RT thread.
pub fn service_rt_line(report: &Value) -> String {
    let setup = report
        .get("rt_setup")
        .and_then(Value::as_str)
        .unwrap_or("?");
    if report.get("latency_bench_repin").is_some() {
        format!(
            "{setup} → RT thread re-pinned to its core by the bench (service pinning bug, see child.log)"
        )
    } else {
        setup.to_string()
    }
}
