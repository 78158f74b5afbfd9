//! What the backend is opened with: the interface, the SubDevices expected in
//! order with their identities, and for each drive its axis, counts per mm and
//! direction.

use serde::{Deserialize, Serialize};
use std::time::Duration;

/// A SubDevice's identity as `softnc ethercat scan` prints it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// Vendor id.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision.
    pub revision: u32,
}

impl std::fmt::Display for Identity {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "vendor {:#010x} product {:#010x} revision {:#010x}",
            self.vendor_id, self.product_code, self.revision
        )
    }
}

/// What a SubDevice is to the machine.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Role {
    /// A CiA 402 drive in CSP driving `axis`.
    Drive {
        /// Axis index.
        axis: u8,
        /// Encoder counts per mm at the axis.
        counts_per_mm: f64,
        /// +1, or −1 where the drive counts against the axis.
        direction: i8,
        /// Following error window written to 0x6065 (counts).
        following_error_window_counts: u32,
    },
    /// A digital I/O terminal (on the bus, its signals not yet served).
    Io,
}

/// One expected SubDevice.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ExpectedSubDevice {
    /// Identity (the serial number is not compared).
    pub identity: Identity,
    /// Role.
    pub role: Role,
}

/// The bus.
#[derive(Debug, Clone, PartialEq)]
pub struct EtherCatConfig {
    /// Network interface dedicated to the bus.
    pub interface: String,
    /// The servo cycle: SYNC0 period and 0x60C2.
    pub cycle: Duration,
    /// How long `cycle()` waits for its frame before calling it lost.
    pub response_timeout: Duration,
    /// The SubDevices in bus order.
    pub subdevices: Vec<ExpectedSubDevice>,
}

/// How long a cycle waits for its frame unless the configuration says.
pub const DEFAULT_RESPONSE_TIMEOUT_S: f64 = 0.002;

fn default_response_timeout_s() -> f64 {
    DEFAULT_RESPONSE_TIMEOUT_S
}

/// The daemon configuration's section (`backend: EtherCat((interface: "enp2s0",
/// subdevices: [...]))`): the bus without its cycle, which is the machine
/// profile's interpolation cycle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EtherCatSettings {
    /// Network interface dedicated to the bus.
    pub interface: String,
    /// How long a cycle waits for its frame (s).
    #[serde(default = "default_response_timeout_s")]
    pub response_timeout_s: f64,
    /// The SubDevices in bus order.
    pub subdevices: Vec<ExpectedSubDevice>,
}

impl EtherCatSettings {
    /// The bus at servo cycle `cycle_s`.
    pub fn bus_config(&self, cycle_s: f64) -> EtherCatConfig {
        EtherCatConfig {
            interface: self.interface.clone(),
            cycle: Duration::from_secs_f64(cycle_s),
            response_timeout: Duration::from_secs_f64(self.response_timeout_s.max(0.0)),
            subdevices: self.subdevices.clone(),
        }
    }
}
