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

/// The tests that start a controller, a bus emulator or a learning run take turns
/// (as when each file was its own binary, run one after another): a loaded machine
/// makes real-time jobs late.
pub fn one_controller_at_a_time() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    // a failed test poisons the lock; the next one may still run
    ONE.lock().unwrap_or_else(|e| e.into_inner())
}
