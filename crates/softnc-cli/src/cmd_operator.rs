//! Operator commands: talk to `softnc-mmi` over iceoryx2 request-response.

use anyhow::Result;
pub use softnc_daemon::client::Operator;
use softnc_ipc::ControlKind;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

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
    /// deceleration limits and ends "aborted"; the machine is idle after.
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
    /// Home one axis, or all in the profile's order; waits until done.
    Home {
        /// X, Y or Z (default: all).
        axis: Option<String>,
    },
    /// Jog: `jog AXIS SPEED_MM_PER_MIN` runs continuously (to the soft limit once
    /// homed) while this command runs — Ctrl-C, or `jog AXIS 0` from elsewhere,
    /// stops it (a client that goes away stops it within `jog_deadman_s`);
    /// `jog AXIS --step MM` moves by a distance.
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

/// The axis index of a letter X, Y or Z.
fn axis_index(name: &str) -> Result<u32> {
    match name.to_ascii_uppercase().as_str() {
        "X" => Ok(0),
        "Y" => Ok(1),
        "Z" => Ok(2),
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
pub fn run(cmd: OperatorCmd, config: &Path) -> Result<ExitCode> {
    let op = Operator::connect(config)?;
    let simple = |kind, value| -> Result<ExitCode> {
        let r = op.request(kind, value, "")?;
        println!("{}", r.message.as_str());
        Ok(if r.accepted == 1 {
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
            let flags = if adaptive_force {
                softnc_ipc::JOB_ADAPTIVE_FORCE
            } else {
                0
            };
            let r = op.submit_job(&abs.display().to_string(), from_line.unwrap_or(0), flags)?;
            if r.accepted != 1 {
                eprintln!("{}", r.message.as_str());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message.as_str());
            if wait {
                let outcome = wait_job(&op, r.job_id, true)?;
                return Ok(if outcome == "completed" {
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
                println!("{s}");
            } else {
                print!("{}", status_text(&s));
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Hold => simple(ControlKind::Hold, 0.0),
        OperatorCmd::Resume => simple(ControlKind::Resume, 0.0),
        OperatorCmd::Abort => simple(ControlKind::Abort, 0.0),
        OperatorCmd::Override { pct } => simple(ControlKind::FeedOverride, pct / 100.0),
        OperatorCmd::SpindleOverride { pct } => simple(ControlKind::SpindleOverride, pct / 100.0),
        OperatorCmd::Estop => simple(ControlKind::EStop, 0.0),
        OperatorCmd::Reset => simple(ControlKind::Reset, 0.0),
        OperatorCmd::Shutdown => simple(ControlKind::Shutdown, 0.0),
        OperatorCmd::On => simple(ControlKind::MachineOn, 0.0),
        OperatorCmd::Off => simple(ControlKind::MachineOff, 0.0),
        OperatorCmd::Step => simple(ControlKind::Step, 0.0),
        OperatorCmd::SingleBlock { switch } => {
            simple(ControlKind::SingleBlock, (switch == OnOff::On) as u8 as f64)
        }
        OperatorCmd::OptionalStop { switch } => simple(
            ControlKind::OptionalStop,
            (switch == OnOff::On) as u8 as f64,
        ),
        OperatorCmd::BlockDelete { switch } => {
            simple(ControlKind::BlockDelete, (switch == OnOff::On) as u8 as f64)
        }
        OperatorCmd::Home { axis } => {
            let axis = axis.as_deref().map(axis_index).transpose()?;
            let r = op.request_axis(ControlKind::Home, axis.unwrap_or(u32::MAX), 0.0, "")?;
            println!("{}", r.message.as_str());
            if r.accepted != 1 {
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            let s = wait_while_state(&op, "Homing")?;
            let homed = s["homed"].clone();
            println!("{} (homed {homed})", s["state"].as_str().unwrap_or("?"));
            let all = axis.map_or_else(
                || {
                    homed
                        .as_array()
                        .is_some_and(|h| h.iter().all(|b| b == true))
                },
                |i| homed[i as usize] == true,
            );
            Ok(if all {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(1)
            })
        }
        OperatorCmd::Jog { axis, speed, step } => {
            let i = axis_index(&axis)?;
            let (kind, value) = match (speed, step) {
                (Some(_), Some(_)) => anyhow::bail!("jog: a speed or --step, not both"),
                (None, None) => anyhow::bail!("jog: a speed (mm/min) or --step MM"),
                (Some(v), None) => (ControlKind::Jog, v),
                (None, Some(d)) => (ControlKind::JogStep, d),
            };
            let r = op.request_axis(kind, i, value, "")?;
            println!("{}", r.message.as_str());
            if r.accepted != 1 {
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            if kind == ControlKind::Jog && value == 0.0 {
                return Ok(ExitCode::SUCCESS);
            }
            // a continuous jog lives while this command renews it
            let renew = (kind == ControlKind::Jog).then_some((i, value));
            let s = jog_until_stopped(&op, renew)?;
            println!(
                "{} at {:.4} mm",
                s["state"].as_str().unwrap_or("?"),
                s["machine_mm"][i as usize].as_f64().unwrap_or(f64::NAN)
            );
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Mdi { blocks } => {
            let r = op.request(ControlKind::Mdi, 0.0, &blocks.join("\n"))?;
            if r.accepted != 1 {
                eprintln!("{}", r.message.as_str());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message.as_str());
            let outcome = wait_job(&op, r.job_id, false)?;
            println!("MDI {}: {outcome}", r.job_id);
            Ok(if outcome == "completed" {
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
            let i = axis_index(&axis)?;
            let r = op.request_axis(
                ControlKind::TouchOff,
                i,
                value,
                coords.as_deref().unwrap_or(""),
            )?;
            if r.accepted != 1 {
                eprintln!("{}", r.message.as_str());
                return Ok(ExitCode::from(crate::EXIT_REFUSED));
            }
            println!("{}", r.message.as_str());
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Offsets { json } => {
            let r = op.request(ControlKind::Offsets, 0.0, "")?;
            let v: serde_json::Value = serde_json::from_str(r.message.as_str())?;
            if json {
                println!("{v}");
            } else {
                print!("{}", offsets_text(&v));
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
                let d = diameter.map(|d| d.to_string()).unwrap_or_default();
                let r = op.request_axis(ControlKind::ToolSet, number, length, &d)?;
                println!("{}", r.message.as_str());
                if r.accepted != 1 {
                    return Ok(ExitCode::from(crate::EXIT_REFUSED));
                }
            }
            let r = op.request(ControlKind::Tools, 0.0, "")?;
            if r.accepted != 1 {
                eprintln!("{}", r.message.as_str());
                return Ok(ExitCode::from(1));
            }
            let v: serde_json::Value = serde_json::from_str(r.message.as_str())?;
            if json {
                println!("{v}");
            } else {
                println!("{:>6} {:>12} {:>12}", "tool", "length mm", "diameter mm");
                for t in v.as_array().into_iter().flatten() {
                    println!(
                        "{:>6} {:>12.4} {:>12.4}",
                        t["number"],
                        t["length_mm"].as_f64().unwrap_or(f64::NAN),
                        t["diameter_mm"].as_f64().unwrap_or(f64::NAN)
                    );
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        OperatorCmd::Jobs { json } => {
            let jobs = op.jobs()?;
            if json {
                println!("{}", serde_json::Value::Array(jobs));
            } else {
                for j in &jobs {
                    println!(
                        "{:>4}  {:<11} {:>9} cycles  contour max {:>8.2} µm rms {:>7.2} µm  {}",
                        j["job_id"],
                        j["outcome"].as_str().unwrap_or(""),
                        j["cycles"],
                        j["accuracy"]["contour_max_abs_um"].as_f64().unwrap_or(0.0),
                        j["accuracy"]["contour_rms_um"].as_f64().unwrap_or(0.0),
                        j["path"].as_str().unwrap_or("")
                    );
                }
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}

/// Poll the status until its state is no longer `state` (after it has been, or a
/// second has passed); returns the last status.
fn wait_while_state(op: &Operator, state: &str) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let mut seen = false;
    loop {
        let s = op.status()?;
        let now = s["state"].as_str().unwrap_or("");
        seen |= now == state;
        if now != state && (seen || t0.elapsed() > Duration::from_secs(1)) {
            return Ok(s);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Follow a jog until the axis stops; a continuous one (`renew`: axis, speed) is
/// renewed meanwhile — its dead-man stops it once this command is gone.
fn jog_until_stopped(op: &Operator, renew: Option<(u32, f64)>) -> Result<serde_json::Value> {
    let t0 = std::time::Instant::now();
    let mut seen = false;
    loop {
        if let Some((axis, speed)) = renew {
            let r = op.request_axis(ControlKind::Jog, axis, speed, "")?;
            if r.accepted != 1 {
                // it ended (a soft limit, `jog AXIS 0`, an abort)
                return op.status();
            }
        }
        let s = op.status()?;
        let jogging = s["state"].as_str() == Some("Jogging");
        seen |= jogging;
        if !jogging && (seen || t0.elapsed() > Duration::from_secs(1)) {
            return Ok(s);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// The offsets as an operator reads them.
pub fn offsets_text(v: &serde_json::Value) -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let _ = writeln!(
        out,
        "{:<7}{:>12}{:>12}{:>12}{:>10}",
        "", "X", "Y", "Z", "R deg"
    );
    for sys in v["systems"].as_array().into_iter().flatten() {
        let o = &sys["origin_mm"];
        let _ = writeln!(
            out,
            "{:<7}{:>12.4}{:>12.4}{:>12.4}{:>10.3}{}",
            sys["coords"].as_str().unwrap_or("?"),
            f(&o[0]),
            f(&o[1]),
            f(&o[2]),
            f(&sys["rotation_deg"]),
            if sys["active"] == true {
                "  active"
            } else {
                ""
            }
        );
    }
    let g = &v["g92_mm"];
    let _ = writeln!(
        out,
        "{:<7}{:>12.4}{:>12.4}{:>12.4}",
        "G92",
        f(&g[0]),
        f(&g[1]),
        f(&g[2])
    );
    let t = &v["tool_offset_mm"];
    let _ = writeln!(
        out,
        "tool {} offset {:.4} {:.4} {:.4}",
        v["tool"],
        f(&t[0]),
        f(&t[1]),
        f(&t[2])
    );
    out
}

/// The status as an operator reads it (`--json` gives all of it).
pub fn status_text(s: &serde_json::Value) -> String {
    use std::fmt::Write;
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let mut out = String::new();
    let _ = writeln!(
        out,
        "state {}   feed override {:.0} %   spindle {:.0} rpm (override {:.0} %)",
        s["state"].as_str().unwrap_or("?"),
        f(&s["feed_override"]) * 100.0,
        f(&s["spindle_rpm"]),
        f(&s["spindle_override"]) * 100.0
    );
    let sw = &s["switches"];
    let on: Vec<&str> = [
        ("single_block", "single block"),
        ("optional_stop", "optional stop"),
        ("block_delete", "block delete"),
    ]
    .into_iter()
    .filter(|(k, _)| sw[*k] == true)
    .map(|(_, name)| name)
    .collect();
    if !on.is_empty() {
        let _ = writeln!(out, "switches on: {}", on.join(", "));
    }
    if let Some(modal) = s["modal"].as_array() {
        let words: Vec<&str> = modal.iter().filter_map(|w| w.as_str()).collect();
        let _ = writeln!(out, "modal: {}", words.join(" "));
    }
    let j = &s["job"];
    if !j.is_null() {
        let _ = writeln!(
            out,
            "job {} {} {:.0} %   {}",
            j["job_id"],
            j["outcome"].as_str().unwrap_or("?"),
            f(&j["progress"]) * 100.0,
            j["path"].as_str().unwrap_or("")
        );
        if let Some(line) = s["program_line"].as_u64() {
            let _ = writeln!(out, "    at program line {line}");
        }
        if let Some(path) = s["checking"].as_str() {
            let _ = writeln!(out, "    checking {path}");
        }
        let af = &s["adaptive_force"];
        if !af.is_null() {
            let _ = writeln!(
                out,
                "    adaptive force: override {:.0} %, {} revolutions, last force estimate {:.0} N",
                f(&af["override"]) * 100.0,
                af["revolutions"],
                f(&af["force_n"])
            );
        }
        let a = &j["accuracy"];
        let _ = writeln!(
            out,
            "    contour error max {:.2} µm, rms {:.2} µm",
            f(&a["contour_max_abs_um"]),
            f(&a["contour_rms_um"])
        );
    } else {
        let _ = writeln!(out, "no job yet");
    }
    let ax = &s["axes"];
    if !ax.is_null() {
        let row = |name: &str, v: &serde_json::Value, k: f64| {
            let cells: Vec<String> = v
                .as_array()
                .into_iter()
                .flatten()
                .map(|x| format!("{:>12.4}", x.as_f64().unwrap_or(f64::NAN) * k))
                .collect();
            format!("{name:<18}{}\n", cells.join(""))
        };
        let homed: Vec<&str> = s["homed"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|h| if h == true { "homed" } else { "NOT homed" })
            .collect();
        let _ = writeln!(
            out,
            "{:<18}{:>12}{:>12}{:>12}",
            "",
            format!("X {}", homed.first().unwrap_or(&"")),
            format!("Y {}", homed.get(1).unwrap_or(&"")),
            format!("Z {}", homed.get(2).unwrap_or(&""))
        );
        out.push_str(&row(
            &format!("work mm ({})", s["coords"].as_str().unwrap_or("?")),
            &s["work_mm"],
            1.0,
        ));
        out.push_str(&row("command mm", &ax["cmd_mm"], 1.0));
        out.push_str(&row("actual mm", &ax["actual_mm"], 1.0));
        out.push_str(&row("following err µm", &ax["following_err_um"], 1.0));
    }
    let p = &s["processes"];
    let _ = writeln!(
        out,
        "processes: interpolation {}, position {}, supervisor {}",
        p["interp"].as_str().unwrap_or("?"),
        p["position"].as_str().unwrap_or("?"),
        p["supervisor"].as_str().unwrap_or("?")
    );
    let alarms = s["alarms"].as_array().cloned().unwrap_or_default();
    if alarms.is_empty() {
        let _ = writeln!(out, "no alarms");
    }
    for a in alarms {
        let _ = writeln!(
            out,
            "alarm {} (job {}): {}",
            a["code"].as_str().unwrap_or("?"),
            a["job_id"],
            a["message"].as_str().unwrap_or("")
        );
    }
    out
}

/// Follow a job until it ends; returns its outcome. Shows a progress bar on a terminal.
/// What an operator waiting for the job in `status` is told when it ends other
/// than completed: how it ended and why (its record's alarms, else the machine's
/// alarms about it). `None` for a completed job.
pub fn job_end_message(status: &serde_json::Value) -> Option<String> {
    let job = &status["job"];
    let outcome = job["outcome"].as_str().unwrap_or("ended");
    if outcome == "completed" {
        return None;
    }
    let id = job["job_id"].as_u64().unwrap_or(0);
    let texts = |v: &serde_json::Value| -> Vec<String> {
        v.as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|x| x.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default()
    };
    let mut why = texts(&job["alarms"]);
    if why.is_empty() {
        why = status["alarms"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter(|x| x["job_id"].as_u64() == Some(id))
                    .filter_map(|x| {
                        Some(format!(
                            "{}: {}",
                            x["code"].as_str()?,
                            x["message"].as_str()?
                        ))
                    })
                    .collect()
            })
            .unwrap_or_default();
    }
    Some(if why.is_empty() {
        format!("job {id} {outcome}")
    } else {
        format!("job {id} {outcome}: {}", why.join("; "))
    })
}

pub fn wait_job(op: &Operator, job_id: u64, bar: bool) -> Result<String> {
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
        let job = &s["job"];
        if job["job_id"].as_u64() == Some(job_id) {
            let progress = job["progress"].as_f64().unwrap_or(0.0);
            if let Some(pb) = &pb {
                pb.set_position((progress * 1000.0) as u64);
            } else if bar {
                let pct = (progress * 100.0) as i64;
                if pct / 10 != last_pct / 10 {
                    eprintln!("job {job_id}: {pct} %");
                    last_pct = pct;
                }
            }
            let outcome = job["outcome"].as_str().unwrap_or("").to_string();
            if outcome != "running" {
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

    #[test]
    fn a_job_that_did_not_complete_says_how_it_ended_and_why() {
        let refused = serde_json::json!({"job": {"job_id": 4, "outcome": "refused",
            "alarms": ["JobRefused: /shop/a.ngc:2:1: Subroutine 'Oside' not found"]},
            "alarms": []});
        assert_eq!(
            job_end_message(&refused).unwrap(),
            "job 4 refused: JobRefused: /shop/a.ngc:2:1: Subroutine 'Oside' not found"
        );
        // the record has none yet: the machine's alarms about the job
        let aborted = serde_json::json!({"job": {"job_id": 5, "outcome": "aborted", "alarms": []},
            "alarms": [{"code": "FollowingError", "job_id": 5, "message": "X 2.1 mm"},
                       {"code": "Other", "job_id": 0, "message": "unrelated"}]});
        assert_eq!(
            job_end_message(&aborted).unwrap(),
            "job 5 aborted: FollowingError: X 2.1 mm"
        );
        let bare = serde_json::json!({"job": {"job_id": 6, "outcome": "aborted"}});
        assert_eq!(job_end_message(&bare).unwrap(), "job 6 aborted");
        let done = serde_json::json!({"job": {"job_id": 7, "outcome": "completed"}});
        assert_eq!(job_end_message(&done), None);
    }
}
