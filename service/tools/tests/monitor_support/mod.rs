//! Shared by the `monitor_*` tests: a synthetic telemetry publisher, the `rig monitor`
//! binary as a child process (stopped with SIGTERM), and a small HTTP/1.1 client over
//! `std::net` (the tests need no HTTP client crate).

#![allow(dead_code)]

use ipc_types::telemetry::ports::TelemetryPublisher;
use ipc_types::telemetry::{
    LATENCY_BUCKETS, LatencySnapshot, TelemetryCounters, TelemetryFrame, TelemetryInfo, live_flags,
    run_state, set_fixed_text, verdict_state,
};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// A rig name unique to this test and process.
pub fn unique_rig(tag: &str) -> String {
    format!("mon-{tag}-{}", std::process::id())
}

/// The counters every synthetic frame carries: each field a different value.
pub fn counters() -> TelemetryCounters {
    TelemetryCounters {
        received: 100_000,
        published: 99_990,
        controller_steps: 99_980,
        lost: 7,
        samples_past_startup: 90_000,
        lost_past_startup: 5,
        held_past_startup: 3,
        caught_up: 11,
        rejected: 2,
        deadline_misses: 13,
        plant_reported_misses: 12,
        plan_covered_misses: 4,
        max_consecutive_misses: 3,
        safe_state_entries: 1,
        safe_state_cycles: 40,
        plant_silent_events: 0,
        new_sessions: 0,
        saturated_cycles: 9,
        controller_faults: 0,
        fallback_cycles: 0,
        publish_failures: 0,
        foreign_samples: 0,
        commands_applied: 2,
        commands_refused: 1,
        telemetry_dropped: 6,
    }
}

/// A latency snapshot of `count` values spread over the buckets (µs-scale values).
pub fn latency(count: u64, scale: u64) -> LatencySnapshot {
    let mut buckets = [0u64; LATENCY_BUCKETS];
    // Cumulative: a tenth at or below 5 µs, half at or below 20 µs, all but 1 at or below
    // 125 µs (one value above 10 ms lands in +Inf only).
    for (i, b) in buckets.iter_mut().enumerate() {
        *b = match i {
            0..=1 => 0,
            2 => count / 10,
            3 => count / 4,
            4..=6 => count / 2,
            _ => count - 1,
        };
    }
    LatencySnapshot {
        count,
        sum_ns: (count * 20_000 * scale) as f64,
        p50_ns: 18_000 * scale,
        p90_ns: 60_000 * scale,
        p99_ns: 110_000 * scale,
        p999_ns: 120_000 * scale,
        max_ns: 15_000_000,
        buckets,
    }
}

/// The info of run `run_id` of `rig`: one tunable `alpha` in [0, 1] and a configuration.
pub fn info(rig: &str, run_id: u64) -> Box<TelemetryInfo> {
    let mut i = Box::new(TelemetryInfo::empty());
    i.run_id = run_id;
    i.service_pid = 4242;
    i.sample_period_ns = 125_000;
    i.budget_ns = 100_000;
    i.counts = ipc_types::ChannelCounts::new(2, 2, 0, 1).unwrap();
    i.n_tunables = 1;
    set_fixed_text(&mut i.tunables[0].name, "alpha");
    i.tunables[0].min = 0.0;
    i.tunables[0].max = 1.0;
    i.tunables[0].initial = 0.2;
    set_fixed_text(&mut i.rig, rig);
    set_fixed_text(&mut i.controller, "rcac");
    set_fixed_text(&mut i.run_folder, "/tmp/runs/x");
    set_fixed_text(&mut i.config_path, "/tmp/scenario.toml");
    i.set_config_text(&format!(
        "[service]\nrig = \"{rig}\"\n# monitor-test-config\n"
    ));
    i
}

/// Frame `frame_seq` of run `run_id` with 10 points from sample `10·frame_seq`.
pub fn frame(run_id: u64, frame_seq: u64) -> TelemetryFrame {
    let mut f = TelemetryFrame::empty();
    f.run_id = run_id;
    f.frame_seq = frame_seq;
    f.state = run_state::RUNNING;
    f.flags = live_flags::ADAPTATION_FROZEN | live_flags::COMMANDS_ENABLED;
    f.verdict = verdict_state::FAILED;
    set_fixed_text(&mut f.verdict_text, "DEADLINE: 13 misses > 10");
    f.n_z = 2;
    f.n_u = 1;
    f.service_pid = 4242;
    f.n_tunables = 1;
    f.tunable_values[0] = 0.25;
    f.unix_minus_monotonic_ns = 1_700_000_000_000_000_000;
    f.t_publish_ns = 5_000_000_000 + frame_seq * 50_000_000;
    f.n_points = 10;
    for k in 0..10u64 {
        let seq = frame_seq * 10 + k;
        let p = &mut f.points[k as usize];
        p.seq = seq;
        p.t_sample_ns = 5_000_000_000 + seq * 5_000_000;
        p.theta_norm = 1.5;
        p.z[0] = (seq as f64 * 0.1).sin();
        p.z[1] = 0.5;
        p.u[0] = -0.25;
    }
    f.last_seq = frame_seq * 10 + 9;
    f.counters = counters();
    f.latency = [
        latency(1000, 1),
        latency(1000, 1),
        latency(1000, 2),
        latency(1000, 1),
    ];
    f.tones.n_tones = 2;
    f.tones.window_samples = 8000;
    f.tones.hz = [0.0; 16];
    f.tones.hz[0] = 120.0;
    f.tones.hz[1] = 87.5;
    for i in 0..2 {
        for j in 0..2 {
            f.tones.amplitude[i][j] = 0.01;
            f.tones.open_loop[i][j] = 1.0;
        }
    }
    f
}

/// A thread that publishes rig `rig`'s info once and a frame of run `run_id` every 20 ms
/// until stopped (frames carry the same counters, so that a test can compare them).
pub struct FakeService {
    stop: Arc<AtomicBool>,
    frames: Arc<AtomicU64>,
    thread: Option<JoinHandle<()>>,
}

impl FakeService {
    /// Starts publishing; `last` turns every frame from then on into run-ended frames when
    /// set.
    pub fn start(rig: &str, run_id: u64) -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let frames = Arc::new(AtomicU64::new(0));
        let (s, n, rig) = (stop.clone(), frames.clone(), rig.to_string());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread = std::thread::spawn(move || {
            // iceoryx2 ports stay on the thread that made them.
            let p = match TelemetryPublisher::create(&rig) {
                Ok(p) => p,
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                    return;
                }
            };
            assert!(p.publish_info(&info(&rig, run_id)));
            let _ = ready_tx.send(Ok(()));
            let mut k = 0u64;
            while !s.load(Ordering::Relaxed) {
                p.publish(&frame(run_id, k));
                k += 1;
                n.store(k, Ordering::Relaxed);
                std::thread::sleep(Duration::from_millis(20));
            }
            // The last frame says the run ended.
            let mut f = frame(run_id, k);
            f.state = run_state::ENDED;
            p.publish(&f);
        });
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => panic!("telemetry publisher: {e}"),
            Err(_) => panic!("the publisher thread ended"),
        }
        Self {
            stop,
            frames,
            thread: Some(thread),
        }
    }

    /// Frames published so far.
    pub fn frames(&self) -> u64 {
        self.frames.load(Ordering::Relaxed)
    }

    /// Publishes an ended frame and drops the publisher (the service goes away).
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            t.join().expect("publisher thread");
        }
    }
}

impl Drop for FakeService {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// `rig monitor` as a child process.
pub struct MonitorProcess {
    child: Child,
    /// Its HTTP address.
    pub http: SocketAddr,
    /// Its Foxglove address, when asked for.
    pub foxglove: Option<SocketAddr>,
}

impl MonitorProcess {
    /// Starts `rig monitor --listen 127.0.0.1:0 ARGS…` and reads where it listens.
    pub fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_rig"))
            .arg("monitor")
            .args(["--listen", "127.0.0.1:0"])
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starting rig monitor");
        let want_fox = args.contains(&"--foxglove");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut http = None;
        let mut foxglove = None;
        let deadline = Instant::now() + Duration::from_secs(30);
        while http.is_none() || (want_fox && foxglove.is_none()) {
            let left = deadline.saturating_duration_since(Instant::now());
            let line = match rx.recv_timeout(left) {
                Ok(l) => l,
                Err(_) => {
                    let _ = child.kill();
                    panic!("rig monitor did not say where it listens");
                }
            };
            if let Some(rest) = line.strip_prefix("rig monitor: listening on http://") {
                let addr = rest.split('/').next().unwrap();
                http = Some(addr.parse().expect("HTTP address"));
            } else if let Some(rest) = line.strip_prefix("rig monitor: foxglove on ws://") {
                foxglove = Some(rest.trim().parse().expect("Foxglove address"));
            }
        }
        Self {
            child,
            http: http.unwrap(),
            foxglove,
        }
    }

    /// Whether it still runs.
    pub fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Stops it with SIGTERM and returns its exit status.
    pub fn stop(mut self) -> std::process::ExitStatus {
        self.terminate()
    }

    fn terminate(&mut self) -> std::process::ExitStatus {
        unsafe {
            libc::kill(self.child.id() as i32, libc::SIGTERM);
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            if let Ok(Some(s)) = self.child.try_wait() {
                return s;
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                return self.child.wait().expect("wait");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for MonitorProcess {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            self.terminate();
        }
    }
}

/// An HTTP reply.
#[derive(Debug)]
pub struct Reply {
    /// Status code.
    pub status: u16,
    /// Headers, names in lower case.
    pub headers: Vec<(String, String)>,
    /// Body.
    pub body: String,
}

impl Reply {
    /// A header's value.
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The body as JSON.
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", self.body))
    }
}

/// One HTTP/1.1 request (`Connection: close`).
pub fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &str,
) -> Reply {
    let mut s = TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        req += &format!("{k}: {v}\r\n");
    }
    req += &format!("Content-Length: {}\r\n\r\n{body}", body.len());
    s.write_all(req.as_bytes()).expect("send");
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).expect("read");
    let text = String::from_utf8(raw).expect("UTF-8 reply");
    let (head, rest) = text.split_once("\r\n\r\n").expect("a header block");
    let mut lines = head.split("\r\n");
    let status: u16 = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|c| c.parse().ok())
        .expect("status line");
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    let chunked = headers
        .iter()
        .any(|(k, v)| k == "transfer-encoding" && v.contains("chunked"));
    let body = if chunked {
        dechunk(rest)
    } else {
        rest.to_string()
    };
    Reply {
        status,
        headers,
        body,
    }
}

fn dechunk(mut s: &str) -> String {
    let mut out = String::new();
    while let Some((size, rest)) = s.split_once("\r\n") {
        let n = usize::from_str_radix(size.trim(), 16).expect("chunk size");
        if n == 0 {
            break;
        }
        out += &rest[..n];
        s = &rest[n + 2..];
    }
    out
}

/// `GET path`.
pub fn get(addr: SocketAddr, path: &str) -> Reply {
    request(addr, "GET", path, &[], "")
}

/// `POST path` with a JSON body.
pub fn post_json(addr: SocketAddr, path: &str, body: &str) -> Reply {
    request(
        addr,
        "POST",
        path,
        &[("Content-Type", "application/json")],
        body,
    )
}

/// Polls `f` every 20 ms until it returns `Some` (panics after 30 s, naming `what`).
pub fn wait_for<T>(what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The state of rig `rig` in `/api/state`.
pub fn rig_state(addr: SocketAddr, rig: &str) -> serde_json::Value {
    let s = get(addr, "/api/state").json();
    s["rigs"]
        .as_array()
        .expect("rigs")
        .iter()
        .find(|r| r["rig"] == rig)
        .cloned()
        .expect("the rig in /api/state")
}
