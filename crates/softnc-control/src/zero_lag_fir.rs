//! Zero-lag non-causal FIR command filter (paper 002, eq 1–3).
//!
//! The position task reads N future command positions from the lookahead ring, so it
//! can filter with a symmetric window around the current sample: zero phase, hence
//! no lag, where a causal filter with the same coefficients lags N samples.

use crate::config::CommandFilterConfig;
use softnc_core::ring::LookaheadRing;

/// Why a filter cannot be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FirDesignError {
    /// f must lie in (0, 1/(2T)).
    #[error(
        "filter frequency {f_hz} Hz must lie between 0 and the Nyquist frequency {nyquist_hz} Hz"
    )]
    Frequency {
        /// Requested frequency.
        f_hz: f64,
        /// Nyquist frequency 1/(2T).
        nyquist_hz: f64,
    },
    /// N must be at least 1.
    #[error("filter order N must be at least 1")]
    Order,
}

/// Symmetric FIR of order N: 2N + 1 taps k'_{−N..N}, unity DC gain.
#[derive(Debug, Clone, PartialEq)]
pub struct ZeroLagFir {
    /// k'_0 .. k'_N (k'_{−i} = k'_i).
    half: Vec<f64>,
}

impl ZeroLagFir {
    /// Coefficients from filter frequency `f_hz`, cycle `t_s` and order `n` (eq 2, 3).
    pub fn design(f_hz: f64, t_s: f64, n: usize) -> Result<Self, FirDesignError> {
        let nyquist_hz = 0.5 / t_s;
        if !(f_hz > 0.0 && f_hz < nyquist_hz) {
            return Err(FirDesignError::Frequency { f_hz, nyquist_hz });
        }
        if n == 0 {
            return Err(FirDesignError::Order);
        }
        let pi = std::f64::consts::PI;
        let mut half = Vec::with_capacity(n + 1);
        half.push(2.0 * f_hz * t_s); // k_0 = 2fT (eq 2)
        for i in 1..=n {
            let i_f = i as f64;
            // k_i = (1 + cos(πi/N)) / (2πi) · sin(2πfTi) (eq 2)
            half.push(
                (1.0 + (pi * i_f / n as f64).cos()) / (2.0 * pi * i_f)
                    * (2.0 * pi * f_hz * t_s * i_f).sin(),
            );
        }
        // k'_i = k_i / Σ_{−N..N} k_i (eq 3)
        let sum: f64 = half[0] + 2.0 * half[1..].iter().sum::<f64>();
        half.iter_mut().for_each(|k| *k /= sum);
        Ok(ZeroLagFir { half })
    }

    /// Order N.
    pub fn order(&self) -> usize {
        self.half.len() - 1
    }

    /// Coefficient k'_j for j in −N..=N.
    pub fn coeff(&self, j: i64) -> f64 {
        self.half[j.unsigned_abs() as usize]
    }

    /// ρ'(i) = Σ_{j=−N..N} k'_j ρ(i−j) (eq 1) over the ring's window around its
    /// current sample, per axis. `None` until the window is available.
    pub fn apply<const AXES: usize, const CAP: usize>(
        &self,
        ring: &LookaheadRing<AXES, CAP>,
    ) -> Option<[f64; AXES]> {
        let mut out = [0.0; AXES];
        for (axis, o) in out.iter_mut().enumerate() {
            *o = self.apply_axis(ring, axis)?;
        }
        Some(out)
    }

    /// ρ'(i) of eq 1 on axis `axis` only.
    pub fn apply_axis<const AXES: usize, const CAP: usize>(
        &self,
        ring: &LookaheadRing<AXES, CAP>,
        axis: usize,
    ) -> Option<f64> {
        let n = self.order() as i64;
        let mut out = 0.0;
        // pair symmetric taps: k'_j (ρ(i−j) + ρ(i+j)), summed from the outside in
        for j in (1..=n).rev() {
            out += self.coeff(j) * (ring.at(-j)?[axis] + ring.at(j)?[axis]);
        }
        Some(out + self.half[0] * ring.at(0)?[axis])
    }

    /// Frequency response H(f) = k'_0 + 2 Σ k'_i cos(2π f T i) (real: zero phase).
    pub fn response(&self, f_hz: f64, t_s: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * f_hz * t_s;
        self.half[0]
            + 2.0
                * self.half[1..]
                    .iter()
                    .enumerate()
                    .map(|(i, k)| k * (w * (i + 1) as f64).cos())
                    .sum::<f64>()
    }
}

/// The command filters of all axes of a position task: each axis filtered by its own
/// zero-lag FIR or passed through; designed once per job, off the cycle path.
#[derive(Debug, Clone, PartialEq)]
pub struct CommandFilter<const AXES: usize> {
    axes: [Option<ZeroLagFir>; AXES],
}

impl<const AXES: usize> Default for CommandFilter<AXES> {
    /// All axes pass their commands through.
    fn default() -> Self {
        CommandFilter {
            axes: std::array::from_fn(|_| None),
        }
    }
}

impl<const AXES: usize> CommandFilter<AXES> {
    /// Filters from the profile's per-axis settings at cycle `t_s` (`None` = off).
    pub fn design(
        configs: [Option<CommandFilterConfig>; AXES],
        t_s: f64,
    ) -> Result<Self, (usize, FirDesignError)> {
        let mut axes: [Option<ZeroLagFir>; AXES] = std::array::from_fn(|_| None);
        for (axis, cfg) in configs.iter().enumerate() {
            if let Some(c) = cfg {
                axes[axis] =
                    Some(ZeroLagFir::design(c.frequency_hz, t_s, c.order).map_err(|e| (axis, e))?);
            }
        }
        Ok(CommandFilter { axes })
    }

    /// Future (and past) samples the filters read: the largest order, 0 when all off.
    pub fn window(&self) -> usize {
        self.axes
            .iter()
            .flatten()
            .map(ZeroLagFir::order)
            .max()
            .unwrap_or(0)
    }

    /// True when some axis is filtered.
    pub fn is_active(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }

    /// The filter of axis `axis`, if on.
    pub fn axis(&self, axis: usize) -> Option<&ZeroLagFir> {
        self.axes[axis].as_ref()
    }

    /// The position command of the ring's current sample: filtered (eq 1) on the
    /// axes that have a filter, as interpolated on the others. `None` until the
    /// window is in.
    pub fn apply<const CAP: usize>(&self, ring: &LookaheadRing<AXES, CAP>) -> Option<[f64; AXES]> {
        let mut out = ring.at(0)?;
        for (axis, f) in self.axes.iter().enumerate() {
            if let Some(f) = f {
                out[axis] = f.apply_axis(ring, axis)?;
            }
        }
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_core::ring::RingSample;

    #[test]
    fn unity_dc_gain_and_symmetry() {
        let f = ZeroLagFir::design(10.0, 0.001, 50).unwrap();
        let sum: f64 = (-50..=50).map(|j| f.coeff(j)).sum();
        assert!((sum - 1.0).abs() < 1e-12);
        assert!((f.response(0.0, 0.001) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn cutoff_near_half_gain_and_stopband_small() {
        // eq 2 is a Hann-windowed ideal low-pass of cut-off f: about half gain at f
        let f = ZeroLagFir::design(20.0, 0.001, 100).unwrap();
        let at_f = f.response(20.0, 0.001);
        assert!((at_f - 0.5).abs() < 0.05, "H(f) = {at_f}");
        assert!(f.response(5.0, 0.001) > 0.95);
        assert!(f.response(60.0, 0.001).abs() < 0.01);
    }

    #[test]
    fn zero_lag_on_constant_velocity_where_causal_lags_n() {
        let t = 0.001;
        let n = 40usize;
        let fir = ZeroLagFir::design(15.0, t, n).unwrap();
        let mut ring: LookaheadRing<1, 512> = LookaheadRing::new();
        let v = 25.0; // mm/s
        let x = |k: i64| v * t * k as f64;
        for k in 0..200 {
            ring.push(
                RingSample {
                    seq: k,
                    pos_mm: [x(k as i64)],
                },
                false,
            )
            .unwrap();
        }
        for _ in 0..80 {
            ring.advance();
        }
        let i = ring.current_index() as i64;
        let filtered = fir.apply(&ring).unwrap()[0];
        assert!(
            (filtered - x(i)).abs() < 1e-9,
            "zero-lag filter moved a ramp by {}",
            filtered - x(i)
        );
        // the same coefficients applied causally (k'_j to ρ(i−N−j)) lag N samples
        let causal: f64 = (-(n as i64)..=n as i64)
            .map(|j| fir.coeff(j) * x(i - n as i64 - j))
            .sum();
        assert!((causal - x(i - n as i64)).abs() < 1e-9);
        assert!((x(i) - causal - v * t * n as f64).abs() < 1e-9);
    }

    #[test]
    fn bad_designs_are_refused() {
        assert!(matches!(
            ZeroLagFir::design(600.0, 0.001, 10),
            Err(FirDesignError::Frequency { .. })
        ));
        assert_eq!(
            ZeroLagFir::design(10.0, 0.001, 0),
            Err(FirDesignError::Order)
        );
    }
}
