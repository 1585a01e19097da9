//! Which noiseless RLS/FTVRF runs settle slowly after the change, and why (§5.3.1,
//! Figure 5.2: "all simulations converge to the true parameters in less than 20 steps").
//!
//! Per run of the noiseless Monte Carlo (same seeds as [`super::montecarlo`]) it records:
//!
//! - the settling of the relative parameter error `‖θ_k − θ‖/‖θ‖` after the change at
//!   `k = 100` under several readings of "converge": it stays below 1 %, 5 % or 10 % to the
//!   end of the run, or first falls below 1 % or 10 %, or every component stays within
//!   [`VISUAL`] of its true value (a line width on the figure's `θ` axis);
//! - the excitation over the [`HORIZON`] steps from the change on ([`super::excitation`]):
//!   `σ_min` and the condition number of the regressor matrix, the input's RMS;
//! - the F-test's response (Algorithm 1, (5.1), (5.4)): when `λ_k` first drops below 1 after
//!   the change, for how many steps it stays below 1, its smallest value.
//!
//! The runs are written to `case1_noiseless_ftvrf_runs.csv`; [`contrast`] sets the slowest
//! runs against the medians over all runs, and [`spearman`] ranks settling against each
//! feature.

use std::fmt::Write as _;
use std::path::Path;

use crate::file_error::{FileError, FileOp};
use crate::study::forgetting::ForgettingError;
use crate::study::forgetting::excitation::Excitation;
use crate::study::forgetting::experiment::{Case, Method, Trace, Variant};
use crate::study::forgetting::montecarlo::{SeededRun, percentile};
use crate::study::forgetting::plant::{CHANGE_STEP, Plant};

/// Steps from the change over which the excitation is measured: the claim's 20 steps.
pub const HORIZON: usize = 20;
/// Largest error of every `θ` component (absolute) that the "visual" reading accepts.
pub const VISUAL: f64 = 0.02;
/// Steps of the noiseless runs (as in the Monte Carlo).
pub const STEPS: usize = 300;

/// What one noiseless RLS/FTVRF run did after the change.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunFeatures {
    /// Index of the run in the Monte Carlo.
    pub run: u64,
    /// Its seed ([`run_seed`](crate::study::forgetting::experiment::run_seed)).
    pub seed: u64,
    /// Steps until the relative error stays below 1 % (the study's settling).
    pub settle: Option<usize>,
    /// The same at 5 %.
    pub settle_5: Option<usize>,
    /// The same at 10 %.
    pub settle_10: Option<usize>,
    /// Steps until the relative error first falls below 1 %.
    pub first_1: Option<usize>,
    /// Steps until the relative error first falls below 10 %.
    pub first_10: Option<usize>,
    /// Steps until every component stays within [`VISUAL`] of its true value.
    pub settle_visual: Option<usize>,
    /// The excitation over [`HORIZON`] steps from the change.
    pub excitation: Excitation,
    /// Steps after the change of the first `λ_k < 1` (`None`: never).
    pub forget_start: Option<usize>,
    /// Number of steps from the change on with `λ_k < 1`.
    pub forget_steps: usize,
    /// The smallest `λ_k` from the change on.
    pub lambda_min: f64,
    /// Steps after the change of the first `λ_k = 1` after forgetting started (`None`:
    /// forgetting never started or never ended).
    pub forget_end: Option<usize>,
    /// The relative parameter error when forgetting ends (NaN without an end).
    pub error_at_forget_end: f64,
    /// `tr(P)` when forgetting ends (NaN without an end).
    pub trace_at_forget_end: f64,
    /// `σ_min` of the regressor rows of the forgetting steps (NaN without an end or when
    /// the rows are not finite).
    pub sigma_min_forgetting: f64,
}

/// Steps after the change until `err` (one value per row of `ks`) stays below `threshold`
/// to its end (`None`: its last value is not below; NaN counts as not below).
pub fn stays_below(ks: &[usize], err: &[f64], threshold: f64) -> Option<usize> {
    let mut settle = Some(0);
    for (&k, &e) in ks.iter().zip(err) {
        if k >= CHANGE_STEP && e.partial_cmp(&threshold) != Some(std::cmp::Ordering::Less) {
            settle = Some(k + 1 - CHANGE_STEP);
        }
    }
    match (ks.last(), settle) {
        (Some(&last), Some(s)) if s + CHANGE_STEP > last => None,
        _ => settle,
    }
}

/// Steps after the change until `err` first falls below `threshold` (`None`: never).
pub fn first_below(ks: &[usize], err: &[f64], threshold: f64) -> Option<usize> {
    ks.iter()
        .zip(err)
        .find(|&(&k, &e)| k >= CHANGE_STEP && e < threshold)
        .map(|(&k, _)| k - CHANGE_STEP)
}

/// The features of run `run` (seed `seed`) from its recorded trace (every step recorded
/// from the change for [`HORIZON`] steps); `None` when the trace does not reach them.
pub fn features(run: u64, seed: u64, t: &Trace) -> Option<RunFeatures> {
    let rel: Vec<f64> = t
        .theta
        .iter()
        .zip(&t.truth)
        .map(|(th, tr)| {
            let num: f64 = th.iter().zip(tr).map(|(a, b)| (a - b).powi(2)).sum();
            let den: f64 = tr.iter().map(|b| b * b).sum();
            (num / den).sqrt()
        })
        .collect();
    let worst: Vec<f64> = t
        .theta
        .iter()
        .zip(&t.truth)
        .map(|(th, tr)| {
            th.iter()
                .zip(tr)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        })
        .collect();
    let start = t.ks.iter().position(|&k| k == CHANGE_STEP)?;
    let window = t.phi.get(start..start + HORIZON)?;
    if t.ks[start + HORIZON - 1] != CHANGE_STEP + HORIZON - 1 {
        return None;
    }
    let excitation = Excitation::of(window)?;
    let after = start..t.ks.len();
    let start_row = after.clone().find(|&i| t.lambda[i] < 1.0);
    let forget_start = start_row.map(|i| t.ks[i] - CHANGE_STEP);
    let end_row = start_row.and_then(|s| (s..t.ks.len()).find(|&i| t.lambda[i] >= 1.0));
    let at_end = |v: &[f64]| end_row.map_or(f64::NAN, |i| v[i]);
    let sigma_min_forgetting = match (start_row, end_row) {
        (Some(a), Some(b)) => t
            .phi
            .get(a..b)
            .and_then(Excitation::of)
            .map_or(f64::NAN, |e| e.sigma_min),
        _ => f64::NAN,
    };
    Some(RunFeatures {
        run,
        seed,
        settle: stays_below(&t.ks, &rel, 0.01),
        settle_5: stays_below(&t.ks, &rel, 0.05),
        settle_10: stays_below(&t.ks, &rel, 0.10),
        first_1: first_below(&t.ks, &rel, 0.01),
        first_10: first_below(&t.ks, &rel, 0.10),
        settle_visual: stays_below(&t.ks, &worst, VISUAL),
        excitation,
        forget_start,
        forget_steps: after.clone().filter(|&i| t.lambda[i] < 1.0).count(),
        lambda_min: after.map(|i| t.lambda[i]).fold(1.0, f64::min),
        forget_end: end_row.map(|i| t.ks[i] - CHANGE_STEP),
        error_at_forget_end: at_end(&rel),
        trace_at_forget_end: at_end(&t.trace_p),
        sigma_min_forgetting,
    })
}

/// The `runs` noiseless RLS/FTVRF runs of master seed `seed` (those of the Monte Carlo),
/// recorded, in run order: the items of the slow runs' stage.
pub fn items(runs: usize, seed: u64) -> Vec<SeededRun> {
    SeededRun::all(
        Case::Noiseless,
        Method::Ftvrf,
        Variant::STUDY,
        STEPS,
        runs,
        seed,
        true,
    )
}

/// The features of the run `item` ([`items`]) on `plant` (an error as its message).
pub fn features_of(plant: &Plant, item: &SeededRun) -> Result<RunFeatures, String> {
    let (_, trace) = item.run_on(plant)?;
    let trace = trace.ok_or_else(|| ForgettingError::NoTrace.to_string())?;
    features(item.run, item.seed, &trace).ok_or_else(|| ForgettingError::NoTrace.to_string())
}

/// Spearman's rank correlation of `x` and `y` (ties get their mean rank; `+∞` ranks last);
/// NaN when fewer than two pairs or one side is constant.
pub fn spearman(x: &[f64], y: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        let mut r = vec![0.0; v.len()];
        let mut i = 0;
        while i < idx.len() {
            let mut j = i;
            while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
                j += 1;
            }
            let mean = (i + j) as f64 / 2.0;
            for &k in &idx[i..=j] {
                r[k] = mean;
            }
            i = j + 1;
        }
        r
    }
    let n = x.len().min(y.len());
    if n < 2 {
        return f64::NAN;
    }
    let (rx, ry) = (ranks(&x[..n]), ranks(&y[..n]));
    let mean = (n - 1) as f64 / 2.0;
    let cov: f64 = rx
        .iter()
        .zip(&ry)
        .map(|(a, b)| (a - mean) * (b - mean))
        .sum();
    let vx: f64 = rx.iter().map(|a| (a - mean).powi(2)).sum();
    let vy: f64 = ry.iter().map(|b| (b - mean).powi(2)).sum();
    cov / (vx * vy).sqrt()
}

/// Steps as a number (`+∞` for "never").
fn num(v: Option<usize>) -> f64 {
    v.map_or(f64::INFINITY, |s| s as f64)
}

/// Steps as text ("never" for `None`).
fn txt(v: Option<usize>) -> String {
    v.map_or_else(|| "never".into(), |s| s.to_string())
}

/// Writes the runs as CSV, one row per run.
pub fn write_csv(path: &Path, runs: &[RunFeatures]) -> Result<(), ForgettingError> {
    let mut s = String::from(
        "run,seed,settle_1pct,settle_5pct,settle_10pct,first_below_1pct,first_below_10pct,settle_visual,\
         sigma_min,sigma_max,condition,input_rms,forget_start,forget_steps,lambda_min,\
         forget_end,rel_error_at_forget_end,trP_at_forget_end,sigma_min_forgetting\n",
    );
    for r in runs {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{},{},{:.6e},{},{:.6e},{:.6e},{:.6e}",
            r.run,
            r.seed,
            txt(r.settle),
            txt(r.settle_5),
            txt(r.settle_10),
            txt(r.first_1),
            txt(r.first_10),
            txt(r.settle_visual),
            r.excitation.sigma_min,
            r.excitation.sigma_max,
            r.excitation.condition(),
            r.excitation.input_rms,
            txt(r.forget_start),
            r.forget_steps,
            r.lambda_min,
            txt(r.forget_end),
            r.error_at_forget_end,
            r.trace_at_forget_end,
            r.sigma_min_forgetting
        );
    }
    std::fs::write(path, s)
        .map_err(|e| FileError::new(FileOp::Writing, path.to_path_buf(), e).into())
}

/// The slowest runs against the medians over all runs, and how settling ranks with each
/// feature.
#[derive(Debug, Clone, PartialEq)]
pub struct Contrast {
    /// The slowest runs (1 % settling, slowest first).
    pub slowest: Vec<RunFeatures>,
    /// Medians over all runs of the [`FEATURES`]: `σ_min`, condition, input RMS,
    /// forgetting start, forgetting steps, smallest `λ`, the relative error and `tr(P)`
    /// when forgetting ends, `σ_min` over the forgetting steps.
    pub median: [f64; NF],
    /// The same medians over the slowest runs.
    pub slowest_median: [f64; NF],
    /// Spearman's correlation of the 1 % settling with each feature.
    pub rank_correlation: [f64; NF],
}

/// The features of a run in the order of [`FEATURES`].
fn feature_row(r: &RunFeatures) -> [f64; NF] {
    [
        r.excitation.sigma_min,
        r.excitation.condition(),
        r.excitation.input_rms,
        num(r.forget_start),
        r.forget_steps as f64,
        r.lambda_min,
        r.error_at_forget_end,
        r.trace_at_forget_end,
        r.sigma_min_forgetting,
    ]
}

/// Number of features compared ([`FEATURES`]).
pub const NF: usize = 9;

/// Names of the features.
pub const FEATURES: [&str; NF] = [
    "sigma_min(Phi)",
    "cond(Phi)",
    "input RMS",
    "forget start",
    "forget steps",
    "min lambda",
    "rel err at forget end",
    "tr P at forget end",
    "sigma_min forgetting",
];

/// The `count` slowest of `runs` against all of them (`None` when `runs` is empty).
pub fn contrast(runs: &[RunFeatures], count: usize) -> Option<Contrast> {
    if runs.is_empty() {
        return None;
    }
    let mut order: Vec<&RunFeatures> = runs.iter().collect();
    order.sort_by(|a, b| {
        num(b.settle)
            .total_cmp(&num(a.settle))
            .then(a.run.cmp(&b.run))
    });
    let slowest: Vec<RunFeatures> = order.iter().take(count.max(1)).map(|r| **r).collect();
    let medians = |set: &[RunFeatures]| -> [f64; NF] {
        std::array::from_fn(|j| {
            let mut col: Vec<f64> = set.iter().map(|r| feature_row(r)[j]).collect();
            percentile(&mut col, 0.5)
        })
    };
    let settle: Vec<f64> = runs.iter().map(|r| num(r.settle)).collect();
    Some(Contrast {
        median: medians(runs),
        slowest_median: medians(&slowest),
        rank_correlation: std::array::from_fn(|j| {
            let col: Vec<f64> = runs.iter().map(|r| feature_row(r)[j]).collect();
            spearman(&settle, &col)
        }),
        slowest,
    })
}

/// The contrast as text for the summary.
pub fn report(c: &Contrast, runs: usize) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nSlow runs (case 1 noiseless, RLS/FTVRF, {runs} runs; excitation over k = {CHANGE_STEP}..{}; \
         forgetting: lambda_k < 1 from k = {CHANGE_STEP}):",
        CHANGE_STEP + HORIZON - 1
    );
    let _ = writeln!(
        s,
        "{:>5} {:>20} {:>7} {:>6} {:>10} {:>10} {:>9} {:>9} {:>9} {:>8} {:>8} {:>10} {:>10}",
        "run",
        "seed",
        "settle",
        "10%",
        "sigma_min",
        "cond",
        "u RMS",
        "1st <1%",
        "forget@",
        "forget#",
        "min lam",
        "err@end",
        "trP@end"
    );
    for r in &c.slowest {
        let _ = writeln!(
            s,
            "{:>5} {:>20} {:>7} {:>6} {:>10.3} {:>10.1} {:>9.3} {:>9} {:>9} {:>8} {:>8.4} {:>10.3e} {:>10.3e}",
            r.run,
            r.seed,
            txt(r.settle),
            txt(r.settle_10),
            r.excitation.sigma_min,
            r.excitation.condition(),
            r.excitation.input_rms,
            txt(r.first_1),
            txt(r.forget_start),
            r.forget_steps,
            r.lambda_min,
            r.error_at_forget_end,
            r.trace_at_forget_end
        );
    }
    let _ = writeln!(
        s,
        "{:<18} median(all)  median(slowest)  Spearman(settle, feature)",
        "feature"
    );
    for (j, name) in FEATURES.iter().enumerate() {
        let _ = writeln!(
            s,
            "{:<18} {:>11.4} {:>16.4} {:>26.3}",
            name, c.median[j], c.slowest_median[j], c.rank_correlation[j]
        );
    }
    s
}

/// One sentence on what the slowest runs have in common, from the numbers of `c`: each
/// feature's median over the slowest runs against all runs, strongest rank correlation with
/// settling first; features constant over the runs are named apart.
pub fn why(c: &Contrast) -> String {
    let ids: Vec<String> = c.slowest.iter().map(|r| r.run.to_string()).collect();
    let settles: Vec<String> = c.slowest.iter().map(|r| txt(r.settle)).collect();
    let mut order: Vec<usize> = (0..NF)
        .filter(|&j| c.rank_correlation[j].is_finite())
        .collect();
    order.sort_by(|&a, &b| {
        c.rank_correlation[b]
            .abs()
            .total_cmp(&c.rank_correlation[a].abs())
    });
    let parts: Vec<String> = order
        .iter()
        .map(|&j| {
            format!(
                "{} {:.3} vs {:.3} ({:+.2})",
                FEATURES[j], c.slowest_median[j], c.median[j], c.rank_correlation[j]
            )
        })
        .collect();
    let constant: Vec<String> = (0..NF)
        .filter(|&j| !c.rank_correlation[j].is_finite())
        .map(|j| format!("{} {}", FEATURES[j], c.median[j]))
        .collect();
    let mut s = format!(
        "Slow runs: the {} slowest (runs {}; 1 % settling {} steps); their medians against all runs', \
         by Spearman correlation with settling (in brackets): {}",
        c.slowest.len(),
        ids.join(", "),
        settles.join(", "),
        parts.join(", ")
    );
    if !constant.is_empty() {
        let _ = write!(s, "; the same in every run: {}", constant.join(", "));
    }
    let _ = write!(
        s,
        " (excitation over the {HORIZON} steps from the change; forgetting = lambda_k < 1 from the change on, \
         its end = the first lambda_k = 1 after it)"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::forgetting::experiment::N;

    #[test]
    fn settling_readings_of_a_hand_made_error() {
        // Steps 90..=130: 1 until k = 104, 0.05 at 105..=107, 0.005 after except a blip
        // of 0.02 at 112.
        let ks: Vec<usize> = (90..=130).collect();
        let err: Vec<f64> = ks
            .iter()
            .map(|&k| match k {
                _ if k < 105 => 1.0,
                105..=107 => 0.05,
                112 => 0.02,
                _ => 0.005,
            })
            .collect();
        assert_eq!(stays_below(&ks, &err, 0.01), Some(13));
        assert_eq!(stays_below(&ks, &err, 0.1), Some(5));
        assert_eq!(first_below(&ks, &err, 0.01), Some(8));
        assert_eq!(first_below(&ks, &err, 0.1), Some(5));
        // Bad at the last step: never; good from the change on: 0.
        let mut late = err.clone();
        *late.last_mut().unwrap() = 1.0;
        assert_eq!(stays_below(&ks, &late, 0.01), None);
        let good = vec![0.0; ks.len()];
        assert_eq!(stays_below(&ks, &good, 0.01), Some(0));
        assert_eq!(first_below(&ks, &late[..10], 0.01), None);
    }

    #[test]
    fn spearman_of_known_rankings() {
        let x = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert!((spearman(&x, &[2.0, 4.0, 8.0, 16.0, 32.0]) - 1.0).abs() < 1e-12);
        assert!((spearman(&x, &[5.0, 4.0, 3.0, 2.0, 1.0]) + 1.0).abs() < 1e-12);
        // One swap among five: 1 − 6·2/(5·24) = 0.9.
        assert!((spearman(&x, &[1.0, 3.0, 2.0, 4.0, 5.0]) - 0.9).abs() < 1e-12);
        // "never" (+∞) ranks last.
        assert!((spearman(&[1.0, f64::INFINITY, 2.0], &[1.0, 3.0, 2.0]) - 1.0).abs() < 1e-12);
        assert!(spearman(&[1.0], &[1.0]).is_nan());
        assert!(spearman(&x, &[1.0; 5]).is_nan());
    }

    /// A trace whose estimate jumps to the truth at `k = 100 + at`, with `λ < 1` for
    /// `k = 100 + f0 .. 100 + f0 + 3` and unit regressor rows scaled by `gain`.
    fn trace(at: usize, f0: usize, gain: f64) -> Trace {
        let mut t = Trace::default();
        for k in 0..200 {
            t.ks.push(k);
            let truth = [1.0, 0.0, 0.0, 0.0, 0.0];
            t.truth.push(truth);
            t.theta.push(if k >= CHANGE_STEP + at {
                truth
            } else {
                [0.0; N]
            });
            t.trace_p.push(1.0);
            let forgetting = (CHANGE_STEP + f0..CHANGE_STEP + f0 + 3).contains(&k);
            t.lambda.push(if forgetting { 0.5 } else { 1.0 });
            t.error.push(0.0);
            t.phi
                .push(std::array::from_fn(|j| if j == k % N { gain } else { 0.0 }));
        }
        t
    }

    #[test]
    fn features_of_hand_made_traces_and_the_slowest_runs() {
        let f = features(3, 99, &trace(12, 2, 1.0)).unwrap();
        assert_eq!(
            (f.settle, f.settle_10, f.first_1, f.settle_visual),
            (Some(12), Some(12), Some(12), Some(12))
        );
        assert_eq!(
            (f.forget_start, f.forget_steps, f.lambda_min),
            (Some(2), 3, 0.5)
        );
        // 20 unit rows, 4 per direction: σ = 2 in every direction.
        assert!((f.excitation.sigma_min - 2.0).abs() < 1e-12);
        // A trace that ends before the horizon has no features.
        let mut short = trace(5, 0, 1.0);
        short.ks.truncate(110);
        short.phi.truncate(110);
        assert_eq!(features(0, 0, &short), None);
        // Slow runs are the weakly excited ones here: the contrast finds them.
        let runs: Vec<RunFeatures> = (0..10)
            .map(|i| {
                let slow = i >= 8;
                features(
                    i,
                    i,
                    &trace(
                        if slow { 40 } else { 10 + i as usize },
                        1,
                        if slow { 0.1 } else { 1.0 },
                    ),
                )
                .unwrap()
            })
            .collect();
        let c = contrast(&runs, 2).unwrap();
        let ids: Vec<u64> = c.slowest.iter().map(|r| r.run).collect();
        assert_eq!(ids, [8, 9]);
        assert!((c.slowest_median[0] - 0.2).abs() < 1e-12);
        assert!((c.median[0] - 2.0).abs() < 1e-12);
        assert!(c.rank_correlation[0] < -0.5, "{c:?}");
        assert!(report(&c, 10).contains("sigma_min"));
        let w = why(&c);
        assert!(
            w.contains("runs 8, 9")
                && w.contains("sigma_min(Phi) 0.200 vs 2.000")
                && w.contains("the same in every run: cond(Phi) 1, forget start 1"),
            "{w}"
        );
        assert_eq!(contrast(&[], 3), None);
    }
}
