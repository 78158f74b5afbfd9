//! `softnc watch`: a terminal UI — axis positions, following and contour error, job
//! progress, alarms, loop jitter and a live plot of the contour error. Keys: q quit,
//! h hold, r resume, + / − feed override ±10 %, ] / [ spindle override ±10 %, e E-stop,
//! x reset.

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

fn f(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn draw(
    frame: &mut ratatui::Frame,
    s: &serde_json::Value,
    plot: &VecDeque<(f64, f64)>,
    note: &str,
) {
    let rows = Layout::default()
        .direction(Direction::Vertical)
        .constraints([
            Constraint::Length(3),
            Constraint::Length(3),
            Constraint::Length(6),
            Constraint::Min(8),
            Constraint::Length(7),
        ])
        .split(frame.area());
    let job = &s["job"];
    let head = format!(
        "state {}   feed {:.0} %   spindle {:.0} % {:.0} rpm   job {} {}   interp {}  position {}   {}",
        s["state"].as_str().unwrap_or("?"),
        f(&s["feed_override"]) * 100.0,
        f(&s["spindle_override"]) * 100.0,
        f(&s["spindle_rpm"]),
        job["job_id"],
        job["path"].as_str().unwrap_or(""),
        s["processes"]["interp"].as_str().unwrap_or("?"),
        s["processes"]["position"].as_str().unwrap_or("?"),
        note
    );
    frame.render_widget(
        Paragraph::new(head).block(Block::default().borders(Borders::ALL).title("softnc")),
        rows[0],
    );
    let progress = job["progress"].as_f64().unwrap_or(0.0).clamp(0.0, 1.0);
    frame.render_widget(
        Gauge::default()
            .block(Block::default().borders(Borders::ALL).title("job progress"))
            .gauge_style(Style::default().fg(Color::Green))
            .ratio(progress),
        rows[1],
    );
    let axes = &s["axes"];
    let names = ["X", "Y", "Z"];
    let table_rows: Vec<Row> = (0..3)
        .map(|i| {
            Row::new(vec![
                names[i].to_string(),
                format!("{:10.4}", f(&axes["cmd_mm"][i])),
                format!("{:10.4}", f(&axes["actual_mm"][i])),
                format!("{:9.2}", f(&axes["following_err_um"][i])),
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
        "axes   contour error {:.2} µm   ring {}",
        f(&axes["contour_err_um"]),
        axes["ring_fill"]
    )));
    frame.render_widget(table, rows[2]);
    let data: Vec<(f64, f64)> = plot.iter().copied().collect();
    let (x0, x1) = (
        data.first().map_or(0.0, |p| p.0),
        data.last().map_or(1.0, |p| p.0),
    );
    let ymax = data.iter().map(|p| p.1.abs()).fold(1.0, f64::max);
    let chart = Chart::new(vec![Dataset::default()
        .name("contour error µm")
        .marker(symbols::Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::default().fg(Color::Cyan))
        .data(&data)])
    .block(
        Block::default()
            .borders(Borders::ALL)
            .title("contour error (live)"),
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
        .constraints([Constraint::Percentage(50), Constraint::Percentage(50)])
        .split(rows[4]);
    let mut loops = vec![];
    for name in ["interp", "position"] {
        let l = &s["loops"][name];
        if !l.is_null() {
            loops.push(ListItem::new(format!(
                "{name}: jitter p50 {:.1} p99 {:.1} p99.9 {:.1} max {:.1} µs",
                f(&l["jitter_ns"]["p50"]) / 1e3,
                f(&l["jitter_ns"]["p99"]) / 1e3,
                f(&l["jitter_ns"]["p999"]) / 1e3,
                f(&l["jitter_ns"]["max"]) / 1e3
            )));
        }
    }
    frame.render_widget(
        List::new(loops).block(Block::default().borders(Borders::ALL).title("loops")),
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
        List::new(alarms).block(
            Block::default().borders(Borders::ALL).title(
                "alarms (q quit, h hold, r resume, +/- feed, ]/[ spindle, e E-stop, x reset)",
            ),
        ),
        bottom[1],
    );
}
