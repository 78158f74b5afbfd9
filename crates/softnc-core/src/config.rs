//! The motion part of a machine profile (RON), validated: name, interpolation cycle,
//! axes, planner, tool table, work offsets, spindle, learning limits, homing and jog.
//! The whole profile (this part with the servo and force sections) is composed above
//! the algorithm crates (`softnc_machine::MachineProfile`); both read the same file
//! through [`ProfileFile`]. A bad field fails with its RON path and a reason.
//!
//! Units are in the field names: `_mm`, `_mm_per_s`, `_mm_per_s2`, `_mm_per_s3`, `_s`.

use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::ron_file::positive;
pub use crate::ron_file::{parse_ron, read_text, ConfigError};

/// One axis of the machine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Axis letter: "X", "Y" or "Z".
    pub name: String,
    /// Negative soft limit, machine coordinates.
    pub min_mm: f64,
    /// Positive soft limit, machine coordinates.
    pub max_mm: f64,
    /// Maximum axis velocity.
    pub max_vel_mm_per_s: f64,
    /// Maximum axis acceleration.
    pub max_acc_mm_per_s2: f64,
    /// Maximum axis jerk (used by the S-curve feed profile).
    pub max_jerk_mm_per_s3: f64,
    /// Encoder resolution (one count).
    pub encoder_resolution_mm: f64,
    /// In-position band: a job ends when every axis's |following error| is within
    /// its band (the axes have settled at the last command).
    #[serde(default = "default_in_position_mm")]
    pub in_position_mm: f64,
}

/// The in-position band when a profile gives none (mm).
pub fn default_in_position_mm() -> f64 {
    0.01
}

/// Shape of the feed profile along the path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum FeedProfile {
    /// Acceleration-limited (trapezoidal velocity).
    #[default]
    Trapezoidal,
    /// Jerk-limited (S-curve velocity).
    SCurve,
}

/// Where the CNC's acceleration/deceleration acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum AccDec {
    /// Before interpolation (softnc's own): the planner keeps every axis within its
    /// acceleration, tangent breaks between blocks included (it slows down at them).
    #[default]
    BeforeInterpolation,
    /// After interpolation, as in a CNC without look-ahead (the FANUC 0-M of paper
    /// 004): the interpolator runs the programmed feed through tangent breaks between
    /// blocks, and the servo's acc/dec lag (part of the profile's plant) smooths them.
    /// Element limits, start and stop ramps stay as planned.
    AfterInterpolation,
}

/// Planner settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannerConfig {
    /// Largest distance a blended corner may deviate from the programmed corner
    /// (G64 without P uses this; G64 P overrides it per program).
    pub tolerance_mm: f64,
    /// Feed profile shape.
    #[serde(default)]
    pub feed_profile: FeedProfile,
    /// Largest feed override, as a fraction (2.55 = 255 %).
    #[serde(default = "default_max_override")]
    pub max_feed_override: f64,
    /// Where acceleration/deceleration acts (default: before interpolation).
    #[serde(default)]
    pub acc_dec: AccDec,
    /// Blend line–arc, arc–line and arc–arc corners with circular fillets and
    /// biarcs (softnc-planner `fillet.rs`, `biarc.rs`) instead of stopping there.
    /// Default on: LinuxCNC's TP programs run in 0.93× LinuxCNC's total time
    /// (0.99× off) and none over 1.05× its time (13 off); planning CAM line/arc
    /// programs costs about twice the instructions (docs/perf-log/planner-figures.md).
    #[serde(default = "default_arc_blends")]
    pub arc_blends: bool,
}

fn default_max_override() -> f64 {
    2.55
}

fn default_arc_blends() -> bool {
    true
}

/// One entry of the tool table (G43 H, M6 T).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ToolEntry {
    /// Tool number (T word).
    pub number: u32,
    /// Tool length offset along Z.
    pub length_mm: f64,
    /// Cutter diameter.
    #[serde(default)]
    pub diameter_mm: f64,
}

/// The motion part of a machine profile: axes, cycle, planner, tool table, work
/// offsets, spindle, learning limits, homing and jog. Read from a profile file with
/// [`MotionProfile::load`] (the file's `servo` and `force` sections skipped).
#[derive(Debug, Clone, PartialEq)]
pub struct MotionProfile {
    /// Human-readable name.
    pub name: String,
    /// Interpolation cycle T (s).
    pub interpolation_cycle_s: f64,
    /// The axes, in X, Y, Z order.
    pub axes: Vec<AxisConfig>,
    /// Planner settings.
    pub planner: PlannerConfig,
    /// Tool table.
    pub tools: Vec<ToolEntry>,
    /// Work offsets G54..G59 (machine coordinates of each system's origin), up to six.
    pub work_offsets_mm: Vec<[f64; 3]>,
    /// The operator's spindle override.
    pub spindle: SpindleConfig,
    /// Limits of repetition-domain learning (`softnc learn`, stored corrections).
    pub learning: LearningConfig,
    /// Homing with switches and incremental encoders (LinuxCNC's HOME sequence).
    /// Absent: absolute encoders — every axis counts as homed at start and no homing
    /// motion runs.
    pub homing: Option<HomingConfig>,
    /// Manual (jog) motion between jobs.
    pub jog: JogConfig,
}

/// A machine profile file as it reads: the motion part's fields with the servo
/// section `S` and the force section `F`, each read by the layer that owns it
/// ([`serde::de::IgnoredAny`] where a reader skips them). Strict: an unknown field
/// is an error naming it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename = "MachineProfile")]
pub struct ProfileFile<S, F> {
    /// Human-readable name.
    pub name: String,
    /// Interpolation cycle T (s).
    pub interpolation_cycle_s: f64,
    /// The axes, in X, Y, Z order.
    pub axes: Vec<AxisConfig>,
    /// Planner settings.
    pub planner: PlannerConfig,
    /// Tool table.
    #[serde(default)]
    pub tools: Vec<ToolEntry>,
    /// Work offsets G54..G59 (machine coordinates of each system's origin), up to six.
    #[serde(default)]
    pub work_offsets_mm: Vec<[f64; 3]>,
    /// The servo side: plants, controllers, measurement (simulated backend).
    #[serde(default)]
    pub servo: S,
    /// Adaptive cutting-force control (paper 003): process, feed motor, controller,
    /// experiments; absent on machines without it.
    #[serde(default)]
    pub force: F,
    /// The operator's spindle override.
    #[serde(default)]
    pub spindle: SpindleConfig,
    /// Limits of repetition-domain learning (`softnc learn`, stored corrections).
    #[serde(default)]
    pub learning: LearningConfig,
    /// Homing with switches and incremental encoders (LinuxCNC's HOME sequence).
    /// Absent: absolute encoders — every axis counts as homed at start and no homing
    /// motion runs.
    #[serde(default)]
    pub homing: Option<HomingConfig>,
    /// Manual (jog) motion between jobs.
    #[serde(default)]
    pub jog: JogConfig,
}

impl<S, F> ProfileFile<S, F> {
    /// The motion part, the servo section and the force section.
    pub fn split(self) -> (MotionProfile, S, F) {
        let ProfileFile {
            name,
            interpolation_cycle_s,
            axes,
            planner,
            tools,
            work_offsets_mm,
            servo,
            force,
            spindle,
            learning,
            homing,
            jog,
        } = self;
        let motion = MotionProfile {
            name,
            interpolation_cycle_s,
            axes,
            planner,
            tools,
            work_offsets_mm,
            spindle,
            learning,
            homing,
            jog,
        };
        (motion, servo, force)
    }
}

/// Homing of a machine with incremental encoders and a home switch per axis: the
/// LinuxCNC homing sequence in short (LinuxCNC docs, "Homing Configuration",
/// `docs/src/config/ini-homing.adoc`): search the switch, latch its edge moving
/// away from it at a slow speed, re-reference the axis there, move to the home
/// position. Only switch homing (no index pulse), latching in the direction
/// opposite to the search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HomingConfig {
    /// Homing order ("home all"): axis names, each once, homed one after the other
    /// (LinuxCNC's HOME_SEQUENCE, without simultaneous groups). Z first is usual,
    /// so the tool clears the work before X and Y move.
    pub order: Vec<String>,
    /// How far outside the soft limits a home switch may sit; the search travels
    /// at most the axis's travel span plus twice this before it gives up.
    #[serde(default = "default_switch_margin_mm")]
    pub switch_margin_mm: f64,
    /// One entry per profile axis, in the order of `axes`.
    pub axes: Vec<AxisHoming>,
}

/// The switch margin when a profile gives none (mm).
pub fn default_switch_margin_mm() -> f64 {
    10.0
}

/// One axis's homing settings (LinuxCNC's `[JOINT_n]` HOME_* values, in mm and mm/s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisHoming {
    /// Machine coordinate of the switch's trip point: after latching, the latched
    /// position is declared to be this (LinuxCNC's HOME_OFFSET).
    pub switch_mm: f64,
    /// Search velocity, signed: the sign is the direction toward the switch
    /// (LinuxCNC's HOME_SEARCH_VEL), nonzero, |v| ≤ the axis's max velocity.
    pub search_vel_mm_per_s: f64,
    /// Latch velocity, signed, opposite in sign to the search: the axis backs off
    /// the switch at this speed and latches where it releases (HOME_LATCH_VEL).
    pub latch_vel_mm_per_s: f64,
    /// Speed of the final move to `home_mm`, > 0 (HOME_FINAL_VEL).
    pub final_vel_mm_per_s: f64,
    /// Where the axis goes when homed, inside the soft limits (LinuxCNC's HOME).
    pub home_mm: f64,
}

/// Manual (jog) motion: the operator's jog speed and the dead-man of a continuous
/// jog.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JogConfig {
    /// Jog speed when the operator has chosen none (LinuxCNC's
    /// `[DISPLAY]DEFAULT_LINEAR_VELOCITY`); clamped to each axis's jog limit.
    pub default_speed_mm_per_s: f64,
    /// Largest jog speed as a fraction of each axis's `max_vel_mm_per_s`, in (0, 1].
    pub max_speed_fraction: f64,
    /// The dead-man (s): a continuous jog its client has not renewed for this long
    /// is stopped (a client killed, a network gone). Short enough that an axis at
    /// its full jog speed runs at most `max_overrun_mm` in it (checked at load).
    #[serde(default = "default_jog_deadman_s")]
    pub deadman_s: f64,
    /// The most an axis may run at its full jog speed (`max_speed_fraction` ×
    /// `max_vel_mm_per_s`) between its client's last renewal and the dead-man's
    /// stop (mm): full jog speed × `deadman_s` must not exceed it. The
    /// deceleration after the stop (v²/2a) comes on top.
    #[serde(default = "default_jog_max_overrun_mm")]
    pub max_overrun_mm: f64,
}

fn default_jog_deadman_s() -> f64 {
    0.1
}

fn default_jog_max_overrun_mm() -> f64 {
    40.0
}

impl Default for JogConfig {
    /// 10 mm/s (600 mm/min) by default, up to each axis's full velocity; a dead-man
    /// of 0.1 s, within which an axis at its full jog speed runs at most 40 mm.
    fn default() -> Self {
        JogConfig {
            default_speed_mm_per_s: 10.0,
            max_speed_fraction: 1.0,
            deadman_s: default_jog_deadman_s(),
            max_overrun_mm: default_jog_max_overrun_mm(),
        }
    }
}

impl JogConfig {
    /// The jog speed of `axis` for a requested speed (`None`: the default speed),
    /// clamped to `[0, max_speed_fraction · max_vel_mm_per_s]`.
    pub fn speed_mm_per_s(&self, axis: &AxisConfig, requested_mm_per_s: Option<f64>) -> f64 {
        let want = requested_mm_per_s.unwrap_or(self.default_speed_mm_per_s);
        let limit = self.max_speed_fraction * axis.max_vel_mm_per_s;
        if want.is_nan() {
            return 0.0;
        }
        want.clamp(0.0, limit)
    }
}

/// Limits of repetition-domain learning on this machine (paper 002 eq 5's correction
/// added to the planned command).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearningConfig {
    /// Largest |correction| learning may add to an axis's command (mm). Absent: per
    /// axis, the following error of the identified closed loop at the axis's
    /// `max_vel_mm_per_s` (its mean delay times that speed), which is what a
    /// correction must lead the axis by to track the fastest programmable motion.
    #[serde(default)]
    pub max_correction_mm: Option<f64>,
}

/// The spindle as the operator sees it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpindleConfig {
    /// Smallest spindle override, as a fraction of the programmed speed.
    pub min_override: f64,
    /// Largest spindle override, as a fraction of the programmed speed.
    pub max_override: f64,
}

impl Default for SpindleConfig {
    /// The 50–120 % of a Fanuc control's spindle override switch.
    fn default() -> Self {
        SpindleConfig {
            min_override: 0.5,
            max_override: 1.2,
        }
    }
}

impl MotionProfile {
    /// Load and validate the motion part of a machine profile file (RON); its
    /// `servo` and `force` sections are skipped unread.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (file, text) = read_text(path)?;
        Self::from_ron_str(&text, &file)
    }

    /// [`MotionProfile::load`] of RON text; `file` names it in errors.
    pub fn from_ron_str(text: &str, file: &str) -> Result<Self, ConfigError> {
        type Skipped = serde::de::IgnoredAny;
        let (profile, _, _) = parse_ron::<ProfileFile<Skipped, Skipped>>(text, file)?.split();
        profile.validate(file)?;
        Ok(profile)
    }

    /// Check every value; the first bad one is reported with its RON path.
    #[allow(clippy::too_many_lines)]
    pub fn validate(&self, file: &str) -> Result<(), ConfigError> {
        self.validate_motion(file)?;
        self.validate_manual(file)?;
        self.validate_offsets(file)
    }

    /// The tool table and work offsets a program is read with.
    pub fn tables(&self) -> MachineTables<'_> {
        MachineTables {
            tools: &self.tools,
            work_offsets_mm: &self.work_offsets_mm,
        }
    }

    /// The first checks of [`MotionProfile::validate`]: cycle, axes, planner, tools,
    /// learning, spindle.
    pub fn validate_motion(&self, file: &str) -> Result<(), ConfigError> {
        let bad = |path: String, reason: &str| ConfigError::Invalid {
            file: file.to_string(),
            path,
            reason: reason.to_string(),
        };
        positive(self.interpolation_cycle_s, "interpolation_cycle_s", file)?;
        if self.interpolation_cycle_s > 0.1 {
            return Err(bad("interpolation_cycle_s".into(), "must be at most 0.1 s"));
        }
        if self.axes.len() != 3 {
            return Err(bad(
                "axes".into(),
                "exactly three axes (X, Y, Z) are supported",
            ));
        }
        for (i, (axis, want)) in self
            .axes
            .iter()
            .zip(crate::Axis::carried().map(crate::Axis::name))
            .enumerate()
        {
            let p = |f: &str| format!("axes[{i}].{f}");
            if axis.name != want {
                return Err(bad(
                    p("name"),
                    &format!("axis {i} must be named \"{want}\""),
                ));
            }
            finite(axis.min_mm, &p("min_mm"), file)?;
            finite(axis.max_mm, &p("max_mm"), file)?;
            if axis.max_mm <= axis.min_mm {
                return Err(bad(p("max_mm"), "must be greater than min_mm"));
            }
            positive(axis.max_vel_mm_per_s, &p("max_vel_mm_per_s"), file)?;
            positive(axis.max_acc_mm_per_s2, &p("max_acc_mm_per_s2"), file)?;
            positive(axis.max_jerk_mm_per_s3, &p("max_jerk_mm_per_s3"), file)?;
            positive(
                axis.encoder_resolution_mm,
                &p("encoder_resolution_mm"),
                file,
            )?;
            positive(axis.in_position_mm, &p("in_position_mm"), file)?;
        }
        positive(self.planner.tolerance_mm, "planner.tolerance_mm", file)?;
        finite(
            self.planner.max_feed_override,
            "planner.max_feed_override",
            file,
        )?;
        if !(1.0..=2.55).contains(&self.planner.max_feed_override) {
            return Err(bad(
                "planner.max_feed_override".into(),
                "must be between 1.0 and 2.55",
            ));
        }
        let mut seen = std::collections::BTreeSet::new();
        for (i, t) in self.tools.iter().enumerate() {
            if !seen.insert(t.number) {
                return Err(bad(
                    format!("tools[{i}].number"),
                    "tool number appears twice",
                ));
            }
            finite(t.length_mm, &format!("tools[{i}].length_mm"), file)?;
            if !(t.diameter_mm >= 0.0 && t.diameter_mm.is_finite()) {
                return Err(bad(
                    format!("tools[{i}].diameter_mm"),
                    "must be finite and >= 0",
                ));
            }
        }
        if let Some(m) = self.learning.max_correction_mm {
            positive(m, "learning.max_correction_mm", file)?;
        }
        finite(self.spindle.min_override, "spindle.min_override", file)?;
        finite(self.spindle.max_override, "spindle.max_override", file)?;
        if !(self.spindle.min_override > 0.0 && self.spindle.min_override <= 1.0) {
            return Err(bad(
                "spindle.min_override".into(),
                "must be above 0 and at most 1.0 (100 %)",
            ));
        }
        if !(1.0..=2.55).contains(&self.spindle.max_override) {
            return Err(bad(
                "spindle.max_override".into(),
                "must be between 1.0 and 2.55",
            ));
        }
        Ok(())
    }

    /// The last check of [`MotionProfile::validate`]: the work offsets.
    pub fn validate_offsets(&self, file: &str) -> Result<(), ConfigError> {
        let bad = |path: String, reason: &str| ConfigError::Invalid {
            file: file.to_string(),
            path,
            reason: reason.to_string(),
        };
        if self.work_offsets_mm.len() > 6 {
            return Err(bad(
                "work_offsets_mm".into(),
                "at most six work offsets (G54..G59)",
            ));
        }
        for (i, o) in self.work_offsets_mm.iter().enumerate() {
            for (k, v) in o.iter().enumerate() {
                finite(*v, &format!("work_offsets_mm[{i}][{k}]"), file)?;
            }
        }
        Ok(())
    }

    /// The middle check of [`MotionProfile::validate`]: jog and homing.
    #[allow(clippy::too_many_lines)]
    pub fn validate_manual(&self, file: &str) -> Result<(), ConfigError> {
        let bad = |path: String, reason: String| ConfigError::Invalid {
            file: file.to_string(),
            path,
            reason,
        };
        positive(
            self.jog.default_speed_mm_per_s,
            "jog.default_speed_mm_per_s",
            file,
        )?;
        if !(self.jog.max_speed_fraction > 0.0 && self.jog.max_speed_fraction <= 1.0) {
            return Err(bad(
                "jog.max_speed_fraction".into(),
                format!("must lie in (0, 1] (got {})", self.jog.max_speed_fraction),
            ));
        }
        positive(self.jog.deadman_s, "jog.deadman_s", file)?;
        positive(self.jog.max_overrun_mm, "jog.max_overrun_mm", file)?;
        for axis in &self.axes {
            let full_mm_per_s = self.jog.max_speed_fraction * axis.max_vel_mm_per_s;
            let overrun_mm = full_mm_per_s * self.jog.deadman_s;
            if overrun_mm > self.jog.max_overrun_mm {
                return Err(bad(
                    "jog.deadman_s".into(),
                    format!(
                        "{} at its full jog speed ({full_mm_per_s} mm/s) runs {overrun_mm} mm in the dead-man's {} s, over jog.max_overrun_mm ({} mm): at most {} s",
                        axis.name,
                        self.jog.deadman_s,
                        self.jog.max_overrun_mm,
                        self.jog.max_overrun_mm / full_mm_per_s
                    ),
                ));
            }
        }
        let Some(h) = &self.homing else {
            return Ok(());
        };
        if !(h.switch_margin_mm >= 0.0 && h.switch_margin_mm.is_finite()) {
            return Err(bad(
                "homing.switch_margin_mm".into(),
                format!("must be finite and >= 0 (got {})", h.switch_margin_mm),
            ));
        }
        if h.axes.len() != self.axes.len() {
            return Err(bad(
                "homing.axes".into(),
                format!(
                    "one entry per profile axis: {} expected, {} given",
                    self.axes.len(),
                    h.axes.len()
                ),
            ));
        }
        for (i, (a, axis)) in h.axes.iter().zip(&self.axes).enumerate() {
            let p = |f: &str| format!("homing.axes[{i}].{f}");
            let (lo, hi) = (
                axis.min_mm - h.switch_margin_mm,
                axis.max_mm + h.switch_margin_mm,
            );
            if !(a.switch_mm.is_finite() && (lo..=hi).contains(&a.switch_mm)) {
                return Err(bad(
                    p("switch_mm"),
                    format!(
                        "must lie within the soft limits ± switch_margin_mm, [{lo}, {hi}] (got {})",
                        a.switch_mm
                    ),
                ));
            }
            let vmax = axis.max_vel_mm_per_s;
            for (name, v) in [
                ("search_vel_mm_per_s", a.search_vel_mm_per_s),
                ("latch_vel_mm_per_s", a.latch_vel_mm_per_s),
                ("final_vel_mm_per_s", a.final_vel_mm_per_s),
            ] {
                if !(v.is_finite() && v != 0.0 && v.abs() <= vmax) {
                    return Err(bad(
                        p(name),
                        format!(
                            "must be nonzero with |v| <= the axis's max_vel_mm_per_s {vmax} (got {v})"
                        ),
                    ));
                }
            }
            if a.final_vel_mm_per_s < 0.0 {
                return Err(bad(
                    p("final_vel_mm_per_s"),
                    format!("must be > 0 (got {})", a.final_vel_mm_per_s),
                ));
            }
            if a.latch_vel_mm_per_s.signum() == a.search_vel_mm_per_s.signum() {
                return Err(bad(
                    p("latch_vel_mm_per_s"),
                    "must be opposite in sign to search_vel_mm_per_s: the latch backs off \
                     the switch (same-direction latching is not supported)"
                        .into(),
                ));
            }
            if !(a.home_mm.is_finite() && (axis.min_mm..=axis.max_mm).contains(&a.home_mm)) {
                return Err(bad(
                    p("home_mm"),
                    format!(
                        "must lie within the soft limits [{}, {}] (got {})",
                        axis.min_mm, axis.max_mm, a.home_mm
                    ),
                ));
            }
        }
        let mut seen = vec![false; self.axes.len()];
        for (k, name) in h.order.iter().enumerate() {
            let Some(i) = self.axes.iter().position(|a| &a.name == name) else {
                return Err(bad(
                    format!("homing.order[{k}]"),
                    format!("\"{name}\" is not an axis of this profile"),
                ));
            };
            if std::mem::replace(&mut seen[i], true) {
                return Err(bad(
                    format!("homing.order[{k}]"),
                    format!("axis \"{name}\" appears twice"),
                ));
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(bad(
                "homing.order".into(),
                format!(
                    "must name every axis once; \"{}\" is missing",
                    self.axes[i].name
                ),
            ));
        }
        Ok(())
    }

    /// True when the axes count as homed at start: the profile has no `homing`
    /// section (absolute encoders).
    pub fn homed_at_start(&self) -> bool {
        self.homing.is_none()
    }

    /// Axis indices in homing order (empty without a `homing` section).
    pub fn homing_order(&self) -> Vec<usize> {
        self.homing.as_ref().map_or_else(Vec::new, |h| {
            h.order
                .iter()
                .filter_map(|n| self.axes.iter().position(|a| &a.name == n))
                .collect()
        })
    }

    /// Per-axis maximum velocities [x, y, z] (mm/s).
    pub fn max_vel(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.axes[i].max_vel_mm_per_s)
    }
    /// Per-axis maximum accelerations [x, y, z] (mm/s²).
    pub fn max_acc(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.axes[i].max_acc_mm_per_s2)
    }
    /// Per-axis maximum jerks [x, y, z] (mm/s³).
    pub fn max_jerk(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.axes[i].max_jerk_mm_per_s3)
    }
    /// Tool length of tool `number`, if it is in the table.
    pub fn tool_length_mm(&self, number: u32) -> Option<f64> {
        self.tools
            .iter()
            .find(|t| t.number == number)
            .map(|t| t.length_mm)
    }
    /// Work offset of coordinate system `index` (0 = G54 … 5 = G59); zero if not given.
    pub fn work_offset_mm(&self, index: usize) -> [f64; 3] {
        self.work_offsets_mm.get(index).copied().unwrap_or([0.0; 3])
    }
}

/// The machine's tables a program is read with: the tool table (G43 H, M6 T) and
/// the work offsets (G54..G59). What the G-code reader takes of a profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MachineTables<'a> {
    /// Tool table.
    pub tools: &'a [ToolEntry],
    /// Work offsets G54..G59, up to six.
    pub work_offsets_mm: &'a [[f64; 3]],
}

impl MachineTables<'_> {
    /// Tool length of tool `number`, if it is in the table.
    pub fn tool_length_mm(&self, number: u32) -> Option<f64> {
        self.tools
            .iter()
            .find(|t| t.number == number)
            .map(|t| t.length_mm)
    }
    /// Work offset of coordinate system `index` (0 = G54 … 5 = G59); zero if not given.
    pub fn work_offset_mm(&self, index: usize) -> [f64; 3] {
        self.work_offsets_mm.get(index).copied().unwrap_or([0.0; 3])
    }
}

impl<'a> From<&'a MotionProfile> for MachineTables<'a> {
    fn from(p: &'a MotionProfile) -> Self {
        p.tables()
    }
}

fn finite(v: f64, path: &str, file: &str) -> Result<(), ConfigError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            file: file.into(),
            path: path.into(),
            reason: "must be a finite number".into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEFAULT: &str = include_str!("../../../config/machines/default.ron");

    #[test]
    fn default_profile_loads() {
        let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        assert_eq!(p.axes[2].name, "Z");
        assert!(p.interpolation_cycle_s > 0.0);
    }

    #[test]
    fn bad_value_names_its_path() {
        let text = DEFAULT.replacen("max_acc_mm_per_s2: 3000.0", "max_acc_mm_per_s2: -1.0", 1);
        assert_ne!(text, DEFAULT, "fixture text changed");
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("axes[0].max_acc_mm_per_s2"), "{err}");
        assert!(err.starts_with("m.ron"), "{err}");
    }

    #[test]
    fn spindle_override_range_defaults_and_is_checked() {
        let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        assert_eq!(p.spindle, SpindleConfig::default());
        let text = DEFAULT.replacen(
            "planner: (",
            "spindle: (min_override: 0.5, max_override: 0.9),\n    planner: (",
            1,
        );
        assert_ne!(text, DEFAULT, "fixture text changed");
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("spindle.max_override"), "{err}");
        let text = text.replace(
            "min_override: 0.5, max_override: 0.9",
            "min_override: 0.0, max_override: 1.5",
        );
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("spindle.min_override"), "{err}");
    }

    #[test]
    fn wrong_type_and_unknown_field_name_their_path() {
        let text = DEFAULT.replacen("tolerance_mm: 0.01", "tolerance_mm: \"small\"", 1);
        assert_ne!(text, DEFAULT);
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("planner.tolerance_mm"), "{err}");
        let text = DEFAULT.replacen(
            "tolerance_mm: 0.01",
            "tolerance_mm: 0.01, tolerence: 1.0",
            1,
        );
        let err = MotionProfile::from_ron_str(&text, "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.contains("tolerence"), "{err}");
    }

    const INCREMENTAL: &str = include_str!("../../../config/machines/default-incremental.ron");

    fn invalid(text: &str) -> String {
        MotionProfile::from_ron_str(text, "m.ron")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn profiles_without_homing_count_as_homed_and_keep_default_jog() {
        let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        assert!(p.homing.is_none());
        assert!(p.homed_at_start());
        assert!(p.homing_order().is_empty());
        assert_eq!(p.jog, JogConfig::default());
    }

    #[test]
    fn incremental_profile_loads_with_homing_z_first() {
        let p = MotionProfile::from_ron_str(INCREMENTAL, "default-incremental.ron").unwrap();
        assert!(!p.homed_at_start());
        assert_eq!(p.homing_order(), vec![2, 0, 1]);
        let h = p.homing.as_ref().unwrap();
        for (a, axis) in h.axes.iter().zip(&p.axes) {
            // switches near the positive end, searched toward it, latched backing off
            assert!(a.switch_mm >= axis.max_mm && a.switch_mm <= axis.max_mm + h.switch_margin_mm);
            assert!(a.search_vel_mm_per_s > 0.0 && a.latch_vel_mm_per_s < 0.0);
        }
        assert_eq!(p.jog.max_speed_fraction, 0.5);
        // everything else is default.ron's
        let d = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        assert_eq!(p.axes, d.axes);
    }

    #[test]
    fn jog_speed_is_clamped_to_the_axis_fraction() {
        let p = MotionProfile::from_ron_str(INCREMENTAL, "default-incremental.ron").unwrap();
        let x = &p.axes[0];
        assert_eq!(p.jog.speed_mm_per_s(x, None), 10.0);
        assert_eq!(p.jog.speed_mm_per_s(x, Some(1e6)), 0.5 * x.max_vel_mm_per_s);
        assert_eq!(p.jog.speed_mm_per_s(x, Some(-3.0)), 0.0);
        assert_eq!(p.jog.speed_mm_per_s(x, Some(f64::NAN)), 0.0);
    }

    #[test]
    fn a_deadman_too_long_for_the_overrun_bound_is_refused_with_its_path() {
        let p = MotionProfile::from_ron_str(DEFAULT, "default.ron").unwrap();
        // X and Y at 400 mm/s: 40 mm in 0.1 s, the bound itself
        assert_eq!((p.jog.deadman_s, p.jog.max_overrun_mm), (0.1, 40.0));
        let text = INCREMENTAL.replace(
            "max_speed_fraction: 0.5)",
            "max_speed_fraction: 0.5, deadman_s: 0.2, max_overrun_mm: 39.0)",
        );
        assert_ne!(text, INCREMENTAL);
        let e = invalid(&text);
        assert!(e.contains("jog.deadman_s"), "{e}");
        assert!(
            e.contains("runs 40 mm") && e.contains("at most 0.195 s"),
            "{e}"
        );
        // within it: taken
        let ok = INCREMENTAL.replace(
            "max_speed_fraction: 0.5)",
            "max_speed_fraction: 0.5, deadman_s: 0.2, max_overrun_mm: 40.0)",
        );
        assert_eq!(
            MotionProfile::from_ron_str(&ok, "m.ron")
                .unwrap()
                .jog
                .deadman_s,
            0.2
        );
        let e = invalid(&INCREMENTAL.replace(
            "max_speed_fraction: 0.5)",
            "max_speed_fraction: 0.5, deadman_s: 0.0)",
        ));
        assert!(e.contains("jog.deadman_s"), "{e}");
    }

    #[test]
    fn bad_homing_values_name_their_path() {
        let cases = [
            (
                "switch_mm: 405.0",
                "switch_mm: 420.0",
                "homing.axes[0].switch_mm",
            ),
            (
                "search_vel_mm_per_s: 40.0",
                "search_vel_mm_per_s: 0.0",
                "homing.axes[0].search_vel_mm_per_s",
            ),
            (
                "search_vel_mm_per_s: 40.0",
                "search_vel_mm_per_s: 500.0",
                "homing.axes[0].search_vel_mm_per_s",
            ),
            (
                "latch_vel_mm_per_s: -2.0",
                "latch_vel_mm_per_s: 2.0",
                "homing.axes[0].latch_vel_mm_per_s",
            ),
            (
                "final_vel_mm_per_s: 100.0",
                "final_vel_mm_per_s: -100.0",
                "homing.axes[0].final_vel_mm_per_s",
            ),
            ("home_mm: 90.0", "home_mm: 101.0", "homing.axes[2].home_mm"),
            (
                "order: [\"Z\", \"X\", \"Y\"]",
                "order: [\"Z\", \"X\", \"X\"]",
                "homing.order[2]",
            ),
            (
                "order: [\"Z\", \"X\", \"Y\"]",
                "order: [\"Z\", \"X\", \"A\"]",
                "homing.order[2]",
            ),
            (
                "order: [\"Z\", \"X\", \"Y\"]",
                "order: [\"Z\", \"X\"]",
                "homing.order",
            ),
            (
                "switch_margin_mm: 10.0",
                "switch_margin_mm: -1.0",
                "homing.switch_margin_mm",
            ),
            (
                "max_speed_fraction: 0.5",
                "max_speed_fraction: 1.5",
                "jog.max_speed_fraction",
            ),
            (
                "default_speed_mm_per_s: 10.0",
                "default_speed_mm_per_s: 0.0",
                "jog.default_speed_mm_per_s",
            ),
        ];
        for (from, to, path) in cases {
            let text = INCREMENTAL.replacen(from, to, 1);
            assert_ne!(text, INCREMENTAL, "fixture text changed: {from}");
            let err = invalid(&text);
            assert!(err.contains(&format!("`{path}`")), "{to}: {err}");
        }
        // one entry per axis
        let i = INCREMENTAL.find("            (switch_mm: 255.0").unwrap();
        let j = INCREMENTAL[i..].find("(switch_mm: 105.0").unwrap() + i;
        let text = format!("{}{}", &INCREMENTAL[..i], &INCREMENTAL[j..]);
        assert!(
            invalid(&text).contains("`homing.axes`"),
            "{}",
            invalid(&text)
        );
        // unknown field
        let text = INCREMENTAL.replacen("home_mm: 0.0", "home_mm: 0.0, home_offset: 1.0", 1);
        assert!(invalid(&text).contains("home_offset"));
    }

    #[test]
    fn syntax_error_has_a_position() {
        let err = MotionProfile::from_ron_str("MotionProfile(name: \"x\",, )", "m.ron")
            .unwrap_err()
            .to_string();
        assert!(err.starts_with("m.ron"), "{err}");
    }
}
