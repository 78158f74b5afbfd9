//! Periodic cutting disturbance T = A sin(2π f_d t + θ_d), f_d = w_s l / 60 (paper 000 eq 2–3).

use crate::config::CuttingDisturbance;

/// The disturbance of one profile, evaluated at a time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cutting {
    omega_rad_per_s: f64,
    flutes: f64,
    amplitude: [f64; 3],
    phase_rad: f64,
}

impl Cutting {
    /// From the profile's settings.
    pub fn new(cfg: &CuttingDisturbance) -> Self {
        Cutting {
            omega_rad_per_s: std::f64::consts::TAU * cfg.frequency_hz(),
            flutes: f64::from(cfg.flutes),
            amplitude: cfg.amplitude,
            phase_rad: cfg.phase_rad,
        }
    }
    /// Disturbance at the plant input of `axis` at time `t_s` (eq 3, periodic part).
    #[inline]
    pub fn at(&self, axis: usize, t_s: f64) -> f64 {
        self.amplitude[axis] * (self.omega_rad_per_s * t_s + self.phase_rad).sin()
    }
    /// From time `t_s` on the spindle turns at `rpm`: f_d = rpm · flutes / 60 (eq 2).
    /// The tooth phase runs on without a jump.
    pub fn set_spindle_rpm(&mut self, rpm: f64, t_s: f64) {
        let omega = std::f64::consts::TAU * rpm * self.flutes / 60.0;
        if omega != self.omega_rad_per_s {
            self.phase_rad += (self.omega_rad_per_s - omega) * t_s;
            self.omega_rad_per_s = omega;
        }
    }
    /// Tooth frequency f_d (Hz, eq 2).
    pub fn frequency_hz(&self) -> f64 {
        self.omega_rad_per_s / std::f64::consts::TAU
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_000_tooth_frequency_and_phase() {
        // 1500 rpm, 2 flutes: f_d = 50 Hz (000 eq 2 and Sec. IV)
        let c = Cutting::new(&CuttingDisturbance {
            spindle_rpm: 1500.0,
            flutes: 2,
            amplitude: [2.0, 1.0, 0.0],
            phase_rad: std::f64::consts::FRAC_PI_2,
        });
        assert!((c.frequency_hz() - 50.0).abs() < 1e-12);
        assert!((c.at(0, 0.0) - 2.0).abs() < 1e-12);
        assert!((c.at(0, 0.01) + 2.0).abs() < 1e-12, "half a period later");
        assert_eq!(c.at(2, 0.003), 0.0);
        let mut c = c;
        let before = c.at(0, 0.0123);
        c.set_spindle_rpm(1800.0, 0.0123);
        assert!((c.frequency_hz() - 60.0).abs() < 1e-12);
        assert!(
            (c.at(0, 0.0123) - before).abs() < 1e-12,
            "the tooth phase runs on without a jump"
        );
    }
}
