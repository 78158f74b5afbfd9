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

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use softnc_control::discrete_tf::DiscreteTf;
use softnc_control::dob::DobConfig;
use softnc_control::mbda::MbdaConfig;
use softnc_control::pdc::{self, PdcConfig};
use softnc_core::servo::PlantModel;
use softnc_core::MachineProfile;
use std::path::{Path, PathBuf};
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

/// The compensator design file (`config/pdc/*.ron`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdcProfile {
    /// Sample time of the plant models (s).
    pub sample_time_s: f64,
    /// Fallback nominal plants P_n per axis (used when the machine profile has none).
    pub plants: Vec<AxisPlant>,
    /// PDC design parameters.
    pub pdc: PdcConfig,
    /// DOB Q filter.
    pub dob: DobConfig,
    /// MBDA PI gains.
    pub mbda: MbdaConfig,
}

/// A nominal plant in z⁻¹.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisPlant {
    /// Axis name ("X", "Y", …).
    pub axis: String,
    /// Numerator b_0, b_1, ….
    pub num: Vec<f64>,
    /// Denominator a_0, a_1, ….
    pub den: Vec<f64>,
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

/// A path relative to the current directory, else to the workspace root.
pub fn resolve(rel: &Path) -> PathBuf {
    if rel.exists() || rel.is_absolute() {
        return rel.to_path_buf();
    }
    let ws = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel);
    if ws.exists() {
        ws
    } else {
        rel.to_path_buf()
    }
}

/// The machine profile path for a name or path.
pub fn machine_path(machine: &str) -> PathBuf {
    let p = PathBuf::from(machine);
    if machine.ends_with(".ron") || p.exists() {
        return resolve(&p);
    }
    resolve(&PathBuf::from(format!("config/machines/{machine}.ron")))
}

/// The compensator design file for a machine name or profile path.
pub fn pdc_profile_path(machine: &str, explicit: Option<&PathBuf>) -> PathBuf {
    if let Some(p) = explicit {
        return resolve(p);
    }
    let stem = Path::new(machine)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| machine.to_string());
    let first = resolve(&PathBuf::from(format!("config/pdc/{stem}.ron")));
    if first.exists() {
        return first;
    }
    let short = stem.trim_end_matches("-pdc");
    resolve(&PathBuf::from(format!("config/pdc/{short}.ron")))
}

/// Load a compensator design file, naming the bad field on error.
pub fn load_pdc_profile(path: &Path) -> Result<PdcProfile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read compensator design file {}", path.display()))?;
    Ok(softnc_core::config::parse_ron(
        &text,
        &path.display().to_string(),
    )?)
}

fn axis_index(axis: &str) -> Result<usize> {
    match axis.to_ascii_lowercase().as_str() {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => bail!("unknown axis `{other}` (x, y or z)"),
    }
}

/// Nominal plant of `axis` and its sample time: from the machine profile's servo
/// section when the profile exists, else from the design file. Also says where from.
pub fn nominal_plant(
    machine: &str,
    profile: &PdcProfile,
    axis: &str,
) -> Result<(DiscreteTf, f64, String)> {
    let idx = axis_index(axis)?;
    let mpath = machine_path(machine);
    if mpath.exists() {
        let m = MachineProfile::load(&mpath)?;
        if let Some(servo) = m.servo.axes.get(idx) {
            if let PlantModel::VelocityLoop {
                num, den, sample_s, ..
            } = &servo.plant
            {
                let tf = DiscreteTf::new(vec![0.0, num[0], num[1]], vec![1.0, den[0], den[1]])?;
                return Ok((
                    tf,
                    *sample_s,
                    format!("{} servo.axes[{idx}].plant", mpath.display()),
                ));
            }
        }
    }
    let p = profile
        .plants
        .iter()
        .find(|p| p.axis.eq_ignore_ascii_case(axis))
        .with_context(|| format!("no plant for axis {axis} in the design file"))?;
    let tf = DiscreteTf::new(p.num.clone(), p.den.clone())?;
    Ok((
        tf,
        profile.sample_time_s,
        format!(
            "design file plants[{}] (no velocity-loop servo profile)",
            p.axis
        ),
    ))
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
