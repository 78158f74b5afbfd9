//! Adaptive cutting-force control (paper 003): keep the peak feed-direction cutting
//! force at a reference by driving the feed override.
//!
//! - [`config`]: the profile's `force` section (process, motor, calibration,
//!   controller, cases, adaptive feed, simulated stock) and its validation.
//! - [`zoh`]: the plant f_c/v_c = K_c d / ((1 + τ_s s)(1 + τ_c s)) discretised with a
//!   zero-order hold into the ARMA form of eq 8 (eq 5–7, derived anew: the printed
//!   eq 7 has typos).
//! - [`rls`]: on-line estimation of Θ = [−φ₁, −φ₂, θ₁, θ₂] (eq 11–12) by recursive
//!   least squares with covariance resetting and a dead zone.
//! - [`robust_servo`]: Davison's robust servo (eq 13–17) with the gains placing the
//!   four closed-loop poles exactly (a Diophantine equation, linear in four
//!   unknowns), and the closed-loop matrix of eq 20.
//! - [`park`]: Clarke/Park transform of the feed motor's phase currents to I_q
//!   (eq 25–27) and the linear force calibration (eq 31–32).
//! - [`force_estimate`]: I_q → force → peak per spindle revolution.
//! - [`force_control`]: the adaptive loop: RLS, pole placement, servo law, feed
//!   clamped to the override range and rate-limited.
//! - [`force_loop`]: the closed loop per interpolation cycle: phase currents in,
//!   once per spindle revolution the feed override out.
//!
//! Vectors and matrices are nalgebra's fixed-size types (no allocation per sample).
#![warn(missing_docs)]
// Index loops mirror the papers' matrix equations; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

pub mod config;
pub mod force_control;
pub mod force_estimate;
pub mod force_loop;
pub mod park;
pub mod rls;
pub mod robust_servo;
pub mod zoh;

pub use force_control::{AdaptiveForceControl, ControlStep, ForceControlConfig};
pub use force_estimate::{ForceEstimator, RevolutionPeak};
pub use force_loop::{ForceLoop, ForceLoopConfig, ForceLoopControl, Revolution};
pub use park::{park_iq, ForceCalibration};
pub use rls::{Rls, RlsConfig};
pub use robust_servo::{place_poles, PlacementError, RobustServo, ServoGains};
pub use zoh::{zoh_second_order, Arma2};
