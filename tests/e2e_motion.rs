//! End-to-end tests of motion's edge cases through softncd, its three processes and
//! the operator client: what moves nothing holds every axis, a dwell takes its
//! time, a stalled loop is a fault, homing after an E-stop, loop-timing alarms.
// (the harness re-exports what other test files use)
#[allow(unused_imports)]
mod support;
use support::*;

/// Rows (cmd x y z, actual x y z) of job `job_id`'s trace, once its file is
/// complete (the trace thread closes it); empty if the job wrote none.
fn trace_rows(d: &Daemon, job_id: u64) -> Vec<[f64; 6]> {
    let path = d.dir.join(format!("data/trace-job{job_id}.csv"));
    let t0 = Instant::now();
    let mut last_len = usize::MAX;
    loop {
        // written by its own thread: done once it stops growing
        let len = std::fs::metadata(&path).map_or(0, |m| m.len() as usize);
        if (len > 0 && len == last_len) || t0.elapsed() > Duration::from_secs(5) {
            break;
        }
        last_len = len;
        std::thread::sleep(Duration::from_millis(200));
    }
    trace_columns(&std::fs::read_to_string(&path).unwrap_or_default())
}

/// How far a held axis may be measured from its command: the simulated machine's
/// servo holds within tens of µm between jobs (the failures this guards against
/// are steps of millimetres).
const ACTUAL_TOL_MM: f64 = 0.1;

/// The measured position in the status.
fn actual_mm(s: &Status) -> [f64; 3] {
    let axes = s.axes.as_ref().expect("the axes");
    [0, 1, 2].map(|i| axes.actual_mm[i])
}

/// Run `text` as MDI (or, with `as_job`, as a job file); wait until it has ended and
/// the machine is idle. `None`: refused (with its message).
fn run_block(d: &Daemon, op: &Operator, text: &str, as_job: bool) -> Result<u64, String> {
    let r = if as_job {
        let job = d.dir.join("zero.ngc");
        std::fs::write(&job, text).unwrap();
        op.request(&submit(&abs(&job))).unwrap()
    } else {
        op.request(&mdi_request(text)).unwrap()
    };
    if !r.is_accepted() {
        return Err(r.message().to_string());
    }
    let s = d.wait_job(op, id(&r), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{text:?}: {s}");
    d.wait_status(op, Duration::from_secs(10), "idle", |s| {
        s.state == MachineState::Idle
    });
    Ok(id(&r))
}

/// Every shape of a block or job that moves nothing leaves every axis where it
/// stands: commanded exactly there, measured within the in-position band, in the
/// status and in every traced cycle; no alarm; and a real move after them lands
/// where it should.
fn zero_motion_holds_every_axis(tag: &str, edits: &[(&str, &str)]) {
    let d = Daemon::start_in(fresh_dir(tag), tag, "Lockstep", true, "default.ron", edits);
    let op = d.operator();
    run_block(&d, &op, "G90 G0 X5 Y5 Z0", false).unwrap();
    let p = machine_mm(&op.status().unwrap());
    assert!(p[0] > 1.0 && p[1] > 1.0, "the first move went to {p:?}");
    // (the reader refuses an arc to its own start with R, and one of zero radius,
    // as LinuxCNC does: a full circle is not a zero-length arc)
    let refused_arcs = [
        "F300 G2 X5 Y5 R3",
        "F300 G2 X5 Y5 I0 J0",
        "F300 G3 I0 J0 Z0",
    ];
    let blocks = [
        "G0 X5",
        "G0 X5 Y5 Z0",
        "G1 X5 Y5 F300",
        "G91 G0 X0 Y0 Z0",
        "G1 Z0 F300",
        "G90",
        "G4 P0.3",
        "M3 S1000",
        "M5",
        "M8",
        "M9",
        "G92 X1",
        "G92.1",
        "G10 L2 P2 X1 Y2",
        "G0 X5 Y5 Z0\nG1 X5 F300\nG4 P0.2\nG0 Y5",
    ];
    let jobs = [
        "G21 G90\nG0 X5 Y5 Z0\nG1 X5 Y5 Z0 F300\nM2\n",
        "G21 G90\nG4 P0.2\nM2\n",
        "G21 G90\nM3 S800\nM8\nM9\nM5\nM2\n",
        "G21 G90\nG92 X3\nG92.1\nG10 L2 P3 X1\nM2\n",
        "%\nG0 X5\n%\n",
    ];
    let mut ran = Vec::new();
    let check = |what: &str, ran: &mut Vec<u64>, result: Result<u64, String>| {
        if let Ok(id) = result {
            ran.push(id);
        }
        let s = op.status().unwrap();
        assert_eq!(s.state, MachineState::Idle, "after {what:?}: {s}");
        let (cmd, act) = (machine_mm(&s), actual_mm(&s));
        for axis in 0..3 {
            assert!(
                (cmd[axis] - p[axis]).abs() < 1e-9 && (act[axis] - p[axis]).abs() < ACTUAL_TOL_MM,
                "after {what:?} the machine is commanded at {cmd:?}, measured at {act:?}; it stood at {p:?}"
            );
        }
        let alarms = &s.alarms;
        assert!(
            alarms.iter().all(|a| a.code == AlarmKind::JobRefused),
            "after {what:?}: {alarms:?}"
        );
    };
    for b in refused_arcs {
        let r = run_block(&d, &op, b, false);
        assert!(r.is_err(), "{b:?} was taken");
        check(b, &mut ran, r);
    }
    for b in blocks {
        let r = run_block(&d, &op, b, false);
        assert!(r.is_ok(), "{b:?}: {r:?}");
        check(b, &mut ran, r);
    }
    for j in jobs {
        let r = run_block(&d, &op, j, true);
        assert!(r.is_ok(), "{j:?}: {r:?}");
        check(j, &mut ran, r);
    }
    // every cycle that ran, commanded and measured where the machine stood (a
    // job done with nothing to move never reached the position loop: no trace)
    let jobs = op.jobs().unwrap();
    for id in ran {
        let cycles = jobs.iter().find(|j| j.job_id == id).unwrap().cycles;
        let file = d.dir.join(format!("data/trace-job{id}.csv"));
        if cycles == 0 {
            assert!(!file.exists(), "job {id} ran no cycle but left a trace");
            continue;
        }
        let rows = trace_rows(&d, id);
        assert!(!rows.is_empty(), "job {id} ran {cycles} cycles: no trace");
        for row in rows {
            for axis in 0..3 {
                assert!(
                    (row[axis] - p[axis]).abs() < 1e-9
                        && (row[3 + axis] - p[axis]).abs() < ACTUAL_TOL_MM,
                    "job {id} commanded {:?}, measured {:?}; the machine stood at {p:?}",
                    &row[..3],
                    &row[3..]
                );
            }
        }
    }
    // and the machine still moves as programmed
    run_block(&d, &op, "G90 G0 X6 Y5 Z0", false).unwrap();
    let at = machine_mm(&op.status().unwrap());
    assert!(
        (at[0] - (p[0] + 1.0)).abs() < 1e-9 && (at[1] - p[1]).abs() < 1e-9,
        "{at:?}"
    );
}

#[test]
fn a_block_or_job_that_moves_nothing_holds_every_axis_on_the_simulated_machine() {
    zero_motion_holds_every_axis("zerosim", &[]);
}

#[test]
fn a_block_or_job_that_moves_nothing_holds_every_axis_on_the_loopback_drive() {
    zero_motion_holds_every_axis("zeroloop", &[("backend: Simulated", "backend: Loopback")]);
}

/// Submit `text` as a job file (or MDI) and time it to its end: (seconds, the final
/// status).
/// A job that changes the tool and takes its length (`T1 M6`, `G43 H1`, as
/// `examples/demo.ngc` does) runs a second time on the same machine: the modal
/// state the first left (`G43.1 Z…`) does not move its start by the tool's
/// length (found from the web panel: the second run jumped Z by 12.979 mm and
/// tripped the following-error limit).
#[test]
fn a_job_with_a_tool_length_offset_runs_again_without_a_jump() {
    let tag = "toolagain";
    let d = Daemon::start_in(fresh_dir(tag), tag, "Lockstep", true, "default.ron", &[]);
    let op = d.operator();
    let text = "G21 G90\nT1 M6\nG43 H1\nG0 X5 Y5\nG1 Z-2 F600\nG0 Z5\nM2\n";
    for run in 0..2 {
        let job_id = run_block(&d, &op, text, true).unwrap_or_else(|e| panic!("run {run}: {e}"));
        let s = op.status().unwrap();
        assert!(
            alarms_with(&s, AlarmKind::FollowingError).is_empty(),
            "run {run}: {:?}",
            s.alarms
        );
        // every traced cycle's command within one cycle's travel of the last
        let rows = trace_rows(&d, job_id);
        assert!(rows.len() > 100, "run {run}: {} traced cycles", rows.len());
        for w in rows.windows(2) {
            let step = (0..3)
                .map(|k| (w[1][k] - w[0][k]).abs())
                .fold(0.0, f64::max);
            assert!(step < 1.0, "run {run}: a step of {step} mm in the command");
        }
    }
}

fn timed_run(d: &Daemon, op: &Operator, text: &str, as_job: bool) -> (f64, Status) {
    let t0 = Instant::now();
    let r = if as_job {
        let job = d.dir.join("dwell.ngc");
        std::fs::write(&job, text).unwrap();
        op.request(&submit(&abs(&job))).unwrap()
    } else {
        op.request(&mdi_request(text)).unwrap()
    };
    assert!(r.is_accepted(), "{text:?}: {}", r.message());
    let s = d.wait_job(op, id(&r), Duration::from_secs(30));
    (t0.elapsed().as_secs_f64(), s)
}

#[test]
fn a_program_that_only_dwells_takes_its_dwell_holding_still() {
    let d = Daemon::start("dwell", "Realtime", false);
    let op = d.operator();
    run_block(&d, &op, "G90 G0 X5 Y5 Z0", false).unwrap();
    let p = machine_mm(&op.status().unwrap());
    for (text, as_job, dwell_s) in [
        ("G4 P1", false, 1.0),
        // (with a feed: a program that ends in M2 with none leaves the modal
        // preamble a G1 at feed 0, which the next job is refused on — the files
        // area's modal preamble, not this test's)
        ("G21 G90 F600\nG4 P2\nM2\n", true, 2.0),
        // a dwell between moves still stands its time at the first move's end
        ("G21 G90\nG1 X6 F600\nG4 P1\nG1 X5\nM2\n", true, 1.0 + 0.2),
    ] {
        let (took_s, s) = timed_run(&d, &op, text, as_job);
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{text:?}: {s}");
        assert!(
            took_s >= dwell_s * 0.95,
            "{text:?} ended after {took_s:.3} s: its dwell was skipped"
        );
        let cycles = job_of(&s).cycles;
        assert!(
            cycles as f64 >= dwell_s * 1000.0 * 0.95,
            "{text:?}: {cycles} cycles"
        );
        let s = d.wait_status(&op, Duration::from_secs(5), "idle", |s| {
            s.state == MachineState::Idle
        });
        let at = machine_mm(&s);
        for axis in 0..3 {
            assert!(
                (at[axis] - p[axis]).abs() < 1e-9,
                "{text:?}: at {at:?}, from {p:?}"
            );
        }
    }
}

#[test]
fn an_estop_during_homing_leaves_the_axes_unhomed_and_a_later_home_homes_them() {
    let tag = "homeestop";
    let dir = fresh_dir(tag);
    let profile = quick_homing_profile(&dir.join("profile"));
    let d = Daemon::start_in(
        dir.clone(),
        tag,
        "Lockstep",
        false,
        profile.to_str().unwrap(),
        &[],
    );
    let op = d.operator();
    let all_homed = vec![true, true, true];
    let (ok, msg) = ask(&op, &Request::Home { axis: None });
    assert!(ok, "{msg}");
    // under way: the first axis has left where it stood
    let s0 = machine_mm(&op.status().unwrap());
    d.wait_status(&op, Duration::from_secs(20), "homing moves", |s| {
        s.state == MachineState::Homing && (0..3).any(|i| (machine_mm(s)[i] - s0[i]).abs() > 1.0)
    });
    let (ok, msg) = ask(&op, &Request::EStop);
    assert!(ok, "{msg}");
    let s = d.wait_status(&op, Duration::from_secs(5), "E-stop", |s| {
        s.state == MachineState::EStopped
    });
    assert_ne!(s.homed, all_homed, "{s}");
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok, "{msg}");
    let s = d.wait_status(&op, Duration::from_secs(5), "reset", |s| {
        s.state == MachineState::Idle || s.state == MachineState::Off
    });
    if s.state == MachineState::Off {
        op.machine_on(Duration::from_secs(10)).unwrap();
    }
    // homing again homes every axis, as it does the first time
    let (ok, msg) = ask(&op, &Request::Home { axis: None });
    assert!(ok, "{msg}");
    let t0 = Instant::now();
    let s = d.wait_status(&op, Duration::from_secs(60), "homed", |s| {
        s.state == MachineState::Idle
            && (s.homed == all_homed || t0.elapsed() > Duration::from_secs(2))
    });
    assert_eq!(s.homed, all_homed, "home after the E-stop did nothing: {s}");
    let home = machine_mm(&s);
    for (got, want) in home.iter().zip([0.0, 0.0, 90.0]) {
        assert!((got - want).abs() < 1e-9, "home position {home:?}");
    }
}

/// Send `signal` (`-STOP`, `-CONT`) to `pid`.
/// The messages of the status's alarms with `code`.
fn alarms_with(s: &Status, code: AlarmKind) -> Vec<String> {
    s.alarms
        .iter()
        .filter(|a| a.code == code)
        .map(|a| a.message.clone())
        .collect()
}

/// After a fault: reset (and on, if the reset leaves the machine off), then a job
/// runs to its end.
fn reset_and_run_a_job(d: &Daemon, op: &Operator) {
    let (ok, msg) = ask(op, &Request::Reset);
    assert!(ok, "{msg}");
    let s = d.wait_status(op, Duration::from_secs(10), "reset", |s| {
        s.state == MachineState::Idle || s.state == MachineState::Off
    });
    if s.state == MachineState::Off {
        op.machine_on(Duration::from_secs(10)).unwrap();
    }
    d.runs_the_short_job(op);
}

#[test]
fn a_stall_of_the_position_loop_mid_job_stops_the_machine_as_a_fault() {
    let d = Daemon::start("stallpos", "Realtime", false);
    let op = d.operator();
    let job = start_moving(&d, &op);
    let pid = d.pid_of("softnc-position").unwrap();
    // 1 s: ten times the stall bound, a tenth of the supervisor's watchdog
    stop_for(pid, Duration::from_secs(1));
    let s = d.wait_job(&op, job, Duration::from_secs(20));
    assert_eq!(
        job_of(&s).outcome,
        Outcome::Aborted,
        "the job went on after the stall: {s}"
    );
    let s = d.wait_status(&op, Duration::from_secs(10), "the stall fault", |s| {
        s.state == MachineState::Faulted && !alarms_with(s, AlarmKind::LoopStall).is_empty()
    });
    let stall = alarms_with(&s, AlarmKind::LoopStall);
    assert!(stall[0].contains("position loop stood"), "{stall:?}");
    // it stays faulted (not resumed), the process the same one (not the watchdog's)
    std::thread::sleep(Duration::from_millis(1500));
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Faulted, "{s}");
    assert_eq!(d.pid_of("softnc-position"), Some(pid));
    reset_and_run_a_job(&d, &op);
}

#[test]
fn a_stall_of_the_interpolation_loop_mid_job_is_noticed_and_the_job_stops() {
    let d = Daemon::start("stallinterp", "Realtime", false);
    let op = d.operator();
    let job = start_moving(&d, &op);
    let pid = d.pid_of("softnc-interp").unwrap();
    stop_for(pid, Duration::from_secs(1));
    let s = d.wait_job(&op, job, Duration::from_secs(20));
    assert_ne!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let s = d.wait_status(&op, Duration::from_secs(10), "the stall alarm", |s| {
        alarms_with(s, AlarmKind::LoopStall)
            .iter()
            .any(|m| m.contains("interpolation loop stood"))
    });
    assert_ne!(s.state, MachineState::Running, "{s}");
    reset_and_run_a_job(&d, &op);
}

#[test]
fn late_position_cycles_raise_one_alarm_per_period_not_one_per_cycle() {
    let d = Daemon::start_edited(
        "late",
        "Realtime",
        &[("late_alarm_period_s: 10.0", "late_alarm_period_s: 4.0")],
    );
    let op = d.operator();
    d.wait_status(&op, Duration::from_secs(10), "loop figures", |s| {
        s.loops.position.map_or(0, |l| l.cycles) > 500
    });
    let pid = d.pid_of("softnc-position").unwrap();
    let late_of_position = |s: &Status| {
        alarms_with(s, AlarmKind::LoopLate)
            .into_iter()
            .filter(|m| m.contains("position loop ran late"))
            .collect::<Vec<_>>()
    };
    // three 40 ms stops within a second: late (beyond 10 ms), no stall (100 ms)
    let t0 = Instant::now();
    for _ in 0..3 {
        stop_for(pid, Duration::from_millis(40));
        std::thread::sleep(Duration::from_millis(300));
    }
    let s = d.wait_status(&op, Duration::from_secs(5), "a late-cycle alarm", |s| {
        !late_of_position(s).is_empty()
    });
    assert_eq!(
        s.state,
        MachineState::Idle,
        "late cycles are not a fault: {s}"
    );
    assert!(
        t0.elapsed() < Duration::from_secs(4),
        "the period is over already"
    );
    assert_eq!(late_of_position(&s).len(), 1, "{s}");
    // the rest in one alarm once the period is over, with their count
    let s = d.wait_status(&op, Duration::from_secs(10), "the period's alarm", |s| {
        late_of_position(s).len() >= 2
    });
    let msgs = late_of_position(&s);
    assert_eq!(msgs.len(), 2, "one alarm per period: {msgs:?}");
    let count: u64 = msgs[0]
        .split("ran late: ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(count >= 2, "{msgs:?}");
}

/// The trace's columns of the machine around the axes (spindle command and actual
/// rpm, coolant bits, M62 outputs) beside cmd x, per row.
fn machine_trace(d: &Daemon, job_id: u64) -> Vec<[f64; 5]> {
    trace_rows(d, job_id); // (waits until the file is complete)
    let text = std::fs::read_to_string(d.dir.join(format!("data/trace-job{job_id}.csv"))).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let cols = [
        col("cmd_x_mm"),
        col("spindle_cmd_rpm"),
        col("spindle_rpm"),
        col("coolant"),
        col("dout"),
    ];
    lines
        .map(|l| {
            let f: Vec<f64> = l
                .split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect();
            cols.map(|c| f[c])
        })
        .collect()
}

/// The machine around the axes between jobs (issue 35), on the simulated machine:
/// what an MDI command or a job leaves on stays on, as in LinuxCNC — the spindle
/// `S5000 M3` started turns at speed after its MDI ended and a second later,
/// `M8`'s coolant stays on, and the next job's feed starts at once on the spindle
/// already at speed (no run-up, no at-speed wait); that job's M30 stops the
/// spindle and the coolant; an abort stops them (LinuxCNC's task abort); an
/// E-stop stops them, and neither the reset nor `on` starts them again.
#[test]
#[allow(clippy::too_many_lines)]
fn the_spindle_and_coolant_stay_on_between_jobs_until_m5_m30_abort_or_estop() {
    let tag = "between";
    let d = Daemon::start_in(fresh_dir(tag), tag, "Lockstep", true, "default.ron", &[]);
    let op = d.operator();
    let minute = Duration::from_secs(60);
    let mdi = |text: &str| {
        let r = op.request(&mdi_request(text)).unwrap();
        assert!(r.is_accepted(), "{text}: {}", r.message());
        let s = d.wait_job(&op, id(&r), minute);
        assert_eq!(job_of(&s).outcome, Outcome::Completed, "{text}: {s}");
        d.wait_status(&op, minute, "idle", |s| s.state == MachineState::Idle)
    };
    // at `rpm` within the at-speed band (2 %) and reported at speed
    let turning_at = |s: &Status, rpm: f64| {
        let sp = s.spindle.unwrap();
        sp.commanded_rpm == rpm && sp.at_speed && (sp.actual_rpm - rpm).abs() <= 0.02 * rpm
    };

    // S5000 M3: the MDI ends with the spindle at speed, and it keeps turning
    let s = mdi("S5000 M3");
    assert!(turning_at(&s, 5000.0), "{:?}", s.spindle);
    std::thread::sleep(Duration::from_secs(1));
    let s = op.status().unwrap();
    assert!(turning_at(&s, 5000.0), "a second later: {:?}", s.spindle);
    assert!(!s.coolant.flood && !s.coolant.mist);
    // M8: flood on, and it stays on
    mdi("M8");
    std::thread::sleep(Duration::from_millis(500));
    let s = op.status().unwrap();
    assert!(s.coolant.flood && !s.coolant.mist, "{:?}", s.coolant);
    assert!(turning_at(&s, 5000.0), "{:?}", s.spindle);

    // a job's feed on the spindle already at speed: it starts at once, the
    // spindle and the coolant on from its first cycle; its M30 stops both
    let job = d.dir.join("feed.ngc");
    std::fs::write(&job, "G21 G90\nG1 X5 F1200\nM30\n").unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let job_id = id(&r);
    let s = d.wait_job(&op, job_id, minute);
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let notes = job_of(&s).notes.clone();
    assert!(
        !notes.iter().any(|n| n.contains("waiting for the spindle")),
        "{notes:?}"
    );
    let rows = machine_trace(&d, job_id);
    let [x, cmd_rpm, rpm, coolant] = [0, 1, 2, 3];
    let x0 = rows[0][x];
    let moving = (0..rows.len())
        .find(|&k| (rows[k][x] - x0).abs() > 1e-4)
        .unwrap();
    // (the acceptance job's run-up from rest to 8000 rpm takes over 300 cycles;
    // here only the command filter's lead-in comes before the move)
    assert!(moving < 100, "X moved at cycle {moving}");
    let at_x5 = (0..rows.len())
        .find(|&k| (rows[k][x] - 5.0).abs() < 1e-9)
        .unwrap();
    for r in &rows[..at_x5] {
        assert!(
            r[cmd_rpm] == 5000.0 && (r[rpm] - 5000.0).abs() <= 100.0 && r[coolant] as u32 & 2 != 0,
            "during the feed: {r:?}"
        );
    }
    let last = rows.last().unwrap();
    assert_eq!((last[cmd_rpm], last[coolant]), (0.0, 0.0), "M30: {last:?}");
    let s = d.wait_status(&op, minute, "idle", |s| s.state == MachineState::Idle);
    let sp = s.spindle.unwrap();
    assert_eq!(sp.commanded_rpm, 0.0, "{sp:?}");
    assert!(!s.coolant.flood && !s.coolant.mist);

    // an abort: the spindle and the coolant stop
    mdi("S4000 M3 M7");
    let job = d.dir.join("slow.ngc");
    std::fs::write(&job, "G21 G90\nG1 X0 F5\nM2\n").unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let job_id = id(&r);
    let s = d.wait_status(&op, minute, "the slow feed", |s| {
        s.state == MachineState::Running && s.job(job_id).is_some_and(|j| j.record.cycles > 200)
    });
    assert!(turning_at(&s, 4000.0) && s.coolant.mist, "{s}");
    assert!(op.request(&Request::Abort).unwrap().is_accepted());
    let s = d.wait_job(&op, job_id, minute);
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    let s = d.wait_status(&op, minute, "idle", |s| s.state == MachineState::Idle);
    assert_eq!(
        s.spindle.unwrap().commanded_rpm,
        0.0,
        "after the abort: {s}"
    );
    assert!(!s.coolant.mist && !s.coolant.flood, "after the abort: {s}");
    // M5 in an MDI command stops it
    let s = mdi("S2000 M3");
    assert!(turning_at(&s, 2000.0), "{:?}", s.spindle);
    let s = mdi("M5");
    assert_eq!(s.spindle.unwrap().commanded_rpm, 0.0, "M5: {s}");
    // and so does an abort while idle (LinuxCNC's), the coolant too
    let s = mdi("S2000 M3 M8");
    assert!(turning_at(&s, 2000.0) && s.coolant.flood, "{s}");
    let r = op.request(&Request::Abort).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_status(&op, minute, "stopped by the abort", |s| {
        s.spindle.unwrap().commanded_rpm == 0.0 && !s.coolant.flood
    });
    assert_eq!(s.state, MachineState::Idle, "{s}");

    // S3000 M3, then an E-stop: stopped; the reset and `on` leave it stopped
    let s = mdi("S3000 M3");
    assert!(turning_at(&s, 3000.0), "{:?}", s.spindle);
    assert!(op.request(&Request::EStop).unwrap().is_accepted());
    let s = d.wait_status(&op, minute, "E-stopped", |s| {
        s.state == MachineState::EStopped
    });
    assert_eq!(s.spindle.unwrap().commanded_rpm, 0.0, "E-stopped: {s}");
    assert!(op.request(&Request::Reset).unwrap().is_accepted());
    let s = d.wait_status(&op, minute, "off", |s| s.state == MachineState::Off);
    assert_eq!(s.spindle.unwrap().commanded_rpm, 0.0, "reset: {s}");
    op.machine_on(minute).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Idle);
    assert_eq!(s.spindle.unwrap().commanded_rpm, 0.0, "on: {s}");
    assert!(!s.coolant.mist && !s.coolant.flood, "on: {s}");
    // and the modal state says so (LinuxCNC's interpreter takes the spindle from
    // the machine): an S alone sets the speed, it does not start the spindle
    let modal = s.modal.clone().unwrap_or_default();
    assert!(
        modal.iter().any(|w| w == "S3000") && !modal.iter().any(|w| w == "M3"),
        "{modal:?}"
    );
    let s = mdi("S3500");
    assert_eq!(s.spindle.unwrap().commanded_rpm, 0.0, "S alone: {s}");
}

/// Issue 35's acceptance job (examples/machine/acceptance.ngc) on the simulated
/// machine, one daemon run: the spindle runs up on its model and the feed moves
/// start only at speed, coolant on then off, the tool change's prompt and its wait
/// for `resume` (the simulated tool changer made too slow to answer), the message,
/// the M0 pause, M62's output switching at the sample where the next motion starts,
/// M66 released by its input (set by the test during the M0 pause, before the M66:
/// a lockstep daemon runs its 2 s timeout faster than the test could answer) well
/// before its timeout.
#[test]
#[allow(clippy::too_many_lines)]
fn the_machine_around_the_axes_runs_the_acceptance_job() {
    let tag = "machine";
    let dir = fresh_dir(tag);
    std::fs::create_dir_all(&dir).unwrap();
    let profile = dir.join("slow-changer.ron");
    let text = std::fs::read_to_string(repo().join("config/machines/default.ron")).unwrap();
    assert!(text.contains("tool_change_s: 2.0"));
    std::fs::write(
        &profile,
        text.replace("tool_change_s: 2.0", "tool_change_s: 600.0"),
    )
    .unwrap();
    let d = Daemon::start_in(dir, tag, "Lockstep", true, profile.to_str().unwrap(), &[]);
    let op = d.operator();
    let job = d.dir.join("acceptance.ngc");
    std::fs::copy(repo().join("examples/machine/acceptance.ngc"), &job).unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let job_id = id(&r);
    let notes = |s: &Status| {
        s.job(job_id)
            .map(|j| j.record.notes.clone())
            .unwrap_or_default()
    };
    let noted = |s: &Status, what: &str| notes(s).iter().any(|n| n.contains(what));
    let minute = Duration::from_secs(60);

    // the tool change: paused with its prompt until the operator resumes
    let s = d.wait_status(&op, minute, "the tool change", |s| {
        s.state == MachineState::Paused && noted(s, "prompt: insert T2, then resume")
    });
    assert!(
        noted(&s, "prompt: waiting for the spindle at 8000 rpm"),
        "{:?}",
        notes(&s)
    );
    assert!(
        !noted(&s, "message:"),
        "the message comes after the M6: {:?}",
        notes(&s)
    );
    std::thread::sleep(Duration::from_millis(300));
    let s = op.status().unwrap();
    assert_eq!(
        s.state,
        MachineState::Paused,
        "still waiting for the operator"
    );
    // the status at the tool change: its prompt, T2 prepared, the spindle stopped
    // for the change (LinuxCNC's M6: STOP_SPINDLE_TURNING first) and running down
    // on its model, flood on
    assert_eq!(s.prompt.as_deref(), Some("insert T2, then resume"), "{s:?}");
    assert_eq!(s.tool_prepared, Some(2));
    assert_ne!(s.tool, 2, "not in the spindle before the change");
    let sp = s.spindle.unwrap();
    assert_eq!(sp.commanded_rpm, 0.0, "{sp:?}");
    assert!(sp.actual_rpm < 8000.0 - 160.0, "{sp:?}");
    assert!(s.coolant.flood && !s.coolant.mist);
    assert_eq!(s.message, None);
    assert!(op.request(&Request::Resume).unwrap().is_accepted());

    // the message, then the M0 pause
    let s = d.wait_status(&op, minute, "the M0", |s| {
        s.state == MachineState::Paused && noted(s, "message:")
    });
    assert!(
        noted(&s, "message: tool 2 in: check the coolant, then resume"),
        "{:?}",
        notes(&s)
    );
    // the status at the M0: the message, T2 in the spindle, no machine prompt
    assert_eq!(
        s.message.as_deref(),
        Some("tool 2 in: check the coolant, then resume")
    );
    assert_eq!((s.tool, s.prompt.as_deref()), (2, None), "{s:?}");
    // M66 P0 L3 Q2's input 0 (raw line 64) high
    d.sim_panel(softnc_ipc::SimPanel::DIGITAL, 64, 1.0);
    assert!(op.request(&Request::Resume).unwrap().is_accepted());
    let s = d.wait_job(&op, job_id, minute);
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert!(s.alarms.is_empty(), "{s}");
    // M66's result in #5399: noted when the wait ends, and the (DEBUG,…) after it
    // shows the machine's value (filled in when the path reached it)
    assert!(
        noted(&s, "M66 P0 (line 14): 1 (#5399)") && noted(&s, "message: M66 P0 gave 1"),
        "{:?}",
        notes(&s)
    );

    let rows = machine_trace(&d, job_id);
    let [x, cmd_rpm, rpm, coolant, dout] = [0, 1, 2, 3, 4];
    let first = |from: usize, f: &dyn Fn(&[f64; 5]) -> bool| {
        (from..rows.len()).find(|&k| f(&rows[k])).unwrap()
    };
    // the spindle runs up on its model (0.88 s to 12,000 rpm at full torque)
    let on = first(0, &|r| r[cmd_rpm] == 8000.0);
    let at_speed = first(on, &|r| (r[rpm] - 8000.0).abs() <= 160.0);
    assert!(at_speed - on > 300, "run-up {} cycles", at_speed - on);
    let mid = rows[(on + at_speed) / 2][rpm];
    assert!(mid > 1000.0 && mid < 7800.0, "half-way: {mid} rpm");
    // the feed move to X5 starts only at speed
    let x0 = rows[on][x];
    let moving = first(on, &|r| (r[x] - x0).abs() > 1e-4);
    assert!(
        moving > at_speed,
        "X moved at cycle {moving}, at speed at {at_speed}"
    );
    // coolant (flood, bit 1) on after the move, off at the end
    let flood = first(0, &|r| r[coolant] as u32 & 2 != 0);
    assert!(
        flood > moving && rows[flood][x] > 4.999,
        "M8 at X {}",
        rows[flood][x]
    );
    assert_eq!(rows.last().unwrap()[coolant], 0.0);
    assert_eq!(rows.last().unwrap()[cmd_rpm], 0.0);
    // the spindle stopped for the tool change and ran up again after the M0
    let stopped = first(flood, &|r| r[cmd_rpm] == 0.0);
    let again = first(stopped, &|r| r[cmd_rpm] == 8000.0);
    assert!(
        (stopped..again).all(|k| (rows[k][x] - 5.0).abs() < 1e-9),
        "stopped and started again at X5"
    );
    // M62 P1 switches with the first sample of the move to X10: the command stood
    // at X5 until then, and moves from the next cycles on
    let out = first(0, &|r| r[dout] as u64 & 2 != 0);
    assert!(out > again);
    // (the feed to X10 waited for the spindle back at speed)
    assert!(
        (rows[out][rpm] - 8000.0).abs() <= 160.0,
        "at {} rpm",
        rows[out][rpm]
    );
    assert!(
        (1..50).all(|k| (rows[out - k][x] - 5.0).abs() < 1e-9),
        "at rest at X5 before the output"
    );
    // (its first sample: under one cycle at F1200, 20 µm)
    assert!(
        rows[out][x] > 5.0 && rows[out][x] < 5.02,
        "the output's cycle is the move's first: X {}",
        rows[out][x]
    );
    assert!(rows[out + 200][x] > 5.0 + 1e-4, "moving after it");
    // M66 stood at X10 until the machine had it (the interpolator hears the
    // machine `lookahead` samples late), released by its input long before 2 s
    let at_10 = first(out, &|r| (r[x] - 10.0).abs() < 1e-9);
    let leaves = first(at_10, &|r| r[x] > 10.0 + 1e-9);
    let stood = leaves - at_10;
    assert!(stood > 50 && stood < 1000, "stood {stood} cycles at X10");
}
