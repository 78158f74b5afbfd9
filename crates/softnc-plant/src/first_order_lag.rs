//! First-order-lag servo G(s) = 1/(1 + Ts) from command to table position (paper 004 eq 1),
//! with static friction at reversals (the "stick motion" of 004 Sec. 2.3).

/// One axis of paper 004's TNV-40 seen from the command input: servo and acc/dec as
/// one lag T, the lag e = r − x being the position loop's velocity demand e/T. When
/// the motion reverses, static friction holds the axis until the velocity loop's
/// drive breaks it away: |e + (1/T_i)∫e dt| > `stick_mm`, the integral taken since
/// the axis stopped (a PI velocity loop: proportional part e, integrator (1/T_i)∫e,
/// both in the lag's units). Without integrator (T_i = 0) the lag alone must exceed
/// `stick_mm`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstOrderLag {
    tau_s: f64,
    stick_mm: f64,
    stick_integral_s: f64,
    pos_mm: f64,
    /// Sign of the last motion (0 before the first).
    dir: f64,
    stuck: bool,
    /// (1/T_i)∫e dt since the axis stopped (mm).
    wind_mm: f64,
}

impl FirstOrderLag {
    /// Lag `tau_s`, stick `stick_mm` (0 = none), velocity-loop integral time
    /// `stick_integral_s` (0 = no integrator: the lag alone breaks the axis away).
    pub fn new(tau_s: f64, stick_mm: f64, stick_integral_s: f64) -> Self {
        FirstOrderLag {
            tau_s,
            stick_mm,
            stick_integral_s,
            pos_mm: 0.0,
            dir: 0.0,
            stuck: false,
            wind_mm: 0.0,
        }
    }
    /// At rest at `pos_mm`.
    pub fn reset(&mut self, pos_mm: f64) {
        self.pos_mm = pos_mm;
        self.dir = 0.0;
        self.stuck = false;
        self.wind_mm = 0.0;
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
                if self.stick_integral_s > 0.0 {
                    self.wind_mm += e * h_s / self.stick_integral_s;
                }
                let drive = e + self.wind_mm;
                if drive.abs() <= self.stick_mm {
                    return 0.0;
                }
                self.stuck = false;
            } else if self.dir != 0.0 && dir != self.dir {
                self.stuck = true;
                self.wind_mm = 0.0;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Time stuck (s) after a reversal when the command moves away at `v_mm_s`.
    fn stuck_time(stick_integral_s: f64, v_mm_s: f64) -> f64 {
        let h = 1e-4;
        let mut p = FirstOrderLag::new(0.03, 0.01, stick_integral_s);
        p.reset(0.0);
        p.substep(1e-6, h); // moving +
        let mut t = 0.0;
        let mut cmd = p.pos_mm();
        p.substep(cmd - 1e-9, h); // reverses: stuck
        assert!(p.is_stuck());
        while p.is_stuck() {
            t += h;
            cmd -= v_mm_s * h;
            p.substep(cmd, h);
            assert!(t < 10.0);
        }
        t
    }

    #[test]
    fn lag_alone_breaks_away_at_the_stick() {
        // e = v·t reaches 10 µm: 0.01 s at 1 mm/s
        assert!((stuck_time(0.0, 1.0) - 0.01).abs() < 2e-4);
    }

    #[test]
    fn the_integrator_frees_the_axis_earlier_and_continuously() {
        // e + ∫e/T_i = v t + v t²/(2 T_i) = 10 µm with T_i = 5 ms, v = 1 mm/s:
        // t² + 0.01 t − 1e-4 = 0, t = (√5 − 1)/200 s ≈ 6.18 ms (10 ms without T_i)
        let t = stuck_time(0.005, 1.0);
        assert!((t - 0.00618).abs() < 2e-4, "{t}");
        // a faster command frees it sooner, never later
        assert!(stuck_time(0.005, 2.0) < t);
    }
}
