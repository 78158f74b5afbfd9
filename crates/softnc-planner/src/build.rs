//! From canonical motions to path segments: machine coordinates, blends at corners
//! (G64), exact stops (G61/G9), per-segment limits and junction speeds.

use crate::fillet::{self, ArcView};
use crate::path::{element_limits, max_to, min_to, ElementShape, Geom};
use softnc_core::{AccDec, FeedProfile, MotionProfile, Plane, Primitive, Vec3};
use softnc_gcode::{Motion, MotionKind, PathMode, Program};

/// Share of an axis's acceleration that a small tangent discontinuity between two
/// elements may use, per sample (trapezoidal; the S-curve profile stops at them).
/// The elements plan to the rest, `1 − KINK_SHARE`, so that a kink taken while the
/// path accelerates at its limit still keeps every sample within 1.000× (no blanket
/// margin: velocity and jerk are planned to 1.000× of the profile's limits).
pub const KINK_SHARE: f64 = 0.01;
/// S-curve: share of the jerk limit spent on tangential jerk.
pub const SCURVE_TANGENTIAL_JERK_SHARE: f64 = 0.4;
/// S-curve: share of the jerk limit spent on centripetal jerk terms on curves.
pub const SCURVE_CURVE_JERK_SHARE: f64 = 0.15;
/// S-curve: share of the jerk limit spent on a curvature step between elements
/// (sampled, so a step of Δa appears as ≤ Δa·3/(4T)).
pub const SCURVE_CURVATURE_STEP_SHARE: f64 = 0.25;
/// S-curve: a corner is blended only if the blend can be taken at this share of the
/// speed around it; otherwise the path stops at the corner.
pub const SCURVE_MIN_BLEND_SPEED_SHARE: f64 = 0.1;
/// Corners turning more than this (rad) are never blended: the path reverses.
pub const MAX_BLEND_TURN_RAD: f64 = 3.1;
/// Direction changes below this (in |Δt|) are treated as tangent-continuous.
pub const TANGENT_EPS: f64 = 1e-9;

/// S-curve: the speed at which the centripetal jerk terms on a curve use their share
/// of the jerk limit: κ²v³ ≤ budget and 3κ·v·a_t ≤ budget.
fn scurve_curve_cap(k: f64, lim: &Limits) -> f64 {
    if k <= 0.0 {
        return f64::INFINITY;
    }
    let j_min = lim.jmax.iter().cloned().fold(f64::INFINITY, f64::min);
    let budget = SCURVE_CURVE_JERK_SHARE * j_min;
    (budget / (k * k))
        .cbrt()
        .min(budget / (3.0 * k * lim.scurve_acc))
}

/// The smallest blend radius whose curvature caps still let it run at `v_mm_per_s`:
/// its centripetal acceleration κv² within `ARC_NORMAL_SHARE` of `acc_mm_per_s2` (the
/// blend's per-axis acceleration bound), and with the S-curve also its jerk terms
/// within their share ([`scurve_curve_cap`]: κ²v³ ≤ budget, 3κ·v·a_t ≤ budget).
/// Infinite where the speed is.
fn speed_radius_mm(lim: &Limits, v_mm_per_s: f64, acc_mm_per_s2: f64) -> f64 {
    let v = v_mm_per_s;
    let mut r = v * v / (crate::path::ARC_NORMAL_SHARE * acc_mm_per_s2);
    if lim.profile == FeedProfile::SCurve {
        let j_min = lim.jmax.iter().cloned().fold(f64::INFINITY, f64::min);
        let budget = SCURVE_CURVE_JERK_SHARE * j_min;
        r = r
            .max((v * v * v / budget).sqrt())
            .max(3.0 * v * lim.scurve_acc / budget);
    }
    r
}

/// The speed a line allows next to a corner: its feed and its axis velocity cap.
fn line_corner_speed(lim: &Limits, feed_mm_per_s: f64, dir: Vec3) -> f64 {
    element_limits(&ElementShape::line(1.0, dir), lim.vmax, lim.amax)
        .vel_mm_per_s
        .min(feed_mm_per_s)
}

/// The speed an arc of radius `radius_mm` allows next to a corner: its feed, the
/// fastest axis and its centripetal cap on the slowest axis's acceleration (an upper
/// bound of its own caps: the blend next to it needs no more).
fn arc_corner_speed(lim: &Limits, feed_mm_per_s: f64, radius_mm: f64) -> f64 {
    let v_top = lim.vmax.iter().cloned().fold(0.0, f64::max);
    let a_min = lim.amax.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut v = (crate::path::ARC_NORMAL_SHARE * a_min * radius_mm)
        .sqrt()
        .min(v_top)
        .min(feed_mm_per_s);
    if lim.profile == FeedProfile::SCurve && radius_mm > 0.0 {
        v = v.min(scurve_curve_cap(1.0 / radius_mm, lim));
    }
    v
}

/// The tolerance a fillet or biarc at a corner turning from `t_in` to `t_out` needs
/// for its speed (mm): the corner runs at most at the move before's feed and at the
/// slower of the two moves' own speeds (`cap_in`, `cap_out`: [`line_corner_speed`],
/// [`arc_corner_speed`]; the blend meets each at a junction no faster than it), v; a circular blend of the turn θ at that speed needs the
/// radius r = [`speed_radius_mm`] (on the slowest axis's acceleration: at least the
/// blend's own) and deviates r·(1/cos(θ/2) − 1) from the corner; the fillets and
/// biarcs keep within 0.9 of their tolerance, hence the 1/0.9. The program's or
/// profile's tolerance caps it ([`PathBuilder::blend`]).
fn speed_tolerance_mm(
    lim: &Limits,
    feed_in_mm_per_s: f64,
    t_in: Vec3,
    t_out: Vec3,
    cap_in: f64,
    cap_out: f64,
) -> f64 {
    let v = feed_in_mm_per_s.min(cap_in.min(cap_out));
    if !v.is_finite() {
        return f64::INFINITY;
    }
    let a_min = lim.amax.iter().cloned().fold(f64::INFINITY, f64::min);
    let r = speed_radius_mm(lim, v, a_min);
    let half = 0.5 * t_in.dot(t_out).clamp(-1.0, 1.0).acos();
    r * (1.0 / half.cos() - 1.0) / 0.9
}

/// S-curve: whether blending the corner between `a` and `b` at `through` (the
/// blend's curvature cap) costs less time than stopping there (acc/dec before
/// interpolation: an S-curve corner that is not blended is a stop). The blend's cap holds
/// on every element within its reach, in full (`dilate_caps`: an element has one
/// cap), so both moves run at `through` wherever that is below their own speed
/// (min(feed, slowest axis limit)): a rapid after a 10 mm/min feed, blended at
/// 0.057 mm/s, crawled its 96.5 mm for 1,690 s. Stopping costs the profile's wait
/// of one window plus braking from and accelerating back to each move's speed
/// (v/(2a) more than running through at v, each side).
fn scurve_blend_pays(
    lim: &Limits,
    a: &Pending,
    b: &Pending,
    found: &Blend,
    through_mm_per_s: f64,
    vmin_mm_per_s: f64,
) -> bool {
    let speed = |p: &Pending| p.feed_mm_per_s.min(vmin_mm_per_s);
    let crawl_s = |len_mm: f64, v: f64| {
        if through_mm_per_s < v {
            len_mm.max(0.0) * (1.0 / through_mm_per_s - 1.0 / v)
        } else {
            0.0
        }
    };
    let (v_a, v_b) = (speed(a), speed(b));
    let blend_cost_s = crawl_s(a.len - a.start_trim - found.end_trim_prev, v_a)
        + crawl_s(b.len - found.start_trim_next, v_b);
    let stop_cost_s = lim.scurve_window_s + (v_a + v_b) / (2.0 * lim.scurve_acc);
    blend_cost_s <= stop_cost_s
}

/// One element of the planned path with its limits (its geometry is kept apart, in
/// the same order, so that the passes over the limits touch less memory).
#[derive(Debug, Clone, Copy)]
pub struct Segment {
    /// Arc length at the start of this element from the start of the path (mm).
    pub s0: f64,
    /// Length (mm).
    pub len: f64,
    /// Index of the program motion this element belongs to.
    pub motion: u32,
    /// True for G1/G2/G3 (and their blends).
    pub feed_move: bool,
    /// Programmed feed (mm/s); infinite for traverses.
    pub feed_mm_per_s: f64,
    /// Hard speed limit on the element (axis velocities, curvature).
    pub vel_cap: f64,
    /// Tangential acceleration limit (mm/s²).
    pub acc: f64,
    /// Hard speed limit at the end (junction with the next element); 0 = stop.
    pub v_end_hard: f64,
    /// Time to stand still at the end (G4 dwell), s.
    pub dwell_s: f64,
    /// Source line of the motion this element belongs to (for a pause: the line
    /// of the M0/M1, or of the block that single block stops after).
    pub line: u32,
    /// What the path does once it has come to rest at the end (after any dwell).
    pub stop: StopKind,
    /// The element ends its block's last motion (the next motion comes from another
    /// line): where single block stops.
    pub block_end: bool,
    /// A machine stop: a zero-length element at the point of a machine operation
    /// that LinuxCNC's task waits for motion for (`MachineOp::stops_motion`);
    /// `motion` is the operation's index. The path comes to rest before it and, where
    /// the interpolator is told to wait at machine stops, stands on it until
    /// released (before its dwell).
    pub machine: bool,
    /// The motion the samples carry while the path waits at the end of this element
    /// for the operator (`stop`): the M0/M1's own index where one stops here, else
    /// `motion`.
    pub pause_motion: u32,
}

/// What the path does at the end of an element where it comes to rest.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum StopKind {
    /// Nothing: it goes on (after its dwell).
    #[default]
    None,
    /// M0: waits for the operator's resume.
    Program,
    /// M1 with the optional-stop switch on: waits for the operator's resume.
    Optional,
    /// Single block (`PlanOptions::single_block`): the end of a block; waits for
    /// the operator's resume (step) while single block is on.
    Block,
    /// Goes on at the next interpolation cycle (the end of run-from-line's
    /// approach, `MotionKind::Sync`).
    Sync,
}

/// The stop that wins where two meet at one point: one that waits for the operator
/// over a sync, M0 over M1 over single block.
fn stronger(a: StopKind, b: StopKind) -> StopKind {
    let rank = |k: StopKind| match k {
        StopKind::None => 0,
        StopKind::Sync => 1,
        StopKind::Block => 2,
        StopKind::Optional => 3,
        StopKind::Program => 4,
    };
    if rank(b) > rank(a) {
        b
    } else {
        a
    }
}

/// What the builder needs from the machine profile.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Per-axis velocity limits (mm/s).
    pub vmax: [f64; 3],
    /// Per-axis acceleration the elements plan to: the limit less the kinks' share
    /// (`1 − KINK_SHARE`) (mm/s²).
    pub amax: [f64; 3],
    /// Per-axis acceleration a kink may use over one cycle: `KINK_SHARE` of the
    /// limit (mm/s²).
    pub kink_acc: [f64; 3],
    /// Per-axis jerk limits (mm/s³).
    pub jmax: [f64; 3],
    /// Interpolation cycle T (s).
    pub cycle_s: f64,
    /// Default blend tolerance (mm).
    pub tolerance_mm: f64,
    /// Feed profile shape.
    pub profile: FeedProfile,
    /// Where acc/dec acts: after interpolation, tangent breaks pass at the feed.
    pub acc_dec: AccDec,
    /// Blend corners that involve arcs (`planner.arc_blends`).
    pub arc_blends: bool,
    /// Largest feed override (`planner.max_feed_override`): a feed move never runs
    /// faster than its feed times this.
    pub max_feed_override: f64,
    /// A bound on any element's path acceleration (mm/s²): the norm of the axes'
    /// limits (a line's min_i A_i/|u_i| is at most that, since Σ u_i² = 1).
    pub path_acc_bound_mm_per_s2: f64,
    /// S-curve only: global tangential acceleration (mm/s²).
    pub scurve_acc: f64,
    /// S-curve only: smoothing window (s).
    pub scurve_window_s: f64,
}

impl Limits {
    /// Limits of a machine profile.
    pub fn from_profile(p: &MotionProfile) -> Limits {
        let vmax = p.max_vel();
        let amax = p.max_acc().map(|a| a * (1.0 - KINK_SHARE));
        let kink_acc = p.max_acc().map(|a| a * KINK_SHARE);
        let jmax = p.max_jerk();
        let a_min = amax.iter().cloned().fold(f64::INFINITY, f64::min);
        let j_min = jmax.iter().cloned().fold(f64::INFINITY, f64::min);
        let scurve_acc = crate::path::ARC_TANGENTIAL_SHARE * a_min;
        // Moving average of length W on s(t): |s'''| ≤ 2·a/W.
        let w = 2.0 * scurve_acc / (SCURVE_TANGENTIAL_JERK_SHARE * j_min);
        let cycle_s = p.interpolation_cycle_s;
        let window = (w / cycle_s).ceil().max(1.0) * cycle_s;
        Limits {
            vmax,
            amax,
            kink_acc,
            jmax,
            cycle_s,
            tolerance_mm: p.planner.tolerance_mm,
            profile: p.planner.feed_profile,
            acc_dec: p.planner.acc_dec,
            arc_blends: p.planner.arc_blends,
            max_feed_override: p.planner.max_feed_override,
            path_acc_bound_mm_per_s2: p.max_acc().iter().map(|a| a * a).sum::<f64>().sqrt(),
            scurve_acc,
            scurve_window_s: window,
        }
    }

    /// The most an arc's tangent may turn away from its circle's for a fillet to
    /// touch it ([`ArcView::of`]): the angle the kink share passes at the axes' top
    /// speed (rad).
    pub(crate) fn max_drift_rad(&self) -> f64 {
        let kink = self.kink_acc.iter().cloned().fold(f64::INFINITY, f64::min);
        let v_top = Vec3::new(self.vmax[0], self.vmax[1], self.vmax[2]).norm();
        kink * self.cycle_s / v_top
    }
}

/// What the builder asks of a programmed arc at its joins that depends on the arc
/// and the limits alone: its end tangents (`PathBuilder::kink_at_speed`) and its
/// views from either end (`PathBuilder::circle_blend`). [`ArcPrep::of`] works them
/// out ahead, on the reading thread of `check_program_parallel` with `arc_blends`
/// (where the planning thread is the slower of the two), and
/// [`PathBuilder::push_prepared`] takes them; the same functions of the same
/// arguments, so the same bits as the builder's own.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ArcPrep {
    /// `arc_end_tangent` at the start.
    start_tangent: Vec3,
    /// `arc_end_tangent` at the end.
    end_tangent: Vec3,
    /// |end − centre| in the arc's plane, as [`ArcView::of`] computes it (mm).
    end_radius_mm: f64,
    /// `Primitive::length` (mm).
    len_mm: f64,
}

impl ArcPrep {
    /// The arc's data; None for a line (or no primitive).
    #[inline]
    pub(crate) fn of(prim: &Option<Primitive>) -> Option<ArcPrep> {
        let p = prim.as_ref()?;
        Some(ArcPrep {
            end_radius_mm: fillet::end_radius_mm(p)?,
            start_tangent: arc_end_tangent_inline(p, false),
            end_tangent: arc_end_tangent_inline(p, true),
            len_mm: p.length(),
        })
    }

    /// [`ArcView::of`] the arc `p` whose data this is.
    fn view(&self, p: &Primitive, at_end: bool, max_drift_rad: f64) -> Option<ArcView> {
        ArcView::of_measured(p, at_end, max_drift_rad, self.end_radius_mm, self.len_mm)
    }
}

/// A line–arc fillet worked out ahead ([`fillet::line_arc`] of the join between a
/// motion and the one before it, on the reading thread of `check_program_parallel`,
/// see [`FilletsAhead`]), keyed by the arguments of that call the builder may hold
/// otherwise. The builder takes it ([`FilletAhead::matching`]) only where those are
/// the same bits, so the path is the same as without it.
///
/// The key is what the builder's state can change: both shares (the move before the
/// corner gives at most what the blend at its start left of it,
/// `min_to(0.5·len, len − start_trim)`, where the reader can only take half), the
/// tolerance, and the corner. The direction and the arc's view are functions of the
/// two motions' primitives and arc data alone, worked out by the same code on both
/// threads (`line_len_dir` is `push_unmerged`'s arithmetic, [`ArcPrep::view`] the
/// builder's `view_next`), and the joins are the builder's (the same motions held as
/// [`PathBuilder::push_unmerged`] holds them, the corner their common point); debug
/// builds keep them too and assert that a fillet taken was worked out from the
/// builder's own bits. About 130 bytes, where the whole arguments and
/// [`fillet::Fillet`] took 320: the records cross from one core to the other.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FilletAhead {
    corner: Vec3,
    line_avail_mm: f64,
    arc_avail_mm: f64,
    tol_mm: f64,
    /// What `line_arc` gave (None: no fillet found).
    found: Option<FilletFound>,
    /// The direction and the arc's view it was worked out with (debug builds).
    #[cfg(debug_assertions)]
    rest: (Vec3, ArcView),
}

/// A [`fillet::Fillet`] without what the builder's own arguments give back bit for
/// bit ([`FilletFound::fillet`]): the point on the line (`corner − u·line_trim`, as
/// `line_arc_at` computes it), the components of the centre and of the point on the
/// arc along the plane's normal (the line point's and the arc centre's there), and
/// the arc trim (`arc_trim_rad·R`). Debug builds assert each fillet handed over
/// comes back so; `fillets_ahead_are_taken_where_their_arguments_are_the_builders`
/// compares the paths.
#[derive(Debug, Clone, Copy)]
struct FilletFound {
    line_trim: f64,
    arc_trim_rad: f64,
    /// The centre's components along the plane's first two axes.
    center_ab: (f64, f64),
    radius: f64,
    /// The point on the arc's components along the plane's first two axes.
    p_arc_ab: (f64, f64),
    sweep: f64,
    cos_sweep: f64,
    sin_sweep: f64,
}

impl FilletFound {
    /// `f` (`line_arc` of `corner`, `u` and `arc`) in short.
    fn of(f: &fillet::Fillet, arc: &ArcView) -> FilletFound {
        let (a, b, _) = arc.axes;
        FilletFound {
            line_trim: f.line_trim,
            arc_trim_rad: f.arc_trim_rad,
            center_ab: (f.center[a], f.center[b]),
            radius: f.radius,
            p_arc_ab: (f.p_arc[a], f.p_arc[b]),
            sweep: f.sweep,
            cos_sweep: f.cos_sweep,
            sin_sweep: f.sin_sweep,
        }
    }

    /// The whole fillet, given the arguments it was worked out from.
    fn fillet(&self, corner: Vec3, u: Vec3, arc: &ArcView) -> fillet::Fillet {
        let (a, b, _) = arc.axes;
        let p_line = corner - u * self.line_trim;
        let mut center = p_line;
        (center[a], center[b]) = self.center_ab;
        let mut p_arc = arc.center;
        (p_arc[a], p_arc[b]) = self.p_arc_ab;
        fillet::Fillet {
            line_trim: self.line_trim,
            arc_trim: self.arc_trim_rad * arc.radius,
            arc_trim_rad: self.arc_trim_rad,
            center,
            radius: self.radius,
            p_line,
            p_arc,
            sweep: self.sweep,
            cos_sweep: self.cos_sweep,
            sin_sweep: self.sin_sweep,
        }
    }
}

impl FilletAhead {
    /// The fillet found, if it was worked out from these arguments bit for bit
    /// (`Some(None)`: no fillet there); None where any argument of the key differs.
    fn matching(
        &self,
        corner: Vec3,
        u: Vec3,
        line_avail_mm: f64,
        arc: &ArcView,
        arc_avail_mm: f64,
        tol_mm: f64,
    ) -> Option<Option<fillet::Fillet>> {
        let same = |x: f64, y: f64| x.to_bits() == y.to_bits();
        let key = same(self.line_avail_mm, line_avail_mm)
            & same(self.arc_avail_mm, arc_avail_mm)
            & same(self.tol_mm, tol_mm)
            & same(self.corner[0], corner[0])
            & same(self.corner[1], corner[1])
            & same(self.corner[2], corner[2]);
        if !key {
            return None;
        }
        #[cfg(debug_assertions)]
        {
            let same3 = |x: Vec3, y: Vec3| same(x[0], y[0]) && same(x[1], y[1]) && same(x[2], y[2]);
            let (w, v) = &self.rest;
            assert!(
                same3(*w, u)
                    && same3(v.center, arc.center)
                    && same(v.radius, arc.radius)
                    && same3(v.normal, arc.normal)
                    && same(v.sense, arc.sense)
                    && same(v.len, arc.len)
                    && v.axes == arc.axes
                    && same(v.orient, arc.orient),
                "a fillet ahead keyed as the builder's own from other arguments"
            );
        }
        Some(self.found.map(|f| f.fillet(corner, u, arc)))
    }
}

/// One motion as [`FilletsAhead`] sees it: the motion, its primitive and arc data.
type AheadMove<'m> = (&'m Motion, &'m Option<Primitive>, &'m Option<ArcPrep>);

/// The reading thread's side of the fillets worked out ahead: it follows the motions as
/// [`PathBuilder::push_unmerged`] will hold them and works out the line–arc fillets of
/// a chunk's joins where asked ([`FilletsAhead::chunk`]). Joins whose moves it cannot
/// foresee (G64 Q chains, dwells, pauses, single block, zero-length moves) get none; a
/// fillet whose arguments turn out otherwise in the builder is not taken.
#[derive(Debug)]
pub(crate) struct FilletsAhead {
    /// The builder's limits (the speed a fillet needs, [`speed_tolerance_mm`]).
    lim: Limits,
    tolerance_mm: f64,
    max_drift_rad: f64,
    /// Single block: every block ends in an exact stop, no fillets.
    single_block: bool,
    /// The last motion of the chunk before, with its primitive and arc data.
    last: Option<(Motion, Option<Primitive>, Option<ArcPrep>)>,
}

impl FilletsAhead {
    /// For these limits and the single-block setting.
    pub(crate) fn new(lim: &Limits, single_block: bool) -> FilletsAhead {
        FilletsAhead {
            lim: *lim,
            tolerance_mm: lim.tolerance_mm,
            max_drift_rad: lim.max_drift_rad(),
            single_block,
            last: None,
        }
    }

    /// The chunk `motions` (with their primitives and arc data) follows the chunk
    /// last given; where `work` is set, the fillet of each line–arc or arc–line join
    /// ending at one of its motions goes to `out`, with the motion's index in the chunk.
    pub(crate) fn chunk(
        &mut self,
        motions: &[Motion],
        prims: &[Option<Primitive>],
        preps: &[Option<ArcPrep>],
        work: bool,
        out: &mut Vec<(u32, FilletAhead)>,
    ) {
        if work && !self.single_block {
            // each join's arguments in one slot, written in place
            let mut slot = AheadArgs::EMPTY;
            if let (Some((m, p, q)), Some(m1), Some(p1), Some(q1)) =
                (&self.last, motions.first(), prims.first(), preps.first())
            {
                if self.join((m, p, q), (m1, p1, q1), 0, &mut slot) {
                    slot.push(&slot.fillet(), out);
                }
            }
            for k in 1..motions.len().min(prims.len()).min(preps.len()) {
                if self.join(
                    (&motions[k - 1], &prims[k - 1], &preps[k - 1]),
                    (&motions[k], &prims[k], &preps[k]),
                    k,
                    &mut slot,
                ) {
                    slot.push(&slot.fillet(), out);
                }
            }
        }
        if let (Some(m), Some(p), Some(q)) = (motions.last(), prims.last(), preps.last()) {
            self.last = Some((*m, *p, *q));
        }
    }

    /// The blend tolerance of a move (with a primitive) that the builder holds as it
    /// comes and whether a blend may end it; None for what it takes otherwise (dwells,
    /// pauses, G64 Q lines and arcs).
    fn mode(&self, m: &Motion) -> Option<(bool, f64)> {
        if !matches!(
            m.kind,
            MotionKind::Traverse { .. } | MotionKind::Feed { .. } | MotionKind::Arc { .. }
        ) {
            return None;
        }
        match m.path_mode {
            PathMode::ExactStop => Some((false, self.tolerance_mm)),
            PathMode::Blend {
                naive_cam_mm: Some(q),
                ..
            } if q > 0.0 => None,
            PathMode::Blend { tolerance_mm, .. } => match tolerance_mm {
                Some(p) if p > 0.0 => Some((true, p)),
                _ => Some((true, self.tolerance_mm)),
            },
        }
    }

    /// The arguments of the fillet at the join of `a` and `b` (at index `k`) to
    /// `slot`, if a line meets an arc there and the builder will blend it: true then.
    fn join(
        &self,
        (ma, pa, qa): AheadMove,
        (mb, pb, qb): AheadMove,
        k: usize,
        slot: &mut AheadArgs,
    ) -> bool {
        let (Some(pa), Some(pb)) = (pa, pb) else {
            return false;
        };
        // (a line–line or arc–arc join: nothing to do, before any other test)
        if matches!(pa, Primitive::Line { .. }) == matches!(pb, Primitive::Line { .. }) {
            return false;
        }
        let (Some((true, tol_a)), Some((_, tol_b))) = (self.mode(ma), self.mode(mb)) else {
            return false;
        };
        // (no blend between a traverse and a feed move: the builder stops there)
        let traverse = |m: &Motion| matches!(m.kind, MotionKind::Traverse { .. });
        if traverse(ma) != traverse(mb) {
            return false;
        }
        let feed = |m: &Motion| match m.kind {
            MotionKind::Feed {
                feed_mm_per_min, ..
            }
            | MotionKind::Arc {
                feed_mm_per_min, ..
            } => feed_mm_per_min / 60.0,
            _ => f64::INFINITY,
        };
        let lim = &self.lim;
        let (feed_a, feed_b) = (feed(ma), feed(mb));
        let (corner, u, line_avail_mm, arc, arc_avail_mm, speed_tol) = match (pa, pb, qa, qb) {
            (&Primitive::Line { start, end }, Primitive::Arc { .. }, None, Some(q)) => {
                let Some((len_a, dir_a)) = line_len_dir(start, end) else {
                    return false;
                };
                if q.len_mm < 1e-9 {
                    return false;
                }
                let Some(view) = q.view(pb, false, self.max_drift_rad) else {
                    return false;
                };
                let speed_tol = speed_tolerance_mm(
                    lim,
                    feed_a,
                    dir_a,
                    q.start_tangent,
                    line_corner_speed(lim, feed_a, dir_a),
                    arc_corner_speed(lim, feed_b, arc_radius_mm(pb)),
                );
                (end, dir_a, 0.5 * len_a, view, 0.5 * q.len_mm, speed_tol)
            }
            (Primitive::Arc { .. }, &Primitive::Line { start, end }, Some(q), None) => {
                let Some((len_b, dir_b)) = line_len_dir(start, end) else {
                    return false;
                };
                if q.len_mm < 1e-9 {
                    return false;
                }
                let Some(view) = q.view(pa, true, self.max_drift_rad) else {
                    return false;
                };
                let speed_tol = speed_tolerance_mm(
                    lim,
                    feed_a,
                    q.end_tangent,
                    dir_b,
                    arc_corner_speed(lim, feed_a, arc_radius_mm(pa)),
                    line_corner_speed(lim, feed_b, dir_b),
                );
                (start, -dir_b, 0.5 * len_b, view, 0.5 * q.len_mm, speed_tol)
            }
            _ => return false,
        };
        let tol_mm = min_to(tol_a.min(tol_b), speed_tol);
        *slot = AheadArgs {
            k,
            corner,
            u,
            line_avail_mm,
            arc,
            arc_avail_mm,
            tol_mm,
        };
        true
    }
}

/// The arguments of a fillet worked out ahead.
struct AheadArgs {
    k: usize,
    corner: Vec3,
    u: Vec3,
    line_avail_mm: f64,
    arc: ArcView,
    arc_avail_mm: f64,
    tol_mm: f64,
}

impl AheadArgs {
    /// An empty slot.
    const EMPTY: AheadArgs = AheadArgs {
        k: 0,
        corner: Vec3::ZERO,
        u: Vec3::ZERO,
        line_avail_mm: 0.0,
        arc: ArcView {
            center: Vec3::ZERO,
            radius: 0.0,
            normal: Vec3::ZERO,
            sense: 0.0,
            len: 0.0,
            axes: (0, 1, 2),
            orient: 0.0,
        },
        arc_avail_mm: 0.0,
        tol_mm: 0.0,
    };

    /// [`fillet::line_arc`] of these arguments.
    fn fillet(&self) -> Option<fillet::Fillet> {
        fillet::line_arc(
            self.corner,
            self.u,
            self.line_avail_mm,
            &self.arc,
            self.arc_avail_mm,
            self.tol_mm,
        )
    }

    /// Its record, with the fillet `f` found for it (read where it was written).
    fn push(&self, f: &Option<fillet::Fillet>, out: &mut Vec<(u32, FilletAhead)>) {
        let (corner, u, arc) = (self.corner, self.u, &self.arc);
        let found = f.as_ref().map(|f| {
            let short = FilletFound::of(f, arc);
            debug_assert_eq!(
                format!("{f:?}"),
                format!("{:?}", short.fillet(corner, u, arc)),
                "a fillet in short gives it back"
            );
            short
        });
        out.push((
            self.k as u32,
            FilletAhead {
                corner,
                line_avail_mm: self.line_avail_mm,
                arc_avail_mm: self.arc_avail_mm,
                tol_mm: self.tol_mm,
                found,
                #[cfg(debug_assertions)]
                rest: (u, *arc),
            },
        ));
    }
}

/// A line's length and unit direction as `PathBuilder::push_unmerged` computes them;
/// None where it drops the line (shorter than 1e-9 mm).
fn line_len_dir(start: Vec3, end: Vec3) -> Option<(f64, Vec3)> {
    let d = end - start;
    let len = d.norm();
    let dir = if len > 0.0 {
        d * (1.0 / len)
    } else {
        Vec3::ZERO
    };
    (len >= 1e-9).then_some((len, dir))
}

/// A move in machine coordinates that waits for its successor: a blend at the corner
/// between them trims its end.
struct Pending {
    geom: Geom,
    /// Length of the programmed move (mm).
    len: f64,
    /// Unit direction (lines).
    dir: Vec3,
    motion: u32,
    feed_move: bool,
    feed_mm_per_s: f64,
    exact_stop: bool,
    tolerance_mm: f64,
    dwell_s: f64,
    /// Source line.
    line: u32,
    /// What happens once at rest at its end.
    stop: StopKind,
    /// Ends its block (set when the next motion comes from another line).
    block_end: bool,
    /// A machine stop ([`Segment::machine`]).
    machine: bool,
    /// [`Segment::pause_motion`].
    pause_motion: u32,
    /// Arc length taken from the start by the blend at the previous corner.
    start_trim: f64,
    /// Arcs: where the blend at the previous corner meets it (the sub-arc starts
    /// exactly there).
    start_at: Option<Vec3>,
    /// Arcs: the angle about the centre the fillet at the previous corner takes
    /// (rad; None for a biarc, whose sub-arc takes its angles from its points).
    start_trim_rad: Option<f64>,
}

impl Pending {
    /// A record to be written over ([`PathBuilder`]'s first boxes).
    fn placeholder() -> Pending {
        Pending {
            geom: Geom::Line {
                start: Vec3::ZERO,
                end: Vec3::ZERO,
                from: 0.0,
                to: 0.0,
                prog_len: 0.0,
            },
            len: 0.0,
            dir: Vec3::ZERO,
            motion: 0,
            feed_move: false,
            feed_mm_per_s: 0.0,
            exact_stop: false,
            tolerance_mm: 0.0,
            dwell_s: 0.0,
            line: 0,
            stop: StopKind::None,
            block_end: false,
            machine: false,
            pause_motion: 0,
            start_trim: 0.0,
            start_at: None,
            start_trim_rad: None,
        }
    }

    /// The end of the held move (its programmed end).
    fn end_point(&self) -> Vec3 {
        match &self.geom {
            Geom::Line { end, .. } => *end,
            Geom::Arc(prim) => prim.end(),
            g => g.point_at(self.len),
        }
    }
}

/// The path built so far: limits and geometry of every element, in order.
#[derive(Debug, Clone, Default)]
pub struct Path {
    /// Limits of each element.
    pub segs: Vec<Segment>,
    /// Geometry of each element (machine coordinates).
    pub geoms: Vec<Geom>,
    /// Programmed primitives of moves that left no element of their own (zero length,
    /// or a line used up by the blends at both its ends), by motion index.
    pub orphans: Vec<(u32, Primitive)>,
    /// Elements before the first move's (a dwell at the very start).
    pub lead_in: usize,
}

impl Path {
    /// The programmed primitive of motion `index` (None for dwells and unknown indices).
    pub fn motion_primitive(&self, index: usize) -> Option<Primitive> {
        let Ok(m) = u32::try_from(index) else {
            return None;
        };
        // orphans first: a G64 Q merged line is an element of the chain's last
        // motion, whose programmed line is an orphan
        if let Ok(k) = self.orphans.binary_search_by_key(&m, |o| o.0) {
            return Some(self.orphans[k].1);
        }
        let segs = &self.segs[self.lead_in..];
        let from = segs.partition_point(|s| s.motion < m);
        segs[from..]
            .iter()
            .zip(&self.geoms[self.lead_in + from..])
            .take_while(|(s, _)| s.motion == m)
            .find_map(|(s, g)| if s.machine { None } else { g.programmed() })
    }
}

/// Builds the path one motion at a time (blending, exact stops, limits and junction
/// speeds), holding back only the last move, whose end a blend may still trim.
pub struct PathBuilder {
    lim: Limits,
    path: Path,
    /// The last move, held back (boxed: a move's record goes from `spare` to here
    /// to `spare` again without being copied, about 250 bytes twice a move).
    pending: Option<Box<Pending>>,
    /// The record of the move emitted last, for the next move to be written into.
    spare: Option<Box<Pending>>,
    pending_dwell_at_start: f64,
    last_point: Option<Vec3>,
    s0: f64,
    /// End tangent of the last element pushed.
    prev_end_tangent: Vec3,
    /// How much of each axis's acceleration the last element pushed may use.
    prev_acc_use: AccUse,
    /// G64 Q: the G1 lines held back while they stay within Q of one line.
    chain: NaiveCamChain,
    /// Single block from the start (`PlanOptions::single_block`): every block
    /// ends in an exact stop that waits ([`StopKind::Block`]).
    single_block: bool,
    /// A pause or sync before the first move (an element of its own).
    pending_stop_at_start: (StopKind, u32, u32),
    /// Elements already handed on by [`PathBuilder::drain_settled`] (a streamed
    /// path keeps only the last one, whose end speed the next may still change).
    base: usize,
    /// The arc data of the pending move ([`PathBuilder::prep_prev`]) and of the move
    /// after it while their corner is blended ([`PathBuilder::prep_next`]), if given:
    /// two slots whose roles swap once the move after becomes the pending one (the
    /// record, about 80 bytes, is written once instead of copied from slot to slot).
    preps: [Option<ArcPrep>; 2],
    /// The slot of `preps` that is [`PathBuilder::prep_next`] (0 or 1).
    prep_next_slot: usize,
    /// [`Limits::max_drift_rad`] of `lim`, worked out once (rad).
    max_drift_rad: f64,
    /// The axes' top speed |vmax| of `lim`, worked out once (mm/s).
    v_top_mm_per_s: f64,
    /// Whether [`Path::orphans`] are kept: a streamed path
    /// ([`PathBuilder::set_streamed`]) drops them with every batch it drains, so it
    /// does not record them at all (a trimmed arc's primitive, about 120 bytes, is
    /// copied there at every join otherwise).
    keep_orphans: bool,
}

/// LinuxCNC's "naive CAM" merging (G64 Q, its `emccanon.cc` `see_segment` /
/// `flush_segments`, written anew here): consecutive G1 lines with the same feed and
/// path mode are held back while every end point of the chain lies within Q of the
/// straight line from the chain's start to its latest end, at most
/// `NAIVE_CAM_MAX_CHAIN` of them; the chain then runs as that one line. Every
/// programmed vertex is within Q of the merged line, and so (distance to a segment is
/// convex) is the whole programmed polyline, and every point of the merged line is
/// within Q of it: the path deviates at most Q + the blend tolerance.
#[derive(Debug, Default)]
struct NaiveCamChain {
    /// The last motion of the chain (its feed and path mode stand for the chain).
    last: Option<Motion>,
    /// Start point of the chain (machine coordinates).
    start: Vec3,
    /// Q (mm).
    q_mm: f64,
    /// Index and programmed line of every motion in the chain.
    lines: Vec<(u32, Primitive)>,
}

/// Most G1 lines one G64 Q chain merges (LinuxCNC: 100).
pub const NAIVE_CAM_MAX_CHAIN: usize = 100;

/// Distance from `p` to the segment `a`–`b` (mm).
pub(crate) fn dist_to_segment(p: Vec3, a: Vec3, b: Vec3) -> f64 {
    let ab = b - a;
    let l2 = ab.dot(ab);
    let t = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * t)).norm()
}

impl NaiveCamChain {
    /// Whether motion `m` (a G1 line `start` → `end` with Q = `q`) continues the chain.
    fn links(&self, m: &Motion, end: Vec3, q: f64) -> bool {
        let Some(last) = &self.last else {
            return false;
        };
        let same_feed = matches!(
            (last.kind, m.kind),
            (MotionKind::Feed { feed_mm_per_min: f1, .. }, MotionKind::Feed { feed_mm_per_min: f2, .. })
                if f1 == f2
        );
        same_feed
            && last.path_mode == m.path_mode
            && q == self.q_mm
            && self.lines.len() < NAIVE_CAM_MAX_CHAIN
            && self
                .lines
                .iter()
                .all(|(_, l)| dist_to_segment(l.end(), self.start, end) <= q)
    }
}

impl PathBuilder {
    /// An empty path for these limits; `motions_hint` sizes the storage.
    pub fn new(lim: &Limits, motions_hint: usize) -> PathBuilder {
        // with arc blends a CAM program of lines and arcs has a blend at nearly every
        // join and an orphan for every trimmed arc: growing the arrays past the hint
        // copied them (44 MB for the 200k-line benchmark program); room that is never
        // written costs no memory
        let (cap, orphans) = if lim.arc_blends {
            (2 * motions_hint + 1, motions_hint / 2)
        } else {
            (motions_hint + motions_hint / 8 + 1, 0)
        };
        PathBuilder {
            lim: *lim,
            path: Path {
                segs: Vec::with_capacity(cap),
                geoms: Vec::with_capacity(cap),
                orphans: Vec::with_capacity(orphans),
                lead_in: 0,
            },
            pending: None,
            spare: None,
            pending_dwell_at_start: 0.0,
            last_point: None,
            s0: 0.0,
            prev_end_tangent: Vec3::ZERO,
            prev_acc_use: AccUse::default(),
            chain: NaiveCamChain::default(),
            single_block: false,
            pending_stop_at_start: (StopKind::None, 0, 0),
            base: 0,
            preps: [None, None],
            prep_next_slot: 0,
            max_drift_rad: lim.max_drift_rad(),
            v_top_mm_per_s: Vec3::new(lim.vmax[0], lim.vmax[1], lim.vmax[2]).norm(),
            keep_orphans: true,
        }
    }

    /// A streamed path ([`PathBuilder::drain_settled`]): the programmed primitives of
    /// moves without an element of their own ([`Path::orphans`]) are not recorded,
    /// since the drained path does not keep them. Elements and limits are the same.
    pub(crate) fn set_streamed(&mut self) {
        self.keep_orphans = false;
        self.path.orphans = Vec::new();
    }

    /// Record `prim`, the programmed primitive of motion `index`, among the orphans
    /// (unless streamed).
    fn orphan(&mut self, index: u32, prim: Primitive) {
        if self.keep_orphans {
            self.path.orphans.push((index, prim));
        }
    }

    /// Single block from the start: every block ends in an exact stop that waits
    /// for the operator ([`StopKind::Block`]); no G64 Q merging across blocks.
    pub fn set_single_block(&mut self, on: bool) {
        self.single_block = on;
    }

    /// Elements whose limits are settled (all but the last, whose end speed the next
    /// element still sets) once at least `batch` of them wait: handed to `out` in
    /// order and dropped, together with the orphans (a streamed path does not keep
    /// the programmed primitives).
    pub(crate) fn drain_settled(&mut self, batch: usize, out: &mut impl FnMut(&Segment, &Geom)) {
        self.drain_settled_vec(batch, &mut |segs, geoms| {
            for (s, g) in segs.iter().zip(geoms) {
                out(s, g);
            }
        });
    }

    /// [`PathBuilder::drain_settled`] handing the settled elements over all at once,
    /// in their own vector: `out` gets them (all but the last element) with their
    /// geometry and may take the vector whole, leaving an empty one in its place
    /// (`std::mem::swap`), so that they are not copied; whatever it leaves is
    /// dropped, and the last element stays.
    ///
    /// The test whether enough wait is inline in the caller (it runs after every
    /// motion and passes about once in `batch` elements); the hand-over is not
    /// (planning thread −3.4 M on the 200k-line program).
    pub(crate) fn drain_settled_vec(
        &mut self,
        batch: usize,
        out: &mut impl FnMut(&mut Vec<Segment>, &[Geom]),
    ) {
        if self.path.segs.len() > batch.max(1) {
            self.hand_over_settled(out);
        }
    }

    /// [`PathBuilder::drain_settled_vec`] once more than one element waits.
    fn hand_over_settled(&mut self, out: &mut impl FnMut(&mut Vec<Segment>, &[Geom])) {
        let n = self.path.segs.len();
        let Some(last) = self.path.segs.pop() else {
            return;
        };
        out(&mut self.path.segs, &self.path.geoms[..n - 1]);
        self.path.segs.clear();
        self.path.segs.push(last);
        self.path.geoms.drain(..n - 1);
        self.path.orphans.clear();
        self.base += n - 1;
    }

    /// The end of a streamed path: the rest of its elements to `out` (limits as
    /// [`PathBuilder::finish`] leaves them before the S-curve spreading of caps,
    /// which [`CapDilator`] does on the stream).
    pub(crate) fn finish_stream(mut self, out: &mut impl FnMut(&Segment, &Geom)) {
        self.close();
        self.drain_settled(0, out);
        if let (Some(s), Some(g)) = (self.path.segs.last(), self.path.geoms.last()) {
            out(s, g);
        }
    }

    /// [`PathBuilder::push`] with the arc data of `prim` worked out ahead
    /// ([`ArcPrep::of`] of `prim` and these limits; None for a line): the same path.
    /// `ahead`: the fillet of its join with the motion before it, if worked out ahead
    /// ([`FilletsAhead`]; taken only where its arguments are the builder's own).
    pub(crate) fn push_prepared(
        &mut self,
        index: usize,
        m: &Motion,
        prim: &Option<Primitive>,
        prep: Option<&ArcPrep>,
        ahead: Option<&FilletAhead>,
    ) {
        self.push_with(index, m, prim, prep, ahead);
    }

    /// Add motion number `index`; `prim` is its programmed primitive in machine
    /// coordinates (None for dwells). G1 lines under G64 Q are merged first.
    pub fn push(&mut self, index: usize, m: &Motion, prim: Option<Primitive>) {
        self.push_with(index, m, &prim, None, None);
    }

    /// [`PathBuilder::push`] with the arc data of `prim`, if given (by reference:
    /// the motion's records are copied once, into the held move).
    ///
    /// Inline (into [`PathBuilder::push_prepared`] and [`PathBuilder::push`]): one call
    /// less a motion (planning thread −0.4 M on the 200k-line program).
    fn push_with(
        &mut self,
        index: usize,
        m: &Motion,
        prim: &Option<Primitive>,
        prep: Option<&ArcPrep>,
        ahead: Option<&FilletAhead>,
    ) {
        let q = match m.path_mode {
            PathMode::Blend {
                naive_cam_mm: Some(q),
                ..
            } if q > 0.0 && !self.single_block => q,
            _ => 0.0,
        };
        // no G64 Q line and no chain held: straight to the builder (what the rest
        // does then), without the frame the chain's handling sets up (about 14
        // instructions a motion)
        if q <= 0.0 && self.chain.last.is_none() {
            return self.push_unmerged(index, m, prim, prep, ahead);
        }
        self.push_chained(index, m, prim, prep, ahead, q);
    }

    /// [`PathBuilder::push_with`] where a G64 Q line comes or a chain is held: `q`
    /// the motion's Q (0 where none).
    fn push_chained(
        &mut self,
        index: usize,
        m: &Motion,
        prim: &Option<Primitive>,
        prep: Option<&ArcPrep>,
        ahead: Option<&FilletAhead>,
        q: f64,
    ) {
        let line = match (&m.kind, prim) {
            (MotionKind::Feed { .. }, &Some(l @ Primitive::Line { start, end }))
                if q > 0.0 && (end - start).norm() >= 1e-9 =>
            {
                Some(l)
            }
            _ => None,
        };
        if let Some(l) = line {
            if self.chain.links(m, l.end(), q) {
                self.chain.lines.push((index as u32, l));
                self.chain.last = Some(*m);
                return;
            }
        }
        self.flush_chain();
        match line {
            Some(l) => {
                self.chain.last = Some(*m);
                self.chain.start = l.start();
                self.chain.q_mm = q;
                self.chain.lines.push((index as u32, l));
            }
            None => self.push_unmerged(index, m, prim, prep, ahead),
        }
    }

    /// Run the held-back G64 Q chain as one line (its motions' programmed lines go to
    /// the orphans; the merged element belongs to the chain's last motion).
    fn flush_chain(&mut self) {
        let Some(last) = self.chain.last.take() else {
            return;
        };
        let n = self.chain.lines.len();
        let Some(&(index, last_line)) = self.chain.lines.last() else {
            return;
        };
        let merged = if n > 1 {
            if self.keep_orphans {
                self.path.orphans.extend(self.chain.lines.iter().copied());
            }
            Primitive::Line {
                start: self.chain.start,
                end: last_line.end(),
            }
        } else {
            last_line
        };
        self.chain.lines.clear();
        // (a G64 Q chain flushed before a motion is another motion: not its arc data)
        self.push_unmerged(index as usize, &last, &Some(merged), None, None);
    }

    /// Add motion number `index` as it is programmed (no G64 Q merging).
    #[allow(clippy::too_many_lines)]
    fn push_unmerged(
        &mut self,
        index: usize,
        m: &Motion,
        prim: &Option<Primitive>,
        prep: Option<&ArcPrep>,
        ahead: Option<&FilletAhead>,
    ) {
        let lim = &self.lim;
        let (exact, tol) = match m.path_mode {
            PathMode::ExactStop => (true, lim.tolerance_mm),
            PathMode::Blend { tolerance_mm, .. } => match tolerance_mm {
                Some(p) if p > 0.0 => (false, p),
                _ => (false, lim.tolerance_mm),
            },
        };
        if let Some(last) = self.pending.as_mut() {
            if last.line != m.line {
                last.block_end = true;
                if self.single_block {
                    last.exact_stop = true;
                    if last.stop == StopKind::None {
                        last.stop = StopKind::Block;
                    }
                }
            }
        }
        let (feed_move, feed) = match m.kind {
            MotionKind::Pause { .. } | MotionKind::Sync => {
                let kind = match m.kind {
                    MotionKind::Pause { optional: false } => StopKind::Program,
                    MotionKind::Pause { optional: true } => StopKind::Optional,
                    _ => StopKind::Sync,
                };
                match self.pending.as_mut() {
                    // a stop that waits outranks a sync, a program stop the others
                    Some(last) => {
                        last.exact_stop = true;
                        last.stop = stronger(last.stop, kind);
                        last.line = m.line;
                        if kind != StopKind::Sync {
                            last.pause_motion = index as u32;
                        }
                    }
                    None => {
                        let (k, _, _) = self.pending_stop_at_start;
                        self.pending_stop_at_start = (stronger(k, kind), m.line, index as u32);
                        self.last_point.get_or_insert(m.start + m.offset_mm);
                    }
                }
                return;
            }
            // refused before it is built (`PlanError::ProbeMove`)
            MotionKind::Probe { .. } => return,
            MotionKind::Dwell { seconds } => {
                if let Some(last) = self.pending.as_mut() {
                    last.exact_stop = true;
                    last.dwell_s += seconds.max(0.0);
                } else {
                    self.pending_dwell_at_start += seconds.max(0.0);
                    self.last_point.get_or_insert(m.start + m.offset_mm);
                }
                return;
            }
            MotionKind::Machine(op) => {
                if op.stops_motion() {
                    self.push_machine_stop(index, m);
                }
                return;
            }
            MotionKind::Traverse { .. } => (false, f64::INFINITY),
            MotionKind::Feed {
                feed_mm_per_min, ..
            }
            | MotionKind::Arc {
                feed_mm_per_min, ..
            } => (true, feed_mm_per_min / 60.0),
        };
        // (the primitive read where the motion holds it and written once, into the
        // held move's record: not copied to the stack first)
        let Some(src) = prim.as_ref() else { return };
        // the held move's record, its geometry and direction written in place in
        // each arm (not assembled on the stack and copied in: about 15 instructions a
        // motion); an arc's length is its `ArcPrep`'s where one came with it
        // (`Primitive::length` of the same arc, the same bits)
        let mut next = self
            .spare
            .take()
            .unwrap_or_else(|| Box::new(Pending::placeholder()));
        let len = match *src {
            Primitive::Line { start, end } => {
                let d = end - start;
                let len = d.norm();
                next.dir = if len > 0.0 {
                    d * (1.0 / len)
                } else {
                    Vec3::ZERO
                };
                next.geom = Geom::Line {
                    start,
                    end,
                    from: 0.0,
                    to: len,
                    prog_len: len,
                };
                len
            }
            Primitive::Arc { .. } => {
                next.dir = Vec3::ZERO;
                next.geom = Geom::Arc(*src);
                match prep {
                    Some(q) => {
                        debug_assert_eq!(
                            q.len_mm.to_bits(),
                            src.length().to_bits(),
                            "the arc data of another arc"
                        );
                        q.len_mm
                    }
                    None => src.length(),
                }
            }
        };
        if len < 1e-9 {
            self.spare = Some(next);
            self.orphan(index as u32, *src);
            return;
        }
        if self.last_point.is_none() {
            self.last_point = Some(src.start());
        }
        next.len = len;
        next.motion = index as u32;
        next.feed_move = feed_move;
        next.feed_mm_per_s = feed;
        next.exact_stop = exact;
        next.tolerance_mm = tol;
        next.dwell_s = 0.0;
        next.line = m.line;
        next.stop = StopKind::None;
        next.block_end = false;
        next.machine = false;
        next.pause_motion = index as u32;
        next.start_trim = 0.0;
        next.start_at = None;
        next.start_trim_rad = None;
        // (written into the slot where it lies, not through a copy on the stack)
        let slot = &mut self.preps[self.prep_next_slot & 1];
        match prep {
            Some(q) => *slot = Some(*q),
            None => *slot = None,
        }
        match self.pending.take() {
            Some(mut prev) => {
                // a change between traverse and feed is never blended: the path stops
                // exactly at the join (as LinuxCNC: a rapid blended into a cut can
                // hit a clamp)
                if prev.feed_move != next.feed_move {
                    prev.exact_stop = true;
                }
                let blend = self.blend(&prev, &next, ahead);
                if let Some(b) = blend {
                    next.start_trim = b.start_trim_next;
                    next.start_at = b.next_start_at;
                    next.start_trim_rad = b.next_start_trim_rad;
                }
                self.emit(&prev, blend.as_ref(), false);
                self.spare = Some(prev);
            }
            None => self.start_dwell(),
        }
        self.pending = Some(next);
        // the move after is now the pending one: its slot becomes `prep_prev`, the
        // other is written before it is read again (`prep_next` of the next move)
        self.prep_next_slot ^= 1;
    }

    /// A machine operation the path comes to rest for: the move held before it
    /// stops exactly at its end, and the operation becomes a zero-length element
    /// there ([`Segment::machine`]), held as a move is, so that a dwell or pause
    /// after it ends it and the next move is not blended into it.
    fn push_machine_stop(&mut self, index: usize, m: &Motion) {
        let at = match self.pending.as_deref() {
            Some(prev) => prev.end_point(),
            None => *self.last_point.get_or_insert(m.start + m.offset_mm),
        };
        let mut next = self
            .spare
            .take()
            .unwrap_or_else(|| Box::new(Pending::placeholder()));
        next.geom = Geom::Line {
            start: at,
            end: at,
            from: 0.0,
            to: 0.0,
            prog_len: 0.0,
        };
        next.len = 0.0;
        next.dir = Vec3::ZERO;
        next.motion = index as u32;
        next.feed_move = false;
        next.feed_mm_per_s = f64::INFINITY;
        next.exact_stop = true;
        next.tolerance_mm = self.lim.tolerance_mm;
        next.dwell_s = 0.0;
        next.line = m.line;
        next.stop = StopKind::None;
        next.block_end = false;
        next.machine = true;
        next.pause_motion = index as u32;
        next.start_trim = 0.0;
        next.start_at = None;
        next.start_trim_rad = None;
        self.preps[self.prep_next_slot & 1] = None;
        match self.pending.take() {
            Some(mut prev) => {
                prev.exact_stop = true;
                self.emit(&prev, None, false);
                self.spare = Some(prev);
            }
            None => self.start_dwell(),
        }
        self.pending = Some(next);
        self.prep_next_slot ^= 1;
    }

    /// The dwell (and pause) before the first move, as an element of its own.
    fn start_dwell(&mut self) {
        let (stop, line, pause_motion) = self.pending_stop_at_start;
        if self.pending_dwell_at_start > 0.0 || stop != StopKind::None {
            let p = self.last_point.unwrap_or(Vec3::ZERO);
            self.path.segs.push(Segment {
                s0: 0.0,
                len: 0.0,
                motion: 0,
                feed_move: false,
                feed_mm_per_s: f64::INFINITY,
                vel_cap: f64::INFINITY,
                acc: 1.0,
                v_end_hard: 0.0,
                dwell_s: self.pending_dwell_at_start,
                line,
                stop,
                block_end: stop != StopKind::None,
                machine: false,
                pause_motion,
            });
            self.path.geoms.push(Geom::Line {
                start: p,
                end: p,
                from: 0.0,
                to: 0.0,
                prog_len: 0.0,
            });
            self.path.lead_in = 1;
            self.pending_dwell_at_start = 0.0;
            self.pending_stop_at_start = (StopKind::None, 0, 0);
        }
    }

    /// Blend at a corner: a circular arc tangent to both moves (line–line here,
    /// line–arc and arc–line in [`crate::fillet`]), and how far it trims each (G64 P
    /// tolerance, half of each move at most).
    /// `ahead`: the fillet of this join if worked out ahead ([`FilletAhead`]).
    fn blend(&self, a: &Pending, b: &Pending, ahead: Option<&FilletAhead>) -> Option<Blend> {
        if a.exact_stop || a.dwell_s > 0.0 {
            return None;
        }
        // the tolerance a fillet or biarc may use: the program's or profile's, capped
        // by what the corner's speed needs (line–line blends work out their radius
        // for speed themselves, `blend_lines`)
        let tol_mm = match (&a.geom, &b.geom) {
            (Geom::Line { .. }, Geom::Line { .. }) => min_to(a.tolerance_mm, b.tolerance_mm),
            _ => min_to(
                min_to(a.tolerance_mm, b.tolerance_mm),
                self.speed_tolerance(a, b),
            ),
        };
        if !matches!((&a.geom, &b.geom), (Geom::Line { .. }, Geom::Line { .. }))
            && (!self.lim.arc_blends || self.kink_at_speed(a, b))
        {
            // arc blends off, or a tangent join taken at speed that needs none
            return None;
        }
        // (the blend found goes back as it came, not unwrapped and wrapped again: a
        // `Blend` is a few hundred bytes)
        let lim = &self.lim;
        if lim.profile != FeedProfile::SCurve {
            let found = self.circle_blend(a, b, ahead, tol_mm);
            if found.is_some() {
                return found;
            }
            return self.biarc_blend(a, b, tol_mm);
        }
        let found = self
            .circle_blend(a, b, ahead, tol_mm)
            .or_else(|| self.biarc_blend(a, b, tol_mm));
        if let Some(found) = &found {
            // A blend so tight that the jerk limit crawls through it is slower than
            // stopping: stop at the corner instead.
            let tightest = found
                .arc
                .radius
                .min(found.arc2.map_or(f64::INFINITY, |a| a.radius));
            let through = scurve_curve_cap(1.0 / tightest, lim);
            let vmin = lim.vmax.iter().cloned().fold(f64::INFINITY, f64::min);
            let around = a.feed_mm_per_s.min(b.feed_mm_per_s).min(vmin);
            if through < SCURVE_MIN_BLEND_SPEED_SHARE * around {
                return None;
            }
            // (acc/dec after interpolation passes the corner at its feed instead)
            if lim.acc_dec == AccDec::BeforeInterpolation
                && !scurve_blend_pays(lim, a, b, found, through, vmin)
            {
                return None;
            }
        }
        found
    }

    /// A single circular blend: line–line here, line–arc, arc–line and arc–arc of
    /// one plane in [`crate::fillet`].
    ///
    /// Inline (into [`PathBuilder::push_unmerged`], its one hot caller): the call,
    /// its frame and the `Option<Blend>` handed back cost about 13 instructions a
    /// join (planning thread −2.6 M on the 200k-line program).
    #[allow(clippy::too_many_lines)]
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn circle_blend(
        &self,
        a: &Pending,
        b: &Pending,
        ahead: Option<&FilletAhead>,
        tol_mm: f64,
    ) -> Option<Blend> {
        // (by reference: the geometries are not copied to be matched)
        match (&a.geom, &b.geom) {
            (Geom::Line { .. }, Geom::Line { .. }) => self.blend_lines(a, b),
            (&Geom::Line { end, .. }, Geom::Arc(arc)) => {
                // (the view and the fillet by reference into their `Option`s: not
                // copied out, about 100 and 140 bytes)
                let view = self.view_next(arc);
                let view = view.as_ref()?;
                let f = line_arc_or_ahead(
                    ahead,
                    end,
                    a.dir,
                    min_to(0.5 * a.len, a.len - a.start_trim),
                    view,
                    0.5 * b.len,
                    tol_mm,
                );
                let f = f.as_ref()?;
                let e1 = (f.p_line - f.center) * (1.0 / f.radius);
                Some(Blend {
                    arc2: None,
                    arc: BlendArc {
                        center: f.center,
                        e1,
                        e2: a.dir,
                        radius: f.radius,
                        sweep: f.sweep,
                    },
                    sweep_cos_sin: Some((f.cos_sweep, f.sin_sweep)),
                    end_trim_prev: f.line_trim,
                    start_trim_next: f.arc_trim,
                    prev_end_at: None,
                    next_start_at: Some(f.p_arc),
                    prev_end_trim_rad: None,
                    next_start_trim_rad: Some(f.arc_trim_rad),
                })
            }
            (Geom::Arc(arc), &Geom::Line { start, .. }) => {
                // the line–arc construction on the path run backwards
                let view = match self.prep_prev() {
                    Some(p) => p.view(arc, true, self.max_drift_rad()),
                    None => ArcView::of(arc, true, self.max_drift_rad()),
                };
                let view = view.as_ref()?;
                let f = line_arc_or_ahead(
                    ahead,
                    start,
                    -b.dir,
                    0.5 * b.len,
                    view,
                    min_to(0.5 * a.len, a.len - a.start_trim),
                    tol_mm,
                );
                let f = f.as_ref()?;
                let e1 = (f.p_arc - f.center) * (1.0 / f.radius);
                // backwards the fillet runs from the line with e2' = −b.dir; forwards
                // it starts at the arc point with the opposite of its end tangent there
                let e1_back = (f.p_line - f.center) * (1.0 / f.radius);
                let t_back = -b.dir * f.cos_sweep - e1_back * f.sin_sweep;
                Some(Blend {
                    arc2: None,
                    arc: BlendArc {
                        center: f.center,
                        e1,
                        e2: -t_back,
                        radius: f.radius,
                        sweep: f.sweep,
                    },
                    sweep_cos_sin: Some((f.cos_sweep, f.sin_sweep)),
                    end_trim_prev: f.arc_trim,
                    start_trim_next: f.line_trim,
                    prev_end_at: Some(f.p_arc),
                    next_start_at: None,
                    prev_end_trim_rad: Some(f.arc_trim_rad),
                    next_start_trim_rad: None,
                })
            }
            (Geom::Arc(arc_a), Geom::Arc(arc_b)) => {
                let view = self.view_next(arc_b)?;
                let f = fillet::arc_arc(
                    arc_a.end(),
                    arc_a,
                    min_to(0.5 * a.len, a.len - a.start_trim),
                    &view,
                    0.5 * b.len,
                    tol_mm,
                    self.max_drift_rad(),
                )?;
                let e1 = (f.p_line - f.center) * (1.0 / f.radius);
                Some(Blend {
                    arc2: None,
                    arc: BlendArc {
                        center: f.center,
                        e1,
                        e2: arc_a.tangent_at(a.len - f.line_trim),
                        radius: f.radius,
                        sweep: f.sweep,
                    },
                    // (e2 is the first arc's tangent, not quite the construction's u)
                    sweep_cos_sin: None,
                    end_trim_prev: f.line_trim,
                    start_trim_next: f.arc_trim,
                    prev_end_at: Some(f.p_line),
                    next_start_at: Some(f.p_arc),
                    // the first arc's point d before its end: `Primitive::point_at`'s
                    // angle there, sweep·d/length
                    prev_end_trim_rad: Some(prim_sweep(arc_a).abs() * f.line_trim / a.len),
                    next_start_trim_rad: Some(f.arc_trim_rad),
                })
            }
            _ => None,
        }
    }

    /// A biarc blend ([`fillet::biarc`]) at a corner with an arc or helix that no
    /// single circle blends (helices, arcs of different planes, fillets not found):
    /// each move gives at most half its length (less what the blend at its start
    /// took), arcs only if they can be trimmed ([`trimmable_arc`]).
    fn biarc_blend(&self, a: &Pending, b: &Pending, tol_mm: f64) -> Option<Blend> {
        if matches!((a.geom, b.geom), (Geom::Line { .. }, Geom::Line { .. })) {
            return None;
        }
        let before_avail = (0.5 * a.len).min(a.len - a.start_trim);
        let after_avail = 0.5 * b.len;
        let corner = match a.geom {
            Geom::Line { end, .. } => end,
            Geom::Arc(p) if trimmable_arc(&p) => p.end(),
            _ => return None,
        };
        if let Geom::Arc(p) = b.geom {
            if !trimmable_arc(&p) {
                return None;
            }
        }
        let (t_in, t_out) = (
            end_tangent(&a.geom, a.dir, a.len),
            start_tangent(&b.geom, b.dir),
        );
        if t_in.dot(t_out).clamp(-1.0, 1.0).acos() > MAX_BLEND_TURN_RAD {
            return None;
        }
        let before = |d: f64| match a.geom {
            Geom::Arc(p) => (p.point_at(a.len - d), path_tangent(&p, a.len - d)),
            _ => (corner - a.dir * d, a.dir),
        };
        let after = |d: f64| match b.geom {
            Geom::Arc(p) => (p.point_at(d), path_tangent(&p, d)),
            _ => (corner + b.dir * d, b.dir),
        };
        let f = fillet::biarc(corner, before, before_avail, after, after_avail, tol_mm)?;
        let piece = |p: &fillet::ArcPiece| BlendArc {
            center: p.center,
            e1: p.e1,
            e2: p.e2,
            radius: p.radius,
            sweep: p.sweep,
        };
        let on_arc = |g: &Geom, at: Vec3| matches!(g, Geom::Arc(_)).then_some(at);
        Some(Blend {
            arc: piece(&f.arcs[0]),
            arc2: Some(piece(&f.arcs[1])),
            sweep_cos_sin: None,
            end_trim_prev: f.trim_before,
            start_trim_next: f.trim_after,
            prev_end_at: on_arc(&a.geom, f.p_before),
            next_start_at: on_arc(&b.geom, f.p_after),
            prev_end_trim_rad: None,
            next_start_trim_rad: None,
        })
    }

    /// The largest angle between a blended arc's tangent and its circle's (rad): the
    /// velocity step it makes at the highest path speed, v·angle per cycle, stays
    /// within the kink share of every axis's acceleration.
    fn max_drift_rad(&self) -> f64 {
        self.max_drift_rad
    }

    /// The arc data of the pending move, if given.
    fn prep_prev(&self) -> &Option<ArcPrep> {
        &self.preps[(self.prep_next_slot ^ 1) & 1]
    }

    /// The arc data of the move after the pending one while their corner is
    /// blended, if given.
    fn prep_next(&self) -> &Option<ArcPrep> {
        &self.preps[self.prep_next_slot & 1]
    }

    /// [`ArcView::of`] the move after the corner being blended (an arc, `arc`), from
    /// its start: from its [`ArcPrep`] where one came with it.
    fn view_next(&self, arc: &Primitive) -> Option<ArcView> {
        match self.prep_next() {
            Some(p) => p.view(arc, false, self.max_drift_rad()),
            None => ArcView::of(arc, false, self.max_drift_rad()),
        }
    }

    /// Whether the tangent break between `a` and `b` is small enough that the kink
    /// share passes it at the feed of both (and the axes' top speed): no blend then.
    fn kink_at_speed(&self, a: &Pending, b: &Pending) -> bool {
        let t1 = match &a.geom {
            Geom::Line { .. } => a.dir,
            Geom::Arc(p) => match self.prep_prev() {
                Some(q) => q.end_tangent,
                None => arc_end_tangent(p, true),
            },
            Geom::Blend { .. } => return false,
        };
        let t2 = match &b.geom {
            Geom::Line { .. } => b.dir,
            Geom::Arc(p) => match self.prep_next() {
                Some(q) => q.start_tangent,
                None => arc_end_tangent(p, false),
            },
            Geom::Blend { .. } => return false,
        };
        let lim = &self.lim;
        let dt = t2 - t1;
        let v = min_to(
            min_to(a.feed_mm_per_s, b.feed_mm_per_s),
            self.v_top_mm_per_s,
        );
        lim.profile == FeedProfile::Trapezoidal
            && lim.acc_dec == AccDec::BeforeInterpolation
            && (0..3).all(|i| dt[i].abs() * v <= lim.kink_acc[i] * lim.cycle_s)
    }

    /// [`speed_tolerance_mm`] of the corner between `a` and `b` (one of them an arc):
    /// the tangents and arc data the kink test takes ([`ArcPrep`] where it came, the
    /// same bits as [`FilletsAhead`] works with).
    fn speed_tolerance(&self, a: &Pending, b: &Pending) -> f64 {
        let lim = &self.lim;
        let (t_in, cap_in) = match &a.geom {
            Geom::Arc(p) => (
                match self.prep_prev() {
                    Some(q) => q.end_tangent,
                    None => arc_end_tangent(p, true),
                },
                arc_corner_speed(lim, a.feed_mm_per_s, arc_radius_mm(p)),
            ),
            _ => (a.dir, line_corner_speed(lim, a.feed_mm_per_s, a.dir)),
        };
        let (t_out, cap_out) = match &b.geom {
            Geom::Arc(p) => (
                match self.prep_next() {
                    Some(q) => q.start_tangent,
                    None => arc_end_tangent(p, false),
                },
                arc_corner_speed(lim, b.feed_mm_per_s, arc_radius_mm(p)),
            ),
            _ => (b.dir, line_corner_speed(lim, b.feed_mm_per_s, b.dir)),
        };
        speed_tolerance_mm(lim, a.feed_mm_per_s, t_in, t_out, cap_in, cap_out)
    }

    /// The smallest line–line blend radius that gives the corner its speed
    /// (infinite where no speed bounds it). A blend of radius r (at least
    /// r* = [`speed_radius_mm`] of v_b, where its centripetal cap, and with the
    /// S-curve its jerk caps, reach v_b) runs at v_b, the lower of its axes' velocity
    /// cap over its sweep and its feed (the first move's), which does not depend on r,
    /// and it meets each line at a junction no faster than that line (its own feed and
    /// axis cap, v₁ and v₂): v_b = min(v_blend, v₁, v₂). A larger blend
    /// would only shorten the path a little while deviating more from the programmed
    /// corner: the tolerance is a cap, not a target.
    fn radius_for_speed(&self, a: &Pending, b: &Pending, e1: Vec3, e2: Vec3, theta: f64) -> f64 {
        let lim = &self.lim;
        let v1 = line_corner_speed(lim, a.feed_mm_per_s, a.dir);
        let v2 = line_corner_speed(lim, b.feed_mm_per_s, b.dir);
        // the blend's axis velocity cap and acceleration do not depend on its radius
        let shape = ElementShape::blend(e1, e2, 1.0, theta);
        let mut v_blend = a.feed_mm_per_s;
        let mut a_axis = f64::INFINITY;
        for i in 0..3 {
            if shape.vel_weight[i] > 1e-12 {
                v_blend = v_blend.min(lim.vmax[i] / shape.vel_weight[i]);
            }
            if shape.acc_weight[i] > 1e-12 {
                a_axis = a_axis.min(lim.amax[i] / shape.acc_weight[i]);
            }
        }
        let v = v_blend.min(v1.min(v2));
        if !v.is_finite() {
            return f64::INFINITY;
        }
        // and at least a cycle's travel long, (v + a·T)·T: shorter elements leave
        // their junctions only the kink share (`junction_speed`), so that a dense
        // polyline of tiny blends crawled (a circle of 2,000 lines at 1 % of its
        // feed); with the S-curve at least the smoothing window's travel, v·W (the
        // window averages the tangent breaks of all elements within it: 22 % of that
        // circle at 95 % of its feed with blends one cycle long)
        let mut min_len_mm = (v + lim.path_acc_bound_mm_per_s2 * lim.cycle_s) * lim.cycle_s;
        if lim.profile == FeedProfile::SCurve {
            min_len_mm = min_len_mm.max(v * lim.scurve_window_s);
        }
        speed_radius_mm(lim, v, a_axis).max(min_len_mm / theta)
    }

    /// Blend at a line–line corner.
    fn blend_lines(&self, a: &Pending, b: &Pending) -> Option<Blend> {
        let (u1, u2) = (a.dir, b.dir);
        let cos_t = u1.dot(u2).clamp(-1.0, 1.0);
        let theta = cos_t.acos();
        if (u2 - u1).norm() <= TANGENT_EPS || theta > MAX_BLEND_TURN_RAD {
            return None;
        }
        let half = 0.5 * theta;
        let (la, lb) = (a.len, b.len);
        let avail_a = (0.5 * la).min(la - a.start_trim);
        let d_max = avail_a.min(0.5 * lb);
        let tan_half = half.tan();
        let r_tol = a.tolerance_mm.min(b.tolerance_mm) / (1.0 / half.cos() - 1.0);
        let r_len = d_max / tan_half;
        let mut r = r_tol.min(r_len);
        if r.is_nan() || r <= 1e-9 {
            return None;
        }
        let nrm = (u2 - u1 * cos_t).unit();
        r = r.min(self.radius_for_speed(a, b, -nrm, u1, theta));
        let d = r * tan_half;
        let Geom::Line { end: a1, .. } = a.geom else {
            return None;
        };
        let p1 = a1 - u1 * d;
        let center = p1 + nrm * r;
        Some(Blend {
            arc: BlendArc {
                center,
                e1: -nrm,
                e2: u1,
                radius: r,
                sweep: theta,
            },
            arc2: None,
            sweep_cos_sin: None,
            end_trim_prev: d,
            start_trim_next: d,
            prev_end_at: None,
            next_start_at: None,
            prev_end_trim_rad: None,
            next_start_trim_rad: None,
        })
    }

    /// Push the elements of a move whose successor is known (`last`: it has none).
    ///
    /// Each element's geometry is pushed onto `path.geoms` where it is built (from
    /// the held move's fields or the sub-arc's), not built in a local and copied
    /// there by [`PathBuilder::push_element`]: that local, an enum with a one-byte
    /// tag, was copied through the stack at odd offsets (see [`BlendArc`]).
    fn emit(&mut self, p: &Pending, blend: Option<&Blend>, last: bool) {
        let stop = p.exact_stop || p.dwell_s > 0.0 || p.stop != StopKind::None || last;
        // (the two common elements, a trimmed line and a sub-arc cut by fillets,
        // each push their shape where they build it, `push_shaped`: merged into
        // one local, the shape went through the stack, where `ElementShape::arc`,
        // out of line, returns it; the rarer ones through `push_shaped_cold`)
        match &p.geom {
            &Geom::Line {
                start,
                end,
                prog_len,
                ..
            } => {
                let to = prog_len - blend.map_or(0.0, |b| b.end_trim_prev);
                let len = max_to(to - p.start_trim, 0.0);
                self.path.geoms.push(Geom::Line {
                    start,
                    end,
                    from: p.start_trim,
                    to,
                    prog_len,
                });
                let shape = ElementShape::line(len, p.dir);
                self.push_shaped(p, &shape, blend, stop);
            }
            // (by reference: the held move's arc is not copied out to be cut)
            Geom::Arc(prim) => {
                let end_trim = blend.map_or(0.0, |b| b.end_trim_prev);
                if p.start_trim == 0.0 && end_trim == 0.0 {
                    self.path.geoms.push(p.geom);
                    let shape = ElementShape::arc(prim);
                    self.push_shaped_cold(p, &shape, blend, stop);
                } else {
                    // the programmed arc stays exact among the orphans
                    self.orphan(p.motion, *prim);
                    let (from, to) = (p.start_trim, p.len - end_trim);
                    if to - from < 1e-6 {
                        // used up by the blends at both its ends
                        let at = prim.point_at(from);
                        let dir = Vec3::ZERO;
                        self.path.geoms.push(Geom::Line {
                            start: at,
                            end: at,
                            from: 0.0,
                            to: 0.0,
                            prog_len: 0.0,
                        });
                        let shape = ElementShape::line(0.0, dir);
                        self.push_shaped_cold(p, &shape, blend, stop);
                    } else {
                        let at_from = p.start_at.unwrap_or_else(|| prim.point_at(from));
                        let at_to = blend
                            .and_then(|b| b.prev_end_at)
                            .unwrap_or_else(|| prim.point_at(to));
                        // the angles the fillets took at either end (0 where none)
                        let start_rad = if p.start_trim == 0.0 {
                            Some(0.0)
                        } else {
                            p.start_trim_rad
                        };
                        let end_rad = if end_trim == 0.0 {
                            Some(0.0)
                        } else {
                            blend.and_then(|b| b.prev_end_trim_rad)
                        };
                        if let (Some(s_rad), Some(e_rad)) = (start_rad, end_rad) {
                            // cut from the circle by fillets: planned as a circle
                            // where its end radius is off by rounding only
                            // (`sub_arc_by_angles` on the path: the held arc copied
                            // there and cut in place)
                            self.path.geoms.push(p.geom);
                            let shape = match self.path.geoms.last_mut() {
                                Some(Geom::Arc(sub)) => {
                                    cut_by_angles(sub, at_from, at_to, s_rad, e_rad);
                                    ElementShape::sub_arc(sub)
                                }
                                _ => unreachable!("the held move is an arc"),
                            };
                            self.push_shaped(p, &shape, blend, stop);
                        } else {
                            let sub = if prim_sweep(prim).abs() < std::f64::consts::TAU {
                                sub_arc(prim, at_from, at_to)
                            } else {
                                // a helix of a turn or more, trimmed by biarcs only
                                sub_arc_span(prim, from, to, at_from, at_to)
                            };
                            self.path.geoms.push(Geom::Arc(sub));
                            let shape = ElementShape::arc(&sub);
                            self.push_shaped_cold(p, &shape, blend, stop);
                        }
                    }
                }
            }
            Geom::Blend { .. } => unreachable!("moves are lines or arcs"),
        }
    }

    /// The element of move `p` whose geometry [`PathBuilder::emit`] has just pushed,
    /// of shape `shape`, then the blend after it (if any).
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn push_shaped(
        &mut self,
        p: &Pending,
        shape: &ElementShape,
        blend: Option<&Blend>,
        stop: bool,
    ) {
        match blend {
            Some(b) => {
                self.push_element(p, shape, 0.0, false, false);
                // the blend's arcs, by reference; a fillet's (one arc, its sweep's
                // cosine and sine given) pushed here, not through a call
                match (&b.arc2, b.sweep_cos_sin) {
                    (None, Some(trig)) => self.push_blend_trig(p, &b.arc, trig),
                    _ => {
                        self.push_blend_piece(p, &b.arc, b.sweep_cos_sin);
                        if let Some(a2) = &b.arc2 {
                            self.push_blend_piece(p, a2, None);
                        }
                    }
                }
            }
            None => self.push_element(p, shape, p.dwell_s, stop, false),
        }
    }

    /// [`PathBuilder::push_shaped`] out of line, for the rarer elements.
    fn push_shaped_cold(
        &mut self,
        p: &Pending,
        shape: &ElementShape,
        blend: Option<&Blend>,
        stop: bool,
    ) {
        self.push_shaped(p, shape, blend, stop);
    }

    /// Push a blend arc `arc` of move `p`'s corner (its sweep's cosine and sine where
    /// the construction gave them).
    fn push_blend_piece(&mut self, p: &Pending, arc: &BlendArc, trig: Option<(f64, f64)>) {
        let &BlendArc {
            e1,
            e2,
            radius,
            sweep,
            ..
        } = arc;
        // (each arm pushes its own shape: merged into one local, the shape went
        // through the stack, where `ElementShape::blend`, out of line, returns it)
        match trig {
            Some(trig) => self.push_blend_trig(p, arc, trig),
            None => {
                let shape = ElementShape::blend(e1, e2, radius, sweep);
                self.path.geoms.push(arc.geom());
                self.push_element(p, &shape, 0.0, false, true);
            }
        }
    }

    /// [`PathBuilder::push_blend_piece`] of an arc whose sweep's cosine and sine the
    /// construction gave (`trig`).
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn push_blend_trig(&mut self, p: &Pending, arc: &BlendArc, (cos_s, sin_s): (f64, f64)) {
        let &BlendArc {
            e1,
            e2,
            radius,
            sweep,
            ..
        } = arc;
        let shape = ElementShape::blend_trig(e1, e2, radius, sweep, cos_s, sin_s);
        self.path.geoms.push(arc.geom());
        self.push_element(p, &shape, 0.0, false, true);
    }

    /// Push one element with its limits (its geometry is the last of `path.geoms`,
    /// pushed by the caller) and settle the junction speed with the one before it.
    /// One too short to keep is taken off `path.geoms` again, and its programmed
    /// primitive (not a blend's) goes to the orphans.
    ///
    /// Inline (into [`PathBuilder::emit`] and [`PathBuilder::push_blend_piece`]):
    /// the shape is then read where its callers built it (planning thread −2.0 M on
    /// the 200k-line program, with `circle_blend` inline; alone, in `plan12`, −2.3 M
    /// but +1.2 M on the reading thread).
    #[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
    fn push_element(
        &mut self,
        m: &Pending,
        shape: &ElementShape,
        dwell: f64,
        stop: bool,
        is_blend: bool,
    ) {
        let lim = &self.lim;
        let len = shape.len;
        if len < 1e-9 && !stop && dwell == 0.0 {
            // a line used up entirely by the blends at both its ends
            if let Some(prim) = self.path.geoms.pop().and_then(|g| g.programmed()) {
                self.orphan(m.motion, prim);
            }
            return;
        }
        if m.machine {
            // a machine stop: standing, no limits of its own
            self.path.segs.push(Segment {
                s0: self.s0,
                len: 0.0,
                motion: m.motion,
                feed_move: false,
                feed_mm_per_s: f64::INFINITY,
                vel_cap: f64::INFINITY,
                acc: 1.0,
                v_end_hard: 0.0,
                dwell_s: dwell,
                line: m.line,
                stop: m.stop,
                block_end: m.block_end,
                machine: true,
                pause_motion: m.pause_motion,
            });
            return;
        }
        let el = element_limits(shape, lim.vmax, lim.amax);
        let mut vel_cap = el.vel_mm_per_s;
        let mut acc = el.acc_mm_per_s2;
        if lim.profile == FeedProfile::SCurve {
            acc = acc.min(lim.scurve_acc);
            vel_cap = vel_cap.min(scurve_curve_cap(shape.curvature, lim));
        }
        let acc_use = AccUse::of(shape, acc, vel_cap, m.feed_mm_per_s, lim);
        // the junction with the element before (not after a stop); a streamed path
        // keeps the last element (`drain_settled`), so n > 0 whenever base + n > 0
        let n = self.path.segs.len();
        if self.base + n > self.path.lead_in && n > 0 {
            let a = &mut self.path.segs[n - 1];
            if a.v_end_hard != 0.0 {
                // (the geometries indexed only where the curvature step is asked
                // for, S-curve: not two bounds checks an element)
                let geoms = &self.path.geoms;
                let uses = [&self.prev_acc_use, &acc_use];
                a.v_end_hard = junction_speed(
                    lim,
                    a.vel_cap,
                    vel_cap,
                    self.prev_end_tangent,
                    shape,
                    uses,
                    || geoms[n].curvature_vec(false) - geoms[n - 1].curvature_vec(true),
                );
            }
        }
        self.path.segs.push(Segment {
            s0: self.s0,
            len,
            motion: m.motion,
            feed_move: m.feed_move,
            feed_mm_per_s: m.feed_mm_per_s,
            vel_cap,
            acc,
            v_end_hard: if stop { 0.0 } else { f64::INFINITY },
            dwell_s: dwell,
            line: m.line,
            // the move's last element carries its stop (a blend arc never: a move
            // that stops is not blended)
            stop: if stop { m.stop } else { StopKind::None },
            block_end: m.block_end && !is_blend,
            machine: m.machine,
            pause_motion: if stop { m.pause_motion } else { m.motion },
        });
        self.s0 += len;
        self.prev_end_tangent = shape.end_tangent;
        self.prev_acc_use = acc_use;
    }

    /// The path: the last move ends in a stop.
    pub fn finish(mut self) -> Path {
        self.close();
        if self.lim.profile == FeedProfile::SCurve {
            dilate_caps(
                &mut self.path.segs,
                self.lim.scurve_window_s,
                self.lim.scurve_acc,
            );
        }
        self.path
    }

    /// Push what is held back; the last element ends in a stop.
    fn close(&mut self) {
        self.flush_chain();
        // a G64 Q chain goes to the orphans when it ends, after the moves it held back;
        // a merged line used up by its blends is an orphan of its last motion too, pushed
        // after the chain's own lines: the stable sort keeps the programmed one first
        self.path.orphans.sort_by_key(|o| o.0);
        self.path.orphans.dedup_by_key(|o| o.0);
        match self.pending.take() {
            Some(p) => self.emit(&p, None, true),
            None => self.start_dwell(),
        }
        if let Some(last) = self.path.segs.last_mut() {
            last.v_end_hard = 0.0;
        }
    }
}

/// A blend found at a corner: its geometry and how much it takes from each move.
#[derive(Debug, Clone, Copy)]
struct Blend {
    arc: BlendArc,
    /// The second arc of a biarc blend ([`fillet::biarc`]), run after `arc`.
    arc2: Option<BlendArc>,
    /// cos and sin of `arc`'s sweep where the construction gave them (fillets):
    /// its shape then needs no trigonometry.
    sweep_cos_sin: Option<(f64, f64)>,
    /// Arc length taken from the end of the move before the corner (mm).
    end_trim_prev: f64,
    /// Arc length taken from the start of the move after it (mm).
    start_trim_next: f64,
    /// Where the blend leaves the move before it, if that is an arc.
    prev_end_at: Option<Vec3>,
    /// Where the blend meets the move after it, if that is an arc.
    next_start_at: Option<Vec3>,
    /// The angle about the centre the blend takes from the end of the arc before it,
    /// where a fillet gave it (rad): the sub-arc's angles then need no `atan2`.
    prev_end_trim_rad: Option<f64>,
    /// The angle the blend takes from the start of the arc after it (rad).
    next_start_trim_rad: Option<f64>,
}

/// A blend arc of a [`Blend`]: the fields of [`Geom::Blend`] without the enum's tag.
/// A `Geom` holds its tag in its first byte and an arc's plane in its second
/// (`Primitive`'s layout), so LLVM copied the bytes after the tag of every `Geom`
/// built on the stack in 16-byte moves at odd offsets, whose loads waited on the
/// narrower stores just before them (stores that cannot be forwarded): the hottest
/// samples of `emit` and `push_unmerged`. The `Geom` is now built only where it is
/// pushed ([`BlendArc::geom`]).
#[derive(Debug, Clone, Copy)]
struct BlendArc {
    center: Vec3,
    e1: Vec3,
    e2: Vec3,
    radius: f64,
    sweep: f64,
}

impl BlendArc {
    /// The path element's geometry.
    fn geom(&self) -> Geom {
        Geom::Blend {
            center: self.center,
            e1: self.e1,
            e2: self.e2,
            radius: self.radius,
            sweep: self.sweep,
        }
    }
}

/// [`fillet::line_arc`] of these arguments: the fillet worked out ahead where it was
/// worked out from the same bits ([`FilletAhead::matching`]), else computed here.
fn line_arc_or_ahead(
    ahead: Option<&FilletAhead>,
    corner: Vec3,
    u: Vec3,
    line_avail_mm: f64,
    arc: &ArcView,
    arc_avail_mm: f64,
    tol_mm: f64,
) -> Option<fillet::Fillet> {
    if let Some(found) =
        ahead.and_then(|h| h.matching(corner, u, line_avail_mm, arc, arc_avail_mm, tol_mm))
    {
        return found;
    }
    fillet::line_arc(corner, u, line_avail_mm, arc, arc_avail_mm, tol_mm)
}

/// The stretch of a planar arc of at most one revolution between its points `from`
/// and `to`, as an arc of its own (same centre, plane and direction).
fn sub_arc(prim: &Primitive, from: Vec3, to: Vec3) -> Primitive {
    let Primitive::Arc {
        center,
        plane,
        sweep,
        ..
    } = *prim
    else {
        return *prim;
    };
    let turns = if sweep > 0.0 { 1 } else { -1 };
    Primitive::arc(from, to, center, plane, turns)
}

/// The stretch of a planar arc of at most one revolution (fillets take only those,
/// [`fillet::ArcView::of`]) that leaves `start_rad` of its sweep at its start and
/// `end_rad` at its end to fillets, between their touch points `from` and `to`, as an
/// arc of its own: [`sub_arc`] with the angles the fillets gave instead of two
/// `atan2`s of the points. Its radius is the programmed start radius, which `from`
/// lies on (the fillet's touch point, or the arc's start); `to` lies on the circle
/// through the arc's end, so a rounded end radius still runs as a spiral between the
/// two. (The builder cuts the arc in place, [`cut_by_angles`]; this is the same
/// cut on a copy, for the tests.)
#[cfg(test)]
fn sub_arc_by_angles(
    prim: &Primitive,
    from: Vec3,
    to: Vec3,
    start_rad: f64,
    end_rad: f64,
) -> Primitive {
    let mut sub = *prim;
    cut_by_angles(&mut sub, from, to, start_rad, end_rad);
    sub
}

/// [`sub_arc_by_angles`] in place: the arc `arc` becomes its stretch (the builder
/// copies the held arc onto the path and cuts it there: an arc put together on the
/// stack, its plane a byte beside seven of padding, was copied from there in
/// 16-byte loads that waited on narrower stores just before them).
fn cut_by_angles(arc: &mut Primitive, from: Vec3, to: Vec3, start_rad: f64, end_rad: f64) {
    let Primitive::Arc {
        start,
        center,
        plane,
        start_angle,
        sweep,
        normal_travel,
        end,
        ..
    } = arc
    else {
        return;
    };
    let sign = sweep.signum();
    // the centre with the start's component along the normal (`plane.axes().2`),
    // put together by name: an index worked out at run time took the vector through
    // the stack, and its 16-byte reload waited on the component's store
    let [cx, cy, cz] = center.0;
    let [fx, fy, fz] = from.0;
    *center = match plane {
        Plane::XY => Vec3::new(cx, cy, fz),
        Plane::XZ => Vec3::new(cx, fy, cz),
        Plane::YZ => Vec3::new(fx, cy, cz),
    };
    *start = from;
    *start_angle += sign * start_rad;
    *sweep -= sign * (start_rad + end_rad);
    *normal_travel = 0.0;
    *end = to;
}

/// The signed sweep of an arc (0 for a line).
fn prim_sweep(prim: &Primitive) -> f64 {
    match *prim {
        Primitive::Arc { sweep, .. } => sweep,
        Primitive::Line { .. } => 0.0,
    }
}

/// The stretch [`from`, `to`] (arc length) of an arc or helix, of any number of
/// turns, as an arc of its own: the programmed parametrisation (angle, normal travel
/// and the radius's linear change all proportional to arc length) restricted to it;
/// `at_from`, `at_to` are its points there (`Primitive::point_at`).
fn sub_arc_span(prim: &Primitive, from: f64, to: f64, at_from: Vec3, at_to: Vec3) -> Primitive {
    let Primitive::Arc {
        center,
        plane,
        radius,
        start_angle,
        sweep,
        normal_travel,
        end,
        ..
    } = *prim
    else {
        return *prim;
    };
    let len = prim.length();
    let (u0, u1) = (from / len, to / len);
    let n = plane.axes().2;
    let end_radius = plane.radius_at(center, end);
    let mut c = center;
    c[n] = at_from[n];
    Primitive::Arc {
        start: at_from,
        center: c,
        plane,
        radius: radius + (end_radius - radius) * u0,
        start_angle: start_angle + sweep * u0,
        sweep: sweep * (u1 - u0),
        normal_travel: normal_travel * (u1 - u0),
        end: at_to,
    }
}

/// Whether an arc or helix may be trimmed by a biarc: any the reader took (an end
/// radius that differs from the start's runs as the programmed spiral, the radius
/// changing linearly with the angle; the biarc touches it along its true tangent,
/// [`path_tangent`], and the sub-arc keeps its parametrisation).
fn trimmable_arc(prim: &Primitive) -> bool {
    match *prim {
        Primitive::Arc { radius, .. } => radius > 0.0,
        Primitive::Line { .. } => true,
    }
}

/// The unit tangent at arc length `s` of the path `Primitive::point_at` draws: on an
/// arc whose end radius differs from its start's, the derivative of
/// c + r(u)·(cos θ(u), sin θ(u)) + h·u·n with r, θ linear in u = s/length, which
/// has the radial component r_e − r₀ beside the circle's r(u)·sweep
/// (`Primitive::tangent_at` gives the circle's).
fn path_tangent(prim: &Primitive, s: f64) -> Vec3 {
    let Primitive::Arc {
        center,
        plane,
        radius,
        start_angle,
        sweep,
        normal_travel,
        end,
        ..
    } = *prim
    else {
        return prim.tangent_at(s);
    };
    let len = prim.length();
    let u = if len > 0.0 {
        (s / len).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (a, b, n) = plane.axes();
    let dr = plane.radius_at(center, end) - radius;
    if dr == 0.0 {
        return prim.tangent_at(s);
    }
    let r = radius + dr * u;
    let th = start_angle + sweep * u;
    let (sin, cos) = th.sin_cos();
    let mut t = Vec3::ZERO;
    t[a] = dr * cos - r * sweep * sin;
    t[b] = dr * sin + r * sweep * cos;
    t[n] = normal_travel;
    t.unit()
}

/// Unit tangent of an arc or helix at its start or end (`Primitive::tangent_at` there)
/// from the radial vector of the start or end point, without trigonometry:
/// R·sweep·(−sin θ, cos θ) = sweep·(−r_b, r_a)·R/|r| in the plane, the normal travel
/// along the normal.
///
/// The vector is put together for each plane by name (not by the indices of
/// [`Plane::axes`]: no stores and loads through the stack), and where the start or a
/// planar end is at the radius the scale of 1 is not multiplied in (x·1 = x).
///
/// Out of line for the builder's kink test (inlining it there grows the builder's
/// loop past what its other calls are inlined in); [`ArcPrep::of`], on the reading
/// thread, takes [`arc_end_tangent_inline`].
fn arc_end_tangent(p: &Primitive, at_end: bool) -> Vec3 {
    arc_end_tangent_inline(p, at_end)
}

/// [`arc_end_tangent`], inlined where it is called.
fn arc_end_tangent_inline(p: &Primitive, at_end: bool) -> Vec3 {
    let Primitive::Arc {
        start,
        center,
        plane,
        radius,
        sweep,
        normal_travel,
        end,
        ..
    } = *p
    else {
        return p.tangent_at(0.0);
    };
    let q = if at_end { end } else { start };
    // (a, b) in the plane: the same differences as `q[a] - center[a]` and so on
    let (ra, rb) = match plane {
        Plane::XY => (q[0] - center[0], q[1] - center[1]),
        Plane::XZ => (q[2] - center[2], q[0] - center[0]),
        Plane::YZ => (q[1] - center[1], q[2] - center[2]),
    };
    // the start point is at the radius; the end point of a helix may not be
    let (ta, tb) = if at_end && normal_travel != 0.0 {
        let scale = radius / ra.hypot(rb);
        (-sweep * rb * scale, sweep * ra * scale)
    } else {
        (-sweep * rb, sweep * ra)
    };
    let t = match plane {
        Plane::XY => Vec3::new(ta, tb, normal_travel),
        Plane::XZ => Vec3::new(tb, normal_travel, ta),
        Plane::YZ => Vec3::new(normal_travel, ta, tb),
    };
    t.unit()
}

/// The programmed radius of an arc (0 for a line).
fn arc_radius_mm(p: &Primitive) -> f64 {
    match *p {
        Primitive::Arc { radius, .. } => radius,
        Primitive::Line { .. } => 0.0,
    }
}

/// Unit tangent at the end of a move held back by the builder.
fn end_tangent(g: &Geom, dir: Vec3, len: f64) -> Vec3 {
    match g {
        Geom::Arc(p) => p.tangent_at(len),
        _ => dir,
    }
}

/// Unit tangent at the start of a move held back by the builder.
fn start_tangent(g: &Geom, dir: Vec3) -> Vec3 {
    match g {
        Geom::Arc(p) => p.tangent_at(0.0),
        _ => dir,
    }
}

/// What an element may ask of each axis's acceleration: its tangential acceleration
/// `acc` and, on a curve, the centripetal κv². On axis i the two add up to
/// |t_i·a_t + n_i·a_n| ≤ √(t_i² + n_i²)·√(a_t² + a_n²) ≤ weight_i·√(acc² + (κv²)²)
/// (`ElementShape::acc_weight`: |u_i| on a line, √(t_i² + n_i²) on a curve).
#[derive(Debug, Clone, Copy, Default)]
struct AccUse {
    weight: [f64; 3],
    /// The tangential acceleration a_t (mm/s²).
    acc_mm_per_s2: f64,
    /// The centripetal κ·v_top², v_top the element's cap or its feed at the largest
    /// override (its highest speed) (mm/s²).
    normal_mm_per_s2: f64,
    /// The element's length (mm).
    len_mm: f64,
}

impl AccUse {
    fn of(shape: &ElementShape, acc_mm_per_s2: f64, cap: f64, feed: f64, lim: &Limits) -> AccUse {
        let v = min_to(cap, feed * lim.max_feed_override);
        AccUse {
            weight: shape.acc_weight,
            acc_mm_per_s2,
            normal_mm_per_s2: shape.curvature * v * v,
            len_mm: shape.len,
        }
    }

    /// √(a_t² + (κ·v_top²)²) (mm/s²): worked out only where a junction needs it
    /// (a tangent break with room to look at), not for every element.
    fn magnitude_mm_per_s2(&self) -> f64 {
        let (a_t, a_n) = (self.acc_mm_per_s2, self.normal_mm_per_s2);
        if a_n > 0.0 {
            (a_t * a_t + a_n * a_n).sqrt()
        } else {
            a_t
        }
    }
}

/// Highest speed through the junction of two elements. A tangent break of Δt turns
/// the velocity by v·Δt_i within one cycle: on each axis that takes v·|Δt_i|/T on top
/// of what the elements on either side use there (the sampled second difference
/// across the junction averages the two elements' accelerations and adds the step).
/// So the step may use the room the two elements leave on each axis,
/// A_i − max(use_a_i, use_b_i) with the uses of [`AccUse`] at the junction's speed
/// bound — at least `KINK_SHARE` of A_i, which every element leaves (its limits are
/// planned to `1 − KINK_SHARE`), and about half of A_i between two curves (whose
/// tangential share is `ARC_TANGENTIAL_SHARE`). S-curve: stop at it, and keep the
/// curvature step within its jerk share; with acc/dec after interpolation the feed
/// passes it unchanged, reversals excepted.
///
/// Inline (into [`PathBuilder::push_element`]): out of line it took its nine
/// arguments and the curvature closure through the stack, about 29 instructions an
/// element (planning thread −11.6 M on the 200k-line program).
#[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
fn junction_speed(
    lim: &Limits,
    cap_a: f64,
    cap_b: f64,
    end_tangent_a: Vec3,
    b: &ElementShape,
    uses: [&AccUse; 2],
    curvature_step: impl Fn() -> Vec3,
) -> f64 {
    let mut v = min_to(cap_a, cap_b);
    let dt = b.start_tangent - end_tangent_a;
    if lim.acc_dec == AccDec::AfterInterpolation {
        // |Δt| = 2 sin(θ/2): reversals still stop
        let turn_rad = 2.0 * (0.5 * dt.norm()).min(1.0).asin();
        if turn_rad <= MAX_BLEND_TURN_RAD {
            return v;
        }
    }
    let kink = dt.norm() > TANGENT_EPS;
    if kink && lim.profile == FeedProfile::SCurve {
        // a tangent break at speed is a jerk impulse: stop there
        return 0.0;
    }
    if kink {
        let v_bound = v;
        // the kink share every element leaves; T/|Δt_i| kept for the room below
        let mut v_share = v_bound;
        let mut t_over_dt = [0.0; 3];
        for i in 0..3 {
            let di = dt[i].abs();
            if di > 1e-12 {
                t_over_dt[i] = lim.cycle_s / di;
                v_share = min_to(v_share, lim.kink_acc[i] * t_over_dt[i]);
            }
        }
        v = v_share;
        // More than the kink share only where no other tangent break can fall within
        // a cycle of this one: both elements at least a cycle's travel long (speed
        // within a cycle of the junction at most v + a·T). The sampled second
        // difference weighs the breaks within its two cycles by 1 − |τ|/T, which
        // then sum to at most 1, and a window of n cycles takes at most n of them.
        let v_spacing = if v_share < v_bound {
            uses[0].len_mm.min(uses[1].len_mm) / lim.cycle_s
                - lim.path_acc_bound_mm_per_s2 * lim.cycle_s
        } else {
            0.0
        };
        if v_spacing > v_share {
            // the room the two elements leave
            let mut v_room = v_bound.min(v_spacing);
            let magnitudes = [uses[0].magnitude_mm_per_s2(), uses[1].magnitude_mm_per_s2()];
            for (i, &t_dt) in t_over_dt.iter().enumerate() {
                if t_dt > 0.0 {
                    let full = lim.amax[i] + lim.kink_acc[i];
                    // the most of axis i's acceleration either element uses at any
                    // speed it runs at
                    let used =
                        (uses[0].weight[i] * magnitudes[0]).max(uses[1].weight[i] * magnitudes[1]);
                    let room = (full - used).max(lim.kink_acc[i]);
                    v_room = v_room.min(room * t_dt);
                }
            }
            v = v_share.max(v_room);
        }
    }
    if lim.profile == FeedProfile::SCurve {
        let dk = curvature_step();
        for i in 0..3 {
            let di = dk[i].abs();
            if di > 1e-12 {
                let budget = SCURVE_CURVATURE_STEP_SHARE * lim.jmax[i] * lim.cycle_s * 4.0 / 3.0;
                v = v.min((budget / di).sqrt());
            }
        }
    }
    v
}

/// Programmed primitive of a motion in machine coordinates (None for dwells).
///
/// Inlined into its callers: returned through the stack, the reader's loop copied
/// each 112-byte result to the vector with 16-byte loads of what it had just stored
/// in 8-byte pieces, which the processor cannot forward (a stall at each of them).
#[inline]
pub fn motion_primitive(m: &Motion) -> Option<Primitive> {
    let off = m.offset_mm;
    match m.kind {
        MotionKind::Traverse { end } | MotionKind::Feed { end, .. } => Some(Primitive::Line {
            start: m.start + off,
            end: end + off,
        }),
        MotionKind::Arc {
            end,
            center,
            plane,
            turns,
            ..
        } => Some(Primitive::arc(
            m.start + off,
            end + off,
            center + off,
            plane,
            turns,
        )),
        // (a probe move is refused before it is built: `PlanError::ProbeMove`)
        MotionKind::Dwell { .. }
        | MotionKind::Pause { .. }
        | MotionKind::Sync
        | MotionKind::Probe { .. }
        | MotionKind::Machine(_) => None,
    }
}

/// Build the whole path of a program at once.
pub fn build_path(program: &Program, lim: &Limits) -> Path {
    let mut b = PathBuilder::new(lim, program.motions.len());
    for (i, m) in program.motions.iter().enumerate() {
        b.push(i, m, motion_primitive(m));
    }
    b.finish()
}

/// S-curve: the smoothed position lags the acceleration-limited one, so a hard speed
/// limit c (an element's cap or a junction's limit) must already hold on the
/// acceleration-limited profile within R = max(W·c, (c² + a²W²)/(2a)) of where it
/// applies (W the window, a the path acceleration): inside, the window sees no faster
/// motion; outside, braking at a keeps v ≤ distance/W. Stops are not spread, and no
/// limit is spread across a stop: the profile waits one window there, so a smoothed
/// sample before the stop averages only motion before it, one after only motion
/// after it.
fn dilate_caps(segs: &mut [Segment], window_s: f64, acc: f64) {
    let n = segs.len();
    let mut dilated: Vec<f64> = segs.iter().map(|s| s.vel_cap).collect();
    let reach =
        |c: f64| (window_s * c).max((c * c + acc * acc * window_s * window_s) / (2.0 * acc));
    // (limit, start, end) of each constraint along the path
    let spread = |c: f64, from: f64, to: f64, k: usize, dilated: &mut [f64]| {
        let r = reach(c);
        dilated[k] = dilated[k].min(c);
        let mut j = k;
        while j > 0 && segs[j - 1].v_end_hard != 0.0 && segs[j - 1].s0 + segs[j - 1].len >= from - r
        {
            j -= 1;
            dilated[j] = dilated[j].min(c);
        }
        let mut j = k + 1;
        while j < n && segs[j - 1].v_end_hard != 0.0 && segs[j].s0 <= to + r {
            dilated[j] = dilated[j].min(c);
            j += 1;
        }
    };
    for (k, seg) in segs.iter().enumerate() {
        let (a, b) = (seg.s0, seg.s0 + seg.len);
        if seg.len > 0.0 {
            spread(seg.vel_cap, a, b, k, &mut dilated);
        }
        let v = seg.v_end_hard;
        if v > 0.0 && v.is_finite() {
            spread(v, b, b, k, &mut dilated);
        }
    }
    for k in 0..n {
        segs[k].vel_cap = dilated[k];
        let next = if k + 1 < n { dilated[k + 1] } else { 0.0 };
        segs[k].v_end_hard = segs[k].v_end_hard.min(dilated[k]).min(next);
    }
}

/// [`dilate_caps`] on a stream of elements, with bounded memory: the same caps, bit
/// for bit (a minimum over the same constraints), each element handed on once no
/// later constraint can reach it. Every constraint's reach is at most that of the
/// fastest speed the axes allow (|V|, the norm of the axes' limits: an element's cap
/// keeps every axis within its V_i, so v² = Σ(t_i·v)² ≤ Σ V_i²), so an element is
/// settled once the path has gone that reach beyond the end of the element after it.
pub(crate) struct CapDilator {
    window_s: f64,
    acc: f64,
    /// Reach of the fastest constraint possible (mm).
    reach_max_mm: f64,
    /// Elements not yet settled and their dilated cap, in order.
    held: std::collections::VecDeque<(Segment, Geom, f64)>,
    /// Constraints reaching forward: (last path position they reach, cap).
    ahead: Vec<(f64, f64)>,
}

impl CapDilator {
    /// For the limits `lim` (S-curve window and acceleration).
    pub(crate) fn new(lim: &Limits) -> CapDilator {
        let v_top = Vec3::new(lim.vmax[0], lim.vmax[1], lim.vmax[2]).norm();
        let mut d = CapDilator {
            window_s: lim.scurve_window_s,
            acc: lim.scurve_acc,
            reach_max_mm: 0.0,
            held: std::collections::VecDeque::new(),
            ahead: Vec::new(),
        };
        // rounding may put a cap a few ulps above |V|: a margin far above that
        d.reach_max_mm = d.reach(v_top * (1.0 + 1e-6));
        d
    }

    /// R(c) exactly as [`dilate_caps`] computes it.
    fn reach(&self, c: f64) -> f64 {
        let (window_s, acc) = (self.window_s, self.acc);
        (window_s * c).max((c * c + acc * acc * window_s * window_s) / (2.0 * acc))
    }

    /// The next element (its limits as the builder settled them); settled elements go
    /// to `out` with their dilated caps.
    pub(crate) fn push(
        &mut self,
        seg: &Segment,
        geom: &Geom,
        out: &mut impl FnMut(&Segment, &Geom),
    ) {
        let (a, b) = (seg.s0, seg.s0 + seg.len);
        // no constraint reaches across a stop
        if self.held.back().is_some_and(|h| h.0.v_end_hard == 0.0) {
            self.ahead.clear();
        }
        // constraints of the elements before that reach this one
        let mut d = seg.vel_cap;
        self.ahead.retain(|&(until, c)| {
            if a <= until {
                d = d.min(c);
                true
            } else {
                false // the path only goes on: it never reaches another element
            }
        });
        // this element's own, back over the held elements and ahead
        let own = |c: f64, from: f64, to: f64, d: &mut f64, this: &mut CapDilator| {
            let r = this.reach(c);
            *d = d.min(c);
            for h in this.held.iter_mut().rev() {
                if h.0.v_end_hard != 0.0 && h.0.s0 + h.0.len >= from - r {
                    h.2 = h.2.min(c);
                } else {
                    break;
                }
            }
            this.ahead.push((to + r, c));
        };
        if seg.len > 0.0 {
            own(seg.vel_cap, a, b, &mut d, self);
        }
        let v = seg.v_end_hard;
        if v > 0.0 && v.is_finite() {
            own(v, b, b, &mut d, self);
        }
        self.held.push_back((*seg, *geom, d));
        // no later constraint reaches back before `settled`
        let settled = b - self.reach_max_mm;
        while self.held.len() >= 2 && self.held[1].0.s0 + self.held[1].0.len < settled {
            self.emit_front(out);
        }
    }

    fn emit_front(&mut self, out: &mut impl FnMut(&Segment, &Geom)) {
        let Some((mut seg, geom, d)) = self.held.pop_front() else {
            return;
        };
        let next = self.held.front().map_or(0.0, |h| h.2);
        seg.vel_cap = d;
        seg.v_end_hard = seg.v_end_hard.min(d).min(next);
        out(&seg, &geom);
    }

    /// The end of the path: the held elements to `out`.
    pub(crate) fn finish(mut self, out: &mut impl FnMut(&Segment, &Geom)) {
        while !self.held.is_empty() {
            self.emit_front(out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_core::Plane;

    /// The default machine with arc blends, and the motions of a CAM-like program:
    /// line–arc and arc–line joins, a G64 Q chain before an arc, a dwell, a pause, an
    /// exact stop, a zero-length line and a tolerance change among them.
    fn fillet_joins() -> (Limits, Vec<Motion>) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
        let mut p = MotionProfile::load(&dir.join("default.ron")).unwrap();
        p.planner.arc_blends = true;
        let text = crate::test_programs::fillet_joins_program(40, "M0", false, None);
        let program = softnc_gcode::read_program(&text, "f.ngc", &p).unwrap();
        (Limits::from_profile(&p), program.motions)
    }

    /// The path of `motions` with their arc data and, unless `tamper` is None, the
    /// fillets worked out ahead (in chunks of 7 motions) changed by it, and how many
    /// were handed over.
    fn path_with_fillets_ahead(
        lim: &Limits,
        motions: &[Motion],
        tamper: Option<&dyn Fn(&mut FilletAhead)>,
    ) -> (String, usize) {
        let prims: Vec<_> = motions.iter().map(motion_primitive).collect();
        let preps: Vec<_> = prims.iter().map(ArcPrep::of).collect();
        let mut ahead = FilletsAhead::new(lim, false);
        let mut aheads = vec![None; motions.len()];
        let mut part = vec![];
        for c in (0..motions.len()).step_by(7) {
            let e = (c + 7).min(motions.len());
            let work = tamper.is_some();
            ahead.chunk(&motions[c..e], &prims[c..e], &preps[c..e], work, &mut part);
            for (k, mut f) in part.drain(..) {
                if let Some(t) = tamper {
                    t(&mut f);
                }
                aheads[c + k as usize] = Some(f);
            }
        }
        let mut b = PathBuilder::new(lim, motions.len());
        for (k, m) in motions.iter().enumerate() {
            b.push_prepared(k, m, &prims[k], preps[k].as_ref(), aheads[k].as_ref());
        }
        let path = b.finish();
        let handed = aheads.iter().flatten().count();
        (format!("{:?}{:?}", path.segs, path.geoms), handed)
    }

    /// A fillet worked out ahead (`FilletsAhead`) gives the builder's own path; the
    /// builder takes one whose arguments are its own bits (a tampered result shows in
    /// the path) and no other (a tolerance one ulp off: the tampered result is not
    /// taken).
    #[test]
    fn fillets_ahead_are_taken_where_their_arguments_are_the_builders() {
        let (lim, motions) = fillet_joins();
        let (own, _) = path_with_fillets_ahead(&lim, &motions, None);
        let (ahead, handed) = path_with_fillets_ahead(&lim, &motions, Some(&|_| {}));
        assert!(handed >= 60, "{handed} fillets handed over");
        assert_eq!(ahead, own, "fillets ahead: the same path");
        let (none, _) = path_with_fillets_ahead(&lim, &motions, Some(&|f| f.found = None));
        assert_ne!(none, own, "the fillets handed over are taken");
        let (off, _) = path_with_fillets_ahead(
            &lim,
            &motions,
            Some(&|f| {
                f.found = None;
                f.tol_mm = f64::from_bits(f.tol_mm.to_bits() + 1);
            }),
        );
        assert_eq!(off, own, "a fillet from other arguments is not taken");
    }

    /// `sub_arc_by_angles` (the fillets' angles) gives the stretch `sub_arc` (two
    /// `atan2`s of the touch points) gives: same start angle, sweep and points, for
    /// both directions, in all three planes, trimmed at one end or both.
    #[test]
    fn sub_arc_by_angles_is_sub_arc() {
        for plane in [Plane::XY, Plane::XZ, Plane::YZ] {
            let (a, b, n) = plane.axes();
            for turns in [1, -1] {
                let (radius, th0, th1) = (2.5f64, 0.3f64, 2.9f64);
                let at = |th: f64| {
                    let mut p = Vec3::ZERO;
                    p[a] = 1.0 + radius * th.cos();
                    p[b] = -2.0 + radius * th.sin();
                    p[n] = 0.7;
                    p
                };
                let mut c = Vec3::ZERO;
                c[a] = 1.0;
                c[b] = -2.0;
                let (start, end) = if turns > 0 {
                    (at(th0), at(th1))
                } else {
                    (at(th1), at(th0))
                };
                let prim = Primitive::arc(start, end, c, plane, turns);
                let sweep = prim_sweep(&prim);
                for (s_rad, e_rad) in [(0.4, 0.0), (0.0, 0.7), (0.25, 0.5)] {
                    let sign = sweep.signum();
                    let prim_angle = |th: f64| match prim {
                        Primitive::Arc { start_angle, .. } => start_angle + sign * th,
                        _ => unreachable!(),
                    };
                    let from = at(prim_angle(s_rad));
                    let to = at(prim_angle(sweep.abs() - e_rad));
                    let want = sub_arc(&prim, from, to);
                    let got = sub_arc_by_angles(&prim, from, to, s_rad, e_rad);
                    let (Primitive::Arc { sweep: ws, .. }, Primitive::Arc { sweep: gs, .. }) =
                        (want, got)
                    else {
                        unreachable!()
                    };
                    assert!((ws - gs).abs() < 1e-12, "{plane:?} {turns}: {ws} vs {gs}");
                    // the centre (its normal component the start's, put together by
                    // plane in `cut_by_angles`), the plane and the end points: the
                    // same bits as `sub_arc`'s (the radius is the programmed one, not
                    // `from`'s distance)
                    let parts = |p: Primitive| match p {
                        Primitive::Arc {
                            start,
                            center,
                            plane,
                            normal_travel,
                            end,
                            ..
                        } => (start, center, plane, normal_travel, end),
                        _ => unreachable!(),
                    };
                    assert_eq!(parts(want), parts(got), "{plane:?} {turns}");
                    assert!((want.length() - got.length()).abs() < 1e-12);
                    for k in 0..=10 {
                        let s = want.length() * k as f64 / 10.0;
                        let d = (want.point_at(s) - got.point_at(s)).norm();
                        assert!(d < 1e-12, "{plane:?} {turns} at {s}: {d}");
                    }
                    assert_eq!(got.start(), from);
                    assert_eq!(got.end(), to);
                }
            }
        }
    }
}
