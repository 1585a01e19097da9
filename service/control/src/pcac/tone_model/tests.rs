//! The internal model of known tones against a known plant: the product model predicts
//! with the plant part's Markov parameters and continues the tones, the identification on
//! `D`-filtered data recovers the plant part with the tones present, `v_free` is `W`'s
//! response, and the closed loop cancels the tones.

use super::*;
use crate::bocf::HorizonPrediction;
use crate::controller::{Controller, Dimensions, StepInput};
use crate::forgetting::ForgettingRule;
use crate::mpc::condense::Weight;
use crate::pcac::{IdKernel, Pcac, PcacParams, PcacTiming};
use crate::test_support::{Gauss, io_model_params, max_abs_diff};

/// The plant part `y = −F̂_1 y_{k−1} − F̂_2 y_{k−2} + Ĝ_1 u_{k−1} + Ĝ_2 u_{k−2}` as `θ`.
const PLANT: [f64; 4] = [-0.7, 0.1, 0.5, 0.25];
const OMEGAS: [f64; 2] = [0.4, 1.7];

fn tone(k: usize) -> f64 {
    let k = k as f64;
    0.8 * (OMEGAS[0] * k + 0.3).sin() + 0.5 * (OMEGAS[1] * k - 1.0).cos()
}

fn internal_model(m: usize) -> InternalModel {
    InternalModel {
        omegas: OMEGAS.to_vec(),
        notch_radius: 0.9,
        r_notch: vec![1.0; m],
        r_level: vec![0.0; m],
    }
}

/// The plant part driven by `u`, plus the tones at its output.
struct TonePlant {
    s: [f64; 2],
    u: [f64; 2],
    k: usize,
}

impl TonePlant {
    fn new() -> Self {
        Self {
            s: [0.0; 2],
            u: [0.0; 2],
            k: 0,
        }
    }
    fn output(&self) -> f64 {
        self.s[0] + tone(self.k)
    }
    /// Applies `u` over the period and moves on.
    fn advance(&mut self, u: f64) {
        let [f1, f2, g1, g2] = PLANT;
        let next = -f1 * self.s[0] - f2 * self.s[1] + g1 * u + g2 * self.u[0];
        self.s = [next, self.s[0]];
        self.u = [u, self.u[0]];
        self.k += 1;
    }
}

fn siso_model(theta0: Vec<f64>, p0: f64) -> IoModel {
    let mut pr = io_model_params(
        2,
        1,
        1,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    pr.theta0 = theta0;
    pr.p0 = p0;
    IoModel::new(&pr).unwrap()
}

#[test]
fn the_product_model_has_the_markov_parameters_of_the_plant_part() {
    let mut g = Gauss::new(5);
    let (n, p, m) = (4, 2, 2);
    let mut pr = io_model_params(
        n,
        p,
        m,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    pr.theta0 = g.vec(n * p * (p + m)).iter().map(|x| 0.2 * x).collect();
    let model = IoModel::new(&pr).unwrap();
    let tm = ToneModel::new(&model, &internal_model(m), 30).unwrap();
    let view = tm.view();
    assert_eq!(view.order(), n + 4);
    let (mut plain, mut product) = (
        HorizonPrediction::new(&model, 30).unwrap(),
        HorizonPrediction::new(&view, 30).unwrap(),
    );
    plain.compute_from_state(&model).unwrap();
    product.compute_from_state(&view).unwrap();
    let scale = plain.markov().iter().fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(scale > 0.1);
    assert!(
        max_abs_diff(plain.markov(), product.markov()) < 1e-12 * (1.0 + scale),
        "the Markov parameters differ"
    );
}

#[test]
fn the_free_response_continues_the_plant_and_the_tones_exactly() {
    let mut g = Gauss::new(9);
    let model = siso_model(PLANT.to_vec(), 1.0);
    let ell = 40;
    let mut tm = ToneModel::new(&model, &internal_model(1), ell).unwrap();
    let mut plant = TonePlant::new();
    let mut u_prev = 0.0;
    for _ in 0..50 {
        tm.take_sample(&[plant.output()], &[u_prev]);
        let u = g.normal();
        plant.advance(u);
        u_prev = u;
    }
    // Sample k: y_k measured, u_k = u_prev... in next-step timing u_k is committed.
    let y_k = plant.output();
    tm.take_sample(&[y_k], &[u_prev]);
    let u_k = g.normal();
    let mut pred = HorizonPrediction::new(&tm.view(), ell).unwrap();
    pred.compute_committed(&tm.view(), &[u_k]).unwrap();
    // The truth: u_k, then zero inputs; y_{k+1}, …, y_{k+ℓ}.
    let mut truth = Vec::new();
    plant.advance(u_k);
    for _ in 0..ell {
        truth.push(plant.output());
        plant.advance(0.0);
    }
    let err = max_abs_diff(pred.free_response(), &truth);
    assert!(err < 1e-9, "free response off by {err}");
}

#[test]
fn identification_on_filtered_data_recovers_the_plant_part_with_the_tones_present() {
    let mut g = Gauss::new(11);
    let mut model = siso_model(Vec::new(), 1e4);
    let mut tm = ToneModel::new(&model, &internal_model(1), 10).unwrap();
    // The plain ARX fit of the same data, for contrast.
    let mut plain = siso_model(Vec::new(), 1e4);
    let mut plant = TonePlant::new();
    let mut u_prev = 0.0;
    for k in 0..3000 {
        let y = [plant.output()];
        tm.take_sample(&y, &[u_prev]);
        let (yf, uf) = tm.filtered();
        // The first n̂ + 2n_t filtered samples see the zero histories before the data.
        if k < tm.window() {
            model.observe(yf, uf).unwrap();
        } else {
            model.update(yf, uf).unwrap();
        }
        plain.update(&y, &[u_prev]).unwrap();
        let u = g.normal();
        plant.advance(u);
        u_prev = u;
    }
    let err = max_abs_diff(model.coefficients(), &PLANT);
    assert!(
        err < 1e-6,
        "filtered fit off by {err}: {:?}",
        model.coefficients()
    );
    let plain_err = max_abs_diff(plain.coefficients(), &PLANT);
    assert!(
        plain_err > 100.0 * err,
        "the plain fit is off by only {plain_err}"
    );
}

#[test]
fn v_free_plus_the_toeplitz_response_is_the_notch_filter_of_the_whole_input() {
    let mut g = Gauss::new(13);
    let m = 2;
    let ell = 12;
    let mut pr = io_model_params(
        3,
        1,
        m,
        ForgettingRule::Constant { lambda: 1.0 },
        IdKernel::Shared,
    );
    pr.theta0 = Vec::new();
    let model = IoModel::new(&pr).unwrap();
    let mut tm = ToneModel::new(&model, &internal_model(m), ell).unwrap();
    let ann = ToneAnnihilator::new(&OMEGAS, 0.9).unwrap();
    let w = ann.notch_impulse_response(ell);
    let mut inputs: Vec<Vec<f64>> = Vec::new();
    for _ in 0..30 {
        let u = g.vec(m);
        tm.take_sample(&[0.0], &u);
        inputs.push(u);
    }
    let committed = g.vec(2 * m);
    let v_free = tm.fill_v_free(&committed).to_vec();
    let plan = g.vec(ell * m);
    // The whole sequence: the past, the committed rows, the plan; W run from rest.
    let mut seq = inputs.clone();
    seq.extend(committed.chunks(m).map(<[f64]>::to_vec));
    seq.extend(plan.chunks(m).map(<[f64]>::to_vec));
    let (d, den) = (ann.coefficients(), ann.notch_denominator());
    for j in 0..m {
        let mut v = vec![0.0; seq.len()];
        for t in 0..seq.len() {
            let mut x = 0.0;
            for i in 0..=t.min(ann.order()) {
                x += d[i] * seq[t - i][j];
            }
            for i in 1..=t.min(ann.order()) {
                x -= den[i] * v[t - i];
            }
            v[t] = x;
        }
        let start = seq.len() - ell;
        for i in 0..ell {
            let conv: f64 = (0..=i).map(|s| w[i - s] * plan[s * m + j]).sum();
            let got = v_free[i * m + j] + conv;
            assert!((got - v[start + i]).abs() < 1e-10, "input {j}, step {i}");
        }
    }
}

fn tone_pcac(timing: PcacTiming) -> Pcac {
    let params = PcacParams::builder(2, 1, 1, 0.01, 30)
        .theta0(PLANT.iter().map(|v| 0.8 * v).collect())
        .forgetting(ForgettingRule::Constant { lambda: 1.0 })
        .trace_limit(f64::INFINITY)
        .q(Weight::Scalar(10.0))
        .r(Weight::Scalar(0.0))
        .input_bounds(vec![-20.0], vec![20.0])
        .timing(timing)
        .internal_model(Some(internal_model(1)))
        .build();
    Pcac::new(&params, Dimensions::new(1, 1, 0, 1)).unwrap()
}

#[test]
fn pcac_with_the_internal_model_cancels_known_tones_in_either_timing() {
    for timing in [PcacTiming::SameStep, PcacTiming::NextStep] {
        let mut c = tone_pcac(timing);
        let mut plant = TonePlant::new();
        let mut noise = Gauss::new(17);
        let (mut y, mut u_prev) = (Vec::new(), 0.0);
        let steps = 3000;
        for _ in 0..steps {
            let yk = [plant.output() + 1e-4 * noise.normal()];
            let mut u = [0.0];
            c.step(
                &StepInput {
                    seq: 0,
                    y: &yk,
                    z: &yk,
                    r: &[],
                    u_applied: Some(&[u_prev]),
                    lost: 0,
                },
                &mut u,
            );
            assert!(u[0].is_finite() && u[0].abs() <= 20.0);
            y.push(yk[0]);
            plant.advance(u[0]);
            u_prev = u[0];
        }
        assert_eq!(c.counts_of().fallbacks, 0, "{timing:?}");
        assert_eq!(c.counts_of().fast_path, 0, "{timing:?}");
        let tail = &y[steps - 1000..];
        let amps = crate::tones::tone_amplitudes(tail, steps - 1000, &OMEGAS).unwrap();
        for (a, open) in amps.iter().zip([0.8, 0.5]) {
            let db = 20.0 * (open / a).log10();
            assert!(db > 40.0, "{timing:?}: only {db:.1} dB");
        }
    }
}

#[test]
fn the_internal_model_refuses_the_always_fast_path_and_bad_settings_by_name() {
    use crate::mpc::fast_path::FastPathMode;
    let base = || {
        PcacParams::builder(2, 1, 1, 1.0, 20)
            .r(Weight::Scalar(0.0))
            .internal_model(Some(internal_model(1)))
    };
    let dims = Dimensions::new(1, 1, 0, 1);
    let field = |p: PcacParams| p.validate(dims).unwrap_err().field.to_string();
    assert_eq!(
        field(base().fast_path(FastPathMode::Always).build()),
        "fast-path"
    );
    let mut im = internal_model(1);
    im.notch_radius = 1.0;
    assert_eq!(
        field(base().internal_model(Some(im)).build()),
        "internal-model.notch-radius"
    );
    let mut im = internal_model(1);
    im.omegas = vec![4.0];
    assert_eq!(
        field(base().internal_model(Some(im)).build()),
        "internal-model.tones-hz"
    );
    let mut im = internal_model(1);
    im.r_level = vec![1.0, 2.0];
    assert_eq!(
        field(base().internal_model(Some(im)).build()),
        "internal-model.r-level"
    );
    let mut im = internal_model(1);
    im.r_notch = vec![0.0];
    assert_eq!(
        field(base().internal_model(Some(im)).build()),
        "internal-model.r-notch"
    );
    // Auto never takes the fast path with it, and R = 0 is accepted.
    assert!(
        Pcac::new(&base().fast_path(FastPathMode::Auto).build(), dims)
            .unwrap()
            .counts_of()
            .fast_path
            == 0
    );
}
