//! Discrete transfer functions in z⁻¹: evaluation on the unit circle, polynomial
//! helpers, a Schur–Cohn stability test, and a filter with state allocated once.
//!
//! A transfer function is `B(z⁻¹) / A(z⁻¹)` with `B = b_0 + b_1 z⁻¹ + …` and
//! `A = 1 + a_1 z⁻¹ + …` (normalised so `a_0 = 1`). Design code builds them with
//! `Vec`s; [`TfFilter`] copies the coefficients once and then steps without
//! allocating (direct form II transposed).

use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// A complex frequency response value: nalgebra's re-export of `num-complex`.
pub type Complex = nalgebra::Complex<f64>;

/// Why a transfer function cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TfError {
    /// The denominator is empty or its leading coefficient a_0 is zero.
    #[error("denominator must have a non-zero leading coefficient a0")]
    Denominator,
    /// The numerator is empty.
    #[error("numerator must have at least one coefficient")]
    Numerator,
    /// A coefficient is NaN or infinite.
    #[error("transfer-function coefficients must be finite")]
    NotFinite,
}

/// `B(z⁻¹) / A(z⁻¹)` with `a_0 = 1`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DiscreteTf {
    num: Vec<f64>,
    den: Vec<f64>,
}

impl DiscreteTf {
    /// From numerator `b_0, b_1, …` and denominator `a_0, a_1, …` coefficients of
    /// z⁻⁰, z⁻¹, …; divides both by `a_0`.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self, TfError> {
        if num.is_empty() {
            return Err(TfError::Numerator);
        }
        let a0 = *den.first().ok_or(TfError::Denominator)?;
        if a0 == 0.0 {
            return Err(TfError::Denominator);
        }
        if num.iter().chain(den.iter()).any(|c| !c.is_finite()) {
            return Err(TfError::NotFinite);
        }
        Ok(DiscreteTf {
            num: num.iter().map(|b| b / a0).collect(),
            den: den.iter().map(|a| a / a0).collect(),
        })
    }

    /// An FIR filter with the given taps (denominator 1).
    pub fn fir(taps: Vec<f64>) -> Result<Self, TfError> {
        DiscreteTf::new(taps, vec![1.0])
    }

    /// Numerator coefficients b_0, b_1, … (of z⁻⁰, z⁻¹, …).
    pub fn num(&self) -> &[f64] {
        &self.num
    }

    /// Denominator coefficients 1, a_1, … (of z⁻⁰, z⁻¹, …).
    pub fn den(&self) -> &[f64] {
        &self.den
    }

    /// Value at z = e^{jωT}, ω = 2π·`freq_hz`, T = `sample_time_s`.
    pub fn response(&self, freq_hz: f64, sample_time_s: f64) -> Complex {
        let w_t = 2.0 * PI * freq_hz * sample_time_s;
        poly_at_unit_circle(&self.num, w_t) / poly_at_unit_circle(&self.den, w_t)
    }

    /// Gain at z = 1 (B(1) / A(1)).
    pub fn dc_gain(&self) -> f64 {
        self.num.iter().sum::<f64>() / self.den.iter().sum::<f64>()
    }

    /// Series connection `self · other`.
    pub fn series(&self, other: &DiscreteTf) -> DiscreteTf {
        DiscreteTf {
            num: poly_mul(&self.num, &other.num),
            den: poly_mul(&self.den, &other.den),
        }
    }

    /// `k · self`.
    pub fn scaled(&self, k: f64) -> DiscreteTf {
        DiscreteTf {
            num: self.num.iter().map(|b| k * b).collect(),
            den: self.den.clone(),
        }
    }

    /// `z^{−n} · self`.
    pub fn delayed(&self, n: usize) -> DiscreteTf {
        let mut num = vec![0.0; n];
        num.extend_from_slice(&self.num);
        DiscreteTf {
            num,
            den: self.den.clone(),
        }
    }

    /// Number of leading zero numerator coefficients (pure delay in samples).
    pub fn input_delay_samples(&self) -> usize {
        self.num.iter().take_while(|b| **b == 0.0).count()
    }

    /// All poles strictly inside the unit circle (Schur–Cohn on A).
    pub fn is_stable(&self) -> bool {
        is_schur_stable(&self.den)
    }
}

/// Σ c_i e^{−j i ωT}.
pub fn poly_at_unit_circle(c: &[f64], w_t: f64) -> Complex {
    c.iter()
        .enumerate()
        .fold(Complex::new(0.0, 0.0), |acc, (i, ci)| {
            acc + Complex::from_polar(*ci, -w_t * i as f64)
        })
}

/// Product of two polynomials in z⁻¹ (convolution of coefficients).
pub fn poly_mul(p: &[f64], q: &[f64]) -> Vec<f64> {
    if p.is_empty() || q.is_empty() {
        return Vec::new();
    }
    let mut out = vec![0.0; p.len() + q.len() - 1];
    for (i, pi) in p.iter().enumerate() {
        for (j, qj) in q.iter().enumerate() {
            out[i + j] += pi * qj;
        }
    }
    out
}

/// Sum of two polynomials in z⁻¹.
pub fn poly_add(p: &[f64], q: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; p.len().max(q.len())];
    for (i, pi) in p.iter().enumerate() {
        out[i] += pi;
    }
    for (i, qi) in q.iter().enumerate() {
        out[i] += qi;
    }
    out
}

/// True when every root of `c_0 + c_1 z⁻¹ + … + c_n z⁻ⁿ` (i.e. of
/// `c_0 zⁿ + … + c_n`) lies strictly inside the unit circle. Schur–Cohn step-down:
/// reflection coefficient k = c_n / c_0 must satisfy |k| < 1 at every step.
pub fn is_schur_stable(c: &[f64]) -> bool {
    let mut p: Vec<f64> = c.to_vec();
    while p.len() > 1 && p[p.len() - 1] == 0.0 {
        p.pop();
    }
    if p.is_empty() || p[0] == 0.0 {
        return false;
    }
    while p.len() > 1 {
        let n = p.len() - 1;
        let k = p[n] / p[0];
        if !k.is_finite() || k.abs() >= 1.0 {
            return false;
        }
        let d = 1.0 - k * k;
        let next: Vec<f64> = (0..n).map(|i| (p[i] - k * p[n - i]) / d).collect();
        p = next;
    }
    true
}

/// Filter state for a [`DiscreteTf`]: direct form II transposed, coefficients and
/// state sized once at construction; [`TfFilter::step`] does not allocate.
#[derive(Debug, Clone, PartialEq)]
pub struct TfFilter {
    b: Vec<f64>,
    a: Vec<f64>,
    state: Vec<f64>,
}

impl TfFilter {
    /// A filter at rest realising `tf`.
    pub fn new(tf: &DiscreteTf) -> Self {
        let n = tf.num.len().max(tf.den.len());
        let mut b = tf.num.clone();
        b.resize(n, 0.0);
        let mut a = tf.den.clone();
        a.resize(n, 0.0);
        TfFilter {
            b,
            a,
            state: vec![0.0; n.saturating_sub(1)],
        }
    }

    /// One sample: input x(k) → output y(k).
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let n = self.state.len();
        if n == 0 {
            return self.b[0] * x;
        }
        let y = self.b[0] * x + self.state[0];
        for i in 0..n - 1 {
            self.state[i] = self.b[i + 1] * x - self.a[i + 1] * y + self.state[i + 1];
        }
        self.state[n - 1] = self.b[n] * x - self.a[n] * y;
        y
    }

    /// The part of the next output that does not depend on the next input; for a
    /// strictly proper filter (b_0 = 0) it *is* the next output. Simulated plants
    /// use it to present y(k), which depends on inputs up to k−1, before the
    /// controller computes the input of cycle k.
    #[inline]
    pub fn pending_output(&self) -> f64 {
        self.state.first().copied().unwrap_or(0.0)
    }

    /// Back to rest (all state zero).
    pub fn reset(&mut self) {
        self.state.iter_mut().for_each(|s| *s = 0.0);
    }
}

/// Why FIR taps cannot be swapped in.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FirSwapError {
    /// The new tap vector has a different length from the running one.
    #[error("new FIR has {new} taps, the running one {running}")]
    Length {
        /// Taps in the new filter.
        new: usize,
        /// Taps in the running filter.
        running: usize,
    },
}

/// FIR filter `Σ h_i x(k−i)` with an explicit input history, so its taps can be
/// replaced between two samples without losing the history (a redesigned filter
/// continues on the same past inputs). Sized once; stepping does not allocate.
#[derive(Debug, Clone, PartialEq)]
pub struct FirFilter {
    taps: Vec<f64>,
    history: Vec<f64>,
}

impl FirFilter {
    /// A filter at rest with taps h_0, h_1, ….
    pub fn new(taps: Vec<f64>) -> Self {
        let n = taps.len();
        FirFilter {
            taps,
            history: vec![0.0; n],
        }
    }

    /// The taps in use.
    pub fn taps(&self) -> &[f64] {
        &self.taps
    }

    /// One sample: x(k) → y(k).
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let n = self.history.len();
        if n == 0 {
            return 0.0;
        }
        self.history.copy_within(0..n - 1, 1);
        self.history[0] = x;
        self.taps
            .iter()
            .zip(self.history.iter())
            .map(|(h, x)| h * x)
            .sum()
    }

    /// Exchange the taps with `taps` (same length) without allocating: the old
    /// taps come back in `taps`, to be dropped off the real-time path.
    pub fn swap_taps(&mut self, taps: &mut Vec<f64>) -> Result<(), FirSwapError> {
        if taps.len() != self.taps.len() {
            return Err(FirSwapError::Length {
                new: taps.len(),
                running: self.taps.len(),
            });
        }
        std::mem::swap(&mut self.taps, taps);
        Ok(())
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.history.iter_mut().for_each(|x| *x = 0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pnx() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
    }

    #[test]
    fn response_matches_filtered_sine_in_steady_state() {
        let tf = pnx();
        let t = 0.001;
        let f = 50.0;
        let h = tf.response(f, t);
        let mut filt = TfFilter::new(&tf);
        let (mut max_err, n) = (0.0_f64, 4000);
        for k in 0..n {
            let w = 2.0 * PI * f * t * k as f64;
            let y = filt.step(w.sin());
            if k > 3000 {
                let expect = h.norm() * (w + h.arg()).sin();
                max_err = max_err.max((y - expect).abs());
            }
        }
        assert!(max_err < 1e-6, "steady-state mismatch {max_err}");
    }

    #[test]
    fn dc_gain_and_normalisation() {
        assert!((pnx().dc_gain() - 1.0).abs() < 1e-9);
        let tf = DiscreteTf::new(vec![2.0], vec![2.0, -1.0]).unwrap();
        assert_eq!(tf.den(), &[1.0, -0.5]);
        assert!((tf.dc_gain() - 2.0).abs() < 1e-12);
        assert_eq!(
            DiscreteTf::new(vec![1.0], vec![0.0, 1.0]),
            Err(TfError::Denominator)
        );
    }

    #[test]
    fn schur_cohn_agrees_with_known_roots() {
        // (1 − 0.5z⁻¹)(1 + 0.9z⁻¹): stable; (1 − 1.1z⁻¹): not; (1 − z⁻¹): not (on circle)
        assert!(is_schur_stable(&poly_mul(&[1.0, -0.5], &[1.0, 0.9])));
        assert!(!is_schur_stable(&poly_mul(&[1.0, -0.5], &[1.0, -1.1])));
        assert!(!is_schur_stable(&[1.0, -1.0]));
        assert!(pnx().is_stable());
        // complex pair at radius 1.02
        let r: f64 = 1.02;
        assert!(!is_schur_stable(&[1.0, -2.0 * r * 0.3_f64.cos(), r * r]));
    }

    #[test]
    fn fir_filter_impulse_response_is_its_taps() {
        let taps = vec![0.5, -1.0, 2.0, 0.25];
        let mut f = TfFilter::new(&DiscreteTf::fir(taps.clone()).unwrap());
        let out: Vec<f64> = (0..6)
            .map(|k| f.step(if k == 0 { 1.0 } else { 0.0 }))
            .collect();
        assert_eq!(&out[..4], &taps[..]);
        assert_eq!(&out[4..], &[0.0, 0.0]);
    }

    #[test]
    fn fir_with_history_matches_tf_filter_and_swaps_taps() {
        let taps = vec![0.3, -0.2, 0.7, 0.1];
        let mut a = FirFilter::new(taps.clone());
        let mut b = TfFilter::new(&DiscreteTf::fir(taps).unwrap());
        for k in 0..20 {
            let x = (k as f64 * 0.7).sin();
            assert!((a.step(x) - b.step(x)).abs() < 1e-12);
        }
        let mut new = vec![1.0, 0.0, 0.0, 0.0];
        a.swap_taps(&mut new).unwrap();
        assert_eq!(new, vec![0.3, -0.2, 0.7, 0.1]);
        assert_eq!(a.step(5.0), 5.0);
        assert!(a.swap_taps(&mut vec![1.0]).is_err());
    }

    #[test]
    fn series_and_delay() {
        let tf = pnx()
            .delayed(2)
            .series(&DiscreteTf::fir(vec![1.0, 1.0]).unwrap());
        assert_eq!(tf.input_delay_samples(), 3);
        let f = 30.0;
        let expect = pnx().response(f, 0.001)
            * Complex::from_polar(1.0, -2.0 * 2.0 * PI * f * 0.001)
            * (Complex::new(1.0, 0.0) + Complex::from_polar(1.0, -2.0 * PI * f * 0.001));
        assert!((tf.response(f, 0.001) - expect).norm() < 1e-12);
    }
}
