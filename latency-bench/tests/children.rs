//! The bench's child processes: a failed connection says how the child stands (its exit
//! status, or that it still runs) with the end of its log; a killed bench leaves no service
//! child behind (such a leftover busy-polls at `SCHED_FIFO` on the RT core for ever and
//! starves every later bench's service child, whose plant then reports "no peer: …
//! /actuation did not appear within 20.0 s"); and a round under the rig name of a run that
//! was killed still connects.
//!
//! The two-process tests run the built `latency-bench` binary; they take the bench's cores
//! one at a time (a lock), and none asserts a timing.

mod common;
use common::test_dir;
use ipc_types::ChannelCounts;
use ipc_types::rt::RtRequest;
use latency_bench::child::{ChildProc, drive};
use latency_bench::cli::{Cli, Settings};
use latency_bench::roundtrip::{RoundTripPlan, contract_round, contract_round_trips};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One two-process test at a time: they share the plant and RT cores.
static CORES: Mutex<()> = Mutex::new(());

const BENCH: &str = env!("CARGO_BIN_EXE_latency-bench");

fn counts() -> ChannelCounts {
    ChannelCounts::new(1, 1, 0, 1).expect("within capacity")
}

/// A unique rig name for one test.
fn rig(test: &str) -> String {
    format!("{}-{test}", latency_bench::rig_base())
}

/// No real-time set-up: the plant side of the tests that do not measure.
fn no_rt() -> RtRequest {
    RtRequest {
        core: None,
        fifo_priority: None,
        mlockall: false,
        prefault_stack_bytes: 0,
        cpu_latency_us: None,
    }
}

fn plan(connect_timeout: Duration) -> RoundTripPlan {
    RoundTripPlan {
        warmup: 10,
        samples: 100,
        gap_ns: 0,
        answer_timeout: Duration::from_secs(10),
        connect_timeout,
    }
}

/// `/bin/sh -c script` started as the bench starts its service child, logging into
/// `<dir>/child.log`.
fn shell_child(dir: &Path, script: &str) -> ChildProc {
    let args = ["-c".to_string(), script.to_string()];
    ChildProc::spawn(
        Some(Path::new("/bin/sh")),
        &args,
        &dir.join("child.log"),
        "service (busy-poll)",
    )
    .expect("starting /bin/sh")
}

#[test]
fn a_child_that_exits_early_yields_an_error_naming_its_exit_status_and_the_end_of_its_log() {
    let dir = test_dir("early-exit");
    let mut child = shell_child(&dir, "echo 'cannot pin to core 7' >&2; exit 3");
    let rig = rig("early");
    let plan = plan(Duration::from_secs(600));
    let err = drive(&mut child, no_rt(), Duration::from_secs(600), |abort| {
        contract_round_trips(&rig, counts(), &plan, abort)
    })
    .expect_err("no service ever connects");
    assert!(err.contains("connecting as the plant"), "{err}");
    assert!(
        err.contains("the service (busy-poll) child exited (exit status: 3)"),
        "{err}"
    );
    assert!(err.contains("cannot pin to core 7"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_child_that_runs_but_never_connects_is_named_as_still_running_in_the_connection_error() {
    let dir = test_dir("no-connect");
    let mut child = shell_child(&dir, "echo 'still setting up'; exec sleep 600");
    let pid = child.pid();
    let watched = Watched::new_or_gone(pid);
    let rig = rig("noconn");
    let plan = plan(Duration::from_millis(300));
    let err = drive(&mut child, no_rt(), Duration::from_secs(600), |abort| {
        contract_round_trips(&rig, counts(), &plan, abort)
    })
    .expect_err("the child never connects");
    assert!(err.contains("/actuation' did not appear"), "{err}");
    assert!(
        err.contains(&format!("child is still running (pid {pid})")),
        "{err}"
    );
    assert!(err.contains("still setting up"), "{err}");
    // Dropping it terminates it.
    drop(child);
    assert!(!running(&watched), "dropping a ChildProc ends its process");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Fields after the command name of `/proc/<pid>/stat`.
fn stat(pid: u32) -> Option<Vec<String>> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let close = text.rfind(')')?;
    Some(
        text[close + 1..]
            .split_whitespace()
            .map(str::to_string)
            .collect(),
    )
}

/// A process by pid and start time, so that a reused pid is not taken for it.
struct Watched {
    pid: u32,
    started: Option<String>,
}

impl Watched {
    fn new_or_gone(pid: u32) -> Self {
        Self {
            pid,
            started: stat(pid).map(|f| f[19].clone()),
        }
    }
}

/// Whether it still runs (exists, is not a zombie, and is the same process).
fn running(w: &Watched) -> bool {
    match (stat(w.pid), &w.started) {
        (Some(f), Some(started)) => f[0] != "Z" && f[0] != "X" && &f[19] == started,
        _ => false,
    }
}

/// The children of `parent` (by the parent pid in their stat).
fn children_of(parent: u32) -> Vec<u32> {
    let mut found = Vec::new();
    for e in std::fs::read_dir("/proc").expect("/proc").flatten() {
        if let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok())
            && stat(pid).and_then(|f| f.get(1).and_then(|p| p.parse().ok())) == Some(parent)
        {
            found.push(pid);
        }
    }
    found
}

/// A full bench run with round trips that last for hours, writing into `dir`; returns it
/// and its first contract round's folder once that round's service child has connected.
fn long_bench(dir: &Path) -> (Child, PathBuf) {
    let out = dir.join("out");
    let bench = Command::new(BENCH)
        .args(["--samples", "1000000000", "--rounds", "1"])
        .args(["--skip-cyclictest", "--skip-pcac", "--out"])
        .arg(&out)
        .arg("--results")
        .arg(dir.join("results.md"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(std::fs::File::create(dir.join("bench.log")).expect("bench.log"))
        .spawn()
        .expect("starting latency-bench");
    let round = out.join("contract-rtt").join("round-0");
    let deadline = Instant::now() + Duration::from_secs(120);
    while !std::fs::read_to_string(round.join("child.log"))
        .unwrap_or_default()
        .contains("connected to the plant")
    {
        assert!(
            Instant::now() < deadline,
            "the contract round's service child did not connect; bench log:\n{}",
            std::fs::read_to_string(dir.join("bench.log")).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    (bench, round)
}

/// Waits until none of `procs` runs (30 s at most), then kills any left (by pid) and
/// returns their pids.
fn left_running(procs: &[Watched]) -> Vec<u32> {
    let deadline = Instant::now() + Duration::from_secs(30);
    while procs.iter().any(running) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(50));
    }
    let left: Vec<u32> = procs.iter().filter(|w| running(w)).map(|w| w.pid).collect();
    for pid in &left {
        // SAFETY: kill with the pid of a process this test started, and a valid signal.
        unsafe { libc::kill(*pid as i32, libc::SIGKILL) };
    }
    left
}

#[test]
fn a_killed_bench_leaves_no_service_child_running_on_the_rt_core() {
    let _cores = CORES.lock().unwrap_or_else(|e| e.into_inner());
    let dir = test_dir("killed-bench");
    let (mut bench, round) = long_bench(&dir);
    let children: Vec<Watched> = children_of(bench.id())
        .into_iter()
        .map(Watched::new_or_gone)
        .collect();
    assert_eq!(
        children.len(),
        1,
        "one service child during a contract round"
    );
    bench.kill().expect("SIGKILL to the bench");
    let _ = bench.wait();
    let left = left_running(&children);
    assert!(
        left.is_empty(),
        "the service child {left:?} outlived the bench that started it"
    );
    // It was stopped by SIGTERM (PR_SET_PDEATHSIG): it ended its loop and wrote its report.
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(round.join("report.json")).expect("the child's report.json"),
    )
    .expect("valid JSON");
    assert_eq!(report["stop_reason"], "signal", "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_round_under_the_rig_name_of_a_killed_run_still_connects() {
    let _cores = CORES.lock().unwrap_or_else(|e| e.into_inner());
    let dir = test_dir("stale-rig");
    let (mut bench, round) = long_bench(&dir);
    let config = std::fs::read_to_string(round.join("config.toml")).expect("config.toml");
    let rig = config
        .lines()
        .find_map(|l| l.strip_prefix("name = \""))
        .and_then(|l| l.strip_suffix('"'))
        .expect("the rig name in config.toml")
        .to_string();
    // Both processes killed at once: neither removes its iceoryx2 resources.
    let mut procs = children_of(bench.id());
    procs.push(bench.id());
    let watched: Vec<Watched> = procs.iter().copied().map(Watched::new_or_gone).collect();
    for pid in &procs {
        // SAFETY: kill with the pid of a process this test started, and a valid signal.
        unsafe { libc::kill(*pid as i32, libc::SIGKILL) };
    }
    let _ = bench.wait();
    assert!(left_running(&watched).is_empty());

    // A new round on the same rig name, with the stale resources of the killed one.
    let cli =
        <Cli as clap::Parser>::parse_from(["latency-bench", "--samples", "200", "--rounds", "1"]);
    let mut s = Settings::from(&cli.opts);
    s.child_exe = Some(PathBuf::from(BENCH));
    let (h, _, report) = contract_round(&s, &dir.join("again"), &rig, counts())
        .unwrap_or_else(|e| panic!("a round on the killed run's rig '{rig}' failed: {e}"));
    assert_eq!(h.len(), s.plan.samples);
    assert_eq!(report["stop_reason"], "plant-ended", "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}
