//! `softnc demo`, the README's first command, as a newcomer runs it: from any folder,
//! leaving nothing behind in the temporary folder, whether the job runs or not.

use std::path::PathBuf;
use std::process::{Command, Output};

/// Run `softnc demo ARGS` in `cwd`; the output and the demo's own temporary folder.
fn demo_in(cwd: &PathBuf, args: &[&str]) -> (Output, PathBuf) {
    let child = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("demo")
        .args(args)
        .current_dir(cwd)
        .env_remove("SOFTNC_CONFIG")
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("softnc runs");
    let dir = std::env::temp_dir().join(format!("softnc-demo-{}", child.id()));
    (child.wait_with_output().unwrap(), dir)
}

/// An empty folder that is not the checkout.
fn elsewhere(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softnc-demo-test-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn the_demo_runs_from_any_folder_and_leaves_nothing_behind() {
    let _one = crate::one_controller_at_a_time();
    let cwd = elsewhere("run");
    let (out, dir) = demo_in(&cwd, &["--backend", "loopback", "--json"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "softnc demo failed: {stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["outcome"], "completed", "{report}");
    assert!(
        report["job"]["cycles"].as_u64().unwrap_or(0) > 20_000,
        "the demo job ran: {report}"
    );
    assert!(!dir.exists(), "{} left behind", dir.display());
    assert_eq!(std::fs::read_dir(&cwd).unwrap().count(), 0, "files in cwd");
    let _ = std::fs::remove_dir_all(&cwd);
}

#[test]
fn a_demo_that_fails_says_why_and_leaves_nothing_behind() {
    let _one = crate::one_controller_at_a_time();
    let cwd = elsewhere("fail");
    let (out, dir) = demo_in(&cwd, &["--job", "no-such-job.ngc"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a missing job is an error");
    assert!(stderr.contains("no-such-job.ngc"), "{stderr}");
    assert!(!dir.exists(), "{} left behind", dir.display());
    let _ = std::fs::remove_dir_all(&cwd);
}

#[test]
fn a_refused_demo_job_stops_the_demo_controller_and_leaves_nothing_behind() {
    let _one = crate::one_controller_at_a_time();
    let cwd = elsewhere("refused");
    std::fs::write(cwd.join("far.ngc"), "G21 G90\nG1 X100000 F600\nM2\n").unwrap();
    let (out, dir) = demo_in(&cwd, &["--job", "far.ngc"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "a refused job is an error: {stderr}");
    assert!(stderr.contains("job refused"), "{stderr}");
    assert!(!dir.exists(), "{} left behind", dir.display());
    // none of the demo controller's processes runs on
    let name = dir.file_name().unwrap().to_string_lossy().into_owned();
    let left = Command::new("pgrep").args(["-f", &name]).output().unwrap();
    assert!(
        left.stdout.is_empty(),
        "processes of the demo left: {}",
        String::from_utf8_lossy(&left.stdout)
    );
    let _ = std::fs::remove_dir_all(&cwd);
}
