//! One simulated axis: the profile's plant model (000, 001 or 004) with its random
//! parameter variation drawn once from the seed.

use softnc_machine::servo::PlantModel;
use softnc_plant::dc_motor::DcMotor;
use softnc_plant::first_order_lag::FirstOrderLag;
use softnc_plant::rng::Rng;
use softnc_plant::velocity_loop::VelocityLoop;
pub use softnc_servo::CommandMode;

/// Longest integration sub-step of the continuous models (s). A numerical setting: the
/// plants' time constants are ≥ 10 ms, so 1 ms steps of their exact (ZOH) solutions
/// leave only the friction switching instants off by < 1 ms.
pub const MAX_SUBSTEP_S: f64 = 0.001;

/// Paper 001's K is per minute; the model integrates in seconds.
const SECONDS_PER_MINUTE: f64 = 60.0;

/// A simulated axis.
#[derive(Debug, Clone, PartialEq)]
pub enum Plant {
    /// Paper 000 eq 35/36.
    VelocityLoop(VelocityLoop),
    /// Paper 001.
    DcMotor(DcMotor),
    /// Paper 004 eq 1.
    FirstOrderLag(FirstOrderLag),
}

impl Plant {
    /// Build from the profile's model; `rng` supplies the ± variations (001 Sec. 4.1:
    /// K and τ ± `param_variation`, friction ± `friction_variation`, uniform, once per run).
    /// With `vary` off the nominal values are used.
    pub fn new(model: &PlantModel, rng: &mut Rng, vary: bool) -> Self {
        match model {
            PlantModel::VelocityLoop {
                num,
                den,
                sample_s,
                lead_mm,
                coulomb_rad_s,
            } => Plant::VelocityLoop(VelocityLoop::new(
                *num,
                *den,
                *sample_s,
                *lead_mm,
                *coulomb_rad_s,
            )),
            PlantModel::DcMotor {
                gain_mm_per_min_per_dac,
                tau_s,
                dac_limit,
                friction,
                param_variation,
                friction_variation,
            } => {
                // draw all three always, so switching variation off keeps other streams aligned
                let dk = rng.symmetric(*param_variation);
                let dt = rng.symmetric(*param_variation);
                let df = rng.symmetric(*friction_variation);
                let (dk, dt, df) = if vary { (dk, dt, df) } else { (0.0, 0.0, 0.0) };
                Plant::DcMotor(DcMotor::new(
                    gain_mm_per_min_per_dac / SECONDS_PER_MINUTE * (1.0 + dk),
                    tau_s * (1.0 + dt),
                    *dac_limit,
                    friction.clone(),
                    1.0 + df,
                ))
            }
            PlantModel::FirstOrderLag {
                tau_s,
                stick_mm,
                stick_integral_s,
            } => Plant::FirstOrderLag(FirstOrderLag::new(*tau_s, *stick_mm, *stick_integral_s)),
        }
    }

    /// What this axis's command means.
    pub fn command_mode(&self) -> CommandMode {
        match self {
            Plant::VelocityLoop(_) => CommandMode::Velocity,
            Plant::DcMotor(_) => CommandMode::Effort,
            Plant::FirstOrderLag(_) => CommandMode::Position,
        }
    }

    /// Sub-steps per cycle of `cycle_s`.
    pub fn substeps(&self, cycle_s: f64) -> u32 {
        match self {
            // discrete at its identification rate, which the profile checks equals the cycle
            Plant::VelocityLoop(_) => 1,
            _ => (cycle_s / MAX_SUBSTEP_S - 1e-9).ceil().max(1.0) as u32,
        }
    }

    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        match self {
            Plant::VelocityLoop(p) => p.reset(pos_mm),
            Plant::DcMotor(p) => p.reset(pos_mm),
            Plant::FirstOrderLag(p) => p.reset(pos_mm),
        }
    }

    /// True table position (mm).
    #[inline]
    pub fn pos_mm(&self) -> f64 {
        match self {
            Plant::VelocityLoop(p) => p.pos_mm(),
            Plant::DcMotor(p) => p.pos_mm(),
            Plant::FirstOrderLag(p) => p.pos_mm(),
        }
    }

    /// What reaches the plant for command `cmd`: the DAC's count for 001, else `cmd`.
    #[inline]
    pub fn command_input(&self, cmd: f64) -> f64 {
        match self {
            Plant::DcMotor(p) => p.dac(cmd),
            _ => cmd,
        }
    }

    /// Advance `h_s` with `input` = command input + disturbance (plant-input units).
    /// Returns the model-equivalent motor current: the net drive after friction (001:
    /// DAC counts; 000: rad/s of velocity-loop input; 004: mm/s of velocity demand).
    #[inline]
    pub fn substep(&mut self, input: f64, h_s: f64) -> f64 {
        match self {
            Plant::VelocityLoop(p) => p.step(input),
            Plant::DcMotor(p) => p.substep(input, h_s),
            Plant::FirstOrderLag(p) => p.substep(input, h_s),
        }
    }
}
