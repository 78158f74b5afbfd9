//! softnc core: the types every other crate shares.
//!
//! - [`axes`]: the one axis type: [`Axis`] (LinuxCNC's nine letters) and
//!   [`Axes<T>`], one value per axis the stack carries ([`MAX_AXES`]).
//! - [`geom`]: 3-vectors in mm and the path primitives (lines, arcs/helices) that the
//!   G-code front end produces, the planner follows and the contour-error metric measures.
//! - [`config`]: the motion part of a machine profile in RON, validated; a bad field
//!   fails with its RON path. The whole profile (with the servo and force sections)
//!   is `softnc-machine`'s.
//! - [`ron_file`]: RON configuration files read with the path of a bad field, and
//!   [`ConfigError`], the error every section's validation reports.
//! - [`ring`]: the lookahead ring of command samples and its sizing rule.
//! - [`machine_io`]: the machine around the axes as the processes exchange it:
//!   [`MachineOutputs`] on every command sample, [`MachineInputs`] in every status.
//! - [`store`]: atomic file writes (job history, learning stores).
//! - [`taken`]: files a controller runs, taken in safely (regular, bounded, read once).
//!
//! ```
//! let profile = softnc_core::config::MotionProfile::from_ron_str(
//!     include_str!("../../../config/machines/default.ron"), "default.ron").unwrap();
//! assert_eq!(profile.axes.len(), 3);
//! ```
#![warn(missing_docs)]

pub mod axes;
pub mod config;
pub mod geom;
pub mod machine_io;
pub mod ring;
pub mod ron_file;
pub mod store;
pub mod taken;

pub use axes::{Axes, Axis, ALL_AXES};
pub use config::{
    AccDec, AxisConfig, AxisHoming, ConfigError, FeedProfile, HomingConfig, JogConfig,
    MachineTables, MotionProfile, PlannerConfig, SpindleConfig, ToolEntry,
};
pub use geom::{Plane, Primitive, Vec3};
pub use machine_io::{MachineInputs, MachineOutputs, SpindleDir};

/// Axes the whole stack carries, X, Y, Z: the one axis count of the profile, the
/// servo boundary, the learning store and the messages between the processes.
pub const MAX_AXES: usize = 3;
pub use ring::{CommandRing, LookaheadRing, RingError, RingSample, COMMAND_RING_CAPACITY};
