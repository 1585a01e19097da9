//! # constraint_check: whether a plan satisfies the receding-horizon constraints as the QP
//! solver judges them
//!
//! A plan `U = [u_{1|k}; …; u_{ℓ|k}]` with its predicted outputs
//! `Y = Γ̂ x_{1|k} + T̂ U` (2.43) is checked against every constraint the condensed QP of
//! [`super::condense`] has (dissertation section 2.3.2.2):
//!
//! ```text
//! C_ℓ Y + 𝓓_ℓ ≤ 0                  (2.49)   per step i and row r: C_c,r y_{i|k} + 𝓓_r ≤ 0
//! U_min ≤ U ≤ U_max                (2.50)
//! ΔU_min ≤ ΔU ≤ ΔU_max             (2.51)   ΔU = [u_{1|k} − u_k; u_{2|k} − u_{1|k}; …]  (2.47)
//! ```
//!
//! with the convention of [`super::qp::QpSettings::feasibility_tol`]: a row
//! `a_jᵀ U ≤ b_j` of the QP counts as violated when
//! `(a_jᵀ U − b_j) / ‖a_j‖ > tol (1 + |b_j| / ‖a_j‖)`, which for the condensed rows is
//!
//! - an input bound (`a = ±e`): `u − u_max > tol (1 + |u_max|)`, `u_min − u > tol (1 + |u_min|)`;
//! - a move bound of step 0 (`a = ±e`, `b = Δu_max + u_k` or `−Δu_min − u_k`):
//!   `±u_{1|k} − b > tol (1 + |b|)`; of a later step (`a = ±(e_i − e_{i−1})`, `‖a‖ = √2`,
//!   `b = Δu_max` or `−Δu_min`): `±Δu_i − b > tol (√2 + |b|)`;
//! - an output row (`a` the row of `C_c T̂`, `b = −𝓓_r − C_c,r (Γ̂ x_{1|k})_i`, so
//!   `a U − b = C_c,r y_{i|k} + 𝓓_r`): `C_c,r y_{i|k} + 𝓓_r > tol (‖a‖ + |b|)`, with
//!   `‖a‖² = Σ_{s=1}^{i−1} ‖C_c,r Ĥ_s‖²` (the row's blocks are `C_c,r Ĥ_{i−j}`, `j < i`); a
//!   row that is zero (step 1, whose `y_{1|k}` no input reaches, or outputs no input
//!   reaches yet) is violated when `b < −tol (1 + |b|)`, where the solver reports the
//!   problem infeasible.
//!
//! Bounds at `±∞` are absent, as in the QP. When every constraint passes, the solver would
//! accept the plan as it stands: started from the unconstrained minimizer (its dual
//! method's start), it finds nothing violated and returns it.
//!
//! ## Real-time use
//!
//! [`ConstraintCheck::new`] copies the bounds and output constraints of the spec;
//! [`ConstraintCheck::satisfied`] allocates nothing, never panics (slices of the wrong
//! length count as not satisfied) and costs `O(ℓ (m + n_c p m))`.

use super::condense::MpcSpec;
use crate::linalg::dot_in_order as dot;

#[cfg(test)]
mod tests;

/// The constraints (2.49)–(2.51) of a spec and the solver's feasibility tolerance (module
/// docs).
#[derive(Clone, Debug)]
pub struct ConstraintCheck {
    ell: usize,
    m: usize,
    p: usize,
    u_min: Vec<f64>,
    u_max: Vec<f64>,
    /// `Δu_min`, `Δu_max` (`m` each; empty without move bounds).
    du_min: Vec<f64>,
    du_max: Vec<f64>,
    /// `C_c` (`n_c × p`) and `𝓓` (`n_c`; empty without output constraints).
    cc: Vec<f64>,
    dd: Vec<f64>,
    /// `‖a‖²` of the output rows of the current step, per row of `C_c`.
    norm2: Vec<f64>,
    tol: f64,
}

impl ConstraintCheck {
    /// The constraints of `spec` (checked by [`super::condense::Condenser::new`]) and the
    /// solver's `feasibility_tol` ([`super::qp::QpSettings::feasibility_tol`]).
    pub fn new(spec: &MpcSpec, feasibility_tol: f64) -> Self {
        let (du_min, du_max) = match &spec.move_bounds {
            Some(mb) => (mb.min.clone(), mb.max.clone()),
            None => (Vec::new(), Vec::new()),
        };
        let (cc, dd) = match &spec.output_constraints {
            Some(oc) => (oc.c.clone(), oc.d.clone()),
            None => (Vec::new(), Vec::new()),
        };
        Self {
            ell: spec.horizon,
            m: spec.n_inputs,
            p: spec.n_outputs,
            u_min: spec.u_min.clone(),
            u_max: spec.u_max.clone(),
            norm2: vec![0.0; dd.len()],
            du_min,
            du_max,
            cc,
            dd,
            tol: feasibility_tol,
        }
    }

    /// Whether [`ConstraintCheck::satisfied`] reads the free response and the Markov
    /// parameters: only for output constraints (2.49).
    pub fn reads_prediction(&self) -> bool {
        !self.dd.is_empty()
    }

    /// Whether the plan `u` (`ℓ·m`) with its predicted outputs `outputs` (`ℓ·p`, `Y` of
    /// (2.43)) satisfies every constraint within the tolerance (module docs), for the free
    /// response `free_response` (`Γ̂ x_{1|k}`, `ℓ·p`), the Markov parameters `markov`
    /// (`Ĥ_1, …`, at least `ℓ−1` blocks of `p × m`) and the move reference `u_k` (`m`).
    /// Without output constraints the free response and the Markov parameters are not
    /// read ([`ConstraintCheck::reads_prediction`]) and may be of any length.
    /// Allocation-free; false for slices of the wrong length or non-finite values.
    pub fn satisfied(
        &mut self,
        u: &[f64],
        outputs: &[f64],
        free_response: &[f64],
        markov: &[f64],
        u_k: &[f64],
    ) -> bool {
        let (ell, m, p) = (self.ell, self.m, self.p);
        let nc = self.dd.len();
        // The prediction is read by the output constraints only.
        let prediction_ok = nc == 0
            || (free_response.len() == ell * p && markov.len() >= ell.saturating_sub(1) * p * m);
        if u.len() != ell * m
            || outputs.len() != ell * p
            || !prediction_ok
            || u_k.len() != m
            || self.u_min.len() != m
            || self.u_max.len() != m
            || self.cc.len() != nc * p
        {
            return false;
        }
        let tol = self.tol;
        let over = |excess: f64, scale: f64| excess > tol * scale || excess.is_nan();
        // Input bounds (2.50); a NaN counts as a violation.
        for row in u.chunks_exact(m) {
            for ((x, lo), hi) in row.iter().zip(&self.u_min).zip(&self.u_max) {
                if hi.is_finite() && over(x - hi, 1.0 + hi.abs()) {
                    return false;
                }
                if lo.is_finite() && over(lo - x, 1.0 + lo.abs()) {
                    return false;
                }
                if !x.is_finite() {
                    return false;
                }
            }
        }
        // Move bounds (2.51): step 0 against u_k (‖a‖ = 1), later steps ‖a‖ = √2.
        if self.du_min.len() == m && self.du_max.len() == m {
            for (i, row) in u.chunks_exact(m).enumerate() {
                for j in 0..m {
                    let (hi, lo) = (self.du_max[j], self.du_min[j]);
                    let (up, down) = if i == 0 {
                        // Rows u_0 ≤ Δu_max + u_k and −u_0 ≤ −Δu_min − u_k.
                        let (bu, bd) = (hi + u_k[j], -lo - u_k[j]);
                        (
                            bu.is_finite() && over(row[j] - bu, 1.0 + bu.abs()),
                            bd.is_finite() && over(-row[j] - bd, 1.0 + bd.abs()),
                        )
                    } else {
                        let du = row[j] - u[(i - 1) * m + j];
                        let r2 = core::f64::consts::SQRT_2;
                        (
                            hi.is_finite() && over(du - hi, r2 + hi.abs()),
                            lo.is_finite() && over(lo - du, r2 + lo.abs()),
                        )
                    };
                    if up || down {
                        return false;
                    }
                }
            }
        }
        // Output constraints (2.49).
        if nc == 0 {
            return true;
        }
        self.norm2.fill(0.0);
        for i in 0..ell {
            if i >= 1 {
                // Row (i, r) gains the block C_c,r Ĥ_i (its blocks are Ĥ_1 … Ĥ_i).
                let h = &markov[(i - 1) * p * m..i * p * m];
                for (n2, crow) in self.norm2.iter_mut().zip(self.cc.chunks_exact(p)) {
                    for j in 0..m {
                        let v: f64 = (0..p).map(|k| crow[k] * h[k * m + j]).sum();
                        *n2 += v * v;
                    }
                }
            }
            let y = &outputs[i * p..(i + 1) * p];
            let yf = &free_response[i * p..(i + 1) * p];
            for ((crow, d), n2) in self.cc.chunks_exact(p).zip(&self.dd).zip(&self.norm2) {
                let b = -d - dot(crow, yf);
                let violated = if *n2 > 0.0 {
                    let excess = dot(crow, y) + d;
                    over(excess, n2.sqrt() + b.abs())
                } else {
                    b < -tol * (1.0 + b.abs()) || !b.is_finite()
                };
                if violated {
                    return false;
                }
            }
        }
        true
    }
}
