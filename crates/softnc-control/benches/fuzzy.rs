//! Cost of one fuzzy-controller step (paper 001 FLC): target ≤ 200 ns per axis.
//!
//! The error sequence sweeps the whole universe (and beyond it) so every branch of
//! the fuzzifier and every rule cell is exercised.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use softnc_control::fuzzy::{FuzzyConfig, FuzzyController};

fn errors() -> Vec<f64> {
    // 1024 errors in BLU: a slow sweep of ±30 plus a fast ripple of ±6.
    (0..1024)
        .map(|k| {
            let t = k as f64;
            30.0 * (t * 0.0123).sin() + 6.0 * (t * 0.71).sin()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let cfg = FuzzyConfig::from_ron_str(
        include_str!("../../../config/fuzzy/paper001.ron"),
        "paper001.ron",
    )
    .unwrap();
    let es = errors();
    let mut flc = FuzzyController::new(&cfg);
    let mut k = 0usize;
    c.bench_function("fuzzy_step", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(flc.step(black_box(es[k])))
        })
    });
    let flc = FuzzyController::new(&cfg);
    c.bench_function("fuzzy_surface", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(flc.surface(black_box(es[k]), black_box(es[(k + 7) & 1023] * 0.2)))
        })
    });
    let mut axes = [
        FuzzyController::new(&cfg),
        FuzzyController::new(&cfg),
        FuzzyController::new(&cfg),
    ];
    c.bench_function("fuzzy_step_3_axes", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            let mut s = 0.0;
            for (i, a) in axes.iter_mut().enumerate() {
                s += a.step(black_box(es[(k + 100 * i) & 1023]));
            }
            black_box(s)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
