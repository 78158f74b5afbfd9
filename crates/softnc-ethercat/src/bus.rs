//! Bringing the bus up with ethercrab: the MainDevice on its storage, the TX/RX
//! task on a thread of its own (kept with an idle MainDevice for the next
//! bring-up on the interface), the SubDevices found and
//! compared with the expected ones, the drives' PDO mapping, CSP and 0x60C2 by SDO,
//! DC SYNC0 at the cycle, and the group taken to OP.

use crate::cia402;
use crate::config::{EtherCatConfig, Identity, Role};
use crate::exec::block_on;
use ethercrab::subdevice_group::{DcConfiguration, HasDc, Op};
use ethercrab::{DcSync, MainDevice, MainDeviceConfig, PduStorage, SubDeviceGroup, Timeouts};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// SubDevices a bus may have.
pub const MAX_SUBDEVICES: usize = 16;
/// Bytes of process image.
pub const MAX_PDI: usize = 256;
const MAX_FRAMES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
/// Bring-up steps (state changes, SDOs) get this long.
const BRING_UP: Duration = Duration::from_secs(10);
/// ethercrab's PDU timeout, at least (bring-up on a loaded machine).
const BRING_UP_PDU: Duration = Duration::from_millis(100);
/// DC static drift compensation frames at bring-up (ethercrab's default is 10 000).
const DC_SYNC_ITERATIONS: u32 = 200;
/// SYNC0 starts this long after the DC configuration.
const SYNC0_START_DELAY: Duration = Duration::from_millis(10);
/// Cycles of process data allowed for the SubDevices to reach OP.
const OP_CYCLES: usize = 1000;

/// The group in OP with DC.
pub type Group = SubDeviceGroup<MAX_SUBDEVICES, MAX_PDI, ethercrab::DefaultLock, Op, HasDc>;

/// Why the bus could not be brought up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OpenError {
    /// The interface or its TX/RX task.
    #[error("network interface {iface}: {reason}")]
    Interface {
        /// Interface.
        iface: String,
        /// Cause.
        reason: String,
    },
    /// ethercrab failed at a step.
    #[error("EtherCAT {step}: {reason}")]
    Bus {
        /// What was being done.
        step: &'static str,
        /// ethercrab's error.
        reason: String,
    },
    /// A bring-up step did not finish in time.
    #[error("EtherCAT {0}: timed out")]
    Timeout(&'static str),
    /// Not as many SubDevices as configured.
    #[error("{found} SubDevices on the bus, {expected} configured")]
    Count {
        /// Configured.
        expected: usize,
        /// Found.
        found: usize,
    },
    /// A SubDevice is not the one configured at its position.
    #[error("SubDevice {position}: found {found}, configured {expected}")]
    IdentityMismatch {
        /// Position (0 first).
        position: usize,
        /// Configured identity.
        expected: Identity,
        /// Found identity.
        found: Identity,
    },
    /// An SDO of the drive set-up was refused.
    #[error("SubDevice {position}: SDO {index:#06x}:{sub}: {reason}")]
    Sdo {
        /// Position.
        position: usize,
        /// Index.
        index: u16,
        /// Subindex.
        sub: u8,
        /// Abort or error.
        reason: String,
    },
    /// The configuration cannot be served.
    #[error("EtherCAT configuration: {0}")]
    Config(String),
}

/// One SubDevice found by [`scan`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Found {
    /// Position (0 first).
    pub position: usize,
    /// Configured station address ethercrab gave it.
    pub station_address: u16,
    /// Name from its EEPROM.
    pub name: String,
    /// Identity.
    pub identity: Identity,
    /// Serial number.
    pub serial: u32,
}

/// MainDevices not in use, each with its TX/RX thread still running on its
/// interface: the next bring-up there takes one (ethercrab's `init` resets the
/// SubDevices and starts afresh), so repeated bring-ups do not grow the heap.
/// ethercrab's storage and MainDevice are borrowed `'static` by its TX/RX task
/// and given back only through `unsafe` `release_all`: each MainDevice made here
/// stays for the life of the process (≈ 20 KiB), one per interface and bus in use
/// at once.
static IDLE: Mutex<Vec<Idle>> = Mutex::new(Vec::new());

/// A MainDevice waiting in [`IDLE`].
struct Idle {
    iface: String,
    pdu_timeout: Duration,
    md: &'static MainDevice<'static>,
    txrx: std::thread::JoinHandle<()>,
}

/// A MainDevice in use (its TX/RX thread running on the interface); back to the
/// idle ones when dropped.
pub struct Master {
    md: &'static MainDevice<'static>,
    idle: Option<Idle>,
}

impl Master {
    /// The MainDevice.
    pub fn md(&self) -> &'static MainDevice<'static> {
        self.md
    }

    fn of(idle: Idle) -> Self {
        Master {
            md: idle.md,
            idle: Some(idle),
        }
    }
}

impl Drop for Master {
    fn drop(&mut self) {
        if let Some(i) = self.idle.take() {
            // a thread that ended (its interface gone) takes its MainDevice with it
            if !i.txrx.is_finished() {
                IDLE.lock().unwrap_or_else(|e| e.into_inner()).push(i);
            }
        }
    }
}

/// A MainDevice on `iface` with ethercrab's PDU timeout `pdu_timeout`: an idle
/// one of an earlier bring-up, or a new one with its TX/RX thread.
pub fn main_device(iface: &str, pdu_timeout: Duration) -> Result<Master, OpenError> {
    if !std::path::Path::new("/sys/class/net").join(iface).exists() {
        return Err(OpenError::Interface {
            iface: iface.into(),
            reason: "no such network interface".into(),
        });
    }
    {
        let mut idle = IDLE.lock().unwrap_or_else(|e| e.into_inner());
        // the ones whose thread ended (their interface gone) are left
        idle.retain(|i| !i.txrx.is_finished());
        if let Some(k) = idle
            .iter()
            .position(|i| i.iface == iface && i.pdu_timeout == pdu_timeout)
        {
            return Ok(Master::of(idle.swap_remove(k)));
        }
    }
    let storage: &'static PduStorage<MAX_FRAMES, MAX_PDU_DATA> =
        Box::leak(Box::new(PduStorage::new()));
    let (tx, rx, pdu_loop) = storage.try_split().map_err(|()| OpenError::Interface {
        iface: iface.into(),
        reason: "PDU storage already split".into(),
    })?;
    let name = iface.to_string();
    // the socket is opened on the task's thread; its outcome is reported back
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let txrx = std::thread::Builder::new()
        .name("ethercat-txrx".into())
        .spawn(move || {
            // ethercrab's async task on async-io's reactor: a lost frame only times
            // out its future (its io_uring task waits for every read it submitted,
            // so one lost frame would stop it). It runs until its socket fails
            // (the interface gone) or the process ends.
            match ethercrab::std::tx_rx_task(&name, tx, rx) {
                Ok(task) => {
                    let _ = ready_tx.send(Ok(()));
                    let _ = async_io::block_on(task);
                }
                Err(e) => {
                    let _ = ready_tx.send(Err(e.to_string()));
                }
            }
        })
        .map_err(|e| OpenError::Interface {
            iface: iface.into(),
            reason: e.to_string(),
        })?;
    // no such interface, no CAP_NET_RAW: said at once
    match ready_rx.recv() {
        Ok(Ok(())) => {}
        Ok(Err(reason)) => {
            return Err(OpenError::Interface {
                iface: iface.into(),
                reason,
            })
        }
        Err(_) => {
            return Err(OpenError::Interface {
                iface: iface.into(),
                reason: "the TX/RX thread ended".into(),
            })
        }
    }
    let timeouts = Timeouts {
        pdu: pdu_timeout,
        state_transition: Duration::from_secs(5),
        // an SII EEPROM read at bring-up (off the cycle): ethercrab's 10 ms timed
        // out against the emulated SubDevices on a loaded 2-core machine, where
        // SOEM gives it 20 ms; a real ESC answers in a few
        eeprom: EEPROM_TIMEOUT,
        wait_loop_delay: Duration::from_micros(200),
        ..Timeouts::default()
    };
    let config = MainDeviceConfig {
        dc_static_sync_iterations: DC_SYNC_ITERATIONS,
        ..MainDeviceConfig::default()
    };
    let md: &'static MainDevice<'static> =
        Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts, config)));
    Ok(Master::of(Idle {
        iface: iface.into(),
        pdu_timeout,
        md,
        txrx,
    }))
}

/// How long an SII EEPROM read may take at bring-up.
const EEPROM_TIMEOUT: Duration = Duration::from_millis(100);

pub(crate) fn bus_err(step: &'static str) -> impl Fn(ethercrab::error::Error) -> OpenError {
    move |e| OpenError::Bus {
        step,
        reason: e.to_string(),
    }
}

fn run<F: std::future::Future<Output = Result<T, ethercrab::error::Error>>, T>(
    step: &'static str,
    f: F,
) -> Result<T, OpenError> {
    block_on(f, Instant::now() + BRING_UP)
        .ok_or(OpenError::Timeout(step))?
        .map_err(bus_err(step))
}

/// The SubDevices on `iface`, in order, brought to PRE-OP.
pub fn scan(iface: &str) -> Result<Vec<Found>, OpenError> {
    let master = main_device(iface, BRING_UP_PDU)?;
    let md = master.md();
    let group = run(
        "scan",
        md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercrab::std::ethercat_now),
    )?;
    Ok(group
        .iter(md)
        .enumerate()
        .map(|(position, s)| {
            let id = s.identity();
            Found {
                position,
                station_address: s.configured_address(),
                name: s.name().to_string(),
                identity: Identity {
                    vendor_id: id.vendor_id,
                    product_code: id.product_id,
                    revision: id.revision,
                },
                serial: id.serial,
            }
        })
        .collect())
}

/// The bus brought up to OP as `config` says.
pub fn bring_up(config: &EtherCatConfig) -> Result<(Master, Group), OpenError> {
    let cycle_ns = config.cycle.as_nanos() as u64;
    let (period, index) = cia402::interpolation_period(cycle_ns)
        .ok_or_else(|| OpenError::Config(format!("cycle {cycle_ns} ns has no 0x60C2 form")))?;
    // bring-up's register and EEPROM accesses get a PDU timeout of their own; the
    // cycle bounds its wait itself (a dropped future gives its frame back)
    let master = main_device(&config.interface, config.response_timeout.max(BRING_UP_PDU))?;
    let md = master.md();
    let mut group = run(
        "init",
        md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercrab::std::ethercat_now),
    )?;
    if group.len() != config.subdevices.len() {
        return Err(OpenError::Count {
            expected: config.subdevices.len(),
            found: group.len(),
        });
    }
    for (position, (mut s, want)) in group.iter_mut(md).zip(&config.subdevices).enumerate() {
        let id = s.identity();
        let found = Identity {
            vendor_id: id.vendor_id,
            product_code: id.product_id,
            revision: id.revision,
        };
        if found != want.identity {
            return Err(OpenError::IdentityMismatch {
                position,
                expected: want.identity,
                found,
            });
        }
        let Role::Drive {
            following_error_window_counts,
            ..
        } = want.role
        else {
            continue;
        };
        let sdo = |index: u16, sub: u8| {
            move |e: ethercrab::error::Error| OpenError::Sdo {
                position,
                index,
                sub,
                reason: e.to_string(),
            }
        };
        macro_rules! write {
            ($index:expr, $sub:expr, $v:expr) => {
                block_on(s.sdo_write($index, $sub, $v), Instant::now() + BRING_UP)
                    .ok_or(OpenError::Timeout("SDO"))?
                    .map_err(sdo($index, $sub))?
            };
        }
        // PDO mapping (CiA 301: assignment and mapping emptied, filled, counted)
        write!(0x1C12, 0, 0u8);
        write!(0x1600, 0, 0u8);
        let mapping = want.pdo.clone().unwrap_or_default();
        for (k, o) in mapping.rx.iter().enumerate() {
            write!(0x1600, k as u8 + 1, o.mapping_entry());
        }
        write!(0x1600, 0, mapping.rx.len() as u8);
        write!(0x1C12, 1, 0x1600u16);
        write!(0x1C12, 0, 1u8);
        write!(0x1C13, 0, 0u8);
        write!(0x1A00, 0, 0u8);
        for (k, o) in mapping.tx.iter().enumerate() {
            write!(0x1A00, k as u8 + 1, o.mapping_entry());
        }
        write!(0x1A00, 0, mapping.tx.len() as u8);
        write!(0x1C13, 1, 0x1A00u16);
        write!(0x1C13, 0, 1u8);
        write!(0x6060, 0, cia402::MODE_CSP);
        write!(0x60C2, 1, period);
        write!(0x60C2, 2, index);
        write!(0x6065, 0, following_error_window_counts);
        s.set_dc_sync(DcSync::Sync0);
    }
    let group = run("PRE-OP with process data", group.into_pre_op_pdi(md))?;
    let group = run(
        "DC",
        group.configure_dc_sync(
            md,
            DcConfiguration {
                start_delay: SYNC0_START_DELAY,
                sync0_period: config.cycle,
                sync0_shift: Duration::ZERO,
            },
        ),
    )?;
    let group = run("SAFE-OP", group.into_safe_op(md))?;
    let group = run("OP request", group.request_into_op(md))?;
    for _ in 0..OP_CYCLES {
        let r = run("OP", group.tx_rx_dc(md))?;
        if r.all_op() {
            return Ok((master, group));
        }
        std::thread::sleep(config.cycle);
    }
    Err(OpenError::Timeout("OP"))
}
