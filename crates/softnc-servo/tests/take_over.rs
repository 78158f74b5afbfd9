//! A job's engine takes the machine over from the last one: a drive kept across
//! jobs is handed on as it stands (not enabled or homed again); a backend that is
//! not (the simulated machine) is replaced by the new engine's own, homed at the
//! job's start.

use softnc_core::Axes;
use softnc_machine::MachineProfile;
use softnc_servo::{
    AxisStatus, BackendError, CommandMode, CycleEngine, LoopbackBackend, ServoBackend,
};
use std::path::PathBuf;

/// A loopback drive that counts what is done to it.
struct Counted {
    serial: u32,
    kept: bool,
    enables: u32,
    homes: u32,
    inner: LoopbackBackend,
}

impl Counted {
    fn new(serial: u32, kept: bool) -> Self {
        Counted {
            serial,
            kept,
            enables: 0,
            homes: 0,
            inner: LoopbackBackend::new(),
        }
    }
}

impl ServoBackend for Counted {
    fn axes(&self) -> usize {
        self.inner.axes()
    }
    fn command_mode(&self, axis: usize) -> CommandMode {
        self.inner.command_mode(axis)
    }
    fn mm_per_count(&self, axis: usize) -> f64 {
        self.inner.mm_per_count(axis)
    }
    fn enable(&mut self) -> Result<(), BackendError> {
        self.enables += 1;
        self.inner.enable()
    }
    fn disable(&mut self) {
        self.inner.disable()
    }
    fn home(&mut self, pos_mm: Axes<f64>) {
        self.homes += 1;
        self.inner.home(pos_mm)
    }
    fn write_commands(&mut self, cmd: Axes<f64>) {
        self.inner.write_commands(cmd)
    }
    fn cycle(&mut self) -> Result<(), BackendError> {
        self.inner.cycle()
    }
    fn read_counts(&self) -> Axes<i64> {
        self.inner.read_counts()
    }
    fn read_currents(&self) -> Axes<f64> {
        self.inner.read_currents()
    }
    fn read_status(&self) -> Axes<AxisStatus> {
        self.inner.read_status()
    }
    fn kept_across_jobs(&self) -> bool {
        self.kept
    }
}

fn profile() -> MachineProfile {
    MachineProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

/// Job 1's engine on drive 1, enabled and homed at 0, moved to X 4: then job 2's
/// engine (with drive 2 of its own) takes over at X 4. Also: the enables and homes
/// of drive 1 and of drive 2 before the take-over.
fn two_jobs(kept: bool) -> (CycleEngine<Counted>, [(u32, u32); 2]) {
    let p = profile();
    let mut job1 = CycleEngine::new(&p, Counted::new(1, kept));
    job1.backend_mut().enable().unwrap();
    job1.reset([0.0; 3]);
    for k in 1..=400 {
        job1.step([0.01 * k as f64, 0.0, 0.0], true).unwrap();
    }
    assert_eq!(job1.measured_mm()[0], 4.0);
    let mut job2 = CycleEngine::new(&p, Counted::new(2, kept));
    job2.backend_mut().enable().unwrap();
    let before = [job1.backend(), job2.backend()].map(|d| (d.enables, d.homes));
    job2.take_over(&mut job1, [4.0, 0.0, 0.0]);
    (job2, before)
}

#[test]
fn a_drive_kept_across_jobs_is_handed_on_as_it_stands() {
    let (job2, before) = two_jobs(true);
    let d = job2.backend();
    assert_eq!(
        (d.serial, (d.enables, d.homes)),
        (1, before[0]),
        "job 2 runs on drive 1, not enabled or homed again"
    );
    assert_eq!(job2.measured_mm()[0], 4.0);
}

#[test]
fn a_backend_not_kept_is_the_new_engines_own_homed_at_the_start() {
    let (job2, before) = two_jobs(false);
    let d = job2.backend();
    assert_eq!(
        (d.serial, d.homes),
        (2, before[1].1 + 1),
        "job 2 runs on its own machine, homed at the start"
    );
    assert_eq!(job2.measured_mm()[0], 4.0);
}

/// The outputs held between jobs (a spindle turning, flood on, a digital output)
/// are the machine's: the next job's engine writes them from its first cycle on,
/// on a drive handed on and on a fresh machine alike (no spindle stop at a job's
/// start).
#[test]
fn the_outputs_held_between_jobs_go_over_to_the_next_jobs_engine() {
    use softnc_core::machine_io::{MachineOutputs, SpindleDir};
    let held = MachineOutputs {
        spindle_dir: SpindleDir::Clockwise,
        spindle_rpm: 5000.0,
        coolant_flood: true,
        digital: 0b100,
        ..MachineOutputs::default()
    };
    for kept in [true, false] {
        let p = profile();
        let mut job1 = CycleEngine::new(&p, Counted::new(1, kept));
        job1.backend_mut().enable().unwrap();
        job1.reset([0.0; 3]);
        job1.set_outputs(&held);
        job1.step([0.0; 3], false).unwrap();
        assert_eq!(*job1.io().last_outputs(), held);
        let mut job2 = CycleEngine::new(&p, Counted::new(2, kept));
        job2.backend_mut().enable().unwrap();
        job2.take_over(&mut job1, [0.0; 3]);
        job2.step([0.0; 3], false).unwrap();
        assert_eq!(*job2.io().last_outputs(), held, "kept {kept}");
    }
}
