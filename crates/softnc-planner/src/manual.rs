//! Manual motion between jobs: jogging and homing, one axis at a time, stepped once
//! per interpolation cycle T.
//!
//! - [`AxisMover`]: one axis's point-to-point generator, the idea of LinuxCNC's
//!   `simple_tp` (`src/emc/motion/simple_tp.c`: a velocity request that lets the axis
//!   stop at its target, ramped at the acceleration limit), written again for the
//!   sampled trajectory: each cycle it takes the largest velocity that keeps
//!   |Δv| ≤ a·T, |v| ≤ the commanded speed and still lets the axis stop *exactly* on
//!   the target by braking at a·T per cycle — so on the 1 ms samples the first
//!   difference stays within the velocity limit, the second within the acceleration
//!   limit, the target is never passed and is landed on exactly (to the bit), in at
//!   most the continuous trapezoid's time plus a few cycles (time-optimal on the
//!   sample grid, greedy). Retargeting mid-move and stopping keep the limits.
//! - [`jog_target`]: continuous jog = [`AxisMover::move_to`] toward the soft limit
//!   (homed) or a travel span away (unhomed, as LinuxCNC jogs unhomed joints),
//!   [`AxisMover::stop`] when the operator lets go.
//! - [`HomingSequence`]: LinuxCNC's homing sequence in short (LinuxCNC docs, "Homing
//!   Configuration", `docs/src/config/ini-homing.adoc`; HOME_SEARCH_VEL,
//!   HOME_LATCH_VEL, HOME_FINAL_VEL, HOME_OFFSET → `switch_mm`, HOME → `home_mm`):
//!   back off a tripped switch, search it, latch where it releases backing off slowly,
//!   re-reference the axis so that the latch point reads `switch_mm`, move to
//!   `home_mm`. Switch homing only (no index pulse), latching opposite to the search.
//!
//! Nothing here allocates; every `step` is a handful of floating-point operations.
//!
//! # Stepping it from the position cycle
//!
//! Between jobs, per axis `i`, once per cycle T:
//!
//! - Jog: `mover.reset(last_cmd[i])` when manual mode begins; on "jog +/−" pressed,
//!   `mover.move_to(jog_target(axis, mover.pos_mm(), dir, homed), speed)` with
//!   `speed = profile.jog.speed_mm_per_s(axis, requested)`; released → `mover.stop()`;
//!   an increment → `move_to(pos ± step, speed)`. Each cycle
//!   `cmd[i] = mover.step()`.
//! - Homing (profiles with a `homing` section; axes in `profile.homing_order()`,
//!   one at a time, the others holding): `HomingSequence::from_profile(&profile, i,
//!   cmd[i])`, then each cycle `let s = seq.step(actual_mm[i], switch[i]);
//!   cmd[i] = s.command_mm;` with the latest measured position (in the same frame as
//!   the commands) and the switch input. On [`HomingEvent::Rereferenced`] add
//!   `correction_mm` to the axis's offset (machine = encoder + offset) from this
//!   cycle on: the command already jumped by it, so the command in the encoder frame
//!   (`cmd − offset`) stays continuous. [`HomingEvent::Done`] → the axis is homed
//!   (at `home_mm`; wait for in-position if needed); [`HomingEvent::Failed`] → alarm,
//!   the axis is at rest and stays unhomed.

use softnc_core::{AxisConfig, AxisHoming, MotionProfile};

/// Why a manual motion could not be set up.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ManualError {
    /// A limit or speed is not a finite number above zero.
    #[error("{what} must be a finite number > 0 (got {value})")]
    NotPositive {
        /// Which value.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// A position is not finite.
    #[error("{what} must be a finite number (got {value})")]
    NotFinite {
        /// Which value.
        what: &'static str,
        /// The value given.
        value: f64,
    },
    /// The profile has no `homing` section (absolute encoders) or no entry for the axis.
    #[error("the machine profile has no homing settings for axis {axis}")]
    NoHoming {
        /// Axis index.
        axis: usize,
    },
}

fn positive(what: &'static str, value: f64) -> Result<f64, ManualError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ManualError::NotPositive { what, value })
    }
}

fn finite(what: &'static str, value: f64) -> Result<f64, ManualError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ManualError::NotFinite { what, value })
    }
}

/// What the mover is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    /// At rest, nothing pending.
    Idle,
    /// Going to `target_mm` at up to `speed_mm_per_s`, to stop there.
    MoveTo { target_mm: f64, speed_mm_per_s: f64 },
    /// Braking at the acceleration limit to rest, wherever that is.
    Stop,
}

/// One axis's point-to-point motion generator, stepped once per cycle `dt_s`
/// (LinuxCNC's `simple_tp`, re-derived for exact stops on the sample grid).
///
/// The velocity is the first difference of the command samples,
/// v_k = (p_k − p_{k−1})/T. With h = a·T, a move that brakes at h per cycle from
/// step velocity v (this cycle's step included) covers
/// S(v) = T·Σ_{k≥0} max(v − k·h, 0); each cycle the mover takes
/// v = clamp(sign(e)·min(speed, S⁻¹(|e|)), v_prev − h, v_prev + h) for the remaining
/// distance e, which is the largest velocity from which it can still stop exactly on
/// the target. The last step (S⁻¹(|e|) ≤ h) lands on the target bit for bit.
#[derive(Debug, Clone)]
pub struct AxisMover {
    pos_mm: f64,
    vel_mm_per_s: f64,
    max_vel_mm_per_s: f64,
    max_acc_mm_per_s2: f64,
    dt_s: f64,
    mode: Mode,
}

impl AxisMover {
    /// A mover at rest at `pos_mm` with the axis limits and the cycle `dt_s`.
    pub fn new(
        pos_mm: f64,
        max_vel_mm_per_s: f64,
        max_acc_mm_per_s2: f64,
        dt_s: f64,
    ) -> Result<Self, ManualError> {
        Ok(AxisMover {
            pos_mm: finite("pos_mm", pos_mm)?,
            vel_mm_per_s: 0.0,
            max_vel_mm_per_s: positive("max_vel_mm_per_s", max_vel_mm_per_s)?,
            max_acc_mm_per_s2: positive("max_acc_mm_per_s2", max_acc_mm_per_s2)?,
            dt_s: positive("dt_s", dt_s)?,
            mode: Mode::Idle,
        })
    }

    /// A mover for `axis` of a profile (its `max_vel_mm_per_s`, `max_acc_mm_per_s2`).
    pub fn for_axis(axis: &AxisConfig, pos_mm: f64, dt_s: f64) -> Result<Self, ManualError> {
        Self::new(pos_mm, axis.max_vel_mm_per_s, axis.max_acc_mm_per_s2, dt_s)
    }

    /// At rest at `pos_mm`, nothing pending (after a job, an abort, an E-stop).
    pub fn reset(&mut self, pos_mm: f64) {
        self.pos_mm = pos_mm;
        self.vel_mm_per_s = 0.0;
        self.mode = Mode::Idle;
    }

    /// Go to `target_mm` at up to `speed_mm_per_s` (clamped to the axis's max
    /// velocity) and stop exactly there. May be called mid-move: the new target and
    /// speed take over within the acceleration limit (a target behind the moving axis
    /// is reached after braking and reversing).
    pub fn move_to(&mut self, target_mm: f64, speed_mm_per_s: f64) -> Result<(), ManualError> {
        let target_mm = finite("target_mm", target_mm)?;
        let speed = positive("speed_mm_per_s", speed_mm_per_s)?.min(self.max_vel_mm_per_s);
        self.mode = if target_mm == self.pos_mm && self.vel_mm_per_s == 0.0 {
            Mode::Idle
        } else {
            Mode::MoveTo {
                target_mm,
                speed_mm_per_s: speed,
            }
        };
        Ok(())
    }

    /// Brake at the acceleration limit to rest, wherever that is (within
    /// v²/2a + one cycle's travel).
    pub fn stop(&mut self) {
        if self.mode != Mode::Idle {
            self.mode = Mode::Stop;
        }
    }

    /// Shift the coordinates by `offset_mm` (re-referencing after homing): position
    /// and any pending target move with it, the velocity is unchanged.
    pub fn shift(&mut self, offset_mm: f64) {
        self.pos_mm += offset_mm;
        if let Mode::MoveTo { target_mm, .. } = &mut self.mode {
            *target_mm += offset_mm;
        }
    }

    /// The next command position (one cycle on). Allocation-free.
    pub fn step(&mut self) -> f64 {
        let h = self.max_acc_mm_per_s2 * (1.0 - ACC_ROUNDING_MARGIN) * self.dt_s;
        let v = self.vel_mm_per_s;
        match self.mode {
            Mode::Idle => {}
            Mode::Stop => {
                let v_next = v - v.signum() * v.abs().min(h);
                self.pos_mm += v_next * self.dt_s;
                self.vel_mm_per_s = v_next;
                if v_next == 0.0 {
                    self.mode = Mode::Idle;
                }
            }
            Mode::MoveTo {
                target_mm,
                speed_mm_per_s,
            } => {
                let e = target_mm - self.pos_mm;
                let (reach, n) = braking_speed(e.abs(), h, self.dt_s);
                let v_des = e.signum() * reach.min(speed_mm_per_s);
                let v_next = v_des.clamp(v - h, v + h);
                // the last step: what is left is within one cycle's braking; land on
                // the target to the bit when the step taken is (to rounding) that one
                let lands = n == 1
                    && e != 0.0
                    && (v_next - e / self.dt_s).abs() <= LANDING_SLACK * h
                    && v_next.signum() == e.signum();
                if lands || e == 0.0 && v_next == 0.0 {
                    self.pos_mm = target_mm;
                    self.vel_mm_per_s = v_next.clamp(-h, h);
                    if self.vel_mm_per_s == 0.0 {
                        self.mode = Mode::Idle;
                    }
                } else {
                    self.pos_mm += v_next * self.dt_s;
                    self.vel_mm_per_s = v_next;
                }
            }
        }
        self.pos_mm
    }

    /// Current command position.
    pub fn pos_mm(&self) -> f64 {
        self.pos_mm
    }
    /// Velocity of the last step, (p_k − p_{k−1})/T.
    pub fn vel_mm_per_s(&self) -> f64 {
        self.vel_mm_per_s
    }
    /// Stopped and no motion pending.
    pub fn at_rest(&self) -> bool {
        self.mode == Mode::Idle
    }
    /// The pending target, if a move is under way.
    pub fn target_mm(&self) -> Option<f64> {
        match self.mode {
            Mode::MoveTo { target_mm, .. } => Some(target_mm),
            _ => None,
        }
    }
    /// The axis's maximum velocity.
    pub fn max_vel_mm_per_s(&self) -> f64 {
        self.max_vel_mm_per_s
    }
    /// The axis's maximum acceleration.
    pub fn max_acc_mm_per_s2(&self) -> f64 {
        self.max_acc_mm_per_s2
    }
    /// The cycle T.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }
}

/// Fraction of the acceleration limit the mover keeps in reserve for the f64
/// rounding of the command positions: a sample p_k is v·T away from p_{k−1} only to
/// half an ulp of |p|, so the sampled second difference carries up to ulp(|p|)/T² of
/// rounding (≈ 1.1·10⁻⁷ mm/s² at |p| = 1 m, T = 1 ms). Planning with (1 − 10⁻⁶)·a
/// keeps the samples within a for every a ≥ 0.2 mm/s² at that size, at a cost of
/// 10⁻⁶ of the acceleration time.
pub const ACC_ROUNDING_MARGIN: f64 = 1e-6;

/// Relative slack (of a·T) within which a last step counts as landing on the target:
/// the step's velocity and the remaining distance over T differ by rounding only.
const LANDING_SLACK: f64 = 1e-9;

/// S⁻¹(d) and its number of steps n: the largest step velocity v from which braking
/// by `h` per cycle covers exactly `d` (this step included), and how many steps that
/// takes. With n steps, v ∈ ((n−1)h, nh] and S(v) = T·(n·v − h·n(n−1)/2).
fn braking_speed(d_mm: f64, h: f64, dt_s: f64) -> (f64, u64) {
    if d_mm <= 0.0 {
        return (0.0, 0);
    }
    // S(n·h) = T·h·n(n+1)/2: the smallest n with that ≥ d
    let x = d_mm / (h * dt_s);
    let tri = |n: f64| n * (n + 1.0) / 2.0;
    let mut n = ((-1.0 + (1.0 + 8.0 * x).sqrt()) / 2.0).ceil().max(1.0);
    while n > 1.0 && tri(n - 1.0) >= x {
        n -= 1.0;
    }
    while tri(n) < x {
        n += 1.0;
    }
    let v = (d_mm / dt_s + h * n * (n - 1.0) / 2.0) / n;
    (v.clamp((n - 1.0) * h, n * h), n as u64)
}

/// Direction of a jog.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JogDirection {
    /// Toward −.
    Negative,
    /// Toward +.
    Positive,
}

/// Target of a continuous jog of `axis` from `pos_mm`: give it to
/// [`AxisMover::move_to`] with the jog speed while the key is held, [`AxisMover::stop`]
/// when it is let go. Homed: the soft limit in that direction, so the jog stops at
/// the limit without overshoot — or `pos_mm` itself when the axis already stands at
/// or beyond that limit (no motion further out). Unhomed: `pos_mm` ± the axis's
/// travel span (LinuxCNC jogs unhomed joints without soft limits).
pub fn jog_target(axis: &AxisConfig, pos_mm: f64, direction: JogDirection, homed: bool) -> f64 {
    let span_mm = axis.max_mm - axis.min_mm;
    match (direction, homed) {
        (JogDirection::Positive, true) => axis.max_mm.max(pos_mm),
        (JogDirection::Negative, true) => axis.min_mm.min(pos_mm),
        (JogDirection::Positive, false) => pos_mm + span_mm,
        (JogDirection::Negative, false) => pos_mm - span_mm,
    }
}

/// The home switch of a simulated axis: active at or beyond `trip_mm` in the search
/// direction (the sign of `search_vel_mm_per_s`), for simulated machines and tests.
pub fn simulated_switch_active(search_vel_mm_per_s: f64, trip_mm: f64, actual_mm: f64) -> bool {
    if search_vel_mm_per_s >= 0.0 {
        actual_mm >= trip_mm
    } else {
        actual_mm <= trip_mm
    }
}

/// Why homing failed. The axis is at rest when this is reported.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum HomingError {
    /// The search travelled its whole distance without the switch becoming active.
    #[error("home switch not found within {travel_mm} mm of search travel")]
    SwitchNotFound {
        /// Distance searched.
        travel_mm: f64,
    },
    /// Backing off (before the search or while latching), the switch did not
    /// release within the travel.
    #[error("home switch did not release within {travel_mm} mm of backing off")]
    SwitchNotReleased {
        /// Distance backed off.
        travel_mm: f64,
    },
    /// A limit switch of the axis tripped while it homed: the homing was aborted
    /// and the axis braked to rest (LinuxCNC's homing aborts with "hit limit in
    /// home state" unless HOME_IGNORE_LIMITS, which softnc does not have).
    #[error(
        "its {} limit switch tripped during the homing (aborted)",
        if *.max { "maximum" } else { "minimum" }
    )]
    LimitSwitch {
        /// The maximum-end switch (else the minimum-end one).
        max: bool,
    },
}

/// Phase of a [`HomingSequence`] (LinuxCNC docs, "Homing Configuration").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HomingPhase {
    /// Not stepped yet: the first step reads the switch and picks BackOff or Search.
    Start,
    /// The switch was active at start: move away from it at the search speed until
    /// it releases (LinuxCNC backs off a tripped switch, opposite to HOME_SEARCH_VEL).
    BackOff,
    /// Move toward the switch at |search_vel| (its sign is the direction) until the
    /// switch reads active; give up after the travel span plus twice the margin.
    Search,
    /// The switch was found: brake at the acceleration limit to rest.
    SearchStop,
    /// Back off the switch at |latch_vel| (opposite to the search) until it
    /// releases; the latch point is the actual position at that edge, interpolated
    /// linearly between the two cycles' actual positions (their midpoint).
    Latch,
    /// Latched: brake to rest; then the axis is re-referenced (the latch point reads
    /// `switch_mm`, LinuxCNC's HOME_OFFSET) and the final move starts.
    LatchStop,
    /// Move to `home_mm` (LinuxCNC's HOME) at `final_vel`, in corrected coordinates.
    Final,
    /// Aborted ([`HomingSequence::abort`]): braking at the acceleration limit to
    /// rest, then `Failed` with this error.
    Aborting(HomingError),
    /// Homed, at rest at `home_mm`.
    Done,
    /// Failed, at rest.
    Failed(HomingError),
}

/// Something the caller must act on, reported by one [`HomingSequence::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HomingEvent {
    /// The axis is re-referenced: machine position = encoder reading +
    /// `correction_mm` from now on. This step's command is already in the corrected
    /// coordinates (it jumped by `correction_mm`); the caller shifts its actual
    /// positions by the same amount this cycle.
    Rereferenced {
        /// Added to every position from this cycle on.
        correction_mm: f64,
    },
    /// Homed: at rest at `home_mm`.
    Done,
    /// Failed, at rest.
    Failed(HomingError),
}

/// What one cycle of homing gives the caller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomingStep {
    /// This cycle's command position (in corrected coordinates once re-referenced).
    pub command_mm: f64,
    /// The phase after this step.
    pub phase: HomingPhase,
    /// An event to act on, at most one per step.
    pub event: Option<HomingEvent>,
}

/// One axis's homing, stepped once per cycle with the axis's actual position and
/// its home switch (LinuxCNC's homing sequence for switch homing with HOME_SEARCH_VEL
/// and HOME_LATCH_VEL of opposite signs, no index; LinuxCNC docs, "Homing
/// Configuration"). The moves are [`AxisMover`] moves, so every command sample keeps
/// the axis's velocity and acceleration limits; the detections stop the mover at the
/// acceleration limit.
#[derive(Debug, Clone)]
pub struct HomingSequence {
    cfg: AxisHoming,
    mover: AxisMover,
    phase: HomingPhase,
    /// Search direction: +1 or −1 (the sign of `search_vel_mm_per_s`).
    dir: f64,
    /// Longest search or back-off distance: the travel span plus twice the margin.
    travel_mm: f64,
    prev_actual_mm: f64,
    prev_switch: bool,
    latched_mm: f64,
    correction_mm: f64,
}

impl HomingSequence {
    /// Homing of `axis` with its settings `homing`, starting at rest at `start_mm`
    /// (the axis's current command position, uncorrected); the search gives up after
    /// the travel span plus `2 · switch_margin_mm`.
    pub fn new(
        axis: &AxisConfig,
        homing: &AxisHoming,
        switch_margin_mm: f64,
        dt_s: f64,
        start_mm: f64,
    ) -> Result<Self, ManualError> {
        positive("search_vel_mm_per_s", homing.search_vel_mm_per_s.abs())?;
        positive("latch_vel_mm_per_s", homing.latch_vel_mm_per_s.abs())?;
        positive("final_vel_mm_per_s", homing.final_vel_mm_per_s)?;
        finite("switch_mm", homing.switch_mm)?;
        finite("home_mm", homing.home_mm)?;
        let margin = finite("switch_margin_mm", switch_margin_mm)?.max(0.0);
        Ok(HomingSequence {
            cfg: *homing,
            mover: AxisMover::for_axis(axis, start_mm, dt_s)?,
            phase: HomingPhase::Start,
            dir: homing.search_vel_mm_per_s.signum(),
            travel_mm: axis.max_mm - axis.min_mm + 2.0 * margin,
            prev_actual_mm: start_mm,
            prev_switch: false,
            latched_mm: f64::NAN,
            correction_mm: 0.0,
        })
    }

    /// Homing of axis `index` of `profile` (its `homing` section), from `start_mm`.
    pub fn from_profile(
        profile: &MotionProfile,
        index: usize,
        start_mm: f64,
    ) -> Result<Self, ManualError> {
        let no = ManualError::NoHoming { axis: index };
        let h = profile.homing.as_ref().ok_or(no)?;
        let (axis, homing) = profile.axes.get(index).zip(h.axes.get(index)).ok_or(no)?;
        Self::new(
            axis,
            homing,
            h.switch_margin_mm,
            profile.interpolation_cycle_s,
            start_mm,
        )
    }

    /// One cycle: `actual_mm` is the axis's actual position (in corrected
    /// coordinates once [`HomingEvent::Rereferenced`] was reported), `switch_active`
    /// its home switch. Returns this cycle's command. Allocation-free.
    pub fn step(&mut self, actual_mm: f64, switch_active: bool) -> HomingStep {
        let mut event = None;
        let search_speed = self.cfg.search_vel_mm_per_s.abs();
        let toward = self.mover.pos_mm() + self.dir * self.travel_mm;
        let away = self.mover.pos_mm() - self.dir * self.travel_mm;
        match self.phase {
            HomingPhase::Start => {
                self.phase = if switch_active {
                    HomingPhase::BackOff
                } else {
                    HomingPhase::Search
                };
                let target = if switch_active { away } else { toward };
                // speeds were checked positive in `new`
                let _ = self.mover.move_to(target, search_speed);
            }
            HomingPhase::BackOff => {
                if !switch_active {
                    // reverse into the search (the mover brakes and turns within its limits)
                    let _ = self.mover.move_to(toward, search_speed);
                    self.phase = HomingPhase::Search;
                } else if self.mover.at_rest() {
                    event = Some(self.fail(HomingError::SwitchNotReleased {
                        travel_mm: self.travel_mm,
                    }));
                }
            }
            HomingPhase::Search => {
                if switch_active {
                    self.mover.stop();
                    self.phase = HomingPhase::SearchStop;
                } else if self.mover.at_rest() {
                    event = Some(self.fail(HomingError::SwitchNotFound {
                        travel_mm: self.travel_mm,
                    }));
                }
            }
            HomingPhase::SearchStop => {
                if self.mover.at_rest() {
                    if switch_active {
                        let _ = self.mover.move_to(away, self.cfg.latch_vel_mm_per_s.abs());
                        self.phase = HomingPhase::Latch;
                    } else {
                        // the switch let go while stopping (bounce): search again
                        let _ = self.mover.move_to(toward, search_speed);
                        self.phase = HomingPhase::Search;
                    }
                }
            }
            HomingPhase::Latch => {
                if self.prev_switch && !switch_active {
                    self.latched_mm = 0.5 * (self.prev_actual_mm + actual_mm);
                    self.mover.stop();
                    self.phase = HomingPhase::LatchStop;
                } else if self.mover.at_rest() {
                    event = Some(self.fail(HomingError::SwitchNotReleased {
                        travel_mm: self.travel_mm,
                    }));
                }
            }
            HomingPhase::LatchStop => {
                if self.mover.at_rest() {
                    self.correction_mm = self.cfg.switch_mm - self.latched_mm;
                    self.mover.shift(self.correction_mm);
                    let _ = self
                        .mover
                        .move_to(self.cfg.home_mm, self.cfg.final_vel_mm_per_s);
                    self.phase = HomingPhase::Final;
                    event = Some(HomingEvent::Rereferenced {
                        correction_mm: self.correction_mm,
                    });
                }
            }
            HomingPhase::Final => {
                if self.mover.at_rest() {
                    self.phase = HomingPhase::Done;
                    event = Some(HomingEvent::Done);
                }
            }
            HomingPhase::Aborting(e) => {
                if self.mover.at_rest() {
                    event = Some(self.fail(e));
                }
            }
            HomingPhase::Done | HomingPhase::Failed(_) => {}
        }
        self.prev_actual_mm = actual_mm;
        self.prev_switch = switch_active;
        HomingStep {
            command_mm: self.mover.step(),
            phase: self.phase,
            event,
        }
    }

    /// Abort the homing with `e` (a limit switch tripped, LinuxCNC's HOME_ABORT):
    /// the axis brakes at its acceleration limit, and the step on which it is at
    /// rest reports [`HomingEvent::Failed`] with `e`. Nothing happens once the
    /// sequence is done, failed or already aborting. Allocation-free.
    pub fn abort(&mut self, e: HomingError) {
        if !matches!(
            self.phase,
            HomingPhase::Done | HomingPhase::Failed(_) | HomingPhase::Aborting(_)
        ) {
            self.mover.stop();
            self.phase = HomingPhase::Aborting(e);
        }
    }

    fn fail(&mut self, e: HomingError) -> HomingEvent {
        self.phase = HomingPhase::Failed(e);
        HomingEvent::Failed(e)
    }

    /// The current phase.
    pub fn phase(&self) -> HomingPhase {
        self.phase
    }
    /// The latch point in uncorrected coordinates (NaN before the latch).
    pub fn latched_mm(&self) -> f64 {
        self.latched_mm
    }
    /// The correction applied at re-referencing (0 before).
    pub fn correction_mm(&self) -> f64 {
        self.correction_mm
    }
    /// The last command position.
    pub fn command_mm(&self) -> f64 {
        self.mover.pos_mm()
    }
    /// True once homed.
    pub fn is_done(&self) -> bool {
        self.phase == HomingPhase::Done
    }
}
