//! Manual motion between jobs, on the position cycle: jogs (continuous and
//! incremental) and homing, one [`AxisMover`] per axis and the profile's homing
//! sequence ([`softnc_planner::manual`]). Nothing here allocates after
//! [`Manual::new`]: the homing order is kept in a fixed array.
//!
//! The home switches are simulated (a switch trips where the profile puts it, on the
//! measured position): the simulated and loopback backends have none of their own;
//! a drive's home input is read through the backend when one is attached.

use softnc_core::AxisConfig;
use softnc_machine::MachineProfile;
use softnc_planner::manual::{
    jog_target, simulated_switch_active, AxisMover, HomingEvent, HomingSequence, JogDirection,
};

/// Axes the position process moves.
const AXES: usize = 3;

/// What the manual motion did this cycle, beyond its command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ManualEvent {
    /// Axis `axis` was re-referenced: its coordinates move by `correction_mm` (the
    /// caller shifts its measured and commanded positions).
    Rereferenced {
        /// Axis index.
        axis: usize,
        /// New coordinate − old coordinate (mm).
        correction_mm: f64,
    },
    /// Axis `axis` is homed.
    Homed {
        /// Axis index.
        axis: usize,
    },
    /// Homing of axis `axis` failed (it is at rest, not homed).
    HomingFailed {
        /// Axis index.
        axis: usize,
        /// Why (fixed text).
        why: softnc_planner::manual::HomingError,
    },
}

/// Jogs and homing between jobs.
pub struct Manual {
    axes: [AxisConfig; AXES],
    profile: MachineProfile,
    movers: [AxisMover; AXES],
    /// The homing under way: its axis and sequence.
    homing: Option<(usize, HomingSequence)>,
    /// Axes still to home after it, in order.
    queue: [usize; AXES],
    queue_len: usize,
    queue_next: usize,
    /// The profile's homing order.
    order: [usize; AXES],
    order_len: usize,
    /// A motion is under way (jog or homing).
    active: bool,
}

impl Manual {
    /// Manual motion for `profile`'s axes, at rest at `pos_mm`.
    pub fn new(profile: &MachineProfile, pos_mm: [f64; AXES]) -> anyhow::Result<Manual> {
        let dt_s = profile.interpolation_cycle_s;
        let axes: [AxisConfig; AXES] = std::array::from_fn(|i| profile.axes[i].clone());
        let mut movers = Vec::with_capacity(AXES);
        for (a, p) in axes.iter().zip(pos_mm) {
            movers.push(AxisMover::for_axis(a, p, dt_s)?);
        }
        let movers: [AxisMover; AXES] = movers
            .try_into()
            .map_err(|_| anyhow::anyhow!("three axes"))?;
        let mut order = [0; AXES];
        let listed = profile.homing_order();
        for (slot, i) in order.iter_mut().zip(&listed) {
            *slot = *i;
        }
        Ok(Manual {
            axes,
            profile: profile.clone(),
            movers,
            homing: None,
            queue: [0; AXES],
            queue_len: 0,
            queue_next: 0,
            order,
            order_len: listed.len().min(AXES),
            active: false,
        })
    }

    /// A jog or homing is under way.
    pub fn active(&self) -> bool {
        self.active
    }

    /// Homing is under way.
    pub fn homing(&self) -> bool {
        self.homing.is_some()
    }

    /// The axes stand at `pos_mm` (a job ended there, the machine came on, an
    /// E-stop cut a jog or a homing short): nothing is under way any more, so the
    /// next jog or homing starts afresh (a homing cut short left `active` set, and
    /// every later `home` was refused as if one still ran).
    pub fn hold(&mut self, pos_mm: [f64; AXES]) {
        for (m, p) in self.movers.iter_mut().zip(pos_mm) {
            m.reset(p);
        }
        self.homing = None;
        self.queue_len = 0;
        self.queue_next = 0;
        self.active = false;
    }

    /// Continuous jog of `axis` at `speed_mm_per_s` (signed; 0 stops it), to the
    /// soft limit when `homed`.
    pub fn jog(&mut self, axis: usize, speed_mm_per_s: f64, homed: bool) {
        if axis >= AXES || self.homing.is_some() || !speed_mm_per_s.is_finite() {
            return;
        }
        let m = &mut self.movers[axis];
        if speed_mm_per_s == 0.0 {
            m.stop();
            return;
        }
        let dir = if speed_mm_per_s > 0.0 {
            JogDirection::Positive
        } else {
            JogDirection::Negative
        };
        let target = jog_target(&self.axes[axis], m.pos_mm(), dir, homed);
        let speed = self
            .profile
            .jog
            .speed_mm_per_s(&self.axes[axis], Some(speed_mm_per_s.abs()));
        if m.move_to(target, speed).is_ok() {
            self.active = true;
        }
    }

    /// Incremental jog of `axis` by `step_mm` at the profile's jog speed; refused
    /// (false) beyond a soft limit of a homed axis.
    pub fn jog_step(&mut self, axis: usize, step_mm: f64, homed: bool) -> bool {
        if axis >= AXES || self.homing.is_some() || !step_mm.is_finite() {
            return false;
        }
        let a = &self.axes[axis];
        let m = &mut self.movers[axis];
        let target = m.target_mm().unwrap_or(m.pos_mm()) + step_mm;
        if homed && !(a.min_mm..=a.max_mm).contains(&target) {
            return false;
        }
        let speed = self.profile.jog.speed_mm_per_s(a, None);
        let ok = m.move_to(target, speed).is_ok();
        self.active |= ok;
        ok
    }

    /// Home `axis`, or every axis in the profile's order (`None`). False: the
    /// profile has no homing (absolute encoders) for it.
    pub fn home(&mut self, axis: Option<usize>) -> bool {
        if self.profile.homing.is_none() || self.active {
            return false;
        }
        self.queue_len = 0;
        self.queue_next = 0;
        match axis {
            Some(i) if i < AXES => {
                self.queue[0] = i;
                self.queue_len = 1;
            }
            Some(_) => return false,
            None => {
                self.queue[..self.order_len].copy_from_slice(&self.order[..self.order_len]);
                self.queue_len = self.order_len;
            }
        }
        self.active = self.queue_len > 0;
        self.active
    }

    /// Stop every motion (abort): decelerate to rest; homing ends unfinished.
    pub fn stop(&mut self) {
        if let Some((i, seq)) = self.homing.take() {
            self.movers[i].reset(seq.command_mm());
        }
        self.queue_len = 0;
        for m in &mut self.movers {
            m.stop();
        }
    }

    /// One cycle: the command for every axis, given the measured positions (in the
    /// coordinates of the commands); an event when one happened.
    pub fn step(&mut self, measured_mm: [f64; AXES]) -> ([f64; AXES], Option<ManualEvent>) {
        let mut event = None;
        if self.homing.is_none() && self.queue_next < self.queue_len {
            let i = self.queue[self.queue_next];
            self.queue_next += 1;
            match HomingSequence::from_profile(&self.profile, i, self.movers[i].pos_mm()) {
                Ok(seq) => self.homing = Some((i, seq)),
                Err(_) => self.queue_len = 0,
            }
        }
        let mut cmd = [0.0; AXES];
        for (i, m) in self.movers.iter_mut().enumerate() {
            cmd[i] = if matches!(self.homing, Some((h, _)) if h == i) {
                m.pos_mm()
            } else {
                m.step()
            };
        }
        if let Some((i, seq)) = self.homing.as_mut() {
            let i = *i;
            let switch = self
                .profile
                .homing
                .as_ref()
                .and_then(|h| h.axes.get(i))
                .is_some_and(|h| {
                    simulated_switch_active(h.search_vel_mm_per_s, h.switch_mm, measured_mm[i])
                });
            let s = seq.step(measured_mm[i], switch);
            cmd[i] = s.command_mm;
            match s.event {
                Some(HomingEvent::Rereferenced { correction_mm }) => {
                    event = Some(ManualEvent::Rereferenced {
                        axis: i,
                        correction_mm,
                    });
                }
                Some(HomingEvent::Done) => {
                    self.movers[i].reset(s.command_mm);
                    self.homing = None;
                    event = Some(ManualEvent::Homed { axis: i });
                }
                Some(HomingEvent::Failed(why)) => {
                    self.movers[i].reset(s.command_mm);
                    self.homing = None;
                    self.queue_len = 0;
                    event = Some(ManualEvent::HomingFailed { axis: i, why });
                }
                None => {}
            }
        }
        self.active = self.homing.is_some()
            || self.queue_next < self.queue_len
            || self.movers.iter().any(|m| !m.at_rest());
        (cmd, event)
    }
}
