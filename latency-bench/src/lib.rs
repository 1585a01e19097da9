//! # latency-bench: does the service fit the 8 kHz budget on this machine?
//!
//! One run of `cargo run --release -p latency-bench` answers these questions, each against
//! a reference measured in the same run on the same machine, so that a noisy machine
//! moves both numbers of a comparison together:
//!
//! 1. **What does the contract cost over raw iceoryx2?** ([`roundtrip`]) Two processes —
//!    the bench re-executes its own binary for the second one — exchange `N` samples in
//!    lockstep. The parent is pinned on the plant core and busy-polls; the child is pinned
//!    on the RT core and busy-polls. With the *contract* the parent plays the plant through
//!    `ipc_types::ports::connect` and the child is the real service
//!    (`service::runtime::run`, controller and telemetry included); with *raw* the child
//!    is a minimal iceoryx2 echo with payloads of the same sizes and the same QoS. The
//!    round trip is timed by the parent alone (`CLOCK_MONOTONIC` before the send, after the
//!    receipt of the answer with the same sequence number), so both variants are timed by
//!    the same code. The two variants alternate in rounds of fresh processes in ABBA order
//!    (contract, raw, raw, contract, …) and each variant's rounds are merged, so that a
//!    change of the machine's load during the run weighs on both alike. The ratio
//!    contract/raw at p50 and p99 is the figure of merit; the target is ≤ 1.5.
//! 2. **How late does the loop wake up at 8 kHz?** ([`paced`]) The parent paces
//!    measurements on `CLOCK_MONOTONIC` absolute sleeps at 8 kHz with a deadline of half a
//!    period, like plant-proxy in real-time mode; the child runs the real service in
//!    busy-poll and then in blocking mode, and its run report gives the wake-up latency
//!    (sample timestamp → receipt by the RT thread). The parent also records its own
//!    pacing lateness (the floor under every wake-up figure) and the plant-publish →
//!    actuation-publish time. [`cyclictest`] measures the machine's own timer wake-up floor
//!    on the RT core at the same interval, when it is installed.
//! 3. **What does one controller step cost?** ([`step_cost`]) Each named controller
//!    configuration ([`configs::step_cases`]) is built through the service's configuration
//!    path and stepped many times on the pinned RT core under `SCHED_FIFO`, timing each
//!    step; the cost is also given as a share of the 125 µs period.
//! 4. **How much of the response time does answer-first take out?** ([`timing_phase`])
//!    In the same paced set-up, the service runs each controller of
//!    [`configs::timing_cases`] with `timing = "compute-first"` and with
//!    `timing = "answer-first"`, in ABBA rounds of fresh processes, the plant closing the
//!    controller's loop; the rows are the service's own response time (sample time →
//!    publication of the answer) and compute time, with answer-first ÷ compute-first.
//! 5. **What does a PCAC step cost, and how does it compare with clarabel and OSQP?**
//!    ([`pcac_cost`]) `Pcac::step` at the truss size and at the sampling-arm size, each in a
//!    closed loop, with clarabel and OSQP ([`osqp_anchor`]) timed on the same QPs and the
//!    step taken apart into its kernels; and the cost per period of re-planning every `N`
//!    samples, which spreads a solve over `N` periods ([`pcac_replan`]). `latency-bench
//!    pcac` runs this phase alone.
//! 6. **How does the acoustic rig do through a sound card under JACK?** ([`jack_phase`])
//!    `latency-bench jack` runs the design path and RCAC through a JACK server with the
//!    dummy backend and the simulated room for each period, in lockstep and in real time
//!    (idle and loaded), beside the direct loop: tone suppression, misses, xruns per
//!    minute, round trips and the delay the server adds.
//!
//! Every distribution is an HdrHistogram ([`hist`]), written as a percentile distribution
//! (`.hgrm`, µs) and as an interval log (`.hlog`, V2 + deflate, ns) into the output folder,
//! next to a `summary.json` and the printed [`table`]. [`machine`] records what the OS
//! granted (pinning, `SCHED_FIFO`, `mlockall`) and the kernel, since the figures mean
//! little without them. [`report`] also writes the printed table, with the machine, the
//! date and the command line, into the results file (in the output folder by default;
//! `--results docs/results/latency-bench.md` writes the one the docs link to). [`cli`] holds the command line and the
//! settings it resolves to.

#![warn(missing_docs)]

pub mod catch_up;
pub mod child;
pub mod cli;
pub mod configs;
pub mod cyclictest;
pub mod hist;
pub mod jack_phase;
pub mod machine;
pub mod osqp_anchor;
pub mod paced;
pub mod pcac_cost;
pub mod pcac_phase;
pub mod pcac_replan;
pub mod report;
pub mod rls_cost;
pub mod roundtrip;
pub mod step_cost;
pub mod synthetic_arm;
pub mod table;
pub mod timing_phase;

use ipc_types::rt::{RtRequest, RtSetup};
use report::Measured;
use std::path::Path;
use std::time::{Duration, Instant, SystemTime};

/// Sampling period of the budget the bench checks: 8 kHz.
pub const PERIOD_NS: u64 = 125_000;

/// `SCHED_FIFO` priority of every real-time thread of the bench (both processes), the
/// service's default and the one given to cyclictest.
pub const RT_PRIORITY: i32 = 80;

/// The real-time set-up every measuring thread of the bench asks for: pinned on `core`,
/// `SCHED_FIFO` at [`RT_PRIORITY`], `mlockall`, a prefaulted stack of 256 KiB, and the
/// CPUs' wake-up latency held at 0 µs as the service holds it by default.
pub fn rt_request(core: usize) -> RtRequest {
    RtRequest {
        core: Some(core),
        fifo_priority: Some(RT_PRIORITY),
        mlockall: true,
        prefault_stack_bytes: 256 * 1024,
        cpu_latency_us: Some(0),
    }
}

/// Runs `work` on a thread pinned to `rt_core` at `SCHED_FIFO` ([`rt_request`]): the
/// helper thread of the phases that time kernels. Returns the RT set-up outcome and
/// `work`'s result.
pub fn on_rt_core<T: Send + 'static>(
    rt_core: usize,
    name: &str,
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<(RtSetup, T), String> {
    let rt = rt_request(rt_core);
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let setup = ipc_types::rt::setup_current_thread(&rt);
            (setup, work())
        })
        .map_err(|e| format!("starting the {name} thread: {e}"))?
        .join()
        .map_err(|_| format!("the {name} thread failed"))
}

/// What [`timed_on_rt_core`] ran: the RT set-up outcome, the work's result, and the
/// wall-clock start and the duration of the run (for the interval logs).
pub struct TimedRun<T> {
    /// What the OS granted the thread.
    pub setup: RtSetup,
    /// The work's result.
    pub value: T,
    /// Wall-clock start of the run.
    pub start: SystemTime,
    /// How long the run took.
    pub elapsed: Duration,
}

/// The frame of a phase that times kernels: creates the phase's folder `dir`, then runs
/// `work` [`on_rt_core`] as the thread `name`, timing the run. When the folder or the
/// thread cannot be made, the failed row `id`, `label` of the phase instead.
pub fn timed_on_rt_core<T: Send + 'static>(
    rt_core: usize,
    dir: &Path,
    name: &str,
    (id, label): (&str, &str),
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<TimedRun<T>, Box<Measured>> {
    let failed = |why: String| Box::new(Measured::failed(id, label, why));
    std::fs::create_dir_all(dir).map_err(|e| failed(format!("creating {}: {e}", dir.display())))?;
    let start = SystemTime::now();
    let t = Instant::now();
    let (setup, value) = on_rt_core(rt_core, name, work).map_err(failed)?;
    Ok(TimedRun {
        setup,
        value,
        start,
        elapsed: t.elapsed(),
    })
}

/// The base of the rig names of one bench run, `bench-<pid>-<start in ms since the Unix
/// epoch>`; each two-process round appends its own suffix (`-rtt0`, `-raw1`, `-block`).
///
/// The pid alone is not enough: pids repeat across runs (they wrap at `pid_max`, and a
/// container or a machine booted from the same image hands out the same pids in the same
/// order), and a rig name under which an earlier bench that was killed left iceoryx2
/// resources may be unusable: a service whose static configuration (under `/tmp`)
/// outlived its dynamic one (in `/dev/shm`, gone with a reboot) is refused with
/// `HangsInCreation` by every later open, and no dead node refers to it any more for
/// `ipc_types::ports::cleanup_dead_nodes` to remove it.
pub fn rig_base() -> String {
    let ms = SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map(|d| d.as_millis())
        .unwrap_or(0);
    format!("bench-{}-{ms}", std::process::id())
}

/// A progress line on standard error (the table goes to standard output).
pub fn progress(msg: &str) {
    eprintln!("[latency-bench] {msg}");
}

#[cfg(test)]
mod tests {
    #[test]
    fn rig_bases_differ_between_runs_of_the_same_pid_and_make_valid_rig_names() {
        let a = super::rig_base();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = super::rig_base();
        assert_ne!(a, b, "two runs of one pid get different rig names");
        assert!(
            a.starts_with(&format!("bench-{}-", std::process::id())),
            "{a}"
        );
        for suffix in ["-rtt10", "-raw10", "-busy-poll"] {
            ipc_types::ports::service_names(&format!("{a}{suffix}")).expect("a valid rig name");
        }
    }
}
