//! The paper profiles load, and a bad servo field is reported with its RON path.

use softnc_machine::MachineProfile;
use std::path::PathBuf;

fn machines() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines")
}

#[test]
fn paper_profiles_load() {
    for name in ["tnv40-pdc", "mill-friction", "tnv40-ilc", "default"] {
        let p = MachineProfile::load(&machines().join(format!("{name}.ron")))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(p.axes.len(), 3, "{name}");
    }
}

#[test]
fn bad_servo_field_names_its_ron_path() {
    let text = std::fs::read_to_string(machines().join("mill-friction.ron")).unwrap();
    let bad = text.replacen("tau_s: 0.056", "tau_s: -0.056", 1);
    assert_ne!(bad, text);
    let err = MachineProfile::from_ron_str(&bad, "m.ron")
        .unwrap_err()
        .to_string();
    assert!(err.contains("servo.axes[1].plant.tau_s"), "{err}");
    let bad = text.replacen("kd: 670.0", "kd: 670.0, kdd: 1.0", 1);
    let err = MachineProfile::from_ron_str(&bad, "m.ron")
        .unwrap_err()
        .to_string();
    assert!(err.contains("kdd"), "{err}");
}
