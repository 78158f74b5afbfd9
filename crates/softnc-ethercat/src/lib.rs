//! The EtherCAT backend: CiA 402 servo drives in cyclic synchronous position mode
//! (CSP) on an EtherCAT bus, through the `ethercrab` MainDevice, behind
//! `softnc_servo::ServoBackend` (docs/architecture.md, "A real drive";
//! docs/ethercat.md).
//!
//! ethercrab's TX/RX runs on a thread of its own (`tx_rx_task` under `async_io::block_on`);
//! the cycle drives ethercrab's futures on the caller's thread with [`exec`]'s
//! executor, bounded by the configured response timeout and allocation-free.

pub mod backend;
pub mod bus;
pub mod cia402;
pub mod config;
pub mod exec;

pub use backend::{BusStats, EtherCatBackend};
pub use bus::{scan, Found, OpenError};
pub use config::{
    BitLine, EtherCatConfig, EtherCatSettings, ExpectedSubDevice, Identity, PdoMapping, PdoObject,
    Role,
};
