//! The crate's integration tests in one binary, each file a module: one build of
//! the shared test code and one link instead of one per file (CI time).
//! Tests that need a process of their own (a counting global allocator, a memory
//! measurement) stay beside this folder as binaries of their own.

mod backend_conformance;
mod compensation;
mod determinism;
mod machine_io;
mod paper_models;
mod profiles;
mod variation;
