//! `latency-bench`: checks the 8 kHz budget on this machine in one run.
//!
//! ```text
//! cargo run --release -p latency-bench [-- --samples N --seconds S --out DIR --quick --skip-cyclictest]
//! cargo run --release -p latency-bench -- pcac [--steps N --workload truss|arm|all --out DIR]
//! ```
//!
//! Runs, in order: the contract round trip against the real service, the raw iceoryx2
//! ping-pong, the service's wake-up latency at 8 kHz in busy-poll and blocking mode,
//! cyclictest on the RT core (when installed), the step cost of each known controller
//! configuration, the RLS update cost and the PCAC step cost beside clarabel (the `pcac`
//! subcommand runs the last alone). Prints the machine facts and one table, and writes every distribution
//! (`.hgrm`, `.hlog`), the service's run reports and a `summary.json` to the output folder
//! (default `bench-results/<unix-time>/`). See the library docs for the method of each
//! measurement.

use clap::{Parser, Subcommand};
use hdrhistogram::Histogram;
use ipc_types::ChannelCounts;
use ipc_types::rt::{RtRequest, RtSetup};
use latency_bench::child::{self, ChildProc};
use latency_bench::configs::{self, Channels};
use latency_bench::cyclictest::{self, CyclictestRun};
use latency_bench::hist::{self, Summary, ratio};
use latency_bench::machine;
use latency_bench::paced::{self, PacedResult};
use latency_bench::pcac_cost::{self, PcacCost, Workload};
use latency_bench::roundtrip::{self, RoundTripPlan};
use latency_bench::step_cost;
use latency_bench::table::{self, Row, fmt_ratio};
use latency_bench::{PERIOD_NS, RT_PRIORITY};
use serde_json::{Value, json};
use service::config::WaitMode;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The issue's target for contract / raw at p50 and p99.
const TARGET_RATIO: f64 = 1.5;

#[derive(Parser)]
#[command(
    name = "latency-bench",
    about = "Checks the 8 kHz budget: contract round trip vs raw iceoryx2, loop wake-up vs cyclictest, controller step cost"
)]
struct Cli {
    #[command(subcommand)]
    role: Option<Role>,
    #[command(flatten)]
    opts: Options,
}

#[derive(clap::Args, Debug, Clone)]
struct Options {
    /// Round trips recorded per variant, over all rounds (default 50000; 5000 with --quick).
    #[arg(long)]
    samples: Option<u64>,
    /// Round trips run before recording per variant, over all rounds (default samples / 10).
    #[arg(long)]
    warmup: Option<u64>,
    /// Rounds of the round-trip comparison, each with fresh child processes, in ABBA order
    /// (default 5; 2 with --quick).
    #[arg(long)]
    rounds: Option<u64>,
    /// Busy-wait between an answer and the next round trip, µs; the same for both variants
    /// (0: back-to-back).
    #[arg(long, default_value_t = 20.0)]
    gap_us: f64,
    /// Seconds of 8 kHz pacing per wait mode, and of cyclictest (default 5; 1 with --quick).
    #[arg(long)]
    seconds: Option<f64>,
    /// Timed steps per controller configuration (default 200000; 20000 with --quick).
    #[arg(long)]
    steps: Option<u64>,
    /// Output folder (default bench-results/<unix-time>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Do not run cyclictest even if it is installed.
    #[arg(long)]
    skip_cyclictest: bool,
    /// A short run for smoke tests.
    #[arg(long)]
    quick: bool,
    /// Enable the service's CSV signal log in the service runs (off by default).
    #[arg(long)]
    service_log: bool,
    /// Core of the plant side (the parent's measuring thread).
    #[arg(long, default_value_t = 0)]
    plant_core: usize,
    /// Core of the real-time side (service RT thread, echo, cyclictest, step cost).
    #[arg(long, default_value_t = 1)]
    rt_core: usize,
    /// Timed PCAC steps per workload (truss, arm), each also solved by clarabel
    /// (default 2000; 300 with --quick). `latency-bench pcac` runs this phase alone.
    #[arg(long)]
    pcac_steps: Option<u64>,
    /// Do not run the PCAC phase.
    #[arg(long)]
    skip_pcac: bool,
}

/// The options of `latency-bench pcac`.
#[derive(clap::Args, Debug, Clone)]
struct PcacArgs {
    /// Timed steps per workload (default 5000; 300 with --quick).
    #[arg(long)]
    steps: Option<u64>,
    /// Untimed steps before timing (default: the workload's, 500).
    #[arg(long)]
    warmup: Option<u64>,
    /// Which workload: truss, arm or all.
    #[arg(long, default_value = "all")]
    workload: String,
    /// Time the PCAC step only, without solving its QPs with clarabel.
    #[arg(long)]
    no_clarabel: bool,
    /// Output folder (default bench-results/pcac-<unix-time>).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Core of the timing thread (pinned, SCHED_FIFO).
    #[arg(long, default_value_t = 1)]
    rt_core: usize,
    /// A short run for smoke tests.
    #[arg(long)]
    quick: bool,
}

#[derive(Subcommand)]
enum Role {
    /// Only the PCAC step cost (truss and sampling-arm sizes) beside clarabel.
    Pcac(PcacArgs),
    /// Child role: the real service.
    #[command(hide = true)]
    ChildService {
        #[arg(long)]
        config: PathBuf,
        #[arg(long)]
        wait: String,
        #[arg(long)]
        core: usize,
        #[arg(long)]
        run_folder: PathBuf,
    },
    /// Child role: the raw iceoryx2 echo.
    #[command(hide = true)]
    ChildEcho {
        #[arg(long)]
        rig: String,
        #[arg(long)]
        core: usize,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let code = match cli.role {
        Some(Role::ChildService {
            config,
            wait,
            core,
            run_folder,
        }) => {
            let wait = match wait.as_str() {
                "busy-poll" => WaitMode::BusyPoll,
                "block" => WaitMode::Block,
                other => {
                    eprintln!("unknown wait mode {other}");
                    return ExitCode::from(2);
                }
            };
            child::run_service_child(&config, wait, core, &run_folder)
        }
        Some(Role::ChildEcho { rig, core }) => roundtrip::run_echo_child(&rig, core),
        Some(Role::Pcac(a)) => pcac_only(&a),
        None => bench(&cli.opts),
    };
    ExitCode::from(code.clamp(0, 255) as u8)
}

/// The settings of one run, defaults resolved.
#[derive(Debug, Clone)]
struct Settings {
    /// The plan of one round (samples and warm-up per round).
    plan: RoundTripPlan,
    rounds: u64,
    seconds: f64,
    steps: u64,
    step_warmup: u64,
    plant_core: usize,
    rt_core: usize,
    service_log: bool,
    cyclictest: bool,
    /// Timed PCAC steps per workload; `None`: the phase is skipped.
    pcac_steps: Option<u64>,
}

impl Settings {
    fn from(o: &Options) -> Self {
        let samples = o
            .samples
            .unwrap_or(if o.quick { 5_000 } else { 50_000 })
            .max(1);
        let warmup = o.warmup.unwrap_or(samples / 10);
        let rounds = o
            .rounds
            .unwrap_or(if o.quick { 2 } else { 5 })
            .clamp(1, samples);
        let steps = o
            .steps
            .unwrap_or(if o.quick { 20_000 } else { 200_000 })
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
                .unwrap_or(if o.quick { 1.0 } else { 5.0 })
                .max(0.01),
            steps,
            step_warmup: (steps / 20).max(100),
            plant_core: o.plant_core,
            rt_core: o.rt_core,
            service_log: o.service_log,
            cyclictest: !o.skip_cyclictest,
            pcac_steps: (!o.skip_pcac).then(|| {
                o.pcac_steps
                    .unwrap_or(if o.quick { 300 } else { 2_000 })
                    .max(1)
            }),
        }
    }

    fn plant_rt(&self) -> RtRequest {
        RtRequest {
            core: Some(self.plant_core),
            fifo_priority: Some(RT_PRIORITY),
            mlockall: true,
            prefault_stack_bytes: 256 * 1024,
        }
    }

    /// Longest a round-trip measurement may take before the bench gives up on it: the
    /// connection time, plus four times a generous estimate of the run.
    fn rtt_limit(&self) -> Duration {
        let n = self.plan.warmup + self.plan.samples;
        let per_sample_ns = self.plan.gap_ns + 50_000;
        Duration::from_secs(30) + Duration::from_nanos(4 * n * per_sample_ns)
    }

    fn json(&self) -> Value {
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
        })
    }
}

/// One measurement's outcome, for the table and `summary.json`.
struct Measured {
    id: String,
    label: String,
    count: Option<u64>,
    us: [Option<f64>; 4],
    summary: Option<Summary>,
    note: String,
    files: Vec<PathBuf>,
    error: Option<String>,
}

impl Measured {
    fn from_summary(id: &str, label: &str, s: Summary, files: Vec<PathBuf>) -> Self {
        Self {
            id: id.into(),
            label: label.into(),
            count: Some(s.count),
            us: s.columns_us(),
            summary: Some(s),
            note: String::new(),
            files,
            error: None,
        }
    }

    fn empty(id: &str, label: &str, note: &str) -> Self {
        Self {
            id: id.into(),
            label: label.into(),
            count: None,
            us: [None; 4],
            summary: None,
            note: note.into(),
            files: Vec::new(),
            error: None,
        }
    }

    fn failed(id: &str, label: &str, why: String) -> Self {
        Self {
            id: id.into(),
            label: label.into(),
            count: None,
            us: [None; 4],
            summary: None,
            note: String::new(),
            files: Vec::new(),
            error: Some(why),
        }
    }

    fn row(&self) -> Row {
        let note = match &self.error {
            Some(e) => format!("FAILED: {}", e.lines().next().unwrap_or("")),
            None => self.note.clone(),
        };
        Row::new(self.label.clone(), self.count, self.us, note)
    }

    fn json(&self) -> Value {
        json!({
            "id": self.id,
            "label": self.label,
            "summary": self.summary,
            "p50_us": self.us[0], "p99_us": self.us[1], "p99_9_us": self.us[2], "max_us": self.us[3],
            "note": self.note,
            "files": self.files,
            "error": self.error,
        })
    }
}

fn unix_now() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

fn progress(msg: &str) {
    eprintln!("[latency-bench] {msg}");
}

fn bench(o: &Options) -> i32 {
    let s = Settings::from(o);
    let started = unix_now();
    let out = o
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("bench-results").join(started.to_string()));
    if let Err(e) = std::fs::create_dir_all(&out) {
        eprintln!("cannot create {}: {e}", out.display());
        return 2;
    }
    // The plant thread's RT set-up, probed once for the machine facts (mlockall holds for
    // the whole process from here on).
    let probe = std::thread::spawn({
        let rt = s.plant_rt();
        move || ipc_types::rt::setup_current_thread(&rt)
    })
    .join()
    .expect("probe thread");
    let facts = machine::collect(&probe);
    println!("{}", facts.render());
    if probe.any_refused() {
        println!(
            "WARNING: the OS refused part of the real-time set-up; latency figures are not those of an RT setup\n"
        );
    }
    progress(&format!("writing to {}", out.display()));

    let pid = std::process::id();
    let counts = ChannelCounts::new(1, 1, 0, 1).expect("within capacity");
    let mut measured: Vec<Measured> = Vec::new();
    let mut reports = serde_json::Map::new();
    let mut extra = serde_json::Map::new();
    let mut details: Vec<String> = Vec::new();

    // 1. Contract round trip and raw ping-pong, interleaved.
    let contract_ratio = round_trip_phase(
        &s,
        &out,
        pid,
        counts,
        &mut measured,
        &mut reports,
        &mut details,
    );

    // 2. Wake-up latency at 8 kHz.
    let mut plant_rows: Vec<Measured> = Vec::new();
    for (i, (mode, wait)) in [("busy-poll", "busy-poll"), ("block", "block")]
        .into_iter()
        .enumerate()
    {
        progress(&format!(
            "{}/6 service wake-up at 8 kHz, {mode}, {:.1} s",
            3 + i,
            s.seconds
        ));
        let dir = out.join(format!("wakeup-{mode}"));
        let rig = format!("bench-{pid}-{mode}");
        let label = format!("service wake-up 8 kHz {mode}");
        match paced_phase(&s, &dir, &rig, wait, counts) {
            Ok((p, setup, report)) => {
                let wk = report
                    .pointer("/latency/wakeup")
                    .ok_or("report.json has no latency.wakeup".to_string())
                    .and_then(Summary::from_service_json);
                match wk {
                    Ok(sum) => {
                        let mut m = Measured::from_summary(
                            &format!("wakeup-{mode}"),
                            &label,
                            sum,
                            vec![dir.join("wakeup.hgrm"), dir.join("wakeup.hlog")],
                        );
                        m.files.retain(|f| f.exists());
                        // Samples the service never saw are in no histogram of its own.
                        if let Some(n) = report.pointer("/stats/skipped").and_then(Value::as_u64) {
                            m.note = format!("{n} samples skipped by the service");
                        }
                        measured.push(m);
                    }
                    Err(e) => {
                        measured.push(Measured::failed(&format!("wakeup-{mode}"), &label, e));
                    }
                }
                let files = hist::write_files(&dir, "plant-pacing", &p.pacing, p.start, p.duration)
                    .unwrap_or_default();
                plant_rows.push(Measured::from_summary(
                    &format!("pacing-{mode}"),
                    &format!("  plant pacing lateness ({mode} run)"),
                    Summary::of(&p.pacing),
                    files,
                ));
                let files = hist::write_files(
                    &dir,
                    "plant-publish-to-answer",
                    &p.publish_to_answer,
                    p.start,
                    p.duration,
                )
                .unwrap_or_default();
                let mut m = Measured::from_summary(
                    &format!("publish-to-answer-{mode}"),
                    &format!("  plant publish → u_k published ({mode})"),
                    Summary::of(&p.publish_to_answer),
                    files,
                );
                m.note = format!("{} of {} answers in time", p.in_time, p.samples);
                plant_rows.push(m);
                let misses = report
                    .pointer("/stats/deadline_misses")
                    .and_then(Value::as_u64);
                details.push(format!(
                    "8 kHz {mode}: {} samples, deadline {:.1} µs: {} answered in time, {} late, {} missing (plant view); service counted {} misses; service RT set-up: {}; plant thread: {}",
                    p.samples,
                    PERIOD_NS as f64 / 2_000.0,
                    p.in_time,
                    p.late,
                    p.missing(),
                    misses.map(|m| m.to_string()).unwrap_or_else(|| "?".into()),
                    service_rt_line(&report),
                    setup.describe()
                ));
                extra.insert(
                    format!("paced-{mode}"),
                    json!({
                        "samples": p.samples, "in_time": p.in_time, "late": p.late, "missing": p.missing(),
                        "pacing_lateness": Summary::of(&p.pacing),
                        "publish_to_answer": Summary::of(&p.publish_to_answer),
                        "plant_rt_setup": setup.describe(),
                    }),
                );
                reports.insert(format!("wakeup-{mode}"), report);
            }
            Err(e) => {
                measured.push(Measured::failed(&format!("wakeup-{mode}"), &label, e));
            }
        }
    }

    // Cyclictest on the RT core.
    progress("5/6 cyclictest");
    let ct_label = format!("cyclictest (core {}, {} µs)", s.rt_core, PERIOD_NS / 1_000);
    let ct = cyclictest_phase(&s, &out.join("cyclictest"));
    let ct_measured = match &ct {
        Ok(Some((run, files))) => {
            let h = &run.histogram;
            let us = [
                h.percentile_us(0.5),
                h.percentile_us(0.99),
                h.percentile_us(0.999),
                h.max(),
            ];
            extra.insert(
                "cyclictest".into(),
                json!({
                    "command": run.command, "total": h.total(), "overflows": h.overflows,
                    "min_us": h.min_us, "avg_us": h.avg_us, "max_us": h.max_us,
                    "p50_us": us[0], "p99_us": us[1], "p99_9_us": us[2],
                    "percentiles": "from its 1 µs histogram, at bucket middles",
                }),
            );
            Measured {
                id: "cyclictest".into(),
                label: ct_label,
                count: Some(h.total()),
                us,
                summary: None,
                note: "machine floor; percentiles ±0.5 µs (1 µs buckets)".into(),
                files: files.clone(),
                error: None,
            }
        }
        Ok(None) => {
            let why = if s.cyclictest {
                "cyclictest not installed"
            } else {
                "skipped (--skip-cyclictest)"
            };
            extra.insert("cyclictest".into(), json!(why));
            Measured::empty("cyclictest", &ct_label, why)
        }
        Err(e) => Measured::failed("cyclictest", &ct_label, e.clone()),
    };
    // Ratios of the service wake-up to the machine floor.
    let mut wake_ratios = serde_json::Map::new();
    if ct_measured.error.is_none() && ct_measured.count.is_some() {
        for m in measured.iter_mut().filter(|m| m.id.starts_with("wakeup-")) {
            if let Some(sum) = m.summary {
                let r = |v: u64, c: Option<f64>| c.filter(|c| *c > 0.0).map(|c| v as f64 / 1e3 / c);
                let (p50, p99, max) = (
                    r(sum.p50_ns, ct_measured.us[0]),
                    r(sum.p99_ns, ct_measured.us[1]),
                    r(sum.max_ns, ct_measured.us[3]),
                );
                let skipped = std::mem::take(&mut m.note);
                m.note = format!(
                    "÷ cyclictest: p50 {}, p99 {}, max {}",
                    fmt_ratio(p50),
                    fmt_ratio(p99),
                    fmt_ratio(max)
                );
                if !skipped.is_empty() {
                    m.note = format!("{}; {skipped}", m.note);
                }
                wake_ratios.insert(
                    m.id.trim_start_matches("wakeup-").to_string(),
                    json!({ "p50": p50, "p99": p99, "max": max }),
                );
            }
        }
    }
    measured.extend(plant_rows);
    measured.push(ct_measured);

    // 3. Controller step cost.
    progress("6/6 controller step cost");
    let step_rows = step_phase(&s, &out.join("step-cost"));
    measured.extend(step_rows);
    progress("RLS update cost (fast kernel against the textbook one)");
    measured.extend(rls_phase(&s, &out.join("rls")));
    if let Some(steps) = s.pcac_steps {
        progress(&format!(
            "PCAC step cost beside clarabel, {steps} steps per workload"
        ));
        let (rows, lines, v) = pcac_phase(
            s.rt_core,
            &out.join("pcac"),
            &Workload::ALL,
            None,
            steps,
            true,
        );
        measured.extend(rows);
        details.extend(lines);
        extra.insert("pcac".into(), v);
    }

    // Output.
    let rows: Vec<Row> = measured.iter().map(Measured::row).collect();
    let table = table::render(&rows);
    println!("{table}");
    for d in &details {
        println!("{d}");
    }
    let load_end = machine::load_average();
    println!("load average at the end: {load_end}");
    println!("results: {}", out.display());
    let table_text = format!("{}\n{table}\n{}\n", facts.render(), details.join("\n"));
    let summary = json!({
        "bench": "latency-bench",
        "started_unix": started,
        "command": std::env::args().collect::<Vec<_>>(),
        "machine": facts,
        "settings": s.json(),
        "measurements": measured.iter().map(Measured::json).collect::<Vec<_>>(),
        "ratios": {
            "contract_over_raw": contract_ratio,
            "wakeup_over_cyclictest": Value::Object(wake_ratios),
        },
        "details": details,
        "load_average_at_end": load_end,
        "extra": Value::Object(extra),
        "service_reports": Value::Object(reports),
    });
    write_results(&out, &table_text, &summary, &measured)
}

/// Writes a service configuration for `rig` into `dir` and starts the service child on it.
fn spawn_service(s: &Settings, dir: &Path, rig: &str, wait: &str) -> Result<ChildProc, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let text = configs::service_toml(
        rig,
        Channels { y: 1, z: 1, u: 1 },
        &configs::loop_controller(),
        s.service_log,
    );
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
    ChildProc::spawn(&args, &dir.join("child.log"), &format!("service ({wait})"))
}

fn read_report(dir: &Path) -> Result<Value, String> {
    let path = dir.join("report.json");
    let text =
        std::fs::read_to_string(&path).map_err(|e| format!("reading {}: {e}", path.display()))?;
    let mut report: Value =
        serde_json::from_str(&text).map_err(|e| format!("parsing {}: {e}", path.display()))?;
    if let (Ok(note), Some(obj)) = (
        std::fs::read_to_string(dir.join(child::REPIN_NOTE)),
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
fn service_rt_line(report: &Value) -> String {
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

/// One round of one round-trip variant: its histogram, the plant thread's RT set-up and
/// the service's run report (`Null` for the raw variant).
type RoundOutcome = Result<(Histogram<u64>, RtSetup, Value), String>;

fn contract_round(s: &Settings, dir: &Path, rig: &str, counts: ChannelCounts) -> RoundOutcome {
    let mut child = spawn_service(s, dir, rig, "busy-poll")?;
    let plan = s.plan;
    let (h, setup) = child::drive(&mut child, s.plant_rt(), s.rtt_limit(), |abort| {
        roundtrip::contract_round_trips(rig, counts, &plan, abort)
    })?;
    child.wait(Duration::from_secs(30))?;
    let report = read_report(dir)?;
    Ok((h, setup, report))
}

fn raw_round(s: &Settings, dir: &Path, rig: &str) -> RoundOutcome {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let args = vec![
        "child-echo".to_string(),
        "--rig".into(),
        rig.into(),
        "--core".into(),
        s.rt_core.to_string(),
    ];
    let mut child = ChildProc::spawn(&args, &dir.join("child.log"), "raw echo")?;
    let plan = s.plan;
    let (h, setup) = child::drive(&mut child, s.plant_rt(), s.rtt_limit(), |abort| {
        roundtrip::raw_round_trips(rig, &plan, abort)
    })?;
    child.wait(Duration::from_secs(30))?;
    Ok((h, setup, Value::Null))
}

/// Min and max of some values, as "a–b" with two decimals (or one value when equal).
fn range(values: &[f64], unit: &str) -> String {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return "-".into();
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if (hi - lo).abs() < 0.005 {
        format!("{lo:.2}{unit}")
    } else {
        format!("{lo:.2}–{hi:.2}{unit}")
    }
}

/// The contract and raw round trips, in `s.rounds` rounds of fresh child processes in ABBA
/// order (contract, raw, raw, contract, …), so that slow changes of the machine's load
/// weigh on both variants alike. Each round records `s.plan.samples` round trips after
/// `s.plan.warmup`; the rows are the merged histograms. Returns the ratio block of
/// `summary.json`.
fn round_trip_phase(
    s: &Settings,
    out: &Path,
    pid: u32,
    counts: ChannelCounts,
    measured: &mut Vec<Measured>,
    reports: &mut serde_json::Map<String, Value>,
    details: &mut Vec<String>,
) -> Value {
    const IDS: [&str; 2] = ["contract-rtt", "raw-rtt"];
    const LABELS: [&str; 2] = ["contract round trip (service)", "raw iceoryx2 ping-pong"];
    let mut merged = [hist::new_histogram(), hist::new_histogram()];
    let mut per_round: [Vec<Summary>; 2] = [Vec::new(), Vec::new()];
    let mut errors: [Option<String>; 2] = [None, None];
    let mut setups: Vec<String> = Vec::new();
    let mut service_side: Vec<[f64; 3]> = Vec::new();
    let start = SystemTime::now();
    let t = Instant::now();
    for r in 0..s.rounds {
        let order = if r % 2 == 0 { [0, 1] } else { [1, 0] };
        for v in order {
            if errors[v].is_some() {
                continue;
            }
            progress(&format!(
                "{}/6 {}, round {}/{}: {} round trips after {} warm-up",
                v + 1,
                LABELS[v],
                r + 1,
                s.rounds,
                s.plan.samples,
                s.plan.warmup
            ));
            let dir = out.join(IDS[v]).join(format!("round-{r}"));
            let outcome = if v == 0 {
                contract_round(s, &dir, &format!("bench-{pid}-rtt{r}"), counts)
            } else {
                raw_round(s, &dir, &format!("bench-{pid}-raw{r}"))
            };
            match outcome {
                Ok((h, setup, report)) => {
                    let _ = merged[v].add(&h);
                    per_round[v].push(Summary::of(&h));
                    setups.push(setup.describe());
                    if !report.is_null() {
                        let p50 = |k: &str| {
                            report
                                .pointer(&format!("/latency/{k}/p50"))
                                .and_then(Value::as_u64)
                                .map(|ns| ns as f64 / 1e3)
                        };
                        if let (Some(w), Some(rsp), Some(c)) =
                            (p50("wakeup"), p50("response"), p50("compute"))
                        {
                            service_side.push([w, rsp, c]);
                        }
                        if r == 0 {
                            details.push(format!(
                                "contract rounds: service RT set-up: {}",
                                service_rt_line(&report)
                            ));
                        }
                        reports.insert(format!("{}-round-{r}", IDS[v]), report);
                    }
                }
                Err(e) => errors[v] = Some(format!("round {}: {e}", r + 1)),
            }
        }
    }
    let elapsed = t.elapsed();
    let mut rows = Vec::new();
    for v in 0..2 {
        let dir = out.join(IDS[v]);
        match &errors[v] {
            Some(e) => rows.push(Measured::failed(IDS[v], LABELS[v], e.clone())),
            None => {
                let files =
                    hist::write_files(&dir, "rtt", &merged[v], start, elapsed).unwrap_or_default();
                rows.push(Measured::from_summary(
                    IDS[v],
                    LABELS[v],
                    Summary::of(&merged[v]),
                    files,
                ));
            }
        }
    }
    let [mut contract, mut raw] = <[Measured; 2]>::try_from(rows).ok().expect("two rows");
    let ratios = match (&contract.summary, &raw.summary) {
        (Some(c), Some(r)) => {
            let p50 = ratio(c.p50_ns, r.p50_ns);
            let p99 = ratio(c.p99_ns, r.p99_ns);
            let pass = p50
                .zip(p99)
                .map(|(a, b)| a <= TARGET_RATIO && b <= TARGET_RATIO);
            contract.note = format!(
                "÷ raw: p50 {}, p99 {} → {} (target ≤ {TARGET_RATIO})",
                fmt_ratio(p50),
                fmt_ratio(p99),
                match pass {
                    Some(true) => "PASS",
                    Some(false) => "FAIL",
                    None => "n/a",
                }
            );
            raw.note = "reference for the contract row".into();
            let round_ratio = |f: fn(&Summary) -> u64| -> Vec<f64> {
                per_round[0]
                    .iter()
                    .zip(&per_round[1])
                    .filter_map(|(c, r)| ratio(f(c), f(r)))
                    .collect()
            };
            let (r50, r99) = (round_ratio(|s| s.p50_ns), round_ratio(|s| s.p99_ns));
            details.push(format!(
                "contract ÷ raw per round: p50 {}, p99 {} ({} rounds, ABBA order)",
                range(&r50, ""),
                range(&r99, ""),
                r50.len()
            ));
            json!({
                "p50": p50, "p99": p99, "target": TARGET_RATIO, "pass": pass,
                "per_round_p50": r50, "per_round_p99": r99,
                "per_round_contract": per_round[0], "per_round_raw": per_round[1],
            })
        }
        _ => Value::Null,
    };
    if !service_side.is_empty() {
        let col = |i: usize| service_side.iter().map(|v| v[i]).collect::<Vec<_>>();
        let in_service: Vec<f64> = service_side.iter().map(|v| v[1] - v[0]).collect();
        details.push(format!(
            "contract rounds, service side (p50 per round): plant send → receipt {}, plant send → u_k published {} \
             (so ≈ {} from receipt to publication), of which controller step {}",
            range(&col(0), " µs"),
            range(&col(1), " µs"),
            range(&in_service, " µs"),
            range(&col(2), " µs")
        ));
    }
    let spacing = if s.plan.gap_ns == 0 {
        "back-to-back".to_string()
    } else {
        format!(
            "{:.0} µs busy-wait after each answer",
            s.plan.gap_ns as f64 / 1e3
        )
    };
    details.push(format!(
        "round trips: parent on core {} and child on core {}, both busy-polling, SCHED_FIFO {RT_PRIORITY}; {} rounds × {} samples after {} warm-up each, {spacing}, same for both variants; plant thread: {}",
        s.plant_core,
        s.rt_core,
        s.rounds,
        s.plan.samples,
        s.plan.warmup,
        setups.first().map(String::as_str).unwrap_or("?")
    ));
    measured.push(contract);
    measured.push(raw);
    ratios
}

fn paced_phase(
    s: &Settings,
    dir: &Path,
    rig: &str,
    wait: &str,
    counts: ChannelCounts,
) -> Result<(PacedResult, RtSetup, Value), String> {
    let mut child = spawn_service(s, dir, rig, wait)?;
    let seconds = s.seconds;
    let (p, setup) = child::drive(
        &mut child,
        s.plant_rt(),
        Duration::from_secs_f64(40.0 + 3.0 * seconds),
        |abort| paced::paced_plant(rig, counts, seconds, Duration::from_secs(20), abort),
    )?;
    child.wait(Duration::from_secs(30))?;
    let report = read_report(dir)?;
    Ok((p, setup, report))
}

fn cyclictest_phase(
    s: &Settings,
    dir: &Path,
) -> Result<Option<(CyclictestRun, Vec<PathBuf>)>, String> {
    if !s.cyclictest {
        return Ok(None);
    }
    let Some(exe) = cyclictest::find() else {
        return Ok(None);
    };
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let seconds = s.seconds.ceil().max(1.0) as u64;
    let start = SystemTime::now();
    let t = Instant::now();
    let run = cyclictest::run(&exe, s.rt_core, PERIOD_NS / 1_000, seconds)?;
    let elapsed = t.elapsed();
    let _ = std::fs::write(
        dir.join("cyclictest.txt"),
        format!("$ {}\n{}", run.command, run.output),
    );
    let mut files = vec![dir.join("cyclictest.txt")];
    if let Ok(f) = hist::write_files(dir, "cyclictest", &run.histogram.to_hdr(), start, elapsed) {
        files.extend(f);
    }
    Ok(Some((run, files)))
}

/// Runs `work` on a thread pinned to the RT core at `SCHED_FIFO` (helper threads of the
/// bench phases that time kernels); returns the RT set-up outcome and `work`'s result.
fn on_rt_core<T: Send + 'static>(
    rt_core: usize,
    name: &str,
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<(ipc_types::rt::RtSetup, T), String> {
    let rt = RtRequest {
        core: Some(rt_core),
        fifo_priority: Some(RT_PRIORITY),
        mlockall: true,
        prefault_stack_bytes: 256 * 1024,
    };
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

/// The RLS update at the sizes of `rls_cost::RLS_SIZES`, fast and textbook kernels
/// interleaved on the pinned RT core (see `latency_bench::rls_cost`).
fn rls_phase(s: &Settings, dir: &Path) -> Vec<Measured> {
    if let Err(e) = std::fs::create_dir_all(dir) {
        return vec![Measured::failed(
            "rls",
            "rls update",
            format!("creating {}: {e}", dir.display()),
        )];
    }
    let base = (s.steps / 10).max(1000);
    let start = SystemTime::now();
    let t = Instant::now();
    let results = match on_rt_core(s.rt_core, "bench-rls", move || {
        latency_bench::rls_cost::RLS_SIZES
            .iter()
            .map(|&(n, p)| {
                let steps = latency_bench::rls_cost::updates_for(n, p, base);
                (
                    n,
                    p,
                    latency_bench::rls_cost::measure(n, p, steps / 10, steps),
                )
            })
            .collect::<Vec<_>>()
    }) {
        Ok((_, v)) => v,
        Err(e) => return vec![Measured::failed("rls", "rls update", e)],
    };
    let elapsed = t.elapsed();
    let mut out = Vec::new();
    for (n, p, r) in results {
        let slug = format!("rls-{n}x{p}");
        match r {
            Ok((fast, text, diff)) => {
                let ff = hist::write_files(dir, &format!("{slug}-fast"), &fast, start, elapsed)
                    .unwrap_or_default();
                let tf = hist::write_files(dir, &format!("{slug}-textbook"), &text, start, elapsed)
                    .unwrap_or_default();
                let (sf, st) = (Summary::of(&fast), Summary::of(&text));
                let mut m = Measured::from_summary(
                    &format!("{slug}-fast"),
                    &format!("rls ({n}, {p}) fast"),
                    sf,
                    ff,
                );
                let ratio = |a: u64, b: u64| if b > 0 { a as f64 / b as f64 } else { f64::NAN };
                m.note = format!(
                    "textbook ÷ fast: p50 {:.1}×, p99 {:.1}×; p99 {:.1} % of 125 µs; θ agree to {diff:.0e}",
                    ratio(st.p50_ns, sf.p50_ns),
                    ratio(st.p99_ns, sf.p99_ns),
                    100.0 * sf.p99_ns as f64 / PERIOD_NS as f64
                );
                out.push(m);
                out.push(Measured::from_summary(
                    &format!("{slug}-textbook"),
                    &format!("  rls ({n}, {p}) textbook"),
                    st,
                    tf,
                ));
            }
            Err(e) => out.push(Measured::failed(&slug, &format!("rls ({n}, {p})"), e)),
        }
    }
    out
}

fn step_phase(s: &Settings, dir: &Path) -> Vec<Measured> {
    if let Err(e) = std::fs::create_dir_all(dir) {
        return vec![Measured::failed(
            "step-cost",
            "step cost",
            format!("creating {}: {e}", dir.display()),
        )];
    }
    let cases = configs::step_cases();
    let (warmup, steps) = (s.step_warmup, s.steps);
    let start = SystemTime::now();
    let t = Instant::now();
    let (setup, (results, overhead)) = match on_rt_core(s.rt_core, "bench-step", move || {
        let results: Vec<_> = cases
            .iter()
            .map(|c| (c.clone(), step_cost::measure(c, warmup, steps)))
            .collect();
        (results, step_cost::timer_overhead(steps))
    }) {
        Ok(v) => v,
        Err(e) => return vec![Measured::failed("step-cost", "step cost", e)],
    };
    let elapsed = t.elapsed();
    let mut out = Vec::new();
    for (case, r) in results {
        let id = format!("step-{}", case.slug);
        let label = format!("step: {}", case.name);
        match r {
            Ok((h, _kind)) => {
                let files =
                    hist::write_files(dir, &case.slug, &h, start, elapsed).unwrap_or_default();
                let sum = Summary::of(&h);
                let mut m = Measured::from_summary(&id, &label, sum, files);
                let pct = |ns: u64| 100.0 * ns as f64 / PERIOD_NS as f64;
                m.note = format!(
                    "of 125 µs: p99 {:.2} %, max {:.1} %",
                    pct(sum.p99_ns),
                    pct(sum.max_ns)
                );
                out.push(m);
            }
            Err(e) => out.push(Measured::failed(&id, &label, e)),
        }
    }
    let files =
        hist::write_files(dir, "timer-overhead", &overhead, start, elapsed).unwrap_or_default();
    let mut m = Measured::from_summary(
        "timer-overhead",
        "  timer overhead (2× clock_gettime)",
        Summary::of(&overhead),
        files,
    );
    m.note = format!("inside every step value; step thread: {}", setup.describe());
    out.push(m);
    out
}

/// The PCAC step at each of `workloads` on the pinned RT core, beside clarabel on the same
/// QPs when `clarabel` (see `latency_bench::pcac_cost`): the table rows, the detail lines
/// and the JSON block of `summary.json`.
fn pcac_phase(
    rt_core: usize,
    dir: &Path,
    workloads: &[Workload],
    warmup: Option<u64>,
    steps: u64,
    clarabel: bool,
) -> (Vec<Measured>, Vec<String>, Value) {
    if let Err(e) = std::fs::create_dir_all(dir) {
        return (
            vec![Measured::failed(
                "pcac",
                "pcac step",
                format!("creating {}: {e}", dir.display()),
            )],
            Vec::new(),
            Value::Null,
        );
    }
    let list = workloads.to_vec();
    let start = SystemTime::now();
    let t = Instant::now();
    let (setup, results) = match on_rt_core(rt_core, "bench-pcac", move || {
        list.iter()
            .map(|&w| {
                let warm = warmup.unwrap_or(w.default_warmup());
                (w, pcac_cost::measure(w, warm, steps, clarabel))
            })
            .collect::<Vec<_>>()
    }) {
        Ok(v) => v,
        Err(e) => {
            return (
                vec![Measured::failed("pcac", "pcac step", e)],
                Vec::new(),
                Value::Null,
            );
        }
    };
    let elapsed = t.elapsed();
    let mut rows = Vec::new();
    let mut lines = Vec::new();
    let mut json_out = serde_json::Map::new();
    for (w, r) in results {
        match r {
            Ok(c) => {
                let (mut m, l, v) = pcac_rows(&c, dir, start, elapsed, clarabel);
                rows.append(&mut m);
                lines.extend(l);
                json_out.insert(w.slug().into(), v);
            }
            Err(e) => rows.push(Measured::failed(w.slug(), w.label(), e)),
        }
    }
    lines.push(format!(
        "pcac: timing thread: {}; each workload's copies run in blocks of {} samples, the first {} timed steps of a block recorded apart (cold cache)",
        setup.describe(),
        pcac_cost::BLOCK,
        pcac_cost::REWARM
    ));
    (rows, lines, Value::Object(json_out))
}

/// `p`-quantile of a histogram, 0 when it is empty.
fn quantile(h: &Histogram<u64>, p: f64) -> u64 {
    if h.is_empty() {
        0
    } else {
        h.value_at_quantile(p)
    }
}

/// The rows, detail lines and JSON of one PCAC workload.
fn pcac_rows(
    c: &PcacCost,
    dir: &Path,
    start: SystemTime,
    elapsed: Duration,
    clarabel: bool,
) -> (Vec<Measured>, Vec<String>, Value) {
    let w = c.workload;
    let slug = w.slug();
    let mut rows = Vec::new();
    let files = |name: &str, h: &Histogram<u64>| {
        hist::write_files(dir, name, h, start, elapsed).unwrap_or_default()
    };
    let step = Summary::of(&c.step);
    let timed = c.step.len() + c.cold.len();
    let pct = |n: u64| 100.0 * n as f64 / timed.max(1) as f64;
    let mut m = Measured::from_summary(
        slug,
        &format!("{} step", w.label()),
        step,
        files(slug, &c.step),
    );
    let target = w.target_ns();
    let verdict = |ns: u64, t: u64| if ns < t { "PASS" } else { "FAIL" };
    let mut note = format!(
        "p99 {} target {} µs",
        verdict(step.p99_ns, target),
        target / 1_000
    );
    if let Some(st) = w.stretch_ns() {
        note.push_str(&format!(
            ", {} stretch {} µs",
            if step.p99_ns < st { "meets" } else { "misses" },
            st / 1_000
        ));
    }
    note.push_str(&format!(
        "; fallbacks {}; u at bound {:.1} %",
        c.fallback_steps,
        pct(c.saturated)
    ));
    if w.params().mpc.move_bounds.is_some() {
        note.push_str(&format!(", Δu at bound {:.1} %", pct(c.at_move_bound)));
    }
    m.note = note;
    rows.push(m);
    let cl = Summary::of(&c.clarabel);
    if clarabel {
        let mut m = Measured::from_summary(
            &format!("{slug}-clarabel"),
            "  clarabel, same QPs (set-up + solve)",
            cl,
            files(&format!("{slug}-clarabel"), &c.clarabel),
        );
        m.note = format!(
            "÷ pcac step: p50 {}×, p99 {}×; first move agrees to {:.1e} ({} of {} compared{})",
            fmt_ratio(ratio(cl.p50_ns, step.p50_ns)),
            fmt_ratio(ratio(cl.p99_ns, step.p99_ns)),
            c.max_first_move_diff,
            c.compared,
            timed,
            if c.clarabel_unsolved > 0 {
                format!(", clarabel not solved {}", c.clarabel_unsolved)
            } else {
                String::new()
            }
        );
        rows.push(m);
    }
    for (i, what) in ["no active constraint", "≥ 1 active constraint"]
        .iter()
        .enumerate()
    {
        let id = format!("{slug}-step-active-{i}");
        let h = &c.step_by_active[i];
        let mut m = Measured::from_summary(
            &id,
            &format!("  steps with {what}"),
            Summary::of(h),
            files(&id, h),
        );
        m.note = format!(
            "{:.0} % of the warm steps",
            100.0 * h.len() as f64 / c.step.len().max(1) as f64
        );
        rows.push(m);
    }
    for (i, name) in pcac_cost::PIECES.iter().enumerate() {
        let id = format!("{slug}-piece-{i}");
        let mut m = Measured::from_summary(
            &id,
            &format!("  {name}"),
            Summary::of(&c.pieces[i]),
            files(&id, &c.pieces[i]),
        );
        let share = ratio(Summary::of(&c.pieces[i]).p50_ns, step.p50_ns).unwrap_or(0.0);
        m.note = format!("{:.0} % of the step's p50", 100.0 * share);
        rows.push(m);
    }
    let mut m = Measured::from_summary(
        &format!("{slug}-cold"),
        "  step at a block start (cold cache)",
        Summary::of(&c.cold),
        files(&format!("{slug}-cold"), &c.cold),
    );
    m.note = "not in the step row".into();
    rows.push(m);
    let ct = &c.counters;
    let mut diffs = c.first_move_diffs.clone();
    diffs.sort_by(f64::total_cmp);
    let diff_q = |q: f64| -> f64 {
        if diffs.is_empty() {
            f64::NAN
        } else {
            diffs[((q * diffs.len() as f64) as usize).min(diffs.len() - 1)]
        }
    };
    let active_any = timed.saturating_sub(c.active.count_between(0, 0));
    let lines = vec![
        format!(
            "{slug}: active constraints per step p50 {} / p90 {} / p99 {} / max {}, {:.0} % of steps with ≥ 1; QP iterations p50 {} / p99 {} / max {}",
            quantile(&c.active, 0.5),
            quantile(&c.active, 0.9),
            quantile(&c.active, 0.99),
            c.active.max(),
            pct(active_any),
            quantile(&c.iterations, 0.5),
            quantile(&c.iterations, 0.99),
            c.iterations.max(),
        ),
        format!(
            "{slug}: first move |u − u_clarabel| (tol {:.0e}) p50 {:.1e} / p90 {:.1e} / p99 {:.1e} / max {:.1e}; beyond {:.0e} at {} of {} compared steps; there: clarabel re-solved at tol {:.0e} agrees to {:.1e} ({} re-solves not solved); ρ = (J(U_cl) − J(U))/(½eᵀHe) ≥ {:.3} (≥ 1: clarabel's point is higher than ours by at least ½eᵀHe); clarabel's constraint violation ≤ {:.1e}",
            pcac_cost::CLARABEL_TOL,
            diff_q(0.5),
            diff_q(0.9),
            diff_q(0.99),
            c.max_first_move_diff,
            pcac_cost::AGREE_TOL,
            c.over_tol,
            c.compared,
            pcac_cost::CLARABEL_TIGHT_TOL,
            c.tight_diff,
            c.tight_unsolved,
            c.optimality_ratio,
            c.clarabel_violation,
        ),
        format!(
            "{slug}: {} timed steps; max |u| {:.3}; counters over the whole run: {} MPC steps, {} solved, {} fallbacks ({} infeasible, {} iteration cap, {} numerical, {} refused), {} identification resets; reference copy mismatches {}; pieces' first move vs the step's {:.1e}",
            timed,
            c.max_abs_u,
            ct.steps,
            ct.solved,
            ct.fallbacks,
            ct.infeasible,
            ct.max_iterations,
            ct.numerical_error,
            ct.refused,
            ct.id_resets,
            c.replica_mismatches,
            c.pieces_diff,
        ),
    ];
    let active_hist: Vec<(u64, u64)> = c
        .active
        .iter_recorded()
        .map(|v| (v.value_iterated_to(), v.count_at_value()))
        .collect();
    let v = json!({
        "step": step,
        "cold": Summary::of(&c.cold),
        "clarabel": if clarabel { Some(cl) } else { None },
        "pieces": pcac_cost::PIECES.iter().zip(&c.pieces).map(|(n, h)| json!({"name": n, "summary": Summary::of(h)})).collect::<Vec<_>>(),
        "max_first_move_diff": c.max_first_move_diff,
        "compared": c.compared,
        "clarabel_unsolved": c.clarabel_unsolved,
        "pieces_diff": c.pieces_diff,
        "first_move_diff_p50": diff_q(0.5),
        "first_move_diff_p90": diff_q(0.9),
        "first_move_diff_p99": diff_q(0.99),
        "tight_unsolved": c.tight_unsolved,
        "over_agree_tol": c.over_tol,
        "tight_tol_diff": c.tight_diff,
        "optimality_ratio": if c.optimality_ratio.is_finite() { Some(c.optimality_ratio) } else { None },
        "clarabel_violation": c.clarabel_violation,
        "replica_mismatches": c.replica_mismatches,
        "saturated_steps": c.saturated,
        "move_bound_steps": c.at_move_bound,
        "fallback_steps": c.fallback_steps,
        "max_abs_u": c.max_abs_u,
        "active_constraints": active_hist,
        "iterations": Summary::of(&c.iterations),
        "counters": {
            "steps": ct.steps, "solved": ct.solved, "fallbacks": ct.fallbacks,
            "infeasible": ct.infeasible, "max_iterations": ct.max_iterations,
            "numerical_error": ct.numerical_error, "refused": ct.refused,
            "id_resets": ct.id_resets,
        },
        "target_p99_ns": w.target_ns(),
        "stretch_p99_ns": w.stretch_ns(),
    });
    (rows, lines, v)
}

/// `latency-bench pcac`: the PCAC phase alone, with the machine facts, the table and a
/// `summary.json`.
fn pcac_only(a: &PcacArgs) -> i32 {
    let workloads: Vec<Workload> = match a.workload.as_str() {
        "all" => Workload::ALL.to_vec(),
        "truss" => vec![Workload::Truss],
        "arm" => vec![Workload::Arm],
        other => {
            eprintln!("unknown workload {other} (truss, arm or all)");
            return 2;
        }
    };
    let steps = a.steps.unwrap_or(if a.quick { 300 } else { 5_000 }).max(1);
    let started = unix_now();
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("bench-results").join(format!("pcac-{started}")));
    if let Err(e) = std::fs::create_dir_all(&out) {
        eprintln!("cannot create {}: {e}", out.display());
        return 2;
    }
    let probe = match on_rt_core(a.rt_core, "bench-probe", || ()) {
        Ok((setup, ())) => setup,
        Err(e) => {
            eprintln!("{e}");
            return 2;
        }
    };
    let facts = machine::collect(&probe);
    println!("{}", facts.render());
    if probe.any_refused() {
        println!(
            "WARNING: the OS refused part of the real-time set-up; latency figures are not those of an RT setup\n"
        );
    }
    let load_start = machine::load_average();
    progress(&format!(
        "PCAC step cost, {steps} steps per workload, writing to {}",
        out.display()
    ));
    let (measured, mut details, v) =
        pcac_phase(a.rt_core, &out, &workloads, a.warmup, steps, !a.no_clarabel);
    let rows: Vec<Row> = measured.iter().map(Measured::row).collect();
    let table = table::render(&rows);
    println!("{table}");
    let load_end = machine::load_average();
    details.push(format!(
        "load average at the start: {load_start}; at the end: {load_end}"
    ));
    for d in &details {
        println!("{d}");
    }
    println!("results: {}", out.display());
    let table_text = format!("{}\n{table}\n{}\n", facts.render(), details.join("\n"));
    let summary = json!({
        "bench": "latency-bench pcac",
        "started_unix": started,
        "command": std::env::args().collect::<Vec<_>>(),
        "machine": facts,
        "steps": steps,
        "measurements": measured.iter().map(Measured::json).collect::<Vec<_>>(),
        "details": details,
        "pcac": v,
    });
    write_results(&out, &table_text, &summary, &measured)
}

/// Writes `table.txt` and `summary.json` into `out`; the exit code: 1 when the summary
/// cannot be written or a measurement failed, else 0.
fn write_results(out: &Path, table_text: &str, summary: &Value, measured: &[Measured]) -> i32 {
    let _ = std::fs::write(out.join("table.txt"), table_text);
    let text = serde_json::to_string_pretty(summary).expect("the summary serializes");
    if let Err(e) = std::fs::write(out.join("summary.json"), text) {
        eprintln!("writing summary.json: {e}");
        return 1;
    }
    if measured.iter().any(|m| m.error.is_some()) {
        1
    } else {
        0
    }
}
