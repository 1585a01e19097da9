//! The command line of `latency-bench` and the settings of a run, defaults resolved.
//!
//! ```text
//! latency-bench [--samples N --seconds S --out DIR --results FILE --quick --skip-cyclictest …]
//! latency-bench pcac [--steps N --workload truss|arm|all --replan-every 2,3,4 --qp-share B --out DIR --results FILE …]
//! latency-bench jack [--periods 16,32,64 --seconds S --ident-seconds S --loads idle,busy --out DIR --results FILE …]
//! ```
//!
//! Two hidden subcommands select the role of the child process of the two-process
//! measurements ([`crate::child`]).

use crate::report;
use crate::roundtrip::RoundTripPlan;
use crate::{PERIOD_NS, RT_PRIORITY, rt_request};
use clap::{Parser, Subcommand};
use ipc_types::rt::RtRequest;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The whole command line.
#[derive(Parser)]
#[command(
    name = "latency-bench",
    about = "Checks the 8 kHz budget: contract round trip vs raw iceoryx2, loop wake-up vs cyclictest, controller step cost"
)]
pub struct Cli {
    /// A subcommand; none runs every phase.
    #[command(subcommand)]
    pub role: Option<Role>,
    /// The options of the full run.
    #[command(flatten)]
    pub opts: Options,
}

/// The options of the full run (no subcommand).
// The doc comments are also the `--help` text, so `<unix-time>` stays as it is.
#[allow(rustdoc::invalid_html_tags)]
#[derive(clap::Args, Debug, Clone)]
pub struct Options {
    /// Round trips recorded per variant, over all rounds (default 50000; 5000 with --quick).
    #[arg(long)]
    pub samples: Option<u64>,
    /// Round trips run before recording per variant, over all rounds (default samples / 10).
    #[arg(long)]
    pub warmup: Option<u64>,
    /// Rounds of the round-trip comparison and of each timing comparison, each with fresh
    /// child processes, in ABBA order (default 5; 2 with --quick).
    #[arg(long)]
    pub rounds: Option<u64>,
    /// Busy-wait between an answer and the next round trip, µs; the same for both variants
    /// (0: back-to-back).
    #[arg(long, default_value_t = 20.0)]
    pub gap_us: f64,
    /// Seconds of 8 kHz pacing per wait mode, of cyclictest, and per timing and controller
    /// in the response-time phase, over its rounds (default 5; 1 with --quick).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Timed steps per controller configuration (default 200000; 20000 with --quick).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Output folder, results file, `--quick`.
    #[command(flatten)]
    pub run: RunArgs,
    /// Do not run cyclictest even if it is installed.
    #[arg(long)]
    pub skip_cyclictest: bool,
    /// Enable the service's CSV signal log in the service runs (off by default).
    #[arg(long)]
    pub service_log: bool,
    /// Core of the plant side (the parent's measuring thread).
    #[arg(long, default_value_t = 0)]
    pub plant_core: usize,
    /// Core of the real-time side (service RT thread, echo, cyclictest, step cost).
    #[arg(long, default_value_t = 1)]
    pub rt_core: usize,
    /// Timed PCAC steps per workload (truss, arm), each also solved by clarabel and OSQP
    /// (default 2000; 300 with --quick). `latency-bench pcac` runs this phase alone.
    #[arg(long)]
    pub pcac_steps: Option<u64>,
    /// Do not run the PCAC phase.
    #[arg(long)]
    pub skip_pcac: bool,
    /// Do not run the response-time phase (compute-first against answer-first).
    #[arg(long)]
    pub skip_timing: bool,
}

/// The options of `latency-bench pcac`.
#[allow(rustdoc::invalid_html_tags)]
#[derive(clap::Args, Debug, Clone)]
pub struct PcacArgs {
    /// Timed steps per workload (default 5000; 300 with --quick).
    #[arg(long)]
    pub steps: Option<u64>,
    /// Untimed steps before timing (default: the workload's, 500).
    #[arg(long)]
    pub warmup: Option<u64>,
    /// Which workload: truss, arm or all.
    #[arg(long, default_value = "all")]
    pub workload: String,
    /// Do not solve the PCAC step's QPs with clarabel.
    #[arg(long)]
    pub no_clarabel: bool,
    /// Do not solve the PCAC step's QPs with OSQP.
    #[arg(long)]
    pub no_osqp: bool,
    /// Core of the timing thread (pinned, SCHED_FIFO).
    #[arg(long, default_value_t = 1)]
    pub rt_core: usize,
    /// Re-planning periods N to time on the truss workload beside a solve at every sample
    /// (comma-separated; 0 for none).
    #[arg(long, value_delimiter = ',', default_values_t = crate::pcac_replan::DEFAULT_PERIODS)]
    pub replan_every: Vec<usize>,
    /// Time each re-planning period N ≥ 4 a second time with the QP cut into shares of
    /// this many active-set changes per period (`qp-changes-per-period`; 0: not).
    #[arg(long, default_value_t = 0)]
    pub qp_share: usize,
    /// Output folder, results file, `--quick`.
    #[command(flatten)]
    pub run: RunArgs,
}

/// The options of every run, full or `latency-bench pcac`: where it writes, and how long it
/// takes.
#[allow(rustdoc::invalid_html_tags)]
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// Output folder (default bench-results/<unix-time>; bench-results/pcac-<unix-time> for
    /// `latency-bench pcac`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Results file; this run replaces its section (default `latency-bench.md` in the
    /// output folder; the repository's is docs/results/latency-bench.md, written only when
    /// named here).
    #[arg(long)]
    pub results: Option<PathBuf>,
    /// A short run for smoke tests.
    #[arg(long)]
    pub quick: bool,
}

impl RunArgs {
    /// The results file of a run whose output folder is `out` ([`report::results_file`]).
    pub fn results_file(&self, out: &Path) -> PathBuf {
        report::results_file(self.results.as_deref(), out)
    }
}

/// `latency-bench jack`: the acoustic rig through a sound card under JACK.
#[derive(clap::Args, Debug, Clone)]
pub struct JackArgs {
    /// JACK periods to run, frames (comma-separated).
    #[arg(long, value_delimiter = ',', default_values_t = [16u32, 32, 64])]
    pub periods: Vec<u32>,
    /// Seconds of each RCAC run (default 10; 3 with --quick).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Seconds of each identification run (default 20; 5 with --quick).
    #[arg(long)]
    pub ident_seconds: Option<f64>,
    /// Loads of the real-time runs (comma-separated: idle, busy).
    #[arg(long, value_delimiter = ',', default_values_t = ["idle".to_string(), "busy".to_string()])]
    pub loads: Vec<String>,
    /// Output folder, results file, `--quick`.
    #[command(flatten)]
    pub run: RunArgs,
}

/// A subcommand: the PCAC phase alone, the JACK loop, or one of the child roles.
#[derive(Subcommand)]
pub enum Role {
    /// Only the PCAC step cost (truss and sampling-arm sizes) beside clarabel and OSQP.
    Pcac(PcacArgs),
    /// The acoustic rig through a sound card under JACK (a dummy server and the simulated
    /// room) against its direct loop: tone suppression, misses, xruns, round trips, the
    /// delay the server adds, for each period.
    Jack(JackArgs),
    /// Child role: the real service.
    #[command(hide = true)]
    ChildService {
        /// The service configuration the parent wrote.
        #[arg(long)]
        config: PathBuf,
        /// `busy-poll` or `block`.
        #[arg(long)]
        wait: String,
        /// The RT core.
        #[arg(long)]
        core: usize,
        /// Where the service writes its run report and histograms.
        #[arg(long)]
        run_folder: PathBuf,
    },
    /// Child role: the raw iceoryx2 echo.
    #[command(hide = true)]
    ChildEcho {
        /// The rig name of the echo's services.
        #[arg(long)]
        rig: String,
        /// The RT core.
        #[arg(long)]
        core: usize,
    },
}

/// The settings of one full run, defaults resolved.
#[derive(Debug, Clone)]
pub struct Settings {
    /// The plan of one round (samples and warm-up per round).
    pub plan: RoundTripPlan,
    /// Rounds of the round-trip comparison.
    pub rounds: u64,
    /// Seconds of 8 kHz pacing per wait mode, of cyclictest, and per timing and controller
    /// in the response-time phase (split over its rounds).
    pub seconds: f64,
    /// Timed steps per controller configuration.
    pub steps: u64,
    /// Untimed steps before them.
    pub step_warmup: u64,
    /// Core of the plant side.
    pub plant_core: usize,
    /// Core of the real-time side.
    pub rt_core: usize,
    /// The service's CSV signal log in the service runs.
    pub service_log: bool,
    /// Run cyclictest when it is installed.
    pub cyclictest: bool,
    /// Timed PCAC steps per workload; `None`: the phase is skipped.
    pub pcac_steps: Option<u64>,
    /// Run the response-time phase (compute-first against answer-first).
    pub timing: bool,
    /// `--results`: the results file this run writes its section into, or `None` for the
    /// output folder's ([`report::results_file`]).
    pub results: Option<PathBuf>,
    /// The executable started as the child process (`None`: this executable, which is
    /// what the bench does; tests name the built `latency-bench` binary).
    pub child_exe: Option<PathBuf>,
}

impl Settings {
    /// Resolves the defaults of `o` (the `--quick` ones when it is set).
    pub fn from(o: &Options) -> Self {
        let samples = o
            .samples
            .unwrap_or(if o.run.quick { 5_000 } else { 50_000 })
            .max(1);
        let warmup = o.warmup.unwrap_or(samples / 10);
        let rounds = o
            .rounds
            .unwrap_or(if o.run.quick { 2 } else { 5 })
            .clamp(1, samples);
        let steps = o
            .steps
            .unwrap_or(if o.run.quick { 20_000 } else { 200_000 })
            .max(1);
        Self {
            rounds,
            plan: RoundTripPlan {
                warmup: warmup.div_ceil(rounds),
                samples: samples.div_ceil(rounds),
                gap_ns: (o.gap_us.max(0.0) * 1_000.0) as u64,
                answer_timeout: Duration::from_secs(2),
                connect_timeout: Duration::from_secs(20),
            },
            seconds: o
                .seconds
                .unwrap_or(if o.run.quick { 1.0 } else { 5.0 })
                .max(0.01),
            steps,
            step_warmup: (steps / 20).max(100),
            plant_core: o.plant_core,
            rt_core: o.rt_core,
            service_log: o.service_log,
            cyclictest: !o.skip_cyclictest,
            pcac_steps: (!o.skip_pcac).then(|| {
                o.pcac_steps
                    .unwrap_or(if o.run.quick { 300 } else { 2_000 })
                    .max(1)
            }),
            timing: !o.skip_timing,
            results: o.run.results.clone(),
            child_exe: None,
        }
    }

    /// The real-time set-up of the plant-side (parent) measuring thread.
    pub fn plant_rt(&self) -> RtRequest {
        rt_request(self.plant_core)
    }

    /// Longest a round-trip measurement may take before the bench gives up on it: the
    /// connection time, plus four times a generous estimate of the run.
    pub fn rtt_limit(&self) -> Duration {
        let n = self.plan.warmup + self.plan.samples;
        let per_sample_ns = self.plan.gap_ns + 50_000;
        Duration::from_secs(30) + Duration::from_nanos(4 * n * per_sample_ns)
    }

    /// The settings block of `summary.json`.
    pub fn json(&self) -> Value {
        json!({
            "round_trip_rounds": self.rounds,
            "round_trip_samples_per_round": self.plan.samples,
            "round_trip_warmup_per_round": self.plan.warmup,
            "round_trip_spacing": if self.plan.gap_ns == 0 {
                "back-to-back".to_string()
            } else {
                format!("busy-wait of {} ns after each answer", self.plan.gap_ns)
            },
            "paced_seconds_per_mode": self.seconds,
            "period_ns": PERIOD_NS,
            "paced_deadline_ns": PERIOD_NS / 2,
            "step_cost_steps": self.steps,
            "step_cost_warmup": self.step_warmup,
            "plant_core": self.plant_core,
            "rt_core": self.rt_core,
            "fifo_priority": RT_PRIORITY,
            "service_log": self.service_log,
            "pcac_steps": self.pcac_steps,
            "timing_phase": self.timing,
            "timing_rounds_per_timing": self.rounds,
            "timing_seconds_per_round": self.seconds / self.rounds.max(1) as f64,
        })
    }
}
