//! The position loop's outgoing messages leave through a bounded lock-free queue to a
//! publisher thread: iceoryx2 0.10's `send` allocates a small bookkeeping object per
//! sample, and the cycle path must allocate nothing. The loop pushes (no allocation,
//! no lock) and wakes the thread (a futex wake, no blocking).

use crate::bus::Bus;
use anyhow::Result;
use crossbeam_queue::ArrayQueue;
use softnc_ipc::{Alarm, Heartbeat, LoopStats, PositionStatus, ServiceNames};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// One outgoing message.
#[derive(Debug, Clone, Copy)]
pub enum OutMsg {
    /// Position status (every cycle).
    Status(PositionStatus),
    /// Heartbeat.
    Heartbeat(Heartbeat),
    /// Loop timing.
    LoopStats(LoopStats),
    /// Alarm.
    Alarm(Alarm),
}

/// Messages the queue holds.
pub const OUTBOX_CAPACITY: usize = 4096;

/// The loop's side of the outbox.
pub struct Outbox {
    queue: Arc<ArrayQueue<OutMsg>>,
    stop: Arc<AtomicBool>,
    dropped: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
    lossless: bool,
}

impl Outbox {
    /// Start the publisher thread with its own node `<instance>/<node>`. `lossless`:
    /// a full queue makes `send` wait (lockstep) instead of dropping (realtime).
    pub fn start(names: ServiceNames, node: &str, lossless: bool) -> Result<Self> {
        let queue = Arc::new(ArrayQueue::new(OUTBOX_CAPACITY));
        let stop = Arc::new(AtomicBool::new(false));
        let (q, st) = (queue.clone(), stop.clone());
        let node = node.to_string();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), String>>();
        let thread = std::thread::Builder::new()
            .name("outbox".into())
            .spawn(move || {
                let opened = (|| -> Result<_> {
                    let bus = Bus::new(names, &node)?;
                    Ok((
                        bus.status_publisher()?,
                        bus.heartbeat_publisher()?,
                        bus.loop_stats_publisher()?,
                        bus.alarm_publisher()?,
                        bus,
                    ))
                })();
                let (status, heartbeat, stats, alarms, _bus) = match opened {
                    Ok(p) => {
                        let _ = ready_tx.send(Ok(()));
                        p
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(format!("{e:#}")));
                        return;
                    }
                };
                loop {
                    while let Some(m) = q.pop() {
                        let r = match m {
                            OutMsg::Status(s) => status.send_copy(s).map(|_| ()),
                            OutMsg::Heartbeat(h) => heartbeat.send_copy(h).map(|_| ()),
                            OutMsg::LoopStats(l) => stats.send_copy(l).map(|_| ()),
                            OutMsg::Alarm(a) => alarms.send_copy(a).map(|_| ()),
                        };
                        if let Err(e) = r {
                            tracing::warn!("publishing failed: {e:?}");
                        }
                    }
                    if st.load(Ordering::Acquire) && q.is_empty() {
                        return;
                    }
                    std::thread::park_timeout(Duration::from_millis(1));
                }
            })?;
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => anyhow::bail!("outbox: {e}"),
            Err(_) => anyhow::bail!("outbox thread ended"),
        }
        Ok(Outbox {
            queue,
            stop,
            dropped: Arc::new(AtomicU64::new(0)),
            thread: Some(thread),
            lossless,
        })
    }

    /// Queue a message and wake the publisher (allocation-free). When the queue is
    /// full the message is dropped and counted.
    pub fn send(&self, m: OutMsg) {
        let mut item = m;
        loop {
            match self.queue.push(item) {
                Ok(()) => break,
                Err(back) if self.lossless => {
                    item = back;
                    if let Some(t) = &self.thread {
                        t.thread().unpark();
                    }
                    std::thread::yield_now();
                }
                Err(_) => {
                    self.dropped.fetch_add(1, Ordering::Relaxed);
                    break;
                }
            }
        }
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    /// Messages dropped because the publisher fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Drop for Outbox {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}
