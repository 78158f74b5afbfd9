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
            MotionKind::Dwell { .. } | MotionKind::Pause { .. } | MotionKind::Sync => (None, None),
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
            | MotionKind::Arc { end, .. } => Some(end),
            MotionKind::Dwell { .. } | MotionKind::Pause { .. } | MotionKind::Sync => None,
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
}
