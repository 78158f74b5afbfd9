//! `fillet::line_arc` alone, on the line–arc joins of the 200,000-line throughput
//! workload, against its copy as of 557cc9e: the calls one after the other as a loop
//! runs them (independent: the processor may overlap them) and chained (each call's
//! corner waits for the one before: the latency of one call).

use criterion::{black_box, criterion_group, Criterion, Throughput};
use softnc_core::Vec3;
use softnc_planner::fillet::{self, ArcView, Fillet};

#[path = "common/workload.rs"]
mod workload;
use workload::{big_program, default_profile};

#[path = "common/fillet_joins.rs"]
mod fillet_joins;
use fillet_joins::{joins, Join};

/// (the old copy's coverage points count nothing here)
macro_rules! cover {
    ($i:expr) => {};
}

#[path = "../tests/common/line_arc_557.rs"]
mod line_arc_557;

/// The workload's blend tolerance (its `G64 P0.01`, mm).
const TOL_MM: f64 = 0.01;

type LineArc = fn(Vec3, Vec3, f64, &ArcView, f64, f64) -> Option<Fillet>;
/// A loop over the joins with one `line_arc`.
type Loop = fn(&[Join], LineArc) -> f64;

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

/// Two joins at a time through `fillet::line_arc_2` (`_f` unused: a `Loop`).
fn pairs(js: &[Join], _f: LineArc) -> f64 {
    fn join(j: &Join) -> fillet::LineArcJoin<'_> {
        fillet::LineArcJoin {
            corner: j.corner,
            u: j.u,
            line_avail_mm: j.line_avail_mm,
            arc: &j.arc,
            arc_avail_mm: j.arc_avail_mm,
            tol_mm: j.tol_mm,
        }
    }
    let mut acc = 0.0;
    let mut out = [None, None];
    for w in js.chunks_exact(2) {
        fillet::line_arc_2([join(&w[0]), join(&w[1])], &mut out);
        for x in out.iter().flatten() {
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

/// `FILLET_AB=rounds`: instead of criterion, rounds of the four loops in turn (each
/// round in a new order), printing the least and the median time of each per call
/// (ns): on a machine others load, the least is the figure to compare.
fn interleaved(rounds: usize) {
    let js = workload_joins();
    let cases: [(&str, Loop, LineArc); 5] = [
        ("new_pairs", pairs, fillet::line_arc),
        ("new_independent", independent, fillet::line_arc),
        ("557_independent", independent, line_arc_557::line_arc),
        ("new_chained", chained, fillet::line_arc),
        ("557_chained", chained, line_arc_557::line_arc),
    ];
    let mut times = vec![Vec::new(); cases.len()];
    let mut order: Vec<usize> = (0..cases.len()).collect();
    for round in 0..rounds {
        order.rotate_left(1 + round % (cases.len() - 1));
        for &i in &order {
            let (_, run, f) = cases[i];
            let t = std::time::Instant::now();
            black_box(run(black_box(&js), f));
            times[i].push(t.elapsed().as_secs_f64() * 1e9 / js.len() as f64);
        }
    }
    for (i, (name, _, _)) in cases.iter().enumerate() {
        let t = &mut times[i];
        t.sort_by(f64::total_cmp);
        println!(
            "{name:16} least {:6.1} ns  median {:6.1} ns",
            t[0],
            t[t.len() / 2]
        );
    }
}

fn benches(c: &mut Criterion) {
    let js = workload_joins();
    let mut g = c.benchmark_group("line_arc");
    g.throughput(Throughput::Elements(js.len() as u64));
    g.bench_function("new_independent", |b| {
        b.iter(|| independent(black_box(&js), fillet::line_arc))
    });
    g.bench_function("557_independent", |b| {
        b.iter(|| independent(black_box(&js), line_arc_557::line_arc))
    });
    g.bench_function("new_pairs", |b| {
        b.iter(|| pairs(black_box(&js), fillet::line_arc))
    });
    g.bench_function("new_chained", |b| {
        b.iter(|| chained(black_box(&js), fillet::line_arc))
    });
    g.bench_function("557_chained", |b| {
        b.iter(|| chained(black_box(&js), line_arc_557::line_arc))
    });
    g.finish();
}

criterion_group!(fillet_benches, benches);

fn main() {
    match std::env::var("FILLET_AB").ok().and_then(|r| r.parse().ok()) {
        Some(rounds) => interleaved(rounds),
        None => {
            fillet_benches();
            Criterion::default().configure_from_args().final_summary();
        }
    }
}
