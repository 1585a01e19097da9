//! The Monte Carlo's seeded runs ([`SeededRun`], each an item of a sharded stage), and
//! what is made of them after the gather: percentile bands and the summary statistics.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::study::forgetting::experiment::{
    Case, Method, N, RunSummary, Trace, Variant, recorded, run_seed, run_with,
};
use crate::study::forgetting::plant::Plant;

pub use control::linalg::percentile;

/// 5th, 50th and 95th percentile of one signal at one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Band {
    /// 5th percentile.
    pub p05: f64,
    /// Median.
    pub p50: f64,
    /// 95th percentile.
    pub p95: f64,
}

impl Band {
    /// The band of `v` (reordered).
    pub fn of(v: &mut [f64]) -> Self {
        Self {
            p05: percentile(v, 0.05),
            p50: percentile(v, 0.5),
            p95: percentile(v, 0.95),
        }
    }
}

/// Bands at every recorded step: `θ` components, `tr(P)`, `λ`, `e`.
#[derive(Debug, Clone, Default)]
pub struct Bands {
    /// Recorded steps.
    pub ks: Vec<usize>,
    /// True `θ` per step.
    pub truth: Vec<[f64; N]>,
    /// Bands of the `θ` components per step.
    pub theta: Vec<[Band; N]>,
    /// Band of `tr(P)` per step.
    pub trace_p: Vec<Band>,
    /// Band of `λ` per step.
    pub lambda: Vec<Band>,
    /// Band of `e` per step.
    pub error: Vec<Band>,
}

/// Aggregated statistics of a Monte Carlo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Summary {
    /// Number of runs.
    pub runs: usize,
    /// Median of the settling steps (`+∞`: "never").
    pub settle_median: f64,
    /// 95th percentile of the settling steps (`+∞`: "never").
    pub settle_p95: f64,
    /// The slowest run's settling steps (`+∞`: one never settles).
    pub settle_max: f64,
    /// Median of the settling steps at the 10 % threshold.
    pub settle_loose_median: f64,
    /// 95th percentile of the settling steps at the 10 % threshold.
    pub settle_loose_p95: f64,
    /// The slowest run's settling steps at the 10 % threshold.
    pub settle_loose_max: f64,
    /// Fraction of runs that never settle.
    pub never_fraction: f64,
    /// Fraction of runs with `λ_k < 1` for `τ_d + 1 ≤ k < 100`.
    pub early_forget_fraction: f64,
    /// Median over runs of `max_k tr(P_k)`.
    pub max_trace_median: f64,
    /// Largest `tr(P_k)` over all runs and steps.
    pub max_trace_max: f64,
    /// Median over runs of the final `tr(P)`.
    pub final_trace_median: f64,
    /// Total guard resets over all runs.
    pub resets: u64,
    /// Median of the steps after the change until the prior error has converged
    /// ([`super::experiment::error_settle`]; `+∞`: "never").
    pub error_settle_median: f64,
}

/// Summarizes per-run results.
pub fn summarize(runs: &[RunSummary]) -> Summary {
    let mut settle: Vec<f64> = runs
        .iter()
        .map(|r| r.settle.map_or(f64::INFINITY, |s| s as f64))
        .collect();
    let mut loose: Vec<f64> = runs
        .iter()
        .map(|r| r.settle_loose.map_or(f64::INFINITY, |s| s as f64))
        .collect();
    let mut error_settle: Vec<f64> = runs
        .iter()
        .map(|r| r.error_settle.map_or(f64::INFINITY, |s| s as f64))
        .collect();
    let mut max_tr: Vec<f64> = runs.iter().map(|r| r.max_trace).collect();
    let mut final_tr: Vec<f64> = runs.iter().map(|r| r.final_trace).collect();
    let n = runs.len().max(1) as f64;
    Summary {
        runs: runs.len(),
        settle_median: percentile(&mut settle, 0.5),
        settle_p95: percentile(&mut settle, 0.95),
        settle_max: settle.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        settle_loose_median: percentile(&mut loose, 0.5),
        settle_loose_p95: percentile(&mut loose, 0.95),
        settle_loose_max: loose.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        never_fraction: runs.iter().filter(|r| r.settle.is_none()).count() as f64 / n,
        early_forget_fraction: runs.iter().filter(|r| r.early_forget).count() as f64 / n,
        max_trace_median: percentile(&mut max_tr, 0.5),
        max_trace_max: max_tr.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        final_trace_median: percentile(&mut final_tr, 0.5),
        resets: runs.iter().map(|r| r.resets).sum(),
        error_settle_median: percentile(&mut error_settle, 0.5),
    }
}

/// Result of one Monte Carlo.
#[derive(Debug, Clone)]
pub struct MonteCarlo {
    /// Aggregated statistics.
    pub summary: Summary,
    /// Percentile bands (empty when not requested).
    pub bands: Bands,
}

/// One seeded run of a Monte Carlo, an item of a sharded stage
/// ([`crate::study::shard::Runs::map`]; its `Debug` text is its identity): run `run` of
/// `method` on `case` under `variant` with `steps` steps, seeded with
/// [`run_seed`]`(master, case, run)`, its trajectory recorded when `record` is set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeededRun {
    /// The case.
    pub case: Case,
    /// The estimator.
    pub method: Method,
    /// The noise and the prior error's convergence rule.
    pub variant: Variant,
    /// Steps.
    pub steps: usize,
    /// The run's index in its Monte Carlo.
    pub run: u64,
    /// Its seed ([`run_seed`]).
    pub seed: u64,
    /// Whether the trajectory is recorded (for the bands).
    pub record: bool,
}

impl SeededRun {
    /// The `runs` runs of `method` on `case` under `variant` with `steps` steps from the
    /// master seed `seed`, in run order; run `i` uses [`run_seed`]`(seed, case, i)`, so
    /// results do not depend on the thread count or on how the runs are sharded, and the
    /// methods and variants of a case meet the same inputs.
    pub fn all(
        case: Case,
        method: Method,
        variant: Variant,
        steps: usize,
        runs: usize,
        seed: u64,
        record: bool,
    ) -> Vec<SeededRun> {
        (0..runs as u64)
            .map(|run| SeededRun {
                case,
                method,
                variant,
                steps,
                run,
                seed: run_seed(seed, case, run),
                record,
            })
            .collect()
    }

    /// Runs it on `plant`: its summary and, when recorded, its trace (an error as its
    /// message).
    pub fn run_on(&self, plant: &Plant) -> Result<(RunSummary, Option<Trace>), String> {
        run_with(
            plant,
            self.case,
            &self.method.config(),
            self.variant,
            self.steps,
            self.seed,
            self.record,
        )
        .map_err(|e| e.to_string())
    }

    /// Simulates the run on `plant` (an error as its message).
    pub fn simulate(&self, plant: &Plant) -> Result<McRun, String> {
        let (summary, trace) = self.run_on(plant)?;
        Ok(McRun {
            summary,
            series: trace.map(Series::of),
        })
    }
}

/// What the bands need of one run's recorded trajectory: per recorded step its `θ`,
/// `tr(P)`, `λ` and `e` (the steps and the true `θ` are the same in every run of a case:
/// [`recorded_steps`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Series {
    /// Estimates, `N` per row.
    pub theta: Vec<[f64; N]>,
    /// `tr(P)` per row.
    pub trace_p: Vec<f64>,
    /// `λ_k` per row.
    pub lambda: Vec<f64>,
    /// Prior error `e_k` per row.
    pub error: Vec<f64>,
}

impl Series {
    /// The series of a recorded trace.
    pub fn of(t: Trace) -> Self {
        Self {
            theta: t.theta,
            trace_p: t.trace_p,
            lambda: t.lambda,
            error: t.error,
        }
    }
}

/// One seeded run's result: its summary and, when recorded, its series.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct McRun {
    /// The run's scalar results.
    pub summary: RunSummary,
    /// Its recorded series (`None` when not recorded).
    pub series: Option<Series>,
}

/// The recorded steps of a run of `steps` steps ([`recorded`]) and the true `θ` at each, as
/// a recorded [`Trace`] holds them.
pub fn recorded_steps(plant: &Plant, steps: usize) -> (Vec<usize>, Vec<[f64; N]>) {
    let ks: Vec<usize> = (0..steps).filter(|&k| recorded(k)).collect();
    let truth = ks.iter().map(|&k| *plant.theta_at(k)).collect();
    (ks, truth)
}

/// The Monte Carlo of the seeded runs `runs` (all of one case with `steps` steps): their
/// summary and, when `with_bands`, the percentile bands of their series.
pub fn aggregate(plant: &Plant, steps: usize, runs: &[McRun], with_bands: bool) -> MonteCarlo {
    let summaries: Vec<RunSummary> = runs.iter().map(|r| r.summary).collect();
    let summary = summarize(&summaries);
    let bands = if with_bands {
        let series: Vec<&Series> = runs.iter().filter_map(|r| r.series.as_ref()).collect();
        let (ks, truth) = recorded_steps(plant, steps);
        bands_of(&ks, &truth, &series)
    } else {
        Bands::default()
    };
    MonteCarlo { summary, bands }
}

/// Percentile bands over equally recorded series, at the recorded steps `ks` with the true
/// `θ` `truth`.
pub fn bands_of(ks: &[usize], truth: &[[f64; N]], series: &[&Series]) -> Bands {
    if series.is_empty() {
        return Bands::default();
    }
    let rows = ks.len();
    let per_row: Vec<([Band; N], Band, Band, Band)> = (0..rows)
        .into_par_iter()
        .map(|i| {
            let mut col = vec![0.0; series.len()];
            let mut th = [Band {
                p05: 0.0,
                p50: 0.0,
                p95: 0.0,
            }; N];
            for (j, b) in th.iter_mut().enumerate() {
                for (c, t) in col.iter_mut().zip(series) {
                    *c = t.theta[i][j];
                }
                *b = Band::of(&mut col);
            }
            let mut of = |f: &dyn Fn(&Series) -> f64| {
                for (c, t) in col.iter_mut().zip(series) {
                    *c = f(t);
                }
                Band::of(&mut col)
            };
            let tr = of(&|t| t.trace_p[i]);
            let la = of(&|t| t.lambda[i]);
            let er = of(&|t| t.error[i]);
            (th, tr, la, er)
        })
        .collect();
    Bands {
        ks: ks.to_vec(),
        truth: truth.to_vec(),
        theta: per_row.iter().map(|r| r.0).collect(),
        trace_p: per_row.iter().map(|r| r.1).collect(),
        lambda: per_row.iter().map(|r| r.2).collect(),
        error: per_row.iter().map(|r| r.3).collect(),
    }
}

/// [`SeededRun::all`] simulated here and [`aggregate`]d: the Monte Carlo of `runs` runs of
/// `method` on `case` (the tests' shortcut; the study hands its runs to its stages).
#[cfg(test)]
pub fn monte_carlo(
    plant: &Plant,
    case: Case,
    method: Method,
    steps: usize,
    runs: usize,
    seed: u64,
    with_bands: bool,
) -> Result<MonteCarlo, String> {
    let items = SeededRun::all(case, method, Variant::STUDY, steps, runs, seed, with_bands);
    let results: Vec<McRun> = items
        .par_iter()
        .map(|r| r.simulate(plant))
        .collect::<Result<_, _>>()?;
    Ok(aggregate(plant, steps, &results, with_bands))
}

/// The summary of `runs` runs of `method` on `case` under `variant` (no bands), simulated
/// here (the tests' shortcut).
#[cfg(test)]
pub fn monte_carlo_variant(
    plant: &Plant,
    case: Case,
    method: Method,
    variant: Variant,
    runs: usize,
    seed: u64,
) -> Result<Summary, String> {
    let items = SeededRun::all(case, method, variant, case.steps(), runs, seed, false);
    let results: Vec<McRun> = items
        .par_iter()
        .map(|r| r.simulate(plant))
        .collect::<Result<_, _>>()?;
    Ok(aggregate(plant, case.steps(), &results, false).summary)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::forgetting::experiment::settle_of_sequence;
    use crate::study::forgetting::plant::CHANGE_STEP as K0;

    #[test]
    fn percentiles_of_a_hand_made_sequence() {
        let mut v = vec![5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(percentile(&mut v, 0.5), 3.0);
        assert_eq!(percentile(&mut v, 0.0), 1.0);
        assert_eq!(percentile(&mut v, 1.0), 5.0);
        assert_eq!(percentile(&mut v, 0.25), 2.0);
        assert!((percentile(&mut v, 0.95) - 4.8).abs() < 1e-12);
        let mut w = vec![1.0, f64::INFINITY, 2.0];
        assert_eq!(percentile(&mut w, 0.5), 2.0);
        assert_eq!(percentile(&mut w, 1.0), f64::INFINITY);
    }

    #[test]
    fn settling_of_a_hand_made_sequence() {
        // Error 1 before the change, 0.5 until k0 + 7, a blip at k0 + 12, then converged.
        let mut err = vec![1.0; 200];
        for (k, e) in err.iter_mut().enumerate().skip(K0) {
            *e = if k < K0 + 7 || k == K0 + 12 {
                0.5
            } else {
                0.001
            };
        }
        assert_eq!(settle_of_sequence(&err), Some(13));
        // Converged from the change on.
        let mut ok = vec![1.0; 150];
        ok[K0..].fill(0.0);
        assert_eq!(settle_of_sequence(&ok), Some(0));
        // Not converged at the last step: never.
        let mut late = ok.clone();
        *late.last_mut().unwrap() = 0.02;
        assert_eq!(settle_of_sequence(&late), None);
        // NaN counts as not converged.
        let mut nan = ok.clone();
        nan[K0 + 3] = f64::NAN;
        assert_eq!(settle_of_sequence(&nan), Some(4));
    }

    #[test]
    fn summary_of_hand_made_runs() {
        let r = |settle: Option<usize>, early: bool, tr: f64| RunSummary {
            settle,
            settle_loose: settle,
            early_forget: early,
            max_trace: tr,
            final_trace: tr / 2.0,
            resets: 0,
            error_settle: settle,
        };
        let runs = [
            r(Some(10), false, 500.0),
            r(Some(20), true, 600.0),
            r(None, false, 700.0),
            r(Some(30), false, 800.0),
        ];
        let s = summarize(&runs);
        assert_eq!(s.runs, 4);
        assert_eq!(s.settle_median, 25.0);
        assert_eq!(s.settle_p95, f64::INFINITY);
        assert_eq!(s.settle_max, f64::INFINITY);
        assert_eq!(summarize(&runs[..2]).settle_max, 20.0);
        assert_eq!(summarize(&runs[..2]).settle_loose_max, 20.0);
        assert_eq!(s.never_fraction, 0.25);
        assert_eq!(s.early_forget_fraction, 0.25);
        assert_eq!(s.max_trace_median, 650.0);
        assert_eq!(s.max_trace_max, 800.0);
        assert_eq!(s.error_settle_median, 25.0);
    }

    /// The chapter's qualitative finding (§5.3.1, Figures 5.1–5.2): without noise,
    /// RLS/FTVRF converges within 50 steps of the change; RLS/CRF (λ = 0.99) does not.
    #[test]
    fn ftvrf_converges_after_the_change_and_crf_does_not() {
        let plant = Plant::chapter().unwrap();
        let runs = 50;
        let ft = monte_carlo(&plant, Case::Noiseless, Method::Ftvrf, 300, runs, 42, false)
            .unwrap()
            .summary;
        assert!(ft.settle_median <= 50.0, "{ft:?}");
        assert!(ft.settle_p95 <= 50.0, "{ft:?}");
        assert_eq!(ft.early_forget_fraction, 0.0, "{ft:?}");
        let crf = monte_carlo(&plant, Case::Noiseless, Method::Crf, 300, runs, 42, false)
            .unwrap()
            .summary;
        // Not a single run of RLS/CRF settles within 50 steps (5th percentile > 50).
        let results: Vec<RunSummary> = (0..runs as u64)
            .map(|i| {
                crate::study::forgetting::experiment::run(
                    &plant,
                    Case::Noiseless,
                    Method::Crf,
                    300,
                    crate::study::forgetting::experiment::run_seed(42, Case::Noiseless, i),
                    false,
                )
                .unwrap()
                .0
            })
            .collect();
        assert!(
            results.iter().all(|r| r.settle.is_none_or(|s| s > 50)),
            "{crf:?}"
        );
        assert!(crf.settle_median > 50.0, "{crf:?}");
    }

    /// §5.3.3 (Figures 5.7–5.8): with a non-persistent input, tr(P) stays bounded for
    /// RLS/FTVRF and grows without bound for RLS/CRF.
    #[test]
    fn nonpersistent_input_keeps_ftvrf_trace_bounded() {
        let plant = Plant::chapter().unwrap();
        let ft = monte_carlo(
            &plant,
            Case::Nonpersistent,
            Method::Ftvrf,
            2000,
            20,
            7,
            false,
        )
        .unwrap()
        .summary;
        assert!(ft.max_trace_max < 1e4, "{ft:?}");
        let crf = monte_carlo(&plant, Case::Nonpersistent, Method::Crf, 2000, 20, 7, false)
            .unwrap()
            .summary;
        assert!(crf.final_trace_median > 1e6, "{crf:?}");
    }

    /// The bands' steps and true `θ`, taken from the plant, are those a recorded run holds.
    #[test]
    fn recorded_steps_are_those_of_a_recorded_run() {
        let plant = Plant::chapter().unwrap();
        for case in Case::ALL {
            let (_, t) = crate::study::forgetting::experiment::run(
                &plant,
                case,
                Method::Crf,
                case.steps(),
                5,
                true,
            )
            .unwrap();
            let t = t.unwrap();
            let (ks, truth) = recorded_steps(&plant, case.steps());
            assert_eq!(ks, t.ks);
            assert_eq!(truth, t.truth);
        }
    }

    #[test]
    fn monte_carlo_is_reproducible() {
        let plant = Plant::chapter().unwrap();
        let a = monte_carlo(&plant, Case::Noisy, Method::Ftvrf, 150, 8, 3, true).unwrap();
        let b = monte_carlo(&plant, Case::Noisy, Method::Ftvrf, 150, 8, 3, true).unwrap();
        assert_eq!(a.summary, b.summary);
        assert_eq!(a.bands.theta, b.bands.theta);
        let c = monte_carlo(&plant, Case::Noisy, Method::Ftvrf, 150, 8, 4, true).unwrap();
        assert_ne!(a.bands.theta, c.bands.theta);
    }
}
