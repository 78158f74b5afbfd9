//! Paper 001, Table 5: contour errors of PID and fuzzy-logic control (FLC) on the
//! plain-slideway mill (`config/machines/mill-friction.ron`), six contour/feed cases.
//!
//! Every case is planned from `examples/paper001/*.ngc` by the project's planner and
//! run through the simulated machine with the same seeds for every controller, so PID
//! and FLC meet the same K, τ and friction realisation. Contour error is the true
//! (unquantised) table position's distance to the programmed path of the active motion
//! (paper eq 9 for the line, eq 10 for the circle, the active leg for the corner),
//! sampled every cycle of the feed moves and for `HOLD_S` after the last one.

use crate::error::{ExperimentError, Result};
use crate::{workspace_file, Experiment, ExperimentId, Report, RunOptions};
use softnc_machine::fuzzy::FuzzyConfig;
use softnc_machine::MachineProfile;
use std::path::{Path, PathBuf};

pub use crate::p001_cases::{
    best_stack, drive_feedforward, machine_for, plot_circle, prepare, run, table, to_json, to_text,
    Case, PreparedCase, Row, Stack, Stats, TracePoint, CASES, HOLD_S,
};

/// The machine of the experiment.
pub const MACHINE: &str = "config/machines/mill-friction.ron";
/// The fuzzy rule base and membership table of the paper.
pub const FUZZY: &str = "config/fuzzy/paper001.ron";

/// The experiment `001-table5`.
pub struct Table5;

/// What the experiment found, and what its plots need.
pub struct Table5Report {
    /// The six rows.
    pub rows: Vec<Row>,
    /// The seeds averaged over.
    pub seeds: Vec<u64>,
    /// The plant-reading audit, when asked for.
    pub audit: Option<crate::p001_audit::Audit>,
    /// The machine it ran on.
    pub machine: MachineProfile,
    /// The FLC's rule base.
    pub flc: FuzzyConfig,
}

impl Report for Table5Report {
    fn to_json(&self) -> serde_json::Value {
        let mut doc = to_json(&self.rows);
        if let Some(a) = &self.audit {
            doc["audit"] = crate::p001_audit::to_json(a);
        }
        doc
    }
    fn to_text(&self) -> String {
        let mut s = to_text(&self.rows, &self.seeds);
        if let Some(a) = &self.audit {
            s += &format!("\n{}", crate::p001_audit::to_text(a));
        }
        s
    }
    fn write_plots(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        let mut written = Vec::new();
        for case in CASES.iter().filter(|c| c.contour == "circle") {
            let out = dir.join(format!("reproduce-001-circle-{}.svg", case.feed));
            plot_circle(case, &self.machine, &self.flc, 1, &out)?;
            written.push(out);
        }
        Ok(written)
    }
}

impl Experiment for Table5 {
    fn id(&self) -> ExperimentId {
        ExperimentId::Table5001
    }
    fn default_machine(&self) -> &'static str {
        MACHINE
    }
    fn run(&self, options: &RunOptions) -> Result<Box<dyn Report>> {
        let machine = options.machine_profile(MACHINE)?;
        let flc_path = options
            .fuzzy
            .clone()
            .unwrap_or_else(|| workspace_file(FUZZY));
        let flc =
            FuzzyConfig::load(&flc_path).map_err(|e| ExperimentError::Config(e.to_string()))?;
        let seeds: Vec<u64> = (1..=options.seeds).collect();
        let rows = table(&machine, &flc, &seeds)?;
        let audit = if options.audit {
            Some(crate::p001_audit::audit(&machine, &flc, &seeds)?)
        } else {
            None
        };
        Ok(Box::new(Table5Report {
            rows,
            seeds,
            audit,
            machine,
            flc,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup() -> (MachineProfile, FuzzyConfig) {
        let m = MachineProfile::load(&workspace_file(MACHINE)).unwrap();
        let f = FuzzyConfig::load(&workspace_file(FUZZY)).unwrap();
        (m, f)
    }

    #[test]
    fn same_seed_same_result_and_controllers_differ() {
        let (m, f) = setup();
        let case = CASES[2];
        let p = prepare(&case, &m).unwrap();
        let pid = machine_for(&m, Stack::Pid, &f);
        let flc = machine_for(&m, Stack::Flc, &f);
        let a = run(&p, &pid, 3, |_| {}).unwrap();
        let b = run(&p, &pid, 3, |_| {}).unwrap();
        assert_eq!(a, b);
        let c = run(&p, &flc, 3, |_| {}).unwrap();
        assert_ne!(a, c);
        assert!(a.max > 0.0 && a.rms > 0.0 && a.max >= a.rms);
    }
    fn rows(seeds: u64) -> Vec<Row> {
        let (m, f) = setup();
        table(&m, &f, &(1..=seeds).collect::<Vec<_>>()).unwrap()
    }

    /// The reproduced Table 5 (mean of seeds 1–5, 10 µm) and its plant-reading audit
    /// as regression figures, as `softnc reproduce 001-table5 --audit` printed them on
    /// 2026-11-25: [PID max, FLC max, PID rms, FLC rms, best max, best rms] per row.
    /// The issue's acceptance (FLC ≤ PID in max and RMS in every row) is NOT met: the
    /// FLC is not worse than the PID in 1 of 12 cells on the project's reading, and in
    /// 12 of 12 only under the (mm/s)/V ±10 V reading, on which Table 4's PID is
    /// unstable (pole radius 1.287) — docs/reproduce-001.md. A change to the plant, the
    /// controllers, the planner or the simulator that moves a figure by more than 1 % (+ the 0.01
    /// printed) fails here (re-recorded after the planner dropped its 2 % margin).
    #[test]
    fn table5_and_audit_regression_figures() {
        const TABLE: [[f64; 6]; 6] = [
            [6.03, 6.20, 1.12, 1.30, 5.98, 1.11],
            [6.23, 6.21, 1.55, 1.86, 6.31, 1.54],
            [11.76, 11.92, 2.08, 2.23, 11.16, 1.94],
            [17.16, 19.30, 6.25, 6.25, 12.32, 3.11],
            [6.47, 7.56, 1.70, 1.78, 2.78, 1.00],
            [10.62, 11.17, 2.99, 3.00, 1.54, 0.96],
        ];
        let close = |got: f64, want: f64| (got - want).abs() <= 0.01 * want.abs() + 0.006;
        let rows = rows(5);
        assert_eq!(rows.len(), TABLE.len());
        for (r, want) in rows.iter().zip(TABLE) {
            let got = [
                r.pid.max, r.flc.max, r.pid.rms, r.flc.rms, r.best.max, r.best.rms,
            ];
            for (g, w) in got.iter().zip(want) {
                assert!(
                    close(*g, w),
                    "{} {}: {got:.2?} vs recorded {want:?}",
                    r.case.contour,
                    r.case.feed
                );
            }
        }
        // the audit: per reading, FLC-not-worse cells (of 12; None = not run: the DAC
        // cannot drive the feeds), worst FLC/PID ratio, PID pole radius
        let want: [(Option<usize>, Option<f64>, f64); 7] = [
            (Some(1), Some(1.20), 0.952),
            (Some(1), Some(1.13), 0.951),
            (Some(0), Some(1.39), 0.952),
            (Some(1), Some(1.41), 0.951),
            (Some(0), Some(3.15), 0.953),
            (Some(12), Some(0.45), 1.287),
            (None, None, 0.960),
        ];
        let (m, f) = setup();
        let audit = crate::p001_audit::audit(&m, &f, &(1..=5).collect::<Vec<_>>()).unwrap();
        assert_eq!(audit.readings.len(), want.len());
        for (r, (cells, worst, pole)) in audit.readings.iter().zip(want) {
            let name = format!("{} {}", r.reading.k_unit, r.reading.const_feed);
            assert_eq!(r.flc_not_worse(), cells, "{name}");
            match (r.worst_flc_over_pid(), worst) {
                (Some(g), Some(w)) => assert!(close(g, w), "{name}: worst FLC/PID {g:.3} vs {w}"),
                (g, w) => assert_eq!(g, w, "{name}"),
            }
            assert!(
                (r.pid_pole_radius - pole).abs() <= 0.0006,
                "{name}: pole radius {:.4} vs {pole}",
                r.pid_pole_radius
            );
        }
    }

    /// What does hold: the FLC with Table 4's equivalent gains performs like the PID
    /// (every cell within 35 %), and the best stack (PID + drive feedforward) is not
    /// worse than the PID in RMS anywhere and beats it in max on the circle and the corner.
    #[test]
    fn flc_is_equivalent_to_pid_and_feedforward_wins() {
        let rows = rows(5);
        assert_eq!(rows.len(), 6);
        for r in &rows {
            let name = format!("{} {}", r.case.contour, r.case.feed);
            for (f, p) in [(r.flc.max, r.pid.max), (r.flc.rms, r.pid.rms)] {
                assert!(f / p > 0.65 && f / p < 1.35, "{name}: FLC {f} vs PID {p}");
            }
            // on the line the feedforward changes little (stiction dominates): 2 % slack
            assert!(
                r.best.rms <= 1.02 * r.pid.rms,
                "{name}: best {:?} vs PID {:?}",
                r.best,
                r.pid
            );
            if r.case.contour != "line" {
                assert!(
                    r.best.max < r.pid.max,
                    "{name}: best {:?} vs PID {:?}",
                    r.best,
                    r.pid
                );
            }
        }
        // Quadrant and start-up stiction dominate the max error at low feed and are
        // within a factor of 2 of the paper's PID figures (line, circle low).
        for r in rows.iter().take(3) {
            let ratio = r.pid.max / r.case.paper[0];
            assert!(ratio > 0.5 && ratio < 2.0, "{:?}: {ratio}", r.case);
        }
    }

    #[test]
    fn json_has_the_issue_shape() {
        let v = to_json(&rows(1));
        let rows = v["rows"].as_array().unwrap();
        assert_eq!(rows.len(), 6);
        let r = &rows[3];
        assert_eq!(r["contour"], "circle");
        assert_eq!(r["feed"], "high");
        for k in ["pid", "flc", "best"] {
            assert!(r[k]["max"].as_f64().unwrap() > 0.0, "{k}");
            assert!(r[k]["rms"].as_f64().unwrap() > 0.0, "{k}");
        }
        assert_eq!(r["paper"]["pid_max"], 39.9);
        assert_eq!(r["paper"]["flc_rms"], 11.7);
    }
}
