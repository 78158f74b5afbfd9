//! Encoder: measurement noise (Gaussian, seeded) then quantisation to counts.

use crate::rng::Rng;

/// One axis's encoder.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoder {
    mm_per_count: f64,
    noise_std_mm: f64,
    rng: Rng,
}

impl Encoder {
    /// Resolution `mm_per_count`, noise σ `noise_std_mm` (0 = none), its own random stream.
    pub fn new(mm_per_count: f64, noise_std_mm: f64, rng: Rng) -> Self {
        Encoder {
            mm_per_count,
            noise_std_mm,
            rng,
        }
    }
    /// Counts read for true position `pos_mm`. With `quantise` off the count is the
    /// nearest integer anyway, so the switch only makes sense together with a fine
    /// resolution; [`Encoder::read_mm`] gives the unquantised reading.
    #[inline]
    pub fn read_counts(&mut self, pos_mm: f64, noisy: bool) -> i64 {
        (self.read_mm(pos_mm, noisy) / self.mm_per_count).round() as i64
    }
    /// The noisy, unquantised reading (mm).
    #[inline]
    pub fn read_mm(&mut self, pos_mm: f64, noisy: bool) -> f64 {
        if noisy && self.noise_std_mm > 0.0 {
            pos_mm + self.noise_std_mm * self.rng.normal()
        } else {
            pos_mm
        }
    }
    /// mm per count.
    pub fn mm_per_count(&self) -> f64 {
        self.mm_per_count
    }
}
