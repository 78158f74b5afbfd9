//! softnc's RS274/NGC front end (written by hand: no maintained crate reads LinuxCNC's
//! dialect with its modal-group rules and errors).
//!
//! Read a program into canonical motions:
//!
//! ```no_run
//! let profile = softnc_core::MotionProfile::load("config/machines/default.ron".as_ref()).unwrap();
//! let program = softnc_gcode::read_program("G21 G90\nG1 X10 F600\nM2\n", "demo.ngc", &profile).unwrap();
//! assert_eq!(program.motions.len(), 1);
//! ```
#![warn(missing_docs)]

pub mod canon;
pub mod compiled;
pub mod error;
pub mod expr;
pub mod interp;
pub mod lexer;
pub mod log_files;
pub mod norm;
mod oword;
pub mod params;
pub mod x87;

pub use canon::{
    CoolantLine, MachineOp, MessageKind, Motion, MotionKind, OverrideSwitch, PathMode, ProbeKind,
    Program, SpindleTurn, WaitInput, WaitMode,
};
pub use error::{ErrorKind, GcodeError};
pub use params::Params;

use softnc_core::MachineTables;
use std::path::PathBuf;

/// How a program is read beyond the machine profile.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// Folders searched, in order, for `NAME.ngc` when a program calls a
    /// subroutine `O<NAME>` it does not define (LinuxCNC's `SUBROUTINE_PATH`);
    /// after them the program's own folder.
    pub subroutine_path: Vec<PathBuf>,
    /// At most this many blocks (lines read, skipped lines included) before reading
    /// stops with [`ErrorKind::BlockLimit`]; `None`: one million more than the
    /// program has bytes, which a program without loops never reaches.
    pub block_limit: Option<u64>,
    /// Parameters at the start (e.g. read from a parameter file); `None`: all 0
    /// but the machine profile's work offsets.
    pub params: Option<Params>,
    /// Offsets and stored positions in parameters (5161-5390) are in inches, as
    /// LinuxCNC's stand-alone `rs274` keeps them when run without an INI file;
    /// `false` (default): in mm, the machine's unit (LinuxCNC with
    /// `[TRAJ]LINEAR_UNITS = mm`).
    pub parameters_in_inches: bool,
    /// Where the machine is when the program starts (machine coordinates, mm), as
    /// LinuxCNC's interpreter is synchronised with the machine before a program:
    /// the first motion starts there, and axes it does not name stay there.
    /// `None`: at the origin.
    pub start_mm: Option<softnc_core::Vec3>,
    /// G-code run before the program, without line numbers of its own: the modal
    /// state the machine's last MDI command or job left ([`Program::end_modal`]), as
    /// LinuxCNC's interpreter keeps it from one to the next. It may hold only modal
    /// words ([`preamble::check_line`]): anything else refuses the program.
    pub preamble: Option<String>,
    /// The file the preamble was read from, for its errors (`None`: "the machine's
    /// modal state").
    pub preamble_file: Option<String>,
    /// How subroutine files are found and read ([`SubroutineFiles`]).
    pub subroutines: SubroutineFiles,
    /// The optional-stop switch: M1 stops the program (a
    /// [`MotionKind::Pause`] with `optional: true`) only while it is on; off
    /// (default), M1 does nothing, as LinuxCNC with its switch off.
    pub optional_stop: bool,
    /// The block-delete switch: on, a line whose first character (spaces and tabs
    /// aside) is `/` is not read at all, as LinuxCNC's `read_text` makes it an empty
    /// line (O-lines and comments on it included). Off (default, as `rs274`'s
    /// driver starts): the `/` is ignored and the line runs.
    pub block_delete: bool,
    /// Run from line N (LinuxCNC's run-from-line): the program is read from its
    /// start with every motion before the start block left out (modal state,
    /// offsets, parameters and the current point evolve as if it ran). The start
    /// block is the first block of the main program, at call level 0 and not
    /// skipped, whose line number is at least N. Before it a safe approach is
    /// emitted from [`ReadOptions::start_mm`] (where the machine stands) as
    /// traverses with exact stops: Z up to max(machine Z, the start's Z), then X
    /// and Y, then Z down to the start point (where the start block's first motion
    /// starts), ended by a [`MotionKind::Sync`]. Refused (`file:N:1`) when line N
    /// lies in a subroutine definition, when no block at or after line N runs, or
    /// when no motion follows it.
    pub from_line: Option<u32>,
    /// The folder of the user M codes (M100–M199): `M1nn` there must be an
    /// executable file (LinuxCNC's `USER_M_PATH`), else the program is refused
    /// with `file:line` where it is used; `None`: every user M code is refused.
    pub user_m_codes: Option<PathBuf>,
    /// What a reading ahead does with M66's result in #5399 ([`M66Results`]).
    pub m66_results: M66Results,
    /// What a reading does at a probe move (G38.x), whose results only the machine
    /// knows ([`ProbeResults`]).
    pub probe_results: ProbeResults,
    /// `(LOGOPEN,…)` and `(LOGAPPEND,…)` are taken: the program's log files are
    /// collected in [`Program::log_files`] for the caller to write into its log
    /// folder ([`log_files::write`]). Off (default): they refuse the program as
    /// unsupported.
    pub log_files: bool,
}

/// M66 (wait for an input) puts the input's value in #5399 when the machine gets
/// there. LinuxCNC's interpreter stops reading ahead at an M66 and reads on once
/// the wait is done (`convert_m` sets `input_flag`, `execute_block` returns
/// `INTERP_EXECUTE_FINISH`, and the next `Interp::read` puts
/// `GET_EXTERNAL_DIGITAL_INPUT`/`GET_EXTERNAL_ANALOG_INPUT` in #5399: the input's
/// value, −1 after a timeout); softnc reads the whole program before motion, so it
/// cannot know the value. After an M66 #5399 holds the value rs274's stand-alone
/// interpreter gives it (digital: `#5399 != 0` as 0/1; analog: unchanged), and
/// this says whether a program may read it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum M66Results {
    /// A read of #5399 after an M66 refuses the program (`Unsupported`, at the
    /// `#5399` that reads it) — in an expression, an assignment, a word, an O-word
    /// condition: what moves never depends on a value the plan guessed — except in
    /// a `(DEBUG,…)` or `(PRINT,…)` comment, whose text keeps the place
    /// ([`M66_RESULT_MARK`]) for the machine sequencer to fill in with the value
    /// the machine gave when the path reaches it ([`write_message`]). Jobs are
    /// read so.
    #[default]
    Refuse,
    /// Read on with rs274's stand-in value, as its stand-alone interpreter does
    /// (`softnc plan --canon`, the conformance corpus).
    StandIn,
}

/// A probe move (G38.2–G38.5) ends where the probe trips, or at its end without
/// a trip; LinuxCNC's interpreter stops reading ahead there and, at its next
/// read, takes the machine's position as the current point and the trip in
/// #5061–#5069 (the probed position, program frame and units) and #5070 (1
/// tripped, 0 not: `set_probe_data`). What a reading does there.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum ProbeResults {
    /// A probe move refuses the program (`Unsupported`, at its `G38.x`): the
    /// machine does not run probe moves yet. Jobs are read so.
    #[default]
    Refuse,
    /// Read on with rs274's stand-in results, as its stand-alone interpreter
    /// (`saicanon.cc`): #5061–#5063 the move's end, #5064–#5069 0, #5070 0, and the
    /// current point the end backed off 0.254 mm (0.01 in) toward the start
    /// (`softnc plan --canon`, the conformance corpus). Such a reading is not
    /// planned: no machine ends there. With an XY rotation in force the point
    /// after the move can differ from rs274's in the third decimal (its
    /// stand-alone canon backs off from a start it keeps in a frame of its own).
    StandIn,
    /// The machine ran the program's first `results.len()` probe moves, in the
    /// order they run (loops and subroutines included), with these results: the
    /// reading is the continuation after the last of them — everything up to and
    /// including it is read but not handed on (it ran) — and ends after the next
    /// probe move, whose result the machine has yet to give
    /// ([`Program::awaits_probe`]). A G38.2/G38.4 that ended without a trip
    /// refuses the program at its line, as LinuxCNC's motion aborts it.
    Known(Vec<ProbeResult>),
}

/// What the machine reports of a probe move it ran ([`ProbeResults::Known`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeResult {
    /// The probe tripped (made or lost contact as the move asked).
    pub tripped: bool,
    /// Where it tripped (machine coordinates, mm); where the move stopped when
    /// it did not.
    pub probed_mm: softnc_core::Vec3,
    /// Where the machine stands after the move (machine coordinates, mm): the
    /// current point the program goes on from.
    pub stopped_mm: softnc_core::Vec3,
}

/// In a message text ([`Program::messages`]), the place of a `#5399` read after an
/// M66 (with [`M66Results::Refuse`]): this character, then one ASCII digit, the
/// decimals it is shown with (`%d`: 0, `%f`: 4, `%.Nf`: N, else 6).
pub const M66_RESULT_MARK: char = '\u{1}';

/// Writes `v` as a `(DEBUG,…)`/`(PRINT,…)` comment shows a parameter (LinuxCNC's
/// `convert_param_comment`: `%.Nf`, 0 within `TOLERANCE_EQUAL`, `######` where
/// the text would be 30 characters or more). Allocates nothing.
pub fn write_param_value(
    out: &mut impl std::fmt::Write,
    v: f64,
    decimals: usize,
) -> std::fmt::Result {
    struct Count(usize);
    impl std::fmt::Write for Count {
        fn write_str(&mut self, s: &str) -> std::fmt::Result {
            self.0 += s.len();
            Ok(())
        }
    }
    let v = if v.abs() < expr::TOLERANCE_EQUAL {
        0.0
    } else {
        v
    };
    let mut n = Count(0);
    std::fmt::Write::write_fmt(&mut n, format_args!("{v:.decimals$}"))?;
    if n.0 >= 30 {
        out.write_str("######")
    } else {
        out.write_fmt(format_args!("{v:.decimals$}"))
    }
}

/// Writes message text `text` with each [`M66_RESULT_MARK`] replaced by
/// `m66_result` as the comment shows a parameter ([`write_param_value`]), or by
/// `#5399` where no M66 has given a value (`None`). Allocates nothing.
pub fn write_message(
    out: &mut impl std::fmt::Write,
    text: &str,
    m66_result: Option<f64>,
) -> std::fmt::Result {
    let mut rest = text;
    while let Some(k) = rest.find(M66_RESULT_MARK) {
        out.write_str(&rest[..k])?;
        let after = &rest[k + M66_RESULT_MARK.len_utf8()..];
        let (decimals, tail) = match after.as_bytes().first() {
            Some(d) if d.is_ascii_digit() => (usize::from(d - b'0'), &after[1..]),
            _ => (6, after),
        };
        match m66_result {
            Some(v) => write_param_value(out, v, decimals)?,
            None => out.write_str("#5399")?,
        }
        rest = tail;
    }
    out.write_str(rest)
}

/// Whether message text `text` shows an M66 result filled in at run time.
pub fn message_shows_m66_result(text: &str) -> bool {
    text.contains(M66_RESULT_MARK)
}

/// A subroutine file a reading took in: found on the search path or beside the
/// program, read once ([`Program::subroutine_files`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SubroutineFile {
    /// The subroutine's name as called (`o<name> call`: `name`, lower case).
    pub name: String,
    /// Where it was found (its errors name this path).
    pub path: String,
    /// Its bytes as read.
    pub bytes: std::sync::Arc<[u8]>,
}

/// How subroutine files (`o<name> call` of a subroutine the program does not
/// define) are taken in: as a job is (a regular file of an ordinary file system, of
/// bounded size, read once: [`softnc_core::taken`]), or from the files a check took
/// in, so that what was checked is what runs.
#[derive(Debug, Clone, Default)]
pub struct SubroutineFiles {
    /// Most bytes of one subroutine file, and of all those a reading takes in
    /// together; `None`: no limit.
    pub max_bytes: Option<u64>,
    /// Only these files (a checked job's), matched by name; the folders are not
    /// searched and a subroutine not among them is not found.
    pub snapshot: Option<std::sync::Arc<Vec<SubroutineFile>>>,
}

/// The modal preamble ([`ReadOptions::preamble`]): only modal words.
pub mod preamble {
    pub use crate::interp::check_preamble_line as check_line;

    /// Whether every line of `text` (a preamble read from `file`) holds only modal
    /// words; the first that does not, by file, line and column.
    pub fn check(text: &str, file: &str) -> Result<(), crate::GcodeError> {
        for (i, l) in text.lines().enumerate() {
            check_line(l).map_err(|(off, kind)| crate::GcodeError {
                file: file.to_string(),
                line: i as u32 + 1,
                column: crate::lexer::column(l, off),
                kind,
            })?;
        }
        Ok(())
    }
}

/// [`read_program`] with [`ReadOptions`]; also returns the parameters as the
/// program left them.
pub fn read_program_with<'a>(
    text: &str,
    file: &str,
    tables: impl Into<MachineTables<'a>>,
    options: &ReadOptions,
) -> Result<(Program, Params), GcodeError> {
    interp::read_with(text, file, tables.into(), options, usize::MAX, &mut |_| {})
}

/// Read a whole program: lex, parse and interpret it with the machine's tool table and
/// work offsets. The first error stops reading.
pub fn read_program<'a>(
    text: &str,
    file: &str,
    tables: impl Into<MachineTables<'a>>,
) -> Result<Program, GcodeError> {
    interp::read(text, file, tables.into())
}

/// [`read_program`] for long programs: the motions go to `sink` as they are read, in
/// chunks of `chunk` (the last one shorter), and the returned [`Program`] has none.
/// `sink` gets the interpreter's buffer; whatever it leaves there is dropped, and the
/// buffer (or one it swaps in) is reused for the next chunk. On an error, the
/// chunks handed over before it are all that `sink` gets.
pub fn read_program_chunked<'a>(
    text: &str,
    file: &str,
    tables: impl Into<MachineTables<'a>>,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<Program, GcodeError> {
    interp::read_chunked(text, file, tables.into(), chunk.max(1), sink)
}

/// [`read_program_chunked`] with [`ReadOptions`].
pub fn read_program_chunked_with<'a>(
    text: &str,
    file: &str,
    tables: impl Into<MachineTables<'a>>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<Program, GcodeError> {
    interp::read_with(text, file, tables.into(), options, chunk.max(1), sink).map(|(p, _)| p)
}

/// [`read_program_chunked_with`] that also returns the parameters as the program
/// left them (what LinuxCNC writes back to its parameter file at the end, and a
/// daemon keeps for the next program: G10 L2/L20, G92, G28.1/G30.1 persist).
pub fn read_program_chunked_params<'a>(
    text: &str,
    file: &str,
    tables: impl Into<MachineTables<'a>>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<(Program, Params), GcodeError> {
    interp::read_with(text, file, tables.into(), options, chunk.max(1), sink)
}

/// [`read_program_chunked_params`] of a program's bytes, checked as UTF-8 where they
/// are read (a window at a time, not the whole text before its first line): the
/// same reading where they are UTF-8; where a line is not, the error
/// [`ErrorKind::NotUtf8`](crate::ErrorKind::NotUtf8), after which the caller reads
/// `String::from_utf8_lossy` of them with [`read_program_chunked_params`] (the
/// motions already handed to `sink` are to be dropped).
pub fn read_program_chunked_params_bytes<'a>(
    bytes: &[u8],
    file: &str,
    tables: impl Into<MachineTables<'a>>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<(Program, Params), GcodeError> {
    interp::read_bytes_with(bytes, file, tables.into(), options, chunk.max(1), sink)
}
