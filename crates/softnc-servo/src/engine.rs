//! One position cycle, as the daemon and the simulator both run it: read the encoders,
//! step every axis's controller stack, write the commands, let the machine move.

use crate::backend::{BackendError, CommandMode, ServoBackend, MAX_AXES};
use crate::design::CompensationDesignError;
use softnc_control::compensation::{AxisCompensation, CompensationError};
use softnc_control::discrete_tf::DiscreteTf;
use softnc_control::zero_lag_fir::{CommandFilter, FirDesignError};
use softnc_control::AxisController;
use softnc_core::Axes;
use softnc_core::CommandRing;
use softnc_machine::servo::PlantModel;
use softnc_machine::MachineProfile;

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
    pub cmd_mm: Axes<f64>,
    /// Measured position at the start of the cycle, when the command was compared (mm).
    pub actual_mm: Axes<f64>,
    /// Following error command − measured (mm).
    pub following_mm: Axes<f64>,
    /// Command written to each drive (its command mode's units).
    pub ctrl_out: Axes<f64>,
}

/// Controller stacks and a servo backend, stepped one cycle at a time.
#[derive(Debug, Clone)]
pub struct CycleEngine<B: ServoBackend> {
    filter: CommandFilter<MAX_AXES>,
    spindle: Option<crate::spindle::SpindleSchedule>,
    controllers: [AxisController; MAX_AXES],
    modes: [CommandMode; MAX_AXES],
    mm_per_count: Axes<f64>,
    /// The machine's named signals on the backend's lines.
    io: crate::io::MachineIo,
    /// The outputs of the sample in use (the program's).
    program_outputs: softnc_core::machine_io::MachineOutputs,
    /// Machine on, amplifiers enabled, spindle override.
    out_state: crate::io::OutputState,
    backend: B,
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
            std::array::from_fn(|i| profile.axis_servo(i).command_filter),
            profile.interpolation_cycle_s,
        )
        .map_err(|(axis, error)| EngineError::Filter { axis, error })?;
        let fd_hz = profile.servo.cutting.as_ref().map(|c| c.frequency_hz());
        e.design_compensation(profile, fd_hz)?;
        e.reset(Axes::splat(0.0));
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
            let wanted = cfg.pdc.is_some()
                || cfg.outer != softnc_machine::compensation::OuterCompensator::None;
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
        let controllers = std::array::from_fn(|i| {
            AxisController::new(&profile.axis_servo(i).controller, cycle_s)
        });
        let modes = std::array::from_fn(|i| backend.command_mode(i));
        let mm_per_count = std::array::from_fn(|i| backend.mm_per_count(i));
        let io = crate::io::MachineIo::new(profile, backend.io_lines());
        let mut e = CycleEngine {
            filter: CommandFilter::default(),
            spindle: None,
            controllers,
            modes,
            mm_per_count: Axes(mm_per_count),
            io,
            program_outputs: softnc_core::machine_io::MachineOutputs::default(),
            out_state: crate::io::OutputState::default(),
            backend,
        };
        e.reset(Axes::splat(0.0));
        e
    }

    /// Put the axes at rest at `pos_mm` (start of a job).
    pub fn reset(&mut self, pos_mm: impl Into<Axes<f64>>) {
        let pos_mm = pos_mm.into();
        self.backend.home(pos_mm);
        for (c, x) in self.controllers.iter_mut().zip(pos_mm) {
            c.reset(x);
        }
    }

    /// Restart every controller at `cmd_mm`, as on enabling the drives: no
    /// integrator, filter or feed-forward state from before (a stop, the drives
    /// off) carries over, so the first command after it steps no integrator. The
    /// backend is not homed: its positions stay what they read. Allocation-free.
    pub fn restart_controllers_at(&mut self, cmd_mm: impl Into<Axes<f64>>) {
        for (c, x) in self.controllers.iter_mut().zip(cmd_mm.into()) {
            c.reset(x);
        }
    }

    /// This engine runs the next job from `start_mm`, after `running`, the engine
    /// of the machine until now: a backend [kept across
    /// jobs](ServoBackend::kept_across_jobs) moves over from `running` as it stands
    /// (enabled, homed: a drive is not re-homed to the command, which would fold
    /// the following error into its offset) and only the controllers start at
    /// `start_mm`; any other backend is this engine's own, homed at `start_mm`
    /// ([`reset`](Self::reset)). At a cycle boundary: swaps, allocates nothing.
    pub fn take_over(&mut self, running: &mut CycleEngine<B>, start_mm: impl Into<Axes<f64>>) {
        let start_mm = start_mm.into();
        // the I/O's state (debounce, the E-stop latch) is the machine's, not the job's
        self.io.take_state_from(&running.io);
        self.out_state = running.out_state;
        // and so are the outputs held between jobs (the spindle turning, coolant)
        self.program_outputs = running.program_outputs;
        if running.backend.kept_across_jobs() {
            std::mem::swap(&mut self.backend, &mut running.backend);
            for (c, x) in self.controllers.iter_mut().zip(start_mm) {
                c.reset(x);
            }
        } else {
            self.reset(start_mm);
            self.backend.take_external_io(&running.backend);
        }
    }

    /// Measured positions (mm).
    #[inline]
    pub fn measured_mm(&self) -> Axes<f64> {
        let counts = self.backend.read_counts();
        Axes::from_fn(|a| counts[a] as f64 * self.mm_per_count[a])
    }

    /// One cycle with command `cmd_mm`; `cutting` tells the machine whether the tool
    /// is in the material (feed moves).
    #[inline]
    pub fn step(
        &mut self,
        cmd_mm: impl Into<Axes<f64>>,
        cutting: bool,
    ) -> Result<CycleRecord, BackendError> {
        let cmd_mm = cmd_mm.into();
        // 1. inputs
        let actual_mm = self.measured_mm();
        // 2. controller stacks
        let mut out = Axes::splat(0.0);
        for i in 0..MAX_AXES {
            let u = self.controllers[i].step(cmd_mm[i], actual_mm[i]).u;
            out[i] = match self.modes[i] {
                // the drive closes the loop: it gets the command position itself
                CommandMode::Position => cmd_mm[i],
                CommandMode::Velocity | CommandMode::Effort => u,
            };
        }
        // 3. outputs, and the machine moves one cycle (the I/O exchanged with it)
        if let Some(sim) = self.backend.simulated() {
            sim.set_cutting(cutting);
        }
        let raw = self.io.outputs(&self.program_outputs, self.out_state);
        self.backend.write_io(&raw);
        self.backend.write_commands(out);
        self.backend.cycle()?;
        let raw = self.backend.read_io();
        self.io.inputs(&raw);
        Ok(CycleRecord {
            cmd_mm,
            actual_mm,
            following_mm: Axes::from_fn(|a| cmd_mm[a] - actual_mm[a]),
            ctrl_out: out,
        })
    }

    /// The outputs of the sample in use from the next cycle on (the program's: the
    /// safe state goes out instead while the machine is off or E-stopped).
    #[inline]
    pub fn set_outputs(&mut self, outputs: &softnc_core::machine_io::MachineOutputs) {
        self.program_outputs = *outputs;
    }

    /// Machine on, amplifiers enabled and the spindle override from the next cycle
    /// on.
    #[inline]
    pub fn set_output_state(&mut self, state: crate::io::OutputState) {
        self.out_state = state;
    }

    /// The I/O alone, on a cycle that does not step the axes (drives off,
    /// E-stop): the outputs written, the backend's I/O exchanged, the inputs read.
    #[inline]
    pub fn exchange_io(&mut self) -> Result<softnc_core::machine_io::MachineInputs, BackendError> {
        let raw = self.io.outputs(&self.program_outputs, self.out_state);
        self.backend.write_io(&raw);
        self.backend.exchange_io()?;
        let raw = self.backend.read_io();
        Ok(self.io.inputs(&raw))
    }

    /// The machine's named signals: the inputs last read, the outputs last
    /// written, the E-stop latch.
    pub fn io(&self) -> &crate::io::MachineIo {
        &self.io
    }

    /// The named signals, to reset the E-stop latch (off or on the cycle: nothing
    /// allocates).
    pub fn io_mut(&mut self) -> &mut crate::io::MachineIo {
        &mut self.io
    }

    /// The designer of the job's PDC tables: each axis's PDC designer and the
    /// distinct programmed speeds of `changes` ((first motion, rpm), 0 = stopped; from
    /// its S, M3, M4, M5 words, `Plan::spindle_changes`). `None` without a cutting
    /// section in the profile (no flute count, no tooth frequency: nothing to follow).
    /// Allocates: call it off the cycle path, and hand the designer to a design thread
    /// for the operator's spindle overrides.
    pub fn spindle_designer(
        &self,
        profile: &MachineProfile,
        changes: &[(u32, f64)],
    ) -> Option<crate::spindle::SpindleDesigner> {
        let cutting = profile.servo.cutting.as_ref()?;
        let (speeds_rpm, _) = crate::spindle::SpindleSchedule::plan(cutting.spindle_rpm, changes);
        Some(crate::spindle::SpindleDesigner {
            designers: std::array::from_fn(|i| {
                self.controllers[i]
                    .compensation
                    .as_deref()
                    .and_then(|c| c.pdc_designer())
                    .cloned()
            }),
            speeds_rpm,
            flutes: f64::from(cutting.flutes),
        })
    }

    /// The job's spindle speed changes ((first motion, rpm), 0 = stopped; from its
    /// S, M3, M4, M5 words, `Plan::spindle_changes`) at spindle override
    /// `override_frac`: every axis's PDC is designed now for each speed (off the cycle
    /// path: this allocates) and [`CycleEngine::step_ring`] swaps the designs in at the
    /// cycle where a speed takes effect, and tells the backend. Without a cutting
    /// section in the profile there is nothing to follow. The I/O's spindle speed
    /// command is the programmed speed × `override_frac` from now on either way.
    pub fn set_spindle_schedule(
        &mut self,
        profile: &MachineProfile,
        changes: &[(u32, f64)],
        override_frac: f64,
    ) -> Result<(), CompensationDesignError> {
        self.out_state.spindle_override = override_frac;
        let Some(designer) = self.spindle_designer(profile, changes) else {
            self.spindle = None;
            return Ok(());
        };
        let table = designer.design(override_frac)?;
        let (speeds_rpm, changes) =
            crate::spindle::SpindleSchedule::plan(designer.speeds_rpm[0], changes);
        // the design running now (the profile's speed, no override) is replaced by the
        // table's first speed at the first cycle, like an installed override
        let slots = vec![[None, None, None]; speeds_rpm.len()];
        self.spindle = Some(crate::spindle::SpindleSchedule {
            changes,
            next: 0,
            speeds_rpm,
            table,
            active: 0,
            retiring: None,
            installed: true,
            replaced: Some(Box::new(crate::spindle::SpindleDesigns {
                override_frac: 1.0,
                fd_hz: Vec::new(),
                taps: slots,
            })),
        });
        Ok(())
    }

    /// The spindle schedule of the job, if one was set.
    pub fn spindle_schedule(&self) -> Option<&crate::spindle::SpindleSchedule> {
        self.spindle.as_ref()
    }

    /// Install the designs of a new spindle override (made by the job's
    /// [`crate::spindle::SpindleDesigner`] on a design thread): the running speed's
    /// design and the spindle's new speed take effect at the next cycle boundary.
    /// Moves vectors, never allocates. Refused (the designs come back) without a
    /// schedule, for another job's table, or while the table replaced last is still
    /// waiting for [`CycleEngine::take_replaced_spindle_designs`].
    pub fn install_spindle_designs(
        &mut self,
        mut designs: Box<crate::spindle::SpindleDesigns>,
    ) -> Result<(), Box<crate::spindle::SpindleDesigns>> {
        self.collect_retired();
        let Some(s) = self.spindle.as_mut() else {
            return Err(designs);
        };
        if s.replaced.is_some() || s.installed || designs.taps.len() != s.table.taps.len() {
            return Err(designs);
        }
        std::mem::swap(&mut s.table, &mut *designs);
        s.installed = true;
        s.replaced = Some(designs);
        Ok(())
    }

    /// The table the last override (or the job's start) replaced, once the taps that
    /// ran from it are back in it: drop it off the cycle path.
    pub fn take_replaced_spindle_designs(&mut self) -> Option<Box<crate::spindle::SpindleDesigns>> {
        self.collect_retired();
        let s = self.spindle.as_mut()?;
        if s.installed || matches!(s.retiring, Some(crate::spindle::Retiring::Replaced(_))) {
            return None;
        }
        s.replaced.take()
    }

    /// Put the taps the last swap retired back where they belong.
    fn collect_retired(&mut self) {
        use crate::spindle::Retiring;
        let Some(s) = self.spindle.as_mut() else {
            return;
        };
        let Some(retiring) = s.retiring.take() else {
            return;
        };
        for (axis, c) in self.controllers.iter_mut().enumerate() {
            let Some(t) = c.compensation.as_deref_mut().and_then(|c| c.take_retired()) else {
                continue;
            };
            let slot = match retiring {
                Retiring::Table(k) => s.table.taps.get_mut(k),
                Retiring::Replaced(k) => s.replaced.as_mut().and_then(|r| r.taps.get_mut(k)),
            };
            if let Some(slot) = slot {
                slot[axis] = Some(t);
            }
        }
    }

    /// At a cycle boundary: put back the taps the last swap retired; if motion
    /// `motion` runs the spindle at another speed, or a new override's table was
    /// installed, stage the design of the speed that runs now and tell the backend.
    /// Moves vectors, never allocates.
    fn follow_spindle(&mut self, motion: u32) {
        use crate::spindle::Retiring;
        self.collect_retired();
        let Some(s) = self.spindle.as_mut() else {
            return;
        };
        let k = match s.change_at(motion) {
            Some(k) => k,
            None if s.installed => s.active,
            None => return,
        };
        for (axis, c) in self.controllers.iter_mut().enumerate() {
            if let (Some(comp), Some(taps)) =
                (c.compensation.as_deref_mut(), s.table.taps[k][axis].take())
            {
                comp.stage_taps(taps, s.table.fd_hz[k]);
            }
        }
        // the taps running now are of the replaced table if one was installed
        s.retiring = Some(if s.installed {
            Retiring::Replaced(s.active)
        } else {
            Retiring::Table(s.active)
        });
        s.installed = false;
        s.active = k;
        self.backend.set_spindle_rpm(s.effective_rpm());
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
        Some(self.step(Axes(cmd_mm), cutting))
    }

    /// The backend.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The backend, to enable or disable its drives (off the cycle path).
    pub fn backend_mut(&mut self) -> &mut B {
        &mut self.backend
    }

    /// The controller of axis `axis`.
    pub fn controller(&self, axis: usize) -> &AxisController {
        &self.controllers[axis]
    }
}
