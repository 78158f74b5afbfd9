//! The per-axis controller stack: command shaping → feedback → feedforward →
//! compensators, one `step` per position cycle, nothing allocated.
//!
//! Later blocks (fuzzy feedback, DOB, MBDA, PDC, learning corrections) slot in as
//! further variants of [`Feedback`] and fields of [`AxisController`].

use crate::compensation::AxisCompensation;
use crate::config::ControllerConfig;
use crate::fuzzy::FuzzyController;
use crate::pid::IncrementalPid;

/// The feedback law.
#[derive(Debug, Clone, PartialEq)]
pub enum Feedback {
    /// P, PI or PID in incremental form (001 eq 14).
    Pid(IncrementalPid),
    /// Fuzzy-logic PD plus integral (001 eq 2–8), on the error in its input units.
    Fuzzy(Box<FuzzyController>),
}

/// One axis's controller.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisController {
    /// Feedback law on the position error.
    pub feedback: Feedback,
    /// Velocity feedforward gain (output per mm/s).
    pub vff: f64,
    /// Acceleration feedforward gain (output per mm/s²).
    pub aff: f64,
    /// Output limit (±); 0 = none.
    pub limit: f64,
    /// Disturbance compensation after feedback and feedforward (paper 000 DOB/MBDA
    /// + PDC), designed by the caller from the profile; `None` = off.
    pub compensation: Option<Box<AxisCompensation>>,
    cycle_s: f64,
    cmd1: f64,
    cmd2: f64,
    primed: u8,
}

/// What one controller step produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControlOutput {
    /// Controller output (plant input units).
    pub u: f64,
    /// Position error used (mm).
    pub error_mm: f64,
    /// Command velocity estimate (mm/s).
    pub cmd_vel_mm_s: f64,
}

impl AxisController {
    /// From the profile's settings, at cycle `cycle_s`.
    pub fn new(cfg: &ControllerConfig, cycle_s: f64) -> Self {
        AxisController {
            feedback: match &cfg.fuzzy {
                Some(f) => Feedback::Fuzzy(Box::new(FuzzyController::new(f))),
                None => Feedback::Pid(IncrementalPid::new(
                    cfg.kp,
                    cfg.ki,
                    cfg.kd,
                    cfg.output_limit,
                )),
            },
            vff: cfg.vff,
            aff: cfg.aff,
            limit: cfg.output_limit,
            compensation: None,
            cycle_s,
            cmd1: 0.0,
            cmd2: 0.0,
            primed: 0,
        }
    }

    /// Back to rest at position `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        match &mut self.feedback {
            Feedback::Pid(p) => p.reset(),
            Feedback::Fuzzy(f) => f.reset(0.0),
        }
        if let Some(c) = &mut self.compensation {
            c.reset(pos_mm);
        }
        self.cmd1 = pos_mm;
        self.cmd2 = pos_mm;
        self.primed = 2;
    }

    /// One cycle: command and measured position in, output out.
    pub fn step(&mut self, cmd_mm: f64, measured_mm: f64) -> ControlOutput {
        if self.primed < 2 {
            self.cmd2 = if self.primed == 0 { cmd_mm } else { self.cmd1 };
            self.cmd1 = cmd_mm;
            self.primed = 2;
        }
        let t = self.cycle_s;
        let vel = (cmd_mm - self.cmd1) / t;
        let acc = (cmd_mm - 2.0 * self.cmd1 + self.cmd2) / (t * t);
        let e = cmd_mm - measured_mm;
        let fb = match &mut self.feedback {
            Feedback::Pid(p) => p.step(e),
            Feedback::Fuzzy(f) => f.step_mm(e),
        };
        let mut u = fb + self.vff * vel + self.aff * acc;
        if self.limit > 0.0 {
            u = u.clamp(-self.limit, self.limit);
        }
        if let Some(c) = &mut self.compensation {
            u = c.step(u, measured_mm);
            if self.limit > 0.0 {
                u = u.clamp(-self.limit, self.limit);
            }
        }
        self.cmd2 = self.cmd1;
        self.cmd1 = cmd_mm;
        ControlOutput {
            u,
            error_mm: e,
            cmd_vel_mm_s: vel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feedforward_of_a_ramp() {
        let cfg = ControllerConfig {
            kp: 0.0,
            ki: 0.0,
            kd: 0.0,
            vff: 2.0,
            aff: 0.0,
            output_limit: 0.0,
            fuzzy: None,
        };
        let mut c = AxisController::new(&cfg, 0.001);
        c.reset(0.0);
        let mut u = 0.0;
        for k in 1..10 {
            u = c.step(k as f64 * 0.01, k as f64 * 0.01).u;
        }
        assert!((u - 20.0).abs() < 1e-9, "v = 10 mm/s, vff 2 → {u}");
    }
}
