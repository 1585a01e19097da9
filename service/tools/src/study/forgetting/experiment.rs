//! The three cases of §5.3 and the three estimators compared there, and one simulation run.

use control::forgetting::ForgettingRule;
use control::rls::{Rls, RlsConfig};

use crate::study::common::convergence::{convergence_time, rms};
use crate::study::forgetting::ForgettingError;
use crate::study::forgetting::plant::{CHANGE_STEP, Plant, dot, regressor};
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Number of parameters `n`.
pub const N: usize = 5;
/// Short window `τ_n`.
pub const TAU_N: usize = 10;
/// Long window `τ_d`.
pub const TAU_D: usize = 80;
/// Forgetting gain `η`.
pub const ETA: f64 = 1.0;
/// Significance level `α`.
pub const ALPHA: f64 = 0.001;
/// Constant forgetting factor of RLS/CRF.
pub const LAMBDA_CRF: f64 = 0.99;
/// Initial covariance `P_0 = 100 I`.
pub const P0: f64 = 100.0;
/// Variance of the measurement noise `v_k ~ N(0, 0.05)`.
pub const NOISE_VAR: f64 = 0.05;

/// The experiments of §5.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    /// §5.3.1: `u_k ~ N(0, 1)`, noiseless measurements.
    Noiseless,
    /// §5.3.2: `u_k ~ N(0, 1)`, `v_k ~ N(0, 0.05)` added to `y_k`.
    Noisy,
    /// §5.3.3, (5.9): `u_k ~ N(0, 1)` for `k < 100`, `u_k = 0` afterwards, noisy measurements.
    Nonpersistent,
}

impl Case {
    /// All cases in the chapter's order.
    pub const ALL: [Case; 3] = [Case::Noiseless, Case::Noisy, Case::Nonpersistent];

    /// Short name used in file names.
    pub fn name(self) -> &'static str {
        match self {
            Case::Noiseless => "noiseless",
            Case::Noisy => "noisy",
            Case::Nonpersistent => "nonpersistent",
        }
    }

    /// Case number (1–3) used in labels and seeds.
    pub fn number(self) -> u64 {
        match self {
            Case::Noiseless => 1,
            Case::Noisy => 2,
            Case::Nonpersistent => 3,
        }
    }

    /// Default run length in steps.
    pub fn steps(self) -> usize {
        match self {
            Case::Noiseless | Case::Noisy => 300,
            Case::Nonpersistent => 5000,
        }
    }

    /// Standard deviation of the measurement noise.
    pub fn noise_std(self) -> f64 {
        match self {
            Case::Noiseless => 0.0,
            Case::Noisy | Case::Nonpersistent => NOISE_VAR.sqrt(),
        }
    }

    /// The input at step `k` given a fresh standard normal sample `z`.
    pub fn input(self, k: usize, z: f64) -> f64 {
        match self {
            Case::Nonpersistent if k >= CHANGE_STEP => 0.0,
            _ => z,
        }
    }
}

/// The estimators of §5.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// RLS with F-test variable-rate forgetting (Algorithm 1).
    Ftvrf,
    /// RLS with constant-rate forgetting `λ = 0.99`.
    Crf,
    /// RLS with RMS-ratio variable-rate forgetting (Proposition 5.2.1).
    Rmsvrf,
}

impl Method {
    /// All methods.
    pub const ALL: [Method; 3] = [Method::Ftvrf, Method::Crf, Method::Rmsvrf];

    /// Short name used in file names and tables.
    pub fn name(self) -> &'static str {
        match self {
            Method::Ftvrf => "ftvrf",
            Method::Crf => "crf",
            Method::Rmsvrf => "rmsvrf",
        }
    }

    /// Display label.
    pub fn label(self) -> &'static str {
        match self {
            Method::Ftvrf => "RLS/FTVRF",
            Method::Crf => "RLS/CRF",
            Method::Rmsvrf => "RLS/RMSVRF",
        }
    }

    /// The forgetting rule with the chapter's parameters.
    pub fn rule(self) -> ForgettingRule {
        match self {
            Method::Ftvrf => ForgettingRule::FTest {
                tau_n: TAU_N,
                tau_d: TAU_D,
                eta: ETA,
                alpha: ALPHA,
            },
            Method::Crf => ForgettingRule::Constant { lambda: LAMBDA_CRF },
            Method::Rmsvrf => ForgettingRule::RmsRatio {
                tau_n: TAU_N,
                tau_d: TAU_D,
                eta: ETA,
            },
        }
    }

    /// The RLS configuration: `θ_0 = 0`, `P_0 = 100 I`, no trace guard (the study wants to
    /// see unbounded growth).
    pub fn config(self) -> RlsConfig {
        RlsConfig {
            n: N,
            p: 1,
            theta0: vec![0.0; N],
            p0: P0,
            rule: self.rule(),
            trace_limit: f64::INFINITY,
        }
    }
}

/// Relative parameter error below which an estimate counts as converged.
pub const CONVERGED: f64 = 0.01;
/// A looser threshold also reported: with noisy measurements the equation-error estimate
/// is biased (noise enters the regressor), so 1 % may never be reached by any method.
pub const CONVERGED_LOOSE: f64 = 0.10;

/// Per-run scalar results.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunSummary {
    /// Steps after the change until `‖θ_k − θ_true‖/‖θ_true‖` stays below 1 % through the
    /// end of the run; `None` when it does not.
    pub settle: Option<usize>,
    /// The same with the threshold [`CONVERGED_LOOSE`] (10 %).
    pub settle_loose: Option<usize>,
    /// Whether `λ_k < 1` for some `τ_d + 1 ≤ k < 100` (forgetting before the change).
    pub early_forget: bool,
    /// `max_k tr(P_k)`.
    pub max_trace: f64,
    /// `tr(P)` at the end of the run.
    pub final_trace: f64,
    /// Number of guard resets of the estimator.
    pub resets: u64,
    /// Steps after the change until the prior error `e_k` has converged
    /// ([`error_settle`]); `None` when it has not by the end.
    pub error_settle: Option<usize>,
}

/// Trailing window of the prior error's convergence ([`error_settle`]), steps.
pub const ERROR_WINDOW: usize = 10;

/// The bound of the prior error's convergence ([`error_settle`]), times its late RMS.
pub const ERROR_BOUND: f64 = 2.0;

/// Steps after the change until the prior error `errs[k]` (one per step from 0) has
/// converged: [`convergence_time`] of `e_k` from the change on, trailing windows of
/// `window` steps (the study's: [`ERROR_WINDOW`]), against `bound` (the study's:
/// [`ERROR_BOUND`]) times its RMS over the last third of the run (the level the noise
/// leaves). `None` when it has not converged by the end.
pub fn error_settle(errs: &[f64], window: usize, bound: f64) -> Option<usize> {
    let after = errs.get(CHANGE_STEP..)?;
    let late = rms(&errs[errs.len() - errs.len() / 3..]);
    // convergence_time's bound is twice its target.
    convergence_time(after, 1.0, window, late * bound / 2.0).map(|t| t.round() as usize)
}

/// What a run may change from its case as the study reads the chapter (the sensitivity
/// of the claims, [`super::sensitivity`]): the measurement noise and the prior error's
/// convergence rule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Variant {
    /// The standard deviation of the measurement noise (`None`: the case's,
    /// [`Case::noise_std`]).
    pub noise_std: Option<f64>,
    /// The trailing window of [`error_settle`], steps.
    pub error_window: usize,
    /// The bound of [`error_settle`], times the late RMS.
    pub error_bound: f64,
}

impl Variant {
    /// The study's reading.
    pub const STUDY: Variant = Variant {
        noise_std: None,
        error_window: ERROR_WINDOW,
        error_bound: ERROR_BOUND,
    };
}

/// A recorded trajectory: row `i` is step `ks[i]`, with the estimate after the update that
/// used `y_k` (the chapter's `θ_{k+1}`), the true `θ` generating `y_k`, `tr(P)` after the
/// update, the `λ_k` used and the prior error `e_k`.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    /// Recorded steps.
    pub ks: Vec<usize>,
    /// Estimates, `N` per row.
    pub theta: Vec<[f64; N]>,
    /// True parameters, `N` per row.
    pub truth: Vec<[f64; N]>,
    /// `tr(P)` per row.
    pub trace_p: Vec<f64>,
    /// `λ_k` per row.
    pub lambda: Vec<f64>,
    /// Prior error `e_k` per row.
    pub error: Vec<f64>,
    /// The regressor `φ_k` (as measured) that the update of the row used.
    pub phi: Vec<[f64; N]>,
}

/// Which steps to record: every step up to 400, then every 10th (keeps the long
/// non-persistent Monte Carlo small).
#[allow(
    clippy::manual_is_multiple_of,
    reason = "usize::is_multiple_of is newer than the workspace rust-version"
)]
pub fn recorded(k: usize) -> bool {
    k <= 400 || k % 10 == 0
}

/// Seed of run `run` of `case` (shared by the methods: common random numbers).
pub fn run_seed(master: u64, case: Case, run: u64) -> u64 {
    // One ChaCha stream per (case, run) of the master seed.
    let mut r = ChaCha8Rng::seed_from_u64(master);
    r.set_stream((case.number() << 32) | run);
    r.next_u64()
}

/// Simulates one run of `method` on `case` with `steps` steps and the given seed; returns
/// the summary and, when `record` is set, the recorded trajectory.
pub fn run(
    plant: &Plant,
    case: Case,
    method: Method,
    steps: usize,
    seed: u64,
    record: bool,
) -> Result<(RunSummary, Option<Trace>), ForgettingError> {
    run_with(
        plant,
        case,
        &method.config(),
        Variant::STUDY,
        steps,
        seed,
        record,
    )
}

/// [`run`] with the estimator's settings `config` instead of a method's printed ones (the
/// other readings of §5.3's settings, [`super::readings`]) and the `variant` of the noise
/// and the error's convergence rule; the input and the plant are those of `case` and
/// `seed`, so runs with the same seed see the same input.
pub fn run_with(
    plant: &Plant,
    case: Case,
    config: &RlsConfig,
    variant: Variant,
    steps: usize,
    seed: u64,
    record: bool,
) -> Result<(RunSummary, Option<Trace>), ForgettingError> {
    let mut rls = Rls::new(config).map_err(ForgettingError::Rls)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = variant.noise_std.unwrap_or(case.noise_std());
    let mut u = vec![0.0; steps];
    let mut y_true = vec![0.0; steps];
    let mut y_meas = vec![0.0; steps];
    let mut phi = [0.0; N];
    let mut phi_meas = [0.0; N];
    let mut trace = record.then(Trace::default);
    let mut last_bad: Option<usize> = None;
    let mut last_bad_loose: Option<usize> = None;
    let mut early_forget = false;
    let mut max_trace = rls.trace_p();
    let mut resets = 0;
    let mut errs = Vec::with_capacity(steps);
    for k in 0..steps {
        let z: f64 = rng.sample(StandardNormal);
        let v: f64 = rng.sample(StandardNormal);
        u[k] = case.input(k, z);
        regressor(&y_true, &u, k, &mut phi);
        let truth = plant.theta_at(k);
        y_true[k] = dot(truth, &phi);
        y_meas[k] = y_true[k] + noise * v;
        regressor(&y_meas, &u, k, &mut phi_meas);
        let step = rls.update(&phi_meas, &y_meas[k..=k]);
        if step.reset {
            resets += 1;
        }
        errs.push(rls.prior_error()[0]);
        let th = rls.theta();
        let tr = rls.trace_p();
        max_trace = max_trace.max(tr);
        if (TAU_D + 1..CHANGE_STEP).contains(&k) && step.lambda < 1.0 {
            early_forget = true;
        }
        if k >= CHANGE_STEP {
            let num: f64 = th.iter().zip(truth).map(|(a, b)| (a - b).powi(2)).sum();
            let den: f64 = truth.iter().map(|b| b * b).sum();
            let rel = (num / den).sqrt();
            if !below(rel, CONVERGED) {
                last_bad = Some(k);
            }
            if !below(rel, CONVERGED_LOOSE) {
                last_bad_loose = Some(k);
            }
        }
        if let Some(t) = trace.as_mut().filter(|_| recorded(k)) {
            let mut est = [0.0; N];
            est.copy_from_slice(th);
            t.ks.push(k);
            t.theta.push(est);
            t.truth.push(*truth);
            t.trace_p.push(tr);
            t.lambda.push(step.lambda);
            t.error.push(rls.prior_error()[0]);
            t.phi.push(phi_meas);
        }
    }
    Ok((
        RunSummary {
            settle: settle_steps(steps, last_bad),
            settle_loose: settle_steps(steps, last_bad_loose),
            early_forget,
            max_trace,
            final_trace: rls.trace_p(),
            resets,
            error_settle: error_settle(&errs, variant.error_window, variant.error_bound),
        },
        trace,
    ))
}

/// Steps after the change until the error stays converged, from the last non-converged
/// step `last_bad` (`None`: converged already at the change). `None` when the last step
/// of the run is not converged.
pub fn settle_steps(steps: usize, last_bad: Option<usize>) -> Option<usize> {
    match last_bad {
        None => Some(0),
        Some(k) if k + 1 >= steps => None,
        Some(k) => Some(k + 1 - CHANGE_STEP),
    }
}

/// Steps after the change until `err` (indexed by step `k`, starting at 0) stays below
/// [`CONVERGED`] through its end; `None` when its last value is not below.
pub fn settle_of_sequence(err: &[f64]) -> Option<usize> {
    let last_bad = (CHANGE_STEP..err.len())
        .rev()
        .find(|&k| !below(err[k], CONVERGED));
    settle_steps(err.len(), last_bad)
}

/// `x < threshold`, false for NaN.
fn below(x: f64, threshold: f64) -> bool {
    x.partial_cmp(&threshold) == Some(std::cmp::Ordering::Less)
}
