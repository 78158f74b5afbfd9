//! End milling as the feed axis sees it (paper 003 eq 2–4): the peak feed-direction
//! force of a tooth pass follows τ_c·dF/dt + F = K_c·d·v_a with K_c = k_c/(N·Z) and
//! τ_c = k_c·d/(K_s·N·Z); each tooth's force is a half-sine pulse of that peak over
//! its engagement angle. The depth and material come from the cut's segments along
//! the feed axis.

use softnc_machine::force::{ForceCase, ForceProfile, MillingTool};
use std::f64::consts::{PI, TAU};

/// Seconds per minute (rpm → rev/s).
const SECONDS_PER_MINUTE: f64 = 60.0;

/// Depth and material of the cut along the feed axis, from the start of the cut.
#[derive(Debug, Clone, PartialEq)]
pub struct CutProfile {
    /// (end of the stretch along the feed axis from the start (mm), k_c (N/mm²),
    /// depth (mm)), in order.
    stretches: Vec<(f64, f64, f64)>,
}

impl CutProfile {
    /// From a case of the profile (names resolved; the profile is validated).
    pub fn from_case(force: &ForceProfile, case: &ForceCase) -> Self {
        let mut end = 0.0;
        let stretches = case
            .segments
            .iter()
            .map(|s| {
                end += s.length_mm;
                let k_c = force
                    .material(&s.material)
                    .map(|m| m.k_c_n_per_mm2)
                    .unwrap_or(0.0);
                (end, k_c, s.depth_mm)
            })
            .collect();
        CutProfile { stretches }
    }

    /// Explicit stretches: (end (mm), k_c (N/mm²), depth (mm)).
    pub fn new(stretches: Vec<(f64, f64, f64)>) -> Self {
        CutProfile { stretches }
    }

    /// (k_c, depth) at distance `s_mm` from the start; `None` outside the stock.
    pub fn at(&self, s_mm: f64) -> Option<(f64, f64)> {
        if s_mm < 0.0 {
            return None;
        }
        self.stretches
            .iter()
            .find(|(end, _, _)| s_mm < *end)
            .map(|&(_, k, d)| (k, d))
    }

    /// Index of the stretch at `s_mm` (`None` outside).
    pub fn index_at(&self, s_mm: f64) -> Option<usize> {
        if s_mm < 0.0 {
            return None;
        }
        self.stretches.iter().position(|(end, _, _)| s_mm < *end)
    }

    /// Total length (mm).
    pub fn length_mm(&self) -> f64 {
        self.stretches.last().map(|s| s.0).unwrap_or(0.0)
    }
}

/// The milling process: the peak-force state and the spindle angle.
#[derive(Debug, Clone, PartialEq)]
pub struct MillingProcess {
    flutes: u32,
    engagement_rad: f64,
    stiffness_n_per_mm: f64,
    spindle_rev_per_s: f64,
    spindle_rad: f64,
    peak_n: f64,
    k_c: f64,
    depth_mm: f64,
}

impl MillingProcess {
    /// Tool `tool` at `spindle_rpm`, not cutting.
    pub fn new(tool: &MillingTool, spindle_rpm: f64) -> Self {
        MillingProcess {
            flutes: tool.flutes,
            engagement_rad: tool.engagement_deg.to_radians(),
            stiffness_n_per_mm: tool.stiffness_n_per_mm,
            spindle_rev_per_s: spindle_rpm / SECONDS_PER_MINUTE,
            spindle_rad: 0.0,
            peak_n: 0.0,
            k_c: 0.0,
            depth_mm: 0.0,
        }
    }

    /// Material constant k_c (N/mm²) and depth d (mm) from now on (0 depth: air).
    pub fn set_cut(&mut self, k_c: f64, depth_mm: f64) {
        self.k_c = k_c;
        self.depth_mm = depth_mm;
    }

    /// Spindle revolution period (s).
    pub fn revolution_s(&self) -> f64 {
        1.0 / self.spindle_rev_per_s
    }

    /// Tooth-passing frequency N·Z (Hz).
    pub fn tooth_hz(&self) -> f64 {
        self.spindle_rev_per_s * self.flutes as f64
    }

    /// Static gain K_c·d (N per mm/s), eq 2 and 4.
    pub fn gain_n_per_mm_s(&self) -> f64 {
        self.k_c * self.depth_mm / self.tooth_hz()
    }

    /// Cutting time constant τ_c (s), eq 3.
    pub fn tau_c_s(&self) -> f64 {
        self.k_c * self.depth_mm / (self.stiffness_n_per_mm * self.tooth_hz())
    }

    /// The peak force of a tooth pass now (N).
    pub fn peak_n(&self) -> f64 {
        self.peak_n
    }

    /// Spindle angle (rad, 0 ..< 2π).
    pub fn spindle_rad(&self) -> f64 {
        self.spindle_rad
    }

    /// Teeth's force pattern at the current spindle angle (0..=1 per tooth, summed).
    fn pattern(&self) -> f64 {
        let pitch = TAU / self.flutes as f64;
        (0..self.flutes)
            .map(|i| {
                let a = (self.spindle_rad - i as f64 * pitch).rem_euclid(TAU);
                if a < self.engagement_rad {
                    (PI * a / self.engagement_rad).sin()
                } else {
                    0.0
                }
            })
            .sum()
    }

    /// Advance `h_s` at feed speed `v_mm_per_s` (held over the step); returns the
    /// instantaneous feed-direction force (N).
    pub fn step(&mut self, v_mm_per_s: f64, h_s: f64) -> f64 {
        let target = self.gain_n_per_mm_s() * v_mm_per_s.max(0.0);
        let tau = self.tau_c_s();
        self.peak_n = if tau > 0.0 {
            target + (self.peak_n - target) * (-h_s / tau).exp()
        } else {
            target
        };
        self.spindle_rad = (self.spindle_rad + TAU * self.spindle_rev_per_s * h_s).rem_euclid(TAU);
        self.peak_n * self.pattern()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slot_mill() -> MillingTool {
        MillingTool {
            name: "t".into(),
            diameter_mm: 10.0,
            flutes: 2,
            engagement_deg: 180.0,
            stiffness_n_per_mm: 500.0,
        }
    }

    #[test]
    fn steady_peak_force_is_kc_d_v_over_nz() {
        let mut m = MillingProcess::new(&slot_mill(), 600.0);
        m.set_cut(1000.0, 2.0);
        assert!((m.tooth_hz() - 20.0).abs() < 1e-12);
        assert!((m.tau_c_s() - 1000.0 * 2.0 / (500.0 * 20.0)).abs() < 1e-12);
        let h = 1e-4;
        let mut peak_seen: f64 = 0.0;
        for k in 0..100_000 {
            let f = m.step(5.0, h);
            if k > 90_000 {
                peak_seen = peak_seen.max(f);
            }
        }
        let want = 1000.0 * 2.0 * 5.0 / 20.0;
        assert!((m.peak_n() - want).abs() < 1e-6);
        assert!(
            (peak_seen - want).abs() / want < 1e-3,
            "{peak_seen} vs {want}"
        );
    }

    #[test]
    fn peak_follows_the_first_order_lag_of_eq_2() {
        let mut m = MillingProcess::new(&slot_mill(), 600.0);
        m.set_cut(1000.0, 2.0);
        let tau = m.tau_c_s();
        let h = 1e-3;
        let n = (tau / h).round() as usize;
        for _ in 0..n {
            m.step(5.0, h);
        }
        let want = 500.0 * (1.0 - (-1.0f64).exp());
        assert!((m.peak_n() - want).abs() < 1e-9 * want + 1e-6);
    }

    #[test]
    fn cut_profile_finds_the_stretch() {
        let c = CutProfile::new(vec![(10.0, 1.0, 2.0), (25.0, 2.0, 3.5)]);
        assert_eq!(c.at(-0.1), None);
        assert_eq!(c.at(0.0), Some((1.0, 2.0)));
        assert_eq!(c.at(10.0), Some((2.0, 3.5)));
        assert_eq!(c.index_at(24.9), Some(1));
        assert_eq!(c.at(25.0), None);
    }
}
