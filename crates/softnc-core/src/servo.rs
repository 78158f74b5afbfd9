//! The servo side of a machine profile: per-axis plant model, controller stack and
//! measurement, as the simulated backend and the position loop use them.
//!
//! Units are in the names; where a paper's unit is not a length (a DAC count, rad/s),
//! the field says so.

use serde::{Deserialize, Serialize};

pub use softnc_control::config::{CommandFilterConfig, ControllerConfig, MAX_COMMAND_FILTER_ORDER};

/// Servo settings of the whole machine.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ServoProfile {
    /// One entry per axis (X, Y, Z); missing axes use `AxisServo::default()`.
    #[serde(default)]
    pub axes: Vec<AxisServo>,
    /// Periodic cutting disturbance (paper 000 eq 2–3), off when absent.
    #[serde(default)]
    pub cutting: Option<CuttingDisturbance>,
    /// Random seed of the simulated machine (parameter variation, noise).
    #[serde(default = "default_seed")]
    pub seed: u64,
}

fn default_seed() -> u64 {
    1
}

/// One axis: plant, controller, measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisServo {
    /// The simulated drive and mechanics.
    pub plant: PlantModel,
    /// The position controller.
    pub controller: ControllerConfig,
    /// Standard deviation of position measurement noise (mm), before quantisation.
    #[serde(default)]
    pub noise_mm: f64,
    /// Disturbance compensation (paper 000 DOB/MBDA and PDC); none by default.
    #[serde(default)]
    pub compensation: softnc_control::config::compensation::Compensation,
    /// Zero-lag non-causal command filter (paper 002 eq 1–3); off when absent.
    #[serde(default)]
    pub command_filter: Option<CommandFilterConfig>,
    /// A lightly damped structural mode between motor and table (simulated machine
    /// only); none when absent.
    #[serde(default)]
    pub resonance: Option<StructuralMode>,
}

impl Default for AxisServo {
    fn default() -> Self {
        AxisServo {
            plant: PlantModel::FirstOrderLag {
                tau_s: 0.01,
                stick_mm: 0.0,
                stick_integral_s: 0.0,
            },
            controller: ControllerConfig::default(),
            noise_mm: 0.0,
            compensation: Default::default(),
            command_filter: None,
            resonance: None,
        }
    }
}

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
