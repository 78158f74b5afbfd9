//! The job history: one record per job, kept in `<data_dir>/jobs.json` (written
//! atomically), paged to the operator newest first.

use super::MmiTask;
use serde::{Deserialize, Serialize};
use softnc_core::store::write_atomic;
use softnc_core::Axes;
use softnc_ipc::{OperatorReply, PositionStatus};
use std::time::{Instant, SystemTime};

/// One job in the history.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct JobRecord {
    /// Job id.
    pub job_id: u64,
    /// Program file.
    pub path: String,
    /// Submitted (seconds since the Unix epoch).
    pub submitted_unix_s: u64,
    /// "running", "completed", "aborted".
    pub outcome: String,
    /// Planned samples.
    pub planned_samples: u64,
    /// Cycles run.
    pub cycles: u64,
    /// Length of the planned path (mm).
    #[serde(default)]
    pub planned_path_mm: f64,
    /// How far along the planned path the position loop is (mm).
    #[serde(default)]
    pub path_mm: f64,
    /// Accuracy over the job's feed moves.
    pub accuracy: Accuracy,
    /// Remarks that are not alarms (a learned correction applied, faded out, …).
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
        let p = if self.outcome == "completed" {
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

/// Accuracy of a job, accumulated from the position status stream.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Accuracy {
    /// Largest |contour error| (µm).
    pub contour_max_abs_um: f64,
    /// RMS contour error (µm).
    pub contour_rms_um: f64,
    /// Largest |following error| per axis (µm).
    pub following_max_abs_um: Axes<f64>,
    #[serde(skip)]
    sum_sq: f64,
    #[serde(skip)]
    n: u64,
}

impl Accuracy {
    pub(super) fn add(&mut self, s: &PositionStatus) {
        if s.contour_err_mm.is_finite() {
            let e = s.contour_err_mm * 1000.0;
            self.contour_max_abs_um = self.contour_max_abs_um.max(e.abs());
            self.sum_sq += e * e;
            self.n += 1;
            self.contour_rms_um = (self.sum_sq / self.n as f64).sqrt();
        }
        for (i, max_um) in self.following_max_abs_um.iter_mut().enumerate() {
            *max_um = max_um.max(s.following_err_mm[i].abs() * 1000.0);
        }
    }
}

/// The job history in `path`, and the highest job id it ever used. An unreadable
/// file is kept aside (`jobs.json.unreadable-<unix s>`) and a new history started;
/// job ids go on from the highest one found in it.
pub(super) fn load_jobs(path: &std::path::Path) -> (Vec<JobRecord>, u64) {
    let bytes = match std::fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return (Vec::new(), 0),
        Err(e) => {
            tracing::error!("{}: cannot read the job history: {e}", path.display());
            return (Vec::new(), 0);
        }
    };
    match serde_json::from_slice::<Vec<JobRecord>>(&bytes) {
        Ok(mut jobs) => {
            // a job "running" when the MMI last stopped did not finish under it
            for j in jobs.iter_mut().filter(|j| j.outcome == "running") {
                j.outcome = "interrupted".into();
            }
            let max = jobs.iter().map(|j| j.job_id).max().unwrap_or(0);
            (jobs, max)
        }
        Err(e) => {
            let stamp = SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map(|d| d.as_secs())
                .unwrap_or(0);
            let aside = path.with_extension(format!("json.unreadable-{stamp}"));
            match std::fs::rename(path, &aside) {
                Ok(()) => tracing::error!(
                    "{}: unreadable job history ({e}); kept as {}, starting a new one",
                    path.display(),
                    aside.display()
                ),
                Err(re) => tracing::error!(
                    "{}: unreadable job history ({e}), and it cannot be kept aside ({re})",
                    path.display()
                ),
            }
            (Vec::new(), highest_job_id(&String::from_utf8_lossy(&bytes)))
        }
    }
}

/// Files of the data directory that could not be written, and why: the MMI holds
/// what they should hold and writes them again every `job_record_period_s` until
/// they are written (a read-only or full disk made writable again).
#[derive(Debug, Default)]
pub(super) struct Unsaved {
    /// By slot ([`Unsaved::HISTORY`], …): why the file is not written.
    pub(super) slots: [Option<String>; 3],
}

impl Unsaved {
    /// The job history.
    pub(super) const HISTORY: usize = 0;
    /// The parameter file.
    pub(super) const PARAMS: usize = 1;
    /// The modal state file.
    pub(super) const MODAL: usize = 2;
    const NAMES: [&'static str; 3] = ["job_history", "parameters", "modal_state"];

    /// Some file is not written.
    pub(super) fn any(&self) -> bool {
        self.slots.iter().any(Option::is_some)
    }

    /// The parameter file is not written.
    pub(super) fn params(&self) -> Option<&String> {
        self.slots[Self::PARAMS].as_ref()
    }

    /// The modal state file is not written.
    pub(super) fn modal(&self) -> Option<&String> {
        self.slots[Self::MODAL].as_ref()
    }

    /// `{"job_history": why, …}` of the files not written.
    pub(super) fn json(&self) -> serde_json::Value {
        let map: serde_json::Map<String, serde_json::Value> = Self::NAMES
            .iter()
            .zip(&self.slots)
            .filter_map(|(n, e)| e.as_ref().map(|e| (n.to_string(), e.clone().into())))
            .collect();
        serde_json::Value::Object(map)
    }
}

/// The highest `"job_id": N` in a history that no longer parses.
pub(super) fn highest_job_id(text: &str) -> u64 {
    text.match_indices("\"job_id\"")
        .filter_map(|(i, k)| {
            let rest = text[i + k.len()..]
                .trim_start()
                .strip_prefix(':')?
                .trim_start();
            let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
            digits.parse().ok()
        })
        .max()
        .unwrap_or(0)
}

impl MmiTask {
    pub(super) fn jobs_path(&self) -> std::path::PathBuf {
        self.cfg.data_dir.join("jobs.json")
    }

    /// Write the job history; a failure (a read-only or full disk) is an alarm the
    /// first time, the history is kept in memory and written again every
    /// `job_record_period_s` until it is written.
    pub(super) fn save_jobs(&mut self) {
        self.last_save = Instant::now();
        let text = serde_json::to_vec_pretty(&self.jobs).unwrap_or_default();
        let written = write_atomic(&self.jobs_path(), &text).map_err(|e| e.to_string());
        let what = format!("job history {}", self.jobs_path().display());
        if let Err(e) = self.note_saved(Unsaved::HISTORY, &what, written) {
            tracing::warn!("{e}");
        }
    }

    /// The outcome of writing file `what` (an [`Unsaved`] slot): an alarm when it
    /// first fails, and it is tried again; said in the log once written again.
    pub(super) fn note_saved(
        &mut self,
        slot: usize,
        what: &str,
        written: Result<(), String>,
    ) -> anyhow::Result<()> {
        let period = self.cfg.config.job_record_period_s;
        match written {
            Ok(()) => {
                if self.unsaved.slots[slot].take().is_some() {
                    tracing::info!("{what}: written again");
                }
            }
            Err(e) => {
                let first = self.unsaved.slots[slot].is_none();
                self.unsaved.slots[slot] = Some(e.clone());
                if first {
                    tracing::error!("{what} not saved: {e}");
                    self.alarm(&format!(
                        "{what} not saved: {e}; kept in memory, tried again every {period} s"
                    ))?;
                }
            }
        }
        Ok(())
    }

    /// One page of the job history, newest first, from `offset` (skipped newest
    /// records): `{"total", "offset", "jobs"}` with as many records as fit a reply.
    pub fn jobs_page(&self, offset: f64) -> String {
        let total = self.jobs.len();
        let offset = if offset.is_finite() && offset > 0.0 {
            (offset as usize).min(total)
        } else {
            0
        };
        // room for the envelope; each record is added while the page still fits
        let cap = OperatorReply::MESSAGE_CAPACITY - 64;
        let mut body = String::from("[");
        for j in self.jobs.iter().rev().skip(offset) {
            let rec = serde_json::to_string(j).unwrap_or_default();
            if body.len() + rec.len() + 2 > cap && body.len() > 1 {
                break;
            }
            if body.len() > 1 {
                body.push(',');
            }
            body.push_str(&rec);
        }
        body.push(']');
        format!("{{\"total\":{total},\"offset\":{offset},\"jobs\":{body}}}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unreadable_history_is_kept_aside_and_job_ids_go_on() {
        let dir = std::env::temp_dir().join(format!("softnc-jobs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("jobs.json");
        let whole = r#"[{"job_id": 50, "path": "a.ngc"}, {"job_id": 51, "path": "b.ngc"}]"#;
        let cut = &whole[..whole.len() - 8];
        std::fs::write(&path, cut).unwrap();
        let (jobs, floor) = load_jobs(&path);
        assert!(jobs.is_empty());
        assert_eq!(floor, 51);
        let kept: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with("jobs.json.unreadable-")
            })
            .collect();
        assert_eq!(kept.len(), 1, "kept aside");
        assert_eq!(std::fs::read_to_string(kept[0].path()).unwrap(), cut);
        assert!(!path.exists(), "a new history starts");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
