//! `fillet::line_arc` with the construction on n = u turned a quarter (`fillet16`,
//! after ce178c5), written plainly (its angles by `libm::atan2`, as the planner's):
//! the reference the planner's must match bit for bit (`tests/line_arc_bits.rs`). The includer defines
//! `cover!(i)`, called where the code takes one of its rarer paths (`COVER_POINTS`
//! of them; the test counts them).
#![allow(dead_code, clippy::all)]

use softnc_core::Vec3;
use softnc_planner::fillet::{ArcView, Fillet};

/// How many places call `cover!`.
pub const COVER_POINTS: usize = 11;

const DEVIATION_SHARE: f64 = 0.9;
const TRIM_TRIES: usize = 16;
const FILLET_CLOSURE_MM: f64 = 1e-7;
const CLOSURE_SURE_SHARE: f64 = 0.25;

fn min_to(acc: f64, x: f64) -> f64 {
    if x < acc {
        x
    } else {
        acc
    }
}

fn max_to(acc: f64, x: f64) -> f64 {
    if x > acc {
        x
    } else {
        acc
    }
}

/// 2·0.9·tol·cos(θ/2)·(1 + cos(θ/2))/sin θ, cos(θ/2) = √((1 + c)/2).
fn first_trim_cs(c: f64, s: f64, tol_mm: f64) -> f64 {
    if !(-1.0..=1.0).contains(&c) {
        cover!(9); // a clamped (or NaN) turn cosine
    }
    let c = c.clamp(-1.0, 1.0);
    let s = min_to(s, 1.0);
    let one_plus_c = 1.0 + c;
    if one_plus_c <= 0.0 {
        cover!(6);
        return 0.0; // a reversal: no fillet
    }
    if s <= 0.0 {
        return f64::INFINITY;
    }
    let cos_half = (0.5 * one_plus_c).sqrt();
    2.0 * DEVIATION_SHARE * tol_mm * cos_half * (1.0 + cos_half) / s
}

/// The new `fillet::line_arc`.
pub fn line_arc(
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
) -> Option<Fillet> {
    match arc.axes {
        (0, 1, 2) => line_arc_in::<0, 1, 2>(corner, u, line_avail, arc, arc_avail, tol_mm),
        (2, 0, 1) => line_arc_in::<2, 0, 1>(corner, u, line_avail, arc, arc_avail, tol_mm),
        (1, 2, 0) => line_arc_in::<1, 2, 0>(corner, u, line_avail, arc, arc_avail, tol_mm),
        _ => None,
    }
}

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
    // the arc's unit tangent at the corner, and the turn's cosine and sine
    // (t = k·(−p_b, p_a): u·t = k·(u_b·p_a − u_a·p_b), (u × t)·N = k·(u·p))
    let k = arc.sense * arc.orient / p_norm;
    let cos_turn = (ub * pa - ua * pb) * k;
    let sin_turn = (ua * pa + ub * pb) * k;
    if !(sin_turn.abs() >= 1e-9) {
        cover!(10);
        return None; // tangent (or reversing) join
    }
    // u turned a quarter towards the turn
    let (na, nb) = if sin_turn > 0.0 { (-ub, ua) } else { (ub, -ua) };
    let mut d = min_to(line_avail, first_trim_cs(cos_turn, sin_turn.abs(), tol_mm));
    for try_no in 0..TRIM_TRIES {
        if d <= 1e-9 {
            return None;
        }
        if let Some((f, surely, deviation)) =
            line_arc_at::<A, B, N>(corner, u, d, arc, arc_avail, (na, nb), (pa, pb))
        {
            cover!(8);
            if deviation <= DEVIATION_SHARE * tol_mm {
                if surely || closes(&f, u) {
                    if !surely {
                        cover!(7);
                    }
                    cover!(4);
                    if try_no > 0 {
                        cover!(2);
                    }
                    return Some(f);
                }
                cover!(0);
            } else {
                cover!(3);
            }
        }
        d *= 0.7;
    }
    None
}

fn line_arc_at<const A: usize, const B: usize, const N: usize>(
    corner: Vec3,
    u: Vec3,
    d: f64,
    arc: &ArcView,
    arc_avail: f64,
    (na, nb): (f64, f64),
    (pa, pb): (f64, f64),
) -> Option<(Fillet, bool, f64)> {
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
        cover!(1);
        return None;
    };
    let wn = wa * na + wb * nb;
    let r = (big_r * big_r - (wa * wa + wb * wb)) / (2.0 * (wn - sigma * big_r));
    if !(r.is_finite() && r > 1e-6) {
        return None;
    }
    let (fa, fb) = (wa + na * r, wb + nb * r);
    let fc_norm = (fa * fa + fb * fb).sqrt();
    let radial_mismatch_mm = (fc_norm - (big_r + sigma * r)).abs();
    if fc_norm < 1e-12 || radial_mismatch_mm > 1e-7 * max_to(big_r, 1.0) {
        cover!(5);
        return None;
    }
    // T − F = −σ·r·(F − c)/|F − c|, against e1 = −n and e2 = u
    let q1 = sigma * (fa * na + fb * nb);
    let q2 = -sigma * (fa * ua + fb * ub);
    if q2 <= 0.0 {
        return None;
    }
    let inv_f = 1.0 / fc_norm;
    let (cos_sweep, sin_sweep) = (q1 * inv_f, q2 * inv_f);
    // the arc's tangent at T: sense·N × (T − c)/R
    let so = arc.sense * arc.orient;
    let along = (ua * cos_sweep + na * sin_sweep) * -fb + (ub * cos_sweep + nb * sin_sweep) * fa;
    let along = along * (so * inv_f);
    if along < 1.0 - 1e-9 {
        return None;
    }
    let sweep = libm::atan2(q2, q1);
    if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
        return None;
    }
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
    let mut center = p1;
    center[A] = ca + fa;
    center[B] = cb + fb;
    let mut p_arc = arc.center;
    p_arc[A] = ca + fa * scale;
    p_arc[B] = cb + fb * scale;
    let surely = radial_mismatch_mm
        + r * u[N].abs()
        + (p1[N] - arc.center[N]).abs()
        + 100.0 * f64::EPSILON * (ca.abs() + cb.abs() + wa.abs() + wb.abs() + big_r + r)
        <= CLOSURE_SURE_SHARE * FILLET_CLOSURE_MM;
    let fillet = Fillet {
        line_trim: d,
        arc_trim,
        arc_trim_rad,
        center,
        radius: r,
        p_line: p1,
        p_arc,
        sweep,
        cos_sweep,
        sin_sweep,
    };
    // how far it passes from the corner: |C − F| − r
    let (da, db) = (pa - fa, pb - fb);
    let deviation = ((da * da + db * db).sqrt() - r).abs();
    Some((fillet, surely, deviation))
}

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
