//! Corners (issue 36): no blend between a traverse and a feed move (the path stops
//! exactly at the join), and a blend no larger than the corner's speed needs, with
//! the tolerance (`G64 P`, else the profile's) a cap, never a target.

mod common;
use common::*;
use softnc_core::{FeedProfile, MotionProfile, Vec3};
use softnc_gcode::PathMode;

/// LinuxCNC's `axis_mm` limits (`../shared/planner/axis_mm.ron`): 30.48 mm/s and
/// 508 mm/s² on every axis, trapezoidal, the tolerance far above any corner (1000 mm,
/// as that profile imitates LinuxCNC's G64 without P).
fn axis_mm() -> MotionProfile {
    let mut p = profile(FeedProfile::Trapezoidal);
    for a in &mut p.axes {
        a.max_vel_mm_per_s = 30.48;
        a.max_acc_mm_per_s2 = 508.0;
    }
    p.planner.tolerance_mm = 1000.0;
    p.planner.max_feed_override = 1.0;
    p
}

/// Closest any sample comes to `corner` (mm), and the largest distance travelled in
/// the cycles just before and after the closest sample (mm).
fn pass_at(s: &[softnc_planner::Sample], corner: Vec3) -> (f64, f64) {
    let (k, d) = s
        .iter()
        .enumerate()
        .map(|(k, x)| (k, (x.pos_mm - corner).norm()))
        .fold((0, f64::INFINITY), |b, x| if x.1 < b.1 { x } else { b });
    let step = |i: usize, j: usize| (s[j].pos_mm - s[i].pos_mm).norm();
    let before = if k > 0 { step(k - 1, k) } else { 0.0 };
    let after = if k + 1 < s.len() { step(k, k + 1) } else { 0.0 };
    (d, before.max(after))
}

#[test]
fn traverse_feed_and_feed_traverse_corners_stop_exactly_at_the_corner() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let mut p = axis_mm();
        p.planner.feed_profile = fp;
        // a rapid down meets a cut at an angle, the cut meets a rapid up; and the
        // same nearly tangent (a 1° turn a kink would pass at speed)
        let mut b = Builder::new(Vec3::ZERO);
        b.rapid(20.0, 0.0, 0.0)
            .line(40.0, 20.0, 0.0, 1500.0)
            .rapid(40.0, 40.0, 0.0)
            .rapid(60.0, 40.0, 0.0)
            .line(80.0, 40.0 + 20.0 * 1f64.to_radians().tan(), 0.0, 1500.0);
        let plan = plan_of(&b, &p);
        let s = run(&plan);
        let r = limit_ratios(&s, &p);
        assert!(
            r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9,
            "{fp:?} limits {r:?}"
        );
        // the path acceleration of any element: at most the norm of the axes' limits
        let a_max = 508.0 * 3f64.sqrt();
        let t = p.interpolation_cycle_s;
        let lines = [
            (
                Vec3::ZERO,
                Vec3::new(20.0, 0.0, 0.0),
                Vec3::new(40.0, 20.0, 0.0),
            ),
            (
                Vec3::new(20.0, 0.0, 0.0),
                Vec3::new(40.0, 20.0, 0.0),
                Vec3::new(40.0, 40.0, 0.0),
            ),
            (
                Vec3::new(40.0, 40.0, 0.0),
                Vec3::new(60.0, 40.0, 0.0),
                b.pos,
            ),
        ];
        for (from, corner, to) in lines {
            let (d, step) = pass_at(&s, corner);
            // at rest at the corner: the stop falls inside a cycle, and a sample a
            // fraction of a cycle from a standstill is at most a·T²/2 from it
            assert!(
                d <= 0.5 * a_max * t * t,
                "{fp:?} {corner:?}: closest sample {d} mm away"
            );
            assert!(
                step <= a_max * t * t,
                "{fp:?} {corner:?}: {step} mm in the cycle next to the corner"
            );
            // and every sample near it lies on the programmed lines: no blend
            let on = |q: Vec3| {
                let seg = |a: Vec3, b: Vec3| {
                    distance(&softnc_core::Primitive::Line { start: a, end: b }, q)
                };
                seg(from, corner).min(seg(corner, to))
            };
            for x in s.iter().filter(|x| (x.pos_mm - corner).norm() < 2.0) {
                let off = on(x.pos_mm);
                assert!(
                    off <= 1e-9,
                    "{fp:?} {corner:?}: a sample {off} mm off the path"
                );
            }
        }
    }
}
