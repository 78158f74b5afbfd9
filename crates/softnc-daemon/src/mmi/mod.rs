//! `softnc-mmi`: job queue, machine state, alarms, job history and the operator API
//! (iceoryx2 request-response). It checks a job completely — G-code, planning, soft
//! limits — before anything moves, and forwards operator commands to the
//! interpolation and position processes.
//!
//! - this module: the loop (`poll`), the machine state and its transitions
//!   ([`transition`], docs/operations.md), the operator's commands, status;
//! - `check`: a submitted job, MDI block or touch-off taken in off the loop;
//! - `setup`: jog, touch-off, the tool table, and why a program is refused now;
//! - `program`: what a check takes in (a job, MDI, a touch-off), shared by both;
//! - `history`: the job records and `jobs.json`.
//!
//! Operator requests and replies are `softnc-api` types, serialised in the
//! iceoryx2 payloads ([`wire_reply`]).

mod check;
mod history;
pub mod oplog;
mod program;
mod setup;

use history::{add_accuracy, load_jobs, ContourRms, Outcome};
pub use history::{Accuracy, JobRecord};
use program::CheckKind;
use softnc_api::{Reply, Request};

use crate::config::Loaded;
use crate::interp::Switches;
use crate::lifecycle::StopWatch;
use crate::machine_store::{offsets_json, MachineStore, Offsets};
use anyhow::{Context, Result};
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use softnc_api::ProcessHealth;
use softnc_ipc::bus::{Bus, Pub, Sub};
use softnc_ipc::{
    Alarm, AlarmCode, ControlCommand, ControlKind, FixedStr, Heartbeat, LoopStats, MachineState,
    OperatorReply, OperatorRequest, PositionStatus, ProcessId,
};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

#[derive(Debug, Clone, Copy)]
struct Peer {
    last_seen: Option<Instant>,
    state: u32,
    /// Its pid, from its heartbeats.
    pid: u32,
    /// The pid of an instance reported lost: its heartbeats still queued are stale.
    lost_pid: Option<u32>,
    /// The job its last heartbeat was about (0 none).
    job_id: u64,
}

/// The MMI's iceoryx2 ports to the other processes, with the sequence of its
/// control commands and its own heartbeat's.
struct Ports {
    control: Pub<ControlCommand>,
    status: Sub<PositionStatus>,
    heartbeats: Sub<Heartbeat>,
    alarms_sub: Sub<Alarm>,
    alarms_pub: Pub<Alarm>,
    loop_stats: Sub<LoopStats>,
    heartbeat: Pub<Heartbeat>,
    control_seq: u64,
    hb_counter: u64,
    last_hb: Instant,
}

impl Ports {
    /// Send a control command to the interpolation and position processes (the
    /// next in sequence).
    fn send_control(
        &mut self,
        kind: ControlKind,
        job_id: u64,
        axis: u32,
        value: f64,
        flags: u32,
        path: &str,
    ) -> Result<()> {
        self.control_seq += 1;
        self.control.send_copy(ControlCommand {
            seq: self.control_seq,
            sender: ProcessId::Mmi.wire(),
            kind: kind.wire(),
            job_id,
            axis,
            value,
            flags,
            path: FixedStr::try_new(path)?,
        })?;
        Ok(())
    }
}

/// The machine as the MMI knows it: the position process's last status, the other
/// processes' health and loop timing, the alarms, and what the operator asked for
/// (a hold or an abort, a state not yet acknowledged, the overrides, switches, a
/// jog's lease).
struct Machine {
    last: Option<PositionStatus>,
    peers: [Peer; 4],
    loops: [Option<LoopStats>; 4],
    alarms: VecDeque<Alarm>,
    /// The job an abort or a stop was asked for: it ends "aborted", not "completed".
    abort_asked: Option<u64>,
    /// A hold or an abort of the running job, accepted (Held, Stopping); cleared by
    /// resume and at the job's end.
    intent: Option<MachineState>,
    feed_override: f64,
    /// The rapid override in force (fraction, 0..=1).
    rapid_override: f64,
    /// The operator overrides the limit switches (`OverrideLimits`): cleared by
    /// the first status with none tripped, as the position process clears its own.
    limits_overridden: bool,
    /// The operator's program-flow switches.
    switches: Switches,
    /// A continuous jog's axis, speed and when its client last renewed it (the
    /// dead-man).
    jog_lease: Option<(u32, f64, Instant)>,
    /// An incremental jog's axis and target (machine coordinates, mm): its
    /// distance to go while the axis jogs.
    jog_target: Option<(usize, f64)>,
    /// A state a command just sent asks the position process for (machine on/off,
    /// homing, a jog), the command's `seq` and when it was sent: the state the
    /// operator sees until the position process's status acknowledges the command
    /// (`mmi_control_seq`), so that a status read right after the reply does not
    /// show the state before it.
    asked: Option<(MachineState, u64, Instant)>,
    /// The running job's `StartJob` command (job id, its `seq`): once the position
    /// process has taken it (`mmi_control_seq`) while off, the job cannot run.
    start_sent: Option<(u64, u64)>,
    /// Alarms raised up to this time (ns since the Unix epoch) were acknowledged by
    /// a reset: replayed to a restarted MMI, they are not shown again. Kept in
    /// `<data_dir>/alarms-acknowledged` across MMI restarts.
    alarms_acknowledged_unix_ns: u64,
}

/// The MMI process, in owned parts: the operator endpoint, the ports to the other
/// processes, the machine's state and alarms, the job history, the job checks and
/// the machine's setup (parameters, modal state, tool table).
pub struct MmiTask {
    cfg: Loaded,
    /// The operator endpoint (request-response): `softnc-api` requests in, replies
    /// out.
    endpoint: Server<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
    ports: Ports,
    machine: Machine,
    history: history::History,
    checks: check::Checks,
    setup: setup::Setup,
    /// The running job's machine sequencer (built by its check, from the same
    /// text and setup the interpolator runs): the tool, coolant, spindle command,
    /// message and prompt at the sample the position process uses. Not kept across
    /// an MMI restart (those fields are then empty until the next job). With it,
    /// the end points of the job's motions: the distance to go.
    job_machine: Option<(
        u64,
        softnc_planner::machine_sequencer::MachineSequencer,
        softnc_planner::stream::MotionEnds,
    )>,
    shutdown: bool,
    stop: StopWatch,
    _bus: Bus,
}

type OperatorRequestIn =
    iceoryx2::active_request::ActiveRequest<ipc::Service, OperatorRequest, (), OperatorReply, ()>;

const ALARM_HISTORY: usize = 50;

/// The file in the data directory that keeps when the alarms were last acknowledged.
const ALARMS_ACKNOWLEDGED: &str = "alarms-acknowledged";

impl MmiTask {
    /// Open the services and the job history.
    #[allow(clippy::too_many_lines)]
    pub fn new(cfg: Loaded) -> Result<Self> {
        let names = softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance);
        let bus = Bus::new(names.clone(), "mmi")?;
        let svc = bus
            .node
            .service_builder(&names.operator().as_str().try_into()?)
            .request_response::<OperatorRequest, OperatorReply>()
            .max_clients(16)
            .open_or_create()
            .context("operator service")?;
        let server = svc.server_builder().create().context("operator server")?;
        let (jobs, job_id_floor) = load_jobs(&cfg.data_dir.join("jobs.json"));
        let store = MachineStore::new(&cfg.data_dir);
        // a controller starting starts with the interpreter's defaults (as LinuxCNC);
        // an MMI restarted under a running one keeps the machine's modal state
        if std::env::var_os(crate::cli::RESTARTED_ENV).is_none() {
            store.clear_modal();
        }
        let restarted = std::env::var_os(crate::cli::RESTARTED_ENV).is_some();
        let alarms_acknowledged_unix_ns = if restarted {
            std::fs::read_to_string(cfg.data_dir.join(ALARMS_ACKNOWLEDGED))
                .ok()
                .and_then(|t| t.trim().parse().ok())
                .unwrap_or(0)
        } else {
            0
        };
        let (modal, modal_error) = match store.load_modal() {
            Ok(m) => (m, None),
            Err(e) => {
                tracing::error!("{e}");
                (None, Some(e))
            }
        };
        let (params, params_error) = match store.load_params() {
            Ok(p) => (p, None),
            Err(e) => {
                tracing::error!("{e}");
                (None, Some(e))
            }
        };
        let mut task = MmiTask {
            job_machine: None,
            endpoint: server,
            ports: Ports {
                control: bus.control_publisher()?,
                status: bus.status_subscriber()?,
                heartbeats: bus.heartbeat_subscriber()?,
                alarms_sub: bus.alarm_subscriber()?,
                alarms_pub: bus.alarm_publisher()?,
                loop_stats: bus.loop_stats_subscriber()?,
                heartbeat: bus.heartbeat_publisher()?,
                control_seq: 0,
                hb_counter: 0,
                last_hb: Instant::now() - Duration::from_secs(1),
            },
            cfg,
            machine: Machine {
                last: None,
                peers: [Peer {
                    last_seen: None,
                    state: 0,
                    pid: 0,
                    lost_pid: None,
                    job_id: 0,
                }; 4],
                loops: [None; 4],
                alarms: VecDeque::new(),
                abort_asked: None,
                start_sent: None,
                intent: None,
                feed_override: 1.0,
                rapid_override: 1.0,
                limits_overridden: false,
                switches: Switches::default(),
                jog_lease: None,
                jog_target: None,
                asked: None,
                alarms_acknowledged_unix_ns,
            },
            history: history::History {
                jobs,
                contour_rms: ContourRms::default(),
                job_id_floor,
                last_save: Instant::now(),
                unsaved: history::Unsaved::default(),
            },
            checks: check::Checks {
                checking: None,
                abandoned: Vec::new(),
            },
            setup: setup::Setup {
                store,
                params,
                params_error,
                pending_params: None,
                modal,
                modal_error,
            },
            shutdown: false,
            stop: StopWatch::manual(),
            _bus: bus,
        };
        // a file the machine cannot run with is said at once, by name
        let unusable: Vec<String> = [&task.setup.params_error, &task.setup.modal_error]
            .into_iter()
            .flatten()
            .cloned()
            .collect();
        for e in unusable {
            task.alarm(&e)?;
        }
        Ok(task)
    }

    /// Raise an alarm of the MMI's own (`Other`).
    fn alarm(&mut self, msg: &str) -> Result<()> {
        self.raise(AlarmCode::Other, msg)
    }

    /// Raise an alarm of the MMI's own, of kind `code`.
    fn raise(&mut self, code: AlarmCode, msg: &str) -> Result<()> {
        self.ports.alarms_pub.send_copy(Alarm {
            code: code.wire(),
            axis: u32::MAX,
            process: ProcessId::Mmi.wire(),
            job_id: 0,
            time_index: 0,
            pid: std::process::id(),
            raised_unix_ns: softnc_rt::unix_ns(),
            message: FixedStr::truncated(msg),
        })?;
        Ok(())
    }

    /// Stop when `stop` asks (SIGTERM/SIGINT, the supervisor's death).
    pub fn set_stop_watch(&mut self, stop: StopWatch) {
        self.stop = stop;
    }

    fn send_control(
        &mut self,
        kind: ControlKind,
        job_id: u64,
        value: f64,
        path: &str,
    ) -> Result<()> {
        self.send_control_axis(kind, job_id, u32::MAX, value, path)
    }

    fn send_control_axis(
        &mut self,
        kind: ControlKind,
        job_id: u64,
        axis: u32,
        value: f64,
        path: &str,
    ) -> Result<()> {
        self.send_control_flags(kind, job_id, axis, value, 0, path)
    }

    fn send_control_flags(
        &mut self,
        kind: ControlKind,
        job_id: u64,
        axis: u32,
        value: f64,
        flags: u32,
        path: &str,
    ) -> Result<()> {
        self.ports
            .send_control(kind, job_id, axis, value, flags, path)
    }

    /// The machine state as the position process reports it (off before it
    /// reports).
    pub fn position_state(&self) -> MachineState {
        self.machine
            .last
            .and_then(|s| MachineState::from_wire(s.state))
            .unwrap_or(MachineState::Off)
    }

    /// A job is under way: started and not ended (also before its first sample).
    fn job_active(&self) -> bool {
        self.machine.last.is_some_and(|s| s.job_id != 0) || self.history.any_running()
    }

    /// The machine state the operator sees (docs/operations.md): the position
    /// process's, with a job's hold or stop along its path as asked for and accepted,
    /// or as the interpolator reports it (a stop on a signal), and faulted when the
    /// supervisor has given up on a process.
    pub fn machine_state(&self) -> MachineState {
        let pos = self.position_state();
        let supervisor = self.machine.peers[ProcessId::Supervisor as usize];
        let supervisor_faulted = supervisor
            .last_seen
            .is_some_and(|t| t.elapsed().as_secs_f64() <= self.cfg.config.heartbeat_timeout_s)
            && supervisor.state == MachineState::Faulted.wire();
        // the position process's last word does not stand once it is gone
        let position_lost = self.peer_status(ProcessId::Position) == ProcessHealth::Lost;
        // a command sent and not yet taken: what it asked for, not the state before
        let asked = self.asked_pending();
        match pos {
            MachineState::Faulted | MachineState::EStopped => pos,
            _ if supervisor_faulted || position_lost => MachineState::Faulted,
            _ if asked.is_some() => asked.unwrap_or(pos),
            MachineState::Off | MachineState::Homing | MachineState::Jogging => pos,
            _ if self.job_active() => {
                let running = self
                    .history
                    .jobs
                    .iter()
                    .rev()
                    .find(|j| j.outcome == Outcome::Running);
                let mdi = running.is_some_and(|j| j.mdi.is_some());
                // the interpolator's word on this job (not a stale one on the last)
                let peer = self.machine.peers[ProcessId::Interp as usize];
                let interp = MachineState::from_wire(peer.state)
                    .filter(|_| running.is_some_and(|j| j.job_id == peer.job_id));
                match (self.machine.intent, interp) {
                    (Some(i), _) => i,
                    (None, Some(MachineState::Stopping)) => MachineState::Stopping,
                    (None, Some(MachineState::Paused)) => MachineState::Paused,
                    _ if mdi => MachineState::Mdi,
                    _ => MachineState::Running,
                }
            }
            _ => MachineState::Idle,
        }
    }

    /// Remember the state the command just sent asks for ([`MmiTask::asked`]).
    fn ask_state(&mut self, state: MachineState) {
        self.machine.asked = Some((state, self.ports.control_seq, Instant::now()));
    }

    /// The state asked for by a command the position process has not yet
    /// acknowledged (at most a heartbeat timeout: a process that restarted in
    /// between never will).
    fn asked_pending(&self) -> Option<MachineState> {
        let (state, seq, sent) = self.machine.asked?;
        let acknowledged = self.machine.last.is_some_and(|s| s.mmi_control_seq >= seq);
        let waited = sent.elapsed().as_secs_f64() > self.cfg.config.heartbeat_timeout_s;
        (!acknowledged && !waited).then_some(state)
    }

    /// Serve until a `Shutdown` request or a stop (signal, the supervisor's death),
    /// then until the running job has stopped (its record says how) or `stopping.record_wait_s`.
    pub fn run(&mut self) -> Result<()> {
        let mut stopping_since: Option<Instant> = None;
        loop {
            self.poll()?;
            if self.stop.requested().is_some() && !self.shutdown {
                self.shutdown = true;
                self.machine.abort_asked = self.history.running().map(|j| j.job_id);
            }
            if self.shutdown {
                let since = *stopping_since.get_or_insert_with(Instant::now);
                let moving = self.machine.last.is_some_and(|s| {
                    s.job_id != 0
                        && matches!(
                            MachineState::from_wire(s.state),
                            Some(MachineState::Running | MachineState::Held | MachineState::Idle)
                        )
                });
                if !moving || since.elapsed().as_secs_f64() > self.cfg.config.stopping.record_wait_s
                {
                    self.save_jobs();
                    return Ok(());
                }
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    /// One pass over every input.
    #[allow(clippy::too_many_lines)]
    pub fn poll(&mut self) -> Result<()> {
        let mut changed = false;
        while let Some(s) = self.ports.status.receive()? {
            let s = *s;
            let prev_state = self.position_state();
            if s.job_id != 0 {
                // reattached after an MMI restart: the job is still running
                if let Some(j) = self
                    .history
                    .jobs
                    .iter_mut()
                    .find(|j| j.job_id == s.job_id && j.outcome == Outcome::Interrupted)
                {
                    j.outcome = Outcome::Running;
                }
            }
            let running = self
                .history
                .jobs
                .iter_mut()
                .rev()
                .find(|j| j.outcome == Outcome::Running);
            if let Some(job) = running {
                if s.job_id == job.job_id {
                    add_accuracy(
                        &mut job.accuracy,
                        &mut self.history.contour_rms,
                        job.job_id,
                        &s,
                    );
                    job.cycles = job.cycles.max(s.time_index + 1);
                    job.path_mm = job.path_mm.max(s.path_mm);
                }
            }
            self.machine.last = Some(s);
            if s.job_id == 0 && self.history.running().is_none() {
                self.modal_follows_the_machine(&s);
            }
            let inputs = softnc_core::machine_io::MachineInputs::from(s.inputs);
            if inputs.limit_min | inputs.limit_max == 0 {
                self.machine.limits_overridden = false;
            }
            let now_state = self.position_state();
            if prev_state != now_state || s.job_id == 0 || now_state == MachineState::Off {
                let abort_asked = self.machine.abort_asked;
                let mut ended = false;
                if let Some(job) = self.history.running() {
                    // the position process took the job's start while off (the
                    // drives did not come on: its alarm says why): it never runs
                    let taken_while_off = now_state == MachineState::Off
                        && self
                            .machine
                            .start_sent
                            .is_some_and(|(id, seq)| id == job.job_id && s.mmi_control_seq >= seq);
                    if taken_while_off {
                        job.alarms
                            .push("the machine is off: the job did not start".to_string());
                    }
                    if taken_while_off
                        || matches!(now_state, MachineState::Faulted | MachineState::EStopped)
                    {
                        job.outcome = Outcome::Aborted;
                        ended = true;
                    } else if now_state == MachineState::Idle && s.job_id == 0 && job.cycles > 0 {
                        // stopped along its path by an abort or a stop: not completed
                        let aborted = abort_asked == Some(job.job_id);
                        job.outcome = if aborted {
                            Outcome::Aborted
                        } else {
                            Outcome::Completed
                        };
                        ended = true;
                    }
                }
                if ended {
                    changed = true;
                    self.machine.intent = None;
                    self.machine.abort_asked = None;
                    self.keep_params_of_completed_job()?;
                }
            }
        }
        while let Some(h) = self.ports.heartbeats.receive()? {
            if let Some(p) = self.machine.peers.get_mut(h.process as usize) {
                if p.lost_pid == Some(h.pid) {
                    continue; // sent before it died
                }
                p.last_seen = Some(Instant::now());
                p.state = h.state;
                p.pid = h.pid;
                p.job_id = h.job_id;
            }
        }
        while let Some(a) = self.ports.alarms_sub.receive()? {
            if a.raised_unix_ns != 0 && a.raised_unix_ns <= self.machine.alarms_acknowledged_unix_ns
            {
                // replayed to this (restarted) MMI, acknowledged by a reset before
                continue;
            }
            if a.code == AlarmCode::Note.wire() {
                // a remark for the job's record, not an alarm
                let (job_id, text) = (a.job_id, a.message.as_str().to_string());
                if let Some(j) = self
                    .history
                    .jobs
                    .iter_mut()
                    .rev()
                    .find(|j| j.job_id == job_id)
                {
                    history::push_note(&mut j.notes, text, history::JOB_NOTES_KEPT);
                    changed = true;
                }
                continue;
            }
            if a.code == AlarmCode::ProcessLost.wire() && a.process != ProcessId::Supervisor.wire()
            {
                // the process named is gone: not alive until its successor says so
                // (an alarm about an instance before the one heard now is stale:
                // its successor stays alive)
                let mut current = true;
                if let Some(p) = self.machine.peers.get_mut(a.process as usize) {
                    current = a.pid == 0 || p.pid == 0 || p.pid == a.pid;
                    if current {
                        p.lost_pid = Some(if a.pid != 0 { a.pid } else { p.pid });
                        p.last_seen = None;
                    }
                }
                // the servo loop died under the job: it ended there (faulted); the
                // interpolator took the job with it (its successor knows nothing of
                // it) — also one started after its death, before the death was told
                if current
                    && (a.process == ProcessId::Position.wire()
                        || a.process == ProcessId::Interp.wire())
                {
                    let alarm = format!("ProcessLost: {}", a.message.as_str());
                    // (a death told again to a restarted MMI is older than the job
                    // running now: not this job's)
                    let died_unix_s = a.raised_unix_ns / 1_000_000_000;
                    if let Some(j) = self
                        .history
                        .running()
                        .filter(|j| a.raised_unix_ns == 0 || died_unix_s >= j.submitted_unix_s)
                    {
                        j.outcome = Outcome::Aborted;
                        if a.job_id != j.job_id {
                            j.alarms.push(alarm);
                        }
                        changed = true;
                    }
                    self.machine.intent = None;
                    self.machine.abort_asked = None;
                }
            }
            // kept in the record of the job it concerns; a job the interpolator
            // refused (its file changed after the check) never started
            let code = AlarmCode::from_wire(a.code).unwrap_or(AlarmCode::Other);
            if a.job_id == 0 && concerns_the_running_job(code) {
                // a process lost or restarted while a job ran: in its record (once,
                // though a restarted MMI is told again what its predecessor was)
                let text = format!("{code:?}: {}", a.message.as_str());
                if let Some(j) = self.history.running() {
                    if !j.alarms.contains(&text) {
                        j.alarms.push(text);
                        changed = true;
                    }
                }
            }
            if let Some(j) = self
                .history
                .jobs
                .iter_mut()
                .rev()
                .find(|j| j.job_id == a.job_id)
            {
                // (once, though a restarted MMI is told again what its predecessor was)
                let text = format!("{code:?}: {}", a.message.as_str());
                if !j.alarms.contains(&text) {
                    j.alarms.push(text);
                }
                if code == AlarmCode::JobRefused && j.outcome == Outcome::Running {
                    j.outcome = Outcome::Refused;
                    self.machine.intent = None;
                }
                changed = true;
            }
            if self.machine.alarms.len() == ALARM_HISTORY {
                self.machine.alarms.pop_front();
            }
            self.machine.alarms.push_back(*a);
        }
        while let Some(l) = self.ports.loop_stats.receive()? {
            if let Some(slot) = self.machine.loops.get_mut(l.process as usize) {
                *slot = Some(*l);
            }
        }
        // the running job's record is written as it progresses (once a second); a
        // file that could not be written is tried again as often
        let running = self.history.any_running();
        let due =
            self.history.last_save.elapsed().as_secs_f64() >= self.cfg.config.job_record_period_s;
        if changed || (running && due) || (self.history.unsaved.any() && due) {
            self.save_jobs();
        }
        if due && self.history.unsaved.any() {
            self.retry_unsaved()?;
        }
        // abandoned checks that have ended
        self.checks.abandoned.retain(|(_, t)| !t.is_finished());
        while let Some(req) = self.endpoint.receive()? {
            let text = req.message.as_str().to_string();
            // a client that gave up waiting (this process was stopped) is gone: its
            // reply goes nowhere, which is no reason to stop serving
            let request = match softnc_api::decode_request(&text) {
                Ok(r) => r,
                Err(e) => {
                    oplog::unreadable(&e.to_string());
                    let reply = Reply::refused(format!("{e}; nothing done"));
                    if let Err(e) = req.send_copy(wire_reply(&reply, "unreadable")) {
                        tracing::warn!("reply not delivered: {e:?}");
                    }
                    continue;
                }
            };
            let reply = self.handle(&request)?;
            oplog::answered(&request, reply.as_ref());
            match reply {
                Some(reply) => {
                    if let Err(e) = req.send_copy(wire_reply(&reply, request.name())) {
                        tracing::warn!("reply not delivered: {e:?}");
                    }
                }
                // a job taken in off the loop: answered when its check ends
                None => match self.checks.checking.as_mut() {
                    Some(c) => c.request = Some(req),
                    None => {
                        let reply = Self::reply(false, 0, "job not started");
                        if let Err(e) = req.send_copy(wire_reply(&reply, request.name())) {
                            tracing::warn!("reply not delivered: {e:?}");
                        }
                    }
                },
            }
        }
        self.poll_checking()?;
        self.watch_jog()?;
        if self.ports.last_hb.elapsed().as_secs_f64() >= self.cfg.config.heartbeat_period_s {
            self.ports.hb_counter += 1;
            self.ports.heartbeat.send_copy(Heartbeat {
                process: ProcessId::Mmi.wire(),
                pid: std::process::id(),
                counter: self.ports.hb_counter,
                state: self.machine_state().wire(),
                job_id: self.machine.last.map_or(0, |s| s.job_id),
            })?;
            self.ports.last_hb = Instant::now();
        }
        Ok(())
    }

    /// A completed job's (or MDI's) parameters become the machine's: saved, and
    /// read back from the file (so that the next check and the interpolator's plan
    /// read the same values). An aborted job's are dropped.
    fn keep_params_of_completed_job(&mut self) -> Result<()> {
        let Some((job_id, params, modal)) = self.setup.pending_params.take() else {
            return Ok(());
        };
        let completed = self
            .history
            .jobs
            .iter()
            .any(|j| j.job_id == job_id && j.outcome == Outcome::Completed);
        if completed {
            self.save_params(&params)?;
            self.save_modal(modal);
        }
        Ok(())
    }

    /// Between jobs the modal state follows what the machine has on: a spindle or
    /// a coolant the machine stopped without a program saying so (an E-stop,
    /// machine off, a fault, an abort, a restart) is no longer M3/M4, M7/M8 in it,
    /// as LinuxCNC's interpreter takes the spindle's and the coolant's state from
    /// the machine when it synchronises (`Interp::synch`: `GET_EXTERNAL_SPINDLE`,
    /// `GET_EXTERNAL_MIST`, `GET_EXTERNAL_FLOOD`). Else an `S` alone in the next
    /// command would start the spindle the machine stopped.
    fn modal_follows_the_machine(&mut self, s: &PositionStatus) {
        let Some(modal) = self.setup.modal.as_deref() else {
            return;
        };
        let o: softnc_core::machine_io::MachineOutputs = s.outputs.into();
        let stopped = o.spindle_dir == softnc_core::machine_io::SpindleDir::Stopped;
        let off = |line: &str| match line.trim() {
            "M3" | "M4" => stopped,
            "M7" => !o.coolant_mist,
            "M8" => !o.coolant_flood,
            _ => false,
        };
        if !modal.lines().any(off) {
            return;
        }
        let kept: String = modal
            .lines()
            .filter(|l| !off(l))
            .map(|l| format!("{l}\n"))
            .collect();
        self.save_modal(kept);
    }

    /// The modal state a completed MDI command or job left becomes the machine's
    /// (kept in memory; a file that cannot be written is tried again).
    fn save_modal(&mut self, modal: String) {
        let unchanged = self.setup.modal.as_deref() == Some(modal.as_str())
            && self.history.unsaved.modal().is_none();
        self.setup.modal = Some(modal);
        if !unchanged {
            let _ = self.write_modal();
        }
    }

    /// Write the modal state to its file: an alarm the first time it fails.
    fn write_modal(&mut self) -> Result<()> {
        let Some(modal) = self.setup.modal.clone() else {
            return Ok(());
        };
        let written = self.setup.store.save_modal(&modal);
        let what = format!("modal state {}", self.setup.store.modal_path().display());
        self.note_saved(history::Unsaved::MODAL, &what, written)
    }

    /// A completed job's parameters become the machine's: kept in memory as the
    /// file will give them back, and written (unless unchanged). While the file is
    /// not written jobs are refused (a restart would lose the offsets); it is tried
    /// again until written.
    fn save_params(&mut self, params: &softnc_gcode::Params) -> Result<()> {
        // as the file gives them back (LinuxCNC's six decimals)
        let kept = match softnc_gcode::Params::from_var_text(&params.to_var_text(), "parameters") {
            Ok(p) => p,
            Err(e) => {
                self.alarm(&format!("parameters not kept: {e}"))?;
                return Ok(());
            }
        };
        let unchanged =
            self.setup.params.as_ref() == Some(&kept) && self.history.unsaved.params().is_none();
        self.setup.params = Some(kept);
        if !unchanged {
            self.write_params()?;
        }
        Ok(())
    }

    /// Write the machine's parameters to their file: an alarm the first time it
    /// fails.
    fn write_params(&mut self) -> Result<()> {
        let Some(params) = self.setup.params.clone() else {
            return Ok(());
        };
        let written = self.setup.store.save_params(&params);
        let what = format!("parameters {}", self.setup.store.params_path().display());
        self.note_saved(history::Unsaved::PARAMS, &what, written)
    }

    /// Files that could not be written, tried again.
    fn retry_unsaved(&mut self) -> Result<()> {
        if self.history.unsaved.params().is_some() {
            self.write_params()?;
        }
        if self.history.unsaved.modal().is_some() {
            self.write_modal()?;
        }
        Ok(())
    }

    /// An accepted reply (about job `job_id`, 0: none) or a refusal, saying `msg`.
    fn reply(accepted: bool, job_id: u64, msg: &str) -> Reply {
        if accepted {
            Reply::accepted((job_id != 0).then_some(job_id), msg)
        } else {
            Reply::refused(msg)
        }
    }

    /// The reply to a request; `None` when it is answered later (a job being
    /// checked, see [`Checking`]).
    #[allow(clippy::too_many_lines)]
    fn handle(&mut self, request: &Request) -> Result<Option<Reply>> {
        let state = self.machine_state();
        let axis_index = |a: &softnc_api::Axis| a.index() as u32;
        Ok(Some(match request {
            Request::SubmitJob {
                path,
                from_line,
                adaptive_force,
            } => return Ok(self.submit_job(path, *from_line, *adaptive_force, state)),
            Request::Mdi { blocks } => {
                let text = blocks.clone();
                if text.trim().is_empty() {
                    return Ok(Some(Self::reply(false, 0, "MDI: no block given")));
                }
                if let Some(why) = self.refuse_program(state, "MDI") {
                    return Ok(Some(Self::reply(false, 0, &why)));
                }
                let path = match self.mdi_file(&text) {
                    Ok(p) => p,
                    Err(e) => return Ok(Some(Self::reply(false, 0, &format!("MDI: {e}")))),
                };
                return Ok(self.begin_check(path, CheckKind::Mdi { text }));
            }
            Request::TouchOff {
                axis,
                value_mm,
                coords,
            } => {
                return self.touch_off(
                    axis_index(axis),
                    *value_mm,
                    coords.as_deref().unwrap_or(""),
                    state,
                )
            }
            Request::Offsets => {
                let table = offsets_json(
                    self.setup.params.as_ref(),
                    self.setup.modal.as_deref(),
                    &self.cfg.machine,
                );
                match serde_json::from_value(table) {
                    Ok(t) => Reply::Offsets(t),
                    Err(e) => Self::reply(false, 0, &format!("offsets: {e}")),
                }
            }
            Request::Tools => match self.setup.store.load_tools(&self.cfg.machine) {
                Ok(t) => Reply::Tools(
                    t.into_iter()
                        .map(|t| softnc_api::Tool {
                            number: t.number,
                            length_mm: t.length_mm,
                            diameter_mm: t.diameter_mm,
                        })
                        .collect(),
                ),
                Err(e) => Self::reply(false, 0, &e),
            },
            Request::ToolSet {
                tool,
                length_mm,
                diameter_mm,
            } => return self.tool_set(*tool, *length_mm, *diameter_mm),
            Request::SingleBlock { on } => self.switch(ControlKind::SingleBlock, *on)?,
            Request::OptionalStop { on } => self.switch(ControlKind::OptionalStop, *on)?,
            Request::BlockDelete { on } => self.switch(ControlKind::BlockDelete, *on)?,
            Request::MachineOn => self.drives_or_home(ControlKind::MachineOn, u32::MAX, state)?,
            Request::MachineOff => self.drives_or_home(ControlKind::MachineOff, u32::MAX, state)?,
            Request::OverrideLimits => self.override_limits(state)?,
            Request::Home { axis } => self.drives_or_home(
                ControlKind::Home,
                axis.as_ref().map_or(u32::MAX, axis_index),
                state,
            )?,
            Request::Jog {
                axis,
                speed_mm_per_min,
            } => self.jog(ControlKind::Jog, axis_index(axis), *speed_mm_per_min, state)?,
            Request::JogStep { axis, distance_mm } => {
                self.jog(ControlKind::JogStep, axis_index(axis), *distance_mm, state)?
            }
            Request::Step => match transition(ControlKind::Step, state) {
                Err(why) => Self::reply(false, 0, &format!("Step refused ({state:?}): {why}")),
                Ok(next) => {
                    let job_id = self.history.running().map_or(0, |j| j.job_id);
                    self.send_control(ControlKind::Step, 0, 0.0, "")?;
                    Self::reply(
                        true,
                        job_id,
                        &format!("job {job_id}: next block ({next:?})"),
                    )
                }
            },
            Request::FeedOverride { fraction } => {
                let value = *fraction;
                let max = self.cfg.machine.planner.max_feed_override;
                if !(0.0..=max).contains(&value) {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("override must be 0..={:.0} %", max * 100.0),
                    )));
                }
                self.machine.feed_override = value;
                self.send_control(ControlKind::FeedOverride, 0, value, "")?;
                Self::reply(true, 0, &format!("feed override {:.0} %", value * 100.0))
            }
            Request::RapidOverride { fraction } => {
                let value = *fraction;
                if !(0.0..=1.0).contains(&value) {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        "rapid override must be 0..=100 %",
                    )));
                }
                self.machine.rapid_override = value;
                self.send_control(ControlKind::RapidOverride, 0, value, "")?;
                Self::reply(true, 0, &format!("rapid override {:.0} %", value * 100.0))
            }
            Request::SpindleOverride { fraction } => {
                let value = *fraction;
                let range = self.cfg.machine.spindle;
                if !(range.min_override..=range.max_override).contains(&value) {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!(
                            "spindle override must be {:.0}..={:.0} % (the profile's spindle section)",
                            range.min_override * 100.0,
                            range.max_override * 100.0
                        ),
                    )));
                }
                self.send_control(ControlKind::SpindleOverride, 0, value, "")?;
                Self::reply(true, 0, &format!("spindle override {:.0} %", value * 100.0))
            }
            Request::Hold => self.job_command(ControlKind::Hold, state)?,
            Request::Resume => self.job_command(ControlKind::Resume, state)?,
            Request::Abort => self.job_command(ControlKind::Abort, state)?,
            Request::EStop => self.job_command(ControlKind::EStop, state)?,
            Request::Reset => self.job_command(ControlKind::Reset, state)?,
            Request::Shutdown => {
                if let Some(c) = self.checks.checking.as_mut() {
                    c.cancelled = Some("the controller is shutting down");
                }
                self.machine.abort_asked = self.history.running().map(|j| j.job_id);
                self.send_control(ControlKind::Shutdown, 0, 0.0, "")?;
                self.shutdown = true;
                Self::reply(true, 0, "shutting down")
            }
            Request::Status => Reply::Status(Box::new(self.status())),
            Request::Jobs { offset } => self.history.page(*offset),
        }))
    }

    /// Submit a job: read once (a regular file under the limit), checked, and run
    /// from its immutable copy; on a thread of its own (a long program takes a
    /// while) — the loop goes on serving status and E-stop. `None`: answered when
    /// the check ends.
    fn submit_job(
        &mut self,
        path: &str,
        from_line: Option<u32>,
        adaptive_asked: bool,
        state: MachineState,
    ) -> Option<Reply> {
        if let Some(why) = self.refuse_program(state, "job") {
            return Some(Self::reply(false, 0, &why));
        }
        let from_line = from_line.filter(|l| *l != 0 && *l != u32::MAX);
        // adaptive feed: asked for, or the profile's default; only on a
        // machine whose profile has the force loop
        let adaptive_feed = self
            .cfg
            .machine
            .force
            .as_ref()
            .and_then(|f| f.adaptive_feed.as_ref());
        let adaptive_force = adaptive_asked || adaptive_feed.is_some_and(|a| a.enabled);
        if adaptive_force && adaptive_feed.is_none() {
            return Some(Self::reply(
                false,
                0,
                &format!(
                    "adaptive force refused: the machine profile {} has no force.adaptive_feed section; nothing started",
                    self.cfg.machine_path.display()
                ),
            ));
        }
        self.begin_check(
            path.to_string(),
            CheckKind::Job {
                from_line,
                adaptive_force,
            },
        )
    }

    /// A program-flow switch (single block, optional stop, block delete) on or off.
    fn switch(&mut self, kind: ControlKind, on: bool) -> Result<Reply> {
        let value = if on { 1.0 } else { 0.0 };
        self.machine.switches.apply(kind, value);
        self.send_control(kind, 0, value, "")?;
        let name = match kind {
            ControlKind::SingleBlock => "single block",
            ControlKind::OptionalStop => "optional stop",
            _ => "block delete",
        };
        let when = if self.job_active() && kind != ControlKind::SingleBlock {
            " (from the next job)"
        } else {
            ""
        };
        Ok(Self::reply(
            true,
            0,
            &format!("{name} {}{when}", if on { "on" } else { "off" }),
        ))
    }

    /// Machine on, machine off, or homing `axis` (`u32::MAX`: all).
    fn drives_or_home(
        &mut self,
        kind: ControlKind,
        axis: u32,
        state: MachineState,
    ) -> Result<Reply> {
        // the E-stop input latched open (the position process's inputs): the
        // machine cannot be switched on until it is closed and reset (LinuxCNC's
        // external E-stop, `iocontrol.0.emc-enable-in`)
        let estop_input = self
            .machine
            .last
            .is_some_and(|s| softnc_core::machine_io::MachineInputs::from(s.inputs).estop_open);
        if kind == ControlKind::MachineOn && estop_input {
            return Ok(Self::reply(
                false,
                0,
                &format!("{kind:?} refused ({state:?}): the E-stop input is open"),
            ));
        }
        // a limit switch tripped: on only with the override (LinuxCNC's)
        let tripped = self.limits_tripped();
        if kind == ControlKind::MachineOn
            && !tripped.is_empty()
            && !self.machine.limits_overridden
            && state == MachineState::Off
        {
            return Ok(Self::reply(
                false,
                0,
                &format!(
                    "{kind:?} refused ({state:?}): limit switch tripped ({}): override-limits first, then jog off it away from the switch",
                    tripped.join(", ")
                ),
            ));
        }
        Ok(match transition(kind, state) {
            Err(why) => Self::reply(false, 0, &format!("{kind:?} refused ({state:?}): {why}")),
            Ok(next) => {
                let axes = self.cfg.machine.axes.len().min(3) as u32;
                if kind == ControlKind::Home && axis != u32::MAX && axis >= axes {
                    return Ok(Self::reply(false, 0, "home: no such axis"));
                }
                self.send_control_axis(kind, 0, axis, 0.0, "")?;
                self.ask_state(next);
                let what = match kind {
                    ControlKind::MachineOn => "machine on".to_string(),
                    ControlKind::MachineOff => "machine off".to_string(),
                    _ if axis == u32::MAX => "homing all axes".to_string(),
                    _ => format!("homing {}", self.axis_name(axis)),
                };
                Self::reply(true, 0, &format!("{what} ({next:?})"))
            }
        })
    }

    /// Hold, resume, abort, E-stop or reset.
    fn job_command(&mut self, kind: ControlKind, state: MachineState) -> Result<Reply> {
        Ok(match transition(kind, state) {
            Err(why) => Self::reply(false, 0, &format!("{kind:?} refused ({state:?}): {why}")),
            Ok(next) => {
                let job_id = self.history.running().map_or(0, |j| j.job_id);
                match kind {
                    ControlKind::Hold => self.machine.intent = Some(MachineState::Held),
                    ControlKind::Resume => self.machine.intent = None,
                    // idle: nothing to stop but the spindle and the coolant (the
                    // position process does that on every abort)
                    ControlKind::Abort if state == MachineState::Idle => {}
                    ControlKind::Abort => {
                        self.machine.intent = Some(MachineState::Stopping);
                        self.machine.abort_asked = Some(job_id);
                    }
                    ControlKind::Reset => {
                        // acknowledged: the machine's list is cleared, the jobs'
                        // records keep theirs; a restarted MMI does not show
                        // them again
                        self.machine.alarms.clear();
                        self.acknowledge_alarms();
                    }
                    ControlKind::EStop => {
                        if let Some(c) = self.checks.checking.as_mut() {
                            c.cancelled = Some("emergency stop while it was checked");
                        }
                    }
                    _ => {}
                }
                if kind != ControlKind::Reset || state != MachineState::Idle {
                    self.send_control(kind, 0, 0.0, "")?;
                }
                let what = match kind {
                    ControlKind::Hold => format!("job {job_id} held"),
                    ControlKind::Resume => format!("job {job_id} resumed"),
                    ControlKind::Abort if state == MachineState::Idle => {
                        "spindle stopped, coolant off".to_string()
                    }
                    ControlKind::Abort => format!("job {job_id} stopping along its path"),
                    ControlKind::EStop => "emergency stop".to_string(),
                    _ if state == MachineState::Idle => "alarms cleared".to_string(),
                    _ if state == MachineState::Off => "alarms cleared".to_string(),
                    _ if self.peer_status(ProcessId::Position) != ProcessHealth::Alive => {
                        "reset: alarms cleared; the position process is started again, the machine comes back off (`on` to switch the drives on)".to_string()
                    }
                    _ => "reset: alarms cleared, the machine is off (`on` to switch the drives on)".to_string(),
                };
                Self::reply(true, job_id, &format!("{what} ({next:?})"))
            }
        })
    }

    /// A reset acknowledged the alarms raised until now: kept for a restarted MMI.
    fn acknowledge_alarms(&mut self) {
        self.machine.alarms_acknowledged_unix_ns = softnc_rt::unix_ns();
        let path = self.cfg.data_dir.join(ALARMS_ACKNOWLEDGED);
        let text = self.machine.alarms_acknowledged_unix_ns.to_string();
        if let Err(e) = softnc_core::store::write_atomic(&path, text.as_bytes()) {
            tracing::warn!("{}: {e}", path.display());
        }
    }

    /// Alive (a heartbeat within the timeout), lost (silent, or reported lost and
    /// not yet back) or unseen.
    fn peer_status(&self, p: ProcessId) -> ProcessHealth {
        let timeout = self.cfg.config.heartbeat_timeout_s;
        match self.machine.peers[p as usize].last_seen {
            Some(t) if t.elapsed().as_secs_f64() <= timeout => ProcessHealth::Alive,
            Some(_) => ProcessHealth::Lost,
            None if self.machine.peers[p as usize].lost_pid.is_some() => ProcessHealth::Lost,
            None => ProcessHealth::Unseen,
        }
    }

    /// The running job's machine around the axes at the sample the position
    /// process uses: the sequencer's state there, the message's text and the
    /// prompt of the machine stop it stands at.
    fn job_around(
        &self,
        s: Option<&PositionStatus>,
    ) -> Option<(
        softnc_planner::machine_sequencer::SequencerState,
        Option<String>,
        Option<String>,
    )> {
        let s = s?;
        let (job_id, seq, _) = self.job_machine.as_ref()?;
        let running = self
            .history
            .jobs
            .iter()
            .rev()
            .any(|j| j.job_id == *job_id && j.outcome == Outcome::Running);
        if !running || s.job_id != *job_id {
            return None;
        }
        let st = seq.state_of(s.motion);
        let message = st
            .message
            .and_then(|i| seq.message_text(i))
            .map(|t| self.message_shown(*job_id, t.trim()));
        let prompt = seq.waiting_at(s.motion).map(|w| w.to_string());
        Some((st, message, prompt))
    }

    /// A message's text as the operator sees it: with #5399 after an M66 (known
    /// at the machine only), the text the interpolation process filled in with
    /// the machine's value when the path reached it (the job's last `message: `
    /// note of that form), else `#5399` in its place.
    fn message_shown(&self, job_id: u64, text: &str) -> String {
        if !softnc_gcode::message_shows_m66_result(text) {
            return text.to_string();
        }
        let mark = softnc_gcode::M66_RESULT_MARK;
        let head = &text[..text.find(mark).unwrap_or(0)];
        let tail = text
            .rfind(mark)
            .map_or("", |k| text.get(k + mark.len_utf8() + 1..).unwrap_or(""));
        let noted = self
            .history
            .jobs
            .iter()
            .rev()
            .find(|j| j.job_id == job_id)
            .and_then(|j| {
                j.notes.iter().rev().find_map(|n| {
                    let t = n.strip_prefix("message: ")?;
                    (t.starts_with(head) && t.ends_with(tail)).then(|| t.to_string())
                })
            });
        noted.unwrap_or_else(|| {
            let mut shown = String::new();
            let _ = softnc_gcode::write_message(&mut shown, text, None);
            shown
        })
    }

    /// What the motion in progress has still to go per axis (X, Y, Z; mm): the
    /// running job's (or MDI command's) motion at the sample the position process
    /// uses, from its programmed end point, or an incremental jog's to its target;
    /// zero otherwise (idle, a continuous jog, homing, an MMI restarted under a job).
    fn distance_to_go_mm(&self, s: Option<&PositionStatus>) -> [f64; 3] {
        let mut to_go = [0.0; 3];
        let Some(s) = s else { return to_go };
        let end = match self.machine_state() {
            MachineState::Jogging => self.machine.jog_target.map(|(axis, target_mm)| {
                let mut end = [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]];
                if axis < 3 {
                    end[axis] = target_mm;
                }
                end
            }),
            MachineState::Idle
            | MachineState::Off
            | MachineState::Homing
            | MachineState::Faulted
            | MachineState::EStopped => None,
            _ => self
                .job_machine
                .as_ref()
                .filter(|(job_id, _, _)| *job_id == s.job_id && s.job_id != 0)
                .and_then(|(_, _, ends)| ends.end_mm(s.motion)),
        };
        if let Some(end) = end {
            for (i, d) in to_go.iter_mut().enumerate() {
                let v = end[i] - s.cmd_mm[i];
                *d = if v.is_finite() { v } else { 0.0 };
            }
        }
        to_go
    }

    /// The status the operator sees.
    #[allow(clippy::too_many_lines)]
    pub fn status(&self) -> softnc_api::Status {
        use softnc_api as api;
        let loops = |p: ProcessId| {
            self.machine.loops[p as usize].map(|l| {
                let pct = |v: [u64; 4]| api::Percentiles {
                    p50: v[0],
                    p99: v[1],
                    p999: v[2],
                    max: v[3],
                };
                api::LoopTiming {
                    cycles: l.cycles,
                    overruns: l.overruns,
                    jitter_ns: pct(l.jitter_ns),
                    compute_ns: pct(l.compute_ns),
                    latency_ns: pct(l.latency_ns),
                }
            })
        };
        let job = self
            .history
            .jobs
            .iter()
            .rev()
            .find(|j| j.outcome == Outcome::Running)
            .or(self.history.jobs.last());
        let s = self.machine.last;
        let offsets = Offsets::from_params(self.setup.params.as_ref(), &self.cfg.machine)
            .with_modal(self.setup.modal.as_deref());
        let machine_mm = s.map(|s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]);
        let modal_has = |word: &str| {
            self.setup
                .modal
                .as_deref()
                .is_some_and(|m| m.lines().any(|l| l.trim() == word))
        };
        let around = self.job_around(s.as_ref());
        api::Status {
            api_version: api::API_VERSION,
            state: api_state(self.machine_state()),
            homed: self.homed().iter().copied().collect(),
            checking: self.checks.checking.as_ref().map(|c| c.path.clone()),
            machine_mm,
            work_mm: machine_mm.map(|m| offsets.work_mm(m)),
            distance_to_go_mm: self.distance_to_go_mm(s.as_ref()),
            coords: offsets.coords_name().to_string(),
            offsets: api::ActiveOffsets {
                g5x_mm: offsets.g5x_mm,
                rotation_deg: offsets.rotation_deg,
                g92_mm: offsets.g92_mm,
                tool_offset_mm: offsets.tool_mm,
            },
            // in a job: the tool in the spindle at the sample in use
            tool: around
                .as_ref()
                .map_or(offsets.tool, |a| a.0.tool_in_spindle),
            // the modal state the machine is in between programs (the last MDI
            // command's or job's end), as G-code words
            modal: self
                .setup
                .modal
                .as_deref()
                .map(|m| m.split_whitespace().map(String::from).collect()),
            // the outputs the position process has in force: in a job the sample in
            // use's, between jobs the last job's or MDI command's (held), off or
            // E-stopped the safe state; before its first status, the modal state's
            coolant: match s {
                Some(s) => {
                    let o: softnc_core::machine_io::MachineOutputs = s.outputs.into();
                    api::Coolant {
                        mist: o.coolant_mist,
                        flood: o.coolant_flood,
                    }
                }
                None => api::Coolant {
                    mist: modal_has("M7"),
                    flood: modal_has("M8"),
                },
            },
            params_error: self.setup.params_error.clone(),
            modal_error: self.setup.modal_error.clone(),
            // files of the data directory not written (retried), by what they hold
            unsaved: self.history.unsaved.to_api(),
            abandoned_checks: self.checks.abandoned_running() as u64,
            switches: api::Switches {
                single_block: self.machine.switches.single_block,
                optional_stop: self.machine.switches.optional_stop,
                block_delete: self.machine.switches.block_delete,
            },
            program_line: s.filter(|s| s.job_id != 0 && s.line != 0).map(|s| s.line),
            feed_override: self.machine.feed_override,
            rapid_override: self.machine.rapid_override,
            spindle_override: s.map(|s| s.spindle_override),
            spindle_rpm: s.map(|s| s.spindle_rpm),
            spindle: s.map(|s| {
                let inputs: softnc_core::machine_io::MachineInputs = s.inputs.into();
                let outputs: softnc_core::machine_io::MachineOutputs = s.outputs.into();
                let commanded_rpm = outputs.spindle_signed_rpm();
                api::Spindle {
                    commanded_rpm,
                    actual_rpm: inputs.spindle_rpm,
                    at_speed: inputs.spindle_at_speed,
                }
            }),
            tool_prepared: around.as_ref().map(|a| a.0.tool_prepared),
            limits_tripped: self.limits_tripped(),
            limits_overridden: self.machine.limits_overridden,
            pending: self.asked_pending().map(api_state),
            message: around.as_ref().and_then(|a| a.1.clone()),
            prompt: around.as_ref().and_then(|a| a.2.clone()),
            adaptive_force: s
                .filter(|s| s.job_id != 0 && s.force_override.is_finite())
                .map(|s| api::AdaptiveForce {
                    override_fraction: s.force_override,
                    revolutions: s.force_revolutions,
                    force_n: s.force_n.is_finite().then_some(s.force_n),
                }),
            job: job.map(|j| api::JobStatus {
                record: j.clone(),
                progress: j.progress(),
            }),
            axes: s.map(|s| api::AxesStatus {
                cmd_mm: s.cmd_mm[..3].to_vec(),
                actual_mm: s.actual_mm[..3].to_vec(),
                following_err_um: s.following_err_mm[..3].iter().map(|e| e * 1000.0).collect(),
                contour_err_um: s
                    .contour_err_mm
                    .is_finite()
                    .then_some(s.contour_err_mm * 1000.0),
                ring_fill: s.ring_fill,
            }),
            processes: api::Processes {
                interp: self.peer_status(ProcessId::Interp),
                position: self.peer_status(ProcessId::Position),
                supervisor: self.peer_status(ProcessId::Supervisor),
            },
            loops: api::Loops {
                interp: loops(ProcessId::Interp),
                position: loops(ProcessId::Position),
                bus: self.machine.loops[ProcessId::Position as usize]
                    .filter(|l| l.bus[0] > 0)
                    .map(|l| api::BusFigures {
                        frames: l.bus[0],
                        lost_frames: l.bus[1],
                        wkc_errors: l.bus[2],
                        send_to_receive_ns: api::Percentiles {
                            p50: l.bus[3],
                            p99: l.bus[4],
                            p999: 0,
                            max: l.bus[5],
                        },
                        dc_deviation_reads: l.bus[6],
                        dc_deviation_last_ns: l.bus[7],
                        dc_deviation_max_ns: l.bus[8],
                    }),
            },
            alarms: self
                .machine
                .alarms
                .iter()
                .rev()
                .take(10)
                .map(|a| api::Alarm {
                    code: api_alarm_kind(AlarmCode::from_wire(a.code).unwrap_or(AlarmCode::Other)),
                    job_id: a.job_id,
                    message: a.message.as_str().to_string(),
                })
                .collect(),
        }
    }
}

/// A reply as the wire carries it (`request`: the request it answers, for a reply
/// too large to send, which is replaced by one saying so: never cut short).
pub(crate) fn wire_reply(reply: &Reply, request: &str) -> OperatorReply {
    let text = softnc_api::encode_reply(reply, request, OperatorReply::MESSAGE_CAPACITY);
    let message = FixedStr::try_new(&text).unwrap_or_else(|e| {
        // encode_reply keeps within the capacity: not reached
        FixedStr::truncated(&format!(
            "{{\"reply\":\"refused\",\"body\":{{\"reason\":\"reply of {e} not sent\"}}}}"
        ))
    });
    OperatorReply { message }
}

/// The operator's name of a machine state.
fn api_state(s: MachineState) -> softnc_api::MachineState {
    use softnc_api::MachineState as A;
    match s {
        MachineState::Idle => A::Idle,
        MachineState::Running => A::Running,
        MachineState::Held => A::Held,
        MachineState::Faulted => A::Faulted,
        MachineState::EStopped => A::EStopped,
        MachineState::Stopping => A::Stopping,
        MachineState::Off => A::Off,
        MachineState::Homing => A::Homing,
        MachineState::Jogging => A::Jogging,
        MachineState::Paused => A::Paused,
        MachineState::Mdi => A::Mdi,
    }
}

/// Alarms raised outside any job (job id 0) that the record of a job running then
/// keeps: a process lost or started again, a loop's timing.
fn concerns_the_running_job(c: AlarmCode) -> bool {
    matches!(
        c,
        AlarmCode::ProcessLost
            | AlarmCode::ProcessRestarted
            | AlarmCode::LoopLate
            | AlarmCode::LoopStall
    )
}

/// The operator's kind of an alarm code.
fn api_alarm_kind(c: AlarmCode) -> softnc_api::AlarmKind {
    use softnc_api::AlarmKind as K;
    match c {
        AlarmCode::SequenceError => K::SequenceError,
        AlarmCode::RingDry => K::RingDry,
        AlarmCode::ProcessLost => K::ProcessLost,
        AlarmCode::FollowingError => K::FollowingError,
        AlarmCode::EStop => K::EStop,
        AlarmCode::JobRefused => K::JobRefused,
        AlarmCode::Note => K::Note,
        AlarmCode::PlanStarved => K::PlanStarved,
        AlarmCode::PlanFailed => K::PlanFailed,
        AlarmCode::MachineWait => K::MachineWait,
        AlarmCode::MachineOn => K::MachineOn,
        AlarmCode::LoopStall => K::LoopStall,
        AlarmCode::LoopLate => K::LoopLate,
        AlarmCode::ProcessRestarted => K::ProcessRestarted,
        AlarmCode::Other => K::Other,
    }
}

/// What an operator command does in a machine state (docs/operations.md): the next
/// state, or why it is refused (and nothing is sent).
pub fn transition(kind: ControlKind, state: MachineState) -> Result<MachineState, &'static str> {
    use ControlKind as K;
    use MachineState::*;
    match (kind, state) {
        (K::EStop, _) => Ok(EStopped),
        (K::MachineOn, Off) => Ok(Idle),
        (K::MachineOn, Faulted | EStopped) => Err("the machine needs a reset"),
        (K::MachineOn, _) => Err("the machine is on"),
        (K::MachineOff, Idle) => Ok(Off),
        (K::MachineOff, Off) => Err("the machine is off"),
        (K::MachineOff, Faulted | EStopped) => Err("the machine needs a reset"),
        (K::MachineOff, _) => Err("the axes are moving: stop them first"),
        (K::Home, Idle) => Ok(Homing),
        (K::Home, Homing) => Err("already homing"),
        (K::Jog, Idle | Jogging) => Ok(Jogging),
        (K::JogStep, Idle) => Ok(Jogging),
        (K::JogStep, Jogging) => Err("a jog is under way: stop it first"),
        (K::Hold, Running | Mdi) => Ok(Held),
        (K::Hold, Held) => Err("already held"),
        (K::Resume, Held | Paused) => Ok(Running),
        (K::Resume, _) => Err("nothing is held or paused"),
        (K::Step, Paused) => Ok(Running),
        (K::Step, _) => Err("nothing is paused at a block end"),
        (K::Abort, Running | Held | Paused | Mdi) => Ok(Stopping),
        (K::Abort, Homing | Jogging) => Ok(Idle),
        // nothing moves: the spindle and the coolant stop (LinuxCNC's task abort)
        (K::Abort, Idle) => Ok(Idle),
        (K::Abort, Stopping) => Err("already stopping"),
        // the latch cleared, the drives left off: `on` switches them on (LinuxCNC)
        (K::Reset, Faulted | EStopped) => Ok(Off),
        (K::Reset, Idle) => Ok(Idle),
        (K::Reset, Off) => Ok(Off),
        (K::Reset, Running | Held | Stopping | Paused | Mdi | Homing | Jogging) => {
            Err("the axes are moving: abort (stops along the path) or E-stop first")
        }
        // the state stays; refused without a tripped switch (`override_limits`)
        (K::OverrideLimits, Off | Idle | Jogging | Faulted | EStopped) => Ok(state),
        (_, Off) => Err("the machine is off"),
        (_, Idle) => Err("no job is running"),
        (_, Faulted | EStopped) => Err("the machine needs a reset"),
        (_, Stopping) => Err("the job is stopping"),
        (_, Homing) => Err("the axes are homing"),
        (_, Jogging) => Err("an axis is jogging"),
        (_, Running | Held | Paused | Mdi) => Err("a job is running"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ControlKind::*;
    use MachineState::*;

    #[test]
    fn every_command_in_every_state_goes_where_docs_operations_says_or_is_refused() {
        let states = [Idle, Running, Held, Stopping, Faulted, EStopped];
        let table: &[(ControlKind, [Option<MachineState>; 6])] = &[
            // Idle, Running, Held, Stopping, Faulted, EStopped
            (Hold, [None, Some(Held), None, None, None, None]),
            (Resume, [None, None, Some(Running), None, None, None]),
            (
                Abort,
                [Some(Idle), Some(Stopping), Some(Stopping), None, None, None],
            ),
            (EStop, [Some(EStopped); 6]),
            (Reset, [Some(Idle), None, None, None, Some(Off), Some(Off)]),
            // the state stays (the MMI refuses it without a tripped switch)
            (
                OverrideLimits,
                [Some(Idle), None, None, None, Some(Faulted), Some(EStopped)],
            ),
        ];
        for (kind, row) in table {
            for (state, want) in states.iter().zip(row) {
                let got = transition(*kind, *state);
                assert_eq!(got.ok(), *want, "{kind:?} in {state:?}: {got:?}");
            }
        }
        // a refusal says why
        assert!(transition(Reset, Running).unwrap_err().contains("abort"));
        // a reset never switches the drives on: after it, `on` is needed, and only
        // then does anything move
        for latched in [Faulted, EStopped] {
            let after = transition(Reset, latched).unwrap();
            assert_eq!(after, Off, "reset in {latched:?}");
            assert_eq!(transition(MachineOn, after), Ok(Idle));
            for moving in [Home, Jog, JogStep] {
                assert!(transition(moving, after).is_err(), "{moving:?} after reset");
            }
        }
        assert_eq!(transition(Reset, Off), Ok(Off));
        assert_eq!(transition(OverrideLimits, Off), Ok(Off));
        assert!(transition(Resume, Running)
            .unwrap_err()
            .contains("nothing is held"));
    }
}
