//! The experiments' plots: line charts with a legend, stacked in one SVG file. Every
//! experiment draws through [`write_svg`], so axes, captions and legends look alike.

use crate::error::{ExperimentError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend entry (no entry when empty).
    pub name: String,
    /// (x, y) points in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub colour: RGBColor,
}

impl Series {
    /// A named line.
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>, colour: RGBColor) -> Self {
        Series {
            name: name.into(),
            points,
            colour,
        }
    }
}

/// One chart: a caption, axes, lines and vertical marks.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Caption above the chart.
    pub title: String,
    /// Caption font size (px).
    pub title_px: u32,
    /// Height of the panel (px).
    pub height_px: u32,
    /// X-axis label.
    pub x_desc: String,
    /// Y-axis label.
    pub y_desc: String,
    /// X range.
    pub x: Range<f64>,
    /// Y range.
    pub y: Range<f64>,
    /// Number of x tick labels (`None`: plotters' choice).
    pub x_labels: Option<usize>,
    /// The lines.
    pub series: Vec<Series>,
    /// Vertical marks (x, colour) spanning the y range.
    pub marks: Vec<(f64, RGBColor)>,
}

impl Panel {
    /// A panel `height_px` high with an 18 px caption and no marks.
    pub fn new(title: impl Into<String>, height_px: u32, x: Range<f64>, y: Range<f64>) -> Self {
        Panel {
            title: title.into(),
            title_px: 18,
            height_px,
            x_desc: String::new(),
            y_desc: String::new(),
            x_labels: None,
            x,
            y,
            series: Vec::new(),
            marks: Vec::new(),
        }
    }

    /// With axis labels.
    pub fn axes(mut self, x_desc: impl Into<String>, y_desc: impl Into<String>) -> Self {
        self.x_desc = x_desc.into();
        self.y_desc = y_desc.into();
        self
    }

    /// With these lines.
    pub fn lines(mut self, series: Vec<Series>) -> Self {
        self.series = series;
        self
    }
}

/// The range of the y values of `series`, padded by `pad_frac` of its span (at
/// least `min_span`); `fallback` when there are no finite values.
pub fn y_range(
    series: &[Series],
    pad_frac: f64,
    min_span: f64,
    fallback: Range<f64>,
) -> Range<f64> {
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    if !lo.is_finite() {
        return fallback;
    }
    let pad = pad_frac * (hi - lo).max(min_span);
    (lo - pad)..(hi + pad)
}

/// Write `panels`, stacked top to bottom, `width_px` wide, as an SVG file.
pub fn write_svg(path: &Path, width_px: u32, panels: &[Panel]) -> Result<()> {
    let fail = |e: &dyn std::fmt::Display| ExperimentError::Plot {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let height: u32 = panels.iter().map(|p| p.height_px).sum();
    let root = SVGBackend::new(path, (width_px, height.max(1))).into_drawing_area();
    root.fill(&WHITE).map_err(|e| fail(&e))?;
    let mut rest = root.clone();
    for (i, panel) in panels.iter().enumerate() {
        let area = if i + 1 < panels.len() {
            let (top, bottom) = rest.split_vertically(panel.height_px);
            rest = bottom;
            top
        } else {
            rest.clone()
        };
        draw_panel(&area, panel).map_err(|e| fail(&e))?;
    }
    root.present().map_err(|e| fail(&e))?;
    Ok(())
}

type DrawResult = std::result::Result<(), DrawingAreaErrorKind<std::io::Error>>;

fn draw_panel(area: &DrawingArea<SVGBackend, Shift>, panel: &Panel) -> DrawResult {
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", panel.title_px))
        .margin(12)
        .x_label_area_size(34)
        .y_label_area_size(54)
        .build_cartesian_2d(panel.x.clone(), panel.y.clone())?;
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(&panel.x_desc).y_desc(&panel.y_desc);
    if let Some(n) = panel.x_labels {
        mesh.x_labels(n);
    }
    mesh.draw()?;
    let mut legend = false;
    for s in &panel.series {
        let colour = s.colour;
        let drawn = chart.draw_series(LineSeries::new(s.points.iter().copied(), colour))?;
        if !s.name.is_empty() {
            legend = true;
            drawn
                .label(s.name.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
        }
    }
    for &(x, colour) in &panel.marks {
        chart.draw_series(std::iter::once(PathElement::new(
            vec![(x, panel.y.start), (x, panel.y.end)],
            colour,
        )))?;
    }
    if legend {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stacked_panels_are_written_with_their_lines_and_legends() {
        let path =
            std::env::temp_dir().join(format!("softnc-plot-test-{}.svg", std::process::id()));
        let line = |name: &str, k: f64, colour| {
            Series::new(
                name,
                (0..50).map(|i| (i as f64, k * i as f64)).collect(),
                colour,
            )
        };
        let top = Panel::new("top panel", 200, 0.0..50.0, 0.0..100.0)
            .axes("x", "y")
            .lines(vec![
                line("slope one", 1.0, RED),
                line("slope two", 2.0, BLUE),
            ]);
        let bottom = Panel {
            marks: vec![(25.0, GREEN)],
            ..Panel::new("bottom panel", 100, 0.0..50.0, -1.0..1.0)
                .lines(vec![line("", 0.0, BLACK)])
        };
        write_svg(&path, 400, &[top, bottom]).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        for text in ["top panel", "bottom panel", "slope one", "slope two"] {
            assert!(svg.contains(text), "{text}");
        }
        assert!(svg.contains("height=\"300\""), "panels stack: 200 + 100 px");
        let err = write_svg(Path::new("/nonexistent-dir/plot.svg"), 400, &[]).unwrap_err();
        assert!(matches!(err, ExperimentError::Plot { .. }), "{err}");
    }

    #[test]
    fn y_range_pads_the_values_and_falls_back_without_any() {
        let s = [Series::new("", vec![(0.0, 2.0), (1.0, 4.0)], RED)];
        assert_eq!(y_range(&s, 0.5, 0.0, 0.0..1.0), 1.0..5.0);
        assert_eq!(y_range(&[], 0.5, 0.0, -3.0..3.0), -3.0..3.0);
    }
}
