//! The stock on the simulated machine's table and the feed motor that pushes the
//! cutter through it (paper 003): each cycle the feed axis's true position gives the
//! depth and material under the cutter (the profile's `force.sim_workpiece`), the
//! milling process its force (eq 2–4), and the PMSM feed motor its phase currents
//! (eq 24–30) — what a drive would report for the force estimate.
//!
//! The cutting force does not act back on the axis: as in the paper's experiments,
//! the position loop holds the feed against it; only the motor's currents carry it.

use crate::milling::{CutProfile, MillingProcess};
use crate::pmsm::PmsmFeedMotor;
use softnc_machine::force::ForceProfile;
use softnc_plant::rng::Rng;
use softnc_servo::PhaseCurrents;

/// Random stream of the phase-current sensors' noise (the one paper 003's
/// experiments draw from).
pub const STREAM_CURRENT_NOISE: u64 = 300;

/// The stock, the cutter in it and the feed motor.
#[derive(Debug, Clone)]
pub struct StockCut {
    feed_axis: usize,
    start_mm: f64,
    cut: CutProfile,
    milling: MillingProcess,
    motor: PmsmFeedMotor,
    /// The feed axis's true position at the end of the last cycle (None: not yet).
    last_pos_mm: Option<f64>,
    /// The last cycle's cutting force (N) and phase currents.
    force_n: f64,
    phases: PhaseCurrents,
}

impl StockCut {
    /// The stock of `force.sim_workpiece` (`None` without one); sensor noise from
    /// `seed` when `noise`.
    pub fn from_profile(force: &ForceProfile, seed: u64, noise: bool) -> Option<Self> {
        let w = force.sim_workpiece.as_ref()?;
        let case = force.case(&w.case)?;
        let tool = force.tool(&case.tool)?;
        Some(StockCut {
            feed_axis: force.feed_axis,
            start_mm: w.start_mm,
            cut: CutProfile::from_case(force, case),
            milling: MillingProcess::new(tool, case.spindle_rpm),
            motor: PmsmFeedMotor::new(&force.motor, Rng::stream(seed, STREAM_CURRENT_NOISE), noise),
            last_pos_mm: None,
            force_n: 0.0,
            phases: PhaseCurrents::default(),
        })
    }

    /// The axis that feeds the cutter through the stock.
    pub fn feed_axis(&self) -> usize {
        self.feed_axis
    }

    /// One cycle of `h_s`: the feed axis ended it at true position `pos_mm` and is
    /// measured at `measured_mm` (the motor's commutation angle comes from the
    /// encoder, as a drive's does).
    pub fn cycle(&mut self, pos_mm: f64, measured_mm: f64, h_s: f64) {
        let v_mm_per_s = match self.last_pos_mm {
            Some(p) => (pos_mm - p) / h_s,
            None => 0.0,
        };
        self.last_pos_mm = Some(pos_mm);
        match self.cut.at(pos_mm - self.start_mm) {
            Some((k_c, depth_mm)) => self.milling.set_cut(k_c, depth_mm),
            None => self.milling.set_cut(0.0, 0.0),
        }
        self.force_n = self.milling.step(v_mm_per_s, h_s);
        let c = self.motor.step(self.force_n, pos_mm, h_s);
        self.phases = PhaseCurrents {
            i_u_a: c.meas_u,
            i_v_a: c.meas_v,
            theta_e_rad: self.motor.electrical_rad(measured_mm),
        };
    }

    /// The cutter is out of the stock and the motor at rest: a fresh start from
    /// position `pos_mm` (homing).
    pub fn reset(&mut self) {
        self.last_pos_mm = None;
        self.force_n = 0.0;
        self.phases = PhaseCurrents::default();
    }

    /// The last cycle's true feed-direction cutting force (N).
    pub fn force_n(&self) -> f64 {
        self.force_n
    }

    /// The last cycle's measured phase currents and electrical angle.
    pub fn phases(&self) -> PhaseCurrents {
        self.phases
    }

    /// Index of the stock's segment under the cutter at feed-axis position `pos_mm`.
    pub fn segment_at(&self, pos_mm: f64) -> Option<usize> {
        self.cut.index_at(pos_mm - self.start_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_machine::MachineProfile;

    fn profile() -> MachineProfile {
        MachineProfile::from_ron_str(
            include_str!("../../../config/machines/mch10-force.ron"),
            "mch10-force.ron",
        )
        .unwrap()
    }

    #[test]
    fn the_force_follows_the_depth_under_the_cutter_and_reaches_the_motor_currents() {
        let p = profile();
        let force = p.force.as_ref().unwrap();
        let mut s = StockCut::from_profile(force, 1, false).unwrap();
        let h = p.interpolation_cycle_s;
        let v_mm_per_s = 200.0 / 60.0;
        // 2 s in each of case I's first two segments (2.0 and 3.5 mm deep)
        let mut peak = [0.0f64; 2];
        let mut iq_peak = [0.0f64; 2];
        for (seg, x0) in [(0, 20.0), (1, 55.0)] {
            s.reset();
            for k in 0..2000 {
                let x = x0 + v_mm_per_s * h * k as f64;
                s.cycle(x, x, h);
                assert_eq!(s.segment_at(x), Some(seg));
                if k > 1000 {
                    peak[seg] = peak[seg].max(s.force_n());
                    // current amplitude (Clarke): |I_q| with I_d = 0
                    let ph = s.phases();
                    let beta = (ph.i_u_a + 2.0 * ph.i_v_a) / 3f64.sqrt();
                    iq_peak[seg] = iq_peak[seg].max(ph.i_u_a.hypot(beta));
                }
            }
        }
        // steady peak K_c·d·v: proportional to the depth
        let ratio = peak[1] / peak[0];
        assert!((ratio - 3.5 / 2.0).abs() < 0.02, "force ratio {ratio}");
        assert!(iq_peak[1] > iq_peak[0], "{iq_peak:?}");
        // out of the stock: no cutting force
        s.reset();
        for k in 0..100 {
            s.cycle(-10.0 + k as f64 * 0.003, 0.0, h);
        }
        assert_eq!(s.force_n(), 0.0);
    }

    #[test]
    fn no_workpiece_no_stock() {
        let mut p = profile();
        let force = p.force.as_mut().unwrap();
        force.sim_workpiece = None;
        assert!(StockCut::from_profile(force, 1, true).is_none());
    }
}
