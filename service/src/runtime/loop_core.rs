//! The pure per-sample logic of the RT loop: admission, sessions, the deadline policy and
//! the reset policy composed around the controller, with every buffer pre-allocated. How a
//! sample is answered under each `service.timing` is in [`answer`].

use super::checkpoint_slot::{CheckpointMark, CheckpointSlot, Offered};
use super::deadline::DeadlineMonitor;
use super::gate::MeasurementGate;
use super::live_tap::LiveTap;
use super::operator::OperatorInbox;
use super::reset::{ControllerResetPolicy, ResetCause, TimingFaultReset};
use super::sent::SentLog;
use super::session::{Arrival, Idle, SessionTracker};
use super::tones::ToneMeter;
use super::{LoopEvent, LoopStats};
use super::{force_regulation, model_following, verdict};
use crate::config::ServiceConfig;
use crate::logging::{LogProducer, LogRecord};
use crate::record::Recorder;
use crate::telemetry::TelemetryRt;
use control::controller::{Controller, MAX_INTERNALS, StepInput};
use ipc_types::timing_rules::{self, Reported};
use ipc_types::{
    Actuation, CONTRACT_VERSION, ChannelCounts, MAX_PLAN, MAX_U, MAX_Z, Measurement, Timing,
    actuation_status, measurement_flags,
};
use std::sync::Arc;

mod answer;
mod command;
mod live;

// Every plan row the contract carries can be filled by a controller's plan.
const _: () = assert!(control::ahead::MAX_PLAN_ROWS >= MAX_PLAN);

/// The pure per-sample logic of the RT loop, all buffers pre-allocated. The IPC glue
/// around it only receives and calls [`LoopCore::handle`] (or [`LoopCore::observe`] for a
/// sample taken in too late), which publish through an [`Outbox`].
///
/// It composes the policies, each a plain-data type with no I/O and no clock of its own:
/// the [`MeasurementGate`] (which samples may reach the controller), the
/// [`SessionTracker`] (sequence numbers, silence, stall or new plant), the
/// [`DeadlineMonitor`] (misses, safe state) and the [`ControllerResetPolicy`] (what a
/// fault does to what the controller learned).
pub struct LoopCore {
    controller: Box<dyn Controller>,
    telemetry: TelemetryRt,
    log: Option<LogProducer>,
    events: rtrb::Producer<LoopEvent>,
    counts: ChannelCounts,
    gate: MeasurementGate,
    session: SessionTracker,
    deadline: DeadlineMonitor,
    resets: ControllerResetPolicy,
    safe_input: [f64; MAX_U],
    /// The last input published (held when a measurement is rejected).
    last_u: [f64; MAX_U],
    scratch_u: [f64; MAX_U],
    /// The timing the loop runs ([`Timing::ComputeFirst`] when the controller has no ahead
    /// form) and the plan entries per answer.
    timing: Timing,
    plan_length: usize,
    /// The ahead answer prepared by the last `advance`: `u`, plan, status, compute time.
    prepared: Actuation,
    /// The prepared answer's plan is still to be made (its last `advance` did not adapt).
    plan_pending: bool,
    /// The actuation being composed.
    outgoing: Actuation,
    /// The controller's plan rows (`MAX_PLAN × n_u`).
    plan_rows: Vec<f64>,
    /// What was published for the last samples.
    sent: SentLog,
    open_loop_cycles: u64,
    /// Windows of `z` for the per-tone report.
    pub tones: ToneMeter,
    /// The model-following error norm (4.85), for a controller that follows a model.
    pub following: model_following::ModelFollowing,
    /// The contact phases of a force-regulating rig (`service.report.force-regulation`).
    pub force: force_regulation::ForceRegulation,
    pub(super) period_ns: u64,
    silent_periods: u64,
    rms_settle_cycles: u64,
    /// Counters, readable at any time.
    pub stats: LoopStats,
    z_sum_sq: [f64; MAX_Z],
    z_sum_sq_settled: [f64; MAX_Z],
    z_count: u64,
    z_count_settled: u64,
    record: LogRecord,
    internals: [f64; MAX_INTERNALS],
    pending_jitter: Option<u64>,
    /// The next sample comes from another publisher than the previous one.
    new_peer_pending: bool,
    /// The sample being answered has a possible sample time.
    timestamp_ok: bool,
    u_applied_tolerance: f64,
    /// The previous sample's `u_applied` report was a mismatch.
    foreign_run: bool,
    /// Sequence number at the last entry into the safe state.
    safe_since_seq: u64,
    recover_after: Option<u64>,
    recover_tolerance: u64,
    /// Allocations made on the RT thread during the loop (filled in when it ends).
    pub rt_allocations: crate::rt_alloc::RtAllocStats,
    /// What the pacer's awake-share cap did (filled in when the loop ends).
    pub pacing: super::pacing::PacingReport,
    /// Where checkpoints go to the writer (`None`: none are taken during the run).
    checkpoints: Option<Arc<CheckpointSlot>>,
    checkpoint_every: u64,
    cycles_since_checkpoint: u64,
    /// Where every input and output of the loop goes for `record.bin` ([`crate::record`]).
    recorder: Option<Recorder>,
    /// Refused samples already accounted for by [`LoopCore::count_past_startup`].
    refusals_counted: u64,
    /// Where operator commands come from and their results go ([`operator`](super::operator)).
    operator: Option<OperatorInbox>,
    /// The operator holds the loop in its safe state.
    operator_safe: bool,
    /// The operator froze the controller's adaptation.
    adaptation_frozen: bool,
    /// The operator asked the run to end.
    stop_requested: bool,
    /// Where the live view's samples and state go ([`live_tap`](super::live_tap)).
    live: Option<LiveTap>,
    /// The last sample came from a lockstep plant.
    lockstep: bool,
}

/// What [`LoopCore::handle`] did with one sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CycleDecision {
    /// Compute time of the controller in this cycle (0 when it did not run).
    pub compute_ns: u64,
    /// The plant says this was its last sample.
    pub last_sample: bool,
    /// The sample was answered. A refused sample (a duplicate, a backward number, an
    /// unexplained jump) and a sample of an injected stall are not.
    pub answer: bool,
}

/// Where the loop's actuations go: the iceoryx2 publisher of the service
/// ([`rt_loop`](super::rt_loop)), a recorder in tests.
pub trait Outbox {
    /// Publishes `act`, stamping its `t_publish_ns`; returns whether it was sent and the
    /// time just after. Must not allocate, block or panic.
    fn publish(&mut self, act: &mut Actuation) -> (bool, u64);
}

/// What a sample's answer is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// The measurement was rejected by the gate: the last input is held.
    Rejected,
    /// The safe input, with this status bit (`SAFE_STATE` or `OPEN_LOOP`); the controller
    /// takes the sample in without adapting.
    Safe(u32),
    /// The controller's input.
    Control,
}

/// The main answer of a cycle, once published.
#[derive(Debug, Clone, Copy)]
struct Published {
    ok: bool,
    t_pub: u64,
    /// The controller's time in this cycle.
    compute_ns: u64,
    status: u32,
}

/// The header of an actuation for sample `seq` answering measurement `m`.
fn header(a: &mut Actuation, seq: u64, m: &Measurement, counts: ChannelCounts, timing: Timing) {
    a.contract_version = CONTRACT_VERSION;
    a.seq = seq;
    a.reply_to = m.seq;
    a.t_sample_ns = m.t_sample_ns;
    a.counts = counts;
    a.timing = timing.wire();
}

/// The controller's view of measurement `m`, `lost` samples after the previous one.
pub(super) fn step_input(m: &Measurement, lost: u64) -> StepInput<'_> {
    StepInput {
        seq: m.seq,
        y: m.y(),
        z: m.z(),
        r: m.r(),
        u_applied: m.u_applied(),
        lost,
    }
}

/// Replaces non-finite inputs by the safe input: the runtime never sends a NaN.
fn sanitize(u: &mut [f64], safe: &[f64]) {
    for (v, s) in u.iter_mut().zip(safe) {
        if !v.is_finite() {
            *v = *s;
        }
    }
}

impl LoopCore {
    /// Builds the loop state from the configuration (allocating; before the RT phase).
    /// What a timing fault does to the controller is [`TimingFaultReset::default`]
    /// (keep what it learned) until the configuration carries it; see
    /// [`LoopCore::with_timing_fault_reset`].
    pub fn new(
        cfg: &ServiceConfig,
        controller: Box<dyn Controller>,
        telemetry: TelemetryRt,
        log: Option<LogProducer>,
        events: rtrb::Producer<LoopEvent>,
    ) -> Self {
        let on_timing_fault = cfg.policy.on_timing_fault;
        let mut safe_input = [0.0; MAX_U];
        safe_input[..cfg.safe_input.len()].copy_from_slice(&cfg.safe_input);
        let mut controller = controller;
        let timing =
            timing_rules::effective_timing(cfg.answer.timing, controller.ahead().is_some());
        let mut core = Self {
            controller,
            telemetry,
            log,
            events,
            counts: cfg.counts,
            gate: MeasurementGate::new(cfg.counts, &cfg.limits),
            session: SessionTracker::new(
                cfg.policy.silent_periods,
                cfg.sample_period_ns,
                cfg.policy.silent_periods,
            ),
            deadline: DeadlineMonitor::new(&cfg.policy),
            resets: ControllerResetPolicy {
                on_timing_fault,
                reset_on_resume: cfg.policy.reset_on_resume,
            },
            safe_input,
            last_u: safe_input,
            scratch_u: [0.0; MAX_U],
            timing,
            plan_length: timing_rules::effective_plan_length(timing, cfg.answer.plan_length),
            prepared: Actuation::zeroed(cfg.counts),
            plan_pending: false,
            outgoing: Actuation::zeroed(cfg.counts),
            plan_rows: vec![0.0; MAX_PLAN * cfg.counts.n_u as usize],
            sent: SentLog::default(),
            open_loop_cycles: cfg.open_loop_cycles,
            tones: ToneMeter::new(
                &cfg.tone_report,
                cfg.open_loop_cycles,
                cfg.counts.n_z as usize,
                cfg.sample_period_ns as f64 * 1e-9,
            ),
            following: model_following::ModelFollowing::new(cfg.tone_report.error_window),
            force: force_regulation::ForceRegulation::new(
                cfg.tone_report.force_regulation,
                cfg.sample_period_ns as f64 * 1e-9,
            ),
            period_ns: cfg.sample_period_ns,
            silent_periods: cfg.policy.silent_periods,
            rms_settle_cycles: cfg.rms_settle_cycles,
            stats: LoopStats::default(),
            z_sum_sq: [0.0; MAX_Z],
            z_sum_sq_settled: [0.0; MAX_Z],
            z_count: 0,
            z_count_settled: 0,
            record: LogRecord::zeroed(),
            internals: [0.0; MAX_INTERNALS],
            pending_jitter: None,
            new_peer_pending: false,
            timestamp_ok: false,
            u_applied_tolerance: cfg.policy.u_applied_tolerance,
            foreign_run: false,
            safe_since_seq: 0,
            recover_after: cfg.policy.recover_after,
            recover_tolerance: cfg.policy.recover_tolerance,
            rt_allocations: Default::default(),
            pacing: Default::default(),
            checkpoints: None,
            checkpoint_every: cfg.checkpoint_every_cycles,
            cycles_since_checkpoint: 0,
            recorder: None,
            refusals_counted: 0,
            operator: None,
            operator_safe: false,
            adaptation_frozen: false,
            stop_requested: false,
            live: None,
            lockstep: false,
        };
        core.refresh_prepared();
        core
    }

    /// The timing the loop runs: the configured one, or compute-first for a controller
    /// without an ahead form.
    pub fn timing(&self) -> Timing {
        self.timing
    }

    /// Plan entries per answer (0 with compute-first).
    pub fn plan_length(&self) -> usize {
        self.plan_length
    }

    /// What the controller's plans hold, when it sends any.
    pub fn plan_source(&mut self) -> Option<&'static str> {
        if self.plan_length == 0 {
            return None;
        }
        self.controller.ahead().map(|a| a.plan_source())
    }

    /// The prepared answer from the controller's ready input, without a plan (at the start,
    /// and after a reset or a new data stream).
    fn refresh_prepared(&mut self) {
        let n_u = self.counts.n_u as usize;
        let Some(ahead) = self.controller.ahead() else {
            return;
        };
        let s = ahead.ready(&mut self.prepared.u[..n_u]);
        self.prepared.status = crate::wire::actuation_status(s);
        self.prepared.plan_len = 0;
        self.prepared.compute_ns = 0;
        self.plan_pending = true;
        sanitize(&mut self.prepared.u[..n_u], &self.safe_input);
    }

    /// Hands a checkpoint of what the controller learned to `slot` every
    /// `service.checkpoint-every` of answered samples ([`checkpoint`](super::checkpoint)); without a slot, or
    /// with `checkpoint-every = 0`, none is taken during the run.
    pub fn with_checkpoints(mut self, slot: Arc<CheckpointSlot>) -> Self {
        self.checkpoints = (!slot.is_empty() && self.checkpoint_every > 0).then_some(slot);
        self
    }

    /// Takes operator commands from `inbox` at sample boundaries
    /// ([`LoopCore::take_commands`]).
    pub fn with_operator(mut self, inbox: OperatorInbox) -> Self {
        self.operator = Some(inbox);
        self
    }

    /// Feeds the live view through `tap` ([`live_tap`](super::live_tap)).
    pub fn with_live(mut self, tap: LiveTap) -> Self {
        self.live = Some(tap);
        self
    }

    /// Records every input and output of the loop through `recorder` ([`crate::record`]).
    pub fn with_recorder(mut self, recorder: Recorder) -> Self {
        self.recorder = Some(recorder);
        self
    }

    /// The controller's own per-thread set-up ([`Controller::prepare_thread`]), on the
    /// thread that runs the loop.
    pub fn prepare_controller_thread(&mut self) {
        self.controller.prepare_thread();
    }

    /// The sequence number of the last accepted sample (`None` before any).
    pub fn last_seq(&self) -> Option<u64> {
        self.session.last_seq()
    }

    /// The controller (read-only: for the final checkpoint and the report).
    pub fn controller(&self) -> &dyn Controller {
        &*self.controller
    }

    /// Every `checkpoint_every` answered samples, copies what the controller learned into
    /// a free buffer of the slot (a `memcpy`; skipped and counted when none is free).
    fn maybe_checkpoint(&mut self, seq: u64) {
        let Some(slot) = &self.checkpoints else {
            return;
        };
        self.cycles_since_checkpoint += 1;
        if self.cycles_since_checkpoint < self.checkpoint_every {
            return;
        }
        self.cycles_since_checkpoint = 0;
        let mark = CheckpointMark {
            seq,
            plant_session: self.stats.new_sessions + 1,
        };
        match slot.offer(&*self.controller, mark) {
            Offered::Copied => self.stats.checkpoints_taken += 1,
            Offered::Busy => self.stats.checkpoints_skipped += 1,
            Offered::NotFinite => self.stats.checkpoints_not_finite += 1,
        }
    }

    /// Sets what a timing fault (leaving the safe state, a stalled plant resuming) does to
    /// the controller's learned state ([`reset`](super::reset) has the whole table).
    pub fn with_timing_fault_reset(mut self, on_timing_fault: TimingFaultReset) -> Self {
        self.resets.on_timing_fault = on_timing_fault;
        self
    }

    /// The controller reset policy in force.
    pub fn reset_policy(&self) -> ControllerResetPolicy {
        self.resets
    }

    fn event(&mut self, e: LoopEvent) {
        if self.events.push(e).is_err() {
            self.stats.events_dropped += 1;
        }
    }

    /// Copies the policies' counters into [`LoopStats`].
    fn sync_stats(&mut self) {
        let s = &mut self.stats;
        let session = self.session.counts();
        s.received = session.received;
        s.skipped = session.lost;
        s.rejected_duplicate = session.duplicates;
        s.rejected_backward = session.backward;
        s.rejected_jump = session.implausible_jumps;
        s.new_sessions = session.new_sessions;
        s.plant_silent_events = session.silences;
        s.plant_resumes = session.resumes;
        let rejected = self.gate.rejected();
        s.rejected_contract = rejected.contract;
        s.rejected_non_finite = rejected.non_finite;
        s.rejected_out_of_range = rejected.out_of_range;
        let deadline = self.deadline.counts();
        s.deadline_misses = deadline.late;
        s.protected_misses = deadline.protected_misses;
        s.plant_reported_misses = deadline.plant_reported;
        s.plan_covered_misses = deadline.plan_covered;
        s.max_consecutive_misses = deadline.max_consecutive;
        s.safe_state_entries = deadline.safe_state_entries;
    }

    fn reset_controller_if(&mut self, cause: ResetCause) {
        if self.resets.resets(cause) {
            self.controller.reset();
            self.refresh_prepared();
        }
    }

    /// Passes `m` through the measurement gate.
    fn admissible(&mut self, m: &Measurement) -> bool {
        let ok = self.gate.check(m).is_ok();
        self.sync_stats();
        ok
    }

    /// The next sample comes from another publisher than the previous one (a restarted or
    /// replaced plant): it begins a new plant session. Called by the IPC glue, which pins
    /// the peer's identity.
    pub fn note_new_peer(&mut self) {
        if let Some(r) = self.recorder.as_mut() {
            r.new_peer();
        }
        self.new_peer_pending = true;
    }

    /// Session bookkeeping of a received sample (first sample, resume after silence, new
    /// plant session, gaps); returns the number of samples lost just before it, or `None`
    /// when the sample is refused ([`session`]) and must neither reach the controller nor
    /// be answered.
    fn admit(&mut self, m: &Measurement) -> Option<u64> {
        let new_peer = core::mem::take(&mut self.new_peer_pending);
        let was_silent = self.session.is_silent();
        let lockstep = m.flags & measurement_flags::LOCKSTEP != 0;
        let arrival = self
            .session
            .arrive(m.seq, m.t_sample_ns, new_peer, lockstep);
        match arrival {
            Arrival::First => self.event(LoopEvent::FirstSample { seq: m.seq }),
            Arrival::Next { .. } | Arrival::Refused(_) => {}
            Arrival::Resumed { .. } => {
                self.event(LoopEvent::PlantResumed { seq: m.seq });
                self.deadline.new_connection();
                self.reset_controller_if(ResetCause::StallResumed);
            }
            Arrival::NewSession { from, cause } => {
                if was_silent {
                    self.event(LoopEvent::PlantResumed { seq: m.seq });
                }
                let left_safe_state = self.deadline.new_session();
                self.event(LoopEvent::NewPlantSession {
                    from,
                    to: m.seq,
                    cause,
                    left_safe_state,
                });
                if self.resets.resets(ResetCause::NewPlantSession) {
                    self.controller.reset();
                } else {
                    self.controller.restart_data();
                }
                self.refresh_prepared();
                self.tones.new_session();
                self.sent.clear();
                self.foreign_run = false;
            }
        }
        self.sync_stats();
        arrival.accepted().then(|| arrival.lost())
    }

    /// Compares the plant's report of the input it applied after sample `k − 1` with what
    /// the service sent for it; raises [`LoopEvent::ForeignActuation`] at the first
    /// mismatch of a run.
    fn check_u_applied(&mut self, m: &Measurement) {
        let on_time = timing_rules::reported(m.flags) == Reported::OnTime;
        let Some(applied) = m.u_applied() else {
            return;
        };
        let Some((sent_u, _)) = m.seq.checked_sub(1).and_then(|k| self.sent.input_for(k)) else {
            return;
        };
        if !on_time {
            return;
        }
        let difference = applied
            .iter()
            .zip(sent_u)
            .map(|(a, s)| (a - s).abs())
            .fold(0.0, |m: f64, d| if d.is_nan() || d > m { d } else { m });
        // A NaN report counts as a mismatch.
        let mismatch = difference.is_nan() || difference > self.u_applied_tolerance;
        if mismatch {
            self.stats.foreign_actuations += 1;
            if !self.foreign_run {
                self.event(LoopEvent::ForeignActuation {
                    seq: m.seq,
                    difference,
                });
            }
        }
        self.foreign_run = mismatch;
    }

    /// True for a sample of an injected stall: `INJECTED_STALL` with `LOCKSTEP` (the flag
    /// means nothing in real time).
    fn injected_stall(m: &Measurement) -> bool {
        let both = measurement_flags::INJECTED_STALL | measurement_flags::LOCKSTEP;
        m.flags & both == both
    }

    /// Counts sample `m`, received after `lost` lost ones, toward the shares of the verdict
    /// when it is past start-up (the grace period and the open-loop phase): the samples,
    /// the lost ones, and whether the plant held its input before it.
    fn count_past_startup(&mut self, m: &Measurement, lost: u64) {
        let refusals =
            self.stats.rejected_duplicate + self.stats.rejected_backward + self.stats.rejected_jump;
        let refused_before = refusals != self.refusals_counted;
        self.refusals_counted = refusals;
        if self.deadline.in_grace(self.session.connection_cycle())
            || self.session.session_cycle() <= self.open_loop_cycles
        {
            return;
        }
        // A hold counts against the loop only when the service had sent an input for that
        // period: after a refused or lost sample the plant holds by design, and that is
        // counted as what it is.
        let answered = !refused_before
            && m.seq
                .checked_sub(1)
                .is_some_and(|k| self.sent.input_for(k).is_some());
        let held = answered && timing_rules::reported(m.flags) == Reported::HeldOrSafe;
        let s = &mut self.stats;
        s.samples_past_startup += 1 + lost;
        s.lost_past_startup += lost;
        s.held_past_startup += u64::from(held);
    }

    /// Takes in a measurement that was received too late to be answered, because a newer
    /// one was already waiting: the controller records it ([`Controller::observe`], or an
    /// ahead controller's `advance` without adaptation, with the input the plant applies
    /// for it as far as the loop knows) so that its memory keeps every sample, but no
    /// actuation is computed for the plant. A sample of an injected stall is acknowledged
    /// through `out`.
    pub fn observe(&mut self, m: &Measurement, out: &mut dyn Outbox) {
        if let Some(r) = self.recorder.as_mut() {
            r.observe(m);
        }
        if Self::injected_stall(m) {
            self.take_in_stalled(m, out);
        } else {
            self.take_in_late(m);
        }
    }

    fn take_in_late(&mut self, m: &Measurement) {
        let Some(lost) = self.admit(m) else {
            return;
        };
        self.count_past_startup(m, lost);
        self.stats.caught_up += 1;
        if !self.admissible(m) {
            return;
        }
        let n_u = self.counts.n_u as usize;
        let input = step_input(m, lost);
        if self.timing == Timing::ComputeFirst {
            self.controller.observe(&input, &mut self.scratch_u[..n_u]);
        } else {
            let mut applied = [0.0; MAX_U];
            self.sent
                .expected_input(m.seq, &self.safe_input[..n_u], &mut applied[..n_u]);
            self.advance(&input, &applied[..n_u], false);
        }
        self.accumulate_z(m);
    }

    /// A sample of an injected stall: taken in as one that arrived too late, then
    /// acknowledged (`STALL_ACK`, not an input).
    fn take_in_stalled(&mut self, m: &Measurement, out: &mut dyn Outbox) {
        self.take_in_late(m);
        self.stats.stalls_acknowledged += 1;
        let a = &mut self.outgoing;
        header(a, m.seq, m, self.counts, self.timing);
        a.status = actuation_status::STALL_ACK;
        a.u = [0.0; MAX_U];
        a.plan_len = 0;
        a.compute_ns = 0;
        let (ok, _) = self.publish(out);
        self.count_extra(ok);
    }

    fn count_extra(&mut self, ok: bool) {
        if ok {
            self.stats.published_extra += 1;
        } else {
            self.stats.publish_failures += 1;
        }
    }

    /// Called while no sample is pending; returns true when the plant has just been declared
    /// silent or is silent.
    pub fn on_idle(&mut self, now_ns: u64) -> bool {
        match self.session.idle(now_ns) {
            Idle::Active => false,
            Idle::Silent => true,
            Idle::WentSilent { last_seq } => {
                if let Some(r) = self.recorder.as_mut() {
                    r.went_silent(now_ns);
                }
                self.sync_stats();
                let periods = self.silent_periods;
                self.event(LoopEvent::PlantSilent { last_seq, periods });
                self.push_live_state();
                true
            }
        }
    }

    /// Reports the result of a stale-resource clean-up done while the plant is silent.
    pub fn note_cleanup(&mut self, count: usize) {
        if count > 0 {
            self.event(LoopEvent::DeadNodesCleaned {
                count: count as u64,
            });
        }
    }

    /// RMS of each performance channel over the whole run and after the settling time.
    pub fn z_rms(&self) -> (Vec<f64>, Vec<f64>) {
        let n = self.counts.n_z as usize;
        let rms = |s: &[f64; MAX_Z], c: u64| {
            s[..n]
                .iter()
                .map(|v| {
                    if c > 0 {
                        (v / c as f64).sqrt()
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        };
        (
            rms(&self.z_sum_sq, self.z_count),
            rms(&self.z_sum_sq_settled, self.z_count_settled),
        )
    }

    /// Where the safe state stands now, when the loop is in it (for the verdict).
    pub fn safe_state_at_end(&self) -> Option<verdict::SafeStateAtEnd> {
        self.deadline
            .in_safe_state()
            .then(|| verdict::SafeStateAtEnd {
                since_s: self.safe_since_seq as f64 * self.period_ns as f64 * 1e-9,
                recover_after: self.recover_after,
                tolerance: self.recover_tolerance,
                longest_clean_run: self.deadline.longest_clean_run(),
            })
    }

    /// Hands the histogram box back at the end of a run.
    pub fn flush_telemetry(&mut self) {
        self.telemetry.flush();
    }
}

#[cfg(test)]
mod tests;
