//! The crate's integration tests in one binary, each file a module: one build of
//! the shared test code and one link instead of one per file (CI time).
//! Tests that need a process of their own (a counting global allocator, a memory
//! measurement) stay beside this folder as binaries of their own, as does one that includes
//! planner sources with its own coverage counter at its crate root (`line_arc_bits`).

mod arc_blends;
mod biarc;
#[path = "../common/mod.rs"]
mod common;
mod corners;
mod dense_and_override;
mod flow;
mod kinks;
mod limits;
mod machine;
mod motion_primitives;
mod naive_cam;
mod properties;
mod rapid_override;
mod soft_limits;
mod spirals;
mod stream;
mod streamed;
