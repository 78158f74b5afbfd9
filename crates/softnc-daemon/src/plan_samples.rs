//! A plan's samples as the offline simulator takes them (`softnc sim`, the lockstep
//! tests): the interpolator's samples as command samples, its feed override open to
//! adaptive feed ([`softnc_sim::simulate_adaptive`]) as the interpolation process
//! opens it to the position process's force loop, and — with a machine sequencer
//! ([`PlanSamples::with_machine`]) — the machine around the axes as the
//! interpolation process runs it: each sample's `outputs` from the sequencer, the
//! path released from a machine stop on the simulated machine's inputs heard with
//! the daemon's lag (`lookahead_samples`, [`FeedbackHistory`]). The simulator has
//! no operator: a tool change waits for the simulated tool changer's
//! `tool-changed` — or, on a machine whose profile maps no `ToolChanged` input (no
//! changer: the daemon asks its operator), is done at once, as by an operator who
//! resumes at the prompt — and a program stop (M0/M1) does not wait. It runs no
//! user M code (M100–M199): each is taken as done (exit status 0) as soon as the
//! machine has its stop.

use softnc_core::machine_io::MachineOutputs;
use softnc_planner::machine_sequencer::{
    Action, FeedbackHistory, MachineSequencer, SequencerConfig, SequencerState,
};
use softnc_planner::Interpolator;
use softnc_sim::{CommandSample, OverridableSamples};
use std::cell::RefCell;
use std::rc::Rc;

/// The sequencer's figures from the machine profile: the interpolation cycle and
/// the spindle's at-speed timeout (`servo.io.at_speed_timeout_s`; no I/O map: no
/// timeout, the spindle reads at speed). No user M-code timeout: the offline
/// simulator takes them as done at once, and the interpolation process sets the
/// daemon configuration's `user_m_timeout_s`.
pub fn sequencer_config(profile: &softnc_machine::MachineProfile) -> SequencerConfig {
    SequencerConfig {
        cycle_s: profile.interpolation_cycle_s,
        spindle_at_speed_timeout_s: profile
            .servo
            .io
            .as_ref()
            .map_or(0.0, |io| io.at_speed_timeout_s),
        user_m_timeout_s: 0.0,
    }
}

/// The machine state a job starts from: the outputs the machine holds (`held`:
/// the last job's or MDI command's, as the position process reports them —
/// [`MachineOutputs::safe`] on a cold machine, which is what the offline
/// simulator runs a job on), without a tool-change request; the tool in the
/// spindle as parameter 5400 says. A spindle already turning is not waited for:
/// only a job's own M3/M4/S waits for the spindle at speed.
pub fn initial_state(
    params: Option<&softnc_gcode::Params>,
    held: MachineOutputs,
) -> SequencerState {
    let tool = params.map_or(0.0, |p| p.get(5400));
    SequencerState {
        outputs: held.held_for_next_job(),
        tool_in_spindle: if tool.is_finite() && tool > 0.0 {
            tool as u32
        } else {
            0
        },
        ..SequencerState::default()
    }
}

/// The inputs as the position process publishes them (through its status's wire
/// form), so the simulator hears exactly what the interpolation process hears.
pub fn as_published(
    inputs: &softnc_core::machine_io::MachineInputs,
) -> softnc_core::machine_io::MachineInputs {
    softnc_ipc::InputsWire::from(*inputs).into()
}

/// A simulation's machine sequencer for `program` (read with `options`) on a cold
/// machine (outputs safe) and the history its samples hear the machine through,
/// `lag` samples late (the daemon's `lookahead_samples`): pass both to
/// [`PlanSamples::with_machine`] and record every cycle with [`hear`].
pub fn sim_machine(
    program: &softnc_gcode::Program,
    profile: &softnc_machine::MachineProfile,
    options: &softnc_planner::PlanOptions,
    lag: u64,
) -> (MachineSequencer, Rc<RefCell<FeedbackHistory>>) {
    let seq = MachineSequencer::new(
        program,
        sequencer_config(profile),
        initial_state(options.params.as_ref(), MachineOutputs::safe()),
    );
    (seq, Rc::new(RefCell::new(FeedbackHistory::new(lag))))
}

/// The simulated machine used sample `seq` on the cycle of `row`: what the
/// position process's status of that cycle tells the interpolation process.
pub fn hear<B: softnc_servo::ServoBackend>(
    heard: &RefCell<FeedbackHistory>,
    seq: u64,
    row: &softnc_servo::TraceRow,
    engine: &softnc_servo::CycleEngine<B>,
) {
    heard
        .borrow_mut()
        .record(seq, row.motion, as_published(engine.io().last_inputs()));
}

/// Whether the profile maps a tool changer's `tool-changed` input (without one the
/// daemon's tool change waits for the operator's resume).
pub fn has_tool_changer(profile: &softnc_machine::MachineProfile) -> bool {
    profile.servo.io.as_ref().is_some_and(|io| {
        io.inputs
            .iter()
            .any(|l| matches!(l.signal, softnc_machine::io::InputSignal::ToolChanged))
    })
}

/// The machine side of [`PlanSamples`].
struct Machine {
    seq: MachineSequencer,
    heard: Rc<RefCell<FeedbackHistory>>,
    /// No tool changer: the simulated operator resumes at a tool change at once.
    operator_resumes: bool,
    /// Samples given so far.
    n: u64,
    /// The job failed at a machine stop: the stream ended there.
    failed: bool,
}

/// The samples of a plan's interpolator.
pub struct PlanSamples<'p> {
    it: Interpolator<'p>,
    machine: Option<Machine>,
}

impl<'p> PlanSamples<'p> {
    /// The samples without the machine around the axes (outputs off, no wait).
    pub fn new(it: Interpolator<'p>) -> Self {
        PlanSamples { it, machine: None }
    }

    /// The samples with the machine around the axes: `it` planned with
    /// `wait_at_machine_stops`, `heard` recorded by the simulation's observer
    /// ([`FeedbackHistory::record`] with the sample number, motion and
    /// [`as_published`] inputs of every cycle).
    pub fn with_machine(
        it: Interpolator<'p>,
        seq: MachineSequencer,
        heard: Rc<RefCell<FeedbackHistory>>,
    ) -> Self {
        PlanSamples {
            it,
            machine: Some(Machine {
                seq,
                heard,
                operator_resumes: false,
                n: 0,
                failed: false,
            }),
        }
    }

    /// On a machine without a tool changer ([`has_tool_changer`] false) the
    /// simulated operator resumes at every tool change at once (else the
    /// simulation would wait for ever).
    pub fn without_tool_changer(mut self, none: bool) -> Self {
        if let Some(m) = self.machine.as_mut() {
            m.operator_resumes = none;
        }
        self
    }

    /// The interpolator (its overrides).
    pub fn interpolator(&mut self) -> &mut Interpolator<'p> {
        &mut self.it
    }

    /// Whether the job stopped at a machine stop that failed (the spindle not at
    /// speed in time): the samples end there.
    pub fn failed(&self) -> bool {
        self.machine.as_ref().is_some_and(|m| m.failed)
    }
}

impl Iterator for PlanSamples<'_> {
    type Item = CommandSample;
    fn next(&mut self) -> Option<CommandSample> {
        if self.failed() {
            return None;
        }
        let s = self.it.next()?;
        let mut c = CommandSample {
            pos_mm: softnc_core::Axes::from_xyz(s.pos_mm.0, 0.0),
            motion: s.motion,
            feed_move: s.feed_move,
            outputs: Default::default(),
        };
        if let Some(m) = self.machine.as_mut() {
            let mut fb = m.heard.borrow().feedback_for(m.n);
            fb.resume = m.operator_resumes;
            // a user M code is not run here: done as soon as the machine has it
            fb.user_command_done = true;
            let step = m.seq.step(s.motion, self.it.machine_stop(), &fb);
            c.outputs = step.state.outputs;
            match step.action {
                Action::Release => self.it.release_machine_stop(),
                Action::Fail(_) => m.failed = true,
                Action::Wait(_) | Action::Run => {}
            }
            m.n += 1;
        }
        Some(c)
    }
}

impl OverridableSamples for PlanSamples<'_> {
    fn set_feed_override(&mut self, override_frac: f64) {
        self.it.set_feed_override(override_frac);
    }
}
