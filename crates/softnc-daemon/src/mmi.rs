//! `softnc-mmi`: job queue, machine state, alarms, job history and the operator API
//! (iceoryx2 request-response). It checks a job completely — G-code, planning, soft
//! limits — before anything moves, and forwards operator commands to the
//! interpolation and position processes.

use crate::bus::{Bus, Pub, Sub};
use crate::config::Loaded;
use crate::interp::check_bytes;
use crate::jobfile::intake;
use crate::lifecycle::StopWatch;
use anyhow::{Context, Result};
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use serde::{Deserialize, Serialize};
use softnc_core::store::write_atomic;
use softnc_ipc::{
    Alarm, AlarmCode, ControlCommand, ControlKind, FixedStr, Heartbeat, LoopStats, MachineState,
    OperatorReply, OperatorRequest, PositionStatus, ProcessId,
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
    pub following_max_abs_um: [f64; 3],
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
        for i in 0..3 {
            self.following_max_abs_um[i] =
                self.following_max_abs_um[i].max(s.following_err_mm[i].abs() * 1000.0);
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
    stop: StopWatch,
    _bus: Bus,
}

type OperatorRequestIn =
    iceoryx2::active_request::ActiveRequest<ipc::Service, OperatorRequest, (), OperatorReply, ()>;

/// What the check of a submitted job gives: the program taken in, the path of its
/// copy and the plan's figures; or why it is refused.
type CheckResult = std::result::Result<(crate::jobfile::JobFile, String, PlanStats), String>;

/// A job being taken in (read once, copied, planned from the machine's position) on
/// a thread of its own: the loop goes on serving status, E-stop and heartbeats.
struct Checking {
    path: String,
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
        self.control_seq += 1;
        self.control.send_copy(ControlCommand {
            seq: self.control_seq,
            kind: kind.wire(),
            job_id,
            value,
            path: FixedStr::try_new(path)?,
        })?;
        Ok(())
    }

    /// The machine state as the position process reports it (Idle before it reports).
    pub fn position_state(&self) -> MachineState {
        self.last
            .and_then(|s| MachineState::from_wire(s.state))
            .unwrap_or(MachineState::Idle)
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
            _ if self.job_active() => {
                let interp = MachineState::from_wire(self.peers[ProcessId::Interp as usize].state);
                match (self.intent, interp) {
                    (Some(i), _) => i,
                    (None, Some(MachineState::Stopping)) => MachineState::Stopping,
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
            (Some(why), _) => Err(format!("{path}: {why}; job not started")),
            (None, Ok(_)) if state != MachineState::Idle || self.job_active() => Err(format!(
                "{path}: the machine became {state:?} while it was checked; job not started"
            )),
            (None, r) => r,
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
            Ok((job, copy, stats)) => {
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
                self.jobs.push(JobRecord {
                    job_id,
                    path: path.clone(),
                    submitted_unix_s: submitted,
                    outcome: "running".into(),
                    planned_samples: stats.samples,
                    cycles: 0,
                    planned_path_mm: stats.path_length_mm,
                    path_mm: 0.0,
                    accuracy: Accuracy::default(),
                    notes: Vec::new(),
                    alarms: Vec::new(),
                    program: Some(copy.clone()),
                    sha256: Some(job.sha256.clone()),
                });
                self.save_jobs();
                // the feed override is the machine's, not the job's: the job starts at
                // the one in force (carried here, so a restarted interpolator knows it)
                self.send_control(ControlKind::StartJob, job_id, self.feed_override, &copy)?;
                Self::reply(true, job_id, &format!("job {job_id} started: {path}"))
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
                if self.shutdown {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        "shutting down; job not started",
                    )));
                }
                if state != MachineState::Idle || self.job_active() {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("machine is busy ({state:?}); job not started"),
                    )));
                }
                for p in [ProcessId::Interp, ProcessId::Position] {
                    if self.peer_status(p) != "alive" {
                        return Ok(Some(Self::reply(
                            false,
                            0,
                            &format!(
                                "the {} process is {}; job not started",
                                p.name(),
                                self.peer_status(p)
                            ),
                        )));
                    }
                }
                if let Some(c) = &self.checking {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("{} is being checked; job not started", c.path),
                    )));
                }
                // read once (a regular file under the limit), checked, and run from
                // its immutable copy; on a thread of its own (a long program takes a
                // while) — the loop goes on serving status and E-stop
                let limit = self.cfg.config.max_job_bytes;
                let programs = self.cfg.data_dir.join("programs");
                let machine = self.cfg.machine.clone();
                // planned from where the machine is, as the interpolator plans it
                let start_mm = self
                    .last
                    .map_or([0.0; 3], |s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]);
                let (tx, rx) = std::sync::mpsc::channel();
                let job_path = path.clone();
                let spawned =
                    std::thread::Builder::new()
                        .name("job-check".into())
                        .spawn(move || {
                            let _ =
                                tx.send(check_job(&job_path, limit, &programs, &machine, start_mm));
                        });
                if let Err(e) = spawned {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("cannot check the job: {e}; job not started"),
                    )));
                }
                self.checking = Some(Checking {
                    path,
                    request: None,
                    result: rx,
                    cancelled: None,
                });
                return Ok(None);
            }
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
        serde_json::json!({
            "state": format!("{:?}", self.machine_state()),
            "checking": self.checking.as_ref().map(|c| c.path.as_str()),
            "machine_mm": s.map(|s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]),
            "program_line": s.filter(|s| s.job_id != 0 && s.line != 0).map(|s| s.line),
            "feed_override": self.feed_override,
            "spindle_override": s.map(|s| s.spindle_override),
            "spindle_rpm": s.map(|s| s.spindle_rpm),
            "job": job.map(|j| serde_json::json!({
                "job_id": j.job_id, "path": j.path, "outcome": j.outcome,
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
    use MachineState::*;
    match (kind, state) {
        (ControlKind::EStop, _) => Ok(EStopped),
        (ControlKind::Hold, Running) => Ok(Held),
        (ControlKind::Hold, Held) => Err("already held"),
        (ControlKind::Resume, Held) => Ok(Running),
        (ControlKind::Resume, _) => Err("nothing is held"),
        (ControlKind::Abort, Running | Held) => Ok(Stopping),
        (ControlKind::Abort, Stopping) => Err("already stopping"),
        (ControlKind::Reset, Faulted | EStopped) => Ok(Idle),
        (ControlKind::Reset, Idle) => Ok(Idle),
        (ControlKind::Reset, Running | Held | Stopping) => {
            Err("a job is moving: abort it (stops along the path) or E-stop first")
        }
        (_, Idle) => Err("no job is running"),
        (_, Faulted | EStopped) => Err("the machine needs a reset"),
        (_, Stopping) => Err("the job is stopping"),
        _ => Err("not in this state"),
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
/// immutable copy under `programs`, planned from `start_mm` as the interpolator will
/// plan it. Runs off the MMI's loop.
fn check_job(
    path: &str,
    limit: u64,
    programs: &std::path::Path,
    machine: &softnc_core::MachineProfile,
    start_mm: [f64; 3],
) -> CheckResult {
    let job = intake(path, limit, programs).map_err(|e| e.to_string())?;
    // checked as it will be streamed: the plan's figures, never the whole plan
    let (_, _, checked) = check_bytes(&job.bytes, path, machine, start_mm)?;
    let copy = job.copy.display().to_string();
    if !FixedStr::<512>::fits(&copy) {
        return Err(format!(
            "{copy}: the job's copy has a path over 512 bytes (data_dir too deep)"
        ));
    }
    Ok((job, copy, checked.stats()))
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
