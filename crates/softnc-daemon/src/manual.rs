//! Manual motion between jobs, on the position cycle: jogs (continuous and
//! incremental) and homing, one [`AxisMover`] per axis and the profile's homing
//! sequence ([`softnc_planner::manual`]). Nothing here allocates after
//! [`Manual::new`]: the homing order is kept in a fixed array.
//!
//! The homing sequence is LinuxCNC's on the home switch (`softnc_planner::manual`'s
//! [`HomingSequence`]): search toward the switch at HOME_SEARCH_VEL
//! (`search_vel_mm_per_s`), back off it at HOME_LATCH_VEL (`latch_vel_mm_per_s`)
//! and latch where it releases, the latch point reads HOME_OFFSET (`switch_mm`),
//! then the move to HOME (`home_mm`); a switch already active at the start is
//! backed off first. The switch is the axis's `Home` input
//! ([`MachineInputs::home`], read through the I/O boundary `softnc_servo::io`) when
//! the profile's `servo.io` maps one for the axis; an axis without one keeps a
//! switch simulated on its measured position (active at and beyond `switch_mm` in
//! the search direction). A limit switch of the axis tripping while it homes aborts
//! the homing (it brakes to rest and fails: LinuxCNC's "hit limit in home state").

use softnc_core::machine_io::MachineInputs;
use softnc_core::AxisConfig;
use softnc_machine::MachineProfile;
use softnc_planner::manual::{
    jog_target, simulated_switch_active, AxisMover, HomingError, HomingEvent, HomingSequence,
    JogDirection,
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
    /// Bit i: axis i homes on its `Home` input (else on the simulated switch).
    home_inputs: u32,
}

impl Manual {
    /// Manual motion for `profile`'s axes, at rest at `pos_mm`; bit i of
    /// `home_inputs` set: axis i has a home switch input (`MachineIo::home_switches`).
    pub fn new(
        profile: &MachineProfile,
        pos_mm: [f64; AXES],
        home_inputs: u32,
    ) -> anyhow::Result<Manual> {
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
            home_inputs,
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

    /// The axis homing now.
    pub fn homing_axis(&self) -> Option<usize> {
        self.homing.as_ref().map(|(i, _)| *i)
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
    /// coordinates of the commands) and the inputs read with them; an event when
    /// one happened.
    pub fn step(
        &mut self,
        measured_mm: [f64; AXES],
        inputs: &MachineInputs,
    ) -> ([f64; AXES], Option<ManualEvent>) {
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
            let bit = 1u32 << i;
            let switch = if self.home_inputs & bit != 0 {
                inputs.home & bit != 0
            } else {
                self.profile
                    .homing
                    .as_ref()
                    .and_then(|h| h.axes.get(i))
                    .is_some_and(|h| {
                        simulated_switch_active(h.search_vel_mm_per_s, h.switch_mm, measured_mm[i])
                    })
            };
            if (inputs.limit_min | inputs.limit_max) & bit != 0 {
                seq.abort(HomingError::LimitSwitch {
                    max: inputs.limit_max & bit != 0,
                });
            }
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

#[cfg(test)]
mod tests {
    //! Homing on the simulated machine (`softnc_sim`'s backend behind a cycle
    //! engine, its home and limit switches wired as its cabinet), stepped as the
    //! position cycle steps it.
    use super::*;
    use softnc_planner::manual::HomingError;
    use softnc_servo::CycleEngine;
    use softnc_sim::{SimBackend, SimOptions};

    const Z: usize = 2;

    fn shipped() -> MachineProfile {
        MachineProfile::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../config/machines/default-incremental.ron"),
        )
        .unwrap()
    }

    /// `p` with its simulated machine's Z home switch at `switch_mm` (the homing
    /// section is where the simulated cabinet puts it).
    fn z_switch_at(mut p: MachineProfile, switch_mm: f64) -> MachineProfile {
        p.homing.as_mut().unwrap().axes[Z].switch_mm = switch_mm;
        p
    }

    struct Run {
        /// Z's command every cycle, in the frame before re-referencing.
        z_cmd_before: Vec<f64>,
        events: Vec<ManualEvent>,
        engine: CycleEngine<SimBackend>,
        last_cmd: [f64; AXES],
        /// Z's home input was seen active.
        home_seen: bool,
    }

    /// Home Z of `manual` (the profile the daemon reads) on the simulated machine
    /// of `machine` (the cabinet), from `start_mm`, as `PositionTask` steps it.
    fn home_z(manual: &MachineProfile, machine: &MachineProfile, start_mm: [f64; AXES]) -> Run {
        let mut engine =
            softnc_sim::simulated_engine(machine, machine.servo.seed, SimOptions::default());
        engine.reset(start_mm);
        let mut m = Manual::new(manual, start_mm, engine.io().home_switches()).unwrap();
        assert!(m.home(Some(Z)));
        let mut run = Run {
            z_cmd_before: vec![],
            events: vec![],
            last_cmd: start_mm,
            home_seen: false,
            engine,
        };
        let mut rereferenced = false;
        for _ in 0..200_000 {
            let inputs = *run.engine.io().last_inputs();
            run.home_seen |= inputs.home & 1 << Z != 0;
            let (cmd, ev) = m.step(run.engine.measured_mm().0, &inputs);
            if let Some(ManualEvent::Rereferenced {
                axis,
                correction_mm,
            }) = ev
            {
                let mut at = run.last_cmd;
                at[axis] = run.engine.measured_mm()[axis] + correction_mm;
                run.engine.reset(at);
                rereferenced = true;
            }
            run.events.extend(ev);
            if !rereferenced {
                run.z_cmd_before.push(cmd[Z]);
            }
            run.engine.step(cmd, false).unwrap();
            run.last_cmd = cmd;
            if !m.active() {
                // the axis settles on the last command (the drive's lag)
                for _ in 0..1000 {
                    run.engine.step(run.last_cmd, false).unwrap();
                }
                return run;
            }
        }
        panic!("homing did not end: {:?}", run.events);
    }

    fn max(v: &[f64]) -> f64 {
        v.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    }

    /// The machine's switch is 5 mm short of where the profile says: the search
    /// stops on the switch input there (not where the profile's figure would), the
    /// latch point reads HOME_OFFSET (`switch_mm`) and Z ends at HOME.
    #[test]
    fn the_home_switch_input_stops_the_search_and_sets_the_position() {
        let manual = shipped();
        let h = manual.homing.as_ref().unwrap().axes[Z];
        let machine = z_switch_at(shipped(), h.switch_mm - 5.0);
        let r = home_z(&manual, &machine, [0.0; AXES]);
        assert!(r.home_seen);
        assert_eq!(r.events.last(), Some(&ManualEvent::Homed { axis: Z }));
        let v = h.search_vel_mm_per_s;
        let braking_mm = v * v / (2.0 * manual.axes[Z].max_acc_mm_per_s2);
        let top = max(&r.z_cmd_before);
        assert!(
            top >= h.switch_mm - 5.0 && top <= h.switch_mm - 5.0 + braking_mm + v * 0.002,
            "the search went to {top} mm"
        );
        // the latch point (5 mm short of the profile's figure) reads HOME_OFFSET:
        // the coordinates move by +5 mm (to the latch's resolution), then Z goes
        // to HOME
        let correction_mm = r
            .events
            .iter()
            .find_map(|e| match e {
                ManualEvent::Rereferenced { correction_mm, .. } => Some(*correction_mm),
                _ => None,
            })
            .unwrap();
        assert!((correction_mm - 5.0).abs() < 0.01, "{correction_mm}");
        assert_eq!(r.last_cmd[Z], h.home_mm);
        let measured = r.engine.measured_mm()[Z];
        assert!((measured - h.home_mm).abs() < 0.01, "{measured}");
    }

    /// Without a `Home` input for the axis in the I/O map, today's behaviour: the
    /// switch is simulated on the measured position at `switch_mm`.
    #[test]
    fn without_a_home_input_the_switch_is_simulated_at_the_profiles_figure() {
        let mut manual = shipped();
        if let Some(io) = manual.servo.io.as_mut() {
            io.inputs
                .retain(|l| !matches!(l.signal, softnc_machine::io::InputSignal::Home(_)));
        }
        let h = manual.homing.as_ref().unwrap().axes[Z];
        let mut machine = z_switch_at(manual.clone(), h.switch_mm - 5.0);
        machine.servo.io = manual.servo.io.clone();
        let r = home_z(&manual, &machine, [0.0; AXES]);
        assert!(!r.home_seen, "no Home input mapped");
        assert_eq!(r.events.last(), Some(&ManualEvent::Homed { axis: Z }));
        assert!(max(&r.z_cmd_before) >= h.switch_mm);
        assert_eq!(r.last_cmd[Z], h.home_mm);
    }

    /// Z starts on its switch: it backs off first (down, away from it), then
    /// searches, latches and ends at HOME.
    #[test]
    fn a_switch_active_at_the_start_is_backed_off_first() {
        let p = shipped();
        let h = p.homing.as_ref().unwrap().axes[Z];
        let start = h.switch_mm + 2.0;
        let r = home_z(&p, &p, [0.0, 0.0, start]);
        assert_eq!(r.events.last(), Some(&ManualEvent::Homed { axis: Z }));
        let low = r.z_cmd_before.iter().copied().fold(f64::INFINITY, f64::min);
        // backed off until the switch released (its edge, behind the lagging axis)
        assert!(low < h.switch_mm + 0.01, "backed off to {low} mm only");
        assert_eq!(r.last_cmd[Z], h.home_mm);
        let true_mm = r.engine.backend().true_pos_mm()[Z];
        assert!((true_mm - h.home_mm).abs() < 0.01, "{true_mm}");
    }

    /// The switch lies beyond the maximum limit switch: the search trips the limit,
    /// the homing is aborted (a homing error), Z brakes to rest just past it.
    #[test]
    fn a_limit_switch_hit_during_the_search_is_a_homing_error() {
        let manual = shipped();
        let margin = manual.servo.sim_io.unwrap().limit_switch_margin_mm;
        let limit_mm = manual.axes[Z].max_mm + margin;
        let machine = z_switch_at(shipped(), limit_mm + 20.0);
        let r = home_z(&manual, &machine, [0.0; AXES]);
        assert_eq!(
            r.events,
            vec![ManualEvent::HomingFailed {
                axis: Z,
                why: HomingError::LimitSwitch { max: true }
            }]
        );
        let at = r.engine.measured_mm()[Z];
        assert!(at >= limit_mm && at < limit_mm + 0.5, "stopped at {at} mm");
    }

    /// No switch within the search travel (travel span + 2 × switch margin): a
    /// homing error, at rest.
    #[test]
    fn no_switch_within_the_travel_is_a_homing_error() {
        let manual = shipped();
        let mut machine = z_switch_at(shipped(), 1e6);
        machine.servo.sim_io = None; // no limit switches either
        let r = home_z(&manual, &machine, [0.0; AXES]);
        let hc = manual.homing.as_ref().unwrap();
        let travel_mm = manual.axes[Z].max_mm - manual.axes[Z].min_mm + 2.0 * hc.switch_margin_mm;
        assert_eq!(
            r.events,
            vec![ManualEvent::HomingFailed {
                axis: Z,
                why: HomingError::SwitchNotFound { travel_mm }
            }]
        );
        assert_eq!(r.last_cmd[Z], travel_mm);
    }
}
