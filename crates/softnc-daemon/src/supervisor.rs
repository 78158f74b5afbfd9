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

use crate::bus::{clean_dead_nodes, Bus, Pub, Sub};
use crate::config::Loaded;
use anyhow::{Context, Result};
use softnc_ipc::{
    Alarm, AlarmCode, ControlCommand, ControlKind, FixedStr, Heartbeat, MachineState, ProcessId,
};
use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

/// How often the supervisor looks at its children.
const WATCH_PERIOD: Duration = Duration::from_millis(20);
/// How long children get to stop on shutdown before they are killed.
const STOP_GRACE: Duration = Duration::from_secs(3);

struct Proc {
    name: &'static str,
    id: ProcessId,
    child: Option<Child>,
    restarts: u32,
}

/// The supervisor.
pub struct Supervisor {
    cfg: Loaded,
    bin_dir: PathBuf,
    procs: Vec<Proc>,
    control_sub: Sub<ControlCommand>,
    control_pub: Pub<ControlCommand>,
    alarms: Pub<Alarm>,
    heartbeat: Pub<Heartbeat>,
    faulted: bool,
    hb_counter: u64,
    last_hb: Instant,
    bus: Bus,
}

impl Supervisor {
    /// Prepare: clean stale resources of a previous run, open the services.
    pub fn new(cfg: Loaded) -> Result<Self> {
        let cleaned = clean_dead_nodes();
        if cleaned > 0 {
            tracing::info!("removed stale resources of {cleaned} dead node(s)");
        }
        let names = softnc_ipc::ServiceNames::new(&cfg.config.service_prefix, &cfg.config.instance);
        let bus = Bus::new(names, "supervisor")?;
        let bin_dir = std::env::current_exe()
            .context("locating softncd")?
            .parent()
            .map(PathBuf::from)
            .unwrap_or_default();
        let p = |name, id| Proc {
            name,
            id,
            child: None,
            restarts: 0,
        };
        Ok(Supervisor {
            procs: vec![
                p("softnc-mmi", ProcessId::Mmi),
                p("softnc-position", ProcessId::Position),
                p("softnc-interp", ProcessId::Interp),
            ],
            control_sub: bus.control_subscriber()?,
            control_pub: bus.control_publisher()?,
            alarms: bus.alarm_publisher()?,
            heartbeat: bus.heartbeat_publisher()?,
            cfg,
            bin_dir,
            faulted: false,
            hb_counter: 0,
            last_hb: Instant::now() - Duration::from_secs(1),
            bus,
        })
    }

    fn spawn(&self, name: &str) -> Result<Child> {
        let exe = self.bin_dir.join(name);
        Command::new(&exe)
            .arg("--config")
            .arg(&self.cfg.path)
            .spawn()
            .with_context(|| format!("starting {}", exe.display()))
    }

    fn alarm(&mut self, code: AlarmCode, msg: &str) {
        tracing::warn!("{msg}");
        let _ = self.alarms.send_copy(Alarm {
            code: code.wire(),
            axis: u32::MAX,
            process: ProcessId::Supervisor.wire(),
            job_id: 0,
            time_index: 0,
            message: FixedStr::new(msg),
        });
    }

    /// Start everything and watch until shutdown (SIGINT/SIGTERM or a `Shutdown`
    /// control command).
    pub fn run(&mut self) -> Result<()> {
        for i in 0..self.procs.len() {
            let child = self.spawn(self.procs[i].name)?;
            self.procs[i].child = Some(child);
        }
        tracing::info!("softncd running: {}", self.cfg.path.display());
        loop {
            if self.bus.node.wait(WATCH_PERIOD).is_err() {
                tracing::info!("termination requested");
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
            for i in 0..self.procs.len() {
                let exited = match self.procs[i].child.as_mut() {
                    Some(c) => c.try_wait().ok().flatten(),
                    None => None,
                };
                let Some(status) = exited else { continue };
                self.procs[i].child = None;
                let (name, id) = (self.procs[i].name, self.procs[i].id);
                match id {
                    ProcessId::Position => {
                        self.faulted = true;
                        self.alarm(
                            AlarmCode::ProcessLost,
                            &format!("{name} exited ({status}); machine faulted, reset required"),
                        );
                        let n = clean_dead_nodes();
                        tracing::info!("removed stale resources of {n} dead node(s)");
                    }
                    _ => {
                        self.alarm(
                            AlarmCode::ProcessLost,
                            &format!("{name} exited ({status}); restarting it"),
                        );
                        clean_dead_nodes();
                        self.procs[i].restarts += 1;
                        self.procs[i].child = Some(self.spawn(name)?);
                    }
                }
            }
            if reset && self.faulted {
                if let Some(i) = self
                    .procs
                    .iter()
                    .position(|p| p.id == ProcessId::Position && p.child.is_none())
                {
                    clean_dead_nodes();
                    self.procs[i].restarts += 1;
                    self.procs[i].child = Some(self.spawn(self.procs[i].name)?);
                }
                self.faulted = false;
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
        self.stop_all();
        Ok(())
    }

    fn stop_all(&mut self) {
        let _ = self.control_pub.send_copy(ControlCommand {
            seq: u64::MAX,
            kind: ControlKind::Shutdown.wire(),
            job_id: 0,
            value: 0.0,
            path: FixedStr::empty(),
        });
        let t0 = Instant::now();
        while t0.elapsed() < STOP_GRACE
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
