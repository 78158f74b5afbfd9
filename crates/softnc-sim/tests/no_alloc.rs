//! The per-cycle step (controller stacks + simulated machine) allocates nothing.

use softnc_core::MachineProfile;
use softnc_sim::{CycleEngine, SimOptions};
use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

struct Counting;
static ALLOCS: AtomicU64 = AtomicU64::new(0);

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
fn cycle_step_allocates_nothing() {
    for name in ["mill-friction", "tnv40-pdc", "tnv40-ilc", "default"] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../config/machines")
            .join(format!("{name}.ron"));
        let mut p = MachineProfile::load(&path).unwrap();
        // the default profile has no servo section: make its default axes explicit
        p.servo.axes = (0..3).map(|i| p.axis_servo(i)).collect();
        for a in &mut p.servo.axes {
            a.noise_mm = 0.001;
        }
        let mut engine = CycleEngine::simulated(&p, 3, SimOptions::default());
        let t = p.interpolation_cycle_s;
        let before = ALLOCS.load(Ordering::SeqCst);
        let mut sink = 0.0;
        for k in 0..20_000u32 {
            let x = 5.0 * (f64::from(k) * t).sin();
            let rec = engine.step([x, -x, 0.5 * x], k % 2 == 0).unwrap();
            sink += rec.following_mm[0];
        }
        let after = ALLOCS.load(Ordering::SeqCst);
        assert!(sink.is_finite());
        assert_eq!(
            after - before,
            0,
            "{name}: {} allocations in 20 000 cycles",
            after - before
        );
    }
}
