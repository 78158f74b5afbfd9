//! The adaptive cutting-force control section of a machine profile (paper 003): the
//! milling process (materials, tools), the PMSM feed motor, the force calibration run,
//! the adaptive controller's settings and the experiments (cases I–III).
//!
//! Units are in the field names; every number of the paper's machine and process
//! lives in `config/machines/mch10-force.ron`, none in code. This crate owns the
//! schema and its validation; the machine profile (`softnc_machine::MachineProfile`)
//! composes it as its `force` section (`softnc_machine::force` re-exports it).

use crate::rls::RlsConfig;
use serde::{Deserialize, Serialize};

/// A value of the section that parses but is not acceptable: its RON path (from the
/// profile's root, `force.…`) and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("at `{path}`: {reason}")]
pub struct Invalid {
    /// RON path of the offending field.
    pub path: String,
    /// What is wrong and what is expected.
    pub reason: String,
}

/// Everything paper 003 needs beyond the axes and the servo section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceProfile {
    /// Index of the feed axis that cuts (0 = X).
    pub feed_axis: usize,
    /// Work materials (003 eq 3–4: k_c).
    pub materials: Vec<Material>,
    /// Cutters (Z, spindle + tool stiffness K_s, engagement).
    pub tools: Vec<MillingTool>,
    /// The feed motor (PMSM) and its current sensors.
    pub motor: PmsmConfig,
    /// The calibration cut that fits I_q = a·F + b (003 eq 31–32).
    pub calibration: CalibrationRun,
    /// The adaptive robust controller's settings.
    pub controller: ForceControllerConfig,
    /// The experiments (the paper's cases I, II, III).
    pub cases: Vec<ForceCase>,
    /// Adaptive feed on a running job (the daemon, `softnc sim --adaptive-force`):
    /// which case's controller and reference, and the calibration in force.
    #[serde(default)]
    pub adaptive_feed: Option<AdaptiveFeed>,
    /// The stock the simulated machine cuts (the simulated backend's cutting force
    /// and feed-motor currents); `None`: the simulated machine cuts nothing.
    #[serde(default)]
    pub sim_workpiece: Option<SimWorkpiece>,
}

/// Adaptive feed on a running job: the force loop of paper 003 closed in the
/// controller, its override capped by the operator's.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdaptiveFeed {
    /// Every job runs with adaptive feed (else only `job submit --adaptive-force`).
    pub enabled: bool,
    /// The case whose reference force, poles, spindle speed and programmed feed the
    /// loop runs with (the override is the feed over that programmed feed).
    pub case: String,
    /// The force estimate's calibration I_q = a·F + b (003 eq 32), as `softnc
    /// reproduce 003-force` fits it on this machine.
    pub calibration: ForceCalibrationLine,
}

/// A fitted calibration line I_q = a·F + b (003 eq 32).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceCalibrationLine {
    /// Slope a (A/N).
    pub a_per_n: f64,
    /// Offset b (A).
    pub b_a: f64,
}

/// The stock on the simulated machine's table: a case's segments (depth and
/// material along the feed axis) from `start_mm` on the feed axis, cut with the
/// case's tool at its spindle speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimWorkpiece {
    /// The case whose tool, spindle speed and segments the stock is.
    pub case: String,
    /// Feed-axis position (mm) where the stock begins.
    pub start_mm: f64,
}

/// A work material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Name used by cut segments.
    pub name: String,
    /// Material constant k_c of 003 eq 3–4 (N/mm², with N in rev/s): the steady peak
    /// feed force per mm of depth and mm of feed per tooth.
    pub k_c_n_per_mm2: f64,
}

/// A milling cutter.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MillingTool {
    /// Name used by cases.
    pub name: String,
    /// Diameter (mm), for the record.
    pub diameter_mm: f64,
    /// Flutes or inserts Z.
    pub flutes: u32,
    /// Angle of the revolution over which one tooth cuts (deg); a slot is 180°.
    pub engagement_deg: f64,
    /// Spindle and tool stiffness K_s (N/mm), 003 eq 3.
    pub stiffness_n_per_mm: f64,
}

/// The PMSM feed motor driving the feed axis through a ball screw, and its sensors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PmsmConfig {
    /// Ball-screw lead (mm per motor revolution).
    pub lead_mm: f64,
    /// Multiplier n_p of the rotor angle in the Park transform (003 eq 27–28).
    pub pole_pairs: u32,
    /// Torque constant K_t (N·m/A), 003 eq 26.
    pub torque_constant_nm_per_a: f64,
    /// Coulomb friction of the slide (N), 003 eq 30.
    pub friction_n: f64,
    /// Moving mass referred to the table (kg), 003 eq 29.
    pub moving_mass_kg: f64,
    /// Bandwidth of the drive's torque response to a load (Hz).
    pub torque_bandwidth_hz: f64,
    /// Standard deviation of each phase-current sensor's noise (A).
    pub current_noise_a: f64,
}

/// The calibration cut: fixed feed, several depths, one material and tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationRun {
    /// Material name.
    pub material: String,
    /// Tool name.
    pub tool: String,
    /// Spindle speed (rpm).
    pub spindle_rpm: f64,
    /// Feed (mm/min), override 100 %.
    pub feed_mm_per_min: f64,
    /// Depths of cut (mm), one calibration segment each.
    pub depths_mm: Vec<f64>,
    /// Revolutions cut per depth.
    pub revolutions_per_depth: u32,
    /// Revolutions skipped at the start of each depth (transient).
    pub skip_revolutions: u32,
}

/// The prior model the estimator starts from: K/((1 + τ_s s)(1 + τ_c s)), v in mm/min.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PriorModel {
    /// Static gain K_c·d (N per mm/min).
    pub gain_n_per_mm_min: f64,
    /// Feed-drive time constant τ_s (s).
    pub tau_s: f64,
    /// Cutting time constant τ_c (s).
    pub tau_c_s: f64,
}

/// The adaptive robust controller's settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceControllerConfig {
    /// Closed-loop poles (z) unless the case gives its own.
    pub poles: [f64; 4],
    /// Estimator.
    pub rls: RlsConfig,
    /// Starting model.
    pub prior: PriorModel,
    /// Lowest feed override (fraction; the paper's range is 0–2.55).
    pub override_min: f64,
    /// Highest feed override (fraction, ≤ the planner's `max_feed_override`).
    pub override_max: f64,
    /// Largest override change per control sample (fraction of the programmed feed).
    pub override_step_max: f64,
}

/// One stretch of the cut with constant depth and material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CutSegment {
    /// Length along the feed axis (mm).
    pub length_mm: f64,
    /// Axial depth d (mm).
    pub depth_mm: f64,
    /// Material name.
    pub material: String,
    /// The paper's settled feed on this stretch (mm/min), when it prints one.
    #[serde(default)]
    pub paper_feed_mm_per_min: Option<f64>,
}

/// A disturbance of the process for tests: the cutting force is multiplied by
/// `force_scale` from `at_s` for `duration_s` (0.0 = tool breakage, 3.0 = a spike).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceEvent {
    /// Start (s from the start of the cut).
    pub at_s: f64,
    /// Duration (s).
    pub duration_s: f64,
    /// Factor on the force.
    pub force_scale: f64,
}

/// One experiment: a straight cut along the feed axis over `segments`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ForceCase {
    /// Name ("I", "II", …).
    pub name: String,
    /// Tool name.
    pub tool: String,
    /// Spindle speed (rpm); one control sample per revolution.
    pub spindle_rpm: f64,
    /// Reference peak force f_c* (N).
    pub force_ref_n: f64,
    /// Programmed feed F (mm/min) of the NC program (override 100 %).
    pub programmed_feed_mm_per_min: f64,
    /// Closed-loop poles for this case (default: the controller's).
    #[serde(default)]
    pub poles: Option<[f64; 4]>,
    /// Revolutions at the end of each segment over which the settled figures are taken.
    pub settled_revolutions: u32,
    /// The stretches of the cut.
    pub segments: Vec<CutSegment>,
    /// Process disturbances (tests).
    #[serde(default)]
    pub events: Vec<ForceEvent>,
}

impl ForceProfile {
    /// Material by name.
    pub fn material(&self, name: &str) -> Option<&Material> {
        self.materials.iter().find(|m| m.name == name)
    }
    /// Tool by name.
    pub fn tool(&self, name: &str) -> Option<&MillingTool> {
        self.tools.iter().find(|t| t.name == name)
    }
    /// Case by name.
    pub fn case(&self, name: &str) -> Option<&ForceCase> {
        self.cases.iter().find(|c| c.name == name)
    }

    /// Check every value; `max_override` is the planner's.
    #[allow(clippy::too_many_lines)]
    pub fn validate(&self, max_override: f64) -> Result<(), Invalid> {
        let bad = |path: String, reason: &str| Invalid {
            path: format!("force.{path}"),
            reason: reason.to_string(),
        };
        let pos = |v: f64, path: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(path.to_string(), "must be finite and > 0"))
            }
        };
        if self.feed_axis > 2 {
            return Err(bad("feed_axis".into(), "must be 0, 1 or 2"));
        }
        for (i, m) in self.materials.iter().enumerate() {
            pos(m.k_c_n_per_mm2, &format!("materials[{i}].k_c_n_per_mm2"))?;
        }
        for (i, t) in self.tools.iter().enumerate() {
            let p = |f: &str| format!("tools[{i}].{f}");
            pos(t.diameter_mm, &p("diameter_mm"))?;
            pos(t.stiffness_n_per_mm, &p("stiffness_n_per_mm"))?;
            if t.flutes == 0 {
                return Err(bad(p("flutes"), "must be at least 1"));
            }
            if !(t.engagement_deg > 0.0 && t.engagement_deg <= 360.0) {
                return Err(bad(p("engagement_deg"), "must be in (0, 360]"));
            }
        }
        let m = &self.motor;
        pos(m.lead_mm, "motor.lead_mm")?;
        pos(m.torque_constant_nm_per_a, "motor.torque_constant_nm_per_a")?;
        pos(m.torque_bandwidth_hz, "motor.torque_bandwidth_hz")?;
        if m.pole_pairs == 0 {
            return Err(bad("motor.pole_pairs".into(), "must be at least 1"));
        }
        for (v, f) in [
            (m.friction_n, "motor.friction_n"),
            (m.moving_mass_kg, "motor.moving_mass_kg"),
            (m.current_noise_a, "motor.current_noise_a"),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(f.into(), "must be finite and >= 0"));
            }
        }
        let c = &self.calibration;
        self.check_names(&c.material, &c.tool, "calibration", &bad)?;
        pos(c.spindle_rpm, "calibration.spindle_rpm")?;
        pos(c.feed_mm_per_min, "calibration.feed_mm_per_min")?;
        if c.depths_mm.len() < 2 {
            return Err(bad(
                "calibration.depths_mm".into(),
                "at least two depths are needed to fit a line",
            ));
        }
        for (i, d) in c.depths_mm.iter().enumerate() {
            pos(*d, &format!("calibration.depths_mm[{i}]"))?;
        }
        if c.revolutions_per_depth <= c.skip_revolutions {
            return Err(bad(
                "calibration.revolutions_per_depth".into(),
                "must exceed skip_revolutions",
            ));
        }
        let k = &self.controller;
        check_poles(&k.poles, "controller.poles", &bad)?;
        pos(k.rls.p0, "controller.rls.p0")?;
        if !(k.rls.forgetting > 0.0 && k.rls.forgetting <= 1.0) {
            return Err(bad("controller.rls.forgetting".into(), "must be in (0, 1]"));
        }
        if !(k.rls.dead_zone.is_finite() && k.rls.dead_zone >= 0.0) {
            return Err(bad(
                "controller.rls.dead_zone_n".into(),
                "must be finite and >= 0",
            ));
        }
        pos(k.rls.reset_trace, "controller.rls.reset_trace")?;
        pos(
            k.prior.gain_n_per_mm_min,
            "controller.prior.gain_n_per_mm_min",
        )?;
        pos(k.prior.tau_s, "controller.prior.tau_s")?;
        pos(k.prior.tau_c_s, "controller.prior.tau_c_s")?;
        if !(k.override_min >= 0.0
            && k.override_min < k.override_max
            && k.override_max <= max_override + 1e-12)
        {
            return Err(bad(
                "controller.override_max".into(),
                "need 0 <= override_min < override_max <= planner.max_feed_override",
            ));
        }
        pos(k.override_step_max, "controller.override_step_max")?;
        if self.cases.is_empty() {
            return Err(bad("cases".into(), "at least one case"));
        }
        for (i, case) in self.cases.iter().enumerate() {
            let p = |f: &str| format!("cases[{i}].{f}");
            if self.cases[..i].iter().any(|c| c.name == case.name) {
                return Err(bad(p("name"), "case name appears twice"));
            }
            if self.tool(&case.tool).is_none() {
                return Err(bad(p("tool"), "no tool of that name in force.tools"));
            }
            pos(case.spindle_rpm, &p("spindle_rpm"))?;
            pos(case.force_ref_n, &p("force_ref_n"))?;
            pos(
                case.programmed_feed_mm_per_min,
                &p("programmed_feed_mm_per_min"),
            )?;
            if let Some(poles) = &case.poles {
                check_poles(poles, &p("poles"), &bad)?;
            }
            if case.settled_revolutions == 0 {
                return Err(bad(p("settled_revolutions"), "must be at least 1"));
            }
            if case.segments.is_empty() {
                return Err(bad(p("segments"), "at least one segment"));
            }
            for (j, s) in case.segments.iter().enumerate() {
                let q = |f: &str| format!("cases[{i}].segments[{j}].{f}");
                pos(s.length_mm, &q("length_mm"))?;
                pos(s.depth_mm, &q("depth_mm"))?;
                if self.material(&s.material).is_none() {
                    return Err(bad(q("material"), "no material of that name"));
                }
                if let Some(f) = s.paper_feed_mm_per_min {
                    pos(f, &q("paper_feed_mm_per_min"))?;
                }
            }
            for (j, e) in case.events.iter().enumerate() {
                let q = |f: &str| format!("cases[{i}].events[{j}].{f}");
                if !(e.at_s.is_finite() && e.at_s >= 0.0) {
                    return Err(bad(q("at_s"), "must be finite and >= 0"));
                }
                pos(e.duration_s, &q("duration_s"))?;
                if !(e.force_scale.is_finite() && e.force_scale >= 0.0) {
                    return Err(bad(q("force_scale"), "must be finite and >= 0"));
                }
            }
        }
        if let Some(a) = &self.adaptive_feed {
            if self.case(&a.case).is_none() {
                return Err(bad(
                    "adaptive_feed.case".into(),
                    "no case of that name in force.cases",
                ));
            }
            pos(a.calibration.a_per_n, "adaptive_feed.calibration.a_per_n")?;
            if !a.calibration.b_a.is_finite() {
                return Err(bad(
                    "adaptive_feed.calibration.b_a".into(),
                    "must be finite",
                ));
            }
        }
        if let Some(w) = &self.sim_workpiece {
            if self.case(&w.case).is_none() {
                return Err(bad(
                    "sim_workpiece.case".into(),
                    "no case of that name in force.cases",
                ));
            }
            if !w.start_mm.is_finite() {
                return Err(bad("sim_workpiece.start_mm".into(), "must be finite"));
            }
        }
        Ok(())
    }

    /// The case adaptive feed runs with (validated).
    pub fn adaptive_case(&self) -> Option<(&AdaptiveFeed, &ForceCase)> {
        let a = self.adaptive_feed.as_ref()?;
        Some((a, self.case(&a.case)?))
    }

    fn check_names(
        &self,
        material: &str,
        tool: &str,
        at: &str,
        bad: &dyn Fn(String, &str) -> Invalid,
    ) -> Result<(), Invalid> {
        if self.material(material).is_none() {
            return Err(bad(format!("{at}.material"), "no material of that name"));
        }
        if self.tool(tool).is_none() {
            return Err(bad(format!("{at}.tool"), "no tool of that name"));
        }
        Ok(())
    }
}

fn check_poles(
    poles: &[f64; 4],
    path: &str,
    bad: &dyn Fn(String, &str) -> Invalid,
) -> Result<(), Invalid> {
    if poles.iter().all(|p| p.is_finite() && p.abs() < 1.0) {
        Ok(())
    } else {
        Err(bad(path.into(), "poles must lie inside the unit circle"))
    }
}
