//! What the MMI answers.

use crate::job::JobsPage;
use crate::nan::{f64_or_nan, xyz_or_nan};
use crate::status::Status;
use serde::{Deserialize, Serialize};

/// The MMI's answer to one [`crate::Request`]. On the wire: `{"reply": "<snake_case
/// name>", "body": …}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "reply", content = "body", rename_all = "snake_case")]
pub enum Reply {
    /// Done, or under way.
    Accepted {
        /// The job the request started or concerns.
        #[serde(default)]
        job_id: Option<u64>,
        /// What was done, as an operator reads it.
        message: String,
    },
    /// Not done, and nothing was sent to the machine for it.
    Refused {
        /// Why (`file:line:column: reason` for a program).
        reason: String,
    },
    /// The machine's status.
    Status(Box<Status>),
    /// A page of the job history.
    Jobs(JobsPage),
    /// The work offsets.
    Offsets(OffsetTable),
    /// The tool table.
    Tools(Vec<Tool>),
    /// The answer did not fit the wire's payload: not sent (never cut short).
    TooLarge {
        /// The request it answers ([`crate::Request::name`]).
        request: String,
        /// Its size serialised (bytes).
        bytes: u64,
        /// What the payload holds (bytes).
        capacity: u64,
    },
}

impl Reply {
    /// An accepted reply.
    pub fn accepted(job_id: Option<u64>, message: impl Into<String>) -> Reply {
        Reply::Accepted {
            job_id,
            message: message.into(),
        }
    }

    /// A refusal.
    pub fn refused(reason: impl Into<String>) -> Reply {
        Reply::Refused {
            reason: reason.into(),
        }
    }

    /// The request was accepted (also a status, jobs, offsets or tools answer).
    pub fn is_accepted(&self) -> bool {
        !matches!(self, Reply::Refused { .. } | Reply::TooLarge { .. })
    }

    /// The job an accepted request started or concerns.
    pub fn job_id(&self) -> Option<u64> {
        match self {
            Reply::Accepted { job_id, .. } => *job_id,
            _ => None,
        }
    }

    /// What an operator reads of it: the message, the reason, or what was answered.
    pub fn message(&self) -> String {
        match self {
            Reply::Accepted { message, .. } => message.clone(),
            Reply::Refused { reason } => reason.clone(),
            Reply::Status(s) => format!("status ({})", s.state),
            Reply::Jobs(p) => format!(
                "jobs {}..{} of {}",
                p.offset,
                p.offset + p.jobs.len() as u64,
                p.total
            ),
            Reply::Offsets(o) => format!("offsets ({} active)", o.active),
            Reply::Tools(t) => format!("{} tools", t.len()),
            Reply::TooLarge {
                request,
                bytes,
                capacity,
            } => format!(
                "the reply to {request} is {bytes} bytes, over the {capacity} bytes a reply holds: not sent"
            ),
        }
    }
}

/// One coordinate system of the work offsets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WorkSystem {
    /// Its name (`"G54"`).
    pub coords: String,
    /// Its origin in machine coordinates (mm).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub origin_mm: [f64; 3],
    /// Its XY rotation (degrees).
    #[serde(deserialize_with = "f64_or_nan")]
    pub rotation_deg: f64,
    /// It is the active one.
    pub active: bool,
}

/// The work offsets: G54 … G59.3, G92 and the tool offset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OffsetTable {
    /// The active coordinate system (`"G54"`).
    pub active: String,
    /// The nine coordinate systems.
    pub systems: Vec<WorkSystem>,
    /// G92 offset (mm).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub g92_mm: [f64; 3],
    /// The tool in the spindle (0: none).
    pub tool: u32,
    /// Its offset in effect (mm).
    #[serde(deserialize_with = "xyz_or_nan")]
    pub tool_offset_mm: [f64; 3],
}

/// One tool of the tool table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tool {
    /// Tool number (T word).
    pub number: u32,
    /// Length offset along Z (mm).
    pub length_mm: f64,
    /// Cutter diameter (mm).
    #[serde(default)]
    pub diameter_mm: f64,
}
