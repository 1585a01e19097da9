//! A synthetic service for trying `rig monitor` without a rig: it publishes a run's
//! telemetry (info once, a frame every 50 ms with 40 decimated points of a two-channel `z`
//! whose two tones an imaginary controller suppresses over the first 20 s) and answers the
//! operator commands (they change the flags and the tunable `alpha` it reports).
//!
//! ```sh
//! cargo run --release -p rig-tools --example monitor_demo -- demo &
//! target/release/rig monitor --rig demo --allow-commands
//! ```
//!
//! It runs until killed; a run ends (and a new one starts) on `stop-run`.

use ipc_types::operator::{OperatorReply, OperatorServer, command, outcome};
use ipc_types::telemetry::ports::TelemetryPublisher;
use ipc_types::telemetry::{
    LATENCY_BUCKET_BOUNDS_NS, TelemetryFrame, TelemetryInfo, live_flags, run_state, set_fixed_text,
    verdict_state,
};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

const PERIOD_NS: u64 = 125_000;
const DECIMATION: u64 = 10;
const POINTS_PER_FRAME: u64 = 40;
const TONES: [f64; 2] = [120.0, 310.0];
/// Latencies are binned up to this many µs.
const MAX_US: u64 = 1000;

fn monotonic_ns() -> u64 {
    ipc_types::clock::monotonic_ns()
}

fn unix_ns() -> i128 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_nanos() as i128)
        .unwrap_or(0)
}

fn info(rig: &str, run_id: u64) -> Box<TelemetryInfo> {
    let mut i = Box::new(TelemetryInfo::empty());
    i.run_id = run_id;
    i.service_pid = std::process::id();
    i.sample_period_ns = PERIOD_NS;
    i.budget_ns = 100_000;
    i.counts = ipc_types::ChannelCounts::new(2, 2, 0, 1).unwrap_or_default();
    i.n_tunables = 1;
    set_fixed_text(&mut i.tunables[0].name, "alpha");
    i.tunables[0].min = 0.0;
    i.tunables[0].max = 1.0;
    i.tunables[0].initial = 0.2;
    set_fixed_text(&mut i.rig, rig);
    set_fixed_text(&mut i.controller, "rcac");
    set_fixed_text(&mut i.run_folder, "runs/demo");
    set_fixed_text(&mut i.config_path, "scenarios/demo.toml");
    i.set_config_text(&format!(
        "# monitor_demo: a synthetic run\n[service]\nrig = \"{rig}\"\nperiod-us = 125\n\n[controller]\nkind = \"rcac\"\nalpha = 0.2\n"
    ));
    i
}

/// A pseudo-random number in [0, 1) from a counter.
fn noise(k: u64) -> f64 {
    let mut x = k.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x ^= x >> 29;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^= x >> 32;
    (x >> 11) as f64 / (1u64 << 53) as f64
}

fn main() {
    let rig = std::env::args().nth(1).unwrap_or_else(|| "demo".into());
    let publisher = match TelemetryPublisher::create(&rig) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("monitor_demo: rig '{rig}': {e}");
            std::process::exit(2);
        }
    };
    let server = OperatorServer::create(&rig).ok();
    loop {
        run(&rig, &publisher, server.as_ref());
        std::thread::sleep(Duration::from_secs(2));
    }
}

fn run(rig: &str, publisher: &TelemetryPublisher, server: Option<&OperatorServer>) {
    let run_id = unix_ns() as u64;
    publisher.publish_info(&info(rig, run_id));
    println!("monitor_demo: rig '{rig}', run {run_id}");
    let start = Instant::now();
    let (mut flags, mut alpha) = (live_flags::COMMANDS_ENABLED, 0.2);
    let mut f = TelemetryFrame::empty();
    let (mut seq, mut frame_seq) = (0u64, 0u64);
    // Response times in 1 µs bins up to MAX_US, their count, sum and largest.
    let mut bins = vec![0u64; MAX_US as usize];
    let (mut total, mut sum_ns, mut max_ns, mut misses) = (0u64, 0f64, 0u64, 0u64);
    let mut stop = false;
    while !stop {
        if let Some(s) = server {
            while let Some(p) = s.receive() {
                let r = p.request();
                let mut reply = OperatorReply::new(r.request_id, outcome::APPLIED, "");
                match r.command {
                    command::FREEZE_ADAPTATION => flags |= live_flags::ADAPTATION_FROZEN,
                    command::RESUME_ADAPTATION => flags &= !live_flags::ADAPTATION_FROZEN,
                    command::ENTER_SAFE_STATE => {
                        flags |= live_flags::SAFE_STATE | live_flags::OPERATOR_SAFE_STATE
                    }
                    command::LEAVE_SAFE_STATE => {
                        flags &= !(live_flags::SAFE_STATE | live_flags::OPERATOR_SAFE_STATE)
                    }
                    command::STOP_RUN => stop = true,
                    command::SET_TUNABLE
                        if r.tunable() == "alpha" && (0.0..=1.0).contains(&r.value) =>
                    {
                        alpha = r.value;
                        reply.value = alpha;
                    }
                    command::SET_TUNABLE => {
                        reply = OperatorReply::new(
                            r.request_id,
                            outcome::REFUSED,
                            "alpha is the only tunable, within [0, 1]",
                        );
                    }
                    _ => {
                        reply = OperatorReply::new(
                            r.request_id,
                            outcome::BAD_REQUEST,
                            "unknown command",
                        )
                    }
                }
                if reply.outcome == outcome::APPLIED {
                    reply.applied_before_seq = seq + 1;
                }
                p.reply(&reply);
            }
        }
        let t_s = start.elapsed().as_secs_f64();
        let now = monotonic_ns();
        // The tones decay while adapting; the safe state lets them back.
        let gain = if flags & live_flags::SAFE_STATE != 0 {
            1.0
        } else {
            (-t_s / 5.0).exp().max(0.02)
        };
        f.run_id = run_id;
        f.frame_seq = frame_seq;
        f.state = if stop {
            run_state::ENDED
        } else {
            run_state::RUNNING
        };
        f.flags = flags;
        f.service_pid = std::process::id();
        f.n_z = 2;
        f.n_u = 1;
        f.n_tunables = 1;
        f.tunable_values[0] = alpha;
        f.unix_minus_monotonic_ns = (unix_ns() - i128::from(now)) as i64;
        f.t_publish_ns = now;
        f.n_points = POINTS_PER_FRAME as u32;
        for k in 0..POINTS_PER_FRAME {
            let t_ns = now - (POINTS_PER_FRAME - 1 - k) * DECIMATION * PERIOD_NS;
            let t = t_ns as f64 * 1e-9;
            let p = &mut f.points[k as usize];
            p.seq = seq;
            p.t_sample_ns = t_ns;
            let tone = |hz: f64, ph: f64| (2.0 * std::f64::consts::PI * hz * t + ph).sin();
            p.z[0] = gain * (tone(TONES[0], 0.0) + 0.5 * tone(TONES[1], 1.0))
                + 0.02 * (noise(seq) - 0.5);
            p.z[1] = gain * (0.7 * tone(TONES[0], 0.4) + 0.3 * tone(TONES[1], 2.0))
                + 0.02 * (noise(seq + 7) - 0.5);
            p.u[0] = (1.0 - gain) * -0.8 * tone(TONES[0], 0.2);
            p.theta_norm = 3.0 * (1.0 - gain) + 0.1;
            seq += DECIMATION;
        }
        f.last_seq = seq - 1;
        // Counters and latency histograms (run totals).
        let c = &mut f.counters;
        c.received = seq;
        c.published = seq;
        c.controller_steps = seq;
        c.samples_past_startup = seq.saturating_sub(8000);
        for k in 0..POINTS_PER_FRAME {
            let v = 15_000
                + (noise(seq * 3 + k) * 40_000.0) as u64
                + if noise(seq + k) > 0.999 { 200_000 } else { 0 };
            if v > 125_000 {
                misses += 1;
            }
            bins[((v / 1000) as usize).min(MAX_US as usize - 1)] += 1;
            total += 1;
            sum_ns += v as f64;
            max_ns = max_ns.max(v);
        }
        c.deadline_misses = misses;
        f.verdict = if misses > 10 {
            verdict_state::FAILED
        } else if seq > 8000 {
            verdict_state::OK
        } else {
            verdict_state::PENDING
        };
        if misses > 10 {
            set_fixed_text(
                &mut f.verdict_text,
                &format!("DEADLINE: {misses} misses > 10"),
            );
        }
        for (i, l) in f.latency.iter_mut().enumerate() {
            let scale = [1, 1, 2, 1][i];
            let (count, sum) = (total, sum_ns * scale as f64);
            // Percentile p: the upper edge of the 1 µs bin where the count reaches p.
            let q = |p: f64| -> u64 {
                let want = ((count as f64) * p).ceil().max(1.0) as u64;
                let mut acc = 0;
                for (us, n) in bins.iter().enumerate() {
                    acc += n;
                    if acc >= want {
                        return (us as u64 + 1) * 1000 * scale;
                    }
                }
                MAX_US * 1000 * scale
            };
            l.count = count;
            l.sum_ns = sum;
            l.p50_ns = q(0.5);
            l.p90_ns = q(0.9);
            l.p99_ns = q(0.99);
            l.p999_ns = q(0.999);
            l.max_ns = max_ns * scale;
            for (b, &le) in l.buckets.iter_mut().zip(&LATENCY_BUCKET_BOUNDS_NS) {
                *b = bins
                    .iter()
                    .enumerate()
                    .take_while(|(us, _)| (*us as u64 + 1) * 1000 * scale <= le)
                    .map(|(_, n)| n)
                    .sum();
            }
        }
        f.tones.n_tones = 2;
        f.tones.window_samples = 8000;
        for (i, hz) in TONES.iter().enumerate() {
            f.tones.hz[i] = *hz;
            f.tones.open_loop[i][0] = [1.0, 0.5][i];
            f.tones.open_loop[i][1] = [0.7, 0.3][i];
            f.tones.amplitude[i][0] = gain * f.tones.open_loop[i][0];
            f.tones.amplitude[i][1] = gain * f.tones.open_loop[i][1];
        }
        publisher.publish(&f);
        frame_seq += 1;
        std::thread::sleep(Duration::from_millis(50));
    }
}
