//! Closed loops across two real processes over iceoryx2 shared memory, in lockstep so the
//! result does not depend on timing.

use rig_tests::*;

/// The first-order plant 1/(s + p) of `scenarios/first-order-lockstep.toml` discretized
/// exactly under ZOH at T: x⁺ = a x + b u, y = x, with a = e^{−pT}, b = (1 − a)/p.
fn first_order_ab() -> (f64, f64) {
    let (p, t) = (5.0_f64, 0.001_f64);
    let a = (-p * t).exp();
    (a, (1.0 - a) / p)
}

/// Runs plant-proxy (lockstep, `steps` samples, with a trace) against the service with the
/// given controller tables; returns the trace rows and the service's report.
fn run_lockstep(
    test: &str,
    controller: &str,
    extra_service: &str,
    extra: &str,
    steps: u64,
) -> (Vec<Vec<f64>>, serde_json::Value, TestDir) {
    let dir = TestDir::new(test);
    let rig = rig_name(test);
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig)
        + &test_service_tables(extra_service, controller)
        + extra;
    let scenario = dir.write("scenario.toml", &text);
    let trace = dir.path.join("trace.csv");
    let run_folder = run_lockstep_pair(
        &dir,
        &scenario,
        steps,
        &["--trace", trace.to_str().unwrap()],
    );
    let (header, rows) = read_csv(&trace);
    assert_eq!(header[0], "k");
    assert_eq!(header[2], "y0");
    assert_eq!(rows.len() as u64, steps);
    let report = read_json(&run_folder.join("report.json"));
    (rows, report, dir)
}

#[test]
fn a_static_gain_loop_matches_the_hand_computed_response_to_1e_9() {
    let (rows, report, _dir) = run_lockstep("static-gain", &static_gain_controller(), "", "", 2000);
    let (a, b) = first_order_ab();
    let k_gain = 2.0;
    // y_k = (a − b K)^k y_0 with y_0 = 1: the closed loop computed by hand.
    let mut worst: f64 = 0.0;
    for row in &rows {
        let k = row[0] as i32;
        let expected = (a - b * k_gain).powi(k);
        worst = worst.max((row[2] - expected).abs());
        // u_k = −K y_k was applied.
        assert!((row[4] + k_gain * row[2]).abs() < 1e-12, "u at k={k}");
    }
    assert!(worst < 1e-9, "largest deviation {worst:e}");
    assert_eq!(report["stats"]["controller_steps"], 2000);
    assert_eq!(report["stats"]["deadline_misses"], 0);
}

#[test]
fn a_dynamic_controller_loop_matches_an_independent_recursion_to_1e_9() {
    // fixtures/dynamic-controller.toml: the matrices of the recursion below.
    let controller = fixture("dynamic-controller.toml");
    let (rows, _report, _dir) = run_lockstep("dynamic", &controller, "", "", 3000);
    let (a, b) = first_order_ab();
    // Independent recursion of plant and controller.
    let (mut x, mut xc) = (1.0_f64, [0.0_f64; 2]);
    let mut worst: f64 = 0.0;
    for row in &rows {
        let y = x;
        let u = -0.3 * xc[0] - 0.2 * xc[1] - 1.0 * y;
        worst = worst.max((row[2] - y).abs()).max((row[4] - u).abs());
        xc = [0.9 * xc[0] + 0.05 * xc[1] + y, 0.7 * xc[1] + 0.5 * y];
        x = a * x + b * u;
    }
    assert!(worst < 1e-9, "largest deviation {worst:e}");
}

#[test]
fn lockstep_runs_are_bit_for_bit_repeatable() {
    let controller = static_gain_controller();
    let (r1, _, _d1) = run_lockstep("repeat-a", &controller, "", "", 500);
    let (r2, _, _d2) = run_lockstep("repeat-b", &controller, "", "", 500);
    for (a, b) in r1.iter().zip(&r2) {
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x.to_bits(), y.to_bits());
        }
    }
}

#[test]
fn nan_inf_and_out_of_range_measurements_are_rejected_counted_and_u_stays_finite() {
    // fixtures/proxy-faults.toml: NaN at 10 and 11, ±∞ at 20 and 30, 50.0 at 40–42.
    let (rows, report, dir) = run_lockstep(
        "faults",
        &static_gain_controller(),
        "y-min = -10.0\ny-max = 10.0",
        &fixture("proxy-faults.toml"),
        200,
    );
    let stats = &report["stats"];
    assert_eq!(stats["rejected_non_finite"], 4, "{stats}");
    assert_eq!(stats["rejected_out_of_range"], 3, "{stats}");
    assert_eq!(stats["controller_steps"], 200 - 7);
    // Every applied input is finite, and a rejected sample holds the previous input.
    for row in &rows {
        assert!(row[4].is_finite(), "u not finite at k={}", row[0]);
    }
    for k in [10usize, 11, 20, 30, 40, 41, 42] {
        assert_eq!(rows[k][4], rows[k - 1][4], "u held at k={k}");
    }
    // The service's own signal log agrees: u finite, status flags the rejections.
    let (header, log) = read_csv(&dir.path.join("service-run").join("signals.csv"));
    let u_col = header.iter().position(|h| h == "u0").expect("u0 column");
    let status_col = header
        .iter()
        .position(|h| h == "status")
        .expect("status column");
    assert!(log.iter().all(|r| r[u_col].is_finite()));
    let rejected = log
        .iter()
        .filter(|r| (r[status_col] as u32) & ipc_types::actuation_status::MEASUREMENT_REJECTED != 0)
        .count();
    assert_eq!(rejected, 7);
}
