//! `rig monitor` outlives the service: when the publisher goes away the rig turns stale
//! with the ended run's final state still shown; a new run (new `run_id`) is picked up
//! and the old one is listed among the earlier runs; the scope starts again with it.

mod monitor_support;

use monitor_support::*;

/// `adaptive_rig_up` of `rig`, read with a Prometheus text parser.
fn up(addr: std::net::SocketAddr, rig: &str) -> f64 {
    let text = get(addr, "/metrics").body;
    let s = prometheus_parse::Scrape::parse(text.lines().map(|l| Ok(l.to_string()))).unwrap();
    let x = s
        .samples
        .iter()
        .find(|x| x.metric == "adaptive_rig_up" && x.labels.get("rig") == Some(rig))
        .expect("adaptive_rig_up");
    match x.value {
        prometheus_parse::Value::Gauge(v) => v,
        ref other => panic!("{other:?}"),
    }
}

#[test]
fn the_monitor_survives_the_service_and_picks_up_a_new_run() {
    let rig = unique_rig("restart");
    let mut m = MonitorProcess::start(&["--rig", &rig]);
    let first = FakeService::start(&rig, 1_000);
    wait_for("the first run", || {
        let s = rig_state(m.http, &rig);
        (s["connection"] == "live" && s["run"]["run_id"] == 1_000).then_some(())
    });
    // The service ends its run and goes away.
    first.stop();
    let s = wait_for("a stale rig", || {
        let s = rig_state(m.http, &rig);
        (s["connection"] == "stale").then_some(s)
    });
    assert_eq!(s["run"]["run_id"], 1_000, "the last run stays on show");
    assert_eq!(s["run"]["run_state"], "ended");
    assert_eq!(s["run"]["counters"]["deadline_misses"], 13);
    assert_eq!(up(m.http, &rig), 0.0);
    assert!(m.running());

    // A new service, a new run.
    let second = FakeService::start(&rig, 2_000);
    let s = wait_for("the second run", || {
        let s = rig_state(m.http, &rig);
        (s["connection"] == "live" && s["run"]["run_id"] == 2_000 && s["info"]["run_id"] == 2_000)
            .then_some(s)
    });
    let prev = s["previous_runs"].as_array().unwrap();
    assert_eq!(prev.len(), 1);
    assert_eq!(prev[0]["run_id"], 1_000);
    assert_eq!(prev[0]["run_state"], "ended");
    assert_eq!(s["runs_seen"], 2);
    assert_eq!(s["info"]["current"], true);
    // The scope holds the new run's points only: its first frame starts at sample 0.
    let pts = get(m.http, &format!("/api/points?rig={rig}")).json();
    assert_eq!(pts["run_id"], 2_000);
    assert_eq!(pts["points"][0]["seq"], 0);
    assert!(second.frames() > 0);
    assert_eq!(up(m.http, &rig), 1.0);
    second.stop();
    assert!(m.stop().success());
}
