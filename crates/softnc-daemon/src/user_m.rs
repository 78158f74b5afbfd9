//! User M codes (M100–M199) as LinuxCNC runs them: the executable file `M1nn` of
//! the user M-code folder (`DaemonConfig::user_m_path`, LinuxCNC's
//! `[RS274NGC]USER_M_PATH`), started with P and Q as two arguments formatted `%f`
//! (`emctask.cc` `user_defined_add_m_code`: `"dir/M1%02d %f %f"`), while the path
//! stands at the M code; exit status 0 lets the path go on, anything else stops
//! the job (`emctaskmain.cc`, `WAITING_FOR_SYSTEM_CMD`: a non-zero exit is an
//! error).
//!
//! The interpolation loop must not spawn or wait for a process: it pushes a
//! [`Request`] onto a lock-free queue and reads [`Report`]s from another
//! ([`UserMRunner::request`], [`UserMRunner::report`]: no allocation, no lock,
//! no system call); a thread of its own, off the real-time path, starts the
//! executable, polls it and kills it when asked to ([`Request::Cancel`]: the job's
//! timeout, abort or end) or when it outlives the configured timeout.

use crossbeam_queue::ArrayQueue;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Requests in flight at most (the loop has one user M code at a time).
const QUEUE_CAPACITY: usize = 8;
/// How often the runner looks at its queue and its child.
const POLL_PERIOD: Duration = Duration::from_millis(2);

/// What the interpolation loop asks of the runner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// Run `M{code}` with `p` and `q`; reported under `ticket`.
    Run {
        /// Which request (increasing).
        ticket: u64,
        /// 100..=199.
        code: u8,
        /// P (−1 when not given).
        p: f64,
        /// Q (−1 when not given).
        q: f64,
    },
    /// Kill the executable of `ticket` if it still runs (reported as
    /// [`Outcome::Killed`]).
    Cancel {
        /// Which request.
        ticket: u64,
    },
}

/// How a user M code ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// It exited with this status (0: done).
    Exited(i32),
    /// It could not be started (no such file, not executable, …).
    NotStarted,
    /// It was killed: cancelled, or past the timeout, or ended by a signal.
    Killed,
}

impl Outcome {
    /// The exit status the sequencer gets (`Feedback::user_command_failed`):
    /// the status, −1 where there is none.
    pub fn status(self) -> i32 {
        match self {
            Outcome::Exited(s) => s,
            Outcome::NotStarted | Outcome::Killed => -1,
        }
    }
}

/// One request's end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Report {
    /// The request's ticket.
    pub ticket: u64,
    /// How it ended.
    pub outcome: Outcome,
}

/// The runner thread and its two queues.
pub struct UserMRunner {
    requests: Arc<ArrayQueue<Request>>,
    reports: Arc<ArrayQueue<Report>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl UserMRunner {
    /// Start the runner for the executables of `dir`, each killed after
    /// `timeout_s`.
    pub fn start(dir: PathBuf, timeout_s: f64) -> std::io::Result<Self> {
        let requests = Arc::new(ArrayQueue::new(QUEUE_CAPACITY));
        let reports = Arc::new(ArrayQueue::new(QUEUE_CAPACITY));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (requests, reports, stop) = (requests.clone(), reports.clone(), stop.clone());
            let timeout = Duration::from_secs_f64(timeout_s.max(0.0));
            std::thread::Builder::new()
                .name("user-m".into())
                .spawn(move || run(&dir, timeout, &requests, &reports, &stop))?
        };
        Ok(UserMRunner {
            requests,
            reports,
            stop,
            thread: Some(thread),
        })
    }

    /// Ask the runner (from the cycle: lock-free, allocation-free). `false`: the
    /// queue is full.
    pub fn request(&self, r: Request) -> bool {
        self.requests.push(r).is_ok()
    }

    /// The next report, if any (from the cycle).
    pub fn report(&self) -> Option<Report> {
        self.reports.pop()
    }
}

impl Drop for UserMRunner {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The runner thread: one executable at a time, in request order.
fn run(
    dir: &std::path::Path,
    timeout: Duration,
    requests: &ArrayQueue<Request>,
    reports: &ArrayQueue<Report>,
    stop: &AtomicBool,
) {
    let mut child: Option<(u64, std::process::Child, Instant)> = None;
    let report = |ticket: u64, outcome: Outcome| {
        tracing::info!(ticket, ?outcome, "user M code ended");
        // (a report the loop no longer waits for may be dropped)
        let _ = reports.force_push(Report { ticket, outcome });
    };
    while !stop.load(Ordering::Relaxed) {
        while let Some(r) = requests.pop() {
            match r {
                Request::Run { ticket, code, p, q } => {
                    if let Some((t, mut c, _)) = child.take() {
                        let _ = c.kill();
                        let _ = c.wait();
                        report(t, Outcome::Killed);
                    }
                    let path = dir.join(format!("M{code}"));
                    tracing::info!(ticket, path = %path.display(), p, q, "user M code started");
                    match std::process::Command::new(&path)
                        .arg(format!("{p:.6}"))
                        .arg(format!("{q:.6}"))
                        .stdin(std::process::Stdio::null())
                        .spawn()
                    {
                        Ok(c) => child = Some((ticket, c, Instant::now())),
                        Err(e) => {
                            tracing::warn!(path = %path.display(), "user M code not started: {e}");
                            report(ticket, Outcome::NotStarted);
                        }
                    }
                }
                Request::Cancel { ticket } => {
                    if let Some((_, mut c, _)) = child.take_if(|(t, _, _)| *t == ticket) {
                        let _ = c.kill();
                        let _ = c.wait();
                        report(ticket, Outcome::Killed);
                    }
                }
            }
        }
        if let Some((ticket, c, started)) = child.as_mut() {
            match c.try_wait() {
                Ok(Some(status)) => {
                    let outcome = status.code().map_or(Outcome::Killed, Outcome::Exited);
                    report(*ticket, outcome);
                    child = None;
                }
                Ok(None) if started.elapsed() >= timeout => {
                    let _ = c.kill();
                    let _ = c.wait();
                    report(*ticket, Outcome::Killed);
                    child = None;
                }
                Ok(None) => {}
                Err(_) => {
                    report(*ticket, Outcome::Killed);
                    child = None;
                }
            }
        }
        std::thread::sleep(POLL_PERIOD);
    }
    if let Some((_, mut c, _)) = child {
        let _ = c.kill();
        let _ = c.wait();
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn script(dir: &std::path::Path, name: &str, body: &str) {
        let p = dir.join(name);
        std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    fn wait_report(r: &UserMRunner) -> Report {
        let t = Instant::now();
        loop {
            if let Some(rep) = r.report() {
                return rep;
            }
            assert!(t.elapsed() < Duration::from_secs(10), "no report");
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    #[test]
    fn runs_with_p_and_q_reports_the_status_and_kills_on_cancel_or_timeout() {
        let dir = std::env::temp_dir().join(format!("softnc-user-m-run-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("args");
        script(&dir, "M101", &format!("echo \"$1 $2\" > {}", out.display()));
        script(&dir, "M102", "exit 3");
        script(&dir, "M103", "sleep 30");
        let r = UserMRunner::start(dir.clone(), 0.5).unwrap();
        let run = |ticket, code| Request::Run {
            ticket,
            code,
            p: 2.0,
            q: -1.0,
        };
        assert!(r.request(run(1, 101)));
        assert_eq!(
            wait_report(&r),
            Report {
                ticket: 1,
                outcome: Outcome::Exited(0)
            }
        );
        // LinuxCNC's "%f %f"
        assert_eq!(
            std::fs::read_to_string(&out).unwrap(),
            "2.000000 -1.000000\n"
        );
        assert!(r.request(run(2, 102)));
        assert_eq!(
            wait_report(&r),
            Report {
                ticket: 2,
                outcome: Outcome::Exited(3)
            }
        );
        assert!(r.request(run(3, 199)));
        assert_eq!(
            wait_report(&r),
            Report {
                ticket: 3,
                outcome: Outcome::NotStarted
            }
        );
        // cancelled at once
        let t = Instant::now();
        assert!(r.request(run(4, 103)));
        assert!(r.request(Request::Cancel { ticket: 4 }));
        assert_eq!(
            wait_report(&r),
            Report {
                ticket: 4,
                outcome: Outcome::Killed
            }
        );
        // past the timeout
        assert!(r.request(run(5, 103)));
        assert_eq!(
            wait_report(&r),
            Report {
                ticket: 5,
                outcome: Outcome::Killed
            }
        );
        assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
        drop(r);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
