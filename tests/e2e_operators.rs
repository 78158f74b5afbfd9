//! Issue 35 ("Operators and the service"): the operator group. A controller with an
//! operator group serves it a gateway socket; a local user in the group operates the
//! machine with the `softnc` command, without root; a local user outside it can
//! neither read the status nor command the machine. Two users and a group made by
//! the test (skipped with a message where it cannot make them: not root, no
//! `useradd`).
//!
//! A test of the `softnc-cli` package (where `softnc` is built with it), on the
//! shared harness; its `softncd` is the one built beside `softnc`.
#[allow(unused_imports)] // the shared harness re-exports what other test files use
mod support;
use support::*;

/// Local users and a group made for the test, removed when dropped.
struct Accounts {
    group: String,
    operator: String,
    outsider: String,
}

impl Accounts {
    /// Make the group, a user in it (a supplementary member, as `usermod -aG`
    /// makes one) and a user outside it; `None` (and why) where that cannot be done.
    fn make() -> Result<Accounts, String> {
        if unsafe_free_euid() != 0 {
            return Err("not root: cannot create local users".into());
        }
        let tag = std::process::id() % 100_000;
        let a = Accounts {
            group: format!("sncops{tag}"),
            operator: format!("sncop{tag}"),
            outsider: format!("sncout{tag}"),
        };
        let run = |cmd: &str, args: &[&str]| -> Result<(), String> {
            let out = Command::new(cmd)
                .args(args)
                .output()
                .map_err(|e| format!("{cmd}: {e}"))?;
            if out.status.success() {
                Ok(())
            } else {
                Err(format!(
                    "{cmd} {args:?}: {}",
                    String::from_utf8_lossy(&out.stderr).trim()
                ))
            }
        };
        run("groupadd", &[&a.group])?;
        run("useradd", &["-M", "-N", "-G", &a.group, &a.operator])?;
        run("useradd", &["-M", "-N", &a.outsider])?;
        Ok(a)
    }
}

impl Drop for Accounts {
    fn drop(&mut self) {
        for u in [&self.operator, &self.outsider] {
            let _ = Command::new("userdel").arg(u).output();
        }
        let _ = Command::new("groupdel").arg(&self.group).output();
    }
}

/// `softnc ARGS` run as local user `user` with its groups (`runuser`).
fn softnc_as(user: &str, config: &Path, args: &[&str]) -> (bool, String) {
    let out = Command::new("runuser")
        .args(["-u", user, "--"])
        .arg(env!("CARGO_BIN_EXE_softnc"))
        .arg("--config")
        .arg(config)
        .args(args)
        .env_remove("SOFTNC_RUN_DIR")
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

#[test]
fn a_member_of_the_operator_group_operates_without_root_and_no_one_else_can() {
    let accounts = match Accounts::make() {
        Ok(a) => a,
        Err(why) => {
            eprintln!("SKIPPED: the operator-group test needs two local users: {why}");
            return;
        }
    };
    let d = Daemon::start_edited(
        "operators",
        "Lockstep",
        &[(
            "mmi_silence_stop_s: 1.0,",
            &format!(
                "mmi_silence_stop_s: 1.0,\n    operators: Some((group: \"{}\", socket: \"operator.sock\")),",
                accounts.group
            ),
        )],
    );
    let root_op = d.operator_off();
    let socket = d.dir.join("operator.sock");
    {
        use std::os::unix::fs::{FileTypeExt, MetadataExt};
        let meta = std::fs::symlink_metadata(&socket).expect("softncd made the gateway socket");
        assert!(meta.file_type().is_socket());
        assert_eq!(
            meta.mode() & 0o777,
            0o660,
            "the socket is the owner's and the group's"
        );
    }

    // the group's member: status, on, E-stop, reset — through the gateway
    let (ok, out) = softnc_as(&accounts.operator, &d.config, &["status", "--json"]);
    assert!(ok, "an operator reads the status: {out}");
    let status: Status = serde_json::from_str(&out).expect("a Status as JSON");
    assert_eq!(status.state, MachineState::Off);
    let (ok, out) = softnc_as(&accounts.operator, &d.config, &["on"]);
    assert!(ok, "an operator switches the machine on: {out}");
    d.wait_status(&root_op, Duration::from_secs(10), "on", |s| {
        s.state == MachineState::Idle
    });
    let (ok, out) = softnc_as(&accounts.operator, &d.config, &["estop"]);
    assert!(ok, "an operator's E-stop: {out}");
    d.wait_status(&root_op, Duration::from_secs(10), "E-stopped", |s| {
        s.state == MachineState::EStopped
    });
    let (ok, out) = softnc_as(&accounts.operator, &d.config, &["reset"]);
    assert!(ok, "an operator's reset: {out}");

    // the outsider: no status, no command, and the machine does not move
    let (ok, out) = softnc_as(&accounts.outsider, &d.config, &["status", "--json"]);
    assert!(!ok, "a user outside the group reads no status: {out}");
    assert!(
        out.contains("operator group") || out.contains("ermission denied"),
        "the refusal says why: {out}"
    );
    let before = root_op.status().unwrap().state;
    let (ok, out) = softnc_as(&accounts.outsider, &d.config, &["estop"]);
    assert!(!ok, "a user outside the group cannot E-stop: {out}");
    let (ok, out) = softnc_as(&accounts.outsider, &d.config, &["on"]);
    assert!(!ok, "a user outside the group cannot switch on: {out}");
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(root_op.status().unwrap().state, before);
    drop(root_op);
    drop(d);
    assert!(!socket.exists(), "softncd removes its socket when it stops");
}

/// This process's effective user id (from /proc: the test needs no libc call).
fn unsafe_free_euid() -> u32 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2))
                .and_then(|u| u.parse().ok())
        })
        .unwrap_or(u32::MAX)
}
