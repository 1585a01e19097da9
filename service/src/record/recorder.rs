//! The RT thread's end of the record queue: encodes an entry into a pre-allocated buffer
//! and copies it into a bounded lock-free byte ring; when the ring is full the entry is
//! dropped and counted, and its index is used anyway so that a reader sees the gap.

use super::entry::{encode_marker, encode_measurement, encode_operator, encode_publish};
use super::layout::{EntryKind, RecordLayout};
use ipc_types::{Actuation, Measurement};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counters shared by the recorder, the writer and the run report.
#[derive(Debug, Default)]
pub(super) struct Counters {
    /// Entries offered (pushed or dropped).
    pub(super) offered: AtomicU64,
    /// Entries dropped because the ring was full.
    pub(super) dropped: AtomicU64,
}

/// The RT side of a record: [`Recorder::handle`], [`Recorder::observe`],
/// [`Recorder::new_peer`], [`Recorder::went_silent`], [`Recorder::publish`]. None of them
/// allocates, locks, blocks, does I/O or panics.
pub struct Recorder {
    tx: rtrb::Producer<u8>,
    layout: RecordLayout,
    scratch: Box<[u8]>,
    index: u64,
    dropped: u64,
    counters: Arc<Counters>,
}

impl Recorder {
    pub(super) fn new(
        tx: rtrb::Producer<u8>,
        layout: RecordLayout,
        counters: Arc<Counters>,
    ) -> Self {
        Self {
            tx,
            layout,
            scratch: vec![0u8; layout.max_entry_bytes()].into_boxed_slice(),
            index: 0,
            dropped: 0,
            counters,
        }
    }

    /// The layout it encodes with.
    pub fn layout(&self) -> &RecordLayout {
        &self.layout
    }

    /// Entries offered so far (pushed or dropped).
    pub fn offered(&self) -> u64 {
        self.index
    }

    /// Entries dropped so far because the ring was full.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Records measurement `m` handed to the loop at `t_recv_ns`.
    #[inline]
    pub fn handle(&mut self, m: &Measurement, t_recv_ns: u64) {
        let n = encode_measurement(
            &self.layout,
            EntryKind::Handle,
            self.index,
            m,
            t_recv_ns,
            &mut self.scratch,
        );
        self.commit(n);
    }

    /// Records measurement `m` taken in too late.
    #[inline]
    pub fn observe(&mut self, m: &Measurement) {
        let n = encode_measurement(
            &self.layout,
            EntryKind::Observe,
            self.index,
            m,
            0,
            &mut self.scratch,
        );
        self.commit(n);
    }

    /// Records that the next sample comes from another publisher.
    #[inline]
    pub fn new_peer(&mut self) {
        let n = encode_marker(EntryKind::NewPeer, self.index, None, &mut self.scratch);
        self.commit(n);
    }

    /// Records that the loop declared the plant silent at `now_ns`.
    #[inline]
    pub fn went_silent(&mut self, now_ns: u64) {
        let n = encode_marker(
            EntryKind::WentSilent,
            self.index,
            Some(now_ns),
            &mut self.scratch,
        );
        self.commit(n);
    }

    /// Records operator command `q`, applied before the next entry.
    #[inline]
    pub fn operator(&mut self, q: &crate::runtime::operator::Queued) {
        let (index, value) = match q.command {
            crate::runtime::operator::Command::SetTunable { index, value } => (index as u32, value),
            _ => (0, 0.0),
        };
        let n = encode_operator(
            self.index,
            q.request_id,
            q.command.code(),
            index,
            value,
            &mut self.scratch,
        );
        self.commit(n);
    }

    /// Records actuation `act`, published (`ok`) with the publisher's time `t_pub_ns`.
    #[inline]
    pub fn publish(&mut self, act: &Actuation, ok: bool, t_pub_ns: u64) {
        let n = encode_publish(
            &self.layout,
            self.index,
            act,
            ok,
            t_pub_ns,
            &mut self.scratch,
        );
        self.commit(n);
    }

    /// Copies the first `n` bytes of the scratch buffer into the ring as one entry, or
    /// drops and counts it.
    #[inline]
    fn commit(&mut self, n: usize) {
        let n = n.min(self.scratch.len());
        match self.tx.write_chunk_uninit(n) {
            Ok(mut chunk) => {
                let (first, second) = chunk.as_mut_slices();
                let (head, tail) = self.scratch[..n].split_at(first.len().min(n));
                for (dst, src) in first.iter_mut().zip(head) {
                    dst.write(*src);
                }
                for (dst, src) in second.iter_mut().zip(tail) {
                    dst.write(*src);
                }
                // SAFETY: the chunk holds exactly `n` slots (`first.len() + second.len() ==
                // n`), and the two loops above wrote every one of them.
                unsafe { chunk.commit_all() };
            }
            Err(_) => {
                self.dropped += 1;
                self.counters.dropped.store(self.dropped, Ordering::Relaxed);
            }
        }
        self.index += 1;
        self.counters.offered.store(self.index, Ordering::Relaxed);
    }
}
