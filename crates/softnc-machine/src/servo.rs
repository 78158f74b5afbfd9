//! The servo side of a machine profile: per-axis plant model, controller stack and
//! measurement, as the simulated backend and the position loop use them.
//!
//! Units are in the names; where a paper's unit is not a length (a DAC count, rad/s),
//! the field says so.

use serde::{Deserialize, Serialize};

pub use softnc_control::config::{CommandFilterConfig, ControllerConfig, MAX_COMMAND_FILTER_ORDER};
/// The plant models' sections: owned by `softnc-plant`.
pub use softnc_plant::config::{
    CuttingDisturbance, Friction001, PlantModel, SpindleModel, StructuralMode,
};

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
    /// The I/O map: which backend line each signal of the machine around the axes
    /// is; absent: no signal is mapped (no E-stop input, no limit switches, the
    /// spindle counted at speed).
    #[serde(default)]
    pub io: Option<crate::io::IoConfig>,
    /// The simulated machine's spindle; absent: it has none.
    #[serde(default)]
    pub spindle: Option<SpindleModel>,
    /// The simulated machine's tool changer, limit switches and probe plane;
    /// absent: no tool changer answers, no limit switch trips, no probe plane.
    #[serde(default)]
    pub sim_io: Option<crate::io::SimIo>,
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
    pub compensation: crate::compensation::Compensation,
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
