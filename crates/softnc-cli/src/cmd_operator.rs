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
    Override {
        /// Percent.
        pct: f64,
    },
    /// Set the spindle override (percent of the programmed speed, within the
    /// profile's `spindle` range; 50..=120 by default). The PDC of every axis is
    /// redesigned for the new tooth frequency off the cycle and swapped in with the
    /// new speed.
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
        OperatorCmd::Job(JobCmd::Submit { file, wait }) => {
            let abs = std::fs::canonicalize(&file).unwrap_or(file.clone());
            let r = op.request(ControlKind::StartJob, 0.0, &abs.display().to_string())?;
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
        let _ = writeln!(out, "{:<18}{:>12}{:>12}{:>12}", "", "X", "Y", "Z");
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
                return Ok(outcome);
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}
