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

/// [`read_program`] for long programs: the motions go to `sink` as they are read, in
/// chunks of `chunk` (the last one shorter), and the returned [`Program`] has none.
/// `sink` gets the interpreter's buffer; whatever it leaves there is dropped, and the
/// buffer (or one it swaps in) is reused for the next chunk. On an error, the
/// chunks handed over before it are all that `sink` gets.
pub fn read_program_chunked(
    text: &str,
    file: &str,
    profile: &MachineProfile,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<Program, GcodeError> {
    interp::read_chunked(text, file, profile, chunk.max(1), sink)
}
