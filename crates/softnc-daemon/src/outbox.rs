//! The cyclic loops' outgoing messages leave through a bounded lock-free queue to a
//! publisher thread: iceoryx2 0.10's `send` allocates a small bookkeeping object per
//! sample, and the cycle path must allocate nothing. The loop pushes (no allocation,
//! no lock) and wakes the thread (a futex wake, no blocking).
//!
//! One implementation serves both loops, over the message enum of each:
//! [`PositionMsg`] (status every cycle, heartbeats, loop stats, alarms) and
//! [`InterpMsg`] (command samples, heartbeats, loop stats, alarms and notes). One
//! queue and one thread per loop keep the loop's messages in the order it sent them.
//!
//! The thread is started by the cycle thread and would inherit its SCHED_FIFO
//! priority: it goes back to SCHED_OTHER first. So a loop waiting for room sleeps
//! rather than yields (a yield would not let a SCHED_OTHER thread on its core run).
//! It also logs the alarms it publishes, so that no log line is formatted on the
//! cycle. If the thread ends (a message that must arrive could not be published, or
//! a bug), the loop's next [`Outbox::send`] says so.

use anyhow::Result;
use crossbeam_queue::ArrayQueue;
use softnc_ipc::bus::{Bus, Pub};
use softnc_ipc::{
    Alarm, AlarmCode, CommandSample, Heartbeat, LoopStats, PositionStatus, ServiceNames,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Messages the queue holds, at least.
pub const OUTBOX_CAPACITY: usize = 4096;

/// How long a loop waits for room in a full queue before it gives the publisher up
/// as stalled.
pub const STALL_TIMEOUT: Duration = Duration::from_secs(2);

/// How long a loop sleeps between tries while the queue is full.
const FULL_WAIT: Duration = Duration::from_micros(50);

/// A message enum an [`Outbox`] carries.
pub trait Outgoing: Copy + Send + std::fmt::Debug + 'static {
    /// The publishers, opened on the publisher thread.
    type Ports;
    /// Open the publishers on `bus`.
    fn open(bus: &Bus) -> Result<Self::Ports>;
    /// Publish the message.
    fn publish(self, ports: &Self::Ports) -> Result<()>;
    /// Never dropped: a full queue makes the loop wait, and a failed publish ends
    /// the publisher thread (the loop then sees it) instead of being logged.
    fn must_arrive(&self) -> bool {
        false
    }
}

/// Why a message could not be queued (on the cycle path: no text, no allocation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum OutboxError {
    /// The publisher thread has ended (its log says why).
    #[error("the outbox's publisher thread has ended (see its log)")]
    Ended,
    /// The queue stayed full for [`STALL_TIMEOUT`].
    #[error("the outbox's publisher thread has taken nothing for {STALL_TIMEOUT:?}")]
    Stalled,
}

/// One outgoing message of the position loop.
#[derive(Debug, Clone, Copy)]
pub enum PositionMsg {
    /// Position status (every cycle).
    Status(PositionStatus),
    /// Heartbeat.
    Heartbeat(Heartbeat),
    /// Loop timing.
    LoopStats(LoopStats),
    /// Alarm.
    Alarm(Alarm),
}

impl Outgoing for PositionMsg {
    type Ports = (
        Pub<PositionStatus>,
        Pub<Heartbeat>,
        Pub<LoopStats>,
        Pub<Alarm>,
    );
    fn open(bus: &Bus) -> Result<Self::Ports> {
        Ok((
            bus.status_publisher()?,
            bus.heartbeat_publisher()?,
            bus.loop_stats_publisher()?,
            bus.alarm_publisher()?,
        ))
    }
    fn publish(self, (status, heartbeat, stats, alarms): &Self::Ports) -> Result<()> {
        match self {
            PositionMsg::Status(s) => status.send_copy(s).map(drop)?,
            PositionMsg::Heartbeat(h) => heartbeat.send_copy(h).map(drop)?,
            PositionMsg::LoopStats(l) => stats.send_copy(l).map(drop)?,
            PositionMsg::Alarm(a) => {
                log_alarm(&a);
                alarms.send_copy(a).map(drop)?
            }
        }
        Ok(())
    }
}

/// One outgoing message of the interpolation loop.
#[derive(Debug, Clone, Copy)]
pub enum InterpMsg {
    /// A command sample: never dropped.
    Command(CommandSample),
    /// Heartbeat.
    Heartbeat(Heartbeat),
    /// Loop timing.
    LoopStats(LoopStats),
    /// Alarm or note.
    Alarm(Alarm),
}

impl Outgoing for InterpMsg {
    type Ports = (
        Pub<CommandSample>,
        Pub<Heartbeat>,
        Pub<LoopStats>,
        Pub<Alarm>,
    );
    fn open(bus: &Bus) -> Result<Self::Ports> {
        Ok((
            bus.command_publisher()?,
            bus.heartbeat_publisher()?,
            bus.loop_stats_publisher()?,
            bus.alarm_publisher()?,
        ))
    }
    fn publish(self, (commands, heartbeat, stats, alarms): &Self::Ports) -> Result<()> {
        match self {
            InterpMsg::Command(c) => commands.send_copy(c).map(drop)?,
            InterpMsg::Heartbeat(h) => heartbeat.send_copy(h).map(drop)?,
            InterpMsg::LoopStats(l) => stats.send_copy(l).map(drop)?,
            InterpMsg::Alarm(a) => {
                log_alarm(&a);
                alarms.send_copy(a).map(drop)?
            }
        }
        Ok(())
    }
    fn must_arrive(&self) -> bool {
        matches!(self, InterpMsg::Command(_))
    }
}

/// The log line of an alarm (a note: the job's remark), written off the cycle.
fn log_alarm(a: &Alarm) {
    match AlarmCode::from_wire(a.code) {
        Some(AlarmCode::Note) => tracing::info!("job {}: {}", a.job_id, a.message.as_str()),
        code => tracing::warn!("alarm {code:?}: {}", a.message.as_str()),
    }
}

/// The loop's side of the outbox.
pub struct Outbox<M: Outgoing> {
    queue: Arc<ArrayQueue<M>>,
    stop: Arc<AtomicBool>,
    dropped: u64,
    waits: u64,
    thread: Option<std::thread::JoinHandle<()>>,
    lossless: bool,
}

impl<M: Outgoing> Outbox<M> {
    /// Start the publisher thread with its own node `<instance>/<node>` and a queue
    /// of `capacity` messages (at least [`OUTBOX_CAPACITY`]). `lossless`: a full
    /// queue makes `send` wait (lockstep) instead of dropping (realtime); messages
    /// that [must arrive](Outgoing::must_arrive) always wait. `fifo_priority`: the
    /// publisher's own SCHED_FIFO priority, below its loop's (it carries the loop's
    /// messages, and a command sample published late runs the ring dry); `None`:
    /// SCHED_OTHER.
    pub fn start(
        names: ServiceNames,
        node: &str,
        capacity: usize,
        lossless: bool,
        fifo_priority: Option<u8>,
    ) -> Result<Self> {
        let queue = Arc::new(ArrayQueue::<M>::new(capacity.max(OUTBOX_CAPACITY)));
        let stop = Arc::new(AtomicBool::new(false));
        let (q, st) = (queue.clone(), stop.clone());
        let node = node.to_string();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), String>>();
        let thread = std::thread::Builder::new()
            .name(node.clone())
            .spawn(move || {
                // started by the cycle thread: not at its SCHED_FIFO priority, at
                // its own below it (or none); it sleeps between messages, so the loop
                // on its core runs first
                if let Err(e) = softnc_rt::leave_realtime() {
                    tracing::warn!("{node}: {e}");
                }
                if fifo_priority.is_some() {
                    softnc_rt::setup_realtime(&softnc_rt::RtOptions {
                        fifo_priority,
                        ..Default::default()
                    });
                }
                let opened = Bus::new(names, &node)
                    .map_err(anyhow::Error::from)
                    .and_then(|bus| Ok((M::open(&bus)?, bus)));
                let (ports, _bus) = match opened {
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
                        if let Err(e) = m.publish(&ports) {
                            if m.must_arrive() {
                                tracing::error!("{node}: publishing {m:?} failed: {e:#}; ending");
                                return;
                            }
                            tracing::warn!("{node}: publishing failed: {e:#}");
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
            dropped: 0,
            waits: 0,
            thread: Some(thread),
            lossless,
        })
    }

    /// Queue a message and wake the publisher (allocation-free, no lock). When the
    /// queue is full the message is dropped and counted, or — lossless, or a message
    /// that must arrive — the loop waits for room (counted).
    pub fn send(&mut self, m: M) -> Result<(), OutboxError> {
        if !self.is_alive() {
            return Err(OutboxError::Ended);
        }
        let mut item = m;
        let mut full_since: Option<Instant> = None;
        loop {
            match self.queue.push(item) {
                Ok(()) => break,
                Err(back) if self.lossless || back.must_arrive() => {
                    item = back;
                    let since = *full_since.get_or_insert_with(|| {
                        self.waits += 1;
                        Instant::now()
                    });
                    if !self.is_alive() {
                        return Err(OutboxError::Ended);
                    }
                    if since.elapsed() > STALL_TIMEOUT {
                        return Err(OutboxError::Stalled);
                    }
                    self.wake();
                    // sleep, not yield: the publisher may share this core at SCHED_OTHER
                    std::thread::sleep(FULL_WAIT);
                }
                Err(_) => {
                    self.dropped += 1;
                    break;
                }
            }
        }
        self.wake();
        Ok(())
    }

    fn wake(&self) {
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    /// False once the publisher thread has ended.
    pub fn is_alive(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Messages dropped because the publisher fell behind.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Sends that found the queue full and waited for room.
    pub fn waits(&self) -> u64 {
        self.waits
    }
}

impl<M: Outgoing> Drop for Outbox<M> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
        if self.dropped > 0 || self.waits > 0 {
            tracing::warn!(
                "outbox: {} messages dropped, {} waits for room in a full queue",
                self.dropped,
                self.waits
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An instance of the test's own.
    fn names(tag: &str) -> ServiceNames {
        ServiceNames::new("softnc", &format!("outboxtest{tag}{}", std::process::id()))
    }

    fn heartbeat(counter: u64) -> InterpMsg {
        InterpMsg::Heartbeat(Heartbeat {
            process: 0,
            pid: 0,
            counter,
            state: 0,
            job_id: 0,
        })
    }

    #[test]
    fn messages_arrive_in_the_order_sent() {
        let names = names("order");
        let bus = Bus::new(names.clone(), "listener").unwrap();
        let commands = bus.command_subscriber().unwrap();
        let beats = bus.heartbeat_subscriber().unwrap();
        let mut out = Outbox::<InterpMsg>::start(names, "order-out", 0, true, None).unwrap();
        for k in 0..500 {
            out.send(InterpMsg::Command(CommandSample::new(k, 1, k, [0.0; 3])))
                .unwrap();
            if k % 100 == 0 {
                out.send(heartbeat(k)).unwrap();
            }
        }
        // (read while the publisher lives: its samples go with it)
        let (mut seqs, mut counters) = (Vec::new(), Vec::new());
        let t0 = Instant::now();
        while seqs.len() < 500 || counters.len() < 5 {
            assert!(
                t0.elapsed() < Duration::from_secs(30),
                "{seqs:?} {counters:?}"
            );
            while let Some(c) = commands.receive().unwrap() {
                seqs.push(c.seq);
            }
            while let Some(h) = beats.receive().unwrap() {
                counters.push(h.counter);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(seqs, (0..500).collect::<Vec<_>>());
        assert_eq!(counters, [0, 100, 200, 300, 400]);
        assert_eq!((out.dropped(), out.waits()), (0, 0));
    }

    /// The scheduling policy of this process's thread named `name` (0 SCHED_OTHER,
    /// 1 SCHED_FIFO), from field 41 of its `/proc` stat.
    fn policy_of(name: &str) -> Option<u32> {
        stat_field(name, 41)
    }

    /// The real-time priority of this process's thread named `name` (field 40).
    fn priority_of(name: &str) -> Option<u32> {
        stat_field(name, 40)
    }

    /// Field `field` (1-based, as proc(5) counts) of the `/proc` stat of this
    /// process's thread named `name`.
    fn stat_field(name: &str, field: usize) -> Option<u32> {
        for task in std::fs::read_dir("/proc/self/task").ok()? {
            let task = task.ok()?.path();
            let comm = std::fs::read_to_string(task.join("comm")).ok()?;
            if comm.trim_end() == name {
                let stat = std::fs::read_to_string(task.join("stat")).ok()?;
                let after_comm = &stat[stat.rfind(')')? + 2..];
                return after_comm.split(' ').nth(field - 3)?.parse().ok();
            }
        }
        None
    }

    #[test]
    fn the_publisher_thread_runs_at_its_own_priority_not_the_loops() {
        let cycle = std::thread::Builder::new().name("fifo-loop".into());
        cycle
            .spawn(|| {
                let rt = softnc_rt::setup_realtime(&softnc_rt::RtOptions {
                    fifo_priority: Some(10),
                    ..Default::default()
                });
                let other =
                    Outbox::<InterpMsg>::start(names("fifo"), "other-out", 0, true, None).unwrap();
                let below =
                    Outbox::<InterpMsg>::start(names("fifo2"), "below-out", 0, true, Some(9))
                        .unwrap();
                let me = policy_of("fifo-loop");
                let (other_policy, below_policy) = (policy_of("other-out"), policy_of("below-out"));
                let below_prio = priority_of("below-out");
                softnc_rt::leave_realtime().unwrap();
                drop((other, below));
                if rt.fifo.is_some() {
                    assert_eq!(me, Some(1), "the loop's thread runs SCHED_FIFO");
                    assert_eq!(
                        below_policy,
                        Some(1),
                        "a publisher given a priority runs SCHED_FIFO"
                    );
                    assert_eq!(
                        below_prio,
                        Some(9),
                        "at its own priority, not the loop's 10"
                    );
                } else {
                    eprintln!("SCHED_FIFO refused here: the inheritance is not exercised");
                }
                assert_eq!(
                    other_policy,
                    Some(0),
                    "a publisher without one runs SCHED_OTHER"
                );
            })
            .unwrap()
            .join()
            .unwrap();
    }

    /// An outbox whose "publisher" only drains the queue once `release` is set (and
    /// ends at `stop`).
    fn held(release: Arc<AtomicBool>) -> Outbox<InterpMsg> {
        let queue = Arc::new(ArrayQueue::new(8));
        let stop = Arc::new(AtomicBool::new(false));
        let (q, st) = (queue.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            while !st.load(Ordering::Acquire) {
                if release.load(Ordering::Acquire) {
                    while q.pop().is_some() {}
                }
                std::thread::park_timeout(Duration::from_millis(1));
            }
        });
        Outbox {
            queue,
            stop,
            dropped: 0,
            waits: 0,
            thread: Some(thread),
            lossless: false,
        }
    }

    fn sample(k: u64) -> InterpMsg {
        InterpMsg::Command(CommandSample::new(k, 1, k, [0.0; 3]))
    }

    #[test]
    fn a_full_queue_drops_a_heartbeat_but_waits_for_a_command_sample() {
        let release = Arc::new(AtomicBool::new(false));
        let mut out = held(release.clone());
        for k in 0..8 {
            out.send(sample(k)).unwrap();
        }
        out.send(heartbeat(1)).unwrap();
        assert_eq!((out.dropped(), out.waits()), (1, 0));
        let releaser = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            release.store(true, Ordering::Release);
        });
        out.send(sample(8)).unwrap();
        releaser.join().unwrap();
        assert_eq!((out.dropped(), out.waits()), (1, 1));
    }

    #[test]
    fn the_loop_sees_a_publisher_that_stalls_or_ends() {
        let mut out = held(Arc::new(AtomicBool::new(false)));
        for k in 0..8 {
            out.send(sample(k)).unwrap();
        }
        assert_eq!(out.send(sample(8)), Err(OutboxError::Stalled));
        // the thread ends (as after a failed command publish, or a panic)
        out.stop.store(true, Ordering::Release);
        let t0 = Instant::now();
        while out.is_alive() {
            assert!(t0.elapsed() < Duration::from_secs(30), "thread did not end");
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(out.send(heartbeat(2)), Err(OutboxError::Ended));
    }
}
