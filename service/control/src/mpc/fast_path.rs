//! # fast_path: the receding-horizon QP solved without condensing when no constraint is
//! active
//!
//! The QP (2.48)–(2.51) of the dissertation is strictly convex, so when the unconstrained
//! minimizer `U*` of (2.48) satisfies every constraint (2.49)–(2.51) it is the QP's
//! solution, and its active set is empty. The fast path computes `U*` by the Riccati
//! recursion of [`super::riccati`] (`O(ℓ N n̂p (p + m))`, `N = n̂p + m`, without forming
//! the `ℓm × ℓm` Hessian), checks it with [`super::constraint_check`] (the solver's
//! feasibility tolerance) and reports whether it may be used; when it may not (a
//! constraint would be active, non-finite data, a lost pivot), the caller condenses and
//! solves the QP as it would have without the fast path ([`super::condense`],
//! [`super::qp`]). Its answer is then the same up to rounding: exactly the minimizer the
//! QP defines, computed another way.
//!
//! ## When it pays ([`FastPathMode::Auto`])
//!
//! The recursion's cost grows with `ℓ` and the square of `N = n̂p + m` (times `n̂p`), the
//! dense path's with the cube of the number of decision variables `ℓm`. [`FastPath::new`]
//! compares, once, the multiply–adds of one recursion ([`Riccati::operation_count`]:
//! `ℓ (2 n̂p (p + m) w + N² + m N w + 2 m² w) + ℓ (m w + n̂p (p + m))`, `w` = `N` rounded up
//! to a multiple of 4) with those of the dense path
//! ([`dense_operation_count`]): condensing `ℓ²m²p_t / 2` (the Toeplitz recursion of
//! `T_tᵀ Q T_t`) `+ (ℓm)² / 2` (mirroring `H`), the solver's Cholesky factorization
//! `(ℓm)³ / 6`, its two triangular solves `2 (ℓm)²` and its pass over the inequality rows
//! `n_ineq · ℓm`, and takes the fast path when the recursion is cheaper and `N` is within
//! the recursion's rows ([`Riccati::MAX_N`] `= 32`):
//!
//! | problem | `n̂p` | `ℓm` | recursion | dense path | fast path |
//! | --- | --- | --- | --- | --- | --- |
//! | sampling arm (§7.3: `n̂ 1`, `p 5`, `m 2`, `ℓ 50`, move bounds) | 5 | 100 | 42 k | 227 k | yes |
//! | truss (§6.2: `n̂ 25`, `p 4`, `m 2`, `ℓ 40`) | 100 | 80 | 6.3 M | 105 k | no |
//!
//! The count leaves out what the step does either way (identification, prediction) and
//! the extra recursion of a step whose minimizer violates a constraint (then both paths
//! run): a problem whose constraints are active at most steps gains nothing from the fast
//! path even where the count favours it, and [`FastPathMode::Never`] turns it off
//! (PCAC's `fast-path` setting); [`FastPathMode::Always`] takes it whatever the count
//! (for `N ≤ 32`).
//!
//! ## Real-time use
//!
//! [`FastPath::new`] allocates every buffer; [`FastPath::solve`] allocates nothing, never
//! panics and runs bounded loops (those of [`Riccati::solve`] and
//! [`ConstraintCheck::satisfied`]).

use super::condense::{MpcSpec, SpecError};
use super::constraint_check::ConstraintCheck;
use super::riccati::Riccati;
use crate::bocf::Realization;

/// Whether PCAC tries the fast path (the `fast-path` setting).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FastPathMode {
    /// When the recursion costs fewer multiply–adds than condensing and factorizing
    /// (module docs).
    #[default]
    Auto,
    /// At every step (when `N = n̂p + m ≤` [`Riccati::MAX_N`]).
    Always,
    /// Never: every step condenses and solves the QP.
    Never,
}

/// Multiply–adds of condensing and factorizing the dense QP of `spec` (module docs):
/// `ℓ²m²p_t / 2 + (ℓm)² / 2 + (ℓm)³ / 6 + 2 (ℓm)² + n_ineq · ℓm`, with
/// `n_ineq = 2ℓm` (move bounds) `+ ℓ n_c` (output constraints). Saturates instead of
/// overflowing.
pub fn dense_operation_count(spec: &MpcSpec) -> u64 {
    let ell = spec.horizon as u64;
    let (m, pt) = (spec.n_inputs as u64, spec.n_tracked as u64);
    let n = ell.saturating_mul(m);
    let nc = spec.output_constraints.as_ref().map_or(0, |oc| oc.d.len()) as u64;
    let move_rows = if spec.move_bounds.is_some() { 2 * n } else { 0 };
    let n_ineq = move_rows.saturating_add(ell.saturating_mul(nc));
    let n2 = n.saturating_mul(n);
    (ell.saturating_mul(ell)
        .saturating_mul(m * m)
        .saturating_mul(pt)
        / 2)
    .saturating_add(n2 / 2)
    .saturating_add(n2.saturating_mul(n) / 6)
    .saturating_add(2 * n2)
    .saturating_add(n_ineq.saturating_mul(n))
}

/// The Riccati minimizer and the constraint check of the module docs.
#[derive(Clone, Debug)]
pub struct FastPath {
    riccati: Riccati,
    check: ConstraintCheck,
    /// `n̂`, `p`, `m` of the model.
    dims: [usize; 3],
    /// The coefficients `Θ̃` kept by [`FastPath::keep_model`] (`n̂p(p+m)`).
    coef: Vec<f64>,
}

impl FastPath {
    /// Whether `mode` takes the fast path for `spec` and a model of order `n_hat`: never
    /// when `N = n̂p + m` exceeds [`Riccati::MAX_N`] or the spec has the tone-notch input
    /// cost (2.48') ([`super::condense::NotchInputCost`], which the recursion does not
    /// know); for [`FastPathMode::Auto`], when
    /// [`Riccati::operation_count`] is below [`dense_operation_count`].
    pub fn chosen(mode: FastPathMode, spec: &MpcSpec, n_hat: usize) -> bool {
        let n = n_hat
            .saturating_mul(spec.n_outputs)
            .saturating_add(spec.n_inputs);
        // The recursion knows only (2.48)'s move penalty, not the tone-notch cost (2.48').
        if n > Riccati::MAX_N || spec.input_notch.is_some() {
            return false;
        }
        match mode {
            FastPathMode::Always => true,
            FastPathMode::Never => false,
            FastPathMode::Auto => {
                let (p, m, ell) = (spec.n_outputs, spec.n_inputs, spec.horizon);
                Riccati::operation_count(n_hat, p, m, ell) < dense_operation_count(spec)
            }
        }
    }

    /// The fast path for `spec` (checked by [`super::condense::Condenser::new`]) and a
    /// model of order `n_hat`, with the QP solver's `feasibility_tol`, when `mode` chooses
    /// it ([`FastPath::chosen`]); `None` otherwise.
    ///
    /// # Errors
    ///
    /// Those of [`Riccati::new`], and [`FastPathMode::Always`] with the tone-notch input
    /// cost.
    pub fn new(
        spec: &MpcSpec,
        n_hat: usize,
        feasibility_tol: f64,
        mode: FastPathMode,
    ) -> Result<Option<Self>, SpecError> {
        if mode == FastPathMode::Always && spec.input_notch.is_some() {
            return Err(SpecError(
                "fast-path = \"always\": the Riccati fast path does not support the tone-notch \
                 input cost (2.48') of the internal model; use \"auto\" or \"never\""
                    .into(),
            ));
        }
        if !Self::chosen(mode, spec, n_hat) {
            return Ok(None);
        }
        let (p, m) = (spec.n_outputs, spec.n_inputs);
        Ok(Some(Self {
            riccati: Riccati::new(spec, n_hat)?,
            check: ConstraintCheck::new(spec, feasibility_tol),
            dims: [n_hat, p, m],
            coef: vec![0.0; n_hat * p * (p + m)],
        }))
    }

    /// Keeps a copy of the coefficients `Θ̃` of `real` for [`FastPath::solve_kept`]: the
    /// realization a prediction used, for a minimizer computed in a later sample period
    /// (PCAC's re-planning, [`crate::pcac::PcacParams::replan_every`]), when
    /// identification has moved the model on. False (nothing kept) when `real` does not
    /// have this fast path's dimensions. Allocation-free.
    pub fn keep_model(&mut self, real: &Realization<'_>) -> bool {
        let [n_hat, p, m] = self.dims;
        let coef = real.coefficients();
        if [real.n_hat(), real.p(), real.m()] != self.dims || coef.len() != n_hat * p * (p + m) {
            return false;
        }
        self.coef.copy_from_slice(coef);
        true
    }

    /// The realization kept by the last [`FastPath::keep_model`] (zero coefficients
    /// before any), for the rest of a deferred prediction
    /// ([`crate::bocf::HorizonPrediction::complete`]) when the fast path's minimizer is not
    /// the solution.
    pub fn kept_realization(&self) -> Option<Realization<'_>> {
        let [n_hat, p, m] = self.dims;
        Realization::new(n_hat, p, m, &self.coef).ok()
    }

    /// Whether the constraint check reads the prediction's free response and Markov
    /// parameters ([`ConstraintCheck::reads_prediction`]: only with output constraints).
    /// When it does not, [`FastPath::solve`] needs only the prediction's start state, and
    /// the rest of the prediction may wait until a QP is condensed
    /// ([`crate::bocf::HorizonPrediction::defer_horizon`]).
    pub fn reads_prediction(&self) -> bool {
        self.check.reads_prediction()
    }

    /// [`FastPath::solve`] for the realization kept by the last [`FastPath::keep_model`].
    /// Allocation-free.
    pub fn solve_kept(
        &mut self,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
        free_response: &[f64],
        markov: &[f64],
    ) -> bool {
        let [n_hat, p, m] = self.dims;
        let Ok(real) = Realization::new(n_hat, p, m, &self.coef) else {
            return false;
        };
        self.riccati.solve(&real, x0, u_k, reference).is_ok()
            && self.check.satisfied(
                self.riccati.u(),
                self.riccati.outputs(),
                free_response,
                markov,
                u_k,
            )
    }

    /// Computes `U*` for the realization `real`, the start state `x0`, the move reference
    /// `u_k` and the command `reference` ([`Riccati::solve`]) and returns whether it is
    /// the QP's solution: finite and within every constraint
    /// ([`ConstraintCheck::satisfied`] with the prediction's `free_response` and
    /// `markov`). Allocation-free.
    pub fn solve(
        &mut self,
        real: &Realization<'_>,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
        free_response: &[f64],
        markov: &[f64],
    ) -> bool {
        self.riccati.solve(real, x0, u_k, reference).is_ok()
            && self.check.satisfied(
                self.riccati.u(),
                self.riccati.outputs(),
                free_response,
                markov,
                u_k,
            )
    }

    /// `U* = [u_{1|k}; …; u_{ℓ|k}]` of the last [`FastPath::solve`] (`ℓ·m`; meaningful when
    /// it returned true).
    pub fn u(&self) -> &[f64] {
        self.riccati.u()
    }

    /// The predicted outputs `y_{1|k} … y_{ℓ|k}` of `U*` (`ℓ·p`).
    pub fn outputs(&self) -> &[f64] {
        self.riccati.outputs()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pcac::PcacParams;

    /// The counts and choices of the module docs' table.
    #[test]
    fn auto_chooses_the_fast_path_for_the_arm_and_not_for_the_truss() {
        let mut arm = PcacParams::chapter_7().build().mpc;
        arm.move_bounds = Some(crate::mpc::condense::MoveBounds::symmetric(50.0, 2));
        let truss = PcacParams::chapter_6().build().mpc;
        // ℓ²m²p_t/2 + (ℓm)²/2 + (ℓm)³/6 + 2(ℓm)² + n_ineq·ℓm.
        assert_eq!(
            dense_operation_count(&arm),
            15_000 + 5_000 + 166_666 + 20_000 + 20_000
        );
        assert_eq!(
            dense_operation_count(&truss),
            3_200 + 3_200 + 85_333 + 12_800
        );
        assert_eq!(Riccati::operation_count(1, 5, 2, 50), 41_800);
        assert_eq!(Riccati::operation_count(25, 4, 2, 40), 6_322_400);
        assert!(FastPath::chosen(FastPathMode::Auto, &arm, 1));
        assert!(!FastPath::chosen(FastPathMode::Auto, &truss, 25));
        // Beyond the recursion's rows (N = 102 > 32) not even when asked.
        assert!(!FastPath::chosen(FastPathMode::Always, &truss, 25));
        // A SISO problem of order 4, ℓ = 10, where condensing is cheaper (2 250 against
        // 666 multiply–adds): only when asked.
        let small = crate::test_support::siso_mpc_spec(10, 1.0, 1.0, 1.0, 0.5);
        assert_eq!(Riccati::operation_count(4, 1, 1, 10), 2_250);
        assert_eq!(dense_operation_count(&small), 50 + 50 + 166 + 200 + 200);
        assert!(!FastPath::chosen(FastPathMode::Auto, &small, 4));
        assert!(FastPath::chosen(FastPathMode::Always, &small, 4));
        assert!(!FastPath::chosen(FastPathMode::Never, &arm, 1));
        assert!(
            FastPath::new(&truss, 25, 1e-10, FastPathMode::Auto)
                .unwrap()
                .is_none()
        );
        assert!(
            FastPath::new(&arm, 1, 1e-10, FastPathMode::Auto)
                .unwrap()
                .is_some()
        );
    }
}
