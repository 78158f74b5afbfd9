//! The job history: one record per job, kept in `<data_dir>/jobs.json` (written
//! atomically), paged to the operator newest first.

use super::MmiTask;
pub use softnc_api::{Accuracy, JobRecord, Outcome};
use softnc_api::{JobsPage, Reply};
use softnc_core::store::write_atomic;
use softnc_core::MAX_AXES;
use softnc_ipc::{OperatorReply, PositionStatus};
use std::time::{Instant, SystemTime};

/// Notes kept in one job's record (`JobRecord::notes`): a program that prints in
/// a loop (`(PRINT,…)`, `(DEBUG,…)`) sends a note per pass, and the record is
/// written whole at every change. Past this many, one last note says how many
/// more came and were not kept ("… N more notes not kept").
pub const JOB_NOTES_KEPT: usize = 200;

/// The marker note after [`JOB_NOTES_KEPT`] notes.
fn notes_not_kept(n: u64) -> String {
    format!("… {n} more note{} not kept", if n == 1 { "" } else { "s" })
}

/// The count of a marker note made by [`notes_not_kept`].
fn count_not_kept(note: &str) -> Option<u64> {
    let n = note.strip_prefix("… ")?.split(' ').next()?;
    let rest = note.strip_prefix("… ")?.strip_prefix(n)?;
    matches!(rest, " more note not kept" | " more notes not kept")
        .then(|| n.parse().ok())
        .flatten()
}

/// Add `text` to a job's `notes`, keeping at most `kept` notes and then one
/// marker that counts the notes not kept.
pub(super) fn push_note(notes: &mut Vec<String>, text: String, kept: usize) {
    if notes.len() < kept {
        notes.push(text);
        return;
    }
    let counted = notes.get(kept).and_then(|m| count_not_kept(m)).unwrap_or(0);
    notes.truncate(kept);
    notes.push(notes_not_kept(counted + 1));
}

/// The RMS contour error of the running job, accumulated from the position status
/// stream (the record keeps the result, [`Accuracy::contour_rms_um`]).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct ContourRms {
    /// The job it is of.
    job_id: u64,
    sum_sq_um2: f64,
    n: u64,
}

/// Add one position status of job `acc`'s to its accuracy.
pub(super) fn add_accuracy(
    acc: &mut Accuracy,
    rms: &mut ContourRms,
    job_id: u64,
    s: &PositionStatus,
) {
    if rms.job_id != job_id {
        *rms = ContourRms {
            job_id,
            ..ContourRms::default()
        };
    }
    if s.contour_err_mm.is_finite() {
        let e = s.contour_err_mm * 1000.0;
        acc.contour_max_abs_um = acc.contour_max_abs_um.max(e.abs());
        rms.sum_sq_um2 += e * e;
        rms.n += 1;
        acc.contour_rms_um = (rms.sum_sq_um2 / rms.n as f64).sqrt();
    }
    if acc.following_max_abs_um.len() < MAX_AXES {
        acc.following_max_abs_um.resize(MAX_AXES, 0.0);
    }
    for (i, max_um) in acc
        .following_max_abs_um
        .iter_mut()
        .enumerate()
        .take(MAX_AXES)
    {
        *max_um = max_um.max(s.following_err_mm[i].abs() * 1000.0);
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
            for j in jobs.iter_mut().filter(|j| j.outcome == Outcome::Running) {
                j.outcome = Outcome::Interrupted;
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

/// The job history and what is written of it: one record per job, the running
/// job's RMS contour error accumulated, the ids used, when it was last written and
/// which files of the data directory could not be.
pub(super) struct History {
    pub(super) jobs: Vec<JobRecord>,
    /// The running job's RMS contour error, accumulated.
    pub(super) contour_rms: ContourRms,
    /// Job ids go on above this (an unreadable history's highest).
    pub(super) job_id_floor: u64,
    /// When the history was last written.
    pub(super) last_save: Instant,
    /// Files of the data directory that could not be written ([`Unsaved`]).
    pub(super) unsaved: Unsaved,
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

    /// The files not written, by what they hold, and why.
    pub(super) fn to_api(&self) -> softnc_api::Unsaved {
        softnc_api::Unsaved {
            job_history: self.slots[Self::HISTORY].clone(),
            parameters: self.slots[Self::PARAMS].clone(),
            modal_state: self.slots[Self::MODAL].clone(),
        }
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
        self.history.last_save = Instant::now();
        let text = serde_json::to_vec_pretty(&self.history.jobs).unwrap_or_default();
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
                if self.history.unsaved.slots[slot].take().is_some() {
                    tracing::info!("{what}: written again");
                }
            }
            Err(e) => {
                let first = self.history.unsaved.slots[slot].is_none();
                self.history.unsaved.slots[slot] = Some(e.clone());
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
}

impl History {
    /// One page of the job history, newest first, from `offset` (skipped newest
    /// records): as many records as fit a reply (at least one: a record too large
    /// for a reply alone is answered [`Reply::TooLarge`]).
    pub(super) fn page(&self, offset: u64) -> Reply {
        let total = self.jobs.len() as u64;
        let offset = offset.min(total);
        let page = |jobs: Vec<JobRecord>| {
            Reply::Jobs(JobsPage {
                total,
                offset,
                jobs,
            })
        };
        // the page's size serialised: the empty page's, plus each record's
        // (serialised alone as in the list) and a comma between records
        let envelope = softnc_api::encode_reply(&page(Vec::new()), "jobs", usize::MAX).len();
        let mut bytes = envelope;
        let mut jobs: Vec<JobRecord> = Vec::new();
        for j in self.jobs.iter().rev().skip(offset as usize) {
            let len =
                serde_json::to_string(j).map_or(0, |t| t.len()) + usize::from(!jobs.is_empty());
            if !jobs.is_empty() && bytes + len > OperatorReply::MESSAGE_CAPACITY {
                break;
            }
            bytes += len;
            jobs.push(j.clone());
        }
        page(jobs)
    }

    /// The running job's record.
    pub(super) fn running(&mut self) -> Option<&mut JobRecord> {
        self.jobs
            .iter_mut()
            .rev()
            .find(|j| j.outcome == Outcome::Running)
    }

    /// A job is running (its record says so).
    pub(super) fn any_running(&self) -> bool {
        self.jobs.iter().any(|j| j.outcome == Outcome::Running)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_past_the_cap_are_counted_in_one_last_note() {
        let mut notes = Vec::new();
        for k in 0..JOB_NOTES_KEPT {
            push_note(&mut notes, format!("print: {k}"), JOB_NOTES_KEPT);
        }
        assert_eq!(notes.len(), JOB_NOTES_KEPT);
        push_note(&mut notes, "print: x".into(), JOB_NOTES_KEPT);
        assert_eq!(notes.len(), JOB_NOTES_KEPT + 1);
        assert_eq!(notes[JOB_NOTES_KEPT], "… 1 more note not kept");
        for _ in 0..1234 {
            push_note(&mut notes, "print: y".into(), JOB_NOTES_KEPT);
        }
        assert_eq!(notes.len(), JOB_NOTES_KEPT + 1);
        assert_eq!(
            notes[JOB_NOTES_KEPT - 1],
            format!("print: {}", JOB_NOTES_KEPT - 1)
        );
        assert_eq!(notes[JOB_NOTES_KEPT], "… 1235 more notes not kept");
        // a note that only looks like the marker is kept as it is
        let mut few = vec![];
        push_note(&mut few, "… 3 more notes not kept".into(), 2);
        push_note(&mut few, "b".into(), 2);
        push_note(&mut few, "c".into(), 2);
        assert_eq!(
            few,
            ["… 3 more notes not kept", "b", "… 1 more note not kept"]
        );
    }

    fn record(job_id: u64, path_len: usize) -> JobRecord {
        JobRecord {
            job_id,
            path: format!("/shop/{}", "p".repeat(path_len)),
            submitted_unix_s: 0,
            outcome: Outcome::Completed,
            planned_samples: 100,
            cycles: 100,
            planned_path_mm: 10.0,
            path_mm: 10.0,
            accuracy: Accuracy::default(),
            notes: vec![],
            alarms: vec![],
            program: None,
            sha256: None,
            mdi: None,
            from_line: None,
            adaptive_force: false,
        }
    }

    fn history(jobs: Vec<JobRecord>) -> History {
        History {
            jobs,
            contour_rms: ContourRms::default(),
            job_id_floor: 0,
            last_save: Instant::now(),
            unsaved: Unsaved::default(),
        }
    }

    #[test]
    fn a_long_history_comes_whole_in_pages_that_each_fit_a_reply() {
        let h = history((1..=200).map(|id| record(id, 300)).collect());
        let mut seen = Vec::new();
        let mut pages = 0;
        while (seen.len() as u64) < 200 {
            let reply = h.page(seen.len() as u64);
            let text = softnc_api::encode_reply(&reply, "jobs", usize::MAX);
            assert!(
                text.len() <= OperatorReply::MESSAGE_CAPACITY,
                "{} bytes",
                text.len()
            );
            let Reply::Jobs(page) = reply else {
                panic!("not a page: {reply:?}")
            };
            assert_eq!((page.total, page.offset), (200, seen.len() as u64));
            assert!(!page.jobs.is_empty());
            seen.extend(page.jobs.iter().map(|j| j.job_id));
            pages += 1;
        }
        assert!(pages > 1, "a long history takes several pages");
        let want: Vec<u64> = (1..=200).rev().collect();
        assert_eq!(seen, want, "newest first, each once");
        // past the end: an empty page
        let Reply::Jobs(end) = h.page(500) else {
            panic!("not a page")
        };
        assert!(end.jobs.is_empty());
    }

    #[test]
    fn a_record_too_large_for_a_reply_is_an_error_reply_not_cut() {
        let h = history(vec![record(1, OperatorReply::MESSAGE_CAPACITY)]);
        let text = softnc_api::encode_reply(&h.page(0), "jobs", OperatorReply::MESSAGE_CAPACITY);
        assert!(text.len() <= OperatorReply::MESSAGE_CAPACITY);
        match softnc_api::decode_reply(&text).unwrap() {
            Reply::TooLarge {
                request, capacity, ..
            } => assert_eq!(
                (request.as_str(), capacity),
                ("jobs", OperatorReply::MESSAGE_CAPACITY as u64)
            ),
            other => panic!("{other:?}"),
        }
    }

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
