//! The discrete-time plants of chapter 4 through the scenario files and `PlantSim`: the
//! published `y`, `z` and `r` are the difference equation and the command formulas bit for
//! bit, the poles and zeros are the chapter's, the input disturbance enters at the input,
//! and bad tables are refused naming the field.

use plant_proxy::command::Command;
use plant_proxy::scenario::{self, PlantKind, Scenario};
use plant_proxy::sim::PlantSim;
use std::f64::consts::PI;
use std::path::Path;

fn load(name: &str) -> Scenario {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenarios/mrac")
        .join(name);
    scenario::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

fn parse(text: &str) -> Scenario {
    scenario::parse(text, "test.toml").unwrap_or_else(|e| panic!("{e}"))
}

/// An independent recursion `y_k = Σ_j b_j v_{k−j} − Σ_i a_i y_{k−i}` over the applied
/// inputs `v` (zero before `k = 0`), same order of summation as the plant.
fn recursion(b: &[f64], a: &[f64], v: &[f64]) -> Vec<f64> {
    let mut y: Vec<f64> = Vec::new();
    for k in 0..v.len() {
        let mut acc = 0.0;
        for j in 1..b.len() {
            if k >= j {
                acc += b[j] * v[k - j];
            }
        }
        for i in 1..a.len() {
            if k >= i {
                acc -= a[i] * y[k - i];
            }
        }
        y.push(acc);
    }
    y
}

/// Runs `sim` with the inputs `u`: the published `(y, z, r)` per sample.
fn run(sim: &mut PlantSim, u: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut ys, mut zs, mut rs) = (Vec::new(), Vec::new(), Vec::new());
    let (mut y, mut z, mut r) = ([0.0], [0.0], vec![0.0; sim.n_r()]);
    for &uk in u {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        ys.push(y[0]);
        zs.push(z[0]);
        rs.push(r.first().copied().unwrap_or(f64::NAN));
        sim.advance(&[uk]).unwrap();
    }
    (ys, zs, rs)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// A deterministic, irregular control input.
fn input(len: usize) -> Vec<f64> {
    (0..len)
        .map(|k| (0.21 * k as f64).sin() - 0.3 * (2.3 * k as f64).cos())
        .collect()
}

fn sim_of(s: &Scenario) -> PlantSim {
    PlantSim::new(&s.plant, s.rig.sample_period).unwrap()
}

#[test]
fn examples_1_and_2_publish_the_difference_equation_and_the_unit_step() {
    let den = [1.0, -2.0 * 0.5 * (PI / 4.0).cos(), 0.25];
    for (file, zero) in [("example1.toml", 0.5), ("example2.toml", 1.5)] {
        let s = load(file);
        assert_eq!(s.plant.kind, PlantKind::MracExample);
        assert_eq!(s.rig.sample_period, 0.001);
        assert_eq!((s.rig.duration / s.rig.sample_period).round(), 201.0);
        let p = &s.plant;
        assert_eq!(
            (p.n_u(), p.n_w(), p.n_y(), p.n_z(), p.n_r()),
            (1, 0, 1, 1, 1)
        );
        let d = p.discrete.as_ref().unwrap();
        assert_eq!(d.tf.num(), &[0.0, 1.0, -zero]);
        assert_eq!(d.tf.den(), &den);
        assert!(d.input_disturbance.is_empty());
        let u = input(200);
        let (y, z, r) = run(&mut sim_of(&s), &u);
        let want = recursion(&[0.0, 1.0, -zero], &den, &u);
        assert_eq!(bits(&y), bits(&want), "{file}");
        assert_eq!(bits(&z), bits(&y), "{file}: z = y");
        assert!(r.iter().all(|&v| v == 1.0), "{file}: unit step");
        // The step response of the plant alone: y_1 = 1, y_2 = 1 − zero + 0.7071…
        let (y, _, _) = run(&mut sim_of(&s), &[1.0; 3]);
        assert_eq!(y[..2], [0.0, 1.0]);
        assert_eq!(y[2], 1.0 - zero - den[1]);
    }
}

#[test]
fn the_scenarios_poles_are_at_rho_e_to_the_plus_minus_j_nu_and_the_zeros_the_chapters() {
    for (file, zero) in [
        ("example1.toml", 0.5),
        ("example2.toml", 1.5),
        ("example3.toml", 0.5),
    ] {
        let s = load(file);
        let d = sim_of(&s).describe();
        let pole = |v: &serde_json::Value| (v[0].as_f64().unwrap(), v[1].as_f64().unwrap());
        let poles: Vec<(f64, f64)> = d["plant-poles"]
            .as_array()
            .unwrap()
            .iter()
            .map(pole)
            .collect();
        let (re, im) = (0.5 * (PI / 4.0).cos(), 0.5 * (PI / 4.0).sin());
        assert_eq!(poles.len(), 2, "{file}");
        for want in [(re, im), (re, -im)] {
            assert!(
                poles
                    .iter()
                    .any(|p| (p.0 - want.0).abs() < 1e-12 && (p.1 - want.1).abs() < 1e-12),
                "{file}: {want:?} not in {poles:?}"
            );
        }
        let zeros = d["channels"][0]["zeros"].as_array().unwrap();
        assert_eq!(zeros.len(), 1);
        assert!((pole(&zeros[0]).0 - zero).abs() < 1e-12 && pole(&zeros[0]).1 == 0.0);
        assert_eq!(d["channels"][0]["num"], serde_json::json!([1.0, -zero]));
        assert_eq!(d["mrac-example"]["rho"], 0.5);
    }
}

#[test]
fn example_3s_disturbance_enters_at_the_plant_input() {
    let s = load("example3.toml");
    let d = s.plant.discrete.as_ref().unwrap();
    assert_eq!(d.input_disturbance.len(), 1);
    assert_eq!(d.input_disturbance[0].omega, 0.35);
    let u = input(300);
    let (y, z, _) = run(&mut sim_of(&s), &u);
    // The applied input is u_k + cos(0.35 k).
    let v: Vec<f64> = u
        .iter()
        .enumerate()
        .map(|(k, uk)| uk + (0.35 * k as f64).cos())
        .collect();
    let tf = &d.tf;
    assert_eq!(bits(&y), bits(&recursion(tf.num(), tf.den(), &v)));
    assert_eq!(bits(&z), bits(&y));
    // The same as Example 1's plant driven by u + d.
    let (y1, _, _) = run(&mut sim_of(&load("example1.toml")), &v);
    assert_eq!(bits(&y), bits(&y1));
    // With u = 0 the output is the disturbance's response alone: nonzero.
    let (y0, _, _) = run(&mut sim_of(&s), &[0.0; 50]);
    assert_eq!(y0[0], 0.0);
    assert_eq!(y0[1], 1.0);
    assert!(y0.iter().skip(2).any(|&v| v != 0.0));
}

const DISCRETE: &str = r#"
[rig]
name = "discrete"
sample-period = 0.001
duration = 1.0

[plant]
kind = "discrete"

[plant.discrete]
num = [0.0, 0.0, 1.0, 0.5, -0.25]
den = [1.0, -1.2, 0.5, -0.1]
"#;

#[test]
fn a_discrete_plant_from_num_and_den_is_its_recursion_with_its_input_delay() {
    let s = parse(DISCRETE);
    assert_eq!(s.plant.kind, PlantKind::Discrete);
    assert_eq!(s.plant.n_r(), 0);
    assert_eq!(s.plant.n_x(), 3 + 4);
    let (b, a) = ([0.0, 0.0, 1.0, 0.5, -0.25], [1.0, -1.2, 0.5, -0.1]);
    let u = input(500);
    let (y, z, _) = run(&mut sim_of(&s), &u);
    assert_eq!(bits(&y), bits(&recursion(&b, &a, &u)));
    assert_eq!(bits(&z), bits(&y));
    // plant.input-delays = [3]: the input is u_{k−3}.
    let delayed = parse(&DISCRETE.replace(
        "kind = \"discrete\"",
        "kind = \"discrete\"\ninput-delays = [3]",
    ));
    let (yd, _, _) = run(&mut sim_of(&delayed), &u);
    let mut shifted = vec![0.0; 3];
    shifted.extend_from_slice(&u[..u.len() - 3]);
    assert_eq!(bits(&yd), bits(&recursion(&b, &a, &shifted)));
    // A leading a_0 ≠ 1 is divided out: the same plant.
    let scaled = parse(&DISCRETE.replace(
        "num = [0.0, 0.0, 1.0, 0.5, -0.25]\nden = [1.0, -1.2, 0.5, -0.1]",
        "num = [0.0, 0.0, 2.0, 1.0, -0.5]\nden = [2.0, -2.4, 1.0, -0.2]",
    ));
    let (ys, _, _) = run(&mut sim_of(&scaled), &u);
    assert_eq!(bits(&ys), bits(&y));
}

#[test]
fn the_fixed_counts_of_a_discrete_plant_may_be_omitted_or_spelled_out() {
    let ex1 = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/mrac/example1.toml"),
    )
    .unwrap();
    let mut short = ex1.clone();
    for line in [
        "inputs = 1\n",
        "disturbances = 0\n",
        "outputs-y = 1\n",
        "outputs-z = 1\n",
        "commands = 1\n",
    ] {
        assert!(short.contains(line), "{line}");
        short = short.replacen(line, "", 1);
    }
    assert_eq!(parse(&short).plant, parse(&ex1).plant);
}

#[test]
fn the_discrete_kind_and_the_mrac_example_kind_agree_at_the_same_coefficients() {
    let text = DISCRETE.replace(
        "num = [0.0, 0.0, 1.0, 0.5, -0.25]\nden = [1.0, -1.2, 0.5, -0.1]",
        "num = [0.0, 1.0, -0.5]\nden = [1.0, -0.7071067811865476, 0.25]",
    );
    let u = input(200);
    let (a, _, _) = run(&mut sim_of(&parse(&text)), &u);
    let (b, _, _) = run(&mut sim_of(&load("example1.toml")), &u);
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn measurement_noise_is_added_to_y_and_z_but_not_fed_back_into_the_plant() {
    let noisy = parse(&format!(
        "{DISCRETE}\n[plant.noise]\ny-std = 0.1\nseed = 3\n"
    ));
    let u = input(100);
    let (y, z, _) = run(&mut sim_of(&noisy), &u);
    let clean = recursion(&[0.0, 0.0, 1.0, 0.5, -0.25], &[1.0, -1.2, 0.5, -0.1], &u);
    assert!(y.iter().zip(&clean).all(|(a, b)| a != b));
    let err: f64 = y
        .iter()
        .zip(&clean)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1.0, "{err}");
    assert_eq!(bits(&z), bits(&clean), "z has no noise here");
    let mut sim = sim_of(&noisy);
    let (mut yn, mut z0) = ([0.0], [0.0]);
    for &uk in &u[..10] {
        sim.advance(&[uk]).unwrap();
    }
    sim.sample_noiseless(&mut yn, &mut z0).unwrap();
    assert_eq!(yn[0], clean[10]);
}

#[test]
fn an_apply_offset_has_no_effect_on_a_discrete_plant() {
    let s = parse(DISCRETE);
    let u = input(60);
    let mut ideal = sim_of(&s);
    let mut offset = sim_of(&s);
    offset.set_apply_offset(Some(0.5)).unwrap();
    assert_eq!(offset.apply_offset(), None);
    assert!(offset.set_apply_offset(Some(1.5)).is_err());
    assert_eq!(bits(&run(&mut ideal, &u).0), bits(&run(&mut offset, &u).0));
    // reset returns to rest.
    offset.reset();
    assert_eq!(
        bits(&run(&mut offset, &u).0),
        bits(&run(&mut sim_of(&s), &u).0)
    );
    assert_eq!(offset.n_plant_states(), 7);
    assert_eq!(offset.n_exosystem_states(), 0);
    assert_eq!(offset.state().len(), 7);
}

fn command_of(table: &str) -> (Command, Vec<f64>) {
    let s = parse(&format!("{DISCRETE}\n{table}\n"));
    let (_, _, r) = run(&mut sim_of(&s), &[0.0; 300]);
    (s.plant.command, r)
}

#[test]
fn the_generated_commands_are_published_in_r_as_their_formulas() {
    let (c, r) = command_of("[plant.command]\nkind = \"step\"\namplitude = 2.5\nstart = 10");
    assert_eq!(
        c,
        Command::Step {
            amplitude: 2.5,
            start: 10
        }
    );
    for (k, v) in r.iter().enumerate() {
        assert_eq!(*v, if k >= 10 { 2.5 } else { 0.0 }, "k = {k}");
    }
    let (_, r) = command_of("[plant.command]\nkind = \"step\"");
    assert!(
        r.iter().all(|&v| v == 1.0),
        "a unit step from k = 0 by default"
    );

    let (_, r) = command_of("[plant.command]\nkind = \"harmonics\"\npreset = \"two-harmonic\"");
    for (k, v) in r.iter().enumerate() {
        let k = k as f64;
        assert_eq!(*v, k.cos() + (k / 8.0).cos());
    }
    let (_, r) = command_of("[plant.command]\nkind = \"harmonics\"\npreset = \"four-harmonic\"");
    for (k, v) in r.iter().enumerate() {
        let k = k as f64;
        assert_eq!(
            *v,
            k.cos() + (k / 2.0).cos() + (k / 4.0).cos() + (k / 8.0).cos()
        );
    }
    let (_, r) = command_of(
        "[plant.command]\nkind = \"harmonics\"\nterms = [ { amplitude = 0.5, frequency-rad-step = 0.3, phase-rad = 1.0 }, { amplitude = 2.0, frequency-rad-step = 0.0 } ]",
    );
    for (k, v) in r.iter().enumerate() {
        assert_eq!(*v, 0.5 * (0.3 * k as f64 + 1.0).cos() + 2.0);
    }
}

#[test]
fn a_generated_command_works_for_a_continuous_plant_too() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/first-order-lockstep.toml"),
    )
    .unwrap();
    let s = parse(&format!(
        "{text}\n[plant.command]\nkind = \"harmonics\"\npreset = \"two-harmonic\"\n"
    ));
    assert_eq!(s.plant.n_r(), 1);
    let mut sim = sim_of(&s);
    let (mut y, mut z, mut r) = ([0.0], [0.0], [0.0]);
    for k in 0..20u64 {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        assert_eq!(r[0], (k as f64).cos() + (k as f64 / 8.0).cos());
        sim.advance(&[0.0]).unwrap();
    }
}

#[test]
fn bad_tables_are_refused_naming_the_field() {
    let ex1 = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/mrac/example1.toml"),
    )
    .unwrap();
    let ex3 = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/mrac/example3.toml"),
    )
    .unwrap();
    let step =
        format!("{DISCRETE}\n[plant.command]\nkind = \"step\"\namplitude = 1.0\nstart = 0\n");
    let cases: Vec<(&str, &str, &str, &str)> = vec![
        // (base, from, to, field)
        (&ex1, "rho = 0.5", "rho = 1.0", "plant.mrac-example.rho"),
        (&ex1, "rho = 0.5", "rho = 0.0", "plant.mrac-example.rho"),
        (&ex1, "rho = 0.5", "rho = -0.5", "plant.mrac-example.rho"),
        (&ex1, "rho = 0.5", "rho = nan", "plant.mrac-example.rho"),
        (&ex1, "rho = 0.5", "rho = inf", "plant.mrac-example.rho"),
        (&ex1, "rho = 0.5", "", "plant.mrac-example.rho"),
        (
            &ex1,
            "nu = 0.7853981633974483",
            "nu = 4.0",
            "plant.mrac-example.nu",
        ),
        (
            &ex1,
            "nu = 0.7853981633974483",
            "nu = -0.1",
            "plant.mrac-example.nu",
        ),
        (
            &ex1,
            "example = 1",
            "example = 3",
            "plant.mrac-example.example",
        ),
        (&ex1, "[plant.mrac-example]", "[plant.mrac-exampel]", ""),
        (
            &ex1,
            "kind = \"mrac-example\"",
            "kind = \"discrete\"",
            "plant.mrac-example",
        ),
        (&ex1, "\ninputs = 1\n", "\ninputs = 2\n", "plant.inputs"),
        (
            &ex1,
            "\ndisturbances = 0\n",
            "\ndisturbances = 1\n",
            "plant.disturbances",
        ),
        (
            &ex1,
            "\noutputs-z = 1\n",
            "\noutputs-z = 2\n",
            "plant.outputs-z",
        ),
        (
            &ex1,
            "kind = \"mrac-example\"",
            "kind = \"mrac-example\"\ninitial-state = [1.0]",
            "plant.initial-state",
        ),
        (
            &ex1,
            "\ncommands = 1\n",
            "\ncommands = 2\n",
            "plant.commands",
        ),
        (
            &step,
            "kind = \"step\"",
            "kind = \"ramp\"",
            "plant.command.kind",
        ),
        (
            &step,
            "amplitude = 1.0",
            "amplitude = inf",
            "plant.command.amplitude",
        ),
        (
            &step,
            "amplitude = 1.0",
            "preset = \"two-harmonic\"",
            "plant.command.preset",
        ),
        (
            &step,
            "kind = \"step\"",
            "kind = \"harmonics\"",
            "plant.command.amplitude",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"",
            "plant.command.preset",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\npreset = \"three-harmonic\"",
            "plant.command.preset",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\nterms = []",
            "plant.command.terms",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\nterms = [ { amplitude = 1.0, frequency-rad-step = 4.0 } ]",
            "plant.command.terms[0].frequency-rad-step",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\nterms = [ { frequency-rad-step = 1.0 } ]",
            "plant.command.terms[0].amplitude",
        ),
        (
            &step,
            "kind = \"step\"\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\npreset = \"two-harmonic\"\nterms = [ { amplitude = 1.0, frequency-rad-step = 1.0 } ]",
            "plant.command.preset",
        ),
        (&step, "start = 0", "begin = 0", "plant.command"),
        (
            &ex3,
            "frequency-rad-step = 0.35",
            "frequency-rad-step = 3.5",
            "plant.input-disturbance.harmonics[0].frequency-rad-step",
        ),
        (
            &ex3,
            "amplitude = 1.0, frequency",
            "amplitude = nan, frequency",
            "plant.input-disturbance.harmonics[0].amplitude",
        ),
        (
            &ex3,
            "phase-rad = 0.0",
            "phase-rad = inf",
            "plant.input-disturbance.harmonics[0].phase-rad",
        ),
        (
            &ex3,
            "harmonics = [ {",
            "harmonics = [] # {",
            "plant.input-disturbance.harmonics",
        ),
        (
            &ex3,
            "[plant.input-disturbance]",
            "[plant.disturbance]\nwhite-std = 0.0\n[plant.input-disturbance]",
            "plant.disturbance",
        ),
        (
            DISCRETE,
            "den = [1.0, -1.2, 0.5, -0.1]",
            "den = []",
            "plant.discrete.den",
        ),
        (
            DISCRETE,
            "den = [1.0, -1.2, 0.5, -0.1]",
            "den = [0.0, 1.0]",
            "plant.discrete.den",
        ),
        (
            DISCRETE,
            "den = [1.0, -1.2, 0.5, -0.1]",
            "den = [1.0, inf]",
            "plant.discrete.den[1]",
        ),
        (
            DISCRETE,
            "den = [1.0, -1.2, 0.5, -0.1]",
            "",
            "plant.discrete.den",
        ),
        (
            DISCRETE,
            "num = [0.0, 0.0, 1.0, 0.5, -0.25]",
            "num = [1.0, 0.5]",
            "plant.discrete.num",
        ),
        (
            DISCRETE,
            "num = [0.0, 0.0, 1.0, 0.5, -0.25]",
            "num = []",
            "plant.discrete.num",
        ),
        (
            DISCRETE,
            "num = [0.0, 0.0, 1.0, 0.5, -0.25]",
            "num = [0.0, nan]",
            "plant.discrete.num[1]",
        ),
        (
            DISCRETE,
            "kind = \"discrete\"",
            "kind = \"discrete\"\ninput-delays = [1, 2]",
            "plant.input-delays",
        ),
        (
            DISCRETE,
            "[plant.discrete]",
            "[plant.tf]\nyu = [[0]]\n[plant.discrete]",
            "plant.tf",
        ),
    ];
    for (base, from, to, field) in cases {
        assert!(base.contains(from), "{from}");
        let text = base.replacen(from, to, 1);
        let e = scenario::parse(&text, "bad.toml").expect_err(&format!("{from} → {to}"));
        let m = e.to_string();
        if field.is_empty() {
            // An unknown table is a TOML error naming the key.
            assert!(m.contains("mrac-exampel"), "{m}");
            continue;
        }
        assert_eq!(e.field(), Some(field), "{from} → {to}: {m}");
        assert!(
            m.starts_with(&format!("bad.toml: field '{field}': ")),
            "{m}"
        );
    }
    // The input disturbance is for the discrete kinds only.
    let tf = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/first-order-lockstep.toml"),
    )
    .unwrap();
    let e = scenario::parse(
        &format!("{tf}\n[plant.input-disturbance]\nharmonics = [ {{ amplitude = 1.0, frequency-rad-step = 0.35 }} ]\n"),
        "bad.toml",
    )
    .unwrap_err();
    assert_eq!(e.field(), Some("plant.input-disturbance"), "{e}");
}

#[test]
fn the_scenario_files_spell_out_the_counts_the_service_reads() {
    // Without [service.channels] the service takes its counts from these keys of [plant]
    // (a missing `commands` counting as 0), so they must be there and agree.
    for file in ["example1.toml", "example2.toml", "example3.toml"] {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../scenarios/mrac")
            .join(file);
        let table: toml::Table = toml::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        let plant = &table["plant"];
        let s = load(file);
        for (key, n) in [
            ("outputs-y", s.plant.n_y()),
            ("outputs-z", s.plant.n_z()),
            ("commands", s.plant.n_r()),
            ("inputs", s.plant.n_u()),
        ] {
            assert_eq!(
                plant.get(key).and_then(|v| v.as_integer()),
                Some(n as i64),
                "{file}: plant.{key}"
            );
        }
    }
}

#[test]
fn a_discrete_plant_built_in_code_runs_as_the_file_and_bad_parameters_are_refused() {
    use plant_proxy::discrete::DiscretePlant;
    use plant_proxy::harmonic::Harmonic;
    use plant_proxy::mrac_examples::MracExample;
    use plant_proxy::scenario::{PlantParams, Tone};
    let plant = DiscretePlant {
        tf: MracExample::MinimumPhase.plant(0.5, PI / 4.0).unwrap(),
        input_disturbance: vec![Harmonic::unit(0.35)],
        example: None,
    };
    let mut params = PlantParams::new_discrete(plant.clone());
    params.command = Command::Step {
        amplitude: 1.0,
        start: 0,
    };
    let u = input(200);
    let mut sim = PlantSim::new(&params, 0.001).unwrap();
    let (y, _, r) = run(&mut sim, &u);
    let (y3, _, r3) = run(&mut sim_of(&load("example3.toml")), &u);
    assert_eq!(bits(&y), bits(&y3));
    assert_eq!(bits(&r), bits(&r3));

    let mut bad = params.clone();
    bad.discrete.as_mut().unwrap().input_disturbance[0].omega = f64::NAN;
    assert!(PlantSim::new(&bad, 0.001).is_err());
    let mut bad = params.clone();
    bad.disturbance.tones.push(Tone {
        input: 0,
        amplitude: 1.0,
        omega: 1.0,
        phase: 0.0,
    });
    assert!(PlantSim::new(&bad, 0.001).is_err());
    let mut bad = params.clone();
    bad.initial_state = vec![1.0];
    assert!(PlantSim::new(&bad, 0.001).is_err());
    let mut bad = params;
    bad.command = Command::harmonics_at(&[7.0]);
    assert!(PlantSim::new(&bad, 0.001).is_err());
}
