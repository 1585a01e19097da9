//! # The wire contract between a plant process and the control service
//!
//! Two processes exchange one sample each per sampling period over iceoryx2 shared memory:
//!
//! ```text
//!  plant side (clock master)        Measurement{seq k}        control side
//!  plant-proxy or DAQ I/O  ──────────────────────────────────► service RT loop
//!                          ◄──────────────────────────────────
//!                                   Actuation{seq k}
//! ```
//!
//! At sample `k` the plant publishes a [`Measurement`] carrying the measurement `y_k`, the
//! performance variable `z_k` and the command `r_k` (the notation of Figure 3.1 and (2.15) of
//! the dissertation), stamped with the sample time on `CLOCK_MONOTONIC`. The service answers
//! with an [`Actuation`] carrying an input and the sequence number of the sample whose
//! period it is for. The plant applies the input for sample `k` at its deadline offset
//! ([`Measurement::deadline_ns`]; 0 is the sample instant itself); a reply that arrives
//! later is discarded.
//!
//! How the answer relates to the sample is the service's [`Timing`]: it computes `u_k` from
//! `y_k` and answers (compute-first), answers with `u_k` prepared from the data up to
//! `k − 1` and then computes (answer-first), or sends `u_{k+1}` as soon as it has taken in
//! `y_k`, so that the plant holds it before sample `k + 1` (send-ahead). An actuation may
//! carry a short **plan**, the inputs the controller expects to give for the samples after
//! its own ([`Actuation::plan`]), which a plant applies when an answer is late.
//!
//! Every payload is `#[repr(C)]`, `Copy` and [`ZeroCopySend`] with an explicit, versioned
//! type name, so that a DAQ process written against iceoryx2's C or C++ API with the header
//! `include/adaptive_rig_contract.h` can replace the simulated plant. Capacities are fixed
//! ([`MAX_Y`], [`MAX_Z`], [`MAX_R`], [`MAX_U`]); each sample says how many channels it uses.
//!
//! Compatibility is checked twice:
//! - at connect time, from the service attributes each side writes when it creates its
//!   publish-subscribe service ([`ports`]): a peer with another [`CONTRACT_VERSION`], other
//!   channel counts or another sample period is refused with a message naming each difference;
//! - on every sample, from its header ([`Measurement::contract_version`],
//!   [`Measurement::counts`]), which is a few integer compares.

#![warn(missing_docs)]

pub mod clock;
pub mod cpu_latency;
pub mod files;
pub mod operator;
pub mod peer;
pub mod ports;
pub mod rt;
pub mod rt_alloc;
pub mod telemetry;
pub mod timing_rules;

use iceoryx2::prelude::ZeroCopySend;

/// Version of this contract. Bumped on every change of layout or meaning.
pub const CONTRACT_VERSION: u32 = 3;
/// Capacity of the measurement vector `y`.
pub const MAX_Y: usize = 16;
/// Capacity of the performance vector `z`.
pub const MAX_Z: usize = 16;
/// Capacity of the command vector `r`.
pub const MAX_R: usize = 16;
/// Capacity of the actuation vector `u`.
pub const MAX_U: usize = 8;
/// Capacity of an actuation's plan: the inputs for the samples after its own.
pub const MAX_PLAN: usize = 64;

/// Flags a plant sets in [`Measurement::flags`].
pub mod measurement_flags {
    /// The plant runs in lockstep: it waits for every actuation, so there is no deadline.
    pub const LOCKSTEP: u32 = 1 << 0;
    /// The plant's watchdog has tripped: it applies its safe output, not the controller's.
    pub const PLANT_SAFE_OUTPUT: u32 = 1 << 1;
    /// The actuation for the previous sample missed the deadline (or never came).
    pub const PREVIOUS_ACTUATION_MISSED: u32 = 1 << 2;
    /// The plant ends its run after this sample; it will publish no more.
    pub const LAST_SAMPLE: u32 = 1 << 3;
    /// [`Measurement::u_applied`](crate::Measurement::u_applied) holds the input the plant
    /// really applied after the previous sample (a DAQ process that cannot read its outputs
    /// back leaves this bit clear).
    pub const U_APPLIED: u32 = 1 << 4;
    /// The actuation for the previous sample missed its deadline and the plant applied the
    /// entry of the service's latest plan for that sample instead
    /// ([`Actuation::plan`](crate::Actuation::plan)); set together with
    /// [`PREVIOUS_ACTUATION_MISSED`].
    pub const PLAN_APPLIED: u32 = 1 << 5;
    /// Lockstep only (with [`LOCKSTEP`]): the plant injects a stall of the service. The
    /// service takes this sample in as one that reached it after a newer one (it observes
    /// it and does not answer it) and acknowledges it with
    /// [`actuation_status::STALL_ACK`](crate::actuation_status::STALL_ACK); the plant
    /// applies its late policy for the sample's period.
    pub const INJECTED_STALL: u32 = 1 << 6;
}

/// Status bits the service sets in [`Actuation::status`].
pub mod actuation_status {
    /// The controller ran normally and `u` is its output.
    pub const OK: u32 = 0;
    /// The service is in its safe state; `u` is the configured safe input.
    pub const SAFE_STATE: u32 = 1 << 0;
    /// The measurement was rejected (not finite or out of range); `u` holds the last good value.
    pub const MEASUREMENT_REJECTED: u32 = 1 << 1;
    /// A finite value of the controller's law was clipped to its configured limits.
    pub const SATURATED: u32 = 1 << 2;
    /// The service is inside its start-up grace period.
    pub const STARTING: u32 = 1 << 3;
    /// The controller reported an internal fault (its law gave a non-finite value, or a
    /// reset of adaptive state).
    pub const CONTROLLER_FAULT: u32 = 1 << 4;
    /// The service is in its open-loop phase (`service.open-loop`): `u` is the safe input
    /// and the controller only observes.
    pub const OPEN_LOOP: u32 = 1 << 5;
    /// The controller could not compute its law for this sample (for example PCAC's
    /// receding-horizon problem was infeasible or not solved within its iteration cap)
    /// and `u` is its fallback input (hold the last input within its bounds).
    pub const FALLBACK: u32 = 1 << 6;
    /// The acknowledgement of a sample flagged
    /// [`measurement_flags::INJECTED_STALL`](crate::measurement_flags::INJECTED_STALL): the
    /// service took it in without answering it. `u` and the plan are not inputs; the
    /// plant never applies them.
    pub const STALL_ACK: u32 = 1 << 7;
}

/// When the service answers a sample, stated in every [`Actuation::timing`] and in the
/// service's connect attributes.
///
/// A controller whose input `u_k` depends only on the data up to `k − 1` (RCAC (2.15)–(2.16),
/// an LTI controller without feedthrough, PCAC in the dissertation's timing) can work
/// ahead; one that needs `y_k` for `u_k` answers compute-first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Timing {
    /// At sample `k` the service computes `u_k` from `y_k` and then publishes
    /// `Actuation{seq k}`: the response time contains the controller's cost.
    ComputeFirst = 0,
    /// At sample `k` the service publishes `Actuation{seq k}` with the input it prepared
    /// from the data up to `k − 1`, then takes `y_k` in and prepares `u_{k+1}`.
    AnswerFirst = 1,
    /// At sample `k` the service takes `y_k` in, prepares `u_{k+1}` and publishes
    /// `Actuation{seq k + 1}` at once, so that the plant holds it before sample `k + 1`
    /// (it also answers sample `k` itself when no input was sent ahead for it).
    SendAhead = 2,
}

impl Timing {
    /// Every timing, in wire order.
    pub const ALL: [Timing; 3] = [Timing::ComputeFirst, Timing::AnswerFirst, Timing::SendAhead];

    /// The value carried in [`Actuation::timing`].
    pub const fn wire(self) -> u32 {
        self as u32
    }

    /// The timing of a wire value; `None` for an unknown one.
    pub const fn from_wire(v: u32) -> Option<Self> {
        match v {
            0 => Some(Timing::ComputeFirst),
            1 => Some(Timing::AnswerFirst),
            2 => Some(Timing::SendAhead),
            _ => None,
        }
    }

    /// The name used in configuration files, attributes and reports (`"send-ahead"`, …).
    pub const fn name(self) -> &'static str {
        match self {
            Timing::ComputeFirst => "compute-first",
            Timing::AnswerFirst => "answer-first",
            Timing::SendAhead => "send-ahead",
        }
    }

    /// The timing of a name given by [`Timing::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// How many samples ahead of the measurement it answers the published input is:
    /// 1 for [`Timing::SendAhead`], else 0.
    pub const fn lead(self) -> u64 {
        match self {
            Timing::SendAhead => 1,
            Timing::ComputeFirst | Timing::AnswerFirst => 0,
        }
    }
}

/// Channel counts used by one side of the contract.
///
/// The plant states what it measures (`n_y`, `n_z`, `n_r`) and how many inputs it accepts
/// (`n_u`); the service states what its controller reads and produces. They must be equal.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[type_name("adaptive_rig::ChannelCounts.v1")]
pub struct ChannelCounts {
    /// Number of measurement channels `y` used (≤ [`MAX_Y`]).
    pub n_y: u16,
    /// Number of performance channels `z` used (≤ [`MAX_Z`]).
    pub n_z: u16,
    /// Number of command channels `r` used (≤ [`MAX_R`]).
    pub n_r: u16,
    /// Number of actuation channels `u` used (≤ [`MAX_U`]).
    pub n_u: u16,
}

impl ChannelCounts {
    /// Counts from `usize`s, refused when a count exceeds its capacity.
    pub fn new(n_y: usize, n_z: usize, n_r: usize, n_u: usize) -> Result<Self, String> {
        let check = |what: &str, n: usize, max: usize| {
            if n > max {
                Err(format!(
                    "{what}: {n} channels requested, the contract carries at most {max}"
                ))
            } else {
                Ok(n as u16)
            }
        };
        Ok(Self {
            n_y: check("measurement channels y", n_y, MAX_Y)?,
            n_z: check("performance channels z", n_z, MAX_Z)?,
            n_r: check("command channels r", n_r, MAX_R)?,
            n_u: check("actuation channels u", n_u, MAX_U)?,
        })
    }

    /// True when every count is within the contract's capacities.
    pub fn within_capacity(&self) -> bool {
        (self.n_y as usize) <= MAX_Y
            && (self.n_z as usize) <= MAX_Z
            && (self.n_r as usize) <= MAX_R
            && (self.n_u as usize) <= MAX_U
    }

    /// The list of differences between `self` (named `own`) and `peer` (named `peer_name`),
    /// one human-readable line each; empty when they agree.
    pub fn differences(&self, own: &str, peer: &ChannelCounts, peer_name: &str) -> Vec<String> {
        let mut out = Vec::new();
        let fields = [
            ("measurement channels (y)", self.n_y, peer.n_y),
            ("performance channels (z)", self.n_z, peer.n_z),
            ("command channels (r)", self.n_r, peer.n_r),
            ("actuation channels (u)", self.n_u, peer.n_u),
        ];
        for (what, mine, theirs) in fields {
            if mine != theirs {
                out.push(format!(
                    "{what}: {peer_name} uses {theirs}, {own} uses {mine}"
                ));
            }
        }
        out
    }
}

/// One sample of the plant, published at the start of period `seq`.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::Measurement.v3")]
pub struct Measurement {
    /// Must equal [`CONTRACT_VERSION`].
    pub contract_version: u32,
    /// Bits of [`measurement_flags`].
    pub flags: u32,
    /// Sample index `k`, starting at 0 and increasing by one per period.
    pub seq: u64,
    /// Sample time `kT` on `CLOCK_MONOTONIC` in nanoseconds.
    pub t_sample_ns: u64,
    /// The plant's sampling period `T` in nanoseconds.
    pub period_ns: u64,
    /// The plant's deadline for the input of this sample, in nanoseconds after
    /// `t_sample_ns`: the plant applies the actuation with this `seq` then, so it must have
    /// arrived by then. 0 in real time is the sample instant itself (a DAC latched on the
    /// sample clock; only a service that sends ahead can meet it). Not a deadline in
    /// lockstep ([`measurement_flags::LOCKSTEP`]): the plant waits for every answer.
    pub deadline_ns: u64,
    /// Channel counts actually used in this sample.
    pub counts: ChannelCounts,
    /// Measurement `y_k`; entries past `counts.n_y` are zero.
    pub y: [f64; MAX_Y],
    /// Performance variable `z_k`; entries past `counts.n_z` are zero.
    pub z: [f64; MAX_Z],
    /// Command `r_k`; entries past `counts.n_r` are zero.
    pub r: [f64; MAX_R],
    /// The input the plant applied in answer to sample `k − 1`, held over the period that
    /// ends at this sample: `u_{k−1}` when that actuation arrived in time, otherwise what the
    /// plant's late policy or watchdog applied instead (the held or the safe input). Valid
    /// when [`measurement_flags::U_APPLIED`] is set; entries past `counts.n_u` are zero.
    /// At `seq = 0` it is the input held before the run.
    pub u_applied: [f64; MAX_U],
}

impl Measurement {
    /// An all-zero sample of the current contract version with the given counts.
    pub const fn zeroed(counts: ChannelCounts) -> Self {
        Self {
            contract_version: CONTRACT_VERSION,
            flags: 0,
            seq: 0,
            t_sample_ns: 0,
            period_ns: 0,
            deadline_ns: 0,
            counts,
            y: [0.0; MAX_Y],
            z: [0.0; MAX_Z],
            r: [0.0; MAX_R],
            u_applied: [0.0; MAX_U],
        }
    }

    /// The used part of `y`, clamped to the capacity.
    pub fn y(&self) -> &[f64] {
        &self.y[..(self.counts.n_y as usize).min(MAX_Y)]
    }
    /// The used part of `z`, clamped to the capacity.
    pub fn z(&self) -> &[f64] {
        &self.z[..(self.counts.n_z as usize).min(MAX_Z)]
    }
    /// The used part of `r`, clamped to the capacity.
    pub fn r(&self) -> &[f64] {
        &self.r[..(self.counts.n_r as usize).min(MAX_R)]
    }
    /// The used part of `u_applied` when the plant reports it
    /// ([`measurement_flags::U_APPLIED`]), clamped to the capacity.
    pub fn u_applied(&self) -> Option<&[f64]> {
        (self.flags & measurement_flags::U_APPLIED != 0)
            .then(|| &self.u_applied[..(self.counts.n_u as usize).min(MAX_U)])
    }
}

/// The service's answer: the input for the period that starts at sample `seq`, and its plan
/// for the samples after it.
///
/// With [`Timing::ComputeFirst`] and [`Timing::AnswerFirst`] it answers the measurement with
/// the same `seq`; with [`Timing::SendAhead`] it answers measurement `seq − 1` (or `seq`
/// itself when no input was sent ahead for it); [`Actuation::reply_to`] says which.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::Actuation.v3")]
pub struct Actuation {
    /// Must equal [`CONTRACT_VERSION`].
    pub contract_version: u32,
    /// Bits of [`actuation_status`].
    pub status: u32,
    /// The sample whose period `u` is for: the plant applies `u` at that sample's deadline.
    pub seq: u64,
    /// The [`Measurement::seq`] whose receipt this actuation answers (`seq` or `seq − 1`,
    /// see [`Timing`]).
    pub reply_to: u64,
    /// The [`Measurement::t_sample_ns`] of `reply_to`, echoed.
    pub t_sample_ns: u64,
    /// `CLOCK_MONOTONIC` time at which the service published it, in nanoseconds.
    pub t_publish_ns: u64,
    /// Time the controller took for it, in nanoseconds (with [`Timing::AnswerFirst`], the
    /// computation that prepared `u`, done after the previous answer).
    pub compute_ns: u64,
    /// Channel counts actually used; only `n_u` is meaningful for the payload.
    pub counts: ChannelCounts,
    /// The service's [`Timing`] ([`Timing::wire`]).
    pub timing: u32,
    /// How many entries of `plan` are valid (at most [`MAX_PLAN`]).
    pub plan_len: u32,
    /// Control input for sample `seq`; entries past `counts.n_u` are zero.
    pub u: [f64; MAX_U],
    /// The plan: `plan[j]` is the input the controller expects to give for sample
    /// `seq + 1 + j`, for `j < plan_len`. A plant whose answer for a sample is late may
    /// apply the entry of the latest plan for it (`proxy.late-policy = "plan"`). Entries
    /// past `plan_len` and past `counts.n_u` are zero.
    pub plan: [[f64; MAX_U]; MAX_PLAN],
}

impl Actuation {
    /// An all-zero actuation of the current contract version with the given counts.
    pub const fn zeroed(counts: ChannelCounts) -> Self {
        Self {
            contract_version: CONTRACT_VERSION,
            status: 0,
            seq: 0,
            reply_to: 0,
            t_sample_ns: 0,
            t_publish_ns: 0,
            compute_ns: 0,
            counts,
            timing: Timing::ComputeFirst.wire(),
            plan_len: 0,
            u: [0.0; MAX_U],
            plan: [[0.0; MAX_U]; MAX_PLAN],
        }
    }

    /// The used part of `u`, clamped to the capacity.
    pub fn u(&self) -> &[f64] {
        &self.u[..(self.counts.n_u as usize).min(MAX_U)]
    }

    /// The used part of the plan entry for sample `seq + 1 + j`; `None` past `plan_len`.
    pub fn plan_entry(&self, j: usize) -> Option<&[f64]> {
        (j < timing_rules::plan_rows(self.plan_len))
            .then(|| &self.plan[j][..(self.counts.n_u as usize).min(MAX_U)])
    }

    /// The input this actuation carries for sample `k`: `u` for `k = seq`, the plan's entry
    /// for a later sample it covers; `None` otherwise ([`timing_rules::carried`]).
    pub fn input_for(&self, k: u64) -> Option<&[f64]> {
        match timing_rules::carried(self.seq, self.plan_len, k)? {
            timing_rules::Carried::Input => Some(self.u()),
            timing_rules::Carried::PlanRow(j) => self.plan_entry(j),
        }
    }

    /// The service's [`Timing`]; `None` for an unknown wire value.
    pub fn timing(&self) -> Option<Timing> {
        Timing::from_wire(self.timing)
    }
}

/// The C header that mirrors this crate's layout, for DAQ processes written in C or C++.
pub const C_HEADER: &str = include_str!("../include/adaptive_rig_contract.h");

#[cfg(test)]
mod layout_tests {
    use super::*;
    use core::mem::{align_of, offset_of, size_of};

    /// Reads `#define NAME value` from the C header.
    fn header_value(name: &str) -> usize {
        for line in C_HEADER.lines() {
            let mut it = line.split_whitespace();
            if it.next() == Some("#define") && it.next() == Some(name) {
                let v = it.next().expect("value after the name");
                let v = v.trim_end_matches('u').trim_end_matches('U');
                return v
                    .parse()
                    .unwrap_or_else(|_| panic!("{name} = {v} is not a number"));
            }
        }
        panic!("the C header does not define {name}");
    }

    #[test]
    fn the_c_header_states_the_rust_constants() {
        assert_eq!(
            header_value("AR_CONTRACT_VERSION"),
            CONTRACT_VERSION as usize
        );
        assert_eq!(header_value("AR_MAX_Y"), MAX_Y);
        assert_eq!(header_value("AR_MAX_Z"), MAX_Z);
        assert_eq!(header_value("AR_MAX_R"), MAX_R);
        assert_eq!(header_value("AR_MAX_U"), MAX_U);
        assert_eq!(header_value("AR_MAX_PLAN"), MAX_PLAN);
    }

    #[test]
    fn the_flag_and_status_bits_in_the_c_header_match_the_rust_constants() {
        use crate::{actuation_status as a, measurement_flags as m};
        let pairs = [
            ("AR_MEAS_LOCKSTEP", m::LOCKSTEP),
            ("AR_MEAS_PLANT_SAFE_OUTPUT", m::PLANT_SAFE_OUTPUT),
            (
                "AR_MEAS_PREVIOUS_ACTUATION_MISSED",
                m::PREVIOUS_ACTUATION_MISSED,
            ),
            ("AR_MEAS_LAST_SAMPLE", m::LAST_SAMPLE),
            ("AR_MEAS_U_APPLIED", m::U_APPLIED),
            ("AR_MEAS_PLAN_APPLIED", m::PLAN_APPLIED),
            ("AR_MEAS_INJECTED_STALL", m::INJECTED_STALL),
            ("AR_ACT_OK", a::OK),
            ("AR_ACT_SAFE_STATE", a::SAFE_STATE),
            ("AR_ACT_MEASUREMENT_REJECTED", a::MEASUREMENT_REJECTED),
            ("AR_ACT_SATURATED", a::SATURATED),
            ("AR_ACT_STARTING", a::STARTING),
            ("AR_ACT_CONTROLLER_FAULT", a::CONTROLLER_FAULT),
            ("AR_ACT_OPEN_LOOP", a::OPEN_LOOP),
            ("AR_ACT_FALLBACK", a::FALLBACK),
            ("AR_ACT_STALL_ACK", a::STALL_ACK),
            ("AR_TIMING_COMPUTE_FIRST", Timing::ComputeFirst.wire()),
            ("AR_TIMING_ANSWER_FIRST", Timing::AnswerFirst.wire()),
            ("AR_TIMING_SEND_AHEAD", Timing::SendAhead.wire()),
        ];
        for (name, value) in pairs {
            let text = C_HEADER
                .lines()
                .find_map(|l| l.strip_prefix(&format!("#define {name} ")))
                .unwrap_or_else(|| panic!("the C header does not define {name}"));
            let v = u32::from_str_radix(
                text.trim().trim_start_matches("0x").trim_end_matches('u'),
                16,
            )
            .unwrap();
            assert_eq!(v, value, "{name}");
        }
    }

    #[test]
    fn the_measurement_layout_matches_the_c_header() {
        assert_eq!(
            size_of::<Measurement>(),
            header_value("AR_MEASUREMENT_SIZE")
        );
        assert_eq!(
            align_of::<Measurement>(),
            header_value("AR_MEASUREMENT_ALIGN")
        );
        let offsets = [
            (
                "AR_MEASUREMENT_OFFSET_CONTRACT_VERSION",
                offset_of!(Measurement, contract_version),
            ),
            (
                "AR_MEASUREMENT_OFFSET_FLAGS",
                offset_of!(Measurement, flags),
            ),
            ("AR_MEASUREMENT_OFFSET_SEQ", offset_of!(Measurement, seq)),
            (
                "AR_MEASUREMENT_OFFSET_T_SAMPLE_NS",
                offset_of!(Measurement, t_sample_ns),
            ),
            (
                "AR_MEASUREMENT_OFFSET_PERIOD_NS",
                offset_of!(Measurement, period_ns),
            ),
            (
                "AR_MEASUREMENT_OFFSET_DEADLINE_NS",
                offset_of!(Measurement, deadline_ns),
            ),
            (
                "AR_MEASUREMENT_OFFSET_COUNTS",
                offset_of!(Measurement, counts),
            ),
            ("AR_MEASUREMENT_OFFSET_Y", offset_of!(Measurement, y)),
            ("AR_MEASUREMENT_OFFSET_Z", offset_of!(Measurement, z)),
            ("AR_MEASUREMENT_OFFSET_R", offset_of!(Measurement, r)),
            (
                "AR_MEASUREMENT_OFFSET_U_APPLIED",
                offset_of!(Measurement, u_applied),
            ),
        ];
        for (name, off) in offsets {
            assert_eq!(off, header_value(name), "{name}");
        }
    }

    #[test]
    fn the_actuation_layout_matches_the_c_header() {
        assert_eq!(size_of::<Actuation>(), header_value("AR_ACTUATION_SIZE"));
        assert_eq!(align_of::<Actuation>(), header_value("AR_ACTUATION_ALIGN"));
        let offsets = [
            (
                "AR_ACTUATION_OFFSET_CONTRACT_VERSION",
                offset_of!(Actuation, contract_version),
            ),
            ("AR_ACTUATION_OFFSET_STATUS", offset_of!(Actuation, status)),
            ("AR_ACTUATION_OFFSET_SEQ", offset_of!(Actuation, seq)),
            (
                "AR_ACTUATION_OFFSET_REPLY_TO",
                offset_of!(Actuation, reply_to),
            ),
            (
                "AR_ACTUATION_OFFSET_T_SAMPLE_NS",
                offset_of!(Actuation, t_sample_ns),
            ),
            (
                "AR_ACTUATION_OFFSET_T_PUBLISH_NS",
                offset_of!(Actuation, t_publish_ns),
            ),
            (
                "AR_ACTUATION_OFFSET_COMPUTE_NS",
                offset_of!(Actuation, compute_ns),
            ),
            ("AR_ACTUATION_OFFSET_COUNTS", offset_of!(Actuation, counts)),
            ("AR_ACTUATION_OFFSET_TIMING", offset_of!(Actuation, timing)),
            (
                "AR_ACTUATION_OFFSET_PLAN_LEN",
                offset_of!(Actuation, plan_len),
            ),
            ("AR_ACTUATION_OFFSET_U", offset_of!(Actuation, u)),
            ("AR_ACTUATION_OFFSET_PLAN", offset_of!(Actuation, plan)),
        ];
        for (name, off) in offsets {
            assert_eq!(off, header_value(name), "{name}");
        }
    }

    #[test]
    fn the_channel_counts_layout_matches_the_c_header() {
        assert_eq!(
            size_of::<ChannelCounts>(),
            header_value("AR_CHANNEL_COUNTS_SIZE")
        );
        assert_eq!(
            offset_of!(ChannelCounts, n_y),
            header_value("AR_CHANNEL_COUNTS_OFFSET_N_Y")
        );
        assert_eq!(
            offset_of!(ChannelCounts, n_z),
            header_value("AR_CHANNEL_COUNTS_OFFSET_N_Z")
        );
        assert_eq!(
            offset_of!(ChannelCounts, n_r),
            header_value("AR_CHANNEL_COUNTS_OFFSET_N_R")
        );
        assert_eq!(
            offset_of!(ChannelCounts, n_u),
            header_value("AR_CHANNEL_COUNTS_OFFSET_N_U")
        );
    }

    #[test]
    fn the_type_names_in_the_c_header_match_the_rust_type_names() {
        use iceoryx2::prelude::ZeroCopySend;
        // SAFETY: type_name only returns the constant given in #[type_name].
        let names = unsafe { [Measurement::type_name(), Actuation::type_name()] };
        for name in names {
            assert!(
                C_HEADER.contains(&format!("\"{name}\"")),
                "header lacks {name}"
            );
        }
    }

    #[test]
    fn an_actuation_gives_its_input_and_its_plan_entries_by_sample() {
        let mut a = Actuation::zeroed(ChannelCounts::new(1, 1, 0, 2).unwrap());
        a.seq = 10;
        a.u[..2].copy_from_slice(&[1.0, 2.0]);
        a.plan_len = 2;
        a.plan[0][..2].copy_from_slice(&[3.0, 4.0]);
        a.plan[1][..2].copy_from_slice(&[5.0, 6.0]);
        a.plan[2][..2].copy_from_slice(&[7.0, 8.0]);
        assert_eq!(a.input_for(9), None);
        assert_eq!(a.input_for(10), Some(&[1.0, 2.0][..]));
        assert_eq!(a.input_for(11), Some(&[3.0, 4.0][..]));
        assert_eq!(a.input_for(12), Some(&[5.0, 6.0][..]));
        // Past plan_len: not covered, whatever the buffer holds.
        assert_eq!(a.input_for(13), None);
        assert_eq!(a.input_for(u64::MAX), None);
        a.plan_len = u32::MAX;
        assert_eq!(
            a.plan_entry(MAX_PLAN),
            None,
            "plan_len is clamped to the capacity"
        );
    }

    #[test]
    fn timings_round_trip_through_their_wire_values_and_names() {
        for t in Timing::ALL {
            assert_eq!(Timing::from_wire(t.wire()), Some(t));
            assert_eq!(Timing::from_name(t.name()), Some(t));
        }
        assert_eq!(Timing::from_wire(3), None);
        assert_eq!(Timing::from_name("ahead"), None);
        assert_eq!(Timing::SendAhead.lead(), 1);
        assert_eq!(Timing::AnswerFirst.lead(), 0);
    }

    /// Compiles the header with the machine's C compiler, so its own `_Static_assert`s on
    /// sizes and offsets are checked against the C compiler's layout too.
    #[test]
    fn the_c_header_compiles_and_its_static_asserts_hold() {
        let dir = std::env::temp_dir().join(format!("ar-header-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let src = dir.join("check.c");
        std::fs::write(
            &src,
            "#include \"adaptive_rig_contract.h\"\nint main(void){return 0;}\n",
        )
        .unwrap();
        let include = concat!(env!("CARGO_MANIFEST_DIR"), "/include");
        let out = match std::process::Command::new("cc")
            .args([
                "-std=c11",
                "-Wall",
                "-Werror",
                "-fsyntax-only",
                "-I",
                include,
            ])
            .arg(&src)
            .output()
        {
            Ok(o) => o,
            Err(e) => {
                eprintln!("no C compiler ({e}); the header's static asserts were not compiled");
                return;
            }
        };
        let _ = std::fs::remove_dir_all(&dir);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
