//! `softnc demo`: start `softncd` on the simulated machine, run the demo job through
//! all three processes, show progress, print the accuracy and timing report, shut
//! down cleanly.

use crate::cmd_operator::{wait_job, Operator};
use anyhow::{bail, Context, Result};
use softnc_api::{Alarm, JobStatus, Loops, Outcome, Request};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};
use std::time::{Duration, Instant};

/// Arguments of `softnc demo`.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// The job to run (default: the demo job `examples/demo.ngc`, built into
    /// `softnc`, so that the demo runs from any folder).
    #[arg(long)]
    job: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// The servo backend: the profile's simulated machine, or a loopback that
    /// follows the command exactly (contour error ≈ 0).
    #[arg(long, value_enum, default_value_t = Backend::Simulated)]
    backend: Backend,
}

/// `--backend` of `softnc demo`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// The machine profile's simulated machine.
    Simulated,
    /// Axes that follow the command exactly.
    Loopback,
    /// Emulated CiA 402 drives and an I/O terminal on EtherCAT over a veth pair
    /// made for the demo (root needed; docs/ethercat.md).
    EthercatEmulated,
}

/// The demo job, `examples/demo.ngc`, as built into `softnc`.
const DEMO_JOB: &str = include_str!("../../../examples/demo.ngc");

/// Where `softncd` is: beside this binary.
fn softncd_path() -> Result<PathBuf> {
    let me = std::env::current_exe().context("locating softnc")?;
    let p = me.with_file_name("softncd");
    if !p.exists() {
        bail!(
            "{} not found: build the workspace first (cargo build --release)",
            p.display()
        );
    }
    Ok(p)
}

/// Run the demo: on an instance of its own (`demo<pid>`, data in a temporary
/// folder), so that it never touches a controller already running from the same
/// configuration, and two demos run side by side.
pub fn run(args: DemoArgs, config: &Path) -> Result<ExitCode> {
    let loaded = softnc_daemon::config::DaemonConfig::load(config)?;
    let dir = std::env::temp_dir().join(format!("softnc-demo-{}", std::process::id()));
    let instance = format!("demo{}", std::process::id());
    // the emulated bus lives as long as the demo
    let mut bus = None;
    let args_json = args.json;
    let backend = match args.backend {
        Backend::Simulated => softnc_daemon::config::BackendKind::Simulated,
        Backend::Loopback => softnc_daemon::config::BackendKind::Loopback,
        Backend::EthercatEmulated => {
            let (settings, veth, emu) = emulated_bus(loaded.machine.axes.len())?;
            bus = Some((veth, emu));
            softnc_daemon::config::BackendKind::EtherCat(settings)
        }
    };
    // a new folder of our own (not one planted in the shared temporary folder)
    {
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new()
            .mode(0o700)
            .create(&dir)
            .with_context(|| format!("creating the demo's folder {}", dir.display()))?;
    }
    let r = (|| {
        let demo_config = loaded
            .write_instance_copy_on(&dir, &instance, backend)
            .with_context(|| format!("writing the demo's configuration into {}", dir.display()))?;
        let job = match &args.job {
            Some(job) => std::fs::canonicalize(job).with_context(|| job.display().to_string())?,
            None => {
                let job = dir.join("demo.ngc");
                std::fs::write(&job, DEMO_JOB)
                    .with_context(|| format!("writing {}", job.display()))?;
                job
            }
        };
        run_on(args, &demo_config, &job)
    })();
    let _ = std::fs::remove_dir_all(&dir);
    if let Some((_veth, emu)) = &bus {
        print_bus(emu, args_json);
    }
    r
}

/// A veth pair and the emulated segment on it: one CiA 402 drive per axis, then an
/// I/O terminal; the daemon's `EtherCat` settings for it.
fn emulated_bus(
    axes: usize,
) -> Result<(
    softnc_ethercat::EtherCatSettings,
    softnc_ethercat_emu::veth::VethPair,
    softnc_ethercat_emu::Emulator,
)> {
    use softnc_ethercat::{ExpectedSubDevice, Identity, Role};
    use softnc_ethercat_emu::DeviceKind;
    if !softnc_ethercat_emu::veth::is_root() {
        bail!("--backend ethercat-emulated needs root: it makes a veth pair and opens packet sockets on it");
    }
    let veth = softnc_ethercat_emu::veth::VethPair::create().map_err(anyhow::Error::msg)?;
    let mut kinds = vec![DeviceKind::Drive; axes];
    kinds.push(DeviceKind::Io);
    // the emulated ESCs answer at a real-time priority between the daemon's two
    // loops (interpolation 70, position 80), as hardware answers whatever the
    // host's other work
    let emu =
        softnc_ethercat_emu::Emulator::spawn_at(&veth.sub, &kinds, Some(EMULATED_FIFO_PRIORITY))?;
    let subdevices = kinds
        .iter()
        .enumerate()
        .map(|(p, &k)| {
            let id = softnc_ethercat_emu::identity(k, p);
            ExpectedSubDevice {
                identity: Identity {
                    vendor_id: id.vendor_id,
                    product_code: id.product_code,
                    revision: id.revision,
                },
                role: match k {
                    DeviceKind::Drive => Role::Drive {
                        axis: p as u8,
                        counts_per_mm: softnc_ethercat_emu::DRIVE_COUNTS_PER_MM,
                        direction: 1,
                        following_error_window_counts: EMULATED_FE_WINDOW_COUNTS,
                    },
                    DeviceKind::Io => Role::Io,
                },
                // the demo's terminal carries no signal: its tool change is
                // answered by the demo as the operator
                inputs: Vec::new(),
                outputs: Vec::new(),
                pdo: None,
            }
        })
        .collect();
    eprintln!(
        "EtherCAT: {} emulated SubDevices on {} (MainDevice on {})",
        kinds.len(),
        veth.sub,
        veth.main
    );
    let settings = softnc_ethercat::EtherCatSettings {
        interface: veth.main.clone(),
        response_timeout_s: EMULATED_RESPONSE_TIMEOUT_S,
        subdevices,
    };
    Ok((settings, veth, emu))
}

/// How long a cycle waits for the emulated SubDevices' answer (s): they are a
/// thread of an ordinary process sharing the machine with the controller's
/// real-time ones, and on a busy machine they wait their turn (a late answer costs
/// the position loop an overrun; a lost one aborts the job).
const EMULATED_RESPONSE_TIMEOUT_S: f64 = 0.05;

/// The emulated SubDevices' SCHED_FIFO priority.
const EMULATED_FIFO_PRIORITY: u8 = 75;

/// The emulated drives' following-error window (counts): 5 mm at 0.1 µm.
const EMULATED_FE_WINDOW_COUNTS: u32 = 50_000;

/// The bus as the emulated SubDevices saw it (on standard error beside a JSON
/// report).
fn print_bus(emu: &softnc_ethercat_emu::Emulator, json: bool) {
    let out = |line: String| {
        if json {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    };
    let s = emu.stats();
    out(format!(
        "  EtherCAT (emulated SubDevices): frames answered {}, dropped {}",
        s.answered, s.dropped
    ));
    for v in emu.views() {
        if let softnc_ethercat_emu::app::AppView::Drive(d) = v.app {
            out(format!(
                "    drive {}: {} targets received, at {} counts, SYNC0 events {}",
                v.position, d.targets_received, d.position_counts, v.sync0_events
            ));
        }
    }
}

fn run_on(args: DemoArgs, config: &Path, job: &Path) -> Result<ExitCode> {
    let backend = args.backend;
    let run_dir = config.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut daemon = Command::new(softncd_path()?)
        .arg("--config")
        .arg(config)
        // its own instance's lock lives (and goes) with its temporary folder
        .env("SOFTNC_RUN_DIR", run_dir)
        .spawn()
        .context("starting softncd")?;
    let result = (|| -> Result<(DemoReport, Outcome)> {
        let op = Operator::wait_ready(config, Duration::from_secs(20))?;
        // shut the demo's controller down whatever happens from here on
        let _shutdown = ShutdownOnDrop(&op);
        // the controller starts with its drives off, as a machine does
        op.machine_on(Duration::from_secs(20))?;
        eprintln!("machine on");
        eprintln!("softncd started; submitting {}", job.display());
        let r = op.request(&Request::SubmitJob {
            path: job.display().to_string(),
            from_line: None,
            adaptive_force: false,
        })?;
        if !r.is_accepted() {
            bail!("job refused: {}", r.message());
        }
        let t0 = Instant::now();
        let job_id = r.job_id().unwrap_or(0);
        answer_tool_changes(&op, job_id)?;
        let outcome = wait_job(&op, job_id, true)?;
        let wall = t0.elapsed().as_secs_f64();
        let status = op.status()?;
        let report = DemoReport {
            job: status.job,
            wall_time_s: wall,
            loops: status.loops,
            alarms: status.alarms,
            outcome,
            backend: format!("{backend:?}"),
        };
        Ok((report, outcome))
    })();
    // wait for a clean shutdown; if it hangs (or the MMI never answered), SIGTERM,
    // which stops the children in order too; SIGKILL only as a last resort
    let waited = |d: &mut std::process::Child, s: u64| -> Result<bool> {
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(s) {
            if d.try_wait()?.is_some() {
                return Ok(true);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(false)
    };
    if !waited(&mut daemon, 10)? {
        let _ = Command::new("kill")
            .args(["-TERM", &daemon.id().to_string()])
            .status();
        if !waited(&mut daemon, 10)? {
            let _ = daemon.kill();
            let _ = daemon.wait();
        }
    }
    let (report, outcome) = result?;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report);
    }
    Ok(if outcome == Outcome::Completed {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// How long a tool change's prompt stands before the demo answers it.
const TOOL_CHANGE_PATIENCE: Duration = Duration::from_millis(500);

/// Until job `job_id` ends: a tool change the job asks the operator for (a
/// machine whose I/O has no tool changer: an EtherCAT bus without the changer's
/// lines) is done at once, as the operator at the machine does — said on standard
/// error; the job's progress every 10 %.
fn answer_tool_changes(op: &Operator, job_id: u64) -> Result<()> {
    let mut answered = None;
    let mut asked: Option<Instant> = None;
    let mut last_pct = -1i64;
    loop {
        let s = op.status()?;
        let Some(job) = s.job(job_id) else {
            // not in the status yet
            std::thread::sleep(Duration::from_millis(100));
            continue;
        };
        if job.record.outcome.ended() {
            return Ok(());
        }
        let pct = (job.progress * 100.0) as i64;
        if pct / 10 != last_pct / 10 {
            eprintln!("job {job_id}: {pct} %");
            last_pct = pct;
        }
        match s.prompt.as_deref() {
            // a tool change the machine does itself (a changer on its lines) asks
            // for a moment only: the operator is asked once it stands
            Some(p) if p.starts_with("insert T") && answered.is_none() => {
                let since = *asked.get_or_insert_with(Instant::now);
                if since.elapsed() >= TOOL_CHANGE_PATIENCE {
                    eprintln!("demo: the job asks \"{p}\": resumed, as the operator at a machine without a tool changer");
                    let r = op.request(&Request::Resume)?;
                    if !r.is_accepted() {
                        eprintln!("demo: resume refused: {}", r.message());
                    }
                    answered = Some(());
                }
            }
            Some(_) => {}
            None => {
                answered = None;
                asked = None;
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Asks the demo's controller to shut down when dropped (the demo ended, or failed).
struct ShutdownOnDrop<'a>(&'a Operator);

impl Drop for ShutdownOnDrop<'_> {
    fn drop(&mut self) {
        let _ = self.0.request(&Request::Shutdown);
    }
}

/// What the demo reports: the job's record at its end, the loops' timing and the
/// alarms (`softnc-api` types).
#[derive(serde::Serialize)]
struct DemoReport {
    job: Option<JobStatus>,
    wall_time_s: f64,
    loops: Loops,
    alarms: Vec<Alarm>,
    outcome: Outcome,
    backend: String,
}

fn print_report(r: &DemoReport) {
    if let Some(j) = &r.job {
        let j = &j.record;
        let a = &j.accuracy;
        println!("job {} {}: {}", j.job_id, j.outcome, j.path);
        println!("  servo backend: {}", r.backend);
        println!(
            "  cycles {} (planned {}), wall time {:.2} s",
            j.cycles, j.planned_samples, r.wall_time_s
        );
        println!(
            "  contour error: max |e| {:.2} µm, rms {:.2} µm",
            a.contour_max_abs_um, a.contour_rms_um
        );
        let f: Vec<String> = a
            .following_max_abs_um
            .iter()
            .map(|v| format!("{v:.1}"))
            .collect();
        println!("  following error max |e| X/Y/Z: {} µm", f.join(" / "));
    }
    for (name, l) in [("interp", r.loops.interp), ("position", r.loops.position)] {
        let Some(l) = l else { continue };
        let us = |v: u64| v as f64 / 1000.0;
        println!(
            "  {name} loop: {} cycles, jitter p50/p99/p99.9/max {:.1}/{:.1}/{:.1}/{:.1} µs, compute p99 {:.1} µs, overruns {}",
            l.cycles,
            us(l.jitter_ns.p50),
            us(l.jitter_ns.p99),
            us(l.jitter_ns.p999),
            us(l.jitter_ns.max),
            us(l.compute_ns.p99),
            l.overruns
        );
        if l.latency_ns.p50 > 0 {
            println!(
                "    interp → position sample latency through iceoryx2 p50/p99/p99.9/max {:.1}/{:.1}/{:.1}/{:.1} µs",
                us(l.latency_ns.p50),
                us(l.latency_ns.p99),
                us(l.latency_ns.p999),
                us(l.latency_ns.max)
            );
        }
    }
    if let Some(b) = r.loops.bus {
        let us = |v: u64| v as f64 / 1000.0;
        let s = b.send_to_receive_ns;
        println!(
            "  EtherCAT (MainDevice): frames {}, lost {}, working-counter errors {}, send-to-receive p50/p99/max {:.0}/{:.0}/{:.1} µs",
            b.frames,
            b.lost_frames,
            b.wkc_errors,
            us(s.p50),
            us(s.p99),
            us(s.max)
        );
        println!(
            "    DC system time difference (0x092C): {} reads, last {:.3} µs, max {:.3} µs",
            b.dc_deviation_reads,
            us(b.dc_deviation_last_ns),
            us(b.dc_deviation_max_ns)
        );
    }
    for al in &r.alarms {
        println!("  alarm {:?}: {}", al.code, al.message);
    }
}
