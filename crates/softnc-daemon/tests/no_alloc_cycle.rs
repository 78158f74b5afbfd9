//! The position cycle allocates nothing once motion has started: a counting global
//! allocator (counting only on the thread that runs the cycles) proves it.

use softnc_daemon::bus::Bus;
use softnc_daemon::config::DaemonConfig;
use softnc_daemon::position::{EngineFactory, PositionTask};
use softnc_ipc::{CommandSample, MachineState, ServiceNames};
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

#[test]
fn position_cycle_allocates_nothing_during_motion() {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("softnc-noalloc-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("machines")).unwrap();
    std::fs::copy(
        repo.join("config/machines/default.ron"),
        dir.join("machines/default.ron"),
    )
    .unwrap();
    std::fs::copy(repo.join("config/iceoryx2.toml"), dir.join("iceoryx2.toml")).unwrap();
    let cfg = std::fs::read_to_string(repo.join("config/default.ron"))
        .unwrap()
        .replace(
            "instance: \"mill1\"",
            &format!("instance: \"noalloc{}\"", std::process::id()),
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
    // a 10 mm/s move along X, 600 samples
    let n = 600u64;
    let send = |k: u64| {
        let mut s = CommandSample::new(k, 7, k, [0.01 * k as f64, 0.0, -10.0]);
        s.flags |= CommandSample::FLAG_FEED_MOVE;
        if k + 1 == n {
            s.flags |= CommandSample::FLAG_END_OF_JOB;
        }
        commands.send_copy(s).unwrap();
    };
    for k in 0..200 {
        send(k);
    }
    // start: the first cycles set the job up (a fresh engine: allocation before motion)
    for _ in 0..3 {
        task.cycle().unwrap();
    }
    assert_eq!(task.state(), MachineState::Running);
    let mut next = 200;
    let mut counted_cycles = 0;
    for _ in 0..350 {
        if next < n {
            send(next); // the feeder's allocations (if any) are not counted
            next += 1;
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
    let _ = std::fs::remove_dir_all(&dir);
}
