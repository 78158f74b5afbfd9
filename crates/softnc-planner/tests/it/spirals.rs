//! Arcs whose end radius differs from the start radius (spirals: CAM output rounds the
//! end point; LinuxCNC and softnc run them with the radius changing linearly along the
//! sweep, `Primitive::point_at`) stay within every axis's velocity and acceleration
//! limit on the samples, at 1.000× (issue 17), where the feed asks for more than the
//! axes give. Before `ElementShape::arc` took the spiral's own derivative, a spiral
//! ran at its circle's limits: `violation_checks/bug424_long.ngc` reached 1.000034× the
//! X velocity limit on the short arc of its line 6 (start radius 3.5990 mm, end
//! 3.5995 mm, 1.6° of sweep).

use super::common;
use common::*;
use proptest::prelude::*;
use softnc_core::{FeedProfile, MotionProfile, Plane, Vec3};

/// Largest ratio of any sample's per-axis velocity or acceleration (first and second
/// differences) to its limit that passes: f64 rounding of the samples, no margin.
const SLACK: f64 = 1e-9;

/// LinuxCNC's `axis_mm` limits (`../shared/planner/axis_mm.ron`, where bug424_long was
/// measured): 30.48 mm/s and 508 mm/s² on every axis.
fn axis_mm(fp: FeedProfile) -> MotionProfile {
    let mut p = profile(fp);
    for a in &mut p.axes {
        a.max_vel_mm_per_s = 30.48;
        a.max_acc_mm_per_s2 = 508.0;
    }
    p
}

/// Plans `b` on `p`, checks every sample's velocity and acceleration (and, S-curve,
/// jerk) on every axis and that the path ends exactly at the program's end.
fn check(b: &Builder, p: &MotionProfile, what: &str) {
    let plan = plan_of(b, p);
    let s = run(&plan);
    let r = limit_ratios(&s, p);
    assert!(
        r[0] <= 1.0 + SLACK && r[1] <= 1.0 + SLACK,
        "{what}: velocity {:.9}x, acceleration {:.9}x",
        r[0],
        r[1]
    );
    assert!((s.last().unwrap().pos_mm - b.pos).norm() < 1e-9, "{what}");
    if p.planner.feed_profile == FeedProfile::SCurve {
        assert!(r[2] <= 1.0 + SLACK, "{what}: jerk {:.9}x", r[2]);
    }
}

/// Lines 3–8 of `violation_checks/bug424_long.ngc`: three CAM arcs, each with an end
/// radius 0.5–0.8 µm off its start radius, at F120000 (far above the axes' 30.48 mm/s).
#[test]
fn bug424_spirals_stay_within_axis_limits() {
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let mut b = Builder::new(Vec3::ZERO);
        let f = 120_000.0;
        b.line(54.834, -52.151, 0.0, f);
        b.line(55.038, -59.286, 0.0, f);
        let xy = |x: f64, y: f64| Vec3::new(x, y, 0.0);
        let (x, y) = (55.038, -59.286);
        b.arc(
            xy(58.636, -62.782),
            xy(x + 3.598, y + 0.103),
            Plane::XY,
            1,
            f,
        );
        let (x, y) = (58.636, -62.782);
        b.arc(xy(58.739, -62.781), xy(x, y + 3.599), Plane::XY, 1, f);
        let (x, y) = (58.739, -62.781);
        b.arc(
            xy(62.104, -60.15),
            xy(x - 0.103, y + 3.598),
            Plane::XY,
            1,
            f,
        );
        check(&b, &axis_mm(fp), &format!("bug424 {fp:?}"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
    /// Random chains of spirals (any plane, both senses, sweeps from 0.3° to 1.5 turns,
    /// some rising along the normal, end radius up to 20 µm or 2 % off the start's,
    /// short and long radii) at feeds above what the axes give, joined at random
    /// angles or on the circle's tangent of the arc before, blended or stopped, both
    /// profiles: every sample within every axis's
    /// velocity and acceleration limit at 1.000×, and the path ends exactly.
    #[test]
    fn random_spirals_stay_within_axis_limits(
        ops in prop::collection::vec(
            (0.3..30.0f64, 0.0..6.3f64, 0..3u8, 0.005..9.5f64, any::<bool>(),
             -1.0..1.0f64, prop::sample::select(vec![0.0, 0.0, 0.5, -2.0]), any::<bool>()),
            1..6),
        wobble in prop::sample::select(vec![0.02, 0.002, 0.0005]),
        relative in any::<bool>(),
        feed in prop::sample::select(vec![2_000.0, 6_000.0, 120_000.0]),
        arc_blends in any::<bool>(),
        scurve in any::<bool>(),
    ) {
        let fp = if scurve { FeedProfile::SCurve } else { FeedProfile::Trapezoidal };
        let mut p = axis_mm(fp);
        p.planner.arc_blends = arc_blends;
        let mut b = Builder::new(Vec3::ZERO);
        // the plane, sense and end angle of the arc before
        let mut before: Option<(u8, bool, f64)> = None;
        for (radius, ang, pl, sweep, ccw, dr, travel, tangent) in ops {
            // on the circle's tangent of the arc before (so the true tangents break
            // by the spirals' radial drift), or at a random angle
            let (pl, ccw, ang) = match before {
                Some(prev) if tangent => prev,
                _ => (pl, ccw, ang),
            };
            let plane = [Plane::XY, Plane::XZ, Plane::YZ][pl as usize];
            let (a, bb, n) = plane.axes();
            let pos = b.pos;
            let mut c = pos;
            c[a] = pos[a] - radius * ang.cos();
            c[bb] = pos[bb] - radius * ang.sin();
            let th = ang + if ccw { sweep } else { -sweep };
            before = Some((pl, ccw, th));
            // the end radius: off by up to `wobble` mm, or that share of the radius
            let end_radius = radius + dr * if relative { wobble * radius } else { wobble };
            let mut e = c;
            e[a] = c[a] + end_radius * th.cos();
            e[bb] = c[bb] + end_radius * th.sin();
            e[n] = pos[n] + travel;
            let turns = 1 + (sweep / std::f64::consts::TAU) as i32;
            b.arc(e, c, plane, if ccw { turns } else { -turns }, feed);
        }
        check(&b, &p, &format!("{fp:?} arc_blends {arc_blends} feed {feed}"));
    }
}
