//! `softnc-mmi`: job queue, machine state, alarms, job history and the operator API
//! (iceoryx2 request-response). It checks a job completely — G-code, planning, soft
//! limits — before anything moves, and forwards operator commands to the
//! interpolation and position processes.

use crate::bus::{Bus, Pub, Sub};
use crate::config::Loaded;
use crate::interp::{check_bytes, JobSetup, Switches};
use crate::jobfile::intake;
use crate::lifecycle::StopWatch;
use crate::machine_store::{coords_number, offsets_json, MachineStore, Offsets};
use anyhow::{Context, Result};
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use serde::{Deserialize, Serialize};
use softnc_core::store::write_atomic;
use softnc_core::{Axes, MAX_AXES};
use softnc_ipc::{
    Alarm, AlarmCode, ControlCommand, ControlKind, FixedStr, Heartbeat, LoopStats, MachineState,
    OperatorReply, OperatorRequest, PositionStatus, ProcessId, JOB_ADAPTIVE_FORCE,
};
use softnc_planner::PlanStats;
use std::collections::VecDeque;
use std::time::{Duration, Instant, SystemTime};

/// One job in the history.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct JobRecord {
    /// Job id.
    pub job_id: u64,
    /// Program file.
    pub path: String,
    /// Submitted (seconds since the Unix epoch).
    pub submitted_unix_s: u64,
    /// "running", "completed", "aborted".
    pub outcome: String,
    /// Planned samples.
    pub planned_samples: u64,
    /// Cycles run.
    pub cycles: u64,
    /// Length of the planned path (mm).
    #[serde(default)]
    pub planned_path_mm: f64,
    /// How far along the planned path the position loop is (mm).
    #[serde(default)]
    pub path_mm: f64,
    /// Accuracy over the job's feed moves.
    pub accuracy: Accuracy,
    /// Remarks that are not alarms (a learned correction applied, faded out, …).
    #[serde(default)]
    pub notes: Vec<String>,
    /// The alarms raised while it ran ("Code: message"); kept when the operator
    /// clears the machine's alarms.
    #[serde(default)]
    pub alarms: Vec<String>,
    /// The immutable copy of the program that ran (`<data_dir>/programs/<sha256>.ngc`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub program: Option<String>,
    /// SHA-256 of the program that ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    /// The block(s) of an MDI command (`None`: a job from a file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mdi: Option<String>,
    /// The line a run-from-line job started at.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_line: Option<u32>,
    /// The job ran with adaptive feed (paper 003's force loop on the override).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub adaptive_force: bool,
}

impl JobRecord {
    /// How much of the job is done (0..=1): the position along the planned path
    /// (a completed job is done; a path of length 0, dwells only, counts cycles).
    pub fn progress(&self) -> f64 {
        let p = if self.outcome == "completed" {
            1.0
        } else if self.planned_path_mm > 0.0 {
            self.path_mm / self.planned_path_mm
        } else if self.planned_samples > 0 {
            self.cycles as f64 / self.planned_samples as f64
        } else {
            0.0
        };
        p.clamp(0.0, 1.0)
    }
}

/// Accuracy of a job, accumulated from the position status stream.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Accuracy {
    /// Largest |contour error| (µm).
    pub contour_max_abs_um: f64,
    /// RMS contour error (µm).
    pub contour_rms_um: f64,
    /// Largest |following error| per axis (µm).
    pub following_max_abs_um: Axes<f64>,
    #[serde(skip)]
    sum_sq: f64,
    #[serde(skip)]
    n: u64,
}

impl Accuracy {
    fn add(&mut self, s: &PositionStatus) {
        if s.contour_err_mm.is_finite() {
            let e = s.contour_err_mm * 1000.0;
            self.contour_max_abs_um = self.contour_max_abs_um.max(e.abs());
            self.sum_sq += e * e;
            self.n += 1;
            self.contour_rms_um = (self.sum_sq / self.n as f64).sqrt();
        }
        for (i, max_um) in self.following_max_abs_um.iter_mut().enumerate() {
            *max_um = max_um.max(s.following_err_mm[i].abs() * 1000.0);
        }
    }
}

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

/// The MMI process.
pub struct MmiTask {
    cfg: Loaded,
    server: Server<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
    control: Pub<ControlCommand>,
    status: Sub<PositionStatus>,
    heartbeats: Sub<Heartbeat>,
    alarms_sub: Sub<Alarm>,
    alarms_pub: Pub<Alarm>,
    loop_stats: Sub<LoopStats>,
    heartbeat: Pub<Heartbeat>,
    last: Option<PositionStatus>,
    peers: [Peer; 4],
    loops: [Option<LoopStats>; 4],
    alarms: VecDeque<Alarm>,
    jobs: Vec<JobRecord>,
    control_seq: u64,
    /// Job ids go on above this (an unreadable history's highest).
    job_id_floor: u64,
    /// When the running job's record was last written.
    last_save: Instant,
    feed_override: f64,
    hb_counter: u64,
    last_hb: Instant,
    shutdown: bool,
    /// The job an abort or a stop was asked for: it ends "aborted", not "completed".
    abort_asked: Option<u64>,
    /// A hold or an abort of the running job, accepted (Held, Stopping); cleared by
    /// resume and at the job's end.
    intent: Option<MachineState>,
    /// A submitted job being read and checked off the loop; answered when done.
    checking: Option<Checking>,
    /// The parameter file and the tool table.
    store: MachineStore,
    /// The machine's parameters as last saved (`None`: the profile's offsets).
    params: Option<softnc_gcode::Params>,
    /// Why the parameter file cannot be used: jobs, MDI and touch-off are refused.
    params_error: Option<String>,
    /// The running job's parameters and modal state at its end: kept when it
    /// completes.
    pending_params: Option<(u64, softnc_gcode::Params, String)>,
    /// The modal state (G-code) the last completed MDI command or job left: the
    /// next one starts with it, as in LinuxCNC.
    modal: Option<String>,
    /// The operator's program-flow switches.
    switches: Switches,
    /// A continuous jog's axis, speed and when its client last renewed it (the
    /// dead-man).
    jog_lease: Option<(u32, f64, Instant)>,
    stop: StopWatch,
    _bus: Bus,
}

type OperatorRequestIn =
    iceoryx2::active_request::ActiveRequest<ipc::Service, OperatorRequest, (), OperatorReply, ()>;

/// What the check of a submitted job gives: the program taken in, the path of its
/// copy, the plan's figures and the parameters as it leaves them; or why it is
/// refused.
type CheckResult = std::result::Result<
    (
        crate::jobfile::JobFile,
        String,
        PlanStats,
        softnc_gcode::Params,
        String,
    ),
    String,
>;

/// What is being checked.
#[derive(Debug, Clone, PartialEq)]
enum CheckKind {
    /// A job from a file (from a line).
    Job {
        from_line: Option<u32>,
        /// With adaptive feed.
        adaptive_force: bool,
    },
    /// MDI block(s).
    Mdi { text: String },
    /// A touch-off (a G10 L20 block: no motion).
    TouchOff { what: String },
}

/// A job being taken in (read once, copied, planned from the machine's position) on
/// a thread of its own: the loop goes on serving status, E-stop and heartbeats.
struct Checking {
    path: String,
    kind: CheckKind,
    /// The operator's request, answered when the check ends.
    request: Option<OperatorRequestIn>,
    result: std::sync::mpsc::Receiver<CheckResult>,
    /// An E-stop or a stop came while checking: the job is not started.
    cancelled: Option<&'static str>,
}

const ALARM_HISTORY: usize = 50;

impl MmiTask {
    /// Open the services and the job history.
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
        let modal = store.load_modal().unwrap_or_else(|e| {
            tracing::error!("{e}");
            None
        });
        let (params, params_error) = match store.load_params() {
            Ok(p) => (p, None),
            Err(e) => {
                tracing::error!("{e}");
                (None, Some(e))
            }
        };
        Ok(MmiTask {
            server,
            control: bus.control_publisher()?,
            status: bus.status_subscriber()?,
            heartbeats: bus.heartbeat_subscriber()?,
            alarms_sub: bus.alarm_subscriber()?,
            alarms_pub: bus.alarm_publisher()?,
            loop_stats: bus.loop_stats_subscriber()?,
            heartbeat: bus.heartbeat_publisher()?,
            cfg,
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
            jobs,
            control_seq: 0,
            job_id_floor,
            last_save: Instant::now(),
            feed_override: 1.0,
            hb_counter: 0,
            last_hb: Instant::now() - Duration::from_secs(1),
            shutdown: false,
            checking: None,
            store,
            params,
            params_error,
            pending_params: None,
            modal,
            switches: Switches::default(),
            jog_lease: None,
            abort_asked: None,
            intent: None,
            stop: StopWatch::manual(),
            _bus: bus,
        })
    }

    /// Stop when `stop` asks (SIGTERM/SIGINT, the supervisor's death).
    pub fn set_stop_watch(&mut self, stop: StopWatch) {
        self.stop = stop;
    }

    fn jobs_path(&self) -> std::path::PathBuf {
        self.cfg.data_dir.join("jobs.json")
    }

    fn save_jobs(&mut self) {
        self.last_save = Instant::now();
        let text = serde_json::to_vec_pretty(&self.jobs).unwrap_or_default();
        if let Err(e) = write_atomic(&self.jobs_path(), &text) {
            tracing::warn!(
                "cannot write job history {}: {e}",
                self.jobs_path().display()
            );
        }
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
        self.control_seq += 1;
        self.control.send_copy(ControlCommand {
            seq: self.control_seq,
            kind: kind.wire(),
            job_id,
            axis,
            value,
            flags,
            path: FixedStr::try_new(path)?,
        })?;
        Ok(())
    }

    /// The machine state as the position process reports it (off before it
    /// reports).
    pub fn position_state(&self) -> MachineState {
        self.last
            .and_then(|s| MachineState::from_wire(s.state))
            .unwrap_or(MachineState::Off)
    }

    /// A job is under way: started and not ended (also before its first sample).
    fn job_active(&self) -> bool {
        self.last.is_some_and(|s| s.job_id != 0) || self.jobs.iter().any(|j| j.outcome == "running")
    }

    /// The machine state the operator sees (docs/operations.md): the position
    /// process's, with a job's hold or stop along its path as asked for and accepted,
    /// or as the interpolator reports it (a stop on a signal), and faulted when the
    /// supervisor has given up on a process.
    pub fn machine_state(&self) -> MachineState {
        let pos = self.position_state();
        let supervisor = self.peers[ProcessId::Supervisor as usize];
        let supervisor_faulted = supervisor
            .last_seen
            .is_some_and(|t| t.elapsed().as_secs_f64() <= self.cfg.config.heartbeat_timeout_s)
            && supervisor.state == MachineState::Faulted.wire();
        // the position process's last word does not stand once it is gone
        let position_lost = self.peer_status(ProcessId::Position) == "lost";
        match pos {
            MachineState::Faulted | MachineState::EStopped => pos,
            _ if supervisor_faulted || position_lost => MachineState::Faulted,
            MachineState::Off | MachineState::Homing | MachineState::Jogging => pos,
            _ if self.job_active() => {
                let running = self.jobs.iter().rev().find(|j| j.outcome == "running");
                let mdi = running.is_some_and(|j| j.mdi.is_some());
                // the interpolator's word on this job (not a stale one on the last)
                let peer = self.peers[ProcessId::Interp as usize];
                let interp = MachineState::from_wire(peer.state)
                    .filter(|_| running.is_some_and(|j| j.job_id == peer.job_id));
                match (self.intent, interp) {
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

    fn running_job(&mut self) -> Option<&mut JobRecord> {
        self.jobs.iter_mut().rev().find(|j| j.outcome == "running")
    }

    /// Serve until a `Shutdown` request or a stop (signal, the supervisor's death),
    /// then until the running job has stopped (its record says how) or `stopping.record_wait_s`.
    pub fn run(&mut self) -> Result<()> {
        let mut stopping_since: Option<Instant> = None;
        loop {
            self.poll()?;
            if self.stop.requested().is_some() && !self.shutdown {
                self.shutdown = true;
                self.abort_asked = self.running_job().map(|j| j.job_id);
            }
            if self.shutdown {
                let since = *stopping_since.get_or_insert_with(Instant::now);
                let moving = self.last.is_some_and(|s| {
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
    pub fn poll(&mut self) -> Result<()> {
        let mut changed = false;
        while let Some(s) = self.status.receive()? {
            let s = *s;
            let prev_state = self.position_state();
            if s.job_id != 0 {
                // reattached after an MMI restart: the job is still running
                if let Some(j) = self
                    .jobs
                    .iter_mut()
                    .find(|j| j.job_id == s.job_id && j.outcome == "interrupted")
                {
                    j.outcome = "running".into();
                }
            }
            if let Some(job) = self.running_job() {
                if s.job_id == job.job_id {
                    job.accuracy.add(&s);
                    job.cycles = job.cycles.max(s.time_index + 1);
                    job.path_mm = job.path_mm.max(s.path_mm);
                }
            }
            self.last = Some(s);
            let now_state = self.position_state();
            if prev_state != now_state || s.job_id == 0 {
                let abort_asked = self.abort_asked;
                let mut ended = false;
                if let Some(job) = self.running_job() {
                    if matches!(now_state, MachineState::Faulted | MachineState::EStopped) {
                        job.outcome = "aborted".into();
                        ended = true;
                    } else if now_state == MachineState::Idle && s.job_id == 0 && job.cycles > 0 {
                        // stopped along its path by an abort or a stop: not completed
                        let aborted = abort_asked == Some(job.job_id);
                        job.outcome = if aborted { "aborted" } else { "completed" }.into();
                        ended = true;
                    }
                }
                if ended {
                    changed = true;
                    self.intent = None;
                    self.abort_asked = None;
                    self.keep_params_of_completed_job()?;
                }
            }
        }
        while let Some(h) = self.heartbeats.receive()? {
            if let Some(p) = self.peers.get_mut(h.process as usize) {
                if p.lost_pid == Some(h.pid) {
                    continue; // sent before it died
                }
                p.last_seen = Some(Instant::now());
                p.state = h.state;
                p.pid = h.pid;
                p.job_id = h.job_id;
            }
        }
        while let Some(a) = self.alarms_sub.receive()? {
            if a.code == AlarmCode::Note.wire() {
                // a remark for the job's record, not an alarm
                let (job_id, text) = (a.job_id, a.message.as_str().to_string());
                if let Some(j) = self.jobs.iter_mut().rev().find(|j| j.job_id == job_id) {
                    j.notes.push(text);
                    changed = true;
                }
                continue;
            }
            if a.code == AlarmCode::ProcessLost.wire() && a.process != ProcessId::Supervisor.wire()
            {
                // the process named is gone: not alive until its successor says so
                if let Some(p) = self.peers.get_mut(a.process as usize) {
                    p.lost_pid = Some(p.pid);
                    p.last_seen = None;
                }
                if a.process == ProcessId::Position.wire() {
                    // the servo loop died under the job: it ended there (faulted)
                    let alarm = format!("ProcessLost: {}", a.message.as_str());
                    if let Some(j) = self.running_job() {
                        j.outcome = "aborted".into();
                        if a.job_id != j.job_id {
                            j.alarms.push(alarm);
                        }
                        changed = true;
                    }
                    self.intent = None;
                    self.abort_asked = None;
                }
            }
            // kept in the record of the job it concerns; a job the interpolator
            // refused (its file changed after the check) never started
            let code = AlarmCode::from_wire(a.code).unwrap_or(AlarmCode::Other);
            if let Some(j) = self.jobs.iter_mut().rev().find(|j| j.job_id == a.job_id) {
                j.alarms.push(format!("{code:?}: {}", a.message.as_str()));
                if code == AlarmCode::JobRefused && j.outcome == "running" {
                    j.outcome = "refused".into();
                    self.intent = None;
                }
                changed = true;
            }
            if self.alarms.len() == ALARM_HISTORY {
                self.alarms.pop_front();
            }
            self.alarms.push_back(*a);
        }
        while let Some(l) = self.loop_stats.receive()? {
            if let Some(slot) = self.loops.get_mut(l.process as usize) {
                *slot = Some(*l);
            }
        }
        // the running job's record is written as it progresses (once a second)
        let running = self.jobs.iter().any(|j| j.outcome == "running");
        if changed
            || (running
                && self.last_save.elapsed().as_secs_f64() >= self.cfg.config.job_record_period_s)
        {
            self.save_jobs();
        }
        while let Some(req) = self.server.receive()? {
            let r = *req;
            match self.handle(&r)? {
                Some(reply) => {
                    req.send_copy(reply)?;
                }
                // a job taken in off the loop: answered when its check ends
                None => match self.checking.as_mut() {
                    Some(c) => c.request = Some(req),
                    None => {
                        req.send_copy(Self::reply(false, 0, "job not started"))?;
                    }
                },
            }
        }
        self.poll_checking()?;
        self.watch_jog()?;
        if self.last_hb.elapsed().as_secs_f64() >= self.cfg.config.heartbeat_period_s {
            self.hb_counter += 1;
            self.heartbeat.send_copy(Heartbeat {
                process: ProcessId::Mmi.wire(),
                pid: std::process::id(),
                counter: self.hb_counter,
                state: self.machine_state().wire(),
                job_id: self.last.map_or(0, |s| s.job_id),
            })?;
            self.last_hb = Instant::now();
        }
        Ok(())
    }

    /// A completed job's (or MDI's) parameters become the machine's: saved, and
    /// read back from the file (so that the next check and the interpolator's plan
    /// read the same values). An aborted job's are dropped.
    fn keep_params_of_completed_job(&mut self) -> Result<()> {
        let Some((job_id, params, modal)) = self.pending_params.take() else {
            return Ok(());
        };
        let completed = self
            .jobs
            .iter()
            .any(|j| j.job_id == job_id && j.outcome == "completed");
        if completed {
            self.save_params(&params)?;
            self.save_modal(modal);
        }
        Ok(())
    }

    /// The modal state a completed MDI command or job left becomes the machine's.
    fn save_modal(&mut self, modal: String) {
        if let Err(e) = self.store.save_modal(&modal) {
            tracing::warn!("modal state not kept: {e}");
        }
        self.modal = Some(modal);
    }

    fn save_params(&mut self, params: &softnc_gcode::Params) -> Result<()> {
        let saved = self
            .store
            .save_params(params)
            .and_then(|()| self.store.load_params());
        match saved {
            Ok(p) => {
                self.params = p;
                self.params_error = None;
            }
            Err(e) => {
                self.params_error = Some(e.clone());
                self.alarms_pub.send_copy(Alarm {
                    code: AlarmCode::Other.wire(),
                    axis: u32::MAX,
                    process: ProcessId::Mmi.wire(),
                    job_id: 0,
                    time_index: 0,
                    message: FixedStr::truncated(&format!("parameters not saved: {e}")),
                })?;
            }
        }
        Ok(())
    }

    /// A continuous jog whose client stopped renewing it is stopped (the dead-man).
    fn watch_jog(&mut self) -> Result<()> {
        let Some((axis, _, renewed)) = self.jog_lease else {
            return Ok(());
        };
        let age = renewed.elapsed().as_secs_f64();
        let jogging = self.position_state() == MachineState::Jogging;
        if !jogging && age > self.cfg.config.heartbeat_timeout_s {
            // it ended (a soft limit, an abort, a stop)
            self.jog_lease = None;
        } else if jogging && age > self.cfg.config.jog_deadman_s {
            self.jog_lease = None;
            self.send_control_axis(ControlKind::Jog, 0, axis, 0.0, "")?;
            let name = self.axis_name(axis);
            let deadman = self.cfg.config.jog_deadman_s;
            self.alarms_pub.send_copy(Alarm {
                code: AlarmCode::Other.wire(),
                axis,
                process: ProcessId::Mmi.wire(),
                job_id: 0,
                time_index: 0,
                message: FixedStr::truncated(&format!(
                    "jog of {name} stopped: its client did not renew it for {deadman} s"
                )),
            })?;
        }
        Ok(())
    }

    fn axis_name(&self, axis: u32) -> String {
        self.cfg
            .machine
            .axes
            .get(axis as usize)
            .map_or_else(|| format!("axis {axis}"), |a| a.name.clone())
    }

    /// Which axes are homed, as the position process reports them.
    pub fn homed(&self) -> Axes<bool> {
        let mask = self.last.map_or(0, |s| s.homed);
        Axes::from_fn(|a| mask & (1 << a.index()) != 0)
    }

    /// Why a job, MDI or touch-off cannot be taken in now, if it cannot.
    fn refuse_program(&self, state: MachineState, what: &str) -> Option<String> {
        if self.shutdown {
            return Some(format!("shutting down; {what} not started"));
        }
        if state == MachineState::Off {
            return Some(format!("the machine is off; {what} not started"));
        }
        if state != MachineState::Idle || self.job_active() {
            return Some(format!("machine is busy ({state:?}); {what} not started"));
        }
        if let Some(e) = &self.params_error {
            return Some(format!("{e}; {what} not started"));
        }
        let homed = self.homed();
        if homed.iter().any(|h| !h) {
            let missing: Vec<String> = (0..MAX_AXES)
                .filter(|&i| !homed[i])
                .map(|i| self.axis_name(i as u32))
                .collect();
            return Some(format!(
                "not homed ({}): home first (`softnc home`); {what} not started",
                missing.join(", ")
            ));
        }
        for p in [ProcessId::Interp, ProcessId::Position] {
            if self.peer_status(p) != "alive" {
                return Some(format!(
                    "the {} process is {}; {what} not started",
                    p.name(),
                    self.peer_status(p)
                ));
            }
        }
        if let Some(c) = &self.checking {
            return Some(format!("{} is being checked; {what} not started", c.path));
        }
        None
    }

    /// Read and check a program off the loop ([`Checking`]); answered when done.
    fn begin_check(&mut self, path: String, kind: CheckKind) -> Option<OperatorReply> {
        let limit = self.cfg.config.max_job_bytes;
        let programs = self.cfg.data_dir.join("programs");
        let machine = match self.store.profile(&self.cfg.machine) {
            Ok(m) => m,
            Err(e) => return Some(Self::reply(false, 0, &format!("{e}; nothing started"))),
        };
        // planned from where the machine is, with its offsets, as the interpolator
        // will plan it
        let setup = JobSetup {
            start_mm: self
                .last
                .map_or([0.0; 3], |s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]),
            params: self.params.clone(),
            switches: self.switches,
            from_line: match kind {
                CheckKind::Job { from_line, .. } => from_line,
                _ => None,
            },
            subroutine_path: self.cfg.subroutine_path.clone(),
            preamble: self.modal.clone(),
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let job_path = path.clone();
        let spawned = std::thread::Builder::new()
            .name("job-check".into())
            .spawn(move || {
                let _ = tx.send(check_job(&job_path, limit, &programs, &machine, &setup));
            });
        if let Err(e) = spawned {
            return Some(Self::reply(
                false,
                0,
                &format!("cannot check the job: {e}; job not started"),
            ));
        }
        self.checking = Some(Checking {
            path,
            kind,
            request: None,
            result: rx,
            cancelled: None,
        });
        None
    }

    /// MDI text (or a touch-off's block) as a program file the check takes in.
    fn mdi_file(&self, text: &str) -> std::result::Result<String, String> {
        let dir = self.cfg.data_dir.join("mdi");
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = dir.join("mdi.ngc");
        // between percent signs: the program ends without M2, whose reset of the
        // modal state (G54, G90, …) an MDI block must not make
        let program = format!("%\n{text}\n%\n");
        write_atomic(&path, program.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path.display().to_string())
    }

    /// The end of a job's check: start it (its record, the interpolator told) or
    /// refuse it, and answer the operator who submitted it.
    fn poll_checking(&mut self) -> Result<()> {
        let Some(c) = self.checking.as_mut() else {
            return Ok(());
        };
        if self.stop.requested().is_some() && c.cancelled.is_none() {
            c.cancelled = Some("the controller is stopping");
        }
        let result = match c.result.try_recv() {
            Ok(r) => r,
            Err(std::sync::mpsc::TryRecvError::Empty) => return Ok(()),
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                Err("the job's check ended without a result".to_string())
            }
        };
        let Some(c) = self.checking.take() else {
            return Ok(());
        };
        let path = c.path;
        let state = self.machine_state();
        let result = match (c.cancelled, result) {
            (Some(why), _) => Err(format!("{path}: {why}; not started")),
            (None, Ok(_)) if state != MachineState::Idle || self.job_active() => Err(format!(
                "{path}: the machine became {state:?} while it was checked; not started"
            )),
            (None, r) => r,
        };
        // an MDI command's errors name its blocks, not the file it was put in
        let result = match (&c.kind, result) {
            (CheckKind::Mdi { .. } | CheckKind::TouchOff { .. }, Err(msg)) => {
                Err(mdi_error(&path, &msg))
            }
            (_, r) => r,
        };
        let reply = match result {
            Err(msg) => {
                self.alarms_pub.send_copy(Alarm {
                    code: AlarmCode::JobRefused.wire(),
                    axis: u32::MAX,
                    process: ProcessId::Mmi.wire(),
                    job_id: 0,
                    time_index: 0,
                    message: FixedStr::truncated(&msg),
                })?;
                Self::reply(false, 0, &msg)
            }
            Ok((job, copy, stats, params, modal)) => {
                let job_id = self
                    .jobs
                    .iter()
                    .map(|j| j.job_id)
                    .max()
                    .unwrap_or(0)
                    .max(self.job_id_floor)
                    + 1;
                let submitted = SystemTime::now()
                    .duration_since(SystemTime::UNIX_EPOCH)
                    .map(|d| d.as_secs())
                    .unwrap_or(0);
                let (mdi, from_line, adaptive_force) = match &c.kind {
                    CheckKind::Job {
                        from_line,
                        adaptive_force,
                    } => (None, *from_line, *adaptive_force),
                    CheckKind::Mdi { text } => (Some(text.clone()), None, false),
                    CheckKind::TouchOff { what } => (Some(what.clone()), None, false),
                };
                // nothing to move (a G10, G92, G5x block, a touch-off): done here
                let moves = stats.moves > 0;
                self.jobs.push(JobRecord {
                    job_id,
                    path: path.clone(),
                    submitted_unix_s: submitted,
                    outcome: if moves { "running" } else { "completed" }.into(),
                    planned_samples: stats.samples,
                    cycles: 0,
                    planned_path_mm: stats.path_length_mm,
                    path_mm: 0.0,
                    accuracy: Accuracy::default(),
                    notes: Vec::new(),
                    alarms: Vec::new(),
                    program: Some(copy.clone()),
                    sha256: Some(job.sha256.clone()),
                    mdi,
                    from_line,
                    adaptive_force,
                });
                self.save_jobs();
                if !moves {
                    self.save_params(&params)?;
                    self.save_modal(modal);
                    let what = match &c.kind {
                        CheckKind::TouchOff { what } => what.clone(),
                        CheckKind::Mdi { .. } => format!("MDI {job_id}"),
                        CheckKind::Job { .. } => format!("job {job_id}"),
                    };
                    Self::reply(true, job_id, &format!("{what}: done (nothing to move)"))
                } else {
                    self.pending_params = Some((job_id, params, modal));
                    // the feed override is the machine's, not the job's: the job
                    // starts at the one in force (carried here, so a restarted
                    // interpolator knows it)
                    self.send_control_flags(
                        ControlKind::StartJob,
                        job_id,
                        from_line.unwrap_or(0),
                        self.feed_override,
                        if adaptive_force {
                            JOB_ADAPTIVE_FORCE
                        } else {
                            0
                        },
                        &copy,
                    )?;
                    let what = if matches!(c.kind, CheckKind::Job { .. }) {
                        "job"
                    } else {
                        "MDI"
                    };
                    Self::reply(true, job_id, &format!("{what} {job_id} started: {path}"))
                }
            }
        };
        if let Some(req) = c.request {
            // the operator may be gone (timed out): the job stands either way
            let _ = req.send_copy(reply);
        }
        Ok(())
    }

    /// A reply; one too long for the wire is refused whole, never cut.
    fn reply(accepted: bool, job_id: u64, msg: &str) -> OperatorReply {
        match FixedStr::try_new(msg) {
            Ok(message) => OperatorReply {
                accepted: accepted as u32,
                job_id,
                message,
            },
            Err(e) => OperatorReply {
                accepted: 0,
                job_id,
                message: FixedStr::truncated(&format!("reply not sent: {e}")),
            },
        }
    }

    /// The reply to a request; `None` when it is answered later (a job being
    /// checked, see [`Checking`]).
    fn handle(&mut self, r: &OperatorRequest) -> Result<Option<OperatorReply>> {
        let Some(kind) = ControlKind::from_wire(r.kind) else {
            return Ok(Some(Self::reply(false, 0, "unknown request")));
        };
        let state = self.machine_state();
        Ok(Some(match kind {
            ControlKind::StartJob => {
                let path = r.path.as_str().to_string();
                if let Some(why) = self.refuse_program(state, "job") {
                    return Ok(Some(Self::reply(false, 0, &why)));
                }
                // read once (a regular file under the limit), checked, and run from
                // its immutable copy; on a thread of its own (a long program takes a
                // while) — the loop goes on serving status and E-stop
                let from_line = (r.axis != 0 && r.axis != u32::MAX).then_some(r.axis);
                // adaptive feed: asked for, or the profile's default; only on a
                // machine whose profile has the force loop
                let adaptive_feed = self
                    .cfg
                    .machine
                    .force
                    .as_ref()
                    .and_then(|f| f.adaptive_feed.as_ref());
                let adaptive_force =
                    r.flags & JOB_ADAPTIVE_FORCE != 0 || adaptive_feed.is_some_and(|a| a.enabled);
                if adaptive_force && adaptive_feed.is_none() {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!(
                            "adaptive force refused: the machine profile {} has no force.adaptive_feed section; nothing started",
                            self.cfg.machine_path.display()
                        ),
                    )));
                }
                return Ok(self.begin_check(
                    path,
                    CheckKind::Job {
                        from_line,
                        adaptive_force,
                    },
                ));
            }
            ControlKind::Mdi => {
                let text = r.path.as_str().to_string();
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
            ControlKind::TouchOff => {
                let axes = self.cfg.machine.axes.len().min(3) as u32;
                if r.axis >= axes {
                    return Ok(Some(Self::reply(false, 0, "touch-off: no such axis")));
                }
                if !r.value.is_finite() {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        "touch-off: the value is not a number",
                    )));
                }
                let coords = r.path.as_str();
                let p = if coords.is_empty() {
                    0 // the active system
                } else {
                    match coords_number(coords) {
                        Some(n) => n,
                        None => {
                            return Ok(Some(Self::reply(
                                false,
                                0,
                                &format!(
                                "touch-off: {coords:?} is not a coordinate system (G54 … G59.3)"
                            ),
                            )))
                        }
                    }
                };
                if matches!(
                    state,
                    MachineState::Running
                        | MachineState::Held
                        | MachineState::Paused
                        | MachineState::Stopping
                        | MachineState::Mdi
                        | MachineState::Homing
                        | MachineState::Jogging
                ) {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!(
                            "touch-off refused ({state:?}): the axes are moving; touch off at rest"
                        ),
                    )));
                }
                if let Some(why) = self.refuse_program(state, "touch-off") {
                    return Ok(Some(Self::reply(false, 0, &why)));
                }
                let name = self.axis_name(r.axis);
                let block = format!("G10 L20 P{p} {name}{:.6}", r.value);
                let what = format!(
                    "touch-off {name} = {:.4} in {}",
                    r.value,
                    if p == 0 {
                        Offsets::from_params(self.params.as_ref(), &self.cfg.machine).coords_name()
                    } else {
                        crate::machine_store::coords_name(p)
                    }
                );
                let path = match self.mdi_file(&block) {
                    Ok(p) => p,
                    Err(e) => return Ok(Some(Self::reply(false, 0, &format!("touch-off: {e}")))),
                };
                return Ok(self.begin_check(path, CheckKind::TouchOff { what }));
            }
            ControlKind::Offsets => Self::reply(
                true,
                0,
                &offsets_json(
                    self.params.as_ref(),
                    self.modal.as_deref(),
                    &self.cfg.machine,
                )
                .to_string(),
            ),
            ControlKind::Tools => match self.store.load_tools(&self.cfg.machine) {
                Ok(t) => Self::reply(true, 0, &serde_json::to_string(&t).unwrap_or_default()),
                Err(e) => Self::reply(false, 0, &e),
            },
            ControlKind::ToolSet => {
                if self.job_active() || self.checking.is_some() {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        "tool table: a job is running; edit it between jobs",
                    )));
                }
                let diameter = r.path.as_str().trim();
                let diameter_mm: Option<f64> = if diameter.is_empty() {
                    None
                } else {
                    match diameter.parse::<f64>() {
                        Ok(d) if d.is_finite() && d >= 0.0 => Some(d),
                        _ => {
                            return Ok(Some(Self::reply(
                                false,
                                0,
                                &format!("tool table: diameter {diameter:?} is not a number ≥ 0"),
                            )))
                        }
                    }
                };
                if !r.value.is_finite() || r.axis == 0 || r.axis == u32::MAX {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        "tool table: a tool number > 0 and a finite length are needed",
                    )));
                }
                let mut tools = match self.store.load_tools(&self.cfg.machine) {
                    Ok(t) => t,
                    Err(e) => return Ok(Some(Self::reply(false, 0, &e))),
                };
                match tools.iter_mut().find(|t| t.number == r.axis) {
                    Some(t) => {
                        t.length_mm = r.value;
                        if let Some(d) = diameter_mm {
                            t.diameter_mm = d;
                        }
                    }
                    None => tools.push(softnc_core::config::ToolEntry {
                        number: r.axis,
                        length_mm: r.value,
                        diameter_mm: diameter_mm.unwrap_or(0.0),
                    }),
                }
                tools.sort_by_key(|t| t.number);
                match self.store.save_tools(&tools) {
                    Ok(()) => Self::reply(
                        true,
                        0,
                        &format!("tool {}: length {:.4} mm", r.axis, r.value),
                    ),
                    Err(e) => Self::reply(false, 0, &e),
                }
            }
            ControlKind::SingleBlock | ControlKind::OptionalStop | ControlKind::BlockDelete => {
                let on = r.value != 0.0;
                self.switches.apply(kind, r.value);
                self.send_control(kind, 0, if on { 1.0 } else { 0.0 }, "")?;
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
                Self::reply(
                    true,
                    0,
                    &format!("{name} {}{when}", if on { "on" } else { "off" }),
                )
            }
            ControlKind::MachineOn | ControlKind::MachineOff | ControlKind::Home => {
                match transition(kind, state) {
                    Err(why) => {
                        Self::reply(false, 0, &format!("{kind:?} refused ({state:?}): {why}"))
                    }
                    Ok(next) => {
                        let axes = self.cfg.machine.axes.len().min(3) as u32;
                        if kind == ControlKind::Home && r.axis != u32::MAX && r.axis >= axes {
                            return Ok(Some(Self::reply(false, 0, "home: no such axis")));
                        }
                        self.send_control_axis(kind, 0, r.axis, 0.0, "")?;
                        let what = match kind {
                            ControlKind::MachineOn => "machine on".to_string(),
                            ControlKind::MachineOff => "machine off".to_string(),
                            _ if r.axis == u32::MAX => "homing all axes".to_string(),
                            _ => format!("homing {}", self.axis_name(r.axis)),
                        };
                        Self::reply(true, 0, &format!("{what} ({next:?})"))
                    }
                }
            }
            ControlKind::Jog | ControlKind::JogStep => self.jog(kind, r, state)?,
            ControlKind::Step => match transition(kind, state) {
                Err(why) => Self::reply(false, 0, &format!("Step refused ({state:?}): {why}")),
                Ok(next) => {
                    let job_id = self.running_job().map_or(0, |j| j.job_id);
                    self.send_control(ControlKind::Step, 0, 0.0, "")?;
                    Self::reply(
                        true,
                        job_id,
                        &format!("job {job_id}: next block ({next:?})"),
                    )
                }
            },
            ControlKind::FeedOverride => {
                let max = self.cfg.machine.planner.max_feed_override;
                if !(0.0..=max).contains(&r.value) {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("override must be 0..={:.0} %", max * 100.0),
                    )));
                }
                self.feed_override = r.value;
                self.send_control(kind, 0, r.value, "")?;
                Self::reply(true, 0, &format!("feed override {:.0} %", r.value * 100.0))
            }
            ControlKind::SpindleOverride => {
                let range = self.cfg.machine.spindle;
                if !(range.min_override..=range.max_override).contains(&r.value) {
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
                self.send_control(kind, 0, r.value, "")?;
                Self::reply(
                    true,
                    0,
                    &format!("spindle override {:.0} %", r.value * 100.0),
                )
            }
            ControlKind::Hold
            | ControlKind::Resume
            | ControlKind::Abort
            | ControlKind::EStop
            | ControlKind::Reset => match transition(kind, state) {
                Err(why) => Self::reply(false, 0, &format!("{kind:?} refused ({state:?}): {why}")),
                Ok(next) => {
                    let job_id = self.running_job().map_or(0, |j| j.job_id);
                    match kind {
                        ControlKind::Hold => self.intent = Some(MachineState::Held),
                        ControlKind::Resume => self.intent = None,
                        ControlKind::Abort => {
                            self.intent = Some(MachineState::Stopping);
                            self.abort_asked = Some(job_id);
                        }
                        ControlKind::Reset => {
                            // acknowledged: the machine's list is cleared, the jobs'
                            // records keep theirs
                            self.alarms.clear();
                        }
                        ControlKind::EStop => {
                            if let Some(c) = self.checking.as_mut() {
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
                        ControlKind::Abort => format!("job {job_id} stopping along its path"),
                        ControlKind::EStop => "emergency stop".to_string(),
                        _ if state == MachineState::Idle => "alarms cleared".to_string(),
                        _ => "reset: alarms cleared".to_string(),
                    };
                    Self::reply(true, job_id, &format!("{what} ({next:?})"))
                }
            },
            ControlKind::Shutdown => {
                if let Some(c) = self.checking.as_mut() {
                    c.cancelled = Some("the controller is shutting down");
                }
                self.abort_asked = self.running_job().map(|j| j.job_id);
                self.send_control(kind, 0, 0.0, "")?;
                self.shutdown = true;
                Self::reply(true, 0, "shutting down")
            }
            ControlKind::Status => Self::reply(true, 0, &self.status_json().to_string()),
            ControlKind::Jobs => Self::reply(true, 0, &self.jobs_page(r.value)),
        }))
    }

    /// A continuous jog (speed in mm/min, 0 stops it; renewed by its client within
    /// `jog_deadman_s`) or an incremental one (a distance in mm), checked against the
    /// axis's limits and, once homed, its soft limits.
    fn jog(
        &mut self,
        kind: ControlKind,
        r: &OperatorRequest,
        state: MachineState,
    ) -> Result<OperatorReply> {
        let axes = self.cfg.machine.axes.len().min(3) as u32;
        if r.axis >= axes {
            return Ok(Self::reply(false, 0, "jog: no such axis"));
        }
        if !r.value.is_finite() {
            return Ok(Self::reply(false, 0, "jog: the value is not a number"));
        }
        let i = r.axis as usize;
        let a = self.cfg.machine.axes[i].clone();
        let name = a.name.clone();
        let homed = self.homed()[i];
        let pos_mm = self.last.map_or(0.0, |s| s.cmd_mm[i]);
        let deadman = self.cfg.config.jog_deadman_s;
        if kind == ControlKind::Jog {
            let speed = r.value;
            if speed == 0.0 {
                if state != MachineState::Jogging {
                    return Ok(Self::reply(
                        false,
                        0,
                        &format!("jog {name} 0: nothing is jogging"),
                    ));
                }
                self.jog_lease = None;
                self.send_control_axis(kind, 0, r.axis, 0.0, "")?;
                return Ok(Self::reply(true, 0, &format!("jog of {name} stopping")));
            }
            let max = a.max_vel_mm_per_s * 60.0;
            if speed.abs() > max {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog speed {speed} mm/min over {name}'s limit {max} mm/min"),
                ));
            }
            if let Some(lease) = self.jog_lease.as_mut() {
                if state == MachineState::Jogging && lease.0 == r.axis && lease.1 == speed {
                    lease.2 = Instant::now();
                    return Ok(Self::reply(true, 0, &format!("jog of {name} renewed")));
                }
            }
            if let Err(why) = transition(kind, state) {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog refused ({state:?}): {why}"),
                ));
            }
            if state == MachineState::Jogging && self.jog_lease.is_none_or(|l| l.0 != r.axis) {
                return Ok(Self::reply(
                    false,
                    0,
                    "another jog is under way: stop it first",
                ));
            }
            let at_limit =
                (speed > 0.0 && pos_mm >= a.max_mm) || (speed < 0.0 && pos_mm <= a.min_mm);
            if homed && at_limit {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog refused: {name} is at its soft limit ({pos_mm:.4} mm)"),
                ));
            }
            self.jog_lease = Some((r.axis, speed, Instant::now()));
            self.send_control_axis(kind, 0, r.axis, speed, "")?;
            let until = if homed {
                "to its soft limit"
            } else {
                "(not homed: no soft limits)"
            };
            return Ok(Self::reply(
                true,
                0,
                &format!(
                    "jogging {name} at {speed} mm/min {until}; renew within {deadman} s, `softnc jog {name} 0` stops"
                ),
            ));
        }
        // incremental
        if let Err(why) = transition(kind, state) {
            return Ok(Self::reply(
                false,
                0,
                &format!("jog refused ({state:?}): {why}"),
            ));
        }
        if r.value == 0.0 {
            return Ok(Self::reply(false, 0, "jog: a step of 0 mm"));
        }
        let target_mm = pos_mm + r.value;
        if homed && !(a.min_mm..=a.max_mm).contains(&target_mm) {
            return Ok(Self::reply(
                false,
                0,
                &format!(
                    "jog beyond the soft limit: {name} would reach {target_mm:.4} mm, outside [{}, {}] mm",
                    a.min_mm, a.max_mm
                ),
            ));
        }
        self.send_control_axis(kind, 0, r.axis, r.value, "")?;
        Ok(Self::reply(
            true,
            0,
            &format!("jogging {name} by {} mm to {target_mm:.4} mm", r.value),
        ))
    }

    /// "alive" (a heartbeat within the timeout), "lost" (silent, or reported lost and
    /// not yet back) or "unseen".
    fn peer_status(&self, p: ProcessId) -> &'static str {
        let timeout = self.cfg.config.heartbeat_timeout_s;
        match self.peers[p as usize].last_seen {
            Some(t) if t.elapsed().as_secs_f64() <= timeout => "alive",
            Some(_) => "lost",
            None if self.peers[p as usize].lost_pid.is_some() => "lost",
            None => "unseen",
        }
    }

    /// One page of the job history, newest first, from `offset` (skipped newest
    /// records): `{"total", "offset", "jobs"}` with as many records as fit a reply.
    pub fn jobs_page(&self, offset: f64) -> String {
        let total = self.jobs.len();
        let offset = if offset.is_finite() && offset > 0.0 {
            (offset as usize).min(total)
        } else {
            0
        };
        // room for the envelope; each record is added while the page still fits
        let cap = OperatorReply::MESSAGE_CAPACITY - 64;
        let mut body = String::from("[");
        for j in self.jobs.iter().rev().skip(offset) {
            let rec = serde_json::to_string(j).unwrap_or_default();
            if body.len() + rec.len() + 2 > cap && body.len() > 1 {
                break;
            }
            if body.len() > 1 {
                body.push(',');
            }
            body.push_str(&rec);
        }
        body.push(']');
        format!("{{\"total\":{total},\"offset\":{offset},\"jobs\":{body}}}")
    }

    /// The status the operator sees.
    pub fn status_json(&self) -> serde_json::Value {
        let peer = |p: ProcessId| self.peer_status(p);
        let loops = |p: ProcessId| {
            self.loops[p as usize].map(|l| {
                serde_json::json!({"cycles": l.cycles, "overruns": l.overruns,
                    "jitter_ns": {"p50": l.jitter_ns[0], "p99": l.jitter_ns[1], "p999": l.jitter_ns[2], "max": l.jitter_ns[3]},
                    "compute_ns": {"p50": l.compute_ns[0], "p99": l.compute_ns[1], "p999": l.compute_ns[2], "max": l.compute_ns[3]},
                    "latency_ns": {"p50": l.latency_ns[0], "p99": l.latency_ns[1], "p999": l.latency_ns[2], "max": l.latency_ns[3]}})
            })
        };
        let job = self
            .jobs
            .iter()
            .rev()
            .find(|j| j.outcome == "running")
            .or(self.jobs.last());
        let s = self.last;
        let offsets = Offsets::from_params(self.params.as_ref(), &self.cfg.machine)
            .with_modal(self.modal.as_deref());
        let machine_mm = s.map(|s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]);
        serde_json::json!({
            "state": format!("{:?}", self.machine_state()),
            "homed": self.homed(),
            "checking": self.checking.as_ref().map(|c| c.path.as_str()),
            "machine_mm": machine_mm,
            "work_mm": machine_mm.map(|m| offsets.work_mm(m)),
            "coords": offsets.coords_name(),
            "offsets": {"g5x_mm": offsets.g5x_mm, "rotation_deg": offsets.rotation_deg,
                "g92_mm": offsets.g92_mm, "tool_offset_mm": offsets.tool_mm},
            "tool": offsets.tool,
            // the modal state the machine is in between programs (the last MDI
            // command's or job's end), as G-code words
            "modal": self.modal.as_deref().map(|m| m.split_whitespace().collect::<Vec<_>>()),
            "coolant": {
                "mist": self.modal.as_deref().is_some_and(|m| m.lines().any(|l| l.trim() == "M7")),
                "flood": self.modal.as_deref().is_some_and(|m| m.lines().any(|l| l.trim() == "M8")),
            },
            "params_error": self.params_error,
            "switches": {"single_block": self.switches.single_block,
                "optional_stop": self.switches.optional_stop,
                "block_delete": self.switches.block_delete},
            "program_line": s.filter(|s| s.job_id != 0 && s.line != 0).map(|s| s.line),
            "feed_override": self.feed_override,
            "spindle_override": s.map(|s| s.spindle_override),
            "spindle_rpm": s.map(|s| s.spindle_rpm),
            "adaptive_force": s.filter(|s| s.job_id != 0 && s.force_override.is_finite()).map(|s| serde_json::json!({
                "override": s.force_override,
                "revolutions": s.force_revolutions,
                "force_n": s.force_n.is_finite().then_some(s.force_n),
            })),
            "job": job.map(|j| serde_json::json!({
                "job_id": j.job_id, "path": j.path, "outcome": j.outcome,
                "program": j.program, "mdi": j.mdi, "from_line": j.from_line,
                "adaptive_force": j.adaptive_force,
                "cycles": j.cycles, "planned_samples": j.planned_samples,
                "path_mm": j.path_mm, "planned_path_mm": j.planned_path_mm,
                "progress": j.progress(),
                "accuracy": j.accuracy,
                "notes": j.notes,
            })),
            "axes": s.map(|s| serde_json::json!({
                "cmd_mm": &s.cmd_mm[..3], "actual_mm": &s.actual_mm[..3],
                "following_err_um": s.following_err_mm[..3].iter().map(|e| e * 1000.0).collect::<Vec<_>>(),
                "contour_err_um": if s.contour_err_mm.is_finite() { Some(s.contour_err_mm * 1000.0) } else { None },
                "ring_fill": s.ring_fill,
            })),
            "processes": {"interp": peer(ProcessId::Interp), "position": peer(ProcessId::Position), "supervisor": peer(ProcessId::Supervisor)},
            "loops": {"interp": loops(ProcessId::Interp), "position": loops(ProcessId::Position)},
            "alarms": self.alarms.iter().rev().take(10).map(|a| serde_json::json!({
                "code": format!("{:?}", AlarmCode::from_wire(a.code).unwrap_or(AlarmCode::Other)),
                "job_id": a.job_id, "message": a.message.as_str()})).collect::<Vec<_>>(),
        })
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
        (K::Abort, Stopping) => Err("already stopping"),
        (K::Reset, Faulted | EStopped) => Ok(Idle),
        (K::Reset, Idle) => Ok(Idle),
        (K::Reset, Off) => Ok(Off),
        (K::Reset, Running | Held | Stopping | Paused | Mdi | Homing | Jogging) => {
            Err("the axes are moving: abort (stops along the path) or E-stop first")
        }
        (_, Off) => Err("the machine is off"),
        (_, Idle) => Err("no job is running"),
        (_, Faulted | EStopped) => Err("the machine needs a reset"),
        (_, Stopping) => Err("the job is stopping"),
        (_, Homing) => Err("the axes are homing"),
        (_, Jogging) => Err("an axis is jogging"),
        (_, Running | Held | Paused | Mdi) => Err("a job is running"),
    }
}

/// An error of the MDI file `path` (`path:LINE:COL: why`, its first line the `%`
/// that opens it) as the operator's blocks: `MDI block N, column C: why`.
fn mdi_error(path: &str, msg: &str) -> String {
    let located = msg.strip_prefix(path).and_then(|rest| {
        let mut parts = rest.strip_prefix(':')?.splitn(3, ':');
        let line: u32 = parts.next()?.parse().ok()?;
        let col: u32 = parts.next()?.parse().ok()?;
        Some((line, col, parts.next()?.trim_start()))
    });
    match located {
        Some((line, col, why)) if line >= 2 => {
            format!("MDI block {}, column {col}: {why}", line - 1)
        }
        Some((_, _, why)) => format!("MDI: {why}"),
        None => format!("MDI: {msg}"),
    }
}

/// The job history in `path`, and the highest job id it ever used. An unreadable
/// file is kept aside (`jobs.json.unreadable-<unix s>`) and a new history started;
/// job ids go on from the highest one found in it.
fn load_jobs(path: &std::path::Path) -> (Vec<JobRecord>, u64) {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return (Vec::new(), 0),
        Err(e) => {
            tracing::error!("{}: cannot read the job history: {e}", path.display());
            return (Vec::new(), 0);
        }
    };
    match serde_json::from_slice::<Vec<JobRecord>>(&bytes) {
        Ok(mut jobs) => {
            // a job "running" when the MMI last stopped did not finish under it
            for j in jobs.iter_mut().filter(|j| j.outcome == "running") {
                j.outcome = "interrupted".into();
            }
            let max = jobs.iter().map(|j| j.job_id).max().unwrap_or(0);
            (jobs, max)
        }
        Err(e) => {
            let stamp = SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0);
            let aside = path.with_extension(format!("json.unreadable-{stamp}"));
            match std::fs::rename(path, &aside) {
                Ok(()) => tracing::error!(
                    "{}: unreadable job history ({e}); kept as {}, starting a new one",
                    path.display(),
                    aside.display()
                ),
                Err(re) => tracing::error!(
                    "{}: unreadable job history ({e}), and it cannot be kept aside ({re})",
                    path.display()
                ),
            }
            (Vec::new(), highest_job_id(&String::from_utf8_lossy(&bytes)))
        }
    }
}

/// The highest `"job_id": N` in a history that no longer parses.
fn highest_job_id(text: &str) -> u64 {
    text.match_indices("\"job_id\"")
        .filter_map(|(i, k)| {
            let rest = text[i + k.len()..]
                .trim_start()
                .strip_prefix(':')?
                .trim_start();
            let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
            digits.parse().ok()
        })
        .max()
        .unwrap_or(0)
}

/// Take a submitted job in: read once (a regular file under `limit`), stored as an
/// immutable copy under `programs`, planned as `setup` says (from where the machine
/// is, with its offsets) as the interpolator will plan it, with the parameters it
/// leaves. Runs off the MMI's loop.
fn check_job(
    path: &str,
    limit: u64,
    programs: &std::path::Path,
    machine: &softnc_core::MachineProfile,
    setup: &JobSetup,
) -> CheckResult {
    let job = intake(path, limit, programs).map_err(|e| e.to_string())?;
    // checked as it will be streamed: the plan's figures, never the whole plan
    let (_, _, checked, modal) = check_bytes(&job.bytes, path, machine, setup)?;
    let params = checked.end_params().clone();
    let copy = job.copy.display().to_string();
    if !FixedStr::<512>::fits(&copy) {
        return Err(format!(
            "{copy}: the job's copy has a path over 512 bytes (data_dir too deep)"
        ));
    }
    Ok((job, copy, checked.stats(), params, modal))
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
                [None, Some(Stopping), Some(Stopping), None, None, None],
            ),
            (EStop, [Some(EStopped); 6]),
            (
                Reset,
                [Some(Idle), None, None, None, Some(Idle), Some(Idle)],
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
        assert!(transition(Resume, Running)
            .unwrap_err()
            .contains("nothing is held"));
    }

    #[test]
    fn mdi_errors_name_the_operators_blocks() {
        let p = "/d/mdi/mdi.ngc";
        assert_eq!(
            mdi_error(p, &format!("{p}:3:7: Failed to find sub")),
            "MDI block 2, column 7: Failed to find sub"
        );
        assert_eq!(mdi_error(p, "cannot read"), "MDI: cannot read");
    }

    #[test]
    fn an_unreadable_history_is_kept_aside_and_job_ids_go_on() {
        let dir = std::env::temp_dir().join(format!("softnc-jobs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("jobs.json");
        let whole = r#"[{"job_id": 50, "path": "a.ngc"}, {"job_id": 51, "path": "b.ngc"}]"#;
        let cut = &whole[..whole.len() - 8];
        std::fs::write(&path, cut).unwrap();
        let (jobs, floor) = load_jobs(&path);
        assert!(jobs.is_empty());
        assert_eq!(floor, 51);
        let kept: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with("jobs.json.unreadable-")
            })
            .collect();
        assert_eq!(kept.len(), 1, "kept aside");
        assert_eq!(std::fs::read_to_string(kept[0].path()).unwrap(), cut);
        assert!(!path.exists(), "a new history starts");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
