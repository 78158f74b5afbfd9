//! Identified discrete velocity loop P_n(z⁻¹) = (b₁z⁻¹ + b₂z⁻²)/(1 + a₁z⁻¹ + a₂z⁻²) (paper 000 eq 35, 36),
//! with the position integrated from motor speed and Coulomb friction (stick–slip) at its input.

use crate::stick_slip::{karnopp, Breakaway, Contact};

/// One axis of paper 000's TNV-40: velocity command u (rad/s) → motor speed y (rad/s)
/// → table position (mm) through a screw of `lead_mm` per revolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityLoop {
    b: [f64; 2],
    a: [f64; 2],
    mm_per_rad: f64,
    coulomb_rad_per_s: f64,
    sample_s: f64,
    y: [f64; 2],
    w1: f64,
    pos_mm: f64,
}

impl VelocityLoop {
    /// Numerator [b₁, b₂], denominator [a₁, a₂], identified at `sample_s`; screw lead;
    /// Coulomb friction as an equivalent velocity-command offset (rad/s).
    pub fn new(
        num: [f64; 2],
        den: [f64; 2],
        sample_s: f64,
        lead_mm: f64,
        coulomb_rad_per_s: f64,
    ) -> Self {
        VelocityLoop {
            b: num,
            a: den,
            mm_per_rad: lead_mm / std::f64::consts::TAU,
            coulomb_rad_per_s,
            sample_s,
            y: [0.0; 2],
            w1: 0.0,
            pos_mm: 0.0,
        }
    }
    /// DC gain P_n(1) = (b₁ + b₂)/(1 + a₁ + a₂).
    pub fn dc_gain(&self) -> f64 {
        (self.b[0] + self.b[1]) / (1.0 + self.a[0] + self.a[1])
    }
    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        self.y = [0.0; 2];
        self.w1 = 0.0;
        self.pos_mm = pos_mm;
    }
    /// Table position (mm).
    pub fn pos_mm(&self) -> f64 {
        self.pos_mm
    }
    /// Motor speed y (rad/s).
    pub fn speed_rad_per_s(&self) -> f64 {
        self.y[0]
    }
    /// The identification sample time (s): one call of [`VelocityLoop::step`].
    pub fn sample_s(&self) -> f64 {
        self.sample_s
    }
    /// One sample with `drive` = velocity command + disturbance at the plant input (rad/s).
    /// Returns the effective plant input after friction (rad/s).
    #[inline]
    pub fn step(&mut self, drive: f64) -> f64 {
        let y0 = self.y[0];
        let fc = self.coulomb_rad_per_s;
        let contact = karnopp(y0, drive, Breakaway { pos: fc, neg: fc }, fc.copysign(y0));
        let w = match contact {
            Contact::Stuck => {
                // held: the loop's memory is at rest, the table does not move
                self.y = [0.0; 2];
                self.w1 = 0.0;
                return 0.0;
            }
            Contact::Slip { net } => net,
        };
        let mut y_new =
            -self.a[0] * self.y[0] - self.a[1] * self.y[1] + self.b[0] * w + self.b[1] * self.w1;
        // velocity reversal: Karnopp decides at zero speed whether the axis sticks there
        if y0 != 0.0 && y_new * y0 < 0.0 && drive.abs() <= fc {
            y_new = 0.0;
        }
        self.pos_mm += 0.5 * (y0 + y_new) * self.sample_s * self.mm_per_rad;
        self.y = [y_new, y0];
        self.w1 = w;
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// P_nx of paper 000 eq 35.
    fn pnx() -> VelocityLoop {
        VelocityLoop::new([0.1894, -0.1866], [-1.8106, 0.8134], 0.001, 10.0, 0.0)
    }

    #[test]
    fn difference_equation_by_hand() {
        let mut p = pnx();
        p.step(1.0);
        assert_eq!(p.speed_rad_per_s(), 0.1894, "y(1) = b1");
        p.step(1.0);
        let y2 = 1.8106 * 0.1894 + 0.1894 - 0.1866;
        assert!((p.speed_rad_per_s() - y2).abs() < 1e-15);
    }
}
