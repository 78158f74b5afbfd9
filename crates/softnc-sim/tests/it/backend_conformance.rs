//! The simulated machine of every profile passes the servo boundary's conformance
//! suite (`softnc_servo::conformance`), the one every backend runs against itself.

use softnc_machine::MachineProfile;
use softnc_servo::conformance;
use softnc_sim::{SimBackend, SimOptions};
use std::path::PathBuf;

fn profile(name: &str) -> MachineProfile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/machines")
        .join(format!("{name}.ron"));
    MachineProfile::load(&path).unwrap()
}

#[test]
fn simulated_backend_conforms_for_every_profile() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok()?.path().file_stem()?.to_str().map(String::from))
        .collect();
    names.sort();
    assert!(names.len() >= 8, "{names:?}");
    for name in names {
        let p = profile(&name);
        // quiet encoders: at rest the counts stand still to a count
        let opts = SimOptions {
            noise: false,
            ..SimOptions::default()
        };
        conformance::run(&name, &p, &|| SimBackend::new(&p, 1, opts));
        conformance::deterministic(&name, &p, &|| SimBackend::new(&p, 1, SimOptions::default()));
    }
}
