//! Reading and planning in one pass (`read_and_plan`, and on two threads
//! `read_and_plan_parallel`) gives the plan and the errors of `read_program` + `plan`.

use super::common;
use common::profile;
use softnc_core::FeedProfile;
use softnc_planner::{
    plan, read_and_plan, read_and_plan_parallel, Plan, PlanOptions, ReadPlanError,
};
use std::fmt::Write;

fn same_plan(a: &Plan, b: &Plan, whole_stream: bool) {
    assert_eq!(a.stats(), b.stats());
    assert_eq!(a.elements(), b.elements());
    assert_eq!(a.motions(), b.motions());
    for k in 0..a.motions() {
        assert_eq!(a.motion_primitive(k), b.motion_primitive(k), "motion {k}");
    }
    if whole_stream {
        assert!(a.interpolator().eq(b.interpolator()));
    } else {
        assert!(a
            .interpolator()
            .take(20_000)
            .eq(b.interpolator().take(20_000)));
    }
}

/// Lines, arcs in both formats, dwells, exact stops and blends: a few thousand motions
/// (several chunks).
fn program() -> String {
    let mut s = String::from("G21 G90 G17 G64 P0.02\nG0 X0 Y0 Z1\nG4 P0.1\nG1 Z-1 F900\n");
    let mut x = 0.0;
    for i in 0..3000 {
        match i % 6 {
            0 => writeln!(s, "G1 X{:.4} Y{:.4}", x + 0.7, (i % 5) as f64 * 0.1).unwrap(),
            1 => writeln!(s, "G1 X{:.4} Y0.3", x + 1.2).unwrap(),
            2 => writeln!(s, "G2 X{:.4} Y0.3 I0.25 J0", x + 1.7).unwrap(),
            3 => writeln!(s, "G3 X{:.4} Y0.3 R0.25 F1200", x + 2.2).unwrap(),
            4 if i % 60 == 4 => writeln!(s, "G61 G1 Y1\nG4 P0.05\nG64 G1 Y0.3").unwrap(),
            _ => writeln!(s, "G0 X{:.4}", x + 2.5).unwrap(),
        }
        if i % 6 == 5 {
            x += 2.5;
            if x > 200.0 {
                x = 0.0;
                s.push_str("G0 Z1\nG0 X0\nG1 Z-1\n");
            }
        }
    }
    s.push_str("M2\n");
    s
}

#[test]
fn one_pass_and_two_threads_plan_as_reading_then_planning() {
    let text = program();
    for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
        let p = profile(fp);
        let opts = PlanOptions::default();
        let program = softnc_gcode::read_program(&text, "t.ngc", &p).unwrap();
        let want = plan(&program, &p, &opts).unwrap();
        for (prog, got) in [
            read_and_plan(&text, "t.ngc", &p, &opts).unwrap(),
            read_and_plan_parallel(&text, "t.ngc", &p, &opts).unwrap(),
        ] {
            assert_eq!(prog.blocks, program.blocks);
            assert_eq!(prog.warnings, program.warnings);
            assert!(prog.motions.is_empty());
            same_plan(&want, &got, fp == FeedProfile::Trapezoidal);
        }
    }
}

#[test]
fn errors_come_as_reading_then_planning_gives_them() {
    let p = profile(FeedProfile::Trapezoidal);
    let opts = PlanOptions::default();
    // a soft-limit violation early, a G-code error late: the G-code error wins
    let mut text = String::from("G21 G90\nG0 X-5000\n");
    for i in 0..5000 {
        writeln!(text, "G1 X{} F1000", i % 100).unwrap();
    }
    let with_error = format!("{text}G1 X1 Y2 X3\nM2\n");
    let want = softnc_gcode::read_program(&with_error, "e.ngc", &p).unwrap_err();
    for got in [
        read_and_plan(&with_error, "e.ngc", &p, &opts),
        read_and_plan_parallel(&with_error, "e.ngc", &p, &opts),
    ] {
        assert_eq!(got.unwrap_err(), ReadPlanError::Gcode(want.clone()));
    }
    // without it, the soft limit
    let ok = format!("{text}M2\n");
    let program = softnc_gcode::read_program(&ok, "e.ngc", &p).unwrap();
    let want = plan(&program, &p, &opts).unwrap_err();
    for got in [
        read_and_plan(&ok, "e.ngc", &p, &opts),
        read_and_plan_parallel(&ok, "e.ngc", &p, &opts),
    ] {
        assert_eq!(got.unwrap_err(), ReadPlanError::Plan(want.clone()));
    }
}
