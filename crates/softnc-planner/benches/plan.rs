//! Planner throughput: parse + plan of a 200,000-line G1/G2/G3 program (reading then
//! planning; in one streaming pass; in one pass on two threads), plan alone, and the
//! cost of one interpolation sample.
//!
//! `SOFTNC_WRITE_BIG=1 cargo bench -p softnc-planner --bench plan` also writes the
//! program to `$TMPDIR/softnc-big-200k.ngc`, to time LinuxCNC on the same file:
//! `time rs274 -g $TMPDIR/softnc-big-200k.ngc /dev/null < /dev/null`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use softnc_planner::{plan, read_and_plan, read_and_plan_parallel, PlanOptions};

#[path = "common/workload.rs"]
mod workload;
use workload::{big_program, default_profile};

fn benches(c: &mut Criterion) {
    let p = default_profile();
    let text = big_program(200_000);
    let n_lines = text.lines().count() as u64;
    if std::env::var_os("SOFTNC_WRITE_BIG").is_some() {
        std::fs::write(std::env::temp_dir().join("softnc-big-200k.ngc"), &text).unwrap();
    }
    let mut g = c.benchmark_group("planner");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n_lines));
    let program = softnc_gcode::read_program(&text, "big.ngc", &p);
    match &program {
        Ok(program) => {
            g.bench_function("parse_and_plan_200k_lines", |b| {
                b.iter(|| {
                    let prog = softnc_gcode::read_program(&text, "big.ngc", &p).unwrap();
                    plan(
                        &prog,
                        &p,
                        &PlanOptions {
                            ignore_soft_limits: true,
                            ..Default::default()
                        },
                    )
                    .unwrap()
                })
            });
            let opts = PlanOptions {
                ignore_soft_limits: true,
                ..Default::default()
            };
            g.bench_function("read_and_plan_200k_lines", |b| {
                b.iter(|| read_and_plan(&text, "big.ngc", &p, &opts).unwrap())
            });
            g.bench_function("read_and_plan_parallel_200k_lines", |b| {
                b.iter(|| read_and_plan_parallel(&text, "big.ngc", &p, &opts).unwrap())
            });
            g.bench_function("plan_only_200k_lines", |b| {
                b.iter(|| {
                    plan(
                        program,
                        &p,
                        &PlanOptions {
                            ignore_soft_limits: true,
                            ..Default::default()
                        },
                    )
                    .unwrap()
                })
            });
            let planned = plan(
                program,
                &p,
                &PlanOptions {
                    ignore_soft_limits: true,
                    ..Default::default()
                },
            )
            .unwrap();
            g.throughput(Throughput::Elements(100_000));
            g.bench_function("interpolate_100k_samples", |b| {
                b.iter(|| {
                    planned
                        .interpolator()
                        .take(100_000)
                        .fold(0.0, |acc, s| acc + s.pos_mm[0])
                })
            });
        }
        Err(e) => eprintln!("G-code reader refused the benchmark program: {e}"),
    }
    g.finish();
}

criterion_group!(planner, benches);
criterion_main!(planner);
