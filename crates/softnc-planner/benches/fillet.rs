//! `fillet::line_arc` alone, on the line–arc joins of the 200,000-line throughput
//! workload: the calls one after the other as a loop runs them (independent: the
//! processor may overlap them) and chained (each call's corner waits for the one
//! before: the latency of one call).

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use softnc_core::Vec3;
use softnc_planner::fillet::{self, ArcView, Fillet};

#[path = "common/workload.rs"]
mod workload;
use workload::{big_program, default_profile};

#[path = "common/fillet_joins.rs"]
mod fillet_joins;
use fillet_joins::{joins, Join};

/// The workload's blend tolerance (its `G64 P0.01`, mm).
const TOL_MM: f64 = 0.01;

type LineArc = fn(Vec3, Vec3, f64, &ArcView, f64, f64) -> Option<Fillet>;

fn independent(js: &[Join], f: LineArc) -> f64 {
    let mut acc = 0.0;
    for j in js {
        if let Some(x) = f(
            j.corner,
            j.u,
            j.line_avail_mm,
            &j.arc,
            j.arc_avail_mm,
            j.tol_mm,
        ) {
            acc += x.radius;
        }
    }
    acc
}

fn chained(js: &[Join], f: LineArc) -> f64 {
    let mut acc = 0.0;
    let mut dep = 0.0;
    for j in js {
        let mut corner = j.corner;
        corner[0] += dep;
        if let Some(x) = f(
            corner,
            j.u,
            j.line_avail_mm,
            &j.arc,
            j.arc_avail_mm,
            j.tol_mm,
        ) {
            acc += x.radius;
            dep = x.sweep * 0.0;
        }
    }
    acc
}

/// The workload's joins.
fn workload_joins() -> Vec<Join> {
    let p = default_profile();
    let text = big_program(200_000);
    let program = softnc_gcode::read_program(&text, "big.ngc", &p).expect("workload reads");
    joins(&program, TOL_MM)
}

fn benches(c: &mut Criterion) {
    let js = workload_joins();
    let mut g = c.benchmark_group("line_arc");
    g.throughput(Throughput::Elements(js.len() as u64));
    g.bench_function("independent", |b| {
        b.iter(|| independent(black_box(&js), fillet::line_arc))
    });
    g.bench_function("chained", |b| {
        b.iter(|| chained(black_box(&js), fillet::line_arc))
    });
    g.finish();
}

criterion_group!(fillet_benches, benches);
criterion_main!(fillet_benches);
