//! G64 Q (LinuxCNC's "naive CAM" merging): noisy, nearly collinear G1 polylines run as
//! long lines, faster, within every axis limit, within P + Q of the programmed path,
//! and every programmed motion's primitive is still given back exactly.

use super::common;
use common::*;
use proptest::prelude::*;
use softnc_core::{FeedProfile, Primitive, Vec3};
use softnc_gcode::{MotionKind, PathMode};
use softnc_planner::{Plan, Sample};

/// Largest distance of any sample from the whole programmed path (every motion).
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

/// Every motion's programmed primitive, as the plan gives it back.
fn primitives_exact(plan: &Plan, b: &Builder) {
    for (k, m) in b.motions.iter().enumerate() {
        let want = softnc_planner::build::motion_primitive(m);
        let is_move = !matches!(m.kind, MotionKind::Dwell { .. });
        if is_move {
            assert_eq!(plan.motion_primitive(k), want, "motion {k}");
        }
    }
}

/// Two legs of 0.05 mm G1 segments that zig-zag ±`noise` mm across a square's sides.
fn noisy_square(mode: PathMode, noise: f64) -> Builder {
    let mut b = Builder::new(Vec3::ZERO);
    b.mode = mode;
    let f = 24000.0;
    let n = 1000;
    for k in 1..=n {
        let y = if k % 2 == 0 || k == n { noise } else { -noise };
        b.line(0.05 * k as f64, y, 0.0, f);
    }
    for k in 1..=n {
        let x = if k % 2 == 0 || k == n { noise } else { -noise };
        b.line(50.0 + x, 0.05 * k as f64, 0.0, f);
    }
    b
}

#[test]
fn q_merges_a_noisy_polyline_into_lines_faster_and_within_p_plus_q() {
    let p = profile(FeedProfile::Trapezoidal);
    let (tol, q) = (0.01, 0.01);
    let plain = noisy_square(
        PathMode::Blend {
            tolerance_mm: Some(tol),
            naive_cam_mm: None,
        },
        0.004,
    );
    let merged = noisy_square(
        PathMode::Blend {
            tolerance_mm: Some(tol),
            naive_cam_mm: Some(q),
        },
        0.004,
    );
    let (plan_plain, plan_merged) = (plan_of(&plain, &p), plan_of(&merged, &p));
    let (t_plain, t_merged) = (
        plan_plain.stats().duration_s,
        plan_merged.stats().duration_s,
    );
    // 2,000 segments of 0.05 mm with 0.16 rad corners crawl through their blends; Q
    // makes lines of 5 mm (100 motions per chain at most) in line within µm
    assert!(
        t_merged < 0.5 * t_plain,
        "merged {t_merged} s, plain {t_plain} s"
    );
    let s = run(&plan_merged);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "{r:?}");
    assert!((s.last().unwrap().pos_mm - merged.pos).norm() < 1e-9);
    let dev = deviation_from_program(&s, &merged);
    assert!(dev <= tol + q + 1e-6, "deviation {dev}");
    assert!(dev > 0.003, "the merged line should cut the zig-zag: {dev}");
    primitives_exact(&plan_merged, &merged);
}

#[test]
fn q_does_not_merge_beyond_its_tolerance_or_across_feeds() {
    let p = profile(FeedProfile::Trapezoidal);
    let mode = PathMode::Blend {
        tolerance_mm: Some(0.01),
        naive_cam_mm: Some(0.001),
    };
    // noise of 4 µm against Q = 1 µm: nothing merges, the same plan as without Q
    let with_q = noisy_square(mode, 0.004);
    let without_q = noisy_square(
        PathMode::Blend {
            tolerance_mm: Some(0.01),
            naive_cam_mm: None,
        },
        0.004,
    );
    let (a, b) = (plan_of(&with_q, &p), plan_of(&without_q, &p));
    assert_eq!(a.stats().duration_s, b.stats().duration_s);
    // collinear lines with different feeds stay apart: the slow one keeps its feed
    let mut c = Builder::new(Vec3::ZERO);
    c.mode = PathMode::Blend {
        tolerance_mm: Some(0.01),
        naive_cam_mm: Some(0.1),
    };
    c.line(10.0, 0.0, 0.0, 6000.0)
        .line(20.0, 0.0, 0.0, 600.0)
        .line(30.0, 0.0, 0.0, 6000.0);
    let plan = plan_of(&c, &p);
    assert!(
        plan.stats().duration_s > 10.0 / 10.0,
        "{}",
        plan.stats().duration_s
    );
    primitives_exact(&plan, &c);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]
    /// Random noisy polylines (with corners, feed changes and a dwell) under random
    /// P and Q: within every limit, within P + Q of the program, end exactly, every
    /// programmed primitive given back.
    #[test]
    fn random_noisy_polylines_stay_within_limits_and_p_plus_q(
        steps in prop::collection::vec((0.05..3.0f64, -0.05..0.05f64, 0.0..6.3f64, 0..8u8), 2..120),
        tol in 0.001..0.2f64,
        q in 0.001..0.1f64,
        scurve in any::<bool>(),
    ) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let p = profile(fp);
        let mut b = Builder::new(Vec3::ZERO);
        b.mode = PathMode::Blend { tolerance_mm: Some(tol), naive_cam_mm: Some(q) };
        let mut heading = 0.0f64;
        for (len, noise, turn, kind) in steps {
            if kind == 0 {
                heading = turn; // a real corner
            }
            let (x, y) = (b.pos[0] + len * heading.cos() - noise * heading.sin(),
                          b.pos[1] + len * heading.sin() + noise * heading.cos());
            match kind {
                1 => { b.line(x, y, b.pos[2], 900.0); }
                2 => { b.dwell(0.01); }
                3 => { b.rapid(x, y, b.pos[2] - 0.1); }
                _ => { b.line(x, y, b.pos[2], 6000.0); }
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
        prop_assert!(dev <= tol + q + 1e-6, "deviation {} > P {} + Q {}", dev, tol, q);
        primitives_exact(&plan, &b);
    }
}
