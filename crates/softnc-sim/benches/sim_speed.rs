//! Offline simulation speed: 3 axes at 1 kHz, incremental PID + feedforward, the
//! paper 001 DC servo with eq 15 friction and stick–slip, 8-bit DAC, encoders, noise.
//! Also one axis's controller step (PID + feedforward) per call.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use softnc_control::AxisController;
use softnc_machine::servo::ControllerConfig;
use softnc_machine::MachineProfile;
use softnc_sim::{simulate, simulated_engine, CommandSample, SimOptions};
use std::path::PathBuf;
use std::time::Instant;

/// Paper 001's machine moved to a 1 kHz cycle: the eq 14 gains carry the sample time,
/// so K_i scales with T and K_d with 1/T; velocity feedforward 1/K.
fn profile_1khz() -> MachineProfile {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/mill-friction.ron");
    let mut p = MachineProfile::load(&path).unwrap();
    let scale = 0.001 / p.interpolation_cycle_s;
    p.interpolation_cycle_s = 0.001;
    for a in &mut p.servo.axes {
        a.controller.ki *= scale;
        a.controller.kd /= scale;
        a.controller.vff = 60.0 / 28.35;
        a.noise_mm = 0.001;
    }
    p
}

/// `n` cycles of a 20 mm circle at 1 m/min in XY with Z oscillating.
fn samples(n: u64) -> impl Iterator<Item = CommandSample> {
    let w = 1000.0 / 60.0 / 20.0;
    (0..n).map(move |k| {
        let t = k as f64 * 0.001;
        CommandSample {
            pos_mm: softnc_core::Axes([
                20.0 * (w * t).cos(),
                20.0 * (w * t).sin(),
                2.0 * (0.5 * w * t).sin(),
            ]),
            motion: 0,
            feed_move: true,
            outputs: Default::default(),
        }
    })
}

fn run(p: &MachineProfile, n: u64) -> f64 {
    let mut engine = simulated_engine(p, 1, SimOptions::default());
    let r = simulate(
        &mut engine,
        0.001,
        samples(n),
        |_| None,
        |row| {
            black_box(row);
        },
    )
    .unwrap();
    r.following[0].rms()
}

fn bench(c: &mut Criterion) {
    let p = profile_1khz();
    let mut g = c.benchmark_group("sim");
    g.sample_size(10);
    g.bench_function("3 axes 1 kHz PID+friction, 60 s simulated", |b| {
        b.iter(|| run(&p, 60_000))
    });
    g.finish();

    // one simulated hour, timed once, to state the real-time factor
    let start = Instant::now();
    let rms = run(&p, 3_600_000);
    let wall = start.elapsed().as_secs_f64();
    println!(
        "one simulated hour (3 600 000 cycles, 3 axes): {wall:.3} s wall, real-time factor {:.0}x (following rms X {:.1} µm)",
        3600.0 / wall,
        rms * 1000.0
    );

    let cfg = ControllerConfig {
        kp: 240.0,
        ki: 1.0,
        kd: 6700.0,
        vff: 2.1,
        aff: 0.1,
        output_limit: 127.0,
        ..ControllerConfig::default()
    };
    let mut axis = AxisController::new(&cfg, 0.001);
    axis.reset(0.0);
    let mut k = 0u64;
    c.bench_function("controller step, one axis, PID + feedforward", |b| {
        b.iter(|| {
            k += 1;
            let cmd = k as f64 * 1e-3;
            black_box(axis.step(black_box(cmd), black_box(cmd - 0.01)))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
