//! The modal interpreter: blocks of words → canonical motions, with LinuxCNC's
//! modal-group rules, execution order within a block and errors.

use crate::canon::{Motion, MotionKind, PathMode, Program};
use crate::error::{ErrorKind, GcodeError};
use crate::lexer::{lex_line, Line, Word};
use softnc_core::{MachineProfile, Plane, Vec3};

const MM_PER_INCH: f64 = 25.4;
/// R-format arcs: how far the radius may fall short of half the chord (LinuxCNC's
/// RADIUS_TOLERANCE_INCH 0.00005 in; the mm value is its conversion).
const RADIUS_TOLERANCE_INCH: f64 = 0.00005;
/// Centre-format arcs: end radius may differ from start radius by this much (in the
/// program's units) when the relative difference exceeds `SPIRAL_RELATIVE_TOLERANCE`.
const CENTER_ARC_RADIUS_TOLERANCE_INCH: f64 = 2.0 * 0.001 * std::f64::consts::SQRT_2;
const CENTER_ARC_RADIUS_TOLERANCE_MM: f64 = 2.0 * 0.01 * std::f64::consts::SQRT_2;
const SPIRAL_RELATIVE_TOLERANCE: f64 = 0.001;
/// At most this many M codes on a line.
const MAX_M_CODES: usize = 4;
/// Work coordinate systems G54..G59.3.
const COORD_SYSTEMS: usize = 9;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MotionMode {
    Rapid,
    Linear,
    ArcCw,
    ArcCcw,
}

/// Modal groups of G codes (LinuxCNC numbering).
fn g_group(code: i32) -> Option<u8> {
    Some(match code {
        0
        | 10
        | 20
        | 30
        | 50
        | 51
        | 52
        | 53
        | 330
        | 331
        | 382..=385
        | 710
        | 711
        | 720
        | 721
        | 730
        | 740
        | 760
        | 800..=890 => 1,
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
        40 | 90 | 100 | 280 | 281 | 300 | 301 | 530 | 920 | 921 | 922 | 923 => 0,
        _ => return None,
    })
}

/// Modal groups of M codes.
fn m_group(code: i32) -> Option<u8> {
    Some(match code {
        0 | 1 | 2 | 30 | 60 => 4,
        6 | 61 => 6,
        3 | 4 | 5 | 19 => 7,
        7 | 8 | 9 => 8,
        48 | 49 | 50 | 51 | 52 | 53 => 9,
        62..=68 => 5,
        70..=73 => 11,
        98 | 99 => 12,
        _ => return None,
    })
}

fn fmt_code(letter: char, code: i32) -> String {
    if code % 10 == 0 {
        format!("{letter}{}", code / 10)
    } else {
        format!("{letter}{}.{}", code / 10, code % 10)
    }
}

/// One block's words sorted out.
#[derive(Default)]
struct Block {
    g: [Option<(i32, u32)>; 16],
    m: [Option<(i32, u32)>; 13],
    m_count: usize,
    /// value and column per letter A..Z
    val: [Option<(f64, u32)>; 26],
}

impl Block {
    fn get(&self, l: u8) -> Option<f64> {
        self.val[(l - b'A') as usize].map(|v| v.0)
    }
    fn col(&self, l: u8) -> u32 {
        self.val[(l - b'A') as usize].map_or(1, |v| v.1)
    }
    fn has(&self, l: u8) -> bool {
        self.val[(l - b'A') as usize].is_some()
    }
    fn g_in(&self, group: u8) -> Option<i32> {
        self.g[group as usize].map(|x| x.0)
    }
    fn m_in(&self, group: u8) -> Option<i32> {
        self.m[group as usize].map(|x| x.0)
    }
}

/// The interpreter's modal state.
struct Interp<'a> {
    file: &'a str,
    profile: &'a MachineProfile,
    inch: bool,
    absolute: bool,
    ijk_absolute: bool,
    plane: Plane,
    inverse_time: bool,
    feed_raw: f64,
    motion: Option<MotionMode>,
    /// Current point, canonical frame, in the program's units (as LinuxCNC keeps it,
    /// so that canonical output rounds exactly as rs274 prints it).
    pos: Vec3,
    /// The point as the canonical interface last saw it (motion ends and origin
    /// changes, not tool-length changes): after a tool change LinuxCNC re-reads its
    /// position from there.
    canon_pos: Vec3,
    /// A tool change happened: re-read the position before the next block.
    sync_pending: bool,
    coord: usize,
    tool_length_mm: f64,
    tool_selected: u32,
    tool_loaded: u32,
    path: PathMode,
    motions: Vec<Motion>,
    warnings: Vec<String>,
}

type R<T> = Result<T, (u32, ErrorKind)>;

fn bad<T>(col: u32, msg: impl Into<String>) -> R<T> {
    Err((col, ErrorKind::Invalid(msg.into())))
}

fn unsup<T>(col: u32, word: String, why: &str) -> R<T> {
    Err((
        col,
        ErrorKind::Unsupported {
            word,
            why: why.into(),
        },
    ))
}

impl<'a> Interp<'a> {
    fn new(file: &'a str, profile: &'a MachineProfile) -> Self {
        Interp {
            file,
            profile,
            inch: false,
            absolute: true,
            ijk_absolute: false,
            plane: Plane::XY,
            inverse_time: false,
            feed_raw: 0.0,
            motion: None,
            pos: Vec3::ZERO,
            canon_pos: Vec3::ZERO,
            sync_pending: false,
            coord: 0,
            tool_length_mm: 0.0,
            tool_selected: 0,
            tool_loaded: 0,
            path: PathMode::Blend { tolerance_mm: None },
            motions: Vec::new(),
            warnings: Vec::new(),
        }
    }

    fn scale(&self) -> f64 {
        if self.inch {
            MM_PER_INCH
        } else {
            1.0
        }
    }

    fn work_offset(&self, index: usize) -> Vec3 {
        if index < 6 {
            Vec3(self.profile.work_offset_mm(index))
        } else {
            Vec3::ZERO
        }
    }

    /// Canonical frame → machine coordinates.
    fn offset(&self) -> Vec3 {
        let mut o = self.work_offset(self.coord);
        o[2] += self.tool_length_mm;
        o
    }

    fn sort(&self, line: &Line) -> R<Block> {
        let mut b = Block::default();
        for w in &line.words {
            let Word {
                letter,
                value,
                column,
            } = *w;
            match letter {
                b'G' => {
                    let code10 = value * 10.0;
                    let code = code10.round();
                    if (code10 - code).abs() > 1e-6 || code < 0.0 {
                        return bad(column, "Unknown g code used");
                    }
                    let code = code as i32;
                    let Some(group) = g_group(code) else {
                        if code == 90 {
                            unreachable!()
                        }
                        return bad(column, "Unknown g code used");
                    };
                    if let Some((prev, _)) = b.g[group as usize] {
                        // LinuxCNC lets G80 stand beside a motion code (the motion wins)
                        if group == 1 && (prev == 800 || code == 800) {
                            if code != 800 {
                                b.g[1] = Some((code, column));
                            }
                            continue;
                        }
                        return bad(column, "Two g codes used from same modal group");
                    }
                    b.g[group as usize] = Some((code, column));
                }
                b'M' => {
                    let code = value.round();
                    if (value - code).abs() > 1e-6 || code < 0.0 {
                        return bad(column, "Unknown m code used");
                    }
                    let code = code as i32;
                    let Some(group) = m_group(code) else {
                        if (100..=199).contains(&code) {
                            return unsup(
                                column,
                                fmt_code('M', code * 10),
                                "user M codes are not supported",
                            );
                        }
                        return bad(column, "Unknown m code used");
                    };
                    if b.m[group as usize].is_some() {
                        return bad(column, "Two m codes used from same modal group");
                    }
                    b.m_count += 1;
                    if b.m_count > MAX_M_CODES {
                        return bad(column, "Too many m codes on line");
                    }
                    b.m[group as usize] = Some((code, column));
                }
                _ => {
                    let slot = &mut b.val[(letter - b'A') as usize];
                    if slot.is_some() {
                        return bad(
                            column,
                            format!(
                                "Multiple {} words on one line",
                                (letter as char).to_ascii_lowercase()
                            ),
                        );
                    }
                    *slot = Some((value, column));
                }
            }
        }
        Ok(b)
    }

    /// Refuse what softnc does not implement yet, naming the first such word.
    fn refuse_unsupported(&self, line: &Line) -> R<()> {
        for w in &line.words {
            let col = w.column;
            match w.letter {
                b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => {
                    return unsup(
                        col,
                        format!("{}", w.letter as char),
                        "axes other than X, Y, Z are not supported",
                    )
                }
                b'G' => {
                    let code = (w.value * 10.0).round() as i32;
                    let why = match code {
                        50..=53 => Some("splines (G5.x) are not supported yet"),
                        70 => Some("lathe diameter mode G7 is not supported"),
                        100 => Some("G10 (setting tables and offsets) is not supported yet"),
                        171 | 181 | 191 => Some("UVW planes are not supported"),
                        280 | 281 | 300 | 301 => {
                            Some("G28/G30 reference returns are not supported yet")
                        }
                        330 | 331 => Some("spindle-synchronised motion is not supported"),
                        382..=385 => Some("probing (G38.x) is not supported"),
                        410 | 411 | 420 | 421 => {
                            Some("cutter radius compensation is not supported yet")
                        }
                        431 | 432 => Some("dynamic tool length offsets are not supported yet"),
                        710 | 711 | 720 | 721 | 730 | 740 | 760 | 810..=890 => {
                            Some("canned cycles are not supported yet")
                        }
                        920..=923 => Some("G92 offsets are not supported yet"),
                        950 => Some("feed per revolution G95 is not supported"),
                        960 => Some("constant surface speed G96 is not supported"),
                        _ => None,
                    };
                    if let Some(why) = why {
                        return unsup(col, fmt_code('G', code), why);
                    }
                }
                b'M' => {
                    let code = w.value.round() as i32;
                    let why = match code {
                        66 | 67 | 68 => Some("M66-M68 I/O are not supported"),
                        70..=73 => Some("modal state save/restore (M70-M73) is not supported yet"),
                        98 | 99 => Some("M98/M99 subprograms are not supported yet"),
                        _ => None,
                    };
                    if let Some(why) = why {
                        return unsup(col, fmt_code('M', code * 10), why);
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    fn block(&mut self, line_no: u32, b: &Block) -> R<bool> {
        if self.sync_pending {
            self.pos = self.canon_pos;
            self.sync_pending = false;
        }
        let s = self.scale();
        // which words the block's codes use (LinuxCNC check_other_codes)
        let motion_code = b.g_in(1);
        let nonmodal = b.g_in(0);
        let arc_block = matches!(motion_code, Some(20) | Some(30))
            || (motion_code.is_none()
                && matches!(self.motion, Some(MotionMode::ArcCw | MotionMode::ArcCcw))
                && ["X", "Y", "Z"].iter().any(|l| b.has(l.as_bytes()[0])));
        let m_uses_p = matches!(b.m_in(9), Some(50..=53)) || b.m_in(5).is_some();
        if b.has(b'P')
            && !(arc_block
                || matches!(nonmodal, Some(40))
                || matches!(b.g_in(13), Some(640))
                || m_uses_p)
        {
            return bad(b.col(b'P'), "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it");
        }
        if b.has(b'Q') && !matches!(b.g_in(13), Some(640)) && b.m_in(6) != Some(61) {
            return bad(b.col(b'Q'), "Q word with no g code that uses it");
        }
        if b.has(b'R') && !arc_block {
            return bad(b.col(b'R'), "R word with no g code that uses it");
        }
        for (l, name) in [(b'I', "I"), (b'J', "J"), (b'K', "K")] {
            if b.has(l) && !arc_block {
                return bad(
                    b.col(l),
                    format!(
                        "{name} word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it"
                    ),
                );
            }
        }
        if b.has(b'H') && b.g_in(8) != Some(430) {
            return bad(b.col(b'H'), "H word with no G43 or G43.2 to use it");
        }
        if b.has(b'D') {
            return bad(
                b.col(b'D'),
                "D word with no G41, G41.1, G42, G42.1 to use it",
            );
        }
        if b.has(b'L') {
            return bad(b.col(b'L'), "L word with no g code that uses it");
        }
        for l in [b'F', b'S'] {
            if b.get(l).is_some_and(|v| v < 0.0) {
                return bad(
                    b.col(l),
                    format!("Negative {} word used", (l as char).to_ascii_lowercase()),
                );
            }
        }
        if b.get(b'T').is_some_and(|v| v < 0.0) {
            return bad(b.col(b'T'), "Negative tool id used");
        }

        // 2. feed mode, 3. feed rate
        match b.g_in(5) {
            Some(930) => self.inverse_time = true,
            Some(940) => self.inverse_time = false,
            _ => {}
        }
        if let Some(f) = b.get(b'F') {
            self.feed_raw = f;
        } else if self.inverse_time && b.g_in(5) == Some(930) {
            self.feed_raw = 0.0;
        }
        // 5. tool select, 6. change
        if let Some(t) = b.get(b'T') {
            self.tool_selected = t.round() as u32;
        }
        match b.m_in(6) {
            Some(6) => {
                self.tool_loaded = self.tool_selected;
                self.sync_pending = true;
            }
            Some(61) => {
                let Some(q) = b.get(b'Q') else {
                    return bad(b.m[6].map_or(1, |m| m.1), "Q word missing with M61");
                };
                if q < 0.0 || q.fract() != 0.0 {
                    return bad(b.col(b'Q'), "Invalid tool number with M61");
                }
                self.tool_loaded = q as u32;
                self.sync_pending = true;
            }
            _ => {}
        }
        // 10. dwell
        if nonmodal == Some(40) {
            let Some(p) = b.get(b'P') else {
                return bad(b.g[0].map_or(1, |g| g.1), "Dwell time missing with g4");
            };
            if p < 0.0 {
                return bad(b.col(b'P'), "Negative dwell time");
            }
            self.motions.push(Motion {
                line: line_no,
                start: self.pos * s,
                kind: MotionKind::Dwell { seconds: p },
                offset_mm: self.offset(),
                path_mode: self.path,
                inch: self.inch,
                canon_end: self.pos,
                canon_center: Vec3::ZERO,
            });
        }
        // 11. plane, 12. units
        match b.g_in(2) {
            Some(170) => self.plane = Plane::XY,
            Some(180) => self.plane = Plane::XZ,
            Some(190) => self.plane = Plane::YZ,
            _ => {}
        }
        match b.g_in(6) {
            Some(200) if !self.inch => {
                self.inch = true;
                self.pos = self.pos * (1.0 / MM_PER_INCH);
                self.canon_pos = self.canon_pos * (1.0 / MM_PER_INCH);
            }
            Some(210) if self.inch => {
                self.inch = false;
                self.pos = self.pos * MM_PER_INCH;
                self.canon_pos = self.canon_pos * MM_PER_INCH;
            }
            _ => {}
        }
        let s = if b.g_in(6).is_some() { self.scale() } else { s };
        // 14. tool length offset
        match b.g_in(8) {
            Some(430) => {
                let tool = match b.get(b'H') {
                    Some(h) => {
                        if h < 0.0 || h.fract() != 0.0 {
                            return bad(b.col(b'H'), "Negative or fractional H word");
                        }
                        h as u32
                    }
                    None => self.tool_loaded,
                };
                let len = if tool == 0 {
                    0.0
                } else {
                    match self.profile.tool_length_mm(tool) {
                        Some(l) => l,
                        None => {
                            return bad(
                                b.col(b'H').max(1),
                                format!("Requested tool {tool} not found in the tool table"),
                            )
                        }
                    }
                };
                self.pos[2] -= (len - self.tool_length_mm) / s;
                self.tool_length_mm = len;
            }
            Some(490) => {
                self.pos[2] += self.tool_length_mm / s;
                self.tool_length_mm = 0.0;
            }
            _ => {}
        }
        // 15. coordinate system
        if let Some(code) = b.g_in(12) {
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
            debug_assert!(idx < COORD_SYSTEMS);
            let shift = (self.work_offset(self.coord) - self.work_offset(idx)) * (1.0 / s);
            self.pos += shift;
            self.canon_pos += shift;
            self.coord = idx;
        }
        // 16. path control
        match b.g_in(13) {
            Some(610) | Some(611) => self.path = PathMode::ExactStop,
            Some(640) => {
                let p = b.get(b'P').map(|p| p * s);
                self.path = PathMode::Blend {
                    tolerance_mm: p.filter(|p| *p > 0.0),
                };
            }
            _ => {}
        }
        // 17. distance modes
        match b.g_in(3) {
            Some(900) => self.absolute = true,
            Some(910) => self.absolute = false,
            _ => {}
        }
        match b.g_in(4) {
            Some(901) => self.ijk_absolute = true,
            Some(911) => self.ijk_absolute = false,
            _ => {}
        }
        // 19-20. motion
        let axes = [b.get(b'X'), b.get(b'Y'), b.get(b'Z')];
        let any_axis = axes.iter().any(Option::is_some);
        if motion_code == Some(800) {
            self.motion = None;
            if any_axis && nonmodal != Some(530) {
                return bad(
                    b.col(b'X').min(b.col(b'Y')).min(b.col(b'Z')),
                    "Cannot use axis values with G80",
                );
            }
        }
        let new_mode = match motion_code {
            Some(0) => Some(MotionMode::Rapid),
            Some(10) => Some(MotionMode::Linear),
            Some(20) => Some(MotionMode::ArcCw),
            Some(30) => Some(MotionMode::ArcCcw),
            _ => None,
        };
        if let Some(m) = new_mode {
            self.motion = Some(m);
        }
        let g53 = nonmodal == Some(530);
        let moves = new_mode.is_some() || (any_axis && motion_code != Some(800));
        if any_axis && !moves {
            return bad(
                b.col(b'X').min(b.col(b'Y')).min(b.col(b'Z')),
                "Cannot use axis values without a g code that uses them",
            );
        }
        if moves {
            let Some(mode) = self.motion else {
                let col = [b'X', b'Y', b'Z']
                    .iter()
                    .filter(|l| b.has(**l))
                    .map(|l| b.col(*l))
                    .min()
                    .unwrap_or(1);
                return bad(
                    col,
                    "Cannot use axis values without a g code that uses them",
                );
            };
            if nonmodal == Some(40) && any_axis && new_mode.is_none() {
                return bad(1, "Cannot use axis values without a g code that uses them");
            }
            // end point, canonical frame (mm)
            let mut end = self.pos;
            if g53 {
                if !matches!(mode, MotionMode::Rapid | MotionMode::Linear) {
                    return bad(b.g[0].map_or(1, |g| g.1), "Must use g0 or g1 with g53");
                }
                if !self.absolute {
                    return bad(b.g[0].map_or(1, |g| g.1), "Cannot use g53 incremental");
                }
                let off = self.offset();
                for i in 0..3 {
                    if let Some(v) = axes[i] {
                        end[i] = v - off[i] / s;
                    }
                }
            } else {
                for i in 0..3 {
                    if let Some(v) = axes[i] {
                        end[i] = if self.absolute { v } else { self.pos[i] + v };
                    }
                }
            }
            let feed_col = b.g[1].map_or(1, |g| g.1);
            let kind = match mode {
                MotionMode::Rapid => MotionKind::Traverse { end: end * s },
                MotionMode::Linear => {
                    let feed =
                        self.feed_mm_per_min(b, feed_col, (end - self.pos).norm() * s, "g1")?;
                    MotionKind::Feed {
                        end: end * s,
                        feed_mm_per_min: feed,
                    }
                }
                MotionMode::ArcCw | MotionMode::ArcCcw => self.arc(b, mode, end, feed_col)?,
            };
            let (canon_end, canon_center) = match kind {
                MotionKind::Arc { center, .. } => (end, center * (1.0 / s)),
                _ => (end, Vec3::ZERO),
            };
            self.motions.push(Motion {
                line: line_no,
                start: self.pos * s,
                kind,
                offset_mm: self.offset(),
                path_mode: self.path,
                inch: self.inch,
                canon_end,
                canon_center,
            });
            self.pos = end;
            self.canon_pos = end;
        }
        // 21. stop
        Ok(matches!(b.m_in(4), Some(2) | Some(30)))
    }

    fn feed_mm_per_min(&self, b: &Block, col: u32, length_mm: f64, what: &str) -> R<f64> {
        if self.inverse_time {
            let Some(f) = b.get(b'F') else {
                return bad(col, format!("F word missing with inverse time {what} move"));
            };
            if f <= 0.0 {
                return bad(
                    b.col(b'F'),
                    format!("Zero or negative F word with inverse time {what} move"),
                );
            }
            // the feed that covers the move in 1/F minutes
            Ok(length_mm * f)
        } else {
            if self.feed_raw <= 0.0 {
                return bad(col, format!("Cannot do {what} with zero feed rate"));
            }
            Ok(self.feed_raw * self.scale())
        }
    }

    fn arc(&self, b: &Block, mode: MotionMode, end: Vec3, col: u32) -> R<MotionKind> {
        let s = self.scale();
        let (a, bb, n) = self.plane.axes();
        let ccw = mode == MotionMode::ArcCcw;
        let what = if ccw { "g3" } else { "g2" };
        let letters = [b'I', b'J', b'K'];
        let (la, lb, ln) = (letters[a], letters[bb], letters[n]);
        let plane_name = match self.plane {
            Plane::XY => "xy",
            Plane::XZ => "xz",
            Plane::YZ => "yz",
        };
        if b.has(ln) {
            return bad(
                b.col(ln),
                format!("{} word given for arc in {plane_name} plane", ln as char),
            );
        }
        let turns_abs = match b.get(b'P') {
            Some(p) => {
                if p.fract() != 0.0 || p < 1.0 {
                    return bad(b.col(b'P'), "P value not a positive integer with g2 or g3");
                }
                p as i32
            }
            None => 1,
        };
        let (s0, s1) = (self.pos[a], self.pos[bb]);
        let (e0, e1) = (end[a], end[bb]);
        // LinuxCNC's tolerances are in the program's units
        let units_scale = if self.inch { 1.0 } else { MM_PER_INCH };
        let (c0, c1);
        if let Some(r_raw) = b.get(b'R') {
            if b.has(la) || b.has(lb) {
                return bad(b.col(b'R'), "Mixed radius ijk format for arc");
            }
            if e0 == s0 && e1 == s1 {
                return bad(b.col(b'R'), "Current point same as end point of arc");
            }
            let radius = r_raw;
            let abs_r = radius.abs();
            let (mid0, mid1) = ((e0 + s0) / 2.0, (e1 + s1) / 2.0);
            let mut half = (mid0 - e0).hypot(mid1 - e1);
            if half - abs_r > RADIUS_TOLERANCE_INCH * units_scale {
                return bad(b.col(b'R'), "Arc radius too small to reach end point");
            }
            if abs_r == 0.0 || half / abs_r > 1.0 - 1e-12 {
                half = abs_r;
            }
            let theta = if (!ccw && radius > 0.0) || (ccw && radius < 0.0) {
                (e1 - s1).atan2(e0 - s0) - std::f64::consts::FRAC_PI_2
            } else {
                (e1 - s1).atan2(e0 - s0) + std::f64::consts::FRAC_PI_2
            };
            let turn2 = if abs_r > 0.0 {
                (half / abs_r).asin()
            } else {
                0.0
            };
            let offset = abs_r * turn2.cos();
            c0 = mid0 + offset * theta.cos();
            c1 = mid1 + offset * theta.sin();
        } else {
            if !b.has(la) && !b.has(lb) {
                return bad(
                    col,
                    format!("R, I, J, and K words all missing for arc ({what})"),
                );
            }
            let i = b.get(la).unwrap_or(0.0);
            let j = b.get(lb).unwrap_or(0.0);
            if self.ijk_absolute {
                c0 = i;
                c1 = j;
            } else {
                c0 = s0 + i;
                c1 = s1 + j;
            }
            let r1 = (c0 - s0).hypot(c1 - s1);
            let r2 = (c0 - e0).hypot(c1 - e1);
            let radius_tol = RADIUS_TOLERANCE_INCH * units_scale;
            if r1 < radius_tol || r2 < radius_tol {
                return bad(col, "Zero radius arc");
            }
            let abs_err = (r1 - r2).abs();
            let rel_err = abs_err / r1.max(r2);
            let spiral_abs = if self.inch {
                CENTER_ARC_RADIUS_TOLERANCE_INCH
            } else {
                CENTER_ARC_RADIUS_TOLERANCE_MM
            };
            if abs_err > spiral_abs && rel_err > SPIRAL_RELATIVE_TOLERANCE {
                return bad(
                    col,
                    format!(
                        "Radius to end of arc differs from radius to start: r1={:.4} r2={:.4} abs_err={:.4} rel_err={:.4}%",
                        r1,
                        r2,
                        abs_err,
                        rel_err * 100.0
                    ),
                );
            }
        }
        let mut center = self.pos;
        center[a] = c0;
        center[bb] = c1;
        let turns = if ccw { turns_abs } else { -turns_abs };
        // arc length for inverse-time feed
        let prim =
            softnc_core::Primitive::arc(self.pos * s, end * s, center * s, self.plane, turns);
        let feed = self.feed_mm_per_min(b, col, prim.length(), "arc")?;
        Ok(MotionKind::Arc {
            end: end * s,
            center: center * s,
            plane: self.plane,
            turns,
            feed_mm_per_min: feed,
        })
    }
}

/// Read a whole program (see [`crate::read_program`]).
pub fn read(text: &str, file: &str, profile: &MachineProfile) -> Result<Program, GcodeError> {
    let mut it = Interp::new(file, profile);
    let mut line = Line::default();
    let mut blocks = 0usize;
    let mut started_with_percent = false;
    let mut seen_content = false;
    let mut ended = false;
    let err = |line_no: usize, (col, kind): (u32, ErrorKind)| GcodeError {
        file: file.to_string(),
        line: line_no as u32,
        column: col,
        kind,
    };
    for (idx, raw) in text.lines().enumerate() {
        let line_no = idx + 1;
        blocks = line_no;
        if let Err(e) = lex_line(raw, &mut line) {
            // an unsupported word before the bad spot is the better explanation
            it.refuse_unsupported(&line).map_err(|e| err(line_no, e))?;
            return Err(err(line_no, e));
        }
        if line.percent {
            if !seen_content && !started_with_percent {
                started_with_percent = true;
                continue;
            }
            ended = true;
            break;
        }
        if line.words.is_empty() {
            if line.message.is_some() || !raw.trim().is_empty() {
                seen_content = true;
            }
            continue;
        }
        seen_content = true;
        // a `/` line runs: the block-delete switch is off, as in rs274's default
        it.refuse_unsupported(&line).map_err(|e| err(line_no, e))?;
        let block = it.sort(&line).map_err(|e| err(line_no, e))?;
        let stop = it
            .block(line_no as u32, &block)
            .map_err(|e| err(line_no, e))?;
        if stop {
            ended = true;
            break;
        }
    }
    if !ended {
        return Err(err(
            blocks.max(1),
            (
                1,
                ErrorKind::Invalid("File ended with no percent sign or program end".into()),
            ),
        ));
    }
    let _ = it.file;
    Ok(Program {
        file: file.to_string(),
        blocks,
        motions: it.motions,
        warnings: it.warnings,
    })
}
