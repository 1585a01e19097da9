use super::*;
use crate::sim::PlantSim;

const GOOD: &str = r#"
[rig]
name = "unit_rig-1"
sample-rate-hz = 100.0
duration = 2.0

[service]
anything = "belongs to the service"

[controller]
kind = "whatever"

[plant]
kind = "transfer-function"
inputs = 2
disturbances = 1
outputs-y = 1
outputs-z = 1
input-delays = [0, 3]

[plant.tf]
yu = [[ { num = [1.0], den = [1.0, 2.0] }, 0 ]]
yw = [[ { num = [2.0], den = [1.0, 1.0, 4.0] } ]]
zu = [[ { num = [1.0], den = [1.0, 2.0] }, { num = [1.0, 0.0], den = [1.0, 3.0] } ]]

[plant.disturbance]
tones = [ { input = 0, amplitude = 2.0, frequency-rad-s = 3.0, phase-deg = 90.0 } ]
white-std = 0.1

[plant.noise]
y-std = [0.01]
seed = 9
"#;

fn refused(text: &str) -> ScenarioError {
    parse(text, "bad.toml").expect_err("must be refused")
}

/// For each case of the refusal-case file `cases` (`tests/fixtures/refusals/`): `from`
/// occurs in `base`; with its first occurrence replaced by `to` the file is refused naming
/// `field`, as `bad.toml: field '<field>': …`.
fn assert_refused_naming(base: &str, cases: &str) {
    for c in rig_scenario::refusal_cases::parse(cases).unwrap() {
        let e = refused(&c.edit(base).unwrap());
        assert_eq!(e.field(), Some(c.field.as_str()), "{c:?}: {e}");
        let m = e.to_string();
        assert!(
            m.starts_with(&format!("bad.toml: field '{}': ", c.field)),
            "{m}"
        );
    }
}

fn scenario_file(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios")
        .join(name)
}

#[test]
fn a_good_file_gives_typed_parameters_and_other_tables_are_ignored() {
    let s = parse(GOOD, "good.toml").unwrap();
    assert_eq!(s.rig.name, "unit_rig-1");
    assert!((s.rig.sample_period - 0.01).abs() < 1e-18);
    assert_eq!(s.rig.duration, 2.0);
    let p = &s.plant;
    assert_eq!(p.kind, PlantKind::TransferFunction);
    let d = p.model.dims();
    assert_eq!((d.n_u, d.n_w, d.n_y, d.n_z), (2, 1, 1, 1));
    // u0 column: G_yu and G_zu share 1/(s+2) (1 state); u1: s/(s+3) (1 state); w: 2 states.
    assert_eq!(p.model.n_x(), 4);
    assert_eq!(p.input_delays, vec![0, 3]);
    assert_eq!(p.initial_state, vec![0.0; 4]);
    assert_eq!(p.disturbance.white_std, vec![0.1]);
    let t = p.disturbance.tones[0];
    assert_eq!((t.input, t.amplitude, t.omega), (0, 2.0, 3.0));
    assert!((t.phase - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert_eq!(
        p.noise,
        NoiseParams {
            y_std: vec![0.01],
            z_std: vec![0.0],
            seed: 9
        }
    );
    assert_eq!(p.command, crate::command::Command::Constant(Vec::new()));
}

#[test]
fn bad_values_are_refused_naming_the_file_and_the_field() {
    let cases = include_str!("../../../tests/fixtures/refusals/plant-tf.toml");
    assert_refused_naming(GOOD, cases);
}

#[test]
fn unknown_keys_and_wrong_types_are_refused_with_their_line() {
    let m = refused(&GOOD.replace("seed = 9", "seed = 9\nsed = 1")).to_string();
    assert!(
        m.starts_with("bad.toml: not valid TOML") && m.contains("sed"),
        "{m}"
    );
    let m = refused(&GOOD.replace("inputs = 2", "inputs = \"two\"")).to_string();
    assert!(m.contains("line") && m.contains("inputs"), "{m}");
    let m = refused("[rig\nname=").to_string();
    assert!(m.starts_with("bad.toml: not valid TOML"), "{m}");
    let m = refused("[service]\nx = 1\n").to_string();
    assert_eq!(m, "bad.toml: field 'rig': the [rig] table is missing");
    let e = load(Path::new("/nonexistent/scenario.toml")).unwrap_err();
    assert!(matches!(e, ScenarioError::Io { .. }), "{e}");
}

#[test]
fn state_space_and_modal_plants_are_read() {
    let ss = r#"
[rig]
name = "ss"
sample-period = 0.1
duration = 1.0
[plant]
kind = "state-space"
inputs = 1
disturbances = 0
outputs-y = 1
outputs-z = 0
commands = 2
command = [1.0, -1.0]
[plant.ss]
a = [[0.0, 1.0], [-4.0, -0.4]]
b-u = [[0.0], [1.0]]
c-y = [[1.0, 0.0]]
d-yu = [[0.5]]
"#;
    let s = parse(ss, "ss.toml").unwrap();
    assert_eq!(s.plant.model.d_yu[(0, 0)], 0.5);
    assert_eq!(
        s.plant.command,
        crate::command::Command::Constant(vec![1.0, -1.0])
    );
    assert_refused_naming(
        ss,
        include_str!("../../../tests/fixtures/refusals/plant-state-space.toml"),
    );

    let modal = r#"
[rig]
name = "modal"
sample-period = 0.001
duration = 1.0
[plant]
kind = "modal"
inputs = 1
disturbances = 0
outputs-y = 1
outputs-z = 1
[plant.modal]
modes = [ { frequency-hz = 50.0, damping = 0.02, b-u = [1.0], c-y = [2.0], c-z-vel = [0.5] } ]
"#;
    let s = parse(modal, "modal.toml").unwrap();
    let m = &s.plant.model;
    assert_eq!(m.n_x(), 2);
    assert!((m.a[(1, 0)] + (2.0 * std::f64::consts::PI * 50.0).powi(2)).abs() < 1e-9);
    assert_eq!((m.c_y[(0, 0)], m.c_z[(0, 1)]), (2.0, 0.5));
    assert_refused_naming(
        modal,
        include_str!("../../../tests/fixtures/refusals/plant-modal.toml"),
    );
}

#[test]
fn the_siso_3_50_file_holds_the_expanded_coefficients_of_3_50() {
    use std::f64::consts::PI;
    let s = load(&scenario_file("siso-3-50.toml")).unwrap();
    assert_eq!(s.rig.sample_period, 0.01);
    let (zeta, wz, wp) = (0.1, 15.0 * PI, 20.0 * PI);
    let k = 400.0 * PI * PI * wp * wp / (wz * wz);
    let num = [k, k * 2.0 * zeta * wz, k * wz * wz];
    let den = [
        1.0,
        50.0 * PI + 2.0 * zeta * wp,
        400.0 * PI * PI + 100.0 * PI * zeta * wp + wp * wp,
        50.0 * PI * wp * wp + 800.0 * PI * PI * zeta * wp,
        400.0 * PI * PI * wp * wp,
    ];
    let text = std::fs::read_to_string(scenario_file("siso-3-50.toml")).unwrap();
    let raw: toml::Table = toml::from_str(&text).unwrap();
    let tf = raw["plant"]["tf"].as_table().unwrap();
    for block in ["yu", "yw", "zu", "zw"] {
        let e = &tf[block][0][0];
        let got = |key: &str| -> Vec<f64> {
            e[key]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_float().unwrap())
                .collect()
        };
        for (g, w) in got("num")
            .iter()
            .zip(&num)
            .chain(got("den").iter().zip(&den))
        {
            assert!((g - w).abs() <= 1e-12 * w.abs(), "{block}: {g} vs {w}");
        }
    }
    // One exact harmonic disturbance at ω_d = 11π rad/s on w.
    let tones = &s.plant.disturbance.tones;
    assert_eq!(tones.len(), 1);
    assert!((tones[0].omega - 11.0 * PI).abs() < 1e-12);
    // Four states per column: u and w columns.
    assert_eq!(s.plant.model.n_x(), 8);
    let sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
    let d = sim.describe();
    assert_eq!(d["channels"][0]["order"], 4);
}

#[test]
fn the_first_order_lockstep_file_decays_as_e_to_the_minus_5t() {
    let s = load(&scenario_file("first-order-lockstep.toml")).unwrap();
    let mut sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
    let steps = (s.rig.duration / s.rig.sample_period).round() as u64;
    assert_eq!(steps, 2000);
    let (mut y, mut z, mut r) = ([0.0], [0.0], []);
    for k in 0..steps {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        let want = (-5.0 * k as f64 * 0.001).exp();
        assert!((y[0] - want).abs() < 1e-13 && y == z, "k = {k}");
        sim.advance(&[0.0]).unwrap();
    }
}

#[test]
fn the_acoustic_rig_has_twelve_modes_seven_tones_and_an_open_loop_level_of_order_one() {
    let s = load(&scenario_file("acoustic-rig.toml")).unwrap();
    assert_eq!(s.rig.sample_period, 1.25e-4);
    assert_eq!(s.rig.duration, 10.0);
    let p = &s.plant;
    assert_eq!(p.kind, PlantKind::Modal);
    assert_eq!(p.model.n_x(), 24);
    assert_eq!(p.input_delays, vec![9, 16]);
    let freqs: Vec<f64> = p
        .disturbance
        .tones
        .iter()
        .map(|t| t.omega / (2.0 * std::f64::consts::PI))
        .collect();
    let want = [800.0, 900.0, 1060.0, 1300.0, 1600.0, 2200.0, 3000.0];
    assert!(
        freqs.iter().zip(&want).all(|(f, w)| (f - w).abs() < 1e-9),
        "{freqs:?}"
    );
    let mut sim = PlantSim::new(p, s.rig.sample_period).unwrap();
    assert_eq!(sim.n_exosystem_states(), 14);
    // Open loop: after the transient (0.5 s), the microphone level is about the 7 tones of
    // 0.5 Pa: an RMS of √(7/8) ≈ 0.94 Pa.
    let (mut y, mut z, mut r) = ([0.0], [0.0], []);
    let (mut sum_y, mut sum_z, mut n) = (0.0, 0.0, 0.0);
    for k in 0..8000 {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        if k >= 4000 {
            sum_y += y[0] * y[0];
            sum_z += z[0] * z[0];
            n += 1.0;
        }
        sim.advance(&[0.0, 0.0]).unwrap();
    }
    let (rms_y, rms_z) = ((sum_y / n).sqrt(), (sum_z / n).sqrt());
    assert!((0.8..1.1).contains(&rms_z), "open-loop RMS of z {rms_z}");
    assert!((rms_y - rms_z).abs() < 0.01, "{rms_y} vs {rms_z}");
}

// ---------------------------------------------------------------------------------------
// Band-limited disturbances.

/// `y = w`: a plant whose measurement is the disturbance itself (the state is unused).
fn band_file(ts: f64, rms: f64, cutoff_hz: f64, order: usize) -> String {
    format!(
        r#"
[rig]
name = "band"
sample-period = {ts}
duration = 1.0

[plant]
kind = "state-space"
inputs = 1
disturbances = 1
outputs-y = 1
outputs-z = 1

[plant.ss]
a = [[-1.0]]
b-u = [[0.0]]
b-w = [[0.0]]
c-y = [[0.0]]
c-z = [[0.0]]
d-yw = [[1.0]]

[plant.disturbance]
band-limited = [ {{ input = 0, rms = {rms}, cutoff-hz = {cutoff_hz}, order = {order} }} ]

[plant.noise]
seed = 5
"#
    )
}

#[test]
fn the_butterworth_realization_has_the_butterworth_magnitude_and_unit_dc_gain() {
    use crate::lti::StateSpace;
    use nalgebra::Complex;
    let wc = 2.0 * PI * 25.0;
    for n in 1..=MAX_BAND_LIMITED_ORDER {
        let (a, b, out) = crate::sim::butterworth_lowpass(n, wc);
        let mut c = DMatrix::zeros(1, n);
        c[(0, out)] = 1.0;
        let ss = StateSpace {
            a,
            b,
            c,
            d: DMatrix::zeros(1, 1),
        };
        for w in [0.0, 0.3 * wc, wc, 2.0 * wc, 7.0 * wc] {
            let h = ss.freq_response(Complex::new(0.0, w)).unwrap()[(0, 0)];
            let want = 1.0 / (1.0 + (w / wc).powi(2 * n as i32));
            assert!(
                (h.norm_sqr() - want).abs() < 1e-10 * want.max(1e-300) + 1e-14,
                "order {n}, ω = {w}: {} against {want}",
                h.norm_sqr()
            );
        }
    }
}

#[test]
fn the_white_noise_covariance_is_exact_and_reaches_the_stationary_variance() {
    use crate::sim::{butterworth_lowpass, butterworth_noise_variance, white_noise_covariance};
    let wc = 2.0 * PI * 5.0;
    for n in 1..=6 {
        let (a, b, out) = butterworth_lowpass(n, wc);
        // Over a long period (e^{−0.26·ω_c·T} ≈ e^{−40}): the stationary covariance.
        let p = white_noise_covariance(&a, &b, 5.0).unwrap();
        let var = butterworth_noise_variance(n, wc);
        assert!(
            (p[(out, out)] - var).abs() < 1e-9 * var,
            "order {n}: {} against {var}",
            p[(out, out)]
        );
        // Two periods are one period, then another one propagated: Q(2T) = Q + Φ Q Φᵀ.
        let t = 0.013;
        let q1 = white_noise_covariance(&a, &b, t).unwrap();
        let q2 = white_noise_covariance(&a, &b, 2.0 * t).unwrap();
        let phi = (&a * t).exp();
        let q2_from_q1 = &q1 + &phi * &q1 * phi.transpose();
        assert!((&q2 - q2_from_q1).norm() < 1e-10 * q2.norm(), "order {n}");
    }
}

#[test]
fn a_band_limited_disturbance_has_its_rms_and_correlation_at_any_sample_rate() {
    use crate::sim::{butterworth_lowpass, butterworth_noise_variance, white_noise_covariance};
    let (rms, cutoff, order) = (2.0, 5.0, 3);
    let wc = 2.0 * PI * cutoff;
    // Theory: stationary P of the unit-intensity filter, scaled; lag-T correlation
    // C e^{A T} P Cᵀ / C P Cᵀ.
    let (a, b, out) = butterworth_lowpass(order, wc);
    let p = white_noise_covariance(&a, &b, 10.0).unwrap() * (rms * rms)
        / butterworth_noise_variance(order, wc);
    // T = 0.01 s (Nyquist 50 Hz) and T = 0.1 s (Nyquist 5 Hz: half the band aliases).
    for ts in [0.01, 0.1] {
        let s = parse(&band_file(ts, rms, cutoff, order), "band.toml").unwrap();
        let b = s.plant.disturbance.band_limited[0];
        assert_eq!((b.input, b.order), (0, order));
        assert!((b.omega_c - wc).abs() < 1e-12 * wc);
        let mut sim = PlantSim::new(&s.plant, ts).unwrap();
        assert_eq!(sim.n_exosystem_states(), order);
        let rho_theory = ((&a * ts).exp() * &p)[(out, out)] / p[(out, out)];
        let (mut y, mut z, mut r) = ([0.0], [0.0], []);
        let (mut sum2, mut lag, mut prev, mut n) = (0.0, 0.0, 0.0, 0.0);
        for k in 0..60_000 {
            sim.sample(&mut y, &mut z, &mut r).unwrap();
            if k >= 1000 {
                sum2 += y[0] * y[0];
                lag += y[0] * prev;
                n += 1.0;
            }
            prev = y[0];
            sim.advance(&[0.0]).unwrap();
        }
        let var = sum2 / n;
        let rho = lag / sum2;
        assert!(
            (var.sqrt() - rms).abs() < 0.06 * rms,
            "T = {ts}: RMS {} against {rms}",
            var.sqrt()
        );
        assert!(
            (rho - rho_theory).abs() < 0.03,
            "T = {ts}: lag-1 correlation {rho} against {rho_theory}"
        );
    }
}

#[test]
fn bad_band_limited_entries_are_refused() {
    let good = band_file(0.01, 1.0, 5.0, 2);
    let cases = include_str!("../../../tests/fixtures/refusals/plant-band-limited.toml");
    assert_refused_naming(&good, cases);
}
