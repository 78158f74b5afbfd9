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
    /// A programmed line or arc/helix.
    Prim(Primitive),
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
    /// Arc length (mm).
    pub fn length(&self) -> f64 {
        match self {
            Geom::Prim(p) => p.length(),
            Geom::Blend { radius, sweep, .. } => radius * sweep,
        }
    }

    /// Point at arc length `s`.
    pub fn point_at(&self, s: f64) -> Vec3 {
        match *self {
            Geom::Prim(p) => p.point_at(s),
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

    /// Unit tangent at the start.
    pub fn start_tangent(&self) -> Vec3 {
        match *self {
            Geom::Prim(p) => p.tangent_at(0.0),
            Geom::Blend { e2, .. } => e2,
        }
    }

    /// Unit tangent at the end.
    pub fn end_tangent(&self) -> Vec3 {
        match *self {
            Geom::Prim(p) => p.tangent_at(p.length()),
            Geom::Blend { e1, e2, sweep, .. } => (e2 * sweep.cos() - e1 * sweep.sin()).unit(),
        }
    }

    /// Curvature vector at the start or end (κ·n, 1/mm): zero on lines.
    pub fn curvature_vec(&self, at_end: bool) -> Vec3 {
        match *self {
            Geom::Prim(p @ Primitive::Line { .. }) => {
                let _ = p;
                Vec3::ZERO
            }
            Geom::Prim(p @ Primitive::Arc { center, plane, .. }) => {
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

    /// Per-axis weight w_i ≥ max over the element of |t_i| (velocity) and of
    /// √(t_i² + n_i²) (acceleration): how much of the path motion axis i carries.
    fn axis_weights(&self) -> ([f64; 3], [f64; 3]) {
        match *self {
            Geom::Prim(Primitive::Line { start, end }) => {
                let u = (end - start).unit().abs();
                (u.0, u.0)
            }
            Geom::Prim(
                p @ Primitive::Arc {
                    plane,
                    radius,
                    sweep,
                    normal_travel,
                    ..
                },
            ) => {
                let (a, b, n) = plane.axes();
                let len = p.length().max(f64::MIN_POSITIVE);
                let horiz = (radius * sweep).abs() / len;
                let vert = normal_travel.abs() / len;
                let mut w = [0.0; 3];
                w[a] = horiz;
                w[b] = horiz;
                w[n] = vert;
                let mut wa = [0.0; 3];
                wa[a] = 1.0;
                wa[b] = 1.0;
                wa[n] = vert;
                (w, wa)
            }
            Geom::Blend { e1, e2, .. } => {
                let w = [0, 1, 2].map(|i| e1[i].hypot(e2[i]).min(1.0));
                (w, w)
            }
        }
    }

    /// Curvature (1/mm).
    pub fn curvature(&self) -> f64 {
        match *self {
            Geom::Prim(p) => p.curvature(),
            Geom::Blend { radius, .. } => 1.0 / radius,
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

/// Limits of `g` given per-axis velocity and acceleration limits.
pub fn element_limits(g: &Geom, vmax: [f64; 3], amax: [f64; 3]) -> ElementLimits {
    let (wv, wa) = g.axis_weights();
    let mut vel = f64::INFINITY;
    let mut acc = f64::INFINITY;
    for i in 0..3 {
        if wv[i] > 1e-12 {
            vel = vel.min(vmax[i] / wv[i]);
        }
    }
    let kappa = g.curvature();
    if kappa > 0.0 {
        // Curved: split each axis's acceleration between path and centripetal parts.
        let mut a_axis = f64::INFINITY;
        for i in 0..3 {
            if wa[i] > 1e-12 {
                a_axis = a_axis.min(amax[i] / wa[i]);
            }
        }
        acc = ARC_TANGENTIAL_SHARE * a_axis;
        vel = vel.min((ARC_NORMAL_SHARE * a_axis / kappa).sqrt());
    } else {
        for i in 0..3 {
            if wa[i] > 1e-12 {
                acc = acc.min(amax[i] / wa[i]);
            }
        }
    }
    ElementLimits {
        vel_mm_per_s: vel,
        acc_mm_per_s2: acc,
    }
}
