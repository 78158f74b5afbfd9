//! Issue 33 ("A web operator panel"), in a real browser: a real-time `softncd` on the
//! simulated machine with its panel `softnc-web` on, driven by headless Chromium over
//! WebDriver (`chromedriver`, Debian's `chromium-driver`): log in with the token,
//! switch on, home, touch off, jog X by a 10 mm step and read 10.000, upload
//! `examples/demo.ngc`, run it, see the line, the progress and the backplot's tool
//! trail advance; kill `softnc-web` mid-job (the page shows the lost connection and
//! picks the restarted panel up without a reload; the job goes on), hold and read
//! `Held` within 200 ms, resume, complete with the accuracy report; E-stop a second
//! run. Screenshots at 1024×600 and 1920×1080 into `target/`, checked non-blank.
//! Also: the DRO's distance to go during a jog step and the job; the job's history
//! entry opened, its trace's contour/following-error plot drawn with the accuracy
//! report's figures (a third screenshot, `target/web-history-1024x600.png`); G54 X set
//! in the offsets form and read on the DRO; single block, step, block delete and
//! optional stop from the page on a small program; `status_needs_token` (the panel
//! restarted with it: even the status 401 without the token).
//! Without the token every command is refused (401/403) and the status readable; a
//! cross-origin WebSocket, a 100 MB upload and a binary upload are refused.
//!
//! Chromium and chromedriver are installed with apt-get when missing (CI runs as
//! root); the test is SKIPPED, saying so, only when they cannot be.
#[allow(unused_imports)] // the shared harness re-exports what other test files use
mod support;
use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::json;
use std::io::{Read, Write};
use std::net::TcpStream;
use support::*;

/// The operator token the test writes.
const TOKEN: &str = "e2e-web-operator-token-5f2a";

/// The page must show a hold as `Held` within this long of the click.
const HELD_WITHIN_MS: f64 = 200.0;

/// A free TCP port on this host.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn on_path(name: &str) -> Option<PathBuf> {
    let out = Command::new("sh")
        .args(["-c", &format!("command -v {name}")])
        .output()
        .ok()?;
    let p = String::from_utf8_lossy(&out.stdout).trim().to_string();
    (!p.is_empty()).then(|| PathBuf::from(p))
}

/// Chromium and chromedriver, installed with apt-get when missing (as root).
fn browser() -> Result<(PathBuf, PathBuf), String> {
    let found = || Some((on_path("chromium")?, on_path("chromedriver")?));
    if let Some(f) = found() {
        return Ok(f);
    }
    let root = Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0");
    if !root {
        return Err("chromium/chromedriver missing and not root to install them".into());
    }
    eprintln!("e2e_web: installing chromium and chromium-driver with apt-get");
    let apt = |args: &[&str]| {
        Command::new("apt-get")
            .args(args)
            .env("DEBIAN_FRONTEND", "noninteractive")
            .status()
            .map_err(|e| e.to_string())
    };
    apt(&["update", "-qq"])?;
    let st = apt(&["install", "-y", "-qq", "chromium", "chromium-driver"])?;
    found().ok_or(format!("apt-get install chromium chromium-driver: {st}"))
}

/// chromedriver, stopped on drop.
struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// One raw HTTP/1.1 exchange (`head` without the blank line, then `body`): the status
/// code and the response text.
/// (0 and nothing: the panel does not take the connection.)
fn http(port: u16, head: &str, body: &[u8]) -> (u16, String) {
    let Ok(mut s) = TcpStream::connect(("127.0.0.1", port)) else {
        return (0, String::new());
    };
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let _ = s.write_all(
        format!("{head}\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n").as_bytes(),
    );
    let _ = s.write_all(body);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out).to_string();
    let code = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (code, text)
}

/// POST `body` to `path` with `token` (None: no Authorization header).
fn post(port: u16, path: &str, token: Option<&str>, body: &str) -> (u16, String) {
    let auth = token.map_or(String::new(), |t| format!("\r\nAuthorization: Bearer {t}"));
    http(
        port,
        &format!(
            "POST {path} HTTP/1.1\r\nContent-Type: application/json\r\nContent-Length: {}{auth}",
            body.len()
        ),
        body.as_bytes(),
    )
}

/// The text of element `id`.
async fn text_of(c: &Client, id: &str) -> String {
    // (the DOM's text: WebDriver's visible text leaves out what scrolled away)
    let v = c
        .execute(
            "const e = document.getElementById(arguments[0]); return e ? e.textContent : null;",
            vec![json!(id)],
        )
        .await
        .unwrap_or_else(|e| panic!("#{id}: {e}"));
    v.as_str()
        .unwrap_or_else(|| panic!("no element #{id}"))
        .to_string()
}

/// Wait until the text of `id` satisfies `pred` (its last text in the panic).
async fn wait_text(
    c: &Client,
    id: &str,
    timeout: Duration,
    what: &str,
    pred: impl Fn(&str) -> bool,
) -> String {
    let t0 = Instant::now();
    loop {
        let t = text_of(c, id).await;
        if pred(&t) {
            return t;
        }
        assert!(
            t0.elapsed() < timeout,
            "{what}: #{id} reads {t:?} after {timeout:?}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

async fn click(c: &Client, css: &str) {
    c.find(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("{css}: {e}"))
        .click()
        .await
        .unwrap_or_else(|e| panic!("click {css}: {e}"));
}

/// A JavaScript expression's value in the page.
async fn js(c: &Client, expr: &str) -> serde_json::Value {
    c.execute(&format!("return {expr};"), vec![]).await.unwrap()
}

/// A screenshot at `w`×`h` into `target/web-{view}{w}x{h}.png`, checked to be the
/// size asked and not blank (many colours, no colour over 90 % of it).
async fn screenshot(c: &Client, view: &str, w: u32, h: u32) -> PathBuf {
    // the window's outer size: resize until the page's viewport is w × h
    c.set_window_size(w, h).await.unwrap();
    for _ in 0..3 {
        let inner = js(c, "[window.innerWidth, window.innerHeight]").await;
        let (iw, ih) = (
            inner[0].as_u64().unwrap() as u32,
            inner[1].as_u64().unwrap() as u32,
        );
        if (iw, ih) == (w, h) {
            break;
        }
        let (ow, oh) = c.get_window_size().await.unwrap();
        c.set_window_size(ow as u32 + w - iw, oh as u32 + h - ih)
            .await
            .unwrap();
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    let png_bytes = c.screenshot().await.unwrap();
    let path = repo().join(format!("target/web-{view}{w}x{h}.png"));
    std::fs::write(&path, &png_bytes).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(&png_bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (w, h), "screenshot size");
    let px = info.color_type.samples();
    let mut counts = std::collections::HashMap::<[u8; 3], u64>::new();
    for p in buf[..info.buffer_size()].chunks(px) {
        *counts.entry([p[0], p[1], p[2]]).or_default() += 1;
    }
    let most = counts.values().max().copied().unwrap_or(0);
    let total = u64::from(w) * u64::from(h);
    assert!(
        counts.len() > 50 && most * 10 < total * 9,
        "{}: blank ({} colours, the commonest on {most} of {total} pixels)",
        path.display(),
        counts.len()
    );
    eprintln!("e2e_web: {} ({} colours)", path.display(), counts.len());
    path
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[allow(clippy::too_many_lines)]
async fn the_panel_runs_a_job_in_a_real_browser() {
    let (chromium, chromedriver) = match browser() {
        Ok(b) => b,
        Err(e) => {
            eprintln!("SKIPPED: e2e_web: no headless Chromium ({e})");
            return;
        }
    };
    let t_start = Instant::now();
    let port = free_port();
    // (with the daemon's per-cycle traces: the history's plot reads them)
    let d = daemon_with_panel("web", "Realtime", port);
    let op = d.operator_off();
    // the panel serves: the status readable without the token, live
    let t0 = Instant::now();
    loop {
        let (code, body) = http(port, "GET /api/status HTTP/1.1", b"");
        if code == 200 && body.contains("\"link\":\"ok\"") {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the panel's status: {code} {body}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }

    // -- without the token: every command refused, 401 without, 403 with a wrong one
    for body in [
        r#"{"command":"machine_on"}"#,
        r#"{"command":"e_stop"}"#,
        r#"{"command":"mdi","blocks":"G0 X1"}"#,
        r#"{"command":"jog_step","axis":"X","distance_mm":1.0}"#,
    ] {
        let (code, text) = post(port, "/api/command", None, body);
        assert_eq!(code, 401, "{body} without the token: {text}");
        let (code, text) = post(port, "/api/command", Some("not-the-token"), body);
        assert_eq!(code, 403, "{body} with a wrong token: {text}");
    }
    let (code, _) = post(port, "/api/run", None, r#"{"program":"x"}"#);
    assert_eq!(code, 401, "run without the token");
    let (code, _) = http(
        port,
        "POST /api/programs HTTP/1.1\r\nContent-Length: 6",
        b"G0 X1\n",
    );
    assert_eq!(code, 401, "upload without the token");
    // a state-changing GET does not exist
    let (code, _) = http(port, "GET /api/command HTTP/1.1", b"");
    assert_eq!(code, 405, "GET /api/command");
    assert_eq!(
        op.status().unwrap().state,
        MachineState::Off,
        "nothing was done"
    );

    // -- a cross-origin WebSocket refused, a same-origin one taken
    let ws_head = |origin: &str| {
        format!(
            "GET /ws HTTP/1.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nOrigin: {origin}"
        )
    };
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(
        format!(
            "{}\r\nHost: 127.0.0.1:{port}\r\n\r\n",
            ws_head("http://evil.example")
        )
        .as_bytes(),
    )
    .unwrap();
    let mut buf = [0u8; 256];
    let n = s.read(&mut buf).unwrap();
    let reply = String::from_utf8_lossy(&buf[..n]);
    assert!(
        reply.starts_with("HTTP/1.1 403"),
        "cross-origin WebSocket: {reply}"
    );
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(
        format!(
            "{}\r\nHost: 127.0.0.1:{port}\r\n\r\n",
            ws_head(&format!("http://127.0.0.1:{port}"))
        )
        .as_bytes(),
    )
    .unwrap();
    let n = s.read(&mut buf).unwrap();
    let reply = String::from_utf8_lossy(&buf[..n]);
    assert!(
        reply.starts_with("HTTP/1.1 101"),
        "same-origin WebSocket: {reply}"
    );
    drop(s);

    // -- uploads: 100 MB and binary refused (with the token)
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s.write_all(
        format!(
            "POST /api/programs HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nAuthorization: Bearer {TOKEN}\r\nContent-Length: {}\r\nX-File-Name: big.ngc\r\n\r\n",
            100u64 << 20
        )
        .as_bytes(),
    )
    .unwrap();
    // (the first megabyte of it; the answer comes without the rest)
    let _ = s.write_all(&b"G1 X1 Y1 F100\n".repeat(75_000));
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let reply = String::from_utf8_lossy(&out);
    assert!(reply.starts_with("HTTP/1.1 413"), "100 MB upload: {reply}");
    let binary: Vec<u8> = (0..4096u32).map(|i| (i * 7 % 256) as u8).collect();
    let (code, text) = http(
        port,
        &format!(
            "POST /api/programs HTTP/1.1\r\nAuthorization: Bearer {TOKEN}\r\nContent-Length: {}\r\nX-File-Name: part.ngc",
            binary.len()
        ),
        &binary,
    );
    assert_eq!(code, 415, "binary upload: {text}");

    // -- the browser
    let driver_port = free_port();
    let driver = Driver(
        Command::new(&chromedriver)
            .arg(format!("--port={driver_port}"))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("chromedriver starts"),
    );
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        json!({"binary": chromium, "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
            "--disable-dev-shm-usage", "--window-size=1024,600", "--hide-scrollbars"]}),
    );
    let t0 = Instant::now();
    let c = loop {
        let connector = hyper_util::client::legacy::connect::HttpConnector::new();
        match ClientBuilder::new(connector)
            .capabilities(caps.clone())
            .connect(&format!("http://127.0.0.1:{driver_port}"))
            .await
        {
            Ok(c) => break c,
            Err(e) if t0.elapsed() > Duration::from_secs(30) => panic!("WebDriver session: {e}"),
            Err(_) => tokio::time::sleep(Duration::from_millis(200)).await,
        }
    };
    let url = format!("http://127.0.0.1:{port}/");
    c.goto(&url).await.unwrap();
    wait_text(&c, "link", Duration::from_secs(10), "the page live", |t| {
        t == "live"
    })
    .await;
    wait_text(
        &c,
        "state",
        Duration::from_secs(5),
        "the state shown",
        |t| t == "Off",
    )
    .await;
    // read-only: a command from the page is refused, nothing moves
    click(&c, ".tab[data-view=manual]").await;
    click(&c, "#btn-on").await;
    wait_text(&c, "log", Duration::from_secs(5), "the refusal", |t| {
        t.contains("read-only")
    })
    .await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        text_of(&c, "state").await,
        "Off",
        "a read-only page switched the machine on"
    );

    // -- log in, switch on, home, touch off, jog X by a 10 mm step
    c.find(Locator::Id("token"))
        .await
        .unwrap()
        .send_keys(TOKEN)
        .await
        .unwrap();
    click(&c, "#login").await;
    wait_text(&c, "auth-state", Duration::from_secs(5), "logged in", |t| {
        t == "operator"
    })
    .await;
    click(&c, "#btn-on").await;
    wait_text(&c, "state", Duration::from_secs(30), "machine on", |t| {
        t == "Idle"
    })
    .await;
    click(&c, "#btn-home").await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    wait_text(&c, "state", Duration::from_secs(60), "homed", |t| {
        t == "Idle"
    })
    .await;
    for a in ["x", "y", "z"] {
        wait_text(
            &c,
            &format!("homed-{a}"),
            Duration::from_secs(5),
            "homed mark",
            |t| t == "●",
        )
        .await;
    }
    // a continuous jog held on the page, then the page goes quiet (its renewals stop
    // without a release, as a frozen tab's): the panel stops the jog
    click(&c, "#jog-mode option[value='cont']").await;
    let speed = c.find(Locator::Id("jog-speed")).await.unwrap();
    speed.clear().await.unwrap();
    speed.send_keys("600").await.unwrap();
    c.execute(
        "document.querySelector(\".jogb[data-axis=X][data-dir='1']\").dispatchEvent(new PointerEvent('pointerdown', {bubbles: true}));",
        vec![],
    )
    .await
    .unwrap();
    wait_text(
        &c,
        "state",
        Duration::from_secs(5),
        "the continuous jog",
        |t| t == "Jogging",
    )
    .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_eq!(
        text_of(&c, "state").await,
        "Jogging",
        "the held jog goes on"
    );
    c.execute(
        "clearInterval(S.jogTimer); S.jogTimer = null; S.jogAxis = null;",
        vec![],
    )
    .await
    .unwrap();
    let t0 = Instant::now();
    wait_text(
        &c,
        "state",
        Duration::from_secs(2),
        "the quiet page's jog stopped",
        |t| t == "Idle",
    )
    .await;
    eprintln!(
        "e2e_web: the page went quiet: the jog stopped within {:?}",
        t0.elapsed()
    );
    // touch off X and Y at 0 where the axes stand
    for axis in ["X", "Y"] {
        click(&c, &format!("#touch-axis option[value='{axis}']")).await;
        let v = c.find(Locator::Id("touch-value")).await.unwrap();
        v.clear().await.unwrap();
        v.send_keys("0").await.unwrap();
        click(&c, "#btn-touch").await;
        wait_text(
            &c,
            &format!("dro-work-{}", axis.to_lowercase()),
            Duration::from_secs(20),
            "touched off",
            |t| t == "0.000",
        )
        .await;
    }
    click(&c, "#jog-mode option[value='10']").await;
    click(&c, ".jogb[data-axis=X][data-dir='1']").await;
    // the distance to go on the DRO while it moves: the work position and it add
    // up to the step's end (to the DRO's 3 decimals)
    let t0 = Instant::now();
    let (work_x, to_go_x) = loop {
        let v = js(
            &c,
            "[document.getElementById('dro-work-x').textContent, document.getElementById('dro-dtg-x').textContent]",
        )
        .await;
        let num = |k: usize| v[k].as_str().and_then(|t| t.parse::<f64>().ok());
        if let (Some(w), Some(g)) = (num(0), num(1)) {
            if g > 0.0 {
                break (w, g);
            }
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "no distance to go shown during the jog step: {v}"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    };
    assert!(
        (work_x + to_go_x - 10.0).abs() <= 0.0015,
        "the DRO read X {work_x} with {to_go_x} to go during the 10 mm step"
    );
    eprintln!("e2e_web: during the jog step the DRO read X {work_x:.3} with {to_go_x:.3} mm to go");
    wait_text(
        &c,
        "dro-work-x",
        Duration::from_secs(20),
        "the 10 mm jog step",
        |t| t == "10.000",
    )
    .await;
    wait_text(&c, "state", Duration::from_secs(10), "the jog done", |t| {
        t == "Idle"
    })
    .await;
    for a in ["x", "y", "z"] {
        wait_text(
            &c,
            &format!("dro-dtg-{a}"),
            Duration::from_secs(2),
            "nothing to go at rest",
            |t| t == "0.000",
        )
        .await;
    }
    // back to X 0 for the program (its contour spans X -40 … 40)
    click(&c, "#jog-mode option[value='10']").await;
    click(&c, ".jogb[data-axis=X][data-dir='-1']").await;
    wait_text(
        &c,
        "dro-work-x",
        Duration::from_secs(20),
        "the jog back",
        |t| t == "0.000",
    )
    .await;
    wait_text(&c, "state", Duration::from_secs(10), "the jog done", |t| {
        t == "Idle"
    })
    .await;

    // -- upload examples/demo.ngc and run it
    click(&c, ".tab[data-view=program]").await;
    let demo = std::fs::canonicalize(repo().join("examples/demo.ngc")).unwrap();
    upload(&c, &demo, "demo.ngc", "the upload listed").await;
    let t0 = Instant::now();
    while js(&c, "S.plan ? S.plan.length : 0")
        .await
        .as_u64()
        .unwrap_or(0)
        == 0
    {
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "no backplot of the program"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    click(&c, "#btn-run").await;
    wait_text(
        &c,
        "state",
        Duration::from_secs(60),
        "the job running",
        |t| t == "Running",
    )
    .await;
    let line0: u32 = wait_text(&c, "line", Duration::from_secs(10), "a line", |t| {
        t.parse::<u32>().is_ok()
    })
    .await
    .parse()
    .unwrap();
    let progress = |t: &str| -> f64 {
        t.rsplit(' ')
            .nth(1)
            .and_then(|p| p.parse().ok())
            .unwrap_or(-1.0)
    };
    let p0 = progress(&text_of(&c, "progress").await);
    wait_text(
        &c,
        "line",
        Duration::from_secs(20),
        "the line advancing",
        |t| t.parse::<u32>().is_ok_and(|l| l > line0),
    )
    .await;
    wait_text(
        &c,
        "progress",
        Duration::from_secs(20),
        "the progress advancing",
        |t| progress(t) > p0,
    )
    .await;
    let trail = js(&c, "S.trail.length").await.as_u64().unwrap();
    assert!(trail > 1, "the backplot's tool trail: {trail} points");
    // a distance to go on the DRO during the job
    let t0 = Instant::now();
    loop {
        let v = js(
            &c,
            "['x','y','z'].map((a) => Math.abs(parseFloat(document.getElementById('dro-dtg-' + a).textContent) || 0))",
        )
        .await;
        if v.as_array()
            .unwrap()
            .iter()
            .any(|x| x.as_f64().unwrap_or(0.0) > 0.001)
        {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "no distance to go shown during the job: {v}"
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let current = js(&c, "document.querySelector('#listing li.current') ? document.querySelector('#listing li.current').textContent : ''").await;
    assert!(
        current.as_str().is_some_and(|t| !t.trim().is_empty()),
        "the current line in the listing: {current}"
    );

    // -- kill softnc-web mid-job: the page shows the loss at once, picks the restarted
    // panel up without a reload, and the job runs on
    c.execute("window.__noReload = true;", vec![])
        .await
        .unwrap();
    d.kill9("softnc-web");
    let t0 = Instant::now();
    wait_text(
        &c,
        "link",
        Duration::from_secs(2),
        "the lost connection shown",
        |t| t != "live",
    )
    .await;
    let shown_lost_ms = t0.elapsed().as_millis();
    assert!(
        js(&c, "document.body.classList.contains('stale')")
            .await
            .as_bool()
            .unwrap(),
        "stale figures not marked"
    );
    wait_text(
        &c,
        "link",
        Duration::from_secs(15),
        "the restarted panel picked up",
        |t| t == "live",
    )
    .await;
    assert_eq!(
        js(&c, "window.__noReload === true").await,
        json!(true),
        "the page reloaded"
    );
    wait_text(
        &c,
        "auth-state",
        Duration::from_secs(5),
        "logged in again",
        |t| t == "operator",
    )
    .await;
    assert_eq!(
        text_of(&c, "state").await,
        "Running",
        "the job after the panel's restart"
    );
    eprintln!("e2e_web: softnc-web killed: the page showed it in {shown_lost_ms} ms, back live after {:?}", t0.elapsed());

    // -- hold: `Held` on the page within 200 ms of the click (measured in the page)
    let held_ms = c
        .execute_async(
            "const done = arguments[arguments.length - 1];
             const t0 = performance.now();
             document.getElementById('btn-hold').click();
             const check = () => {
               const dt = performance.now() - t0;
               if (document.getElementById('state').textContent === 'Held') done(dt);
               else if (dt > 5000) done(-1); else setTimeout(check, 1);
             };
             check();",
            vec![],
        )
        .await
        .unwrap()
        .as_f64()
        .unwrap();
    eprintln!("e2e_web: Held shown {held_ms:.0} ms after the click");
    assert!(
        (0.0..=HELD_WITHIN_MS).contains(&held_ms),
        "Held shown {held_ms:.0} ms after the click (bound {HELD_WITHIN_MS} ms)"
    );
    tokio::time::sleep(Duration::from_millis(500)).await;
    click(&c, "#btn-resume").await;
    wait_text(&c, "state", Duration::from_secs(5), "resumed", |t| {
        t == "Running"
    })
    .await;
    // feed override 150 % from the page: the rest of the job goes faster
    c.execute(
        "const r = document.getElementById('feed-ovr'); r.value = 150; r.dispatchEvent(new Event('change'));",
        vec![],
    )
    .await
    .unwrap();
    wait_text(
        &c,
        "feed-ovr-val",
        Duration::from_secs(5),
        "the feed override",
        |t| t == "150 %",
    )
    .await;
    let acc = wait_text(
        &c,
        "accuracy",
        Duration::from_secs(120),
        "the job's accuracy report",
        |t| t.contains("completed"),
    )
    .await;
    assert!(acc.contains("contour max") && acc.contains("µm"), "{acc}");
    eprintln!("e2e_web: {acc}");
    let jobs = op.jobs().unwrap();
    let job = &jobs[0];
    assert_eq!(job.outcome, Outcome::Completed, "{job}");
    assert!(
        !job.alarms.iter().any(|a| a.contains("softnc-web")),
        "the panel's death in the job's record: {:?}",
        job.alarms
    );
    assert!(job.accuracy.contour_max_abs_um > 0.0, "{job}");
    screenshot(&c, "", 1024, 600).await;
    click(&c, ".tab[data-view=history]").await;
    let history = wait_text(&c, "jobs", Duration::from_secs(5), "the job history", |t| {
        t.contains("completed")
    })
    .await;
    assert!(history.contains("demo.ngc"), "{history}");
    // the backplot's executed path is now the job's trace, coloured by its contour
    // error
    let t0 = Instant::now();
    while js(&c, "S.trailFrom").await != json!("trace") {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the backplot did not take the job's trace"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // the job's entry opened: its contour and following error plot from its trace,
    // the figures the accuracy report's
    click(&c, &format!("#jobs tr[data-job='{}']", job.job_id)).await;
    let figures = wait_text(
        &c,
        "trace-figures",
        Duration::from_secs(10),
        "the job's trace plot",
        |t| t.contains("contour max"),
    )
    .await;
    eprintln!("e2e_web: {figures}");
    let after = |t: &str, key: &str| -> Vec<f64> {
        let rest = &t[t.find(key).unwrap_or_else(|| panic!("{key} in {t:?}")) + key.len()..];
        rest.split(" µm")
            .next()
            .unwrap()
            .split('/')
            .map(|v| v.trim().parse::<f64>().unwrap_or(f64::NAN))
            .collect()
    };
    let contour = after(&figures, "contour max ")[0];
    let following = after(&figures, "following max X/Y/Z ");
    let report = &job.accuracy;
    assert!(
        (contour - report.contour_max_abs_um).abs() <= 0.05 + 1e-9,
        "the plot's contour max {contour} µm, the report's {} µm",
        report.contour_max_abs_um
    );
    for (i, f) in following.iter().enumerate() {
        assert!(
            (f - report.following_max_abs_um[i]).abs() <= 0.05 + 1e-9,
            "the plot's following max {following:?} µm, the report's {:?} µm",
            report.following_max_abs_um
        );
    }
    let drawn = js(
        &c,
        "(() => { const c = document.getElementById('trace-plot'); const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; let n = 0; for (let k = 3; k < d.length; k += 4) if (d[k] > 0) n++; return [n, c.width * c.height]; })()",
    )
    .await;
    let (lit, all) = (drawn[0].as_u64().unwrap(), drawn[1].as_u64().unwrap());
    assert!(
        all > 0 && lit * 50 > all,
        "the trace plot is blank: {lit} of {all} pixels drawn"
    );
    screenshot(&c, "history-", 1024, 600).await;

    // -- the work offsets edited in the page: G54 X set, read back on the DRO
    click(&c, ".tab[data-view=tables]").await;
    wait_text(
        &c,
        "offsets",
        Duration::from_secs(10),
        "the offsets table",
        |t| t.contains("G59.3"),
    )
    .await;
    let s = op.status().unwrap();
    let machine_x = s.machine_mm.unwrap()[0];
    let g54 = op.offsets().unwrap().systems[0].origin_mm;
    let g54_x = machine_x - s.offsets.g92_mm[0] - s.offsets.tool_offset_mm[0] - 12.5;
    click(&c, "#ofs-sys option[value='1']").await;
    let x = c.find(Locator::Id("ofs-x")).await.unwrap();
    x.clear().await.unwrap();
    x.send_keys(&format!("{g54_x:.4}")).await.unwrap();
    click(&c, "#btn-ofs-set").await;
    wait_text(
        &c,
        "dro-work-x",
        Duration::from_secs(20),
        "the G54 X set in the page",
        |t| t == "12.500",
    )
    .await;
    let now = op.offsets().unwrap().systems[0].origin_mm;
    assert!(
        (now[0] - g54_x).abs() < 1e-3
            && (now[1] - g54[1]).abs() < 1e-6
            && (now[2] - g54[2]).abs() < 1e-6,
        "G54 after the edit {now:?} (was {g54:?}, X {g54_x} asked)"
    );
    // back as it was (the next run's contour is where it was)
    wait_text(
        &c,
        "offsets",
        Duration::from_secs(10),
        "the table read again",
        |t| t.contains(&format!("{g54_x:.3}")),
    )
    .await;
    let x = c.find(Locator::Id("ofs-x")).await.unwrap();
    x.clear().await.unwrap();
    x.send_keys(&format!("{}", g54[0])).await.unwrap();
    click(&c, "#btn-ofs-set").await;
    let back = format!(
        "{:.3}",
        machine_x - s.offsets.g92_mm[0] - s.offsets.tool_offset_mm[0] - g54[0]
    )
    .replace("-0.000", "0.000");
    wait_text(
        &c,
        "dro-work-x",
        Duration::from_secs(20),
        "G54 X back",
        |t| t == back,
    )
    .await;

    // MDI from the page: a modal block, done and kept in the page's MDI history (the
    // tool length offset the job left stays in force: the second run starts with
    // the previous job's `G43.1 Z…` in its modal state, which once E-stopped it on a
    // Z following error the size of the offset)
    click(&c, ".tab[data-view=manual]").await;
    c.find(Locator::Id("mdi"))
        .await
        .unwrap()
        .send_keys("G54")
        .await
        .unwrap();
    click(&c, "#btn-mdi").await;
    wait_text(
        &c,
        "log",
        Duration::from_secs(20),
        "the MDI block done",
        |t| t.contains("MDI") && t.contains("done"),
    )
    .await;
    wait_text(
        &c,
        "mdi-history",
        Duration::from_secs(2),
        "the MDI history",
        |t| t.contains("G54"),
    )
    .await;
    wait_text(&c, "state", Duration::from_secs(10), "the MDI done", |t| {
        t == "Idle"
    })
    .await;
    click(&c, ".tab[data-view=program]").await;

    // -- the program-flow switches from the page, on a small program: single block
    // stops after each block, block delete skips the `/` line, optional stop stops
    // at the M1 (the last two on as the controller starts)
    let flow = d.dir.join("flow.ngc");
    std::fs::write(
        &flow,
        "G21 G90 G64 P0.01\nG1 X1 Y0 F1200\n/G1 X2\nG1 X3\nG1 Y1\nM1\nG1 X4\nM2\n",
    )
    .unwrap();
    for (id, on) in [
        ("sw-delete", true),
        ("sw-optional", true),
        ("sw-single", false),
    ] {
        assert_eq!(
            js(&c, &format!("document.getElementById('{id}').checked")).await,
            json!(on),
            "#{id} as the controller starts"
        );
    }
    // optional stop off and on again from the page: the status follows
    for want in [false, true] {
        click(&c, "#sw-optional").await;
        let t0 = Instant::now();
        while op.status().unwrap().switches.optional_stop != want {
            assert!(
                t0.elapsed() < Duration::from_secs(5),
                "optional stop {want}"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    click(&c, "#sw-single").await;
    let t0 = Instant::now();
    while !op.status().unwrap().switches.single_block {
        assert!(t0.elapsed() < Duration::from_secs(5), "single block on");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    upload(&c, &flow, "flow.ngc", "the small program listed").await;
    let t0 = Instant::now();
    while js(&c, "S.plan ? S.plan.length : 0").await != json!(5) {
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "the small program selected"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    click(&c, "#btn-run").await;
    // paused at each block's end: the first block, then (stepped) the next one run,
    // X3 (block delete: the `/G1 X2` was not)
    let paused_at = |x: &'static str| {
        let c = c.clone();
        async move {
            wait_text(&c, "state", Duration::from_secs(30), "a pause", |t| {
                t == "Paused"
            })
            .await;
            wait_text(
                &c,
                "dro-work-x",
                Duration::from_secs(5),
                "paused at the block's end",
                |t| t == x,
            )
            .await;
            tokio::time::sleep(Duration::from_millis(300)).await;
            assert_eq!(text_of(&c, "state").await, "Paused", "standing at X {x}");
            assert_eq!(text_of(&c, "dro-work-x").await, x, "standing at X {x}");
        }
    };
    paused_at("1.000").await;
    assert_eq!(text_of(&c, "line").await, "2", "single block after line 2");
    click(&c, "#btn-step").await;
    paused_at("3.000").await;
    assert_eq!(
        text_of(&c, "line").await,
        "4",
        "stepped to line 4's end, line 3 (`/`) skipped"
    );
    // single block off, resume: line 5 runs, the optional stop at the M1 (line 6)
    click(&c, "#sw-single").await;
    let t0 = Instant::now();
    while op.status().unwrap().switches.single_block {
        assert!(t0.elapsed() < Duration::from_secs(5), "single block off");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    click(&c, "#btn-resume").await;
    wait_text(&c, "line", Duration::from_secs(10), "the M1", |t| t == "6").await;
    paused_at("3.000").await;
    assert_eq!(
        text_of(&c, "dro-work-y").await,
        "1.000",
        "line 5 run before the M1"
    );
    click(&c, "#btn-resume").await;
    wait_text(
        &c,
        "progress",
        Duration::from_secs(30),
        "the small program done",
        |t| t.contains("completed"),
    )
    .await;
    assert_eq!(
        text_of(&c, "dro-work-x").await,
        "4.000",
        "the program's end"
    );
    wait_text(&c, "state", Duration::from_secs(10), "idle", |t| {
        t == "Idle"
    })
    .await;
    eprintln!("e2e_web: single block, step, block delete and optional stop from the page: paused at X 1 and 3 (line 3 skipped), the M1 after line 5, done at X 4");
    // the demo selected again for the second run
    c.execute(
        "[...document.querySelectorAll('#programs li')].find((li) => li.textContent.includes('demo.ngc')).click();",
        vec![],
    )
    .await
    .unwrap();
    let t0 = Instant::now();
    while js(&c, "S.plan ? S.plan.length : 0")
        .await
        .as_u64()
        .unwrap_or(0)
        <= 5
    {
        assert!(
            t0.elapsed() < Duration::from_secs(5),
            "the demo selected again"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }

    // -- a second run, E-stopped from the page
    click(&c, "#btn-run").await;
    wait_text(
        &c,
        "state",
        Duration::from_secs(60),
        "the second run",
        |t| t == "Running",
    )
    .await;
    let line1: u32 = wait_text(&c, "line", Duration::from_secs(10), "a line", |t| {
        t.parse::<u32>().is_ok()
    })
    .await
    .parse()
    .unwrap();
    wait_text(
        &c,
        "line",
        Duration::from_secs(20),
        "the second run advancing",
        |t| t.parse::<u32>().is_ok_and(|l| l > line1 + 2),
    )
    .await;
    screenshot(&c, "", 1920, 1080).await;
    assert_eq!(
        text_of(&c, "state").await,
        "Running",
        "the second run before the E-stop"
    );
    click(&c, "#estop").await;
    wait_text(&c, "state", Duration::from_secs(2), "the E-stop", |t| {
        t == "EStopped"
    })
    .await;
    let s = op.status().unwrap();
    assert_eq!(s.state, MachineState::EStopped);
    assert!(
        s.alarms.iter().any(|a| a.code == AlarmKind::EStop)
            && !s.alarms.iter().any(|a| a.code == AlarmKind::FollowingError),
        "the operator's E-stop: {:?}",
        s.alarms
    );
    let _ = c.close().await;
    drop(driver);

    // -- `status_needs_token`: the panel started again with it reads nothing
    // without the token (401), with it the status
    let cfg = std::fs::read_to_string(&d.config).unwrap();
    let edited = cfg.replace(
        "token_file: \"token\")",
        "token_file: \"token\", status_needs_token: true)",
    );
    assert_ne!(cfg, edited, "the web section in {}", d.config.display());
    std::fs::write(&d.config, edited).unwrap();
    let before = d.pid_of("softnc-web");
    d.kill9("softnc-web");
    let t0 = Instant::now();
    loop {
        let (code, _) = http(port, "GET /api/status HTTP/1.1", b"");
        if code == 401 && d.pid_of("softnc-web") != before {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "the status with status_needs_token: {code}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    for path in [
        "/api/status",
        "/api/jobs",
        "/api/programs",
        &format!("/api/jobs/{}/trace", job.job_id),
    ] {
        let (code, text) = http(port, &format!("GET {path} HTTP/1.1"), b"");
        assert_eq!(code, 401, "GET {path} without the token: {text}");
        let (code, text) = http(
            port,
            &format!("GET {path} HTTP/1.1\r\nAuthorization: Bearer {TOKEN}"),
            b"",
        );
        assert_eq!(code, 200, "GET {path} with the token: {text}");
    }
    eprintln!("e2e_web: done in {:?}", t_start.elapsed());
}

/// Issue 33: killing `softnc-web` mid-job does not disturb the job. On a lockstep
/// `softncd` with the panel (its trace is then bit for bit the offline simulator's,
/// as `e2e_daemon`'s lockstep tests hold), the panel is killed while
/// `examples/demo.ngc` runs, the supervisor starts it again and it serves again
/// before the job ends; the job completes without an alarm about the panel and its
/// trace is byte for byte the simulator's of the same job: the panel's death left
/// no mark on the motion. (No browser: the page's reconnection is the browser
/// test's.)
/// Upload `path` through the page's file input and wait until the program list
/// shows `name` (`what` names the wait in a failure).
async fn upload(c: &Client, path: &std::path::Path, name: &str, what: &str) {
    c.find(Locator::Id("file"))
        .await
        .unwrap()
        .send_keys(&path.display().to_string())
        .await
        .unwrap();
    click(c, "#btn-upload").await;
    wait_text(c, "programs", Duration::from_secs(10), what, |t| {
        t.contains(name)
    })
    .await;
}

/// A `softncd` (`clock`, with per-cycle traces) whose configuration starts the web
/// panel on `port` with the operator token [`TOKEN`] in its file.
fn daemon_with_panel(tag: &str, clock: &str, port: u16) -> Daemon {
    let d = Daemon::start_in(
        fresh_dir(tag),
        tag,
        clock,
        true,
        "default.ron",
        &[(
            "    check_timeout_s: 60.0,",
            &format!(
                "    check_timeout_s: 60.0,\n    web: Some((listen: \"127.0.0.1:{port}\", token_file: \"token\")),"
            ),
        )],
    );
    std::fs::write(d.dir.join("token"), format!("{TOKEN}\n")).unwrap();
    d
}

#[test]
fn killing_the_panel_mid_job_leaves_the_jobs_trace_byte_for_byte_the_simulators() {
    let port = free_port();
    let d = daemon_with_panel("webkill", "Lockstep", port);
    let op = d.operator();
    let serving = |what: &str| {
        let t0 = Instant::now();
        loop {
            let (code, body) = http(port, "GET /api/status HTTP/1.1", b"");
            if code == 200 && body.contains("\"link\":\"ok\"") {
                return;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "{what}: the panel's status {code} {body}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    serving("the panel up");
    let job = d.dir.join("demo.ngc");
    std::fs::copy(repo().join("examples/demo.ngc"), &job).unwrap();
    let r = op.request(&submit(&abs(&job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let job_id = id(&r);
    d.wait_status(&op, Duration::from_secs(60), "the job moving", |s| {
        s.job(job_id).is_some_and(|j| j.record.cycles > 2000)
    });
    let before = d.pid_of("softnc-web");
    d.kill9("softnc-web");
    let killed_at = job_of(&op.status().unwrap()).clone();
    let t0 = Instant::now();
    while d.pid_of("softnc-web").is_none() || d.pid_of("softnc-web") == before {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "softnc-web not started again"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    serving("the panel started again");
    let back = job_of(&op.status().unwrap()).clone();
    assert_eq!(
        killed_at.outcome,
        Outcome::Running,
        "killed mid-job: {killed_at}"
    );
    assert_eq!(
        back.outcome,
        Outcome::Running,
        "the job ended before the panel was back (not mid-job): {back}"
    );
    eprintln!(
        "e2e_web: softnc-web killed at cycle {} of {} planned, serving again by cycle {}",
        killed_at.cycles, killed_at.planned_samples, back.cycles
    );
    let s = d.wait_job(&op, job_id, Duration::from_secs(300));
    let done = job_of(&s);
    assert_eq!(done.outcome, Outcome::Completed, "{s}");
    assert!(
        !done.alarms.iter().any(|a| a.contains("softnc-web")),
        "the panel's death in the job's record: {:?}",
        done.alarms
    );
    let sim = d.dir.join("sim.csv");
    simulator_trace(&job, &d.dir.join("machines/default.ron"), &sim);
    let want = std::fs::read(&sim).unwrap();
    assert!(want.len() > 10_000, "simulator trace too short");
    let got = d.trace_of(job_id, want.len());
    if got != want {
        let (g, w) = (
            String::from_utf8_lossy(&got),
            String::from_utf8_lossy(&want),
        );
        let first = g.lines().zip(w.lines()).position(|(a, b)| a != b);
        panic!(
            "the daemon's trace ({} lines) differs from the simulator's ({} lines) first at line {first:?}:\n{:?}\n{:?}",
            g.lines().count(),
            w.lines().count(),
            first.and_then(|i| g.lines().nth(i)),
            first.and_then(|i| w.lines().nth(i))
        );
    }
    eprintln!(
        "e2e_web: job {job_id}'s trace, the panel killed mid-job: {} bytes, byte for byte the simulator's",
        got.len()
    );
}
