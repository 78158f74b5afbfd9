//! The sampled path honours every axis limit (finite differences, 1.00×), stays within
//! tolerance of the programmed path and ends exactly at its last point.

use super::common;
use common::*;
use softnc_core::{FeedProfile, Plane, Vec3};

fn check(b: &Builder, fp: FeedProfile) -> (Vec<softnc_planner::Sample>, [f64; 3]) {
    let p = profile(fp);
    let plan = plan_of(b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x of limit", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x of limit", r[1]);
    if fp == FeedProfile::SCurve {
        assert!(r[2] <= 1.0 + 1e-9, "jerk {:.4}x of limit", r[2]);
    }
    let last = s.last().unwrap().pos_mm;
    assert_eq!(last, b.pos, "ends exactly at the last programmed point");
    let dev = max_path_deviation(&s, &plan, b.motions.len());
    assert!(dev <= p.planner.tolerance_mm + 1e-9, "deviation {dev} mm");
    (s, r)
}

fn square_and_arcs() -> Builder {
    let mut b = Builder::new(Vec3::ZERO);
    b.rapid(10.0, 10.0, -5.0)
        .line(60.0, 10.0, -5.0, 3000.0)
        .line(60.0, 60.0, -5.0, 3000.0)
        .line(10.0, 60.0, -5.0, 3000.0)
        .line(10.0, 10.0, -5.0, 3000.0)
        .arc(
            Vec3::new(50.0, 10.0, -5.0),
            Vec3::new(30.0, 10.0, -5.0),
            Plane::XY,
            -1,
            2000.0,
        )
        .arc(
            Vec3::new(50.0, 10.0, -8.0),
            Vec3::new(30.0, 10.0, -5.0),
            Plane::XY,
            2,
            2000.0,
        )
        .line(50.0, 10.0, 0.0, 1000.0)
        .rapid(0.0, 0.0, 0.0);
    b
}

#[test]
fn trapezoidal_square_and_arcs_within_limits() {
    let (_, r) = check(&square_and_arcs(), FeedProfile::Trapezoidal);
    assert!(r[1] > 0.5, "uses the acceleration it has: {r:?}");
}

#[test]
fn scurve_square_and_arcs_within_limits() {
    check(&square_and_arcs(), FeedProfile::SCurve);
}

#[test]
fn three_d_corners_and_planes() {
    let mut b = Builder::new(Vec3::ZERO);
    b.line(20.0, 5.0, -3.0, 6000.0)
        .line(25.0, 30.0, -10.0, 6000.0)
        .line(0.0, 0.0, 0.0, 6000.0)
        .arc(
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 0.0),
            Plane::XZ,
            -1,
            1500.0,
        )
        .arc(
            Vec3::new(10.0, 10.0, 20.0),
            Vec3::new(10.0, 10.0, 10.0),
            Plane::YZ,
            1,
            1500.0,
        )
        .rapid(0.0, 0.0, 0.0);
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        check(&b, fp);
    }
}

#[test]
fn exact_stop_and_dwell() {
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = softnc_gcode::PathMode::ExactStop;
    b.line(10.0, 0.0, 0.0, 1200.0)
        .line(10.0, 10.0, 0.0, 1200.0)
        .dwell(0.5)
        .line(0.0, 0.0, 0.0, 1200.0);
    let (s, _) = check(&b, FeedProfile::Trapezoidal);
    // the corner (10,0) is reached: the stop lies within one cycle of a sample
    let near = s
        .iter()
        .map(|x| (x.pos_mm - Vec3::new(10.0, 0.0, 0.0)).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(
        near < 0.5 * 3000.0 * 1e-6,
        "closest sample {near} mm from the corner"
    );
    // the dwell: at least 0.5 s standing at (10,10)
    let still = s
        .iter()
        .filter(|x| (x.pos_mm - Vec3::new(10.0, 10.0, 0.0)).norm() < 1e-12)
        .count();
    assert!(
        still as f64 * 0.001 >= 0.5,
        "{still} samples at the dwell point"
    );
}
