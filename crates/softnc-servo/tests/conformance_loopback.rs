//! The loopback backend passes the same conformance suite as the simulated machine,
//! and follows its command exactly.

use softnc_machine::MachineProfile;
use softnc_servo::{conformance, CycleEngine, LoopbackBackend, ServoBackend};
use std::path::PathBuf;

fn profile(name: &str) -> MachineProfile {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/machines")
        .join(format!("{name}.ron"));
    MachineProfile::load(&path).unwrap()
}

#[test]
fn loopback_conforms() {
    for name in ["default", "mill-friction", "tnv40-ilc"] {
        let p = profile(name);
        conformance::run(&format!("loopback/{name}"), &p, &LoopbackBackend::new);
        conformance::deterministic(&format!("loopback/{name}"), &p, &LoopbackBackend::new);
    }
}

#[test]
fn loopback_is_where_it_was_commanded_one_cycle_later() {
    let p = profile("default");
    let mut e = CycleEngine::new(&p, LoopbackBackend::new());
    e.reset([1.0, 2.0, 3.0]);
    let mut last = [1.0, 2.0, 3.0];
    for k in 0..1000 {
        let t = k as f64 * 1e-3;
        let cmd = [1.0 + t.sin(), 2.0 + t.cos(), 3.0 - t];
        let rec = e.step(cmd, true).unwrap();
        // measured at the start of the cycle: the previous command, to a nanometre
        for (i, (act, want)) in rec.actual_mm.iter().zip(last).enumerate() {
            assert!((act - want).abs() <= 1e-9, "cycle {k} axis {i}");
        }
        last = cmd;
    }
    e.backend_mut().disable();
    let held = e.measured_mm();
    e.step([50.0; 3], false).unwrap();
    e.step([50.0; 3], false).unwrap();
    assert_eq!(e.measured_mm(), held, "disabled: it stays");
    assert!(e.backend().read_status().iter().all(|s| !s.enabled));
}

/// A backend that keeps following commands after `disable` (a drive that ignores
/// its control word): the suite must catch it.
struct IgnoresDisable(LoopbackBackend);

impl ServoBackend for IgnoresDisable {
    fn axes(&self) -> usize {
        self.0.axes()
    }
    fn command_mode(&self, axis: usize) -> softnc_servo::CommandMode {
        self.0.command_mode(axis)
    }
    fn mm_per_count(&self, axis: usize) -> f64 {
        self.0.mm_per_count(axis)
    }
    fn enable(&mut self) -> Result<(), softnc_servo::BackendError> {
        self.0.enable()
    }
    fn disable(&mut self) {}
    fn home(&mut self, pos_mm: softnc_core::Axes<f64>) {
        self.0.home(pos_mm)
    }
    fn write_commands(&mut self, cmd: softnc_core::Axes<f64>) {
        self.0.write_commands(cmd)
    }
    fn cycle(&mut self) -> Result<(), softnc_servo::BackendError> {
        self.0.cycle()
    }
    fn read_counts(&self) -> softnc_core::Axes<i64> {
        self.0.read_counts()
    }
    fn read_currents(&self) -> softnc_core::Axes<f64> {
        self.0.read_currents()
    }
    fn read_status(&self) -> softnc_core::Axes<softnc_servo::AxisStatus> {
        self.0.read_status()
    }
}

#[test]
#[should_panic(expected = "enabled after disable()")]
fn the_suite_catches_a_drive_that_ignores_disable() {
    let p = profile("default");
    conformance::run("ignores-disable", &p, &|| {
        IgnoresDisable(LoopbackBackend::new())
    });
}

#[test]
fn loopback_echoes_its_outputs_to_its_inputs() {
    use softnc_core::machine_io::{MachineOutputs, SpindleDir};
    let p = profile("default");
    let mut e = CycleEngine::new(&p, LoopbackBackend::new());
    let mut o = MachineOutputs {
        spindle_dir: SpindleDir::CounterClockwise,
        spindle_rpm: 5000.0,
        digital: 1 << 2,
        ..MachineOutputs::default()
    };
    o.analog[1] = 3.5;
    e.set_outputs(&o);
    e.set_output_state(softnc_servo::io::OutputState {
        spindle_override: 0.5,
        ..Default::default()
    });
    // through the shipped map: M62 P2 → line 66 → M66 P2, M67 E1 → E1, the spindle
    // at its command at once
    e.step([0.0; 3], false).unwrap();
    let m = *e.io().last_inputs();
    assert_eq!(m.digital, 1 << 2);
    assert_eq!(m.analog[1], 3.5);
    assert_eq!(m.spindle_rpm, -2500.0);
    assert!(m.spindle_at_speed && !m.estop_open);
    // a tool-change request is answered on its own line at once
    o.tool_change = true;
    e.set_outputs(&o);
    assert!(e.exchange_io().unwrap().tool_changed);
    // raw: out line k is in line k
    let b = e.backend_mut();
    let raw = softnc_servo::RawOutputs {
        digital: 1 << 127 | 1 << 16,
        ..Default::default()
    };
    b.write_io(&raw);
    b.exchange_io().unwrap();
    let echoed = b.read_io();
    assert_eq!(echoed.digital, raw.digital);
    // line 16 is the shipped map's E-stop: the echo opened it, and it latches
    assert!(e.io_mut().inputs(&echoed).estop_open);
    assert!(e.exchange_io().unwrap().estop_open, "latched");
    assert!(e.io_mut().reset_estop());
}

/// A spindle that reports feedback but never turns: the suite must catch it.
struct DeadSpindle(LoopbackBackend);

impl ServoBackend for DeadSpindle {
    fn axes(&self) -> usize {
        self.0.axes()
    }
    fn command_mode(&self, axis: usize) -> softnc_servo::CommandMode {
        self.0.command_mode(axis)
    }
    fn mm_per_count(&self, axis: usize) -> f64 {
        self.0.mm_per_count(axis)
    }
    fn enable(&mut self) -> Result<(), softnc_servo::BackendError> {
        self.0.enable()
    }
    fn disable(&mut self) {
        self.0.disable()
    }
    fn home(&mut self, pos_mm: softnc_core::Axes<f64>) {
        self.0.home(pos_mm)
    }
    fn write_commands(&mut self, cmd: softnc_core::Axes<f64>) {
        self.0.write_commands(cmd)
    }
    fn cycle(&mut self) -> Result<(), softnc_servo::BackendError> {
        self.0.cycle()
    }
    fn read_counts(&self) -> softnc_core::Axes<i64> {
        self.0.read_counts()
    }
    fn read_currents(&self) -> softnc_core::Axes<f64> {
        self.0.read_currents()
    }
    fn read_status(&self) -> softnc_core::Axes<softnc_servo::AxisStatus> {
        self.0.read_status()
    }
    fn io_lines(&self) -> softnc_servo::IoLines {
        softnc_servo::IoLines::ALL
    }
}

#[test]
#[should_panic(expected = "commanded 1000 rpm")]
fn the_suite_catches_a_spindle_that_does_not_turn() {
    let p = profile("default");
    conformance::run_io("dead-spindle", &p, &|| DeadSpindle(LoopbackBackend::new()));
}
