//! The Rust twin of `first_order_plant.c`, for measuring what the C interface costs: the
//! same first-order plant, the same lockstep loop and the same timing of each sample
//! (publish to input), through plant-side's `PlantSide` directly instead of `ar_plant_*`.
//!
//! ```text
//! cargo run --release -p adaptive-rig-c --example first_order_plant_rs -- RIG STEPS
//! ```

use ipc_types::clock::monotonic_ns;
use ipc_types::{ChannelCounts, measurement_flags};
use plant_side::{Mode, PlantPolicy, PlantSide, PlantSideOptions, Wait};
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(rig), Some(Ok(steps))) = (args.first(), args.get(1).map(|s| s.parse::<u64>())) else {
        eprintln!("usage: first_order_plant_rs RIG STEPS");
        return ExitCode::from(2);
    };
    let period_ns = 1_000_000u64;
    let p = 5.0_f64;
    let a = (-p * period_ns as f64 * 1e-9).exp();
    let b = (1.0 - a) / p;
    let mut policy = PlantPolicy::new(1);
    policy.mode = Mode::Lockstep;
    let counts = ChannelCounts::new(1, 1, 0, 1).expect("one channel each");
    let mut opts = PlantSideOptions::new("first-order-rs");
    opts.verbose = true;
    let mut side = match PlantSide::connect(rig, counts, period_ns, policy, opts) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("first_order_plant_rs: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut spans = Vec::with_capacity(steps as usize);
    let mut x = 1.0_f64;
    for k in 0..steps {
        let t_k = monotonic_ns();
        let y = [x];
        let extra = if k + 1 == steps {
            measurement_flags::LAST_SAMPLE
        } else {
            0
        };
        let t_pub = monotonic_ns();
        let input = side
            .publish(k, t_k, [&y, &y, &[]], extra)
            .and_then(|_| side.take(k, Wait::Lockstep));
        let input = match input {
            Ok(Some(i)) => i,
            Ok(None) => break,
            Err(e) => {
                eprintln!("first_order_plant_rs: {e}");
                return ExitCode::FAILURE;
            }
        };
        spans.push(monotonic_ns() - t_pub);
        x = a * x + b * input.u[0];
    }
    let r = side.finish();
    let done = spans.len();
    println!(
        "done: {} samples, {} actuations applied, {} misses, {:.6} s, {:.3} us per sample",
        r.samples,
        r.actuations_applied,
        r.misses,
        r.wall_time_s,
        r.wall_time_s * 1e6 / done.max(1) as f64
    );
    if done > 0 {
        spans.sort_unstable();
        println!(
            "publish->input: p50 {:.3} us, p99 {:.3} us, max {:.3} us over {done} samples",
            spans[done / 2] as f64 * 1e-3,
            spans[done * 99 / 100] as f64 * 1e-3,
            spans[done - 1] as f64 * 1e-3
        );
    }
    ExitCode::SUCCESS
}
