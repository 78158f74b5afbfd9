//! The contour error: the actual position's distance to the programmed path near it.
//!
//! The command of a cycle lies on a motion of the program (a primitive: a line, an
//! arc or a helix); the axes, lagging or leading it, may be on the one before or
//! after — just past a corner the command is on the next line while the axes are
//! still finishing the blend of the last. The contour error is therefore the
//! distance from the actual position to the nearest point of the *bounded*
//! primitives near the command: the command's own, the one on either side, and
//! further ones as long as the path between them and the command's primitive is
//! shorter than the distance between the command and the actual position (the
//! axes cannot be further along the path than that). Its sign is the nearest
//! primitive's side ([`Primitive::contour_error`]: left of a line seen from +Z,
//! outside an arc).
//!
//! One implementation for the position process and the simulator
//! (`softnc_sim::simulate`), so that a lockstep daemon's trace and `softnc sim`'s
//! agree bit for bit. Allocation-free, a bounded amount of work per cycle
//! ([`MAX_NEIGHBOURS`] primitives each way at most).

use softnc_core::{Primitive, Vec3};
use std::f64::consts::TAU;

/// The most primitives looked at on either side of the command's (a program of
/// very short segments would otherwise have the cycle walk far back along a long
/// lag).
pub const MAX_NEIGHBOURS: u32 = 32;

/// The contour error of `actual_mm` when the command `cmd_mm` is on motion
/// `motion` of the program whose motion `m` is `path(m)` (`None`: no path there —
/// a dwell, or past the program's end). `None` when the command's motion has no
/// path. Signed as described in the module's documentation (mm).
#[inline]
pub fn contour_error_near<P>(path: P, motion: u32, cmd_mm: Vec3, actual_mm: Vec3) -> Option<f64>
where
    P: Fn(u32) -> Option<Primitive>,
{
    let own = path(motion)?;
    let lag_mm = (actual_mm - cmd_mm).norm();
    let mut best = (distance_to(&own, actual_mm), own);
    let mut consider = |p: Primitive| {
        let d = distance_to(&p, actual_mm);
        if d < best.0 {
            best = (d, p);
        }
    };
    // back along the path: the neighbour always, then while the path between is
    // shorter than the lag (a dwell, no path, stands the axes: nothing beyond it)
    let mut between_mm = 0.0;
    for k in 1..=MAX_NEIGHBOURS.min(motion) {
        let Some(p) = path(motion - k) else { break };
        if k > 1 && between_mm > lag_mm {
            break;
        }
        consider(p);
        between_mm += p.length();
    }
    // on along it likewise (the axes may lead the command a little)
    let mut between_mm = 0.0;
    for k in 1..=MAX_NEIGHBOURS {
        let Some(m) = motion.checked_add(k) else {
            break;
        };
        let Some(p) = path(m) else { break };
        if k > 1 && between_mm > lag_mm {
            break;
        }
        consider(p);
        between_mm += p.length();
    }
    let (d, nearest) = best;
    Some(if nearest.contour_error(actual_mm) < 0.0 {
        -d
    } else {
        d
    })
}

/// The distance (mm, ≥ 0) from `x` to the nearest point of primitive `p`, between
/// its ends.
pub fn distance_to(p: &Primitive, x: Vec3) -> f64 {
    match *p {
        Primitive::Line { start, end } => {
            let d = end - start;
            let len2 = d.dot(d);
            let u = if len2 > 0.0 {
                ((x - start).dot(d) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (x - (start + d * u)).norm()
        }
        Primitive::Arc {
            start,
            center,
            plane,
            radius,
            start_angle,
            sweep,
            normal_travel,
            end,
        } => {
            let ends = (x - start).norm().min((x - end).norm());
            if sweep == 0.0 {
                return ends;
            }
            let (a, b, n) = plane.axes();
            let end_radius = plane.radius_at(center, end);
            let rho = (x[a] - center[a]).hypot(x[b] - center[b]);
            let theta = (x[b] - center[b]).atan2(x[a] - center[a]);
            // the angle travelled from the start to x's angle, in the sweep's
            // direction, then each turn of a helix that reaches it
            let dir = sweep.signum();
            let mut along = ((theta - start_angle) * dir).rem_euclid(TAU);
            let mut nearest = ends;
            while along <= sweep.abs() {
                let u = along / sweep.abs();
                let r = radius + (end_radius - radius) * u;
                let h = x[n] - (start[n] + normal_travel * u);
                nearest = nearest.min((rho - r).hypot(h));
                along += TAU;
            }
            nearest
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_core::Plane;

    fn line(a: [f64; 2], b: [f64; 2]) -> Primitive {
        Primitive::Line {
            start: Vec3::new(a[0], a[1], 0.0),
            end: Vec3::new(b[0], b[1], 0.0),
        }
    }

    #[test]
    fn a_line_is_bounded_by_its_ends() {
        let l = line([0.0, 0.0], [10.0, 0.0]);
        assert!((distance_to(&l, Vec3::new(5.0, 0.3, 0.0)) - 0.3).abs() < 1e-12);
        // past the end: the distance to the end, not to the infinite line
        assert!((distance_to(&l, Vec3::new(13.0, 4.0, 0.0)) - 5.0).abs() < 1e-12);
        assert!((distance_to(&l, Vec3::new(-3.0, 0.0, 0.0)) - 3.0).abs() < 1e-12);
    }

    #[test]
    fn an_arc_is_bounded_by_its_sweep_and_a_helix_by_its_turns() {
        // a quarter circle of radius 10 about the origin, from (10, 0) to (0, 10), G3
        let q = Primitive::arc(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
            Vec3::ZERO,
            Plane::XY,
            1,
        );
        let at = |deg: f64, r: f64| {
            let t = deg.to_radians();
            Vec3::new(r * t.cos(), r * t.sin(), 0.0)
        };
        assert!((distance_to(&q, at(45.0, 10.2)) - 0.2).abs() < 1e-12);
        assert!((distance_to(&q, at(45.0, 9.9)) - 0.1).abs() < 1e-12);
        // outside the sweep: the nearer end
        let p = at(180.0, 10.0);
        assert!((distance_to(&q, p) - (p - Vec3::new(0.0, 10.0, 0.0)).norm()).abs() < 1e-12);
        // the circle's own measure ignores the sweep
        assert!(q.contour_error(p).abs() < 1e-12);
        // a helix of two turns rising 4 mm: a point on its second turn
        let h = Primitive::arc(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(10.0, 0.0, 4.0),
            Vec3::ZERO,
            Plane::XY,
            2,
        );
        let on_second = Vec3::new(0.0, 10.0, 2.5 + 0.01);
        assert!((distance_to(&h, on_second) - 0.01).abs() < 1e-9);
    }

    #[test]
    fn past_a_corner_the_lagging_axes_are_measured_against_the_line_they_are_on() {
        // a corner at (10, 0): along X, then along Y
        let path = [
            Some(line([0.0, 0.0], [10.0, 0.0])),
            Some(line([10.0, 0.0], [10.0, 10.0])),
        ];
        let get = |m: u32| path.get(m as usize).copied().flatten();
        // the command just past the corner, the axes 0.5 mm behind on the first
        let cmd = Vec3::new(10.0, 0.2, 0.0);
        let actual = Vec3::new(9.7, 0.001, 0.0);
        // against the command's line alone: 0.3 mm; against the path: 1 µm
        assert!((path[1].unwrap().contour_error(actual).abs() - 0.3).abs() < 1e-12);
        let e = contour_error_near(get, 1, cmd, actual).unwrap();
        assert!((e - 0.001).abs() < 1e-12, "{e}");
        // right of the first line's direction: negative
        let e = contour_error_near(get, 1, cmd, Vec3::new(9.7, -0.002, 0.0)).unwrap();
        assert!((e + 0.002).abs() < 1e-12, "{e}");
        // no path at the command's motion: none
        assert_eq!(contour_error_near(get, 5, cmd, actual), None);
    }

    #[test]
    fn neighbours_beyond_the_lag_or_a_dwell_are_not_looked_at() {
        // a long way back the path passes close to the actual position again, but
        // the axes cannot be there: the lag is 0.1 mm
        let path = [
            Some(line([0.0, 0.05], [20.0, 0.05])),
            None, // a dwell
            Some(line([20.0, 0.05], [20.0, 5.0])),
            Some(line([20.0, 5.0], [0.0, 5.0])),
            Some(line([0.0, 5.0], [0.0, 0.0])),
            Some(line([0.0, 0.0], [10.0, 0.0])),
        ];
        let get = |m: u32| path.get(m as usize).copied().flatten();
        let cmd = Vec3::new(5.1, 0.0, 0.0);
        let actual = Vec3::new(5.0, 0.0, 0.0);
        let e = contour_error_near(get, 5, cmd, actual).unwrap();
        assert_eq!(e, 0.0);
        let actual = Vec3::new(5.0, 0.04, 0.0);
        let e = contour_error_near(get, 5, cmd, actual).unwrap();
        assert!(
            (e - 0.04).abs() < 1e-12,
            "the first line, 10 µm away, is not near: {e}"
        );
        // after the dwell the path before it is not looked at
        let e = contour_error_near(
            get,
            2,
            Vec3::new(20.0, 0.1, 0.0),
            Vec3::new(19.0, 0.05, 0.0),
        )
        .unwrap();
        assert!((e.abs() - 1.0).abs() < 1e-12, "{e}");
    }
}
