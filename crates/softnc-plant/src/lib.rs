//! The papers' identified machines as plant models, each seeded and
//! bit-reproducible, with their configuration. `softnc-sim` assembles them into a
//! simulated axis behind the servo boundary; a new plant model goes here.
//!
//! ```
//! use softnc_plant::first_order_lag::FirstOrderLag;
//! // paper 004 eq 1: G(s) = 1/(1 + Ts), T = 10 ms, no stick; a 1 mm step for one T
//! let mut lag = FirstOrderLag::new(0.01, 0.0, 0.0);
//! for _ in 0..10 { lag.substep(1.0, 0.001); }
//! assert!((lag.pos_mm() - (1.0 - (-1.0f64).exp())).abs() < 1e-12);
//! ```
#![warn(missing_docs)]

/// The plant sections of a machine profile, with their validation.
pub mod config;
/// Periodic cutting disturbance (paper 000 eq 2–3).
pub mod cutting_disturbance;
/// DC servo with friction eq 15 and stick–slip (paper 001).
pub mod dc_motor;
/// Encoder noise and quantisation.
pub mod encoder;
/// First-order-lag servo with stick at reversals (paper 004 eq 1).
pub mod first_order_lag;
/// A lightly damped structural mode between motor and table.
pub mod resonance;
/// Seeded generator (xoshiro256**, SplitMix64, Box–Muller).
pub mod rng;
/// A spindle with inertia, a torque-limited drive and its own encoder.
pub mod spindle;
/// Karnopp stick–slip friction.
pub mod stick_slip;
/// Identified discrete velocity loops (paper 000 eq 35, 36).
pub mod velocity_loop;

pub use config::{CuttingDisturbance, Friction001, PlantModel, SpindleModel, StructuralMode};
pub use rng::Rng;
