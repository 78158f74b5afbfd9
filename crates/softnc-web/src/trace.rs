//! A job's per-cycle trace (`<data_dir>/trace-job<N>.csv`, written by the position
//! process when the daemon configuration has `trace: true`), read off the MMI and
//! off the real-time path and thinned for the page's plot: per bucket of cycles the
//! largest contour and following errors (so the plot's peaks are the trace's) and
//! where the command stood.

use serde::Serialize;
use std::path::{Path, PathBuf};

/// Most points a plot gets (a bucket of cycles each).
pub const MAX_POINTS: usize = 2000;

/// Why a job's trace cannot be given.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// No trace file: the daemon writes none with `trace: false` (its default).
    #[error("no trace of job {job_id} ({path}): the daemon writes traces with `trace: true` in its configuration")]
    Missing {
        /// The job.
        job_id: u64,
        /// Where it would be.
        path: String,
    },
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line that is not a trace row.
    #[error("{path}:{line}: not a trace row ({why})")]
    Row {
        /// The file.
        path: String,
        /// 1-based line.
        line: usize,
        /// What is wrong with it.
        why: String,
    },
}

/// A job's trace, thinned to at most [`MAX_POINTS`] points.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct JobTrace {
    /// The job.
    pub job_id: u64,
    /// The trace's rows (cycles).
    pub rows: u64,
    /// Each point's first cycle's time from the job's start (s).
    pub time_s: Vec<f64>,
    /// Each point's largest contour error (µm, absolute; `None`: no feed move in it).
    pub contour_um: Vec<Option<f64>>,
    /// Each point's largest following error per axis (µm, absolute; X, Y, Z).
    pub following_um: [Vec<f64>; 3],
    /// Each point's last command position (machine coordinates, mm; X, Y, Z).
    pub cmd_mm: Vec<[f64; 3]>,
    /// The whole trace's largest contour error (µm).
    pub contour_max_abs_um: f64,
    /// The whole trace's largest following error per axis (µm).
    pub following_max_abs_um: [f64; 3],
}

/// The trace file of job `job_id` in `data_dir`.
pub fn path_of(data_dir: &Path, job_id: u64) -> PathBuf {
    data_dir.join(format!("trace-job{job_id}.csv"))
}

/// Read and thin job `job_id`'s trace.
pub fn read(data_dir: &Path, job_id: u64) -> Result<JobTrace, TraceError> {
    let path = path_of(data_dir, job_id);
    let shown = path.display().to_string();
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(TraceError::Missing {
                job_id,
                path: shown,
            })
        }
        Err(source) => {
            return Err(TraceError::Io {
                path: shown,
                source,
            })
        }
    };
    parse(&text, job_id, &shown)
}

/// The columns a row has (`softnc_servo::trace::HEADER`).
const COLUMNS: usize = 15;
/// Columns: time, command X/Y/Z, following error X/Y/Z, contour error.
const TIME: usize = 0;
const CMD: usize = 1;
const FE: usize = 7;
const CONTOUR: usize = 14;

/// One row's figures: time, command, following errors, contour error.
type Row = (f64, [f64; 3], [f64; 3], Option<f64>);

/// Thin a trace's text (`file` for messages).
pub fn parse(text: &str, job_id: u64, file: &str) -> Result<JobTrace, TraceError> {
    let bad = |line: usize, why: String| TraceError::Row {
        path: file.to_string(),
        line,
        why,
    };
    let mut rows: Vec<Row> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        if k == 0 {
            if !line.starts_with("time_s,") || line.split(',').count() != COLUMNS {
                return Err(bad(1, "not the trace header".into()));
            }
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != COLUMNS {
            return Err(bad(
                k + 1,
                format!("{} columns, not {COLUMNS}", cells.len()),
            ));
        }
        let num = |i: usize| -> Result<f64, TraceError> {
            cells[i]
                .parse::<f64>()
                .map_err(|e| bad(k + 1, format!("column {}: {e}", i + 1)))
        };
        let contour = if cells[CONTOUR].is_empty() {
            None
        } else {
            Some(num(CONTOUR)?)
        };
        rows.push((
            num(TIME)?,
            [num(CMD)?, num(CMD + 1)?, num(CMD + 2)?],
            [num(FE)?, num(FE + 1)?, num(FE + 2)?],
            contour,
        ));
    }
    let mut out = JobTrace {
        job_id,
        rows: rows.len() as u64,
        ..JobTrace::default()
    };
    let per = rows.len().div_ceil(MAX_POINTS).max(1);
    for bucket in rows.chunks(per) {
        let mut contour: Option<f64> = None;
        let mut fe = [0.0f64; 3];
        for (_, _, f, c) in bucket {
            if let Some(c) = c {
                contour = Some(contour.map_or(c.abs(), |m| m.max(c.abs())));
            }
            for (m, v) in fe.iter_mut().zip(f) {
                *m = m.max(v.abs());
            }
        }
        out.time_s.push(bucket[0].0);
        out.cmd_mm.push(bucket[bucket.len() - 1].1);
        out.contour_um.push(contour);
        for ((series, max), v) in out
            .following_um
            .iter_mut()
            .zip(out.following_max_abs_um.iter_mut())
            .zip(fe)
        {
            series.push(v);
            *max = max.max(v);
        }
        if let Some(c) = contour {
            out.contour_max_abs_um = out.contour_max_abs_um.max(c);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: f64, x: f64, fe_x: f64, contour: Option<f64>) -> String {
        format!(
            "{t},{x},0,0,{x},0,0,{fe_x},-2,0,0,0,0,0,{}\n",
            contour.map_or(String::new(), |c| c.to_string())
        )
    }

    #[test]
    fn a_long_trace_is_thinned_keeping_its_peaks() {
        let mut text = format!("{}\n", softnc_servo_header());
        let n = 5 * MAX_POINTS + 3;
        for k in 0..n {
            let contour = (k % 7 != 0).then_some(if k == 4321 { -37.5 } else { 1.0 });
            let fe = if k == 777 { -12.25 } else { 0.5 };
            text.push_str(&row(k as f64 * 0.001, k as f64 * 0.01, fe, contour));
        }
        let t = parse(&text, 7, "t.csv").unwrap();
        assert_eq!(t.rows, n as u64);
        assert!(t.time_s.len() <= MAX_POINTS, "{}", t.time_s.len());
        assert_eq!(t.time_s.len(), t.contour_um.len());
        assert_eq!(t.contour_max_abs_um, 37.5);
        assert_eq!(t.following_max_abs_um, [12.25, 2.0, 0.0]);
        assert_eq!(
            t.contour_um.iter().flatten().copied().fold(0.0, f64::max),
            37.5
        );
        // the last point stands where the trace ends
        let last = t.cmd_mm.last().unwrap();
        assert!((last[0] - (n - 1) as f64 * 0.01).abs() < 1e-9, "{last:?}");
    }

    #[test]
    fn a_bad_row_is_named_and_a_missing_trace_says_why() {
        let text = format!("{}\n1,2,3\n", softnc_servo_header());
        let e = parse(&text, 1, "t.csv").unwrap_err().to_string();
        assert!(e.starts_with("t.csv:2: not a trace row"), "{e}");
        let dir = std::env::temp_dir().join(format!("softnc-web-trace-{}", std::process::id()));
        let e = read(&dir, 9).unwrap_err().to_string();
        assert!(
            e.contains("no trace of job 9") && e.contains("trace: true"),
            "{e}"
        );
    }

    /// The trace files' header.
    fn softnc_servo_header() -> &'static str {
        softnc_servo::trace::HEADER
    }

    #[test]
    fn the_columns_read_are_the_trace_files() {
        let cols: Vec<&str> = softnc_servo::trace::HEADER.split(',').collect();
        assert_eq!(cols.len(), COLUMNS);
        assert_eq!(
            [cols[TIME], cols[CMD], cols[FE], cols[CONTOUR]],
            ["time_s", "cmd_x_mm", "fe_x_um", "contour_um"]
        );
    }
}
