//! Path elements the planner follows: programmed lines and arcs, and the 3-D blend
//! arcs it inserts at corners; each with its per-axis limits folded into path limits.

use softnc_core::{Plane, Primitive, Vec3};

/// Share of an axis's acceleration a curved element may spend along the path; the
/// rest goes to centripetal acceleration, with `ARC_TANGENTIAL_SHARE² +
/// ARC_NORMAL_SHARE² = 1` so that |t_i·a_t + n_i·a_n| ≤ A_i on every axis.
pub const ARC_TANGENTIAL_SHARE: f64 = 0.5;
/// Share of an axis's acceleration a curved element may spend on centripetal acceleration.
pub const ARC_NORMAL_SHARE: f64 = 0.866_025_403_784_438_6;

/// [`ElementShape::sub_arc`]: the largest change of radius along a sub-arc, relative
/// to R·|φ| (its length), that is taken for rounding of its end point and planned as
/// a circle; the speed it leaves out is at most this share (the spiral's radial drift
/// |ΔR|/(R·|φ|), `spiral_weights`). Rounding of a touch point computed on the circle
/// is a few ulps of its coordinates: 1e-13 mm at 300 mm, 4e-13 of a quarter circle of
/// 0.25 mm.
pub const SUB_ARC_SNAP_REL: f64 = 1e-12;

/// `acc.min(x)` where `acc` is never NaN (a limit, a bound, a running minimum): the
/// same value bit for bit, a NaN `x` included (it leaves `acc`), since `f64::min` is
/// `x < acc ? x : acc` unless `acc` itself is NaN. Written out it is one `minsd`;
/// `f64::min` adds six instructions for a NaN `acc` on SSE2, about twenty times per
/// element on the planning thread.
pub(crate) fn min_to(acc: f64, x: f64) -> f64 {
    if x < acc {
        x
    } else {
        acc
    }
}

/// `acc.max(x)` where `acc` is never NaN: [`min_to`]'s counterpart (one `maxsd`).
pub(crate) fn max_to(acc: f64, x: f64) -> f64 {
    if x > acc {
        x
    } else {
        acc
    }
}

/// Geometry of one path element, machine coordinates (mm).
///
/// The tag is a whole word (`repr(u64)`): with the default layout it was one byte
/// followed by seven of padding, and LLVM copied a `Geom` built on the stack (a
/// blend arc or a cut line pushed onto the path) in 16-byte moves at odd offsets
/// whose loads waited on the narrower stores just before them (a store that cannot
/// be forwarded): the hottest samples of the builder's `emit` and
/// `push_blend_piece`. A `Geom` is 8 bytes longer (120).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(u64)]
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
/// ends, and per-axis weights w_i = max over the element of |t_i| (velocity; exact
/// over the swept part of arcs, so that a short arc along a diagonal runs at the
/// diagonal's speed, not the slowest axis's) and ≥ max of
/// √(t_i² + n_i²) (acceleration): how much of the path motion axis i carries.
#[derive(Debug, Clone, Copy)]
pub struct ElementShape {
    /// Arc length (mm).
    pub len: f64,
    /// Unit tangent at the start; on a spiral (an arc whose end radius differs from
    /// its start radius) dp/ds, the path's velocity per unit of planned speed there.
    pub start_tangent: Vec3,
    /// Unit tangent at the end; dp/ds on a spiral.
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
        Self::arc_snapped(p, false)
    }

    /// A planar sub-arc that fillets cut from a circle (`build::sub_arc_by_angles`):
    /// [`ElementShape::arc`], except that an end radius off the start's by no more
    /// than rounding (|ΔR| ≤ `SUB_ARC_SNAP_REL`·R·|φ|, the end point being the
    /// fillet's touch point computed on the circle) is taken as the start's: a
    /// circle's weights and tangents, not [`spiral_weights`]' (about 400 → 270
    /// instructions a sub-arc). The spiral's radial drift |ΔR|/(R·|φ|) it leaves out
    /// is then at most `SUB_ARC_SNAP_REL` of the speed.
    ///
    /// Inline (into the builder's `emit`): planning thread −0.8 M on the 200k-line
    /// program.
    #[inline]
    pub fn sub_arc(p: &Primitive) -> ElementShape {
        Self::arc_snapped(p, true)
    }

    /// [`ElementShape::arc`]; with `snap` [`ElementShape::sub_arc`]: [`arc_in`] with
    /// the plane's axes as constants.
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn arc_snapped(p: &Primitive, snap: bool) -> ElementShape {
        match p {
            Primitive::Arc {
                plane: Plane::XY, ..
            } => Self::arc_in::<0, 1, 2>(p, snap),
            Primitive::Arc {
                plane: Plane::XZ, ..
            } => Self::arc_in::<2, 0, 1>(p, snap),
            Primitive::Arc {
                plane: Plane::YZ, ..
            } => Self::arc_in::<1, 2, 0>(p, snap),
            Primitive::Line { .. } => {
                let (s, e) = (p.start(), p.end());
                let d = e - s;
                ElementShape::line(d.norm(), d.unit())
            }
        }
    }

    /// [`ElementShape::arc_snapped`] of an arc in the plane whose axes
    /// ([`Plane::axes`]) are `A`, `B` and the normal `N`: the same arithmetic, with
    /// the components picked at compile time (no addresses worked out and no
    /// vectors kept in memory to be indexed: about a third fewer instructions).
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn arc_in<const A: usize, const B: usize, const N: usize>(
        p: &Primitive,
        snap: bool,
    ) -> ElementShape {
        let Primitive::Arc {
            start,
            center,
            radius,
            start_angle,
            sweep,
            normal_travel,
            end,
            ..
        } = *p
        else {
            let (s, e) = (p.start(), p.end());
            let d = e - s;
            return ElementShape::line(d.norm(), d.unit());
        };
        let (a, b, n) = (A, B, N);
        let rs = radius * sweep;
        // `Primitive::length` of the arc, inline (its call, about 15 instructions a
        // sub-arc with the call's set-up, gives the same bits)
        let len = Primitive::arc_length(rs, normal_travel);
        // tangent = (R·sweep·(−sin θ, cos θ), h) normalised, θ the radial angle
        let mut ts = Vec3::ZERO;
        ts[a] = -sweep * (start[b] - center[b]);
        ts[b] = sweep * (start[a] - center[a]);
        ts[n] = normal_travel;
        let (ea, eb) = (end[a] - center[a], end[b] - center[b]);
        let mut re = (ea * ea + eb * eb).sqrt();
        if snap && normal_travel == 0.0 && (re - radius).abs() <= SUB_ARC_SNAP_REL * rs.abs() {
            re = radius;
        }
        let (cos_e, sin_e) = if re > 1e-12 * max_to(radius, 1.0) {
            (ea / re, eb / re)
        } else {
            let th = start_angle + sweep;
            (th.cos(), th.sin())
        };
        let mut te = Vec3::ZERO;
        te[a] = -rs * sin_e;
        te[b] = rs * cos_e;
        te[n] = normal_travel;
        let is_spiral = re != radius && radius > 0.0;
        if is_spiral {
            // a spiral (`spiral_weights`): its true tangents, (ΔR·cos θ − r·φ·sin θ,
            // ΔR·sin θ + r·φ·cos θ, h) at r = R₀ and r = R₁, not its circle's; a
            // junction between spirals the circles would call tangent breaks by
            // about ΔR/(R·φ) (2.7× A on the samples with the circles' tangents)
            let d_radius = re - radius;
            ts[a] += d_radius * (start[a] - center[a]) / radius;
            ts[b] += d_radius * (start[b] - center[b]) / radius;
            let re_phi = re * sweep;
            te[a] = d_radius * cos_e - re_phi * sin_e;
            te[b] = d_radius * sin_e + re_phi * cos_e;
        }
        let l = max_to(len, f64::MIN_POSITIVE);
        // (in the plane, l = |rs|: the divisions would give exactly 1 and 0)
        let (horiz, vert) = if normal_travel == 0.0 && l == rs.abs() {
            (1.0, 0.0)
        } else {
            (rs.abs() / l, normal_travel.abs() / l)
        };
        // the largest |t_a| and |t_b| over the sweep: t ∝ (−sin θ, cos θ), so
        // |t_a| peaks (at 1) where cos θ changes sign, |t_b| where sin θ does; a sweep
        // shorter than π passes each at most once, so the signs at the ends tell
        let (cos_s, sin_s) = (
            (start[a] - center[a]) / radius,
            (start[b] - center[b]) / radius,
        );
        let short = sweep.abs() < std::f64::consts::PI && radius > 0.0;
        let peak = |u0: f64, u1: f64, v0: f64, v1: f64| {
            if short && u0 * u1 > 0.0 {
                min_to(1.0, max_to(v0.abs(), v1.abs()))
            } else {
                1.0
            }
        };
        // the largest |sin θ| and |cos θ| over the sweep (|t_a| and |t_b| of the circle)
        let (peak_a, peak_b) = (
            peak(cos_s, cos_e, sin_s, sin_e),
            peak(sin_s, sin_e, cos_s, cos_e),
        );
        let mut w = [0.0; 3];
        let mut wa = [0.0; 3];
        // (a degenerate arc from its centre keeps the circle's weights)
        if !is_spiral {
            w[a] = horiz * peak_a;
            w[b] = horiz * peak_b;
            wa[a] = 1.0;
            wa[b] = 1.0;
        } else {
            let spiral = spiral_weights(radius, re, sweep, l, peak_a, peak_b);
            (w[a], w[b], wa[a], wa[b]) = spiral;
        }
        w[n] = vert;
        wa[n] = vert;
        // a spiral's tangents are dp/ds, not unit vectors: its path runs at
        // |dp/ds| ≠ 1 times the planned speed at its ends, so that a junction sees
        // the step in velocity both in direction and in size
        let (start_tangent, end_tangent) = if is_spiral {
            (ts * (1.0 / l), te * (1.0 / l))
        } else {
            (ts.unit(), te.unit())
        };
        ElementShape {
            len,
            start_tangent,
            end_tangent,
            vel_weight: w,
            acc_weight: wa,
            curvature: p.curvature(),
        }
    }

    /// A blend arc (see [`Geom::Blend`]).
    pub fn blend(e1: Vec3, e2: Vec3, radius: f64, sweep: f64) -> ElementShape {
        // √(t_i² + n_i²) = √(e1_i² + e2_i²) all along the arc
        let wa = [0, 1, 2].map(|i| e1[i].hypot(e2[i]).min(1.0));
        let (cos_s, sin_s) = (sweep.cos(), sweep.sin());
        Self::blend_with(e1, e2, radius, sweep, cos_s, sin_s, wa)
    }

    /// A blend arc whose construction gave the cosine and sine of its sweep (the
    /// fillets of `crate::fillet`): [`ElementShape::blend`] without trigonometry, and
    /// √(e1_i² + e2_i²) as a square root rather than `hypot` (unit vectors: no
    /// overflow to guard against).
    ///
    /// Inline (into the builder's `push_blend_piece`): planning thread −0.4 M on
    /// the 200k-line program (with `junction_speed` and `push_element` inline).
    #[inline]
    pub fn blend_trig(
        e1: Vec3,
        e2: Vec3,
        radius: f64,
        sweep: f64,
        cos_s: f64,
        sin_s: f64,
    ) -> ElementShape {
        let mut wa = [0.0; 3];
        for (i, w) in wa.iter_mut().enumerate() {
            *w = min_to(1.0, (e1[i] * e1[i] + e2[i] * e2[i]).sqrt());
        }
        Self::blend_with(e1, e2, radius, sweep, cos_s, sin_s, wa)
    }

    /// The shape of a blend arc from its sweep's cosine and sine and its
    /// acceleration weights √(e1_i² + e2_i²).
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn blend_with(
        e1: Vec3,
        e2: Vec3,
        radius: f64,
        sweep: f64,
        cos_s: f64,
        sin_s: f64,
        wa: [f64; 3],
    ) -> ElementShape {
        let end_tangent = e2 * cos_s - e1 * sin_s;
        let end_radial = e1 * cos_s + e2 * sin_s;
        // |t_i| reaches its amplitude √(e1_i² + e2_i²) only where the radial component
        // r_i = e1_i cos φ + e2_i sin φ changes sign (dt_i/dφ = −r_i); a sweep shorter
        // than π passes at most one such point, so the signs at the ends tell
        let mut wv = wa;
        for (i, w) in wv.iter_mut().enumerate() {
            if sweep < std::f64::consts::PI && e1[i] * end_radial[i] > 0.0 {
                *w = min_to(wa[i], max_to(e2[i].abs(), end_tangent[i].abs()));
            }
        }
        ElementShape {
            len: radius * sweep,
            start_tangent: e2,
            end_tangent: end_tangent.unit(),
            vel_weight: wv,
            acc_weight: wa,
            curvature: 1.0 / radius,
        }
    }
}

/// In-plane velocity and acceleration weights `(w_a, w_b, wa_a, wa_b)` of a spiral:
/// an arc whose end radius `end_radius` differs from its start radius `radius`, run
/// as `Primitive::point_at` runs it, with the radius r(u) = R₀ + ΔR·u and the angle
/// θ(u) = θ₀ + φ·u linear in u = s/L, L = [`Primitive::length`] (R₀·|φ| in the
/// plane: the circle's length, not the spiral's). Then
/// dp_a/ds = (ΔR·cos θ − r·φ·sin θ)/L and dp_b/ds = (ΔR·sin θ + r·φ·cos θ)/L, whose
/// peaks exceed the circle's |t_a| ≤ 1 by about |ΔR|/R₀ (the path runs faster than
/// its nominal speed where r > R₀) and |ΔR|/(R₀·|φ|) (the radial drift, large on
/// short arcs): bounded by (|ΔR|·max|cos θ| + r_max·|φ|·max|sin θ|)/L, `peak_a` =
/// max|sin θ| and `peak_b` = max|cos θ| over the sweep, and by
/// √(ΔR² + r_max²φ²)/L. The acceleration weight bounds √(T_i² + (N_i/κ)²) (T = dp/ds,
/// N = d²p/ds², κ = [`Primitive::curvature`] = R₀φ²/L²): with e = ΔR/φ,
/// R₀²·(T_a² + (N_a/κ)²) ≤ r² + e²(cos²θ + 4 sin²θ) + 2e·r·sin θ·cos θ
/// ≤ r_max² + |e|·r_max + 4e², so that `element_limits`'s split
/// (|a_t| ≤ 0.5·A, κv² ≤ 0.866·A) keeps every axis within A on the spiral too.
fn spiral_weights(
    radius: f64,
    end_radius: f64,
    sweep: f64,
    len: f64,
    peak_a: f64,
    peak_b: f64,
) -> (f64, f64, f64, f64) {
    let d_radius = (end_radius - radius).abs();
    let r_max = radius.max(end_radius);
    let r_phi = r_max * sweep.abs();
    let norm = d_radius.hypot(r_phi);
    let w_a = (d_radius * peak_b + r_phi * peak_a).min(norm) / len;
    let w_b = (d_radius * peak_a + r_phi * peak_b).min(norm) / len;
    let e = d_radius / sweep.abs().max(f64::MIN_POSITIVE);
    let wa = (r_max * r_max + e * r_max + 4.0 * e * e).sqrt() / radius;
    (w_a, w_b, wa, wa)
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
///
/// Inline always: with the builder's elements pushed where their shapes are built
/// (`PathBuilder::emit`'s arms), LLVM left one of its copies (the sub-arc's) out of
/// line, the shape handed over in memory (planning thread −2.1 M on the 200k-line
/// program).
#[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
pub fn element_limits(g: &ElementShape, vmax: [f64; 3], amax: [f64; 3]) -> ElementLimits {
    let (wv, wa) = (g.vel_weight, g.acc_weight);
    // an axis's limit over its weight (the division skipped for the common weight 1,
    // where it is exact)
    let per_weight = |limit: f64, w: f64| if w == 1.0 { limit } else { limit / w };
    let mut vel = f64::INFINITY;
    let mut acc = f64::INFINITY;
    for i in 0..3 {
        if wv[i] > 1e-12 {
            vel = min_to(vel, per_weight(vmax[i], wv[i]));
        }
    }
    let kappa = g.curvature;
    if kappa > 0.0 {
        // Curved: split each axis's acceleration between path and centripetal parts.
        let mut a_axis = f64::INFINITY;
        for i in 0..3 {
            if wa[i] > 1e-12 {
                a_axis = min_to(a_axis, per_weight(amax[i], wa[i]));
            }
        }
        acc = ARC_TANGENTIAL_SHARE * a_axis;
        vel = min_to(vel, (ARC_NORMAL_SHARE * a_axis / kappa).sqrt());
    } else {
        for i in 0..3 {
            if wa[i] > 1e-12 {
                acc = min_to(acc, per_weight(amax[i], wa[i]));
            }
        }
    }
    ElementLimits {
        vel_mm_per_s: vel,
        acc_mm_per_s2: acc,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_core::Plane;

    /// Largest |t_i| over an element, by sampling its points finely.
    fn sampled_peak(geom: &Geom, len: f64) -> [f64; 3] {
        let n = 20_000;
        let mut w = [0.0f64; 3];
        for k in 0..n {
            let (s0, s1) = (len * k as f64 / n as f64, len * (k + 1) as f64 / n as f64);
            let t = (geom.point_at(s1) - geom.point_at(s0)) * (1.0 / (s1 - s0));
            for i in 0..3 {
                w[i] = w[i].max(t[i].abs());
            }
        }
        w
    }

    fn assert_tight(weight: [f64; 3], sampled: [f64; 3], what: &str) {
        for i in 0..3 {
            // never below the true peak (a limit), and not above it (speed)
            assert!(
                weight[i] >= sampled[i] - 1e-9,
                "{what}: axis {i} {weight:?} < {sampled:?}"
            );
            assert!(
                weight[i] <= sampled[i] + 1e-4,
                "{what}: axis {i} {weight:?} ≫ {sampled:?}"
            );
        }
    }

    #[test]
    fn velocity_weights_are_the_peak_over_the_swept_part() {
        let diag = (0.5f64).sqrt();
        for (k, sweep) in [0.1, 0.5, 1.5, 3.0, 3.5, 6.2].into_iter().enumerate() {
            for start_deg in [0.0, 30.0, 45.0, 100.0, 200.0, 300.0] {
                let a = f64::to_radians(start_deg);
                // blend in a tilted plane
                let e1 = Vec3::new(a.cos() * diag, a.sin(), a.cos() * diag);
                let e2 = Vec3::new(-a.sin() * diag, a.cos(), -a.sin() * diag);
                let (r, c) = (3.0, Vec3::new(1.0, 2.0, 3.0));
                let shape = ElementShape::blend(e1, e2, r, sweep);
                let geom = Geom::Blend {
                    center: c,
                    e1,
                    e2,
                    radius: r,
                    sweep,
                };
                assert_tight(shape.vel_weight, sampled_peak(&geom, r * sweep), "blend");
                // programmed arcs and helices, both directions
                for (turns, dz) in [(1, 0.0), (-1, 0.0), (1, 2.0)] {
                    let th = if turns > 0 { a + sweep } else { a - sweep };
                    let start = c + Vec3::new(r * a.cos(), r * a.sin(), 0.0);
                    let end = c + Vec3::new(r * th.cos(), r * th.sin(), dz);
                    let p = Primitive::arc(start, end, c, Plane::XY, turns);
                    let shape = ElementShape::arc(&p);
                    let what = format!("arc {k} {start_deg} {turns}");
                    assert_tight(
                        shape.vel_weight,
                        sampled_peak(&Geom::Arc(p), p.length()),
                        &what,
                    );
                }
            }
        }
    }

    /// Spirals (end radius off the start radius, as `Primitive::point_at` runs them):
    /// the velocity weights bound the sampled |dp_i/ds| and exceed it by at most
    /// twice the radial drift and |ΔR|/R₀,
    /// the acceleration weights bound √(T_i² + (N_i/κ)²) sampled by second
    /// differences, and the end tangents are dp/ds at the ends (a junction sees the
    /// velocity step). With the circle's weights and tangents (before) the first
    /// assertion fails: |dp_a/ds| reaches (R₀ + ΔR)/R₀ > 1 on an axis.
    #[test]
    fn spiral_weights_and_tangents_are_its_own() {
        let c = Vec3::new(1.0, 2.0, 3.0);
        for (radius, d_radius, sweep) in [
            (3.599, 0.0005, 0.0286),
            (3.599, -0.0005, 0.0286),
            (20.0, 0.01, 1.2),
            (20.0, -0.4, 3.0),
            (5.0, 0.002, 6.0),
            (0.5, 0.01, 0.3),
        ] {
            for start_deg in [-90.0, 0.0, 30.0, 135.0, 250.0] {
                for (turns, dz) in [(1, 0.0), (-1, 0.0), (1, 0.7)] {
                    let a = f64::to_radians(start_deg);
                    let th = if turns > 0 { a + sweep } else { a - sweep };
                    let r1 = radius + d_radius;
                    let start = c + Vec3::new(radius * a.cos(), radius * a.sin(), 0.0);
                    let end = c + Vec3::new(r1 * th.cos(), r1 * th.sin(), dz);
                    let p = Primitive::arc(start, end, c, Plane::XY, turns);
                    let shape = ElementShape::arc(&p);
                    let what =
                        format!("R {radius} ΔR {d_radius} φ {sweep} at {start_deg}° {turns} {dz}");
                    let len = p.length();
                    let geom = Geom::Arc(p);
                    let sampled = sampled_peak(&geom, len);
                    for i in 0..3 {
                        assert!(
                            shape.vel_weight[i] >= sampled[i] - 1e-9,
                            "{what}: velocity weight {i} {:?} < {sampled:?}",
                            shape.vel_weight
                        );
                        // (conservative by at most twice the radial drift
                        // |ΔR|/(R₀·φ), whose sign against the circle's term is not
                        // looked at, and |ΔR|/R₀, r_max taken all along)
                        let drift = (d_radius / (radius * sweep)).abs();
                        let slack = 2.0 * drift + (d_radius / radius).abs() + 1e-4;
                        assert!(
                            shape.vel_weight[i] <= sampled[i] + slack,
                            "{what}: velocity weight {i} {:?} ≫ {sampled:?}",
                            shape.vel_weight
                        );
                    }
                    // √(T_i² + (N_i/κ)²) by differences over 2,000 steps
                    let (n, kappa) = (2_000, shape.curvature);
                    let h = len / n as f64;
                    for k in 1..n {
                        let s = k as f64 * h;
                        let (q0, q1, q2) =
                            (geom.point_at(s - h), geom.point_at(s), geom.point_at(s + h));
                        let t = (q2 - q0) * (0.5 / h);
                        let nn = (q2 - q1 * 2.0 + q0) * (1.0 / (h * h));
                        for i in 0..3 {
                            let need = t[i].hypot(nn[i] / kappa);
                            assert!(
                                shape.acc_weight[i] >= need - 1e-6,
                                "{what}: acceleration weight {i} {:?} < {need} at {k}",
                                shape.acc_weight
                            );
                        }
                    }
                    // the end tangents: dp/ds at the ends, by differences
                    let e = 1e-7 * len;
                    let t0 = (geom.point_at(e) - geom.point_at(0.0)) * (1.0 / e);
                    let t1 = (geom.point_at(len) - geom.point_at(len - e)) * (1.0 / e);
                    assert!(
                        (t0 - shape.start_tangent).norm() < 1e-6,
                        "{what}: start {t0:?} {:?}",
                        shape.start_tangent
                    );
                    assert!(
                        (t1 - shape.end_tangent).norm() < 1e-6,
                        "{what}: end {t1:?} {:?}",
                        shape.end_tangent
                    );
                }
            }
        }
    }

    /// `ElementShape::sub_arc` plans a sub-arc whose end radius is off by rounding
    /// (|ΔR| ≤ `SUB_ARC_SNAP_REL`·R·|φ|) as its circle (acceleration weights 1 in the
    /// plane, unit tangents), and one off by more as `arc` does (a spiral: weights
    /// above 1). Fails if the snap is dropped (first case) or taken too far (second).
    #[test]
    fn sub_arc_takes_a_rounded_end_radius_as_the_circle() {
        let (c, radius, a0, sweep) = (Vec3::new(300.0, 2.0, -1.0), 0.25, 0.3f64, 1.2f64);
        let at = |r: f64, th: f64| c + Vec3::new(r * th.cos(), r * th.sin(), 0.0);
        let arc_to = |end_radius: f64| Primitive::Arc {
            start: at(radius, a0),
            center: c,
            plane: Plane::XY,
            radius,
            start_angle: a0,
            sweep,
            normal_travel: 0.0,
            end: at(end_radius, a0 + sweep),
        };
        // rounding: 40 ulps of the coordinates (1e-14 mm at 300 mm), under 3e-13
        let rounded = arc_to(radius + 1e-14);
        let spiral = ElementShape::arc(&rounded);
        assert!(spiral.acc_weight[0] > 1.0, "{:?}", spiral.acc_weight);
        let snapped = ElementShape::sub_arc(&rounded);
        assert_eq!(snapped.acc_weight, [1.0, 1.0, 0.0]);
        assert!((snapped.end_tangent.norm() - 1.0).abs() < 1e-15);
        assert!((snapped.end_tangent - spiral.end_tangent).norm() < 1e-12);
        for i in 0..3 {
            assert!((snapped.vel_weight[i] - spiral.vel_weight[i]).abs() < 1e-12);
        }
        // a programmed change of radius (CAM rounding of 1e-9 mm) stays a spiral
        let cam = arc_to(radius + 1e-9);
        let (a, b) = (ElementShape::arc(&cam), ElementShape::sub_arc(&cam));
        assert!(a.acc_weight[0] > 1.0);
        assert_eq!(a.acc_weight, b.acc_weight);
        assert_eq!(a.vel_weight, b.vel_weight);
        assert_eq!(a.end_tangent, b.end_tangent);
    }

    /// `blend_trig` (the fillets' shape from the construction's cos and sin) is
    /// `blend`'s shape: same tangents and weights, in and out of the coordinate
    /// planes, short and long sweeps.
    /// `min_to` and `max_to` are `f64::min` and `f64::max` bit for bit wherever the
    /// first argument is not NaN: signed zeros, infinities and a NaN second argument
    /// included.
    #[test]
    fn min_to_and_max_to_are_the_library_min_and_max() {
        let values = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.25,
            1e-300,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for &acc in values.iter().filter(|v| !v.is_nan()) {
            for &x in &values {
                let (a, x) = (std::hint::black_box(acc), std::hint::black_box(x));
                assert_eq!(min_to(a, x).to_bits(), a.min(x).to_bits(), "min({a}, {x})");
                assert_eq!(max_to(a, x).to_bits(), a.max(x).to_bits(), "max({a}, {x})");
            }
        }
    }

    #[test]
    fn blend_trig_is_blend() {
        let cases = [
            (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), 0.3, 1.2),
            (
                Vec3::new(0.0, -1.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                2.0,
                3.0,
            ),
            (
                Vec3::new(0.6, 0.0, 0.8),
                Vec3::new(0.0, 1.0, 0.0),
                0.01,
                0.05,
            ),
            (
                Vec3::new(0.48, 0.6, 0.64),
                Vec3::new(-0.8, 0.6, 0.0),
                5.0,
                2.5,
            ),
        ];
        for (e1, e2, radius, sweep) in cases {
            let e2 = (e2 - e1 * e1.dot(e2)).unit();
            let a = ElementShape::blend(e1, e2, radius, sweep);
            let b = ElementShape::blend_trig(e1, e2, radius, sweep, sweep.cos(), sweep.sin());
            assert_eq!(a.len, b.len);
            assert_eq!(a.curvature, b.curvature);
            assert!((a.end_tangent - b.end_tangent).norm() < 1e-15);
            for i in 0..3 {
                assert!((a.vel_weight[i] - b.vel_weight[i]).abs() < 1e-15, "{i}");
                assert!((a.acc_weight[i] - b.acc_weight[i]).abs() < 1e-15, "{i}");
            }
        }
    }
}
