//! Blends at line–arc, arc–line and arc–arc corners (`fillet.rs`, profile switch
//! `planner.arc_blends`, on in these tests): the path does not stop there, stays within every axis limit and within the G64 tolerance of the program,
//! and every programmed primitive is still given back exactly.

use super::common;
use common::*;
use proptest::prelude::*;
use softnc_core::{FeedProfile, Plane, Primitive, Vec3};
use softnc_gcode::{MotionKind, PathMode};
use softnc_planner::Sample;

/// The test profile with arc blends on.
fn arc_profile(fp: FeedProfile) -> softnc_core::MotionProfile {
    let mut p = profile(fp);
    p.planner.arc_blends = true;
    p
}

/// The test profile with arc blends off (the corners stop).
fn stop_profile(fp: FeedProfile) -> softnc_core::MotionProfile {
    let mut p = profile(fp);
    p.planner.arc_blends = false;
    p
}

/// Largest distance of any sample from the whole programmed path.
fn deviation_from_program(samples: &[Sample], b: &Builder) -> f64 {
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
                .map(|p| match p {
                    Primitive::Line { .. } => distance(p, s.pos_mm),
                    Primitive::Arc { .. } => p.contour_error(s.pos_mm).abs(),
                })
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

/// line → quarter arc turning the other way → line, in `plane`: two corners of 45°
/// where a line meets an arc.
fn line_arc_line(plane: Plane, cw: bool, tol: f64) -> Builder {
    let (a, bb, _) = plane.axes();
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = PathMode::Blend {
        tolerance_mm: Some(tol),
        naive_cam_mm: None,
    };
    let at = |x: f64, y: f64| {
        let mut v = Vec3::ZERO;
        v[a] = x;
        v[bb] = y;
        v
    };
    let f = 6000.0;
    // along +a to (20, 0); the arc leaves at 45° to it (centre chosen so), ends, then
    // a line leaves the arc's end at 45° again
    let p1 = at(20.0, 0.0);
    let [x, y, z] = p1.0;
    b.line(x, y, z, f);
    let r = 10.0;
    let s = if cw { -1.0 } else { 1.0 };
    // tangent at the arc start is (cos 45°, s·sin 45°)·…: centre on the normal
    let (tx, ty) = (0.5f64.sqrt(), s * 0.5f64.sqrt());
    let c = p1 + at(-ty * r * s, tx * r * s);
    let ang0 = (p1[bb] - c[bb]).atan2(p1[a] - c[a]);
    let ang1 = ang0 + s * 1.0;
    let end = c + at(r * ang1.cos(), r * ang1.sin());
    b.arc(end, c, plane, if cw { -1 } else { 1 }, f);
    let out = end + at(15.0, 0.0);
    let [x, y, z] = out.0;
    b.line(x, y, z, f);
    b
}

#[test]
fn line_arc_corners_are_blended_in_every_plane_within_limits_and_tolerance() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = arc_profile(fp);
        for plane in [Plane::XY, Plane::XZ, Plane::YZ] {
            for cw in [false, true] {
                let tol = 0.05;
                let b = line_arc_line(plane, cw, tol);
                let mut exact = line_arc_line(plane, cw, tol);
                let off = plan_of(&b, &stop_profile(fp));
                for m in &mut exact.motions {
                    m.path_mode = PathMode::ExactStop;
                }
                // the corners are real: the arc leaves the line (and the line the arc)
                // at more than 20°
                let prims: Vec<Primitive> = b
                    .motions
                    .iter()
                    .filter_map(softnc_planner::build::motion_primitive)
                    .collect();
                let dir = |q: &Primitive| (q.end() - q.start()).unit();
                let (arc, len) = (prims[1], prims[1].length());
                assert!(dir(&prims[0]).dot(arc.tangent_at(0.0)) < 20f64.to_radians().cos());
                assert!(arc.tangent_at(len).dot(dir(&prims[2])) < 20f64.to_radians().cos());
                let plan = plan_of(&b, &p);
                let stopping = plan_of(&exact, &p);
                // the switch: off, the corners stop as under exact stop
                assert!(
                    (off.stats().duration_s - stopping.stats().duration_s).abs() < 0.01,
                    "{fp:?} {plane:?} {cw}: off {} s, exact stop {} s",
                    off.stats().duration_s,
                    stopping.stats().duration_s
                );
                let s = run(&plan);
                let what = format!("{fp:?} {plane:?} cw {cw}");
                let r = limit_ratios(&s, &p);
                assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{what}: {r:?}");
                if fp == FeedProfile::SCurve {
                    assert!(r[2] <= 1.0 + 1e-9, "{what}: jerk {r:?}");
                }
                assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9, "{what}");
                let dev = deviation_from_program(&s, &b);
                assert!(dev <= tol + 1e-6, "{what}: deviation {dev}");
                if fp == FeedProfile::Trapezoidal {
                    // blended: no stop at the corners, and faster than stopping there
                    let v = min_inner_speed(&s, p.interpolation_cycle_s);
                    assert!(v > 10.0, "{what}: slowest {v} mm/s");
                    assert!(
                        plan.stats().duration_s < stopping.stats().duration_s - 0.02,
                        "{what}: {} s vs {} s stopping",
                        plan.stats().duration_s,
                        stopping.stats().duration_s
                    );
                }
                for (k, m) in b.motions.iter().enumerate() {
                    assert_eq!(
                        plan.motion_primitive(k),
                        softnc_planner::build::motion_primitive(m),
                        "{what}: motion {k}"
                    );
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]
    /// Random chains of lines and planar arcs (any plane, both senses, short and long)
    /// under random tolerances: within every limit, within the tolerance of the program,
    /// ending exactly, every primitive given back.
    #[test]
    fn random_line_arc_chains_stay_within_limits_and_tolerance(
        ops in prop::collection::vec((0.05..20.0f64, 0.0..6.3f64, 0..3u8, any::<bool>(), 0.1..4.0f64, any::<bool>()), 1..10),
        tol in 0.001..0.5f64,
        scurve in any::<bool>(),
    ) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let p = arc_profile(fp);
        let mut b = Builder::new(Vec3::ZERO);
        b.mode = PathMode::Blend { tolerance_mm: Some(tol), naive_cam_mm: None };
        for (len, ang, pl, is_arc, sweep, ccw) in ops {
            let plane = [Plane::XY, Plane::XZ, Plane::YZ][pl as usize];
            let (a, bb, _) = plane.axes();
            let pos = b.pos;
            if is_arc {
                let mut c = pos;
                c[a] = pos[a] - len * ang.cos();
                c[bb] = pos[bb] - len * ang.sin();
                let th = ang + if ccw { sweep } else { -sweep };
                let mut e = c;
                e[a] = c[a] + len * th.cos();
                e[bb] = c[bb] + len * th.sin();
                b.arc(e, c, plane, if ccw { 1 } else { -1 }, 3000.0);
            } else {
                let mut e = pos;
                e[a] = pos[a] + len * ang.cos();
                e[bb] = pos[bb] + len * ang.sin();
                b.line(e[0], e[1], e[2], 6000.0);
            }
        }
        let plan = plan_of(&b, &p);
        let s = run(&plan);
        let r = limit_ratios(&s, &p);
        prop_assert!(r[0] <= 1.0 + 1e-9, "velocity {}", r[0]);
        prop_assert!(r[1] <= 1.0 + 1e-9, "acceleration {}", r[1]);
        if scurve {
            prop_assert!(r[2] <= 1.0 + 1e-9, "jerk {}", r[2]);
        }
        prop_assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9);
        let dev = deviation_from_program(&s, &b);
        prop_assert!(dev <= tol + 1e-6, "deviation {} > {}", dev, tol);
        for (k, m) in b.motions.iter().enumerate() {
            if !matches!(m.kind, MotionKind::Dwell { .. }) {
                prop_assert_eq!(plan.motion_primitive(k), softnc_planner::build::motion_primitive(m));
            }
        }
    }
}

/// Two arcs of one plane meeting at a corner (a sawtooth of arcs), both senses.
/// `wobble_mm`: the corner moved along the first axis, so that the first arc's end
/// radius differs from its start radius as CAM rounding makes it.
fn arc_arc(plane: Plane, first_ccw: bool, second_ccw: bool, tol: f64, wobble_mm: f64) -> Builder {
    let (a, bb, _) = plane.axes();
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = PathMode::Blend {
        tolerance_mm: Some(tol),
        naive_cam_mm: None,
    };
    let at = |x: f64, y: f64| {
        let mut v = Vec3::ZERO;
        v[a] = x;
        v[bb] = y;
        v
    };
    let turns = |ccw: bool| if ccw { 1 } else { -1 };
    // first arc: from the origin to (20, 0) about (10, ∓6); second: on to (40, 0)
    // about (30, ±6)
    let s1 = if first_ccw { -6.0 } else { 6.0 };
    b.arc(
        at(20.0 + wobble_mm, 0.0),
        at(10.0, s1),
        plane,
        turns(first_ccw),
        6000.0,
    );
    let s2 = if second_ccw { -6.0 } else { 6.0 };
    b.arc(
        at(40.0, 0.0),
        at(30.0, s2),
        plane,
        turns(second_ccw),
        6000.0,
    );
    b
}

#[test]
fn arc_arc_corners_of_one_plane_are_blended_within_limits_and_tolerance() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = arc_profile(fp);
        for plane in [Plane::XY, Plane::XZ, Plane::YZ] {
            let senses = [(true, true), (true, false), (false, true), (false, false)];
            for ((c1, c2), wobble) in senses.into_iter().flat_map(|c| [(c, 0.0), (c, 6e-5)]) {
                let tol = 0.05;
                let b = arc_arc(plane, c1, c2, tol, wobble);
                let plan = plan_of(&b, &p);
                let s = run(&plan);
                let what = format!("{fp:?} {plane:?} {c1} {c2} wobble {wobble}");
                let r = limit_ratios(&s, &p);
                assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{what}: {r:?}");
                if fp == FeedProfile::SCurve {
                    assert!(r[2] <= 1.0 + 1e-9, "{what}: jerk {r:?}");
                }
                assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9, "{what}");
                let dev = deviation_from_program(&s, &b);
                assert!(dev <= tol + 1e-6, "{what}: deviation {dev}");
                if fp == FeedProfile::Trapezoidal {
                    let v = min_inner_speed(&s, p.interpolation_cycle_s);
                    // no stop: without the blend the slowest is 0.4 mm/s
                    assert!(v > 5.0, "{what}: slowest {v} mm/s");
                }
                for (k, m) in b.motions.iter().enumerate() {
                    assert_eq!(
                        plan.motion_primitive(k),
                        softnc_planner::build::motion_primitive(m),
                        "{what}: motion {k}"
                    );
                }
            }
        }
    }
}

/// The proptest's arc radius (mm): a 0.1 rad arc 5 µm long.
const TINY_ARC_RADIUS_MM: f64 = 0.05;
/// A larger radius of the same family (mm). Before the fix a scan of the family
/// (radii 0.01–5 mm, sweeps 0.1–1 rad, kinks 1e-6–1e-3 rad, G64 P0.001–0.05) found
/// 710 of 6,144 joins failing under the S-curve, at 5 mm fillets ending up to 5e-3 mm
/// off the arc (jerk up to 104×, acceleration 1.7× the limits); none after.
const SHORT_ARC_RADIUS_MM: f64 = 5.0;

/// A point of `plane` from its in-plane coordinates.
fn in_plane(plane: Plane, x: f64, y: f64) -> Vec3 {
    let (a, bb, _) = plane.axes();
    let mut v = Vec3::ZERO;
    v[a] = x;
    v[bb] = y;
    v
}

/// A long line (`LONG_LINE_MM`) and a short arc of radius `radius_mm` and
/// `ARC_SWEEP_RAD` (5 µm long at 0.05 mm, the proptest's) joined `kink_rad` off
/// tangent, the kink turning against the arc (sense `s` = ±1), so that the arc turns
/// back onto the line's direction at once: the fillet there is nearly straight, of
/// radius ≈ 5e7 mm in the proptest's case. Line first (`line_first`) or
/// the arc first and the line after it, in `plane`, G64 P0.001.
fn line_and_tiny_arc(
    plane: Plane,
    s: f64,
    kink_rad: f64,
    radius_mm: f64,
    line_first: bool,
) -> Builder {
    /// The line (mm) and the direction it runs in (rad): the proptest's case.
    const LONG_LINE_MM: f64 = 16.18306963938766;
    const LINE_ANGLE_RAD: f64 = 4.452478054257627;
    const ARC_SWEEP_RAD: f64 = 0.1;
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = PathMode::Blend {
        tolerance_mm: Some(0.001),
        naive_cam_mm: None,
    };
    let turns = if s > 0.0 { 1 } else { -1 };
    let r = radius_mm;
    if line_first {
        let (cth, sth) = (LINE_ANGLE_RAD.cos(), LINE_ANGLE_RAD.sin());
        let (px, py) = (LONG_LINE_MM * cth, LONG_LINE_MM * sth);
        let p = in_plane(plane, px, py);
        b.line(p[0], p[1], p[2], 6000.0);
        // the arc's start tangent: the line's turned by −s·kink
        let tau = LINE_ANGLE_RAD - s * kink_rad;
        let (cx, cy) = (px - s * r * tau.sin(), py + s * r * tau.cos());
        let alpha = (py - cy).atan2(px - cx) + s * ARC_SWEEP_RAD;
        let end = in_plane(plane, cx + r * alpha.cos(), cy + r * alpha.sin());
        b.arc(end, in_plane(plane, cx, cy), plane, turns, 3000.0);
    } else {
        // the arc from the origin, its centre at radius angle LINE_ANGLE_RAD behind
        let (cx, cy) = (-r * LINE_ANGLE_RAD.cos(), -r * LINE_ANGLE_RAD.sin());
        let alpha = LINE_ANGLE_RAD + s * ARC_SWEEP_RAD;
        let (ex, ey) = (cx + r * alpha.cos(), cy + r * alpha.sin());
        b.arc(
            in_plane(plane, ex, ey),
            in_plane(plane, cx, cy),
            plane,
            turns,
            3000.0,
        );
        // the line leaves along the arc's end tangent turned by −s·kink
        let tau = alpha + s * std::f64::consts::FRAC_PI_2 - s * kink_rad;
        let e = in_plane(
            plane,
            ex + LONG_LINE_MM * tau.cos(),
            ey + LONG_LINE_MM * tau.sin(),
        );
        b.line(e[0], e[1], e[2], 6000.0);
    }
    b
}

/// The proptest's case (`arc_blends.proptest-regressions`) and its family: a long line
/// into a tiny arc (and a tiny arc into a long line) nearly tangent, the arc turning
/// back onto the line's direction, in every plane, both senses, both profiles. The
/// line–arc fillet there had a radius of 5e7 mm and, from its normal's rounding, ended
/// 1.65e-4 mm past the arc's touch point: a step in the path that the S-curve sampled
/// as 3.19× the jerk limit. Now a fillet must close on the arc
/// (`fillet::FILLET_CLOSURE_MM`): the path is continuous and within every limit.
#[test]
fn nearly_tangent_tiny_arcs_after_long_lines_keep_the_path_continuous_and_the_jerk_limit() {
    /// Largest gap between consecutive elements of the built path (mm).
    const MAX_GAP_MM: f64 = 1e-7;
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = arc_profile(fp);
        let lim = softnc_planner::build::Limits::from_profile(&p);
        for plane in [Plane::XY, Plane::XZ, Plane::YZ] {
            for s in [1.0, -1.0] {
                for (kink_rad, radius_mm) in [3.484644217537703e-5, 1e-5, 1e-4]
                    .into_iter()
                    .flat_map(|k| [(k, TINY_ARC_RADIUS_MM), (k, SHORT_ARC_RADIUS_MM)])
                {
                    for line_first in [true, false] {
                        let what = format!(
                            "{fp:?} {plane:?} s {s} kink {kink_rad} R {radius_mm} line first {line_first}"
                        );
                        let b = line_and_tiny_arc(plane, s, kink_rad, radius_mm, line_first);
                        let path = softnc_planner::build::build_path(&b.program(), &lim);
                        for k in 1..path.segs.len() {
                            let end = path.geoms[k - 1].point_at(path.segs[k - 1].len);
                            let gap = (path.geoms[k].point_at(0.0) - end).norm();
                            assert!(gap <= MAX_GAP_MM, "{what}: gap {gap} mm before element {k}");
                        }
                        let plan = plan_of(&b, &p);
                        let smp = run(&plan);
                        let r = limit_ratios(&smp, &p);
                        assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{what}: {r:?}");
                        if fp == FeedProfile::SCurve {
                            assert!(r[2] <= 1.0 + 1e-9, "{what}: jerk {r:?}");
                        }
                        assert!((smp.last().unwrap().pos_mm - b.pos).norm() < 1e-9, "{what}");
                        let dev = deviation_from_program(&smp, &b);
                        assert!(dev <= 0.001 + 1e-6, "{what}: deviation {dev}");
                    }
                }
            }
        }
    }
}
