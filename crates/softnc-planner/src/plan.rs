//! Planning entry point and the sample stream (API fixed; implementation in progress).

use softnc_core::{MachineProfile, Primitive, Vec3};
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

/// One command sample at the interpolation cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Cycle index from the start of the job (time = index · T).
    pub index: u64,
    /// Command position, machine coordinates (mm).
    pub pos_mm: Vec3,
    /// Index into the program's motions of the motion being executed.
    pub motion: u32,
    /// True while that motion is a feed move (G1/G2/G3), false for traverses/dwells.
    pub feed_move: bool,
}

/// A planned program.
#[derive(Debug, Clone)]
pub struct Plan {
    _private: (),
}

/// Pulls samples from a plan, one per interpolation cycle.
pub struct Interpolator<'a> {
    _plan: &'a Plan,
}

/// Plan a program for a machine.
pub fn plan(
    program: &Program,
    profile: &MachineProfile,
    options: &PlanOptions,
) -> Result<Plan, PlanError> {
    let _ = (program, profile, options);
    unimplemented!("planner in progress")
}

impl Plan {
    /// Figures of the plan.
    pub fn stats(&self) -> PlanStats {
        unimplemented!()
    }
    /// The programmed path of motion `index` in machine coordinates (None for dwells).
    pub fn motion_primitive(&self, index: usize) -> Option<Primitive> {
        let _ = index;
        unimplemented!()
    }
    /// A fresh sample stream from the start of the program.
    pub fn interpolator(&self) -> Interpolator<'_> {
        Interpolator { _plan: self }
    }
}

impl Interpolator<'_> {
    /// Set the live feed override (0.0 ..= profile max, e.g. 2.55); applied smoothly.
    pub fn set_feed_override(&mut self, fraction: f64) {
        let _ = fraction;
    }
}

impl Iterator for Interpolator<'_> {
    type Item = Sample;
    fn next(&mut self) -> Option<Sample> {
        unimplemented!()
    }
}
