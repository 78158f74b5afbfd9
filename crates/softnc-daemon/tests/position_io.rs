//! The machine around the axes on the position cycle (the simulated machine of
//! config/machines/default.ron, its I/O map): a sample's outputs switch when it is
//! the sample in use; an opened E-stop input stops the job as the E-stop does, `on`
//! and reset are refused while it is open; a limit switch stops the machine with an
//! alarm naming the axis and the end, `on` is refused while it is tripped unless the
//! operator overrides the limits (until the switches are released), and the axis
//! jogs off it only away from it. A position task driven directly, as the
//! no-allocation tests drive it (no daemon).

use softnc_core::machine_io::{MachineOutputs, SpindleDir};
use softnc_daemon::position::{EngineFactory, PositionTask};
use softnc_ipc::bus::Bus;
use softnc_ipc::{
    CommandSample, ControlCommand, ControlKind, FixedStr, MachineState, ServiceNames,
};
use std::time::{Duration, Instant};

mod common;

type Task = PositionTask<softnc_sim::SimBackend>;

fn position_task(tag: &str) -> (std::path::PathBuf, Task, Bus) {
    let (dir, loaded) = common::lockstep_config(tag, "default.ron", false);
    let names = ServiceNames::new(&loaded.config.service_prefix, &loaded.config.instance);
    let machine = loaded.machine.clone();
    let make_engine: EngineFactory<softnc_sim::SimBackend> = Box::new(move || {
        softnc_sim::simulated_engine(
            &machine,
            machine.servo.seed,
            softnc_sim::SimOptions::default(),
        )
    });
    let task = PositionTask::new(loaded, make_engine).unwrap();
    let bus = Bus::new(names, "test-driver").unwrap();
    (dir, task, bus)
}

fn control(kind: ControlKind, seq: u64) -> ControlCommand {
    ControlCommand {
        flags: 0,
        seq,
        sender: softnc_ipc::ProcessId::Mmi.wire(),
        kind: kind.wire(),
        job_id: 0,
        axis: u32::MAX,
        value: 0.0,
        path: FixedStr::empty(),
    }
}

/// Sends a job's samples: the first 200 at once, then one per cycle (as the
/// interpolator keeps its lookahead; a subscriber's buffer holds no whole job).
struct Feeder<F: Fn(u64) -> CommandSample> {
    publisher: softnc_ipc::bus::Pub<CommandSample>,
    next: u64,
    n: u64,
    make: F,
}

impl<F: Fn(u64) -> CommandSample> Feeder<F> {
    fn new(bus: &Bus, n: u64, make: F) -> Self {
        let mut f = Feeder {
            publisher: bus.command_publisher().unwrap(),
            next: 0,
            n,
            make,
        };
        for _ in 0..200 {
            f.feed();
        }
        f
    }
    fn feed(&mut self) {
        if self.next < self.n {
            self.publisher.send_copy((self.make)(self.next)).unwrap();
            self.next += 1;
        }
    }
}

/// Cycle until `done`, within 30 s, feeding a sample per cycle.
fn cycle_until<F: Fn(u64) -> CommandSample>(
    task: &mut Task,
    feeder: &mut Feeder<F>,
    what: &str,
    done: impl Fn(&Task) -> bool,
) {
    let t0 = Instant::now();
    while !done(task) {
        feeder.feed();
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "{what}: timed out in {:?}",
            task.state()
        );
        task.cycle().unwrap();
        std::thread::sleep(Duration::from_micros(200));
    }
}

/// The alarms published so far (the outbox thread sends them a little later).
fn alarms(sub: &softnc_ipc::bus::Sub<softnc_ipc::Alarm>) -> Vec<String> {
    let mut texts = Vec::new();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(300) {
        while let Some(a) = sub.receive().unwrap() {
            texts.push(a.message.as_str().to_string());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    texts
}

/// Sample `k` of job 7 along X from `x0_mm` at `step_mm` per sample, the outputs
/// from sample `switch_at` on with M62 P1 and the spindle on.
fn sample(k: u64, n: u64, x0_mm: f64, step_mm: f64, switch_at: u64) -> CommandSample {
    let mut s = CommandSample::new(k, 7, k, [x0_mm + step_mm * k as f64, 0.0, 0.0]);
    s.motion = u32::from(k >= switch_at);
    if k >= switch_at {
        s.outputs = MachineOutputs {
            spindle_dir: SpindleDir::Clockwise,
            spindle_rpm: 6000.0,
            coolant_flood: true,
            digital: 1 << 1,
            ..MachineOutputs::default()
        }
        .into();
    }
    if k + 1 == n {
        s.flags |= CommandSample::FLAG_END_OF_JOB;
    }
    s
}

#[test]
fn outputs_at_the_sample_in_use_and_the_estop_input_stops_the_job() {
    let (dir, mut task, bus) = position_task("posio");
    let ctl = bus.control_publisher().unwrap();
    let alarm_sub = bus.alarm_subscriber().unwrap();
    ctl.send_copy(control(ControlKind::MachineOn, 1)).unwrap();
    let (n, switch_at) = (3000u64, 400u64);
    let mut feeder = Feeder::new(&bus, n, |k| sample(k, n, 0.0, 0.001, switch_at));
    cycle_until(&mut task, &mut feeder, "motion", |t| {
        t.state() == MachineState::Running
    });
    // the outputs switch at the cycle whose sample in use is the first carrying them
    let mut switched_at = None;
    while switched_at.is_none() {
        feeder.feed();
        task.cycle().unwrap();
        let seq = task.current_seq().expect("a sample in use");
        let dout = task.engine().io().last_outputs().digital;
        assert_eq!(
            dout != 0,
            seq >= switch_at,
            "M62 P1 {dout} with sample {seq} in use"
        );
        if dout != 0 {
            switched_at = Some(seq);
        }
    }
    assert_eq!(switched_at, Some(switch_at));
    let raw = task.simulated().unwrap().raw_outputs();
    assert!(raw.spindle.enable && raw.spindle.rpm == 6000.0, "{raw:?}");
    assert_eq!(raw.digital >> softnc_sim::wiring::OUT_FLOOD & 1, 1);
    // the E-stop chain opens mid-job: stopped as the E-stop stops it
    for _ in 0..200 {
        feeder.feed();
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::Running);
    let spinning = task.engine().io().last_inputs().spindle_rpm;
    assert!(spinning > 1000.0, "the spindle model turns: {spinning} rpm");
    task.simulated().unwrap().set_estop_open(true);
    task.cycle().unwrap();
    assert_eq!(task.state(), MachineState::EStopped);
    task.cycle().unwrap();
    let raw = task.simulated().unwrap().raw_outputs();
    assert!(!raw.spindle.enable, "the spindle stops");
    for line in [
        softnc_sim::wiring::OUT_FLOOD,
        softnc_sim::wiring::OUT_MACHINE_ON,
        softnc_sim::wiring::OUT_AMP_ENABLE,
        softnc_sim::wiring::USER + 1,
    ] {
        assert_eq!(raw.digital >> line & 1, 0, "line {line} off");
    }
    assert!(task.engine().io().last_inputs().estop_open);
    let texts = alarms(&alarm_sub);
    assert!(
        texts.iter().any(|t| t.contains("E-stop input opened")),
        "{texts:?}"
    );
    // reset and on refused while it is open
    ctl.send_copy(control(ControlKind::Reset, 2)).unwrap();
    ctl.send_copy(control(ControlKind::MachineOn, 3)).unwrap();
    for _ in 0..20 {
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::EStopped);
    let texts = alarms(&alarm_sub);
    assert!(
        texts
            .iter()
            .any(|t| t.contains("reset refused: the E-stop input is open")),
        "{texts:?}"
    );
    // closed, reset, on
    task.simulated().unwrap().set_estop_open(false);
    // (a reset is taken against the input as read at the last cycle)
    task.cycle().unwrap();
    ctl.send_copy(control(ControlKind::Reset, 4)).unwrap();
    cycle_until(&mut task, &mut feeder, "reset", |t| {
        t.state() == MachineState::Off
    });
    assert!(!task.engine().io().last_inputs().estop_open);
    ctl.send_copy(control(ControlKind::MachineOn, 5)).unwrap();
    cycle_until(&mut task, &mut feeder, "on", |t| {
        t.state() == MachineState::Idle
    });
    let raw = task.simulated().unwrap().raw_outputs();
    assert_eq!(raw.digital >> softnc_sim::wiring::OUT_MACHINE_ON & 1, 1);
    assert!(!raw.spindle.enable, "between jobs: the safe outputs");
    let _ = std::fs::remove_dir_all(&dir);
}

/// After a reset off a tripped limit switch: `on` is refused while the switch is
/// tripped (LinuxCNC), until the operator overrides the limits; then it is on.
fn on_with_the_limits_overridden<F: Fn(u64) -> CommandSample>(
    task: &mut Task,
    feeder: &mut Feeder<F>,
    ctl: &softnc_ipc::bus::Pub<ControlCommand>,
    alarm_sub: &softnc_ipc::bus::Sub<softnc_ipc::Alarm>,
) {
    // on is refused while the switch is tripped (LinuxCNC), until the operator
    // overrides the limits
    ctl.send_copy(control(ControlKind::MachineOn, 3)).unwrap();
    for _ in 0..20 {
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::Off, "on with a limit tripped");
    let texts = alarms(alarm_sub);
    assert!(
        texts
            .iter()
            .any(|t| t.contains("machine on refused: a limit switch is tripped")),
        "{texts:?}"
    );
    ctl.send_copy(control(ControlKind::OverrideLimits, 30))
        .unwrap();
    ctl.send_copy(control(ControlKind::MachineOn, 31)).unwrap();
    cycle_until(task, feeder, "on", |t| t.state() == MachineState::Idle);
    assert!(task.limits_overridden());
}

#[test]
fn a_limit_switch_stops_the_machine_naming_axis_and_end() {
    let (dir, mut task, bus) = position_task("poslim");
    let p = softnc_machine::MachineProfile::load(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../../config/machines/default.ron"),
    )
    .unwrap();
    let trip_mm = p.axes[0].max_mm + p.servo.sim_io.unwrap().limit_switch_margin_mm;
    let ctl = bus.control_publisher().unwrap();
    let alarm_sub = bus.alarm_subscriber().unwrap();
    ctl.send_copy(control(ControlKind::MachineOn, 1)).unwrap();
    // X from 1 mm short of its max limit switch on through it at 1 m/min
    let n = 2000u64;
    let mut feeder = Feeder::new(&bus, n, |k| {
        sample(k, n, trip_mm - 1.0, 1000.0 / 60.0 * 0.001, n)
    });
    cycle_until(&mut task, &mut feeder, "motion", |t| {
        t.state() == MachineState::Running
    });
    cycle_until(&mut task, &mut feeder, "the limit switch", |t| {
        t.state() != MachineState::Running
    });
    assert_eq!(task.state(), MachineState::EStopped);
    let at = task.engine().measured_mm()[0];
    assert!(
        at >= trip_mm && at < trip_mm + 0.1,
        "stopped at {at} mm, switch at {trip_mm}"
    );
    assert_eq!(task.engine().io().last_inputs().limit_max, 1);
    let texts = alarms(&alarm_sub);
    assert!(
        texts
            .iter()
            .any(|t| t.contains("X maximum limit switch tripped")),
        "{texts:?}"
    );
    // reset (the switch stays tripped: it does not stop the machine again)
    ctl.send_copy(control(ControlKind::Reset, 2)).unwrap();
    cycle_until(&mut task, &mut feeder, "reset", |t| {
        t.state() == MachineState::Off
    });
    on_with_the_limits_overridden(&mut task, &mut feeder, &ctl, &alarm_sub);
    for _ in 0..20 {
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::Idle);
    // off the switch only away from it
    let jog = |seq: u64, mm_per_min: f64| ControlCommand {
        axis: 0,
        value: mm_per_min,
        ..control(ControlKind::Jog, seq)
    };
    ctl.send_copy(jog(4, 600.0)).unwrap();
    for _ in 0..20 {
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::Idle, "jogged toward the switch");
    let texts = alarms(&alarm_sub);
    assert!(
        texts
            .iter()
            .any(|t| t.contains("jog of X toward its tripped maximum limit switch refused")),
        "{texts:?}"
    );
    ctl.send_copy(jog(5, -600.0)).unwrap();
    cycle_until(&mut task, &mut feeder, "jog away", |t| {
        t.state() == MachineState::Jogging
    });
    // off the switch the override ends by itself; the jog goes on
    cycle_until(&mut task, &mut feeder, "the switch released", |t| {
        t.engine().io().last_inputs().limit_max == 0
    });
    task.cycle().unwrap();
    assert!(
        !task.limits_overridden(),
        "the override outlived the switch"
    );
    assert_eq!(task.state(), MachineState::Jogging);
    ctl.send_copy(jog(6, 0.0)).unwrap();
    cycle_until(&mut task, &mut feeder, "jog stopped", |t| {
        t.state() == MachineState::Idle
    });
    // no switch tripped: an override is refused
    ctl.send_copy(control(ControlKind::OverrideLimits, 7))
        .unwrap();
    task.cycle().unwrap();
    assert!(!task.limits_overridden());
    let texts = alarms(&alarm_sub);
    assert!(
        texts
            .iter()
            .any(|t| t.contains("limit override refused: no limit switch is tripped")),
        "{texts:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Between jobs the position process holds what the last job left on (as
/// LinuxCNC): the spindle turning, flood on, M62 P1 on, also cycles later and in
/// its status; an abort then stops the spindle and the coolant and keeps the
/// digital output (LinuxCNC's task abort); an E-stop puts everything in the safe
/// state, and neither the reset nor `on` turns anything on again.
#[test]
fn outputs_are_held_between_jobs_until_an_abort_or_an_estop() {
    let (dir, mut task, bus) = position_task("posheld");
    let ctl = bus.control_publisher().unwrap();
    let status = bus.status_subscriber().unwrap();
    ctl.send_copy(control(ControlKind::MachineOn, 1)).unwrap();
    let n = 600u64;
    let mut feeder = Feeder::new(&bus, n, |k| sample(k, n, 0.0, 0.001, 0));
    cycle_until(&mut task, &mut feeder, "motion", |t| {
        t.state() == MachineState::Running
    });
    cycle_until(&mut task, &mut feeder, "the job's end", |t| {
        t.state() == MachineState::Idle && t.current_seq().is_none()
    });
    for _ in 0..500 {
        task.cycle().unwrap();
    }
    let raw = task.simulated().unwrap().raw_outputs();
    assert!(raw.spindle.enable && raw.spindle.rpm == 6000.0, "{raw:?}");
    assert_eq!(raw.digital >> softnc_sim::wiring::OUT_FLOOD & 1, 1);
    assert_eq!(raw.digital >> (softnc_sim::wiring::USER + 1) & 1, 1);
    // (the status says so, for the MMI and the next job's sequencer)
    let mut last = None;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_millis(300) {
        task.cycle().unwrap();
        while let Some(s) = status.receive().unwrap() {
            last = Some(*s);
        }
    }
    let o: MachineOutputs = last.expect("a status").outputs.into();
    assert_eq!(o.spindle_signed_rpm(), 6000.0);
    assert!(o.coolant_flood && o.digital == 2, "{o:?}");
    // an abort: spindle and coolant off, the digital output kept
    ctl.send_copy(control(ControlKind::Abort, 2)).unwrap();
    for _ in 0..5 {
        task.cycle().unwrap();
    }
    let raw = task.simulated().unwrap().raw_outputs();
    assert!(!raw.spindle.enable, "{raw:?}");
    assert_eq!(raw.digital >> softnc_sim::wiring::OUT_FLOOD & 1, 0);
    assert_eq!(raw.digital >> (softnc_sim::wiring::USER + 1) & 1, 1);
    // an E-stop: the safe state, and it stays after the reset and `on`
    ctl.send_copy(control(ControlKind::EStop, 3)).unwrap();
    task.cycle().unwrap();
    assert_eq!(task.state(), MachineState::EStopped);
    task.cycle().unwrap();
    let raw = task.simulated().unwrap().raw_outputs();
    assert_eq!(raw.digital >> (softnc_sim::wiring::USER + 1) & 1, 0);
    ctl.send_copy(control(ControlKind::Reset, 4)).unwrap();
    cycle_until(&mut task, &mut feeder, "reset", |t| {
        t.state() == MachineState::Off
    });
    ctl.send_copy(control(ControlKind::MachineOn, 5)).unwrap();
    cycle_until(&mut task, &mut feeder, "on", |t| {
        t.state() == MachineState::Idle
    });
    for _ in 0..100 {
        task.cycle().unwrap();
    }
    let raw = task.simulated().unwrap().raw_outputs();
    assert!(!raw.spindle.enable, "{raw:?}");
    assert_eq!(raw.digital >> (softnc_sim::wiring::USER + 1) & 1, 0);
    assert_eq!(raw.digital >> softnc_sim::wiring::OUT_MACHINE_ON & 1, 1);
    let _ = std::fs::remove_dir_all(&dir);
}
