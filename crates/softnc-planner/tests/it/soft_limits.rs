//! Soft limits are found before any motion, wherever a move leaves the travel: at its
//! end, or only at the bulge of an arc whose end points stay inside the box drawn so
//! far (the planner skips the box test for moves inside that box, so this is where a
//! wrong shortcut would let a move through).

use super::common;
use common::profile;
use softnc_core::FeedProfile;
use softnc_planner::{plan, read_and_plan, read_and_plan_parallel, PlanError, PlanOptions};

/// The soft-limit refusal of a program (all three entry points agree), or None.
fn refusal(text: &str) -> Option<PlanError> {
    let p = profile(FeedProfile::Trapezoidal);
    let opts = PlanOptions::default();
    let program = softnc_gcode::read_program(text, "s.ngc", &p).expect("reads");
    let two_step = plan(&program, &p, &opts).err();
    for got in [
        read_and_plan(text, "s.ngc", &p, &opts).err(),
        read_and_plan_parallel(text, "s.ngc", &p, &opts).err(),
    ] {
        let got = got.map(|e| match e {
            softnc_planner::ReadPlanError::Plan(e) => e,
            other => panic!("not a planning error: {other}"),
        });
        assert_eq!(got, two_step);
    }
    two_step
}

/// A box x ∈ [−100, 100], y ∈ [−200, 240] drawn first (default.ron: Y travel ±250).
const BOX: &str = "G21 G90 G17\nG0 X-100 Y-200\nG1 X100 Y240 F1000\nG1 X-60 Y200\n";

#[test]
fn a_line_past_the_travel_is_refused_at_its_line() {
    let e = refusal(&format!("{BOX}G1 X20 Y-260\nM2\n")).expect("refused");
    let PlanError::SoftLimit {
        line, axis, pos_mm, ..
    } = e
    else {
        panic!("{e}");
    };
    assert_eq!((line, axis), (5, 'Y'));
    assert!((pos_mm + 260.0).abs() < 1e-9, "{pos_mm}");
}

#[test]
fn an_arc_bulging_past_the_travel_is_refused_though_its_ends_are_inside_the_box() {
    // from (−60, 200) clockwise over the top to (60, 200), centre (0, 200): y = 260
    let e = refusal(&format!("{BOX}G2 X60 Y200 I60 J0\nM2\n")).expect("refused");
    let PlanError::SoftLimit {
        line, axis, pos_mm, ..
    } = e
    else {
        panic!("{e}");
    };
    assert_eq!((line, axis), (5, 'Y'));
    assert!((pos_mm - 260.0).abs() < 1e-9, "{pos_mm}");
    // the same arc the other way round (G3, under) stays inside: y ≥ 140
    assert_eq!(refusal(&format!("{BOX}G3 X60 Y200 I60 J0\nM2\n")), None);
}

#[test]
fn moves_inside_the_box_keep_its_figures() {
    let p = profile(FeedProfile::Trapezoidal);
    let inside = format!("{BOX}G3 X60 Y200 I60 J0\nG1 X0 Y0\nG2 X0 Y0 I10 J0\nM2\n");
    let program = softnc_gcode::read_program(&inside, "s.ngc", &p).unwrap();
    let s = plan(&program, &p, &PlanOptions::default()).unwrap().stats();
    assert_eq!(s.bounds_min_mm.0, [-100.0, -200.0, 0.0]);
    assert_eq!(s.bounds_max_mm.0, [100.0, 240.0, 0.0]);
    assert_eq!(s.moves, 6);
}

/// A probe move (read with rs274's stand-in results, as `softnc plan --canon`
/// reads it) is refused at its line: no machine stands where the stand-in says,
/// and the machine does not run probe moves yet.
#[test]
fn a_probe_move_is_refused_at_its_line() {
    let p = profile(FeedProfile::Trapezoidal);
    let options = softnc_gcode::ReadOptions {
        probe_results: softnc_gcode::ProbeResults::StandIn,
        ..Default::default()
    };
    let (program, _) = softnc_gcode::read_program_with(
        "G21 F100\nG0 X1\nG38.2 Z-5\nG0 Z5\nM2\n",
        "s.ngc",
        &p,
        &options,
    )
    .expect("reads");
    let e = plan(&program, &p, &PlanOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "s.ngc:3:1: G38.2: a probe move is not planned (the machine does not run probe moves yet)"
    );
}
