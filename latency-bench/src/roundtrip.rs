//! Contract round trip against raw iceoryx2 ping-pong, between two processes.
//!
//! ## Method
//!
//! The parent thread (pinned on the plant core, `SCHED_FIFO`, busy-polling) sends sample
//! `k`, then spins on its subscriber until the answer carrying `k` arrives:
//!
//! ```text
//!  t0 = monotonic_ns()  →  send sample k  →  spin: receive() … answer k  →  t1 = monotonic_ns()
//!  RTT_k = t1 − t0      (recorded for k ≥ warm-up)
//!  next sample no earlier than t1 + gap   (a busy-wait: no sleep, no wake-up in the path)
//! ```
//!
//! Both variants run this same code ([`time_round_trips`]); only the closures that send a
//! sample and poll for the answer differ:
//!
//! - **contract** ([`contract_round_trips`]): the parent is the plant of the contract
//!   (`ipc_types::ports::connect::<Measurement, Actuation>`, [`Side::Plant`]) and sends
//!   [`Measurement`]s with `LOCKSTEP` set and no deadline (`deadline_ns = 0`, so the service
//!   counts no miss), the last one with `LAST_SAMPLE` so that the service exits. The child
//!   is the real service in busy-poll mode: validation, controller step, telemetry,
//!   publication of the [`Actuation`] — everything a deployed loop does per sample. The
//!   plant does not notify the `measurement` event: a busy-polling service does not listen
//!   to it (in blocking mode a plant must, see `crate::paced`).
//! - **raw** ([`raw_round_trips`]): the child is a minimal iceoryx2 echo
//!   ([`run_echo_child`]) on services of its own, with payloads of exactly the sizes of
//!   [`Measurement`] and [`Actuation`] ([`RawPing`], [`RawPong`]) and the same QoS as
//!   `ipc_types::ports` (buffer 4, history 0, safe overflow, 2 loans). It receives, reads
//!   the sequence number, loans, writes and sends the answer: the floor of any protocol on
//!   iceoryx2 between these two cores.
//!
//! The ratio contract/raw is therefore what the contract and the service add to iceoryx2
//! itself.
//!
//! [`round_trip_phase`] is the phase of the full run: both variants in rounds of fresh
//! child processes in ABBA order, merged per variant, with their ratio against
//! [`TARGET_RATIO`].

use crate::child::{self, ChildProc};
use crate::cli::Settings;
use crate::hist::new_histogram;
use crate::hist::{self, Summary, ratio};
use crate::progress;
use crate::report::{Collected, Measured};
use crate::table::fmt_ratio;
use crate::{PERIOD_NS, RT_PRIORITY};
use core::hint::spin_loop;
use core::mem::size_of;
use hdrhistogram::Histogram;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use ipc_types::clock::monotonic_ns;
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::rt::RtSetup;
use ipc_types::{Actuation, ChannelCounts, Measurement, measurement_flags};
use serde_json::{Value, json};
use std::fmt::Debug;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::SystemTime;
use std::time::{Duration, Instant};

/// How many round trips, how far apart, and how long to wait for one answer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundTripPlan {
    /// Round trips run first and not recorded.
    pub warmup: u64,
    /// Round trips recorded.
    pub samples: u64,
    /// Busy-wait between the receipt of an answer and the next send, ns (0: back-to-back).
    pub gap_ns: u64,
    /// Longest wait for one answer before the measurement is abandoned.
    pub answer_timeout: Duration,
    /// How long to wait for the peer to connect.
    pub connect_timeout: Duration,
}

/// The measurement loop shared by both variants; see the module docs. `send(k, last, t0)`
/// sends sample `k` (the last one when `last`) stamped `t0`; `poll()` returns the sequence
/// number of an answer if one is pending. `abort` stops the wait for an answer (the child
/// died).
pub fn time_round_trips<S, P>(
    plan: &RoundTripPlan,
    abort: &AtomicBool,
    mut send: S,
    mut poll: P,
) -> Result<Histogram<u64>, String>
where
    S: FnMut(u64, bool, u64) -> Result<(), String>,
    P: FnMut() -> Result<Option<u64>, String>,
{
    let mut h = new_histogram();
    let total = plan.warmup + plan.samples;
    let timeout_ns = plan.answer_timeout.as_nanos() as u64;
    let mut next = monotonic_ns();
    for k in 0..total {
        while monotonic_ns() < next {
            spin_loop();
        }
        let t0 = monotonic_ns();
        send(k, k + 1 == total, t0)?;
        let mut spins: u32 = 0;
        let t1 = loop {
            match poll()? {
                Some(seq) if seq == k => break monotonic_ns(),
                Some(_) => {} // a stale answer; keep waiting for k
                None => {
                    spin_loop();
                    spins = spins.wrapping_add(1);
                    if spins & 0xFFFF == 0 {
                        if abort.load(Ordering::Relaxed) {
                            return Err(format!(
                                "aborted while waiting for the answer to sample {k}"
                            ));
                        }
                        if monotonic_ns().saturating_sub(t0) > timeout_ns {
                            return Err(format!(
                                "no answer to sample {k} within {:.1} s",
                                plan.answer_timeout.as_secs_f64()
                            ));
                        }
                    }
                }
            }
        };
        if k >= plan.warmup {
            h.saturating_record(t1.saturating_sub(t0));
        }
        next = t1 + plan.gap_ns;
    }
    Ok(h)
}

/// A measurement value that changes from sample to sample without any arithmetic that
/// could cost more than a few cycles.
#[inline]
pub fn test_signal(k: u64) -> f64 {
    ((k % 64) as f64 - 32.0) * 0.01
}

/// The contract variant, parent side: connects as the plant of rig `rig` with `counts` and
/// runs [`time_round_trips`] against the service child.
pub fn contract_round_trips(
    rig: &str,
    counts: ChannelCounts,
    plan: &RoundTripPlan,
    abort: &AtomicBool,
) -> Result<Histogram<u64>, String> {
    let own = ContractInfo::new(Side::Plant, counts, PERIOD_NS);
    let opts = ConnectOptions::new(plan.connect_timeout).with_shutdown(abort);
    let ports: PlantPorts = ipc_types::ports::connect(rig, own, "bench-plant", opts)
        .map_err(|e| format!("connecting as the plant: {e}"))?;
    let mut m = Measurement::zeroed(counts);
    m.period_ns = PERIOD_NS;
    m.deadline_ns = 0;
    let send = |k: u64, last: bool, t0: u64| {
        m.seq = k;
        m.t_sample_ns = t0;
        m.flags = measurement_flags::LOCKSTEP
            | if last {
                measurement_flags::LAST_SAMPLE
            } else {
                0
            };
        m.y[0] = test_signal(k);
        publish(&ports.publisher, m, "measurement", k)
    };
    let poll = || poll_seq(&ports.subscriber, |a| a.seq, "an actuation");
    time_round_trips(plan, abort, send, poll)
}

/// Publishes a copy of `payload`, the `what` of sequence number `k`, on `publisher`.
fn publish<T: Debug + ZeroCopySend>(
    publisher: &Publisher<ipc::Service, T, ()>,
    payload: T,
    what: &str,
    k: u64,
) -> Result<(), String> {
    publisher
        .send_copy(payload)
        .map(|_| ())
        .map_err(|e| format!("sending {what} {k}: {e:?}"))
}

/// The sequence number (`seq` of the payload) of the next answer on `subscriber`, if one
/// came; a failure to receive names `what`.
fn poll_seq<T: Debug + ZeroCopySend>(
    subscriber: &Subscriber<ipc::Service, T, ()>,
    seq: impl Fn(&T) -> u64,
    what: &str,
) -> Result<Option<u64>, String> {
    match subscriber.receive() {
        Ok(Some(a)) => Ok(Some(seq(&a))),
        Ok(None) => Ok(None),
        Err(e) => Err(format!("receiving {what}: {e:?}")),
    }
}

const PING_FILL: usize = (size_of::<Measurement>() - 24) / 8;
const PONG_FILL: usize = (size_of::<Actuation>() - 24) / 8;

/// Set in [`RawPing::flags`] on the last ping: the echo exits after answering it.
pub const RAW_LAST: u64 = 1;

/// The raw variant's request: exactly the size and alignment of a [`Measurement`].
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("latency_bench::RawPing.v1")]
pub struct RawPing {
    /// Sequence number.
    pub seq: u64,
    /// [`RAW_LAST`] or 0.
    pub flags: u64,
    /// Send time, ns.
    pub t_send_ns: u64,
    /// Padding to the size of a [`Measurement`].
    pub fill: [u64; PING_FILL],
}

/// The raw variant's answer: exactly the size and alignment of an [`Actuation`].
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("latency_bench::RawPong.v1")]
pub struct RawPong {
    /// Sequence number of the ping answered.
    pub seq: u64,
    /// Unused; keeps the layout parallel to [`RawPing`].
    pub flags: u64,
    /// Unused; keeps the layout parallel to [`RawPing`].
    pub t_send_ns: u64,
    /// Padding to the size of an [`Actuation`].
    pub fill: [u64; PONG_FILL],
}

const _: () = assert!(size_of::<RawPing>() == size_of::<Measurement>());
const _: () = assert!(size_of::<RawPong>() == size_of::<Actuation>());
const _: () = assert!(align_of::<RawPing>() == align_of::<Measurement>());
const _: () = assert!(align_of::<RawPong>() == align_of::<Actuation>());

/// The two publish-subscribe ports of one side of the raw ping-pong, and what keeps them
/// alive.
pub struct RawPorts<Out: Debug + ZeroCopySend + 'static, In: Debug + ZeroCopySend + 'static> {
    /// Publisher of this side's payload.
    pub publisher: Publisher<ipc::Service, Out, ()>,
    /// Subscriber to the other side's payload.
    pub subscriber: Subscriber<ipc::Service, In, ()>,
    _out: PubSubFactory<ipc::Service, Out, ()>,
    _in: PubSubFactory<ipc::Service, In, ()>,
    _node: Node<ipc::Service>,
}

/// Name of the raw ping (parent → child) service of rig `rig`.
pub fn ping_service(rig: &str) -> String {
    format!("latency-bench/{rig}/ping")
}

/// Name of the raw pong (child → parent) service of rig `rig`.
pub fn pong_service(rig: &str) -> String {
    format!("latency-bench/{rig}/pong")
}

fn open_pubsub<T: Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
) -> Result<PubSubFactory<ipc::Service, T, ()>, String> {
    let service_name = ServiceName::new(name).map_err(|e| format!("service name {name}: {e:?}"))?;
    // The QoS of ipc_types::ports (pubsub_builder): the same buffers and overflow policy.
    node.service_builder(&service_name)
        .publish_subscribe::<T>()
        .max_publishers(2)
        .max_subscribers(4)
        .subscriber_max_buffer_size(4)
        .history_size(0)
        .enable_safe_overflow(true)
        .open_or_create()
        .map_err(|e| format!("opening {name}: {e:?}"))
}

/// Opens (or creates) the services `out_name` and `in_name`, creates the ports, and waits
/// until the other side subscribes to `out_name` so that no first sample is lost.
pub fn raw_connect<Out, In>(
    out_name: &str,
    in_name: &str,
    node_name: &str,
    timeout: Duration,
    abort: &AtomicBool,
) -> Result<RawPorts<Out, In>, String>
where
    Out: Debug + ZeroCopySend + 'static,
    In: Debug + ZeroCopySend + 'static,
{
    set_log_level(LogLevel::Error);
    ipc_types::ports::cleanup_dead_nodes();
    let name = NodeName::new(node_name).map_err(|e| format!("node name {node_name}: {e:?}"))?;
    let node = NodeBuilder::new()
        .name(&name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|e| format!("creating node {node_name}: {e:?}"))?;
    let start = Instant::now();
    let retry = |what: String| -> Result<(), String> {
        if abort.load(Ordering::Relaxed) {
            return Err(format!("aborted while {what}"));
        }
        if start.elapsed() > timeout {
            return Err(format!(
                "{what}: no peer within {:.0} s",
                timeout.as_secs_f64()
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
        Ok(())
    };
    // Both sides may try to create the same service at once; the loser retries the open.
    let out = loop {
        match open_pubsub::<Out>(&node, out_name) {
            Ok(f) => break f,
            Err(e) => retry(e)?,
        }
    };
    let inp = loop {
        match open_pubsub::<In>(&node, in_name) {
            Ok(f) => break f,
            Err(e) => retry(e)?,
        }
    };
    let publisher = out
        .publisher_builder()
        .max_loaned_samples(2)
        .create()
        .map_err(|e| format!("creating the publisher of {out_name}: {e:?}"))?;
    let subscriber = inp
        .subscriber_builder()
        .create()
        .map_err(|e| format!("creating the subscriber of {in_name}: {e:?}"))?;
    while out.dynamic_config().number_of_subscribers() == 0 {
        retry(format!("waiting for a subscriber of {out_name}"))?;
    }
    Ok(RawPorts {
        publisher,
        subscriber,
        _out: out,
        _in: inp,
        _node: node,
    })
}

/// The raw variant, parent side: runs [`time_round_trips`] against the echo child of rig
/// `rig`.
pub fn raw_round_trips(
    rig: &str,
    plan: &RoundTripPlan,
    abort: &AtomicBool,
) -> Result<Histogram<u64>, String> {
    let ports: RawPorts<RawPing, RawPong> = raw_connect(
        &ping_service(rig),
        &pong_service(rig),
        "bench-raw-ping",
        plan.connect_timeout,
        abort,
    )?;
    let mut p = RawPing {
        seq: 0,
        flags: 0,
        t_send_ns: 0,
        fill: [0; PING_FILL],
    };
    let send = |k: u64, last: bool, t0: u64| {
        p.seq = k;
        p.t_send_ns = t0;
        p.flags = if last { RAW_LAST } else { 0 };
        publish(&ports.publisher, p, "ping", k)
    };
    let poll = || poll_seq(&ports.subscriber, |a| a.seq, "a pong");
    time_round_trips(plan, abort, send, poll)
}

/// The echo child: pins itself to `core` with `SCHED_FIFO` and `mlockall` (the service's
/// RT set-up), answers every ping of rig `rig` with a pong carrying its sequence number,
/// busy-polling, and exits after the ping marked [`RAW_LAST`] (or on SIGTERM, or after 60 s
/// without a ping). Returns the process exit code.
pub fn run_echo_child(rig: &str, core: usize) -> i32 {
    let setup = ipc_types::rt::setup_current_thread(&crate::rt_request(core));
    eprintln!("[echo] real-time set-up: {}", setup.describe());
    let shutdown = crate::child::shutdown_flag();
    let ports: RawPorts<RawPong, RawPing> = match raw_connect(
        &pong_service(rig),
        &ping_service(rig),
        "bench-raw-echo",
        Duration::from_secs(60),
        &shutdown,
    ) {
        Ok(p) => p,
        Err(e) => {
            eprintln!("[echo] {e}");
            return 1;
        }
    };
    eprintln!("[echo] connected; echoing");
    let mut answered: u64 = 0;
    let mut spins: u32 = 0;
    let mut last_rx = Instant::now();
    loop {
        match ports.subscriber.receive() {
            Ok(Some(ping)) => {
                let (seq, flags) = (ping.seq, ping.flags);
                drop(ping);
                let pong = RawPong {
                    seq,
                    flags: 0,
                    t_send_ns: 0,
                    fill: [0; PONG_FILL],
                };
                match ports.publisher.loan_uninit() {
                    Ok(sample) => {
                        if let Err(e) = sample.write_payload(pong).send() {
                            eprintln!("[echo] send failed: {e:?}");
                        }
                    }
                    Err(e) => eprintln!("[echo] loan failed: {e:?}"),
                }
                answered += 1;
                if flags & RAW_LAST != 0 {
                    break;
                }
                last_rx = Instant::now();
            }
            Ok(None) => {
                spin_loop();
                spins = spins.wrapping_add(1);
                if spins & 0xFFFF == 0
                    && (shutdown.load(Ordering::Relaxed)
                        || last_rx.elapsed() > Duration::from_secs(60))
                {
                    eprintln!("[echo] stopping without the last ping");
                    break;
                }
            }
            Err(e) => {
                eprintln!("[echo] receive failed: {e:?}");
                return 1;
            }
        }
    }
    eprintln!("[echo] answered {answered} pings");
    0
}

// The phase: ABBA rounds of fresh child processes, merged per variant.

/// The issue's target for contract / raw at p50 and p99.
pub const TARGET_RATIO: f64 = 1.5;

/// One round of one round-trip variant: its histogram, the plant thread's RT set-up and
/// the service's run report (`Null` for the raw variant).
pub type RoundOutcome = Result<(Histogram<u64>, RtSetup, Value), String>;

/// One contract round: the real service (busy-poll) as the child, the parent as the
/// contract's plant.
pub fn contract_round(s: &Settings, dir: &Path, rig: &str, counts: ChannelCounts) -> RoundOutcome {
    let mut child = child::spawn_service(s, dir, rig, "busy-poll")?;
    let plan = s.plan;
    let (h, setup) = child::drive(&mut child, s.plant_rt(), s.rtt_limit(), |abort| {
        contract_round_trips(rig, counts, &plan, abort)
    })?;
    child.wait(Duration::from_secs(30))?;
    let report = child::read_report(dir)?;
    Ok((h, setup, report))
}

/// One raw round: the iceoryx2 echo as the child.
pub fn raw_round(s: &Settings, dir: &Path, rig: &str) -> RoundOutcome {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let args = vec![
        "child-echo".to_string(),
        "--rig".into(),
        rig.into(),
        "--core".into(),
        s.rt_core.to_string(),
    ];
    let mut child = ChildProc::spawn(
        s.child_exe.as_deref(),
        &args,
        &dir.join("child.log"),
        "raw echo",
    )?;
    child.rt_core = Some(s.rt_core);
    let plan = s.plan;
    let (h, setup) = child::drive(&mut child, s.plant_rt(), s.rtt_limit(), |abort| {
        raw_round_trips(rig, &plan, abort)
    })?;
    child.wait(Duration::from_secs(30))?;
    Ok((h, setup, Value::Null))
}

/// Min and max of some values, as "a–b" with two decimals (or one value when equal).
fn range(values: &[f64], unit: &str) -> String {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return "-".into();
    }
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if (hi - lo).abs() < 0.005 {
        format!("{lo:.2}{unit}")
    } else {
        format!("{lo:.2}–{hi:.2}{unit}")
    }
}

/// The contract and raw round trips, in `s.rounds` rounds of fresh child processes in ABBA
/// order (contract, raw, raw, contract, …), so that slow changes of the machine's load
/// weigh on both variants alike. Each round records `s.plan.samples` round trips after
/// `s.plan.warmup`, on the rig `<rig_base>-rtt<r>` or `<rig_base>-raw<r>`
/// ([`crate::rig_base`]); the rows are the merged histograms. Returns the ratio block of
/// `summary.json`; the rows, details and service reports go into `col`.
pub fn round_trip_phase(
    s: &Settings,
    out: &Path,
    rig_base: &str,
    counts: ChannelCounts,
    col: &mut Collected,
) -> Value {
    let Collected {
        measured,
        details,
        reports,
        ..
    } = col;
    const IDS: [&str; 2] = ["contract-rtt", "raw-rtt"];
    const LABELS: [&str; 2] = ["contract round trip (service)", "raw iceoryx2 ping-pong"];
    let mut merged = [hist::new_histogram(), hist::new_histogram()];
    let mut per_round: [Vec<Summary>; 2] = [Vec::new(), Vec::new()];
    let mut errors: [Option<String>; 2] = [None, None];
    let mut setups: Vec<String> = Vec::new();
    let mut service_side: Vec<[f64; 3]> = Vec::new();
    let start = SystemTime::now();
    let t = Instant::now();
    for r in 0..s.rounds {
        let order = if r % 2 == 0 { [0, 1] } else { [1, 0] };
        for v in order {
            if errors[v].is_some() {
                continue;
            }
            progress(&format!(
                "{}/6 {}, round {}/{}: {} round trips after {} warm-up",
                v + 1,
                LABELS[v],
                r + 1,
                s.rounds,
                s.plan.samples,
                s.plan.warmup
            ));
            let dir = out.join(IDS[v]).join(format!("round-{r}"));
            let outcome = if v == 0 {
                contract_round(s, &dir, &format!("{rig_base}-rtt{r}"), counts)
            } else {
                raw_round(s, &dir, &format!("{rig_base}-raw{r}"))
            };
            match outcome {
                Ok((h, setup, report)) => {
                    let _ = merged[v].add(&h);
                    per_round[v].push(Summary::of(&h));
                    setups.push(setup.describe());
                    if !report.is_null() {
                        let p50 = |k: &str| {
                            report
                                .pointer(&format!("/latency/{k}/p50"))
                                .and_then(Value::as_u64)
                                .map(|ns| ns as f64 / 1e3)
                        };
                        if let (Some(w), Some(rsp), Some(c)) =
                            (p50("wakeup"), p50("response"), p50("compute"))
                        {
                            service_side.push([w, rsp, c]);
                        }
                        if r == 0 {
                            details.push(format!(
                                "contract rounds: service RT set-up: {}",
                                child::service_rt_line(&report)
                            ));
                        }
                        reports.insert(format!("{}-round-{r}", IDS[v]), report);
                    }
                }
                Err(e) => errors[v] = Some(format!("round {}: {e}", r + 1)),
            }
        }
    }
    let elapsed = t.elapsed();
    let mut rows = Vec::new();
    for v in 0..2 {
        let dir = out.join(IDS[v]);
        match &errors[v] {
            Some(e) => rows.push(Measured::failed(IDS[v], LABELS[v], e.clone())),
            None => {
                let files =
                    hist::write_files(&dir, "rtt", &merged[v], start, elapsed).unwrap_or_default();
                rows.push(Measured::from_summary(
                    IDS[v],
                    LABELS[v],
                    Summary::of(&merged[v]),
                    files,
                ));
            }
        }
    }
    let [mut contract, mut raw] = <[Measured; 2]>::try_from(rows).expect("two rows");
    let ratios = match (&contract.summary, &raw.summary) {
        (Some(c), Some(r)) => {
            let p50 = ratio(c.p50_ns, r.p50_ns);
            let p99 = ratio(c.p99_ns, r.p99_ns);
            let pass = p50
                .zip(p99)
                .map(|(a, b)| a <= TARGET_RATIO && b <= TARGET_RATIO);
            contract.note = format!(
                "÷ raw: p50 {}, p99 {} → {} (target ≤ {TARGET_RATIO})",
                fmt_ratio(p50),
                fmt_ratio(p99),
                match pass {
                    Some(true) => "PASS",
                    Some(false) => "FAIL",
                    None => "n/a",
                }
            );
            raw.note = "reference for the contract row".into();
            let round_ratio = |f: fn(&Summary) -> u64| -> Vec<f64> {
                per_round[0]
                    .iter()
                    .zip(&per_round[1])
                    .filter_map(|(c, r)| ratio(f(c), f(r)))
                    .collect()
            };
            let (r50, r99) = (round_ratio(|s| s.p50_ns), round_ratio(|s| s.p99_ns));
            details.push(format!(
                "contract ÷ raw per round: p50 {}, p99 {} ({} rounds, ABBA order)",
                range(&r50, ""),
                range(&r99, ""),
                r50.len()
            ));
            json!({
                "p50": p50, "p99": p99, "target": TARGET_RATIO, "pass": pass,
                "per_round_p50": r50, "per_round_p99": r99,
                "per_round_contract": per_round[0], "per_round_raw": per_round[1],
            })
        }
        _ => Value::Null,
    };
    if !service_side.is_empty() {
        let col = |i: usize| service_side.iter().map(|v| v[i]).collect::<Vec<_>>();
        let in_service: Vec<f64> = service_side.iter().map(|v| v[1] - v[0]).collect();
        details.push(format!(
            "contract rounds, service side (p50 per round): plant send → receipt {}, plant send → u_k published {} \
             (so ≈ {} from receipt to publication), of which controller step {}",
            range(&col(0), " µs"),
            range(&col(1), " µs"),
            range(&in_service, " µs"),
            range(&col(2), " µs")
        ));
    }
    let spacing = if s.plan.gap_ns == 0 {
        "back-to-back".to_string()
    } else {
        format!(
            "{:.0} µs busy-wait after each answer",
            s.plan.gap_ns as f64 / 1e3
        )
    };
    details.push(format!(
        "round trips: parent on core {} and child on core {}, both busy-polling, SCHED_FIFO {RT_PRIORITY}; {} rounds × {} samples after {} warm-up each, {spacing}, same for both variants; plant thread: {}",
        s.plant_core,
        s.rt_core,
        s.rounds,
        s.plan.samples,
        s.plan.warmup,
        setups.first().map(String::as_str).unwrap_or("?")
    ));
    measured.push(contract);
    measured.push(raw);
    ratios
}
