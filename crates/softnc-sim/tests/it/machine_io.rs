//! The simulated machine's lines through the shipped I/O map (`servo.io` of
//! config/machines/default*.ron): its spindle, switches, probe, tool changer,
//! E-stop chain and user lines, as the position cycle sees them.

use softnc_core::machine_io::{MachineOutputs, SpindleDir};
use softnc_core::Axes;
use softnc_machine::MachineProfile;
use softnc_servo::{CycleEngine, ServoBackend};
use softnc_sim::{wiring, SimBackend, SimOptions};
use std::path::PathBuf;

fn profile(name: &str) -> MachineProfile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/machines")
        .join(format!("{name}.ron"));
    MachineProfile::load(&path).unwrap()
}

fn engine(p: &MachineProfile) -> CycleEngine<SimBackend> {
    CycleEngine::new(p, SimBackend::new(p, 1, SimOptions::default()))
}

#[test]
fn the_spindle_reaches_speed_on_its_model_and_at_speed_says_so() {
    let p = profile("default");
    let mut e = engine(&p);
    let cycle_s = p.interpolation_cycle_s;
    e.set_outputs(&MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 12000.0,
        ..MachineOutputs::default()
    });
    let mut at_speed_s = None;
    for k in 1..=3000 {
        let m = e.exchange_io().unwrap();
        if m.spindle_at_speed && at_speed_s.is_none() {
            at_speed_s = Some(k as f64 * cycle_s);
        }
        if k == 100 {
            assert!(
                !m.spindle_at_speed,
                "at speed after 0.1 s: {}",
                m.spindle_rpm
            );
        }
    }
    let t = at_speed_s.expect("never at speed");
    println!("0 -> 12000 rpm within the 2 % band: {t} s");
    assert!((0.7..1.2).contains(&t), "at speed after {t} s");
    let m = *e.io().last_inputs();
    assert!((m.spindle_rpm - 12000.0).abs() < 30.0, "{}", m.spindle_rpm);
    // 3 s, 2 of them at 200 rev/s: the index counted every revolution
    assert_eq!(m.spindle_index_count, m.spindle_revs.floor() as u64);
    assert!(m.spindle_index_count > 400, "{}", m.spindle_index_count);
    // the trace columns
    let t = e.io().trace();
    assert_eq!(t.spindle_cmd_rpm, 12000.0);
    assert_eq!(t.spindle_rpm, m.spindle_rpm);
}

#[test]
fn limit_and_home_switches_trip_where_the_profile_puts_them() {
    let p = profile("default-incremental");
    let margin = p.servo.sim_io.unwrap().limit_switch_margin_mm;
    let mut e = engine(&p);
    // inside the travel: nothing
    e.reset([0.0, 0.0, 0.0]);
    let m = e.exchange_io().unwrap();
    assert_eq!((m.limit_min, m.limit_max, m.home), (0, 0, 0));
    // X on its home switch (405 mm, searched in +), Y past its max limit switch,
    // Z past its min one
    let x_home = p.homing.as_ref().unwrap().axes[0].switch_mm;
    e.reset([
        x_home + 0.001,
        p.axes[1].max_mm + margin + 0.01,
        p.axes[2].min_mm - margin - 0.01,
    ]);
    let m = e.exchange_io().unwrap();
    // (Y past its limit switch is past its home switch, 255 mm, too)
    assert_eq!(m.home, 1 << 0 | 1 << 1);
    assert_eq!(m.limit_max, 1 << 1);
    assert_eq!(m.limit_min, 1 << 2);
    // just short of them
    e.reset([
        x_home - 0.001,
        p.axes[1].max_mm + margin - 0.01,
        p.axes[2].min_mm - margin + 0.01,
    ]);
    let m = e.exchange_io().unwrap();
    assert_eq!((m.limit_min, m.limit_max, m.home), (0, 0, 1 << 1));
}

#[test]
fn the_probe_the_tool_changer_and_the_user_lines() {
    let p = profile("default");
    let plane = p.servo.sim_io.unwrap().probe_plane_z_mm.unwrap();
    let cycle_s = p.interpolation_cycle_s;
    let mut e = engine(&p);
    e.reset([0.0, 0.0, plane + 0.01]);
    assert!(!e.exchange_io().unwrap().probe);
    e.reset([0.0, 0.0, plane - 0.01]);
    assert!(e.exchange_io().unwrap().probe, "below the probe plane");
    e.backend_mut().simulated().unwrap().set_probe(Some(false));
    assert!(!e.exchange_io().unwrap().probe, "driven by the test");
    // the tool changer answers after its delay, and drops its answer with the request
    let mut o = MachineOutputs {
        tool_change: true,
        coolant_flood: true,
        digital: 1 << 3,
        ..MachineOutputs::default()
    };
    e.set_outputs(&o);
    let delay = (p.servo.sim_io.unwrap().tool_change_s / cycle_s).round() as usize;
    for k in 1..delay {
        assert!(
            !e.exchange_io().unwrap().tool_changed,
            "answered at cycle {k}"
        );
    }
    assert!(e.exchange_io().unwrap().tool_changed);
    // the outputs are observable on the machine
    let raw = e.backend_mut().simulated().unwrap().raw_outputs();
    assert_eq!(raw.digital >> wiring::OUT_FLOOD & 1, 1);
    assert_eq!(raw.digital >> wiring::OUT_MIST & 1, 0);
    assert_eq!(raw.digital >> (wiring::USER + 3) & 1, 1, "M62 P3");
    assert_eq!(raw.digital >> wiring::OUT_TOOL_CHANGE & 1, 1);
    o.tool_change = false;
    e.set_outputs(&o);
    assert!(!e.exchange_io().unwrap().tool_changed);
    // M66 P1 and E2 from outside
    let sim = e.backend_mut().simulated().unwrap();
    sim.set_digital_input(wiring::USER + 1, true);
    sim.set_analog_input(2, 4.5);
    let m = e.exchange_io().unwrap();
    assert_eq!(m.digital, 1 << 1);
    assert_eq!(m.analog[2], 4.5);
}

#[test]
fn the_estop_chain_latches_and_the_outputs_go_safe() {
    let p = profile("default");
    let mut e = engine(&p);
    e.set_outputs(&MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 6000.0,
        coolant_mist: true,
        ..MachineOutputs::default()
    });
    for _ in 0..500 {
        e.step(Axes::splat(0.0), false).unwrap();
    }
    let raw = e.backend_mut().simulated().unwrap().raw_outputs();
    assert!(raw.spindle.enable && raw.digital >> wiring::OUT_MACHINE_ON & 1 == 1);
    let turning = e.io().last_inputs().spindle_rpm;
    assert!(turning > 3000.0, "{turning}");
    // the chain opens for one cycle
    e.backend_mut().simulated().unwrap().set_estop_open(true);
    assert!(e.step(Axes::splat(0.0), false).is_ok());
    assert!(e.io().last_inputs().estop_open);
    e.backend_mut().simulated().unwrap().set_estop_open(false);
    e.step(Axes::splat(0.0), false).unwrap();
    assert!(e.io().last_inputs().estop_open, "latched");
    let raw = e.backend_mut().simulated().unwrap().raw_outputs();
    assert!(!raw.spindle.enable, "spindle stopped");
    for line in [
        wiring::OUT_MIST,
        wiring::OUT_MACHINE_ON,
        wiring::OUT_AMP_ENABLE,
    ] {
        assert_eq!(raw.digital >> line & 1, 0, "line {line}");
    }
    // the spindle brakes on its model
    for _ in 0..2000 {
        e.exchange_io().unwrap();
    }
    assert!(e.io().last_inputs().spindle_rpm.abs() < 30.0);
    assert!(e.io_mut().reset_estop());
}

#[test]
fn the_next_jobs_fresh_machine_keeps_what_the_world_set_on_its_lines() {
    let p = profile("default");
    let mut job1 = engine(&p);
    let sim = job1.backend_mut().simulated().unwrap();
    sim.set_estop_open(true);
    sim.set_digital_input(wiring::USER, true);
    job1.exchange_io().unwrap();
    assert!(job1.io().estop_latched());
    let mut job2 = engine(&p);
    job2.take_over(&mut job1, [1.0, 2.0, 3.0]);
    assert!(job2.io().estop_latched(), "the latch is the machine's");
    let m = job2.exchange_io().unwrap();
    assert!(m.estop_open && job2.io().estop_input_open());
    assert_eq!(m.digital, 1);
    // closed on the new machine: reset clears it
    job2.backend_mut()
        .simulated()
        .unwrap()
        .set_estop_open(false);
    job2.exchange_io().unwrap();
    assert!(job2.io_mut().reset_estop());
}

/// Each job runs on a fresh simulated machine (the daemon's `take_over`): the
/// spindle turning at the end of one job is the spindle of the next, still
/// turning at its speed with its angle and index count, not a spindle at rest.
#[test]
fn the_spindle_keeps_turning_into_the_next_jobs_fresh_machine() {
    let p = profile("default");
    let mut running = engine(&p);
    let cmd = MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 6000.0,
        ..MachineOutputs::default()
    };
    running.set_outputs(&cmd);
    for _ in 0..2000 {
        running.exchange_io().unwrap();
    }
    let before = *running.io().last_inputs();
    let true_rpm = running
        .backend_mut()
        .simulated()
        .unwrap()
        .spindle_true_rpm();
    assert!((true_rpm - 6000.0).abs() < 60.0, "{true_rpm}");
    let mut next = engine(&p);
    next.take_over(&mut running, Axes::splat(0.0));
    let sim = next.backend_mut().simulated().unwrap();
    assert_eq!(
        sim.spindle_true_rpm(),
        true_rpm,
        "the spindle started at rest"
    );
    // the next job commands it on: it is at speed at once, its encoder goes on
    next.set_outputs(&cmd);
    let m = next.exchange_io().unwrap();
    assert!(m.spindle_at_speed, "{}", m.spindle_rpm);
    assert!(m.spindle_revs > before.spindle_revs);
    assert!(m.spindle_index_count >= before.spindle_index_count);
    // an M5 in it brakes the same spindle
    next.set_outputs(&MachineOutputs::default());
    for _ in 0..3000 {
        next.exchange_io().unwrap();
    }
    let sim = next.backend_mut().simulated().unwrap();
    assert!(
        sim.spindle_true_rpm().abs() < 1e-6,
        "{}",
        sim.spindle_true_rpm()
    );
}

#[test]
fn m19_orients_the_spindle_model_from_its_index_and_reports_it_oriented() {
    let p = profile("default");
    let spindle = p.servo.spindle.expect("the default profile's spindle");
    let mut e = engine(&p);
    e.set_outputs(&MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 3000.0,
        ..MachineOutputs::default()
    });
    for _ in 0..1500 {
        assert!(!e.exchange_io().unwrap().spindle_oriented);
    }
    // M19 R90 (the path's outputs: the spindle stopped, orienting)
    let count_deg = 360.0 / f64::from(spindle.encoder_counts_per_rev);
    for (angle, dir) in [(90.0, 0u8), (300.0, 1), (45.5, 2)] {
        e.set_outputs(&MachineOutputs {
            spindle_orient_deg: Some(angle),
            spindle_orient_dir: dir,
            ..MachineOutputs::default()
        });
        let k = (1..=5000)
            .find(|_| e.exchange_io().unwrap().spindle_oriented)
            .expect("never oriented");
        // held there
        for _ in 0..500 {
            assert!(e.exchange_io().unwrap().spindle_oriented);
        }
        let m = *e.io().last_inputs();
        let at = m.spindle_revs.rem_euclid(1.0) * 360.0;
        let err = (at - angle + 180.0).rem_euclid(360.0) - 180.0;
        println!(
            "M19 R{angle} P{dir}: oriented after {:.3} s, encoder angle {at:.3} deg, error {err:.4} deg (band {} deg), {:.2} rpm",
            k as f64 * p.interpolation_cycle_s,
            spindle.orient_band_deg,
            m.spindle_rpm
        );
        assert!(err.abs() <= spindle.orient_band_deg, "{err} deg");
        assert!(err.abs() <= count_deg, "{err} deg: more than a count");
        assert!(m.spindle_rpm.abs() < 15.0, "{} rpm", m.spindle_rpm);
    }
    // M3 again: no longer oriented
    e.set_outputs(&MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 600.0,
        ..MachineOutputs::default()
    });
    assert!(!e.exchange_io().unwrap().spindle_oriented);
}
