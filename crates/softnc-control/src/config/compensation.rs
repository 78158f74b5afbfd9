//! Disturbance compensation settings of one axis (paper 000): the general
//! compensator for friction (disturbance observer or model-based attenuator) and
//! the periodic disturbance canceller. The algorithms live in `softnc-control`
//! (`dob`, `mbda`, `pdc`, `compensation`); these are their profile settings.

use serde::{Deserialize, Serialize};

/// Compensation of one axis, applied to the position controller's output (a
/// velocity command for paper 000's velocity-loop plants). Off by default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct Compensation {
    /// Outer, general compensator (friction and other aperiodic disturbances).
    #[serde(default)]
    pub outer: OuterCompensator,
    /// Inner periodic disturbance canceller, designed for the spindle's tooth
    /// frequency when a job starts and whenever the spindle speed changes.
    #[serde(default)]
    pub pdc: Option<PdcConfig>,
}

/// The outer compensator of paper 000 Fig. 4 / Fig. 6.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub enum OuterCompensator {
    /// None.
    #[default]
    None,
    /// Disturbance observer with the Umeno–Hori Q filter (eq 32).
    Dob(DobConfig),
    /// Model-based disturbance attenuator (eq 33–34).
    Mbda(MbdaConfig),
}

/// Q-filter parameters (eq 32).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DobConfig {
    /// Order K of the Q filter (degree of its denominator).
    pub order_k: usize,
    /// Relative degree r of Q (≥ the model's relative degree, ≥ 1, ≤ K).
    pub relative_degree_r: usize,
    /// Time constant τ of Q [s].
    pub tau_s: f64,
}

/// PI gains of M(z⁻¹) (output difference → plant input, same units in and out).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MbdaConfig {
    /// Proportional gain K_p [1].
    pub kp: f64,
    /// Integral gain K_i [1/s].
    pub ki_per_s: f64,
}

/// How the zero angles in the configuration are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ZeroAngleReading {
    /// θ_k as written.
    Literal,
    /// θ_k − π: the reading under which the paper's printed zeros give its figures.
    MinusPi,
}

/// One zero z_k = r_k e^{jθ_k} of L_min (eq 20); its conjugate is added.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ZeroSpec {
    /// r_k, 0 < r_k < 1.
    pub radius: f64,
    /// θ_k in units of π (before the [`ZeroAngleReading`] is applied).
    pub angle_pi: f64,
}

/// One point of the stated multiplicative model uncertainty |Δ(f)| (eq 13),
/// interpolated linearly in frequency and held constant beyond the ends.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UncertaintyPoint {
    /// Frequency [Hz].
    pub freq_hz: f64,
    /// |Δ| at that frequency (relative, 0.2 = 20 %).
    pub relative: f64,
}

/// PDC design parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdcConfig {
    /// The M/4 zeros z_k of L (eq 20); M = 4 · zeros, D_L = 2 · zeros.
    pub zeros: Vec<ZeroSpec>,
    /// How `zeros[..].angle_pi` is read.
    pub angle_reading: ZeroAngleReading,
    /// Number of taps N of W (order N − 1, eq 23).
    pub w_taps: usize,
    /// RLS initialisation R(0) = δ⁻¹ I (eq 31).
    pub rls_delta: f64,
    /// Samples over which the RLS adapts.
    pub rls_samples: usize,
    /// Samples run through P_m before the RLS starts adapting.
    pub rls_warmup_samples: usize,
    /// Allowed | |H P_n(f_d)| − 1 | (eq 11).
    pub gain_tolerance: f64,
    /// Allowed |∠H P_n(f_d)| [deg] (eq 12).
    pub phase_tolerance_deg: f64,
    /// L must be at most this gain at the Nyquist frequency [dB].
    pub max_l_gain_nyquist_db: f64,
    /// Stated multiplicative model uncertainty |Δ(f)| for eq 13.
    pub uncertainty: Vec<UncertaintyPoint>,
    /// Frequencies in (0, f_s/2] on which eq 13 is checked (plus DC).
    pub robust_grid_points: usize,
    /// Our extension (not in the paper): also teach W to block DC, so that
    /// H·P_n(0) = 0. The RLS input gets a constant offset of this size whose
    /// desired output is 0 (eq 26 becomes s(n) + c, the target stays s(n)); 0 = the
    /// paper's single sinusoid. Without it the paper's W leaves H·P_n(0) ≈ −1: the
    /// canceller doubles slow disturbances (friction) and feeds slow measurement
    /// noise back.
    #[serde(default)]
    pub w_dc_block_level: f64,
}
