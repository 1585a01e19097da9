//! `rig monitor` on real runs, as a user watches them: its `/metrics` after a lockstep
//! main job against the run's own report, and its page in a real headless browser
//! (Debian's `chromium` driven through `chromedriver` over WebDriver) while a lockstep run
//! goes on: the scope updates, "freeze adaptation" stops `‖θ‖`, and the display latency
//! (sample time to page) is shown.
//!
//! The browser test needs `chromium` and `chromedriver` (Debian: `apt-get install chromium
//! chromium-driver`; `.ci/run` installs them), or `RIG_CHROMEDRIVER` naming a driver. No
//! test asserts a timing.

use ipc_types::operator::{OperatorClient, OperatorRequest, command};
use rig_tests::*;
use serde_json::Value;
use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// `GET path` on `addr` (HTTP/1.1, one request per connection): the body.
fn get(addr: &str, path: &str) -> String {
    let mut s = std::net::TcpStream::connect(addr).unwrap_or_else(|e| panic!("{addr}: {e}"));
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").expect("an HTTP response");
    assert!(head.starts_with("HTTP/1.1 200"), "{path}: {head}");
    if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        dechunk(body)
    } else {
        body.to_string()
    }
}

fn dechunk(mut body: &str) -> String {
    let mut out = String::new();
    while let Some((size, rest)) = body.split_once("\r\n") {
        let n = usize::from_str_radix(size.trim(), 16).unwrap_or(0);
        if n == 0 {
            break;
        }
        out.push_str(&rest[..n]);
        body = &rest[n + 2..];
    }
    out
}

/// Starts `rig monitor --rig <rig> --listen 127.0.0.1:0 <extra…>`; returns it and its
/// address.
fn start_monitor(rig: &str, extra: &[&str]) -> (Proc, String) {
    let mut args = vec!["monitor", "--rig", rig, "--listen", "127.0.0.1:0"];
    args.extend_from_slice(extra);
    let monitor = Proc::start("monitor", &bin("rig"), &args);
    let line = monitor.wait_for_line("listening on http://", Duration::from_secs(60));
    let addr = line
        .split("http://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .expect("an address")
        .to_string();
    (monitor, addr)
}

/// The monitor's view of the one rig it watches, once `done` holds.
fn wait_state(addr: &str, what: &str, done: impl Fn(&Value) -> bool) -> Value {
    let start = Instant::now();
    loop {
        let v: Value = serde_json::from_str(&get(addr, "/api/state")).unwrap();
        let rig = v["rigs"][0].clone();
        if done(&rig) {
            return rig;
        }
        assert!(
            start.elapsed() < Duration::from_secs(300),
            "waited for {what}: {rig}"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn the_metrics_of_a_lockstep_main_job_are_the_counters_of_its_report() {
    let test = "monitor-metrics";
    let dir = TestDir::new(test);
    let rig = rig_name(test);
    let scenario = dir.write("scenario.toml", &acoustic_rig_scenario(test));
    let folder = dir.path.join("run");
    let (mut monitor, addr) = start_monitor(&rig, &[]);
    let mut launch = start_launch(
        &scenario,
        &folder,
        &["--mode", "lockstep", "--duration", "3.0"],
    );
    launch.wait_success(Duration::from_secs(300));
    wait_state(&addr, "the run's last frame", |r| {
        r["run"]["run_state"] == "ended"
    });
    let report = read_json(&folder.join("report.json"));
    let text = get(&addr, "/metrics");
    let scrape = prometheus_parse::Scrape::parse(text.lines().map(|l| Ok(l.to_string()))).unwrap();
    let value = |name: &str| -> f64 {
        let s = scrape
            .samples
            .iter()
            .find(|s| s.metric == name && s.labels.get("rig") == Some(rig.as_str()))
            .unwrap_or_else(|| panic!("{name} of rig {rig} not in\n{text}"));
        match &s.value {
            prometheus_parse::Value::Counter(v)
            | prometheus_parse::Value::Gauge(v)
            | prometheus_parse::Value::Untyped(v) => *v,
            other => panic!("{name}: {other:?}"),
        }
    };
    let stat = |k: &str| report["stats"][k].as_u64().unwrap() as f64;
    for (metric, field) in [
        ("adaptive_rig_received_total", "received"),
        ("adaptive_rig_published_total", "published"),
        ("adaptive_rig_controller_steps_total", "controller_steps"),
        ("adaptive_rig_lost_total", "skipped"),
        ("adaptive_rig_deadline_misses_total", "deadline_misses"),
        ("adaptive_rig_safe_state_cycles_total", "safe_state_cycles"),
        ("adaptive_rig_saturated_cycles_total", "saturated_cycles"),
    ] {
        assert_eq!(value(metric), stat(field), "{metric}");
    }
    assert!(stat("received") > 20_000.0);
    // The response histogram holds what the report's latency summary counted.
    let response = scrape
        .samples
        .iter()
        .find(|s| {
            s.metric == "adaptive_rig_response_latency_seconds"
                && s.labels.get("rig") == Some(rig.as_str())
        })
        .expect("the response histogram");
    let prometheus_parse::Value::Histogram(buckets) = &response.value else {
        panic!("{:?}", response.value);
    };
    let count = buckets.last().map(|b| b.count).unwrap_or(0.0);
    assert_eq!(
        count,
        report["latency"]["response"]["count"].as_u64().unwrap() as f64
    );
    let verdict_ok = report["verdict"]["ok"].as_bool().unwrap();
    assert_eq!(
        value("adaptive_rig_verdict_ok"),
        f64::from(u8::from(verdict_ok))
    );
    monitor.signal(libc::SIGTERM);
    monitor.wait(Duration::from_secs(30));
}

/// chromedriver: `RIG_CHROMEDRIVER`, or Debian's.
fn chromedriver() -> PathBuf {
    let p = std::env::var_os("RIG_CHROMEDRIVER")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromedriver"));
    assert!(
        p.exists(),
        "{} not found: the browser test needs chromium and chromedriver (apt-get install \
         chromium chromium-driver), or RIG_CHROMEDRIVER naming a driver",
        p.display()
    );
    p
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

#[test]
fn the_page_shows_the_run_live_and_its_freeze_button_stops_theta() {
    let test = "monitor-page";
    let dir = TestDir::new(test);
    let rig = rig_name(test);
    let scenario = operator_tone_scenario(&dir, &rig);
    let folder = dir.path.join("run");
    let (mut monitor, addr) = start_monitor(&rig, &["--allow-commands"]);
    let mut service = start_service("service", &scenario, &folder);
    // The operator ends the run; the plant has samples for far longer.
    let mut plant = start_lockstep_plant("plant", &scenario, 50_000_000, &[]);
    let port = free_port();
    let mut driver = Proc::start(
        "chromedriver",
        &chromedriver(),
        &[&format!("--port={port}")],
    );
    driver.wait_for_line("started successfully", Duration::from_secs(60));
    let shot = dir.path.join("page.png");

    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let (theta_before, theta_frozen, latency_ms) = rt.block_on(async {
        let mut caps = serde_json::Map::new();
        caps.insert(
            "goog:chromeOptions".into(),
            serde_json::json!({
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                         "--window-size=1400,1600"]
            }),
        );
        let connector = hyper_util::client::legacy::connect::HttpConnector::new();
        let c = fantoccini::ClientBuilder::new(connector)
            .capabilities(caps)
            .connect(&format!("http://127.0.0.1:{port}"))
            .await
            .expect("a WebDriver session in chromium");
        c.goto(&format!("http://{addr}/")).await.unwrap();
        let read = |id: &'static str, attr: Option<&'static str>| {
            let c = c.clone();
            async move {
                let e = c.find(fantoccini::Locator::Id(id)).await.unwrap();
                match attr {
                    Some(a) => e.attr(a).await.unwrap().unwrap_or_default(),
                    None => e.text().await.unwrap(),
                }
            }
        };
        let until = |what: &'static str, id: &'static str, ok: fn(&str) -> bool| {
            let read = &read;
            async move {
                let start = Instant::now();
                loop {
                    let v = read(id, None).await;
                    if ok(&v) {
                        return v;
                    }
                    assert!(
                        start.elapsed() < Duration::from_secs(120),
                        "the page never showed {what} (#{id}: {v})"
                    );
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            }
        };
        // The scope updates: the newest sample's index grows.
        let first: u64 = until("a running loop", "last-seq", |v| {
            v.parse::<u64>().is_ok_and(|k| k > 1_000)
        })
        .await
        .parse()
        .unwrap();
        until("newer samples", "last-seq", |v| !v.is_empty()).await;
        let start = Instant::now();
        let mut later = first;
        while later <= first + 1_000 && start.elapsed() < Duration::from_secs(120) {
            later = read("last-seq", None).await.parse().unwrap_or(first);
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        assert!(
            later > first + 1_000,
            "the page's sample index stayed at {later}"
        );
        let theta_before = read("theta-norm", Some("data-value")).await;
        // Freeze: the button sends the command; the flag comes on and θ stops.
        c.find(fantoccini::Locator::Id("freeze"))
            .await
            .unwrap()
            .click()
            .await
            .unwrap();
        until("the freeze's reply", "command-result", |v| {
            v.contains("applied")
        })
        .await;
        let start = Instant::now();
        loop {
            let class = read("flag-adaptation-frozen", Some("class")).await;
            if class.split_whitespace().any(|c| c == "on") {
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(60), "flag: {class}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        // Let frames of frozen samples arrive, then θ must hold over further samples.
        tokio::time::sleep(Duration::from_millis(500)).await;
        let frozen_seq: u64 = read("last-seq", None).await.parse().unwrap();
        let theta_frozen = read("theta-norm", Some("data-value")).await;
        let start = Instant::now();
        loop {
            let k: u64 = read("last-seq", None).await.parse().unwrap();
            if k > frozen_seq + 2_000 {
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(120), "stuck at {k}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let theta_later = read("theta-norm", Some("data-value")).await;
        assert_eq!(theta_later, theta_frozen, "θ changed while frozen");
        let latency_ms = read("display-latency-ms", None).await;
        let png = c.screenshot().await.unwrap();
        std::fs::write(&shot, png).unwrap();
        c.close().await.unwrap();
        (theta_before, theta_frozen, latency_ms)
    });
    eprintln!(
        "display latency shown: {latency_ms} ms; screenshot {}",
        shot.display()
    );
    assert!(!theta_before.is_empty() && !theta_frozen.is_empty());
    assert!(
        latency_ms.trim().parse::<f64>().is_ok_and(|v| v >= 0.0),
        "display latency: {latency_ms}"
    );
    let client = OperatorClient::open(&rig).unwrap();
    let reply = client
        .send(
            &OperatorRequest::new(command::STOP_RUN, 1),
            Duration::from_secs(20),
        )
        .unwrap();
    assert_eq!(reply.message(), "");
    service.wait(Duration::from_secs(60));
    plant.signal(libc::SIGTERM);
    plant.wait(Duration::from_secs(60));
    let report = read_json(&folder.join("report.json"));
    let commands = report["operator_commands"].as_array().unwrap();
    assert_eq!(commands[0]["command"], "freeze-adaptation");
    assert_eq!(commands[0]["outcome"], "applied");
    driver.signal(libc::SIGTERM);
    monitor.signal(libc::SIGTERM);
    monitor.wait(Duration::from_secs(30));
    driver.wait(Duration::from_secs(30));
}
