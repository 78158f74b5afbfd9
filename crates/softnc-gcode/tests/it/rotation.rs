//! XY rotation of coordinate systems (`G10 L2 R`, parameters 5210 + 20·n) as
//! LinuxCNC 2.9 applies it. The expected values are what LinuxCNC's `rs274`
//! (2.9.0~pre1) printed for these programs with an empty parameter file
//! (`rs274 -v empty.var -g t.ngc`): its canonical calls (the unrotated program
//! frame) and its `(DEBUG,…)` messages (`#<_abs_x>`, the machine position, and
//! the stored parameters, in inches as `rs274` keeps them without an INI file).

use softnc_core::{MotionProfile, Vec3};
use softnc_gcode::{ErrorKind, MotionKind, Program, ReadOptions};
use std::path::PathBuf;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

/// Read as `rs274` does: all parameters 0 at the start, kept in inches.
fn read(text: &str) -> Result<Program, softnc_gcode::GcodeError> {
    let options = ReadOptions {
        params: Some(softnc_gcode::Params::default()),
        parameters_in_inches: true,
        ..Default::default()
    };
    softnc_gcode::read_program_with(text, "t.ngc", &profile(), &options).map(|(p, _)| p)
}

const PROGRAM: &str = "G21 F100
G10 L2 P1 X10 Y5 R30
G0 X1 Y2
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421 #5230)
G92 X0 Y0
G1 X3 Y1
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421)
G3 X1 Y3 I-2 J0
G10 L20 P0 X5 Y5
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421 #5221 #5222)
G0 X0 Y0
G28.1
(DEBUG,#5161 #5162)
G53 G0 X1
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421)
G10 L2 P2 X-4 R-45
G55
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421)
G0 X2 Y0
G54
G28
(DEBUG,#<_abs_x> #<_abs_y> #5420 #5421)
M2
";

fn close(a: Vec3, b: [f64; 3], tol: f64) -> bool {
    a.0.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn rotated_systems_read_as_rs274_reads_them() {
    let mut p = read(PROGRAM).unwrap();
    p.motions
        .retain(|m| !matches!(m.kind, softnc_gcode::MotionKind::Machine(_)));
    // rs274's STRAIGHT_TRAVERSE / STRAIGHT_FEED / ARC_FEED, in order (program frame)
    let canon: [[f64; 3]; 8] = [
        [1.0, 2.0, 0.0],
        [3.0, 1.0, 0.0],
        [1.0, 3.0, 0.0], // ARC_FEED(1, 3, centre 1, 1, turn 1)
        [0.0, 0.0, 0.0],
        [-5.5442, 3.2010, 0.0], // G53 X1: the point back through the rotation
        [2.0, 0.0, 0.0],
        [-8.9160, 0.2897, 0.0], // G28: the waypoint, the current point in G54
        [0.0, 0.0, 0.0],
    ];
    assert_eq!(p.motions.len(), canon.len());
    for (m, want) in p.motions.iter().zip(canon) {
        let (end, _) = m.canon_view();
        assert!(
            close(end.unwrap(), want, 1e-9),
            "line {}: {end:?} vs {want:?}",
            m.line
        );
    }
    let (_, center) = p.motions[2].canon_view();
    assert!(close(center.unwrap(), [1.0, 1.0, 0.0], 1e-9));
    assert!(matches!(
        p.motions[2].kind,
        MotionKind::Arc { turns: 1, .. }
    ));
    // rs274's MESSAGE lines
    let debug: Vec<&str> = p
        .warnings
        .iter()
        .map(|w| w.split(": debug: ").nth(1).unwrap_or(w))
        .collect();
    assert_eq!(
        debug,
        [
            "9.866025 7.232051 1.000000 2.000000 30.000000",
            "11.964102 9.598076 3.000000 1.000000",
            "9.232051 10.330127 5.000000 5.000000 0.296689 0.049919",
            "0.291414 0.137795",
            "1.000000 3.500000 -5.544229 3.200962",
            "1.000000 3.500000 0.060660 4.010408",
            "7.401924 3.500000 0.000000 0.000000",
        ]
    );
    // the motions' frame: end + offset is where LinuxCNC puts the machine
    // (#<_abs_x>, #<_abs_y> printed after the motion)
    let machine = |k: usize| p.motions[k].kind.end().unwrap() + p.motions[k].offset_mm;
    for (k, want) in [
        (0, [9.866025, 7.232051]),
        (1, [11.964102, 9.598076]),
        (3, [0.291414 * 25.4, 0.137795 * 25.4]),
        (4, [1.0, 3.5]),
        (7, [7.401924, 3.5]),
    ] {
        let got = machine(k);
        assert!(
            close(got, [want[0], want[1], 0.0], 2e-5),
            "motion {k}: {got:?}"
        );
    }
    // the arc's centre turns with the system: R(30°)·(centre + G92) + origin
    if let MotionKind::Arc { center, plane, .. } = p.motions[2].kind {
        assert_eq!(plane, softnc_core::Plane::XY);
        let c = center + p.motions[2].offset_mm;
        let (s, co) = 30f64.to_radians().sin_cos();
        let want = [10.0 + 2.0 * co - 3.0 * s, 5.0 + 2.0 * s + 3.0 * co, 0.0];
        assert!(close(c, want, 1e-9), "{c:?} vs {want:?}");
    }
    // the machine path is continuous: each motion starts where the last ended
    for w in p.motions.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let end = a.kind.end().unwrap() + a.offset_mm;
        assert!(close(b.start + b.offset_mm, end.0, 1e-9), "line {}", b.line);
    }
}

#[test]
fn rotation_is_kept_per_system_and_read_at_the_start() {
    // G10 L2 P2 R90 on a system not in use changes nothing until G55 selects it;
    // the current point (1, 0) is then (0, -1) in G55, and X1 goes to (1, -1)
    let p = read("G10 L2 P2 R90\nG0 X1\nG55\nG0 X1\nM2\n").unwrap();
    // (the moves: M2's spindle stop has no end)
    let m: Vec<Vec3> = p
        .motions
        .iter()
        .filter_map(|m| m.kind.end().map(|e| e + m.offset_mm))
        .collect();
    assert!(close(m[0], [1.0, 0.0, 0.0], 1e-12));
    assert!(close(m[1], [1.0, 1.0, 0.0], 1e-12), "{:?}", m[1]);
    let (end, _) = p.motions[1].canon_view();
    assert!(close(end.unwrap(), [1.0, -1.0, 0.0], 1e-12));
    // a parameter file with 5250 = 90 and 5220 = 2 starts rotated
    let mut params = softnc_gcode::Params::default();
    params.set(5220, 2.0);
    params.set(5250, 90.0);
    let options = ReadOptions {
        params: Some(params),
        ..Default::default()
    };
    let (p, _) =
        softnc_gcode::read_program_with("G0 X1\nM2\n", "t.ngc", &profile(), &options).unwrap();
    let m = p.motions[0].kind.end().unwrap() + p.motions[0].offset_mm;
    assert!(close(m, [0.0, 1.0, 0.0], 1e-12), "{m:?}");
    // R0 takes the rotation away again: the point stays (0, 1), X1 goes to (1, 1)
    // (rs274: STRAIGHT_TRAVERSE(1, 0, 0) then (1, 1, 0))
    let p = read("G10 L2 P0 R90\nG0 X1\nG10 L2 P0 R0\nG0 X1\nM2\n").unwrap();
    let m = p.motions[1].kind.end().unwrap() + p.motions[1].offset_mm;
    assert!(close(m, [1.0, 1.0, 0.0], 1e-12), "{m:?}");
    let (end, _) = p.motions[1].canon_view();
    assert!(close(end.unwrap(), [1.0, 1.0, 0.0], 1e-12));
}

#[test]
fn rotated_arcs_out_of_the_xy_plane_are_refused() {
    let e = read("G10 L2 P0 R60\nF100\nG18 G2 X2 Z0 I1 K0\nM2\n").unwrap_err();
    assert!(matches!(e.kind, ErrorKind::Unsupported { .. }), "{e}");
    assert_eq!((e.line, e.column), (3, 5));
    // R in L20 is LinuxCNC's error
    let e = read("G10 L20 P1 X1 R5\nM2\n").unwrap_err();
    assert_eq!(e.kind.to_string(), "R not allowed in G10 L20");
}
