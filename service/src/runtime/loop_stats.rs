//! The counters of the RT loop, readable at any time and copied into the run report.

use serde::Serialize;

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
    /// observed them ([`Controller::observe`](control::controller::Controller::observe)) and only the newest was answered.
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
    /// Operator commands applied ([`crate::runtime::operator`]).
    pub commands_applied: u64,
    /// Operator commands refused (nothing changed).
    pub commands_refused: u64,
    /// Samples and states the live view did not get because its ring was full.
    pub telemetry_dropped: u64,
}
