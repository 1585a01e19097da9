//! The fault campaign of issue 14, signals (docs/faults.md): SIGINT and SIGTERM to the
//! service while a plant is still running stop it cleanly: exit status 0, `report.json`
//! written with `stop_reason = "signal"`, and every logged row of `signals.csv` on disk,
//! whole. (`peer_failures.rs`, `killing_the_plant_is_detected_and_a_new_plant_is_served`,
//! checks SIGTERM once the plant has ended; here the plant is mid-run, and SIGINT too.)
//! Lockstep; no timing is asserted.

use rig_tests::*;
use std::time::Duration;

#[test]
fn sigint_and_sigterm_to_the_service_mid_run_stop_it_cleanly_with_its_report_and_every_logged_row_written()
 {
    for (sig, name) in [(libc::SIGINT, "sigint"), (libc::SIGTERM, "sigterm")] {
        let dir = TestDir::new(&format!("campaign-{name}"));
        let sc = dir.write(
            "scenario.toml",
            &(with_rig_name(&scenario_text("first-order-lockstep.toml"), &rig_name(name))
                + &test_service_tables("", &static_gain_controller())),
        );
        let run_folder = dir.path.join("service-run");
        let mut svc = start_service("service", &sc, &run_folder);
        let plant = start_lockstep_plant("plant", &sc, 100_000_000, &[]);
        svc.wait_for_line("plant connected", Duration::from_secs(30));
        std::thread::sleep(Duration::from_millis(500));
        svc.signal(sig);
        let st = svc.wait(Duration::from_secs(30));
        drop(plant);
        assert!(st.success(), "{name}: {st:?}\n{}", svc.output());

        let report = read_json(&run_folder.join("report.json"));
        assert_eq!(report["stop_reason"], "signal", "{name}");
        let published = report["stats"]["published"].as_u64().unwrap();
        assert!(published > 0, "{name}: {report}");
        let (header, rows) = read_csv(&run_folder.join("signals.csv"));
        assert_eq!(
            rows.len() as u64,
            report["log_written"].as_u64().unwrap(),
            "{name}"
        );
        assert_eq!(rows.len() as u64, published, "{name}: every answer logged");
        // Whole rows only: every field of every row, the last one included, is a number.
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r.len(), header.len(), "{name}: row {i} is torn");
            assert!(
                r.iter().all(|v| v.is_finite()),
                "{name}: row {i} has a non-number: {r:?}"
            );
        }
        let seq = column(&header, "seq");
        assert!(
            rows.windows(2).all(|w| w[1][seq] == w[0][seq] + 1.0),
            "{name}: a gap in the logged sequence"
        );
        assert_eq!(
            report["verdict"]["ok"], true,
            "{name}: {}",
            report["verdict"]
        );
    }
}
