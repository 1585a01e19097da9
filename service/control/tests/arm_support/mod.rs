//! What the sampling-arm tests share: the rigid spacecraft of §7.1 on a linear
//! (Kelvin–Voigt) surface with the regularized friction (7.29), integrated by RK4 with
//! the torques held over each period; a robust gain standing in for the LMI design; PCAC
//! with the settings of §7.3.

#![allow(clippy::needless_range_loop, dead_code)] // reference computations; each test binary uses a part

use control::arm::controller::{ArmController, ArmControllerParams, N_R, N_U, N_Y};
use control::arm::dynamics::{ArmModel, ArmParams};
use control::arm::feedback_linearization::{ContactPrior, FeedbackLinearization, zoh};
use control::mpc::condense::MoveBounds;
use control::pcac::PcacParams;
use control::{Controller, Dimensions, StepInput};
use nalgebra::{DMatrix, Vector2, Vector4};

/// The rig's sample period (2 kHz).
pub const TS: f64 = 0.0005;
/// The desired contact force of §7.3, N.
pub const F_D: f64 = 25.0;

/// A discrete LQR gain for the χ-dynamics (7.39) at the surface `(k_s, c_s)`, zero-order
/// hold at `TS`: `τ_f = K χ` minimizing `Σ χᵀ diag(q) χ + τ_fᵀ τ_f r` (a stand-in for the
/// LMI design of (7.41), which is another helper's).
pub fn lqr_gain(k_s: f64, c_s: f64, q: [f64; 3], r: f64) -> [f64; 6] {
    let a = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -k_s, 0.0]);
    let b = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 0.0, -c_s]);
    let (ad, bd) = zoh(&a, &b, TS).unwrap();
    let qm = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&q));
    let rm = DMatrix::identity(2, 2) * r;
    let mut p = qm.clone();
    for _ in 0..200_000 {
        let btp = bd.transpose() * &p;
        let gain = (&rm + &btp * &bd).try_inverse().unwrap() * &btp * &ad;
        let next = &qm + ad.transpose() * &p * (&ad - &bd * &gain);
        let done = (&next - &p).amax() <= 1e-12 * next.amax();
        p = next;
        if done {
            break;
        }
    }
    let btp = bd.transpose() * &p;
    let k = -(&rm + &btp * &bd).try_inverse().unwrap() * &btp * &ad;
    // Row-major: the column-major storage of Kᵀ.
    let mut gain = [0.0; 6];
    gain.copy_from_slice(k.transpose().as_slice());
    gain
}

/// The spectral radius of `A_d + B_d K` for the χ-dynamics at `(k_s, c_s)`.
pub fn closed_loop_radius(k: &[f64; 6], k_s: f64, c_s: f64) -> f64 {
    let a = DMatrix::from_row_slice(3, 3, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -k_s, 0.0]);
    let b = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 0.0, 1.0, 0.0, -c_s]);
    let (ad, bd) = zoh(&a, &b, TS).unwrap();
    let km = DMatrix::from_row_slice(2, 3, k);
    (ad + bd * km)
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

/// PCAC with the settings of §7.3: `n̂ = 1`, `P_0 = 10 I`, F-test (τ_n = 40, τ_d = 200,
/// η = 0.1, α = 0.001), `ℓ = 50`, `Q = diag(1000, 100, 1)` on `C_t ζ = χ`, `R = I`,
/// `|u_aug| ≤ 100`, moves `|Δu_aug| ≤ 50` (as `scenarios/arm/pcac.toml`; the chapter gives
/// none), the prior `w_0` of the contact model.
pub fn chapter_pcac() -> PcacParams {
    let fl = FeedbackLinearization::new(ArmParams::CHAPTER_7);
    let theta0 = fl.pcac_prior(&ContactPrior::CHAPTER_7, TS).unwrap();
    PcacParams::chapter_7()
        .theta0(theta0)
        .move_bounds(Some(MoveBounds::symmetric(50.0, 2)))
        .build()
}

/// The robust gain of these tests: [`lqr_gain`] on Figure 7.4's surface
/// (`k_s = 2·10⁵`, `c_s = 5`) with `Q = diag(1000, 100, 1)`, `R = 100 I`.
///
/// A much stiffer gain (`R = I`: `K ≈ [−31 0 0; 0 −580 0.85]`) makes `τ_f` nearly a
/// linear function of `ẏ` and `e` in the closed-loop data, and PCAC's identification,
/// which regresses on `τ_f`, then attributes the force's response to the wrong regressor
/// (the `e`-row coefficient of `τ_{2,f}` changes sign within 20 samples) and the
/// augmentation destabilizes the loop: the augmentation needs the persistent excitation
/// that a gentle robust gain leaves to `u_aug`.
pub fn test_gain() -> [f64; 6] {
    lqr_gain(2.0e5, 5.0, [1000.0, 100.0, 1.0], 100.0)
}

/// Algorithm 3 with the robust gain `k` and [`chapter_pcac`], on [`rig`].
pub fn augmented_with(k: [f64; 6]) -> ArmController {
    let params = ArmControllerParams {
        pcac: Some(chapter_pcac()),
        ..ArmControllerParams::robust_only(k)
    };
    ArmController::new(&params, rig()).unwrap()
}

pub fn rig() -> Dimensions {
    Dimensions::new(N_Y, 1, N_R, N_U)
}

/// A surface with the linear contact model (7.27) and the regularized friction (7.29).
#[derive(Clone, Copy)]
pub struct Surface {
    pub k_s: f64,
    pub c_s: f64,
    pub mu: f64,
}

impl Surface {
    /// `(F_c, F_f)` at the sampler's height and velocity; no force above the surface and
    /// no pull into it.
    fn forces(&self, y: f64, xd: f64, yd: f64) -> (f64, f64) {
        let f_c = if y < 0.0 {
            (-self.k_s * y - self.c_s * yd).max(0.0)
        } else {
            0.0
        };
        let slip = (xd.abs() / 1e-4).min(1.0);
        (f_c, -self.mu * slip * f_c * xd.signum())
    }
}

/// The rigid spacecraft of §7.1, integrated by RK4 at `TS / 50` with the torques held.
pub struct Spacecraft {
    model: ArmModel,
    pub q: Vector4<f64>,
    pub qd: Vector4<f64>,
    pub surface: Surface,
}

impl Spacecraft {
    /// At contact: `θ̄_0 = (π/4, π/2)`, the sampler on the surface, all moving down at 0.1 m/s.
    pub fn at_contact(surface: Surface) -> Self {
        Self {
            model: ArmModel::new(ArmParams::CHAPTER_7),
            q: Vector4::new(
                std::f64::consts::FRAC_PI_4,
                std::f64::consts::FRAC_PI_2,
                0.0,
                0.0,
            ),
            qd: Vector4::new(0.0, 0.0, 0.0, -0.1),
            surface,
        }
    }

    /// `y = [θ_1, θ_2, θ̇_1, θ̇_2, ẋ, ẏ, F_c]`.
    pub fn measure(&self) -> [f64; 7] {
        let (f_c, _) = self.surface.forces(self.q[3], self.qd[2], self.qd[3]);
        [
            self.q[0], self.q[1], self.qd[0], self.qd[1], self.qd[2], self.qd[3], f_c,
        ]
    }

    fn derivative(&self, q: &Vector4<f64>, qd: &Vector4<f64>, tau: &Vector2<f64>) -> Vector4<f64> {
        let (f_c, f_f) = self.surface.forces(q[3], qd[2], qd[3]);
        let force = ArmModel::generalized_force(tau, f_f, f_c);
        self.model
            .accelerations(q, qd, &force)
            .expect("M positive definite")
    }

    /// One sample period with the torques `tau` held.
    pub fn advance(&mut self, tau: &[f64]) {
        let tau = Vector2::new(tau[0], tau[1]);
        let n = 50;
        let h = TS / n as f64;
        for _ in 0..n {
            let (q, v) = (self.q, self.qd);
            let a1 = self.derivative(&q, &v, &tau);
            let (q2, v2) = (q + v * (h / 2.0), v + a1 * (h / 2.0));
            let a2 = self.derivative(&q2, &v2, &tau);
            let (q3, v3) = (q + v2 * (h / 2.0), v + a2 * (h / 2.0));
            let a3 = self.derivative(&q3, &v3, &tau);
            let (q4, v4) = (q + v3 * h, v + a3 * h);
            let a4 = self.derivative(&q4, &v4, &tau);
            self.q += (v + v2 * 2.0 + v3 * 2.0 + v4) * (h / 6.0);
            self.qd += (a1 + a2 * 2.0 + a3 * 2.0 + a4) * (h / 6.0);
        }
    }
}

/// One controller step on the spacecraft's measurement with the command `f_d`.
pub fn step(c: &mut ArmController, sc: &Spacecraft, k: u64, f_d: f64) -> ([f64; 2], u32) {
    let y = sc.measure();
    let mut u = [f64::NAN; 2];
    let s = c.step(
        &StepInput {
            seq: k,
            y: &y,
            z: &y[6..],
            r: &[f_d],
            u_applied: None,
            lost: 0,
        },
        &mut u,
    );
    (u, s)
}

/// The augmented controller of §7.3 with the committed LMI gain ([`committed_gain`]).
pub fn augmented() -> ArmController {
    augmented_with(committed_gain())
}

/// `K` of the committed robust-gain file `scenarios/arm/robust-gain.toml` (the LMI
/// design of (7.41) by `rig-design robust-gain`), read from its `k = [[…], […]]` line.
pub fn committed_gain() -> [f64; 6] {
    let text = include_str!("../../../../scenarios/arm/robust-gain.toml");
    let line = text
        .lines()
        .find(|l| l.trim_start().starts_with("k = "))
        .expect("a k line");
    let list = line.split('#').next().unwrap();
    let values: Vec<f64> = list
        .split(['[', ']', ',', '='])
        .filter_map(|t| t.trim().parse().ok())
        .collect();
    values.try_into().expect("K has 2 × 3 entries")
}
