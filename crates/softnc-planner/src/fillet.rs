//! Blends at line–arc and arc–line corners: a circular fillet tangent to the line and
//! to the arc's circle, in the arc's plane (planar arcs only; helices keep their
//! stop). Written for softnc; LinuxCNC 2.9's arc blends (`blendmath.c`) were the model
//! for blending these joins at all, not for the construction.
//!
//! Construction, for a line that runs into the corner C along u and an arc (centre c,
//! radius R) that leaves C: the fillet touches the line at P₁ = C − d·u, so its centre
//! is F = P₁ + r·n (n ⊥ u, towards the turn). Tangency to the circle,
//! |F − c| = R + σr (σ = +1 outside, −1 inside), is linear in r:
//! r = (R² − |w|²) / (2(w·n − σR)), w = P₁ − c. The fillet meets the circle at
//! T = c + R·(F − c)/|F − c|. A candidate is kept only if it is a real blend: r > 0, it
//! turns less than π, its tangent at T is the arc's (same direction), T lies on the arc
//! within the arc length it may give, and every sampled point of it lies within the
//! tolerance of the programmed line or arc. An arc–line corner is the same
//! construction on the path run backwards.

use softnc_core::{Primitive, Vec3};

/// Share of the tolerance the fillet's distance from the corner may use.
const DEVIATION_SHARE: f64 = 0.9;
/// Largest difference between an arc's start and end radius (CAM rounding) for which
/// it is blended: near each end it is taken as the circle through that end, the
/// sub-arc between the blends keeps the programmed change of radius.
const MAX_RADIUS_MISMATCH_MM: f64 = 1e-4;
/// Halvings of the line's trim tried before giving up on a blend.
const TRIM_TRIES: usize = 16;

/// The arc as seen from the corner: the circle, and the direction of travel away from
/// the corner (`sense` · N × radial).
#[derive(Debug, Clone, Copy)]
pub struct ArcView {
    /// Centre (in the plane of the corner).
    pub center: Vec3,
    /// Radius (mm).
    pub radius: f64,
    /// Unit normal of the arc's plane.
    pub normal: Vec3,
    /// +1 or −1: travel away from the corner is `sense`·N × (X − c)/R.
    pub sense: f64,
    /// Arc length of the arc from the corner (mm).
    pub len: f64,
}

impl ArcView {
    /// A planar arc, from its start (`at_end` false) or from its end run backwards.
    /// None for helices, arcs of more than one revolution, and arcs whose end radius
    /// differs from the start's by more than `MAX_RADIUS_MISMATCH_MM` or turns their
    /// tangent away from the circle's by more than `max_drift_rad` (such an arc runs
    /// as a spiral whose tangent leaves the circle's by ≈ ΔR/(R·sweep); a blend
    /// touching it is tangent to the circle, so the angle is a kink the junction speed
    /// does not see: the caller bounds it by what the kink share allows at top speed).
    pub fn of(p: &Primitive, at_end: bool, max_drift_rad: f64) -> Option<ArcView> {
        let Primitive::Arc {
            center,
            plane,
            radius,
            sweep,
            normal_travel,
            end,
            ..
        } = *p
        else {
            return None;
        };
        let (a, b, n) = plane.axes();
        let re = (end[a] - center[a]).hypot(end[b] - center[b]);
        if normal_travel != 0.0
            || (re - radius).abs() > MAX_RADIUS_MISMATCH_MM
            || 2.0 * (re - radius).abs() > max_drift_rad * radius * sweep.abs()
            || sweep.abs() >= std::f64::consts::TAU
            || radius <= 0.0
        {
            return None;
        }
        let mut normal = Vec3::ZERO;
        normal[n] = 1.0;
        let s = sweep.signum();
        Some(ArcView {
            center,
            // seen from its end, the circle through the end point (the programmed
            // radius may change along the arc by up to MAX_RADIUS_MISMATCH_MM)
            radius: if at_end { re } else { radius },
            normal,
            sense: if at_end { -s } else { s },
            len: p.length(),
        })
    }

    /// Arc length from the corner `c0` to the circle point nearest `x`, in the
    /// direction of travel away from the corner, in [0, 2πR).
    fn arc_len_to(&self, c0: Vec3, x: Vec3) -> f64 {
        let (p, q) = (c0 - self.center, x - self.center);
        let ang = (p.cross(q).dot(self.normal) * self.sense).atan2(p.dot(q));
        let ang = if ang < 0.0 {
            ang + std::f64::consts::TAU
        } else {
            ang
        };
        ang * self.radius
    }

    /// Unit tangent (direction of travel away from the corner) at circle point `x`.
    fn tangent(&self, x: Vec3) -> Vec3 {
        self.normal.cross(x - self.center).unit() * self.sense
    }
}

/// A fillet found for a corner, in the direction line → arc.
#[derive(Debug, Clone, Copy)]
pub struct Fillet {
    /// Where it leaves the line (or first arc) (mm from the corner).
    pub line_trim: f64,
    /// Where it meets the arc (arc length from the corner, mm).
    pub arc_trim: f64,
    /// Centre.
    pub center: Vec3,
    /// Radius (mm).
    pub radius: f64,
    /// Point on the line where it starts.
    pub p_line: Vec3,
    /// Point on the arc where it ends.
    pub p_arc: Vec3,
    /// Turn (rad, in (0, π)).
    pub sweep: f64,
}

/// The first trim tried: what a line–line blend within 0.9·`tol_mm` would take at
/// a corner turning from `t1` to `t2` (the curvature of the arc changes it by a
/// factor near one; the tries halve it from there).
fn first_trim(t1: Vec3, t2: Vec3, tol_mm: f64) -> f64 {
    let half = 0.5 * t1.dot(t2).clamp(-1.0, 1.0).acos();
    let sec_minus_one = 1.0 / half.cos() - 1.0;
    if sec_minus_one <= 0.0 {
        return f64::INFINITY;
    }
    DEVIATION_SHARE * tol_mm / sec_minus_one * half.tan()
}

/// The fillet at corner `corner` between a line arriving along unit `u` (of which
/// `line_avail` mm before the corner may be given) and an arc leaving it (`arc`, of
/// which `arc_avail` mm may be given), within `tol_mm` of the program: the largest
/// found trying the line's trim from `line_avail` down by halves.
pub fn line_arc(
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
) -> Option<Fillet> {
    let t2 = arc.tangent(corner);
    let perp = t2 - u * u.dot(t2);
    if perp.norm() < 1e-9 || u.dot(arc.normal).abs() > 1e-9 {
        return None; // tangent (or reversing) join, or a line out of the arc's plane
    }
    let n = perp.unit();
    let mut d = line_avail.min(first_trim(u, t2, tol_mm));
    for _ in 0..TRIM_TRIES {
        if d <= 1e-9 {
            return None;
        }
        let p1 = corner - u * d;
        if let Some(f) = candidate(corner, p1, u, &[n], d, arc, arc_avail) {
            if corner_deviation(&f, corner) <= DEVIATION_SHARE * tol_mm {
                return Some(f);
            }
        }
        d *= 0.7;
    }
    None
}

/// The fillet at corner `corner` between two arcs of one plane: `a` arriving (its
/// programmed primitive, of which `a_avail` mm before the corner may be given) and
/// `b` leaving (`b_avail` mm), within `tol_mm`: the largest found trying the first
/// arc's trim from `a_avail` down by halves.
pub fn arc_arc(
    corner: Vec3,
    a: &Primitive,
    a_avail: f64,
    b: &ArcView,
    b_avail: f64,
    tol_mm: f64,
    max_drift_rad: f64,
) -> Option<Fillet> {
    let a_view = ArcView::of(a, true, max_drift_rad)?;
    if (a_view.normal - b.normal).norm() > 1e-12 {
        return None; // arcs in different planes
    }
    let a_len = a.length();
    let t1 = a.tangent_at(a_len);
    let t2 = b.tangent(corner);
    if (t2 - t1).norm() < 1e-9 {
        return None; // tangent join
    }
    let mut d = a_avail.min(first_trim(t1, t2, tol_mm));
    for _ in 0..TRIM_TRIES {
        if d <= 1e-9 {
            return None;
        }
        let p1 = a.point_at(a_len - d);
        let u = a.tangent_at(a_len - d);
        let radial = (p1 - a_view.center).unit();
        if let Some(f) = candidate(corner, p1, u, &[radial, -radial], d, b, b_avail) {
            if corner_deviation(&f, corner) <= DEVIATION_SHARE * tol_mm {
                return Some(f);
            }
        }
        d *= 0.7;
    }
    None
}

/// The fillet leaving the first move at `p1` (direction of travel `u` there, `d` before
/// the corner) with its centre along one of `normals`, if one is a real blend.
fn candidate(
    corner: Vec3,
    p1: Vec3,
    u: Vec3,
    normals: &[Vec3],
    d: f64,
    arc: &ArcView,
    arc_avail: f64,
) -> Option<Fillet> {
    let w = p1 - arc.center;
    let big_r = arc.radius;
    let mut best: Option<Fillet> = None;
    for (&n, sigma) in normals.iter().flat_map(|n| [(n, 1.0), (n, -1.0)]) {
        let den = 2.0 * (w.dot(n) - sigma * big_r);
        let r = (big_r * big_r - w.dot(w)) / den;
        if !(r.is_finite() && r > 1e-6) {
            continue;
        }
        let f = p1 + n * r;
        let fc = f - arc.center;
        if fc.norm() < 1e-12 || ((fc.norm() - (big_r + sigma * r)).abs() > 1e-7 * big_r.max(1.0)) {
            continue;
        }
        let t = arc.center + fc.unit() * big_r;
        // sweep from P₁ to T about F, in the direction of u at P₁
        let (e1, e2) = ((p1 - f) * (1.0 / r), u);
        let q = t - f;
        let sweep = q.dot(e2).atan2(q.dot(e1));
        if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
            continue;
        }
        let t_fillet = e2 * sweep.cos() - e1 * sweep.sin();
        if t_fillet.dot(arc.tangent(t)) < 1.0 - 1e-9 {
            continue;
        }
        let arc_trim = arc.arc_len_to(corner, t);
        if !(arc_trim > 1e-9 && arc_trim <= arc_avail) {
            continue;
        }
        let this = Fillet {
            line_trim: d,
            arc_trim,
            center: f,
            radius: r,
            p_line: p1,
            p_arc: t,
            sweep,
        };
        if best.is_none_or(|b| this.sweep < b.sweep) {
            best = Some(this);
        }
    }
    best
}

/// How far the fillet passes from the programmed corner: |C − F| − r, the distance
/// from C to the nearest point of the fillet (as for line–line blends, δ of the
/// corner; the tests measure the samples' distance to the programmed path).
fn corner_deviation(f: &Fillet, corner: Vec3) -> f64 {
    ((corner - f.center).norm() - f.radius).abs()
}
