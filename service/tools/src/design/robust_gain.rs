//! The robust gain of §7.2.2 as a semidefinite program: (7.41), normalized, solved with
//! clarabel's positive semidefinite cones ([`super::sdp`]).
//!
//! # The normalization
//!
//! (7.41) as printed (minimize `s ≥ 0` subject to the vertex inequalities and
//! `Q ⪰ s I`) is homogeneous: `Q = Y = 0`, `s = 0` is feasible and optimal, and says nothing
//! about `K`. The program solved here fixes the scale of `Q` and *maximizes* the margin:
//!
//! ```text
//! maximize s   subject to   [ e^{−2λT} Q − s I   A_i Q + B_{ij} Y ]  ⪰ 0   (four vertices)
//!                           [ (A_i Q + B_{ij} Y)ᵀ        Q        ]
//!                           Q ⪰ s I,   Q ⪯ I,
//! ```
//!
//! `K = Y Q⁻¹`. `s > 0` is exactly strict feasibility of (7.40) (scale any strictly
//! feasible `(Q, Y)` into `Q ⪯ I`), with `(A + B K) Q (A + B K)ᵀ ⪯ e^{−2λT} Q − s I` on the
//! whole box (the vertices cover it: see `control::arm::robust`); the optimal `s` is the
//! file's `margin`. `s ≤ 0` means no common quadratic Lyapunov function certifies the decay
//! rate `λ` over the box.
//!
//! # Units of the state
//!
//! `s` is bounded by `λ_min(Q)` under `Q ⪯ I`, so it depends on the units of `χ`: with the
//! velocities in m/s and the force error in N, the certificate `Q` of the chapter's box has
//! a condition number of about 10⁷ and `s` sinks below the solver's tolerance. The program is
//! therefore solved on `χ̃ = D χ`, `D = diag(1, 1, 1/e_0)` (a force error of `e_0` newtons
//! weighs as much as 1 m/s), with `Ã = D A D⁻¹`, `B̃ = D B` and `K = K̃ D`; feasibility and
//! the spectral radii do not depend on `e_0`, only the conditioning does.
//! [`best_force_scale`] picks the `e_0` that maximizes `s` (a golden-section search over
//! `log₁₀ e_0 ∈ [0, 5]`).
//!
//! # The largest certified decay rate
//!
//! `s(λ)` decreases with `λ`; [`largest_certified_decay`] bisects for the largest `λ` with
//! `s > `[`MARGIN_TOLERANCE`], which the tool prints beside the requested one.

use super::sdp::{self, SdpError, SdpSolution, Tolerances};
use control::arm::robust::{LmiCertificate, LmiMargins, RobustBox, Vertex};
use nalgebra::{DMatrix, Matrix2x3, Matrix3, Vector3};

/// A robust gain that cannot be designed or certified, naming the decay rate at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RobustGainError {
    /// The box is refused (`RobustBox::validate`'s message).
    #[error("{0}")]
    Box(String),
    /// LQR weights that are not finite and positive (`LqrWeights::validate`'s message).
    #[error("{0}")]
    Weights(String),
    /// A force scale that is not positive.
    #[error("force scale {0} must be positive")]
    ForceScale(f64),
    /// The program (7.41) at a decay rate has no solution.
    #[error("(7.41) at λ = {decay_rate} /s: {source}")]
    Sdp {
        /// The decay rate, 1/s.
        decay_rate: f64,
        /// Why.
        #[source]
        source: SdpError,
    },
    /// The solution's `Q` is singular.
    #[error("(7.41) at λ = {decay_rate} /s: Q is singular")]
    Singular {
        /// The decay rate, 1/s.
        decay_rate: f64,
    },
    /// The program (7.41) for a given gain has no solution.
    #[error("(7.41) for a given K at λ = {decay_rate} /s: {source}")]
    GivenGain {
        /// The decay rate, 1/s.
        decay_rate: f64,
        /// Why.
        #[source]
        source: SdpError,
    },
}

message_from!(RobustGainError);

/// The margin `s` a design must exceed to count as a strict certificate (well above
/// clarabel's default feasibility tolerance of 10⁻⁸).
pub const MARGIN_TOLERANCE: f64 = 1e-7;

/// How far below zero an inequality's smallest eigenvalue may be at the returned point and
/// still count as satisfied (the interior-point solver's residual).
pub const FEASIBILITY_TOLERANCE: f64 = 1e-7;

/// A solved normalized (7.41).
#[derive(Debug, Clone, PartialEq)]
pub struct RobustDesign {
    /// The box it was solved for.
    pub design: RobustBox,
    /// `e_0` (N s/m) of the scaling `χ̃ = diag(1, 1, 1/e_0) χ`.
    pub force_scale: f64,
    /// `(Q̃, Ỹ, s)` in the scaled coordinates.
    pub certificate: LmiCertificate,
    /// `K = Ỹ Q̃⁻¹ D` on `χ = [ẋ ẏ e]`.
    pub gain: Matrix2x3<f64>,
    /// The solver's status and iterations.
    pub solver: String,
    /// The solver stopped at the tolerances it was given (`Solved`), not at clarabel's
    /// reduced ones (`AlmostSolved`).
    pub full_accuracy: bool,
    /// The dual bound on the margin (minus the dual cost): the optimal `s` at this `e_0`
    /// lies between it and [`RobustDesign::margin`] up to the residuals.
    pub dual_margin: f64,
}

impl RobustDesign {
    /// The scaling `D = diag(1, 1, 1/e_0)`.
    pub fn scale(&self) -> Vector3<f64> {
        scale(self.force_scale)
    }

    /// The vertices in the scaled coordinates the certificate uses.
    pub fn scaled_vertices(&self) -> [Vertex; 4] {
        let d = self.scale();
        self.design.vertices().map(|v| v.scaled(&d))
    }

    /// The optimal `s`.
    pub fn margin(&self) -> f64 {
        self.certificate.s
    }

    /// The smallest eigenvalues of the normalized program's inequalities at the solution.
    pub fn margins(&self) -> LmiMargins {
        let alpha = self.design.contraction().powi(2);
        self.certificate.margins(&self.scaled_vertices(), alpha)
    }

    /// The smallest eigenvalues of (7.40)'s Schur form itself (`s = 0`).
    pub fn lyapunov_margins(&self) -> LmiMargins {
        let alpha = self.design.contraction().powi(2);
        LmiCertificate {
            s: 0.0,
            ..self.certificate
        }
        .margins(&self.scaled_vertices(), alpha)
    }

    /// The largest margin `s` at which the returned `(Q̃, Ỹ)` satisfies the normalized
    /// program *exactly* (no solver residual): with `M_v = Ã_v Q̃ + B̃_v Ỹ` and `Q̃ ≻ 0`,
    /// the vertex inequality is, by its Schur complement, `s ≤ λ_min(α Q̃ − M_v Q̃⁻¹ M_vᵀ)`;
    /// `Q̃ ⪰ s I` is `s ≤ λ_min(Q̃)`; and when `λ_max(Q̃)` exceeds 1 by the residual,
    /// `(Q̃, Ỹ, s) / λ_max(Q̃)` satisfies `Q̃ ⪯ I` as well (every inequality is homogeneous
    /// in `(Q̃, Ỹ, s)`). So this is a lower bound on the optimal `s` at this `e_0` (up to
    /// the rounding of 3×3 eigenvalues); `None` when `Q̃` is not positive definite.
    pub fn feasible_margin(&self) -> Option<f64> {
        let q = self.certificate.q;
        let ev = q.symmetric_eigenvalues();
        if ev.min() <= 0.0 {
            return None;
        }
        let qi = q.try_inverse()?;
        let alpha = self.design.contraction().powi(2);
        let schur = self.scaled_vertices().map(|v| {
            let m = v.a * q + v.b * self.certificate.y;
            let c = q * alpha - m * qi * m.transpose();
            (0.5 * (c + c.transpose())).symmetric_eigenvalues().min()
        });
        let s = schur.iter().copied().fold(ev.min(), f64::min);
        Some(s / ev.max().max(1.0))
    }

    /// The condition number of `Q̃`.
    pub fn condition(&self) -> f64 {
        let ev = self.certificate.q.symmetric_eigenvalues();
        ev.max() / ev.min()
    }

    /// `s > `[`MARGIN_TOLERANCE`], every inequality holds at the solution within
    /// [`FEASIBILITY_TOLERANCE`] and (7.40) holds strictly at every vertex.
    pub fn certified(&self) -> bool {
        self.margin() > MARGIN_TOLERANCE
            && self.margins().min() >= -FEASIBILITY_TOLERANCE
            && self.lyapunov_margins().vertices.iter().all(|m| *m > 0.0)
            && self.certificate.q.symmetric_eigenvalues().min() > 0.0
    }
}

fn scale(force_scale: f64) -> Vector3<f64> {
    Vector3::new(1.0, 1.0, 1.0 / force_scale)
}

/// `Q` from its six entries in svec order `(0,0), (0,1), (1,1), (0,2), (1,2), (2,2)`.
fn sym3(x: &[f64]) -> Matrix3<f64> {
    Matrix3::new(x[0], x[1], x[3], x[1], x[2], x[4], x[3], x[4], x[5])
}

/// The blocks of the normalized (7.41) at `cert` that must be positive semidefinite (the
/// maps of [`sdp::affine_lmis`]): `L` of one vertex of `vertices` each (with `α =
/// alpha`), then `Q̃ − s I` and `I − Q̃`.
fn lmi_blocks(cert: &LmiCertificate, vertices: &[Vertex], alpha: f64) -> Vec<DMatrix<f64>> {
    let to_d = |m: Matrix3<f64>| DMatrix::from_fn(3, 3, |i, j| m[(i, j)]);
    let mut out: Vec<DMatrix<f64>> = vertices
        .iter()
        .map(|v| {
            let l = cert.vertex_matrix(v, alpha);
            DMatrix::from_fn(6, 6, |i, j| l[(i, j)])
        })
        .collect();
    out.push(to_d(cert.q - Matrix3::identity() * cert.s));
    out.push(to_d(Matrix3::identity() - cert.q));
    out
}

/// Solves the normalized (7.41) for `design` in the coordinates scaled by `e_0 =
/// force_scale`. Variables: the six entries of `Q̃`, the six of `Ỹ` (row-major), `s`.
pub fn solve(design: &RobustBox, force_scale: f64) -> Result<RobustDesign, RobustGainError> {
    solve_with(design, force_scale, &Tolerances::DEFAULT)
}

/// [`solve`] with the solver's stopping tolerances `tol`.
pub fn solve_with(
    design: &RobustBox,
    force_scale: f64,
    tol: &Tolerances,
) -> Result<RobustDesign, RobustGainError> {
    design.validate().map_err(RobustGainError::Box)?;
    if !(force_scale.is_finite() && force_scale > 0.0) {
        return Err(RobustGainError::ForceScale(force_scale));
    }
    let d = scale(force_scale);
    let vertices = design.vertices().map(|v| v.scaled(&d));
    let alpha = design.contraction().powi(2);
    let lmis = sdp::affine_lmis(13, |x| {
        let cert = LmiCertificate {
            q: sym3(&x[0..6]),
            y: Matrix2x3::from_row_slice(&x[6..12]),
            s: x[12],
        };
        lmi_blocks(&cert, &vertices, alpha)
    });
    let mut c = vec![0.0; 13];
    c[12] = -1.0;
    let SdpSolution {
        x,
        dual_cost,
        status,
        full_accuracy,
        iterations,
        ..
    } = sdp::minimize_with(&c, &lmis, tol).map_err(|source| RobustGainError::Sdp {
        decay_rate: design.decay_rate,
        source,
    })?;
    let certificate = LmiCertificate {
        q: sym3(&x[0..6]),
        y: Matrix2x3::from_row_slice(&x[6..12]),
        s: x[12],
    };
    let gain = certificate.gain().ok_or(RobustGainError::Singular {
        decay_rate: design.decay_rate,
    })? * Matrix3::from_diagonal(&d);
    Ok(RobustDesign {
        design: *design,
        force_scale,
        certificate,
        gain,
        solver: format!("clarabel {status} in {iterations} iterations"),
        full_accuracy,
        dual_margin: -dual_cost,
    })
}

/// The largest margin `s` that certifies a *given* gain `K` over `design`'s box at `e_0 =
/// force_scale`: the normalized (7.41) with `Ỹ = K̃ Q̃` (`K̃ = K D⁻¹`), maximized over `Q̃`
/// and `s` only. The result's `gain` is `K`; its certificate is `(Q̃, K̃ Q̃, s)`. A gain
/// that is optimal for the box has the optimal `s` of [`solve`] here (up to the solver's
/// accuracy); a perturbed one has less.
pub fn certify_gain(
    design: &RobustBox,
    gain: &Matrix2x3<f64>,
    force_scale: f64,
) -> Result<RobustDesign, RobustGainError> {
    design.validate().map_err(RobustGainError::Box)?;
    if !(force_scale.is_finite() && force_scale > 0.0) {
        return Err(RobustGainError::ForceScale(force_scale));
    }
    let d = scale(force_scale);
    let k_scaled = gain * Matrix3::from_diagonal(&d.map(|v| 1.0 / v));
    let vertices = design.vertices().map(|v| v.scaled(&d));
    let alpha = design.contraction().powi(2);
    let cert_of = |x: &[f64]| {
        let q = sym3(&x[0..6]);
        LmiCertificate {
            q,
            y: k_scaled * q,
            s: x[6],
        }
    };
    let lmis = sdp::affine_lmis(7, |x| lmi_blocks(&cert_of(x), &vertices, alpha));
    let mut c = vec![0.0; 7];
    c[6] = -1.0;
    let sol = sdp::minimize(&c, &lmis).map_err(|source| RobustGainError::GivenGain {
        decay_rate: design.decay_rate,
        source,
    })?;
    Ok(RobustDesign {
        design: *design,
        force_scale,
        certificate: cert_of(&sol.x),
        gain: *gain,
        solver: format!("clarabel {} in {} iterations", sol.status, sol.iterations),
        full_accuracy: sol.full_accuracy,
        dual_margin: -sol.dual_cost,
    })
}

/// The width (decades of `e_0`) of the final bracket of [`best_force_scale`]'s search.
pub const FORCE_SCALE_BRACKET: f64 = 0.01;

/// [`solve`] at the `e_0 ∈ [1, 10⁵]` N s/m that maximizes the margin `s` (golden-section
/// search over `log₁₀ e_0`, to [`FORCE_SCALE_BRACKET`] decades).
pub fn best_force_scale(design: &RobustBox) -> Result<RobustDesign, RobustGainError> {
    best_force_scale_with(design, &Tolerances::DEFAULT)
}

/// [`best_force_scale`] with the solver's stopping tolerances `tol`.
pub fn best_force_scale_with(
    design: &RobustBox,
    tol: &Tolerances,
) -> Result<RobustDesign, RobustGainError> {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let at = |l: f64| solve_with(design, 10f64.powf(l), tol);
    let (mut a, mut b) = (0.0_f64, 5.0_f64);
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (at(x1)?, at(x2)?);
    while b - a > FORCE_SCALE_BRACKET {
        if f1.margin() >= f2.margin() {
            b = x2;
            (x2, f2) = (x1, f1);
            x1 = b - g * (b - a);
            f1 = at(x1)?;
        } else {
            a = x1;
            (x1, f1) = (x2, f2);
            x2 = a + g * (b - a);
            f2 = at(x2)?;
        }
    }
    Ok(if f1.margin() >= f2.margin() { f1 } else { f2 })
}

/// The largest decay rate `λ` (1/s) for which the normalized (7.41) over `design`'s box has
/// `s > `[`MARGIN_TOLERANCE`] at `e_0 = force_scale`, to a relative 10⁻³; `None` when not
/// even `λ = 0` (robust stability) is certified.
pub fn largest_certified_decay(
    design: &RobustBox,
    force_scale: f64,
) -> Result<Option<f64>, RobustGainError> {
    let ok = |l: f64| -> Result<bool, RobustGainError> {
        let d = RobustBox {
            decay_rate: l,
            ..*design
        };
        Ok(solve(&d, force_scale)?.margin() > MARGIN_TOLERANCE)
    };
    if !ok(0.0)? {
        return Ok(None);
    }
    // Bracket: grow from the requested rate (or 10⁻³ /s) until the program fails.
    let mut lo = 0.0;
    let mut hi = design.decay_rate.max(1e-3);
    while ok(hi)? {
        lo = hi;
        hi *= 2.0;
        if hi > 1.0 / design.sample_period {
            return Ok(Some(lo));
        }
    }
    while hi - lo > 1e-3 * hi {
        let mid = 0.5 * (lo + hi);
        if ok(mid)? {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(Some(lo))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A box small enough to be certified with a wide margin (also the other objectives'
    /// test box).
    pub(crate) const NARROW: RobustBox = RobustBox {
        sample_period: 0.0005,
        decay_rate: 0.05,
        stiffness: [300.0, 3000.0],
        damping: [0.35, 5.0],
    };

    #[test]
    fn a_narrow_box_is_certified_and_its_gain_passes_the_independent_check() {
        let d = solve(&NARROW, 100.0).unwrap();
        assert!(d.certified(), "{d:?}");
        let m = d.margins();
        assert!(m.min() >= -FEASIBILITY_TOLERANCE, "{m:?}");
        assert!(m.upper >= -FEASIBILITY_TOLERANCE);
        let check = NARROW.check_gain(&d.gain, 40);
        assert!(check.passed(), "{check:?}");
    }

    #[test]
    fn the_margin_does_not_grow_with_the_decay_rate() {
        let slow = solve(&NARROW, 100.0).unwrap().margin();
        let fast = RobustBox {
            decay_rate: 50.0,
            ..NARROW
        };
        let fast = solve(&fast, 100.0).unwrap().margin();
        assert!(fast < slow, "s({}) = {fast} ≥ s(0.05) = {slow}", 50.0);
    }

    #[test]
    fn a_decay_rate_beyond_the_sample_rate_is_not_certified() {
        // e^{−λT} below the best deadbeat-free radius: λ T = 5 asks every mode to shrink by
        // e⁵ per sample on every surface, which no single gain does.
        let d = RobustBox {
            decay_rate: 10_000.0,
            ..NARROW
        };
        let r = solve(&d, 100.0).unwrap();
        assert!(!r.certified());
        assert!(r.margin() <= MARGIN_TOLERANCE);
    }

    #[test]
    fn the_largest_certified_rate_separates_certified_from_not() {
        let star = largest_certified_decay(&NARROW, 100.0).unwrap().unwrap();
        assert!(star > NARROW.decay_rate);
        let below = RobustBox {
            decay_rate: 0.98 * star,
            ..NARROW
        };
        let above = RobustBox {
            decay_rate: 1.05 * star,
            ..NARROW
        };
        assert!(solve(&below, 100.0).unwrap().certified());
        assert!(solve(&above, 100.0).unwrap().margin() <= MARGIN_TOLERANCE);
    }
}
