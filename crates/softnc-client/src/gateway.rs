//! The operator gateway's wire, both ends: a Unix stream socket that `softncd` serves
//! to the members of the controller's operator group (the socket is the group's,
//! mode 0660). One request per line — `softnc-api`'s request envelope, as on
//! iceoryx2 — and one answer line per request: `ok ` followed by the reply envelope,
//! or `err ` followed by why the gateway could not get one (no MMI answers, …).

use anyhow::{bail, Context, Result};
use softnc_api::{Reply, Request, JOB_CHECK_TIMEOUT};
use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Bytes of a request line (the request envelope's limit on iceoryx2).
pub const REQUEST_LINE_BYTES: usize = softnc_ipc::OperatorRequest::MESSAGE_CAPACITY;
/// Bytes of an answer line: the reply envelope's limit and the prefix.
pub const ANSWER_LINE_BYTES: usize = softnc_ipc::OperatorReply::MESSAGE_CAPACITY + 8;
/// How long the gateway waits for more than a request's reply (a job's check may
/// take [`JOB_CHECK_TIMEOUT`]).
const ANSWER_MARGIN: Duration = Duration::from_secs(10);

/// One answer line.
pub fn answer_line(answer: &Result<Reply, String>, request_name: &str) -> String {
    match answer {
        Ok(reply) => format!(
            "ok {}\n",
            softnc_api::encode_reply(
                reply,
                request_name,
                softnc_ipc::OperatorReply::MESSAGE_CAPACITY
            )
        ),
        Err(why) => format!("err {}\n", why.replace('\n', " ")),
    }
}

/// Read one line of at most `max` bytes (without its newline); `None` at the end of
/// the stream; an error for a longer line or one that is not UTF-8.
pub fn read_line<R: BufRead>(reader: &mut R, max: usize) -> std::io::Result<Option<String>> {
    let mut buf = Vec::new();
    let n = std::io::Read::take(&mut *reader, max as u64 + 1).read_until(b'\n', &mut buf)?;
    if n == 0 {
        return Ok(None);
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
    } else if buf.len() > max {
        return Err(std::io::Error::other(format!(
            "a line longer than {max} bytes"
        )));
    }
    String::from_utf8(buf)
        .map(Some)
        .map_err(|_| std::io::Error::other("a line that is not UTF-8"))
}

/// The client's end: one connection to the gateway.
pub(crate) struct GatewayLink {
    reader: BufReader<UnixStream>,
    writer: UnixStream,
    socket: PathBuf,
    instance: String,
}

impl GatewayLink {
    /// Connect to the gateway socket `socket` of instance `instance`.
    pub(crate) fn connect(socket: &Path, instance: &str) -> Result<Self> {
        let stream = UnixStream::connect(socket).with_context(|| {
            format!(
                "no controller answers for instance {instance:?} at its operator gateway {} (is softncd running, and is this user in its operator group?)",
                socket.display()
            )
        })?;
        let writer = stream.try_clone().context("operator gateway socket")?;
        Ok(GatewayLink {
            reader: BufReader::new(stream),
            writer,
            socket: socket.to_path_buf(),
            instance: instance.to_string(),
        })
    }

    /// Send one request and read its answer.
    pub(crate) fn request(&mut self, request: &Request) -> Result<Reply> {
        let text = softnc_api::encode_request(request, REQUEST_LINE_BYTES)?;
        let wait = if request.answered_after_check() {
            JOB_CHECK_TIMEOUT
        } else {
            crate::REPLY_TIMEOUT
        } + ANSWER_MARGIN;
        self.reader.get_ref().set_read_timeout(Some(wait))?;
        let gone = |e: std::io::Error| {
            anyhow::anyhow!(
                "operator gateway {} of instance {:?}: {e} (is softncd running?)",
                self.socket.display(),
                self.instance
            )
        };
        self.writer
            .write_all(format!("{text}\n").as_bytes())
            .map_err(gone)?;
        let Some(line) = read_line(&mut self.reader, ANSWER_LINE_BYTES).map_err(gone)? else {
            return Err(gone(std::io::Error::other("it closed the connection")));
        };
        if let Some(envelope) = line.strip_prefix("ok ") {
            return softnc_api::decode_reply(envelope).with_context(|| {
                format!(
                    "unreadable reply from the operator gateway ({} bytes)",
                    envelope.len()
                )
            });
        }
        if let Some(why) = line.strip_prefix("err ") {
            bail!("{why}");
        }
        bail!(
            "unreadable answer from the operator gateway ({} bytes)",
            line.len()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_bounded_and_whole() {
        let mut r = BufReader::new(&b"abc\ndef"[..]);
        assert_eq!(read_line(&mut r, 3).unwrap().as_deref(), Some("abc"));
        assert_eq!(read_line(&mut r, 3).unwrap().as_deref(), Some("def"));
        assert_eq!(read_line(&mut r, 3).unwrap(), None);
        let mut long = BufReader::new(&b"abcdef\n"[..]);
        assert!(read_line(&mut long, 3).is_err());
        let mut bad = BufReader::new(&b"\xff\xfe\n"[..]);
        assert!(read_line(&mut bad, 3).is_err());
    }

    #[test]
    fn answers_carry_replies_and_errors_on_one_line() {
        let ok = answer_line(&Ok(Reply::accepted(None, "on")), "on");
        assert!(ok.starts_with("ok ") && ok.ends_with('\n') && ok.matches('\n').count() == 1);
        let reply = softnc_api::decode_reply(ok.trim_end().strip_prefix("ok ").unwrap()).unwrap();
        assert!(reply.is_accepted());
        let err = answer_line(&Err("no MMI\nanswers".into()), "on");
        assert_eq!(err, "err no MMI answers\n");
    }
}
