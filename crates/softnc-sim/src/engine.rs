//! One position cycle, as the daemon and the simulator both run it: read the encoders,
//! step every axis's controller stack, write the commands, let the machine move.

use crate::backend::{BackendError, ServoBackend, SimBackend, SimOptions, MAX_AXES};
use crate::plant::CommandMode;
use softnc_control::AxisController;
use softnc_core::MachineProfile;

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
    controllers: [AxisController; MAX_AXES],
    modes: [CommandMode; MAX_AXES],
    mm_per_count: [f64; MAX_AXES],
    backend: B,
}

impl CycleEngine<SimBackend> {
    /// The simulated machine of `profile` with its controllers, seeded by `seed`.
    pub fn simulated(profile: &MachineProfile, seed: u64, options: SimOptions) -> Self {
        CycleEngine::new(profile, SimBackend::new(profile, seed, options))
    }
}

impl<B: ServoBackend> CycleEngine<B> {
    /// The profile's controllers in front of `backend`.
    pub fn new(profile: &MachineProfile, backend: B) -> Self {
        let cycle_s = profile.interpolation_cycle_s;
        let controllers =
            [0, 1, 2].map(|i| AxisController::new(&profile.axis_servo(i).controller, cycle_s));
        let modes = [0, 1, 2].map(|i| backend.command_mode(i));
        let mm_per_count = [0, 1, 2].map(|i| backend.mm_per_count(i));
        let mut e = CycleEngine {
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

    /// The backend.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// The controller of axis `axis`.
    pub fn controller(&self, axis: usize) -> &AxisController {
        &self.controllers[axis]
    }
}
