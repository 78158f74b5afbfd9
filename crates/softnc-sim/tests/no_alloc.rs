//! The per-cycle step (controller stacks + simulated machine) allocates nothing.

use softnc_machine::MachineProfile;
use softnc_sim::{simulated_engine, SimOptions};
use std::path::PathBuf;

use softnc_test_support::{allocations as allocs, Counting};

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
        let mut engine = simulated_engine(&p, 3, SimOptions::default());
        let t = p.interpolation_cycle_s;
        let before = allocs();
        let mut sink = 0.0;
        for k in 0..20_000u32 {
            let x = 5.0 * (f64::from(k) * t).sin();
            let rec = engine.step([x, -x, 0.5 * x], k % 2 == 0).unwrap();
            sink += rec.following_mm[0];
        }
        let after = allocs();
        assert!(sink.is_finite());
        assert_eq!(
            after - before,
            0,
            "{name}: {} allocations in 20 000 cycles",
            after - before
        );
    }
}

#[test]
fn filtered_cycle_from_the_ring_allocates_nothing() {
    // paper 002's zero-lag filter reading the command ring, and a structural mode
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/mill-resonance.ron");
    let p = MachineProfile::load(&path).unwrap();
    let mut engine = simulated_engine(&p, 3, SimOptions::default());
    assert_eq!(engine.filter_window(), 75);
    let t = p.interpolation_cycle_s;
    let x = |k: u64| 5.0 * (k as f64 * t).sin();
    let mut ring = Box::new(softnc_core::CommandRing::new());
    ring.reset_padded(engine.filter_window());
    let mut next = 0u64;
    let mut push = |ring: &mut softnc_core::CommandRing| {
        let s = softnc_core::RingSample {
            seq: next,
            pos_mm: [x(next), -x(next), 0.0],
        };
        ring.push(s, false).unwrap();
        next += 1;
    };
    for _ in 0..200 {
        push(&mut ring);
    }
    let before = allocs();
    let mut sink = 0.0;
    for _ in 0..20_000 {
        push(&mut ring);
        let rec = engine
            .step_ring(&ring, 0, true)
            .expect("window in")
            .unwrap();
        sink += rec.cmd_mm[0];
        assert!(ring.advance());
    }
    let after = allocs();
    assert!(sink.is_finite());
    assert_eq!(
        after - before,
        0,
        "{} allocations in 20 000 filtered cycles",
        after - before
    );
}
