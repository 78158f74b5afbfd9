//! Same seed ⇒ bit-identical trace; different seeds ⇒ different traces.

use softnc_core::{Plane, Primitive, Vec3};
use softnc_machine::MachineProfile;
use softnc_sim::{simulate, simulated_engine, CommandSample, SimOptions};
use std::f64::consts::TAU;
use std::path::PathBuf;

fn profile(name: &str) -> MachineProfile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/machines")
        .join(format!("{name}.ron"));
    let mut p = MachineProfile::load(&path).unwrap();
    // measurement noise on, so the seed matters for every model
    // the default profile has no servo section: make its default axes explicit
    p.servo.axes = (0..3).map(|i| p.axis_servo(i)).collect();
    for a in &mut p.servo.axes {
        a.noise_mm = 0.0005;
    }
    p
}

/// Every number of every cycle of a 20 mm circle, as bits.
fn trace(p: &MachineProfile, seed: u64) -> Vec<u64> {
    let t = p.interpolation_cycle_s;
    let (r, f) = (20.0, 400.0);
    let omega = f / 60.0 / r;
    let n = (TAU / omega / t).round() as u64;
    let circle = Primitive::arc(
        Vec3::new(r, 0.0, 0.0),
        Vec3::new(r, 0.0, 0.0),
        Vec3::ZERO,
        Plane::XY,
        1,
    );
    let samples = (0..n).map(|k| {
        let th = omega * t * k as f64;
        CommandSample {
            pos_mm: softnc_core::Axes([r * th.cos(), r * th.sin(), 0.0]),
            motion: 0,
            feed_move: true,
            outputs: Default::default(),
        }
    });
    let mut engine = simulated_engine(p, seed, SimOptions::default());
    let mut bits = Vec::new();
    simulate(
        &mut engine,
        t,
        samples,
        |_| Some(circle),
        |row| {
            let rec = &row.record;
            for v in rec
                .actual_mm
                .iter()
                .chain(&rec.following_mm)
                .chain(&rec.ctrl_out)
            {
                bits.push(v.to_bits());
            }
            bits.push(row.contour_mm.unwrap().to_bits());
        },
    )
    .unwrap();
    bits
}

#[test]
fn one_seed_is_bit_identical_and_seeds_differ() {
    for name in ["mill-friction", "tnv40-pdc", "tnv40-ilc", "default"] {
        let p = profile(name);
        let a = trace(&p, 11);
        let b = trace(&p, 11);
        assert!(a == b, "{name}: two runs with seed 11 differ");
        let c = trace(&p, 12);
        assert!(a != c, "{name}: seeds 11 and 12 gave the same trace");
    }
}
