//! RLS on a scalar regression with a diagonal regularization `R_θ`, through the crate's
//! [`Rls`] kernel.
//!
//! Both controllers of this module minimize
//!
//! ```text
//! J_k(θ̂) = Σ_{i=1}^{k} λ^{k−i} ẑ_i(θ̂)² + λ^k (θ̂ − θ̂_0)ᵀ R_θ (θ̂ − θ̂_0)        (4.42), (4.76)
//! ẑ_i(θ̂) = φ_i θ̂ − b_i
//! ```
//!
//! ((4.41): `φ = [Φ_k Φ_{f,k}]`, `b = −u_{f,k}`; (4.75): `φ = Φ_{f,k}`,
//! `b = u_{f,k} − z_{f,k}`). [`Rls`] starts from `P_0 = p0 I`; a diagonal
//! `R_θ = diag(r_1, …, r_N)` is taken by the change of variables `θ̂ = S θ̂'`,
//! `S = diag(r_i^{−1/2})`: then `(θ̂ − θ̂_0)ᵀ R_θ (θ̂ − θ̂_0) = |θ̂' − θ̂'_0|²` and
//! `φ θ̂ = (φ S) θ̂'`, so RLS with `P'_0 = I` on the regressor `φ S` minimizes the same
//! cost, exactly (the scaling is the only difference in rounding). The forgetting factor
//! `λ_k` comes from any [`ForgettingRule`] of the kernel (`λ_k ≡ λ` for (4.42), (4.76)),
//! applied to the scalar prior error. The kernel's guard resets `θ̂, P` to `θ̂_0, P_0` on a
//! blow-up; its trace limit bounds `tr(R_θ^{1/2} P R_θ^{1/2})`, which is `N` at the start.

use crate::ParamError;
use crate::forgetting::ForgettingRule;
use crate::rls::{Rls, RlsConfig, RlsStep};

/// RLS with `P_0 = R_θ⁻¹`, `R_θ` diagonal (module docs); allocation-free after
/// construction.
#[derive(Debug, Clone)]
pub(crate) struct Estimator {
    rls: Rls,
    /// `s_i = r_i^{−1/2}`.
    scale: Vec<f64>,
    /// `θ̂ = S θ̂'`.
    theta: Vec<f64>,
    /// `φ S`.
    phi_scaled: Vec<f64>,
}

/// Checks `θ̂_0`, `R_θ = diag(r_theta)`, the trace limit and the forgetting rule for `n`
/// coefficients; the errors name `theta0`, `r-theta`, `trace-limit` and the forgetting
/// rule's fields.
pub(crate) fn check(
    n: usize,
    theta0: Option<&[f64]>,
    r_theta: &[f64],
    rule: &ForgettingRule,
    trace_limit: f64,
) -> Result<(), ParamError> {
    if let Some(t) = theta0 {
        if t.len() != n {
            return Err(ParamError::new(
                "theta0",
                format!("has {} entries, expected {n}", t.len()),
            ));
        }
        if let Some(i) = t.iter().position(|v| !v.is_finite()) {
            return Err(ParamError::at("theta0", i, "is not finite"));
        }
    }
    if r_theta.len() != n {
        return Err(ParamError::new(
            "r-theta",
            format!(
                "has {} entries, expected {n} (the diagonal of R_θ, one per coefficient)",
                r_theta.len()
            ),
        ));
    }
    if let Some(i) = r_theta.iter().position(|v| !(*v > 0.0 && v.is_finite())) {
        return Err(ParamError::at(
            "r-theta",
            i,
            format!("{} must be positive and finite", r_theta[i]),
        ));
    }
    if trace_limit.is_nan() || trace_limit <= n as f64 {
        return Err(ParamError::new(
            "trace-limit",
            format!("{trace_limit} must exceed tr(R_θ^½ P_0 R_θ^½) = {n}"),
        ));
    }
    rule.validate(1)
}

impl Estimator {
    /// Builds the estimator after [`check`].
    pub(crate) fn new(
        n: usize,
        theta0: Option<&[f64]>,
        r_theta: &[f64],
        rule: &ForgettingRule,
        trace_limit: f64,
    ) -> Result<Self, ParamError> {
        check(n, theta0, r_theta, rule, trace_limit)?;
        let scale: Vec<f64> = r_theta.iter().map(|r| 1.0 / r.sqrt()).collect();
        let theta = theta0.map_or_else(|| vec![0.0; n], <[f64]>::to_vec);
        let theta0_scaled: Vec<f64> = theta.iter().zip(&scale).map(|(t, s)| t / s).collect();
        let rls = Rls::new(&RlsConfig {
            n,
            p: 1,
            theta0: theta0_scaled,
            p0: 1.0,
            rule: rule.clone(),
            trace_limit,
        })
        .map_err(|e| ParamError::new("forgetting", e))?;
        let mut e = Self {
            rls,
            scale,
            theta,
            phi_scaled: vec![0.0; n],
        };
        e.sync();
        Ok(e)
    }

    /// `θ̂ = S θ̂'` from the kernel's estimate.
    fn sync(&mut self) {
        for ((t, s), tp) in self.theta.iter_mut().zip(&self.scale).zip(self.rls.theta()) {
            *t = s * tp;
        }
    }

    /// One update with the row `φ` (length `N`) and target `b`: `θ̂_{k−1} → θ̂_k`
    /// minimizing (4.42)/(4.76). `phi` must have length `N` (the callers' buffers do).
    pub(crate) fn update(&mut self, phi: &[f64], b: f64) -> RlsStep {
        for ((d, p), s) in self.phi_scaled.iter_mut().zip(phi).zip(&self.scale) {
            *d = p * s;
        }
        let st = self.rls.update(&self.phi_scaled, &[b]);
        self.sync();
        st
    }

    /// The estimate `θ̂_k`.
    pub(crate) fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// `tr(R_θ^{1/2} P_k R_θ^{1/2})` (the kernel's scaled covariance trace).
    pub(crate) fn trace(&self) -> f64 {
        self.rls.trace_p()
    }

    /// Guard resets since construction.
    pub(crate) fn resets(&self) -> u64 {
        self.rls.resets()
    }

    /// Back to `θ̂_0`, `P_0`.
    pub(crate) fn reset(&mut self) {
        self.rls.reset();
        self.sync();
    }

    /// Empties the forgetting windows, keeps `θ̂` and `P`.
    pub(crate) fn restart_data(&mut self) {
        self.rls.restart_data();
    }

    /// The kernel's learned blocks (in the scaled coordinates `θ̂'`, `P'`).
    pub(crate) fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        self.rls.learned(visit);
    }

    /// Takes back the blocks of [`Estimator::learned`].
    pub(crate) fn restore_learned(
        &mut self,
        saved: &crate::learned::Learned<'_>,
    ) -> Result<(), String> {
        let r = self.rls.restore_learned(saved);
        self.sync();
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    #[test]
    fn a_diagonal_r_theta_gives_the_regularized_batch_solution() {
        // λ = 1: θ̂_k = (R_θ + Σ φᵢᵀφᵢ)⁻¹ (R_θ θ̂_0 + Σ φᵢᵀ bᵢ), (2.5).
        let r = [1e-2, 3.0, 0.5];
        let t0 = [0.1, -0.2, 0.3];
        let mut est = Estimator::new(3, Some(&t0), &r, &ForgettingRule::DEFAULT, f64::INFINITY)
            .expect("valid");
        let mut a = DMatrix::from_diagonal(&DVector::from_row_slice(&r));
        let mut rhs = &a * DVector::from_row_slice(&t0);
        for k in 0..7 {
            let kf = k as f64;
            let phi = [kf.sin(), 1.0 + 0.3 * kf, (0.7 * kf).cos()];
            let b = 0.5 * kf - 1.0;
            est.update(&phi, b);
            let p = DVector::from_row_slice(&phi);
            a += &p * p.transpose();
            rhs += &p * b;
        }
        let want = a.lu().solve(&rhs).expect("invertible");
        for (got, w) in est.theta().iter().zip(want.iter()) {
            assert!((got - w).abs() < 1e-9 * (1.0 + w.abs()), "{got} vs {w}");
        }
    }

    #[test]
    fn bad_weights_are_refused_by_name() {
        let rule = ForgettingRule::DEFAULT;
        let e = check(2, None, &[1.0], &rule, f64::INFINITY).unwrap_err();
        assert_eq!(e.field, "r-theta");
        let e = check(2, None, &[1.0, 0.0], &rule, f64::INFINITY).unwrap_err();
        assert_eq!((e.field, e.index), ("r-theta", Some(1)));
        let e = check(2, Some(&[0.0]), &[1.0, 1.0], &rule, f64::INFINITY).unwrap_err();
        assert_eq!(e.field, "theta0");
        let e = check(2, None, &[1.0, 1.0], &rule, 2.0).unwrap_err();
        assert_eq!(e.field, "trace-limit");
        let bad = ForgettingRule::Constant { lambda: 1.5 };
        let e = check(2, None, &[1.0, 1.0], &bad, f64::INFINITY).unwrap_err();
        assert_eq!(e.field, "forgetting.lambda");
    }
}
