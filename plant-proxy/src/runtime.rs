//! The plant process: the clock master of the contract.
//!
//! At sample `k` the plant publishes `y_k`, `z_k`, `r_k` stamped with the sample time, then
//! takes the service's actuation `u_k` and advances the simulation to `k+1`:
//!
//! - **real-time mode**: samples are paced on `CLOCK_MONOTONIC` at `t_k = t_0 + kT`. The
//!   actuation must arrive by the deadline `t_k + dT` (`proxy.deadline = d`, a fraction of
//!   the period); the plant sleeps until then and takes the actuation with sequence number
//!   `k`. One that is absent or late (it answers an older sample) is a miss: the plant holds
//!   the last input or applies the safe input (`proxy.late-policy`). The simulation applies
//!   `u_k` over `[kT, (k+1)T)` as in the dissertation (`proxy.intersample = "ideal"`), or
//!   from `kT + dT` on, as the real hold would (`"at-deadline"`).
//! - **lockstep mode**: the plant waits (on the service's event) until actuation `k` has
//!   arrived, then advances; as fast as possible and bit-for-bit deterministic for a seed.
//!   An actuation that does not come within `proxy.lockstep-timeout` counts as a miss.
//!
//! A watchdog puts the plant into its safe output after `proxy.watchdog-periods`
//! consecutive misses, says so, removes the stale resources of dead iceoryx2 nodes (so a
//! restarted service can connect), and leaves the safe output on the next valid actuation.
//! In lockstep mode the plant does not wait for ever: when no service has answered for
//! `proxy.peer-timeout` after the watchdog tripped (the time a service is given to connect
//! at start-up), it gives up with [`PlantError::GaveUp`] (a non-zero exit status).
//!
//! Only the service the plant connected to drives it: its publisher is pinned at connect
//! (`ipc_types::peer`), an actuation from any other publisher is refused and counted
//! ([`PlantReport::foreign_discarded`]), and a restarted service, which can only appear once
//! the old one's publisher is gone, is recognized and counted ([`PlantReport::new_services`]).
//! `[proxy.faults]` injects NaN, ±Inf and out-of-range measurements at given samples, for
//! testing the service's input validation.

use crate::scenario::Scenario;
use crate::sim::PlantSim;
use ipc_types::clock::{monotonic_ns, sleep_until_ns};
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::rt::RtRequest;
use ipc_types::{
    Actuation, CONTRACT_VERSION, ChannelCounts, MAX_U, Measurement, measurement_flags,
};
use serde::{Deserialize, Serialize};
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How the plant paces itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    /// Paced on `CLOCK_MONOTONIC` at the sample period.
    RealTime,
    /// Advance when actuation `k` has arrived.
    Lockstep,
}

/// What the plant applies when an actuation is missing or late.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LatePolicy {
    /// Keep the last applied input.
    Hold,
    /// Apply the safe input.
    Safe,
}

/// When a new input takes effect inside the period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Intersample {
    /// `u_k` over `[kT, (k+1)T)`: the dissertation's sampled-data assumption.
    Ideal,
    /// `u_{k-1}` until `kT + dT`, then `u_k`: what the real hold does with a deadline offset.
    AtDeadline,
}

/// Measurement faults to inject (by sample index).
#[derive(Debug, Clone, Default, PartialEq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub struct Faults {
    /// Samples whose first measurement channel is NaN.
    #[serde(default)]
    pub nan_at: Vec<u64>,
    /// Samples whose first measurement channel is +Inf.
    #[serde(default)]
    pub inf_at: Vec<u64>,
    /// Samples whose first measurement channel is -Inf.
    #[serde(default)]
    pub neg_inf_at: Vec<u64>,
    /// Samples whose first measurement channel is `out-of-range-value`.
    #[serde(default)]
    pub out_of_range_at: Vec<u64>,
    /// The value used for `out-of-range-at`.
    #[serde(default = "default_oor")]
    pub out_of_range_value: f64,
}

fn default_oor() -> f64 {
    1e6
}

impl Faults {
    fn total(&self) -> usize {
        self.nan_at.len() + self.inf_at.len() + self.neg_inf_at.len() + self.out_of_range_at.len()
    }
    /// The injected value at sample `k`, if any.
    fn at(&self, k: u64) -> Option<f64> {
        if self.nan_at.contains(&k) {
            Some(f64::NAN)
        } else if self.inf_at.contains(&k) {
            Some(f64::INFINITY)
        } else if self.neg_inf_at.contains(&k) {
            Some(f64::NEG_INFINITY)
        } else if self.out_of_range_at.contains(&k) {
            Some(self.out_of_range_value)
        } else {
            None
        }
    }
}

#[derive(Debug, Clone, Default, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
struct RawProxy {
    mode: Option<Mode>,
    deadline: Option<f64>,
    late_policy: Option<LatePolicy>,
    intersample: Option<Intersample>,
    safe_input: Option<Vec<f64>>,
    watchdog_periods: Option<u64>,
    lockstep_timeout: Option<f64>,
    peer_timeout: Option<f64>,
    core: Option<usize>,
    fifo_priority: Option<i32>,
    mlockall: Option<bool>,
    faults: Option<Faults>,
}

/// The `[proxy]` table of a scenario: how plant-proxy runs the plant.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyConfig {
    /// Pacing.
    pub mode: Mode,
    /// Deadline offset as a fraction of the period, in (0, 1].
    pub deadline: f64,
    /// Input on a miss.
    pub late_policy: LatePolicy,
    /// When a new input takes effect in the simulation.
    pub intersample: Intersample,
    /// The safe input, one per control input.
    pub safe_input: Vec<f64>,
    /// Consecutive misses that trip the watchdog.
    pub watchdog_periods: u64,
    /// Lockstep: how long to wait for an actuation before counting a miss.
    pub lockstep_timeout: Duration,
    /// How long to wait for the service at start.
    pub peer_timeout: Duration,
    /// Real-time set-up of the plant thread (real-time mode only).
    pub rt: RtRequest,
    /// Faults to inject.
    pub faults: Faults,
}

/// A refused `[proxy]` table.
#[derive(Debug, Clone, PartialEq)]
pub struct ProxyConfigError(pub String);

impl fmt::Display for ProxyConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ProxyConfigError {}

impl ProxyConfig {
    /// Reads the `[proxy]` table from the scenario text (defaults when absent).
    pub fn parse(text: &str, origin: &str, n_u: usize) -> Result<Self, ProxyConfigError> {
        let err = |field: &str, m: String| {
            ProxyConfigError(format!("{origin}: field 'proxy.{field}': {m}"))
        };
        let table: toml::Table = toml::from_str(text)
            .map_err(|e| ProxyConfigError(format!("{origin}: not valid TOML: {e}")))?;
        let raw: RawProxy = match table.get("proxy") {
            None => RawProxy::default(),
            Some(v) => v.clone().try_into().map_err(|e: toml::de::Error| {
                ProxyConfigError(format!("{origin}: table 'proxy': {e}"))
            })?,
        };
        let deadline = raw.deadline.unwrap_or(0.5);
        if !(deadline > 0.0 && deadline <= 1.0) {
            return Err(err(
                "deadline",
                format!("{deadline} is not a fraction of the period in (0, 1]"),
            ));
        }
        let safe_input = raw.safe_input.unwrap_or_else(|| vec![0.0; n_u]);
        if safe_input.len() != n_u || safe_input.iter().any(|v| !v.is_finite()) {
            return Err(err(
                "safe-input",
                format!("needs {n_u} finite values (one per control input)"),
            ));
        }
        let watchdog_periods = raw.watchdog_periods.unwrap_or(100);
        if watchdog_periods == 0 {
            return Err(err("watchdog-periods", "must be at least 1".into()));
        }
        const MAX_WAIT_S: f64 = 86_400.0;
        let secs = |v: Option<f64>, d: f64, f: &str| {
            let v = v.unwrap_or(d);
            // A day at most: longer waits are a typo, and the conversion stays exact.
            if v.is_finite() && v > 0.0 && v <= MAX_WAIT_S {
                Ok(Duration::from_secs_f64(v))
            } else {
                Err(err(f, format!("{v} s is not in (0, {MAX_WAIT_S}] s")))
            }
        };
        let fifo_priority = ipc_types::rt::fifo_priority_from_config(raw.fifo_priority, 70)
            .map_err(|m| err("fifo-priority", m))?;
        Ok(Self {
            mode: raw.mode.unwrap_or(Mode::RealTime),
            deadline,
            late_policy: raw.late_policy.unwrap_or(LatePolicy::Hold),
            intersample: raw.intersample.unwrap_or(Intersample::Ideal),
            safe_input,
            watchdog_periods,
            lockstep_timeout: secs(raw.lockstep_timeout, 1.0, "lockstep-timeout")?,
            peer_timeout: secs(raw.peer_timeout, 30.0, "peer-timeout")?,
            rt: RtRequest {
                core: raw.core,
                fifo_priority,
                mlockall: raw.mlockall.unwrap_or(true),
                prefault_stack_bytes: 256 * 1024,
            },
            faults: raw.faults.unwrap_or_default(),
        })
    }
}

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

/// Counters and results of a plant run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PlantReport {
    /// Rig name.
    pub rig: String,
    /// Mode used.
    pub mode: String,
    /// Samples published.
    pub samples: u64,
    /// Valid actuations applied.
    pub actuations_applied: u64,
    /// Samples without a valid actuation by the deadline (or timeout).
    pub misses: u64,
    /// Actuations that arrived after their deadline (answering an older sample).
    pub late_discarded: u64,
    /// Actuations refused (other contract, counts, or non-finite u).
    pub invalid_discarded: u64,
    /// Actuations refused because they did not come from the pinned service (a foreign
    /// publisher, or a replaced service's leftovers).
    pub foreign_discarded: u64,
    /// Times a new service replaced the one the plant was connected to.
    pub new_services: u64,
    /// The pid of the service the plant is pinned to at the end of the run, when known.
    pub service_pid: Option<u32>,
    /// Watchdog trips.
    pub watchdog_trips: u64,
    /// Recoveries from the safe output.
    pub watchdog_recoveries: u64,
    /// Samples spent in the safe output.
    pub safe_output_samples: u64,
    /// Faults injected.
    pub faults_injected: u64,
    /// Real-time set-up outcome.
    pub rt_setup: String,
    /// RMS of each performance channel (noise included).
    pub z_rms: Vec<f64>,
    /// Wall time of the run, s.
    pub wall_time_s: f64,
    /// Set when the lockstep plant gave up ([`PlantError::GaveUp`]): why. `None` for a run
    /// that ended at its last sample or on a signal.
    pub gave_up: Option<String>,
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
    let ts = scenario.rig.sample_period;
    let period_ns = (ts * 1e9).round() as u64;
    let mut sim =
        PlantSim::new(&scenario.plant, ts).map_err(|e| PlantError::Config(e.to_string()))?;
    if proxy.intersample == Intersample::AtDeadline && proxy.deadline < 1.0 {
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

    let own = ContractInfo::new(Side::Plant, counts, period_ns);
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
            "[plant-proxy] connected; {} steps at {:.1} Hz in {:?} mode",
            steps,
            1.0 / ts,
            proxy.mode
        );
    }

    let mut report = PlantReport {
        rig: scenario.rig.name.clone(),
        mode: format!("{:?}", proxy.mode),
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
    let mut y = vec![0.0; n_y];
    let mut z = vec![0.0; n_z];
    let mut r = vec![0.0; n_r];
    let mut u_applied = [0.0; MAX_U];
    u_applied[..n_u].copy_from_slice(&proxy.safe_input);
    let mut z_sum_sq = vec![0.0; n_z];
    let mut consecutive_misses = 0u64;
    let mut tripped = false;
    let mut previous_missed = false;
    // Lockstep: when the watchdog tripped, and since when no valid actuation came.
    let mut tripped_at: Option<Instant> = None;
    let wall = Instant::now();
    let t0 = monotonic_ns() + 2 * period_ns.max(1_000_000);

    for k in 0..steps {
        if shutdown.load(Ordering::Relaxed) {
            break;
        }
        let t_k = match proxy.mode {
            Mode::RealTime => {
                let t = t0 + k * period_ns;
                sleep_until_ns(t);
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
        m.deadline_ns = match proxy.mode {
            Mode::RealTime => (proxy.deadline * period_ns as f64) as u64,
            Mode::Lockstep => 0,
        };
        m.flags = match proxy.mode {
            Mode::Lockstep => measurement_flags::LOCKSTEP,
            Mode::RealTime => 0,
        };
        if tripped {
            m.flags |= measurement_flags::PLANT_SAFE_OUTPUT;
        }
        if previous_missed {
            m.flags |= measurement_flags::PREVIOUS_ACTUATION_MISSED;
        }
        if k + 1 == steps {
            m.flags |= measurement_flags::LAST_SAMPLE;
        }
        m.y[..n_y].copy_from_slice(&y);
        m.z[..n_z].copy_from_slice(&z);
        m.r[..n_r].copy_from_slice(&r);
        m.u_applied[..n_u].copy_from_slice(&u_applied[..n_u]);
        m.flags |= measurement_flags::U_APPLIED;
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
        let new_services_before = report.new_services;

        // Collect the answer to sample k.
        let answer = match proxy.mode {
            Mode::RealTime => {
                sleep_until_ns(t_k + m.deadline_ns);
                drain_for(&ports, k, counts, &mut report)
            }
            Mode::Lockstep => {
                let deadline = Instant::now() + proxy.lockstep_timeout;
                loop {
                    if let Some(a) = drain_for(&ports, k, counts, &mut report) {
                        break Some(a);
                    }
                    let now = Instant::now();
                    if now >= deadline || shutdown.load(Ordering::Relaxed) {
                        break None;
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
        if answer.is_none() && shutdown.load(Ordering::Relaxed) {
            // Stopped while waiting: this sample was never answered nor applied.
            break;
        }
        let status = match answer {
            Some(a) => {
                report.actuations_applied += 1;
                tripped_at = None;
                consecutive_misses = 0;
                previous_missed = false;
                if tripped {
                    tripped = false;
                    report.watchdog_recoveries += 1;
                    eprintln!(
                        "[plant-proxy] valid actuation again at seq {k}: leaving the safe output"
                    );
                }
                u_applied[..n_u].copy_from_slice(&a.u[..n_u]);
                a.status
            }
            None => {
                report.misses += 1;
                consecutive_misses += 1;
                previous_missed = true;
                if proxy.late_policy == LatePolicy::Safe {
                    u_applied[..n_u].copy_from_slice(&proxy.safe_input);
                }
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
                if let Some(t) = tripped_at
                    && t.elapsed() >= proxy.peer_timeout
                {
                    report.service_pid = ports.peer_pid();
                    report.z_rms = z_sum_sq
                        .iter()
                        .map(|s| (s / report.samples.max(1) as f64).sqrt())
                        .collect();
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
    report.z_rms = z_sum_sq
        .iter()
        .map(|s| (s / report.samples.max(1) as f64).sqrt())
        .collect();
    report.wall_time_s = wall.elapsed().as_secs_f64();
    report.service_pid = ports.peer_pid();
    if opts.verbose || report.foreign_discarded > 0 || report.new_services > 0 {
        eprintln!("[plant-proxy] {}", trust_line(&report));
    }
    Ok(report)
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

/// Drains the actuation subscriber; returns the valid actuation for sample `k`, counting
/// foreign (not from the pinned service), late and invalid ones.
fn drain_for(
    ports: &PlantPorts,
    k: u64,
    counts: ChannelCounts,
    report: &mut PlantReport,
) -> Option<Actuation> {
    let mut found = None;
    while let Ok(Some(sample)) = ports.subscriber.receive() {
        match ports.admit(sample.origin()) {
            Origin::Peer => {}
            Origin::NewPeer => report.new_services += 1,
            Origin::Foreign => {
                report.foreign_discarded += 1;
                continue;
            }
        }
        let a: Actuation = *sample;
        let n_u = counts.n_u as usize;
        let valid = a.contract_version == CONTRACT_VERSION
            && a.counts.n_u == counts.n_u
            && a.u[..n_u].iter().all(|v| v.is_finite());
        if !valid {
            report.invalid_discarded += 1;
        } else if a.seq == k {
            found = Some(a);
        } else if a.seq < k {
            report.late_discarded += 1;
        }
    }
    found
}
