//! The position cycle allocates nothing once motion has started, also when it raises
//! an alarm: a counting global allocator (counting only on the thread that runs the
//! cycles) proves it.

use softnc_daemon::position::{EngineFactory, PositionTask};
use softnc_ipc::bus::Bus;
use softnc_ipc::{
    CommandSample, ControlCommand, ControlKind, FixedStr, MachineState, ServiceNames,
};

mod common;

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

/// Cycle until the job's preparation is in and motion has started.
fn start_motion(task: &mut PositionTask<softnc_sim::SimBackend>) {
    let t0 = std::time::Instant::now();
    while task.state() != MachineState::Running {
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(30),
            "motion did not start"
        );
        task.cycle().unwrap();
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

#[test]
fn position_cycle_allocates_nothing_during_motion() {
    let counted = run_counted("default.ron", "plain", None, FED_WHOLE_JOB);
    assert_eq!(counted.state, MachineState::Running, "still moving");
    assert_eq!(counted.spindle_rpm, 0.0, "default.ron has no spindle model");
}

/// The interpolator stops sending mid-job: the ring runs dry, the cycle raises its
/// alarm (the message formatted into the alarm's fixed buffer) and stops along the
/// path — no allocation on the cycle for the fault either.
#[test]
fn a_ring_running_dry_raises_its_alarm_without_allocating() {
    let counted = run_counted("default.ron", "dry", None, 400);
    assert_eq!(
        counted.state,
        MachineState::Faulted,
        "stopped after the dry ring"
    );
    assert!(
        counted
            .alarms
            .iter()
            .any(|a| a.starts_with("command ring ran dry (")
                && a.ends_with("stopping along the path")),
        "{:?}",
        counted.alarms
    );
}

/// The operator turns the spindle override during motion on the TNV-40 with its PDC
/// (paper 000): the request, the design thread's table coming back, its installation
/// and the swap at a cycle boundary, and the replaced table going back — no allocation
/// on the cycle.
#[test]
fn a_spindle_override_during_motion_allocates_nothing_on_the_cycle() {
    let counted = run_counted("tnv40-dob-pdc.ron", "spindle", Some(1.2), FED_WHOLE_JOB);
    assert_eq!(counted.state, MachineState::Running, "still moving");
    assert_eq!(
        counted.spindle_rpm, 1800.0,
        "1500 rpm × 120 %, swapped in while counted"
    );
    assert_eq!(
        counted.pdc_fd_hz,
        [60.0, 60.0],
        "X's and Y's PDC run the 60 Hz design"
    );
}

/// Paper 003's force loop on the cycle (adaptive feed): the phase currents of the
/// simulated stock's feed motor every cycle, a revolution's RLS update, pole placement
/// and servo law every 100 ms — no allocation on the cycle.
#[test]
fn adaptive_feed_allocates_nothing_on_the_cycle() {
    let counted = run_counted_with("mch10-force.ron", "adaptive", None, FED_WHOLE_JOB, true);
    assert_eq!(counted.state, MachineState::Running, "still moving");
    assert!(
        counted.revolutions >= 6,
        "{} revolutions of the force loop while counted",
        counted.revolutions
    );
}

/// Samples of the 1000-sample job that the feeder sends: all of them.
const FED_WHOLE_JOB: u64 = 1000;

struct Counted {
    /// The machine's state after the counted cycles.
    state: MachineState,
    /// The texts of the alarms raised.
    alarms: Vec<String>,
    spindle_rpm: f64,
    /// The tooth frequency X's and Y's PDC run (0 without one).
    pdc_fd_hz: [f64; 2],
    /// Revolutions the force loop closed (adaptive feed).
    revolutions: u64,
}

/// A position task on the simulated `machine_file` (lockstep, instance `tag`) and a
/// bus to drive it.
fn position_task(
    tag: &str,
    machine_file: &str,
) -> (
    std::path::PathBuf,
    PositionTask<softnc_sim::SimBackend>,
    Bus,
) {
    let (dir, loaded) = common::lockstep_config(tag, machine_file, false);
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

/// A move along X on `machine`, the position cycles counted once motion runs; with
/// `spindle_override`, sent 50 counted cycles in; the feeder sends the first `fed`
/// samples of the job.
fn run_counted(machine_file: &str, tag: &str, spindle_override: Option<f64>, fed: u64) -> Counted {
    run_counted_with(machine_file, tag, spindle_override, fed, false)
}

/// [`run_counted`]; with `adaptive`, the job is started with adaptive feed.
#[allow(clippy::too_many_lines)]
fn run_counted_with(
    machine_file: &str,
    tag: &str,
    spindle_override: Option<f64>,
    fed: u64,
    adaptive: bool,
) -> Counted {
    let (dir, mut task, bus) = position_task(&format!("noalloc{tag}"), machine_file);
    let commands = bus.command_publisher().unwrap();
    let control = bus.control_publisher().unwrap();
    let alarms = bus.alarm_subscriber().unwrap();
    // the machine on (a position process starts with its drives off)
    control
        .send_copy(ControlCommand {
            flags: 0,
            seq: 0,
            sender: softnc_ipc::ProcessId::Mmi.wire(),
            kind: ControlKind::MachineOn.wire(),
            job_id: 0,
            axis: u32::MAX,
            value: 0.0,
            path: FixedStr::empty(),
        })
        .unwrap();
    if adaptive {
        // job 7 with adaptive feed (no program to read: the samples come below)
        control
            .send_copy(ControlCommand {
                flags: softnc_ipc::JOB_ADAPTIVE_FORCE,
                seq: 1,
                sender: softnc_ipc::ProcessId::Mmi.wire(),
                kind: ControlKind::StartJob.wire(),
                job_id: 7,
                axis: 0,
                value: 1.0,
                path: FixedStr::empty(),
            })
            .unwrap();
    }
    // a 2 mm/s cut along X, 1000 samples
    let n = 1000u64;
    let send = |k: u64| {
        let mut s = CommandSample::new(k, 7, k, [0.002 * k as f64, 0.0, 0.0]);
        s.flags |= CommandSample::FLAG_FEED_MOVE;
        // the machine around the axes switched mid-job (spindle, coolant, M62, M67):
        // through the I/O map to the simulated machine's lines on the counted cycles
        if k >= 300 {
            let mut o = softnc_core::machine_io::MachineOutputs {
                spindle_dir: softnc_core::machine_io::SpindleDir::Clockwise,
                spindle_rpm: 6000.0,
                coolant_flood: true,
                digital: 1 << 2,
                ..Default::default()
            };
            o.analog[1] = 2.5;
            s.outputs = o.into();
        }
        if k + 1 == n {
            s.flags |= CommandSample::FLAG_END_OF_JOB;
        }
        commands.send_copy(s).unwrap();
    };
    for k in 0..200 {
        send(k);
    }
    // start: the preparation thread builds the job's engine; motion starts when it is in
    start_motion(&mut task);
    // the programmed path the contour error is measured against (set here, as the
    // job has no program file): the cut and a neighbour after it
    let at = |x: f64| softnc_core::Vec3::new(x, 0.0, 0.0);
    task.set_job_primitives(vec![
        Some(softnc_core::Primitive::Line {
            start: at(0.0),
            end: at(2.0),
        }),
        Some(softnc_core::Primitive::Line {
            start: at(2.0),
            end: at(4.0),
        }),
    ]);
    let mut next = 200;
    let mut counted_cycles = 0;
    for i in 0..700 {
        // the feeder's and the operator's allocations (if any) are not counted
        if next < n.min(fed) {
            send(next);
            next += 1;
        }
        if let (50, Some(v)) = (i, spindle_override) {
            control
                .send_copy(ControlCommand {
                    flags: 0,
                    seq: 1,
                    sender: softnc_ipc::ProcessId::Mmi.wire(),
                    kind: ControlKind::SpindleOverride.wire(),
                    job_id: 0,
                    axis: u32::MAX,
                    value: v,
                    path: FixedStr::empty(),
                })
                .unwrap();
        }
        if i > 50 && i % 50 == 0 {
            // give the design thread time, as real cycles would
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        common::count(|| task.cycle()).unwrap();
        counted_cycles += 1;
    }
    let allocs = common::allocations();
    assert_eq!(
        allocs, 0,
        "{allocs} allocations in {counted_cycles} position cycles"
    );
    let spindle_rpm = task
        .engine()
        .spindle_schedule()
        .map_or(0.0, |s| s.effective_rpm());
    let pdc_fd_hz = [0, 1].map(|i| {
        task.engine()
            .controller(i)
            .compensation
            .as_ref()
            .map_or(0.0, |c| c.pdc_fd_hz())
    });
    // the outbox thread publishes them a little later
    let mut texts = Vec::new();
    let t0 = std::time::Instant::now();
    while t0.elapsed() < std::time::Duration::from_millis(500) {
        while let Some(a) = alarms.receive().unwrap() {
            texts.push(a.message.as_str().to_string());
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let _ = std::fs::remove_dir_all(&dir);
    Counted {
        state: task.state(),
        alarms: texts,
        spindle_rpm,
        pdc_fd_hz,
        revolutions: task.adaptive_feed().map_or(0, |a| a.revolutions()),
    }
}

/// Homing and jogging run on the position cycle: the homing sequence (search, latch,
/// re-referencing, final move) on the simulated machine's home switch inputs (the
/// profile maps `Home` for every axis; the limit switches watched for an abort)
/// and the jog movers allocate nothing there either.
#[test]
fn homing_and_jogging_allocate_nothing_on_the_cycle() {
    let (dir, mut task, bus) = position_task("noallocmanual", "default-incremental.ron");
    let control = bus.control_publisher().unwrap();
    let send = |seq: u64, kind: ControlKind, axis: u32, value: f64| {
        control
            .send_copy(ControlCommand {
                flags: 0,
                seq,
                sender: softnc_ipc::ProcessId::Mmi.wire(),
                kind: kind.wire(),
                job_id: 0,
                axis,
                value,
                path: FixedStr::empty(),
            })
            .unwrap();
    };
    send(1, ControlKind::MachineOn, u32::MAX, 0.0);
    // all axes, Z X Y: each axis's sequence starts on the cycle
    send(2, ControlKind::Home, u32::MAX, 0.0);
    task.cycle().unwrap();
    assert_eq!(task.state(), MachineState::Homing);
    let mut cycles = 0;
    while task.state() == MachineState::Homing {
        common::count(|| task.cycle()).unwrap();
        cycles += 1;
        assert!(cycles < 100_000, "homing did not end");
    }
    assert_eq!(task.state(), MachineState::Idle, "homed");
    assert_eq!(task.homed(), 7, "all homed");
    // a continuous jog of X stopped mid-way, and a step
    send(3, ControlKind::Jog, 0, 3000.0);
    for _ in 0..300 {
        common::count(|| task.cycle()).unwrap();
    }
    assert_eq!(task.state(), MachineState::Jogging);
    send(4, ControlKind::Jog, 0, 0.0);
    while task.state() == MachineState::Jogging {
        common::count(|| task.cycle()).unwrap();
    }
    send(5, ControlKind::JogStep, 1, -2.5);
    task.cycle().unwrap();
    while task.state() == MachineState::Jogging {
        common::count(|| task.cycle()).unwrap();
    }
    let allocs = common::allocations();
    assert_eq!(allocs, 0, "{allocs} allocations homing and jogging");
    let _ = std::fs::remove_dir_all(&dir);
}
