//! `softncd`: starts the three processes, watches them, restarts or stops them.
//!
//! - `softnc-interp` exits: the position process runs its ring dry and stops along the
//!   path (it raises the alarm); the supervisor restarts the interpolator so that a
//!   new job can run after a reset.
//! - `softnc-position` exits: the machine is faulted. The supervisor raises an alarm,
//!   removes the dead node's shared-memory resources and restarts the position
//!   process only on the operator's `reset`.
//! - `softnc-mmi` exits: motion continues; the supervisor restarts the MMI, which
//!   reattaches to the running job.
//! - `softnc-web` (the web operator panel, when the configuration has `web`) exits:
//!   nothing else is touched (it is an operator client of the MMI, outside the
//!   real-time path); it is restarted with the same back-off, and past the limit left
//!   down with an alarm, the machine not faulted. It sends no heartbeat: only its
//!   exit is watched. Its alarms are `Other` (not a running job's).
//! - Every death is a `ProcessLost` alarm and every restart a `ProcessRestarted`
//!   one; the alarm service keeps the last alarms (its history) and the supervisor
//!   delivers them to every new subscriber as it appears, so a restarted MMI learns
//!   of its predecessor's death and shows it (status, TUI, the running job's record).
//! - A child silent (no heartbeat) past `supervisor.watchdog_s` — hung, or stopped
//!   with SIGSTOP — is killed and handled as dead. Restarts back off (doubling from
//!   `restart_delay_s`); past `restart_limit` restarts in `restart_window_s` the
//!   process is left down and the machine faulted with an alarm naming it, until
//!   `reset`.
//! - One `softncd` per instance ([`crate::lifecycle::InstanceLock`]); SIGTERM/SIGINT
//!   or a `Shutdown` command: the children are told to stop (a running job
//!   decelerates along its path), given `stopping.children_grace_s`, then killed; exit 0.
//!   Children stop by themselves when `softncd` dies (`kill -9`).
//! - systemd: `READY=1` once every child has sent a heartbeat, `WATCHDOG=1` at half
//!   `WatchdogSec`, `STOPPING=1` ([`crate::lifecycle::Notify`]).

use crate::config::Loaded;
use crate::lifecycle::{InstanceLock, Notify, StopWatch};
use anyhow::{Context, Result};
use iceoryx2::port::update_connections::UpdateConnections;
use softnc_ipc::bus::{clean_dead_nodes, Bus, Pub, Sub};
use softnc_ipc::{
    Alarm, AlarmCode, ControlCommand, ControlKind, FixedStr, Heartbeat, MachineState, ProcessId,
};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// How often the supervisor looks at its children.
const WATCH_PERIOD: Duration = Duration::from_millis(20);

/// The web operator panel's binary.
const WEB_PANEL: &str = "softnc-web";

struct Proc {
    name: &'static str,
    id: ProcessId,
    child: Option<Child>,
    /// When the running child was started.
    started: Instant,
    /// Its last heartbeat (None: none yet).
    last_hb: Option<Instant>,
    /// The job its last heartbeat named (0: none): the job its death concerns.
    last_job: u64,
    /// Restarts within the configured window.
    restarts: VecDeque<Instant>,
    /// A restart waiting out its back-off.
    restart_at: Option<Instant>,
    /// Restarted too often: left down until `reset`.
    given_up: bool,
    /// Started at least once: the next start is a restart.
    started_once: bool,
    /// The web panel: no heartbeat, its death faults nothing (module docs).
    panel: bool,
}

/// The supervisor.
pub struct Supervisor {
    cfg: Loaded,
    bin_dir: PathBuf,
    procs: Vec<Proc>,
    control_sub: Sub<ControlCommand>,
    control_pub: Pub<ControlCommand>,
    heartbeats: Sub<Heartbeat>,
    alarms: Pub<Alarm>,
    heartbeat: Pub<Heartbeat>,
    faulted: bool,
    hb_counter: u64,
    last_hb: Instant,
    stop: StopWatch,
    notify: Notify,
    bus: Bus,
    /// The operator group's socket, served while the supervisor lives (dropped
    /// before the lock: its socket is removed first).
    _gateway: Option<crate::operator_gateway::Gateway>,
    /// Held for the supervisor's life: one controller per instance.
    _lock: InstanceLock,
}

impl Supervisor {
    /// Prepare: take the instance's lock (a second controller of the instance is
    /// refused before it touches anything), catch SIGTERM/SIGINT, clean stale
    /// resources of a previous run, open the services, serve the operator gateway
    /// when the configuration has an operator group.
    pub fn new(cfg: Loaded) -> Result<Self> {
        let lock = InstanceLock::acquire(
            &cfg.data_dir,
            &cfg.config.service_prefix,
            &cfg.config.instance,
        )?;
        let stop = StopWatch::start(false).context("signal watcher")?;
        let cleaned = clean_dead_nodes();
        if cleaned > 0 {
            tracing::info!("removed stale resources of {cleaned} dead node(s)");
        }
        let names = softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance);
        let bus = Bus::new(names, "supervisor")?;
        let gateway = crate::operator_gateway::Gateway::start(&cfg)?;
        let bin_dir = std::env::current_exe()
            .context("locating softncd")?
            .parent()
            .map(PathBuf::from)
            .unwrap_or_default();
        let p = |name, id| Proc {
            name,
            id,
            child: None,
            started: Instant::now(),
            last_hb: None,
            last_job: 0,
            restarts: VecDeque::new(),
            started_once: false,
            restart_at: None,
            given_up: false,
            panel: false,
        };
        let mut procs = vec![
            p("softnc-mmi", ProcessId::Mmi),
            p("softnc-position", ProcessId::Position),
            p("softnc-interp", ProcessId::Interp),
        ];
        if cfg.config.web.is_some() {
            procs.push(Proc {
                panel: true,
                ..p(WEB_PANEL, ProcessId::Supervisor)
            });
        }
        Ok(Supervisor {
            procs,
            control_sub: bus.control_subscriber()?,
            control_pub: bus.control_publisher()?,
            heartbeats: bus.heartbeat_subscriber()?,
            alarms: bus.alarm_publisher()?,
            heartbeat: bus.heartbeat_publisher()?,
            cfg,
            bin_dir,
            faulted: false,
            hb_counter: 0,
            last_hb: Instant::now() - Duration::from_secs(1),
            stop,
            notify: Notify::from_env(),
            bus,
            _gateway: gateway,
            _lock: lock,
        })
    }

    /// Start process `i`; the web panel's failure to start is an alarm (it is left
    /// down until `reset`), not the supervisor's error.
    fn spawn(&mut self, i: usize) -> Result<()> {
        match self.spawn_process(i) {
            Err(e) if self.procs[i].panel => {
                self.procs[i].given_up = true;
                self.alarm(
                    AlarmCode::Other,
                    ProcessId::Supervisor,
                    0,
                    &format!("{WEB_PANEL} not started: {e:#}"),
                );
                Ok(())
            }
            r => r,
        }
    }

    fn spawn_process(&mut self, i: usize) -> Result<()> {
        let exe = self.bin_dir.join(self.procs[i].name);
        let mut cmd = Command::new(&exe);
        cmd.arg("--config").arg(&self.cfg.path);
        if self.procs[i].started_once {
            // a restart under a running controller (the position process then comes
            // back with its drives on, as the machine was)
            cmd.env(crate::cli::RESTARTED_ENV, "1");
        }
        let child = cmd
            .spawn()
            .with_context(|| format!("starting {}", exe.display()))?;
        let pid = child.id();
        let p = &mut self.procs[i];
        let restart = p.started_once;
        p.child = Some(child);
        p.started_once = true;
        p.started = Instant::now();
        p.last_hb = None;
        p.restart_at = None;
        if restart {
            let (name, id) = (p.name, p.id);
            let code = if p.panel {
                AlarmCode::Other
            } else {
                AlarmCode::ProcessRestarted
            };
            self.alarm(
                code,
                id,
                pid,
                &format!("{name} started again (pid {pid}) after it was lost"),
            );
        }
        Ok(())
    }

    /// An alarm about process `about` (a `ProcessLost` names the process lost and
    /// its pid `pid`).
    fn alarm(&mut self, code: AlarmCode, about: ProcessId, pid: u32, msg: &str) {
        self.job_alarm(code, about, pid, 0, msg);
    }

    /// [`Self::alarm`] about job `job_id` (the MMI keeps it in that job's record).
    fn job_alarm(&mut self, code: AlarmCode, about: ProcessId, pid: u32, job_id: u64, msg: &str) {
        tracing::warn!("{msg}");
        let _ = self.alarms.send_copy(Alarm {
            code: code.wire(),
            axis: u32::MAX,
            process: about.wire(),
            job_id,
            time_index: 0,
            message: FixedStr::truncated(msg),
            pid,
            raised_unix_ns: softnc_rt::unix_ns(),
        });
    }

    /// Start everything and watch until shutdown (SIGINT/SIGTERM or a `Shutdown`
    /// control command): exits, heartbeats (a child silent past the watchdog is
    /// killed and handled as dead), restarts with back-off and a limit.
    pub fn run(&mut self) -> Result<()> {
        for i in 0..self.procs.len() {
            self.spawn(i)?;
        }
        tracing::info!("softncd running: {}", self.cfg.path.display());
        let mut ready = false;
        let mut last_watchdog = Instant::now();
        loop {
            let _ = self.bus.node.wait(WATCH_PERIOD);
            if let Some(why) = self.stop.requested() {
                tracing::info!("stop requested ({why:?}): stopping the job and the processes");
                break;
            }
            let mut shutdown = false;
            let mut reset = false;
            while let Some(c) = self.control_sub.receive()? {
                match ControlKind::from_wire(c.kind) {
                    Some(ControlKind::Shutdown) => shutdown = true,
                    Some(ControlKind::Reset) => reset = true,
                    _ => {}
                }
            }
            if shutdown {
                break;
            }
            while let Some(h) = self.heartbeats.receive()? {
                let now = Instant::now();
                if let Some(p) = self.procs.iter_mut().find(|p| {
                    p.id.wire() == h.process && p.child.as_ref().is_some_and(|c| c.id() == h.pid)
                }) {
                    p.last_hb = Some(now);
                    p.last_job = h.job_id;
                }
            }
            self.watch_children()?;
            // a subscriber new since the last look (a restarted MMI) gets the
            // alarms kept in the service's history — the death of the process it
            // replaces among them — without waiting for the next alarm
            if let Err(e) = self.alarms.update_connections() {
                tracing::warn!("alarm service: {e:?}");
            }
            if reset {
                self.reset()?;
            }
            if !ready && self.procs.iter().all(|p| p.panel || p.last_hb.is_some()) {
                ready = true;
                self.notify.send("READY=1");
                tracing::info!("all processes up");
            }
            if let Some(every) = self.notify.watchdog_every() {
                if last_watchdog.elapsed() >= every {
                    self.notify.send("WATCHDOG=1");
                    last_watchdog = Instant::now();
                }
            }
            if self.last_hb.elapsed().as_secs_f64() >= self.cfg.config.heartbeat_period_s {
                self.hb_counter += 1;
                let state = if self.faulted {
                    MachineState::Faulted
                } else {
                    MachineState::Idle
                };
                self.heartbeat.send_copy(Heartbeat {
                    process: ProcessId::Supervisor.wire(),
                    pid: std::process::id(),
                    counter: self.hb_counter,
                    state: state.wire(),
                    job_id: 0,
                })?;
                self.last_hb = Instant::now();
            }
        }
        self.notify.send("STOPPING=1");
        self.stop_all();
        Ok(())
    }

    /// Exits, silent children, restarts that are due.
    fn watch_children(&mut self) -> Result<()> {
        let watchdog = Duration::from_secs_f64(self.cfg.config.supervisor.watchdog_s);
        for i in 0..self.procs.len() {
            let p = &mut self.procs[i];
            let mut died: Option<String> = None;
            let pid = p.child.as_ref().map_or(0, |c| c.id());
            if let Some(c) = p.child.as_mut() {
                if let Some(status) = c.try_wait().ok().flatten() {
                    died = Some(status.to_string());
                } else if !p.panel {
                    let silent_since = p.last_hb.unwrap_or(p.started);
                    if silent_since.elapsed() > watchdog {
                        let _ = c.kill();
                        let status = c.wait().map_or_else(|e| e.to_string(), |st| st.to_string());
                        died = Some(format!(
                            "silent for {:.1} s (watchdog {:.1} s), killed: {status}",
                            silent_since.elapsed().as_secs_f64(),
                            watchdog.as_secs_f64()
                        ));
                    }
                }
            }
            if let Some(how) = died {
                self.procs[i].child = None;
                self.on_death(i, pid, &how);
            }
            let p = &self.procs[i];
            if p.child.is_none() && !p.given_up && p.restart_at.is_some_and(|t| Instant::now() >= t)
            {
                self.spawn(i)?;
            }
        }
        Ok(())
    }

    fn on_death(&mut self, i: usize, pid: u32, how: &str) {
        // told first: cleaning up after the dead process takes a while
        self.report_death(i, pid, how);
        let n = clean_dead_nodes();
        tracing::info!("removed stale resources of {n} dead node(s)");
    }

    /// The `ProcessLost` alarm of a death (about the job the process last named in
    /// its heartbeat), and the restart it schedules.
    fn report_death(&mut self, i: usize, pid: u32, how: &str) {
        let (name, id, job) = (self.procs[i].name, self.procs[i].id, self.procs[i].last_job);
        self.procs[i].last_job = 0;
        if id == ProcessId::Position {
            self.faulted = true;
            self.job_alarm(
                AlarmCode::ProcessLost,
                id,
                pid,
                job,
                &format!("{name} exited ({how}); machine faulted, reset required"),
            );
            return;
        }
        let sv = self.cfg.config.supervisor;
        let panel = self.procs[i].panel;
        // the panel's death concerns no job and faults nothing
        let (code, job) = if panel {
            (AlarmCode::Other, 0)
        } else {
            (AlarmCode::ProcessLost, job)
        };
        let window = Duration::from_secs_f64(sv.restart_window_s);
        let now = Instant::now();
        let p = &mut self.procs[i];
        while p
            .restarts
            .front()
            .is_some_and(|t| now.duration_since(*t) > window)
        {
            p.restarts.pop_front();
        }
        if p.restarts.len() >= sv.restart_limit as usize {
            p.given_up = true;
            let n = p.restarts.len();
            let consequence = if panel {
                "reset to try again (the machine runs on)"
            } else {
                self.faulted = true;
                "machine faulted, reset to try again"
            };
            self.job_alarm(
                code,
                id,
                pid,
                job,
                &format!(
                    "{name} exited ({how}) after {n} restarts within {:.0} s: not restarted; {consequence}",
                    sv.restart_window_s
                ),
            );
            return;
        }
        let delay_s =
            (sv.restart_delay_s * 2f64.powi(p.restarts.len() as i32)).min(sv.restart_delay_max_s);
        p.restarts.push_back(now);
        p.restart_at = Some(now + Duration::from_secs_f64(delay_s));
        self.job_alarm(
            code,
            id,
            pid,
            job,
            &format!("{name} exited ({how}); restarting it in {delay_s:.1} s"),
        );
    }

    /// The operator's reset: the position process (after a fault) and any process
    /// given up on are started again.
    fn reset(&mut self) -> Result<()> {
        if let Some(i) = self.procs.iter().position(|p| p.panel && p.given_up) {
            let p = &mut self.procs[i];
            p.given_up = false;
            p.restarts.clear();
            if p.child.is_none() {
                self.spawn(i)?;
            }
        }
        if !self.faulted {
            return Ok(());
        }
        for i in 0..self.procs.len() {
            let p = &mut self.procs[i];
            let down = p.child.is_none() && (p.id == ProcessId::Position || p.given_up);
            p.given_up = false;
            p.restarts.clear();
            if down {
                clean_dead_nodes();
                self.spawn(i)?;
            }
        }
        self.faulted = false;
        // say so at once: the MMI refuses jobs while the supervisor reports a fault
        self.last_hb = Instant::now() - Duration::from_secs(1);
        Ok(())
    }

    /// Stop the children as a signal to the group would: SIGTERM to each (a running
    /// job decelerates along its path, the MMI records how it ended), then
    /// `stopping.children_grace_s`, then SIGKILL for any left.
    fn stop_all(&mut self) {
        use iceoryx2_bb_posix::process::{Process, ProcessId as Pid};
        use iceoryx2_bb_posix::signal::Signal;
        let _ = self.control_pub.send_copy(ControlCommand {
            flags: 0,
            seq: u64::MAX,
            sender: softnc_ipc::ProcessId::Supervisor.wire(),
            kind: ControlKind::Shutdown.wire(),
            job_id: 0,
            axis: u32::MAX,
            value: 0.0,
            path: FixedStr::empty(),
        });
        for p in &mut self.procs {
            if let Some(c) = p.child.as_mut() {
                if c.try_wait().ok().flatten().is_none() {
                    let pid = Pid::new(c.id() as _);
                    if let Err(e) = Process::from_pid(pid).send_signal(Signal::Terminate) {
                        tracing::warn!("SIGTERM to {}: {e:?}", p.name);
                    }
                }
            }
        }
        let t0 = Instant::now();
        while t0.elapsed().as_secs_f64() < self.cfg.config.stopping.children_grace_s
            && self.procs.iter_mut().any(|p| {
                p.child
                    .as_mut()
                    .is_some_and(|c| c.try_wait().ok().flatten().is_none())
            })
        {
            std::thread::sleep(Duration::from_millis(10));
        }
        for p in &mut self.procs {
            if let Some(c) = p.child.as_mut() {
                if c.try_wait().ok().flatten().is_none() {
                    tracing::warn!("{} did not stop; killing it", p.name);
                    let _ = c.kill();
                }
                let _ = c.wait();
            }
        }
        clean_dead_nodes();
    }
}
