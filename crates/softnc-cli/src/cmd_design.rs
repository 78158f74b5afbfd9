//! `softnc design pdc --machine P --fd HZ [--axis x|y] [--json]`: design the
//! periodic disturbance canceller of paper 000 for one axis and print L, W, H·P_n
//! at f_d and the eq 13 robust margin. A design that fails eq 11–13 is refused
//! (exit 2).
//!
//! The nominal plant P_n comes from the machine profile's servo section
//! (`PlantModel::VelocityLoop`) when `config/machines/<P>.ron` exists; otherwise
//! from the `plants` section of the compensator design file
//! `config/pdc/<P>.ron` (or `config/pdc/<P without -pdc>.ron`), which also holds
//! the PDC/DOB/MBDA design parameters.

use anyhow::Result;
use serde::Serialize;
use softnc_control::pdc;
use softnc_experiments::pdc_profile::{load_pdc_profile, nominal_plant, pdc_profile_path};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `softnc design`.
#[derive(clap::Args)]
pub struct DesignArgs {
    #[command(subcommand)]
    what: DesignWhat,
}

#[derive(clap::Subcommand)]
enum DesignWhat {
    /// Periodic disturbance canceller (paper 000): L, W, H = L·W, eq 11–13 checks.
    Pdc(PdcArgs),
}

#[derive(clap::Args)]
struct PdcArgs {
    /// Machine: a profile name (`tnv40-pdc` → config/machines/tnv40-pdc.ron) or a path.
    #[arg(long)]
    machine: String,
    /// Disturbance frequency f_d = rpm · flutes / 60 (Hz).
    #[arg(long)]
    fd: f64,
    /// Axis to design for.
    #[arg(long, default_value = "x")]
    axis: String,
    /// Compensator design file; default config/pdc/<machine>.ron.
    #[arg(long)]
    pdc_profile: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

/// What `design pdc --json` prints.
#[derive(Debug, Serialize)]
struct PdcReport {
    machine: String,
    axis: String,
    plant_source: String,
    fd_hz: f64,
    sample_time_s: f64,
    l_taps: Vec<f64>,
    delay_samples: usize,
    l_gain_at_fd: f64,
    l_gain_nyquist_db: f64,
    w_taps: Vec<f64>,
    w_unshaped_gain_nyquist_db: f64,
    h_taps: Vec<f64>,
    hp_gain_at_fd: f64,
    hp_phase_deg_at_fd: f64,
    hp_gain_dc: f64,
    robust_margin: f64,
    robust_margin_freq_hz: f64,
}

/// Run `softnc design`.
pub fn run(args: DesignArgs) -> Result<ExitCode> {
    match args.what {
        DesignWhat::Pdc(a) => run_pdc(a),
    }
}

fn run_pdc(a: PdcArgs) -> Result<ExitCode> {
    let ppath = pdc_profile_path(&a.machine, a.pdc_profile.as_ref());
    let profile = load_pdc_profile(&ppath)?;
    let (model, sample_time_s, plant_source) = nominal_plant(&a.machine, &profile, &a.axis)?;
    let d = match pdc::design(&profile.pdc, &model, sample_time_s, a.fd) {
        Ok(d) => d,
        Err(e) => {
            if a.json {
                println!("{}", serde_json::json!({ "refused": e.to_string() }));
            }
            eprintln!("softnc: PDC design refused: {e}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
    };
    let report = PdcReport {
        machine: a.machine.clone(),
        axis: a.axis.to_ascii_uppercase(),
        plant_source,
        fd_hz: d.fd_hz,
        sample_time_s: d.sample_time_s,
        l_taps: d.l_taps,
        delay_samples: d.delay_samples,
        l_gain_at_fd: d.l_gain_at_fd,
        l_gain_nyquist_db: d.l_gain_nyquist_db,
        w_taps: d.w_taps,
        w_unshaped_gain_nyquist_db: d.w_unshaped_gain_nyquist_db,
        h_taps: d.h_taps,
        hp_gain_at_fd: d.hp_gain_at_fd,
        hp_phase_deg_at_fd: d.hp_phase_deg_at_fd,
        hp_gain_dc: d.hp_gain_dc,
        robust_margin: d.robust_margin,
        robust_margin_freq_hz: d.robust_margin_freq_hz,
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let r = &report;
        println!(
            "PDC for {} axis {} at f_d = {} Hz (T = {} s)",
            r.machine, r.axis, r.fd_hz, r.sample_time_s
        );
        println!("  plant:      {}", r.plant_source);
        println!(
            "  L:          {} taps, delay D_L = {} samples, M_L = |L(f_d)| = {:.4}, |L(f_s/2)| = {:.1} dB",
            r.l_taps.len(),
            r.delay_samples,
            r.l_gain_at_fd,
            r.l_gain_nyquist_db
        );
        println!(
            "  W:          {:?} (unshaped W for P_n: {:.1} dB at f_s/2)",
            r.w_taps, r.w_unshaped_gain_nyquist_db
        );
        println!(
            "  H·P_n(f_d): {:.4} at {:.3} deg (eq 11-12); H·P_n(0) = {:.3}",
            r.hp_gain_at_fd, r.hp_phase_deg_at_fd, r.hp_gain_dc
        );
        println!(
            "  eq 13:      robust margin {:.3} (worst at {:.1} Hz)",
            r.robust_margin, r.robust_margin_freq_hz
        );
    }
    Ok(ExitCode::SUCCESS)
}
