//! The planar spacecraft with a two-link sampling arm, dissertation §7.1, (7.1)–(7.26).
//!
//! Generalized coordinates `q = [θ_1 θ_2 x y]ᵀ` (7.2): the relative joint angles and the
//! sampler's position relative to the surface. Five rigid bodies: the sampler `m_s` at
//! `(x, y)`, link 1 (`m_1`, `Ī_1`) with its centre of mass at `R_1` along it, link 2
//! (`m_2`, `Ī_2`) at `L_1` then `R_2`, and the spacecraft bus `m_sc` at the far end,
//! `L_1` then `L_2` (7.3)–(7.5).
//!
//! # Velocities (7.9)–(7.14)
//!
//! Every translating body's velocity is `J(q) q̇` with a `2 × 4` Jacobian of one shape:
//! a point at `a` along link 1 and then `b` along link 2 (`s_1 = sin θ_1`,
//! `s_12 = sin(θ_1 + θ_2)`, …)
//!
//! ```text
//! J_{a,b}(q) = [ −a s_1 − b s_12   −b s_12   1  0 ]
//!              [  a c_1 + b c_12    b c_12   0  1 ]
//! ```
//!
//! with `(a, b) = (0, 0)` for the sampler (`A`, (7.9)), `(R_1, 0)` for link 1 (`B`,
//! (7.10)), `(L_1, R_2)` for link 2 (`C`, (7.11)) and `(L_1, L_2)` for the bus (`D`,
//! (7.12)). The link rotations are `E q̇ = θ̇_1` (7.13) and `F q̇ = θ̇_1 + θ̇_2` (7.14).
//!
//! # Mass matrix (7.15)–(7.16)
//!
//! ```text
//! T = ½ q̇ᵀ M(q) q̇,   M = m_s AᵀA + m_1 BᵀB + m_2 CᵀC + m_sc DᵀD + Ī_1 EᵀE + Ī_2 FᵀF
//! ```
//!
//! `M` depends on `θ_1`, `θ_2` only, and its lower-right block is `m_0 I_2`,
//! `m_0 = m_sc + m_1 + m_2 + m_s` (7.30). Its partial derivatives are exact, by the
//! product rule (7.17): `∂(JᵀJ)/∂θ_i = (∂J/∂θ_i)ᵀ J + Jᵀ ∂J/∂θ_i`, with
//!
//! ```text
//! ∂J_{a,b}/∂θ_1 = [ −a c_1 − b c_12   −b c_12   0  0 ]     ∂J_{a,b}/∂θ_2 = [ −b c_12  −b c_12  0  0 ]
//!                 [ −a s_1 − b s_12   −b s_12   0  0 ]                     [ −b s_12  −b s_12  0  0 ]
//! ```
//!
//! and `∂M/∂x = ∂M/∂y = 0`.
//!
//! # Equations of motion (7.19)–(7.26)
//!
//! ```text
//! M(q) q̈ + D(q, q̇) q̇ = Q                                                    (7.1)
//! D(q, q̇) = Ṁ − ½ [I_4 ⊗ q̇ᵀ] ∂M/∂q,   Ṁ = Σ_i q̇_i ∂M/∂q_i                (7.21)–(7.24)
//! Q = [τ_1 + τ_2,  τ_2,  F_f,  F_c]ᵀ                                          (7.25)–(7.26)
//! ```
//!
//! Row `i` of `½ [I_4 ⊗ q̇ᵀ] ∂M/∂q` is `½ q̇ᵀ ∂M/∂q_i`, so rows 3 and 4 are zero. `D` is
//! not skew-related to `Ṁ` entry by entry; what the derivation gives is the energy
//! identity `q̇ᵀ (Ṁ − 2D) q̇ = 0` (so `dT/dt = q̇ᵀ Q`), which the tests check. An extra
//! force `f` on the bus (the thrusters of the guidance, not part of (7.26)) adds
//! `D_busᵀ f` to `Q` ([`ArmModel::bus_force`]).
//!
//! # Real time
//!
//! Everything here works on nalgebra's fixed-size types: nothing allocates, nothing
//! panics; the solve of (7.1) returns `None` when `M` is not positive definite.

use nalgebra::{Matrix2, Matrix2x4, Matrix4, Vector2, Vector4};

/// The physical parameters of §7.3 (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmParams {
    /// Spacecraft bus mass `m_sc` (kg).
    pub m_sc: f64,
    /// Link 1 mass `m_1` (kg).
    pub m1: f64,
    /// Link 2 mass `m_2` (kg).
    pub m2: f64,
    /// Sampler mass `m_s` (kg).
    pub m_s: f64,
    /// Link 1 length `L_1` (m).
    pub l1: f64,
    /// Link 2 length `L_2` (m).
    pub l2: f64,
    /// Distance from the sampler end of link 1 to its centre of mass `R_1` (m).
    pub r1: f64,
    /// Distance from the joint to link 2's centre of mass `R_2` (m).
    pub r2: f64,
    /// Link 1 centroidal inertia `Ī_1` (kg m²).
    pub i1: f64,
    /// Link 2 centroidal inertia `Ī_2` (kg m²).
    pub i2: f64,
}

impl ArmParams {
    /// The spacecraft of §7.3: `m_sc = 420` kg, `m_1 = m_2 = m_s = 1` kg,
    /// `L_1 = L_2 = 2` m, `R_1 = R_2 = 1` m, `Ī_1 = Ī_2 = 1/3` kg m².
    pub const CHAPTER_7: ArmParams = ArmParams {
        m_sc: 420.0,
        m1: 1.0,
        m2: 1.0,
        m_s: 1.0,
        l1: 2.0,
        l2: 2.0,
        r1: 1.0,
        r2: 1.0,
        i1: 1.0 / 3.0,
        i2: 1.0 / 3.0,
    };

    /// `m_0 = m_sc + m_1 + m_2 + m_s` (7.30).
    pub fn total_mass(&self) -> f64 {
        self.m_sc + self.m1 + self.m2 + self.m_s
    }

    /// The name of the first parameter that is not finite and positive, if any.
    pub fn invalid_field(&self) -> Option<&'static str> {
        let fields = [
            ("m-sc", self.m_sc),
            ("m1", self.m1),
            ("m2", self.m2),
            ("m-s", self.m_s),
            ("l1", self.l1),
            ("l2", self.l2),
            ("r1", self.r1),
            ("r2", self.r2),
            ("i1", self.i1),
            ("i2", self.i2),
        ];
        fields
            .iter()
            .find(|(_, v)| !(v.is_finite() && *v > 0.0))
            .map(|(name, _)| *name)
    }
}

/// `L = [[1, 1], [0, 1]]`: the map from the joint torques to the generalized forces on
/// `θ_1`, `θ_2` (7.26), `Q_θ = L τ`.
pub const TORQUE_MAP: Matrix2<f64> = Matrix2::new(1.0, 1.0, 0.0, 1.0);

/// The model (7.1)–(7.26) of one spacecraft ([`ArmParams`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArmModel {
    /// The parameters.
    pub params: ArmParams,
}

/// The blocks of (7.30): `M = [[M_1, M_2], [M_2ᵀ, m_0 I]]`,
/// `D = [[D_1, D_2], [D_21, 0]]`.
///
/// (7.30) writes the lower-left block of `D` as `D_2ᵀ`; from (7.24) it is `Ṁ_2ᵀ`
/// (row 3 and 4 of `½ [I ⊗ q̇ᵀ] ∂M/∂q` vanish), which differs from `D_2ᵀ` by
/// `½ [θ̇ᵀ ∂M_2/∂θ_1; θ̇ᵀ ∂M_2/∂θ_2]ᵀ`. The blocks are kept as (7.24) defines them, so that
/// the feedback linearization cancels exactly the plant's terms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Partition {
    /// `M_1(θ̄)`, the arm block.
    pub m1: Matrix2<f64>,
    /// `M_2(θ̄)`, the arm–sampler coupling.
    pub m2: Matrix2<f64>,
    /// `m_0`, the total mass.
    pub m0: f64,
    /// `D_1(θ̄, q̇)`.
    pub d1: Matrix2<f64>,
    /// `D_2(θ̄, q̇)`.
    pub d2: Matrix2<f64>,
    /// The lower-left block of `D` (`Ṁ_2ᵀ`).
    pub d21: Matrix2<f64>,
}

/// `J_{a,b}(q)` and its partial derivatives with respect to `θ_1`, `θ_2` (module docs).
fn jacobian(a: f64, b: f64, th1: f64, th2: f64) -> [Matrix2x4<f64>; 3] {
    let (s1, c1) = th1.sin_cos();
    let (s12, c12) = (th1 + th2).sin_cos();
    let j = Matrix2x4::new(
        -a * s1 - b * s12,
        -b * s12,
        1.0,
        0.0,
        a * c1 + b * c12,
        b * c12,
        0.0,
        1.0,
    );
    let d1 = Matrix2x4::new(
        -a * c1 - b * c12,
        -b * c12,
        0.0,
        0.0,
        -a * s1 - b * s12,
        -b * s12,
        0.0,
        0.0,
    );
    let d2 = Matrix2x4::new(-b * c12, -b * c12, 0.0, 0.0, -b * s12, -b * s12, 0.0, 0.0);
    [j, d1, d2]
}

impl ArmModel {
    /// The model of `params`.
    pub fn new(params: ArmParams) -> Self {
        Self { params }
    }

    /// The translating bodies as `(mass, a, b)`: sampler, link 1, link 2, bus.
    fn bodies(&self) -> [(f64, f64, f64); 4] {
        let p = &self.params;
        [
            (p.m_s, 0.0, 0.0),
            (p.m1, p.r1, 0.0),
            (p.m2, p.l1, p.r2),
            (p.m_sc, p.l1, p.l2),
        ]
    }

    /// `M(q)` (7.16) and `∂M/∂θ_1`, `∂M/∂θ_2` (exact, module docs).
    pub fn mass_matrix_with_partials(&self, q: &Vector4<f64>) -> [Matrix4<f64>; 3] {
        let p = &self.params;
        let mut m = Matrix4::zeros();
        let mut dm1 = Matrix4::zeros();
        let mut dm2 = Matrix4::zeros();
        for (mass, a, b) in self.bodies() {
            let [j, j1, j2] = jacobian(a, b, q[0], q[1]);
            m += mass * j.transpose() * j;
            let t1 = j1.transpose() * j;
            let t2 = j2.transpose() * j;
            dm1 += mass * (t1 + t1.transpose());
            dm2 += mass * (t2 + t2.transpose());
        }
        // Ī_1 EᵀE + Ī_2 FᵀF, E = [1 0 0 0], F = [1 1 0 0].
        m[(0, 0)] += p.i1 + p.i2;
        m[(0, 1)] += p.i2;
        m[(1, 0)] += p.i2;
        m[(1, 1)] += p.i2;
        [m, dm1, dm2]
    }

    /// `M(q)` (7.16).
    pub fn mass_matrix(&self, q: &Vector4<f64>) -> Matrix4<f64> {
        self.mass_matrix_with_partials(q)[0]
    }

    /// `D(q, q̇)` (7.24) from `M`'s partial derivatives.
    pub fn damping_from_partials(dm: &[Matrix4<f64>; 3], qd: &Vector4<f64>) -> Matrix4<f64> {
        let (dm1, dm2) = (&dm[1], &dm[2]);
        let mut d = dm1 * qd[0] + dm2 * qd[1];
        let half1 = 0.5 * (qd.transpose() * dm1);
        let half2 = 0.5 * (qd.transpose() * dm2);
        for c in 0..4 {
            d[(0, c)] -= half1[c];
            d[(1, c)] -= half2[c];
        }
        d
    }

    /// `D(q, q̇)` (7.24).
    pub fn damping_matrix(&self, q: &Vector4<f64>, qd: &Vector4<f64>) -> Matrix4<f64> {
        Self::damping_from_partials(&self.mass_matrix_with_partials(q), qd)
    }

    /// The blocks of (7.30) at `(q, q̇)`.
    pub fn partition(&self, q: &Vector4<f64>, qd: &Vector4<f64>) -> Partition {
        let dm = self.mass_matrix_with_partials(q);
        let d = Self::damping_from_partials(&dm, qd);
        let m = &dm[0];
        Partition {
            m1: m.fixed_view::<2, 2>(0, 0).into_owned(),
            m2: m.fixed_view::<2, 2>(0, 2).into_owned(),
            m0: self.params.total_mass(),
            d1: d.fixed_view::<2, 2>(0, 0).into_owned(),
            d2: d.fixed_view::<2, 2>(0, 2).into_owned(),
            d21: d.fixed_view::<2, 2>(2, 0).into_owned(),
        }
    }

    /// The generalized force (7.26) of the joint torques `τ`, the friction `F_f` and the
    /// contact force `F_c`.
    pub fn generalized_force(tau: &Vector2<f64>, f_f: f64, f_c: f64) -> Vector4<f64> {
        let qt = TORQUE_MAP * tau;
        Vector4::new(qt[0], qt[1], f_f, f_c)
    }

    /// The generalized force of a force `f` (world frame) on the bus's centre of mass:
    /// `D_busᵀ f`, with `D_bus` of (7.12).
    pub fn bus_force(&self, q: &Vector4<f64>, f: &Vector2<f64>) -> Vector4<f64> {
        let p = &self.params;
        let [j, _, _] = jacobian(p.l1, p.l2, q[0], q[1]);
        j.transpose() * f
    }

    /// The bus's velocity `D_bus(q) q̇` (7.8).
    pub fn bus_velocity(&self, q: &Vector4<f64>, qd: &Vector4<f64>) -> Vector2<f64> {
        let p = &self.params;
        let [j, _, _] = jacobian(p.l1, p.l2, q[0], q[1]);
        j * qd
    }

    /// The bus's position `p_sc` (7.5).
    pub fn bus_position(&self, q: &Vector4<f64>) -> Vector2<f64> {
        let p = &self.params;
        let (s1, c1) = q[0].sin_cos();
        let (s12, c12) = (q[0] + q[1]).sin_cos();
        Vector2::new(q[2] + p.l1 * c1 + p.l2 * c12, q[3] + p.l1 * s1 + p.l2 * s12)
    }

    /// The kinetic energy `T = ½ q̇ᵀ M q̇` (7.15).
    pub fn kinetic_energy(&self, q: &Vector4<f64>, qd: &Vector4<f64>) -> f64 {
        0.5 * qd.dot(&(self.mass_matrix(q) * qd))
    }

    /// The total linear momentum `Σ m_i v_i = ∂T/∂[ẋ ẏ]` (rows 3–4 of `M q̇`).
    pub fn linear_momentum(&self, q: &Vector4<f64>, qd: &Vector4<f64>) -> Vector2<f64> {
        let mq = self.mass_matrix(q) * qd;
        Vector2::new(mq[2], mq[3])
    }

    /// `q̈` from (7.1): `M q̈ = Q − D q̇`; `None` when `M` is not positive definite or the
    /// result is not finite.
    pub fn accelerations(
        &self,
        q: &Vector4<f64>,
        qd: &Vector4<f64>,
        force: &Vector4<f64>,
    ) -> Option<Vector4<f64>> {
        let dm = self.mass_matrix_with_partials(q);
        let d = Self::damping_from_partials(&dm, qd);
        let rhs = force - d * qd;
        let qdd = dm[0].cholesky()?.solve(&rhs);
        qdd.iter().all(|v| v.is_finite()).then_some(qdd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: ArmModel = ArmModel {
        params: ArmParams::CHAPTER_7,
    };

    fn states() -> impl Iterator<Item = (Vector4<f64>, Vector4<f64>)> {
        (0..7).flat_map(|i| {
            (0..7).map(move |j| {
                let th1 = -1.2 + 0.5 * i as f64;
                let th2 = 0.3 + 0.4 * j as f64;
                let q = Vector4::new(th1, th2, 0.3 * i as f64, -0.01 * j as f64);
                let qd = Vector4::new(0.2 - 0.05 * j as f64, -0.1 + 0.03 * i as f64, 0.02, -0.1);
                (q, qd)
            })
        })
    }

    #[test]
    fn the_mass_matrix_is_symmetric_positive_definite_with_m0_in_its_corner() {
        for (q, _) in states() {
            let m = MODEL.mass_matrix(&q);
            assert!((m - m.transpose()).abs().max() < 1e-12);
            assert!(m.cholesky().is_some(), "M not positive definite at {q:?}");
            let m0 = ArmParams::CHAPTER_7.total_mass();
            assert!((m[(2, 2)] - m0).abs() < 1e-12 && (m[(3, 3)] - m0).abs() < 1e-12);
            assert!(m[(2, 3)].abs() < 1e-12);
        }
    }

    #[test]
    fn the_exact_partials_match_central_differences() {
        let h = 1e-6;
        for (q, _) in states() {
            let dm = MODEL.mass_matrix_with_partials(&q);
            for i in 0..2 {
                let mut qp = q;
                let mut qm = q;
                qp[i] += h;
                qm[i] -= h;
                let fd = (MODEL.mass_matrix(&qp) - MODEL.mass_matrix(&qm)) / (2.0 * h);
                // Central differences: truncation O(h²), rounding O(ε‖M‖/h) ≈ 1e-6 here.
                let err = (fd - dm[i + 1]).abs().max();
                let scale = dm[0].abs().max();
                assert!(
                    err < 1e-8 * scale,
                    "∂M/∂θ_{}: {err} against ‖M‖ {scale}",
                    i + 1
                );
            }
        }
    }

    #[test]
    fn the_damping_matrix_satisfies_the_energy_identity() {
        for (q, qd) in states() {
            let dm = MODEL.mass_matrix_with_partials(&q);
            let d = ArmModel::damping_from_partials(&dm, &qd);
            let mdot = dm[1] * qd[0] + dm[2] * qd[1];
            let form = qd.dot(&((mdot - 2.0 * d) * qd));
            assert!(form.abs() < 1e-10, "q̇ᵀ(Ṁ − 2D)q̇ = {form}");
            let p = MODEL.partition(&q, &qd);
            assert!((p.d21 - mdot.fixed_view::<2, 2>(2, 0)).abs().max() < 1e-12);
            assert!(d.fixed_view::<2, 2>(2, 2).abs().max() < 1e-12);
        }
    }

    #[test]
    fn torques_enter_through_l_and_bus_forces_through_the_bus_jacobian() {
        let q = Vector4::new(0.7, 1.4, 0.1, 0.2);
        let g = ArmModel::generalized_force(&Vector2::new(2.0, 3.0), 5.0, 7.0);
        assert_eq!(g, Vector4::new(5.0, 3.0, 5.0, 7.0));
        // Virtual work: fᵀ v_bus = Q_busᵀ q̇ for any q̇.
        let f = Vector2::new(0.3, -1.1);
        let qd = Vector4::new(0.2, -0.4, 0.05, 0.07);
        let lhs = f.dot(&MODEL.bus_velocity(&q, &qd));
        let rhs = MODEL.bus_force(&q, &f).dot(&qd);
        assert!((lhs - rhs).abs() < 1e-14);
    }
}
