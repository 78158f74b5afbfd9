//! First-order-lag servo G(s) = 1/(1 + Ts) from command to table position (paper 004 eq 1),
//! with static friction at reversals (the "stick motion" of 004 Sec. 2.3).

/// One axis of paper 004's TNV-40 seen from the command input: servo and acc/dec as
/// one lag T. When the motion reverses, the axis stays until the lag |r − x| exceeds
/// `stick_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstOrderLag {
    tau_s: f64,
    stick_mm: f64,
    pos_mm: f64,
    /// Sign of the last motion (0 before the first).
    dir: f64,
    stuck: bool,
}

impl FirstOrderLag {
    /// Lag `tau_s`, stick `stick_mm` (0 = none).
    pub fn new(tau_s: f64, stick_mm: f64) -> Self {
        FirstOrderLag {
            tau_s,
            stick_mm,
            pos_mm: 0.0,
            dir: 0.0,
            stuck: false,
        }
    }
    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        self.pos_mm = pos_mm;
        self.dir = 0.0;
        self.stuck = false;
    }
    /// Table position (mm).
    pub fn pos_mm(&self) -> f64 {
        self.pos_mm
    }
    /// True while held by static friction after a reversal.
    pub fn is_stuck(&self) -> bool {
        self.stuck
    }
    /// Advance `h_s` towards command `cmd_mm` (held over the step: zero-order hold).
    /// Returns the velocity demand (r − x)/T (mm/s).
    #[inline]
    pub fn substep(&mut self, cmd_mm: f64, h_s: f64) -> f64 {
        let e = cmd_mm - self.pos_mm;
        if self.stick_mm > 0.0 && e != 0.0 {
            let dir = e.signum();
            if self.stuck {
                if e.abs() <= self.stick_mm {
                    return 0.0;
                }
                self.stuck = false;
            } else if self.dir != 0.0 && dir != self.dir {
                self.stuck = true;
                self.dir = dir;
                return 0.0;
            }
            self.dir = dir;
        }
        // exact response of the lag to a held command
        self.pos_mm = cmd_mm - e * (-h_s / self.tau_s).exp();
        e / self.tau_s
    }
}
