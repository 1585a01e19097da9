//! Helpers shared by the unit tests of the math kernels (compiled for tests only): a
//! seeded random source, the forgetting rules and model and horizon parameters the tests
//! build again and again, and error measures.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use crate::forgetting::ForgettingRule;
use crate::mpc::condense::{MoveBounds, MpcSpec, Weight};
use crate::pcac::{IdKernel, IoModelParams};

/// A seeded source of uniform and standard normal numbers for reproducible tests.
pub struct Gauss(ChaCha8Rng);

impl Gauss {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(ChaCha8Rng::seed_from_u64(seed))
    }
    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        self.0.sample(StandardNormal)
    }
    /// `len` standard normal numbers.
    pub fn vec(&mut self, len: usize) -> Vec<f64> {
        (0..len).map(|_| self.normal()).collect()
    }
}

/// F-test forgetting (Algorithm 1) with the windows `τn`, `τd`, the gain `η` and the
/// significance level `α`.
pub fn f_test(tau_n: usize, tau_d: usize, eta: f64, alpha: f64) -> ForgettingRule {
    ForgettingRule::FTest {
        tau_n,
        tau_d,
        eta,
        alpha,
    }
}

/// The two rules that Proposition 5.2.1 makes equal, with the same windows and gain:
/// F-test forgetting at `α = 1 − F_{τn,τd}(1)`, and RMS-ratio forgetting.
pub fn proposition_5_2_1_rules(
    tau_n: usize,
    tau_d: usize,
    eta: f64,
) -> (ForgettingRule, ForgettingRule) {
    let alpha = 1.0
        - FisherSnedecor::new(tau_n as f64, tau_d as f64)
            .unwrap()
            .cdf(1.0);
    (
        f_test(tau_n, tau_d, eta, alpha),
        ForgettingRule::RmsRatio { tau_n, tau_d, eta },
    )
}

/// PCAC's identified model (2.24) of order `n̂` with `p` outputs and `m` inputs: `θ_0 = 0`,
/// `P_0 = 100 I`, no trace limit.
pub fn io_model_params(
    n_hat: usize,
    p: usize,
    m: usize,
    rule: ForgettingRule,
    kernel: IdKernel,
) -> IoModelParams {
    IoModelParams {
        n_hat,
        p,
        m,
        theta0: Vec::new(),
        p0: 100.0,
        rule,
        trace_limit: f64::INFINITY,
        kernel,
    }
}

/// A SISO receding-horizon problem that tracks its one output with the weights `q`, `r`,
/// the input bounds `±u_max` and the move bounds `±du_max`, without output constraints.
pub fn siso_mpc_spec(horizon: usize, q: f64, r: f64, u_max: f64, du_max: f64) -> MpcSpec {
    MpcSpec {
        horizon,
        n_inputs: 1,
        n_outputs: 1,
        n_tracked: 1,
        tracking: vec![1.0],
        q: Weight::Scalar(q),
        r: Weight::Scalar(r),
        u_min: vec![-u_max],
        u_max: vec![u_max],
        move_bounds: Some(MoveBounds::symmetric(du_max, 1)),
        output_constraints: None,
        input_notch: None,
    }
}

/// The largest `|a_i − b_i|` (the lengths must agree).
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// The largest `|a_i|`.
pub fn max_abs(a: &[f64]) -> f64 {
    a.iter().map(|x| x.abs()).fold(0.0, f64::max)
}
