//! Paper 000's compensators as one block of the per-axis stack: an outer DOB or
//! MBDA for friction and an inner PDC for the periodic cutting disturbance
//! (Fig. 4: DOB + PDC, Fig. 6: MBDA + PDC). The block sits between the position
//! controller's output u (velocity command, rad/s) and the drive:
//! `u → outer → PDC → v`.
//!
//! **Speed measurement.** The blocks need the motor speed y (rad/s); the position
//! loop has encoder positions only, so y is the position difference per cycle,
//! `y_m(k) = (x(k) − x(k−1)) / T · 2π / lead`. For a velocity loop whose position
//! integrates speed trapezoidally this is `(y(k) + y(k−1))/2`, i.e. the plant the
//! blocks see is `P_meas = P_n (1 + z⁻¹)/2`. The PDC and MBDA are designed on
//! `P_meas` (no inverse needed); the DOB needs a stable inverse and `P_meas` has a
//! zero at z = −1, so the DOB inverts `P_n` and applies `(1 + z⁻¹)/2` to its input
//! path instead ([`Dob::design_with_factor`]): no model error.
//!
//! **Redesign.** The PDC is designed for the tooth frequency when the job starts;
//! when the spindle speed changes, [`PdcDesigner::design`] runs off the real-time
//! path (it allocates), [`AxisCompensation::stage_pdc`] hands the new H over, and
//! the next [`AxisCompensation::step`] swaps it in at the cycle boundary without
//! allocating (the filter history is kept).

use crate::config::compensation::{Compensation, OuterCompensator, PdcConfig};
use crate::discrete_tf::{DiscreteTf, TfError};
use crate::dob::{Dob, DobDesignError};
use crate::mbda::{Mbda, MbdaDesignError};
use crate::pdc::{self, Pdc, PdcDesign, PdcDesignError};

/// Why an axis's compensation cannot be designed.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum CompensationError {
    /// The plant model is not a usable transfer function.
    #[error("plant model: {0}")]
    Model(#[from] TfError),
    /// The DOB design failed.
    #[error("DOB: {0}")]
    Dob(#[from] DobDesignError),
    /// The MBDA design failed.
    #[error("MBDA: {0}")]
    Mbda(#[from] MbdaDesignError),
    /// The PDC design failed (eq 11–13 or its inputs).
    #[error("PDC: {0}")]
    Pdc(#[from] PdcDesignError),
    /// A PDC is configured but no disturbance frequency is known (spindle off).
    #[error("PDC configured but the spindle's tooth frequency is unknown")]
    NoFrequency,
    /// Compensation needs a velocity-loop plant (paper 000).
    #[error("compensation needs a velocity-loop plant model")]
    Plant,
}

/// The measurement factor (1 + z⁻¹)/2 of the position-difference speed.
pub const MEASUREMENT_FACTOR: [f64; 2] = [0.5, 0.5];

/// `P_meas = P_n (1 + z⁻¹)/2`: the plant as seen through the position-difference
/// speed measurement (see the module docs).
pub fn measured_model(p_n: &DiscreteTf) -> DiscreteTf {
    p_n.series(&DiscreteTf::fir(MEASUREMENT_FACTOR.to_vec()).expect("two finite taps"))
}

/// What redesigns the PDC of one axis: its settings and model. Cloneable, so a
/// design thread can own one.
#[derive(Debug, Clone, PartialEq)]
pub struct PdcDesigner {
    config: PdcConfig,
    model: DiscreteTf,
    cycle_s: f64,
}

impl PdcDesigner {
    /// Design H for tooth frequency `fd_hz` (allocates; off the real-time path).
    pub fn design(&self, fd_hz: f64) -> Result<PdcDesign, PdcDesignError> {
        pdc::design(&self.config, &self.model, self.cycle_s, fd_hz)
    }
}

#[derive(Debug, Clone)]
enum Outer {
    None,
    Dob(Dob),
    Mbda(Mbda),
}

/// The compensation block of one axis, ready to step.
#[derive(Debug, Clone)]
pub struct AxisCompensation {
    outer: Outer,
    pdc: Option<Pdc>,
    designer: Option<PdcDesigner>,
    pdc_fd_hz: f64,
    staged: Option<(Vec<f64>, f64)>,
    retired: Option<Vec<f64>>,
    rad_per_mm: f64,
    cycle_s: f64,
    last_pos_mm: f64,
    speed_rad_s: f64,
}

impl PartialEq for AxisCompensation {
    /// Same settings and design (the running state is not compared).
    fn eq(&self, other: &Self) -> bool {
        self.designer == other.designer
            && self.pdc_fd_hz == other.pdc_fd_hz
            && self.rad_per_mm == other.rad_per_mm
            && self.cycle_s == other.cycle_s
            && std::mem::discriminant(&self.outer) == std::mem::discriminant(&other.outer)
    }
}

impl AxisCompensation {
    /// Design the block for velocity-loop model `p_n` (velocity command → motor
    /// speed, rad/s, discrete at `cycle_s`), a screw of `lead_mm` per revolution,
    /// and tooth frequency `fd_hz` (needed when a PDC is configured).
    pub fn design(
        cfg: &Compensation,
        p_n: &DiscreteTf,
        cycle_s: f64,
        lead_mm: f64,
        fd_hz: Option<f64>,
    ) -> Result<AxisCompensation, CompensationError> {
        let p_meas = measured_model(p_n);
        let outer = match &cfg.outer {
            OuterCompensator::None => Outer::None,
            OuterCompensator::Dob(d) => Outer::Dob(Dob::design_with_factor(
                d,
                p_n,
                &MEASUREMENT_FACTOR,
                cycle_s,
            )?),
            OuterCompensator::Mbda(m) => Outer::Mbda(Mbda::design(m, &p_meas, cycle_s)?),
        };
        let (pdc, designer, pdc_fd_hz) = match &cfg.pdc {
            None => (None, None, 0.0),
            Some(pc) => {
                let designer = PdcDesigner {
                    config: pc.clone(),
                    model: p_meas,
                    cycle_s,
                };
                let fd = fd_hz.ok_or(CompensationError::NoFrequency)?;
                let d = designer.design(fd)?;
                (Some(Pdc::new(&d)), Some(designer), fd)
            }
        };
        Ok(AxisCompensation {
            outer,
            pdc,
            designer,
            pdc_fd_hz,
            staged: None,
            retired: None,
            rad_per_mm: std::f64::consts::TAU / lead_mm,
            cycle_s,
            last_pos_mm: 0.0,
            speed_rad_s: 0.0,
        })
    }

    /// The PDC's designer, to redesign off the real-time path (`None` without PDC).
    pub fn pdc_designer(&self) -> Option<&PdcDesigner> {
        self.designer.as_ref()
    }

    /// The tooth frequency the running PDC was designed for (Hz; 0 without PDC).
    pub fn pdc_fd_hz(&self) -> f64 {
        self.pdc_fd_hz
    }

    /// Hand over a redesigned PDC; it is swapped in at the start of the next step.
    pub fn stage_pdc(&mut self, design: PdcDesign) {
        self.stage_taps(design.h_taps, design.fd_hz);
    }

    /// Stage the taps of H = L·W designed for `fd_hz` (moved in: no allocation);
    /// they are swapped in at the start of the next [`AxisCompensation::step`].
    pub fn stage_taps(&mut self, h_taps: Vec<f64>, fd_hz: f64) {
        self.staged = Some((h_taps, fd_hz));
    }

    /// The taps replaced by the last swap, to be dropped off the real-time path.
    pub fn take_retired(&mut self) -> Option<Vec<f64>> {
        self.retired.take()
    }

    /// Back to rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        match &mut self.outer {
            Outer::None => {}
            Outer::Dob(d) => d.reset(),
            Outer::Mbda(m) => m.reset(),
        }
        if let Some(p) = &mut self.pdc {
            p.reset();
        }
        self.last_pos_mm = pos_mm;
        self.speed_rad_s = 0.0;
    }

    /// The measured motor speed of the last step (rad/s).
    pub fn speed_rad_s(&self) -> f64 {
        self.speed_rad_s
    }

    /// One cycle: controller output `u` (rad/s) and measured position → drive
    /// command v (rad/s). Does not allocate.
    #[inline]
    pub fn step(&mut self, u: f64, measured_mm: f64) -> f64 {
        if let Some((mut taps, fd_hz)) = self.staged.take() {
            if let Some(p) = &mut self.pdc {
                if p.swap_h_taps(&mut taps).is_ok() {
                    self.pdc_fd_hz = fd_hz;
                }
            }
            self.retired = Some(taps);
        }
        let y = (measured_mm - self.last_pos_mm) / self.cycle_s * self.rad_per_mm;
        self.last_pos_mm = measured_mm;
        self.speed_rad_s = y;
        let u1 = match &mut self.outer {
            Outer::None => u,
            Outer::Dob(d) => d.step(u, y),
            Outer::Mbda(m) => m.step(u, y),
        };
        match &mut self.pdc {
            Some(p) => p.step(u1, y),
            None => u1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::compensation::{DobConfig, MbdaConfig};
    use crate::discrete_tf::TfFilter;
    use std::f64::consts::TAU;

    const T: f64 = 0.001;
    const LEAD_MM: f64 = 10.0;

    fn pnx() -> DiscreteTf {
        DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
    }

    fn pdc_cfg() -> PdcConfig {
        softnc_core::ron_file::parse_ron::<PdcConfig>(
            include_str!("../../../config/pdc/paper000-canceller.ron"),
            "config/pdc/paper000-canceller.ron",
        )
        .unwrap()
    }

    /// Position-loop run of the nominal velocity loop with a sinusoidal disturbance
    /// of `fd_true` at the plant input; returns the steady-state position error
    /// amplitude (mm). Positions integrate speed trapezoidally, as the simulator does.
    fn ripple_mm(comp: Option<&mut AxisCompensation>, fd_true: f64, restage: Option<f64>) -> f64 {
        let mut plant = TfFilter::new(&pnx());
        let mm_per_rad = LEAD_MM / TAU;
        let (mut x, mut y_prev, mut amp) = (0.0, 0.0, 0.0_f64);
        let mut comp = comp;
        if let Some(c) = comp.as_deref_mut() {
            c.reset(0.0);
        }
        for k in 0..6000 {
            if k == 1000 {
                if let (Some(c), Some(fd)) = (comp.as_deref_mut(), restage) {
                    let d = c.pdc_designer().unwrap().design(fd).unwrap();
                    c.stage_pdc(d);
                }
            }
            let u = -40.0 * x / mm_per_rad;
            let v = match comp.as_deref_mut() {
                Some(c) => c.step(u, x),
                None => u,
            };
            plant.step(v + 0.1 * (TAU * fd_true * T * k as f64).sin());
            let y_next = plant.pending_output();
            x += 0.5 * (y_prev + y_next) * T * mm_per_rad;
            y_prev = y_next;
            if k > 5000 {
                amp = amp.max(x.abs());
            }
        }
        amp
    }

    fn cfg(outer: OuterCompensator, pdc: bool) -> Compensation {
        Compensation {
            outer,
            pdc: pdc.then(pdc_cfg),
        }
    }

    #[test]
    fn pdc_removes_the_periodic_error_behind_dob_and_mbda() {
        let none = ripple_mm(None, 50.0, None);
        let dob = OuterCompensator::Dob(DobConfig {
            order_k: 3,
            relative_degree_r: 1,
            tau_s: 0.002,
        });
        let mbda = OuterCompensator::Mbda(MbdaConfig {
            kp: 2.0,
            ki_per_s: 200.0,
        });
        for outer in [OuterCompensator::None, dob, mbda] {
            let mut without =
                AxisCompensation::design(&cfg(outer, false), &pnx(), T, LEAD_MM, Some(50.0))
                    .unwrap();
            let mut with =
                AxisCompensation::design(&cfg(outer, true), &pnx(), T, LEAD_MM, Some(50.0))
                    .unwrap();
            let e_without = ripple_mm(Some(&mut without), 50.0, None);
            let e_with = ripple_mm(Some(&mut with), 50.0, None);
            assert!(
                e_with < 0.2 * e_without,
                "{outer:?}: {e_with} vs {e_without} (no compensation {none})"
            );
        }
    }

    #[test]
    fn redesign_is_swapped_in_at_a_cycle_boundary() {
        let c = cfg(OuterCompensator::None, true);
        // designed for 50 Hz, the spindle runs at 60 Hz: poor
        let mut stale = AxisCompensation::design(&c, &pnx(), T, LEAD_MM, Some(50.0)).unwrap();
        let e_stale = ripple_mm(Some(&mut stale), 60.0, None);
        // the same, redesigned for 60 Hz after 1 s and swapped in
        let mut redesigned = AxisCompensation::design(&c, &pnx(), T, LEAD_MM, Some(50.0)).unwrap();
        let e_new = ripple_mm(Some(&mut redesigned), 60.0, Some(60.0));
        assert_eq!(redesigned.pdc_fd_hz(), 60.0);
        assert!(redesigned.take_retired().is_some());
        let mut direct = AxisCompensation::design(&c, &pnx(), T, LEAD_MM, Some(60.0)).unwrap();
        let e_direct = ripple_mm(Some(&mut direct), 60.0, None);
        assert!(
            (e_new - e_direct).abs() <= 0.05 * e_direct + 1e-9,
            "{e_new} vs {e_direct}"
        );
        assert!(e_new < 0.5 * e_stale, "{e_new} vs stale {e_stale}");
    }

    #[test]
    fn pdc_without_a_frequency_is_refused() {
        assert_eq!(
            AxisCompensation::design(&cfg(OuterCompensator::None, true), &pnx(), T, LEAD_MM, None)
                .unwrap_err(),
            CompensationError::NoFrequency
        );
    }
}
