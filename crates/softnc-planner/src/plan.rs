//! Planning entry point: program → checked segments → [`Plan`] with its figures.

use crate::build::{motion_primitive, Limits, Path, PathBuilder, Segment};
use crate::interp::Interpolator;
use softnc_core::geom::rem_tau;
use softnc_core::{FeedProfile, MotionProfile, Primitive, Vec3};
use softnc_gcode::{GcodeError, Motion, MotionKind, Program};

/// Options for one planning run.
#[derive(Debug, Clone, Default)]
pub struct PlanOptions {
    /// Do not refuse motions outside the soft limits (offline analysis only).
    pub ignore_soft_limits: bool,
    /// Where the machine is when the job starts (machine coordinates, mm): the
    /// program is read and planned from there. `None`: the origin.
    pub start_mm: Option<[f64; 3]>,
    /// Elements the window of a streamed plan holds
    /// ([`stream_program`](crate::stream::stream_program)); 0: the default,
    /// [`DEFAULT_STREAM_WINDOW_SEGMENTS`](crate::stream::DEFAULT_STREAM_WINDOW_SEGMENTS).
    /// Rounded up to a power of two of at least the lookahead's reach.
    pub stream_window_segments: usize,
    /// The optional-stop switch: M1 pauses only while it is on
    /// ([`softnc_gcode::ReadOptions::optional_stop`]).
    pub optional_stop: bool,
    /// The block-delete switch: lines starting with `/` are not read
    /// ([`softnc_gcode::ReadOptions::block_delete`]).
    pub block_delete: bool,
    /// Run from this line ([`softnc_gcode::ReadOptions::from_line`]): the motions
    /// before it are left out and a safe approach from `start_mm` leads to it.
    pub from_line: Option<u32>,
    /// Single block from the start: every block ends in an exact stop where the
    /// path waits for [`StreamInterpolator::resume`](crate::StreamInterpolator::resume)
    /// (no blending or G64 Q merging across block ends).
    pub single_block: bool,
    /// M0 (and M1 with `optional_stop`) wait for
    /// [`StreamInterpolator::resume`](crate::StreamInterpolator::resume), as a
    /// machine's program stop does. `false` (default): the path comes to rest there
    /// exactly the same way and goes on with the next cycle, for callers that never
    /// resume (offline simulation, figures, tests); the daemon sets it.
    pub wait_at_program_stops: bool,
    /// Machine stops (a machine operation the path comes to rest for: spindle,
    /// coolant, M6, messages, immediate I/O, M66, M19, user M codes) wait for
    /// [`StreamInterpolator::release_machine_stop`](crate::StreamInterpolator::release_machine_stop),
    /// which the machine sequencer ([`crate::machine_sequencer`]) decides. `false`
    /// (default): the path comes to rest there the same way and goes on at once.
    pub wait_at_machine_stops: bool,
    /// The user M-code folder ([`softnc_gcode::ReadOptions::user_m_codes`]).
    pub user_m_codes: Option<std::path::PathBuf>,
    /// M66's #5399 ([`softnc_gcode::ReadOptions::m66_results`]).
    pub m66_results: softnc_gcode::M66Results,
    /// The machine's parameters at the start (offsets, G92, active system: the
    /// parameter file, or what the last job or MDI left, LinuxCNC's persistent
    /// parameters; 5220 selects the coordinate system); `None`: the profile's work
    /// offsets.
    pub params: Option<softnc_gcode::Params>,
    /// Folders searched for subroutine files (LinuxCNC's `SUBROUTINE_PATH`).
    pub subroutine_path: Vec<std::path::PathBuf>,
    /// The modal state the machine's last MDI command or job left, as G-code run
    /// before the program ([`softnc_gcode::ReadOptions::preamble`]).
    pub preamble: Option<String>,
    /// The file the preamble was read from ([`softnc_gcode::ReadOptions::preamble_file`]).
    pub preamble_file: Option<String>,
    /// How subroutine files are taken in ([`softnc_gcode::ReadOptions::subroutines`]).
    pub subroutines: softnc_gcode::SubroutineFiles,
    /// `(LOGOPEN,…)` taken ([`softnc_gcode::ReadOptions::log_files`]).
    pub log_files: bool,
}

impl PlanOptions {
    /// How the G-code reader reads a program planned with these options (the
    /// motions the plan is built from).
    pub fn read_options(&self) -> softnc_gcode::ReadOptions {
        softnc_gcode::ReadOptions {
            start_mm: self.start_mm.map(softnc_core::Vec3),
            optional_stop: self.optional_stop,
            block_delete: self.block_delete,
            from_line: self.from_line,
            params: self.params.clone(),
            subroutine_path: self.subroutine_path.clone(),
            preamble: self.preamble.clone(),
            preamble_file: self.preamble_file.clone(),
            subroutines: self.subroutines.clone(),
            user_m_codes: self.user_m_codes.clone(),
            m66_results: self.m66_results,
            log_files: self.log_files,
            ..Default::default()
        }
    }
}

/// Why a program cannot be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A motion leaves the machine's travel.
    #[error("{file}:{line}:1: soft limit: {axis} would reach {pos_mm:.4} mm, outside [{min_mm}, {max_mm}] mm")]
    SoftLimit {
        /// File.
        file: String,
        /// Source line of the motion.
        line: u32,
        /// Axis letter.
        axis: char,
        /// Position reached (machine coordinates).
        pos_mm: f64,
        /// Lower soft limit.
        min_mm: f64,
        /// Upper soft limit.
        max_mm: f64,
    },
    /// A probe move (G38.x): the machine does not run probe moves yet, and where
    /// one ends only the machine knows.
    #[error("{file}:{line}:1: {code}: a probe move is not planned (the machine does not run probe moves yet)")]
    ProbeMove {
        /// File.
        file: String,
        /// Source line of the motion.
        line: u32,
        /// `G38.2` … `G38.5`.
        code: &'static str,
    },
}

/// Figures of a planned program.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlanStats {
    /// Path length of all moves (mm).
    pub path_length_mm: f64,
    /// Planned run time at 100 % override (s).
    pub duration_s: f64,
    /// Number of samples at the interpolation cycle.
    pub samples: u64,
    /// Highest programmed feed of a feed move (mm/min).
    pub max_feed_mm_min: f64,
    /// Number of moves (traverses, feeds and arcs; dwells are not moves).
    pub moves: usize,
    /// Bounding box of the path, machine coordinates (mm).
    pub bounds_min_mm: Vec3,
    /// Bounding box of the path, machine coordinates (mm).
    pub bounds_max_mm: Vec3,
}

/// A planned program: the path elements with their limits, ready to interpolate.
#[derive(Debug, Clone)]
pub struct Plan {
    /// Where the machine stands at the start ([`PlanOptions::start_mm`]): the
    /// samples of a path without an element hold there.
    start_mm: Option<Vec3>,
    /// Single block from the start ([`PlanOptions::single_block`]).
    single_block: bool,
    /// M0/M1 wait ([`PlanOptions::wait_at_program_stops`]).
    wait_at_program_stops: bool,
    /// Machine stops wait ([`PlanOptions::wait_at_machine_stops`]).
    wait_at_machine_stops: bool,
    path: Path,
    n_motions: usize,
    /// (first motion, rpm) wherever the spindle speed changes (0 = stopped).
    spindle_changes: Vec<(u32, f64)>,
    lim: Limits,
    brake_dist_mm: f64,
    max_override: f64,
    stats: PlanStats,
}

/// Plan a program for a machine: soft limits first, then blending and limits.
pub fn plan(
    program: &Program,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<Plan, PlanError> {
    let mut p = Planner::new(profile, options, &program.file, program.motions.len());
    for m in &program.motions {
        p.push(m)?;
    }
    Ok(p.finish())
}

/// Why a program text cannot be planned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReadPlanError {
    /// The G-code reader refused the program.
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// The planner refused it.
    #[error(transparent)]
    Plan(#[from] PlanError),
}

/// Room to reserve for the path of a program text: about one motion per 24 bytes
/// (a short `G1 X… Y…` line); a longer path only grows the storage.
fn motions_hint(text: &str) -> usize {
    text.len() / 24
}

/// Motions per chunk between the reader and the planner in [`read_and_plan`]: small
/// enough to stay in cache, large enough that handing a chunk over costs nothing.
pub const READ_CHUNK_MOTIONS: usize = 1024;

/// Read and plan a program text in one pass: each chunk of motions is planned as soon
/// as it is read, so the motions are never all held at once. Gives the same plan as
/// [`read_program`](softnc_gcode::read_program) then [`plan`], and the same first
/// error (a G-code error anywhere before a soft-limit violation). The returned
/// [`Program`] has no motions (blocks and warnings only).
pub fn read_and_plan(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, Plan), ReadPlanError> {
    let mut planner = Planner::new(profile, options, file, motions_hint(text));
    let mut refused: Option<PlanError> = None;
    let program = softnc_gcode::read_program_chunked_with(
        text,
        file,
        profile,
        &options.read_options(),
        READ_CHUNK_MOTIONS,
        &mut |chunk: &mut Vec<Motion>| {
            if refused.is_none() {
                for m in chunk.iter() {
                    if let Err(e) = planner.push(m) {
                        refused = Some(e);
                        break;
                    }
                }
            }
        },
    )?;
    match refused {
        Some(e) => Err(e.into()),
        None => Ok((program, planner.finish())),
    }
}

/// [`read_and_plan`] on two threads: the calling thread reads and works out each
/// motion's programmed primitive, a second one checks them, builds the path from the
/// chunks as they come and plans it (the same plan and errors).
pub fn read_and_plan_parallel(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, Plan), ReadPlanError> {
    use std::sync::mpsc::{channel, sync_channel};
    type Chunk = (Vec<Motion>, Vec<Option<Primitive>>);
    let (to_planner, chunks) = sync_channel::<Chunk>(8);
    let (recycle, recycled) = channel::<Chunk>();
    std::thread::scope(|scope| {
        let planner = scope.spawn(move || {
            let mut planner = Planner::new(profile, options, file, motions_hint(text));
            let mut refused: Option<PlanError> = None;
            for (mut motions, mut prims) in chunks {
                if refused.is_none() {
                    for (m, prim) in motions.iter().zip(&prims) {
                        if let Err(e) = planner.push_primitive(m, *prim) {
                            refused = Some(e);
                            break;
                        }
                    }
                }
                motions.clear();
                prims.clear();
                let _ = recycle.send((motions, prims)); // the reader may be gone
            }
            match refused {
                Some(e) => Err(e),
                None => Ok(planner.finish()),
            }
        });
        let read = softnc_gcode::read_program_chunked_with(
            text,
            file,
            profile,
            &options.read_options(),
            READ_CHUNK_MOTIONS,
            &mut |chunk: &mut Vec<Motion>| {
                let (fresh, mut prims) = recycled.try_recv().unwrap_or_else(|_| {
                    (
                        Vec::with_capacity(READ_CHUNK_MOTIONS),
                        Vec::with_capacity(READ_CHUNK_MOTIONS),
                    )
                });
                prims.extend(chunk.iter().map(motion_primitive));
                // a planner that stopped early (it cannot) only loses the chunk
                let _ = to_planner.send((std::mem::replace(chunk, fresh), prims));
            },
        );
        drop(to_planner);
        let planned = planner
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        let program = read?;
        Ok((program, planned?))
    })
}

/// Checks motions one at a time and gathers the plan's figures: soft limits, the
/// bounding box, the highest feed, the spindle speed changes.
pub(crate) struct Checker<'a> {
    profile: &'a MotionProfile,
    options: &'a PlanOptions,
    file: &'a str,
    bmin: Vec3,
    bmax: Vec3,
    max_feed: f64,
    pub(crate) n_motions: usize,
    n_moves: usize,
    pub(crate) spindle_changes: Vec<(u32, f64)>,
    /// The spindle speed of the last of `spindle_changes` (0 before the first).
    spindle_rpm: f64,
}

impl<'a> Checker<'a> {
    pub(crate) fn new(profile: &'a MotionProfile, options: &'a PlanOptions, file: &'a str) -> Self {
        Checker {
            profile,
            options,
            file,
            bmin: Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            bmax: Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
            max_feed: 0.0,
            n_motions: 0,
            n_moves: 0,
            spindle_changes: Vec::new(),
            spindle_rpm: 0.0,
        }
    }

    /// Check a motion whose programmed primitive in machine coordinates is `prim`
    /// (None for dwells): the soft limit it breaks, if any.
    ///
    /// Inline, with the common case in a few comparisons: a move inside the box of
    /// the moves so far (which is inside the travel) neither grows the box nor can
    /// break a soft limit, and the spindle speed rarely changes; the rest is in
    /// [`Checker::grow_box`] and [`Checker::spindle_change`], out of line.
    #[inline]
    pub(crate) fn check(&mut self, m: &Motion, prim: &Option<Primitive>) -> Result<(), PlanError> {
        if let MotionKind::Probe { probe, .. } = m.kind {
            return Err(PlanError::ProbeMove {
                file: self.file.to_string(),
                line: m.line,
                code: probe.name(),
            });
        }
        if let Some(p) = prim {
            self.n_moves += 1;
            if let MotionKind::Feed {
                feed_mm_per_min, ..
            }
            | MotionKind::Arc {
                feed_mm_per_min, ..
            } = m.kind
            {
                // `max_feed.max(feed)`: a NaN feed leaves it, as `f64::max` does
                if feed_mm_per_min > self.max_feed {
                    self.max_feed = feed_mm_per_min;
                }
            }
            // a primitive inside the box so far neither grows it nor leaves the travel
            // (the box is inside it)
            if !within(p, self.bmin, self.bmax) {
                self.grow_box(m, p)?;
            }
        }
        if m.spindle_rpm != self.spindle_rpm {
            self.spindle_change(m.spindle_rpm);
        }
        self.n_motions += 1;
        Ok(())
    }

    /// The box grown by primitive `p` of motion `m`, which is not inside it: the soft
    /// limit it breaks, if any.
    fn grow_box(&mut self, m: &Motion, p: &Primitive) -> Result<(), PlanError> {
        let (lo, hi) = bounding_box(p);
        if !self.options.ignore_soft_limits {
            self.check_travel(m, lo, hi)?;
        }
        self.bmin = self.bmin.min(lo);
        self.bmax = self.bmax.max(hi);
        Ok(())
    }

    /// The spindle speed changes to `rpm` at the motion being checked.
    #[cold]
    fn spindle_change(&mut self, rpm: f64) {
        self.spindle_changes.push((self.n_motions as u32, rpm));
        self.spindle_rpm = rpm;
    }

    /// The soft limit that a motion reaching from `lo` to `hi` breaks, if any.
    fn check_travel(&self, m: &Motion, lo: Vec3, hi: Vec3) -> Result<(), PlanError> {
        for (i, axis) in self.profile.axes.iter().enumerate() {
            for v in [lo[i], hi[i]] {
                if v < axis.min_mm - 1e-9 || v > axis.max_mm + 1e-9 {
                    return Err(PlanError::SoftLimit {
                        file: self.file.to_string(),
                        line: m.line,
                        axis: axis.name.chars().next().unwrap_or('?'),
                        pos_mm: v,
                        min_mm: axis.min_mm,
                        max_mm: axis.max_mm,
                    });
                }
            }
        }
        Ok(())
    }

    /// Where the machine stands when the program starts, if the options say
    /// ([`PlanOptions::start_mm`]): where a path without an element (nothing moves)
    /// holds.
    pub(crate) fn start_mm(&self) -> Option<Vec3> {
        self.options.start_mm.map(Vec3)
    }

    /// The plan of the checked motions, whose path is `path`.
    fn finish(self, lim: Limits, path: Path) -> Plan {
        let path_length_mm = path.segs.last().map_or(0.0, |s| s.s0 + s.len);
        let (stats, brake_dist_mm) =
            self.figures(&lim, path_length_mm, planned_duration(&path.segs, &lim));
        Plan {
            start_mm: self.start_mm(),
            single_block: self.options.single_block,
            wait_at_program_stops: self.options.wait_at_program_stops,
            wait_at_machine_stops: self.options.wait_at_machine_stops,
            path,
            n_motions: self.n_motions,
            spindle_changes: self.spindle_changes,
            lim,
            brake_dist_mm,
            max_override: self.profile.planner.max_feed_override,
            stats,
        }
    }

    /// The figures of the checked motions, whose path is `path_length_mm` long and
    /// whose [`planned_duration`] is `timed`; and the lookahead's braking distance.
    pub(crate) fn figures(
        &self,
        lim: &Limits,
        path_length_mm: f64,
        timed: (f64, f64, f64),
    ) -> (PlanStats, f64) {
        let (mut bmin, mut bmax) = (self.bmin, self.bmax);
        if !bmin[0].is_finite() {
            bmin = Vec3::ZERO;
            bmax = Vec3::ZERO;
        }
        let (duration_s, v_top, a_min) = timed;
        let brake_dist_mm = if a_min.is_finite() && a_min > 0.0 {
            v_top * v_top / (2.0 * a_min)
        } else {
            0.0
        };
        let samples = (duration_s / lim.cycle_s - 1e-9).ceil().max(0.0) as u64 + 1;
        let stats = PlanStats {
            path_length_mm,
            duration_s,
            samples,
            max_feed_mm_min: self.max_feed,
            moves: self.n_moves,
            bounds_min_mm: bmin,
            bounds_max_mm: bmax,
        };
        (stats, brake_dist_mm)
    }
}

/// Plans motions one at a time: checks, figures and the path.
struct Planner<'a> {
    checker: Checker<'a>,
    lim: Limits,
    builder: PathBuilder,
}

impl<'a> Planner<'a> {
    fn new(
        profile: &'a MotionProfile,
        options: &'a PlanOptions,
        file: &'a str,
        motions_hint: usize,
    ) -> Self {
        let lim = Limits::from_profile(profile);
        let mut builder = PathBuilder::new(&lim, motions_hint);
        builder.set_single_block(options.single_block);
        Planner {
            checker: Checker::new(profile, options, file),
            lim,
            builder,
        }
    }

    fn push(&mut self, m: &Motion) -> Result<(), PlanError> {
        self.push_primitive(m, motion_primitive(m))
    }

    /// [`Planner::push`] with the motion's programmed primitive already worked out.
    fn push_primitive(&mut self, m: &Motion, prim: Option<Primitive>) -> Result<(), PlanError> {
        let index = self.checker.n_motions;
        self.checker.check(m, &prim)?;
        self.builder.push(index, m, prim);
        Ok(())
    }

    fn finish(self) -> Plan {
        let path = self.builder.finish();
        self.checker.finish(self.lim, path)
    }
}

impl Plan {
    /// Figures of the plan.
    pub fn stats(&self) -> PlanStats {
        self.stats.clone()
    }
    /// The programmed path of motion `index` in machine coordinates (None for dwells).
    pub fn motion_primitive(&self, index: usize) -> Option<Primitive> {
        if index >= self.n_motions {
            return None;
        }
        self.path.motion_primitive(index)
    }
    /// Number of program motions (dwells included).
    pub fn motions(&self) -> usize {
        self.n_motions
    }
    /// The spindle speed changes of the program: (first motion, rpm), in order; the
    /// spindle is stopped (0 rpm) before the first.
    pub fn spindle_changes(&self) -> &[(u32, f64)] {
        &self.spindle_changes
    }
    /// Number of path elements (programmed pieces and blends).
    pub fn elements(&self) -> usize {
        self.path.segs.len()
    }
    /// The interpolation cycle T (s).
    pub fn cycle_s(&self) -> f64 {
        self.lim.cycle_s
    }
    /// A fresh sample stream from the start of the program. Everything it needs is
    /// allocated here; pulling samples allocates nothing.
    pub fn interpolator(&self) -> Interpolator<'_> {
        let mut it = Interpolator::new(
            &self.path.segs,
            &self.path.geoms,
            self.lim,
            self.brake_dist_mm,
            self.max_override,
            self.start_mm,
        );
        it.set_single_block(self.single_block);
        it.core_mut()
            .set_wait_at_program_stops(self.wait_at_program_stops);
        it.core_mut()
            .set_wait_at_machine_stops(self.wait_at_machine_stops);
        it
    }
}

/// Planned run time at 100 % override: forward and backward passes over the whole
/// path, then each element's time-optimal profile, plus dwells and S-curve settling.
/// Also the highest finite speed cap and the lowest acceleration of the elements.
fn planned_duration(segs: &[Segment], lim: &Limits) -> (f64, f64, f64) {
    let n = segs.len();
    if n == 0 {
        return (0.0, 0.0, f64::INFINITY);
    }
    // backward: highest speed at the end of each element
    let mut vend = vec![0.0f64; n];
    let mut next_start = 0.0f64;
    let (mut v_top, mut a_min) = (0.0f64, f64::INFINITY);
    for k in (0..n).rev() {
        let s = &segs[k];
        if s.vel_cap.is_finite() {
            v_top = v_top.max(s.vel_cap);
        }
        a_min = a_min.min(s.acc);
        (vend[k], next_start) = backward_step(s, next_start);
    }
    // forward
    let mut fwd = ForwardTime::new(lim);
    for (k, s) in segs.iter().enumerate() {
        fwd.step(s, vend[k]);
    }
    (fwd.t, v_top, a_min)
}

/// The element's cap: the hard one and the feed at 100 %.
fn cap(s: &Segment) -> f64 {
    min_num(s.vel_cap, s.feed_mm_per_s) // (the feed is never NaN)
}

/// `a.min(b)` for a `b` that is not NaN, in one comparison (`f64::min` also tests
/// for NaN on both sides): a NaN `a` gives `b`, as `f64::min` does. Equal operands
/// give `b`, the same value (the two could differ only as +0 and −0, and no speed,
/// length or acceleration of the duration passes is −0). The operand that may be
/// NaN (a root of a product with an infinite acceleration) goes first.
fn min_num(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a.max(b)` for a `b` that is not NaN, in one comparison, as [`min_num`].
fn max_num(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// Whether `v`, which is not −∞, is finite: `v.is_finite()` in one comparison
/// (a NaN compares false, as `is_finite` gives).
fn finite_not_neg_inf(v: f64) -> bool {
    v < f64::INFINITY
}

/// One step of the backward pass of [`planned_duration`]: the highest end speed of
/// element `s` given the highest start speed `next_start` of the one after it, and
/// its own highest start speed.
///
/// Where the element's own end limit binds (`next_start` ≥ min(v_end_hard, cap), the
/// common case) the result does not depend on `next_start`: min(min(a, n), c) is
/// then min(a, c), the same value. Taking that branch keeps the square root out of
/// the chain of dependent steps, so successive elements' roots overlap.
fn backward_step(s: &Segment, next_start: f64) -> (f64, f64) {
    let own = s.v_end_hard.min(cap(s));
    if next_start >= own {
        (own, start_speed(s, own))
    } else {
        backward_step_bound(s, next_start)
    }
}

/// [`backward_step`] where the next element's start speed binds.
#[cold]
fn backward_step_bound(s: &Segment, next_start: f64) -> (f64, f64) {
    let vend = s.v_end_hard.min(next_start).min(cap(s));
    (vend, start_speed(s, vend))
}

/// The highest start speed of element `s` that can still end at `vend`.
fn start_speed(s: &Segment, vend: f64) -> f64 {
    cap(s).min((vend * vend + 2.0 * s.acc * s.len).sqrt())
}

/// Whether element `s`'s highest start speed from a stop at its end,
/// [`start_speed`]`(s, 0)` = min(cap, √(2·acc·len)), is surely at least `v` (≥ 0):
/// where 2·acc·len ≥ fl(v²)·(1 + 4ε) > v² the correctly rounded root is ≥ v (the
/// bound of [`ForwardTime::step`]); false may be a false negative, never a false
/// positive.
fn starts_at_least(s: &Segment, v: f64) -> bool {
    v <= 0.0 || (cap(s) >= v && 2.0 * s.acc * s.len >= (v * v) * (1.0 + 4.0 * f64::EPSILON))
}

/// The forward pass of [`planned_duration`]: time along the elements in order.
#[derive(Clone, Copy)]
struct ForwardTime {
    t: f64,
    v0: f64,
    settle: f64,
}

impl ForwardTime {
    fn new(lim: &Limits) -> ForwardTime {
        let settle = match lim.profile {
            FeedProfile::SCurve => lim.scurve_window_s,
            FeedProfile::Trapezoidal => 0.0,
        };
        ForwardTime {
            t: 0.0,
            v0: 0.0,
            settle,
        }
    }

    /// Element `s`, whose end speed the backward pass capped at `vend`.
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn step(&mut self, s: &Segment, vend: f64) {
        let vend_sq_up = (vend * vend) * (1.0 + 4.0 * f64::EPSILON);
        self.step_pre(s, vend, vend_sq_up, cap(s), 2.0 * s.acc * s.len);
    }

    /// [`ForwardTime::step`] with `vend_sq_up` = fl(vend²)·(1 + 4ε), the element's
    /// [`cap`] `c` and `two_al` = 2·acc·len worked out already (by
    /// [`DurationPass::push_slice`], which needs them for [`starts_at_least`]
    /// first): the same arithmetic, so the same bits.
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn step_pre(&mut self, s: &Segment, vend: f64, vend_sq_up: f64, c: f64, two_al: f64) {
        let v0 = self.v0;
        // v1 = min(vend, √x); where x ≥ vend² surely (x ≥ fl(vend²)·(1 + 2⁻⁵⁰) > vend²,
        // and a correctly rounded root of x ≥ y² is ≥ y), v1 is vend without the root:
        // the next element's v0 then does not wait for it. (`vend` ≥ 0, so finite is
        // below ∞.)
        let x = v0 * v0 + two_al;
        let v1 = if finite_not_neg_inf(vend) && x >= vend_sq_up {
            vend
        } else {
            min_num(x.sqrt(), vend)
        };
        if s.len > 0.0 {
            let vp = min_num(((v0 * v0 + v1 * v1) / 2.0 + s.acc * s.len).sqrt(), c);
            if vp == v0 && vp == v1 && vp > 0.0 && finite_not_neg_inf(vp) && s.acc > 0.0 {
                // cruising through: the terms below are exactly 0 (x − x = 0, 0/a =
                // 0, 0 + 0 + c = c) but for len/vp; four divisions spared
                self.t += s.len / vp;
                if s.v_end_hard == 0.0 {
                    self.t += s.dwell_s + self.settle;
                }
                self.v0 = v1;
                return;
            }
            let d_acc = (vp * vp - v0 * v0) / (2.0 * s.acc);
            let d_dec = (vp * vp - v1 * v1) / (2.0 * s.acc);
            let cruise = max_num(s.len - d_acc - d_dec, 0.0);
            self.t += max_num(vp - v0, 0.0) / s.acc
                + max_num(vp - v1, 0.0) / s.acc
                + if vp > 0.0 { cruise / vp } else { 0.0 };
        }
        if s.v_end_hard == 0.0 {
            self.t += s.dwell_s + self.settle;
        }
        self.v0 = v1;
    }
}

/// [`planned_duration`] on a stream of elements, with bounded memory: the same
/// figures bit for bit. An element's end speed from the backward pass depends on the
/// elements after it only until the pass saturates (a stop, or a start speed at the
/// element's cap whatever comes after): the elements up to such a point are timed and
/// dropped. The pass is monotonic in the speed coming from behind, so where it gives
/// the same end speed from a stop (0) and from no limit (∞) after the last element
/// held, that end speed is the whole path's.
pub(crate) struct DurationPass {
    /// The elements not yet timed, in order. A `Vec`, not a deque: the common case
    /// times all of them at once ([`DurationPass::push`]), and only
    /// [`DurationPass::settle`] leaves some behind (moved to the front, rarely).
    held: Vec<Segment>,
    /// Scratch for the end speeds of the held elements.
    vend: Vec<f64>,
    fwd: ForwardTime,
    v_top: f64,
    a_min: f64,
    /// Held elements at which to look for a saturated point again.
    scan_at: usize,
}

/// Held elements before [`DurationPass`] first looks for a saturated point.
const DURATION_SCAN_MIN: usize = 256;
/// Longest run of elements [`DurationPass::push_slice`] times where they lie; below
/// `DURATION_SCAN_MIN`, the fewest held elements at which `push` scans.
const DURATION_RUN_MAX: usize = 128;

impl DurationPass {
    pub(crate) fn new(lim: &Limits) -> DurationPass {
        DurationPass {
            held: Vec::new(),
            vend: Vec::new(),
            fwd: ForwardTime::new(lim),
            v_top: 0.0,
            a_min: f64::INFINITY,
            scan_at: DURATION_SCAN_MIN,
        }
    }

    /// The next element of the path (limits final).
    pub(crate) fn push(&mut self, s: &Segment) {
        if s.vel_cap.is_finite() {
            self.v_top = self.v_top.max(s.vel_cap);
        }
        self.a_min = self.a_min.min(s.acc);
        // the common case: `s`'s start speed even from a stop at its end reaches the
        // end limit of the element before it, whose end speed is then that limit
        // whatever comes after: the held elements are timed at once (the same
        // figures as `settle` would find later, without holding and scanning them)
        if let Some(last) = self.held.last() {
            let own = last.v_end_hard.min(cap(last));
            if starts_at_least(s, own) {
                let k = self.held.len() - 1;
                if k == 0 {
                    self.fwd.step(last, own);
                    self.held.clear();
                } else {
                    self.time_upto(k, own);
                }
            }
        }
        self.held.push(*s);
        if self.held.len() >= self.scan_at {
            self.settle();
        }
    }

    /// [`DurationPass::push`] of each of `segs` in order, the same figures bit for
    /// bit, without copying each element into the held ones: once `push` leaves one
    /// element held, the held elements are a run `segs[j..=k]` where they lie, timed
    /// (as [`DurationPass::time_upto`] times them) when the next element's start from
    /// a stop reaches the run's last end limit. A run of `DURATION_RUN_MAX` (below any
    /// `scan_at`, so that `push` would not have scanned it either) and the run left at
    /// the end of `segs` are copied into the held elements, as `push` holds them.
    pub(crate) fn push_slice(&mut self, segs: &[Segment]) {
        let mut i = 0;
        while i < segs.len() {
            self.push(&segs[i]);
            i += 1;
            if self.held.len() == 1 {
                break; // it is `segs[i - 1]`
            }
        }
        if i == segs.len() {
            return;
        }
        self.held.clear();
        let (mut j, mut k) = (i - 1, i - 1);
        // the figures and the forward pass in locals; each element's cap and
        // 2·acc·len worked out once, for its own test and for its step after
        let (mut v_top, mut a_min, mut fwd) = (self.v_top, self.a_min, self.fwd);
        let mut last_cap = cap(&segs[k]);
        let mut last_two_al = 2.0 * segs[k].acc * segs[k].len;
        let mut last = &segs[k];
        for s in &segs[k + 1..] {
            if finite_not_neg_inf(s.vel_cap) {
                // (a −∞ cap would leave `v_top` as it is, as `is_finite` does)
                v_top = max_num(v_top, s.vel_cap);
            }
            a_min = min_num(a_min, s.acc);
            let c = cap(s);
            let two_al = 2.0 * s.acc * s.len;
            let own = min_num(last.v_end_hard, last_cap);
            let own_sq_up = (own * own) * (1.0 + 4.0 * f64::EPSILON);
            // `starts_at_least(s, own)`
            if own <= 0.0 || (c >= own && two_al >= own_sq_up) {
                if j == k {
                    fwd.step_pre(last, own, own_sq_up, last_cap, last_two_al);
                } else {
                    time_run(&mut self.vend, &mut fwd, &segs[j..=k], own);
                }
                j = k + 1;
            }
            (last, last_cap, last_two_al) = (s, c, two_al);
            k += 1;
            if k + 1 - j >= DURATION_RUN_MAX {
                break;
            }
        }
        (self.v_top, self.a_min, self.fwd) = (v_top, a_min, fwd);
        self.held.extend_from_slice(&segs[j..=k]);
        for s in &segs[k + 1..] {
            self.push(s);
        }
    }

    /// Time the held elements up to the last saturated point.
    fn settle(&mut self) {
        let n = self.held.len();
        let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
        let mut at = None;
        for k in (0..n).rev() {
            let s = &self.held[k];
            let (vlo, next_lo) = backward_step(s, lo);
            let (vhi, next_hi) = backward_step(s, hi);
            if vlo == vhi {
                at = Some((k, vlo));
                break;
            }
            (lo, hi) = (next_lo, next_hi);
        }
        let Some((k, vend_k)) = at else {
            self.scan_at = 2 * n;
            return;
        };
        self.time_upto(k, vend_k);
        self.scan_at = 2 * self.held.len() + DURATION_SCAN_MIN;
    }

    /// Time the held elements 0..=k, element k's end speed being `vend_k`.
    fn time_upto(&mut self, k: usize, vend_k: f64) {
        self.vend.clear();
        self.vend.resize(k + 1, 0.0);
        self.vend[k] = vend_k;
        let mut next_start = start_speed(&self.held[k], vend_k);
        for j in (0..k).rev() {
            (self.vend[j], next_start) = backward_step(&self.held[j], next_start);
        }
        for (j, s) in self.held.drain(..=k).enumerate() {
            self.fwd.step(&s, self.vend[j]);
        }
    }

    /// The run time, the highest finite speed cap and the lowest acceleration, as
    /// [`planned_duration`] gives them for the whole path.
    pub(crate) fn finish(mut self) -> (f64, f64, f64) {
        let n = self.held.len();
        if n > 0 {
            let vend_last = backward_step(&self.held[n - 1], 0.0).0;
            self.time_upto(n - 1, vend_last);
        }
        (self.fwd.t, self.v_top, self.a_min)
    }
}

/// Time the elements `run` on `fwd`, the last one's end speed being `vend_last`:
/// the arithmetic of [`DurationPass::time_upto`] on elements not held (`vend`:
/// scratch). Out of line: runs of more than one element are rare (a fillet whose
/// start from a stop cannot reach the end limit before it).
#[cold]
fn time_run(vend: &mut Vec<f64>, fwd: &mut ForwardTime, run: &[Segment], vend_last: f64) {
    let k = run.len() - 1;
    vend.clear();
    vend.resize(k + 1, 0.0);
    vend[k] = vend_last;
    let mut next_start = start_speed(&run[k], vend_last);
    for j in (0..k).rev() {
        (vend[j], next_start) = backward_step(&run[j], next_start);
    }
    for (j, s) in run.iter().enumerate() {
        fwd.step(s, vend[j]);
    }
}

/// Whether a primitive lies inside the box [lo, hi]: its end points and, for an arc,
/// the square around its circle in the arc's plane (which holds the points at the
/// cardinal angles as [`bounding_box`] computes them: c ± r·1 exactly, c + r·ε
/// between c − r and c + r).
fn within(p: &Primitive, lo: Vec3, hi: Vec3) -> bool {
    // (`&`, not `&&`: all the comparisons at once, one branch)
    let inside = |q: &Vec3| {
        (q[0] >= lo[0])
            & (q[0] <= hi[0])
            & (q[1] >= lo[1])
            & (q[1] <= hi[1])
            & (q[2] >= lo[2])
            & (q[2] <= hi[2])
    };
    match p {
        Primitive::Line { start, end } => inside(start) & inside(end),
        Primitive::Arc {
            start,
            end,
            center,
            plane,
            radius,
            ..
        } => {
            let (a, b, _) = plane.axes();
            inside(start)
                & inside(end)
                & (center[a] - radius >= lo[a])
                & (center[a] + radius <= hi[a])
                & (center[b] - radius >= lo[b])
                & (center[b] + radius <= hi[b])
        }
    }
}

/// Axis-aligned bounding box of a primitive.
fn bounding_box(p: &Primitive) -> (Vec3, Vec3) {
    let (s, e) = (p.start(), p.end());
    let (mut lo, mut hi) = (s.min(e), s.max(e));
    if let Primitive::Arc {
        center,
        plane,
        radius,
        start_angle,
        sweep,
        ..
    } = *p
    {
        let (a, b, _) = plane.axes();
        // the points at the cardinal angles crossed by the sweep (the test only for
        // those that would grow the box)
        for (q, (cos_q, sin_q)) in CARDINAL.iter().enumerate() {
            let mut pt = center;
            pt[a] += radius * cos_q;
            pt[b] += radius * sin_q;
            if (0..3).all(|i| pt[i] >= lo[i] && pt[i] <= hi[i]) {
                continue;
            }
            let ang = q as f64 * std::f64::consts::FRAC_PI_2;
            let rel = if sweep >= 0.0 {
                rem_tau(ang - start_angle)
            } else {
                rem_tau(start_angle - ang)
            };
            if rel <= sweep.abs() {
                lo = lo.min(pt);
                hi = hi.max(pt);
            }
        }
    }
    (lo, hi)
}

/// (cos, sin) of 0, π/2, π and 3π/2 as the library computes them.
const CARDINAL: [(f64, f64); 4] = [
    (1.0, 0.0),
    (6.123_233_995_736_766e-17, 1.0),
    (-1.0, 1.224_646_799_147_353_2e-16),
    (-1.836_970_198_721_029_7e-16, -1.0),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// An element for the duration passes: length, acceleration, hard cap, feed and
    /// end limit.
    fn seg(len: f64, acc: f64, cap: f64, feed: f64, v_end_hard: f64) -> Segment {
        Segment {
            s0: 0.0,
            len,
            motion: 0,
            feed_move: true,
            feed_mm_per_s: feed,
            vel_cap: cap,
            acc,
            v_end_hard,
            dwell_s: 0.0,
            line: 0,
            stop: crate::build::StopKind::None,
            block_end: false,
            machine: false,
            pause_motion: 0,
        }
    }

    /// `DurationPass` (timing each element as soon as the next one's start speed
    /// from a stop reaches its end limit, or at a saturated point) gives
    /// `planned_duration`'s figures bit for bit: long elements that settle at once,
    /// runs of short ones whose end speeds depend on elements far ahead (which the
    /// pass must hold), stops, and infinite end limits.
    #[test]
    fn duration_pass_matches_the_whole_path_bit_for_bit() {
        let text = include_str!("../../../config/machines/default.ron");
        let profile = MotionProfile::from_ron_str(text, "default.ron").unwrap();
        let lim = Limits::from_profile(&profile);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            // xorshift64: a fixed pseudo-random sequence
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for case in 0..40 {
            let n = 1 + case * 37;
            let segs: Vec<Segment> = (0..n)
                .map(|k| {
                    // runs of tiny elements, some longer than `push_slice` times
                    // where they lie and than `push` holds before it scans
                    let run = if case % 3 == 0 { 300 } else { 50 };
                    let short = (k / run) % 2 == 1;
                    let len = if short { 1e-4 * next() } else { 5.0 * next() };
                    let acc = 50.0 + 2000.0 * next();
                    let cap = if next() < 0.1 {
                        f64::INFINITY
                    } else {
                        10.0 + 90.0 * next()
                    };
                    let end = if k + 1 == n || next() < 0.02 {
                        0.0
                    } else {
                        f64::INFINITY
                    };
                    seg(len, acc, cap, 20.0 + 80.0 * next(), end)
                })
                .collect();
            let mut pass = DurationPass::new(&lim);
            for s in &segs {
                pass.push(s);
            }
            // and in slices of all lengths (`push_slice`, as the reader of
            // `check_program_parallel` times the planner's batches)
            let mut sliced = DurationPass::new(&lim);
            let mut rest = &segs[..];
            let widths = [1, 3, 200, 7, 1000, 2];
            let mut w = case;
            while !rest.is_empty() {
                w += 1;
                let width = widths[w % widths.len()];
                let (batch, after) = rest.split_at(width.min(rest.len()));
                sliced.push_slice(batch);
                rest = after;
            }
            let (t_whole, v_whole, a_whole) = planned_duration(&segs, &lim);
            for (how, pass) in [("push", pass), ("push_slice", sliced)] {
                let (t, v_top, a_min) = pass.finish();
                assert_eq!(
                    t.to_bits(),
                    t_whole.to_bits(),
                    "case {case} {how}: {t} vs {t_whole}"
                );
                assert_eq!(v_top.to_bits(), v_whole.to_bits(), "case {case} {how}");
                assert_eq!(a_min.to_bits(), a_whole.to_bits(), "case {case} {how}");
            }
        }
    }

    #[test]
    fn cardinal_table_matches_the_library() {
        for (q, (c, s)) in CARDINAL.iter().enumerate() {
            let ang = q as f64 * std::f64::consts::FRAC_PI_2;
            assert_eq!((ang.cos(), ang.sin()), (*c, *s));
        }
    }
}
