//! `scripted_plant`: a plant side that sends exactly the samples of a script, for the fault
//! campaign (`tests/tests/campaign_*.rs`).
//!
//! ```text
//! scripted_plant <rig> <script-file> <out.json> [--period-ns N]
//! ```
//!
//! It connects to the service of rig `<rig>` as the plant (`ipc_types::ports::connect`,
//! `Side::Plant`, one `y`, one `z`, no `r`, one `u`, a period of `N` ns, 1 ms by default),
//! then sends one lockstep `Measurement` per sample of the script and waits for the
//! `Actuation` with its sequence number, up to the sample's timeout. A sample that gets no
//! answer is recorded as unanswered; the next sample then carries
//! `PREVIOUS_ACTUATION_MISSED`, as a plant that held its input would say.
//!
//! The script has one line per sample or range of samples (`#` starts a comment):
//!
//! ```text
//! <seq> | <from>..<to>   [y=V] [wait=MS] [missed] [u-offset=V] [last]
//! ```
//!
//! - `<from>..<to>`: the samples `from, from + 1, …, to − 1`, each with the options;
//! - `y=V`: the measured `y` and `z` (default 1.0);
//! - `wait=MS`: how long to wait for the answer (default 5000 ms); use a short one for a
//!   sample the service is expected to refuse, so that the plant does not hang on it;
//! - `missed`: set `PREVIOUS_ACTUATION_MISSED` even though the previous answer came;
//! - `u-offset=V`: report as `u_applied` the input the service sent plus `V` (a foreign
//!   actuation: the plant says it applied something the service did not send);
//! - `last`: set `LAST_SAMPLE` on the line's last sample.
//!
//! Every sample carries `LOCKSTEP`, `U_APPLIED` (the last answered input, held, plus any
//! offset), `t_sample_ns = ipc_types::clock::monotonic_ns()` and `deadline_ns = 0`.
//!
//! At the end it writes `<out.json>`: `{"samples": [{"seq", "answered", "u", "status"}, …],
//! "answered": n, "unanswered": n}` (`u` and `status` are `null` when unanswered), prints
//! `scripted plant: done, A answered, U unanswered` and exits with 0. Exit status 2: bad
//! arguments or script; 3: the connection failed.

use ipc_types::clock::monotonic_ns;
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::{ChannelCounts, Measurement, measurement_flags};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// One sample of the script.
#[derive(Debug, Clone, Copy)]
struct Step {
    seq: u64,
    y: f64,
    wait: Duration,
    missed: bool,
    u_offset: f64,
    last: bool,
}

/// Parses the script text into its samples.
fn parse_script(text: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let bad = |m: String| format!("script line {}: {m}: '{raw}'", n + 1);
        let mut words = line.split_whitespace();
        let seqs = words.next().unwrap_or("");
        let num = |s: &str| s.parse::<u64>().map_err(|e| bad(format!("'{s}': {e}")));
        let (from, to) = match seqs.split_once("..") {
            Some((a, b)) => (num(a)?, num(b)?),
            None => {
                let k = num(seqs)?;
                (k, k + 1)
            }
        };
        if to <= from {
            return Err(bad("empty range".into()));
        }
        let mut step = Step {
            seq: from,
            y: 1.0,
            wait: Duration::from_secs(5),
            missed: false,
            u_offset: 0.0,
            last: false,
        };
        for w in words {
            let float = |s: &str| s.parse::<f64>().map_err(|e| bad(format!("'{s}': {e}")));
            match w.split_once('=') {
                Some(("y", v)) => step.y = float(v)?,
                Some(("wait", v)) => step.wait = Duration::from_millis(num(v)?),
                Some(("u-offset", v)) => step.u_offset = float(v)?,
                None if w == "missed" => step.missed = true,
                None if w == "last" => step.last = true,
                _ => return Err(bad(format!("unknown option '{w}'"))),
            }
        }
        for seq in from..to {
            steps.push(Step {
                seq,
                last: step.last && seq + 1 == to,
                ..step
            });
        }
    }
    Ok(steps)
}

/// What happened to one sample.
struct Outcome {
    seq: u64,
    answer: Option<(f64, u32)>,
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let (Some(rig), Some(script), Some(out)) = (args.get(1), args.get(2), args.get(3)) else {
        eprintln!("usage: scripted_plant <rig> <script-file> <out.json> [--period-ns N]");
        return ExitCode::from(2);
    };
    let period_ns = match args.get(4).map(String::as_str) {
        None => 1_000_000,
        Some("--period-ns") => match args.get(5).and_then(|v| v.parse::<u64>().ok()) {
            Some(p) if p > 0 => p,
            _ => {
                eprintln!("scripted plant: --period-ns needs a positive integer");
                return ExitCode::from(2);
            }
        },
        Some(other) => {
            eprintln!("scripted plant: unknown argument '{other}'");
            return ExitCode::from(2);
        }
    };
    let steps = match std::fs::read_to_string(script)
        .map_err(|e| format!("reading {script}: {e}"))
        .and_then(|t| parse_script(&t))
    {
        Ok(s) => s,
        Err(e) => {
            eprintln!("scripted plant: {e}");
            return ExitCode::from(2);
        }
    };
    let counts = ChannelCounts::new(1, 1, 0, 1).expect("valid counts");
    let own = ContractInfo::new(Side::Plant, counts, period_ns);
    let opts = ConnectOptions::new(Duration::from_secs(30))
        .with_listener(true)
        .with_waiting_message("scripted plant: waiting for the service ...");
    let ports: PlantPorts = match ipc_types::ports::connect(rig, own, "scripted-plant", opts) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("scripted plant: connecting: {e}");
            return ExitCode::from(3);
        }
    };
    eprintln!(
        "scripted plant: connected to the service of rig '{rig}'; {} samples to send",
        steps.len()
    );

    let mut applied = 0.0;
    let mut previous_answered = true;
    let mut outcomes = Vec::with_capacity(steps.len());
    for step in &steps {
        let mut m = Measurement::zeroed(counts);
        m.seq = step.seq;
        m.t_sample_ns = monotonic_ns();
        m.period_ns = period_ns;
        m.deadline_ns = 0;
        m.flags = measurement_flags::LOCKSTEP | measurement_flags::U_APPLIED;
        if !previous_answered || step.missed {
            m.flags |= measurement_flags::PREVIOUS_ACTUATION_MISSED;
        }
        if step.last {
            m.flags |= measurement_flags::LAST_SAMPLE;
        }
        m.y[0] = step.y;
        m.z[0] = step.y;
        m.u_applied[0] = applied + step.u_offset;
        let _ = ports.publisher.send_copy(m);
        let _ = ports.notifier.notify();

        let deadline = Instant::now() + step.wait;
        let answer = loop {
            let mut found = None;
            while let Ok(Some(sample)) = ports.subscriber.receive() {
                if ports.admit(sample.origin()) == Origin::Foreign {
                    continue;
                }
                if sample.seq == step.seq && found.is_none() {
                    found = Some((sample.u[0], sample.status));
                }
            }
            if found.is_some() {
                break found;
            }
            let now = Instant::now();
            if now >= deadline {
                break None;
            }
            if let Some(l) = &ports.listener {
                let _ = l.timed_wait(
                    |_| {},
                    (deadline - now).clamp(Duration::from_millis(1), Duration::from_millis(10)),
                );
            }
        };
        previous_answered = answer.is_some();
        if let Some((u, _)) = answer {
            applied = u;
        }
        outcomes.push(Outcome {
            seq: step.seq,
            answer,
        });
    }

    let answered = outcomes.iter().filter(|o| o.answer.is_some()).count();
    let samples: Vec<serde_json::Value> = outcomes
        .iter()
        .map(|o| {
            serde_json::json!({
                "seq": o.seq,
                "answered": o.answer.is_some(),
                "u": o.answer.map(|a| a.0),
                "status": o.answer.map(|a| a.1),
            })
        })
        .collect();
    let report = serde_json::json!({
        "samples": samples,
        "answered": answered,
        "unanswered": outcomes.len() - answered,
    });
    if let Err(e) = std::fs::write(out, report.to_string()) {
        eprintln!("scripted plant: writing {out}: {e}");
        return ExitCode::from(2);
    }
    eprintln!(
        "scripted plant: done, {answered} answered, {} unanswered",
        outcomes.len() - answered
    );
    ExitCode::SUCCESS
}
