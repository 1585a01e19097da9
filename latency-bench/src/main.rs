//! `latency-bench`: checks the 8 kHz budget on this machine in one run.
//!
//! ```text
//! cargo run --release -p latency-bench [-- --samples N --seconds S --out DIR --results FILE --quick --skip-cyclictest --skip-timing]
//! cargo run --release -p latency-bench -- pcac [--steps N --workload truss|arm|all --no-clarabel --no-osqp --out DIR --results FILE]
//! cargo run --release -p latency-bench -- jack [--periods 16,32,64 --seconds S --ident-seconds S --loads idle,busy --out DIR --results FILE]
//! ```
//!
//! Runs, in order: the contract round trip against the real service, the raw iceoryx2
//! ping-pong, the service's wake-up latency at 8 kHz in sleep-poll, busy-poll and blocking mode,
//! cyclictest on the RT core (when installed), the service's response time with
//! compute-first against answer-first per controller, the step cost of each known controller
//! configuration, the RLS update cost and the PCAC step cost beside clarabel and OSQP (the `pcac`
//! subcommand runs the last alone). The `jack` subcommand runs the acoustic rig through a
//! sound card under JACK against its direct loop (it needs `jackd`). Prints the machine facts and one table, writes every
//! distribution (`.hgrm`, `.hlog`), the service's run reports and a `summary.json` to the
//! output folder (default `bench-results/<unix-time>/`), and the table with the machine,
//! the date and the command line into the results file (default `latency-bench.md` in the
//! output folder; `--results docs/results/latency-bench.md` updates the repository's). See
//! the library docs for the method of each measurement.

use clap::Parser;
use ipc_types::ChannelCounts;
use ipc_types::rt::RtSetup;
use latency_bench::cli::{Cli, JackArgs, Options, PcacArgs, Role, Settings};
use latency_bench::jack_phase::{self, JackPlan, Load};
use latency_bench::machine::{self, MachineFacts};
use latency_bench::pcac_cost::{Anchors, Workload};
use latency_bench::report::{self, Collected, RunKind, RunRecord};
use latency_bench::{
    child, cyclictest, paced, pcac_phase, rls_cost, roundtrip, step_cost, timing_phase,
};
use latency_bench::{on_rt_core, progress};
use serde_json::{Map, Value, json};
use service::config::WaitMode;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = Cli::parse();
    let code = match cli.role {
        Some(Role::ChildService {
            config,
            wait,
            core,
            run_folder,
        }) => {
            let Some(wait) = [WaitMode::SleepPoll, WaitMode::BusyPoll, WaitMode::Block]
                .into_iter()
                .find(|w| w.name() == wait)
            else {
                eprintln!("unknown wait mode {wait}");
                return ExitCode::from(2);
            };
            child::run_service_child(&config, wait, core, &run_folder)
        }
        Some(Role::ChildEcho { rig, core }) => roundtrip::run_echo_child(&rig, core),
        Some(Role::Pcac(a)) => pcac_only(&a),
        Some(Role::Jack(a)) => jack_only(&a),
        None => bench(&cli.opts),
    };
    ExitCode::from(code.clamp(0, 255) as u8)
}

/// The start of a run (Unix time) and its output folder, created: `out` when given, else
/// `bench-results/<prefix><unix-time>`; the exit code 2 when it cannot be created.
fn start_run(out: Option<&Path>, prefix: &str) -> Result<(u64, PathBuf), i32> {
    let started = report::unix_now();
    let out = out
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("bench-results").join(format!("{prefix}{started}")));
    std::fs::create_dir_all(&out).map_err(|e| {
        eprintln!("cannot create {}: {e}", out.display());
        2
    })?;
    Ok((started, out))
}

/// `summary.json` of the run `bench` started at `started` with `command` on the machine
/// `facts`: those four entries, then the object `rest`.
fn summary(
    bench: &str,
    started: u64,
    command: &[String],
    facts: &MachineFacts,
    rest: Value,
) -> Map<String, Value> {
    let mut m = into_map(json!({
        "bench": bench,
        "started_unix": started,
        "command": command,
        "machine": facts,
    }));
    m.extend(into_map(rest));
    m
}

/// Collects and prints the machine facts for the RT set-up `probe` of the measuring thread
/// and the RT core `rt_core`.
fn machine_facts(probe: &RtSetup, rt_core: usize) -> MachineFacts {
    let facts = machine::collect(probe, rt_core);
    println!("{}", facts.render());
    if probe.any_refused() {
        println!(
            "WARNING: the OS refused part of the real-time set-up; latency figures are not those of an RT setup\n"
        );
    }
    facts
}

/// The full run: every phase in order, then the table and the files.
fn bench(o: &Options) -> i32 {
    let s = Settings::from(o);
    let (started, out) = match start_run(o.run.out.as_deref(), "") {
        Ok(run) => run,
        Err(code) => return code,
    };
    // The plant thread's RT set-up, probed once for the machine facts (mlockall holds for
    // the whole process from here on).
    let probe = std::thread::spawn({
        let rt = s.plant_rt();
        move || ipc_types::rt::setup_current_thread(&rt)
    })
    .join()
    .expect("probe thread");
    let facts = machine_facts(&probe, s.rt_core);
    progress(&format!("writing to {}", out.display()));
    // A real-time thread already spinning on one of the bench's cores (a service child of
    // an earlier bench that was killed) would starve this run's threads there.
    for core in [s.plant_core, s.rt_core] {
        let note = machine::core_occupancy_note(core, &[]);
        if !note.is_empty() {
            progress(&format!("WARNING: {note}"));
        }
    }

    // Rig names unique to this run (see latency_bench::rig_base).
    let rig_base = latency_bench::rig_base();
    let counts = ChannelCounts::new(1, 1, 0, 1).expect("within capacity");
    let mut col = Collected::default();

    // 1. Contract round trip and raw ping-pong, interleaved.
    let contract_ratio = roundtrip::round_trip_phase(&s, &out, &rig_base, counts, &mut col);
    // 2. Wake-up latency at 8 kHz, against cyclictest on the RT core.
    let plant_rows = paced::wakeup_phase(&s, &out, &rig_base, counts, &mut col);
    let (ct, wake_ratios) = cyclictest::cyclictest_phase(&s, &out.join("cyclictest"), &mut col);
    col.measured.extend(plant_rows);
    col.measured.push(ct);
    // Response time with compute-first against answer-first, per controller.
    if s.timing {
        timing_phase::timing_phase(&s, &out.join("timing"), &rig_base, &mut col);
    }
    // 3. Controller step cost, RLS update cost, PCAC step cost.
    progress("6/6 controller step cost");
    col.measured
        .extend(step_cost::step_phase(&s, &out.join("step-cost")));
    progress("RLS update cost (fast kernel against the textbook one)");
    col.measured
        .extend(rls_cost::rls_phase(&s, &out.join("rls")));
    if let Some(steps) = s.pcac_steps {
        progress(&format!(
            "PCAC step cost beside clarabel and OSQP, {steps} steps per workload"
        ));
        let (rows, lines, v) = pcac_phase::pcac_phase(
            s.rt_core,
            &out.join("pcac"),
            &Workload::ALL,
            None,
            steps,
            Anchors::BOTH,
            latency_bench::pcac_replan::Runs {
                every: &latency_bench::pcac_replan::DEFAULT_PERIODS,
                qp_share: 0,
            },
        );
        col.measured.extend(rows);
        col.details.extend(lines);
        col.extra.insert("pcac".into(), v);
    }

    let load_end = machine::load_average();
    let command: Vec<String> = std::env::args().collect();
    let summary = summary(
        "latency-bench",
        started,
        &command,
        &facts,
        json!({
        "settings": s.json(),
        "ratios": {
            "contract_over_raw": contract_ratio,
            "wakeup_over_cyclictest": Value::Object(wake_ratios),
        },
        "load_average_at_end": load_end,
        "extra": Value::Object(std::mem::take(&mut col.extra)),
        "service_reports": Value::Object(std::mem::take(&mut col.reports)),
        }),
    );
    let results = report::results_file(s.results.as_deref(), &out);
    let record = RunRecord {
        kind: RunKind::Full,
        started_unix: started,
        command,
        facts: &facts,
        settings: s.json(),
        out: &out,
        results: &results,
    };
    let footer = [format!("load average at the end: {load_end}")];
    report::finish(&record, &col, &footer, summary)
}

/// `latency-bench pcac`: the PCAC phase alone, with the machine facts, the table, a
/// `summary.json` and its section of the results file.
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
    let steps = a
        .steps
        .unwrap_or(if a.run.quick { 300 } else { 5_000 })
        .max(1);
    let anchors = Anchors {
        clarabel: !a.no_clarabel,
        osqp: !a.no_osqp,
    };
    let (started, out) = match start_run(a.run.out.as_deref(), "pcac-") {
        Ok(run) => run,
        Err(code) => return code,
    };
    let probe = match on_rt_core(a.rt_core, "bench-probe", || ()) {
        Ok((setup, ())) => setup,
        Err(e) => {
            eprintln!("{e}");
            return 2;
        }
    };
    let facts = machine_facts(&probe, a.rt_core);
    let load_start = machine::load_average();
    progress(&format!(
        "PCAC step cost, {steps} steps per workload, writing to {}",
        out.display()
    ));
    let replan: Vec<usize> = a.replan_every.iter().copied().filter(|&n| n > 0).collect();
    let (measured, details, v) = pcac_phase::pcac_phase(
        a.rt_core,
        &out,
        &workloads,
        a.warmup,
        steps,
        anchors,
        latency_bench::pcac_replan::Runs {
            every: &replan,
            qp_share: a.qp_share,
        },
    );
    let mut col = Collected {
        measured,
        details,
        ..Collected::default()
    };
    let load_end = machine::load_average();
    col.details.push(format!(
        "load average at the start: {load_start}; at the end: {load_end}"
    ));
    let command: Vec<String> = std::env::args().collect();
    let summary = summary(
        "latency-bench pcac",
        started,
        &command,
        &facts,
        json!({ "steps": steps, "pcac": v }),
    );
    let results = a.run.results_file(&out);
    let record = RunRecord {
        kind: RunKind::Pcac,
        started_unix: started,
        command,
        facts: &facts,
        settings: json!({
            "steps": steps,
            "warmup": a.warmup,
            "workload": a.workload,
            "clarabel": anchors.clarabel,
            "osqp": anchors.osqp,
            "replan_every": replan,
            "qp_share": a.qp_share,
            "rt_core": a.rt_core,
        }),
        out: &out,
        results: &results,
    };
    report::finish(&record, &col, &[], summary)
}

/// `latency-bench jack`: the JACK phase alone ([`latency_bench::jack_phase`]).
fn jack_only(a: &JackArgs) -> i32 {
    let quick = a.run.quick;
    let loads = match a
        .loads
        .iter()
        .map(|l| Load::parse(l))
        .collect::<Result<Vec<_>, _>>()
    {
        Ok(l) => l,
        Err(e) => {
            eprintln!("--loads: {e}");
            return 2;
        }
    };
    if a.periods.is_empty() || a.periods.contains(&0) {
        eprintln!("--periods: give one or more periods of at least one frame");
        return 2;
    }
    let seconds = a.seconds.unwrap_or(if quick { 3.0 } else { 10.0 });
    let ident_seconds = a.ident_seconds.unwrap_or(if quick { 5.0 } else { 20.0 });
    for (name, v) in [("--seconds", seconds), ("--ident-seconds", ident_seconds)] {
        if !(v.is_finite() && v > 0.0) {
            eprintln!("{name} {v} is not a positive number of seconds");
            return 2;
        }
    }
    let Some(bin_dir) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent().map(Path::to_path_buf))
    else {
        eprintln!("cannot find the folder of this executable (rig and rig-design are beside it)");
        return 2;
    };
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let (started, out) = match start_run(a.run.out.as_deref(), "jack-") {
        Ok(run) => run,
        Err(code) => return code,
    };
    let probe = match on_rt_core(1, "bench-probe", || ()) {
        Ok((setup, ())) => setup,
        Err(e) => {
            eprintln!("{e}");
            return 2;
        }
    };
    let facts = machine_facts(&probe, 1);
    let plan = JackPlan {
        periods: a.periods.clone(),
        seconds,
        ident_seconds,
        loads,
        repo,
        bin_dir,
    };
    let (runs, mut lines, v) = jack_phase::jack_phase(&plan, &out);
    let failed = !v["failures"].as_array().is_none_or(Vec::is_empty);
    let table = jack_phase::render(&runs);
    println!("{table}");
    lines.insert(
        0,
        format!("load average at the end: {}", machine::load_average()),
    );
    for l in &lines {
        println!("{l}");
    }
    let command: Vec<String> = std::env::args().collect();
    let summary = summary(
        "latency-bench jack",
        started,
        &command,
        &facts,
        json!({ "jack": v }),
    );
    let results = a.run.results_file(&out);
    let record = RunRecord {
        kind: RunKind::Jack,
        started_unix: started,
        command,
        facts: &facts,
        settings: json!({
            "periods": plan.periods,
            "seconds": seconds,
            "ident_seconds": ident_seconds,
            "loads": a.loads,
        }),
        out: &out,
        results: &results,
    };
    let code = report::write_results(
        &out,
        &format!("{}\n{table}\n{}\n", facts.render(), lines.join("\n")),
        &Value::Object(summary),
        &[],
        &record,
        &table,
        &lines,
    );
    println!("results: {}", out.display());
    if failed { 1 } else { code }
}

/// The object of a `json!({…})` literal.
fn into_map(v: Value) -> Map<String, Value> {
    match v {
        Value::Object(m) => m,
        _ => unreachable!("a JSON object literal"),
    }
}
