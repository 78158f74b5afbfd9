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

use crate::build::dist_to_segment;
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
    #[inline]
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
fn fillet_if_closes<const A: usize, const B: usize, const N: usize>(
    c: &Candidate,
    arc: &ArcView,
    u: Vec3,
) -> Option<Fillet> {
    let f = c.fillet::<A, B, N>(arc);
    closes(&f, u).then_some(f)
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
    let sweep = libm::atan2(q2, q1);
    if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
        return None;
    }
    // the arc's angle from C to T in its direction of travel, in [0, 2π)
    let ang = libm::atan2((pa * fb - pb * fa) * so, pa * fa + pb * fb);
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
/// `after(d)` d mm after it, the largest d found trying down by 0.7 from the
/// smallest of `before_avail`, `after_avail` and — for a turn θ ≤
/// [`SMALL_TURN_RAD`] — the trim a circular blend of that turn takes at 0.9·`tol_mm`
/// from the corner, 0.9·`tol_mm`/tan(θ/4); else (or if none is found) from
/// 0.9·`tol_mm`.
///
/// Construction (the equal-tangent-length biarc of Bolton, "Biarc curves", CAD 7(2),
/// 1975): with ends P₀, P₁ and unit tangents T₀, T₁, the control points Q₀ = P₀ + αT₀
/// and Q₁ = P₁ − αT₁ must lie 2α apart, |V − α(T₀ + T₁)| = 2α with V = P₁ − P₀:
/// 2(T₀·T₁ − 1)α² − 2(V·(T₀ + T₁))α + V·V = 0, whose positive root gives the join
/// point J = (Q₀ + Q₁)/2 with tangent (Q₁ − Q₀)/2α; each half is the circle arc from
/// its end along its tangent through J. Every point of the blend lies within
/// 0.9·`tol_mm` of the programmed path: of the corner (its largest distance from
/// the corner, computed per arc, which bounds it) or else of the moves' pieces it
/// replaces ([`path_deviation`]). The corner alone kept every trim under the
/// tolerance: the blend of a 1.6° kink between CAM arcs within 0.2 µm had a
/// radius of 0.02 mm and passed at 3 mm/s, where its tolerance allows the feed.
pub fn biarc(
    corner: Vec3,
    before: impl Fn(f64) -> (Vec3, Vec3),
    before_avail: f64,
    after: impl Fn(f64) -> (Vec3, Vec3),
    after_avail: f64,
    tol_mm: f64,
) -> Option<Biarc> {
    let avail = before_avail.min(after_avail);
    let turn_rad = before(0.0).1.dot(after(0.0).1).clamp(-1.0, 1.0).acos();
    let by_turn = DEVIATION_SHARE * tol_mm / (0.25 * turn_rad).tan();
    let small = turn_rad <= SMALL_TURN_RAD;
    small
        .then(|| biarc_from(corner, &before, &after, avail.min(by_turn), tol_mm))
        .flatten()
        .or_else(|| {
            biarc_from(
                corner,
                &before,
                &after,
                avail.min(DEVIATION_SHARE * tol_mm),
                tol_mm,
            )
        })
}

/// Turns up to this (10°) are blended by their distance from the path
/// ([`path_deviation`]); larger ones by their distance from the corner alone (from
/// the path their blends grew past LinuxCNC's deviation: docs/perf-log/planner-36.md).
pub const SMALL_TURN_RAD: f64 = std::f64::consts::PI / 18.0;
/// Chords each move's piece next to a corner is cut into for [`path_deviation`].
const PATH_CHORDS: usize = 12;
/// Points of each biarc piece [`path_deviation`] measures.
const BLEND_POINTS: usize = 6;

/// The largest distance of the biarc `arcs` from the programmed path it replaces:
/// the move before over its last `d` mm, the move after over its first `d` mm, each
/// cut into [`PATH_CHORDS`] chords, plus the largest chord's sagitta (|Δt|·length/8
/// of a circular piece), so that it bounds the distance to the path itself.
/// Allocation-free.
fn path_deviation(
    arcs: &[ArcPiece; 2],
    before: &impl Fn(f64) -> (Vec3, Vec3),
    after: &impl Fn(f64) -> (Vec3, Vec3),
    d: f64,
) -> f64 {
    let mut pts = [(Vec3::ZERO, Vec3::ZERO); 2 * PATH_CHORDS + 1];
    let step = d / PATH_CHORDS as f64;
    for (k, p) in pts.iter_mut().enumerate() {
        *p = if k <= PATH_CHORDS {
            before(step * (PATH_CHORDS - k) as f64)
        } else {
            after(step * (k - PATH_CHORDS) as f64)
        };
    }
    let mut sagitta = 0.0f64;
    for w in pts.windows(2) {
        sagitta = sagitta.max((w[1].0 - w[0].0).norm() * (w[1].1 - w[0].1).norm() / 8.0);
    }
    let mut dev = 0.0f64;
    for a in arcs {
        for j in 0..=BLEND_POINTS {
            let q = a.point(a.sweep * j as f64 / BLEND_POINTS as f64);
            let mut nearest = f64::INFINITY;
            for w in pts.windows(2) {
                nearest = nearest.min(dist_to_segment(q, w[0].0, w[1].0));
            }
            dev = dev.max(nearest);
        }
    }
    dev + sagitta
}

/// [`biarc`]'s search from the trim `d` down.
fn biarc_from(
    corner: Vec3,
    before: &impl Fn(f64) -> (Vec3, Vec3),
    after: &impl Fn(f64) -> (Vec3, Vec3),
    mut d: f64,
    tol_mm: f64,
) -> Option<Biarc> {
    for _ in 0..TRIM_TRIES {
        if d.is_nan() || d <= 1e-9 {
            return None;
        }
        let ((p0, t0), (p1, t1)) = (before(d), after(d));
        if let Some(arcs) = biarc_pieces(p0, t0, p1, t1) {
            let bound = DEVIATION_SHARE * tol_mm;
            let near_corner = arcs[0]
                .farthest_from(corner)
                .max(arcs[1].farthest_from(corner))
                <= bound;
            if near_corner || path_deviation(&arcs, before, after, d) <= bound {
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
