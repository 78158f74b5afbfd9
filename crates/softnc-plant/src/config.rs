//! The plant models' configuration: each model's schema and validation (with the
//! RON path of a bad field), composed into the machine profile's `servo` section by
//! `softnc-core`. Paper values are in the profiles under `config/machines/`.

use serde::{Deserialize, Serialize};
use softnc_core::ron_file::{positive, ConfigError};

/// Simulated plant of one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum PlantModel {
    /// Paper 000: identified discrete velocity loop
    /// P_n(z⁻¹) = (b₁z⁻¹ + b₂z⁻²)/(1 + a₁z⁻¹ + a₂z⁻²) from velocity command to motor
    /// speed (rad/s) at `sample_s`, driving a screw of `lead_mm` per revolution.
    /// The controller output is the velocity command in rad/s.
    VelocityLoop {
        /// [b₁, b₂].
        num: [f64; 2],
        /// [a₁, a₂].
        den: [f64; 2],
        /// Sample time the model was identified at (s); must equal the cycle.
        sample_s: f64,
        /// Table travel per motor revolution (mm).
        lead_mm: f64,
        /// Constant (Coulomb) friction, as an equivalent velocity-command offset
        /// opposing motion (rad/s); 0 = none.
        #[serde(default)]
        coulomb_rad_s: f64,
    },
    /// Paper 001: a DC servo of open-loop gain K and time constant τ, driven by an
    /// 8-bit DAC: τ·dV/dt + V = K·(u − F_d(V)), friction F_d of eq 15 in DAC counts,
    /// with stick–slip (Karnopp): at rest the axis stays while |u| is below the
    /// breakaway friction.
    DcMotor {
        /// Open-loop gain K ((mm/min) per DAC count).
        gain_mm_per_min_per_dac: f64,
        /// Time constant τ (s).
        tau_s: f64,
        /// DAC saturation (counts, ±).
        dac_limit: f64,
        /// Friction model F_d(V).
        friction: Friction001,
        /// Relative random variation of K and τ (±, uniform, seeded), e.g. 0.05.
        #[serde(default)]
        param_variation: f64,
        /// Relative random variation of friction (±, uniform, seeded), e.g. 0.08.
        #[serde(default)]
        friction_variation: f64,
    },
    /// Paper 004: servo and acc/dec as one first-order lag G(s) = 1/(1 + Ts) from
    /// command position to table position, with static friction at reversals: after
    /// the axis stops and the command turns back, it stays until the velocity loop's
    /// drive (the lag, plus its integral if `stick_integral_s` > 0) exceeds
    /// `stick_mm`. The controller is bypassed (its output is the command).
    FirstOrderLag {
        /// Time constant T (s).
        tau_s: f64,
        /// Lost motion at a reversal (mm); 0 = none: the lag e the velocity loop's
        /// proportional part alone needs to break the axis away.
        #[serde(default)]
        stick_mm: f64,
        /// Integral time T_i of the velocity loop's PI (s): while stuck the drive is
        /// e + (1/T_i)∫e dt, and the axis breaks away when it exceeds `stick_mm`;
        /// 0 = no integrator.
        #[serde(default)]
        stick_integral_s: f64,
    },
}

/// Friction of paper 001 eq 15: saturated above |V| ≥ v_sat, a quadratic below
/// (V in mm/s, F in DAC counts).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction001 {
    /// Speed from which friction is constant (mm/s).
    pub v_sat_mm_s: f64,
    /// Friction for V ≥ v_sat.
    pub pos_sat: f64,
    /// Quadratic [a, b, c] (a·V² + b·V + c) for 0 ≤ V < v_sat.
    pub pos_quad: [f64; 3],
    /// Quadratic for −v_sat ≤ V < 0.
    pub neg_quad: [f64; 3],
    /// Friction for V < −v_sat.
    pub neg_sat: f64,
}

impl Friction001 {
    /// F_d(V) (DAC counts) for V in mm/s (eq 15).
    pub fn at(&self, v_mm_s: f64) -> f64 {
        let q = |c: &[f64; 3]| c[0] * v_mm_s * v_mm_s + c[1] * v_mm_s + c[2];
        if v_mm_s >= self.v_sat_mm_s {
            self.pos_sat
        } else if v_mm_s >= 0.0 {
            q(&self.pos_quad)
        } else if v_mm_s >= -self.v_sat_mm_s {
            q(&self.neg_quad)
        } else {
            self.neg_sat
        }
    }
}

/// Periodic cutting disturbance T = A·sin(2π f_d t + θ) with f_d = rpm·flutes/60
/// (paper 000 eq 2–3), added at every axis's plant input during feed moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CuttingDisturbance {
    /// Spindle speed (rpm).
    pub spindle_rpm: f64,
    /// Number of flutes.
    pub flutes: u32,
    /// Amplitude per axis (plant input units).
    pub amplitude: [f64; 3],
    /// Phase θ_d (rad).
    #[serde(default)]
    pub phase_rad: f64,
}

impl CuttingDisturbance {
    /// Tooth-passing frequency f_d (Hz), eq 2.
    pub fn frequency_hz(&self) -> f64 {
        self.spindle_rpm * self.flutes as f64 / 60.0
    }
}

/// A structural mode between the motor (whose encoder the loop reads) and the table:
/// ẍ_t = ω²(x_m − x_t) + 2ζω(ẋ_m − ẋ_t), ω = 2π·`frequency_hz`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StructuralMode {
    /// Natural frequency (Hz).
    pub frequency_hz: f64,
    /// Damping ratio ζ (0 < ζ < 1; lightly damped: 0.01–0.05).
    pub damping_ratio: f64,
}

impl PlantModel {
    /// Checks the model at RON path `prefix` of `file`; a discrete model must be
    /// identified at the cycle `cycle_s`.
    pub fn validate_at(&self, file: &str, prefix: &str, cycle_s: f64) -> Result<(), ConfigError> {
        let p = |f: &str| format!("{prefix}.{f}");
        match self {
            PlantModel::VelocityLoop {
                num,
                den,
                sample_s,
                lead_mm,
                coulomb_rad_s,
            } => {
                if (sample_s - cycle_s).abs() > 1e-12 {
                    return Err(ConfigError::invalid(
                        file,
                        p("sample_s"),
                        "must equal interpolation_cycle_s (the model is discrete at that rate)",
                    ));
                }
                positive(*lead_mm, &p("lead_mm"), file)?;
                if !(num.iter().chain(den.iter()).all(|v| v.is_finite()) && *coulomb_rad_s >= 0.0) {
                    return Err(ConfigError::invalid(
                        file,
                        prefix.to_string(),
                        "coefficients must be finite and coulomb_rad_s >= 0",
                    ));
                }
                // poles inside the unit circle: |a2| < 1 and |a1| < 1 + a2
                if !(den[1].abs() < 1.0 && den[0].abs() < 1.0 + den[1]) {
                    return Err(ConfigError::invalid(
                        file,
                        p("den"),
                        "the velocity loop is unstable (poles outside the unit circle)",
                    ));
                }
            }
            PlantModel::DcMotor {
                gain_mm_per_min_per_dac,
                tau_s,
                dac_limit,
                param_variation,
                friction_variation,
                ..
            } => {
                positive(
                    *gain_mm_per_min_per_dac,
                    &p("gain_mm_per_min_per_dac"),
                    file,
                )?;
                positive(*tau_s, &p("tau_s"), file)?;
                positive(*dac_limit, &p("dac_limit"), file)?;
                for (n, v) in [
                    ("param_variation", param_variation),
                    ("friction_variation", friction_variation),
                ] {
                    if !(0.0..MAX_RELATIVE_VARIATION).contains(v) {
                        return Err(ConfigError::invalid(file, p(n), "must be in [0, 0.5)"));
                    }
                }
            }
            PlantModel::FirstOrderLag {
                tau_s,
                stick_mm,
                stick_integral_s,
            } => {
                positive(*tau_s, &p("tau_s"), file)?;
                for (n, v) in [
                    ("stick_mm", stick_mm),
                    ("stick_integral_s", stick_integral_s),
                ] {
                    if !(*v >= 0.0 && v.is_finite()) {
                        return Err(ConfigError::invalid(file, p(n), "must be finite and >= 0"));
                    }
                }
            }
        }
        Ok(())
    }
}

/// Largest relative random variation of a simulated parameter (exclusive): ±50 %
/// would let a gain or time constant reach zero.
pub const MAX_RELATIVE_VARIATION: f64 = 0.5;

impl CuttingDisturbance {
    /// Checks the disturbance at RON path `prefix` of `file`: its tooth frequency
    /// must lie below the Nyquist frequency of the cycle `cycle_s`.
    pub fn validate_at(&self, file: &str, prefix: &str, cycle_s: f64) -> Result<(), ConfigError> {
        positive(self.spindle_rpm, &format!("{prefix}.spindle_rpm"), file)?;
        if self.flutes == 0 {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.flutes"),
                "must be at least 1",
            ));
        }
        if self.frequency_hz() >= 0.5 / cycle_s {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.spindle_rpm"),
                "tooth frequency at or above the Nyquist frequency of the cycle",
            ));
        }
        Ok(())
    }
}

impl StructuralMode {
    /// Checks the mode at RON path `prefix` of `file`.
    pub fn validate_at(&self, file: &str, prefix: &str) -> Result<(), ConfigError> {
        positive(self.frequency_hz, &format!("{prefix}.frequency_hz"), file)?;
        if !(self.damping_ratio > 0.0 && self.damping_ratio < 1.0) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.damping_ratio"),
                "must lie between 0 and 1 (a lightly damped mode)",
            ));
        }
        Ok(())
    }
}

/// A simulated spindle (the `servo.spindle` section): a rotor of inertia J driven by
/// its drive's speed loop with a torque limit, against a viscous loss, and its own
/// encoder (counts per revolution, one index pulse per revolution). The drive
/// accelerates at τ_max/J until it is within `speed_loop_s`·(τ_max/J) of the
/// command, then settles on it with time constant `speed_loop_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpindleModel {
    /// Rotor, tool holder and tool inertia J (kg·m²).
    pub inertia_kg_m2: f64,
    /// The drive's torque limit τ_max (N·m).
    pub max_torque_nm: f64,
    /// Viscous loss b (N·m per rad/s): the drive feeds it forward, so the spindle
    /// reaches its command; it brakes the spindle when the drive is off.
    pub viscous_nm_per_rad_s: f64,
    /// Time constant of the drive's speed loop below the torque limit (s).
    pub speed_loop_s: f64,
    /// Highest speed the drive turns at (rpm); commands above are clipped.
    pub max_rpm: f64,
    /// Encoder counts per revolution (one index pulse per revolution).
    pub encoder_counts_per_rev: u32,
    /// M19: the highest speed the drive turns at while it orients the spindle
    /// (rpm; LinuxCNC's `orient` component's search speed).
    #[serde(default = "default_orient_rpm")]
    pub orient_rpm: f64,
    /// M19: the spindle is oriented (LinuxCNC's `spindle.N.is-oriented`) while
    /// its encoder's angle from the index is within this of the angle asked
    /// (degrees; the `orient` component's `tolerance`).
    #[serde(default = "default_orient_band_deg")]
    pub orient_band_deg: f64,
}

/// LinuxCNC's `orient` examples search at about a revolution a second.
fn default_orient_rpm() -> f64 {
    60.0
}

/// Half a degree: a few counts of a 4096-count encoder.
fn default_orient_band_deg() -> f64 {
    0.5
}

impl SpindleModel {
    /// Checks the spindle at RON path `prefix` of `file`.
    pub fn validate_at(&self, file: &str, prefix: &str, cycle_s: f64) -> Result<(), ConfigError> {
        positive(self.inertia_kg_m2, &format!("{prefix}.inertia_kg_m2"), file)?;
        positive(self.max_torque_nm, &format!("{prefix}.max_torque_nm"), file)?;
        positive(self.max_rpm, &format!("{prefix}.max_rpm"), file)?;
        if !(self.viscous_nm_per_rad_s >= 0.0 && self.viscous_nm_per_rad_s.is_finite()) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.viscous_nm_per_rad_s"),
                "must be finite and >= 0",
            ));
        }
        if !(self.speed_loop_s >= 2.0 * cycle_s && self.speed_loop_s.is_finite()) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.speed_loop_s"),
                "must be at least two interpolation cycles (the model steps once per cycle)",
            ));
        }
        let loss_nm = self.viscous_nm_per_rad_s * self.max_rpm * std::f64::consts::TAU / 60.0;
        if loss_nm >= self.max_torque_nm {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.viscous_nm_per_rad_s"),
                "the loss at max_rpm takes the whole torque: the spindle could not reach it",
            ));
        }
        if self.encoder_counts_per_rev == 0 {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.encoder_counts_per_rev"),
                "must be at least 1",
            ));
        }
        positive(self.orient_rpm, &format!("{prefix}.orient_rpm"), file)?;
        let count_deg = 360.0 / f64::from(self.encoder_counts_per_rev);
        if !(self.orient_band_deg >= count_deg && self.orient_band_deg < 180.0) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.orient_band_deg"),
                format!(
                    "must be at least one encoder count ({count_deg:.4} deg) and below 180 deg"
                ),
            ));
        }
        Ok(())
    }
}
