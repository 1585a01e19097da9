//! Other objectives for the robust gain of §7.2.2 over the same decay-rate vertex
//! inequalities (7.40): the smallest gain, and an LQR cost bound. The committed design
//! ([`super::robust_gain`], objective [`Objective::Margin`]) maximizes the margin `s` under
//! `Q ⪯ I`, which drives `K₁₁` to about `−1/T_s` (deadbeat in `ẋ`); these two ask for a
//! gain that is certified for the same decay rate over the same box but chosen by another
//! rule, so that the chapter's results can be compared against more than one reading of
//! (7.41).
//!
//! Everything is in the scaled coordinates `χ̃ = D χ`, `D = diag(1, 1, 1/e_0)` of
//! [`super::robust_gain`] (`Ã_v = D A_v D⁻¹`, `B̃_v = D B_v`, `K = K̃ D`), and `Q̃`, `Ỹ` are
//! written `Q`, `Y` below.
//!
//! # Strictness
//!
//! For the minimum gain, (7.40) at the vertices, `[α Q, A_v Q + B_v Y; (A_v Q + B_v Y)ᵀ, Q] ⪰ 0`, is imposed at
//! the *program's* rate `λ_p = `[`RATE_MARGIN`]` · λ` (`α_p = e^{−2 λ_p T_s}`), not at `λ`
//! itself: an optimum of a linear objective lies on the boundary of the inequalities it
//! is pressed against, and a gain on the boundary at `λ` certifies `λ` with `s = 0`, which
//! no solver residual can tell from infeasible. At `λ_p > λ` the gain certifies `λ` with
//! `(A_v + B_v K) Q (A_v + B_v K)ᵀ ⪯ α_p Q ≺ α Q`. The gain is then certified at `λ` by
//! [`super::robust_gain::certify_gain`] (the normalized (7.41) with `Y = K̃ Q`, maximized
//! over `Q` and `s`), whose `s` is comparable with the margin design's. The LQR design
//! keeps a margin `σ > 0` in the normalized (7.41) itself instead (below).
//!
//! # Minimum gain ([`Objective::MinGain`])
//!
//! ```text
//! minimize t   subject to   [ α_p Q            A_v Q + B_v Y ]  ⪰ 0   (four vertices)
//!                           [ (A_v Q + B_v Y)ᵀ       Q       ]
//!                           Q ⪰ I,
//!                           [ t I₂   Y ]  ⪰ 0.
//!                           [ Yᵀ     Q ]
//! ```
//!
//! The last inequality is, by its Schur complement, `Y Q⁻¹ Yᵀ ⪯ t I`, i.e.
//! `K̃ Q K̃ᵀ ⪯ t I`; with `Q ⪰ I` this gives `K̃ K̃ᵀ ⪯ K̃ Q K̃ᵀ ⪯ t I`, so `‖K̃‖₂ ≤ √t`.
//! `Q ⪰ I` fixes the scale of the homogeneous (7.40) from below (any strictly feasible
//! `(Q, Y)` scales into it), and the objective keeps `Q` from growing (a larger `Q` raises
//! `K̃ Q K̃ᵀ`), so the program is bounded and the optimum is attained: the gain of
//! (nearly) smallest spectral norm `‖K̃‖₂` that (7.40) certifies at `λ_p`. Variables: the six
//! entries of `Q`, the six of `Y`, `t`.
//!
//! # LQR cost bound ([`Objective::Lqr`])
//!
//! For the cost `J = Σ_k T_s (χ̃_kᵀ W_x χ̃_k + u_kᵀ W_u u_k)` (the sampled
//! `∫ χᵀ W χ + uᵀ R u dt`; `W_x = D⁻¹ W D⁻¹` for a weight `W` on `χ`, `W_u = R`) and
//! `u = K̃ χ̃`, `V(χ̃) = γ χ̃ᵀ Q⁻¹ χ̃` bounds `J` from `χ̃_0` at each vertex `v` when `V`
//! decreases by at least the stage cost there:
//! `(A_v + B_v K̃)ᵀ γQ⁻¹ (A_v + B_v K̃) − γQ⁻¹ + T_s (W_x + K̃ᵀ W_u K̃) ⪯ 0`. Multiplied by
//! `Q/γ` on both sides (`Y = K̃ Q`), with two Schur complements, this is linear in
//! `(Q, Y, γ)` (the robust LQR bound in the form of Kothare, Balakrishnan and Morari, 1996):
//!
//! ```text
//! [ Q                  (A_v Q + B_v Y)ᵀ   Q (T_s W_x)^{1/2}   Yᵀ (T_s W_u)^{1/2} ]
//! [ A_v Q + B_v Y      Q                  0                   0                  ]  ⪰ 0
//! [ (T_s W_x)^{1/2} Q  0                  γ I₃                0                  ]
//! [ (T_s W_u)^{1/2} Y  0                  0                   γ I₂               ]
//! ```
//!
//! `γ` is then the largest cost from an initial state on the ellipsoid `χ̃_0ᵀ Q⁻¹ χ̃_0 = 1`
//! at any vertex. The scale of `Q` is fixed, and the decay rate certified strictly, by the
//! normalized (7.41) itself with its margin held at a fraction of the margin design's
//! optimum, `σ = `[`LQR_MARGIN_FRACTION`]` · s*`:
//!
//! ```text
//! minimize γ   subject to   the four LQR inequalities above,
//!                           [ α Q − σ I          A_v Q + B_v Y ]  ⪰ 0   (four vertices, α = e^{−2λT_s}),
//!                           [ (A_v Q + B_v Y)ᵀ   Q             ]
//!                           σ I ⪯ Q ⪯ I.
//! ```
//!
//! (An unnormalized bound, `Q` free and `trace Q⁻¹` minimized with (7.40) at `λ_p`, was
//! tried first: clarabel stops at its reduced accuracy there, whose residual of `10⁻⁴`
//! is larger than the `≈ 10⁻⁶` between `λ_p` and `λ` per sample, and the gain is not
//! certified.) Variables: `Q` (6), `Y` (6), `γ`. The weights are diagonal,
//! `W = diag(w_ẋ, w_ẏ, w_e)` and `R = diag(r, r)`; [`LqrWeights::BRYSON`] takes them from
//! the largest acceptable values (Bryson's rule). The vertex bound is the vertices' only
//! (the cost is not convex in `(k_s, c_s)`); the decay rate is certified on the whole box
//! as for the margin design.

use super::robust_gain::{RobustDesign, RobustGainError, certify_gain};
use super::sdp::{self, SdpError, SdpSolution};
use control::arm::robust::{LmiCertificate, RobustBox, Vertex};
use nalgebra::{DMatrix, Matrix2x3, Matrix3, Vector3};

/// The program's decay rate over the requested one (module docs, Strictness).
pub const RATE_MARGIN: f64 = 1.05;

/// The LQR design's margin `σ` as a fraction of the margin design's optimal `s*`.
pub const LQR_MARGIN_FRACTION: f64 = 0.5;

/// The objective of a robust gain design over the decay-rate inequalities (7.40).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Objective {
    /// The committed design: maximize the margin `s` under `s I ⪯ Q ⪯ I`
    /// ([`super::robust_gain::solve`]).
    Margin,
    /// The smallest `‖K̃‖₂` (module docs).
    MinGain,
    /// The smallest trace of an LQR cost bound with these weights (module docs).
    Lqr(LqrWeights),
}

impl Objective {
    /// `margin`, `min-gain` or `lqr` (the command line's and the file names' word).
    pub fn name(&self) -> &'static str {
        match self {
            Objective::Margin => "margin",
            Objective::MinGain => "min-gain",
            Objective::Lqr(_) => "lqr",
        }
    }
}

/// The diagonal LQR weights on `χ = [ẋ, ẏ, e]` and on both inputs (physical units: the
/// cost is `∫ w_ẋ ẋ² + w_ẏ ẏ² + w_e e² + r |u|² dt`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LqrWeights {
    /// `[w_ẋ, w_ẏ, w_e]`, in (s/m)², (s/m)², 1/N².
    pub state: [f64; 3],
    /// `r` on each input.
    pub input: f64,
}

impl LqrWeights {
    /// Bryson's rule with 0.1 m/s on both velocities, `F_d = 25 N` on the force error and
    /// 10 on the input: `w = 1/(largest acceptable value)²`.
    pub const BRYSON: LqrWeights = LqrWeights {
        state: [100.0, 100.0, 1.0 / 625.0],
        input: 0.01,
    };

    /// Every weight finite and positive.
    pub fn validate(&self) -> Result<(), String> {
        if self
            .state
            .iter()
            .chain([&self.input])
            .all(|w| w.is_finite() && *w > 0.0)
        {
            Ok(())
        } else {
            Err(format!(
                "LQR weights {:?} (state) and {} (input) must be finite and positive",
                self.state, self.input
            ))
        }
    }
}

/// A gain designed with an [`Objective`] other than the margin, certified at the box's
/// decay rate.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectiveDesign {
    /// The objective.
    pub objective: Objective,
    /// The optimal objective value: `t ≥ ‖K̃‖₂²` or `γ`.
    pub value: f64,
    /// The program's solution `(Q̃, Ỹ, s)` (`s = 0` for min-gain, `σ` for LQR).
    pub program: LmiCertificate,
    /// The program's solver status and iterations.
    pub solver: String,
    /// The program stopped at full accuracy.
    pub full_accuracy: bool,
    /// The gain's own certificate at the box's rate: the normalized (7.41) with
    /// `Ỹ = K̃ Q̃` ([`certify_gain`]); its `gain` is `K` and its `margin()` the certified `s`.
    pub certified: RobustDesign,
}

impl ObjectiveDesign {
    /// `K` on `χ = [ẋ, ẏ, e]`.
    pub fn gain(&self) -> Matrix2x3<f64> {
        self.certified.gain
    }
}

fn sym3(x: &[f64]) -> Matrix3<f64> {
    Matrix3::new(x[0], x[1], x[3], x[1], x[2], x[4], x[3], x[4], x[5])
}

fn dm<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_fn(R, C, |i, j| m[(i, j)])
}

/// `[top-left, off; offᵀ, bottom-right]`.
fn block2(tl: &DMatrix<f64>, off: &DMatrix<f64>, br: &DMatrix<f64>) -> DMatrix<f64> {
    let (n, m) = (tl.nrows(), br.nrows());
    let mut out = DMatrix::zeros(n + m, n + m);
    out.view_mut((0, 0), (n, n)).copy_from(tl);
    out.view_mut((0, n), (n, m)).copy_from(off);
    out.view_mut((n, 0), (m, n)).copy_from(&off.transpose());
    out.view_mut((n, n), (m, m)).copy_from(br);
    out
}

/// The decay-rate inequalities (7.40) at `alpha` at every vertex.
fn decay_blocks(
    q: &Matrix3<f64>,
    y: &Matrix2x3<f64>,
    v: &[Vertex],
    alpha: f64,
) -> Vec<DMatrix<f64>> {
    let cert = LmiCertificate {
        q: *q,
        y: *y,
        s: 0.0,
    };
    v.iter()
        .map(|v| dm(&cert.vertex_matrix(v, alpha)))
        .collect()
}

/// The LQR inequality (module docs) at one vertex with `sx = (T_s W_x)^{1/2}` and
/// `su = (T_s W_u)^{1/2}` (diagonal).
fn lqr_block(
    q: &Matrix3<f64>,
    y: &Matrix2x3<f64>,
    v: &Vertex,
    sx: &Matrix3<f64>,
    su: &nalgebra::Matrix2<f64>,
    gamma: f64,
) -> DMatrix<f64> {
    let m = v.a * q + v.b * y;
    let mut l = DMatrix::zeros(11, 11);
    let mut put = |r: usize, c: usize, b: DMatrix<f64>| {
        l.view_mut((r, c), (b.nrows(), b.ncols())).copy_from(&b);
        if r != c {
            l.view_mut((c, r), (b.ncols(), b.nrows()))
                .copy_from(&b.transpose());
        }
    };
    put(0, 0, dm(q));
    put(0, 3, dm(&m.transpose()));
    put(3, 3, dm(q));
    put(0, 6, dm(&(q * sx)));
    put(6, 6, DMatrix::identity(3, 3) * gamma);
    put(0, 9, dm(&(y.transpose() * su)));
    put(9, 9, DMatrix::identity(2, 2) * gamma);
    l
}

/// Designs the gain of `objective` for `design`'s box at `e_0 = force_scale` and certifies
/// it at the box's decay rate. [`Objective::Margin`] is [`super::robust_gain::solve`]'s
/// program, certified the same way (so every objective is reported alike).
pub fn solve(
    design: &RobustBox,
    force_scale: f64,
    objective: Objective,
) -> Result<ObjectiveDesign, RobustGainError> {
    design.validate().map_err(RobustGainError::Box)?;
    if !(force_scale.is_finite() && force_scale > 0.0) {
        return Err(RobustGainError::ForceScale(force_scale));
    }
    let sdp_err = |source: SdpError| RobustGainError::Sdp {
        decay_rate: design.decay_rate,
        source,
    };
    let d = Vector3::new(1.0, 1.0, 1.0 / force_scale);
    let vertices = design.vertices().map(|v| v.scaled(&d));
    let program_box = RobustBox {
        decay_rate: RATE_MARGIN * design.decay_rate,
        ..*design
    };
    let alpha = program_box.contraction().powi(2);
    let q_of = |x: &[f64]| sym3(&x[0..6]);
    let y_of = |x: &[f64]| Matrix2x3::from_row_slice(&x[6..12]);
    let (c, lmis, s_program) = match objective {
        Objective::Margin => {
            let m = super::robust_gain::solve(design, force_scale)?;
            let certified = certify_gain(design, &m.gain, force_scale)?;
            return Ok(ObjectiveDesign {
                objective,
                value: m.margin(),
                program: m.certificate,
                solver: m.solver,
                full_accuracy: m.full_accuracy,
                certified,
            });
        }
        Objective::MinGain => {
            let lmis = sdp::affine_lmis(13, |x| {
                let (q, y) = (q_of(x), y_of(x));
                let mut b = decay_blocks(&q, &y, &vertices, alpha);
                b.push(dm(&(q - Matrix3::identity())));
                b.push(block2(&(DMatrix::identity(2, 2) * x[12]), &dm(&y), &dm(&q)));
                b
            });
            let mut c = vec![0.0; 13];
            c[12] = 1.0;
            (c, lmis, 0.0)
        }
        Objective::Lqr(w) => {
            w.validate().map_err(RobustGainError::Weights)?;
            let ts = design.sample_period;
            // W_x = D⁻¹ W D⁻¹ on χ̃ (diagonal).
            let sx =
                Matrix3::from_diagonal(&Vector3::from_fn(|i, _| (ts * w.state[i]).sqrt() / d[i]));
            let su = nalgebra::Matrix2::identity() * (ts * w.input).sqrt();
            let sigma =
                LQR_MARGIN_FRACTION * super::robust_gain::solve(design, force_scale)?.margin();
            let alpha = design.contraction().powi(2);
            let lmis = sdp::affine_lmis(13, |x| {
                let (q, y) = (q_of(x), y_of(x));
                let mut b: Vec<DMatrix<f64>> = vertices
                    .iter()
                    .map(|v| lqr_block(&q, &y, v, &sx, &su, x[12]))
                    .collect();
                let cert = LmiCertificate { q, y, s: sigma };
                b.extend(vertices.iter().map(|v| dm(&cert.vertex_matrix(v, alpha))));
                b.push(dm(&(q - Matrix3::identity() * sigma)));
                b.push(dm(&(Matrix3::identity() - q)));
                b
            });
            let mut c = vec![0.0; 13];
            c[12] = 1.0;
            (c, lmis, sigma)
        }
    };
    let SdpSolution {
        x,
        cost,
        status,
        full_accuracy,
        iterations,
        ..
    } = sdp::minimize(&c, &lmis).map_err(sdp_err)?;
    let program = LmiCertificate {
        q: q_of(&x),
        y: y_of(&x),
        s: s_program,
    };
    let gain = program.gain().ok_or(RobustGainError::Singular {
        decay_rate: design.decay_rate,
    })? * Matrix3::from_diagonal(&d);
    let certified = certify_gain(design, &gain, force_scale)?;
    Ok(ObjectiveDesign {
        objective,
        value: cost,
        program,
        solver: format!("clarabel {status} in {iterations} iterations"),
        full_accuracy,
        certified,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::design::robust_gain::tests::NARROW;
    use crate::design::robust_gain::{FEASIBILITY_TOLERANCE, MARGIN_TOLERANCE};

    const SCALE: f64 = 100.0;

    fn scaled_norm(k: &Matrix2x3<f64>) -> f64 {
        let kt = k * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, SCALE));
        kt.singular_values().max()
    }

    /// A design's gain is certified at the box's rate with a margin above `least` (7.41),
    /// its (7.40) holds at every vertex with a positive smallest eigenvalue, and the
    /// spectral radii pass.
    fn assert_certified(d: &ObjectiveDesign, least: f64) {
        let c = &d.certified;
        assert!(c.margin() > least, "{:?}: s = {}", d.objective, c.margin());
        assert!(
            c.margins().min() >= -FEASIBILITY_TOLERANCE,
            "{:?}",
            c.margins()
        );
        assert!(c.lyapunov_margins().vertices.iter().all(|m| *m > 0.0));
        assert!(
            NARROW.check_gain(&d.gain(), 30).passed(),
            "{:?}",
            d.objective
        );
    }

    #[test]
    fn the_smallest_gain_is_no_larger_than_the_margin_designs_and_both_are_certified() {
        let margin = solve(&NARROW, SCALE, Objective::Margin).unwrap();
        let small = solve(&NARROW, SCALE, Objective::MinGain).unwrap();
        assert_certified(&margin, MARGIN_TOLERANCE);
        // The min-gain program asks (7.40) at only 1.05 λ, so on this narrow box its gain
        // keeps s ≈ 5e-9 at λ, below the solver's tolerance: for it the vertex margins and
        // the spectral-radius grid check are the evidence, and s must only be positive.
        assert_certified(&small, 0.0);
        let (nm, ns) = (scaled_norm(&margin.gain()), scaled_norm(&small.gain()));
        assert!(ns <= nm, "‖K̃‖ min-gain {ns} > margin {nm}");
        // The bound t ≥ ‖K̃‖² of the program holds at its solution.
        assert!(
            ns * ns <= small.value * (1.0 + 1e-6),
            "{ns}² > t = {}",
            small.value
        );
        // Much smaller, in fact: the margin design is deadbeat in ẋ (K₁₁ ≈ −1/T_s).
        assert!(ns < 0.1 * nm, "{ns} vs {nm}");
    }

    /// `Σ_k A^kᵀ S A^k` by doubling (`A` stable).
    fn lyapunov_sum(a: &Matrix3<f64>, s: &Matrix3<f64>) -> Matrix3<f64> {
        let (mut p, mut ak) = (*s, *a);
        for _ in 0..60 {
            p += ak.transpose() * p * ak;
            ak *= ak;
        }
        p
    }

    #[test]
    fn the_lqr_bound_exceeds_the_true_cost_at_every_vertex() {
        let w = LqrWeights::BRYSON;
        let d = solve(&NARROW, SCALE, Objective::Lqr(w)).unwrap();
        assert_certified(&d, MARGIN_TOLERANCE);
        let k = d.gain();
        let ts = NARROW.sample_period;
        // The cost Σ T_s (χᵀ W χ + uᵀ R u) from χ_0 is χ_0ᵀ P χ_0 (P by the Lyapunov sum);
        // on χ̃ = D χ it is χ̃_0ᵀ D⁻¹ P D⁻¹ χ̃_0, which must be below γ χ̃_0ᵀ Q̃⁻¹ χ̃_0.
        let dinv = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, SCALE));
        let wx = Matrix3::from_diagonal(&Vector3::from(w.state));
        let bound = d.program.q.try_inverse().unwrap() * d.value;
        for v in NARROW.vertices() {
            let acl = v.a + v.b * k;
            let stage = (wx + k.transpose() * k * w.input) * ts;
            let p = dinv * lyapunov_sum(&acl, &stage) * dinv;
            let gap = (bound - p).symmetric_eigenvalues().min();
            assert!(
                gap >= -1e-6 * bound.norm(),
                "vertex ({}, {}): bound − cost has eigenvalue {gap}",
                v.stiffness,
                v.damping
            );
        }
        // Heavier input weight: a smaller gain.
        let heavy = LqrWeights {
            input: 100.0 * w.input,
            ..w
        };
        let h = solve(&NARROW, SCALE, Objective::Lqr(heavy)).unwrap();
        assert_certified(&h, MARGIN_TOLERANCE);
        assert!(
            scaled_norm(&h.gain()) < scaled_norm(&k),
            "{:?} vs {k:?}",
            h.gain()
        );
    }

    #[test]
    fn bad_weights_and_an_uncertifiable_rate_are_errors_or_uncertified() {
        let bad = LqrWeights {
            input: -1.0,
            ..LqrWeights::BRYSON
        };
        let e = solve(&NARROW, SCALE, Objective::Lqr(bad))
            .unwrap_err()
            .to_string();
        assert!(e.contains("must be finite and positive"), "{e}");
        let fast = RobustBox {
            decay_rate: 10_000.0,
            ..NARROW
        };
        match solve(&fast, SCALE, Objective::MinGain) {
            Err(e) => assert!(e.to_string().contains("10000"), "{e}"),
            Ok(d) => assert!(d.certified.margin() <= MARGIN_TOLERANCE, "{d:?}"),
        }
    }
}
