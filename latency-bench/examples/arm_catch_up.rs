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
//!   `T_us` ([`latency_bench::catch_up`]: each answered step costs `65 µs + 10 µs` per QP
//!   iteration, samples that arrive meanwhile are caught up, at most the subscriber's 4,
//!   older ones lost, and the plant holds its input when an answer misses `T/2`).

use control::mpc::qp::{DenseQpSolver, QpSettings, WarmStart};
use control::pcac::Pcac;
use control::{Controller, MAX_INTERNALS, StepInput};
use latency_bench::catch_up::replay;
use latency_bench::synthetic_arm::{ARM_M, ARM_P, ArmPlant, pcac_params};

/// Index of `qp_iterations` in PCAC's internals.
const ITERATIONS: usize = 5;

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
    let r = replay(period_us, n);
    for a in r.answered.iter().take(40).filter(|a| a.active > 0.0) {
        println!(
            "  sample {}: {} lost, {} caught up, {} QP iterations, {} active, {} µs",
            a.sample, a.lost, a.caught_up, a.iterations, a.active, a.cost_us
        );
    }
    println!(
        "answer-first at {period_us} µs: {n} samples, {} answered ({} in time), \
         {} caught up, {} lost",
        r.answered.len(),
        r.in_time,
        r.observed,
        r.lost
    );
    let costs: Vec<f64> = r.answered.iter().map(|a| a.cost_us).collect();
    let iterations: Vec<f64> = r.answered.iter().map(|a| a.iterations).collect();
    println!("  step cost, µs:  {}", quantiles(&costs));
    println!("  QP iterations:  {}", quantiles(&iterations));
    println!("  {:?}", r.controller.counts_of());
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
