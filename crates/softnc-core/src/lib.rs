//! softnc core: the types every other crate shares.
//!
//! - [`axes`]: the one axis type: [`Axis`] (LinuxCNC's nine letters) and
//!   [`Axes<T>`], one value per axis the stack carries ([`MAX_AXES`]).
//! - [`geom`]: 3-vectors in mm and the path primitives (lines, arcs/helices) that the
//!   G-code front end produces, the planner follows and the contour-error metric measures.
//! - [`config`]: machine profiles in RON, validated; a bad field fails with its RON path.
//! - [`servo`]: the servo side of a profile: plant models, controllers, disturbances.
//! - [`force`]: the adaptive cutting-force control section (paper 003).
//! - [`ring`]: the lookahead ring of command samples.
//! - [`store`]: atomic file writes (job history, learning stores).
//! - [`taken`]: files a controller runs, taken in safely (regular, bounded, read once).
//!
//! ```
//! let profile = softnc_core::config::MachineProfile::from_ron_str(
//!     include_str!("../../../config/machines/default.ron"), "default.ron").unwrap();
//! assert_eq!(profile.axes.len(), 3);
//! ```
#![warn(missing_docs)]

pub mod axes;
/// Paper 000's compensation section: owned by `softnc-control`.
pub use softnc_control::config::compensation;
pub mod config;
/// The adaptive cutting-force section (paper 003): owned by `softnc-adaptive`,
/// composed into the profile here.
pub use softnc_adaptive::config as force;
/// Paper 001's fuzzy-controller section: owned by `softnc-control`.
pub use softnc_control::config::fuzzy;
pub mod geom;
pub mod ring;
pub mod servo;
pub mod store;
pub mod taken;

pub use axes::{Axes, Axis, ALL_AXES};
pub use config::{
    AccDec, AxisConfig, AxisHoming, ConfigError, FeedProfile, HomingConfig, JogConfig,
    MachineProfile, PlannerConfig, SpindleConfig, ToolEntry,
};
pub use geom::{Plane, Primitive, Vec3};

/// Axes the whole stack carries, X, Y, Z: the one axis count of the profile, the
/// servo boundary, the learning store and the messages between the processes.
pub const MAX_AXES: usize = 3;
pub use ring::{CommandRing, LookaheadRing, RingError, RingSample, COMMAND_RING_CAPACITY};
