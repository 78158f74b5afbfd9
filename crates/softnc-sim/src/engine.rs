//! One position cycle, as the daemon and the simulator both run it: read the encoders,
//! step every axis's controller stack, write the commands, let the machine move.

use crate::backend::{BackendError, ServoBackend, SimBackend, SimOptions, MAX_AXES};
use crate::plant::CommandMode;
use softnc_control::compensation::{AxisCompensation, CompensationError};
use softnc_control::discrete_tf::DiscreteTf;
use softnc_control::zero_lag_fir::{CommandFilter, FirDesignError};
use softnc_control::AxisController;
use softnc_core::servo::PlantModel;
use softnc_core::{CommandRing, MachineProfile};

/// Why an axis's disturbance compensation (paper 000) could not be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("servo.axes[{axis}].compensation: {error}")]
pub struct CompensationDesignError {
    /// Axis index.
    pub axis: usize,
    /// What failed.
    pub error: CompensationError,
}

/// Why a profile's controller stacks could not be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum EngineError {
    /// The disturbance compensation (paper 000) failed its design.
    #[error(transparent)]
    Compensation(#[from] CompensationDesignError),
    /// The zero-lag command filter (paper 002) could not be designed.
    #[error("servo.axes[{axis}].command_filter: {error}")]
    Filter {
        /// Axis index.
        axis: usize,
        /// What failed.
        error: FirDesignError,
    },
}

impl EngineError {
    /// The axis whose design failed.
    pub fn axis(&self) -> usize {
        match self {
            EngineError::Compensation(e) => e.axis,
            EngineError::Filter { axis, .. } => *axis,
        }
    }
}

/// What one cycle produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct CycleRecord {
    /// Command position per axis (mm).
    pub cmd_mm: [f64; MAX_AXES],
    /// Measured position at the start of the cycle, when the command was compared (mm).
    pub actual_mm: [f64; MAX_AXES],
    /// Following error command − measured (mm).
    pub following_mm: [f64; MAX_AXES],
    /// Command written to each drive (its command mode's units).
    pub ctrl_out: [f64; MAX_AXES],
}

/// Controller stacks and a servo backend, stepped one cycle at a time.
#[derive(Debug, Clone)]
pub struct CycleEngine<B: ServoBackend> {
    filter: CommandFilter<MAX_AXES>,
    spindle: Option<crate::spindle::SpindleSchedule>,
    controllers: [AxisController; MAX_AXES],
    modes: [CommandMode; MAX_AXES],
    mm_per_count: [f64; MAX_AXES],
    backend: B,
}

impl CycleEngine<SimBackend> {
    /// The simulated machine of `profile` with its controllers, seeded by `seed`.
    ///
    /// # Panics
    /// When the profile's disturbance compensation cannot be designed; see
    /// [`CycleEngine::try_new`].
    pub fn simulated(profile: &MachineProfile, seed: u64, options: SimOptions) -> Self {
        CycleEngine::new(profile, SimBackend::new(profile, seed, options))
    }
}

impl<B: ServoBackend> CycleEngine<B> {
    /// The profile's controllers in front of `backend`.
    ///
    /// # Panics
    /// When the profile's disturbance compensation or command filter cannot be
    /// designed (a PDC that fails eq 11–13, an unstable MBDA, …);
    /// [`CycleEngine::try_new`] reports it.
    pub fn new(profile: &MachineProfile, backend: B) -> Self {
        match Self::try_new(profile, backend) {
            Ok(e) => e,
            Err(err) => panic!("{err}"),
        }
    }

    /// The profile's controllers, with their disturbance compensation designed for
    /// the profile's spindle speed, and its command filters, in front of `backend`.
    pub fn try_new(profile: &MachineProfile, backend: B) -> Result<Self, EngineError> {
        let mut e = Self::without_compensation(profile, backend);
        e.filter = CommandFilter::design(
            [0, 1, 2].map(|i| profile.axis_servo(i).command_filter),
            profile.interpolation_cycle_s,
        )
        .map_err(|(axis, error)| EngineError::Filter { axis, error })?;
        let fd_hz = profile.servo.cutting.as_ref().map(|c| c.frequency_hz());
        e.design_compensation(profile, fd_hz)?;
        e.reset([0.0; MAX_AXES]);
        Ok(e)
    }

    /// Design (or remove) every axis's compensation from `profile` for tooth
    /// frequency `fd_hz` (off the real-time path: it allocates). Axes whose profile
    /// has no compensation get none.
    pub fn design_compensation(
        &mut self,
        profile: &MachineProfile,
        fd_hz: Option<f64>,
    ) -> Result<(), CompensationDesignError> {
        let cycle_s = profile.interpolation_cycle_s;
        for axis in 0..MAX_AXES {
            let servo = profile.axis_servo(axis);
            let cfg = &servo.compensation;
            let wanted =
                cfg.pdc.is_some() || cfg.outer != softnc_core::compensation::OuterCompensator::None;
            if !wanted {
                self.controllers[axis].compensation = None;
                continue;
            }
            let err = |error| CompensationDesignError { axis, error };
            let PlantModel::VelocityLoop {
                num, den, lead_mm, ..
            } = servo.plant
            else {
                return Err(err(CompensationError::Plant));
            };
            let p_n = DiscreteTf::new(vec![0.0, num[0], num[1]], vec![1.0, den[0], den[1]])
                .map_err(|e| err(e.into()))?;
            let c = AxisCompensation::design(cfg, &p_n, cycle_s, lead_mm, fd_hz).map_err(err)?;
            self.controllers[axis].compensation = Some(Box::new(c));
        }
        Ok(())
    }

    /// Redesign every axis's PDC for a new tooth frequency (spindle speed or
    /// override change). The design runs here, between cycles; the new filters are
    /// swapped in at the start of the next [`CycleEngine::step`].
    pub fn redesign_pdc(&mut self, fd_hz: f64) -> Result<(), CompensationDesignError> {
        for (axis, c) in self.controllers.iter_mut().enumerate() {
            let Some(comp) = c.compensation.as_deref_mut() else {
                continue;
            };
            let Some(designer) = comp.pdc_designer() else {
                continue;
            };
            let d = designer
                .design(fd_hz)
                .map_err(|e| CompensationDesignError {
                    axis,
                    error: e.into(),
                })?;
            comp.stage_pdc(d);
        }
        Ok(())
    }

    /// The profile's controllers without compensation in front of `backend`.
    fn without_compensation(profile: &MachineProfile, backend: B) -> Self {
        let cycle_s = profile.interpolation_cycle_s;
        let controllers =
            [0, 1, 2].map(|i| AxisController::new(&profile.axis_servo(i).controller, cycle_s));
        let modes = [0, 1, 2].map(|i| backend.command_mode(i));
        let mm_per_count = [0, 1, 2].map(|i| backend.mm_per_count(i));
        let mut e = CycleEngine {
            filter: CommandFilter::default(),
            spindle: None,
            controllers,
            modes,
            mm_per_count,
            backend,
        };
        e.reset([0.0; MAX_AXES]);
        e
    }

    /// Put the axes at rest at `pos_mm` (start of a job).
    pub fn reset(&mut self, pos_mm: [f64; MAX_AXES]) {
        self.backend.home(pos_mm);
        for (c, x) in self.controllers.iter_mut().zip(pos_mm) {
            c.reset(x);
        }
    }

    /// Measured positions (mm).
    #[inline]
    pub fn measured_mm(&self) -> [f64; MAX_AXES] {
        let counts = self.backend.read_counts();
        [0, 1, 2].map(|i| counts[i] as f64 * self.mm_per_count[i])
    }

    /// One cycle with command `cmd_mm`; `cutting` tells the machine whether the tool
    /// is in the material (feed moves).
    #[inline]
    pub fn step(
        &mut self,
        cmd_mm: [f64; MAX_AXES],
        cutting: bool,
    ) -> Result<CycleRecord, BackendError> {
        // 1. inputs
        let actual_mm = self.measured_mm();
        // 2. controller stacks
        let mut out = [0.0; MAX_AXES];
        for i in 0..MAX_AXES {
            let u = self.controllers[i].step(cmd_mm[i], actual_mm[i]).u;
            out[i] = match self.modes[i] {
                // the drive closes the loop: it gets the command position itself
                CommandMode::Position => cmd_mm[i],
                CommandMode::Velocity | CommandMode::Effort => u,
            };
        }
        // 3. outputs, and the machine moves one cycle
        self.backend.set_cutting(cutting);
        self.backend.write_commands(out);
        self.backend.cycle()?;
        Ok(CycleRecord {
            cmd_mm,
            actual_mm,
            following_mm: [0, 1, 2].map(|i| cmd_mm[i] - actual_mm[i]),
            ctrl_out: out,
        })
    }

    /// The job's spindle speed changes ((first motion, rpm), 0 = stopped; from its
    /// S, M3, M4, M5 words, `Plan::spindle_changes`): every axis's PDC is designed now
    /// for each speed (off the cycle path: this allocates) and
    /// [`CycleEngine::step_ring`] swaps the designs in at the cycle where a speed takes
    /// effect, and tells the backend. Without a cutting section in the profile (no
    /// flute count, no tooth frequency) there is nothing to follow.
    pub fn set_spindle_schedule(
        &mut self,
        profile: &MachineProfile,
        changes: &[(u32, f64)],
    ) -> Result<(), CompensationDesignError> {
        let Some(cutting) = profile.servo.cutting.as_ref() else {
            self.spindle = None;
            return Ok(());
        };
        let mut s = crate::spindle::SpindleSchedule::new(
            cutting.spindle_rpm,
            f64::from(cutting.flutes),
            changes,
        );
        for k in 1..s.speeds_rpm.len() {
            for (axis, c) in self.controllers.iter().enumerate() {
                let Some(designer) = c.compensation.as_deref().and_then(|c| c.pdc_designer())
                else {
                    continue;
                };
                let d = designer
                    .design(s.fd_hz[k])
                    .map_err(|e| CompensationDesignError {
                        axis,
                        error: e.into(),
                    })?;
                s.taps[k][axis] = Some(d.h_taps);
            }
        }
        self.spindle = Some(s);
        Ok(())
    }

    /// The spindle schedule of the job, if one was set.
    pub fn spindle_schedule(&self) -> Option<&crate::spindle::SpindleSchedule> {
        self.spindle.as_ref()
    }

    /// At a cycle boundary: put back the taps the last swap retired, and if motion
    /// `motion` runs the spindle at another speed, stage its designs and tell the
    /// backend. Moves vectors, never allocates.
    fn follow_spindle(&mut self, motion: u32) {
        let Some(s) = self.spindle.as_mut() else {
            return;
        };
        if let Some(from) = s.retiring.take() {
            for (axis, c) in self.controllers.iter_mut().enumerate() {
                if let Some(comp) = c.compensation.as_deref_mut() {
                    if let Some(t) = comp.take_retired() {
                        s.taps[from][axis] = Some(t);
                    }
                }
            }
        }
        let Some(k) = s.change_at(motion) else {
            return;
        };
        for (axis, c) in self.controllers.iter_mut().enumerate() {
            if let (Some(comp), Some(taps)) =
                (c.compensation.as_deref_mut(), s.taps[k][axis].take())
            {
                comp.stage_taps(taps, s.fd_hz[k]);
            }
        }
        s.retiring = Some(s.active);
        s.active = k;
        self.backend.set_spindle_rpm(s.speeds_rpm[k]);
    }

    /// Samples the command filters read ahead of (and behind) the current one: the
    /// position task starts motion only when this many future samples are in.
    pub fn filter_window(&self) -> usize {
        self.filter.window()
    }

    /// The command filters (paper 002).
    pub fn command_filter(&self) -> &CommandFilter<MAX_AXES> {
        &self.filter
    }

    /// One cycle at the ring's current sample, of program motion `motion`: the
    /// spindle speed of that motion takes effect (its PDC designs swapped in), the
    /// command filters (paper 002 eq 1) read the window [i−N, i+N] and the
    /// controllers get the filtered command. `None` (nothing stepped) until the
    /// window is in.
    #[inline]
    pub fn step_ring(
        &mut self,
        ring: &CommandRing,
        motion: u32,
        cutting: bool,
    ) -> Option<Result<CycleRecord, BackendError>> {
        let cmd_mm = self.filter.apply(ring)?;
        self.follow_spindle(motion);
        Some(self.step(cmd_mm, cutting))
    }

    /// The backend.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The controller of axis `axis`.
    pub fn controller(&self, axis: usize) -> &AxisController {
        &self.controllers[axis]
    }
}
