//! The loop's side of the live view: every sample and, every few milliseconds, the loop's
//! state go into a wait-free ring for the telemetry thread ([`crate::live`]).
//!
//! The RT thread copies a [`LiveSample`] per handled sample (its `z`, the input given for
//! it, its status; on every `point_every`-th sample also `‖θ_k‖`) and a [`LiveState`] (the
//! counters and state bits) every `state_every` samples and whenever the state changes
//! (a command, silence). A full ring drops the item and counts it
//! ([`LoopStats::telemetry_dropped`]): the loop never waits for a reader. The ring is
//! allocated before the loop starts; a push is a copy of a few hundred bytes.

use super::LoopStats;
use super::verdict::SafeStateAtEnd;
use ipc_types::{MAX_U, MAX_Z};

/// One handled sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveSample {
    /// Sample index `k`.
    pub seq: u64,
    /// Sample time, `CLOCK_MONOTONIC` ns.
    pub t_sample_ns: u64,
    /// The status of the input given for sample `k`.
    pub status: u32,
    /// The measurement's flags.
    pub flags: u32,
    /// A decimated point of the scope (its `theta_norm` is set).
    pub point: bool,
    /// `‖θ_k‖` on a point, NaN otherwise or for a controller without `θ`.
    pub theta_norm: f64,
    /// `z_k`.
    pub z: [f64; MAX_Z],
    /// The input given for sample `k`.
    pub u: [f64; MAX_U],
}

/// The loop's counters and state bits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LiveState {
    /// The counters so far.
    pub stats: LoopStats,
    /// [`ipc_types::telemetry::live_flags`].
    pub flags: u32,
    /// The newest sample's index.
    pub last_seq: u64,
    /// Where the safe state stands, when the loop is in it (for the verdict so far).
    pub safe_state: Option<SafeStateAtEnd>,
    /// The value of each of the controller's tunables (NaN: not used).
    pub tunables: [f64; ipc_types::telemetry::MAX_TUNABLES],
}

/// What the ring carries.
// Every slot of the ring holds the larger variant: boxing it would allocate per item on
// the RT thread.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LiveItem {
    /// A handled sample.
    Sample(LiveSample),
    /// The loop's state.
    State(LiveState),
}

/// The loop's end of the ring.
#[derive(Debug)]
pub struct LiveTap {
    tx: rtrb::Producer<LiveItem>,
    point_every: u64,
    state_every: u64,
    since_point: u64,
    since_state: u64,
}

/// The ring: `capacity` items; a point every `point_every` samples, the state every
/// `state_every` samples (both at least 1).
pub fn channel(
    capacity: usize,
    point_every: u64,
    state_every: u64,
) -> (LiveTap, rtrb::Consumer<LiveItem>) {
    let (tx, rx) = rtrb::RingBuffer::new(capacity.max(2));
    (
        LiveTap {
            tx,
            point_every: point_every.max(1),
            state_every: state_every.max(1),
            // The first sample is a point, and the state goes with it.
            since_point: point_every.max(1) - 1,
            since_state: state_every.max(1) - 1,
        },
        rx,
    )
}

impl LiveTap {
    /// Whether the next sample is a decimated point (counts it).
    #[inline]
    pub fn next_is_point(&mut self) -> bool {
        self.since_point += 1;
        if self.since_point >= self.point_every {
            self.since_point = 0;
            true
        } else {
            false
        }
    }

    /// Whether the state is due after the next sample (counts it).
    #[inline]
    pub fn state_due(&mut self) -> bool {
        self.since_state += 1;
        if self.since_state >= self.state_every {
            self.since_state = 0;
            true
        } else {
            false
        }
    }

    /// Queues `item`; returns false when the ring was full (the item is dropped).
    #[inline]
    pub fn push(&mut self, item: LiveItem) -> bool {
        self.tx.push(item).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: u64) -> LiveItem {
        LiveItem::Sample(LiveSample {
            seq,
            t_sample_ns: seq,
            status: 0,
            flags: 0,
            point: false,
            theta_norm: 0.0,
            z: [0.0; MAX_Z],
            u: [0.0; MAX_U],
        })
    }

    #[test]
    fn points_come_every_point_every_samples_starting_with_the_first() {
        let (mut tap, _rx) = channel(8, 3, 5);
        let points: Vec<bool> = (0..7).map(|_| tap.next_is_point()).collect();
        assert_eq!(points, [true, false, false, true, false, false, true]);
        let states: Vec<bool> = (0..6).map(|_| tap.state_due()).collect();
        assert_eq!(states, [true, false, false, false, false, true]);
    }

    #[test]
    fn a_full_ring_drops_instead_of_waiting() {
        let (mut tap, mut rx) = channel(2, 1, 1);
        assert!(tap.push(sample(1)));
        assert!(tap.push(sample(2)));
        assert!(!tap.push(sample(3)));
        assert_eq!(rx.pop(), Ok(sample(1)));
        assert!(tap.push(sample(4)));
    }
}
