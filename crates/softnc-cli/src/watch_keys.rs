//! The operator's keys in `softnc watch` (issue 19, machine operation): a pure
//! function from a key, the UI's state and the last status to the requests to
//! send ([`on_key`]), the timers of a held continuous jog and of the offsets view
//! ([`on_tick`]) and what a reply changes ([`on_reply`]); and the program listing's
//! cache ([`Listing`]). Nothing here talks to the daemon, so all of it is tested
//! without one; `cmd_watch` sends the [`Action`]s and draws the [`Ui`].
//!
//! The key map is [`KEY_MAP`] (the `?` overlay); `docs/operations.md` ("The terminal
//! UI") describes it for the operator.

use ratatui::crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
pub use softnc_api::Request;
use softnc_api::{Axis, JobRecord, OffsetTable, Reply, Status};
use std::time::{Duration, Instant};

/// Incremental jog steps that `i` cycles through (mm).
pub const JOG_STEPS_MM: [f64; 4] = [0.01, 0.1, 1.0, 10.0];
/// The step selected when the UI starts (index into [`JOG_STEPS_MM`]: 0.1 mm).
pub const JOG_STEP_START: usize = 1;
/// Continuous jog speeds that `,` / `.` step down / up through (mm/min); the MMI
/// refuses a speed over the axis's limit.
pub const JOG_SPEEDS_MM_PER_MIN: [f64; 7] = [60.0, 120.0, 300.0, 600.0, 1200.0, 3000.0, 6000.0];
/// The continuous jog speed selected when the UI starts (index into
/// [`JOG_SPEEDS_MM_PER_MIN`]: 600 mm/min).
pub const JOG_SPEED_START: usize = 3;
/// A continuous jog is held while its key is: pressed again by the terminal's key
/// repeat. This long after the last press (or repeat) the UI stops it itself
/// (`Jog` 0); where the terminal reports key releases it stops at the release. The
/// MMI's dead-man (the profile's `jog.deadman_s`) stops it if the UI goes away.
pub const JOG_KEY_HOLD: Duration = Duration::from_millis(500);
/// A held continuous jog is renewed (the same `Jog` again) at least this often:
/// the operator contract's period, which the daemon keeps below the profile's
/// dead-man (`jog.deadman_s`); key repeats faster than this send nothing more.
pub const JOG_RENEW: Duration = softnc_api::JOG_RENEW_PERIOD;
/// The offsets view asks the MMI for the offsets again this often while it is open
/// (a touch-off or an MDI `G10` changes them).
pub const OFFSETS_REFRESH: Duration = Duration::from_secs(1);
/// `+` / `-` change the feed override by this much (fraction).
pub const FEED_OVERRIDE_STEP: f64 = 0.1;
/// The largest feed override the UI asks for (fraction; the MMI refuses one over the
/// profile's `max_feed_override`).
pub const FEED_OVERRIDE_MAX: f64 = 2.55;
/// `]` / `[` change the spindle override by this much (fraction); the MMI refuses what
/// is outside the profile's spindle range.
pub const SPINDLE_OVERRIDE_STEP: f64 = 0.1;
/// `}` / `{` change the rapid override by this much (fraction, within 0..=1).
pub const RAPID_OVERRIDE_STEP: f64 = 0.1;
/// The axes the UI shows and jogs (the status's arrays are X, Y, Z).
pub const AXES: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

/// Every key, for the `?` overlay (two columns, each at most 38 characters).
pub const KEY_MAP: [(&str, &str); 11] = [
    ("←/→ jog X−/X+   ↑/↓ jog Y+/Y−", "PgUp/PgDn jog Z+/Z−"),
    ("i step 0.01/0.1/1/10 mm", "c continuous jog on/off"),
    (",/. continuous speed −/+", "H home all axes"),
    ("o machine on   O machine off", "m MDI line (Enter sends)"),
    ("t then x/y/z: touch off to 0", "v offsets view"),
    ("s single block   n next block", "1 optional stop (M1)"),
    ("/ block delete", "h hold   r resume   a abort"),
    (
        "+/- feed, }/{ rapid override ±10 %",
        "]/[ spindle override ±10 %",
    ),
    ("F1 or e E-STOP", "x reset   L override limits"),
    ("Esc closes, cancels", "? this help"),
    ("q or Ctrl-C quit", "(a jog stops at any other key)"),
];

/// A continuous jog of `axis` at `speed_mm_per_min` (0 stops it).
pub fn jog(axis: Axis, speed_mm_per_min: f64) -> Request {
    Request::Jog {
        axis,
        speed_mm_per_min,
    }
}

/// An incremental jog of `axis` by `distance_mm`.
pub fn jog_step(axis: Axis, distance_mm: f64) -> Request {
    Request::JogStep { axis, distance_mm }
}

/// What the UI asks of its loop.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Send this request (in order) and give the reply to [`on_reply`].
    Send(Request),
    /// Leave the UI.
    Quit,
}

/// What the keys do now.
#[derive(Debug, Clone, PartialEq)]
pub enum Mode {
    /// The operator's keys.
    Normal,
    /// Typing an MDI block: every printable key is text; Enter sends, Esc cancels.
    Mdi(String),
    /// `t` was pressed: x, y or z touches that axis off to 0 in the active system;
    /// Esc cancels; any other key cancels and then acts as usual.
    TouchOff,
}

/// A continuous jog the UI holds (renews) while its key repeats.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldJog {
    /// The axis.
    pub axis: Axis,
    /// Signed speed sent (mm/min).
    pub speed_mm_per_min: f64,
    /// Last press or repeat of its key.
    pub key_at: Instant,
    /// Last `Jog` sent for it.
    pub sent_at: Instant,
}

/// The UI's own state (what is not in the status).
#[derive(Debug, Clone)]
pub struct Ui {
    /// What the keys do now.
    pub mode: Mode,
    /// Selected incremental step (index into [`JOG_STEPS_MM`]).
    pub step_idx: usize,
    /// Continuous jog mode (`c`) rather than incremental steps.
    pub continuous: bool,
    /// Selected continuous speed (index into [`JOG_SPEEDS_MM_PER_MIN`]).
    pub speed_idx: usize,
    /// The offsets panel shows in place of the live plot (`v`).
    pub offsets_view: bool,
    /// The last `Offsets` reply.
    pub offsets: Option<OffsetTable>,
    /// When the offsets were last asked for.
    pub offsets_asked_at: Option<Instant>,
    /// The key overlay (`?`).
    pub help: bool,
    /// The continuous jog being held, if any.
    pub jog: Option<HeldJog>,
    /// The last reply's message (or error), shown on the message line.
    pub note: String,
}

impl Default for Ui {
    fn default() -> Self {
        Ui {
            mode: Mode::Normal,
            step_idx: JOG_STEP_START,
            continuous: false,
            speed_idx: JOG_SPEED_START,
            offsets_view: false,
            offsets: None,
            offsets_asked_at: None,
            help: false,
            jog: None,
            note: String::new(),
        }
    }
}

impl Ui {
    /// The selected incremental step (mm).
    pub fn step_mm(&self) -> f64 {
        JOG_STEPS_MM[self.step_idx % JOG_STEPS_MM.len()]
    }

    /// The selected continuous jog speed (mm/min, unsigned).
    pub fn speed_mm_per_min(&self) -> f64 {
        JOG_SPEEDS_MM_PER_MIN[self.speed_idx.min(JOG_SPEEDS_MM_PER_MIN.len() - 1)]
    }
}

/// The axis and direction (+1 / −1) a jog key moves: ←/→ X−/X+, ↑/↓ Y+/Y−,
/// PgUp/PgDn Z+/Z−.
pub fn jog_key(code: KeyCode) -> Option<(Axis, f64)> {
    match code {
        KeyCode::Left => Some((Axis::X, -1.0)),
        KeyCode::Right => Some((Axis::X, 1.0)),
        KeyCode::Up => Some((Axis::Y, 1.0)),
        KeyCode::Down => Some((Axis::Y, -1.0)),
        KeyCode::PageUp => Some((Axis::Z, 1.0)),
        KeyCode::PageDown => Some((Axis::Z, -1.0)),
        _ => None,
    }
}

/// The switches as the status shows them (all off without a status).
fn switches(s: Option<&Status>) -> softnc_api::Switches {
    s.map(|s| s.switches).unwrap_or_default()
}

/// An override `steps` steps of `step` from `current` (rounded to the step first, so
/// repeated presses land on round percentages), within `0..=max` (`None`: no upper
/// bound here, the MMI checks it).
fn override_step(current: f64, step: f64, steps: f64, max: Option<f64>) -> f64 {
    let v = (((current / step).round() + steps) * step).max(0.0);
    max.map_or(v, |m| v.min(m))
}

/// The request that stops a continuous jog of `axis`.
fn stop_jog(axis: Axis) -> Action {
    Action::Send(jog(axis, 0.0))
}

/// What a key does: the requests to send, in order (and the UI's state changed).
/// `s` is the last status (for toggles, overrides and the active coordinate
/// system; `None` before one came), `now` the time of the key (for a held
/// continuous jog).
///
/// - F1 is an E-stop in every mode; Ctrl-C quits in every mode.
/// - In MDI entry only text, Backspace, Enter (send `Mdi`) and Esc (cancel) act.
/// - After `t`, x/y/z sends a `TouchOff` of that axis to 0 in the active system.
/// - A key other than a jog key or `,`/`.` first stops a held continuous jog.
/// - A key release (terminals that report them) of the held jog's axis stops it.
#[allow(clippy::too_many_lines)]
pub fn on_key(ui: &mut Ui, key: KeyEvent, s: Option<&Status>, now: Instant) -> Vec<Action> {
    let mut out = Vec::new();
    if key.kind == KeyEventKind::Release {
        if let (Some(j), Some((axis, _))) = (ui.jog, jog_key(key.code)) {
            if j.axis == axis {
                ui.jog = None;
                out.push(stop_jog(axis));
            }
        }
        return out;
    }
    let ctrl = key.modifiers.contains(KeyModifiers::CONTROL);
    if key.code == KeyCode::F(1) {
        // the E-stop stops a jog too: nothing is left to renew
        ui.jog = None;
        ui.mode = Mode::Normal;
        out.push(Action::Send(Request::EStop));
        return out;
    }
    if ctrl && key.code == KeyCode::Char('c') {
        if let Some(j) = ui.jog.take() {
            out.push(stop_jog(j.axis));
        }
        out.push(Action::Quit);
        return out;
    }
    match &mut ui.mode {
        Mode::Mdi(text) => {
            match key.code {
                KeyCode::Char(c) if !ctrl => text.push(c),
                KeyCode::Backspace => {
                    text.pop();
                }
                KeyCode::Enter => {
                    let block = text.trim().to_string();
                    ui.mode = Mode::Normal;
                    if !block.is_empty() {
                        out.push(Action::Send(Request::Mdi { blocks: block }));
                    }
                }
                KeyCode::Esc => ui.mode = Mode::Normal,
                _ => {}
            }
            return out;
        }
        Mode::TouchOff => {
            ui.mode = Mode::Normal;
            let axis = match key.code {
                KeyCode::Char(c) if !ctrl => "xyz".find(c.to_ascii_lowercase()).map(|i| AXES[i]),
                _ => None,
            };
            if let Some(axis) = axis {
                // the system the operator sees; the active one without a status
                out.push(Action::Send(Request::TouchOff {
                    axis,
                    value_mm: 0.0,
                    coords: s.map(|s| s.coords.clone()),
                }));
                return out;
            }
            if key.code == KeyCode::Esc {
                return out;
            }
            // any other key cancels the touch-off and acts as usual
        }
        Mode::Normal => {}
    }
    if ctrl {
        return out;
    }
    let jog = jog_key(key.code);
    let keeps_jog = jog.is_some() || matches!(key.code, KeyCode::Char(',' | '.'));
    if !keeps_jog {
        if let Some(j) = ui.jog.take() {
            out.push(stop_jog(j.axis));
        }
    }
    if let Some((axis, sign)) = jog {
        jog_request(ui, axis, sign, now, &mut out);
        return out;
    }
    let send = Action::Send;
    let feed = s.map_or(1.0, |s| s.feed_override);
    let spindle = s.and_then(|s| s.spindle_override).unwrap_or(1.0);
    let rapid = s.map_or(1.0, |s| s.rapid_override);
    let sw = switches(s);
    match key.code {
        KeyCode::Char('q') => out.push(Action::Quit),
        KeyCode::Char('?') => ui.help = !ui.help,
        KeyCode::Esc => {
            if ui.help {
                ui.help = false;
            } else {
                ui.offsets_view = false;
            }
        }
        KeyCode::Char('h') => out.push(send(Request::Hold)),
        KeyCode::Char('r') => out.push(send(Request::Resume)),
        KeyCode::Char('a') => out.push(send(Request::Abort)),
        KeyCode::Char('e') => out.push(send(Request::EStop)),
        KeyCode::Char('x') => out.push(send(Request::Reset)),
        KeyCode::Char('+') => out.push(send(Request::FeedOverride {
            fraction: override_step(feed, FEED_OVERRIDE_STEP, 1.0, Some(FEED_OVERRIDE_MAX)),
        })),
        KeyCode::Char('-') => out.push(send(Request::FeedOverride {
            fraction: override_step(feed, FEED_OVERRIDE_STEP, -1.0, Some(FEED_OVERRIDE_MAX)),
        })),
        KeyCode::Char(']') => out.push(send(Request::SpindleOverride {
            fraction: override_step(spindle, SPINDLE_OVERRIDE_STEP, 1.0, None),
        })),
        KeyCode::Char('[') => out.push(send(Request::SpindleOverride {
            fraction: override_step(spindle, SPINDLE_OVERRIDE_STEP, -1.0, None),
        })),
        KeyCode::Char('}') => out.push(send(Request::RapidOverride {
            fraction: override_step(rapid, RAPID_OVERRIDE_STEP, 1.0, Some(1.0)),
        })),
        KeyCode::Char('{') => out.push(send(Request::RapidOverride {
            fraction: override_step(rapid, RAPID_OVERRIDE_STEP, -1.0, Some(1.0)),
        })),
        KeyCode::Char('o') => out.push(send(Request::MachineOn)),
        KeyCode::Char('O') => out.push(send(Request::MachineOff)),
        KeyCode::Char('L') => out.push(send(Request::OverrideLimits)),
        KeyCode::Char('H') => out.push(send(Request::Home { axis: None })),
        KeyCode::Char('i') => ui.step_idx = (ui.step_idx + 1) % JOG_STEPS_MM.len(),
        KeyCode::Char('c') => ui.continuous = !ui.continuous,
        KeyCode::Char(',') => ui.speed_idx = ui.speed_idx.saturating_sub(1),
        KeyCode::Char('.') => {
            ui.speed_idx = (ui.speed_idx + 1).min(JOG_SPEEDS_MM_PER_MIN.len() - 1)
        }
        KeyCode::Char('m') => ui.mode = Mode::Mdi(String::new()),
        KeyCode::Char('t') => ui.mode = Mode::TouchOff,
        KeyCode::Char('v') => {
            ui.offsets_view = !ui.offsets_view;
            if ui.offsets_view {
                ui.offsets_asked_at = Some(now);
                out.push(send(Request::Offsets));
            }
        }
        KeyCode::Char('s') => out.push(send(Request::SingleBlock {
            on: !sw.single_block,
        })),
        KeyCode::Char('n') => out.push(send(Request::Step)),
        KeyCode::Char('1') => out.push(send(Request::OptionalStop {
            on: !sw.optional_stop,
        })),
        KeyCode::Char('/') => out.push(send(Request::BlockDelete {
            on: !sw.block_delete,
        })),
        _ => {}
    }
    out
}

/// A jog key: an incremental `JogStep` of the selected step, or in continuous mode a
/// `Jog` at the selected speed, held by the key's repeats (renewed at most every
/// [`JOG_RENEW`]); a jog of another axis is stopped first.
fn jog_request(ui: &mut Ui, axis: Axis, sign: f64, now: Instant, out: &mut Vec<Action>) {
    if !ui.continuous {
        out.push(Action::Send(jog_step(axis, sign * ui.step_mm())));
        return;
    }
    let speed = sign * ui.speed_mm_per_min();
    let renew = Action::Send(jog(axis, speed));
    match ui.jog.as_mut() {
        Some(j) if j.axis == axis && j.speed_mm_per_min == speed => {
            j.key_at = now;
            if now.duration_since(j.sent_at) >= JOG_RENEW {
                j.sent_at = now;
                out.push(renew);
            }
            return;
        }
        // the same axis at another speed or the other way: the MMI takes it at once
        Some(j) if j.axis == axis => {}
        Some(j) => out.push(stop_jog(j.axis)),
        None => {}
    }
    ui.jog = Some(HeldJog {
        axis,
        speed_mm_per_min: speed,
        key_at: now,
        sent_at: now,
    });
    out.push(renew);
}

/// The timers: a held continuous jog is renewed every [`JOG_RENEW`] and stopped
/// [`JOG_KEY_HOLD`] after its key's last press or repeat; the open offsets view is
/// refreshed every [`OFFSETS_REFRESH`].
pub fn on_tick(ui: &mut Ui, now: Instant) -> Vec<Action> {
    let mut out = Vec::new();
    if let Some(j) = ui.jog.as_mut() {
        if now.duration_since(j.key_at) > JOG_KEY_HOLD {
            let axis = j.axis;
            ui.jog = None;
            out.push(stop_jog(axis));
        } else if now.duration_since(j.sent_at) >= JOG_RENEW {
            j.sent_at = now;
            out.push(Action::Send(jog(j.axis, j.speed_mm_per_min)));
        }
    }
    if ui.offsets_view
        && !matches!(ui.offsets_asked_at, Some(t) if now.duration_since(t) < OFFSETS_REFRESH)
    {
        ui.offsets_asked_at = Some(now);
        out.push(Action::Send(Request::Offsets));
    }
    out
}

/// What a reply to `req` changes: the offsets view takes an `Offsets` reply; a
/// refused (or failed) `Jog` is no longer held; the message line shows the reply
/// (a refused stop of a jog that had already ended says nothing).
pub fn on_reply(ui: &mut Ui, req: &Request, reply: Result<Reply, String>) {
    let (accepted, message) = match reply {
        Ok(Reply::Offsets(table)) if *req == Request::Offsets => {
            ui.offsets = Some(table);
            return;
        }
        Ok(r) => (r.is_accepted(), r.message()),
        Err(e) => (false, e),
    };
    match req {
        Request::Jog {
            speed_mm_per_min, ..
        } if *speed_mm_per_min == 0.0 && !accepted => {}
        Request::Jog {
            axis,
            speed_mm_per_min,
        } if !accepted
            && ui
                .jog
                .is_some_and(|j| j.axis == *axis && j.speed_mm_per_min == *speed_mm_per_min) =>
        {
            ui.jog = None;
            ui.note = message;
        }
        _ => ui.note = message,
    }
}

/// The program text of a job, read once per job: the immutable copy the daemon runs
/// (`job.program`), or an MDI job's block(s) (`job.mdi`).
#[derive(Debug, Clone, PartialEq)]
pub struct Listing {
    /// The job it belongs to.
    pub job_id: u64,
    /// An MDI job's text rather than a program file.
    pub mdi: bool,
    /// The text (or why there is none).
    text: String,
    /// Byte range of each line in `text`.
    lines: Vec<std::ops::Range<usize>>,
}

impl Listing {
    /// A listing of `text` for `job_id`.
    pub fn from_text(job_id: u64, mdi: bool, text: String) -> Self {
        let mut lines = Vec::new();
        let mut start = 0;
        for l in text.split_inclusive('\n') {
            let body = l.trim_end_matches(['\n', '\r']).len();
            lines.push(start..start + body);
            start += l.len();
        }
        Listing {
            job_id,
            mdi,
            text,
            lines,
        }
    }

    /// The listing of a job: its MDI text, or the file at `job.program` (a line
    /// saying why when it is unreadable or not named).
    pub fn for_job(job: &JobRecord) -> Self {
        let job_id = job.job_id;
        if let Some(mdi) = &job.mdi {
            return Self::from_text(job_id, true, mdi.to_string());
        }
        let text = match &job.program {
            Some(path) => match std::fs::read(path) {
                Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
                Err(e) => format!("(cannot read the program {path}: {e})"),
            },
            None => "(the job names no program copy)".to_string(),
        };
        Self::from_text(job_id, false, text)
    }

    /// Keep `cache` for the status's job: read its program when the job changes
    /// (once per job), drop it when there is no job.
    pub fn refresh(cache: &mut Option<Listing>, s: Option<&Status>) {
        match s.and_then(|s| s.job.as_ref()) {
            None => *cache = None,
            Some(j) if cache.as_ref().is_some_and(|l| l.job_id == j.record.job_id) => {}
            Some(j) => *cache = Some(Self::for_job(&j.record)),
        }
    }

    /// How many lines.
    pub fn line_count(&self) -> usize {
        self.lines.len()
    }

    /// Line `n` (1-based, as `program_line`).
    pub fn line(&self, n: usize) -> Option<&str> {
        let r = self.lines.get(n.checked_sub(1)?)?;
        Some(&self.text[r.clone()])
    }

    /// The first line (1-based) of a window of `height` lines that shows `current`
    /// a third of the way down (or the top when there is no current line).
    pub fn window_start(&self, current: Option<usize>, height: usize) -> usize {
        let Some(c) = current else { return 1 };
        let last_start = self.line_count().saturating_sub(height) + 1;
        c.saturating_sub(height / 3).clamp(1, last_start.max(1))
    }
}

/// A status from JSON for the tests: `patch` laid over an idle machine's status
/// (objects merged key by key, a job's record given the fields it must have).
#[cfg(test)]
pub(crate) fn test_status(patch: serde_json::Value) -> Status {
    fn merge(base: &mut serde_json::Value, patch: serde_json::Value) {
        match (base, patch) {
            (serde_json::Value::Object(b), serde_json::Value::Object(p)) => {
                for (k, v) in p {
                    merge(b.entry(k).or_insert(serde_json::Value::Null), v);
                }
            }
            (b, p) => *b = p,
        }
    }
    let mut v = serde_json::json!({"state": "Idle", "coords": "G54",
        "offsets": {"g5x_mm": [0.0, 0.0, 0.0], "rotation_deg": 0.0,
            "g92_mm": [0.0, 0.0, 0.0], "tool_offset_mm": [0.0, 0.0, 0.0]},
        "tool": 0, "feed_override": 1.0,
        "processes": {"interp": "alive", "position": "alive", "supervisor": "alive"}});
    if patch["job"].is_object() {
        v["job"] = serde_json::json!({"job_id": 0, "path": "", "outcome": "running"});
    }
    merge(&mut v, patch);
    serde_json::from_value(v).expect("a status")
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn key(code: KeyCode) -> KeyEvent {
        KeyEvent::new(code, KeyModifiers::NONE)
    }

    fn ch(c: char) -> KeyEvent {
        key(KeyCode::Char(c))
    }

    fn sent(actions: &[Action]) -> Vec<Request> {
        actions
            .iter()
            .filter_map(|a| match a {
                Action::Send(r) => Some(r.clone()),
                Action::Quit => None,
            })
            .collect()
    }

    fn idle() -> Status {
        test_status(
            json!({"state": "Idle", "coords": "G55", "feed_override": 1.0, "spindle_override": 1.0,
               "switches": {"single_block": false, "optional_stop": true, "block_delete": false}}),
        )
    }

    fn ax(i: usize) -> Axis {
        AXES[i]
    }

    #[test]
    fn arrow_keys_jog_the_selected_step_and_i_cycles_it() {
        let mut ui = Ui::default();
        let t = Instant::now();
        let s = idle();
        let cases = [
            (KeyCode::Left, 0, -0.1),
            (KeyCode::Right, 0, 0.1),
            (KeyCode::Up, 1, 0.1),
            (KeyCode::Down, 1, -0.1),
            (KeyCode::PageUp, 2, 0.1),
            (KeyCode::PageDown, 2, -0.1),
        ];
        for (code, axis, mm) in cases {
            let r = sent(&on_key(&mut ui, key(code), Some(&s), t));
            assert_eq!(r, vec![jog_step(ax(axis), mm)]);
        }
        let mut steps = vec![];
        for _ in 0..4 {
            assert!(on_key(&mut ui, ch('i'), Some(&s), t).is_empty());
            steps.push(ui.step_mm());
        }
        assert_eq!(steps, vec![1.0, 10.0, 0.01, 0.1]);
        on_key(&mut ui, ch('i'), Some(&s), t);
        let r = sent(&on_key(&mut ui, key(KeyCode::PageDown), Some(&s), t));
        assert_eq!(r, vec![jog_step(ax(2), -1.0)]);
        assert!(ui.jog.is_none(), "an incremental jog is not held");
    }

    #[test]
    fn continuous_jog_is_held_by_key_repeats_and_stopped_after_the_last() {
        let mut ui = Ui::default();
        let t0 = Instant::now();
        let s = idle();
        on_key(&mut ui, ch('c'), Some(&s), t0);
        assert!(ui.continuous);
        on_key(&mut ui, ch('.'), Some(&s), t0);
        assert_eq!(ui.speed_mm_per_min(), 1200.0);
        let ms = |k: u64| t0 + Duration::from_millis(k);
        let r = sent(&on_key(&mut ui, key(KeyCode::Right), Some(&s), ms(0)));
        assert_eq!(r, vec![jog(ax(0), 1200.0)]);
        // a repeat sooner than JOG_RENEW sends nothing more, one later renews
        assert!(on_key(&mut ui, key(KeyCode::Right), Some(&s), ms(10)).is_empty());
        let r = sent(&on_key(&mut ui, key(KeyCode::Right), Some(&s), ms(120)));
        assert_eq!(r, vec![jog(ax(0), 1200.0)]);
        // the timer renews it while the key is held (the terminal's repeat delay) …
        let r = sent(&on_tick(&mut ui, ms(300)));
        assert_eq!(r, vec![jog(ax(0), 1200.0)]);
        assert!(on_tick(&mut ui, ms(310)).is_empty());
        // … and stops it JOG_KEY_HOLD after the last repeat
        let r = sent(&on_tick(&mut ui, ms(120 + 501)));
        assert_eq!(r, vec![jog(ax(0), 0.0)]);
        assert!(ui.jog.is_none());
        assert!(on_tick(&mut ui, ms(2000)).is_empty());
    }

    #[test]
    fn continuous_jog_stops_at_a_release_another_axis_or_any_other_key() {
        let mut ui = Ui {
            continuous: true,
            ..Ui::default()
        };
        let t = Instant::now();
        let s = idle();
        on_key(&mut ui, key(KeyCode::Up), Some(&s), t);
        // another axis: the first is stopped, then the new one starts
        let r = sent(&on_key(&mut ui, key(KeyCode::PageDown), Some(&s), t));
        assert_eq!(r, vec![jog(ax(1), 0.0), jog(ax(2), -600.0)]);
        // the other direction on the same axis: sent at once
        let r = sent(&on_key(&mut ui, key(KeyCode::PageUp), Some(&s), t));
        assert_eq!(r, vec![jog(ax(2), 600.0)]);
        // a release of its key stops it
        let mut release = key(KeyCode::PageUp);
        release.kind = KeyEventKind::Release;
        let r = sent(&on_key(&mut ui, release, Some(&s), t));
        assert_eq!(r, vec![jog(ax(2), 0.0)]);
        // any other key stops it before acting
        on_key(&mut ui, key(KeyCode::Left), Some(&s), t);
        let r = sent(&on_key(&mut ui, ch('h'), Some(&s), t));
        assert_eq!(r, vec![jog(ax(0), 0.0), Request::Hold]);
        // quitting stops it too
        on_key(&mut ui, key(KeyCode::Left), Some(&s), t);
        let a = on_key(&mut ui, ch('q'), Some(&s), t);
        assert_eq!(a, vec![Action::Send(jog(ax(0), 0.0)), Action::Quit]);
        // a refused jog is no longer held (nothing left to renew)
        let r = sent(&on_key(&mut ui, key(KeyCode::Left), Some(&s), t));
        on_reply(&mut ui, &r[0], Ok(Reply::refused("jog refused (Off)")));
        assert!(ui.jog.is_none());
        assert_eq!(ui.note, "jog refused (Off)");
    }

    #[test]
    fn mdi_entry_takes_every_key_as_text_and_enter_sends_it() {
        let mut ui = Ui::default();
        let t = Instant::now();
        let s = idle();
        on_key(&mut ui, ch('m'), Some(&s), t);
        assert_eq!(ui.mode, Mode::Mdi(String::new()));
        // e, x, q, h … are text here, not E-stop, reset, quit, hold
        for c in "G0 X1ehqx".chars() {
            assert!(on_key(&mut ui, ch(c), Some(&s), t).is_empty(), "{c} acted");
        }
        for _ in 0..4 {
            on_key(&mut ui, key(KeyCode::Backspace), Some(&s), t);
        }
        assert!(on_key(&mut ui, key(KeyCode::Left), Some(&s), t).is_empty());
        assert_eq!(ui.mode, Mode::Mdi("G0 X1".into()));
        let r = sent(&on_key(&mut ui, key(KeyCode::Enter), Some(&s), t));
        assert_eq!(
            r,
            vec![Request::Mdi {
                blocks: "G0 X1".into()
            }]
        );
        assert_eq!(ui.mode, Mode::Normal);
        // Esc cancels, an empty line sends nothing
        on_key(&mut ui, ch('m'), Some(&s), t);
        on_key(&mut ui, ch('G'), Some(&s), t);
        assert!(on_key(&mut ui, key(KeyCode::Esc), Some(&s), t).is_empty());
        assert_eq!(ui.mode, Mode::Normal);
        on_key(&mut ui, ch('m'), Some(&s), t);
        assert!(on_key(&mut ui, key(KeyCode::Enter), Some(&s), t).is_empty());
        // F1 is an E-stop even while typing
        on_key(&mut ui, ch('m'), Some(&s), t);
        let r = sent(&on_key(&mut ui, key(KeyCode::F(1)), Some(&s), t));
        assert_eq!(r, vec![Request::EStop]);
        assert_eq!(ui.mode, Mode::Normal);
    }

    #[test]
    fn switches_toggle_from_the_status_and_flow_keys_send_their_request() {
        let mut ui = Ui::default();
        let t = Instant::now();
        let s = idle();
        let one = |ui: &mut Ui, c: char| sent(&on_key(ui, ch(c), Some(&s), t));
        assert_eq!(one(&mut ui, 's'), vec![Request::SingleBlock { on: true }]);
        // optional stop is on in the status: `1` turns it off
        assert_eq!(one(&mut ui, '1'), vec![Request::OptionalStop { on: false }]);
        assert_eq!(one(&mut ui, '/'), vec![Request::BlockDelete { on: true }]);
        assert_eq!(one(&mut ui, 'n'), vec![Request::Step]);
        assert_eq!(one(&mut ui, 'H'), vec![Request::Home { axis: None }]);
        assert_eq!(one(&mut ui, 'o'), vec![Request::MachineOn]);
        assert_eq!(one(&mut ui, 'O'), vec![Request::MachineOff]);
        assert_eq!(one(&mut ui, 'e'), vec![Request::EStop]);
        assert_eq!(one(&mut ui, 'x'), vec![Request::Reset]);
        assert_eq!(one(&mut ui, 'L'), vec![Request::OverrideLimits]);
        let fraction = |r: &[Request]| match r {
            [Request::FeedOverride { fraction }] => ("feed", *fraction),
            [Request::SpindleOverride { fraction }] => ("spindle", *fraction),
            [Request::RapidOverride { fraction }] => ("rapid", *fraction),
            other => panic!("{other:?}"),
        };
        let (what, f) = fraction(&one(&mut ui, '+'));
        assert_eq!(what, "feed");
        assert!((f - 1.1).abs() < 1e-12, "{f}");
        let fast = test_status(json!({"feed_override": 2.5}));
        let r = sent(&on_key(&mut ui, ch('+'), Some(&fast), t));
        assert_eq!(fraction(&r), ("feed", FEED_OVERRIDE_MAX));
        let slow = test_status(json!({"feed_override": 0.0}));
        let r = sent(&on_key(&mut ui, ch('-'), Some(&slow), t));
        assert_eq!(fraction(&r), ("feed", 0.0));
        let (what, f) = fraction(&one(&mut ui, '['));
        assert_eq!(what, "spindle");
        assert!((f - 0.9).abs() < 1e-12);
        // the rapid override stays within 0..=100 %
        assert_eq!(fraction(&one(&mut ui, '}')), ("rapid", 1.0));
        let (what, f) = fraction(&one(&mut ui, '{'));
        assert_eq!(what, "rapid");
        assert!((f - 0.9).abs() < 1e-12, "{f}");
        assert!(on_key(&mut ui, ch('q'), Some(&s), t).contains(&Action::Quit));
    }

    #[test]
    fn touch_off_is_t_then_an_axis_letter_to_zero_in_the_shown_system() {
        let mut ui = Ui::default();
        let t = Instant::now();
        let s = idle();
        assert!(on_key(&mut ui, ch('t'), Some(&s), t).is_empty());
        assert_eq!(ui.mode, Mode::TouchOff);
        let r = sent(&on_key(&mut ui, ch('y'), Some(&s), t));
        assert_eq!(
            r,
            vec![Request::TouchOff {
                axis: Axis::Y,
                value_mm: 0.0,
                coords: Some("G55".into())
            }]
        );
        assert_eq!(ui.mode, Mode::Normal);
        // `x` after `t` is the X axis, not a reset
        on_key(&mut ui, ch('t'), Some(&s), t);
        let r = sent(&on_key(&mut ui, ch('x'), Some(&s), t));
        assert!(
            matches!(r[0], Request::TouchOff { axis: Axis::X, .. }),
            "{r:?}"
        );
        // Esc cancels; another key cancels and acts (an E-stop stays an E-stop)
        on_key(&mut ui, ch('t'), Some(&s), t);
        assert!(on_key(&mut ui, key(KeyCode::Esc), Some(&s), t).is_empty());
        assert_eq!(ui.mode, Mode::Normal);
        on_key(&mut ui, ch('t'), Some(&s), t);
        let r = sent(&on_key(&mut ui, ch('e'), Some(&s), t));
        assert_eq!(r, vec![Request::EStop]);
        assert_eq!(ui.mode, Mode::Normal);
    }

    #[test]
    fn offsets_view_asks_when_opened_and_refreshes_while_open() {
        let mut ui = Ui::default();
        let t0 = Instant::now();
        let s = idle();
        let r = sent(&on_key(&mut ui, ch('v'), Some(&s), t0));
        assert_eq!(r, vec![Request::Offsets]);
        assert!(ui.offsets_view);
        on_reply(
            &mut ui,
            &r[0],
            Ok(Reply::Offsets(OffsetTable {
                active: "G55".into(),
                systems: vec![],
                g92_mm: [0.0; 3],
                tool: 0,
                tool_offset_mm: [0.0; 3],
            })),
        );
        assert_eq!(ui.offsets.as_ref().unwrap().active, "G55");
        assert!(on_tick(&mut ui, t0 + Duration::from_millis(500)).is_empty());
        let r = sent(&on_tick(&mut ui, t0 + OFFSETS_REFRESH));
        assert_eq!(r, vec![Request::Offsets]);
        assert!(on_key(&mut ui, ch('v'), Some(&s), t0).is_empty());
        assert!(!ui.offsets_view);
        assert!(on_tick(&mut ui, t0 + 10 * OFFSETS_REFRESH).is_empty());
    }

    #[test]
    fn help_toggles_and_esc_closes_it_without_quitting() {
        let mut ui = Ui::default();
        let t = Instant::now();
        let s = idle();
        on_key(&mut ui, ch('?'), Some(&s), t);
        assert!(ui.help);
        assert!(on_key(&mut ui, key(KeyCode::Esc), Some(&s), t).is_empty());
        assert!(!ui.help);
        let ctrl_c = KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL);
        assert_eq!(on_key(&mut ui, ctrl_c, Some(&s), t), vec![Action::Quit]);
        assert!(!ui.continuous, "Ctrl-C is not `c`");
    }

    #[test]
    fn the_listing_is_read_once_per_job_and_windows_the_current_line() {
        let dir = std::env::temp_dir().join(format!("softnc-watch-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.ngc");
        let text: String = (1..=20).map(|k| format!("N{k} G1 X{k}\r\n")).collect();
        std::fs::write(&path, &text).unwrap();
        let s = test_status(json!({"job": {"job_id": 4, "program": path.to_str().unwrap()}}));
        let mut cache = None;
        Listing::refresh(&mut cache, Some(&s));
        let l = cache.clone().unwrap();
        assert_eq!(
            (l.line_count(), l.line(1), l.line(20)),
            (20, Some("N1 G1 X1"), Some("N20 G1 X20"))
        );
        assert_eq!(l.line(0), None);
        assert_eq!(l.line(21), None);
        // the same job is not read again (the file may go)
        std::fs::remove_file(&path).unwrap();
        Listing::refresh(&mut cache, Some(&s));
        assert_eq!(cache.as_ref(), Some(&l));
        // a new job is read; an MDI job lists its text
        let mdi = test_status(json!({"job": {"job_id": 5, "mdi": "G0 X1\nG0 Y2"}}));
        Listing::refresh(&mut cache, Some(&mdi));
        let m = cache.clone().unwrap();
        assert!(m.mdi);
        assert_eq!(m.line(2), Some("G0 Y2"));
        let gone = test_status(json!({"job": {"job_id": 6, "program": path.to_str().unwrap()}}));
        Listing::refresh(&mut cache, Some(&gone));
        assert!(cache
            .as_ref()
            .unwrap()
            .line(1)
            .unwrap()
            .contains("cannot read"));
        Listing::refresh(&mut cache, Some(&test_status(json!({"job": null}))));
        assert!(cache.is_none());
        // windows: the current line a third of the way down, within the text
        assert_eq!(l.window_start(None, 6), 1);
        assert_eq!(l.window_start(Some(2), 6), 1);
        assert_eq!(l.window_start(Some(10), 6), 8);
        assert_eq!(l.window_start(Some(20), 6), 15);
        assert_eq!(m.window_start(Some(2), 6), 1);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
