//! A disturbance compensation (paper 000) that could not be designed for an axis:
//! the one error of the engine's designs when it is built ([`crate::engine`]) and of
//! the spindle designer's per spindle speed ([`crate::spindle`]).

use softnc_control::compensation::CompensationError;

/// Why an axis's disturbance compensation (paper 000) could not be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("servo.axes[{axis}].compensation: {error}")]
pub struct CompensationDesignError {
    /// Axis index.
    pub axis: usize,
    /// What failed.
    pub error: CompensationError,
}
