//! Cost of one recursive-least-squares update, fast kernel against the textbook one.
//!
//! ## Method
//!
//! For each size `(n, p)` — parameters and outputs — both `control::rls::Rls` (the
//! allocation-free kernel) and `control::rls::TextbookRls` (the same equations (2.12)–(2.14)
//! written plainly, the test oracle) are fed the same data: regressors `φ_k` (p × n) with
//! entries uniform in [−1, 1) from a seeded generator, precomputed into a table, and
//! `y_k = φ_k θ + 0.01 v_k` for a fixed random `θ`, with F-test forgetting (τ_n = 10,
//! τ_d = 80, η = 1, α = 0.001) so that the forgetting rule is part of the cost. Each update is
//! timed with two `CLOCK_MONOTONIC` readings on the calling thread (pinned, `SCHED_FIFO`
//! when the bench runs it).
//!
//! The two kernels run interleaved in blocks of [`BLOCK`] updates (the fast kernel's block,
//! then the textbook kernel's block on the same data), so that a slow spell of the machine
//! hits both. The fast kernel is timed on at least [`FAST_MIN_STEPS`] updates (it is cheap);
//! the textbook kernel, which costs many times more, only on the `steps` requested, after which
//! the fast kernel runs on alone. The agreement of the two is checked on `θ` at the update
//! where the textbook kernel stopped.
//!
//! **Cold-cache rule.** The textbook kernel allocates several `n × n` matrices per update,
//! which evicts the fast kernel's covariance (361 KB packed at `n = 300`) from L2; in the
//! product the RLS runs every cycle with only the controller sharing its core's cache. The
//! first [`REWARM`] fast updates after each textbook block therefore run but are *not*
//! recorded in the fast histogram; they are counted and kept apart ([`RlsCost::cold`]) so
//! that the cost of a cold start stays visible. With blocks this long the rule drops at most
//! [`REWARM`] of every [`BLOCK`] fast updates.
//!
//! [`rls_phase`] runs every size of [`RLS_SIZES`] on the pinned RT core.

use crate::cli::Settings;
use crate::hist::new_histogram;
use crate::hist::{self, Summary};
use crate::report::Measured;
use crate::{PERIOD_NS, timed_on_rt_core};
use control::forgetting::ForgettingRule;
use control::rls::{Rls, RlsConfig, TextbookRls};
use hdrhistogram::Histogram;
use ipc_types::clock::monotonic_ns;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// The sizes `(n, p)` the issue asks for: a chapter 5 identification, a small MIMO one,
/// full-RLS RCAC with 300 coefficients (1 and 3 outputs) and a PCAC-size model.
pub const RLS_SIZES: [(usize, usize); 5] = [(5, 1), (35, 5), (300, 1), (300, 3), (600, 4)];

/// Rows of the precomputed data table.
const TABLE: usize = 256;

/// Updates per interleaved block of each kernel.
pub const BLOCK: u64 = 512;

/// Fast updates after each textbook block that are run but not recorded (cold cache).
pub const REWARM: u64 = 2;

/// Least number of timed fast updates (percentiles up to p99.9 from ≥ 5 samples).
pub const FAST_MIN_STEPS: u64 = 5_000;

/// Updates to time for size `(n, p)`, scaled so that each size takes about the same time.
pub fn updates_for(n: usize, p: usize, base: u64) -> u64 {
    let work = (n * n * p).max(1) as u64;
    (base * 25 / work.max(25)).clamp(500, base)
}

/// The result of [`measure_detailed`].
pub struct RlsCost {
    /// Fast kernel, ns per update (warm: the cold-cache rule's updates excluded).
    pub fast: Histogram<u64>,
    /// Textbook kernel, ns per update.
    pub text: Histogram<u64>,
    /// Fast updates run right after a textbook block (excluded from `fast`), ns.
    pub cold: Histogram<u64>,
    /// Largest difference of the two `θ`, relative to the largest `|θ_i|` of the
    /// textbook kernel, at the update where the textbook kernel stopped.
    pub diff: f64,
}

/// Times `steps` updates of each kernel after `warmup` untimed ones; returns the
/// histograms (ns) of the fast and of the textbook kernel, and the largest relative
/// difference of their parameter vectors at the end (they must agree). See
/// [`measure_detailed`] (the fast kernel is timed on at least [`FAST_MIN_STEPS`] updates;
/// its cold updates are left out).
pub fn measure(
    n: usize,
    p: usize,
    warmup: u64,
    steps: u64,
) -> Result<(Histogram<u64>, Histogram<u64>, f64), String> {
    let r = measure_detailed(n, p, warmup, steps)?;
    Ok((r.fast, r.text, r.diff))
}

/// Runs `f` between two `CLOCK_MONOTONIC` readings; the time between them, ns (its result
/// is kept from being optimised away).
#[inline(always)]
fn time_ns<T>(f: impl FnOnce() -> T) -> u64 {
    let t0 = monotonic_ns();
    let step = f();
    let t1 = monotonic_ns();
    core::hint::black_box(step);
    t1.saturating_sub(t0)
}

/// The measurement of the module docs: `warmup` untimed updates of both kernels, then
/// `steps` timed textbook updates and `max(steps, FAST_MIN_STEPS)` timed fast ones, in
/// interleaved blocks of [`BLOCK`], with the cold-cache rule.
pub fn measure_detailed(n: usize, p: usize, warmup: u64, steps: u64) -> Result<RlsCost, String> {
    let cfg = RlsConfig {
        rule: ForgettingRule::FTest {
            tau_n: 10,
            tau_d: 80,
            eta: 1.0,
            alpha: 0.001,
        },
        trace_limit: 1e12,
        ..RlsConfig::new(n, p, 100.0)
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
    let mut h_cold = new_histogram();
    let text_total = warmup + steps;
    let fast_total = warmup + steps.max(FAST_MIN_STEPS);
    let mut fast_theta_at_text_end = Vec::new();
    let mut cold_left = 0u64;
    let mut k = 0u64;
    // The regressor and output of update `j`, from the table.
    let data = |j: u64| {
        let row = (j as usize) % TABLE;
        (
            &phis[row * p * n..(row + 1) * p * n],
            &ys[row * p..(row + 1) * p],
        )
    };
    while k < fast_total {
        let end = (k + BLOCK).min(fast_total);
        for j in k..end {
            let (phi, y) = data(j);
            let dt = time_ns(|| fast.update(phi, y));
            if cold_left > 0 {
                cold_left -= 1;
                if j >= warmup {
                    h_cold.saturating_record(dt);
                }
            } else if j >= warmup {
                h_fast.saturating_record(dt);
            }
            if j + 1 == text_total {
                fast_theta_at_text_end = fast.theta().to_vec();
            }
        }
        let text_end = end.min(text_total);
        for j in k..text_end {
            let (phi, y) = data(j);
            let dt = time_ns(|| text.update(phi, y));
            if j >= warmup {
                h_text.saturating_record(dt);
            }
        }
        if k < text_end {
            cold_left = REWARM;
        }
        k = end;
    }
    let scale = text.theta().iter().map(|v| v.abs()).fold(1e-300, f64::max);
    let diff = fast_theta_at_text_end
        .iter()
        .zip(text.theta())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale;
    Ok(RlsCost {
        fast: h_fast,
        text: h_text,
        cold: h_cold,
        diff,
    })
}

/// The RLS update at the sizes of `rls_cost::RLS_SIZES`, fast and textbook kernels
/// interleaved on the pinned RT core (see the module docs): a row per size and kernel, distributions written into `dir`.
pub fn rls_phase(s: &Settings, dir: &Path) -> Vec<Measured> {
    let base = (s.steps / 10).max(1000);
    let run = match timed_on_rt_core(
        s.rt_core,
        dir,
        "bench-rls",
        ("rls", "rls update"),
        move || {
            RLS_SIZES
                .iter()
                .map(|&(n, p)| {
                    let steps = updates_for(n, p, base);
                    (n, p, measure(n, p, steps / 10, steps))
                })
                .collect::<Vec<_>>()
        },
    ) {
        Ok(run) => run,
        Err(failed) => return vec![*failed],
    };
    let (start, elapsed) = (run.start, run.elapsed);
    let results = run.value;
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
