//! `run_plant` in process against a fake service thread over real iceoryx2 ports: the
//! lockstep waiting rule with a send-ahead service and with a compute-first one, injected
//! stalls, plan entries and fallbacks, and the flags and inputs the next measurements
//! report; in real time, a plant latched at the sample instant with a send-ahead service,
//! and its refusal of a service that does not send ahead.
//!
//! The fake service answers sample `j` with `u = 100 + j` and plans `u = −(100 + j)` for the
//! samples after it, so the input each measurement reports (`u_applied`, the input applied
//! for the previous sample) says where it came from.

mod common;

use common::first_order_with;
use ipc_types::ports::{ConnectOptions, ContractInfo, ServicePorts, Side};
use ipc_types::{Actuation, Measurement, Timing, actuation_status, measurement_flags as mf};
use plant_proxy::runtime::{PlantError, PlantReport, PlantRunOptions, ProxyConfig, run_plant};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

fn answer(j: u64) -> f64 {
    100.0 + j as f64
}

fn planned(j: u64) -> f64 {
    -(100.0 + j as f64)
}

/// What the fake service saw of one measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Seen {
    seq: u64,
    flags: u32,
    u_applied: f64,
}

/// The fake service: answers with `timing` (send-ahead: `A{k}` when nothing was sent ahead
/// for `k`, then `A{k+1}` with `plan_len` plan entries; compute-first: `A{k}`), acknowledges
/// injected stalls, and returns what it saw once the plant's last sample came.
fn fake_service(
    rig: String,
    timing: Timing,
    plan_len: usize,
) -> std::thread::JoinHandle<Vec<Seen>> {
    std::thread::spawn(move || {
        let counts = ipc_types::ChannelCounts::new(1, 1, 0, 1).unwrap();
        let own = ContractInfo::new(Side::Service, counts, 1_000_000).with_timing(timing);
        let opts = ConnectOptions::new(Duration::from_secs(20)).with_listener(true);
        let ports: ServicePorts =
            ipc_types::ports::connect(&rig, own, "fake-service", opts).expect("connect");
        let send = |seq: u64, reply_to: u64, status: u32| {
            let mut a = Actuation::zeroed(counts);
            (a.seq, a.reply_to, a.status, a.timing) = (seq, reply_to, status, timing.wire());
            a.u[0] = answer(seq);
            a.plan_len = plan_len as u32;
            for (j, e) in a.plan.iter_mut().take(plan_len).enumerate() {
                e[0] = planned(seq + 1 + j as u64);
            }
            ports.publisher.send_copy(a).expect("send");
        };
        let mut seen = Vec::new();
        let mut sent_ahead_for = None;
        let start = Instant::now();
        loop {
            assert!(start.elapsed() < Duration::from_secs(60), "{seen:?}");
            let Some(m) = ports.subscriber.receive().expect("receive") else {
                if let Some(l) = &ports.listener {
                    let _ = l.timed_wait(|_| {}, Duration::from_millis(5));
                }
                continue;
            };
            let m: Measurement = *m;
            seen.push(Seen {
                seq: m.seq,
                flags: m.flags,
                u_applied: m.u_applied[0],
            });
            let k = m.seq;
            if m.flags & mf::INJECTED_STALL != 0 {
                send(k, k, actuation_status::STALL_ACK);
                sent_ahead_for = None;
            } else if timing == Timing::SendAhead {
                if sent_ahead_for != Some(k) {
                    send(k, k, 0);
                }
                send(k + 1, k, 0);
                sent_ahead_for = Some(k + 1);
            } else {
                send(k, k, 0);
            }
            let _ = ports.notifier.notify();
            if m.flags & mf::LAST_SAMPLE != 0 {
                return seen;
            }
        }
    })
}

fn rig(name: &str) -> String {
    format!("pp-{name}-{}", std::process::id())
}

/// Runs the plant of the first-order scenario with `proxy` for `steps` samples against a
/// fake service of `timing`; the plant's report and what the service saw.
fn run(
    name: &str,
    proxy: &str,
    steps: u64,
    timing: Timing,
    plan_len: usize,
) -> (Result<PlantReport, PlantError>, Option<Vec<Seen>>) {
    let rig = rig(name);
    let text = first_order_with(&rig, proxy);
    let scenario = plant_proxy::scenario::parse(&text, "test.toml").unwrap();
    let proxy = ProxyConfig::parse(&text, "test.toml", 1).unwrap();
    let service = fake_service(rig, timing, plan_len);
    let opts = PlantRunOptions {
        steps: Some(steps),
        trace: None,
        verbose: false,
    };
    let report = run_plant(&scenario, &proxy, &opts, &AtomicBool::new(false));
    let seen = service.join().ok();
    (report, seen)
}

const LOCKSTEP: &str = "[proxy]\nmode = \"lockstep\"\nlockstep-timeout = 10.0\npeer-timeout = 20.0";

/// The flags of a measurement that matter here.
const TIMING_FLAGS: u32 =
    mf::INJECTED_STALL | mf::PREVIOUS_ACTUATION_MISSED | mf::PLAN_APPLIED | mf::PLANT_SAFE_OUTPUT;

#[test]
fn lockstep_with_a_send_ahead_service_applies_the_input_sent_ahead_then_the_plan_then_the_fallback()
{
    // Stalled samples 5 to 8; plans of 2 entries.
    let proxy = format!(
        "{LOCKSTEP}\nlate-policy = \"plan\"\nplan-fallback = \"hold\"\n[proxy.faults]\nstalls = [{{ at = 5, periods = 4 }}]"
    );
    let (report, seen) = run("ahead-stall", &proxy, 14, Timing::SendAhead, 2);
    let report = report.expect("the run ends at its last sample");
    let seen = seen.expect("the fake service ends");
    assert_eq!(
        seen.iter().map(|s| s.seq).collect::<Vec<_>>(),
        (0..14).collect::<Vec<_>>()
    );
    // seen[k + 1] reports the input applied for sample k.
    let applied: Vec<f64> = seen[1..].iter().map(|s| s.u_applied).collect();
    let expected = [
        answer(0),
        answer(1),
        answer(2),
        answer(3),
        answer(4),
        answer(5),  // stalled, but sent ahead (with A{5}'s plan) before the stall
        planned(6), // A{5}'s plan, entry 0
        planned(7), // entry 1
        planned(7), // past plan_len: the fallback holds
        answer(9),  // the service answers the first sample after the stall itself
        answer(10),
        answer(11),
        answer(12),
    ];
    assert_eq!(applied, expected);
    let flags: Vec<u32> = seen.iter().map(|s| s.flags & TIMING_FLAGS).collect();
    let (stall, missed, plan) = (
        mf::INJECTED_STALL,
        mf::PREVIOUS_ACTUATION_MISSED,
        mf::PLAN_APPLIED,
    );
    assert_eq!(
        flags,
        [
            0,
            0,
            0,
            0,
            0,
            stall,
            stall,
            stall | missed | plan,
            stall | missed | plan,
            missed,
            0,
            0,
            0,
            0
        ]
    );
    assert!(seen.iter().all(|s| s.flags & mf::LOCKSTEP != 0));
    assert_eq!(seen[0].u_applied, 0.0, "the safe input before the run");
    assert_eq!(report.samples, 14);
    assert_eq!(report.actuations_applied, 11);
    assert_eq!(report.misses, 3);
    assert_eq!(report.plan_entries_applied, 2);
    assert_eq!(report.misses_held_or_safe, 1);
    assert_eq!(report.stalls_injected, 4);
    assert_eq!(report.stall_acks, 4);
    assert_eq!(report.late_discarded, 0);
    assert_eq!(report.invalid_discarded, 0);
    assert_eq!(report.timing.as_deref(), Some("send-ahead"));
    assert_eq!(report.applies, "lockstep");
    assert_eq!((report.clock_slips, report.slipped_s), (0, 0.0));
}

#[test]
fn lockstep_with_a_compute_first_service_misses_each_stalled_sample_to_the_late_policy() {
    let proxy = format!(
        "{LOCKSTEP}\nlate-policy = \"safe\"\nsafe-input = [-1.0]\n[proxy.faults]\nstalls = [{{ at = 3, periods = 2 }}]"
    );
    let (report, seen) = run("compute-stall", &proxy, 8, Timing::ComputeFirst, 0);
    let report = report.expect("the run ends at its last sample");
    let seen = seen.expect("the fake service ends");
    let applied: Vec<f64> = seen.iter().map(|s| s.u_applied).collect();
    assert_eq!(
        applied,
        [
            -1.0,
            answer(0),
            answer(1),
            answer(2),
            -1.0,
            -1.0,
            answer(5),
            answer(6)
        ]
    );
    let flags: Vec<u32> = seen.iter().map(|s| s.flags & TIMING_FLAGS).collect();
    let (stall, missed) = (mf::INJECTED_STALL, mf::PREVIOUS_ACTUATION_MISSED);
    assert_eq!(flags, [0, 0, 0, stall, stall | missed, missed, 0, 0]);
    assert_eq!(report.misses, 2);
    assert_eq!(report.misses_held_or_safe, 2);
    assert_eq!(report.plan_entries_applied, 0);
    assert_eq!(report.stalls_injected, 2);
    assert_eq!(report.timing.as_deref(), Some("compute-first"));
}

#[test]
fn lockstep_runs_are_repeatable_bit_for_bit() {
    let proxy = format!(
        "{LOCKSTEP}\nlate-policy = \"plan\"\n[proxy.faults]\nstalls = [{{ at = 2, periods = 3 }}]"
    );
    let a = run("repeat-a", &proxy, 10, Timing::SendAhead, 1).1.unwrap();
    let b = run("repeat-b", &proxy, 10, Timing::SendAhead, 1).1.unwrap();
    assert_eq!(a, b);
}

/// Real time at 100 Hz with the input latched at the sample instant (deadline 0).
const AT_SAMPLE: &str = "[proxy]\nmode = \"real-time\"\ndeadline = 0.0\nfifo-priority = 0\nmlockall = false\npeer-timeout = 20.0\nwatchdog-periods = 1000";

#[test]
fn a_plant_latched_at_the_sample_applies_inputs_sent_ahead_and_misses_only_the_first() {
    let text = AT_SAMPLE.replace("[proxy]", "[proxy]\nlate-policy = \"plan\"");
    let rig = rig("at-sample");
    let mut full = first_order_with(&rig, &text);
    full = full.replacen("sample-period = 0.001", "sample-period = 0.01", 1);
    let scenario = plant_proxy::scenario::parse(&full, "test.toml").unwrap();
    let proxy = ProxyConfig::parse(&full, "test.toml", 1).unwrap();
    let service = {
        // The fake service's period must be the plant's.
        let rig = rig.clone();
        std::thread::spawn(move || {
            let counts = ipc_types::ChannelCounts::new(1, 1, 0, 1).unwrap();
            let own =
                ContractInfo::new(Side::Service, counts, 10_000_000).with_timing(Timing::SendAhead);
            let opts = ConnectOptions::new(Duration::from_secs(20)).with_listener(true);
            let ports: ServicePorts =
                ipc_types::ports::connect(&rig, own, "fake-service-rt", opts).expect("connect");
            let mut seen = Vec::new();
            let mut sent_ahead_for = None;
            let start = Instant::now();
            loop {
                assert!(start.elapsed() < Duration::from_secs(60), "{seen:?}");
                let Some(m) = ports.subscriber.receive().unwrap() else {
                    if let Some(l) = &ports.listener {
                        let _ = l.timed_wait(|_| {}, Duration::from_millis(1));
                    }
                    continue;
                };
                let k = m.seq;
                seen.push((k, m.flags, m.u_applied[0], m.deadline_ns));
                for seq in [k, k + 1] {
                    if seq == k && sent_ahead_for == Some(k) {
                        continue;
                    }
                    let mut a = Actuation::zeroed(counts);
                    (a.seq, a.reply_to, a.timing) = (seq, k, Timing::SendAhead.wire());
                    a.u[0] = answer(seq);
                    ports.publisher.send_copy(a).unwrap();
                }
                sent_ahead_for = Some(k + 1);
                let _ = ports.notifier.notify();
                if m.flags & mf::LAST_SAMPLE != 0 {
                    return seen;
                }
            }
        })
    };
    let opts = PlantRunOptions {
        steps: Some(30),
        trace: None,
        verbose: false,
    };
    let report = run_plant(&scenario, &proxy, &opts, &AtomicBool::new(false)).unwrap();
    let seen = service.join().unwrap();
    assert_eq!(report.applies, "at-sample");
    assert!(seen.iter().all(|s| s.3 == 0), "deadline_ns is 0");
    // Sample 0: nothing can have been sent ahead of the first measurement, and A{0} comes
    // after it: a miss (held at the safe input, no plan yet), and A{0} is late.
    assert_eq!(
        seen[1].1 & TIMING_FLAGS,
        mf::PREVIOUS_ACTUATION_MISSED,
        "{seen:?}"
    );
    assert_eq!(seen[1].2, 0.0);
    // Then the input sent ahead is there at each sample instant (10 ms of slack each).
    assert!(report.actuations_applied >= 25, "{report:?}");
    assert_eq!(seen[2].2, answer(1), "{seen:?}");
    assert!(report.late_discarded >= 1, "A{{0}}: {report:?}");
    assert_eq!(report.timing.as_deref(), Some("send-ahead"));
}

#[test]
fn a_plant_latched_at_the_sample_refuses_a_service_that_does_not_send_ahead() {
    let rig = rig("at-sample-refused");
    let text = first_order_with(&rig, AT_SAMPLE);
    let scenario = plant_proxy::scenario::parse(&text, "test.toml").unwrap();
    let proxy = ProxyConfig::parse(&text, "test.toml", 1).unwrap();
    let service = std::thread::spawn(move || {
        let counts = ipc_types::ChannelCounts::new(1, 1, 0, 1).unwrap();
        let own =
            ContractInfo::new(Side::Service, counts, 1_000_000).with_timing(Timing::ComputeFirst);
        let opts = ConnectOptions::new(Duration::from_secs(5));
        ipc_types::ports::connect::<Actuation, Measurement>(&rig, own, "fake-service-cf", opts)
            .map(|_| ())
            .map_err(|e| e.to_string())
    });
    // The service first, so that the plant reads its attributes and refuses it.
    std::thread::sleep(Duration::from_millis(300));
    let opts = PlantRunOptions {
        steps: Some(10),
        trace: None,
        verbose: false,
    };
    let err = run_plant(&scenario, &proxy, &opts, &AtomicBool::new(false))
        .expect_err("refused at connect");
    let msg = err.to_string();
    assert!(
        matches!(err, PlantError::Connect(_)) && msg.contains("only a service that sends ahead"),
        "{msg}"
    );
    assert!(
        service.join().unwrap().is_err(),
        "the service is refused too"
    );
}
