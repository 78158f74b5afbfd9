//! The position process's preparation thread: everything the position task needs
//! that reads files, allocates or designs filters runs here, off the cycle.
//!
//! - **A job** (`StartJob`): read and plan its program (the programmed path, for the
//!   contour error; its S words), build a fresh controller stack and machine for it —
//!   exactly as `softnc sim` builds them — and design its PDC for every programmed
//!   spindle speed at the spindle override in force (paper 000).
//! - **A spindle override** during a job: redesign every speed's PDC at the new
//!   override.
//!
//! The cycle hands requests over and takes the results back through bounded lock-free
//! queues (push, pop and a futex wake: no allocation, no lock), swaps them in at a
//! cycle boundary, and hands what they replace back here to be dropped.

use crossbeam_queue::ArrayQueue;
use softnc_core::{Primitive, MAX_AXES};
use softnc_ipc::FixedStr;
use softnc_machine::MachineProfile;
use softnc_servo::adaptive_feed::AdaptiveFeed;
use softnc_servo::spindle::{SpindleDesigner, SpindleDesigns};
use softnc_servo::{CycleEngine, ServoBackend};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Builds the engine for a job: controller stacks in front of the servo backend (on
/// the preparation thread).
pub type EngineFactory<B> = Box<dyn FnMut() -> CycleEngine<B> + Send>;

/// Requests and results each queue holds.
pub const PREP_QUEUE_CAPACITY: usize = 16;

/// What the cycle asks for.
#[derive(Debug, Clone, Copy)]
// passed by value through a fixed queue: boxing a variant would allocate on the cycle
#[allow(clippy::large_enum_variant)]
pub enum PrepRequest {
    /// Prepare job `job_id` of program `path` (empty: no program to read — a job
    /// whose start this process did not see) at spindle override `spindle_override`.
    Job {
        /// The job.
        job_id: u64,
        /// Its program.
        path: FixedStr<512>,
        /// Spindle override in force (fraction).
        spindle_override: f64,
        /// Where the machine is (the program is planned from there).
        start_mm: [f64; MAX_AXES],
        /// The line it runs from (`None`: the start).
        from_line: Option<u32>,
        /// The operator's switches when it started.
        switches: crate::interp::Switches,
        /// With adaptive feed: the operator's override when it started (the force
        /// loop's ceiling); `None` without.
        adaptive_cap: Option<f64>,
    },
    /// Redesign job `job_id`'s PDC tables at spindle override `spindle_override`.
    SpindleOverride {
        /// The job.
        job_id: u64,
        /// The new override (fraction).
        spindle_override: f64,
    },
}

/// A job, ready to run.
pub struct JobPrep<B: ServoBackend> {
    /// The job.
    pub job_id: u64,
    /// Its controller stacks and machine, PDC tables designed.
    pub engine: CycleEngine<B>,
    /// Its programmed path per motion (for the contour error).
    pub primitives: Vec<Option<Primitive>>,
    /// The program line of each motion.
    pub lines: Vec<u32>,
    /// Its trace file, when traces are on.
    pub trace: Option<crate::trace::TraceSink>,
    /// Why its spindle speeds cannot be followed (axis, message): the job faults
    /// before motion.
    pub error: Option<(usize, String)>,
    /// Its force loop (adaptive feed), when it runs with one.
    pub adaptive: Option<AdaptiveFeed>,
}

/// Where job traces go.
#[derive(Debug, Clone)]
pub struct TraceTo {
    /// `trace-job<N>.csv` files go here.
    pub dir: std::path::PathBuf,
    /// Never drop a row (lockstep).
    pub lossless: bool,
}

/// What comes back to the cycle.
// passed by value through a fixed queue: the refusal's text is not boxed so that the
// cycle frees nothing when it takes one
#[allow(clippy::large_enum_variant)]
pub enum Prepared<B: ServoBackend> {
    /// A job, ready to run.
    Job(Box<JobPrep<B>>),
    /// The PDC tables of job `job_id` at a new spindle override.
    Spindle {
        /// The job.
        job_id: u64,
        /// The designs.
        designs: Box<SpindleDesigns>,
    },
    /// A spindle override whose design failed (eq 11–13): refused.
    SpindleRefused {
        /// The job.
        job_id: u64,
        /// The refused override (fraction).
        spindle_override: f64,
        /// Why.
        message: FixedStr<256>,
    },
}

/// What the cycle has replaced, to be dropped here.
pub enum Retired<B: ServoBackend> {
    /// A job's preparation (holding the engine and path it replaced).
    Job(Box<JobPrep<B>>),
    /// A replaced PDC table.
    Spindle(Box<SpindleDesigns>),
    /// A finished job's trace, to be closed.
    Trace(crate::trace::TraceSink),
}

/// The cycle's side of the preparation thread.
pub struct Prep<B: ServoBackend> {
    requests: Arc<ArrayQueue<PrepRequest>>,
    results: Arc<ArrayQueue<Prepared<B>>>,
    retired: Arc<ArrayQueue<Retired<B>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl<B: ServoBackend + Send + 'static> Prep<B> {
    /// Start the thread; it builds engines with `make_engine` for `machine`.
    /// Traces go to `trace` (`None`: no traces).
    pub fn start(
        machine: MachineProfile,
        make_engine: EngineFactory<B>,
        trace: Option<TraceTo>,
        store: crate::machine_store::MachineStore,
    ) -> std::io::Result<Self> {
        let requests = Arc::new(ArrayQueue::new(PREP_QUEUE_CAPACITY));
        let results = Arc::new(ArrayQueue::new(PREP_QUEUE_CAPACITY));
        let retired = Arc::new(ArrayQueue::new(PREP_QUEUE_CAPACITY));
        let stop = Arc::new(AtomicBool::new(false));
        let mut worker = Worker {
            machine,
            store,
            make_engine,
            trace,
            requests: requests.clone(),
            results: results.clone(),
            retired: retired.clone(),
            stop: stop.clone(),
            job: None,
        };
        let thread = std::thread::Builder::new()
            .name("position-prep".into())
            .spawn(move || worker.run())?;
        Ok(Prep {
            requests,
            results,
            retired,
            stop,
            thread: Some(thread),
        })
    }
}

impl<B: ServoBackend> Prep<B> {
    /// False once the thread has ended (it only ends on a bug: a panic).
    pub fn is_alive(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    fn wake(&self) {
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    /// Ask for something (allocation-free). False when the queue is full.
    pub fn request(&self, r: PrepRequest) -> bool {
        let ok = self.requests.push(r).is_ok();
        self.wake();
        ok
    }

    /// A result, if one is ready (allocation-free).
    pub fn poll(&self) -> Option<Prepared<B>> {
        self.results.pop()
    }

    /// Hand something replaced back to be dropped off the cycle (allocation-free).
    /// If the queue is full it waits for the thread to make room: dropping it on the
    /// cycle would free memory there.
    pub fn retire(&self, r: Retired<B>) {
        let mut item = r;
        while let Err(back) = self.retired.push(item) {
            item = back;
            self.wake();
            // sleep, not yield: the thread may share this core at SCHED_OTHER
            std::thread::sleep(Duration::from_micros(50));
        }
        self.wake();
    }
}

impl<B: ServoBackend> Drop for Prep<B> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// The thread's side.
struct Worker<B: ServoBackend> {
    machine: MachineProfile,
    /// The machine's parameter file and tool table.
    store: crate::machine_store::MachineStore,
    make_engine: EngineFactory<B>,
    trace: Option<TraceTo>,
    requests: Arc<ArrayQueue<PrepRequest>>,
    results: Arc<ArrayQueue<Prepared<B>>>,
    retired: Arc<ArrayQueue<Retired<B>>>,
    stop: Arc<AtomicBool>,
    /// The latest job prepared and its PDC table designer.
    job: Option<(u64, Option<SpindleDesigner>)>,
}

impl<B: ServoBackend> Worker<B> {
    fn run(&mut self) {
        // started by the cycle thread: not at its SCHED_FIFO priority
        if let Err(e) = softnc_rt::leave_realtime() {
            tracing::warn!("position preparation thread: {e}");
        }
        while !self.stop.load(Ordering::Acquire) {
            while let Some(r) = self.retired.pop() {
                match r {
                    Retired::Job(mut p) => {
                        if let Some(t) = p.trace.take() {
                            t.finish();
                        }
                    }
                    Retired::Trace(t) => t.finish(),
                    Retired::Spindle(_) => {}
                }
            }
            while let Some(r) = self.requests.pop() {
                if let Some(done) = self.serve(r) {
                    self.deliver(done);
                }
            }
            std::thread::park_timeout(Duration::from_millis(5));
        }
        // the process is ending: what was retired last (a job's trace) is written out
        while let Some(r) = self.retired.pop() {
            drop(r);
        }
    }

    /// Hand a result over; waits while the cycle has not taken the earlier ones.
    fn deliver(&self, done: Prepared<B>) {
        let mut item = done;
        while let Err(back) = self.results.push(item) {
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            item = back;
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    fn serve(&mut self, r: PrepRequest) -> Option<Prepared<B>> {
        match r {
            PrepRequest::Job {
                job_id,
                path,
                spindle_override,
                start_mm,
                from_line,
                switches,
                adaptive_cap,
            } => {
                tracing::info!("job {job_id}: preparing the position process");
                // the job read as the interpolator reads it: the machine's offsets
                // and tools
                let setup =
                    self.store
                        .job_setup(&self.machine, start_mm, switches, from_line, job_id);
                let (machine, setup) = match setup {
                    Ok(s) => s,
                    Err(e) => {
                        tracing::warn!("job {job_id}: {e}");
                        (self.machine.clone(), crate::interp::JobSetup::at(start_mm))
                    }
                };
                let (mut prep, designer) = prepare_job(
                    &machine,
                    &mut self.make_engine,
                    job_id,
                    path.as_str(),
                    spindle_override,
                    &setup,
                );
                if let Some(to) = &self.trace {
                    let file = to.dir.join(format!("trace-job{job_id}.csv"));
                    let _ = std::fs::create_dir_all(&to.dir);
                    match crate::trace::TraceSink::start(&file, to.lossless) {
                        Ok(t) => prep.trace = Some(t),
                        Err(e) => tracing::warn!("cannot trace to {}: {e}", file.display()),
                    }
                }
                if let Some(cap) = adaptive_cap {
                    match AdaptiveFeed::from_profile(&machine, cap) {
                        Ok(a) => prep.adaptive = Some(a),
                        Err(e) => {
                            prep.error
                                .get_or_insert((usize::MAX, format!("job {job_id}: {e}")));
                        }
                    }
                }
                self.job = Some((job_id, designer));
                Some(Prepared::Job(Box::new(prep)))
            }
            PrepRequest::SpindleOverride {
                job_id,
                spindle_override,
            } => {
                let designer = match &self.job {
                    Some((id, Some(d))) if *id == job_id => d,
                    // another job, or one without a spindle to follow
                    _ => return None,
                };
                Some(match designer.design(spindle_override) {
                    Ok(designs) => Prepared::Spindle {
                        job_id,
                        designs: Box::new(designs),
                    },
                    Err(e) => Prepared::SpindleRefused {
                        job_id,
                        spindle_override,
                        message: FixedStr::truncated(&e.to_string()),
                    },
                })
            }
        }
    }
}

/// (first motion, rpm) wherever a job's spindle speed changes.
type SpindleChanges = Vec<(u32, f64)>;

/// A job's motions as the position process keeps them: each one's programmed
/// primitive and program line.
type JobMotions = (Vec<Option<Primitive>>, Vec<u32>);

/// The programmed primitive of every motion of the program at `path` (what the
/// contour error is measured against; a plan keeps the same ones,
/// `softnc-planner/tests/it/motion_primitives.rs`) and its spindle speed changes, read
/// from `start_mm` without planning the program whole: the motions are read in
/// chunks, the spindle changes come from the streamed check.
fn job_primitives(
    path: &str,
    machine: &MachineProfile,
    setup: &crate::interp::JobSetup,
) -> Result<(JobMotions, SpindleChanges), String> {
    let (text, options, checked, _, _, _) = crate::interp::check_job(path, machine, setup)?;
    let mut primitives = Vec::with_capacity(checked.motions());
    let mut lines = Vec::with_capacity(checked.motions());
    softnc_gcode::read_program_chunked_with(
        &text,
        path,
        machine,
        &options.read_options(),
        softnc_planner::plan::READ_CHUNK_MOTIONS,
        &mut |chunk| {
            primitives.extend(chunk.iter().map(softnc_planner::build::motion_primitive));
            lines.extend(chunk.iter().map(|m| m.line));
        },
    )
    .map_err(|e| e.to_string())?;
    Ok(((primitives, lines), checked.spindle_changes().to_vec()))
}

/// Read and plan the program at `path` (if any), build the job's engine and design
/// its PDC tables at `spindle_override`. A program that cannot be read gives no
/// path: the interpolator refuses it and raises the alarm.
pub fn prepare_job<B: ServoBackend>(
    machine: &MachineProfile,
    make_engine: &mut EngineFactory<B>,
    job_id: u64,
    path: &str,
    spindle_override: f64,
    setup: &crate::interp::JobSetup,
) -> (JobPrep<B>, Option<SpindleDesigner>) {
    let ((primitives, lines), spindle_changes) = if path.is_empty() {
        ((Vec::new(), Vec::new()), Vec::new())
    } else {
        job_primitives(path, machine, setup).unwrap_or_default()
    };
    // a fresh machine for every job, exactly as `softnc sim` starts one
    let mut engine = make_engine();
    let error = engine
        .set_spindle_schedule(machine, &spindle_changes, spindle_override)
        .err()
        .map(|e| {
            (
                e.axis,
                format!("job {job_id}: a spindle speed of the job: {e}"),
            )
        });
    let designer = engine.spindle_designer(machine, &spindle_changes);
    (
        JobPrep {
            job_id,
            engine,
            primitives,
            lines,
            trace: None,
            error,
            adaptive: None,
        },
        designer,
    )
}

#[cfg(test)]
mod tests {
    use softnc_rt::{leave_realtime, setup_realtime, RtOptions};

    #[test]
    fn a_helper_thread_can_always_leave_realtime() {
        // without privileges SCHED_FIFO is refused, but going (back) to SCHED_OTHER
        // never is
        std::thread::spawn(|| {
            let _ = setup_realtime(&RtOptions {
                fifo_priority: Some(10),
                ..RtOptions::default()
            });
            leave_realtime().unwrap();
            let policy = thread_priority::thread_schedule_policy().unwrap();
            assert_eq!(
                policy,
                thread_priority::ThreadSchedulePolicy::Normal(
                    thread_priority::NormalThreadSchedulePolicy::Other
                )
            );
        })
        .join()
        .unwrap();
    }
}
