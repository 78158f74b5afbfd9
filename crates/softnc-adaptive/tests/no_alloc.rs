//! The adaptive force loop's per-sample path allocates nothing (counting global
//! allocator): the RLS update on nalgebra's `Vector4`/`Matrix4` (003 eq 11–12), the
//! pole placement's 4×4 LU solve (eq 13–22), the servo law and the whole
//! [`ForceLoop::cycle`] — phase currents in, feed override out — that a controller
//! steps every interpolation cycle.
//!
//! Only allocations made by the test's own thread are counted: the test harness's
//! other threads may allocate at any time.

use nalgebra::Vector4;
use softnc_adaptive::robust_servo::{characteristic_polynomial, closed_loop_matrix};
use softnc_adaptive::{
    place_poles, zoh_second_order, ForceCalibration, ForceControlConfig, ForceLoop,
    ForceLoopConfig, ForceLoopControl, Rls, RlsConfig, RobustServo,
};

use softnc_test_support::{allocations as allocs, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Phase currents of a motor producing I_q = `iq` at electrical angle `theta_e`
/// (i_d = 0): inverse Park and Clarke.
fn currents(iq: f64, theta_e: f64) -> (f64, f64) {
    let (alpha, beta) = (-iq * theta_e.sin(), iq * theta_e.cos());
    (alpha, -0.5 * alpha + 3f64.sqrt() / 2.0 * beta)
}

/// The counter works: a `Vec` allocates on this thread.
fn assert_counter_counts() {
    let before = allocs();
    let v: Vec<u64> = Vec::with_capacity(8);
    assert!(
        allocs() > before,
        "the counting allocator saw no allocation"
    );
    drop(v);
}

#[test]
fn rls_pole_placement_and_servo_allocate_nothing() {
    let t_s = 0.1;
    let plant = zoh_second_order(3.0, 0.05, 0.25, t_s);
    let cfg = RlsConfig {
        p0: 1e3,
        forgetting: 0.99,
        dead_zone: 1e-9,
        reset_trace: 1e-3,
    };
    let mut rls = Rls::new(cfg, Vector4::new(0.5, 0.0, 0.1, 0.1));
    let mut servo = RobustServo::default();
    let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 0.0, 0.0);
    let mut x = 7u64;
    let mut checksum = 0.0;
    let before = allocs();
    for t in 0..20_000 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = if (x >> 33) & 1 == 1 { 1.0 } else { -1.0 };
        let y = -plant.phi1 * y1 - plant.phi2 * y2 + plant.theta1 * u1 + plant.theta2 * u2;
        checksum += rls.update(&Vector4::new(y1, y2, u1, u2), y);
        let poles = [0.4, 0.45, 0.65, 0.7 - 1e-6 * (t % 7) as f64];
        let g = place_poles(&plant, poles, t_s).expect("placeable");
        let cp = characteristic_polynomial(&closed_loop_matrix(&plant, &g, t_s));
        checksum += servo.step(&g, y, 1.0, t_s) + cp[4];
        (y2, y1, u2, u1) = (y1, y, u1, u);
    }
    let after = allocs();
    assert!(checksum.is_finite());
    // the estimator did adapt: it identified the plant
    for (a, b) in rls.theta().iter().zip(plant.theta().iter()) {
        assert!(
            (a - b).abs() < 1e-6,
            "{:?} vs {:?}",
            rls.theta(),
            plant.theta()
        );
    }
    assert_eq!(after - before, 0, "RLS / placement / servo allocated");
    assert_counter_counts();
}

#[test]
fn the_force_loop_cycle_allocates_nothing() {
    let t_s = 0.1;
    let plant = zoh_second_order(2.0, 0.15, 0.3, t_s);
    let calibration = ForceCalibration {
        a_per_n: 0.01,
        b_a: 1.0,
    };
    let control = ForceLoopControl {
        config: ForceControlConfig {
            poles: [0.4, 0.45, 0.65, 0.7],
            t_s,
            rls: RlsConfig {
                p0: 1e-2,
                forgetting: 1.0,
                dead_zone: 1e-3,
                reset_trace: 1e-5,
            },
            prior: zoh_second_order(1.0, 0.2, 0.2, t_s),
            v_min: 0.0,
            v_max: 510.0,
            dv_max: 50.0,
        },
        force_ref_n: 300.0,
    };
    let cycles = 10u64;
    let mut lp = ForceLoop::new(ForceLoopConfig {
        calibration,
        cycles_per_revolution: cycles,
        programmed_feed: 200.0,
        control: Some(control),
    })
    .expect("the prior model is placeable");
    let (mut y1, mut y2, mut u1, mut u2) = (0.0, 0.0, 200.0, 200.0);
    let (mut revolutions, mut accepted) = (0u64, 0u64);
    let mut force = 0.0;
    let before = allocs();
    for rev in 0..2_000u64 {
        // a depth of cut that steps every 300 revolutions keeps the estimator adapting
        let depth = if (rev / 300) % 2 == 0 { 1.0 } else { 1.6 };
        force =
            -plant.phi1 * y1 - plant.phi2 * y2 + depth * (plant.theta1 * u1 + plant.theta2 * u2);
        let iq = calibration.a_per_n * force + calibration.b_a;
        for k in 0..cycles {
            let th = 0.7 * (rev * cycles + k) as f64;
            let (i_u, i_v) = currents(iq, th);
            if let Some(r) = lp.cycle(i_u, i_v, th) {
                revolutions += 1;
                if r.control.is_some_and(|c| c.model_accepted) {
                    accepted += 1;
                }
                (y2, y1, u2, u1) = (y1, force, u1, r.feed_cmd);
            }
        }
    }
    let after = allocs();
    assert_eq!(revolutions, 2_000);
    assert!(accepted > 0, "the estimator never updated the gains");
    assert!(force.is_finite());
    assert_eq!(after - before, 0, "ForceLoop::cycle allocated");
    assert_counter_counts();
}
