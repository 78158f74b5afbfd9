//! Operator commands: talk to `softnc-mmi` over iceoryx2 request-response.

use anyhow::{Context, Result};
use softnc_api::{Axis, JobRecord, MachineState, OffsetTable, Outcome, Reply, Request, Status};
pub use softnc_client::Operator;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicI32, Ordering};
use std::time::{Duration, Instant};

/// Operator subcommands.
#[derive(clap::Subcommand)]
pub enum OperatorCmd {
    /// Jobs: `submit FILE [--wait]`.
    #[command(subcommand)]
    Job(JobCmd),
    /// Machine status.
    Status {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Feed hold.
    Hold,
    /// Resume after a feed hold.
    Resume,
    /// Cycle stop: the running (or held) job stops along its path within the
    /// deceleration limits and ends "aborted"; the machine is idle after. The
    /// spindle and the coolant stop (idle too, as LinuxCNC's abort); the M62–M68
    /// outputs stay.
    Abort,
    /// Set the feed override (percent, 0..=255).
    #[command(allow_negative_numbers = true)]
    Override {
        /// Percent.
        pct: f64,
    },
    /// Set the spindle override (percent of the programmed speed, within the
    /// profile's `spindle` range; 50..=120 by default). The PDC of every axis is
    /// redesigned for the new tooth frequency off the cycle and swapped in with the
    /// new speed.
    #[command(allow_negative_numbers = true)]
    SpindleOverride {
        /// Percent.
        pct: f64,
    },
    /// Set the rapid override (percent of the traverse speed, 0..=100): traverses
    /// run at it, feed moves keep the feed override; a change acts within the
    /// lookahead, as the feed override does.
    #[command(allow_negative_numbers = true)]
    RapidOverride {
        /// Percent.
        pct: f64,
    },
    /// Emergency stop.
    Estop,
    /// Reset after a fault or E-stop (refused while a job moves); clears the
    /// machine's alarms (each job's record keeps its own).
    Reset,
    /// Job history, newest first (all of it, fetched page by page).
    Jobs {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Stop the daemon.
    Shutdown,
    /// Machine on: drives enabled, holding position (the daemon starts off).
    On,
    /// Machine off: drives disabled (refused while anything moves).
    Off,
    /// Override the limit switches (LinuxCNC's override limits): with a limit
    /// switch tripped, lets the machine be switched on (`on`) and jogged off it,
    /// away from the switch only; ends by itself once every switch is released.
    /// Refused while none is tripped.
    OverrideLimits,
    /// Home one axis, or all in the profile's order; waits until done.
    Home {
        /// X, Y or Z (default: all).
        axis: Option<String>,
    },
    /// Jog: `jog AXIS SPEED_MM_PER_MIN` runs continuously (to the soft limit once
    /// homed) while this command runs — Ctrl-C (SIGINT) or SIGTERM stops it at once
    /// (the command then exits 128 + the signal: 130, 143), as does `jog AXIS 0` from
    /// elsewhere (a client that goes away stops it within the profile's `jog.deadman_s`);
    /// `jog AXIS --step MM` moves by a distance (a signal stops it too).
    #[command(allow_negative_numbers = true)]
    Jog {
        /// X, Y or Z.
        axis: String,
        /// Speed (mm/min, signed); 0 stops a jog.
        speed: Option<f64>,
        /// Move by this distance (mm, signed) instead, at the profile's jog speed.
        #[arg(long, allow_negative_numbers = true)]
        step: Option<f64>,
    },
    /// Run MDI block(s) with the machine's offsets and parameters; waits until done.
    Mdi {
        /// One block per argument.
        #[arg(required = true)]
        blocks: Vec<String>,
    },
    /// Set the work offset so that the current position reads VALUE on AXIS
    /// (G10 L20), in the active coordinate system or `--coords`.
    #[command(allow_negative_numbers = true)]
    TouchOff {
        /// X, Y or Z.
        axis: String,
        /// The value the current position gets (mm).
        value: f64,
        /// G54 … G59.3 (default: the active one).
        #[arg(long)]
        coords: Option<String>,
    },
    /// The work offsets (G54 … G59.3, G92, tool offset).
    Offsets {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// The tool table; `tools set N --length L [--diameter D]` edits it.
    Tools {
        /// Print JSON.
        #[arg(long)]
        json: bool,
        #[command(subcommand)]
        cmd: Option<ToolsCmd>,
    },
    /// Single block: stop at the end of every block (`step` runs the next).
    SingleBlock {
        /// on or off.
        switch: OnOff,
    },
    /// Single block: run the next block.
    Step,
    /// Optional stop: M1 stops when on.
    OptionalStop {
        /// on or off.
        switch: OnOff,
    },
    /// Block delete: lines starting with `/` are skipped when on.
    BlockDelete {
        /// on or off.
        switch: OnOff,
    },
}

/// A switch position.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

impl OnOff {
    /// True when on.
    pub fn on(self) -> bool {
        self == OnOff::On
    }
}

/// `softnc tools ...`
#[derive(clap::Subcommand)]
pub enum ToolsCmd {
    /// Set a tool's length (and diameter).
    #[command(allow_negative_numbers = true)]
    Set {
        /// Tool number.
        number: u32,
        /// Length offset (mm).
        #[arg(long, allow_negative_numbers = true)]
        length: f64,
        /// Diameter (mm).
        #[arg(long)]
        diameter: Option<f64>,
    },
}

/// The axis of a letter X, Y or Z.
fn axis_of(name: &str) -> Result<Axis> {
    let mut chars = name.chars();
    match (chars.next().and_then(Axis::from_letter), chars.next()) {
        (Some(a @ (Axis::X | Axis::Y | Axis::Z)), None) => Ok(a),
        _ => anyhow::bail!("{name:?} is not an axis (X, Y or Z)"),
    }
}

/// `softnc job ...`
#[derive(clap::Subcommand)]
pub enum JobCmd {
    /// Submit a G-code program.
    Submit {
        /// The program.
        file: PathBuf,
        /// Wait for the job to end, with a progress bar.
        #[arg(long)]
        wait: bool,
        /// Run from this line (LinuxCNC's run-from-line): the lines before it set
        /// the modal state, the machine approaches the start point safely (the
        /// clearance axis first), then the program runs on from there.
        #[arg(long)]
        from_line: Option<u32>,
        /// Adaptive feed (paper 003): the force loop of the profile's
        /// `force.adaptive_feed` drives the feed override, live; the operator's
        /// feed override is its ceiling (at 100 % it can only slow the cut down).
        #[arg(long)]
        adaptive_force: bool,
    },
}

/// Run an operator subcommand against the daemon configured in `config`.
#[allow(clippy::too_many_lines)]
pub fn run(cmd: OperatorCmd, config: &Path) -> Result<ExitCode> {
    let op = Operator::connect(config)?;
    let simple = |request: Request| -> Result<ExitCode> {
        let r = op.request(&request)?;
        println!("{}", r.message());
        Ok(if r.is_accepted() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(crate::EXIT_REFUSED)
        })
    };
    match cmd {
        OperatorCmd::Job(JobCmd::Submit {
            file,
            wait,
            from_line,
            adaptive_force,
        }) => {
            let abs = std::fs::canonicalize(&file).unwrap_or(file.clone());
            if from_line == Some(0) {
                anyhow::bail!("--from-line: lines are numbered from 1");
            }
            let r = op.request(&Request::SubmitJob {
                path: abs.display().to_string(),
                from_line,
                adaptive_force,
            })?;
            if !r.is_accepted() {
                eprintln!("{}", r.message());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message());
            if wait {
                let outcome = wait_job(&op, r.job_id().unwrap_or(0), true)?;
                return Ok(if outcome == Outcome::Completed {
                    ExitCode::SUCCESS
                } else {
                    ExitCode::from(1)
                });
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Status { json } => {
            let s = op.status()?;
            if json {
                println!("{}", serde_json::to_string(&s)?);
            } else {
                print!("{}", status_text(&s));
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Hold => simple(Request::Hold),
        OperatorCmd::Resume => simple(Request::Resume),
        OperatorCmd::Abort => simple(Request::Abort),
        OperatorCmd::Override { pct } => simple(Request::FeedOverride {
            fraction: pct / 100.0,
        }),
        OperatorCmd::SpindleOverride { pct } => simple(Request::SpindleOverride {
            fraction: pct / 100.0,
        }),
        OperatorCmd::RapidOverride { pct } => simple(Request::RapidOverride {
            fraction: pct / 100.0,
        }),
        OperatorCmd::Estop => simple(Request::EStop),
        OperatorCmd::Reset => simple(Request::Reset),
        OperatorCmd::Shutdown => simple(Request::Shutdown),
        OperatorCmd::On => simple(Request::MachineOn),
        OperatorCmd::Off => simple(Request::MachineOff),
        OperatorCmd::OverrideLimits => simple(Request::OverrideLimits),
        OperatorCmd::Step => simple(Request::Step),
        OperatorCmd::SingleBlock { switch } => simple(Request::SingleBlock { on: switch.on() }),
        OperatorCmd::OptionalStop { switch } => simple(Request::OptionalStop { on: switch.on() }),
        OperatorCmd::BlockDelete { switch } => simple(Request::BlockDelete { on: switch.on() }),
        OperatorCmd::Home { axis } => {
            let axis = axis.as_deref().map(axis_of).transpose()?;
            let r = op.request(&Request::Home { axis })?;
            println!("{}", r.message());
            if !r.is_accepted() {
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            let s = wait_while_state(&op, MachineState::Homing)?;
            println!("{} (homed {:?})", s.state, s.homed);
            let all = match axis {
                None => s.all_homed(),
                Some(a) => s.homed.get(a.index()).copied().unwrap_or(false),
            };
            Ok(if all {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            })
        }
        OperatorCmd::Jog { axis, speed, step } => {
            let axis = axis_of(&axis)?;
            let request = match (speed, step) {
                (Some(_), Some(_)) => anyhow::bail!("jog: a speed or --step, not both"),
                (None, None) => anyhow::bail!("jog: a speed (mm/min) or --step MM"),
                (Some(v), None) => Request::Jog {
                    axis,
                    speed_mm_per_min: v,
                },
                (None, Some(d)) => Request::JogStep {
                    axis,
                    distance_mm: d,
                },
            };
            // Ctrl-C (SIGINT) or SIGTERM stops the jog at once instead of ending this
            // command (which would leave the jog to the dead-man); caught from before
            // the request, so that no signal falls between it and the loop below
            let signals = (speed != Some(0.0)).then(JogSignals::catch).transpose()?;
            let r = op.request(&request)?;
            println!("{}", r.message());
            if !r.is_accepted() {
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            if speed == Some(0.0) {
                return Ok(ExitCode::SUCCESS);
            }
            // a continuous jog lives while this command renews it
            let renew = matches!(request, Request::Jog { .. }).then_some(request);
            let s = match jog_until_stopped(&op, renew.as_ref())? {
                JogEnd::Stopped(s) => *s,
                JogEnd::Signal(signal) => return stop_jog_on_signal(&op, axis, signal),
            };
            drop(signals);
            println!(
                "{} at {:.4} mm",
                s.state,
                s.machine_mm.map_or(f64::NAN, |m| m[axis.index()])
            );
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Mdi { blocks } => {
            let r = op.request(&Request::Mdi {
                blocks: blocks.join("\n"),
            })?;
            if !r.is_accepted() {
                eprintln!("{}", r.message());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message());
            let job_id = r.job_id().unwrap_or(0);
            let outcome = wait_job(&op, job_id, false)?;
            println!("MDI {job_id}: {outcome}");
            Ok(if outcome == Outcome::Completed {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            })
        }
        OperatorCmd::TouchOff {
            axis,
            value,
            coords,
        } => {
            let r = op.request(&Request::TouchOff {
                axis: axis_of(&axis)?,
                value_mm: value,
                coords,
            })?;
            if !r.is_accepted() {
                eprintln!("{}", r.message());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message());
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Offsets { json } => {
            let o = op.offsets()?;
            if json {
                println!("{}", serde_json::to_string(&o)?);
            } else {
                print!("{}", offsets_text(&o));
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Tools { json, cmd } => {
            if let Some(ToolsCmd::Set {
                number,
                length,
                diameter,
            }) = cmd
            {
                let r = op.request(&Request::ToolSet {
                    tool: number,
                    length_mm: length,
                    diameter_mm: diameter,
                })?;
                println!("{}", r.message());
                if !r.is_accepted() {
                    return Ok(ExitCode::from(crate::EXIT_REFUSED));
                }
            }
            let tools = match op.request(&Request::Tools)? {
                Reply::Tools(t) => t,
                other => {
                    eprintln!("{}", other.message());
                    return Ok(ExitCode::from(1));
                }
            };
            if json {
                println!("{}", serde_json::to_string(&tools)?);
            } else {
                println!("{:>6} {:>12} {:>12}", "tool", "length mm", "diameter mm");
                for t in &tools {
                    println!(
                        "{:>6} {:>12.4} {:>12.4}",
                        t.number, t.length_mm, t.diameter_mm
                    );
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Jobs { json } => {
            let jobs = op.jobs()?;
            if json {
                println!("{}", serde_json::to_string(&jobs)?);
            } else {
                for j in &jobs {
                    println!("{}", job_line(j));
                }
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// One job of the history as an operator reads it.
fn job_line(j: &JobRecord) -> String {
    format!(
        "{:>4}  {:<11} {:>9} cycles  contour max {:>8.2} µm rms {:>7.2} µm  {}",
        j.job_id,
        j.outcome.name(),
        j.cycles,
        j.accuracy.contour_max_abs_um,
        j.accuracy.contour_rms_um,
        j.path
    )
}

/// Poll the status until its state is no longer `state` (after it has been, or a
/// second has passed); returns the last status.
fn wait_while_state(op: &Operator, state: MachineState) -> Result<Status> {
    let t0 = Instant::now();
    let mut seen = false;
    loop {
        let s = op.status()?;
        seen |= s.state == state;
        if s.state != state && (seen || t0.elapsed() > Duration::from_secs(1)) {
            return Ok(s);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// How often a jog in progress looks for a caught signal.
const JOG_SIGNAL_POLL: Duration = Duration::from_millis(5);

/// How often a jog in progress is renewed and its status read: the operator
/// contract's period, which the daemon keeps below its dead-man.
const JOG_RENEW_PERIOD: Duration = softnc_api::JOG_RENEW_PERIOD;

/// How long the CLI waits for the axis to come to rest after it asked a jog to stop
/// on a signal (the jog's deceleration; beyond it, it reports and exits anyway).
const JOG_STOP_WAIT: Duration = Duration::from_secs(2);

/// How a followed jog ended.
enum JogEnd {
    /// The axis stopped (a step done, a soft limit, `jog AXIS 0`, an abort).
    Stopped(Box<Status>),
    /// SIGINT or SIGTERM arrived (its number) while the axis was moving.
    Signal(libc::c_int),
}

/// The signal caught by [`JogSignals`]' handler; 0 while none has come.
static JOG_SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn on_jog_signal(signal: libc::c_int) {
    // async-signal-safe: one atomic store
    JOG_SIGNAL.store(signal, Ordering::SeqCst);
}

/// SIGINT and SIGTERM caught (they no longer end the process) while this lives;
/// the actions before are put back when it is dropped.
struct JogSignals {
    previous: Vec<(libc::c_int, libc::sigaction)>,
}

impl JogSignals {
    const SIGNALS: [libc::c_int; 2] = [libc::SIGINT, libc::SIGTERM];

    /// Catch SIGINT and SIGTERM. iceoryx2's own handler (installed on its first
    /// use) is set up before, so that it never replaces this one later.
    #[allow(unsafe_code)] // (its SAFETY lines below)
    fn catch() -> Result<JogSignals> {
        let _ = iceoryx2_bb_posix::signal::SignalHandler::last_signal();
        JOG_SIGNAL.store(0, Ordering::SeqCst);
        let mut caught = JogSignals {
            previous: Vec::new(),
        };
        for sig in Self::SIGNALS {
            // SAFETY: zeroed sigactions are valid (no flags, empty mask) before we
            // fill one; the handler only stores to an atomic (async-signal-safe);
            // sigaction is given valid pointers.
            let (rc, previous) = unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                let mut previous: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_jog_signal as extern "C" fn(libc::c_int) as usize;
                action.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut action.sa_mask);
                (libc::sigaction(sig, &action, &mut previous), previous)
            };
            if rc != 0 {
                // `caught` drops: the signals caught so far get their actions back
                return Err(std::io::Error::last_os_error())
                    .context("catching SIGINT/SIGTERM for the jog");
            }
            caught.previous.push((sig, previous));
        }
        Ok(caught)
    }

    /// The signal that has arrived since [`JogSignals::catch`], if any.
    fn caught() -> Option<libc::c_int> {
        match JOG_SIGNAL.load(Ordering::SeqCst) {
            0 => None,
            sig => Some(sig),
        }
    }
}

impl Drop for JogSignals {
    #[allow(unsafe_code)] // (its SAFETY line below)
    fn drop(&mut self) {
        for (sig, previous) in &self.previous {
            // SAFETY: `previous` is the action sigaction returned for `sig`.
            unsafe { libc::sigaction(*sig, previous, std::ptr::null_mut()) };
        }
    }
}

/// A signal's name as an operator knows it.
fn signal_name(signal: libc::c_int) -> String {
    match signal {
        libc::SIGINT => "SIGINT".into(),
        libc::SIGTERM => "SIGTERM".into(),
        other => format!("signal {other}"),
    }
}

/// Follow a jog until the axis stops or SIGINT/SIGTERM arrives (looked for every
/// [`JOG_SIGNAL_POLL`]); a continuous one (`renew`: its request) is renewed every
/// [`JOG_RENEW_PERIOD`] meanwhile — its dead-man stops it once this command is gone.
fn jog_until_stopped(op: &Operator, renew: Option<&Request>) -> Result<JogEnd> {
    let t0 = Instant::now();
    let mut seen = false;
    let mut next_renew = t0;
    loop {
        if let Some(signal) = JogSignals::caught() {
            return Ok(JogEnd::Signal(signal));
        }
        if Instant::now() >= next_renew {
            next_renew = Instant::now() + JOG_RENEW_PERIOD;
            if let Some(request) = renew {
                if !op.request(request)?.is_accepted() {
                    // it ended (a soft limit, `jog AXIS 0`, an abort)
                    return Ok(JogEnd::Stopped(Box::new(op.status()?)));
                }
            }
            let s = op.status()?;
            let jogging = s.state == MachineState::Jogging;
            seen |= jogging;
            if !jogging && (seen || t0.elapsed() > Duration::from_secs(1)) {
                return Ok(JogEnd::Stopped(Box::new(s)));
            }
        }
        std::thread::sleep(JOG_SIGNAL_POLL);
    }
}

/// A jog interrupted by `signal`: ask it to stop (`jog AXIS 0`), wait up to
/// [`JOG_STOP_WAIT`] for the axis to come to rest, say so on stderr; exit status
/// 128 + the signal's number, as a shell reports a command ended by it.
fn stop_jog_on_signal(op: &Operator, axis: Axis, signal: libc::c_int) -> Result<ExitCode> {
    let name = signal_name(signal);
    let stop = Request::Jog {
        axis,
        speed_mm_per_min: 0.0,
    };
    let r = op
        .request(&stop)
        .with_context(|| format!("{name}: the request to stop the jog failed"))?;
    // refused: the jog had just ended by itself ("nothing is jogging")
    eprintln!("{name}: {}", r.message());
    let t0 = Instant::now();
    let s = loop {
        let s = op.status()?;
        if s.state != MachineState::Jogging || t0.elapsed() > JOG_STOP_WAIT {
            break s;
        }
        std::thread::sleep(JOG_SIGNAL_POLL);
    };
    eprintln!(
        "jog of {} stopped by {name}: {} at {:.4} mm",
        axis.name(),
        s.state,
        s.machine_mm.map_or(f64::NAN, |m| m[axis.index()])
    );
    Ok(ExitCode::from(128u8.saturating_add(
        u8::try_from(signal).unwrap_or(u8::MAX - 128),
    )))
}

/// The offsets as an operator reads them.
pub fn offsets_text(o: &OffsetTable) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<7}{:>12}{:>12}{:>12}{:>10}",
        "", "X", "Y", "Z", "R deg"
    );
    for sys in &o.systems {
        let m = sys.origin_mm;
        let _ = writeln!(
            out,
            "{:<7}{:>12.4}{:>12.4}{:>12.4}{:>10.3}{}",
            sys.coords,
            m[0],
            m[1],
            m[2],
            sys.rotation_deg,
            if sys.active { "  active" } else { "" }
        );
    }
    let g = o.g92_mm;
    let _ = writeln!(
        out,
        "{:<7}{:>12.4}{:>12.4}{:>12.4}",
        "G92", g[0], g[1], g[2]
    );
    let t = o.tool_offset_mm;
    let _ = writeln!(
        out,
        "tool {} offset {:.4} {:.4} {:.4}",
        o.tool, t[0], t[1], t[2]
    );
    out
}

/// A number or NaN (not reported).
fn or_nan(v: Option<f64>) -> f64 {
    v.unwrap_or(f64::NAN)
}

/// The status as an operator reads it (`--json` gives all of it).
pub fn status_text(s: &Status) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "state {}   feed override {:.0} %   rapid override {:.0} %   spindle {:.0} rpm (override {:.0} %)",
        s.state,
        s.feed_override * 100.0,
        s.rapid_override * 100.0,
        or_nan(s.spindle_rpm),
        or_nan(s.spindle_override) * 100.0
    );
    let sw = s.switches;
    let on: Vec<&str> = [
        (sw.single_block, "single block"),
        (sw.optional_stop, "optional stop"),
        (sw.block_delete, "block delete"),
    ]
    .into_iter()
    .filter(|(on, _)| *on)
    .map(|(_, name)| name)
    .collect();
    if !on.is_empty() {
        let _ = writeln!(out, "switches on: {}", on.join(", "));
    }
    if let Some(modal) = &s.modal {
        let _ = writeln!(out, "modal: {}", modal.join(" "));
    }
    if let Some(j) = &s.job {
        let _ = writeln!(
            out,
            "job {} {} {:.0} %   {}",
            j.record.job_id,
            j.record.outcome,
            j.progress * 100.0,
            j.record.path
        );
        if let Some(line) = s.program_line {
            let _ = writeln!(out, "    at program line {line}");
        }
        if let Some(path) = &s.checking {
            let _ = writeln!(out, "    checking {path}");
        }
        if let Some(af) = &s.adaptive_force {
            let _ = writeln!(
                out,
                "    adaptive force: override {:.0} %, {} revolutions, last force estimate {:.0} N",
                af.override_fraction * 100.0,
                af.revolutions,
                or_nan(af.force_n)
            );
        }
        let a = &j.record.accuracy;
        let _ = writeln!(
            out,
            "    contour error max {:.2} µm, rms {:.2} µm",
            a.contour_max_abs_um, a.contour_rms_um
        );
    } else {
        let _ = writeln!(out, "no job yet");
    }
    if let Some(ax) = &s.axes {
        let row = |name: &str, v: &[f64]| {
            let cells: Vec<String> = v.iter().map(|x| format!("{x:>12.4}")).collect();
            format!("{name:<18}{}\n", cells.join(""))
        };
        let homed = |i: usize| match s.homed.get(i) {
            Some(true) => "homed",
            Some(false) => "NOT homed",
            None => "",
        };
        let _ = writeln!(
            out,
            "{:<18}{:>12}{:>12}{:>12}",
            "",
            format!("X {}", homed(0)),
            format!("Y {}", homed(1)),
            format!("Z {}", homed(2))
        );
        out.push_str(&row(
            &format!("work mm ({})", s.coords),
            &s.work_mm.map(|w| w.to_vec()).unwrap_or_default(),
        ));
        out.push_str(&row("to go mm", &s.distance_to_go_mm));
        out.push_str(&row("command mm", &ax.cmd_mm));
        out.push_str(&row("actual mm", &ax.actual_mm));
        out.push_str(&row("following err µm", &ax.following_err_um));
    }
    let p = s.processes;
    let _ = writeln!(
        out,
        "processes: interpolation {}, position {}, supervisor {}",
        p.interp, p.position, p.supervisor
    );
    if s.alarms.is_empty() {
        let _ = writeln!(out, "no alarms");
    }
    for a in &s.alarms {
        let _ = writeln!(out, "alarm {:?} (job {}): {}", a.code, a.job_id, a.message);
    }
    out
}

/// What an operator waiting for the job in `status` is told when it ends other
/// than completed: how it ended and why (its record's alarms, else the machine's
/// alarms about it). `None` for a completed job, or when no job is shown.
pub fn job_end_message(status: &Status) -> Option<String> {
    let job = &status.job.as_ref()?.record;
    if job.outcome == Outcome::Completed {
        return None;
    }
    let id = job.job_id;
    let mut why = job.alarms.clone();
    if why.is_empty() {
        why = status
            .alarms
            .iter()
            .filter(|a| a.job_id == id)
            .map(|a| format!("{:?}: {}", a.code, a.message))
            .collect();
    }
    Some(if why.is_empty() {
        format!("job {id} {}", job.outcome)
    } else {
        format!("job {id} {}: {}", job.outcome, why.join("; "))
    })
}

/// Follow a job until it ends; returns its outcome. Shows a progress bar on a terminal.
pub fn wait_job(op: &Operator, job_id: u64, bar: bool) -> Result<Outcome> {
    use std::io::IsTerminal;
    let pb = if bar && std::io::stderr().is_terminal() {
        let pb = indicatif::ProgressBar::new(1000);
        pb.set_style(
            indicatif::ProgressStyle::with_template(
                "{spinner} job {msg} [{bar:40}] {percent:>3}% {elapsed}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        pb.set_message(job_id.to_string());
        Some(pb)
    } else {
        None
    };
    let mut last_pct = -1i64;
    loop {
        let s = op.status()?;
        if let Some(job) = s.job(job_id) {
            let progress = job.progress;
            if let Some(pb) = &pb {
                pb.set_position((progress * 1000.0) as u64);
            } else if bar {
                let pct = (progress * 100.0) as i64;
                if pct / 10 != last_pct / 10 {
                    eprintln!("job {job_id}: {pct} %");
                    last_pct = pct;
                }
            }
            let outcome = job.record.outcome;
            if outcome.ended() {
                if let Some(pb) = &pb {
                    pb.finish_and_clear();
                }
                if let Some(why) = job_end_message(&s) {
                    eprintln!("{why}");
                }
                return Ok(outcome);
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[cfg(test)]
mod job_end_tests {
    use super::job_end_message;
    use softnc_api::Status;

    /// A status read from JSON (the fields the test does not name as an idle
    /// machine's).
    fn status(job: serde_json::Value, alarms: serde_json::Value) -> Status {
        let v = serde_json::json!({"state": "Idle", "coords": "G54",
            "offsets": {"g5x_mm": [0.0, 0.0, 0.0], "rotation_deg": 0.0,
                "g92_mm": [0.0, 0.0, 0.0], "tool_offset_mm": [0.0, 0.0, 0.0]},
            "tool": 0, "feed_override": 1.0,
            "processes": {"interp": "alive", "position": "alive", "supervisor": "alive"},
            "job": job, "alarms": alarms});
        serde_json::from_value(v).unwrap()
    }

    #[test]
    fn a_job_that_did_not_complete_says_how_it_ended_and_why() {
        let refused = status(
            serde_json::json!({"job_id": 4, "path": "/shop/a.ngc", "outcome": "refused",
                "alarms": ["JobRefused: /shop/a.ngc:2:1: Subroutine 'Oside' not found"]}),
            serde_json::json!([]),
        );
        assert_eq!(
            job_end_message(&refused).unwrap(),
            "job 4 refused: JobRefused: /shop/a.ngc:2:1: Subroutine 'Oside' not found"
        );
        // the record has none yet: the machine's alarms about the job
        let aborted = status(
            serde_json::json!({"job_id": 5, "path": "/shop/b.ngc", "outcome": "aborted", "alarms": []}),
            serde_json::json!([{"code": "FollowingError", "job_id": 5, "message": "X 2.1 mm"},
                       {"code": "Other", "job_id": 0, "message": "unrelated"}]),
        );
        assert_eq!(
            job_end_message(&aborted).unwrap(),
            "job 5 aborted: FollowingError: X 2.1 mm"
        );
        let bare = status(
            serde_json::json!({"job_id": 6, "path": "/shop/c.ngc", "outcome": "aborted"}),
            serde_json::json!([]),
        );
        assert_eq!(job_end_message(&bare).unwrap(), "job 6 aborted");
        let done = status(
            serde_json::json!({"job_id": 7, "path": "/shop/d.ngc", "outcome": "completed"}),
            serde_json::json!([]),
        );
        assert_eq!(job_end_message(&done), None);
    }
}

#[cfg(test)]
mod parse_tests {
    use super::OperatorCmd;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(subcommand)]
        cmd: OperatorCmd,
    }

    #[test]
    fn override_limits_is_a_subcommand() {
        let cli = Cli::try_parse_from(["softnc", "override-limits"]).unwrap();
        assert!(matches!(cli.cmd, OperatorCmd::OverrideLimits));
    }
}
