//! The plant process: the clock master of the contract.
//!
//! At sample `k` the plant publishes `y_k`, `z_k`, `r_k` stamped with the sample time, and
//! applies an input for the period that starts at `k`: the service's actuation with
//! `seq = k` if it holds it at the application instant, else a **miss** resolved by
//! `proxy.late-policy` ([`crate::late_policy`]). Which input that is, is decided by the
//! plant's [`ActuationBook`], which keeps the actuations received ahead of their sample (a
//! service that sends ahead publishes the input for `k + 1` as soon as it has taken `y_k`
//! in), refuses late and invalid ones, and holds the newest plan.
//!
//! - **real-time mode**: samples are paced on `CLOCK_MONOTONIC` at `t_k = t_0 + kT`
//!   ([`SampleClock`]; `proxy.overrun` says what happens when the plant itself wakes more
//!   than a period late). The input for sample `k` is applied at `t_k + dT`
//!   (`proxy.deadline = d`, a fraction of the period, carried in the sample as
//!   `deadline_ns`). With `d > 0` the plant publishes at `t_k`, sleeps until the deadline and
//!   decides. With `d = 0` the input is latched at the sample clock, as a DAC driven by the
//!   ADC clock does: at `t_k` the plant decides the input for `k` from what it holds,
//!   then samples and publishes `M_k` (only a service that sends ahead can meet that). The
//!   simulation applies `u_k` over `[kT, (k+1)T)` as in the dissertation
//!   (`proxy.intersample = "ideal"`), or from `kT + dT` on, as the real hold would
//!   (`"at-deadline"`; the same for `d = 0`).
//! - **lockstep mode**: after publishing `M_k` the plant waits (on the service's event, up to
//!   `proxy.lockstep-timeout`) until the service has answered `M_k`: it holds a valid
//!   actuation with `reply_to ≥ k`, or, for an injected stall, the acknowledgement of `k`
//!   ([`ActuationBook::answers`]). Then the input for `k` is the actuation with `seq = k` if
//!   the plant holds it (sent ahead during the previous step, or the answer itself), else a
//!   miss. The plant never publishes `M_{k+1}` before the service has answered (or
//!   acknowledged) `M_k`, so a run is as fast as possible and bit-for-bit deterministic for a
//!   seed, with compute-first and send-ahead services alike. `[proxy.faults] stalls` flags
//!   samples with `INJECTED_STALL` ([`crate::faults`]).
//!
//! Every measurement reports the period that ends at it: the input applied for sample
//! `k − 1` (`u_applied`), `PREVIOUS_ACTUATION_MISSED` when that was a miss, with
//! `PLAN_APPLIED` when a plan covered it, and `PLANT_SAFE_OUTPUT` while the watchdog holds the
//! safe output.
//!
//! A watchdog puts the plant into its safe output after `proxy.watchdog-periods`
//! consecutive misses (plan-covered or not), says so, removes the stale resources of dead
//! iceoryx2 nodes (so a restarted service can connect), and leaves the safe output on the
//! next valid actuation. In lockstep mode the plant does not wait for ever: when no service
//! has answered for `proxy.peer-timeout` after the watchdog tripped (the time a service is
//! given to connect at start-up), it gives up with [`PlantError::GaveUp`] (a non-zero exit
//! status).
//!
//! Only the service the plant connected to drives it: its publisher is pinned at connect
//! (`ipc_types::peer`), an actuation from any other publisher is refused and counted
//! ([`PlantReport::foreign_discarded`]), and a restarted service, which can only appear once
//! the old one's publisher is gone, is recognized and counted ([`PlantReport::new_services`]);
//! what the old one had sent is forgotten. `[proxy.faults]` also injects NaN, ±Inf and
//! out-of-range measurements at given samples, for testing the service's input validation.

pub use crate::faults::{Faults, Stall};
pub use crate::late_policy::{LatePolicy, PlanFallback};
pub use crate::plant_report::PlantReport;
pub use crate::proxy_config::{Intersample, Mode, ProxyConfig, ProxyConfigError};
pub use crate::sample_clock::Overrun;

use crate::actuation_book::{AHEAD_CAPACITY, ActuationBook, Decision, Offer};
use crate::sample_clock::SampleClock;
use crate::scenario::Scenario;
use crate::sim::PlantSim;
use ipc_types::clock::{monotonic_ns, sleep_until_ns};
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::{ChannelCounts, MAX_U, Measurement, Timing, measurement_flags};
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Options of one plant run that do not belong in the scenario.
#[derive(Debug, Clone, Default)]
pub struct PlantRunOptions {
    /// Number of samples to run (default: the scenario's duration).
    pub steps: Option<u64>,
    /// Write a CSV trace (k, y, z, u applied, flags) here.
    pub trace: Option<PathBuf>,
    /// Print progress and events.
    pub verbose: bool,
}

/// Why a plant run failed.
#[derive(Debug)]
pub enum PlantError {
    /// The model or the proxy configuration could not be built.
    Config(String),
    /// Connecting to the service failed.
    Connect(ipc_types::ports::ConnectError),
    /// Writing the trace failed.
    Io(String),
    /// Lockstep: no service answered for `proxy.peer-timeout` after the watchdog tripped;
    /// the plant gave up. The report of the run so far comes with it.
    GaveUp {
        /// What happened, for the user.
        message: String,
        /// The counters up to the end.
        report: Box<PlantReport>,
    },
}

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlantError::Config(m) | PlantError::Io(m) => f.write_str(m),
            PlantError::Connect(e) => write!(f, "{e}"),
            PlantError::GaveUp { message, .. } => f.write_str(message),
        }
    }
}

impl std::error::Error for PlantError {}

struct Trace {
    out: std::io::BufWriter<std::fs::File>,
}

impl Trace {
    fn create(path: &Path, n_y: usize, n_z: usize, n_u: usize) -> Result<Self, PlantError> {
        let f = std::fs::File::create(path)
            .map_err(|e| PlantError::Io(format!("creating trace {}: {e}", path.display())))?;
        let mut out = std::io::BufWriter::new(f);
        let mut header = String::from("k,t");
        for i in 0..n_y {
            header += &format!(",y{i}");
        }
        for i in 0..n_z {
            header += &format!(",z{i}");
        }
        for i in 0..n_u {
            header += &format!(",u{i}");
        }
        header += ",flags,actuation_status\n";
        out.write_all(header.as_bytes())
            .map_err(|e| PlantError::Io(e.to_string()))?;
        Ok(Self { out })
    }

    /// One row: sample `k` at time `t`, the signals `[y, z, u]`, the flags and status.
    fn row(&mut self, k: u64, t: f64, [y, z, u]: [&[f64]; 3], flags: u32, status: u32) {
        let _ = write!(self.out, "{k},{t}");
        for v in y.iter().chain(z).chain(u) {
            let _ = write!(self.out, ",{v:e}");
        }
        let _ = writeln!(self.out, ",{flags},{status}");
    }
}

/// Runs the plant of `scenario` against the service until `steps` samples are done or
/// `shutdown` is set.
pub fn run_plant(
    scenario: &Scenario,
    proxy: &ProxyConfig,
    opts: &PlantRunOptions,
    shutdown: &AtomicBool,
) -> Result<PlantReport, PlantError> {
    proxy
        .check_mode(&format!("rig '{}'", scenario.rig.name))
        .map_err(|e| PlantError::Config(e.0))?;
    let ts = scenario.rig.sample_period;
    let period_ns = (ts * 1e9).round() as u64;
    let mut sim =
        PlantSim::new(&scenario.plant, ts).map_err(|e| PlantError::Config(e.to_string()))?;
    // At deadline 0 (or 1) the real hold and the ideal one are the same.
    if proxy.intersample == Intersample::AtDeadline && proxy.deadline > 0.0 && proxy.deadline < 1.0
    {
        sim.set_apply_offset(Some(proxy.deadline))
            .map_err(|e| PlantError::Config(e.to_string()))?;
    }
    let (n_y, n_z, n_r, n_u) = (sim.n_y(), sim.n_z(), sim.n_r(), sim.n_u());
    let counts = ChannelCounts::new(n_y, n_z, n_r, n_u).map_err(PlantError::Config)?;
    if proxy.safe_input.len() != n_u {
        return Err(PlantError::Config(format!(
            "proxy.safe-input needs {n_u} values"
        )));
    }
    let steps = opts
        .steps
        .unwrap_or_else(|| (scenario.rig.duration / ts).round() as u64);
    let mut trace = match &opts.trace {
        Some(p) => Some(Trace::create(p, n_y, n_z, n_u)?),
        None => None,
    };

    let rt_setup = if proxy.mode == Mode::RealTime {
        let s = ipc_types::rt::setup_current_thread(&proxy.rt);
        if s.any_refused() {
            eprintln!(
                "[plant-proxy] WARNING: real-time set-up incomplete: {}",
                s.describe()
            );
        }
        s.describe()
    } else {
        "lockstep: none requested".to_string()
    };

    let applies = proxy.applies();
    let own = ContractInfo::new(Side::Plant, counts, period_ns).with_applies(applies);
    let waiting = format!(
        "[plant-proxy] rig '{}': waiting for the service ...",
        scenario.rig.name
    );
    let copts = ConnectOptions::new(proxy.peer_timeout)
        .with_shutdown(shutdown)
        .with_listener(proxy.mode == Mode::Lockstep)
        .with_waiting_message(opts.verbose.then_some(waiting.as_str()));
    let ports: PlantPorts =
        ipc_types::ports::connect(&scenario.rig.name, own, "adaptive-rig-plant", copts)
            .map_err(PlantError::Connect)?;
    if opts.verbose {
        eprintln!(
            "[plant-proxy] connected; {} steps at {:.1} Hz in {:?} mode, inputs applied {}, late policy {}",
            steps,
            1.0 / ts,
            proxy.mode,
            applies.name(),
            proxy.describe_late_policy()
        );
    }

    let mut report = PlantReport {
        rig: scenario.rig.name.clone(),
        mode: format!("{:?}", proxy.mode),
        applies: applies.name().to_string(),
        rt_setup,
        faults_injected: proxy.faults.total() as u64,
        service_pid: ports.peer_pid(),
        ..Default::default()
    };
    if opts.verbose {
        eprintln!(
            "[plant-proxy] pinned to the service {}; actuations from any other process are refused",
            describe_pid(ports.peer_pid())
        );
    }
    let mut book = Box::new(ActuationBook::<AHEAD_CAPACITY>::new(
        n_u,
        proxy.miss_policy(),
    ));
    let mut y = vec![0.0; n_y];
    let mut z = vec![0.0; n_z];
    let mut r = vec![0.0; n_r];
    let mut u_applied = [0.0; MAX_U];
    u_applied[..n_u].copy_from_slice(&proxy.safe_input);
    let mut z_sum_sq = vec![0.0; n_z];
    let mut consecutive_misses = 0u64;
    let mut tripped = false;
    // What the next measurement says of the input applied for the previous sample.
    let mut previous_missed = false;
    let mut previous_plan = false;
    // The timing of the last actuation applied (wire value).
    let mut last_timing: Option<u32> = None;
    // Lockstep: when the watchdog tripped, and since when no valid actuation came.
    let mut tripped_at: Option<Instant> = None;
    let wall = Instant::now();
    let mut clock = SampleClock::new(
        monotonic_ns() + 2 * period_ns.max(1_000_000),
        period_ns,
        proxy.overrun,
    );
    // Real time at deadline 0: the input is latched at the sample clock, before the sample.
    let latch_at_sample = applies == ipc_types::ports::Applies::AtSample;
    let deadline_ns = match proxy.mode {
        Mode::RealTime => (proxy.deadline * period_ns as f64) as u64,
        Mode::Lockstep => 0,
    };

    for k in 0..steps {
        if shutdown.load(Ordering::Relaxed) {
            break;
        }
        // The flags of the period that ends at sample k.
        let mut flags = match proxy.mode {
            Mode::Lockstep => measurement_flags::LOCKSTEP,
            Mode::RealTime => 0,
        };
        if tripped {
            flags |= measurement_flags::PLANT_SAFE_OUTPUT;
        }
        if previous_missed {
            flags |= measurement_flags::PREVIOUS_ACTUATION_MISSED;
        }
        if previous_plan {
            flags |= measurement_flags::PLAN_APPLIED;
        }
        if k + 1 == steps {
            flags |= measurement_flags::LAST_SAMPLE;
        }
        let stalled = proxy.mode == Mode::Lockstep && proxy.faults.stalled(k);
        if stalled {
            flags |= measurement_flags::INJECTED_STALL;
        }
        // The input applied for sample k − 1, which this measurement reports.
        let u_reported = u_applied;
        let new_services_before = report.new_services;

        let mut decided = None;
        let t_k = match proxy.mode {
            Mode::RealTime => {
                let t = clock.wait(k);
                if latch_at_sample {
                    drain(&ports, &mut book, k, &mut report);
                    decided = Some(book.decide(k));
                }
                t
            }
            Mode::Lockstep => monotonic_ns(),
        };
        sim.sample(&mut y, &mut z, &mut r)
            .map_err(|e| PlantError::Config(e.to_string()))?;
        let mut m = Measurement::zeroed(counts);
        m.seq = k;
        m.t_sample_ns = t_k;
        m.period_ns = period_ns;
        m.deadline_ns = deadline_ns;
        m.flags = flags | measurement_flags::U_APPLIED;
        m.y[..n_y].copy_from_slice(&y);
        m.z[..n_z].copy_from_slice(&z);
        m.r[..n_r].copy_from_slice(&r);
        m.u_applied[..n_u].copy_from_slice(&u_reported[..n_u]);
        if let Some(v) = proxy.faults.at(k)
            && n_y > 0
        {
            m.y[0] = v;
        }
        for (s, v) in z_sum_sq.iter_mut().zip(&z) {
            *s += v * v;
        }
        let _ = ports.publisher.send_copy(m);
        let _ = ports.notifier.notify();
        report.samples += 1;
        report.stalls_injected += u64::from(stalled);

        // The input for sample k.
        let decision = match (decided, proxy.mode) {
            (Some(d), _) => d,
            (None, Mode::RealTime) => {
                sleep_until_ns(t_k + deadline_ns);
                drain(&ports, &mut book, k, &mut report);
                book.decide(k)
            }
            (None, Mode::Lockstep) => {
                let deadline = Instant::now() + proxy.lockstep_timeout;
                loop {
                    drain(&ports, &mut book, k, &mut report);
                    if book.answers(k) {
                        break;
                    }
                    let now = Instant::now();
                    if now >= deadline || shutdown.load(Ordering::Relaxed) {
                        break;
                    }
                    if let Some(l) = &ports.listener {
                        // At least 1 ms: iceoryx2 waits on a socket receive timeout, and a
                        // timeout that rounds down to 0 µs means "wait for ever" there (seen
                        // as a lockstep plant that never woke up once its service had died).
                        let wait = (deadline - now)
                            .clamp(Duration::from_millis(1), Duration::from_millis(10));
                        let _ = l.timed_wait(|_| {}, wait);
                    }
                }
                book.decide(k)
            }
        };
        if report.new_services != new_services_before {
            // A restarted service took over (rare: outside the per-sample path proper).
            let presence = ports.refresh_peer();
            report.service_pid = ports.peer_pid();
            eprintln!(
                "[plant-proxy] a new service ({}) answers at seq {k}: the plant is pinned to it now ({presence:?})",
                describe_pid(ports.peer_pid())
            );
        }
        if decision.is_miss() && shutdown.load(Ordering::Relaxed) {
            // Stopped while waiting: this sample was never answered nor applied.
            break;
        }
        let status = match decision {
            Decision::Answered { u, status, timing } => {
                report.actuations_applied += 1;
                tripped_at = None;
                consecutive_misses = 0;
                previous_missed = false;
                previous_plan = false;
                if tripped {
                    tripped = false;
                    report.watchdog_recoveries += 1;
                    eprintln!(
                        "[plant-proxy] valid actuation again at seq {k}: leaving the safe output"
                    );
                }
                u_applied[..n_u].copy_from_slice(&u[..n_u]);
                last_timing = Some(timing);
                status
            }
            miss => {
                report.misses += 1;
                consecutive_misses += 1;
                previous_missed = true;
                if !tripped && consecutive_misses >= proxy.watchdog_periods {
                    tripped = true;
                    report.watchdog_trips += 1;
                    eprintln!(
                        "[plant-proxy] WATCHDOG: no valid actuation for {consecutive_misses} periods (last at seq {}); applying the safe output",
                        k.saturating_sub(consecutive_misses)
                    );
                    let n = ipc_types::ports::cleanup_dead_nodes();
                    if n > 0 {
                        eprintln!(
                            "[plant-proxy] removed stale resources of {n} dead iceoryx2 node(s)"
                        );
                    }
                    if proxy.mode == Mode::Lockstep {
                        tripped_at = Some(Instant::now());
                        eprintln!(
                            "[plant-proxy] lockstep: waiting up to {:.1} s (proxy.peer-timeout) for a service to answer, then giving up",
                            proxy.peer_timeout.as_secs_f64()
                        );
                    }
                }
                // The watchdog's safe output overrides a plan as it overrides the rest.
                previous_plan = false;
                match (miss, tripped) {
                    (Decision::Plan { u, .. }, false) => {
                        u_applied[..n_u].copy_from_slice(&u[..n_u]);
                        previous_plan = true;
                        report.plan_entries_applied += 1;
                    }
                    (Decision::Safe, _) => {
                        u_applied[..n_u].copy_from_slice(&proxy.safe_input);
                        report.misses_held_or_safe += 1;
                    }
                    _ => report.misses_held_or_safe += 1,
                }
                if report.actuations_applied == 0 && !previous_plan {
                    report.misses_before_first_answer += 1;
                }
                if let Some(t) = tripped_at
                    && t.elapsed() >= proxy.peer_timeout
                {
                    finish(&mut report, &z_sum_sq, last_timing, &clock, &ports);
                    return Err(give_up(report, k, consecutive_misses, proxy, &ports, wall));
                }
                u32::MAX
            }
        };
        if tripped {
            u_applied[..n_u].copy_from_slice(&proxy.safe_input);
            report.safe_output_samples += 1;
        }
        if let Some(t) = trace.as_mut() {
            t.row(
                k,
                sim.time(),
                [&m.y[..n_y], &z, &u_applied[..n_u]],
                m.flags,
                status,
            );
        }
        sim.advance(&u_applied[..n_u])
            .map_err(|e| PlantError::Config(e.to_string()))?;
    }
    if let Some(mut t) = trace {
        t.out
            .flush()
            .map_err(|e| PlantError::Io(format!("writing the trace: {e}")))?;
    }
    finish(&mut report, &z_sum_sq, last_timing, &clock, &ports);
    report.wall_time_s = wall.elapsed().as_secs_f64();
    if opts.verbose || report.foreign_discarded > 0 || report.new_services > 0 {
        eprintln!("[plant-proxy] {}", trust_line(&report));
    }
    Ok(report)
}

/// Fills the report's end-of-run figures: RMS of `z`, the service's pid and timing, the
/// clock's slips.
fn finish(
    report: &mut PlantReport,
    z_sum_sq: &[f64],
    last_timing: Option<u32>,
    clock: &SampleClock,
    ports: &PlantPorts,
) {
    report.z_rms = z_sum_sq
        .iter()
        .map(|s| (s / report.samples.max(1) as f64).sqrt())
        .collect();
    report.service_pid = ports.peer_pid();
    report.timing = last_timing.map(|w| match Timing::from_wire(w) {
        Some(t) => t.name().to_string(),
        None => format!("unknown ({w})"),
    });
    report.clock_slips = clock.slips();
    report.slipped_s = clock.slipped_ns() as f64 * 1e-9;
}

/// "pid 1234" or "of unknown pid".
fn describe_pid(pid: Option<u32>) -> String {
    match pid {
        Some(p) => format!("pid {p}"),
        None => "of unknown pid".into(),
    }
}

/// The trust counters of a report, one line.
pub fn trust_line(r: &PlantReport) -> String {
    format!(
        "service {}: {} foreign actuation(s) refused, {} new service(s) during the run",
        describe_pid(r.service_pid),
        r.foreign_discarded,
        r.new_services
    )
}

/// The lockstep plant's end when no service answers after its watchdog tripped.
fn give_up(
    mut report: PlantReport,
    k: u64,
    misses: u64,
    proxy: &ProxyConfig,
    ports: &PlantPorts,
    wall: Instant,
) -> PlantError {
    report.wall_time_s = wall.elapsed().as_secs_f64();
    let presence = match ports.refresh_peer() {
        ipc_types::ports::PeerPresence::Present { pid } => {
            format!(
                "the service ({}) is still registered but silent",
                describe_pid(pid)
            )
        }
        ipc_types::ports::PeerPresence::Gone => "the service is gone".to_string(),
        ipc_types::ports::PeerPresence::Replaced { pid } => format!(
            "another service ({}) holds the actuation service but did not answer",
            describe_pid(pid)
        ),
    };
    let message = format!(
        "WATCHDOG: giving up in lockstep at seq {k}: no valid actuation for {misses} samples, and none for {:.1} s (proxy.peer-timeout) since the watchdog tripped; {presence}. {}",
        proxy.peer_timeout.as_secs_f64(),
        trust_line(&report)
    );
    eprintln!("[plant-proxy] {message}");
    report.gave_up = Some(message.clone());
    PlantError::GaveUp {
        message,
        report: Box::new(report),
    }
}

/// Offers every pending actuation to the book while the plant is at sample `k`, counting
/// foreign (not from the pinned service), late, invalid, dropped ones and stall
/// acknowledgements. A new service (the pinned one was replaced) starts a fresh book.
fn drain<const N: usize>(
    ports: &PlantPorts,
    book: &mut ActuationBook<N>,
    k: u64,
    report: &mut PlantReport,
) {
    while let Ok(Some(sample)) = ports.subscriber.receive() {
        match ports.admit(sample.origin()) {
            Origin::Peer => {}
            Origin::NewPeer => {
                report.new_services += 1;
                book.clear();
            }
            Origin::Foreign => {
                report.foreign_discarded += 1;
                continue;
            }
        }
        match book.offer(&sample, k) {
            Offer::Kept => {}
            Offer::KeptDropping { .. } => report.ahead_dropped += 1,
            Offer::Late => report.late_discarded += 1,
            Offer::Invalid => report.invalid_discarded += 1,
            Offer::StallAck => report.stall_acks += 1,
        }
    }
}
