//! The whole machine profile, composed above the algorithm crates: `softnc-core`'s
//! motion part ([`MotionProfile`]: axes, cycle, planner, tools, offsets, spindle,
//! learning, homing, jog) with the servo section ([`servo`]: plants from
//! `softnc-plant`, controllers from `softnc-control`) and the force section
//! ([`force`], paper 003, from `softnc-adaptive`), read from one RON file and
//! validated; a bad field fails with its RON path.
//!
//! ```
//! let profile = softnc_machine::MachineProfile::from_ron_str(
//!     include_str!("../../../config/machines/default.ron"), "default.ron").unwrap();
//! assert_eq!(profile.axes.len(), 3);
//! assert_eq!(profile.servo.axes.len(), 3);
//! ```
#![warn(missing_docs)]

use serde::{Deserialize, Deserializer};
use std::path::Path;

use softnc_core::config::{
    parse_ron, read_text, ConfigError, MachineTables, MotionProfile, ProfileFile,
};

/// The adaptive cutting-force section (paper 003): owned by `softnc-adaptive`,
/// composed into the profile here.
pub use softnc_adaptive::config as force;
/// Paper 000's compensation section: owned by `softnc-control`.
pub use softnc_control::config::compensation;
/// Paper 001's fuzzy-controller section: owned by `softnc-control`.
pub use softnc_control::config::fuzzy;
pub mod io;
pub mod servo;

/// A machine profile: the motion part (read through `Deref`: `profile.axes`,
/// `profile.planner`), the servo side and the force section.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineProfile {
    /// Name, cycle, axes, planner, tools, offsets, spindle, learning, homing, jog.
    pub motion: MotionProfile,
    /// The servo side: plants, controllers, measurement (simulated backend).
    pub servo: servo::ServoProfile,
    /// Adaptive cutting-force control (paper 003): process, feed motor, controller,
    /// experiments; absent on machines without it.
    pub force: Option<force::ForceProfile>,
}

impl std::ops::Deref for MachineProfile {
    type Target = MotionProfile;
    fn deref(&self) -> &MotionProfile {
        &self.motion
    }
}

impl std::ops::DerefMut for MachineProfile {
    fn deref_mut(&mut self) -> &mut MotionProfile {
        &mut self.motion
    }
}

/// The tables a program is read with (the G-code reader's entry points take them).
impl<'a> From<&'a MachineProfile> for MachineTables<'a> {
    fn from(p: &'a MachineProfile) -> Self {
        p.motion.tables()
    }
}

impl<'de> Deserialize<'de> for MachineProfile {
    /// The profile file's fields ([`ProfileFile`]), unknown ones refused.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        type File = ProfileFile<servo::ServoProfile, Option<force::ForceProfile>>;
        let (motion, servo, force) = File::deserialize(d)?.split();
        Ok(MachineProfile {
            motion,
            servo,
            force,
        })
    }
}

impl MachineProfile {
    /// Load and validate a profile from a RON file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (file, text) = read_text(path)?;
        Self::from_ron_str(&text, &file)
    }

    /// Parse and validate a profile from RON text; `file` names it in errors.
    pub fn from_ron_str(text: &str, file: &str) -> Result<Self, ConfigError> {
        let profile: MachineProfile = parse_ron(text, file)?;
        profile.validate(file)?;
        Ok(profile)
    }

    /// Check every value; the first bad one is reported with its RON path.
    pub fn validate(&self, file: &str) -> Result<(), ConfigError> {
        self.motion.validate_motion(file)?;
        self.validate_servo(file)?;
        self.motion.validate_manual(file)?;
        if let Some(f) = &self.force {
            f.validate(self.planner.max_feed_override)
                .map_err(|e| ConfigError::Invalid {
                    file: file.to_string(),
                    path: e.path,
                    reason: e.reason,
                })?;
        }
        self.motion.validate_offsets(file)
    }

    /// The servo section's checks (each axis's controller, filter, resonance and
    /// plant, the cutting disturbance), with the RON paths of the whole file.
    pub fn validate_servo(&self, file: &str) -> Result<(), ConfigError> {
        let bad = |path: String, reason: &str| ConfigError::Invalid {
            file: file.to_string(),
            path,
            reason: reason.to_string(),
        };
        if self.servo.axes.len() > 3 {
            return Err(bad("servo.axes".into(), "at most three axes"));
        }
        for (i, a) in self.servo.axes.iter().enumerate() {
            let p = |f: &str| format!("servo.axes[{i}].{f}");
            if !(a.noise_mm >= 0.0 && a.noise_mm.is_finite()) {
                return Err(bad(p("noise_mm"), "must be finite and >= 0"));
            }
            a.controller.validate_at(file, &p("controller"))?;
            if let Some(f) = &a.command_filter {
                f.validate_at(file, &p("command_filter"), self.interpolation_cycle_s)?;
            }
            if let Some(m) = &a.resonance {
                m.validate_at(file, &p("resonance"))?;
            }
            a.plant
                .validate_at(file, &p("plant"), self.interpolation_cycle_s)?;
        }
        if let Some(c) = &self.servo.cutting {
            c.validate_at(file, "servo.cutting", self.interpolation_cycle_s)?;
        }
        if let Some(io) = &self.servo.io {
            let names: Vec<String> = self.axes.iter().map(|a| a.name.clone()).collect();
            io.validate_at(file, "servo.io", &names)?;
        }
        if let Some(s) = &self.servo.spindle {
            s.validate_at(file, "servo.spindle", self.interpolation_cycle_s)?;
        }
        if let Some(s) = &self.servo.sim_io {
            let margin = self.homing.as_ref().map_or(0.0, |h| h.switch_margin_mm);
            s.validate_at(file, "servo.sim_io", margin)?;
        }
        Ok(())
    }

    /// Servo settings of axis `i` (defaults when the profile has none).
    pub fn axis_servo(&self, i: usize) -> servo::AxisServo {
        self.servo.axes.get(i).cloned().unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULT: &str = include_str!("../../../config/machines/default.ron");
    const INCREMENTAL: &str = include_str!("../../../config/machines/default-incremental.ron");

    fn invalid(text: &str) -> String {
        MachineProfile::from_ron_str(text, "m.ron")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn every_profile_reads_whole_and_its_motion_part_alone() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
        let mut n = 0;
        for e in std::fs::read_dir(&dir).unwrap() {
            let path = e.unwrap().path();
            if path.extension().is_some_and(|x| x == "ron") {
                let whole = MachineProfile::load(&path).unwrap();
                let motion = MotionProfile::load(&path).unwrap();
                assert_eq!(whole.motion, motion, "{}", path.display());
                n += 1;
            }
        }
        assert!(n >= 5, "{n} profiles");
    }

    #[test]
    fn default_profile_loads_with_its_servo_section() {
        let p = MachineProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        assert_eq!(p.axes[2].name, "Z");
        assert_eq!(p.servo.axes.len(), 3);
        assert!(p.force.is_none());
        let i = MachineProfile::from_ron_str(INCREMENTAL, "default-incremental.ron").unwrap();
        assert_eq!(i.servo, p.servo);
    }

    #[test]
    fn bad_values_anywhere_name_their_path() {
        // motion part
        let text = DEFAULT.replacen("max_acc_mm_per_s2: 3000.0", "max_acc_mm_per_s2: -1.0", 1);
        assert_ne!(text, DEFAULT, "fixture text changed");
        let err = invalid(&text);
        assert!(err.contains("`axes[0].max_acc_mm_per_s2`"), "{err}");
        assert!(err.starts_with("m.ron"), "{err}");
        // servo section: a value refused, a wrong type, an unknown field
        let text = DEFAULT.replacen("noise_mm: 0.00005", "noise_mm: -1.0", 1);
        assert_ne!(text, DEFAULT, "fixture text changed");
        assert!(
            invalid(&text).contains("`servo.axes[0].noise_mm`"),
            "{}",
            invalid(&text)
        );
        let text = DEFAULT.replacen("noise_mm: 0.00005", "noise_mm: \"x\"", 1);
        assert!(
            invalid(&text).contains("`servo.axes[0].noise_mm`"),
            "{}",
            invalid(&text)
        );
        let text = DEFAULT.replacen("noise_mm: 0.00005", "noise_mm: 0.00005, nois_mm: 1.0", 1);
        assert!(invalid(&text).contains("nois_mm"), "{}", invalid(&text));
        // an unknown top-level field, read whole or for its motion part alone
        let text = DEFAULT.replacen(
            "work_offsets_mm: [],",
            "work_offsets_mm: [], servos: (),",
            1,
        );
        assert_ne!(text, DEFAULT, "fixture text changed");
        assert!(invalid(&text).contains("servos"), "{}", invalid(&text));
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("servos"), "{err}");
    }

    #[test]
    fn the_motion_checks_run_before_the_servo_checks() {
        let text = DEFAULT
            .replacen("tolerance_mm: 0.01", "tolerance_mm: -1.0", 1)
            .replacen("noise_mm: 0.00005", "noise_mm: -1.0", 1);
        assert!(
            invalid(&text).contains("`planner.tolerance_mm`"),
            "{}",
            invalid(&text)
        );
        let text = INCREMENTAL
            .replacen("noise_mm: 0.00005", "noise_mm: -1.0", 1)
            .replacen("max_speed_fraction: 0.5", "max_speed_fraction: 1.5", 1);
        assert!(
            invalid(&text).contains("`servo.axes[0].noise_mm`"),
            "{}",
            invalid(&text)
        );
    }

    #[test]
    fn the_io_map_is_checked_with_its_paths() {
        let p = MachineProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        let io = p.servo.io.as_ref().unwrap();
        assert_eq!(io.inputs[0].signal, io::InputSignal::EStop);
        assert!(p.servo.spindle.is_some() && p.servo.sim_io.is_some());
        for (from, to, path) in [
            (
                "LimitMin(\"X\"), line: 17",
                "LimitMin(\"W\"), line: 17",
                "servo.io.inputs[1].signal",
            ),
            (
                "(signal: Probe, line: 26)",
                "(signal: Probe, line: 128)",
                "servo.io.inputs[10].line",
            ),
            (
                "(signal: Probe, line: 26)",
                "(signal: EStop, line: 26)",
                "servo.io.inputs[10].signal",
            ),
            (
                "(signal: CoolantMist, line: 3)",
                "(signal: CoolantMist, line: 2)",
                "servo.io.outputs[3].line",
            ),
            (
                "(signal: Output(3), line: 67)",
                "(signal: Output(64), line: 67)",
                "servo.io.outputs[11].signal",
            ),
            (
                "analog_outputs: [(e: 0, line: 0)",
                "analog_outputs: [(e: 8, line: 0)",
                "servo.io.analog_outputs[0].e",
            ),
            (
                "at_speed_frac: 0.02",
                "at_speed_frac: 1.5",
                "servo.io.at_speed_frac",
            ),
            (
                "at_speed_timeout_s: 5.0",
                "at_speed_timeout_s: 0.0",
                "servo.io.at_speed_timeout_s",
            ),
            (
                "max_torque_nm: 15.0",
                "max_torque_nm: 0.1",
                "servo.spindle.viscous_nm_per_rad_s",
            ),
            (
                "speed_loop_s: 0.05",
                "speed_loop_s: 0.001",
                "servo.spindle.speed_loop_s",
            ),
            (
                "(signal: Home(\"X\"), line: 23)",
                "(signal: Home(\"X\"), line: 23, debounce_cycles: 2, active_low: true, x: 1)",
                "x",
            ),
        ] {
            let text = DEFAULT.replacen(from, to, 1);
            assert_ne!(text, DEFAULT, "fixture text changed: {from}");
            let err = invalid(&text);
            assert!(err.contains(path), "{path}: {err}");
        }
        // the limit switches beyond the home switches' margin
        let text = INCREMENTAL.replacen(
            "limit_switch_margin_mm: 15.0",
            "limit_switch_margin_mm: 10.0",
            1,
        );
        assert_ne!(text, INCREMENTAL, "fixture text changed");
        assert!(
            invalid(&text).contains("`servo.sim_io.limit_switch_margin_mm`"),
            "{}",
            invalid(&text)
        );
    }
}
