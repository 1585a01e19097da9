//! The rules of the timing protocol (`docs/timing-protocol.md`), each stated once, as pure
//! functions: inputs in, decision out; no I/O, no clock, no allocation, no panic, so that
//! the RT loops of both sides call them.
//!
//! Every place that applies a rule calls it from here: the plant's book of actuations and
//! its watchdog (`plant-side`), the service's RT loop and its record of what it sent
//! (`service`), the configuration checks, the connect check ([`crate::ports`]) and
//! [`Actuation::input_for`]. The Python package (`adaptive_rig/timing_rules.py`) states
//! the same rules; both are run against the one file of test vectors,
//! `ipc-types/tests/vectors/timing.json`.
//!
//! # The rules
//!
//! With `T` the period, `d ∈ [0, 1]` the plant's deadline fraction, `k` a sample,
//! `lead` = 1 for send-ahead and 0 otherwise ([`Timing::lead`]):
//!
//! | rule | definition | function |
//! | --- | --- | --- |
//! | when the plant applies | lockstep; at the sample instant when `d = 0`; else at `kT + dT` | [`applies`] |
//! | deadline offset | `D = ⌊d T⌋` ns in real time, 0 in lockstep | [`deadline_offset_ns`] |
//! | application instant | `t_k + D` | [`application_instant`] |
//! | a plant and a service can meet | a plant applying at the sample needs send-ahead | [`timings_meet`] |
//! | the answer's sample | `k + lead` (wrapping) | [`answer_seq`] |
//! | the extra answer | send-ahead answers `k` itself when nothing went ahead for it | [`answers_sample_itself`] |
//! | the answer's deadline (service-measured) | `D_k + lead·T`, none in lockstep | [`answer_deadline_ns`] |
//! | a late answer | `t_publish − t_k > D` with `D > 0` and a possible sample time | [`answer_late`] |
//! | what an actuation carries for `k` | `u` at `k = seq`, plan row `j = k − seq − 1 < plan_len` | [`carried`], [`plan_row`] |
//! | the measurement it answers | `max(reply_to, seq − lead)` | [`answered_measurement`] |
//! | a valid actuation | contract version, `n_u`, `plan_len ≤ MAX_PLAN`, finite `u` and plan rows | [`actuation_valid`] |
//! | what an arriving actuation is | stall acknowledgement, invalid, late (`seq < k`), in time | [`arrival`] |
//! | the newest plan | a plan replaces the held one when its `seq` is not older | [`plan_supersedes`] |
//! | a miss | the plan row for `k`, else the policy's hold or safe | [`on_miss`] |
//! | the watchdog | trips at `watchdog-periods` consecutive misses; its safe output overrides all | [`watchdog_trips`], [`applied`] |
//! | the plant's report | `PREVIOUS_ACTUATION_MISSED`, `PLAN_APPLIED`, `PLANT_SAFE_OUTPUT` | [`report_flags`], [`reported`] |
//! | what the service expects applied | what it sent, else the newest plan's row, else held, else safe | [`expected_input`] |
//! | the timing a service runs | `auto` and the controller's ahead form; plans only with ahead timings | [`resolve_timing`], [`plan_length`], [`effective_timing`] |
//!
//! Sequence numbers are `u64` and never wrap in a run; the functions are still total over
//! the whole range (a plan row past `u64::MAX` is not covered; [`answer_seq`] wraps).

use crate::ports::Applies;
use crate::{
    Actuation, CONTRACT_VERSION, MAX_PLAN, MAX_U, Timing, actuation_status, measurement_flags,
};
use serde::{Deserialize, Serialize};

// ---- when the plant applies an input ----

/// When a plant applies the input of a sample: in lockstep it waits for each answer; in
/// real time at the sample instant when its deadline fraction `d` is 0 (a DAC latched on
/// the sample clock), else at `kT + dT`.
pub fn applies(lockstep: bool, deadline_fraction: f64) -> Applies {
    if lockstep {
        Applies::Lockstep
    } else if deadline_fraction == 0.0 {
        Applies::AtSample
    } else {
        Applies::AtDeadline
    }
}

/// The deadline offset `D` a plant carries in [`crate::Measurement::deadline_ns`]: `d·T`
/// nanoseconds (truncated) in real time, 0 in lockstep (no deadline: the plant waits).
pub fn deadline_offset_ns(lockstep: bool, deadline_fraction: f64, period_ns: u64) -> u64 {
    if lockstep {
        0
    } else {
        (deadline_fraction * period_ns as f64) as u64
    }
}

/// The instant a real-time plant applies the input of the sample taken at `t_sample_ns`:
/// `t_k + D` (saturating).
pub const fn application_instant(t_sample_ns: u64, deadline_offset_ns: u64) -> u64 {
    t_sample_ns.saturating_add(deadline_offset_ns)
}

/// True when a plant that applies as `plant` can be served by a service of `timing`: only a
/// service that sends ahead puts the input there before the sample instant.
pub const fn timings_meet(plant: Applies, timing: Timing) -> bool {
    !matches!(plant, Applies::AtSample) || matches!(timing, Timing::SendAhead)
}

// ---- what the service answers, and when it is late ----

/// The sample whose input the service's main answer to measurement `k` is for: `k + lead`
/// (wrapping at `u64::MAX`).
pub const fn answer_seq(k: u64, timing: Timing) -> u64 {
    k.wrapping_add(timing.lead())
}

/// True when the service, besides its main answer, answers sample `k` itself: with
/// send-ahead, when no input was sent ahead for `k` (the first sample of a session, one
/// after a stall).
pub const fn answers_sample_itself(timing: Timing, sent_ahead_for_k: bool) -> bool {
    matches!(timing, Timing::SendAhead) && !sent_ahead_for_k
}

/// The plant's deadline for the service's answer to measurement `k`, in ns after `t_k`:
/// the sample's `deadline_ns` plus `lead·T` (an input sent ahead is due at the next
/// sample's deadline), saturating; 0 (none) in lockstep.
pub const fn answer_deadline_ns(
    lockstep: bool,
    deadline_ns: u64,
    period_ns: u64,
    timing: Timing,
) -> u64 {
    if lockstep {
        0
    } else {
        deadline_ns.saturating_add(timing.lead().saturating_mul(period_ns))
    }
}

/// True when an answer is late by the service's measurement: a deadline was given
/// (`deadline_ns > 0`), the sample time is possible, and the response time (sample to
/// publication) is past the deadline. An answer exactly at the deadline is in time.
pub const fn answer_late(timestamp_ok: bool, deadline_ns: u64, response_ns: u64) -> bool {
    timestamp_ok && deadline_ns > 0 && response_ns > deadline_ns
}

// ---- what an actuation carries, and what it answers ----

/// The plan rows an actuation declaring `plan_len` holds: `min(plan_len, MAX_PLAN)`.
pub const fn plan_rows(plan_len: u32) -> usize {
    let n = plan_len as usize;
    if n < MAX_PLAN { n } else { MAX_PLAN }
}

/// The plan row of an actuation for sample `seq` (with `plan_len` rows) that carries the
/// input for sample `k`: `j = k − seq − 1` when `k > seq` and `j < min(plan_len, MAX_PLAN)`.
pub const fn plan_row(seq: u64, plan_len: u32, k: u64) -> Option<usize> {
    if k <= seq {
        return None;
    }
    let j = k - seq - 1;
    if j < plan_rows(plan_len) as u64 {
        Some(j as usize)
    } else {
        None
    }
}

/// Which part of an actuation carries the input for a sample ([`carried`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Carried {
    /// Its input `u` (the sample is its `seq`).
    Input,
    /// Its plan row `j` (the sample is `seq + 1 + j`).
    PlanRow(usize),
}

/// What an actuation for sample `seq` with `plan_len` plan rows carries for sample `k`: its
/// input at `k = seq`, its [`plan_row`] after it, nothing before it or past the plan.
pub const fn carried(seq: u64, plan_len: u32, k: u64) -> Option<Carried> {
    if k == seq {
        return Some(Carried::Input);
    }
    match plan_row(seq, plan_len, k) {
        Some(j) => Some(Carried::PlanRow(j)),
        None => None,
    }
}

/// The measurement an actuation answers: its `reply_to`, or `seq − lead` of its timing when
/// that is larger (`lead` 0 for an unknown wire value). The two agree for a service that
/// follows the contract; the second keeps a service that leaves `reply_to` at 0 from
/// stalling a lockstep plant.
pub const fn answered_measurement(seq: u64, reply_to: u64, timing_wire: u32) -> u64 {
    let lead = match Timing::from_wire(timing_wire) {
        Some(t) => t.lead(),
        None => 0,
    };
    let s = seq.saturating_sub(lead);
    if reply_to > s { reply_to } else { s }
}

/// True when the actuation's header fits a plant of `n_u` inputs: this contract's version
/// and the same `n_u`.
pub const fn header_valid(a: &Actuation, n_u: usize) -> bool {
    a.contract_version == CONTRACT_VERSION && a.counts.n_u as usize == n_u
}

/// True when the actuation can be an input of a plant of `n_u` inputs: [`header_valid`],
/// `plan_len ≤ MAX_PLAN`, and a finite `u` and finite plan rows (their first `n_u` values;
/// values past `n_u` or past `plan_len` are not looked at).
pub fn actuation_valid(a: &Actuation, n_u: usize) -> bool {
    let n = if n_u < MAX_U { n_u } else { MAX_U };
    header_valid(a, n_u)
        && (a.plan_len as usize) <= MAX_PLAN
        && a.u[..n].iter().all(|v| v.is_finite())
        && a.plan[..plan_rows(a.plan_len)]
            .iter()
            .all(|row| row[..n].iter().all(|v| v.is_finite()))
}

/// What an actuation received while the plant is at sample `k` is ([`arrival`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// A stall acknowledgement ([`actuation_status::STALL_ACK`]) with a valid header: it
    /// acknowledges its `reply_to`, and is never an input nor a plan.
    StallAck,
    /// Refused: an invalid header, or (not an acknowledgement) not [`actuation_valid`].
    Invalid,
    /// Valid, for a sample before `k` whose input is decided: not an input (late), but its
    /// plan may cover later samples.
    Late,
    /// Valid, for sample `k` or a later one: kept as that sample's input.
    InTime,
}

/// Classifies an actuation received while a plant of `n_u` inputs is at sample `k` (the
/// sample whose input it decides next).
pub fn arrival(a: &Actuation, n_u: usize, k: u64) -> Arrival {
    if a.status & actuation_status::STALL_ACK != 0 {
        if header_valid(a, n_u) {
            Arrival::StallAck
        } else {
            Arrival::Invalid
        }
    } else if !actuation_valid(a, n_u) {
        Arrival::Invalid
    } else if a.seq < k {
        Arrival::Late
    } else {
        Arrival::InTime
    }
}

/// True when a valid actuation for sample `candidate` becomes the plant's plan source in
/// place of the one it holds (for sample `held`, if any): when it is not older.
pub const fn plan_supersedes(held: Option<u64>, candidate: u64) -> bool {
    match held {
        None => true,
        Some(h) => candidate >= h,
    }
}

// ---- a miss, the watchdog and the plant's report ----

/// What the plant applies on a miss that no plan covers, under the plan policy
/// (`proxy.plan-fallback`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlanFallback {
    /// Keep the last applied input (the default).
    #[default]
    Hold,
    /// Apply the safe input.
    Safe,
}

impl PlanFallback {
    /// The name used in the configuration (`"hold"`, `"safe"`).
    pub const fn name(self) -> &'static str {
        match self {
            PlanFallback::Hold => "hold",
            PlanFallback::Safe => "safe",
        }
    }
}

/// The plant's policy of a miss (`proxy.late-policy` with its `proxy.plan-fallback`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissPolicy {
    /// Hold the last applied input.
    Hold,
    /// Apply the safe input.
    Safe,
    /// Apply the newest plan's row for the sample, else the fallback.
    Plan(PlanFallback),
}

/// The input of a missed sample ([`on_miss`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MissInput {
    /// Row `j` of the newest plan.
    PlanRow(usize),
    /// The input applied for the previous sample.
    Hold,
    /// The safe input.
    Safe,
}

/// The input of a sample whose actuation is missing at its application instant: under
/// [`MissPolicy::Plan`] the newest plan's row for it (`newest_plan_row`, from [`plan_row`]
/// of the plan source), else the fallback; hold and safe never use a plan.
pub const fn on_miss(policy: MissPolicy, newest_plan_row: Option<usize>) -> MissInput {
    match (policy, newest_plan_row) {
        (MissPolicy::Hold, _) => MissInput::Hold,
        (MissPolicy::Safe, _) => MissInput::Safe,
        (MissPolicy::Plan(_), Some(j)) => MissInput::PlanRow(j),
        (MissPolicy::Plan(PlanFallback::Hold), None) => MissInput::Hold,
        (MissPolicy::Plan(PlanFallback::Safe), None) => MissInput::Safe,
    }
}

/// True when the plant's watchdog trips now: it has not tripped and `consecutive_misses`
/// (this one included) reached `watchdog_periods`.
pub const fn watchdog_trips(tripped: bool, consecutive_misses: u64, watchdog_periods: u64) -> bool {
    !tripped && consecutive_misses >= watchdog_periods
}

/// What the plant applied for a sample ([`applied`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Applied {
    /// The service's actuation for the sample.
    Answered,
    /// A miss: the newest plan's row.
    Plan,
    /// A miss: the input of the previous sample, held.
    Held,
    /// A miss: the safe input (the late policy's).
    Safe,
    /// The watchdog's safe output (it overrides everything, a plan too).
    WatchdogSafe,
}

impl Applied {
    /// True unless the service's actuation was applied.
    pub const fn is_miss(self) -> bool {
        !matches!(self, Applied::Answered)
    }
}

/// What the plant applies given the sample's decision (`None`: the actuation was there;
/// else the [`on_miss`] input) and whether the watchdog holds the safe output after this
/// sample's update (a valid actuation releases it before; see [`watchdog_trips`]).
pub const fn applied(miss: Option<MissInput>, tripped: bool) -> Applied {
    if tripped {
        return Applied::WatchdogSafe;
    }
    match miss {
        None => Applied::Answered,
        Some(MissInput::PlanRow(_)) => Applied::Plan,
        Some(MissInput::Hold) => Applied::Held,
        Some(MissInput::Safe) => Applied::Safe,
    }
}

/// The flags the plant sets in its next measurement about the period it applied as `a`:
/// [`measurement_flags::PREVIOUS_ACTUATION_MISSED`] for a miss, with
/// [`measurement_flags::PLAN_APPLIED`] for a plan row; [`measurement_flags::PLANT_SAFE_OUTPUT`]
/// while the watchdog holds the safe output.
pub const fn report_flags(a: Applied) -> u32 {
    let mut f = 0;
    if a.is_miss() {
        f |= measurement_flags::PREVIOUS_ACTUATION_MISSED;
    }
    if matches!(a, Applied::Plan) {
        f |= measurement_flags::PLAN_APPLIED;
    }
    if matches!(a, Applied::WatchdogSafe) {
        f |= measurement_flags::PLANT_SAFE_OUTPUT;
    }
    f
}

/// How the plant's report of the previous period reads to the service ([`reported`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reported {
    /// The service's actuation was applied in time.
    OnTime,
    /// A miss a plan covered.
    PlanRow,
    /// A miss that reached the plant as a held or safe input (or the watchdog's output).
    HeldOrSafe,
}

/// Reads a measurement's flags as the report of the period before it: the watchdog's safe
/// output, else a miss with or without a plan, else on time.
pub const fn reported(flags: u32) -> Reported {
    let missed = flags & measurement_flags::PREVIOUS_ACTUATION_MISSED != 0;
    if flags & measurement_flags::PLANT_SAFE_OUTPUT != 0 {
        Reported::HeldOrSafe
    } else if !missed {
        Reported::OnTime
    } else if flags & measurement_flags::PLAN_APPLIED != 0 {
        Reported::PlanRow
    } else {
        Reported::HeldOrSafe
    }
}

// ---- what the service expects the plant to apply ----

/// The input the service expects the plant to apply for a sample ([`expected_input`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expected {
    /// The input it sent for the sample.
    Sent,
    /// Row `j` of the plan of its newest actuation (what a plant with the plan policy
    /// applies).
    PlanRow(usize),
    /// The input of its newest actuation (what a holding plant applies).
    Held,
    /// Nothing was sent before the sample: the safe input.
    Safe,
}

/// What the plant applies for sample `k` as far as the service knows, given whether it sent
/// an input for `k` and its newest actuation (`seq`, `plan_len`), if any: the sent input,
/// else, when the newest is for an earlier sample, its plan row for `k` or its input held;
/// else the safe input. The plant's report in the next sample corrects a wrong guess.
pub const fn expected_input(sent_for_k: bool, newest: Option<(u64, u32)>, k: u64) -> Expected {
    if sent_for_k {
        return Expected::Sent;
    }
    match newest {
        Some((seq, plan_len)) if seq < k => match plan_row(seq, plan_len, k) {
            Some(j) => Expected::PlanRow(j),
            None => Expected::Held,
        },
        _ => Expected::Safe,
    }
}

// ---- the timing a service runs ----

/// `service.timing` as written: `"auto"` or one timing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimingChoice {
    /// Send ahead when the controller can, else compute first.
    Auto,
    /// This timing.
    Fixed(Timing),
}

/// The timing of a `choice` for a controller that has an ahead form (`answers_ahead`) or
/// not; `Err(t)`: the timing `t` needs an ahead form the controller lacks (only
/// compute-first works without one).
pub const fn resolve_timing(choice: TimingChoice, answers_ahead: bool) -> Result<Timing, Timing> {
    match choice {
        TimingChoice::Auto if answers_ahead => Ok(Timing::SendAhead),
        TimingChoice::Auto => Ok(Timing::ComputeFirst),
        TimingChoice::Fixed(Timing::ComputeFirst) => Ok(Timing::ComputeFirst),
        TimingChoice::Fixed(t) if answers_ahead => Ok(t),
        TimingChoice::Fixed(t) => Err(t),
    }
}

/// Why a plan length is refused ([`plan_length`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlanLengthRefusal {
    /// More rows than an actuation carries ([`MAX_PLAN`]).
    PastCapacity,
    /// Plans come with the ahead timings; compute-first sends none.
    ComputeFirst,
}

/// The plan length `requested` for a service of `timing`: at most [`MAX_PLAN`], and 0 with
/// compute-first.
pub const fn plan_length(requested: u64, timing: Timing) -> Result<usize, PlanLengthRefusal> {
    if requested > MAX_PLAN as u64 {
        Err(PlanLengthRefusal::PastCapacity)
    } else if requested > 0 && matches!(timing, Timing::ComputeFirst) {
        Err(PlanLengthRefusal::ComputeFirst)
    } else {
        Ok(requested as usize)
    }
}

/// The timing the loop runs: the configured one when the controller has an ahead form,
/// else compute-first.
pub const fn effective_timing(configured: Timing, has_ahead: bool) -> Timing {
    if has_ahead {
        configured
    } else {
        Timing::ComputeFirst
    }
}

/// The plan rows the loop sends under `timing`: none with compute-first, else the
/// configured length clamped to [`MAX_PLAN`].
pub const fn effective_plan_length(timing: Timing, configured: usize) -> usize {
    match timing {
        Timing::ComputeFirst => 0,
        _ if configured < MAX_PLAN => configured,
        _ => MAX_PLAN,
    }
}
