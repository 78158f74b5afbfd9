//! A plan's samples as the offline simulator takes them (`softnc sim`, the lockstep
//! tests): the interpolator's samples as command samples, its feed override open to
//! adaptive feed ([`softnc_sim::simulate_adaptive`]) as the interpolation process
//! opens it to the position process's force loop.

use softnc_planner::Interpolator;
use softnc_sim::{CommandSample, OverridableSamples};

/// The samples of a plan's interpolator.
pub struct PlanSamples<'p>(pub Interpolator<'p>);

impl Iterator for PlanSamples<'_> {
    type Item = CommandSample;
    fn next(&mut self) -> Option<CommandSample> {
        self.0.next().map(|s| CommandSample {
            pos_mm: softnc_core::Axes::from_xyz(s.pos_mm.0, 0.0),
            motion: s.motion,
            feed_move: s.feed_move,
            outputs: Default::default(),
        })
    }
}

impl OverridableSamples for PlanSamples<'_> {
    fn set_feed_override(&mut self, override_frac: f64) {
        self.0.set_feed_override(override_frac);
    }
}
