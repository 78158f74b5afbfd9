//! Cost of one per-axis step of the paper-000 stack: P position controller + DOB +
//! PDC (target ≤ 300 ns per axis), with the DOB and PDC on their own and the
//! simulated plant alone for reference.
//!
//! Design data are those of `config/pdc/tnv40.ron` (paper 000: zeros, 3-tap W,
//! Q filter K = 3, r = 1, τ = 2 ms) on P_nx (eq 35); the designs run outside the
//! timed loop.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use softnc_control::compensation::AxisCompensation;
use softnc_control::config::compensation::{Compensation, OuterCompensator};
use softnc_control::config::ControllerConfig;
use softnc_control::discrete_tf::{DiscreteTf, TfFilter};
use softnc_control::dob::{Dob, DobConfig};
use softnc_control::pdc::{self, Pdc, PdcConfig, UncertaintyPoint};
use softnc_control::AxisController;

const T_S: f64 = 0.001;

fn pnx() -> DiscreteTf {
    DiscreteTf::new(vec![0.0, 0.1894, -0.1866], vec![1.0, -1.8106, 0.8134]).unwrap()
}

fn pdc_config() -> PdcConfig {
    PdcConfig {
        robust_grid_points: 2000,
        w_dc_block_level: 0.5,
        uncertainty: vec![
            UncertaintyPoint {
                freq_hz: 0.0,
                relative: 0.2,
            },
            UncertaintyPoint {
                freq_hz: 100.0,
                relative: 0.3,
            },
            UncertaintyPoint {
                freq_hz: 500.0,
                relative: 1.0,
            },
        ],
        ..softnc_core::ron_file::parse_ron::<PdcConfig>(
            include_str!("../../../config/pdc/paper000-canceller.ron"),
            "config/pdc/paper000-canceller.ron",
        )
        .unwrap()
    }
}

fn bench(c: &mut Criterion) {
    let model = pnx();
    let design = pdc::design(&pdc_config(), &model, T_S, 50.0).unwrap();
    let dob_cfg = DobConfig {
        order_k: 3,
        relative_degree_r: 3,
        tau_s: 0.002,
    };
    let p_cfg = ControllerConfig {
        kp: 30.0,
        vff: 1.0,
        ..ControllerConfig::default()
    };
    let cmds: Vec<f64> = (0..1024).map(|k| 0.002 * k as f64).collect();
    let mut k = 0usize;

    // the stack as the engine runs it: P + feedforward, then the compensation block
    // (position-difference speed, DOB, PDC) inside AxisController::step
    let comp = Compensation {
        outer: OuterCompensator::Dob(dob_cfg),
        pdc: Some(pdc_config()),
    };
    let mut ctrl = AxisController::new(&p_cfg, T_S);
    ctrl.compensation = Some(Box::new(
        AxisCompensation::design(&comp, &model, T_S, 10.0, Some(50.0)).unwrap(),
    ));
    ctrl.reset(0.0);
    let mut x_mm = 0.0;
    c.bench_function("axis_controller_step_p_dob_pdc", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            let u = ctrl.step(black_box(cmds[k]), black_box(x_mm)).u;
            x_mm += 0.001 * (cmds[k] - x_mm);
            black_box(u)
        })
    });

    let mut ctrl = AxisController::new(&p_cfg, T_S);
    ctrl.reset(0.0);
    let mut dob = Dob::design(&dob_cfg, &model, T_S).unwrap();
    let mut pdc = Pdc::new(&design);
    let mut plant = TfFilter::new(&model);
    x_mm = 0.0;
    c.bench_function("stack_p_dob_pdc_step_with_plant", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            let y = plant.pending_output();
            x_mm += y * T_S;
            let u = ctrl.step(black_box(cmds[k]), x_mm).u;
            let v = pdc.step(dob.step(u, y), y);
            plant.step(black_box(v));
            black_box(v)
        })
    });

    let mut ctrl = AxisController::new(&p_cfg, T_S);
    ctrl.reset(0.0);
    let mut dob = Dob::design(&dob_cfg, &model, T_S).unwrap();
    let mut pdc = Pdc::new(&design);
    c.bench_function("stack_p_dob_pdc_step", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            let y = black_box(cmds[(k + 3) & 1023]);
            let u = ctrl.step(black_box(cmds[k]), y).u;
            black_box(pdc.step(dob.step(u, y), y))
        })
    });

    let mut dob = Dob::design(&dob_cfg, &model, T_S).unwrap();
    c.bench_function("dob_step", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(dob.step(black_box(cmds[k]), black_box(cmds[(k + 5) & 1023])))
        })
    });
    let mut pdc = Pdc::new(&design);
    c.bench_function("pdc_step", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(pdc.step(black_box(cmds[k]), black_box(cmds[(k + 5) & 1023])))
        })
    });
    let mut plant = TfFilter::new(&model);
    c.bench_function("plant_step", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(plant.step(black_box(cmds[k])))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
