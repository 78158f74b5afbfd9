//! softnc's runtime: the three cyclic processes and their supervisor.
//!
//! - [`config`]: `config/default.ron`, one file for all processes.
//! - `softnc_ipc::bus`: the iceoryx2 node and services every process opens.
//! - [`interp`]: `softnc-interp`, job → planner → command samples, paced by the
//!   position process's consumption so the lookahead ring stays filled.
//! - [`position`]: `softnc-position`, lookahead ring → controller stack → servo
//!   backend, faults and status.
//! - [`prep`]: the position process's preparation thread: jobs' paths, engines,
//!   traces and PDC designs (S words, spindle override), made off the cycle.
//! - [`outbox`]: both loops' messages leave through a lock-free queue to a
//!   publisher thread.
//! - [`job_setup`]: how a job is read beyond its text (start, parameters, switches).
//! - [`jobfile`]: a job's program taken in once (regular file, size limit) and kept
//!   as an immutable copy named by its hash, which the other processes run.
//! - [`machine_store`]: the parameter file (work offsets, G92, stored positions)
//!   and the tool table, kept between jobs and restarts.
//! - [`manual`]: jogs and homing between jobs, on the position cycle.
//! - [`mmi`]: `softnc-mmi`, job checks, machine state, alarms, history, operator API.
//! - [`supervisor`]: `softncd`, starts, watches, restarts and stops the processes.
//! - [`lifecycle`]: one controller per instance (a lock), stopping on SIGTERM/SIGINT
//!   or the parent's death, systemd's readiness and watchdog.
//! - [`cli`]: shared start-up of the binaries.
//! - [`loop_watch`]: a real-time loop's watch over its own timing (stalls, late
//!   cycles).
//! - [`trace`]: per-cycle CSV traces, written off the cycle path.
//! - [`plan_samples`]: a plan's samples for the offline simulator, their feed
//!   override open to adaptive feed as the interpolation process opens it.
//!
//! The operator client is the crate `softnc-client`; the operator contract the
//! MMI serves is the crate `softnc-api`.
#![warn(missing_docs)]

pub mod cli;
pub mod config;
pub mod interp;
pub mod job_setup;
pub mod jobfile;
pub mod lifecycle;
pub mod loop_watch;
pub mod machine_store;
pub mod manual;
pub mod mmi;
pub mod operator_gateway;
pub mod outbox;
pub mod plan_samples;
pub mod position;
pub mod prep;
pub mod supervisor;
pub mod trace;
pub mod user_m;
