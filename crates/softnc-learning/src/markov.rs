//! Markov-parameter learning in the repetition domain (paper 002, eq 5).
//!
//! The servo (command → position, closed loop) is taken as LTI with unit impulse
//! response h(i) = CA^{i−1}B, i = 1, 2, … (its Markov parameters). After repetition
//! j−1 with error e_{j−1}(k) = P_desired(k) − y_{j−1}(k), the command of repetition j is
//!
//!   P_j(k) = P_{j−1}(k) + s · Σ_{i=1..p} h(i) · e_{j−1}(k+i)          (002 eq 5)
//!
//! (e(k+i) = 0 past the end): a non-causal filter in the time domain, causal in the
//! repetition domain. `p` is the learning buffer size (how many Markov terms are
//! used); the paper's Fig. 4 shows a small p already converges fast.

use nalgebra::DVectorView;

/// Identify the first `p` Markov parameters h(1..=p) from the measured response `y`
/// of the closed loop, at rest, to a one-sample pulse of `height` commanded at index
/// `at`: h(i) = y(at + i) / height.
pub fn identify_markov(y: &[f64], at: usize, height: f64, p: usize) -> Vec<f64> {
    (1..=p)
        .map(|i| y.get(at + i).copied().unwrap_or(0.0) / height)
        .collect()
}

/// How many of the identified terms `h` carry the response: the measured response
/// of a real (or simulated) loop does not decay to zero but settles, within the
/// measurement floor, to a rest value (friction holds the axis a little off, the
/// encoder quantises). The rest value is the median of the last quarter of `h`;
/// the terms after the last one farther than `floor` (relative to the pulse height)
/// from it are floor, not response: the count up to there is returned.
pub fn settled_terms(h: &[f64], floor: f64) -> usize {
    if h.is_empty() {
        return 0;
    }
    let mut tail: Vec<f64> = h[h.len() - h.len().div_ceil(4)..].to_vec();
    tail.sort_by(f64::total_cmp);
    let rest = tail[tail.len() / 2];
    h.iter()
        .rposition(|v| (v - rest).abs() > floor)
        .map_or(0, |i| i + 1)
}

/// The learning law with its gain and buffer of Markov parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkovLearner {
    /// Learning gain s.
    pub gain: f64,
    /// h(1..=p).
    pub markov: Vec<f64>,
}

impl MarkovLearner {
    /// A learner using the first `buffer` of the identified parameters.
    pub fn new(gain: f64, markov: &[f64], buffer: usize) -> Self {
        MarkovLearner {
            gain,
            markov: markov[..buffer.min(markov.len())].to_vec(),
        }
    }

    /// Update `command` (P_{j−1} → P_j) in place from the last repetition's error:
    /// P_j = P_{j−1} + s·H_pᵀe, H_p the lower-triangular banded Toeplitz matrix of
    /// h(1..=p). Row k of H_pᵀe is the dot product of h with e(k+1..k+p), taken over
    /// nalgebra vector views of the buffers (H_p itself, n × n for n samples, is
    /// never formed).
    pub fn update(&self, command: &mut [f64], error: &[f64]) {
        let n = command.len().min(error.len());
        let h = DVectorView::from_slice(&self.markov, self.markov.len());
        let e = DVectorView::from_slice(&error[..n], n);
        for (k, c) in command[..n].iter_mut().enumerate() {
            let terms = h.len().min(n - k - 1);
            *c += self.gain * h.rows(0, terms).dot(&e.rows(k + 1, terms));
        }
    }

    /// A gain for which the update contracts the error 2-norm. With all p terms the
    /// update is a gradient step u += s·Hᵀe on ‖e‖² (H the lower-triangular Toeplitz
    /// matrix of the h(i)), monotone for s < 2/‖H‖²; with a truncated buffer H_p it
    /// is e ← (I − s·H·H_pᵀ)e. Using ‖H‖₂ ≤ Σ|h(i)|, s = 1/(Σ_all|h| · Σ_p|h|).
    pub fn default_gain(markov_all: &[f64], buffer: usize) -> f64 {
        let l1 = |h: &[f64]| h.iter().map(|v| v.abs()).sum::<f64>();
        let d = l1(markov_all) * l1(&markov_all[..buffer.min(markov_all.len())]);
        if d > 0.0 {
            1.0 / d
        } else {
            0.0
        }
    }
}

/// The documented learning gain s of eq 5: with it the error 2-norm fell at every
/// repetition on `examples/learning/lines-arcs.ngc` on `default.ron` (seeds 1–5,
/// buffers 5, 20 and all terms); the LTI bound 1/(Σ_all|h|·Σ_p|h|) (≈ 0.40–0.45 there)
/// did not: stick friction at zero-speed crossings makes the loop non-linear.
pub const DEFAULT_GAIN: f64 = 0.5;

/// Axes a job's learning covers (X, Y, Z).
pub const AXES: usize = softnc_core::MAX_AXES;

/// Eq 5 applied to a whole job, one learner per axis, with the two buffers the paper
/// keeps beside the command buffer: the corrected command P_j (as a correction added
/// to the planned command, so it composes with any filter the position stack applies)
/// and the error e_{j−1} of the last repetition.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MarkovJob {
    /// Learning gain s per axis.
    pub gain: [f64; AXES],
    /// Learning buffer size p (Markov terms used).
    pub buffer: usize,
    /// Identified Markov parameters h(1..) per axis (all identified terms).
    pub markov: [Vec<f64>; AXES],
    /// P_j − P_desired per sample and axis (mm).
    pub correction_mm: [Vec<f64>; AXES],
    /// e_{j−1} = P_desired − y_{j−1} per sample and axis (mm).
    pub last_error_mm: [Vec<f64>; AXES],
    /// Repetitions learnt from so far (j).
    pub repetitions: usize,
    /// Largest |correction| per axis (mm), from the profile's `learning`
    /// ([`softnc_core::config::LearningConfig`]); `None`: unbounded.
    #[serde(default)]
    pub max_correction_mm: Option<[f64; AXES]>,
    /// What this correction did against the unlearned run, when it was measured to
    /// do better (set by `softnc_experiments::learning_runs::learn_markov`); `None`: not measured to
    /// improve anything, so not to be applied.
    #[serde(default)]
    pub improvement: Option<Improvement>,
}

/// The measured improvement of a stored correction on the unlearned run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Improvement {
    /// The learning run whose command is this correction (0 = unlearned).
    pub iteration: usize,
    /// Contour-error RMS of the unlearned run (µm).
    pub unlearned_rms_um: f64,
    /// Contour-error RMS of the run with this correction (µm), below `unlearned_rms_um`.
    pub rms_um: f64,
}

impl Improvement {
    /// Whether the correction did better than the unlearned run (and both are numbers).
    pub fn improved(&self) -> bool {
        self.rms_um.is_finite()
            && self.unlearned_rms_um.is_finite()
            && self.rms_um < self.unlearned_rms_um
    }
}

impl MarkovJob {
    /// A job of `samples` samples with no correction yet. `gain` `None` takes
    /// [`MarkovLearner::default_gain`] per axis.
    pub fn new(markov: [Vec<f64>; AXES], buffer: usize, gain: Option<f64>, samples: usize) -> Self {
        let gain: [f64; AXES] = std::array::from_fn(|a| {
            gain.unwrap_or_else(|| MarkovLearner::default_gain(&markov[a], buffer))
        });
        MarkovJob {
            gain,
            buffer,
            markov,
            correction_mm: std::array::from_fn(|_| vec![0.0; samples]),
            last_error_mm: std::array::from_fn(|_| vec![0.0; samples]),
            repetitions: 0,
            max_correction_mm: None,
            improvement: None,
        }
    }

    /// The same job with every correction bounded to ±`max_correction_mm[axis]`.
    pub fn bounded(mut self, max_correction_mm: [f64; AXES]) -> Self {
        self.max_correction_mm = Some(max_correction_mm.map(f64::abs));
        self
    }

    /// Samples in the job.
    pub fn samples(&self) -> usize {
        self.correction_mm[0].len()
    }

    /// The command of the next repetition at sample `k`: planned + correction.
    pub fn command(&self, k: usize, planned_mm: [f64; AXES]) -> [f64; AXES] {
        std::array::from_fn(|a| {
            planned_mm[a] + self.correction_mm[a].get(k).copied().unwrap_or(0.0)
        })
    }

    /// Learn from one repetition: `planned_mm[k]` the desired positions, `measured_mm[k]`
    /// what the machine did (index k as the command's). Eq 5 updates the correction,
    /// except at sample 0: the job starts at rest there, so it stays as planned.
    pub fn learn(&mut self, planned_mm: &[[f64; AXES]], measured_mm: &[[f64; AXES]]) {
        let n = self.samples().min(planned_mm.len()).min(measured_mm.len());
        for a in 0..AXES {
            for k in 0..n {
                self.last_error_mm[a][k] = planned_mm[k][a] - measured_mm[k][a];
            }
            let learner = MarkovLearner::new(self.gain[a], &self.markov[a], self.buffer);
            learner.update(&mut self.correction_mm[a][..n], &self.last_error_mm[a][..n]);
            if let Some(bound) = self.max_correction_mm.map(|b| b[a]) {
                for c in &mut self.correction_mm[a][..n] {
                    *c = c.clamp(-bound, bound);
                }
            }
            // the job starts with the machine at rest on its first sample: that
            // sample is where the axes are, not a command learning may move
            if let Some(c0) = self.correction_mm[a].first_mut() {
                *c0 = 0.0;
            }
        }
        self.repetitions += 1;
        self.improvement = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first-order closed loop y(k+1) = a y(k) + (1−a) u(k).
    fn run(u: &[f64], a: f64) -> Vec<f64> {
        let mut y = vec![0.0; u.len()];
        for k in 1..u.len() {
            y[k] = a * y[k - 1] + (1.0 - a) * u[k - 1];
        }
        y
    }

    #[test]
    fn identified_markov_parameters_are_the_impulse_response() {
        let a = 0.9;
        let mut u = vec![0.0; 50];
        u[5] = 2.0;
        let y = run(&u, a);
        let h = identify_markov(&y, 5, 2.0, 5);
        for (i, hi) in h.iter().enumerate() {
            let want = (1.0 - a) * a.powi(i as i32);
            assert!(
                (hi - want).abs() < 1e-12,
                "h({}) = {hi}, want {want}",
                i + 1
            );
        }
    }

    /// The update is eq 5 term by term: c(k) += s Σ_{i=1..p} h(i) e(k+i), e = 0 past
    /// the end, for buffers shorter and longer than the job.
    #[test]
    fn update_is_eq5_term_by_term() {
        let n = 37;
        let error: Vec<f64> = (0..n).map(|k| (k as f64 * 0.7).sin() + 0.1).collect();
        let start: Vec<f64> = (0..n).map(|k| k as f64 * 0.01).collect();
        let h_all: Vec<f64> = (1..=60)
            .map(|i| 0.8f64.powi(i) * (i as f64).cos())
            .collect();
        for p in [0usize, 1, 3, 8, 9, 36, 37, 60] {
            let learner = MarkovLearner::new(0.5, &h_all, p);
            let mut cmd = start.clone();
            learner.update(&mut cmd, &error);
            for k in 0..n {
                let mut acc = 0.0;
                for i in 1..=p {
                    if k + i < n {
                        acc += h_all[i - 1] * error[k + i];
                    }
                }
                let want = start[k] + 0.5 * acc;
                assert!(
                    (cmd[k] - want).abs() <= 1e-12 * (1.0 + want.abs()),
                    "p {p}, k {k}: {} vs {want}",
                    cmd[k]
                );
            }
        }
        // a shorter error than command: only the common samples move
        let learner = MarkovLearner::new(1.0, &[1.0, 1.0], 2);
        let mut cmd = vec![0.0; 4];
        learner.update(&mut cmd, &[1.0, 2.0, 3.0]);
        assert_eq!(cmd, vec![5.0, 3.0, 0.0, 0.0]);
    }

    #[test]
    fn settled_terms_stop_where_the_response_reaches_its_rest_value() {
        // a response decaying to a rest value of -3e-4 (an axis held off by friction)
        let h: Vec<f64> = (0..400)
            .map(|i| 0.2 * 0.9f64.powi(i) - 3e-4 * (1.0 - 0.9f64.powi(i)))
            .collect();
        let n = settled_terms(&h, 1e-4);
        // 0.2·0.9^i + 3e-4·0.9^i > 1e-4 ⇔ i < ln(1e-4/0.2003)/ln 0.9 ≈ 72.1
        assert_eq!(n, 73);
        assert_eq!(settled_terms(&[], 1e-4), 0);
    }

    #[test]
    fn learning_converges_and_error_norm_never_grows() {
        let a = 0.95;
        let n = 400;
        let desired: Vec<f64> = (0..n).map(|k| (k as f64 * 0.02).sin() * 10.0).collect();
        let mut u = vec![0.0; n];
        u[1] = 1.0;
        let h = identify_markov(&run(&u, a), 1, 1.0, n - 2);
        for buffer in [5usize, 20, n - 2] {
            let learner = MarkovLearner::new(MarkovLearner::default_gain(&h, buffer), &h, buffer);
            let mut cmd = desired.clone();
            let mut last = f64::INFINITY;
            let mut first = 0.0;
            for it in 0..30 {
                let y = run(&cmd, a);
                let e: Vec<f64> = desired.iter().zip(&y).map(|(d, y)| d - y).collect();
                // only the part the learning can reach: e(0) depends on nothing learnt
                let norm = e[1..].iter().map(|v| v * v).sum::<f64>().sqrt();
                if it == 0 {
                    first = norm;
                }
                assert!(
                    norm <= last * (1.0 + 1e-9),
                    "buffer {buffer}: error grew at repetition {it}: {last} -> {norm}"
                );
                last = norm;
                learner.update(&mut cmd, &e);
            }
            assert!(last < 0.2 * first, "buffer {buffer}: {first} -> {last}");
        }
    }
}
