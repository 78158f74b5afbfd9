//! What the backend is opened with: the interface, the SubDevices expected in
//! order with their identities, and for each drive its axis, counts per mm and
//! direction.

use std::time::Duration;

/// A SubDevice's identity as `softnc ethercat scan` prints it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
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
#[derive(Debug, Clone, Copy, PartialEq)]
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
#[derive(Debug, Clone, Copy, PartialEq)]
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
