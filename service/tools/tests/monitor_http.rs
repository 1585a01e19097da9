//! `rig monitor` over HTTP against a synthetic service: `/metrics` read with a Prometheus
//! text parser says what the frames say, `/api/state` and `/api/points` carry the frame,
//! the info and the points, the page has its elements, and bad requests get JSON errors.

mod monitor_support;

use monitor_support::*;
use prometheus_parse::{Scrape, Value};
use rig_tools::monitor::counters::{COUNTERS, MAXIMA};

fn scrape(text: &str) -> Scrape {
    Scrape::parse(text.lines().map(|l| Ok(l.to_string()))).expect("Prometheus text")
}

/// The value of series `name` with label `rig` (and the other labels given).
fn value(s: &Scrape, name: &str, labels: &[(&str, &str)]) -> Option<f64> {
    s.samples
        .iter()
        .find(|x| x.metric == name && labels.iter().all(|(k, v)| x.labels.get(k) == Some(*v)))
        .map(|x| match &x.value {
            Value::Counter(v) | Value::Gauge(v) | Value::Untyped(v) => *v,
            other => panic!("{name} is not a scalar: {other:?}"),
        })
}

#[test]
fn metrics_state_and_points_follow_the_published_frames() {
    let rig = unique_rig("http");
    let service = FakeService::start(&rig, 1_700_000_000_123_000_000);
    let m = MonitorProcess::start(&["--rig", &rig]);

    // Live, with the run's info.
    let st = wait_for("a live rig with its info", || {
        let s = rig_state(m.http, &rig);
        (s["connection"] == "live" && s["info"]["current"] == true).then_some(s)
    });
    let run = &st["run"];
    assert_eq!(run["run_id"], 1_700_000_000_123_000_000u64);
    assert_eq!(run["run_state"], "running");
    assert_eq!(run["verdict"], "failed");
    assert_eq!(run["verdict_text"], "DEADLINE: 13 misses > 10");
    assert_eq!(run["flags"]["adaptation_frozen"], true);
    assert_eq!(run["flags"]["safe_state"], false);
    assert_eq!(run["theta_norm"], 1.5);
    assert_eq!(run["counters"]["deadline_misses"], 13);
    assert_eq!(run["counters"]["telemetry_dropped"], 6);
    assert_eq!(run["latency"]["response"]["p99_ns"], 220_000);
    assert_eq!(run["tones"]["tones"][1]["hz"], 87.5);
    let sup = run["tones"]["tones"][0]["suppression_db"][0]
        .as_f64()
        .unwrap();
    assert!((sup - 40.0).abs() < 1e-9, "{sup}");
    assert_eq!(run["tunables"][0]["name"], "alpha");
    assert_eq!(run["tunables"][0]["value"], 0.25);
    assert_eq!(st["info"]["controller"], "rcac");
    assert!(
        st["info"]["config_text"]
            .as_str()
            .unwrap()
            .contains("# monitor-test-config")
    );
    assert_eq!(st["info"]["counts"]["n_z"], 2);

    // /metrics through a real Prometheus text parser.
    let reply = get(m.http, "/metrics");
    assert_eq!(reply.status, 200);
    assert!(
        reply
            .header("content-type")
            .unwrap()
            .starts_with("text/plain; version=0.0.4")
    );
    let s = scrape(&reply.body);
    let r = [("rig", rig.as_str())];
    let c = counters();
    for f in COUNTERS {
        let want = (f.get)(&c) as f64;
        if MAXIMA.contains(&f.name) {
            assert_eq!(
                value(&s, &format!("adaptive_rig_{}", f.name), &r),
                Some(want),
                "{}",
                f.name
            );
        } else {
            assert_eq!(
                value(&s, &format!("adaptive_rig_{}_total", f.name), &r),
                Some(want),
                "{}",
                f.name
            );
        }
    }
    assert_eq!(value(&s, "adaptive_rig_up", &r), Some(1.0));
    assert_eq!(value(&s, "adaptive_rig_adaptation_frozen", &r), Some(1.0));
    assert_eq!(value(&s, "adaptive_rig_safe_state", &r), Some(0.0));
    assert_eq!(value(&s, "adaptive_rig_verdict_ok", &r), Some(0.0));
    assert_eq!(value(&s, "adaptive_rig_theta_norm", &r), Some(1.5));
    assert_eq!(
        value(
            &s,
            "adaptive_rig_run_info",
            &[("rig", &rig), ("controller", "rcac")]
        ),
        Some(1.0)
    );
    assert_eq!(
        value(
            &s,
            "adaptive_rig_tunable_value",
            &[("rig", &rig), ("tunable", "alpha")]
        ),
        Some(0.25)
    );
    let sup = value(
        &s,
        "adaptive_rig_tone_suppression_db",
        &[("rig", &rig), ("hz", "87.5"), ("channel", "1")],
    )
    .unwrap();
    assert!((sup - 40.0).abs() < 1e-9);
    assert_eq!(
        value(
            &s,
            "adaptive_rig_latency_percentile_seconds",
            &[
                ("rig", &rig),
                ("histogram", "response"),
                ("percentile", "99")
            ]
        ),
        Some(220e-6)
    );
    assert_eq!(
        value(
            &s,
            "adaptive_rig_latency_max_seconds",
            &[("rig", &rig), ("histogram", "wakeup")]
        ),
        Some(0.015)
    );

    // The histograms: buckets as the frame's cumulative counts, +Inf = count, sum in s.
    let lat = latency(1000, 2);
    let h = s
        .samples
        .iter()
        .find(|x| {
            x.metric == "adaptive_rig_response_latency_seconds" && x.labels.get("rig") == Some(&rig)
        })
        .expect("the response histogram");
    let Value::Histogram(buckets) = &h.value else {
        panic!("not a histogram: {h:?}")
    };
    let mut got: Vec<(f64, f64)> = buckets.iter().map(|b| (b.less_than, b.count)).collect();
    got.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut want: Vec<(f64, f64)> = ipc_types::telemetry::LATENCY_BUCKET_BOUNDS_NS
        .iter()
        .zip(lat.buckets)
        .map(|(&le, n)| (le as f64 / 1e9, n as f64))
        .collect();
    want.push((f64::INFINITY, lat.count as f64));
    assert_eq!(got, want);
    assert_eq!(
        value(&s, "adaptive_rig_response_latency_seconds_count", &r),
        Some(1000.0)
    );
    let sum = value(&s, "adaptive_rig_response_latency_seconds_sum", &r).unwrap();
    assert!((sum - lat.sum_ns / 1e9).abs() < 1e-12, "{sum}");
    // Every family has its help and type.
    assert!(s.docs.contains_key("adaptive_rig_deadline_misses_total"));
    assert!(
        reply
            .body
            .contains("# TYPE adaptive_rig_response_latency_seconds histogram\n")
    );
    assert!(
        reply
            .body
            .contains("# TYPE adaptive_rig_deadline_misses_total counter\n")
    );

    // Points after a sample, in order, with Unix times.
    let all = get(m.http, &format!("/api/points?rig={rig}")).json();
    let pts = all["points"].as_array().unwrap();
    assert!(!pts.is_empty());
    let last = pts.last().unwrap()["seq"].as_u64().unwrap();
    let since = last.saturating_sub(5);
    let some = get(m.http, &format!("/api/points?rig={rig}&since={since}")).json();
    let seqs: Vec<u64> = some["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["seq"].as_u64().unwrap())
        .collect();
    assert!(seqs.iter().all(|&k| k > since), "{seqs:?}");
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "{seqs:?}");
    let p0 = &some["points"][0];
    assert_eq!(p0["z"].as_array().unwrap().len(), 2);
    assert_eq!(p0["u"][0], -0.25);
    let t = p0["t_unix_ms"].as_f64().unwrap();
    let want_t = (1_700_000_000_000_000_000u64 + 5_000_000_000 + seqs[0] * 5_000_000) as f64 / 1e6;
    assert!((t - want_t).abs() < 1e-3, "{t} vs {want_t}");
    // One rig: ?rig= may be left out.
    assert_eq!(
        get(m.http, "/api/points?max=3").json()["points"]
            .as_array()
            .unwrap()
            .len(),
        3
    );

    // The page.
    let page = get(m.http, "/");
    assert_eq!(page.status, 200);
    for id in [
        "scope",
        "theta-norm",
        "verdict",
        "freeze",
        "last-seq",
        "display-latency-ms",
        "config",
    ] {
        assert!(page.body.contains(&format!("id=\"{id}\"")), "#{id}");
    }
    let js = get(m.http, "/page.js");
    assert_eq!(js.status, 200);
    assert!(
        js.header("content-type")
            .unwrap()
            .starts_with("text/javascript")
    );

    assert!(service.frames() > 0);
    service.stop();
    assert!(m.stop().success());
}

#[test]
fn bad_requests_get_json_errors_and_commands_are_refused_without_the_flag() {
    let (a, b) = (unique_rig("bad-a"), unique_rig("bad-b"));
    let m = MonitorProcess::start(&["--rig", &a, "--rig", &b]);

    // Nothing published yet: both rigs wait, /metrics says they are down.
    let st = get(m.http, "/api/state").json();
    assert_eq!(st["monitor"]["commands_allowed"], false);
    assert_eq!(st["rigs"].as_array().unwrap().len(), 2);
    assert_eq!(st["rigs"][0]["connection"], "waiting");
    assert_eq!(st["rigs"][0]["run"], serde_json::Value::Null);
    let s = scrape(&get(m.http, "/metrics").body);
    assert_eq!(value(&s, "adaptive_rig_up", &[("rig", &a)]), Some(0.0));
    assert_eq!(value(&s, "adaptive_rig_up", &[("rig", &b)]), Some(0.0));
    assert_eq!(
        value(&s, "adaptive_rig_deadline_misses_total", &[("rig", &a)]),
        None
    );

    let r = get(m.http, &format!("/api/points?rig={a}&since=abc"));
    assert_eq!(r.status, 400);
    assert!(r.json()["error"].as_str().unwrap().contains("since=abc"));
    let r = get(m.http, "/api/points?rig=nope");
    assert_eq!(r.status, 404);
    assert!(
        r.json()["error"]
            .as_str()
            .unwrap()
            .contains("rig 'nope' is not monitored")
    );
    let r = get(m.http, "/api/points");
    assert_eq!(r.status, 400, "two rigs: the rig must be named");
    assert_eq!(get(m.http, "/nowhere").status, 404);

    let body = format!(r#"{{"rig": "{a}", "command": "freeze-adaptation"}}"#);
    let r = post_json(m.http, "/api/command", &body);
    assert_eq!(r.status, 403);
    assert!(
        r.json()["error"]
            .as_str()
            .unwrap()
            .contains("--allow-commands")
    );
    assert!(m.stop().success());
}

#[test]
fn a_bad_option_is_refused_naming_it() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rig"))
        .args(["monitor", "--rig", "no/slash", "--listen", "127.0.0.1:0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--rig no/slash"), "{err}");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rig"))
        .args(["monitor", "--rig", "ok", "--listen", "not-an-address"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--listen not-an-address"));
}

#[test]
fn a_sigterm_sent_as_soon_as_it_listens_stops_it_cleanly() {
    // The signal handlers are in place before the monitor says where it listens, so a
    // supervisor that stops it right away gets a clean exit, not a kill by the signal.
    for i in 0..5 {
        let m = MonitorProcess::start(&["--rig", &unique_rig(&format!("term-{i}"))]);
        let status = m.stop();
        assert!(status.success(), "run {i}: {status:?}");
    }
}
