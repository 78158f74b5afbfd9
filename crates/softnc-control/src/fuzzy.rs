//! Fuzzy-logic position controller with integral term (paper 001, eq 2–8 and 13).
//!
//! PD-type fuzzy map plus an integrator (eq 3):
//!
//! ```text
//! u(k)   = F[e(k), Δe(k)] + u_I(k),   Δe(k) = e(k) − e(k−1)
//! u_I(k) = u_I(k−1) + K_I e(k)
//! ```
//!
//! F fuzzifies e and Δe over sets whose membership functions are triangles with their
//! feet on the neighbours' centres (the two end sets are trapezoids that saturate), so
//! an input belongs to at most two sets and at most four rules fire. Rule strength is
//! Mamdani min, `w_ij = min(μ_Ai(e), μ_Bj(Δe))` (eq 6), and the output is the
//! simplified centroid `u = Σ w_l C_l / Σ w_l` over the fired rules (eq 8), C_l being
//! the centre of the rule's output set (Table 3 gives centres, and Table 4's
//! equivalent gains follow from them; see `docs/controllers.md`). The sum u is
//! saturated to the DAC range (8-bit in the paper); u_I is held inside the same range.
//!
//! Everything is precomputed into fixed-size arrays by [`FuzzyController::new`]; the
//! cycle method [`FuzzyController::step`] allocates nothing.
//!
//! ```
//! use softnc_control::fuzzy::{FuzzyConfig, FuzzyController};
//! // paper 001's controller lives in a file, not in code
//! let cfg = FuzzyConfig::from_ron_str(
//!     include_str!("../../../config/fuzzy/paper001.ron"), "paper001.ron").unwrap();
//! let mut flc = FuzzyController::new(&cfg);
//! // e = 7 BLU (PS) and Δe = 0: rule (PS, ZR) → PS, centre 15, plus K_I·e = 0.7.
//! flc.reset(7.0);
//! let u = flc.step(7.0);
//! assert!((u - 15.7).abs() < 1e-12);
//! ```

pub use crate::config::fuzzy::{FuzzyConfig, FuzzyVariable, MAX_SETS};

/// Triangular/trapezoidal partition of one input, precomputed.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Partition {
    n: usize,
    c: [f64; MAX_SETS],
    /// 1 / (c[k+1] − c[k]).
    inv_gap: [f64; MAX_SETS],
}

impl Partition {
    fn new(centres: &[f64]) -> Self {
        let n = centres.len();
        let mut c = [0.0; MAX_SETS];
        let mut inv_gap = [0.0; MAX_SETS];
        c[..n].copy_from_slice(centres);
        for k in 0..n - 1 {
            inv_gap[k] = 1.0 / (c[k + 1] - c[k]);
        }
        Partition { n, c, inv_gap }
    }

    /// (k, μ_k(x), μ_{k+1}(x)): x lies between centres k and k+1; memberships of all
    /// other sets are zero. Outside the universe the end set holds membership 1.
    fn fuzzify(&self, x: f64) -> (usize, f64, f64) {
        let last = self.n - 1;
        if x <= self.c[0] {
            return (0, 1.0, 0.0);
        }
        if x >= self.c[last] {
            return (last - 1, 0.0, 1.0);
        }
        let mut k = 0;
        while k + 1 < last && x >= self.c[k + 1] {
            k += 1;
        }
        let hi = (x - self.c[k]) * self.inv_gap[k];
        (k, 1.0 - hi, hi)
    }
}

/// The fuzzy controller, ready to run: precomputed tables and the two state values.
#[derive(Debug, Clone, PartialEq)]
pub struct FuzzyController {
    e: Partition,
    de: Partition,
    /// Output-set centre of rule (i, j).
    rule_out: [[f64; MAX_SETS]; MAX_SETS],
    k_i: f64,
    u_min: f64,
    u_max: f64,
    input_unit_mm: f64,
    e_prev: f64,
    u_i: f64,
}

impl FuzzyController {
    /// Precompute from a configuration. The configuration must have passed
    /// [`FuzzyConfig::validate_at`] (the loaders do this); otherwise this panics.
    pub fn new(cfg: &FuzzyConfig) -> Self {
        if let Err(e) = cfg.validate_at("<FuzzyController::new>", "") {
            panic!("invalid fuzzy configuration: {e}");
        }
        let mut rule_out = [[0.0; MAX_SETS]; MAX_SETS];
        for (i, row) in cfg.rules.iter().enumerate() {
            for (j, name) in row.iter().enumerate() {
                let k = cfg
                    .u
                    .names
                    .iter()
                    .position(|n| n == name)
                    .expect("validated");
                rule_out[i][j] = cfg.u.centres[k];
            }
        }
        FuzzyController {
            e: Partition::new(&cfg.e.centres),
            de: Partition::new(&cfg.de.centres),
            rule_out,
            k_i: cfg.k_i,
            u_min: cfg.u_min,
            u_max: cfg.u_max,
            input_unit_mm: cfg.input_unit_mm,
            e_prev: 0.0,
            u_i: 0.0,
        }
    }

    /// The fuzzy map F[e, Δe] (eq 4–8) without integral or saturation, in config units.
    #[inline]
    pub fn surface(&self, e: f64, de: f64) -> f64 {
        let (i, a0, a1) = self.e.fuzzify(e);
        let (j, b0, b1) = self.de.fuzzify(de);
        // Mamdani min (eq 6) on the four candidate rules; zero weights drop out.
        let w00 = a0.min(b0);
        let w01 = a0.min(b1);
        let w10 = a1.min(b0);
        let w11 = a1.min(b1);
        let r0 = &self.rule_out[i];
        let r1 = &self.rule_out[i + 1];
        // Simplified centroid (eq 8). Memberships form a partition of unity, so one of
        // a0, a1 and one of b0, b1 is >= 0.5 and the denominator is >= 0.5.
        let num = w00 * r0[j] + w01 * r0[j + 1] + w10 * r1[j] + w11 * r1[j + 1];
        num / (w00 + w01 + w10 + w11)
    }

    /// One cycle: error e(k) in input units (BLU) → saturated output (eq 3).
    /// Allocates nothing. A NaN error gives a NaN output.
    #[inline]
    pub fn step(&mut self, e: f64) -> f64 {
        let de = e - self.e_prev;
        self.e_prev = e;
        self.u_i = (self.u_i + self.k_i * e).clamp(self.u_min, self.u_max);
        (self.surface(e, de) + self.u_i).clamp(self.u_min, self.u_max)
    }

    /// One cycle with the error in mm (divided by `input_unit_mm`).
    #[inline]
    pub fn step_mm(&mut self, e_mm: f64) -> f64 {
        self.step(e_mm / self.input_unit_mm)
    }

    /// Clear the integrator and set e(k−1) (so the first Δe is `e_prev − e_prev`-based).
    pub fn reset(&mut self, e_prev: f64) {
        self.e_prev = e_prev;
        self.u_i = 0.0;
    }

    /// The integral term u_I(k) after the last step.
    pub fn integral(&self) -> f64 {
        self.u_i
    }

    /// Length of one input unit, mm.
    pub fn input_unit_mm(&self) -> f64 {
        self.input_unit_mm
    }

    /// Sector bounds of the surface (eq 13) and the equivalent P and D gains.
    ///
    /// The surface is split as eq 11–12 suggest: u₁(e) = F(e, 0) and
    /// u₂ = F(e, Δe) − F(e, 0). K₁ bounds u₁/e over e ≠ 0, K₂ bounds u₂/Δe over
    /// Δe ≠ 0, both inside the universe of discourse (end centres). `grid` chooses
    /// where the surface is sampled.
    pub fn equivalent_gains(&self, grid: SectorGrid) -> EquivalentGains {
        let mut k1 = (f64::INFINITY, f64::NEG_INFINITY);
        let mut k2 = (f64::INFINITY, f64::NEG_INFINITY);
        let mut visit = |e: f64, de: f64| {
            let u1 = self.surface(e, 0.0);
            if e.abs() > 1e-12 {
                let g = u1 / e;
                k1 = (k1.0.min(g), k1.1.max(g));
            }
            if de.abs() > 1e-12 {
                let g = (self.surface(e, de) - u1) / de;
                k2 = (k2.0.min(g), k2.1.max(g));
            }
        };
        match grid {
            SectorGrid::Centres => {
                for &e in &self.e.c[..self.e.n] {
                    for &de in &self.de.c[..self.de.n] {
                        visit(e, de);
                    }
                }
            }
            SectorGrid::Dense(steps) => {
                let steps = steps.max(2);
                let lin = |p: &Partition, k: usize| {
                    let (lo, hi) = (p.c[0], p.c[p.n - 1]);
                    lo + (hi - lo) * k as f64 / steps as f64
                };
                for a in 0..=steps {
                    for b in 0..=steps {
                        visit(lin(&self.e, a), lin(&self.de, b));
                    }
                }
            }
        }
        EquivalentGains {
            k1_min: k1.0,
            k1_max: k1.1,
            // + 0.0 turns a −0 (a zero step divided by a negative Δe) into 0.
            k2_min: k2.0 + 0.0,
            k2_max: k2.1,
            p: 0.5 * (k1.0 + k1.1),
            d: 0.5 * k2.1,
        }
    }
}

/// Where [`FuzzyController::equivalent_gains`] samples the surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SectorGrid {
    /// Only at the membership centres, where F equals the rule table's output centres
    /// (the rule-table reading of eq 13).
    Centres,
    /// A uniform (steps+1)² grid over the universe of e and Δe: the continuous surface,
    /// including the steeper patches that min inference makes between centres.
    Dense(usize),
}

/// Sector bounds (eq 13) and the equivalent gains derived from them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EquivalentGains {
    /// Smallest u₁/e.
    pub k1_min: f64,
    /// Largest u₁/e.
    pub k1_max: f64,
    /// Smallest u₂/Δe.
    pub k2_min: f64,
    /// Largest u₂/Δe.
    pub k2_max: f64,
    /// Equivalent proportional gain (K₁min + K₁max)/2.
    pub p: f64,
    /// Equivalent derivative gain K₂max/2 (the paper's K₂min is 0).
    pub d: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER_RON: &str = include_str!("../../../config/fuzzy/paper001.ron");

    /// Paper 001's controller, from its file.
    fn paper_cfg() -> FuzzyConfig {
        FuzzyConfig::from_ron_str(PAPER_RON, "paper001.ron").unwrap()
    }

    fn paper() -> FuzzyController {
        FuzzyController::new(&paper_cfg())
    }

    /// The file's rule base, 7×7 (rows e = NL..PL, columns Δe = NL..PL).
    fn paper_rules() -> Vec<Vec<String>> {
        paper_cfg().rules
    }

    fn set_index(name: &str) -> usize {
        paper_cfg().u.names.iter().position(|s| s == name).unwrap()
    }

    #[test]
    fn rule_table_keeps_every_printed_entry() {
        // Table 1 as extracted: six entries per row (SEEDS.md). Each printed row must
        // be the reconstructed row with exactly one column removed: column 0 (Δe = NL).
        let printed: [[&str; 6]; 7] = [
            ["NL", "NL", "NL", "NL", "NL", "NL"],
            ["NL", "NM", "NM", "NS", "NS", "NS"],
            ["NM", "NM", "NS", "NS", "NS", "ZR"],
            ["ZR", "ZR", "ZR", "ZR", "ZR", "ZR"],
            ["PS", "PS", "PS", "PM", "PM", "PL"],
            ["PS", "PS", "PM", "PM", "PL", "PL"],
            ["PL", "PL", "PL", "PL", "PL", "PL"],
        ];
        let rules = paper_rules();
        for (i, row) in printed.iter().enumerate() {
            assert_eq!(&rules[i][1..], &row[..], "row {i}");
        }
    }

    #[test]
    fn rule_table_is_odd_symmetric_and_monotone() {
        let rules = paper_rules();
        let n = 7;
        for i in 0..n {
            for j in 0..n {
                let u = set_index(rules[i][j].as_str()) as i32 - 3;
                let m = set_index(rules[n - 1 - i][n - 1 - j].as_str()) as i32 - 3;
                assert_eq!(u, -m, "u(-e,-de) != -u(e,de) at ({i},{j})");
                if j + 1 < n {
                    let next = set_index(rules[i][j + 1].as_str());
                    // Positive e: a growing error (larger Δe) needs a larger command;
                    // negative e: larger Δe means converging, so a smaller |command|.
                    // Both read as: non-decreasing along Δe.
                    assert!(next >= set_index(rules[i][j].as_str()), "row {i} col {j}");
                }
                if i + 1 < n {
                    assert!(
                        set_index(rules[i + 1][j].as_str()) >= set_index(rules[i][j].as_str()),
                        "col {j} row {i}"
                    );
                }
            }
        }
    }

    #[test]
    fn principle_small_diverging_beats_large_converging() {
        // "a small error not converging needs a larger command than a large error
        // decreasing fast": (PS, PL) > (PM, NL) and mirrored.
        let rules = paper_rules();
        assert!(set_index(rules[4][6].as_str()) > set_index(rules[5][0].as_str()));
        assert!(set_index(rules[2][0].as_str()) < set_index(rules[1][6].as_str()));
    }

    #[test]
    fn surface_hits_rule_centres_and_is_odd() {
        let rules = paper_rules();
        let f = paper();
        let ec = [-21.0, -14.0, -7.0, 0.0, 7.0, 14.0, 21.0];
        let dc = [-4.5, -3.0, -1.5, 0.0, 1.5, 3.0, 4.5];
        let uc = [-55.0, -35.0, -15.0, 0.0, 15.0, 35.0, 55.0];
        for (i, &e) in ec.iter().enumerate() {
            for (j, &d) in dc.iter().enumerate() {
                let want = uc[set_index(rules[i][j].as_str())];
                assert_eq!(f.surface(e, d), want, "({e},{d})");
            }
        }
        for a in -30..=30 {
            for b in -30..=30 {
                let (e, d) = (a as f64 * 0.83, b as f64 * 0.19);
                let s = f.surface(e, d) + f.surface(-e, -d);
                assert!(s.abs() < 1e-9, "not odd at ({e},{d}): {s}");
            }
        }
        // Saturating end sets: beyond the universe the output stays at PL.
        assert_eq!(f.surface(100.0, 0.0), 55.0);
        assert_eq!(f.surface(100.0, -100.0), 55.0);
    }

    #[test]
    fn four_rule_example_by_hand() {
        // e = 10.5 (half PS, half PM), Δe = 0.5 (2/3 ZR, 1/3 PS).
        // Rules: (PS,ZR)→PS w=.5, (PS,PS)→PM w=1/3, (PM,ZR)→PM w=.5, (PM,PS)→PM w=1/3.
        let f = paper();
        let want = (0.5 * 15.0 + (1.0 / 3.0 + 0.5 + 1.0 / 3.0) * 35.0) / (0.5 + 0.5 + 2.0 / 3.0);
        assert!((f.surface(10.5, 0.5) - want).abs() < 1e-12);
    }

    #[test]
    fn integral_and_saturation() {
        let mut f = paper();
        f.reset(0.0);
        // Δe = 0 after the first step; constant e = 7: F = 15, u_I grows by 0.7.
        let u0 = f.step(7.0); // Δe = 7 → PL column: (PS, PL) → PL = 55, u_I = 0.7
        assert!((u0 - 55.7).abs() < 1e-12, "{u0}");
        let u1 = f.step(7.0);
        assert!((u1 - 16.4).abs() < 1e-12, "{u1}");
        for _ in 0..10_000 {
            f.step(50.0);
        }
        assert_eq!(f.step(50.0), 127.0);
        assert_eq!(f.integral(), 127.0);
        // Held integrator recovers at once when the error reverses.
        let u = f.step(-50.0);
        assert!(u < 127.0 - 55.0, "{u}");
        assert_eq!(FuzzyController::new(&paper_cfg()).step(-1e9), -128.0);
    }

    #[test]
    fn step_mm_scales_by_blu() {
        let mut a = paper();
        let mut b = paper();
        for k in 0..50 {
            let e = (k as f64 * 0.37).sin() * 0.3;
            assert_eq!(a.step_mm(e), b.step(e / 0.01));
        }
    }

    #[test]
    fn equivalent_gains_against_table4() {
        let f = paper();
        let g = f.equivalent_gains(SectorGrid::Centres);
        // K1 from column ZR: 15/7 .. 55/21; K2 from the 15→35 step over 1.5 BLU.
        assert!((g.k1_min - 15.0 / 7.0).abs() < 1e-12, "{g:?}");
        assert!((g.k1_max - 55.0 / 21.0).abs() < 1e-12, "{g:?}");
        assert_eq!(g.k2_min, 0.0, "paper: K2min = 0");
        assert!((g.k2_max - 20.0 / 1.5).abs() < 1e-12, "{g:?}");
        // Table 4: P 2.4, D 6.7 (printed to one decimal).
        assert!((g.p - 2.4).abs() < 0.05, "P = {}", g.p);
        assert!((g.d - 6.7).abs() < 0.05, "D = {}", g.d);
        // The continuous surface: K1 is the same (Δe = 0 interpolates the ZR column
        // linearly), but between centres min inference with the normalised centroid
        // (eq 6, 8) is not bilinear: where one input sits near a centre, a small Δe
        // adds a rule of weight b to a denominator of 1, so the secant u2/Δe reaches
        // 40/1.5 (twice the table step) near e = ±7, and near e = ±21 a saturated
        // NL/PL rule pulls u2 against Δe (K2 < 0). The paper's K2min = 0 and D = 6.7
        // are statements about the rule table, i.e. the `Centres` reading.
        let dense = f.equivalent_gains(SectorGrid::Dense(840));
        assert!((dense.k1_min - g.k1_min).abs() < 1e-9, "{dense:?}");
        assert!((dense.k1_max - g.k1_max).abs() < 1e-9, "{dense:?}");
        assert!(dense.k2_min < -10.0, "{dense:?}");
        assert!(
            dense.k2_max > 1.9 * g.k2_max && dense.k2_max <= 40.0 / 1.5 + 1e-9,
            "{dense:?}"
        );
    }

    fn mutate(from: &str, to: &str) -> String {
        let text = PAPER_RON.replacen(from, to, 1);
        assert_ne!(text, PAPER_RON, "fixture text `{from}` not found");
        text
    }

    fn refused(text: &str) -> String {
        FuzzyConfig::from_ron_str(text, "bad.ron")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn malformed_tables_are_refused_with_their_path() {
        // Unknown set name in the rule base.
        let err = refused(&mutate(
            r#"["ZR", "PS", "PS", "PS", "PM", "PM", "PL"]"#,
            r#"["ZR", "PS", "PX", "PS", "PM", "PM", "PL"]"#,
        ));
        assert!(err.contains("rules[4][2]") && err.contains("PX"), "{err}");
        // Wrong row length.
        let err = refused(&mutate(
            r#"["ZR", "PS", "PS", "PS", "PM", "PM", "PL"]"#,
            r#"["ZR", "PS", "PS", "PM", "PM", "PL"]"#,
        ));
        assert!(err.contains("`rules[4]`"), "{err}");
        // Wrong number of rows.
        let err = refused(&mutate(
            r#"["ZR", "ZR", "ZR", "ZR", "ZR", "ZR", "ZR"],"#,
            "",
        ));
        assert!(err.contains("`rules`"), "{err}");
        // Non-monotone centres.
        let err = refused(&mutate("-1.5, 0.0, 1.5", "0.0, -1.5, 1.5"));
        assert!(err.contains("de.centres[3]"), "{err}");
        // Centre count differs from the set count.
        let err = refused(&mutate("-55.0, -35.0,", "-35.0,"));
        assert!(err.contains("u.centres"), "{err}");
        // Wrong type: path from serde_path_to_error.
        let err = refused(&mutate("k_i: 0.1", "k_i: \"small\""));
        assert!(err.contains("k_i"), "{err}");
        // Unknown field.
        let err = refused(&mutate("k_i: 0.1", "k_i: 0.1, k_d: 1.0"));
        assert!(err.contains("k_d"), "{err}");
        // Duplicate set name.
        let err = refused(&mutate(
            r#"names: ["NL", "NM", "NS", "ZR", "PS", "PM", "PL"]"#,
            r#"names: ["NL", "NM", "NS", "ZR", "PS", "PS", "PL"]"#,
        ));
        assert!(err.contains("e.names[5]"), "{err}");
        // Inside a profile the prefix is part of the path.
        let mut cfg = paper_cfg();
        cfg.rules[0][0] = "XX".into();
        let err = cfg
            .validate_at("m.ron", "axes[1].fuzzy")
            .unwrap_err()
            .to_string();
        assert!(err.contains("axes[1].fuzzy.rules[0][0]"), "{err}");
    }

    #[test]
    fn stack_runs_the_flc_when_the_profile_selects_it() {
        use crate::stack::{AxisController, Feedback};
        let cfg = crate::config::ControllerConfig {
            kp: 240.0,
            ki: 10.0,
            kd: 670.0,
            vff: 0.0,
            aff: 0.0,
            output_limit: 127.0,
            fuzzy: Some(paper_cfg()),
        };
        let mut axis = AxisController::new(&cfg, 0.01);
        assert!(matches!(axis.feedback, Feedback::Fuzzy(_)));
        axis.reset(0.0);
        let mut flc = paper();
        for k in 1..200 {
            let cmd = 0.05 * k as f64;
            let meas = 0.05 * k as f64 - 0.3 * (k as f64 * 0.1).sin();
            let u = axis.step(cmd, meas).u;
            assert_eq!(u, flc.step_mm(cmd - meas), "cycle {k}");
        }
        let pid = AxisController::new(
            &crate::config::ControllerConfig { fuzzy: None, ..cfg },
            0.01,
        );
        assert!(matches!(pid.feedback, Feedback::Pid(_)));
    }

    #[test]
    fn general_rule_base_of_other_size_runs() {
        // A 3×5 rule base with different names per variable.
        let cfg = FuzzyConfig {
            input_unit_mm: 0.001,
            e: FuzzyVariable {
                names: vec!["N".into(), "Z".into(), "P".into()],
                centres: vec![-1.0, 0.0, 1.0],
            },
            de: FuzzyVariable {
                names: ["a", "b", "c", "d", "e"].map(String::from).to_vec(),
                centres: vec![-2.0, -1.0, 0.0, 1.0, 2.0],
            },
            u: FuzzyVariable {
                names: vec!["neg".into(), "zero".into(), "pos".into()],
                centres: vec![-10.0, 0.0, 10.0],
            },
            rules: vec![
                ["neg", "neg", "neg", "neg", "zero"]
                    .map(String::from)
                    .to_vec(),
                ["neg", "zero", "zero", "zero", "pos"]
                    .map(String::from)
                    .to_vec(),
                ["zero", "pos", "pos", "pos", "pos"]
                    .map(String::from)
                    .to_vec(),
            ],
            k_i: 0.0,
            u_min: -5.0,
            u_max: 5.0,
        };
        let mut f = FuzzyController::new(&cfg);
        assert_eq!(f.surface(0.5, 0.0), 5.0);
        assert_eq!(f.surface(1.0, -2.0), 0.0);
        assert_eq!(f.step(1.0), 5.0);
    }
}
