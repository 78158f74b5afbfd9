//! The crate's integration tests in one binary, each file a module: one build of
//! the shared test code and one link instead of one per file (CI time).
//! Tests that need a process of their own (a counting global allocator, a memory
//! measurement) stay beside this folder as binaries of their own.

mod comp;
mod corpus;
mod cycles;
mod diff_fuzz;
mod errors;
mod files_taken;
mod flow;
mod golden;
mod language;
mod machine_ops;
mod probe;
mod props;
mod rotation;
mod rs274_calls;
mod spindle;
