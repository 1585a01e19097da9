//! The real-time path does not allocate. The service's global allocator
//! ([`RtAwareAllocator`]) counts every allocation made on a thread marked real-time:
//!
//! - the controller step, and the loop's own per-sample work (validation, deadline policy,
//!   histograms with interval swaps, the signal-log queue) make none at all;
//! - every push into the record's queue (`record.bin`), kept or dropped, makes none;
//! - the full loop over real iceoryx2 ports makes exactly one per published sample, which
//!   is iceoryx2 0.10's per-loan `Rc` (see `service::rt_alloc`), served from the RT pool,
//!   and none from the system allocator.

use control::StepInput;
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, ServicePorts, Side};
use ipc_types::{Actuation, Measurement, measurement_flags};
use service::config::{ServiceConfig, WaitMode};
use service::record::RecordHeader;
use service::rt_alloc::{RtAllocStats, RtAwareAllocator, enter_rt_thread, thread_stats};
use service::runtime::checkpoint_slot::{CheckpointMark, CheckpointSlot, Offered};
use service::runtime::{LoopCore, Pacer, StopReason, rt_loop};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

#[global_allocator]
static GLOBAL: RtAwareAllocator = RtAwareAllocator;

fn config(rig: &str) -> ServiceConfig {
    config_with(rig, "")
}

/// [`config`] with extra lines at the end of the `[service]` table.
fn config_with(rig: &str, service_extra: &str) -> ServiceConfig {
    parse_config(
        rig,
        "sample-period = 0.001",
        "y = 2, z = 1, u = 2",
        &format!(
            r#"fifo-priority = 0
mlockall = false
wait = "busy-poll"
histogram-interval = 0.25
y-min = -100.0
y-max = 100.0
{service_extra}"#
        ),
        r#"[controller]
kind = "lti"
u-min = -5.0
u-max = 5.0
[controller.ss]
a = [[0.5, 0.1, 0.0], [0.0, 0.4, 0.1], [0.0, 0.0, 0.3]]
b = [[1.0, 0.0], [0.0, 1.0], [0.5, 0.5]]
c = [[0.1, 0.2, 0.3], [0.3, 0.2, 0.1]]
d = [[0.01, 0.0], [0.0, 0.01]]
[log]
queue-capacity = 1024
"#,
    )
}

/// The configuration of a scenario text made of a `[rig]` table named `rig` with the line
/// `rate` (its sample period or rate), a `[service]` table with `channels = { <channels> }`
/// and the lines `service`, then `tables` (the controller's and any others).
fn parse_config(
    rig: &str,
    rate: &str,
    channels: &str,
    service: &str,
    tables: &str,
) -> ServiceConfig {
    let text = format!(
        "\n[rig]\nname = \"{rig}\"\n{rate}\n[service]\nchannels = {{ {channels} }}\n{service}\n{tables}"
    );
    ServiceConfig::parse(&text, rig).unwrap()
}

/// The signal log's layout of the tests' rig (`y = 2, z = 1, u = 2`), every sample logged,
/// with the controller's `internal_names`.
fn log_layout(internal_names: Vec<String>) -> service::logging::LogLayout {
    service::logging::LogLayout {
        n_y: 2,
        n_z: 1,
        n_u: 2,
        internal_names,
        decimation: 1,
    }
}

/// Asserts that this thread is counted by the allocator and allocated nothing since
/// `before`, neither from the RT pool nor from the system allocator; `what` says which run
/// (called only on failure, so that building the message is not counted).
fn assert_nothing_allocated_since(before: &RtAllocStats, what: impl Fn() -> String) {
    let d = thread_stats().since(before);
    assert!(d.installed && d.counted, "{}: {d:?}", what());
    assert_eq!(
        (d.pool_served, d.system_on_rt_thread),
        (0, 0),
        "{}: {d:?}",
        what()
    );
}

#[test]
fn a_controller_step_does_not_allocate() {
    let cfg = config("unit-noalloc-step");
    let mut ctl = cfg.controller.build(cfg.counts).unwrap();
    let mut u = [0.0; 2];
    for k in 0..100 {
        ctl.step(
            &StepInput {
                seq: k,
                y: &[0.1, -0.2],
                z: &[0.0],
                r: &[],
                ..Default::default()
            },
            &mut u,
        );
    }
    enter_rt_thread(16);
    let before = thread_stats();
    for k in 0..100_000u64 {
        let y = [(k as f64 * 0.01).sin(), (k as f64 * 0.02).cos()];
        ctl.step(
            &StepInput {
                seq: k,
                y: &y,
                z: &[0.0],
                r: &[],
                ..Default::default()
            },
            &mut u,
        );
    }
    assert_nothing_allocated_since(&before, String::new);
}

#[test]
fn steady_state_cycles_of_the_rt_loop_do_not_allocate() {
    let rig = format!("unit-noalloc-{}", std::process::id());
    let cfg = config(&rig);
    let counts = cfg.counts;
    let period_ns = cfg.sample_period_ns;
    let folder = std::env::temp_dir().join(format!("noalloc-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();

    // Everything that allocates, built before the RT phase.
    let controller = cfg.controller.build(counts).unwrap();
    let (tele_rt, mut reporter) =
        service::telemetry::channel(cfg.budget_ns, cfg.histogram_interval_cycles, 4, &folder)
            .unwrap();
    let layout = log_layout(controller.internal_names());
    let (producer, writer) = service::logging::channel(cfg.log.queue_capacity, layout);
    let writer = writer.spawn(folder.join("signals.csv")).unwrap();
    let (events_tx, mut events_rx) = rtrb::RingBuffer::new(64);
    let core = LoopCore::new(&cfg, controller, tele_rt, Some(producer), events_tx);
    let header = RecordHeader::for_run(&cfg, "lti", core.timing(), core.plan_length(), None);
    let (recorder, record_writer) = service::record::channel(&header, cfg.log.queue_capacity);
    let record_writer = record_writer
        .spawn(&folder.join(service::record::FILE_NAME))
        .unwrap();
    // The live view's ring, drained by a reader thread, and the operator's rings, fed by
    // it: the loop takes commands at its sample boundaries.
    let (tap, mut live_rx) = service::runtime::live_tap::channel(4096, 8, 80);
    let (mut operator, inbox) = service::runtime::operator::channel();
    let mut core = core
        .with_recorder(recorder)
        .with_live(tap)
        .with_operator(inbox);

    // The plant: a thread that answers in lockstep with a simple first-order response.
    const STEPS: u64 = 30_000;
    const WARM_UP: u64 = 3_000;
    let stop_reporter = Arc::new(AtomicBool::new(false));
    let reporter_thread = {
        let stop = stop_reporter.clone();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Acquire) {
                reporter.poll().unwrap();
                std::thread::sleep(Duration::from_millis(5));
            }
            reporter
        })
    };
    let reader_stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let stop = reader_stop.clone();
        std::thread::spawn(move || {
            use service::runtime::operator::{Command, Queued};
            let (mut samples, mut states, mut results) = (0u64, 0u64, 0u64);
            let commands = [
                Command::EnterSafeState,
                Command::LeaveSafeState,
                Command::FreezeAdaptation,
            ];
            let mut sent = 0;
            while !stop.load(Ordering::Acquire) {
                while let Ok(item) = live_rx.pop() {
                    match item {
                        service::runtime::live_tap::LiveItem::Sample(_) => samples += 1,
                        service::runtime::live_tap::LiveItem::State(_) => states += 1,
                    }
                }
                // One command each time the loop is some thousand samples further.
                if sent < commands.len() && samples > (WARM_UP + 5_000 * (sent as u64 + 1)) {
                    let q = Queued {
                        request_id: sent as u64,
                        command: commands[sent],
                    };
                    operator.commands.push(q).unwrap();
                    sent += 1;
                }
                while operator.results.pop().is_ok() {
                    results += 1;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            (samples, states, results)
        })
    };
    let plant_rig = rig.clone();
    let plant = std::thread::spawn(move || {
        let own = ContractInfo::new(Side::Plant, counts, period_ns);
        let opts = ConnectOptions::new(Duration::from_secs(20));
        let ports: PlantPorts =
            ipc_types::ports::connect(&plant_rig, own, "noalloc-plant", opts).unwrap();
        let mut x = [1.0_f64, -1.0];
        for k in 0..STEPS {
            let mut m = Measurement::zeroed(counts);
            m.seq = k;
            m.t_sample_ns = ipc_types::clock::monotonic_ns();
            m.period_ns = period_ns;
            m.flags = measurement_flags::LOCKSTEP;
            if k + 1 == STEPS {
                m.flags |= measurement_flags::LAST_SAMPLE;
            }
            m.y[..2].copy_from_slice(&x);
            m.z[0] = x[0];
            if k == WARM_UP + 100 {
                m.y[0] = f64::NAN; // a rejected sample in the counted phase
            }
            ports.publisher.send_copy(m).unwrap();
            let start = Instant::now();
            let a: Actuation = loop {
                if let Some(s) = ports.subscriber.receive().unwrap()
                    && s.seq == k
                {
                    break *s;
                }
                assert!(
                    start.elapsed() < Duration::from_secs(10),
                    "no answer to {k}"
                );
                std::hint::spin_loop();
            };
            x = [0.9 * x[0] + 0.05 * a.u[0], 0.8 * x[1] + 0.05 * a.u[1]];
        }
    });

    let own = ContractInfo::new(Side::Service, counts, period_ns);
    let opts = ConnectOptions::new(Duration::from_secs(20));
    let ports: ServicePorts =
        ipc_types::ports::connect(&rig, own, "noalloc-service", opts).unwrap();
    let shutdown = AtomicBool::new(false);

    // Warm-up: first connections, first swaps.
    let r = rt_loop(
        &ports,
        &mut core,
        &shutdown,
        &mut Pacer::new(WaitMode::BusyPoll, period_ns, 0),
        Some(WARM_UP),
        false,
    );
    assert_eq!(r, StopReason::MaxCycles);

    enter_rt_thread(256);
    let published_before = core.stats.published;
    let before = thread_stats();
    let r = rt_loop(
        &ports,
        &mut core,
        &shutdown,
        // The default wait: its sleeps and polls allocate nothing either.
        // With the awake-share cap as a throttled SCHED_FIFO thread has it.
        &mut Pacer::new(WaitMode::SleepPoll, period_ns, 40_000).with_throttling_budget(Some(0.95)),
        None,
        true,
    );
    let d = thread_stats().since(&before);
    let published = core.stats.published - published_before;

    assert_eq!(r, StopReason::PlantEnded);
    plant.join().unwrap();
    assert_eq!(core.stats.received, STEPS);
    assert_eq!(core.stats.rejected_non_finite, 1);
    assert_eq!(core.stats.published, STEPS);
    assert_eq!(
        d.system_on_rt_thread, 0,
        "the RT loop reached the system allocator: {d:?}"
    );
    assert_eq!(
        d.pool_served, published,
        "exactly iceoryx2's one loan state per published sample: {d:?}"
    );
    assert_eq!(d.foreign_frees, 0);

    core.flush_telemetry();
    stop_reporter.store(true, Ordering::Release);
    let reporter = reporter_thread.join().unwrap();
    let summary = reporter.finish().unwrap();
    // Missed swaps (the reporter was slower than the loop) lose no sample.
    assert_eq!(summary.response.count, STEPS - 1, "{summary:?}"); // all but the first sample
    let stats = writer.finish().unwrap();
    assert_eq!(stats.written + stats.dropped, STEPS);
    // One measurement and one actuation per sample went to the record, and the three
    // operator commands.
    let record = record_writer.finish().unwrap();
    assert_eq!(record.entries, 2 * STEPS + 3, "{record:?}");
    assert_eq!(
        record.written + record.dropped,
        record.entries,
        "{record:?}"
    );
    // Every sample went to the live view, or was counted as dropped.
    reader_stop.store(true, Ordering::Release);
    let (samples, states, results) = reader.join().unwrap();
    assert!(states > 0);
    assert_eq!(samples + core.stats.telemetry_dropped.min(samples), samples);
    assert!(samples > WARM_UP, "{samples}");
    // The commands were applied in the counted phase (the LTI controller refuses to
    // freeze: it does not adapt).
    assert_eq!(results, 3);
    assert_eq!(core.stats.commands_applied, 2);
    assert_eq!(core.stats.commands_refused, 1);
    while events_rx.pop().is_ok() {}
    let _ = std::fs::remove_dir_all(&folder);
}

/// An [`Outbox`](service::runtime::Outbox) that keeps the last actuation published, in
/// place.
struct KeepLast(ipc_types::Actuation);

impl service::runtime::Outbox for KeepLast {
    fn publish(&mut self, act: &mut ipc_types::Actuation) -> (bool, u64) {
        act.t_publish_ns = ipc_types::clock::monotonic_ns();
        self.0 = *act;
        (true, ipc_types::clock::monotonic_ns())
    }
}

#[test]
fn the_loops_own_per_sample_work_does_not_allocate_at_all_in_any_timing() {
    // An open-loop phase that ends inside the counted region, and a tone report.
    let extra = "open-loop = 2.0\nreport = { tones-hz = [50.0], window = 0.5 }";
    // The LTI controller has a feedthrough: compute-first. Without it, it answers ahead.
    let runs = [
        (
            ipc_types::Timing::ComputeFirst,
            config_with("unit-noalloc-core", extra),
        ),
        (
            ipc_types::Timing::AnswerFirst,
            ahead_lti(extra, ipc_types::Timing::AnswerFirst, 8),
        ),
        (
            ipc_types::Timing::SendAhead,
            ahead_lti(extra, ipc_types::Timing::SendAhead, 64),
        ),
    ];
    for (timing, cfg) in runs {
        // Each on a thread of its own, marked real-time afresh.
        std::thread::spawn(move || loop_core_run(&cfg, timing))
            .join()
            .unwrap_or_else(|_| panic!("{timing:?}"));
    }
}

/// [`config_with`]'s controller without its feedthrough `D`, answering by `timing` with
/// plans of `plan_length`.
fn ahead_lti(service_extra: &str, timing: ipc_types::Timing, plan_length: usize) -> ServiceConfig {
    let mut cfg = config_with("unit-noalloc-core", service_extra);
    if let service::config::ControllerConfig::Lti { params } = &mut cfg.controller {
        params.d.fill(0.0);
    }
    cfg.answer = service::config::AnswerTiming {
        timing,
        plan_length,
    };
    cfg
}

/// 50,000 cycles of the loop core with `cfg`, counted past the first 1,000: samples lost,
/// received late and rejected on the way.
fn loop_core_run(cfg: &ServiceConfig, timing: ipc_types::Timing) {
    let folder = std::env::temp_dir().join(format!("noalloc-core-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let controller = cfg.controller.build(cfg.counts).unwrap();
    let (tele_rt, mut reporter) =
        service::telemetry::channel(cfg.budget_ns, 100, 2, &folder).unwrap();
    let layout = log_layout(controller.internal_names());
    let (producer, writer) = service::logging::channel(64, layout);
    let (events_tx, _events_rx) = rtrb::RingBuffer::new(64);
    let core = LoopCore::new(cfg, controller, tele_rt, Some(producer), events_tx);
    // The record's queue, never drained: it fills and then drops, allocating nothing.
    let header = RecordHeader::for_run(cfg, "lti", core.timing(), core.plan_length(), None);
    let (recorder, _record_writer) = service::record::channel(&header, 64);
    // The live view's ring, never drained: it fills, then drops and counts.
    let (tap, _live_rx) = service::runtime::live_tap::channel(64, 10, 100);
    let (mut operator, inbox) = service::runtime::operator::channel();
    let mut core = core
        .with_recorder(recorder)
        .with_live(tap)
        .with_operator(inbox);
    assert_eq!(core.timing(), timing);
    let mut m = Measurement::zeroed(cfg.counts);
    let mut out = KeepLast(Actuation::zeroed(cfg.counts));
    let mut cycle = |core: &mut LoopCore, k: u64| {
        if k % 500 == 250 {
            // A sample lost on the way: a gap in the sequence.
            return;
        }
        m.seq = k;
        m.t_sample_ns = ipc_types::clock::monotonic_ns();
        m.period_ns = 1_000_000;
        m.y[0] = (k as f64 * 0.1).sin();
        m.y[1] = if k % 1000 == 7 { f64::INFINITY } else { 0.5 };
        m.z[0] = (2.0 * std::f64::consts::PI * 50.0 * k as f64 * 1e-3).sin();
        m.flags = measurement_flags::U_APPLIED;
        if k % 700 == 3 {
            m.flags |=
                measurement_flags::PREVIOUS_ACTUATION_MISSED | measurement_flags::PLAN_APPLIED;
        }
        m.u_applied[..2].copy_from_slice(&out.0.u[..2]);
        let t_recv = ipc_types::clock::monotonic_ns();
        core.take_commands();
        if k % 100 == 30 {
            // Received too late: a newer sample was waiting.
            core.observe(&m, &mut out);
            return;
        }
        core.handle(&m, t_recv, &mut out);
    };
    for k in 0..1000 {
        cycle(&mut core, k);
        reporter.poll().unwrap();
    }
    enter_rt_thread(16);
    let before = thread_stats();
    // The reporter is not polled now: the RT side runs out of spare boxes and keeps
    // recording (missed swaps), and the log queue fills and drops; neither may allocate.
    // Operator commands of every kind arrive meanwhile.
    use service::runtime::operator::{Command, Queued};
    let commands = [
        (10_000, Command::EnterSafeState),
        (10_100, Command::LeaveSafeState),
        (20_000, Command::FreezeAdaptation),
        (30_000, Command::ResumeAdaptation),
        (
            40_000,
            Command::SetTunable {
                index: 0,
                value: 0.5,
            },
        ),
    ];
    for k in 1000..50_000 {
        if let Some((_, command)) = commands.iter().find(|(at, _)| *at == k) {
            let q = Queued {
                request_id: k,
                command: *command,
            };
            operator.commands.push(q).unwrap();
        }
        cycle(&mut core, k);
    }
    assert_nothing_allocated_since(&before, || format!("{timing:?}"));
    assert_eq!(
        core.stats.commands_applied + core.stats.commands_refused,
        5,
        "{timing:?}"
    );
    assert!(core.stats.telemetry_dropped > 0, "{timing:?}");
    while operator.results.pop().is_ok() {}
    assert_eq!(core.stats.rejected_non_finite, 50, "{timing:?}");
    assert!(core.stats.controller_steps > 45_000, "{timing:?}");
    assert_eq!(core.stats.caught_up, 500, "{timing:?}");
    assert_eq!(core.stats.skipped, 100, "{timing:?}");
    // The tone report saw both windows (the tone is the same in both: 0 dB).
    let r = core.tones.report().unwrap();
    assert!(r.error.is_none(), "{:?}", r.error);
    assert!(r.samples[0] > 400 && r.samples[1] > 400, "{:?}", r.samples);
    assert!(r.tones[0].suppression_db.unwrap().abs() < 1e-6);
    drop(writer);
    let _ = std::fs::remove_dir_all(&folder);
}

#[test]
fn every_kind_of_record_entry_is_pushed_and_dropped_without_allocating() {
    let cfg = ahead_lti("", ipc_types::Timing::SendAhead, 64);
    let header = RecordHeader::for_run(&cfg, "lti", ipc_types::Timing::SendAhead, 64, None);
    // A queue of 4 samples, never drained: it fills, then every push is dropped.
    let (mut recorder, _writer) = service::record::channel(&header, 4);
    let mut m = Measurement::zeroed(cfg.counts);
    let mut a = Actuation::zeroed(cfg.counts);
    a.plan_len = 64;
    enter_rt_thread(16);
    let before = thread_stats();
    for k in 0..10_000u64 {
        m.seq = k;
        m.y[0] = k as f64;
        a.seq = k + 1;
        recorder.handle(&m, k);
        recorder.observe(&m);
        recorder.publish(&a, true, k);
        recorder.new_peer();
        recorder.went_silent(k);
    }
    assert_nothing_allocated_since(&before, String::new);
    assert_eq!(recorder.offered(), 50_000);
    assert!(recorder.dropped() > 49_000, "{}", recorder.dropped());
}

#[test]
fn an_rls_update_with_each_forgetting_rule_does_not_allocate() {
    use control::forgetting::ForgettingRule;
    use control::rls::{Rls, RlsConfig};
    enter_rt_thread(16);
    for (n, p) in [(5, 1), (35, 5), (60, 3)] {
        for rule in [
            ForgettingRule::Constant { lambda: 0.99 },
            ForgettingRule::FTest {
                tau_n: 10,
                tau_d: 80,
                eta: 1.0,
                alpha: 0.001,
            },
            ForgettingRule::RmsRatio {
                tau_n: 10,
                tau_d: 80,
                eta: 1.0,
            },
        ] {
            let cfg = RlsConfig {
                n,
                p,
                theta0: vec![0.0; n],
                p0: 100.0,
                rule,
                trace_limit: 1e12,
            };
            // Built outside the counted region.
            let mut rls = service::rt_alloc::outside_rt(|| Rls::new(&cfg).unwrap());
            let phi: Vec<f64> = (0..n * p)
                .map(|i| ((i * 7 + 3) % 11) as f64 / 11.0 - 0.5)
                .collect();
            let mut y = vec![0.0; p];
            let before = thread_stats();
            for k in 0..2_000 {
                for (i, v) in y.iter_mut().enumerate() {
                    // A parameter change at k = 1000 so that forgetting engages.
                    *v = if k < 1000 { 1.0 } else { -2.0 } * (i as f64 + 1.0)
                        + ((k * 13 % 7) as f64) * 0.01;
                }
                rls.update(&phi, &y);
            }
            assert_nothing_allocated_since(&before, || format!("({n}, {p}) {cfg:?}"));
        }
    }
}

/// An RCAC scenario of the acoustic rig's shape (`l_u = 2`, `l_y = l_z = 1`, 8 kHz) with a
/// dereverberated target model with delays 9 and 16 (the fixture
/// `rcac-acoustic-shape-controller.toml`); `update` holds the update-law keys.
fn rcac_config(update: &str) -> ServiceConfig {
    let controller = include_str!("../../tests/fixtures/rcac-acoustic-shape-controller.toml")
        .replacen(
            "\n[controller.target-model]\n",
            &format!("\n{update}\n[controller.target-model]\n"),
            1,
        );
    parse_config(
        "unit-noalloc-rcac",
        "sample-rate-hz = 8000",
        "y = 1, z = 1, u = 2",
        "",
        &controller,
    )
}

/// Steady-state RCAC steps (l_θ = 300) under the counting allocator: past `k_w`, with
/// saturation, a non-finite sample, the applied-input correction, bridged gaps, observed
/// samples, checkpoint copies ([`CheckpointSlot::offer`]), a data restart and, for RLS,
/// the R_u rows and a windowed forgetting rule.
fn rcac_steps_do_not_allocate(update: &str) {
    // Built outside the counted region (the gradient test runs several on one thread).
    let mut ctl = service::rt_alloc::outside_rt(|| {
        let cfg = rcac_config(update);
        cfg.controller.build(cfg.counts).unwrap()
    });
    assert_eq!(ctl.kind(), "rcac");
    let mut u = [0.0; 2];
    let mut internals = [0.0; control::MAX_INTERNALS];
    let signal = |k: u64, u: &[f64; 2]| {
        let t = k as f64 / 8000.0;
        (2.0 * std::f64::consts::PI * 800.0 * t).sin() + 0.1 * u[0] - 0.05 * u[1]
    };
    for k in 0..300 {
        let z = signal(k, &u);
        ctl.step(
            &StepInput {
                seq: k,
                y: &[z],
                z: &[z],
                r: &[],
                ..Default::default()
            },
            &mut u,
        );
    }
    let slot = service::rt_alloc::outside_rt(|| CheckpointSlot::new(&*ctl));
    assert!(!slot.is_empty());
    enter_rt_thread(16);
    let before = thread_stats();
    let mut scratch = [0.0; 2];
    let mut offered = 0;
    for k in 300..5_300u64 {
        // A checkpoint copied every 1000 samples (the writer takes them off the RT
        // thread), and a new data stream (a new plant session) once.
        if k % 1000 == 0 {
            let mark = CheckpointMark {
                seq: k,
                plant_session: 1,
            };
            offered += u64::from(slot.offer(&*ctl, mark) == Offered::Copied);
            let taken = service::rt_alloc::outside_rt(|| slot.take().map(|(m, _)| m.seq));
            assert_eq!(taken, Some(k));
        }
        if k == 3000 {
            ctl.restart_data();
        }
        let z = if k == 1000 { f64::NAN } else { signal(k, &u) };
        // The imperfect-loop paths too: the applied input reported, samples lost (a gap
        // bridged) and samples only observed.
        let prev = u;
        let input = StepInput {
            seq: k,
            y: &[z],
            z: &[z],
            r: &[],
            u_applied: Some(&prev),
            lost: if k % 997 == 0 { 3 } else { 0 },
        };
        if k % 101 == 0 {
            ctl.observe(&input, &mut scratch);
        } else {
            ctl.step(&input, &mut u);
        }
        ctl.internals(&mut internals);
        assert!(u.iter().all(|v| v.is_finite()));
    }
    assert_nothing_allocated_since(&before, || update.to_string());
    assert_eq!(offered, 5, "{update}");
}

#[test]
fn an_rcac_step_with_the_rls_update_does_not_allocate() {
    rcac_steps_do_not_allocate(
        "update = \"rls\"\np0 = 1.0\nru = 0.01\n[controller.forgetting]\nrule = \"f-test\"\ntau-n = 10\ntau-d = 100\neta = 0.5\nalpha = 0.001",
    );
}

#[test]
fn an_rcac_step_with_the_gradient_update_does_not_allocate() {
    for step in ["opt", "sigma", "frobenius", "exp"] {
        rcac_steps_do_not_allocate(&format!(
            "update = \"gradient\"\nstep-size = \"{step}\"\nalpha = 0.5\nr = 0.001\nru = [[0.01, 0.0], [0.0, 0.02]]"
        ));
    }
}

/// A PCAC controller at the truss size of chapter 6 (`n̂ = 25`, `p = 4`, `m = 2`, 600
/// coefficients, `ℓ = 40`) read from a scenario text, with move bounds and, when
/// `infeasible`, an output constraint `y_4 ≤ −100` no prediction can meet; re-planning
/// every `replan` samples (next-step timing) when `replan > 1`, with the QP cut into
/// shares of 2 active-set changes per period when `replan ≥ 4`, and the Hessian built in
/// every third cycle only (cycles of `replan + 3` samples) when `kept`.
fn truss_size_pcac(infeasible: bool, replan: usize) -> Box<dyn control::Controller> {
    truss_size_pcac_with(infeasible, replan, false)
}

/// [`truss_size_pcac`], keeping the Hessian between builds when `kept`.
fn truss_size_pcac_with(
    infeasible: bool,
    replan: usize,
    kept: bool,
) -> Box<dyn control::Controller> {
    let timing = if kept {
        format!(
            "timing = \"next-step\"\nreplan-every = {replan}\nqp-changes-per-period = 2\n\
             hessian-every = 3\nhessian-cycle = {}\nfast-path = \"never\"\n",
            replan + 3
        )
    } else if replan >= 4 {
        format!("timing = \"next-step\"\nreplan-every = {replan}\nqp-changes-per-period = 2\n")
    } else if replan > 1 {
        format!("timing = \"next-step\"\nreplan-every = {replan}\n")
    } else {
        String::new()
    };
    let constraints = if infeasible {
        "[controller.output-constraints]\nc = [[0.0, 0.0, 0.0, 1.0]]\nd = [100.0]\n"
    } else {
        ""
    };
    let cfg = parse_config(
        "pcac-no-alloc",
        "sample-period = 0.02",
        "y = 4, z = 4, u = 2",
        "fifo-priority = 0\nmlockall = false",
        &format!(
            r#"[controller]
kind = "pcac"
n-hat = 25
p0 = 1.0
theta0 = 1e-10
horizon = 40
tracking = [[0.0, 0.0, 0.0, 1.0]]
q = 1e6
r = 1.0
u-min = -10.0
u-max = 10.0
du-min = -2.0
du-max = 2.0
{timing}[controller.forgetting]
rule = "f-test"
tau-n = 40
tau-d = 200
eta = 0.1
alpha = 0.001
{constraints}"#
        ),
    );
    cfg.controller.build(cfg.counts).unwrap()
}

/// The whole PCAC step at the truss size: identification (shared-covariance RLS with
/// F-test forgetting), realization, condensing with input and move bounds, the
/// warm-started QP and the first move; with caught-up samples (`observe`), lost samples
/// (bridging), held inputs (`u_applied`), internals for the log, a reset, and a controller
/// whose every QP is infeasible (fallback). Built outside the counted region; 800 steps
/// inside it make no allocation.
#[test]
fn the_pcac_step_does_not_allocate() {
    pcac_steps_make_no_allocation(1);
}

/// [`the_pcac_step_does_not_allocate`] re-planning every 3 samples: the solve's units spread
/// over the periods, the plan followed between, cycles dropped by observations and lost
/// samples.
#[test]
fn the_pcac_step_re_planning_every_3_does_not_allocate() {
    pcac_steps_make_no_allocation(3);
}

/// The truss-size step allocates nothing re-planning every 5 samples with the QP cut
/// into shares of 2 active-set changes over the periods 3 to 5.
#[test]
fn the_pcac_step_re_planning_every_5_with_the_qp_in_shares_does_not_allocate() {
    pcac_steps_make_no_allocation(5);
}

/// The truss-size step allocates nothing re-planning every 4 samples and building the
/// Hessian in every third cycle only: the kept cycles start the QP from the kept
/// factorization.
#[test]
fn the_pcac_step_keeping_the_hessian_does_not_allocate() {
    pcac_steps_make_no_allocation_with(4, true);
}

/// The body of the PCAC allocation tests, re-planning every `replan` samples.
fn pcac_steps_make_no_allocation(replan: usize) {
    pcac_steps_make_no_allocation_with(replan, false);
}

/// [`pcac_steps_make_no_allocation`], keeping the Hessian between builds when `kept`.
fn pcac_steps_make_no_allocation_with(replan: usize, kept: bool) {
    use control::status;
    let (mut ctl, mut stuck) = service::rt_alloc::outside_rt(|| {
        (
            truss_size_pcac_with(false, replan, kept),
            truss_size_pcac_with(true, replan, kept),
        )
    });
    // A lightly damped 2-input, 4-output plant (one mode per output) with a disturbance,
    // so that the model has something to identify and the inputs reach their bounds.
    let mut x = [[0.0f64; 2]; 4];
    let (mut y, mut u, mut applied) = ([0.0; 4], [0.0; 2], [0.0; 2]);
    let mut internals = [0.0; control::MAX_INTERNALS];
    let (mut solved, mut fallbacks) = (0, 0);
    let mut run = |ctl: &mut Box<dyn control::Controller>,
                   k: usize,
                   solved: &mut usize,
                   fallbacks: &mut usize| {
        let w = (0.3 * k as f64).sin() + 0.5 * (1.1 * k as f64).sin();
        for (o, (xo, yo)) in x.iter_mut().zip(y.iter_mut()).enumerate() {
            let a = 1.9 - 0.05 * o as f64;
            let next = a * xo[0] - 0.95 * xo[1] + 0.1 * applied[o % 2] + 0.05 * w;
            *xo = [next, xo[0]];
            *yo = next;
        }
        let input = StepInput {
            seq: k as u64,
            y: &y,
            z: &y,
            r: &[],
            u_applied: Some(&applied),
            // Two samples lost now and then: bridged, identification paused.
            lost: if k.is_multiple_of(97) { 2 } else { 0 },
        };
        if k % 50 == 7 {
            // Caught up: taken in, not answered; the plant holds its input.
            ctl.observe(&input, &mut u);
        } else {
            let s = ctl.step(&input, &mut u);
            if s & status::FALLBACK != 0 {
                *fallbacks += 1;
            } else {
                *solved += 1;
            }
            // Every 9th answer is late: the plant holds the previous input.
            if !k.is_multiple_of(9) {
                applied = u;
            }
        }
        ctl.internals(&mut internals);
    };
    for k in 0..200 {
        run(&mut ctl, k, &mut solved, &mut fallbacks);
    }
    enter_rt_thread(16);
    let before = thread_stats();
    for k in 200..800 {
        run(&mut ctl, k, &mut solved, &mut fallbacks);
    }
    ctl.reset();
    for k in 800..900 {
        run(&mut ctl, k, &mut solved, &mut fallbacks);
    }
    let (solved_before, fallbacks_before) = (solved, fallbacks);
    for k in 0..100 {
        run(&mut stuck, k, &mut solved, &mut fallbacks);
    }
    assert_nothing_allocated_since(&before, String::new);
    assert!(solved_before > 700, "only {solved_before} QPs solved");
    assert!(fallbacks_before < 20, "{fallbacks_before} fallbacks");
    // The infeasible controller fell back at every answered step — re-planning, at every
    // answered step that had a plan: not the N − 1 answers after its start and after each
    // of its 2 observations, which hold the input until the first plan takes over.
    // (With the Hessian kept, the first cycle after each of them builds it: `N + 3` long.)
    let first_cycle = if kept { replan + 3 } else { replan };
    let unplanned = 3 * (first_cycle - 1);
    assert_eq!(solved - solved_before, unplanned);
    let kept_factors = ctl
        .counters()
        .iter()
        .find(|(name, _)| *name == "factorizations kept")
        .map_or(0, |(_, n)| *n);
    assert_eq!(kept_factors > 0, kept, "{kept_factors} factorizations kept");
    assert_eq!(fallbacks - fallbacks_before, 98 - unplanned);
    assert!(
        u.iter()
            .chain(&applied)
            .all(|v| v.is_finite() && v.abs() <= 10.0)
    );
}

/// A PCAC controller at the sampling arm's size of chapter 7 (`n̂ = 1`, `p = 5`, `m = 2`,
/// `ℓ = 50`), where the default `fast-path = "auto"` takes the unconstrained fast path
/// (the Riccati minimizer, checked against the bounds), read from a scenario text with
/// input bounds, move bounds and an output constraint that the plans meet at most steps
/// and not at all; re-planning every `replan` samples (next-step timing) when
/// `replan > 1`.
fn arm_size_pcac(replan: usize) -> Box<dyn control::Controller> {
    let timing = if replan > 1 {
        format!("timing = \"next-step\"\nreplan-every = {replan}\n")
    } else {
        String::new()
    };
    let cfg = parse_config(
        "pcac-fast-no-alloc",
        "sample-period = 0.0005",
        "y = 5, z = 5, u = 2",
        "fifo-priority = 0\nmlockall = false",
        &(r#"[controller]
kind = "pcac"
n-hat = 1
p0 = 10.0
theta0 = 0.01
horizon = 50
tracking = [[0.0, 0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 0.0, 1.0]]
q = [1000.0, 100.0, 1.0]
r = 1.0
u-min = -1.0
u-max = 1.0
du-min = -0.2
du-max = 0.2
"#
        .to_string()
            + &timing
            + r#"[controller.forgetting]
rule = "f-test"
tau-n = 40
tau-d = 200
eta = 0.1
alpha = 0.001
[controller.output-constraints]
c = [[1.0, 0.0, 0.0, 0.0, 0.0]]
d = [-2.0]
"#),
    );
    cfg.controller.build(cfg.counts).unwrap()
}

/// The PCAC step through the unconstrained fast path: at the arm's size, steps whose
/// Riccati minimizer meets the input, move and output bounds skip condensing and the QP,
/// the others (a disturbance that pushes the inputs to their bounds now and then) fall
/// back to them; with caught-up samples, lost samples, internals and a reset. Built
/// outside the counted region; 900 steps inside it make no allocation, and both paths ran.
#[test]
fn the_pcac_fast_path_step_does_not_allocate() {
    pcac_fast_path_steps_make_no_allocation(1);
}

/// [`the_pcac_fast_path_step_does_not_allocate`] re-planning every 3 samples: the fast
/// path runs in the condensing unit's period, on the realization the prediction kept.
#[test]
fn the_pcac_fast_path_step_re_planning_every_3_does_not_allocate() {
    pcac_fast_path_steps_make_no_allocation(3);
}

/// The body of the fast-path allocation tests, re-planning every `replan` samples.
fn pcac_fast_path_steps_make_no_allocation(replan: usize) {
    let mut ctl = service::rt_alloc::outside_rt(|| arm_size_pcac(replan));
    let counter = |ctl: &dyn control::Controller, name: &str| {
        ctl.counters()
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, v)| *v)
            .unwrap()
    };
    // Five first-order outputs driven by the two inputs and a disturbance that comes and
    // goes (its bursts saturate the inputs).
    let mut y = [0.0f64; 5];
    let (mut u, mut applied) = ([0.0; 2], [0.0; 2]);
    let mut internals = [0.0; control::MAX_INTERNALS];
    let mut run = |ctl: &mut Box<dyn control::Controller>, k: usize| {
        let burst = if (k / 60) % 3 == 2 { 3.0 } else { 0.1 };
        let w = burst * (0.2 * k as f64).sin();
        for (o, yo) in y.iter_mut().enumerate() {
            let a = 0.9 - 0.05 * o as f64;
            *yo = a * *yo + 0.2 * applied[o % 2] + 0.1 * w;
        }
        let input = StepInput {
            seq: k as u64,
            y: &y,
            z: &y,
            r: &[],
            u_applied: Some(&applied),
            lost: if k % 131 == 5 { 1 } else { 0 },
        };
        if k % 50 == 7 {
            ctl.observe(&input, &mut u);
        } else {
            ctl.step(&input, &mut u);
            applied = u;
        }
        ctl.internals(&mut internals);
    };
    for k in 0..200 {
        run(&mut ctl, k);
    }
    let (fast0, solved0) = (
        counter(ctl.as_ref(), "fast path"),
        counter(ctl.as_ref(), "qp solved"),
    );
    enter_rt_thread(16);
    let before = thread_stats();
    for k in 200..1000 {
        run(&mut ctl, k);
    }
    ctl.reset();
    for k in 1000..1100 {
        run(&mut ctl, k);
    }
    assert_nothing_allocated_since(&before, String::new);
    let (fast, solved) = (
        counter(ctl.as_ref(), "fast path") - fast0,
        counter(ctl.as_ref(), "qp solved") - solved0,
    );
    // Both paths ran (172 and 710 of 882 solves at N = 1, 26 and 256 of 282 at N = 3).
    assert!(fast >= 10, "the fast path solved {fast} of {solved}");
    assert!(
        solved - fast >= 10,
        "only {} of {solved} solves fell back to the QP",
        solved - fast
    );
    // No print here: libtest's captured output would be a block of this thread's RT pool
    // freed by the harness's thread, a foreign free that the RT loop's test, running
    // alongside, counts (the counter is process-wide).
    assert!(u.iter().all(|v| v.is_finite() && v.abs() <= 1.0));
}

/// As in the service: the controller is built on one thread and stepped on another (the RT
/// thread) from its very first step, after `prepare_thread` there. (Without it the QP's
/// first Cholesky factorization on the new thread allocates the matrix-multiply kernels'
/// per-thread packing buffer once: the service's report showed that single allocation.)
#[test]
fn the_first_pcac_steps_on_a_new_thread_do_not_allocate() {
    let mut ctl = service::rt_alloc::outside_rt(|| truss_size_pcac(false, 1));
    std::thread::spawn(move || {
        ctl.prepare_thread();
        enter_rt_thread(16);
        let before = thread_stats();
        let mut u = [0.0; 2];
        for k in 0..50 {
            let y = [
                1e-3 * (k as f64).sin(),
                0.0,
                2e-3,
                -1e-3 * (0.3 * k as f64).cos(),
            ];
            ctl.step(
                &StepInput {
                    seq: k,
                    y: &y,
                    z: &y,
                    ..Default::default()
                },
                &mut u,
            );
        }
        assert_nothing_allocated_since(&before, String::new);
    })
    .join()
    .unwrap();
}

/// The dense QP's warm starts with fixed bounds, right and wrong (bounds freed at the start
/// and inside dual steps, rows held from the start, bounds fixed in bulk from a cold start,
/// an infeasible problem) make no allocation. A 40-variable problem with input and move
/// bounds whose unconstrained minimizer leaves the box.
#[test]
fn qp_solves_with_fixed_and_freed_bounds_do_not_allocate() {
    use control::mpc::qp::{
        ConstraintId, DenseQpSolver, QpProblem, QpSettings, QpStatus, WarmStart,
    };
    let n = 40;
    // H: tridiagonal (a discrete second difference plus a diagonal), G: moves u_i − u_{i−1}
    // of both signs within 0.3.
    let mut hess = vec![0.0; n * n];
    for i in 0..n {
        hess[i * n + i] = 2.5;
        if i > 0 {
            hess[i * n + i - 1] = -1.0;
            hess[(i - 1) * n + i] = -1.0;
        }
    }
    let mut g = vec![0.0; 2 * (n - 1) * n];
    for i in 1..n {
        let (r0, r1) = ((i - 1) * n, (n - 1 + i - 1) * n);
        g[r0 + i] = 1.0;
        g[r0 + i - 1] = -1.0;
        g[r1 + i] = -1.0;
        g[r1 + i - 1] = 1.0;
    }
    let h = vec![0.3; 2 * (n - 1)];
    let (lb, ub) = (vec![-1.0; n], vec![1.0; n]);
    let fs: Vec<Vec<f64>> = (0..6)
        .map(|k| {
            (0..n)
                .map(|i| -4.0 * ((0.2 + 0.05 * k as f64) * i as f64).sin())
                .collect()
        })
        .collect();
    let all_upper: Vec<ConstraintId> = (0..n).map(ConstraintId::Upper).collect();
    let mut ids = vec![ConstraintId::Row(0); 3 * n];
    let mut solver =
        service::rt_alloc::outside_rt(|| DenseQpSolver::new(n, 2 * (n - 1), QpSettings::default()));
    let h_bad = vec![-1.0; 2 * (n - 1)];
    enter_rt_thread(16);
    let before = thread_stats();
    let (mut solved, mut fixed, mut freed, mut infeasible) = (0, 0, 0, 0);
    let mut k_ids = 0;
    for round in 0..30 {
        let f = &fs[round % fs.len()];
        let p = QpProblem {
            hess: &hess,
            f,
            lb: &lb,
            ub: &ub,
            g: &g,
            h: &h,
        };
        for warm in [
            WarmStart::Cold,
            WarmStart::ActiveSet(&ids[..k_ids]),
            WarmStart::ActiveSet(&all_upper),
        ] {
            if solver.solve(&p, warm) == QpStatus::Solved {
                solved += 1;
            }
            fixed += solver.fixed_at_start();
            freed += solver.freed_bounds();
        }
        k_ids = solver.active_set_into(&mut ids);
        let bad = QpProblem { h: &h_bad, ..p };
        if solver.solve(&bad, WarmStart::ActiveSet(&all_upper)) == QpStatus::Infeasible {
            infeasible += 1;
        }
    }
    assert_nothing_allocated_since(&before, String::new);
    assert_eq!((solved, infeasible), (90, 30));
    assert!(fixed > 1000 && freed > 100, "{fixed} fixed, {freed} freed");
}

/// A PCAC controller with the internal model of known tones (`[controller.internal-model]`:
/// `D(q)`-filtered identification, the product-model prediction, the tone-notch and
/// level input cost in condensing), at a reduced acoustic size (`n̂ = 12`, `p = 1`,
/// `m = 2`, three tones, `ℓ = 24`), next-step timing, re-planning every `replan` samples.
fn internal_model_pcac(replan: usize) -> Box<dyn control::Controller> {
    let cfg = parse_config(
        "pcac-internal-model-no-alloc",
        "sample-period = 1.25e-4",
        "y = 1, z = 1, u = 2",
        "fifo-priority = 0\nmlockall = false",
        &format!(
            r#"[controller]
kind = "pcac"
n-hat = 12
p0 = 0.01
theta0 = 0.01
horizon = 24
q = 10.0
u-min = -5.0
u-max = 5.0
du-min = -4.0
du-max = 4.0
timing = "next-step"
replan-every = {replan}
[controller.internal-model]
tones-hz = [800.0, 1300.0, 3000.0]
notch-radius = 0.97
r-level = [100.0, 0.0]
"#
        ),
    );
    cfg.controller.build(cfg.counts).unwrap()
}

/// The PCAC step with the internal model of known tones, solving at every sample and
/// re-planning every 3: steps with lost samples (bridged), caught-up samples, held inputs,
/// internals and a reset make no allocation once built.
#[test]
fn the_pcac_step_with_the_internal_model_does_not_allocate() {
    for replan in [1, 3] {
        let mut ctl = service::rt_alloc::outside_rt(|| internal_model_pcac(replan));
        let mut x = [0.0f64; 2];
        let (mut y, mut u, mut applied) = ([0.0; 1], [0.0; 2], [0.0; 2]);
        let mut internals = [0.0; control::MAX_INTERNALS];
        let mut answered = 0;
        let mut run = |ctl: &mut Box<dyn control::Controller>, k: usize, answered: &mut usize| {
            let t = k as f64;
            let w = (0.63 * t).sin() + 0.5 * (2.36 * t).sin();
            let next = 1.6 * x[0] - 0.8 * x[1] + 0.1 * applied[0] + 0.2 * applied[1] + 0.05 * w;
            x = [next, x[0]];
            y[0] = next;
            let input = StepInput {
                seq: k as u64,
                y: &y,
                z: &y,
                r: &[],
                u_applied: Some(&applied),
                lost: if k.is_multiple_of(97) { 2 } else { 0 },
            };
            if k % 50 == 7 {
                ctl.observe(&input, &mut u);
            } else {
                ctl.step(&input, &mut u);
                *answered += 1;
                if !k.is_multiple_of(9) {
                    applied = u;
                }
            }
            ctl.internals(&mut internals);
        };
        for k in 0..200 {
            run(&mut ctl, k, &mut answered);
        }
        enter_rt_thread(16);
        let before = thread_stats();
        for k in 200..600 {
            run(&mut ctl, k, &mut answered);
        }
        ctl.reset();
        for k in 600..700 {
            run(&mut ctl, k, &mut answered);
        }
        assert_nothing_allocated_since(&before, || format!("replan-every = {replan}"));
        assert!(answered > 600);
        assert!(
            u.iter()
                .chain(&applied)
                .all(|v| v.is_finite() && v.abs() <= 5.0)
        );
    }
}
