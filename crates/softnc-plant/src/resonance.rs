//! A lightly damped structural mode between the motor and the table.
//!
//! The loop reads the motor's encoder (a semi-closed loop, as on most machine tools),
//! so the mode does not act back on the servo; the table follows the motor through
//! ẍ_t = ω²(x_m − x_t) + 2ζω(ẋ_m − ẋ_t). In the deflection d = x_t − x_m this is
//! d̈ + 2ζω ḋ + ω² d = −ẍ_m. The motor moves at constant velocity within a cycle, so
//! ẍ_m is an impulse at each cycle boundary (the velocity step, which ḋ takes in full)
//! and the deflection decays freely in between: the cycle is solved exactly by the
//! free response's state-transition matrix, computed once.

use crate::config::StructuralMode;

/// The mode's state and its exact one-cycle transition.
#[derive(Debug, Clone, PartialEq)]
pub struct Resonance {
    /// exp(A·T) for the state [d, ḋ], A = [[0, 1], [−ω², −2ζω]].
    phi: [[f64; 2]; 2],
    cycle_s: f64,
    /// Deflection table − motor (mm) and its rate (mm/s).
    defl_mm: f64,
    defl_rate_mm_s: f64,
    /// Motor velocity during the last cycle (mm/s).
    motor_vel_mm_s: f64,
    /// Motor position at the end of the last cycle (mm).
    motor_mm: f64,
}

impl Resonance {
    /// The mode `mode` stepped at cycle `cycle_s`, at rest at 0.
    pub fn new(mode: &StructuralMode, cycle_s: f64) -> Self {
        let w = 2.0 * std::f64::consts::PI * mode.frequency_hz;
        let z = mode.damping_ratio;
        let sigma = z * w;
        let wd = w * (1.0 - z * z).sqrt();
        let (s, c) = (wd * cycle_s).sin_cos();
        let e = (-sigma * cycle_s).exp();
        let phi = [
            [e * (c + sigma / wd * s), e * s / wd],
            [-e * w * w / wd * s, e * (c - sigma / wd * s)],
        ];
        Resonance {
            phi,
            cycle_s,
            defl_mm: 0.0,
            defl_rate_mm_s: 0.0,
            motor_vel_mm_s: 0.0,
            motor_mm: 0.0,
        }
    }

    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        self.defl_mm = 0.0;
        self.defl_rate_mm_s = 0.0;
        self.motor_vel_mm_s = 0.0;
        self.motor_mm = pos_mm;
    }

    /// One cycle in which the motor moved to `motor_mm`.
    pub fn cycle(&mut self, motor_mm: f64) {
        let v = (motor_mm - self.motor_mm) / self.cycle_s;
        // the motor's velocity step at the cycle boundary: the table keeps its velocity
        self.defl_rate_mm_s -= v - self.motor_vel_mm_s;
        let (d, r) = (self.defl_mm, self.defl_rate_mm_s);
        self.defl_mm = self.phi[0][0] * d + self.phi[0][1] * r;
        self.defl_rate_mm_s = self.phi[1][0] * d + self.phi[1][1] * r;
        self.motor_vel_mm_s = v;
        self.motor_mm = motor_mm;
    }

    /// Table position (mm).
    pub fn table_mm(&self) -> f64 {
        self.motor_mm + self.defl_mm
    }

    /// Deflection table − motor (mm).
    pub fn deflection_mm(&self) -> f64 {
        self.defl_mm
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(f: f64, z: f64) -> StructuralMode {
        StructuralMode {
            frequency_hz: f,
            damping_ratio: z,
        }
    }

    /// Reference: the mode integrated with RK4 at 1 µs against the same motor motion.
    fn rk4(m: &StructuralMode, motor: impl Fn(f64) -> (f64, f64), t_end: f64) -> f64 {
        let w = 2.0 * std::f64::consts::PI * m.frequency_hz;
        let z = m.damping_ratio;
        let h = 1e-6;
        let (mut x, mut v) = (motor(0.0).0, 0.0);
        let f = |t: f64, x: f64, v: f64| {
            let (xm, vm) = motor(t);
            w * w * (xm - x) + 2.0 * z * w * (vm - v)
        };
        let steps = (t_end / h).round() as usize;
        for k in 0..steps {
            let t = k as f64 * h;
            let k1 = (v, f(t, x, v));
            let k2 = (
                v + 0.5 * h * k1.1,
                f(t + 0.5 * h, x + 0.5 * h * k1.0, v + 0.5 * h * k1.1),
            );
            let k3 = (
                v + 0.5 * h * k2.1,
                f(t + 0.5 * h, x + 0.5 * h * k2.0, v + 0.5 * h * k2.1),
            );
            let k4 = (v + h * k3.1, f(t + h, x + h * k3.0, v + h * k3.1));
            x += h / 6.0 * (k1.0 + 2.0 * k2.0 + 2.0 * k3.0 + k4.0);
            v += h / 6.0 * (k1.1 + 2.0 * k2.1 + 2.0 * k3.1 + k4.1);
        }
        x
    }

    #[test]
    fn exact_cycle_matches_fine_integration_of_a_move() {
        let m = mode(40.0, 0.03);
        let t = 0.001;
        // the motor accelerates at 2000 mm/s² for 50 ms, then holds its speed: the
        // sampled motion is piecewise linear between cycles, as the backend sees it
        let xm = |time: f64| {
            let ta = 0.05;
            if time < ta {
                1000.0 * time * time
            } else {
                1000.0 * ta * ta + 100.0 * (time - ta)
            }
        };
        let mut r = Resonance::new(&m, t);
        r.reset(0.0);
        let cycles = 120;
        for k in 1..=cycles {
            r.cycle(xm(k as f64 * t));
        }
        let lin = |time: f64| {
            let k = (time / t).floor();
            let (a, b) = (xm(k * t), xm((k + 1.0) * t));
            (a + (b - a) * (time / t - k), (b - a) / t)
        };
        let reference = rk4(&m, lin, cycles as f64 * t);
        assert!(
            (r.table_mm() - reference).abs() < 1e-7,
            "{} vs {reference}",
            r.table_mm()
        );
        // the acceleration step rang the mode: the deflection is far from static
        assert!(r.deflection_mm().abs() > 1e-3, "{}", r.deflection_mm());
    }

    #[test]
    fn at_constant_speed_the_ringing_decays_and_at_rest_nothing_moves() {
        let m = mode(30.0, 0.05);
        let mut r = Resonance::new(&m, 0.001);
        r.reset(5.0);
        for _ in 0..100 {
            r.cycle(5.0);
        }
        assert_eq!(r.table_mm(), 5.0);
        // a velocity step excites the mode; its envelope decays as exp(−ζωt)
        let mut x = 5.0;
        let mut peak_early: f64 = 0.0;
        let mut peak_late: f64 = 0.0;
        for k in 0..2000 {
            x += 0.05;
            r.cycle(x);
            let d = r.deflection_mm().abs();
            if k < 100 {
                peak_early = peak_early.max(d);
            } else if k >= 1000 {
                peak_late = peak_late.max(d);
            }
        }
        let w = 2.0 * std::f64::consts::PI * 30.0;
        // a velocity step of v rings with amplitude ≈ v/ω_d
        let v = 50.0;
        assert!((peak_early / (v / w) - 1.0).abs() < 0.1, "{peak_early}");
        // and at constant speed the deflection dies out: no static deflection
        let decay = (-0.05 * w * 0.9).exp();
        assert!(
            peak_late < 1.5 * decay * peak_early,
            "{peak_late} {peak_early}"
        );
    }
}
