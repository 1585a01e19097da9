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

use super::{RlsStep, data_finite, guard_passes, prior_errors};
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
    /// `P̃_k`, upper triangle row-packed (row `i` has `n − i` entries, diagonal first).
    cov: Vec<f64>,
    /// `tr P̃_k`.
    trace: f64,
    /// `g = P̃_k ψᵀ`.
    g: Vec<f64>,
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
            trace: 0.0,
            g: vec![0.0; n],
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
        self.cov.fill(0.0);
        let mut off = 0;
        for i in 0..self.n {
            self.cov[off] = self.p0;
            off += self.n - i;
        }
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

        // g = P̃ ψᵀ from the packed upper triangle, row by row: the row's entries right of
        // the diagonal serve both g_i (a dot product) and g_j, j > i (an axpy).
        self.g.fill(0.0);
        let mut off = 0;
        for i in 0..n {
            let row = &self.cov[off..off + n - i];
            let acc = row[0] * psi[i] + dot(&row[1..], &psi[i + 1..]);
            axpy(psi[i], &row[1..], &mut self.g[i + 1..]);
            self.g[i] += acc;
            off += n - i;
        }
        let s = dot(psi, &self.g);
        let d = 1.0 + beta * s;
        if !(d > 0.0 && d.is_finite()) {
            return self.fail(lambda, error_norm);
        }

        // P̃_{k+1} = β P̃ − (β²/d) g gᵀ, in place (one pass), with its trace; `sum` of all
        // entries is non-finite if any entry is (or on overflow, which resets as well).
        let c = beta * beta / d;
        let (mut trace, mut min_diag, mut sum) = (0.0, f64::INFINITY, 0.0);
        let mut off = 0;
        for i in 0..n {
            let row = &mut self.cov[off..off + n - i];
            sum += rank1_row(row, &self.g[i..], beta, c * self.g[i]);
            trace += row[0];
            min_diag = f64::min(min_diag, row[0]);
            off += n - i;
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
        if !guard_passes(
            &self.theta,
            sum.is_finite(),
            min_diag,
            p as f64 * trace,
            self.trace_limit,
        ) {
            return self.fail(lambda, error_norm);
        }
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

    /// `P̃_k`, upper triangle row-packed (row `i` has `n − i` entries, diagonal first).
    pub fn packed_covariance(&self) -> &[f64] {
        &self.cov
    }

    /// Visits what the estimator learned as the blocks of a checkpoint
    /// ([`crate::learned`]): `theta` (Θ̃_k, row-major), `P-tilde` (the packed triangle of
    /// P̃_k) and `trace` (`[tr P̃_k]`). Does not allocate.
    pub fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        visit("theta", &self.theta);
        visit("P-tilde", &self.cov);
        visit("trace", &[self.trace]);
    }

    /// Takes back the blocks of [`SharedRls::learned`] and restarts the forgetting rule.
    /// Allocates (it checks that P̃_k is positive definite).
    ///
    /// # Errors
    ///
    /// A missing, mis-sized or non-finite block, a covariance that is not positive
    /// definite or whose trace the guard would refuse; the estimator is then at `Θ̃_0`, `P̃_0`.
    pub fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        let n = self.n;
        let theta = saved.block("theta", n * self.p)?;
        let cov = saved.block("P-tilde", n * (n + 1) / 2)?;
        self.trace = saved.scalar("trace")?;
        self.theta.copy_from_slice(theta);
        self.cov.copy_from_slice(cov);
        self.forgetting.reset();
        self.err.fill(0.0);
        let p = crate::learned::unpack_symmetric(&self.cov, n);
        let checked =
            crate::learned::check_covariance(&p, self.p as f64 * self.trace, self.trace_limit);
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

/// `row_j ← β row_j − cg g_j` over the common length; returns the sum of the new entries
/// (four lanes, so the loop vectorizes).
#[inline(always)]
fn rank1_row(row: &mut [f64], g: &[f64], beta: f64, cg: f64) -> f64 {
    let n = row.len().min(g.len());
    let (row, g) = (&mut row[..n], &g[..n]);
    let mut acc = [0.0; 4];
    let mut rc = row.chunks_exact_mut(4);
    let mut gc = g.chunks_exact(4);
    for (r, gg) in (&mut rc).zip(&mut gc) {
        for t in 0..4 {
            r[t] = beta * r[t] - cg * gg[t];
            acc[t] += r[t];
        }
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (r, &gg) in rc.into_remainder().iter_mut().zip(gc.remainder()) {
        *r = beta * *r - cg * gg;
        s += *r;
    }
    s
}
