//! The HTTP side: the page, the read-only API, the commands (POST and the
//! WebSocket, never a GET), the token and the origin checks, the uploads.

use crate::link::Link;
use crate::programs::{Programs, UploadError};
use axum::body::{Body, Bytes};
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{DefaultBodyLimit, Path as UrlPath, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;
use serde_json::json;
use sha2::{Digest, Sha256};
use softnc_api::{Axis, Reply, Request};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

/// The page and its assets, built into the binary.
const INDEX_HTML: &str = include_str!("assets/index.html");
const APP_JS: &str = include_str!("assets/app.js");
const STYLE_CSS: &str = include_str!("assets/style.css");

/// A continuous jog stops when the page has sent nothing about it for this long (the
/// page renews a held jog every 50 ms): the panel's dead-man, before the MMI's own.
const JOG_QUIET: Duration = Duration::from_millis(150);

/// How often a held continuous jog is renewed to the MMI (its renewal period).
const JOG_RENEW: Duration = softnc_api::JOG_RENEW_PERIOD;

/// The largest message a page may send over the WebSocket (bytes; MDI blocks fit).
const WS_MAX_MESSAGE_BYTES: usize = 64 << 10;

/// What every handler shares.
pub struct App {
    /// The connection to the MMI.
    pub link: Link,
    /// The uploaded programs.
    pub programs: Programs,
    /// The operator token's file.
    pub token_file: PathBuf,
    /// Reading (status, programs, history) needs the token too.
    pub status_needs_token: bool,
    /// The daemon's data directory (the jobs' traces).
    pub data_dir: PathBuf,
}

/// Why a request is not served: its HTTP status and the reason.
type Refusal = (StatusCode, String);

impl App {
    /// The operator token (`None`: its file is missing, unreadable or empty: every
    /// command is refused).
    fn token(&self) -> Option<String> {
        let text = std::fs::read_to_string(&self.token_file).ok()?;
        let t = text.trim();
        (!t.is_empty()).then(|| t.to_string())
    }

    /// Whether `given` is the operator token (compared as hashes, in constant time
    /// over the digest).
    fn token_matches(&self, given: &str) -> bool {
        let Some(token) = self.token() else {
            return false;
        };
        let (a, b) = (
            Sha256::digest(token.as_bytes()),
            Sha256::digest(given.as_bytes()),
        );
        a.iter()
            .zip(b.iter())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
    }

    /// A command's request must carry the token (`Authorization: Bearer …`): 401
    /// without, 403 with a wrong one.
    fn operator(&self, headers: &HeaderMap) -> Result<(), Refusal> {
        let Some(value) = headers.get(header::AUTHORIZATION) else {
            return Err((
                StatusCode::UNAUTHORIZED,
                "the operator token is needed for every command".into(),
            ));
        };
        let given = value
            .to_str()
            .ok()
            .and_then(|v| v.strip_prefix("Bearer "))
            .unwrap_or("");
        if self.token_matches(given.trim()) {
            Ok(())
        } else {
            Err((StatusCode::FORBIDDEN, "wrong operator token".into()))
        }
    }

    /// A read: open, or the token when the configuration says so.
    fn reader(&self, headers: &HeaderMap) -> Result<(), Refusal> {
        if self.status_needs_token {
            self.operator(headers)
        } else {
            Ok(())
        }
    }
}

/// The router.
pub fn router(app: Arc<App>) -> Router {
    let upload_limit = usize::try_from(app.programs.limit_bytes()).unwrap_or(usize::MAX);
    Router::new()
        .route("/", get(index))
        .route("/app.js", get(app_js))
        .route("/style.css", get(style_css))
        .route("/api/status", get(status))
        .route("/api/jobs", get(jobs))
        .route("/api/jobs/{id}/trace", get(job_trace))
        .route("/api/programs", get(list_programs).post(upload))
        .route("/api/programs/{id}", get(program_text))
        .route("/api/command", post(command))
        .route("/api/run", post(run))
        .route("/ws", get(ws))
        .layer(DefaultBodyLimit::max(upload_limit))
        .with_state(app)
}

async fn index() -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        INDEX_HTML,
    )
        .into_response()
}

async fn app_js() -> Response {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        APP_JS,
    )
        .into_response()
}

async fn style_css() -> Response {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        STYLE_CSS,
    )
        .into_response()
}

/// A JSON body with the right type.
fn json_text(text: String) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], text).into_response()
}

/// A refusal as JSON `{"ok": false, "message": …}`.
fn refuse((code, message): Refusal) -> Response {
    (code, Json(json!({"ok": false, "message": message}))).into_response()
}

/// The latest status message (`link: "lost"` while the MMI does not answer).
async fn status(State(app): State<Arc<App>>, headers: HeaderMap) -> Response {
    if let Err(r) = app.reader(&headers) {
        return refuse(r);
    }
    let text = app.link.status.borrow().clone();
    json_text(text)
}

/// The job history's newest page.
async fn jobs(State(app): State<Arc<App>>, headers: HeaderMap) -> Response {
    if let Err(r) = app.reader(&headers) {
        return refuse(r);
    }
    let text = app.link.jobs.borrow().clone();
    json_text(text)
}

/// A job's trace, thinned for the plot ([`crate::trace`]); 404 without one.
async fn job_trace(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    UrlPath(id): UrlPath<String>,
) -> Response {
    if let Err(r) = app.reader(&headers) {
        return refuse(r);
    }
    let Ok(job_id) = id.parse::<u64>() else {
        return refuse((StatusCode::BAD_REQUEST, format!("{id:?} is not a job id")));
    };
    let dir = app.data_dir.clone();
    match tokio::task::spawn_blocking(move || crate::trace::read(&dir, job_id)).await {
        Ok(Ok(t)) => Json(t).into_response(),
        Ok(Err(e @ crate::trace::TraceError::Missing { .. })) => {
            refuse((StatusCode::NOT_FOUND, e.to_string()))
        }
        Ok(Err(e)) => refuse((StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
        Err(e) => refuse((StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
    }
}

async fn list_programs(State(app): State<Arc<App>>, headers: HeaderMap) -> Response {
    if let Err(r) = app.reader(&headers) {
        return refuse(r);
    }
    Json(json!({"programs": app.programs.list()})).into_response()
}

async fn program_text(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    UrlPath(id): UrlPath<String>,
) -> Response {
    if let Err(r) = app.reader(&headers) {
        return refuse(r);
    }
    match app.programs.path(&id) {
        Some(p) => match tokio::fs::read_to_string(&p).await {
            Ok(text) => {
                ([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], text).into_response()
            }
            Err(e) => refuse((StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
        },
        None => refuse((StatusCode::NOT_FOUND, "no such program".into())),
    }
}

/// A request from another site's page (its `Origin` not this host): refused.
fn cross_origin(headers: &HeaderMap) -> Option<Refusal> {
    let origin = headers.get(header::ORIGIN)?.to_str().unwrap_or("");
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .unwrap_or("");
    let same = origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
        .is_some_and(|o| !host.is_empty() && o == host);
    (!same).then(|| {
        (
            StatusCode::FORBIDDEN,
            format!("cross-origin request from {origin:?} refused"),
        )
    })
}

/// Upload a program: the token, a size within the limit, text only; stored under a
/// name the panel makes (`X-File-Name` is a label).
async fn upload(State(app): State<Arc<App>>, headers: HeaderMap, body: Body) -> Response {
    if let Some(r) = cross_origin(&headers) {
        return refuse(r);
    }
    if let Err(r) = app.operator(&headers) {
        return refuse(r);
    }
    let limit = app.programs.limit_bytes();
    let declared = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    if let Some(n) = declared.filter(|n| *n > limit) {
        return refuse((
            StatusCode::PAYLOAD_TOO_LARGE,
            UploadError::TooLarge { bytes: n, limit }.to_string(),
        ));
    }
    let bytes: Bytes =
        match axum::body::to_bytes(body, usize::try_from(limit).unwrap_or(usize::MAX)).await {
            Ok(b) => b,
            Err(_) => {
                return refuse((
                    StatusCode::PAYLOAD_TOO_LARGE,
                    format!("the program is over the {limit} bytes the panel takes"),
                ))
            }
        };
    let name = headers
        .get("x-file-name")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("program.ngc")
        .to_string();
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    match app.programs.store(&name, &bytes, now) {
        Ok(p) => Json(json!({"ok": true, "program": p})).into_response(),
        Err(e @ UploadError::TooLarge { .. }) => {
            refuse((StatusCode::PAYLOAD_TOO_LARGE, e.to_string()))
        }
        Err(e @ (UploadError::NotText(_) | UploadError::Empty)) => {
            refuse((StatusCode::UNSUPPORTED_MEDIA_TYPE, e.to_string()))
        }
        Err(e @ UploadError::Io(_)) => refuse((StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
    }
}

/// Whether the panel passes `request` on as a plain command (a job runs by program
/// id, a continuous jog only over the WebSocket with its dead-man, no shutdown).
fn plain_command(request: &Request) -> Result<(), String> {
    match request {
        Request::SubmitJob { .. } => Err("a program runs by its id (upload it, then run)".into()),
        Request::Shutdown => Err("the panel does not shut the controller down".into()),
        Request::Jog { .. } => {
            Err("a continuous jog goes over the WebSocket (its dead-man needs it)".into())
        }
        _ => Ok(()),
    }
}

/// The reply of a command as JSON.
fn reply_json(id: Option<u64>, result: Result<Reply, String>) -> serde_json::Value {
    match result {
        Ok(r) => json!({"t": "reply", "id": id, "ok": r.is_accepted(), "message": r.message(),
            "reply": r}),
        Err(e) => json!({"t": "reply", "id": id, "ok": false, "message": e}),
    }
}

/// A command over HTTP: `POST /api/command` with a `softnc-api` request.
async fn command(State(app): State<Arc<App>>, headers: HeaderMap, body: Bytes) -> Response {
    if let Some(r) = cross_origin(&headers) {
        return refuse(r);
    }
    if let Err(r) = app.operator(&headers) {
        return refuse(r);
    }
    let request: Request = match serde_json::from_slice(&body) {
        Ok(r) => r,
        Err(e) => return refuse((StatusCode::BAD_REQUEST, format!("not a request: {e}"))),
    };
    if let Err(e) = plain_command(&request) {
        return refuse((StatusCode::BAD_REQUEST, e));
    }
    let r = app.link.request(request).await;
    Json(reply_json(None, r)).into_response()
}

/// What runs a stored program.
#[derive(Debug, Deserialize)]
struct RunProgram {
    program: String,
    #[serde(default)]
    from_line: Option<u32>,
}

/// The job request of a stored program (`None`: no such program).
fn run_request(app: &App, run: &RunProgram) -> Option<Request> {
    let path = app.programs.path(&run.program)?;
    Some(Request::SubmitJob {
        path: path.display().to_string(),
        from_line: run.from_line,
        adaptive_force: false,
    })
}

/// Run a stored program: `POST /api/run` `{"program": id}`.
async fn run(State(app): State<Arc<App>>, headers: HeaderMap, body: Bytes) -> Response {
    if let Some(r) = cross_origin(&headers) {
        return refuse(r);
    }
    if let Err(r) = app.operator(&headers) {
        return refuse(r);
    }
    let run: RunProgram = match serde_json::from_slice(&body) {
        Ok(r) => r,
        Err(e) => return refuse((StatusCode::BAD_REQUEST, format!("not a run: {e}"))),
    };
    let Some(request) = run_request(&app, &run) else {
        return refuse((StatusCode::NOT_FOUND, "no such program".into()));
    };
    let r = app.link.request(request).await;
    Json(reply_json(None, r)).into_response()
}

/// The WebSocket: its origin must be this host's.
async fn ws(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    upgrade: WebSocketUpgrade,
) -> Response {
    if let Some(r) = cross_origin(&headers) {
        return refuse(r);
    }
    upgrade
        .max_message_size(WS_MAX_MESSAGE_BYTES)
        .on_upgrade(move |socket| session(app, socket))
}

/// What a page sends over the WebSocket.
#[derive(Debug, Deserialize)]
#[serde(tag = "t", rename_all = "snake_case")]
enum FromPage {
    /// The operator token (never in a URL).
    Auth { token: String },
    /// A command.
    Cmd { id: u64, request: Request },
    /// Run a stored program.
    Run {
        id: u64,
        #[serde(flatten)]
        run: RunProgram,
    },
    /// A continuous jog held (renewed by the page every 50 ms; 0 stops it).
    Jog {
        #[serde(with = "softnc_api::axis_letter")]
        axis: Axis,
        speed_mm_per_min: f64,
    },
    /// Still here.
    Ping,
}

/// A continuous jog held by the page.
struct HeldJog {
    axis: Axis,
    speed_mm_per_min: f64,
    /// The page's last word about it.
    heard: Instant,
    /// A renewal is with the MMI.
    in_flight: Arc<AtomicBool>,
    /// Its first request has been answered.
    answered: bool,
}

/// One page's session.
#[allow(clippy::too_many_lines)]
async fn session(app: Arc<App>, mut socket: WebSocket) {
    let (out_tx, mut out_rx) = mpsc::unbounded_channel::<String>();
    let mut status = app.link.status.clone();
    let mut jobs = app.link.jobs.clone();
    status.mark_changed();
    jobs.mark_changed();
    let mut authorized = false;
    let mut jog: Option<HeldJog> = None;
    let mut tick = tokio::time::interval(JOG_RENEW);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let hello = json!({"t": "hello", "status_needs_token": app.status_needs_token,
        "max_upload_bytes": app.programs.limit_bytes(),
        "token_configured": app.token().is_some()});
    if socket
        .send(Message::Text(hello.to_string().into()))
        .await
        .is_err()
    {
        return;
    }
    loop {
        let readable = authorized || !app.status_needs_token;
        let out = tokio::select! {
            m = socket.recv() => {
                let text = match m {
                    Some(Ok(Message::Text(t))) => t.to_string(),
                    Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                    Some(Ok(_)) => continue,
                };
                let msg = match serde_json::from_str::<FromPage>(&text) {
                    Ok(m) => m,
                    Err(e) => {
                        let _ = out_tx.send(json!({"t": "reply", "id": null, "ok": false,
                            "message": format!("not understood: {e}")}).to_string());
                        continue;
                    }
                };
                match msg {
                    FromPage::Ping => None,
                    FromPage::Auth { token } => {
                        authorized = app.token_matches(token.trim());
                        if authorized {
                            status.mark_changed();
                            jobs.mark_changed();
                        }
                        Some(json!({"t": "auth", "ok": authorized,
                            "message": if authorized { "operator" } else { "wrong operator token: read-only" }}).to_string())
                    }
                    _ if !authorized => Some(json!({"t": "reply", "id": msg_id(&text), "ok": false,
                        "message": "read-only: the operator token is needed for every command"}).to_string()),
                    FromPage::Cmd { id, request } => {
                        if let Err(e) = plain_command(&request) {
                            Some(reply_json(Some(id), Err(e)).to_string())
                        } else {
                            let (app, tx) = (app.clone(), out_tx.clone());
                            tokio::spawn(async move {
                                let r = app.link.request(request).await;
                                let _ = tx.send(reply_json(Some(id), r).to_string());
                            });
                            None
                        }
                    }
                    FromPage::Run { id, run } => match run_request(&app, &run) {
                        None => Some(reply_json(Some(id), Err("no such program".into())).to_string()),
                        Some(request) => {
                            let (app, tx) = (app.clone(), out_tx.clone());
                            tokio::spawn(async move {
                                let r = app.link.request(request).await;
                                let _ = tx.send(reply_json(Some(id), r).to_string());
                            });
                            None
                        }
                    },
                    FromPage::Jog { axis, speed_mm_per_min } => {
                        let same = jog.as_ref().is_some_and(|j| j.axis == axis
                            && j.speed_mm_per_min == speed_mm_per_min);
                        if speed_mm_per_min == 0.0 || !speed_mm_per_min.is_finite() {
                            if let Some(j) = jog.take() {
                                stop_jog(&app, j.axis);
                            }
                        } else if same {
                            if let Some(j) = jog.as_mut() {
                                j.heard = Instant::now();
                            }
                        } else {
                            if let Some(j) = jog.take() {
                                if j.axis != axis {
                                    stop_jog(&app, j.axis);
                                }
                            }
                            jog = Some(HeldJog { axis, speed_mm_per_min, heard: Instant::now(),
                                in_flight: Arc::new(AtomicBool::new(false)), answered: false });
                            renew_jog(&app, jog.as_mut(), &out_tx);
                        }
                        None
                    }
                }
            }
            r = status.changed(), if readable => {
                if r.is_err() { break; }
                let text = status.borrow_and_update().clone();
                Some(text)
            }
            r = jobs.changed(), if readable => {
                if r.is_err() { break; }
                let text = jobs.borrow_and_update().clone();
                Some(text)
            }
            Some(text) = out_rx.recv() => Some(text),
            _ = tick.tick() => {
                if jog.as_ref().is_some_and(|j| j.heard.elapsed() > JOG_QUIET) {
                    if let Some(j) = jog.take() {
                        stop_jog(&app, j.axis);
                        Some(json!({"t": "reply", "id": null, "ok": false,
                            "message": format!("jog {} stopped: the page went quiet", j.axis.name())}).to_string())
                    } else { None }
                } else {
                    renew_jog(&app, jog.as_mut(), &out_tx);
                    None
                }
            }
        };
        if let Some(text) = out {
            if socket.send(Message::Text(text.into())).await.is_err() {
                break;
            }
        }
    }
    // the page is gone: its jog stops now, not at the MMI's dead-man
    if let Some(j) = jog {
        stop_jog(&app, j.axis);
    }
}

/// The `id` of a page's message, for the refusal of a command it may not send.
fn msg_id(text: &str) -> serde_json::Value {
    serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| v.get("id").cloned())
        .unwrap_or(serde_json::Value::Null)
}

/// Renew a held jog to the MMI unless a renewal is still with it; the first
/// request's answer goes to the page.
fn renew_jog(app: &Arc<App>, jog: Option<&mut HeldJog>, out: &mpsc::UnboundedSender<String>) {
    let Some(j) = jog else { return };
    if j.in_flight.swap(true, Ordering::AcqRel) {
        return;
    }
    let first = !j.answered;
    j.answered = true;
    let (app, out, in_flight) = (app.clone(), out.clone(), j.in_flight.clone());
    let request = Request::Jog {
        axis: j.axis,
        speed_mm_per_min: j.speed_mm_per_min,
    };
    tokio::spawn(async move {
        let r = app.link.request(request).await;
        in_flight.store(false, Ordering::Release);
        if first {
            let _ = out.send(reply_json(None, r).to_string());
        }
    });
}

/// Stop a continuous jog of `axis`.
fn stop_jog(app: &Arc<App>, axis: Axis) {
    let app = app.clone();
    tokio::spawn(async move {
        if let Err(e) = app
            .link
            .request(Request::Jog {
                axis,
                speed_mm_per_min: 0.0,
            })
            .await
        {
            tracing::warn!("stopping the jog of {}: {e}", axis.name());
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(header::HeaderName, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.insert(k.clone(), v.parse().unwrap());
        }
        h
    }

    #[test]
    fn another_sites_origin_is_refused_and_this_hosts_taken() {
        let host = (header::HOST, "127.0.0.1:8080");
        assert_eq!(
            cross_origin(&headers(std::slice::from_ref(&host))),
            None,
            "no Origin: not a browser's page"
        );
        assert_eq!(
            cross_origin(&headers(&[
                host.clone(),
                (header::ORIGIN, "http://127.0.0.1:8080")
            ])),
            None
        );
        for evil in [
            "http://evil.example",
            "http://127.0.0.1:8081",
            "null",
            "http://127.0.0.1:8080.evil",
        ] {
            let r = cross_origin(&headers(&[host.clone(), (header::ORIGIN, evil)]));
            assert_eq!(r.map(|r| r.0), Some(StatusCode::FORBIDDEN), "{evil}");
        }
        // no Host to compare with: refused
        let r = cross_origin(&headers(&[(header::ORIGIN, "http://127.0.0.1:8080")]));
        assert_eq!(r.map(|r| r.0), Some(StatusCode::FORBIDDEN));
    }

    #[test]
    fn a_job_by_path_a_shutdown_and_a_continuous_jog_are_not_plain_commands() {
        let refused = [
            Request::SubmitJob {
                path: "/etc/passwd".into(),
                from_line: None,
                adaptive_force: false,
            },
            Request::Shutdown,
            Request::Jog {
                axis: Axis::X,
                speed_mm_per_min: 100.0,
            },
        ];
        for r in &refused {
            assert!(plain_command(r).is_err(), "{r:?}");
        }
        for r in [
            Request::EStop,
            Request::Hold,
            Request::JogStep {
                axis: Axis::X,
                distance_mm: 10.0,
            },
            Request::Mdi {
                blocks: "G0 X0".into(),
            },
        ] {
            assert!(plain_command(&r).is_ok(), "{r:?}");
        }
    }

    #[test]
    fn a_page_message_reads_as_the_panel_expects() {
        let m: FromPage =
            serde_json::from_str(r#"{"t":"jog","axis":"x","speed_mm_per_min":-500}"#).unwrap();
        assert!(
            matches!(m, FromPage::Jog { axis: Axis::X, speed_mm_per_min } if speed_mm_per_min == -500.0)
        );
        let m: FromPage = serde_json::from_str(
            r#"{"t":"cmd","id":7,"request":{"command":"feed_override","fraction":0.5}}"#,
        )
        .unwrap();
        assert!(
            matches!(m, FromPage::Cmd { id: 7, request: Request::FeedOverride { fraction } } if fraction == 0.5)
        );
        let m: FromPage =
            serde_json::from_str(r#"{"t":"run","id":2,"program":"ab","from_line":5}"#).unwrap();
        assert!(
            matches!(m, FromPage::Run { id: 2, run } if run.program == "ab" && run.from_line == Some(5))
        );
        assert!(serde_json::from_str::<FromPage>(
            r#"{"t":"cmd","id":1,"request":{"command":"rm"}}"#
        )
        .is_err());
    }
}
