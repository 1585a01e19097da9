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
//! with an [`Actuation`] carrying `u_k` and the same sequence number. The plant applies `u_k`
//! at its deadline offset inside the period; a reply that arrives later is discarded.
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
pub mod files;
pub mod peer;
pub mod ports;
pub mod rt;

use iceoryx2::prelude::ZeroCopySend;

/// Version of this contract. Bumped on every change of layout or meaning.
pub const CONTRACT_VERSION: u32 = 2;
/// Capacity of the measurement vector `y`.
pub const MAX_Y: usize = 16;
/// Capacity of the performance vector `z`.
pub const MAX_Z: usize = 16;
/// Capacity of the command vector `r`.
pub const MAX_R: usize = 16;
/// Capacity of the actuation vector `u`.
pub const MAX_U: usize = 8;

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
}

/// Status bits the service sets in [`Actuation::status`].
pub mod actuation_status {
    /// The controller ran normally and `u` is its output.
    pub const OK: u32 = 0;
    /// The service is in its safe state; `u` is the configured safe input.
    pub const SAFE_STATE: u32 = 1 << 0;
    /// The measurement was rejected (not finite or out of range); `u` holds the last good value.
    pub const MEASUREMENT_REJECTED: u32 = 1 << 1;
    /// The controller output was clipped to its configured limits.
    pub const SATURATED: u32 = 1 << 2;
    /// The service is inside its start-up grace period.
    pub const STARTING: u32 = 1 << 3;
    /// The controller reported an internal fault (for example a reset of adaptive state).
    pub const CONTROLLER_FAULT: u32 = 1 << 4;
    /// The service is in its open-loop phase (`service.open-loop`): `u` is the safe input
    /// and the controller only observes.
    pub const OPEN_LOOP: u32 = 1 << 5;
    /// The controller could not compute its law for this sample (for example PCAC's
    /// receding-horizon problem was infeasible or not solved within its iteration cap)
    /// and `u` is its fallback input (hold the last input within its bounds).
    pub const FALLBACK: u32 = 1 << 6;
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
#[type_name("adaptive_rig::Measurement.v2")]
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
    /// Deadline offset in nanoseconds after `t_sample_ns` by which the actuation must arrive;
    /// 0 when there is none (lockstep).
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

/// The service's answer to the measurement with the same `seq`.
#[repr(C)]
#[derive(Debug, Clone, Copy, ZeroCopySend)]
#[type_name("adaptive_rig::Actuation.v2")]
pub struct Actuation {
    /// Must equal [`CONTRACT_VERSION`].
    pub contract_version: u32,
    /// Bits of [`actuation_status`].
    pub status: u32,
    /// The [`Measurement::seq`] this actuation answers.
    pub seq: u64,
    /// The [`Measurement::t_sample_ns`] it answers, echoed.
    pub t_sample_ns: u64,
    /// `CLOCK_MONOTONIC` time at which the service published it, in nanoseconds.
    pub t_publish_ns: u64,
    /// Time the controller step took, in nanoseconds.
    pub compute_ns: u64,
    /// Channel counts actually used; only `n_u` is meaningful for the payload.
    pub counts: ChannelCounts,
    /// Control input `u_k`; entries past `counts.n_u` are zero.
    pub u: [f64; MAX_U],
}

impl Actuation {
    /// An all-zero actuation of the current contract version with the given counts.
    pub const fn zeroed(counts: ChannelCounts) -> Self {
        Self {
            contract_version: CONTRACT_VERSION,
            status: 0,
            seq: 0,
            t_sample_ns: 0,
            t_publish_ns: 0,
            compute_ns: 0,
            counts,
            u: [0.0; MAX_U],
        }
    }

    /// The used part of `u`, clamped to the capacity.
    pub fn u(&self) -> &[f64] {
        &self.u[..(self.counts.n_u as usize).min(MAX_U)]
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
            ("AR_ACT_OK", a::OK),
            ("AR_ACT_SAFE_STATE", a::SAFE_STATE),
            ("AR_ACT_MEASUREMENT_REJECTED", a::MEASUREMENT_REJECTED),
            ("AR_ACT_SATURATED", a::SATURATED),
            ("AR_ACT_STARTING", a::STARTING),
            ("AR_ACT_CONTROLLER_FAULT", a::CONTROLLER_FAULT),
            ("AR_ACT_OPEN_LOOP", a::OPEN_LOOP),
            ("AR_ACT_FALLBACK", a::FALLBACK),
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
            ("AR_ACTUATION_OFFSET_U", offset_of!(Actuation, u)),
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
