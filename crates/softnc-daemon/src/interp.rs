//! `softnc-interp`: the interpolation process (paper 002's *servo task*).
//!
//! On a `StartJob` control command it reads and plans the job, then publishes one
//! command sample per interpolation cycle, keeping the position process's lookahead
//! ring filled to `lookahead_samples` ahead of the sample it is using (it learns that
//! from the position status). Because samples are produced only that far ahead,
//! a feed override or hold re-times every sample not yet sent and acts on motion
//! within the ring's depth. The job's last sample carries `FLAG_END_OF_JOB`.
//!
//! **Learned jobs** (paper 002 eq 5): when the job starts, the learning store is
//! looked up for (job file, machine profile file, feed override in force); a Markov
//! entry `softnc learn` made for exactly that is loaded before motion and its
//! correction added to command sample k while the job runs as planned. The moment
//! the job is re-timed (a feed override other than the entry's, a hold, an abort)
//! sample k no longer is the learnt sample k: the correction of the last sample sent
//! is held and ramped to zero over the lookahead depth (a dropped correction — up to
//! a few hundred µm at corners — would be a position step), and the job record gets
//! a note. Radius-law entries (paper 004) are another program, not applied.
//!
//! **On the cycle** nothing is allocated, locked or written: the job is read and
//! planned and its correction loaded before motion ([`InterpTask::plan_job`]); each
//! [`InterpTask::cycle`] reads status and control, pulls samples and queues them,
//! with heartbeats and notes, for the outbox thread ([`crate::outbox`]), which
//! publishes them in order and logs the notes.

use crate::config::{ClockMode, Loaded};
use crate::lifecycle::StopWatch;
use crate::loop_watch::{LoopEvent, LoopWatch};
use crate::outbox::{InterpMsg, Outbox, OUTBOX_CAPACITY};
use anyhow::{Context, Result};
use softnc_ipc::bus::{Bus, Sub};
use softnc_ipc::{
    Alarm, AlarmCode, CommandSample, ControlCommand, ControlKind, FixedStr, Heartbeat,
    MachineState, PositionStatus, ProcessId, JOB_ADAPTIVE_FORCE,
};
use softnc_learning::{JobCorrection, LearningStore, Lookup};
use softnc_planner::machine_sequencer::{
    Action, FeedbackHistory, MachineSequencer, SequencerState, Waiting,
};
use softnc_planner::stream::{
    check_and_stream, check_program, stream_program, CheckedProgram, StreamInterpolator, StreamMode,
};
use softnc_planner::{PlanOptions, ReadPlanError};
use softnc_servo::adaptive_feed::OverrideSchedule;
use std::fmt::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

pub use crate::job_setup::{JobSetup, Switches};

/// How long the loop sleeps when it has nothing to send.
const IDLE_SLEEP: Duration = Duration::from_micros(100);

/// The interpolation process.
pub struct InterpTask {
    cfg: Loaded,
    status: Sub<PositionStatus>,
    control: Sub<ControlCommand>,
    /// Command samples, heartbeats, loop stats and alarms leave through the outbox
    /// thread, in the order sent.
    outbox: Outbox<InterpMsg>,
    stats: softnc_rt::LoopStats,
    /// The loop's watch over its own timing (stalls, late cycles; realtime only).
    watch: LoopWatch,
    hb_counter: u64,
    last_hb: Instant,
    /// A heartbeat is due now (the state changed).
    beat_now: bool,
    state: MachineState,
    job_id: u64,
    /// Where the machine is, from the position process's status: a job is planned
    /// from there.
    machine_mm: [f64; 3],
    /// The outputs the machine holds (spindle, coolant, M62–M68), from the
    /// position process's status: a job's machine sequencer starts from them.
    machine_outputs: softnc_core::machine_io::MachineOutputs,
    /// The operator's program-flow switches, as the MMI last set them.
    switches: Switches,
    /// The rapid override as the MMI last set it (fraction, 0..=1): a job starts
    /// with it, and a change acts within the lookahead.
    rapid_override: f64,
    /// The `seq` of the running job's `StartJob`: a position process that has taken
    /// it (`mmi_control_seq`) and stands off dropped the job.
    start_seq: u64,

    /// The machine's parameter file and tool table: a job is read with them.
    store: crate::machine_store::MachineStore,
    shutdown: bool,
    /// SIGTERM/SIGINT or the supervisor's death: stop the job along its path, end.
    stop: StopWatch,
    /// The user M codes' runner thread (spawns and waits off the cycle).
    user_m: crate::user_m::UserMRunner,
    /// The last user M-code request's ticket.
    user_m_tickets: u64,
    _bus: Bus,
}

/// What happened to a job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JobEnd {
    /// All samples sent and consumed.
    Completed,
    /// Aborted (E-stop, abort, shutdown) after a controlled stop.
    Aborted,
    /// Refused before any sample was sent.
    Refused,
}

/// A job read and checked (its plan's figures, no plan held), its learned correction
/// (if any) loaded: everything that reads a file is done. [`InterpTask::start`]
/// streams it.
pub struct PlannedJob {
    job_id: u64,
    /// The profile with the machine's tool table.
    machine: softnc_machine::MachineProfile,
    path: String,
    /// The program's text: all the interpolation process holds of it.
    text: Arc<str>,
    options: PlanOptions,
    checked: CheckedProgram,
    /// The feed override in force when the job starts (fraction).
    feed_override: f64,
    learned: Option<JobCorrection>,
    /// With adaptive feed: the position process's force loop gives the override.
    adaptive: bool,
    /// The machine around the axes for the job (built before motion).
    sequencer: Option<MachineSequencer>,
}

impl PlannedJob {
    /// The job.
    pub fn job_id(&self) -> u64 {
        self.job_id
    }

    /// Whether a learned correction was loaded for it.
    pub fn learned(&self) -> bool {
        self.learned.is_some()
    }
}

/// A job being streamed: the state [`InterpTask::cycle`] advances, one call per
/// interpolation cycle. The plan comes in a bounded window from a producer thread
/// (`softnc_planner::stream`), never whole.
pub struct Streaming<'p> {
    job_id: u64,
    it: StreamInterpolator,
    /// The thread reading and planning the program into `it`'s window.
    producer: Option<std::thread::JoinHandle<Result<(), ReadPlanError>>>,
    /// Times the stream ran short, already reported.
    starved_reported: u64,
    learned: Option<JobCorrection>,
    /// The feed override the learned correction belongs to (fraction).
    learned_override: f64,
    /// Samples kept in flight beyond the one the position process uses.
    ahead: u64,
    next_seq: u64,
    /// The last sample the position process reported using.
    consumed: Option<u64>,
    sent_last: bool,
    operator_override: f64,
    /// Adaptive feed: the force loop's overrides in flight and in force.
    force: Option<ForceOverride>,
    held: bool,
    aborting: bool,
    /// The last planned sample, repeated while a learned correction still runs out.
    end_hold: Option<softnc_planner::Sample>,
    /// The first sample sent while the stream stands paused (M0/M1, single block).
    pause_seq: Option<u64>,
    /// The machine around the axes: each sample's outputs, and when the path may
    /// leave a machine stop.
    machine: MachineSequencer,
    /// The machine's inputs of this job's samples, heard `ahead` samples late.
    heard: FeedbackHistory,
    /// The operator resumed while the path waited at a machine stop.
    resume_at_stop: bool,
    /// What the path waits for at a machine stop (`None`: not waiting).
    waiting: Option<Waiting>,
    /// The sample from which the path waits for the operator at a tool change.
    operator_wait_seq: Option<u64>,
    /// The operator message last noted in the job's record.
    message_noted: Option<u32>,
    /// The `(PRINT,…)` last noted.
    printed_noted: Option<u32>,
    /// The user M code started for the machine stop of this motion, its ticket,
    /// and how it ended (`None`: still running).
    user_m: Option<(u32, u64, Option<crate::user_m::Outcome>)>,
    _job: std::marker::PhantomData<&'p mut PlannedJob>,
}

/// The interpolator's side of adaptive feed.
#[derive(Debug, Clone, Copy)]
struct ForceOverride {
    /// The position process's overrides, each due `lookahead` samples after the
    /// sample it was computed at (as `softnc sim --adaptive-force` applies them).
    schedule: OverrideSchedule,
    /// The force loop's override in force (fraction).
    override_frac: f64,
    /// Revolutions already scheduled.
    revolutions: u64,
}

impl Streaming<'_> {
    /// The override the path runs at when neither held nor stopping: the
    /// operator's, or with adaptive feed the force loop's capped by it.
    fn running_override(&self) -> f64 {
        match &self.force {
            Some(f) => f.override_frac.min(self.operator_override),
            None => self.operator_override,
        }
    }

    /// Samples sent so far.
    pub fn sent(&self) -> u64 {
        self.next_seq
    }

    /// End the stream: the producer thread stops (it finds the window gone) and is
    /// joined. Off the cycle path.
    pub fn finish(mut self) {
        let producer = self.producer.take();
        drop(self);
        if let Some(p) = producer {
            let _ = p.join();
        }
    }
}

impl InterpTask {
    /// Open the services and start the outbox thread.
    pub fn new(cfg: Loaded) -> Result<Self> {
        let names = softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance);
        let bus = Bus::new(names.clone(), "interp")?;
        // at most `ahead + 1` samples are in flight (queued, published or in the
        // position process's ring); twice that can never fill it, heartbeats and
        // notes included
        let capacity = OUTBOX_CAPACITY.max(4 * (cfg.config.lookahead_samples + 1));
        let store = crate::machine_store::MachineStore::new(&cfg.data_dir);
        let user_m =
            crate::user_m::UserMRunner::start(cfg.user_m_dir.clone(), cfg.config.user_m_timeout_s)
                .context("starting the user M-code runner thread")?;
        Ok(InterpTask {
            user_m,
            user_m_tickets: 0,
            status: bus.status_subscriber()?,
            control: bus.control_subscriber()?,
            // lossless: command samples are never dropped, and the rest is rare
            outbox: Outbox::start(
                names,
                "interp-out",
                capacity,
                true,
                cfg.config.interp_rt.helper_priority(),
            )?,
            stats: softnc_rt::LoopStats::new(),
            watch: LoopWatch::new(
                &cfg.config.loop_timing,
                Duration::from_secs_f64(cfg.machine.interpolation_cycle_s),
            ),
            cfg,
            hb_counter: 0,
            last_hb: Instant::now(),
            beat_now: true,
            state: MachineState::Idle,
            job_id: 0,
            machine_mm: [0.0; 3],
            machine_outputs: softnc_core::machine_io::MachineOutputs::safe(),
            switches: Switches::default(),
            rapid_override: 1.0,
            start_seq: 0,

            store,
            shutdown: false,
            stop: StopWatch::manual(),
            _bus: bus,
        })
    }

    /// Stop (as on a `Shutdown` command) when `stop` asks: a running job decelerates
    /// along its path, then the process ends.
    pub fn set_stop_watch(&mut self, stop: StopWatch) {
        self.stop = stop;
    }

    /// Serve control commands until `Shutdown`.
    pub fn run(&mut self) -> Result<()> {
        while !self.shutdown {
            if self.stop.requested().is_some() {
                self.shutdown = true;
                break;
            }
            while let Some(st) = self.status.receive()? {
                self.machine_mm = [st.cmd_mm[0], st.cmd_mm[1], st.cmd_mm[2]];
                self.machine_outputs = st.outputs.into();
            }
            while let Some(c) = self.control.receive()? {
                let c = *c;
                match ControlKind::from_wire(c.kind) {
                    Some(ControlKind::StartJob) if self.state == MachineState::Idle => {
                        let max = self.cfg.machine.planner.max_feed_override;
                        let feed_override = if (0.0..=max).contains(&c.value) {
                            c.value
                        } else {
                            1.0
                        };
                        tracing::info!("job {}: planning {}", c.job_id, c.path.as_str());
                        let waits = self.outbox.waits();
                        let from_line = (c.axis != 0 && c.axis != u32::MAX).then_some(c.axis);
                        let adaptive = c.flags & JOB_ADAPTIVE_FORCE != 0;
                        self.start_seq = c.seq;
                        let end = self.run_job(
                            c.path.as_str(),
                            c.job_id,
                            feed_override,
                            from_line,
                            adaptive,
                        )?;
                        tracing::info!("job {} {:?}", c.job_id, end);
                        if self.outbox.waits() > waits {
                            tracing::warn!(
                                "job {}: the outbox queue was full {} times; the loop waited",
                                c.job_id,
                                self.outbox.waits() - waits
                            );
                        }
                    }
                    Some(ControlKind::StartJob) => tracing::warn!(
                        "job {}: not started, the interpolator is {:?}",
                        c.job_id,
                        self.state
                    ),
                    Some(ControlKind::EStop) => self.state = MachineState::EStopped,
                    Some(ControlKind::Reset) => self.state = MachineState::Idle,
                    Some(k) if self.switches.apply(k, c.value) => {}
                    Some(ControlKind::RapidOverride) if (0.0..=1.0).contains(&c.value) => {
                        self.rapid_override = c.value;
                    }
                    Some(ControlKind::Shutdown) => self.shutdown = true,
                    _ => {}
                }
            }
            self.beat()?;
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(())
    }

    /// The machine state as this process sees it.
    pub fn state(&self) -> MachineState {
        self.state
    }

    /// Queue a message for the outbox thread (allocation-free).
    fn send(&mut self, m: InterpMsg) -> Result<()> {
        self.outbox.send(m)?;
        Ok(())
    }

    fn beat(&mut self) -> Result<()> {
        if self.beat_now
            || self.last_hb.elapsed().as_secs_f64() >= self.cfg.config.heartbeat_period_s
        {
            self.beat_now = false;
            self.hb_counter += 1;
            self.send(InterpMsg::Heartbeat(Heartbeat {
                process: ProcessId::Interp.wire(),
                pid: std::process::id(),
                counter: self.hb_counter,
                state: self.state.wire(),
                job_id: self.job_id,
            }))?;
            if self.stats.cycles() > 0 {
                let (j, c) = (self.stats.jitter(), self.stats.compute());
                self.send(InterpMsg::LoopStats(softnc_ipc::LoopStats {
                    process: ProcessId::Interp.wire(),
                    cycles: self.stats.cycles(),
                    jitter_ns: [j.p50_ns, j.p99_ns, j.p999_ns, j.max_ns],
                    compute_ns: [c.p50_ns, c.p99_ns, c.p999_ns, c.max_ns],
                    overruns: self.stats.overruns(),
                    latency_ns: [0; 4],
                    bus: [0; 9],
                }))?;
            }
            self.last_hb = Instant::now();
        }
        Ok(())
    }

    /// An alarm (logged by the outbox thread).
    fn alarm(&mut self, code: AlarmCode, message: &str) -> Result<()> {
        self.raise(code, FixedStr::truncated(message))
    }

    /// A remark for the job's record (not an alarm).
    fn note(&mut self, message: &str) -> Result<()> {
        self.raise(AlarmCode::Note, FixedStr::truncated(message))
    }

    /// An alarm or note whose text is already in its fixed buffer: allocation-free,
    /// for the cycle (logged by the outbox thread).
    fn raise(&mut self, code: AlarmCode, message: FixedStr<256>) -> Result<()> {
        self.send(InterpMsg::Alarm(Alarm {
            code: code.wire(),
            axis: u32::MAX,
            process: ProcessId::Interp.wire(),
            job_id: self.job_id,
            time_index: 0,
            pid: std::process::id(),
            raised_unix_ns: softnc_rt::unix_ns(),
            message,
        }))
    }

    /// The learned correction of the job `bytes` planned as `plan`, at the feed
    /// override `override_pct` in force, if the store has one that applies.
    fn learned(&mut self, job: &PlannedJob, override_pct: u32) -> Result<Option<JobCorrection>> {
        let store = LearningStore::new(&self.cfg.learning_dir);
        let machine = &job.machine;
        // the planned samples, counted on a stream of their own (only when the store
        // has an entry for the program)
        // (the machine stops not waited at: nothing would release them)
        let count = || {
            let options = PlanOptions {
                wait_at_machine_stops: false,
                ..job.options.clone()
            };
            check_and_stream(&job.text, &job.path, machine, &options, |it| it.count())
                .map_or(0, |(_, n)| n)
        };
        let found = softnc_learning::entry::lookup(
            &store,
            job.text.as_bytes(),
            &self.cfg.machine_bytes,
            override_pct,
            count,
            machine.interpolation_cycle_s,
        );
        match found {
            Ok(Lookup::None) => Ok(None),
            Ok(Lookup::Markov(c)) => {
                self.note(&format!(
                    "learned correction applied: {} ({} repetitions, max |correction| {:.1} µm, last learning run {:.3} µm RMS)",
                    c.entry,
                    c.repetitions,
                    c.max_abs_mm() * 1000.0,
                    c.last_rms_um.unwrap_or(f64::NAN)
                ))?;
                Ok(Some(c))
            }
            Ok(Lookup::NotApplied(why)) => {
                tracing::warn!("job {}: {why}", self.job_id);
                self.note(&why)?;
                Ok(None)
            }
            Err(e) => {
                tracing::warn!("job {}: learning store: {e}", self.job_id);
                self.note(&format!("learning store not read: {e}"))?;
                Ok(None)
            }
        }
    }

    /// Read, plan and stream one job, starting at feed override `feed_override`
    /// (fraction: the operator's, in force when the job starts); with `adaptive`,
    /// the position process's force loop gives the override, capped by the
    /// operator's.
    pub fn run_job(
        &mut self,
        path: &str,
        job_id: u64,
        feed_override: f64,
        from_line: Option<u32>,
        adaptive: bool,
    ) -> Result<JobEnd> {
        let Some(mut job) = self.plan_job(path, job_id, feed_override, from_line, adaptive)? else {
            return Ok(JobEnd::Refused);
        };
        let mut s = self.start(&mut job)?;
        // realtime: one cycle per interpolation period on absolute deadlines (timed);
        // lockstep: as fast as the position process consumes
        let realtime = self.cfg.config.clock == ClockMode::Realtime;
        let period = Duration::from_secs_f64(self.cfg.machine.interpolation_cycle_s);
        let mut clock = softnc_rt::PeriodicClock::new(period, Duration::from_micros(100));
        loop {
            let (woke, jitter, late) = if realtime {
                clock.wait()
            } else {
                (Instant::now(), Duration::ZERO, 0)
            };
            if realtime {
                if let Some(ev) = self.watch.observe(jitter, woke) {
                    self.on_timing(&mut s, ev)?;
                }
            }
            let end = self.cycle(&mut s)?;
            if realtime {
                self.stats.record(jitter, woke.elapsed(), late);
            }
            if let Some(end) = end {
                s.finish();
                return Ok(end);
            }
            if !realtime {
                // lockstep runs as fast as the position process consumes, but a
                // paused job stands at the nominal rate (not millions of standing
                // samples a second)
                std::thread::sleep(if self.state == MachineState::Paused {
                    period
                } else {
                    IDLE_SLEEP
                });
            }
        }
    }

    /// What the loop's watch found: after a stall the job stops along its path (the
    /// samples it sent meanwhile are not the ones the machine needed when), with an
    /// alarm; late cycles are reported. Allocation-free (texts in fixed buffers).
    fn on_timing(&mut self, s: &mut Streaming<'_>, ev: LoopEvent) -> Result<()> {
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        let mut msg = FixedStr::<256>::empty();
        match ev {
            LoopEvent::Stall { period } => {
                if !s.aborting {
                    s.aborting = true;
                    s.it.set_feed_override(0.0);
                    self.state = MachineState::Stopping;
                }
                let _ = write!(
                    msg,
                    "the interpolation loop stood {:.1} ms (bound {:.1} ms): the job stops along its path",
                    ms(period),
                    ms(self.watch.stall_bound())
                );
                self.raise(AlarmCode::LoopStall, msg)
            }
            LoopEvent::Late { count, worst, over } => {
                let _ = write!(
                    msg,
                    "the interpolation loop ran late: {count} cycle(s) off their period by more than {:.1} ms in {:.1} s (worst {:.1} ms)",
                    ms(self.watch.late_bound()),
                    over.as_secs_f64(),
                    ms(worst)
                );
                self.raise(AlarmCode::LoopLate, msg)
            }
        }
    }

    /// Read and plan job `job_id` and load its learned correction: all that reads a
    /// file or allocates, before motion. `None`: refused (the alarm is raised).
    pub fn plan_job(
        &mut self,
        path: &str,
        job_id: u64,
        feed_override: f64,
        from_line: Option<u32>,
        adaptive: bool,
    ) -> Result<Option<PlannedJob>> {
        self.job_id = job_id;
        // the machine's offsets and tools, as the MMI checked the job with them
        // with what the MMI checked it with: its preamble, parameters and
        // subroutine files
        let setup = self.store.job_setup(
            &self.cfg.machine,
            self.machine_mm,
            self.switches,
            from_line,
            job_id,
        );
        let user_m_dir = self.cfg.user_m_dir.clone();
        let log_files = self.cfg.gcode_log_dir.is_some();
        let checked = setup.and_then(|(machine, mut setup)| {
            setup.user_m_codes = Some(user_m_dir);
            setup.log_files = log_files;
            check_job(path, &machine, &setup).map(|c| (machine, c))
        });
        let (machine, (text, options, checked, _, _, logs)) = match checked {
            Ok(p) => p,
            Err(msg) => {
                self.alarm(AlarmCode::JobRefused, &msg)?;
                self.job_id = 0;
                return Ok(None);
            }
        };
        // the machine operations' tables, before motion (a second reading of the
        // text the check read: the same motions)
        let sequencer = softnc_planner::stream::stream_sequencer(
            &text,
            path,
            &machine,
            &options,
            softnc_planner::machine_sequencer::SequencerConfig {
                user_m_timeout_s: self.cfg.config.user_m_timeout_s,
                ..crate::plan_samples::sequencer_config(&machine)
            },
            // the outputs the last job or MDI command left on (held by the position
            // process): a spindle turning goes on turning, not waited for again
            crate::plan_samples::initial_state(options.params.as_ref(), self.machine_outputs),
        );
        let sequencer = match sequencer {
            Ok(s) => s,
            Err(e) => {
                self.alarm(AlarmCode::JobRefused, &e.to_string())?;
                self.job_id = 0;
                return Ok(None);
            }
        };
        // the program's log files, once it is accepted and before motion
        if let Some(dir) = &self.cfg.gcode_log_dir {
            if let Err(e) = softnc_gcode::log_files::write(dir, &logs) {
                let msg = format!(
                    "{path}: cannot write its log files in {}: {e}",
                    dir.display()
                );
                self.alarm(AlarmCode::JobRefused, &msg)?;
                self.job_id = 0;
                return Ok(None);
            }
        }
        let mut job = PlannedJob {
            job_id,
            machine,
            path: path.to_string(),
            text,
            options,
            checked,
            feed_override,
            learned: None,
            adaptive,
            sequencer: Some(sequencer),
        };
        // a learned correction belongs to the feed override it was learned at
        let override_pct = (feed_override * 100.0).round() as u32;
        job.learned = self.learned(&job, override_pct)?;
        if job.adaptive && job.learned.take().is_some() {
            // and to a job that is not re-timed
            self.note("adaptive feed re-times the job: its learned correction is not applied")?;
        }
        Ok(Some(job))
    }

    /// Start streaming a planned job: the machine runs it from the next
    /// [`InterpTask::cycle`] on.
    pub fn start<'p>(&mut self, job: &'p mut PlannedJob) -> Result<Streaming<'p>> {
        self.job_id = job.job_id;
        self.state = MachineState::Running;
        // lockstep runs exactly as the simulator (the interpolator waits for the
        // producer); real time never waits: a producer behind brakes the path to a
        // stop within its limits, and is reported
        let mode = match self.cfg.config.clock {
            ClockMode::Lockstep => StreamMode::Offline,
            ClockMode::Realtime => StreamMode::RealTime,
        };
        let (producer, mut it) = stream_program(
            job.text.clone(),
            &job.path,
            &job.machine,
            &job.options,
            &job.checked,
            mode,
        );
        let producer = std::thread::Builder::new()
            .name("plan-stream".into())
            .spawn(move || producer.run())
            .context("starting the plan's producer thread")?;
        // before motion: the window filled (allocation happens here, not later)
        it.fill();
        // adaptive feed: the force loop starts at 100 %, capped by the operator's
        let start_override = if job.adaptive {
            job.feed_override.min(1.0)
        } else {
            job.feed_override
        };
        if start_override != 1.0 {
            // from rest: the first sample already runs at the operator's override
            it.set_feed_override(start_override);
        }
        if self.rapid_override != 1.0 {
            it.set_rapid_override(self.rapid_override);
        }
        Ok(Streaming {
            job_id: job.job_id,
            it,
            producer: Some(producer),
            starved_reported: 0,
            learned: job.learned.take(),
            learned_override: job.feed_override,
            ahead: self.cfg.config.lookahead_samples as u64,
            next_seq: 0,
            consumed: None,
            sent_last: false,
            operator_override: job.feed_override,
            force: job.adaptive.then(|| ForceOverride {
                schedule: OverrideSchedule::new(self.cfg.config.lookahead_samples as u64),
                override_frac: 1.0,
                revolutions: 0,
            }),
            held: false,
            aborting: false,
            end_hold: None,
            pause_seq: None,
            machine: job.sequencer.take().unwrap_or_else(|| {
                MachineSequencer::new(
                    &softnc_gcode::Program::default(),
                    crate::plan_samples::sequencer_config(&job.machine),
                    SequencerState::default(),
                )
            }),
            heard: FeedbackHistory::new(self.cfg.config.lookahead_samples as u64),
            resume_at_stop: false,
            waiting: None,
            operator_wait_seq: None,
            message_noted: None,
            printed_noted: None,
            user_m: None,
            _job: std::marker::PhantomData,
        })
    }

    /// One interpolation cycle of a streaming job: the position process's progress,
    /// control commands, then command samples up to `ahead` beyond the one in use,
    /// and a heartbeat when due. Allocates nothing. `Some`: the job has ended.
    pub fn cycle(&mut self, s: &mut Streaming<'_>) -> Result<Option<JobEnd>> {
        let end = self.step(s)?;
        if let Some(end) = end {
            // a user M code still running is killed with its job
            if let Some((_, ticket, None)) = s.user_m {
                self.user_m
                    .request(crate::user_m::Request::Cancel { ticket });
            }
            self.state = match (end, self.state) {
                // stopped by a fault or an E-stop: that stands until a reset
                (JobEnd::Aborted, st @ (MachineState::Faulted | MachineState::EStopped)) => st,
                _ => MachineState::Idle,
            };
            self.job_id = 0;
        }
        Ok(end)
    }

    #[allow(clippy::too_many_lines)]
    fn step(&mut self, s: &mut Streaming<'_>) -> Result<Option<JobEnd>> {
        let job_id = s.job_id;
        let ahead = s.ahead;
        while let Some(st) = self.status.receive()? {
            self.machine_mm = [st.cmd_mm[0], st.cmd_mm[1], st.cmd_mm[2]];
            self.machine_outputs = st.outputs.into();
            if st.job_id == job_id {
                s.consumed = Some(s.consumed.map_or(st.seq, |c: u64| c.max(st.seq)));
                // (a status of the job before the position process uses its first
                // sample — it waits for the window, or a PDC's tables — says
                // nothing about the machine under a sample)
                let using = matches!(
                    MachineState::from_wire(st.state),
                    Some(MachineState::Running | MachineState::Held)
                );
                if using {
                    s.heard.record(st.seq, st.motion, st.inputs.into());
                }
                // adaptive feed: a revolution closed at sample `seq`
                if let Some(f) = s.force.as_mut() {
                    if st.force_revolutions > f.revolutions && st.force_override.is_finite() {
                        f.revolutions = st.force_revolutions;
                        f.schedule.push(st.seq, st.force_override);
                    }
                }
            }
            let stopped = matches!(
                MachineState::from_wire(st.state),
                Some(MachineState::Faulted | MachineState::EStopped)
            );
            // the position process stands off and has taken this job's start:
            // it dropped the job (the drives did not come on)
            let dropped = st.job_id == 0
                && MachineState::from_wire(st.state) == Some(MachineState::Off)
                && st.mmi_control_seq >= self.start_seq;
            if dropped {
                return Ok(Some(JobEnd::Aborted));
            }
            if stopped && (st.job_id == job_id || st.job_id == 0) {
                self.state = MachineState::from_wire(st.state).unwrap_or(MachineState::Faulted);
                return Ok(Some(JobEnd::Aborted));
            }
        }
        // a stop asked for by a signal or the supervisor's death: as a Shutdown
        let stop_now = !self.shutdown && self.stop.requested().is_some();
        let mut pending = stop_now.then(|| ControlCommand {
            flags: 0,
            seq: 0,
            sender: softnc_ipc::ProcessId::Interp.wire(),
            kind: ControlKind::Shutdown.wire(),
            job_id: 0,
            axis: u32::MAX,
            value: 0.0,
            path: FixedStr::empty(),
        });
        loop {
            let c = match pending.take() {
                Some(c) => c,
                None => match self.control.receive()? {
                    Some(c) => *c,
                    None => break,
                },
            };
            let kind = ControlKind::from_wire(c.kind);
            // re-timed from the next sample on: the learned correction fades out
            let retimed = match kind {
                Some(ControlKind::FeedOverride) => c.value != s.learned_override,
                Some(ControlKind::RapidOverride) => c.value != self.rapid_override,
                Some(ControlKind::Hold | ControlKind::Abort | ControlKind::Shutdown) => true,
                _ => false,
            };
            let next_seq = s.next_seq;
            if let Some(l) = s.learned.as_mut().filter(|l| retimed && !l.fading()) {
                l.fade_out(next_seq as usize, ahead as usize);
                let why = match kind {
                    Some(ControlKind::FeedOverride) => "feed override changed",
                    Some(ControlKind::RapidOverride) => "rapid override changed",
                    Some(ControlKind::Hold) => "feed hold",
                    _ => "abort",
                };
                // formatted in place: nothing allocated while the job runs
                let mut msg = FixedStr::<256>::empty();
                let _ = write!(
                    msg,
                    "learned correction faded out from sample {next_seq} over {ahead} samples: {why} (the job is re-timed)"
                );
                self.raise(AlarmCode::Note, msg)?;
            }
            match kind {
                Some(ControlKind::FeedOverride) => {
                    s.operator_override = c.value;
                    if !s.held && !s.aborting {
                        s.it.set_feed_override(s.running_override());
                    }
                }
                Some(ControlKind::Hold) => {
                    s.held = true;
                    s.it.set_feed_override(0.0);
                    self.state = MachineState::Held;
                }
                // a feed hold is resumed first; a pause (M0/M1, a block end in
                // single block) then
                Some(ControlKind::Resume) if !s.aborting && s.held => {
                    s.held = false;
                    s.it.set_feed_override(s.running_override());
                    self.state = MachineState::Running;
                }
                // at a machine stop (a tool change): the operator's acknowledgement
                Some(ControlKind::Resume) if !s.aborting && s.it.machine_stop().is_some() => {
                    s.resume_at_stop = true;
                }
                Some(ControlKind::Resume) if !s.aborting => {
                    s.it.set_single_block(self.switches.single_block);
                    s.it.resume();
                }
                // one block, then a stop at its end
                Some(ControlKind::Step) if !s.aborting && !s.held => {
                    s.it.set_single_block(true);
                    s.it.resume();
                }
                // traverses at the rapid override, within the lookahead
                Some(ControlKind::RapidOverride) if (0.0..=1.0).contains(&c.value) => {
                    self.rapid_override = c.value;
                    s.it.set_rapid_override(c.value);
                }
                Some(
                    k @ (ControlKind::SingleBlock
                    | ControlKind::OptionalStop
                    | ControlKind::BlockDelete),
                ) => {
                    self.switches.apply(k, c.value);
                    if k == ControlKind::SingleBlock {
                        // live: from the next block end the path can still stop at
                        s.it.set_single_block(self.switches.single_block);
                    }
                }
                Some(ControlKind::Abort) => {
                    s.aborting = true;
                    s.it.set_feed_override(0.0);
                    self.state = MachineState::Stopping;
                }
                Some(ControlKind::EStop) => {
                    self.state = MachineState::EStopped;
                    return Ok(Some(JobEnd::Aborted));
                }
                // the MMI resets only a machine that is not moving (faulted: the
                // position process was lost under this job): the job is over
                Some(ControlKind::Reset) => {
                    self.state = MachineState::Idle;
                    return Ok(Some(JobEnd::Aborted));
                }
                Some(ControlKind::Shutdown) => {
                    self.shutdown = true;
                    s.aborting = true;
                    s.it.set_feed_override(0.0);
                    self.state = MachineState::Stopping;
                }
                _ => {}
            }
        }
        // the stream: a producer behind (real time) is reported as it grows; one that
        // failed ends the job along its path
        let starved = s.it.starved();
        if starved > 0 && starved >= 2 * s.starved_reported {
            s.starved_reported = starved;
            let mut msg = FixedStr::<256>::empty();
            let _ = write!(
                msg,
                "the plan fell behind the interpolation {starved} times: the path slowed to a stop at the end of what was planned"
            );
            self.raise(AlarmCode::PlanStarved, msg)?;
        }
        if s.it.failed() && !s.aborting {
            s.aborting = true;
            s.it.set_feed_override(0.0);
            self.state = MachineState::Stopping;
            self.raise(
                AlarmCode::PlanFailed,
                FixedStr::truncated(
                    "the program could not be planned again while it ran: stopped along the path",
                ),
            )?;
        }
        // keep the ring filled `ahead` samples beyond the one in use
        let limit = s.consumed.map_or(ahead + 1, |c| c + 1 + ahead);
        while !s.sent_last && s.next_seq < limit {
            let sample = match &mut s.end_hold {
                // after the planned end: the final position, held (see below)
                Some(h) => {
                    h.index += 1;
                    *h
                }
                None => {
                    // adaptive feed: the force loop's override due at this sample
                    let due = s.force.as_mut().and_then(|f| {
                        let v = f.schedule.due(s.next_seq)?;
                        f.override_frac = v;
                        Some(v)
                    });
                    if due.is_some() && !s.held && !s.aborting {
                        s.it.set_feed_override(s.running_override());
                    }
                    let Some(sample) = s.it.next() else { break };
                    sample
                }
            };
            // a learned job ends where its correction is zero for good: the
            // learnt hold tail after the planned end (or the end of a fade-out)
            let correction_done = s
                .learned
                .as_ref()
                .is_none_or(|l| l.done_at(s.next_seq as usize));
            let stopped_for_abort = s.aborting
                && s.next_seq > 0
                && s.it.path_speed_mm_per_s() == 0.0
                && correction_done;
            let planned_end = s.it.is_finished();
            if planned_end && s.end_hold.is_none() && !correction_done {
                s.end_hold = Some(softnc_planner::Sample {
                    feed_move: false,
                    ..sample
                });
            }
            let last = (planned_end && correction_done) || stopped_for_abort;
            let mut pos_mm = sample.pos_mm.0;
            if let Some(l) = s.learned.as_ref() {
                let d = l.at(s.next_seq as usize);
                for (p, d) in pos_mm.iter_mut().zip(d) {
                    *p += d;
                }
            }
            let mut c = CommandSample::new(s.next_seq, job_id, sample.index, pos_mm);
            c.outputs = self.machine_step(s, &sample)?.into();
            c.motion = sample.motion;
            c.path_mm = sample.path_mm;
            if sample.feed_move {
                c.flags |= CommandSample::FLAG_FEED_MOVE;
            }
            if last {
                c.flags |= CommandSample::FLAG_END_OF_JOB;
                s.sent_last = true;
            }
            c.sent_unix_ns = softnc_rt::unix_ns();
            self.send(InterpMsg::Command(c))?;
            s.next_seq += 1;
        }
        // paused (M0/M1, single block) once the position process stands there too
        // (the stream is `ahead` samples ahead of it)
        let stream_paused = s.it.paused_at_line().is_some() && !s.held && !s.aborting;
        if !stream_paused {
            s.pause_seq = None;
        } else if s.pause_seq.is_none() {
            s.pause_seq = Some(s.next_seq);
        }
        let paused = s
            .pause_seq
            .or(s.operator_wait_seq)
            .is_some_and(|p| s.consumed.is_some_and(|c| c >= p));
        let was = self.state;
        match self.state {
            MachineState::Running if paused => self.state = MachineState::Paused,
            MachineState::Paused if !paused => self.state = MachineState::Running,
            _ => {}
        }
        // told at once, not at the next heartbeat
        self.beat_now |= self.state != was;
        self.beat()?;
        if s.sent_last && s.consumed.is_some_and(|c| c + 1 >= s.next_seq) {
            return Ok(Some(if s.aborting {
                JobEnd::Aborted
            } else {
                JobEnd::Completed
            }));
        }
        Ok(None)
    }
}

impl InterpTask {
    /// The machine sequencer's step for `sample` (the next to send): its outputs,
    /// the machine stop released where the machine's inputs (heard `ahead` samples
    /// late) or the operator allow, the job stopped along its path where a machine
    /// operation fails (a `MachineWait` alarm). Messages and prompts go to the job's
    /// record as notes as they are reached. Allocation-free.
    fn machine_step(
        &mut self,
        s: &mut Streaming<'_>,
        sample: &softnc_planner::Sample,
    ) -> Result<softnc_core::machine_io::MachineOutputs> {
        let stop = s.it.machine_stop();
        let mut fb = s.heard.feedback_for(s.next_seq);
        fb.resume = s.resume_at_stop;
        // the user M code of this stop: how its executable ended
        while let Some(r) = self.user_m.report() {
            if let Some(u) = s.user_m.as_mut().filter(|u| u.1 == r.ticket) {
                u.2 = Some(r.outcome);
            }
        }
        if let Some((_, _, Some(outcome))) = s.user_m.filter(|u| Some(u.0) == stop) {
            match outcome {
                crate::user_m::Outcome::Exited(0) => fb.user_command_done = true,
                o => fb.user_command_failed = Some(o.status()),
            }
        }
        let step = s.machine.step(sample.motion, stop, &fb);
        if let (Action::Wait(Waiting::UserCommand { code, p, q }), Some(m)) = (step.action, stop) {
            if s.user_m.is_none_or(|u| u.0 != m) {
                // the path stands at it: start it (on the runner's thread)
                self.user_m_tickets += 1;
                let ticket = self.user_m_tickets;
                let queued =
                    self.user_m
                        .request(crate::user_m::Request::Run { ticket, code, p, q });
                let outcome = (!queued).then_some(crate::user_m::Outcome::NotStarted);
                s.user_m = Some((m, ticket, outcome));
            }
        }
        if let (Action::Fail(_), Some((m, ticket, None))) = (step.action, s.user_m) {
            if Some(m) == stop {
                // past its timeout: killed
                self.user_m
                    .request(crate::user_m::Request::Cancel { ticket });
            }
        }
        if stop.is_some() && fb.applied_motion.is_some_and(|m| Some(m) >= stop) {
            // the resume was heard at this stop
            s.resume_at_stop = false;
        }
        if stop.is_none() {
            s.resume_at_stop = false;
        }
        // (a print does not stop the path: it is reached with the next motion's first
        // sample, before a message there)
        // an M66's result (#5399) for the operator and the job's record
        if let Some(r) = step.input_result {
            let mut msg = FixedStr::<256>::empty();
            let _ = write!(msg, "{r}");
            self.raise(AlarmCode::Note, msg)?;
        }
        // (texts with #5399 after an M66 are filled in with the machine's value)
        if let Some(i) = step.state.printed.filter(|&i| Some(i) != s.printed_noted) {
            s.printed_noted = Some(i);
            let mut msg = FixedStr::<256>::empty();
            let _ = write!(msg, "print: ");
            let _ = s.machine.write_message(i, &mut msg);
            self.raise(AlarmCode::Note, msg)?;
        }
        if let Some(i) = step.state.message.filter(|&i| Some(i) != s.message_noted) {
            s.message_noted = Some(i);
            let mut msg = FixedStr::<256>::empty();
            let _ = write!(msg, "message: ");
            let _ = s.machine.write_message(i, &mut msg);
            self.raise(AlarmCode::Note, msg)?;
        }
        let waiting = match step.action {
            Action::Wait(w) if w != Waiting::Applied => Some(w),
            _ => None,
        };
        if let Some(w) = waiting.filter(|_| waiting != s.waiting) {
            let mut msg = FixedStr::<256>::empty();
            let _ = write!(msg, "prompt: {w}");
            self.raise(AlarmCode::Note, msg)?;
        }
        s.waiting = waiting;
        match (waiting, s.operator_wait_seq) {
            (Some(Waiting::ToolChange { .. }), None) => s.operator_wait_seq = Some(s.next_seq),
            (Some(Waiting::ToolChange { .. }), Some(_)) => {}
            _ => s.operator_wait_seq = None,
        }
        match step.action {
            Action::Release => s.it.release_machine_stop(),
            Action::Fail(e) if !s.aborting => {
                s.aborting = true;
                s.it.set_feed_override(0.0);
                self.state = MachineState::Stopping;
                let mut msg = FixedStr::<256>::empty();
                let _ = write!(msg, "{e}: the job stops");
                self.raise(AlarmCode::MachineWait, msg)?;
            }
            _ => {}
        }
        Ok(step.state.outputs)
    }
}

/// Check a program's bytes (read from `path`) for `machine` as `setup` says (from
/// where the machine is, with its parameters), as it will be streamed: its plan's
/// figures and first error, in memory bounded by the braking distance, never the
/// whole plan. The error text is the operator's (`path:line:column: reason`).
pub fn check_bytes(
    bytes: &[u8],
    path: &str,
    machine: &softnc_machine::MachineProfile,
    setup: &JobSetup,
) -> Result<Checked, String> {
    let text: Arc<str> = Arc::from(String::from_utf8_lossy(bytes));
    let options = setup.plan_options();
    let (program, checked) =
        check_program(&text, path, machine, &options).map_err(|e| e.to_string())?;
    Ok((
        text,
        options,
        checked,
        program.end_modal,
        program.subroutine_files,
        program.log_files,
    ))
}

/// A program checked: its text, the options it is planned with, the plan's figures,
/// the modal state it leaves (G-code), the subroutine files it took in and the log
/// files it writes.
pub type Checked = (
    Arc<str>,
    PlanOptions,
    CheckedProgram,
    String,
    Vec<softnc_gcode::SubroutineFile>,
    Vec<softnc_gcode::log_files::LogFile>,
);

/// Read a program (the MMI's copy) and check it as `setup` says ([`check_bytes`]);
/// its text is the learning store's key.
pub fn check_job(
    path: &str,
    machine: &softnc_machine::MachineProfile,
    setup: &JobSetup,
) -> Result<Checked, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: cannot read: {e}"))?;
    check_bytes(&bytes, path, machine, setup)
}
