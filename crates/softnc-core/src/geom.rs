//! Geometry in millimetres: [`Vec3`] and the path [`Primitive`]s (lines, arcs, helices).
//!
//! Arcs follow RS274/NGC: an arc lies in a [`Plane`]; its sweep is measured about the
//! plane's normal with the right-handed in-plane axes of [`Plane::axes`] (XY → (x, y),
//! XZ → (z, x), YZ → (y, z)), so G3 (counter-clockwise) sweeps are positive and G2
//! sweeps negative. A helix adds a linear motion along the normal.

use std::ops::{Add, AddAssign, Index, IndexMut, Mul, Neg, Sub};

/// A 3-vector (x, y, z), millimetres unless a name says otherwise.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Vec3(pub [f64; 3]);

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3([0.0; 3]);
    /// A vector from components.
    #[inline]
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3([x, y, z])
    }
    /// Dot product.
    #[inline]
    pub fn dot(self, o: Vec3) -> f64 {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }
    /// Cross product.
    #[inline]
    pub fn cross(self, o: Vec3) -> Vec3 {
        let [a, b, c] = self.0;
        let [d, e, f] = o.0;
        Vec3([b * f - c * e, c * d - a * f, a * e - b * d])
    }
    /// Euclidean length.
    #[inline]
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }
    /// This vector scaled to unit length (zero stays zero).
    #[inline]
    pub fn unit(self) -> Vec3 {
        let n = self.norm();
        if n > 0.0 {
            self * (1.0 / n)
        } else {
            Vec3::ZERO
        }
    }
    /// Component-wise absolute value.
    #[inline]
    pub fn abs(self) -> Vec3 {
        Vec3(self.0.map(f64::abs))
    }
    /// Largest component.
    #[inline]
    pub fn max_elem(self) -> f64 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }
    /// Component-wise minimum.
    #[inline]
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3([
            self.0[0].min(o.0[0]),
            self.0[1].min(o.0[1]),
            self.0[2].min(o.0[2]),
        ])
    }
    /// Component-wise maximum.
    #[inline]
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3([
            self.0[0].max(o.0[0]),
            self.0[1].max(o.0[1]),
            self.0[2].max(o.0[2]),
        ])
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}
impl AddAssign for Vec3 {
    #[inline]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}
impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}
impl Mul<f64> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, k: f64) -> Vec3 {
        Vec3(self.0.map(|v| v * k))
    }
}
impl Neg for Vec3 {
    type Output = Vec3;
    #[inline]
    fn neg(self) -> Vec3 {
        self * -1.0
    }
}
impl Index<usize> for Vec3 {
    type Output = f64;
    #[inline]
    fn index(&self, i: usize) -> &f64 {
        &self.0[i]
    }
}
impl IndexMut<usize> for Vec3 {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        &mut self.0[i]
    }
}

/// The arc plane (G17, G18, G19).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Plane {
    /// G17.
    #[default]
    XY,
    /// G18.
    XZ,
    /// G19.
    YZ,
}

impl Plane {
    /// Axis indices (first in-plane, second in-plane, normal), right-handed.
    pub const fn axes(self) -> (usize, usize, usize) {
        match self {
            Plane::XY => (0, 1, 2),
            Plane::XZ => (2, 0, 1),
            Plane::YZ => (1, 2, 0),
        }
    }
    /// Distance of `p` from `center` within the plane (mm): an arc's radius at `p`
    /// (its end radius may differ a little from its start's: the path is then a
    /// spiral, the radius changing linearly with the angle).
    #[inline]
    pub fn radius_at(self, center: Vec3, p: Vec3) -> f64 {
        let (a, b, _) = self.axes();
        (p[a] - center[a]).hypot(p[b] - center[b])
    }
    /// Lower-case name as in canonical output: "xy", "xz", "yz".
    pub const fn name(self) -> &'static str {
        match self {
            Plane::XY => "xy",
            Plane::XZ => "xz",
            Plane::YZ => "yz",
        }
    }
}

/// `x.rem_euclid(τ)`, without the division when |x| < 2τ (the same result: the
/// remainder of a smaller number is the number itself, and for τ ≤ |x| < 2τ it is
/// x ∓ τ, which floating point gives exactly by Sterbenz's lemma).
pub fn rem_tau(x: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let ax = x.abs();
    let r = if ax < tau {
        x
    } else if ax == tau {
        0.0f64.copysign(x) // what `%` gives: a zero of x's sign
    } else if ax < 2.0 * tau {
        if x > 0.0 {
            x - tau
        } else {
            x + tau
        }
    } else {
        x % tau
    };
    if r < 0.0 {
        r + tau
    } else {
        r
    }
}

/// One geometric piece of a path, parameterised by arc length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// A straight line.
    Line {
        /// Start point.
        start: Vec3,
        /// End point.
        end: Vec3,
    },
    /// A circular arc or helix.
    Arc {
        /// Start point.
        start: Vec3,
        /// Centre; its component along the plane normal equals the start's.
        center: Vec3,
        /// Plane of the arc.
        plane: Plane,
        /// In-plane radius (mm).
        radius: f64,
        /// In-plane angle of the start point about the centre (rad).
        start_angle: f64,
        /// Signed sweep about the plane normal (rad); G3 > 0, G2 < 0.
        sweep: f64,
        /// Travel along the plane normal from start to end (mm; helix).
        normal_travel: f64,
        /// Programmed end point. When its radius differs slightly from the start's
        /// (within the interpreter's tolerance) the radius changes linearly along the
        /// sweep, as LinuxCNC does, so the arc ends exactly here.
        end: Vec3,
    },
}

impl Primitive {
    /// An arc from `start` to `end` about `center` (normal component ignored), with
    /// `turns` as in LinuxCNC (signed, G3 > 0, |turns| = 1 for up to one revolution).
    /// The end radius may differ from the start radius; the arc takes the start radius
    /// (the interpreter has already checked the mismatch against its tolerance).
    ///
    /// One copy of the arithmetic per plane ([`Primitive::arc_in`]): with the axes
    /// constants the points stay in registers, where indexing them by a variable
    /// axis put them on the stack (the same operations in the same order, so the
    /// same bits; test `arc_per_plane_is_the_variable_axes_arc`).
    #[inline]
    pub fn arc(start: Vec3, end: Vec3, center: Vec3, plane: Plane, turns: i32) -> Primitive {
        match plane {
            Plane::XY => Self::arc_in::<0, 1, 2>(start, end, center, plane, turns),
            Plane::XZ => Self::arc_in::<2, 0, 1>(start, end, center, plane, turns),
            Plane::YZ => Self::arc_in::<1, 2, 0>(start, end, center, plane, turns),
        }
    }

    /// [`Primitive::arc`] in the plane whose axes ([`Plane::axes`]) are `A`, `B`
    /// (in the plane) and `N` (its normal).
    fn arc_in<const A: usize, const B: usize, const N: usize>(
        start: Vec3,
        end: Vec3,
        center: Vec3,
        plane: Plane,
        turns: i32,
    ) -> Primitive {
        debug_assert_eq!(plane.axes(), (A, B, N));
        let (a, b, n) = (A, B, N);
        let mut c = center;
        c[n] = start[n];
        let (sa, sb) = (start[a] - c[a], start[b] - c[b]);
        let radius = sa.hypot(sb);
        let start_angle = sb.atan2(sa);
        let end_angle = (end[b] - c[b]).atan2(end[a] - c[a]);
        let tau = std::f64::consts::TAU;
        let extra = (turns.unsigned_abs().max(1) - 1) as f64 * tau;
        let sweep = if turns >= 0 {
            let mut d = rem_tau(end_angle - start_angle);
            if d <= 1e-12 {
                d = tau;
            }
            d + extra
        } else {
            let mut d = rem_tau(start_angle - end_angle);
            if d <= 1e-12 {
                d = tau;
            }
            -(d + extra)
        };
        Primitive::Arc {
            start,
            center: c,
            plane,
            radius,
            start_angle,
            sweep,
            normal_travel: end[n] - start[n],
            end,
        }
    }

    /// Start point.
    #[inline]
    pub fn start(&self) -> Vec3 {
        match *self {
            Primitive::Line { start, .. } | Primitive::Arc { start, .. } => start,
        }
    }

    /// End point.
    #[inline]
    pub fn end(&self) -> Vec3 {
        match *self {
            Primitive::Line { end, .. } | Primitive::Arc { end, .. } => end,
        }
    }

    /// Arc length (mm).
    #[inline]
    pub fn length(&self) -> f64 {
        match *self {
            Primitive::Line { start, end } => (end - start).norm(),
            Primitive::Arc {
                radius,
                sweep,
                normal_travel,
                ..
            } => Self::arc_length(radius * sweep, normal_travel),
        }
    }

    /// An arc's length from its radius times its sweep `rs` and its travel along the
    /// plane's normal (`Primitive::length` of an arc; inline where a caller has the
    /// two at hand).
    #[inline]
    pub fn arc_length(rs: f64, normal_travel: f64) -> f64 {
        if normal_travel == 0.0 {
            rs.abs() // what hypot gives, without its cost
        } else {
            rs.hypot(normal_travel)
        }
    }

    /// Point at arc length `s` from the start (clamped to [0, length]).
    pub fn point_at(&self, s: f64) -> Vec3 {
        let len = self.length();
        let u = if len > 0.0 {
            (s / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        match *self {
            Primitive::Line { start, end } => {
                if u >= 1.0 {
                    end
                } else {
                    start + (end - start) * u
                }
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
                if u >= 1.0 {
                    return end;
                }
                let (a, b, n) = plane.axes();
                let end_radius = plane.radius_at(center, end);
                let r = radius + (end_radius - radius) * u;
                let th = start_angle + sweep * u;
                let mut p = center;
                p[a] = center[a] + r * th.cos();
                p[b] = center[b] + r * th.sin();
                p[n] = start[n] + normal_travel * u;
                p
            }
        }
    }

    /// Unit tangent at arc length `s`.
    pub fn tangent_at(&self, s: f64) -> Vec3 {
        match *self {
            Primitive::Line { start, end } => (end - start).unit(),
            Primitive::Arc {
                plane,
                radius,
                start_angle,
                sweep,
                normal_travel,
                ..
            } => {
                let len = self.length();
                let u = if len > 0.0 {
                    (s / len).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (a, b, n) = plane.axes();
                let th = start_angle + sweep * u;
                let mut t = Vec3::ZERO;
                t[a] = -radius * sweep * th.sin();
                t[b] = radius * sweep * th.cos();
                t[n] = normal_travel;
                t.unit()
            }
        }
    }

    /// Curvature (1/mm) of the path; zero for lines. For a helix, the curvature of
    /// the helix, R·ω² / (R²ω² + h²) per unit angle.
    #[inline]
    pub fn curvature(&self) -> f64 {
        match *self {
            Primitive::Line { .. } => 0.0,
            Primitive::Arc {
                radius,
                sweep,
                normal_travel,
                ..
            } => {
                let rs = radius * sweep;
                let l2 = rs * rs + normal_travel * normal_travel;
                if l2 > 0.0 {
                    radius * sweep * sweep / l2
                } else {
                    0.0
                }
            }
        }
    }

    /// Signed contour error of point `p` against this primitive (mm).
    ///
    /// Lines: distance to the infinite line, positive to the left of the direction of
    /// travel seen from +Z (for lines with no XY component, unsigned). Arcs: in-plane
    /// distance from the centre minus the radius, positive outside the circle.
    pub fn contour_error(&self, p: Vec3) -> f64 {
        match *self {
            Primitive::Line { start, end } => {
                let d = end - start;
                let len = d.norm();
                if len == 0.0 {
                    return (p - start).norm();
                }
                let u = d * (1.0 / len);
                let w = p - start;
                let perp = w - u * w.dot(u);
                let dist = perp.norm();
                let cross_z = d[0] * w[1] - d[1] * w[0];
                if d[0].hypot(d[1]) > 1e-12 * len && cross_z < 0.0 {
                    -dist
                } else {
                    dist
                }
            }
            Primitive::Arc {
                center,
                plane,
                radius,
                ..
            } => {
                let (a, b, _) = plane.axes();
                (p[a] - center[a]).hypot(p[b] - center[b]) - radius
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`Primitive::arc`] as it was before its copies per plane: the axes indexed
    /// by the variables [`Plane::axes`] gives.
    fn arc_variable_axes(
        start: Vec3,
        end: Vec3,
        center: Vec3,
        plane: Plane,
        turns: i32,
    ) -> Primitive {
        let (a, b, n) = plane.axes();
        let mut c = center;
        c[n] = start[n];
        let (sa, sb) = (start[a] - c[a], start[b] - c[b]);
        let radius = sa.hypot(sb);
        let start_angle = sb.atan2(sa);
        let end_angle = (end[b] - c[b]).atan2(end[a] - c[a]);
        let tau = std::f64::consts::TAU;
        let extra = (turns.unsigned_abs().max(1) - 1) as f64 * tau;
        let sweep = if turns >= 0 {
            let mut d = rem_tau(end_angle - start_angle);
            if d <= 1e-12 {
                d = tau;
            }
            d + extra
        } else {
            let mut d = rem_tau(start_angle - end_angle);
            if d <= 1e-12 {
                d = tau;
            }
            -(d + extra)
        };
        Primitive::Arc {
            start,
            center: c,
            plane,
            radius,
            start_angle,
            sweep,
            normal_travel: end[n] - start[n],
            end,
        }
    }

    /// The bits of every number of an arc, and its plane.
    fn arc_bits(p: &Primitive) -> (Vec<u64>, Plane) {
        let Primitive::Arc {
            start,
            center,
            plane,
            radius,
            start_angle,
            sweep,
            normal_travel,
            end,
        } = *p
        else {
            panic!("not an arc: {p:?}");
        };
        let mut bits: Vec<u64> = [start, center, end]
            .iter()
            .flat_map(|v| v.0.map(f64::to_bits))
            .collect();
        bits.extend([radius, start_angle, sweep, normal_travel].map(f64::to_bits));
        (bits, plane)
    }

    #[test]
    fn arc_per_plane_is_the_variable_axes_arc() {
        // pseudo-random points (a fixed linear congruential sequence), values on and
        // off the axes through the centre, zeros of both signs, whole turns
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let k = state >> 33;
            match k % 8 {
                0 => 0.0,
                1 => -0.0,
                2 => 0.25,
                3 => -((k % 97) as f64) * 0.125,
                _ => (k as f64 / (1u64 << 31) as f64 - 0.5) * 40.0,
            }
        };
        for i in 0..30_000 {
            let mut v = || Vec3::new(next(), next(), next());
            let (start, end, center) = (v(), v(), v());
            let plane = [Plane::XY, Plane::XZ, Plane::YZ][i % 3];
            let turns = [1, -1, 2, -3, 0][i % 5];
            let (got, want) = (
                Primitive::arc(start, end, center, plane, turns),
                arc_variable_axes(start, end, center, plane, turns),
            );
            assert_eq!(
                arc_bits(&got),
                arc_bits(&want),
                "{start:?} {end:?} {center:?} {plane:?}"
            );
        }
    }

    #[test]
    fn planar_arc_length_is_what_hypot_gives() {
        for k in 1..2000 {
            let rs = (k as f64 * 0.37).powf(1.3) * if k % 2 == 0 { -1.0 } else { 1.0 };
            let a = Primitive::Arc {
                start: Vec3::ZERO,
                center: Vec3::ZERO,
                plane: Plane::XY,
                radius: 1.0,
                start_angle: 0.0,
                sweep: rs,
                normal_travel: 0.0,
                end: Vec3::ZERO,
            };
            assert_eq!(a.length().to_bits(), rs.hypot(0.0).to_bits());
        }
    }

    #[test]
    fn rem_tau_is_rem_euclid() {
        let tau = std::f64::consts::TAU;
        let mut xs: Vec<f64> = (-4000..4000).map(|k| k as f64 * 0.00731 + 1e-3).collect();
        // the edges of the fast paths and their neighbours
        for e in [0.0, tau, 2.0 * tau, 3.0 * tau] {
            for v in [e, -e] {
                let mut lo = v;
                let mut hi = v;
                for _ in 0..4 {
                    xs.extend([lo, hi]);
                    lo = lo.next_down();
                    hi = hi.next_up();
                }
            }
        }
        for x in xs {
            assert_eq!(rem_tau(x).to_bits(), x.rem_euclid(tau).to_bits(), "{x}");
        }
    }

    #[test]
    fn full_circle_g3_and_g2() {
        let s = Vec3::new(10.0, 0.0, 0.0);
        let c = Vec3::ZERO;
        let ccw = Primitive::arc(s, s, c, Plane::XY, 1);
        let cw = Primitive::arc(s, s, c, Plane::XY, -1);
        assert!((ccw.length() - std::f64::consts::TAU * 10.0).abs() < 1e-9);
        assert!((cw.length() - std::f64::consts::TAU * 10.0).abs() < 1e-9);
        // a quarter of the way round: CCW at +Y, CW at -Y
        let q = ccw.length() / 4.0;
        assert!((ccw.point_at(q) - Vec3::new(0.0, 10.0, 0.0)).norm() < 1e-9);
        assert!((cw.point_at(q) - Vec3::new(0.0, -10.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn xz_plane_is_z_then_x() {
        // G18 G3 from (x=10,z=0) about origin: counter-clockwise about +Y in (z, x).
        let a = Primitive::arc(
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::ZERO,
            Plane::XZ,
            -1,
        );
        assert!((a.length() - std::f64::consts::FRAC_PI_2 * 10.0).abs() < 1e-9);
        assert!((a.end() - Vec3::new(0.0, 0.0, 10.0)).norm() < 1e-9);
    }

    #[test]
    fn helix_end_and_curvature() {
        let a = Primitive::arc(
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(5.0, 0.0, -2.0),
            Vec3::ZERO,
            Plane::XY,
            2,
        );
        assert!((a.end() - Vec3::new(5.0, 0.0, -2.0)).norm() < 1e-9);
        let rs = 5.0 * 4.0 * std::f64::consts::PI;
        assert!((a.length() - rs.hypot(2.0)).abs() < 1e-9);
        assert!(a.curvature() < 0.2 && a.curvature() > 0.19);
    }

    #[test]
    fn contour_error_signs() {
        let l = Primitive::Line {
            start: Vec3::ZERO,
            end: Vec3::new(10.0, 0.0, 0.0),
        };
        assert!((l.contour_error(Vec3::new(3.0, 0.5, 0.0)) - 0.5).abs() < 1e-12);
        assert!((l.contour_error(Vec3::new(3.0, -0.5, 0.0)) + 0.5).abs() < 1e-12);
        let c = Primitive::arc(
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::ZERO,
            Plane::XY,
            1,
        );
        assert!((c.contour_error(Vec3::new(0.0, 1.1, 0.0)) - 0.1).abs() < 1e-12);
    }
}
