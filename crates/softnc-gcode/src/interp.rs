//! The modal interpreter: lines of words → canonical motions, following LinuxCNC 2.9's
//! `rs274ngc` (`read_items`, `enhance_block`, `check_items`, `execute_block`): the same
//! modal groups, the same checks in the same order, the same execution order within a
//! block, the same arc geometry and tolerances, and its error messages.
//!
//! Positions are kept as LinuxCNC keeps them: in the program's units (inch after G20)
//! and in the active work coordinate system with the tool length offset applied, so
//! that the canonical output rounds exactly as `rs274` prints it. Motions carry them
//! converted to mm.

mod comp;
mod cycles;
mod fast;
mod machine;
mod modal;
pub(crate) mod ngc;
mod offsets;

use crate::canon::{MachineOp, MessageKind, Motion, MotionKind, PathMode, Program};
use crate::error::{ErrorKind, GcodeError};
use crate::lexer::{bad_character, column, lex_words, significant, Line, Word, SLOW};
use crate::norm::Norm;
use crate::params::Params;
use crate::ReadOptions;
use ngc::{Control, Jump, Pc, Setting};
use softnc_core::{MachineTables, Plane, Vec3};

use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, PI, SQRT_2};
use std::hash::BuildHasherDefault;

const MM_PER_INCH: f64 = 25.4;
/// R-format arcs: how far the radius may fall short of half the chord, and the
/// smallest radius of a centre-format arc (LinuxCNC `RADIUS_TOLERANCE_INCH`, and its
/// mm conversion).
const RADIUS_TOLERANCE_INCH: f64 = 0.00005;
const RADIUS_TOLERANCE_MM: f64 = RADIUS_TOLERANCE_INCH * MM_PER_INCH;
/// Centre-format arcs: the radius at the end may differ from the radius at the start
/// by this much absolutely (program units) when the relative difference exceeds
/// `SPIRAL_RELATIVE_TOLERANCE`, and never by 100 times this much.
const CENTER_ARC_RADIUS_TOLERANCE_INCH: f64 = 2.0 * 0.001 * SQRT_2;
const CENTER_ARC_RADIUS_TOLERANCE_MM: f64 = 2.0 * 0.01 * SQRT_2;
const SPIRAL_RELATIVE_TOLERANCE: f64 = 0.001;
/// R-format arcs: chord/diameter ratios above 1 - TINY are taken as a semicircle.
const TINY: f64 = 1e-12;
/// At most this many M codes on a line.
const MAX_EMS: usize = 4;
/// LinuxCNC reads lines into a 255-byte buffer: a line of 254 bytes or more (with its
/// newline) is "too long".
const LINELEN: usize = 255;

// modal groups (LinuxCNC's GM_* indices)
const GM_MODAL_0: usize = 0;
const GM_MOTION: usize = 1;
const GM_PLANE: usize = 2;
const GM_DISTANCE: usize = 3;
const GM_IJK_DISTANCE: usize = 4;
const GM_FEED_MODE: usize = 5;
const GM_UNITS: usize = 6;
const GM_CUTTER_COMP: usize = 7;
const GM_TOOL_LENGTH: usize = 8;
const GM_RETRACT: usize = 10;
const GM_COORD: usize = 12;
const GM_CONTROL: usize = 13;
const G_GROUPS: usize = 17;
const M_GROUPS: usize = 11;

// G codes × 10
const G_0: i32 = 0;
const G_1: i32 = 10;
const G_2: i32 = 20;
const G_3: i32 = 30;
const G_4: i32 = 40;
const G_53: i32 = 530;
const G_38_2: i32 = 382;
const G_38_5: i32 = 385;
const G_80: i32 = 800;
const G_90: i32 = 900;
const G_91: i32 = 910;

/// Modal groups of G codes (code × 10), as LinuxCNC 2.9's interpreter assigns them;
/// `None` is a code it does not know ("Unknown g code used").
fn g_group(code: i32) -> Option<usize> {
    Some(match code {
        40 | 53 | 100 | 280 | 281 | 300 | 301 | 520 | 530 | 920 => 0,
        0
        | 10
        | 20
        | 30
        | 50
        | 51
        | 52
        | 330
        | 331
        | 382..=385
        | 700
        | 710..=712
        | 720..=722
        | 730
        | 740
        | 760
        | 800
        | 810
        | 820
        | 830
        | 840
        | 850
        | 860
        | 870
        | 880
        | 890 => 1,
        170 | 171 | 180 | 181 | 190 | 191 => 2,
        900 | 910 => 3,
        901 | 911 => 4,
        930 | 940 | 950 => 5,
        200 | 210 => 6,
        400 | 410 | 411 | 420 | 421 => 7,
        430 | 431 | 432 | 490 => 8,
        980 | 990 => 10,
        540 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => 12,
        610 | 611 | 640 => 13,
        960 | 970 => 14,
        70 | 80 => 15,
        921..=923 => 16,
        _ => return None,
    })
}

/// Modal groups of M codes, as LinuxCNC 2.9 assigns them (M100..M199 are user codes).
fn m_group(code: i32) -> Option<usize> {
    Some(match code {
        0 | 1 | 2 | 30 | 60 | 99 => 4,
        62..=68 => 5,
        6 | 61 => 6,
        3 | 4 | 5 | 19 | 70..=73 => 7,
        7..=9 => 8,
        48..=53 => 9,
        100..=199 => 10,
        _ => return None,
    })
}

/// Why softnc refuses a G code LinuxCNC knows (`None`: supported).
fn g_unsupported(code: i32) -> Option<&'static str> {
    Some(match code {
        0
        | 10
        | 20
        | 30
        | 40
        | 80
        | 170
        | 180
        | 190
        | 200
        | 210
        | 400
        | 410
        | 411
        | 420
        | 421
        | 430
        | 490
        | 530
        | 540
        | 550
        | 560
        | 570
        | 580
        | 590..=593
        | 610
        | 611
        | 640
        | 800
        | 900
        | 910
        | 901
        | 911
        | 930
        | 940
        | 970
        | 980
        | 990
        | 100
        | 280
        | 281
        | 300
        | 301
        | 520
        | 431
        | 432
        | 920..=923 => return None,
        50..=53 => "splines (G5, G5.1, G5.2, G5.3) are not supported yet",
        70 => "lathe diameter mode (G7) is not supported",
        171 | 181 | 191 => "the UVW planes are not supported",
        330 | 331 => "spindle-synchronised motion (G33) is not supported",
        382..=385 => "probing (G38.x) is not run by the machine yet (`softnc plan --canon` reads it with rs274's stand-in results)",
        730 | 740 | 810..=870 | 890 => return None,
        700..=722 => "the lathe cycles G70, G71 and G72 are not supported yet",
        760 => "the threading cycle G76 needs spindle-synchronised motion, which softnc does not have yet",
        880 => "G88 stops for the operator to retract the spindle by hand; softnc cannot know where the program goes on from",
        950 => "feed per revolution (G95) is not supported",
        960 => "constant surface speed (G96) is not supported",
        _ => "this G code is not supported",
    })
}

/// Why softnc refuses an M code LinuxCNC knows (`None`: supported).
fn m_unsupported(code: i32) -> Option<&'static str> {
    Some(match code {
        0..=9 | 19 | 30 | 48..=53 | 61..=68 | 70..=73 | 100..=199 => return None,
        60 => "pallet change (M60) is not supported",
        99 => "M99 is not supported",
        _ => "this M code is not supported",
    })
}

fn fmt_code(letter: char, code10: i32) -> String {
    if code10 % 10 == 0 {
        format!("{letter}{}", code10 / 10)
    } else {
        format!("{letter}{}.{}", code10 / 10, code10 % 10)
    }
}

/// LinuxCNC's `round_to_int`.
fn round_to_int(x: f64) -> i32 {
    (x + 0.5).floor() as i32
}

/// One block's words sorted out (LinuxCNC's `block`). Each table has a bit mask of
/// the entries set on this line, so that emptying the block costs three stores.
struct Block {
    /// G code (× 10) and its offset per modal group.
    g: [(i32, u32); G_GROUPS],
    g_set: u32,
    /// M code and its offset per modal group.
    m: [(i32, u32); M_GROUPS],
    m_set: u32,
    m_count: usize,
    /// Value and offset per letter A..Z and the polar words `@` and `^` (P and Q:
    /// the last one read), at [`slot`].
    val: [(f64, u32); SLOTS],
    val_set: u32,
    /// LinuxCNC keeps P and Q as numbers with -1 meaning "none".
    p_number: f64,
    q_number: f64,
    motion_to_be: Option<i32>,
}

/// The letters of [`Block::val_set`] that a step of `Interp::execute` before the
/// motion reads, the feed rate aside (S, T; H for G43): a block without them, any
/// M code or any G code but its motion's takes the short way.
const NOT_MOTION_ONLY: u32 = letter_bit(b'S') | letter_bit(b'T') | letter_bit(b'H');

/// The letters `check_other_codes` tests (Q: `q_number` is set only with it).
const OTHER_CODES: u32 = letter_bit(b'D')
    | letter_bit(b'E')
    | letter_bit(b'H')
    | letter_bit(b'I')
    | letter_bit(b'J')
    | letter_bit(b'K')
    | letter_bit(b'L')
    | letter_bit(b'P')
    | letter_bit(b'Q')
    | letter_bit(b'R');

/// Slots of [`Block::val`]: A..Z at 0..25, `^` at 29, `@` at 31.
const SLOTS: usize = 32;

/// The slot of word letter `l` (A..Z, `@`, `^`) in [`Block::val`]: without a branch,
/// `^` and `@` fall on slots no letter uses.
const fn slot(l: u8) -> usize {
    (l.wrapping_sub(b'A') & (SLOTS as u8 - 1)) as usize
}

/// The bit of letter `l` in [`Block::val_set`].
const fn letter_bit(l: u8) -> u32 {
    1 << slot(l)
}

/// The polar-coordinate words `@` (distance) and `^` (angle, degrees).
const POLAR: u32 = letter_bit(b'@') | letter_bit(b'^');

impl Default for Block {
    fn default() -> Self {
        Block {
            g: [(0, 0); G_GROUPS],
            g_set: 0,
            m: [(0, 0); M_GROUPS],
            m_set: 0,
            m_count: 0,
            val: [(0.0, 0); SLOTS],
            val_set: 0,
            p_number: -1.0,
            q_number: -1.0,
            motion_to_be: None,
        }
    }
}

impl Block {
    /// Back to empty.
    fn clear(&mut self) {
        self.g_set = 0;
        self.m_set = 0;
        self.val_set = 0;
        self.m_count = 0;
        self.p_number = -1.0;
        self.q_number = -1.0;
        self.motion_to_be = None;
    }
    fn set_g(&mut self, group: usize, code: i32, off: u32) {
        self.g[group] = (code, off);
        self.g_set |= 1 << group;
    }
    fn set_m(&mut self, group: usize, code: i32, off: u32) {
        self.m[group] = (code, off);
        self.m_set |= 1 << group;
    }
    fn set_val(&mut self, l: u8, value: f64, off: u32) {
        self.val[slot(l)] = (value, off);
        self.val_set |= letter_bit(l);
    }
    fn get(&self, l: u8) -> Option<f64> {
        self.has(l).then(|| self.val[slot(l)].0)
    }
    fn off(&self, l: u8) -> u32 {
        if self.has(l) {
            self.val[slot(l)].1
        } else {
            0
        }
    }
    fn has(&self, l: u8) -> bool {
        self.val_set & letter_bit(l) != 0
    }
    /// A polar-coordinate word (`@` or `^`) is on the line.
    fn polar(&self) -> bool {
        self.val_set & POLAR != 0
    }
    /// Offset of the first polar word (for messages).
    fn polar_off(&self) -> u32 {
        [b'@', b'^']
            .iter()
            .filter(|l| self.has(**l))
            .map(|l| self.off(*l))
            .min()
            .unwrap_or(0)
    }
    /// No word on the line (a line of assignments or comments alone): no G or M
    /// code and no letter with a value (P and Q set their letter too).
    fn is_empty(&self) -> bool {
        self.g_set == 0 && self.m_set == 0 && self.val_set == 0
    }
    fn has_g(&self, group: usize) -> bool {
        self.g_set & (1 << group) != 0
    }
    fn g_in(&self, group: usize) -> Option<i32> {
        self.has_g(group).then(|| self.g[group].0)
    }
    fn g_off(&self, group: usize) -> u32 {
        if self.has_g(group) {
            self.g[group].1
        } else {
            0
        }
    }
    fn has_m(&self, group: usize) -> bool {
        self.m_set & (1 << group) != 0
    }
    fn m_in(&self, group: usize) -> Option<i32> {
        self.has_m(group).then(|| self.m[group].0)
    }
    fn m_off(&self, group: usize) -> u32 {
        if self.has_m(group) {
            self.m[group].1
        } else {
            0
        }
    }
    /// Offset of the first axis word (for messages).
    fn axis_off(&self) -> u32 {
        [b'X', b'Y', b'Z']
            .iter()
            .filter(|l| self.has(**l))
            .map(|l| self.off(*l))
            .min()
            .unwrap_or(0)
    }
    /// Offset of the motion G code, or else of the first axis word (for messages).
    fn motion_off(&self) -> u32 {
        if self.has_g(GM_MOTION) {
            self.g_off(GM_MOTION)
        } else {
            self.axis_off()
        }
    }
}

/// The interpreter's modal state.
struct Interp<'a> {
    tables: MachineTables<'a>,
    inch: bool,
    absolute: bool,
    ijk_absolute: bool,
    plane: Plane,
    inverse_time: bool,
    /// Feed rate in the program's units per minute (LinuxCNC's `feed_rate`).
    feed: f64,
    /// Motion mode (G code × 10); `None` for none or G80.
    motion: Option<i32>,
    /// Canned cycles retract to the level where the series began (G98, LinuxCNC's
    /// `OLD_Z`); else to the R plane (G99, `R_PLANE`, LinuxCNC's start).
    retract_old_z: bool,
    /// What canned cycles keep from one block to the next.
    cycle: cycles::CycleState,
    /// The feed and spindle override switches as M48–M51 and the tapping cycles
    /// leave them (LinuxCNC's canonical `fo_enable`, `so_enable`; on at the start).
    feed_override_on: bool,
    speed_override_on: bool,
    /// Current point, canonical frame, program units.
    pos: Vec3,
    /// The point as the canonical interface last saw it (motion ends, unit and origin
    /// changes, not tool length changes): after a tool change `rs274` re-reads its
    /// position from there.
    canon_pos: Vec3,
    /// A tool change happened: re-read the position before the next block.
    sync_pending: bool,
    /// Work coordinate system 0 = G54 … 8 = G59.3.
    coord: usize,
    /// Active tool length offset (mm).
    tool_length_mm: f64,
    /// Tool selected by T, tool in the spindle after M6, and its length (mm).
    tool_selected: u32,
    spindle_length_mm: f64,
    /// S word in force (rpm) and whether the spindle turns (M3/M4 vs M5).
    s_rpm: f64,
    spindle_on: bool,
    path: PathMode,
    motions: Vec<Motion>,
    warnings: Vec<String>,
    file: &'a str,
    /// Parameter table.
    params: Params,
    /// O-word control state.
    ctl: Control,
    /// Number of the line being read (`#<_line>`).
    line_no: usize,
    /// Active G54…G59.3 offset (program units; LinuxCNC `origin_offset`).
    origin: Vec3,
    /// G92/G52 offset (program units; LinuxCNC `axis_offset`).
    g92: Vec3,
    /// XY rotation of the active system (degrees; LinuxCNC `rotation_xy`, from
    /// parameter 5210 + 20·n): machine = R(point + g92) + origin + tool.
    rotation_deg: f64,
    /// Canonical frame → machine (mm): origin + g92 + tool length, kept up to date.
    offset_mm: Vec3,
    /// Parameters hold inches (see [`ReadOptions::parameters_in_inches`]).
    user_inch: bool,
    /// G43 active (else G49), for M70-M73.
    tool_offset_on: bool,
    /// The exact-stop code in force (610 or 611), for M70-M73.
    exact_stop_code: i32,
    /// The spindle M code in force (3, 4 or 5), for M70-M73.
    spindle_code: i32,
    /// Tool lengths (mm) set by G10 L1/L10/L11, over the profile's tool table.
    tool_edits: std::collections::HashMap<u32, f64>,
    /// Tool diameters (mm) and orientations set by G10 L1/L10/L11 R and Q, over
    /// the profile's tool table (diameter, orientation 0).
    tool_shape_edits: std::collections::HashMap<u32, (f64, i32)>,
    /// The diameter (mm) and orientation of the tool in the spindle (cutter
    /// compensation without D).
    spindle_shape: (f64, i32),
    /// Cutter radius compensation ([`comp`]).
    comp: comp::Comp,
    /// #5420–#5428 was read while compensation is on (an error at the line).
    position_read_in_comp: std::cell::Cell<bool>,
    /// Number of the tool in the spindle (M6, M61).
    tool_loaded: u32,
    /// Coolant (M7, M8; M9 turns both off), for `#<_mist>` and `#<_flood>`.
    mist: bool,
    flood: bool,
    /// Named parameters the line being read assigns: they exist from there on
    /// the line, with the value 0, as LinuxCNC's `add_named_param` makes them.
    /// Each name ends with a `>` (no name holds one); the buffer is reused.
    line_named: std::cell::RefCell<String>,
    /// The arguments of the last `call` read (`read_o`), for `control` to pass: kept
    /// here, not in the `OLine`, so that a read O-line is small to move.
    call_args: std::cell::RefCell<Vec<f64>>,
    /// The optional-stop switch ([`ReadOptions::optional_stop`]).
    optional_stop: bool,
    /// Run from line: motions are left out (the state evolves) until the start
    /// block ([`ReadOptions::from_line`]).
    suppress: bool,
    /// Moves kept after the safe approach of a run from line.
    moves_after_start: u64,
    /// Where the machine stood when reading began (machine coordinates, mm).
    start_machine_mm: Vec3,
    /// Texts of the operator messages read ([`Program::messages`]).
    messages: Vec<String>,
    /// Whether `(LOGOPEN,…)` is taken ([`ReadOptions::log_files`]).
    log_files_on: bool,
    /// The log files written so far ([`crate::log_files`]).
    log_files: crate::log_files::LogFiles,
    /// The user M-code folder ([`ReadOptions::user_m_codes`]).
    user_m: machine::UserMCodes,
    /// [`ReadOptions::m66_results`].
    m66_results: crate::M66Results,
    /// [`ReadOptions::probe_results`].
    probe_results: crate::ProbeResults,
    /// Probe moves read so far.
    probes_read: usize,
    /// The line of a probe move whose result is not known: reading stops after
    /// its block ([`crate::ProbeResults::Known`]).
    awaits_probe: Option<u32>,
    /// The line of the first M66 read while its result is unknown to the reading
    /// (`M66Results::Refuse`).
    m66_unknown_since: Option<u32>,
    /// #5399 was read since the M66 of `m66_unknown_since`.
    m66_read: std::cell::Cell<bool>,
}

type R<T> = Result<T, (u32, ErrorKind)>;

fn bad<T>(off: u32, msg: impl Into<String>) -> R<T> {
    Err((off, ErrorKind::Invalid(msg.into())))
}

fn unsup<T>(off: u32, word: String, why: &str) -> R<T> {
    Err((
        off,
        ErrorKind::Unsupported {
            word,
            why: why.into(),
        },
    ))
}

impl<'a> Interp<'a> {
    fn new(file: &'a str, tables: MachineTables<'a>) -> Self {
        Interp {
            tables,
            inch: false,
            absolute: true,
            ijk_absolute: false,
            plane: Plane::XY,
            inverse_time: false,
            feed: 0.0,
            motion: None,
            retract_old_z: false,
            cycle: cycles::CycleState::default(),
            feed_override_on: true,
            speed_override_on: true,
            pos: Vec3::ZERO,
            canon_pos: Vec3::ZERO,
            sync_pending: false,
            coord: 0,
            tool_length_mm: 0.0,
            tool_selected: 0,
            spindle_length_mm: 0.0,
            s_rpm: 0.0,
            spindle_on: false,
            path: PathMode::default(),
            motions: Vec::new(),
            warnings: Vec::new(),
            file,
            params: Params::default(),
            ctl: Control::default(),
            line_no: 0,
            origin: Vec3::ZERO,
            g92: Vec3::ZERO,
            rotation_deg: 0.0,
            offset_mm: Vec3::ZERO,
            user_inch: false,
            tool_offset_on: false,
            exact_stop_code: 610,
            spindle_code: 5,
            tool_edits: std::collections::HashMap::new(),
            tool_shape_edits: std::collections::HashMap::new(),
            spindle_shape: (0.0, 0),
            comp: comp::Comp::default(),
            position_read_in_comp: std::cell::Cell::new(false),
            tool_loaded: 0,
            mist: false,
            flood: false,
            line_named: std::cell::RefCell::new(String::new()),
            call_args: std::cell::RefCell::new(Vec::new()),
            optional_stop: false,
            suppress: false,
            moves_after_start: 0,
            start_machine_mm: Vec3::ZERO,
            messages: Vec::new(),
            log_files_on: false,
            log_files: crate::log_files::LogFiles::default(),
            user_m: machine::UserMCodes::default(),
            m66_results: crate::M66Results::default(),
            probe_results: crate::ProbeResults::default(),
            probes_read: 0,
            awaits_probe: None,
            m66_unknown_since: None,
            m66_read: std::cell::Cell::new(false),
        }
    }

    /// A copy of the modal state for the short way's cross-check in debug builds
    /// ([`Interp::fast_lines`]): everything but the motions and warnings so far and
    /// the O-word control state, which no line of the short way reads or changes
    /// (it runs only outside a skip).
    #[cfg(debug_assertions)]
    fn copy_for_cross_check(&self) -> Interp<'a> {
        Interp {
            tables: self.tables,
            inch: self.inch,
            absolute: self.absolute,
            ijk_absolute: self.ijk_absolute,
            plane: self.plane,
            inverse_time: self.inverse_time,
            feed: self.feed,
            motion: self.motion,
            retract_old_z: self.retract_old_z,
            cycle: self.cycle,
            feed_override_on: self.feed_override_on,
            speed_override_on: self.speed_override_on,
            pos: self.pos,
            canon_pos: self.canon_pos,
            sync_pending: self.sync_pending,
            coord: self.coord,
            tool_length_mm: self.tool_length_mm,
            tool_selected: self.tool_selected,
            spindle_length_mm: self.spindle_length_mm,
            s_rpm: self.s_rpm,
            spindle_on: self.spindle_on,
            path: self.path,
            motions: Vec::new(),
            warnings: Vec::new(),
            file: self.file,
            params: self.params.clone(),
            ctl: ngc::Control::default(),
            line_no: self.line_no,
            origin: self.origin,
            g92: self.g92,
            rotation_deg: self.rotation_deg,
            offset_mm: self.offset_mm,
            user_inch: self.user_inch,
            tool_offset_on: self.tool_offset_on,
            exact_stop_code: self.exact_stop_code,
            spindle_code: self.spindle_code,
            tool_edits: self.tool_edits.clone(),
            tool_shape_edits: self.tool_shape_edits.clone(),
            spindle_shape: self.spindle_shape,
            comp: self.comp.clone(),
            position_read_in_comp: self.position_read_in_comp.clone(),
            tool_loaded: self.tool_loaded,
            mist: self.mist,
            flood: self.flood,
            line_named: self.line_named.clone(),
            call_args: self.call_args.clone(),
            optional_stop: self.optional_stop,
            suppress: self.suppress,
            moves_after_start: self.moves_after_start,
            start_machine_mm: self.start_machine_mm,
            messages: Vec::new(),
            log_files_on: self.log_files_on,
            log_files: self.log_files.clone(),
            user_m: self.user_m.clone(),
            m66_results: self.m66_results,
            probe_results: self.probe_results.clone(),
            probes_read: self.probes_read,
            awaits_probe: self.awaits_probe,
            m66_unknown_since: self.m66_unknown_since,
            m66_read: self.m66_read.clone(),
        }
    }

    /// mm per program unit.
    fn scale(&self) -> f64 {
        if self.inch {
            MM_PER_INCH
        } else {
            1.0
        }
    }

    /// Canonical frame → machine coordinates (mm).
    fn offset(&self) -> Vec3 {
        self.offset_mm
    }

    /// G43, G43.1, G43.2, G49: the tool length offset becomes `len_mm` (`s`: mm
    /// per program unit); the current point moves the other way so that the tool
    /// stands where it stood (`convert_tool_length_offset`). The point a tool
    /// change re-reads (`canon_pos`) stays, as in rs274's stand-alone canon.
    fn tool_length_changes(&mut self, len_mm: f64, s: f64) {
        self.pos[2] -= (len_mm - self.tool_length_mm) / s;
        self.tool_length_mm = len_mm;
    }

    /// A tool's length (mm) as LinuxCNC's `find_tool_index` finds it: tool 0 is the
    /// tool in the spindle.
    fn tool_length(&self, tool: i32, off: u32) -> R<f64> {
        if tool == 0 {
            return Ok(self.spindle_length_mm);
        }
        match u32::try_from(tool).ok().and_then(|t| {
            self.tool_edits
                .get(&t)
                .copied()
                .or_else(|| self.tables.tool_length_mm(t))
        }) {
            Some(l) => Ok(l),
            None => bad(
                off,
                format!("Requested tool {tool} not found in the tool table"),
            ),
        }
    }

    /// A tool's diameter (mm) and orientation as `find_tool_index` finds its
    /// entry: tool 0 is the tool in the spindle.
    fn tool_shape(&self, tool: i32, off: u32) -> R<(f64, i32)> {
        self.tool_length(tool, off)?;
        if tool == 0 {
            return Ok(self.spindle_shape);
        }
        let t = tool as u32;
        Ok(self.tool_shape_edits.get(&t).copied().unwrap_or_else(|| {
            let d = self
                .tables
                .tools
                .iter()
                .find(|e| e.number == t)
                .map_or(0.0, |e| e.diameter_mm);
            (d, 0)
        }))
    }

    /// `read_items` for one word: into the block, with LinuxCNC's reading errors (the
    /// words come in the order of the line); codes and axes softnc does not implement
    /// are refused where they stand.
    #[allow(clippy::too_many_lines)]
    fn sort_word(&self, w: Word, b: &mut Block) -> R<()> {
        let Word {
            letter,
            value,
            offset,
        } = w;
        match letter {
            b'G' => {
                let v10 = value * 10.0;
                let mut code = v10.floor();
                if v10 - code > 0.999 {
                    code = v10.ceil();
                } else if v10 - code > 0.001 {
                    return bad(offset, "G-code out of range");
                }
                if code > 999.0 {
                    return bad(offset, "G-code out of range");
                }
                if code < 0.0 {
                    return bad(offset, "Negative g code used");
                }
                let code = code as i32;
                let Some(group) = g_group(code) else {
                    return bad(offset, "Unknown g code used");
                };
                if let Some(why) = g_unsupported(code) {
                    let probe_read = (G_38_2..=G_38_5).contains(&code)
                        && self.probe_results != crate::ProbeResults::Refuse;
                    if !probe_read {
                        return unsup(offset, fmt_code('G', code), why);
                    }
                }
                match b.g_in(group) {
                    // G80 beside another motion code: the other one counts
                    Some(_) if code == G_80 => {}
                    None | Some(G_80) => b.set_g(group, code, offset),
                    Some(_) => return bad(offset, "Two g codes used from same modal group"),
                }
            }
            b'M' => {
                let code = integer(value, offset)?;
                if code < 0 {
                    return bad(offset, "Negative m code used");
                }
                if code > 199 {
                    return bad(offset, format!("M-code greater than 199: M{code}"));
                }
                let Some(group) = m_group(code) else {
                    return bad(offset, format!("Unknown m code used: M{code}"));
                };
                if b.has_m(group) {
                    return bad(offset, "Two m codes used from same modal group");
                }
                if let Some(why) = m_unsupported(code) {
                    return unsup(offset, format!("M{code}"), why);
                }
                b.set_m(group, code, offset);
                b.m_count += 1;
            }
            b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => {
                return unsup(
                    offset,
                    format!("{}", letter as char),
                    "axes other than X, Y and Z are not supported",
                );
            }
            // LinuxCNC 2.9 takes the last of several (`@5 @6` is @6)
            b'@' | b'^' => b.set_val(letter, value, offset),
            b'P' | b'Q' => {
                let number = if letter == b'P' {
                    &mut b.p_number
                } else {
                    &mut b.q_number
                };
                if *number > -1.0 {
                    return bad(
                        offset,
                        format!(
                            "Multiple {} words on one line",
                            (letter as char).to_ascii_lowercase()
                        ),
                    );
                }
                *number = value;
                b.set_val(letter, value, offset);
            }
            _ => {
                if b.has(letter) {
                    return bad(
                        offset,
                        format!(
                            "Multiple {} words on one line",
                            (letter as char).to_ascii_lowercase()
                        ),
                    );
                }
                let value = match letter {
                    b'F' if value < 0.0 => return bad(offset, "Negative f word used"),
                    b'S' if value < 0.0 => return bad(offset, "Negative spindle speed used"),
                    b'H' => {
                        let v = integer(value, offset)?;
                        if v < -1 {
                            return bad(offset, "Negative h word used");
                        }
                        f64::from(v)
                    }
                    b'L' => {
                        let v = integer(value, offset)?;
                        if v < 0 {
                            return bad(offset, "Negative l word used");
                        }
                        f64::from(v)
                    }
                    b'T' => {
                        let v = integer(value, offset)?;
                        if v < 0 {
                            return bad(offset, "Negative tool id (tool not found)");
                        }
                        f64::from(v)
                    }
                    _ => value,
                };
                b.set_val(letter, value, offset);
            }
        }
        Ok(())
    }

    /// [`Self::sort_word`] kept out of line, for the full reader (the hot path
    /// inlines its own copy).
    fn sort_word_slow(&self, w: Word, b: &mut Block) -> R<()> {
        self.sort_word(w, b)
    }

    /// `enhance_block` and `check_items`.
    #[allow(clippy::too_many_lines)]
    fn check(&self, b: &mut Block) -> R<()> {
        if b.is_empty() {
            // nothing below applies to a block without words (every test asks for
            // a word); a loop's assignment lines take this way on every pass
            return Ok(());
        }
        let polar = b.polar();
        if polar {
            if self.plane != Plane::XY {
                return bad(
                    b.polar_off(),
                    "Cannot use polar coordinate except in G17 plane",
                );
            }
            for (l, msg) in [
                (b'X', "Cannot specify both polar coordinate and X word"),
                (b'Y', "Cannot specify both polar coordinate and Y word"),
            ] {
                if b.has(l) {
                    return bad(b.off(l), msg);
                }
            }
        }
        let axis = b.has(b'X') || b.has(b'Y') || b.has(b'Z');
        let ijk = b.has(b'I') || b.has(b'J') || b.has(b'K');
        let mode0 = b.g_in(GM_MODAL_0);
        let covets = matches!(mode0, Some(100 | 280 | 300 | 520 | 920));
        if let Some(mode1) = b.g_in(GM_MOTION) {
            if mode1 == G_80 && (axis || polar) && !covets {
                let off = if axis { b.axis_off() } else { b.polar_off() };
                return bad(off, "Cannot use axis values with g80");
            }
            if mode1 == G_80 && polar && mode0 == Some(920) {
                return bad(
                    b.polar_off(),
                    "Polar coordinates can only be used for motion",
                );
            }
            if mode1 == G_80 && !axis && matches!(mode0, Some(520 | 920)) {
                return bad(b.g_off(GM_MODAL_0), "All axes missing with g52 or g92");
            }
            if mode1 != G_80 && covets {
                return bad(
                    b.g_off(GM_MOTION),
                    "Cannot use two g codes that both use axis values",
                );
            }
            // (check_g_codes: every motion code but G0–G3, G5.2, G70–G72 and the
            // user's; the others softnc reads are the cycles and the probes)
            let needs_axes = cycles::is_cycle(mode1) || (G_38_2..=G_38_5).contains(&mode1);
            if !axis && !polar && needs_axes {
                return bad(b.g_off(GM_MOTION), "All axes missing with motion code");
            }
            b.motion_to_be = Some(mode1);
        } else if covets {
            if polar && mode0 == Some(920) {
                return bad(
                    b.polar_off(),
                    "Polar coordinates can only be used for motion",
                );
            }
            if !axis && matches!(mode0, Some(520 | 920)) {
                return bad(b.g_off(GM_MODAL_0), "All axes missing with g52 or g92");
            }
        } else if axis || polar {
            let tool_mode = b.g_in(GM_TOOL_LENGTH);
            let dynamic = matches!(tool_mode, Some(431 | 432));
            match self.motion {
                None if !dynamic => {
                    let off = if axis { b.axis_off() } else { b.polar_off() };
                    return bad(
                        off,
                        "Cannot use axis values without a g code that uses them",
                    );
                }
                // G43.1 takes the axis words; G43.2 leaves them to the motion too
                Some(m) if tool_mode != Some(431) => b.motion_to_be = Some(m),
                _ => {}
            }
        } else if ijk && matches!(self.motion, Some(G_2 | G_3)) {
            b.motion_to_be = self.motion;
        }
        let motion = b.motion_to_be;
        if polar && motion.is_none() {
            return bad(
                b.polar_off(),
                "Polar coordinates can only be used for motion",
            );
        }
        let arc = matches!(motion, Some(G_2 | G_3));
        // the canned cycles' words (check_other_codes)
        let cycle = motion.filter(|m| cycles::is_cycle(*m)).unwrap_or(0);
        let g87 = cycle == 870;
        // check_g_codes
        if mode0 == Some(G_4) {
            if b.p_number == -1.0 {
                return bad(b.g_off(GM_MODAL_0), "Dwell time missing with g4");
            }
            if matches!(b.g_in(GM_MOTION), Some(G_2 | G_3)) {
                return bad(
                    b.g_off(GM_MODAL_0),
                    "G4 not allowed with G2 or G3 because they both use P",
                );
            }
        } else if mode0 == Some(100) {
            let p = b.p_number;
            let p_int = if p >= 0.0 {
                (p + 0.5) as i32
            } else {
                (p - 0.5) as i32
            };
            let l = b.get(b'L').map_or(0, |l| l as i32);
            let off = b.g_off(GM_MODAL_0);
            if ![0, 1, 2, 10, 11, 20].contains(&l) {
                return bad(
                    off,
                    "Line with G10 does not have L0, L1, L10, L11, L2, or L20",
                );
            }
            if (p + 0.0001) - f64::from(p_int) > 0.0002 {
                return bad(off, "P value not an integer with G10");
            }
            if (l == 2 || l == 20) && !(0..=9).contains(&p_int) {
                return bad(off, format!("P value out of range (0-9) with G10 L{l}"));
            }
            if (l == 1 || l == 10 || l == 11) && p_int < 1 {
                return bad(off, format!("P value out of range with G10 L{l}"));
            }
        } else if mode0 == Some(G_53) {
            if !matches!(motion, Some(G_0 | G_1)) {
                return bad(b.g_off(GM_MODAL_0), "Must use g0 or g1 with g53");
            }
            let d = b.g_in(GM_DISTANCE);
            if d == Some(G_91) || (d != Some(G_90) && !self.absolute) {
                return bad(b.g_off(GM_MODAL_0), "Cannot use g53 incremental");
            }
        }
        // check_m_codes
        if b.m_count > MAX_EMS {
            return bad(
                (0..M_GROUPS).map(|g| b.m_off(g)).max().unwrap_or(0),
                "Too many m codes on line",
            );
        }
        // check_other_codes (what the supported codes could use): each test asks
        // for one of these letters
        if b.val_set & OTHER_CODES == 0 {
            return Ok(());
        }
        let comp_code = b.g_in(GM_CUTTER_COMP);
        if b.has(b'D') && !matches!(comp_code, Some(410 | 411 | 420 | 421)) {
            return bad(
                b.off(b'D'),
                "D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it",
            );
        }
        let m5 = b.m_in(5);
        let m7 = b.m_in(7);
        let m9 = b.m_in(9);
        let user_m = b.has_m(10);
        if b.has(b'E') && !matches!(m5, Some(66..=68)) {
            return bad(
                b.off(b'E'),
                "E word with no G70, G76, M66, M67 or M68 to use it",
            );
        }
        if b.has(b'H') && !matches!(b.g_in(GM_TOOL_LENGTH), Some(430 | 432)) {
            return bad(b.off(b'H'), "H word with no G43 or G76 to use it");
        }
        if b.has(b'I') && !arc && !g87 && mode0 != Some(100) {
            return bad(
                b.off(b'I'),
                "I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it",
            );
        }
        if b.has(b'J') && !arc && !g87 && mode0 != Some(100) {
            return bad(
                b.off(b'J'),
                "J word with no G2, G3, G5, G5.1, G10, G76 or G87 to use it",
            );
        }
        if b.has(b'K') && !arc && !g87 {
            return bad(
                b.off(b'K'),
                "K word with no G2, G3, G33, G33.1, G76, or G87 to use it",
            );
        }
        if b.has(b'L')
            && mode0 != Some(100)
            && m5 != Some(66)
            && !matches!(cycle, 730 | 810..=890)
            && !matches!(comp_code, Some(410 | 411 | 420 | 421))
        {
            return bad(
                b.off(b'L'),
                "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code",
            );
        }
        if b.has(b'P') {
            if mode0 != Some(G_4)
                && mode0 != Some(100)
                && b.g_in(GM_CONTROL) != Some(640)
                && !arc
                && !matches!(cycle, 740 | 820 | 840 | 860 | 880 | 890)
                && !matches!(m9, Some(50..=53))
                && !matches!(m5, Some(62..=66))
                && m7 != Some(19)
                && !user_m
            {
                return bad(
                    b.off(b'P'),
                    "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it",
                );
            }
            if arc || m7 == Some(19) {
                let p = b.p_number;
                if (f64::from(round_to_int(p)) - p).abs() > 0.001 {
                    return bad(b.off(b'P'), "P value not an integer with M19 G2 or G3");
                }
                if m7 == Some(19) && !(0..=2).contains(&round_to_int(p)) {
                    return bad(b.off(b'P'), "P value must be 0,1,or 2 with M19");
                }
                if arc && round_to_int(p) < 1 {
                    return bad(b.off(b'P'), "P value should be 1 or greater with G2 or G3");
                }
            }
        }
        if b.q_number != -1.0
            && !matches!(cycle, 730 | 830)
            && b.g_in(GM_CONTROL) != Some(640)
            && b.m_in(6) != Some(61)
            && mode0 != Some(100)
            && !matches!(m5, Some(66..=68))
            && m7 != Some(19)
            && !user_m
        {
            return bad(
                b.off(b'Q'),
                "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it",
            );
        }
        if b.has(b'R')
            && !arc
            && cycle == 0
            && mode0 != Some(100)
            && m7 != Some(19)
            && !matches!(comp_code, Some(411 | 421))
        {
            return bad(b.off(b'R'), "R word with no g code that uses it");
        }
        if b.has(b'R') && m7 == Some(19) {
            if b.g_in(GM_CONTROL) == Some(640) {
                return bad(
                    b.off(b'R'),
                    "R word is ambiguous on a line with both G64 and M19 - use separate lines",
                );
            }
            if !(0.0..=360.0).contains(&b.get(b'R').unwrap_or(0.0)) {
                return bad(b.off(b'R'), "R value must be within 0..360 with M19");
            }
        }
        Ok(())
    }

    /// The last comment of the block (`convert_comment`).
    fn comment(&mut self, raw: &str, line: &Line, line_no: u32) -> R<()> {
        let Some((s, e)) = line.comment else {
            return Ok(());
        };
        let off = line.comment_offset;
        let text = raw.get(s as usize..e as usize).unwrap_or("").trim_start();
        let starts = |tag: &str| {
            text.len() >= tag.len()
                && text.as_bytes()[..tag.len()].eq_ignore_ascii_case(tag.as_bytes())
        };
        for tag in ["py,", "pyrun,", "pyreload"] {
            if starts(tag) {
                return unsup(off, format!("({tag}"), "embedded Python is not supported");
            }
        }
        // (ABORT,) stops the program with its text; (MSG,) is a message;
        // (DEBUG,) (while #5599 > 0), (PRINT,) and (LOG,) are messages with the
        // parameters in them substituted as LinuxCNC prints them
        if starts("abort,") {
            return bad(off, format!("Program aborted: {}", &text[6..]));
        }
        if starts("msg,") {
            self.warnings
                .push(format!("{}:{line_no}: message: {}", self.file, &text[4..]));
            self.push_message(line_no, MessageKind::Msg, &text[4..]);
        }
        for (tag, what, kind) in [
            ("debug,", "debug", Some(MessageKind::Debug)),
            ("print,", "print", Some(MessageKind::Print)),
            ("log,", "log", None),
        ] {
            if starts(tag) {
                if tag == "debug," && self.params.get(5599) <= 0.0 {
                    return Ok(());
                }
                let expanded = self
                    .expand_comment(&text[tag.len()..])
                    .map_err(|k| (off, k))?;
                // (an M66's result is shown as `#5399`: known at the machine only)
                let mut shown = String::new();
                let _ = crate::write_message(&mut shown, &expanded, None);
                self.warnings
                    .push(format!("{}:{line_no}: {what}: {shown}", self.file));
                if let Some(kind) = kind {
                    self.push_message(line_no, kind, &expanded);
                } else if self.log_files_on {
                    if expanded.contains(crate::M66_RESULT_MARK) {
                        return unsup(
                            off,
                            "(log,".into(),
                            "a log line with M66's result (#5399): the value is known at the machine only",
                        );
                    }
                    self.log_files.log(&expanded);
                }
                return Ok(());
            }
        }
        for (tag, truncate) in [("logopen,", true), ("logappend,", false)] {
            if starts(tag) {
                if !self.log_files_on {
                    return unsup(
                        off,
                        format!("({tag}"),
                        "writing log files needs a log folder (the daemon's `gcode_log_dir`, `softnc plan --log-dir`)",
                    );
                }
                let name = text[tag.len()..].trim();
                if let Some(why) = crate::log_files::name_problem(name) {
                    return bad(off, format!("log file '{name}': {why}"));
                }
                self.log_files.open(name, truncate);
                return Ok(());
            }
        }
        if self.log_files_on && text.trim_end().eq_ignore_ascii_case("logclose") {
            self.log_files.close();
        }
        Ok(())
    }

    /// `execute_block` for one checked block; `Ok(true)` at program end.
    #[allow(clippy::too_many_lines)]
    fn execute(&mut self, line_no: u32, b: &Block) -> R<bool> {
        if self.sync_pending {
            // rs274 re-reads its position from the canonical interface after a tool change
            self.pos = self.canon_pos;
            self.sync_pending = false;
        }
        if b.is_empty() {
            // nothing below acts without a word (every step asks for one)
            return Ok(false);
        }
        if b.m_set == 0 && b.g_set & !(1 << GM_MOTION) == 0 && b.val_set & NOT_MOTION_ONLY == 0 {
            // a motion line (no M code, no G code but the motion's, no S, T or H):
            // of the steps below only the feed rate and the motion act
            if let Some(f) = b.get(b'F') {
                if !self.inverse_time {
                    self.feed = f;
                }
            }
            self.motion_step(line_no, b)?;
            return Ok(false);
        }
        // feed mode, feed rate
        match b.g_in(GM_FEED_MODE) {
            Some(930) => self.inverse_time = true,
            Some(940) => {
                self.inverse_time = false;
                self.feed = 0.0;
            }
            _ => {}
        }
        if let Some(f) = b.get(b'F') {
            if !self.inverse_time {
                self.feed = f;
            }
        }
        // spindle speed (RS274 order: after the feed rate, before the tool): a
        // speed change while the spindle turns is an operation of its own
        // (`SET_SPINDLE_SPEED`), unless an M3/M4/M5/M19 of the line says more
        if let Some(sw) = b.get(b'S') {
            self.s_rpm = sw;
            if self.spindle_on && !b.has_m(7) {
                let dir = self.spindle_turn();
                self.push_machine(line_no, MachineOp::SpindleOn { dir, rpm: sw });
            }
        }
        // tool select (`SELECT_TOOL`)
        if let Some(t) = b.get(b'T') {
            self.tool_length(t as i32, b.off(b'T'))?;
            self.tool_selected = t as u32;
            self.push_machine(
                line_no,
                MachineOp::ToolPrepare {
                    tool: self.tool_selected,
                },
            );
        }
        // convert_m: I/O, tool change, spindle, coolant, override switches, user
        // M codes, in its order
        self.machine_codes(line_no, b)?;
        // M70-M73 (group 7, after the tool change in convert_m)
        match b.m_in(7) {
            Some(70) => self.save_modal(false),
            Some(73) => self.save_modal(true),
            Some(71) => self.invalidate_modal(),
            Some(72) => self.restore_modal_here(line_no, b.m_off(7))?,
            _ => {}
        }
        // G codes, in convert_g's order
        if b.g_in(GM_MODAL_0) == Some(G_4) {
            let p = b.p_number;
            if p < 0.0 {
                self.warnings.push(format!(
                    "{}:{line_no}: negative dwell P{p} taken as no dwell",
                    self.file
                ));
            }
            self.push_standing(
                line_no,
                MotionKind::Dwell {
                    seconds: p.max(0.0),
                },
            );
        }
        if let Some(code) = b.g_in(GM_PLANE) {
            let plane = match code {
                170 => Plane::XY,
                180 => Plane::XZ,
                _ => Plane::YZ,
            };
            if self.comp.on() {
                // convert_set_plane
                let off = b.g_off(GM_PLANE);
                if plane != self.plane {
                    return bad(
                        off,
                        "Cannot change planes with cutter radius compensation on",
                    );
                }
                if plane == Plane::YZ {
                    return bad(
                        off,
                        "Cutter radius compensation allowed only in XY, XZ planes",
                    );
                }
            }
            self.plane = plane;
        }
        match b.g_in(GM_UNITS) {
            Some(200) if !self.inch => {
                self.inch = true;
                self.pos = self.pos * (1.0 / MM_PER_INCH);
                self.canon_pos = self.canon_pos * (1.0 / MM_PER_INCH);
                self.origin = self.origin * (1.0 / MM_PER_INCH);
                self.g92 = self.g92 * (1.0 / MM_PER_INCH);
                self.feed /= MM_PER_INCH;
                self.comp.scale(1.0 / MM_PER_INCH);
            }
            Some(210) if self.inch => {
                self.inch = false;
                self.pos = self.pos * MM_PER_INCH;
                self.canon_pos = self.canon_pos * MM_PER_INCH;
                self.origin = self.origin * MM_PER_INCH;
                self.g92 = self.g92 * MM_PER_INCH;
                self.feed *= MM_PER_INCH;
                self.comp.scale(MM_PER_INCH);
            }
            _ => {}
        }
        let s = self.scale();
        // cutter radius compensation (convert_cutter_compensation; G8, radius
        // mode, changes nothing here)
        match b.g_in(GM_CUTTER_COMP) {
            Some(400) => self.comp_off(b.g_off(GM_CUTTER_COMP))?,
            Some(code) => self.comp_on(code, b)?,
            None => {}
        }
        let z_before = self.pos[2];
        match b.g_in(GM_TOOL_LENGTH) {
            Some(430) => {
                let len = match b.get(b'H') {
                    Some(h) => self.tool_length(h as i32, b.off(b'H'))?,
                    None => self.spindle_length_mm,
                };
                self.tool_length_changes(len, s);
                self.tool_offset_on = true;
                self.refresh_offset();
            }
            Some(code @ (431 | 432)) => {
                // dynamic offsets (convert_tool_length_offset): G43.1 sets, G43.2 adds
                let off = b.g_off(GM_TOOL_LENGTH);
                if b.has(b'X') || b.has(b'Y') {
                    return unsup(
                        off,
                        fmt_code('G', code),
                        "X and Y tool offsets are not supported (Z only)",
                    );
                }
                let mut len = self.tool_length_mm;
                if code == 431 {
                    if let Some(z) = b.get(b'Z') {
                        len = z * s;
                    }
                } else {
                    if b.has(b'H') && b.has(b'Z') {
                        return bad(off, "G43.2: Can not have both H and axis words");
                    }
                    match (b.get(b'H'), b.get(b'Z')) {
                        (Some(h), _) => len += self.tool_length(h as i32, b.off(b'H'))?,
                        (None, Some(z)) => len += z * s,
                        (None, None) => {
                            return bad(off, "G43.2: No axes specified and H word missing")
                        }
                    }
                }
                self.tool_length_changes(len, s);
                self.tool_offset_on = true;
                self.refresh_offset();
            }
            Some(490) => {
                self.tool_length_changes(0.0, s);
                self.tool_offset_on = false;
                self.refresh_offset();
            }
            _ => {}
        }
        if self.pos[2] != z_before && self.comp.holding() {
            self.comp.shift_z(self.pos[2] - z_before);
        }
        if let Some(code) = b.g_in(GM_COORD) {
            if self.comp.on() {
                return bad(
                    b.g_off(GM_COORD),
                    "Cannot change coordinate systems with cutter radius compensation on",
                );
            }
            let idx = match code {
                540 => 0,
                550 => 1,
                560 => 2,
                570 => 3,
                580 => 4,
                590 => 5,
                591 => 6,
                592 => 7,
                _ => 8,
            };
            self.select_coord(idx);
        }
        if b.has_g(GM_CONTROL) && self.comp.on() {
            return bad(
                b.g_off(GM_CONTROL),
                "Cannot change control mode with cutter radius compensation on",
            );
        }
        match b.g_in(GM_CONTROL) {
            Some(c @ (610 | 611)) => {
                self.path = PathMode::ExactStop;
                self.exact_stop_code = c;
            }
            Some(640) => {
                let (p, q) = (b.p_number, b.q_number);
                self.path = PathMode::Blend {
                    tolerance_mm: (p > 0.0).then_some(p * s),
                    naive_cam_mm: (q > 0.0).then_some(q * s),
                };
            }
            _ => {}
        }
        match b.g_in(GM_DISTANCE) {
            Some(G_90) => self.absolute = true,
            Some(G_91) => self.absolute = false,
            _ => {}
        }
        match b.g_in(GM_IJK_DISTANCE) {
            Some(901) => self.ijk_absolute = true,
            Some(911) => self.ijk_absolute = false,
            _ => {}
        }
        // retract mode (`convert_retract_mode`)
        if b.has_g(GM_RETRACT) && self.comp.on() {
            return bad(
                b.g_off(GM_RETRACT),
                "Cannot change retract mode with cutter radius compensation on",
            );
        }
        match b.g_in(GM_RETRACT) {
            Some(980) => self.retract_old_z = true,
            Some(990) => self.retract_old_z = false,
            _ => {}
        }
        // G10, G28, G30, G52, G92 (convert_g's modal group 0, after the modes)
        if let Some(code) = b.g_in(GM_MODAL_0) {
            self.modal_0(line_no, code, b)?;
        }
        // G92.1, G92.2, G92.3 (LinuxCNC's group 16, "G92 is applied")
        if let Some(code) = b.g_in(16) {
            self.modal_0(line_no, code, b)?;
        }
        // motion
        self.motion_step(line_no, b)?;
        // stop codes (convert_stop, the last step of execute_block): the moves held
        // for cutter compensation go; M0 always, M1 while the optional-stop switch
        // is on; M2, M30 end the program
        if let Some(code) = b.m_in(4) {
            self.comp_stop(matches!(code, 2 | 30), b.m_off(4))?;
        }
        match b.m_in(4) {
            Some(0) => self.push_standing(line_no, MotionKind::Pause { optional: false }),
            Some(1) if self.optional_stop => {
                self.push_standing(line_no, MotionKind::Pause { optional: true })
            }
            _ => {}
        }
        Ok(matches!(b.m_in(4), Some(2) | Some(30)))
    }

    /// `convert_motion` for the block's motion, if it has one: a motion that is not
    /// a canned cycle ends a series of cycles.
    fn motion_step(&mut self, line_no: u32, b: &Block) -> R<()> {
        let Some(m) = b.motion_to_be else {
            return Ok(());
        };
        if !cycles::is_cycle(m) {
            self.cycle.end_series();
        }
        match m {
            G_80 => self.motion = None,
            G_0 | G_1 => self.straight(line_no, m, b)?,
            G_2 | G_3 => self.arc(line_no, m, b)?,
            G_38_2..=G_38_5 => self.probe(line_no, m, b)?,
            _ if cycles::is_cycle(m) => self.cycle(line_no, m, b)?,
            _ => {
                return unsup(
                    b.motion_off(),
                    fmt_code('G', m),
                    "this motion code is not supported",
                )
            }
        }
        Ok(())
    }

    /// A motion that stands at the current point (dwell, pause).
    fn push_standing(&mut self, line_no: u32, kind: MotionKind) {
        // while moves are held for cutter compensation, what LinuxCNC queues
        // waits behind them, and the rest happens where the last motion handed on
        // ended
        let at = if self.comp.holding() {
            if comp::Comp::queues(&kind) {
                let rpm = self.spindle_rpm();
                self.comp.hold(line_no, kind, rpm);
                return;
            }
            self.comp.emitted()
        } else {
            self.pos
        };
        let m = Motion {
            line: line_no,
            start: sc(self.frame(at), self.scale()),
            kind,
            offset_mm: self.offset(),
            path_mode: self.path,
            inch: self.inch,
            canon_end: at,
            canon_center: Vec3::ZERO,
            spindle_rpm: self.spindle_rpm(),
        };
        self.keep(m);
    }

    /// Hand a motion on, unless a run from line has not reached its start block.
    fn keep(&mut self, mut m: Motion) {
        if let Some(stands) = self.comp.take_exit_start(m.kind.end().is_some()) {
            // after a compensation exit the tool stands off the interpreter's point
            m.start = stands - m.offset_mm;
        }
        if !self.suppress && !self.before_the_last_probe_run() {
            self.moves_after_start += u64::from(m.kind.end().is_some());
            self.motions.push(m);
        }
    }

    /// With [`crate::ProbeResults::Known`]: a probe move the machine ran is still
    /// ahead (what comes before it ran too: not handed on).
    pub(super) fn before_the_last_probe_run(&self) -> bool {
        matches!(&self.probe_results, crate::ProbeResults::Known(r) if self.probes_read < r.len())
    }

    /// The machine position of the current point (mm).
    fn machine_pos(&self) -> Vec3 {
        sc(self.frame(self.pos), self.scale()) + self.offset()
    }

    /// A point of [`Motion`]'s frame (mm) in the program's frame and units, as
    /// LinuxCNC holds it (the XY rotation turned back about the G92 origin).
    fn unframe(&self, p_mm: Vec3) -> Vec3 {
        let p = sc(p_mm, 1.0 / self.scale());
        if self.rotation_deg == 0.0 {
            return p;
        }
        let g = self.g92;
        let (x, y) = rotate(p[0] + g[0], p[1] + g[1], -self.rotation_deg);
        Vec3([x - g[0], y - g[1], p[2]])
    }

    /// Run from line: the start block is reached. Motions are kept from here on,
    /// after the safe approach from where the machine stood to the current point
    /// (the start of the start block's first motion), in machine coordinates: Z up
    /// to the higher of the two, X and Y, Z down; traverses with exact stops, then
    /// a [`MotionKind::Sync`].
    fn start_run(&mut self, line_no: u32) {
        if self.sync_pending {
            // as execute() would before this block: rs274's point after a tool change
            self.pos = self.canon_pos;
            self.sync_pending = false;
        }
        self.suppress = false;
        let from = self.start_machine_mm;
        let to = self.machine_pos();
        let clear_z = from[2].max(to[2]);
        let mut points = [Vec3::ZERO; 3];
        let mut n = 0;
        let mut at = from;
        for p in [
            Vec3([from[0], from[1], clear_z]),
            Vec3([to[0], to[1], clear_z]),
            to,
        ] {
            if p != at {
                points[n] = p;
                n += 1;
                at = p;
            }
        }
        let o = self.offset();
        let mut start = from - o;
        if n == 0 {
            self.push_machine_state(line_no, start);
        }
        for (k, &p) in points[..n].iter().enumerate() {
            if k + 1 == n {
                // the spindle and the coolant as the program has them there, before
                // the last traverse goes to the start point
                self.push_machine_state(line_no, start);
            }
            let end = p - o;
            let m = Motion {
                line: line_no,
                start,
                kind: MotionKind::Traverse { end },
                offset_mm: o,
                path_mode: PathMode::ExactStop,
                inch: self.inch,
                canon_end: self.unframe(end),
                canon_center: Vec3::ZERO,
                spindle_rpm: self.spindle_rpm(),
            };
            self.keep(m);
            start = end;
        }
        self.push_standing(line_no, MotionKind::Sync);
        self.moves_after_start = 0;
    }

    /// `find_ends`: the end point of a move (program units, canonical frame).
    fn find_ends(&self, b: &Block) -> R<Vec3> {
        if b.g_in(GM_MODAL_0) == Some(G_53) {
            if b.polar() {
                return bad(b.polar_off(), "Cannot use polar coordinates with G53");
            }
            return Ok(self.find_ends_g53(b));
        }
        let mut end = self.pos;
        if self.comp.on() && !self.comp.firstmove() {
            // cutter compensation: the programmed point for the plane's axes (X in
            // both planes, Y in XY, Z in XZ), not the tool's centre
            let p = self.comp.program();
            end[0] = p[0];
            match self.plane {
                Plane::XY => end[1] = p[1],
                _ => end[2] = p[2],
            }
        }
        for (i, l) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(v) = b.get(l) {
                end[i] = if self.absolute { v } else { end[i] + v };
            }
        }
        if b.polar() {
            self.polar_ends(b, &mut end)?;
        }
        Ok(end)
    }

    /// The X and Y of `end` from the polar words (`interp_find.cc` `find_ends`):
    /// `@` the distance from the origin of the program's frame (G90) or added to
    /// the current one (G91), `^` the angle in degrees from +X (G91: added to the
    /// current point's), each keeping the other coordinate where it is given none.
    #[cold]
    fn polar_ends(&self, b: &Block, end: &mut Vec3) -> R<()> {
        let (x, y) = (end[0], end[1]);
        let at_origin = x == 0.0 && y == 0.0;
        let d2r = |deg: f64| deg * (std::f64::consts::PI / 180.0);
        let (radius, theta) = (b.get(b'@'), b.get(b'^'));
        let (r, t) = if self.absolute {
            match (radius, theta) {
                (Some(r), Some(t)) => (r, d2r(t)),
                (Some(r), None) => {
                    if at_origin {
                        return bad(
                            b.off(b'@'),
                            "Must specify angle in polar coordinate if at the origin",
                        );
                    }
                    (r, y.atan2(x))
                }
                (None, Some(t)) => (y.hypot(x), d2r(t)),
                (None, None) => return Ok(()),
            }
        } else {
            // the distance first, then the angle, each from the point before it
            let (mut px, mut py) = (x, y);
            if let Some(r) = radius {
                if px == 0.0 && py == 0.0 {
                    return bad(
                        b.off(b'@'),
                        "Incremental motion with polar coordinates is indeterminate when at the origin",
                    );
                }
                let (t, r) = (py.atan2(px), py.hypot(px) + r);
                (px, py) = (r * t.cos(), r * t.sin());
            }
            if let Some(t) = theta {
                if px == 0.0 && py == 0.0 {
                    return bad(
                        b.off(b'^'),
                        "G91 motion with polar coordinates is indeterminate when at the origin",
                    );
                }
                let (t, r) = (py.atan2(px) + d2r(t), py.hypot(px));
                (px, py) = (r * t.cos(), r * t.sin());
            }
            end[0] = px;
            end[1] = py;
            return Ok(());
        };
        end[0] = r * t.cos();
        end[1] = r * t.sin();
        Ok(())
    }

    /// `find_ends` under G53: the words are machine coordinates; X and Y go back
    /// through the XY rotation (`interp_find.cc`: the current point is rotated
    /// out, the words replace its coordinates, the result is rotated back in).
    #[cold]
    fn find_ends_g53(&self, b: &Block) -> Vec3 {
        let s = self.scale();
        let (o, g) = (self.origin, self.g92);
        let (cx, cy) = rotate(self.pos[0] + g[0], self.pos[1] + g[1], self.rotation_deg);
        let px = b.get(b'X').map_or(cx, |v| v - o[0]);
        let py = b.get(b'Y').map_or(cy, |v| v - o[1]);
        let (px, py) = rotate(px, py, -self.rotation_deg);
        let pz = b
            .get(b'Z')
            .map_or(self.pos[2], |v| v - o[2] - g[2] - self.tool_length_mm / s);
        Vec3([px - g[0], py - g[1], pz])
    }

    /// A point of the program's frame (program units) in the frame of
    /// [`Motion`]'s positions: the program's frame turned by the XY rotation
    /// about the G92 origin, so that `machine = frame + offset` as LinuxCNC's
    /// `rotate_and_offset_pos` (`emccanon.cc`) maps it. Without rotation the point
    /// itself.
    fn frame(&self, p: Vec3) -> Vec3 {
        if self.rotation_deg == 0.0 {
            p
        } else {
            self.rotated(p)
        }
    }

    #[cold]
    fn rotated(&self, p: Vec3) -> Vec3 {
        let g = self.g92;
        let (x, y) = rotate(p[0] + g[0], p[1] + g[1], self.rotation_deg);
        Vec3([x - g[0], y - g[1], p[2]])
    }

    /// A motion's kind with its end (and centre) in the rotated frame.
    #[cold]
    fn rotate_kind(&self, kind: MotionKind, end: Vec3, center: Vec3) -> MotionKind {
        let s = self.scale();
        let e = sc(self.rotated(end), s);
        match kind {
            MotionKind::Traverse { .. } => MotionKind::Traverse { end: e },
            MotionKind::Feed {
                feed_mm_per_min, ..
            } => MotionKind::Feed {
                end: e,
                feed_mm_per_min,
            },
            MotionKind::Arc {
                plane,
                turns,
                feed_mm_per_min,
                ..
            } => MotionKind::Arc {
                end: e,
                center: sc(self.rotated(center), s),
                plane,
                turns,
                feed_mm_per_min,
            },
            MotionKind::Probe {
                feed_mm_per_min,
                probe,
                ..
            } => MotionKind::Probe {
                end: e,
                feed_mm_per_min,
                probe,
            },
            d @ (MotionKind::Dwell { .. }
            | MotionKind::Pause { .. }
            | MotionKind::Sync
            | MotionKind::Machine(_)) => d,
        }
    }

    /// Spindle speed now (rpm; 0 while stopped).
    fn spindle_rpm(&self) -> f64 {
        if self.spindle_on {
            self.s_rpm
        } else {
            0.0
        }
    }

    fn push(&mut self, line_no: u32, kind: MotionKind, end: Vec3, center: Vec3) {
        self.push_from(line_no, self.pos, kind, end, center, self.spindle_rpm());
        self.pos = end;
        self.canon_pos = end;
    }

    /// Hand on a motion from `start` to `end` (program units, canonical frame).
    fn push_from(
        &mut self,
        line_no: u32,
        start: Vec3,
        kind: MotionKind,
        end: Vec3,
        center: Vec3,
        spindle_rpm: f64,
    ) {
        let (start, kind) = if self.rotation_deg == 0.0 {
            (start, kind)
        } else {
            (self.rotated(start), self.rotate_kind(kind, end, center))
        };
        let m = Motion {
            line: line_no,
            start: sc(start, self.scale()),
            kind,
            offset_mm: self.offset(),
            path_mode: self.path,
            inch: self.inch,
            canon_end: end,
            canon_center: center,
            spindle_rpm,
        };
        self.keep(m);
    }

    /// `convert_straight`.
    fn straight(&mut self, line_no: u32, mode: i32, b: &Block) -> R<()> {
        self.comp.arc_allowed_again();
        let off = b.motion_off();
        if mode == G_1 {
            if !self.inverse_time && self.feed == 0.0 {
                return bad(off, "Cannot do g1 with zero feed rate");
            }
            if self.inverse_time && !b.has(b'F') {
                return bad(off, "F word missing with inverse time g1 move");
            }
        }
        self.motion = Some(mode);
        let end = self.find_ends(b)?;
        let s = self.scale();
        if mode == G_1 && self.inverse_time {
            let d = end - self.pos;
            let length = if d.0.iter().any(|c| c.abs() > 1e-7) {
                d.norm()
            } else {
                0.0
            };
            self.feed = (length * b.get(b'F').unwrap_or(0.0)).max(0.1);
        }
        if self.comp_straight(line_no, mode, b, end)? {
            return Ok(());
        }
        let kind = if mode == G_0 {
            MotionKind::Traverse { end: sc(end, s) }
        } else {
            MotionKind::Feed {
                end: sc(end, s),
                feed_mm_per_min: self.feed * s,
            }
        };
        self.push(line_no, kind, end, Vec3::ZERO);
        Ok(())
    }

    /// `convert_probe` (G38.2–G38.5), then what the next `Interp::read` does after
    /// it (`set_probe_data`) with the results [`ReadOptions::probe_results`] gives.
    fn probe(&mut self, line_no: u32, mode: i32, b: &Block) -> R<()> {
        let off = b.motion_off();
        let probe = crate::ProbeKind::of_g38(mode - G_38_2 + 2);
        if self.comp.on() {
            return bad(off, "Cannot probe with cutter radius comp on");
        }
        if self.feed == 0.0 {
            return bad(off, "Cannot probe with zero feed rate");
        }
        let end = self.find_ends(b)?;
        if probe.fails_without_trip && end == self.pos {
            return bad(off, "Start point too close to probe point");
        }
        self.motion = Some(mode);
        let s = self.scale();
        let start = self.pos;
        let kind = MotionKind::Probe {
            end: sc(end, s),
            feed_mm_per_min: self.feed * s,
            probe,
        };
        let index = self.probes_read;
        self.probes_read += 1;
        if let crate::ProbeResults::Known(ran) = &self.probe_results {
            if let Some(r) = ran.get(index).copied() {
                // it ran: not handed on again; the machine's result is the program's
                if !r.tripped && probe.fails_without_trip {
                    return bad(
                        off,
                        format!("{}: probe move finished without tripping", probe.name()),
                    );
                }
                let to_program = |m: Vec3| self.unframe(m - self.offset());
                let (probed, at) = (to_program(r.probed_mm), to_program(r.stopped_mm));
                self.set_probe_data(probed, at, r.tripped);
                return Ok(());
            }
        }
        self.push(line_no, kind, end, Vec3::ZERO);
        match &self.probe_results {
            crate::ProbeResults::Refuse => {
                unreachable!("G38 is refused where it is read (g_unsupported)")
            }
            crate::ProbeResults::Known(_) => {
                // the machine has yet to run it: the reading ends after this block
                self.awaits_probe = Some(line_no);
            }
            crate::ProbeResults::StandIn => {
                // saicanon's STRAIGHT_PROBE: the probed point is the end, the machine
                // stands 0.254 mm (0.01 in) back from it toward the start — the start
                // as its canonical calls left it, in the XY-rotated frame, while
                // convert_probe hands it the end unrotated (rs274's quirk, kept)
                let d = self.frame(start) - end;
                let dist = d.norm();
                let at = if dist != 0.0 {
                    let backoff = if self.inch { 0.01 } else { 0.254 };
                    end + sc(d, backoff / dist)
                } else {
                    end
                };
                self.set_probe_data(end, at, false);
            }
        }
        Ok(())
    }

    /// `set_probe_data`: the machine stands at `at` (the current point), the probe
    /// tripped (`tripped`) at `probed` (program frame and units).
    fn set_probe_data(&mut self, probed: Vec3, at: Vec3, tripped: bool) {
        self.pos = at;
        self.canon_pos = at;
        for (k, v) in probed.0.iter().enumerate() {
            self.params.set(5061 + k, *v);
        }
        for n in 5064..=5069 {
            self.params.set(n, 0.0);
        }
        self.params.set(5070, if tripped { 1.0 } else { 0.0 });
    }

    /// `convert_arc` and `convert_arc2` with `arc_data_ijk` / `arc_data_r`.
    #[allow(clippy::too_many_lines)]
    fn arc(&mut self, line_no: u32, mode: i32, b: &Block) -> R<()> {
        let off = b.motion_off();
        if self.comp.arc_not_allowed() {
            return bad(
                off,
                "The move just after exiting cutter compensation mode must be straight, not an arc",
            );
        }
        let ijk = b.has(b'I') || b.has(b'J') || b.has(b'K');
        let r_word = b.get(b'R');
        if r_word.is_none() && !ijk {
            return bad(off, "R i j k words all missing for arc");
        }
        if r_word.is_some() && ijk {
            return bad(b.off(b'R'), "Mixed radius ijk format for arc");
        }
        if !self.inverse_time && self.feed == 0.0 {
            return bad(off, "Cannot make arc with zero feed rate");
        }
        if self.inverse_time && !b.has(b'F') {
            return bad(off, "F word missing with inverse time arc move");
        }
        // the plane's first and second axes and the normal, as LinuxCNC orders them
        let (a1, a2, an) = self.plane.axes();
        let axis_letter = [b'X', b'Y', b'Z'];
        let ijk_letter = [b'I', b'J', b'K'];
        let (l1, l2, ln) = (ijk_letter[a1], ijk_letter[a2], ijk_letter[an]);
        let plane_name = self.plane.name();
        let (mut o1, mut o2) = (0.0, 0.0);
        if ijk {
            if b.has(ln) {
                return bad(
                    b.off(ln),
                    format!("{} word given for arc in {plane_name} plane", ln as char),
                );
            }
            // LinuxCNC checks the pair's letters in alphabetical order
            let (first, second) = if l1 < l2 { (l1, l2) } else { (l2, l1) };
            let missing = if !b.has(first) {
                Some(first)
            } else if !b.has(second) {
                Some(second)
            } else {
                None
            };
            if let (Some(l), true) = (missing, self.ijk_absolute) {
                return bad(
                    off,
                    format!("{} word missing in absolute center arc", l as char),
                );
            }
            o1 = b.get(l1).unwrap_or(0.0);
            o2 = b.get(l2).unwrap_or(0.0);
        } else {
            let (x1, x2) = (axis_letter[a1], axis_letter[a2]);
            // in the XY plane a polar word gives the end (`convert_arc`)
            let polar_end = b.polar() && self.plane == Plane::XY;
            if !b.has(x1) && !b.has(x2) && !polar_end {
                let (f, s2) = if a1 < a2 { (x1, x2) } else { (x2, x1) };
                return bad(
                    off,
                    format!(
                        "{} and {} words missing for arc in {plane_name} plane",
                        f as char,
                        (s2 as char).to_ascii_lowercase()
                    ),
                );
            }
        }
        let end = self.find_ends(b)?;
        self.motion = Some(mode);
        if self.comp_arc(line_no, mode, b, end, (o1, o2))? {
            return Ok(());
        }
        let inch = self.inch;
        let turns_abs = if b.has(b'P') {
            round_to_int(b.p_number)
        } else {
            1
        };
        let (c1, c2, turns) = if let Some(radius) = r_word {
            let tol = if inch {
                RADIUS_TOLERANCE_INCH
            } else {
                RADIUS_TOLERANCE_MM
            };
            arc_data_r(
                mode,
                (self.pos[a1], self.pos[a2]),
                (end[a1], end[a2]),
                radius,
                turns_abs,
                tol,
            )
            .or_else(|m| bad(b.off(b'R'), m))?
        } else {
            let (rtol, stol) = if inch {
                (RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_INCH)
            } else {
                (RADIUS_TOLERANCE_MM, CENTER_ARC_RADIUS_TOLERANCE_MM)
            };
            arc_data_ijk(
                mode,
                (self.pos[a1], self.pos[a2]),
                (end[a1], end[a2]),
                self.ijk_absolute,
                (o1, o2),
                turns_abs,
                rtol,
                stol,
                [axis_letter[a1] as char, axis_letter[a2] as char],
            )
            .or_else(|m| bad(off, m))?
        };
        if self.inverse_time {
            let length = find_arc_length(
                (self.pos[a1], self.pos[a2], self.pos[an]),
                (c1, c2),
                turns,
                (end[a1], end[a2], end[an]),
            );
            self.feed = (length * b.get(b'F').unwrap_or(0.0)).max(0.1);
        }
        let mut center = self.pos;
        center[a1] = c1;
        center[a2] = c2;
        if self.rotation_deg != 0.0 && self.plane != Plane::XY {
            // LinuxCNC turns the arc's plane with the system; softnc's arcs lie in
            // the XY, XZ or YZ plane
            return unsup(
                off,
                fmt_code('G', mode),
                "arcs in the XZ or YZ plane of a rotated coordinate system (G10 L2 R) are not supported",
            );
        }
        let s = self.scale();
        let kind = MotionKind::Arc {
            end: sc(end, s),
            center: sc(center, s),
            plane: self.plane,
            turns,
            feed_mm_per_min: self.feed * s,
        };
        self.push(line_no, kind, end, center);
        Ok(())
    }
}

/// At most this many normalized lines are kept for loops and subroutines (a
/// bound on memory; lines beyond it are normalized on every read).
const NORM_CACHE_LINES: usize = 4096;

/// The lines kept once the program has jumped, by [`line_key`]: the normalized line
/// (its values compiled as they are read), the lexer's `block_delete` and `python`
/// flags for it, and where it ends ([`LineEnd`]).
type LineCache = HashMap<u64, (Norm, (bool, bool), LineEnd), BuildHasherDefault<KeyHasher>>;

/// Where a kept line ends, as [`LineSplit`] found it: the offset of its end, of the
/// next line, and whether a newline ended it (a kept line is not scanned again).
type LineEnd = (usize, usize, bool);

/// Bits of a byte offset in a [`line_key`] (programs are far shorter than 2^48
/// bytes; a longer one only shares keys, which compare equal, never wrongly).
const KEY_OFFSET_BITS: u32 = 48;

/// A line's key: its source's index and its byte offset in one word.
fn line_key(source: usize, offset: usize) -> u64 {
    ((source as u64) << KEY_OFFSET_BITS) ^ offset as u64
}

/// Hashes a [`line_key`] with one multiplication (Fibonacci hashing): the keys are
/// distinct small numbers, for which byte-wise FNV costs several times more.
#[derive(Default)]
pub(super) struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ u64::from(b)).wrapping_mul(FIB_HASH);
        }
    }
    fn write_u64(&mut self, k: u64) {
        self.0 = k.wrapping_mul(FIB_HASH);
    }
}

/// 2^64 / φ, odd: multiplying by it spreads consecutive keys over the table.
const FIB_HASH: u64 = 0x9e37_79b9_7f4a_7c15;

/// `Interp::rotate` (`interp_convert.cc`): `(x, y)` turned by `deg` degrees about
/// the origin, counter-clockwise.
fn rotate(x: f64, y: f64, deg: f64) -> (f64, f64) {
    let t = deg * (std::f64::consts::PI / 180.0);
    let (sin, cos) = t.sin_cos();
    (x * cos - y * sin, x * sin + y * cos)
}

/// `v * s` (inlined: the hot path).
fn sc(v: Vec3, s: f64) -> Vec3 {
    Vec3([v.0[0] * s, v.0[1] * s, v.0[2] * s])
}

/// `read_integer_value`.
fn integer(v: f64, off: u32) -> R<i32> {
    let f = v.floor();
    let r = if v - f > 0.9999 {
        v.ceil()
    } else if v - f > 0.0001 {
        return bad(off, "Non integer value for integer");
    } else {
        f
    };
    if r.abs() > 1e9 {
        return bad(off, "Non integer value for integer");
    }
    Ok(r as i32)
}

/// Centre and turns of a centre-format arc (LinuxCNC `arc_data_ijk`).
#[allow(clippy::too_many_arguments)]
fn arc_data_ijk(
    mode: i32,
    cur: (f64, f64),
    end: (f64, f64),
    absolute: bool,
    ij: (f64, f64),
    p: i32,
    radius_tolerance: f64,
    spiral_tolerance: f64,
    names: [char; 2],
) -> Result<(f64, f64, i32), String> {
    let (cx, cy) = if absolute {
        ij
    } else {
        (cur.0 + ij.0, cur.1 + ij.1)
    };
    let r1 = (cx - cur.0).hypot(cy - cur.1);
    let r2 = (cx - end.0).hypot(cy - end.1);
    let [a, b] = names;
    if r1 < radius_tolerance || r2 < radius_tolerance {
        return Err(format!(
            "Zero-radius arc: start=({a}{:.4},{b}{:.4}) center=({a}{cx:.4},{b}{cy:.4}) end=({a}{:.4},{b}{:.4}) r1={r1:.4} r2={r2:.4}",
            cur.0, cur.1, end.0, end.1
        ));
    }
    let abs_err = (r1 - r2).abs();
    let rel_err = abs_err / r1.max(r2);
    if abs_err > spiral_tolerance * 100.0
        || (rel_err > SPIRAL_RELATIVE_TOLERANCE && abs_err > spiral_tolerance)
    {
        return Err(format!(
            "Radius to end of arc differs from radius to start: start=({a}{:.4},{b}{:.4}) center=({a}{cx:.4},{b}{cy:.4}) end=({a}{:.4},{b}{:.4}) r1={r1:.4} r2={r2:.4} abs_err={abs_err:.4} rel_err={:.4}%",
            cur.0,
            cur.1,
            end.0,
            end.1,
            rel_err * 100.0
        ));
    }
    Ok((cx, cy, if mode == G_2 { -p } else { p }))
}

/// Centre and turns of a radius-format arc (LinuxCNC `arc_data_r`).
fn arc_data_r(
    mode: i32,
    cur: (f64, f64),
    end: (f64, f64),
    radius: f64,
    p: i32,
    tolerance: f64,
) -> Result<(f64, f64, i32), String> {
    if end == cur {
        return Err("Current point same as end point of arc".into());
    }
    let abs_radius = radius.abs();
    let mid = ((end.0 + cur.0) / 2.0, (end.1 + cur.1) / 2.0);
    let mut half = (mid.0 - end.0).hypot(mid.1 - end.1);
    if half - abs_radius > tolerance {
        return Err("Arc radius too small to reach end point".into());
    }
    if half / abs_radius > 1.0 - TINY {
        half = abs_radius;
    }
    let heading = (end.1 - cur.1).atan2(end.0 - cur.0);
    let theta = if (mode == G_2 && radius > 0.0) || (mode == G_3 && radius < 0.0) {
        heading - FRAC_PI_2
    } else {
        heading + FRAC_PI_2
    };
    let ratio = half / abs_radius;
    // a half circle (the radius as long as half the chord, or taken as such
    // above): the cosine of asin(1) computed once, the same bits
    let offset = abs_radius
        * if ratio == 1.0 {
            cos_asin_one()
        } else {
            ratio.asin().cos()
        };
    let (cx, cy) = (mid.0 + offset * theta.cos(), mid.1 + offset * theta.sin());
    if !(cx.is_finite() && cy.is_finite()) {
        return Err("Arc radius too small to reach end point".into());
    }
    Ok((cx, cy, if mode == G_2 { -p } else { p }))
}

/// `1f64.asin().cos()` (`arc_data_r` of a half circle), computed once by the same
/// functions on the same value.
fn cos_asin_one() -> f64 {
    static COS: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    *COS.get_or_init(|| 1f64.asin().cos())
}

/// LinuxCNC `find_turn`: the angle swept (radians, counter-clockwise positive).
fn find_turn(start: (f64, f64), c: (f64, f64), turn: i32, end: (f64, f64)) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (start.1 - c.1).atan2(start.0 - c.0);
    let mut beta = (end.1 - c.1).atan2(end.0 - c.0);
    if turn > 0 {
        if beta <= alpha {
            beta += 2.0 * PI;
        }
        (beta - alpha) + f64::from(turn - 1) * 2.0 * PI
    } else {
        if alpha <= beta {
            alpha += 2.0 * PI;
        }
        (beta - alpha) + f64::from(turn + 1) * 2.0 * PI
    }
}

/// LinuxCNC `find_arc_length` (helix included).
fn find_arc_length(start: (f64, f64, f64), c: (f64, f64), turn: i32, end: (f64, f64, f64)) -> f64 {
    let radius = (c.0 - start.0).hypot(c.1 - start.1);
    let theta = find_turn((start.0, start.1), c, turn, (end.0, end.1));
    if end.2 == start.2 {
        radius * theta.abs()
    } else {
        (radius * theta).hypot(end.2 - start.2)
    }
}

/// Read a whole program (see [`crate::read_program`]).
pub fn read(text: &str, file: &str, tables: MachineTables<'_>) -> Result<Program, GcodeError> {
    read_chunked(text, file, tables, usize::MAX, &mut |_| {})
}

/// Read a program handing its motions to `sink` as they are read, whenever `chunk`
/// have gathered, and the rest at the end (see [`crate::read_program_chunked`]).
pub fn read_chunked(
    text: &str,
    file: &str,
    tables: MachineTables<'_>,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<Program, GcodeError> {
    read_with(text, file, tables, &ReadOptions::default(), chunk, sink).map(|(p, _)| p)
}

/// One program text: the main one (borrowed) or a subroutine file.
struct Source<'t> {
    name: String,
    text: SourceText<'t>,
    /// The window of the text checked last for NUL bytes and `(`
    /// ([`Source::may_hold_nul_or_paren`]).
    clean: std::cell::Cell<CleanWindow>,
    /// Where the text is bytes: the window of it checked last as UTF-8, from its
    /// offset ([`Source::line`]).
    utf8: std::cell::Cell<(usize, &'t str)>,
}

/// A program's text: UTF-8 already, or bytes checked as UTF-8 where they are read
/// (a program handed over as bytes, [`read_bytes_with`]).
enum SourceText<'t> {
    /// The main program's text.
    Str(&'t str),
    /// A subroutine file's (made UTF-8 when read, lossy).
    Owned(String),
    /// The main program's bytes.
    Bytes(&'t [u8]),
}

/// Bytes [`Source::line`] checks as UTF-8 at once from the line asked about (then
/// to the end of the line there).
const UTF8_WINDOW_BYTES: usize = 1 << 16;

/// Bytes of a program text from `from` to `to` checked for NUL bytes and `(`
/// ([`has_nul_or_paren`]); `clean` where it holds neither.
#[derive(Debug, Clone, Copy, Default)]
struct CleanWindow {
    from: usize,
    to: usize,
    clean: bool,
}

/// Bytes [`Source::may_hold_nul_or_paren`] checks at once from the line asked
/// about: about 2,500 lines of CAM output, a few microseconds.
const CLEAN_WINDOW_BYTES: usize = 1 << 16;

impl<'t> Source<'t> {
    /// A program text, nothing of it checked yet.
    fn new(name: String, text: SourceText<'t>) -> Source<'t> {
        Source {
            name,
            text,
            clean: Default::default(),
            utf8: std::cell::Cell::new((0, "")),
        }
    }

    /// The text's bytes.
    fn bytes(&self) -> &[u8] {
        match &self.text {
            SourceText::Str(t) => t.as_bytes(),
            SourceText::Owned(t) => t.as_bytes(),
            SourceText::Bytes(b) => b,
        }
    }

    /// The line at bytes `s..e` (`s` after a newline or at the start, `e` at a
    /// newline or the end) as text; None where the text is bytes that are not UTF-8
    /// there. Bytes are checked a window at a time ([`UTF8_WINDOW_BYTES`], to a line's
    /// end) where a line is first asked for outside the window checked last, and
    /// the lines inside it are taken from it as they are.
    fn line(&self, s: usize, e: usize) -> Option<&str> {
        match &self.text {
            SourceText::Str(t) => Some(&t[s..e]),
            SourceText::Owned(t) => Some(&t[s..e]),
            SourceText::Bytes(b) => {
                let (from, w) = self.utf8.get();
                if from <= s && e <= from + w.len() {
                    return Some(&w[s - from..e - from]);
                }
                let b: &'t [u8] = b;
                let end = s.saturating_add(UTF8_WINDOW_BYTES).max(e).min(b.len());
                // (to a newline: a line is never cut, nor a character)
                let end = match b[end..].iter().position(|&c| c == b'\n') {
                    Some(k) => end + k,
                    None => b.len(),
                };
                let w = std::str::from_utf8(&b[s..end]).ok()?;
                self.utf8.set((s, w));
                Some(&w[..e - s])
            }
        }
    }

    /// Whether the line at bytes `s..e` may hold a NUL byte or a `(` (`lex_words`'
    /// `maybe`: where it cannot, the lexer spares two searches of the line). The text
    /// is checked a window at a time where the general reader first asks (the lines
    /// the short way reads, `fast`, need no check): a program read the short way is
    /// not scanned whole before its first line is read, and a line of a window with
    /// a `(` anywhere in it is searched as every line was when the whole text had one.
    fn may_hold_nul_or_paren(&self, s: usize, e: usize) -> bool {
        let w = self.clean.get();
        if w.from <= s && e <= w.to {
            return !w.clean;
        }
        let b = self.bytes();
        let to = e.max(s.saturating_add(CLEAN_WINDOW_BYTES)).min(b.len());
        let clean = !has_nul_or_paren(&b[s..to]);
        self.clean.set(CleanWindow { from: s, to, clean });
        !clean
    }
}

/// Look for `NAME.ngc`: among a checked job's files when the options hold them
/// ([`crate::SubroutineFiles::snapshot`]), else on the search path, then beside the
/// main program; taken in as a job is (a regular file of an ordinary file system,
/// read once, at most what is left of [`crate::SubroutineFiles::max_bytes`] after
/// the `taken_bytes` already read). `Ok(None)`: not found; `Err`: found and refused.
fn find_sub_file(
    name: &str,
    main_file: &str,
    options: &ReadOptions,
    taken_bytes: u64,
) -> Result<Option<crate::SubroutineFile>, String> {
    if let Some(files) = &options.subroutines.snapshot {
        return Ok(files.iter().find(|f| f.name == name).cloned());
    }
    let file_name = format!("{name}.ngc");
    let beside = std::path::Path::new(main_file)
        .parent()
        .map(|p| p.to_path_buf())
        .unwrap_or_default();
    let left = options
        .subroutines
        .max_bytes
        .map_or(u64::MAX, |max| max.saturating_sub(taken_bytes));
    for dir in options
        .subroutine_path
        .iter()
        .chain(std::iter::once(&beside))
    {
        let p = dir.join(&file_name);
        match softnc_core::taken::read_regular(&p, left) {
            Ok(bytes) => {
                return Ok(Some(crate::SubroutineFile {
                    name: name.to_string(),
                    path: p.display().to_string(),
                    bytes: bytes.into(),
                }))
            }
            Err(e) if e.is_not_found() => continue,
            Err(e @ softnc_core::taken::TakeError::TooLarge { .. }) => {
                let max = options.subroutines.max_bytes.unwrap_or(u64::MAX);
                return Err(format!(
                    "subroutine file {e} (subroutine files: at most {max} bytes together)"
                ));
            }
            Err(e) => return Err(format!("subroutine file {e}")),
        }
    }
    Ok(None)
}

/// Whether `text`, one line of a modal preamble ([`ReadOptions::preamble`]), holds
/// only modal words: the modes of the G groups (motion mode without axis words,
/// plane, distance modes, feed mode, units, G40, G43.1 with its Z or G49, the
/// coordinate system, path control with G64's P and Q, return mode, spindle speed
/// mode, lathe diameter mode), F, S, T with M6, M3/M4/M5, M7/M8/M9 — what
/// [`Program::end_modal`] writes and LinuxCNC's modal state restores. No motion, no
/// axis word, no O-word, parameter, expression or comment. `Err`: the byte offset
/// of what is not allowed, and why.
pub fn check_preamble_line(text: &str) -> Result<(), (u32, ErrorKind)> {
    let why = |off: u32, what: String| {
        Err((
            off,
            ErrorKind::Invalid(format!(
                "{what}: the machine's modal state may hold only modal words (G modes, F, S, T M6, M3/M4/M5, M7/M8/M9)"
            )),
        ))
    };
    let mut line = Line::default();
    if let Err((off, kind)) = crate::lexer::lex_line(text, &mut line) {
        if off == SLOW {
            let at = text.find(['#', '[', 'o', 'O']).unwrap_or(0) as u32;
            return why(at, "an O-word, a parameter or an expression".into());
        }
        return Err((off, kind));
    }
    if line.block_delete || line.python {
        return why(0, "a block delete or an embedded statement".into());
    }
    if line.comment.is_some() {
        return why(line.comment_offset, "a comment".into());
    }
    let has = |c: i32| {
        line.words
            .iter()
            .any(|w| w.letter == b'G' && (w.value * 10.0).round() as i32 == c)
    };
    for w in &line.words {
        let ok = match w.letter {
            b'G' => {
                // the modes of LinuxCNC's modal groups: not group 0 (G4, G10, G28, G53,
                // G92, …), cutter compensation only off (G40), the tool length offset
                // as G43.1 with its value or G49 (G43 would read a tool table entry),
                // nothing of group 16 (G92.x: parameters the machine keeps)
                let code = (w.value * 10.0).round() as i32;
                match g_group(code) {
                    Some(0 | 16) | None => false,
                    Some(7) => code == 400,
                    Some(8) => code == 431 || code == 490,
                    Some(_) => true,
                }
            }
            b'M' => [3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0].contains(&w.value),
            b'F' | b'S' | b'T' => true,
            b'P' | b'Q' => has(640),
            b'Z' => has(431),
            _ => false,
        };
        if !ok {
            let word = format!("{}{}", w.letter as char, w.value);
            let what = match w.letter {
                b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => {
                    format!("{word} is an axis word")
                }
                b'G' | b'M' => format!("{word} is not a modal word"),
                _ => format!("{word} is not a modal word here"),
            };
            return why(w.offset, what);
        }
    }
    Ok(())
}

/// [`read_chunked`] with options; also returns the parameters as left.
pub fn read_with(
    text: &str,
    file: &str,
    tables: MachineTables<'_>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<(Program, Params), GcodeError> {
    read_lines(text, file, tables, options, chunk, sink, true)
}

/// [`read_with`] of a program's bytes, checked as UTF-8 where they are read: the
/// same reading where they are UTF-8, else [`ErrorKind::NotUtf8`] at the first line
/// that is not (see [`crate::read_program_chunked_params_bytes`]).
pub fn read_bytes_with(
    bytes: &[u8],
    file: &str,
    tables: MachineTables<'_>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
) -> Result<(Program, Params), GcodeError> {
    read_source(
        SourceText::Bytes(bytes),
        file,
        tables,
        options,
        chunk,
        sink,
        true,
    )
}

/// [`read_with`]; `fast`: common motion lines take the short way of [`fast`]
/// (`false`, for tests: every line the general way).
fn read_lines(
    text: &str,
    file: &str,
    tables: MachineTables<'_>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
    fast: bool,
) -> Result<(Program, Params), GcodeError> {
    read_source(
        SourceText::Str(text),
        file,
        tables,
        options,
        chunk,
        sink,
        fast,
    )
}

/// [`read_lines`] of a text or of bytes checked as UTF-8 where read.
#[allow(clippy::too_many_lines)]
fn read_source<'t>(
    main_text: SourceText<'t>,
    file: &str,
    tables: MachineTables<'_>,
    options: &ReadOptions,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
    fast: bool,
) -> Result<(Program, Params), GcodeError> {
    let mut it = Interp::new(file, tables);
    it.user_inch = options.parameters_in_inches;
    it.optional_stop = options.optional_stop;
    it.suppress = options.from_line.is_some();
    it.user_m.dir = options.user_m_codes.clone();
    it.log_files_on = options.log_files;
    it.m66_results = options.m66_results;
    it.probe_results = options.probe_results.clone();
    match &options.params {
        Some(p) => it.params = p.clone(),
        None => it.params_from_profile(),
    }
    // (DEBUG,) output on, as LinuxCNC sets it at every start (volatile)
    it.params.set(5599, 1.0);
    it.init_offsets();
    if let Some(m) = options.start_mm {
        // the machine's position in the program's frame (mm until a G20)
        // (find_relative: the XY rotation turns back about the G92 origin)
        let (o, k) = (it.offset(), it.scale());
        let p = Vec3([0, 1, 2].map(|i| (m.0[i] - o.0[i]) / k));
        let g = it.g92;
        let (x, y) = rotate(p[0] + g[0], p[1] + g[1], -it.rotation_deg);
        it.pos = Vec3([x - g[0], y - g[1], p[2]]);
        it.canon_pos = it.pos;
    }
    if let Some(pre) = &options.preamble {
        // the machine's modal state, left by the last MDI or job: it sets modes and
        // moves nothing (only modal words; its motion-mode line makes no motion of the
        // program's)
        let pre_file = options
            .preamble_file
            .as_deref()
            .unwrap_or("<the machine's modal state>");
        let pre_err = |i: usize, l: &str, (off, kind): (u32, ErrorKind)| GcodeError {
            file: pre_file.into(),
            line: i as u32 + 1,
            column: column(l, off),
            kind,
        };
        for (i, l) in pre.lines().enumerate() {
            check_preamble_line(l).map_err(|e| pre_err(i, l, e))?;
        }
        let before = it.motions.len();
        for (i, l) in pre.lines().enumerate() {
            it.run_preamble(l).map_err(|e| pre_err(i, l, e))?;
        }
        it.motions.truncate(before);
        // the interpreter synchronised with the machine at the start: the point a
        // tool change re-reads is where the machine stands, in the frame of the
        // offsets the modal state set (LinuxCNC's `synch` reads the machine's
        // position less the origin and the tool length offset in force). Else a
        // job after one that left `G43.1 Z…` and starting with an M6 jumps by the
        // tool length.
        it.canon_pos = it.pos;
    }
    it.start_machine_mm = it.machine_pos();
    let bytes: &'t [u8] = match main_text {
        SourceText::Str(t) => t.as_bytes(),
        SourceText::Bytes(b) => b,
        SourceText::Owned(_) => unreachable!("a main program is borrowed"),
    };
    it.motions.reserve((bytes.len() / 16).min(chunk.max(1)));
    let mut line = Line::default();
    let mut block = Block::default();
    let mut norm = Norm::default();
    let mut sets: Vec<Setting> = Vec::new();
    // normalized lines by (source, byte offset), once the program has jumped
    let mut norm_cache: LineCache = Default::default();
    let mut jumped = false;
    let mut sources = vec![Source::new(file.to_string(), main_text)];
    // the subroutine files taken in, and their bytes together
    let mut taken: Vec<crate::SubroutineFile> = Vec::new();
    let mut taken_bytes = 0u64;
    let err_in =
        |name: &str, line_no: usize, raw: &str, (off, kind): (u32, ErrorKind)| GcodeError {
            file: name.to_string(),
            line: line_no as u32,
            column: column(raw, off),
            kind,
        };
    let err = |line_no: usize, raw: &str, e: (u32, ErrorKind)| err_in(file, line_no, raw, e);
    // `%` on the first non-blank line: the program runs to the next lone `%`
    let mut prescan = LineSplit { b: bytes, pos: 0 };
    let mut first = 0;
    let first_line = loop {
        let Some((s, e, _)) = prescan.next() else {
            return Err(err(
                first.max(1),
                "",
                (
                    0,
                    ErrorKind::Invalid("File ended with no percent sign".into()),
                ),
            ));
        };
        if !significant(&bytes[s..e])
            .iter()
            .all(|c| matches!(c, b' ' | b'\t' | 0x0b | 0x0c | b'\r'))
        {
            break (s, e);
        }
        first += 1;
    };
    let percent_flag = {
        let sig = significant(&bytes[first_line.0..first_line.1]);
        sig.last() == Some(&b'%')
            && sig[..sig.len() - 1]
                .iter()
                .all(|c| matches!(c, b' ' | b'\t' | 0x0b | 0x0c | b'\r'))
    };
    // the lines to run: after the `%` line, or all of them
    let (mut pos, first) = if percent_flag {
        (prescan.pos, first + 1)
    } else {
        (0, 0)
    };
    let limit = options
        .block_limit
        .unwrap_or(1_000_000 + bytes.len() as u64);
    let mut executed: u64 = 0;
    let mut cur = 0usize; // source index
    let mut next_line_no = first + 1;
    let mut n_lines = first;
    'files: loop {
        let src = &sources[cur];
        let src_text: &[u8] = src.bytes();
        let src_name: &str = &src.name;
        let mut split = LineSplit { b: src_text, pos };
        // where the short way last stopped (the line there is read the general way)
        let mut fast_stop = usize::MAX;
        // the lines of this file, up to a jump
        let (jump, after) = loop {
            // a kept line (once the program has jumped): its end is known, and its
            // normalized text at hand
            let kept_here = if norm_cache.is_empty() {
                None
            } else {
                norm_cache.get(&line_key(cur, split.pos))
            };
            if fast
                && kept_here.is_none()
                && split.pos != fast_stop
                && it.ctl.skipping.is_none()
                && src_text.get(split.pos).is_some_and(|&c| fast::may_start(c))
            {
                // common motion lines, read and run the short way (`fast`) up to
                // the first other line, which is read below (and not tried again)
                let (pos, read) = it.fast_lines(
                    src_text,
                    split.pos,
                    next_line_no,
                    limit.saturating_sub(executed),
                    chunk,
                );
                fast_stop = pos;
                if read > 0 {
                    // (the short way reads ASCII words alone; bytes given unchecked
                    // are held to that, so that what it read is UTF-8)
                    if matches!(src.text, SourceText::Bytes(_))
                        && !src_text[split.pos..pos].is_ascii()
                    {
                        return Err(err_in(src_name, next_line_no, "", (0, ErrorKind::NotUtf8)));
                    }
                    split.pos = pos;
                    next_line_no += read as usize;
                    n_lines = next_line_no - 1;
                    executed += read;
                    if it.motions.len() >= chunk {
                        sink(&mut it.motions);
                        it.motions.clear();
                    }
                    continue;
                }
            }
            let next = match kept_here {
                Some((_, _, (e, next, newline))) => {
                    let s = split.pos;
                    split.pos = *next;
                    Some((s, *e, *newline))
                }
                None => split.next(),
            };
            let Some((s, e, newline)) = next else {
                if let Some(sk) = &it.ctl.skipping {
                    return Err(err_in(
                        &src.name,
                        n_lines.max(1),
                        "",
                        (
                            0,
                            ErrorKind::Invalid(format!(
                                "File ended while looking for O-word label '{sk}' (from line {})",
                                it.ctl.skipping_start
                            )),
                        ),
                    ));
                }
                if cur != 0 {
                    return Err(err_in(
                        &src.name,
                        n_lines.max(1),
                        "",
                        (
                            0,
                            ErrorKind::Invalid("Subroutine file ended without its endsub".into()),
                        ),
                    ));
                }
                break 'files;
            };
            let line_no = next_line_no;
            next_line_no += 1;
            n_lines = line_no;
            executed += 1;
            let Some(raw) = src.line(s, e) else {
                return Err(err_in(src_name, line_no, "", (0, ErrorKind::NotUtf8)));
            };
            if executed > limit {
                return Err(err_in(
                    &src.name,
                    line_no,
                    raw,
                    (0, ErrorKind::BlockLimit { limit }),
                ));
            }
            it.line_no = line_no;
            if e - s + usize::from(newline) >= LINELEN - 1 {
                return Err(err_in(
                    src_name,
                    line_no,
                    raw,
                    (0, ErrorKind::Invalid("Command too long".into())),
                ));
            }
            let pc = Pc {
                file: cur,
                pos: s,
                next: split.pos,
                line_no,
            };
            let mut jump = Jump::Next;
            // block delete (read_text): a `/` first makes the line empty
            let deleted = options.block_delete
                && raw
                    .bytes()
                    .find(|c| !matches!(c, b' ' | b'\t'))
                    .is_some_and(|c| c == b'/');
            if let Some(n) = options.from_line {
                if it.suppress && cur == 0 && it.ctl.level() == 0 && line_no >= n as usize {
                    if it.ctl.defining_sub {
                        return Err(err(
                            n as usize,
                            "",
                            (
                                0,
                                ErrorKind::Invalid(format!(
                                    "cannot run from line {n}: it lies in the definition of subroutine o<{}> (LinuxCNC refuses this too)",
                                    it.ctl.skipping.as_deref().unwrap_or("")
                                )),
                            ),
                        ));
                    }
                    if it.ctl.skipping.is_none() && !deleted {
                        if it.comp.busy() {
                            // the moves held for the corner before the start block
                            // were never cut: the path there is not the program's
                            return Err(err(
                                n as usize,
                                "",
                                (
                                    0,
                                    ErrorKind::Invalid(format!(
                                        "cannot run from line {n}: cutter radius compensation is on there (or its exit move not made); start at a line where it is off (G40)"
                                    )),
                                ),
                            ));
                        }
                        it.start_run(line_no as u32);
                    }
                }
            }
            if deleted {
                // not read at all
            } else if it.ctl.skipping.is_some() {
                // only O-lines count while skipping; nothing else on a line is read
                jump = it
                    .skip_line(raw, &mut norm, &mut block, &mut line, &mut sets, &pc)
                    .map_err(|x| err_in(src_name, line_no, raw, x))?;
            } else {
                // each word goes into the block as it is read: words before a lexing
                // error are read (and may fail) first, as in LinuxCNC
                block.clear();
                let key = line_key(cur, s);
                let mut oline = None;
                if let Some((n, flags, _)) = kept_here {
                    // read before: the fast lexer handed it to the full reader then,
                    // and would again (it depends on the text alone), leaving these
                    // flags
                    (line.block_delete, line.python) = *flags;
                    (line.blank, line.percent) = (false, false);
                    line.comment_offset = 0;
                    // a kept O-line compiled whole: read and run at once (nothing
                    // between them applies: no `%`, no Python — the first read of a
                    // line with it ended the program —, no assignments)
                    if !line.python {
                        if let Some(r) = it.run_kept_o(n, &mut line, &pc) {
                            let jump = r.map_err(|x| err_in(src_name, line_no, raw, x))?;
                            it.position_read_check()
                                .map_err(|x| err_in(src_name, line_no, raw, x))?;
                            if jump != Jump::Next {
                                break (jump, split.pos);
                            }
                            continue;
                        }
                    }
                    oline = it
                        .read_norm(n, &mut block, &mut line, &mut sets)
                        .map_err(|x| err_in(src_name, line_no, raw, x))?;
                } else {
                    let maybe = src.may_hold_nul_or_paren(s, e);
                    let lexed = lex_words(raw, &mut line, maybe, |w| it.sort_word(w, &mut block));
                    match lexed {
                        Ok(()) => {}
                        Err((SLOW, _)) => {
                            // the words the lexer sorted before handing over
                            block.clear();
                            // parameters, expressions or an O-word: the full reader,
                            // on the normalized line (kept, with its values compiled
                            // as they are read, for lines read again once the program
                            // has jumped: loops and subroutines)
                            norm.build(significant(raw.as_bytes()));
                            let r = if jumped && norm_cache.len() < NORM_CACHE_LINES {
                                let mut kept = norm.clone();
                                kept.keep = true;
                                let (n, _, _) = norm_cache.entry(key).or_insert((
                                    kept,
                                    (line.block_delete, line.python),
                                    (e, split.pos, newline),
                                ));
                                it.read_norm(n, &mut block, &mut line, &mut sets)
                            } else {
                                it.read_norm(&norm, &mut block, &mut line, &mut sets)
                            };
                            oline = r.map_err(|x| err_in(src_name, line_no, raw, x))?;
                        }
                        Err(x) => return Err(err_in(src_name, line_no, raw, x)),
                    }
                }
                if line.percent {
                    if percent_flag && cur == 0 {
                        run_from_reached(&it, options, file)?;
                        return Ok(finish(
                            it,
                            file,
                            executed as usize + first,
                            chunk,
                            sink,
                            taken,
                        ));
                    }
                    let off = raw.find('%').unwrap_or(0) as u32;
                    return Err(err_in(
                        src_name,
                        line_no,
                        raw,
                        (off, ErrorKind::Invalid(bad_character(b'%'))),
                    ));
                }
                if line.python {
                    return Err(err_in(
                        src_name,
                        line_no,
                        raw,
                        (
                            0,
                            ErrorKind::Unsupported {
                                word: ";py,".into(),
                                why: "embedded Python is not supported".into(),
                            },
                        ),
                    ));
                }
                it.position_read_check()
                    .map_err(|x| err_in(src_name, line_no, raw, x))?;
                if !sets.is_empty() {
                    it.commit(&mut sets);
                }
                if let Some(o) = oline {
                    jump = it
                        .control(&o, &pc)
                        .map_err(|x| err_in(src_name, line_no, raw, x))?;
                } else if !line.blank {
                    // a `/` line runs: the block-delete switch is off, as in rs274's default
                    it.check(&mut block)
                        .map_err(|x| err_in(src_name, line_no, raw, x))?;
                    if line.comment.is_some() {
                        it.comment(raw, &line, line_no as u32)
                            .map_err(|x| err_in(src_name, line_no, raw, x))?;
                    }
                    let stop = it
                        .execute(line_no as u32, &block)
                        .map_err(|x| err_in(src_name, line_no, raw, x))?;
                    if stop {
                        // convert_stop (M2, M30): G54 is selected again, so the next
                        // program starts there; reading ends, so only 5220 shows it
                        it.params.set(5220, 1.0);
                        // and the modes it resets (G54 G17 G90 G94 M5 M9 G1): the
                        // modal state the next program starts with
                        it.coord = 0;
                        it.plane = Plane::XY;
                        it.absolute = true;
                        it.inverse_time = false;
                        it.program_end(line_no as u32);
                        it.motion = Some(G_1);
                        run_from_reached(&it, options, file)?;
                        return Ok(finish(
                            it,
                            file,
                            executed as usize + first,
                            chunk,
                            sink,
                            taken,
                        ));
                    }
                    if it.awaits_probe.is_some() {
                        // a probe move the machine has yet to run: what follows
                        // depends on its result (`ProbeResults::Known`)
                        return Ok(finish(
                            it,
                            file,
                            executed as usize + first,
                            chunk,
                            sink,
                            taken,
                        ));
                    }
                    if it.motions.len() >= chunk {
                        sink(&mut it.motions);
                        it.motions.clear();
                    }
                }
                if it.m66_read.get() {
                    it.check_5399_read(raw)
                        .map_err(|x| err_in(src_name, line_no, raw, x))?;
                }
            }
            if jump != Jump::Next {
                break (jump, split.pos);
            }
        };
        pos = after;
        match jump {
            Jump::Percent => {
                // read_text's end of file while skipping: LinuxCNC's error
                let sk = it.ctl.skipping.clone().unwrap_or_default();
                return Err(err_in(
                    &sources[cur].name,
                    n_lines,
                    "%",
                    (
                        0,
                        ErrorKind::Invalid(format!("Failed to find sub 'O{sk}' before EOF")),
                    ),
                ));
            }
            Jump::Next => {}
            Jump::To(f, p, l) => {
                cur = f;
                pos = p;
                next_line_no = l;
                jumped = true;
            }
            Jump::OpenSub => {
                let name = it.wanted_sub().unwrap_or_default().to_string();
                let main_dir_file = file.to_string();
                let file_name = format!("{name}.ngc");
                if let Some(k) = sources.iter().skip(1).position(|s| {
                    std::path::Path::new(&s.name).file_name()
                        == Some(std::ffi::OsStr::new(&file_name))
                }) {
                    let k = k + 1;
                    cur = k;
                    pos = 0;
                    next_line_no = 1;
                } else {
                    let found = find_sub_file(&name, &main_dir_file, options, taken_bytes)
                        .map_err(|why| {
                            err_in(
                                &sources[cur].name,
                                n_lines,
                                "",
                                (0, ErrorKind::Invalid(why)),
                            )
                        })?;
                    if let Some(f) = found {
                        taken_bytes += f.bytes.len() as u64;
                        let body = String::from_utf8_lossy(&f.bytes).into_owned();
                        sources.push(Source::new(f.path.clone(), SourceText::Owned(body)));
                        taken.push(f);
                        cur = sources.len() - 1;
                        pos = 0;
                        next_line_no = 1;
                    } else if cur != 0 {
                        let checked = if options.subroutines.snapshot.is_some() {
                            " among the files the job was checked with"
                        } else {
                            ""
                        };
                        return Err(err_in(
                            &sources[cur].name,
                            n_lines,
                            "",
                            (
                                0,
                                ErrorKind::Invalid(format!(
                                    "Subroutine 'O{name}' not found -- not in offset table and no file '{name}.ngc' found{checked}"
                                )),
                            ),
                        ));
                    }
                }
                // else: look for its definition further on in the main program
            }
        }
    }
    let msg = if percent_flag {
        "File ended with no percent sign"
    } else {
        "File ended with no percent sign or program end"
    };
    Err(err(n_lines.max(1), "", (0, ErrorKind::Invalid(msg.into()))))
}

/// Bytes [`has_nul_or_paren`] tests in one step (four 16-byte vector compares
/// per byte sought, one test of their union).
const HIT_BLOCK: usize = 64;

/// Whether `b` holds a NUL byte or a `(`: one pass, in blocks of fixed length that
/// the compiler turns into vector compares.
fn has_nul_or_paren(b: &[u8]) -> bool {
    let is_hit = |c: u8| c == 0 || c == b'(';
    let mut blocks = b.chunks_exact(HIT_BLOCK);
    blocks.by_ref().any(|block| {
        block
            .iter()
            .fold(0u8, |hits, &c| hits | u8::from(is_hit(c)))
            != 0
    }) || blocks.remainder().iter().any(|&c| is_hit(c))
}

/// The lines of a text as byte ranges `(start, end, ended by a newline)`, as
/// `split('\n')` gives them without the empty piece after a final newline.
struct LineSplit<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Iterator for LineSplit<'_> {
    type Item = (usize, usize, bool);
    fn next(&mut self) -> Option<(usize, usize, bool)> {
        let s = self.pos;
        if s >= self.b.len() {
            return None;
        }
        Some(match find_newline(&self.b[s..]) {
            Some(k) => {
                self.pos = s + k + 1;
                (s, s + k, true)
            }
            None => {
                self.pos = self.b.len();
                (s, self.b.len(), false)
            }
        })
    }
}

/// Offset of the first `\n` in `b`, eight bytes at a time (lines are short: a
/// general `memchr` spends more on setting up than on searching).
fn find_newline(b: &[u8]) -> Option<usize> {
    const ONES: u64 = 0x0101_0101_0101_0101;
    const HIGHS: u64 = 0x8080_8080_8080_8080;
    let mut i = 0;
    while let Some(chunk) = b.get(i..i + 8) {
        let mut w = [0u8; 8];
        w.copy_from_slice(chunk);
        let x = u64::from_le_bytes(w) ^ (ONES * u64::from(b'\n'));
        // the lowest zero byte of x is found exactly (borrows only reach above it)
        let zero = x.wrapping_sub(ONES) & !x & HIGHS;
        if zero != 0 {
            return Some(i + (zero.trailing_zeros() / 8) as usize);
        }
        i += 8;
    }
    b[i..].iter().position(|&c| c == b'\n').map(|k| i + k)
}

/// A run from line must have reached its start block and moved after it.
fn run_from_reached(it: &Interp, options: &ReadOptions, file: &str) -> Result<(), GcodeError> {
    let Some(n) = options.from_line else {
        return Ok(());
    };
    let why = if it.suppress {
        format!("cannot run from line {n}: no block at or after line {n} runs")
    } else if it.moves_after_start == 0 {
        format!("cannot run from line {n}: no motion follows it")
    } else {
        return Ok(());
    };
    Err(GcodeError {
        file: file.to_string(),
        line: n,
        column: 1,
        kind: ErrorKind::Invalid(why),
    })
}

fn finish(
    mut it: Interp,
    file: &str,
    blocks: usize,
    chunk: usize,
    sink: &mut dyn FnMut(&mut Vec<Motion>),
    subroutine_files: Vec<crate::SubroutineFile>,
) -> (Program, Params) {
    if chunk != usize::MAX {
        if !it.motions.is_empty() {
            sink(&mut it.motions);
        }
        it.motions = Vec::new();
    }
    it.comp_dropped_at_end();
    let end_modal = it.modal_gcode();
    (
        Program {
            file: file.to_string(),
            blocks,
            motions: it.motions,
            warnings: it.warnings,
            end_modal,
            subroutine_files,
            messages: it.messages,
            log_files: it.log_files.files,
            awaits_probe: it.awaits_probe,
        },
        it.params,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The checkout's default machine profile.
    fn default_profile() -> softnc_core::MotionProfile {
        softnc_core::MotionProfile::load(
            &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../config/machines/default.ron"),
        )
        .unwrap()
    }

    /// `has_nul_or_paren` finds a NUL or a `(` at every offset of texts of every
    /// length around its block (in a block, in the rest after the last), and says
    /// no to texts without either.
    #[test]
    fn nul_or_paren_found_at_every_offset() {
        for len in 0..3 * HIT_BLOCK + 3 {
            let clean = vec![b'G'; len];
            assert!(!has_nul_or_paren(&clean), "{len}");
            for at in 0..len {
                for hit in [0u8, b'('] {
                    let mut t = clean.clone();
                    t[at] = hit;
                    assert!(has_nul_or_paren(&t), "{len} {at} {hit}");
                }
            }
        }
    }

    /// Comments and NUL bytes far into a long program (past the first windows
    /// `Source::may_hold_nul_or_paren` checks) are read as where the whole text was
    /// scanned first: the comment's words and what follows a NUL are not read, the
    /// general way and the short way alike, and a window with neither is lexed
    /// without searching its lines.
    #[test]
    fn comments_and_nul_bytes_past_the_first_window_are_read() {
        let profile = default_profile();
        let mut text = String::from("G21 G90 F100\n");
        let (comment_at, nul_at, lines) = (12_000, 17_000, 20_000);
        for i in 1..=lines {
            text.push_str(&match i {
                _ if i == comment_at => "G1 X1.5 (X9 Y9 a comment)\n".to_string(),
                _ if i == nul_at => "G1 X2.5\0X9 Y9\n".to_string(),
                _ => format!("G1 X{}.25 Y{}\n", i % 7, i % 3),
            });
        }
        text.push_str("M2\n");
        assert!(
            comment_at * 11 > 2 * CLEAN_WINDOW_BYTES && text.len() > 3 * CLEAN_WINDOW_BYTES,
            "{}",
            text.len()
        );
        for fast in [false, true] {
            let mut motions = Vec::new();
            read_lines(
                &text,
                "long.ngc",
                profile.tables(),
                &ReadOptions::default(),
                1024,
                &mut |chunk: &mut Vec<Motion>| motions.append(chunk),
                fast,
            )
            .unwrap();
            let end_at = |line: usize| {
                let m = motions
                    .iter()
                    .find(|m| m.line as usize == line + 1)
                    .unwrap();
                (m.canon_end[0], m.canon_end[1])
            };
            // (no spindle stop at M2: the spindle never turned)
            assert_eq!(motions.len(), lines, "fast {fast}");
            // (Y modal: the line before's)
            let y_before = |line: usize| ((line - 1) % 3) as f64;
            assert_eq!(
                end_at(comment_at),
                (1.5, y_before(comment_at)),
                "fast {fast}"
            );
            assert_eq!(end_at(nul_at), (2.5, y_before(nul_at)), "fast {fast}");
            assert_eq!(
                end_at(comment_at + 1),
                (
                    ((comment_at + 1) % 7) as f64 + 0.25,
                    ((comment_at + 1) % 3) as f64
                )
            );
        }
    }

    /// A program read from its bytes (`read_bytes_with`) reads as its text does where
    /// the bytes are UTF-8, with lines of several windows, non-ASCII characters in
    /// comments far into it and a jump back across windows (a subroutine called at
    /// the end, defined at the start); where a line is not UTF-8, read the short way
    /// or the general way, near the start or past the first windows, it stops with
    /// `NotUtf8` (the caller then reads the lossy text).
    #[test]
    fn bytes_read_as_their_text_and_stop_where_not_utf8() {
        let profile = default_profile();
        let mut text =
            String::from("o<wave> sub\nG1 X0 Y#1 F300 (café)\no<wave> endsub\nG21 G90 F100\n");
        for i in 1..=20_000 {
            text.push_str(&format!("G1 X{}.25 Y{}\n", i % 7, i % 3));
            if i % 5_000 == 0 {
                text.push_str("G1 X1 (über — ünïcödé)\n");
            }
        }
        text.push_str("o<wave> call [2]\nM2\n");
        assert!(text.len() > 3 * UTF8_WINDOW_BYTES, "{}", text.len());
        let read = |bytes: &[u8], from_text: bool| {
            let mut motions = Vec::new();
            let mut sink = |chunk: &mut Vec<Motion>| motions.append(chunk);
            let opts = ReadOptions::default();
            let r = if from_text {
                read_with(
                    std::str::from_utf8(bytes).unwrap(),
                    "b.ngc",
                    profile.tables(),
                    &opts,
                    512,
                    &mut sink,
                )
            } else {
                read_bytes_with(bytes, "b.ngc", profile.tables(), &opts, 512, &mut sink)
            };
            r.map(|(p, _)| (format!("{p:?}"), format!("{motions:?}")))
        };
        assert_eq!(
            read(text.as_bytes(), false).unwrap(),
            read(text.as_bytes(), true).unwrap()
        );
        for (at, bad) in [
            (300usize, &b"\xff"[..]),
            (150_000, b"\xc3("),
            (200_000, b"\xe2\x82"),
        ] {
            // a plain motion line (the short way) and a comment (the general way)
            let line_start = text[at..].find('\n').unwrap() + at + 1;
            for insert_at in [line_start + 3, line_start] {
                let mut bytes = text.as_bytes().to_vec();
                bytes.splice(insert_at..insert_at, bad.iter().copied());
                let e = read(&bytes, false).unwrap_err();
                assert_eq!(e.kind, ErrorKind::NotUtf8, "{at} {insert_at}: {e}");
            }
        }
    }

    /// A block is empty only without any word: `check` and `execute` skip such
    /// a block, so a G code, an M code or a lettered value alone must not count
    /// as empty.
    #[test]
    fn a_block_with_any_word_is_not_empty() {
        let profile = default_profile();
        let it = Interp::new("t.ngc", profile.tables());
        for (letter, value) in [
            (b'G', 1.0),
            (b'M', 3.0),
            (b'P', 2.0),
            (b'Q', 1.0),
            (b'X', 0.0),
            (b'F', 100.0),
        ] {
            let mut b = Block::default();
            assert!(b.is_empty());
            it.sort_word(
                Word {
                    letter,
                    value,
                    offset: 0,
                },
                &mut b,
            )
            .unwrap();
            assert!(!b.is_empty(), "{} alone", letter as char);
            b.clear();
            assert!(b.is_empty());
        }
    }

    #[test]
    fn lines_split_as_str_split() {
        for text in [
            "",
            "\n",
            "\n\n",
            "a",
            "a\n",
            "a\nb",
            "G1 X1\r\nG2 X2 Y3 I4 J5\n\nM2",
            "0123456789abcdef\n0123456\n",
            "long line without newline at all here",
        ] {
            let mut want = Vec::new();
            let mut start = 0;
            for piece in text.split('\n') {
                let end = start + piece.len();
                if end == text.len() && piece.is_empty() {
                    break;
                }
                want.push((start, end, end < text.len()));
                start = end + 1;
            }
            let got: Vec<_> = LineSplit {
                b: text.as_bytes(),
                pos: 0,
            }
            .collect();
            assert_eq!(got, want, "{text:?}");
        }
        for n in 0..40 {
            let mut t = vec![b'x'; n];
            assert_eq!(find_newline(&t), None);
            t.push(b'\n');
            t.extend_from_slice(b"ab\n");
            assert_eq!(find_newline(&t), Some(n));
        }
    }

    #[test]
    fn turn_angles_as_linuxcnc() {
        let t = find_turn((1.0, 0.0), (0.0, 0.0), 1, (1.0, 0.0));
        assert!((t - 2.0 * PI).abs() < 1e-12);
        let t = find_turn((1.0, 0.0), (0.0, 0.0), -1, (0.0, 1.0));
        assert!((t + 1.5 * PI).abs() < 1e-12);
        let t = find_turn((1.0, 0.0), (0.0, 0.0), 2, (0.0, 1.0));
        assert!((t - 2.5 * PI).abs() < 1e-12);
    }

    /// A half circle's centre takes the kept cosine of asin(1): the same bits as
    /// computing it, and the same centre as the formula written out.
    #[test]
    fn half_circles_take_the_kept_cosine() {
        assert_eq!(cos_asin_one().to_bits(), 1f64.asin().cos().to_bits());
        for (mode, radius) in [(G_2, 0.25), (G_3, 0.25), (G_2, -0.25), (G_3, 2.0)] {
            let (cur, end) = ((2.1, 0.1), (2.6, 0.1));
            let (cx, cy, _) = arc_data_r(mode, cur, end, radius, 1, RADIUS_TOLERANCE_MM).unwrap();
            let abs_radius = f64::abs(radius);
            let mid = ((end.0 + cur.0) / 2.0, (end.1 + cur.1) / 2.0);
            let mut half = (mid.0 - end.0).hypot(mid.1 - end.1);
            if half / abs_radius > 1.0 - TINY {
                half = abs_radius;
            }
            let heading = (end.1 - cur.1).atan2(end.0 - cur.0);
            let theta = if (mode == G_2 && radius > 0.0) || (mode == G_3 && radius < 0.0) {
                heading - FRAC_PI_2
            } else {
                heading + FRAC_PI_2
            };
            let offset = abs_radius * (half / abs_radius).asin().cos();
            let want = (mid.0 + offset * theta.cos(), mid.1 + offset * theta.sin());
            assert_eq!(
                (cx.to_bits(), cy.to_bits()),
                (want.0.to_bits(), want.1.to_bits())
            );
        }
    }

    #[test]
    fn integers_as_linuxcnc() {
        assert_eq!(integer(2.99995, 0).unwrap(), 3);
        assert_eq!(integer(3.00005, 0).unwrap(), 3);
        assert!(integer(3.001, 0).is_err());
    }
}
