//! The feedback linearization of the sampling arm (7.31), the error dynamics it leaves
//! (7.32)–(7.38), their zero-order-hold model and the PCAC prior `w_0` of §7.3.
//!
//! # Partition (7.30)
//!
//! With `p = [x y]ᵀ` the sampler's position, `θ̄ = [θ_1 θ_2]ᵀ`, and the blocks of
//! [`Partition`]:
//!
//! ```text
//! M = [ M_1   M_2   ]      D = [ D_1    D_2 ]                                     (7.30)
//!     [ M_2ᵀ  m_0 I ]          [ D_21   0   ]
//! ```
//!
//! (7.30) prints the lower-left block of `D` as `D_2ᵀ`. From (7.24) it is `Ṁ_2ᵀ`: the
//! rows 3–4 of `½ [I_4 ⊗ q̇ᵀ] ∂M/∂q` are `½ q̇ᵀ ∂M/∂x`, `½ q̇ᵀ ∂M/∂y`, which vanish, so
//! rows 3–4 of `D` are those of `Ṁ` (lower-right `ṁ_0 I = 0`). `D_2ᵀ` differs from it by
//! `½ [θ̇ᵀ ∂M_2/∂θ_1; θ̇ᵀ ∂M_2/∂θ_2]ᵀ`, so that using `D_2ᵀ` would leave a term quadratic in
//! `θ̇` uncancelled. Everything here uses `D_21 = Ṁ_2ᵀ` ([`Partition::d21`]) where
//! (7.30), (7.31) and (7.35) print `D_2ᵀ`.
//!
//! # The torques (7.31)
//!
//! Rows 3–4 and 1–2 of (7.1) with `Q = [L τ; F_f; F_c]` (7.26) read
//!
//! ```text
//! M_2ᵀ θ̈ + m_0 p̈ + D_21 θ̇ = [F_f; F_c]                                            (a)
//! M_1 θ̈ + M_2 p̈ + D_1 θ̇ + D_2 ṗ = L τ                                            (b)
//! ```
//!
//! `(a)` gives `θ̈ = M_2^{−T} ([F_f; F_c] − m_0 p̈ − D_21 θ̇)` (c), and `(c)` in `(b)`:
//!
//! ```text
//! L τ = (D_1 − M_1 M_2^{−T} D_21) θ̇ + D_2 ṗ + M_1 M_2^{−T} [F_f; F_c] + N p̈,
//! N ≜ M_2 − m_0 M_1 M_2^{−T}.                                                          (d)
//! ```
//!
//! The controller measures `θ̄, θ̇, ṗ, F_c` but not the friction `F_f`, and asks for
//! `p̈ = τ_f`: (7.31) is `(d)` with `p̈ → τ_f` and `F_f → 0`,
//!
//! ```text
//! τ = L⁻¹ [ (D_1 − M_1 M_2^{−T} D_21) θ̇ + D_2 ṗ + M_1 M_2^{−T} [0; 1] F_c + N τ_f ]  (7.31)
//!   = L⁻¹ (h + N τ_f)                                                       ([`FlTerms`])
//! ```
//!
//! # The closed loop (7.33)–(7.38)
//!
//! Subtracting (7.31) from `(d)`: `N (p̈ − τ_f) + M_1 M_2^{−T} [1; 0] F_f = 0`, so
//!
//! ```text
//! p̈ = τ_f − ξ [1; 0] F_f,          ξ ≜ N⁻¹ M_1 M_2^{−T}                         (7.38)
//! θ̈ = −M_2^{−T} D_21 θ̇ − m_0 M_2^{−T} τ_f + M_2^{−T} [0; 1] F_c
//!     + M_2^{−T} (I + m_0 ξ) [1; 0] F_f                                            by (c)
//! ė = −k_s ẏ − c_s ÿ = −k_s ẏ − c_s τ_{2,f} + c_s [0 1] ξ [1; 0] F_f        by (7.32)
//! ```
//!
//! and with `F_c = e + F_d` in the `θ̈` rows, for `ζ = [θ̇_1 θ̇_2 ẋ ẏ e]ᵀ` (7.34):
//!
//! ```text
//! ζ̇ = A ζ + B τ_f + E F_f + c F_d                                                   (7.33)
//! A = [ −M_2^{−T} D_21   0 0   M_2^{−T}[0; 1] ]      B = [ −m_0 M_2^{−T} ]
//!     [  0_{2×2}         0 0   0              ]          [  I_2          ]
//!     [  0  0            0 −k_s  0            ]          [  0   −c_s     ]          (7.35)–(7.36)
//! E = [ M_2^{−T} (I + m_0 ξ) [1; 0] ;  −ξ [1; 0] ;  c_s [0 1] ξ [1; 0] ]            (7.37)
//! c = [ M_2^{−T} [0; 1] ;  0 ;  0 ;  0 ]
//! ```
//!
//! ([`ErrorDynamics`]; `A` depends on `θ̇` through `D_21`, so (7.33) is exact at the state
//! it is evaluated at). Compared with the printed equations:
//!
//! - **`B`'s `θ̈` rows are `−m_0 M_2^{−T}`**; (7.36) prints `+M_2^{−T} m_0 I_2`.
//! - **`E`** (7.37) prints `M_2^{−T} [1; 0]`, `ξ [1; 0]`, `−c_s [0 1] ξ [1; 0]`: the `p`
//!   and `e` rows with the opposite sign (as if `p̈ = τ_f + ξ [1; 0] F_f`), and the `θ̈`
//!   rows without the `m_0 ξ` part that the friction's effect on `p̈` brings in.
//! - **The constant `c F_d`** is missing from (7.33): `θ̈` sees `F_c = e + F_d`, not `e`.
//!   It does not enter the `χ = [ẋ ẏ e]` dynamics of the robust design (7.39) nor the
//!   discrete model below (an input–output model (7.42) has no constant term).
//! - `D_21` for `D_2ᵀ`, as above.
//!
//! The tests check `(A, B, E, c)` against [`ArmModel::accelerations`] at many states
//! with friction and show that the printed `B` and `E` do not reproduce it.
//!
//! # The discrete model and the PCAC prior (§7.3)
//!
//! `(A_d, B_d)` is the exact zero-order-hold discretization of `(A, B)` at `T_s`: the
//! top blocks of `exp([[A, B], [0, 0]] T_s)` ([`zoh`]). §7.3 initializes PCAC "to match"
//! it at `k_s = 100` N/m, `c_s = 10³` N s/m and the contact state `θ̄_0 = (π/4, π/2)`,
//! `q̇ = (0, 0, 0, −0.1)` ([`ContactPrior::CHAPTER_7`]): the model (7.42) with `n̂ = 1`,
//! `ŷ_k = −F̂_1 y_{k−1} + Ĝ_1 τ_{f,k−1}`, equals `ζ_k = A_d ζ_{k−1} + B_d τ_{f,k−1}` for
//!
//! ```text
//! F̂_1 = −A_d,   Ĝ_1 = B_d,   w_0 = vec [F̂_1 Ĝ_1]  (35 values, column-stacked (7.45))
//! ```
//!
//! ([`FeedbackLinearization::pcac_prior`], in the order of
//! [`IoModelParams::theta0`](crate::pcac::IoModelParams::theta0)).
//!
//! # Real time
//!
//! [`FeedbackLinearization::terms`] and [`FlTerms`] work on nalgebra's fixed-size types:
//! no allocation, no panic; a singular `M_2` (the arm stretched, `sin θ_2 = 0`) or a
//! non-finite result gives `None`. The discretization and the prior allocate (they are
//! for configuration time).

use nalgebra::{DMatrix, Matrix2, SMatrix, Vector2, Vector4};

use super::dynamics::{ArmModel, ArmParams, Partition, TORQUE_MAP};
use crate::ParamError;

/// `5 × 5` matrices of the error dynamics.
pub type Matrix5 = SMatrix<f64, 5, 5>;
/// `5 × 2` matrices of the error dynamics.
pub type Matrix5x2 = SMatrix<f64, 5, 2>;
/// Vectors of the error state `ζ` (7.34).
pub type Vector5 = SMatrix<f64, 5, 1>;

/// `L⁻¹ = [[1, −1], [0, 1]]`, the inverse of [`TORQUE_MAP`].
pub const TORQUE_MAP_INV: Matrix2<f64> = Matrix2::new(1.0, -1.0, 0.0, 1.0);

/// The terms of (7.31) at one measurement: `L τ = h + N τ_f` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlTerms {
    /// `h = (D_1 − M_1 M_2^{−T} D_21) θ̇ + D_2 ṗ + M_1 M_2^{−T} [0; 1] F_c`.
    pub h: Vector2<f64>,
    /// `N = M_2 − m_0 M_1 M_2^{−T}`.
    pub n: Matrix2<f64>,
}

impl FlTerms {
    /// The joint torques (7.31) for the virtual input `τ_f`: `τ = L⁻¹ (h + N τ_f)`.
    #[inline]
    pub fn torques(&self, tau_f: &Vector2<f64>) -> Vector2<f64> {
        TORQUE_MAP_INV * (self.h + self.n * tau_f)
    }

    /// The virtual input that the torques `τ` amount to: `τ_f = N⁻¹ (L τ − h)` (the
    /// inverse of [`FlTerms::torques`]); `None` when `N` is singular or the result not
    /// finite.
    #[inline]
    pub fn virtual_input(&self, tau: &Vector2<f64>) -> Option<Vector2<f64>> {
        let v = self.n.try_inverse()? * (TORQUE_MAP * tau - self.h);
        v.iter().all(|x| x.is_finite()).then_some(v)
    }
}

/// The error dynamics (7.33) at one state: `ζ̇ = A ζ + B τ_f + E F_f + c F_d` (module docs,
/// with the signs derived there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorDynamics {
    /// `A` (7.35).
    pub a: Matrix5,
    /// `B` (7.36).
    pub b: Matrix5x2,
    /// `E` (7.37), the friction's input.
    pub e: Vector5,
    /// `c`, the desired force's input (`θ̈` sees `F_c = e + F_d`).
    pub c: Vector5,
}

/// The surface and the state at which §7.3 builds PCAC's prior `w_0` (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPrior {
    /// Surface stiffness `k_s` of the linear contact model (7.27), N/m.
    pub k_s: f64,
    /// Surface damping `c_s` (7.27), N s/m.
    pub c_s: f64,
    /// The joint angles `θ̄` at contact, rad.
    pub theta: [f64; 2],
    /// `q̇ = [θ̇_1 θ̇_2 ẋ ẏ]` at contact.
    pub qd: [f64; 4],
}

impl ContactPrior {
    /// §7.3: `k_s = 100` N/m, `c_s = 10³` N s/m, `θ̄_0 = (π/4, π/2)` and the descent at
    /// 0.1 m/s, `q̇ = (0, 0, 0, −0.1)`.
    pub const CHAPTER_7: ContactPrior = ContactPrior {
        k_s: 100.0,
        c_s: 1000.0,
        theta: [std::f64::consts::FRAC_PI_4, std::f64::consts::FRAC_PI_2],
        qd: [0.0, 0.0, 0.0, -0.1],
    };

    /// Checks the values: `k_s`, `c_s` finite and `≥ 0`, the state finite. Fields are
    /// named as in the arm controller's `[controller.pcac.prior]` table
    /// (`"pcac.prior.k-s"`, …).
    ///
    /// # Errors
    ///
    /// The first refused field.
    pub fn validate(&self) -> Result<(), ParamError> {
        if !(self.k_s.is_finite() && self.k_s >= 0.0) {
            return Err(ParamError::new(
                "pcac.prior.k-s",
                format!("{} N/m must be finite and ≥ 0", self.k_s),
            ));
        }
        if !(self.c_s.is_finite() && self.c_s >= 0.0) {
            return Err(ParamError::new(
                "pcac.prior.c-s",
                format!("{} N s/m must be finite and ≥ 0", self.c_s),
            ));
        }
        if self.theta.iter().any(|v| !v.is_finite()) {
            return Err(ParamError::new("pcac.prior.theta", "must be finite"));
        }
        if self.qd.iter().any(|v| !v.is_finite()) {
            return Err(ParamError::new("pcac.prior.qd", "must be finite"));
        }
        Ok(())
    }
}

/// The feedback linearization (7.31) of one spacecraft (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackLinearization {
    model: ArmModel,
}

/// `q = [θ̄; 0; 0]`: `M` and `D` do not depend on `x`, `y`.
#[inline]
fn coordinates(theta: &Vector2<f64>) -> Vector4<f64> {
    Vector4::new(theta[0], theta[1], 0.0, 0.0)
}

impl FeedbackLinearization {
    /// The linearization for the nominal spacecraft `params`.
    pub fn new(params: ArmParams) -> Self {
        Self {
            model: ArmModel::new(params),
        }
    }

    /// The model it linearizes.
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The blocks of (7.30) and `M_2^{−T}` at `(θ̄, q̇)`; `None` when `M_2` is singular.
    fn blocks(&self, theta: &Vector2<f64>, qd: &Vector4<f64>) -> Option<(Partition, Matrix2<f64>)> {
        let part = self.model.partition(&coordinates(theta), qd);
        let m2_inv_t = part.m2.transpose().try_inverse()?;
        m2_inv_t
            .iter()
            .all(|v| v.is_finite())
            .then_some((part, m2_inv_t))
    }

    /// `h` and `N` of (7.31) from the measured `θ̄`, `q̇ = [θ̇_1 θ̇_2 ẋ ẏ]` and `F_c`;
    /// `None` when `M_2` is singular or a term is not finite. Never allocates.
    pub fn terms(&self, theta: &Vector2<f64>, qd: &Vector4<f64>, f_c: f64) -> Option<FlTerms> {
        let (part, m2_inv_t) = self.blocks(theta, qd)?;
        let m1_m2 = part.m1 * m2_inv_t;
        let theta_d = Vector2::new(qd[0], qd[1]);
        let p_d = Vector2::new(qd[2], qd[3]);
        let h =
            (part.d1 - m1_m2 * part.d21) * theta_d + part.d2 * p_d + m1_m2 * Vector2::new(0.0, f_c);
        let n = part.m2 - part.m0 * m1_m2;
        let terms = FlTerms { h, n };
        (h.iter().chain(n.iter()).all(|v| v.is_finite())).then_some(terms)
    }

    /// The joint torques (7.31) for the virtual input `τ_f`; `None` as for
    /// [`FeedbackLinearization::terms`] or when the torques are not finite.
    pub fn torques(
        &self,
        theta: &Vector2<f64>,
        qd: &Vector4<f64>,
        f_c: f64,
        tau_f: &Vector2<f64>,
    ) -> Option<Vector2<f64>> {
        let tau = self.terms(theta, qd, f_c)?.torques(tau_f);
        tau.iter().all(|v| v.is_finite()).then_some(tau)
    }

    /// The error dynamics (7.33)–(7.38) at `(θ̄, q̇)` for the surface `(k_s, c_s)`;
    /// `None` when `M_2` or `N` is singular.
    pub fn error_dynamics(
        &self,
        theta: &Vector2<f64>,
        qd: &Vector4<f64>,
        k_s: f64,
        c_s: f64,
    ) -> Option<ErrorDynamics> {
        let (part, m2_inv_t) = self.blocks(theta, qd)?;
        let n = part.m2 - part.m0 * part.m1 * m2_inv_t;
        let xi = n.try_inverse()? * part.m1 * m2_inv_t;
        let xi_f = xi.column(0).into_owned();
        let mut a = Matrix5::zeros();
        a.fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&(-m2_inv_t * part.d21));
        a.fixed_view_mut::<2, 1>(0, 4)
            .copy_from(&m2_inv_t.column(1));
        a[(4, 3)] = -k_s;
        let mut b = Matrix5x2::zeros();
        b.fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&(-part.m0 * m2_inv_t));
        b[(2, 0)] = 1.0;
        b[(3, 1)] = 1.0;
        b[(4, 1)] = -c_s;
        let theta_f = m2_inv_t * (Vector2::new(1.0, 0.0) + part.m0 * xi_f);
        let e = Vector5::new(theta_f[0], theta_f[1], -xi_f[0], -xi_f[1], c_s * xi_f[1]);
        let c = Vector5::new(m2_inv_t[(0, 1)], m2_inv_t[(1, 1)], 0.0, 0.0, 0.0);
        let finite = a
            .iter()
            .chain(&b)
            .chain(&e)
            .chain(&c)
            .all(|v| v.is_finite());
        finite.then_some(ErrorDynamics { a, b, e, c })
    }

    /// `(A_d, B_d)`: the zero-order-hold discretization at `ts` of `(A, B)` (7.35)–(7.36)
    /// at the prior's state and surface (module docs). Allocates.
    ///
    /// # Errors
    ///
    /// A refused prior ([`ContactPrior::validate`], as text), a singular `M_2` at its
    /// state, or a period that is not positive and finite.
    pub fn discrete_model(
        &self,
        prior: &ContactPrior,
        ts: f64,
    ) -> Result<(DMatrix<f64>, DMatrix<f64>), String> {
        prior.validate().map_err(|e| e.to_string())?;
        let theta = Vector2::from(prior.theta);
        let qd = Vector4::from(prior.qd);
        let dynamics = self
            .error_dynamics(&theta, &qd, prior.k_s, prior.c_s)
            .ok_or_else(|| {
                format!(
                    "the arm is singular at θ̄ = ({}, {}) (M_2 or N not invertible)",
                    prior.theta[0], prior.theta[1]
                )
            })?;
        let a = DMatrix::from_fn(5, 5, |i, j| dynamics.a[(i, j)]);
        let b = DMatrix::from_fn(5, 2, |i, j| dynamics.b[(i, j)]);
        zoh(&a, &b, ts)
    }

    /// PCAC's prior `w_0 = vec [F̂_1 Ĝ_1]`, `F̂_1 = −A_d`, `Ĝ_1 = B_d` (module docs): 35
    /// values in the order of `IoModelParams::theta0` (`θ[c·5 + r] = Θ̃[r, c]`) for
    /// `n̂ = 1`, `p = 5`, `m = 2`. Allocates.
    ///
    /// # Errors
    ///
    /// As [`FeedbackLinearization::discrete_model`].
    pub fn pcac_prior(&self, prior: &ContactPrior, ts: f64) -> Result<Vec<f64>, String> {
        let (ad, bd) = self.discrete_model(prior, ts)?;
        let (p, m) = (5, 2);
        let mut theta = vec![0.0; p * (p + m)];
        for c in 0..p + m {
            for r in 0..p {
                theta[c * p + r] = if c < p { -ad[(r, c)] } else { bd[(r, c - p)] };
            }
        }
        Ok(theta)
    }
}

/// The exact zero-order-hold discretization of `ẋ = A x + B u` at the period `ts`:
/// `A_d = e^{A T_s}`, `B_d = ∫_0^{T_s} e^{A s} ds B`, the top blocks of
/// `exp([[A, B], [0, 0]] T_s)` (nalgebra's matrix exponential). Allocates.
///
/// # Errors
///
/// When `A` is not square, `B` has another number of rows, an entry is not finite, or
/// `ts` is not positive and finite.
pub fn zoh(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    ts: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>), String> {
    let (n, m) = (a.nrows(), b.ncols());
    if a.ncols() != n || b.nrows() != n {
        return Err(format!(
            "A is {}×{} and B {}×{}: need a square A and B with as many rows",
            a.nrows(),
            a.ncols(),
            b.nrows(),
            m
        ));
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(format!("the period {ts} s must be positive and finite"));
    }
    if a.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err("A and B must be finite".into());
    }
    let mut aug = DMatrix::zeros(n + m, n + m);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * ts));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * ts));
    let e = aug.exp();
    Ok((
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    ))
}

#[cfg(test)]
mod tests;
