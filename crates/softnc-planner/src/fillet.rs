//! Blends at line–arc and arc–line corners: a circular fillet tangent to the line and
//! to the arc's circle, in the arc's plane (planar arcs only; helices keep their
//! stop). Written for softnc; LinuxCNC 2.9's arc blends (`blendmath.c`) were the model
//! for blending these joins at all, not for the construction.
//!
//! Construction, for a line that runs into the corner C along u and an arc (centre c,
//! radius R) that leaves C: the fillet touches the line at P₁ = C − d·u, so its centre
//! is F = P₁ + r·n (n = u turned a quarter towards the turn). Tangency to the circle,
//! |F − c| = R + σr (σ = +1 outside, −1 inside), is linear in r:
//! r = (R² − |w|²) / (2(w·n − σR)), w = P₁ − c. The fillet meets the circle at
//! T = c + R·(F − c)/|F − c|. A candidate is kept only if it is a real blend: r > 0, it
//! turns less than π, its tangent at T is the arc's (same direction), T lies on the arc
//! within the arc length it may give, and every sampled point of it lies within the
//! tolerance of the programmed line or arc. An arc–line corner is the same
//! construction on the path run backwards.

use crate::path::{max_to, min_to};
use softnc_core::{Primitive, Vec3};

/// Share of the tolerance the fillet's distance from the corner may use.
const DEVIATION_SHARE: f64 = 0.9;
/// Largest difference between an arc's start and end radius (CAM rounding) for which
/// it is blended: near each end it is taken as the circle through that end, the
/// sub-arc between the blends keeps the programmed change of radius.
pub(crate) const MAX_RADIUS_MISMATCH_MM: f64 = 1e-4;
/// Halvings of the line's trim tried before giving up on a blend.
const TRIM_TRIES: usize = 16;
/// Largest distance between where a fillet ends as its element runs it (centre F,
/// radius r, from P₁ along e1 = (P₁ − F)/r and the line's direction u through the
/// sweep: `Geom::Blend`) and the point T where it meets the arc (mm); as
/// `BIARC_CLOSURE_MM` for the biarcs. At a nearly tangent join whose arc turns back
/// onto the line's direction the fillet is nearly straight and its radius enormous
/// (a line into a 0.05 mm arc 3.5e-5 rad off tangent: r = 5e7 mm): the rounding of
/// its normal (≈ 1e-12 rad off ⟂ u) times r moved its end 1.65e-4 mm past T, a step
/// in position the S-curve sampled as 3.2× the jerk limit. A fillet that does not
/// close is built again on the exact perpendicular of u, and if that does not close
/// either it is no blend: a shorter trim (smaller r) is tried. (Line–arc joins only: the
/// arc–arc fillets take their normal as the first arc's radial, ⟂ its tangent to
/// rounding, and a scan of nearly tangent long-arc → tiny-arc joins left no gap.)
pub(crate) const FILLET_CLOSURE_MM: f64 = 1e-7;

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
    /// The plane's axes (a, b, normal), as `Plane::axes`.
    pub axes: (usize, usize, usize),
    /// +1 where (a, b, normal) is right-handed (e_a × e_b = N), else −1: in the
    /// plane's coordinates N × (x, y) = `orient`·(−y, x).
    pub orient: f64,
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
        let re = end_radius_mm(p)?;
        Self::of_measured(p, at_end, max_drift_rad, re, p.length())
    }

    /// [`ArcView::of`] given the arc's end radius in its plane `re` (|end − c|,
    /// computed as `of` does) and its length `len` (`Primitive::length`): no square
    /// root, the same view.
    #[inline(always)]
    pub fn of_measured(
        p: &Primitive,
        at_end: bool,
        max_drift_rad: f64,
        re: f64,
        len: f64,
    ) -> Option<ArcView> {
        let Primitive::Arc {
            center,
            plane,
            radius,
            sweep,
            normal_travel,
            ..
        } = *p
        else {
            return None;
        };
        let (a, b, n) = plane.axes();
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
            len,
            axes: (a, b, n),
            // (a, b, n) cyclic (0 1 2, 1 2 0, 2 0 1) is right-handed
            orient: if b == (a + 1) % 3 { 1.0 } else { -1.0 },
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

/// An arc's end radius |end − c| in its plane (`Plane::radius_at` without `hypot`:
/// the squares cannot overflow for coordinates a machine reaches); None for a line.
pub(crate) fn end_radius_mm(p: &Primitive) -> Option<f64> {
    let Primitive::Arc {
        center, plane, end, ..
    } = *p
    else {
        return None;
    };
    let (a, b, _) = plane.axes();
    let (ea, eb) = (end[a] - center[a], end[b] - center[b]);
    Some((ea * ea + eb * eb).sqrt())
}

/// The first trim tried: what a line–line blend within 0.9·`tol_mm` would take at
/// a corner turning from `t1` to `t2` (the curvature of the arc changes it by a
/// factor near one; the tries shorten it from there).
fn first_trim(t1: Vec3, t2: Vec3, tol_mm: f64) -> f64 {
    first_trim_cs(t1.dot(t2), t1.cross(t2).norm(), tol_mm)
}

/// [`first_trim`] from the cosine `c` and sine `s` of the turn θ: the blend of a
/// line–line corner that passes 0.9·`tol_mm` from it trims δ·tan(θ/2)/(sec(θ/2) − 1),
/// and with cos(θ/2) = √((1 + c)/2) and 1 − cos(θ/2) = s²/(2(1 + c)(1 + cos(θ/2)))
/// that is 2·δ·cos(θ/2)·(1 + cos(θ/2))/s: one root and one division, and no loss of
/// precision at small turns (no difference of nearly equal numbers).
#[inline(always)]
fn first_trim_cs(c: f64, s: f64, tol_mm: f64) -> f64 {
    // (the clamp only where it changes c: off the chain of roots and divisions that
    // every fillet waits on)
    let one_plus_c = if (-1.0..=1.0).contains(&c) {
        1.0 + c
    } else {
        first_trim_clamped(c)
    };
    let s = min_to(s, 1.0);
    if one_plus_c <= 0.0 {
        return 0.0; // a reversal: no fillet
    }
    if s <= 0.0 {
        return f64::INFINITY; // no turn: any trim keeps within the tolerance
    }
    let cos_half = (0.5 * one_plus_c).sqrt();
    2.0 * DEVIATION_SHARE * tol_mm * cos_half * (1.0 + cos_half) / s
}

/// 1 + c for a turn cosine `c` beyond [−1, 1] (or NaN): clamped first, as
/// [`first_trim_cs`] takes it.
#[cold]
#[inline(never)]
fn first_trim_clamped(c: f64) -> f64 {
    1.0 + c.clamp(-1.0, 1.0)
}

/// The fillet at corner `corner` between a line arriving along unit `u` (of which
/// `line_avail` mm before the corner may be given) and an arc leaving it (`arc`, of
/// which `arc_avail` mm may be given), within `tol_mm` of the program: the largest
/// found trying the line's trim from the first trim ([`first_trim_cs`], at most
/// `line_avail`) down by factors of 0.7.
pub fn line_arc(
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
) -> Option<Fillet> {
    // (the view's axes are always a `Plane`'s, `ArcView::of_measured`)
    match arc.axes {
        (0, 1, 2) => line_arc_in::<0, 1, 2>(corner, u, line_avail, arc, arc_avail, tol_mm),
        (2, 0, 1) => line_arc_in::<2, 0, 1>(corner, u, line_avail, arc, arc_avail, tol_mm),
        (1, 2, 0) => line_arc_in::<1, 2, 0>(corner, u, line_avail, arc, arc_avail, tol_mm),
        _ => None,
    }
}

/// [`line_arc`] in the plane whose axes ([`ArcView::axes`]) are `A`, `B` and the
/// normal `N`: the same arithmetic, with the components picked at compile time (no
/// addresses worked out at run time, fewer vectors kept in memory to be indexed).
///
/// All of it in the arc's plane coordinates (a, b) (the line lies in that plane
/// within 1e-9; the normal coordinate is the arc's). With p = C − c the corner from
/// the centre and k = sense·orient/|p|, the arc's unit tangent at C is
/// t = k·(−p_b, p_a), so the turn's cosine is u·t = k·(u_b·p_a − u_a·p_b) and its
/// sine (u × t)·N = k·(u·p): one root and one division. The fillet's centre lies
/// along n, u turned a quarter towards the turn: (−u_b, u_a) or (u_b, −u_a), exactly
/// ⟂ u (n·u is x − x = 0) and of u's length, with no root or division.
#[inline(always)]
fn line_arc_in<const A: usize, const B: usize, const N: usize>(
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
) -> Option<Fillet> {
    if u[N].abs() > 1e-9 {
        return None; // a line out of the arc's plane
    }
    let (ua, ub) = (u[A], u[B]);
    let (pa, pb) = (corner[A] - arc.center[A], corner[B] - arc.center[B]);
    let p_norm = (pa * pa + pb * pb).sqrt();
    if p_norm.is_nan() || p_norm <= 0.0 {
        return None;
    }
    let k = arc.sense * arc.orient / p_norm;
    let cos_turn = (ub * pa - ua * pb) * k;
    let sin_turn = (ua * pa + ub * pb) * k;
    let turns = sin_turn.abs() >= 1e-9; // (false for NaN too)
    if !turns {
        return None; // tangent (or reversing) join
    }
    let n = if sin_turn > 0.0 { (-ub, ua) } else { (ub, -ua) };
    let mut d = min_to(line_avail, first_trim_cs(cos_turn, sin_turn.abs(), tol_mm));
    for _ in 0..TRIM_TRIES {
        if d <= 1e-9 {
            return None;
        }
        if let Some(c) = line_arc_at::<A, B, N>(corner, u, d, arc, arc_avail, tol_mm, n, (pa, pb)) {
            // (a fillet whose bound proves it closes is not measured, in tests too)
            debug_assert!(
                !c.surely || closes(&c.fillet::<A, B, N>(arc), u),
                "closure bound wrong: {c:?}"
            );
            if c.surely {
                return Some(c.fillet::<A, B, N>(arc));
            }
            if let Some(f) = fillet_if_closes::<A, B, N>(&c, arc, u) {
                return Some(f);
            }
        }
        d *= 0.7;
    }
    None
}

/// The fillet of a candidate whose bound did not prove it closes, where it does
/// close ([`closes`]). Out of line and cold: the fillets of CAM programs are proven
/// to close by their bound.
#[cold]
#[inline(never)]
fn fillet_if_closes<const A: usize, const B: usize, const N: usize>(
    c: &Candidate,
    arc: &ArcView,
    u: Vec3,
) -> Option<Fillet> {
    let f = c.fillet::<A, B, N>(arc);
    closes(&f, u).then_some(f)
}

/// The arguments of one [`line_arc`] call, for [`line_arc_2`].
#[derive(Debug, Clone, Copy)]
pub struct LineArcJoin<'a> {
    /// The corner.
    pub corner: Vec3,
    /// The line's unit direction, into the corner.
    pub u: Vec3,
    /// How much of the line may be given (mm).
    pub line_avail_mm: f64,
    /// The arc, seen from the corner.
    pub arc: &'a ArcView,
    /// How much of the arc may be given (mm).
    pub arc_avail_mm: f64,
    /// The blend tolerance (mm).
    pub tol_mm: f64,
}

/// [`line_arc`] of two joins at once, with the same bits as two calls, the fillets
/// written to `out` in place (about 140 bytes each). Both are worked out side by side
/// in the two lanes of the processor's two-double registers (`lanes::F2`), the same
/// operations in the same order as `line_arc_in` on its first trim, so that one pass
/// of instructions serves both and the two chains of roots and divisions overlap
/// (a call alone mostly waits on its chain). A join whose first trim does not give
/// a fillet along that path at once (any of `line_arc_in`'s tests failing or taking a
/// special case: a clamped turn cosine, a second trim, a closure to measure, an
/// `atan2` off fdlibm's main path), or a pair in two different planes, is worked
/// out by [`line_arc`] (its lane's numbers are dropped). For consecutive joins
/// worked out ahead (`FilletsAhead`): on the 200k-line workload's joins about 60 ns
/// a join against 83 ns for calls one after the other (`benches/fillet.rs`).
pub fn line_arc_2(joins: [LineArcJoin<'_>; 2], out: &mut [Option<Fillet>; 2]) {
    if joins[0].arc.axes == joins[1].arc.axes {
        match joins[0].arc.axes {
            (0, 1, 2) => return line_arc_2_in::<0, 1, 2>(&joins, out),
            (2, 0, 1) => return line_arc_2_in::<2, 0, 1>(&joins, out),
            (1, 2, 0) => return line_arc_2_in::<1, 2, 0>(&joins, out),
            _ => {}
        }
    }
    out[0] = line_arc_one(&joins[0]);
    out[1] = line_arc_one(&joins[1]);
}

/// [`line_arc`] of `j`.
#[inline(always)]
pub(crate) fn line_arc_one(j: &LineArcJoin) -> Option<Fillet> {
    line_arc(
        j.corner,
        j.u,
        j.line_avail_mm,
        j.arc,
        j.arc_avail_mm,
        j.tol_mm,
    )
}

/// [`line_arc_2`] for two joins in the plane of axes `A`, `B` and normal `N`: lane
/// `i` computes [`line_arc_in`]'s first trim of `joins[i]`, with each of its tests
/// kept as a mask (`ok`) where it returns or branches (a NaN fails every one).
#[inline(always)]
fn line_arc_2_in<const A: usize, const B: usize, const N: usize>(
    joins: &[LineArcJoin<'_>; 2],
    out: &mut [Option<Fillet>; 2],
) {
    use lanes::F2;
    use std::f64::consts::{PI, TAU};
    let [j0, j1] = joins;
    let both = |f: &dyn Fn(&LineArcJoin) -> f64| F2::new(f(j0), f(j1));
    let k = F2::splat;
    let u_n = both(&|j| j.u[N]);
    let mut ok = u_n.abs().le(k(1e-9));
    let (ua, ub) = (both(&|j| j.u[A]), both(&|j| j.u[B]));
    let (ca, cb) = (both(&|j| j.arc.center[A]), both(&|j| j.arc.center[B]));
    let (corner_a, corner_b) = (both(&|j| j.corner[A]), both(&|j| j.corner[B]));
    let (pa, pb) = (corner_a - ca, corner_b - cb);
    let p_norm = (pa * pa + pb * pb).sqrt();
    ok = ok & p_norm.gt(k(0.0));
    let so = both(&|j| j.arc.sense) * both(&|j| j.arc.orient);
    let kt = so / p_norm;
    let cos_turn = (ub * pa - ua * pb) * kt;
    let sin_turn = (ua * pa + ub * pb) * kt;
    ok = ok & sin_turn.abs().ge(k(1e-9));
    let left = sin_turn.gt(k(0.0));
    let (na, nb) = (F2::select(left, -ub, ub), F2::select(left, ua, -ua));
    // first_trim_cs: the cosine within [−1, 1] (its clamp does nothing), no
    // reversal (the sine is positive: the test above)
    let c = cos_turn;
    ok = ok & c.ge(k(-1.0)) & c.le(k(1.0));
    let s = sin_turn.abs();
    let s = F2::select(k(1.0).lt(s), k(1.0), s);
    let one_plus_c = k(1.0) + c;
    ok = ok & one_plus_c.gt(k(0.0));
    let cos_half = (k(0.5) * one_plus_c).sqrt();
    let tol = both(&|j| j.tol_mm);
    let first = k(2.0 * DEVIATION_SHARE) * tol * cos_half * (k(1.0) + cos_half) / s;
    let line_avail = both(&|j| j.line_avail_mm);
    let d = F2::select(first.lt(line_avail), first, line_avail);
    ok = ok & d.gt(k(1e-9));
    // line_arc_at
    let big_r = both(&|j| j.arc.radius);
    let corner_n = both(&|j| j.corner[N]);
    let (p1a, p1b, p1n) = (corner_a - ua * d, corner_b - ub * d, corner_n - u_n * d);
    let (wa, wb) = (p1a - ca, p1b - cb);
    let wu = wa * ua + wb * ub;
    ok = ok & (wu.lt(k(0.0)) | wu.gt(k(0.0)));
    let sigma = F2::select(wu.lt(k(0.0)), k(1.0), k(-1.0));
    let wn = wa * na + wb * nb;
    let r = (big_r * big_r - (wa * wa + wb * wb)) / (k(2.0) * (wn - sigma * big_r));
    ok = ok & r.lt(k(f64::INFINITY)) & r.gt(k(1e-6));
    let (fa, fb) = (wa + na * r, wb + nb * r);
    let fc_norm = (fa * fa + fb * fb).sqrt();
    let radial_mismatch_mm = (fc_norm - (big_r + sigma * r)).abs();
    let r_or_1 = F2::select(k(1.0).gt(big_r), k(1.0), big_r);
    ok = ok & fc_norm.ge(k(1e-12)) & radial_mismatch_mm.le(k(1e-7) * r_or_1);
    let (da, db) = (pa - fa, pb - fb);
    let deviation = ((da * da + db * db).sqrt() - r).abs();
    ok = ok & deviation.le(k(DEVIATION_SHARE) * tol);
    let q1 = sigma * (fa * na + fb * nb);
    let q2 = -sigma * (fa * ua + fb * ub);
    ok = ok & q2.gt(k(0.0));
    let inv_f = k(1.0) / fc_norm;
    let (cos_sweep, sin_sweep) = (q1 * inv_f, q2 * inv_f);
    let along = ((ua * cos_sweep + na * sin_sweep) * -fb + (ub * cos_sweep + nb * sin_sweep) * fa)
        * (so * inv_f);
    ok = ok & along.ge(k(1.0 - 1e-9));
    let sweep = q2.atan2(q1);
    ok = ok & sweep.gt(k(1e-9)) & sweep.lt(k(PI - 1e-6));
    let ang = ((pa * fb - pb * fa) * so).atan2(pa * fa + pb * fb);
    let arc_trim_rad = F2::select(ang.lt(k(0.0)), ang + k(TAU), ang);
    let arc_trim = arc_trim_rad * big_r;
    ok = ok & arc_trim.gt(k(1e-9)) & arc_trim.le(both(&|j| j.arc_avail_mm));
    let (center_a, center_b) = (ca + fa, cb + fb);
    let scale = big_r * inv_f;
    let (p_arc_a, p_arc_b) = (ca + fa * scale, cb + fb * scale);
    let center_n = both(&|j| j.arc.center[N]);
    // closure_bound_mm
    let bound = radial_mismatch_mm
        + r * u_n.abs()
        + (p1n - center_n).abs()
        + k(100.0 * f64::EPSILON) * (ca.abs() + cb.abs() + wa.abs() + wb.abs() + big_r + r);
    ok = ok & bound.le(k(CLOSURE_SURE_SHARE * FILLET_CLOSURE_MM));
    let bits = ok.bits();
    let lane = |i: usize, x: F2| if i == 0 { x.lanes().0 } else { x.lanes().1 };
    let fillet = |i: usize, j: &LineArcJoin, out: &mut Option<Fillet>| {
        if bits & (1 << i) == 0 {
            *out = line_arc_one(j);
            return;
        }
        let mut p_line = j.corner;
        (p_line[A], p_line[B], p_line[N]) = (lane(i, p1a), lane(i, p1b), lane(i, p1n));
        let mut center = p_line;
        (center[A], center[B]) = (lane(i, center_a), lane(i, center_b));
        let mut p_arc = j.arc.center;
        (p_arc[A], p_arc[B]) = (lane(i, p_arc_a), lane(i, p_arc_b));
        *out = Some(Fillet {
            line_trim: lane(i, d),
            arc_trim: lane(i, arc_trim),
            arc_trim_rad: lane(i, arc_trim_rad),
            center,
            radius: lane(i, r),
            p_line,
            p_arc,
            sweep: lane(i, sweep),
            cos_sweep: lane(i, cos_sweep),
            sin_sweep: lane(i, sin_sweep),
        });
    };
    let [out0, out1] = out;
    fillet(0, j0, out0);
    fillet(1, j1, out1);
}

/// A fillet found by [`line_arc_at`], in the numbers it was built from: the
/// [`Fillet`] ([`Candidate::fillet`]) is written once, where it is kept (not moved
/// through the stack with each test: about 130 bytes).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    /// [`Fillet::line_trim`].
    line_trim: f64,
    /// [`Fillet::arc_trim`].
    arc_trim: f64,
    /// [`Fillet::arc_trim_rad`].
    arc_trim_rad: f64,
    /// [`Fillet::center`] along the plane's axes a and b (its normal component is
    /// `p_line`'s).
    center_ab: (f64, f64),
    /// [`Fillet::radius`].
    radius: f64,
    /// [`Fillet::p_line`].
    p_line: Vec3,
    /// [`Fillet::p_arc`] along a and b (its normal component is the arc centre's).
    p_arc_ab: (f64, f64),
    /// [`Fillet::sweep`].
    sweep: f64,
    /// [`Fillet::cos_sweep`].
    cos_sweep: f64,
    /// [`Fillet::sin_sweep`].
    sin_sweep: f64,
    /// Whether [`closure_bound_mm`] proves that it closes.
    surely: bool,
}

impl Candidate {
    /// The fillet, for an arc in the plane of axes `A`, `B` and normal `N`.
    #[inline(always)]
    fn fillet<const A: usize, const B: usize, const N: usize>(&self, arc: &ArcView) -> Fillet {
        let mut center = self.p_line;
        center[A] = self.center_ab.0;
        center[B] = self.center_ab.1;
        let mut p_arc = arc.center;
        p_arc[A] = self.p_arc_ab.0;
        p_arc[B] = self.p_arc_ab.1;
        p_arc[N] = arc.center[N];
        Fillet {
            line_trim: self.line_trim,
            arc_trim: self.arc_trim,
            arc_trim_rad: self.arc_trim_rad,
            center,
            radius: self.radius,
            p_line: self.p_line,
            p_arc,
            sweep: self.sweep,
            cos_sweep: self.cos_sweep,
            sin_sweep: self.sin_sweep,
        }
    }
}

/// The line–arc fillet leaving the line `d` before the corner ([`line_arc_in`] in
/// the arc's plane coordinates), if it is a real blend within `tol_mm`: n = (`na`,
/// `nb`) the unit normal of u towards the turn, (`pa`, `pb`) the corner from the
/// centre. With w = P₁ − c, F − c = w + r·n. T − F = −σr·(F − c)/|F − c| (to the
/// radial mismatch) turns the fillet forwards (q·u > 0) only for σ·(w·u) < 0, so
/// that tangency alone is built; against e1 = (P₁ − F)/r = −n and e2 = u its
/// direction is σ·((F − c)·n, −(F − c)·u)/|F − c|, which gives the sweep's cosine and
/// sine with one division and its angle (`atan2`, free of scale) without one.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // (the join's arguments, and what line_arc_in worked out)
fn line_arc_at<const A: usize, const B: usize, const N: usize>(
    corner: Vec3,
    u: Vec3,
    d: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
    (na, nb): (f64, f64),
    (pa, pb): (f64, f64),
) -> Option<Candidate> {
    let (ua, ub) = (u[A], u[B]);
    let (ca, cb) = (arc.center[A], arc.center[B]);
    let big_r = arc.radius;
    let p1 = corner - u * d;
    let (wa, wb) = (p1[A] - ca, p1[B] - cb);
    let wu = wa * ua + wb * ub;
    let sigma = if wu < 0.0 {
        1.0
    } else if wu > 0.0 {
        -1.0
    } else {
        return None;
    };
    let wn = wa * na + wb * nb;
    let r = (big_r * big_r - (wa * wa + wb * wb)) / (2.0 * (wn - sigma * big_r));
    if !(r.is_finite() && r > 1e-6) {
        return None;
    }
    // F − c, and T − c = R·(F − c)/|F − c|
    let (fa, fb) = (wa + na * r, wb + nb * r);
    let fc_norm = (fa * fa + fb * fb).sqrt();
    let radial_mismatch_mm = (fc_norm - (big_r + sigma * r)).abs();
    if fc_norm < 1e-12 || radial_mismatch_mm > 1e-7 * max_to(big_r, 1.0) {
        return None;
    }
    // how far the fillet passes from the corner, |C − F| − r, within its share
    let (da, db) = (pa - fa, pb - fb);
    let within = ((da * da + db * db).sqrt() - r).abs() <= DEVIATION_SHARE * tol_mm;
    if !within {
        return None; // (a NaN tolerance too)
    }
    let q1 = sigma * (fa * na + fb * nb);
    let q2 = -sigma * (fa * ua + fb * ub);
    if q2 <= 0.0 {
        return None;
    }
    let inv_f = 1.0 / fc_norm;
    let (cos_sweep, sin_sweep) = (q1 * inv_f, q2 * inv_f);
    // the fillet's end tangent u·cos φ + n·sin φ against the arc's at T,
    // sense·N × (T − c)/R = sense·orient·(−(F − c)_b, (F − c)_a)/|F − c|
    let so = arc.sense * arc.orient;
    let along = ((ua * cos_sweep + na * sin_sweep) * -fb + (ub * cos_sweep + nb * sin_sweep) * fa)
        * (so * inv_f);
    if along < 1.0 - 1e-9 {
        return None;
    }
    let sweep = atan2(q2, q1);
    if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
        return None;
    }
    // the arc's angle from C to T in its direction of travel, in [0, 2π)
    let ang = atan2((pa * fb - pb * fa) * so, pa * fa + pb * fb);
    let arc_trim_rad = if ang < 0.0 {
        ang + std::f64::consts::TAU
    } else {
        ang
    };
    let arc_trim = arc_trim_rad * big_r;
    if !(arc_trim > 1e-9 && arc_trim <= arc_avail) {
        return None;
    }
    let scale = big_r * inv_f;
    let surely = closure_bound_mm(
        radial_mismatch_mm,
        r,
        u[N].abs(),
        (p1[N] - arc.center[N]).abs(),
        ca.abs() + cb.abs() + wa.abs() + wb.abs() + big_r,
    ) <= CLOSURE_SURE_SHARE * FILLET_CLOSURE_MM;
    Some(Candidate {
        line_trim: d,
        arc_trim,
        arc_trim_rad,
        center_ab: (ca + fa, cb + fb),
        radius: r,
        p_line: p1,
        p_arc_ab: (ca + fa * scale, cb + fb * scale),
        sweep,
        cos_sweep,
        sin_sweep,
        surely,
    })
}

/// Share of [`FILLET_CLOSURE_MM`] below which [`closure_bound_mm`] proves a
/// line–arc fillet closes without measuring it ([`closes`]): a quarter, a margin of
/// four over the bound's own constants.
const CLOSURE_SURE_SHARE: f64 = 0.25;

/// An upper bound (mm) on how far a line–arc fillet built by `line_arc_at` ends from
/// where it should, either way it is laid ([`closes`]), from what its construction
/// leaves: the radial mismatch |‖F − c‖ − (R ± r)| it accepted (the fillet's end is
/// the point at r from F towards T, T at ‖T − F‖ = r ± that from F), r·|u_N| and
/// |P₁_N − c_N| off the arc's plane, and 100 ε of the coordinates', the radii's and
/// the fillet's own magnitudes for the rounding of the few tens of operations
/// between (n is exactly ⟂ u: no term for a skewed pair −n, u).
#[inline(always)]
fn closure_bound_mm(
    radial_mismatch_mm: f64,
    r_mm: f64,
    u_normal: f64,
    p1_off_plane_mm: f64,
    magnitudes_mm: f64,
) -> f64 {
    radial_mismatch_mm
        + r_mm * u_normal
        + p1_off_plane_mm
        + 100.0 * f64::EPSILON * (magnitudes_mm + r_mm)
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

/// Whether fillet `f`, leaving the line along `u`, ends as its element runs it
/// (`Geom::Blend`: F + e1·r·cos φ + e2·r·sin φ) within `FILLET_CLOSURE_MM` of where
/// it should, either way the builder lays it (`PathBuilder::circle_blend`): line →
/// arc from P₁ with e1 = (P₁ − F)/r, e2 = u to T; arc → line (the construction on the
/// path run backwards) from T with e1 = (T − F)/r, e2 = −(u·cos φ − (P₁ − F)/r·sin φ)
/// to P₁.
/// The distances are compared squared (no roots: about a fifth of a fillet's cost
/// otherwise); they differ from `norm() <= FILLET_CLOSURE_MM` only within rounding
/// of the bound itself.
#[inline(always)]
fn closes(f: &Fillet, u: Vec3) -> bool {
    let (r, c, s) = (f.radius, f.cos_sweep, f.sin_sweep);
    let inv_r = 1.0 / r;
    let e1 = (f.p_line - f.center) * inv_r;
    let end = f.center + e1 * (r * c) + u * (r * s);
    let e1_back = (f.p_arc - f.center) * inv_r;
    let e2_back = -(u * c - e1 * s);
    let start = f.center + e1_back * (r * c) + e2_back * (r * s);
    let (gap_end, gap_start) = (end - f.p_arc, start - f.p_line);
    let bound_sq = FILLET_CLOSURE_MM * FILLET_CLOSURE_MM;
    gap_end.dot(gap_end) <= bound_sq && gap_start.dot(gap_start) <= bound_sq
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

/// `atan2(y, x)` as fdlibm computes it (Sun Microsystems 1993, `e_atan2.c` and
/// `s_atan.c`, as musl and Rust's `libm` crate keep them: error below 1 ulp), inline:
/// the fillets take two angles per corner, and the system library's `atan2` (glibc,
/// correctly rounded) cost about 150 instructions a call on the 200k-line benchmark.
/// Non-finite arguments go to the library.
#[inline(always)]
fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    /// The low part of π (π − `PI`).
    const PI_LO: f64 = 1.2246467991473532e-16;
    if !(x.is_finite() && y.is_finite()) {
        return atan2_not_finite(y, x);
    }
    if y == 0.0 {
        return if x.is_sign_negative() {
            PI.copysign(y)
        } else {
            y
        };
    }
    if x == 0.0 {
        return FRAC_PI_2.copysign(y);
    }
    let (ay, ax) = (y.abs(), x.abs());
    // |y/x| beyond 2⁶⁰ is π/2 to the last bit; below 2⁻⁶⁰ behind a negative x, 0
    let z = if ay > ax * 1.152_921_504_606_847e18 {
        FRAC_PI_2 + 0.5 * PI_LO
    } else if x < 0.0 && ay * 1.152_921_504_606_847e18 < ax {
        0.0
    } else {
        atan_nonneg(ay / ax)
    };
    match (x < 0.0, y < 0.0) {
        (false, false) => z,
        (false, true) => -z,
        (true, false) => PI - (z - PI_LO),
        (true, true) => (z - PI_LO) - PI,
    }
}

/// [`atan2`] of two pairs of arguments at once (`y.0`, `x.0`) and (`y.1`, `x.1`):
/// [`lanes::F2::atan2`] (the test of the two-lane `atan2` against the scalar one).
#[cfg(test)]
fn atan2_2(y: (f64, f64), x: (f64, f64)) -> (f64, f64) {
    lanes::F2::new(y.0, y.1)
        .atan2(lanes::F2::new(x.0, x.1))
        .lanes()
}

/// The rows of [`lanes::F2::atan2`]'s reduction, by how many of 7/16, 11/16, 19/16
/// and 39/16 the ratio reaches: `a` and `b` of (x·a − b)/(a + x·b), which is x itself
/// (a = 1, b = 0: x·1 − 0 and 1 + x·0 are exact), fdlibm's (2x − 1)/(2 + x),
/// (x − 1)/(x + 1), (x − 1.5)/(1 + 1.5x) and −1/x (a = 0: x·0 − 1 = −1 and 0 + x = x,
/// x finite and positive); then atan's high and low parts at the reference point
/// (zero for the row without reduction: 0 − ((x·s − 0) − x) = x − x·s exactly, the
/// negation being exact).
const ATAN_ROWS: [[f64; 4]; 5] = [
    [1.0, 0.0, 0.0, 0.0],
    [2.0, 1.0, ATAN_HI[0], ATAN_LO[0]],
    [1.0, 1.0, ATAN_HI[1], ATAN_LO[1]],
    [1.0, 1.5, ATAN_HI[2], ATAN_LO[2]],
    [0.0, 1.0, ATAN_HI[3], ATAN_LO[3]],
];

/// Two doubles side by side, one per lane, and the arithmetic [`line_arc_2`] needs
/// on them: plain `f64` operations lane by lane, so each lane gives the bits the same
/// computation on `f64` gives (IEEE 754 add, subtract, multiply, divide and square
/// root, correctly rounded; a sign flip and an absolute value on the sign bit). The
/// two lanes' instructions come interleaved, so the processor overlaps the two chains
/// of roots and divisions (where the compiler does not pair them into two-double
/// registers itself). Safe code: no intrinsics (`unsafe` is kept for IPC).
mod lanes {
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};

    /// Two doubles (lane 0, lane 1).
    #[derive(Clone, Copy)]
    pub(super) struct F2([f64; 2]);

    /// A comparison's outcome in each lane: all ones where it holds, else zero (as
    /// the processor's packed comparisons give it, so that the compiler can use them).
    #[derive(Clone, Copy)]
    pub(super) struct M2([u64; 2]);

    /// All ones where `holds`.
    #[inline(always)]
    fn mask(holds: bool) -> u64 {
        u64::from(holds).wrapping_neg()
    }

    /// `f` of each lane.
    #[inline(always)]
    fn each(a: F2, f: impl Fn(f64) -> f64) -> F2 {
        F2([f(a.0[0]), f(a.0[1])])
    }

    /// `f` of each pair of lanes.
    #[inline(always)]
    fn both(a: F2, b: F2, f: impl Fn(f64, f64) -> f64) -> F2 {
        F2([f(a.0[0], b.0[0]), f(a.0[1], b.0[1])])
    }

    /// `f` of each pair of lanes, a comparison.
    #[inline(always)]
    fn test(a: F2, b: F2, f: impl Fn(f64, f64) -> bool) -> M2 {
        M2([mask(f(a.0[0], b.0[0])), mask(f(a.0[1], b.0[1]))])
    }

    impl F2 {
        #[inline(always)]
        pub(super) fn new(lane0: f64, lane1: f64) -> F2 {
            F2([lane0, lane1])
        }
        #[inline(always)]
        pub(super) fn splat(x: f64) -> F2 {
            F2([x, x])
        }
        /// (lane 0, lane 1).
        #[inline(always)]
        pub(super) fn lanes(self) -> (f64, f64) {
            (self.0[0], self.0[1])
        }
        #[inline(always)]
        pub(super) fn sqrt(self) -> F2 {
            each(self, f64::sqrt)
        }
        /// `f64::abs` (the sign bit cleared).
        #[inline(always)]
        pub(super) fn abs(self) -> F2 {
            each(self, f64::abs)
        }
        #[inline(always)]
        pub(super) fn lt(self, o: F2) -> M2 {
            test(self, o, |a, b| a < b)
        }
        #[inline(always)]
        pub(super) fn le(self, o: F2) -> M2 {
            test(self, o, |a, b| a <= b)
        }
        #[inline(always)]
        pub(super) fn gt(self, o: F2) -> M2 {
            test(self, o, |a, b| a > b)
        }
        #[inline(always)]
        pub(super) fn ge(self, o: F2) -> M2 {
            test(self, o, |a, b| a >= b)
        }
        /// `if m { a } else { b }`, lane by lane.
        #[inline(always)]
        pub(super) fn select(m: M2, a: F2, b: F2) -> F2 {
            let pick =
                |m: u64, a: f64, b: f64| f64::from_bits((m & a.to_bits()) | (!m & b.to_bits()));
            F2([pick(m.0[0], a.0[0], b.0[0]), pick(m.0[1], a.0[1], b.0[1])])
        }

        /// [`super::atan2`]`(self, x)` lane by lane: the operations of
        /// [`super::atan2`] and [`super::atan_nonneg`] in their order, so the same
        /// bits. Where `atan_nonneg` branches on the reduced argument, each lane
        /// picks its row of [`super::ATAN_ROWS`]; the quadrant is a mask and the sign
        /// of y. A pair that leaves fdlibm's main path in either lane (an argument
        /// zero or not finite, |y/x| beyond 2⁶⁰ either way or below 2⁻²⁸) goes
        /// through [`super::atan2`] one lane after the other.
        #[inline(always)]
        pub(super) fn atan2(self, x: F2) -> F2 {
            use super::{ATAN_POLY, ATAN_ROWS};
            use std::f64::consts::PI;
            /// |y/x| beyond which fdlibm's `atan2` takes no ratio (2⁶⁰).
            const TWO_60: f64 = 1.152_921_504_606_847e18;
            /// The low part of π (π − `PI`), as [`super::atan2`]'s.
            const PI_LO: f64 = 1.2246467991473532e-16;
            /// Below this ratio (2⁻²⁸) `atan_nonneg` gives the ratio itself.
            const TINY: f64 = 3.725290298461914e-09;
            /// fdlibm's reduction bounds (7/16, 11/16, 19/16, 39/16).
            const BOUNDS: [f64; 4] = [0.4375, 0.6875, 1.1875, 2.4375];
            let y = self;
            let (ay, ax) = (y.abs(), x.abs());
            let (inf, zero, two_60) = (F2::splat(f64::INFINITY), F2::splat(0.0), F2::splat(TWO_60));
            // fdlibm's main path: both finite and non-zero, not |y| > |x|·2⁶⁰, and
            // not (x < 0 and |y|·2⁶⁰ < |x|) (NaN fails every comparison)
            let main = ay.lt(inf) & ax.lt(inf) & ay.gt(zero) & ax.gt(zero);
            let main = main & ay.le(ax * two_60) & (x.gt(zero) | (ay * two_60).ge(ax));
            let r = ay / ax;
            let main = main & r.ge(F2::splat(TINY));
            if main.bits() != 0b11 {
                return apart(y, x);
            }
            // each lane's row: how many of the bounds its ratio reaches
            let row = |v: f64| &ATAN_ROWS[BOUNDS.iter().filter(|&&b| v >= b).count()];
            let (row0, row1) = (row(r.0[0]), row(r.0[1]));
            let (a, b) = (F2([row0[0], row1[0]]), F2([row0[1], row1[1]]));
            let (hi, lo) = (F2([row0[2], row1[2]]), F2([row0[3], row1[3]]));
            let t = (r * a - b) / (a + r * b);
            // atan_nonneg's polynomial, its operations in its order
            let c = |i: usize| F2::splat(ATAN_POLY[i]);
            let z = t * t;
            let w = z * z;
            let mut s1 = c(8) + w * c(10);
            for i in [6, 4, 2, 0] {
                s1 = c(i) + w * s1;
            }
            let s1 = z * s1;
            let mut s2 = c(7) + w * c(9);
            for i in [5, 3, 1] {
                s2 = c(i) + w * s2;
            }
            let s2 = w * s2;
            let at = hi - ((t * (s1 + s2) - lo) - t);
            // the quadrant: π − (z − π_lo) behind a negative x, then y's sign
            // ((z − π_lo) − π is the negation of π − (z − π_lo), exactly)
            let turned = F2::splat(PI) - (at - F2::splat(PI_LO));
            let v = F2::select(x.lt(zero), turned, at);
            both(v, y, |v, y| v.copysign(y))
        }
    }

    /// [`F2::atan2`] for a pair off fdlibm's main path: one [`super::atan2`] after
    /// the other.
    #[cold]
    #[inline(never)]
    fn apart(y: F2, x: F2) -> F2 {
        let ((y0, y1), (x0, x1)) = (y.lanes(), x.lanes());
        F2::new(super::atan2(y0, x0), super::atan2(y1, x1))
    }

    impl M2 {
        /// Lane 0 in bit 0, lane 1 in bit 1.
        #[inline(always)]
        pub(super) fn bits(self) -> i32 {
            (self.0[0] & 1) as i32 | (((self.0[1] & 1) as i32) << 1)
        }
    }

    impl BitAnd for M2 {
        type Output = M2;
        #[inline(always)]
        fn bitand(self, o: M2) -> M2 {
            M2([self.0[0] & o.0[0], self.0[1] & o.0[1]])
        }
    }

    impl BitOr for M2 {
        type Output = M2;
        #[inline(always)]
        fn bitor(self, o: M2) -> M2 {
            M2([self.0[0] | o.0[0], self.0[1] | o.0[1]])
        }
    }

    impl Add for F2 {
        type Output = F2;
        #[inline(always)]
        fn add(self, o: F2) -> F2 {
            both(self, o, |a, b| a + b)
        }
    }

    impl Sub for F2 {
        type Output = F2;
        #[inline(always)]
        fn sub(self, o: F2) -> F2 {
            both(self, o, |a, b| a - b)
        }
    }

    impl Mul for F2 {
        type Output = F2;
        #[inline(always)]
        fn mul(self, o: F2) -> F2 {
            both(self, o, |a, b| a * b)
        }
    }

    impl Div for F2 {
        type Output = F2;
        #[inline(always)]
        fn div(self, o: F2) -> F2 {
            both(self, o, |a, b| a / b)
        }
    }

    impl Neg for F2 {
        type Output = F2;
        /// The sign bit flipped, as `-x` on an `f64`.
        #[inline(always)]
        fn neg(self) -> F2 {
            each(self, |a| -a)
        }
    }
}

/// The system library's `atan2(y, x)`, for [`atan2`]'s non-finite arguments: out of
/// line and cold, so that the registers the call clobbers are not saved on the way
/// to every inline `atan2`.
#[cold]
#[inline(never)]
fn atan2_not_finite(y: f64, x: f64) -> f64 {
    y.atan2(x)
}

/// atan(0.5), atan(1), atan(1.5), atan(∞): high parts.
const ATAN_HI: [f64; 4] = [
    0.4636476090008061,
    std::f64::consts::FRAC_PI_4,
    0.982793723247329,
    std::f64::consts::FRAC_PI_2,
];
/// Their low parts.
const ATAN_LO: [f64; 4] = [
    2.2698777452961687e-17,
    3.061616997868383e-17,
    1.3903311031230998e-17,
    6.123233995736766e-17,
];
/// atan(x) = x − x·(x²·(T0 + x⁴(T2 + …)) + x⁴(T1 + x⁴(T3 + …))) on |x| < 7/16.
const ATAN_POLY: [f64; 11] = [
    0.3333333333333293,
    -0.19999999999876483,
    0.14285714272503466,
    -0.11111110405462356,
    0.09090887133436507,
    -0.0769187620504483,
    0.06661073137387531,
    -0.058335701337905735,
    0.049768779946159324,
    -0.036531572744216916,
    0.016285820115365782,
];

/// fdlibm's `atan(x)` for finite x ≥ 0: reduced about 0.5, 1 or 1.5 (or by 1/x) to
/// |x| < 7/16, then an odd polynomial of degree 23 (`ATAN_POLY`) and the reference
/// angle in two parts (`ATAN_HI`, `ATAN_LO`).
#[inline(always)]
fn atan_nonneg(x: f64) -> f64 {
    let (id, x) = if x < 0.4375 {
        if x < 3.725290298461914e-09 {
            return x; // below 2⁻²⁸: atan(x) = x to the last bit
        }
        (None, x)
    } else if x < 0.6875 {
        (Some(0), (2.0 * x - 1.0) / (2.0 + x))
    } else if x < 1.1875 {
        (Some(1), (x - 1.0) / (x + 1.0))
    } else if x < 2.4375 {
        (Some(2), (x - 1.5) / (1.0 + 1.5 * x))
    } else {
        (Some(3), -1.0 / x)
    };
    let t = &ATAN_POLY;
    let z = x * x;
    let w = z * z;
    let s1 = z * (t[0] + w * (t[2] + w * (t[4] + w * (t[6] + w * (t[8] + w * t[10])))));
    let s2 = w * (t[1] + w * (t[3] + w * (t[5] + w * (t[7] + w * t[9]))));
    match id {
        None => x - x * (s1 + s2),
        Some(i) => ATAN_HI[i] - ((x * (s1 + s2) - ATAN_LO[i]) - x),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `atan2_2` gives, lane by lane, the bits of `atan2` (the scalar fdlibm code,
    /// as at 557cc9e but for its non-finite arguments going to the library out of
    /// line): on random angles and radii in every quadrant, on ratios a few units in
    /// the last place either side of each reduction bound, of 2⁻²⁸ and of 2⁶⁰, on
    /// arguments of random bits and of extreme values (zero, subnormal, huge,
    /// infinite, NaN), and on pairs that mix those in their lanes.
    #[test]
    fn atan2_2_is_atan2_lane_by_lane() {
        let mut state = 0x0a7a_2b17_u64;
        let mut next = move || {
            // SplitMix64
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        };
        let unit = |b: u64| (b >> 11) as f64 / (1u64 << 53) as f64;
        let mut args: Vec<(f64, f64)> = Vec::new();
        let n = if cfg!(debug_assertions) {
            20_000
        } else {
            400_000
        };
        for _ in 0..n {
            let th = std::f64::consts::PI * (2.0 * unit(next()) - 1.0);
            let r = (unit(next()) * 40.0 - 20.0).exp();
            args.push((r * th.sin(), r * th.cos()));
            args.push((f64::from_bits(next()), f64::from_bits(next())));
        }
        let bounds: [f64; 8] = [
            0.4375,
            0.6875,
            1.1875,
            2.4375,
            3.725290298461914e-09,
            1.152_921_504_606_847e18,
            1.0 / 1.152_921_504_606_847e18,
            1.0,
        ];
        for b in bounds {
            for ulps in -40i64..=40 {
                let ratio = f64::from_bits((b.to_bits() as i64 + ulps) as u64);
                for scale in [1.0, 3.0, 1e-7, 1e9] {
                    for (sy, sx) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                        args.push((sy * ratio * scale, sx * scale));
                        args.push((sy * scale, sx * scale / ratio));
                    }
                }
            }
        }
        let edges = [
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            5e-324,
            -5e-324,
            f64::MIN_POSITIVE,
            f64::MAX,
            -f64::MAX,
            1.0,
            -1.0,
            1e-300,
            1e300,
        ];
        for &y in &edges {
            for &x in &edges {
                args.push((y, x));
            }
        }
        let mut main_pairs = 0;
        for (k, &(y0, x0)) in args.iter().enumerate() {
            // each with its neighbour, the next one on, and itself
            for &(y1, x1) in [
                args[(k + 1) % args.len()],
                args[(k * 7 + 3) % args.len()],
                (y0, x0),
            ]
            .iter()
            {
                let (g0, g1) = atan2_2((y0, y1), (x0, x1));
                let (w0, w1) = (atan2(y0, x0), atan2(y1, x1));
                assert_eq!(
                    (g0.to_bits(), g1.to_bits()),
                    (w0.to_bits(), w1.to_bits()),
                    "atan2_2(({y0:e}, {y1:e}), ({x0:e}, {x1:e})) = ({g0:e}, {g1:e}), atan2 ({w0:e}, {w1:e})"
                );
                main_pairs += usize::from(g0.is_finite() && g1.is_finite());
            }
        }
        assert!(main_pairs > args.len());
    }

    /// The inline `atan2` agrees with the system library's within 2 ulp over every
    /// quadrant, the axes, the reduction intervals' ends and tiny and huge ratios.
    #[test]
    fn atan2_is_the_library_atan2() {
        let mut worst = 0.0f64;
        let mut check = |y: f64, x: f64| {
            let (got, want) = (atan2(y, x), y.atan2(x));
            let err = (got - want).abs() / (f64::EPSILON * want.abs().max(f64::MIN_POSITIVE));
            assert!(err <= 2.0, "atan2({y}, {x}) = {got}, library {want}");
            worst = worst.max(err);
        };
        for k in 0..200_000 {
            let th = -std::f64::consts::PI + std::f64::consts::TAU * (k as f64 + 0.37) / 200_000.0;
            for r in [1e-3, 0.25, 1.0, 7.5, 3e4] {
                check(r * th.sin(), r * th.cos());
            }
        }
        for ratio in [
            0.0, 1e-300, 1e-20, 3e-9, 0.4375, 0.6875, 1.1875, 2.4375, 1.0, 0.5, 1.5, 1e10, 1e20,
            1e300,
        ] {
            for (sy, sx) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                check(sy * ratio, sx * 1.0);
                check(sy * 1.0, sx * ratio);
            }
        }
        assert_eq!(atan2(0.0, -1.0), std::f64::consts::PI);
        assert_eq!(atan2(1.0, 0.0), std::f64::consts::FRAC_PI_2);
        assert!(worst > 0.0); // (not all exact: the test compares something)
    }
}
