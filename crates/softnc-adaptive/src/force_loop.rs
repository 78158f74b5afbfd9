//! The adaptive cutting-force loop of paper 003 (Fig. 1–2) as one type stepped every
//! interpolation cycle: the feed motor's measured phase currents and electrical angle
//! go in (eq 25–27), their peak I_q per spindle revolution through the calibration
//! (eq 31–32) is the measured force, and once per revolution the adaptive robust
//! controller ([`AdaptiveForceControl`]: RLS, pole placement, Davison servo, clamp and
//! rate limit) gives the new feed override — the same override an operator sets.
//!
//! It knows nothing of where the currents come from (the simulated PMSM in
//! `softnc reproduce 003-force`, a drive's current feedback in a controller) nor of
//! the interpolator it steers: the caller applies [`Revolution::override_frac`].
//! Stepping allocates nothing.

use crate::force_control::{AdaptiveForceControl, ControlStep, ForceControlConfig};
use crate::force_estimate::ForceEstimator;
use crate::park::ForceCalibration;
use crate::robust_servo::PlacementError;

/// The controller of a loop: its settings and the reference force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLoopControl {
    /// The adaptive controller's settings (feed in the programmed feed's units;
    /// `t_s` one revolution).
    pub config: ForceControlConfig,
    /// Reference peak force f* (N).
    pub force_ref_n: f64,
}

/// Settings of a loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLoopConfig {
    /// Calibration of the force estimate (eq 32).
    pub calibration: ForceCalibration,
    /// Interpolation cycles per spindle revolution (one control sample).
    pub cycles_per_revolution: u64,
    /// The programmed feed the override scales (e.g. mm/min).
    pub programmed_feed: f64,
    /// The controller; `None` measures only and keeps the override at 100 % (the
    /// calibration cut).
    pub control: Option<ForceLoopControl>,
}

/// What the loop did at the end of a revolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Revolution {
    /// Peak I_q of the revolution (A); 0 without samples.
    pub peak_iq_a: f64,
    /// Estimated peak force (N), the peak I_q through the calibration; 0 without samples.
    pub est_force_n: f64,
    /// Override to apply from now on (fraction).
    pub override_frac: f64,
    /// Feed commanded from now on: override × programmed feed.
    pub feed_cmd: f64,
    /// The controller's step (`None` without a controller).
    pub control: Option<ControlStep>,
}

/// The loop's state.
#[derive(Debug, Clone, PartialEq)]
pub struct ForceLoop {
    estimator: ForceEstimator,
    controller: Option<(AdaptiveForceControl, f64)>,
    cycles_per_revolution: u64,
    programmed_feed: f64,
    cycle: u64,
    override_frac: f64,
}

impl ForceLoop {
    /// A loop at the start of a cut, override 100 %.
    pub fn new(cfg: ForceLoopConfig) -> Result<Self, PlacementError> {
        let controller = match cfg.control {
            Some(c) => Some((
                AdaptiveForceControl::new(c.config, cfg.programmed_feed)?,
                c.force_ref_n,
            )),
            None => None,
        };
        Ok(ForceLoop {
            estimator: ForceEstimator::new(cfg.calibration),
            controller,
            cycles_per_revolution: cfg.cycles_per_revolution.max(1),
            programmed_feed: cfg.programmed_feed,
            cycle: 0,
            override_frac: 1.0,
        })
    }

    /// Interpolation cycles per revolution of spindle period `revolution_s` at cycle
    /// time `cycle_s` (at least one).
    pub fn cycles_per_revolution(revolution_s: f64, cycle_s: f64) -> u64 {
        (revolution_s / cycle_s).round().max(1.0) as u64
    }

    /// One interpolation cycle: measured phase currents i_u, i_v (A) and the
    /// electrical angle n_p·θ (rad). At the end of a revolution, the revolution's
    /// figures and the override to apply.
    pub fn cycle(&mut self, i_u: f64, i_v: f64, theta_e: f64) -> Option<Revolution> {
        self.estimator.push(i_u, i_v, theta_e);
        self.cycle += 1;
        if !self.cycle.is_multiple_of(self.cycles_per_revolution) {
            return None;
        }
        let (peak_iq_a, est_force_n) = match self.estimator.take_revolution_peak_iq() {
            Some(iq) => (iq, self.estimator.calibration().force_n(iq)),
            None => (0.0, 0.0),
        };
        let mut feed_cmd = self.programmed_feed * self.override_frac;
        let mut control = None;
        if let Some((ctl, force_ref_n)) = self.controller.as_mut() {
            let step = ctl.step(est_force_n, *force_ref_n);
            self.override_frac = step.v / self.programmed_feed;
            feed_cmd = step.v;
            control = Some(step);
        }
        Some(Revolution {
            peak_iq_a,
            est_force_n,
            override_frac: self.override_frac,
            feed_cmd,
            control,
        })
    }

    /// The operator's override (fraction) as a ceiling on the loop's: the
    /// controller's feed is capped at it from the next revolution on (see
    /// [`AdaptiveForceControl::set_v_cap`]); the override in force now drops to it
    /// at once when above.
    pub fn set_override_cap(&mut self, cap_frac: f64) {
        if let Some((c, _)) = self.controller.as_mut() {
            c.set_v_cap(cap_frac * self.programmed_feed);
        }
        self.override_frac = self.override_frac.min(cap_frac);
    }

    /// The override in force (fraction).
    pub fn override_frac(&self) -> f64 {
        self.override_frac
    }

    /// Covariance resets of the estimator so far.
    pub fn covariance_resets(&self) -> u64 {
        self.controller
            .as_ref()
            .map_or(0, |(c, _)| c.covariance_resets())
    }

    /// Estimates refused so far (the last good gains were kept).
    pub fn rejected(&self) -> u64 {
        self.controller.as_ref().map_or(0, |(c, _)| c.rejected())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rls::RlsConfig;
    use crate::zoh::zoh_second_order;

    /// Currents of a motor producing I_q = `iq` at angle `theta_e` (i_d = 0).
    fn currents(iq: f64, theta_e: f64) -> (f64, f64) {
        // inverse Park and Clarke of (i_d, i_q) = (0, iq)
        let (alpha, beta) = (-iq * theta_e.sin(), iq * theta_e.cos());
        let i_u = alpha;
        let i_v = -0.5 * alpha + 3f64.sqrt() / 2.0 * beta;
        (i_u, i_v)
    }

    fn cfg(control: Option<ForceLoopControl>) -> ForceLoopConfig {
        ForceLoopConfig {
            calibration: ForceCalibration {
                a_per_n: 0.01,
                b_a: 1.0,
            },
            cycles_per_revolution: 10,
            programmed_feed: 200.0,
            control,
        }
    }

    #[test]
    fn measures_the_peak_force_once_per_revolution() {
        let mut l = ForceLoop::new(cfg(None)).unwrap();
        let mut revs = Vec::new();
        for k in 0..30 {
            // I_q peaks at 5 A in the middle of each revolution: F = (5 − 1)/0.01 = 400 N
            let iq = if k % 10 == 5 { 5.0 } else { 2.0 };
            if let Some(r) = l.cycle(
                currents(iq, 0.3 * k as f64).0,
                currents(iq, 0.3 * k as f64).1,
                0.3 * k as f64,
            ) {
                revs.push(r);
            }
        }
        assert_eq!(revs.len(), 3);
        for r in revs {
            assert!((r.peak_iq_a - 5.0).abs() < 1e-9, "{r:?}");
            assert!((r.est_force_n - 400.0).abs() < 1e-6, "{r:?}");
            assert_eq!(r.override_frac, 1.0);
            assert_eq!(r.feed_cmd, 200.0);
            assert!(r.control.is_none());
        }
    }

    /// Closed around a force process that follows the feed (the ARMA plant of eq 8 in
    /// the revolution domain), the loop settles the measured force at the reference.
    #[test]
    fn closed_around_a_process_it_holds_the_reference() {
        let t_s = 0.1;
        let plant = zoh_second_order(2.0, 0.15, 0.3, t_s);
        let control = ForceLoopControl {
            config: ForceControlConfig {
                poles: [0.4, 0.45, 0.65, 0.7],
                t_s,
                rls: RlsConfig {
                    p0: 1e-2,
                    forgetting: 1.0,
                    dead_zone: 1.0,
                    reset_trace: 1e-5,
                },
                prior: zoh_second_order(1.0, 0.2, 0.2, t_s),
                v_min: 0.0,
                v_max: 510.0,
                dv_max: 50.0,
            },
            force_ref_n: 300.0,
        };
        let c = cfg(Some(control));
        let mut l = ForceLoop::new(c).unwrap();
        let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 200.0, 200.0);
        let mut force = 0.0;
        for rev in 0..200 {
            force = -plant.phi1 * y1 - plant.phi2 * y2 + plant.theta1 * u1 + plant.theta2 * u2;
            let iq = c.calibration.a_per_n * force + c.calibration.b_a;
            let mut out = None;
            for k in 0..10 {
                let th = 0.7 * (rev * 10 + k) as f64;
                let (i_u, i_v) = currents(iq, th);
                out = l.cycle(i_u, i_v, th).or(out);
            }
            let r = out.expect("one revolution per ten cycles");
            assert!((r.est_force_n - force).abs() < 1e-6);
            assert!((0.0..=510.0 / 200.0).contains(&r.override_frac));
            (y2, y1, u2, u1) = (y1, force, u1, r.feed_cmd);
        }
        assert!((force - 300.0).abs() < 1.0, "settled at {force} N");
        assert!((l.override_frac() - 150.0 / 200.0).abs() < 0.01);
    }
}
