//! What every `ServoBackend` must do, written once and run on each backend (today the
//! simulated machine of every profile; a real drive's backend runs the same checks).

use softnc_core::MachineProfile;
use softnc_sim::{CommandMode, ServoBackend, SimBackend, SimOptions, MAX_AXES};
use std::path::PathBuf;

/// Homing, a cycle at rest, and the counts' scale.
fn conformance<B: ServoBackend>(name: &str, b: &mut B) {
    assert!(b.axes() >= 1 && b.axes() <= MAX_AXES, "{name}: axes");
    let home = [12.5, -7.25, 3.0];
    b.home(home);
    for (i, &home_mm) in home.iter().enumerate().take(b.axes()) {
        let res = b.mm_per_count(i);
        assert!(res > 0.0 && res.is_finite(), "{name}: axis {i} resolution");
        let counts = b.read_counts()[i];
        let pos = counts as f64 * res;
        assert!(
            (pos - home_mm).abs() <= res,
            "{name}: axis {i} homed to {pos}, not {home_mm}"
        );
        assert!(b.read_status()[i].enabled, "{name}: axis {i} not enabled");
        assert!(
            !b.read_status()[i].fault,
            "{name}: axis {i} faulted at rest"
        );
    }
    // holding command: position mode gets the home position, others zero effort
    let hold = [0, 1, 2].map(|i| match b.command_mode(i) {
        CommandMode::Position => home[i],
        CommandMode::Velocity | CommandMode::Effort => 0.0,
    });
    let before = b.read_counts();
    for _ in 0..100 {
        b.write_commands(hold);
        b.cycle().unwrap();
    }
    assert_eq!(b.read_counts(), before, "{name}: moved while held");
    for c in b.read_currents() {
        assert!(c.is_finite(), "{name}: current");
    }
}

#[test]
fn simulated_backend_conforms_for_every_profile() {
    for name in ["mill-friction", "tnv40-pdc", "tnv40-ilc", "default"] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../config/machines")
            .join(format!("{name}.ron"));
        let p = MachineProfile::load(&path).unwrap();
        let opts = SimOptions {
            noise: false,
            ..SimOptions::default()
        };
        conformance(name, &mut SimBackend::new(&p, 1, opts));
    }
}
