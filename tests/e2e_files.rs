//! End-to-end tests of the files a controller takes in and keeps (issue 34): job
//! and subroutine files that could wedge the check, a check that takes too long,
//! the parameter file cut short, the modal state file, subroutine files beside the
//! program, the job history on a read-only disk, the program copies.

// (the shared harness has helpers this file does not use)
#[allow(unused_imports)]
mod support;
use support::*;

/// Submit `path` on a thread of its own; the reply, or a failure after `within`.
fn submit_within(d: &Daemon, path: &str, within: Duration) -> (bool, String) {
    let (config, job) = (d.config.clone(), path.to_string());
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let op = Operator::connect(&config).unwrap();
        let r = op.request(&submit(&job)).unwrap();
        let _ = tx.send((r.is_accepted(), r.message().to_string()));
    });
    rx.recv_timeout(within)
        .unwrap_or_else(|_| panic!("no answer to the submit of {path} within {within:?}"))
}

/// A program of `body` in `dir` as `name`.
fn program(dir: &Path, name: &str, body: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

/// The short job runs to its end (the checker is not wedged).
fn a_later_job_runs(d: &Daemon, op: &Operator) {
    let (ok, msg) = submit_within(d, &abs(&short_job(&d.dir)), Duration::from_secs(30));
    assert!(ok, "a later job: {msg}");
    let id = op.jobs().unwrap()[0].job_id;
    let s = d.wait_job(op, id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
}

#[test]
fn a_fifo_subroutine_a_link_to_dev_zero_and_a_kernel_file_are_refused_and_later_jobs_run() {
    let d = Daemon::start("fifo", "Lockstep", false);
    let op = d.operator();
    let shop = d.dir.join("shop");
    let caller = program(&shop, "calls.ngc", "G21 G90\no<fifo> call\nM2\n");
    let made = Command::new("mkfifo")
        .arg(shop.join("fifo.ngc"))
        .status()
        .unwrap()
        .success();
    assert!(made, "mkfifo");
    // a FIFO called as a subroutine: refused at once, never opened for a writer
    let (ok, msg) = submit_within(&d, &abs(&caller), Duration::from_secs(20));
    assert!(
        !ok && msg.contains("fifo.ngc") && msg.contains("a FIFO"),
        "{msg}"
    );
    a_later_job_runs(&d, &op);
    // a subroutine that is a link to /dev/zero: refused unread (no memory eaten)
    let zero = program(&shop, "zero-caller.ngc", "G21 G90\no<zero> call\nM2\n");
    std::os::unix::fs::symlink("/dev/zero", shop.join("zero.ngc")).unwrap();
    let (ok, msg) = submit_within(&d, &abs(&zero), Duration::from_secs(20));
    assert!(!ok && msg.contains("character device"), "{msg}");
    // a kernel file as the job: it says it is a regular file of 0 bytes, and reading
    // /proc/kmsg blocks; refused unread
    let (ok, msg) = submit_within(&d, "/proc/kmsg", Duration::from_secs(20));
    assert!(!ok && msg.contains("kernel file"), "{msg}");
    let s = op.status().unwrap();
    assert!(s.checking.is_none(), "{s}");
    a_later_job_runs(&d, &op);
}

/// A program whose check takes seconds: a few MB of comments (they raise the
/// executed-block limit) and a loop of millions of blocks, then one move.
fn slow_to_check_job(dir: &Path, name: &str) -> PathBuf {
    let mut text = String::from("G21 G90\n");
    for _ in 0..200_000 {
        text.push_str("(a long comment line that only makes the file bigger ....)\n");
    }
    text.push_str("#1=0\no100 while [#1 LT 4000000]\n#1=[#1+1]\no100 endwhile\nG1 X10 F600\nM2\n");
    program(dir, name, &text)
}

#[test]
fn a_check_over_its_time_is_abandoned_the_job_refused_and_later_jobs_run() {
    let d = Daemon::start_edited(
        "checktimeout",
        "Lockstep",
        &[
            ("check_timeout_s: 60.0", "check_timeout_s: 0.3"),
            ("max_abandoned_checks: 2", "max_abandoned_checks: 1"),
        ],
    );
    let op = d.operator();
    let slow = slow_to_check_job(&d.dir, "slow.ngc");
    let t0 = Instant::now();
    let (ok, msg) = submit_within(&d, &abs(&slow), Duration::from_secs(20));
    assert!(!ok && msg.contains("check_timeout_s"), "{msg}");
    assert!(t0.elapsed() < Duration::from_secs(5), "{:?}", t0.elapsed());
    // its thread still runs: at most one such, so the next submit is refused, saying why
    let s = op.status().unwrap();
    assert!(s.checking.is_none(), "{s}");
    assert_eq!(s.abandoned_checks, 1, "{s}");
    let (ok, msg) = submit_within(&d, &abs(&short_job(&d.dir)), Duration::from_secs(10));
    assert!(!ok && msg.contains("abandoned checks still run"), "{msg}");
    // once it has ended jobs are taken again; nothing of the abandoned one started
    d.wait_status(
        &op,
        Duration::from_secs(120),
        "the abandoned check's end",
        |s| s.abandoned_checks == 0,
    );
    assert!(
        op.jobs().unwrap().is_empty(),
        "no record of the abandoned job"
    );
    let s = op.status().unwrap();
    assert_eq!(s.axes.as_ref().unwrap().cmd_mm, [0.0, 0.0, 0.0], "{s}");
    a_later_job_runs(&d, &op);
    // nothing of the abandoned job kept in the data directory
    use sha2::Digest;
    let slow_sha: String = sha2::Sha256::digest(std::fs::read(&slow).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    assert!(
        !d.dir.join(format!("data/programs/{slow_sha}.ngc")).exists(),
        "the abandoned job's copy was kept"
    );
}

#[test]
fn a_parameter_file_cut_short_is_refused_by_name_and_parameter_and_kept() {
    let dir = fresh_dir("varcut");
    let mut d = Daemon::start_in(dir.clone(), "varcut", "Lockstep", false, "default.ron", &[]);
    d.keep_dir = true;
    let op = d.operator();
    let r = op.request(&mdi_request("G10 L2 P3 X11 Y22 Z-33")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let offsets = op.offsets().unwrap();
    let g56 = &offsets.systems[2];
    assert_eq!(g56.coords, "G56");
    assert_eq!(g56.origin_mm, [11.0, 22.0, -33.0], "{g56:?}");
    drop(op);
    drop(d);
    // cut to 50 lines: G56's X is the last one left
    let var = dir.join("data/softnc.var");
    let text = std::fs::read_to_string(&var).unwrap();
    let cut: String = text.lines().take(50).map(|l| format!("{l}\n")).collect();
    assert!(cut.lines().last().unwrap().starts_with("5261"), "{cut}");
    std::fs::write(&var, &cut).unwrap();
    let d = Daemon::start_in(dir, "varcut", "Lockstep", false, "default.ron", &[]);
    let op = d.operator();
    let s = op.status().unwrap();
    let e = s.params_error.clone().unwrap_or_default();
    assert!(
        e.contains("softnc.var") && e.contains("required parameter missing: #5262"),
        "{s}"
    );
    // said as an alarm, by name
    let alarms = alarm_text(&s);
    assert!(alarms.contains("required parameter missing"), "{s}");
    // jobs, MDI and touch-off refused; nothing moves; the file is left as it is
    let r = op.request(&mdi_request("G56 G0 X0 Y0")).unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert!(r.message().contains("required parameter missing"));
    let (ok, msg) = submit_within(&d, &abs(&short_job(&d.dir)), Duration::from_secs(10));
    assert!(!ok && msg.contains("required parameter missing"), "{msg}");
    let r = op
        .request(&Request::TouchOff {
            axis: axis(0),
            value_mm: 0.0,
            coords: None,
        })
        .unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    assert_eq!(
        std::fs::read_to_string(&var).unwrap(),
        cut,
        "the file was replaced"
    );
    let s = op.status().unwrap();
    assert_eq!(s.axes.as_ref().unwrap().cmd_mm, [0.0, 0.0, 0.0], "{s}");
}

#[test]
fn the_modal_state_holds_only_modal_words_and_the_run_uses_the_checked_one() {
    let d = Daemon::start("modal", "Lockstep", false);
    let op = d.operator();
    let r = op.request(&mdi_request("G1 F600")).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let modal = d.dir.join("data/modal.ngc");
    d.wait_status(&op, Duration::from_secs(30), "the MDI's end", |s| {
        s.state == MachineState::Idle && s.job.as_ref().is_some_and(|j| j.record.outcome.ended())
    });
    let good = std::fs::read_to_string(&modal).unwrap();
    // a motion slipped into the file: the job runs as it was checked (4 mm along X)
    std::fs::write(&modal, format!("{good}G0 X50 Y50\n")).unwrap();
    let job = program(&d.dir, "four.ngc", "G91 G1 X4\nG90\nM2\n");
    let (ok, msg) = submit_within(&d, &abs(&job), Duration::from_secs(20));
    assert!(ok, "{msg}");
    let id = op.jobs().unwrap()[0].job_id;
    let s = d.wait_job(&op, id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let planned = job_of(&s).planned_path_mm;
    assert!((planned - 4.0).abs() < 1e-9, "{s}");
    assert_eq!(s.axes.as_ref().unwrap().cmd_mm, [4.0, 0.0, 0.0], "{s}");
    // an MMI restarted reads the file: refused by file, line and column, nothing moves
    let lines = good.lines().count() + 1;
    std::fs::write(&modal, format!("{good}G0 X50 Y50\n")).unwrap();
    d.kill9("softnc-mmi");
    std::thread::sleep(Duration::from_millis(500));
    let op = d.operator_off();
    d.wait_status(&op, Duration::from_secs(30), "the MMI back", |s| {
        s.state == MachineState::Idle
    });
    let (ok, msg) = submit_within(&d, &abs(&job), Duration::from_secs(20));
    let want = format!("{}:{lines}:4: X50 is an axis word", modal.display());
    assert!(!ok && msg.contains(&want), "{msg} (want {want})");
    let r = op.request(&mdi_request("G0 X1")).unwrap();
    assert!(!r.is_accepted(), "{}", r.message());
    let s = op.status().unwrap();
    assert!(
        s.modal_error.as_ref().is_some_and(|e| e.contains(&want)),
        "{s}"
    );
    assert_eq!(s.axes.as_ref().unwrap().cmd_mm, [4.0, 0.0, 0.0], "{s}");
    // fixed: taken again
    std::fs::write(&modal, &good).unwrap();
    let (ok, msg) = submit_within(&d, &abs(&job), Duration::from_secs(20));
    assert!(ok, "{msg}");
}

#[test]
fn a_subroutine_beside_the_program_runs_as_it_was_checked() {
    let d = Daemon::start("besides", "Lockstep", false);
    let op = d.operator();
    let shop = d.dir.join("shop");
    let sub = program(
        &shop,
        "side.ngc",
        "o<side> sub\nG1 X3 F600\no<side> endsub\n",
    );
    let main = program(&shop, "main.ngc", "G21 G90\no<side> call\nG1 Y2 F600\nM2\n");
    let (ok, msg) = submit_within(&d, &abs(&main), Duration::from_secs(20));
    assert!(ok, "{msg}");
    // changed after the check: what was checked runs
    std::fs::write(&sub, "o<side> sub\nG0 X90 Y90\no<side> endsub\n").unwrap();
    let id = op.jobs().unwrap()[0].job_id;
    let s = d.wait_job(&op, id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert_eq!(s.axes.as_ref().unwrap().cmd_mm, [3.0, 2.0, 0.0], "{s}");
    assert!(job_of(&s).alarms.is_empty(), "{s}");
    // the subroutine file's copy is kept beside the program's
    let copies = std::fs::read_dir(d.dir.join("data/programs"))
        .unwrap()
        .filter(|e| e.as_ref().unwrap().path().extension() == Some("ngc".as_ref()))
        .count();
    assert_eq!(copies, 2, "main's and side's copies");
}

#[test]
fn a_refused_program_keeps_no_copy_and_copies_are_not_world_readable() {
    use std::os::unix::fs::PermissionsExt;
    let d = Daemon::start("copies", "Lockstep", false);
    let op = d.operator();
    let secret = program(&d.dir, "secret.ngc", "G21 G90\nG1 X1 F600\nG5.5 X2\nM2\n");
    std::fs::set_permissions(&secret, std::fs::Permissions::from_mode(0o600)).unwrap();
    let (ok, msg) = submit_within(&d, &abs(&secret), Duration::from_secs(20));
    assert!(!ok, "{msg}");
    let programs = d.dir.join("data/programs");
    let kept: Vec<_> = std::fs::read_dir(&programs)
        .map(|r| r.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    assert!(kept.is_empty(), "a refused program left {kept:?}");
    let (ok, msg) = submit_within(&d, &abs(&short_job(&d.dir)), Duration::from_secs(20));
    assert!(ok, "{msg}");
    let id = op.jobs().unwrap()[0].job_id;
    d.wait_job(&op, id, Duration::from_secs(60));
    for e in std::fs::read_dir(&programs).unwrap() {
        let p = e.unwrap().path();
        let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode & 0o007, 0, "{} is {mode:o}", p.display());
    }
    let mode = std::fs::metadata(&programs).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode & 0o007, 0, "programs/ is {mode:o}");
}

/// A read-only bind mount of a folder on itself, made writable again and undone
/// when dropped.
struct ReadOnly(PathBuf);

impl ReadOnly {
    /// `None` (said loudly) where mounts are not permitted.
    fn mount(dir: &Path) -> Option<ReadOnly> {
        let run = |args: &[&str]| {
            Command::new("mount")
                .args(args)
                .status()
                .is_ok_and(|s| s.success())
        };
        let d = dir.display().to_string();
        if !run(&["--bind", &d, &d]) {
            eprintln!("SKIPPED: cannot bind-mount {d} (needs root and mount rights)");
            return None;
        }
        let ro = ReadOnly(dir.to_path_buf());
        if !run(&["-o", "remount,ro,bind", &d]) {
            eprintln!("SKIPPED: cannot remount {d} read-only");
            return None;
        }
        Some(ro)
    }

    fn writable(&self) {
        let d = self.0.display().to_string();
        let ok = Command::new("mount")
            .args(["-o", "remount,rw,bind", &d])
            .status()
            .is_ok_and(|s| s.success());
        assert!(ok, "remount {d} read-write");
    }
}

impl Drop for ReadOnly {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn job_history_on_a_read_only_disk_is_an_alarm_and_is_written_once_writable() {
    let d = Daemon::start("rodisk", "Realtime", false);
    let op = d.operator();
    let id = start_moving(&d, &op);
    let Some(ro) = ReadOnly::mount(&d.dir.join("data")) else {
        return;
    };
    let s = d.wait_job(&op, id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    let s = d.wait_status(&op, Duration::from_secs(10), "the history's alarm", |s| {
        s.unsaved.job_history.is_some()
    });
    let alarms = alarm_text(&s);
    assert!(
        alarms.contains("job history") && alarms.contains("not saved"),
        "{s}"
    );
    assert_ne!(
        d.job_record(id).map(|j| j.outcome),
        Some(Outcome::Completed),
        "written on a read-only disk?"
    );
    // writable again: written, the alarm's cause gone, jobs taken again
    ro.writable();
    let s = d.wait_status(&op, Duration::from_secs(10), "the history written", |s| {
        s.unsaved == softnc_api::Unsaved::default()
    });
    assert_eq!(
        d.job_record(id).map(|j| j.outcome),
        Some(Outcome::Completed),
        "{s}"
    );
    drop(ro);
    let (ok, msg) = submit_within(&d, &abs(&short_job(&d.dir)), Duration::from_secs(20));
    assert!(ok, "{msg}");
}

#[test]
fn a_jobs_log_files_are_written_in_the_log_folder_only_once_it_is_accepted() {
    let d = Daemon::start_edited(
        "gcodelogs",
        "Lockstep",
        &[(
            "check_timeout_s: 60.0",
            "check_timeout_s: 60.0, gcode_log_dir: Some(\"gcode-logs\")",
        )],
    );
    let op = d.operator();
    let logs = d.dir.join("gcode-logs");
    let shop = d.dir.join("shop");
    // a probing-style report: a loop's values into a log file, then a move
    let job = program(
        &shop,
        "report.ngc",
        "G21 G90\n(LOGOPEN,holes.txt)\n#1=0\no10 while [#1 LT 3]\n(LOG,hole #1 at X[#1*10])\n#1=[#1+1]\no10 endwhile\n(LOGCLOSE)\n(LOG,not logged)\nG1 X5 F600\nM2\n",
    );
    let (ok, msg) = submit_within(&d, &abs(&job), Duration::from_secs(20));
    assert!(ok, "{msg}");
    let id = op.jobs().unwrap()[0].job_id;
    let s = d.wait_job(&op, id, Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    assert_eq!(
        std::fs::read_to_string(logs.join("holes.txt")).unwrap(),
        "hole 0.000000 at X[0.000000*10]\nhole 1.000000 at X[1.000000*10]\nhole 2.000000 at X[2.000000*10]\n"
    );
    // a name that leaves the folder: refused at its line, nothing written anywhere
    let escape = program(
        &shop,
        "escape.ngc",
        "G21\n(LOGOPEN,../escaped.txt)\n(LOG,x)\nM2\n",
    );
    let (ok, msg) = submit_within(&d, &abs(&escape), Duration::from_secs(20));
    assert!(
        !ok && msg.contains("escape.ngc:2:") && msg.contains("plain file name"),
        "{msg}"
    );
    assert!(!d.dir.join("escaped.txt").exists());
    // a program refused further on writes no log file
    let late = program(
        &shop,
        "late.ngc",
        "G21\n(LOGOPEN,late.txt)\n(LOG,first)\nG1 X[1/0] F100\nM2\n",
    );
    let (ok, msg) = submit_within(&d, &abs(&late), Duration::from_secs(20));
    assert!(!ok && msg.contains("late.ngc:4:"), "{msg}");
    assert!(
        !logs.join("late.txt").exists(),
        "a refused job wrote its log"
    );
    a_later_job_runs(&d, &op);
}
