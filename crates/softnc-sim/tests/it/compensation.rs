//! Paper 000 compensation in the cycle engine: designed from the profile, PDC
//! removes the periodic error on the TNV-40, a redesign is swapped in between
//! cycles, a failing design is refused.

use softnc_machine::compensation::{
    Compensation, DobConfig, OuterCompensator, PdcConfig, UncertaintyPoint,
};
use softnc_machine::MachineProfile;
use softnc_servo::CycleEngine;
use softnc_sim::{simulated_engine, SimBackend, SimOptions};
use std::path::PathBuf;

fn tnv40() -> MachineProfile {
    let path =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/tnv40-pdc.ron");
    MachineProfile::load(&path).unwrap()
}

fn pdc() -> PdcConfig {
    softnc_core::ron_file::parse_ron::<PdcConfig>(
        include_str!("../../../../config/pdc/paper000-canceller.ron"),
        "config/pdc/paper000-canceller.ron",
    )
    .unwrap()
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
    detrended_rms(&errs)
}

/// RMS of `errs` about their mean.
fn detrended_rms(errs: &[f64]) -> f64 {
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
    let mut only_dob = simulated_engine(
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
    let mut dob_pdc = simulated_engine(
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
    let e_direct = ripple_rms(&mut simulated_engine(&at_1800, 1, opts), |_| {});
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

/// RMS of the X following error minus its mean over the last second of a 2 mm/s
/// move along X stepped through the command ring: motion 0 for the first second,
/// motion 1 after it.
fn ripple_rms_ring(engine: &mut CycleEngine<SimBackend>) -> f64 {
    ripple_rms_ring_with(engine, |_, _| {})
}

/// [`ripple_rms_ring`] with `between(k, engine)` called before cycle `k`.
fn ripple_rms_ring_with(
    engine: &mut CycleEngine<SimBackend>,
    mut between: impl FnMut(u64, &mut CycleEngine<SimBackend>),
) -> f64 {
    let t = 0.001;
    engine.reset([0.0; 3]);
    let mut ring = Box::new(softnc_core::CommandRing::new());
    ring.reset_padded(engine.filter_window());
    let x = |k: u64| 2.0 * t * k as f64;
    let mut errs = Vec::new();
    for k in 0..3000u64 {
        ring.push(
            softnc_core::RingSample {
                seq: k,
                pos_mm: [x(k), 0.0, 0.0],
            },
            k == 2999,
        )
        .unwrap();
        let motion = u32::from(k >= 1000);
        between(k, engine);
        engine.step_ring(&ring, motion, true).unwrap().unwrap();
        if k >= 2000 {
            errs.push(x(k) - engine.backend().true_pos_mm()[0]);
        }
        ring.advance();
    }
    detrended_rms(&errs)
}

/// The TNV-40 with a PDC on X and Y, spindle at 1500 rpm, and the simulator's options
/// (no quantisation: the ripple is measured below the encoder's count).
fn tnv40_with_pdc() -> (MachineProfile, SimOptions) {
    let comp = Compensation {
        outer: OuterCompensator::None,
        pdc: Some(pdc()),
    };
    let opts = SimOptions {
        quantisation: false,
        ..SimOptions::default()
    };
    (with(&tnv40(), comp), opts)
}

/// The ripple when the machine turns at 1800 rpm with the PDC still designed for
/// `m1500`'s 1500 rpm (stale), and of a job at 1800 rpm from the start (direct).
fn stale_and_direct_at_1800(m1500: &MachineProfile, opts: SimOptions) -> (f64, f64) {
    let mut m1800 = m1500.clone();
    m1800.servo.cutting.as_mut().unwrap().spindle_rpm = 1800.0;
    let mut stale = CycleEngine::try_new(m1500, SimBackend::new(&m1800, 1, opts)).unwrap();
    let mut direct = simulated_engine(&m1800, 1, opts);
    (ripple_rms_ring(&mut stale), ripple_rms_ring(&mut direct))
}

#[test]
fn an_s_word_mid_job_redesigns_the_pdc_at_its_cycle() {
    let (m1500, opts) = tnv40_with_pdc();
    // the job: S1500 M3 from motion 0, S1800 from motion 1
    let changes = [(0u32, 1500.0), (1, 1800.0)];
    let mut followed = simulated_engine(&m1500, 1, opts);
    followed
        .set_spindle_schedule(&m1500, &changes, 1.0)
        .unwrap();
    assert_eq!(
        followed.spindle_schedule().unwrap().speeds_rpm(),
        &[1500.0, 1800.0]
    );
    let e_followed = ripple_rms_ring(&mut followed);
    assert_eq!(followed.spindle_schedule().unwrap().active_rpm(), 1800.0);
    let (e_stale, e_direct) = stale_and_direct_at_1800(&m1500, opts);
    assert!(
        e_followed < 0.5 * e_stale,
        "{e_followed} vs stale {e_stale}"
    );
    assert!(
        (e_followed - e_direct).abs() < 0.1 * e_direct + 1e-6,
        "{e_followed} vs direct {e_direct}"
    );
    // a speed whose design fails eq 13 refuses the job before motion
    let mut bad = simulated_engine(&m1500, 1, opts);
    assert!(bad
        .set_spindle_schedule(&m1500, &[(0, 29_000.0)], 1.0)
        .is_err());
}

#[test]
fn a_spindle_override_mid_job_redesigns_every_speed_off_the_cycle() {
    let (m1500, opts) = tnv40_with_pdc();
    // the job runs S1500 throughout; the operator turns the spindle override to 120 %
    // at 0.5 s: a design thread makes the table, the cycle installs it
    let changes = [(0u32, 1500.0)];
    let mut overridden = simulated_engine(&m1500, 1, opts);
    overridden
        .set_spindle_schedule(&m1500, &changes, 1.0)
        .unwrap();
    let designer = overridden.spindle_designer(&m1500, &changes).unwrap();
    let designs = std::thread::spawn(move || designer.design(1.2).unwrap())
        .join()
        .unwrap();
    assert_eq!(
        designs.fd_hz,
        vec![60.0],
        "1500 rpm × 120 % × 2 flutes / 60"
    );
    let mut designs = Some(Box::new(designs));
    let mut replaced = Vec::new();
    let e_overridden = ripple_rms_ring_with(&mut overridden, |k, e| {
        if let Some(old) = e.take_replaced_spindle_designs() {
            replaced.push((k, old));
        }
        if k == 500 {
            e.install_spindle_designs(designs.take().unwrap()).unwrap();
        }
    });
    let s = overridden.spindle_schedule().unwrap();
    assert_eq!((s.override_frac(), s.effective_rpm()), (1.2, 1800.0));
    assert_eq!(s.active_fd_hz(), 60.0);
    // the job's start table comes back after the first cycle, the override's
    // replaced table after the cycle that swapped it, holding the taps that ran
    assert_eq!(
        replaced.len(),
        2,
        "{:?}",
        replaced.iter().map(|r| r.0).collect::<Vec<_>>()
    );
    assert_eq!(replaced[1].0, 501, "back before the cycle after the swap");
    assert_eq!(replaced[1].1.override_frac, 1.0);
    assert!(
        replaced[1].1.taps[0][0].is_some(),
        "the 1500 rpm taps came back"
    );
    let (e_stale, e_direct) = stale_and_direct_at_1800(&m1500, opts);
    eprintln!(
        "ripple RMS after a 120 % override: redesigned {:.2} nm, stale {:.2} nm, at 1800 rpm from the start {:.2} nm",
        e_overridden * 1e6,
        e_stale * 1e6,
        e_direct * 1e6
    );
    assert!(
        e_overridden < 0.5 * e_stale,
        "{e_overridden} vs stale {e_stale}"
    );
    assert!(
        (e_overridden - e_direct).abs() < 0.1 * e_direct + 1e-6,
        "{e_overridden} vs direct {e_direct}"
    );
    // an override whose design fails eq 13 is refused on the design thread
    let designer = overridden.spindle_designer(&m1500, &changes).unwrap();
    assert!(designer.design(19.0).is_err());
}
