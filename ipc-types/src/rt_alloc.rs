//! A global allocator that watches the real-time thread.
//!
//! Both sides of the contract use it: the service's RT thread, and the loop of a plant side
//! (`plant_side::run`, plant-proxy, a DAQ process that installs it).
//!
//! The service's own real-time path does not allocate. One dependency does: iceoryx2 0.10
//! allocates a small reference-counted state (an `Rc` of 48 bytes) for every sample it
//! loans to a publisher (`ChunkMutSharedState::new`, called from `Publisher::loan_uninit`
//! and `send_copy`), and frees it when the sample is sent. Leaving that to the system
//! allocator puts an unbounded call (locks on a miss of the thread cache, `brk`/`mmap`) in
//! the loop once per sample.
//!
//! [`RtAwareAllocator`] is installed as the global allocator of the service binary (and of
//! plant-proxy). A thread
//! that calls [`enter_rt_thread`] gets a private pool of fixed-size blocks, allocated once;
//! from then on, every allocation on that thread that fits a block is served from the pool
//! in O(1) (pop from a free list) and freed back to it (push), with no lock and no system
//! call. Every allocation on that thread is counted, split into served-by-the-pool and
//! fell-through-to-the-system; the run report prints both, and the allocation test asserts
//! that the system count is zero and that the pool count is exactly one per published
//! sample, so a new allocation anywhere in the loop fails the test.
//!
//! All other threads, and every allocation before [`enter_rt_thread`], go to the system
//! allocator unchanged.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

/// Size of one pool block in bytes (also its alignment limit).
pub const BLOCK_SIZE: usize = 128;
/// Largest alignment a pool block satisfies.
pub const BLOCK_ALIGN: usize = 64;

#[repr(C, align(64))]
struct Block {
    next: *mut Block,
    _rest: [u8; BLOCK_SIZE - core::mem::size_of::<*mut Block>()],
}

struct Pool {
    free: *mut Block,
    base: usize,
    end: usize,
    served: u64,
    system: u64,
}

thread_local! {
    static POOL: Cell<*mut Pool> = const { Cell::new(core::ptr::null_mut()) };
}

/// Most threads that can have a pool in the process's life (the service has one RT thread;
/// test binaries run one thread per test). A thread beyond it is not counted, which
/// [`RtAllocStats::counted`] reports.
const MAX_POOLS: usize = 32;
/// Address ranges of every pool, so that a block freed by a thread that does not own it
/// is recognized (and leaked) instead of being handed to the system allocator.
static POOL_RANGES: [(AtomicUsize, AtomicUsize); MAX_POOLS] =
    [const { (AtomicUsize::new(0), AtomicUsize::new(0)) }; MAX_POOLS];
static POOLS_REGISTERED: AtomicUsize = AtomicUsize::new(0);
static FOREIGN_FREES: AtomicU64 = AtomicU64::new(0);
static INSTALLED: AtomicU64 = AtomicU64::new(0);

/// The global allocator; see the module docs. Install it with
/// `#[global_allocator] static A: RtAwareAllocator = RtAwareAllocator;`.
pub struct RtAwareAllocator;

#[inline]
fn in_any_pool(ptr: *mut u8) -> bool {
    let p = ptr as usize;
    let n = POOLS_REGISTERED.load(Ordering::Acquire).min(MAX_POOLS);
    POOL_RANGES[..n]
        .iter()
        .any(|(b, e)| p >= b.load(Ordering::Relaxed) && p < e.load(Ordering::Relaxed))
}

/// This thread's pool, when `ptr` is one of its blocks.
#[inline]
fn own_pool_of(ptr: *mut u8) -> Option<&'static mut Pool> {
    let pool = POOL.with(|p| p.get());
    if pool.is_null() {
        return None;
    }
    // SAFETY: created by enter_rt_thread on this thread, never freed.
    let pool = unsafe { &mut *pool };
    let p = ptr as usize;
    (p >= pool.base && p < pool.end).then_some(pool)
}

// SAFETY: every pointer handed out is either from `System` with the caller's layout, or a
// pool block of BLOCK_SIZE bytes aligned to BLOCK_ALIGN, handed out only for layouts that
// fit; pool blocks are only touched by the thread that owns the pool (the free list lives
// in a thread-local), and a block is returned to the pool only by its owner.
unsafe impl GlobalAlloc for RtAwareAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        INSTALLED.store(1, Ordering::Relaxed);
        let pool = POOL.with(|p| p.get());
        if !pool.is_null() {
            if layout.size() <= BLOCK_SIZE && layout.align() <= BLOCK_ALIGN {
                // SAFETY: `pool` was created by enter_rt_thread on this thread and lives
                // for the rest of the process.
                let pool = unsafe { &mut *pool };
                let block = pool.free;
                if !block.is_null() {
                    // SAFETY: `block` is a free pool block owned by this thread.
                    pool.free = unsafe { (*block).next };
                    pool.served += 1;
                    return block.cast();
                }
            }
            // SAFETY: as above.
            unsafe { (*pool).system += 1 };
        }
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if let Some(pool) = own_pool_of(ptr) {
            let block = ptr.cast::<Block>();
            // SAFETY: the block is no longer used by the caller; it is at least
            // BLOCK_SIZE bytes and aligned for a Block.
            unsafe { (*block).next = pool.free };
            pool.free = block;
            return;
        }
        if in_any_pool(ptr) {
            // A pool block freed by a thread that does not own it: leak it rather than race.
            FOREIGN_FREES.fetch_add(1, Ordering::Relaxed);
            return;
        }
        // SAFETY: not a pool block, so it came from System with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !POOL.with(|p| p.get()).is_null() || in_any_pool(ptr) {
            // Through alloc/dealloc so that pool blocks and counters stay consistent.
            // SAFETY: the new layout has the old alignment and a non-zero size.
            let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
            // SAFETY: as for alloc.
            let new = unsafe { self.alloc(new_layout) };
            if !new.is_null() {
                // SAFETY: both regions are valid for the smaller size and do not overlap.
                unsafe { core::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size)) };
                // SAFETY: `ptr` was allocated with `layout`.
                unsafe { self.dealloc(ptr, layout) };
            }
            return new;
        }
        // SAFETY: forwarded with the caller's arguments.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Counters of the allocations made on the calling thread since it entered its pool.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct RtAllocStats {
    /// True when [`RtAwareAllocator`] is the global allocator of this process.
    pub installed: bool,
    /// True when the calling thread has its pool ([`enter_rt_thread`] succeeded), so that
    /// its allocations are counted. Without it every count below reads zero.
    pub counted: bool,
    /// Allocations served from the RT pool (bounded time, no lock, no system call).
    pub pool_served: u64,
    /// Allocations on the RT thread that went to the system allocator (must be 0).
    pub system_on_rt_thread: u64,
    /// Pool blocks freed by another thread (leaked; must be 0).
    pub foreign_frees: u64,
}

/// The calling thread's counters so far (zeros for a thread without a pool);
/// `foreign_frees` is process-wide.
pub fn thread_stats() -> RtAllocStats {
    let pool = POOL.with(|p| p.get());
    let (pool_served, system_on_rt_thread) = if pool.is_null() {
        (0, 0)
    } else {
        // SAFETY: this thread's pool, never freed.
        unsafe { ((*pool).served, (*pool).system) }
    };
    RtAllocStats {
        installed: INSTALLED.load(Ordering::Relaxed) != 0,
        counted: !pool.is_null(),
        pool_served,
        system_on_rt_thread,
        foreign_frees: FOREIGN_FREES.load(Ordering::Relaxed),
    }
}

impl RtAllocStats {
    /// Counts accumulated between `earlier` and `self`.
    pub fn since(&self, earlier: &RtAllocStats) -> RtAllocStats {
        RtAllocStats {
            installed: self.installed,
            counted: self.counted,
            pool_served: self.pool_served - earlier.pool_served,
            system_on_rt_thread: self.system_on_rt_thread - earlier.system_on_rt_thread,
            foreign_frees: self.foreign_frees - earlier.foreign_frees,
        }
    }
}

/// Gives the calling thread a pool of `blocks` blocks (allocated now, once) and starts
/// counting its allocations. Call it after set-up, right before the loop. Idempotent.
pub fn enter_rt_thread(blocks: usize) {
    if !POOL.with(|p| p.get()).is_null() {
        return;
    }
    let blocks = blocks.max(1);
    let layout = Layout::array::<Block>(blocks).expect("pool layout");
    // SAFETY: non-zero size; the memory is never freed (the pool lives as long as the
    // process, and blocks may still be referenced by iceoryx2 state).
    let base = unsafe { System.alloc(layout) }.cast::<Block>();
    if base.is_null() {
        return;
    }
    let mut free: *mut Block = core::ptr::null_mut();
    for i in (0..blocks).rev() {
        // SAFETY: `i < blocks`, inside the allocation.
        let b = unsafe { base.add(i) };
        // SAFETY: `b` is valid for writes.
        unsafe { (*b).next = free };
        free = b;
    }
    let (b, e) = (base as usize, base as usize + blocks * BLOCK_SIZE);
    let slot = POOLS_REGISTERED.fetch_add(1, Ordering::AcqRel);
    if slot >= MAX_POOLS {
        POOLS_REGISTERED.fetch_sub(1, Ordering::AcqRel);
        // SAFETY: allocated above with this layout and not handed out.
        unsafe { System.dealloc(base.cast(), layout) };
        return;
    }
    POOL_RANGES[slot].0.store(b, Ordering::Relaxed);
    POOL_RANGES[slot].1.store(e, Ordering::Relaxed);
    let pool = Box::into_raw(Box::new(Pool {
        free,
        base: b,
        end: e,
        served: 0,
        system: 0,
    }));
    POOL.with(|p| p.set(pool));
}

/// Runs `f` with this thread's pool and counting suspended: its allocations go to the system
/// allocator uncounted. For housekeeping the RT thread does while it is not controlling
/// (the plant is silent), never for the control path.
pub fn outside_rt<R>(f: impl FnOnce() -> R) -> R {
    let saved = POOL.with(|p| p.replace(core::ptr::null_mut()));
    let r = f();
    POOL.with(|p| p.set(saved));
    r
}
