//! Paper 001 Sec. 4.1: K and τ vary ±5 %, friction ±8 %, drawn from the seed.

use softnc_machine::MachineProfile;
use softnc_sim::{Plant, SimBackend, SimOptions};
use std::path::PathBuf;

#[test]
fn parameter_variation_stays_in_its_band_and_follows_the_seed() {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/mill-friction.ron");
    let p = MachineProfile::load(&path).unwrap();
    let nominal_k = 28.35 / 60.0;
    let nominal_tau = 0.055;
    let mut gains = Vec::new();
    for seed in 0..200 {
        let b = SimBackend::new(&p, seed, SimOptions::default());
        let Plant::DcMotor(m) = b.plant(0) else {
            panic!("X of mill-friction is a DC motor")
        };
        let (k, tau) = (m.gain_mm_per_s_per_dac(), m.tau_s());
        assert!(
            (k / nominal_k - 1.0).abs() <= 0.05 + 1e-12,
            "seed {seed}: K {k}"
        );
        assert!(
            (tau / nominal_tau - 1.0).abs() <= 0.05 + 1e-12,
            "seed {seed}: τ {tau}"
        );
        let brk = m.breakaway().pos / 20.49;
        assert!(
            (brk - 1.0).abs() <= 0.08 + 1e-12,
            "seed {seed}: friction x{brk}"
        );
        gains.push(k);
        // the same seed gives the same machine
        let again = SimBackend::new(&p, seed, SimOptions::default());
        assert_eq!(again.plant(0), b.plant(0));
    }
    // the draws use the band: some near each edge
    let lo = gains.iter().cloned().fold(f64::MAX, f64::min) / nominal_k;
    let hi = gains.iter().cloned().fold(f64::MIN, f64::max) / nominal_k;
    assert!(lo < 0.96 && hi > 1.04, "K/K0 in [{lo}, {hi}]");
    // switched off: nominal
    let off = SimOptions {
        variation: false,
        ..SimOptions::default()
    };
    let Plant::DcMotor(m) = SimBackend::new(&p, 5, off).plant(0).clone() else {
        unreachable!()
    };
    assert_eq!(m.tau_s(), nominal_tau);
}
