//! The plant side of one connection: publish the measurement of sample `k`, take the input
//! for sample `k`.
//!
//! A plant process is the clock master of the contract. For each sample `k` it
//!
//! 1. reads its sensors at `t_k` and **publishes** `M_k = {seq k, t_k, y_k, z_k, r_k}`
//!    ([`PlantSide::publish`]), reporting the period that ends at `t_k`: the input applied
//!    for sample `k − 1` (`u_applied`), `PREVIOUS_ACTUATION_MISSED` when that was a miss,
//!    with `PLAN_APPLIED` when a plan covered it, and `PLANT_SAFE_OUTPUT` while the
//!    watchdog holds the safe output;
//! 2. **takes** the input for sample `k` at its application instant ([`PlantSide::take`]):
//!    the service's actuation with `seq = k` if it holds it then, else a **miss** resolved
//!    by the late policy ([`crate::late_policy`]: hold, safe, or the newest plan's entry).
//!    Which input that is, is decided by an [`ActuationBook`], which keeps the actuations
//!    received ahead of their sample (a service that sends ahead publishes `u_{k+1}` as soon
//!    as it has taken `y_k` in), refuses late and invalid ones, and holds the newest plan.
//!    The application instant is the caller's ([`Wait`]): at once (a DAC latched at the
//!    sample clock, `deadline = 0`: call `take` before `publish`), at `t_k + dT`, as soon as
//!    the answer is there (software-timed output), or in lockstep when the service has
//!    answered `M_k`.
//!
//! A **watchdog** puts the plant into its safe output after `watchdog-periods` consecutive
//! misses (plan-covered or not), says so, removes the stale resources of dead iceoryx2
//! nodes (so a restarted service can connect), and leaves the safe output on the next valid
//! actuation. In lockstep the plant does not wait for ever: when no service has answered
//! for `peer-timeout` after the watchdog tripped, [`PlantSide::take`] gives up with
//! [`PlantError::GaveUp`].
//!
//! Only the service the plant connected to drives it: its publisher is pinned at connect
//! (`ipc_types::peer`), an actuation from any other publisher is refused and counted, and
//! a restarted service, which can only appear once the old one's publisher is gone, is
//! recognized and counted; what the old one had sent is forgotten.
//!
//! `publish` and `take` do not allocate, and only sleep or wait as [`Wait`] says; messages
//! about the watchdog and a new service go to standard error (rare events, outside the
//! per-sample path proper). Connect and [`PlantSide::finish`] allocate.

use crate::actuation_book::{AHEAD_CAPACITY, ActuationBook, Decision, Offer};
use crate::plant_report::{PlantReport, RoundTrip};
use crate::policy::{Mode, PlantPolicy};
use hdrhistogram::Histogram;
use ipc_types::clock::{monotonic_ns, sleep_until_ns};
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectError, ConnectOptions, ContractInfo, PlantPorts, Side};
use ipc_types::timing_rules;
use ipc_types::{ChannelCounts, MAX_U, MAX_Z, Measurement, Timing, measurement_flags};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Why a plant side failed.
#[derive(Debug)]
pub enum PlantError {
    /// The policy, the counts or a call's arguments are not usable; the message names them.
    Config(String),
    /// Connecting to the service failed.
    Connect(ConnectError),
    /// The plant's I/O (a sensor, an actuator, a trace file) failed; the message says which.
    Io(String),
    /// Lockstep: no service answered for `peer-timeout` after the watchdog tripped; the
    /// plant gave up. The report of the run so far comes with it.
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

/// When [`PlantSide::take`] decides the input of sample `k`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait {
    /// Now, from what has arrived: a DAC latched at the sample clock (`deadline = 0`), where
    /// `take(k)` comes before `publish(k)`, or a caller that keeps its own time.
    Now,
    /// At the absolute `CLOCK_MONOTONIC` time (ns), whatever arrives before: the fixed
    /// application instant `t_k + dT` of a hold whose timing must not depend on the service.
    At(u64),
    /// As soon as the actuation for `k` is there, at the latest at the absolute time (ns):
    /// software-timed output that applies each answer when it comes.
    Until(u64),
    /// As [`Wait::Until`], polling without ever sleeping: a caller whose thread must not
    /// give up the CPU, such as an audio server's process callback that decides a block of
    /// samples within a budget ends at the absolute time (ns).
    Spin(u64),
    /// Until the service has answered (or acknowledged) `M_k`, at most the policy's
    /// `lockstep-timeout`.
    Lockstep,
    /// Lockstep, for a sample `k` that was not published (an injected loss) while `M_{k−1}`
    /// was: a service that sends ahead publishes the input for `k` with its answer to
    /// `M_{k−1}`, sometimes as the second of two actuations (after a gap, `M_{k−1}` gets an
    /// answer of its own first). Waits until that input is there, at most the policy's
    /// `lockstep-timeout`; decides at once when the service does not send ahead. So the
    /// input of a lost sample never depends on which of the two had arrived.
    LockstepAhead,
}

/// What the plant applies for one sample, from [`PlantSide::take`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Input {
    /// The input (entries past `n_u` are zero).
    pub u: [f64; MAX_U],
    /// Where it comes from.
    pub kind: InputKind,
    /// The applied actuation's status ([`ipc_types::actuation_status`]); `None` on a miss.
    pub status: Option<u32>,
    /// The flags measurement `k` was published with (0 when `take` came first).
    pub published_flags: u32,
}

/// Where the input of a sample comes from: [`ipc_types::timing_rules::Applied`] (the rule
/// [`ipc_types::timing_rules::applied`]).
pub use ipc_types::timing_rules::Applied as InputKind;

/// What one side says when it connects, besides its policy.
#[derive(Debug, Clone, Copy)]
pub struct PlantSideOptions<'a> {
    /// Prefix of the messages on standard error, e.g. `"plant-proxy"` or `"daq"`.
    pub label: &'a str,
    /// The iceoryx2 node name.
    pub node_name: &'a str,
    /// Print progress and events.
    pub verbose: bool,
    /// Set (from a signal handler) to abandon waits: connect, lockstep answers.
    pub shutdown: Option<&'a AtomicBool>,
}

impl<'a> PlantSideOptions<'a> {
    /// Messages prefixed `label`, node `adaptive-rig-plant`, not verbose, no shutdown flag.
    pub const fn new(label: &'a str) -> Self {
        Self {
            label,
            node_name: "adaptive-rig-plant",
            verbose: false,
            shutdown: None,
        }
    }
}

/// What the plant reports of one decided period in the next measurement.
#[derive(Debug, Clone, Copy)]
struct Period {
    u: [f64; MAX_U],
    kind: InputKind,
}

/// The plant side of one connection to the service. See the [module documentation](self).
pub struct PlantSide<'a> {
    ports: PlantPorts,
    counts: ChannelCounts,
    period_ns: u64,
    policy: PlantPolicy,
    label: String,
    verbose: bool,
    shutdown: Option<&'a AtomicBool>,
    book: Box<ActuationBook<AHEAD_CAPACITY>>,
    report: PlantReport,
    /// The latest decided period and the one before it, with the sample of the latest.
    latest: Period,
    before: Period,
    latest_k: Option<u64>,
    consecutive_misses: u64,
    tripped: bool,
    last_timing: Option<u32>,
    /// Lockstep: when the watchdog tripped (no valid actuation since).
    tripped_at: Option<Instant>,
    /// A new service appeared while draining: refresh the pin after the decision.
    repinned: bool,
    /// The flags of the latest measurement published, its sample and when it was sent.
    published: Option<(u64, u32)>,
    published_at_ns: u64,
    /// Round trips publish → answer, ns (allocated at connect; recording does not allocate).
    round_trip: Histogram<u64>,
    z_sum_sq: [f64; MAX_Z],
    wall: Instant,
}

impl<'a> PlantSide<'a> {
    /// Connects to the service of rig `rig` as its plant: `counts` channels, one sample
    /// every `period_ns`, applying inputs by `policy`. Waits up to `policy.peer_timeout` for
    /// the service; refuses one whose contract differs (version, counts, period, timing),
    /// naming each difference.
    pub fn connect(
        rig: &str,
        counts: ChannelCounts,
        period_ns: u64,
        policy: PlantPolicy,
        opts: PlantSideOptions<'a>,
    ) -> Result<Self, PlantError> {
        let n_u = counts.n_u as usize;
        policy
            .validate(n_u)
            .map_err(|m| PlantError::Config(format!("rig '{rig}': plant policy: {m}")))?;
        if period_ns == 0 {
            return Err(PlantError::Config(format!(
                "rig '{rig}': the sample period must be positive"
            )));
        }
        let applies = policy.applies();
        let own = ContractInfo::new(Side::Plant, counts, period_ns).with_applies(applies);
        let waiting = format!("[{}] rig '{rig}': waiting for the service ...", opts.label);
        let mut copts = ConnectOptions::new(policy.peer_timeout)
            .with_listener(policy.mode == Mode::Lockstep)
            .with_waiting_message(opts.verbose.then_some(waiting.as_str()));
        if let Some(s) = opts.shutdown {
            copts = copts.with_shutdown(s);
        }
        let ports: PlantPorts = ipc_types::ports::connect(rig, own, opts.node_name, copts)
            .map_err(PlantError::Connect)?;
        let mut u0 = [0.0; MAX_U];
        u0[..n_u].copy_from_slice(&policy.safe_input);
        let initial = Period {
            u: u0,
            kind: InputKind::Answered,
        };
        let report = PlantReport {
            rig: rig.to_string(),
            mode: match policy.mode {
                Mode::RealTime => "RealTime".into(),
                Mode::Lockstep => "Lockstep".into(),
            },
            applies: applies.name().to_string(),
            service_pid: ports.peer_pid(),
            ..Default::default()
        };
        let side = Self {
            book: Box::new(ActuationBook::new(n_u, policy.miss_policy())),
            ports,
            counts,
            period_ns,
            label: opts.label.to_string(),
            verbose: opts.verbose,
            shutdown: opts.shutdown,
            report,
            latest: initial,
            before: initial,
            latest_k: None,
            consecutive_misses: 0,
            tripped: false,
            last_timing: None,
            tripped_at: None,
            repinned: false,
            published: None,
            published_at_ns: 0,
            round_trip: Histogram::new_with_bounds(1, ROUND_TRIP_MAX_NS, 3)
                .map_err(|e| PlantError::Config(format!("round-trip histogram: {e}")))?,
            z_sum_sq: [0.0; MAX_Z],
            wall: Instant::now(),
            policy,
        };
        if side.verbose {
            eprintln!(
                "[{}] pinned to the service {}; actuations from any other process are refused",
                side.label,
                describe_pid(side.ports.peer_pid())
            );
        }
        Ok(side)
    }

    /// The channel counts.
    pub const fn counts(&self) -> ChannelCounts {
        self.counts
    }

    /// The sample period, ns.
    pub const fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// The prefix of its messages.
    pub fn label(&self) -> &str {
        &self.label
    }

    /// The policy.
    pub const fn policy(&self) -> &PlantPolicy {
        &self.policy
    }

    /// The counters so far.
    pub const fn report(&self) -> &PlantReport {
        &self.report
    }

    /// The counters so far, for the caller's own fields (`rt_setup`, `faults_injected`, the
    /// clock's slips).
    pub fn report_mut(&mut self) -> &mut PlantReport {
        &mut self.report
    }

    /// The deadline offset carried in each measurement, ns: `d·T` in real time, 0 in
    /// lockstep.
    pub fn deadline_offset_ns(&self) -> u64 {
        timing_rules::deadline_offset_ns(
            self.policy.mode == Mode::Lockstep,
            self.policy.deadline,
            self.period_ns,
        )
    }

    /// Publishes measurement `k` taken at `t_sample_ns` (`CLOCK_MONOTONIC`) with the sensor
    /// values `y`, `z`, `r` (exactly the connected counts) and `extra_flags`
    /// ([`measurement_flags::LAST_SAMPLE`] on the last sample of a run,
    /// [`measurement_flags::INJECTED_STALL`] in lockstep tests; others are the plant side's
    /// and ignored). Returns the flags published.
    pub fn publish(
        &mut self,
        k: u64,
        t_sample_ns: u64,
        [y, z, r]: [&[f64]; 3],
        extra_flags: u32,
    ) -> Result<u32, PlantError> {
        let c = self.counts;
        if y.len() != c.n_y as usize || z.len() != c.n_z as usize || r.len() != c.n_r as usize {
            return Err(PlantError::Config(format!(
                "publish: {} y, {} z, {} r value(s) for a plant of n_y = {}, n_z = {}, n_r = {}",
                y.len(),
                z.len(),
                r.len(),
                c.n_y,
                c.n_z,
                c.n_r
            )));
        }
        // The period that ends at sample k: the latest decided one, unless that is k's own
        // (the input was latched at the sample instant, before this measurement).
        let reported = if self.latest_k == Some(k) {
            self.before
        } else {
            self.latest
        };
        let mut flags = match self.policy.mode {
            Mode::Lockstep => measurement_flags::LOCKSTEP,
            Mode::RealTime => 0,
        };
        flags |= timing_rules::report_flags(reported.kind);
        flags |= extra_flags & measurement_flags::LAST_SAMPLE;
        let stalled = self.policy.mode == Mode::Lockstep
            && extra_flags & measurement_flags::INJECTED_STALL != 0;
        if stalled {
            flags |= measurement_flags::INJECTED_STALL;
        }
        let mut m = Measurement::zeroed(c);
        m.seq = k;
        m.t_sample_ns = t_sample_ns;
        m.period_ns = self.period_ns;
        m.deadline_ns = self.deadline_offset_ns();
        m.flags = flags | measurement_flags::U_APPLIED;
        m.y[..y.len()].copy_from_slice(y);
        m.z[..z.len()].copy_from_slice(z);
        m.r[..r.len()].copy_from_slice(r);
        let n_u = c.n_u as usize;
        m.u_applied[..n_u].copy_from_slice(&reported.u[..n_u]);
        for (s, v) in self.z_sum_sq.iter_mut().zip(z) {
            *s += v * v;
        }
        self.published_at_ns = monotonic_ns();
        let _ = self.ports.publisher.send_copy(m);
        let _ = self.ports.notifier.notify();
        self.report.samples += 1;
        self.report.stalls_injected += u64::from(stalled);
        self.published = Some((k, m.flags));
        Ok(m.flags)
    }

    /// Takes in actuations until `done` holds for the book, at most the policy's
    /// `lockstep-timeout` (or until shutdown); true when `done` held.
    fn lockstep_wait(
        &mut self,
        k: u64,
        done: impl Fn(&ActuationBook<AHEAD_CAPACITY>) -> bool,
    ) -> bool {
        let deadline = Instant::now() + self.policy.lockstep_timeout;
        loop {
            self.drain(k);
            if done(&self.book) {
                return true;
            }
            let now = Instant::now();
            if now >= deadline || self.stopping() {
                return false;
            }
            if let Some(l) = &self.ports.listener {
                // At least 1 ms: iceoryx2 waits on a socket receive timeout, and a timeout
                // that rounds down to 0 µs means "wait for ever" there (seen as a lockstep
                // plant that never woke up once its service had died).
                let wait =
                    (deadline - now).clamp(Duration::from_millis(1), Duration::from_millis(10));
                let _ = l.timed_wait(|_| {}, wait);
            } else {
                std::thread::sleep(Duration::from_micros(POLL_NS / 1000));
            }
        }
    }

    /// Decides the input for sample `k` when `wait` says ([`Wait`]), and updates the
    /// watchdog and the counters. `Ok(None)`: the shutdown flag was set while the sample was
    /// still unanswered (it was neither decided nor applied). Call it once per sample, `k`
    /// increasing.
    pub fn take(&mut self, k: u64, wait: Wait) -> Result<Option<Input>, PlantError> {
        let decision = match wait {
            Wait::Now => {
                self.drain(k);
                self.book.decide(k)
            }
            Wait::At(t) => {
                sleep_until_ns(t);
                self.drain(k);
                self.book.decide(k)
            }
            Wait::Until(t) | Wait::Spin(t) => {
                let sleeps = matches!(wait, Wait::Until(_));
                let mut waited = false;
                loop {
                    self.drain(k);
                    if self.book.holds(k) {
                        self.time_round_trip(k, waited);
                        break;
                    }
                    waited = true;
                    if monotonic_ns() >= t || self.stopping() {
                        break;
                    }
                    if sleeps {
                        sleep_until_ns(t.min(monotonic_ns() + POLL_NS));
                    } else {
                        std::hint::spin_loop();
                    }
                }
                self.book.decide(k)
            }
            Wait::Lockstep => {
                if self.lockstep_wait(k, |book| book.answers(k)) {
                    self.time_round_trip(k, false);
                }
                self.book.decide(k)
            }
            Wait::LockstepAhead => {
                self.lockstep_wait(k, |book| !book.sends_ahead() || book.holds(k));
                self.book.decide(k)
            }
        };
        if self.repinned {
            // A restarted service took over (rare: outside the per-sample path proper).
            self.repinned = false;
            let presence = self.ports.refresh_peer();
            self.report.service_pid = self.ports.peer_pid();
            eprintln!(
                "[{}] a new service ({}) answers at seq {k}: the plant is pinned to it now ({presence:?})",
                self.label,
                describe_pid(self.ports.peer_pid())
            );
        }
        if decision.is_miss() && self.stopping() {
            // Stopped while waiting: this sample was never answered nor applied.
            return Ok(None);
        }
        let input = self.resolve(k, decision)?;
        Ok(Some(input))
    }

    /// Counts the decision, runs the watchdog and records the period for the next
    /// measurement.
    fn resolve(&mut self, k: u64, decision: Decision) -> Result<Input, PlantError> {
        let n_u = self.counts.n_u as usize;
        let mut u = self.latest.u;
        let mut status = None;
        if let Decision::Answered {
            u: answer,
            status: s,
            timing,
        } = decision
        {
            self.report.actuations_applied += 1;
            self.tripped_at = None;
            self.consecutive_misses = 0;
            if self.tripped {
                self.tripped = false;
                self.report.watchdog_recoveries += 1;
                eprintln!(
                    "[{}] valid actuation again at seq {k}: leaving the safe output",
                    self.label
                );
            }
            u[..n_u].copy_from_slice(&answer[..n_u]);
            self.last_timing = Some(timing);
            status = Some(s);
        } else {
            self.report.misses += 1;
            self.consecutive_misses += 1;
            if timing_rules::watchdog_trips(
                self.tripped,
                self.consecutive_misses,
                self.policy.watchdog_periods,
            ) {
                self.trip(k);
            }
        }
        // The watchdog's safe output overrides a plan as it overrides the rest.
        let kind = timing_rules::applied(decision.miss_input(), self.tripped);
        match (kind, decision) {
            (InputKind::Plan, Decision::Plan { u: entry, .. }) => {
                u[..n_u].copy_from_slice(&entry[..n_u]);
                self.report.plan_entries_applied += 1;
            }
            (InputKind::Safe | InputKind::WatchdogSafe, _) => {
                u[..n_u].copy_from_slice(&self.policy.safe_input);
            }
            _ => {}
        }
        if kind.is_miss() && kind != InputKind::Plan {
            self.report.misses_held_or_safe += 1;
        }
        if kind.is_miss() {
            if self.report.actuations_applied == 0 && kind != InputKind::Plan {
                self.report.misses_before_first_answer += 1;
            }
            if let Some(t) = self.tripped_at
                && t.elapsed() >= self.policy.peer_timeout
            {
                return Err(self.give_up(k));
            }
        }
        if kind == InputKind::WatchdogSafe {
            self.report.safe_output_samples += 1;
        }
        self.before = self.latest;
        self.latest = Period { u, kind };
        self.latest_k = Some(k);
        let published_flags = match self.published {
            Some((p, flags)) if p == k => flags,
            _ => 0,
        };
        Ok(Input {
            u,
            kind,
            status,
            published_flags,
        })
    }

    fn trip(&mut self, k: u64) {
        self.tripped = true;
        self.report.watchdog_trips += 1;
        eprintln!(
            "[{}] WATCHDOG: no valid actuation for {} periods (last at seq {}); applying the safe output",
            self.label,
            self.consecutive_misses,
            k.saturating_sub(self.consecutive_misses)
        );
        let n = ipc_types::ports::cleanup_dead_nodes();
        if n > 0 {
            eprintln!(
                "[{}] removed stale resources of {n} dead iceoryx2 node(s)",
                self.label
            );
        }
        if self.policy.mode == Mode::Lockstep {
            self.tripped_at = Some(Instant::now());
            eprintln!(
                "[{}] lockstep: waiting up to {:.1} s (proxy.peer-timeout) for a service to answer, then giving up",
                self.label,
                self.policy.peer_timeout.as_secs_f64()
            );
        }
    }

    /// Records the round trip of `M_k` when it was the latest measurement published; with
    /// a service that sends ahead, also that of `M_{k−1}` (whose answer carries `u_k`) when
    /// the plant `waited` for it after publishing `M_{k−1}` (a caller that takes `u_k` before
    /// publishing `M_k`, deciding a block of samples at once).
    fn time_round_trip(&mut self, k: u64, waited: bool) {
        let ahead = waited && self.book.sends_ahead();
        if matches!(self.published, Some((p, _)) if p == k || (ahead && p + 1 == k)) {
            let dt = monotonic_ns().saturating_sub(self.published_at_ns);
            self.round_trip.saturating_record(dt.max(1));
        }
    }

    fn stopping(&self) -> bool {
        self.shutdown.is_some_and(|s| s.load(Ordering::Relaxed))
    }

    /// Offers every pending actuation to the book while the plant is at sample `k`,
    /// counting foreign (not from the pinned service), late, invalid, dropped ones and stall
    /// acknowledgements. A new service (the pinned one was replaced) starts a fresh book.
    fn drain(&mut self, k: u64) {
        while let Ok(Some(sample)) = self.ports.subscriber.receive() {
            match self.ports.admit(sample.origin()) {
                Origin::Peer => {}
                Origin::NewPeer => {
                    self.report.new_services += 1;
                    self.repinned = true;
                    self.book.clear();
                }
                Origin::Foreign => {
                    self.report.foreign_discarded += 1;
                    continue;
                }
            }
            match self.book.offer(&sample, k) {
                Offer::Kept => {}
                Offer::KeptDropping { .. } => self.report.ahead_dropped += 1,
                Offer::Late => self.report.late_discarded += 1,
                Offer::Invalid => self.report.invalid_discarded += 1,
                Offer::StallAck => self.report.stall_acks += 1,
            }
        }
    }

    /// The report so far with its end-of-run figures (RMS of `z`, the service's pid and
    /// timing, the round trip, the wall time since connect), without ending the run.
    /// Allocates: not for the per-sample path.
    pub fn snapshot(&self) -> PlantReport {
        let mut r = self.report.clone();
        let n_z = self.counts.n_z as usize;
        let samples = r.samples.max(1) as f64;
        r.z_rms = self.z_sum_sq[..n_z]
            .iter()
            .map(|s| (s / samples).sqrt())
            .collect();
        r.service_pid = self.ports.peer_pid();
        r.timing = self.last_timing.map(|w| match Timing::from_wire(w) {
            Some(t) => t.name().to_string(),
            None => format!("unknown ({w})"),
        });
        r.wall_time_s = self.wall.elapsed().as_secs_f64();
        let h = &self.round_trip;
        r.round_trip = (!h.is_empty()).then(|| RoundTrip {
            samples: h.len(),
            p50_us: h.value_at_quantile(0.5) as f64 * 1e-3,
            p99_us: h.value_at_quantile(0.99) as f64 * 1e-3,
            max_us: h.max() as f64 * 1e-3,
        });
        r
    }

    /// Ends the run: the report with its end-of-run figures. Printed trust counters when
    /// verbose, or when a foreign actuation was refused or a new service appeared.
    pub fn finish(mut self) -> PlantReport {
        self.report = self.snapshot();
        if self.verbose || self.report.foreign_discarded > 0 || self.report.new_services > 0 {
            eprintln!("[{}] {}", self.label, trust_line(&self.report));
        }
        self.report
    }

    /// The lockstep plant's end when no service answers after its watchdog tripped.
    fn give_up(&mut self, k: u64) -> PlantError {
        self.report = self.snapshot();
        let presence = match self.ports.refresh_peer() {
            ipc_types::ports::PeerPresence::Present { pid } => format!(
                "the service ({}) is still registered but silent",
                describe_pid(pid)
            ),
            ipc_types::ports::PeerPresence::Gone => "the service is gone".to_string(),
            ipc_types::ports::PeerPresence::Replaced { pid } => format!(
                "another service ({}) holds the actuation service but did not answer",
                describe_pid(pid)
            ),
        };
        let message = format!(
            "WATCHDOG: giving up in lockstep at seq {k}: no valid actuation for {} samples, and none for {:.1} s (proxy.peer-timeout) since the watchdog tripped; {presence}. {}",
            self.consecutive_misses,
            self.policy.peer_timeout.as_secs_f64(),
            trust_line(&self.report)
        );
        eprintln!("[{}] {message}", self.label);
        self.report.gave_up = Some(message.clone());
        PlantError::GaveUp {
            message,
            report: Box::new(self.report.clone()),
        }
    }
}

/// The largest round trip the histogram tells apart, ns (longer ones count as this).
const ROUND_TRIP_MAX_NS: u64 = 10_000_000_000;

/// How often [`Wait::Until`] (and a lockstep wait without a listener) looks for the answer.
const POLL_NS: u64 = 20_000;

/// "pid 1234" or "of unknown pid".
pub fn describe_pid(pid: Option<u32>) -> String {
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
