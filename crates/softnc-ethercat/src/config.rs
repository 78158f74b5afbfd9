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
    /// A digital I/O terminal (its bits on raw lines through `inputs`/`outputs`).
    Io,
}

/// One bit of a SubDevice's digital inputs or outputs carried on a raw line of
/// the I/O boundary (`softnc_servo::io`: the machine profile's `servo.io` names
/// the signal on the line).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BitLine {
    /// Bit of the SubDevice's digital inputs or outputs (a drive: 0x60FD / 0x60FE;
    /// a terminal: its process data, bit 0 of the first byte first).
    pub bit: u8,
    /// Raw line (0 … 127).
    pub line: u8,
}

/// One expected SubDevice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExpectedSubDevice {
    /// Identity (the serial number is not compared).
    pub identity: Identity,
    /// Role.
    pub role: Role,
    /// Its digital inputs on raw input lines (a terminal's E-stop chain, probe,
    /// tool-changed; a drive's home switch, 0x60FD bit 2).
    #[serde(default)]
    pub inputs: Vec<BitLine>,
    /// Raw output lines on its digital outputs (a terminal's spindle, coolant).
    #[serde(default)]
    pub outputs: Vec<BitLine>,
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

/// Highest bit of a SubDevice's digital inputs or outputs that can be wired (a
/// drive's 0x60FD/0x60FE are 32 bits; a terminal's process data is checked at
/// bring-up).
const MAX_BIT: u8 = 63;

/// The wiring of `subdevices` to raw lines checked: each line within the raw
/// lines, each bit within [`MAX_BIT`], no input line fed by two bits, no output
/// line on two bits of one SubDevice. The RON path of a bad entry and why.
pub fn check_wiring(subdevices: &[ExpectedSubDevice]) -> Result<(), (String, String)> {
    let mut fed = 0u128;
    for (p, s) in subdevices.iter().enumerate() {
        let max_bit = match s.role {
            Role::Drive { .. } => 31,
            Role::Io => MAX_BIT,
        };
        let mut driven = 0u128;
        for (dir, wires) in [("inputs", &s.inputs), ("outputs", &s.outputs)] {
            for (k, w) in wires.iter().enumerate() {
                let path = format!("subdevices[{p}].{dir}[{k}]");
                if usize::from(w.line) >= softnc_servo::io::RAW_DIGITAL_LINES {
                    return Err((
                        format!("{path}.line"),
                        format!(
                            "line {} beyond the raw lines 0 … {}",
                            w.line,
                            softnc_servo::io::RAW_DIGITAL_LINES - 1
                        ),
                    ));
                }
                if w.bit > max_bit {
                    return Err((
                        format!("{path}.bit"),
                        format!("bit {} beyond {max_bit}", w.bit),
                    ));
                }
                let line = 1u128 << w.line;
                let seen = if dir == "inputs" {
                    &mut fed
                } else {
                    &mut driven
                };
                if *seen & line != 0 {
                    return Err((
                        format!("{path}.line"),
                        format!("line {} is on another bit already", w.line),
                    ));
                }
                *seen |= line;
            }
        }
    }
    Ok(())
}

impl EtherCatSettings {
    /// The settings checked (the wiring, the response timeout): the RON path
    /// below the section of a bad value and why.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if !(self.response_timeout_s > 0.0 && self.response_timeout_s.is_finite()) {
            return Err((
                "response_timeout_s".into(),
                "must be a finite number of seconds > 0".into(),
            ));
        }
        check_wiring(&self.subdevices)
    }
}
