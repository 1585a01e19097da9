//! The sampling arm of chapter 7 (`kind = "sampling-arm"`) through the scenario files and
//! `PlantSim`, as plant-proxy's loops and the offline studies run it: the files load with
//! the arm's wire contract, the plant reaches the surface at 2 s with zero torque and
//! publishes `r = F_d` for the contact phase, noise and seeds behave as for the other
//! kinds, and bad fields are refused naming the field.

mod common;

use plant_proxy::arm::{ContactModel, Phase};
use plant_proxy::scenario::{self, PlantKind, Scenario};
use plant_proxy::sim::PlantSim;
use rig_scenario::refusal_cases;

const FILES: [&str; 5] = [
    "linear",
    "hunt-crossley",
    "double-linear",
    "double-hunt-crossley",
    "lockstep-short",
];

fn load(name: &str) -> Scenario {
    let path = common::scenario_path(&format!("arm/{name}.toml"));
    scenario::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn text(name: &str) -> String {
    std::fs::read_to_string(common::scenario_path(&format!("arm/{name}.toml"))).unwrap()
}

/// Runs `steps` samples with zero torque; returns `(r, z, y[6])` per sample.
fn run_zero_torque(sim: &mut PlantSim, steps: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
    let mut out = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..steps {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        out.0.push(r[0]);
        out.1.push(z[0]);
        out.2.push(y[6]);
        sim.advance(&[0.0, 0.0])
            .unwrap_or_else(|e| panic!("sample {k}: {e}"));
    }
    out
}

#[test]
fn the_arm_scenarios_load_with_the_wire_contract_of_the_arm_rig() {
    for name in FILES {
        let s = load(name);
        let p = &s.plant;
        assert_eq!(p.kind, PlantKind::SamplingArm, "{name}");
        assert_eq!(
            (p.n_u(), p.n_w(), p.n_y(), p.n_z(), p.n_r()),
            (2, 0, 7, 1, 1)
        );
        assert_eq!(s.rig.sample_period, 0.0005, "{name}: 2 kHz");
        let arm = p.arm.as_ref().unwrap();
        assert_eq!(arm.spacecraft, control::arm::dynamics::ArmParams::CHAPTER_7);
        assert_eq!(arm.guidance.force_set_point, 25.0);
        assert_eq!(arm.surface.friction, 0.5);
        let double = name.starts_with("double");
        assert_eq!(arm.second.is_some(), double, "{name}");
        assert!(s.rig.duration >= if double { 11.0 } else { 2.5 }, "{name}");
    }
    let surface = |name: &str| load(name).plant.arm.unwrap().surface.model;
    assert_eq!(
        surface("linear"),
        ContactModel::kelvin_voigt(2e5, 5.0).unwrap()
    );
    assert_eq!(
        surface("hunt-crossley"),
        ContactModel::hunt_crossley(2e5, 0.9).unwrap()
    );
    let second = |name: &str| load(name).plant.arm.unwrap().second.unwrap();
    assert_eq!(
        second("double-linear").surface.model,
        ContactModel::kelvin_voigt(200.0, 500.0).unwrap()
    );
    assert_eq!(
        second("double-hunt-crossley").surface.model,
        ContactModel::hunt_crossley(300.0, 0.2).unwrap()
    );
    assert_eq!(second("double-linear").sample_mass, 0.5);
}

#[test]
fn with_zero_torque_every_scenario_touches_down_at_two_seconds_and_runs_to_its_end() {
    for name in FILES {
        let s = load(name);
        let mut sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
        let steps = s.run_steps(None).unwrap();
        let (r, z, y_fc) = run_zero_torque(&mut sim, steps);
        let arm = sim.arm().unwrap();
        let onset = arm.contact_onsets()[0].expect("no contact");
        assert!((onset - 2.0).abs() < 1e-9, "{name}: contact at {onset}");
        // r = F_d from the first sample at or after the onset, for 2 s, then 0.
        let first = (onset / 0.0005).ceil() as usize;
        assert!(r[..first].iter().all(|&v| v == 0.0), "{name}");
        let end = (((onset + 2.0) / 0.0005).ceil() as usize).min(r.len());
        assert!(r[first..end].iter().all(|&v| v == 25.0), "{name}");
        assert!(r[end..].iter().all(|&v| v == 0.0), "{name}");
        // The sampler is pushed by the surface; y's force sensor is z without noise.
        assert!(z.iter().any(|&f| f > 1.0), "{name}: no contact force");
        assert!(z.iter().all(|&f| f >= 0.0), "{name}: an adhesive force");
        assert_eq!(z, y_fc, "{name}");
        assert_eq!(z[..first].iter().filter(|&&f| f != 0.0).count(), 0);
        // Past the first contact phase the guidance departs; a double maneuver has
        // started its second descent (the collapsed arm does not reach the surface again).
        if name.starts_with("double") {
            assert_eq!(arm.guidance().maneuver(), 2, "{name}");
        } else if s.rig.duration > 4.5 {
            assert_eq!(arm.phase(), Phase::Departure, "{name}");
        }
    }
}

#[test]
fn describe_reports_the_arm_and_the_apply_offset_is_accepted() {
    let s = load("double-hunt-crossley");
    let mut sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
    let d = sim.describe();
    assert_eq!(d["surface"]["law"]["model"], "hunt-crossley");
    assert_eq!(d["second-sampling"]["surface"]["law"]["stiffness"], 300.0);
    assert_eq!(d["states"]["plant"], 8);
    assert_eq!(sim.n_plant_states(), 8);
    assert_eq!(sim.state().len(), 8);
    sim.set_apply_offset(Some(0.5)).unwrap();
    assert_eq!(sim.apply_offset(), Some(0.5));
    assert!(sim.set_apply_offset(Some(1.5)).is_err());
    sim.set_apply_offset(None).unwrap();
    assert_eq!(sim.apply_offset(), None);
}

#[test]
fn measurement_noise_is_seeded_per_sensor_and_the_truth_stays_noiseless() {
    let noisy = text("linear").replace(
        "y-std = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]",
        "y-std = [1e-3, 1e-3, 1e-2, 1e-2, 1e-3, 1e-3, 0.5]",
    );
    let s = scenario::parse(&noisy, "noisy").unwrap();
    assert_eq!(s.plant.noise.y_std[6], 0.5);
    let run = || {
        let mut sim = PlantSim::new(&s.plant, s.rig.sample_period).unwrap();
        let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
        let mut ys = Vec::new();
        for _ in 0..4200 {
            sim.sample(&mut y, &mut z, &mut r).unwrap();
            let mut truth = ([0.0; 7], [0.0; 1]);
            sim.sample_noiseless(&mut truth.0, &mut truth.1).unwrap();
            assert_eq!(z, truth.1, "z is the true contact force");
            ys.push((y, truth.0));
            sim.advance(&[0.0, 0.0]).unwrap();
        }
        ys
    };
    let a = run();
    assert_eq!(a, run(), "the same seed, the same run");
    let dev: Vec<f64> = (0..7)
        .map(|i| {
            let n = a.len() as f64;
            (a.iter().map(|(y, t)| (y[i] - t[i]).powi(2)).sum::<f64>() / n).sqrt()
        })
        .collect();
    for (i, (d, s)) in dev
        .iter()
        .zip([1e-3, 1e-3, 1e-2, 1e-2, 1e-3, 1e-3, 0.5])
        .enumerate()
    {
        assert!((d / s - 1.0).abs() < 0.1, "sensor {i}: std {d} for {s}");
    }
}

#[test]
fn a_study_can_change_the_surface_before_building_the_simulation() {
    let mut p = load("linear").plant;
    let arm = p.arm_mut().unwrap();
    arm.surface.model = ContactModel::kelvin_voigt(300.0, 0.35).unwrap();
    let mut sim = PlantSim::new(&p, 0.0005).unwrap();
    let (mut y, mut z, mut r) = ([0.0; 7], [0.0; 1], [0.0; 1]);
    for _ in 0..4010 {
        sim.sample(&mut y, &mut z, &mut r).unwrap();
        sim.advance(&[0.0, 0.0]).unwrap();
    }
    let arm = sim.arm().unwrap();
    assert_eq!(arm.surface().model.stiffness(), 300.0);
    // 5 ms into a 300 N/m surface: a fraction of a newton, not the stiff surface's tens.
    assert!(arm.in_contact() && arm.contact_force() < 1.0);
    // An invalid surface is refused when the simulation is built.
    p.arm_mut().unwrap().surface.model = ContactModel::KelvinVoigt {
        stiffness: -1.0,
        damping: 0.0,
    };
    let e = PlantSim::new(&p, 0.0005).unwrap_err().to_string();
    assert!(e.contains("surface.stiffness"), "{e}");
}

#[test]
fn bad_fields_are_refused_naming_the_field() {
    let base = text("double-linear");
    let cases =
        refusal_cases::parse(include_str!("../../tests/fixtures/refusals/arm-plant.toml")).unwrap();
    for c in cases {
        let t = c.edit(&base).unwrap();
        let e = scenario::parse(&t, "arm.toml").unwrap_err();
        if c.field.is_empty() {
            // An unknown table: the TOML reader names the key.
            assert!(e.to_string().contains("lid"), "{e}");
        } else {
            assert_eq!(e.field(), Some(c.field.as_str()), "{c:?}: {e}");
        }
        assert!(e.to_string().starts_with("arm.toml"), "{e}");
    }
    // The second site's surface is required with [plant.second-sampling].
    let t = base.replacen("[plant.second-sampling.surface]", "[plant.unused]", 1);
    assert!(scenario::parse(&t, "arm.toml").is_err());
    let cut = base
        .split("[plant.second-sampling.surface]")
        .next()
        .unwrap()
        .to_string();
    let e = scenario::parse(&cut, "arm.toml").unwrap_err();
    assert_eq!(e.field(), Some("plant.second-sampling.surface"), "{e}");
    // The arm's tables with another kind, and the arm without its surface.
    let other = text("linear").replacen(
        "\nkind = \"sampling-arm\"\n",
        "\nkind = \"state-space\"\n",
        1,
    );
    let e = scenario::parse(&other, "arm.toml").unwrap_err();
    assert!(e.field().unwrap().starts_with("plant."), "{e}");
    let e = scenario::parse(
        &text("linear").replacen("[plant.surface]", "[plant.unused]", 1),
        "arm.toml",
    )
    .unwrap_err();
    assert!(e.to_string().contains("unused"), "{e}");
    let no_surface: String = text("linear")
        .split("[plant.surface]")
        .next()
        .unwrap()
        .to_string()
        + "\n[plant.noise]\nseed = 1\n";
    let e = scenario::parse(&no_surface, "arm.toml").unwrap_err();
    assert_eq!(e.field(), Some("plant.surface"), "{e}");
}

#[test]
fn the_minimal_arm_scenario_takes_the_chapters_defaults() {
    let minimal = "[rig]\nname = \"arm\"\nsample-rate-hz = 2000.0\nduration = 1.0\n\n\
        [plant]\nkind = \"sampling-arm\"\n\n\
        [plant.surface]\nmodel = \"kelvin-voigt\"\nstiffness = 2.0e5\ndamping = 5.0\n";
    let s = scenario::parse(minimal, "minimal").unwrap();
    let full = load("linear");
    assert_eq!(s.plant.arm, full.plant.arm);
    assert_eq!(
        (s.plant.n_u(), s.plant.n_y(), s.plant.n_z(), s.plant.n_r()),
        (2, 7, 1, 1)
    );
}
