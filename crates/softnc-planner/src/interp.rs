//! The interpolator: walks the segments at the interpolation cycle T.
//!
//! Path speed follows a time-optimal acceleration-limited profile computed in
//! continuous time (constant-acceleration pieces, switching exactly where they must,
//! also inside a cycle), so samples taken every T inherit its bounds. Each time it
//! enters an element or the override changes it looks ahead along the path as far as
//! the longest braking distance (bounded by [`MAX_LOOKAHEAD_SEGMENTS`]) to find how
//! fast it may leave the element. With the S-curve profile, the path position is
//! smoothed by a moving average of the acceleration-limited one over a fixed window
//! (a bell-shaped acc/dec, jerk ≤ 2·a/window), still along the exact path.

use crate::build::{Limits, Segment, StopKind};
use crate::path::Geom;
use softnc_core::{FeedProfile, Vec3};

/// Largest number of elements one lookahead pass visits. If the elements within the
/// braking distance are more than this, the planner assumes a stop after them
/// (safe, slower).
pub const MAX_LOOKAHEAD_SEGMENTS: usize = 20_000;
/// An arrival at a block end at most this fast is at rest there: single block
/// switched on mid-stream brakes to the block end through the feed pass, whose end
/// speed `sqrt(v² − 2·a·d)`, taken with v and d nearly 0 in the last braking cycle,
/// keeps a rounding residue (3e-6 mm/s measured on `tests/flow.rs`' zig-zag). Taking
/// it as 0 is a speed step of at most 1e-3 mm/s: 1e-6 mm in a 1 ms cycle, an
/// acceleration of 1 mm/s² over it, well inside the 1 % of every axis's limit
/// that the elements leave for tangent breaks.
pub const REST_SPEED_MM_PER_S: f64 = 1e-3;
/// Largest S-curve window in cycles (the ring is allocated once, before motion).
pub const MAX_SCURVE_WINDOW_CYCLES: usize = 4096;

/// One command sample at the interpolation cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Cycle index from the start of the job (time = index · T).
    pub index: u64,
    /// Command position, machine coordinates (mm).
    pub pos_mm: Vec3,
    /// Index into the program's motions of the motion being executed.
    pub motion: u32,
    /// True while that motion is a feed move (G1/G2/G3), false for traverses/dwells.
    pub feed_move: bool,
    /// Distance along the planned path from its start (mm): the job's progress.
    pub path_mm: f64,
}

/// Where the interpolator finds the path elements, by their index from the start of
/// the path: a whole plan's arrays ([`SliceSource`]), or the window of a streamed
/// plan ([`crate::stream`]), which holds the elements between the output cursor and
/// what the producer has delivered.
pub(crate) trait SegmentSource {
    /// Element `k`'s limits (`k` must be available: [`SegmentSource::has`]).
    fn seg(&self, k: usize) -> &Segment;
    /// Element `k`'s geometry (`k` must be available).
    fn geom(&self, k: usize) -> &Geom;
    /// Whether element `k` is available, taking in what has been delivered.
    fn has(&mut self, k: usize) -> bool;
    /// True once no element beyond the available ones will ever come: the path ends
    /// with the last available one.
    fn ended(&self) -> bool;
    /// Elements before `k` will not be asked for again.
    fn release_before(&mut self, _k: usize) {}
    /// Take in some of what has been delivered (once per sample), so that the
    /// lookahead finds it when it looks further.
    fn top_up(&mut self) {}
}

/// A whole plan's elements.
pub(crate) struct SliceSource<'a> {
    segs: &'a [Segment],
    geoms: &'a [Geom],
}

impl SegmentSource for SliceSource<'_> {
    fn seg(&self, k: usize) -> &Segment {
        &self.segs[k]
    }
    fn geom(&self, k: usize) -> &Geom {
        &self.geoms[k]
    }
    fn has(&mut self, k: usize) -> bool {
        k < self.segs.len()
    }
    fn ended(&self) -> bool {
        true
    }
}

/// Pulls samples from a plan, one per interpolation cycle, without allocating.
pub struct Interpolator<'a> {
    core: Core<SliceSource<'a>>,
}

/// The interpolator over any [`SegmentSource`]: the whole plan's and the streamed
/// plan's sample streams are this same code, so they are equal bit for bit whenever
/// the stream delivers the elements the lookahead asks for.
pub(crate) struct Core<S> {
    src: S,
    lim: Limits,
    brake_dist_mm: f64,
    override_frac: f64,
    max_override: f64,
    /// The live rapid override (0..=1): traverses run at this fraction of their
    /// speed limit, as LinuxCNC's `rapid_scale` (feed moves at the feed override).
    rapid_frac: f64,
    // acceleration-limited ("raw") state
    k: usize,
    s: f64,
    v: f64,
    hold_left_s: f64,
    holding: bool,
    raw_done: bool,
    vend_soft: f64,
    vend_hard: f64,
    envelope_dirty: bool,
    force_brake: bool,
    // S-curve smoothing ring over the raw path position
    ring: Vec<f64>,
    ring_pos: usize,
    // output cursor
    cursor: usize,
    index: u64,
    finished: bool,
    start: Vec3,
    /// Set once the first sample's element is known (at once for a whole plan).
    primed: bool,
    /// Waiting at the end of the last delivered element for the next one.
    waiting: bool,
    /// Times the path ran short: a lookahead cut by the end of the delivered elements,
    /// a wait for the next one, or a first sample without any.
    starved: u64,
    /// At rest at the end of element `k`, waiting for [`Core::resume`] (M0, M1,
    /// single block), and why.
    paused: Option<StopKind>,
    /// The rest of this cycle stands (a sync: the next element starts with the
    /// next cycle).
    cycle_done: bool,
    /// Single block, live: the path stops at every block end it can still stop at
    /// and waits there.
    single_block: bool,
    /// M0/M1 wait for [`Core::resume`] (else they rest and go on, as a sync).
    stops_wait: bool,
    /// Machine stops wait for [`Core::release_machine_stop`] (else the path rests
    /// there and goes on).
    machine_stops_wait: bool,
    /// Standing on the machine stop element `k`, waiting for
    /// [`Core::release_machine_stop`].
    machine_wait: bool,
}

impl<'a> Interpolator<'a> {
    pub(crate) fn new(
        segs: &'a [Segment],
        geoms: &'a [Geom],
        lim: Limits,
        brake_dist_mm: f64,
        max_override: f64,
        start_mm: Option<Vec3>,
    ) -> Self {
        // a path without an element holds where the machine stands (never at a
        // default origin: that is a step of up to the whole travel)
        let start = geoms
            .first()
            .map(|g| g.point_at(0.0))
            .or(start_mm)
            .unwrap_or_default();
        let mut core = Core::new(
            SliceSource { segs, geoms },
            lim,
            brake_dist_mm,
            max_override,
            start,
        );
        core.prime();
        Interpolator { core }
    }

    /// Set the live feed override (0.0 ..= the profile's maximum); applied smoothly
    /// from the next cycle on, within the acceleration (and jerk) limits.
    pub fn set_feed_override(&mut self, fraction: f64) {
        self.core.set_feed_override(fraction)
    }

    /// The live feed override in force.
    pub fn feed_override(&self) -> f64 {
        self.core.override_frac
    }

    /// Set the live rapid override (0.0 ..= 1.0): traverses run at this fraction of
    /// their speed limit (feed moves keep the feed override), applied as the feed
    /// override is: from the next cycle on, within the acceleration (and jerk)
    /// limits.
    pub fn set_rapid_override(&mut self, fraction: f64) {
        self.core.set_rapid_override(fraction)
    }

    /// The live rapid override in force.
    pub fn rapid_override(&self) -> f64 {
        self.core.rapid_frac
    }

    /// Current path speed of the acceleration-limited profile (mm/s).
    pub fn path_speed_mm_per_s(&self) -> f64 {
        self.core.v
    }

    /// True once the last sample has been produced.
    pub fn is_finished(&self) -> bool {
        self.core.finished
    }

    /// The core, to set it up.
    pub(crate) fn core_mut(&mut self) -> &mut Core<SliceSource<'a>> {
        &mut self.core
    }

    /// Go on from a pause (M0, M1, a single-block stop); see
    /// [`StreamInterpolator::resume`](crate::StreamInterpolator::resume).
    pub fn resume(&mut self) {
        self.core.resume()
    }

    /// The source line the path is paused at (waiting for [`Interpolator::resume`]).
    pub fn paused_at_line(&self) -> Option<u32> {
        self.core.paused().map(|(_, line)| line)
    }

    /// Why the path is paused.
    pub fn pause_kind(&self) -> Option<StopKind> {
        self.core.paused().map(|(kind, _)| kind)
    }

    /// The machine operation the path waits at; see
    /// [`StreamInterpolator::machine_stop`](crate::StreamInterpolator::machine_stop).
    pub fn machine_stop(&self) -> Option<u32> {
        self.core.machine_stop()
    }

    /// Go on from a machine stop; see
    /// [`StreamInterpolator::release_machine_stop`](crate::StreamInterpolator::release_machine_stop).
    pub fn release_machine_stop(&mut self) {
        self.core.release_machine_stop()
    }

    /// Single block on or off, live; see
    /// [`StreamInterpolator::set_single_block`](crate::StreamInterpolator::set_single_block).
    pub fn set_single_block(&mut self, on: bool) {
        self.core.set_single_block(on)
    }

    /// Whether single block is on.
    pub fn single_block(&self) -> bool {
        self.core.single_block()
    }
}

impl Iterator for Interpolator<'_> {
    type Item = Sample;

    #[inline]
    fn next(&mut self) -> Option<Sample> {
        self.core.next_sample()
    }
}

impl<S: SegmentSource> Core<S> {
    /// A sample stream from the start of the path; `start` is where the path starts
    /// (its first sample when it has no element). Call [`Core::prime`] before the first
    /// sample once the first element is there (else the first sample waits for it).
    pub(crate) fn new(
        src: S,
        lim: Limits,
        brake_dist_mm: f64,
        max_override: f64,
        start: Vec3,
    ) -> Self {
        let window = match lim.profile {
            FeedProfile::Trapezoidal => 1,
            FeedProfile::SCurve => ((lim.scurve_window_s / lim.cycle_s).round() as usize)
                .clamp(1, MAX_SCURVE_WINDOW_CYCLES),
        };
        Core {
            src,
            lim,
            brake_dist_mm,
            override_frac: 1.0,
            max_override,
            rapid_frac: 1.0,
            k: 0,
            s: 0.0,
            v: 0.0,
            hold_left_s: 0.0,
            holding: false,
            raw_done: false,
            vend_soft: 0.0,
            vend_hard: 0.0,
            envelope_dirty: true,
            force_brake: false,
            ring: vec![0.0; window],
            ring_pos: 0,
            cursor: 0,
            index: 0,
            finished: false,
            start,
            primed: false,
            waiting: false,
            starved: 0,
            paused: None,
            cycle_done: false,
            single_block: false,
            stops_wait: false,
            machine_stops_wait: false,
            machine_wait: false,
        }
    }

    /// Whether machine stops wait for [`Core::release_machine_stop`] (see
    /// [`PlanOptions::wait_at_machine_stops`](crate::PlanOptions::wait_at_machine_stops)).
    pub(crate) fn set_wait_at_machine_stops(&mut self, on: bool) {
        self.machine_stops_wait = on;
    }

    /// The motion index of the machine operation the path waits at.
    pub(crate) fn machine_stop(&self) -> Option<u32> {
        self.machine_wait.then(|| self.src.seg(self.k).motion)
    }

    /// Go on from the machine stop the path waits at: its dwell, then the next
    /// element. Nothing while not waiting at one.
    pub(crate) fn release_machine_stop(&mut self) {
        if self.machine_wait {
            self.machine_wait = false;
            let seg = *self.src.seg(self.k);
            self.rest_or_leave(&seg);
        }
    }

    /// Whether M0/M1 wait for [`Core::resume`] (see
    /// [`PlanOptions::wait_at_program_stops`](crate::PlanOptions::wait_at_program_stops)).
    pub(crate) fn set_wait_at_program_stops(&mut self, on: bool) {
        self.stops_wait = on;
    }

    /// Go on from a pause (M0, M1, single block): the next element starts with the
    /// next cycle. Nothing while not paused.
    pub(crate) fn resume(&mut self) {
        if self.paused.take().is_some() {
            self.next_element();
            self.skip_empty();
        }
    }

    /// Why and at which source line the path waits for [`Core::resume`].
    pub(crate) fn paused(&self) -> Option<(StopKind, u32)> {
        self.paused.map(|k| (k, self.src.seg(self.k).line))
    }

    /// Single block on or off. On: the path stops at the first block end it can
    /// still stop at within its limits, and at every one after it, and waits for
    /// [`Core::resume`] there; off: it goes on through block ends (a pause it
    /// waits in already still waits).
    pub(crate) fn set_single_block(&mut self, on: bool) {
        if on != self.single_block {
            self.single_block = on;
            self.envelope_dirty = true;
        }
    }

    /// Whether single block is on.
    pub(crate) fn single_block(&self) -> bool {
        self.single_block
    }

    /// Whether the path, at rest at the end of `seg`, waits there: M0, M1, and
    /// block ends while single block is on.
    fn waits_at(&self, seg: &Segment) -> Option<StopKind> {
        match seg.stop {
            StopKind::Program | StopKind::Optional if self.stops_wait => Some(seg.stop),
            StopKind::Block if self.single_block => Some(StopKind::Block),
            StopKind::None
                if self.single_block && seg.block_end && self.v <= REST_SPEED_MM_PER_S =>
            {
                Some(StopKind::Block)
            }
            _ => None,
        }
    }

    /// At rest at the end of element `k` (after its dwell): wait, stand out the
    /// cycle (sync), or go on.
    fn leave(&mut self) {
        let seg = *self.src.seg(self.k);
        if let Some(kind) = self.waits_at(&seg) {
            self.paused = Some(kind);
            self.v = 0.0;
            return;
        }
        if seg.stop != StopKind::None || seg.machine {
            // a sync, a machine stop, or a stop that does not wait: on with the next
            // cycle (a sample stands at the point)
            self.cycle_done = true;
        }
        self.next_element();
        self.skip_empty();
    }

    /// Take the first element if it is there (or the path is known to be empty):
    /// true once done. Before it, the first sample waits at the start.
    pub(crate) fn prime(&mut self) -> bool {
        if !self.primed {
            if self.src.has(0) {
                self.primed = true;
                self.skip_empty();
            } else if self.src.ended() {
                self.primed = true;
                self.raw_done = true;
            }
        }
        self.primed
    }

    /// The element source.
    pub(crate) fn source(&self) -> &S {
        &self.src
    }

    /// The element source, to fill it.
    pub(crate) fn src_mut(&mut self) -> &mut S {
        &mut self.src
    }

    /// Times the path ran short (see the field).
    pub(crate) fn starved(&self) -> u64 {
        self.starved
    }

    /// Set the live feed override (see [`Interpolator::set_feed_override`]).
    pub(crate) fn set_feed_override(&mut self, fraction: f64) {
        let f = if fraction.is_finite() {
            fraction.clamp(0.0, self.max_override)
        } else {
            0.0
        };
        if f != self.override_frac {
            self.override_frac = f;
            self.envelope_dirty = true;
        }
    }

    /// The live feed override in force.
    pub(crate) fn feed_override(&self) -> f64 {
        self.override_frac
    }

    /// Current path speed of the acceleration-limited profile (mm/s).
    pub(crate) fn path_speed_mm_per_s(&self) -> f64 {
        self.v
    }

    /// True once the last sample has been produced.
    pub(crate) fn is_finished(&self) -> bool {
        self.finished
    }

    /// The element's speed under the overrides: a feed move's feed times the feed
    /// override; a traverse's speed limit times the rapid override (LinuxCNC's
    /// `control.c`: `rapid_scale` for `EMC_MOTION_TYPE_TRAVERSE`, `feed_scale` else),
    /// never above the element's limit. A feed override of 0 is softnc's feed hold
    /// (the daemon holds so): it stops traverses too, as LinuxCNC's feed hold does
    /// (`net_feed_scale` 0); before, a traverse's infinite feed times 0 made NaN and
    /// the traverse ran through the hold.
    fn soft_cap(&self, seg: &Segment) -> f64 {
        if self.override_frac == 0.0 {
            return 0.0;
        }
        let cap = seg.vel_cap.min(seg.feed_mm_per_s * self.override_frac);
        if seg.feed_move || self.rapid_frac >= 1.0 {
            cap
        } else if self.rapid_frac > 0.0 {
            cap.min(seg.vel_cap * self.rapid_frac)
        } else {
            0.0
        }
    }

    /// Set the live rapid override (0.0 ..= 1.0; see [`Core::soft_cap`]).
    pub(crate) fn set_rapid_override(&mut self, fraction: f64) {
        let f = if fraction.is_finite() {
            fraction.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if f != self.rapid_frac {
            self.rapid_frac = f;
            self.envelope_dirty = true;
        }
    }

    /// The live rapid override in force.
    pub(crate) fn rapid_override(&self) -> f64 {
        self.rapid_frac
    }

    /// Skip zero-length elements without a dwell at the current position.
    fn skip_empty(&mut self) {
        while !self.raw_done
            && !self.waiting
            && self.src.seg(self.k).len <= 0.0
            && self.src.seg(self.k).dwell_s <= 0.0
            && self.src.seg(self.k).stop == StopKind::None
            && !self.src.seg(self.k).machine
        {
            self.next_element();
        }
    }

    fn next_element(&mut self) {
        if self.src.seg(self.k).v_end_hard == 0.0 {
            self.v = 0.0;
        }
        if self.src.has(self.k + 1) {
            self.k += 1;
            self.s = 0.0;
        } else if self.src.ended() {
            self.raw_done = true;
            self.s = self.src.seg(self.k).len;
            self.v = 0.0;
        } else {
            // the next element has not come: stand at the end of this one (the
            // lookahead braked to a stop there) until it does
            self.waiting = true;
            self.starved += 1;
            self.s = self.src.seg(self.k).len;
            self.v = 0.0;
        }
        self.envelope_dirty = true;
        self.force_brake = false;
    }

    /// Highest speeds at the end of element k: (with feed caps, geometric only). The
    /// end of the delivered elements counts as a stop (a starved lookahead).
    fn end_speed_limits(&mut self, k: usize) -> (f64, f64) {
        let mut j = k;
        let mut dist = 0.0;
        while self.src.seg(j).v_end_hard > 0.0
            && j - k < MAX_LOOKAHEAD_SEGMENTS
            && dist < self.brake_dist_mm
        {
            if !self.src.has(j + 1) {
                if !self.src.ended() {
                    self.starved += 1;
                }
                break;
            }
            j += 1;
            dist += self.src.seg(j).len;
        }
        // Backward pass from a stop at the end of element j.
        let mut soft_next = 0.0f64;
        let mut hard_next = 0.0f64;
        let mut m = j;
        let single_block = self.single_block;
        loop {
            let seg = self.src.seg(m);
            // single block: a block end is a stop for the feed (not a hard limit:
            // one the path cannot stop at any more is passed)
            let soft_end = if single_block && seg.block_end {
                0.0
            } else {
                seg.v_end_hard.min(soft_next).min(self.soft_cap(seg))
            };
            let hard_end = seg.v_end_hard.min(hard_next).min(seg.vel_cap);
            if m == k {
                return (soft_end, hard_end);
            }
            let two_al = 2.0 * seg.acc * seg.len;
            soft_next = self
                .soft_cap(seg)
                .min((soft_end * soft_end + two_al).sqrt());
            hard_next = seg.vel_cap.min((hard_end * hard_end + two_al).sqrt());
            m -= 1;
        }
    }

    /// Advance the acceleration-limited profile by `dt` seconds.
    #[allow(clippy::too_many_lines)]
    fn advance(&mut self, mut dt: f64) {
        let mut guard = 0u32;
        self.cycle_done = false;
        while dt > 0.0 && !self.raw_done {
            guard += 1;
            if guard > 1_000_000 {
                break; // cannot happen with finite inputs; never spin forever
            }
            if self.paused.is_some() || self.cycle_done || self.machine_wait {
                break; // standing: the rest of the cycle passes
            }
            if self.waiting {
                if !self.src.has(self.k + 1) {
                    if self.src.ended() {
                        self.waiting = false;
                        self.raw_done = true;
                    }
                    break; // standing: the cycle passes
                }
                self.waiting = false;
                self.k += 1;
                self.s = 0.0;
                self.envelope_dirty = true;
                self.force_brake = false;
                self.skip_empty();
                continue;
            }
            if self.holding {
                let h = self.hold_left_s.min(dt);
                self.hold_left_s -= h;
                dt -= h;
                if self.hold_left_s <= 0.0 {
                    self.holding = false;
                    self.leave();
                }
                continue;
            }
            if self.envelope_dirty {
                let (soft, hard) = self.end_speed_limits(self.k);
                self.vend_soft = soft;
                self.vend_hard = hard;
                self.envelope_dirty = false;
                self.force_brake = false;
            }
            let seg = *self.src.seg(self.k);
            let d = seg.len - self.s;
            if d <= 1e-12 {
                self.arrive(&seg);
                continue;
            }
            let a = seg.acc;
            let v = self.v;
            let cap = self.soft_cap(&seg);
            // End speed: the feed-capped one when reachable, else as low as braking
            // allows but never above the geometric limit.
            let reachable = (v * v - 2.0 * a * d).max(0.0).sqrt();
            let ve = self.vend_hard.min(self.vend_soft.max(reachable));
            // never aim above what accelerating over the rest of the element reaches
            let ve = ve.min((v * v + 2.0 * a * d).sqrt());
            let brake_d = (v * v - ve * ve) / (2.0 * a);
            if self.force_brake || d <= brake_d * (1.0 + 1e-9) + 1e-12 {
                // Braking to the end of the element.
                let a_req = if d > 0.0 {
                    ((v * v - ve * ve) / (2.0 * d)).max(0.0)
                } else {
                    0.0
                };
                let t_end = if v + ve > 0.0 {
                    2.0 * d / (v + ve)
                } else {
                    f64::INFINITY
                };
                if t_end <= dt {
                    dt -= t_end;
                    self.s = seg.len;
                    self.v = ve;
                    self.arrive(&seg);
                } else {
                    self.s += v * dt - 0.5 * a_req * dt * dt;
                    self.v = (v - a_req * dt).max(0.0);
                    dt = 0.0;
                }
                continue;
            }
            let tau;
            if v < cap {
                let vp = ((v * v + ve * ve) / 2.0 + a * d).sqrt();
                let vt = cap.min(vp);
                let t1 = ((vt - v) / a).max(0.0);
                tau = t1.min(dt);
                self.s += v * tau + 0.5 * a * tau * tau;
                self.v = if tau == t1 { vt } else { v + a * tau };
                if tau == t1 && vt == vp {
                    self.force_brake = true; // at the braking point
                }
            } else if v > cap {
                let t1 = (v - cap) / a;
                tau = t1.min(dt);
                self.s += v * tau - 0.5 * a * tau * tau;
                self.v = if tau == t1 { cap } else { v - a * tau };
            } else if v > 0.0 {
                let t1 = ((d - brake_d) / v).max(0.0);
                tau = t1.min(dt);
                self.s += v * tau;
                if tau == t1 {
                    self.force_brake = true; // at the braking point
                }
            } else {
                tau = dt; // feed hold at standstill
            }
            self.s = self.s.min(seg.len);
            dt -= tau;
        }
    }

    fn arrive(&mut self, seg: &Segment) {
        self.s = seg.len;
        if seg.machine && self.machine_stops_wait {
            // a machine stop: stand on it until released (its dwell after)
            self.machine_wait = true;
            self.v = 0.0;
            return;
        }
        self.rest_or_leave(seg);
    }

    /// At the end of `seg`: stand out its dwell (and the S-curve's settling where
    /// the path rests), then leave it.
    fn rest_or_leave(&mut self, seg: &Segment) {
        // at rest here: a stop of the path, or a block end single block stops at
        let rests = seg.v_end_hard == 0.0 || self.waits_at(seg).is_some();
        let hold = if rests {
            self.v = 0.0;
            let settle = match self.lim.profile {
                FeedProfile::SCurve => self.lim.scurve_window_s,
                FeedProfile::Trapezoidal => 0.0,
            };
            seg.dwell_s + settle
        } else {
            0.0
        };
        if hold > 0.0 {
            self.holding = true;
            self.hold_left_s = hold;
        } else {
            self.leave();
        }
    }

    fn raw_position(&self) -> f64 {
        let seg = self.src.seg(self.k);
        seg.s0 + self.s.min(seg.len)
    }

    /// The point at path position `s_path` and the element it lies on.
    fn point_at(&mut self, s_path: f64) -> (Vec3, u32, bool) {
        loop {
            let seg = self.src.seg(self.cursor);
            if !(s_path > seg.s0 + seg.len && self.src.has(self.cursor + 1)) {
                break;
            }
            self.cursor += 1;
        }
        let seg = self.src.seg(self.cursor);
        let pos = self.src.geom(self.cursor).point_at(s_path - seg.s0);
        (pos, seg.motion, seg.feed_move)
    }

    /// The next sample (see [`Interpolator`]'s `next`).
    pub(crate) fn next_sample(&mut self) -> Option<Sample> {
        if self.finished {
            return None;
        }
        if !self.prime() {
            // the first element has not come: the start, again
            self.starved += 1;
            return Some(Sample {
                index: 0,
                pos_mm: self.start,
                motion: 0,
                feed_move: false,
                path_mm: 0.0,
            });
        }
        if self.raw_done && self.index == 0 && !self.src.has(0) {
            self.finished = true;
            return Some(Sample {
                index: 0,
                pos_mm: self.start,
                motion: 0,
                feed_move: false,
                path_mm: 0.0,
            });
        }
        self.src.top_up();
        if self.index > 0 {
            self.advance(self.lim.cycle_s);
        }
        let raw = self.raw_position();
        let n = self.ring.len();
        let s_path = if n == 1 {
            raw
        } else {
            if self.index == 0 {
                self.ring.iter_mut().for_each(|x| *x = raw);
            }
            self.ring[self.ring_pos] = raw;
            self.ring_pos = (self.ring_pos + 1) % n;
            let sum: f64 = self.ring.iter().sum();
            // all equal (standing still): exactly that value, not a rounded mean
            if self.ring.iter().all(|&x| x == raw) {
                raw
            } else {
                (sum / n as f64).min(raw)
            }
        };
        let done_raw = self.raw_done && !self.holding;
        let settled = done_raw && (n == 1 || self.ring.iter().all(|&x| x == raw));
        let (pos, motion, feed_move, path_mm) = if settled {
            // raw_done: k is the last element
            let last = self.k;
            self.cursor = last;
            let seg = self.src.seg(last);
            (
                self.src.geom(last).point_at(seg.len),
                seg.motion,
                seg.feed_move,
                seg.s0 + seg.len,
            )
        } else if n == 1 {
            // trapezoidal: the point at the raw position within its element (from
            // the element's own start, so that a path run from line N gives the
            // uninterrupted plan's points bit for bit whatever lies before it)
            self.cursor = self.k;
            let seg = self.src.seg(self.k);
            (
                self.src.geom(self.k).point_at(self.s.min(seg.len)),
                seg.motion,
                seg.feed_move,
                s_path,
            )
        } else {
            let (pos, motion, feed_move) = self.point_at(s_path);
            (pos, motion, feed_move, s_path)
        };
        // standing at a machine stop or a pause: the samples carry the operation's
        // (the M0/M1's) own motion, so that its line is reported at once
        let motion = if self.machine_wait {
            self.src.seg(self.k).motion
        } else if self.paused.is_some() {
            self.src.seg(self.k).pause_motion
        } else {
            motion
        };
        let sample = Sample {
            index: self.index,
            pos_mm: pos,
            motion,
            feed_move,
            path_mm,
        };
        self.index += 1;
        if settled {
            self.finished = true;
        }
        self.src.release_before(self.cursor.min(self.k));
        Some(sample)
    }
}
