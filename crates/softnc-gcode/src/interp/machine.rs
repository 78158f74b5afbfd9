//! The machine around the axes in `convert_m` (LinuxCNC's `interp_convert.cc`):
//! digital and analog I/O (M62–M68), the tool change (M6, M61), the spindle
//! (M3, M4, M5, M19), the coolant (M7, M8, M9), the override switches (M48–M53)
//! and user M codes (M100–M199), in that order, each a [`MachineOp`] at the current
//! point ([`MotionKind::Machine`]).

use super::{bad, round_to_int, Block, Interp, R};
use crate::canon::{
    CoolantLine, MachineOp, MessageKind, MotionKind, OverrideSwitch, SpindleTurn, WaitInput,
    WaitMode,
};
use crate::ErrorKind;
use softnc_core::machine_io::{ANALOG_LINES, DIGITAL_LINES};

/// The user M-code folder and what the reading found there.
#[derive(Debug, Clone, Default)]
pub(crate) struct UserMCodes {
    /// [`crate::ReadOptions::user_m_codes`].
    pub dir: Option<std::path::PathBuf>,
    /// Bit `n − 100`: `M{n}` was found executable (asked once a reading).
    found: u128,
}

impl UserMCodes {
    /// Whether `M{code}` is an executable file of the folder; `Err` says why not.
    fn check(&mut self, code: i32) -> Result<(), String> {
        let bit = 1u128 << (code - 100);
        if self.found & bit != 0 {
            return Ok(());
        }
        let Some(dir) = &self.dir else {
            return Err("no user M-code folder is configured".into());
        };
        let path = dir.join(format!("M{code}"));
        let meta = std::fs::metadata(&path)
            .map_err(|e| format!("{} cannot be read: {e}", path.display()))?;
        if !meta.is_file() || !executable(&meta) {
            return Err(format!("{} is not an executable file", path.display()));
        }
        self.found |= bit;
        Ok(())
    }
}

#[cfg(unix)]
fn executable(meta: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::PermissionsExt;
    meta.permissions().mode() & 0o111 != 0
}

#[cfg(not(unix))]
fn executable(_meta: &std::fs::Metadata) -> bool {
    true
}

impl Interp<'_> {
    /// A machine operation at the current point.
    pub(super) fn push_machine(&mut self, line_no: u32, op: MachineOp) {
        self.push_standing(line_no, MotionKind::Machine(op));
    }

    /// Run from line: the spindle (M3/M4 at the S in force) and the coolant as the
    /// modal state has them, at `start` (canonical frame, mm) on the approach; the
    /// tool in the spindle is the operator's to check.
    pub(super) fn push_machine_state(&mut self, line_no: u32, start: softnc_core::Vec3) {
        let mut ops = [None, None, None];
        if self.spindle_on {
            ops[0] = Some(MachineOp::SpindleOn {
                dir: self.spindle_turn(),
                rpm: self.s_rpm,
            });
        }
        if self.mist {
            ops[1] = Some(MachineOp::Coolant {
                which: CoolantLine::Mist,
                on: true,
            });
        }
        if self.flood {
            ops[2] = Some(MachineOp::Coolant {
                which: CoolantLine::Flood,
                on: true,
            });
        }
        for op in ops.into_iter().flatten() {
            let m = crate::canon::Motion {
                line: line_no,
                start,
                kind: MotionKind::Machine(op),
                offset_mm: self.offset(),
                path_mode: crate::canon::PathMode::ExactStop,
                inch: self.inch,
                canon_end: self.unframe(start),
                canon_center: softnc_core::Vec3::ZERO,
                spindle_rpm: self.spindle_rpm(),
            };
            self.keep(m);
        }
    }

    /// The program end (M2, M30; LinuxCNC's `convert_stop`, steps 7 and 9): the
    /// spindle stops ([`Self::implicit_spindle_stop`]), then each coolant that is on goes
    /// off (`MIST_OFF`, `FLOOD_OFF`), and the modal state says M5, no M7/M8.
    pub(super) fn program_end(&mut self, line_no: u32) {
        self.implicit_spindle_stop(line_no);
        if self.mist {
            self.mist = false;
            self.push_machine(
                line_no,
                MachineOp::Coolant {
                    which: CoolantLine::Mist,
                    on: false,
                },
            );
        }
        if self.flood {
            self.flood = false;
            self.push_machine(
                line_no,
                MachineOp::Coolant {
                    which: CoolantLine::Flood,
                    on: false,
                },
            );
        }
    }

    /// LinuxCNC's implicit `STOP_SPINDLE_TURNING` (at M6 and at the program end):
    /// the modal state says M5, and the stop is emitted only when the spindle turns.
    /// LinuxCNC emits it whether the spindle turns or not; here every machine
    /// operation is a stop of the path, and a stop that changes nothing would make
    /// every program (most never turn a spindle) stand one sample more at its end.
    fn implicit_spindle_stop(&mut self, line_no: u32) {
        let turning = self.spindle_on;
        self.spindle_on = false;
        self.spindle_code = 5;
        if turning {
            self.push_machine(line_no, MachineOp::SpindleOff);
        }
    }

    /// A comment for the operator: its text into the message table, its operation
    /// at the current point.
    pub(super) fn push_message(&mut self, line_no: u32, kind: MessageKind, text: &str) {
        let index = self.messages.len() as u32;
        self.messages.push(text.to_string());
        self.push_machine(line_no, MachineOp::Message { index, kind });
    }

    /// The direction the spindle turns in (M3 unless M4 is in force).
    pub(super) fn spindle_turn(&self) -> SpindleTurn {
        if self.spindle_code == 4 {
            SpindleTurn::CounterClockwise
        } else {
            SpindleTurn::Clockwise
        }
    }

    /// `convert_m` for one checked block (M0, M1, M2, M30 are `convert_stop`'s,
    /// M70–M73 the caller's).
    pub(super) fn machine_codes(&mut self, line_no: u32, b: &Block) -> R<()> {
        if let Some(code) = b.m_in(5) {
            self.io_code(line_no, code, b)?;
        }
        self.tool_change_codes(line_no, b)?;
        self.spindle_codes(line_no, b)?;
        // coolant (read by #<_mist>, #<_flood>): M7 `MIST_ON`, M8 `FLOOD_ON`, M9
        // `MIST_OFF` then `FLOOD_OFF`, whatever was on
        let coolant = |which, on| MachineOp::Coolant { which, on };
        match b.m_in(8) {
            Some(7) => {
                self.mist = true;
                self.push_machine(line_no, coolant(CoolantLine::Mist, true));
            }
            Some(8) => {
                self.flood = true;
                self.push_machine(line_no, coolant(CoolantLine::Flood, true));
            }
            Some(9) => {
                self.mist = false;
                self.flood = false;
                self.push_machine(line_no, coolant(CoolantLine::Mist, false));
                self.push_machine(line_no, coolant(CoolantLine::Flood, false));
            }
            _ => {}
        }
        if let Some(code) = b.m_in(9) {
            // M50–M53 without P (p_number −1) switch on, as LinuxCNC's `p_number != 0`
            let on = b.p_number != 0.0;
            let (switch, on) = match code {
                48 => (OverrideSwitch::FeedAndSpindle, true),
                49 => (OverrideSwitch::FeedAndSpindle, false),
                50 => (OverrideSwitch::Feed, on),
                51 => (OverrideSwitch::Spindle, on),
                52 => (OverrideSwitch::AdaptiveFeed, on),
                _ => (OverrideSwitch::FeedHold, on),
            };
            if self.comp.on() {
                return bad(
                    b.m_off(9),
                    if on {
                        "Cannot enable overrides with cutter radius compensation on"
                    } else {
                        "Cannot disable overrides with cutter radius compensation on"
                    },
                );
            }
            match switch {
                OverrideSwitch::FeedAndSpindle => {
                    self.feed_override_on = on;
                    self.speed_override_on = on;
                }
                OverrideSwitch::Feed => self.feed_override_on = on,
                OverrideSwitch::Spindle => self.speed_override_on = on,
                _ => {}
            }
            self.push_machine(line_no, MachineOp::Overrides { switch, on });
        }
        if let Some(code) = b.m_in(10) {
            // user M codes (`enqueue_M_USER_COMMAND` with P and Q, −1 where absent);
            // one without its executable is LinuxCNC's NCE_UNKNOWN_M_CODE_USED
            if let Err(why) = self.user_m.check(code) {
                return bad(b.m_off(10), format!("Unknown M code used: M{code} ({why})"));
            }
            self.push_machine(
                line_no,
                MachineOp::UserM {
                    code: code as u8,
                    p: b.p_number,
                    q: b.q_number,
                },
            );
        }
        Ok(())
    }

    /// M62–M68 with LinuxCNC's checks and messages.
    fn io_code(&mut self, line_no: u32, code: i32, b: &Block) -> R<()> {
        let off = b.m_off(5);
        let p = round_to_int(b.p_number);
        let digital_line = |what: &str| -> R<u8> {
            if !b.has(b'P') {
                return bad(off, format!("No valid P word with M{code}"));
            }
            match u8::try_from(p) {
                Ok(l) if usize::from(l) < DIGITAL_LINES => Ok(l),
                _ => bad(off, format!("{what} {p} out of bounds")),
            }
        };
        let e = b.get(b'E').map(round_to_int);
        if self.comp.on() && code != 66 {
            return bad(
                off,
                match code {
                    62 => "Cannot set motion output with cutter radius compensation on",
                    63 => "Cannot set motion digital output with cutter radius compensation on",
                    64 | 65 => {
                        "Cannot set auxiliary digital output with cutter radius compensation on"
                    }
                    67 => "Cannot set motion analog output with cutter radius compensation on",
                    _ => "Cannot set auxiliary analog output with cutter radius compensation on",
                },
            );
        }
        let op = match code {
            62..=65 => MachineOp::DigitalOut {
                line: digital_line("Digital output")?,
                on: code == 62 || code == 64,
                synchronised: code <= 63,
            },
            66 => {
                let op = self.wait_input(b, off)?;
                if self.comp.on() {
                    return bad(
                        off,
                        "Cannot wait for digital input with cutter radius compensation on",
                    );
                }
                op
            }
            _ => {
                let Some(e) = e.filter(|e| *e >= 0) else {
                    return bad(off, format!("Invalid analog index with M{code}"));
                };
                if e as usize >= ANALOG_LINES {
                    return bad(off, format!("Analog output {e} out of bounds"));
                }
                MachineOp::AnalogOut {
                    line: e as u8,
                    // LinuxCNC passes q_number as it stands (−1 without a Q)
                    value: b.q_number,
                    synchronised: code == 67,
                }
            }
        };
        if let MachineOp::WaitInput { input, .. } = op {
            self.input_waited(input, line_no);
        }
        self.push_machine(line_no, op);
        Ok(())
    }

    /// M66's words, checked as LinuxCNC checks them.
    fn wait_input(&self, b: &Block, off: u32) -> R<MachineOp> {
        let (has_p, has_e, has_l) = (b.has(b'P'), b.has(b'E'), b.has(b'L'));
        let l = b.get(b'L').map_or(0, round_to_int);
        if has_p && has_e {
            return bad(
                off,
                "Invalid to select both a digital and an analog input with M66",
            );
        }
        if b.q_number <= 0.0 && has_l && l > 0 {
            return bad(off, "Zero timeout with wait type != immediate return");
        }
        if has_e && has_l && l != 0 {
            return bad(
                off,
                "Can't select analog input with wait type != immediate return",
            );
        }
        let p = round_to_int(b.p_number);
        let e = b.get(b'E').map_or(-1, round_to_int);
        if (has_p && p < 0) || (has_e && e < 0) || (!has_p && !has_e) {
            return bad(
                off,
                "Need to have either a valid P or a valid E word with M66",
            );
        }
        let timeout_s = if b.q_number > 0.0 { b.q_number } else { 0.0 };
        if has_p {
            if p as usize >= DIGITAL_LINES {
                return bad(off, "Digital input selected out of bounds");
            }
            let mode = match l {
                0 => WaitMode::Immediate,
                1 => WaitMode::Rise,
                2 => WaitMode::Fall,
                3 => WaitMode::High,
                4 => WaitMode::Low,
                _ => return bad(off, format!("Unknown wait type L{l} with M66")),
            };
            Ok(MachineOp::WaitInput {
                input: WaitInput::Digital(p as u8),
                mode,
                timeout_s,
            })
        } else {
            if e as usize >= ANALOG_LINES {
                return bad(off, "Analog input selected out of bounds");
            }
            Ok(MachineOp::WaitInput {
                input: WaitInput::Analog(e as u8),
                mode: WaitMode::Immediate,
                timeout_s: 0.0,
            })
        }
    }

    /// After M66: #5399 as rs274's stand-alone interpreter leaves it (its
    /// `GET_EXTERNAL_DIGITAL_INPUT` returns the default, `#5399 != 0`; the analog one
    /// `#5399`), and, unless [`crate::M66Results::StandIn`], a read of it from here
    /// on refuses the program.
    fn input_waited(&mut self, input: WaitInput, line_no: u32) {
        if matches!(input, WaitInput::Digital(_)) {
            let v = f64::from(u8::from(self.params.get(5399) != 0.0));
            self.params.set(5399, v);
        }
        if self.m66_results == crate::M66Results::Refuse {
            self.m66_unknown_since.get_or_insert(line_no);
        }
    }

    /// M6 (`CHANGE_TOOL`) and M61 (`CHANGE_TOOL_NUMBER`).
    fn tool_change_codes(&mut self, line_no: u32, b: &Block) -> R<()> {
        match b.m_in(6) {
            Some(6) => {
                self.spindle_length_mm = self.tool_length(self.tool_selected as i32, 0)?;
                self.spindle_shape = self.tool_shape(self.tool_selected as i32, 0)?;
                // `convert_tool_change`: the spindle stops before the change (LinuxCNC's
                // default, without `TOOL_CHANGE_WITH_SPINDLE_ON`); a spindle that is not
                // turning is not stopped again (a stop that changes nothing would still
                // be a stop of the path)
                self.implicit_spindle_stop(line_no);
                self.tool_loaded = self.tool_selected;
                self.sync_pending = true;
                self.push_machine(
                    line_no,
                    MachineOp::ToolChange {
                        tool: self.tool_selected,
                    },
                );
            }
            Some(61) => {
                // sets the number of the tool in the spindle; rs274 keeps its data
                let off = b.m_off(6);
                let tool = round_to_int(b.q_number);
                if tool < 0 {
                    return bad(
                        off,
                        "Need non-negative Q-word to specify tool number with M61",
                    );
                }
                self.tool_length(tool, off)?;
                self.tool_loaded = tool as u32;
                self.sync_pending = true;
            }
            _ => {}
        }
        Ok(())
    }

    /// M3, M4, M5 and M19 (M70–M73 of the group are the caller's).
    fn spindle_codes(&mut self, line_no: u32, b: &Block) -> R<()> {
        match b.m_in(7) {
            Some(c @ (3 | 4)) => {
                self.spindle_on = true;
                self.spindle_code = c;
                let dir = self.spindle_turn();
                self.push_machine(
                    line_no,
                    MachineOp::SpindleOn {
                        dir,
                        rpm: self.s_rpm,
                    },
                );
            }
            Some(5) => {
                self.spindle_on = false;
                self.spindle_code = 5;
                self.push_machine(line_no, MachineOp::SpindleOff);
            }
            Some(19) => {
                // the spindle stops; `ORIENT_SPINDLE` only with R or P, the wait for
                // it (Q) > 0
                self.spindle_on = false;
                self.spindle_code = 5;
                if b.has(b'Q') && b.q_number <= 0.0 {
                    return bad(b.off(b'Q'), "Q word with M19 requires a value > 0");
                }
                if b.has(b'R') || b.has(b'P') {
                    self.push_machine(
                        line_no,
                        MachineOp::SpindleOrient {
                            angle_deg: b.get(b'R').unwrap_or(0.0),
                            direction: if b.has(b'P') {
                                round_to_int(b.p_number) as u8
                            } else {
                                0
                            },
                            timeout_s: b.q_number.max(0.0),
                        },
                    );
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// A read of #5399 where M66's result is unknown to a reading ahead: refused,
    /// at the `#5399` of line `raw` (its first; the line's start where it is
    /// reached otherwise, e.g. `#[5000 + 399]`). LinuxCNC reads no further than
    /// an M66 until the machine has waited (`INTERP_EXECUTE_FINISH`, the "queue
    /// buster"), so what follows may depend on the value; softnc checks the whole
    /// program before motion (its soft limits, its plan), which a branch on a value
    /// known only at the machine would escape.
    pub(super) fn check_5399_read(&self, raw: &str) -> R<()> {
        match (self.m66_read.get(), self.m66_unknown_since) {
            (true, Some(line)) => Err((
                where_5399(raw),
                ErrorKind::Unsupported {
                    word: "#5399".into(),
                    why: format!(
                        "#5399 holds the result of the M66 on line {line} only once the \
                         machine has waited there, and softnc checks the whole program \
                         before motion: after an M66, #5399 may be shown in (DEBUG,…) and \
                         (PRINT,…) comments (filled in when the machine gets there), not \
                         used in an expression, an assignment, a word or an O-word"
                    ),
                },
            )),
            _ => Ok(()),
        }
    }
}

/// The byte offset of the first `#5399` (spaces allowed after `#`) in `raw`
/// outside comments, else 0.
fn where_5399(raw: &str) -> u32 {
    let b = raw.as_bytes();
    let mut depth = 0u32;
    for (i, &c) in b.iter().enumerate() {
        match c {
            b'(' => depth += 1,
            b')' => depth = depth.saturating_sub(1),
            b';' if depth == 0 => break,
            b'#' if depth == 0 => {
                let digits: Vec<u8> = b[i + 1..]
                    .iter()
                    .copied()
                    .filter(|d| *d != b' ' && *d != b'\t')
                    .take(5)
                    .collect();
                if digits.starts_with(b"5399") && !digits.get(4).is_some_and(u8::is_ascii_digit) {
                    return i as u32;
                }
            }
            _ => {}
        }
    }
    0
}
