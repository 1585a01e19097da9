use super::*;
use crate::scenario::{self, PlantKind};
use crate::sim::PlantSim;
use std::path::Path;

fn scenario_file(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios/truss")
        .join(name)
}

const FILES: [&str; 3] = [
    "harmonic.toml",
    "broadband-25hz.toml",
    "broadband-50hz-aliasing.toml",
];

/// The modal frequencies (Hz) documented in plant-proxy/MODELS.md and the scenario files.
const DOCUMENTED_HZ: [f64; 16] = [
    0.848, 3.723, 8.223, 8.466, 12.559, 23.194, 32.203, 34.870, 47.277, 48.009, 54.046, 55.290,
    56.831, 59.745, 68.626, 77.760,
];

/// The truss of the scenario files, read through the scenario loader.
fn section_6_2_truss() -> TrussPlant {
    let text = std::fs::read_to_string(scenario_file("harmonic.toml")).unwrap();
    let v: toml::Value = toml::from_str(&text).unwrap();
    let t = v.get("plant").and_then(|p| p.get("truss")).unwrap();
    let dims = ChannelDims {
        n_u: 2,
        n_w: 1,
        n_y: 4,
        n_z: 4,
    };
    from_toml(t, dims).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn the_element_matrices_of_a_horizontal_member_are_those_of_6_2() {
    let (e, a, rho, l) = (1e11, 5e-4, 1700.0, 3.0);
    let (m, k) = global_element_matrices(e, a, rho, (1.0, 2.0), (4.0, 2.0));
    let (mbar, kbar) = element_matrices(e, a, rho, l);
    let mu = rho * a * l / 6.0;
    let kappa = e * a / l;
    #[rustfmt::skip]
    let m62 = [
        [2.0, 0.0, 1.0, 0.0],
        [0.0, 2.0, 0.0, 1.0],
        [1.0, 0.0, 2.0, 0.0],
        [0.0, 1.0, 0.0, 2.0],
    ];
    #[rustfmt::skip]
    let k62 = [
        [ 1.0, 0.0, -1.0, 0.0],
        [ 0.0, 0.0,  0.0, 0.0],
        [-1.0, 0.0,  1.0, 0.0],
        [ 0.0, 0.0,  0.0, 0.0],
    ];
    for i in 0..4 {
        for j in 0..4 {
            assert_eq!(mbar[(i, j)], mu * m62[i][j]);
            assert_eq!(kbar[(i, j)], kappa * k62[i][j]);
            // A horizontal member: global = local.
            assert!((m[(i, j)] - mbar[(i, j)]).abs() <= 1e-12 * mu);
            assert!((k[(i, j)] - kbar[(i, j)]).abs() <= 1e-12 * kappa);
        }
    }
}

#[test]
fn a_vertical_member_is_stiff_in_y_and_a_diagonal_one_in_its_direction() {
    let (e, a, rho) = (1e11, 5e-4, 1700.0);
    let (m, k) = global_element_matrices(e, a, rho, (0.0, 0.0), (0.0, 2.0));
    let kappa = e * a / 2.0;
    // Stiffness only between the y displacements.
    let expected = [
        [0.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, -1.0],
        [0.0, 0.0, 0.0, 0.0],
        [0.0, -1.0, 0.0, 1.0],
    ];
    for i in 0..4 {
        for j in 0..4 {
            assert!((k[(i, j)] - kappa * expected[i][j]).abs() <= 1e-9 * kappa);
        }
    }
    // The consistent mass (6.2) is invariant under the rotation.
    let (mbar, _) = element_matrices(e, a, rho, 2.0);
    assert!((m - mbar).norm() <= 1e-12 * mbar.norm());
    // At 30°: K = EA/L [[R, −R], [−R, R]], R = [[c², cs], [cs, s²]].
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let (_, k) = global_element_matrices(e, a, rho, (1.0, 1.0), (1.0 + 2.0 * c, 1.0 + 2.0 * s));
    let r = [[c * c, c * s], [c * s, s * s]];
    for i in 0..4 {
        for j in 0..4 {
            let sign = if (i < 2) == (j < 2) { 1.0 } else { -1.0 };
            assert!((k[(i, j)] - sign * kappa * r[i % 2][j % 2]).abs() <= 1e-9 * kappa);
        }
    }
}

#[test]
fn the_truss_has_16_dof_symmetric_m_and_k_and_k_is_positive_definite() {
    let tp = section_6_2_truss();
    let t = &tp.truss;
    assert_eq!(t.n_dof(), 16);
    assert_eq!(t.nodes.iter().filter(|n| n.fixed).count(), 2);
    assert_eq!(t.members.len(), 16);
    let (m, k) = t.assemble();
    assert_eq!((m.nrows(), k.nrows()), (16, 16));
    assert!((&m - m.transpose()).norm() <= 1e-14 * m.norm());
    assert!((&k - k.transpose()).norm() <= 1e-14 * k.norm());
    assert!(m.clone().cholesky().is_some());
    assert!(k.clone().cholesky().is_some(), "K is not positive definite");
    let eig = SymmetricEigen::new(k.clone());
    assert!(eig.eigenvalues.iter().all(|&l| l > 0.0));
    // The lumped masses are on the diagonal of both directions of their node: node 3
    // (2 kg) carries 2 kg more than node 1 (1 kg), which sits on the same members' pattern
    // apart from the bay below it.
    let dof = |name: &str| t.dof_map()[t.nodes.iter().position(|n| n.name == name).unwrap()];
    let member_mass = t.density * t.area;
    assert!(m[(dof("3").unwrap(), dof("3").unwrap())] > 2.0 + member_mass);
}

#[test]
fn the_modes_are_mass_normalized_and_have_the_documented_frequencies() {
    let tp = section_6_2_truss();
    let (m, k) = tp.truss.assemble();
    let modes = &tp.modes;
    let phi = &modes.phi;
    let ptm = phi.transpose() * &m * phi;
    let ptk = phi.transpose() * &k * phi;
    assert!((ptm - DMatrix::<f64>::identity(16, 16)).norm() < 1e-10);
    for i in 0..16 {
        for j in 0..16 {
            let w2 = if i == j { modes.omega[i].powi(2) } else { 0.0 };
            assert!((ptk[(i, j)] - w2).abs() < 1e-8 * modes.omega[15].powi(2));
        }
    }
    let f = modes.frequencies_hz();
    for (got, doc) in f.iter().zip(DOCUMENTED_HZ) {
        assert!(
            (got - doc).abs() < 6e-4,
            "{got} Hz against the documented {doc} Hz"
        );
    }
    assert!(f.windows(2).all(|w| w[0] <= w[1]));
    // The cluster near 10 Hz: three modes between 8 and 13 Hz, none between 4 and 8 or
    // between 13 and 20.
    assert_eq!(f.iter().filter(|&&x| (8.0..13.0).contains(&x)).count(), 3);
    assert!(
        !f.iter()
            .any(|&x| (4.0..8.0).contains(&x) || (13.0..20.0).contains(&x))
    );
}

#[test]
fn every_mode_of_the_continuous_model_has_zeta_0_005() {
    let tp = section_6_2_truss();
    let modes = &tp.modes;
    // Modal damping: Φᵀ C Φ = diag(2ζω).
    let c = tp.truss.damping_matrix(modes);
    let ptc = modes.phi.transpose() * &c * &modes.phi;
    for i in 0..16 {
        assert!(close(ptc[(i, i)], 2.0 * 0.005 * modes.omega[i], 1e-9));
    }
    // From the eigenvalues of the simulated (modal) model and of the physical model.
    for a in [tp.model.a.clone(), tp.truss.physical_plant().unwrap().a] {
        let mut lambda = crate::lti::eigenvalues(&a).unwrap();
        assert_eq!(lambda.len(), 32);
        lambda.sort_by(|x, y| x.norm().total_cmp(&y.norm()));
        for (i, l) in lambda.iter().enumerate() {
            let zeta = -l.re / l.norm();
            assert!((zeta - 0.005).abs() < 1e-7, "eigenvalue {l}: ζ = {zeta}");
            assert!(close(l.norm(), modes.omega[i / 2], 1e-8));
        }
    }
}

#[test]
fn the_modal_and_the_physical_models_have_the_same_frequency_response() {
    let tp = section_6_2_truss();
    let modal = tp.model.state_space();
    let physical = tp.truss.physical_plant().unwrap().state_space();
    for hz in [0.0, 0.1, 0.848, 1.0, 8.3, 10.0, 30.0, 100.0] {
        let s = Complex::new(0.0, 2.0 * PI * hz);
        let g1 = modal.freq_response(s).unwrap();
        let g2 = physical.freq_response(s).unwrap();
        assert!((&g1 - &g2).norm() <= 1e-8 * g2.norm(), "at {hz} Hz");
    }
}

#[test]
fn the_sensors_have_gain_10_per_mm_on_the_static_displacements() {
    let tp = section_6_2_truss();
    let t = &tp.truss;
    let (_, k) = t.assemble();
    let kinv = k.cholesky().unwrap().inverse();
    // DC response of the simulated model: inputs [u; w], outputs [y; z].
    let g0 = tp
        .model
        .state_space()
        .freq_response(Complex::new(0.0, 0.0))
        .unwrap();
    let inputs: Vec<&Port> = t.actuators.iter().chain(&t.disturbances).collect();
    let outputs: Vec<&Port> = t.sensors_y.iter().chain(&t.sensors_z).collect();
    for (i, s) in outputs.iter().enumerate() {
        // 10 per millimetre of δx (K⁻¹ is in metres per newton).
        assert_eq!(s.gain, 1e4);
        assert_eq!(s.direction, Direction::X);
        for (j, f) in inputs.iter().enumerate() {
            let static_disp = kinv[(t.port_dof(s), t.port_dof(f))];
            assert!(
                close(g0[(i, j)].re, 1e4 * static_disp, 1e-8),
                "y{i} ← input {j}: {} against 1e4 × {static_disp}",
                g0[(i, j)].re
            );
            assert!(g0[(i, j)].im.abs() < 1e-12 * static_disp.abs().max(1e-30));
        }
    }
    // Actuators at nodes 3 and 4, sensors at 5 to 8, disturbance at 1, all in x.
    let names =
        |ps: &[Port]| -> Vec<String> { ps.iter().map(|p| t.nodes[p.node].name.clone()).collect() };
    assert_eq!(names(&t.actuators), ["3", "4"]);
    assert_eq!(names(&t.disturbances), ["1"]);
    assert_eq!(names(&t.sensors_y), ["5", "6", "7", "8"]);
}

#[test]
fn the_noise_sigma_gives_40_db_on_node_8_for_a_0_1_hz_unit_tone() {
    let sc = scenario::load(&scenario_file("harmonic.toml")).unwrap();
    let sigma = sc.plant.noise.y_std[0];
    assert!(sc.plant.noise.y_std.iter().all(|&s| s == sigma));
    assert!(sc.plant.noise.z_std.iter().all(|&s| s == 0.0));
    // Independently of the modal sum: the state-space frequency response, w → y_3.
    let g = tp_response(&sc.plant.model, 3, 2.0 * PI * 0.1);
    let rms = g / 2f64.sqrt();
    assert!(close(rms / sigma, 100.0, 1e-9), "RMS/σ = {}", rms / sigma);
    // The documented value (plant-proxy/MODELS.md): y = 10·δx in mm.
    assert!((sigma - 1.7681e-3).abs() < 1e-7, "σ = {sigma:e}");
}

/// `|G_{y_i, w_0}(jω)|` of a plant with inputs `[u (2); w (1)]`.
fn tp_response(p: &GeneralizedPlant, i: usize, omega: f64) -> f64 {
    let g = p
        .state_space()
        .freq_response(Complex::new(0.0, omega))
        .unwrap();
    g[(i, 2)].norm()
}

#[test]
fn the_scenario_files_load_and_describe() {
    let mut hz = Vec::new();
    for name in FILES {
        let sc = scenario::load(&scenario_file(name)).unwrap();
        assert_eq!(sc.plant.kind, PlantKind::Truss);
        assert_eq!(
            (
                sc.plant.n_u(),
                sc.plant.n_w(),
                sc.plant.n_y(),
                sc.plant.n_z()
            ),
            (2, 1, 4, 4)
        );
        assert_eq!(sc.plant.n_x(), 32);
        let sim = PlantSim::new(&sc.plant, sc.rig.sample_period).unwrap();
        let d = sim.describe();
        assert_eq!(d["states"]["plant"], 32);
        assert_eq!(d["channels"].as_array().unwrap().len(), 16);
        hz.push((name, sc.rig.sample_period, d));
    }
    let (_, ts, d) = &hz[0];
    assert_eq!(*ts, 0.02);
    let tones: Vec<f64> = d["tones"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["frequency-hz"].as_f64().unwrap())
        .collect();
    assert!(close(tones[0], 0.354, 1e-12) && close(tones[1], 1.0, 1e-12));
    assert!(close(tones[2], 1.55, 1e-12));
    for ((_, ts, d), (want_ts, cutoff)) in hz[1..].iter().zip([(0.02, 25.0), (0.1, 50.0)]) {
        assert_eq!(*ts, want_ts);
        let b = &d["band-limited"][0];
        assert!(close(b["cutoff-hz"].as_f64().unwrap(), cutoff, 1e-12));
        assert_eq!(b["rms"], 1.0);
        assert_eq!(d["states"]["exosystem"], 4);
    }
}

#[test]
fn a_bad_truss_is_refused_naming_the_field() {
    let text = std::fs::read_to_string(scenario_file("harmonic.toml")).unwrap();
    let cases = rig_scenario::refusal_cases::parse(include_str!(
        "../../../tests/fixtures/refusals/truss-plant.toml"
    ))
    .unwrap();
    for c in cases {
        let bad = c.edit(&text).unwrap();
        let e = scenario::parse(&bad, "bad.toml").expect_err(&c.field);
        assert_eq!(e.field(), Some(c.field.as_str()), "{e}");
    }
}

/// The stationary covariance of the truss plant driven by a band-limited disturbance on
/// `w` (filter states appended), computed exactly.
fn stationary_y_rms(tp: &TrussPlant, rms: f64, cutoff_hz: f64, order: usize) -> Vec<f64> {
    use crate::sim::{butterworth_lowpass, butterworth_noise_variance, white_noise_covariance};
    let p = &tp.model;
    let n_p = p.n_x();
    let wc = 2.0 * PI * cutoff_hz;
    let (af, bf, out) = butterworth_lowpass(order, wc);
    let n = n_p + order;
    let mut a = DMatrix::zeros(n, n);
    a.view_mut((0, 0), (n_p, n_p)).copy_from(&p.a);
    a.view_mut((n_p, n_p), (order, order)).copy_from(&af);
    a.view_mut((0, n_p + out), (n_p, 1))
        .copy_from(&p.b_w.column(0));
    let mut g = DMatrix::zeros(n, 1);
    g.view_mut((n_p, 0), (order, 1))
        .copy_from(&(bf * (rms / butterworth_noise_variance(order, wc).sqrt())));
    // The slowest mode decays as e^{−ζω_1 t}, ζω_1 = 0.027 s⁻¹: 3000 s is e^{−80}.
    let q = white_noise_covariance(&a, &g, 3000.0).unwrap();
    (0..p.c_y.nrows())
        .map(|i| {
            let mut c = DMatrix::zeros(1, n);
            c.view_mut((0, 0), (1, n_p)).copy_from(&p.c_y.row(i));
            (&c * &q * c.transpose())[(0, 0)].sqrt()
        })
        .collect()
}

#[test]
fn the_open_loop_levels_are_as_documented() {
    let tp = section_6_2_truss();
    let modes = tp.truss.plant_modes(&tp.modes);
    // Tone amplitudes at y_3 (node 8, 10·δx in mm) per newton on w (plant-proxy/MODELS.md).
    for (hz, want) in [(0.354, 3.072e-1), (1.0, 8.033e-1), (1.55, 1.842e-1)] {
        let amp = modal_response(&modes, 3, 0, 2.0 * PI * hz).norm();
        assert!((amp - want).abs() < 1e-3 * want, "{hz} Hz: {amp:e}");
    }
    // Broadband: the exact stationary RMS of each y (noiseless), and a long simulation.
    for (name, cutoff, want) in [
        (
            "broadband-25hz.toml",
            25.0,
            [4.729e-1, 4.723e-1, 7.346e-1, 7.336e-1],
        ),
        (
            "broadband-50hz-aliasing.toml",
            50.0,
            [3.344e-1, 3.340e-1, 5.194e-1, 5.187e-1],
        ),
    ] {
        let exact = stationary_y_rms(&tp, 1.0, cutoff, 4);
        for (e, w) in exact.iter().zip(want) {
            assert!((e - w).abs() < 1e-3 * w, "{name}: {exact:?}");
        }
        let sc = scenario::load(&scenario_file(name)).unwrap();
        let ts = sc.rig.sample_period;
        let mut sim = PlantSim::new(&sc.plant, ts).unwrap();
        let (mut y, mut z, mut r) = ([0.0; 4], [0.0; 4], []);
        let mut sum = [0.0; 4];
        let mut n = 0.0;
        // 10000 s: about 270 time constants of the first mode.
        let (skip, steps) = ((200.0 / ts) as usize, (10_200.0 / ts) as usize);
        for k in 0..steps {
            sim.sample(&mut y, &mut z, &mut r).unwrap();
            if k >= skip {
                for i in 0..4 {
                    sum[i] += z[i] * z[i];
                }
                n += 1.0;
            }
            sim.advance(&[0.0, 0.0]).unwrap();
        }
        for i in 0..4 {
            let rms = (sum[i] / n).sqrt();
            assert!(
                (rms - exact[i]).abs() < 0.1 * exact[i],
                "{name}: simulated RMS of z{i} {rms:e} against {:e}",
                exact[i]
            );
        }
    }
}
