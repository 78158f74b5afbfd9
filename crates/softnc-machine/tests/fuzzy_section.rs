//! Paper 001's fuzzy-controller section (schema and validation in
//! `softnc-control`) inside a machine profile: selected per axis, refused values
//! named by their RON path.

use softnc_machine::fuzzy::*;
use softnc_machine::MachineProfile;

const MILL: &str = include_str!("../../../config/machines/mill-friction.ron");
const PAPER: &str = include_str!("../../../config/fuzzy/paper001.ron");
const PID_Y: &str = "controller: (kp: 240.0, ki: 10.0, kd: 670.0, output_limit: 127.0),";

/// mill-friction.ron with axis Y's controller replaced by the FLC text `flc`.
fn mill_with_flc(flc: &str) -> String {
    let body = &flc[flc.find("FuzzyConfig(").expect("fixture")..];
    let at = MILL
        .match_indices(PID_Y)
        .nth(1)
        .expect("fixture: Y controller")
        .0;
    format!(
        "{}controller: (kp: 0.0, output_limit: 127.0, fuzzy: Some({body})),{}",
        &MILL[..at],
        &MILL[at + PID_Y.len()..]
    )
}

#[test]
fn profile_selects_the_flc_per_axis() {
    let p = MachineProfile::from_ron_str(&mill_with_flc(PAPER), "m.ron").unwrap();
    assert_eq!(p.axis_servo(0).controller.fuzzy, None);
    assert_eq!(
        p.axis_servo(1).controller.fuzzy,
        Some(FuzzyConfig::from_ron_str(PAPER, "paper001.ron").unwrap())
    );
}

#[test]
fn flc_profile_is_mill_friction_with_the_flc_on_x_and_y() {
    let pid = MachineProfile::from_ron_str(MILL, "mill-friction.ron").unwrap();
    let mut flc = MachineProfile::from_ron_str(
        include_str!("../../../config/machines/mill-friction-flc.ron"),
        "mill-friction-flc.ron",
    )
    .unwrap();
    for i in 0..2 {
        let c = &mut flc.servo.axes[i].controller;
        assert_eq!(
            c.fuzzy,
            Some(FuzzyConfig::from_ron_str(PAPER, "paper001.ron").unwrap()),
            "axis {i}"
        );
        *c = pid.servo.axes[i].controller.clone();
    }
    flc.name = pid.name.clone();
    assert_eq!(flc, pid);
}

#[test]
fn malformed_flc_in_a_profile_is_refused_with_its_path() {
    let bad = PAPER.replacen(
        r#"["PL", "PL", "PL", "PL", "PL", "PL", "PL"], // e = PL"#,
        r#"["PL", "PL", "PL", "PL", "PL", "PL", "XL"], // e = PL"#,
        1,
    );
    assert_ne!(bad, PAPER);
    let err = MachineProfile::from_ron_str(&mill_with_flc(&bad), "m.ron")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("servo.axes[1].controller.fuzzy.rules[6][6]"),
        "{err}"
    );
    let bad = PAPER.replacen("-14.0, -7.0, 0.0", "-14.0, -17.0, 0.0", 1);
    assert_ne!(bad, PAPER);
    let err = MachineProfile::from_ron_str(&mill_with_flc(&bad), "m.ron")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("servo.axes[1].controller.fuzzy.e.centres[2]"),
        "{err}"
    );
    // a type error inside the table: serde_path_to_error names the path
    let bad = PAPER.replacen("k_i: 0.1", "k_i: [0.1]", 1);
    let err = MachineProfile::from_ron_str(&mill_with_flc(&bad), "m.ron")
        .unwrap_err()
        .to_string();
    assert!(err.contains("servo.axes[1].controller.fuzzy.k_i"), "{err}");
}
