//! A submitted job (or MDI block, or touch-off) taken in off the loop: read once,
//! copied, checked and planned from where the machine is; started or refused when
//! the check ends.

use super::history::{Accuracy, JobRecord};
use super::setup::mdi_error;
use super::{MmiTask, OperatorRequestIn};
use crate::interp::{check_bytes, JobSetup};
use crate::jobfile::intake;
use anyhow::Result;
use softnc_ipc::{
    Alarm, AlarmCode, ControlKind, FixedStr, MachineState, OperatorReply, ProcessId,
    JOB_ADAPTIVE_FORCE,
};
use softnc_planner::PlanStats;
use std::time::SystemTime;

/// What the check of a submitted job gives: the program taken in, the path of its
/// copy, the plan's figures and the parameters as it leaves them; or why it is
/// refused.
pub(super) type CheckResult = std::result::Result<
    (
        crate::jobfile::JobFile,
        String,
        PlanStats,
        softnc_gcode::Params,
        String,
    ),
    String,
>;

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

/// A job being taken in (read once, copied, planned from the machine's position) on
/// a thread of its own: the loop goes on serving status, E-stop and heartbeats.
pub(super) struct Checking {
    pub(super) path: String,
    pub(super) kind: CheckKind,
    /// The operator's request, answered when the check ends.
    pub(super) request: Option<OperatorRequestIn>,
    pub(super) result: std::sync::mpsc::Receiver<CheckResult>,
    /// An E-stop or a stop came while checking: the job is not started.
    pub(super) cancelled: Option<&'static str>,
}

/// Take a submitted job in: read once (a regular file under `limit`), stored as an
/// immutable copy under `programs`, planned as `setup` says (from where the machine
/// is, with its offsets) as the interpolator will plan it, with the parameters it
/// leaves. Runs off the MMI's loop.
pub(super) fn check_job(
    path: &str,
    limit: u64,
    programs: &std::path::Path,
    machine: &softnc_core::MachineProfile,
    setup: &JobSetup,
) -> CheckResult {
    let job = intake(path, limit, programs).map_err(|e| e.to_string())?;
    // checked as it will be streamed: the plan's figures, never the whole plan
    let (_, _, checked, modal) = check_bytes(&job.bytes, path, machine, setup)?;
    let params = checked.end_params().clone();
    let copy = job.copy.display().to_string();
    if !FixedStr::<512>::fits(&copy) {
        return Err(format!(
            "{copy}: the job's copy has a path over 512 bytes (data_dir too deep)"
        ));
    }
    Ok((job, copy, checked.stats(), params, modal))
}

impl MmiTask {
    /// Read and check a program off the loop ([`Checking`]); answered when done.
    pub(super) fn begin_check(&mut self, path: String, kind: CheckKind) -> Option<OperatorReply> {
        let limit = self.cfg.config.max_job_bytes;
        let programs = self.cfg.data_dir.join("programs");
        let machine = match self.store.profile(&self.cfg.machine) {
            Ok(m) => m,
            Err(e) => return Some(Self::reply(false, 0, &format!("{e}; nothing started"))),
        };
        // planned from where the machine is, with its offsets, as the interpolator
        // will plan it
        let setup = JobSetup {
            start_mm: self
                .last
                .map_or([0.0; 3], |s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]),
            params: self.params.clone(),
            switches: self.switches,
            from_line: match kind {
                CheckKind::Job { from_line, .. } => from_line,
                _ => None,
            },
            subroutine_path: self.cfg.subroutine_path.clone(),
            preamble: self.modal.clone(),
        };
        let (tx, rx) = std::sync::mpsc::channel();
        let job_path = path.clone();
        let spawned = std::thread::Builder::new()
            .name("job-check".into())
            .spawn(move || {
                let _ = tx.send(check_job(&job_path, limit, &programs, &machine, &setup));
            });
        if let Err(e) = spawned {
            return Some(Self::reply(
                false,
                0,
                &format!("cannot check the job: {e}; job not started"),
            ));
        }
        self.checking = Some(Checking {
            path,
            kind,
            request: None,
            result: rx,
            cancelled: None,
        });
        None
    }

    /// The end of a job's check: start it (its record, the interpolator told) or
    /// refuse it, and answer the operator who submitted it.
    pub(super) fn poll_checking(&mut self) -> Result<()> {
        let Some(c) = self.checking.as_mut() else {
            return Ok(());
        };
        if self.stop.requested().is_some() && c.cancelled.is_none() {
            c.cancelled = Some("the controller is stopping");
        }
        let result = match c.result.try_recv() {
            Ok(r) => r,
            Err(std::sync::mpsc::TryRecvError::Empty) => return Ok(()),
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                Err("the job's check ended without a result".to_string())
            }
        };
        let Some(c) = self.checking.take() else {
            return Ok(());
        };
        let path = c.path;
        let state = self.machine_state();
        let result = match (c.cancelled, result) {
            (Some(why), _) => Err(format!("{path}: {why}; not started")),
            (None, Ok(_)) if state != MachineState::Idle || self.job_active() => Err(format!(
                "{path}: the machine became {state:?} while it was checked; not started"
            )),
            (None, r) => r,
        };
        // an MDI command's errors name its blocks, not the file it was put in
        let result = match (&c.kind, result) {
            (CheckKind::Mdi { .. } | CheckKind::TouchOff { .. }, Err(msg)) => {
                Err(mdi_error(&path, &msg))
            }
            (_, r) => r,
        };
        let reply = match result {
            Err(msg) => {
                self.alarms_pub.send_copy(Alarm {
                    code: AlarmCode::JobRefused.wire(),
                    axis: u32::MAX,
                    process: ProcessId::Mmi.wire(),
                    job_id: 0,
                    time_index: 0,
                    message: FixedStr::truncated(&msg),
                })?;
                Self::reply(false, 0, &msg)
            }
            Ok((job, copy, stats, params, modal)) => {
                let job_id = self
                    .jobs
                    .iter()
                    .map(|j| j.job_id)
                    .max()
                    .unwrap_or(0)
                    .max(self.job_id_floor)
                    + 1;
                let submitted = SystemTime::now()
                    .duration_since(SystemTime::UNIX_EPOCH)
                    .map(|d| d.as_secs())
                    .unwrap_or(0);
                let (mdi, from_line, adaptive_force) = match &c.kind {
                    CheckKind::Job {
                        from_line,
                        adaptive_force,
                    } => (None, *from_line, *adaptive_force),
                    CheckKind::Mdi { text } => (Some(text.clone()), None, false),
                    CheckKind::TouchOff { what } => (Some(what.clone()), None, false),
                };
                // nothing to run (a G10, G92, G5x block, M codes, a touch-off):
                // done here; a dwell takes its time on the machine like a move
                let moves = stats.moves > 0 || stats.duration_s > 0.0;
                self.jobs.push(JobRecord {
                    job_id,
                    path: path.clone(),
                    submitted_unix_s: submitted,
                    outcome: if moves { "running" } else { "completed" }.into(),
                    planned_samples: stats.samples,
                    cycles: 0,
                    planned_path_mm: stats.path_length_mm,
                    path_mm: 0.0,
                    accuracy: Accuracy::default(),
                    notes: Vec::new(),
                    alarms: Vec::new(),
                    program: Some(copy.clone()),
                    sha256: Some(job.sha256.clone()),
                    mdi,
                    from_line,
                    adaptive_force,
                });
                self.save_jobs();
                if !moves {
                    self.save_params(&params)?;
                    self.save_modal(modal);
                    let what = match &c.kind {
                        CheckKind::TouchOff { what } => what.clone(),
                        CheckKind::Mdi { .. } => format!("MDI {job_id}"),
                        CheckKind::Job { .. } => format!("job {job_id}"),
                    };
                    Self::reply(true, job_id, &format!("{what}: done (nothing to move)"))
                } else {
                    self.pending_params = Some((job_id, params, modal));
                    // the feed override is the machine's, not the job's: the job
                    // starts at the one in force (carried here, so a restarted
                    // interpolator knows it)
                    self.send_control_flags(
                        ControlKind::StartJob,
                        job_id,
                        from_line.unwrap_or(0),
                        self.feed_override,
                        if adaptive_force {
                            JOB_ADAPTIVE_FORCE
                        } else {
                            0
                        },
                        &copy,
                    )?;
                    let what = if matches!(c.kind, CheckKind::Job { .. }) {
                        "job"
                    } else {
                        "MDI"
                    };
                    Self::reply(true, job_id, &format!("{what} {job_id} started: {path}"))
                }
            }
        };
        if let Some(req) = c.request {
            // the operator may be gone (timed out): the job stands either way
            let _ = req.send_copy(reply);
        }
        Ok(())
    }
}
