//! `softnc-position`: the position-control process (paper 002's *position task*).
//!
//! Each cycle, in the order of a servo loop: inputs (control commands, command samples
//! into the lookahead ring) → faults (sequence errors, ring running dry, following
//! error) → mode → position command → controller stack and servo backend → status.
//! Motion starts only when the ring holds `window` future samples. If the ring runs
//! dry mid-job (the interpolator died or stalled), the axes decelerate along the path
//! still in the ring and the machine is faulted with an alarm; so too when the MMI
//! has been silent past `mmi_silence_stop_s` (a jog or a homing decelerates). An
//! E-stop comes from the MMI or straight from an operator client (the `estop`
//! service); a reset clears it or a fault and leaves the drives off.
//!
//! The machine around the axes is exchanged on every cycle, between jobs too
//! ([`softnc_servo::io::MachineIo`] in the engine): each command sample carries
//! its outputs, applied while it is the sample in use (a synchronised output
//! switches at the cycle where the next motion's first sample is in use); between
//! jobs the last job's or MDI command's outputs are held (a spindle started by
//! `S5000 M3` keeps turning, coolant stays on, M62–M68 outputs stay as set, as in
//! LinuxCNC; a program's M2/M30 stops the spindle and the coolant itself); an
//! abort stops the spindle and the coolant and keeps the digital and analog
//! outputs (LinuxCNC's task abort); while the machine is off, E-stopped or
//! faulted the safe state goes out with machine-on and amplifier-enable off. The
//! inputs and the outputs in force go out in every status
//! (`PositionStatus::inputs`, `PositionStatus::outputs`). An opened E-stop input
//! stops the machine as the operator's E-stop does (latched: a reset is refused
//! while it is open, and so is `on`); a limit switch that trips while the machine
//! is on does the same, with an alarm naming the axis and the end; off it, the
//! axis jogs only away from the switch. While a limit switch is tripped the machine is switched on
//! only with the operator's override (LinuxCNC's override limits), which lasts
//! until every switch is released and under which a switch stops nothing.
//!
//! Nothing on the cycle reads a file or allocates: a job's programmed path, its fresh
//! engine, its trace file and its PDC designs, and the redesigns a spindle override
//! asks for, are made by the preparation thread ([`crate::prep`]) and swapped in at a
//! cycle boundary; motion starts only when the job's preparation is in.

use crate::config::{ClockMode, Loaded};
use crate::lifecycle::StopWatch;
use crate::loop_watch::{LoopEvent, LoopWatch};
use crate::manual::{Manual, ManualEvent};
use crate::outbox::{Outbox, PositionMsg, OUTBOX_CAPACITY};
use crate::prep::{JobPrep, Prep, PrepRequest, Prepared, Retired};
use anyhow::Result;
use softnc_core::machine_io::MachineOutputs;
use softnc_core::{Axes, CommandRing, Primitive, RingSample, Vec3, COMMAND_RING_CAPACITY};
use softnc_ipc::bus::{Bus, Sub};
use softnc_ipc::{
    Alarm, AlarmCode, CommandSample, ControlCommand, ControlKind, EStopRequest, FixedStr,
    Heartbeat, LoopStats as LoopStatsMsg, MachineState, PositionStatus, ProcessId, MAX_AXES,
};
use softnc_rt::{LoopStats, PeriodicClock};
use softnc_servo::spindle::SpindleDesigns;
use softnc_servo::{CycleEngine, ServoBackend};
use std::time::{Duration, Instant};

/// Decelerating along the path left in the ring after it ran dry.
#[derive(Debug, Clone, Copy, PartialEq)]
struct DryStop {
    /// Where the stop starts: the position last commanded.
    origin: [f64; MAX_AXES],
    speed_mm_per_s: f64,
    /// Arc length travelled along the remaining samples.
    s_mm: f64,
}

/// Where the job on the machine is, as the position cycle steps it: one value for
/// what were a job id, a "prepared" flag, a dry stop and a settling counter that had
/// to agree.
#[derive(Debug, Clone, Copy, PartialEq)]
enum JobPhase {
    /// No job on the machine.
    NoJob,
    /// Job `id`'s first sample is in; its preparation (engine, path, trace) is not.
    Preparing { id: u64 },
    /// Job `id` is prepared: its samples are stepped once the window is in.
    Ready { id: u64 },
    /// Job `id`'s last sample was stepped; the axes settle into position (`cycles`
    /// so far).
    Settling { id: u64, cycles: u64 },
    /// Job `id`'s ring ran dry: stopping along the path still in it (and standing
    /// there, faulted, once stopped, until a reset).
    DryStop { id: u64, stop: DryStop },
}

impl JobPhase {
    /// The job (0: none).
    fn job_id(self) -> u64 {
        match self {
            JobPhase::NoJob => 0,
            JobPhase::Preparing { id }
            | JobPhase::Ready { id }
            | JobPhase::Settling { id, .. }
            | JobPhase::DryStop { id, .. } => id,
        }
    }

    /// The job's preparation is in (its engine runs it).
    fn prepared(self) -> bool {
        matches!(
            self,
            JobPhase::Ready { .. } | JobPhase::Settling { .. } | JobPhase::DryStop { .. }
        )
    }

    /// The dry stop under way.
    fn dry(self) -> Option<DryStop> {
        match self {
            JobPhase::DryStop { stop, .. } => Some(stop),
            _ => None,
        }
    }

    /// Cycles the axes have been settling after the job's last sample.
    fn settling(self) -> Option<u64> {
        match self {
            JobPhase::Settling { cycles, .. } => Some(cycles),
            _ => None,
        }
    }
}

/// Every axis homed (a machine with absolute encoders).
const ALL_HOMED: u32 = (1 << MAX_AXES) - 1;

/// Builds the engine for a job (defined with the preparation thread that calls it).
pub use crate::prep::EngineFactory;

/// The position-control process over a servo backend `B` (the simulated machine now).
pub struct PositionTask<B: ServoBackend> {
    cfg: Loaded,
    engine: CycleEngine<B>,
    /// Reads, builds and designs off the cycle.
    prep: Prep<B>,
    /// The job whose preparation was asked for last (0 none).
    requested_job: u64,
    /// A job's preparation, until its first sample arrives.
    staged_job: Option<Box<JobPrep<B>>>,
    /// Where the job starts (its first sample).
    start_mm: [f64; MAX_AXES],
    /// PDC tables of a spindle override, until the engine takes them (job id).
    pending_designs: Option<(u64, Box<SpindleDesigns>)>,
    /// Spindle override in force (fraction of the programmed speed).
    spindle_override: f64,
    /// The preparation thread has ended (reported once).
    prep_lost: bool,
    trace: Option<crate::trace::TraceSink>,
    ring: CommandRing,
    window: usize,
    commands: Sub<CommandSample>,
    control: Sub<ControlCommand>,
    /// E-stops straight from operator clients (past the MMI).
    estop: Sub<EStopRequest>,
    /// Settings on the simulated machine's panel (tests).
    sim_panel: Sub<softnc_ipc::SimPanel>,
    /// Heartbeats: the MMI's tell this process it is there.
    heartbeats: Sub<Heartbeat>,
    /// When the MMI was last heard (a heartbeat or a command).
    mmi_heard: Instant,
    /// The MMI's silence has stopped the motion (reported once, until heard again).
    mmi_silent: bool,
    /// Status, heartbeats, loop stats and alarms leave through the outbox thread.
    outbox: Outbox<PositionMsg>,
    state: MachineState,
    /// The operator's program-flow switches (a job's motions are read with them).
    switches: crate::interp::Switches,
    /// The line the requested job runs from.
    from_line: Option<u32>,
    /// The job on the machine and where it is.
    phase: JobPhase,
    primitives: Vec<Option<Primitive>>,
    /// The running job's program line per motion.
    lines: Vec<u32>,
    current: Option<CommandSample>,
    /// (motion, flags, path length, outputs) of the job's samples from the one in
    /// use on, beside the ring.
    flags: std::collections::VecDeque<(u32, u32, f64, MachineOutputs)>,
    /// The outputs of the machine around the axes in force (spindle, coolant,
    /// M62–M68): the sample in use's during a job; between jobs the last job's or
    /// MDI command's, held as LinuxCNC holds them (its program end, M2/M30, stops
    /// the spindle and the coolant); after an abort without the spindle and the
    /// coolant ([`MachineOutputs::after_abort`]); the safe state while the machine
    /// is off, E-stopped or faulted.
    outputs: MachineOutputs,
    /// The running job was aborted: its samples' spindle and coolant are not
    /// applied any more (until the next job).
    job_aborted: bool,
    /// The limit switches tripped at the last cycle (min, max): a switch stops the
    /// machine when it trips, not again while it stays tripped.
    limits_seen: (u32, u32),
    /// The operator overrides the limit switches (LinuxCNC's override limits,
    /// its `overrideLimitMask` as one flag): the machine may be switched on with
    /// one tripped and a switch tripping does not stop it; cleared by the first
    /// cycle with none tripped.
    limits_overridden: bool,
    last_cmd: [f64; MAX_AXES],
    prev_cmd: [f64; MAX_AXES],
    /// Each axis's in-position band (the profile's).
    in_position_mm: [f64; MAX_AXES],
    /// Each axis's measurement floor: what the reading of an axis at rest varies
    /// by (two encoder counts and four σ of the measurement noise, the floor the
    /// Markov identification uses).
    measurement_floor_mm: [f64; MAX_AXES],
    /// Cycles the axes get to come into position after a job's last sample.
    in_position_timeout_cycles: u64,
    /// Lockstep: since when the ring has lacked the samples the next cycle needs
    /// (the interpolator's silence, not the time since its last sample: a job whose
    /// preparation took longer than the timeout must not start with a dry stop).
    starved_since: Option<Instant>,
    /// The job started last.
    last_job_id: u64,
    /// Bit i: axis i is homed.
    homed: u32,
    /// The `seq` of the last control command from the MMI taken (its acknowledgement).
    mmi_control_seq: u64,
    /// The running job's force loop (adaptive feed), when it runs with one.
    adaptive: Option<softnc_servo::adaptive_feed::AdaptiveFeed>,
    /// A feed hold, an abort or a stop is in force: the force loop stands (the feed
    /// is the operator's, not its own).
    feed_held: bool,
    /// Jogs and homing between jobs.
    manual: Manual,
    /// Their trace (`trace: true`), the whole process's life.
    manual_trace: Option<crate::trace::TraceSink>,
    /// Cycles run (the manual trace's row numbers).
    cycles: u64,
    latency: softnc_rt::LatencyStats,
    /// When the last command sample came in (unix ns) and how long it took from
    /// the interpolator (ns): what a ring-dry alarm tells the operator.
    last_sample_rx: (u64, u64),
    stats: LoopStats,
    /// The loop's watch over its own timing (stalls, late cycles; realtime only).
    watch: LoopWatch,
    hb_counter: u64,
    last_hb: Instant,
    /// A stop was asked for (`Shutdown`, a signal, the supervisor's death): the
    /// process ends once the axes are at rest.
    shutdown: bool,
    stop: StopWatch,
    _bus: Bus,
}

impl<B: ServoBackend + Send + 'static> PositionTask<B> {
    /// Open the services; `make_engine` builds the controller stacks in front of the
    /// backend — the same engine `softnc sim` steps — fresh for every job (before
    /// motion), so a job runs exactly as the simulator runs it.
    pub fn new(cfg: Loaded, mut make_engine: EngineFactory<B>) -> Result<Self> {
        let engine = make_engine();
        let names = softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance);
        let bus = Bus::new(names, "position")?;
        let window = softnc_core::ring::window_for_lookahead(cfg.config.lookahead_samples);
        let (in_position_mm, measurement_floor_mm) = standing_bands(&cfg.machine);
        let in_position_timeout_cycles =
            (cfg.config.in_position_timeout_s / cfg.machine.interpolation_cycle_s).ceil() as u64;
        let manual_trace = manual_trace(&cfg);
        let trace = cfg.config.trace.then(|| crate::prep::TraceTo {
            dir: cfg.data_dir.clone(),
            lossless: cfg.config.clock == ClockMode::Lockstep,
        });
        let prep = Prep::start(
            cfg.machine.clone(),
            make_engine,
            trace,
            crate::machine_store::MachineStore::new(&cfg.data_dir),
        )?;
        // absolute encoders (no homing section): homed from the start
        let homed = if cfg.machine.homed_at_start() {
            ALL_HOMED
        } else {
            0
        };
        let manual = Manual::new(&cfg.machine, [0.0; MAX_AXES], engine.io().home_switches())?;
        let watch = LoopWatch::new(
            &cfg.config.loop_timing,
            Duration::from_secs_f64(cfg.machine.interpolation_cycle_s),
        );
        // DaemonConfig::load refuses a filter wider than the window
        anyhow::ensure!(
            engine.filter_window() <= window,
            "the command filter reads {} samples ahead, more than the {window} kept",
            engine.filter_window()
        );
        Ok(PositionTask {
            commands: bus.command_subscriber()?,
            control: bus.control_subscriber()?,
            estop: bus.estop_subscriber()?,
            sim_panel: bus.sim_panel_subscriber()?,
            heartbeats: bus.heartbeat_subscriber()?,
            mmi_heard: Instant::now(),
            mmi_silent: false,
            outbox: Outbox::start(
                softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance),
                "position-out",
                OUTBOX_CAPACITY,
                // lockstep: never drop a status (the interpolator paces itself on it)
                cfg.config.clock == ClockMode::Lockstep,
                cfg.config.position_rt.helper_priority(),
            )?,
            cfg,
            engine,
            prep,
            requested_job: 0,
            staged_job: None,
            start_mm: [0.0; MAX_AXES],
            pending_designs: None,
            spindle_override: 1.0,
            prep_lost: false,
            trace: None,
            ring: CommandRing::new(),
            window,
            // drives off: a controller starts off, and a position process restarted
            // (on the reset after it was lost) comes back off too — a reset never
            // switches the drives on, the operator's `on` does
            state: MachineState::Off,
            switches: crate::interp::Switches::default(),
            from_line: None,
            phase: JobPhase::NoJob,
            primitives: Vec::new(),
            lines: Vec::new(),
            current: None,
            flags: std::collections::VecDeque::with_capacity(COMMAND_RING_CAPACITY),
            outputs: MachineOutputs::safe(),
            job_aborted: false,
            limits_seen: (0, 0),
            limits_overridden: false,
            last_cmd: [0.0; MAX_AXES],
            prev_cmd: [0.0; MAX_AXES],
            starved_since: None,
            in_position_mm,
            measurement_floor_mm,
            in_position_timeout_cycles,
            last_job_id: 0,
            homed,
            mmi_control_seq: 0,
            adaptive: None,
            feed_held: false,
            manual,
            manual_trace,
            cycles: 0,
            latency: softnc_rt::LatencyStats::new(),
            last_sample_rx: (0, 0),
            stats: LoopStats::new(),
            watch,
            hb_counter: 0,
            last_hb: Instant::now() - Duration::from_secs(1),
            shutdown: false,
            stop: StopWatch::manual(),
            _bus: bus,
        })
    }

    /// Stop when `stop` asks (SIGTERM/SIGINT, the supervisor's death), once the axes
    /// are at rest.
    pub fn set_stop_watch(&mut self, stop: StopWatch) {
        self.stop = stop;
    }

    /// The axes are not moving a job: nothing runs or is held, no stop along the
    /// path is under way.
    pub fn at_rest(&self) -> bool {
        !matches!(self.state, MachineState::Running | MachineState::Held)
    }

    /// Raise an alarm; its text is formatted into the message's fixed buffer, so a
    /// fault found on the cycle allocates nothing (logged by the outbox thread).
    fn alarm(&mut self, code: AlarmCode, axis: u32, msg: std::fmt::Arguments<'_>) -> Result<()> {
        let mut message = FixedStr::empty();
        // a message longer than the buffer is cut, never an error
        let _ = std::fmt::Write::write_fmt(&mut message, msg);
        self.outbox.send(PositionMsg::Alarm(Alarm {
            code: code.wire(),
            axis,
            process: ProcessId::Position.wire(),
            job_id: self.phase.job_id(),
            time_index: self.current.map_or(0, |c| c.time_index),
            message,
            pid: std::process::id(),
            raised_unix_ns: softnc_rt::unix_ns(),
        }))?;
        Ok(())
    }

    /// Run cycles until a stop is asked for and the axes are at rest: a running job
    /// stops along its path first (the interpolator aborts it; if it is gone, the
    /// ring runs dry and the axes stop on what is left of it).
    pub fn run(&mut self) -> Result<()> {
        let period = Duration::from_secs_f64(self.cfg.machine.interpolation_cycle_s);
        let mut clock = PeriodicClock::new(period, Duration::from_micros(150));
        // when this process itself was asked to stop (a signal, the supervisor's
        // death): the interpolator normally stops the job along its path; if it has
        // not within the grace, the axes stop on what the ring holds
        let mut own_stop: Option<Instant> = None;
        // a stop asked of this process itself: how long the interpolator gets to stop
        // the job along its path before the axes stop on the ring's remaining samples
        let own_stop_grace = Duration::from_secs_f64(self.cfg.config.stopping.interp_grace_s);
        loop {
            if self.stop.requested().is_some() {
                self.shutdown = true;
                let since = *own_stop.get_or_insert_with(Instant::now);
                if !self.at_rest() && self.phase.dry().is_none() && since.elapsed() > own_stop_grace
                {
                    self.begin_dry_stop();
                }
            }
            if self.shutdown && self.at_rest() {
                // one last status: at rest, and no job (the one that stopped is over)
                if self.phase.job_id() != 0 && self.state == MachineState::Idle {
                    self.phase = JobPhase::NoJob;
                }
                self.cycle()?;
                break;
            }
            let (woke, jitter, late) = match self.cfg.config.clock {
                ClockMode::Realtime => {
                    let (woke, jitter, late) = clock.wait();
                    // before the cycle: a loop that stood does not go on as if it
                    // had not
                    if let Some(ev) = self.watch.observe(jitter, woke) {
                        self.on_timing(ev)?;
                    }
                    (woke, jitter, late)
                }
                ClockMode::Lockstep => {
                    // one cycle per available sample
                    if !self.wait_for_sample()? {
                        self.housekeeping()?;
                        continue;
                    }
                    (Instant::now(), Duration::ZERO, 0)
                }
            };
            self.cycle()?;
            self.stats.record(jitter, woke.elapsed(), late);
            self.housekeeping()?;
        }
        // at rest: the drives stop following commands (CiA 402: disabled)
        self.engine.backend_mut().disable();
        // a trace still open (the job stopped along its path) is written out when
        // the preparation thread ends with this task
        if let Some(t) = self.trace.take() {
            self.prep.retire(Retired::Trace(t));
        }
        if let Some(t) = self.manual_trace.take() {
            self.prep.retire(Retired::Trace(t));
        }
        Ok(())
    }

    /// What the loop's watch found: a stall stops whatever moves as a fault (the
    /// axes got no command while it stood: a drive has stood or faulted itself, and
    /// resuming would take up a path whose timing is lost); late cycles are
    /// reported. Allocation-free (the texts go into the alarm's fixed buffer).
    fn on_timing(&mut self, ev: LoopEvent) -> Result<()> {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        match ev {
            LoopEvent::Stall { period } => {
                let bound_ms = ms(self.watch.stall_bound());
                let moving = matches!(
                    self.state,
                    MachineState::Running
                        | MachineState::Held
                        | MachineState::Homing
                        | MachineState::Jogging
                );
                if !moving {
                    return self.alarm(
                        AlarmCode::LoopStall,
                        u32::MAX,
                        format_args!(
                            "the position loop stood {:.1} ms (bound {bound_ms:.1} ms) while nothing moved",
                            ms(period)
                        ),
                    );
                }
                if matches!(self.state, MachineState::Homing | MachineState::Jogging) {
                    // a homing cut short leaves its axis unhomed
                    self.manual.stop();
                    self.manual.hold(self.last_cmd);
                }
                // as on a following-error fault: the drives are no longer stepped,
                // the job is over (its trace closed off the cycle); a reset recovers
                self.state = MachineState::Faulted;
                if let Some(t) = self.trace.take() {
                    self.prep.retire(Retired::Trace(t));
                }
                self.alarm(
                    AlarmCode::LoopStall,
                    u32::MAX,
                    format_args!(
                        "the position loop stood {:.1} ms (bound {bound_ms:.1} ms): motion stopped as a fault; reset to go on",
                        ms(period)
                    ),
                )
            }
            LoopEvent::Late { count, worst, over } => {
                let bound_ms = ms(self.watch.late_bound());
                self.alarm(
                    AlarmCode::LoopLate,
                    u32::MAX,
                    format_args!(
                        "the position loop ran late: {count} cycle(s) off their period by more than {bound_ms:.1} ms in {:.1} s (worst {:.1} ms)",
                        over.as_secs_f64(),
                        ms(worst)
                    ),
                )
            }
        }
    }

    /// Lockstep: wait (briefly) for the next sample. True when a cycle should run:
    /// a sample is there, the machine is not moving, or the interpolator has been
    /// silent for the heartbeat timeout (then the cycle finds the ring dry and stops
    /// along the path).
    fn wait_for_sample(&mut self) -> Result<bool> {
        let t0 = Instant::now();
        loop {
            self.pull_commands()?;
            self.take_prepared()?;
            let moving = matches!(self.state, MachineState::Running | MachineState::Held)
                && self.phase.dry().is_none();
            let starting = self.state == MachineState::Idle && self.phase.job_id() != 0;
            if (moving || (starting && self.phase.prepared())) && self.ring.ready(self.window)
                || (moving && self.phase.settling().is_some())
            {
                self.starved_since = None;
                return Ok(true);
            }
            if !moving && !starting {
                // between jobs: cycle at the nominal rate, not as fast as the CPU allows
                std::thread::sleep(Duration::from_secs_f64(
                    self.cfg.machine.interpolation_cycle_s,
                ));
                self.pull_commands()?;
                return Ok(true);
            }
            let starved = *self.starved_since.get_or_insert_with(Instant::now);
            if moving && starved.elapsed().as_secs_f64() > self.cfg.config.heartbeat_timeout_s {
                self.starved_since = None;
                return Ok(true);
            }
            if t0.elapsed() > Duration::from_millis(2) {
                return Ok(false); // housekeeping, then wait again
            }
            std::thread::yield_now();
        }
    }

    /// The command of axes that stand where they are measured (the drives off, or
    /// being switched on): the measured position, as LinuxCNC's motion controller
    /// sets the command to the feedback while disabled — except on an axis whose
    /// reading is within its measurement floor of the last command: it stands
    /// there, and its command stands (a count of encoder noise does not become the
    /// command, and a machine switched on where it was switched off commands what
    /// it did).
    fn command_where_standing(&self) -> [f64; MAX_AXES] {
        let measured = self.engine.measured_mm();
        std::array::from_fn(|i| {
            if (measured[i] - self.last_cmd[i]).abs() > self.measurement_floor_mm[i] {
                measured[i]
            } else {
                self.last_cmd[i]
            }
        })
    }

    /// The job's trace is complete (the job ended, or stopped where it is): its
    /// file is closed off the cycle path, so every row up to the stop is written
    /// out now rather than when the next job's trace replaces it.
    fn close_trace(&mut self) {
        if let Some(t) = self.trace.take() {
            self.prep.retire(Retired::Trace(t));
        }
    }

    /// The emergency stop (from the MMI, straight from a client, the E-stop input
    /// or a limit switch: `cause`): everything stops where it is; reported once per
    /// E-stop.
    fn emergency_stop(&mut self, cause: StopCause) -> Result<()> {
        self.manual.stop();
        self.manual.hold(self.last_cmd);
        // every drive stops by itself now (a fieldbus's quick stop at the next
        // exchange; the axes are not stepped from here on)
        self.engine.backend_mut().estop();
        if self.state == MachineState::EStopped {
            return Ok(());
        }
        self.state = MachineState::EStopped;
        self.close_trace();
        match cause {
            StopCause::Client(pid) => self.alarm(
                AlarmCode::EStop,
                u32::MAX,
                format_args!("emergency stop (from operator client pid {pid}, past the MMI)"),
            ),
            StopCause::Operator => {
                self.alarm(AlarmCode::EStop, u32::MAX, format_args!("emergency stop"))
            }
            StopCause::Input => self.alarm(
                AlarmCode::EStop,
                u32::MAX,
                format_args!(
                    "emergency stop: the E-stop input opened (latched: reset once it is closed)"
                ),
            ),
            StopCause::Backend(e) => {
                let axis = match e {
                    softnc_servo::BackendError::Bus { axis: Some(a), .. }
                    | softnc_servo::BackendError::DriveFault { axis: a }
                    | softnc_servo::BackendError::NotEnabled { axis: a } => u32::from(a),
                    _ => u32::MAX,
                };
                let name = softnc_core::Axis::name_of(axis as usize);
                let named = if axis == u32::MAX { "" } else { name };
                self.alarm(
                    AlarmCode::EStop,
                    axis,
                    format_args!(
                        "emergency stop: servo backend {e}{}{named}; every drive stopped",
                        if named.is_empty() { "" } else { ", axis " },
                    ),
                )
            }
            StopCause::Limit { axis, max } => {
                let at_mm = self.engine.measured_mm()[axis];
                self.alarm(
                    AlarmCode::EStop,
                    axis as u32,
                    format_args!(
                        "emergency stop: {} {} limit switch tripped at {at_mm:.3} mm",
                        softnc_core::Axis::name_of(axis),
                        if max { "maximum" } else { "minimum" },
                    ),
                )
            }
        }
    }

    /// The inputs read this cycle: an opened E-stop input stops the machine (from
    /// any state but E-stopped), a limit switch tripping while the machine is on
    /// too.
    fn watch_inputs(&mut self) -> Result<()> {
        let m = *self.engine.io().last_inputs();
        if m.estop_open && self.state != MachineState::EStopped {
            self.emergency_stop(StopCause::Input)?;
        }
        let (seen_min, seen_max) = self.limits_seen;
        self.limits_seen = (m.limit_min, m.limit_max);
        // the override ends by itself once every switch is released (LinuxCNC's
        // motion controller clears its override mask so), and while it lasts a
        // switch stops nothing
        if m.limit_min | m.limit_max == 0 {
            self.limits_overridden = false;
        }
        if self.limits_overridden {
            return Ok(());
        }
        let on = !matches!(self.state, MachineState::Off | MachineState::EStopped);
        let new_min = m.limit_min & !seen_min;
        let new_max = m.limit_max & !seen_max;
        // a limit of the axis homing aborts its homing (`Manual::step`, next
        // cycle), as LinuxCNC's homing: a homing error, not an E-stop
        let homing = self.manual.homing_axis().map_or(0, |i| 1u32 << i);
        if on && (new_min | new_max) & !homing != 0 {
            let (new_min, new_max) = (new_min & !homing, new_max & !homing);
            let max = new_min == 0;
            let bits = if max { new_max } else { new_min };
            let axis = bits.trailing_zeros() as usize;
            self.emergency_stop(StopCause::Limit { axis, max })?;
        }
        Ok(())
    }

    /// The MMI heard from (heartbeats); what moves stops when it has been silent
    /// past `mmi_silence_stop_s`: a job along its path, a jog or a homing
    /// decelerating (a hung MMI can take no hold, abort or E-stop).
    fn watch_mmi(&mut self) -> Result<()> {
        while let Some(h) = self.heartbeats.receive()? {
            if h.process == ProcessId::Mmi.wire() {
                self.mmi_heard = Instant::now();
                self.mmi_silent = false;
            }
        }
        let silent_s = self.mmi_heard.elapsed().as_secs_f64();
        if self.mmi_silent || silent_s <= self.cfg.config.mmi_silence_stop_s {
            return Ok(());
        }
        let job_moving = matches!(self.state, MachineState::Running | MachineState::Held)
            && self.phase.dry().is_none();
        let manual = matches!(self.state, MachineState::Homing | MachineState::Jogging);
        if !job_moving && !manual {
            return Ok(());
        }
        self.mmi_silent = true;
        let bound_s = self.cfg.config.mmi_silence_stop_s;
        if job_moving {
            // stopped along the path left in the ring, then faulted there
            self.feed_held = true;
            self.begin_dry_stop();
            // (not `ProcessLost`: the MMI reads that as this process lost)
            self.alarm(
                AlarmCode::Other,
                u32::MAX,
                format_args!(
                    "the MMI has been silent for {silent_s:.1} s (bound {bound_s} s): the job stops along its path"
                ),
            )
        } else {
            self.manual.stop();
            // (not `ProcessLost`: the MMI reads that as this process lost)
            self.alarm(
                AlarmCode::Other,
                u32::MAX,
                format_args!(
                    "the MMI has been silent for {silent_s:.1} s (bound {bound_s} s): jog or homing stopped"
                ),
            )
        }
    }

    /// Control commands from the MMI, E-stops straight from clients.
    #[allow(clippy::too_many_lines)]
    fn pull_control(&mut self) -> Result<()> {
        while let Some(e) = self.estop.receive()? {
            let pid = e.sender_pid;
            self.emergency_stop(StopCause::Client(pid))?;
        }
        while let Some(p) = self.sim_panel.receive()? {
            let p = *p;
            if let Some(sim) = self.engine.backend_mut().simulated() {
                let (line, on) = (p.line as usize, p.value != 0.0);
                match p.kind {
                    softnc_ipc::SimPanel::ESTOP => sim.set_estop_open(on),
                    softnc_ipc::SimPanel::DIGITAL => sim.set_digital_input(line, on),
                    softnc_ipc::SimPanel::ANALOG => sim.set_analog_input(line, p.value),
                    softnc_ipc::SimPanel::PROBE => {
                        sim.set_probe((p.value >= 0.0).then_some(p.value > 0.0));
                    }
                    _ => {}
                }
            }
        }
        while let Some(c) = self.control.receive()? {
            if c.sender == ProcessId::Mmi.wire() {
                self.mmi_control_seq = c.seq;
                self.mmi_heard = Instant::now();
            }
            if ControlKind::from_wire(c.kind) == Some(ControlKind::Abort) {
                // LinuxCNC's task abort: the spindle and the coolant stop, now and
                // for the rest of the job; the digital and analog outputs stay
                self.outputs = self.outputs.after_abort();
                self.job_aborted = self.phase.job_id() != 0;
            }
            match ControlKind::from_wire(c.kind) {
                Some(ControlKind::EStop) => self.emergency_stop(StopCause::Operator)?,
                Some(ControlKind::Reset)
                    if self.state == MachineState::EStopped
                        && !self.engine.io_mut().reset_estop() =>
                {
                    self.alarm(
                        AlarmCode::EStop,
                        u32::MAX,
                        format_args!("reset refused: the E-stop input is open"),
                    )?;
                }
                Some(ControlKind::Reset) => {
                    // (off the cycle's steady state: a reset) the backend made whole
                    // first (a fieldbus's SubDevices back in OP); a cause still
                    // there refuses the reset
                    let recovered = match self.state {
                        MachineState::EStopped | MachineState::Faulted => {
                            self.engine.backend_mut().recover()
                        }
                        _ => Ok(()),
                    };
                    if let Err(e) = recovered {
                        self.alarm(
                            AlarmCode::EStop,
                            u32::MAX,
                            format_args!("reset refused: the servo backend is still faulted: {e}"),
                        )?;
                    } else if matches!(self.state, MachineState::EStopped | MachineState::Faulted) {
                        // the latch cleared, the machine off: switching the drives
                        // on is the operator's `on` (as LinuxCNC)
                        self.engine.backend_mut().disable();
                        self.state = MachineState::Off;
                        self.ring.reset();
                        self.flags.clear();
                        self.phase = JobPhase::NoJob;
                        self.requested_job = 0;
                        self.current = None;
                    }
                }
                Some(ControlKind::Shutdown) => {
                    self.shutdown = true;
                    // the job stops along its path: the feed is not the force loop's
                    self.feed_held = true;
                }
                Some(ControlKind::StartJob)
                    if matches!(
                        self.state,
                        MachineState::Off | MachineState::EStopped | MachineState::Faulted
                    ) =>
                {
                    // the drives are not on (switching them on failed, or an
                    // E-stop came first): the job never starts, not even later
                    let state = self.state;
                    self.alarm(
                        AlarmCode::Other,
                        u32::MAX,
                        format_args!("job {} not started: the machine is {state:?}", c.job_id),
                    )?;
                }
                Some(ControlKind::StartJob) => {
                    // the programmed path, a fresh engine, the PDC designs: made off
                    // the cycle, swapped in before motion
                    self.requested_job = c.job_id;
                    self.from_line = (c.axis != 0 && c.axis != u32::MAX).then_some(c.axis);
                    self.feed_held = false;
                    self.prep.request(PrepRequest::Job {
                        job_id: c.job_id,
                        path: c.path,
                        spindle_override: self.spindle_override,
                        start_mm: self.last_cmd,
                        from_line: self.from_line,
                        switches: self.switches,
                        adaptive_cap: (c.flags & softnc_ipc::JOB_ADAPTIVE_FORCE != 0)
                            .then_some(c.value),
                    });
                }
                Some(ControlKind::MachineOn)
                    if self.state == MachineState::Off && self.engine.io().estop_latched() =>
                {
                    self.alarm(
                        AlarmCode::EStop,
                        u32::MAX,
                        format_args!("machine on refused: the E-stop input is open"),
                    )?;
                }
                Some(ControlKind::MachineOn)
                    if self.state == MachineState::Off
                        && self.limit_tripped()
                        && !self.limits_overridden =>
                {
                    self.alarm(
                        AlarmCode::MachineOn,
                        u32::MAX,
                        format_args!(
                            "machine on refused: a limit switch is tripped (override the limits to jog off it)"
                        ),
                    )?;
                }
                Some(ControlKind::OverrideLimits) if self.limit_tripped() => {
                    self.limits_overridden = true;
                }
                Some(ControlKind::OverrideLimits) => {
                    self.alarm(
                        AlarmCode::Other,
                        u32::MAX,
                        format_args!("limit override refused: no limit switch is tripped"),
                    )?;
                }
                Some(ControlKind::MachineOn) if self.state == MachineState::Off => {
                    match self.engine.backend_mut().enable() {
                        Ok(()) => {
                            // holding where the axes stand: the command is taken from
                            // the measured position (`command_where_standing`) and
                            // the controllers restart there (no step into an
                            // integrator), so switching on moves no axis
                            self.last_cmd = self.command_where_standing();
                            self.prev_cmd = self.last_cmd;
                            self.engine.restart_controllers_at(self.last_cmd);
                            self.state = MachineState::Idle;
                        }
                        Err(e) => {
                            // (off the cycle's steady state: switching on failed)
                            let why = self.engine.backend().enable_failure().unwrap_or_default();
                            let sep = if why.is_empty() { "" } else { ": " };
                            self.alarm(
                                AlarmCode::MachineOn,
                                u32::MAX,
                                format_args!("machine on: {e}{sep}{why}"),
                            )?
                        }
                    }
                }
                // the MMI asks only when nothing moves
                Some(ControlKind::MachineOff)
                    if self.state == MachineState::Idle && self.phase.job_id() == 0 =>
                {
                    self.engine.backend_mut().disable();
                    self.state = MachineState::Off;
                }
                Some(ControlKind::Home) if self.idle_between_jobs() => {
                    self.manual.hold(self.last_cmd);
                    let axis = (c.axis != u32::MAX).then_some(c.axis as usize);
                    if self.manual.home(axis) {
                        // homing again: the axes it homes are not homed until done
                        match axis {
                            Some(i) => self.homed &= !(1 << i),
                            None => self.homed = 0,
                        }
                        self.state = MachineState::Homing;
                    } else if self.cfg.machine.homed_at_start() {
                        // absolute encoders: nothing to do
                        self.homed = ALL_HOMED;
                    }
                }
                Some(ControlKind::Jog | ControlKind::JogStep)
                    if self.toward_a_tripped_limit(c.axis, c.value) =>
                {
                    let i = c.axis as usize;
                    let max = c.value > 0.0;
                    self.alarm(
                        AlarmCode::Other,
                        c.axis,
                        format_args!(
                            "jog of {} toward its tripped {} limit switch refused: jog away from it",
                            softnc_core::Axis::name_of(i),
                            if max { "maximum" } else { "minimum" },
                        ),
                    )?;
                }
                Some(ControlKind::Jog)
                    if self.idle_between_jobs() || self.state == MachineState::Jogging =>
                {
                    if self.state != MachineState::Jogging {
                        self.manual.hold(self.last_cmd);
                    }
                    let i = c.axis as usize;
                    let homed = self.homed & (1 << i) != 0;
                    self.manual.jog(i, c.value / 60.0, homed);
                    if self.manual.active() {
                        self.state = MachineState::Jogging;
                    }
                }
                Some(ControlKind::JogStep) if self.idle_between_jobs() => {
                    self.manual.hold(self.last_cmd);
                    let i = c.axis as usize;
                    let homed = self.homed & (1 << i) != 0;
                    if self.manual.jog_step(i, c.value, homed) {
                        self.state = MachineState::Jogging;
                    }
                }
                Some(ControlKind::Abort)
                    if matches!(self.state, MachineState::Homing | MachineState::Jogging) =>
                {
                    self.manual.stop();
                }
                Some(k) if self.switches.apply(k, c.value) => {}
                // adaptive feed: the operator's override caps the force loop's; a
                // hold or an abort stops it (the interpolator owns the override)
                Some(ControlKind::FeedOverride) => {
                    if let Some(a) = self.adaptive.as_mut() {
                        a.set_override_cap(c.value);
                    }
                }
                Some(ControlKind::Hold | ControlKind::Abort) => self.feed_held = true,
                Some(ControlKind::Resume) => self.feed_held = false,
                Some(ControlKind::SpindleOverride) => {
                    // the MMI checked the profile's range
                    self.spindle_override = c.value;
                    if self.requested_job != 0 {
                        self.prep.request(PrepRequest::SpindleOverride {
                            job_id: self.requested_job,
                            spindle_override: c.value,
                        });
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Command samples from the interpolator, after the control commands: the MMI
    /// publishes a job's StartJob before the interpolator can send its first sample.
    fn pull_commands(&mut self) -> Result<()> {
        self.pull_control()?;
        while let Some(c) = self.commands.receive()? {
            let c = *c;
            if c.sent_unix_ns != 0 {
                let now = softnc_rt::unix_ns();
                let took = now.saturating_sub(c.sent_unix_ns);
                self.latency.record_ns(took);
                self.last_sample_rx = (now, took);
            }
            // another job's first sample starts it when no job runs; late samples of
            // the job that just finished or was aborted are ignored
            if self.phase.job_id() == 0 && c.job_id != 0 && c.job_id != self.last_job_id {
                self.start_job(c)?;
            }
            if c.job_id != self.phase.job_id() {
                continue; // a late sample of an aborted job
            }
            let s = RingSample {
                seq: c.seq,
                pos_mm: [c.pos_mm[0], c.pos_mm[1], c.pos_mm[2]],
            };
            match self.ring.push(s, c.is_end()) {
                Ok(()) => self.flags.push_back((
                    c.motion,
                    c.flags,
                    c.path_mm,
                    MachineOutputs::from(c.outputs),
                )),
                Err(e) => {
                    let job = self.phase.job_id();
                    self.alarm(
                        AlarmCode::SequenceError,
                        u32::MAX,
                        format_args!("job {job}: {e}"),
                    )?;
                    self.begin_dry_stop();
                }
            }
        }
        Ok(())
    }

    fn start_job(&mut self, first: CommandSample) -> Result<()> {
        self.flags.clear();
        self.job_aborted = false;
        // (a hold or an abort before it is not this job's)
        self.feed_held = false;
        self.phase = JobPhase::Preparing { id: first.job_id };
        self.last_job_id = first.job_id;
        self.current = None;
        let start = [first.pos_mm[0], first.pos_mm[1], first.pos_mm[2]];
        self.start_mm = start;
        // N lead-in and run-out cycles for the engine's command filters (paper 002);
        // every job's engine is built from the same profile, so the running one tells
        self.ring.reset_padded(self.engine.filter_window());
        if self.requested_job != first.job_id {
            // a job whose start this process did not see (it was restarted): a fresh
            // machine without the programmed path
            self.requested_job = first.job_id;
            self.prep.request(PrepRequest::Job {
                job_id: first.job_id,
                path: FixedStr::empty(),
                spindle_override: self.spindle_override,
                start_mm: self.last_cmd,
                from_line: None,
                switches: self.switches,
                // (a restarted process does not know the job's options: without)
                adaptive_cap: None,
            });
        }
        self.last_cmd = start;
        self.prev_cmd = start;
        self.install_job()
    }

    /// Take what the preparation thread has made.
    fn take_prepared(&mut self) -> Result<()> {
        if !self.prep_lost && !self.prep.is_alive() {
            // no job can be prepared any more: fault rather than wait for ever
            self.prep_lost = true;
            self.state = MachineState::Faulted;
            self.alarm(
                AlarmCode::Other,
                u32::MAX,
                format_args!(
                    "the position process's preparation thread ended: no job can start; restart the daemon"
                ),
            )?;
        }
        while let Some(r) = self.prep.poll() {
            match r {
                Prepared::Job(p) => {
                    if let Some(old) = self.staged_job.replace(p) {
                        self.prep.retire(Retired::Job(old));
                    }
                }
                Prepared::Spindle { job_id, designs } => {
                    if let Some((_, old)) = self.pending_designs.replace((job_id, designs)) {
                        self.prep.retire(Retired::Spindle(old));
                    }
                }
                Prepared::SpindleRefused {
                    job_id,
                    spindle_override,
                    message,
                } => {
                    self.alarm(
                        AlarmCode::Other,
                        u32::MAX,
                        format_args!(
                            "job {job_id}: spindle override {:.0} % refused: {}",
                            spindle_override * 100.0,
                            message.as_str()
                        ),
                    )?;
                }
            }
        }
        self.install_job()?;
        if self.phase.prepared() {
            if let Some(old) = self.engine.take_replaced_spindle_designs() {
                self.prep.retire(Retired::Spindle(old));
            }
            if let Some((job_id, designs)) = self.pending_designs.take() {
                if job_id != self.phase.job_id() {
                    self.prep.retire(Retired::Spindle(designs));
                } else if let Err(back) = self.engine.install_spindle_designs(designs) {
                    // the last table is still being swapped out: next cycle
                    self.pending_designs = Some((job_id, back));
                }
            }
        }
        Ok(())
    }

    /// Swap the running job's preparation in once it and the job's first sample
    /// are both there: its engine at rest at the start, its path, its trace.
    fn install_job(&mut self) -> Result<()> {
        let JobPhase::Preparing { id: job_id } = self.phase else {
            return Ok(());
        };
        let Some(mut p) = self.staged_job.take() else {
            return Ok(());
        };
        if p.job_id != self.phase.job_id() {
            // an earlier job's, or a later one's: keep a later one staged
            if p.job_id > self.phase.job_id() {
                self.staged_job = Some(p);
            } else {
                self.prep.retire(Retired::Job(p));
            }
            return Ok(());
        }
        // the new engine takes the machine over (a drive handed on, or a fresh
        // simulated machine at the start)
        p.engine.take_over(&mut self.engine, self.start_mm);
        std::mem::swap(&mut self.engine, &mut p.engine);
        std::mem::swap(&mut self.primitives, &mut p.primitives);
        std::mem::swap(&mut self.lines, &mut p.lines);
        std::mem::swap(&mut self.trace, &mut p.trace);
        std::mem::swap(&mut self.adaptive, &mut p.adaptive);
        self.phase = JobPhase::Ready { id: job_id };
        if let Some((axis, msg)) = p.error.take() {
            self.state = MachineState::Faulted;
            self.alarm(AlarmCode::Other, axis as u32, format_args!("{msg}"))?;
        }
        self.prep.retire(Retired::Job(p));
        Ok(())
    }

    /// A jog of axis `axis` in the direction of `value`'s sign would go toward a
    /// limit switch that is tripped (LinuxCNC lets an axis off its limit switch
    /// only away from it).
    fn toward_a_tripped_limit(&self, axis: u32, value: f64) -> bool {
        let m = self.engine.io().last_inputs();
        let bit = 1u32.checked_shl(axis).unwrap_or(0);
        (value > 0.0 && m.limit_max & bit != 0) || (value < 0.0 && m.limit_min & bit != 0)
    }

    /// A limit switch is tripped (at the last cycle's read).
    fn limit_tripped(&self) -> bool {
        let m = self.engine.io().last_inputs();
        m.limit_min | m.limit_max != 0
    }

    /// The operator overrides the limit switches (until they are all released).
    pub fn limits_overridden(&self) -> bool {
        self.limits_overridden
    }

    /// On, no job, nothing moving by hand.
    fn idle_between_jobs(&self) -> bool {
        self.state == MachineState::Idle && self.phase.job_id() == 0
    }

    /// One cycle of a jog or homing: the command, and the state when it is over.
    fn manual_step(&mut self) -> Result<[f64; MAX_AXES]> {
        let inputs = *self.engine.io().last_inputs();
        let (cmd, event) = self.manual.step(self.engine.measured_mm().0, &inputs);
        match event {
            Some(ManualEvent::Rereferenced {
                axis,
                correction_mm,
            }) => {
                // the axis's coordinates move by the correction (the encoder is
                // re-referenced where it stands, at rest): the engine restarts there,
                // the other axes where they are commanded
                let mut at = self.last_cmd;
                at[axis] = self.engine.measured_mm()[axis] + correction_mm;
                self.engine.reset(at);
                self.last_cmd[axis] += correction_mm;
                self.prev_cmd[axis] += correction_mm;
                // the manual trace goes on in the new frame after a gap of a cycle
                // (its positions step by the correction: not a motion)
                self.cycles += 1;
            }
            Some(ManualEvent::Homed { axis }) => {
                self.homed |= 1 << axis;
            }
            Some(ManualEvent::HomingFailed { axis, why }) => {
                let name = softnc_core::Axis::name_of(axis);
                self.alarm(
                    AlarmCode::Other,
                    axis as u32,
                    format_args!("homing {name} failed: {why}"),
                )?;
            }
            None => {}
        }
        if !self.manual.active() {
            self.state = MachineState::Idle;
        }
        Ok(cmd)
    }

    /// The running job's force loop, when it runs with adaptive feed.
    pub fn adaptive_feed(&self) -> Option<&softnc_servo::adaptive_feed::AdaptiveFeed> {
        self.adaptive.as_ref()
    }

    /// Set the programmed path of the job (for the contour error).
    pub fn set_job_primitives(&mut self, prims: Vec<Option<Primitive>>) {
        self.primitives = prims;
    }

    fn begin_dry_stop(&mut self) {
        if self.phase.dry().is_none()
            && matches!(self.state, MachineState::Running | MachineState::Held)
        {
            let v = dist(self.last_cmd, self.prev_cmd) / self.cfg.machine.interpolation_cycle_s;
            self.phase = JobPhase::DryStop {
                id: self.phase.job_id(),
                stop: DryStop {
                    origin: self.last_cmd,
                    speed_mm_per_s: v,
                    s_mm: 0.0,
                },
            };
        }
    }

    /// One position cycle.
    #[allow(clippy::too_many_lines)]
    pub fn cycle(&mut self) -> Result<()> {
        // 1. inputs (control first: a job's StartJob comes before its samples)
        self.pull_commands()?;
        self.take_prepared()?;
        self.watch_mmi()?;
        // 2. mode and position command
        let mut cmd = self.last_cmd;
        let mut feed_move = false;
        // Some(motion) when this cycle steps the ring's current sample
        let mut ring_motion = None;
        match self.state {
            MachineState::Idle => {
                if matches!(self.phase, JobPhase::Ready { .. }) && self.ring.ready(self.window) {
                    self.state = MachineState::Running;
                }
            }
            MachineState::Running | MachineState::Held => {}
            // the position process never enters Stopping (the interpolator's and
            // the MMI's view of an abort)
            MachineState::Faulted | MachineState::EStopped | MachineState::Stopping => {}
            MachineState::Off
            | MachineState::Homing
            | MachineState::Jogging
            | MachineState::Paused
            | MachineState::Mdi => {}
        }
        if matches!(self.state, MachineState::Running | MachineState::Held) {
            if let Some(stop) = self.phase.dry() {
                cmd = self.dry_stop_step(stop);
            } else if self.phase.settling().is_some() {
                // after the job's last sample: the command stands, the axes settle
            } else if !self.ring.ready(self.window) {
                let (ahead, needed) = (self.ring.ahead().saturating_sub(1), self.window);
                let (rx_ns, took_ns) = self.last_sample_rx;
                let ago_ms = softnc_rt::unix_ns().saturating_sub(rx_ns) as f64 * 1e-6;
                let took_ms = took_ns as f64 * 1e-6;
                self.alarm(
                    AlarmCode::RingDry,
                    u32::MAX,
                    format_args!(
                        "command ring ran dry ({ahead} samples ahead, {needed} needed; the last sample came {ago_ms:.1} ms ago, {took_ms:.1} ms after it was sent); stopping along the path"
                    ),
                )?;
                self.begin_dry_stop();
                if let Some(stop) = self.phase.dry() {
                    cmd = self.dry_stop_step(stop);
                }
            } else if let Some(p) = self.ring.at(0) {
                // stepped below by `step_ring`, which filters it (paper 002 eq 1) over
                // the window [i−N, i+N]: exactly what `softnc sim` steps
                cmd = p;
                let (motion, flags, path_mm, outputs) =
                    self.flags
                        .front()
                        .copied()
                        .unwrap_or((0, 0, 0.0, MachineOutputs::safe()));
                feed_move = flags & CommandSample::FLAG_FEED_MOVE != 0;
                ring_motion = Some(motion);
                // the sample in use carries the outputs (as `softnc sim` applies them)
                let outputs = if self.job_aborted {
                    outputs.after_abort()
                } else {
                    outputs
                };
                self.outputs = outputs;
                self.current = Some(CommandSample {
                    seq: self.ring.source_index(),
                    job_id: self.phase.job_id(),
                    time_index: self.ring.current_index(),
                    pos_mm: p,
                    motion,
                    flags,
                    sent_unix_ns: 0,
                    path_mm,
                    outputs: outputs.into(),
                });
            }
        }
        // 3. controller stacks and servo backend (the engine `softnc sim` steps); the
        //    machine stands still (not stepped) between jobs
        let moving = matches!(self.state, MachineState::Running | MachineState::Held)
            || self.phase.dry().is_some();
        // between jobs the servo holds the last command: the machine keeps running
        // (not in a fault or E-stop, where the drives are off)
        let holding = self.idle_between_jobs()
            || matches!(self.state, MachineState::Homing | MachineState::Jogging);
        if matches!(self.state, MachineState::Homing | MachineState::Jogging) {
            cmd = self.manual_step()?;
        }
        // the machine around the axes: the safe state while it is off, E-stopped or
        // faulted; else the sample in use's outputs, or between jobs the last ones
        // held
        let on = !matches!(
            self.state,
            MachineState::Off | MachineState::EStopped | MachineState::Faulted
        );
        if !on {
            self.outputs = MachineOutputs::safe();
        }
        self.engine.set_outputs(&self.outputs);
        self.engine.set_output_state(softnc_servo::io::OutputState {
            machine_on: on,
            amp_enable: on,
            spindle_override: self.spindle_override,
        });
        let rec = if moving || holding {
            let stepped = match ring_motion {
                Some(motion) => self.engine.step_ring(&self.ring, motion, feed_move),
                None => None,
            };
            match stepped.unwrap_or_else(|| self.engine.step(cmd, feed_move)) {
                Ok(r) => {
                    cmd = r.cmd_mm.0;
                    r
                }
                Err(e) => {
                    // the E-stop path: every drive stopped, the job's trace closed
                    self.emergency_stop(StopCause::Backend(e))?;
                    softnc_servo::CycleRecord {
                        cmd_mm: Axes(cmd),
                        ..Default::default()
                    }
                }
            }
        } else {
            // the axes stand (drives off): the I/O is exchanged alone
            if let Err(e) = self.engine.exchange_io() {
                self.alarm(
                    AlarmCode::Other,
                    u32::MAX,
                    format_args!("servo backend I/O fault: {e}"),
                )?;
            }
            // the drives are not stepped; off, E-stopped or faulted the command
            // follows the measured position, as LinuxCNC's motion controller's does
            // while disabled, so neither a reset nor the next `on` steps it
            let actual_mm = self.engine.measured_mm();
            if matches!(
                self.state,
                MachineState::Off | MachineState::EStopped | MachineState::Faulted
            ) {
                cmd = self.command_where_standing();
            }
            softnc_servo::CycleRecord {
                cmd_mm: Axes(cmd),
                actual_mm,
                following_mm: Axes::from_fn(|a| cmd[a.index()] - actual_mm[a]),
                ctrl_out: Axes::splat(0.0),
            }
        };
        // the force loop (adaptive feed) on the cycles that step the job's samples,
        // as the simulator steps it: its override goes out in the status
        if let (Some(a), Some(_)) = (self.adaptive.as_mut(), ring_motion) {
            if !self.feed_held && self.phase.dry().is_none() {
                a.cycle(self.engine.backend());
            }
        }
        let fe = rec.following_mm;
        // 4. faults: the E-stop input and the limit switches, following error
        self.watch_inputs()?;
        if matches!(self.state, MachineState::Running | MachineState::Held) {
            if let Some(axis) =
                (0..MAX_AXES).find(|&i| fe[i].abs() > self.cfg.config.following_error_limit_mm)
            {
                self.state = MachineState::EStopped;
                let limit_mm = self.cfg.config.following_error_limit_mm;
                self.alarm(
                    AlarmCode::FollowingError,
                    axis as u32,
                    format_args!(
                        "following error {:.3} mm on {} over the limit {limit_mm} mm: emergency stop",
                        fe[axis],
                        softnc_core::Axis::name_of(axis),
                    ),
                )?;
            }
        }
        // 5. status (contour error exactly as the simulator computes it: the actual
        //    position's distance to the programmed path near the command)
        let contour = match (feed_move, self.current) {
            (true, Some(c)) => softnc_servo::contour::contour_error_near(
                |m| self.primitives.get(m as usize).copied().flatten(),
                c.motion,
                Vec3(rec.cmd_mm.xyz()),
                Vec3(rec.actual_mm.xyz()),
            )
            .unwrap_or(f64::NAN),
            _ => f64::NAN,
        };
        self.cycles += 1;
        if let (Some(t), true) = (
            &self.manual_trace,
            matches!(self.state, MachineState::Homing | MachineState::Jogging),
        ) {
            t.push(softnc_servo::TraceRow {
                cycle: self.cycles,
                time_s: self.cycles as f64 * self.cfg.machine.interpolation_cycle_s,
                motion: 0,
                record: rec,
                contour_mm: None,
                io: self.engine.io().trace(),
            });
        }
        if moving {
            if let (Some(t), Some(c)) = (&self.trace, self.current) {
                t.push(softnc_servo::TraceRow {
                    cycle: c.time_index,
                    time_s: c.time_index as f64 * self.cfg.machine.interpolation_cycle_s,
                    motion: c.motion,
                    record: rec,
                    contour_mm: contour.is_finite().then_some(contour),
                    io: self.engine.io().trace(),
                });
            }
        }
        // a job stopped where it is (an E-stop or a fault on this cycle, after its
        // row): its trace is complete
        if matches!(self.state, MachineState::EStopped | MachineState::Faulted)
            && self.phase.dry().is_none()
        {
            self.close_trace();
        }
        if matches!(
            self.state,
            MachineState::Off | MachineState::EStopped | MachineState::Faulted
        ) {
            // (stopped on this cycle: the engine writes them from the next)
            self.outputs = MachineOutputs::safe();
        }
        let mut status = PositionStatus {
            seq: self.current.map_or(0, |c| c.seq),
            job_id: self.phase.job_id(),
            time_index: self.current.map_or(0, |c| c.time_index),
            cmd_mm: [0.0; MAX_AXES],
            actual_mm: [0.0; MAX_AXES],
            following_err_mm: [0.0; MAX_AXES],
            ctrl_out: [0.0; MAX_AXES],
            contour_err_mm: contour,
            ring_fill: self.ring.ahead() as u32,
            state: self.state.wire(),
            spindle_override: self.spindle_override,
            spindle_rpm: match (self.phase.prepared(), self.engine.spindle_schedule()) {
                (true, Some(s)) => s.effective_rpm(),
                _ => 0.0,
            },
            path_mm: self.current.map_or(0.0, |c| c.path_mm),
            motion: self.current.map_or(0, |c| c.motion),
            line: match self.current {
                Some(c) if self.phase.job_id() != 0 => {
                    self.lines.get(c.motion as usize).copied().unwrap_or(0)
                }
                _ => 0,
            },
            homed: self.homed,
            mmi_control_seq: self.mmi_control_seq,
            force_override: f64::NAN,
            force_revolutions: 0,
            force_n: f64::NAN,
            inputs: (*self.engine.io().last_inputs()).into(),
            outputs: self.outputs.into(),
        };
        if let (Some(a), true) = (&self.adaptive, self.phase.job_id() != 0) {
            status.force_override = a.override_frac();
            status.force_revolutions = a.revolutions();
            status.force_n = a.last().map_or(f64::NAN, |r| r.est_force_n);
        }
        status.cmd_mm[..3].copy_from_slice(&cmd);
        status.actual_mm[..MAX_AXES].copy_from_slice(&*rec.actual_mm);
        status.following_err_mm[..MAX_AXES].copy_from_slice(&*fe);
        status.ctrl_out[..MAX_AXES].copy_from_slice(&*rec.ctrl_out);
        self.prev_cmd = self.last_cmd;
        self.last_cmd = cmd;
        // 6. advance
        if self.state == MachineState::Running && self.phase.dry().is_none() {
            let source = self.ring.source_index();
            if self.ring.advance() {
                if self.ring.source_index() > source {
                    self.flags.pop_front();
                }
            } else if self.ring.ended() && self.phase.settling().is_none() {
                // the job's last sample: its trace (the samples, as `softnc sim`
                // writes them) is closed off the cycle path; the job ends when the
                // axes are in position
                if let Some(t) = self.trace.take() {
                    self.prep.retire(Retired::Trace(t));
                }
                self.phase = JobPhase::Settling {
                    id: self.phase.job_id(),
                    cycles: 0,
                };
            }
            if let Some(n) = self.phase.settling() {
                let in_position = (0..MAX_AXES).all(|i| fe[i].abs() <= self.in_position_mm[i]);
                if in_position {
                    self.end_job(&mut status);
                } else if n >= self.in_position_timeout_cycles {
                    let job = self.phase.job_id();
                    let timeout_s = self.cfg.config.in_position_timeout_s;
                    self.alarm(
                        AlarmCode::Other,
                        u32::MAX,
                        format_args!(
                            "job {job}: axes not in position {timeout_s} s after the last command (following error {:.1} / {:.1} / {:.1} µm)",
                            fe[0] * 1000.0,
                            fe[1] * 1000.0,
                            fe[2] * 1000.0
                        ),
                    )?;
                    self.end_job(&mut status);
                } else {
                    self.phase = JobPhase::Settling {
                        id: self.phase.job_id(),
                        cycles: n + 1,
                    };
                }
            }
        }
        self.outbox.send(PositionMsg::Status(status))?;
        Ok(())
    }

    /// The job is over (in position, or settling timed out): report once more with
    /// its id, as idle; the next cycles report idle with no job.
    fn end_job(&mut self, status: &mut PositionStatus) {
        if self.requested_job == self.phase.job_id() {
            self.requested_job = 0; // (not if the next job was asked for)
        }
        // the last status still names the job (the interpolator counts it as
        // consumed); the next cycles report idle with no job
        self.state = MachineState::Idle;
        self.phase = JobPhase::NoJob;
        status.state = self.state.wire();
        self.current = None;
    }

    fn dry_stop_step(&mut self, mut stop: DryStop) -> [f64; MAX_AXES] {
        let t = self.cfg.machine.interpolation_cycle_s;
        let a = self
            .cfg
            .machine
            .max_acc()
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min)
            * 0.98;
        stop.speed_mm_per_s = (stop.speed_mm_per_s - a * t).max(0.0);
        stop.s_mm += stop.speed_mm_per_s * t;
        // walk the polyline of samples from the current one
        let mut remaining = stop.s_mm;
        // from the position last commanded, on through the samples still in the ring
        let mut p = stop.origin;
        let mut k = 0;
        while let Some(q) = self.ring.at(k) {
            let d = dist(p, q);
            if d >= remaining || k as u64 >= self.ring.ahead() {
                if d > 0.0 && d >= remaining {
                    let u = remaining / d;
                    p = [
                        p[0] + (q[0] - p[0]) * u,
                        p[1] + (q[1] - p[1]) * u,
                        p[2] + (q[2] - p[2]) * u,
                    ];
                }
                break;
            }
            remaining -= d;
            p = q;
            k += 1;
        }
        self.phase = JobPhase::DryStop {
            id: self.phase.job_id(),
            stop,
        };
        if stop.speed_mm_per_s == 0.0 {
            self.state = MachineState::Faulted;
            // the job is over: close its trace (off the cycle path)
            if let Some(t) = self.trace.take() {
                self.prep.retire(Retired::Trace(t));
            }
        }
        p
    }

    fn housekeeping(&mut self) -> Result<()> {
        if self.last_hb.elapsed().as_secs_f64() >= self.cfg.config.heartbeat_period_s {
            self.hb_counter += 1;
            self.outbox.send(PositionMsg::Heartbeat(Heartbeat {
                process: ProcessId::Position.wire(),
                pid: std::process::id(),
                counter: self.hb_counter,
                state: self.state.wire(),
                job_id: self.phase.job_id(),
            }))?;
            let j = self.stats.jitter();
            let c = self.stats.compute();
            self.outbox.send(PositionMsg::LoopStats(LoopStatsMsg {
                process: ProcessId::Position.wire(),
                cycles: self.stats.cycles(),
                jitter_ns: [j.p50_ns, j.p99_ns, j.p999_ns, j.max_ns],
                compute_ns: [c.p50_ns, c.p99_ns, c.p999_ns, c.max_ns],
                overruns: self.stats.overruns(),
                latency_ns: {
                    let l = self.latency.percentiles();
                    [l.p50_ns, l.p99_ns, l.p999_ns, l.max_ns]
                },
                bus: self.engine.backend().bus_stats().map_or([0; 9], |b| {
                    [
                        b.frames,
                        b.lost_frames,
                        b.wkc_errors,
                        b.rtt_p50_ns,
                        b.rtt_p99_ns,
                        b.rtt_max_ns,
                        b.dc_reads,
                        b.dc_deviation_last_ns,
                        b.dc_deviation_max_ns,
                    ]
                }),
            }))?;
            self.last_hb = Instant::now();
        }
        Ok(())
    }

    /// The spindle override in force (fraction).
    pub fn spindle_override(&self) -> f64 {
        self.spindle_override
    }

    /// The running job's engine.
    pub fn engine(&self) -> &CycleEngine<B> {
        &self.engine
    }

    /// The simulated machine's own inputs (E-stop chain, user lines, probe), when
    /// the backend is one: for tests, which open the E-stop chain or trip an input
    /// mid-job.
    pub fn simulated(&mut self) -> Option<&mut dyn softnc_servo::SimulatedMachine> {
        self.engine.backend_mut().simulated()
    }

    /// The `seq` of the command sample in use (none between jobs).
    pub fn current_seq(&self) -> Option<u64> {
        self.current.map(|c| c.seq)
    }

    /// Which axes are homed (bit i: axis i).
    pub fn homed(&self) -> u32 {
        self.homed
    }

    /// The machine state as this process sees it.
    pub fn state(&self) -> MachineState {
        self.state
    }

    /// The loop's timing statistics.
    pub fn stats(&self) -> &LoopStats {
        &self.stats
    }
}

/// Manual motion (homing, jogs) traced, when traces are on, to a file of this
/// process's own, made when the process starts (not on the cycle); rows numbered by
/// the cycle.
fn manual_trace(cfg: &Loaded) -> Option<crate::trace::TraceSink> {
    if !cfg.config.trace {
        return None;
    }
    let file = cfg
        .data_dir
        .join(format!("trace-manual-{}.csv", std::process::id()));
    let _ = std::fs::create_dir_all(&cfg.data_dir);
    crate::trace::TraceSink::start(&file, cfg.config.clock == ClockMode::Lockstep)
        .map_err(|e| tracing::warn!("cannot trace to {}: {e}", file.display()))
        .ok()
}

/// Why the machine is E-stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StopCause {
    /// The operator's E-stop through the MMI.
    Operator,
    /// An operator client's E-stop past the MMI (its pid).
    Client(u32),
    /// The external E-stop input opened.
    Input,
    /// Axis `axis`'s limit switch at its maximum (`max`) or minimum end tripped.
    Limit { axis: usize, max: bool },
    /// The servo backend's cycle failed (a fieldbus fault, a drive's fault).
    Backend(softnc_servo::BackendError),
}

/// Each axis's in-position band (the profile's) and measurement floor: two encoder
/// counts and four σ of the profile's measurement noise (what the reading of an
/// axis at rest varies by; the floor the Markov identification uses,
/// `softnc_learning::markov::settled_terms`).
fn standing_bands(machine: &softnc_machine::MachineProfile) -> ([f64; MAX_AXES], [f64; MAX_AXES]) {
    (
        std::array::from_fn(|i| machine.axes[i].in_position_mm),
        std::array::from_fn(|i| {
            2.0 * machine.axes[i].encoder_resolution_mm + 4.0 * machine.axis_servo(i).noise_mm
        }),
    )
}

fn dist(a: [f64; MAX_AXES], b: [f64; MAX_AXES]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
