//! The simulated machine behind the servo boundary ([`softnc_servo::ServoBackend`]),
//! with every line of the I/O boundary ([`softnc_servo::io`]) wired as its cabinet
//! ([`wiring`]): a spindle with inertia and its own encoder (the profile's
//! `servo.spindle`), limit switches past the soft limits and home switches where the
//! homing section puts them, a probe plane, a tool changer that answers after a
//! delay (`servo.sim_io`), and an E-stop chain and user inputs a test sets through
//! [`SimulatedMachine`]. The outputs (coolant, tool-change, M62 lines) are
//! observable there too.
//!
//! The periodic cutting disturbance does not follow the spindle model: its tooth
//! frequency follows the speed the job's PDC schedule sets
//! ([`ServoBackend::set_spindle_rpm`], from the program's S words × override) at
//! the cycle where it takes effect, exactly as before the spindle model came, so the
//! papers' reproductions do not move.

use crate::plant::Plant;
use crate::workpiece::StockCut;
use softnc_core::Axes;
use softnc_machine::MachineProfile;
use softnc_plant::cutting_disturbance::Cutting;
use softnc_plant::encoder::Encoder;
use softnc_plant::resonance::Resonance;
use softnc_plant::rng::Rng;
use softnc_plant::spindle::Spindle;
use softnc_servo::io::{IoLines, RawInputs, RawOutputs, SpindleFeedback};
use softnc_servo::{
    AxisStatus, BackendError, CommandMode, PhaseCurrents, ServoBackend, SimulatedMachine, MAX_AXES,
};

/// How the simulated machine's cabinet is wired: its raw lines. The shipped
/// profiles' I/O maps (`servo.io`) name these; every contact reads high when
/// asserted.
pub mod wiring {
    /// Output: the spindle drive enabled.
    pub const OUT_SPINDLE_ENABLE: usize = 0;
    /// Output: spindle clockwise.
    pub const OUT_SPINDLE_CW: usize = 1;
    /// Output: spindle counter-clockwise.
    pub const OUT_SPINDLE_CCW: usize = 2;
    /// Output: mist coolant.
    pub const OUT_MIST: usize = 3;
    /// Output: flood coolant.
    pub const OUT_FLOOD: usize = 4;
    /// Output: tool-change request to the tool changer.
    pub const OUT_TOOL_CHANGE: usize = 5;
    /// Output: machine on.
    pub const OUT_MACHINE_ON: usize = 6;
    /// Output: amplifiers enabled.
    pub const OUT_AMP_ENABLE: usize = 7;
    /// Input: the tool changer's tool-changed (beside its request: a loopback
    /// backend answers at once).
    pub const IN_TOOL_CHANGED: usize = 5;
    /// Input: the external E-stop chain is open.
    pub const IN_ESTOP: usize = 16;
    /// Input: minimum-end limit switch of axis `a` is line `IN_LIMIT_MIN + a`.
    pub const IN_LIMIT_MIN: usize = 17;
    /// Input: maximum-end limit switch of axis `a` is line `IN_LIMIT_MAX + a`.
    pub const IN_LIMIT_MAX: usize = 20;
    /// Input: home switch of axis `a` is line `IN_HOME + a`.
    pub const IN_HOME: usize = 23;
    /// Input: the probe.
    pub const IN_PROBE: usize = 26;
    /// User lines (M62 P / M66 P in the shipped maps): digital line `USER + P`, both
    /// ways; analog user lines are 0 … 15.
    pub const USER: usize = 64;
}

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
    /// The I/O around the axes.
    io: SimIo,
}

/// The simulated machine's I/O: its spindle, switches, tool changer and what a
/// test sets.
#[derive(Debug, Clone)]
struct SimIo {
    spindle: Option<Spindle>,
    /// (min, max) trip points of each axis's limit switches (mm); none without
    /// `servo.sim_io`.
    limits_mm: Option<[(f64, f64); MAX_AXES]>,
    /// (search velocity, trip point) of each axis's home switch.
    home: [Option<(f64, f64)>; MAX_AXES],
    probe_plane_z_mm: Option<f64>,
    /// Cycles the tool changer takes; none: no tool changer.
    tool_change_cycles: Option<u64>,
    /// Cycles the tool-change request has been up.
    tool_change_for: u64,
    estop_open: bool,
    probe: Option<bool>,
    /// Digital input lines a test set high.
    user_digital: u128,
    user_analog: [f64; softnc_servo::io::RAW_ANALOG_LINES],
    out: RawOutputs,
    inp: RawInputs,
}

impl SimIo {
    fn new(profile: &MachineProfile) -> Self {
        let cycle_s = profile.interpolation_cycle_s;
        let sim = profile.servo.sim_io;
        SimIo {
            spindle: profile.servo.spindle.as_ref().map(Spindle::new),
            limits_mm: sim.map(|s| {
                std::array::from_fn(|i| {
                    profile
                        .axes
                        .get(i)
                        .map_or((f64::NEG_INFINITY, f64::INFINITY), |a| {
                            (
                                a.min_mm - s.limit_switch_margin_mm,
                                a.max_mm + s.limit_switch_margin_mm,
                            )
                        })
                })
            }),
            home: std::array::from_fn(|i| {
                let h = profile.homing.as_ref()?.axes.get(i)?;
                Some((h.search_vel_mm_per_s, h.switch_mm))
            }),
            probe_plane_z_mm: sim.and_then(|s| s.probe_plane_z_mm),
            tool_change_cycles: sim.map(|s| (s.tool_change_s / cycle_s).round() as u64),
            tool_change_for: 0,
            estop_open: false,
            probe: None,
            user_digital: 0,
            user_analog: [0.0; softnc_servo::io::RAW_ANALOG_LINES],
            out: RawOutputs::default(),
            inp: RawInputs::default(),
        }
    }

    /// One cycle of the spindle and the tool changer.
    fn step(&mut self, cycle_s: f64) {
        let cmd = self.out.spindle;
        if let Some(s) = &mut self.spindle {
            match cmd.orient_deg {
                Some(angle) => s.step_orient(angle, cmd.orient_dir, cycle_s),
                None => s.step(cmd.enable, cmd.signed_rpm(), cycle_s),
            }
        }
        if self.out.digital >> wiring::OUT_TOOL_CHANGE & 1 == 1 {
            self.tool_change_for = self.tool_change_for.saturating_add(1);
        } else {
            self.tool_change_for = 0;
        }
    }

    /// The inputs, with the axes at `pos_mm`.
    fn sense(&mut self, pos_mm: &Axes<f64>) {
        // a line set from the panel (a hand on a switch, a wire to an input) reads
        // high whatever the machine's own contact says
        let user = self.user_digital;
        let mut d = user;
        let mut set = |line: usize, on: bool| {
            if on || user >> line & 1 == 1 {
                d |= 1u128 << line;
            } else {
                d &= !(1u128 << line);
            }
        };
        set(wiring::IN_ESTOP, self.estop_open);
        for (i, &x) in pos_mm.iter().enumerate() {
            if let Some(l) = self.limits_mm {
                set(wiring::IN_LIMIT_MIN + i, x <= l[i].0);
                set(wiring::IN_LIMIT_MAX + i, x >= l[i].1);
            }
            if let Some((v, trip)) = self.home[i] {
                set(
                    wiring::IN_HOME + i,
                    if v >= 0.0 { x >= trip } else { x <= trip },
                );
            }
        }
        let plane = self
            .probe_plane_z_mm
            .is_some_and(|z| pos_mm.get(2).is_some_and(|&p| p <= z));
        set(wiring::IN_PROBE, self.probe.unwrap_or(plane));
        if let Some(n) = self.tool_change_cycles {
            set(
                wiring::IN_TOOL_CHANGED,
                self.tool_change_for > 0 && self.tool_change_for >= n,
            );
        }
        self.inp = RawInputs {
            digital: d,
            analog: self.user_analog,
            spindle: self
                .spindle
                .as_ref()
                .map_or(SpindleFeedback::default(), |s| {
                    let r = s.reading();
                    SpindleFeedback {
                        rpm: r.rpm,
                        revs: r.revs,
                        index_count: r.index_count,
                        oriented: r.oriented,
                    }
                }),
        };
    }
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
            io: SimIo::new(profile),
        };
        b.home(Axes::splat(0.0));
        b.sense_io();
        b
    }

    fn sense_io(&mut self) {
        let pos = self.true_pos_mm();
        self.io.sense(&pos);
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
        self.io.step(self.cycle_s);
        self.sense_io();
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
    /// The next job's fresh machine takes over what outlives a job on a real
    /// machine: the spindle as it turns (speed, angle, encoder count: a spindle
    /// left turning keeps turning, one braking goes on braking, on the outputs
    /// the position process writes from then on), the tool changer's request
    /// time, and the E-stop chain, the inputs and the probe a test set. Nothing
    /// here allocates (the spindle is plain data).
    fn take_external_io(&mut self, running: &Self) {
        self.io.spindle.clone_from(&running.io.spindle);
        self.io.tool_change_for = running.io.tool_change_for;
        self.io.out = running.io.out;
        self.io.estop_open = running.io.estop_open;
        self.io.probe = running.io.probe;
        self.io.user_digital = running.io.user_digital;
        self.io.user_analog = running.io.user_analog;
        self.sense_io();
    }
    fn io_lines(&self) -> IoLines {
        IoLines {
            spindle: self.io.spindle.is_some(),
            ..IoLines::ALL
        }
    }
    fn write_io(&mut self, out: &RawOutputs) {
        self.io.out = *out;
    }
    fn exchange_io(&mut self) -> Result<(), BackendError> {
        self.io.step(self.cycle_s);
        self.sense_io();
        Ok(())
    }
    fn read_io(&self) -> RawInputs {
        self.io.inp
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
    fn set_estop_open(&mut self, open: bool) {
        self.io.estop_open = open;
        self.sense_io();
    }
    fn set_digital_input(&mut self, line: usize, high: bool) {
        if line < softnc_servo::io::RAW_DIGITAL_LINES {
            if high {
                self.io.user_digital |= 1u128 << line;
            } else {
                self.io.user_digital &= !(1u128 << line);
            }
            self.sense_io();
        }
    }
    fn set_analog_input(&mut self, line: usize, value: f64) {
        if let Some(v) = self.io.user_analog.get_mut(line) {
            *v = value;
            self.sense_io();
        }
    }
    fn set_probe(&mut self, tripped: Option<bool>) {
        self.io.probe = tripped;
        self.sense_io();
    }
    fn raw_outputs(&self) -> RawOutputs {
        self.io.out
    }
    fn spindle_true_rpm(&self) -> f64 {
        self.io.spindle.as_ref().map_or(0.0, Spindle::true_rpm)
    }
}
