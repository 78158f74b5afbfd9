//! End-to-end tests of the controller as a host service: signals as systemd and
//! `timeout` send them, the instance lock and run folder, the permissions of the
//! shared-memory files against a second, unprivileged local user.
// (the harness re-exports helpers other test files use)
#[allow(unused_imports)]
mod support;
use support::*;

/// Send `signals` (names, in order, back to back) to process `pid`.
fn send_signals(pid: u32, signals: &[&str]) {
    // one `kill` per signal, as fast as they come: what systemd does (SIGTERM then
    // SIGCONT at once) and `timeout` does
    for s in signals {
        let ok = Command::new("kill")
            .args([&format!("-{s}"), &pid.to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -{s} {pid}");
    }
}

#[test]
fn sigterm_followed_at_once_by_sigcont_stops_an_idle_controller_every_time() {
    for round in 0..4 {
        let tag = format!("termcont{round}");
        let mut d = Daemon::start(&tag, "Lockstep", false);
        let instance = format!("e2e{tag}{}", std::process::id());
        let op = d.operator_off();
        drop(op);
        let kids = d.children();
        assert_eq!(kids.len(), 3, "three processes: {kids:?}");
        send_signals(d.child.id(), &["TERM", "CONT"]);
        let st = d.wait_exit(&format!("SIGTERM+SIGCONT (round {round})"));
        assert_eq!(st.code(), Some(0), "softncd exits 0 (round {round})");
        Daemon::wait_gone(&kids, Duration::from_secs(5));
        assert_eq!(
            services_of(&instance),
            Vec::<String>::new(),
            "iceoryx2 services left"
        );
    }
}

#[test]
fn sigterm_followed_at_once_by_sigcont_stops_a_running_job_along_its_path() {
    for round in 0..3 {
        let tag = format!("termcontjob{round}");
        let mut d = Daemon::start(&tag, "Realtime", true);
        let instance = format!("e2e{tag}{}", std::process::id());
        let op = d.operator();
        let job_id = start_moving(&d, &op);
        drop(op);
        let kids = d.children();
        assert_eq!(kids.len(), 3, "three processes: {kids:?}");
        send_signals(d.child.id(), &["TERM", "CONT"]);
        let st = d.wait_exit(&format!("SIGTERM+SIGCONT mid-job (round {round})"));
        assert_eq!(st.code(), Some(0), "softncd exits 0 (round {round})");
        Daemon::wait_gone(&kids, Duration::from_secs(5));
        assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job_id}.csv")));
        let rec = d.job_record(job_id).expect("the job's record");
        assert_eq!(rec.outcome, Outcome::Aborted, "the job's record: {rec}");
        assert_eq!(
            services_of(&instance),
            Vec::<String>::new(),
            "iceoryx2 services left"
        );
    }
}

#[test]
fn each_child_stops_on_sigterm_followed_at_once_by_sigcont() {
    // the children catch the same way: a SIGTERM+SIGCONT to one child alone stops it
    // (it exits 0; softncd restarts it as it does any exit of the interpolator)
    let mut d = Daemon::start("childtermcont", "Lockstep", false);
    drop(d.operator_off());
    // the position process last: after its restart the others' state is issue 34
    // item 7's (not this test's)
    for name in ["softnc-interp", "softnc-mmi", "softnc-position"] {
        let pid = d.pid_of(name).unwrap();
        send_signals(pid, &["TERM", "CONT"]);
        // stopped (not merely still heartbeating): gone within the stopping bounds
        Daemon::wait_gone(&[pid], Duration::from_secs(10));
        if name == "softnc-position" {
            // a lost position process is a fault; reset brings it back
            let t0 = Instant::now();
            loop {
                let reset = Operator::connect(&d.config).and_then(|op| op.request(&Request::Reset));
                if reset.is_ok_and(|r| r.is_accepted()) {
                    break;
                }
                assert!(t0.elapsed() < Duration::from_secs(20), "reset refused");
                std::thread::sleep(Duration::from_millis(200));
            }
        }
        let t0 = Instant::now();
        while d.pid_of(name).is_none_or(|p| p == pid) {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "{name} not restarted"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        if name != "softnc-position" {
            let op = d.operator_off();
            d.wait_status(&op, Duration::from_secs(20), "every process alive", |s| {
                s.processes.interp == ProcessHealth::Alive
                    && s.processes.position == ProcessHealth::Alive
            });
        }
    }
    let kids = d.children();
    send_signals(d.child.id(), &["TERM", "CONT"]);
    let st = d.wait_exit("SIGTERM+SIGCONT");
    assert_eq!(st.code(), Some(0), "softncd exits 0");
    Daemon::wait_gone(&kids, Duration::from_secs(5));
}

/// The uid and gid of the unprivileged local user the attacks run as (`nobody`).
const NOBODY: u32 = 65534;

/// The instance lock file of the test daemon `tag` in folder `dir`.
fn lock_path(dir: &Path, tag: &str) -> PathBuf {
    dir.join(format!("softnc-softnc-e2e{tag}{}.lock", std::process::id()))
}

/// softncd on `config` with run folder `run_dir`: (exit status, stderr) once it
/// exits, or None if it still runs after `within` (then it is shut down).
fn softncd_outcome(config: &Path, run_dir: &Path, within: Duration) -> Option<(i32, String)> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_softncd"))
        .arg("--config")
        .arg(config)
        .env("SOFTNC_RUN_DIR", run_dir)
        .env("RUST_LOG", "warn")
        .process_group(0)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < within {
        if let Some(st) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return Some((st.code().unwrap_or(-1), err));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if let Ok(op) = Operator::connect(config) {
        let _ = op.request(&Request::Shutdown);
    }
    let t0 = Instant::now();
    while child.try_wait().unwrap().is_none() && t0.elapsed() < Duration::from_secs(10) {
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

#[test]
fn a_symlink_planted_at_the_lock_path_is_not_followed() {
    use std::os::unix::fs::PermissionsExt;
    let dir = fresh_dir("symlock");
    std::fs::create_dir_all(&dir).unwrap();
    // a file only root may read or write, and a link to it where the lock goes
    let victim = dir.join("root-only");
    std::fs::write(&victim, "precious\n").unwrap();
    std::fs::set_permissions(&victim, std::fs::Permissions::from_mode(0o600)).unwrap();
    std::os::unix::fs::symlink(&victim, lock_path(&dir, "symlock")).unwrap();
    let mut d = Daemon::start_in(
        dir.clone(),
        "symlock",
        "Lockstep",
        false,
        "default.ron",
        &[],
    );
    let t0 = Instant::now();
    let status = loop {
        if let Some(st) = d.child.try_wait().unwrap() {
            break Some(st);
        }
        if t0.elapsed() > Duration::from_secs(5) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(
        std::fs::read_to_string(&victim).unwrap(),
        "precious\n",
        "the link's target was written through the lock path"
    );
    assert!(
        status.is_some_and(|s| s.code() == Some(1)),
        "softncd must refuse a lock path that is a link: {status:?}"
    );
}

#[test]
fn a_run_folder_others_may_write_is_refused_with_a_clear_message() {
    use std::os::unix::fs::PermissionsExt;
    let mut d = Daemon::start("opendir", "Lockstep", false);
    drop(d.operator_off());
    let open_dir = d.dir.join("open-run");
    std::fs::create_dir_all(&open_dir).unwrap();
    for mode in [0o777, 0o1777, 0o775] {
        std::fs::set_permissions(&open_dir, std::fs::Permissions::from_mode(mode)).unwrap();
        // a second controller of another folder: the instance is held, but the
        // folder must be refused before anything is opened in it
        let out = softncd_outcome(&d.config, &open_dir, Duration::from_secs(5));
        let (code, err) =
            out.unwrap_or_else(|| panic!("softncd ran on a run folder of mode {mode:o}"));
        assert_eq!(code, 1, "{err}");
        assert!(
            err.contains(&open_dir.display().to_string()) && err.contains("writable"),
            "mode {mode:o}: the message names the folder and why: {err}"
        );
        assert!(
            std::fs::read_dir(&open_dir).unwrap().next().is_none(),
            "nothing created in the refused folder"
        );
    }
    d.shutdown_leaving_nothing("opendir");
}

#[test]
fn another_user_cannot_open_the_instance_lock() {
    let mut d = Daemon::start("userlock", "Lockstep", false);
    drop(d.operator_off());
    let lock = lock_path(&d.dir, "userlock");
    assert!(lock.is_file(), "{}", lock.display());
    // nobody may hold (and so block) the lock: it cannot even open the file
    let out = Command::new("sh")
        .args(["-c", "exec 3<\"$1\" && echo opened", "sh"])
        .arg(&lock)
        .uid(NOBODY)
        .gid(NOBODY)
        .output()
        .unwrap();
    assert!(
        !String::from_utf8_lossy(&out.stdout).contains("opened"),
        "an unprivileged user opened the lock file {}",
        lock.display()
    );
    d.shutdown_leaving_nothing("userlock");
}
