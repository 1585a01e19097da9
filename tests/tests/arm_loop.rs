//! The sampling arm of chapter 7 across processes: the service's `sampling-arm` controller
//! (Algorithm 3: feedback linearization, the robust gain of `scenarios/arm/robust-gain.toml`
//! and the PCAC augmentation) against plant-proxy's nonlinear arm on the Figure 7.4
//! surface (Kelvin–Voigt, k_s = 2·10⁵ N/m, c_s = 5 N s/m), in lockstep through the descent
//! and the first 0.5 s of contact (`scenarios/arm/lockstep-short.toml`), and on a soft
//! surface (k_s = 300 N/m) with and without the augmentation for the whole contact. The
//! run report's force regulation is checked against the logged force and the set-point.

use rig_tests::*;
use std::path::PathBuf;

/// Samples of `lockstep-short.toml`: 2.5 s at 2 kHz.
const STEPS: u64 = 5000;

/// Runs the short arm scenario with the controller file `controller` of `scenarios/arm/`;
/// the robust-gain file is copied beside the scenario, where the controller table finds
/// it. Returns the run folder.
fn run(dir: &TestDir, test: &str, controller: &str) -> PathBuf {
    dir.write("robust-gain.toml", &scenario_text("arm/robust-gain.toml"));
    let text = with_rig_name(&scenario_text("arm/lockstep-short.toml"), &rig_name(test))
        + &test_service_tables("", &scenario_text(&format!("arm/{controller}")));
    let sc = dir.write("scenario.toml", &text);
    run_lockstep_pair(dir, &sc, STEPS, &[])
}

/// The contact-phase samples of the log: `(F_c measured, mode)` where the command is on.
fn contact_forces(run: &std::path::Path) -> Vec<f64> {
    let (header, rows) = read_csv(&run.join("signals.csv"));
    let (y6, mode) = (column(&header, "y6"), column(&header, "mode"));
    rows.iter()
        .filter(|r| r[mode] > 0.5)
        .map(|r| r[y6])
        .collect()
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

#[test]
fn the_augmented_arm_controller_holds_25_newtons_across_processes() {
    let dir = TestDir::new("arm-pcac");
    let run = run(&dir, "arm-pcac", "pcac.toml");
    let report = read_json(&run.join("report.json"));
    let phases = report["force_regulation"]["phases"]
        .as_array()
        .unwrap_or_else(|| panic!("no force regulation in {report}"));
    assert_eq!(phases.len(), 1, "{report}");
    let p = &phases[0];
    // Touch-down at 0.2 m / 0.1 m/s = 2 s: the guidance raises F_d at the first sample
    // after it (k = 4001 at 2 kHz).
    assert_eq!(p["first_seq"], 4001, "{report}");
    assert_eq!(p["set_point"], 25.0);
    let logged = contact_forces(&run);
    assert_eq!(logged.len(), 999, "contact samples in the log");
    let reported = p["median"].as_f64().unwrap();
    assert_eq!(
        reported,
        median(&logged),
        "the report's median is the log's"
    );
    // The chapter's goal: 25 N. The augmented loop settles inside ±5 % within the first
    // half second (measured: 0.23 s).
    assert!(
        (reported - 25.0).abs() <= 0.05 * 25.0,
        "median {reported} N"
    );
    let settled = p["settling_s"].as_f64().expect("settled within ±5 %");
    assert!(settled < 0.4, "settled after {settled} s");
    assert_eq!(report["verdict"]["ok"], true, "{report}");
}

#[test]
fn on_a_soft_surface_only_the_augmented_controller_reaches_25_newtons() {
    // Figure 7.3's low-stiffness corner: k_s = 300 N/m, c_s = 5 N s/m, the whole 2 s
    // contact (4 s of run).
    let soft = |t: String| {
        let t = t.replace(
            "stiffness = 2.0e5              # k_s, N/m",
            "stiffness = 300.0              # k_s, N/m",
        );
        t.replace("duration = 2.5 ", "duration = 4.0 ")
    };
    let text = soft(scenario_text("arm/lockstep-short.toml"));
    assert!(text.contains("stiffness = 300.0") && text.contains("duration = 4.0"));
    let mut medians = Vec::new();
    for controller in ["robust.toml", "pcac.toml"] {
        let test = format!("arm-soft-{}", &controller[..controller.len() - 5]);
        let dir = TestDir::new(&test);
        dir.write("robust-gain.toml", &scenario_text("arm/robust-gain.toml"));
        let sc = dir.write(
            "scenario.toml",
            &(with_rig_name(&text, &rig_name(&test))
                + &test_service_tables("", &scenario_text(&format!("arm/{controller}")))),
        );
        let run = run_lockstep_pair(&dir, &sc, 8000, &[]);
        let report = read_json(&run.join("report.json"));
        let p = &report["force_regulation"]["phases"][0];
        assert!(
            (p["duration_s"].as_f64().unwrap() - 1.999).abs() < 1e-9,
            "{report}"
        );
        medians.push(p["median"].as_f64().expect("a contact phase"));
    }
    let (robust, augmented) = (medians[0], medians[1]);
    // The robust gain's slowest decay is at this corner (docs/design-tools.md): its force
    // barely rises in 2 s (measured: 1.2 N); PCAC's augmentation reaches the set-point
    // (measured: 24.99 N).
    assert!(robust < 12.5, "robust median {robust} N");
    assert!(
        (augmented - 25.0).abs() <= 0.05 * 25.0,
        "augmented median {augmented} N"
    );
}
