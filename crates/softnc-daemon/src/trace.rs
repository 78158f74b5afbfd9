//! Per-cycle traces of the position loop, in the format of [`softnc_servo::trace`]
//! (the one `softnc sim --trace` writes).
//!
//! The position loop hands rows to a writer thread through a bounded lock-free queue
//! ([`TraceSink`]); formatting and file I/O never run on the cycle path.

use crossbeam_queue::ArrayQueue;
pub use softnc_servo::trace::{format_row, TraceFile, HEADER};
use softnc_servo::TraceRow;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

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
