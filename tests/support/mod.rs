//! The end-to-end tests' harness: a controller instance of its own per test (softncd
//! on a fresh folder and instance name), the operator client, and the checks several
//! test files share (a stop along the path, services left, the simulator's trace).
#![allow(dead_code)]

#[path = "../../crates/softnc-daemon/tests/common/mod.rs"]
pub mod common;
#[allow(unused_imports)]
pub use common::learn_job;
#[allow(unused_imports)]
pub use softnc_api::{
    AlarmKind, Axis, JobRecord, MachineState, Outcome, ProcessHealth, Reply, Request, Status,
};
pub use softnc_client::Operator;
pub use std::os::unix::process::CommandExt;
pub use std::path::{Path, PathBuf};
pub use std::process::{Child, Command};
pub use std::time::{Duration, Instant};

/// An empty folder for test `tag` of this run.
pub fn fresh_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("softnc-e2e-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The `softncd` binary: this package's own (the daemon's tests), else the one built
/// beside `softnc` (the CLI's tests; `softnc demo` finds it there too) or beside
/// `softnc-web` (the web panel's test).
pub fn softncd_bin() -> PathBuf {
    if let Some(p) = option_env!("CARGO_BIN_EXE_softncd") {
        return PathBuf::from(p);
    }
    let beside = option_env!("CARGO_BIN_EXE_softnc")
        .or(option_env!("CARGO_BIN_EXE_softnc-web"))
        .expect("a test of softnc-daemon, softnc-cli or softnc-web");
    let p = Path::new(beside).with_file_name("softncd");
    assert!(
        p.exists(),
        "{} is not built: `cargo build -p softnc-daemon` (scripts/test builds it)",
        p.display()
    );
    p
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The real-time test daemons' `lookahead_samples` (production: 100): 300 samples
/// keep 75 ms of slack in the ring (its window is ¾ of the lookahead).
pub const E2E_LOOKAHEAD_SAMPLES: u64 = 300;

/// One daemon at a time: each runs three processes with real-time loops, and on a
/// small machine several at once starve each other's clocks.
pub static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A daemon on a fresh instance; shut down (killed if it hangs) on drop.
pub struct Daemon {
    pub child: Child,
    pub config: PathBuf,
    pub dir: PathBuf,
    /// Keep the folder when dropped (the next daemon starts in it).
    pub keep_dir: bool,
    /// Held until the daemon is shut down (fields drop after `Drop::drop`).
    _serial: std::sync::MutexGuard<'static, ()>,
}

impl Daemon {
    pub fn start(tag: &str, clock: &str, trace: bool) -> Daemon {
        Daemon::start_on(tag, clock, trace, "default.ron")
    }

    /// A daemon whose data directory already holds a history of `n` completed jobs
    /// with paths of `path_len` characters.
    pub fn start_with_history(tag: &str, n: u64, path_len: usize) -> Daemon {
        let dir = fresh_dir(tag);
        std::fs::create_dir_all(dir.join("data")).unwrap();
        let jobs: Vec<serde_json::Value> = (1..=n)
            .map(|id| {
                let stem = format!("/shop/job{id:04}-");
                let path = format!("{stem}{}", "p".repeat(path_len - stem.len()));
                serde_json::json!({"job_id": id, "path": path, "submitted_unix_s": 0,
                    "outcome": "completed", "planned_samples": 100, "cycles": 100,
                    "accuracy": {"contour_max_abs_um": 1.0, "contour_rms_um": 0.5,
                        "following_max_abs_um": [1.0, 1.0, 1.0]}})
            })
            .collect();
        std::fs::write(
            dir.join("data/jobs.json"),
            serde_json::to_vec(&jobs).unwrap(),
        )
        .unwrap();
        Daemon::start_in(dir, tag, "Lockstep", false, "default.ron", &[])
    }

    /// A daemon on the machine profile `config/machines/{machine}`.
    pub fn start_on(tag: &str, clock: &str, trace: bool, machine: &str) -> Daemon {
        let dir = fresh_dir(tag);
        Daemon::start_in(dir, tag, clock, trace, machine, &[])
    }

    /// A daemon whose configuration has `edits` (text replacements) made.
    pub fn start_edited(tag: &str, clock: &str, edits: &[(&str, &str)]) -> Daemon {
        let dir = fresh_dir(tag);
        Daemon::start_in(dir, tag, clock, false, "default.ron", edits)
    }

    pub fn start_in(
        dir: PathBuf,
        tag: &str,
        clock: &str,
        trace: bool,
        machine: &str,
        edits: &[(&str, &str)],
    ) -> Daemon {
        // a failed test poisons the lock; the next one may still run
        let serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        std::fs::create_dir_all(dir.join("machines")).unwrap();
        std::fs::copy(
            repo().join("config/machines").join(machine),
            dir.join("machines/default.ron"),
        )
        .unwrap();
        std::fs::copy(
            repo().join("config/iceoryx2.toml"),
            dir.join("iceoryx2.toml"),
        )
        .unwrap();
        // real time: both loops at the production SCHED_FIFO priorities and with
        // their memory locked where the test may have them (unpinned), so that a
        // loaded machine — a compiler beside the tests writing gigabytes — neither
        // starves them nor evicts the pages they run from (a page fault read back
        // from a busy disk stalled a loop past the ring's 25 ms of slack); lockstep
        // needs none
        let (fifo_interp, fifo_position) = if clock == "Realtime" {
            (
                "fifo_priority: Some(70), lock_memory: true",
                "fifo_priority: Some(80), lock_memory: true",
            )
        } else {
            ("", "")
        };
        let cfg = std::fs::read_to_string(repo().join("config/default.ron"))
            .unwrap()
            .replace(
                "instance: \"mill1\"",
                &format!("instance: \"e2e{tag}{}\"", std::process::id()),
            )
            .replace("clock: Realtime", &format!("clock: {clock}"))
            .replace("data_dir: \"../data\"", "data_dir: \"data\"")
            .replace("trace: false", &format!("trace: {trace}"))
            .replace(
                "// learning_dir: Some(\"../learning\")",
                "learning_dir: Some(\"learning\")",
            )
            .replace(
                "interp_rt: (core: Some(0), fifo_priority: Some(70), lock_memory: true)",
                &format!("interp_rt: ({fifo_interp})"),
            )
            .replace(
                "position_rt: (core: Some(1), fifo_priority: Some(80), lock_memory: true)",
                &format!("position_rt: ({fifo_position})"),
            );
        // late cycles: the tests run unpinned, memory unlocked, beside compilers, so
        // a cycle 10 ms late (the production bound) happens without a fault of
        // ours; 30 ms still catches a stalled loop (e2e_motion stops one for 40 ms)
        // and the ring's slack: the production lookahead (100 samples) leaves the
        // interpolator 25 ms to send its next sample; CI's virtual machine stops a
        // vCPU for 25–45 ms when the host steals it (measured: docs/perf-log/ci-time.md),
        // which ran the ring dry in jobs nothing was wrong with. The test daemons keep
        // E2E_LOOKAHEAD_SAMPLES in flight (75 ms of slack); everything that depends
        // on the lookahead (hold, overrides, machine waits) reads it from the config.
        let cfg = if clock == "Realtime" {
            cfg.replace("late_alarm_s: 0.01", "late_alarm_s: 0.03")
                .replace(
                    "lookahead_samples: 100,",
                    &format!("lookahead_samples: {E2E_LOOKAHEAD_SAMPLES},"),
                )
        } else {
            cfg
        };
        let cfg = edits.iter().fold(cfg, |c, (from, to)| {
            assert!(c.contains(from), "config has no {from:?}");
            c.replace(from, to)
        });
        let config = dir.join("default.ron");
        std::fs::write(&config, cfg).unwrap();
        let child = Command::new(softncd_bin())
            .arg("--config")
            .arg(&config)
            // SOFTNC_E2E_LOG=info shows the processes' logs when a test fails
            .env(
                "RUST_LOG",
                std::env::var("SOFTNC_E2E_LOG").unwrap_or_else(|_| "warn".into()),
            )
            // its own process group: a test can signal the controller as a terminal's
            // Ctrl-C does, and nothing else
            .process_group(0)
            // the instance's lock file in the test's folder (removed with it)
            .env("SOFTNC_RUN_DIR", &dir)
            .spawn()
            .unwrap();
        Daemon {
            child,
            config,
            dir,
            keep_dir: false,
            _serial: serial,
        }
    }

    /// The operator client, with the machine on (the daemon starts off).
    /// Set a line of this daemon's simulated machine from outside (its panel:
    /// `softnc_ipc::SimPanel`, the lines of `softnc_sim::wiring`), as a test's hand
    /// on the E-stop chain or an input.
    pub fn sim_panel(&self, kind: u32, line: u32, value: f64) {
        let c = softnc_client::ClientConfig::load(&self.config).unwrap();
        c.setup_iceoryx2().unwrap();
        let names = softnc_ipc::ServiceNames::new(&c.service_prefix, &c.instance);
        let bus = softnc_ipc::bus::Bus::new(names, "test-panel").unwrap();
        let publisher = bus.sim_panel_publisher().unwrap();
        publisher
            .send_copy(softnc_ipc::SimPanel { kind, line, value })
            .unwrap();
        // (the position process takes it at its next cycle)
        std::thread::sleep(Duration::from_millis(100));
    }

    pub fn operator(&self) -> Operator {
        let op = self.operator_off();
        op.machine_on(Duration::from_secs(30)).expect("machine on");
        op
    }

    /// The operator client, the machine left as it is.
    pub fn operator_off(&self) -> Operator {
        Operator::wait_ready(&self.config, Duration::from_secs(30)).expect("MMI answers")
    }

    /// Poll until `pred` holds on the status, or fail after `timeout`.
    pub fn wait_status(
        &self,
        op: &Operator,
        timeout: Duration,
        what: &str,
        pred: impl Fn(&Status) -> bool,
    ) -> Status {
        let t0 = Instant::now();
        loop {
            if let Ok(s) = op.status() {
                if pred(&s) {
                    return s;
                }
                assert!(t0.elapsed() < timeout, "timed out waiting for {what}: {s}");
            } else {
                assert!(
                    t0.elapsed() < timeout,
                    "timed out waiting for {what}: no MMI"
                );
            }
            std::thread::sleep(Duration::from_millis(25));
        }
    }

    pub fn wait_job(&self, op: &Operator, job_id: u64, timeout: Duration) -> Status {
        self.wait_status(op, timeout, "job end", |s| {
            s.job(job_id).is_some_and(|j| j.record.outcome.ended())
        })
    }

    /// Wait for softncd to exit after `what` (a shutdown, a signal); its exit
    /// status. Fails after 15 s.
    pub fn wait_exit(&mut self, what: &str) -> std::process::ExitStatus {
        let t0 = Instant::now();
        loop {
            if let Some(st) = self.child.try_wait().unwrap() {
                return st;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(15),
                "softncd still running 15 s after {what}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Submit [`short_job`]; it is accepted and completes. The status at its end.
    pub fn runs_the_short_job(&self, op: &Operator) -> Status {
        let r = op.request(&submit(&abs(&short_job(&self.dir)))).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        let s = self.wait_job(op, id(&r), Duration::from_secs(60));
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
        s
    }

    /// The daemon's trace of job `job_id`, once it has `len` bytes (the file is closed
    /// by its own thread) or after 10 s.
    pub fn trace_of(&self, job_id: u64, len: usize) -> Vec<u8> {
        let path = self.dir.join(format!("data/trace-job{job_id}.csv"));
        let t0 = Instant::now();
        loop {
            let got = std::fs::read(&path).unwrap_or_default();
            if got.len() >= len || t0.elapsed() > Duration::from_secs(10) {
                return got;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    pub fn pid_of(&self, name: &str) -> Option<u32> {
        // children of this softncd with that name
        let out = Command::new("pgrep")
            .args(["-P", &self.child.id().to_string(), "-x", name])
            .output()
            .ok()?;
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .next()?
            .trim()
            .parse()
            .ok()
    }

    /// The pids of this controller's three processes.
    pub fn children(&self) -> Vec<u32> {
        ["softnc-mmi", "softnc-position", "softnc-interp"]
            .iter()
            .filter_map(|n| self.pid_of(n))
            .collect()
    }

    /// Wait until none of `pids` runs any more (or fail after `timeout`).
    pub fn wait_gone(pids: &[u32], timeout: Duration) {
        let t0 = Instant::now();
        loop {
            let alive: Vec<u32> = pids
                .iter()
                .copied()
                .filter(|p| {
                    // a zombie has no cmdline left; gone is gone
                    std::fs::read_to_string(format!("/proc/{p}/stat"))
                        .map(|s| !s.contains(") Z "))
                        .unwrap_or(false)
                })
                .collect();
            if alive.is_empty() {
                return;
            }
            assert!(
                t0.elapsed() < timeout,
                "processes {alive:?} still running after {timeout:?}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Job `job_id`'s record as the MMI wrote it into its history (`None` if none,
    /// or no history yet).
    pub fn job_record(&self, job_id: u64) -> Option<JobRecord> {
        let text = std::fs::read_to_string(self.dir.join("data/jobs.json")).ok()?;
        let jobs: Vec<JobRecord> = serde_json::from_str(&text).ok()?;
        jobs.into_iter().find(|j| j.job_id == job_id)
    }

    /// Shut the controller down as an operator does; it exits 0 and leaves no
    /// process and no iceoryx2 service of its instance (a killed process's
    /// resources included).
    pub fn shutdown_leaving_nothing(&mut self, tag: &str) {
        let kids = self.children();
        let op = self.operator_off();
        let r = op.request(&Request::Shutdown).unwrap();
        assert!(r.is_accepted(), "{}", r.message());
        drop(op);
        let status = self.wait_exit("shutdown");
        assert_eq!(status.code(), Some(0), "softncd exits 0 on shutdown");
        Daemon::wait_gone(&kids, Duration::from_secs(5));
        let instance = format!("e2e{tag}{}", std::process::id());
        assert_eq!(
            services_of(&instance),
            Vec::<String>::new(),
            "iceoryx2 services left"
        );
    }

    pub fn kill9(&self, name: &str) {
        let pid = self
            .pid_of(name)
            .unwrap_or_else(|| panic!("{name} not running"));
        let ok = Command::new("kill")
            .args(["-9", &pid.to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -9 {name}");
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if let Ok(op) = Operator::connect(&self.config) {
            let _ = op.request(&Request::Shutdown);
        }
        let t0 = Instant::now();
        while self.child.try_wait().ok().flatten().is_none()
            && t0.elapsed() < Duration::from_secs(10)
        {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        if !self.keep_dir {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// The trace of a stopped job shows a stop along the path: from one cycle to the next
/// the command never moves more than it moved in the cycle before plus what the
/// acceleration limit allows (|Δ²x| ≤ √3·3000 mm/s²·T²), and it ends at rest.
pub fn assert_stops_along_the_path(trace: &Path) {
    let t0 = Instant::now();
    let text = loop {
        let t = std::fs::read_to_string(trace).unwrap_or_default();
        if t.lines().count() > 100 || t0.elapsed() > Duration::from_secs(5) {
            break t;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let cmds: Vec<[f64; 3]> = trace_columns(&text);
    assert!(
        cmds.len() > 100,
        "trace of the stopped job: {} rows",
        cmds.len()
    );
    let step = |a: [f64; 3], b: [f64; 3]| {
        ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
    };
    let steps: Vec<f64> = cmds.windows(2).map(|w| step(w[0], w[1])).collect();
    let accel_step_mm = 3f64.sqrt() * 3000.0 * 1e-6 * 1.01;
    for (k, w) in steps.windows(2).enumerate() {
        assert!(
            w[1] <= w[0] + accel_step_mm,
            "position jump at cycle {}: {} mm after {} mm",
            k + 1,
            w[1],
            w[0]
        );
    }
    let last = *steps.last().unwrap();
    assert!(
        last <= accel_step_mm,
        "still moving {last} mm per cycle at the end"
    );
}

/// Send `sig` (`-STOP`, `-CONT`, `-INT`, ...) to process `pid` with kill(1).
pub fn signal(pid: u32, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &pid.to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok, "kill {sig} {pid}");
}

/// Stop process `pid` for `how_long` (alive to the kernel, its loop standing).
pub fn stop_for(pid: u32, how_long: Duration) {
    signal(pid, "-STOP");
    std::thread::sleep(how_long);
    signal(pid, "-CONT");
}

pub fn abs(path: &Path) -> String {
    std::fs::canonicalize(path).unwrap().display().to_string()
}

/// A short job of lines and arcs (about 3 s of motion).
pub fn short_job(dir: &Path) -> PathBuf {
    let p = dir.join("short.ngc");
    std::fs::write(
        &p,
        "G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z5\nG1 Z-1 F600\nG1 X20 F2400\nG2 X30 Y10 R10\nG1 Y30\nG3 X20 Y40 I-10 J0\nG1 X0\nG1 Y0\nG0 Z5\nM2\n",
    )
    .unwrap();
    p
}

/// The simulator's trace of the same job, written with the same writer.
pub fn simulator_trace(job: &Path, machine: &Path, out: &Path) {
    simulator_trace_learned(job, machine, out, None)
}

/// A job as the daemon's interpolation process plans it on `machine`: its plan and
/// its machine sequencer, whose stops wait for the machine heard as late as the
/// daemon's interpolation process hears it (its lookahead).
pub struct JobPlan {
    /// The machine profile.
    pub profile: softnc_machine::MachineProfile,
    /// The plan.
    pub plan: softnc_planner::Plan,
    /// The machine sequencer.
    pub seq: softnc_planner::machine_sequencer::MachineSequencer,
    /// What the sequencer hears of the machine.
    pub heard: std::rc::Rc<std::cell::RefCell<softnc_planner::machine_sequencer::FeedbackHistory>>,
}

/// [`JobPlan`] of `job` on `machine`.
pub fn job_plan(job: &Path, machine: &Path) -> JobPlan {
    let profile = softnc_machine::MachineProfile::load(machine).unwrap();
    let text = std::fs::read_to_string(job).unwrap();
    let options = softnc_planner::PlanOptions {
        wait_at_machine_stops: true,
        ..Default::default()
    };
    let program = softnc_gcode::read_program(&text, &job.display().to_string(), &profile).unwrap();
    let plan = softnc_planner::plan(&program, &profile, &options).unwrap();
    let (seq, heard) =
        softnc_daemon::plan_samples::sim_machine(&program, &profile, &options, daemon_lookahead());
    JobPlan {
        profile,
        plan,
        seq,
        heard,
    }
}

/// [`simulator_trace`] with the learning store `learned` applied as `softnc sim
/// --learned --store DIR` applies it.
pub fn simulator_trace_learned(job: &Path, machine: &Path, out: &Path, learned: Option<&Path>) {
    let JobPlan {
        profile,
        plan,
        seq,
        heard,
    } = job_plan(job, machine);
    let mut engine = softnc_sim::simulated_engine(
        &profile,
        profile.servo.seed,
        softnc_sim::SimOptions::default(),
    );
    engine
        .set_spindle_schedule(&profile, plan.spindle_changes(), 1.0)
        .unwrap();
    let correction = learned.map(|dir| {
        let found = softnc_learning::entry::lookup(
            &softnc_learning::LearningStore::new(dir),
            &std::fs::read(job).unwrap(),
            &std::fs::read(machine).unwrap(),
            softnc_learning::entry::OVERRIDE_PCT,
            || plan.interpolator().count(),
            plan.cycle_s(),
        )
        .unwrap();
        match found {
            softnc_learning::Lookup::Markov(c) => c,
            other => panic!("no learned correction: {other:?}"),
        }
    });
    let mut file = softnc_daemon::trace::TraceFile::create(out).unwrap();
    let planned = softnc_daemon::plan_samples::PlanSamples::with_machine(
        plan.interpolator(),
        seq,
        heard.clone(),
    );
    let samples: Box<dyn Iterator<Item = softnc_sim::sim::CommandSample>> = match &correction {
        Some(c) => Box::new(c.corrected(planned)),
        None => Box::new(planned),
    };
    softnc_sim::simulate_sequenced(
        &mut engine,
        plan.cycle_s(),
        samples,
        |m| plan.motion_primitive(m as usize),
        |row, engine, seq| {
            softnc_daemon::plan_samples::hear(&heard, seq, row, engine);
            file.row(row).unwrap();
        },
    )
    .unwrap();
    file.finish().unwrap();
}

/// The test daemons' `lookahead_samples` (config/default.ron's).
pub fn daemon_lookahead() -> u64 {
    softnc_daemon::config::DaemonConfig::load(&repo().join("config/default.ron"))
        .unwrap()
        .config
        .lookahead_samples as u64
}

/// The iceoryx2 services left for an instance (after its controller stopped).
pub fn services_of(instance: &str) -> Vec<String> {
    use iceoryx2::prelude::*;
    let mut names = Vec::new();
    let _ = ipc::Service::list(Config::global_config(), |d| {
        let n = d.static_details.name().as_str().to_string();
        if n.contains(&format!("/{instance}/")) {
            names.push(n);
        }
        CallbackProgression::Continue
    });
    names
}

/// Start the short job and wait until it moves.
pub fn start_moving(d: &Daemon, op: &Operator) -> u64 {
    let job = short_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_status(op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 800
    });
    id(&r)
}

/// SIGSTOP a child mid-job (alive to the kernel, silent to everyone) and wait until
/// the supervisor's watchdog has killed it; returns its pid.
pub fn sigstop_until_the_watchdog_acts(d: &Daemon, op: &Operator, name: &str) -> u32 {
    let pid = d.pid_of(name).unwrap();
    assert!(Command::new("kill")
        .args(["-STOP", &pid.to_string()])
        .status()
        .unwrap()
        .success());
    let t0 = Instant::now();
    while std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|st| !st.contains(") Z "))
    {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the stopped {name} was not killed"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = op;
    pid
}

/// Peak resident memory of a process (kB), from /proc.
pub fn peak_rss_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

/// A request's (accepted, message).
pub fn ask(op: &Operator, request: &Request) -> (bool, String) {
    let r = op.request(request).unwrap();
    (r.is_accepted(), r.message())
}

/// The job an accepted reply names.
pub fn id(r: &Reply) -> u64 {
    r.job_id()
        .unwrap_or_else(|| panic!("no job in the reply: {}", r.message()))
}

/// The job the status shows (the running one, else the last).
pub fn job_of(s: &Status) -> &JobRecord {
    &s.job
        .as_ref()
        .unwrap_or_else(|| panic!("no job in the status: {s}"))
        .record
}

/// Submit the program `path` from its start.
pub fn submit(path: &str) -> Request {
    Request::SubmitJob {
        path: path.to_string(),
        from_line: None,
        adaptive_force: false,
    }
}

/// Submit the program `path` from line `from_line`.
pub fn submit_from(path: &str, from_line: u32) -> Request {
    Request::SubmitJob {
        path: path.to_string(),
        from_line: Some(from_line),
        adaptive_force: false,
    }
}

/// Run MDI block(s) `blocks`.
pub fn mdi_request(blocks: &str) -> Request {
    Request::Mdi {
        blocks: blocks.to_string(),
    }
}

/// The axis of index `i` (X = 0).
pub fn axis(i: u32) -> Axis {
    Axis::from_index(i as usize).unwrap()
}

/// A continuous jog of axis `i` at `speed_mm_per_min`.
pub fn jog(i: u32, speed_mm_per_min: f64) -> Request {
    Request::Jog {
        axis: axis(i),
        speed_mm_per_min,
    }
}

/// An incremental jog of axis `i` by `distance_mm`.
pub fn jog_step(i: u32, distance_mm: f64) -> Request {
    Request::JogStep {
        axis: axis(i),
        distance_mm,
    }
}

/// The machine's alarms as lines of text (`Code: message`), newest first.
pub fn alarm_text(s: &Status) -> String {
    s.alarms
        .iter()
        .map(|a| format!("{:?}: {}\n", a.code, a.message))
        .collect()
}

/// The command position of the axes in the status (mm).
pub fn cmd_mm(s: &Status) -> Vec<f64> {
    s.axes
        .as_ref()
        .unwrap_or_else(|| panic!("no axes: {s}"))
        .cmd_mm
        .clone()
}

/// The machine position in the status.
pub fn machine_mm(s: &Status) -> [f64; 3] {
    s.machine_mm
        .unwrap_or_else(|| panic!("no machine position: {s}"))
}

/// `config/machines/default-incremental.ron` with homing searches 2.5 times as
/// fast (a shorter test), written into `dir`.
pub fn quick_homing_profile(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("config/machines/default-incremental.ron"))
        .unwrap()
        .replace("search_vel_mm_per_s: 40.0", "search_vel_mm_per_s: 100.0")
        .replace("search_vel_mm_per_s: 30.0", "search_vel_mm_per_s: 75.0");
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("incremental-quick.ron");
    std::fs::write(&path, text).unwrap();
    path
}

/// Wait until the job pauses (M0/M1, single block) at a line; returns the status.
pub fn wait_paused(d: &Daemon, op: &Operator) -> Status {
    d.wait_status(op, Duration::from_secs(30), "a pause", |s| {
        s.state == MachineState::Paused
    })
}

/// The first `N` numbers after the time of every row of a trace CSV (cmd x y z,
/// then actual x y z, ...); rows without them are left out, the header first.
pub fn trace_columns<const N: usize>(text: &str) -> Vec<[f64; N]> {
    text.lines()
        .skip(1)
        .filter_map(|l| {
            let f: Vec<f64> = l
                .split(',')
                .skip(1)
                .take(N)
                .filter_map(|v| v.parse().ok())
                .collect();
            f.try_into().ok()
        })
        .collect()
}
