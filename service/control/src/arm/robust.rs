//! The robust state feedback of §7.2.2: the sampler's velocity and force-error model
//! (7.39), its zero-order-hold discretization over the box of surface properties, the
//! Lyapunov inequalities (7.40)–(7.41) and the independent check of a gain `K`.
//!
//! # Model (7.39)
//!
//! On `χ = [ẋ ẏ e]ᵀ` (sampler velocity in m/s, force error `e = F_c − F_d` in N) the
//! feedback-linearized arm (7.33)–(7.36) reduces to `χ̇ = Ā(k_s) χ + B̄(c_s) τ_f` with
//!
//! ```text
//! Ā(k_s) = [ 0    0   0 ]      B̄(c_s) = [ 1    0  ]
//!          [ 0    0   0 ]               [ 0    1  ]
//!          [ 0  −k_s  0 ]               [ 0  −c_s ]
//! ```
//!
//! # Exact zero-order hold
//!
//! `Ā² = 0`, so the series of `e^{Ā T}` stops after two terms and, with `T = T_s`,
//!
//! ```text
//! A_d(k_s)      = I + Ā T                       = [[1, 0, 0], [0, 1, 0], [0, −k_s T, 1]]
//! B_d(k_s, c_s) = (T I + Ā T²/2) B̄              = [[T, 0], [0, T], [0, −c_s T − k_s T²/2]]
//! ```
//!
//! ([`discrete_model`]; the tests compare it with nalgebra's matrix exponential of the
//! augmented matrix `[[Ā T, B̄ T], [0, 0]]`). `B_d` depends on the stiffness as well as on
//! the damping (the `Ā B̄ T²/2` term), which the dissertation's `A_{d,i} + B_{d,j} K`
//! hides. It is still harmless: `Ā B̄ = [[0, 0], [0, 0], [0, −k_s]]` does not involve
//! `c_s`, so `(A_d, B_d)` is *affine in `(k_s, c_s)` jointly*:
//!
//! ```text
//! (A_d, B_d)(k_s, c_s) = (A_0, B_0) + k_s (A_k, B_k) + c_s (0, B_c).
//! ```
//!
//! # Why four vertices cover the box
//!
//! Write (7.41)'s matrix for one `(A, B)` as
//!
//! ```text
//! L(A, B; Q, Y, s) = [ e^{−2λT} Q − s I    A Q + B Y ]
//!                    [ (A Q + B Y)ᵀ          Q       ]
//! ```
//!
//! For fixed `(Q, Y, s)` it is affine in `(A, B)`, hence (by the above) affine in
//! `(k_s, c_s)`. Any point of the box `[k_1, k_2] × [c_1, c_2]` is a convex combination of
//! its four corners, with the bilinear weights `w_{ij} ≥ 0`, `Σ w_{ij} = 1`, and an affine
//! map carries that combination over: `L(k_s, c_s) = Σ w_{ij} L(k_i, c_j)`. A convex
//! combination of positive semidefinite matrices is positive semidefinite, so the four
//! vertex inequalities `L(k_i, c_j) ⪰ 0` give `L ⪰ 0` over the whole box. With `Q ≻ 0` the
//! Schur complement of `L ⪰ 0` is
//! `(A + B K) Q (A + B K)ᵀ ⪯ e^{−2λT} Q − s I` (`K = Y Q⁻¹`), which is (7.40) with a margin
//! `s`: `V(χ) = χᵀ Q⁻¹ χ` is a common Lyapunov function and every `A_d + B_d K` in the box
//! has spectral radius below `e^{−λT}` (strictly when `s > 0`).
//!
//! # The independent check
//!
//! A gain is checked without the LMIs ([`RobustBox::check_gain`]): the spectral radius of
//! `A_d + B_d K` at the four vertices and over a log-spaced grid of `(k_s, c_s)` inside the
//! box, against `e^{−λT}`. That is weaker than the Lyapunov certificate (it is the frozen
//! parameter's decay, not the time-varying one) but depends on nothing the solver did.
//! [`LmiCertificate::margins`] evaluates the smallest eigenvalues of the inequalities of a
//! solver's `(Q, Y, s)`, for the design tool's own tests.
//!
//! The solve of (7.41) itself is a design-time step (`rig-design robust-gain`, with an SDP
//! solver); nothing here allocates (all matrices are fixed-size).

use nalgebra::linalg::Schur;
use nalgebra::{Matrix2x3, Matrix3, Matrix3x2, Matrix6, Vector3};

/// The continuous model (7.39): `(Ā(k_s), B̄(c_s))` on `χ = [ẋ ẏ e]ᵀ`, input `τ_f`.
pub fn continuous_model(stiffness: f64, damping: f64) -> (Matrix3<f64>, Matrix3x2<f64>) {
    let a = Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -stiffness, 0.0);
    let b = Matrix3x2::new(1.0, 0.0, 0.0, 1.0, 0.0, -damping);
    (a, b)
}

/// The exact zero-order-hold discretization of (7.39) at sample period `t`:
/// `A_d = I + Ā T`, `B_d = (T I + Ā T²/2) B̄` (`Ā` is nilpotent).
pub fn discrete_model(stiffness: f64, damping: f64, t: f64) -> (Matrix3<f64>, Matrix3x2<f64>) {
    let a = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -stiffness * t, 1.0);
    let b = Matrix3x2::new(t, 0.0, 0.0, t, 0.0, -damping * t - 0.5 * stiffness * t * t);
    (a, b)
}

/// The largest modulus of the eigenvalues of `m` (a real Schur decomposition); infinite
/// when `m` is not finite or the decomposition does not converge in 1000 sweeps, so that a
/// bad gain never passes a check.
pub fn spectral_radius(m: &Matrix3<f64>) -> f64 {
    if !m.iter().all(|v| v.is_finite()) {
        return f64::INFINITY;
    }
    match Schur::try_new(*m, f64::EPSILON, 1000) {
        Some(schur) => schur
            .complex_eigenvalues()
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max),
        None => f64::INFINITY,
    }
}

/// The design box of §7.2.2: sample period, decay rate and the ranges of the surface's
/// stiffness and damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RobustBox {
    /// Sample period `T_s` (s).
    pub sample_period: f64,
    /// The slowest exponential decay rate `λ` asked of the closed loop (1/s).
    pub decay_rate: f64,
    /// Stiffness range `[k_1, k_2]` (N/m).
    pub stiffness: [f64; 2],
    /// Damping range `[c_1, c_2]` (N s/m).
    pub damping: [f64; 2],
}

/// One corner of the box: its surface properties and the discrete model there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// `k_s` (N/m).
    pub stiffness: f64,
    /// `c_s` (N s/m).
    pub damping: f64,
    /// `A_d(k_s)`.
    pub a: Matrix3<f64>,
    /// `B_d(k_s, c_s)`.
    pub b: Matrix3x2<f64>,
}

impl Vertex {
    /// The same model in scaled coordinates `χ̃ = D χ`, `D = diag(d)`: `(D A D⁻¹, D B)`;
    /// a gain `K̃` on `χ̃` is `K = K̃ D` on `χ`. Spectral radii are unchanged.
    pub fn scaled(&self, d: &Vector3<f64>) -> Vertex {
        let dm = Matrix3::from_diagonal(d);
        let dinv = Matrix3::from_diagonal(&d.map(|v| 1.0 / v));
        Vertex {
            a: dm * self.a * dinv,
            b: dm * self.b,
            ..*self
        }
    }
}

/// The radius of `A_d + B_d K` at one point of the box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RadiusAt {
    /// `k_s` (N/m).
    pub stiffness: f64,
    /// `c_s` (N s/m).
    pub damping: f64,
    /// Spectral radius of `A_d + B_d K` there.
    pub radius: f64,
}

/// The result of [`RobustBox::check_gain`].
#[derive(Debug, Clone, PartialEq)]
pub struct GainCheck {
    /// The bound `e^{−λ T_s}` every radius must stay below.
    pub bound: f64,
    /// The radius at the four vertices, in the order of [`RobustBox::vertices`].
    pub vertices: [RadiusAt; 4],
    /// The largest vertex radius.
    pub worst_vertex: RadiusAt,
    /// The largest radius over the grid (which includes the vertices).
    pub worst_grid: RadiusAt,
    /// Grid points per axis (log-spaced in `k_s` and in `c_s`).
    pub grid: usize,
}

impl GainCheck {
    /// Every vertex and grid radius is below the bound (and finite).
    pub fn passed(&self) -> bool {
        self.worst_vertex.radius < self.bound && self.worst_grid.radius < self.bound
    }
}

impl RobustBox {
    /// The parameters of §7.3: `T_s = 1/2000 s`, `λ = 0.05 /s`, `k_s ∈ [300, 2.7·10⁵] N/m`,
    /// `c_s ∈ [0.35, 10³] N s/m`.
    pub const CHAPTER_7: RobustBox = RobustBox {
        sample_period: 0.0005,
        decay_rate: 0.05,
        stiffness: [300.0, 2.7e5],
        damping: [0.35, 1e3],
    };

    /// `Err` naming the field when a value is not usable: the period and the ranges must
    /// be finite and positive with `low ≤ high`, the decay rate finite and `≥ 0`.
    pub fn validate(&self) -> Result<(), String> {
        let t = self.sample_period;
        if !(t.is_finite() && t > 0.0) {
            return Err(format!("sample-period {t} is not a positive period"));
        }
        let l = self.decay_rate;
        if !(l.is_finite() && l >= 0.0) {
            return Err(format!("decay-rate {l} must be finite and ≥ 0"));
        }
        for (name, [lo, hi]) in [("stiffness", self.stiffness), ("damping", self.damping)] {
            if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo <= hi) {
                return Err(format!(
                    "{name} [{lo}, {hi}] must be finite, positive and increasing"
                ));
            }
        }
        Ok(())
    }

    /// `e^{−λ T_s}`, the bound on the spectral radius (its square is (7.40)'s factor).
    pub fn contraction(&self) -> f64 {
        (-self.decay_rate * self.sample_period).exp()
    }

    /// The discrete model at `(k_s, c_s)` and this box's sample period.
    pub fn model(&self, stiffness: f64, damping: f64) -> (Matrix3<f64>, Matrix3x2<f64>) {
        discrete_model(stiffness, damping, self.sample_period)
    }

    /// The four corners `(k_i, c_j)`, `i, j ∈ {1, 2}`, in the order `(k_1, c_1)`,
    /// `(k_1, c_2)`, `(k_2, c_1)`, `(k_2, c_2)`.
    pub fn vertices(&self) -> [Vertex; 4] {
        let [k1, k2] = self.stiffness;
        let [c1, c2] = self.damping;
        [(k1, c1), (k1, c2), (k2, c1), (k2, c2)].map(|(k, c)| {
            let (a, b) = self.model(k, c);
            Vertex {
                stiffness: k,
                damping: c,
                a,
                b,
            }
        })
    }

    /// `n` log-spaced values over `[lo, hi]`, ends included (`n ≥ 2`; one value when
    /// `lo = hi`).
    fn log_grid(lo: f64, hi: f64, n: usize) -> impl Iterator<Item = f64> {
        let n = if lo == hi { 1 } else { n.max(2) };
        let ratio = hi / lo;
        (0..n).map(move |i| {
            if i + 1 == n {
                hi
            } else {
                lo * ratio.powf(i as f64 / (n - 1) as f64)
            }
        })
    }

    /// The radius of `A_d + B_d K` at `(k_s, c_s)`.
    pub fn radius(&self, gain: &Matrix2x3<f64>, stiffness: f64, damping: f64) -> RadiusAt {
        let (a, b) = self.model(stiffness, damping);
        RadiusAt {
            stiffness,
            damping,
            radius: spectral_radius(&(a + b * gain)),
        }
    }

    /// The independent check of a gain: spectral radius of `A_d + B_d K` at the four
    /// vertices and over a `grid × grid` log-spaced grid of the box, against
    /// `e^{−λ T_s}`.
    pub fn check_gain(&self, gain: &Matrix2x3<f64>, grid: usize) -> GainCheck {
        let vertices = self
            .vertices()
            .map(|v| self.radius(gain, v.stiffness, v.damping));
        let worst = |a: RadiusAt, b: RadiusAt| if b.radius > a.radius { b } else { a };
        let worst_vertex = vertices[1..].iter().copied().fold(vertices[0], worst);
        let [k1, k2] = self.stiffness;
        let [c1, c2] = self.damping;
        let worst_grid = Self::log_grid(k1, k2, grid)
            .flat_map(|k| Self::log_grid(c1, c2, grid).map(move |c| (k, c)))
            .map(|(k, c)| self.radius(gain, k, c))
            .fold(worst_vertex, worst);
        GainCheck {
            bound: self.contraction(),
            vertices,
            worst_vertex,
            worst_grid,
            grid,
        }
    }
}

/// A candidate solution `(Q, Y, s)` of (7.41), in whatever coordinates its vertices use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmiCertificate {
    /// `Q = Qᵀ` (the inverse of the Lyapunov matrix).
    pub q: Matrix3<f64>,
    /// `Y = K Q`.
    pub y: Matrix2x3<f64>,
    /// The margin `s`.
    pub s: f64,
}

/// The smallest eigenvalues of the inequalities of a [`LmiCertificate`] (each must be
/// `≥ 0`, up to the solver's tolerance, for the certificate to hold).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmiMargins {
    /// `λ_min(L(A_i, B_j; Q, Y, s))` at each vertex, in the order of the vertices given.
    pub vertices: [f64; 4],
    /// `λ_min(Q − s I)`.
    pub lower: f64,
    /// `λ_min(I − Q)` (the normalization `Q ⪯ I`).
    pub upper: f64,
}

impl LmiMargins {
    /// The smallest of all the margins.
    pub fn min(&self) -> f64 {
        self.vertices
            .iter()
            .copied()
            .fold(self.lower.min(self.upper), f64::min)
    }
}

impl LmiCertificate {
    /// The gain `K = Y Q⁻¹`; `None` when `Q` is singular.
    pub fn gain(&self) -> Option<Matrix2x3<f64>> {
        self.q.try_inverse().map(|qi| self.y * qi)
    }

    /// The 6×6 matrix `L(A, B; Q, Y, s)` of (7.41) at one vertex, with `α = e^{−2λT}`.
    pub fn vertex_matrix(&self, v: &Vertex, alpha: f64) -> Matrix6<f64> {
        let m = v.a * self.q + v.b * self.y;
        let mut l = Matrix6::zeros();
        l.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.q * alpha - Matrix3::identity() * self.s));
        l.fixed_view_mut::<3, 3>(0, 3).copy_from(&m);
        l.fixed_view_mut::<3, 3>(3, 0).copy_from(&m.transpose());
        l.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.q);
        l
    }

    /// The smallest eigenvalue of every inequality of the normalized (7.41): the four
    /// vertex matrices, `Q − s I` and `I − Q`, with `α = e^{−2λT}` (the square of
    /// [`RobustBox::contraction`]).
    pub fn margins(&self, vertices: &[Vertex; 4], alpha: f64) -> LmiMargins {
        let min_eig6 = |m: Matrix6<f64>| m.symmetric_eigenvalues().min();
        let min_eig3 = |m: Matrix3<f64>| m.symmetric_eigenvalues().min();
        LmiMargins {
            vertices: vertices.map(|v| min_eig6(self.vertex_matrix(&v, alpha))),
            lower: min_eig3(self.q - Matrix3::identity() * self.s),
            upper: min_eig3(Matrix3::identity() - self.q),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix5;

    const BOX: RobustBox = RobustBox::CHAPTER_7;

    #[test]
    fn the_closed_form_zoh_matches_the_matrix_exponential() {
        for &(k, c, t) in &[
            (300.0, 0.35, 0.0005),
            (2.7e5, 1e3, 0.0005),
            (2.7e5, 0.35, 0.01),
            (1234.5, 67.8, 0.003),
        ] {
            let (ac, bc) = continuous_model(k, c);
            let mut m = Matrix5::zeros();
            m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(ac * t));
            m.fixed_view_mut::<3, 2>(0, 3).copy_from(&(bc * t));
            let e = m.exp();
            let (ad, bd) = discrete_model(k, c, t);
            let scale = 1.0 + k * t;
            assert!((e.fixed_view::<3, 3>(0, 0) - ad).abs().max() < 1e-12 * scale);
            assert!((e.fixed_view::<3, 2>(0, 3) - bd).abs().max() < 1e-12 * scale);
        }
    }

    #[test]
    fn the_zoh_model_is_affine_so_the_vertices_interpolate_the_box_exactly() {
        let v = BOX.vertices();
        let [k1, k2] = BOX.stiffness;
        let [c1, c2] = BOX.damping;
        for &(fk, fc) in &[(0.3, 0.7), (0.01, 0.99), (0.5, 0.5), (0.9, 0.2)] {
            let (k, c) = (k1 + fk * (k2 - k1), c1 + fc * (c2 - c1));
            // Bilinear weights of (k1,c1), (k1,c2), (k2,c1), (k2,c2).
            let w = [
                (1.0 - fk) * (1.0 - fc),
                (1.0 - fk) * fc,
                fk * (1.0 - fc),
                fk * fc,
            ];
            let (a, b) = BOX.model(k, c);
            let ai: Matrix3<f64> = (0..4).map(|i| v[i].a * w[i]).sum();
            let bi: Matrix3x2<f64> = (0..4).map(|i| v[i].b * w[i]).sum();
            assert!((ai - a).abs().max() < 1e-12 * k2 * BOX.sample_period);
            assert!((bi - b).abs().max() < 1e-15 * (1.0 + c2));
        }
    }

    /// The eigenvalues of `A_d + B_d K` for a gain that only feeds `ẋ` back to `τ_1` and
    /// `(ẏ, e)` back to `τ_2`: `1 + T κ_x` and the roots of the 2×2 block's
    /// characteristic polynomial.
    fn decoupled_radius(k: f64, c: f64, t: f64, kx: f64, k1: f64, k2: f64) -> f64 {
        let b = -c * t - 0.5 * k * t * t;
        let m = [[1.0 + t * k1, t * k2], [-k * t + b * k1, 1.0 + b * k2]];
        let tr = m[0][0] + m[1][1];
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let disc = tr * tr - 4.0 * det;
        let r2 = if disc >= 0.0 {
            ((tr.abs() + disc.sqrt()) / 2.0).max((tr.abs() - disc.sqrt()).abs() / 2.0)
        } else {
            det.sqrt()
        };
        r2.max((1.0 + t * kx).abs())
    }

    #[test]
    fn the_spectral_radius_matches_the_closed_form_of_a_decoupled_gain() {
        let gains = [
            (-1000.0, -150.0, 0.5),
            (-10.0, 20.0, 0.01),
            (-5000.0, -1.0, 3.0),
        ];
        for &(kx, k1, k2) in &gains {
            let gain = Matrix2x3::new(kx, 0.0, 0.0, 0.0, k1, k2);
            for v in BOX.vertices() {
                let want = decoupled_radius(v.stiffness, v.damping, BOX.sample_period, kx, k1, k2);
                let got = BOX.radius(&gain, v.stiffness, v.damping).radius;
                assert!((got - want).abs() < 1e-9, "{got} vs {want} at {v:?}");
            }
        }
    }

    #[test]
    fn no_feedback_leaves_the_integrators_on_the_unit_circle_and_fails() {
        let check = BOX.check_gain(&Matrix2x3::zeros(), 10);
        assert!((check.worst_vertex.radius - 1.0).abs() < 1e-6);
        assert!(!check.passed());
    }

    #[test]
    fn a_force_gain_too_large_for_the_stiff_damped_surface_fails_there() {
        // 1 + b τ-gain with b = −c_2 T − k_2 T²/2 ≈ −0.53 leaves the unit circle for a
        // force-error gain of 10, but not on the soft surface.
        let gain = Matrix2x3::new(-1000.0, 0.0, 0.0, 0.0, -150.0, 10.0);
        let check = BOX.check_gain(&gain, 12);
        assert!(!check.passed());
        assert_eq!(check.worst_vertex.damping, BOX.damping[1]);
        assert!(check.worst_vertex.radius > 1.0);
        let soft = BOX.radius(&gain, BOX.stiffness[0], BOX.damping[0]);
        assert!(soft.radius < 1.0);
    }

    #[test]
    fn a_modest_decoupled_gain_passes_and_the_grid_contains_the_vertices() {
        let gain = Matrix2x3::new(-1000.0, 0.0, 0.0, 0.0, -100.0, 1.0);
        let check = BOX.check_gain(&gain, 30);
        assert!(check.passed(), "{check:?}");
        assert!(check.worst_grid.radius >= check.worst_vertex.radius);
        for v in check.vertices {
            assert!(v.radius <= check.worst_vertex.radius);
        }
        // The same gain is not fast enough for a decay rate of 10 /s on the soft surface.
        let fast = RobustBox {
            decay_rate: 10.0,
            ..BOX
        };
        let strict = fast.check_gain(&gain, 30);
        assert!(!strict.passed());
        assert_eq!(strict.worst_vertex.stiffness, BOX.stiffness[0]);
    }

    #[test]
    fn a_non_finite_gain_fails() {
        let gain = Matrix2x3::new(f64::NAN, 0.0, 0.0, 0.0, 0.0, 1.0);
        assert!(!BOX.check_gain(&gain, 3).passed());
    }

    /// `Q` solving `F Q Fᵀ − α Q = −W` (a discrete Lyapunov equation) by vectorization.
    fn lyapunov(f: &Matrix3<f64>, alpha: f64, w: &Matrix3<f64>) -> Matrix3<f64> {
        let mut m = nalgebra::SMatrix::<f64, 9, 9>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    for l in 0..3 {
                        // (F Q Fᵀ)_{ij} = Σ_{kl} F_ik Q_kl F_jl
                        m[(i * 3 + j, k * 3 + l)] += f[(i, k)] * f[(j, l)];
                    }
                }
                m[(i * 3 + j, i * 3 + j)] -= alpha;
            }
        }
        let rhs = nalgebra::SVector::<f64, 9>::from_iterator(w.transpose().iter().map(|v| -v));
        let x = m.lu().solve(&rhs).expect("regular Lyapunov operator");
        Matrix3::from_row_slice(x.as_slice())
    }

    #[test]
    fn margins_of_a_lyapunov_certificate_at_one_point_have_the_sign_of_the_slack() {
        // A degenerate box (one point): Q from the Lyapunov equation with W = w I makes the
        // Schur complement of L equal to (w − s) I, so L ⪰ 0 exactly when s ≤ w.
        let point = RobustBox {
            stiffness: [5000.0; 2],
            damping: [20.0; 2],
            ..BOX
        };
        let gain = Matrix2x3::new(-1000.0, 0.0, 0.0, 0.0, -150.0, 0.5);
        let (a, b) = point.model(5000.0, 20.0);
        let alpha = point.contraction().powi(2);
        let w = 1e-4;
        let q = lyapunov(&(a + b * gain), alpha, &(Matrix3::identity() * w));
        let q = (q + q.transpose()) / 2.0;
        let scale = q.symmetric_eigenvalues().max();
        let (q, w) = (q / scale, w / scale);
        let vertices = point.vertices();
        for (s, holds) in [(0.5 * w, true), (2.0 * w, false)] {
            let cert = LmiCertificate { q, y: gain * q, s };
            let m = cert.margins(&vertices, alpha);
            for v in m.vertices {
                assert_eq!(v >= -1e-12, holds, "s = {s}: margin {v}");
            }
            let q_min = q.symmetric_eigenvalues().min();
            assert!((m.lower - (q_min - s)).abs() < 1e-12, "{m:?}");
            assert!(m.upper > -1e-12, "{m:?}");
            let k = cert.gain().unwrap();
            assert!((k - gain).abs().max() < 1e-6 * gain.abs().max());
        }
        // Q ⪯ I is reported too.
        let cert = LmiCertificate {
            q: q * 2.0,
            y: gain * q * 2.0,
            s: 0.0,
        };
        assert!(cert.margins(&vertices, alpha).upper < 0.0);
    }

    #[test]
    fn scaling_the_state_keeps_the_radius_and_maps_the_gain() {
        let d = Vector3::new(10.0, 10.0, 1.0 / 200.0);
        let gain_scaled = Matrix2x3::new(-1000.0, 0.0, 0.0, 0.0, -150.0, 100.0);
        let gain = gain_scaled * Matrix3::from_diagonal(&d);
        for v in BOX.vertices() {
            let s = v.scaled(&d);
            let r1 = spectral_radius(&(s.a + s.b * gain_scaled));
            let r2 = spectral_radius(&(v.a + v.b * gain));
            assert!((r1 - r2).abs() < 1e-9);
        }
    }

    #[test]
    fn bad_boxes_are_named() {
        let bad = RobustBox {
            damping: [1e3, 0.35],
            ..BOX
        };
        assert!(bad.validate().unwrap_err().contains("damping"));
        let bad = RobustBox {
            sample_period: 0.0,
            ..BOX
        };
        assert!(bad.validate().unwrap_err().contains("sample-period"));
        let bad = RobustBox {
            decay_rate: f64::NAN,
            ..BOX
        };
        assert!(bad.validate().unwrap_err().contains("decay-rate"));
        assert!(BOX.validate().is_ok());
    }
}
