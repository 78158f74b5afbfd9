//! The profile's `force` section (schema and validation in `softnc-adaptive`),
//! loaded as part of a machine profile: refused values name their RON path.

use softnc_core::config::ConfigError;
use softnc_machine::MachineProfile;

const PROFILE: &str = include_str!("../../../config/machines/mch10-force.ron");

#[test]
fn the_paper_003_profile_loads() {
    let p = MachineProfile::from_ron_str(PROFILE, "mch10-force.ron").unwrap();
    let f = p.force.unwrap();
    assert_eq!(f.cases.len(), 4);
    assert!(f.case("I").is_some() && f.material("SM45C").is_some());
}

#[test]
fn bad_force_values_are_refused_with_their_path() {
    for (from, to, path) in [
        (
            "material: \"SM45C\", paper",
            "material: \"brass\", paper",
            "force.cases[1].segments[1].material",
        ),
        (
            "override_max: 2.55",
            "override_max: 3.0",
            "force.controller.override_max",
        ),
        (
            "poles: (0.4, 0.45, 0.65, 0.7),\n            rls",
            "poles: (0.4, 0.45, 1.65, 0.7),\n            rls",
            "force.controller.poles",
        ),
        ("pole_pairs: 4", "pole_pairs: 0", "force.motor.pole_pairs"),
    ] {
        assert!(PROFILE.contains(from), "{from}");
        let text = PROFILE.replacen(from, to, 1);
        match MachineProfile::from_ron_str(&text, "m.ron") {
            Err(ConfigError::Invalid { path: p, .. }) => assert_eq!(p, path),
            other => panic!("{from}: {other:?}"),
        }
    }
}
