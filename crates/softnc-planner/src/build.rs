//! From canonical motions to path segments: machine coordinates, blends at corners
//! (G64), exact stops (G61/G9), per-segment limits and junction speeds.

use crate::path::{element_limits, Geom};
use softnc_core::{FeedProfile, MachineProfile, Primitive, Vec3};
use softnc_gcode::{MotionKind, PathMode, Program};

/// Fraction of every axis limit the planner plans to, so that rounding never takes
/// a sample past 1.00× of a limit.
pub const LIMIT_MARGIN: f64 = 0.98;
/// Share of an axis's acceleration that a small tangent discontinuity between two
/// elements may use, per sample (trapezoidal; the S-curve profile stops at them).
pub const KINK_SHARE: f64 = 0.01;
/// S-curve: share of the jerk limit spent on tangential jerk.
pub const SCURVE_TANGENTIAL_JERK_SHARE: f64 = 0.4;
/// S-curve: share of the jerk limit spent on centripetal jerk terms on curves.
pub const SCURVE_CURVE_JERK_SHARE: f64 = 0.15;
/// S-curve: share of the jerk limit spent on a curvature step between elements
/// (sampled, so a step of Δa appears as ≤ Δa·3/(4T)).
pub const SCURVE_CURVATURE_STEP_SHARE: f64 = 0.25;
/// S-curve: a corner is blended only if the blend can be taken at this share of the
/// speed around it; otherwise the path stops at the corner.
pub const SCURVE_MIN_BLEND_SPEED_SHARE: f64 = 0.1;
/// Corners turning more than this (rad) are never blended: the path reverses.
pub const MAX_BLEND_TURN_RAD: f64 = 3.1;
/// Direction changes below this (in |Δt|) are treated as tangent-continuous.
pub const TANGENT_EPS: f64 = 1e-9;

/// S-curve: the speed at which the centripetal jerk terms on a curve use their share
/// of the jerk limit: κ²v³ ≤ budget and 3κ·v·a_t ≤ budget.
fn scurve_curve_cap(geom: &Geom, lim: &Limits) -> f64 {
    let k = geom.curvature();
    if k <= 0.0 {
        return f64::INFINITY;
    }
    let j_min = lim.jmax.iter().cloned().fold(f64::INFINITY, f64::min);
    let budget = SCURVE_CURVE_JERK_SHARE * j_min;
    (budget / (k * k))
        .cbrt()
        .min(budget / (3.0 * k * lim.scurve_acc))
}

/// One element of the planned path with its limits.
#[derive(Debug, Clone, Copy)]
pub struct Segment {
    /// Geometry (machine coordinates).
    pub geom: Geom,
    /// Arc length at the start of this element from the start of the path (mm).
    pub s0: f64,
    /// Length (mm).
    pub len: f64,
    /// Index of the program motion this element belongs to.
    pub motion: u32,
    /// True for G1/G2/G3 (and their blends).
    pub feed_move: bool,
    /// Programmed feed (mm/s); infinite for traverses.
    pub feed_mm_per_s: f64,
    /// Hard speed limit on the element (axis velocities, curvature).
    pub vel_cap: f64,
    /// Tangential acceleration limit (mm/s²).
    pub acc: f64,
    /// Hard speed limit at the end (junction with the next element); 0 = stop.
    pub v_end_hard: f64,
    /// Time to stand still at the end (G4 dwell), s.
    pub dwell_s: f64,
}

/// What the builder needs from the machine profile.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Per-axis velocity limits with the margin applied (mm/s).
    pub vmax: [f64; 3],
    /// Per-axis acceleration limits with the margin applied (mm/s²).
    pub amax: [f64; 3],
    /// Per-axis jerk limits with the margin applied (mm/s³).
    pub jmax: [f64; 3],
    /// Interpolation cycle T (s).
    pub cycle_s: f64,
    /// Default blend tolerance (mm).
    pub tolerance_mm: f64,
    /// Feed profile shape.
    pub profile: FeedProfile,
    /// S-curve only: global tangential acceleration (mm/s²).
    pub scurve_acc: f64,
    /// S-curve only: smoothing window (s).
    pub scurve_window_s: f64,
}

impl Limits {
    /// Limits of a machine profile.
    pub fn from_profile(p: &MachineProfile) -> Limits {
        let vmax = p.max_vel().map(|v| v * LIMIT_MARGIN);
        let amax = p.max_acc().map(|v| v * LIMIT_MARGIN);
        let jmax = p.max_jerk().map(|v| v * LIMIT_MARGIN);
        let a_min = amax.iter().cloned().fold(f64::INFINITY, f64::min);
        let j_min = jmax.iter().cloned().fold(f64::INFINITY, f64::min);
        let scurve_acc = crate::path::ARC_TANGENTIAL_SHARE * a_min;
        // Moving average of length W on s(t): |s'''| ≤ 2·a/W.
        let w = 2.0 * scurve_acc / (SCURVE_TANGENTIAL_JERK_SHARE * j_min);
        let cycle_s = p.interpolation_cycle_s;
        let window = (w / cycle_s).ceil().max(1.0) * cycle_s;
        Limits {
            vmax,
            amax,
            jmax,
            cycle_s,
            tolerance_mm: p.planner.tolerance_mm,
            profile: p.planner.feed_profile,
            scurve_acc,
            scurve_window_s: window,
        }
    }
}

struct Move {
    prim: Primitive,
    motion: u32,
    feed_move: bool,
    feed_mm_per_s: f64,
    exact_stop: bool,
    tolerance_mm: f64,
    dwell_s: f64,
}

/// Programmed primitive of every motion in machine coordinates (None for dwells).
pub fn motion_primitives(program: &Program) -> Vec<Option<Primitive>> {
    program
        .motions
        .iter()
        .map(|m| {
            let off = m.offset_mm;
            match m.kind {
                MotionKind::Traverse { end } | MotionKind::Feed { end, .. } => {
                    Some(Primitive::Line {
                        start: m.start + off,
                        end: end + off,
                    })
                }
                MotionKind::Arc {
                    end,
                    center,
                    plane,
                    turns,
                    ..
                } => Some(Primitive::arc(
                    m.start + off,
                    end + off,
                    center + off,
                    plane,
                    turns,
                )),
                MotionKind::Dwell { .. } => None,
            }
        })
        .collect()
}

/// Build the segment list.
pub fn build_segments(
    program: &Program,
    prims: &[Option<Primitive>],
    lim: &Limits,
) -> Vec<Segment> {
    // 1. Moves in machine coordinates; dwells become stops with a dwell time.
    let mut moves: Vec<Move> = Vec::with_capacity(program.motions.len());
    let mut pending_dwell_at_start = 0.0;
    let mut last_point: Option<Vec3> = None;
    for (i, m) in program.motions.iter().enumerate() {
        let (exact, tol) = match m.path_mode {
            PathMode::ExactStop => (true, lim.tolerance_mm),
            PathMode::Blend { tolerance_mm } => match tolerance_mm {
                Some(p) if p > 0.0 => (false, p),
                _ => (false, lim.tolerance_mm),
            },
        };
        match (m.kind, prims[i]) {
            (MotionKind::Dwell { seconds }, _) => {
                if let Some(last) = moves.last_mut() {
                    last.exact_stop = true;
                    last.dwell_s += seconds.max(0.0);
                } else {
                    pending_dwell_at_start += seconds.max(0.0);
                    last_point.get_or_insert(m.start + m.offset_mm);
                }
            }
            (kind, Some(prim)) => {
                if prim.length() < 1e-9 {
                    continue;
                }
                let (feed_move, feed) = match kind {
                    MotionKind::Traverse { .. } => (false, f64::INFINITY),
                    MotionKind::Feed {
                        feed_mm_per_min, ..
                    }
                    | MotionKind::Arc {
                        feed_mm_per_min, ..
                    } => (true, feed_mm_per_min / 60.0),
                    MotionKind::Dwell { .. } => unreachable!(),
                };
                if last_point.is_none() {
                    last_point = Some(prim.start());
                }
                moves.push(Move {
                    prim,
                    motion: i as u32,
                    feed_move,
                    feed_mm_per_s: feed,
                    exact_stop: exact,
                    tolerance_mm: tol,
                    dwell_s: 0.0,
                });
            }
            _ => {}
        }
    }

    let mut segs: Vec<Segment> = Vec::with_capacity(moves.len() * 2 + 1);
    if pending_dwell_at_start > 0.0 {
        let p = last_point.unwrap_or(Vec3::ZERO);
        segs.push(Segment {
            geom: Geom::Prim(Primitive::Line { start: p, end: p }),
            s0: 0.0,
            len: 0.0,
            motion: 0,
            feed_move: false,
            feed_mm_per_s: f64::INFINITY,
            vel_cap: f64::INFINITY,
            acc: 1.0,
            v_end_hard: 0.0,
            dwell_s: pending_dwell_at_start,
        });
    }

    // 2. Blends at line-line corners: trim both lines, insert a tangent arc.
    let n = moves.len();
    let mut start_trim = vec![0.0f64; n];
    let mut blends: Vec<Option<Geom>> = vec![None; n];
    for i in 0..n.saturating_sub(1) {
        let (a, b) = (&moves[i], &moves[i + 1]);
        if a.exact_stop || a.dwell_s > 0.0 {
            continue;
        }
        let (Primitive::Line { start: a0, end: a1 }, Primitive::Line { start: b0, end: b1 }) =
            (a.prim, b.prim)
        else {
            continue;
        };
        let u1 = (a1 - a0).unit();
        let u2 = (b1 - b0).unit();
        let cos_t = u1.dot(u2).clamp(-1.0, 1.0);
        let theta = cos_t.acos();
        if (u2 - u1).norm() <= TANGENT_EPS || theta > MAX_BLEND_TURN_RAD {
            continue;
        }
        let half = 0.5 * theta;
        let la = (a1 - a0).norm();
        let lb = (b1 - b0).norm();
        let avail_a = (0.5 * la).min(la - start_trim[i]);
        let d_max = avail_a.min(0.5 * lb);
        let r_tol = a.tolerance_mm.min(b.tolerance_mm) / (1.0 / half.cos() - 1.0);
        let r_len = d_max / half.tan();
        let r = r_tol.min(r_len);
        if r.is_nan() || r <= 1e-9 {
            continue;
        }
        let d = r * half.tan();
        let p1 = a1 - u1 * d;
        let nrm = (u2 - u1 * cos_t).unit();
        let center = p1 + nrm * r;
        let blend = Geom::Blend {
            center,
            e1: -nrm,
            e2: u1,
            radius: r,
            sweep: theta,
        };
        if lim.profile == FeedProfile::SCurve {
            // A blend so tight that the jerk limit crawls through it is slower than
            // stopping: stop at the corner instead.
            let through = scurve_curve_cap(&blend, lim);
            let vmin = lim.vmax.iter().cloned().fold(f64::INFINITY, f64::min);
            let around = a.feed_mm_per_s.min(b.feed_mm_per_s).min(vmin);
            if through < SCURVE_MIN_BLEND_SPEED_SHARE * around {
                continue;
            }
        }
        blends[i] = Some(blend);
        start_trim[i + 1] = d;
        // the end trim of move i is recorded through the blend's start point
    }

    // 3. Elements in order with their limits.
    let mut s0 = 0.0;
    for (i, m) in moves.iter().enumerate() {
        let mut prim = m.prim;
        if let Primitive::Line { start, end } = prim {
            let u = (end - start).unit();
            let st = start + u * start_trim[i];
            let en = match blends[i] {
                Some(Geom::Blend {
                    center, e1, radius, ..
                }) => center + e1 * radius,
                _ => end,
            };
            prim = Primitive::Line {
                start: if start_trim[i] > 0.0 { st } else { start },
                end: en,
            };
        }
        let mut push = |geom: Geom, dwell: f64, stop: bool, segs: &mut Vec<Segment>| {
            let len = geom.length();
            if len < 1e-9 && !stop && dwell == 0.0 {
                return; // a line used up entirely by the blends at both its ends
            }
            let el = element_limits(&geom, lim.vmax, lim.amax);
            let mut vel_cap = el.vel_mm_per_s;
            let mut acc = el.acc_mm_per_s2;
            if lim.profile == FeedProfile::SCurve {
                acc = acc.min(lim.scurve_acc);
                vel_cap = vel_cap.min(scurve_curve_cap(&geom, lim));
            }
            segs.push(Segment {
                geom,
                s0,
                len,
                motion: m.motion,
                feed_move: m.feed_move,
                feed_mm_per_s: m.feed_mm_per_s,
                vel_cap,
                acc,
                v_end_hard: if stop { 0.0 } else { f64::INFINITY },
                dwell_s: dwell,
            });
            s0 += len;
        };
        let stop = m.exact_stop || m.dwell_s > 0.0 || i + 1 == n;
        match blends[i] {
            Some(b) => {
                push(Geom::Prim(prim), 0.0, false, &mut segs);
                push(b, 0.0, false, &mut segs);
            }
            None => push(Geom::Prim(prim), m.dwell_s, stop, &mut segs),
        }
    }
    if let Some(last) = segs.last_mut() {
        last.v_end_hard = 0.0;
    }

    // 4. Junction speeds between consecutive elements.
    for k in 0..segs.len().saturating_sub(1) {
        if segs[k].v_end_hard == 0.0 {
            continue;
        }
        let (a, b) = (segs[k], segs[k + 1]);
        let mut v = a.vel_cap.min(b.vel_cap);
        let dt = b.geom.start_tangent() - a.geom.end_tangent();
        if dt.norm() > TANGENT_EPS && lim.profile == FeedProfile::SCurve {
            // a tangent break at speed is a jerk impulse: stop there
            segs[k].v_end_hard = 0.0;
            continue;
        }
        if dt.norm() > TANGENT_EPS {
            for i in 0..3 {
                let di = dt[i].abs();
                if di > 1e-12 {
                    let lim_i = KINK_SHARE * lim.amax[i] * lim.cycle_s;
                    v = v.min(lim_i / di);
                }
            }
        }
        if lim.profile == FeedProfile::SCurve {
            let dk = b.geom.curvature_vec(false) - a.geom.curvature_vec(true);
            for i in 0..3 {
                let di = dk[i].abs();
                if di > 1e-12 {
                    let budget =
                        SCURVE_CURVATURE_STEP_SHARE * lim.jmax[i] * lim.cycle_s * 4.0 / 3.0;
                    v = v.min((budget / di).sqrt());
                }
            }
        }
        segs[k].v_end_hard = v;
    }
    if lim.profile == FeedProfile::SCurve {
        dilate_caps(&mut segs, lim.scurve_window_s, lim.scurve_acc);
    }
    segs
}

/// S-curve: the smoothed position lags the acceleration-limited one, so a hard speed
/// limit c (an element's cap or a junction's limit) must already hold on the
/// acceleration-limited profile within R = max(W·c, (c² + a²W²)/(2a)) of where it
/// applies (W the window, a the path acceleration): inside, the window sees no faster
/// motion; outside, braking at a keeps v ≤ distance/W. Stops are not spread: the
/// profile waits one window at them.
fn dilate_caps(segs: &mut [Segment], window_s: f64, acc: f64) {
    let n = segs.len();
    let mut dilated: Vec<f64> = segs.iter().map(|s| s.vel_cap).collect();
    let reach =
        |c: f64| (window_s * c).max((c * c + acc * acc * window_s * window_s) / (2.0 * acc));
    // (limit, start, end) of each constraint along the path
    let spread = |c: f64, from: f64, to: f64, k: usize, dilated: &mut [f64]| {
        let r = reach(c);
        dilated[k] = dilated[k].min(c);
        let mut j = k;
        while j > 0 && segs[j - 1].s0 + segs[j - 1].len >= from - r {
            j -= 1;
            dilated[j] = dilated[j].min(c);
        }
        let mut j = k + 1;
        while j < n && segs[j].s0 <= to + r {
            dilated[j] = dilated[j].min(c);
            j += 1;
        }
    };
    for (k, seg) in segs.iter().enumerate() {
        let (a, b) = (seg.s0, seg.s0 + seg.len);
        if seg.len > 0.0 {
            spread(seg.vel_cap, a, b, k, &mut dilated);
        }
        let v = seg.v_end_hard;
        if v > 0.0 && v.is_finite() {
            spread(v, b, b, k, &mut dilated);
        }
    }
    for k in 0..n {
        segs[k].vel_cap = dilated[k];
        let next = if k + 1 < n { dilated[k + 1] } else { 0.0 };
        segs[k].v_end_hard = segs[k].v_end_hard.min(dilated[k]).min(next);
    }
}
