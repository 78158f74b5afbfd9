//! `softnc watch`: the operator's terminal UI (issue 19, machine operation) on an
//! 80×24 terminal or larger — state, coordinate system, tool, overrides and the
//! single block / optional stop / block delete switches; the job's progress; the DRO
//! (machine, work and actual position, following error, homed flag per axis); the
//! live contour error or the offsets; the program listing around the current line;
//! loop jitter and alarms; a message line (replies, the MDI entry, the touch-off
//! prompt); the keys on the last two lines.
//!
//! Keys (what they do is `watch_keys::on_key`, tested without a daemon; `?` shows
//! them all):
//! - jog: ←/→ X−/X+, ↑/↓ Y+/Y−, PgUp/PgDn Z+/Z−, by the selected step (`i` cycles
//!   0.01, 0.1, 1, 10 mm); `c` continuous: a key held (its repeats) jogs at the
//!   selected speed (`,`/`.`: 60 … 6000 mm/min) and the jog stops 0.5 s after the
//!   last repeat, at the release where the terminal reports it, at any other key, or
//!   by the MMI's dead-man if the UI goes away;
//! - `H` home all axes, `o` machine on, `O` machine off;
//! - `m` MDI line (text, Backspace, Enter sends, Esc cancels; other keys type);
//! - `t` then `x`/`y`/`z`: touch that axis off to 0 in the active system;
//! - `v` offsets view (G54 … G59.3, G92, tool), in place of the live plot;
//! - `s` single block, `n` next block, `1` optional stop, `/` block delete;
//! - `h` hold, `r` resume, `a` abort, `+`/`-` feed ±10 %, `]`/`[` spindle ±10 %;
//! - `e` (or F1, which also works while typing MDI) E-stop, `x` reset, `L`
//!   override the limit switches (to switch on and jog off a tripped one);
//! - `?` help, Esc closes it (or the offsets view), `q` or Ctrl-C quits.

use crate::watch_keys::{self, Action, Listing, Mode, Ui, AXES, KEY_MAP};
use anyhow::Result;
use ratatui::crossterm::event::{
    self, Event, KeyboardEnhancementFlags, PopKeyboardEnhancementFlags,
    PushKeyboardEnhancementFlags,
};
use ratatui::crossterm::execute;
use ratatui::layout::{Constraint, Direction, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis, Block, Borders, Chart, Clear, Dataset, Gauge, GraphType, List, ListItem, Paragraph, Row,
    Table, Wrap,
};
use softnc_api::{MachineState, Request, Status};
use softnc_client::Operator;
use std::collections::VecDeque;
use std::path::Path;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Points kept in the live plot.
const PLOT_POINTS: usize = 300;
/// The status is asked for this often (and the screen drawn).
const STATUS_PERIOD: Duration = Duration::from_millis(100);
/// How long the loop waits for a key before it runs its timers (status, the held
/// jog's renewal): a fifth of `watch_keys::JOG_RENEW`, so a held jog is renewed
/// within 1.2 × `JOG_RENEW` of the last renewal.
const INPUT_POLL: Duration = Duration::from_millis(5);

/// Ask the terminal to report key repeats and releases (kitty keyboard protocol),
/// where it can: a continuous jog then stops at the key's release. Returns whether
/// it was turned on (to be turned off on the way out).
fn report_key_releases() -> bool {
    let supported = matches!(
        ratatui::crossterm::terminal::supports_keyboard_enhancement(),
        Ok(true)
    );
    supported
        && execute!(
            std::io::stdout(),
            PushKeyboardEnhancementFlags(
                KeyboardEnhancementFlags::DISAMBIGUATE_ESCAPE_CODES
                    | KeyboardEnhancementFlags::REPORT_EVENT_TYPES
            )
        )
        .is_ok()
}

/// Send one request and give its reply to the UI.
fn send(op: &Operator, ui: &mut Ui, r: &Request) {
    let reply = op.request(r).map_err(|e| e.to_string());
    watch_keys::on_reply(ui, r, reply);
}

/// What the screen shows: the last status, or why there is none.
pub type Shown = Result<Status, String>;

/// Run the terminal UI until `q` (or Ctrl-C).
pub fn run(config: &Path) -> Result<ExitCode> {
    let op = Operator::connect(config)?;
    let mut terminal = ratatui::init();
    let enhanced = report_key_releases();
    if enhanced {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let _ = execute!(std::io::stdout(), PopKeyboardEnhancementFlags);
            previous(info);
        }));
    }
    let mut plot: VecDeque<(f64, f64)> = VecDeque::with_capacity(PLOT_POINTS);
    let mut tick = 0u64;
    let mut ui = Ui::default();
    let mut listing: Option<Listing> = None;
    let mut s: Shown = Err("connecting".to_string());
    let mut status_at: Option<Instant> = None;
    let result = (|| -> Result<()> {
        loop {
            let mut redraw = false;
            if !matches!(status_at, Some(t) if t.elapsed() < STATUS_PERIOD) {
                status_at = Some(Instant::now());
                s = op.status().map_err(|e| format!("no MMI: {e}"));
                tick += 1;
                let contour = s
                    .as_ref()
                    .ok()
                    .and_then(|s| s.axes.as_ref()?.contour_err_um);
                if let Some(c) = contour {
                    if plot.len() == PLOT_POINTS {
                        plot.pop_front();
                    }
                    plot.push_back((tick as f64, c));
                }
                Listing::refresh(&mut listing, s.as_ref().ok());
                redraw = true;
            }
            let mut actions = Vec::new();
            if event::poll(INPUT_POLL)? {
                if let Event::Key(k) = event::read()? {
                    actions = watch_keys::on_key(&mut ui, k, s.as_ref().ok(), Instant::now());
                    redraw = true;
                }
            }
            actions.extend(watch_keys::on_tick(&mut ui, Instant::now()));
            for a in actions {
                match a {
                    Action::Quit => return Ok(()),
                    Action::Send(r) => {
                        send(&op, &mut ui, &r);
                        redraw = true;
                    }
                }
            }
            if redraw {
                terminal.draw(|f| draw(f, &s, &plot, &ui, listing.as_ref()))?;
            }
        }
    })();
    // a jog left held (an error on the way out) is stopped, not left to the dead-man
    if let Some(j) = ui.jog.take() {
        let _ = op.request(&watch_keys::jog(j.axis, 0.0));
    }
    if enhanced {
        let _ = execute!(std::io::stdout(), PopKeyboardEnhancementFlags);
    }
    ratatui::restore();
    result.map(|()| ExitCode::SUCCESS)
}

/// A number for the screen: `-` where there is none (idle, no status yet), never NaN.
/// In `width` columns (0: as wide as it takes): fixed-point when it fits, else
/// scientific with the digits that fit, else `#`s — never digits cut off (a wrong
/// value).
fn num(v: Option<f64>, scale: f64, width: usize, decimals: usize) -> String {
    let Some(x) = v.map(|x| x * scale).filter(|x| x.is_finite()) else {
        return format!("{:>width$}", "-");
    };
    let fixed = format!("{x:width$.decimals$}");
    if width == 0 || fixed.chars().count() <= width {
        return fixed;
    }
    (0..=decimals)
        .rev()
        .map(|p| format!("{x:>width$.p$e}"))
        .find(|t| t.chars().count() <= width)
        .unwrap_or_else(|| "#".repeat(width))
}

/// The keys that stop or clear the machine, first on the last line, always shown
/// (F1 also works while typing MDI).
const KEY_HELP_STOP: &str = "F1, e E-STOP";
/// The rest of the last line in the operator's mode (all keys: `?`).
const KEY_HELP: &str = "  x reset  h hold  r resume  a abort  m MDI  t touch  v offs  ? all";
/// The last line while typing an MDI block.
const KEY_HELP_MDI: &str = "  Enter send  Esc cancel  Backspace erase  (keys type text)";

/// The line above the last while typing an MDI block (the jog keys do not act).
const MDI_HELP: &str = "MDI: the block runs as a job from where the machine stands";

/// The jog keys and the jog mode, for the line above the last.
fn jog_help(ui: &Ui) -> String {
    let how = if ui.continuous {
        format!("{} mm/min (,/.)  c steps", ui.speed_mm_per_min())
    } else {
        format!("step {} mm (i)  c continuous", ui.step_mm())
    };
    format!("jog ←→ X  ↑↓ Y  PgUp/PgDn Z  {how}  H home  o/O on/off")
}

/// The state shown: the machine's, or why there is no status.
fn state_text(shown: &Shown) -> String {
    match shown {
        Ok(s) => s.state.to_string(),
        Err(e) => e.clone(),
    }
}

/// The status line: state (and the processes when one is not alive), coordinate
/// system, tool, overrides, switches.
fn header(shown: &Shown) -> String {
    let mut head = state_text(shown);
    let Ok(s) = shown else {
        return head;
    };
    let on = |v: bool| if v { "on" } else { "off" };
    for (p, health) in [
        ("interp", s.processes.interp),
        ("position", s.processes.position),
    ] {
        if health != softnc_api::ProcessHealth::Alive {
            head.push_str(&format!("  {p} {health}"));
        }
    }
    // the tool in the spindle (→ the one prepared); the spindle's actual speed /
    // the job's command (`*`: at speed), else the speed the position process uses
    let tool = match s.tool_prepared {
        Some(p) if p != s.tool => format!("T{}→{p}", s.tool),
        _ => format!("T{}", s.tool),
    };
    let rpm = match s.spindle {
        Some(sp) => format!(
            "{:.0}/{:.0}{}",
            sp.actual_rpm,
            sp.commanded_rpm,
            if sp.at_speed { "*" } else { "" }
        ),
        None => num(s.spindle_rpm, 1.0, 0, 0),
    };
    head.push_str(&format!(
        "  {}  {tool}  feed {}% spindle {}% {rpm} rpm  SB {} OS {} BD {}",
        s.coords,
        num(Some(s.feed_override), 100.0, 0, 0),
        num(s.spindle_override, 100.0, 0, 0),
        on(s.switches.single_block),
        on(s.switches.optional_stop),
        on(s.switches.block_delete),
    ));
    head
}

/// The message line: the prompt of the machine stop the running job waits at
/// (highlighted), the reply to the operator's last key, coolant and the operator
/// message (`(MSG,…)`). (The spindle's speeds and the tools are on the status line.)
fn machine_line(s: Option<&Status>, note: &str) -> Line<'static> {
    let mut spans = Vec::new();
    if let Some(p) = s.and_then(|s| s.prompt.as_ref()) {
        spans.push(Span::styled(
            format!("{p}  "),
            Style::default()
                .fg(Color::Black)
                .bg(Color::Yellow)
                .add_modifier(Modifier::BOLD),
        ));
    }
    if !note.is_empty() {
        spans.push(Span::raw(format!("{note}  ")));
    }
    if let Some(s) = s {
        let coolant = match (s.coolant.mist, s.coolant.flood) {
            (false, false) => "off",
            (true, false) => "mist",
            (false, true) => "flood",
            (true, true) => "mist+flood",
        };
        spans.push(Span::raw(format!("coolant {coolant}")));
        if let Some(m) = &s.message {
            spans.push(Span::styled(
                format!("  MSG {m}"),
                Style::default().add_modifier(Modifier::BOLD),
            ));
        }
    }
    Line::from(spans)
}

/// The style of the state on the status line.
fn state_style(state: Option<MachineState>) -> Style {
    use MachineState as M;
    match state {
        Some(M::EStopped | M::Faulted) => Style::default()
            .fg(Color::White)
            .bg(Color::Red)
            .add_modifier(Modifier::BOLD),
        Some(M::Running | M::Mdi | M::Jogging | M::Homing) => Style::default().fg(Color::Green),
        Some(M::Held | M::Paused | M::Stopping) => Style::default().fg(Color::Yellow),
        _ => Style::default(),
    }
}

/// The style of the program's current line.
fn current_line_style() -> Style {
    Style::default()
        .fg(Color::Black)
        .bg(Color::Yellow)
        .add_modifier(Modifier::BOLD)
}

/// The screen, laid out to fit an 80×24 terminal: the status line, the job's
/// progress, the DRO, the live contour error (or the offsets) beside the program
/// listing, loops and alarms, the message line, two lines of keys; `?` lays the key
/// map over the middle.
fn draw(
    frame: &mut ratatui::Frame,
    shown: &Shown,
    plot: &VecDeque<(f64, f64)>,
    ui: &Ui,
    listing: Option<&Listing>,
) {
    // the alarms' pane grows (from the middle, down to its minimum) to show every
    // alarm whole, wrapped
    let alarm_inner_width = (frame.area().width as usize * ALARMS_PCT as usize / 100)
        .saturating_sub(2)
        .max(1);
    let s = shown.as_ref().ok();
    let alarm_rows = alarm_lines(s)
        .iter()
        .map(|l| wrapped_rows(l, alarm_inner_width))
        .sum::<usize>();
    let bottom_rows = (alarm_rows as u16 + 2).max(LOOPS_ALARMS_MIN_ROWS);
    let rows = Layout::default()
        .direction(Direction::Vertical)
        .constraints([
            Constraint::Length(1),
            Constraint::Length(1),
            Constraint::Length(6),
            Constraint::Min(6),
            Constraint::Max(bottom_rows),
            Constraint::Length(1),
            Constraint::Length(2),
        ])
        .split(frame.area());
    let head = header(shown);
    let (state_part, rest) = head.split_at(head.find("  ").unwrap_or(head.len()));
    frame.render_widget(
        Paragraph::new(Line::from(vec![
            Span::styled(state_part.to_string(), state_style(s.map(|s| s.state))),
            Span::raw(rest.to_string()),
        ])),
        rows[0],
    );
    draw_job(frame, s, rows[1]);
    draw_dro(frame, s, rows[2]);
    if ui.offsets_view {
        draw_offsets(frame, s, ui, rows[3]);
    } else {
        let middle = Layout::default()
            .direction(Direction::Horizontal)
            .constraints([Constraint::Percentage(50), Constraint::Percentage(50)])
            .split(rows[3]);
        draw_plot(frame, plot, middle[0]);
        draw_listing(frame, s, listing, middle[1]);
    }
    draw_loops_and_alarms(frame, s, rows[4]);
    let coords = s.map_or("the active system", |s| s.coords.as_str());
    let message = match &ui.mode {
        Mode::Mdi(text) => Line::from(vec![
            Span::styled("MDI> ", Style::default().add_modifier(Modifier::BOLD)),
            Span::raw(text.clone()),
            Span::styled("_", Style::default().add_modifier(Modifier::SLOW_BLINK)),
        ]),
        Mode::TouchOff => Line::styled(
            format!("touch-off: x, y or z sets that axis to 0 in {coords}; Esc cancels"),
            Style::default().fg(Color::Yellow),
        ),
        // the reply to the last key while there is one, else the machine around
        // the axes
        // a machine stop's prompt first, the reply to the last key, the machine
        Mode::Normal => machine_line(s, &ui.note),
    };
    frame.render_widget(Paragraph::new(message), rows[5]);
    let (first, stop, rest) = match ui.mode {
        Mode::Mdi(_) => (MDI_HELP.to_string(), "F1 E-STOP", KEY_HELP_MDI),
        _ => (jog_help(ui), KEY_HELP_STOP, KEY_HELP),
    };
    frame.render_widget(
        Paragraph::new(vec![
            Line::raw(first),
            Line::from(vec![
                Span::styled(
                    stop,
                    Style::default().fg(Color::Red).add_modifier(Modifier::BOLD),
                ),
                Span::raw(rest),
            ]),
        ]),
        rows[6],
    );
    if ui.help {
        let area = Rect {
            height: rows[3].height + rows[4].height,
            ..rows[3]
        };
        let lines: Vec<Line> = KEY_MAP
            .iter()
            .map(|(a, b)| Line::raw(format!("{a:<38} {b}")))
            .collect();
        frame.render_widget(Clear, area);
        frame.render_widget(
            Paragraph::new(lines).block(
                Block::default()
                    .borders(Borders::ALL)
                    .title("keys (? or Esc closes)"),
            ),
            area,
        );
    }
}

/// The job's progress bar, with the job, its outcome, the line and the file.
fn draw_job(frame: &mut ratatui::Frame, s: Option<&Status>, area: Rect) {
    let job = s.and_then(|s| s.job.as_ref());
    let progress = job.map_or(0.0, |j| j.progress).clamp(0.0, 1.0);
    let label = match job {
        None => "no job".to_string(),
        Some(j) => {
            let line = s
                .and_then(|s| s.program_line)
                .map_or(String::new(), |l| format!(" line {l}"));
            let what = if j.record.mdi.is_some() {
                "MDI"
            } else {
                j.record.path.as_str()
            };
            format!(
                "job {} {} {:.0} %{line}  {what}",
                j.record.job_id,
                j.record.outcome,
                progress * 100.0,
            )
        }
    };
    frame.render_widget(
        Gauge::default()
            .gauge_style(Style::default().fg(Color::Green))
            .ratio(progress)
            .label(label),
        area,
    );
}

/// The DRO: per axis (`*` when homed) the machine position (the command), the work
/// position (in the active system, G92 and tool offset taken off), the distance
/// to go, the actual position and the following error; the active system in the title.
fn draw_dro(frame: &mut ratatui::Frame, s: Option<&Status>, area: Rect) {
    let axes = s.and_then(|s| s.axes.as_ref());
    let table_rows: Vec<Row> = (0..AXES.len())
        .map(|i| {
            let homed = if s.is_some_and(|s| s.homed.get(i) == Some(&true)) {
                '*'
            } else {
                ' '
            };
            let at = |v: Option<&[f64]>| v.and_then(|v| v.get(i).copied());
            Row::new(vec![
                format!("{} {homed}", AXES[i].name()),
                num(
                    at(s.and_then(|s| s.machine_mm.as_ref()).map(|m| &m[..])),
                    1.0,
                    11,
                    4,
                ),
                num(
                    at(s.and_then(|s| s.work_mm.as_ref()).map(|m| &m[..])),
                    1.0,
                    11,
                    4,
                ),
                num(at(s.map(|s| &s.distance_to_go_mm[..])), 1.0, 11, 4),
                num(at(axes.map(|a| &a.actual_mm[..])), 1.0, 11, 4),
                num(at(axes.map(|a| &a.following_err_um[..])), 1.0, 11, 2),
            ])
        })
        .collect();
    let table = Table::new(
        table_rows,
        [
            Constraint::Length(4),
            Constraint::Length(12),
            Constraint::Length(12),
            Constraint::Length(12),
            Constraint::Length(12),
            Constraint::Length(13),
        ],
    )
    .header(Row::new(vec![
        "axis",
        " machine mm",
        "    work mm",
        "   to go mm",
        "  actual mm",
        "following µm",
    ]))
    .block(Block::default().borders(Borders::ALL).title(format!(
        "DRO {}  (* homed)  contour error {} µm  ring {}",
        s.map_or("-", |s| s.coords.as_str()),
        num(axes.and_then(|a| a.contour_err_um), 1.0, 0, 2),
        axes.map_or("-".into(), |a| a.ring_fill.to_string())
    )));
    frame.render_widget(table, area);
}

/// The live contour error.
fn draw_plot(frame: &mut ratatui::Frame, plot: &VecDeque<(f64, f64)>, area: Rect) {
    let data: Vec<(f64, f64)> = plot.iter().copied().collect();
    let (x0, x1) = (
        data.first().map_or(0.0, |p| p.0),
        data.last().map_or(1.0, |p| p.0),
    );
    let ymax = data.iter().map(|p| p.1.abs()).fold(1.0, f64::max);
    let chart = Chart::new(vec![Dataset::default()
        .marker(symbols::Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::default().fg(Color::Cyan))
        .data(&data)])
    .block(
        Block::default()
            .borders(Borders::ALL)
            .title("contour error µm (live)"),
    )
    .x_axis(Axis::default().bounds([x0, x1.max(x0 + 1.0)]))
    .y_axis(Axis::default().bounds([-ymax, ymax]).labels(vec![
        Line::from(format!("{:.1}", -ymax)),
        Line::from("0"),
        Line::from(format!("{:.1}", ymax)),
    ]));
    frame.render_widget(chart, area);
}

/// The program around the current line (`program_line`), which is highlighted and
/// marked `>`; an MDI job lists its block(s).
fn draw_listing(
    frame: &mut ratatui::Frame,
    s: Option<&Status>,
    listing: Option<&Listing>,
    area: Rect,
) {
    let height = area.height.saturating_sub(2) as usize;
    let current = s.and_then(|s| s.program_line).map(|l| l as usize);
    let (title, lines) = match listing {
        None => ("program".to_string(), vec![Line::raw("(no job)")]),
        Some(l) => {
            let what = if l.mdi { "MDI" } else { "program" };
            let title = match current {
                Some(c) => format!("{what}  line {c}/{}", l.line_count()),
                None => format!("{what}  {} lines", l.line_count()),
            };
            let first = l.window_start(current, height);
            let lines = (first..first + height)
                .filter_map(|n| {
                    let text = l.line(n)?;
                    Some(if Some(n) == current {
                        Line::styled(format!(">{n:>5} {text}"), current_line_style())
                    } else {
                        Line::raw(format!(" {n:>5} {text}"))
                    })
                })
                .collect();
            (title, lines)
        }
    };
    frame.render_widget(
        Paragraph::new(lines).block(Block::default().borders(Borders::ALL).title(title)),
        area,
    );
}

/// One entry of the offsets panel: name, `*` when active, X Y Z (mm), 37 columns.
fn offsets_entry(name: &str, active: bool, mm: Option<[f64; 3]>) -> String {
    let at = |i: usize| mm.map(|m| m[i]);
    format!(
        "{name:<6}{}{}{}{}",
        if active { '*' } else { ' ' },
        num(at(0), 1.0, 10, 3),
        num(at(1), 1.0, 10, 3),
        num(at(2), 1.0, 10, 3)
    )
}

/// The offsets: the origins of G54 … G59.3 (the `Offsets` reply, two per line, the
/// active one marked and highlighted), G92 and the tool offset (live, from the
/// status).
fn draw_offsets(frame: &mut ratatui::Frame, s: Option<&Status>, ui: &Ui, area: Rect) {
    let columns = format!("{:<7}{:>10}{:>10}{:>10}", "", "X", "Y", "Z");
    let mut lines = vec![Line::raw(format!("{columns}   {columns}"))];
    let systems = ui.offsets.as_ref().map_or(&[][..], |o| &o.systems[..]);
    if ui.offsets.is_none() {
        lines.push(Line::raw("(asking softnc-mmi for the offsets …)"));
    }
    for pair in systems.chunks(2) {
        let mut spans = Vec::new();
        for (k, sys) in pair.iter().enumerate() {
            let text = offsets_entry(&sys.coords, sys.active, Some(sys.origin_mm));
            if k > 0 {
                spans.push(Span::raw("   "));
            }
            spans.push(if sys.active {
                Span::styled(text, current_line_style())
            } else {
                Span::raw(text)
            });
        }
        lines.push(Line::from(spans));
    }
    let o = s.map(|s| s.offsets);
    let tool = format!("T{}", s.map_or("-".into(), |s| s.tool.to_string()));
    lines.push(Line::raw(format!(
        "{}   {}",
        offsets_entry("G92", false, o.map(|o| o.g92_mm)),
        offsets_entry(&tool, false, o.map(|o| o.tool_offset_mm))
    )));
    let title = format!(
        "offsets (v closes)  active {}  rotation {}°  t x/y/z: touch off to 0",
        s.map_or("-", |s| s.coords.as_str()),
        num(o.map(|o| o.rotation_deg), 1.0, 0, 1)
    );
    frame.render_widget(
        Paragraph::new(lines).block(Block::default().borders(Borders::ALL).title(title)),
        area,
    );
}

/// The rows of the loops-and-alarms pane when no alarm needs more (borders included).
const LOOPS_ALARMS_MIN_ROWS: u16 = 4;
/// The alarms' share of the screen's width (the loops have the rest).
const ALARMS_PCT: u16 = 60;

/// The alarms as lines of text (`code: message`).
fn alarm_lines(s: Option<&Status>) -> Vec<String> {
    s.map_or(&[][..], |s| &s.alarms[..])
        .iter()
        .map(|a| format!("{:?}: {}", a.code, a.message))
        .collect()
}

/// How many rows `text` takes wrapped at word boundaries into `width` columns (a
/// word longer than a row is broken).
fn wrapped_rows(text: &str, width: usize) -> usize {
    let mut rows = 1;
    let mut used = 0;
    for word in text.split(' ') {
        let len = word.chars().count();
        let need = if used == 0 { len } else { used + 1 + len };
        if need <= width {
            used = need;
        } else {
            rows += (used > 0) as usize + len.saturating_sub(1) / width;
            used = if len % width == 0 && len > 0 {
                width
            } else {
                len % width
            };
        }
    }
    rows
}

/// Loop jitter and the alarms.
fn draw_loops_and_alarms(frame: &mut ratatui::Frame, s: Option<&Status>, area: Rect) {
    let bottom = Layout::default()
        .direction(Direction::Horizontal)
        .constraints([
            Constraint::Percentage(100 - ALARMS_PCT),
            Constraint::Percentage(ALARMS_PCT),
        ])
        .split(area);
    let mut loops = vec![];
    let timing = s.map(|s| s.loops).unwrap_or_default();
    for (name, l) in [("interp", timing.interp), ("position", timing.position)] {
        if let Some(l) = l {
            loops.push(ListItem::new(format!(
                "{name}: p99 {} max {} µs",
                num(Some(l.jitter_ns.p99 as f64), 1e-3, 0, 1),
                num(Some(l.jitter_ns.max as f64), 1e-3, 0, 1)
            )));
        }
    }
    frame.render_widget(
        List::new(loops).block(Block::default().borders(Borders::ALL).title("loop jitter")),
        bottom[0],
    );
    // wrapped, not cut: an alarm's end is often what to do
    let alarms: Vec<Line> = alarm_lines(s).into_iter().map(Line::raw).collect();
    frame.render_widget(
        Paragraph::new(alarms)
            .wrap(Wrap { trim: false })
            .block(Block::default().borders(Borders::ALL).title("alarms")),
        bottom[1],
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::backend::TestBackend;
    use ratatui::buffer::Buffer;
    use ratatui::Terminal;

    fn render(
        s: &serde_json::Value,
        ui: &Ui,
        listing: Option<&Listing>,
        width: u16,
        height: u16,
    ) -> (String, Buffer) {
        let mut t = Terminal::new(TestBackend::new(width, height)).unwrap();
        let plot: VecDeque<(f64, f64)> = (0..50).map(|k| (k as f64, (k as f64).sin())).collect();
        // a status, or (a JSON string) why there is none
        let shown: Shown = match s.as_str() {
            Some(why) => Err(why.to_string()),
            None => Ok(crate::watch_keys::test_status(s.clone())),
        };
        t.draw(|f| draw(f, &shown, &plot, ui, listing)).unwrap();
        let buf = t.backend().buffer().clone();
        let mut out = String::new();
        for y in 0..buf.area.height {
            for x in 0..buf.area.width {
                out.push_str(buf[(x, y)].symbol());
            }
            out.push('\n');
        }
        (out, buf)
    }

    fn screen(s: &serde_json::Value, width: u16, height: u16) -> String {
        render(s, &Ui::default(), None, width, height).0
    }

    fn running() -> serde_json::Value {
        serde_json::json!({
            "state": "Running", "feed_override": 1.0, "spindle_override": 1.0, "spindle_rpm": 0.0,
            "homed": [true, true, false], "coords": "G55", "tool": 2,
            "machine_mm": [1.0, 2.0, 3.0], "work_mm": [-9.0, -18.0, 3.0],
            "switches": {"single_block": true, "optional_stop": false, "block_delete": false},
            "program_line": 7,
            "job": {"job_id": 3, "outcome": "running", "progress": 0.42, "path": "/tmp/a.ngc",
                    "program": "/nonexistent/programs/abc.ngc"},
            "axes": {"cmd_mm": [1.0, 2.0, 3.0], "actual_mm": [1.0, 2.0, 3.0],
                     "following_err_um": [0.5, 0.25, 0.0], "contour_err_um": 1.5, "ring_fill": 100},
            "processes": {"interp": "alive", "position": "alive"},
            "loops": {"interp": {"jitter_ns": {"p99": 1000, "max": 5000}}},
            "alarms": [{"code": "RingDry", "message": "ran dry"}],
        })
    }

    fn program() -> Listing {
        let text: String = (1..=40).map(|k| format!("N{k} G1 X{k} F600\n")).collect();
        Listing::from_text(3, false, text)
    }

    /// The screen row holding `needle`.
    fn row_of(out: &str, needle: &str) -> usize {
        out.lines()
            .position(|l| l.contains(needle))
            .unwrap_or_else(|| panic!("{needle:?} not on screen:\n{out}"))
    }

    #[test]
    fn the_machine_line_shows_spindle_coolant_tools_and_the_prompt_or_message() {
        let mut s = running();
        s["spindle"] = serde_json::json!({"commanded_rpm": 8000.0, "actual_rpm": 7990.4,
                                          "at_speed": true});
        s["coolant"] = serde_json::json!({"mist": false, "flood": true});
        s["tool_prepared"] = serde_json::json!(3);
        s["message"] = serde_json::json!("check the coolant");
        let out = screen(&s, 80, 24);
        row_of(&out, "T2→3  feed 100% spindle 100% 7990/8000* rpm");
        row_of(&out, "coolant flood  MSG check the coolant");
        // a prompt comes first
        s["prompt"] = serde_json::json!("insert T3, then resume");
        let out = screen(&s, 80, 24);
        row_of(&out, "insert T3, then resume  coolant flood");
    }

    #[test]
    fn huge_values_are_shown_right_or_marked_never_wrong() {
        let mut s = running();
        s["machine_mm"] = serde_json::json!([1.0e15, -123456789012.5, 3.0]);
        s["work_mm"] = serde_json::json!([-2.5e300, 1.0e15, 3.0]);
        let out = screen(&s, 80, 24);
        // every number on the screen reads back as its value (to its shown digits)
        // or is an overflow marker: no digits cut off
        for want in [1.0e15, -123456789012.5, -2.5e300] {
            let shown = out
                .split(|c: char| c.is_whitespace() || c == '│')
                .filter_map(|w| w.parse::<f64>().ok())
                .any(|v| (v - want).abs() <= want.abs() * 1e-3);
            assert!(shown, "{want} not shown right:\n{out}");
        }
        assert!(!out.contains("1000000000000000.0"), "{out}");
        // the plain fixed-point form where it fits
        assert!(out.contains("3.000"), "{out}");
        for (v, width) in [(1.0e15, 10), (-1.0e300, 6), (12.5, 10), (-1.0e300, 3)] {
            let t = num(Some(v), 1.0, width, 3);
            assert_eq!(t.chars().count(), width, "{v} in {width}: {t:?}");
            match t.trim().parse::<f64>() {
                Ok(x) => assert!((x - v).abs() <= v.abs() * 0.06, "{v} shown as {t:?}"),
                Err(_) => assert!(t.chars().all(|c| c == '#'), "{v} shown as {t:?}"),
            }
        }
    }

    #[test]
    fn a_long_alarm_is_wrapped_whole_at_80_by_24() {
        let mut s = running();
        let msg = "following error -5.000 mm on axis X beyond the limit of 2.000 mm: emergency stop, drives off, reset required";
        s["alarms"] = serde_json::json!([{"code": "FollowingError", "message": msg}]);
        let out = screen(&s, 80, 24);
        // every word of it on the screen, in order
        let text: String = out
            .replace('│', " ")
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ");
        for word in msg.split_whitespace() {
            assert!(text.contains(word), "{word:?} cut from the alarm:\n{out}");
        }
        assert!(text.contains("reset required"), "{out}");
    }

    #[test]
    fn an_80_by_24_terminal_shows_every_axis_the_line_and_every_key() {
        let out = screen(&running(), 80, 24);
        for row in ["X ", "Y ", "Z "] {
            assert!(
                out.lines()
                    .any(|l| l.trim_start_matches('│').trim_start().starts_with(row)),
                "axis row {row} missing:\n{out}"
            );
        }
        assert!(out.contains("line 7"), "{out}");
        assert!(out.contains("e E-STOP  x reset"), "key help cut:\n{out}");
        assert!(out.contains("RingDry"), "{out}");
        // both key lines whole, in either jog mode
        assert!(out.contains(&format!("{KEY_HELP_STOP}{KEY_HELP}")), "{out}");
        assert!(out.contains(&jog_help(&Ui::default())), "{out}");
        let cont = Ui {
            continuous: true,
            speed_idx: watch_keys::JOG_SPEEDS_MM_PER_MIN.len() - 1,
            ..Ui::default()
        };
        let (out, _) = render(&running(), &cont, None, 80, 24);
        assert!(out.contains(&jog_help(&cont)), "{out}");
        assert!(jog_help(&cont).contains("6000 mm/min"));
    }

    #[test]
    fn the_dro_shows_machine_and_work_position_homed_flags_and_the_system() {
        let out = screen(&running(), 80, 24);
        assert!(out.contains("DRO G55"), "{out}");
        let x = &out.lines().nth(row_of(&out, "X *")).unwrap().to_string();
        assert!(
            x.contains("1.0000") && x.contains("-9.0000") && x.contains("0.50"),
            "{x}"
        );
        let z = out.lines().nth(row_of(&out, "│Z ")).unwrap();
        assert!(!z.contains("Z *"), "Z is not homed: {z}");
        let head = out.lines().next().unwrap();
        for part in [
            "Running",
            "G55",
            "T2",
            "SB on",
            "OS off",
            "BD off",
            "feed 100%",
        ] {
            assert!(head.contains(part), "{part} missing: {head}");
        }
    }

    #[test]
    fn idle_without_a_job_or_status_shows_no_nan() {
        let idle = serde_json::json!({"state": "Idle", "job": null, "axes": null, "alarms": []});
        let out = screen(&idle, 80, 24);
        assert!(!out.contains("NaN"), "{out}");
        assert!(out.contains("no job"), "{out}");
        let none = serde_json::json!("no MMI: timed out");
        assert!(!screen(&none, 80, 24).contains("NaN"));
    }

    #[test]
    fn a_machine_off_before_the_position_process_reports_shows_dashes_not_nan() {
        let off = serde_json::json!({
            "state": "Off", "homed": [false, false, false], "machine_mm": null, "work_mm": null,
            "coords": "G54", "offsets": {"g5x_mm": [0.0, 0.0, 0.0], "rotation_deg": 0.0,
                "g92_mm": [0.0, 0.0, 0.0], "tool_offset_mm": [0.0, 0.0, 0.0]},
            "tool": 0, "switches": {"single_block": false, "optional_stop": false,
                "block_delete": false},
            "program_line": null, "feed_override": 1.0, "spindle_override": null,
            "spindle_rpm": null, "job": null, "axes": null, "alarms": [],
            "processes": {"interp": "alive", "position": "unseen"},
        });
        let out = screen(&off, 80, 24);
        assert!(!out.contains("NaN"), "{out}");
        assert!(out.starts_with("Off  position unseen  G54  T0"), "{out}");
        assert!(out.contains("position unseen"), "{out}");
        let x = out.lines().nth(row_of(&out, "│X ")).unwrap();
        assert!(x.matches(" -").count() >= 4, "{x}");
        assert!(out.contains("(no job)"), "{out}");
        // the offsets view of the same status: dashes where the reply has not come
        let ui = Ui {
            offsets_view: true,
            ..Ui::default()
        };
        let (out, _) = render(&off, &ui, None, 80, 24);
        assert!(!out.contains("NaN"), "{out}");
        assert!(out.contains("asking softnc-mmi"), "{out}");
    }

    #[test]
    fn a_running_job_lists_its_program_around_the_current_line_highlighted() {
        let l = program();
        let (out, buf) = render(&running(), &Ui::default(), Some(&l), 80, 24);
        assert!(out.contains("program  line 7/40"), "{out}");
        let y = row_of(&out, ">    7 N7 G1 X7 F600");
        // the lines before and after it are there, unmarked
        assert!(out.contains("     6 N6 G1 X6"), "{out}");
        assert!(out.contains("     8 N8 G1 X8"), "{out}");
        assert!(
            !out.contains("N1 G1"),
            "the window follows the line:\n{out}"
        );
        let x = out
            .lines()
            .nth(y)
            .unwrap()
            .chars()
            .position(|c| c == '>')
            .unwrap();
        assert_eq!(buf[(x as u16, y as u16)].bg, Color::Yellow);
        let other = row_of(&out, "     8 N8 G1");
        assert_ne!(buf[(x as u16, other as u16)].bg, Color::Yellow);
        // an MDI job lists its block
        let mut mdi = running();
        mdi["job"]["mdi"] = "G0 X10 Y5".into();
        mdi["program_line"] = 1.into();
        let m = Listing::from_text(3, true, "G0 X10 Y5".into());
        let (out, _) = render(&mdi, &Ui::default(), Some(&m), 80, 24);
        assert!(out.contains(">    1 G0 X10 Y5"), "{out}");
        assert!(out.contains("MDI  line 1/1"), "{out}");
    }

    #[test]
    fn the_offsets_view_shows_every_system_g92_and_the_tool_in_place_of_the_plot() {
        let mut s = running();
        s["offsets"] = serde_json::json!({"g5x_mm": [10.0, 20.0, 0.0], "rotation_deg": 0.0,
            "g92_mm": [0.5, 0.0, 0.0], "tool_offset_mm": [0.0, 0.0, 42.125]});
        let names = [
            "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
        ];
        let systems: Vec<serde_json::Value> = names
            .iter()
            .enumerate()
            .map(|(k, n)| {
                serde_json::json!({"coords": n, "origin_mm": [k as f64 * 100.0, -1.5, -999.125],
                    "rotation_deg": 0.0, "active": *n == "G55"})
            })
            .collect();
        let ui = Ui {
            offsets_view: true,
            offsets: Some(
                serde_json::from_value(serde_json::json!({"active": "G55", "systems": systems,
                    "g92_mm": [0.0, 0.0, 0.0], "tool": 2, "tool_offset_mm": [0.0, 0.0, 0.0]}))
                .unwrap(),
            ),
            ..Ui::default()
        };
        let (out, buf) = render(&s, &ui, Some(&program()), 80, 24);
        assert!(!out.contains("contour error µm (live)"), "{out}");
        for n in names {
            assert!(out.contains(&format!("{n:<6}")), "{n} missing:\n{out}");
        }
        assert!(
            out.contains("G59.3     800.000    -1.500  -999.125"),
            "{out}"
        );
        let y = row_of(&out, "G55   *");
        let x = out.lines().nth(y).unwrap().find("G55").unwrap();
        let x = out.lines().nth(y).unwrap()[..x].chars().count();
        assert_eq!(buf[(x as u16, y as u16)].bg, Color::Yellow);
        assert!(
            out.contains("G92         0.500     0.000     0.000"),
            "{out}"
        );
        assert!(
            out.contains("T2          0.000     0.000    42.125"),
            "{out}"
        );
        assert!(out.contains("active G55"), "{out}");
        assert!(out.contains("e E-STOP  x reset"), "{out}");
        assert!(!out.contains("NaN"), "{out}");
    }

    #[test]
    fn mdi_entry_shows_the_typed_line_and_its_keys_with_the_e_stop() {
        let ui = Ui {
            mode: Mode::Mdi("G0 X10 Y5".into()),
            ..Ui::default()
        };
        let (out, _) = render(&running(), &ui, None, 80, 24);
        let y = row_of(&out, "MDI> G0 X10 Y5_");
        assert_eq!(y, 21, "the input line is above the keys:\n{out}");
        assert!(out.contains("F1 E-STOP  Enter send  Esc cancel"), "{out}");
        assert!(
            !out.contains("e E-STOP"),
            "e types text while entering MDI:\n{out}"
        );
        assert!(out.contains(MDI_HELP), "{out}");
        assert!(
            !out.contains("jog ←→"),
            "the jog keys do not act while typing:\n{out}"
        );
    }

    #[test]
    fn touch_off_prompt_names_the_system_and_the_help_overlay_lists_every_key() {
        let ui = Ui {
            mode: Mode::TouchOff,
            ..Ui::default()
        };
        let (out, _) = render(&running(), &ui, None, 80, 24);
        assert!(
            out.contains("x, y or z sets that axis to 0 in G55"),
            "{out}"
        );
        let help = Ui {
            help: true,
            ..Ui::default()
        };
        let (out, _) = render(&running(), &help, None, 80, 24);
        for (a, b) in KEY_MAP {
            assert!(
                out.contains(a) && out.contains(b),
                "{a} / {b} missing:\n{out}"
            );
        }
        assert!(out.contains("e E-STOP  x reset"), "{out}");
    }
}
