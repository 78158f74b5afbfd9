//! Corners (issue 36): no blend between a traverse and a feed move (the path stops
//! exactly at the join), and a blend no larger than the corner's speed needs, with
//! the tolerance (`G64 P`, else the profile's) a cap, never a target.

use super::common;
use common::*;
use softnc_core::{FeedProfile, MotionProfile, Vec3};

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

/// Plans G-code text on `p` and gives its samples.
fn samples_of(text: &str, p: &MotionProfile) -> Vec<softnc_planner::Sample> {
    let program = softnc_gcode::read_program(text, "c.ngc", p).expect("reads");
    let plan = softnc_planner::plan(
        &program,
        p,
        &softnc_planner::PlanOptions {
            ignore_soft_limits: true,
            ..Default::default()
        },
    )
    .expect("plans");
    run(&plan)
}

/// Closest sample to the corner of a 90° turn of two 50 mm lines in XY, the
/// slowest path speed within 1 mm of it and the largest distance of a sample from the
/// programmed lines (mm, mm/s, mm).
fn right_angle(text_mode: &str, feed_mm_per_min: f64, p: &MotionProfile) -> (f64, f64, f64) {
    let text = format!("G21 G90 {text_mode}\nG1 X50 Y0 F{feed_mm_per_min}\nG1 X50 Y50\nM2\n");
    let s = samples_of(&text, p);
    let corner = Vec3::new(50.0, 0.0, 0.0);
    let (d, _) = pass_at(&s, corner);
    let t = p.interpolation_cycle_s;
    let slowest = s
        .windows(2)
        .filter(|w| (w[0].pos_mm - corner).norm() < 1.0)
        .map(|w| (w[1].pos_mm - w[0].pos_mm).norm() / t)
        .fold(f64::INFINITY, f64::min);
    let off = s
        .iter()
        .map(|x| {
            let q = x.pos_mm;
            // from the X line (y = 0, x ≤ 50) or the Y line (x = 50, y ≥ 0)
            let from_x = q[1].abs() + (q[0] - 50.0).max(0.0);
            let from_y = (q[0] - 50.0).abs() + (-q[1]).max(0.0);
            from_x.min(from_y)
        })
        .fold(0.0, f64::max);
    (d, slowest, off)
}

/// `G64` without P takes the profile's `planner.tolerance_mm` (0.01 mm in
/// `default.ron`), as `G64 P0` does; `G64 P` replaces it.
#[test]
fn g64_without_p_takes_the_profiles_tolerance() {
    let p = profile(FeedProfile::Trapezoidal);
    assert_eq!(p.planner.tolerance_mm, 0.01);
    // the blend's midpoint lies δ from the corner and δ·cos 45° from the lines
    for mode in ["G64", "G64 P0"] {
        let (_, _, off) = right_angle(mode, 6000.0, &p);
        assert!(off <= 0.01 + 1e-9, "{mode}: {off} mm off the path");
        assert!(off >= 0.005, "{mode}: {off} mm off the path (not blended)");
    }
    let (_, _, off) = right_angle("G64 P0.5", 6000.0, &p);
    assert!(
        off > 0.01 && off <= 0.5 + 1e-9,
        "G64 P0.5: {off} mm off the path"
    );
}

/// A 90° corner between two X/Y lines under `G64` without P on `axis_mm` (tolerance
/// 1000 mm, so only the speed sizes the blend): the blend turns from X to Y, so it
/// runs at v = min(F, 30.48 mm/s) (neither axis beyond its limit) and needs the
/// radius r* = v²/(0.866·a) for its centripetal acceleration, a = 508 mm/s² less the
/// kinks' 1 % (502.92). Its midpoint lies r*·(√2 − 1) from the programmed corner:
/// F760 (12.67 mm/s) 0.1526 mm (LinuxCNC 0.37 mm on such a corner at 12.7 mm/s,
/// softnc 14.69 mm before), F6000 (30.48 mm/s) 0.8837 mm. The closest sample lies
/// within that bound plus what sampling adds (a sample up to h/2 = v·T/2 along the
/// arc from its midpoint is about 0.43·h²/r farther from the corner: 0.5·h²/r*
/// allowed), and the samples run through the corner at v.
#[test]
fn right_angle_blend_is_the_size_its_speed_needs() {
    let p = axis_mm();
    // (the planner's `KINK_SHARE`, 1 %, left to tangent breaks)
    let a = 508.0 * (1.0 - 0.01);
    for feed in [760.0, 6000.0] {
        let v = (feed / 60.0f64).min(30.48);
        let r_star = v * v / (0.866_025_403_784_438_6 * a);
        let bound = r_star * (2f64.sqrt() - 1.0);
        let (d, slowest, _) = right_angle("G64", feed, &p);
        let h = v * p.interpolation_cycle_s;
        let sampling = 0.5 * h * h / r_star;
        assert!(
            d <= bound + sampling,
            "F{feed}: {d} mm from the corner, bound {bound} + {sampling}"
        );
        // blended (not stopped), at the speed
        assert!(
            d >= 0.9 * bound,
            "F{feed}: {d} mm from the corner, bound {bound}"
        );
        assert!(
            slowest >= 0.99 * v,
            "F{feed}: {slowest} mm/s at the corner, v {v}"
        );
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    /// Random corners of two lines (any turn below a reversal, any lengths, in XY or
    /// in 3-D), random feeds and G64 P: the samples never come farther than P from the
    /// programmed path.
    #[test]
    fn g64_p_is_never_exceeded(
        turn_deg in 5.0f64..170.0,
        lift in -0.5f64..0.5,
        len1 in 0.5f64..60.0,
        len2 in 0.5f64..60.0,
        feed in 30.0f64..20000.0,
        tol in 0.001f64..3.0,
        scurve in proptest::bool::ANY,
    ) {
        let mut p = axis_mm();
        if scurve {
            p.planner.feed_profile = FeedProfile::SCurve;
        }
        let th = turn_deg.to_radians();
        let corner = Vec3::new(len1, 0.0, 0.0);
        let dir2 = Vec3::new(th.cos(), th.sin(), lift).unit();
        let end = corner + dir2 * len2;
        let text = format!(
            "G21 G90 G64 P{tol}\nG1 X{} Y0 Z0 F{feed}\nG1 X{} Y{} Z{}\nM2\n",
            corner[0], end[0], end[1], end[2]
        );
        let s = samples_of(&text, &p);
        let r = limit_ratios(&s, &p);
        proptest::prop_assert!(r[0] <= 1.0 + 1e-9 && r[1] <= 1.0 + 1e-9, "limits {:?}", r);
        // (the corner as the reader rounds it: the text's decimals)
        let program = softnc_gcode::read_program(&text, "c.ngc", &p).unwrap();
        let c = program.motions[0].kind.end().unwrap();
        let e = program.motions[1].kind.end().unwrap();
        let line = |a: Vec3, b: Vec3, q: Vec3| {
            distance(&softnc_core::Primitive::Line { start: a, end: b }, q)
        };
        for x in &s {
            let off = line(Vec3::ZERO, c, x.pos_mm).min(line(c, e, x.pos_mm));
            proptest::prop_assert!(off <= tol + 1e-9, "{} mm off the path, P {}", off, tol);
        }
    }
}
