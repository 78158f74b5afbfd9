//! End-to-end tests of the controller's shared memory against a second,
//! unprivileged local user (`nobody`). A test binary of its own: its controllers and
//! clients use an iceoryx2 prefix of their own (one attack plants a file under it),
//! and a process has one iceoryx2 configuration.
// (the harness re-exports helpers other test files use)
#[allow(unused_imports)]
mod support;
use support::*;

/// The uid and gid of the unprivileged local user the attacks run as.
const NOBODY: u32 = 65534;

/// The iceoryx2 resource prefix of this test run's controllers (the attack tests
/// plant files under it, so no other test's, or other user's, controller shares it).
fn ipc_prefix() -> String {
    format!("sncH{}_", std::process::id())
}

/// An iceoryx2 configuration with this run's own prefix (in cargo's scratch folder
/// for tests: shared by this run's tests, as the process's iceoryx2 configuration
/// is); the edit of the daemon configuration that uses it.
fn own_ipc_config() -> (String, String) {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(repo().join("config/iceoryx2.toml"))
        .unwrap()
        .replace(
            "prefix = \"softnc_\"",
            &format!("prefix = \"{}\"", ipc_prefix()),
        );
    let path = dir.join(format!("iceoryx2-host-{}.toml", std::process::id()));
    std::fs::write(&path, text).unwrap();
    (
        "iceoryx2_config: \"iceoryx2.toml\"".into(),
        format!("iceoryx2_config: \"{}\"", path.display()),
    )
}

/// Held by the tests that share [`ipc_prefix`] (one plants a file under it).
static IPC_TESTS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// The files in /dev/shm with this run's prefix.
fn shm_files() -> Vec<PathBuf> {
    std::fs::read_dir("/dev/shm")
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with(&ipc_prefix()))
        .map(|e| e.path())
        .collect()
}

/// As the unprivileged user: write 16 bytes into each of `files` (without
/// truncating) and create a file in each of `dirs`; the ones that succeeded.
fn writes_as_nobody(files: &[PathBuf], dirs: &[PathBuf]) -> Vec<String> {
    let mut script = String::new();
    for f in files {
        script += &format!(
            "printf 'AAAAAAAAAAAAAAAA' 1<> '{0}' 2>/dev/null && echo 'wrote {0}'\n",
            f.display()
        );
    }
    for d in dirs {
        script += &format!(
            "echo x > '{0}/planted' 2>/dev/null && echo 'created in {0}'\n",
            d.display()
        );
    }
    let out = Command::new("sh")
        .args(["-c", &script])
        .uid(NOBODY)
        .gid(NOBODY)
        .output()
        .unwrap();
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(String::from)
        .collect()
}

/// Status and E-stop answer through new client connections.
fn answers_status_and_estop(d: &Daemon) {
    let op = Operator::connect(&d.config).expect("a client connects");
    op.status().expect("status answers");
    let r = op.request(&Request::EStop).expect("E-stop answers");
    assert!(r.is_accepted(), "{}", r.message());
    let r = op.request(&Request::Reset).expect("reset answers");
    assert!(r.is_accepted(), "{}", r.message());
}

#[test]
fn another_local_user_can_write_no_file_of_the_controller_and_cannot_block_its_clients() {
    let _ipc = IPC_TESTS.lock().unwrap_or_else(|e| e.into_inner());
    let edit = own_ipc_config();
    let mut d = Daemon::start_edited("ipcperm", "Lockstep", &[(&edit.0, &edit.1)]);
    drop(d.operator_off());
    let files = shm_files();
    assert!(
        files
            .iter()
            .any(|f| f.to_string_lossy().ends_with(".global_mgmt")),
        "the node-id file of this prefix: {files:?}"
    );
    // every file of ours in /dev/shm and in iceoryx2's folder, every folder of ours
    let root = PathBuf::from("/tmp/iceoryx2");
    let mut targets = files.clone();
    let mut dirs = vec![root.clone()];
    let mut stack = vec![root.clone()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().filter_map(|e| e.ok()) {
            let p = e.path();
            if e.file_type().unwrap().is_dir() {
                dirs.push(p.clone());
                stack.push(p);
            } else if e.file_name().to_string_lossy().starts_with(&ipc_prefix()) {
                targets.push(p);
            }
        }
    }
    for f in &targets {
        use std::os::unix::fs::MetadataExt;
        let mode = std::fs::symlink_metadata(f).unwrap().mode();
        assert_eq!(
            mode & 0o002,
            0,
            "{} is world-writable ({:o})",
            f.display(),
            mode
        );
    }
    let wrote = writes_as_nobody(&targets, &dirs);
    assert!(
        wrote.is_empty(),
        "an unprivileged user could write: {wrote:?}"
    );
    answers_status_and_estop(&d);
    d.shutdown_leaving_nothing("ipcperm");
    drop(d);
    for f in shm_files() {
        let _ = std::fs::remove_file(f);
    }
}

#[test]
fn a_node_id_file_planted_by_another_user_before_the_start_does_not_block_the_controller() {
    let _ipc = IPC_TESTS.lock().unwrap_or_else(|e| e.into_inner());
    let edit = own_ipc_config();
    // a first run names the node-id file; then it is gone (a reboot) ...
    let mut d = Daemon::start_edited("ipcplant", "Lockstep", &[(&edit.0, &edit.1)]);
    drop(d.operator_off());
    d.shutdown_leaving_nothing("ipcplant");
    drop(d);
    let mgmt = shm_files()
        .into_iter()
        .find(|f| f.to_string_lossy().ends_with(".global_mgmt"))
        .expect("the node-id file");
    for f in shm_files() {
        std::fs::remove_file(f).unwrap();
    }
    // ... and an unprivileged user plants garbage under its name, open to all
    let out = Command::new("sh")
        .args([
            "-c",
            "umask 0; printf 'AAAAAAAAAAAAAAAA' > \"$1\" && chmod 666 \"$1\"",
            "sh",
        ])
        .arg(&mgmt)
        .uid(NOBODY)
        .gid(NOBODY)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut d = Daemon::start_edited("ipcplant2", "Lockstep", &[(&edit.0, &edit.1)]);
    let t0 = Instant::now();
    while Operator::wait_ready(&d.config, Duration::from_secs(2)).is_err() {
        assert!(
            d.child.try_wait().unwrap().is_none(),
            "softncd did not start beside a planted node-id file"
        );
        assert!(t0.elapsed() < Duration::from_secs(20), "no MMI");
    }
    answers_status_and_estop(&d);
    {
        use std::os::unix::fs::MetadataExt;
        let meta = std::fs::symlink_metadata(&mgmt).unwrap();
        assert_eq!(meta.uid(), 0, "the node-id file is the controller's own");
        assert_eq!(meta.mode() & 0o077, 0, "mode {:o}", meta.mode());
    }
    d.shutdown_leaving_nothing("ipcplant2");
    drop(d);
    for f in shm_files() {
        let _ = std::fs::remove_file(f);
    }
}
