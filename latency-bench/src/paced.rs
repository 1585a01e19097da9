//! Service loop wake-up latency at 8 kHz: the parent is a real-time plant.
//!
//! ## Method
//!
//! The parent thread (plant core, `SCHED_FIFO`) does what plant-proxy does in real-time
//! mode, sample by sample:
//!
//! ```text
//!  t_k = t_0 + k·T                                  (T = 125 µs, CLOCK_MONOTONIC)
//!  y_k, z_k from the model                          (before the sleep)
//!  sleep_until_ns(t_k); t_wake = monotonic_ns()     pacing lateness = t_wake − t_k
//!  publish Measurement{seq k, t_sample_ns = t_k, deadline_ns = T/2, real-time flags,
//!                      u_applied = u_{k−1} when the model reports it}
//!  notify the measurement event                     (wakes a blocking service)
//!  sleep_until_ns(t_k + T/2); drain the actuations  answer k there? in time : late/missing
//!  the model applies u_k                            (the answer to k, else the last one held)
//! ```
//!
//! The model ([`PacedModel`]) of the wake-up phase is [`TestSignal`]: a test signal in
//! `y_0` and nothing fed back. The response-time phase ([`crate::timing_phase`]) closes a
//! loop around an adaptive controller instead, through [`paced_service_run`].
//!
//! The service child stamps each receipt and records the wake-up latency
//! `t_recv − t_sample_ns` in its own histograms (its run report, `report.json`, and
//! `wakeup.hgrm` in its run folder): the figure a deployed service reports. Because
//! `t_sample_ns` is the nominal sample time `t_k`, that latency contains the plant's own
//! timer lateness, which the parent records here as the floor under it. The parent also
//! records `t_publish(u_k) − t_publish(y_k)` from the actuation's timestamp: the part the
//! IPC, the service's wake-up and its step add after the plant has actually published
//! (both processes read the same `CLOCK_MONOTONIC`).
//!
//! Every sample is recorded, including the first ones after the service connects: the
//! service records from its first sample on, and the parent does the same so that both
//! cover the same cycles.
//!
//! [`wakeup_phase`] is the phase of the full run: one such run per wait mode (busy-poll,
//! then block), each with a fresh service child.

use crate::PERIOD_NS;
use crate::child;
use crate::cli::Settings;
use crate::hist::new_histogram;
use crate::hist::{self, Summary};
use crate::progress;
use crate::report::{Collected, Measured};
use crate::roundtrip::test_signal;
use hdrhistogram::Histogram;
use ipc_types::clock::{monotonic_ns, sleep_until_ns};
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::rt::RtSetup;
use ipc_types::{ChannelCounts, MAX_U, Measurement, measurement_flags};
use serde_json::{Value, json};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, SystemTime};

/// What the paced plant measured.
#[derive(Debug, Clone)]
pub struct PacedResult {
    /// Pacing lateness `t_wake − t_k`, ns.
    pub pacing: Histogram<u64>,
    /// `t_publish(u_k) − t_publish(y_k)`, ns, for answers that came in time.
    pub publish_to_answer: Histogram<u64>,
    /// Samples published.
    pub samples: u64,
    /// Answers present at the deadline check of their own sample.
    pub in_time: u64,
    /// Answers found only at a later sample's check.
    pub late: u64,
    /// Wall-clock start, for the interval logs.
    pub start: SystemTime,
    /// Duration of the run.
    pub duration: Duration,
}

impl PacedResult {
    /// Samples never answered (or whose answer was overwritten before it was read).
    pub fn missing(&self) -> u64 {
        self.samples.saturating_sub(self.in_time + self.late)
    }
}

/// What the paced plant puts in each measurement, and what it does with each answer.
///
/// [`paced_plant_with`] calls [`PacedModel::sample`] for sample `k` before it sleeps until
/// `t_k` (so that the model's arithmetic is not in the measured path), and
/// [`PacedModel::apply`] after the deadline check of sample `k` with the input the plant
/// applies for it: the answer to `k` when it was there, else the last one applied (a
/// hold).
pub trait PacedModel: Send {
    /// Writes `y_k` and `z_k` (slices of the rig's counts; `z` may be empty).
    fn sample(&mut self, k: u64, y: &mut [f64], z: &mut [f64]);
    /// Takes the input applied for the sample just taken (`n_u` values).
    fn apply(&mut self, u: &[f64]);
    /// Whether each measurement reports the input applied after the previous sample
    /// (`u_applied` with `U_APPLIED`, as plant-proxy does): a closed loop does, so that a
    /// controller that identifies its plant (PCAC) learns from the input the plant really
    /// held when an answer was late. Default: no.
    fn reports_applied(&self) -> bool {
        false
    }
}

/// The measurements of the wake-up phase: `y_0` is [`test_signal`]`(k)`, every other
/// channel 0, and the answers go nowhere.
#[derive(Debug, Clone, Copy, Default)]
pub struct TestSignal;

impl PacedModel for TestSignal {
    fn sample(&mut self, k: u64, y: &mut [f64], z: &mut [f64]) {
        y.fill(0.0);
        z.fill(0.0);
        if let Some(y0) = y.first_mut() {
            *y0 = test_signal(k);
        }
    }

    fn apply(&mut self, _u: &[f64]) {}
}

/// Runs the plant of rig `rig` at 8 kHz for `seconds`, deadline half a period, with the
/// measurements of [`TestSignal`]; see the module docs. `abort` ends it early (the child
/// died).
pub fn paced_plant(
    rig: &str,
    counts: ChannelCounts,
    seconds: f64,
    connect_timeout: Duration,
    abort: &AtomicBool,
) -> Result<PacedResult, String> {
    paced_plant_with(
        rig,
        counts,
        PERIOD_NS,
        seconds,
        connect_timeout,
        abort,
        &mut TestSignal,
    )
}

/// [`paced_plant`] with the sample period `period_ns` (deadline half of it) and the
/// measurements of `model`, which also takes the inputs applied ([`PacedModel`]): a
/// closed loop around the service when the model feeds them back.
pub fn paced_plant_with(
    rig: &str,
    counts: ChannelCounts,
    period_ns: u64,
    seconds: f64,
    connect_timeout: Duration,
    abort: &AtomicBool,
    model: &mut dyn PacedModel,
) -> Result<PacedResult, String> {
    let own = ContractInfo::new(Side::Plant, counts, period_ns);
    let opts = ConnectOptions::new(connect_timeout).with_shutdown(abort);
    let ports: PlantPorts = ipc_types::ports::connect(rig, own, "bench-plant", opts)
        .map_err(|e| format!("connecting as the plant: {e}"))?;
    let n = ((seconds * 1e9 / period_ns as f64).round() as u64).max(1);
    let deadline = period_ns / 2;
    let mut pacing = new_histogram();
    let mut publish_to_answer = new_histogram();
    let (mut in_time, mut late) = (0u64, 0u64);
    let mut m = Measurement::zeroed(counts);
    m.period_ns = period_ns;
    m.deadline_ns = deadline;
    let (n_y, n_z, n_u) = (
        counts.n_y as usize,
        counts.n_z as usize,
        counts.n_u as usize,
    );
    // The input the plant applies: the answer of each sample, held when it is missing.
    let mut applied = [0.0; MAX_U];
    let report_applied = model.reports_applied();
    model.sample(0, &mut m.y[..n_y], &mut m.z[..n_z]);
    let start = SystemTime::now();
    // Leave the service a few ms to enter its loop after the connection.
    let t0 = monotonic_ns() + 10_000_000;
    let mut previous_missed = false;
    let mut published = 0u64;
    for k in 0..n {
        if abort.load(Ordering::Relaxed) {
            return Err(format!("aborted at sample {k} of {n}"));
        }
        let t_k = t0 + k * period_ns;
        sleep_until_ns(t_k);
        let t_wake = monotonic_ns();
        pacing.saturating_record(t_wake.saturating_sub(t_k));
        m.seq = k;
        m.t_sample_ns = t_k;
        m.flags = if previous_missed {
            measurement_flags::PREVIOUS_ACTUATION_MISSED
        } else {
            0
        };
        if report_applied && k > 0 {
            m.flags |= measurement_flags::U_APPLIED;
            m.u_applied[..n_u].copy_from_slice(&applied[..n_u]);
        }
        if k + 1 == n {
            m.flags |= measurement_flags::LAST_SAMPLE;
        }
        let t_pub = monotonic_ns();
        ports
            .publisher
            .send_copy(m)
            .map_err(|e| format!("sending measurement {k}: {e:?}"))?;
        published += 1;
        let _ = ports.notifier.notify();
        sleep_until_ns(t_k + deadline);
        let mut got = false;
        loop {
            match ports.subscriber.receive() {
                Ok(Some(a)) => {
                    if a.seq == k {
                        got = true;
                        applied[..n_u].copy_from_slice(&a.u[..n_u]);
                        publish_to_answer.saturating_record(a.t_publish_ns.saturating_sub(t_pub));
                    } else if a.seq < k {
                        late += 1;
                    }
                }
                Ok(None) => break,
                Err(e) => return Err(format!("receiving an actuation: {e:?}")),
            }
        }
        if got {
            in_time += 1;
        }
        previous_missed = !got;
        model.apply(&applied[..n_u]);
        if k + 1 < n {
            model.sample(k + 1, &mut m.y[..n_y], &mut m.z[..n_z]);
        }
    }
    // An answer to the last sample that came after its check.
    let end = monotonic_ns() + 2_000_000;
    while monotonic_ns() < end {
        match ports.subscriber.receive() {
            Ok(Some(a)) if a.seq + 1 == n && previous_missed => {
                late += 1;
                break;
            }
            Ok(Some(_)) => {}
            _ => std::thread::sleep(Duration::from_micros(100)),
        }
    }
    let duration = start.elapsed().unwrap_or_default();
    Ok(PacedResult {
        pacing,
        publish_to_answer,
        samples: published,
        in_time,
        late,
        start,
        duration,
    })
}

/// The wake-up phase: the service child in sleep-poll (the default), busy-poll, then
/// blocking mode, each paced
/// by [`paced_plant`] at 8 kHz for `s.seconds`. The service's wake-up rows, the detail
/// lines, the `extra` blocks and the run reports go into `col`; the plant-side rows
/// (pacing lateness, publish → answer) are returned, to be placed after the cyclictest
/// ratios are added to the wake-up rows.
pub fn wakeup_phase(
    s: &Settings,
    out: &Path,
    rig_base: &str,
    counts: ChannelCounts,
    col: &mut Collected,
) -> Vec<Measured> {
    let mut plant_rows: Vec<Measured> = Vec::new();
    for (mode, wait) in [
        ("sleep-poll", "sleep-poll"),
        ("busy-poll", "busy-poll"),
        ("block", "block"),
    ] {
        progress(&format!(
            "3-4/6 service wake-up at 8 kHz, {mode}, {:.1} s",
            s.seconds
        ));
        let dir = out.join(format!("wakeup-{mode}"));
        let rig = format!("{rig_base}-{mode}");
        let label = format!("service wake-up 8 kHz {mode}");
        match paced_phase(s, &dir, &rig, wait, counts) {
            Ok((p, setup, report)) => {
                let wk = report
                    .pointer("/latency/wakeup")
                    .ok_or("report.json has no latency.wakeup".to_string())
                    .and_then(Summary::from_service_json);
                match wk {
                    Ok(sum) => {
                        let mut m = Measured::from_summary(
                            &format!("wakeup-{mode}"),
                            &label,
                            sum,
                            vec![dir.join("wakeup.hgrm"), dir.join("wakeup.hlog")],
                        );
                        m.files.retain(|f| f.exists());
                        // Samples the service never saw are in no histogram of its own.
                        if let Some(n) = report.pointer("/stats/skipped").and_then(Value::as_u64) {
                            m.note = format!("{n} samples skipped by the service");
                        }
                        col.measured.push(m);
                    }
                    Err(e) => {
                        col.measured
                            .push(Measured::failed(&format!("wakeup-{mode}"), &label, e));
                    }
                }
                let files = hist::write_files(&dir, "plant-pacing", &p.pacing, p.start, p.duration)
                    .unwrap_or_default();
                plant_rows.push(Measured::from_summary(
                    &format!("pacing-{mode}"),
                    &format!("  plant pacing lateness ({mode} run)"),
                    Summary::of(&p.pacing),
                    files,
                ));
                let files = hist::write_files(
                    &dir,
                    "plant-publish-to-answer",
                    &p.publish_to_answer,
                    p.start,
                    p.duration,
                )
                .unwrap_or_default();
                let mut m = Measured::from_summary(
                    &format!("publish-to-answer-{mode}"),
                    &format!("  plant publish → u_k published ({mode})"),
                    Summary::of(&p.publish_to_answer),
                    files,
                );
                m.note = format!("{} of {} answers in time", p.in_time, p.samples);
                plant_rows.push(m);
                let misses = report
                    .pointer("/stats/deadline_misses")
                    .and_then(Value::as_u64);
                col.details.push(format!(
                    "8 kHz {mode}: {} samples, deadline {:.1} µs: {} answered in time, {} late, {} missing (plant view); service counted {} misses; service RT set-up: {}; plant thread: {}",
                    p.samples,
                    PERIOD_NS as f64 / 2_000.0,
                    p.in_time,
                    p.late,
                    p.missing(),
                    misses.map(|m| m.to_string()).unwrap_or_else(|| "?".into()),
                    child::service_rt_line(&report),
                    setup.describe()
                ));
                col.extra.insert(
                    format!("paced-{mode}"),
                    json!({
                        "samples": p.samples, "in_time": p.in_time, "late": p.late, "missing": p.missing(),
                        "pacing_lateness": Summary::of(&p.pacing),
                        "publish_to_answer": Summary::of(&p.publish_to_answer),
                        "plant_rt_setup": setup.describe(),
                    }),
                );
                col.reports.insert(format!("wakeup-{mode}"), report);
            }
            Err(e) => {
                col.measured
                    .push(Measured::failed(&format!("wakeup-{mode}"), &label, e));
            }
        }
    }
    plant_rows
}

/// One wake-up run in mode `wait`: the paced plant's figures, its RT set-up and the
/// service's run report.
pub fn paced_phase(
    s: &Settings,
    dir: &Path,
    rig: &str,
    wait: &str,
    counts: ChannelCounts,
) -> Result<(PacedResult, RtSetup, Value), String> {
    let child = child::spawn_service(s, dir, rig, wait)?;
    let plant = PacedSpec {
        counts,
        period_ns: PERIOD_NS,
        seconds: s.seconds,
    };
    paced_service_run(s, child, dir, rig, &plant, &mut TestSignal)
}

/// The paced plant of one run: the rig's channel counts, the sample period (the deadline
/// is half of it) and how long it paces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PacedSpec {
    /// The rig's channel counts.
    pub counts: ChannelCounts,
    /// Sample period, ns.
    pub period_ns: u64,
    /// Seconds of pacing.
    pub seconds: f64,
}

/// Paces the service child `child` (started on rig `rig` with its run folder `dir`) as
/// `plant` says with the measurements of `model` ([`paced_plant_with`]), waits for it to
/// exit and reads its run report: the paced plant's figures, its RT set-up and the report.
pub fn paced_service_run(
    s: &Settings,
    mut child: child::ChildProc,
    dir: &Path,
    rig: &str,
    plant: &PacedSpec,
    model: &mut dyn PacedModel,
) -> Result<(PacedResult, RtSetup, Value), String> {
    let PacedSpec {
        counts,
        period_ns,
        seconds,
    } = *plant;
    let (p, setup) = child::drive(
        &mut child,
        s.plant_rt(),
        Duration::from_secs_f64(40.0 + 3.0 * seconds),
        |abort| {
            paced_plant_with(
                rig,
                counts,
                period_ns,
                seconds,
                Duration::from_secs(20),
                abort,
                model,
            )
        },
    )?;
    child.wait(Duration::from_secs(30))?;
    let report = child::read_report(dir)?;
    Ok((p, setup, report))
}
