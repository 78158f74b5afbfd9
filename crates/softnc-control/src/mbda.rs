//! Model-based disturbance attenuator (paper 000, eq 33–34, Fig. 5).
//!
//! The nominal model `P_n` runs in parallel with the plant, driven by the command
//! `u`; the output difference `y_n − y` goes through a PI controller `M(z⁻¹)` and is
//! added to the plant input: `v = u + M (P_n u − y)`. Then
//! `y = (1 + M P_n)/(1 + M P) · P u + P/(1 + M P) · T_L` (eq 33, 34): a high-gain M
//! makes the plant follow the model and attenuates disturbances, without an
//! inverse model.
//!
//! `M(z⁻¹) = K_p + K_i T / (1 − z⁻¹)` (backward-rectangle integral). The design
//! refuses gains for which `1 + M P_n` has a closed-loop pole on or outside the
//! unit circle.

pub use crate::config::compensation::MbdaConfig;
use crate::discrete_tf::{is_schur_stable, poly_add, poly_mul, DiscreteTf, TfFilter};

/// Why an MBDA cannot be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MbdaDesignError {
    /// Gains must be finite and non-negative, the sample time positive.
    #[error("MBDA gains must be finite and >= 0 and the sample time positive (kp = {kp}, ki = {ki_per_s} 1/s)")]
    Gains {
        /// Requested K_p.
        kp: f64,
        /// Requested K_i.
        ki_per_s: f64,
    },
    /// `1 + M P_n` is unstable with these gains.
    #[error("MBDA loop 1 + M·P_n is unstable with kp = {kp}, ki = {ki_per_s} 1/s")]
    Unstable {
        /// Requested K_p.
        kp: f64,
        /// Requested K_i.
        ki_per_s: f64,
    },
}

/// Denominator of the MBDA loop (1 + M P_n = 0): `(1 − z⁻¹) A + (m_0 + m_1 z⁻¹) B`
/// with `m_0 = K_p + K_i T`, `m_1 = −K_p`; `A + K_p B` when `K_i = 0` (no integrator).
pub fn loop_characteristic(
    config: &MbdaConfig,
    model: &DiscreteTf,
    sample_time_s: f64,
) -> Vec<f64> {
    if config.ki_per_s == 0.0 {
        return poly_add(model.den(), &poly_mul(&[config.kp], model.num()));
    }
    let m = [config.kp + config.ki_per_s * sample_time_s, -config.kp];
    poly_add(
        &poly_mul(&[1.0, -1.0], model.den()),
        &poly_mul(&m, model.num()),
    )
}

/// The attenuator of Fig. 5, ready to step.
#[derive(Debug, Clone)]
pub struct Mbda {
    model: TfFilter,
    kp: f64,
    ki_t: f64,
    integral: f64,
    correction: f64,
}

impl Mbda {
    /// Build the attenuator for model `model` sampled every `sample_time_s`.
    pub fn design(
        config: &MbdaConfig,
        model: &DiscreteTf,
        sample_time_s: f64,
    ) -> Result<Mbda, MbdaDesignError> {
        let ok = |g: f64| g.is_finite() && g >= 0.0;
        if !(ok(config.kp) && ok(config.ki_per_s) && sample_time_s > 0.0) {
            return Err(MbdaDesignError::Gains {
                kp: config.kp,
                ki_per_s: config.ki_per_s,
            });
        }
        if !is_schur_stable(&loop_characteristic(config, model, sample_time_s)) {
            return Err(MbdaDesignError::Unstable {
                kp: config.kp,
                ki_per_s: config.ki_per_s,
            });
        }
        Ok(Mbda {
            model: TfFilter::new(model),
            kp: config.kp,
            ki_t: config.ki_per_s * sample_time_s,
            integral: 0.0,
            correction: 0.0,
        })
    }

    /// One cycle: command `u_cmd`, measured output `y_meas` → plant input
    /// `v = u + M (y_n − y)` (Fig. 5).
    #[inline]
    pub fn step(&mut self, u_cmd: f64, y_meas: f64) -> f64 {
        let y_model = self.model.step(u_cmd);
        let e = y_model - y_meas;
        self.integral += self.ki_t * e;
        self.correction = self.kp * e + self.integral;
        u_cmd + self.correction
    }

    /// The latest correction `M (y_n − y)` added to the command.
    pub fn correction(&self) -> f64 {
        self.correction
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.model.reset();
        self.integral = 0.0;
        self.correction = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete_tf::Complex;
    use std::f64::consts::PI;

    const T: f64 = 0.001;

    fn pnx() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
    }

    fn run(cfg: &MbdaConfig, f_hz: f64, steps: usize) -> f64 {
        let mut m = Mbda::design(cfg, &pnx(), T).unwrap();
        let mut plant = TfFilter::new(&pnx());
        let mut amp = 0.0_f64;
        for k in 0..steps {
            let d = if f_hz == 0.0 {
                1.0
            } else {
                (2.0 * PI * f_hz * T * k as f64).sin()
            };
            let y = plant.pending_output();
            let v = m.step(0.0, y);
            plant.step(v + d);
            if k > steps / 2 {
                amp = amp.max(y.abs());
            }
        }
        amp
    }

    #[test]
    fn attenuates_as_eq_34_predicts() {
        let cfg = MbdaConfig {
            kp: 2.0,
            ki_per_s: 200.0,
        };
        // constant disturbance: integral action removes it
        assert!(run(&cfg, 0.0, 4000) < 1e-6);
        // sine: |G_TL| = |P / (1 + M P)| with P = P_n
        let f = 10.0;
        let p = pnx().response(f, T);
        let one = Complex::new(1.0, 0.0);
        let z1 = Complex::from_polar(1.0, -2.0 * PI * f * T);
        let m = (Complex::new(cfg.kp + cfg.ki_per_s * T, 0.0) - z1.scale(cfg.kp)) / (one - z1);
        let g = p / (one + m * p);
        let amp = run(&cfg, f, 6000);
        assert!(
            (amp - g.norm()).abs() < 0.01 * g.norm(),
            "{amp} vs {}",
            g.norm()
        );
        assert!(
            amp < 0.6
                * run(
                    &MbdaConfig {
                        kp: 0.0,
                        ki_per_s: 0.0
                    },
                    f,
                    6000
                )
        );
    }

    #[test]
    fn nominal_plant_follows_the_model_exactly() {
        let mut m = Mbda::design(
            &MbdaConfig {
                kp: 3.0,
                ki_per_s: 100.0,
            },
            &pnx(),
            T,
        )
        .unwrap();
        let mut plant = TfFilter::new(&pnx());
        for k in 0..500 {
            let u = (k as f64 * 0.01).sin();
            let v = m.step(u, plant.pending_output());
            assert!(m.correction().abs() < 1e-12);
            plant.step(v);
        }
    }

    #[test]
    fn unstable_gains_are_refused() {
        assert!(matches!(
            Mbda::design(
                &MbdaConfig {
                    kp: 500.0,
                    ki_per_s: 0.0
                },
                &pnx(),
                T
            ),
            Err(MbdaDesignError::Unstable { .. })
        ));
        assert!(matches!(
            Mbda::design(
                &MbdaConfig {
                    kp: -1.0,
                    ki_per_s: 0.0
                },
                &pnx(),
                T
            ),
            Err(MbdaDesignError::Gains { .. })
        ));
    }
}
