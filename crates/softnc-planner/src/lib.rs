//! softnc's lookahead motion planner and interpolator.
//!
//! Canonical motions (from `softnc-gcode`) become a continuous path in machine
//! coordinates: straight lines and exact arcs, corners blended within a tolerance or
//! stopped at exactly. An [`Interpolator`] walks that path at the interpolation cycle
//! T, one [`Sample`] per call, without allocating, honouring every axis's velocity,
//! acceleration (and, with the S-curve profile, jerk) limit and a live feed override.
//!
//! - [`path`]: path elements (lines, arcs, blend arcs) and their limits from the axes'.
//! - [`build`]: motions → elements: blending, exact stops, junction speeds.
//! - [`interp`]: the sample stream (time-optimal, lookahead, override, S-curve).
//! - [`plan`](mod@plan): the entry point and the plan's figures.
//! - [`stream`]: a plan streamed through a bounded window (long programs).
//! - [`manual`]: jog and homing motion between jobs, one axis at a time.
//! - [`machine_sequencer`]: the machine around the axes during a job (outputs per
//!   sample, when the path leaves a machine stop).
#![warn(missing_docs)]

pub mod build;
pub mod fillet;
pub mod interp;
pub mod machine_sequencer;
pub mod manual;
pub mod path;
pub mod plan;
pub mod stream;
#[cfg(test)]
mod test_programs;

pub use build::StopKind;
pub use interp::{Interpolator, Sample};
pub use plan::{
    plan, read_and_plan, read_and_plan_parallel, Plan, PlanError, PlanOptions, PlanStats,
    ReadPlanError,
};
pub use stream::{
    check_and_stream, check_program, check_program_parallel, check_program_parallel_bytes,
    stream_program, CheckedProgram, StreamInterpolator, StreamMode, StreamProducer,
};
