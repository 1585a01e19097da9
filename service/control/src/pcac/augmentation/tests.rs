//! The augmented PCAC against dense matrices and against a known plant: the closed-loop
//! realization is `Â + B̂ K̄ Ĉ` (7.56), the state estimate is (7.55) on `τ_f`, and the
//! identification regresses on the plant's input `τ_f = K̄ y + u` (7.42)–(7.46).

#![allow(clippy::needless_range_loop)] // index-heavy reference computations

use nalgebra::{DMatrix, DVector};

use super::{Augmentation, OutputFeedback};
use crate::bocf::{HorizonPrediction, IdentifiedModel};
use crate::controller::{Controller, Dimensions, StepInput};
use crate::forgetting::ForgettingRule;
use crate::mpc::condense::Weight;
use crate::pcac::{IdKernel, IoModel, Pcac, PcacParams};
use crate::test_support::{Gauss, io_model_params, max_abs, max_abs_diff};

/// `n̂ = 3`, `p = 3`, `m = 2`, random coefficients and a random `K̄`.
fn random_setup(g: &mut Gauss) -> (IoModel, OutputFeedback) {
    let (n, p, m) = (3, 3, 2);
    let mut pr = io_model_params(
        n,
        p,
        m,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    pr.theta0 = g.vec(n * p * (p + m)).iter().map(|x| 0.3 * x).collect();
    let model = IoModel::new(&pr).unwrap();
    let fb = OutputFeedback {
        gain: g.vec(m * p).iter().map(|x| 0.5 * x).collect(),
    };
    (model, fb)
}

#[test]
fn the_closed_loop_realization_is_a_plus_b_kbar_c_and_its_state_is_that_of_7_55() {
    let mut g = Gauss::new(71);
    for _ in 0..5 {
        let (mut model, fb) = random_setup(&mut g);
        let (n, p, m) = (model.n_hat(), model.p(), model.m());
        let nx = n * p;
        let mut aug = Augmentation::new(&model, &fb);
        // Data as the augmented PCAC stores them: u_aug,k−1 into the closed-loop history,
        // τ_{f,k−1} = u_aug,k−1 + K̄ y_{k−1} into the identified model's.
        for _ in 0..(n + 4) {
            let y = g.vec(p);
            let u = g.vec(m);
            let y_prev = model.last_y().to_vec();
            let tau = aug.take_input(&y_prev, &u).to_vec();
            model.observe(&y, &tau).unwrap();
        }
        aug.refresh(&model);
        let view = aug.view(&model);

        // Dense Â, B̂ of the identified (open-loop) model, Ĉ = [I 0 …], and Â + B̂ K̄ Ĉ.
        let real = model.realization();
        let (mut a, mut b) = (vec![0.0; nx * nx], vec![0.0; nx * m]);
        real.fill_a(&mut a).unwrap();
        real.fill_b(&mut b).unwrap();
        let a = DMatrix::from_row_slice(nx, nx, &a);
        let b = DMatrix::from_row_slice(nx, m, &b);
        let c = DMatrix::from_fn(p, nx, |i, j| f64::from(u8::from(i == j)));
        let kbar = DMatrix::from_row_slice(m, p, &fb.gain);
        let a_cl = &a + &b * &kbar * &c;
        // The structured closed-loop Â' is exactly that matrix.
        let mut a_view = vec![0.0; nx * nx];
        view.realization().fill_a(&mut a_view).unwrap();
        let da = max_abs_diff(a_cl.transpose().as_slice(), &a_view);
        assert!(da < 1e-14, "Â' differs from Â + B̂K̄Ĉ by {da}");

        // (7.55): the closed-loop state from (y, u_aug) equals the open-loop one from (y, τ_f).
        let (mut x_open, mut x_cl) = (vec![0.0; nx], vec![0.0; nx]);
        real.fill_state(&model, &mut x_open).unwrap();
        view.realization().fill_state(&view, &mut x_cl).unwrap();
        let dx = max_abs_diff(&x_open, &x_cl);
        assert!(dx < 1e-12 * (1.0 + max_abs(&x_open)), "x̂ differs by {dx}");

        // Markov parameters Ĉ Â'^{i−1} B̂ and free response Ĉ Â'^{i−1} x̂ against dense powers.
        let ell = 12;
        let mut hp = HorizonPrediction::new(&view, ell).unwrap();
        hp.compute_from_state(&view).unwrap();
        let xv = DVector::from_column_slice(&x_open);
        let mut apow = DMatrix::<f64>::identity(nx, nx);
        for i in 1..=ell {
            let h = &c * &apow * &b;
            let got = &hp.markov()[(i - 1) * p * m..i * p * m];
            let want: Vec<f64> = (0..p)
                .flat_map(|r| (0..m).map(move |s| (r, s)))
                .map(|rs| h[rs])
                .collect();
            let dh = max_abs_diff(got, &want);
            assert!(
                dh < 1e-10 * (1.0 + max_abs(&want)),
                "Ĥ'_{i} differs by {dh}"
            );
            let f = &c * &apow * &xv;
            let df = max_abs_diff(&hp.free_response()[(i - 1) * p..i * p], f.as_slice());
            assert!(
                df < 1e-10 * (1.0 + f.amax()),
                "free response {i} differs by {df}"
            );
            apow = &apow * &a_cl;
        }
    }
}

#[test]
fn a_gain_on_the_last_outputs_is_padded_with_zeros() {
    let fb = OutputFeedback::on_last_outputs(2, 5, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]).unwrap();
    assert_eq!(
        fb.gain,
        vec![0.0, 0.0, 1.0, 2.0, 3.0, 0.0, 0.0, 4.0, 5.0, 6.0]
    );
    let mut tau = [0.0; 2];
    fb.plant_input(&[9.0, 9.0, 1.0, 1.0, 1.0], &[0.5, -0.5], &mut tau);
    assert_eq!(tau, [6.5, 14.5]);
    assert!(OutputFeedback::on_last_outputs(2, 5, 6, &[0.0; 12]).is_err());
    assert!(OutputFeedback::on_last_outputs(2, 5, 3, &[0.0; 5]).is_err());
}

/// The plant `y_{k+1} = A y_k + B τ_k` (`p = 2`, `m = 1`; `F_1 = −A`, `G_1 = B`).
const A: [f64; 4] = [0.9, 0.2, -0.1, 0.7];
const B: [f64; 2] = [0.5, 1.0];
const KBAR: [f64; 2] = [-0.4, -0.3];

fn augmented_params(feedback: bool) -> PcacParams {
    PcacParams::builder(1, 2, 1, 1e3, 10)
        .theta0(vec![1e-3; 6])
        .trace_limit(f64::INFINITY)
        .tracking(1, vec![1.0, 0.0])
        .q(Weight::Scalar(1.0))
        .r(Weight::Scalar(1.0))
        .input_bounds(vec![-5.0], vec![5.0])
        .augmentation(feedback.then(|| OutputFeedback {
            gain: KBAR.to_vec(),
        }))
        .build()
}

/// Runs `pcac` on the plant under `τ = K̄ y + u_aug`, `u_aug` = PCAC's output plus a
/// dither, reported back as the applied input; returns `Θ̃ = [F̂_1 Ĝ_1]` at the end.
fn identify(pcac: &mut Pcac) -> Vec<f64> {
    let mut g = Gauss::new(5);
    let mut y = [0.3, -0.2];
    let mut applied = [0.0];
    for k in 0..600 {
        let mut u = [0.0];
        pcac.step(
            &StepInput {
                seq: k,
                y: &y,
                z: &[],
                r: &[],
                u_applied: Some(&applied),
                lost: 0,
            },
            &mut u,
        );
        applied = [u[0] + g.normal()];
        let tau = KBAR[0] * y[0] + KBAR[1] * y[1] + applied[0];
        y = [
            A[0] * y[0] + A[1] * y[1] + B[0] * tau,
            A[2] * y[0] + A[3] * y[1] + B[1] * tau,
        ];
    }
    pcac.model().coefficients().to_vec()
}

#[test]
fn identification_regresses_on_the_plants_input_tau_f() {
    // Θ̃ = [F_1 G_1] with F_1 = −A, G_1 = B (row-major 2 × 3).
    let plant = [-A[0], -A[1], B[0], -A[2], -A[3], B[1]];
    // What regressing on u_aug would give: the closed loop's F_1 − G_1 K̄ = −(A + B K̄).
    let closed = [
        -A[0] - B[0] * KBAR[0],
        -A[1] - B[0] * KBAR[1],
        B[0],
        -A[2] - B[1] * KBAR[0],
        -A[3] - B[1] * KBAR[1],
        B[1],
    ];
    let counts = Dimensions::new(2, 0, 0, 1);
    let mut aug = Pcac::new(&augmented_params(true), counts).unwrap();
    let got = identify(&mut aug);
    let d = max_abs_diff(&got, &plant);
    assert!(
        d < 1e-4,
        "augmented PCAC identified {got:?}, the plant is {plant:?}"
    );
    // The closed-loop model it plans with is F̂ − Ĝ K̄.
    let view = aug.closed_loop_model().unwrap();
    assert!(max_abs_diff(view.coefficients(), &closed) < 1e-4);
    assert_eq!(aug.augmentation().unwrap().gain, KBAR.to_vec());
    // Plain PCAC on the same loop regresses on u_aug and finds the closed loop instead.
    let mut plain = Pcac::new(&augmented_params(false), counts).unwrap();
    assert!(plain.closed_loop_model().is_none());
    let got_plain = identify(&mut plain);
    assert!(max_abs_diff(&got_plain, &closed) < 1e-4, "{got_plain:?}");
    assert!(max_abs_diff(&got_plain, &plant) > 0.1);
}

#[test]
fn a_feedback_of_the_wrong_size_is_refused_naming_the_field() {
    let mut p = augmented_params(true);
    p.augmentation = Some(OutputFeedback { gain: vec![1.0; 3] });
    let e = Pcac::new(&p, Dimensions::new(2, 0, 0, 1)).err().unwrap();
    assert_eq!(e.field, "augmentation");
    p.augmentation = Some(OutputFeedback {
        gain: vec![f64::NAN, 0.0],
    });
    let e = Pcac::new(&p, Dimensions::new(2, 0, 0, 1)).err().unwrap();
    assert_eq!(e.field, "augmentation");
}
