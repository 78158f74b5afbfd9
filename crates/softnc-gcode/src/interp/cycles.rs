//! Canned cycles G73, G74, G81–G87 and G89, expanded into canonical motions as
//! LinuxCNC 2.9's interpreter expands them (`convert_cycle`, `convert_cycle_xy`,
//! `convert_cycle_yz`, `convert_cycle_zx` and the `convert_cycle_gNN` bodies of
//! `interp_cycles.cc`): the same checks and messages, the same positioning moves
//! (`CYCLE_MACRO`), the same traverse/feed/dwell/spindle sequence, the retract to
//! the R plane (G99) or to the level the cycles started from (G98), `L` repeats,
//! incremental positions (G91), the sticky R, Z, P, Q, I, J, K of a cycle repeated
//! by bare axis words, and the exact-path mode (G61) LinuxCNC switches to for the
//! cycle's motions.
//!
//! The cycles run in the three planes of G17, G18 and G19: the plane's first two
//! axes position the hole, its third axis (Z, Y, X) drills. Left out, refused where
//! the code is read (`g_unsupported`) or here with `file:line:column`:
//! - G88 (stop for the operator to retract the spindle by hand, `PROGRAM_STOP`):
//!   the program would go on from where the operator left the tool, which the
//!   reading cannot know;
//! - G74 and G84 outside G17: LinuxCNC 2.9 swaps the axes of their feed moves in
//!   G18 and G19 (`convert_cycle_g74_g84` calls `cycle_feed` with its arguments in
//!   another order than every other cycle), so the tap would go elsewhere than
//!   programmed;
//! - G76 (threading) needs spindle-synchronised motion.

use super::{bad, sc, unsup, Block, Interp, R};
use crate::canon::{MachineOp, MotionKind, OverrideSwitch, PathMode, SpindleTurn};
use softnc_core::{Plane, Vec3};

/// Cycle codes × 10.
pub(super) const G_73: i32 = 730;
pub(super) const G_74: i32 = 740;
pub(super) const G_82: i32 = 820;
pub(super) const G_83: i32 = 830;
pub(super) const G_84: i32 = 840;
pub(super) const G_85: i32 = 850;
pub(super) const G_86: i32 = 860;
pub(super) const G_87: i32 = 870;
pub(super) const G_89: i32 = 890;

/// The peck retract of G73 and G83 (LinuxCNC 2.9's `G83_RAPID_DELTA`, inches).
const RAPID_DELTA_INCH: f64 = 0.010;

/// Whether a motion code (× 10) is a canned cycle (LinuxCNC's `is_a_cycle`).
pub(super) fn is_cycle(code: i32) -> bool {
    matches!(code, G_73 | G_74) || (801..900).contains(&code)
}

/// The values a cycle keeps for the next block of the same cycle (LinuxCNC's
/// `cycle_*` settings), in program units as the words gave them.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct CycleState {
    /// R word (`cycle_r`).
    r: f64,
    /// The drilling axis' word (`cycle_cc`): Z in G17, Y in G18, X in G19.
    cc: f64,
    /// P word (`cycle_p`): the dwell of G82, G86, G89, G74, G84 (s).
    p: f64,
    /// Q word (`cycle_q`): the peck of G73 and G83.
    q: f64,
    /// I, J, K words of G87 (`cycle_i`, `cycle_j`, `cycle_k`).
    ijk: [f64; 3],
    /// The level of the drilling axis when this series of cycles began
    /// (`cycle_il`), valid while `il_flag` (`cycle_il_flag`): any motion that is
    /// not a cycle ends the series.
    il: f64,
    il_flag: bool,
}

impl CycleState {
    /// Any motion that is not a cycle (G0–G3, G80) ends a series of cycles
    /// (`convert_motion`).
    pub(super) fn end_series(&mut self) {
        self.il_flag = false;
    }

    /// Whether a series of cycles is under way (the next cycle retracts to the
    /// level where it began, with G98).
    pub(super) fn in_series(&self) -> bool {
        self.il_flag
    }
}

/// The words of the axes X, Y, Z.
const AXIS: [u8; 3] = *b"XYZ";

/// LinuxCNC's `D2R`.
fn d2r(deg: f64) -> f64 {
    deg * (std::f64::consts::PI / 180.0)
}

/// What a cycle's body needs besides the hole's position: the values of its words.
struct Hole {
    /// The drilling axis' levels: R plane, clear level (where each repeat
    /// retracts to), bottom.
    r: f64,
    clear: f64,
    bottom: f64,
    /// Dwell (s).
    p: f64,
    /// Peck (G73, G83).
    q: f64,
    /// G87: offsets of the plane's first and second axes (program units) and the
    /// level of the top of the back bore.
    offset: (f64, f64),
    middle: f64,
    /// The spindle's direction at the start (G74, G84, G86, G87).
    dir: SpindleTurn,
}

impl Interp<'_> {
    /// `convert_cycle`: a block of canned cycle `motion` (code × 10).
    #[allow(clippy::too_many_lines)]
    pub(super) fn cycle(&mut self, line_no: u32, motion: i32, b: &Block) -> R<()> {
        let off = b.motion_off();
        if self.feed == 0.0 {
            return bad(off, "Cannot feed with zero feed rate");
        }
        if self.inverse_time {
            return bad(off, "Cannot use inverse time feed with canned cycles");
        }
        if self.comp.on() {
            return bad(off, "Cannot use canned cycles with cutter compensation on");
        }
        let same = self.motion == Some(motion);
        let r_word = match b.get(b'R') {
            Some(r) => r,
            None if same => self.cycle.r,
            None => return bad(off, "R clearance plane unspecified in cycle"),
        };
        let repeats = b.get(b'L').map_or(1, |l| l as i64);
        if repeats == 0 {
            return bad(b.off(b'L'), "Cannot do zero repeats of cycle");
        }
        let plane = self.plane;
        if matches!(motion, G_74 | G_84) && plane != Plane::XY {
            return unsup(
                off,
                super::fmt_code('G', motion),
                "tapping cycles (G74, G84) are supported in the XY plane (G17) only: LinuxCNC 2.9 swaps their axes in G18 and G19",
            );
        }
        // the plane's axes: the hole's position (ia, ib) and the drilling axis (ic)
        let (ia, ib, ic) = plane.axes();
        let name = plane.name();
        let ic_lower = (AXIS[ic] as char).to_ascii_lowercase();
        if !same && !b.has(AXIS[ic]) {
            return bad(
                off,
                format!(
                    "{} value unspecified in {name} plane canned cycle",
                    AXIS[ic] as char
                ),
            );
        }
        let cc_word = b.get(AXIS[ic]).unwrap_or(self.cycle.cc);
        let mut current_cc = self.pos[ic];
        let mut old_cc = if self.cycle.il_flag {
            self.cycle.il
        } else {
            self.cycle.il = current_cc;
            self.cycle.il_flag = true;
            current_cc
        };
        // polar words position the hole in the XY plane only (`check` refuses
        // them in the others)
        let polar = plane == Plane::XY && b.polar();
        let (mut aa, mut bb, r, cc);
        let (mut aa_inc, mut bb_inc, mut radius_inc, mut theta_inc) = (0.0, 0.0, 0.0, 0.0);
        if self.absolute {
            r = r_word;
            cc = cc_word;
            if polar {
                let (cx, cy) = (self.pos[0], self.pos[1]);
                let radius = b.get(b'@').unwrap_or_else(|| cy.hypot(cx));
                let theta = b.get(b'^').map_or_else(|| cy.atan2(cx), d2r);
                aa = radius * theta.cos();
                bb = radius * theta.sin();
            } else {
                aa = b.get(AXIS[ia]).unwrap_or(self.pos[ia]);
                bb = b.get(AXIS[ib]).unwrap_or(self.pos[ib]);
            }
        } else {
            aa_inc = b.get(AXIS[ia]).unwrap_or(0.0);
            bb_inc = b.get(AXIS[ib]).unwrap_or(0.0);
            if polar {
                radius_inc = b.get(b'@').unwrap_or(0.0);
                theta_inc = b.get(b'^').map_or(0.0, d2r);
            }
            r = r_word + old_cc;
            cc = r + cc_word;
            aa = self.pos[ia];
            bb = self.pos[ib];
        }
        if r < cc {
            return bad(
                off,
                format!("R less than {ic_lower} in cycle in {name} plane"),
            );
        }
        // the words of each cycle (LinuxCNC checks them after its first traverse;
        // an error stops the program either way)
        let p = match motion {
            G_82 | G_86 | G_89 | G_74 | G_84 => {
                if !same && b.p_number == -1.0 && !matches!(motion, G_74 | G_84) {
                    return bad(
                        off,
                        format!("Dwell time p word missing with g{}", motion / 10),
                    );
                }
                let p = if b.p_number == -1.0 {
                    self.cycle.p
                } else {
                    b.p_number
                };
                if p < 0.0 {
                    self.warnings.push(format!(
                        "{}:{line_no}: negative dwell P{p} taken as no dwell",
                        self.file
                    ));
                }
                p
            }
            _ => 0.0,
        };
        let q = match motion {
            G_73 | G_83 => {
                if !same && b.q_number == -1.0 {
                    return bad(off, format!("Q word missing with g{}", motion / 10));
                }
                let q = if b.q_number == -1.0 {
                    self.cycle.q
                } else {
                    b.q_number
                };
                if q <= 0.0 {
                    let q_off = if b.has(b'Q') { b.off(b'Q') } else { off };
                    return bad(q_off, "Negative or zero q value used");
                }
                q
            }
            _ => 0.0,
        };
        let mut ijk = self.cycle.ijk;
        if motion == G_87 {
            for (k, l) in [b'I', b'J', b'K'].into_iter().enumerate() {
                match b.get(l) {
                    Some(v) => ijk[k] = v,
                    None if !same => {
                        return bad(off, format!("{} word missing with g87", l as char))
                    }
                    None => {}
                }
            }
        }
        let dir = self.spindle_turn();
        match motion {
            G_74 | G_84 => {
                let code = super::fmt_code('G', motion);
                if !self.spindle_on {
                    return bad(off, format!("Spindle not turning in {code}"));
                }
                if motion == G_74 && dir == SpindleTurn::Clockwise {
                    return bad(off, "Spindle turning clockwise in G74");
                }
                if motion == G_84 && dir == SpindleTurn::CounterClockwise {
                    return bad(off, "Spindle turning counterclockwise in G84");
                }
            }
            G_86 | G_87 if !self.spindle_on => {
                return bad(off, format!("Spindle not turning in g{}", motion / 10));
            }
            _ => {}
        }
        // first motion of a series (maybe): below the R plane, straight up to it
        if old_cc < r {
            let mut end = self.pos;
            end[ic] = r;
            self.cycle_move(line_no, true, end);
            old_cc = r;
            current_cc = old_cc;
        }
        let clear = if self.retract_old_z { old_cc } else { r };
        // the cycle's motions in exact-path mode (SET_MOTION_CONTROL_MODE)
        let saved_path = self.path;
        self.path = PathMode::ExactStop;
        let middle = if self.absolute { ijk[ic] } else { cc + ijk[ic] };
        let mut hole = Hole {
            r,
            clear,
            bottom: cc,
            p,
            q,
            offset: (0.0, 0.0),
            middle,
            dir,
        };
        // CYCLE_MACRO: each repeat moves to its hole, then runs the body
        for rep in 0..repeats {
            aa += aa_inc;
            bb += bb_inc;
            if radius_inc != 0.0 || theta_inc != 0.0 {
                (aa, bb) = polar_step(aa, bb, radius_inc, theta_inc).map_err(|m| (off, m))?;
            }
            let at = |c: f64| plane_point(ia, ib, ic, aa, bb, c);
            if rep == 0 && current_cc > r {
                self.cycle_move(line_no, true, at(current_cc));
                self.cycle_move(line_no, true, at(r));
            } else {
                self.cycle_move(line_no, true, at(clear));
                if clear > r {
                    self.cycle_move(line_no, true, at(r));
                }
            }
            hole.offset = (aa + ijk[ia], bb + ijk[ib]);
            self.cycle_body(
                line_no,
                motion,
                &hole,
                |a, b2, c| plane_point(ia, ib, ic, a, b2, c),
                (aa, bb),
            );
        }
        let mut end = self.pos;
        end[ia] = aa;
        end[ib] = bb;
        end[ic] = clear;
        self.pos = end;
        self.cycle.cc = cc_word;
        self.path = saved_path;
        self.cycle.r = r_word;
        match motion {
            G_82 | G_86 | G_89 | G_74 | G_84 => self.cycle.p = p,
            G_73 | G_83 => self.cycle.q = q,
            G_87 => self.cycle.ijk = ijk,
            _ => {}
        }
        self.motion = Some(motion);
        Ok(())
    }

    /// The motions of one hole of cycle `motion`, the tool standing over it at the
    /// R plane: `point(a, b, c)` is the point of the plane's coordinates `a`, `b`
    /// and the drilling axis' `c`; `(x, y)` the hole in the plane.
    fn cycle_body(
        &mut self,
        line_no: u32,
        motion: i32,
        h: &Hole,
        point: impl Fn(f64, f64, f64) -> Vec3,
        (x, y): (f64, f64),
    ) {
        let at = |c: f64| point(x, y, c);
        let delta = if self.inch {
            RAPID_DELTA_INCH
        } else {
            RAPID_DELTA_INCH * super::MM_PER_INCH
        };
        match motion {
            G_73 | G_83 => {
                let mut depth = h.r - h.q;
                while depth > h.bottom {
                    self.cycle_move(line_no, false, at(depth));
                    if motion == G_83 {
                        self.cycle_move(line_no, true, at(h.r));
                    }
                    self.cycle_move(line_no, true, at(depth + delta));
                    depth -= h.q;
                }
                self.cycle_move(line_no, false, at(h.bottom));
                self.cycle_move(line_no, true, at(h.clear));
            }
            G_74 | G_84 => {
                let (feed_on, speed_on) = (self.feed_override_on, self.speed_override_on);
                self.overrides(line_no, OverrideSwitch::Feed, false);
                self.overrides(line_no, OverrideSwitch::Spindle, false);
                self.cycle_move(line_no, false, at(h.bottom));
                let (down, up) = if motion == G_84 {
                    (SpindleTurn::CounterClockwise, SpindleTurn::Clockwise)
                } else {
                    (SpindleTurn::Clockwise, SpindleTurn::CounterClockwise)
                };
                self.push_machine(line_no, MachineOp::SpindleOff);
                self.spindle_start(line_no, down);
                self.cycle_dwell(line_no, h.p);
                self.cycle_move(line_no, false, at(h.clear));
                self.push_machine(line_no, MachineOp::SpindleOff);
                self.spindle_start(line_no, up);
                if feed_on {
                    self.overrides(line_no, OverrideSwitch::Feed, true);
                }
                if speed_on {
                    self.overrides(line_no, OverrideSwitch::Spindle, true);
                }
            }
            G_85 => {
                self.cycle_move(line_no, false, at(h.bottom));
                self.cycle_move(line_no, false, at(h.r));
                self.cycle_move(line_no, true, at(h.clear));
            }
            G_86 => {
                self.cycle_move(line_no, false, at(h.bottom));
                self.cycle_dwell(line_no, h.p);
                self.spindle_stop(line_no);
                self.cycle_move(line_no, true, at(h.clear));
                self.spindle_start(line_no, h.dir);
            }
            G_87 => {
                let (ox, oy) = h.offset;
                let orient = MachineOp::SpindleOrient {
                    angle_deg: 0.0,
                    // LinuxCNC passes its CANON_DIRECTION as the mode
                    direction: if h.dir == SpindleTurn::Clockwise {
                        2
                    } else {
                        3
                    },
                    timeout_s: 0.0,
                };
                self.cycle_move(line_no, true, point(ox, oy, h.r));
                self.spindle_stop(line_no);
                self.push_machine(line_no, orient);
                self.cycle_move(line_no, true, point(ox, oy, h.bottom));
                self.cycle_move(line_no, true, at(h.bottom));
                self.spindle_start(line_no, h.dir);
                self.cycle_move(line_no, false, at(h.middle));
                self.cycle_move(line_no, false, at(h.bottom));
                self.spindle_stop(line_no);
                self.push_machine(line_no, orient);
                self.cycle_move(line_no, true, point(ox, oy, h.bottom));
                self.cycle_move(line_no, true, point(ox, oy, h.clear));
                self.cycle_move(line_no, true, at(h.clear));
                self.spindle_start(line_no, h.dir);
            }
            G_82 | G_89 => {
                self.cycle_move(line_no, false, at(h.bottom));
                self.cycle_dwell(line_no, h.p);
                self.cycle_move(line_no, motion == G_82, at(h.clear));
            }
            // G81
            _ => {
                self.cycle_move(line_no, false, at(h.bottom));
                self.cycle_move(line_no, true, at(h.clear));
            }
        }
    }

    /// `cycle_traverse` (`traverse`) or `cycle_feed` to `end` (program units).
    fn cycle_move(&mut self, line_no: u32, traverse: bool, end: Vec3) {
        let s = self.scale();
        let kind = if traverse {
            MotionKind::Traverse { end: sc(end, s) }
        } else {
            MotionKind::Feed {
                end: sc(end, s),
                feed_mm_per_min: self.feed * s,
            }
        };
        self.push(line_no, kind, end, Vec3::ZERO);
    }

    /// `DWELL(p)` (a negative time dwells not at all, as G4's).
    fn cycle_dwell(&mut self, line_no: u32, p: f64) {
        self.push_standing(
            line_no,
            MotionKind::Dwell {
                seconds: p.max(0.0),
            },
        );
    }

    /// `STOP_SPINDLE_TURNING` within a cycle: the motions until the spindle starts
    /// again run with it stopped (the modal direction is kept).
    fn spindle_stop(&mut self, line_no: u32) {
        self.push_machine(line_no, MachineOp::SpindleOff);
        self.spindle_on = false;
    }

    /// `START_SPINDLE_CLOCKWISE` / `_COUNTERCLOCKWISE` within a cycle, at the
    /// speed in force.
    fn spindle_start(&mut self, line_no: u32, dir: SpindleTurn) {
        self.spindle_on = true;
        self.push_machine(
            line_no,
            MachineOp::SpindleOn {
                dir,
                rpm: self.s_rpm,
            },
        );
    }

    /// `ENABLE_`/`DISABLE_FEED_OVERRIDE`, `…_SPEED_OVERRIDE`.
    fn overrides(&mut self, line_no: u32, switch: OverrideSwitch, on: bool) {
        match switch {
            OverrideSwitch::Feed => self.feed_override_on = on,
            _ => self.speed_override_on = on,
        }
        self.push_machine(line_no, MachineOp::Overrides { switch, on });
    }
}

/// The point of the plane coordinates `a`, `b` (axes `ia`, `ib`) and the drilling
/// axis' `c` (axis `ic`).
fn plane_point(ia: usize, ib: usize, ic: usize, a: f64, b: f64, c: f64) -> Vec3 {
    let mut p = Vec3::ZERO;
    p[ia] = a;
    p[ib] = b;
    p[ic] = c;
    p
}

/// `CYCLE_MACRO`'s polar increments (G91 with `@` and `^`): the distance from the
/// origin grows by `radius_inc`, then the angle by `theta_inc` (radians).
fn polar_step(
    mut aa: f64,
    mut bb: f64,
    radius_inc: f64,
    theta_inc: f64,
) -> Result<(f64, f64), crate::error::ErrorKind> {
    let at_origin = || {
        crate::error::ErrorKind::Invalid(
            "Incremental motion with polar coordinates is indeterminate when at the origin".into(),
        )
    };
    if radius_inc != 0.0 {
        if bb == 0.0 && aa == 0.0 {
            return Err(at_origin());
        }
        let theta = bb.atan2(aa);
        let radius = bb.hypot(aa) + radius_inc;
        aa = radius * theta.cos();
        bb = radius * theta.sin();
    }
    if theta_inc != 0.0 {
        if bb == 0.0 && aa == 0.0 {
            return Err(at_origin());
        }
        let theta = bb.atan2(aa) + theta_inc;
        let radius = bb.hypot(aa);
        aa = radius * theta.cos();
        bb = radius * theta.sin();
    }
    Ok((aa, bb))
}
