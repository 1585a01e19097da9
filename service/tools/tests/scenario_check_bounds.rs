//! Regression tests of the fault campaign of issue 14: each configuration value that
//! crashed, hung or was accepted although meaningless is refused naming its field, by
//! the whole-scenario check (`rig check`) on a real scenario of `scenarios/`.

mod scenario_check_support;

use scenario_check_support::{assert_refused, check, remove, scenario, scenarios_dir, set};
use toml::Value;

fn acoustic() -> toml::Table {
    scenario("acoustic-rig.toml")
}

fn truss() -> toml::Table {
    scenario("truss/harmonic.toml")
}

/// A refusal case: `(scenario, path, value, field)`.
type Case<'a> = (fn() -> toml::Table, &'a str, Value, &'a str);

/// Each `(scenario, path, value, field)`: the scenario with `path` set to `value` is
/// refused naming `field`.
fn assert_each_refused(cases: &[Case<'_>]) {
    for (base, path, value, field) in cases {
        let mut t = base();
        set(&mut t, path, value.clone());
        assert_refused(&t, field);
    }
}

#[test]
fn the_unmodified_scenarios_are_accepted() {
    let origin = format!("{}/case.toml", scenarios_dir().display());
    for t in [acoustic(), truss()] {
        let c = check(&t, &origin).unwrap();
        assert!(c.plant.is_some());
    }
}

#[test]
fn config_crashers_are_refused_naming_the_field() {
    assert_each_refused(&[
        (
            acoustic,
            "service.peer-timeout",
            Value::Float(1e300),
            "service.peer-timeout",
        ),
        (
            acoustic,
            "log.queue-capacity",
            Value::Integer(1_000_000_000_000_000_000),
            "log.queue-capacity",
        ),
        (
            acoustic,
            "service.report.window",
            Value::Float(1e9),
            "service.report.window",
        ),
        (
            acoustic,
            "controller.nc",
            Value::Integer(100_000_000),
            "controller.nc",
        ),
        (
            truss,
            "controller.horizon",
            Value::Integer(100_000),
            "controller.horizon",
        ),
        (
            truss,
            "controller.n-hat",
            Value::Integer(100_000),
            "controller.n-hat",
        ),
        (
            acoustic,
            "rig.duration",
            Value::Float(1e300),
            "rig.duration",
        ),
    ]);
}

#[test]
fn config_accepted_but_meaningless_values_are_refused_naming_the_field() {
    assert_each_refused(&[
        (
            acoustic,
            "service.open-loop",
            Value::Float(1e300),
            "service.open-loop",
        ),
        (
            acoustic,
            "log.decimation",
            Value::Integer(0),
            "log.decimation",
        ),
        (
            acoustic,
            "plant.modal.modes",
            Value::Array(Vec::new()),
            "plant.modal.modes",
        ),
        (
            acoustic,
            "service.rms-settle",
            Value::Float(f64::NAN),
            "service.rms-settle",
        ),
        (
            truss,
            "controller.forgetting.lambda",
            Value::Float(0.99),
            "controller.forgetting.lambda",
        ),
        (
            acoustic,
            "plant.noise.y-std",
            Value::Float(1e3),
            "plant.noise.y-std",
        ),
        (
            truss,
            "controller.theta0",
            Value::Float(1e300),
            "controller.theta0",
        ),
        (
            acoustic,
            "controller.theta0",
            Value::Array(vec![Value::Float(1e300); 300]),
            "controller.theta0",
        ),
    ]);
}

#[test]
fn config_a_truss_node_without_mass_or_member_is_refused() {
    // A node keeps the consistent mass of its members when its own mass is 0; a truss
    // whose members carry no mass (density 0) and a node without lumped mass has a
    // singular mass matrix.
    let mut t = truss();
    set(&mut t, "plant.truss.nodes[2].mass", Value::Float(0.0));
    set(&mut t, "plant.truss.density", Value::Float(0.0));
    let origin = format!("{}/case.toml", scenarios_dir().display());
    let e = check(&t, &origin).unwrap_err();
    assert!(e.field.starts_with("plant.truss"), "{e}");
}

#[test]
fn config_other_bounds_are_refused_naming_the_field() {
    let rls = || {
        let mut t = acoustic();
        let c = scenario("rcac/acoustic-rls.toml");
        t.insert("controller".into(), c["controller"].clone());
        let file = Value::String("rcac/acoustic-target.toml".into());
        set(&mut t, "controller.target-model-file", file);
        t
    };
    assert_each_refused(&[
        (
            acoustic,
            "service.core",
            Value::Integer(5000),
            "service.core",
        ),
        (
            acoustic,
            "service.grace-periods",
            Value::Integer(i64::MAX),
            "service.grace-periods",
        ),
        (
            acoustic,
            "service.histogram-interval",
            Value::Float(f64::INFINITY),
            "service.histogram-interval",
        ),
        (
            acoustic,
            "service.report.tones-hz",
            Value::Array(vec![Value::Float(100.0); 65]),
            "service.report.tones-hz",
        ),
        (
            acoustic,
            "controller.kw",
            Value::Integer(i64::MAX),
            "controller.kw",
        ),
        (rls, "controller.nc", Value::Integer(1000), "controller.nc"),
        (
            truss,
            "controller.qp-max-iterations",
            Value::Integer(i64::MAX),
            "controller.qp-max-iterations",
        ),
        (
            truss,
            "controller.forgetting.tau-d",
            Value::Integer(i64::MAX),
            "controller.forgetting.tau-d",
        ),
        (
            acoustic,
            "plant.disturbances",
            Value::Integer(1 << 40),
            "plant.disturbances",
        ),
        (
            acoustic,
            "rig.sample-period",
            Value::Float(1e-9),
            "rig.sample-period",
        ),
        (
            acoustic,
            "service.channels",
            toml::toml! { y = 1
            z = 1
            r = 1
            u = 2 }
            .into(),
            "service.channels",
        ),
    ]);
    // A key that the plant half needs, removed: named by the plant's loader.
    let mut t = acoustic();
    remove(&mut t, "plant.kind");
    assert_refused(&t, "plant.kind");
}

#[test]
fn timings_the_two_halves_cannot_meet_are_refused_naming_the_field() {
    assert_each_refused(&[
        // The acoustic plant latches its inputs at the sample instant: only a service
        // that sends ahead meets it.
        (
            acoustic,
            "service.timing",
            Value::String("compute-first".into()),
            "service.plan-length",
        ),
        (
            acoustic,
            "service.timing",
            Value::String("answer-first".into()),
            "proxy.deadline",
        ),
        // Plans without a plan length.
        (
            acoustic,
            "service.plan-length",
            Value::Integer(0),
            "proxy.late-policy",
        ),
        (
            acoustic,
            "service.plan-length",
            Value::Integer(65),
            "service.plan-length",
        ),
    ]);
    // Compute-first without plans against that plant: refused for its deadline.
    let mut t = acoustic();
    set(
        &mut t,
        "service.timing",
        Value::String("compute-first".into()),
    );
    set(&mut t, "service.plan-length", Value::Integer(0));
    set(&mut t, "proxy.late-policy", Value::String("hold".into()));
    remove(&mut t, "proxy.plan-fallback");
    let e = assert_refused(&t, "proxy.deadline");
    assert!(e.message.contains("compute-first"), "{e}");
    // … and accepted with a deadline inside the period.
    set(&mut t, "proxy.deadline", Value::Float(0.8));
    let origin = format!("{}/case.toml", scenarios_dir().display());
    let c = check(&t, &origin).unwrap();
    assert_eq!(c.service.answer.timing, ipc_types::Timing::ComputeFirst);
}
