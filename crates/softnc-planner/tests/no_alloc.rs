//! Pulling samples allocates nothing (a counting global allocator proves it).

mod common;
use common::*;
use softnc_core::{FeedProfile, Plane, Vec3};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    // per thread: the test harness's own threads allocate while a test runs
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    // `try_with`: the slot may be gone while a thread is being torn down
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

fn allocs() -> usize {
    ALLOCS.with(|c| c.get())
}

#[allow(unsafe_code)] // a counting allocator forwarding to `System`
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarding to the system allocator with the caller's layout.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System.alloc with layout l.
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn sample_generation_allocates_nothing() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let mut b = Builder::new(Vec3::ZERO);
        b.rapid(10.0, 10.0, -2.0)
            .line(40.0, 10.0, -2.0, 2400.0)
            .line(40.0, 30.0, -3.0, 2400.0);
        b.arc(
            Vec3::new(40.0, 30.0, -3.0),
            Vec3::new(30.0, 30.0, -3.0),
            Plane::XY,
            1,
            1800.0,
        )
        .dwell(0.1);
        b.line(0.0, 0.0, 0.0, 3000.0);
        let plan = plan_of(&b, &p);
        let mut it = plan.interpolator();
        let before = allocs();
        let mut n = 0u64;
        let mut last = Vec3::ZERO;
        while let Some(s) = it.next() {
            n += 1;
            last = s.pos_mm;
            if n == 500 {
                it.set_feed_override(1.7);
            }
        }
        let after = allocs();
        assert!(n > 1000);
        assert_eq!(last, b.pos);
        assert_eq!(
            after - before,
            0,
            "{fp:?}: {} allocations while pulling {n} samples",
            after - before
        );
    }
}

/// Pauses, resume and single block switched live allocate nothing either.
#[test]
fn pauses_and_single_block_allocate_nothing() {
    let text = "G21 G64\nG1 X20 F3000\nG1 X20 Y20\nM0\nG1 X0 Y20\nG1 X0 Y0\nG1 X10 Y5\nM2\n";
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let options = softnc_planner::PlanOptions {
            wait_at_program_stops: true,
            ..Default::default()
        };
        let (_, plan) = softnc_planner::read_and_plan(text, "t.ngc", &p, &options).unwrap();
        let mut it = plan.interpolator();
        let before = allocs();
        let (mut n, mut pauses) = (0u64, 0u32);
        let mut last = Vec3::ZERO;
        while let Some(s) = it.next() {
            n += 1;
            last = s.pos_mm;
            if it.paused_at_line().is_some() {
                pauses += 1;
                it.resume();
            }
            if n == 200 {
                it.set_single_block(true);
            }
        }
        let after = allocs();
        assert!(pauses >= 2, "{fp:?}: {pauses} pauses");
        assert_eq!(last, Vec3::new(10.0, 5.0, 0.0));
        assert_eq!(
            after - before,
            0,
            "{fp:?}: allocations while pulling {n} samples"
        );
    }
}
