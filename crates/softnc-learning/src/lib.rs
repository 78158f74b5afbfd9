//! Repetition-domain learning for jobs that run again and again.
//!
//! - [`markov`]: paper 002 eq 5 — P_j(k) = P_{j−1}(k) + s·Σ_{i=1..p} CA^{i−1}B·e_{j−1}(k+i),
//!   with the Markov parameters identified from a measured impulse response.
//! - [`radius_ilc`]: paper 004 eq 8–9 — per-degree radius learning for circles.
//! - [`store`]: corrections persisted per job, keyed by job content, machine profile
//!   and feed override, written atomically.
//! - [`entry`]: what an entry holds (`Learned`), where the store is, and a job's
//!   stored Markov correction as the daemon and `softnc sim --learned` apply it.
#![warn(missing_docs)]

pub mod entry;
pub mod markov;
pub mod radius_ilc;
pub mod store;

pub use entry::{store_dir, IterationStats, JobCorrection, Law, LawState, Learned, Lookup};
pub use markov::{identify_markov, Improvement, MarkovLearner};
pub use radius_ilc::RadiusIlc;
pub use store::{LearningKey, LearningStore, StoreError};
