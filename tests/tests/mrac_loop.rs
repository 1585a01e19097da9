//! The chapter-4 controllers across processes: APPC and RC-MRAC in the service against
//! plant-proxy's discrete plants of `scenarios/mrac/`, in lockstep; the run report's
//! model-following error norm (4.85) against the logged `e`, and the chapter's bounds.

use rig_tests::*;
use std::path::{Path, PathBuf};

/// A file of the repository's `scenarios/mrac/` folder.
fn mrac_file(name: &str) -> String {
    scenario_text(&format!("mrac/{name}"))
}

/// Runs `scenario` (with `edit` applied to its text) with the controller file
/// `controller` in lockstep for its 201 samples; returns the run folder.
fn run(
    dir: &TestDir,
    test: &str,
    scenario: &str,
    controller: &str,
    edit: &dyn Fn(String) -> String,
) -> PathBuf {
    let text = edit(with_rig_name(&mrac_file(scenario), &rig_name(test)))
        + &test_service_tables("", &mrac_file(controller));
    let sc = dir.write("scenario.toml", &text);
    run_lockstep_pair(dir, &sc, 201, &[])
}

/// ‖e‖ (4.85) from the logged `e` column (`<kind>_e`) over seq 101–200, and the report's.
fn norms(run: &Path, e_column: &str) -> (f64, f64) {
    let (header, rows) = read_csv(&run.join("signals.csv"));
    let (seq, e) = (column(&header, "seq"), column(&header, e_column));
    let logged = rows
        .iter()
        .filter(|r| (101.0..=200.0).contains(&r[seq]))
        .map(|r| r[e] * r[e])
        .sum::<f64>()
        .sqrt();
    let report = read_json(&run.join("report.json"));
    let f = &report["model_following"];
    assert_eq!(f["window"], serde_json::json!([101, 200]), "{report}");
    assert_eq!(f["window_samples"], 100, "{report}");
    (logged, f["window_norm"].as_f64().expect("a norm"))
}

#[test]
fn rc_mrac_follows_the_step_of_example_1_across_processes() {
    let dir = TestDir::new("mrac-rc-step");
    let run = run(
        &dir,
        "mrac-rc-step",
        "example1.toml",
        "rc-mrac.toml",
        &|t| t,
    );
    let (logged, reported) = norms(&run, "rc_mrac_e");
    assert!(
        (logged - reported).abs() <= 1e-12 * (1.0 + logged),
        "{logged:e} vs {reported:e}"
    );
    // Over the window y_m has settled at N(1)/D_m(1) = 0.5/1.25 = 0.4, so ‖y_m‖ = 0.4·√100
    // = 4.0: the bound 10⁻⁴ asks for a converged loop (measured in process: 1.2·10⁻⁶; a
    // loop that has not converged leaves 10⁻² or more).
    assert!(reported < 1e-4, "‖e‖ = {reported:e}");
}

#[test]
fn appc_follows_the_four_harmonic_command_of_example_1_across_processes() {
    let dir = TestDir::new("mrac-appc-four");
    let four = |t: String| {
        t.replace(
            "kind = \"step\"                  # r_k = amplitude for k ≥ start\namplitude = 1.0\nstart = 0",
            "kind = \"harmonics\"\npreset = \"four-harmonic\"",
        )
    };
    assert!(four(mrac_file("example1.toml")).contains("four-harmonic"));
    let run = run(&dir, "mrac-appc-four", "example1.toml", "appc.toml", &four);
    let (logged, reported) = norms(&run, "appc_e");
    assert!(
        (logged - reported).abs() <= 1e-12 * (1.0 + logged),
        "{logged:e} vs {reported:e}"
    );
    // APPC's 8 coefficients converge only as fast as the command excites them (4.45):
    // measured in process 1.03·10⁻² against ‖y_m‖ ≈ 8.4 over the window; 5·10⁻² is 0.6 %
    // of it.
    assert!(reported < 5e-2, "‖e‖ = {reported:e}");
}
