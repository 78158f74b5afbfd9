//! The job history: one [`JobRecord`] per job (the MMI keeps them in
//! `<data_dir>/jobs.json`), paged to the operator newest first ([`JobsPage`]).

use serde::{Deserialize, Serialize};

/// How a job ended, or that it has not. On the wire (and in `jobs.json`, where
/// records before this type wrote it as a plain string) its lower-case name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// Started and not ended.
    Running,
    /// Ran to its end.
    Completed,
    /// Stopped before its end (an abort, a stop, a fault, an E-stop).
    Aborted,
    /// Refused after it was started (the interpolator could not run it).
    Refused,
    /// Running when the MMI last stopped: it did not finish under it.
    Interrupted,
    /// An outcome this reader does not know (written by a newer MMI).
    #[serde(other)]
    Unknown,
}

impl Outcome {
    /// Its name as on the wire (`"completed"`).
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Running => "running",
            Outcome::Completed => "completed",
            Outcome::Aborted => "aborted",
            Outcome::Refused => "refused",
            Outcome::Interrupted => "interrupted",
            Outcome::Unknown => "unknown",
        }
    }

    /// The job has ended (anything but running).
    pub fn ended(self) -> bool {
        self != Outcome::Running
    }
}

impl std::fmt::Display for Outcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One job in the history.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct JobRecord {
    /// Job id.
    pub job_id: u64,
    /// Program file (for an MDI command, the file its blocks were put in).
    pub path: String,
    /// Submitted (seconds since the Unix epoch).
    #[serde(default)]
    pub submitted_unix_s: u64,
    /// How it ended, or running.
    pub outcome: Outcome,
    /// Planned samples.
    #[serde(default)]
    pub planned_samples: u64,
    /// Cycles run.
    #[serde(default)]
    pub cycles: u64,
    /// Length of the planned path (mm).
    #[serde(default)]
    pub planned_path_mm: f64,
    /// How far along the planned path the position loop is (mm).
    #[serde(default)]
    pub path_mm: f64,
    /// Accuracy over the job's feed moves.
    #[serde(default)]
    pub accuracy: Accuracy,
    /// Remarks that are not alarms (a learned correction applied, faded out, …):
    /// the first 200 a job makes (the MMI's `JOB_NOTES_KEPT`), then one last note
    /// "… N more notes not kept".
    #[serde(default)]
    pub notes: Vec<String>,
    /// The alarms raised while it ran ("Code: message"); kept when the operator
    /// clears the machine's alarms.
    #[serde(default)]
    pub alarms: Vec<String>,
    /// The immutable copy of the program that ran (`<data_dir>/programs/<sha256>.ngc`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub program: Option<String>,
    /// SHA-256 of the program that ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sha256: Option<String>,
    /// The block(s) of an MDI command (`None`: a job from a file).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mdi: Option<String>,
    /// The line a run-from-line job started at.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_line: Option<u32>,
    /// The job ran with adaptive feed (paper 003's force loop on the override).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub adaptive_force: bool,
}

impl JobRecord {
    /// How much of the job is done (0..=1): the position along the planned path
    /// (a completed job is done; a path of length 0, dwells only, counts cycles).
    pub fn progress(&self) -> f64 {
        let p = if self.outcome == Outcome::Completed {
            1.0
        } else if self.planned_path_mm > 0.0 {
            self.path_mm / self.planned_path_mm
        } else if self.planned_samples > 0 {
            self.cycles as f64 / self.planned_samples as f64
        } else {
            0.0
        };
        p.clamp(0.0, 1.0)
    }
}

/// Accuracy of a job over its feed moves.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Accuracy {
    /// Largest |contour error| (µm).
    #[serde(default)]
    pub contour_max_abs_um: f64,
    /// RMS contour error (µm).
    #[serde(default)]
    pub contour_rms_um: f64,
    /// Largest |following error| per axis, X first (µm).
    #[serde(default)]
    pub following_max_abs_um: Vec<f64>,
}

/// One page of the job history, newest first.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct JobsPage {
    /// Records in the whole history.
    pub total: u64,
    /// Newest records skipped before this page.
    pub offset: u64,
    /// As many records as fit one reply.
    pub jobs: Vec<JobRecord>,
}

impl std::fmt::Display for JobRecord {
    /// The record as its JSON (as `softnc jobs --json` prints it).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match serde_json::to_string(self) {
            Ok(text) => f.write_str(&text),
            Err(_) => write!(f, "{self:?}"),
        }
    }
}
