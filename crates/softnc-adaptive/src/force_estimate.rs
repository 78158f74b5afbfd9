//! Sensorless peak-force measurement (paper 003 eq 25–32): the feed motor's phase
//! currents and rotor angle give I_q (Park transform), the calibration line
//! I_q = a·F + b gives the force, and the controlled output is its peak over one
//! spindle revolution (one control sample).

use crate::park::{park_iq, ForceCalibration};

/// Largest value of a signal since the last [`RevolutionPeak::take`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RevolutionPeak {
    max: f64,
}

impl Default for RevolutionPeak {
    fn default() -> Self {
        RevolutionPeak {
            max: f64::NEG_INFINITY,
        }
    }
}

impl RevolutionPeak {
    /// One sample.
    #[inline]
    pub fn push(&mut self, x: f64) {
        if x > self.max {
            self.max = x;
        }
    }
    /// The peak since the last take (`None` without samples); starts a new revolution.
    pub fn take(&mut self) -> Option<f64> {
        let m = self.max;
        self.max = f64::NEG_INFINITY;
        m.is_finite().then_some(m)
    }
}

/// Force estimator: phase currents → I_q → force; peak per revolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceEstimator {
    cal: ForceCalibration,
    peak_iq: RevolutionPeak,
}

impl ForceEstimator {
    /// With calibration `cal` (a > 0).
    pub fn new(cal: ForceCalibration) -> Self {
        ForceEstimator {
            cal,
            peak_iq: RevolutionPeak::default(),
        }
    }

    /// The calibration in use.
    pub fn calibration(&self) -> ForceCalibration {
        self.cal
    }

    /// One current sample: measured i_u, i_v (A) and the electrical angle n_p·θ
    /// (rad). Returns the instantaneous force estimate (N).
    #[inline]
    pub fn push(&mut self, i_u: f64, i_v: f64, theta_e: f64) -> f64 {
        let iq = park_iq(i_u, i_v, theta_e);
        self.peak_iq.push(iq);
        self.cal.force_n(iq)
    }

    /// Peak I_q of the revolution just ended (A); starts the next.
    pub fn take_revolution_peak_iq(&mut self) -> Option<f64> {
        self.peak_iq.take()
    }

    /// Peak force of the revolution just ended (N), from its peak I_q; starts the next.
    pub fn take_revolution_peak(&mut self) -> Option<f64> {
        self.peak_iq.take().map(|iq| self.cal.force_n(iq))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peak_of_a_revolution_through_the_calibration() {
        let cal = ForceCalibration {
            a_per_n: 0.00362,
            b_a: 4.127,
        };
        let mut e = ForceEstimator::new(cal);
        assert_eq!(e.take_revolution_peak(), None);
        for k in 0..100 {
            let th = k as f64 * 0.1;
            let f = 450.0 * (k as f64 * 0.2).sin().abs();
            let iq = cal.a_per_n * f + cal.b_a;
            let est = e.push(
                -iq * th.sin(),
                -iq * (th - 2.0 * std::f64::consts::PI / 3.0).sin(),
                th,
            );
            assert!((est - f).abs() < 1e-9);
        }
        let p = e.take_revolution_peak().unwrap();
        assert!(p <= 450.0 + 1e-9 && p > 449.0, "{p}");
        assert_eq!(e.take_revolution_peak(), None);
    }
}
