//! The E-stop and the machine state after stops and crashes (issue 34, items 4, 5
//! and 7), end to end through softncd, its three processes and the client:
//! - the E-stop reaches the position process with the MMI stopped (SIGSTOP);
//! - a job stops along its path when the MMI is silent past `mmi_silence_stop_s`,
//!   and when the interpolator is stopped (the ring runs dry);
//! - a reset after an E-stop or a fault leaves the drives off: `on` is needed;
//! - after any sequence of crashes (kill -9 of each process), resets and `on`,
//!   `status` says what is so and a reset recovers;
//! - (issue 35) reset and `on` after an E-stop move no axis, and the E-stopped
//!   job's trace has every cycle up to the stop.
#[allow(unused_imports)] // the shared harness re-exports what other test files use
mod support;
use support::*;

/// A job of about 16 s: four laps of a 40 mm square at 2400 mm/min.
fn long_job(dir: &Path) -> PathBuf {
    let p = dir.join("long.ngc");
    let mut text = String::from("G21 G90 G17 G64 P0.01\nG0 X0 Y0 Z5\nG1 Z-1 F600\n");
    for _ in 0..4 {
        text.push_str("G1 X40 F2400\nG1 Y40\nG1 X0\nG1 Y0\n");
    }
    text.push_str("G0 Z5\nM2\n");
    std::fs::write(&p, text).unwrap();
    p
}

/// Start the long job and wait until it moves; its id and the status then.
fn start_long_job(d: &Daemon, op: &Operator) -> (u64, Status) {
    let job = long_job(&d.dir);
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_status(op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 800
    });
    (r.job_id().unwrap(), s)
}

#[test]
fn estop_from_the_client_stops_the_job_while_the_mmi_is_stopped() {
    // the MMI's silence alone must not be what stops the job here
    let dir = fresh_dir("estopmmi");
    let d = Daemon::start_in(
        dir,
        "estopmmi",
        "Realtime",
        false,
        "default.ron",
        &[("mmi_silence_stop_s: 1.0", "mmi_silence_stop_s: 30.0")],
    );
    let op = d.operator();
    let (job, before) = start_long_job(&d, &op);
    let path_before = job_of(&before).path_mm;
    let mmi = d.pid_of("softnc-mmi").unwrap();
    signal(mmi, "-STOP");
    let t0 = Instant::now();
    let r = op.request(&Request::EStop);
    let took = t0.elapsed();
    // the MMI stays stopped a while: the job would run on (16 s long) without the E-stop
    std::thread::sleep(Duration::from_millis(1500));
    signal(mmi, "-CONT");
    let r = r.expect("the E-stop is confirmed with the MMI stopped");
    assert!(r.is_accepted(), "{}", r.message());
    assert!(took < Duration::from_secs(3), "E-stop took {took:?}");
    let s = d.wait_status(&op, Duration::from_secs(10), "E-stopped", |s| {
        s.state == MachineState::EStopped
            && s.job(job).is_some()
            && s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
    });
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    assert!(
        alarm_text(&s).contains("past the MMI"),
        "the position process says where the E-stop came from: {s}"
    );
    // it stopped at once, not when the MMI came back 1.5 s later (40 mm/s)
    let path_after = job_of(&s).path_mm;
    assert!(
        path_after - path_before < 25.0,
        "the job went on {} mm after the E-stop was asked",
        path_after - path_before
    );
    // and it stays where it stopped
    let at = machine_mm(&s);
    std::thread::sleep(Duration::from_millis(500));
    let s = op.status().unwrap();
    assert_eq!(machine_mm(&s), at, "{s}");
    assert_eq!(s.state, MachineState::EStopped, "{s}");
    // the MMI, back, serves as before: reset (the drives stay off), on, a job runs
    assert!(op.request(&Request::Reset).unwrap().is_accepted());
    d.wait_status(&op, Duration::from_secs(10), "off after reset", |s| {
        s.state == MachineState::Off
    });
    op.machine_on(Duration::from_secs(10)).unwrap();
    d.runs_the_short_job(&op);
}

#[test]
fn a_job_stops_along_its_path_when_the_mmi_is_silent_past_the_bound() {
    let d = Daemon::start("mmisilent", "Realtime", true);
    let op = d.operator();
    let (job, _) = start_long_job(&d, &op);
    let mmi = d.pid_of("softnc-mmi").unwrap();
    signal(mmi, "-STOP");
    // past the bound (1 s), well within the supervisor's watchdog (10 s)
    std::thread::sleep(Duration::from_millis(2500));
    signal(mmi, "-CONT");
    let s = d.wait_status(&op, Duration::from_secs(10), "faulted", |s| {
        s.state == MachineState::Faulted && s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
    });
    assert_eq!(job_of(&s).job_id, job, "{s}");
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    assert!(
        alarm_text(&s).contains("MMI has been silent"),
        "{}",
        alarm_text(&s)
    );
    assert!(job_of(&s).path_mm < job_of(&s).planned_path_mm, "{s}");
    assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job}.csv")));
    assert_eq!(
        d.pid_of("softnc-mmi"),
        Some(mmi),
        "the MMI was not restarted"
    );
}

#[test]
fn a_stopped_interpolator_runs_the_ring_dry_and_the_job_stops_along_its_path() {
    let d = Daemon::start("interpstop", "Realtime", true);
    let op = d.operator();
    let (job, _) = start_long_job(&d, &op);
    let interp = d.pid_of("softnc-interp").unwrap();
    signal(interp, "-STOP");
    let s = d.wait_status(&op, Duration::from_secs(10), "faulted", |s| {
        s.state == MachineState::Faulted && s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
    });
    assert!(alarm_text(&s).contains("RingDry"), "{s}");
    assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
    assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job}.csv")));
    signal(interp, "-CONT");
    // reset: off, not on
    assert!(op.request(&Request::Reset).unwrap().is_accepted());
    d.wait_status(&op, Duration::from_secs(10), "off after reset", |s| {
        s.state == MachineState::Off
    });
}

/// Run MDI `block` to its end; its outcome.
fn mdi(d: &Daemon, op: &Operator, block: &str) -> Outcome {
    let r = op.request(&mdi_request(block)).unwrap();
    assert!(r.is_accepted(), "MDI {block}: {}", r.message());
    let s = d.wait_job(op, r.job_id().unwrap(), Duration::from_secs(30));
    job_of(&s).outcome
}

/// The state stays `want` for a while (a heartbeat timeout and more).
fn stays(d: &Daemon, op: &Operator, want: MachineState) -> Status {
    let s = d.wait_status(op, Duration::from_secs(15), want.name(), |s| {
        s.state == want
    });
    std::thread::sleep(Duration::from_millis(700));
    let s2 = op.status().unwrap();
    assert_eq!(s2.state, want, "{want} did not stay: {s2} (was {s})");
    s2
}

/// Drives that do not come on (an EtherCAT bus that is not there): `on` fails with
/// the backend's reason instead of reporting the machine on, and a job sent right
/// behind the `on` — accepted while the switch-on was pending — never starts, never
/// hangs: it ends aborted and nothing moves.
#[test]
fn drives_that_do_not_come_on_fail_on_and_a_job_sent_behind_it_never_hangs() {
    let bus = r#"backend: EtherCat((interface: "nosuchnic0", subdevices: [
        (identity: (vendor_id: 0x5f7, product_code: 0x402, revision: 0x10000),
         role: Drive(axis: 0, counts_per_mm: 10000.0, direction: 1, following_error_window_counts: 50000)),
    ]))"#;
    let d = Daemon::start_edited("nobus", "Realtime", &[("backend: Simulated", bus)]);
    let op = d.operator_off();
    let err = op
        .machine_on(Duration::from_secs(10))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("machine on: ") && err.contains("nosuchnic0"),
        "{err}"
    );
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::Off, "{s}");
    assert!(s.pending.is_none(), "{s}");
    let at = machine_mm(&s);
    // `on` and a job back to back: the job is refused (the position process
    // answered first) or taken and dropped
    let job = short_job(&d.dir);
    assert!(ask(&op, &Request::MachineOn).0);
    let r = op.request(&submit(&abs(&job))).unwrap();
    if r.is_accepted() {
        let s = d.wait_job(&op, id(&r), Duration::from_secs(10));
        assert_eq!(job_of(&s).outcome, Outcome::Aborted, "{s}");
        assert_eq!(job_of(&s).cycles, 0, "{s}");
    } else {
        assert!(r.message().contains("off"), "{}", r.message());
    }
    let s = d.wait_status(&op, Duration::from_secs(5), "off, no job", |s| {
        s.state == MachineState::Off && s.pending.is_none()
    });
    assert_eq!(machine_mm(&s), at, "nothing moved: {s}");
    // no job left running: the next one is refused for the machine being off,
    // not for a busy machine
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(!r.is_accepted());
    assert!(
        r.message().contains("the machine is off"),
        "{}",
        r.message()
    );
}

#[test]
fn reset_after_an_estop_or_a_fault_leaves_the_drives_off_until_on() {
    let d = Daemon::start("resetoff", "Realtime", false);
    let op = d.operator();
    assert_eq!(mdi(&d, &op, "G0 X5"), Outcome::Completed);
    // E-stop, reset: off
    let (ok, msg) = ask(&op, &Request::EStop);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::EStopped);
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok && msg.contains("Off"), "{msg}");
    stays(&d, &op, MachineState::Off);
    // nothing moves until `on`
    let r = op.request(&mdi_request("G0 X10")).unwrap();
    assert!(!r.is_accepted(), "MDI after reset: {}", r.message());
    assert!(r.message().contains("off"), "{}", r.message());
    let (ok, msg) = ask(&op, &jog_step(0, 1.0));
    assert!(!ok, "jog after reset: {msg}");
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::Idle);
    assert_eq!(mdi(&d, &op, "G0 X10"), Outcome::Completed);
    // off, E-stop, reset: still off (the E-stop does not remember "on")
    let (ok, msg) = ask(&op, &Request::MachineOff);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::Off);
    assert!(ask(&op, &Request::EStop).0);
    stays(&d, &op, MachineState::EStopped);
    assert!(ask(&op, &Request::Reset).0);
    stays(&d, &op, MachineState::Off);
    // a fault (the position process lost mid-job): the reset restarts it, off
    op.machine_on(Duration::from_secs(10)).unwrap();
    let _job = start_moving(&d, &op);
    d.kill9("softnc-position");
    stays(&d, &op, MachineState::Faulted);
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok, "{msg}");
    let s = stays(&d, &op, MachineState::Off);
    assert_eq!(s.processes.position, ProcessHealth::Alive, "{s}");
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::Idle);
    assert_eq!(mdi(&d, &op, "G0 X7"), Outcome::Completed);
    // the external E-stop chain (the simulated machine's input) opened mid-job: the
    // job stops as the E-stop stops it, named in the alarms; reset and `on` are
    // refused while it is open; closed, reset and on, the machine runs again
    let _job = start_moving(&d, &op);
    d.sim_panel(softnc_ipc::SimPanel::ESTOP, 0, 1.0);
    let s = stays(&d, &op, MachineState::EStopped);
    assert!(
        s.alarms
            .iter()
            .any(|a| a.message.contains("the E-stop input opened")),
        "{s}"
    );
    let _ = ask(&op, &Request::Reset);
    stays(&d, &op, MachineState::EStopped);
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(
        !ok && msg.contains("the E-stop input is open"),
        "on with the E-stop input open: {msg}"
    );
    d.sim_panel(softnc_ipc::SimPanel::ESTOP, 0, 0.0);
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::Off);
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(ok, "{msg}");
    stays(&d, &op, MachineState::Idle);
    assert_eq!(mdi(&d, &op, "G0 X9"), Outcome::Completed);
    // a limit switch hit mid-job (the X max switch's line held by the panel): the
    // machine stops as the E-stop stops it, the switch named; reset moves no axis;
    // `on` is refused while it is tripped; with the limits overridden the axis
    // jogs off only away from it; released, the override ends and a block runs
    let _job = start_moving(&d, &op);
    d.sim_panel(softnc_ipc::SimPanel::DIGITAL, X_MAX_LIMIT_LINE, 1.0);
    let s = stays(&d, &op, MachineState::EStopped);
    assert!(
        alarm_text(&s).contains("X maximum limit switch tripped"),
        "{}",
        alarm_text(&s)
    );
    let stopped = cmd_mm(&s);
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok, "{msg}");
    let s = stays(&d, &op, MachineState::Off);
    assert_eq!(cmd_mm(&s), stopped, "the reset moved an axis: {s}");
    assert_eq!(s.limits_tripped, vec!["X max".to_string()], "{s}");
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(!ok && msg.contains("limit switch tripped"), "{msg}");
    let (ok, msg) = ask(&op, &Request::OverrideLimits);
    assert!(ok, "{msg}");
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(ok, "{msg}");
    let s = stays(&d, &op, MachineState::Idle);
    assert!(s.limits_overridden, "{s}");
    let at = cmd_mm(&s);
    // toward the switch: refused, nothing moves
    let _ = ask(&op, &jog_step(0, 1.0));
    let s = stays(&d, &op, MachineState::Idle);
    assert_eq!(cmd_mm(&s), at, "jogged toward the tripped switch: {s}");
    assert!(alarm_text(&s).contains("toward its tripped"), "{s}");
    // away from it: the step runs
    let (ok, msg) = ask(&op, &jog_step(0, -1.0));
    assert!(ok, "{msg}");
    d.wait_status(&op, Duration::from_secs(10), "jogged off", |s| {
        s.state == MachineState::Idle && (cmd_mm(s)[0] - (at[0] - 1.0)).abs() < 1e-6
    });
    d.sim_panel(softnc_ipc::SimPanel::DIGITAL, X_MAX_LIMIT_LINE, 0.0);
    d.wait_status(&op, Duration::from_secs(5), "override over", |s| {
        !s.limits_overridden && s.limits_tripped.is_empty()
    });
    assert_eq!(mdi(&d, &op, "G0 X9"), Outcome::Completed);
}

/// The simulated cabinet's X max limit switch line (config/machines/default.ron).
const X_MAX_LIMIT_LINE: u32 = 20;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Step {
    Kill(&'static str),
    Reset,
    On,
    Mdi,
}

/// What the machine should be after the steps so far.
#[derive(Debug, Default)]
struct Model {
    faulted: bool,
    on: bool,
    /// Processes killed since the last reset (their "exited" alarms may show).
    killed_since_reset: Vec<&'static str>,
}

impl Model {
    fn state(&self) -> MachineState {
        match (self.faulted, self.on) {
            (true, _) => MachineState::Faulted,
            (false, true) => MachineState::Idle,
            (false, false) => MachineState::Off,
        }
    }
}

/// The status agrees with what runs (once the supervisor has settled): every
/// process that runs is alive, the position process reported lost exactly when it
/// is not running, the state the model's, and no alarm of a crash before the last
/// reset.
fn agrees(d: &Daemon, s: &Status, m: &Model) -> Result<(), String> {
    let position_runs = d.pid_of("softnc-position").is_some();
    let position_alive = s.processes.position == ProcessHealth::Alive;
    if position_runs != position_alive {
        return Err(format!(
            "position runs: {position_runs}, status: {}",
            s.processes.position
        ));
    }
    if position_runs == m.faulted {
        return Err(format!("position runs: {position_runs}, model {m:?}"));
    }
    if d.pid_of("softnc-interp").is_none() || s.processes.interp != ProcessHealth::Alive {
        return Err(format!("interp: {}", s.processes.interp));
    }
    if s.state != m.state() {
        return Err(format!("state {} (model: {})", s.state, m.state()));
    }
    let alarms = alarm_text(s);
    for name in ["softnc-position", "softnc-interp", "softnc-mmi"] {
        if alarms.contains(&format!("{name} exited")) && !m.killed_since_reset.contains(&name) {
            return Err(format!(
                "an alarm of {name} from before the reset: {alarms}"
            ));
        }
    }
    Ok(())
}

/// Wait until the status agrees with the model, then check that it still does a
/// heartbeat timeout later (nothing replayed or stale turns it over).
fn settle(d: &Daemon, op: &Operator, m: &Model, what: &str) {
    let t0 = Instant::now();
    loop {
        let verdict = op
            .status()
            .map_err(|e| e.to_string())
            .and_then(|s| agrees(d, &s, m).map_err(|e| format!("{e}\nstatus: {s}")));
        match verdict {
            Ok(()) => break,
            Err(e) if t0.elapsed() > Duration::from_secs(15) => {
                panic!("after {what}: the status does not say what is so: {e}")
            }
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    std::thread::sleep(Duration::from_millis(800));
    let s = op.status().unwrap();
    if let Err(e) = agrees(d, &s, m) {
        panic!("after {what}, settled, then: {e}\nstatus: {s}");
    }
}

/// The crash sequences: the issue's own (position, reset, MMI, interp, reset),
/// then every order of the three kills with a reset at a seeded place among them
/// and the machine on or off before; each ends reset, on, a short MDI move.
fn crash_sequences() -> Vec<Vec<Step>> {
    use Step::*;
    let mut seqs = vec![vec![
        Kill("softnc-position"),
        Reset,
        Kill("softnc-mmi"),
        Kill("softnc-interp"),
        Reset,
        On,
        Mdi,
    ]];
    let mut seed: u64 = 0x5eed_0034;
    let mut next = |n: u64| {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 33) % n
    };
    let names = ["softnc-position", "softnc-mmi", "softnc-interp"];
    for order in [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ] {
        let mut seq = Vec::new();
        if next(2) == 0 {
            seq.push(On);
        }
        let reset_at = next(4) as usize;
        for (k, &i) in order.iter().enumerate() {
            if k == reset_at {
                seq.push(Reset);
            }
            seq.push(Kill(names[i]));
        }
        seq.extend([Reset, On, Mdi]);
        seqs.push(seq);
    }
    seqs
}

/// A client of the (restarted) MMI, once it answers (whatever the other
/// processes do).
fn connect_mmi(d: &Daemon) -> Operator {
    let t0 = Instant::now();
    loop {
        if let Ok(op) = Operator::connect(&d.config) {
            if op.status().is_ok() {
                return op;
            }
        }
        assert!(
            t0.elapsed() < Duration::from_secs(15),
            "the MMI does not answer"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn after_any_crash_sequence_status_says_what_is_so_and_reset_recovers() {
    // restarts seconds apart are not a crash loop here
    let d = Daemon::start_edited(
        "crashes",
        "Realtime",
        &[("restart_window_s: 60.0", "restart_window_s: 1.0")],
    );
    let mut op = d.operator_off();
    let mut m = Model::default();
    settle(&d, &op, &m, "start");
    let t0 = Instant::now();
    for (n, seq) in crash_sequences().into_iter().enumerate() {
        for (k, step) in seq.iter().enumerate() {
            let what = format!("sequence {n} {seq:?}, step {k} ({step:?})");
            match *step {
                Step::Kill(name) => {
                    d.kill9(name);
                    if name == "softnc-position" {
                        m.faulted = true;
                    }
                    m.killed_since_reset.push(name);
                    if name == "softnc-mmi" {
                        // a new MMI: a new client connection
                        op = connect_mmi(&d);
                    }
                }
                Step::Reset => {
                    let (ok, msg) = ask(&op, &Request::Reset);
                    assert!(ok, "{what}: reset refused: {msg}");
                    if m.faulted {
                        assert!(msg.contains("Off"), "{what}: {msg}");
                        m.faulted = false;
                        m.on = false;
                    }
                    m.killed_since_reset.clear();
                }
                Step::On => {
                    let (ok, msg) = ask(&op, &Request::MachineOn);
                    let can = !m.faulted && !m.on;
                    assert_eq!(ok, can, "{what}: on: {msg}");
                    m.on |= can;
                }
                Step::Mdi => {
                    let s = op.status().unwrap();
                    let x = machine_mm(&s)[0];
                    let to = if x < 10.0 { x + 5.0 } else { x - 5.0 };
                    assert_eq!(
                        mdi(&d, &op, &format!("G90 G0 X{to:.3}")),
                        Outcome::Completed,
                        "{what}"
                    );
                    let s = op.status().unwrap();
                    assert!((machine_mm(&s)[0] - to).abs() < 1e-3, "{what}: {s}");
                }
            }
            settle(&d, &op, &m, &what);
        }
    }
    eprintln!("crash sequences: {:.1} s", t0.elapsed().as_secs_f64());
}

/// The axes' command and actual positions in a status (mm).
fn cmd_and_actual(s: &Status) -> (Vec<f64>, Vec<f64>) {
    let a = s.axes.as_ref().unwrap_or_else(|| panic!("no axes: {s}"));
    (a.cmd_mm.clone(), a.actual_mm.clone())
}

/// Issue 35: an E-stop mid-job, then reset and `on`, moves no axis — the command
/// does not change across the reset and the switch-on (it is taken from where the
/// axes stand), the actual position stays put — and the E-stopped job's trace has
/// every cycle up to the stop.
#[test]
fn reset_and_on_after_an_estop_move_no_axis_and_the_trace_has_every_cycle() {
    let d = Daemon::start("resetnomove", "Realtime", true);
    let op = d.operator();
    let (job, _) = start_long_job(&d, &op);
    assert!(ask(&op, &Request::EStop).0);
    let s = stays(&d, &op, MachineState::EStopped);
    let (cmd0, act0) = cmd_and_actual(&s);
    // the statuses from the E-stop, through the reset and the switch-on, to a
    // while after it: the command never changes, the axes never move
    let mut statuses = vec![s];
    let watch = |for_s: f64, statuses: &mut Vec<Status>| {
        let t0 = Instant::now();
        while t0.elapsed().as_secs_f64() < for_s {
            statuses.push(op.status().unwrap());
            std::thread::sleep(Duration::from_millis(5));
        }
    };
    watch(0.3, &mut statuses);
    let (ok, msg) = ask(&op, &Request::Reset);
    assert!(ok, "{msg}");
    watch(0.5, &mut statuses);
    let (ok, msg) = ask(&op, &Request::MachineOn);
    assert!(ok, "{msg}");
    watch(1.0, &mut statuses);
    let last = statuses.last().unwrap();
    assert_eq!(last.state, MachineState::Idle, "{last}");
    let mut max_dcmd = 0.0f64;
    let mut max_dact = 0.0f64;
    for s in &statuses {
        let (cmd, act) = cmd_and_actual(s);
        for i in 0..3 {
            max_dcmd = max_dcmd.max((cmd[i] - cmd0[i]).abs());
            max_dact = max_dact.max((act[i] - act0[i]).abs());
        }
    }
    eprintln!(
        "across the reset and on ({} statuses): max |Δ command| = {max_dcmd} mm, max |Δ actual| = {max_dact} mm; command {cmd0:?}, actual {act0:?}",
        statuses.len()
    );
    assert_eq!(max_dcmd, 0.0, "the command moved across the reset and on");
    // an encoder count or two of noise, no motion
    assert!(max_dact < 0.002, "the axes moved {max_dact} mm");
    // the E-stopped job's trace: every cycle from its first to the one the E-stop
    // stopped it at (the last the job's record counts), none missing
    let record = job_of(&statuses[0]);
    assert_eq!(record.job_id, job);
    let text = std::fs::read_to_string(d.dir.join(format!("data/trace-job{job}.csv"))).unwrap();
    let times: Vec<f64> = text
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').next()?.parse().ok())
        .collect();
    let cycle_s = 0.001;
    let index = |t: f64| (t / cycle_s).round() as u64;
    let last_index = index(*times.last().expect("trace rows"));
    assert_eq!(
        last_index + 1,
        record.cycles,
        "the trace ends at cycle {last_index}, the job was stopped after {} cycles",
        record.cycles
    );
    for w in times.windows(2) {
        assert_eq!(
            index(w[1]),
            index(w[0]) + 1,
            "a gap in the trace at {}",
            w[0]
        );
    }
}
