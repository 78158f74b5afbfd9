//! Cutter radius compensation (G40, G41, G42, G41.1, G42.1) as LinuxCNC 2.9's
//! interpreter does it: the tool's centre is kept one tool radius to the left (G41)
//! or right (G42) of the programmed path, in the XY plane (G17) or the XZ plane
//! (G18, where the plane's first axis is Z and its second X).
//!
//! The functions follow `interp_convert.cc` (`convert_cutter_compensation_on`,
//! `convert_cutter_compensation_off`, `convert_straight_comp1`,
//! `convert_straight_comp2`, `convert_arc_comp1`, `convert_arc_comp2`), the queue
//! of `interp_queue.cc` (`enqueue_*`, `dequeue_canons`, `move_endpoint_and_flush`,
//! `set_endpoint`, `qc_scale`, the lathe tool origin of `latheorigin_x`/`_z`) and
//! `arc_data_comp_ijk`/`arc_data_comp_r` of `interp_arc.cc`, step by step (softnc's
//! own code, written from them):
//!
//! - The first move after G41/G42 is the entry: a straight line from where the tool
//!   stands to the point one radius beside the programmed end, square to the line
//!   from the tool to that end (`convert_straight_comp1`), or an arc
//!   (`convert_arc_comp1`).
//! - Each later move is held back in a queue until the next one shows the corner
//!   between them: at an outside (convex) corner an arc about the programmed corner
//!   joins the two offset paths; at an inside (concave) corner the held move's end
//!   is pulled back to where the two offset paths meet (`move_endpoint_and_flush`),
//!   line–line, line–arc, arc–line and arc–arc; a held move that would then run
//!   backwards is a gouge and an error. Arcs grow or shrink by the radius; a concave
//!   arc not larger than the tool is an error.
//! - Whatever the interpreter hands on meanwhile that LinuxCNC queues too (dwells,
//!   spindle, coolant, user M codes) waits in the same queue, in order; tool
//!   selection and changes and messages go out at once, as LinuxCNC's do.
//! - G40 flushes the queue with the last move ending where it stands; the next move
//!   (which must be straight) leaves from there to its programmed end: the exit.
//!   M0, M1, M2 and M30 flush the queue too (`convert_stop`); a program that ends
//!   with a `%` and compensation on loses the moves still held, as LinuxCNC's
//!   interpreter does (softnc warns).
//!
//! While compensation is on, the codes LinuxCNC refuses are refused with its
//! messages: other planes, coordinate systems, path control, retract mode, axis
//! offsets (G52, G92; not G92.1–G92.3), G28/G30 and G28.1/G30.1, G53 moves, G10 L2/L20 of
//! the active system, canned cycles, the I/O and override M codes, reading the
//! current position (#5420–#5428).
//!
//! LinuxCNC adds `M_PIl`, `M_PI_2l` and `2 * M_PIl` to its angles in x87 `long
//! double` and stores the sums in `double`s: so does this ([`Ld`]), so that the
//! compensated points have LinuxCNC's bits (a point half way between two printed
//! decimals prints as `rs274` prints it). One step is taken to first order:
//! `sin(beta - M_PI_2l)` of a line–arc inside corner, which C++ computes with
//! `sinl` of the `long double` difference. The sweeps of `find_turn` (compared with
//! a slack of 0.001 in / 0.0254 mm when a held arc's end moves) stay in `f64`.

use super::{bad, find_turn, sc, Block, Interp, MotionKind, G_0, G_1, G_2, G_3, R};
use crate::canon::Motion;
use crate::x87::Ld;
use softnc_core::{Plane, Vec3};

/// `x + c` in `long double`, stored in a `double`.
fn ld_add(x: f64, c: Ld) -> f64 {
    Ld::from_f64(x).add(c).to_f64()
}

/// `x - c` in `long double`, stored in a `double`.
fn ld_sub(x: f64, c: Ld) -> f64 {
    Ld::from_f64(x).sub(c).to_f64()
}

/// `x > c`, `c` a `long double`.
fn ld_gt(x: f64, c: Ld) -> bool {
    c.lt(Ld::from_f64(x))
}

/// `x < c`, `c` a `long double`.
fn ld_lt(x: f64, c: Ld) -> bool {
    Ld::from_f64(x).lt(c)
}

/// `M_PI_2l` stored in a `double`.
fn half_pi() -> f64 {
    Ld::HALF_PI.to_f64()
}

/// LinuxCNC's `TOLERANCE_CONCAVE_CORNER` (radians).
const SMALL: f64 = 0.05;
/// LinuxCNC's `TOLERANCE_EQUAL`.
const TOLERANCE_EQUAL: f64 = 0.0001;

/// The side of the path the tool keeps to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Side {
    /// G41, G41.1.
    Left,
    /// G42, G42.1.
    Right,
}

/// A canonical call held back while compensation is on (`queued_canon`).
#[derive(Debug, Clone, Copy)]
enum Queued {
    /// `STRAIGHT_TRAVERSE` / `STRAIGHT_FEED`.
    Straight {
        traverse: bool,
        line: u32,
        /// The direction of the programmed move in the plane (first, second axis).
        dir: (f64, f64),
        /// End (program units, canonical frame, X Y Z).
        end: Vec3,
        feed_mm_per_min: f64,
        rpm: f64,
    },
    /// `ARC_FEED`, in the plane's coordinates.
    Arc {
        line: u32,
        /// The sweep of the programmed arc (radians; 0: never moved).
        original_turns: f64,
        end1: f64,
        end2: f64,
        center1: f64,
        center2: f64,
        turn: i32,
        end3: f64,
        feed_mm_per_min: f64,
        rpm: f64,
    },
    /// Anything else LinuxCNC queues (a dwell, a spindle, coolant or user M code).
    Other {
        line: u32,
        kind: MotionKind,
        rpm: f64,
    },
}

/// The compensation state (LinuxCNC's `cutter_comp_*`, `program_*` settings) and
/// its queue.
#[derive(Debug, Clone)]
pub(super) struct Comp {
    /// `cutter_comp_side`: `None` is G40.
    side: Option<Side>,
    /// `cutter_comp_radius` (program units, ≥ 0).
    radius: f64,
    /// `cutter_comp_orientation` (G41.1/G42.1 L in G18; 0 for a mill tool).
    orientation: i32,
    /// `cutter_comp_firstmove`: the next move is the entry.
    firstmove: bool,
    /// `arc_not_allowed`: the move after the exit must be straight.
    arc_not_allowed: bool,
    /// `program_x/y/z`: the programmed point (the tool's centre is `Interp::pos`).
    program: Vec3,
    /// The queue (`qc()`).
    queue: Vec<Queued>,
    /// `endpoint`, `endpoint_valid` of `interp_queue.cc` (plane coordinates).
    endpoint: (f64, f64),
    endpoint_valid: bool,
    /// Where the next motion handed on starts (program units, canonical frame):
    /// the end of the last one.
    emitted: Vec3,
    /// After an exit: where the tool stands (machine coordinates, mm), while the
    /// interpreter's point is the programmed one; the next motion starts there.
    exit_start_mm: Option<Vec3>,
}

impl Default for Comp {
    fn default() -> Self {
        Comp {
            side: None,
            radius: 0.0,
            orientation: 0,
            firstmove: true,
            arc_not_allowed: false,
            program: Vec3::ZERO,
            queue: Vec::new(),
            endpoint: (0.0, 0.0),
            endpoint_valid: false,
            emitted: Vec3::ZERO,
            exit_start_mm: None,
        }
    }
}

/// `TOOL_INSIDE_ARC`.
fn tool_inside_arc(side: Side, turn: i32) -> bool {
    (side == Side::Left && turn > 0) || (side == Side::Right && turn < 0)
}

impl Comp {
    /// Compensation is on (G41/G42 in force, whatever the radius).
    pub(super) fn on(&self) -> bool {
        self.side.is_some()
    }

    /// The G code of the group as `#<_ccomp>` and M70 see it (G41.1 as G41).
    pub(super) fn code(&self) -> i32 {
        match self.side {
            None => 400,
            Some(Side::Left) => 410,
            Some(Side::Right) => 420,
        }
    }

    /// Whether the short way (`fast`) must leave lines to the general reader:
    /// compensation on, or the exit not yet made (its start differs from the
    /// interpreter's point, and an arc is refused).
    pub(super) fn busy(&self) -> bool {
        self.side.is_some() || self.arc_not_allowed || self.exit_start_mm.is_some()
    }

    /// The next compensated move is the entry (`cutter_comp_firstmove`).
    pub(super) fn firstmove(&self) -> bool {
        self.firstmove
    }

    /// The programmed point (`program_x/y/z`).
    pub(super) fn program(&self) -> Vec3 {
        self.program
    }

    /// `arc_not_allowed`.
    pub(super) fn arc_not_allowed(&self) -> bool {
        self.arc_not_allowed
    }

    /// A straight move: arcs may follow (`convert_straight`).
    pub(super) fn arc_allowed_again(&mut self) {
        self.arc_not_allowed = false;
    }

    /// Moves are being held back (`!qc().empty()`).
    pub(super) fn holding(&self) -> bool {
        !self.queue.is_empty()
    }

    /// Where a standing operation happens while moves are held: the end of the
    /// last motion handed on.
    pub(super) fn emitted(&self) -> Vec3 {
        self.emitted
    }

    /// Whether LinuxCNC queues this kind of canonical call behind held moves
    /// (`enqueue_DWELL`, `enqueue_START_SPINDLE_*`, `enqueue_SET_SPINDLE_SPEED`,
    /// `enqueue_STOP_SPINDLE_TURNING`, `enqueue_ORIENT_SPINDLE`, `enqueue_MIST_*`,
    /// `enqueue_FLOOD_*`, `enqueue_M_USER_COMMAND`); tool selection and change,
    /// messages and the rest go out at once.
    pub(super) fn queues(kind: &MotionKind) -> bool {
        use crate::canon::MachineOp as Op;
        matches!(
            kind,
            MotionKind::Dwell { .. }
                | MotionKind::Machine(
                    Op::SpindleOn { .. }
                        | Op::SpindleOff
                        | Op::SpindleOrient { .. }
                        | Op::Coolant { .. }
                        | Op::UserM { .. }
                )
        )
    }

    /// Hold `kind` (a [`Comp::queues`] kind) behind the moves held.
    pub(super) fn hold(&mut self, line: u32, kind: MotionKind, rpm: f64) {
        self.queue.push(Queued::Other { line, kind, rpm });
    }

    /// The start of the motion after an exit, once (machine coordinates, mm).
    pub(super) fn take_exit_start(&mut self, moving: bool) -> Option<Vec3> {
        let s = self.exit_start_mm;
        if moving {
            self.exit_start_mm = None;
        }
        s
    }

    /// `qc_scale` and the unit change of `convert_length_units`: the programmed
    /// point, the radius and the held moves in the new units. (LinuxCNC scales its
    /// `endpoint` once per held call, not once: so does this.)
    pub(super) fn scale(&mut self, k: f64) {
        self.program = self.program * k;
        self.radius *= k;
        self.emitted = self.emitted * k;
        for q in &mut self.queue {
            self.endpoint.0 *= k;
            self.endpoint.1 *= k;
            match q {
                Queued::Arc {
                    end1,
                    end2,
                    end3,
                    center1,
                    center2,
                    ..
                } => {
                    *end1 *= k;
                    *end2 *= k;
                    *end3 *= k;
                    *center1 *= k;
                    *center2 *= k;
                }
                Queued::Straight { end, .. } => *end = *end * k,
                Queued::Other { .. } => {}
            }
        }
    }

    /// The tool length offset changed the interpreter's Z by `dz` while moves are
    /// held: the point the next motion handed on starts from moves with it.
    pub(super) fn shift_z(&mut self, dz: f64) {
        self.emitted[2] += dz;
    }

    /// `set_endpoint`.
    fn set_endpoint(&mut self, x: f64, y: f64) {
        self.endpoint = (x, y);
        self.endpoint_valid = true;
    }

    /// The first held motion is an arc: it, as held.
    fn front_arc(&self) -> Option<(f64, f64, f64, f64, i32)> {
        match self.queue.first() {
            Some(&Queued::Arc {
                end1,
                end2,
                center1,
                center2,
                turn,
                ..
            }) => Some((end1, end2, center1, center2, turn)),
            _ => None,
        }
    }
}

/// A point's coordinates in the compensation plane: (first, second, normal).
fn split(plane: Plane, p: Vec3) -> (f64, f64, f64) {
    let (a, b, n) = plane.axes();
    (p[a], p[b], p[n])
}

/// The point of plane coordinates (first, second, normal).
fn join(plane: Plane, x: f64, y: f64, z: f64) -> Vec3 {
    let (a, b, n) = plane.axes();
    let mut p = Vec3::ZERO;
    p[a] = x;
    p[b] = y;
    p[n] = z;
    p
}

impl Interp<'_> {
    /// `convert_cutter_compensation_on` (G41, G42, G41.1, G42.1 of the block).
    pub(super) fn comp_on(&mut self, code: i32, b: &Block) -> R<()> {
        let off = b.g_off(super::GM_CUTTER_COMP);
        if self.plane == Plane::YZ {
            return bad(
                off,
                "Cutter radius compensation allowed only in XY, XZ planes",
            );
        }
        if self.comp.on() {
            return bad(off, "Cannot turn cutter radius comp on when on");
        }
        let mut side = if matches!(code, 410 | 411) {
            Side::Left
        } else {
            Side::Right
        };
        let (radius, orientation);
        if code == 411 || code == 421 {
            let Some(d) = b.get(b'D') else {
                return bad(off, format!("G{}.1 with no D word", code / 10));
            };
            radius = d / 2.0;
            orientation = match b.get(b'L') {
                Some(l) => {
                    if self.plane != Plane::XZ {
                        return bad(
                            off,
                            format!("G{}.1 with L word, but plane is not G18", code / 10),
                        );
                    }
                    l as i32
                }
                None => 0,
            };
        } else {
            let (diameter_mm, tool_orientation) = match b.get(b'D') {
                None => self.spindle_shape,
                Some(d) => {
                    // is_near_int
                    let tool = (d + 0.5) as i32;
                    if (f64::from(tool) - d).abs() >= 0.0001 {
                        return bad(
                            b.off(b'D'),
                            format!("G{} requires D word to be a whole number", code / 10),
                        );
                    }
                    if tool < 0 {
                        return bad(b.off(b'D'), "Negative D word tool radius index used");
                    }
                    self.tool_shape(tool, b.off(b'D'))?
                }
            };
            radius = diameter_mm / self.scale() / 2.0;
            orientation = tool_orientation;
            if self.plane != Plane::XZ && orientation != 0 && orientation != 9 {
                return bad(
                    off,
                    format!("G{} with lathe tool, but plane is not G18", code / 10),
                );
            }
        }
        let radius = if radius < 0.0 {
            // a negative diameter: the other side, the positive radius
            side = match side {
                Side::Left => Side::Right,
                Side::Right => Side::Left,
            };
            -radius
        } else {
            radius
        };
        self.comp.radius = radius;
        self.comp.orientation = orientation;
        self.comp.side = Some(side);
        Ok(())
    }

    /// `convert_cutter_compensation_off` (G40): the held moves go, the last one
    /// ending where the tool stands; the interpreter's point becomes the programmed
    /// one, and the tool leaves from where it stands with the next (straight) move.
    pub(super) fn comp_off(&mut self, off: u32) -> R<()> {
        if self.comp.on() && self.comp.radius > 0.0 && !self.comp.firstmove {
            let (cx, cy, _) = split(self.plane, self.pos);
            self.move_endpoint_and_flush(cx, cy, off)?;
            self.dequeue_canons();
            // where the last motion handed on ended (a lathe tool's origin, off
            // the radius centre the interpreter's point is)
            let stands = sc(self.frame(self.comp.emitted), self.scale()) + self.offset();
            self.pos = self.comp.program;
            self.comp.exit_start_mm = Some(stands);
            self.comp.arc_not_allowed = true;
        }
        self.comp.side = None;
        self.comp.firstmove = true;
        Ok(())
    }

    /// `convert_stop`'s start (M0, M1, M2, M30): the held moves go, the last one
    /// ending where it ends; M2 and M30 (`end`) turn compensation off.
    pub(super) fn comp_stop(&mut self, end: bool, off: u32) -> R<()> {
        let (cx, cy, _) = split(self.plane, self.pos);
        self.move_endpoint_and_flush(cx, cy, off)?;
        self.dequeue_canons();
        if end {
            self.comp.side = None;
            self.comp.firstmove = true;
        }
        Ok(())
    }

    /// #5420–#5428 read on this line while compensation is on: LinuxCNC's
    /// error for the line.
    pub(super) fn position_read_check(&self) -> R<()> {
        if self.position_read_in_comp.replace(false) {
            return bad(
                0,
                "Cannot read current position with cutter radius compensation on",
            );
        }
        Ok(())
    }

    /// A program ending with compensation on and moves held (a `%` end without
    /// M2): LinuxCNC's interpreter never hands them on; softnc says so.
    pub(super) fn comp_dropped_at_end(&mut self) {
        let moves = self
            .comp
            .queue
            .iter()
            .filter(|q| !matches!(q, Queued::Other { .. }))
            .count();
        if moves > 0 {
            let line = match self.comp.queue[0] {
                Queued::Straight { line, .. }
                | Queued::Arc { line, .. }
                | Queued::Other { line, .. } => line,
            };
            self.warnings.push(format!(
                "{}:{line}: the program ends with cutter radius compensation on: the {moves} move(s) from line {line} held for the next corner are left out, as LinuxCNC leaves them (end the program with G40 and M2)",
                self.file
            ));
            self.comp.queue.clear();
        }
    }

    /// Whether the straight move of this block is compensated (`convert_straight`'s
    /// test), and then the move: `Ok(true)` when it was made here.
    pub(super) fn comp_straight(
        &mut self,
        line_no: u32,
        mode: i32,
        b: &Block,
        end: Vec3,
    ) -> R<bool> {
        if !(self.comp.on() && self.comp.radius > 0.0) {
            return Ok(false);
        }
        let off = b.motion_off();
        if b.g_in(super::GM_MODAL_0) == Some(super::G_53) {
            return bad(off, "Cannot use g53 with cutter radius comp");
        }
        let (px, py, pz) = split(self.plane, end);
        if self.comp.firstmove {
            self.straight_comp1(line_no, mode, px, py, pz, off)?;
        } else {
            self.straight_comp2(line_no, mode, px, py, pz, off)?;
        }
        Ok(true)
    }

    /// The feed now (mm/min).
    fn feed_mm(&self) -> f64 {
        self.feed * self.scale()
    }

    /// `enqueue_STRAIGHT_TRAVERSE` / `enqueue_STRAIGHT_FEED` (plane coordinates).
    #[allow(clippy::too_many_arguments)]
    fn enqueue_straight(&mut self, line: u32, mode: i32, dx: f64, dy: f64, x: f64, y: f64, z: f64) {
        let q = Queued::Straight {
            traverse: mode == G_0,
            line,
            dir: (dx, dy),
            end: join(self.plane, x, y, z),
            feed_mm_per_min: self.feed_mm(),
            rpm: self.spindle_rpm(),
        };
        self.comp.queue.push(q);
    }

    /// `enqueue_ARC_FEED` (plane coordinates).
    #[allow(clippy::too_many_arguments)]
    fn enqueue_arc(
        &mut self,
        line: u32,
        original_turns: f64,
        end: (f64, f64),
        center: (f64, f64),
        turn: i32,
        end3: f64,
    ) {
        let q = Queued::Arc {
            line,
            original_turns,
            end1: end.0,
            end2: end.1,
            center1: center.0,
            center2: center.1,
            turn,
            end3,
            feed_mm_per_min: self.feed_mm(),
            rpm: self.spindle_rpm(),
        };
        self.comp.queue.push(q);
    }

    /// `dequeue_canons`: hand the held calls on, in order, each motion from the
    /// end of the one before (with a lathe tool's origin moved off the radius
    /// centre, `latheorigin_x`/`_z`).
    fn dequeue_canons(&mut self) {
        self.comp.endpoint_valid = false;
        if self.comp.queue.is_empty() {
            return;
        }
        let queue = std::mem::take(&mut self.comp.queue);
        let s = self.scale();
        for q in &queue {
            let start = self.comp.emitted;
            match *q {
                Queued::Straight {
                    traverse,
                    line,
                    end,
                    feed_mm_per_min,
                    rpm,
                    ..
                } => {
                    let mut end = end;
                    end[0] = self.lathe_x(end[0]);
                    end[2] = self.lathe_z(end[2]);
                    let kind = if traverse {
                        MotionKind::Traverse { end: sc(end, s) }
                    } else {
                        MotionKind::Feed {
                            end: sc(end, s),
                            feed_mm_per_min,
                        }
                    };
                    self.push_from(line, start, kind, end, Vec3::ZERO, rpm);
                    self.comp.emitted = end;
                }
                Queued::Arc {
                    line,
                    end1,
                    end2,
                    center1,
                    center2,
                    turn,
                    end3,
                    feed_mm_per_min,
                    rpm,
                    ..
                } => {
                    // ARC_FEED's first coordinate is Z in G18 (latheorigin_z)
                    let (e1, e2, c1, c2) = if self.plane == Plane::XZ {
                        (
                            self.lathe_z(end1),
                            self.lathe_x(end2),
                            self.lathe_z(center1),
                            self.lathe_x(center2),
                        )
                    } else {
                        (end1, end2, center1, center2)
                    };
                    let end = join(self.plane, e1, e2, end3);
                    let (_, _, n) = split(self.plane, start);
                    let center = join(self.plane, c1, c2, n);
                    let kind = MotionKind::Arc {
                        end: sc(end, s),
                        center: sc(center, s),
                        plane: self.plane,
                        turns: turn,
                        feed_mm_per_min,
                    };
                    self.push_from(line, start, kind, end, center, rpm);
                    self.comp.emitted = end;
                }
                Queued::Other { line, kind, rpm } => {
                    let m = Motion {
                        line,
                        start: sc(self.frame(start), s),
                        kind,
                        offset_mm: self.offset(),
                        path_mode: self.path,
                        inch: self.inch,
                        canon_end: start,
                        canon_center: Vec3::ZERO,
                        spindle_rpm: rpm,
                    };
                    self.keep(m);
                }
            }
        }
        self.canon_pos = self.comp.emitted;
        // the queue's storage, for the next moves
        let mut queue = queue;
        queue.clear();
        self.comp.queue = queue;
    }

    /// `latheorigin_x`.
    fn lathe_x(&self, x: f64) -> f64 {
        let (o, r) = (self.comp.orientation, self.comp.radius);
        if self.plane != Plane::XZ {
            return x;
        }
        match o {
            1 | 2 | 6 => x - r,
            3 | 4 | 8 => x + r,
            _ => x,
        }
    }

    /// `latheorigin_z`.
    fn lathe_z(&self, z: f64) -> f64 {
        let (o, r) = (self.comp.orientation, self.comp.radius);
        if self.plane != Plane::XZ {
            return z;
        }
        match o {
            2 | 3 | 7 => z - r,
            1 | 4 | 5 => z + r,
            _ => z,
        }
    }

    /// `move_endpoint_and_flush`: every held motion now ends at `(x, y)`; a
    /// straight one that would run backwards, or an arc that would sweep further
    /// than programmed, is a gouge. Then the queue goes.
    fn move_endpoint_and_flush(&mut self, x: f64, y: f64, off: u32) -> R<()> {
        if self.comp.queue.is_empty() {
            return Ok(());
        }
        let (endpoint, valid) = (self.comp.endpoint, self.comp.endpoint_valid);
        let slack = if self.inch { 0.001 } else { 0.0254 };
        let plane = self.plane;
        for q in &mut self.comp.queue {
            match q {
                Queued::Arc {
                    original_turns,
                    end1,
                    end2,
                    center1,
                    center2,
                    turn,
                    ..
                } => {
                    let r1 = (*end1 - *center1).hypot(*end2 - *center2);
                    let l1 = *original_turns;
                    let r2 = (x - *center1).hypot(y - *center2);
                    let l2 = find_turn(endpoint, (*center1, *center2), *turn, (x, y));
                    if (r1 - r2).abs() > 0.01 {
                        return bad(
                            off,
                            format!("BUG: cutter compensation has generated an invalid arc with mismatched radii r1 {r1:.6} r2 {r2:.6}"),
                        );
                    }
                    if l1 != 0.0 && valid && l2.abs() > l1.abs() + slack {
                        return bad(
                            off,
                            "Arc move in concave corner cannot be reached by the tool without gouging",
                        );
                    }
                    *end1 = x;
                    *end2 = y;
                }
                Queued::Straight {
                    traverse, dir, end, ..
                } => {
                    let (x2, y2) = (x - endpoint.0, y - endpoint.1);
                    let dot = dir.0 * x2 + dir.1 * y2;
                    if valid && dot < 0.0 {
                        return bad(
                            off,
                            if *traverse {
                                "Straight traverse in concave corner cannot be reached by the tool without gouging"
                            } else {
                                "Straight feed in concave corner cannot be reached by the tool without gouging"
                            },
                        );
                    }
                    let (a, b, _) = plane.axes();
                    end[a] = x;
                    end[b] = y;
                }
                Queued::Other { .. } => {}
            }
        }
        self.dequeue_canons();
        self.comp.set_endpoint(x, y);
        Ok(())
    }

    /// `convert_straight_comp1`: the entry move.
    #[allow(clippy::too_many_arguments)]
    fn straight_comp1(
        &mut self,
        line_no: u32,
        mode: i32,
        px: f64,
        py: f64,
        pz: f64,
        off: u32,
    ) -> R<()> {
        let radius = self.comp.radius;
        let side = self.comp.side.unwrap_or(Side::Left);
        let (cx, cy, _) = split(self.plane, self.pos);
        let distance = (px - cx).hypot(py - cy);
        if distance <= radius {
            return bad(
                off,
                "Length of cutter compensation entry move is not greater than the tool radius",
            );
        }
        let direction = (py - cy).atan2(px - cx);
        let alpha = if side == Side::Left {
            ld_add(direction, Ld::HALF_PI)
        } else {
            ld_sub(direction, Ld::HALF_PI)
        };
        let end_x = px + radius * alpha.cos();
        let end_y = py + radius * alpha.sin();
        self.comp.set_endpoint(cx, cy);
        self.comp_start_holding();
        self.enqueue_straight(line_no, mode, alpha.cos(), alpha.sin(), end_x, end_y, pz);
        self.comp.firstmove = false;
        self.pos = join(self.plane, end_x, end_y, pz);
        self.comp.program = join(self.plane, px, py, pz);
        Ok(())
    }

    /// The entry is held: the motions handed on from here start where the
    /// interpreter's point is (the queue is empty: G40 and M2 emptied it).
    fn comp_start_holding(&mut self) {
        self.comp.emitted = self.pos;
    }

    /// `convert_straight_comp2`: a straight move after the entry, with the corner
    /// it makes with the move held.
    #[allow(clippy::too_many_arguments, clippy::too_many_lines)]
    fn straight_comp2(
        &mut self,
        line_no: u32,
        mode: i32,
        px: f64,
        py: f64,
        pz: f64,
        off: u32,
    ) -> R<()> {
        let plane = self.plane;
        let (cx, cy, cz) = split(plane, self.pos);
        let (mut end_x, mut end_y) = (cx, cy);
        let (opx, opy, _) = split(plane, self.comp.program);
        if py == opy && px == opx {
            // no motion in the plane
            self.enqueue_straight(line_no, mode, px - opx, py - opy, cx, cy, pz);
        } else {
            let side = self.comp.side.unwrap_or(Side::Left);
            let radius = self.comp.radius;
            let mut theta = (cy - opy).atan2(cx - opx);
            let mut alpha = (py - opy).atan2(px - opx);
            let (beta, gamma);
            if side == Side::Left {
                if theta < alpha {
                    theta = ld_add(theta, Ld::TWO_PI);
                }
                beta = ld_sub(theta - alpha, Ld::HALF_PI);
                gamma = half_pi();
            } else {
                if alpha < theta {
                    alpha = ld_add(alpha, Ld::TWO_PI);
                }
                beta = ld_sub(alpha - theta, Ld::HALF_PI);
                gamma = -half_pi();
            }
            end_x = px + radius * (alpha + gamma).cos();
            end_y = py + radius * (alpha + gamma).sin();
            let mid_x = opx + radius * (alpha + gamma).cos();
            let mid_y = opy + radius * (alpha + gamma).sin();
            let front_arc = self.comp.front_arc();
            let small = Ld::from_f64(SMALL);
            let concave = if beta < -SMALL || ld_gt(beta, Ld::PI.add(small)) {
                true
            } else {
                // an "h" shape: over the round top, then beside the upright, the tool
                // kept above and outside
                ld_gt(beta, Ld::PI.sub(small))
                    && front_arc.is_some_and(|(.., turn)| {
                        (side == Side::Right && turn > 0) || (side == Side::Left && turn < 0)
                    })
            };
            if !concave && beta > SMALL {
                // an outside corner: an arc about the programmed corner
                self.move_endpoint_and_flush(cx, cy, off)?;
                if mode == G_1 {
                    let turn = if side == Side::Left { -1 } else { 1 };
                    self.enqueue_arc(line_no, 0.0, (mid_x, mid_y), (opx, opy), turn, cz);
                } else {
                    // no arc traverse: a straight one, most of the rapid parallel to
                    // the programmed one
                    self.enqueue_straight(line_no, mode, 0.0, 0.0, mid_x, mid_y, cz);
                }
                self.dequeue_canons();
                self.comp.set_endpoint(mid_x, mid_y);
            } else if concave {
                match front_arc {
                    None => {
                        // line to line: the held line ends where the two meet
                        let halfcorner = Ld::from_f64(beta).add(Ld::PI).half().to_f64();
                        if halfcorner == 0.0 {
                            return bad(
                                off,
                                "Zero degree inside corner is invalid for cutter compensation",
                            );
                        }
                        let retreat = radius / halfcorner.tan();
                        let mx = cx + retreat * (theta + gamma).cos();
                        let my = cy + retreat * (theta + gamma).sin();
                        self.move_endpoint_and_flush(mx, my, off)?;
                    }
                    Some((p_end1, p_end2, p_c1, p_c2, p_turn)) => {
                        // arc to line (the held arc is the compensated one)
                        let oldrad = (p_c2 - p_end2).hypot(p_c1 - p_end1);
                        let base_dir = (py - opy).atan2(px - opx);
                        let theta = if p_turn > 0 {
                            ld_add(base_dir, Ld::HALF_PI)
                        } else {
                            ld_sub(base_dir, Ld::HALF_PI)
                        };
                        let phi = (p_c2 - opy).atan2(p_c1 - opx);
                        let inside = tool_inside_arc(side, p_turn);
                        let oldrad_uncomp = if inside {
                            oldrad + radius
                        } else {
                            oldrad - radius
                        };
                        let alpha = theta - phi;
                        let d = oldrad_uncomp * alpha.cos();
                        let d2 = if inside { d - radius } else { d + radius };
                        let l = d2 / oldrad;
                        if !(-1.0..=1.0).contains(&l) {
                            return bad(
                                off,
                                "Arc to straight motion makes a corner the compensated tool can't fit in without gouging",
                            );
                        }
                        let angle = if inside == (p_turn > 0) {
                            ld_add(-l.acos() + theta, Ld::PI)
                        } else {
                            ld_add(l.acos() + theta, Ld::PI)
                        };
                        let mx = p_c1 + oldrad * angle.cos();
                        let my = p_c2 + oldrad * angle.sin();
                        self.move_endpoint_and_flush(mx, my, off)?;
                    }
                }
            } else {
                // no corner (collinear lines, or a tangent arc to a line)
                self.dequeue_canons();
                self.comp.set_endpoint(cx, cy);
            }
            self.enqueue_straight(line_no, mode, px - opx, py - opy, end_x, end_y, pz);
        }
        self.pos = join(plane, end_x, end_y, pz);
        self.comp.program = join(plane, px, py, pz);
        Ok(())
    }

    /// Whether the arc of this block is compensated (`convert_arc`'s test), and
    /// then the arc (`end` the programmed end, `offsets` the I/J/K of the plane's
    /// axes as given): `Ok(true)` when it was made here.
    pub(super) fn comp_arc(
        &mut self,
        line_no: u32,
        mode: i32,
        b: &Block,
        end: Vec3,
        offsets: (f64, f64),
    ) -> R<bool> {
        if !(self.comp.on() && self.comp.radius > 0.0) || self.plane == Plane::YZ {
            return Ok(false);
        }
        if self.rotation_deg != 0.0 && self.plane != Plane::XY {
            // as `Interp::arc` refuses them uncompensated
            return super::unsup(
                b.motion_off(),
                super::fmt_code('G', mode),
                "arcs in the XZ or YZ plane of a rotated coordinate system (G10 L2 R) are not supported",
            );
        }
        if self.comp.firstmove {
            self.arc_comp1(line_no, mode, b, end, offsets)?;
        } else {
            self.arc_comp2(line_no, mode, b, end, offsets)?;
        }
        Ok(true)
    }

    /// The tolerances of arcs in the program's unit: (radius, spiral).
    fn arc_tolerances(&self) -> (f64, f64) {
        if self.inch {
            (
                super::RADIUS_TOLERANCE_INCH,
                super::CENTER_ARC_RADIUS_TOLERANCE_INCH,
            )
        } else {
            (
                super::RADIUS_TOLERANCE_MM,
                super::CENTER_ARC_RADIUS_TOLERANCE_MM,
            )
        }
    }

    /// `arc_data_comp_ijk` / `arc_data_comp_r` (`comp`: the tool-inside check) or
    /// `arc_data_ijk` / `arc_data_r` from `cur` to `end` (plane coordinates).
    fn comp_arc_data(
        &self,
        mode: i32,
        b: &Block,
        cur: (f64, f64),
        end: (f64, f64),
        offsets: (f64, f64),
        comp: bool,
    ) -> R<(f64, f64, i32)> {
        let (rtol, stol) = self.arc_tolerances();
        let turns = if b.has(b'P') {
            super::round_to_int(b.p_number)
        } else {
            1
        };
        let side = self.comp.side.unwrap_or(Side::Left);
        let concave = (side == Side::Left && mode == G_3) || (side == Side::Right && mode == G_2);
        let tool_radius = self.comp.radius;
        let too_small = || {
            bad(
                b.motion_off(),
                "Tool radius not less than arc radius with comp",
            )
        };
        if let Some(r) = b.get(b'R') {
            if comp && r.abs() <= tool_radius && concave {
                return too_small();
            }
            super::arc_data_r(mode, cur, end, r, turns, rtol).or_else(|m| bad(b.off(b'R'), m))
        } else {
            let (a1, a2, _) = self.plane.axes();
            let names = [b"XYZ"[a1] as char, b"XYZ"[a2] as char];
            let (c1, c2, t) = super::arc_data_ijk(
                mode,
                cur,
                end,
                self.ijk_absolute,
                offsets,
                turns,
                rtol,
                stol,
                names,
            )
            .or_else(|m| bad(b.motion_off(), m))?;
            if comp && concave {
                let arc_radius = (c1 - cur.0).hypot(c2 - cur.1);
                if arc_radius <= tool_radius {
                    return too_small();
                }
            }
            Ok((c1, c2, t))
        }
    }

    /// `inverse_time_rate_arc`: the feed of an arc under G93.
    #[allow(clippy::too_many_arguments)]
    fn comp_inverse_time(
        &mut self,
        b: &Block,
        cur: (f64, f64, f64),
        center: (f64, f64),
        turn: i32,
        end: (f64, f64, f64),
    ) {
        if self.inverse_time {
            let length = super::find_arc_length(cur, center, turn, end);
            self.feed = (length * b.get(b'F').unwrap_or(0.0)).max(0.1);
        }
    }

    /// `convert_arc_comp1`: an arc as the entry move.
    fn arc_comp1(
        &mut self,
        line_no: u32,
        mode: i32,
        b: &Block,
        end: Vec3,
        offsets: (f64, f64),
    ) -> R<()> {
        let off = b.motion_off();
        let plane = self.plane;
        let side = self.comp.side.unwrap_or(Side::Left);
        let tool_radius = self.comp.radius;
        let (_, spiral_tol) = self.arc_tolerances();
        let (cx, cy, cz) = split(plane, self.pos);
        let (mut end_x, mut end_y, end_z) = split(plane, end);
        if (end_x - cx).hypot(end_y - cy) <= tool_radius {
            return bad(
                off,
                "Radius of cutter compensation entry arc is not greater than the tool radius",
            );
        }
        let (center_x, center_y, turn) =
            self.comp_arc_data(mode, b, (cx, cy), (end_x, end_y), offsets, true)?;
        self.comp_inverse_time(
            b,
            (cx, cy, cz),
            (center_x, center_y),
            turn,
            (end_x, end_y, end_z),
        );
        let gamma = if tool_inside_arc(side, turn) {
            (center_y - end_y).atan2(center_x - end_x)
        } else {
            (end_y - center_y).atan2(end_x - center_x)
        };
        self.comp.firstmove = false;
        self.comp.program = join(plane, end_x, end_y, end_z);
        end_x += tool_radius * gamma.cos();
        end_y += tool_radius * gamma.sin();
        // the new centre: on the line from the new end towards the programmed
        // centre, as far from the new end as from the start
        let b_len = (cy - end_y).hypot(cx - end_x) / 2.0;
        let ab_ang = (center_y - end_y).atan2(center_x - end_x);
        let a_ang = (cy - end_y).atan2(cx - end_x) - ab_ang;
        if a_ang.cos().abs() < TOLERANCE_EQUAL {
            return bad(off, "Tool radius not less than arc radius with comp");
        }
        let c_len = b_len / a_ang.cos();
        let center_x = end_x + c_len * ab_ang.cos();
        let center_y = end_y + c_len * ab_ang.sin();
        if ((center_x - end_x).hypot(center_y - end_y) - (center_x - cx).hypot(center_y - cy)).abs()
            > spiral_tol
        {
            return bad(off, "Bug in tool radius comp");
        }
        self.comp_start_holding();
        if self.comp.orientation != 0 && self.comp.orientation != 9 {
            // a lathe tool's origin moves first (else the arc is not an arc)
            self.enqueue_straight(line_no, G_1, 0.0, 0.0, cx, cy, cz);
            self.comp.set_endpoint(cx, cy);
        }
        let sweep = find_turn((cx, cy), (center_x, center_y), turn, (end_x, end_y));
        self.enqueue_arc(
            line_no,
            sweep,
            (end_x, end_y),
            (center_x, center_y),
            turn,
            end_z,
        );
        self.pos = join(plane, end_x, end_y, end_z);
        Ok(())
    }

    /// `convert_arc_comp2`: an arc after the entry, with the corner it makes with
    /// the move held.
    #[allow(clippy::too_many_lines)]
    fn arc_comp2(
        &mut self,
        line_no: u32,
        mode: i32,
        b: &Block,
        end: Vec3,
        offsets: (f64, f64),
    ) -> R<()> {
        let off = b.motion_off();
        let plane = self.plane;
        let (opx, opy, opz) = split(plane, self.comp.program);
        let (cx, cy, cz) = split(plane, self.pos);
        let (end_x, end_y, end_z) = split(plane, end);
        let (centerx, centery, turn) =
            self.comp_arc_data(mode, b, (opx, opy), (end_x, end_y), offsets, false)?;
        self.comp_inverse_time(
            b,
            (opx, opy, opz),
            (centerx, centery),
            turn,
            (end_x, end_y, end_z),
        );
        let side = self.comp.side.unwrap_or(Side::Left);
        let tool_radius = self.comp.radius;
        let arc_radius = (centerx - end_x).hypot(centery - end_y);
        let mut theta = (cy - opy).atan2(cx - opx);
        theta = if side == Side::Left {
            ld_sub(theta, Ld::HALF_PI)
        } else {
            ld_add(theta, Ld::HALF_PI)
        };
        let mut delta = (centery - opy).atan2(centerx - opx);
        let alpha = if mode == G_3 {
            ld_sub(delta, Ld::HALF_PI)
        } else {
            ld_add(delta, Ld::HALF_PI)
        };
        let mut beta = if side == Side::Left {
            theta - alpha
        } else {
            alpha - theta
        };
        // beta from -90° to +270°
        beta = if ld_gt(beta, Ld::one_and_half_pi()) {
            ld_sub(beta, Ld::TWO_PI)
        } else if ld_lt(beta, Ld::HALF_PI.neg()) {
            ld_add(beta, Ld::TWO_PI)
        } else {
            beta
        };
        let gamma;
        if (side == Side::Left && mode == G_3) || (side == Side::Right && mode == G_2) {
            // the tool inside the arc
            gamma = (centery - end_y).atan2(centerx - end_x);
            if arc_radius <= tool_radius {
                return bad(off, "Tool radius not less than arc radius with comp");
            }
        } else {
            gamma = (end_y - centery).atan2(end_x - centerx);
            delta = ld_add(delta, Ld::PI);
        }
        let new_end_x = end_x + tool_radius * gamma.cos();
        let new_end_y = end_y + tool_radius * gamma.sin();
        let inside = tool_inside_arc(side, turn);
        let sweep = find_turn((opx, opy), (centerx, centery), turn, (end_x, end_y));
        let small = Ld::from_f64(SMALL);
        let beta_ld = Ld::from_f64(beta);
        let off_pi = beta_ld.sub(Ld::PI);
        let near_pi = off_pi.lt(small) && small.neg().lt(off_pi);
        if beta < -SMALL || ld_gt(beta, Ld::PI.add(small)) || (near_pi && !inside) {
            // concave (or the convex corner atop an "m" or "h" shape)
            match self.comp.front_arc() {
                None => {
                    // line to arc
                    // sinl of the long double difference, to first order about
                    // the double it rounds to
                    let arg = beta_ld.sub(Ld::HALF_PI);
                    let (hi, lo) = (arg.to_f64(), arg.sub(Ld::from_f64(arg.to_f64())).to_f64());
                    let cy2 = arc_radius * (hi.sin() + hi.cos() * lo);
                    let (dist_from_center, angle_from_center);
                    if inside {
                        dist_from_center = arc_radius - tool_radius;
                        let toward_nominal = cy2 + tool_radius;
                        let l = toward_nominal / dist_from_center;
                        if !(-1.0..=1.0).contains(&l) {
                            return bad(
                                off,
                                "Arc move in concave corner cannot be reached by the tool without gouging",
                            );
                        }
                        angle_from_center = if turn > 0 {
                            theta + l.asin()
                        } else {
                            theta - l.asin()
                        };
                    } else {
                        dist_from_center = arc_radius + tool_radius;
                        let toward_nominal = cy2 - tool_radius;
                        let l = toward_nominal / dist_from_center;
                        if !(-1.0..=1.0).contains(&l) {
                            return bad(
                                off,
                                "Arc move in concave corner cannot be reached by the tool without gouging",
                            );
                        }
                        let theta_pi = Ld::from_f64(theta).add(Ld::PI);
                        angle_from_center = if turn > 0 {
                            theta_pi.sub(Ld::from_f64(l.asin())).to_f64()
                        } else {
                            theta_pi.add(Ld::from_f64(l.asin())).to_f64()
                        };
                    }
                    let midx = centerx + dist_from_center * angle_from_center.cos();
                    let midy = centery + dist_from_center * angle_from_center.sin();
                    self.move_endpoint_and_flush(midx, midy, off)?;
                }
                Some((p_end1, p_end2, p_c1, p_c2, p_turn)) => {
                    // arc to arc
                    let oldrad = (p_c2 - p_end2).hypot(p_c1 - p_end1);
                    let newrad = if inside {
                        arc_radius - tool_radius
                    } else {
                        arc_radius + tool_radius
                    };
                    let arc_cc = (p_c2 - centery).hypot(p_c1 - centerx);
                    if oldrad == 0.0 || arc_cc == 0.0 {
                        return bad(
                            off,
                            "Arc to arc motion is invalid because the arcs have the same center",
                        );
                    }
                    let a = (oldrad * oldrad + arc_cc * arc_cc - newrad * newrad)
                        / (2.0 * oldrad * arc_cc);
                    if !(-1.0..=1.0).contains(&a) {
                        return bad(
                            off,
                            "Arc to arc motion makes a corner the compensated tool can't fit in without gouging",
                        );
                    }
                    let pullback = a.acos();
                    let cc_dir = (centery - p_c2).atan2(centerx - p_c1);
                    let dir = if tool_inside_arc(side, p_turn) == (turn > 0) {
                        cc_dir + pullback
                    } else {
                        cc_dir - pullback
                    };
                    let midx = p_c1 + oldrad * dir.cos();
                    let midy = p_c2 + oldrad * dir.sin();
                    self.move_endpoint_and_flush(midx, midy, off)?;
                }
            }
            self.enqueue_arc(
                line_no,
                sweep,
                (new_end_x, new_end_y),
                (centerx, centery),
                turn,
                end_z,
            );
        } else if beta > SMALL {
            // convex: an arc about the programmed corner, then the arc
            let midx = opx + tool_radius * delta.cos();
            let midy = opy + tool_radius * delta.sin();
            self.dequeue_canons();
            let corner_turn = if side == Side::Left { -1 } else { 1 };
            self.enqueue_arc(line_no, 0.0, (midx, midy), (opx, opy), corner_turn, cz);
            self.dequeue_canons();
            self.comp.set_endpoint(midx, midy);
            self.enqueue_arc(
                line_no,
                sweep,
                (new_end_x, new_end_y),
                (centerx, centery),
                turn,
                end_z,
            );
        } else {
            // convex, tangent: the arc alone
            self.dequeue_canons();
            self.comp.set_endpoint(cx, cy);
            self.enqueue_arc(
                line_no,
                sweep,
                (new_end_x, new_end_y),
                (centerx, centery),
                turn,
                end_z,
            );
        }
        self.comp.program = join(plane, end_x, end_y, end_z);
        self.pos = join(plane, new_end_x, new_end_y, end_z);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inside_arc_as_linuxcnc() {
        assert!(tool_inside_arc(Side::Left, 1));
        assert!(tool_inside_arc(Side::Right, -1));
        assert!(!tool_inside_arc(Side::Left, -1));
        assert!(!tool_inside_arc(Side::Right, 2));
    }

    #[test]
    fn plane_coordinates_round_trip() {
        for plane in [Plane::XY, Plane::XZ] {
            let p = Vec3([1.0, 2.0, 3.0]);
            let (x, y, z) = split(plane, p);
            assert_eq!(join(plane, x, y, z), p);
        }
        // G18: the first coordinate is Z, the second X
        assert_eq!(split(Plane::XZ, Vec3([1.0, 2.0, 3.0])), (3.0, 1.0, 2.0));
    }
}
