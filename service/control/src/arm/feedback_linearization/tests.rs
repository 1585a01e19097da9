//! The feedback linearization against the equations of motion it inverts
//! ([`ArmModel::accelerations`]), the error dynamics against the same, the
//! zero-order-hold model against a fine integration, and the prior against the model.

#![allow(clippy::needless_range_loop)] // index-heavy reference computations

use nalgebra::{DMatrix, DVector, Vector2, Vector4};

use super::*;
use crate::forgetting::ForgettingRule;
use crate::pcac::{IdKernel, IoModel, IoModelParams};

const FL: FeedbackLinearization = FeedbackLinearization {
    model: ArmModel {
        params: ArmParams::CHAPTER_7,
    },
};

/// The rig's sample period (2 kHz).
const TS: f64 = 0.0005;

/// Joint angles away from the stretched arm (`sin θ_2` well away from 0), rates, forces.
fn states() -> impl Iterator<Item = (Vector2<f64>, Vector4<f64>, f64)> {
    (0..8).flat_map(|i| {
        (0..8).map(move |j| {
            let theta = Vector2::new(-1.0 + 0.35 * i as f64, 0.4 + 0.3 * j as f64);
            let qd = Vector4::new(
                0.3 - 0.08 * j as f64,
                -0.2 + 0.05 * i as f64,
                0.05 * (i as f64 - 3.0),
                -0.1 + 0.02 * j as f64,
            );
            let f_c = 3.0 * i as f64 + 0.5 * j as f64;
            (theta, qd, f_c)
        })
    })
}

/// `q̈` of the plant (7.1) under the torques `τ`, the friction and the contact force.
fn plant_accelerations(
    theta: &Vector2<f64>,
    qd: &Vector4<f64>,
    tau: &Vector2<f64>,
    f_f: f64,
    f_c: f64,
) -> Vector4<f64> {
    let q = Vector4::new(theta[0], theta[1], 0.7, -0.01);
    let force = ArmModel::generalized_force(tau, f_f, f_c);
    FL.model()
        .accelerations(&q, qd, &force)
        .expect("M is positive definite")
}

#[test]
fn the_torques_of_7_31_make_the_sampler_accelerate_as_tau_f_without_friction() {
    let mut worst: f64 = 0.0;
    for (theta, qd, f_c) in states() {
        let tau_f = Vector2::new(2.0 - qd[0] * 10.0, -1.5 + f_c * 0.1);
        let tau = FL.torques(&theta, &qd, f_c, &tau_f).unwrap();
        let qdd = plant_accelerations(&theta, &qd, &tau, 0.0, f_c);
        let err = (Vector2::new(qdd[2], qdd[3]) - tau_f).amax();
        worst = worst.max(err);
    }
    assert!(worst < 1e-9, "p̈ − τ_f up to {worst}");
}

#[test]
fn the_virtual_input_inverts_the_torques() {
    for (theta, qd, f_c) in states() {
        let terms = FL.terms(&theta, &qd, f_c).unwrap();
        let tau_f = Vector2::new(0.3 * f_c, -0.7);
        let back = terms.virtual_input(&terms.torques(&tau_f)).unwrap();
        assert!((back - tau_f).amax() < 1e-9 * (1.0 + tau_f.amax()));
    }
}

#[test]
fn a_stretched_arm_has_no_linearization() {
    let qd = Vector4::new(0.1, 0.0, 0.0, -0.1);
    assert!(FL.terms(&Vector2::new(0.7, 0.0), &qd, 1.0).is_none());
    assert!(
        FL.error_dynamics(&Vector2::new(0.7, 0.0), &qd, 1.0, 1.0)
            .is_none()
    );
    assert!(FL.terms(&Vector2::new(0.7, 1.0), &qd, f64::NAN).is_none());
}

/// `ζ̇` of the plant under (7.31) with friction and a linear surface (7.27), against
/// `A ζ + B τ_f + E F_f + c F_d` with the signs derived in the module docs; the printed
/// `B` (`+m_0 M_2^{−T}`) and `E` do not reproduce it.
#[test]
fn the_error_dynamics_reproduce_the_plant_under_the_linearization() {
    let (k_s, c_s, f_d) = (2.0e3, 40.0, 25.0);
    let (mut worst, mut printed_b, mut printed_e): (f64, f64, f64) = (0.0, f64::MAX, f64::MAX);
    for (theta, qd, _) in states() {
        let y = -0.003;
        let f_c = -k_s * y - c_s * qd[3];
        let e = f_c - f_d;
        let f_f = -0.5 * f_c * qd[2].signum();
        let tau_f = Vector2::new(1.2 - 3.0 * qd[2], -0.8 + 0.05 * e);
        let tau = FL.torques(&theta, &qd, f_c, &tau_f).unwrap();
        let qdd = plant_accelerations(&theta, &qd, &tau, f_f, f_c);
        // ζ̇ = [θ̈; p̈; ė], ė = −k_s ẏ − c_s ÿ (7.32).
        let truth = Vector5::new(qdd[0], qdd[1], qdd[2], qdd[3], -k_s * qd[3] - c_s * qdd[3]);
        let zeta = Vector5::new(qd[0], qd[1], qd[2], qd[3], e);
        let d = FL.error_dynamics(&theta, &qd, k_s, c_s).unwrap();
        let model = d.a * zeta + d.b * tau_f + d.e * f_f + d.c * f_d;
        let scale = 1.0 + truth.amax();
        worst = worst.max((model - truth).amax() / scale);

        // As printed: B's θ̈ rows +m_0 M_2^{−T}; E = [M_2^{−T}[1;0]; ξ[1;0]; −c_s[0 1]ξ[1;0]].
        let mut b_printed = d.b;
        let theta_rows = -d.b.fixed_view::<2, 2>(0, 0).into_owned();
        b_printed
            .fixed_view_mut::<2, 2>(0, 0)
            .copy_from(&theta_rows);
        let with_b = d.a * zeta + b_printed * tau_f + d.e * f_f + d.c * f_d;
        printed_b = printed_b.min((with_b - truth).amax() / scale);
        let (part, m2_inv_t) = FL.blocks(&theta, &qd).unwrap();
        let n = part.m2 - part.m0 * part.m1 * m2_inv_t;
        let xi = n.try_inverse().unwrap() * part.m1 * m2_inv_t;
        let th = m2_inv_t.column(0);
        let e_printed = Vector5::new(th[0], th[1], xi[(0, 0)], xi[(1, 0)], -c_s * xi[(1, 0)]);
        let with_e = d.a * zeta + d.b * tau_f + e_printed * f_f + d.c * f_d;
        printed_e = printed_e.min((with_e - truth).amax() / scale);
    }
    eprintln!("(7.33): {worst:.1e}; printed B: {printed_b:.1e}; printed E: {printed_e:.1e}");
    assert!(
        worst < 1e-9,
        "(7.33) differs from the plant by {worst} (relative)"
    );
    assert!(printed_b > 1e-3, "the printed B fits to {printed_b}");
    assert!(printed_e > 1e-6, "the printed E fits to {printed_e}");
}

/// `ẋ = A x + B u` with `u` held, by RK4 with `steps` steps over `ts`.
fn rk4(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    x0: &DVector<f64>,
    u: &DVector<f64>,
    ts: f64,
) -> DVector<f64> {
    let steps = 2000;
    let h = ts / steps as f64;
    let f = |x: &DVector<f64>| a * x + b * u;
    let mut x = x0.clone();
    for _ in 0..steps {
        let k1 = f(&x);
        let k2 = f(&(&x + &k1 * (h / 2.0)));
        let k3 = f(&(&x + &k2 * (h / 2.0)));
        let k4 = f(&(&x + &k3 * h));
        x += (k1 + k2 * 2.0 + k3 * 2.0 + k4) * (h / 6.0);
    }
    x
}

#[test]
fn the_zero_order_hold_model_matches_a_fine_integration() {
    // A state with joint rates (D_21 ≠ 0) and a stiff surface, over one and ten periods.
    let theta = Vector2::new(0.8, 1.5);
    let qd = Vector4::new(0.2, -0.3, 0.01, -0.1);
    let d = FL.error_dynamics(&theta, &qd, 2.0e5, 5.0).unwrap();
    let a = DMatrix::from_fn(5, 5, |i, j| d.a[(i, j)]);
    let b = DMatrix::from_fn(5, 2, |i, j| d.b[(i, j)]);
    let x0 = DVector::from_vec(vec![0.2, -0.3, 0.01, -0.1, -24.0]);
    let u = DVector::from_vec(vec![3.0, -7.0]);
    for ts in [TS, 10.0 * TS] {
        let (ad, bd) = zoh(&a, &b, ts).unwrap();
        let discrete = &ad * &x0 + &bd * &u;
        let integrated = rk4(&a, &b, &x0, &u, ts);
        let err = (&discrete - &integrated).amax() / (1.0 + integrated.amax());
        assert!(err < 1e-11, "ZOH vs RK4 at T_s = {ts}: {err}");
    }
    assert!(zoh(&a, &b, 0.0).is_err());
    assert!(zoh(&a, &DMatrix::zeros(4, 2), TS).is_err());
}

#[test]
fn the_prior_w0_reproduces_the_one_step_predictions_of_the_discrete_model() {
    let prior = ContactPrior::CHAPTER_7;
    let theta0 = FL.pcac_prior(&prior, TS).unwrap();
    assert_eq!(theta0.len(), 35);
    let (ad, bd) = FL.discrete_model(&prior, TS).unwrap();
    let mut model = IoModel::new(&IoModelParams {
        n_hat: 1,
        p: 5,
        m: 2,
        theta0,
        p0: 10.0,
        rule: ForgettingRule::Constant { lambda: 1.0 },
        trace_limit: f64::INFINITY,
        kernel: IdKernel::Shared,
    })
    .unwrap();
    for k in 0..6 {
        let zeta = [
            0.01 * k as f64,
            -0.02,
            0.003,
            -0.1 + 0.01 * k as f64,
            -25.0 + k as f64,
        ];
        let tau_f = [1.0 - k as f64, 0.5 * k as f64];
        model.observe(&zeta, &[0.0, 0.0]).unwrap();
        let mut predicted = [0.0; 5];
        model.predict_one_step(&tau_f, &mut predicted).unwrap();
        let want =
            &ad * DVector::from_column_slice(&zeta) + &bd * DVector::from_column_slice(&tau_f);
        let err = want
            .iter()
            .zip(&predicted)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12 * (1.0 + want.amax()), "sample {k}: {err}");
    }
    // At the contact state θ̇ = 0: D_21 = 0, so the θ̇ columns of A_d are those of I.
    assert!((ad[(0, 0)] - 1.0).abs() < 1e-15 && ad[(0, 1)].abs() < 1e-15);
    // The e row carries −c_s T_s on τ_{2,f} (plus the k_s ẏ coupling).
    assert!((bd[(4, 1)] + prior.c_s * TS).abs() < 1e-3 * prior.c_s * TS);
    let bad = ContactPrior { k_s: -1.0, ..prior };
    assert!(
        FL.pcac_prior(&bad, TS)
            .unwrap_err()
            .contains("pcac.prior.k-s")
    );
}
