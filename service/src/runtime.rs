//! The real-time loop of the service, its policies, and the run report.
//!
//! Two phases, kept apart by types. [`run`] builds everything that allocates — the
//! controller, the histogram boxes, the log and event queues, the iceoryx2 ports — and
//! starts the helper threads (histogram reporter, CSV writer) off the RT core and at normal
//! priority. The RT thread then pins itself, asks for `SCHED_FIFO` and `mlockall`, connects,
//! and runs [`LoopCore`], whose per-sample work is:
//!
//! ```text
//!  wait for measurement k (sleep-poll, busy-poll or blocking on the plant's event: [`pacing`])
//!  session: first sample, next (gaps counted as lost), stall resumed, or new plant session
//!  gate: contract version and counts, finite, in range — else hold u, count
//!  answer, by service.timing (the safe input instead in the safe state and the open-loop
//!  phase, while the controller takes the sample in without adapting):
//!    compute-first  u_k = controller.step(y_k, …); publish Actuation{seq k}
//!    answer-first   publish Actuation{seq k} = the prepared u_k (and plan);
//!                   then advance(k) prepares u_{k+1} and its plan
//!    send-ahead     (publish Actuation{seq k} = the prepared u_k if none went ahead for k);
//!                   advance(k) prepares u_{k+1}; publish Actuation{seq k+1} at once
//!  record wake-up, compute, response time and period jitter
//!  push the signals to the log queue (drop and count when full)
//!  deadline policy: count misses; N consecutive after the grace period ⇒ safe state
//!  (latched, or left after M good answers)
//! ```
//!
//! With answer-first the response time no longer contains the controller's cost; with
//! send-ahead the plant holds `u_{k+1}` before sample `k + 1` is taken, so a stall of the
//! service shorter than a period costs nothing and a plant may latch its inputs on the
//! sample clock (`proxy.deadline = 0`). Its deadline for the answer to sample `k` is then
//! `T + D` after `t_k`. The ahead timings need a controller with an ahead form
//! ([`control::ahead`]); each of their answers may carry the controller's plan for the
//! next `service.plan-length` samples, which a plant applies when an answer is late.
//! Which inputs were sent for which sample is kept in a [`sent::SentLog`].
//!
//! The policies are plain-data types with no I/O and no clock of their own, each with its
//! rules stated in its module:
//!
//! - [`gate`]: which measurements may reach the controller;
//! - [`session`]: sequence numbers, silence, a stall versus a genuinely new plant session;
//! - [`deadline`]: what counts as a miss, when the safe state is entered and left;
//! - [`reset`]: what a fault does to what the controller learned. By default
//!   ([`TimingFaultReset::KeepLearned`]) a timing fault — leaving the safe state, a stalled
//!   plant that resumes its sequence — keeps it; a new plant session keeps it too and
//!   restarts only the controller's data history, unless `service.reset-on-resume` is true;
//! - [`checkpoint`]: what the controller learned, copied every `service.checkpoint-every`
//!   through a [`checkpoint_slot::CheckpointSlot`] (no allocation) and written to
//!   `checkpoint.json` off the RT thread; `--warm-start` starts a later run from it.
//!
//! Nothing in that path allocates, locks, does I/O or panics (a counting-allocator test in
//! `service/tests/no_alloc.rs` runs it). Events (plant silent, resumed, safe state) leave the
//! RT thread through a lock-free queue and are printed by the supervising thread. When no
//! sample has arrived for `silent-periods` periods the plant is declared silent; while it is,
//! and only then, the loop cleans up stale iceoryx2 resources of dead processes every 100 ms
//! so that a restarted plant can connect, and it resumes on the next sample.

pub mod checkpoint;
pub mod checkpoint_slot;
pub mod deadline;
pub mod force_regulation;
pub mod gate;
pub mod model_following;
pub mod pacing;
pub mod reset;
pub mod sent;
pub mod session;
mod tones;
pub mod verdict;
pub use reset::TimingFaultReset;
pub use tones::{ToneLine, ToneMeter, ToneReport};

use crate::config::{ServiceConfig, WaitMode};
use crate::logging::{self, LogLayout, LogProducer, LogRecord};
use crate::record::{self, RecordHeader, RecordStats, Recorder};
use crate::telemetry::{self, CycleTiming, TelemetryRt, TelemetrySummary};
use checkpoint::{Checkpoint, WarmStart};
use checkpoint_slot::{CheckpointMark, CheckpointSlot, Offered};
use control::controller::{Controller, MAX_INTERNALS, StepInput};
use deadline::{Answer, DeadlineMonitor, SafeStateChange};
use gate::MeasurementGate;
use ipc_types::clock::monotonic_ns;
use ipc_types::peer::Origin;
use ipc_types::ports::{ConnectOptions, ContractInfo, ServicePorts, Side};
use ipc_types::rt::RtSetup;
use ipc_types::{
    Actuation, CONTRACT_VERSION, ChannelCounts, MAX_PLAN, MAX_U, MAX_Z, Measurement, Timing,
    actuation_status, measurement_flags,
};
pub use pacing::{Pacer, WaitStep};
use reset::{ControllerResetPolicy, ResetCause};
use sent::SentLog;
use serde::Serialize;
use session::{Arrival, Idle, NewSessionCause, SessionTracker};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Something the RT loop reports; carried out of it through a lock-free queue.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "event", rename_all = "kebab-case")]
pub enum LoopEvent {
    /// The first sample of a plant session arrived.
    FirstSample {
        /// Its sequence number.
        seq: u64,
    },
    /// No sample for the configured number of periods.
    PlantSilent {
        /// The last sequence number received.
        last_seq: u64,
        /// Periods waited.
        periods: u64,
    },
    /// Samples came back after silence (a stall resumed, or a new plant session, which is
    /// then also reported as [`LoopEvent::NewPlantSession`]).
    PlantResumed {
        /// The first sequence number received again.
        seq: u64,
    },
    /// A new plant session begins: another publisher, a sequence restarted after silence,
    /// or a consistent new numbering (see [`session`]).
    NewPlantSession {
        /// The last sequence number of the previous session.
        from: u64,
        /// The first of the new one.
        to: u64,
        /// Why.
        cause: NewSessionCause,
        /// The safe state of the previous session was cleared.
        left_safe_state: bool,
    },
    /// The plant reported applying an input the service did not send (beyond
    /// `service.u-applied-tolerance`) for an actuation it says came in time: another
    /// process drives the actuators, or the plant alters the inputs. Reported at the first
    /// mismatch of a run of them.
    ForeignActuation {
        /// The sample that carried the report.
        seq: u64,
        /// The largest `|u_applied − u_sent|`.
        difference: f64,
    },
    /// Too many consecutive deadline misses: the safe input is applied.
    SafeStateEntered {
        /// Sequence number at which it happened.
        seq: u64,
        /// Consecutive misses counted.
        misses: u64,
    },
    /// The safe state was left after enough good answers.
    SafeStateLeft {
        /// Sequence number at which it happened.
        seq: u64,
    },
    /// The plant said this was its last sample.
    PlantEnded {
        /// Its sequence number.
        seq: u64,
    },
    /// Stale resources of dead iceoryx2 nodes were removed.
    DeadNodesCleaned {
        /// How many nodes.
        count: u64,
    },
}

impl fmt::Display for LoopEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoopEvent::FirstSample { seq } => write!(f, "plant connected: first sample seq {seq}"),
            LoopEvent::PlantSilent { last_seq, periods } => write!(
                f,
                "PLANT SILENT: no sample for {periods} periods after seq {last_seq}; waiting for it to come back"
            ),
            LoopEvent::PlantResumed { seq } => write!(f, "plant resumed at seq {seq}"),
            LoopEvent::NewPlantSession {
                from,
                to,
                cause,
                left_safe_state,
            } => write!(
                f,
                "NEW PLANT SESSION ({}): sequence {from} -> {to}{}",
                cause.name(),
                if *left_safe_state {
                    "; the safe state of the previous session is cleared"
                } else {
                    ""
                }
            ),
            LoopEvent::ForeignActuation { seq, difference } => write!(
                f,
                "FOREIGN ACTUATION at seq {seq}: the plant applied an input the service did not \
                 send (|u_applied − u_sent| = {difference:.3e}); is another process publishing \
                 on this rig?"
            ),
            LoopEvent::SafeStateEntered { seq, misses } => write!(
                f,
                "SAFE STATE at seq {seq}: {misses} consecutive deadline misses; applying the safe input"
            ),
            LoopEvent::SafeStateLeft { seq } => write!(f, "safe state left at seq {seq}"),
            LoopEvent::PlantEnded { seq } => write!(f, "plant ended its run at seq {seq}"),
            LoopEvent::DeadNodesCleaned { count } => {
                write!(
                    f,
                    "removed stale resources of {count} dead iceoryx2 node(s)"
                )
            }
        }
    }
}

/// Counters of the RT loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct LoopStats {
    /// Measurements received.
    pub received: u64,
    /// Answers published: one per answered sample (with send-ahead, the input for the
    /// next sample).
    pub published: u64,
    /// Actuations published besides those answers: with send-ahead, the input for a
    /// sample itself when none had gone ahead for it (a session's first sample, after a
    /// stall); the acknowledgements of injected stalls.
    pub published_extra: u64,
    /// Controller steps run.
    pub controller_steps: u64,
    /// Samples rejected for another contract version or other channel counts.
    pub rejected_contract: u64,
    /// Samples rejected for a NaN or infinite value.
    pub rejected_non_finite: u64,
    /// Samples rejected for a value outside the configured range.
    pub rejected_out_of_range: u64,
    /// Samples refused as duplicates of the last sequence number (never answered).
    pub rejected_duplicate: u64,
    /// Samples refused for a backward sequence number (never answered).
    pub rejected_backward: u64,
    /// Samples refused for a forward jump the plant's clock cannot explain (never answered).
    pub rejected_jump: u64,
    /// New plant sessions after the first.
    pub new_sessions: u64,
    /// Answered samples whose sample time was impossible (0, after the receipt, or before
    /// the previous sample's): left out of the latency figures and the late count.
    pub impossible_timestamps: u64,
    /// Samples whose reported `u_applied` differs from what the service sent.
    pub foreign_actuations: u64,
    /// Samples refused because another publisher than the pinned plant sent them.
    pub foreign_samples: u64,
    /// Samples never seen (gaps in the sequence).
    pub skipped: u64,
    /// Samples received too late to answer (a newer one was waiting); the controller
    /// observed them ([`Controller::observe`]) and only the newest was answered.
    pub caught_up: u64,
    /// Cycles whose response came after the plant's deadline.
    pub deadline_misses: u64,
    /// Misses in protected cycles (grace period, open-loop phase): counted, not acted on.
    pub protected_misses: u64,
    /// Misses the plant reported (its view: the actuation was late or absent).
    pub plant_reported_misses: u64,
    /// Of those, the ones the plant covered with an entry of the service's plan
    /// (`PLAN_APPLIED`); the others reached the plant as a held or safe input.
    pub plan_covered_misses: u64,
    /// Samples of an injected stall (lockstep): taken in without an answer, acknowledged.
    pub stalls_acknowledged: u64,
    /// Longest run of consecutive misses.
    pub max_consecutive_misses: u64,
    /// Entries into the safe state.
    pub safe_state_entries: u64,
    /// Cycles spent in the safe state.
    pub safe_state_cycles: u64,
    /// Times the plant went silent.
    pub plant_silent_events: u64,
    /// Times it came back.
    pub plant_resumes: u64,
    /// Cycles the controller reported saturation.
    pub saturated_cycles: u64,
    /// Cycles the controller reported a fault.
    pub controller_faults: u64,
    /// Cycles the controller could not compute its law and applied its fallback input
    /// (`actuation_status::FALLBACK`, e.g. an infeasible or unsolved MPC problem).
    pub fallback_cycles: u64,
    /// Actuations that could not be published.
    pub publish_failures: u64,
    /// Events dropped because the event queue was full.
    pub events_dropped: u64,
    /// Checkpoints of what the controller learned handed to the writer.
    pub checkpoints_taken: u64,
    /// Checkpoints skipped because the writer still held both buffers.
    pub checkpoints_skipped: u64,
    /// Checkpoints not taken because a learned value was not finite.
    pub checkpoints_not_finite: u64,
    /// Samples past start-up (the grace period and the open-loop phase of a connection):
    /// received, and lost just before one received.
    pub samples_past_startup: u64,
    /// Of those, the samples lost (never received).
    pub lost_past_startup: u64,
    /// Samples past start-up whose plant reports that it held its input or applied its
    /// safe output over the period before although the service had sent an input for it
    /// (a late answer that no plan entry covered).
    pub held_past_startup: u64,
    /// Closed-loop answers whose input differs from the safe input.
    pub inputs_off_safe: u64,
}

/// Why the loop stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StopReason {
    /// SIGINT or SIGTERM.
    Signal,
    /// The plant sent its last sample.
    PlantEnded,
    /// The configured maximum number of cycles was reached.
    MaxCycles,
}

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
    period_ns: u64,
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
    /// Where checkpoints go to the writer (`None`: none are taken during the run).
    checkpoints: Option<Arc<CheckpointSlot>>,
    checkpoint_every: u64,
    cycles_since_checkpoint: u64,
    /// Where every input and output of the loop goes for `record.bin` ([`crate::record`]).
    recorder: Option<Recorder>,
    /// Refused samples already accounted for by [`LoopCore::count_past_startup`].
    refusals_counted: u64,
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
/// ([`rt_loop`]), a recorder in tests.
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
        let timing = match controller.ahead() {
            Some(_) => cfg.answer.timing,
            None => Timing::ComputeFirst,
        };
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
            plan_length: if timing == Timing::ComputeFirst {
                0
            } else {
                cfg.answer.plan_length.min(MAX_PLAN)
            },
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
            checkpoints: None,
            checkpoint_every: cfg.checkpoint_every_cycles,
            cycles_since_checkpoint: 0,
            recorder: None,
            refusals_counted: 0,
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
    /// `service.checkpoint-every` of answered samples ([`checkpoint`]); without a slot, or
    /// with `checkpoint-every = 0`, none is taken during the run.
    pub fn with_checkpoints(mut self, slot: Arc<CheckpointSlot>) -> Self {
        self.checkpoints = (!slot.is_empty() && self.checkpoint_every > 0).then_some(slot);
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
    /// the controller's learned state ([`reset`] has the whole table).
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
        let arrival = self.session.arrive(m.seq, m.t_sample_ns, new_peer);
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
        let on_time = m.flags
            & (measurement_flags::PREVIOUS_ACTUATION_MISSED | measurement_flags::PLANT_SAFE_OUTPUT)
            == 0;
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
        let f = m.flags;
        let answered = !refused_before
            && m.seq
                .checked_sub(1)
                .is_some_and(|k| self.sent.input_for(k).is_some());
        let held = answered
            && ((f & measurement_flags::PREVIOUS_ACTUATION_MISSED != 0
                && f & measurement_flags::PLAN_APPLIED == 0)
                || f & measurement_flags::PLANT_SAFE_OUTPUT != 0);
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

    /// An ahead controller takes sample `k` in with `applied`, adapting when `adapt`, and
    /// the prepared answer becomes its ready input and, after an adapting step, its plan.
    /// Returns the time it took.
    fn advance(&mut self, input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u64 {
        let n_u = self.counts.n_u as usize;
        let t0 = monotonic_ns();
        let Some(ahead) = self.controller.ahead() else {
            return 0;
        };
        let s = ahead.advance(input, applied, adapt);
        let _ = ahead.ready(&mut self.prepared.u[..n_u]);
        // A sample taken in without adaptation (catching up, the safe state) leaves the
        // plan to be made when an answer goes out ([`LoopCore::fill`]).
        self.plan_pending = true;
        if adapt {
            self.make_plan();
        }
        let compute_ns = monotonic_ns().saturating_sub(t0);
        let wire = crate::wire::actuation_status(s);
        self.prepared.status = wire;
        self.prepared.compute_ns = compute_ns;
        sanitize(&mut self.prepared.u[..n_u], &self.safe_input);
        if adapt {
            self.count_status(wire);
        }
        compute_ns
    }

    /// The prepared answer's plan from the controller, up to its first non-finite entry
    /// (the runtime never sends a NaN).
    fn make_plan(&mut self) {
        self.plan_pending = false;
        let n_u = self.counts.n_u as usize;
        let rows = match self.controller.ahead() {
            Some(ahead) if self.plan_length > 0 => {
                let len = (self.plan_length * n_u).min(self.plan_rows.len());
                ahead.plan(&mut self.plan_rows[..len])
            }
            _ => 0,
        };
        let mut len = 0;
        for (j, row) in self
            .plan_rows
            .chunks_exact(n_u.max(1))
            .take(rows)
            .enumerate()
        {
            if n_u == 0 || !row.iter().all(|v| v.is_finite()) {
                break;
            }
            if let Some(dst) = self.prepared.plan.get_mut(j) {
                dst[..n_u].copy_from_slice(row);
                len = j + 1;
            }
        }
        self.prepared.plan_len = len as u32;
    }

    /// An ahead controller takes the sample of an answer of `mode` in: not a rejected one
    /// (the controller never sees it), without adaptation in the safe state and the
    /// open-loop phase. Returns the time it took.
    fn take_in(&mut self, mode: Mode, input: &StepInput<'_>, applied: &[f64]) -> u64 {
        match mode {
            Mode::Rejected => 0,
            Mode::Safe(_) => self.advance(input, applied, false),
            Mode::Control => self.advance(input, applied, true),
        }
    }

    /// Counts a controller step and its status bits.
    fn count_status(&mut self, wire: u32) {
        self.stats.controller_steps += 1;
        if wire & actuation_status::SATURATED != 0 {
            self.stats.saturated_cycles += 1;
        }
        if wire & actuation_status::CONTROLLER_FAULT != 0 {
            self.stats.controller_faults += 1;
        }
        if wire & actuation_status::FALLBACK != 0 {
            self.stats.fallback_cycles += 1;
        }
    }

    /// Publishes the outgoing actuation through `out` and records it.
    fn publish(&mut self, out: &mut dyn Outbox) -> (bool, u64) {
        let (ok, t_pub) = out.publish(&mut self.outgoing);
        if let Some(r) = self.recorder.as_mut() {
            r.publish(&self.outgoing, ok, t_pub);
        }
        (ok, t_pub)
    }

    /// Publishes the outgoing actuation as an input: counted, remembered, held.
    fn send(&mut self, out: &mut dyn Outbox, main: bool) -> (bool, u64) {
        let (ok, t_pub) = self.publish(out);
        if ok {
            self.sent.record(&self.outgoing);
            self.last_u = self.outgoing.u;
            if main {
                self.stats.published += 1;
            } else {
                self.stats.published_extra += 1;
            }
        } else {
            self.stats.publish_failures += 1;
        }
        (ok, t_pub)
    }

    /// Writes the input of `mode` for a sample into the outgoing actuation: the held input
    /// (rejected measurement), the safe input (its plan: the safe input again), or the
    /// prepared answer (its plan too).
    fn fill(&mut self, mode: Mode, status: u32) {
        if mode == Mode::Control && self.plan_pending {
            self.make_plan();
        }
        let a = &mut self.outgoing;
        a.plan_len = 0;
        a.compute_ns = 0;
        match mode {
            Mode::Rejected => {
                a.u = self.last_u;
                a.status = status | actuation_status::MEASUREMENT_REJECTED;
            }
            Mode::Safe(bit) => {
                a.u = self.safe_input;
                a.status = status | bit;
                for row in a.plan.iter_mut().take(self.plan_length) {
                    *row = self.safe_input;
                }
                a.plan_len = self.plan_length.min(MAX_PLAN) as u32;
            }
            Mode::Control => {
                let p = &self.prepared;
                a.u = p.u;
                a.status = status | p.status;
                a.compute_ns = p.compute_ns;
                let len = (p.plan_len as usize).min(MAX_PLAN);
                a.plan[..len].copy_from_slice(&p.plan[..len]);
                a.plan_len = len as u32;
            }
        }
    }

    /// Handles measurement `m` received at `t_recv_ns`: the session and gate, the answer by
    /// the loop's timing (published through `out`), then the deadline policy, histograms,
    /// log and checkpoint of the cycle.
    pub fn handle(
        &mut self,
        m: &Measurement,
        t_recv_ns: u64,
        out: &mut dyn Outbox,
    ) -> CycleDecision {
        if let Some(r) = self.recorder.as_mut() {
            r.handle(m, t_recv_ns);
        }
        let last_sample = m.flags & measurement_flags::LAST_SAMPLE != 0;
        if Self::injected_stall(m) {
            self.take_in_stalled(m, out);
            return CycleDecision {
                compute_ns: 0,
                last_sample,
                answer: false,
            };
        }
        let previous_t_sample = self.session.last_sample_time_ns();
        let Some(lost) = self.admit(m) else {
            return CycleDecision {
                compute_ns: 0,
                last_sample: false,
                answer: false,
            };
        };
        self.timestamp_ok =
            m.t_sample_ns != 0 && m.t_sample_ns <= t_recv_ns && m.t_sample_ns >= previous_t_sample;
        if !self.timestamp_ok {
            self.stats.impossible_timestamps += 1;
        }
        self.check_u_applied(m);
        self.count_past_startup(m, lost);
        let cycle = self.session.connection_cycle();
        let flagged = m.flags & measurement_flags::PREVIOUS_ACTUATION_MISSED != 0;
        let covered = m.flags & measurement_flags::PLAN_APPLIED != 0;
        self.deadline.on_sample(flagged, covered, cycle);
        self.sync_stats();
        let jitter = self
            .session
            .answered(t_recv_ns)
            .map(|dt| dt.abs_diff(self.period_ns));

        let status = if self.deadline.in_grace(cycle) {
            actuation_status::STARTING
        } else {
            actuation_status::OK
        };
        let input = step_input(m, lost);
        let mode = if !self.admissible(m) {
            Mode::Rejected
        } else if self.deadline.in_safe_state() {
            self.stats.safe_state_cycles += 1;
            Mode::Safe(actuation_status::SAFE_STATE)
        } else if self.session.session_cycle() <= self.open_loop_cycles {
            Mode::Safe(actuation_status::OPEN_LOOP)
        } else {
            Mode::Control
        };
        let answer = match self.timing {
            Timing::ComputeFirst => self.compute_first(m, &input, mode, status, out),
            Timing::AnswerFirst => self.answer_first(m, &input, mode, status, out),
            Timing::SendAhead => self.send_ahead(m, &input, mode, status, out),
        };
        if mode != Mode::Rejected {
            self.accumulate_z(m);
        }
        let n_u = self.counts.n_u as usize;
        if mode == Mode::Control && self.outgoing.u[..n_u] != self.safe_input[..n_u] {
            self.stats.inputs_off_safe += 1;
        }
        self.pending_jitter = jitter;
        self.finish_cycle(m, t_recv_ns, answer);
        CycleDecision {
            compute_ns: answer.compute_ns,
            last_sample,
            answer: true,
        }
    }

    /// Compute-first: `u_k` from the step on `y_k` (or held, or safe), then published.
    fn compute_first(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        header(&mut self.outgoing, m.seq, m, self.counts, self.timing);
        let mut compute_ns = 0;
        match mode {
            Mode::Rejected | Mode::Safe(_) => {
                self.fill(mode, status);
                if mode != Mode::Rejected {
                    let t0 = monotonic_ns();
                    self.controller.observe(input, &mut self.scratch_u[..n_u]);
                    compute_ns = monotonic_ns().saturating_sub(t0);
                }
            }
            Mode::Control => {
                let a = &mut self.outgoing;
                a.u = [0.0; MAX_U];
                a.plan_len = 0;
                let t0 = monotonic_ns();
                let s = self.controller.step(input, &mut a.u[..n_u]);
                compute_ns = monotonic_ns().saturating_sub(t0);
                let wire = crate::wire::actuation_status(s);
                // The controller promises finite output; the runtime still never sends a NaN.
                sanitize(&mut a.u[..n_u], &self.safe_input);
                a.status = status | wire;
                self.count_status(wire);
            }
        }
        self.outgoing.compute_ns = compute_ns;
        let (ok, t_pub) = self.send(out, true);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: self.outgoing.status,
        }
    }

    /// Answer-first: the prepared `u_k` published at once, then `advance(k)` prepares
    /// `u_{k+1}`.
    fn answer_first(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        header(&mut self.outgoing, m.seq, m, self.counts, self.timing);
        self.fill(mode, status);
        let (ok, t_pub) = self.send(out, true);
        let answered = self.outgoing.status;
        let applied = self.outgoing.u;
        let compute_ns = self.take_in(mode, input, &applied[..n_u]);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: answered,
        }
    }

    /// Send-ahead: sample `k` answered at once when nothing went ahead for it, then
    /// `advance(k)` and the answer for `k + 1` published.
    fn send_ahead(
        &mut self,
        m: &Measurement,
        input: &StepInput<'_>,
        mode: Mode,
        status: u32,
        out: &mut dyn Outbox,
    ) -> Published {
        let n_u = self.counts.n_u as usize;
        if !self.sent.contains(m.seq) {
            header(&mut self.outgoing, m.seq, m, self.counts, self.timing);
            self.fill(mode, status);
            let _ = self.send(out, false);
        }
        let mut applied = [0.0; MAX_U];
        self.sent
            .expected_input(m.seq, &self.safe_input[..n_u], &mut applied[..n_u]);
        let compute_ns = self.take_in(mode, input, &applied[..n_u]);
        header(
            &mut self.outgoing,
            m.seq.wrapping_add(1),
            m,
            self.counts,
            self.timing,
        );
        self.fill(mode, status);
        self.outgoing.compute_ns = compute_ns;
        let (ok, t_pub) = self.send(out, true);
        Published {
            ok,
            t_pub,
            compute_ns,
            status: self.outgoing.status,
        }
    }

    fn accumulate_z(&mut self, m: &Measurement) {
        self.tones
            .record(self.session.session_cycle(), m.seq, m.z());
        if let Some(e) = self.controller.model_following_error() {
            self.following.record(m.seq, e);
        }
        self.force.record(m.seq, m.y(), m.r());
        self.z_count += 1;
        let settled = self.z_count > self.rms_settle_cycles;
        if settled {
            self.z_count_settled += 1;
        }
        for (i, z) in m.z().iter().enumerate() {
            self.z_sum_sq[i] += z * z;
            if settled {
                self.z_sum_sq_settled[i] += z * z;
            }
        }
    }

    /// Completes the cycle of sample `m` after its answer: deadline policy, histograms, log.
    fn finish_cycle(&mut self, m: &Measurement, t_recv_ns: u64, answer: Published) {
        let response_ns = answer.t_pub.saturating_sub(m.t_sample_ns);
        let cycle = self.session.connection_cycle();
        // The plant's deadline for this answer: with send-ahead it is the next sample's.
        let deadline_ns = if m.flags & measurement_flags::LOCKSTEP != 0 {
            0
        } else {
            m.deadline_ns
                .saturating_add(self.timing.lead().saturating_mul(m.period_ns))
        };
        let verdict = self.deadline.on_answer(Answer {
            cycle,
            open_loop: self.session.session_cycle() <= self.open_loop_cycles,
            published: answer.ok,
            timestamp_ok: self.timestamp_ok,
            response_ns,
            deadline_ns,
        });
        self.sync_stats();
        match verdict.change {
            SafeStateChange::Unchanged => {}
            SafeStateChange::Entered { misses } => {
                self.safe_since_seq = m.seq;
                self.event(LoopEvent::SafeStateEntered { seq: m.seq, misses });
            }
            SafeStateChange::Left => {
                self.reset_controller_if(ResetCause::LeftSafeState);
                self.event(LoopEvent::SafeStateLeft { seq: m.seq });
            }
        }
        let jitter = self.pending_jitter.take();
        // The first sample of a connection waited for the connection, not for the loop: it
        // would only pollute the latency figures; so would an impossible sample time.
        if cycle > 1 && self.timestamp_ok {
            self.telemetry.record(&CycleTiming {
                seq: m.seq,
                wakeup_ns: t_recv_ns.saturating_sub(m.t_sample_ns),
                compute_ns: answer.compute_ns,
                response_ns,
                period_jitter_ns: jitter,
            });
        }
        if let Some(log) = self.log.as_mut() {
            // The row of sample k holds the input the service gave for sample k.
            let (u, status) = match self.sent.input_for(m.seq) {
                Some((u, status)) => (*u, status),
                None => (self.last_u, answer.status),
            };
            let r = &mut self.record;
            r.seq = m.seq;
            r.t_sample_ns = m.t_sample_ns;
            r.status = status;
            r.flags = m.flags;
            r.y = m.y;
            r.z = m.z;
            r.u = u;
            let n = self.controller.internals(&mut self.internals);
            r.internals[..n].copy_from_slice(&self.internals[..n]);
            log.push(r);
        }
        self.maybe_checkpoint(m.seq);
        if m.flags & measurement_flags::LAST_SAMPLE != 0 {
            self.event(LoopEvent::PlantEnded { seq: m.seq });
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

/// Options of one run that do not belong in the configuration file.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Overrides `service.run-dir`: the folder this run writes into (created).
    pub run_folder: Option<PathBuf>,
    /// Stop when the plant sends its last sample.
    pub exit_with_plant: bool,
    /// Stop after this many received samples.
    pub max_cycles: Option<u64>,
    /// Overrides `service.wait`.
    pub wait: Option<WaitMode>,
    /// Overrides `service.core`.
    pub core: Option<usize>,
    /// Start the controller from this checkpoint ([`checkpoint`]).
    pub warm_start: Option<PathBuf>,
}

/// Why the service could not run.
#[derive(Debug)]
pub enum ServiceError {
    /// The run folder could not be created or written.
    Io {
        /// What was being done.
        what: String,
        /// The OS error.
        error: std::io::Error,
    },
    /// The controller could not be built.
    Controller(String),
    /// `require-rt` is set and the OS refused a real-time set-up step.
    RtRefused(String),
    /// The plant could not be connected.
    Connect(ipc_types::ports::ConnectError),
    /// The RT thread ended abnormally.
    RtThread(String),
    /// The warm-start checkpoint was refused (the message names the file and the block).
    Checkpoint(String),
}

impl fmt::Display for ServiceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ServiceError::Io { what, error } => write!(f, "{what}: {error}"),
            ServiceError::Controller(m) => write!(f, "controller: {m}"),
            ServiceError::RtRefused(m) => write!(
                f,
                "real-time set-up refused and service.require-rt is true: {m}"
            ),
            ServiceError::Connect(e) => write!(f, "{e}"),
            ServiceError::RtThread(m) => write!(f, "RT thread: {m}"),
            ServiceError::Checkpoint(m) => write!(f, "warm start refused: {m}"),
        }
    }
}

impl std::error::Error for ServiceError {}

/// The report of one run, written as `report.json` into the run folder and printed.
#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    /// Rig name.
    pub rig: String,
    /// Configuration file.
    pub config: String,
    /// The run folder.
    pub run_folder: String,
    /// Controller kind.
    pub controller: String,
    /// Wait mode used.
    pub wait: String,
    /// The timing that ran (`compute-first`, `answer-first`, `send-ahead`).
    pub timing: String,
    /// Plan entries per answer (0: none).
    pub plan_length: usize,
    /// What the plans held, when the controller sent any.
    pub plan_source: Option<String>,
    /// Outcome of the real-time set-up, one line.
    pub rt_setup: String,
    /// True when any RT set-up step was refused.
    pub rt_degraded: bool,
    /// Conditions that qualify the figures: an incomplete real-time set-up, and every
    /// anomaly the loop counted ([`verdict`]).
    pub warnings: Vec<String>,
    /// Whether the run did what it was started for ([`verdict`]); the exit status follows.
    pub verdict: verdict::RunVerdict,
    /// Why the loop stopped.
    pub stop_reason: StopReason,
    /// Counters.
    pub stats: LoopStats,
    /// Every event, in order.
    pub events: Vec<LoopEvent>,
    /// RMS of each performance channel over the run.
    pub z_rms: Vec<f64>,
    /// RMS of each performance channel after `service.rms-settle` seconds.
    pub z_rms_settled: Vec<f64>,
    /// Latency histograms.
    pub latency: TelemetrySummary,
    /// Signal log records written and dropped.
    pub log_written: u64,
    /// Signal log records dropped because the queue was full.
    pub log_dropped: u64,
    /// Signal log records the writer could not write (full disk, I/O error).
    pub log_lost_to_disk: u64,
    /// The first write failure of the signal log, naming the file; `None` when there was none.
    pub log_first_error: Option<String>,
    /// `record.bin` ([`crate::record`]): entries offered, written, dropped, lost to the
    /// disk, and whether it is complete; `None` with `log.record = false`.
    pub record: Option<RecordStats>,
    /// Response-time budget used for "over budget" (the sample period), ns.
    pub budget_ns: u64,
    /// Sample period, s.
    pub sample_period_s: f64,
    /// Open-loop phase at the start of each session, s (`service.open-loop`).
    pub open_loop_s: f64,
    /// Allocations on the RT thread during the loop: served by its pool (iceoryx2's
    /// per-sample loan state) and from the system allocator (should be 0).
    pub rt_allocations: crate::rt_alloc::RtAllocStats,
    /// Per-tone amplitudes of `z` at the end of the open-loop phase and at the end of the
    /// run (`[service.report]`), when tones are known.
    pub tones: Option<ToneReport>,
    /// The model-following error norm (4.85), for a controller that follows a reference
    /// model (`service.report.error-window`).
    pub model_following: Option<model_following::ModelFollowingReport>,
    /// The contact phases' force regulation (`service.report.force-regulation`).
    pub force_regulation: Option<force_regulation::ForceRegulationReport>,
    /// What the box does to a real-time loop, for the RT core of this run
    /// ([`crate::system_check`]).
    pub system: Vec<crate::system_check::Finding>,
    /// Checkpoints of what the controller learned ([`checkpoint`]); `None` for a
    /// controller that learns nothing.
    pub checkpoint: Option<CheckpointReport>,
    /// Why samples were lost: the RT thread's scheduling over the loop, steal time, and
    /// the other tasks on the RT core ([`crate::scheduling`]).
    pub scheduling: crate::scheduling::SchedulingReport,
    /// What the controller counted over the run ([`Controller::counters`]), e.g. PCAC's
    /// solved, infeasible and unsolved QPs.
    pub controller_counters: Vec<(String, u64)>,
    /// How often an adaptive controller's update ran in closed loop and why it did not
    /// ([`Controller::adaptation`]); `None` for a controller that does not adapt.
    pub adaptation: Option<AdaptationReport>,
}

/// An adaptive controller's closed-loop updates, for the run report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdaptationReport {
    /// Steps whose update ran.
    pub updated: u64,
    /// Steps whose update was suspended, per cause.
    pub suspended: Vec<(String, u64)>,
}

impl From<control::Adaptation> for AdaptationReport {
    fn from(a: control::Adaptation) -> Self {
        Self {
            updated: a.updated,
            suspended: a
                .suspended
                .into_iter()
                .map(|(c, n)| (c.to_string(), n))
                .collect(),
        }
    }
}

/// The checkpoints of a run, for its report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckpointReport {
    /// The file (`checkpoint.json` in the run folder).
    pub path: String,
    /// Checkpoints written (the periodic ones and the final one).
    pub written: u64,
    /// Writes that failed.
    pub failures: u64,
    /// The first failure, naming the file.
    pub first_error: Option<String>,
    /// Sample of the last checkpoint written.
    pub last_seq: Option<u64>,
    /// The checkpoint this run started from, if any.
    pub warm_start: Option<WarmStart>,
}

/// Writes the checkpoints the loop hands over and counts what happened.
struct CheckpointWriter {
    path: PathBuf,
    written: u64,
    failures: u64,
    first_error: Option<String>,
    last_seq: Option<u64>,
}

impl CheckpointWriter {
    fn new(path: PathBuf) -> Self {
        Self {
            path,
            written: 0,
            failures: 0,
            first_error: None,
            last_seq: None,
        }
    }

    fn write(&mut self, c: &Checkpoint) {
        match c.write(&self.path) {
            Ok(()) => {
                self.written += 1;
                self.last_seq = Some(c.seq);
            }
            Err(e) => {
                if self.first_error.is_none() {
                    eprintln!("[service] checkpoint: {e}");
                }
                self.note_failure(e);
            }
        }
    }

    fn note_failure(&mut self, e: String) {
        self.failures += 1;
        self.first_error.get_or_insert(e);
    }
}

impl ToneReport {
    /// The human-readable table.
    pub fn render(&self) -> String {
        let mut out = format!(
            "tones of z ({}; windows of {:.3} s: {} samples at the end of the open-loop phase, {} at the end of the run):
",
            self.source, self.window_s, self.samples[0], self.samples[1]
        );
        if let Some(e) = &self.error {
            out += &format!(
                "  could not measure: {e}
"
            );
        }
        out += "  channel   tone Hz    open loop   closed loop   suppression\n";
        for t in &self.tones {
            let open = t.open.map_or("-".to_string(), |o| format!("{o:.3e}"));
            let db = t
                .suppression_db
                .map_or("-".to_string(), |d| format!("{d:.1} dB"));
            out += &format!(
                "  z{:<7} {:>8.1} {:>12} {:>13.3e} {:>13}\n",
                t.channel, t.hz, open, t.closed, db
            );
        }
        out
    }
}

impl RunReport {
    /// The human-readable report.
    pub fn render(&self) -> String {
        let s = &self.stats;
        let mut out = String::new();
        out += &format!(
            "=== run report: rig '{}', controller {}, wait {} ===\n",
            self.rig, self.controller, self.wait
        );
        out += &format!("run folder: {}\n", self.run_folder);
        out += &format!(
            "timing: {}{}\n",
            self.timing,
            match &self.plan_source {
                Some(src) => format!(", plans of {} inputs ({src})", self.plan_length),
                None => ", no plans".to_string(),
            }
        );
        out += &format!(
            "real-time set-up: {}{}\n",
            self.rt_setup,
            if self.rt_degraded {
                "  (DEGRADED: latency figures are not those of an RT setup)"
            } else {
                ""
            }
        );
        for w in &self.warnings {
            out += &format!("WARNING: {w}\n");
        }
        out += &format!("stopped: {:?}\n", self.stop_reason);
        out += &format!(
            "samples: {} received, {} answered, {} controller steps, {} caught up, {} lost{}\n",
            s.received,
            s.published,
            s.controller_steps,
            s.caught_up,
            s.skipped,
            if s.stalls_acknowledged > 0 {
                format!(", {} of injected stalls", s.stalls_acknowledged)
            } else {
                String::new()
            }
        );
        out += &format!(
            "past start-up: {} samples, {} lost ({:.2} %), {} inputs held or safe at the \
             plant ({:.2} %); {} closed-loop inputs off the safe input\n",
            s.samples_past_startup,
            s.lost_past_startup,
            100.0 * verdict::lost_share(s),
            s.held_past_startup,
            100.0 * verdict::held_share(s),
            s.inputs_off_safe
        );
        if let Some(a) = &self.adaptation {
            let total = a.updated + a.suspended.iter().map(|(_, n)| n).sum::<u64>();
            let causes: Vec<String> = a
                .suspended
                .iter()
                .map(|(c, n)| format!("{n} for {c}"))
                .collect();
            out += &format!(
                "adaptation: {} of {total} closed-loop steps updated; suspended: {}\n",
                a.updated,
                causes.join(", ")
            );
        }
        out += &format!(
            "deadline: {} misses (service-measured), {} reported by the plant ({} covered by \
             the plan, {} held or safe), longest run {}, safe state entered {}× ({} cycles)\n",
            s.deadline_misses,
            s.plant_reported_misses,
            s.plan_covered_misses,
            s.plant_reported_misses
                .saturating_sub(s.plan_covered_misses),
            s.max_consecutive_misses,
            s.safe_state_entries,
            s.safe_state_cycles
        );
        out += &format!(
            "rejected measurements: {} non-finite, {} out of range, {} contract; refused \
             sequence numbers: {} duplicate, {} backward, {} unexplained jump\n",
            s.rejected_non_finite,
            s.rejected_out_of_range,
            s.rejected_contract,
            s.rejected_duplicate,
            s.rejected_backward,
            s.rejected_jump
        );
        out += &format!(
            "plant silent {}×, resumed {}×; controller faults {}, saturated cycles {}, fallback cycles {}\n",
            s.plant_silent_events,
            s.plant_resumes,
            s.controller_faults,
            s.saturated_cycles,
            s.fallback_cycles
        );
        if !self.controller_counters.is_empty() {
            let list = self
                .controller_counters
                .iter()
                .map(|(name, v)| format!("{name} {v}"))
                .collect::<Vec<_>>()
                .join(", ");
            out += &format!("{}: {list}\n", self.controller);
        }
        let to_fix: Vec<&str> = self
            .system
            .iter()
            .filter(|f| f.verdict == crate::system_check::Verdict::Fix)
            .map(|f| f.check)
            .collect();
        if !to_fix.is_empty() {
            out += &format!(
                "system: {} of {} checks to fix ({}); `service check-system` gives the fixes\n",
                to_fix.len(),
                self.system.len(),
                to_fix.join(", ")
            );
        }
        if let Some(c) = &self.checkpoint {
            if let Some(w) = &c.warm_start {
                out += &format!("warm start: {} (taken at sample {})\n", w.path, w.seq);
            }
            out += &format!(
                "checkpoints: {} written to {}{}{}\n",
                c.written,
                c.path,
                c.last_seq
                    .map(|s| format!(", the last at sample {s}"))
                    .unwrap_or_default(),
                if c.failures > 0 {
                    format!(", {} failed", c.failures)
                } else {
                    String::new()
                }
            );
        }
        let fmt_v = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.4e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out += &format!(
            "RMS of z: [{}] (whole run), [{}] (after settling)\n",
            fmt_v(&self.z_rms),
            fmt_v(&self.z_rms_settled)
        );
        out += &format!(
            "signal log: {} records written, {} dropped (queue full), {} lost to the disk{}\n",
            self.log_written,
            self.log_dropped,
            self.log_lost_to_disk,
            self.log_first_error
                .as_deref()
                .map(|e| format!(" ({e})"))
                .unwrap_or_default()
        );
        if let Some(r) = &self.record {
            out += &format!(
                "record: {} entries written to {}, {} dropped (queue full), {} lost to the disk: {}\n",
                r.written,
                r.path,
                r.dropped,
                r.lost_to_disk,
                if r.complete {
                    "complete"
                } else {
                    "INCOMPLETE (a replay stops at the first gap)"
                }
            );
        }
        let a = &self.rt_allocations;
        if a.installed && !a.counted {
            out += "RT-thread allocations: not counted (the RT thread has no pool)\n";
        } else if a.installed {
            out += &format!(
                "RT-thread allocations: {} from the system allocator, {} served by the RT pool (iceoryx2 sample loans)\n",
                a.system_on_rt_thread, a.pool_served
            );
        }
        if let Some(t) = &self.tones {
            out += &t.render();
        }
        if let Some(f) = &self.model_following {
            out += &f.line();
        }
        if let Some(f) = &self.force_regulation {
            out += &f.lines();
        }
        out += &self.scheduling.lines();
        out += &self.latency.render_table(self.budget_ns);
        out += &self.verdict.headline();
        out.push('\n');
        out
    }
}

/// Runs the service with `cfg` until a signal sets `shutdown`, the plant ends (with
/// `exit_with_plant`), or `max_cycles` samples have been received. Prints events as they
/// happen; returns the report, which the caller prints and then writes
/// ([`RunReport::write_json`]).
pub fn run(
    cfg: &ServiceConfig,
    opts: &RunOptions,
    shutdown: Arc<AtomicBool>,
) -> Result<RunReport, ServiceError> {
    let mut cfg = cfg.clone();
    if let Some(w) = opts.wait {
        cfg.wait = w;
    }
    if let Some(c) = opts.core {
        cfg.rt.core = Some(c);
    }
    let folder = match &opts.run_folder {
        Some(f) => f.clone(),
        None => cfg.run_dir.join(format!("{}-{}", cfg.rig, timestamp())),
    };
    std::fs::create_dir_all(&folder).map_err(|error| ServiceError::Io {
        what: format!("creating run folder {}", folder.display()),
        error,
    })?;
    let mut controller = cfg
        .controller
        .build(cfg.counts)
        .map_err(ServiceError::Controller)?;
    let warm_start = match &opts.warm_start {
        Some(path) => Some(
            checkpoint::warm_start(path, &cfg, &mut *controller)
                .map_err(ServiceError::Checkpoint)?,
        ),
        None => None,
    };
    let checkpoint_slot = Arc::new(CheckpointSlot::new(&*controller));
    let mut checkpoints = CheckpointWriter::new(folder.join("checkpoint.json"));
    let controller_kind = controller.kind();
    let internal_names = controller.internal_names();

    let (tele_rt, tele_reporter) =
        telemetry::channel(cfg.budget_ns, cfg.histogram_interval_cycles, 4, &folder).map_err(
            |error| ServiceError::Io {
                what: "creating histogram logs".into(),
                error,
            },
        )?;
    let (log_producer, log_writer) = if cfg.log.enabled {
        let layout = LogLayout {
            n_y: cfg.counts.n_y as usize,
            n_z: cfg.counts.n_z as usize,
            n_u: cfg.counts.n_u as usize,
            internal_names,
            decimation: cfg.log.decimation,
        };
        let (p, w) = logging::channel(cfg.log.queue_capacity, layout);
        (Some(p), Some(w))
    } else {
        (None, None)
    };
    let (event_tx, mut event_rx) = rtrb::RingBuffer::<LoopEvent>::new(1024);
    let rt_core = cfg.rt.core;

    // Helper threads inherit this thread's affinity and policy: off the RT core, normal
    // priority. The RT thread pins itself afterwards.
    ipc_types::rt::keep_off_core(rt_core);
    let sched_watch = crate::scheduling::RunWatch::start(rt_core);
    let rt_probe = sched_watch.probe();
    let log_handle = match log_writer {
        Some(w) => Some(
            w.spawn(folder.join("signals.csv"))
                .map_err(|error| ServiceError::Io {
                    what: "starting the CSV writer".into(),
                    error,
                })?,
        ),
        None => None,
    };
    let reporter_stop = Arc::new(AtomicBool::new(false));
    let reporter_thread = {
        let stop = reporter_stop.clone();
        let mut reporter = tele_reporter;
        std::thread::Builder::new()
            .name("histograms".into())
            .spawn(move || {
                while !stop.load(Ordering::Acquire) {
                    if let Err(e) = reporter.poll() {
                        eprintln!("[service] histogram log write failed: {e}");
                    }
                    std::thread::sleep(Duration::from_millis(50));
                }
                reporter
            })
            .map_err(|error| ServiceError::Io {
                what: "starting the histogram thread".into(),
                error,
            })?
    };

    let mut core = LoopCore::new(&cfg, controller, tele_rt, log_producer, event_tx)
        .with_checkpoints(checkpoint_slot.clone());
    let record_handle = if cfg.log.record {
        // The warm start's checkpoint goes with the record: checkpoint.json is overwritten
        // by this run.
        let warm_copy = match &opts.warm_start {
            Some(path) => {
                let name = "warm-start.json";
                std::fs::copy(path, folder.join(name)).map_err(|error| ServiceError::Io {
                    what: format!(
                        "copying the warm-start checkpoint {} into the run folder",
                        path.display()
                    ),
                    error,
                })?;
                Some(name.to_string())
            }
            None => None,
        };
        let header = RecordHeader::for_run(
            &cfg,
            controller_kind,
            core.timing(),
            core.plan_length(),
            warm_copy,
        );
        let (recorder, writer) = record::channel(&header, cfg.log.queue_capacity);
        let handle = writer
            .spawn(&folder.join(record::FILE_NAME))
            .map_err(|error| ServiceError::Io {
                what: "starting the record writer".into(),
                error,
            })?;
        core = core.with_recorder(recorder);
        Some(handle)
    } else {
        None
    };
    let rt_cfg = cfg.clone();
    let rt_shutdown = shutdown.clone();
    let max_cycles = opts.max_cycles;
    let exit_with_plant = opts.exit_with_plant;
    let rt_thread = std::thread::Builder::new()
        .name("rt-loop".into())
        .spawn(move || {
            rt_probe.register();
            rt_thread_main(
                rt_cfg,
                core,
                rt_shutdown,
                max_cycles,
                exit_with_plant,
                &rt_probe,
            )
        })
        .map_err(|error| ServiceError::Io {
            what: "starting the RT thread".into(),
            error,
        })?;

    // Supervise: print events while the RT thread runs.
    let mut events = Vec::new();
    let mut drain = |events: &mut Vec<LoopEvent>| {
        while let Ok(e) = event_rx.pop() {
            eprintln!("[service] {e}");
            events.push(e);
        }
    };
    while !rt_thread.is_finished() {
        drain(&mut events);
        if let Some((mark, blocks)) = checkpoint_slot.take() {
            checkpoints.write(&Checkpoint::new(&cfg, controller_kind, mark, blocks));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let rt_result = rt_thread
        .join()
        .map_err(|_| ServiceError::RtThread("panicked".into()))?;
    drain(&mut events);
    let scheduling = sched_watch.finish();
    reporter_stop.store(true, Ordering::Release);
    let reporter = reporter_thread
        .join()
        .map_err(|_| ServiceError::RtThread("histogram thread panicked".into()))?;
    let (mut core, setup, stop_reason) = rt_result?;
    core.flush_telemetry();
    if !checkpoint_slot.is_empty() {
        // The final state, whatever the periodic ones were.
        let mark = CheckpointMark {
            seq: core.last_seq().unwrap_or(0),
            plant_session: core.stats.new_sessions + 1,
        };
        let blocks = checkpoint_slot.snapshot(core.controller());
        if blocks.iter().all(|(_, v)| v.iter().all(|x| x.is_finite())) {
            checkpoints.write(&Checkpoint::new(&cfg, controller_kind, mark, blocks));
        } else {
            checkpoints.note_failure("the final learned state is not finite; not written".into());
        }
    }
    let latency = reporter.finish().map_err(|error| ServiceError::Io {
        what: "writing histogram files".into(),
        error,
    })?;
    let mut warnings = Vec::new();
    let log = match log_handle.map(|h| h.finish()) {
        Some(Ok(st)) => LogOutcome {
            written: st.written,
            dropped: st.dropped,
            lost_to_disk: st.lost_to_disk,
            first_error: st.first_error,
            intact: st.intact,
        },
        Some(Err(e)) => {
            warnings.push(format!("the signal log writer failed: {e}"));
            LogOutcome {
                intact: false,
                first_error: Some(e.to_string()),
                ..LogOutcome::default()
            }
        }
        None => LogOutcome::default(),
    };
    let record = match record_handle.map(|h| h.finish()) {
        Some(Ok(st)) => Some(st),
        Some(Err(e)) => {
            warnings.push(format!("the record writer failed: {e}"));
            None
        }
        None => None,
    };
    if let Some(r) = record.as_ref().filter(|r| !r.complete) {
        warnings.push(format!(
            "{}: incomplete ({} of {} entries written, {} dropped (queue full), {} lost to \
             the disk{}); a replay stops at the first gap",
            r.path,
            r.written,
            r.entries,
            r.dropped,
            r.lost_to_disk,
            r.first_error
                .as_deref()
                .map(|e| format!(": {e}"))
                .unwrap_or_default()
        ));
    }
    if let Some(e) = &log.first_error {
        warnings.push(format!(
            "signals.csv: {} records lost to the disk{}: {e}",
            log.lost_to_disk,
            if log.intact {
                ""
            } else {
                " and the file may end in a torn row"
            }
        ));
    }
    for f in &latency.file_errors {
        warnings.push(format!(
            "{}: {} records lost{}",
            f.path,
            f.records_lost,
            f.first_error
                .as_deref()
                .map(|e| format!(": {e}"))
                .unwrap_or_default()
        ));
    }
    let (z_rms, z_rms_settled) = core.z_rms();
    if setup.any_refused() {
        warnings.push(format!("real-time set-up incomplete: {}", setup.describe()));
    }
    let throttled_busy_poll = cfg
        .throttled_busy_poll()
        .filter(|_| setup.fifo == ipc_types::rt::StepOutcome::Done);
    let tones = core.tones.report();
    let adaptation = core.controller.adaptation();
    let verdict = verdict::judge(&verdict::VerdictInputs {
        stats: core.stats,
        safe_state_at_end: core.safe_state_at_end(),
        limits: verdict::Limits {
            max_safe_state_share: cfg.policy.max_safe_state_share,
            max_lost_share: cfg.policy.max_lost_share,
            max_held_share: cfg.policy.max_held_share,
            max_suspended_share: cfg.policy.max_suspended_share,
            min_suppression_db: cfg.tone_report.min_suppression_db,
        },
        open_loop_cycles: cfg.open_loop_cycles,
        log_dropped: log.dropped + log.lost_to_disk,
        adaptation: adaptation.clone(),
        suppression_db: tones
            .as_ref()
            .map(|t| t.tones.iter().map(|l| (l.hz, l.suppression_db)).collect())
            .unwrap_or_default(),
        throttled_busy_poll,
        rt_core_steal: scheduling.steal.rt_core_s.zip(scheduling.loop_s),
    });
    warnings.extend(verdict.warnings.iter().cloned());
    if let Some(e) = &checkpoints.first_error {
        warnings.push(format!(
            "checkpoint: {} of {} writes failed: {e}",
            checkpoints.failures,
            checkpoints.failures + checkpoints.written
        ));
    }
    if let Some(w) = warm_start.as_ref().filter(|w| !w.same_controller_table) {
        warnings.push(format!(
            "warm start from {}: its [controller] table differs from this run's (the shapes \
             match, a value changed)",
            w.path
        ));
    }
    let report = RunReport {
        rig: cfg.rig.clone(),
        config: cfg.origin.clone(),
        run_folder: folder.display().to_string(),
        controller: controller_kind.to_string(),
        wait: format!("{:?}", cfg.wait),
        timing: core.timing().name().to_string(),
        plan_length: core.plan_length(),
        plan_source: core.plan_source().map(str::to_string),
        rt_setup: setup.describe(),
        rt_degraded: setup.any_refused(),
        warnings,
        verdict,
        stop_reason,
        stats: core.stats,
        events,
        z_rms,
        z_rms_settled,
        latency,
        log_written: log.written,
        log_dropped: log.dropped,
        log_lost_to_disk: log.lost_to_disk,
        log_first_error: log.first_error,
        record,
        budget_ns: cfg.budget_ns,
        sample_period_s: cfg.sample_period_ns as f64 * 1e-9,
        open_loop_s: cfg.open_loop_cycles as f64 * cfg.sample_period_ns as f64 * 1e-9,
        rt_allocations: core.rt_allocations,
        tones,
        adaptation: adaptation.map(AdaptationReport::from),
        model_following: core.following.report(),
        force_regulation: core.force.report(),
        system: crate::system_check::check_system(
            &crate::system_check::SystemRoot::live(),
            cfg.rt.core,
        ),
        checkpoint: (!checkpoint_slot.is_empty()).then(|| CheckpointReport {
            path: checkpoints.path.display().to_string(),
            written: checkpoints.written,
            failures: checkpoints.failures,
            first_error: checkpoints.first_error.clone(),
            last_seq: checkpoints.last_seq,
            warm_start: warm_start.clone(),
        }),
        scheduling,
        controller_counters: core
            .controller
            .counters()
            .into_iter()
            .map(|(k, v)| (k.to_string(), v))
            .collect(),
    };
    Ok(report)
}

/// What the signal-log writer reported at the end.
#[derive(Debug, Default)]
struct LogOutcome {
    written: u64,
    dropped: u64,
    lost_to_disk: u64,
    first_error: Option<String>,
    intact: bool,
}

impl RunReport {
    /// Writes the report as `report.json` into its run folder, atomically (a temporary file
    /// renamed over it): the file is the whole report or absent. Print the report first
    /// ([`RunReport::render`]), so that a full disk cannot take it from the user.
    pub fn write_json(&self) -> Result<(), ServiceError> {
        let path = Path::new(&self.run_folder).join("report.json");
        let text = serde_json::to_string_pretty(self).map_err(|e| ServiceError::Io {
            what: "serializing the run report".into(),
            error: std::io::Error::other(e),
        })?;
        ipc_types::files::write_atomic(&path, text.as_bytes()).map_err(|e| ServiceError::Io {
            what: "the run report".into(),
            error: e.into(),
        })
    }
}

fn timestamp() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0);
    format!("{secs}-{}", std::process::id())
}

#[cfg(test)]
mod tests;

/// Blocks in the RT thread's allocation pool (iceoryx2 holds at most a few at once).
pub const RT_POOL_BLOCKS: usize = 256;

type RtResult = Result<(LoopCore, RtSetup, StopReason), ServiceError>;

fn rt_thread_main(
    cfg: ServiceConfig,
    mut core: LoopCore,
    shutdown: Arc<AtomicBool>,
    max_cycles: Option<u64>,
    exit_with_plant: bool,
    probe: &crate::scheduling::RtProbe,
) -> RtResult {
    let setup = ipc_types::rt::setup_current_thread(&cfg.rt);
    if setup.any_refused() {
        eprintln!(
            "[service] WARNING: real-time set-up incomplete: {}",
            setup.describe()
        );
        if cfg.require_rt {
            return Err(ServiceError::RtRefused(setup.describe()));
        }
    }
    if setup.fifo == ipc_types::rt::StepOutcome::Done
        && let Some(w) = cfg.throttled_busy_poll()
    {
        eprintln!("[service] WARNING: {w}");
        if cfg.require_rt {
            return Err(ServiceError::RtRefused(w));
        }
    }
    let own = ContractInfo::new(Side::Service, cfg.counts, cfg.sample_period_ns)
        .with_timing(core.timing());
    let waiting = format!("[service] waiting for the plant on rig '{}' ...", cfg.rig);
    let opts = ConnectOptions::new(cfg.peer_timeout)
        .with_shutdown(&shutdown)
        .with_listener(cfg.wait != WaitMode::BusyPoll)
        .with_waiting_message(waiting.as_str());
    let ports: ServicePorts =
        match ipc_types::ports::connect(&cfg.rig, own, "adaptive-rig-service", opts) {
            Ok(p) => p,
            Err(ipc_types::ports::ConnectError::Interrupted) => {
                return Ok((core, setup, StopReason::Signal));
            }
            Err(e) => return Err(ServiceError::Connect(e)),
        };
    eprintln!(
        "[service] connected to the plant; running ({:?}, {})",
        cfg.wait,
        core.timing().name()
    );
    core.prepare_controller_thread();
    crate::rt_alloc::enter_rt_thread(RT_POOL_BLOCKS);
    let before = crate::rt_alloc::thread_stats();
    crate::rt_alloc::outside_rt(|| probe.loop_starts());
    let stop = rt_loop(
        &ports,
        &mut core,
        &shutdown,
        Pacer::new(cfg.wait, cfg.sample_period_ns, cfg.poll_window_ns),
        max_cycles,
        exit_with_plant,
    );
    core.rt_allocations = crate::rt_alloc::thread_stats().since(&before);
    crate::rt_alloc::outside_rt(|| probe.loop_ends());
    Ok((core, setup, stop))
}

/// The controller's view of measurement `m`, `lost` samples after the previous one.
fn step_input(m: &Measurement, lost: u64) -> StepInput<'_> {
    StepInput {
        seq: m.seq,
        y: m.y(),
        z: m.z(),
        r: m.r(),
        u_applied: m.u_applied(),
        lost,
    }
}

/// Measurements kept per wake-up: the subscriber's whole queue
/// ([`ipc_types::ports::SUBSCRIBER_BUFFER`]), so none is dropped here.
const PENDING: usize = ipc_types::ports::SUBSCRIBER_BUFFER;

/// Takes every pending measurement of the pinned plant, oldest first, into the ring
/// `pending` (with `new_peer[i]` true for the first sample of a plant that replaced the
/// pinned one); returns how many were taken (only the newest `PENDING` are kept when more
/// arrived). Samples of any other publisher are refused and counted by the pin
/// ([`ipc_types::peer`]).
#[inline]
fn take_pending(
    ports: &ServicePorts,
    pending: &mut [Measurement; PENDING],
    new_peer: &mut [bool; PENDING],
) -> usize {
    let mut n = 0;
    while let Ok(Some(sample)) = ports.subscriber.receive() {
        let first_of_new_peer = match ports.admit(sample.origin()) {
            Origin::Peer => false,
            Origin::NewPeer => true,
            Origin::Foreign => continue,
        };
        pending[n % PENDING] = *sample;
        new_peer[n % PENDING] = first_of_new_peer;
        n += 1;
    }
    n
}

/// The service's [`Outbox`]: its iceoryx2 publisher and notifier.
pub struct PortsOutbox<'a>(pub &'a ServicePorts);

impl Outbox for PortsOutbox<'_> {
    #[inline]
    fn publish(&mut self, act: &mut Actuation) -> (bool, u64) {
        let ports = self.0;
        let ok = match ports.publisher.loan_uninit() {
            Ok(sample) => {
                act.t_publish_ns = monotonic_ns();
                let sample = sample.write_payload(*act);
                sample.send().is_ok()
            }
            Err(_) => false,
        };
        let t_pub = monotonic_ns();
        let _ = ports.notifier.notify();
        (ok, t_pub)
    }
}

/// One pass of the RT loop: wait, process, publish. Public so that the allocation test and
/// the latency bench run exactly this code.
pub fn rt_loop(
    ports: &ServicePorts,
    core: &mut LoopCore,
    shutdown: &AtomicBool,
    mut pacer: Pacer,
    max_cycles: Option<u64>,
    exit_with_plant: bool,
) -> StopReason {
    let mut pending = [Measurement::zeroed(ChannelCounts::default()); PENDING];
    let mut new_peer = [false; PENDING];
    let mut out = PortsOutbox(ports);
    let mut spins: u32 = 0;
    let mut last_cleanup_ns = 0u64;
    let mut last_rx_ns = 0u64;
    let period_ns = core.period_ns;
    let late_ns = period_ns.saturating_add(period_ns / 2);
    let wait = pacer.mode();
    let mut left_fifo = false;
    loop {
        if shutdown.load(Ordering::Relaxed) {
            return StopReason::Signal;
        }
        let n = take_pending(ports, &mut pending, &mut new_peer);
        core.stats.foreign_samples = ports.foreign_samples();
        if n > 0 {
            let t_recv = monotonic_ns();
            last_rx_ns = t_recv;
            // Late samples first (a newer one is waiting): observed, not answered.
            let first = n.saturating_sub(PENDING);
            if (first..n).any(|i| new_peer[i % PENDING]) {
                // A replacing plant whose samples came before the loop took its ports in
                // while idle: iceoryx2 allocates when it connects to the new subscriber, so
                // connect now, outside the counted real-time work, before answering it.
                crate::rt_alloc::outside_rt(|| ports.update_connections());
            }
            for i in first..n - 1 {
                if new_peer[i % PENDING] {
                    core.note_new_peer();
                }
                core.observe(&pending[i % PENDING], &mut out);
            }
            if new_peer[(n - 1) % PENDING] {
                core.note_new_peer();
            }
            let m = &pending[(n - 1) % PENDING];
            if m.flags & measurement_flags::LOCKSTEP != 0 && !left_fifo {
                // A lockstep plant has no deadline: leave SCHED_FIFO once (a system call,
                // outside the counted real-time work), so that the ping-pong of a
                // lockstep run does not starve the normal tasks of the RT core.
                left_fifo = true;
                crate::rt_alloc::outside_rt(ipc_types::rt::leave_fifo);
            }
            pacer.on_sample(
                m.t_sample_ns,
                t_recv,
                m.flags & measurement_flags::LOCKSTEP != 0,
            );
            let d = core.handle(m, t_recv, &mut out);
            if d.last_sample && exit_with_plant {
                return StopReason::PlantEnded;
            }
            if max_cycles.is_some_and(|n| core.stats.received >= n) {
                return StopReason::MaxCycles;
            }
            continue;
        }
        match (
            pacer.next(monotonic_ns(), ports.listener.is_some()),
            &ports.listener,
        ) {
            (WaitStep::Block(timeout), Some(listener)) => {
                let _ = listener.timed_wait(|_| {}, timeout);
            }
            (WaitStep::SleepUntil(t), _) => ipc_types::clock::sleep_until_ns(t),
            _ => {
                core::hint::spin_loop();
                spins = spins.wrapping_add(1);
                if !spins.is_multiple_of(256) {
                    continue;
                }
            }
        }
        // The time first, then the look for waiting samples: had this thread itself been
        // stopped in between, the samples that came meanwhile are found and it does not
        // take its own stall for a silent plant.
        let now = monotonic_ns();
        if now.saturating_sub(last_rx_ns) > late_ns {
            // The plant is late by half a period: there is nothing to answer now. A plant
            // that replaces the last one connects while the old one is gone, and iceoryx2
            // allocates when it takes in the new ports; take them in here, outside the
            // counted real-time work, rather than in the receive or publish of the new
            // plant's first sample. Without a change this allocates nothing.
            crate::rt_alloc::outside_rt(|| ports.update_connections());
        }
        // A failing look counts as "none waiting": the silence check must stay reachable,
        // or a dead plant would never be declared silent and never cleaned up after.
        if matches!(ports.subscriber.has_samples(), Ok(true)) {
            continue;
        }
        if core.on_idle(now) && now.saturating_sub(last_cleanup_ns) > 100_000_000 {
            // Silent plant: not controlling anything now, so housekeeping is allowed here.
            last_cleanup_ns = now;
            let n = crate::rt_alloc::outside_rt(|| {
                let n = ipc_types::ports::cleanup_dead_nodes();
                ports.update_connections();
                n
            });
            core.note_cleanup(n);
            if wait == WaitMode::BusyPoll {
                std::thread::sleep(Duration::from_micros(200));
            }
        }
    }
}
