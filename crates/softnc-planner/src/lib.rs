//! softnc's lookahead motion planner and interpolator.
//!
//! Canonical motions (from `softnc-gcode`) become a continuous path in machine
//! coordinates: straight lines and exact arcs, corners blended within a tolerance or
//! stopped at exactly. An [`Interpolator`] walks that path at the interpolation cycle
//! T, one [`Sample`] per call, without allocating, honouring every axis's velocity,
//! acceleration (and, with the S-curve profile, jerk) limit and a live feed override.
#![warn(missing_docs)]

pub mod plan;

pub use plan::{plan, Interpolator, Plan, PlanError, PlanOptions, PlanStats, Sample};
