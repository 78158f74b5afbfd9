//! The machine around the axes during a job, shared by the daemon's interpolation
//! loop and the offline simulator: what each command sample tells the spindle, the
//! coolant and the outputs ([`MachineOutputs`]), and when the path may leave a
//! machine stop ([`crate::StreamInterpolator::machine_stop`]), decided from what
//! the machine reports ([`MachineInputs`]).
//!
//! Built before motion from the program's machine operations
//! ([`softnc_gcode::MachineOp`]): a table of the state in force from each
//! operation on, by motion index. Per sample, [`MachineSequencer::step`] takes the
//! sample's motion index, the machine stop the path waits at (if any) and the
//! latest [`Feedback`]; it allocates nothing and costs O(1) (cursors into the
//! tables, which the samples' motion indices walk forward).
//!
//! The loop that owns an interpolator does, each cycle:
//!
//! ```ignore
//! let sample = it.next().unwrap();
//! let step = seq.step(sample.motion, it.machine_stop(), &feedback);
//! command.outputs = step.state.outputs;
//! match step.action {
//!     Action::Release => it.release_machine_stop(),
//!     Action::Fail(e) => { /* an alarm: abort the job */ }
//!     Action::Wait(_) | Action::Run => {}
//! }
//! ```
//!
//! with the interpolator made with
//! [`PlanOptions::wait_at_machine_stops`](crate::PlanOptions::wait_at_machine_stops).
//!
//! When each operation takes effect (LinuxCNC's task, `emctaskmain.cc`
//! `emcTaskCheckPreconditions`): those that wait for motion
//! ([`MachineOp::stops_motion`]) at their own machine stop, whose samples carry
//! their motion index; the synchronised outputs (M62, M63, M67) at the first sample
//! of the next move (traverse, feed or arc), as LinuxCNC's motion-synchronised
//! outputs; tool prepare (T) and the override switches (M48–M53), which do not
//! stop the path, from the samples after them.
//!
//! A stop is released only on inputs the machine read while it applied a sample of
//! that stop (`Feedback::applied_motion`): inputs read before the command reached
//! the machine say nothing about it.

use softnc_core::machine_io::{MachineInputs, MachineOutputs, SpindleDir};
use softnc_gcode::{
    CoolantLine, MachineOp, MessageKind, MotionKind, OverrideSwitch, Program, SpindleTurn,
    WaitInput, WaitMode,
};

/// What the sequencer needs besides the program (from the machine profile).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SequencerConfig {
    /// The interpolation cycle T (s): the time of one [`MachineSequencer::step`].
    pub cycle_s: f64,
    /// Longest wait for the spindle to reach its speed after M3/M4/S (s); past it
    /// the job fails ([`SequencerError::SpindleNotAtSpeed`]), as LinuxCNC's
    /// `spindle.at-speed` gate does not (it waits forever) but a machine should.
    pub spindle_at_speed_timeout_s: f64,
    /// Longest a user M code (M100–M199) may run (s).
    pub user_m_timeout_s: f64,
}

/// Everything the sequencer keeps in force from one motion index on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SequencerState {
    /// What the command samples carry.
    pub outputs: MachineOutputs,
    /// The tool in the spindle (after the last M6 was done).
    pub tool_in_spindle: u32,
    /// The tool prepared (the last T).
    pub tool_prepared: u32,
    /// The operator message last reached (`Program::messages` index): `(MSG,…)`
    /// and `(DEBUG,…)` (LinuxCNC shows both as `MESSAGE`).
    pub message: Option<u32>,
    /// The `(PRINT,…)` last reached (`Program::messages` index): for the log and
    /// the job's record, not the operator's display (LinuxCNC prints it).
    pub printed: Option<u32>,
    /// M48–M51: feed override enabled.
    pub feed_override_enabled: bool,
    /// M48–M51: spindle override enabled.
    pub spindle_override_enabled: bool,
    /// M52: adaptive feed enabled.
    pub adaptive_feed_enabled: bool,
    /// M53: feed hold enabled.
    pub feed_hold_enabled: bool,
}

impl Default for SequencerState {
    /// Outputs off, no tool, no message, override switches on (LinuxCNC starts with
    /// M48 in force).
    fn default() -> Self {
        SequencerState {
            outputs: MachineOutputs::default(),
            tool_in_spindle: 0,
            tool_prepared: 0,
            message: None,
            printed: None,
            feed_override_enabled: true,
            spindle_override_enabled: true,
            adaptive_feed_enabled: false,
            feed_hold_enabled: true,
        }
    }
}

impl SequencerState {
    /// The state after operation `op`.
    fn apply(&mut self, op: &MachineOp) {
        let o = &mut self.outputs;
        match *op {
            MachineOp::SpindleOn { dir, rpm } => {
                o.spindle_dir = match dir {
                    SpindleTurn::Clockwise => SpindleDir::Clockwise,
                    SpindleTurn::CounterClockwise => SpindleDir::CounterClockwise,
                };
                o.spindle_rpm = rpm;
                o.spindle_orient_deg = None;
            }
            MachineOp::SpindleOff => {
                o.spindle_dir = SpindleDir::Stopped;
                o.spindle_orient_deg = None;
            }
            MachineOp::SpindleOrient {
                angle_deg,
                direction,
                ..
            } => {
                o.spindle_dir = SpindleDir::Stopped;
                o.spindle_orient_deg = Some(angle_deg);
                o.spindle_orient_dir = direction;
            }
            MachineOp::Coolant { which, on } => match which {
                CoolantLine::Mist => o.coolant_mist = on,
                CoolantLine::Flood => o.coolant_flood = on,
            },
            MachineOp::ToolPrepare { tool } => self.tool_prepared = tool,
            MachineOp::ToolChange { .. } => o.tool_change = true,
            MachineOp::Message {
                index,
                kind: MessageKind::Print,
            } => self.printed = Some(index),
            MachineOp::Message { index, .. } => self.message = Some(index),
            MachineOp::DigitalOut { line, on, .. } => {
                let bit = 1u64 << line;
                if on {
                    o.digital |= bit;
                } else {
                    o.digital &= !bit;
                }
            }
            MachineOp::AnalogOut { line, value, .. } => {
                if let Some(a) = o.analog.get_mut(usize::from(line)) {
                    *a = value;
                }
            }
            MachineOp::Overrides { switch, on } => match switch {
                OverrideSwitch::FeedAndSpindle => {
                    self.feed_override_enabled = on;
                    self.spindle_override_enabled = on;
                }
                OverrideSwitch::Feed => self.feed_override_enabled = on,
                OverrideSwitch::Spindle => self.spindle_override_enabled = on,
                OverrideSwitch::AdaptiveFeed => self.adaptive_feed_enabled = on,
                OverrideSwitch::FeedHold => self.feed_hold_enabled = on,
            },
            MachineOp::WaitInput { .. } | MachineOp::UserM { .. } => {}
        }
    }
}

/// What the machine and the operator report, as the caller last heard it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Feedback {
    /// The machine's inputs.
    pub inputs: MachineInputs,
    /// The motion index of this job's command sample the machine was applying when
    /// it read `inputs` (the position status's `motion` once it reports a sample of
    /// this job; the sample's own offline); `None` before it applies any.
    pub applied_motion: Option<u32>,
    /// The operator's resume (cycle start) came since the last step.
    pub resume: bool,
    /// The user M code the path waits at has finished (its executable exited 0).
    pub user_command_done: bool,
    /// The user M code the path waits at has failed: its executable's exit status
    /// (−1: it could not be started, or a signal ended it).
    pub user_command_failed: Option<i32>,
}

/// The machine's reports as a loop running `lookahead` samples ahead of the sample
/// in use hears them: the [`Feedback`] for the sample numbered `n` is what the
/// machine reported on the first cycle it used sample `n − lookahead − 1`. (The
/// interpolation process sends samples up to `lookahead` beyond the last one the
/// position process reported using — `lookahead + 1` before it reports any — so
/// that report is the latest it is sure to have heard; the offline simulator takes
/// the same lag, so both release a stop at the same sample.) Fixed capacity:
/// recording allocates nothing.
#[derive(Debug, Clone)]
pub struct FeedbackHistory {
    /// `lookahead + 1`.
    lag: u64,
    /// (sample number, its motion, the inputs read), oldest first, `lag + 1` long.
    entries: std::collections::VecDeque<(u64, u32, MachineInputs)>,
}

impl FeedbackHistory {
    /// A history for a loop `lookahead` samples ahead.
    pub fn new(lookahead: u64) -> Self {
        let lag = lookahead + 1;
        FeedbackHistory {
            lag,
            entries: std::collections::VecDeque::with_capacity(lag as usize + 2),
        }
    }

    /// The machine used sample `seq` (of motion `motion`) and read `inputs`; later
    /// cycles of the same sample are not kept (the first is the one a loop `lag`
    /// ahead is sure to have heard).
    pub fn record(&mut self, seq: u64, motion: u32, inputs: MachineInputs) {
        if self.entries.back().is_some_and(|e| e.0 >= seq) {
            return;
        }
        if self.entries.len() > self.lag as usize {
            self.entries.pop_front();
        }
        self.entries.push_back((seq, motion, inputs));
    }

    /// The feedback for sample `n` (`applied_motion` `None` before the machine used
    /// sample `n − lookahead − 1`); `resume` and `user_command_done` false.
    pub fn feedback_for(&self, n: u64) -> Feedback {
        let heard = n
            .checked_sub(self.lag)
            .and_then(|target| self.entries.iter().rev().find(|e| e.0 <= target));
        match heard {
            Some(&(_, motion, inputs)) => Feedback {
                inputs,
                applied_motion: Some(motion),
                ..Feedback::default()
            },
            None => Feedback::default(),
        }
    }
}

/// What the path waits for at a machine stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Waiting {
    /// The command has not reached the machine yet.
    Applied,
    /// The spindle to reach its speed (M3, M4, S).
    SpindleAtSpeed {
        /// The speed commanded (rpm).
        rpm: f64,
    },
    /// The tool changer's `tool-changed` or the operator's resume: "insert T{tool},
    /// then resume".
    ToolChange {
        /// The tool to insert.
        tool: u32,
    },
    /// M66: the input.
    Input {
        /// Which.
        input: WaitInput,
        /// How.
        mode: WaitMode,
    },
    /// M19 with Q: the spindle to report itself oriented (LinuxCNC's
    /// `spindle.N.is-oriented`, `WAIT_ORIENT_SPINDLE_COMPLETE`).
    SpindleOriented {
        /// The angle (degrees).
        angle_deg: f64,
    },
    /// A user M code's executable to finish.
    UserCommand {
        /// 100..=199.
        code: u8,
        /// Its P.
        p: f64,
        /// Its Q.
        q: f64,
    },
}

impl std::fmt::Display for Waiting {
    /// The operator's prompt: what the machine waits for.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Waiting::Applied => write!(f, "waiting for the machine"),
            Waiting::SpindleAtSpeed { rpm } => write!(f, "waiting for the spindle at {rpm} rpm"),
            Waiting::ToolChange { tool } => write!(f, "insert T{tool}, then resume"),
            Waiting::Input { input, mode } => {
                let (letter, n) = match input {
                    WaitInput::Digital(p) => ('P', u32::from(*p)),
                    WaitInput::Analog(e) => ('E', u32::from(*e)),
                };
                write!(f, "waiting for input {letter}{n} ({mode:?})")
            }
            Waiting::SpindleOriented { angle_deg } => {
                write!(f, "waiting for the spindle to orient to {angle_deg} deg")
            }
            Waiting::UserCommand { code, p, q } => write!(f, "running M{code} {p:.6} {q:.6}"),
        }
    }
}

/// Why a job cannot go on at a machine stop (the caller raises an alarm and aborts).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SequencerError {
    /// The spindle did not reach its speed within the profile's timeout.
    #[error("line {line}: the spindle did not reach {rpm} rpm within {waited_s:.1} s")]
    SpindleNotAtSpeed {
        /// Source line of the M3/M4/S.
        line: u32,
        /// The speed commanded (rpm).
        rpm: f64,
        /// How long it waited (s).
        waited_s: f64,
    },
    /// M19 with Q: the spindle did not report itself oriented within Q seconds
    /// (LinuxCNC: "wait for orient complete: TIMED OUT", an error that stops the
    /// program).
    #[error("line {line}: the spindle did not orient to {angle_deg} deg within {waited_s:.1} s")]
    SpindleNotOriented {
        /// Source line of the M19.
        line: u32,
        /// The angle (degrees).
        angle_deg: f64,
        /// How long it waited (s).
        waited_s: f64,
    },
    /// A user M code's executable exited with a status other than 0 (LinuxCNC's
    /// task: "system command … exited abnormally", an error that stops the
    /// program).
    #[error("line {line}: M{code} exited with status {status}")]
    UserCommandFailed {
        /// Source line.
        line: u32,
        /// 100..=199.
        code: u8,
        /// Its exit status (−1: not started, or ended by a signal).
        status: i32,
    },
    /// A user M code did not finish within the profile's timeout.
    #[error("line {line}: M{code} did not finish within {waited_s:.1} s")]
    UserCommandTimeout {
        /// Source line.
        line: u32,
        /// 100..=199.
        code: u8,
        /// How long it waited (s).
        waited_s: f64,
    },
}

/// What the caller does after a [`MachineSequencer::step`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// Nothing: the path runs (or stands where the sequencer has no say).
    Run,
    /// Keep waiting at the machine stop.
    Wait(Waiting),
    /// Release the machine stop
    /// ([`crate::StreamInterpolator::release_machine_stop`]).
    Release,
    /// The job cannot go on.
    Fail(SequencerError),
}

/// One step's answer: the state for the sample and what to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The state in force for the sample (its `outputs` go on the command sample).
    pub state: SequencerState,
    /// What to do with the machine stop.
    pub action: Action,
    /// An M66 released on this step: its result (what #5399 holds from here on).
    pub input_result: Option<InputResult>,
}

/// What an M66 gave: LinuxCNC's #5399 after it (`GET_EXTERNAL_DIGITAL_INPUT`:
/// the input as 0/1, `GET_EXTERNAL_ANALOG_INPUT`: its value; −1 after a
/// timeout, `emcStatus->task.input_timeout == 1`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputResult {
    /// Source line of the M66.
    pub line: u32,
    /// The input waited for.
    pub input: WaitInput,
    /// #5399.
    pub value: f64,
    /// The wait timed out (`value` is −1).
    pub timed_out: bool,
}

impl std::fmt::Display for InputResult {
    /// For the operator: `M66 P0: 1 (#5399)`, `M66 P0: timed out: -1 (#5399)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (letter, n) = match self.input {
            WaitInput::Digital(p) => ('P', u32::from(p)),
            WaitInput::Analog(e) => ('E', u32::from(e)),
        };
        write!(f, "M66 {letter}{n} (line {}): ", self.line)?;
        if self.timed_out {
            write!(f, "timed out: ")?;
        }
        write!(f, "{} (#5399)", self.value)
    }
}

/// A machine stop as the table holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct StopEntry {
    motion: u32,
    line: u32,
    op: MachineOp,
}

/// The wait at the current machine stop.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WaitState {
    motion: u32,
    /// Steps since the stop was first seen.
    cycles: u64,
    /// Steps since the machine applied the stop.
    applied_cycles: u64,
    /// M66 rise/fall: the level seen before (None: nothing seen yet).
    last_level: Option<bool>,
}

/// Builds a [`MachineSequencer`]'s tables from the motions in order (for a
/// program streamed in chunks, motion by motion as the check reads them).
#[derive(Debug, Clone)]
pub struct SequencerBuilder {
    cfg: SequencerConfig,
    state: SequencerState,
    changes: Vec<(u32, SequencerState)>,
    stops: Vec<StopEntry>,
    /// Synchronised outputs waiting for the next move.
    pending_sync: Vec<MachineOp>,
    /// An M6 was the last change: the next motion ends it.
    tool_change_done: Option<u32>,
    /// Machine operations pushed.
    operations: u32,
}

impl SequencerBuilder {
    /// Tables from `initial` (the machine's state when the job starts).
    pub fn new(cfg: SequencerConfig, initial: SequencerState) -> Self {
        SequencerBuilder {
            cfg,
            state: initial,
            changes: vec![(0, initial)],
            stops: Vec::new(),
            pending_sync: Vec::new(),
            tool_change_done: None,
            operations: 0,
        }
    }

    fn record(&mut self, index: u32) {
        match self.changes.last_mut() {
            Some(last) if last.0 == index => last.1 = self.state,
            _ => self.changes.push((index, self.state)),
        }
    }

    /// Motion number `index` of the program.
    pub fn push(&mut self, index: u32, m: &softnc_gcode::Motion) {
        if let Some(tool) = self.tool_change_done.take() {
            // the M6 is done when the path leaves it
            self.state.outputs.tool_change = false;
            self.state.tool_in_spindle = tool;
            self.record(index);
        }
        match m.kind {
            MotionKind::Machine(op) => {
                self.operations += 1;
                let synchronised = matches!(
                    op,
                    MachineOp::DigitalOut {
                        synchronised: true,
                        ..
                    } | MachineOp::AnalogOut {
                        synchronised: true,
                        ..
                    }
                );
                if synchronised {
                    self.pending_sync.push(op);
                    return;
                }
                let before = self.state.outputs;
                self.state.apply(&op);
                if let MachineOp::ToolChange { tool } = op {
                    self.tool_change_done = Some(tool);
                }
                self.record(index);
                // a spindle stop or a coolant switch that changes nothing (the
                // program end's spindle stop with the spindle standing) has nothing
                // to wait for: the path does not stand there for the machine
                let no_change = matches!(op, MachineOp::SpindleOff | MachineOp::Coolant { .. })
                    && self.state.outputs == before;
                if op.stops_motion() && !no_change {
                    self.stops.push(StopEntry {
                        motion: index,
                        line: m.line,
                        op,
                    });
                }
            }
            MotionKind::Traverse { .. }
            | MotionKind::Feed { .. }
            | MotionKind::Arc { .. }
            | MotionKind::Probe { .. } => {
                if !self.pending_sync.is_empty() {
                    for op in std::mem::take(&mut self.pending_sync) {
                        self.state.apply(&op);
                    }
                    self.record(index);
                }
            }
            MotionKind::Dwell { .. } | MotionKind::Pause { .. } | MotionKind::Sync => {}
        }
    }

    /// The sequencer, with the program's message texts.
    pub fn finish(self, messages: Vec<String>) -> MachineSequencer {
        MachineSequencer {
            cfg: self.cfg,
            operations: self.operations,
            changes: self.changes,
            stops: self.stops,
            messages,
            change_cursor: 0,
            stop_cursor: 0,
            wait: None,
            input_result: None,
        }
    }
}

/// M66's input in `inputs`: its level (an analog one: not 0) and its value
/// (a digital one: 0/1).
fn input_level(input: WaitInput, inputs: &MachineInputs) -> (bool, f64) {
    match input {
        WaitInput::Digital(p) => {
            let on = inputs.digital >> p & 1 == 1;
            (on, f64::from(u8::from(on)))
        }
        WaitInput::Analog(e) => {
            let v = inputs.analog.get(usize::from(e)).copied().unwrap_or(0.0);
            (v != 0.0, v)
        }
    }
}

/// Whether M66's wait `mode` is met at `level`, the level seen before `before`.
fn input_met(mode: WaitMode, before: Option<bool>, level: bool) -> bool {
    match mode {
        WaitMode::Immediate => true,
        WaitMode::High => level,
        WaitMode::Low => !level,
        WaitMode::Rise => before == Some(false) && level,
        WaitMode::Fall => before == Some(true) && !level,
    }
}

/// A user M code's stop: released when its executable exited 0, failed on another
/// status or past the timeout (`timed_out`), else waiting (`waiting`).
fn user_command(
    fb: &Feedback,
    timed_out: bool,
    waiting: Waiting,
    line: u32,
    waited_s: f64,
) -> Action {
    let Waiting::UserCommand { code, .. } = waiting else {
        return Action::Wait(waiting);
    };
    if fb.user_command_done {
        Action::Release
    } else if let Some(status) = fb.user_command_failed {
        Action::Fail(SequencerError::UserCommandFailed { line, code, status })
    } else if timed_out {
        Action::Fail(SequencerError::UserCommandTimeout {
            line,
            code,
            waited_s,
        })
    } else {
        Action::Wait(waiting)
    }
}

/// The machine around the axes during one job (see the module).
#[derive(Debug, Clone)]
pub struct MachineSequencer {
    cfg: SequencerConfig,
    /// The program's machine operations.
    operations: u32,
    /// (first motion, state in force from it on), by motion.
    changes: Vec<(u32, SequencerState)>,
    /// The machine stops, by motion.
    stops: Vec<StopEntry>,
    messages: Vec<String>,
    change_cursor: usize,
    stop_cursor: usize,
    wait: Option<WaitState>,
    input_result: Option<InputResult>,
}

impl MachineSequencer {
    /// The sequencer of a whole program read at once.
    pub fn new(program: &Program, cfg: SequencerConfig, initial: SequencerState) -> Self {
        let mut b = SequencerBuilder::new(cfg, initial);
        for (i, m) in program.motions.iter().enumerate() {
            b.push(i as u32, m);
        }
        b.finish(program.messages.clone())
    }

    /// Whether the program has machine operations (spindle, coolant, tools,
    /// messages, I/O, …; the program end's spindle stop among them): a program
    /// without moves still runs on the machine for them.
    pub fn has_operations(&self) -> bool {
        self.operations > 0
    }

    /// The state in force for a sample of motion `motion` (O(1) as the motions go
    /// forward; a binary search if one goes back).
    pub fn state_at(&mut self, motion: u32) -> SequencerState {
        let c = &self.changes;
        let mut k = self.change_cursor.min(c.len() - 1);
        if c[k].0 > motion {
            k = c.partition_point(|e| e.0 <= motion).saturating_sub(1);
        }
        while k + 1 < c.len() && c[k + 1].0 <= motion {
            k += 1;
        }
        self.change_cursor = k;
        c[k].1
    }

    /// The machine stop at motion `motion`, if there is one.
    fn stop_at(&mut self, motion: u32) -> Option<StopEntry> {
        let s = &self.stops;
        let mut k = self.stop_cursor.min(s.len().saturating_sub(1));
        if s.get(k).is_some_and(|e| e.motion > motion) {
            k = s.partition_point(|e| e.motion < motion);
        }
        while k < s.len() && s[k].motion < motion {
            k += 1;
        }
        self.stop_cursor = k;
        s.get(k).filter(|e| e.motion == motion).copied()
    }

    /// The state in force for a sample of motion `motion`, looked up without
    /// moving the cursors (O(log n): for a reader of the status, not the cycle).
    pub fn state_of(&self, motion: u32) -> SequencerState {
        let c = &self.changes;
        c[c.partition_point(|e| e.0 <= motion).saturating_sub(1)].1
    }

    /// What the path waits for while it stands at the machine stop of motion
    /// `motion` once the machine has it (`None`: no stop there, or one that is done
    /// once the machine has it): the operator's prompt.
    pub fn waiting_at(&self, motion: u32) -> Option<Waiting> {
        let s = &self.stops;
        let stop = s.get(s.partition_point(|e| e.motion < motion))?;
        if stop.motion != motion {
            return None;
        }
        match stop.op {
            MachineOp::SpindleOn { rpm, .. } => Some(Waiting::SpindleAtSpeed { rpm }),
            MachineOp::ToolChange { tool } => Some(Waiting::ToolChange { tool }),
            MachineOp::WaitInput { input, mode, .. } => Some(Waiting::Input { input, mode }),
            MachineOp::UserM { code, p, q } => Some(Waiting::UserCommand { code, p, q }),
            MachineOp::SpindleOrient {
                angle_deg,
                timeout_s,
                ..
            } if timeout_s > 0.0 => Some(Waiting::SpindleOriented { angle_deg }),
            _ => None,
        }
    }

    /// The text of message `index` (`SequencerState::message`).
    pub fn message_text(&self, index: u32) -> Option<&str> {
        self.messages.get(index as usize).map(String::as_str)
    }

    /// The result of the last M66 released (what LinuxCNC puts in #5399: the
    /// input's value, or −1 where the wait timed out).
    pub fn input_result(&self) -> Option<f64> {
        self.input_result.map(|r| r.value)
    }

    /// Writes message `index` as the operator sees it now: its text with #5399
    /// read after an M66 filled in with the last M66's result
    /// ([`softnc_gcode::write_message`]) — LinuxCNC reads no further than an M66
    /// until the wait is done, so a `(DEBUG,…)`/`(PRINT,…)` after it shows the
    /// machine's value; the path reaches the message only after the M66 was
    /// released. Trimmed; allocates nothing.
    pub fn write_message(&self, index: u32, out: &mut impl std::fmt::Write) -> std::fmt::Result {
        let text = self.message_text(index).unwrap_or("").trim();
        softnc_gcode::write_message(out, text, self.input_result())
    }

    /// One cycle: the state for the sample of motion `sample_motion` and, where the
    /// path waits at the machine stop `machine_stop`
    /// ([`crate::StreamInterpolator::machine_stop`]), whether it may go on.
    pub fn step(&mut self, sample_motion: u32, machine_stop: Option<u32>, fb: &Feedback) -> Step {
        let state = self.state_at(sample_motion);
        let before = self.input_result;
        let action = match machine_stop {
            None => {
                self.wait = None;
                Action::Run
            }
            Some(m) => self.at_stop(m, fb),
        };
        let input_result = match action {
            Action::Release if self.input_result != before => self.input_result,
            _ => None,
        };
        Step {
            state,
            action,
            input_result,
        }
    }

    fn at_stop(&mut self, motion: u32, fb: &Feedback) -> Action {
        let Some(stop) = self.stop_at(motion) else {
            // not an operation of this table: nothing to wait for
            return Action::Release;
        };
        let w = match &mut self.wait {
            Some(w) if w.motion == motion => w,
            w => w.insert(WaitState {
                motion,
                cycles: 0,
                applied_cycles: 0,
                last_level: None,
            }),
        };
        w.cycles += 1;
        if fb.applied_motion.is_none_or(|m| m < motion) {
            return Action::Wait(Waiting::Applied);
        }
        w.applied_cycles += 1;
        let waited_s = w.cycles as f64 * self.cfg.cycle_s;
        let timed_out = |limit_s: f64| limit_s > 0.0 && waited_s >= limit_s;
        let inputs = &fb.inputs;
        match stop.op {
            MachineOp::SpindleOn { rpm, .. } => {
                if inputs.spindle_at_speed {
                    Action::Release
                } else if timed_out(self.cfg.spindle_at_speed_timeout_s) {
                    Action::Fail(SequencerError::SpindleNotAtSpeed {
                        line: stop.line,
                        rpm,
                        waited_s,
                    })
                } else {
                    Action::Wait(Waiting::SpindleAtSpeed { rpm })
                }
            }
            MachineOp::ToolChange { tool } => {
                if inputs.tool_changed || fb.resume {
                    Action::Release
                } else {
                    Action::Wait(Waiting::ToolChange { tool })
                }
            }
            MachineOp::WaitInput {
                input,
                mode,
                timeout_s,
            } => {
                let (level, value) = input_level(input, inputs);
                let met = input_met(mode, w.last_level.replace(level), level);
                let result = |value: f64, timed_out: bool| InputResult {
                    line: stop.line,
                    input,
                    value,
                    timed_out,
                };
                if met {
                    self.input_result = Some(result(value, false));
                    Action::Release
                } else if timed_out(timeout_s) {
                    self.input_result = Some(result(-1.0, true));
                    Action::Release
                } else {
                    Action::Wait(Waiting::Input { input, mode })
                }
            }
            MachineOp::UserM { code, p, q } => user_command(
                fb,
                timed_out(self.cfg.user_m_timeout_s),
                Waiting::UserCommand { code, p, q },
                stop.line,
                waited_s,
            ),
            // M19 with Q (`WAIT_ORIENT_SPINDLE_COMPLETE`): until the spindle is
            // oriented, an error past Q; without Q LinuxCNC does not wait
            MachineOp::SpindleOrient {
                angle_deg,
                timeout_s,
                ..
            } if timeout_s > 0.0 => {
                if inputs.spindle_oriented {
                    Action::Release
                } else if timed_out(timeout_s) {
                    Action::Fail(SequencerError::SpindleNotOriented {
                        line: stop.line,
                        angle_deg,
                        waited_s,
                    })
                } else {
                    Action::Wait(Waiting::SpindleOriented { angle_deg })
                }
            }
            // spindle off, M19 without Q, coolant, immediate outputs, messages: done
            // once the machine has them
            _ => Action::Release,
        }
    }
}
