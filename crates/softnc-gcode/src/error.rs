//! G-code errors: every one carries file:line:column and a plain-language message.

/// What went wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ErrorKind {
    /// A word or construct softnc does not implement yet (parameters, expressions,
    /// O-words, canned cycles, cutter compensation, ...). Never misread.
    #[error("unsupported: {word}: {why}")]
    Unsupported {
        /// The word as written, e.g. `G81`, `#1`, `O100`.
        word: String,
        /// Why or what instead.
        why: String,
    },
    /// The program ran more blocks than the configured limit (an endless loop is
    /// ended here instead of hanging; see `ReadOptions::block_limit`).
    #[error("executed-block limit of {limit} blocks reached (an endless loop?); raise it with the block limit option if the program is meant to run longer")]
    BlockLimit {
        /// The limit that was reached.
        limit: u64,
    },
    /// Anything LinuxCNC would also refuse.
    #[error("{0}")]
    Invalid(String),
    /// A line of a program given as bytes ([`crate::read_program_chunked_params_bytes`])
    /// is not UTF-8: the caller reads the text made UTF-8 (lossy) instead, as a
    /// program given as text is read.
    #[error("the program is not UTF-8")]
    NotUtf8,
}

/// A G-code error at a source position.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}:{column}: {kind}")]
pub struct GcodeError {
    /// File name as given.
    pub file: String,
    /// 1-based line.
    pub line: u32,
    /// 1-based column (character) of the offending word.
    pub column: u32,
    /// What went wrong.
    pub kind: ErrorKind,
}
