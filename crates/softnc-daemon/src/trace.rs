//! Per-cycle traces (CSV): the format `softnc sim --trace` writes, so a daemon run in
//! lockstep and the offline simulator can be compared byte for byte. Numbers are in
//! Rust's shortest round-trip form: equal files ⇔ bit-identical values.
//!
//! The position loop hands rows to a writer thread through a bounded lock-free queue
//! ([`TraceSink`]); formatting and file I/O never run on the cycle path.

use crossbeam_queue::ArrayQueue;
use softnc_sim::sim::TraceRow;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Header line of a trace.
pub const HEADER: &str =
    "time_s,cmd_x_mm,cmd_y_mm,cmd_z_mm,act_x_mm,act_y_mm,act_z_mm,fe_x_um,fe_y_um,fe_z_um,contour_um";

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

/// The position loop's end of a trace: push rows, a thread writes them.
pub struct TraceSink {
    queue: Arc<ArrayQueue<Option<TraceRow>>>,
    dropped: Arc<AtomicU64>,
    done: Arc<AtomicBool>,
    writer: Option<std::thread::JoinHandle<()>>,
    lossless: bool,
}

/// Rows the queue holds (preallocated).
pub const QUEUE_ROWS: usize = 1 << 16;

impl TraceSink {
    /// Start a writer thread on `path`. `lossless`: the loop waits when the queue is
    /// full (lockstep); otherwise rows are dropped and counted (realtime).
    pub fn start(path: &Path, lossless: bool) -> std::io::Result<Self> {
        let mut file = TraceFile::create(path)?;
        let queue: Arc<ArrayQueue<Option<TraceRow>>> = Arc::new(ArrayQueue::new(QUEUE_ROWS));
        let done = Arc::new(AtomicBool::new(false));
        let (q, d) = (queue.clone(), done.clone());
        let writer = std::thread::Builder::new()
            .name("trace-writer".into())
            .spawn(move || loop {
                match q.pop() {
                    Some(Some(row)) => {
                        if file.row(&row).is_err() {
                            return;
                        }
                    }
                    Some(None) => {
                        let _ = file.finish();
                        d.store(true, Ordering::Release);
                        return;
                    }
                    None => std::thread::sleep(std::time::Duration::from_millis(1)),
                }
            })?;
        Ok(TraceSink {
            queue,
            dropped: Arc::new(AtomicU64::new(0)),
            done,
            writer: Some(writer),
            lossless,
        })
    }

    /// Hand one row to the writer (allocation-free).
    pub fn push(&self, row: TraceRow) {
        let mut item = Some(row);
        loop {
            match self.queue.push(item) {
                Ok(()) => return,
                Err(back) if self.lossless => {
                    item = back;
                    std::thread::yield_now();
                }
                Err(_) => {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                    return;
                }
            }
        }
    }

    /// Rows dropped because the writer fell behind (realtime only).
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// End the file and wait for the writer.
    pub fn finish(mut self) {
        self.end();
    }

    fn end(&mut self) {
        if let Some(w) = self.writer.take() {
            while self.queue.push(None).is_err() {
                std::thread::yield_now();
            }
            let _ = w.join();
        }
        let _ = self.done.load(Ordering::Acquire);
    }
}

/// A trace dropped without [`TraceSink::finish`] (the process ending) still gets
/// every row pushed into its file (blocks on the writer: never on the cycle, where
/// traces are retired to the preparation thread).
impl Drop for TraceSink {
    fn drop(&mut self) {
        self.end();
    }
}
