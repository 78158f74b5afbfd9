//! What the workspace's tests share: a counting global allocator.
//!
//! A test binary registers it with
//! `#[global_allocator] static GLOBAL: softnc_test_support::Counting = softnc_test_support::Counting;`
//! and then reads, on the thread under test:
//! - [`allocations`]: every allocation (and reallocation) this thread has made;
//! - [`count`] / [`counted`]: only those made inside `count(f)` (the daemon's cycle
//!   tests, whose harness threads allocate beside them);
//! - [`peak_of`]: the peak of the heap above what was live before, all threads
//!   together (byte counters are global: one such test a binary).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The counting allocator: `System`'s, counting per thread and the live bytes.
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static COUNTED: Cell<usize> = const { Cell::new(0) };
}

/// One allocation on this thread. `try_with`: the slots may be gone while a thread
/// is being torn down.
fn one() {
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
    if COUNTING.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNTED.try_with(|c| c.set(c.get() + 1));
    }
}

/// `n` more bytes live.
fn grow(n: usize) {
    let live = LIVE.fetch_add(n, Relaxed) + n;
    PEAK.fetch_max(live, Relaxed);
}

// SAFETY: every call is forwarded to the system allocator unchanged; the counting
// touches only this thread's cells and two atomics.
#[allow(unsafe_code)] // a counting allocator forwarding to `System`
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        one();
        grow(l.size());
        // SAFETY: forwarding to the system allocator with the caller's layout.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Relaxed);
        // SAFETY: p was allocated by System with layout l.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new_size: usize) -> *mut u8 {
        one();
        if new_size >= l.size() {
            grow(new_size - l.size());
        } else {
            LIVE.fetch_sub(l.size() - new_size, Relaxed);
        }
        // SAFETY: forwarding to the system allocator with the caller's layout.
        unsafe { System.realloc(p, l, new_size) }
    }
}

/// Allocations (and reallocations) this thread has made so far.
pub fn allocations() -> usize {
    ALLOCS.with(Cell::get)
}

/// Run `f` with this thread's allocations counted into [`counted`].
pub fn count<T>(f: impl FnOnce() -> T) -> T {
    COUNTING.with(|c| c.set(true));
    let r = f();
    COUNTING.with(|c| c.set(false));
    r
}

/// Allocations this thread made inside [`count`] so far.
pub fn counted() -> usize {
    COUNTED.with(Cell::get)
}

/// `f`'s result and the peak heap above what was live before it, while it ran
/// (bytes, every thread's).
pub fn peak_of<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let base = LIVE.load(Relaxed);
    PEAK.store(base, Relaxed);
    let r = f();
    (r, PEAK.load(Relaxed).saturating_sub(base))
}

/// Bytes live on the heap now (every thread's).
pub fn live_bytes() -> usize {
    LIVE.load(Relaxed)
}
