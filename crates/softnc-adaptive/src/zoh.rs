//! Zero-order-hold discretisation of two first-order lags in series (003 eq 5–7).

use nalgebra::Vector4;

/// y(t) + φ₁ y(t−1) + φ₂ y(t−2) = θ₁ u(t−1) + θ₂ u(t−2)   (003 eq 8).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arma2 {
    /// φ₁ (= a₁).
    pub phi1: f64,
    /// φ₂ (= a₂).
    pub phi2: f64,
    /// θ₁ (= b₁·gain).
    pub theta1: f64,
    /// θ₂ (= b₂·gain).
    pub theta2: f64,
}

impl Arma2 {
    /// Θ = [−φ₁, −φ₂, θ₁, θ₂] (003 eq 12).
    pub fn theta(&self) -> Vector4<f64> {
        Vector4::new(-self.phi1, -self.phi2, self.theta1, self.theta2)
    }
    /// From Θ.
    pub fn from_theta(t: &Vector4<f64>) -> Self {
        Arma2 {
            phi1: -t[0],
            phi2: -t[1],
            theta1: t[2],
            theta2: t[3],
        }
    }
    /// DC gain (θ₁ + θ₂)/(1 + φ₁ + φ₂).
    pub fn dc_gain(&self) -> f64 {
        (self.theta1 + self.theta2) / (1.0 + self.phi1 + self.phi2)
    }
}

/// ZOH equivalent of gain / ((1 + τ_s s)(1 + τ_c s)) at sample time `t_s`.
///
/// With p_s = e^{−T/τ_s}, p_c = e^{−T/τ_c}: a₁ = −(p_s + p_c), a₂ = p_s·p_c, and from the
/// partial fractions of H(s)/s,
/// b₁ = 1 − p_s − p_c + (τ_s p_c − τ_c p_s) / (τ_s − τ_c),
/// b₂ = p_s p_c + (τ_c p_s − τ_s p_c) / (τ_s − τ_c); equal time constants are taken as
/// the limit (a double pole).
pub fn zoh_second_order(gain: f64, tau_s: f64, tau_c: f64, t_s: f64) -> Arma2 {
    let (ps, pc) = ((-t_s / tau_s).exp(), (-t_s / tau_c).exp());
    let (b1, b2) = if (tau_s - tau_c).abs() > 1e-9 * tau_s.max(tau_c) {
        let d = tau_s - tau_c;
        (
            1.0 - ps - pc + (tau_s * pc - tau_c * ps) / d,
            ps * pc + (tau_c * ps - tau_s * pc) / d,
        )
    } else {
        // double pole p at τ: b₁ = 1 − p − (T/τ)p, b₂ = p² − p + (T/τ)p
        let (p, r) = (ps, t_s / tau_s);
        (1.0 - p - r * p, p * p - p + r * p)
    };
    Arma2 {
        phi1: -(ps + pc),
        phi2: ps * pc,
        theta1: gain * b1,
        theta2: gain * b2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integrate the two lags finely with a held input; sample every `t_s`.
    fn fine(gain: f64, ts: f64, tc: f64, t_s: f64, u: &[f64]) -> Vec<f64> {
        let steps = 2000;
        let h = t_s / steps as f64;
        let (mut x1, mut x2) = (0.0, 0.0);
        let mut y = vec![0.0];
        for &uk in u {
            for _ in 0..steps {
                // RK2 on x1' = (u − x1)/τ_s, x2' = (gain·x1 − x2)/τ_c
                let d1 = (uk - x1) / ts;
                let d2 = (gain * x1 - x2) / tc;
                let (m1, m2) = (x1 + 0.5 * h * d1, x2 + 0.5 * h * d2);
                x1 += h * (uk - m1) / ts;
                x2 += h * (gain * m1 - m2) / tc;
            }
            y.push(x2);
        }
        y
    }

    #[test]
    fn zoh_model_matches_a_fine_step_simulation() {
        for (ts, tc) in [(0.05, 0.2), (0.1, 0.1), (0.3, 0.04)] {
            let (gain, t_s) = (2.5, 0.1);
            let m = zoh_second_order(gain, ts, tc, t_s);
            let u: Vec<f64> = (0..40)
                .map(|k| if k % 13 < 7 { 1.0 } else { -0.5 })
                .collect();
            let y_fine = fine(gain, ts, tc, t_s, &u);
            let mut y = vec![0.0; u.len() + 1];
            y[1] = m.theta1 * u[0];
            for t in 2..=u.len() {
                y[t] = -m.phi1 * y[t - 1] - m.phi2 * y[t - 2]
                    + m.theta1 * u[t - 1]
                    + m.theta2 * u[t - 2];
            }
            for t in 0..=u.len() {
                assert!(
                    (y[t] - y_fine[t]).abs() < 1e-6,
                    "τs {ts} τc {tc} t {t}: {} vs {}",
                    y[t],
                    y_fine[t]
                );
            }
            assert!((m.dc_gain() - gain).abs() < 1e-9);
        }
    }
}
