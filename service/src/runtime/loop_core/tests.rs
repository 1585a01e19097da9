//! [`LoopCore`] with a probe controller: the policies composed, and what faults do to the
//! controller. The configuration is the fixture `tests/loop-core.toml` (grace 2, two
//! misses to the safe state, two good answers out of it, silence after 5 periods).

use super::*;
use crate::config::ServiceConfig;
use crate::runtime::checkpoint_slot::CheckpointSlot;
use crate::runtime::deadline::DeadlineMonitor;
use crate::runtime::reset::ControllerResetPolicy;
use crate::runtime::session::NewSessionCause;
use crate::telemetry;
use control::Dimensions;
use control::controller::{Controller, StepInput};
use ipc_types::{
    Actuation, ChannelCounts, Measurement, Timing, actuation_status, measurement_flags,
};
use std::sync::Arc;
use std::sync::atomic::AtomicU64;
use std::sync::atomic::Ordering;

const T: u64 = 1_000_000;

/// What the probe lets the test see.
#[derive(Default)]
struct Seen {
    resets: AtomicU64,
    restarts: AtomicU64,
    last_lost: AtomicU64,
}

/// A controller whose "learned state" is the number of samples it has taken in since its
/// last reset, and whose output is that number.
struct Probe {
    learned: f64,
    seen: Arc<Seen>,
}

impl Controller for Probe {
    fn kind(&self) -> &'static str {
        "probe"
    }
    fn counts(&self) -> Dimensions {
        Dimensions::new(1, 1, 0, 1)
    }
    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        self.learned += 1.0;
        self.seen.last_lost.store(input.lost, Ordering::Relaxed);
        u[0] = self.learned;
        0
    }
    fn reset(&mut self) {
        self.learned = 0.0;
        self.seen.resets.fetch_add(1, Ordering::Relaxed);
    }
    fn restart_data(&mut self) {
        self.seen.restarts.fetch_add(1, Ordering::Relaxed);
    }
    fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
        visit("count", &[self.learned]);
    }
}

/// An [`Outbox`] that keeps what is published, stamped at a fixed time.
struct Recorder {
    sent: Vec<Actuation>,
    at: u64,
    /// Read at each publication (e.g. how far the controller had got).
    probe: Option<Arc<AtomicU64>>,
    seen_at_publish: Vec<u64>,
}

impl Recorder {
    fn at(at: u64) -> Self {
        Self {
            sent: Vec::new(),
            at,
            probe: None,
            seen_at_publish: Vec::new(),
        }
    }
}

impl Outbox for Recorder {
    fn publish(&mut self, act: &mut Actuation) -> (bool, u64) {
        act.t_publish_ns = self.at;
        self.sent.push(*act);
        if let Some(p) = &self.probe {
            self.seen_at_publish.push(p.load(Ordering::Relaxed));
        }
        (true, self.at)
    }
}

fn fixture() -> ServiceConfig {
    ServiceConfig::parse(include_str!("tests/loop-core.toml"), "loop-core.toml")
        .expect("the fixture is valid")
}

struct Harness {
    core: LoopCore,
    events: rtrb::Consumer<LoopEvent>,
    seen: Arc<Seen>,
    counts: ChannelCounts,
    /// Added to every sample time: sample `seq` is stamped `t0 + seq · T`.
    t0: u64,
    _reporter: telemetry::TelemetryReporter,
}

impl Harness {
    fn new(on_timing_fault: TimingFaultReset) -> Self {
        Self::with(on_timing_fault, |_| {})
    }

    /// A harness on the fixture changed by `edit`.
    fn with(on_timing_fault: TimingFaultReset, edit: impl FnOnce(&mut ServiceConfig)) -> Self {
        let mut cfg = fixture();
        edit(&mut cfg);
        let seen = Arc::new(Seen::default());
        let probe = Probe {
            learned: 0.0,
            seen: seen.clone(),
        };
        let (tele, reporter) = telemetry::channel_in_memory(cfg.budget_ns, 1000, 1);
        let (tx, events) = rtrb::RingBuffer::new(64);
        let core = LoopCore::new(&cfg, Box::new(probe), tele, None, tx)
            .with_timing_fault_reset(on_timing_fault);
        Self {
            core,
            events,
            seen,
            counts: cfg.counts,
            t0: 1,
            _reporter: reporter,
        }
    }

    /// The sample time of `seq`.
    fn at(&self, seq: u64) -> u64 {
        self.t0 + seq * T
    }

    /// Sample `seq`, received at its sample time, with `y = y0` and `flags`.
    fn sample(&self, seq: u64, y0: f64, flags: u32) -> Measurement {
        let mut m = Measurement::zeroed(self.counts);
        m.seq = seq;
        m.t_sample_ns = self.at(seq);
        m.y[0] = y0;
        m.flags = flags;
        m
    }

    /// Processes `m` received at its sample time, publishing 1 µs later; returns the main
    /// answer (published last), or `None` when the sample is not answered.
    fn deliver(&mut self, m: &Measurement) -> Option<Actuation> {
        let mut out = Recorder::at(m.t_sample_ns + 1000);
        let d = self.core.handle(m, m.t_sample_ns, &mut out);
        d.answer
            .then(|| *out.sent.last().expect("an answered sample publishes"))
    }

    /// Sample `seq` arrives at its sample time with `y = y0` and `flags`; returns the
    /// actuation.
    fn answer_with(&mut self, seq: u64, y0: f64, flags: u32) -> Actuation {
        let m = self.sample(seq, y0, flags);
        self.deliver(&m).expect("the sample is answered")
    }

    /// Sample `seq`, on time (`'.'`) or reporting that the previous actuation missed
    /// (`'P'`); returns its status bits and input.
    fn answer(&mut self, seq: u64, kind: char) -> (u32, f64) {
        let flags = match kind {
            'P' => measurement_flags::PREVIOUS_ACTUATION_MISSED,
            _ => 0,
        };
        let act = self.answer_with(seq, 0.0, flags);
        (act.status, act.u[0])
    }

    fn events(&mut self) -> Vec<LoopEvent> {
        std::iter::from_fn(|| self.events.pop().ok()).collect()
    }

    fn resets(&self) -> u64 {
        self.seen.resets.load(Ordering::Relaxed)
    }

    fn restarts(&self) -> u64 {
        self.seen.restarts.load(Ordering::Relaxed)
    }
}

use TimingFaultReset::{KeepLearned, ResetController};
use actuation_status::{MEASUREMENT_REJECTED, SAFE_STATE, STARTING};

#[test]
fn a_core_built_from_the_configuration_keeps_what_the_controller_learned_through_a_timing_fault() {
    let cfg = fixture();
    let (tele, _reporter) = telemetry::channel_in_memory(cfg.budget_ns, 1000, 1);
    let controller = cfg
        .controller
        .build(cfg.counts)
        .expect("the fixture's controller");
    let core = LoopCore::new(&cfg, controller, tele, None, rtrb::RingBuffer::new(1).0);
    assert_eq!(
        core.reset_policy(),
        ControllerResetPolicy {
            on_timing_fault: KeepLearned,
            reset_on_resume: false,
        }
    );
}

#[test]
fn leaving_the_safe_state_resets_the_controller_only_when_configured() {
    // (policy, resets, input of the first closed-loop answer after the safe state)
    let table = [(KeepLearned, 0, 8.0), (ResetController, 1, 1.0)];
    for (policy, resets, u_after) in table {
        let mut h = Harness::new(policy);
        let script = "...PP..";
        let said: Vec<(u32, f64)> = script
            .chars()
            .enumerate()
            .map(|(k, c)| h.answer(k as u64, c))
            .collect();
        let statuses: Vec<u32> = said.iter().map(|s| s.0).collect();
        assert_eq!(
            statuses,
            [STARTING, STARTING, 0, 0, 0, SAFE_STATE, SAFE_STATE],
            "{policy:?}"
        );
        // In the safe state the safe input goes out and the controller only observes.
        assert_eq!((said[5].1, said[6].1), (0.5, 0.5), "{policy:?}");
        assert_eq!(
            h.events(),
            [
                LoopEvent::FirstSample { seq: 0 },
                LoopEvent::SafeStateEntered { seq: 4, misses: 2 },
                LoopEvent::SafeStateLeft { seq: 6 },
            ],
            "{policy:?}"
        );
        assert_eq!(h.answer(7, '.'), (0, u_after), "{policy:?}");
        assert_eq!(h.resets(), resets, "{policy:?}");
        assert_eq!(
            (
                h.core.stats.safe_state_entries,
                h.core.stats.safe_state_cycles
            ),
            (1, 2)
        );
    }
}

#[test]
fn a_stalled_plant_resumes_its_session_and_the_controller_hears_of_the_gap() {
    // (policy, resets, input of the first answer after the stall)
    let table = [(KeepLearned, 0, 6.0), (ResetController, 1, 1.0)];
    for (policy, resets, u_after) in table {
        let mut h = Harness::new(policy);
        for k in 0..5 {
            h.answer(k, '.');
        }
        assert!(!h.core.on_idle(h.at(4) + 5 * T), "{policy:?}");
        assert!(h.core.on_idle(h.at(4) + 5 * T + 1), "{policy:?}");
        // The plant's watchdog flagged the missing actuation: no miss on a new connection.
        let (status, u) = h.answer(20, 'P');
        assert_eq!((status, u), (STARTING, u_after), "{policy:?}");
        assert_eq!(h.seen.last_lost.load(Ordering::Relaxed), 15, "{policy:?}");
        assert_eq!(h.resets(), resets, "{policy:?}");
        assert_eq!(
            h.events()[1..],
            [
                LoopEvent::PlantSilent {
                    last_seq: 4,
                    periods: 5
                },
                LoopEvent::PlantResumed { seq: 20 },
            ],
            "{policy:?}"
        );
        let s = h.core.stats;
        assert_eq!(
            (s.plant_silent_events, s.plant_resumes, s.skipped),
            (1, 1, 15),
            "{policy:?}"
        );
        assert_eq!((s.plant_reported_misses, s.deadline_misses), (0, 0));
    }
}

#[test]
fn a_plant_restarted_from_zero_after_silence_is_a_new_session_that_keeps_what_was_learned() {
    // (timing-fault policy, reset-on-resume, input of the first answer, resets, data
    // restarts): by default the controller keeps its 5 samples and restarts its history.
    let table = [
        (KeepLearned, false, 6.0, 0, 1),
        (ResetController, false, 6.0, 0, 1),
        (KeepLearned, true, 1.0, 1, 0),
    ];
    for (policy, reset_on_resume, u, resets, restarts) in table {
        let mut h = Harness::with(policy, |c| c.policy.reset_on_resume = reset_on_resume);
        for k in 0..5 {
            h.answer(k, '.');
        }
        assert!(h.core.on_idle(100 * T), "{policy:?}");
        h.t0 = 200 * T;
        assert_eq!(h.answer(0, '.'), (STARTING, u), "{policy:?}");
        assert_eq!(h.seen.last_lost.load(Ordering::Relaxed), 0, "{policy:?}");
        assert_eq!((h.resets(), h.restarts()), (resets, restarts), "{policy:?}");
        assert_eq!(
            h.events()[2..],
            [
                LoopEvent::PlantResumed { seq: 0 },
                LoopEvent::NewPlantSession {
                    from: 4,
                    to: 0,
                    cause: NewSessionCause::RestartAfterSilence,
                    left_safe_state: false
                },
            ],
            "{policy:?}"
        );
        assert_eq!((h.core.stats.plant_resumes, h.core.stats.skipped), (1, 0));
    }
}

#[test]
fn a_rejected_measurement_holds_the_last_input_and_never_reaches_the_controller() {
    let mut h = Harness::new(KeepLearned);
    let inputs: Vec<(u32, f64)> = [0.0, f64::NAN, 11.0, 0.0]
        .iter()
        .enumerate()
        .map(|(k, y)| {
            let a = h.answer_with(k as u64, *y, 0);
            (a.status & !STARTING, a.u[0])
        })
        .collect();
    assert_eq!(
        inputs,
        [
            (0, 1.0),
            (MEASUREMENT_REJECTED, 1.0),
            (MEASUREMENT_REJECTED, 1.0),
            (0, 2.0)
        ]
    );
    let s = h.core.stats;
    assert_eq!(
        (
            s.rejected_non_finite,
            s.rejected_out_of_range,
            s.controller_steps
        ),
        (1, 1, 2)
    );
}

#[test]
fn duplicate_and_backward_numbers_of_a_talking_plant_are_refused_unanswered_and_reset_nothing() {
    let mut h = Harness::new(KeepLearned);
    for k in 0..5 {
        h.answer(k, '.');
    }
    for stray in [4, 2, 0] {
        let m = h.sample(stray, 0.0, 0);
        assert!(h.deliver(&m).is_none(), "seq {stray} is not answered");
    }
    // The stream goes on: the controller took in 5 samples and now its sixth.
    assert_eq!(h.answer(5, '.'), (0, 6.0));
    assert_eq!(h.resets(), 0);
    let s = h.core.stats;
    assert_eq!(
        (
            s.rejected_duplicate,
            s.rejected_backward,
            s.new_sessions,
            s.published
        ),
        (1, 2, 0, 6)
    );
    assert_eq!(h.events(), [LoopEvent::FirstSample { seq: 0 }]);
}

#[test]
fn a_new_publisher_begins_a_new_session_out_of_the_safe_state() {
    let mut h = Harness::new(KeepLearned);
    for (k, c) in "...PP".chars().enumerate() {
        h.answer(k as u64, c);
    }
    assert!(h.answer(5, '.').0 & SAFE_STATE != 0);
    h.core.note_new_peer();
    let (status, u) = h.answer(6, '.');
    assert_eq!(
        (status, u),
        (STARTING, 7.0),
        "a fresh session; the controller keeps its 6 samples"
    );
    assert_eq!(
        h.events()[2..],
        [LoopEvent::NewPlantSession {
            from: 5,
            to: 6,
            cause: NewSessionCause::NewPeer,
            left_safe_state: true
        }]
    );
    assert_eq!(
        (h.core.stats.new_sessions, h.resets(), h.restarts()),
        (1, 0, 1)
    );
}

#[test]
fn every_checkpoint_interval_the_learned_state_goes_to_the_slot_and_a_busy_slot_skips() {
    let mut h = Harness::with(KeepLearned, |c| c.checkpoint_every_cycles = 3);
    let probe = Probe {
        learned: 0.0,
        seen: Arc::new(Seen::default()),
    };
    let slot = Arc::new(CheckpointSlot::new(&probe));
    h.core = h.core.with_checkpoints(slot.clone());
    for k in 0..7 {
        h.answer(k, '.');
    }
    // Offered after answers 3 and 6 (seq 2 and 5): the newest is taken.
    let (mark, blocks) = slot.take().expect("a checkpoint");
    assert_eq!((mark.seq, mark.plant_session), (5, 1));
    assert_eq!(blocks, [("count".to_string(), vec![6.0])]);
    for k in 7..16 {
        h.answer(k, '.');
    }
    // Offers at seq 8, 11, 14: two buffers, the third offer is skipped.
    let s = h.core.stats;
    assert_eq!((s.checkpoints_taken, s.checkpoints_skipped), (4, 1));
    assert_eq!(slot.take().unwrap().0.seq, 11);
}

#[test]
fn misses_in_the_open_loop_phase_do_not_send_the_loop_to_the_safe_state() {
    let mut h = Harness::with(KeepLearned, |cfg| cfg.open_loop_cycles = 7);
    let statuses: Vec<u32> = "..PPPPP.."
        .chars()
        .enumerate()
        .map(|(k, c)| h.answer(k as u64, c).0)
        .collect();
    assert!(statuses.iter().all(|s| s & SAFE_STATE == 0), "{statuses:?}");
    let s = h.core.stats;
    assert_eq!(
        (
            s.safe_state_entries,
            s.protected_misses,
            s.plant_reported_misses
        ),
        (0, 5, 5)
    );
}

#[test]
fn a_u_applied_the_service_did_not_send_raises_the_alarm_once_per_run() {
    let mut h = Harness::new(KeepLearned);
    let flags = measurement_flags::U_APPLIED;
    let with_applied = |h: &mut Harness, seq: u64, applied: f64| {
        let mut m = h.sample(seq, 0.0, flags);
        m.u_applied[0] = applied;
        h.deliver(&m).expect("answered").u[0]
    };
    // The probe sends u_k = k + 1; the plant reports what it applied after sample k − 1.
    assert_eq!(with_applied(&mut h, 0, 0.0), 1.0);
    assert_eq!(with_applied(&mut h, 1, 1.0), 2.0);
    with_applied(&mut h, 2, 50.0);
    with_applied(&mut h, 3, 50.0);
    with_applied(&mut h, 4, 4.0);
    assert_eq!(h.core.stats.foreign_actuations, 2);
    assert_eq!(
        h.events()[1..],
        [LoopEvent::ForeignActuation {
            seq: 2,
            difference: 48.0
        }]
    );
}

#[test]
fn an_impossible_sample_time_is_counted_and_kept_out_of_the_late_count() {
    let mut h = Harness::with(KeepLearned, |cfg| {
        cfg.policy.miss_source = crate::config::MissSource::ResponseTime;
    });
    for k in 0..4 {
        h.answer(k, '.');
    }
    let mut m = h.sample(4, 0.0, 0);
    m.t_sample_ns = 0;
    m.deadline_ns = 1;
    let mut out = Recorder::at(h.at(4) + 1000);
    assert!(h.core.handle(&m, h.at(4), &mut out).answer);
    let s = h.core.stats;
    assert_eq!((s.impossible_timestamps, s.deadline_misses), (1, 0));
}

// ---------------------------------------------------------------------------------------
// The ahead timings (answer-first, send-ahead) and plans, with a probe that has an ahead
// form.

/// What the ahead probe lets the test see.
#[derive(Default)]
struct AheadSeen {
    /// `advance` calls so far, and those that adapted.
    advances: Arc<AtomicU64>,
    adapted: AtomicU64,
    /// The `applied` input of the last `advance`, as bits.
    last_applied: AtomicU64,
}

/// A controller with an ahead form: its ready input is `100 + adaptations`, its plan row
/// `j` is `1000 + 10 · adaptations + j`, `rows` of them (row `nan_row` not finite).
struct AheadProbe {
    adapted: u64,
    rows: usize,
    nan_row: Option<usize>,
    seen: Arc<AheadSeen>,
}

impl Controller for AheadProbe {
    fn kind(&self) -> &'static str {
        "ahead-probe"
    }
    fn counts(&self) -> Dimensions {
        Dimensions::new(1, 1, 0, 1)
    }
    fn step(&mut self, _input: &StepInput<'_>, u: &mut [f64]) -> u32 {
        u[0] = -1.0;
        0
    }
    fn reset(&mut self) {
        self.adapted = 0;
    }
    fn ahead(&mut self) -> Option<&mut dyn control::Ahead> {
        Some(self)
    }
}

impl control::Ahead for AheadProbe {
    fn ready(&self, u: &mut [f64]) -> u32 {
        u[0] = 100.0 + self.adapted as f64;
        0
    }
    fn advance(&mut self, _input: &StepInput<'_>, applied: &[f64], adapt: bool) -> u32 {
        self.seen.advances.fetch_add(1, Ordering::Relaxed);
        self.seen
            .last_applied
            .store(applied[0].to_bits(), Ordering::Relaxed);
        if adapt {
            self.adapted += 1;
            self.seen.adapted.fetch_add(1, Ordering::Relaxed);
        }
        0
    }
    fn plan(&mut self, out: &mut [f64]) -> usize {
        let n = self.rows.min(out.len());
        for (j, v) in out.iter_mut().take(n).enumerate() {
            *v = if Some(j) == self.nan_row {
                f64::NAN
            } else {
                1000.0 + 10.0 * self.adapted as f64 + j as f64
            };
        }
        n
    }
    fn plan_source(&self) -> &'static str {
        "the probe's rows"
    }
}

/// A loop core on the fixture running `timing` with plans of `plan_length`, its controller
/// an [`AheadProbe`] with `rows` plan rows.
fn ahead_core(
    timing: Timing,
    plan_length: usize,
    rows: usize,
    nan_row: Option<usize>,
) -> (LoopCore, Arc<AheadSeen>, ChannelCounts) {
    let mut cfg = fixture();
    cfg.answer = crate::config::AnswerTiming {
        timing,
        plan_length,
    };
    let seen = Arc::new(AheadSeen::default());
    let probe = AheadProbe {
        adapted: 0,
        rows,
        nan_row,
        seen: seen.clone(),
    };
    let (tele, _reporter) = telemetry::channel_in_memory(cfg.budget_ns, 1000, 1);
    let core = LoopCore::new(
        &cfg,
        Box::new(probe),
        tele,
        None,
        rtrb::RingBuffer::new(64).0,
    );
    (core, seen, cfg.counts)
}

/// Sample `seq` at `seq · T` with `flags`, reporting `u_applied` when given.
fn sample_at(counts: ChannelCounts, seq: u64, flags: u32) -> Measurement {
    let mut m = Measurement::zeroed(counts);
    m.seq = seq;
    m.t_sample_ns = 1 + seq * T;
    m.period_ns = T;
    m.flags = flags;
    m
}

/// Handles sample `seq`; returns what was published for it, in order.
fn publish_for(core: &mut LoopCore, counts: ChannelCounts, seq: u64, flags: u32) -> Recorder {
    let m = sample_at(counts, seq, flags);
    let mut out = Recorder::at(m.t_sample_ns + 1000);
    core.handle(&m, m.t_sample_ns, &mut out);
    out
}

#[test]
fn answer_first_publishes_the_prepared_input_before_the_controller_takes_the_sample_in() {
    let (mut core, seen, counts) = ahead_core(Timing::AnswerFirst, 0, 0, None);
    assert_eq!(core.timing(), Timing::AnswerFirst);
    for k in 0..5u64 {
        let m = sample_at(counts, k, 0);
        let mut out = Recorder::at(m.t_sample_ns + 1000);
        out.probe = Some(seen.advances.clone());
        core.handle(&m, m.t_sample_ns, &mut out);
        assert_eq!(out.sent.len(), 1, "one answer per sample");
        let a = out.sent[0];
        assert_eq!((a.seq, a.reply_to), (k, k));
        assert_eq!(a.timing, Timing::AnswerFirst.wire());
        // Published while the controller had taken in only the samples before k …
        assert_eq!(out.seen_at_publish, [k], "sample {k}");
        // … and its input is the one prepared by them.
        assert_eq!(a.u[0], 100.0 + k as f64);
    }
    // The controller took every sample in, and was told the input it had given.
    assert_eq!(seen.adapted.load(Ordering::Relaxed), 5);
    assert_eq!(
        f64::from_bits(seen.last_applied.load(Ordering::Relaxed)),
        104.0
    );
    assert_eq!(core.stats.controller_steps, 5);
}

#[test]
fn compute_first_runs_the_step_before_it_publishes() {
    // The probe's step answers −1: compute-first never uses its ahead form.
    let (mut core, seen, counts) = ahead_core(Timing::ComputeFirst, 0, 0, None);
    let out = publish_for(&mut core, counts, 0, 0);
    assert_eq!(out.sent.len(), 1);
    assert_eq!(out.sent[0].u[0], -1.0);
    assert_eq!(seen.advances.load(Ordering::Relaxed), 0);
}

#[test]
fn send_ahead_publishes_the_next_input_at_once_and_answers_a_sample_nothing_went_ahead_for() {
    let (mut core, seen, counts) = ahead_core(Timing::SendAhead, 0, 0, None);
    // The first sample of the session: nothing went ahead for it, so it is answered with
    // the prepared input, then the input for sample 1 goes out.
    let out = publish_for(&mut core, counts, 0, 0);
    let got: Vec<(u64, u64, f64)> = out
        .sent
        .iter()
        .map(|a| (a.seq, a.reply_to, a.u[0]))
        .collect();
    assert_eq!(got, [(0, 0, 100.0), (1, 0, 101.0)]);
    assert_eq!(
        f64::from_bits(seen.last_applied.load(Ordering::Relaxed)),
        100.0,
        "the controller is told the input sent for sample 0"
    );
    // Then one publication per sample: the input for the next.
    for k in 1..4u64 {
        let out = publish_for(&mut core, counts, k, 0);
        let got: Vec<(u64, u64)> = out.sent.iter().map(|a| (a.seq, a.reply_to)).collect();
        assert_eq!(got, [(k + 1, k)]);
    }
    assert_eq!((core.stats.published, core.stats.published_extra), (4, 1));
    // A stall: sample 4 reaches the loop late (5 waits), so nothing went ahead for 5.
    let late = sample_at(counts, 4, 0);
    let mut out = Recorder::at(0);
    core.observe(&late, &mut out);
    assert!(out.sent.is_empty(), "a late sample is not answered");
    assert_eq!(
        f64::from_bits(seen.last_applied.load(Ordering::Relaxed)),
        104.0,
        "the input sent ahead for 4 is what the plant applied"
    );
    let out = publish_for(&mut core, counts, 5, 0);
    let got: Vec<(u64, u64)> = out.sent.iter().map(|a| (a.seq, a.reply_to)).collect();
    assert_eq!(got, [(5, 5), (6, 5)]);
    assert_eq!(core.stats.caught_up, 1);
}

#[test]
fn a_send_ahead_answer_is_late_only_after_the_next_samples_deadline() {
    let (mut core, _, counts) = ahead_core(Timing::SendAhead, 0, 0, None);
    // ResponseTime: the service's own measurement decides; deadline 0 = at the sample.
    core.deadline = DeadlineMonitor::new(&crate::config::DeadlinePolicy {
        miss_source: crate::config::MissSource::ResponseTime,
        ..fixture().policy
    });
    for (k, response) in [(0u64, 0.5), (1, 0.9), (2, 1.1), (3, 0.2)] {
        let m = sample_at(counts, k, 0);
        let mut out = Recorder::at(m.t_sample_ns + (response * T as f64) as u64);
        core.handle(&m, m.t_sample_ns, &mut out);
    }
    assert_eq!(
        core.stats.deadline_misses, 1,
        "only the answer 1.1 T after its sample"
    );
}

#[test]
fn an_answer_carries_the_controllers_plan_up_to_the_configured_length_and_its_first_non_finite_row()
{
    let (mut core, _, counts) = ahead_core(Timing::SendAhead, 4, 10, None);
    let out = publish_for(&mut core, counts, 0, 0);
    // The answer for sample 0 itself carries the plan of the start-up state.
    let first = out.sent[0];
    assert_eq!(first.plan_len, 4);
    assert_eq!(first.plan[3][0], 1003.0);
    let a = out.sent[1];
    assert_eq!(
        a.plan_len, 4,
        "the configured length, not the 10 rows the probe has"
    );
    let rows: Vec<f64> = (0..4).map(|j| a.plan[j][0]).collect();
    assert_eq!(rows, [1010.0, 1011.0, 1012.0, 1013.0]);
    assert_eq!(a.input_for(3), Some(&[1011.0][..]));

    let (mut core, _, counts) = ahead_core(Timing::SendAhead, 8, 8, Some(2));
    let out = publish_for(&mut core, counts, 0, 0);
    assert_eq!(out.sent[1].plan_len, 2, "cut before the NaN row");
    assert!(out.sent[1].plan.iter().flatten().all(|v| v.is_finite()));

    let (mut core, _, counts) = ahead_core(Timing::AnswerFirst, 3, 10, None);
    publish_for(&mut core, counts, 0, 0);
    let out = publish_for(&mut core, counts, 1, 0);
    let a = out.sent[0];
    assert_eq!((a.seq, a.u[0], a.plan_len), (1, 101.0, 3));
    assert_eq!(
        a.plan[0][0], 1010.0,
        "the plan made with the input, for samples 2, 3, 4"
    );
}

#[test]
fn a_sample_of_an_injected_stall_is_taken_in_and_acknowledged_never_answered() {
    let (mut core, seen, counts) = ahead_core(Timing::SendAhead, 2, 2, None);
    publish_for(&mut core, counts, 0, measurement_flags::LOCKSTEP);
    let stalled = measurement_flags::LOCKSTEP | measurement_flags::INJECTED_STALL;
    for k in 1..3u64 {
        let m = sample_at(counts, k, stalled);
        let mut out = Recorder::at(m.t_sample_ns + 1000);
        let d = core.handle(&m, m.t_sample_ns, &mut out);
        assert!(!d.answer);
        let got: Vec<(u64, u32)> = out.sent.iter().map(|a| (a.reply_to, a.status)).collect();
        assert_eq!(got, [(k, actuation_status::STALL_ACK)], "sample {k}");
    }
    // Taken in without adaptation: sample 1 with the input sent ahead for it, sample 2
    // with the entry of the plan of the answer for 1.
    assert_eq!(seen.advances.load(Ordering::Relaxed), 3);
    assert_eq!(seen.adapted.load(Ordering::Relaxed), 1);
    assert_eq!(
        f64::from_bits(seen.last_applied.load(Ordering::Relaxed)),
        1010.0
    );
    // The next sample: nothing went ahead for it, so it is answered at once.
    let out = publish_for(&mut core, counts, 3, measurement_flags::LOCKSTEP);
    let got: Vec<(u64, u64)> = out.sent.iter().map(|a| (a.seq, a.reply_to)).collect();
    assert_eq!(got, [(3, 3), (4, 3)]);
    assert_eq!(core.stats.stalls_acknowledged, 2);
    // In real time the flag means nothing: such a sample is answered.
    let out = publish_for(&mut core, counts, 4, measurement_flags::INJECTED_STALL);
    assert_eq!(out.sent.len(), 1);
    assert_eq!(out.sent[0].status & actuation_status::STALL_ACK, 0);
}

#[test]
fn plan_covered_misses_are_counted_apart_and_do_not_send_the_service_to_its_safe_state() {
    let (mut core, _, counts) = ahead_core(Timing::SendAhead, 4, 4, None);
    let covered = measurement_flags::PREVIOUS_ACTUATION_MISSED | measurement_flags::PLAN_APPLIED;
    for k in 0..3 {
        publish_for(&mut core, counts, k, 0);
    }
    for k in 3..10 {
        publish_for(&mut core, counts, k, covered);
    }
    let s = core.stats;
    assert_eq!((s.plant_reported_misses, s.plan_covered_misses), (7, 7));
    assert_eq!(
        s.safe_state_entries, 0,
        "the fixture enters it after 2 misses"
    );
    // Two uncovered ones do.
    for k in 10..12 {
        publish_for(
            &mut core,
            counts,
            k,
            measurement_flags::PREVIOUS_ACTUATION_MISSED,
        );
    }
    assert_eq!(core.stats.safe_state_entries, 1);
    // In the safe state the answers sent ahead are the safe input, and so is their plan.
    let out = publish_for(&mut core, counts, 12, 0);
    let a = out.sent[0];
    assert_eq!((a.seq, a.u[0], a.plan_len), (13, 0.5, 4));
    assert!(a.plan[..4].iter().all(|row| row[0] == 0.5));
    assert_ne!(a.status & SAFE_STATE, 0);
}

#[test]
fn a_controller_without_an_ahead_form_runs_compute_first_whatever_the_configuration() {
    let mut h = Harness::with(KeepLearned, |c| {
        c.answer = crate::config::AnswerTiming {
            timing: Timing::SendAhead,
            plan_length: 8,
        };
    });
    assert_eq!(
        (h.core.timing(), h.core.plan_length()),
        (Timing::ComputeFirst, 0)
    );
    let a = h.answer_with(0, 0.0, 0);
    assert_eq!((a.seq, a.reply_to, a.plan_len), (0, 0, 0));
}
