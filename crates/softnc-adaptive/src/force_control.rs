//! The adaptive robust force controller of paper 003 (Fig. 1–2), one step per control
//! sample: RLS update of the ARMA model (eq 8, 11–12), exact placement of the four
//! closed-loop poles (eq 18–22, see [`crate::robust_servo`]), the Davison servo law
//! (eq 14–17), the feed clamped to the override range and rate-limited.
//!
//! Safeguards (ours; the paper states the conditions, not what to do when an
//! estimate violates them): the gains are only replaced when the estimated model has
//! the structure of eq 5–7 ([`model_usable`]: real stable poles, which is the paper's
//! condition 1, and a zero in (−1, 0]) and the placement is solvable (conditions 2
//! and 4); otherwise the last good gains stay.
//!
//! **Form and anti-windup.** Eliminating η and ε from eq 14–17 gives the same law as
//! R(q)v = P(q)f + T(q)f* with R = (q − 1)(q − r₀),
//! P = T_s(k(q − r₀) + r₄r₂) + (q − 1)(r₃(q − r₀) + r₄r₁) and
//! T = −T_s(k(q − r₀) + r₄r₂) (T(1) = −P(1): no steady-state error). It is run in that
//! input–output form with the anti-windup observer of Åström–Wittenmark,
//! A_o v = P f + T f* + (A_o − R) v̄, where v̄ is the feed actually applied after the
//! clamp and the rate limit and A_o = (q − z₁)(q − z₂) uses the two fastest requested
//! poles. Unsaturated (v̄ = v) it is exactly eq 14–17; saturated, the controller's
//! memory follows the applied feed through the stable A_o instead of winding up, and
//! a change of gains between samples needs no state conversion. The estimator is fed
//! the applied feed.

use crate::rls::{Rls, RlsConfig};
use crate::robust_servo::{place_poles, PlacementError, ServoGains};
use crate::zoh::Arma2;
use nalgebra::Vector4;

/// Settings of one controller (feed in the caller's units, e.g. mm/min).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceControlConfig {
    /// Desired closed-loop poles (z).
    pub poles: [f64; 4],
    /// Control sample T_s (s): one spindle revolution.
    pub t_s: f64,
    /// Estimator settings.
    pub rls: RlsConfig,
    /// Starting model.
    pub prior: Arma2,
    /// Lowest feed.
    pub v_min: f64,
    /// Highest feed.
    pub v_max: f64,
    /// Largest feed change per sample.
    pub dv_max: f64,
}

/// What one control step did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlStep {
    /// Feed the servo law asked for.
    pub v_law: f64,
    /// Feed applied (clamped and rate-limited).
    pub v: f64,
    /// Model estimate Θ = [−φ₁, −φ₂, θ₁, θ₂] used for the gains.
    pub theta: Vector4<f64>,
    /// Gains in force.
    pub gains: ServoGains,
    /// Estimator's prediction error (N).
    pub prediction_error: f64,
    /// Whether this sample updated the estimate and it gave new gains.
    pub model_accepted: bool,
}

/// The controller's state.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveForceControl {
    cfg: ForceControlConfig,
    rls: Rls,
    gains: ServoGains,
    theta_used: Vector4<f64>,
    /// A_o = q² + ao[0] q + ao[1].
    ao: [f64; 2],
    /// f(t−1), f(t−2).
    y: [f64; 2],
    /// Applied feed v̄(t−1), v̄(t−2).
    u: [f64; 2],
    /// Law output v(t−1), v(t−2).
    v: [f64; 2],
    /// f*(t−1), f*(t−2).
    r: [f64; 2],
    samples: u64,
    rejected: u64,
    /// An outside ceiling on the applied feed (the operator's override), below
    /// `v_max`; infinite when none.
    v_cap: f64,
}

/// Whether `m` can be the sampled plant of eq 5: two real poles in [0, 1) (condition 1:
/// Φ stable, no chatter), θ₁ > 0 and θ₂ ≥ 0 — the ZOH equivalent of two first-order
/// lags with a positive gain always has them, and its zero −θ₂/θ₁ lies in (−1, 0]
/// (the paper finds −0.84…−0.56) — and a finite static gain. An estimate outside
/// this set (typically a near pole–zero cancellation at z ≈ 1 under weak closed-loop
/// excitation) would demand huge gains; it is not used.
pub fn model_usable(m: &Arma2) -> bool {
    let finite = [m.phi1, m.phi2, m.theta1, m.theta2]
        .iter()
        .all(|v| v.is_finite());
    if !finite {
        return false;
    }
    // z² + φ₁z + φ₂ = 0: real roots in [0, 1)
    let disc = m.phi1 * m.phi1 - 4.0 * m.phi2;
    if disc < 0.0 {
        return false;
    }
    let sq = disc.sqrt();
    let (z1, z2) = ((-m.phi1 - sq) / 2.0, (-m.phi1 + sq) / 2.0);
    let poles_ok = [z1, z2].iter().all(|z| (0.0..1.0).contains(z));
    let zero_ok = m.theta1 > 0.0 && m.theta2 >= 0.0 && m.theta2 < m.theta1;
    poles_ok && zero_ok && m.dc_gain().is_finite()
}

impl AdaptiveForceControl {
    /// Start with the prior model's gains; the first step applies `v0` (bumpless).
    pub fn new(cfg: ForceControlConfig, v0: f64) -> Result<Self, PlacementError> {
        let gains = place_poles(&cfg.prior, cfg.poles, cfg.t_s)?;
        let v0 = v0.clamp(cfg.v_min, cfg.v_max);
        let mut fast = cfg.poles;
        fast.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
        Ok(AdaptiveForceControl {
            rls: Rls::new(cfg.rls, cfg.prior.theta()),
            gains,
            theta_used: cfg.prior.theta(),
            ao: [-(fast[0] + fast[1]), fast[0] * fast[1]],
            y: [0.0; 2],
            u: [v0; 2],
            v: [v0; 2],
            r: [0.0; 2],
            samples: 0,
            rejected: 0,
            v_cap: f64::INFINITY,
            cfg,
        })
    }

    /// Updated estimates rejected so far (the last good gains were kept).
    pub fn rejected(&self) -> u64 {
        self.rejected
    }

    /// Covariance resets of the estimator so far.
    pub fn covariance_resets(&self) -> u64 {
        self.rls.resets()
    }

    /// A ceiling on the feed from the next sample on (the operator's override times
    /// the programmed feed; `f64::INFINITY`: none). The ceiling acts like the clamp:
    /// the anti-windup observer follows the feed applied under it, and it is applied
    /// at once, past the rate limit (an operator turning the override down is obeyed
    /// in one sample).
    pub fn set_v_cap(&mut self, v_cap: f64) {
        self.v_cap = v_cap;
    }

    /// The feed applied last.
    pub fn feed(&self) -> f64 {
        self.u[0]
    }

    /// One control sample: the measured peak force `f` (N) of the revolution just
    /// ended and the reference `f_ref` (N). Returns the feed to apply now.
    pub fn step(&mut self, f: f64, f_ref: f64) -> ControlStep {
        let mut pred_err = 0.0;
        let mut accepted = false;
        let before = self.rls.theta();
        if self.samples >= 2 {
            pred_err = self
                .rls
                .update(&Vector4::new(self.y[0], self.y[1], self.u[0], self.u[1]), f);
        }
        if self.samples >= 2 && self.rls.theta() != before {
            let m = Arma2::from_theta(&self.rls.theta());
            if model_usable(&m) {
                if let Ok(g) = place_poles(&m, self.cfg.poles, self.cfg.t_s) {
                    if [g.k, g.r0, g.r1, g.r2, g.r3, g.r4]
                        .iter()
                        .all(|v| v.is_finite())
                        && g.k != 0.0
                    {
                        self.gains = g;
                        self.theta_used = m.theta();
                        accepted = true;
                    }
                }
            }
            if !accepted {
                self.rejected += 1;
            }
        }
        let g = self.gains;
        if self.samples == 0 {
            // bumpless start: as if the force had been `f` and the reference too
            self.y = [f; 2];
            self.r = [f; 2];
        }
        let ts = self.cfg.t_s;
        // R = q² + rr1 q + rr2
        let (rr1, rr2) = (-(1.0 + g.r0), g.r0);
        // P = p2 q² + p1 q + p0
        let p2 = g.r3;
        let p1 = ts * g.k - g.r3 * (g.r0 + 1.0) + g.r4 * g.r1;
        let p0 = -ts * g.k * g.r0 + ts * g.r4 * g.r2 + g.r3 * g.r0 - g.r4 * g.r1;
        // T = t1 q + t0
        let (t1, t0) = (-ts * g.k, ts * (g.k * g.r0 - g.r4 * g.r2));
        let [ao1, ao2] = self.ao;
        let v_law = -ao1 * self.v[0] - ao2 * self.v[1]
            + p2 * f
            + p1 * self.y[0]
            + p0 * self.y[1]
            + t1 * self.r[0]
            + t0 * self.r[1]
            + (ao1 - rr1) * self.u[0]
            + (ao2 - rr2) * self.u[1];
        let lo = self.cfg.v_min.max(self.u[0] - self.cfg.dv_max);
        let hi = self.cfg.v_max.min(self.u[0] + self.cfg.dv_max);
        let v = if v_law.is_finite() {
            v_law.clamp(lo, hi)
        } else {
            self.u[0].clamp(lo, hi)
        }
        .min(self.v_cap);
        // the memory of a non-finite law output restarts from the applied feed
        let v_mem = if v_law.is_finite() { v_law } else { v };
        self.v = [v_mem, self.v[0]];
        self.r = [f_ref, self.r[0]];
        self.y = [f, self.y[0]];
        self.u = [v, self.u[0]];
        self.samples += 1;
        ControlStep {
            v_law,
            v,
            theta: self.theta_used,
            gains: g,
            prediction_error: pred_err,
            model_accepted: accepted,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zoh::zoh_second_order;

    pub(super) fn cfg(prior: Arma2) -> ForceControlConfig {
        ForceControlConfig {
            poles: [0.4, 0.45, 0.65, 0.7],
            t_s: 0.1,
            rls: RlsConfig {
                p0: 1e-2,
                forgetting: 1.0,
                dead_zone: 1.0,
                reset_trace: 1e-5,
            },
            prior,
            v_min: 0.0,
            v_max: 510.0,
            dv_max: 50.0,
        }
    }

    /// Run the controller on ARMA plants switching at `switch` samples.
    fn run(plants: &[Arma2], per: usize, c: ForceControlConfig) -> (Vec<f64>, Vec<f64>) {
        let mut ctl = AdaptiveForceControl::new(c, 200.0).unwrap();
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 200.0, 200.0);
        let (mut ys, mut us) = (vec![], vec![]);
        for m in plants {
            for _ in 0..per {
                let y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
                let s = ctl.step(y, 450.0);
                (y2, y1, u2, u1) = (y1, y, u1, s.v);
                ys.push(y);
                us.push(s.v);
            }
        }
        (ys, us)
    }

    #[test]
    fn regulates_across_gain_changes_from_a_wrong_prior() {
        let t_s = 0.1;
        let plants = [1.7, 3.0, 4.3].map(|g| zoh_second_order(g, 0.15, 0.3, t_s));
        let prior = zoh_second_order(1.0, 0.2, 0.2, t_s);
        let (ys, us) = run(&plants, 150, cfg(prior));
        for (i, g) in [1.7, 3.0, 4.3].iter().enumerate() {
            let y = ys[150 * i + 149];
            let u = us[150 * i + 149];
            assert!((y - 450.0).abs() < 1.0, "segment {i}: force {y}");
            assert!((u - 450.0 / g).abs() < 1.0, "segment {i}: feed {u}");
        }
        for w in us.windows(2) {
            assert!((w[1] - w[0]).abs() <= 50.0 + 1e-9 && (0.0..=510.0).contains(&w[1]));
        }
    }

    #[test]
    fn an_operator_cap_bounds_the_feed_at_once_and_the_loop_recovers_without_windup() {
        let t_s = 0.1;
        let m = zoh_second_order(1.7, 0.15, 0.3, t_s);
        let mut ctl = AdaptiveForceControl::new(cfg(m), 200.0).unwrap();
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 200.0, 200.0);
        let mut step = |ctl: &mut AdaptiveForceControl| {
            let y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
            let v = ctl.step(y, 450.0).v;
            (y2, y1, u2, u1) = (y1, y, u1, v);
            (y, v)
        };
        for _ in 0..100 {
            step(&mut ctl);
        }
        // settled at 450 N ≈ 265 mm/min; the operator caps the feed at 150 mm/min
        ctl.set_v_cap(150.0);
        let (_, v) = step(&mut ctl);
        assert_eq!(
            v, 150.0,
            "the cap is obeyed in one sample, past the rate limit"
        );
        for _ in 0..100 {
            let (_, v) = step(&mut ctl);
            assert!(v <= 150.0);
        }
        // released: back to the reference within the rate limit, no wound-up overshoot
        ctl.set_v_cap(f64::INFINITY);
        let mut peak: f64 = 0.0;
        let mut last = (0.0, 0.0);
        for _ in 0..150 {
            last = step(&mut ctl);
            peak = peak.max(last.0);
        }
        assert!((last.0 - 450.0).abs() < 1.0, "force {}", last.0);
        assert!(peak < 450.0 * 1.1, "overshoot after the cap: {peak} N");
    }

    #[test]
    fn a_lost_process_saturates_the_feed_within_its_limits() {
        let t_s = 0.1;
        let m = zoh_second_order(1.7, 0.15, 0.3, t_s);
        let dead = Arma2 {
            theta1: 0.0,
            theta2: 0.0,
            ..m
        };
        let (_, us) = run(&[m, dead, m], 100, cfg(m));
        assert!(us[100..200].contains(&510.0));
        for w in us.windows(2) {
            assert!((w[1] - w[0]).abs() <= 50.0 + 1e-9 && (0.0..=510.0).contains(&w[1]));
        }
    }

    #[test]
    fn unsaturated_it_is_the_state_space_servo_of_eq_14_to_17() {
        use crate::robust_servo::RobustServo;
        let t_s = 0.1;
        let m = zoh_second_order(1.7, 0.15, 0.3, t_s);
        let mut c = cfg(m);
        c.rls.dead_zone = f64::INFINITY; // no adaptation: fixed gains
        c.v_min = -1e9;
        c.v_max = 1e9;
        c.dv_max = 1e9;
        let g = place_poles(&m, c.poles, t_s).unwrap();
        // both start at the plant's equilibrium at 450 N; the reference steps to 600 N
        let (f0, f_ref) = (450.0, 600.0);
        let v0 = f0 / m.dc_gain();
        let mut ctl = AdaptiveForceControl::new(c, v0).unwrap();
        let eta = (v0 - g.r3 * f0) / (g.k + g.r4 * g.r2 / (1.0 - g.r0));
        let mut servo = RobustServo {
            eta,
            eps: g.r2 * eta / (1.0 - g.r0),
        };
        let (mut y1, mut y2, mut u1, mut u2) = (f0, f0, v0, v0);
        for k in 0..200 {
            let y = -m.phi1 * y1 - m.phi2 * y2 + m.theta1 * u1 + m.theta2 * u2;
            let v_ss = servo.step(&g, y, f_ref, t_s);
            let v_io = ctl.step(y, f_ref).v;
            assert!(
                (v_ss - v_io).abs() < 1e-6 * (1.0 + v_ss.abs()),
                "{k}: {v_ss} vs {v_io}"
            );
            (y2, y1, u2, u1) = (y1, y, u1, v_ss);
        }
        assert!((y1 - f_ref).abs() < 1e-3);
    }

    #[test]
    fn refuses_unstable_or_sign_reversed_models() {
        let m = zoh_second_order(1.7, 0.15, 0.3, 0.1);
        assert!(model_usable(&m));
        assert!(!model_usable(&Arma2 { phi2: 1.2, ..m }));
        assert!(!model_usable(&Arma2 {
            theta1: -m.theta1,
            theta2: -m.theta2,
            ..m
        }));
    }
}
