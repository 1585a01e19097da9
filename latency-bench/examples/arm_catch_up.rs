//! What a catch-up costs the PCAC arm case of the response-time phase (PCAC at the
//! sampling arm's size, `timing = "next-step"`, on [`ArmPlant`]): deterministic replays,
//! QP iterations counted (no clock).
//!
//! ```text
//! cargo run --release -p latency-bench --example arm_catch_up -- gap 3 [plan]
//! cargo run --release -p latency-bench --example arm_catch_up -- loop 125 [8000]
//! ```
//!
//! - `gap g [plan]`: the ahead form in lockstep; every 50 samples `g` samples are taken
//!   in without adaptation, as the service's loop does with samples that came while a
//!   newer one waited, while the plant holds its input (or, with `plan`, follows the
//!   last solution's plan, `late-policy = "plan"`). The QP iterations of the first step
//!   after each gap are compared with the steady steps' and with the same QP solved cold.
//! - `loop T_us [samples]`: the service's answer-first loop in virtual time at period
//!   `T_us`: each answered step costs `65 µs + 10 µs` per QP iteration (the steady
//!   step and one dual active-set step at this size on this machine), samples that
//!   arrive meanwhile are caught up (at most the subscriber's 4; older ones lost), and
//!   the plant holds its input when an answer misses `T/2`.

use control::mpc::qp::{DenseQpSolver, QpSettings, WarmStart};
use control::pcac::Pcac;
use control::{Controller, MAX_INTERNALS, StepInput};
use latency_bench::synthetic_arm::{ARM_M, ARM_P, ArmPlant, pcac_params};

/// Index of `qp_iterations` in PCAC's internals.
const ITERATIONS: usize = 5;
/// Index of `qp_active` in PCAC's internals.
const ACTIVE: usize = 6;
/// Cost model of the `loop` replay: a step without dual steps, µs.
const STEP_US: f64 = 65.0;
/// Cost model of the `loop` replay: one dual active-set step, µs.
const ITERATION_US: f64 = 10.0;
/// Samples the service's subscriber keeps.
const BUFFER: usize = 4;

fn controller() -> Pcac {
    let counts = ipc_types::ChannelCounts::new(ARM_P, ARM_P, 0, ARM_M).expect("counts");
    Pcac::new(&pcac_params(), service::wire::dimensions(counts)).expect("the arm PCAC")
}

fn quantiles(v: &[f64]) -> String {
    let mut w = v.to_vec();
    w.sort_by(f64::total_cmp);
    let q = |p: f64| w[((w.len() - 1) as f64 * p) as usize];
    let mean = w.iter().sum::<f64>() / w.len() as f64;
    format!(
        "{} steps, mean {mean:.2} p50 {} p90 {} p99 {} max {}",
        w.len(),
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    )
}

fn gap(g: u64, follow_plan: bool) {
    let mut c = controller();
    let n = ARM_M * pcac_params().mpc.horizon;
    let mut cold = DenseQpSolver::new(n, 2 * n, QpSettings::default());
    let mut plant = ArmPlant::new(7);
    let (mut y, mut ready, mut held) = ([0.0; ARM_P], [0.0; ARM_M], [0.0; ARM_M]);
    let mut plan = vec![0.0; n];
    let (mut plan_rows, mut since) = (0, 0);
    let mut internals = [0.0; MAX_INTERNALS];
    let (mut after, mut after_cold, mut steady) = (vec![], vec![], vec![]);
    let (mut gap_left, mut post) = (0, false);
    for k in 0..20_000u64 {
        plant.sample(&mut y);
        let prev = held;
        let input = StepInput {
            seq: k,
            y: &y,
            z: &y,
            r: &[],
            u_applied: Some(&prev),
            lost: 0,
        };
        let ahead = c.ahead().expect("next-step PCAC answers ahead");
        if gap_left > 0 {
            since += 1;
            if follow_plan && since <= plan_rows {
                held.copy_from_slice(&plan[(since - 1) * ARM_M..since * ARM_M]);
            }
            ahead.advance(&input, &held, false);
            gap_left -= 1;
            post = gap_left == 0;
        } else {
            ahead.ready(&mut ready);
            held = ready;
            ahead.advance(&input, &ready, true);
            plan_rows = ahead.plan(&mut plan);
            since = 0;
            c.internals(&mut internals);
            if k >= 1000 {
                if post {
                    after.push(internals[ITERATIONS]);
                    let _ = cold.solve(&c.last_problem(), WarmStart::Cold);
                    after_cold.push(cold.iterations() as f64);
                } else {
                    steady.push(internals[ITERATIONS]);
                }
                if k % 50 == 0 {
                    gap_left = g;
                }
            }
            post = false;
        }
        plant.advance(&held);
    }
    let during = if follow_plan {
        "follows the plan"
    } else {
        "holds"
    };
    println!("gap {g}, the plant {during}: QP iterations");
    println!("  steady steps:             {}", quantiles(&steady));
    println!("  first step after the gap: {}", quantiles(&after));
    println!("  the same QPs solved cold: {}", quantiles(&after_cold));
    println!("  {:?}", c.counts_of());
}

fn virtual_loop(period_us: f64, n: usize) {
    let mut c = controller();
    let mut plant = ArmPlant::new(7);
    let mut ys: Vec<[f64; ARM_P]> = Vec::with_capacity(n);
    let mut applied: Vec<[f64; ARM_M]> = Vec::with_capacity(n);
    // The answer to each sample and when it was published, µs.
    let mut answers: Vec<Option<([f64; ARM_M], f64)>> = vec![None; n];
    let mut internals = [0.0; MAX_INTERNALS];
    let (mut t, mut next) = (0.0f64, 0usize);
    let (mut lost_total, mut observed, mut in_time) = (0u64, 0u64, 0u64);
    let (mut costs, mut iterations) = (vec![], vec![]);
    let mut last_sent = [0.0; ARM_M];
    while next < n {
        t = t.max(next as f64 * period_us);
        let newest = ((t / period_us).floor() as usize).min(n - 1);
        let first = newest.saturating_sub(BUFFER - 1).max(next);
        let lost = (first - next) as u64;
        lost_total += lost;
        while ys.len() <= newest {
            let i = ys.len();
            if i > 0 {
                let held = if i > 1 { applied[i - 2] } else { [0.0; ARM_M] };
                let a = match answers[i - 1] {
                    Some((u, tp)) if tp <= (i - 1) as f64 * period_us + period_us / 2.0 => u,
                    _ => held,
                };
                applied.push(a);
                plant.advance(&a);
            }
            let mut y = [0.0; ARM_P];
            plant.sample(&mut y);
            ys.push(y);
        }
        for j in first..=newest {
            let input = StepInput {
                seq: j as u64,
                y: &ys[j],
                z: &ys[j],
                r: &[],
                u_applied: j.checked_sub(1).map(|p| &applied[p][..]),
                lost: if j == first { lost } else { 0 },
            };
            let ahead = c.ahead().expect("next-step PCAC answers ahead");
            if j < newest {
                ahead.advance(&input, &last_sent, false);
                observed += 1;
                t += 1.0;
                continue;
            }
            let mut ready = [0.0; ARM_M];
            ahead.ready(&mut ready);
            answers[j] = Some((ready, t + 1.0));
            last_sent = ready;
            in_time += u64::from(t + 1.0 <= j as f64 * period_us + period_us / 2.0);
            ahead.advance(&input, &ready, true);
            c.internals(&mut internals);
            let cost = STEP_US + ITERATION_US * internals[ITERATIONS];
            t += 1.0 + cost;
            costs.push(cost);
            iterations.push(internals[ITERATIONS]);
            if costs.len() <= 40 && internals[ACTIVE] > 0.0 {
                println!(
                    "  sample {j}: {lost} lost, {} caught up, {} QP iterations, {} active, {cost} µs",
                    newest - first,
                    internals[ITERATIONS],
                    internals[ACTIVE]
                );
            }
        }
        next = newest + 1;
    }
    println!(
        "answer-first at {period_us} µs: {n} samples, {} answered ({in_time} in time), \
         {observed} caught up, {lost_total} lost",
        costs.len()
    );
    println!("  step cost, µs:  {}", quantiles(&costs));
    println!("  QP iterations:  {}", quantiles(&iterations));
    println!("  {:?}", c.counts_of());
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    match arg(0) {
        Some("gap") => gap(
            arg(1).and_then(|s| s.parse().ok()).unwrap_or(3),
            arg(2) == Some("plan"),
        ),
        Some("loop") => virtual_loop(
            arg(1).and_then(|s| s.parse().ok()).unwrap_or(125.0),
            arg(2).and_then(|s| s.parse().ok()).unwrap_or(8000),
        ),
        _ => eprintln!("usage: arm_catch_up gap <g> [plan] | loop <period µs> [samples]"),
    }
}
