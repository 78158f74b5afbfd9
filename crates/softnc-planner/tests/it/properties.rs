//! Property tests: random programs never panic, stay within every axis limit and end
//! exactly at their last point.

use super::common;
use common::*;
use proptest::prelude::*;
use softnc_core::{FeedProfile, Plane, Vec3};

#[derive(Debug, Clone)]
enum Op {
    Rapid(f64, f64, f64),
    Line(f64, f64, f64, f64),
    Arc(f64, f64, i32, u8, f64),
    Dwell(f64),
}

fn op() -> impl Strategy<Value = Op> {
    let c = -50.0..50.0f64;
    prop_oneof![
        (c.clone(), c.clone(), -20.0..0.0f64).prop_map(|(x, y, z)| Op::Rapid(x, y, z)),
        (c.clone(), c.clone(), -20.0..0.0f64, 10.0..8000.0f64)
            .prop_map(|(x, y, z, f)| Op::Line(x, y, z, f)),
        (0.5..20.0f64, 0.0..6.3f64, -2..3i32, 0..3u8, 10.0..6000.0f64)
            .prop_map(|(r, a, t, pl, f)| Op::Arc(r, a, t, pl, f)),
        (0.0..0.05f64).prop_map(Op::Dwell),
    ]
}

fn build(ops: &[Op], exact: bool) -> Builder {
    let mut b = Builder::new(Vec3::ZERO);
    if exact {
        b.mode = softnc_gcode::PathMode::ExactStop;
    }
    for o in ops {
        apply(&mut b, o);
    }
    b
}

/// One operation onto `b`.
fn apply(b: &mut Builder, o: &Op) {
    match *o {
        Op::Rapid(x, y, z) => {
            b.rapid(x, y, z);
        }
        Op::Line(x, y, z, f) => {
            b.line(x, y, z, f);
        }
        Op::Arc(r, ang, turns, pl, f) => {
            let plane = [Plane::XY, Plane::XZ, Plane::YZ][pl as usize];
            let (a, bb, n) = plane.axes();
            let p = b.pos;
            let mut c = p;
            c[a] = p[a] - r * ang.cos();
            c[bb] = p[bb] - r * ang.sin();
            let mut e = c;
            let th = ang + 1.3;
            e[a] = c[a] + r * th.cos();
            e[bb] = c[bb] + r * th.sin();
            e[n] = p[n] + if turns.abs() > 1 { -1.0 } else { 0.0 };
            let t = if turns == 0 { 1 } else { turns };
            b.arc(e, c, plane, t, f);
        }
        Op::Dwell(s) => {
            b.dwell(s);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    #[test]
    fn random_programs_stay_within_limits(ops in prop::collection::vec(op(), 1..12), exact in any::<bool>(), scurve in any::<bool>()) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let p = profile(fp);
        let b = build(&ops, exact);
        let plan = plan_of(&b, &p);
        prop_assert!(plan.stats().samples < 2_000_000, "planned {} samples", plan.stats().samples);
        let s = run(&plan);
        let r = limit_ratios(&s, &p);
        prop_assert!(r[0] <= 1.0 + 1e-9, "velocity {}", r[0]);
        prop_assert!(r[1] <= 1.0 + 1e-9, "acceleration {}", r[1]);
        if scurve {
            prop_assert!(r[2] <= 1.0 + 1e-9, "jerk {}", r[2]);
        }
        prop_assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9);
        let dev = max_path_deviation(&s, &plan, b.motions.len());
        prop_assert!(dev <= p.planner.tolerance_mm + 1e-6, "deviation {}", dev);
    }

    /// M0 pauses waited at and resumed, single block switched on and off at random
    /// cycles (resumed at every block end it stops at): the same limits, the same
    /// end, within the tolerance of the program.
    #[test]
    fn pauses_and_single_block_stay_within_limits(
        ops in prop::collection::vec(op(), 1..12),
        pauses in prop::collection::vec(any::<bool>(), 12),
        on_at in 0..3000u64,
        off_for in 0..3000u64,
        scurve in any::<bool>(),
    ) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let p = profile(fp);
        let mut b = Builder::new(Vec3::ZERO);
        for (k, o) in ops.iter().enumerate() {
            apply(&mut b, o);
            if pauses[k] {
                b.pause();
            }
        }
        let options = softnc_planner::PlanOptions {
            ignore_soft_limits: true,
            wait_at_program_stops: true,
            ..Default::default()
        };
        let plan = softnc_planner::plan(&b.program(), &p, &options).expect("plans");
        let mut it = plan.interpolator();
        let mut s = Vec::new();
        let limit = plan.stats().samples as usize + 100_000;
        while let Some(x) = it.next() {
            s.push(x);
            let n = s.len() as u64;
            if n == on_at {
                it.set_single_block(true);
            }
            if n == on_at + off_for {
                it.set_single_block(false);
            }
            if it.paused_at_line().is_some() {
                it.resume();
            }
            prop_assert!(s.len() < limit, "ran past {} samples", limit);
        }
        let r = limit_ratios(&s, &p);
        prop_assert!(r[0] <= 1.0 + 1e-9, "velocity {}", r[0]);
        prop_assert!(r[1] <= 1.0 + 1e-9, "acceleration {}", r[1]);
        if scurve {
            prop_assert!(r[2] <= 1.0 + 1e-9, "jerk {}", r[2]);
        }
        prop_assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9);
        let dev = max_path_deviation(&s, &plan, b.motions.len());
        prop_assert!(dev <= p.planner.tolerance_mm + 1e-6, "deviation {}", dev);
    }
}

/// Largest ratio of the S-curve plan's run time to the trapezoidal one's on the
/// programs below: the S-curve waits one window (78 ms) at each of its stops.
const MAX_SCURVE_OVER_TRAPEZOIDAL: f64 = 1.01;

/// Plans `ops` with both feed profiles; checks the S-curve plan's limits, end and
/// path deviation, and gives (S-curve, trapezoidal) planned samples.
fn scurve_and_trapezoidal_samples(ops: &[Op]) -> (u64, u64) {
    let b = build(ops, false);
    let p = profile(FeedProfile::SCurve);
    let plan = plan_of(&b, &p);
    let trapezoidal = plan_of(&b, &profile(FeedProfile::Trapezoidal));
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r.iter().all(|&x| x <= 1.0 + 1e-9), "limit ratios {r:?}");
    assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9);
    let dev = max_path_deviation(&s, &plan, b.motions.len());
    assert!(dev <= p.planner.tolerance_mm + 1e-6, "deviation {dev}");
    (plan.stats().samples, trapezoidal.stats().samples)
}

/// The proptest case `cc 125de1c1…` (`properties.proptest-regressions`): with the
/// S-curve, the corner from a 96.5 mm rapid into a 10 mm/min feed was blended at
/// 0.057 mm/s (the blend's jerk cap), a cap that holds on every element within its
/// reach in full, so the rapid and the feed after it crawled at 0.057 mm/s: 2,455,944
/// samples against 468,409 trapezoidal. Stopping at that corner costs a window.
#[test]
fn scurve_rapid_between_slow_feeds_does_not_crawl() {
    let ops = [
        Op::Line(-40.65384959787173, 32.67460696703266, 0.0, 10.0),
        Op::Rapid(37.84728877898609, -23.470344547315296, 0.0),
        Op::Line(48.765187645581996, 0.0, 0.0, 10.0),
    ];
    let (scurve, trapezoidal) = scurve_and_trapezoidal_samples(&ops);
    assert!(
        scurve as f64 <= MAX_SCURVE_OVER_TRAPEZOIDAL * trapezoidal as f64,
        "S-curve {scurve} samples, trapezoidal {trapezoidal}"
    );
}

/// The same corner (100.6°) between two 10 mm/min feeds: blended at 0.057 mm/s, both
/// lines would run at a third of their feed.
#[test]
fn scurve_corner_of_slow_feeds_does_not_crawl() {
    let ops = [
        Op::Line(20.0, -14.322, 0.0, 10.0),
        Op::Line(24.219, -5.254, 0.0, 10.0),
    ];
    let (scurve, trapezoidal) = scurve_and_trapezoidal_samples(&ops);
    assert!(
        scurve as f64 <= MAX_SCURVE_OVER_TRAPEZOIDAL * trapezoidal as f64,
        "S-curve {scurve} samples, trapezoidal {trapezoidal}"
    );
}

/// S-curve: no limit reaches across a stop (the profile waits one window there, so
/// the smoothed samples on either side average motion of that side only). A 50 mm
/// line at 1,200 mm/min stopping before a zig-zag of 0.3 mm lines, blended at
/// 4.8 mm/s (3.8 mm reach), took its time at 4.8 mm/s; now the program takes the
/// line's time and the zig-zag's, each planned alone.
/// Largest ratio of a program's run time to the sum of its two halves' planned alone,
/// where a stop parts them.
const MAX_OVER_PLANNED_APART: f64 = 1.01;

#[test]
fn scurve_limits_do_not_reach_across_a_stop() {
    const FEED_MM_PER_MIN: f64 = 1200.0;
    const START: Vec3 = Vec3::new(50.0, 0.0, 0.0);
    let zigzag = |b: &mut Builder| {
        let (step_x, step_y) = (0.3 * 0.1f64.cos(), 0.3 * 0.1f64.sin());
        for k in 1..=20 {
            let y = if k % 2 == 1 { step_y } else { 0.0 };
            b.line(START[0] + step_x * k as f64, y, 0.0, FEED_MM_PER_MIN);
        }
    };
    let p = profile(FeedProfile::SCurve);
    let mut line = Builder::new(Vec3::ZERO);
    line.mode = softnc_gcode::PathMode::ExactStop;
    line.line(START[0], START[1], START[2], FEED_MM_PER_MIN);
    let mut alone = Builder::new(START);
    zigzag(&mut alone);
    let mut both = Builder::new(Vec3::ZERO);
    both.mode = softnc_gcode::PathMode::ExactStop;
    both.line(START[0], START[1], START[2], FEED_MM_PER_MIN);
    both.mode = softnc_gcode::PathMode::default();
    zigzag(&mut both);
    let samples = |b: &Builder| plan_of(b, &p).stats().samples as f64;
    let (t_line, t_alone, t_both) = (samples(&line), samples(&alone), samples(&both));
    assert!(
        t_both <= MAX_OVER_PLANNED_APART * (t_line + t_alone),
        "line {t_line}, zig-zag {t_alone}, both {t_both} samples"
    );
    let plan = plan_of(&both, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r.iter().all(|&x| x <= 1.0 + 1e-9), "limit ratios {r:?}");
    assert!((s.last().unwrap().pos_mm - both.pos).norm() < 1e-9);
    let dev = max_path_deviation(&s, &plan, both.motions.len());
    assert!(dev <= p.planner.tolerance_mm + 1e-6, "deviation {dev}");
}
