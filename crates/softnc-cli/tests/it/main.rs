//! The crate's integration tests in one binary, each file a module: one build of
//! the shared test code and one link instead of one per file (CI time).
//! Tests that need a process of their own (a counting global allocator, a memory
//! measurement) stay beside this folder as binaries of their own.

mod demo;
mod demo_ethercat;
mod ethercat_scan;
mod install;
mod learn_kill;
mod learn_store;
mod operator_cli;
mod plan_params;
mod sim_comp;
mod sim_cycles;
mod sim_switches;

/// The repository's root.
pub fn repo() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `softnc sim FILE --json` on the default machine with `extra` arguments: its
/// report (the test fails with softnc's stderr if it does not succeed).
pub fn sim_json(file: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("sim")
        .arg(file)
        .arg("--json")
        .args(extra)
        .arg("--machine")
        .arg(repo().join("config/machines/default.ron"))
        .output()
        .expect("softnc runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// `softnc plan FILE --canon`: its motions, one JSON object each (the test fails
/// with softnc's stderr if it does not succeed).
pub fn plan_canon(file: &std::path::Path) -> Vec<serde_json::Value> {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("plan")
        .arg(file)
        .arg("--canon")
        .output()
        .expect("softnc runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .filter(|l| l.trim_start().starts_with('{'))
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The tests that start a controller, a bus emulator or a learning run take turns
/// (as when each file was its own binary, run one after another): a loaded machine
/// makes real-time jobs late.
pub fn one_controller_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    // a failed test poisons the lock; the next one may still run
    ONE.lock().unwrap_or_else(|e| e.into_inner())
}
