//! Disturbance observer with the Umeno–Hori Q filter (paper 000, eq 32, Fig. 3).
//!
//! The observer estimates the disturbance at the plant input as
//! `d̂ = Q·P_n⁻¹·y − Q·v` (v: the plant input the observer itself produced) and
//! subtracts it: `v = u − d̂`. With `P = P_n` the estimate is `Q·d`.
//!
//! **Q filter** (eq 32): `Q(s) = (1 + Σ_{k=1}^{K−r} a_k (τs)^k) / (1 + Σ_{k=1}^{K} b_k (τs)^k)`
//! with binomial coefficients `a_k = b_k = C(K, k)` (the extracted paper prints
//! `K!/(K−k)!`, which has lost the `k!` of the binomial), so the denominator is
//! `(1 + τs)^K`, the DC gain is 1 and `1 − Q` vanishes like `s^{K−r+1}`.
//!
//! **Discretisation** (documented choice): zero-order-hold (step-invariant)
//! transform, the same "Z-transform" the paper uses for its plant models (eq 35,
//! 36 have the ZOH form `b_1 z⁻¹ + b_2 z⁻²`). It is computed exactly: in
//! `w = 1 + τs`, `Q = Σ_m c_m w^{−m}`, each `w^{−m}` has the closed-form step
//! response `1 − e^{−t/τ} Σ_{i<m} (t/τ)^i / i!`; the sampled step response gives
//! the impulse response, and its convolution with the exact denominator
//! `(1 − e^{−T/τ} z⁻¹)^K` gives the numerator. ZOH keeps the DC gain 1 and, for
//! r ≥ 1, makes `Q(z⁻¹)` start with `z⁻¹`, which is what makes `Q·P_n⁻¹` causal for
//! a plant with one sample of input delay. A plant model with d > 1 samples of
//! delay gets `z^{−(d−1)}` folded into Q.

pub use crate::config::compensation::DobConfig;
use crate::discrete_tf::{is_schur_stable, poly_mul, DiscreteTf, TfFilter};

/// Why a DOB cannot be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DobDesignError {
    /// K must be at least 1 and r must lie in 1..=K.
    #[error("Q filter needs order K >= 1 and relative degree 1 <= r <= K (K = {order_k}, r = {relative_degree_r})")]
    Order {
        /// Requested K.
        order_k: usize,
        /// Requested r.
        relative_degree_r: usize,
    },
    /// τ and the sample time must be positive and finite.
    #[error("Q time constant {tau_s} s and sample time {sample_time_s} s must be positive")]
    Time {
        /// Requested τ.
        tau_s: f64,
        /// Sample time.
        sample_time_s: f64,
    },
    /// The model's numerator is zero.
    #[error("plant model has a zero numerator")]
    ZeroModel,
    /// The model has a zero on or outside the unit circle: P_n⁻¹ would be unstable.
    #[error("plant model is not minimum phase; its inverse in the DOB would be unstable")]
    NonMinimumPhase,
    /// The model is unstable.
    #[error("plant model is unstable")]
    UnstableModel,
}

/// Binomial coefficient C(n, k).
fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Continuous Q(s) of eq 32 as (numerator, denominator) coefficients of (τs)^0, (τs)^1, ….
pub fn q_continuous(order_k: usize, relative_degree_r: usize) -> (Vec<f64>, Vec<f64>) {
    let num = (0..=order_k - relative_degree_r)
        .map(|k| binomial(order_k, k))
        .collect();
    let den = (0..=order_k).map(|k| binomial(order_k, k)).collect();
    (num, den)
}

/// ZOH discretisation of eq 32 (see the module docs): `Q(z⁻¹)` with `K + 1`
/// numerator and denominator coefficients, numerator starting with 0.
pub fn q_discrete(config: &DobConfig, sample_time_s: f64) -> Result<DiscreteTf, DobDesignError> {
    let (k_ord, r) = (config.order_k, config.relative_degree_r);
    if k_ord == 0 || r == 0 || r > k_ord {
        return Err(DobDesignError::Order {
            order_k: k_ord,
            relative_degree_r: r,
        });
    }
    if !(config.tau_s > 0.0 && config.tau_s.is_finite() && sample_time_s > 0.0) {
        return Err(DobDesignError::Time {
            tau_s: config.tau_s,
            sample_time_s,
        });
    }
    // N(s') in powers of w = 1 + s': e_j = Σ_{k≥j} C(K,k) C(k,j) (−1)^{k−j}
    let deg_n = k_ord - r;
    let e: Vec<f64> = (0..=deg_n)
        .map(|j| {
            (j..=deg_n)
                .map(|k| {
                    let sign = if (k - j) % 2 == 0 { 1.0 } else { -1.0 };
                    binomial(k_ord, k) * binomial(k, j) * sign
                })
                .sum()
        })
        .collect();
    // Q = Σ_j e_j w^{j−K}: step response of w^{−m} is 1 − e^{−t'} Σ_{i<m} t'^i/i!
    let step = |n: usize| -> f64 {
        let tp = n as f64 * sample_time_s / config.tau_s;
        let decay = (-tp).exp();
        e.iter()
            .enumerate()
            .map(|(j, ej)| {
                let m = k_ord - j;
                let mut term = 1.0;
                let mut partial = 0.0;
                for i in 0..m {
                    if i > 0 {
                        term *= tp / i as f64;
                    }
                    partial += term;
                }
                ej * (1.0 - decay * partial)
            })
            .sum()
    };
    let impulse: Vec<f64> = (0..=k_ord)
        .map(|n| step(n) - if n == 0 { 0.0 } else { step(n - 1) })
        .collect();
    let p = (-sample_time_s / config.tau_s).exp();
    let den: Vec<f64> = (0..=k_ord)
        .map(|i| binomial(k_ord, i) * (-p).powi(i as i32))
        .collect();
    let mut num = poly_mul(&impulse, &den);
    num.truncate(k_ord + 1);
    num[0] = 0.0; // exactly: the step response of a strictly proper Q starts at 0
    DiscreteTf::new(num, den).map_err(|_| DobDesignError::ZeroModel)
}

/// The disturbance observer of Fig. 3(a), ready to step.
#[derive(Debug, Clone)]
pub struct Dob {
    q: DiscreteTf,
    /// Q·P_n⁻¹ applied to the measured output y(k).
    q_pinv: TfFilter,
    /// z·Q (Q without its leading delay) applied to v(k−1).
    q_v: TfFilter,
    last_out: f64,
    estimate: f64,
}

impl Dob {
    /// Build the observer for the discrete plant model `model` (input → output,
    /// e.g. eq 35) sampled every `sample_time_s`.
    pub fn design(
        config: &DobConfig,
        model: &DiscreteTf,
        sample_time_s: f64,
    ) -> Result<Dob, DobDesignError> {
        Dob::design_with_factor(config, model, &[1.0], sample_time_s)
    }

    /// Build the observer for a plant `model · F(z⁻¹)` whose FIR factor `F`
    /// (unit DC gain, e.g. the measurement's (1 + z⁻¹)/2) is not inverted: it is
    /// applied to the plant input instead, `d̂ = Q·model⁻¹·y − Q·F·v`, so with the
    /// exact plant `d̂ = Q·F·d` (the time-delay DOB idea of paper 000's ref. [13]).
    pub fn design_with_factor(
        config: &DobConfig,
        model: &DiscreteTf,
        factor: &[f64],
        sample_time_s: f64,
    ) -> Result<Dob, DobDesignError> {
        let q = q_discrete(config, sample_time_s)?;
        let d = model.input_delay_samples();
        if d >= model.num().len() {
            return Err(DobDesignError::ZeroModel);
        }
        if !model.is_stable() {
            return Err(DobDesignError::UnstableModel);
        }
        let b_prime = &model.num()[d..];
        if !is_schur_stable(b_prime) {
            return Err(DobDesignError::NonMinimumPhase);
        }
        // Q_eff = z^{−(e−1)} Q = z^{−e} Q' with e = max(d, 1), Q' = Q without its
        // leading zero; P_n = z^{−d} B'/A, so Q_eff·P_n⁻¹ = z^{d−e} Q' A / (Q_den B').
        let e = d.max(1);
        let q_prime = &q.num()[1..];
        let mut pinv_num = vec![0.0; e - d];
        pinv_num.extend(poly_mul(q_prime, model.den()));
        let q_pinv = DiscreteTf::new(pinv_num, poly_mul(q.den(), b_prime))
            .map_err(|_| DobDesignError::ZeroModel)?;
        // z·Q_eff = z^{−(e−1)} Q', fed with v(k−1)
        let mut qv_num = vec![0.0; e - 1];
        qv_num.extend(poly_mul(q_prime, factor));
        let q_v =
            DiscreteTf::new(qv_num, q.den().to_vec()).map_err(|_| DobDesignError::ZeroModel)?;
        let q_eff = q
            .delayed(e - 1)
            .series(&DiscreteTf::fir(factor.to_vec()).map_err(|_| DobDesignError::ZeroModel)?);
        Ok(Dob {
            q: q_eff,
            q_pinv: TfFilter::new(&q_pinv),
            q_v: TfFilter::new(&q_v),
            last_out: 0.0,
            estimate: 0.0,
        })
    }

    /// The estimate's transfer from the disturbance, Q (times any extra model delay
    /// and non-inverted factor).
    pub fn q(&self) -> &DiscreteTf {
        &self.q
    }

    /// One cycle: command `u_cmd` and measured plant output `y_meas` at cycle k →
    /// plant input `v = u − d̂` (Fig. 3(a)).
    #[inline]
    pub fn step(&mut self, u_cmd: f64, y_meas: f64) -> f64 {
        let from_y = self.q_pinv.step(y_meas);
        let from_v = self.q_v.step(self.last_out);
        self.estimate = from_y - from_v;
        self.last_out = u_cmd - self.estimate;
        self.last_out
    }

    /// The latest disturbance estimate d̂ (plant-input units).
    pub fn estimate(&self) -> f64 {
        self.estimate
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.q_pinv.reset();
        self.q_v.reset();
        self.last_out = 0.0;
        self.estimate = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discrete_tf::Complex;

    const T: f64 = 0.001;

    fn pnx() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
    }

    fn cfg(k: usize, r: usize, tau_s: f64) -> DobConfig {
        DobConfig {
            order_k: k,
            relative_degree_r: r,
            tau_s,
        }
    }

    #[test]
    fn q_has_unity_dc_gain_and_the_specified_order() {
        for (k, r) in [(1, 1), (2, 1), (3, 1), (3, 2), (4, 2), (5, 3)] {
            let q = q_discrete(&cfg(k, r, 0.003), T).unwrap();
            assert_eq!(q.den().len(), k + 1, "K = {k}");
            assert_eq!(q.num().len(), k + 1);
            assert_eq!(q.input_delay_samples(), 1, "ZOH Q starts with z^-1");
            assert!(
                (q.dc_gain() - 1.0).abs() < 1e-9,
                "K={k} r={r}: {}",
                q.dc_gain()
            );
            assert!(q.is_stable());
        }
        let (n, d) = q_continuous(3, 1);
        assert_eq!(n, vec![1.0, 3.0, 3.0]);
        assert_eq!(d, vec![1.0, 3.0, 3.0, 1.0]);
    }

    #[test]
    fn zoh_q_matches_a_fine_step_simulation_of_q_s() {
        // Q(s) = (1 + 3τs + 3(τs)²)/(1+τs)³ in controllable form, Euler with dt = T/2000,
        // input held over each sample; compare the outputs at the sample instants.
        let tau = 0.004;
        let q = q_discrete(&cfg(3, 1, tau), T).unwrap();
        let mut filt = TfFilter::new(&q);
        let (d0, d1, d2) = (1.0 / tau.powi(3), 3.0 / tau.powi(2), 3.0 / tau);
        let (n0, n1, n2) = (d0, 3.0 * tau * d0, 3.0 * tau * tau * d0);
        let mut x = [0.0_f64; 3];
        let sub = 2000;
        let dt = T / sub as f64;
        let mut max_err = 0.0_f64;
        for k in 0..60 {
            let u = if k < 30 {
                1.0
            } else {
                -0.5 + (k as f64 * 0.3).sin()
            };
            let y_disc = filt.step(u);
            let y_cont = n0 * x[0] + n1 * x[1] + n2 * x[2];
            max_err = max_err.max((y_disc - y_cont).abs());
            for _ in 0..sub {
                let dx2 = -d0 * x[0] - d1 * x[1] - d2 * x[2] + u;
                x = [x[0] + dt * x[1], x[1] + dt * x[2], x[2] + dt * dx2];
            }
        }
        assert!(max_err < 2e-3, "ZOH mismatch {max_err}");
    }

    #[test]
    fn nominal_estimate_is_q_times_disturbance_and_rejects_a_step() {
        let mut dob = Dob::design(&cfg(3, 1, 0.003), &pnx(), T).unwrap();
        let mut plant = TfFilter::new(&pnx());
        let dist = 0.5;
        for _ in 0..400 {
            let v = dob.step(0.0, plant.pending_output());
            plant.step(v + dist);
        }
        let y = plant.pending_output();
        assert!(
            (dob.estimate() - dist).abs() < 1e-6,
            "estimate {}",
            dob.estimate()
        );
        assert!(y.abs() < 1e-6, "output {y}");
        // check estimate transfer d → d̂ equals Q at a sine frequency (nominal plant)
        let f = 20.0;
        let mut dob = Dob::design(&cfg(3, 1, 0.003), &pnx(), T).unwrap();
        let mut plant = TfFilter::new(&pnx());
        let qf: Complex = dob.q().response(f, T);
        let mut err = 0.0_f64;
        for k in 0..3000 {
            let wt = 2.0 * std::f64::consts::PI * f * T * k as f64;
            let v = dob.step(0.0, plant.pending_output());
            plant.step(v + wt.sin());
            // d̂(k) responds to d up to k−1 through Q (whose first tap is zero)
            let expect = qf.norm() * (wt + qf.arg()).sin();
            if k > 2000 {
                err = err.max((dob.estimate() - expect).abs());
            }
        }
        assert!(err < 1e-6, "estimate vs Q·d: {err}");
    }

    #[test]
    fn a_non_inverted_factor_is_applied_to_the_input_exactly() {
        // plant seen through (1 + z⁻¹)/2 (zero at −1: not invertible)
        let f = [0.5, 0.5];
        let seen = pnx().series(&DiscreteTf::fir(f.to_vec()).unwrap());
        let mut dob = Dob::design_with_factor(&cfg(3, 1, 0.003), &pnx(), &f, T).unwrap();
        let mut naive = Dob::design(&cfg(3, 1, 0.003), &pnx(), T).unwrap();
        let (mut p1, mut p2) = (TfFilter::new(&seen), TfFilter::new(&seen));
        let qf = dob.q().response(20.0, T);
        let (mut err, mut naive_err) = (0.0_f64, 0.0_f64);
        for k in 0..3000 {
            let wt = 2.0 * std::f64::consts::PI * 20.0 * T * k as f64;
            let v1 = dob.step(0.0, p1.pending_output());
            p1.step(v1 + wt.sin());
            let v2 = naive.step(0.0, p2.pending_output());
            p2.step(v2 + wt.sin());
            if k > 2000 {
                let expect = qf.norm() * (wt + qf.arg()).sin();
                err = err.max((dob.estimate() - expect).abs());
                naive_err = naive_err.max((naive.estimate() - expect).abs());
            }
        }
        assert!(err < 1e-6, "{err}");
        assert!(naive_err > 1e-3, "the model error should show: {naive_err}");
    }

    #[test]
    fn bad_designs_are_refused() {
        assert!(matches!(
            q_discrete(&cfg(2, 3, 0.003), T),
            Err(DobDesignError::Order { .. })
        ));
        assert!(matches!(
            q_discrete(&cfg(2, 1, 0.0), T),
            Err(DobDesignError::Time { .. })
        ));
        let nmp = DiscreteTf::new(vec![0.0, 0.1, -0.2], vec![1.0, -0.5]).unwrap();
        assert_eq!(
            Dob::design(&cfg(2, 1, 0.003), &nmp, T).unwrap_err(),
            DobDesignError::NonMinimumPhase
        );
    }
}
