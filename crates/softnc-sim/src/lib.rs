//! softnc's simulated servo backend and offline simulator, built from the papers'
//! identified machines, seeded and bit-reproducible. The boundary it implements and
//! the position cycle in front of it are `softnc-servo`'s; the plant models it
//! assembles into an axis are `softnc-plant`'s.
//!
//! ```
//! use softnc_sim::{simulate, simulated_engine, CommandSample, SimOptions};
//! let profile = softnc_machine::MachineProfile::from_ron_str(
//!     include_str!("../../../config/machines/default.ron"), "default.ron").unwrap();
//! let mut engine = simulated_engine(&profile, 7, SimOptions::default());
//! // 100 ms of a 10 mm/s move along X
//! let t = profile.interpolation_cycle_s;
//! let samples = (0..100).map(|k| CommandSample {
//!     pos_mm: softnc_core::Axes([10.0 * t * k as f64, 0.0, 0.0]), motion: 0, feed_move: false,
//!     outputs: Default::default() });
//! let report = simulate(&mut engine, t, samples, |_| None, |_| {}).unwrap();
//! assert_eq!(report.cycles, 100);
//! ```
#![warn(missing_docs)]

/// The simulated machine [`SimBackend`] behind the servo boundary.
pub mod backend;
/// Max / RMS / mean of an error signal.
pub mod metrics;
/// End-milling force process (paper 003 eq 2–4) and the cut's depth/material profile.
pub mod milling;
/// One simulated axis: the profile's model with its seeded variation.
pub mod plant;
/// PMSM feed motor and its phase-current sensors (paper 003 eq 24–30).
pub mod pmsm;
/// Running a job: samples in, errors and trace out.
pub mod sim;
/// The stock on the table and the feed motor cutting through it (paper 003).
pub mod workpiece;

pub use backend::{wiring, SimBackend, SimOptions};
pub use metrics::ErrorStats;
pub use plant::Plant;
pub use sim::{
    simulate, simulate_adaptive, simulate_observed, simulate_sequenced, CommandSample,
    OverridableSamples, SimReport,
};
pub use softnc_plant::Rng;

use softnc_machine::MachineProfile;
use softnc_servo::CycleEngine;

/// The simulated machine of `profile` with its controllers, seeded by `seed`.
///
/// # Panics
/// When the profile's disturbance compensation or command filter cannot be
/// designed; see [`CycleEngine::try_new`].
pub fn simulated_engine(
    profile: &MachineProfile,
    seed: u64,
    options: SimOptions,
) -> CycleEngine<SimBackend> {
    CycleEngine::new(profile, SimBackend::new(profile, seed, options))
}
