//! End-to-end test of the operator contract: a client written only against
//! `softnc-api` (its requests, replies, status and job records) and the client crate
//! `softnc-client` drives a job from submit to its completed record, on a controller
//! whose history is long enough to come in several pages. The harness only starts
//! and stops the controller.

mod support;

use std::time::Instant;

/// The operator's side, with nothing but `softnc-api` and `softnc-client`: the
/// machine on, the program submitted, followed until its record says how it ended,
/// and the whole history read back page by page.
mod client {
    use softnc_api::{JobRecord, MachineState, Outcome, ProcessHealth, Reply, Request, Status};
    use softnc_client::Operator;
    use std::path::Path;
    use std::time::{Duration, Instant};

    /// Poll the status until `pred` holds (or panic after `timeout`).
    fn wait(
        op: &Operator,
        timeout: Duration,
        what: &str,
        pred: impl Fn(&Status) -> bool,
    ) -> Status {
        let t0 = Instant::now();
        loop {
            let s = op.status().expect("the status answers");
            if pred(&s) {
                return s;
            }
            assert!(t0.elapsed() < timeout, "timed out waiting for {what}: {s}");
            std::thread::sleep(Duration::from_millis(25));
        }
    }

    /// Drive the program `path` from submit to its end: the job's record as the
    /// status shows it at the end, and the history (all pages) after it.
    pub fn run_job(config: &Path, path: &str) -> (JobRecord, Vec<JobRecord>) {
        let op = Operator::wait_ready(config, Duration::from_secs(30)).expect("MMI answers");
        let s = op.status().unwrap();
        assert_eq!(s.api_version, softnc_api::API_VERSION);
        assert_eq!(s.processes.interp, ProcessHealth::Alive);
        if s.state == MachineState::Off {
            let r = op.request(&Request::MachineOn).unwrap();
            assert!(matches!(r, Reply::Accepted { .. }), "{r:?}");
        }
        wait(&op, Duration::from_secs(20), "the machine idle", |s| {
            s.state == MachineState::Idle && s.machine_mm.is_some()
        });
        let r = op
            .request(&Request::SubmitJob {
                path: path.to_string(),
                from_line: None,
                adaptive_force: false,
            })
            .unwrap();
        let Reply::Accepted {
            job_id: Some(job_id),
            message,
        } = r
        else {
            panic!("the job was not accepted: {r:?}")
        };
        assert!(message.contains("started"), "{message}");
        // while it runs: the state, the job shown, its progress
        let running = wait(&op, Duration::from_secs(30), "the job running", |s| {
            s.job(job_id)
                .is_some_and(|j| j.record.outcome != Outcome::Running || j.record.cycles > 0)
        });
        let shown = running.job(job_id).unwrap();
        assert!((0.0..=1.0).contains(&shown.progress), "{running}");
        let end = wait(&op, Duration::from_secs(60), "the job's end", |s| {
            s.job(job_id).is_some_and(|j| j.record.outcome.ended())
        });
        let job = end.job(job_id).unwrap();
        assert_eq!(job.progress, 1.0, "{end}");
        // a request the machine refuses now says why, typed
        let r = op.request(&Request::Resume).unwrap();
        assert!(
            matches!(&r, Reply::Refused { reason } if reason.contains("nothing is held")),
            "{r:?}"
        );
        let history = op.jobs().expect("the job history");
        (job.record.clone(), history)
    }
}

#[test]
fn a_client_of_softnc_api_alone_drives_a_job_from_submit_to_its_completed_record() {
    // a history long enough that it comes back in several pages
    let old = 60;
    let d = support::Daemon::start_with_history("api", old, 120);
    let program = support::short_job(&d.dir);
    let path = std::fs::canonicalize(&program).unwrap();
    let t0 = Instant::now();
    let (record, history) = client::run_job(&d.config, &path.display().to_string());
    assert_eq!(record.outcome, softnc_api::Outcome::Completed, "{record}");
    assert_eq!(record.path, path.display().to_string());
    assert!(record.cycles > 0 && record.planned_samples > 0, "{record}");
    assert!(record.planned_path_mm > 0.0, "{record}");
    assert_eq!(record.accuracy.following_max_abs_um.len(), 3, "{record}");
    assert!(
        record.sha256.is_some() && record.program.is_some(),
        "{record}"
    );
    // the whole history, newest first: this job, then the old records as written
    // before it (their outcome a string in jobs.json, read as an Outcome)
    assert_eq!(history.len() as u64, old + 1);
    assert_eq!(history[0].job_id, record.job_id);
    assert_eq!(history[0].outcome, softnc_api::Outcome::Completed);
    assert!(history[1..]
        .iter()
        .all(|j| j.outcome == softnc_api::Outcome::Completed && j.path.len() == 120));
    let ids: Vec<u64> = history[1..].iter().map(|j| j.job_id).collect();
    let want: Vec<u64> = (1..=old).rev().collect();
    assert_eq!(ids, want, "every old record once, newest first");
    assert!(record.job_id > old, "job ids go on after the history's");
    // more than one page: one reply holds a part of it
    let page_bytes = serde_json::to_string(&history).unwrap().len();
    assert!(
        page_bytes > softnc_ipc::OperatorReply::MESSAGE_CAPACITY,
        "the history ({page_bytes} bytes) should need several pages"
    );
    // the record the MMI keeps on disk reads as the same type
    let kept = d
        .job_record(record.job_id)
        .expect("the record in jobs.json");
    assert_eq!(kept.outcome, softnc_api::Outcome::Completed);
    eprintln!(
        "job {} completed in {:.1} s; history of {} records read",
        record.job_id,
        t0.elapsed().as_secs_f64(),
        history.len()
    );
}
