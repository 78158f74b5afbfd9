//! Iterative learning of the command radius of a circle (paper 004, eq 8–9).
//!
//! The circle is cut into one-degree arc commands. After each run the radius actually
//! made is measured per degree, y^k(i), and the command radius corrected:
//!
//!   r^{k+1}(i) = r^k(i) + α (r^d − y^k(i))                                (004 eq 8)
//!
//! and the arc from point i−1 to point i is commanded with the mean of its two end
//! radii, ½ (r^{k+1}(i) + r^{k+1}(i−1))                                    (004 eq 9).

/// Per-degree command radii of one circle.
#[derive(Debug, Clone, PartialEq)]
pub struct RadiusIlc {
    /// Desired radius r^d (mm).
    pub desired_mm: f64,
    /// Learning rate α.
    pub alpha: f64,
    /// Command radius at each degree point, r^k(i), i = 0..360 (mm).
    pub radius_mm: Vec<f64>,
}

/// Points (degrees) a circle is cut into.
pub const POINTS: usize = 360;

impl RadiusIlc {
    /// Start with the desired radius everywhere.
    pub fn new(desired_mm: f64, alpha: f64) -> Self {
        RadiusIlc {
            desired_mm,
            alpha,
            radius_mm: vec![desired_mm; POINTS],
        }
    }

    /// Eq 8 with the measured radius per degree.
    pub fn update(&mut self, measured_mm: &[f64]) {
        for (r, y) in self.radius_mm.iter_mut().zip(measured_mm) {
            *r += self.alpha * (self.desired_mm - y);
        }
    }

    /// Eq 9: the radius to command for the arc ending at degree point `i`.
    pub fn arc_radius_mm(&self, i: usize) -> f64 {
        let prev = (i + POINTS - 1) % POINTS;
        0.5 * (self.radius_mm[i % POINTS] + self.radius_mm[prev])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_shrink_is_learnt_away_in_one_step_with_alpha_one() {
        let mut ilc = RadiusIlc::new(50.0, 1.0);
        // a servo that makes every radius 31 µm too small
        let measured: Vec<f64> = ilc.radius_mm.iter().map(|r| r - 0.031).collect();
        ilc.update(&measured);
        let next: Vec<f64> = ilc.radius_mm.iter().map(|r| r - 0.031).collect();
        assert!(next.iter().all(|y| (y - 50.0).abs() < 1e-12));
        assert!((ilc.arc_radius_mm(0) - 50.031).abs() < 1e-12);
    }
}
