//! Biarc blends (`fillet::biarc`, with `planner.arc_blends`): corners between helices,
//! arcs of different planes and lines, which no single circle can blend, do not stop;
//! the path stays within every axis limit and within the G64 tolerance of the
//! program (distance to the helices measured, not the in-plane radial error), ends
//! exactly, and every programmed primitive is given back.

use super::common;
use common::*;
use proptest::prelude::*;
use softnc_core::{FeedProfile, Plane, Primitive, Vec3};
use softnc_gcode::PathMode;
use softnc_planner::Sample;

/// The test profile with arc blends on or off.
fn with_arc_blends(fp: FeedProfile, on: bool) -> softnc_core::MotionProfile {
    let mut p = profile(fp);
    p.planner.arc_blends = on;
    p
}

/// Distance of `q` from a primitive: a line exactly; an arc or helix by a search
/// over 1,000 points refined by golden-section search around every one of them
/// within h/2 of the nearest (h their spacing): the point nearest the true foot lies
/// within h/2 of it, and an arc of more than a turn passes near `q` once per turn,
/// so the nearest grid point may lie on another turn than the foot.
fn dist(prim: &Primitive, q: Vec3) -> f64 {
    if let Primitive::Line { .. } = prim {
        return distance(prim, q);
    }
    let n = 1000;
    let len = prim.length();
    let h = len / n as f64;
    let d = |s: f64| (prim.point_at(s) - q).norm();
    let grid: Vec<f64> = (0..=n).map(|i| d(i as f64 * h)).collect();
    let nearest = grid.iter().cloned().fold(f64::INFINITY, f64::min);
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let refine = |k: usize| {
        let (mut lo, mut hi) = (
            (((k as f64) - 1.0) * h).max(0.0),
            (((k as f64) + 1.0) * h).min(len),
        );
        for _ in 0..80 {
            let (m1, m2) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if d(m1) < d(m2) {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        d(0.5 * (lo + hi)).min(grid[k])
    };
    (0..=n)
        .filter(|&k| grid[k] <= nearest + 0.5 * h)
        .map(refine)
        .fold(f64::INFINITY, f64::min)
}

/// Largest distance of any sample from the whole programmed path.
fn deviation(samples: &[Sample], b: &Builder) -> f64 {
    let prims: Vec<Primitive> = b
        .motions
        .iter()
        .filter_map(softnc_planner::build::motion_primitive)
        .collect();
    samples
        .iter()
        .map(|s| {
            prims
                .iter()
                .map(|p| dist(p, s.pos_mm))
                .fold(f64::INFINITY, f64::min)
        })
        .fold(0.0, f64::max)
}

/// Lowest path speed between the first and the last tenth of the run (mm/s).
fn min_inner_speed(s: &[Sample], cycle_s: f64) -> f64 {
    let n = s.len();
    s[n / 10..n - n / 10]
        .windows(2)
        .map(|w| (w[1].pos_mm - w[0].pos_mm).norm() / cycle_s)
        .fold(f64::INFINITY, f64::min)
}

/// The checks every biarc-blended program must pass.
fn check(b: &Builder, fp: FeedProfile, tol: f64, what: &str) -> softnc_planner::Plan {
    let p = with_arc_blends(fp, true);
    let plan = plan_of(b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{what}: {r:?}");
    if fp == FeedProfile::SCurve {
        assert!(r[2] <= 1.0 + 1e-9, "{what}: jerk {r:?}");
    }
    assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9, "{what}");
    let dev = deviation(&s, b);
    assert!(dev <= tol + 1e-6, "{what}: deviation {dev} > {tol}");
    for (k, m) in b.motions.iter().enumerate() {
        assert_eq!(
            plan.motion_primitive(k),
            softnc_planner::build::motion_primitive(m),
            "{what}: motion {k}"
        );
    }
    plan
}

/// As in `tort.ngc`: a line, a helix about Z, a line, a helix of more than a turn
/// in the XZ plane, an arc of the YZ plane, a line; every join a real corner.
fn tort_like(tol: f64) -> Builder {
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = PathMode::Blend {
        tolerance_mm: Some(tol),
        naive_cam_mm: None,
    };
    let f = 3000.0;
    b.line(10.0, 0.0, 0.0, f);
    // helix about (10, 8): a half turn while Z rises 4 mm
    b.arc(
        Vec3::new(10.0, 16.0, 4.0),
        Vec3::new(10.0, 8.0, 0.0),
        Plane::XY,
        1,
        f,
    );
    b.line(0.0, 20.0, 6.0, f);
    // XZ helix of 1¼ turns about (0, ·, 0) moving 5 mm along Y
    b.arc(
        Vec3::new(-6.0, 25.0, 0.0),
        Vec3::new(0.0, 20.0, 0.0),
        Plane::XZ,
        -2,
        f,
    );
    // YZ arc (no normal travel) about (·, 25, 12)
    b.arc(
        Vec3::new(-6.0, 37.0, 12.0),
        Vec3::new(-6.0, 25.0, 12.0),
        Plane::YZ,
        1,
        f,
    );
    b.line(4.0, 40.0, 15.0, f);
    b
}

#[test]
fn helix_and_cross_plane_corners_are_blended_within_limits_and_tolerance() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        for tol in [0.01, 0.1, 1000.0] {
            let b = tort_like(tol);
            let what = format!("{fp:?} tol {tol}");
            let plan = check(&b, fp, tol, &what);
            // off, every one of these corners stops
            let off = plan_of(&b, &with_arc_blends(fp, false));
            let p = with_arc_blends(fp, true);
            // (at 0.01 mm some corners are too tight to pass at speed)
            if fp == FeedProfile::Trapezoidal && tol >= 0.1 {
                let s = run(&plan);
                let v = min_inner_speed(&s, p.interpolation_cycle_s);
                assert!(v > 2.0, "{what}: slowest {v} mm/s");
                assert!(
                    plan.stats().duration_s < off.stats().duration_s - 0.05,
                    "{what}: {} s vs {} s stopping",
                    plan.stats().duration_s,
                    off.stats().duration_s
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, ..ProptestConfig::default() })]
    /// Random chains of 3-D lines and helices (any plane, both senses, up to two
    /// turns, rising or falling along the normal, some with an end radius a few µm
    /// off the start's) under random tolerances, both profiles: within every limit, within the tolerance of the program, ending
    /// exactly, every primitive given back.
    #[test]
    fn random_helix_chains_stay_within_limits_and_tolerance(
        ops in prop::collection::vec(
            (0.2..15.0f64, 0.0..6.3f64, -0.9..0.9f64, 0..3u8, any::<bool>(), 0.2..12.0f64, any::<bool>(), -6.0..6.0f64),
            1..8),
        wobble_mm in prop::sample::select(vec![0.0, 0.0, 0.003, -0.004]),
        tol in 0.005..0.5f64,
        scurve in any::<bool>(),
    ) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let mut b = Builder::new(Vec3::ZERO);
        b.mode = PathMode::Blend { tolerance_mm: Some(tol), naive_cam_mm: None };
        for (len, ang, rise, pl, is_arc, sweep, ccw, travel) in ops {
            let plane = [Plane::XY, Plane::XZ, Plane::YZ][pl as usize];
            let (a, bb, n) = plane.axes();
            let pos = b.pos;
            if is_arc {
                let mut c = pos;
                c[a] = pos[a] - len * ang.cos();
                c[bb] = pos[bb] - len * ang.sin();
                let th = ang + if ccw { sweep } else { -sweep };
                let mut e = c;
                e[a] = c[a] + len * th.cos();
                e[bb] = c[bb] + len * th.sin();
                // an end radius rounded as CAM output rounds it (a spiral)
                e[a] += wobble_mm * th.cos();
                e[bb] += wobble_mm * th.sin();
                e[n] = pos[n] + travel;
                let turns = 1 + (sweep / std::f64::consts::TAU) as i32;
                b.arc(e, c, plane, if ccw { turns } else { -turns }, 3000.0);
            } else {
                let mut e = pos;
                let flat = (1.0 - rise * rise).sqrt();
                e[a] = pos[a] + len * flat * ang.cos();
                e[bb] = pos[bb] + len * flat * ang.sin();
                e[n] = pos[n] + len * rise;
                b.line(e[0], e[1], e[2], 6000.0);
            }
        }
        check(&b, fp, tol, "random chain");
    }
}

/// A line, a quarter arc whose end radius is 3 µm off its start's (CAM rounding in
/// inch programs: 1e-4 in; the reader takes it and runs the spiral), a line; both
/// corners 90°. No circle fillet takes such an arc (its tangent drifts from the
/// circle's by 2ΔR/(R·sweep) ≈ 7.6e-4 rad); the biarc touches the spiral along its
/// own tangent, so the corners do not stop.
#[test]
fn corners_at_an_arc_whose_end_radius_is_rounded_are_blended() {
    let spiral = |tol: f64| {
        let mut b = Builder::new(Vec3::ZERO);
        b.mode = PathMode::Blend {
            tolerance_mm: Some(tol),
            naive_cam_mm: None,
        };
        b.line(10.0, 0.0, 0.0, 3000.0);
        b.arc(
            Vec3::new(15.0, -5.003, 0.0),
            Vec3::new(15.0, 0.0, 0.0),
            Plane::XY,
            1,
            3000.0,
        );
        b.line(15.0, -15.003, 0.0, 3000.0);
        b
    };
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        for tol in [0.05, 1000.0] {
            let b = spiral(tol);
            let what = format!("{fp:?} tol {tol}");
            let plan = check(&b, fp, tol, &what);
            if fp == FeedProfile::Trapezoidal {
                let p = with_arc_blends(fp, true);
                let v = min_inner_speed(&run(&plan), p.interpolation_cycle_s);
                assert!(v > 2.0, "{what}: slowest {v} mm/s");
            }
        }
    }
}
