//! The peer's identity, pinned at connect: which publisher a received sample may come from.
//!
//! Each publish-subscribe service of the contract admits exactly **one publisher**
//! ([`crate::ports`] creates them so and refuses a service that admits more). At connect
//! each side pins the publisher of its peer's service (its [`UniquePublisherId`], the node
//! that owns it and that node's pid). The receive path then asks, for every sample, where it
//! came from with [`PeerPin::admit`], giving it iceoryx2's `Sample::origin()` (the publisher
//! of the connection the sample arrived on, which the subscriber knows from its own
//! connection bookkeeping; unlike `header().publisher_id()` it is not written by the
//! sender). The answer is an [`Origin`]:
//!
//! - [`Origin::Peer`]: the pinned peer; use the sample.
//! - [`Origin::NewPeer`]: a publisher that is not the pinned one while the slot can only
//!   hold one. Its existence proves that the pinned publisher has released the slot (its
//!   process dropped it, or died and its stale port was removed by
//!   [`crate::ports::cleanup_dead_nodes`]): a restarted or replaced peer. The pin moves to
//!   it, and the caller starts a new session with it (the service: a new plant session;
//!   the plant: a new service). Its pid is unknown until [`crate::ports::Ports::refresh_peer`]
//!   is called outside the real-time path.
//! - [`Origin::Foreign`]: a sample that must not be used: a leftover of a peer that was
//!   replaced, or any unknown publisher while the pin is not exclusive (see
//!   [`PeerPin::new`]). It is counted ([`PeerPin::foreign_samples`]).
//!
//! Everything here is a few integer compares on [`Cell`]s: no allocation, no lock, no
//! system call, no panic, so [`PeerPin::admit`] runs inside the control step. A `Cell` makes
//! the pin usable through a shared reference (`&Ports`) from the one thread that owns the
//! ports; it is `!Sync`, as the ports are.

use core::cell::Cell;
use iceoryx2::identifiers::UniquePublisherId;

/// Where a received sample came from, as [`PeerPin::admit`] decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Origin {
    /// The pinned peer.
    Peer,
    /// A new peer that replaced the pinned one (the pin has moved to it): begin a new
    /// session with it.
    NewPeer,
    /// Not from the peer: refuse the sample (it has been counted).
    Foreign,
}

/// No publisher: the raw id iceoryx2 never hands out (ids embed a creation time and a pid).
const NONE: u128 = 0;

/// The pinned peer of one side and the counters of what it refused. See the module docs.
#[derive(Debug)]
pub struct PeerPin {
    pinned: Cell<u128>,
    retired: Cell<u128>,
    pid: Cell<u32>,
    exclusive: bool,
    released: Cell<bool>,
    foreign: Cell<u64>,
    new_peers: Cell<u64>,
}

impl PeerPin {
    /// Pins the publisher with raw id `publisher` (`UniquePublisherId::value()`), owned by
    /// process `pid` when known.
    ///
    /// `exclusive` states that the peer's service admits one publisher only, so that a
    /// sample from any other publisher proves the pinned one gone (what
    /// [`crate::ports::connect`] verifies). Without it, an unknown publisher is foreign
    /// until [`PeerPin::release`] says that the pinned peer is gone.
    pub const fn new(publisher: u128, pid: Option<u32>, exclusive: bool) -> Self {
        Self {
            pinned: Cell::new(publisher),
            retired: Cell::new(NONE),
            pid: Cell::new(match pid {
                Some(p) => p,
                None => 0,
            }),
            exclusive,
            released: Cell::new(false),
            foreign: Cell::new(0),
            new_peers: Cell::new(0),
        }
    }

    /// Where a sample sent by `origin` (iceoryx2's `Sample::origin()`) came from; counts the
    /// foreign ones and moves the pin to a new peer (see the module docs). Allocation-free,
    /// lock-free, no system call.
    #[inline]
    pub fn admit(&self, origin: UniquePublisherId) -> Origin {
        self.admit_raw(origin.value())
    }

    /// [`PeerPin::admit`] on a raw publisher id.
    #[inline]
    pub fn admit_raw(&self, origin: u128) -> Origin {
        if origin == self.pinned.get() && origin != NONE {
            return Origin::Peer;
        }
        let vacant = self.exclusive || self.released.get() || self.pinned.get() == NONE;
        if origin == self.retired.get() || origin == NONE || !vacant {
            self.foreign.set(self.foreign.get().saturating_add(1));
            return Origin::Foreign;
        }
        self.retired.set(self.pinned.get());
        self.pinned.set(origin);
        self.pid.set(0);
        self.released.set(false);
        self.new_peers.set(self.new_peers.get().saturating_add(1));
        Origin::NewPeer
    }

    /// Says that the pinned peer is gone (its publisher is no longer registered, or its
    /// process died): the next unknown publisher becomes the new peer. Only needed for a
    /// pin that is not exclusive.
    pub fn release(&self) {
        self.released.set(true);
    }

    /// Records the pid of the pinned peer's process (after a re-pin, from the publisher
    /// list).
    pub fn set_pid(&self, pid: u32) {
        self.pid.set(pid);
    }

    /// The raw id of the pinned publisher.
    pub fn pinned(&self) -> u128 {
        self.pinned.get()
    }

    /// The pid of the pinned peer's process, if known.
    pub fn peer_pid(&self) -> Option<u32> {
        match self.pid.get() {
            0 => None,
            p => Some(p),
        }
    }

    /// Samples refused as foreign so far.
    pub fn foreign_samples(&self) -> u64 {
        self.foreign.get()
    }

    /// How many times the pin moved to a new peer.
    pub fn new_peers(&self) -> u64 {
        self.new_peers.get()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: u128 = 0xA1;
    const B: u128 = 0xB2;
    const C: u128 = 0xC3;

    #[test]
    fn samples_of_the_pinned_peer_are_admitted_and_nothing_is_counted() {
        let pin = PeerPin::new(A, Some(42), true);
        for _ in 0..10 {
            assert_eq!(pin.admit_raw(A), Origin::Peer);
        }
        assert_eq!(pin.foreign_samples(), 0);
        assert_eq!(pin.new_peers(), 0);
        assert_eq!(pin.peer_pid(), Some(42));
    }

    #[test]
    fn on_an_exclusive_slot_another_publisher_is_a_new_peer_and_the_old_one_becomes_foreign() {
        let pin = PeerPin::new(A, Some(42), true);
        assert_eq!(pin.admit_raw(B), Origin::NewPeer);
        assert_eq!(pin.pinned(), B);
        assert_eq!(pin.peer_pid(), None, "the new peer's pid is not known yet");
        assert_eq!(pin.admit_raw(B), Origin::Peer);
        // A late sample of the replaced peer is refused and counted.
        assert_eq!(pin.admit_raw(A), Origin::Foreign);
        assert_eq!(pin.foreign_samples(), 1);
        assert_eq!(pin.new_peers(), 1);
        pin.set_pid(7);
        assert_eq!(pin.peer_pid(), Some(7));
        // A third peer after the second one.
        assert_eq!(pin.admit_raw(C), Origin::NewPeer);
        assert_eq!(pin.admit_raw(B), Origin::Foreign);
        assert_eq!(pin.new_peers(), 2);
    }

    #[test]
    fn on_a_shared_slot_an_unknown_publisher_is_foreign_until_the_peer_is_released() {
        let pin = PeerPin::new(A, None, false);
        assert_eq!(pin.admit_raw(B), Origin::Foreign);
        assert_eq!(pin.admit_raw(B), Origin::Foreign);
        assert_eq!(pin.admit_raw(A), Origin::Peer);
        assert_eq!(pin.foreign_samples(), 2);
        pin.release();
        assert_eq!(pin.admit_raw(B), Origin::NewPeer);
        // The release is used up by the re-pin: a third publisher is foreign again.
        assert_eq!(pin.admit_raw(C), Origin::Foreign);
        assert_eq!(pin.admit_raw(A), Origin::Foreign);
        assert_eq!(pin.admit_raw(B), Origin::Peer);
        assert_eq!(pin.foreign_samples(), 4);
    }

    #[test]
    fn an_empty_pin_takes_the_first_publisher_and_the_null_id_is_never_admitted() {
        let pin = PeerPin::new(NONE, None, false);
        assert_eq!(pin.admit_raw(NONE), Origin::Foreign);
        assert_eq!(pin.admit_raw(A), Origin::NewPeer);
        assert_eq!(pin.admit_raw(A), Origin::Peer);
    }
}
