use super::*;
use crate::lti::Tf;
use crate::scenario::{PlantParams, Tone};
use std::f64::consts::PI;

fn siso_tf(num: &[f64], den: &[f64]) -> GeneralizedPlant {
    let g = Tf::new(num.to_vec(), den.to_vec()).unwrap();
    let dims = ChannelDims {
        n_u: 1,
        n_w: 0,
        n_y: 1,
        n_z: 1,
    };
    GeneralizedPlant::from_tf_blocks(&[vec![Some(g.clone())]], &[], &[vec![Some(g)]], &[], dims)
        .unwrap()
}

fn outputs(sim: &PlantSim) -> (Vec<f64>, Vec<f64>) {
    let mut y = vec![0.0; sim.n_y()];
    let mut z = vec![0.0; sim.n_z()];
    let mut r = vec![0.0; sim.n_r()];
    sim.sample(&mut y, &mut z, &mut r).unwrap();
    (y, z)
}

#[test]
fn the_zero_input_response_of_a_first_order_plant_is_the_exponential() {
    let (p, ts) = (5.0, 0.001);
    let mut params = PlantParams::new(siso_tf(&[1.0], &[1.0, p]));
    params.initial_state = vec![1.0];
    let mut sim = PlantSim::new(&params, ts).unwrap();
    for k in 0..2000u64 {
        let (y, z) = outputs(&sim);
        let want = (-p * k as f64 * ts).exp();
        assert!(
            (y[0] - want).abs() <= 1e-13 * want.max(1e-3),
            "k = {k}: {} vs {want}",
            y[0]
        );
        assert_eq!(y, z);
        assert_eq!(sim.k(), k);
        sim.advance(&[0.0]).unwrap();
    }
    assert!((sim.time() - 2.0).abs() < 1e-12);
}

#[test]
fn a_harmonic_disturbance_is_integrated_exactly_between_samples() {
    // ẋ = −p x + p w, y = x; z = w (D_zw = 1): a fast first-order lag, nearly a static gain.
    let (p, ts) = (400.0, 0.01);
    let (amp, omega, phase) = (1.3, 11.0 * PI, 0.4);
    let mut m = GeneralizedPlant::zeros(
        1,
        ChannelDims {
            n_u: 1,
            n_w: 1,
            n_y: 1,
            n_z: 1,
        },
    );
    m.a[(0, 0)] = -p;
    m.b_w[(0, 0)] = p;
    m.c_y[(0, 0)] = 1.0;
    m.d_zw[(0, 0)] = 1.0;
    let g = p / nalgebra::Complex::new(p, omega);
    // Steady state x(t) = Im(A G e^{j(ωt+φ)}); start on it, so there is no transient.
    let steady = |t: f64| (g * nalgebra::Complex::from_polar(amp, omega * t + phase)).im;
    let mut params = PlantParams::new(m);
    params.initial_state = vec![steady(0.0)];
    params.disturbance.tones = vec![Tone {
        input: 0,
        amplitude: amp,
        omega,
        phase,
    }];
    let mut sim = PlantSim::new(&params, ts).unwrap();
    assert_eq!(sim.n_exosystem_states(), 2);
    for k in 0..5000u64 {
        let t = k as f64 * ts;
        let (y, z) = outputs(&sim);
        assert!(
            (y[0] - steady(t)).abs() < 1e-9,
            "k = {k}: y {} vs {}",
            y[0],
            steady(t)
        );
        assert!(
            (z[0] - amp * (omega * t + phase).sin()).abs() < 1e-9,
            "k = {k}: z"
        );
        sim.advance(&[0.0]).unwrap();
    }
}

#[test]
fn an_input_delay_shifts_the_response_by_exactly_d_samples() {
    let plant = siso_tf(&[2.0, 1.0], &[1.0, 0.8, 9.0]);
    let undelayed = PlantParams::new(plant.clone());
    let mut delayed = PlantParams::new(plant);
    let d = 7;
    delayed.input_delays = vec![d];
    let mut a = PlantSim::new(&undelayed, 0.01).unwrap();
    let mut b = PlantSim::new(&delayed, 0.01).unwrap();
    let u = |k: usize| ((k * 37 % 11) as f64 - 5.0) * 0.3;
    let mut ya = Vec::new();
    let mut yb = Vec::new();
    for k in 0..200 {
        ya.push(outputs(&a).0[0]);
        yb.push(outputs(&b).0[0]);
        a.advance(&[u(k)]).unwrap();
        b.advance(&[u(k)]).unwrap();
    }
    assert!(yb[..=d].iter().all(|&v| v == 0.0));
    assert_eq!(&yb[d..], &ya[..200 - d]);
    assert!(ya.iter().any(|&v| v != 0.0));
}

#[test]
fn a_direct_feedthrough_is_measured_with_the_input_of_the_previous_period() {
    let mut params = PlantParams::new(siso_tf(&[3.0], &[1.0]));
    params.input_delays = vec![2];
    let mut sim = PlantSim::new(&params, 0.1).unwrap();
    let mut y = Vec::new();
    for k in 0..6 {
        y.push(outputs(&sim).0[0]);
        sim.advance(&[k as f64 + 1.0]).unwrap();
    }
    // u_k = k + 1, delay 2, measured one period later: y_k = 3 u_{k−3}.
    assert_eq!(y, vec![0.0, 0.0, 0.0, 3.0, 6.0, 9.0]);
}

fn noisy_params(seed: u64) -> PlantParams {
    let g = Tf::new(vec![1.0, 2.0], vec![1.0, 3.0, 50.0]).unwrap();
    let dims = ChannelDims {
        n_u: 1,
        n_w: 1,
        n_y: 1,
        n_z: 1,
    };
    let col = vec![vec![Some(g)]];
    let m = GeneralizedPlant::from_tf_blocks(&col, &col, &col, &col, dims).unwrap();
    let mut params = PlantParams::new(m);
    params.disturbance.white_std = vec![0.5];
    params.disturbance.tones = vec![Tone {
        input: 0,
        amplitude: 1.0,
        omega: 20.0,
        phase: 0.0,
    }];
    params.noise.y_std = vec![0.1];
    params.noise.z_std = vec![0.2];
    params.noise.seed = seed;
    params
}

fn run_bits(sim: &mut PlantSim, steps: usize) -> Vec<u64> {
    let mut bits = Vec::new();
    for k in 0..steps {
        let (y, z) = outputs(sim);
        bits.push(y[0].to_bits());
        bits.push(z[0].to_bits());
        sim.advance(&[(k as f64 * 0.1).sin()]).unwrap();
    }
    bits
}

#[test]
fn two_simulations_with_the_same_seed_are_bit_for_bit_identical() {
    let mut a = PlantSim::new(&noisy_params(42), 0.01).unwrap();
    let mut b = PlantSim::new(&noisy_params(42), 0.01).unwrap();
    let mut c = PlantSim::new(&noisy_params(43), 0.01).unwrap();
    let ra = run_bits(&mut a, 500);
    assert_eq!(ra, run_bits(&mut b, 500));
    assert_ne!(ra, run_bits(&mut c, 500));
    a.reset();
    assert_eq!(a.k(), 0);
    assert_eq!(ra, run_bits(&mut a, 500));
}

#[test]
fn sampling_twice_at_the_same_k_gives_the_same_noise() {
    let sim = PlantSim::new(&noisy_params(7), 0.01).unwrap();
    assert_eq!(outputs(&sim), outputs(&sim));
    let (mut y, mut z) = (vec![0.0], vec![0.0]);
    sim.sample_noiseless(&mut y, &mut z).unwrap();
    assert_ne!(outputs(&sim).0, y);
}

fn first_order(p: f64, x0: f64) -> PlantParams {
    let mut m = GeneralizedPlant::zeros(
        1,
        ChannelDims {
            n_u: 1,
            n_w: 0,
            n_y: 1,
            n_z: 0,
        },
    );
    m.a[(0, 0)] = -p;
    m.b_u[(0, 0)] = 1.0;
    m.c_y[(0, 0)] = 1.0;
    let mut params = PlantParams::new(m);
    params.initial_state = vec![x0];
    params
}

#[test]
fn an_apply_offset_holds_the_previous_input_for_part_of_the_period() {
    let (p, ts, f) = (3.0, 0.05, 0.3);
    let mut sim = PlantSim::new(&first_order(p, 0.7), ts).unwrap();
    sim.set_apply_offset(Some(f)).unwrap();
    assert_eq!(sim.apply_offset(), Some(f));
    let (e1, e2) = ((-p * f * ts).exp(), (-p * (1.0 - f) * ts).exp());
    let (g1, g2) = ((1.0 - e1) / p, (1.0 - e2) / p);
    let (mut x, mut u_prev) = (0.7, 0.0);
    for k in 0..100 {
        let u = (k as f64 * 0.37).cos();
        let y = outputs(&sim).0[0];
        assert!(
            (y - x).abs() <= 1e-14 * (1.0 + x.abs()),
            "k = {k}: {y} vs {x}"
        );
        sim.advance(&[u]).unwrap();
        x = e2 * (e1 * x + g1 * u_prev) + g2 * u;
        u_prev = u;
    }
}

#[test]
fn a_tiny_apply_offset_approaches_the_ideal_zero_order_hold() {
    let mut ideal = PlantSim::new(&noisy_params(3), 0.01).unwrap();
    let mut offset = PlantSim::new(&noisy_params(3), 0.01).unwrap();
    offset.set_apply_offset(Some(1e-9)).unwrap();
    for k in 0..300 {
        let (ya, za) = outputs(&ideal);
        let (yb, zb) = outputs(&offset);
        assert!(
            (ya[0] - yb[0]).abs() < 1e-7 && (za[0] - zb[0]).abs() < 1e-7,
            "k = {k}"
        );
        let u = [(k as f64 * 0.2).sin() * 3.0];
        ideal.advance(&u).unwrap();
        offset.advance(&u).unwrap();
    }
    offset.set_apply_offset(None).unwrap();
    assert_eq!(offset.apply_offset(), None);
    for bad in [0.0, 1.0, -0.5, f64::NAN] {
        assert!(matches!(
            offset.set_apply_offset(Some(bad)),
            Err(SimError::ApplyOffset(_))
        ));
    }
}

#[test]
fn bad_slices_and_non_finite_inputs_are_refused_without_a_step() {
    let mut sim = PlantSim::new(&noisy_params(1), 0.01).unwrap();
    let (mut y, mut z, mut r) = (vec![0.0; 2], vec![0.0], vec![]);
    assert_eq!(
        sim.sample(&mut y, &mut z, &mut r),
        Err(SimError::Length {
            what: "y",
            expected: 1,
            found: 2
        })
    );
    assert!(matches!(
        sim.advance(&[]),
        Err(SimError::Length { what: "u", .. })
    ));
    assert_eq!(
        sim.advance(&[f64::NAN]),
        Err(SimError::NonFiniteInput { index: 0 })
    );
    assert_eq!(sim.k(), 0);
    assert!(PlantSim::new(&noisy_params(1), 0.0).is_err());
    let mut bad = noisy_params(1);
    bad.initial_state = vec![1.0];
    assert!(matches!(
        PlantSim::new(&bad, 0.01),
        Err(SimError::Params {
            field: "initial_state",
            ..
        })
    ));
}

#[test]
fn describe_reports_the_discrete_transfer_function_of_3_42_with_the_delay_apart() {
    let w = 20.0 * PI;
    let mut params = PlantParams::new(siso_tf(&[w * w], &[1.0, 2.0 * PI, w * w]));
    params.input_delays = vec![4];
    params.disturbance.white_std = vec![];
    let sim = PlantSim::new(&params, 0.01).unwrap();
    let d = sim.describe();
    assert_eq!(d["states"]["plant"], 2);
    let ch = &d["channels"][0];
    assert_eq!(ch["output"], "y0");
    assert_eq!(ch["input"], "u0");
    assert_eq!(ch["delay-samples"], 4);
    let num: Vec<f64> = serde_json::from_value(ch["num"].clone()).unwrap();
    let den: Vec<f64> = serde_json::from_value(ch["den"].clone()).unwrap();
    let want_num = [0.0, 0.1871, 0.1831];
    let want_den = [1.0, -1.569, 0.9391];
    for (g, w) in num[1..]
        .iter()
        .zip(&want_num[1..])
        .chain(den.iter().zip(&want_den))
    {
        assert_eq!(format!("{g:.3e}"), format!("{w:.3e}"), "{num:?} / {den:?}");
    }
    assert!(num[0].abs() < 1e-14);
    assert_eq!(d["channels"].as_array().unwrap().len(), 2); // y0 ← u0 and z0 ← u0
    assert_eq!(ch["poles"].as_array().unwrap().len(), 2);
}

#[test]
fn describe_shows_a_feedthrough_as_one_sample_of_delay() {
    let sim = PlantSim::new(&PlantParams::new(siso_tf(&[3.0], &[1.0])), 0.1).unwrap();
    let ch = &sim.describe()["channels"][0];
    assert_eq!(ch["num"], json!([0.0, 3.0]));
    assert_eq!(ch["den"], json!([1.0, 0.0]));
}

#[test]
fn describe_with_an_offset_matches_the_simulated_impulse_response() {
    let (p, ts) = (4.0, 0.02);
    let mut sim = PlantSim::new(&first_order(p, 0.0), ts).unwrap();
    sim.set_apply_offset(Some(0.25)).unwrap();
    let ch = sim.describe()["channels"][0].clone();
    let num: Vec<f64> = serde_json::from_value(ch["num"].clone()).unwrap();
    let den: Vec<f64> = serde_json::from_value(ch["den"].clone()).unwrap();
    // Impulse response of num/den by long division against the simulation.
    let n = den.len();
    let mut h = [0.0; 12];
    for k in 0..12 {
        let mut v = if k < n { num[k] } else { 0.0 };
        for i in 1..n.min(k + 1) {
            v -= den[i] * h[k - i];
        }
        h[k] = v;
    }
    for (k, hk) in h.iter().enumerate() {
        let y = outputs(&sim).0[0];
        assert!((y - hk).abs() < 1e-14, "k = {k}: {y} vs {hk}");
        sim.advance(&[if k == 0 { 1.0 } else { 0.0 }]).unwrap();
    }
}
