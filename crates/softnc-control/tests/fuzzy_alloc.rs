//! The fuzzy controller's cycle path allocates nothing (counting global allocator).
//!
//! Only allocations made by the test's own thread are counted: the test harness's
//! other threads may allocate at any time.

use softnc_control::fuzzy::{FuzzyConfig, FuzzyController};

use softnc_test_support::{allocations as allocs, Counting};

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
