//! End-to-end tests of the controller as a host service: signals as systemd and
//! `timeout` send them, the instance lock and run folder, the permissions of the
//! shared-memory files against a second, unprivileged local user.
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

/// Wait for softncd to exit after a signal; its exit status.
fn wait_exit(d: &mut Daemon, what: &str) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(st) = d.child.try_wait().unwrap() {
            return st;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(15),
            "softncd still running 15 s after {what}"
        );
        std::thread::sleep(Duration::from_millis(20));
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
        let st = wait_exit(&mut d, &format!("SIGTERM+SIGCONT (round {round})"));
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
        let st = wait_exit(&mut d, &format!("SIGTERM+SIGCONT mid-job (round {round})"));
        assert_eq!(st.code(), Some(0), "softncd exits 0 (round {round})");
        Daemon::wait_gone(&kids, Duration::from_secs(5));
        assert_stops_along_the_path(&d.dir.join(format!("data/trace-job{job_id}.csv")));
        let rec = d.job_record(job_id);
        assert_eq!(rec["outcome"], "aborted", "the job's record: {rec}");
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
                let reset = Operator::connect(&d.config)
                    .and_then(|op| op.request(ControlKind::Reset, 0.0, ""));
                if reset.is_ok_and(|r| r.accepted == 1) {
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
                s["processes"]["interp"] == "alive" && s["processes"]["position"] == "alive"
            });
        }
    }
    let kids = d.children();
    send_signals(d.child.id(), &["TERM", "CONT"]);
    let st = wait_exit(&mut d, "SIGTERM+SIGCONT");
    assert_eq!(st.code(), Some(0), "softncd exits 0");
    Daemon::wait_gone(&kids, Duration::from_secs(5));
}
