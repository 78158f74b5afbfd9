//! Planning entry point: program → checked segments → [`Plan`] with its figures.

use crate::build::{motion_primitive, Limits, Path, PathBuilder, Segment};
use crate::interp::Interpolator;
use softnc_core::{FeedProfile, MachineProfile, Primitive, Vec3};
use softnc_gcode::Program;

/// Options for one planning run.
#[derive(Debug, Clone, Default)]
pub struct PlanOptions {
    /// Do not refuse motions outside the soft limits (offline analysis only).
    pub ignore_soft_limits: bool,
}

/// Why a program cannot be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A motion leaves the machine's travel.
    #[error("{file}:{line}:1: soft limit: {axis} would reach {pos_mm:.4} mm, outside [{min_mm}, {max_mm}] mm")]
    SoftLimit {
        /// File.
        file: String,
        /// Source line of the motion.
        line: u32,
        /// Axis letter.
        axis: char,
        /// Position reached (machine coordinates).
        pos_mm: f64,
        /// Lower soft limit.
        min_mm: f64,
        /// Upper soft limit.
        max_mm: f64,
    },
}

/// Figures of a planned program.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanStats {
    /// Path length of all moves (mm).
    pub path_length_mm: f64,
    /// Planned run time at 100 % override (s).
    pub duration_s: f64,
    /// Number of samples at the interpolation cycle.
    pub samples: u64,
    /// Highest programmed feed of a feed move (mm/min).
    pub max_feed_mm_min: f64,
    /// Bounding box of the path, machine coordinates (mm).
    pub bounds_min_mm: Vec3,
    /// Bounding box of the path, machine coordinates (mm).
    pub bounds_max_mm: Vec3,
}

/// A planned program: the path elements with their limits, ready to interpolate.
#[derive(Debug, Clone)]
pub struct Plan {
    path: Path,
    n_motions: usize,
    lim: Limits,
    brake_dist_mm: f64,
    max_override: f64,
    stats: PlanStats,
}

/// Plan a program for a machine: soft limits first, then blending and limits.
pub fn plan(
    program: &Program,
    profile: &MachineProfile,
    options: &PlanOptions,
) -> Result<Plan, PlanError> {
    let lim = Limits::from_profile(profile);
    let mut builder = PathBuilder::new(&lim, program.motions.len());
    let mut bmin = Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let mut bmax = -bmin;
    let mut max_feed: f64 = 0.0;
    for (i, m) in program.motions.iter().enumerate() {
        let prim = motion_primitive(m);
        if let Some(p) = &prim {
            let (lo, hi) = bounding_box(p);
            if !options.ignore_soft_limits {
                for (i, axis) in profile.axes.iter().enumerate() {
                    for v in [lo[i], hi[i]] {
                        if v < axis.min_mm - 1e-9 || v > axis.max_mm + 1e-9 {
                            return Err(PlanError::SoftLimit {
                                file: program.file.clone(),
                                line: m.line,
                                axis: axis.name.chars().next().unwrap_or('?'),
                                pos_mm: v,
                                min_mm: axis.min_mm,
                                max_mm: axis.max_mm,
                            });
                        }
                    }
                }
            }
            bmin = bmin.min(lo);
            bmax = bmax.max(hi);
            match m.kind {
                softnc_gcode::MotionKind::Feed {
                    feed_mm_per_min, ..
                }
                | softnc_gcode::MotionKind::Arc {
                    feed_mm_per_min, ..
                } => max_feed = max_feed.max(feed_mm_per_min),
                _ => {}
            }
        }
        builder.push(i, m, prim);
    }
    if !bmin[0].is_finite() {
        bmin = Vec3::ZERO;
        bmax = Vec3::ZERO;
    }
    let path_length_mm = builder.length_mm();
    let path = builder.finish();
    let segs = &path.segs;
    let (mut v_top, mut a_min) = (0.0f64, f64::INFINITY);
    for s in segs {
        if s.vel_cap.is_finite() {
            v_top = v_top.max(s.vel_cap);
        }
        a_min = a_min.min(s.acc);
    }
    let brake_dist_mm = if a_min.is_finite() && a_min > 0.0 {
        v_top * v_top / (2.0 * a_min)
    } else {
        0.0
    };
    let duration_s = planned_duration(segs, &lim);
    let samples = (duration_s / lim.cycle_s - 1e-9).ceil().max(0.0) as u64 + 1;
    let stats = PlanStats {
        path_length_mm,
        duration_s,
        samples,
        max_feed_mm_min: max_feed,
        bounds_min_mm: bmin,
        bounds_max_mm: bmax,
    };
    Ok(Plan {
        path,
        n_motions: program.motions.len(),
        lim,
        brake_dist_mm,
        max_override: profile.planner.max_feed_override,
        stats,
    })
}

impl Plan {
    /// Figures of the plan.
    pub fn stats(&self) -> PlanStats {
        self.stats.clone()
    }
    /// The programmed path of motion `index` in machine coordinates (None for dwells).
    pub fn motion_primitive(&self, index: usize) -> Option<Primitive> {
        if index >= self.n_motions {
            return None;
        }
        self.path.motion_primitive(index)
    }
    /// Number of program motions (dwells included).
    pub fn motions(&self) -> usize {
        self.n_motions
    }
    /// Number of path elements (programmed pieces and blends).
    pub fn elements(&self) -> usize {
        self.path.segs.len()
    }
    /// The interpolation cycle T (s).
    pub fn cycle_s(&self) -> f64 {
        self.lim.cycle_s
    }
    /// A fresh sample stream from the start of the program. Everything it needs is
    /// allocated here; pulling samples allocates nothing.
    pub fn interpolator(&self) -> Interpolator<'_> {
        Interpolator::new(
            &self.path.segs,
            &self.path.geoms,
            self.lim, self.brake_dist_mm, self.max_override)
    }
}

/// Planned run time at 100 % override: forward and backward passes over the whole
/// path, then each element's time-optimal profile, plus dwells and S-curve settling.
fn planned_duration(segs: &[Segment], lim: &Limits) -> f64 {
    let n = segs.len();
    if n == 0 {
        return 0.0;
    }
    let cap = |s: &Segment| s.vel_cap.min(s.feed_mm_per_s);
    // backward: highest speed at the end of each element
    let mut vend = vec![0.0f64; n];
    let mut next_start = 0.0f64;
    for k in (0..n).rev() {
        let s = &segs[k];
        vend[k] = s.v_end_hard.min(next_start).min(cap(s));
        next_start = cap(s).min((vend[k] * vend[k] + 2.0 * s.acc * s.len).sqrt());
    }
    // forward
    let mut t = 0.0;
    let mut v0 = 0.0f64;
    let settle = match lim.profile {
        FeedProfile::SCurve => lim.scurve_window_s,
        FeedProfile::Trapezoidal => 0.0,
    };
    for (k, s) in segs.iter().enumerate() {
        let c = cap(s);
        let v1 = vend[k].min((v0 * v0 + 2.0 * s.acc * s.len).sqrt());
        if s.len > 0.0 {
            let vp = c.min(((v0 * v0 + v1 * v1) / 2.0 + s.acc * s.len).sqrt());
            let d_acc = (vp * vp - v0 * v0) / (2.0 * s.acc);
            let d_dec = (vp * vp - v1 * v1) / (2.0 * s.acc);
            let cruise = (s.len - d_acc - d_dec).max(0.0);
            t += (vp - v0).max(0.0) / s.acc
                + (vp - v1).max(0.0) / s.acc
                + if vp > 0.0 { cruise / vp } else { 0.0 };
        }
        if s.v_end_hard == 0.0 {
            t += s.dwell_s + settle;
        }
        v0 = v1;
    }
    t
}

/// Axis-aligned bounding box of a primitive.
fn bounding_box(p: &Primitive) -> (Vec3, Vec3) {
    let (s, e) = (p.start(), p.end());
    let (mut lo, mut hi) = (s.min(e), s.max(e));
    if let Primitive::Arc {
        center,
        plane,
        radius,
        start_angle,
        sweep,
        ..
    } = *p
    {
        let (a, b, _) = plane.axes();
        // cardinal angles crossed by the sweep
        for q in 0..4 {
            let ang = q as f64 * std::f64::consts::FRAC_PI_2;
            let rel = if sweep >= 0.0 {
                (ang - start_angle).rem_euclid(std::f64::consts::TAU)
            } else {
                (start_angle - ang).rem_euclid(std::f64::consts::TAU)
            };
            if rel <= sweep.abs() {
                let mut pt = center;
                pt[a] += radius * ang.cos();
                pt[b] += radius * ang.sin();
                lo = lo.min(pt);
                hi = hi.max(pt);
            }
        }
    }
    (lo, hi)
}
