//! Each motion carries the spindle speed it runs at: the S word in force while M3/M4
//! turn the spindle, 0 while it stands (M5, or before any M3/M4).

use softnc_core::MotionProfile;
use softnc_gcode::read_program;
use std::path::PathBuf;

fn profile() -> MotionProfile {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron");
    MotionProfile::load(&p).unwrap()
}

#[test]
fn motions_carry_the_spindle_speed_in_force() {
    let text = "G21 G90\n\
                G1 X1 F100\n\
                S1500 G1 X2\n\
                M3 G1 X3\n\
                S1800 G1 X4\n\
                G4 P0.5\n\
                M5 G1 X5\n\
                S1200 M4 G1 X6\n\
                M2\n";
    let p = read_program(text, "s.ngc", &profile()).unwrap();
    let rpm: Vec<f64> = p
        .motions
        .iter()
        .filter(|m| !matches!(m.kind, softnc_gcode::MotionKind::Machine(_)))
        .map(|m| m.spindle_rpm)
        .collect();
    // S before M3 only sets the speed; M3 in a block with a move applies to it (RS274
    // order: spindle before motion); the dwell runs at the speed in force
    assert_eq!(rpm, vec![0.0, 0.0, 1500.0, 1800.0, 1800.0, 0.0, 1200.0]);
}
