//! The fuzzy controller's cycle path allocates nothing (counting global allocator).

use softnc_control::fuzzy::{FuzzyConfig, FuzzyController};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn step_allocates_nothing() {
    let mut flc = FuzzyController::new(&FuzzyConfig::paper001());
    let before = ALLOCS.load(Ordering::SeqCst);
    let mut s = 0.0;
    for k in 0..100_000 {
        let e = 40.0 * (k as f64 * 0.001).sin() + 3.0 * (k as f64 * 0.9).cos();
        s += flc.step(e) + flc.surface(e, -e * 0.1);
    }
    let after = ALLOCS.load(Ordering::SeqCst);
    assert!(s.is_finite());
    assert_eq!(after - before, 0, "step/surface allocated");
    // The counter works: a Vec allocates.
    let v: Vec<u64> = Vec::with_capacity(8);
    assert!(ALLOCS.load(Ordering::SeqCst) > after);
    drop(v);
}
