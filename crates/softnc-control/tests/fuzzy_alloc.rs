//! The fuzzy controller's cycle path allocates nothing (counting global allocator).
//!
//! Only allocations made by the test's own thread are counted: the test harness's
//! other threads may allocate at any time.

use softnc_control::fuzzy::{FuzzyConfig, FuzzyController};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the slot may be gone while a thread is being torn down.
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

fn allocs() -> usize {
    ALLOCS.with(|c| c.get())
}

#[allow(unsafe_code)] // a counting allocator forwarding to `System`
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn step_allocates_nothing() {
    let cfg = FuzzyConfig::from_ron_str(
        include_str!("../../../config/fuzzy/paper001.ron"),
        "paper001.ron",
    )
    .unwrap();
    let mut flc = FuzzyController::new(&cfg);
    let before = allocs();
    let mut s = 0.0;
    for k in 0..100_000 {
        let e = 40.0 * (k as f64 * 0.001).sin() + 3.0 * (k as f64 * 0.9).cos();
        s += flc.step(e) + flc.surface(e, -e * 0.1);
    }
    let after = allocs();
    assert!(s.is_finite());
    assert_eq!(after - before, 0, "step/surface allocated");
    // The counter works: a Vec allocates on this thread.
    let v: Vec<u64> = Vec::with_capacity(8);
    assert!(allocs() > after);
    drop(v);
}
