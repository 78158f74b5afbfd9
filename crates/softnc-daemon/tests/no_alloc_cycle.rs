//! The position cycle allocates nothing once motion has started: a counting global
//! allocator (counting only on the thread that runs the cycles) proves it.

use softnc_daemon::bus::Bus;
use softnc_daemon::config::DaemonConfig;
use softnc_daemon::position::{EngineFactory, PositionTask};
use softnc_ipc::{
    CommandSample, ControlCommand, ControlKind, FixedStr, MachineState, ServiceNames,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);
thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            ALLOCS.fetch_add(1, Ordering::SeqCst);
        }
        // SAFETY: forwarding to the system allocator with the caller's layout.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: p was allocated by System.alloc with layout l.
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

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
    let counted = run_counted("default.ron", "plain", None);
    assert_eq!(counted.spindle_rpm, 0.0, "default.ron has no spindle model");
}

/// The operator turns the spindle override during motion on the TNV-40 with its PDC
/// (paper 000): the request, the design thread's table coming back, its installation
/// and the swap at a cycle boundary, and the replaced table going back — no allocation
/// on the cycle.
#[test]
fn a_spindle_override_during_motion_allocates_nothing_on_the_cycle() {
    let counted = run_counted("tnv40-dob-pdc.ron", "spindle", Some(1.2));
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

struct Counted {
    spindle_rpm: f64,
    /// The tooth frequency X's and Y's PDC run (0 without one).
    pdc_fd_hz: [f64; 2],
}

/// A move along X on `machine`, the position cycles counted once motion runs; with
/// `spindle_override`, sent 50 counted cycles in.
fn run_counted(machine_file: &str, tag: &str, spindle_override: Option<f64>) -> Counted {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("softnc-noalloc-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("machines")).unwrap();
    std::fs::copy(
        repo.join("config/machines").join(machine_file),
        dir.join("machines/default.ron"),
    )
    .unwrap();
    std::fs::copy(repo.join("config/iceoryx2.toml"), dir.join("iceoryx2.toml")).unwrap();
    let cfg = std::fs::read_to_string(repo.join("config/default.ron"))
        .unwrap()
        .replace(
            "instance: \"mill1\"",
            &format!("instance: \"noalloc{tag}{}\"", std::process::id()),
        )
        .replace("clock: Realtime", "clock: Lockstep")
        .replace("data_dir: \"../data\"", "data_dir: \"data\"");
    std::fs::write(dir.join("default.ron"), cfg).unwrap();
    let loaded = DaemonConfig::load(&dir.join("default.ron")).unwrap();
    loaded.setup_iceoryx2().unwrap();
    let names = ServiceNames::new(&loaded.config.service_prefix, &loaded.config.instance);
    let machine = loaded.machine.clone();
    let make_engine: EngineFactory<softnc_sim::SimBackend> = Box::new(move || {
        softnc_sim::CycleEngine::simulated(
            &machine,
            machine.servo.seed,
            softnc_sim::SimOptions::default(),
        )
    });
    let mut task = PositionTask::new(loaded, make_engine).unwrap();
    let bus = Bus::new(names, "test-feeder").unwrap();
    let commands = bus.command_publisher().unwrap();
    let control = bus.control_publisher().unwrap();
    // a 2 mm/s cut along X, 1000 samples
    let n = 1000u64;
    let send = |k: u64| {
        let mut s = CommandSample::new(k, 7, k, [0.002 * k as f64, 0.0, 0.0]);
        s.flags |= CommandSample::FLAG_FEED_MOVE;
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
    let mut next = 200;
    let mut counted_cycles = 0;
    for i in 0..700 {
        // the feeder's and the operator's allocations (if any) are not counted
        if next < n {
            send(next);
            next += 1;
        }
        if let (50, Some(v)) = (i, spindle_override) {
            control
                .send_copy(ControlCommand {
                    seq: 1,
                    kind: ControlKind::SpindleOverride.wire(),
                    job_id: 0,
                    value: v,
                    path: FixedStr::new(""),
                })
                .unwrap();
        }
        if i > 50 && i % 50 == 0 {
            // give the design thread time, as real cycles would
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        COUNTING.with(|c| c.set(true));
        task.cycle().unwrap();
        COUNTING.with(|c| c.set(false));
        counted_cycles += 1;
    }
    assert_eq!(
        task.state(),
        MachineState::Running,
        "still moving while counted"
    );
    let allocs = ALLOCS.load(Ordering::SeqCst);
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
    let _ = std::fs::remove_dir_all(&dir);
    Counted {
        spindle_rpm,
        pdc_fd_hz,
    }
}
