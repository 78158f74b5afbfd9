//! softnc's position-control stack: one controller per axis, stepped once per
//! position cycle by the daemon and by the offline simulator alike.
//!
//! - [`pid`]: incremental PID (paper 001 eq 14) — P and PI are the same law.
//! - [`stack`]: the per-axis stack (feedback, velocity/acceleration feedforward,
//!   limits); later compensators slot in here.
//! - [`zero_lag_fir`]: zero-lag non-causal command filter (paper 002 eq 1–3).
#![warn(missing_docs)]

pub mod compensation;
pub mod config;
pub mod discrete_tf;
pub mod dob;
pub mod fuzzy;
pub mod mbda;
pub mod pdc;
pub mod pid;
pub mod stack;
pub mod zero_lag_fir;

pub use pid::IncrementalPid;
pub use stack::{AxisController, ControlOutput, Feedback};
pub use zero_lag_fir::ZeroLagFir;
