//! The payload types. All `#[repr(C)]`, `Copy`, fixed size, `ZeroCopySend`.

use crate::fixed_str::FixedStr;
use iceoryx2::prelude::ZeroCopySend;
use softnc_core::machine_io::{MachineInputs, MachineOutputs, SpindleDir, ANALOG_LINES};

/// Axes a sample carries: the stack's one axis count.
pub use softnc_core::MAX_AXES;

/// One command sample per interpolation cycle, interpolation → position control.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::CommandSample")]
pub struct CommandSample {
    /// Sequence number, consecutive within a job (gaps and reordering are alarms).
    pub seq: u64,
    /// Job the sample belongs to.
    pub job_id: u64,
    /// Cycle index from the start of the job (time = index · T).
    pub time_index: u64,
    /// Command position per axis, machine coordinates (mm).
    pub pos_mm: [f64; MAX_AXES],
    /// Index of the program motion being executed.
    pub motion: u32,
    /// `CommandSample::FLAG_*` bits.
    pub flags: u32,
    /// When the interpolator published it (ns since the Unix epoch): the position
    /// process measures the interp → position latency from it.
    pub sent_unix_ns: u64,
    /// Distance along the planned path from the job's start (mm).
    pub path_mm: f64,
    /// What the machine around the axes is told while this sample runs.
    pub outputs: OutputsWire,
}

impl CommandSample {
    /// The job's last sample: the position process pads its window with it.
    pub const FLAG_END_OF_JOB: u32 = 1;
    /// The sample lies on a feed move (G1/G2/G3).
    pub const FLAG_FEED_MOVE: u32 = 2;

    /// A sample for three axes.
    pub fn new(seq: u64, job_id: u64, time_index: u64, xyz_mm: [f64; 3]) -> Self {
        let pos_mm = xyz_mm;
        CommandSample {
            seq,
            job_id,
            time_index,
            pos_mm,
            motion: 0,
            flags: 0,
            sent_unix_ns: 0,
            path_mm: 0.0,
            outputs: OutputsWire::default(),
        }
    }
    /// True if this is the job's last sample.
    pub fn is_end(&self) -> bool {
        self.flags & Self::FLAG_END_OF_JOB != 0
    }
}

/// The machine's state as the processes see it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum MachineState {
    /// Ready for a job.
    Idle = 0,
    /// Running a job.
    Running = 1,
    /// Feed hold: standing on the path, resumable.
    Held = 2,
    /// Controlled stop after a fault; needs a reset.
    Faulted = 3,
    /// Emergency stop; needs a reset.
    EStopped = 4,
    /// A job being stopped along its path (abort, shutdown); idle when at rest.
    Stopping = 5,
    /// Machine off: drives disabled, nothing moves; `MachineOn` makes it idle.
    Off = 6,
    /// Axes homing (the profile's sequence).
    Homing = 7,
    /// An axis jogging (continuous or incremental).
    Jogging = 8,
    /// A job stopped at an M0/M1 or a single-block end: `resume` (or `step`) goes on.
    Paused = 9,
    /// Running an MDI block.
    Mdi = 10,
}

/// Position control → MMI: one per cycle (status and trace).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::PositionStatus")]
pub struct PositionStatus {
    /// Sequence number of the command sample this cycle used.
    pub seq: u64,
    /// Job id (0 when idle).
    pub job_id: u64,
    /// Cycle index from the start of the job.
    pub time_index: u64,
    /// Command position (after command shaping) per axis (mm).
    pub cmd_mm: [f64; MAX_AXES],
    /// Actual position per axis (mm).
    pub actual_mm: [f64; MAX_AXES],
    /// Following error per axis (mm).
    pub following_err_mm: [f64; MAX_AXES],
    /// Controller output per axis (its own unit).
    pub ctrl_out: [f64; MAX_AXES],
    /// Contour error (mm), NaN outside feed moves.
    pub contour_err_mm: f64,
    /// Samples waiting in the lookahead ring.
    pub ring_fill: u32,
    /// Machine state (a [`MachineState`] as `wire()`).
    pub state: u32,
    /// Spindle override in force (fraction of the programmed speed).
    pub spindle_override: f64,
    /// Speed the spindle turns at, programmed × override (rpm; 0 without a spindle
    /// model in the profile or between jobs).
    pub spindle_rpm: f64,
    /// Distance along the planned path of the sample this cycle used (mm): the
    /// job's progress.
    pub path_mm: f64,
    /// Program motion of the sample this cycle used.
    pub motion: u32,
    /// Program line of that motion (1-based; 0 outside a job).
    pub line: u32,
    /// Bit i set: axis i is homed (its machine coordinates are referenced).
    pub homed: u32,
    /// The `seq` of the last MMI control command this process has taken (0: none
    /// since it started): a state the MMI asked for (a jog, homing) is in this
    /// status or already over once this reaches the command's `seq`.
    pub mmi_control_seq: u64,
    /// Adaptive feed: the override the force loop gives (fraction), from sample
    /// `seq` + the lookahead on; NaN when the job runs without it.
    pub force_override: f64,
    /// Adaptive feed: spindle revolutions the force loop has closed in this job (a
    /// new override each).
    pub force_revolutions: u64,
    /// Adaptive feed: the last revolution's estimated peak cutting force (N); NaN
    /// without it.
    pub force_n: f64,
    /// What the machine around the axes reported this cycle.
    pub inputs: InputsWire,
    /// What the machine around the axes was told this cycle (the program's
    /// outputs, before the I/O map): the sample in use's during a job; between
    /// jobs the last job's or MDI command's, held; the safe state while the
    /// machine is off, E-stopped or faulted.
    pub outputs: OutputsWire,
}

/// [`MachineOutputs`] on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct OutputsWire {
    /// Programmed spindle speed (rpm, ≥ 0).
    pub spindle_rpm: f64,
    /// Orient angle (degrees); NaN while not orienting.
    pub spindle_orient_deg: f64,
    /// `OutputsWire::*` bits.
    pub flags: u32,
    /// Spindle direction: 0 stopped, 1 clockwise, 2 counter-clockwise.
    pub spindle_dir: u32,
    /// Digital outputs (bit P).
    pub digital: u64,
    /// Analog outputs (E).
    pub analog: [f64; ANALOG_LINES],
}

impl OutputsWire {
    const MIST: u32 = 1;
    const FLOOD: u32 = 2;
    const TOOL_CHANGE: u32 = 4;
    /// Bits 8–9: M19's orient direction (0 shorter way, 1 cw, 2 ccw).
    const ORIENT_DIR_SHIFT: u32 = 8;
}

impl From<MachineOutputs> for OutputsWire {
    fn from(o: MachineOutputs) -> Self {
        let bit = |on: bool, b: u32| if on { b } else { 0 };
        OutputsWire {
            spindle_rpm: o.spindle_rpm,
            spindle_orient_deg: o.spindle_orient_deg.unwrap_or(f64::NAN),
            flags: bit(o.coolant_mist, Self::MIST)
                | bit(o.coolant_flood, Self::FLOOD)
                | bit(o.tool_change, Self::TOOL_CHANGE)
                | u32::from(o.spindle_orient_dir & 3) << Self::ORIENT_DIR_SHIFT,
            spindle_dir: match o.spindle_dir {
                SpindleDir::Stopped => 0,
                SpindleDir::Clockwise => 1,
                SpindleDir::CounterClockwise => 2,
            },
            digital: o.digital,
            analog: o.analog,
        }
    }
}

impl From<OutputsWire> for MachineOutputs {
    fn from(w: OutputsWire) -> Self {
        MachineOutputs {
            spindle_dir: match w.spindle_dir {
                1 => SpindleDir::Clockwise,
                2 => SpindleDir::CounterClockwise,
                _ => SpindleDir::Stopped,
            },
            spindle_rpm: w.spindle_rpm,
            spindle_orient_deg: (!w.spindle_orient_deg.is_nan()).then_some(w.spindle_orient_deg),
            spindle_orient_dir: (w.flags >> OutputsWire::ORIENT_DIR_SHIFT & 3) as u8,
            coolant_mist: w.flags & OutputsWire::MIST != 0,
            coolant_flood: w.flags & OutputsWire::FLOOD != 0,
            tool_change: w.flags & OutputsWire::TOOL_CHANGE != 0,
            digital: w.digital,
            analog: w.analog,
        }
    }
}

/// [`MachineInputs`] on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct InputsWire {
    /// Spindle speed from its encoder (rpm, signed).
    pub spindle_rpm: f64,
    /// Spindle position (revolutions).
    pub spindle_revs: f64,
    /// Index pulses seen.
    pub spindle_index_count: u64,
    /// `InputsWire::*` bits.
    pub flags: u32,
    /// Bit a: axis a's minimum-end limit switch.
    pub limit_min: u32,
    /// Bit a: axis a's maximum-end limit switch.
    pub limit_max: u32,
    /// Bit a: axis a's home switch.
    pub home: u32,
    /// Digital inputs (bit P).
    pub digital: u64,
    /// Analog inputs (E).
    pub analog: [f64; ANALOG_LINES],
}

impl InputsWire {
    const AT_SPEED: u32 = 1;
    const ESTOP_OPEN: u32 = 2;
    const PROBE: u32 = 4;
    const TOOL_CHANGED: u32 = 8;
    const ORIENTED: u32 = 16;
}

impl From<MachineInputs> for InputsWire {
    fn from(i: MachineInputs) -> Self {
        let bit = |on: bool, b: u32| if on { b } else { 0 };
        InputsWire {
            spindle_rpm: i.spindle_rpm,
            spindle_revs: i.spindle_revs,
            spindle_index_count: i.spindle_index_count,
            flags: bit(i.spindle_at_speed, Self::AT_SPEED)
                | bit(i.estop_open, Self::ESTOP_OPEN)
                | bit(i.probe, Self::PROBE)
                | bit(i.tool_changed, Self::TOOL_CHANGED)
                | bit(i.spindle_oriented, Self::ORIENTED),
            limit_min: i.limit_min,
            limit_max: i.limit_max,
            home: i.home,
            digital: i.digital,
            analog: i.analog,
        }
    }
}

impl From<InputsWire> for MachineInputs {
    fn from(w: InputsWire) -> Self {
        MachineInputs {
            spindle_rpm: w.spindle_rpm,
            spindle_revs: w.spindle_revs,
            spindle_index_count: w.spindle_index_count,
            spindle_at_speed: w.flags & InputsWire::AT_SPEED != 0,
            spindle_oriented: w.flags & InputsWire::ORIENTED != 0,
            estop_open: w.flags & InputsWire::ESTOP_OPEN != 0,
            probe: w.flags & InputsWire::PROBE != 0,
            tool_changed: w.flags & InputsWire::TOOL_CHANGED != 0,
            limit_min: w.limit_min,
            limit_max: w.limit_max,
            home: w.home,
            digital: w.digital,
            analog: w.analog,
        }
    }
}

/// Which process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ProcessId {
    /// The supervisor `softncd`.
    Supervisor = 0,
    /// `softnc-interp`.
    Interp = 1,
    /// `softnc-position`.
    Position = 2,
    /// `softnc-mmi`.
    Mmi = 3,
}

impl ProcessId {
    /// The process's role, as an operator reads it.
    pub fn name(self) -> &'static str {
        match self {
            ProcessId::Supervisor => "supervisor",
            ProcessId::Interp => "interpolation",
            ProcessId::Position => "position",
            ProcessId::Mmi => "MMI",
        }
    }
}

/// "I am alive", from every process.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::Heartbeat")]
pub struct Heartbeat {
    /// Sender ([`ProcessId`] as `wire()`).
    pub process: u32,
    /// OS process id.
    pub pid: u32,
    /// Increments with every heartbeat.
    pub counter: u64,
    /// The sender's view of the machine state ([`MachineState`] as `wire()`).
    pub state: u32,
    /// Job being worked on (0 none).
    pub job_id: u64,
}

/// Timing of one real-time loop (nanoseconds).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::LoopStats")]
pub struct LoopStats {
    /// Which loop ([`ProcessId`] as `wire()`).
    pub process: u32,
    /// Cycles counted.
    pub cycles: u64,
    /// Period jitter |actual − nominal| percentiles p50, p99, p99.9, max.
    pub jitter_ns: [u64; 4],
    /// Compute time per cycle percentiles p50, p99, p99.9, max.
    pub compute_ns: [u64; 4],
    /// Deadlines missed (a cycle started more than one period late).
    pub overruns: u64,
    /// Position process only: interp → position sample latency through iceoryx2,
    /// p50, p99, p99.9, max (ns; 0 when not measured).
    pub latency_ns: [u64; 4],
    /// Position process on a fieldbus only: frames, lost frames, working-counter
    /// errors, send-to-receive p50, p99, max (ns), DC system time difference
    /// reads, last and max |difference| (ns); all 0 without a bus.
    pub bus: [u64; 9],
}

/// What a control command from the MMI asks the interpolation and position
/// processes (the operator's requests are `softnc-api`'s `Request`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum ControlKind {
    /// Start the job in `path` as `job_id`.
    StartJob = 0,
    /// Set the live feed override to `value` (fraction, 0..=2.55).
    FeedOverride = 1,
    /// Feed hold.
    Hold = 2,
    /// Resume after a hold.
    Resume = 3,
    /// Abort the job (controlled stop).
    Abort = 4,
    /// Emergency stop.
    EStop = 5,
    /// Reset after a fault or E-stop.
    Reset = 6,
    /// Shut the process down.
    Shutdown = 7,
    /// Set the spindle override to `value` (fraction of the programmed speed).
    SpindleOverride = 10,
    /// Set the live rapid override to `value` (fraction of the traverse speed,
    /// 0..=1).
    RapidOverride = 16,
    /// Machine on: drives enabled, holding position.
    MachineOn = 11,
    /// Machine off: drives disabled (only when nothing moves).
    MachineOff = 12,
    /// Home `axis` (`u32::MAX`: all axes in the profile's order).
    Home = 13,
    /// Continuous jog of `axis` at `value` mm/min (signed; 0 stops it).
    Jog = 14,
    /// Incremental jog of `axis` by `value` mm at the profile's jog speed.
    JogStep = 15,
    /// Single block on (`value` 1) or off (0).
    SingleBlock = 20,
    /// Single block: run the next block.
    Step = 21,
    /// Optional stop (M1) switch on (`value` 1) or off (0).
    OptionalStop = 22,
    /// Block delete switch on (`value` 1) or off (0).
    BlockDelete = 23,
    /// Override the tripped limit switches until they are all released
    /// (LinuxCNC's override limits).
    OverrideLimits = 24,
}

/// MMI → interpolation and position control.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::ControlCommand")]
pub struct ControlCommand {
    /// Consecutive per sender.
    pub seq: u64,
    /// Who sent it (a [`ProcessId`] as `wire()`): the position process
    /// acknowledges the MMI's commands ([`PositionStatus::mmi_control_seq`]).
    pub sender: u32,
    /// What to do ([`ControlKind`] as `wire()`).
    pub kind: u32,
    /// Job id for `StartJob`.
    pub job_id: u64,
    /// Axis index for `Home`, `Jog`, `JogStep` (`u32::MAX`: none or all).
    pub axis: u32,
    /// Argument: the override fraction (for `StartJob`: the feed override in force,
    /// which the job starts at).
    pub value: f64,
    /// Job options for `StartJob` (bits: [`JOB_ADAPTIVE_FORCE`]); 0 otherwise.
    pub flags: u32,
    /// Job file for `StartJob`.
    pub path: FixedStr<512>,
}

/// Job option: the job runs with adaptive feed (paper 003's force loop drives the
/// feed override, capped by the operator's).
pub const JOB_ADAPTIVE_FORCE: u32 = 1;

/// Alarm codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum AlarmCode {
    /// A command sample was missing or out of order.
    SequenceError = 1,
    /// The lookahead ring ran dry during motion.
    RingDry = 2,
    /// A process died or went silent; the alarm's `process` names the one lost
    /// (raised by the supervisor).
    ProcessLost = 3,
    /// Following error over the limit.
    FollowingError = 4,
    /// Emergency stop.
    EStop = 5,
    /// A job was refused.
    JobRefused = 6,
    /// Not an alarm: a remark for the job's record (e.g. a learned correction applied
    /// or faded out); the MMI keeps it with the job, not in the alarm list.
    Note = 7,
    /// The plan's producer fell behind the interpolation (a long program streamed in
    /// real time): the path slowed to a stop, within its limits, at the end of what
    /// was planned, and went on when more came.
    PlanStarved = 8,
    /// The program could not be planned again while it ran (the check passed): the
    /// job stopped along its path at the end of what was planned.
    PlanFailed = 9,
    /// A machine operation of a job could not be completed (the spindle did not
    /// reach its speed within the profile's `at_speed_timeout_s`): the job stopped
    /// along its path.
    MachineWait = 10,
    /// Switching the machine on failed (the drives did not come on) or was refused
    /// (a limit switch tripped): the machine stays off.
    MachineOn = 11,
    /// A real-time loop stalled (a period far beyond its bound): the position loop
    /// stopped the machine as a fault, the interpolation loop its job.
    LoopStall = 20,
    /// A real-time loop ran late (periods off by more than the configured bound):
    /// how many and the worst, at most one alarm per period.
    LoopLate = 21,
    /// The supervisor started a process again after it died (raised by the
    /// supervisor; `process` and `pid` name the process started).
    ProcessRestarted = 30,
    /// Anything else.
    Other = 99,
}

/// An alarm, from any process.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::Alarm")]
pub struct Alarm {
    /// What ([`AlarmCode`] as `wire()`).
    pub code: u32,
    /// Axis concerned (u32::MAX none).
    pub axis: u32,
    /// Who raised it ([`ProcessId`] as `wire()`); for a `ProcessLost`, the process
    /// lost.
    pub process: u32,
    /// Job (0 none).
    pub job_id: u64,
    /// Cycle index when raised.
    pub time_index: u64,
    /// Plain-language text.
    pub message: FixedStr<256>,
    /// For a `ProcessLost`, the pid of the process lost (0: unknown), so that a
    /// late or replayed alarm never marks its successor lost; otherwise the
    /// raiser's pid.
    pub pid: u32,
    /// When it was raised (ns since the Unix epoch): an alarm replayed to a
    /// restarted MMI that the operator had already acknowledged by a reset is not
    /// shown again.
    pub raised_unix_ns: u64,
}

/// An emergency stop straight from an operator client to the position process
/// (the interpolator learns it from the position status), on the instance's
/// `estop` service: it stops the machine
/// even when the MMI does not answer. The service carries nothing else, so a
/// publisher on it can only stop the machine, never move it.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::EStopRequest")]
pub struct EStopRequest {
    /// The sending client's pid (for the alarm).
    pub sender_pid: u32,
    /// When it was sent (ns since the Unix epoch).
    pub sent_unix_ns: u64,
}

/// A setting on the simulated machine's panel (its E-stop chain, an input line,
/// the probe), from a test to the position process on the instance's `sim_panel`
/// service; the position process applies it through `SimulatedMachine` when its
/// backend is a simulated machine, and ignores it otherwise. For end-to-end tests of
/// the machine around the axes (softnc-sim's `wiring` names the lines).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::SimPanel")]
pub struct SimPanel {
    /// `SimPanel::ESTOP` (value ≠ 0: the chain open), `DIGITAL` (raw input `line`
    /// high when value ≠ 0), `ANALOG` (raw analog input `line` = value) or `PROBE`
    /// (value < 0: left to the probe plane, 0 off, > 0 tripped).
    pub kind: u32,
    /// The raw line (`DIGITAL`, `ANALOG`).
    pub line: u32,
    /// The setting.
    pub value: f64,
}

impl SimPanel {
    /// Open (value ≠ 0) or close the E-stop chain.
    pub const ESTOP: u32 = 1;
    /// Set a raw digital input line.
    pub const DIGITAL: u32 = 2;
    /// Set a raw analog input line.
    pub const ANALOG: u32 = 3;
    /// Drive the probe.
    pub const PROBE: u32 = 4;
}

/// Operator client → MMI (request-response): one `softnc-api` request, serialised
/// (JSON in its envelope, `softnc_api::encode_request`).
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::OperatorRequestJson")]
pub struct OperatorRequest {
    /// The serialised request; one that does not fit is not sent.
    pub message: FixedStr<{ OperatorRequest::MESSAGE_CAPACITY }>,
}

impl OperatorRequest {
    /// Bytes a request holds.
    pub const MESSAGE_CAPACITY: usize = 4096;
}

/// MMI → operator client: one `softnc-api` reply, serialised (JSON in its envelope,
/// `softnc_api::encode_reply`); a reply that does not fit is replaced by one saying
/// so, never cut.
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[repr(C)]
#[type_name("softnc::OperatorReplyJson")]
pub struct OperatorReply {
    /// The serialised reply.
    pub message: FixedStr<{ OperatorReply::MESSAGE_CAPACITY }>,
}

impl OperatorReply {
    /// Bytes a reply holds.
    pub const MESSAGE_CAPACITY: usize = 8192;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enums_round_trip_through_the_wire() {
        for k in [
            ControlKind::StartJob,
            ControlKind::Reset,
            ControlKind::Shutdown,
            ControlKind::OverrideLimits,
        ] {
            assert_eq!(ControlKind::from_wire(k.wire()), Some(k));
        }
        assert_eq!(MachineState::from_wire(77), None);
    }

    #[test]
    fn machine_io_round_trips_through_the_wire() {
        let mut analog = [0.0; ANALOG_LINES];
        analog[3] = 2.5;
        let outputs = [
            MachineOutputs::default(),
            MachineOutputs {
                spindle_dir: SpindleDir::CounterClockwise,
                spindle_rpm: 8000.0,
                spindle_orient_deg: Some(90.0),
                spindle_orient_dir: 2,
                coolant_mist: false,
                coolant_flood: true,
                tool_change: true,
                digital: 1 << 63 | 2,
                analog,
            },
        ];
        for o in outputs {
            assert_eq!(MachineOutputs::from(OutputsWire::from(o)), o);
        }
        let inputs = MachineInputs {
            spindle_rpm: -120.5,
            spindle_revs: 3.25,
            spindle_index_count: 3,
            spindle_at_speed: true,
            spindle_oriented: true,
            estop_open: true,
            probe: false,
            tool_changed: true,
            limit_min: 0b001,
            limit_max: 0b100,
            home: 0b010,
            digital: 5,
            analog,
        };
        assert_eq!(MachineInputs::from(InputsWire::from(inputs)), inputs);
        assert_eq!(
            MachineInputs::from(InputsWire::default()),
            MachineInputs::default()
        );
    }

    #[test]
    fn payloads_are_fixed_size() {
        // sizes are part of the wire format between processes built together
        assert_eq!(
            std::mem::size_of::<CommandSample>(),
            // seq, job, time index; positions; motion + flags; sent time; path;
            // outputs: speed, orient, flags + direction, digital, analog
            8 * 3 + 8 * MAX_AXES + 8 + 8 + 8 + (8 + 8 + 8 + 8 + 8 * ANALOG_LINES)
        );
        assert!(std::mem::size_of::<PositionStatus>() < 640);
        assert!(std::mem::size_of::<ControlCommand>() < 1024);
    }
}

macro_rules! wire_enum {
    ($t:ident { $($v:ident),* $(,)? }) => {
        impl $t {
            /// The value as carried in a payload.
            pub const fn wire(self) -> u32 {
                self as u32
            }
            /// From a payload value (`None` if unknown).
            pub fn from_wire(v: u32) -> Option<Self> {
                $(if v == $t::$v as u32 { return Some($t::$v); })*
                None
            }
        }
    };
}
wire_enum!(MachineState {
    Idle,
    Running,
    Held,
    Faulted,
    EStopped,
    Stopping,
    Off,
    Homing,
    Jogging,
    Paused,
    Mdi
});
wire_enum!(ProcessId {
    Supervisor,
    Interp,
    Position,
    Mmi
});
wire_enum!(ControlKind {
    StartJob,
    FeedOverride,
    Hold,
    Resume,
    Abort,
    EStop,
    Reset,
    Shutdown,
    SpindleOverride,
    RapidOverride,
    MachineOn,
    MachineOff,
    Home,
    Jog,
    JogStep,
    SingleBlock,
    Step,
    OptionalStop,
    BlockDelete,
    OverrideLimits
});
wire_enum!(AlarmCode {
    SequenceError,
    RingDry,
    ProcessLost,
    FollowingError,
    EStop,
    JobRefused,
    Note,
    PlanStarved,
    PlanFailed,
    MachineWait,
    MachineOn,
    LoopStall,
    LoopLate,
    ProcessRestarted,
    Other
});
