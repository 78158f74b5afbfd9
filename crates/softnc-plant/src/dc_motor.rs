//! DC servo of open-loop gain K and time constant τ: τ dV/dt + V = K (u − F_d(V)) (paper 001
//! Fig. 2 and Table 2), friction F_d of eq 15 with Karnopp stick–slip, u from an 8-bit DAC.

use crate::config::Friction001;
use crate::stick_slip::{karnopp, Breakaway, Contact};

/// One axis of paper 001's milling machine, integrated exactly over each sub-step
/// (zero-order hold on the net drive).
#[derive(Debug, Clone, PartialEq)]
pub struct DcMotor {
    gain_mm_per_s_per_dac: f64,
    tau_s: f64,
    dac_limit: f64,
    friction: Friction001,
    friction_scale: f64,
    vel_mm_per_s: f64,
    pos_mm: f64,
}

impl DcMotor {
    /// K in mm/s per DAC count, τ, DAC saturation, friction (already scaled by
    /// `friction_scale` = 1 ± its random variation).
    pub fn new(
        gain_mm_per_s_per_dac: f64,
        tau_s: f64,
        dac_limit: f64,
        friction: Friction001,
        friction_scale: f64,
    ) -> Self {
        DcMotor {
            gain_mm_per_s_per_dac,
            tau_s,
            dac_limit,
            friction,
            friction_scale,
            vel_mm_per_s: 0.0,
            pos_mm: 0.0,
        }
    }
    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        self.vel_mm_per_s = 0.0;
        self.pos_mm = pos_mm;
    }
    /// Table position (mm).
    pub fn pos_mm(&self) -> f64 {
        self.pos_mm
    }
    /// Table velocity (mm/s).
    pub fn vel_mm_per_s(&self) -> f64 {
        self.vel_mm_per_s
    }
    /// K actually used (mm/s per DAC count).
    pub fn gain_mm_per_s_per_dac(&self) -> f64 {
        self.gain_mm_per_s_per_dac
    }
    /// τ actually used (s).
    pub fn tau_s(&self) -> f64 {
        self.tau_s
    }
    /// F_d(V) (eq 15) times this axis's variation, DAC counts.
    #[inline]
    pub fn friction_at(&self, vel_mm_per_s: f64) -> f64 {
        self.friction_scale * self.friction.at(vel_mm_per_s)
    }
    /// What the DAC puts out for controller output `u`: rounded to a count, saturated.
    #[inline]
    pub fn dac(&self, u: f64) -> f64 {
        u.round().clamp(-self.dac_limit, self.dac_limit)
    }
    /// Breakaway levels: F_d at V → 0⁺ and V → 0⁻ (eq 15's constant terms).
    pub fn breakaway(&self) -> Breakaway {
        Breakaway {
            pos: self.friction_scale * self.friction.pos_quad[2].abs(),
            neg: self.friction_scale * self.friction.neg_quad[2].abs(),
        }
    }
    /// Advance `h_s` with drive `drive` (DAC output + disturbance, DAC counts).
    /// Returns the net drive after friction.
    #[inline]
    pub fn substep(&mut self, drive: f64, h_s: f64) -> f64 {
        let v0 = self.vel_mm_per_s;
        let net = match karnopp(v0, drive, self.breakaway(), self.friction_at(v0)) {
            Contact::Stuck => {
                self.vel_mm_per_s = 0.0;
                return 0.0;
            }
            Contact::Slip { net } => net,
        };
        let v_inf = self.gain_mm_per_s_per_dac * net;
        let decay = (-h_s / self.tau_s).exp();
        let v1 = v_inf + (v0 - v_inf) * decay;
        if v0 != 0.0 && v1 * v0 < 0.0 {
            // the velocity passes zero inside the step: stop there; Karnopp decides
            // at the next step whether the axis sticks or reverses
            let t_c = -self.tau_s * (v_inf / (v_inf - v0)).ln();
            self.pos_mm +=
                v_inf * t_c + (v0 - v_inf) * self.tau_s * (1.0 - (-t_c / self.tau_s).exp());
            self.vel_mm_per_s = 0.0;
            return net;
        }
        self.pos_mm += v_inf * h_s + (v0 - v_inf) * self.tau_s * (1.0 - decay);
        self.vel_mm_per_s = v1;
        net
    }
}
