//! softnc's RS274/NGC front end (written by hand: no maintained crate reads LinuxCNC's
//! dialect with its modal-group rules and errors).
//!
//! Read a program into canonical motions:
//!
//! ```no_run
//! let profile = softnc_core::MachineProfile::load("config/machines/default.ron".as_ref()).unwrap();
//! let program = softnc_gcode::read_program("G21 G90\nG1 X10 F600\nM2\n", "demo.ngc", &profile).unwrap();
//! assert_eq!(program.motions.len(), 1);
//! ```
#![warn(missing_docs)]

pub mod canon;
pub mod error;
pub mod interp;
pub mod lexer;

pub use canon::{Motion, MotionKind, PathMode, Program};
pub use error::{ErrorKind, GcodeError};

use softnc_core::MachineProfile;

/// Read a whole program: lex, parse and interpret it with the machine's tool table and
/// work offsets. The first error stops reading.
pub fn read_program(
    text: &str,
    file: &str,
    profile: &MachineProfile,
) -> Result<Program, GcodeError> {
    interp::read(text, file, profile)
}
