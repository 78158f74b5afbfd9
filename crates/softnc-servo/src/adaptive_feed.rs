//! Adaptive feed on a running job (paper 003, Fig. 1): the force loop closed on the
//! position cycle. Each cycle the feed motor's phase currents come from the backend
//! ([`ServoBackend::read_phase_currents`]); once per spindle revolution the loop
//! gives a new feed override, which reaches the interpolator through the operator's
//! override path `latency` samples later and is capped by the operator's override.
//!
//! Both ends are here, so that the daemon (position process → interpolator) and the
//! offline simulator apply the same override from the same sample:
//! - [`AdaptiveFeed`]: the position cycle's side (currents in, override out);
//! - [`OverrideSchedule`]: the interpolator's side (the overrides in flight, each
//!   applied from the sample it is due at).

use crate::ServoBackend;
/// What the loop did at the end of a revolution (the force estimate, the override).
pub use softnc_adaptive::Revolution;
use softnc_adaptive::{
    zoh_second_order, ForceCalibration, ForceControlConfig, ForceLoop, ForceLoopConfig,
    ForceLoopControl, PlacementError,
};
use softnc_machine::force::ForceControllerConfig;
use softnc_machine::MachineProfile;

/// Seconds per minute (rpm → revolution period).
const SECONDS_PER_MINUTE: f64 = 60.0;

/// Overrides an [`OverrideSchedule`] holds in flight (a revolution spans many
/// samples; more than this in flight at once means the loop runs faster than the
/// interpolator reads it).
pub const OVERRIDES_IN_FLIGHT: usize = 8;

/// Why adaptive feed cannot run on a machine.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AdaptiveFeedError {
    /// The profile has no `force.adaptive_feed` section.
    #[error("the machine profile has no force.adaptive_feed section (adaptive feed needs a force model, a case and a calibration)")]
    NotConfigured,
    /// The controller's starting model cannot be placed.
    #[error("force.adaptive_feed: the prior model's poles cannot be placed: {0}")]
    Placement(#[from] PlacementError),
}

/// The settings of a force loop over the profile's controller section: one sample
/// per spindle revolution at `spindle_rpm`, the override the feed over
/// `programmed_feed_mm_per_min`; `control`: (poles, reference force N, calibration),
/// or `None` to measure only (the calibration cut).
pub fn loop_config(
    cycle_s: f64,
    k: &ForceControllerConfig,
    spindle_rpm: f64,
    programmed_feed_mm_per_min: f64,
    control: Option<([f64; 4], f64, ForceCalibration)>,
) -> ForceLoopConfig {
    let revolution_s = 1.0 / (spindle_rpm / SECONDS_PER_MINUTE);
    let cycles_per_revolution = ForceLoop::cycles_per_revolution(revolution_s, cycle_s);
    let t_s = cycles_per_revolution as f64 * cycle_s;
    let f_prog = programmed_feed_mm_per_min;
    ForceLoopConfig {
        calibration: control.map(|c| c.2).unwrap_or(ForceCalibration {
            a_per_n: 1.0,
            b_a: 0.0,
        }),
        cycles_per_revolution,
        programmed_feed: f_prog,
        control: control.map(|(poles, force_ref_n, _)| ForceLoopControl {
            config: ForceControlConfig {
                poles,
                t_s,
                rls: k.rls,
                prior: zoh_second_order(
                    k.prior.gain_n_per_mm_min,
                    k.prior.tau_s,
                    k.prior.tau_c_s,
                    t_s,
                ),
                v_min: k.override_min * f_prog,
                v_max: k.override_max * f_prog,
                dv_max: k.override_step_max * f_prog,
            },
            force_ref_n,
        }),
    }
}

/// The force loop of a running job on the position cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct AdaptiveFeed {
    force_loop: ForceLoop,
    feed_axis: usize,
    revolutions: u64,
    last: Option<Revolution>,
}

impl AdaptiveFeed {
    /// The loop of the profile's `force.adaptive_feed` (its case's reference, poles,
    /// spindle speed and programmed feed), override 100 % capped at `cap_frac` (the
    /// operator's override when the job starts).
    pub fn from_profile(
        profile: &MachineProfile,
        cap_frac: f64,
    ) -> Result<Self, AdaptiveFeedError> {
        let force = profile
            .force
            .as_ref()
            .ok_or(AdaptiveFeedError::NotConfigured)?;
        let (a, case) = force
            .adaptive_case()
            .ok_or(AdaptiveFeedError::NotConfigured)?;
        let k = &force.controller;
        let calibration = ForceCalibration {
            a_per_n: a.calibration.a_per_n,
            b_a: a.calibration.b_a,
        };
        let cfg = loop_config(
            profile.interpolation_cycle_s,
            k,
            case.spindle_rpm,
            case.programmed_feed_mm_per_min,
            Some((case.poles.unwrap_or(k.poles), case.force_ref_n, calibration)),
        );
        let mut force_loop = ForceLoop::new(cfg)?;
        force_loop.set_override_cap(cap_frac);
        Ok(AdaptiveFeed {
            force_loop,
            feed_axis: force.feed_axis,
            revolutions: 0,
            last: None,
        })
    }

    /// One position cycle, after the backend's: its feed motor's currents into the
    /// loop; at the end of a revolution, the new override. A backend that does not
    /// report phase currents leaves the override where it is.
    #[inline]
    pub fn cycle<B: ServoBackend>(&mut self, backend: &B) -> Option<Revolution> {
        let ph = backend.read_phase_currents(self.feed_axis)?;
        let rev = self.force_loop.cycle(ph.i_u_a, ph.i_v_a, ph.theta_e_rad)?;
        self.revolutions += 1;
        self.last = Some(rev);
        Some(rev)
    }

    /// The operator's override (fraction) as the loop's ceiling, from now on.
    pub fn set_override_cap(&mut self, cap_frac: f64) {
        self.force_loop.set_override_cap(cap_frac);
    }

    /// The override in force (fraction).
    pub fn override_frac(&self) -> f64 {
        self.force_loop.override_frac()
    }

    /// Revolutions closed so far.
    pub fn revolutions(&self) -> u64 {
        self.revolutions
    }

    /// The last revolution's figures.
    pub fn last(&self) -> Option<Revolution> {
        self.last
    }
}

/// The interpolator's side: overrides computed at a sample, each applied from the
/// sample `latency` later (by then the position cycle has not used it: the
/// interpolator runs at most `latency` samples ahead). Fixed size: no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OverrideSchedule {
    latency: u64,
    /// (first sample, override fraction), oldest first.
    pending: [(u64, f64); OVERRIDES_IN_FLIGHT],
    len: usize,
}

impl OverrideSchedule {
    /// Overrides applied `latency` samples after the sample they were computed at.
    pub fn new(latency: u64) -> Self {
        OverrideSchedule {
            latency,
            pending: [(0, 0.0); OVERRIDES_IN_FLIGHT],
            len: 0,
        }
    }

    /// The loop gave `override_frac` at the cycle that used sample `seq`. When
    /// [`OVERRIDES_IN_FLIGHT`] are in flight already the oldest is dropped (the
    /// newer one supersedes it).
    pub fn push(&mut self, seq: u64, override_frac: f64) {
        if self.len == OVERRIDES_IN_FLIGHT {
            self.pending.copy_within(1.., 0);
            self.len -= 1;
        }
        self.pending[self.len] = (seq + self.latency, override_frac);
        self.len += 1;
    }

    /// Before sample `seq` is made: the newest override due at or before it, taken
    /// out of the schedule.
    pub fn due(&mut self, seq: u64) -> Option<f64> {
        let n = self.pending[..self.len]
            .iter()
            .take_while(|(at, _)| *at <= seq)
            .count();
        if n == 0 {
            return None;
        }
        let value = self.pending[n - 1].1;
        self.pending.copy_within(n..self.len, 0);
        self.len -= n;
        Some(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_override_is_due_latency_samples_after_the_sample_it_was_computed_at() {
        let mut s = OverrideSchedule::new(100);
        s.push(5, 0.8);
        s.push(30, 1.2);
        assert_eq!(s.due(104), None);
        assert_eq!(s.due(105), Some(0.8));
        assert_eq!(s.due(105), None);
        assert_eq!(s.due(129), None);
        // both due at once (a late reader): the newer wins
        s.push(40, 0.5);
        assert_eq!(s.due(200), Some(0.5));
        assert_eq!(s.due(500), None);
    }

    #[test]
    fn a_full_schedule_drops_the_oldest() {
        let mut s = OverrideSchedule::new(10);
        for k in 0..(OVERRIDES_IN_FLIGHT as u64 + 2) {
            s.push(k, k as f64);
        }
        // the two oldest (due at 10 and 11) were dropped
        assert_eq!(s.due(11), None);
        assert_eq!(s.due(12), Some(2.0));
    }

    #[test]
    fn a_profile_without_adaptive_feed_is_refused_by_name() {
        let p = MachineProfile::from_ron_str(
            include_str!("../../../config/machines/default.ron"),
            "default.ron",
        )
        .unwrap();
        let e = AdaptiveFeed::from_profile(&p, 1.0).unwrap_err();
        assert!(e.to_string().contains("force.adaptive_feed"), "{e}");
    }
}
