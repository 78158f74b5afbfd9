//! The machine as the operator sees it: [`Status`].

use crate::job::JobRecord;
use crate::nan::{f64_or_nan, f64s_or_nan, opt_xyz_or_nan, xyz_or_nan};
use serde::{Deserialize, Serialize};

/// The machine state the operator sees (docs/operations.md). On the wire its name
/// (`"Idle"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MachineState {
    /// Ready for a job.
    Idle,
    /// Running a job.
    Running,
    /// Feed hold: standing on the path, resumable.
    Held,
    /// Controlled stop after a fault; needs a reset.
    Faulted,
    /// Emergency stop; needs a reset.
    EStopped,
    /// A job being stopped along its path (abort, shutdown); idle when at rest.
    Stopping,
    /// Machine off: drives disabled, nothing moves.
    Off,
    /// Axes homing.
    Homing,
    /// An axis jogging.
    Jogging,
    /// A job stopped at an M0/M1 or a single-block end: resume (or step) goes on.
    Paused,
    /// Running an MDI block.
    Mdi,
    /// A state this reader does not know (written by a newer MMI).
    #[serde(other)]
    Unknown,
}

impl MachineState {
    /// Its name as on the wire (`"Idle"`).
    pub fn name(self) -> &'static str {
        match self {
            MachineState::Idle => "Idle",
            MachineState::Running => "Running",
            MachineState::Held => "Held",
            MachineState::Faulted => "Faulted",
            MachineState::EStopped => "EStopped",
            MachineState::Stopping => "Stopping",
            MachineState::Off => "Off",
            MachineState::Homing => "Homing",
            MachineState::Jogging => "Jogging",
            MachineState::Paused => "Paused",
            MachineState::Mdi => "Mdi",
            MachineState::Unknown => "Unknown",
        }
    }
}

impl std::fmt::Display for MachineState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What an alarm is about. On the wire its name (`"FollowingError"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AlarmKind {
    /// A command sample was missing or out of order.
    SequenceError,
    /// The lookahead ring ran dry during motion.
    RingDry,
    /// A process died or went silent.
    ProcessLost,
    /// Following error over the limit.
    FollowingError,
    /// Emergency stop.
    EStop,
    /// A job was refused.
    JobRefused,
    /// A remark for a job's record (not shown as an alarm).
    Note,
    /// The plan's producer fell behind the interpolation.
    PlanStarved,
    /// The program could not be planned again while it ran.
    PlanFailed,
    /// A machine operation of a job could not be completed (the spindle not at
    /// speed in time): the job stopped along its path (a reader of an older
    /// contract reads it as `Other`).
    MachineWait,
    /// Switching the machine on failed (the drives did not come on) or was
    /// refused (a limit switch tripped): it stays off (a reader of an older
    /// contract reads it as `Other`).
    MachineOn,
    /// A real-time loop stalled.
    LoopStall,
    /// A real-time loop ran late.
    LoopLate,
    /// The supervisor started a process again after it died (a reader of an
    /// older contract reads it as `Other`).
    ProcessRestarted,
    /// Anything else (also a kind this reader does not know).
    #[serde(other)]
    Other,
}

/// One alarm of the machine's list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Alarm {
    /// What it is about.
    pub code: AlarmKind,
    /// The job it concerns (0: none).
    #[serde(default)]
    pub job_id: u64,
    /// Plain-language text.
    #[serde(default)]
    pub message: String,
}

/// A process's health as the MMI sees it. On the wire lower case (`"alive"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ProcessHealth {
    /// A heartbeat within the timeout.
    Alive,
    /// Silent, or reported lost and not yet back.
    Lost,
    /// Never heard.
    #[serde(other)]
    Unseen,
}

impl ProcessHealth {
    /// Its name as on the wire (`"alive"`).
    pub fn name(self) -> &'static str {
        match self {
            ProcessHealth::Alive => "alive",
            ProcessHealth::Lost => "lost",
            ProcessHealth::Unseen => "unseen",
        }
    }
}

impl std::fmt::Display for ProcessHealth {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The other processes' health.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Processes {
    /// The interpolation process.
    pub interp: ProcessHealth,
    /// The position-control process.
    pub position: ProcessHealth,
    /// The supervisor `softncd`.
    pub supervisor: ProcessHealth,
}

/// Percentiles of a loop figure (ns).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct Percentiles {
    /// Median.
    pub p50: u64,
    /// 99th percentile.
    pub p99: u64,
    /// 99.9th percentile.
    pub p999: u64,
    /// Largest.
    pub max: u64,
}

/// Timing of one real-time loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct LoopTiming {
    /// Cycles counted.
    pub cycles: u64,
    /// Deadlines missed.
    pub overruns: u64,
    /// Period jitter |actual − nominal| (ns).
    pub jitter_ns: Percentiles,
    /// Compute time per cycle (ns).
    pub compute_ns: Percentiles,
    /// Interp → position sample latency (ns; position loop only, 0 elsewhere).
    pub latency_ns: Percentiles,
}

/// The fieldbus of the position loop (EtherCAT), as its MainDevice counts it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default)]
pub struct BusFigures {
    /// Cycle frames exchanged since the bus came up.
    pub frames: u64,
    /// Frames lost (no answer within the response timeout).
    pub lost_frames: u64,
    /// Cycles with a wrong working counter.
    pub wkc_errors: u64,
    /// The cycle frame's send-to-receive time (ns; p50 and p99 from a 10 µs
    /// histogram, max exact; `p999` not measured, 0).
    pub send_to_receive_ns: Percentiles,
    /// Reads of the DC SubDevices' system time difference (ESC register 0x092C,
    /// one SubDevice a read, every few hundred cycles) that answered.
    pub dc_deviation_reads: u64,
    /// |system time difference| of the last read (ns).
    pub dc_deviation_last_ns: u64,
    /// Largest |system time difference| read since the bus came up (ns).
    pub dc_deviation_max_ns: u64,
}

/// The real-time loops' timing (`None`: not reported yet).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Loops {
    /// The interpolation loop.
    pub interp: Option<LoopTiming>,
    /// The position loop.
    pub position: Option<LoopTiming>,
    /// The position loop's fieldbus, on a backend with one (`None`: none, or not
    /// reported yet; absent in statuses written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bus: Option<BusFigures>,
}

/// The offsets in effect.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ActiveOffsets {
    /// The active coordinate system's origin in machine coordinates (mm).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub g5x_mm: [f64; 3],
    /// Its XY rotation (degrees).
    #[serde(deserialize_with = "f64_or_nan")]
    pub rotation_deg: f64,
    /// G92 offset (zero when not applied).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub g92_mm: [f64; 3],
    /// Tool offset in effect (G43).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub tool_offset_mm: [f64; 3],
}

/// Coolant as the machine has it on (M7 mist, M8 flood): in a job as the sample
/// in use switches it, between jobs as the last job or MDI command left it (held
/// until an M9, a program end, an abort, machine off or an E-stop).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Coolant {
    /// Mist (M7).
    pub mist: bool,
    /// Flood (M8).
    pub flood: bool,
}

/// The spindle as the machine runs it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Spindle {
    /// The speed commanded (rpm, signed: negative M4; 0 stopped), before the
    /// spindle override: in a job the sample in use's, between jobs what the
    /// last job or MDI command left turning (held until an M5, a program end, an
    /// abort, machine off or an E-stop).
    #[serde(default)]
    pub commanded_rpm: f64,
    /// The speed its encoder measures (rpm, signed; the command where the machine
    /// has no spindle feedback).
    #[serde(default)]
    pub actual_rpm: f64,
    /// Within the profile's at-speed band of the command × override.
    #[serde(default)]
    pub at_speed: bool,
}

/// The operator's program-flow switches.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Switches {
    /// Stop at the end of every block until `step`.
    pub single_block: bool,
    /// M1 stops.
    pub optional_stop: bool,
    /// Lines starting with `/` are skipped.
    pub block_delete: bool,
}

/// Files of the data directory that could not be written (tried again), and why.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Unsaved {
    /// The job history `jobs.json`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub job_history: Option<String>,
    /// The parameter file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameters: Option<String>,
    /// The modal state file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modal_state: Option<String>,
}

/// Adaptive feed of the running job.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveForce {
    /// The override the force loop gives (fraction).
    #[serde(rename = "override", deserialize_with = "f64_or_nan")]
    pub override_fraction: f64,
    /// Spindle revolutions the force loop has closed in this job.
    pub revolutions: u64,
    /// The last revolution's estimated peak cutting force (N).
    pub force_n: Option<f64>,
}

/// The axes as the position process reports them (X, Y, Z).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AxesStatus {
    /// Command position after command shaping (mm).
    #[serde(deserialize_with = "f64s_or_nan")]
    pub cmd_mm: Vec<f64>,
    /// Actual position (mm).
    #[serde(deserialize_with = "f64s_or_nan")]
    pub actual_mm: Vec<f64>,
    /// Following error (µm).
    #[serde(deserialize_with = "f64s_or_nan")]
    pub following_err_um: Vec<f64>,
    /// Contour error (µm; `None` outside feed moves).
    pub contour_err_um: Option<f64>,
    /// Samples waiting in the lookahead ring.
    pub ring_fill: u32,
}

/// The job shown: the running one, else the last; its record and progress.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobStatus {
    /// Its record.
    #[serde(flatten)]
    pub record: JobRecord,
    /// How much of it is done (0..=1).
    #[serde(default)]
    pub progress: f64,
}

/// The machine's status.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// The contract's version the writer speaks ([`crate::API_VERSION`]).
    #[serde(default)]
    pub api_version: u32,
    /// The machine state.
    pub state: MachineState,
    /// A command the position process has not yet taken (machine on or off,
    /// homing, a jog): the state it asks for, shown in `state` meanwhile; `None`
    /// once taken. Switching on over a bus can take a second, and can fail (an
    /// alarm "machine on: …", the state back to off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pending: Option<MachineState>,
    /// Which axes are homed (X, Y, Z).
    #[serde(default)]
    pub homed: Vec<bool>,
    /// A program being read and checked.
    #[serde(default)]
    pub checking: Option<String>,
    /// The command position in machine coordinates (mm; `None` before the position
    /// process reports).
    #[serde(default, deserialize_with = "opt_xyz_or_nan")]
    pub machine_mm: Option<[f64; 3]>,
    /// The same in work coordinates (mm).
    #[serde(default, deserialize_with = "opt_xyz_or_nan")]
    pub work_mm: Option<[f64; 3]>,
    /// What the motion in progress has still to go per axis (X, Y, Z; mm): to the
    /// programmed end of the running job's (or MDI command's) current motion, or to
    /// an incremental jog's target; zero when nothing moves to a known end (idle, a
    /// continuous jog, homing).
    #[serde(default)]
    pub distance_to_go_mm: [f64; 3],
    /// The active coordinate system (`"G54"`).
    pub coords: String,
    /// The offsets in effect.
    pub offsets: ActiveOffsets,
    /// The tool in the spindle (0: none).
    pub tool: u32,
    /// The modal state the machine is in between programs (the last MDI command's or
    /// job's end), as G-code words.
    #[serde(default)]
    pub modal: Option<Vec<String>>,
    /// Coolant.
    #[serde(default)]
    pub coolant: Coolant,
    /// Messages: why the parameter file cannot be used (jobs are refused).
    #[serde(default)]
    pub params_error: Option<String>,
    /// Messages: why the modal state file cannot be used (jobs are refused).
    #[serde(default)]
    pub modal_error: Option<String>,
    /// Messages: files of the data directory not written (tried again).
    #[serde(default)]
    pub unsaved: Unsaved,
    /// Checks abandoned after `check_timeout_s` whose threads still run.
    #[serde(default)]
    pub abandoned_checks: u64,
    /// The program-flow switches.
    #[serde(default)]
    pub switches: Switches,
    /// The program line the running job is at (1-based).
    #[serde(default)]
    pub program_line: Option<u32>,
    /// The feed override in force (fraction).
    #[serde(deserialize_with = "f64_or_nan")]
    pub feed_override: f64,
    /// The rapid override in force (fraction; 1.0 in statuses written before it).
    #[serde(default = "one")]
    pub rapid_override: f64,
    /// The spindle override in force (fraction; `None` before the position process
    /// reports).
    #[serde(default)]
    pub spindle_override: Option<f64>,
    /// Spindle speed (rpm; 0 without a spindle model or between jobs).
    #[serde(default)]
    pub spindle_rpm: Option<f64>,
    /// The spindle as the machine runs it: commanded and actual speed, at speed
    /// (`None` before the position process reports).
    #[serde(default)]
    pub spindle: Option<Spindle>,
    /// The tool prepared (the running job's last T; `None` between jobs).
    #[serde(default)]
    pub tool_prepared: Option<u32>,
    /// The operator message (`(MSG,…)`) the running job last reached.
    #[serde(default)]
    pub message: Option<String>,
    /// What the running job waits for at a machine stop ("insert T2, then
    /// resume", "waiting for the spindle at 8000 rpm", "waiting for input P0
    /// (High)"), while the machine stands there.
    #[serde(default)]
    pub prompt: Option<String>,
    /// The limit switches tripped now ("X max", "Z min"), as the position
    /// process reads them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub limits_tripped: Vec<String>,
    /// The operator overrides the limit switches (`override_limits`, LinuxCNC's
    /// override limits): until every one is released.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub limits_overridden: bool,
    /// Adaptive feed of the running job.
    #[serde(default)]
    pub adaptive_force: Option<AdaptiveForce>,
    /// The running job, else the last one.
    #[serde(default)]
    pub job: Option<JobStatus>,
    /// The axes (`None` before the position process reports).
    #[serde(default)]
    pub axes: Option<AxesStatus>,
    /// The processes' health.
    pub processes: Processes,
    /// The real-time loops' timing.
    #[serde(default)]
    pub loops: Loops,
    /// The machine's alarms, newest first (at most ten).
    #[serde(default)]
    pub alarms: Vec<Alarm>,
}

impl Status {
    /// The job shown, if it is job `job_id`.
    pub fn job(&self, job_id: u64) -> Option<&JobStatus> {
        self.job.as_ref().filter(|j| j.record.job_id == job_id)
    }

    /// Every axis is homed.
    pub fn all_homed(&self) -> bool {
        !self.homed.is_empty() && self.homed.iter().all(|h| *h)
    }
}

impl std::fmt::Display for Status {
    /// The status as its JSON (as `softnc status --json` prints it).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match serde_json::to_string(self) {
            Ok(text) => f.write_str(&text),
            Err(_) => write!(f, "{self:?}"),
        }
    }
}

/// 1.0 (a serde default).
fn one() -> f64 {
    1.0
}
