//! softnc's servo boundary: what every drive implements, and the position cycle
//! that runs in front of it — the same for the daemon, the offline simulator and
//! the learning runs.
//!
//! - [`backend`]: the [`ServoBackend`] trait every drive implements (enable/disable,
//!   commands, counts, status), its errors, and the simulation-only extension.
//! - [`engine`]: one position cycle — encoders → controller stacks → drives.
//! - [`design`]: the error of an axis's compensation design (engine and spindle).
//! - [`spindle`]: S words in a running job: PDC designs per spindle speed, swapped
//!   at the cycle.
//! - [`io`]: the I/O boundary beside it (raw lines and the spindle) and the
//!   logical map of the machine's named signals onto them ([`io::MachineIo`]).
//! - [`trace`]: the per-cycle trace row and its CSV format.
//! - [`loopback`]: a backend without dynamics (dry runs).
//! - [`conformance`]: the checks every backend passes.
//! - [`adaptive_feed`]: paper 003's force loop on a running job (currents in,
//!   feed override out) and the interpolator's schedule of its overrides.
#![warn(missing_docs)]

pub mod adaptive_feed;
pub mod backend;
pub mod conformance;
pub mod contour;
pub mod design;
pub mod engine;
pub mod io;
pub mod loopback;
pub mod spindle;
pub mod trace;

pub use backend::{
    AxisStatus, BackendError, BusFault, BusStats, CommandMode, IfName, PhaseCurrents, Positions,
    ServoBackend, SimulatedMachine, MAX_AXES,
};
pub use design::CompensationDesignError;
pub use engine::{CycleEngine, CycleRecord, EngineError};
pub use io::{IoLines, MachineIo, RawInputs, RawOutputs};
pub use loopback::LoopbackBackend;
pub use trace::TraceRow;
