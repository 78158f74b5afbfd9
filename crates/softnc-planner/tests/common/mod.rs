//! Shared helpers for planner tests: programs built from motions, and the checks.
#![allow(dead_code)]

use softnc_core::{FeedProfile, MotionProfile, Plane, Primitive, Vec3};
use softnc_gcode::{Motion, MotionKind, PathMode, Program};
use softnc_planner::{plan, Plan, PlanOptions, Sample};

pub fn profile(feed_profile: FeedProfile) -> MotionProfile {
    let text = include_str!("../../../../config/machines/default.ron");
    let mut p = MotionProfile::from_ron_str(text, "default.ron").unwrap();
    p.planner.feed_profile = feed_profile;
    p
}

/// Build programs motion by motion.
pub struct Builder {
    pub pos: Vec3,
    pub motions: Vec<Motion>,
    pub mode: PathMode,
}

impl Builder {
    pub fn new(start: Vec3) -> Self {
        Builder {
            pos: start,
            motions: vec![],
            mode: PathMode::default(),
        }
    }
    fn push(&mut self, kind: MotionKind) {
        let line = self.motions.len() as u32 + 1;
        self.motions.push(Motion {
            line,
            start: self.pos,
            kind,
            offset_mm: Vec3::ZERO,
            path_mode: self.mode,
            inch: false,
            canon_end: kind.end().unwrap_or(self.pos),
            canon_center: Vec3::ZERO,
            spindle_rpm: 0.0,
        });
        if let Some(e) = kind.end() {
            self.pos = e;
        }
    }
    pub fn rapid(&mut self, x: f64, y: f64, z: f64) -> &mut Self {
        self.push(MotionKind::Traverse {
            end: Vec3::new(x, y, z),
        });
        self
    }
    pub fn line(&mut self, x: f64, y: f64, z: f64, f: f64) -> &mut Self {
        self.push(MotionKind::Feed {
            end: Vec3::new(x, y, z),
            feed_mm_per_min: f,
        });
        self
    }
    pub fn arc(&mut self, end: Vec3, center: Vec3, plane: Plane, turns: i32, f: f64) -> &mut Self {
        self.push(MotionKind::Arc {
            end,
            center,
            plane,
            turns,
            feed_mm_per_min: f,
        });
        self
    }
    /// M0 here.
    pub fn pause(&mut self) -> &mut Self {
        self.push(MotionKind::Pause { optional: false });
        self
    }
    /// A machine operation here.
    pub fn machine(&mut self, op: softnc_gcode::MachineOp) -> &mut Self {
        self.push(MotionKind::Machine(op));
        self
    }
    pub fn dwell(&mut self, s: f64) -> &mut Self {
        self.push(MotionKind::Dwell { seconds: s });
        self
    }
    pub fn program(&self) -> Program {
        Program {
            file: "test.ngc".into(),
            blocks: self.motions.len(),
            motions: self.motions.clone(),
            warnings: vec![],
            end_modal: String::new(),
            subroutine_files: vec![],
            messages: vec![],
            log_files: vec![],
            awaits_probe: None,
        }
    }
}

pub fn plan_of(b: &Builder, p: &MotionProfile) -> Plan {
    plan(
        &b.program(),
        p,
        &PlanOptions {
            ignore_soft_limits: true,
            ..Default::default()
        },
    )
    .expect("plans")
}

pub fn run(plan: &Plan) -> Vec<Sample> {
    let planned = plan.stats().samples as usize;
    let v: Vec<Sample> = plan.interpolator().take(planned + 1000).collect();
    assert!(
        v.len() <= planned + 10,
        "stream ran past its planned {planned} samples"
    );
    v
}

/// Largest ratio of |finite-difference derivative| to its limit over all axes, for
/// velocity, acceleration and jerk.
pub fn limit_ratios(samples: &[Sample], p: &MotionProfile) -> [f64; 3] {
    let t = p.interpolation_cycle_s;
    let (vm, am, jm) = (p.max_vel(), p.max_acc(), p.max_jerk());
    let mut r = [0.0f64; 3];
    for w in samples.windows(4) {
        for i in 0..3 {
            let x = [
                w[0].pos_mm[i],
                w[1].pos_mm[i],
                w[2].pos_mm[i],
                w[3].pos_mm[i],
            ];
            let v = (x[1] - x[0]) / t;
            let a = (x[2] - 2.0 * x[1] + x[0]) / (t * t);
            let j = (x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0]) / (t * t * t);
            r[0] = r[0].max(v.abs() / vm[i]);
            r[1] = r[1].max(a.abs() / am[i]);
            r[2] = r[2].max(j.abs() / jm[i]);
        }
    }
    r
}

/// Distance of `q` from a finite primitive.
pub fn distance(prim: &Primitive, q: Vec3) -> f64 {
    match *prim {
        Primitive::Line { start, end } => {
            let d = end - start;
            let l2 = d.dot(d);
            let u = if l2 > 0.0 {
                ((q - start).dot(d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (q - (start + d * u)).norm()
        }
        Primitive::Arc { .. } => {
            // radial error plus distance along the normal from the helix
            let n = 400;
            let len = prim.length();
            (0..=n)
                .map(|i| (prim.point_at(len * i as f64 / n as f64) - q).norm())
                .fold(f64::INFINITY, f64::min)
                .min(prim.contour_error(q).abs().max(0.0) + f64::INFINITY)
        }
    }
}

/// Largest distance of any sample from the programmed path (the motions near it).
pub fn max_path_deviation(samples: &[Sample], plan: &Plan, n_motions: usize) -> f64 {
    let mut worst = 0.0f64;
    for s in samples {
        let m = s.motion as usize;
        let mut best = f64::INFINITY;
        for k in m.saturating_sub(2)..(m + 3).min(n_motions) {
            if let Some(p) = plan.motion_primitive(k) {
                let d = match p {
                    Primitive::Line { .. } => distance(&p, s.pos_mm),
                    Primitive::Arc { .. } => p.contour_error(s.pos_mm).abs(),
                };
                best = best.min(d);
            }
        }
        if best.is_finite() {
            worst = worst.max(best);
        }
    }
    worst
}
