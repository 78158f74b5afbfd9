//! Small tangent breaks between arcs (CAM arcs that do not quite meet tangentially):
//! passed at the room the elements on either side leave on each axis, not only at
//! the kink share, and still within every limit on the samples (second differences
//! and velocity changes over 5-cycle windows).

use super::common;
use common::*;
use softnc_core::{FeedProfile, Plane, Vec3};

/// Arcs of radius `r_mm` between points `chord_deg` apart on a circle of radius
/// `big_mm` about the origin: each meets the next with a tangent break of
/// 2·(asin(c/2r) − asin(c/2R)).
fn kinked_arcs(big_mm: f64, r_mm: f64, chord_deg: f64, n: usize, feed_mm_per_min: f64) -> Builder {
    let at = |k: usize| {
        let th = (k as f64 * chord_deg).to_radians();
        Vec3::new(big_mm * th.cos(), big_mm * th.sin(), 0.0)
    };
    let mut b = Builder::new(at(0));
    for k in 0..n {
        let (p, q) = (at(k), at(k + 1));
        // centre of the radius-r arc through p and q on the origin's side (CCW)
        let mid = (p + q) * 0.5;
        let half = (q - p).norm() * 0.5;
        let towards_origin = (-mid).unit();
        let center = mid + towards_origin * (r_mm * r_mm - half * half).sqrt();
        b.arc(q, center, Plane::XY, 1, feed_mm_per_min);
    }
    b
}

/// Largest velocity change over `n` cycles per axis, as a ratio of the limit.
fn window_acc_ratio(s: &[softnc_planner::Sample], n: usize, p: &softnc_core::MotionProfile) -> f64 {
    let t = p.interpolation_cycle_s;
    let am = p.max_acc();
    let mut r = 0.0f64;
    for w in s.windows(n + 2) {
        for (i, a_lim) in am.iter().enumerate() {
            let v0 = (w[1].pos_mm[i] - w[0].pos_mm[i]) / t;
            let v1 = (w[n + 1].pos_mm[i] - w[n].pos_mm[i]) / t;
            r = r.max((v1 - v0).abs() / (n as f64 * t) / a_lim);
        }
    }
    r
}

fn path_speeds(s: &[softnc_planner::Sample], cycle_s: f64) -> Vec<f64> {
    s.windows(2)
        .map(|w| (w[1].pos_mm - w[0].pos_mm).norm() / cycle_s)
        .collect()
}

#[test]
fn small_breaks_between_arcs_pass_at_the_feed_within_limits() {
    let p = profile(FeedProfile::Trapezoidal);
    // chord 10° on R 40 (6.97 mm), arcs of R 38: breaks of 0.52° (0.0091 rad); the
    // kink share alone (1 % of 3,000 mm/s² over 1 ms) allows 3.3 mm/s there
    let feed = 3000.0;
    let b = kinked_arcs(40.0, 38.0, 10.0, 30, feed);
    let plan = plan_of(&b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let w5 = window_acc_ratio(&s, 5, &p);
    assert!(w5 <= 1.0 + 1e-9, "acceleration over 5 cycles {w5:.4}x");
    assert_eq!(s.last().unwrap().pos_mm, b.pos);
    // between the first arc's end and the last arc's start the path keeps the feed
    let v = path_speeds(&s, p.interpolation_cycle_s);
    let (ramp, n) = (v.len() / 10, v.len());
    let slowest = v[ramp..n - ramp]
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    assert!(
        slowest >= 0.95 * feed / 60.0,
        "slowest {slowest:.2} mm/s in the middle (feed {:.1})",
        feed / 60.0
    );
}

/// CAM arcs of R 13–20 mm that meet with tangent breaks of about 1.6°
/// (`violation_checks/sam_vel_violation.ngc`, LinuxCNC's `axis_mm` limits: 30.48
/// mm/s, 508 mm/s² and no tolerance to speak of), at a feed above the axes' limit.
/// Each break is blended by a biarc within the deviation its speed needs (about
/// 0.1 µm): held within that of the corner point the biarc's trim, and so its
/// radius (6–35 µm), was a hundred times smaller than the path allows, and the
/// arcs slowed to 2–4 mm/s at every break (`fillet::biarc`).
#[test]
fn arcs_meeting_with_small_breaks_pass_at_speed_through_biarcs_within_tolerance() {
    let mut p = profile(FeedProfile::Trapezoidal);
    for a in p.axes.iter_mut() {
        a.max_vel_mm_per_s = 30.48;
        a.max_acc_mm_per_s2 = 508.0;
    }
    p.planner.tolerance_mm = 1000.0;
    let text = "G21 G90 G64 F100000\nG0 X-2.438 Y-12.611\nG1 X-2.4 Y-12.7\n\
                G2 X-5.097 Y-10.626 I45.476 J63.701\nX-6.825 Y-9.014 I12.543 J15.17\n\
                X-7.945 Y-7.654 I11.703 J10.782\nG1 X-9 Y-6\nM2\n";
    let program = softnc_gcode::read_program(text, "kinks.ngc", &p).unwrap();
    let plan = softnc_planner::plan(&program, &p, &Default::default()).unwrap();
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let w5 = window_acc_ratio(&s, 5, &p);
    assert!(w5 <= 1.0 + 1e-9, "acceleration over 5 cycles {w5:.4}x");
    // the slowest sample near each break between the arcs (not the corners at the
    // lines, which turn 20° and 60°)
    let v = path_speeds(&s, p.interpolation_cycle_s);
    for brk in [[-5.097, -10.626], [-6.825, -9.014]] {
        let (k, _) = s
            .iter()
            .enumerate()
            .map(|(k, x)| (k, (x.pos_mm[0] - brk[0]).hypot(x.pos_mm[1] - brk[1])))
            .fold((0, f64::INFINITY), |b, c| if c.1 < b.1 { c } else { b });
        let slowest = v[k.saturating_sub(20)..(k + 20).min(v.len())]
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        assert!(slowest >= 20.0, "{slowest:.2} mm/s at the break at {brk:?}");
        // and the samples there within a few micrometres of the path (1.3 µm at
        // the first break before, with the tight biarc; 2.1 µm now; the arc
        // before it ends 47 µm off its start radius, CAM rounding)
        let near = &s[k.saturating_sub(20)..(k + 20).min(s.len())];
        let dev = max_path_deviation(near, &plan, program.motions.len());
        assert!(
            dev <= 5e-3,
            "{dev} mm from the path at the break at {brk:?}"
        );
    }
}

#[test]
fn breaks_closer_than_a_cycle_keep_the_kink_share() {
    let p = profile(FeedProfile::Trapezoidal);
    // a polygon of nearly straight arcs (R 100) with corners 1° apart on a circle of
    // R 2 mm (chords of 0.035 mm): breaks of about 0.017 rad all turning the same
    // way. Each alone could take about 80 mm/s in the room the arcs leave, but then
    // two or three would fall within a cycle and add up (a circle of R 2 mm at
    // 80 mm/s needs 3,200 mm/s²); kept a cycle's travel apart they stay within it
    let b = kinked_arcs(2.0, 100.0, 1.0, 700, 6000.0);
    let plan = plan_of(&b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let w5 = window_acc_ratio(&s, 5, &p);
    assert!(w5 <= 1.0 + 1e-9, "acceleration over 5 cycles {w5:.4}x");
    assert_eq!(s.last().unwrap().pos_mm, b.pos);
}

#[test]
fn breaks_between_lines_and_arcs_at_full_tangential_acceleration_stay_within_limits() {
    // lines at their full tangential acceleration leave little room on their main
    // axis: the break there takes what is left, never more
    let p = profile(FeedProfile::Trapezoidal);
    let mut b = Builder::new(Vec3::ZERO);
    let f = 20_000.0;
    b.line(30.0, 0.0, 0.0, f);
    // an arc leaving 0.3° off the line's direction, then a line off its end tangent
    let th = 0.3f64.to_radians();
    let center = Vec3::new(30.0 - 50.0 * th.sin(), 50.0 * th.cos(), 0.0);
    b.arc(Vec3::new(40.0, 1.2, 0.0), center, Plane::XY, 1, f)
        .line(60.0, 4.0, 0.0, f)
        .line(80.0, 4.5, 0.0, f)
        .line(80.0, 4.5, 0.0, f);
    let plan = plan_of(&b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let w5 = window_acc_ratio(&s, 5, &p);
    assert!(w5 <= 1.0 + 1e-9, "acceleration over 5 cycles {w5:.4}x");
}

/// A 90° corner between two diagonal traverses with no tolerance to speak of: the
/// lines run at √2 of the axes' limit, any blend through the corner at the limit (it
/// passes an axis direction), so the blend is the smallest that keeps that speed,
/// r* = V²/(0.866·A) (62 mm here), not the largest the lines allow (141 mm).
#[test]
fn a_blend_slower_than_its_lines_is_only_as_large_as_its_speed_needs() {
    let mut p = profile(FeedProfile::Trapezoidal);
    p.planner.tolerance_mm = 1000.0;
    let mut b = Builder::new(Vec3::ZERO);
    b.rapid(200.0, 200.0, 0.0).rapid(400.0, 0.0, 0.0);
    let plan = plan_of(&b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let corner = Vec3::new(200.0, 200.0, 0.0);
    let closest = s
        .iter()
        .map(|x| (x.pos_mm - corner).norm())
        .fold(f64::INFINITY, f64::min);
    // a blend of radius r passes r·(√2 − 1) from the corner: 25.7 mm for r*,
    // 58.6 mm for the largest
    let a = p.max_acc()[0] * (1.0 - softnc_planner::build::KINK_SHARE);
    let r_star = p.max_vel()[0].powi(2) / (softnc_planner::path::ARC_NORMAL_SHARE * a);
    let want = r_star * (2f64.sqrt() - 1.0);
    assert!(
        (closest - want).abs() < 0.5,
        "passes {closest:.2} mm from the corner, r* gives {want:.2} mm"
    );
    let v = path_speeds(&s, p.interpolation_cycle_s);
    let top = v.iter().cloned().fold(0.0, f64::max);
    assert!(
        top > 1.4 * p.max_vel()[0],
        "the diagonals run at √2·V: {top:.1}"
    );
}

/// A slow feed move (10 mm/s) turning 90° into a fast one (at the axes' limit; a
/// traverse there is an exact stop since issue 36), no tolerance to speak of: the
/// blend runs at the first move's feed, so every millimetre of the fast move it takes
/// is run slowly; the blend is the smallest that keeps the feed, r* = F²/(0.866·A),
/// not the largest the lines allow (50 mm, passing 20.7 mm from the corner).
#[test]
fn a_slow_feed_move_blends_into_a_fast_one_with_the_smallest_blend_that_keeps_its_feed() {
    let mut p = profile(FeedProfile::Trapezoidal);
    p.planner.tolerance_mm = 1000.0;
    let feed_mm_per_s = 10.0;
    let mut b = Builder::new(Vec3::ZERO);
    b.line(100.0, 0.0, 0.0, feed_mm_per_s * 60.0)
        .line(100.0, 100.0, 0.0, 400.0 * 60.0);
    let plan = plan_of(&b, &p);
    let s = run(&plan);
    let r = limit_ratios(&s, &p);
    assert!(r[0] <= 1.0 + 1e-9, "velocity {:.4}x", r[0]);
    assert!(r[1] <= 1.0 + 1e-9, "acceleration {:.4}x", r[1]);
    let corner = Vec3::new(100.0, 0.0, 0.0);
    let closest = s
        .iter()
        .map(|x| (x.pos_mm - corner).norm())
        .fold(f64::INFINITY, f64::min);
    let a = p.max_acc()[0] * (1.0 - softnc_planner::build::KINK_SHARE);
    let r_star = feed_mm_per_s.powi(2) / (softnc_planner::path::ARC_NORMAL_SHARE * a);
    let want = r_star * (2f64.sqrt() - 1.0);
    // a sample lands within a cycle's travel of the blend's middle
    let cycle_travel = feed_mm_per_s * p.interpolation_cycle_s;
    assert!(
        (closest - want).abs() <= cycle_travel,
        "passes {closest:.4} mm from the corner, r* gives {want:.4} mm"
    );
    // and the fast move after it reaches the axis's limit
    let v = path_speeds(&s, p.interpolation_cycle_s);
    let top = v.iter().cloned().fold(0.0, f64::max);
    assert!(top > 0.99 * p.max_vel()[1], "fast move at {top:.1} mm/s");
}
