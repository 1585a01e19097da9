//! The entry kinds of a record and their sizes, fixed by the channel counts and the plan
//! length in the record's header.

use ipc_types::{ChannelCounts, MAX_PLAN, MAX_R, MAX_U, MAX_Y, MAX_Z};

/// Bytes every entry starts with: its kind (1 byte) and its index (`u64`).
pub const ENTRY_HEAD_BYTES: usize = 1 + 8;

/// Bytes of an `Operator` entry's body: request id, command code, tunable index, value.
pub const OPERATOR_BODY_BYTES: usize = 8 + 4 + 4 + 8;

/// The kind of an entry: its first byte.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum EntryKind {
    /// A measurement handed to [`LoopCore::handle`](crate::runtime::LoopCore::handle), with
    /// its receive time.
    Handle = 1,
    /// A measurement taken in too late ([`LoopCore::observe`](crate::runtime::LoopCore::observe)).
    Observe = 2,
    /// The next sample comes from another publisher
    /// ([`LoopCore::note_new_peer`](crate::runtime::LoopCore::note_new_peer)).
    NewPeer = 3,
    /// The loop declared the plant silent at this time
    /// ([`LoopCore::on_idle`](crate::runtime::LoopCore::on_idle)).
    WentSilent = 4,
    /// An actuation the loop published, with what the publisher returned.
    Publish = 5,
    /// The end mark, written by the writer when the run ends: its index is the number of
    /// entries the loop offered, so entries lost at the end show as a gap before it.
    End = 6,
    /// An operator command, applied before the next entry
    /// ([`LoopCore::apply_command`](crate::runtime::LoopCore::apply_command)).
    Operator = 7,
}

impl EntryKind {
    /// The kind of first byte `b`, if any.
    pub fn from_byte(b: u8) -> Option<Self> {
        match b {
            1 => Some(Self::Handle),
            2 => Some(Self::Observe),
            3 => Some(Self::NewPeer),
            4 => Some(Self::WentSilent),
            5 => Some(Self::Publish),
            6 => Some(Self::End),
            7 => Some(Self::Operator),
            _ => None,
        }
    }
}

/// The channels and plan entries a record keeps per entry: the configured counts (values
/// past them are not recorded) and the loop's plan length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordLayout {
    /// Channels recorded of `y`, `z`, `r`, `u` (each clamped to its capacity).
    pub counts: ChannelCounts,
    /// Plan rows recorded per actuation (clamped to [`MAX_PLAN`]).
    pub plan_length: usize,
}

impl RecordLayout {
    /// The layout for `counts` and `plan_length`, clamped to the contract's capacities.
    pub fn new(counts: ChannelCounts, plan_length: usize) -> Self {
        let clamp = |n: u16, max: usize| n.min(max as u16);
        Self {
            counts: ChannelCounts {
                n_y: clamp(counts.n_y, MAX_Y),
                n_z: clamp(counts.n_z, MAX_Z),
                n_r: clamp(counts.n_r, MAX_R),
                n_u: clamp(counts.n_u, MAX_U),
            },
            plan_length: plan_length.min(MAX_PLAN),
        }
    }

    /// `(n_y, n_z, n_r, n_u)` as `usize`.
    pub fn channels(&self) -> (usize, usize, usize, usize) {
        let c = self.counts;
        (
            c.n_y as usize,
            c.n_z as usize,
            c.n_r as usize,
            c.n_u as usize,
        )
    }

    /// Bytes of a [`EntryKind::Handle`] or [`EntryKind::Observe`] entry.
    pub fn measurement_bytes(&self) -> usize {
        let (y, z, r, u) = self.channels();
        // t_recv, contract version, flags, seq, t_sample, period, deadline, counts.
        ENTRY_HEAD_BYTES + 8 + 4 + 4 + 8 + 8 + 8 + 8 + 8 + 8 * (y + z + r + u)
    }

    /// Bytes of a [`EntryKind::Publish`] entry.
    pub fn publish_bytes(&self) -> usize {
        let (_, _, _, u) = self.channels();
        // ok, t_pub, contract version, status, seq, reply_to, t_sample, compute, counts,
        // timing, plan_len, u, plan.
        ENTRY_HEAD_BYTES
            + 1
            + 8
            + 4
            + 4
            + 8
            + 8
            + 8
            + 8
            + 8
            + 4
            + 4
            + 8 * u * (1 + self.plan_length)
    }

    /// Bytes of an entry of `kind`.
    pub fn entry_bytes(&self, kind: EntryKind) -> usize {
        match kind {
            EntryKind::Handle | EntryKind::Observe => self.measurement_bytes(),
            EntryKind::NewPeer | EntryKind::End => ENTRY_HEAD_BYTES,
            EntryKind::WentSilent => ENTRY_HEAD_BYTES + 8,
            EntryKind::Publish => self.publish_bytes(),
            EntryKind::Operator => ENTRY_HEAD_BYTES + OPERATOR_BODY_BYTES,
        }
    }

    /// The largest entry of this layout.
    pub fn max_entry_bytes(&self) -> usize {
        self.measurement_bytes()
            .max(self.publish_bytes())
            .max(ENTRY_HEAD_BYTES + OPERATOR_BODY_BYTES)
    }
}
