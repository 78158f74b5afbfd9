//! PMSM feed motor seen through its phase-current sensors (paper 003 eq 24–30): the
//! torque the axis needs, T_m = (F_c + F_f·sgn v + m·a)·lead/2π (eq 29–30), becomes a
//! q-axis current I_q = T_m/K_t (eq 26) through the drive's torque response (first
//! order at the profile's bandwidth), I_d = 0; the phase currents follow from the
//! electrical angle n_p·θ with θ the rotor angle from the axis position (eq 24, 27–28);
//! the sensors of phases u and v add seeded Gaussian noise.

use softnc_machine::force::PmsmConfig;
use softnc_plant::rng::Rng;
use std::f64::consts::TAU;

/// mm → m.
const M_PER_MM: f64 = 1e-3;

/// Phase currents of one sample (A).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseCurrents {
    /// True i_u.
    pub i_u: f64,
    /// True i_v.
    pub i_v: f64,
    /// True i_w = −i_u − i_v (eq 25).
    pub i_w: f64,
    /// Sensor reading of i_u.
    pub meas_u: f64,
    /// Sensor reading of i_v.
    pub meas_v: f64,
}

/// The feed motor of one axis.
#[derive(Debug, Clone, PartialEq)]
pub struct PmsmFeedMotor {
    cfg: PmsmConfig,
    noise: bool,
    rng: Rng,
    iq_a: f64,
    pos_mm: f64,
    vel_mm_per_s: f64,
    started: bool,
}

impl PmsmFeedMotor {
    /// Motor `cfg`; sensor noise from `rng` when `noise`.
    pub fn new(cfg: &PmsmConfig, rng: Rng, noise: bool) -> Self {
        PmsmFeedMotor {
            cfg: cfg.clone(),
            noise,
            rng,
            iq_a: 0.0,
            pos_mm: 0.0,
            vel_mm_per_s: 0.0,
            started: false,
        }
    }

    /// Electrical angle n_p·θ (rad) at axis position `pos_mm` (eq 27–28).
    pub fn electrical_rad(&self, pos_mm: f64) -> f64 {
        self.cfg.pole_pairs as f64 * TAU * pos_mm / self.cfg.lead_mm
    }

    /// The q-axis current for a steady table force `force_n` (N), eq 26 and 30:
    /// the nominal calibration line I_q = a·F + b.
    pub fn nominal_iq_a(&self, force_n: f64) -> f64 {
        force_n * self.cfg.lead_mm * M_PER_MM / (TAU * self.cfg.torque_constant_nm_per_a)
    }

    /// True q-axis current (A).
    pub fn iq_a(&self) -> f64 {
        self.iq_a
    }

    /// Advance `h_s`: the axis is at `pos_mm` at the end of the step, the cutting
    /// force on the table is `cut_force_n`. Returns the phase currents at the end.
    pub fn step(&mut self, cut_force_n: f64, pos_mm: f64, h_s: f64) -> PhaseCurrents {
        if !self.started {
            self.pos_mm = pos_mm;
            self.started = true;
        }
        let v = (pos_mm - self.pos_mm) / h_s;
        let a = (v - self.vel_mm_per_s) / h_s;
        self.pos_mm = pos_mm;
        self.vel_mm_per_s = v;
        let friction = if v > 0.0 {
            self.cfg.friction_n
        } else if v < 0.0 {
            -self.cfg.friction_n
        } else {
            0.0
        };
        let table_n = cut_force_n + friction + self.cfg.moving_mass_kg * a * M_PER_MM;
        let iq_cmd = self.nominal_iq_a(table_n);
        let alpha = 1.0 - (-TAU * self.cfg.torque_bandwidth_hz * h_s).exp();
        self.iq_a += alpha * (iq_cmd - self.iq_a);
        let th = self.electrical_rad(pos_mm);
        let i_u = -self.iq_a * th.sin();
        let i_v = -self.iq_a * (th - TAU / 3.0).sin();
        let (nu, nv) = if self.noise {
            (
                self.cfg.current_noise_a * self.rng.normal(),
                self.cfg.current_noise_a * self.rng.normal(),
            )
        } else {
            (0.0, 0.0)
        };
        PhaseCurrents {
            i_u,
            i_v,
            i_w: -i_u - i_v,
            meas_u: i_u + nu,
            meas_v: i_v + nv,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> PmsmConfig {
        PmsmConfig {
            lead_mm: 10.0,
            pole_pairs: 4,
            torque_constant_nm_per_a: 0.44,
            friction_n: 1000.0,
            moving_mass_kg: 500.0,
            torque_bandwidth_hz: 60.0,
            current_noise_a: 0.0,
        }
    }

    #[test]
    fn steady_currents_are_balanced_and_carry_the_load() {
        let mut m = PmsmFeedMotor::new(&cfg(), Rng::new(1), false);
        let h = 1e-3;
        let mut c = PhaseCurrents::default();
        for k in 0..2000 {
            c = m.step(450.0, 5.0 * h * k as f64, h);
        }
        assert!((c.i_u + c.i_v + c.i_w).abs() < 1e-12);
        let want = m.nominal_iq_a(1450.0);
        assert!((m.iq_a() - want).abs() < 1e-9, "{} vs {want}", m.iq_a());
        // amplitude of the phase currents is I_q
        let amp = ((c.i_u * c.i_u + c.i_v * c.i_v + c.i_w * c.i_w) * 2.0 / 3.0).sqrt();
        assert!((amp - want).abs() < 1e-9);
    }

    #[test]
    fn torque_response_has_the_configured_bandwidth() {
        let mut m = PmsmFeedMotor::new(&cfg(), Rng::new(1), false);
        let h = 1e-5;
        let tau = 1.0 / (TAU * 60.0);
        let n = (tau / h).round() as usize;
        m.step(0.0, 0.0, h);
        for _ in 0..n {
            m.step(1000.0, 0.0, h);
        }
        let want = m.nominal_iq_a(1000.0) * (1.0 - (-1.0f64).exp());
        assert!((m.iq_a() - want).abs() < 1e-3 * want);
    }
}
