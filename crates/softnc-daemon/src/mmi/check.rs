//! A submitted job (or MDI block, or touch-off) taken in off the loop: read once,
//! copied, checked and planned from where the machine is; started or refused when
//! the check ends.

use super::history::{Accuracy, JobRecord, Outcome};
use super::program::{mdi_error, CheckKind};
use super::{wire_reply, MmiTask, OperatorRequestIn};
use crate::interp::{check_bytes, JobSetup};
use crate::jobfile::{intake, keep_copy, sha256_hex, CheckedSetup, KeptSubroutine};
use anyhow::Result;
use softnc_api::Reply;
use softnc_core::MAX_AXES;
use softnc_ipc::{AlarmCode, ControlKind, FixedStr, MachineState, JOB_ADAPTIVE_FORCE};
use softnc_planner::PlanStats;
use std::path::PathBuf;
use std::time::{Instant, SystemTime};

/// A job that passed its check: its program and the copies kept of it and of its
/// subroutine files, the setup it was checked with, the plan's figures and the
/// parameters and modal state it leaves.
pub(super) struct CheckOk {
    /// The program as read once.
    pub(super) job: crate::jobfile::JobFile,
    /// Its copy.
    pub(super) copy: String,
    /// What it was checked with (its job id set when it is started).
    pub(super) setup: CheckedSetup,
    pub(super) stats: PlanStats,
    pub(super) params: softnc_gcode::Params,
    pub(super) modal: String,
    /// The copies this check made: removed when the job is not started.
    pub(super) created: Vec<PathBuf>,
    /// The job's machine sequencer and its motions' end points, for the status.
    pub(super) sequencer: Option<(
        softnc_planner::machine_sequencer::MachineSequencer,
        softnc_planner::stream::MotionEnds,
    )>,
}

/// What the check of a submitted job gives, or why it is refused.
pub(super) type CheckResult = std::result::Result<CheckOk, String>;

/// The job checks: the one being taken in, and those abandoned after
/// `check_timeout_s` (their path and thread) whose threads may still run: new jobs
/// are refused while `max_abandoned_checks` of them do.
pub(super) struct Checks {
    pub(super) checking: Option<Checking>,
    pub(super) abandoned: Vec<(String, std::thread::JoinHandle<()>)>,
}

impl Checks {
    /// Abandoned checks whose threads still run.
    pub(super) fn abandoned_running(&self) -> usize {
        self.abandoned
            .iter()
            .filter(|(_, t)| !t.is_finished())
            .count()
    }
}

/// A job being taken in (read once, planned from the machine's position) on a
/// thread of its own: the loop goes on serving status, E-stop and heartbeats.
pub(super) struct Checking {
    pub(super) path: String,
    pub(super) kind: CheckKind,
    /// The operator's request, answered when the check ends.
    pub(super) request: Option<OperatorRequestIn>,
    /// The result, handed over when the loop takes it (a rendezvous: once the loop
    /// has let go of it, the thread's hand-over fails and it removes what it kept).
    pub(super) result: std::sync::mpsc::Receiver<CheckResult>,
    /// An E-stop or a stop came while checking: the job is not started.
    pub(super) cancelled: Option<&'static str>,
    /// When the check began (abandoned after `check_timeout_s`).
    pub(super) started: Instant,
    /// The thread.
    pub(super) thread: std::thread::JoinHandle<()>,
}

/// Remove copies a job that is not started made.
pub(super) fn remove_copies(created: &[PathBuf]) {
    for c in created {
        if let Err(e) = std::fs::remove_file(c) {
            tracing::warn!(
                "{}: cannot remove the copy of a job not started: {e}",
                c.display()
            );
        }
    }
}

/// Take a submitted job in: read once (a regular file under `limit`), planned as
/// `setup` says (from where the machine is, with its offsets, subroutine files
/// under the same rules) as the interpolator will plan it, with the parameters it
/// leaves; once it passed, its copy and its subroutine files' copies are kept under
/// `programs`. Runs off the MMI's loop; writes nothing for a refused job.
pub(super) fn check_job(
    path: &str,
    limit: u64,
    programs: &std::path::Path,
    machine: &softnc_machine::MachineProfile,
    setup: &JobSetup,
) -> CheckResult {
    let job = intake(path, limit).map_err(|e| e.to_string())?;
    // checked as it will be streamed: the plan's figures, never the whole plan
    let (text, options, checked, modal, files, _) = check_bytes(&job.bytes, path, machine, setup)?;
    // the machine around the axes as the interpolator will run it (for the status)
    let sequencer = softnc_planner::stream::stream_sequencer_and_ends(
        &text,
        path,
        machine,
        &options,
        crate::plan_samples::sequencer_config(machine),
        // (the status shows the outputs the position process reports; this
        // sequencer gives the tools, the messages and the prompts, the motions'
        // ends the distance to go)
        crate::plan_samples::initial_state(
            options.params.as_ref(),
            softnc_core::machine_io::MachineOutputs::safe(),
        ),
    )
    .ok();
    let params = checked.end_params().clone();
    let mut created = Vec::new();
    let mut keep = |bytes: &[u8], sha: &str| -> std::result::Result<PathBuf, String> {
        let (copy, made) = keep_copy(programs, bytes, sha).map_err(|e| e.to_string())?;
        if made {
            created.push(copy.clone());
        }
        Ok(copy)
    };
    let kept = (|| {
        let copy = keep(&job.bytes, &job.sha256)?.display().to_string();
        if !FixedStr::<512>::fits(&copy) {
            return Err(format!(
                "{copy}: the job's copy has a path over 512 bytes (data_dir too deep)"
            ));
        }
        let subroutines = files
            .iter()
            .map(|f| {
                let sha256 = sha256_hex(&f.bytes);
                Ok(KeptSubroutine {
                    name: f.name.clone(),
                    path: f.path.clone(),
                    copy: keep(&f.bytes, &sha256)?,
                    sha256,
                })
            })
            .collect::<std::result::Result<Vec<_>, String>>()?;
        Ok((copy, subroutines))
    })();
    let (copy, subroutines) = match kept {
        Ok(k) => k,
        Err(e) => {
            remove_copies(&created);
            return Err(e);
        }
    };
    let setup = CheckedSetup {
        job_id: 0,
        program: PathBuf::from(&copy),
        sha256: job.sha256.clone(),
        preamble: setup.preamble.clone(),
        preamble_file: setup.preamble_file.clone(),
        params: setup.params.as_ref().map(|p| p.to_var_text()),
        subroutines,
    };
    Ok(CheckOk {
        job,
        copy,
        setup,
        stats: checked.stats(),
        params,
        modal,
        created,
        sequencer,
    })
}

impl MmiTask {
    /// Read and check a program off the loop ([`Checking`]); answered when done.
    pub(super) fn begin_check(&mut self, path: String, kind: CheckKind) -> Option<Reply> {
        let limit = self.cfg.config.max_job_bytes;
        let programs = self.setup.store.programs_dir();
        let machine = match self.setup.store.profile(&self.cfg.machine) {
            Ok(m) => m,
            Err(e) => return Some(Self::reply(false, 0, &format!("{e}; nothing started"))),
        };
        // planned from where the machine is, with its offsets, as the interpolator
        // will plan it: the parameters as the run reads them back from the job's
        // checked setup (LinuxCNC's text), the modal state, subroutine files under
        // the job's rules
        let params = match self.setup.params.as_ref().map(|p| {
            softnc_gcode::Params::from_var_text(&p.to_var_text(), "the machine's parameters")
        }) {
            None => None,
            Some(Ok(p)) => Some(p),
            Some(Err(e)) => return Some(Self::reply(false, 0, &format!("{e}; nothing started"))),
        };
        let setup = JobSetup {
            start_mm: self
                .machine
                .last
                .map_or([0.0; 3], |s| [s.cmd_mm[0], s.cmd_mm[1], s.cmd_mm[2]]),
            params,
            switches: self.machine.switches,
            from_line: match kind {
                CheckKind::Job { from_line, .. } => from_line,
                _ => None,
            },
            subroutine_path: self.cfg.subroutine_path.clone(),
            user_m_codes: Some(self.cfg.user_m_dir.clone()),
            log_files: self.cfg.gcode_log_dir.is_some(),
            preamble: self.setup.modal.clone(),
            preamble_file: Some(self.setup.store.modal_path().display().to_string()),
            subroutines: softnc_gcode::SubroutineFiles {
                max_bytes: Some(limit),
                snapshot: None,
            },
        };
        // a rendezvous: the result is handed over only to a loop that takes it
        let (tx, rx) = std::sync::mpsc::sync_channel::<CheckResult>(0);
        let job_path = path.clone();
        let spawned = std::thread::Builder::new()
            .name("job-check".into())
            .spawn(move || {
                let r = check_job(&job_path, limit, &programs, &machine, &setup);
                if let Err(std::sync::mpsc::SendError(Ok(abandoned))) = tx.send(r) {
                    // abandoned (too long): nothing of it is kept
                    remove_copies(&abandoned.created);
                }
            });
        let thread = match spawned {
            Ok(t) => t,
            Err(e) => {
                return Some(Self::reply(
                    false,
                    0,
                    &format!("cannot check the job: {e}; job not started"),
                ))
            }
        };
        self.checks.checking = Some(Checking {
            path,
            kind,
            request: None,
            result: rx,
            cancelled: None,
            started: Instant::now(),
            thread,
        });
        None
    }

    /// The end of a job's check: start it (its record, the interpolator told) or
    /// refuse it, and answer the operator who submitted it.
    pub(super) fn poll_checking(&mut self) -> Result<()> {
        let Some(c) = self.checks.checking.as_mut() else {
            return Ok(());
        };
        if self.stop.requested().is_some() && c.cancelled.is_none() {
            c.cancelled = Some("the controller is stopping");
        }
        let timeout_s = self.cfg.config.check_timeout_s;
        let result = match c.result.try_recv() {
            Ok(r) => r,
            Err(std::sync::mpsc::TryRecvError::Empty)
                if c.started.elapsed().as_secs_f64() <= timeout_s =>
            {
                return Ok(())
            }
            Err(std::sync::mpsc::TryRecvError::Empty) => {
                // too long (a file that blocks, a program that takes for ever): the
                // thread cannot be stopped; it is let go (its result, should it come,
                // is dropped with what it kept) and the job refused
                Err(format!(
                    "{}: the check took longer than {timeout_s} s (check_timeout_s) and was abandoned; job not started",
                    c.path
                ))
            }
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                Err("the job's check ended without a result".to_string())
            }
        };
        let Some(c) = self.checks.checking.take() else {
            return Ok(());
        };
        let Checking {
            path,
            kind,
            request,
            result: receiver,
            cancelled,
            thread,
            ..
        } = c;
        // from here on a late result cannot be handed over (the rendezvous fails)
        drop(receiver);
        if !thread.is_finished() {
            self.checks.abandoned.push((path.clone(), thread));
        }
        let state = self.machine_state();
        let not_started = match (cancelled, &result) {
            (Some(why), _) => Some(format!("{path}: {why}; not started")),
            (None, Ok(_)) if state != MachineState::Idle || self.job_active() => Some(format!(
                "{path}: the machine became {state:?} while it was checked; not started"
            )),
            (None, _) => None,
        };
        let result = match (not_started, result) {
            (Some(why), Ok(ok)) => {
                // a refused job keeps no copy
                remove_copies(&ok.created);
                Err(why)
            }
            (Some(why), Err(_)) => Err(why),
            (None, r) => r,
        };
        // an MDI command's errors name its blocks, not the file it was put in
        let result = match (&kind, result) {
            (CheckKind::Mdi { .. } | CheckKind::TouchOff { .. }, Err(msg)) => {
                Err(mdi_error(&path, &msg))
            }
            (_, r) => r,
        };
        let reply = match result {
            Err(msg) => self.refuse_job(&msg)?,
            Ok(ok) => match self.start_checked(ok, &kind, &path)? {
                Ok(reply) => reply,
                Err(msg) => self.refuse_job(&msg)?,
            },
        };
        super::oplog::checked(kind.request_name(), &path, &reply);
        if let Some(req) = request {
            // the operator may be gone (timed out): the job stands either way
            let _ = req.send_copy(wire_reply(&reply, kind.request_name()));
        }
        Ok(())
    }

    /// A refused job: the alarm, and the reply.
    fn refuse_job(&mut self, msg: &str) -> Result<Reply> {
        self.raise(AlarmCode::JobRefused, msg)?;
        Ok(Self::reply(false, 0, msg))
    }

    /// Start a job that passed its check: its checked setup kept, its record, the
    /// interpolator told (or done at once when it moves nothing). `Err`: why it is
    /// not started after all (its copies then removed).
    #[allow(clippy::too_many_lines)]
    fn start_checked(
        &mut self,
        ok: CheckOk,
        kind: &CheckKind,
        path: &str,
    ) -> Result<std::result::Result<Reply, String>> {
        let CheckOk {
            job,
            copy,
            mut setup,
            stats,
            params,
            modal,
            created,
            sequencer,
        } = ok;
        let job_id = self
            .history
            .jobs
            .iter()
            .map(|j| j.job_id)
            .max()
            .unwrap_or(0)
            .max(self.history.job_id_floor)
            + 1;
        // nothing to run (a G10, G92, G5x block, a touch-off): done here; a dwell
        // takes its time on the machine like a move, and machine operations (M3,
        // M8, M62, T, a message, a program end's spindle stop, …) are done there
        let moves = stats.moves > 0
            || stats.duration_s > 0.0
            || sequencer.as_ref().is_some_and(|s| s.0.has_operations());
        if moves {
            // what the run reads the job with: what it was checked with
            setup.job_id = job_id;
            if let Err(e) = setup.save(&self.setup.store.programs_dir()) {
                remove_copies(&created);
                return Ok(Err(format!("{path}: {e}; job not started")));
            }
        }
        let submitted = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map(|d| d.as_secs())
            .unwrap_or(0);
        let (mdi, from_line, adaptive_force) = match kind {
            CheckKind::Job {
                from_line,
                adaptive_force,
            } => (None, *from_line, *adaptive_force),
            CheckKind::Mdi { text } => (Some(text.clone()), None, false),
            CheckKind::TouchOff { what } => (Some(what.clone()), None, false),
        };
        self.history.jobs.push(JobRecord {
            job_id,
            path: path.to_string(),
            submitted_unix_s: submitted,
            outcome: if moves {
                Outcome::Running
            } else {
                Outcome::Completed
            },
            planned_samples: stats.samples,
            cycles: 0,
            planned_path_mm: stats.path_length_mm,
            path_mm: 0.0,
            accuracy: Accuracy {
                following_max_abs_um: vec![0.0; MAX_AXES],
                ..Accuracy::default()
            },
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
            let what = match kind {
                CheckKind::TouchOff { what } => what.clone(),
                CheckKind::Mdi { .. } => format!("MDI {job_id}"),
                CheckKind::Job { .. } => format!("job {job_id}"),
            };
            return Ok(Ok(Self::reply(
                true,
                job_id,
                &format!("{what}: done (nothing to move)"),
            )));
        }
        self.setup.pending_params = Some((job_id, params, modal));
        self.job_machine = sequencer.map(|(s, ends)| (job_id, s, ends));
        // the feed override is the machine's, not the job's: the job starts at the
        // one in force (carried here, so a restarted interpolator knows it)
        self.send_control_flags(
            ControlKind::StartJob,
            job_id,
            from_line.unwrap_or(0),
            self.machine.feed_override,
            if adaptive_force {
                JOB_ADAPTIVE_FORCE
            } else {
                0
            },
            &copy,
        )?;
        self.machine.start_sent = Some((job_id, self.ports.control_seq));
        let what = if matches!(kind, CheckKind::Job { .. }) {
            "job"
        } else {
            "MDI"
        };
        Ok(Ok(Self::reply(
            true,
            job_id,
            &format!("{what} {job_id} started: {path}"),
        )))
    }
}
