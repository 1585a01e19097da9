//! # record: everything the loop saw and sent, for `service replay`
//!
//! `record.bin` in the run folder holds, in the order the loop met them, every input that
//! decides what [`LoopCore`](crate::runtime::LoopCore) computes and every actuation it
//! published, at full precision, so that [`crate::replay`] can run the same `LoopCore` on
//! the same inputs offline and compare its outputs bit for bit.
//!
//! ## What is recorded, and why it suffices
//!
//! `LoopCore` is deterministic given its configuration, its controller's starting state
//! and the sequence of calls made on it with their arguments. Its inputs are:
//!
//! - [`EntryKind::Handle`]: a measurement handed to `handle` (every field the loop reads:
//!   contract version, flags, seq, sample time, period, deadline, channel counts, `y`, `z`,
//!   `r`, `u_applied`) and the receive time (it decides `timestamp_ok`, so the deadline
//!   verdict and the safe state);
//! - [`EntryKind::Observe`]: a measurement taken in too late (`observe`);
//! - [`EntryKind::NewPeer`]: another publisher sends the next sample (`note_new_peer`; a
//!   new plant session);
//! - [`EntryKind::WentSilent`]: the time at which `on_idle` declared the plant silent (the
//!   next sample is then a resume or a new session, which may reset the controller);
//!   the calls of `on_idle` that change nothing are not recorded;
//! - [`EntryKind::Operator`]: an operator command the loop applied (or refused) before
//!   the next entry ([`LoopCore::apply_command`](crate::runtime::LoopCore::apply_command));
//! - [`EntryKind::Publish`]: each actuation published (status, seq, reply-to, sample time,
//!   `u`, plan length and plan rows), with what the publisher returned: sent or not, and
//!   the time after it (the response time, so the deadline misses and the safe state).
//!
//! The clock read inside the loop only gives `compute_ns`, which decides nothing; the
//! configuration (its text and where its relative file names point) and a warm-start
//! checkpoint (copied into the run folder) are in the header. Resets, session changes,
//! safe-state entries and the open-loop phase follow from these inputs, so the replay
//! reproduces them rather than reading them.
//!
//! ## Format (version 2; version 1 is the same without `Operator` entries)
//!
//! All numbers little-endian; `f64` as its IEEE-754 bits.
//!
//! ```text
//! header   "ARRECORD"  u32 version  u32 N  N bytes of JSON (RecordHeader)
//! entries  u8 kind  u64 index  body (fixed size per kind, from the header's counts):
//!   1 Handle, 2 Observe  u64 t_recv (0 for Observe)  u32 contract  u32 flags  u64 seq
//!                        u64 t_sample  u64 period  u64 deadline  4×u16 counts
//!                        f64 y[n_y] z[n_z] r[n_r] u_applied[n_u]
//!   3 NewPeer            (nothing)
//!   4 WentSilent         u64 now
//!   5 Publish            u8 ok  u64 t_pub  u32 contract  u32 status  u64 seq  u64 reply_to
//!                        u64 t_sample  u64 compute_ns  4×u16 counts  u32 timing
//!                        u32 plan_len  f64 u[n_u]  f64 plan[plan_length][n_u]
//!   6 End                (nothing; its index is the number of entries the loop offered)
//!   7 Operator           u64 request_id  u32 command  u32 tunable index  f64 value
//! ```
//!
//! The index counts every entry the loop offered: one dropped by a full queue, or lost
//! to the disk, shows as a gap ([`RecordError::Gap`]), also at the end (before the end
//! mark); a file without the end mark is a run that did not finish
//! ([`RecordError::Unfinished`]).
//!
//! ## Out of the RT thread
//!
//! As the signal log ([`crate::logging`]): [`Recorder`] encodes an entry into a buffer
//! allocated at set-up and copies it into a bounded lock-free byte ring (`rtrb`), or drops
//! and counts it when the ring is full; nothing on that path allocates, locks, blocks,
//! does I/O or panics. The `record-writer` thread cuts the ring into whole entries and
//! writes them through a [`RecordFile`](crate::logging::RecordFile) (whole entries only,
//! failures reported and counted). [`RecordStats::complete`] says in the run report
//! whether every entry reached the file.

mod entry;
mod header;
mod layout;
mod reader;
mod recorder;
mod writer;

#[cfg(test)]
mod tests;

pub use entry::Entry;
pub use header::{FORMAT_VERSION, MAGIC, RecordHeader, config_fingerprint};
pub use layout::{ENTRY_HEAD_BYTES, EntryKind, RecordLayout};
pub use reader::{Located, RecordError, RecordReader};
pub use recorder::Recorder;
pub use writer::{RecordStats, RecordWriter, RecordWriterHandle};

use std::sync::Arc;

/// The file name of the record in a run folder.
pub const FILE_NAME: &str = "record.bin";

/// Creates the RT-side [`Recorder`] and the [`RecordWriter`] of a record described by
/// `header`, with a ring of `samples` samples' entries (one measurement and one actuation
/// each). Allocates: call it before the RT thread starts.
pub fn channel(header: &RecordHeader, samples: usize) -> (Recorder, RecordWriter) {
    let layout = header.layout();
    let bytes = samples
        .max(1)
        .saturating_mul(layout.measurement_bytes() + layout.publish_bytes());
    let (tx, rx) = rtrb::RingBuffer::<u8>::new(bytes);
    let counters = Arc::new(recorder::Counters::default());
    let recorder = Recorder::new(tx, layout, Arc::clone(&counters));
    let writer = RecordWriter {
        rx,
        layout,
        header: header.encode(),
        counters,
    };
    (recorder, writer)
}
