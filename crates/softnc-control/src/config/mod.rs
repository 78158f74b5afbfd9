//! The configuration this crate's algorithms own: each one's schema and validation
//! (with the RON path of a bad field), composed into the machine profile's `servo`
//! section by `softnc-core`. Paper defaults are files under `config/`, not code.
//!
//! - [`ControllerConfig`]: an axis's feedback and feedforward (PID or fuzzy).
//! - [`CommandFilterConfig`]: paper 002's zero-lag command filter.
//! - [`compensation`]: paper 000's DOB, MBDA and PDC.
//! - [`fuzzy`]: paper 001's fuzzy-logic controller.

pub mod compensation;
pub mod fuzzy;

use serde::{Deserialize, Serialize};
use softnc_core::ron_file::ConfigError;

/// The position controller of one axis (the stack's feedback and feedforward).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerConfig {
    /// Proportional gain (output units per mm of error).
    pub kp: f64,
    /// Integral gain per cycle (output units per mm per cycle), incremental form.
    #[serde(default)]
    pub ki: f64,
    /// Derivative gain (output units per mm of error change per cycle).
    #[serde(default)]
    pub kd: f64,
    /// Velocity feedforward (output units per mm/s of command velocity).
    #[serde(default)]
    pub vff: f64,
    /// Acceleration feedforward (output units per mm/s² of command acceleration).
    #[serde(default)]
    pub aff: f64,
    /// Output saturation (±, output units); 0 = none.
    #[serde(default)]
    pub output_limit: f64,
    /// Fuzzy-logic feedback (paper 001) instead of the PID: when present, `kp`, `ki`
    /// and `kd` are unused and this rule base, membership table and integral gain
    /// act on the error (feedforward and `output_limit` still apply).
    #[serde(default)]
    pub fuzzy: Option<fuzzy::FuzzyConfig>,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            kp: 30.0,
            ki: 0.0,
            kd: 0.0,
            vff: 1.0,
            aff: 0.0,
            output_limit: 0.0,
            fuzzy: None,
        }
    }
}

impl ControllerConfig {
    /// Check every value; `prefix` is this section's RON path in its document
    /// (`servo.axes[1].controller`).
    pub fn validate_at(&self, file: &str, prefix: &str) -> Result<(), ConfigError> {
        let p = |f: &str| format!("{prefix}.{f}");
        for (name, v) in [
            ("kp", self.kp),
            ("ki", self.ki),
            ("kd", self.kd),
            ("vff", self.vff),
            ("aff", self.aff),
            ("output_limit", self.output_limit),
        ] {
            if !v.is_finite() {
                return Err(ConfigError::invalid(
                    file,
                    p(name),
                    "must be a finite number",
                ));
            }
        }
        if self.output_limit < 0.0 {
            return Err(ConfigError::invalid(
                file,
                p("output_limit"),
                "must be >= 0 (0 = no limit)",
            ));
        }
        if let Some(f) = &self.fuzzy {
            f.validate_at(file, &p("fuzzy"))?;
        }
        Ok(())
    }
}

/// Largest order N of the zero-lag command filter: its window of 2N + 1 samples must
/// fit the position process's lookahead ring.
pub const MAX_COMMAND_FILTER_ORDER: usize = 1000;

/// The zero-lag non-causal FIR of paper 002 (eq 1–3) on one axis's command positions.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandFilterConfig {
    /// Filter frequency f (Hz), below the Nyquist frequency of the cycle.
    pub frequency_hz: f64,
    /// Order N: the filter reads N past and N future command samples.
    pub order: usize,
}

impl CommandFilterConfig {
    /// Check the filter against the interpolation cycle `cycle_s`; `prefix` is its
    /// RON path (`servo.axes[0].command_filter`).
    pub fn validate_at(&self, file: &str, prefix: &str, cycle_s: f64) -> Result<(), ConfigError> {
        let nyquist_hz = 0.5 / cycle_s;
        if !(self.frequency_hz > 0.0 && self.frequency_hz < nyquist_hz) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.frequency_hz"),
                format!("must lie between 0 and the Nyquist frequency {nyquist_hz} Hz"),
            ));
        }
        if !(1..=MAX_COMMAND_FILTER_ORDER).contains(&self.order) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.order"),
                format!("must be 1 to {MAX_COMMAND_FILTER_ORDER}"),
            ));
        }
        Ok(())
    }
}
