//! Paper 000 compensation in the cycle engine: designed from the profile, PDC
//! removes the periodic error on the TNV-40, a redesign is swapped in between
//! cycles, a failing design is refused.

use softnc_core::compensation::{
    Compensation, DobConfig, OuterCompensator, PdcConfig, UncertaintyPoint,
};
use softnc_core::MachineProfile;
use softnc_sim::{CycleEngine, SimBackend, SimOptions};
use std::path::PathBuf;

fn tnv40() -> MachineProfile {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/tnv40-pdc.ron");
    MachineProfile::load(&path).unwrap()
}

fn pdc() -> PdcConfig {
    PdcConfig::paper000(vec![
        UncertaintyPoint {
            freq_hz: 0.0,
            relative: 0.2,
        },
        UncertaintyPoint {
            freq_hz: 500.0,
            relative: 1.0,
        },
    ])
}

fn with(base: &MachineProfile, comp: Compensation) -> MachineProfile {
    let mut m = base.clone();
    for a in m.servo.axes.iter_mut().take(2) {
        a.compensation = comp.clone();
    }
    m
}

/// RMS of the X following error minus its mean over the last second of a 2 mm/s
/// move along X with the cutting disturbance on (mm).
fn ripple_rms(
    engine: &mut CycleEngine<SimBackend>,
    before_start: impl FnOnce(&mut CycleEngine<SimBackend>),
) -> f64 {
    let t = 0.001;
    engine.reset([0.0; 3]);
    before_start(engine);
    let mut errs = Vec::new();
    for k in 0..3000 {
        let x = 2.0 * t * k as f64;
        engine.step([x, 0.0, 0.0], true).unwrap();
        if k >= 2000 {
            errs.push(x - engine.backend().true_pos_mm()[0]);
        }
    }
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / errs.len() as f64).sqrt()
}

#[test]
fn pdc_from_the_profile_removes_the_periodic_error() {
    let base = tnv40();
    let dob = OuterCompensator::Dob(DobConfig {
        order_k: 3,
        relative_degree_r: 1,
        tau_s: 0.002,
    });
    let opts = SimOptions {
        quantisation: false,
        ..SimOptions::default()
    };
    let mut only_dob = CycleEngine::simulated(
        &with(
            &base,
            Compensation {
                outer: dob,
                pdc: None,
            },
        ),
        1,
        opts,
    );
    let mut dob_pdc = CycleEngine::simulated(
        &with(
            &base,
            Compensation {
                outer: dob,
                pdc: Some(pdc()),
            },
        ),
        1,
        opts,
    );
    let (a, b) = (
        ripple_rms(&mut only_dob, |_| {}),
        ripple_rms(&mut dob_pdc, |_| {}),
    );
    assert!(b < 0.2 * a, "DOB+PDC {b} vs DOB {a}");
}

#[test]
fn spindle_change_redesigns_and_swaps_between_cycles() {
    let base = tnv40();
    let comp = Compensation {
        outer: OuterCompensator::None,
        pdc: Some(pdc()),
    };
    let opts = SimOptions {
        quantisation: false,
        ..SimOptions::default()
    };
    // the machine runs at 1800 rpm (60 Hz)
    let mut at_1800 = with(&base, comp.clone());
    at_1800.servo.cutting.as_mut().unwrap().spindle_rpm = 1800.0;
    // controllers designed for the profile's 1500 rpm, the backend at 1800 rpm
    let stale = || {
        CycleEngine::try_new(
            &with(&base, comp.clone()),
            SimBackend::new(&at_1800, 1, opts),
        )
        .unwrap()
    };
    let e_stale = ripple_rms(&mut stale(), |_| {});
    let e_redesigned = ripple_rms(&mut stale(), |e| e.redesign_pdc(60.0).unwrap());
    let e_direct = ripple_rms(&mut CycleEngine::simulated(&at_1800, 1, opts), |_| {});
    assert!(
        (e_redesigned - e_direct).abs() <= 1e-9 + 1e-6 * e_direct,
        "{e_redesigned} vs {e_direct}"
    );
    assert!(
        e_redesigned < 0.5 * e_stale,
        "{e_redesigned} vs stale {e_stale}"
    );
}

#[test]
fn a_failing_design_is_refused_with_its_axis() {
    let mut bad = pdc();
    bad.uncertainty = vec![UncertaintyPoint {
        freq_hz: 0.0,
        relative: 3.0,
    }];
    let m = with(
        &tnv40(),
        Compensation {
            outer: OuterCompensator::None,
            pdc: Some(bad),
        },
    );
    let err = CycleEngine::try_new(&m, SimBackend::new(&m, 1, SimOptions::default())).unwrap_err();
    assert_eq!(err.axis(), 0);
    assert!(err.to_string().contains("eq 13"), "{err}");
}
