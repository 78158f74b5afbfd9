//! The simulated machine behind the servo boundary ([`softnc_servo::ServoBackend`]).

use crate::plant::Plant;
use crate::workpiece::StockCut;
use softnc_core::Axes;
use softnc_machine::MachineProfile;
use softnc_plant::cutting_disturbance::Cutting;
use softnc_plant::encoder::Encoder;
use softnc_plant::resonance::Resonance;
use softnc_plant::rng::Rng;
use softnc_servo::{
    AxisStatus, BackendError, CommandMode, PhaseCurrents, ServoBackend, SimulatedMachine, MAX_AXES,
};

/// Resolution reported when encoder quantisation is switched off (mm per count): fine
/// enough that the count is the position to floating-point precision over any travel.
pub const UNQUANTISED_MM_PER_COUNT: f64 = 1e-9;

/// Random stream of axis `i`'s parameter variation: `STREAM_VARIATION + i`.
const STREAM_VARIATION: u64 = 100;
/// Random stream of axis `i`'s measurement noise: `STREAM_NOISE + i`.
const STREAM_NOISE: u64 = 200;

/// Switches of the simulated machine's imperfections (all on by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SimOptions {
    /// Quantise positions to the profile's encoder resolution.
    pub quantisation: bool,
    /// Add the profile's measurement noise.
    pub noise: bool,
    /// Apply the profile's periodic cutting disturbance during feed moves.
    pub cutting: bool,
    /// Apply the profile's random parameter variation.
    pub variation: bool,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            quantisation: true,
            noise: true,
            cutting: true,
            variation: true,
        }
    }
}

/// The simulated machine: one [`Plant`] per axis, encoders, cutting disturbance; every
/// random draw from `seed`, so a seed gives a bit-identical run.
#[derive(Debug, Clone)]
pub struct SimBackend {
    plants: [Plant; MAX_AXES],
    encoders: [Encoder; MAX_AXES],
    substeps: [u32; MAX_AXES],
    /// Structural modes between motor and table (axes that have one).
    modes: [Option<Resonance>; MAX_AXES],
    cutting: Option<Cutting>,
    cutting_on: bool,
    /// The stock the cutter goes through (the profile's `force.sim_workpiece`).
    stock: Option<StockCut>,
    options: SimOptions,
    cycle_s: f64,
    cycle: u64,
    cmd: Axes<f64>,
    counts: Axes<i64>,
    currents: Axes<f64>,
    status: Axes<AxisStatus>,
}

impl SimBackend {
    /// The machine of `profile` (its `servo` section) with random seed `seed`.
    pub fn new(profile: &MachineProfile, seed: u64, options: SimOptions) -> Self {
        let cycle_s = profile.interpolation_cycle_s;
        let plants = std::array::from_fn(|i| {
            let mut rng = Rng::stream(seed, STREAM_VARIATION + i as u64);
            Plant::new(&profile.axis_servo(i).plant, &mut rng, options.variation)
        });
        let encoders = std::array::from_fn(|i| {
            let res = if options.quantisation {
                profile.axes[i].encoder_resolution_mm
            } else {
                UNQUANTISED_MM_PER_COUNT
            };
            let noise = if options.noise {
                profile.axis_servo(i).noise_mm
            } else {
                0.0
            };
            Encoder::new(res, noise, Rng::stream(seed, STREAM_NOISE + i as u64))
        });
        let substeps = std::array::from_fn(|i| plants[i].substeps(cycle_s));
        let modes = std::array::from_fn(|i| {
            profile
                .axis_servo(i)
                .resonance
                .map(|m| Resonance::new(&m, cycle_s))
        });
        let cutting = if options.cutting {
            profile.servo.cutting.as_ref().map(Cutting::new)
        } else {
            None
        };
        let stock = profile
            .force
            .as_ref()
            .and_then(|f| StockCut::from_profile(f, seed, options.noise));
        let mut b = SimBackend {
            plants,
            encoders,
            substeps,
            modes,
            cutting,
            cutting_on: false,
            stock,
            options,
            cycle_s,
            cycle: 0,
            cmd: Axes::splat(0.0),
            counts: Axes::splat(0),
            currents: Axes::splat(0.0),
            status: Axes::splat(AxisStatus {
                enabled: true,
                ..AxisStatus::default()
            }),
        };
        b.home(Axes::splat(0.0));
        b
    }

    /// The plant of axis `axis` (its true state, for tests and analysis).
    pub fn plant(&self, axis: usize) -> &Plant {
        &self.plants[axis]
    }

    /// True (unmeasured) positions (mm) of the motors, which the encoders read.
    pub fn true_pos_mm(&self) -> Axes<f64> {
        Axes::from_fn(|a| self.plants[a.index()].pos_mm())
    }

    /// True table positions (mm): the motor's, moved by the structural mode where the
    /// axis has one.
    pub fn table_pos_mm(&self) -> Axes<f64> {
        Axes::from_fn(|a| match &self.modes[a.index()] {
            Some(m) => m.table_mm(),
            None => self.plants[a.index()].pos_mm(),
        })
    }

    /// The stock on the table, when the profile has one.
    pub fn stock(&self) -> Option<&StockCut> {
        self.stock.as_ref()
    }

    /// The switches in force.
    pub fn options(&self) -> SimOptions {
        self.options
    }

    fn measure(&mut self) {
        let noisy = self.options.noise;
        for i in 0..MAX_AXES {
            self.counts[i] = self.encoders[i].read_counts(self.plants[i].pos_mm(), noisy);
        }
    }
}

impl ServoBackend for SimBackend {
    /// Each job runs on a fresh simulated machine at rest at its start, as `softnc
    /// sim` builds it.
    fn kept_across_jobs(&self) -> bool {
        false
    }
    fn axes(&self) -> usize {
        MAX_AXES
    }
    fn command_mode(&self, axis: usize) -> CommandMode {
        self.plants[axis].command_mode()
    }
    fn mm_per_count(&self, axis: usize) -> f64 {
        self.encoders[axis].mm_per_count()
    }
    fn home(&mut self, pos_mm: Axes<f64>) {
        for (p, x) in self.plants.iter_mut().zip(pos_mm) {
            p.reset(x);
        }
        for (m, x) in self.modes.iter_mut().zip(pos_mm) {
            if let Some(m) = m {
                m.reset(x);
            }
        }
        self.cmd = Axes::splat(0.0);
        for (i, c) in self.cmd.iter_mut().enumerate() {
            if self.plants[i].command_mode() == CommandMode::Position {
                *c = pos_mm[i];
            }
        }
        self.cycle = 0;
        self.currents = Axes::splat(0.0);
        if let Some(s) = &mut self.stock {
            s.reset();
        }
        self.measure();
    }
    /// An axis switched on again after it was off stands at rest where it is: the
    /// simulated machine is not stepped while its drives are off, so its motor's
    /// speed (and a structural mode's motion) is what it was at the switch-off; a
    /// real motor has coasted to rest by the time it is switched on again.
    fn enable(&mut self) -> Result<(), BackendError> {
        for i in 0..MAX_AXES {
            if !self.status[i].enabled {
                let at_mm = self.plants[i].pos_mm();
                self.plants[i].reset(at_mm);
                if let Some(m) = &mut self.modes[i] {
                    m.reset(at_mm);
                }
            }
            self.status[i].enabled = true;
        }
        Ok(())
    }
    fn disable(&mut self) {
        // drives off: no torque, no speed; a position-mode drive holds where it is
        for i in 0..MAX_AXES {
            self.status[i].enabled = false;
            self.cmd[i] = match self.plants[i].command_mode() {
                CommandMode::Position => self.plants[i].pos_mm(),
                CommandMode::Velocity | CommandMode::Effort => 0.0,
            };
        }
    }
    fn write_commands(&mut self, cmd: Axes<f64>) {
        for ((c, s), new) in self.cmd.iter_mut().zip(&self.status).zip(cmd) {
            if s.enabled {
                *c = new;
            }
        }
    }
    fn cycle(&mut self) -> Result<(), BackendError> {
        let t0 = self.cycle as f64 * self.cycle_s;
        for i in 0..MAX_AXES {
            let plant = &mut self.plants[i];
            let input = plant.command_input(self.cmd[i]);
            self.status[i].saturated = input != self.cmd[i].round() && input != self.cmd[i];
            let n = self.substeps[i];
            let h = self.cycle_s / n as f64;
            let mut current = 0.0;
            for s in 0..n {
                let dist = match (&self.cutting, self.cutting_on) {
                    (Some(c), true) => c.at(i, t0 + s as f64 * h),
                    _ => 0.0,
                };
                current = plant.substep(input + dist, h);
            }
            self.currents[i] = current;
            if let Some(m) = &mut self.modes[i] {
                m.cycle(plant.pos_mm());
            }
        }
        self.cycle += 1;
        self.measure();
        if let Some(s) = &mut self.stock {
            let i = s.feed_axis();
            let measured_mm = self.counts[i] as f64 * self.encoders[i].mm_per_count();
            s.cycle(self.plants[i].pos_mm(), measured_mm, self.cycle_s);
        }
        Ok(())
    }
    fn read_counts(&self) -> Axes<i64> {
        self.counts
    }
    fn read_currents(&self) -> Axes<f64> {
        self.currents
    }
    fn read_status(&self) -> Axes<AxisStatus> {
        self.status
    }
    fn read_phase_currents(&self, axis: usize) -> Option<PhaseCurrents> {
        self.stock
            .as_ref()
            .filter(|s| s.feed_axis() == axis)
            .map(|s| s.phases())
    }
    fn set_spindle_rpm(&mut self, rpm: f64) {
        let t_s = self.cycle as f64 * self.cycle_s;
        if let Some(c) = &mut self.cutting {
            c.set_spindle_rpm(rpm, t_s);
        }
    }
    fn simulated(&mut self) -> Option<&mut dyn SimulatedMachine> {
        Some(self)
    }
}

impl SimulatedMachine for SimBackend {
    fn set_cutting(&mut self, cutting: bool) {
        self.cutting_on = cutting;
    }
    fn stuck(&self, axis: usize) -> bool {
        match &self.plants[axis] {
            Plant::VelocityLoop(p) => p.speed_rad_per_s() == 0.0,
            Plant::DcMotor(p) => p.vel_mm_per_s() == 0.0,
            Plant::FirstOrderLag(p) => p.is_stuck(),
        }
    }
}
