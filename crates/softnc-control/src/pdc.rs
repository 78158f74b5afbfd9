//! Periodic disturbance canceller without phase delay (paper 000, eq 6–31, Fig. 2).
//!
//! The canceller estimates the disturbance from the difference between the plant
//! output and the nominal model's output and feeds it back through `H = L·W`:
//! `T_E = H (y − P_n v)`, `v = u − T_E`. With `P = P_n`, `T_E = H P_n T_L + H ζ`
//! (eq 10), so `H P_n` must be 1 with zero phase at the disturbance frequency f_d
//! (eq 11, 12) and small where the model is uncertain (eq 13).
//!
//! * `L` is a linear-phase FIR low-pass of order `M = 2 M_1` (`M_0 = 0`) built from
//!   `M/4` zeros `z_k = r_k e^{jθ_k}` (eq 20–22): `L_min = Π (1 − z_k z⁻¹)(1 − z_k* z⁻¹)`,
//!   `L_max(z⁻¹) = L_min(z) z^{−M_1}`, `L = L_min L_max / (L_min(1) L_max(1))`. Its delay is
//!   exactly `D_L = M/2` samples and `M_L = |L(f_d)|` (eq 14, 15).
//! * **Angle reading**: the paper prints `θ = 1.3π, 1.57π, 1.86π`; taken literally
//!   they give a high-pass L (+34 dB at 500 Hz). Read as `θ_k − π` (0.3π, 0.57π,
//!   0.86π: zeros near 150, 285 and 430 Hz at 1 kHz) they give the paper's figures
//!   (|L(50 Hz)| = 0.69, −34 dB at 500 Hz, 6 samples). [`ZeroAngleReading`] makes
//!   the reading explicit in the configuration; a literal reading is refused by the
//!   low-pass check.
//! * `W` is an `N`-tap FIR fitted off-line by RLS (eq 28–31) so that
//!   `W P_m ≈ 1` at f_d for the modified model `P_m = M_L z^{−D_L} P_n` (eq 16, 17).
//!   The RLS runs on `s(n) = sin(2π n f_d T)` (eq 26) through `P_m` from rest; an
//!   optional `rls_warmup_samples` only fills the model before adapting. A 3-tap W
//!   fitted to one sinusoid is under-determined: the start-up transient (no
//!   warm-up, the paper's procedure) pulls W towards inverting `P_m` over a band,
//!   a warm-up leaves the minimum-norm fit of the sinusoid alone; δ and the run
//!   length move the taps too. What is checked is eq 11–13, not the taps.
//! * The design is refused unless L is low-pass enough, eq 11–12 hold within the
//!   configured tolerances, and eq 13 holds for the configured multiplicative
//!   uncertainty `|Δ(f)|` on a frequency grid.

pub use crate::config::compensation::{PdcConfig, UncertaintyPoint, ZeroAngleReading, ZeroSpec};
use crate::discrete_tf::{poly_mul, Complex, DiscreteTf, FirFilter, FirSwapError, TfFilter};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::f64::consts::PI;

/// Why a PDC design is refused.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PdcDesignError {
    /// f_d must lie strictly between 0 and the Nyquist frequency.
    #[error("disturbance frequency {fd_hz} Hz must lie between 0 and the Nyquist frequency {nyquist_hz} Hz")]
    Frequency {
        /// Requested f_d.
        fd_hz: f64,
        /// f_s / 2.
        nyquist_hz: f64,
    },
    /// Zero `index` has a radius outside (0, 1), or there are no zeros.
    #[error("L zero {index} must have 0 < r < 1 (and at least one zero is needed)")]
    Zero {
        /// Index into `zeros`.
        index: usize,
    },
    /// W needs at least one tap; RLS needs δ > 0 and samples.
    #[error("W needs >= 1 tap, the RLS delta > 0 and >= 1 sample")]
    WSetup,
    /// The uncertainty table is empty, or has a negative or non-finite entry.
    #[error("model uncertainty table must be non-empty with finite, non-negative entries")]
    Uncertainty,
    /// The plant model has direct feed-through; the estimate would be algebraic.
    #[error("plant model must be strictly proper (b0 = 0)")]
    ModelNotStrictlyProper,
    /// L is not low-pass enough (literal zero angles give a high-pass).
    #[error("L has {l_gain_nyquist_db:.1} dB at the Nyquist frequency, more than the allowed {limit_db:.1} dB (check the zero angle reading)")]
    NotLowPass {
        /// |L| at f_s/2 [dB].
        l_gain_nyquist_db: f64,
        /// Configured limit [dB].
        limit_db: f64,
    },
    /// The fitted H misses eq 11–12 at f_d.
    #[error("H·P_n at f_d is {hp_gain:.4} at {hp_phase_deg:.2} deg; eq 11-12 need 1 at 0 deg within the tolerances")]
    Fit {
        /// |H P_n(f_d)|.
        hp_gain: f64,
        /// ∠H P_n(f_d) [deg].
        hp_phase_deg: f64,
    },
    /// Eq 13 fails: |H P_n Δ| ≥ 1 somewhere.
    #[error("robust stability (eq 13) fails: margin {margin:.3} < 1 at {freq_hz:.1} Hz")]
    Robust {
        /// min_f 1 / |H P_n Δ|.
        margin: f64,
        /// Frequency of the minimum.
        freq_hz: f64,
    },
}

/// A designed canceller and its figures of merit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PdcDesign {
    /// Disturbance frequency f_d [Hz].
    pub fd_hz: f64,
    /// Sample time T [s].
    pub sample_time_s: f64,
    /// Taps of L (M + 1, symmetric).
    pub l_taps: Vec<f64>,
    /// D_L = M / 2 [samples] (eq 15).
    pub delay_samples: usize,
    /// M_L = |L(f_d)| (eq 14).
    pub l_gain_at_fd: f64,
    /// |L(f_s/2)| [dB].
    pub l_gain_nyquist_db: f64,
    /// Taps of W (eq 23).
    pub w_taps: Vec<f64>,
    /// |W(f_s/2)| [dB] for a W fitted to P_n without L (what L must suppress).
    pub w_unshaped_gain_nyquist_db: f64,
    /// Taps of H = L·W.
    pub h_taps: Vec<f64>,
    /// |H P_n(f_d)| (eq 11: 1).
    pub hp_gain_at_fd: f64,
    /// ∠H P_n(f_d) [deg] (eq 12: 0).
    pub hp_phase_deg_at_fd: f64,
    /// H P_n at DC (the paper's W is not constrained there).
    pub hp_gain_dc: f64,
    /// min_f 1 / (|Δ(f)| |H P_n(f)|) (eq 13 holds when > 1).
    pub robust_margin: f64,
    /// Frequency of that minimum [Hz].
    pub robust_margin_freq_hz: f64,
    /// The nominal model P_n.
    #[serde(skip)]
    pub model: DiscreteTf,
}

/// |Δ(f)| from the table.
pub fn uncertainty_at(table: &[UncertaintyPoint], freq_hz: f64) -> f64 {
    let first = table[0];
    if freq_hz <= first.freq_hz {
        return first.relative;
    }
    for pair in table.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if freq_hz <= b.freq_hz {
            let span = b.freq_hz - a.freq_hz;
            if span <= 0.0 {
                return b.relative;
            }
            return a.relative + (b.relative - a.relative) * (freq_hz - a.freq_hz) / span;
        }
    }
    table[table.len() - 1].relative
}

/// Linear-phase L from the zeros (eq 19–22); taps of z⁰ … z^{−M}.
pub fn design_l(zeros: &[ZeroSpec], reading: ZeroAngleReading) -> Result<Vec<f64>, PdcDesignError> {
    if zeros.is_empty() {
        return Err(PdcDesignError::Zero { index: 0 });
    }
    let mut l_min = vec![1.0];
    for (index, z) in zeros.iter().enumerate() {
        if !(z.radius > 0.0 && z.radius < 1.0 && z.angle_pi.is_finite()) {
            return Err(PdcDesignError::Zero { index });
        }
        let theta = match reading {
            ZeroAngleReading::Literal => z.angle_pi * PI,
            ZeroAngleReading::MinusPi => (z.angle_pi - 1.0) * PI,
        };
        // (1 − z z⁻¹)(1 − z* z⁻¹) = 1 − 2 r cos θ z⁻¹ + r² z⁻² (eq 21)
        l_min = poly_mul(
            &l_min,
            &[1.0, -2.0 * z.radius * theta.cos(), z.radius * z.radius],
        );
    }
    // L_max(z⁻¹) = L_min(z) z^{−M_1}: the reversed coefficients (eq 19)
    let l_max: Vec<f64> = l_min.iter().rev().copied().collect();
    let l = poly_mul(&l_min, &l_max);
    let dc: f64 = l.iter().sum();
    Ok(l.iter().map(|c| c / dc).collect()) // eq 22
}

/// RLS fit of an `n_taps` FIR W with W·plant ≈ 1 at f_d (eq 26–31). Off-line design:
/// the tap count is configured, so W, X and R are nalgebra's dynamic vectors and
/// matrices, allocated once before the run.
pub fn fit_w(plant: &DiscreteTf, fd_hz: f64, sample_time_s: f64, config: &PdcConfig) -> Vec<f64> {
    let n = config.w_taps;
    let mut r = DMatrix::from_diagonal_element(n, n, 1.0 / config.rls_delta); // R(0) = δ⁻¹ I (eq 31)
    let mut w = DVector::zeros(n); // W(0) = 0
    let mut x_vec = DVector::zeros(n);
    let mut filt = TfFilter::new(plant);
    let mut rx = DVector::zeros(n);
    let mut gain = DVector::zeros(n);
    for k in 0..config.rls_warmup_samples + config.rls_samples {
        let s = (2.0 * PI * k as f64 * fd_hz * sample_time_s).sin(); // eq 26
        let x = filt.step(s + config.w_dc_block_level);
        x_vec.as_mut_slice().copy_within(0..n - 1, 1);
        x_vec[0] = x; // X(n) (eq 27)
        if k < config.rls_warmup_samples {
            continue;
        }
        rx.gemv(1.0, &r, &x_vec, 0.0);
        gain.copy_from(&rx);
        gain /= 1.0 + x_vec.dot(&rx); // K(n) (eq 28)
        let xi = s - w.dot(&x_vec); // ξ(n) (eq 30)
        w.axpy(xi, &gain, 1.0); // eq 29
                                // R(n) = R − K (Xᵀ R) and Xᵀ R = (R X)ᵀ since R is symmetric (eq 31)
        r.ger(-1.0, &gain, &rx, 1.0);
    }
    w.as_slice().to_vec()
}

fn db(x: f64) -> f64 {
    20.0 * x.log10()
}

/// Design L, W and H for `model` (strictly proper) at `fd_hz`, and check eq 11–13.
pub fn design(
    config: &PdcConfig,
    model: &DiscreteTf,
    sample_time_s: f64,
    fd_hz: f64,
) -> Result<PdcDesign, PdcDesignError> {
    let nyquist_hz = 0.5 / sample_time_s;
    if !(fd_hz > 0.0 && fd_hz < nyquist_hz) {
        return Err(PdcDesignError::Frequency { fd_hz, nyquist_hz });
    }
    if config.w_taps == 0
        || config.rls_delta <= 0.0
        || config.rls_delta.is_nan()
        || config.rls_samples == 0
    {
        return Err(PdcDesignError::WSetup);
    }
    if config.uncertainty.is_empty()
        || config
            .uncertainty
            .iter()
            .any(|p| !(p.relative >= 0.0 && p.relative.is_finite() && p.freq_hz.is_finite()))
    {
        return Err(PdcDesignError::Uncertainty);
    }
    if model.input_delay_samples() == 0 {
        return Err(PdcDesignError::ModelNotStrictlyProper);
    }
    let l_taps = design_l(&config.zeros, config.angle_reading)?;
    let l_tf = DiscreteTf::fir(l_taps.clone()).map_err(|_| PdcDesignError::Zero { index: 0 })?;
    let delay_samples = (l_taps.len() - 1) / 2;
    let l_gain_nyquist_db = db(l_tf.response(nyquist_hz, sample_time_s).norm());
    if l_gain_nyquist_db > config.max_l_gain_nyquist_db || l_gain_nyquist_db.is_nan() {
        return Err(PdcDesignError::NotLowPass {
            l_gain_nyquist_db,
            limit_db: config.max_l_gain_nyquist_db,
        });
    }
    let l_gain_at_fd = l_tf.response(fd_hz, sample_time_s).norm(); // M_L (eq 14)
                                                                   // P_m = M_L z^{−D_L} P_n (eq 16)
    let p_m = model.delayed(delay_samples).scaled(l_gain_at_fd);
    let w_taps = fit_w(&p_m, fd_hz, sample_time_s, config);
    let w_unshaped = fit_w(model, fd_hz, sample_time_s, config);
    let w_unshaped_gain_nyquist_db = db(DiscreteTf::fir(w_unshaped)
        .map_err(|_| PdcDesignError::WSetup)?
        .response(nyquist_hz, sample_time_s)
        .norm());
    let h_taps = poly_mul(&l_taps, &w_taps);
    let h_tf = DiscreteTf::fir(h_taps.clone()).map_err(|_| PdcDesignError::WSetup)?;
    let hp =
        |f: f64| -> Complex { h_tf.response(f, sample_time_s) * model.response(f, sample_time_s) };
    let at_fd = hp(fd_hz);
    let (hp_gain_at_fd, hp_phase_deg_at_fd) = (at_fd.norm(), at_fd.arg().to_degrees());
    if !((hp_gain_at_fd - 1.0).abs() <= config.gain_tolerance
        && hp_phase_deg_at_fd.abs() <= config.phase_tolerance_deg)
    {
        return Err(PdcDesignError::Fit {
            hp_gain: hp_gain_at_fd,
            hp_phase_deg: hp_phase_deg_at_fd,
        });
    }
    // eq 13 on a grid: margin = min 1 / (|Δ| |H P_n|)
    let (mut robust_margin, mut robust_margin_freq_hz) = (f64::INFINITY, 0.0);
    let points = config.robust_grid_points.max(1);
    for i in 0..=points {
        let f = nyquist_hz * i as f64 / points as f64;
        let loop_gain = uncertainty_at(&config.uncertainty, f) * hp(f).norm();
        let margin = 1.0 / loop_gain;
        if margin < robust_margin {
            robust_margin = margin;
            robust_margin_freq_hz = f;
        }
    }
    if robust_margin <= 1.0 || robust_margin.is_nan() {
        return Err(PdcDesignError::Robust {
            margin: robust_margin,
            freq_hz: robust_margin_freq_hz,
        });
    }
    Ok(PdcDesign {
        fd_hz,
        sample_time_s,
        l_taps,
        delay_samples,
        l_gain_at_fd,
        l_gain_nyquist_db,
        w_taps,
        w_unshaped_gain_nyquist_db,
        hp_gain_dc: hp(0.0).re,
        h_taps,
        hp_gain_at_fd,
        hp_phase_deg_at_fd,
        robust_margin,
        robust_margin_freq_hz,
        model: model.clone(),
    })
}

/// The canceller of Fig. 2, ready to step.
#[derive(Debug, Clone)]
pub struct Pdc {
    h: FirFilter,
    model: TfFilter,
    estimate: f64,
}

impl Pdc {
    /// A canceller at rest running `design`.
    pub fn new(design: &PdcDesign) -> Self {
        Pdc {
            h: FirFilter::new(design.h_taps.clone()),
            model: TfFilter::new(&design.model),
            estimate: 0.0,
        }
    }

    /// T_E(k) = H (y − P_n v)(k); P_n v at k depends on v up to k−1 only.
    #[inline]
    fn estimate_step(&mut self, y_meas: f64) -> f64 {
        self.estimate = self.h.step(y_meas - self.model.pending_output());
        self.estimate
    }

    /// Record the plant input v(k) actually applied.
    #[inline]
    fn commit(&mut self, v: f64) {
        self.model.step(v);
    }

    /// One cycle: command `u_cmd`, measured output `y_meas` → plant input
    /// `v = u − T_E` (Fig. 2).
    #[inline]
    pub fn step(&mut self, u_cmd: f64, y_meas: f64) -> f64 {
        let v = u_cmd - self.estimate_step(y_meas);
        self.commit(v);
        v
    }

    /// The latest estimate T_E (plant-input units).
    pub fn estimate(&self) -> f64 {
        self.estimate
    }

    /// Swap in H of a redesign (same L and W sizes) between two cycles without
    /// allocating; the old taps come back in `h_taps` to be dropped elsewhere.
    pub fn swap_h_taps(&mut self, h_taps: &mut Vec<f64>) -> Result<(), FirSwapError> {
        self.h.swap_taps(h_taps)
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.h.reset();
        self.model.reset();
        self.estimate = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 0.001;

    fn pnx() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
    }

    fn pny() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1425, -0.1404], vec![1.0, -1.8575, 0.8596]).unwrap()
    }

    /// The paper's design data (zeros as printed, read θ − π).
    pub(crate) fn paper_config() -> PdcConfig {
        PdcConfig {
            uncertainty: vec![
                UncertaintyPoint {
                    freq_hz: 0.0,
                    relative: 0.2,
                },
                UncertaintyPoint {
                    freq_hz: 500.0,
                    relative: 0.5,
                },
            ],
            ..softnc_core::ron_file::parse_ron::<PdcConfig>(
                include_str!("../../../config/pdc/paper000-canceller.ron"),
                "config/pdc/paper000-canceller.ron",
            )
            .unwrap()
        }
    }

    #[test]
    fn l_meets_the_papers_figures() {
        let l = design_l(&paper_config().zeros, ZeroAngleReading::MinusPi).unwrap();
        assert_eq!(l.len(), 13);
        for i in 0..13 {
            assert!((l[i] - l[12 - i]).abs() < 1e-12, "taps not symmetric");
        }
        let tf = DiscreteTf::fir(l.clone()).unwrap();
        let at50 = tf.response(50.0, T);
        assert!(
            (at50.norm() - 0.69).abs() <= 0.01,
            "|L(50)| = {}",
            at50.norm()
        );
        // linear phase: exactly −6 ωT at every frequency in the pass band
        for f in [10.0, 50.0, 100.0] {
            let phase = tf.response(f, T).arg();
            let expect = -6.0 * 2.0 * PI * f * T;
            let diff = (phase - expect).rem_euclid(2.0 * PI);
            assert!(diff.min(2.0 * PI - diff) < 1e-9, "phase at {f} Hz");
        }
        assert!(db(tf.response(500.0, T).norm()) <= -30.0);
        assert!((tf.dc_gain() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn literal_angles_give_a_high_pass_and_are_refused() {
        let l = design_l(&paper_config().zeros, ZeroAngleReading::Literal).unwrap();
        let g = db(DiscreteTf::fir(l).unwrap().response(500.0, T).norm());
        assert!(g > 30.0, "literal reading gave {g} dB");
        let mut cfg = paper_config();
        cfg.angle_reading = ZeroAngleReading::Literal;
        assert!(matches!(
            design(&cfg, &pnx(), T, 50.0),
            Err(PdcDesignError::NotLowPass { .. })
        ));
    }

    #[test]
    fn h_times_pn_is_one_at_fd_for_both_axes() {
        for (axis, p) in [("x", pnx()), ("y", pny())] {
            let d = design(&paper_config(), &p, T, 50.0).unwrap();
            assert_eq!(d.delay_samples, 6);
            assert!(
                (d.hp_gain_at_fd - 1.0).abs() <= 0.01,
                "{axis}: {}",
                d.hp_gain_at_fd
            );
            assert!(
                d.hp_phase_deg_at_fd.abs() <= 1.0,
                "{axis}: {}",
                d.hp_phase_deg_at_fd
            );
            assert!(d.robust_margin > 1.0);
            // independent recomputation from the taps
            let h = DiscreteTf::fir(poly_mul(&d.l_taps, &d.w_taps)).unwrap();
            let hp = h.response(50.0, T) * p.response(50.0, T);
            assert!((hp.norm() - d.hp_gain_at_fd).abs() < 1e-12);
        }
    }

    #[test]
    fn the_papers_printed_w_inverts_the_delayed_model_without_m_l() {
        // W_x = 9.915 − 21.856 z⁻¹ + 11.276 z⁻²: |W e^{−j6ωT} P_nx| ≈ 1 at 0° at 50 Hz,
        // i.e. the printed W leaves out M_L; with the L of eq 22 in series,
        // |H P_n| = M_L ≈ 0.69. Our design follows eq 16-17 (W inverts P_m incl. M_L).
        let w = DiscreteTf::fir(vec![9.915, -21.856, 11.276]).unwrap();
        let hp = w.delayed(6).response(50.0, T) * pnx().response(50.0, T);
        assert!((hp.norm() - 1.0).abs() < 0.02, "{}", hp.norm());
        assert!(
            hp.arg().to_degrees().abs() < 2.0,
            "{}",
            hp.arg().to_degrees()
        );
        let l =
            DiscreteTf::fir(design_l(&paper_config().zeros, ZeroAngleReading::MinusPi).unwrap())
                .unwrap();
        let hp_l = w.series(&l).response(50.0, T) * pnx().response(50.0, T);
        assert!((hp_l.norm() - 0.69).abs() < 0.02, "{}", hp_l.norm());
    }

    #[test]
    fn redesign_away_from_50_hz() {
        for fd in [40.0, 60.0] {
            let d = design(&paper_config(), &pnx(), T, fd).unwrap();
            assert!((d.hp_gain_at_fd - 1.0).abs() <= 0.01);
            assert!(d.hp_phase_deg_at_fd.abs() <= 1.0);
        }
    }

    #[test]
    fn failing_designs_are_refused() {
        let mut cfg = paper_config();
        cfg.uncertainty = vec![UncertaintyPoint {
            freq_hz: 0.0,
            relative: 2.0,
        }];
        assert!(matches!(
            design(&cfg, &pnx(), T, 50.0),
            Err(PdcDesignError::Robust { .. })
        ));
        assert!(matches!(
            design(&paper_config(), &pnx(), T, 600.0),
            Err(PdcDesignError::Frequency { .. })
        ));
        let mut cfg = paper_config();
        cfg.zeros[1].radius = 1.2;
        assert_eq!(
            design(&cfg, &pnx(), T, 50.0).unwrap_err(),
            PdcDesignError::Zero { index: 1 }
        );
        // too few RLS samples: the fit misses eq 11-12 and is refused
        let mut cfg = paper_config();
        cfg.rls_samples = 2;
        cfg.rls_warmup_samples = 0;
        assert!(matches!(
            design(&cfg, &pnx(), T, 50.0),
            Err(PdcDesignError::Fit { .. })
        ));
    }

    /// Steady-state amplitude of the periodic position error with the estimate
    /// delayed by `delay` samples (test-only variant of the canceller; `None` = no
    /// compensation), in a P position loop around the nominal velocity loop P_nx.
    fn position_error_amplitude(delay: Option<usize>, fd_hz: f64) -> f64 {
        let design = design(&paper_config(), &pnx(), T, fd_hz).unwrap();
        let mut pdc = Pdc::new(&design);
        let mut plant = TfFilter::new(&pnx());
        let mut line = vec![0.0; delay.unwrap_or(0) + 1];
        let kpp_per_s = 30.0;
        let (mut x, mut amp) = (0.0, 0.0_f64);
        let steps = 6000;
        for k in 0..steps {
            let y = plant.pending_output();
            x += y * T;
            let u = -kpp_per_s * x;
            let v = match delay {
                None => u,
                Some(n) => {
                    let est = pdc.estimate_step(y);
                    line.copy_within(0..n, 1);
                    line[0] = est;
                    let v = u - line[n];
                    pdc.commit(v);
                    v
                }
            };
            let t_l = (2.0 * PI * fd_hz * T * k as f64).sin();
            plant.step(v + t_l);
            if k > steps - 1000 {
                amp = amp.max(x.abs());
            }
        }
        amp
    }

    #[test]
    fn delayed_estimate_error_follows_eq_5() {
        let fd = 50.0;
        let none = position_error_amplitude(None, fd);
        let zero = position_error_amplitude(Some(0), fd) / none;
        assert!(zero < 0.03, "undelayed PDC leaves {zero}");
        for n in [1usize, 2, 3, 4, 6] {
            let theta_c = 2.0 * n as f64 * PI * fd * T; // eq 4
            let predicted = 2.0 * (theta_c / 2.0).sin(); // eq 5, relative to A_per
            let measured = position_error_amplitude(Some(n), fd) / none;
            assert!(
                (measured - predicted).abs() <= 0.1 * predicted,
                "n = {n}: measured {measured}, eq 5 {predicted}"
            );
        }
    }

    #[test]
    fn swapping_h_between_cycles() {
        let d50 = design(&paper_config(), &pnx(), T, 50.0).unwrap();
        let d60 = design(&paper_config(), &pnx(), T, 60.0).unwrap();
        let mut pdc = Pdc::new(&d50);
        let mut taps = d60.h_taps.clone();
        pdc.swap_h_taps(&mut taps).unwrap();
        assert_eq!(taps, d50.h_taps);
    }
}
