//! Path elements the planner follows: programmed lines and arcs, and the 3-D blend
//! arcs it inserts at corners; each with its per-axis limits folded into path limits.

use softnc_core::{Primitive, Vec3};

/// Share of an axis's acceleration a curved element may spend along the path; the
/// rest goes to centripetal acceleration, with `ARC_TANGENTIAL_SHARE² +
/// ARC_NORMAL_SHARE² = 1` so that |t_i·a_t + n_i·a_n| ≤ A_i on every axis.
pub const ARC_TANGENTIAL_SHARE: f64 = 0.5;
/// Share of an axis's acceleration a curved element may spend on centripetal acceleration.
pub const ARC_NORMAL_SHARE: f64 = 0.866_025_403_784_438_6;

/// Geometry of one path element, machine coordinates (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Geom {
    /// The stretch [from, to] (arc length) of the programmed line `start` → `end`
    /// (lines lose their ends to the blends at their corners; the programmed line
    /// stays exact). The element's length is `to - from`.
    Line {
        /// Programmed start point.
        start: Vec3,
        /// Programmed end point.
        end: Vec3,
        /// Arc length of the programmed line where the element starts (mm).
        from: f64,
        /// Arc length of the programmed line where the element ends (mm).
        to: f64,
        /// Length of the programmed line (mm).
        prog_len: f64,
    },
    /// A programmed arc or helix (a [`Primitive::Arc`]; never trimmed).
    Arc(Primitive),
    /// A circular blend arc in any plane: c + r(cos φ·e1 + sin φ·e2), φ ∈ [0, sweep].
    Blend {
        /// Centre.
        center: Vec3,
        /// Unit vector from the centre to the start point.
        e1: Vec3,
        /// Unit vector orthogonal to e1 in the arc's plane, towards the direction of travel.
        e2: Vec3,
        /// Radius (mm).
        radius: f64,
        /// Sweep (rad, > 0).
        sweep: f64,
    },
}

impl Geom {
    /// Point at arc length `s` from the start of the element.
    pub fn point_at(&self, s: f64) -> Vec3 {
        match *self {
            Geom::Line {
                start,
                end,
                from,
                to,
                prog_len,
            } => {
                let t = if s >= to - from {
                    to
                } else {
                    from + s.max(0.0)
                };
                if t >= prog_len {
                    end
                } else {
                    start + (end - start) * (t / prog_len)
                }
            }
            Geom::Arc(p) => p.point_at(s),
            Geom::Blend {
                center,
                e1,
                e2,
                radius,
                sweep,
            } => {
                let phi = if radius > 0.0 {
                    (s / radius).clamp(0.0, sweep)
                } else {
                    0.0
                };
                center + e1 * (radius * phi.cos()) + e2 * (radius * phi.sin())
            }
        }
    }

    /// The programmed primitive this element is part of (None for blends).
    pub fn programmed(&self) -> Option<Primitive> {
        match *self {
            Geom::Line { start, end, .. } => Some(Primitive::Line { start, end }),
            Geom::Arc(p) => Some(p),
            Geom::Blend { .. } => None,
        }
    }

    /// Curvature vector at the start or end (κ·n, 1/mm): zero on lines.
    pub fn curvature_vec(&self, at_end: bool) -> Vec3 {
        match *self {
            Geom::Line { .. } | Geom::Arc(Primitive::Line { .. }) => Vec3::ZERO,
            Geom::Arc(p @ Primitive::Arc { center, plane, .. }) => {
                let s = if at_end { p.length() } else { 0.0 };
                let q = p.point_at(s);
                let (a, b, _) = plane.axes();
                let mut inward = Vec3::ZERO;
                inward[a] = center[a] - q[a];
                inward[b] = center[b] - q[b];
                inward.unit() * p.curvature()
            }
            Geom::Blend {
                center,
                radius,
                sweep,
                e1,
                e2,
            } => {
                let phi = if at_end { sweep } else { 0.0 };
                let q = center + e1 * (radius * phi.cos()) + e2 * (radius * phi.sin());
                (center - q).unit() * (1.0 / radius)
            }
        }
    }

    /// Curvature (1/mm).
    pub fn curvature(&self) -> f64 {
        match *self {
            Geom::Line { .. } => 0.0,
            Geom::Arc(p) => p.curvature(),
            Geom::Blend { radius, .. } => 1.0 / radius,
        }
    }
}

/// What the builder needs to know of an element: its length, unit tangents at both
/// ends, and per-axis weights w_i ≥ max over the element of |t_i| (velocity) and of
/// √(t_i² + n_i²) (acceleration): how much of the path motion axis i carries.
#[derive(Debug, Clone, Copy)]
pub struct ElementShape {
    /// Arc length (mm).
    pub len: f64,
    /// Unit tangent at the start.
    pub start_tangent: Vec3,
    /// Unit tangent at the end.
    pub end_tangent: Vec3,
    /// Velocity weights per axis.
    pub vel_weight: [f64; 3],
    /// Acceleration weights per axis.
    pub acc_weight: [f64; 3],
    /// Curvature (1/mm).
    pub curvature: f64,
}

impl ElementShape {
    /// A straight element along the unit vector `dir`.
    pub fn line(len: f64, dir: Vec3) -> ElementShape {
        let w = dir.abs().0;
        ElementShape {
            len,
            start_tangent: dir,
            end_tangent: dir,
            vel_weight: w,
            acc_weight: w,
            curvature: 0.0,
        }
    }

    /// A programmed arc or helix. The end tangent comes from the programmed end point
    /// (the sweep ends at its angle), so no trigonometry is needed.
    pub fn arc(p: &Primitive) -> ElementShape {
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
            let (s, e) = (p.start(), p.end());
            let d = e - s;
            return ElementShape::line(d.norm(), d.unit());
        };
        let (a, b, n) = plane.axes();
        let rs = radius * sweep;
        let len = p.length();
        // tangent = (R·sweep·(−sin θ, cos θ), h) normalised, θ the radial angle
        let mut ts = Vec3::ZERO;
        ts[a] = -sweep * (start[b] - center[b]);
        ts[b] = sweep * (start[a] - center[a]);
        ts[n] = normal_travel;
        let (ea, eb) = (end[a] - center[a], end[b] - center[b]);
        let re = (ea * ea + eb * eb).sqrt();
        let (cos_e, sin_e) = if re > 1e-12 * radius.max(1.0) {
            (ea / re, eb / re)
        } else {
            let th = start_angle + sweep;
            (th.cos(), th.sin())
        };
        let mut te = Vec3::ZERO;
        te[a] = -rs * sin_e;
        te[b] = rs * cos_e;
        te[n] = normal_travel;
        let l = len.max(f64::MIN_POSITIVE);
        // (in the plane, l = |rs|: the divisions would give exactly 1 and 0)
        let (horiz, vert) = if normal_travel == 0.0 && l == rs.abs() {
            (1.0, 0.0)
        } else {
            (rs.abs() / l, normal_travel.abs() / l)
        };
        let mut w = [0.0; 3];
        w[a] = horiz;
        w[b] = horiz;
        w[n] = vert;
        let mut wa = [0.0; 3];
        wa[a] = 1.0;
        wa[b] = 1.0;
        wa[n] = vert;
        ElementShape {
            len,
            start_tangent: ts.unit(),
            end_tangent: te.unit(),
            vel_weight: w,
            acc_weight: wa,
            curvature: p.curvature(),
        }
    }

    /// A blend arc (see [`Geom::Blend`]).
    pub fn blend(e1: Vec3, e2: Vec3, radius: f64, sweep: f64) -> ElementShape {
        let w = [0, 1, 2].map(|i| e1[i].hypot(e2[i]).min(1.0));
        ElementShape {
            len: radius * sweep,
            start_tangent: e2,
            end_tangent: (e2 * sweep.cos() - e1 * sweep.sin()).unit(),
            vel_weight: w,
            acc_weight: w,
            curvature: 1.0 / radius,
        }
    }
}

/// Path limits of one element derived from the axis limits.
#[derive(Debug, Clone, Copy)]
pub struct ElementLimits {
    /// Highest path speed (mm/s): axis velocities and centripetal acceleration.
    pub vel_mm_per_s: f64,
    /// Highest tangential acceleration (mm/s²).
    pub acc_mm_per_s2: f64,
}

/// Limits of an element of shape `g` given per-axis velocity and acceleration limits.
pub fn element_limits(g: &ElementShape, vmax: [f64; 3], amax: [f64; 3]) -> ElementLimits {
    let (wv, wa) = (g.vel_weight, g.acc_weight);
    // an axis's limit over its weight (the division skipped for the common weight 1,
    // where it is exact)
    let per_weight = |limit: f64, w: f64| if w == 1.0 { limit } else { limit / w };
    let mut vel = f64::INFINITY;
    let mut acc = f64::INFINITY;
    for i in 0..3 {
        if wv[i] > 1e-12 {
            vel = vel.min(per_weight(vmax[i], wv[i]));
        }
    }
    let kappa = g.curvature;
    if kappa > 0.0 {
        // Curved: split each axis's acceleration between path and centripetal parts.
        let mut a_axis = f64::INFINITY;
        for i in 0..3 {
            if wa[i] > 1e-12 {
                a_axis = a_axis.min(per_weight(amax[i], wa[i]));
            }
        }
        acc = ARC_TANGENTIAL_SHARE * a_axis;
        vel = vel.min((ARC_NORMAL_SHARE * a_axis / kappa).sqrt());
    } else {
        for i in 0..3 {
            if wa[i] > 1e-12 {
                acc = acc.min(per_weight(amax[i], wa[i]));
            }
        }
    }
    ElementLimits {
        vel_mm_per_s: vel,
        acc_mm_per_s2: acc,
    }
}
