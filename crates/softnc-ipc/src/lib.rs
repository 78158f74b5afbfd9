//! softnc's messages between processes: fixed-size `#[repr(C)]` iceoryx2 payloads
//! (no heap, no pointers, no serialisation on the hot path) and the service names;
//! the node and services every process and operator client opens the same way
//! ([`bus`]), and the permissions of iceoryx2's files against other local users
//! ([`ipc_guard`]).
//!
//! ```
//! use softnc_ipc::{CommandSample, ServiceNames};
//! let names = ServiceNames::new("softnc", "mill1");
//! assert_eq!(names.command(), "softnc/mill1/command");
//! let s = CommandSample::new(7, 1, 7, [1.0, 2.0, 3.0]);
//! assert_eq!(s.pos_mm[..3], [1.0, 2.0, 3.0]);
//! ```
#![warn(missing_docs)]

pub mod bus;
pub mod fixed_str;
pub mod ipc_guard;
pub mod names;
pub mod payload;

pub use fixed_str::{FixedStr, TooLong};
pub use names::ServiceNames;
pub use payload::{
    Alarm, AlarmCode, CommandSample, ControlCommand, ControlKind, EStopRequest, Heartbeat,
    InputsWire, LoopStats, MachineState, OperatorReply, OperatorRequest, OutputsWire,
    PositionStatus, ProcessId, SimPanel, JOB_ADAPTIVE_FORCE, MAX_AXES,
};
