//! Learning never makes it worse (issue 15): a diverging Markov run stops and keeps
//! its best iteration, the correction is bounded by the profile, only a correction
//! measured to improve on the unlearned run is kept, on every profile in
//! `config/machines/`; the radius law skips zero-length moves.

use softnc_experiments::learning_runs::{
    correction_bound_mm, find_circle, identify, learn_markov, run_job, PreparedJob,
};
use softnc_learning::markov::{MarkovJob, DEFAULT_GAIN};
use softnc_machine::MachineProfile;
use softnc_sim::{simulated_engine, SimOptions};
use std::path::PathBuf;

fn workspace_file(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn machine(name: &str) -> MachineProfile {
    MachineProfile::load(&workspace_file(&format!("config/machines/{name}"))).unwrap()
}

/// Contour-error RMS (µm) of `job` on a fresh simulated machine (seed 1) with the
/// correction of `mj` (or none).
fn rerun_rms_um(m: &MachineProfile, job: &PreparedJob, mj: Option<&MarkovJob>) -> f64 {
    let mut engine = simulated_engine(m, 1, SimOptions::default());
    let run = run_job(&mut engine, job, |k, p| mj.map_or(p, |mj| mj.command(k, p))).unwrap();
    run.contour.rms() * 1000.0
}

/// Learn `text` on `m` with the CLI's defaults (gain 0.5, all terms, the profile's
/// bound); the returned job holds what `softnc learn` would store.
fn learn(m: &MachineProfile, text: &str, iterations: usize) -> (PreparedJob, MarkovJob, usize) {
    let job = PreparedJob::new(text, "job.ngc", m).unwrap();
    let n = job.samples.len();
    let mut engine = simulated_engine(m, 1, SimOptions::default());
    let h = identify(&mut engine, m, job.samples[0].pos_mm.0, n).unwrap();
    let bound = correction_bound_mm(m, &h);
    let mut mj = MarkovJob::new(h, n, Some(DEFAULT_GAIN), n).bounded(bound);
    let its = learn_markov(&mut engine, &job, &mut mj, iterations, |_, _| Ok(())).unwrap();
    (job, mj, its.len())
}

const CIRCLE_40MM_1800: &str = "G21 G90 G17 G94\nG0 X20 Y0 Z0\nG1 F1800\nG3 X20 Y0 I-20 J0\nM2\n";

/// Issue 15 item 10: on tnv40-ilc.ron this circle's Markov learning went
/// 93 → 53 → 274 → … → 31,382 µm and the last correction was stored.
#[test]
fn a_diverging_run_stops_and_keeps_its_best_iteration() {
    let m = machine("tnv40-ilc.ron");
    let (job, mj, runs) = learn(&m, CIRCLE_40MM_1800, 10);
    let _ = runs;
    let imp = mj
        .improvement
        .expect("an iteration improved on the unlearned run");
    assert!(imp.improved(), "{imp:?}");
    let bound = mj.max_correction_mm.unwrap();
    for (a, c) in mj.correction_mm.iter().enumerate() {
        assert!(
            c.iter().all(|v| v.abs() <= bound[a]),
            "axis {a} over ±{}",
            bound[a]
        );
    }
    let unlearned = rerun_rms_um(&m, &job, None);
    let kept = rerun_rms_um(&m, &job, Some(&mj));
    assert!(
        kept < unlearned,
        "kept correction {kept:.1} µm RMS, unlearned {unlearned:.1} µm"
    );
}

#[test]
fn the_correction_is_bounded_by_the_profile() {
    let mut m = machine("tnv40-ilc.ron");
    m.learning.max_correction_mm = Some(0.005);
    let (_, mj, _) = learn(&m, CIRCLE_40MM_1800, 2);
    assert_eq!(mj.max_correction_mm, Some([0.005; 3]));
    let max = mj
        .correction_mm
        .iter()
        .flatten()
        .fold(0.0f64, |a, v| a.max(v.abs()));
    assert!(max <= 0.005 && max > 0.0, "{max}");
    let bad = std::fs::read_to_string(workspace_file("config/machines/tnv40-ilc.ron"))
        .unwrap()
        .replace(
            "cutting: None,\n    ),",
            "cutting: None,\n    ),\n    learning: (max_correction_mm: -1.0),",
        );
    let err = MachineProfile::from_ron_str(&bad, "bad.ron").unwrap_err();
    assert!(
        err.to_string().contains("learning.max_correction_mm"),
        "{err}"
    );
}

/// A short program of lines and an arc with a reversal, inside every profile's travel.
const SHORT: &str =
    "G21 G90 G17 G94\nG0 X0 Y0 Z0\nG1 F600\nG1 X4 Y2\nG2 X8 Y2 I2 J0\nG1 X8 Y0\nG1 X2 Y0\nM2\n";

#[test]
fn markov_learning_improves_or_stops_cleanly_on_every_profile() {
    let dir = workspace_file("config/machines");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|n| n.ends_with(".ron"))
        .collect();
    names.sort();
    assert!(names.len() >= 8, "{names:?}");
    let mut report = vec![];
    for name in &names {
        let m = machine(name);
        // six repetitions: on tnv40-ilc.ron (a 33 ms lag) the unlearned run's lag
        // along the path is no contour error (the distance to the path, issue 35),
        // and the learnt lead overshoots the corners for the first repetitions:
        // 19.5 µm RMS unlearned, 69.4 after the first, 17.8 after the sixth
        let (job, mj, runs) = learn(&m, SHORT, 6);
        let imp = mj
            .improvement
            .unwrap_or_else(|| panic!("{name}: no iteration improved on the unlearned run"));
        let unlearned = rerun_rms_um(&m, &job, None);
        let kept = rerun_rms_um(&m, &job, Some(&mj));
        report.push(format!(
            "{name}: {runs} runs, kept iteration {} ({:.3} → {:.3} µm); rerun {unlearned:.3} → {kept:.3} µm",
            imp.iteration, imp.unlearned_rms_um, imp.rms_um
        ));
        assert!(kept < unlearned, "{}", report.join("\n"));
    }
    println!("{}", report.join("\n"));
}

#[test]
fn the_radius_law_skips_a_zero_length_feed_move() {
    let m = machine("tnv40-ilc.ron");
    let (c, r) = find_circle(CIRCLE_40MM_1800, "C.ngc", &m).unwrap();
    assert!((r - 20.0).abs() < 1e-9 && c.ccw && c.feed_mm_per_min == 1800.0);
    // a move that does move is still refused with its line
    let two = "G21 G90 G17 G94\nG0 X20 Y0 Z0\nG1 X21 F1800\nG3 X21 Y0 I-21 J0\nM2\n";
    let err = find_circle(two, "D.ngc", &m).unwrap_err();
    assert!(err.starts_with("D.ngc:3:"), "{err}");
}

/// The radius law with α = 3 (eq 8 overshoots: e ← (1 − α)e per degree) makes the
/// circle worse than unlearned at its first step: the run stops there.
#[test]
fn a_diverging_radius_run_stops() {
    use softnc_experiments::learning_runs::learn_radius;
    use softnc_learning::radius_ilc::RadiusIlc;
    let m = machine("tnv40-ilc.ron");
    let (c, r) = find_circle(CIRCLE_40MM_1800, "C.ngc", &m).unwrap();
    let mut engine = simulated_engine(&m, 1, SimOptions::default());
    let mut ilc = RadiusIlc::new(r, 3.0);
    let its = learn_radius(&mut engine, &m, &c, &mut ilc, 5, |_, _, _| Ok(())).unwrap();
    assert_eq!(its.len(), 2, "{its:?}");
    assert!(its[1].rms_um > its[0].rms_um, "{its:?}");
}
