//! The panel's only way to the controller: `softnc-client` [`Operator`]s, each on a
//! thread of its own (the client blocks; an iceoryx2 node stays on its thread).
//!
//! - the status thread asks for the status at the configured rate and publishes it
//!   (and the job history, when a job changes) on watch channels, the link's loss
//!   included: a page never takes an old status for a live one;
//! - three command lanes, so that one waiting request does not hold another back:
//!   commands (a job's check takes a while), jogs (renewed every 25 ms) and the
//!   E-stop (its own, never behind anything).

use serde_json::json;
use softnc_api::{Outcome, Reply, Request};
use softnc_client::Operator;
use std::path::Path;
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};
use tokio::sync::{oneshot, watch};

/// How long a lane or the status thread waits before connecting again after its
/// request failed (the MMI restarting, not yet up).
const RECONNECT_DELAY: Duration = Duration::from_millis(200);

/// How often the job history is asked for again while nothing changes (s).
const JOBS_REFRESH: Duration = Duration::from_secs(2);

/// One request waiting for its lane.
struct Pending {
    request: Request,
    reply: oneshot::Sender<Result<Reply, String>>,
}

/// Which lane a request takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lane {
    /// Everything but jogs and the E-stop.
    Command,
    /// Continuous and step jogs.
    Jog,
    /// The E-stop.
    EStop,
}

/// The panel's connection to the MMI.
pub struct Link {
    command: mpsc::Sender<Pending>,
    jog: mpsc::Sender<Pending>,
    estop: mpsc::Sender<Pending>,
    /// The latest status message (JSON text, as sent to the pages).
    pub status: watch::Receiver<String>,
    /// The latest job history message (JSON text).
    pub jobs: watch::Receiver<String>,
}

impl Link {
    /// Start the status thread (at `status_hz`) and the lanes on the configuration
    /// `config`.
    pub fn start(config: &Path, status_hz: f64) -> Link {
        let lane = |name: &str| {
            let (tx, rx) = mpsc::channel::<Pending>();
            let config = config.to_path_buf();
            std::thread::Builder::new()
                .name(format!("lane-{name}"))
                .spawn(move || serve_lane(&config, &rx))
                .expect("spawning a lane thread");
            tx
        };
        let lost = status_message_lost("not connected yet");
        let (status_tx, status) = watch::channel(lost);
        let (jobs_tx, jobs) = watch::channel(json!({"t": "jobs", "jobs": []}).to_string());
        let period = Duration::from_secs_f64(1.0 / status_hz);
        let config_path = config.to_path_buf();
        std::thread::Builder::new()
            .name("status".into())
            .spawn(move || poll_status(&config_path, period, &status_tx, &jobs_tx))
            .expect("spawning the status thread");
        Link {
            command: lane("command"),
            jog: lane("jog"),
            estop: lane("estop"),
            status,
            jobs,
        }
    }

    /// Send `request` on its lane and wait for the reply (an error: no MMI
    /// answered, or the lane is gone).
    pub async fn request(&self, request: Request) -> Result<Reply, String> {
        let lane = match request {
            Request::EStop => Lane::EStop,
            Request::Jog { .. } | Request::JogStep { .. } => Lane::Jog,
            _ => Lane::Command,
        };
        let tx = match lane {
            Lane::Command => &self.command,
            Lane::Jog => &self.jog,
            Lane::EStop => &self.estop,
        };
        let (reply, rx) = oneshot::channel();
        tx.send(Pending { request, reply })
            .map_err(|_| "the panel's link to the MMI is gone".to_string())?;
        rx.await
            .map_err(|_| "the panel's link to the MMI is gone".to_string())?
    }
}

/// A lane: one operator connection, one request at a time; connects again after a
/// failure.
fn serve_lane(config: &Path, rx: &mpsc::Receiver<Pending>) {
    let mut op: Option<Operator> = None;
    while let Ok(p) = rx.recv() {
        if op.is_none() {
            op = Operator::connect(config)
                .map_err(|e| tracing::warn!("connecting to the MMI: {e:#}"))
                .ok();
        }
        let result = match &op {
            Some(o) => o.request(&p.request).map_err(|e| format!("{e:#}")),
            None => Err("no connection to the controller (is softncd running?)".to_string()),
        };
        if result.is_err() {
            op = None;
        }
        let _ = p.reply.send(result);
    }
}

/// The status message of a lost link: no figures, only why.
fn status_message_lost(why: &str) -> String {
    json!({"t": "status", "link": "lost", "error": why, "unix_ms": unix_ms()}).to_string()
}

/// Now in milliseconds since the Unix epoch.
fn unix_ms() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as u64)
}

/// The status thread: ask, publish, at `period`; the job history when the job shown
/// changes (and every [`JOBS_REFRESH`]).
fn poll_status(
    config: &Path,
    period: Duration,
    status_tx: &watch::Sender<String>,
    jobs_tx: &watch::Sender<String>,
) {
    let mut op: Option<Operator> = None;
    let mut seq: u64 = 0;
    let mut last_job: Option<(u64, Outcome)> = None;
    let mut last_jobs_at: Option<Instant> = None;
    let mut next = Instant::now();
    loop {
        next += period;
        if op.is_none() {
            match Operator::connect(config) {
                Ok(o) => op = Some(o),
                Err(e) => {
                    let _ = status_tx.send(status_message_lost(&format!("{e:#}")));
                    std::thread::sleep(RECONNECT_DELAY);
                    next = Instant::now();
                    continue;
                }
            }
        }
        let Some(o) = op.as_ref() else { continue };
        match o.status() {
            Ok(s) => {
                seq += 1;
                let job = s.job.as_ref().map(|j| (j.record.job_id, j.record.outcome));
                let text =
                    json!({"t": "status", "link": "ok", "seq": seq, "unix_ms": unix_ms(), "status": s})
                        .to_string();
                let _ = status_tx.send(text);
                let due = last_jobs_at.is_none_or(|t| t.elapsed() >= JOBS_REFRESH);
                if job != last_job || due {
                    match o.request(&Request::Jobs { offset: 0 }) {
                        Ok(Reply::Jobs(page)) => {
                            let _ = jobs_tx.send(
                                json!({"t": "jobs", "total": page.total, "jobs": page.jobs})
                                    .to_string(),
                            );
                            last_job = job;
                            last_jobs_at = Some(Instant::now());
                        }
                        Ok(other) => tracing::warn!("job history: {}", other.message()),
                        Err(e) => tracing::warn!("job history: {e:#}"),
                    }
                }
            }
            Err(e) => {
                let _ = status_tx.send(status_message_lost(&format!("{e:#}")));
                op = None;
                std::thread::sleep(RECONNECT_DELAY);
                next = Instant::now();
                continue;
            }
        }
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
    }
}
