//! Incremental PID (paper 001 eq 14); P and PI are the same law with zero gains.

/// u(k) = u(k−1) + K_p[e(k) − e(k−1)] + K_i e(k) + K_d[e(k) − 2e(k−1) + e(k−2)]   (001 eq 14)
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IncrementalPid {
    /// K_p.
    pub kp: f64,
    /// K_i (per cycle).
    pub ki: f64,
    /// K_d (per cycle).
    pub kd: f64,
    /// Output limit (±); 0 = none. The stored u(k−1) is the limited one (no wind-up).
    pub limit: f64,
    u1: f64,
    e1: f64,
    e2: f64,
}

impl IncrementalPid {
    /// A controller at rest.
    pub fn new(kp: f64, ki: f64, kd: f64, limit: f64) -> Self {
        IncrementalPid {
            kp,
            ki,
            kd,
            limit,
            u1: 0.0,
            e1: 0.0,
            e2: 0.0,
        }
    }

    /// One step with error e(k).
    pub fn step(&mut self, e: f64) -> f64 {
        let mut u = self.u1
            + self.kp * (e - self.e1)
            + self.ki * e
            + self.kd * (e - 2.0 * self.e1 + self.e2);
        if self.limit > 0.0 {
            u = u.clamp(-self.limit, self.limit);
        }
        self.u1 = u;
        self.e2 = self.e1;
        self.e1 = e;
        u
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.u1 = 0.0;
        self.e1 = 0.0;
        self.e2 = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn p_only_is_proportional() {
        let mut c = IncrementalPid::new(2.0, 0.0, 0.0, 0.0);
        for e in [1.0, 3.0, -2.0, 0.5] {
            assert!((c.step(e) - 2.0 * e).abs() < 1e-12);
        }
    }

    #[test]
    fn integral_accumulates_and_limit_prevents_windup() {
        let mut c = IncrementalPid::new(0.0, 0.5, 0.0, 0.0);
        let mut u = 0.0;
        for _ in 0..4 {
            u = c.step(1.0);
        }
        assert!((u - 2.0).abs() < 1e-12);
        let mut c = IncrementalPid::new(0.0, 1.0, 0.0, 3.0);
        for _ in 0..100 {
            c.step(1.0);
        }
        // saturated at 3; one negative step comes off the limit at once
        assert!((c.step(-1.0) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn derivative_on_a_ramp_is_constant() {
        let mut c = IncrementalPid::new(0.0, 0.0, 1.0, 0.0);
        let outs: Vec<f64> = (0..6).map(|k| c.step(k as f64)).collect();
        // u(k) = Σ second differences = e(k) − e(k−1) = 1 from k ≥ 1
        assert!(
            outs[2..].iter().all(|u| (u - 1.0).abs() < 1e-12),
            "{outs:?}"
        );
    }
}
