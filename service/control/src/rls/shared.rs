//! RLS with `p` right-hand sides sharing one covariance: the Kronecker-reduced form of
//! (2.30)–(2.32) that PCAC's identification uses.
//!
//! When the regressor is `φ_k = ψ_k ⊗ I_p` and `P_0 = p0 I`, the covariance keeps the
//! form `P_k = P̃_k ⊗ I_p` (derivation in `pcac::model`), and with `g_k = P̃_k ψ_kᵀ`,
//! `d_k = 1 + β_k ψ_k g_k` one step is
//!
//! ```text
//! z_k = y_k − Θ̃_k ψ_kᵀ                                      (2.26)
//! P̃_{k+1} = β_k P̃_k − (β_k² / d_k) g_k g_kᵀ                 (2.31)
//! Θ̃_{k+1} = Θ̃_k + (β_k / d_k) z_k g_kᵀ                      (2.32)
//! ```
//!
//! with `β_k = 1/λ_k` from the forgetting rule fed with `z_k`. The prior error, the
//! forgetting and the guard (non-finite data, `d_k ≤ 0`, a non-positive or non-finite
//! covariance, `tr P` above its limit: reset to `Θ̃_0, P̃_0`) are those of [`Rls`](super::Rls).
//!
//! The covariance update is [`Rls`](super::Rls)'s kernel with one row: with
//! `w_k = (β_k / √d_k) g_k`, (2.31) is `P̃_{k+1} = β_k P̃_k − w_k w_kᵀ`, and it is deferred
//! to step `k + 1`, whose one sweep over the packed triangle applies it and forms
//! `g_{k+1}` (the AVX2/FMA sweep when the processor has it); the diagonal and trace of
//! `P̃_{k+1}` are computed and guarded in step `k`, an off-diagonal overflow in the sweep
//! of step `k + 1` (the "Guard" of [`Rls`](super::Rls)).

use nalgebra::DMatrix;

use super::{RlsStep, applied_covariance, data_finite, guard_passes, prior_errors, simd};
use crate::forgetting::{Forgetting, ForgettingRule};
use crate::linalg::{axpy, dot};

/// Scalar-row RLS with `p` right-hand sides sharing one covariance `P̃` (see the module
/// docs), with the prior error, forgetting and guard of [`Rls`](super::Rls).
#[derive(Debug, Clone)]
pub struct SharedRls {
    n: usize,
    p: usize,
    p0: f64,
    trace_limit: f64,
    forgetting: Forgetting,
    /// `Θ̃_0`, p×n row-major.
    theta0: Vec<f64>,
    /// `Θ̃_k`, p×n row-major.
    theta: Vec<f64>,
    /// `Q`, upper triangle row-packed (row `i` has `n − i` entries, diagonal first), with
    /// `P̃_k = β Q − w wᵀ` (the deferred update, module docs).
    cov: Vec<f64>,
    /// The deferred update's `w` (`n`).
    w_pend: Vec<f64>,
    /// The deferred update's `β`.
    beta_pend: f64,
    /// `tr P̃_k`.
    trace: f64,
    /// `g = P̃_k ψᵀ`, then `w_k`.
    g: Vec<f64>,
    /// The sweep's instruction set.
    level: simd::Level,
    /// Prior error `z_k`.
    err: Vec<f64>,
    resets: u64,
}

impl SharedRls {
    /// `n` regressors, `p` outputs, `Θ̃_0` as `p × n` row-major, `P̃_0 = p0 I`, forgetting
    /// `rule` and the guard's limit on `tr P = p tr P̃`.
    pub fn new(
        n: usize,
        p: usize,
        theta0_rows: Vec<f64>,
        p0: f64,
        rule: &ForgettingRule,
        trace_limit: f64,
    ) -> Result<Self, String> {
        let mut s = Self {
            n,
            p,
            p0,
            trace_limit,
            forgetting: Forgetting::new(rule, p)?,
            theta: theta0_rows.clone(),
            theta0: theta0_rows,
            cov: vec![0.0; n * (n + 1) / 2],
            w_pend: vec![0.0; n],
            beta_pend: 1.0,
            trace: 0.0,
            g: vec![0.0; n],
            level: simd::Level::detect(),
            err: vec![0.0; p],
            resets: 0,
        };
        s.reset();
        Ok(s)
    }

    /// Empties the forgetting windows (the data history) and keeps `Θ̃_k` and `P̃_k`, for a
    /// new data stream ([`crate::learned`]). Does not allocate.
    pub fn restart_data(&mut self) {
        self.forgetting.reset();
        self.err.fill(0.0);
    }

    /// Back to `Θ̃_0`, `P̃_0` and the forgetting rule's initial state.
    pub fn reset(&mut self) {
        self.theta.copy_from_slice(&self.theta0);
        super::fill_packed_identity(&mut self.cov, self.n, self.p0);
        self.w_pend.fill(0.0);
        self.beta_pend = 1.0;
        self.trace = self.n as f64 * self.p0;
        self.forgetting.reset();
    }

    fn fail(&mut self, lambda: f64, error_norm: f64) -> RlsStep {
        self.resets += 1;
        self.reset();
        RlsStep::guard_reset(lambda, error_norm)
    }

    /// One step of (2.30)–(2.32) in the reduced form; `psi` has length `n`, `y` length `p`.
    pub fn update(&mut self, psi: &[f64], y: &[f64]) -> RlsStep {
        let (n, p) = (self.n, self.p);
        if !data_finite(psi, y) {
            self.err.fill(0.0);
            return self.fail(1.0, f64::INFINITY);
        }
        // z_k = y_k − Θ̃_k ψ_kᵀ (2.26).
        let theta = &self.theta;
        let (error_norm, y2) =
            prior_errors(y, &mut self.err, |l| dot(&theta[l * n..(l + 1) * n], psi));
        let beta = self.forgetting.beta_scaled(&self.err, y2);
        let lambda = 1.0 / beta;

        // P̃_k = β_{k−1} Q − w_{k−1} w_{k−1}ᵀ (the deferred update) and g = P̃_k ψᵀ, in one
        // sweep that also checks every entry it writes.
        let pending = simd::Pending {
            w: &self.w_pend,
            beta: self.beta_pend,
            n,
            p: 1,
        };
        if !simd::fused_pass(self.level, &mut self.cov, pending, psi, &mut self.g) {
            return self.fail(lambda, error_norm);
        }
        let s = dot(psi, &self.g);
        let d = 1.0 + beta * s;
        if !(d > 0.0 && d.is_finite()) {
            return self.fail(lambda, error_norm);
        }
        // Θ̃_{k+1} = Θ̃_k + z_k (β/d) gᵀ (2.32).
        let kf = beta / d;
        for l in 0..p {
            axpy(
                kf * self.err[l],
                &self.g,
                &mut self.theta[l * n..(l + 1) * n],
            );
        }
        // w_k = (β/√d) g: P̃_{k+1} = β P̃_k − w_k w_kᵀ (2.31), deferred to the next sweep; its
        // diagonal and trace now, exactly as the sweep will store them.
        let scale = beta / d.sqrt();
        for v in &mut self.g {
            *v *= scale;
        }
        let next = simd::Pending {
            w: &self.g,
            beta,
            n,
            p: 1,
        };
        let (trace, min_diag, diag_ok) = simd::next_diag(self.level, &self.cov, next);
        if !guard_passes(
            &self.theta,
            diag_ok,
            min_diag,
            p as f64 * trace,
            self.trace_limit,
        ) {
            return self.fail(lambda, error_norm);
        }
        std::mem::swap(&mut self.g, &mut self.w_pend);
        self.beta_pend = beta;
        self.trace = trace;
        RlsStep::accepted(lambda, error_norm)
    }

    /// Number of regressors `n`.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of outputs `p`.
    pub fn p(&self) -> usize {
        self.p
    }

    /// `Θ̃_k`, `p × n` row-major.
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// The prior error `z_k` of the last update.
    pub fn prior_error(&self) -> &[f64] {
        &self.err
    }

    /// `tr P̃_k` (so `tr P_k = p tr P̃_k`).
    pub fn trace_p_tilde(&self) -> f64 {
        self.trace
    }

    /// `P̃_k` (n×n, exactly symmetric), with the deferred update applied as the next
    /// step will apply it. Allocates: for tests and inspection.
    pub fn covariance(&self) -> DMatrix<f64> {
        applied_covariance(self.level, &self.cov, self.pending())
    }

    fn pending(&self) -> simd::Pending<'_> {
        simd::Pending {
            w: &self.w_pend,
            beta: self.beta_pend,
            n: self.n,
            p: 1,
        }
    }

    /// Visits what the estimator learned as the blocks of a checkpoint
    /// ([`crate::learned`]): `theta` (Θ̃_k, row-major), `Q` (the packed triangle), `w` (the
    /// deferred update) and `beta-trace` (`[β, tr P̃_k]`), with `P̃_k = β Q − w wᵀ`. Does not
    /// allocate.
    pub fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        visit("theta", &self.theta);
        visit("Q", &self.cov);
        visit("w", &self.w_pend);
        visit("beta-trace", &[self.beta_pend, self.trace]);
    }

    /// Takes back the blocks of [`SharedRls::learned`] and restarts the forgetting rule;
    /// the estimator then continues exactly as the saved one would have. Allocates (it
    /// checks that P̃_k is positive definite).
    ///
    /// # Errors
    ///
    /// A missing, mis-sized or non-finite block, a covariance that is not positive
    /// definite or whose trace the guard would refuse; the estimator is then at `Θ̃_0`, `P̃_0`.
    pub fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let n = self.n;
        let theta = saved.block("theta", n * self.p)?;
        let q = saved.block("Q", n * (n + 1) / 2)?;
        let w = saved.block("w", n)?;
        let bt = saved.block("beta-trace", 2)?;
        self.theta.copy_from_slice(theta);
        self.cov.copy_from_slice(q);
        self.w_pend.copy_from_slice(w);
        self.beta_pend = bt[0];
        self.trace = bt[1];
        self.forgetting.reset();
        self.err.fill(0.0);
        let checked = if bt[0] > 0.0 {
            crate::learned::check_covariance(
                &self.covariance(),
                self.p as f64 * self.trace,
                self.trace_limit,
            )
        } else {
            Err(format!("β = {:e} is not positive", bt[0]))
        };
        if checked.is_err() {
            self.reset();
        }
        checked
    }

    /// Guard resets so far.
    pub fn resets(&self) -> u64 {
        self.resets
    }
}
