//! `fillet::line_arc` as it was at 557cc9e (before `fillet14`), kept word for word
//! (only `crate::path`'s `min_to`/`max_to` copied in and the public `Fillet` built):
//! the reference the new one must match bit for bit (`tests/line_arc_bits.rs`) and
//! is timed against (`benches/fillet.rs`). The includer defines `cover!(i)`, called
//! where the old code takes one of its rarer paths (`COVER_POINTS` of them; the test
//! counts them, the benchmark's is empty).
#![allow(dead_code, clippy::all)]

use softnc_core::Vec3;
use softnc_planner::fillet::{ArcView, Fillet};

/// How many places call `cover!`.
pub const COVER_POINTS: usize = 24;

const DEVIATION_SHARE: f64 = 0.9;
const TRIM_TRIES: usize = 16;
const FILLET_CLOSURE_MM: f64 = 1e-7;
const CLOSURE_SURE_SHARE: f64 = 0.25;

#[inline(always)]
fn min_to(acc: f64, x: f64) -> f64 {
    if x < acc {
        x
    } else {
        acc
    }
}

#[inline(always)]
fn max_to(acc: f64, x: f64) -> f64 {
    if x > acc {
        x
    } else {
        acc
    }
}

#[inline(always)]
fn first_trim_cs(c: f64, s: f64, tol_mm: f64) -> f64 {
    if !(-1.0..=1.0).contains(&c) {
        cover!(23); // a clamped (or NaN) turn cosine
    }
    let c = c.clamp(-1.0, 1.0);
    let s = min_to(s, 1.0);
    let one_plus_c = 1.0 + c;
    if one_plus_c <= 0.0 {
        cover!(17);
        return 0.0; // a reversal: no fillet
    }
    let cos_half = (0.5 * one_plus_c).sqrt();
    let one_minus_cos_half = s * s / (2.0 * one_plus_c) / (1.0 + cos_half);
    let sec_minus_one = one_minus_cos_half / cos_half;
    if sec_minus_one <= 0.0 {
        cover!(16);
        return f64::INFINITY;
    }
    let tan_half = s / one_plus_c;
    DEVIATION_SHARE * tol_mm / sec_minus_one * tan_half
}

/// The old `fillet::line_arc`.
#[inline(never)]
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

#[inline(always)]
fn line_arc_in<const A: usize, const B: usize, const N: usize>(
    corner: Vec3,
    u: Vec3,
    line_avail: f64,
    arc: &ArcView,
    arc_avail: f64,
    tol_mm: f64,
) -> Option<Fillet> {
    let (ia, ib, i_n) = (A, B, N);
    if u[i_n].abs() > 1e-9 {
        return None; // a line out of the arc's plane
    }
    let (ua, ub) = (u[ia], u[ib]);
    let (ca, cb) = (arc.center[ia], arc.center[ib]);
    let (pa, pb) = (corner[ia] - ca, corner[ib] - cb);
    let p_norm = (pa * pa + pb * pb).sqrt();
    if p_norm.is_nan() || p_norm <= 0.0 {
        return None;
    }
    let k = arc.sense * arc.orient / p_norm;
    let (ta, tb) = (-pb * k, pa * k);
    let ut = ua * ta + ub * tb;
    let (ma, mb) = (ta - ua * ut, tb - ub * ut);
    let m_norm = (ma * ma + mb * mb).sqrt();
    if m_norm < 1e-9 {
        return None; // tangent (or reversing) join
    }
    let (na, nb) = (ma / m_norm, mb / m_norm);
    let exact_n = || {
        let (sa, sb) = (-ub, ua);
        let s_scale = (na * sa + nb * sb).signum() / (sa * sa + sb * sb).sqrt();
        (sa * s_scale, sb * s_scale)
    };
    let mut d = min_to(
        line_avail,
        first_trim_cs(ut, (ua * tb - ub * ta).abs(), tol_mm),
    );
    for try_no in 0..TRIM_TRIES {
        if d <= 1e-9 {
            return None;
        }
        let at = |n: (f64, f64)| {
            line_arc_at::<A, B, N>(corner, u, d, arc, arc_avail, n, (pa, pb))
                .map(|(f, _)| f)
                .filter(|f| closes(f, u))
        };
        if let Some(f) = line_arc_at::<A, B, N>(corner, u, d, arc, arc_avail, (na, nb), (pa, pb))
            .and_then(|(f, surely)| {
                cover!(19);
                if surely || closes(&f, u) {
                    if !surely {
                        cover!(18);
                    }
                    Some(f)
                } else {
                    cover!(0);
                    let g = at(exact_n());
                    if g.is_some() {
                        cover!(1);
                    }
                    g
                }
            })
        {
            let (fa, fb) = (f.center[ia] - ca, f.center[ib] - cb);
            let (da, db) = (pa - fa, pb - fb);
            let deviation = ((da * da + db * db).sqrt() - f.radius).abs();
            if deviation <= DEVIATION_SHARE * tol_mm {
                cover!(15);
                if try_no > 0 {
                    cover!(2);
                }
                return Some(f);
            }
            cover!(3);
        }
        d *= 0.7;
    }
    None
}

#[inline(always)]
fn line_arc_at<const A: usize, const B: usize, const N: usize>(
    corner: Vec3,
    u: Vec3,
    d: f64,
    arc: &ArcView,
    arc_avail: f64,
    (na, nb): (f64, f64),
    (pa, pb): (f64, f64),
) -> Option<(Fillet, bool)> {
    let (ia, ib, i_n) = (A, B, N);
    let (ua, ub) = (u[ia], u[ib]);
    let (ca, cb) = (arc.center[ia], arc.center[ib]);
    let big_r = arc.radius;
    let p1 = corner - u * d;
    let (wa, wb) = (p1[ia] - ca, p1[ib] - cb);
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
    let (fa, fb) = (wa + na * r, wb + nb * r);
    let fc_norm = (fa * fa + fb * fb).sqrt();
    let radial_mismatch_mm = (fc_norm - (big_r + sigma * r)).abs();
    if fc_norm < 1e-12 || radial_mismatch_mm > 1e-7 * max_to(big_r, 1.0) {
        return None;
    }
    let scale = big_r / fc_norm;
    let (tca, tcb) = (fa * scale, fb * scale);
    let (qa, qb) = (tca - fa, tcb - fb);
    let (q1, q2) = (-(qa * na + qb * nb), qa * ua + qb * ub);
    if q2 <= 0.0 {
        return None;
    }
    let qn = (q1 * q1 + q2 * q2).sqrt();
    let (cos_sweep, sin_sweep) = (q1 / qn, q2 / qn);
    let k = arc.sense * arc.orient / big_r;
    let (ata, atb) = (-tcb * k, tca * k);
    let along = (ua * cos_sweep + na * sin_sweep) * ata + (ub * cos_sweep + nb * sin_sweep) * atb;
    if along < 1.0 - 1e-9 {
        return None;
    }
    let sweep = atan2(q2, q1);
    if !(sweep > 1e-9 && sweep < std::f64::consts::PI - 1e-6) {
        return None;
    }
    let cross = (pa * tcb - pb * tca) * arc.orient * arc.sense;
    let ang = atan2(cross, pa * tca + pb * tcb);
    let arc_trim_rad = if ang < 0.0 {
        ang + std::f64::consts::TAU
    } else {
        ang
    };
    let arc_trim = arc_trim_rad * big_r;
    if !(arc_trim > 1e-9 && arc_trim <= arc_avail) {
        return None;
    }
    let mut center = p1;
    center[ia] = ca + fa;
    center[ib] = cb + fb;
    let mut p_arc = arc.center;
    p_arc[ia] = ca + tca;
    p_arc[ib] = cb + tcb;
    p_arc[i_n] = arc.center[i_n];
    let surely = closure_bound_mm(
        radial_mismatch_mm,
        r,
        (na * ua + nb * ub).abs(),
        u[i_n].abs(),
        (p1[i_n] - arc.center[i_n]).abs(),
        ca.abs() + cb.abs() + wa.abs() + wb.abs() + big_r,
    ) <= CLOSURE_SURE_SHARE * FILLET_CLOSURE_MM;
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
    Some((fillet, surely))
}

#[inline(always)]
fn closure_bound_mm(
    radial_mismatch_mm: f64,
    r_mm: f64,
    n_dot_u: f64,
    u_normal: f64,
    p1_off_plane_mm: f64,
    magnitudes_mm: f64,
) -> f64 {
    radial_mismatch_mm
        + r_mm * (4.0 * n_dot_u + u_normal)
        + p1_off_plane_mm
        + 100.0 * f64::EPSILON * (magnitudes_mm + r_mm)
}

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

#[inline(always)]
fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    const PI_LO: f64 = 1.2246467991473532e-16;
    if !(x.is_finite() && y.is_finite()) {
        cover!(4);
        return y.atan2(x);
    }
    if y == 0.0 {
        cover!(5);
        return if x.is_sign_negative() {
            PI.copysign(y)
        } else {
            y
        };
    }
    if x == 0.0 {
        cover!(6);
        return FRAC_PI_2.copysign(y);
    }
    let (ay, ax) = (y.abs(), x.abs());
    let z = if ay > ax * 1.152_921_504_606_847e18 {
        cover!(7);
        FRAC_PI_2 + 0.5 * PI_LO
    } else if x < 0.0 && ay * 1.152_921_504_606_847e18 < ax {
        cover!(8);
        0.0
    } else {
        atan_nonneg(ay / ax)
    };
    match (x < 0.0, y < 0.0) {
        (false, false) => z,
        (false, true) => {
            cover!(22);
            -z
        }
        (true, false) => {
            cover!(20);
            PI - (z - PI_LO)
        }
        (true, true) => {
            cover!(21);
            (z - PI_LO) - PI
        }
    }
}

#[inline(always)]
fn atan_nonneg(x: f64) -> f64 {
    const ATAN_HI: [f64; 4] = [
        0.4636476090008061,
        std::f64::consts::FRAC_PI_4,
        0.982793723247329,
        std::f64::consts::FRAC_PI_2,
    ];
    const ATAN_LO: [f64; 4] = [
        2.2698777452961687e-17,
        3.061616997868383e-17,
        1.3903311031230998e-17,
        6.123233995736766e-17,
    ];
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
    let (id, x) = if x < 0.4375 {
        if x < 3.725290298461914e-09 {
            cover!(9);
            return x;
        }
        cover!(10);
        (None, x)
    } else if x < 0.6875 {
        cover!(11);
        (Some(0), (2.0 * x - 1.0) / (2.0 + x))
    } else if x < 1.1875 {
        cover!(12);
        (Some(1), (x - 1.0) / (x + 1.0))
    } else if x < 2.4375 {
        cover!(13);
        (Some(2), (x - 1.5) / (1.0 + 1.5 * x))
    } else {
        cover!(14);
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
