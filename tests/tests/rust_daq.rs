//! A DAQ process written in Rust on the plant-side library (the `loopback_daq` example of
//! `plant-side`) closes the loop with the real service, in lockstep.

use rig_tests::*;
use std::time::Duration;

/// The example binary, built by `cargo test --workspace` next to the workspace binaries.
fn loopback_daq() -> std::path::PathBuf {
    bin("examples/loopback_daq")
}

#[test]
fn the_loopback_daq_example_closes_the_loop_with_the_service_sample_by_sample() {
    let dir = TestDir::new("loopback-daq");
    let rig = rig_name("loopback-daq");
    // The service on the first-order scenario's counts and period (1 y, 1 z, 1 u, 1 ms)
    // with the static gain u = −2 y; the loopback reads back what its DAC held: y_k = u_{k−1}.
    let text = with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig)
        + &test_service_tables("", &static_gain_controller());
    let scenario = dir.write("scenario.toml", &text);
    let run_folder = dir.path.join("service-run");
    let mut service = start_service_until_plant_ends(&scenario, &run_folder);
    let steps = 40;
    let mut daq = Proc::start(
        "loopback-daq",
        &loopback_daq(),
        &[&rig, &steps.to_string(), "lockstep", "1000", "1"],
    );
    daq.wait_success(Duration::from_secs(120));
    service.wait_success(Duration::from_secs(60));
    assert!(
        daq.output().contains(&format!(
            "{steps} samples, {steps} actuations applied, 0 misses"
        )),
        "the plant side's report: {}",
        daq.output()
    );
    // y_0 = 1 (the DAC's initial value), u_k = −2 y_k, y_{k+1} = u_k: y_k = (−2)^k, exact
    // in floating point.
    let (header, rows) = read_csv(&run_folder.join("signals.csv"));
    let (iy, iu) = (column(&header, "y0"), column(&header, "u0"));
    assert_eq!(rows.len(), steps);
    for (k, row) in rows.iter().enumerate() {
        let expected = (-2.0_f64).powi(k as i32);
        assert_eq!(row[iy], expected, "y at k = {k}");
        assert_eq!(row[iu], -2.0 * expected, "u at k = {k}");
    }
}

#[test]
fn the_loopback_daq_example_refuses_bad_arguments_with_a_message() {
    let mut daq = Proc::start("loopback-daq", &loopback_daq(), &["rig", "ten"]);
    let status = daq.wait(Duration::from_secs(30));
    assert_eq!(status.code(), Some(2));
    assert!(
        daq.output().contains("STEPS: 'ten' is not a whole number"),
        "{}",
        daq.output()
    );
}
