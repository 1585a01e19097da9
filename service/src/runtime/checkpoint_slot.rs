//! The hand-off of checkpoints from the real-time loop to the thread that writes them.
//!
//! Two buffers, each as long as the controller's learned blocks together
//! ([`Controller::learned`]), and a state per buffer (`FREE → FILLING → READY → TAKEN →
//! FREE`). The real-time side claims a free buffer with one compare-and-swap, copies the
//! blocks into it (no allocation, no lock: a `memcpy` of what was learned), and marks it
//! ready; when neither buffer is free (the writer is still busy with both) the checkpoint is
//! skipped and counted, never waited for. The writer takes every ready buffer, keeps the
//! newest and frees the others. Each state change is a release store or a successful
//! compare-and-swap read with acquire ordering, so the side that owns a buffer sees the
//! other side's writes to it.

use control::Controller;
use control::learned::Blocks;
use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicU8, Ordering};

const FREE: u8 = 0;
const FILLING: u8 = 1;
const READY: u8 = 2;
const TAKEN: u8 = 3;

/// Where a checkpoint was taken.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CheckpointMark {
    /// Sequence number of the last sample the controller had taken in.
    pub seq: u64,
    /// Plant sessions begun so far (1 for the first plant).
    pub plant_session: u64,
}

struct Buffer {
    values: UnsafeCell<Vec<f64>>,
    mark: UnsafeCell<CheckpointMark>,
    state: AtomicU8,
}

/// The two buffers and the layout of the blocks (names and lengths, fixed by the
/// configuration).
pub struct CheckpointSlot {
    layout: Vec<(&'static str, usize)>,
    buffers: [Buffer; 2],
}

// SAFETY: a buffer's contents are only touched by the side that moved its state out of
// FREE (the real-time loop, to FILLING) or out of READY (the writer, to TAKEN), and given
// back with a release store; the other side reads the state with acquire ordering first.
unsafe impl Sync for CheckpointSlot {}

/// What [`CheckpointSlot::offer`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offered {
    /// The blocks were copied and await the writer.
    Copied,
    /// Both buffers were busy: skipped.
    Busy,
    /// A block held a non-finite value: not offered (a checkpoint must be loadable).
    NotFinite,
}

impl CheckpointSlot {
    /// Buffers for `controller`'s learned blocks (allocating; before the real-time loop).
    pub fn new(controller: &dyn Controller) -> Self {
        let mut layout = Vec::new();
        controller.learned(&mut |name, values| layout.push((name, values.len())));
        let total = layout.iter().map(|(_, n)| n).sum();
        let buffer = || Buffer {
            values: UnsafeCell::new(vec![0.0; total]),
            mark: UnsafeCell::new(CheckpointMark::default()),
            state: AtomicU8::new(FREE),
        };
        Self {
            layout,
            buffers: [buffer(), buffer()],
        }
    }

    /// The block names and lengths, in the controller's order.
    pub fn layout(&self) -> &[(&'static str, usize)] {
        &self.layout
    }

    /// True when the controller learns nothing (no checkpoint to take).
    pub fn is_empty(&self) -> bool {
        self.layout.is_empty()
    }

    /// Copies what `controller` learned, taken at `mark`, into a free buffer. Real-time
    /// side: no allocation, no lock, no wait.
    pub fn offer(&self, controller: &dyn Controller, mark: CheckpointMark) -> Offered {
        let Some(buffer) = self.buffers.iter().find(|b| {
            b.state
                .compare_exchange(FREE, FILLING, Ordering::Acquire, Ordering::Relaxed)
                .is_ok()
        }) else {
            return Offered::Busy;
        };
        // SAFETY: this side moved the buffer to FILLING; nobody else touches it until the
        // release store below.
        let (values, slot_mark) = unsafe { (&mut *buffer.values.get(), &mut *buffer.mark.get()) };
        let mut offset = 0;
        let mut finite = true;
        controller.learned(&mut |_, block| {
            let end = offset + block.len();
            if let Some(dst) = values.get_mut(offset..end) {
                dst.copy_from_slice(block);
                finite &= block.iter().all(|v| v.is_finite());
            } else {
                finite = false;
            }
            offset = end;
        });
        *slot_mark = mark;
        if finite && offset == values.len() {
            buffer.state.store(READY, Ordering::Release);
            Offered::Copied
        } else {
            buffer.state.store(FREE, Ordering::Release);
            Offered::NotFinite
        }
    }

    /// The newest ready checkpoint as named blocks, freeing its buffer (writer side; allocates).
    pub fn take(&self) -> Option<(CheckpointMark, Blocks)> {
        let taken: Vec<&Buffer> = self
            .buffers
            .iter()
            .filter(|b| {
                b.state
                    .compare_exchange(READY, TAKEN, Ordering::Acquire, Ordering::Relaxed)
                    .is_ok()
            })
            .collect();
        // SAFETY: this side moved these buffers to TAKEN.
        let newest = taken
            .iter()
            .max_by_key(|b| unsafe { (*b.mark.get()).seq })
            .map(|b| {
                let (values, mark) = unsafe { (&*b.values.get(), *b.mark.get()) };
                (mark, self.split(values))
            });
        for b in taken {
            b.state.store(FREE, Ordering::Release);
        }
        newest
    }

    /// The learned blocks of `controller` now, named (off the real-time loop; allocates).
    pub fn snapshot(&self, controller: &dyn Controller) -> Blocks {
        let mut blocks = Vec::new();
        controller.learned(&mut |name, values| blocks.push((name.to_string(), values.to_vec())));
        blocks
    }

    fn split(&self, values: &[f64]) -> Blocks {
        let mut offset = 0;
        self.layout
            .iter()
            .map(|&(name, n)| {
                let block = values[offset..offset + n].to_vec();
                offset += n;
                (name.to_string(), block)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use control::{Dimensions, StepInput};

    /// Learns `[k, k]` and `[−k]` after `k` steps.
    struct Counter(f64);
    impl Controller for Counter {
        fn kind(&self) -> &'static str {
            "counter"
        }
        fn counts(&self) -> Dimensions {
            Dimensions::new(1, 1, 0, 1)
        }
        fn step(&mut self, _: &StepInput<'_>, _: &mut [f64]) -> u32 {
            self.0 += 1.0;
            0
        }
        fn reset(&mut self) {}
        fn learned(&self, visit: &mut dyn FnMut(&'static str, &[f64])) {
            visit("a", &[self.0, self.0]);
            visit("b", &[-self.0]);
        }
    }

    fn mark(seq: u64) -> CheckpointMark {
        CheckpointMark {
            seq,
            plant_session: 1,
        }
    }

    #[test]
    fn the_newest_ready_checkpoint_is_taken_and_a_third_offer_waits_for_a_free_buffer() {
        let mut c = Counter(1.0);
        let slot = CheckpointSlot::new(&c);
        assert_eq!(slot.layout(), &[("a", 2), ("b", 1)]);
        assert_eq!(slot.offer(&c, mark(10)), Offered::Copied);
        c.0 = 2.0;
        assert_eq!(slot.offer(&c, mark(20)), Offered::Copied);
        c.0 = 3.0;
        assert_eq!(slot.offer(&c, mark(30)), Offered::Busy);
        let (m, blocks) = slot.take().unwrap();
        assert_eq!(m.seq, 20);
        assert_eq!(blocks[0], ("a".to_string(), vec![2.0, 2.0]));
        assert_eq!(blocks[1], ("b".to_string(), vec![-2.0]));
        assert!(slot.take().is_none(), "both buffers were freed");
        assert_eq!(slot.offer(&c, mark(30)), Offered::Copied);
        assert_eq!(slot.take().unwrap().0.seq, 30);
    }

    #[test]
    fn a_non_finite_block_is_not_offered() {
        let c = Counter(f64::NAN);
        let slot = CheckpointSlot::new(&c);
        assert_eq!(slot.offer(&c, mark(1)), Offered::NotFinite);
        assert!(slot.take().is_none());
        assert_eq!(slot.offer(&Counter(1.0), mark(2)), Offered::Copied);
    }
}
