//! The interpolation cycle allocates nothing once motion has started: a counting
//! global allocator (counting only on the thread that runs the cycles) proves it,
//! while the operator changes the feed override, holds and resumes — and, for a
//! learned job, while its correction is added and then faded out with a note. Every
//! `tracing` event counts as an allocation too (the test's subscriber formats each
//! one), so nothing is logged on the cycle either.
//!
//! The test plays the position process: it reads the command samples the
//! interpolator's outbox thread publishes and reports them used, one per cycle.

use softnc_daemon::config::Loaded;
use softnc_daemon::interp::{InterpTask, JobEnd};
use softnc_ipc::bus::Bus;
use softnc_ipc::{
    AlarmCode, CommandSample, ControlCommand, ControlKind, FixedStr, MachineState, PositionStatus,
    ServiceNames, MAX_AXES,
};
use std::path::PathBuf;
use std::time::{Duration, Instant};

mod common;
use common::{allocations, count};

#[global_allocator]
static GLOBAL: common::Counting = common::Counting;

/// A subscriber that formats every event, as a real one would: a log line on the
/// cycle thread is an allocation there.
struct Formatting;

impl tracing::Subscriber for Formatting {
    fn enabled(&self, _: &tracing::Metadata<'_>) -> bool {
        true
    }
    fn new_span(&self, _: &tracing::span::Attributes<'_>) -> tracing::span::Id {
        tracing::span::Id::from_u64(1)
    }
    fn record(&self, _: &tracing::span::Id, _: &tracing::span::Record<'_>) {}
    fn record_follows_from(&self, _: &tracing::span::Id, _: &tracing::span::Id) {}
    fn event(&self, event: &tracing::Event<'_>) {
        std::hint::black_box(format!("{event:?}"));
    }
    fn enter(&self, _: &tracing::span::Id) {}
    fn exit(&self, _: &tracing::span::Id) {}
}

/// A daemon configuration of its own in a fresh folder (lockstep, learning store
/// `<dir>/learning`).
fn setup(tag: &str) -> (PathBuf, Loaded) {
    // (once per test binary; a second test finds it set)
    let _ = tracing::subscriber::set_global_default(Formatting);
    common::lockstep_config(&format!("noallocinterp{tag}"), "default.ron", true)
}

fn status(seq: u64, job_id: u64) -> PositionStatus {
    PositionStatus {
        seq,
        job_id,
        time_index: seq,
        cmd_mm: [0.0; MAX_AXES],
        actual_mm: [0.0; MAX_AXES],
        following_err_mm: [0.0; MAX_AXES],
        ctrl_out: [0.0; MAX_AXES],
        contour_err_mm: f64::NAN,
        ring_fill: 0,
        state: MachineState::Running.wire(),
        spindle_override: 1.0,
        spindle_rpm: 0.0,
        path_mm: 0.0,
        motion: 0,
        line: 0,
        homed: 0,
        mmi_control_seq: 0,
        force_override: f64::NAN,
        force_revolutions: 0,
        force_n: f64::NAN,
        inputs: softnc_ipc::payload::InputsWire::default(),
        outputs: softnc_core::MachineOutputs::safe().into(),
    }
}

struct Counted {
    /// Every command sample of the job, in order.
    samples: Vec<CommandSample>,
    /// Cycles counted and samples the interpolator sent during them.
    cycles: usize,
    sent: u64,
    /// Heartbeats published while counted.
    heartbeats: usize,
    /// The job's notes.
    notes: Vec<String>,
    learned: bool,
    /// Path length of the last sample sent while counted (mm).
    last_counted_step_mm: f64,
}

/// Stream `job_text` as job 1 through an interpolation task, the cycles counted
/// once motion runs; `controls` are sent that many counted cycles in.
fn run_counted(
    tag: &str,
    job_text: &str,
    learned: bool,
    controls: &[(usize, ControlKind, f64)],
) -> Counted {
    run_counted_with(tag, job_text, learned, controls, None)
}

/// [`run_counted`]; with `force_override`, the job runs with adaptive feed and the
/// position process played by the test reports a force-loop revolution with that
/// override every [`SAMPLES_PER_REVOLUTION`] samples.
#[allow(clippy::too_many_lines)]
fn run_counted_with(
    tag: &str,
    job_text: &str,
    learned: bool,
    controls: &[(usize, ControlKind, f64)],
    force_override: Option<f64>,
) -> Counted {
    let (dir, loaded) = setup(tag);
    let job = dir.join("job.ngc");
    std::fs::write(&job, job_text).unwrap();
    // the checked setup the MMI keeps for a job it checked (the interpolator reads
    // the job as it was checked): the profile's offsets, no preamble, no subroutine
    let programs = loaded
        .data_dir
        .join(softnc_daemon::machine_store::PROGRAMS_DIR);
    std::fs::create_dir_all(&programs).unwrap();
    softnc_daemon::jobfile::CheckedSetup {
        job_id: 1,
        program: job.clone(),
        sha256: softnc_daemon::jobfile::sha256_hex(job_text.as_bytes()),
        preamble: None,
        preamble_file: None,
        params: None,
        subroutines: Vec::new(),
    }
    .save(&programs)
    .unwrap();
    if learned {
        common::learn_job(
            &dir.join("learning"),
            &job,
            &dir.join("machines/default.ron"),
            1,
        );
    }
    // a user M code (M101) in the default folder, beside the data directory
    std::fs::create_dir_all(&loaded.user_m_dir).unwrap();
    let m101 = loaded.user_m_dir.join("M101");
    std::fs::write(&m101, "#!/bin/sh\nexit 0\n").unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&m101, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let names = ServiceNames::new(&loaded.config.service_prefix, &loaded.config.instance);
    let ahead = loaded.config.lookahead_samples as u64;
    let mut task = InterpTask::new(loaded).unwrap();
    // the position process and the MMI, played by the test
    let bus = Bus::new(names, "test-position").unwrap();
    let commands = bus.command_subscriber().unwrap();
    let statuses = bus.status_publisher().unwrap();
    let control = bus.control_publisher().unwrap();
    let alarms = bus.alarm_subscriber().unwrap();
    let heartbeats = bus.heartbeat_subscriber().unwrap();

    let job_id = 1;
    let mut planned = task
        .plan_job(
            job.to_str().unwrap(),
            job_id,
            1.0,
            None,
            force_override.is_some(),
        )
        .unwrap()
        .expect("the job is planned");
    assert_eq!(
        planned.learned(),
        learned,
        "a learned correction was loaded"
    );
    let mut stream = task.start(&mut planned).unwrap();
    assert_eq!(task.state(), MachineState::Running);

    let mut received: Vec<CommandSample> = Vec::new();
    let mut consumed: Option<u64> = None;
    let mut notes = Vec::new();
    // the position process: takes what has arrived, uses one sample per cycle
    // (`fast`: all it has)
    let mut position = |received: &mut Vec<CommandSample>, fast: bool| {
        while let Some(c) = commands.receive().unwrap() {
            received.push(*c);
        }
        if let Some(last) = received.last() {
            let next = if fast {
                last.seq
            } else {
                consumed.map_or(0, |c| (c + 1).min(last.seq))
            };
            consumed = Some(next);
            let mut st = status(next, job_id);
            // the machine: the sample's motion, the spindle at speed, the tool
            // changer done (the machine stops are released on what it reports)
            st.motion = received[next as usize].motion;
            st.inputs = softnc_core::machine_io::MachineInputs {
                spindle_at_speed: true,
                tool_changed: true,
                ..Default::default()
            }
            .into();
            if let Some(f) = force_override {
                st.force_override = f;
                st.force_revolutions = next / SAMPLES_PER_REVOLUTION;
            }
            statuses.send_copy(st).unwrap();
        }
    };
    let collect_notes = |notes: &mut Vec<String>| {
        while let Some(a) = alarms.receive().unwrap() {
            assert_eq!(a.code, AlarmCode::Note.wire(), "{:?}", a.message);
            notes.push(a.message.as_str().to_string());
        }
    };

    // motion starts: the ring is filled and the first samples are used (uncounted:
    // the first heartbeat, the first connections)
    let t0 = Instant::now();
    while received.len() < (ahead + 20) as usize {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "motion did not start"
        );
        assert_eq!(task.cycle(&mut stream).unwrap(), None);
        position(&mut received, false);
        std::thread::sleep(Duration::from_micros(200));
    }
    while heartbeats.receive().unwrap().is_some() {}

    let sent_before = stream.sent();
    let mut cycles = 0;
    for i in 0..500 {
        // the operator's and the position process's allocations are not counted
        for &(at, kind, value) in controls {
            if at == i {
                control
                    .send_copy(ControlCommand {
                        flags: 0,
                        seq: i as u64,
                        sender: softnc_ipc::ProcessId::Mmi.wire(),
                        kind: kind.wire(),
                        job_id: 0,
                        axis: u32::MAX,
                        value,
                        path: FixedStr::empty(),
                    })
                    .unwrap();
            }
        }
        let end = count(|| task.cycle(&mut stream).unwrap());
        assert_eq!(end, None, "the job is still running while counted");
        cycles += 1;
        position(&mut received, false);
        // real cycles take time: heartbeats fall due while counted
        std::thread::sleep(Duration::from_micros(200));
    }
    let sent = stream.sent() - sent_before;
    let mut hb = 0;
    while heartbeats.receive().unwrap().is_some() {
        hb += 1;
    }
    let allocs = allocations();
    assert_eq!(
        allocs, 0,
        "{allocs} allocations in {cycles} interpolation cycles"
    );

    // the rest of the job, uncounted: every sample arrives, in order, once
    let t0 = Instant::now();
    let end = loop {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "the job did not end"
        );
        if let Some(end) = task.cycle(&mut stream).unwrap() {
            break end;
        }
        position(&mut received, true);
        std::thread::sleep(Duration::from_micros(200));
    };
    assert_eq!(end, JobEnd::Completed);
    assert_eq!(task.state(), MachineState::Idle);
    let last = received.last().expect("samples arrived");
    assert!(last.is_end(), "the last sample ends the job");
    assert_eq!(last.seq + 1, stream.sent(), "every sample arrived");
    for (k, c) in received.iter().enumerate() {
        assert_eq!((c.seq, c.job_id), (k as u64, job_id), "in order, once");
    }
    // (read while the outbox thread lives: its samples go with it)
    std::thread::sleep(Duration::from_millis(20));
    collect_notes(&mut notes);
    drop(task);
    let _ = std::fs::remove_dir_all(&dir);
    let step_mm = |k: usize| {
        let (a, b) = (received[k - 1].pos_mm, received[k].pos_mm);
        ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
    };
    let last_counted_step_mm = step_mm((sent_before + sent - 1) as usize);
    Counted {
        samples: received,
        cycles,
        sent,
        heartbeats: hb,
        notes,
        learned,
        last_counted_step_mm,
    }
}

/// Samples between the force-loop revolutions the test's position process reports.
const SAMPLES_PER_REVOLUTION: u64 = 50;

/// Adaptive feed: the force loop's overrides arrive in the position process's
/// status, are scheduled `lookahead` samples on and applied through the override
/// path — nothing allocated; the operator's override caps them.
#[test]
fn adaptive_feed_overrides_allocate_nothing_and_the_operator_caps_them() {
    // 600 mm/min = 0.01 mm a 1 ms sample; the loop asks for 50 %, later 80 %, and
    // the operator caps at 60 % (counted cycle 250)
    let text = "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X50 F600\nM2\n";
    let c = run_counted_with("adaptive", text, false, &[], Some(0.5));
    assert!(
        (c.last_counted_step_mm - 0.005).abs() < 1e-6,
        "{} mm a sample at the loop's 50 %",
        c.last_counted_step_mm
    );
    let c = run_counted_with(
        "adaptivecap",
        text,
        false,
        &[(250, ControlKind::FeedOverride, 0.6)],
        Some(0.8),
    );
    assert!(
        (c.last_counted_step_mm - 0.006).abs() < 1e-6,
        "{} mm a sample: 80 % capped at the operator's 60 %",
        c.last_counted_step_mm
    );
}

#[test]
fn interpolation_cycle_allocates_nothing_during_motion() {
    // 50 mm at 600 mm/min: 5 s of motion, far more than counted; override, hold and
    // resume while counted
    let counted = run_counted(
        "plain",
        "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X30 F600\nG2 X40 Y10 R10\nG1 Y20\nM2\n",
        false,
        &[
            (100, ControlKind::FeedOverride, 0.5),
            (200, ControlKind::Hold, 0.0),
            (300, ControlKind::Resume, 0.0),
            (350, ControlKind::FeedOverride, 1.5),
        ],
    );
    assert!(!counted.learned);
    assert!(
        counted.sent >= counted.cycles as u64 - 50,
        "samples sent while counted: {}",
        counted.sent
    );
    assert!(counted.heartbeats >= 1, "a heartbeat while counted");
    assert!(counted.notes.is_empty(), "{:?}", counted.notes);
}

#[test]
fn a_learned_job_fading_its_correction_out_allocates_nothing_on_the_cycle() {
    // 2.5 s of motion, learned once; the override changed while counted re-times the
    // job: the correction fades out and a note says so (formatted in place)
    let counted = run_counted(
        "learned",
        "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X20 F1200\nG3 X10 Y10 I-10 J0\nG1 Y20\nM2\n",
        true,
        &[(200, ControlKind::FeedOverride, 0.8)],
    );
    assert!(counted.learned);
    assert!(counted.heartbeats >= 1, "a heartbeat while counted");
    assert!(counted.sent > 0);
    assert_eq!(counted.notes.len(), 2, "{:?}", counted.notes);
    assert!(
        counted.notes[0].starts_with("learned correction applied"),
        "{:?}",
        counted.notes
    );
    assert!(
        counted.notes[1].starts_with("learned correction faded out"),
        "{:?}",
        counted.notes
    );
}

#[test]
fn a_job_with_machine_stops_allocates_nothing_on_the_cycle() {
    // the spindle, coolant, a message, M66 and a (DEBUG,…) showing its result, a
    // user M code, a tool change and synchronised outputs, each machine stop
    // waiting `lookahead` samples for the machine to apply it: the counted cycles
    // pass the print and message, the M66 (its result noted), the debug text
    // filled in with it and the start of M101 (its executable started by the
    // runner thread, its end heard back) (formatted in place)
    let counted = run_counted(
        "machine",
        "G21 G90 G17\nG0 X0 Y0 Z0\nS1000 M3\nM8\nG1 X0.5 F600\n(PRINT, printed)\n(MSG, hello)\nM66 P0 L0\n(DEBUG, got %d#5399)\nM101 P1 Q2\nT2 M6\nM62 P1\nG1 X1\nM63 P1\nG1 X1.5\nM9\nM5\nG1 X2\nM2\n",
        false,
        &[],
    );
    assert!(counted.sent > 0);
    assert!(counted.heartbeats >= 1, "a heartbeat while counted");
    assert_eq!(
        counted.notes,
        [
            "print: printed",
            "message: hello",
            "M66 P0 (line 8): 0 (#5399)",
            "message: got 0",
            "prompt: running M101 1.000000 2.000000"
        ],
        "the print (for the record), the message, M66's result, the debug text, M101's \
         prompt, in order (M101 exited 0: the job completed)"
    );
    let outputs: Vec<softnc_core::machine_io::MachineOutputs> =
        counted.samples.iter().map(|c| c.outputs.into()).collect();
    assert!(outputs
        .iter()
        .any(|o| o.coolant_flood && o.spindle_rpm == 1000.0));
    assert!(
        outputs.iter().any(|o| o.digital & 2 != 0),
        "M62 P1 switched"
    );
    let last = outputs.last().unwrap();
    assert!(!last.coolant_flood && last.digital == 0, "{last:?}");
}
