//! The acceleration-free bound of a program's run time: every programmed motion run
//! along its programmed primitive at the highest speed its feed and the axes'
//! velocity limits allow at each point, min(F, min_i V_i/|t_i(s)|), with no
//! acceleration, no blend and no wait; dwells counted. No planner on the programmed
//! path can be faster (a blend shortens the path only by what it deviates from it).
//! Beside it the curvature bound: on arcs and helices also no faster than the axes'
//! accelerations allow the centripetal acceleration κv²·n at each point — the highest
//! v for which some tangential acceleration a_t keeps |t_i·a_t + n_i·κv²| ≤ A_i on
//! every axis (a necessary condition at every point, whatever the planner).
//!
//! `cargo run --release -p softnc-planner --example feed_bound -- PROFILE.ron FILE...`
//! reads each program as `tp_limits` does (from the origin, soft limits ignored) and
//! prints one line per program (`FILE: BOUND s curvature BOUND s`) and the totals of
//! the programs read.
use softnc_core::MotionProfile;
use softnc_gcode::MotionKind;
use softnc_planner::PlanOptions;

/// Pieces an arc or helix is cut into to integrate ds / v(s) (its speed varies
/// along it with its tangent).
const ARC_PIECES: usize = 256;

/// The highest speed along unit tangent `t` within the axes' velocity limits.
fn axis_speed(vmax: &[f64; 3], t: [f64; 3]) -> f64 {
    (0..3)
        .filter(|&i| t[i].abs() > 1e-12)
        .map(|i| vmax[i] / t[i].abs())
        .fold(f64::INFINITY, f64::min)
}

/// Whether some tangential acceleration keeps every axis within its limit at speed
/// `v` on a curve with unit tangent `t` and curvature vector `k` (κ·n, 1/mm).
fn curve_feasible(amax: &[f64; 3], t: [f64; 3], k: [f64; 3], v: f64) -> bool {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..3 {
        let c = k[i] * v * v;
        if t[i].abs() < 1e-12 {
            if c.abs() > amax[i] {
                return false;
            }
            continue;
        }
        let (a, b) = ((-amax[i] - c) / t[i], (amax[i] - c) / t[i]);
        lo = lo.max(a.min(b));
        hi = hi.min(a.max(b));
    }
    lo <= hi
}

/// The highest speed up to `cap` at which [`curve_feasible`] holds (bisection).
fn curve_speed(amax: &[f64; 3], t: [f64; 3], k: [f64; 3], cap: f64) -> f64 {
    if curve_feasible(amax, t, k, cap) {
        return cap;
    }
    let (mut lo, mut hi) = (0.0, cap);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if curve_feasible(amax, t, k, mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The curvature vector κ·n of an arc or helix at the point of tangent `t`: in its
/// plane towards the centre, of size R·φ²/L² (R its radius, φ its sweep, L its length).
fn curvature(prim: &softnc_core::Primitive, s: f64) -> [f64; 3] {
    let softnc_core::Primitive::Arc {
        center,
        plane,
        radius,
        sweep,
        ..
    } = *prim
    else {
        return [0.0; 3];
    };
    let len = prim.length();
    let p = prim.point_at(s);
    let (a, b, _) = plane.axes();
    let size = radius * sweep * sweep / (len * len);
    let r = ((p[a] - center[a]).powi(2) + (p[b] - center[b]).powi(2)).sqrt();
    let mut k = [0.0; 3];
    if r > 0.0 {
        k[a] = -size * (p[a] - center[a]) / r;
        k[b] = -size * (p[b] - center[b]) / r;
    }
    k
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(profile_path) = args.next() else {
        eprintln!("usage: feed_bound PROFILE.ron FILE...");
        std::process::exit(2);
    };
    let profile = MotionProfile::load(std::path::Path::new(&profile_path)).expect("profile loads");
    let (vmax, amax) = (profile.max_vel(), profile.max_acc());
    let (mut total_s, mut total_curve_s) = (0.0, 0.0);
    for file in args {
        let Ok(text) = std::fs::read_to_string(&file) else {
            continue;
        };
        let dir = std::path::Path::new(&file)
            .parent()
            .map(|d| d.to_path_buf())
            .unwrap_or_default();
        let opts = PlanOptions {
            ignore_soft_limits: true,
            start_mm: Some([0.0; 3]),
            subroutine_path: vec![dir],
            ..Default::default()
        };
        let read = softnc_gcode::read_program_with(&text, &file, &profile, &opts.read_options());
        let Ok((program, _)) = read else {
            println!("{file}: refused");
            continue;
        };
        let (mut bound_s, mut curve_s) = (0.0, 0.0);
        for m in &program.motions {
            let feed = match m.kind {
                MotionKind::Traverse { .. } => f64::INFINITY,
                MotionKind::Feed {
                    feed_mm_per_min, ..
                }
                | MotionKind::Arc {
                    feed_mm_per_min, ..
                } => feed_mm_per_min / 60.0,
                MotionKind::Dwell { seconds } => {
                    bound_s += seconds;
                    curve_s += seconds;
                    continue;
                }
                _ => continue,
            };
            let Some(prim) = softnc_planner::build::motion_primitive(m) else {
                continue;
            };
            let len = prim.length();
            if !(len > 0.0) {
                continue;
            }
            let pieces = match m.kind {
                MotionKind::Arc { .. } => ARC_PIECES,
                _ => 1,
            };
            let ds = len / pieces as f64;
            for k in 0..pieces {
                let s = (k as f64 + 0.5) * ds;
                let t = prim.tangent_at(s);
                let v = feed.min(axis_speed(&vmax, t.0));
                bound_s += ds / v;
                curve_s += ds / curve_speed(&amax, t.0, curvature(&prim, s), v);
            }
        }
        total_s += bound_s;
        total_curve_s += curve_s;
        println!("{file}: {bound_s:.3} s curvature {curve_s:.3} s");
    }
    println!("feed_bound: total {total_s:.3} s, with curvature {total_curve_s:.3} s");
}
