//! Accuracy figures: running max |e|, RMS and mean of an error signal.

/// Running statistics of one error signal (mm).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    n: u64,
    sum: f64,
    sum_sq: f64,
    max_abs: f64,
}

impl ErrorStats {
    /// Add one sample.
    #[inline]
    pub fn add(&mut self, e: f64) {
        self.n += 1;
        self.sum += e;
        self.sum_sq += e * e;
        self.max_abs = self.max_abs.max(e.abs());
    }
    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.n
    }
    /// Largest |e| (0 with no samples).
    pub fn max_abs(&self) -> f64 {
        self.max_abs
    }
    /// Root mean square (0 with no samples).
    pub fn rms(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            (self.sum_sq / self.n as f64).sqrt()
        }
    }
    /// Mean (0 with no samples).
    pub fn mean(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum / self.n as f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_by_hand() {
        let mut s = ErrorStats::default();
        for e in [3.0, -4.0] {
            s.add(e);
        }
        assert_eq!(s.max_abs(), 4.0);
        assert!((s.rms() - 12.5f64.sqrt()).abs() < 1e-15);
        assert_eq!(s.mean(), -0.5);
    }
}
