//! Why an experiment could not run.

use std::fmt::Display;
use std::path::PathBuf;

/// Why an experiment could not run.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The machine profile (or another configuration file the experiment reads) did
    /// not load: the message names the file and the RON path.
    #[error("{0}")]
    Config(String),
    /// A step of the experiment failed: what it was doing, and why.
    #[error("{context}: {reason}")]
    Step {
        /// What the experiment was doing.
        context: String,
        /// Why it failed.
        reason: String,
    },
    /// A library step refused; its own message says what and why.
    #[error("{0}")]
    Failed(String),
    /// The experiment cannot run as configured (e.g. a profile without the section
    /// it needs).
    #[error("{0}")]
    Refused(String),
    /// A plot could not be written.
    #[error("plot {path}: {reason}")]
    Plot {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl ExperimentError {
    /// A refusal with this message.
    pub fn refused(message: impl Display) -> Self {
        ExperimentError::Refused(message.to_string())
    }
}

/// The experiments' results.
pub type Result<T, E = ExperimentError> = std::result::Result<T, E>;

/// Adds what the experiment was doing to a failure (`context: reason`).
pub(crate) trait Context<T> {
    /// With a fixed context.
    fn context(self, context: impl Display) -> Result<T>;
    /// With a context built only on failure.
    fn with_context<C: Display>(self, context: impl FnOnce() -> C) -> Result<T>;
}

impl<T, E: Display> Context<T> for std::result::Result<T, E> {
    fn context(self, context: impl Display) -> Result<T> {
        self.map_err(|e| ExperimentError::Step {
            context: context.to_string(),
            reason: e.to_string(),
        })
    }
    fn with_context<C: Display>(self, context: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| ExperimentError::Step {
            context: context().to_string(),
            reason: e.to_string(),
        })
    }
}

impl<T> Context<T> for Option<T> {
    fn context(self, context: impl Display) -> Result<T> {
        self.ok_or_else(|| ExperimentError::Refused(context.to_string()))
    }
    fn with_context<C: Display>(self, context: impl FnOnce() -> C) -> Result<T> {
        self.ok_or_else(|| ExperimentError::Refused(context().to_string()))
    }
}

/// A failure of a library step whose own message says enough.
pub(crate) fn failed(e: impl Display) -> ExperimentError {
    ExperimentError::Failed(e.to_string())
}
