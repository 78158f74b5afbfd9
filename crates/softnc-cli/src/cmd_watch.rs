//! `softnc watch`: a terminal UI — axis positions, following and contour error, job
//! progress and program line, alarms, loop jitter and a live plot of the contour
//! error, on an 80×24 terminal or larger. Keys: q quit, h hold, r resume, a abort,
//! + / − feed override ±10 %, ] / [ spindle override ±10 %, e E-stop, x reset.

use anyhow::Result;
use ratatui::crossterm::event::{self, Event, KeyCode};
use ratatui::layout::{Constraint, Direction, Layout};
use ratatui::style::{Color, Style};
use ratatui::symbols;
use ratatui::text::Line;
use ratatui::widgets::{
    Axis, Block, Borders, Chart, Dataset, Gauge, GraphType, List, ListItem, Paragraph, Row, Table,
};
use softnc_daemon::client::Operator;
use softnc_ipc::ControlKind;
use std::collections::VecDeque;
use std::path::Path;
use std::process::ExitCode;
use std::time::Duration;

/// Points kept in the live plot.
const PLOT_POINTS: usize = 300;

/// Run the terminal UI until `q`.
pub fn run(config: &Path) -> Result<ExitCode> {
    let op = Operator::connect(config)?;
    let mut terminal = ratatui::init();
    let mut plot: VecDeque<(f64, f64)> = VecDeque::with_capacity(PLOT_POINTS);
    let mut tick = 0u64;
    let mut note = String::new();
    let result = (|| -> Result<()> {
        loop {
            let s = op
                .status()
                .unwrap_or_else(|e| serde_json::json!({"state": format!("no MMI: {e}")}));
            tick += 1;
            if let Some(c) = s["axes"]["contour_err_um"].as_f64() {
                if plot.len() == PLOT_POINTS {
                    plot.pop_front();
                }
                plot.push_back((tick as f64, c));
            }
            terminal.draw(|f| draw(f, &s, &plot, &note))?;
            if event::poll(Duration::from_millis(100))? {
                if let Event::Key(k) = event::read()? {
                    let ov = s["feed_override"].as_f64().unwrap_or(1.0);
                    // the MMI refuses what is outside the profile's spindle range
                    let sov = s["spindle_override"].as_f64().unwrap_or(1.0);
                    let req = match k.code {
                        KeyCode::Char('q') | KeyCode::Esc => return Ok(()),
                        KeyCode::Char('h') => Some((ControlKind::Hold, 0.0)),
                        KeyCode::Char('r') => Some((ControlKind::Resume, 0.0)),
                        KeyCode::Char('a') => Some((ControlKind::Abort, 0.0)),
                        KeyCode::Char('+') => {
                            Some((ControlKind::FeedOverride, (ov + 0.1).min(2.55)))
                        }
                        KeyCode::Char('-') => {
                            Some((ControlKind::FeedOverride, (ov - 0.1).max(0.0)))
                        }
                        KeyCode::Char(']') => Some((ControlKind::SpindleOverride, sov + 0.1)),
                        KeyCode::Char('[') => Some((ControlKind::SpindleOverride, sov - 0.1)),
                        KeyCode::Char('e') => Some((ControlKind::EStop, 0.0)),
                        KeyCode::Char('x') => Some((ControlKind::Reset, 0.0)),
                        _ => None,
                    };
                    if let Some((kind, v)) = req {
                        note = match op.request(kind, v, "") {
                            Ok(r) => r.message.as_str().to_string(),
                            Err(e) => e.to_string(),
                        };
                    }
                }
            }
        }
    })();
    ratatui::restore();
    result.map(|()| ExitCode::SUCCESS)
}

/// A number for the screen: `-` where there is none (idle, no status yet), never NaN.
fn num(v: &serde_json::Value, scale: f64, width: usize, decimals: usize) -> String {
    match v.as_f64().filter(|x| x.is_finite()) {
        Some(x) => format!("{:width$.decimals$}", x * scale),
        None => format!("{:>width$}", "-"),
    }
}

/// The keys, on the bottom line (fits 80 columns).
const KEY_HELP: &str =
    "q quit  h hold  r resume  a abort  +/- feed  ]/[ spindle  e E-STOP  x reset";

/// The screen, laid out to fit an 80×24 terminal: a status line, the job's progress,
/// the axes (DRO), the live contour error, loops and alarms, the keys.
fn draw(
    frame: &mut ratatui::Frame,
    s: &serde_json::Value,
    plot: &VecDeque<(f64, f64)>,
    note: &str,
) {
    let rows = Layout::default()
        .direction(Direction::Vertical)
        .constraints([
            Constraint::Length(1),
            Constraint::Length(1),
            Constraint::Length(6),
            Constraint::Min(4),
            Constraint::Length(5),
            Constraint::Length(1),
        ])
        .split(frame.area());
    let job = &s["job"];
    let head = format!(
        "{}  feed {} %  spindle {} % {} rpm  interp {} position {}  {}",
        s["state"].as_str().unwrap_or("?"),
        num(&s["feed_override"], 100.0, 0, 0),
        num(&s["spindle_override"], 100.0, 0, 0),
        num(&s["spindle_rpm"], 1.0, 0, 0),
        s["processes"]["interp"].as_str().unwrap_or("?"),
        s["processes"]["position"].as_str().unwrap_or("?"),
        note
    );
    frame.render_widget(Paragraph::new(head), rows[0]);
    let progress = job["progress"].as_f64().unwrap_or(0.0).clamp(0.0, 1.0);
    let label = if job.is_null() {
        "no job".to_string()
    } else {
        let line = s["program_line"]
            .as_u64()
            .map_or(String::new(), |l| format!(" line {l}"));
        format!(
            "job {} {} {:.0} %{line}  {}",
            job["job_id"],
            job["outcome"].as_str().unwrap_or("?"),
            progress * 100.0,
            job["path"].as_str().unwrap_or("")
        )
    };
    frame.render_widget(
        Gauge::default()
            .gauge_style(Style::default().fg(Color::Green))
            .ratio(progress)
            .label(label),
        rows[1],
    );
    let axes = &s["axes"];
    let names = ["X", "Y", "Z"];
    let table_rows: Vec<Row> = (0..3)
        .map(|i| {
            Row::new(vec![
                names[i].to_string(),
                num(&axes["cmd_mm"][i], 1.0, 10, 4),
                num(&axes["actual_mm"][i], 1.0, 10, 4),
                num(&axes["following_err_um"][i], 1.0, 9, 2),
            ])
        })
        .collect();
    let table = Table::new(
        table_rows,
        [
            Constraint::Length(4),
            Constraint::Length(12),
            Constraint::Length(12),
            Constraint::Length(14),
        ],
    )
    .header(Row::new(vec![
        "axis",
        "command mm",
        "actual mm",
        "following µm",
    ]))
    .block(Block::default().borders(Borders::ALL).title(format!(
        "axes  contour error {} µm  ring {}",
        num(&axes["contour_err_um"], 1.0, 0, 2),
        axes["ring_fill"].as_u64().map_or("-".into(), |r| r.to_string())
    )));
    frame.render_widget(table, rows[2]);
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
    frame.render_widget(chart, rows[3]);
    let bottom = Layout::default()
        .direction(Direction::Horizontal)
        .constraints([Constraint::Percentage(45), Constraint::Percentage(55)])
        .split(rows[4]);
    let mut loops = vec![];
    for name in ["interp", "position"] {
        let l = &s["loops"][name];
        if !l.is_null() {
            loops.push(ListItem::new(format!(
                "{name}: p99 {} max {} µs",
                num(&l["jitter_ns"]["p99"], 1e-3, 0, 1),
                num(&l["jitter_ns"]["max"], 1e-3, 0, 1)
            )));
        }
    }
    frame.render_widget(
        List::new(loops).block(Block::default().borders(Borders::ALL).title("loop jitter")),
        bottom[0],
    );
    let alarms: Vec<ListItem> = s["alarms"]
        .as_array()
        .into_iter()
        .flatten()
        .map(|a| {
            ListItem::new(format!(
                "{}: {}",
                a["code"].as_str().unwrap_or("?"),
                a["message"].as_str().unwrap_or("")
            ))
        })
        .collect();
    frame.render_widget(
        List::new(alarms).block(Block::default().borders(Borders::ALL).title("alarms")),
        bottom[1],
    );
    frame.render_widget(Paragraph::new(KEY_HELP), rows[5]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use ratatui::backend::TestBackend;
    use ratatui::Terminal;

    fn screen(s: &serde_json::Value, width: u16, height: u16) -> String {
        let mut t = Terminal::new(TestBackend::new(width, height)).unwrap();
        let plot: VecDeque<(f64, f64)> = (0..50).map(|k| (k as f64, (k as f64).sin())).collect();
        t.draw(|f| draw(f, s, &plot, "")).unwrap();
        let buf = t.backend().buffer().clone();
        let mut out = String::new();
        for y in 0..buf.area.height {
            for x in 0..buf.area.width {
                out.push_str(buf[(x, y)].symbol());
            }
            out.push('\n');
        }
        out
    }

    fn running() -> serde_json::Value {
        serde_json::json!({
            "state": "Running", "feed_override": 1.0, "spindle_override": 1.0, "spindle_rpm": 0.0,
            "program_line": 7,
            "job": {"job_id": 3, "outcome": "running", "progress": 0.42, "path": "/tmp/a.ngc"},
            "axes": {"cmd_mm": [1.0, 2.0, 3.0], "actual_mm": [1.0, 2.0, 3.0],
                     "following_err_um": [0.5, 0.25, 0.0], "contour_err_um": 1.5, "ring_fill": 100},
            "processes": {"interp": "alive", "position": "alive"},
            "loops": {"interp": {"jitter_ns": {"p99": 1000.0, "max": 5000.0}}},
            "alarms": [{"code": "RingDry", "message": "ran dry"}],
        })
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
    }

    #[test]
    fn idle_without_a_job_or_status_shows_no_nan() {
        let idle = serde_json::json!({"state": "Idle", "job": null, "axes": null, "alarms": []});
        let out = screen(&idle, 80, 24);
        assert!(!out.contains("NaN"), "{out}");
        assert!(out.contains("no job"), "{out}");
        let none = serde_json::json!({"state": "no MMI: timed out"});
        assert!(!screen(&none, 80, 24).contains("NaN"));
    }
}
