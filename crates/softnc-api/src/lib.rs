//! softnc's operator contract: what an operator client (the `softnc` CLI, its
//! terminal UI `watch`, a web panel) sends to the MMI and what it gets back, as
//! types.
//!
//! - [`Request`]: one variant per operator command, with its own typed arguments;
//! - [`Reply`]: accepted (with a job id), refused (with the reason), the
//!   [`Status`], a page of [`JobRecord`]s, the work offsets, the tool table, or
//!   [`Reply::TooLarge`] when the answer does not fit the wire;
//! - [`Status`]: the machine as the operator sees it;
//! - [`JobRecord`]: one job of the history (as kept in the MMI's `jobs.json`), its
//!   end an [`Outcome`].
//!
//! On the wire (`softnc-ipc`'s operator request/reply payloads) each message is JSON
//! in an envelope that carries [`API_VERSION`] ([`encode_request`],
//! [`decode_request`], [`encode_reply`], [`decode_reply`]). Readers tolerate fields
//! they do not know (no type here denies unknown fields), so a newer writer's
//! additions do not break an older reader; fields added later have defaults, so
//! records written before them still read.
//!
//! ```
//! use softnc_api::{decode_request, encode_request, Request};
//! let text = encode_request(&Request::FeedOverride { fraction: 0.5 }, 4096).unwrap();
//! assert_eq!(decode_request(&text).unwrap(), Request::FeedOverride { fraction: 0.5 });
//! ```
#![warn(missing_docs)]

mod job;
mod nan;
mod reply;
mod request;
mod status;
mod wire;

pub use job::{Accuracy, JobRecord, JobsPage, Outcome};
pub use reply::{OffsetTable, Reply, Tool, WorkSystem};
pub use request::{axis_letter, Request};
pub use softnc_core::Axis;
pub use status::{
    ActiveOffsets, AdaptiveForce, Alarm, AlarmKind, AxesStatus, BusFigures, Coolant, JobStatus,
    LoopTiming, Loops, MachineState, Percentiles, ProcessHealth, Processes, Spindle, Status,
    Switches, Unsaved,
};
pub use wire::{
    decode_reply, decode_request, encode_reply, encode_request, ApiError, ReplyEnvelope,
    RequestEnvelope, API_VERSION, JOB_CHECK_TIMEOUT, JOG_RENEW_PERIOD,
};
