//! An EtherCAT SubDevice emulator: a segment of emulated ESCs on one end of a
//! network interface (a `veth` pair in the tests), answering real EtherCAT frames
//! from any MainDevice — SOEM as well as softnc's own — as a chain of ESCs does.
//!
//! One module per part of the ESC: [`wire`] (frames, datagrams, working counter,
//! auto-increment addresses), [`esc`] (memory and what accesses do), [`regs`],
//! [`al`] (the AL state machine), [`sii`] (the EEPROM and its categories), [`sm`]
//! and [`fmmu`], [`dc`] (distributed clocks), [`mailbox`] (CoE SDO) over [`od`]
//! (the object dictionary); the devices behind: [`cia402`] (a servo drive in CSP)
//! and [`io_terminal`] (8 in, 8 out); [`control`] (faults on demand).
//!
//! The socket is a `pnet_datalink` layer-2 channel (a packet socket bound to the
//! interface); a frame is processed in place and sent back with the source
//! address's locally-administered bit set, as the first ESC of a segment does.

pub mod al;
pub mod app;
pub mod cia402;
pub mod control;
pub mod dc;
pub mod esc;
pub mod fmmu;
pub mod io_terminal;
pub mod mailbox;
pub mod od;
pub mod regs;
pub mod sii;
pub mod sm;
pub mod veth;
pub mod wire;

use app::{AppView, Application, Identity};
use control::Command;
use esc::Esc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Vendor id of the emulated devices.
pub const VENDOR_ID: u32 = 0x0000_05F7;
/// Product code of the emulated CiA 402 drive.
pub const DRIVE_PRODUCT: u32 = 0x0000_0402;
/// Product code of the emulated I/O terminal.
pub const IO_PRODUCT: u32 = 0x0008_0808;
/// Revision of both.
pub const REVISION: u32 = 0x0001_0000;
/// The drives' encoder (counts per mm): 0.1 µm.
pub const DRIVE_COUNTS_PER_MM: f64 = 10_000.0;
/// How long the socket waits for a frame before looking at commands.
const POLL: Duration = Duration::from_millis(5);

/// Why the emulator could not start.
#[derive(Debug, thiserror::Error)]
pub enum EmuError {
    /// No such interface.
    #[error("no network interface {0:?}")]
    NoInterface(String),
    /// The packet socket could not be opened (root or CAP_NET_RAW needed).
    #[error("opening a packet socket on {iface}: {source}")]
    Socket {
        /// Interface.
        iface: String,
        /// Cause.
        source: std::io::Error,
    },
}

/// What is on the segment, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// A CiA 402 servo drive.
    Drive,
    /// An 8-in/8-out digital I/O terminal.
    Io,
}

/// The identity the emulator gives the device of `kind` at `position`.
pub fn identity(kind: DeviceKind, position: usize) -> Identity {
    Identity {
        vendor_id: VENDOR_ID,
        product_code: match kind {
            DeviceKind::Drive => DRIVE_PRODUCT,
            DeviceKind::Io => IO_PRODUCT,
        },
        revision: REVISION,
        serial: 1000 + position as u32,
    }
}

/// The ESCs of a segment of `kinds`, in order.
pub fn segment(kinds: &[DeviceKind]) -> Vec<Esc> {
    kinds
        .iter()
        .enumerate()
        .map(|(p, &k)| {
            let app: Box<dyn Application> = match k {
                DeviceKind::Drive => {
                    Box::new(cia402::Drive::new(identity(k, p), DRIVE_COUNTS_PER_MM))
                }
                DeviceKind::Io => Box::new(io_terminal::IoTerminal::new(identity(k, p))),
            };
            Esc::new(app, p, kinds.len())
        })
        .collect()
}

/// One SubDevice as a test sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubDeviceView {
    /// Position (0 first).
    pub position: usize,
    /// Identity.
    pub identity: Identity,
    /// Configured station address.
    pub station_address: u16,
    /// AL state.
    pub al_state: al::AlState,
    /// AL status code when the error indicator is set.
    pub al_error: Option<u16>,
    /// SYNC0 events since activation.
    pub sync0_events: u64,
    /// The device.
    pub app: AppView,
}

/// Frame counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FrameStats {
    /// EtherCAT frames answered.
    pub answered: u64,
    /// Frames dropped on command (lost frames, link down).
    pub dropped: u64,
}

/// One process-data frame as a drive received it in OP.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Received {
    /// The frame's number (frames seen by the segment, answered or dropped, 1 first).
    pub frame: u64,
    /// Controlword.
    pub controlword: u16,
    /// Target position (counts).
    pub target_counts: i32,
}

/// Frames a drive's log of received targets keeps (ten minutes at 1 kHz).
const RECEIVED_CAP: usize = 600_000;

#[derive(Default)]
struct Shared {
    views: Vec<SubDeviceView>,
    stats: FrameStats,
    /// Per position: what each drive received, in order (capped).
    received: Vec<Vec<Received>>,
    /// The commands applied, each with the number of frames seen before it.
    applied: Vec<(u64, Command)>,
}

/// The running emulator; stopped when dropped.
pub struct Emulator {
    commands: Sender<Command>,
    shared: Arc<Mutex<Shared>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Emulator {
    /// Opens `iface` and answers frames on a thread of its own with a segment of
    /// `kinds`.
    pub fn spawn(iface: &str, kinds: &[DeviceKind]) -> Result<Self, EmuError> {
        Self::spawn_at(iface, kinds, None)
    }

    /// [`spawn`](Self::spawn), the answering thread at SCHED_FIFO `fifo_priority`
    /// where the process may (the emulated ESCs stand in for hardware, which
    /// answers within microseconds whatever else the host runs); at ordinary
    /// priority, with a warning on standard error, where it may not.
    pub fn spawn_at(
        iface: &str,
        kinds: &[DeviceKind],
        fifo_priority: Option<u8>,
    ) -> Result<Self, EmuError> {
        let interface = pnet_datalink::interfaces()
            .into_iter()
            .find(|i| i.name == iface)
            .ok_or_else(|| EmuError::NoInterface(iface.to_string()))?;
        let config = pnet_datalink::Config {
            read_timeout: Some(POLL),
            ..Default::default()
        };
        let socket_err = |source| EmuError::Socket {
            iface: iface.to_string(),
            source,
        };
        let (tx, rx) = match pnet_datalink::channel(&interface, config).map_err(socket_err)? {
            pnet_datalink::Channel::Ethernet(tx, rx) => (tx, rx),
            _ => return Err(socket_err(std::io::Error::other("not an Ethernet channel"))),
        };
        let (commands, cmd_rx) = channel();
        let shared = Arc::new(Mutex::new(Shared::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let mut escs = segment(kinds);
        publish(&shared, &escs, FrameStats::default());
        let (sh, st) = (shared.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("ethercat-emu".into())
            .spawn(move || {
                if let Some(p) = fifo_priority {
                    set_fifo(p);
                }
                serve(tx, rx, &mut escs, &cmd_rx, &sh, &st);
            })
            .map_err(socket_err)?;
        Ok(Emulator {
            commands,
            shared,
            stop,
            thread: Some(thread),
        })
    }

    /// Gives the emulator a command (applied before the next frame).
    pub fn command(&self, c: Command) {
        let _ = self.commands.send(c);
    }

    /// The SubDevices as of the last frame.
    pub fn views(&self) -> Vec<SubDeviceView> {
        self.shared.lock().expect("emulator state").views.clone()
    }

    /// Frame counters.
    pub fn stats(&self) -> FrameStats {
        self.shared.lock().expect("emulator state").stats
    }

    /// What the drive at `position` received in OP since the last call (controlword
    /// and target of each process-data frame, with the frame's number).
    pub fn take_received(&self, position: usize) -> Vec<Received> {
        let mut s = self.shared.lock().expect("emulator state");
        s.received
            .get_mut(position)
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// The commands applied so far, each with the number of frames the segment had
    /// seen (answered or dropped) before it took effect.
    pub fn applied(&self) -> Vec<(u64, Command)> {
        self.shared.lock().expect("emulator state").applied.clone()
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The calling thread at SCHED_FIFO `priority`, or a warning.
fn set_fifo(priority: u8) {
    use thread_priority::{
        set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
        ScheduleParams, ThreadPriority, ThreadSchedulePolicy,
    };
    let r = set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::from_posix(ScheduleParams {
            sched_priority: i32::from(priority),
        }),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    );
    if let Err(e) = r {
        eprintln!("ethercat-emu: SCHED_FIFO {priority} refused ({e:?}); ordinary priority");
    }
}

fn publish(shared: &Mutex<Shared>, escs: &[Esc], stats: FrameStats) {
    let views: Vec<SubDeviceView> = escs
        .iter()
        .enumerate()
        .map(|(position, e)| {
            let (al_state, al_error) = e.al();
            SubDeviceView {
                position,
                identity: e.app().identity(),
                station_address: e.station_address(),
                al_state,
                al_error,
                sync0_events: e.sync0_events,
                app: e.app().view(),
            }
        })
        .collect();
    let mut s = shared.lock().expect("emulator state");
    let frame = stats.answered + stats.dropped;
    let Shared {
        views: old,
        received,
        ..
    } = &mut *s;
    received.resize_with(views.len(), Vec::new);
    for ((new, old), log) in views.iter().zip(old.iter()).zip(received.iter_mut()) {
        if let (AppView::Drive(n), AppView::Drive(o)) = (new.app, old.app) {
            if n.targets_received > o.targets_received && log.len() < RECEIVED_CAP {
                log.push(Received {
                    frame,
                    controlword: n.controlword,
                    target_counts: n.target_counts,
                });
            }
        }
    }
    s.views = views;
    s.stats = stats;
}

struct Faults {
    link_down: bool,
    drop: u32,
}

fn apply(c: Command, escs: &mut [Esc], faults: &mut Faults) {
    match c {
        Command::LinkDown => faults.link_down = true,
        Command::LinkUp => faults.link_down = false,
        Command::Drop(n) => faults.drop += n,
        Command::DriveFault { position, code } => {
            if let Some(e) = escs.get_mut(position) {
                e.app_mut().inject_fault(code);
            }
        }
        Command::LeaveOp { position } => {
            if let Some(e) = escs.get_mut(position) {
                if e.al().0 == al::AlState::Op {
                    e.fail(al::AlState::SafeOp, al::code::SM_WATCHDOG);
                }
            }
        }
        Command::SkipWorkingCounter { position, frames } => {
            if let Some(e) = escs.get_mut(position) {
                e.skip_working_counter(frames);
            }
        }
        Command::HomeSwitch {
            position,
            at_counts,
        } => {
            if let Some(e) = escs.get_mut(position) {
                e.app_mut().set_home_switch(Some(at_counts));
            }
        }
        Command::Inputs { position, bits } => {
            if let Some(e) = escs.get_mut(position) {
                e.app_mut().set_digital_inputs(bits);
            }
        }
        Command::ClockStep { position, ns } => {
            if let Some(e) = escs.get_mut(position) {
                e.step_clock(u64::from(ns));
            }
        }
    }
}

fn serve(
    mut tx: Box<dyn pnet_datalink::DataLinkSender>,
    mut rx: Box<dyn pnet_datalink::DataLinkReceiver>,
    escs: &mut [Esc],
    commands: &Receiver<Command>,
    shared: &Mutex<Shared>,
    stop: &AtomicBool,
) {
    let clock = dc::HostClock::new();
    let mut faults = Faults {
        link_down: false,
        drop: 0,
    };
    let mut stats = FrameStats::default();
    let mut buf = Vec::with_capacity(1536);
    while !stop.load(Ordering::Relaxed) {
        let mut changed = false;
        while let Ok(c) = commands.try_recv() {
            apply(c, escs, &mut faults);
            shared
                .lock()
                .expect("emulator state")
                .applied
                .push((stats.answered + stats.dropped, c));
            changed = true;
        }
        if changed {
            publish(shared, escs, stats);
        }
        let frame = match rx.next() {
            Ok(f) => f,
            Err(_) => continue, // the poll timed out
        };
        if !wire::is_request(frame) {
            continue;
        }
        if faults.link_down || faults.drop > 0 {
            faults.drop = faults.drop.saturating_sub(1);
            stats.dropped += 1;
            publish(shared, escs, stats);
            continue;
        }
        buf.clear();
        buf.extend_from_slice(frame);
        if wire::process(&mut buf, escs, clock.now_ns()) {
            if let Some(Err(e)) = tx.send_to(&buf, None) {
                eprintln!("ethercat-emu: send: {e}");
            }
            stats.answered += 1;
            publish(shared, escs, stats);
        }
    }
}
