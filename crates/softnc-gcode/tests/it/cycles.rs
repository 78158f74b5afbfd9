//! Canned cycles (G73, G74, G81–G87, G89, G80, G98/G99, `L`, G91) against LinuxCNC's
//! own expansion: each program of `tests/golden/cycles/*.ngc` with the canonical
//! calls `rs274` (LinuxCNC 2.9) printed for it (`*.rs274`, made by `regen.sh` there;
//! CI needs no `rs274`). softnc's reading must make the same sequence of motions
//! (end points to `rs274`'s four decimals), dwells, spindle stops, starts and
//! orientations, override switches and program stops, and run each motion in the
//! path mode LinuxCNC's `SET_MOTION_CONTROL_MODE` calls put it in (exact path
//! inside a cycle). The cycles' errors as LinuxCNC gives them, at their line.

use softnc_core::MotionProfile;
use softnc_gcode::{
    MachineOp, MotionKind, OverrideSwitch, PathMode, Program, ReadOptions, SpindleTurn,
};
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden/cycles")
}

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

/// The numbers between the parentheses of a canonical call.
fn args(line: &str) -> Vec<&str> {
    let inner = &line[line.find('(').unwrap() + 1..line.rfind(')').unwrap()];
    inner.split(',').map(str::trim).collect()
}

/// `rs274`'s output as the events compared: each motion with its end (as printed)
/// and whether LinuxCNC's motion control mode was exact (path or stop) for it.
fn expected(rs274: &str) -> Vec<String> {
    let mut exact = false;
    let mut out = Vec::new();
    let lines: Vec<&str> = rs274.lines().collect();
    let mut turning = false;
    for (k, line) in lines.iter().enumerate() {
        let line = *line;
        let was_turning = turning;
        turning = crate::rs274_calls::turning_after(line, turning);
        if crate::rs274_calls::is_implicit_stop_softnc_leaves_out(&lines, k, was_turning) {
            continue;
        }
        let name = &line[..line.find('(').unwrap_or(line.len())];
        match name {
            "SET_MOTION_CONTROL_MODE" => exact = !line.contains("CANON_CONTINUOUS"),
            "STRAIGHT_TRAVERSE" | "STRAIGHT_FEED" => {
                let a = args(line);
                let mode = if exact { "exact" } else { "blend" };
                out.push(format!("{name}({}, {}, {}) {mode}", a[0], a[1], a[2]));
            }
            "DWELL" => out.push(line.to_string()),
            "ORIENT_SPINDLE" => out.push(line.to_string()),
            "START_SPINDLE_CLOCKWISE"
            | "START_SPINDLE_COUNTERCLOCKWISE"
            | "STOP_SPINDLE_TURNING"
            | "ENABLE_FEED_OVERRIDE"
            | "DISABLE_FEED_OVERRIDE"
            | "ENABLE_SPEED_OVERRIDE"
            | "DISABLE_SPEED_OVERRIDE"
            | "PROGRAM_STOP" => out.push(name.to_string()),
            _ => {}
        }
    }
    out
}

/// softnc's reading as the same events.
fn ours(p: &Program) -> Vec<String> {
    let mut out = Vec::new();
    for m in &p.motions {
        let e = m.canon_end;
        let mode = if m.path_mode == PathMode::ExactStop {
            "exact"
        } else {
            "blend"
        };
        let ev = match m.kind {
            MotionKind::Traverse { .. } => format!(
                "STRAIGHT_TRAVERSE({:.4}, {:.4}, {:.4}) {mode}",
                e[0], e[1], e[2]
            ),
            MotionKind::Feed { .. } => format!(
                "STRAIGHT_FEED({:.4}, {:.4}, {:.4}) {mode}",
                e[0], e[1], e[2]
            ),
            MotionKind::Arc { .. } => "ARC_FEED".into(),
            MotionKind::Dwell { seconds } => format!("DWELL({seconds:.4})"),
            MotionKind::Pause { optional: false } => "PROGRAM_STOP".into(),
            MotionKind::Pause { optional: true } => "OPTIONAL_PROGRAM_STOP".into(),
            MotionKind::Sync => "SYNC".into(),
            MotionKind::Probe { .. } => "STRAIGHT_PROBE".into(),
            MotionKind::Machine(op) => match op {
                MachineOp::SpindleOrient {
                    angle_deg,
                    direction,
                    ..
                } => format!("ORIENT_SPINDLE(0, {angle_deg:.4}, {direction})"),
                MachineOp::SpindleOn {
                    dir: SpindleTurn::Clockwise,
                    ..
                } => "START_SPINDLE_CLOCKWISE".into(),
                MachineOp::SpindleOn { .. } => "START_SPINDLE_COUNTERCLOCKWISE".into(),
                MachineOp::SpindleOff => "STOP_SPINDLE_TURNING".into(),
                MachineOp::Overrides {
                    switch: OverrideSwitch::Feed,
                    on,
                } => format!("{}_FEED_OVERRIDE", if on { "ENABLE" } else { "DISABLE" }),
                MachineOp::Overrides {
                    switch: OverrideSwitch::Spindle,
                    on,
                } => format!("{}_SPEED_OVERRIDE", if on { "ENABLE" } else { "DISABLE" }),
                _ => continue,
            },
        };
        out.push(ev.replace("-0.0000", "0.0000"));
    }
    out
}

fn read(text: &str) -> Result<Program, softnc_gcode::GcodeError> {
    softnc_gcode::read_program_with(text, "t.ngc", &profile(), &ReadOptions::default())
        .map(|(p, _)| p)
}

#[test]
fn each_cycle_expands_as_rs274_expands_it() {
    let mut names: Vec<_> = std::fs::read_dir(dir())
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "ngc").then_some(p)
        })
        .collect();
    names.sort();
    assert!(names.len() >= 10, "{names:?}");
    let mut events = 0;
    for path in names {
        let text = std::fs::read_to_string(&path).unwrap();
        let want: Vec<String> =
            expected(&std::fs::read_to_string(path.with_extension("rs274")).unwrap())
                .into_iter()
                .map(|l| l.replace("-0.0000", "0.0000"))
                .collect();
        let program = read(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let got = ours(&program);
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g, w, "{}: event {k}", path.display());
        }
        assert_eq!(got.len(), want.len(), "{}: {got:#?}", path.display());
        events += got.len();
    }
    assert!(events > 400, "{events} events");
}

/// A cycle's errors, as LinuxCNC 2.9 gives them (`rs274`'s messages), at the line
/// of the block.
#[test]
fn cycle_errors_are_linuxcncs() {
    let head = "G21 G17 G90 F100 S1000 M3\nG0 X0 Y0 Z5\n";
    let cases: &[(&str, &str)] = &[
        ("G81 X1 Y1 Z2 R1", "R less than z in cycle in xy plane"),
        ("G81 X1 Y1 Z-1", "R clearance plane unspecified in cycle"),
        (
            "G81 X1 Y1 R1",
            "Z value unspecified in xy plane canned cycle",
        ),
        (
            "G18 G81 X1 Z1 R1",
            "Y value unspecified in xz plane canned cycle",
        ),
        ("G19 G81 Y1 Z1 R3 X4", "R less than x in cycle in yz plane"),
        ("G82 X1 Y1 Z-1 R1", "Dwell time p word missing with g82"),
        ("G86 X1 Y1 Z-1 R1", "Dwell time p word missing with g86"),
        ("G89 X1 Y1 Z-1 R1", "Dwell time p word missing with g89"),
        ("G83 X1 Y1 Z-1 R1", "Q word missing with g83"),
        ("G73 X1 Y1 Z-1 R1", "Q word missing with g73"),
        ("G83 X1 Y1 Z-1 R1 Q0", "Negative or zero q value used"),
        ("G73 X1 Y1 Z-1 R1 Q-0.5", "Negative or zero q value used"),
        ("G87 X1 Y1 Z-1 R1 J1 K1", "I word missing with g87"),
        ("G87 X1 Y1 Z-1 R1 I1 K1", "J word missing with g87"),
        ("G87 X1 Y1 Z-1 R1 I1 J1", "K word missing with g87"),
        ("G81 X1 Y1 Z-1 R1 L0", "Cannot do zero repeats of cycle"),
        ("G81 R1", "All axes missing with motion code"),
        ("G81 X1 Y1 Z-1 R1 P1", "P word with no G2 G3 G4 G10 G64"),
        (
            "G81 X1 Y1 Z-1 R1 Q1",
            "Q word with no G5, G10, G64, G73, G76, G83",
        ),
        (
            "G82 X1 Y1 Z-1 R1 P1 I1",
            "I word with no G2, G3, G5, G5.1, G10",
        ),
        (
            "G74 X1 Y1 Z-1 R1 L2",
            "L word with no G10, cutter compensation",
        ),
        ("G0 X1 R1", "R word with no g code that uses it"),
        ("G80 X1", "Cannot use axis values with g80"),
        ("M5\nG86 X1 Y1 Z-1 R1 P1", "Spindle not turning in g86"),
        (
            "M5\nG87 X1 Y1 Z-1 R1 I1 J1 K1",
            "Spindle not turning in g87",
        ),
        ("M5\nG84 X1 Y1 Z-1 R1", "Spindle not turning in G84"),
        ("G74 X1 Y1 Z-1 R1", "Spindle turning clockwise in G74"),
        (
            "M4\nG84 X1 Y1 Z-1 R1",
            "Spindle turning counterclockwise in G84",
        ),
        (
            "G93\nG81 X1 Y1 Z-1 R1 F1",
            "Cannot use inverse time feed with canned cycles",
        ),
        ("F0\nG81 X1 Y1 Z-1 R1", "Cannot feed with zero feed rate"),
        (
            "G18\nG81 @1 ^2 Y-1 R1",
            "Cannot use polar coordinate except in G17 plane",
        ),
        (
            "G18\nG0 @1",
            "Cannot use polar coordinate except in G17 plane",
        ),
        (
            "G91 G81 @1 Z-1 R1",
            "Incremental motion with polar coordinates is indeterminate when at the origin",
        ),
    ];
    for (body, msg) in cases {
        let mut text = head.to_string();
        text += body;
        text += "\nM2\n";
        let line = text.lines().count() as u32 - 1;
        let err = match read(&text) {
            Ok(_) => panic!("{body:?} was read"),
            Err(e) => e,
        };
        assert!(
            err.to_string().contains(msg),
            "{body:?}: {err} (expected {msg:?})"
        );
        assert_eq!(err.line, line, "{body:?}: {err}");
    }
}

/// What softnc does not run, refused where the code stands, saying why.
#[test]
fn cycles_softnc_does_not_run_are_refused_saying_why() {
    let head = "G21 G17 G90 F100 S1000 M3\nG0 X0 Y0 Z5\n";
    for (body, why, column) in [
        ("G88 X1 Y1 Z-1 R1 P1", "retract the spindle by hand", 1),
        (
            "G76 P1 Z-5 I-0.1 J0.1 K0.5",
            "spindle-synchronised motion",
            1,
        ),
        ("G18 G84 X1 Z1 Y-1 R1", "XY plane (G17) only", 5),
        ("G19 G74 Y1 Z1 X-1 R1", "XY plane (G17) only", 5),
    ] {
        let text = format!("{head}{body}\nM2\n");
        let err = read(&text).expect_err(body);
        let s = err.to_string();
        assert!(s.contains("unsupported") && s.contains(why), "{body}: {s}");
        assert_eq!((err.line, err.column), (3, column), "{body}: {s}");
    }
}

/// The cycles' modal behaviour in a few lines: a bare position drills again with
/// the sticky R, Z and P; G80 and any other motion code end the cycle (axis words
/// without a motion code are then refused, or move as G0/G1 say).
#[test]
fn bare_positions_repeat_the_cycle_until_cancelled() {
    let holes = |text: &str| -> usize {
        read(text)
            .unwrap()
            .motions
            .iter()
            .filter(|m| matches!(m.kind, MotionKind::Feed { .. }))
            .count()
    };
    let head = "G21 G17 G90 F100\nG0 X0 Y0 Z5\nG81 X1 Y1 Z-1 R1\n";
    assert_eq!(holes(&format!("{head}X2\nY3\nX4 Y4\nM2\n")), 4);
    assert_eq!(holes(&format!("{head}X2 L3\nM2\n")), 4);
    // G0 ends the cycle: the bare X after it is a traverse
    assert_eq!(holes(&format!("{head}G0 X2\nX3\nM2\n")), 1);
    // G1 ends it: the bare X is a feed
    assert_eq!(holes(&format!("{head}G1 X2\nX3\nM2\n")), 3);
    let err = read(&format!("{head}G80\nX2\nM2\n")).unwrap_err();
    assert!(
        err.to_string()
            .contains("Cannot use axis values without a g code that uses them"),
        "{err}"
    );
    assert_eq!(err.line, 5);
    // the next job or MDI command does not inherit the cycle (its words are not
    // in the modal state handed on): it starts in G80, with G98/G99 kept
    let p = read(&format!("G98\n{head}X2\nM2\n")).unwrap();
    assert!(!p.end_modal.contains("G81"), "{}", p.end_modal);
    assert!(p.end_modal.contains("G98"), "{}", p.end_modal);
    // #<_retract_old_z> and #<_retract_r_plane>
    let p = read("G98\n#1 = #<_retract_old_z>\n#2 = #<_retract_r_plane>\nG99\n#3 = #<_retract_old_z>\nG0 X#1 Y#2 Z#3\nM2\n").unwrap();
    assert_eq!(p.motions.last().unwrap().canon_end.0, [1.0, 0.0, 0.0]);
}
