//! Recursive least squares for Θ = [−φ₁, −φ₂, θ₁, θ₂] (003 eq 11–12), with covariance
//! resetting (to keep adapting when the process changes) and a dead zone (stop
//! adapting when the prediction error is small, so noise does not drift the model).
//!
//! Θ, φ and P are nalgebra's fixed-size [`Vector4`] and [`Matrix4`]: the update runs
//! once per control sample and allocates nothing.

use nalgebra::{Matrix4, Vector4};

/// Estimator settings (the profile's `force.controller.rls`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RlsConfig {
    /// Initial and reset covariance P = p0·I.
    pub p0: f64,
    /// Forgetting factor λ (1 = none).
    pub forgetting: f64,
    /// Dead zone: no update while |prediction error| ≤ this (output units: N for
    /// the force loop).
    #[serde(rename = "dead_zone_n")]
    pub dead_zone: f64,
    /// Reset P to p0·I when its trace falls below this.
    pub reset_trace: f64,
}

/// The estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct Rls {
    cfg: RlsConfig,
    theta: Vector4<f64>,
    p: Matrix4<f64>,
    resets: u64,
}

impl Rls {
    /// Start from an initial guess Θ₀.
    pub fn new(cfg: RlsConfig, theta0: Vector4<f64>) -> Self {
        Rls {
            cfg,
            theta: theta0,
            p: Matrix4::from_diagonal_element(cfg.p0),
            resets: 0,
        }
    }

    /// Current estimate Θ.
    pub fn theta(&self) -> Vector4<f64> {
        self.theta
    }

    /// Covariance resets so far.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// One update with regressor Φ_m(t−1) = [y(t−1), y(t−2), u(t−1), u(t−2)] and the
    /// new output y(t) (003 eq 11). Returns the prediction error before the update.
    pub fn update(&mut self, phi: &Vector4<f64>, y: f64) -> f64 {
        let err = y - phi.dot(&self.theta);
        if err.abs() <= self.cfg.dead_zone {
            return err;
        }
        let p_phi = self.p * phi;
        // K = Pφ / (λ + φᵀPφ)   (eq 11)
        let k = p_phi / (self.cfg.forgetting + phi.dot(&p_phi));
        self.theta += k * err;
        // P ← (P − K(Pφ)ᵀ)/λ  (P symmetric)
        self.p = (self.p - k * p_phi.transpose()) / self.cfg.forgetting;
        if self.p.trace() < self.cfg.reset_trace {
            self.p = Matrix4::from_diagonal_element(self.cfg.p0);
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
        let mut rls = Rls::new(cfg(), Vector4::new(0.5, 0.0, 0.1, 0.1));
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
        let mut x = 12345u64;
        for t in 0..600 {
            let m = if t < 300 { m1 } else { m2 };
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let u = if (x >> 33) & 1 == 1 { 1.0 } else { -1.0 };
            let y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
            rls.update(&Vector4::new(y1, y2, u1, u2), y);
            (y2, y1, u2, u1) = (y1, y, u1, u);
            if t == 299 {
                let th = rls.theta();
                for (a, b) in th.iter().zip(m1.theta().iter()) {
                    assert!((a - b).abs() < 1e-4, "{th:?} vs {:?}", m1.theta());
                }
            }
        }
        assert!(
            rls.resets() > 0,
            "covariance resetting keeps the estimator alive"
        );
        for (a, b) in rls.theta().iter().zip(m2.theta().iter()) {
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
        let theta0 = Vector4::new(0.1, 0.2, 0.3, 0.4);
        let mut rls = Rls::new(c, theta0);
        rls.update(&Vector4::new(1.0, 0.0, 0.0, 0.0), 0.1 + 0.4);
        assert_eq!(rls.theta(), theta0);
    }
}
