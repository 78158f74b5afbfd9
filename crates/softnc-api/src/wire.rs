//! The messages on the wire: JSON envelopes carrying [`API_VERSION`].

use crate::reply::Reply;
use crate::request::Request;
use serde::{Deserialize, Serialize};

/// The contract's version. Raised when a field changes meaning or a required field
/// is added; fields added with defaults keep it. Readers take any version (fields
/// they do not know are left aside); a missing one reads as 0 (before versions).
pub const API_VERSION: u32 = 1;

/// A request as sent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RequestEnvelope {
    /// The sender's [`API_VERSION`].
    #[serde(default)]
    pub api_version: u32,
    /// The request.
    pub request: Request,
}

/// A reply as sent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ReplyEnvelope {
    /// The sender's [`API_VERSION`].
    #[serde(default)]
    pub api_version: u32,
    /// The reply.
    pub reply: Reply,
}

/// Why a message could not be put on the wire or read from it.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The request serialised is larger than the payload holds (nothing sent).
    #[error("{request} request of {bytes} bytes, over the {capacity} bytes a request holds: nothing sent")]
    RequestTooLarge {
        /// [`Request::name`].
        request: &'static str,
        /// Its size (bytes).
        bytes: usize,
        /// The payload's (bytes).
        capacity: usize,
    },
    /// Not a message of this contract.
    #[error("unreadable {what}: {source}")]
    Unreadable {
        /// "request" or "reply".
        what: &'static str,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
    /// Could not be serialised.
    #[error("cannot serialise the {what}: {source}")]
    Serialise {
        /// "request" or "reply".
        what: &'static str,
        /// Why.
        #[source]
        source: serde_json::Error,
    },
}

/// `request` as the wire carries it: at most `capacity` bytes, or an error (nothing
/// is cut).
pub fn encode_request(request: &Request, capacity: usize) -> Result<String, ApiError> {
    let text = serde_json::to_string(&RequestEnvelope {
        api_version: API_VERSION,
        request: request.clone(),
    })
    .map_err(|source| ApiError::Serialise {
        what: "request",
        source,
    })?;
    if text.len() > capacity {
        return Err(ApiError::RequestTooLarge {
            request: request.name(),
            bytes: text.len(),
            capacity,
        });
    }
    Ok(text)
}

/// A request as read from the wire.
pub fn decode_request(text: &str) -> Result<Request, ApiError> {
    serde_json::from_str::<RequestEnvelope>(text)
        .map(|e| e.request)
        .map_err(|source| ApiError::Unreadable {
            what: "request",
            source,
        })
}

/// `reply` (to a request named `request`) as the wire carries it, in at most
/// `capacity` bytes: a reply that does not fit is replaced by a
/// [`Reply::TooLarge`] saying so, never cut short.
pub fn encode_reply(reply: &Reply, request: &str, capacity: usize) -> String {
    let envelope = |reply: Reply| {
        serde_json::to_string(&ReplyEnvelope {
            api_version: API_VERSION,
            reply,
        })
    };
    let too_large = |bytes: usize| Reply::TooLarge {
        request: request.to_string(),
        bytes: bytes as u64,
        capacity: capacity as u64,
    };
    let text = match envelope(reply.clone()) {
        Ok(t) => t,
        Err(e) => {
            // not serialisable (cannot happen with these types): said, as a refusal
            return envelope(Reply::refused(format!("reply not serialisable: {e}")))
                .unwrap_or_default();
        }
    };
    if text.len() <= capacity {
        return text;
    }
    envelope(too_large(text.len())).unwrap_or_default()
}

/// A reply as read from the wire.
pub fn decode_reply(text: &str) -> Result<Reply, ApiError> {
    serde_json::from_str::<ReplyEnvelope>(text)
        .map(|e| e.reply)
        .map_err(|source| ApiError::Unreadable {
            what: "reply",
            source,
        })
}

/// How long a client waits for the answer to a request that is answered once a
/// program is checked ([`Request::answered_after_check`]); the MMI's
/// `check_timeout_s` stays below it, so a check ends (passed, refused or abandoned)
/// while its client still waits.
pub const JOB_CHECK_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(300);

/// How often an operator client renews a continuous jog it holds (`Request::Jog`
/// again, the same axis and speed): the daemon refuses at load a machine profile
/// whose dead-man (`jog.deadman_s`) is not longer than this, so a living client's
/// jog is never stopped by it.
pub const JOG_RENEW_PERIOD: std::time::Duration = std::time::Duration::from_millis(25);
