//! Canonical motions: what the interpreter hands the planner.
//!
//! Positions are in the frame of LinuxCNC's canonical output (the active work
//! coordinate system, mm). `offset_mm` maps that frame to machine coordinates
//! (work offset + G92 offset + tool length offset): `machine = end + offset_mm`.
//! In a system turned by an XY rotation (`G10 L2 R`) `start`, `end` and `center`
//! are turned with it (about the G92 origin, as LinuxCNC's `emccanon.cc` turns
//! them), so that this still holds; `canon_end` and `canon_center` keep the
//! unrotated values `rs274` prints.

use softnc_core::{Plane, Vec3};

/// How consecutive motions join (G61, G61.1, G64; LinuxCNC 2.9 has no G9, so neither
/// has softnc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PathMode {
    /// Stop exactly at the end of this motion (G61, G61.1).
    ExactStop,
    /// Blend into the next motion (G64). `None` uses the machine profile's
    /// tolerance; `Some(p)` is G64 P p (mm; 0 means "as fast as possible" as in
    /// LinuxCNC, i.e. the profile's tolerance).
    Blend {
        /// Largest deviation from the programmed corner (mm).
        tolerance_mm: Option<f64>,
        /// G64 Q q (mm): LinuxCNC's "naive CAM" tolerance. Consecutive G1 lines whose
        /// end points all lie within q of one straight line are run as that one line.
        /// `None`: no merging (no Q, or Q0).
        naive_cam_mm: Option<f64>,
    },
}

impl Default for PathMode {
    fn default() -> Self {
        PathMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        }
    }
}

/// What a canonical motion does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MotionKind {
    /// G0 rapid traverse to `end`.
    Traverse {
        /// End point (canonical frame, mm).
        end: Vec3,
    },
    /// G1 straight feed to `end`.
    Feed {
        /// End point (canonical frame, mm).
        end: Vec3,
        /// Feed (mm/min); for G93 the feed that results from the inverse time.
        feed_mm_per_min: f64,
    },
    /// G2/G3 arc or helix to `end`.
    Arc {
        /// End point (canonical frame, mm).
        end: Vec3,
        /// Centre (canonical frame, mm); its normal component is the start's.
        center: Vec3,
        /// Arc plane.
        plane: Plane,
        /// Signed turns as LinuxCNC's `rotation`: G3 > 0, G2 < 0, |turns| = 1 for up
        /// to one revolution.
        turns: i32,
        /// Feed (mm/min).
        feed_mm_per_min: f64,
    },
    /// G4 dwell.
    Dwell {
        /// Dwell time (s).
        seconds: f64,
    },
    /// M0 program stop, or M1 optional stop while the optional-stop switch is on
    /// (`ReadOptions::optional_stop`): LinuxCNC's `PROGRAM_STOP()` /
    /// `OPTIONAL_PROGRAM_STOP()` (`convert_stop`, the last step of a block). The path
    /// comes to rest exactly here (no blending across it) and waits for the
    /// operator's resume (cycle start).
    Pause {
        /// True for M1 (optional stop), false for M0.
        optional: bool,
    },
    /// The path comes to rest here and the next motion starts at the next
    /// interpolation cycle, without waiting for the operator: where LinuxCNC's task
    /// synchronises with motion before it goes on (the end of run-from-line's safe
    /// approach, `ReadOptions::from_line`).
    Sync,
    /// An operation of the machine around the axes (spindle, coolant, tool, I/O,
    /// messages, user M codes, override switches), at the current point, in program
    /// order. Whether the path comes to rest for it is [`MachineOp::stops_motion`].
    Machine(MachineOp),
    /// G38.2–G38.5 straight probe toward `end` at the feed, until the probe input
    /// trips (or clears): LinuxCNC's `STRAIGHT_PROBE`. Where the machine stops and
    /// where the probe tripped come from the machine ([`crate::ProbeResults`]).
    Probe {
        /// End point (canonical frame, mm): where the move stops at the latest.
        end: Vec3,
        /// Feed (mm/min).
        feed_mm_per_min: f64,
        /// Which of the four probe moves.
        probe: ProbeKind,
    },
}

/// Which G38 probe move: LinuxCNC's `probe_type` bits (bit 0: no error without a
/// trip, bit 1: until the probe clears).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProbeKind {
    /// Until the probe makes contact (G38.2, G38.3); else until it loses it
    /// (G38.4, G38.5).
    pub toward_contact: bool,
    /// The program fails when the move ends without a trip (G38.2, G38.4).
    pub fails_without_trip: bool,
}

impl ProbeKind {
    /// The kind of G38.`sub` (2–5).
    pub fn of_g38(sub: i32) -> ProbeKind {
        ProbeKind {
            toward_contact: sub <= 3,
            fails_without_trip: sub % 2 == 0,
        }
    }

    /// The G code's name (`G38.2` …).
    pub fn name(self) -> &'static str {
        match (self.toward_contact, self.fails_without_trip) {
            (true, true) => "G38.2",
            (true, false) => "G38.3",
            (false, true) => "G38.4",
            (false, false) => "G38.5",
        }
    }
}

/// The spindle's direction in a [`MachineOp::SpindleOn`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpindleTurn {
    /// M3.
    Clockwise,
    /// M4.
    CounterClockwise,
}

/// The coolant a [`MachineOp::Coolant`] switches.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CoolantLine {
    /// Mist (M7).
    Mist,
    /// Flood (M8).
    Flood,
}

/// What kind of comment a [`MachineOp::Message`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MessageKind {
    /// `(MSG,…)`: LinuxCNC's `MESSAGE`, shown to the operator.
    Msg,
    /// `(DEBUG,…)` with parameters substituted (while #5599 > 0): LinuxCNC's
    /// `MESSAGE` too.
    Debug,
    /// `(PRINT,…)` with parameters substituted: LinuxCNC's interpreter prints it
    /// on its standard error when it reads the line (no canonical call, no wait).
    Print,
}

/// The input M66 waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitInput {
    /// `P n`: digital input n.
    Digital(u8),
    /// `E n`: analog input n.
    Analog(u8),
}

/// M66's `L` word (LinuxCNC's `WAIT_MODE_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WaitMode {
    /// L0: read the input at once.
    Immediate,
    /// L1: wait for a rising edge.
    Rise,
    /// L2: wait for a falling edge.
    Fall,
    /// L3: wait for the input to be high.
    High,
    /// L4: wait for the input to be low.
    Low,
}

/// The override switches of M48–M53.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverrideSwitch {
    /// M48 (both on), M49 (both off): feed and spindle override.
    FeedAndSpindle,
    /// M50 P: feed override.
    Feed,
    /// M51 P: spindle override.
    Spindle,
    /// M52 P: adaptive feed.
    AdaptiveFeed,
    /// M53 P: feed hold.
    FeedHold,
}

/// One operation of the machine around the axes, as LinuxCNC's interpreter makes a
/// canonical call of it (`convert_m`, `convert_comment`, `convert_speed`,
/// `convert_tool_select`). `Copy`: a message's text is in [`Program::messages`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MachineOp {
    /// M3/M4, or an S word while the spindle turns: turn at `rpm`
    /// (`START_SPINDLE_CLOCKWISE` …, `SET_SPINDLE_SPEED`).
    SpindleOn {
        /// Direction.
        dir: SpindleTurn,
        /// Programmed speed (rpm).
        rpm: f64,
    },
    /// M5, M6 (LinuxCNC stops the spindle before a tool change unless its
    /// `TOOL_CHANGE_WITH_SPINDLE_ON`), and the program end (M2/M30):
    /// `STOP_SPINDLE_TURNING`.
    SpindleOff,
    /// M19 (`ORIENT_SPINDLE`): stop and orient to `angle_deg` (R), turning as
    /// `P` says (0: the shorter way, 1 clockwise, 2 counter-clockwise), within
    /// `timeout_s` (Q; 0: LinuxCNC's default of no timeout).
    SpindleOrient {
        /// Angle (degrees).
        angle_deg: f64,
        /// P: 0, 1 or 2.
        direction: u8,
        /// Q (s).
        timeout_s: f64,
    },
    /// One coolant switched on or off, one of LinuxCNC's `MIST_ON`, `MIST_OFF`,
    /// `FLOOD_ON`, `FLOOD_OFF`: M7 (mist on), M8 (flood on), M9 (mist off, then
    /// flood off: two operations, as LinuxCNC's `convert_m` makes two calls), and
    /// the program end (M2/M30: each coolant that is on, off, as `convert_stop`).
    Coolant {
        /// Which coolant.
        which: CoolantLine,
        /// On or off.
        on: bool,
    },
    /// T: prepare tool `tool` (`SELECT_TOOL`); LinuxCNC's task does not wait for
    /// motion for it.
    ToolPrepare {
        /// Tool number.
        tool: u32,
    },
    /// M6: change to the prepared tool (`CHANGE_TOOL`).
    ToolChange {
        /// The tool that goes into the spindle.
        tool: u32,
    },
    /// A comment for the operator; its text is `Program::messages[index]`.
    Message {
        /// Index into [`Program::messages`].
        index: u32,
        /// Which comment.
        kind: MessageKind,
    },
    /// M62/M63 (`synchronised`: at the start of the next motion) and M64/M65
    /// (immediate): digital output `line` on or off.
    DigitalOut {
        /// P: the output.
        line: u8,
        /// M62/M64: on; M63/M65: off.
        on: bool,
        /// M62/M63.
        synchronised: bool,
    },
    /// M67 (synchronised) and M68 (immediate): analog output `line` to `value`.
    AnalogOut {
        /// E: the output.
        line: u8,
        /// Q: the value.
        value: f64,
        /// M67.
        synchronised: bool,
    },
    /// M66: wait for an input; its value (or −1 on a timeout) goes to #5399.
    WaitInput {
        /// P or E.
        input: WaitInput,
        /// L.
        mode: WaitMode,
        /// Q (s; 0 with L0).
        timeout_s: f64,
    },
    /// M100–M199: run the executable `M1nn` of the user M-code folder with P and Q.
    UserM {
        /// 100..=199.
        code: u8,
        /// P (−1 when not given: LinuxCNC's `p_number`, passed as it stands).
        p: f64,
        /// Q (−1 when not given).
        q: f64,
    },
    /// M48–M53: an override switch on or off.
    Overrides {
        /// Which switch.
        switch: OverrideSwitch,
        /// On or off.
        on: bool,
    },
}

impl MachineOp {
    /// The name of LinuxCNC's canonical call for it (`canon.hh`), as `rs274`
    /// prints it (`PRINT` for `(PRINT,…)`, which has none: the interpreter prints
    /// it itself).
    pub fn canon_name(&self) -> &'static str {
        match *self {
            MachineOp::SpindleOn {
                dir: SpindleTurn::Clockwise,
                ..
            } => "START_SPINDLE_CLOCKWISE",
            MachineOp::SpindleOn { .. } => "START_SPINDLE_COUNTERCLOCKWISE",
            MachineOp::SpindleOff => "STOP_SPINDLE_TURNING",
            MachineOp::SpindleOrient { .. } => "ORIENT_SPINDLE",
            MachineOp::Coolant { which, on } => match (which, on) {
                (CoolantLine::Mist, true) => "MIST_ON",
                (CoolantLine::Mist, false) => "MIST_OFF",
                (CoolantLine::Flood, true) => "FLOOD_ON",
                (CoolantLine::Flood, false) => "FLOOD_OFF",
            },
            MachineOp::ToolPrepare { .. } => "SELECT_TOOL",
            MachineOp::ToolChange { .. } => "CHANGE_TOOL",
            MachineOp::Message {
                kind: MessageKind::Print,
                ..
            } => "PRINT",
            MachineOp::Message { .. } => "MESSAGE",
            MachineOp::DigitalOut {
                on, synchronised, ..
            } => match (synchronised, on) {
                (true, true) => "SET_MOTION_OUTPUT_BIT",
                (true, false) => "CLEAR_MOTION_OUTPUT_BIT",
                (false, true) => "SET_AUX_OUTPUT_BIT",
                (false, false) => "CLEAR_AUX_OUTPUT_BIT",
            },
            MachineOp::AnalogOut { synchronised, .. } => {
                if synchronised {
                    "SET_MOTION_OUTPUT_VALUE"
                } else {
                    "SET_AUX_OUTPUT_VALUE"
                }
            }
            MachineOp::WaitInput { .. } => "WAIT",
            MachineOp::UserM { .. } => "M_USER_COMMAND",
            MachineOp::Overrides { switch, on } => match (switch, on) {
                (OverrideSwitch::FeedAndSpindle, true) => "ENABLE_FEED_OVERRIDE",
                (OverrideSwitch::FeedAndSpindle, false) => "DISABLE_FEED_OVERRIDE",
                (OverrideSwitch::Feed, true) => "ENABLE_FEED_OVERRIDE",
                (OverrideSwitch::Feed, false) => "DISABLE_FEED_OVERRIDE",
                (OverrideSwitch::Spindle, true) => "ENABLE_SPEED_OVERRIDE",
                (OverrideSwitch::Spindle, false) => "DISABLE_SPEED_OVERRIDE",
                (OverrideSwitch::AdaptiveFeed, true) => "ENABLE_ADAPTIVE_FEED",
                (OverrideSwitch::AdaptiveFeed, false) => "DISABLE_ADAPTIVE_FEED",
                (OverrideSwitch::FeedHold, true) => "ENABLE_FEED_HOLD",
                (OverrideSwitch::FeedHold, false) => "DISABLE_FEED_HOLD",
            },
        }
    }

    /// Whether the path comes to rest before this operation and waits until it is
    /// done, as LinuxCNC's task waits for motion to finish before it issues the
    /// command (`emcTaskCheckPreconditions` in `emctaskmain.cc`: spindle, coolant,
    /// tool load, operator messages, system commands (user M codes), M66's
    /// `EMC_AUX_INPUT_WAIT`, M19, immediate I/O wait for motion). Tool prepare (T)
    /// waits only for I/O; synchronised outputs (M62, M63, M67) and the override
    /// switches (M48–M53) go with the motion queue: they take effect at the start
    /// of the next motion; `(PRINT,…)` is the interpreter's own output.
    pub fn stops_motion(&self) -> bool {
        match *self {
            MachineOp::SpindleOn { .. }
            | MachineOp::SpindleOff
            | MachineOp::SpindleOrient { .. }
            | MachineOp::Coolant { .. }
            | MachineOp::ToolChange { .. }
            | MachineOp::WaitInput { .. }
            | MachineOp::UserM { .. } => true,
            MachineOp::Message { kind, .. } => kind != MessageKind::Print,
            MachineOp::DigitalOut { synchronised, .. }
            | MachineOp::AnalogOut { synchronised, .. } => !synchronised,
            MachineOp::ToolPrepare { .. } | MachineOp::Overrides { .. } => false,
        }
    }
}

/// One canonical motion with where it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// 1-based source line.
    pub line: u32,
    /// Start point (canonical frame, mm): the previous motion's end.
    pub start: Vec3,
    /// The motion.
    pub kind: MotionKind,
    /// Canonical frame → machine coordinates for this motion.
    pub offset_mm: Vec3,
    /// How this motion joins the next.
    pub path_mode: PathMode,
    /// The program was in inches (G20) when this motion was read; LinuxCNC's
    /// canonical output prints it in inches with four decimals.
    pub inch: bool,
    /// End in the program's units, exactly as LinuxCNC's interpreter holds it.
    pub canon_end: Vec3,
    /// Arc centre in the program's units (zero for other motions).
    pub canon_center: Vec3,
    /// Spindle speed while this motion runs (rpm): the S word in force while the
    /// spindle turns (M3/M4), 0 while it is stopped (M5, or not started yet).
    pub spindle_rpm: f64,
}

/// A value in program units as LinuxCNC's canonical output prints it (`%.4f`),
/// converted to mm.
pub fn canon_round(v_units: f64, inch: bool) -> f64 {
    let printed: f64 = format!("{v_units:.4}").parse().unwrap_or(v_units);
    let r = if inch { printed * 25.4 } else { printed };
    if r == 0.0 {
        0.0 // no negative zero
    } else {
        r
    }
}

impl Motion {
    /// End and (for arcs) centre as LinuxCNC's canonical output prints them, in mm.
    pub fn canon_view(&self) -> (Option<Vec3>, Option<Vec3>) {
        let r = |v: Vec3| Vec3(v.0.map(|x| canon_round(x, self.inch)));
        match self.kind {
            MotionKind::Arc { .. } => (Some(r(self.canon_end)), Some(r(self.canon_center))),
            MotionKind::Dwell { .. }
            | MotionKind::Pause { .. }
            | MotionKind::Sync
            | MotionKind::Machine(_) => (None, None),
            _ => (Some(r(self.canon_end)), None),
        }
    }
}

impl MotionKind {
    /// End point, if this motion moves.
    pub fn end(&self) -> Option<Vec3> {
        match *self {
            MotionKind::Traverse { end }
            | MotionKind::Feed { end, .. }
            | MotionKind::Arc { end, .. }
            | MotionKind::Probe { end, .. } => Some(end),
            MotionKind::Dwell { .. }
            | MotionKind::Pause { .. }
            | MotionKind::Sync
            | MotionKind::Machine(_) => None,
        }
    }
}

/// A whole program as read.
#[derive(Debug, Clone, Default)]
pub struct Program {
    /// File name as given (used in messages).
    pub file: String,
    /// Number of blocks read: source lines, each time it is read (loops and
    /// subroutine calls read lines again; skipped lines count).
    pub blocks: usize,
    /// The canonical motions in order.
    pub motions: Vec<Motion>,
    /// Things worth telling the operator that do not stop the program
    /// (`file:line: text`).
    pub warnings: Vec<String>,
    /// The modal state the program left, as G-code that sets it
    /// ([`crate::ReadOptions::preamble`] of the next MDI command or job).
    pub end_modal: String,
    /// The subroutine files the reading took in, in the order first called
    /// ([`crate::SubroutineFiles`]).
    pub subroutine_files: Vec<crate::SubroutineFile>,
    /// The texts of the operator messages ([`MachineOp::Message`]'s `index`), in
    /// the order read.
    pub messages: Vec<String>,
    /// The log files the program writes (`(LOGOPEN,…)`, [`crate::log_files`]),
    /// with [`crate::ReadOptions::log_files`]; written by the caller.
    pub log_files: Vec<crate::log_files::LogFile>,
    /// With [`crate::ProbeResults::Known`]: the reading stopped after the probe
    /// move of this line, the last motion, whose result the machine has yet to
    /// give (`None`: the program was read to its end).
    pub awaits_probe: Option<u32>,
}
