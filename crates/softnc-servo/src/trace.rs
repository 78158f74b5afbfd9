//! Per-cycle traces (CSV): what the position loop and the offline simulator write,
//! in one format, so a daemon run in lockstep and the simulator can be compared byte
//! for byte. Numbers are in Rust's shortest round-trip form: equal files ⇔
//! bit-identical values.

use crate::engine::CycleRecord;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// What one position cycle produced, for traces and plots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceRow {
    /// Cycle index from the start of the job.
    pub cycle: u64,
    /// Time (s) = cycle · T.
    pub time_s: f64,
    /// The sample's motion index.
    pub motion: u32,
    /// Command, measured position, following error, drive commands.
    pub record: CycleRecord,
    /// Signed contour error against the active feed move's programmed path (mm);
    /// `None` outside feed moves.
    pub contour_mm: Option<f64>,
    /// The machine around the axes this cycle: spindle commanded and actual speed,
    /// coolant, the M62–M65 outputs.
    pub io: crate::io::IoTrace,
}

/// Header line of a trace: the contour error stays the last column. `spindle_cmd_rpm`
/// is the speed command written (signed, × override), `spindle_rpm` the encoder's,
/// `coolant` bit 0 mist and bit 1 flood, `dout` the M62–M65 outputs (bit P).
pub const HEADER: &str = "time_s,cmd_x_mm,cmd_y_mm,cmd_z_mm,act_x_mm,act_y_mm,act_z_mm,fe_x_um,fe_y_um,fe_z_um,spindle_cmd_rpm,spindle_rpm,coolant,dout,contour_um";

/// Append one row to `out` (no trailing allocation once `out` has grown).
pub fn format_row(out: &mut String, row: &TraceRow) {
    let r = &row.record;
    let _ = write!(out, "{}", row.time_s);
    for v in r.cmd_mm.iter().chain(&r.actual_mm) {
        let _ = write!(out, ",{v}");
    }
    for v in r.following_mm {
        let _ = write!(out, ",{}", v * 1000.0);
    }
    let io = &row.io;
    let _ = write!(
        out,
        ",{},{},{},{}",
        io.spindle_cmd_rpm, io.spindle_rpm, io.coolant, io.digital_out
    );
    match row.contour_mm {
        Some(c) => {
            let _ = write!(out, ",{}", c * 1000.0);
        }
        None => out.push(','),
    }
    out.push('\n');
}

/// Write a whole trace file from rows (the simulator's path).
pub struct TraceFile {
    w: std::io::BufWriter<std::fs::File>,
    buf: String,
}

impl TraceFile {
    /// Create `path` and write the header.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(w, "{HEADER}")?;
        Ok(TraceFile {
            w,
            buf: String::with_capacity(256),
        })
    }
    /// One row.
    pub fn row(&mut self, row: &TraceRow) -> std::io::Result<()> {
        self.buf.clear();
        format_row(&mut self.buf, row);
        self.w.write_all(self.buf.as_bytes())
    }
    /// Flush to disk.
    pub fn finish(mut self) -> std::io::Result<()> {
        self.w.flush()?;
        self.w.get_ref().sync_all()
    }
}
