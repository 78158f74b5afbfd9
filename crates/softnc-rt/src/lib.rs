//! Real-time loop support for softnc's cyclic processes.
//!
//! - [`PeriodicClock`]: fixed-period cycles on absolute deadlines (the next deadline is
//!   the previous one plus the period, never "now plus the period", so no drift),
//!   with a short spin before each deadline for low jitter.
//! - [`LoopStats`]: histograms of period jitter and compute time (p50/p99/p99.9/max),
//!   allocated once, recorded without allocating.
//! - [`setup_realtime`]: core pinning, SCHED_FIFO and mlockall when permitted; warn and
//!   continue when not.
#![warn(missing_docs)]

pub mod clock;
pub mod setup;
pub mod stats;

pub use clock::PeriodicClock;
pub use setup::{leave_realtime, setup_realtime, RtOptions, RtReport};
pub use stats::{unix_ns, LatencyStats, LoopStats, Percentiles};
