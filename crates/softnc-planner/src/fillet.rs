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
pub(crate) const MAX_RADIUS_MISMATCH_MM: f64 = 1e-4;
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
        // |end − c| in the plane (`Plane::radius_at` without `hypot`: the squares
        // cannot overflow for coordinates a machine reaches)
        let (ea, eb) = (end[a] - center[a], end[b] - center[b]);
        let re = (ea * ea + eb * eb).sqrt();
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

    /// Angle about the centre from the corner `c0` to the circle point nearest `x`,
    /// in the direction of travel away from the corner, in [0, 2π) (rad).
    fn angle_to(&self, c0: Vec3, x: Vec3) -> f64 {
        let (p, q) = (c0 - self.center, x - self.center);
        let ang = (p.cross(q).dot(self.normal) * self.sense).atan2(p.dot(q));
        if ang < 0.0 {
            ang + std::f64::consts::TAU
        } else {
            ang
        }
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
    /// The same as an angle about the arc's centre (rad): `arc_trim` over the radius
    /// the arc is seen with ([`ArcView::radius`]).
    pub arc_trim_rad: f64,
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
    /// cos of `sweep` (from the construction, no trigonometry).
    pub cos_sweep: f64,
    /// sin of `sweep`.
    pub sin_sweep: f64,
}

/// The first trim tried: what a line–line blend within 0.9·`tol_mm` would take at
/// a corner turning from `t1` to `t2` (the curvature of the arc changes it by a
/// factor near one; the tries halve it from there).
///
/// With c = cos θ = t1·t2 and s = sin θ = |t1 × t2| (no trigonometry): tan(θ/2) =
/// s/(1 + c), cos(θ/2) = √((1 + c)/2) and sec(θ/2) − 1 = (1 − cos(θ/2))/cos(θ/2)
/// with 1 − cos(θ/2) = (s²/(2(1 + c)))/(1 + cos(θ/2)), which keeps its precision at
/// small turns.
fn first_trim(t1: Vec3, t2: Vec3, tol_mm: f64) -> f64 {
    let c = t1.dot(t2).clamp(-1.0, 1.0);
    let s = t1.cross(t2).norm().min(1.0);
    let one_plus_c = 1.0 + c;
    if one_plus_c <= 0.0 {
        return 0.0; // a reversal: no fillet
    }
    let cos_half = (0.5 * one_plus_c).sqrt();
    let one_minus_cos_half = s * s / (2.0 * one_plus_c) / (1.0 + cos_half);
    let sec_minus_one = one_minus_cos_half / cos_half;
    if sec_minus_one <= 0.0 {
        return f64::INFINITY;
    }
    let tan_half = s / one_plus_c;
    DEVIATION_SHARE * tol_mm / sec_minus_one * tan_half
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
///
/// Of the candidates (each normal, the fillet outside or inside the circle) that are
/// real blends the one that turns least is kept. The sweep φ ∈ (0, π) of each comes
/// from its cosine q₁/|q| (decreasing in φ), so the `atan2`s of the sweep and of the
/// arc position are taken only for a candidate that would beat the best so far (one
/// per corner on CAM programs: the other tangency turns the wrong way).
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
    let w_sq = w.dot(w);
    // every normal is ⟂ u, so F − c = w + r·n has (F − c)·u = w·u, and
    // q = T − F = −σr·(F − c)/|F − c| (|F − c| = R + σr): q·u > 0, a sweep in (0, π),
    // needs σ·(w·u) < 0; the other tangency is not built
    let wu = w.dot(u);
    let mut best: Option<Fillet> = None;
    for &n in normals {
        let wn = w.dot(n);
        for sigma in [1.0, -1.0] {
            if sigma * wu >= 0.0 {
                continue;
            }
            let den = 2.0 * (wn - sigma * big_r);
            let r = (big_r * big_r - w_sq) / den;
            if !(r.is_finite() && r > 1e-6) {
                continue;
            }
            let f = p1 + n * r;
            let fc = f - arc.center;
            let fc_norm = fc.norm();
            if fc_norm < 1e-12 || ((fc_norm - (big_r + sigma * r)).abs() > 1e-7 * big_r.max(1.0)) {
                continue;
            }
            let t = arc.center + fc * (1.0 / fc_norm) * big_r;
            // sweep from P₁ to T about F, in the direction of u at P₁: q = r·(cos φ·e1 +
            // sin φ·e2) (T, F, P₁ and u lie in one plane), so its cosine and sine come
            // from q without trigonometry; a sweep in (0, π) has sin φ > 0
            let (e1, e2) = ((p1 - f) * (1.0 / r), u);
            let q = t - f;
            let (q1, q2) = (q.dot(e1), q.dot(e2));
            if q2 <= 0.0 {
                continue;
            }
            let qn = (q1 * q1 + q2 * q2).sqrt();
            let (cos_sweep, sin_sweep) = (q1 / qn, q2 / qn);
            if best.is_some_and(|b| cos_sweep <= b.cos_sweep) {
                continue; // turns at least as far as the best so far
            }
            let t_fillet = e2 * cos_sweep - e1 * sin_sweep;
            if t_fillet.dot(arc.tangent(t)) < 1.0 - 1e-9 {
                continue;
            }
            let sweep = q2.atan2(q1);
            if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
                continue;
            }
            let arc_trim_rad = arc.angle_to(corner, t);
            let arc_trim = arc_trim_rad * arc.radius;
            if !(arc_trim > 1e-9 && arc_trim <= arc_avail) {
                continue;
            }
            best = Some(Fillet {
                line_trim: d,
                arc_trim,
                arc_trim_rad,
                center: f,
                radius: r,
                p_line: p1,
                p_arc: t,
                sweep,
                cos_sweep,
                sin_sweep,
            });
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

/// One circular arc of a [`Biarc`], in the form of [`crate::path::Geom::Blend`]:
/// `center + radius·(cos φ·e1 + sin φ·e2)`, φ ∈ [0, sweep].
#[derive(Debug, Clone, Copy)]
pub struct ArcPiece {
    /// Centre.
    pub center: Vec3,
    /// Unit vector from the centre to the start point.
    pub e1: Vec3,
    /// Unit tangent at the start.
    pub e2: Vec3,
    /// Radius (mm).
    pub radius: f64,
    /// Sweep (rad, in (0, π)).
    pub sweep: f64,
}

impl ArcPiece {
    /// The arc that leaves `from` along the unit tangent `t` and ends at `to`, if it
    /// is a real turn of less than π (None for a (nearly) straight piece).
    fn through(from: Vec3, t: Vec3, to: Vec3) -> Option<ArcPiece> {
        let c = to - from;
        let n = c - t * t.dot(c);
        let n_len = n.norm();
        if !(n_len > BIARC_MIN_OFFSET_MM && c.dot(t) > -c.norm()) {
            return None;
        }
        let radius = c.dot(c) / (2.0 * n_len);
        let e1 = n * (-1.0 / n_len);
        let center = from - e1 * radius;
        let q = to - center;
        let sweep = q.dot(t).atan2(q.dot(e1));
        if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6 && radius.is_finite()) {
            return None;
        }
        Some(ArcPiece {
            center,
            e1,
            e2: t,
            radius,
            sweep,
        })
    }

    /// Point at angle φ.
    fn point(&self, phi: f64) -> Vec3 {
        self.center + self.e1 * (self.radius * phi.cos()) + self.e2 * (self.radius * phi.sin())
    }

    /// Unit tangent at angle φ.
    fn tangent(&self, phi: f64) -> Vec3 {
        self.e2 * phi.cos() - self.e1 * phi.sin()
    }

    /// The largest distance from `x` to a point of the arc: |q − x|² =
    /// R² + |w|² − 2R·(w₁ cos φ + w₂ sin φ) (w = x − centre, w₁, w₂ its components
    /// along e1, e2) is largest where φ points away from w's projection, if the sweep
    /// reaches that angle, else at an end.
    fn farthest_from(&self, x: Vec3) -> f64 {
        let w = x - self.center;
        let (w1, w2) = (w.dot(self.e1), w.dot(self.e2));
        let mut away = (-w2).atan2(-w1);
        if away < 0.0 {
            away += std::f64::consts::TAU;
        }
        let ends = (self.point(0.0) - x)
            .norm()
            .max((self.point(self.sweep) - x).norm());
        if away <= self.sweep {
            let r2 = self.radius * self.radius + w.dot(w) + 2.0 * self.radius * w1.hypot(w2);
            ends.max(r2.max(0.0).sqrt())
        } else {
            ends
        }
    }
}

/// A blend of two circular arcs (in their own planes, tangent to each other where
/// they meet) at a corner that no single circle can blend: a helix and a line, two
/// helices, arcs of different planes.
#[derive(Debug, Clone, Copy)]
pub struct Biarc {
    /// Arc length given by the move before the corner (mm).
    pub trim_before: f64,
    /// Arc length given by the move after the corner (mm).
    pub trim_after: f64,
    /// Where the blend leaves the move before the corner.
    pub p_before: Vec3,
    /// Where the blend meets the move after the corner.
    pub p_after: Vec3,
    /// The two arcs, in the order they run.
    pub arcs: [ArcPiece; 2],
}

/// Smallest offset of a biarc's end from the tangent line at its start for which it
/// is taken as an arc (mm): below it the radius is not well determined.
const BIARC_MIN_OFFSET_MM: f64 = 1e-7;
/// Largest mismatch between where a biarc piece ends and where it should (its join
/// point, the next move's touch point; mm, and the same in its unit tangent).
const BIARC_CLOSURE_MM: f64 = 1e-7;

/// The biarc blend at `corner`: it leaves the move before at `before(d)` = (point,
/// unit tangent) d mm of arc length before the corner and meets the move after at
/// `after(d)` d mm after it, the largest d found trying from the smallest of
/// `before_avail`, `after_avail` and 0.9·`tol_mm` down by 0.7.
///
/// Construction (the equal-tangent-length biarc of Bolton, "Biarc curves", CAD 7(2),
/// 1975): with ends P₀, P₁ and unit tangents T₀, T₁, the control points Q₀ = P₀ + αT₀
/// and Q₁ = P₁ − αT₁ must lie 2α apart, |V − α(T₀ + T₁)| = 2α with V = P₁ − P₀:
/// 2(T₀·T₁ − 1)α² − 2(V·(T₀ + T₁))α + V·V = 0, whose positive root gives the join
/// point J = (Q₀ + Q₁)/2 with tangent (Q₁ − Q₀)/2α; each half is the circle arc from
/// its end along its tangent through J. Every point of the blend lies within
/// 0.9·`tol_mm` of the programmed corner (its largest distance from the corner,
/// computed per arc), so within that of the programmed path.
pub fn biarc(
    corner: Vec3,
    before: impl Fn(f64) -> (Vec3, Vec3),
    before_avail: f64,
    after: impl Fn(f64) -> (Vec3, Vec3),
    after_avail: f64,
    tol_mm: f64,
) -> Option<Biarc> {
    let mut d = before_avail.min(after_avail).min(DEVIATION_SHARE * tol_mm);
    for _ in 0..TRIM_TRIES {
        if d.is_nan() || d <= 1e-9 {
            return None;
        }
        let ((p0, t0), (p1, t1)) = (before(d), after(d));
        if let Some(arcs) = biarc_pieces(p0, t0, p1, t1) {
            let dev = arcs[0]
                .farthest_from(corner)
                .max(arcs[1].farthest_from(corner));
            if dev <= DEVIATION_SHARE * tol_mm {
                return Some(Biarc {
                    trim_before: d,
                    trim_after: d,
                    p_before: p0,
                    p_after: p1,
                    arcs,
                });
            }
        }
        d *= 0.7;
    }
    None
}

/// The two arcs of the equal-tangent-length biarc from (p0, t0) to (p1, t1), if both
/// are real turns and close on their ends.
fn biarc_pieces(p0: Vec3, t0: Vec3, p1: Vec3, t1: Vec3) -> Option<[ArcPiece; 2]> {
    let v = p1 - p0;
    let ts = t0 + t1;
    let qa = 2.0 * (t0.dot(t1) - 1.0);
    let qb = -2.0 * v.dot(ts);
    let qc = v.dot(v);
    let alpha = if qa.abs() < 1e-12 {
        // parallel tangents: the equation is linear
        if qb.abs() < 1e-300 {
            return None;
        }
        -qc / qb
    } else {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc < 0.0 {
            return None;
        }
        // qa < 0 < qc: the roots have opposite signs; the positive one
        (-qb - disc.sqrt()) / (2.0 * qa)
    };
    if !(alpha.is_finite() && alpha > 0.0) {
        return None;
    }
    let (q0, q1) = (p0 + t0 * alpha, p1 - t1 * alpha);
    let join = (q0 + q1) * 0.5;
    let tj = (q1 - q0).unit();
    let first = ArcPiece::through(p0, t0, join)?;
    let second = ArcPiece::through(join, tj, p1)?;
    let closes = |arc: &ArcPiece, p: Vec3, t: Vec3| {
        (arc.point(arc.sweep) - p).norm() <= BIARC_CLOSURE_MM
            && (arc.tangent(arc.sweep) - t).norm() <= BIARC_CLOSURE_MM
    };
    (closes(&first, join, tj) && closes(&second, p1, t1)).then_some([first, second])
}
