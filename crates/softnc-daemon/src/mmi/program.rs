//! What a check takes in besides a job file: the kinds of program checked (a job,
//! MDI blocks, a touch-off) and how an MDI program's errors read. Shared by the
//! check (`check`) and the commands that start one (`setup`, the operator's).

/// What is being checked.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum CheckKind {
    /// A job from a file (from a line).
    Job {
        from_line: Option<u32>,
        /// With adaptive feed.
        adaptive_force: bool,
    },
    /// MDI block(s).
    Mdi { text: String },
    /// A touch-off (a G10 L20 block: no motion).
    TouchOff { what: String },
}

impl CheckKind {
    /// The operator request that asks for it (`softnc_api::Request::name`).
    pub(super) fn request_name(&self) -> &'static str {
        match self {
            CheckKind::Job { .. } => "submit_job",
            CheckKind::Mdi { .. } => "mdi",
            CheckKind::TouchOff { .. } => "touch_off",
        }
    }
}

/// An error of the MDI file `path` (`path:LINE:COL: why`, its first line the `%`
/// that opens it) as the operator's blocks: `MDI block N, column C: why`.
pub(super) fn mdi_error(path: &str, msg: &str) -> String {
    let located = msg.strip_prefix(path).and_then(|rest| {
        let mut parts = rest.strip_prefix(':')?.splitn(3, ':');
        let line: u32 = parts.next()?.parse().ok()?;
        let col: u32 = parts.next()?.parse().ok()?;
        Some((line, col, parts.next()?.trim_start()))
    });
    match located {
        Some((line, col, why)) if line >= 2 => {
            format!("MDI block {}, column {col}: {why}", line - 1)
        }
        Some((_, _, why)) => format!("MDI: {why}"),
        None => format!("MDI: {msg}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mdi_errors_name_the_operators_blocks() {
        let p = "/d/mdi/mdi.ngc";
        assert_eq!(
            mdi_error(p, &format!("{p}:3:7: Failed to find sub")),
            "MDI block 2, column 7: Failed to find sub"
        );
        assert_eq!(mdi_error(p, "cannot read"), "MDI: cannot read");
    }
}
