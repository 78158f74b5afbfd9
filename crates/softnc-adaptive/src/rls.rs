//! Recursive least squares for Θ = [−φ₁, −φ₂, θ₁, θ₂] (003 eq 11–12), with covariance
//! resetting (to keep adapting when the process changes) and a dead zone (stop
//! adapting when the prediction error is small, so noise does not drift the model).

/// Estimator settings (machine profile).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RlsConfig {
    /// Initial and reset covariance P = p0·I.
    pub p0: f64,
    /// Forgetting factor λ (1 = none).
    pub forgetting: f64,
    /// Dead zone: no update while |prediction error| ≤ this (output units).
    pub dead_zone: f64,
    /// Reset P to p0·I when its trace falls below this.
    pub reset_trace: f64,
}

/// The estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct Rls {
    cfg: RlsConfig,
    theta: [f64; 4],
    p: [[f64; 4]; 4],
    resets: u64,
}

impl Rls {
    /// Start from an initial guess Θ₀.
    pub fn new(cfg: RlsConfig, theta0: [f64; 4]) -> Self {
        let mut r = Rls {
            cfg,
            theta: theta0,
            p: [[0.0; 4]; 4],
            resets: 0,
        };
        r.reset_covariance();
        r
    }

    fn reset_covariance(&mut self) {
        self.p = [[0.0; 4]; 4];
        for (i, row) in self.p.iter_mut().enumerate() {
            row[i] = self.cfg.p0;
        }
    }

    /// Current estimate Θ.
    pub fn theta(&self) -> [f64; 4] {
        self.theta
    }

    /// Covariance resets so far.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// One update with regressor Φ_m(t−1) = [y(t−1), y(t−2), u(t−1), u(t−2)] and the
    /// new output y(t) (003 eq 11). Returns the prediction error before the update.
    pub fn update(&mut self, phi: [f64; 4], y: f64) -> f64 {
        let pred: f64 = (0..4).map(|i| phi[i] * self.theta[i]).sum();
        let err = y - pred;
        if err.abs() <= self.cfg.dead_zone {
            return err;
        }
        let mut pphi = [0.0; 4];
        for (i, v) in pphi.iter_mut().enumerate() {
            *v = (0..4).map(|j| self.p[i][j] * phi[j]).sum();
        }
        let denom = self.cfg.forgetting + (0..4).map(|i| phi[i] * pphi[i]).sum::<f64>();
        let k = pphi.map(|v| v / denom);
        for i in 0..4 {
            self.theta[i] += k[i] * err;
        }
        // P ← (P − k·(Pφ)ᵀ)/λ  (P symmetric)
        for i in 0..4 {
            for j in 0..4 {
                self.p[i][j] = (self.p[i][j] - k[i] * pphi[j]) / self.cfg.forgetting;
            }
        }
        let trace: f64 = (0..4).map(|i| self.p[i][i]).sum();
        if trace < self.cfg.reset_trace {
            self.reset_covariance();
            self.resets += 1;
        }
        err
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zoh::zoh_second_order;

    fn cfg() -> RlsConfig {
        RlsConfig {
            p0: 1e3,
            forgetting: 1.0,
            dead_zone: 1e-9,
            reset_trace: 1e-3,
        }
    }

    #[test]
    fn identifies_a_model_and_tracks_a_change() {
        let cfg = || RlsConfig {
            reset_trace: 0.05,
            ..super::tests::cfg()
        };
        let m1 = zoh_second_order(3.0, 0.05, 0.2, 0.1);
        let m2 = zoh_second_order(6.0, 0.05, 0.35, 0.1);
        let mut rls = Rls::new(cfg(), [0.5, 0.0, 0.1, 0.1]);
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        let mut x = 12345u64;
        for t in 0..600 {
            let m = if t < 300 { m1 } else { m2 };
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = if (x >> 33) & 1 == 1 { 1.0 } else { -1.0 };
            let y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
            rls.update([y1, y2, u1, u2], y);
            (y2, y1, u2, u1) = (y1, y, u1, u);
            if t == 299 {
                let th = rls.theta();
                for (a, b) in th.iter().zip(m1.theta()) {
                    assert!((a - b).abs() < 1e-4, "{th:?} vs {:?}", m1.theta());
                }
            }
        }
        assert!(
            rls.resets() > 0,
            "covariance resetting keeps the estimator alive"
        );
        for (a, b) in rls.theta().iter().zip(m2.theta()) {
            assert!(
                (a - b).abs() < 1e-4,
                "{:?} vs {:?}",
                rls.theta(),
                m2.theta()
            );
        }
    }

    #[test]
    fn dead_zone_stops_adaptation_on_small_errors() {
        let mut c = cfg();
        c.dead_zone = 0.5;
        let mut rls = Rls::new(c, [0.1, 0.2, 0.3, 0.4]);
        rls.update([1.0, 0.0, 0.0, 0.0], 0.1 + 0.4);
        assert_eq!(rls.theta(), [0.1, 0.2, 0.3, 0.4]);
    }
}
