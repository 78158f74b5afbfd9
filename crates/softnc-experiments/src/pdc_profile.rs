//! The compensator design file of paper 000 (`config/pdc/*.ron`): the PDC, DOB and
//! MBDA design parameters and fallback nominal plants, and the nominal plant of an
//! axis (from the machine profile's velocity-loop servo model when there is one).

use crate::error::{failed, Context, ExperimentError, Result};
use crate::workspace_file;
use serde::Deserialize;
use softnc_control::discrete_tf::DiscreteTf;
use softnc_control::dob::DobConfig;
use softnc_control::mbda::MbdaConfig;
use softnc_control::pdc::PdcConfig;
use softnc_machine::servo::PlantModel;
use softnc_machine::MachineProfile;
use std::path::{Path, PathBuf};

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

/// The machine profile path for a name or path.
pub fn machine_path(machine: &str) -> PathBuf {
    let p = PathBuf::from(machine);
    if machine.ends_with(".ron") || p.exists() {
        return workspace_file(&p);
    }
    workspace_file(PathBuf::from(format!("config/machines/{machine}.ron")))
}

/// The compensator design file for a machine name or profile path.
pub fn pdc_profile_path(machine: &str, explicit: Option<&PathBuf>) -> PathBuf {
    if let Some(p) = explicit {
        return workspace_file(p);
    }
    let stem = Path::new(machine)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| machine.to_string());
    let first = workspace_file(PathBuf::from(format!("config/pdc/{stem}.ron")));
    if first.exists() {
        return first;
    }
    let short = stem.trim_end_matches("-pdc");
    workspace_file(PathBuf::from(format!("config/pdc/{short}.ron")))
}

/// Load a compensator design file, naming the bad field on error.
pub fn load_pdc_profile(path: &Path) -> Result<PdcProfile> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read compensator design file {}", path.display()))?;
    softnc_core::config::parse_ron(&text, &path.display().to_string())
        .map_err(|e| ExperimentError::Config(e.to_string()))
}

/// The index of axis `x`, `y` or `z` (any case).
pub fn axis_index(axis: &str) -> Result<usize> {
    match axis.to_ascii_lowercase().as_str() {
        "x" => Ok(0),
        "y" => Ok(1),
        "z" => Ok(2),
        other => Err(ExperimentError::refused(format!(
            "unknown axis `{other}` (x, y or z)"
        ))),
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
        let m = MachineProfile::load(&mpath).map_err(|e| ExperimentError::Config(e.to_string()))?;
        if let Some(servo) = m.servo.axes.get(idx) {
            if let PlantModel::VelocityLoop {
                num, den, sample_s, ..
            } = &servo.plant
            {
                let tf = DiscreteTf::new(vec![0.0, num[0], num[1]], vec![1.0, den[0], den[1]])
                    .map_err(failed)?;
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
    let tf = DiscreteTf::new(p.num.clone(), p.den.clone()).map_err(failed)?;
    Ok((
        tf,
        profile.sample_time_s,
        format!(
            "design file plants[{}] (no velocity-loop servo profile)",
            p.axis
        ),
    ))
}
