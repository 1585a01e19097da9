//! The sampling-arm controller's step at §7.3's size (PCAC with `p = 5`, `m = 2`,
//! `ℓ = 50`: a QP of 100 variables) in a real contact on the simulated spacecraft: no
//! allocation once running, and (ignored, release mode) what a step costs:
//!
//! ```text
//! cargo test --release -p control --test arm_step -- --ignored --nocapture
//! ```

mod arm_support;
mod counting_alloc;

use std::time::Instant;

use arm_support::*;
use control::arm::controller::ArmController;
use control::{Controller, MAX_INTERNALS, StepInput};
use counting_alloc::allocations_in;

/// One controller step on the spacecraft's measurement with the command `f_d`; the
/// closure `around` wraps the call (counting or timing it).
fn answer(
    c: &mut ArmController,
    sc: &Spacecraft,
    k: u64,
    f_d: f64,
    around: &mut dyn FnMut(&mut dyn FnMut()),
) -> [f64; 2] {
    let y = sc.measure();
    let r = [f_d];
    let mut u = [0.0; 2];
    let input = StepInput {
        seq: k,
        y: &y,
        z: &y[6..],
        r: &r,
        u_applied: None,
        lost: 0,
    };
    around(&mut || {
        c.step(&input, &mut u);
    });
    u
}

/// A contact, a hold and a second contact on another surface (the phase changes of
/// §7.3.3), with the internals read every step: after the first 100 samples no step
/// allocates, and PCAC solves its QPs (the solved path is the one counted).
#[test]
fn steps_in_contact_and_hold_do_not_allocate() {
    let mut c = augmented();
    c.prepare_thread();
    let mut sc = Spacecraft::at_contact(Surface {
        k_s: 2.0e5,
        c_s: 5.0,
        mu: 0.5,
    });
    let mut internals = [0.0; MAX_INTERNALS];
    let mut allocations = 0;
    let mut count = |f: &mut dyn FnMut()| allocations += allocations_in(f);
    let mut k = 0;
    for _ in 0..100 {
        let u = answer(&mut c, &sc, k, F_D, &mut |f| f());
        sc.advance(&u);
        k += 1;
    }
    for phase in 0..3 {
        if phase == 2 {
            sc = Spacecraft::at_contact(Surface {
                k_s: 200.0,
                c_s: 500.0,
                mu: 0.5,
            });
        }
        let f_d = if phase == 1 { 0.0 } else { F_D };
        for _ in 0..1000 {
            let u = answer(&mut c, &sc, k, f_d, &mut count);
            let _ = c.internals(&mut internals);
            if phase != 1 {
                sc.advance(&u);
            }
            k += 1;
        }
    }
    let solved = c.pcac().unwrap().counts_of().solved;
    assert_eq!(
        allocations, 0,
        "the arm controller allocated {allocations} times"
    );
    assert!(solved > 1900, "only {solved} QPs solved");
}

/// The cost of one step (linearization, robust gain, PCAC: identification, realization,
/// condensing, the QP of 100 variables with input and move bounds) over a 2 s contact
/// phase on each corner of §7.3's surface box and on Figure 7.4's surface. The closed
/// loop is deterministic, so it is run [`REPLAYS`] times and each step's time is the
/// least of its replays: what the step costs without the preemptions of a shared
/// machine. Prints the distribution and the QP iterations of the slowest steps; no
/// assertion on time.
#[test]
#[ignore]
fn step_cost() {
    let surfaces = [
        (2.0e5, 5.0),
        (300.0, 0.35),
        (300.0, 1000.0),
        (2.7e5, 0.35),
        (2.7e5, 1000.0),
    ];
    let mut all = Vec::new();
    for (k_s, c_s) in surfaces {
        let best = cost_on(Surface { k_s, c_s, mu: 0.5 });
        all.extend(best);
    }
    all.sort_by(f64::total_cmp);
    let q = |p: f64| all[((all.len() - 1) as f64 * p).round() as usize] / 1e3;
    eprintln!(
        "all {} steps: p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
        all.len(),
        q(0.5),
        q(0.99),
        q(0.999),
        q(1.0)
    );
}

/// Replays of one 2 s contact on `surface`; prints its distribution and returns each
/// step's least time, ns.
fn cost_on(surface: Surface) -> Vec<f64> {
    const STEPS: usize = 4000;
    const REPLAYS: usize = 7;
    let mut best = vec![f64::INFINITY; STEPS];
    let mut iterations = vec![0.0; STEPS];
    let mut counts = None;
    for _ in 0..REPLAYS {
        let mut c = augmented();
        c.prepare_thread();
        let mut sc = Spacecraft::at_contact(surface);
        let mut internals = [0.0; MAX_INTERNALS];
        for k in 0..STEPS {
            let mut ns = 0.0;
            let u = answer(&mut c, &sc, k as u64, F_D, &mut |f| {
                let t = Instant::now();
                f();
                ns = t.elapsed().as_nanos() as f64;
            });
            best[k] = best[k].min(ns);
            let _ = c.internals(&mut internals);
            // "qp_iterations": after the arm's 8 internals and PCAC's first five.
            iterations[k] = internals[13];
            sc.advance(&u);
        }
        counts = Some(c.pcac().unwrap().counts_of());
    }
    let counts = counts.unwrap();
    let mut sorted = best.clone();
    sorted.sort_by(f64::total_cmp);
    let q = |p: f64| sorted[((sorted.len() - 1) as f64 * p).round() as usize] / 1e3;
    let mut order: Vec<usize> = (0..STEPS).collect();
    order.sort_by(|&a, &b| best[b].total_cmp(&best[a]));
    let slowest: Vec<String> = order[..4]
        .iter()
        .map(|&i| format!("#{i} {:.0} µs ({} it.)", best[i] / 1e3, iterations[i]))
        .collect();
    eprintln!(
        "k_s = {}, c_s = {}: {} QPs solved, {} fallbacks; p50 {:.1} µs, p99 {:.1} µs, \
         max {:.1} µs; the slowest: {}",
        surface.k_s,
        surface.c_s,
        counts.solved,
        counts.fallbacks,
        q(0.5),
        q(0.99),
        q(1.0),
        slowest.join(", ")
    );
    best
}
