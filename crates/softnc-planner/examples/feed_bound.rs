//! The acceleration-free bound of a program's run time: every programmed motion run
//! along its programmed primitive at the highest speed its feed and the axes'
//! velocity limits allow at each point, min(F, min_i V_i/|t_i(s)|), with no
//! acceleration, no blend and no wait; dwells counted. No planner that runs the
//! programmed path can be faster; a blended corner is shorter than the programmed one
//! (a 90° blend of radius r by (2 − π/2)·r), so a blending planner comes in under
//! these bounds by what its blends cut: they are a yardstick, not a proof.
//! Beside it the curvature bound: on arcs and helices also no faster than the axes'
//! accelerations allow the centripetal acceleration κv²·n at each point — the highest
//! v for which some tangential acceleration a_t keeps |t_i·a_t + n_i·κv²| ≤ A_i on
//! every axis (a necessary condition at every point, whatever the planner). And the
//! stop bound: the curvature bound where the path must also come to rest at the
//! program's start and end, at a change between traverse and feed, at a dwell, an
//! M0/M1 and after a G61 motion: between two such stops the speed at arc length s
//! from the last one is at most √(2∫a ds) (and as much before the next), with a the
//! largest tangential acceleration the axes allow there (lines min_i A_i/|u_i|;
//! arcs the norm of the axes' limits, looser but never lower than the truth). Each
//! piece is timed at the higher of its two ends' speeds, so the bound stays below
//! the time of any planner that runs the programmed path.
//!
//! `cargo run --release -p softnc-planner --example feed_bound -- PROFILE.ron FILE...`
//! reads each program as `tp_limits` does (from the origin, soft limits ignored) and
//! prints one line per program (`FILE: BOUND s curvature BOUND s stops BOUND s`) and
//! the totals of the programs read.
use softnc_core::MotionProfile;
use softnc_gcode::MotionKind;
use softnc_planner::PlanOptions;

/// Pieces an arc or helix is cut into to integrate ds / v(s) (its speed varies
/// along it with its tangent).
const ARC_PIECES: usize = 256;
/// Longest piece a line is cut into for the stop bound's speed envelope (mm).
const LINE_PIECE_MM: f64 = 0.25;

/// A piece of the programmed path for the stop bound: its length, the highest speed
/// on it (curvature bound) and the largest tangential acceleration there; `stop`:
/// the path rests at its start.
struct Piece {
    ds: f64,
    v: f64,
    a: f64,
    stop: bool,
}

/// The stop bound's time over `pieces` (the path rests at the first piece's start and
/// the last piece's end, and at every piece marked `stop`).
fn stop_bound_s(pieces: &[Piece]) -> f64 {
    let n = pieces.len();
    // speed² reachable at each piece's end from the last stop behind it, and before it
    let mut fwd = vec![0.0f64; n];
    let mut v2 = 0.0f64;
    for (k, p) in pieces.iter().enumerate() {
        if p.stop {
            v2 = 0.0;
        }
        v2 = (v2 + 2.0 * p.a * p.ds).min(p.v * p.v);
        fwd[k] = v2;
    }
    let mut total = 0.0;
    let mut v2_back = 0.0f64; // speed² at piece k's end within reach of the stop ahead
    for k in (0..n).rev() {
        let p = &pieces[k];
        let start_back = (v2_back + 2.0 * p.a * p.ds).min(p.v * p.v);
        let start_fwd = if k == 0 || p.stop { 0.0 } else { fwd[k - 1] };
        // the higher of the two ends' speeds (each the lower of both reaches)
        let v_end = fwd[k].min(v2_back).sqrt();
        let v_start = start_fwd.min(start_back).sqrt();
        let v = v_end.max(v_start).min(p.v);
        if v > 0.0 {
            total += p.ds / v;
        }
        v2_back = if p.stop { 0.0 } else { start_back };
    }
    total
}

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
    let (mut total_s, mut total_curve_s, mut total_stop_s) = (0.0, 0.0, 0.0);
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
        let (bound_s, curve_s, stop_s) = bounds(&program, &vmax, &amax);
        total_s += bound_s;
        total_curve_s += curve_s;
        total_stop_s += stop_s;
        println!("{file}: {bound_s:.3} s curvature {curve_s:.3} s stops {stop_s:.3} s");
    }
    println!(
        "feed_bound: total {total_s:.3} s, with curvature {total_curve_s:.3} s, with stops {total_stop_s:.3} s"
    );
}

/// A program's three bounds (s): acceleration-free, curvature, stops.
fn bounds(program: &softnc_gcode::Program, vmax: &[f64; 3], amax: &[f64; 3]) -> (f64, f64, f64) {
    let a_norm = amax.iter().map(|a| a * a).sum::<f64>().sqrt();
    let (mut bound_s, mut curve_s) = (0.0, 0.0);
    let mut pieces: Vec<Piece> = Vec::new();
    // the path rests before the next piece; the kind of the last move (traverse)
    let (mut rest, mut last_traverse) = (true, None::<bool>);
    let mut dwells_s = 0.0;
    for m in &program.motions {
        match m.kind {
            MotionKind::Dwell { .. } | MotionKind::Pause { .. } => rest = true,
            _ => {}
        }
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
                dwells_s += seconds;
                continue;
            }
            _ => continue,
        };
        let Some(prim) = softnc_planner::build::motion_primitive(m) else {
            continue;
        };
        let len = prim.length();
        if len.is_nan() || len <= 0.0 {
            continue;
        }
        let n_pieces = match m.kind {
            MotionKind::Arc { .. } => ARC_PIECES,
            _ => 1,
        };
        let traverse = matches!(m.kind, MotionKind::Traverse { .. });
        if last_traverse.is_some_and(|t| t != traverse) {
            rest = true;
        }
        last_traverse = Some(traverse);
        let is_arc = matches!(m.kind, MotionKind::Arc { .. });
        let ds = len / n_pieces as f64;
        for k in 0..n_pieces {
            let s = (k as f64 + 0.5) * ds;
            let t = prim.tangent_at(s);
            let v = feed.min(axis_speed(vmax, t.0));
            bound_s += ds / v;
            let v_curve = curve_speed(amax, t.0, curvature(&prim, s), v);
            curve_s += ds / v_curve;
            let a = if is_arc {
                a_norm
            } else {
                axis_speed(amax, t.0)
            };
            let cuts = if is_arc {
                1
            } else {
                (ds / LINE_PIECE_MM).ceil().max(1.0) as usize
            };
            for c in 0..cuts {
                pieces.push(Piece {
                    ds: ds / cuts as f64,
                    v: v_curve,
                    a,
                    stop: rest && k == 0 && c == 0,
                });
            }
        }
        rest = m.path_mode == softnc_gcode::PathMode::ExactStop;
    }
    (bound_s, curve_s, stop_bound_s(&pieces) + dwells_s)
}
