//! Streamed plans: a long program never sits in memory as a whole plan (issue 15).
//!
//! A whole [`Plan`](crate::Plan) holds every element of the path; for a 20 MB program
//! that is hundreds of MB of locked memory in the interpolation process. A streamed
//! plan holds a bounded window instead:
//!
//! - [`check_program`] reads and plans the program once, keeping nothing of the path
//!   (the elements are timed as they settle and dropped): the same first error and the
//!   same figures as [`read_and_plan`](crate::read_and_plan) — planned cycles, motions,
//!   spindle changes, bounding box — in memory bounded by the braking distance, not
//!   the program. The daemon checks a job with it before any motion ("no motion from
//!   a rejected job").
//! - [`stream_program`] gives the two ends of a stream: a [`StreamProducer`] that reads
//!   and plans the program again on a non-real-time thread, handing over each element
//!   once its limits are settled, through a bounded, preallocated queue; and a
//!   [`StreamInterpolator`] that pulls one [`Sample`] per call into a preallocated ring
//!   of elements (the window, [`PlanOptions::stream_window_segments`]) and allocates
//!   nothing after [`StreamInterpolator::fill`].
//!
//! The interpolator is the whole plan's own code (`interp::Core`) over the window, so
//! the samples equal [`Plan::interpolator`](crate::Plan::interpolator)'s bit for bit
//! whenever the producer keeps ahead of the lookahead (the tests check it on the test
//! programs and the shared corpus). When it does not, the end of the window counts as
//! a stop: the path brakes within its limits to what it has, never runs past it, and
//! [`StreamInterpolator::starved`] counts the event so that the daemon can alarm.

use crate::build::{
    motion_primitive, ArcPrep, CapDilator, FilletAhead, FilletsAhead, Limits, PathBuilder, Segment,
    StopKind,
};
use crate::interp::{Core, SegmentSource, MAX_LOOKAHEAD_SEGMENTS};
use crate::path::Geom;
use crate::plan::{
    Checker, DurationPass, PlanError, PlanOptions, PlanStats, ReadPlanError, READ_CHUNK_MOTIONS,
};
use crate::Sample;
use softnc_core::{FeedProfile, MotionProfile, Primitive, Vec3};
use softnc_gcode::{Motion, Params, Program};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::Arc;

/// Elements the window holds by default: the lookahead's
/// [`MAX_LOOKAHEAD_SEGMENTS`] ahead of the element being run, plus room for the
/// elements between it and the output cursor (which lags by the S-curve window) and
/// for those in flight. About 3.6 MB of elements.
pub const DEFAULT_STREAM_WINDOW_SEGMENTS: usize = 1 << 15;

/// Elements in flight between the producer and the window.
pub const STREAM_QUEUE_ELEMENTS: usize = 1024;

/// How long a producer whose queue is full waits before it tries again.
const PRODUCER_BACKOFF: std::time::Duration = std::time::Duration::from_micros(200);

/// Elements the window takes from the queue per sample at most (beside what the
/// lookahead asks for): keeps the window full ahead of the lookahead, in bounded time
/// per cycle.
const TOP_UP_PER_SAMPLE: usize = 64;

/// Elements the builder gathers before handing the settled ones on.
const DRAIN_BATCH: usize = 64;

/// The window size `options` ask for: a power of two, at least the lookahead's
/// [`MAX_LOOKAHEAD_SEGMENTS`] + 2.
pub fn stream_window_segments(options: &PlanOptions) -> usize {
    let asked = if options.stream_window_segments == 0 {
        DEFAULT_STREAM_WINDOW_SEGMENTS
    } else {
        options.stream_window_segments
    };
    asked.max(MAX_LOOKAHEAD_SEGMENTS + 2).next_power_of_two()
}

/// Bytes one element takes in the window (its limits and its geometry).
pub fn window_element_bytes() -> usize {
    std::mem::size_of::<Segment>() + std::mem::size_of::<Geom>()
}

/// What checking a program gives: the figures of its plan, without the plan.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckedProgram {
    stats: PlanStats,
    motions: usize,
    elements: usize,
    spindle_changes: Vec<(u32, f64)>,
    brake_dist_mm: f64,
    max_override: f64,
    start_mm: Vec3,
    end_params: Params,
}

impl CheckedProgram {
    /// The parameters as the program left them (issue 16's persistent parameters:
    /// a daemon keeps them for the next job or MDI command through
    /// [`PlanOptions::params`], as LinuxCNC keeps its parameter file, so that
    /// G10 L2/L20 touch-offs, G92 and G28.1/G30.1 persist). After M2/M30, 5220 is 1
    /// (G54), as LinuxCNC's `convert_stop` leaves it.
    pub fn end_params(&self) -> &Params {
        &self.end_params
    }

    /// Figures of the plan (as [`Plan::stats`](crate::Plan::stats)).
    pub fn stats(&self) -> PlanStats {
        self.stats.clone()
    }
    /// Number of program motions (as [`Plan::motions`](crate::Plan::motions)).
    pub fn motions(&self) -> usize {
        self.motions
    }
    /// Number of path elements (as [`Plan::elements`](crate::Plan::elements)).
    pub fn elements(&self) -> usize {
        self.elements
    }
    /// The spindle speed changes (as
    /// [`Plan::spindle_changes`](crate::Plan::spindle_changes)).
    pub fn spindle_changes(&self) -> &[(u32, f64)] {
        &self.spindle_changes
    }
}

/// Plans motions one at a time and hands on each element once its limits are
/// settled, keeping only the elements that later ones may still change.
struct StreamPlanner<'a> {
    checker: Checker<'a>,
    builder: PathBuilder,
    settled: Settled,
    /// Elements the builder gathers before handing the settled ones on
    /// ([`DRAIN_BATCH`]; where they go to another thread a chunk's at once,
    /// [`StreamPlanner::drain_all`]).
    drain_batch: usize,
}

/// The settling stages after the builder: the S-curve spreading of caps, then the
/// figures.
struct Settled {
    dilator: Option<CapDilator>,
    fin: Figures,
}

/// What the settled elements add up to.
struct Figures {
    duration: DurationPass,
    /// Where the elements are timed on another thread (`check_program_parallel`
    /// with `arc_blends`): the settled elements not yet handed over, in order, instead
    /// of `duration`.
    handoff: Option<Vec<Segment>>,
    elements: usize,
    start_mm: Option<Vec3>,
    path_length_mm: f64,
}

impl Figures {
    /// A settled element (final limits), on its way to `out`.
    fn take(&mut self, s: &Segment, g: &Geom, out: &mut impl FnMut(&Segment, &Geom)) {
        match &mut self.handoff {
            Some(v) => v.push(*s),
            None => self.duration.push(s),
        }
        self.elements += 1;
        self.start_mm.get_or_insert_with(|| g.point_at(0.0));
        self.path_length_mm = s.s0 + s.len;
        out(s, g);
    }

    /// [`Figures::take`] of the settled elements in `segs` (geometry `geoms`) in
    /// order: the same figures, the limits handed over in one copy, or where the
    /// hand-over is empty in the vector itself (swapped for the empty one: the
    /// builder's vector, not a copy; docs/perf-log/planner-figures.md, fifteenth round).
    fn take_vec(
        &mut self,
        segs: &mut Vec<Segment>,
        geoms: &[Geom],
        out: &mut impl FnMut(&Segment, &Geom),
    ) {
        let (Some(last), Some(first_geom)) = (segs.last(), geoms.first()) else {
            return;
        };
        self.elements += segs.len();
        self.start_mm
            .get_or_insert_with(|| first_geom.point_at(0.0));
        self.path_length_mm = last.s0 + last.len;
        for (s, g) in segs.iter().zip(geoms.iter()) {
            out(s, g);
        }
        match &mut self.handoff {
            Some(v) if v.is_empty() => std::mem::swap(v, segs),
            Some(v) => v.extend_from_slice(segs),
            None => self.duration.push_slice(segs),
        }
    }
}

impl Settled {
    /// An element from the builder: through the dilator (S-curve) to `out`.
    fn take(&mut self, s: &Segment, g: &Geom, out: &mut impl FnMut(&Segment, &Geom)) {
        let fin = &mut self.fin;
        match &mut self.dilator {
            Some(d) => d.push(s, g, &mut |s, g| fin.take(s, g, out)),
            None => fin.take(s, g, out),
        }
    }

    /// [`Settled::take`] of the elements in `segs` (geometry `geoms`) in order,
    /// whose vector the figures may take ([`Figures::take_vec`]).
    fn take_vec(
        &mut self,
        segs: &mut Vec<Segment>,
        geoms: &[Geom],
        out: &mut impl FnMut(&Segment, &Geom),
    ) {
        match &mut self.dilator {
            Some(_) => {
                for (s, g) in segs.iter().zip(geoms) {
                    self.take(s, g, out);
                }
            }
            None => self.fin.take_vec(segs, geoms, out),
        }
    }

    /// The path has ended: what the dilator holds to `out`.
    fn finish(mut self, out: &mut impl FnMut(&Segment, &Geom)) -> Figures {
        let fin = &mut self.fin;
        if let Some(d) = self.dilator {
            d.finish(&mut |s, g| fin.take(s, g, out));
        }
        self.fin
    }
}

impl<'a> StreamPlanner<'a> {
    fn new(profile: &'a MotionProfile, options: &'a PlanOptions, file: &'a str) -> Self {
        let lim = Limits::from_profile(profile);
        let mut builder = PathBuilder::new(&lim, DRAIN_BATCH);
        builder.set_single_block(options.single_block);
        builder.set_streamed();
        StreamPlanner {
            checker: Checker::new(profile, options, file),
            builder,
            settled: Settled {
                dilator: (lim.profile == FeedProfile::SCurve).then(|| CapDilator::new(&lim)),
                fin: Figures {
                    duration: DurationPass::new(&lim),
                    handoff: None,
                    elements: 0,
                    start_mm: None,
                    path_length_mm: 0.0,
                },
            },
            drain_batch: DRAIN_BATCH,
        }
    }

    fn push(&mut self, m: &Motion, out: &mut impl FnMut(&Segment, &Geom)) -> Result<(), PlanError> {
        self.push_primitive(m, motion_primitive(m), out)
    }

    /// [`StreamPlanner::push`] with the motion's programmed primitive worked out.
    fn push_primitive(
        &mut self,
        m: &Motion,
        prim: Option<Primitive>,
        out: &mut impl FnMut(&Segment, &Geom),
    ) -> Result<(), PlanError> {
        let index = self.checker.n_motions;
        self.checker.check(m, &prim)?;
        self.push_checked(index, m, prim, out);
        Ok(())
    }

    /// Plan motion number `index`, which a [`Checker`] (this one's or another's)
    /// has passed.
    fn push_checked(
        &mut self,
        index: usize,
        m: &Motion,
        prim: Option<Primitive>,
        out: &mut impl FnMut(&Segment, &Geom),
    ) {
        self.builder.push(index, m, prim);
        self.drain(out);
    }

    /// [`StreamPlanner::push_checked`] with the arc data of `prim` and the fillet at its
    /// join with the motion before, where worked out ahead.
    fn push_prepared(
        &mut self,
        index: usize,
        m: &Motion,
        prim: &Option<Primitive>,
        prep: Option<&ArcPrep>,
        ahead: Option<&FilletAhead>,
        out: &mut impl FnMut(&Segment, &Geom),
    ) {
        self.builder.push_prepared(index, m, prim, prep, ahead);
        self.drain(out);
    }

    /// Hand the settled elements on, once [`StreamPlanner::drain_batch`] gathered.
    fn drain(&mut self, out: &mut impl FnMut(&Segment, &Geom)) {
        self.drain_over(self.drain_batch, out);
    }

    /// Hand every settled element on.
    fn drain_all(&mut self, out: &mut impl FnMut(&Segment, &Geom)) {
        self.drain_over(0, out);
    }

    /// Hand the settled elements on where more than `batch` gathered.
    fn drain_over(&mut self, batch: usize, out: &mut impl FnMut(&Segment, &Geom)) {
        let settled = &mut self.settled;
        self.builder
            .drain_settled_vec(batch, &mut |segs, geoms| settled.take_vec(segs, geoms, out));
    }

    fn finish(
        self,
        profile: &MotionProfile,
        end_params: Params,
        out: &mut impl FnMut(&Segment, &Geom),
    ) -> CheckedProgram {
        let StreamPlanner {
            checker,
            builder,
            settled,
            ..
        } = self;
        Self::finish_with(checker, builder, settled, profile, end_params, out)
    }

    /// [`StreamPlanner::finish`] with the [`Checker`] that passed the motions.
    fn finish_with(
        checker: Checker<'a>,
        builder: PathBuilder,
        mut settled: Settled,
        profile: &MotionProfile,
        end_params: Params,
        out: &mut impl FnMut(&Segment, &Geom),
    ) -> CheckedProgram {
        builder.finish_stream(&mut |s, g| settled.take(s, g, out));
        let Figures {
            duration,
            elements,
            start_mm,
            path_length_mm,
            ..
        } = settled.finish(out);
        let lim = Limits::from_profile(profile);
        let (stats, brake_dist_mm) = checker.figures(&lim, path_length_mm, duration.finish());
        // a path without an element (its moves all of zero length, or none) holds
        // where the machine stands, not at a default origin
        let start_mm = start_mm.or(checker.start_mm()).unwrap_or_default();
        CheckedProgram {
            stats,
            motions: checker.n_motions,
            elements,
            spindle_changes: checker.spindle_changes,
            brake_dist_mm,
            max_override: profile.planner.max_feed_override,
            start_mm,
            end_params,
        }
    }
}

/// Read a program from `text` and plan it the way [`stream_program`] will, keeping
/// nothing of the path: the same first error (a G-code error anywhere before a soft
/// limit) and the same figures as [`read_and_plan`](crate::read_and_plan), in memory
/// bounded by the braking distance rather than the program. The returned [`Program`]
/// has no motions (blocks and warnings only).
pub fn check_program(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, CheckedProgram), ReadPlanError> {
    let mut planner = StreamPlanner::new(profile, options, file);
    let mut refused: Option<PlanError> = None;
    let (program, end_params) = softnc_gcode::read_program_chunked_params(
        text,
        file,
        profile,
        &options.read_options(),
        READ_CHUNK_MOTIONS,
        &mut |chunk: &mut Vec<Motion>| {
            if refused.is_none() {
                for m in chunk.iter() {
                    if let Err(e) = planner.push(m, &mut |_, _| {}) {
                        refused = Some(e);
                        break;
                    }
                }
            }
        },
    )?;
    match refused {
        Some(e) => Err(e.into()),
        None => Ok((program, planner.finish(profile, end_params, &mut |_, _| {}))),
    }
}

/// The machine sequencer of a program as [`stream_program`] streams it (read with
/// the same options, so the motion indices are the samples'): a reading of `text`
/// that keeps only the machine operations' tables, before motion.
pub fn stream_sequencer(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    cfg: crate::machine_sequencer::SequencerConfig,
    initial: crate::machine_sequencer::SequencerState,
) -> Result<crate::machine_sequencer::MachineSequencer, ReadPlanError> {
    stream_sequencer_with(text, file, profile, options, cfg, initial, &mut |_, _| {})
}

/// [`stream_sequencer`] with the programmed end points of the motions (machine
/// coordinates, mm; a motion that moves nothing ends where the last one did): the
/// status's distance to go of the motion a sample belongs to.
pub fn stream_sequencer_and_ends(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    cfg: crate::machine_sequencer::SequencerConfig,
    initial: crate::machine_sequencer::SequencerState,
) -> Result<(crate::machine_sequencer::MachineSequencer, MotionEnds), ReadPlanError> {
    let mut ends = MotionEnds::default();
    let seq = stream_sequencer_with(text, file, profile, options, cfg, initial, &mut |_, m| {
        ends.push(m);
    })?;
    Ok((seq, ends))
}

/// The programmed end point of every motion of a program, by motion index (machine
/// coordinates, mm).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MotionEnds {
    ends_mm: Vec<[f64; 3]>,
}

impl MotionEnds {
    /// The next motion: its end, or (moving nothing) where the last one ended, or
    /// its start.
    pub fn push(&mut self, m: &Motion) {
        let end = match m.kind.end() {
            Some(e) => e + m.offset_mm,
            None => match self.ends_mm.last() {
                Some(last) => Vec3(*last),
                None => m.start + m.offset_mm,
            },
        };
        self.ends_mm.push(end.0);
    }

    /// Motion `index`'s end point (`None` past the program's motions).
    pub fn end_mm(&self, index: u32) -> Option<[f64; 3]> {
        self.ends_mm.get(index as usize).copied()
    }

    /// The number of motions.
    pub fn len(&self) -> usize {
        self.ends_mm.len()
    }

    /// No motion.
    pub fn is_empty(&self) -> bool {
        self.ends_mm.is_empty()
    }
}

/// [`stream_sequencer`], calling `each` with every motion and its index.
fn stream_sequencer_with(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    cfg: crate::machine_sequencer::SequencerConfig,
    initial: crate::machine_sequencer::SequencerState,
    each: &mut dyn FnMut(u32, &Motion),
) -> Result<crate::machine_sequencer::MachineSequencer, ReadPlanError> {
    let mut b = crate::machine_sequencer::SequencerBuilder::new(cfg, initial);
    let mut index = 0u32;
    let (program, _) = softnc_gcode::read_program_chunked_params(
        text,
        file,
        profile,
        &options.read_options(),
        READ_CHUNK_MOTIONS,
        &mut |chunk: &mut Vec<Motion>| {
            for m in chunk.iter() {
                b.push(index, m);
                each(index, m);
                index += 1;
            }
        },
    )?;
    Ok(b.finish(program.messages))
}

/// [`check_program`] on two threads: the calling thread reads and works out each
/// motion's programmed primitive, a second one checks and plans the motions chunk by
/// chunk as they come (the same figures and errors). With `arc_blends`, whose fillets
/// make the planning thread the slower of the two, the reading thread also checks
/// the motions, works out the arcs' data ([`ArcPrep`]) and times the settled
/// elements the planner hands back ([`DurationPass`], the same figures bit for bit:
/// the elements come in order), see [`reader_checks`].
/// What `softnc plan` needs for its summary: no path is stored, so a long program
/// costs no memory for one (the page faults of a whole plan's 44 MB were a quarter
/// of `softnc plan`'s time on the 200,000-line benchmark program).
pub fn check_program_parallel(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, CheckedProgram), ReadPlanError> {
    check_program_parallel_with(
        ProgramText::Str(text),
        file,
        profile,
        options,
        FilletsAheadWhen::PlannerBehind,
    )
}

/// [`check_program_parallel`] of a program's bytes, checked as UTF-8 where the
/// reader reads them (`softnc_gcode::read_program_chunked_params_bytes`), not all
/// before the two threads start: the same figures and errors where they are UTF-8;
/// where they are not, the reader's `ErrorKind::NotUtf8`, and the caller checks
/// `String::from_utf8_lossy` of them with [`check_program_parallel`].
pub fn check_program_parallel_bytes(
    bytes: &[u8],
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
) -> Result<(Program, CheckedProgram), ReadPlanError> {
    check_program_parallel_with(
        ProgramText::Bytes(bytes),
        file,
        profile,
        options,
        FilletsAheadWhen::PlannerBehind,
    )
}

/// A program for [`check_program_parallel_with`]: its text, or its bytes checked as
/// UTF-8 where read.
#[derive(Debug, Clone, Copy)]
pub(crate) enum ProgramText<'a> {
    Str(&'a str),
    Bytes(&'a [u8]),
}

/// When the reading thread of [`check_program_parallel`] (where it checks the
/// motions, [`reader_checks`]) works out the line–arc fillets of a chunk's joins
/// ahead ([`FilletsAhead`]) for the planning thread to take.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FilletsAheadWhen {
    /// Never: the planning thread works out every fillet.
    #[cfg_attr(not(test), allow(dead_code))]
    Never,
    /// For every chunk.
    #[cfg_attr(not(test), allow(dead_code))]
    Always,
    /// For a chunk read while at least [`AHEAD_QUEUED_CHUNKS`] chunks wait for the
    /// planning thread (it is behind) and the planning thread built at least
    /// [`AHEAD_PARALLEL_MOTIONS`] motions (so the two ran at once). On the processor
    /// a fillet worked out ahead costs the reader about what it saves the planner
    /// (docs/perf-log/planner-figures.md, "Where the time goes on the processor"), so the share done
    /// ahead follows the planner's backlog. (A third test, that the reader read the
    /// chunk undisturbed, made the rule stick at no fillet ahead once the machine had
    /// other work: runs then took the planner's whole share, 36–50 ms.)
    PlannerBehind,
}

/// Chunks waiting for the planning thread from which the reader works out the next
/// chunk's fillets ahead ([`FilletsAheadWhen::PlannerBehind`]).
const AHEAD_QUEUED_CHUNKS: usize = 1;

/// Motions the planning thread must have built while the reader read a chunk for the
/// two to count as running at once ([`FilletsAheadWhen::PlannerBehind`]): a quarter
/// of a chunk (on two free cores it builds about three quarters of one meanwhile).
const AHEAD_PARALLEL_MOTIONS: usize = PARALLEL_CHUNK_MOTIONS / 4;

/// Motions per chunk the reading thread of [`check_program_parallel`] hands to the
/// planning thread: half of [`READ_CHUNK_MOTIONS`], so that the chunks in flight
/// (motions, primitives, arc data, fillets: about 330 kB at this size) stay in the
/// caches both cores share. On the 200k-line benchmark program with arc blends
/// (docs/perf-log/planner-figures.md, "After `plan11`, `plan12`, `speed8`, `jerk1` and the lead's
/// chunk size") 512 motions and
/// [`PARALLEL_QUEUE_CHUNKS`] chunks queued take 0.95× the wall and cpu time of 1,024
/// and 8 (medians of 51 interleaved whole-process pairs, twice), peak memory 13.7
/// against 19 MiB, page faults 1,950 against 2,600–3,700; 256 measured no better.
const PARALLEL_CHUNK_MOTIONS: usize = READ_CHUNK_MOTIONS / 2;

/// Chunks that may wait for the planning thread in [`check_program_parallel`] before
/// the reader waits: two keep it busy (the reader is the quicker of the two with arc
/// blends, and a chunk takes it about 0.1 ms); more only touch more memory.
const PARALLEL_QUEUE_CHUNKS: usize = 2;

/// Longest the two threads of [`check_program_parallel`] look for each other's
/// progress (a chunk to take, room to send one) before they block on the channel.
/// A thread that blocks sleeps on its core and is woken by the other through the
/// kernel: on the benchmark program's 390 chunks that was about 500 sleeps a run,
/// and where they happened the whole process took 40–55 ms, where runs with a few
/// dozen took 20–29 ms (`/usr/bin/time`, voluntary context switches, 20 runs). A
/// chunk takes the planning thread about 0.1 ms, so on two free cores a wait is
/// seldom longer than this; a thread that waits longer (a machine with other work on
/// the cores) sleeps, and [`HandoffWait`] stops looking for a while. 0.5 ms measured
/// the same on a quiet machine, 2 ms too.
const HANDOFF_SPIN: std::time::Duration = std::time::Duration::from_micros(200);

/// Looks between two readings of the clock while [`spin_until`] waits.
const SPIN_LOOKS: usize = 64;

/// Waits a thread of [`check_program_parallel`] blocks at once after a look that
/// ran out ([`HandoffWait`]); doubled at each further one, up to
/// [`SPIN_SKIP_MAX_WAITS`].
const SPIN_SKIP_FIRST_WAITS: u32 = 8;

/// Most waits blocked at once between two looks ([`HandoffWait`]).
const SPIN_SKIP_MAX_WAITS: u32 = 1024;

/// Wait until `ready()` or for [`HANDOFF_SPIN`]: looking, with the processor's
/// spin-wait hint between looks. False where the time ran out. (Yielding the
/// processor between rounds, tried first, handed it to a busy process for whole time
/// slices: with both cores loaded, single runs took 0.17–0.29 s where blocking took
/// 0.05–0.09 s.)
fn spin_until(ready: impl Fn() -> bool) -> bool {
    if ready() {
        return true;
    }
    let deadline = std::time::Instant::now() + HANDOFF_SPIN;
    loop {
        for _ in 0..SPIN_LOOKS {
            std::hint::spin_loop();
            if ready() {
                return true;
            }
        }
        if std::time::Instant::now() >= deadline {
            return false;
        }
    }
}

/// One thread's waits for the other in [`check_program_parallel`]: a look
/// ([`spin_until`]) while looks pay, else straight to the channel's sleep. On two
/// free cores a look nearly always finds the other's progress; on a machine with
/// other work the two threads share cores, a look runs out, and sleeping is the
/// better wait (with both cores busy, 0.05–0.09 s a run as when the threads always
/// slept, 10 runs twice). So after a look that ran out the next
/// [`SPIN_SKIP_FIRST_WAITS`] waits sleep at once, twice as many after each further
/// one, until a look finds progress again.
#[derive(Debug, Default)]
struct HandoffWait {
    /// Waits still to sleep at once.
    skip: u32,
    /// Waits to sleep at once after the next look that runs out.
    next_skip: u32,
}

impl HandoffWait {
    /// Look for `ready()` where looks pay (the caller then blocks on its channel,
    /// which returns at once if it is ready).
    fn wait(&mut self, ready: impl Fn() -> bool) {
        if self.skip > 0 {
            self.skip -= 1;
            return;
        }
        if spin_until(ready) {
            self.next_skip = 0;
        } else {
            self.next_skip = (self.next_skip * 2).clamp(SPIN_SKIP_FIRST_WAITS, SPIN_SKIP_MAX_WAITS);
            self.skip = self.next_skip;
        }
    }
}

impl FilletsAheadWhen {
    /// Whether the reader works the fillets of a chunk out ahead, with `queued`
    /// chunks waiting for the planning thread, which built `built` motions while the
    /// reader read this chunk.
    fn works(self, queued: usize, built: usize) -> bool {
        match self {
            FilletsAheadWhen::Never => false,
            FilletsAheadWhen::Always => true,
            FilletsAheadWhen::PlannerBehind => {
                queued >= AHEAD_QUEUED_CHUNKS && built >= AHEAD_PARALLEL_MOTIONS
            }
        }
    }
}

/// [`check_program_parallel`] with the fillets worked out ahead `when`.
#[allow(clippy::too_many_lines)]
pub(crate) fn check_program_parallel_with(
    text: ProgramText<'_>,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    when: FilletsAheadWhen,
) -> Result<(Program, CheckedProgram), ReadPlanError> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    use std::sync::mpsc::channel;
    // the motions, their primitives and (where the reader checks) their arc data and
    // the fillets worked out ahead (by index in the chunk)
    type Chunk = (
        Vec<Motion>,
        Vec<Option<Primitive>>,
        Vec<Option<ArcPrep>>,
        Vec<(u32, FilletAhead)>,
    );
    // chunks sent to the planning thread and not yet taken by it
    let queued = AtomicUsize::new(0);
    let queued = &queued;
    // motions the planning thread has built (with the reader checking)
    let built = AtomicUsize::new(0);
    let built = &built;
    // the reader has sent its last chunk
    let read_done = AtomicBool::new(false);
    let read_done = &read_done;
    let (to_planner, chunks) = sync_channel::<Chunk>(PARALLEL_QUEUE_CHUNKS);
    // the end parameters, and the reader's checker where it checked the motions
    let (params_tx, params_rx) = sync_channel::<Params>(1);
    let (recycle, recycled) = channel::<Chunk>();
    // with the reader checking: the settled elements, for the reader to time
    let (timing_tx, timing_rx) = channel::<Vec<Segment>>();
    let (timed_tx, timed_rx) = channel::<Vec<Segment>>(); // the emptied batches back
    let reader_checks = reader_checks(profile);
    std::thread::scope(|scope| {
        let planner = scope.spawn(move || {
            let mut planner = StreamPlanner::new(profile, options, file);
            if reader_checks {
                // (the settled elements of a chunk go over at its end, in the
                // builder's own vector: `Figures::take_vec`)
                planner.settled.fin.handoff = Some(Vec::new());
                planner.drain_batch = usize::MAX;
            }
            let mut refused: Option<PlanError> = None;
            let mut index = 0;
            let mut waits = HandoffWait::default();
            loop {
                // (the reader sends a chunk about every 0.1 ms: a look beats a sleep)
                waits.wait(|| {
                    queued.load(Ordering::Relaxed) > 0 || read_done.load(Ordering::Relaxed)
                });
                let Ok((mut motions, mut prims, mut preps, mut aheads)) = chunks.recv() else {
                    break;
                };
                queued.fetch_sub(1, Ordering::Relaxed);
                if refused.is_none() {
                    let mut next_ahead = 0;
                    for (k, (m, prim)) in motions.iter().zip(&prims).enumerate() {
                        if reader_checks {
                            let ahead = match aheads.get(next_ahead) {
                                Some((j, f)) if *j as usize == k => {
                                    next_ahead += 1;
                                    Some(f)
                                }
                                _ => None,
                            };
                            planner.push_prepared(
                                index,
                                m,
                                prim,
                                preps[k].as_ref(),
                                ahead,
                                &mut |_, _| {},
                            );
                            index += 1;
                            built.store(index, Ordering::Relaxed);
                        } else if let Err(e) = planner.push_primitive(m, *prim, &mut |_, _| {}) {
                            refused = Some(e);
                            break;
                        }
                    }
                }
                if reader_checks {
                    planner.drain_all(&mut |_, _| {});
                }
                motions.clear();
                prims.clear();
                preps.clear();
                aheads.clear();
                // the reader may be gone
                let _ = recycle.send((motions, prims, preps, aheads));
                if let Some(v) = planner.settled.fin.handoff.as_mut() {
                    let fresh = timed_rx
                        .try_recv()
                        .unwrap_or_else(|_| Vec::with_capacity(v.capacity()));
                    let _ = timing_tx.send(std::mem::replace(v, fresh));
                }
            }
            if reader_checks {
                // the reader finishes the figures, with its checker and timing
                return Ok(Planned::Unfinished(Box::new(planner)));
            }
            match refused {
                Some(e) => Err(e),
                // the reader sends the parameters once it has read the whole program
                None => {
                    let end_params = params_rx.recv().unwrap_or_default();
                    let checked = planner.finish(profile, end_params, &mut |_, _| {});
                    Ok(Planned::Finished(Box::new(checked)))
                }
            }
        });
        let mut checker = reader_checks.then(|| Checker::new(profile, options, file));
        let mut built_seen = 0;
        let mut waits = HandoffWait::default();
        let mut fillets_ahead =
            FilletsAhead::new(&Limits::from_profile(profile), options.single_block);
        let mut duration = DurationPass::new(&Limits::from_profile(profile));
        let mut time = |mut batch: Vec<Segment>| {
            duration.push_slice(&batch);
            batch.clear();
            let _ = timed_tx.send(batch); // the planner may be done
        };
        let mut refused: Option<PlanError> = None;
        let mut sink = |chunk: &mut Vec<Motion>| {
            while let Ok(batch) = timing_rx.try_recv() {
                time(batch);
            }
            if refused.is_some() {
                return; // refused: the planner's figures are not needed
            }
            let (fresh, mut prims, mut preps, mut aheads) =
                recycled.try_recv().unwrap_or_else(|_| {
                    (
                        Vec::with_capacity(PARALLEL_CHUNK_MOTIONS),
                        Vec::with_capacity(PARALLEL_CHUNK_MOTIONS),
                        Vec::new(),
                        Vec::new(),
                    )
                });
            prims.extend(chunk.iter().map(motion_primitive));
            if let Some(c) = checker.as_mut() {
                for (m, prim) in chunk.iter().zip(&prims) {
                    if let Err(e) = c.check(m, prim) {
                        refused = Some(e);
                        return;
                    }
                }
                preps.extend(prims.iter().map(ArcPrep::of));
                let work = when.works(
                    queued.load(Ordering::Relaxed),
                    built.load(Ordering::Relaxed).saturating_sub(built_seen),
                );
                fillets_ahead.chunk(chunk, &prims, &preps, work, &mut aheads);
            }
            // (the planner takes a chunk about every 0.1 ms: a look beats a sleep)
            let in_flight = queued.fetch_add(1, Ordering::Relaxed) + 1;
            if in_flight > PARALLEL_QUEUE_CHUNKS {
                waits.wait(|| queued.load(Ordering::Relaxed) <= PARALLEL_QUEUE_CHUNKS);
            }
            // a planner that stopped early (it cannot) only loses the chunk
            let _ = to_planner.send((std::mem::replace(chunk, fresh), prims, preps, aheads));
            built_seen = built.load(Ordering::Relaxed);
        };
        let read_options = options.read_options();
        let read = match text {
            ProgramText::Str(t) => softnc_gcode::read_program_chunked_params(
                t,
                file,
                profile,
                &read_options,
                PARALLEL_CHUNK_MOTIONS,
                &mut sink,
            ),
            ProgramText::Bytes(b) => softnc_gcode::read_program_chunked_params_bytes(
                b,
                file,
                profile,
                &read_options,
                PARALLEL_CHUNK_MOTIONS,
                &mut sink,
            ),
        };
        drop(to_planner);
        read_done.store(true, Ordering::Relaxed);
        let read = read.map(|(program, params)| {
            let _ = params_tx.send(params.clone()); // a planner that refused is gone
            (program, params)
        });
        drop(params_tx);
        // until the planner is done (its sender then goes)
        for batch in timing_rx.iter() {
            time(batch);
        }
        let planned = planner
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e));
        let (program, end_params) = read?;
        if let Some(e) = refused {
            return Err(e.into());
        }
        let checked = match planned? {
            Planned::Finished(c) => *c,
            Planned::Unfinished(sp) => {
                let StreamPlanner {
                    builder,
                    mut settled,
                    ..
                } = *sp;
                if let Some(rest) = settled.fin.handoff.take() {
                    time(rest);
                }
                settled.fin.duration = duration;
                let checker = checker.unwrap_or_else(|| Checker::new(profile, options, file));
                StreamPlanner::finish_with(
                    checker,
                    builder,
                    settled,
                    profile,
                    end_params,
                    &mut |_, _| {},
                )
            }
        };
        Ok((program, checked))
    })
}

/// What the planning thread of [`check_program_parallel`] gives back.
enum Planned<'a> {
    /// The figures, where it checked the motions itself.
    Finished(Box<CheckedProgram>),
    /// The planner with its last move still pending, where the reader checked the
    /// motions and timed the elements handed over: the reader finishes it.
    Unfinished(Box<StreamPlanner<'a>>),
}

/// Whether [`check_program_parallel`]'s reading thread checks the motions (soft
/// limits, bounding box, spindle changes: [`Checker::check`]) as well as working out
/// their primitives, works out the arcs' data for the blends ([`ArcPrep`]) and times
/// the settled elements. With `arc_blends` the planning thread has about twice the
/// elements to build and time (a fillet per line–arc join) and is the slower of the
/// two, so the reader takes these over; without, the reader is the slower and the
/// planner keeps them. The figures and errors are the same either way.
fn reader_checks(profile: &MotionProfile) -> bool {
    profile.planner.arc_blends
}

/// What goes from the producer to the window.
#[derive(Debug, Clone, Copy)]
enum Msg {
    /// The next element, its limits settled.
    Element(Segment, Geom),
    /// The path ends with the last element sent.
    End,
    /// The producer could not plan the program (an error, reported by
    /// [`StreamProducer::run`]): nothing more comes.
    Failed,
}

/// The producing end of a streamed plan: reads and plans the program and hands the
/// elements to its [`StreamInterpolator`]. Run it on a thread of its own (not a
/// real-time one): it allocates, and it waits while the window is full.
pub struct StreamProducer {
    text: Arc<str>,
    file: String,
    profile: MotionProfile,
    options: PlanOptions,
    tx: SyncSender<Msg>,
}

impl StreamProducer {
    /// Read and plan the program, handing each settled element over; returns when
    /// the last is handed over (or the interpolator is gone). The error is the one
    /// [`check_program`] gives for the same text; the interpolator then stops at the
    /// end of what it got and reports [`StreamInterpolator::failed`].
    pub fn run(self) -> Result<(), ReadPlanError> {
        let StreamProducer {
            text,
            file,
            profile,
            options,
            tx,
        } = self;
        let mut gone = false;
        let mut send = |msg: Msg| {
            let mut msg = msg;
            while !gone {
                match tx.try_send(msg) {
                    Ok(()) => return,
                    Err(TrySendError::Full(m)) => {
                        msg = m;
                        std::thread::sleep(PRODUCER_BACKOFF);
                    }
                    Err(TrySendError::Disconnected(_)) => gone = true,
                }
            }
        };
        let mut planner = StreamPlanner::new(&profile, &options, &file);
        let mut refused: Option<PlanError> = None;
        let read = softnc_gcode::read_program_chunked_with(
            &text,
            &file,
            &profile,
            &options.read_options(),
            READ_CHUNK_MOTIONS,
            &mut |chunk: &mut Vec<Motion>| {
                if refused.is_none() {
                    for m in chunk.iter() {
                        if let Err(e) = planner.push(m, &mut |s, g| send(Msg::Element(*s, *g))) {
                            refused = Some(e);
                            send(Msg::Failed);
                            break;
                        }
                    }
                }
            },
        );
        let result = match (read, refused) {
            (Err(e), _) => Err(ReadPlanError::from(e)),
            (Ok(_), Some(e)) => Err(e.into()),
            (Ok(_), None) => {
                planner.finish(&profile, Params::default(), &mut |s, g| {
                    send(Msg::Element(*s, *g))
                });
                Ok(())
            }
        };
        send(if result.is_ok() {
            Msg::End
        } else {
            Msg::Failed
        });
        result
    }
}

/// Whether the interpolator may wait for the producer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StreamMode {
    /// Never wait (the interpolation cycle): when the producer is behind, brake to a
    /// stop at the end of what has come and count [`StreamInterpolator::starved`].
    RealTime,
    /// Wait for the producer whenever the lookahead needs an element that has not
    /// come (offline simulation and tests): samples equal the whole plan's unless the
    /// window is too small.
    Offline,
}

/// Where the stream stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StreamState {
    Open,
    Ended,
    Failed,
}

/// The window: a preallocated ring of elements [tail, end) by their index from the
/// start of the path, filled from the producer's queue.
struct Window {
    segs: Vec<Segment>,
    geoms: Vec<Geom>,
    mask: usize,
    tail: usize,
    end: usize,
    rx: Receiver<Msg>,
    state: StreamState,
    blocking: bool,
}

impl Window {
    /// Take the next message, waiting for it if `wait`: false if none came.
    fn take_one(&mut self, wait: bool) -> bool {
        let msg = if wait {
            self.rx.recv().map_err(|_| TryRecvError::Disconnected)
        } else {
            self.rx.try_recv()
        };
        match msg {
            Ok(Msg::Element(s, g)) => {
                let i = self.end & self.mask;
                self.segs[i] = s;
                self.geoms[i] = g;
                self.end += 1;
                true
            }
            Ok(Msg::End) => {
                self.state = StreamState::Ended;
                false
            }
            Ok(Msg::Failed) | Err(TryRecvError::Disconnected) => {
                self.state = StreamState::Failed;
                false
            }
            Err(TryRecvError::Empty) => false,
        }
    }

    fn room(&self) -> bool {
        self.end - self.tail <= self.mask
    }

    /// Wait until the window is full or the stream has ended or failed.
    fn fill(&mut self) {
        while self.state == StreamState::Open && self.room() {
            self.take_one(true);
        }
    }
}

impl SegmentSource for Window {
    #[inline]
    fn seg(&self, k: usize) -> &Segment {
        &self.segs[k & self.mask]
    }
    #[inline]
    fn geom(&self, k: usize) -> &Geom {
        &self.geoms[k & self.mask]
    }
    fn has(&mut self, k: usize) -> bool {
        while k >= self.end {
            if self.state != StreamState::Open || !self.room() || !self.take_one(self.blocking) {
                return false;
            }
        }
        true
    }
    fn ended(&self) -> bool {
        self.state == StreamState::Ended
    }
    fn top_up(&mut self) {
        for _ in 0..TOP_UP_PER_SAMPLE {
            if self.state != StreamState::Open || !self.room() || !self.take_one(false) {
                break;
            }
        }
    }
    fn release_before(&mut self, k: usize) {
        self.tail = self.tail.max(k.min(self.end));
    }
}

/// The consuming end of a streamed plan: one [`Sample`] per call, as
/// [`Plan::interpolator`](crate::Plan::interpolator) gives them, from a bounded window
/// of elements. Allocates nothing after [`StreamInterpolator::fill`].
pub struct StreamInterpolator {
    core: Core<Window>,
}

impl StreamInterpolator {
    /// Wait until the window is full or the stream has ended (before the first
    /// sample; it may allocate). In [`StreamMode::RealTime`] a stream that was not
    /// filled first starts with [`StreamInterpolator::starved`] samples at the start.
    pub fn fill(&mut self) {
        self.core.src_mut().fill();
        self.core.prime();
    }

    /// Set the live feed override (as
    /// [`Interpolator::set_feed_override`](crate::Interpolator::set_feed_override)).
    pub fn set_feed_override(&mut self, fraction: f64) {
        self.core.set_feed_override(fraction)
    }

    /// The live feed override in force.
    pub fn feed_override(&self) -> f64 {
        self.core.feed_override()
    }

    /// Set the live rapid override (as
    /// [`Interpolator::set_rapid_override`](crate::Interpolator::set_rapid_override)).
    pub fn set_rapid_override(&mut self, fraction: f64) {
        self.core.set_rapid_override(fraction)
    }

    /// The live rapid override in force.
    pub fn rapid_override(&self) -> f64 {
        self.core.rapid_override()
    }

    /// Current path speed of the acceleration-limited profile (mm/s).
    pub fn path_speed_mm_per_s(&self) -> f64 {
        self.core.path_speed_mm_per_s()
    }

    /// True once the last sample has been produced.
    pub fn is_finished(&self) -> bool {
        self.core.is_finished()
    }

    /// Times the stream ran short of elements (0 while the producer keeps up): the
    /// lookahead found the end of the window where the whole plan would have looked
    /// further, the path waited at the end of the window for the next element, or a
    /// first sample came before any element. From the first such event on, the
    /// samples may differ from the whole plan's (slower, within every limit).
    pub fn starved(&self) -> u64 {
        self.core.starved()
    }

    /// True if the producer failed (its [`StreamProducer::run`] gives the error): the
    /// path stops at the end of what it got and the stream never finishes.
    pub fn failed(&self) -> bool {
        self.core.source().state == StreamState::Failed
    }

    /// Elements the window holds at most.
    pub fn window_segments(&self) -> usize {
        self.core.source().mask + 1
    }

    /// Go on from a pause (M0; M1 with the optional-stop switch on; a single-block
    /// stop): the path leaves the point it rests at with the next cycle. Nothing
    /// while not paused. The daemon's resume (cycle start) and step call it. A feed
    /// hold (override 0) is apart: resumed while held, the path stays at rest until
    /// the override rises; held while paused, it stays paused.
    pub fn resume(&mut self) {
        self.core.resume()
    }

    /// The source line the path is paused at, waiting for
    /// [`StreamInterpolator::resume`]: the M0/M1's line, or the line of the block
    /// single block stopped after. `None` while it is not paused (a feed hold is
    /// not a pause).
    pub fn paused_at_line(&self) -> Option<u32> {
        self.core.paused().map(|(_, line)| line)
    }

    /// Why the path is paused ([`StopKind::Program`], [`StopKind::Optional`] or
    /// [`StopKind::Block`]); `None` while it is not.
    pub fn pause_kind(&self) -> Option<StopKind> {
        self.core.paused().map(|(kind, _)| kind)
    }

    /// The index (into the program's motions) of the machine operation the path
    /// stands at, waiting for [`StreamInterpolator::release_machine_stop`]
    /// ([`PlanOptions::wait_at_machine_stops`](crate::PlanOptions::wait_at_machine_stops));
    /// the samples meanwhile carry this index. `None` while it does not wait there.
    pub fn machine_stop(&self) -> Option<u32> {
        self.core.machine_stop()
    }

    /// Go on from the machine stop the path waits at (its dwell, if any, then the
    /// next element with the next cycle). Nothing while it does not wait at one.
    pub fn release_machine_stop(&mut self) {
        self.core.release_machine_stop()
    }

    /// Single block on or off, live (the daemon's step mode). On: the path comes to
    /// rest at the first block end it can still stop at within its limits (at the
    /// feed it runs, braking as for any stop; an end too close to stop at is passed),
    /// and at every block end after it, and waits there for
    /// [`StreamInterpolator::resume`]. A block end inside a blended corner is the end
    /// of the first move's trimmed element: on the block's own programmed line, where
    /// the blend into the next begins; with [`PlanOptions::single_block`] from the start every
    /// block ends in an exact stop at its programmed end. Off: block ends are passed
    /// (a pause the path waits in already still waits for its resume).
    pub fn set_single_block(&mut self, on: bool) {
        self.core.set_single_block(on)
    }

    /// Whether single block is on.
    pub fn single_block(&self) -> bool {
        self.core.single_block()
    }
}

impl Iterator for StreamInterpolator {
    type Item = Sample;

    fn next(&mut self) -> Option<Sample> {
        self.core.next_sample()
    }
}

/// The two ends of a streamed plan of `text`, which `checked` is the
/// [`check_program`] of (with the same profile and options): run the producer on a
/// thread of its own, [`fill`](StreamInterpolator::fill) the interpolator, then pull
/// samples. Everything the interpolator needs is allocated here.
pub fn stream_program(
    text: Arc<str>,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    checked: &CheckedProgram,
    mode: StreamMode,
) -> (StreamProducer, StreamInterpolator) {
    let (tx, rx) = sync_channel(STREAM_QUEUE_ELEMENTS);
    let n = stream_window_segments(options);
    let blank = Segment {
        s0: 0.0,
        len: 0.0,
        motion: 0,
        feed_move: false,
        feed_mm_per_s: 0.0,
        vel_cap: 0.0,
        acc: 1.0,
        v_end_hard: 0.0,
        dwell_s: 0.0,
        line: 0,
        stop: StopKind::None,
        block_end: false,
        machine: false,
        pause_motion: 0,
    };
    let window = Window {
        segs: vec![blank; n],
        geoms: vec![
            Geom::Line {
                start: Vec3::ZERO,
                end: Vec3::ZERO,
                from: 0.0,
                to: 0.0,
                prog_len: 0.0,
            };
            n
        ],
        mask: n - 1,
        tail: 0,
        end: 0,
        rx,
        state: StreamState::Open,
        blocking: mode == StreamMode::Offline,
    };
    let mut core = Core::new(
        window,
        Limits::from_profile(profile),
        checked.brake_dist_mm,
        checked.max_override,
        checked.start_mm,
    );
    core.set_single_block(options.single_block);
    core.set_wait_at_program_stops(options.wait_at_program_stops);
    core.set_wait_at_machine_stops(options.wait_at_machine_stops);
    let producer = StreamProducer {
        text,
        file: file.to_string(),
        profile: profile.clone(),
        options: options.clone(),
        tx,
    };
    (producer, StreamInterpolator { core })
}

/// Check `text`, then stream it offline ([`StreamMode::Offline`]): the producer on a
/// scoped thread, `consume` given the filled interpolator on this one. The samples
/// are the whole plan's, in the window's memory. Gives the check's error, or the
/// check and what `consume` returned.
pub fn check_and_stream<R>(
    text: &str,
    file: &str,
    profile: &MotionProfile,
    options: &PlanOptions,
    consume: impl FnOnce(&mut StreamInterpolator) -> R,
) -> Result<(CheckedProgram, R), ReadPlanError> {
    let (_, checked) = check_program(text, file, profile, options)?;
    let (producer, mut it) = stream_program(
        Arc::from(text),
        file,
        profile,
        options,
        &checked,
        StreamMode::Offline,
    );
    let r = std::thread::scope(|scope| {
        let produced = scope.spawn(move || producer.run());
        it.fill();
        let r = consume(&mut it);
        drop(it); // a consumer that stopped early releases the producer
        produced
            .join()
            .unwrap_or_else(|e| std::panic::resume_unwind(e))
            .map(|()| r)
    })?;
    Ok((checked, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The adaptive rule works fillets out ahead only with the planner behind, having
    /// progressed while the reader read the chunk; the others as they say.
    #[test]
    fn fillets_ahead_only_while_both_threads_run_and_the_planner_is_behind() {
        let w = FilletsAheadWhen::PlannerBehind;
        let (q, b) = (AHEAD_QUEUED_CHUNKS, AHEAD_PARALLEL_MOTIONS);
        assert!(w.works(q, b));
        assert!(!w.works(q - 1, b), "planner not behind");
        assert!(!w.works(q, b - 1), "planner hardly built meanwhile");
        assert!(FilletsAheadWhen::Always.works(0, 0));
        assert!(!FilletsAheadWhen::Never.works(8, READ_CHUNK_MOTIONS));
    }

    /// `check_program_parallel` with the fillets worked out ahead for every chunk, for
    /// none and while the planner is behind: the figures of `check_program` bit for
    /// bit, on line–arc and arc–line joins among G64 Q chains, dwells, pauses, exact
    /// stops and tolerance changes, over many chunks, in both feed profiles and single
    /// block.
    #[test]
    fn handoff_waits_stop_looking_after_looks_that_run_out() {
        let mut w = HandoffWait::default();
        // a look that finds progress: the next wait looks again
        w.wait(|| true);
        assert_eq!((w.skip, w.next_skip), (0, 0));
        // a look that runs out: the next 8 waits sleep at once (no look: `ready` is
        // not asked), then a look, and after it runs out 16
        w.wait(|| false);
        assert_eq!(w.skip, SPIN_SKIP_FIRST_WAITS);
        for _ in 0..SPIN_SKIP_FIRST_WAITS {
            w.wait(|| panic!("looked while skipping"));
        }
        assert_eq!(w.skip, 0);
        w.wait(|| false);
        assert_eq!(w.skip, 2 * SPIN_SKIP_FIRST_WAITS);
        // the skips stop doubling at the most
        for _ in 0..20 {
            while w.skip > 0 {
                w.wait(|| panic!("looked while skipping"));
            }
            w.wait(|| false);
        }
        assert_eq!(w.skip, SPIN_SKIP_MAX_WAITS);
        // a look that finds progress starts over at the first skip
        while w.skip > 0 {
            w.wait(|| panic!("looked while skipping"));
        }
        w.wait(|| true);
        assert_eq!(w.next_skip, 0);
        w.wait(|| false);
        assert_eq!(w.skip, SPIN_SKIP_FIRST_WAITS);
    }

    #[test]
    fn a_look_ends_at_progress_or_after_its_time() {
        assert!(spin_until(|| true));
        let start = std::time::Instant::now();
        assert!(!spin_until(|| false));
        assert!(start.elapsed() >= HANDOFF_SPIN);
    }

    /// A program whose moves all have zero length (or that has none) streams and
    /// plans samples where the machine stands, never at the origin (issue 34: an
    /// MDI `G0 X5` at X5 stepped the machine to machine zero).
    #[test]
    fn a_path_without_elements_holds_where_the_machine_stands() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
        let p = MotionProfile::load(&dir.join("default.ron")).unwrap();
        let at = [5.0, 7.0, -3.0];
        let opts = PlanOptions {
            start_mm: Some(at),
            ..Default::default()
        };
        // (an M3 is a machine stop: one standing element; M2 stops the spindle
        // it started: a second)
        for (text, elements) in [
            ("G90 G0 X5 Y7 Z-3\nG1 X5 F300\nM2\n", 0),
            ("G92 X1\nM2\n", 0),
            ("M3 S100\nM2\n", 2),
        ] {
            let (checked, samples) = check_and_stream(text, "z.ngc", &p, &opts, |it| {
                it.map(|s| s.pos_mm).collect::<Vec<_>>()
            })
            .unwrap();
            assert_eq!(checked.elements(), elements, "{text:?}");
            assert!(!samples.is_empty(), "{text:?}");
            for pos in samples {
                assert_eq!(pos, Vec3(at), "{text:?}");
            }
            let (program, _) =
                softnc_gcode::read_program_with(text, "z.ngc", &p, &opts.read_options()).unwrap();
            let plan = crate::plan(&program, &p, &opts).unwrap();
            for s in plan.interpolator() {
                assert_eq!(s.pos_mm, Vec3(at), "{text:?}");
            }
        }
    }

    /// The motions' ends are in machine coordinates (the work offset added), a
    /// motion that moves nothing ends where the last one did, and in exact stop
    /// every motion's last sample stands on its end (within the 10 µm one cycle
    /// of 1 ms covers at 600 mm/min: the next sample is the next motion's).
    #[test]
    fn the_motions_ends_are_where_their_samples_end() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
        let p = MotionProfile::load(&dir.join("default.ron")).unwrap();
        let opts = PlanOptions::default();
        let text = "G21 G90 G61\nG10 L2 P1 X10 Y-5\nG54 G0 X1 Y2 Z3\nG4 P0.05\nG1 X5 F600\nG2 X9 Y6 R4\nM2\n";
        let (_, ends) = stream_sequencer_and_ends(
            text,
            "e.ngc",
            &p,
            &opts,
            crate::machine_sequencer::SequencerConfig {
                cycle_s: p.interpolation_cycle_s,
                spindle_at_speed_timeout_s: 0.0,
                user_m_timeout_s: 0.0,
            },
            crate::machine_sequencer::SequencerState::default(),
        )
        .unwrap();
        let (program, _) =
            softnc_gcode::read_program_with(text, "e.ngc", &p, &opts.read_options()).unwrap();
        assert_eq!(ends.len(), program.motions.len());
        let moving: Vec<[f64; 3]> = (0..ends.len() as u32)
            .filter(|&i| program.motions[i as usize].kind.end().is_some())
            .map(|i| ends.end_mm(i).unwrap())
            .collect();
        assert_eq!(
            moving,
            [[11.0, -3.0, 3.0], [15.0, -3.0, 3.0], [19.0, 1.0, 3.0]],
            "{ends:?}"
        );
        let dwell = program
            .motions
            .iter()
            .position(|m| matches!(m.kind, softnc_gcode::MotionKind::Dwell { .. }))
            .unwrap() as u32;
        assert_eq!(ends.end_mm(dwell), Some([11.0, -3.0, 3.0]));
        assert_eq!(ends.end_mm(ends.len() as u32), None);
        let plan = crate::plan(&program, &p, &opts).unwrap();
        let mut last: Vec<Option<Vec3>> = vec![None; ends.len()];
        for s in plan.interpolator() {
            last[s.motion as usize] = Some(s.pos_mm);
        }
        for (i, at) in last.iter().enumerate() {
            if let (Some(at), Some(_)) = (at, program.motions[i].kind.end()) {
                let end = ends.end_mm(i as u32).unwrap();
                assert!(
                    (0..3).all(|k| (at.0[k] - end[k]).abs() < 0.011),
                    "motion {i} ends its samples at {at:?}, not {end:?}"
                );
            }
        }
    }

    #[test]
    fn fillets_ahead_change_no_figure() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
        // (3,300 joins: more than 10,000 elements also with the smaller blends of
        // issue 36, 9,680 elements from 3,000 joins)
        let text = crate::test_programs::fillet_joins_program(3300, "M1", true, Some(400.0));
        for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
            for single_block in [false, true] {
                let mut p = MotionProfile::load(&dir.join("default.ron")).unwrap();
                p.planner.arc_blends = true;
                p.planner.feed_profile = fp;
                let opts = PlanOptions {
                    single_block,
                    ignore_soft_limits: true,
                    ..Default::default()
                };
                let key = |r: Result<(Program, CheckedProgram), ReadPlanError>| {
                    r.map(|(p, c)| (p.blocks, c))
                };
                let want = key(check_program(&text, "a.ngc", &p, &opts));
                let elements = want.as_ref().map(|(_, c)| c.elements);
                assert!(elements.is_ok_and(|n| n > 10_000), "{elements:?}");
                for when in [
                    FilletsAheadWhen::Always,
                    FilletsAheadWhen::Never,
                    FilletsAheadWhen::PlannerBehind,
                ] {
                    let got = key(check_program_parallel_with(
                        ProgramText::Str(&text),
                        "a.ngc",
                        &p,
                        &opts,
                        when,
                    ));
                    assert_eq!(got, want, "{fp:?}, single block {single_block}, {when:?}");
                }
            }
        }
    }
}
