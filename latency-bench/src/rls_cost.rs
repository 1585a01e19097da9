//! Cost of one recursive-least-squares update, fast kernel against the textbook one.
//!
//! ## Method
//!
//! For each size `(n, p)` — parameters and outputs — both `service::rls::Rls` (the
//! allocation-free kernel) and `service::rls::TextbookRls` (the same equations (2.12)–(2.14)
//! written plainly, the test oracle) are fed the same data: regressors `φ_k` (p × n) with
//! entries uniform in [−1, 1) from a seeded generator, precomputed into a table, and
//! `y_k = φ_k θ + 0.01 v_k` for a fixed random `θ`, with F-test forgetting (τ_n = 10,
//! τ_d = 80, η = 1, α = 0.001) so that the forgetting rule is part of the cost. Each update is
//! timed with two `CLOCK_MONOTONIC` readings on the calling thread (pinned, `SCHED_FIFO`
//! when the bench runs it). The two kernels run interleaved in blocks of 64 updates, so that
//! a slow spell of the machine hits both.

use crate::hist::new_histogram;
use hdrhistogram::Histogram;
use ipc_types::clock::monotonic_ns;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use service::forgetting::ForgettingRule;
use service::rls::{Rls, RlsConfig, TextbookRls};

/// The sizes `(n, p)` the issue asks for: a chapter 5 identification, a small MIMO one,
/// full-RLS RCAC with 300 coefficients (1 and 3 outputs) and a PCAC-size model.
pub const RLS_SIZES: [(usize, usize); 5] = [(5, 1), (35, 5), (300, 1), (300, 3), (600, 4)];

/// Rows of the precomputed data table.
const TABLE: usize = 256;

/// Updates to time for size `(n, p)`, scaled so that each size takes about the same time.
pub fn updates_for(n: usize, p: usize, base: u64) -> u64 {
    let work = (n * n * p).max(1) as u64;
    (base * 25 / work.max(25)).clamp(500, base)
}

/// Times `steps` updates of each kernel after `warmup` untimed ones; returns the
/// histograms (ns) of the fast and of the textbook kernel, and the largest relative
/// difference of their parameter vectors at the end (they must agree).
pub fn measure(
    n: usize,
    p: usize,
    warmup: u64,
    steps: u64,
) -> Result<(Histogram<u64>, Histogram<u64>, f64), String> {
    let cfg = RlsConfig {
        n,
        p,
        theta0: vec![0.0; n],
        p0: 100.0,
        rule: ForgettingRule::FTest {
            tau_n: 10,
            tau_d: 80,
            eta: 1.0,
            alpha: 0.001,
        },
        trace_limit: 1e12,
    };
    let mut fast = Rls::new(&cfg)?;
    let mut text = TextbookRls::new(&cfg)?;
    let mut rng = ChaCha8Rng::seed_from_u64((n * 1000 + p) as u64);
    let theta: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    let mut phis = vec![0.0; TABLE * p * n];
    let mut ys = vec![0.0; TABLE * p];
    for k in 0..TABLE {
        for i in 0..p {
            let row = &mut phis[(k * p + i) * n..(k * p + i + 1) * n];
            for v in row.iter_mut() {
                *v = rng.random_range(-1.0..1.0);
            }
            let clean: f64 = row.iter().zip(&theta).map(|(a, b)| a * b).sum();
            ys[k * p + i] = clean + 0.01 * rng.random_range(-1.0..1.0);
        }
    }
    let mut h_fast = new_histogram();
    let mut h_text = new_histogram();
    const BLOCK: u64 = 64;
    let total = warmup + steps;
    let mut k = 0u64;
    while k < total {
        let end = (k + BLOCK).min(total);
        for (kernel, h) in [(0, &mut h_fast), (1, &mut h_text)] {
            for j in k..end {
                let row = (j as usize) % TABLE;
                let phi = &phis[row * p * n..(row + 1) * p * n];
                let y = &ys[row * p..(row + 1) * p];
                let t0 = monotonic_ns();
                let step = if kernel == 0 {
                    fast.update(phi, y)
                } else {
                    text.update(phi, y)
                };
                let t1 = monotonic_ns();
                core::hint::black_box(step);
                if j >= warmup {
                    h.saturating_record(t1.saturating_sub(t0));
                }
            }
        }
        k = end;
    }
    let scale = text.theta().iter().map(|v| v.abs()).fold(1e-300, f64::max);
    let diff = fast
        .theta()
        .iter()
        .zip(text.theta())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale;
    Ok((h_fast, h_text, diff))
}
