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
    /// A drive's PDO mapping, written by SDO (`None`: [`PdoMapping::default`]).
    #[serde(default)]
    pub pdo: Option<PdoMapping>,
}

/// An object a drive's PDOs carry (CiA 402).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum PdoObject {
    /// 0x6040 controlword (RxPDO, required).
    ControlWord,
    /// 0x607A target position (RxPDO, required).
    TargetPosition,
    /// 0x6060 modes of operation (RxPDO; without it the mode is set by SDO only).
    ModesOfOperation,
    /// 0x60FE:01 digital outputs (RxPDO).
    DigitalOutputs,
    /// 0x6041 statusword (TxPDO, required).
    StatusWord,
    /// 0x6064 position actual value (TxPDO, required).
    PositionActual,
    /// 0x60F4 following error actual value (TxPDO).
    FollowingErrorActual,
    /// 0x60FD digital inputs (TxPDO; a drive's wired `inputs` need it).
    DigitalInputs,
    /// 0x603F error code (TxPDO; without it a drive fault's alarm says code 0).
    ErrorCode,
    /// 0x6061 modes of operation display (TxPDO).
    ModesOfOperationDisplay,
    /// Any other object (a vendor's), mapped and not read by softnc.
    Other {
        /// Index.
        index: u16,
        /// Subindex.
        sub: u8,
        /// Length: 8, 16 or 32 bits.
        bits: u8,
    },
}

/// Which PDO an object may be mapped into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PdoDirection {
    /// RxPDO (MainDevice to drive).
    Rx,
    /// TxPDO (drive to MainDevice).
    Tx,
    /// Either (an object softnc does not know).
    Either,
}

impl PdoObject {
    /// (index, subindex, bits).
    pub fn entry(self) -> (u16, u8, u8) {
        use PdoObject::*;
        match self {
            ControlWord => (0x6040, 0, 16),
            TargetPosition => (0x607A, 0, 32),
            ModesOfOperation => (0x6060, 0, 8),
            DigitalOutputs => (0x60FE, 1, 32),
            StatusWord => (0x6041, 0, 16),
            PositionActual => (0x6064, 0, 32),
            FollowingErrorActual => (0x60F4, 0, 32),
            DigitalInputs => (0x60FD, 0, 32),
            ErrorCode => (0x603F, 0, 16),
            ModesOfOperationDisplay => (0x6061, 0, 8),
            Other { index, sub, bits } => (index, sub, bits),
        }
    }
    /// The mapping entry as 0x1600/0x1A00 hold it (index, subindex, bits).
    pub fn mapping_entry(self) -> u32 {
        let (i, s, b) = self.entry();
        (u32::from(i) << 16) | (u32::from(s) << 8) | u32::from(b)
    }
    /// Bytes in the process image.
    pub fn bytes(self) -> usize {
        usize::from(self.entry().2 / 8)
    }
    /// Which PDO it belongs in.
    pub fn direction(self) -> PdoDirection {
        use PdoObject::*;
        match self {
            ControlWord | TargetPosition | ModesOfOperation | DigitalOutputs => PdoDirection::Rx,
            Other { .. } => PdoDirection::Either,
            _ => PdoDirection::Tx,
        }
    }
}

/// A drive's PDO mapping: the objects of RxPDO 0x1600 and TxPDO 0x1A00 in order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct PdoMapping {
    /// RxPDO 0x1600.
    pub rx: Vec<PdoObject>,
    /// TxPDO 0x1A00.
    pub tx: Vec<PdoObject>,
}

/// Objects one PDO may map (CiA 301 allows 254; drives often take 8 to 16).
pub const MAX_PDO_ENTRIES: usize = 16;

impl Default for PdoMapping {
    /// RxPDO: controlword, target position, modes of operation, digital outputs;
    /// TxPDO: statusword, position actual, following error actual, digital inputs,
    /// error code.
    fn default() -> Self {
        use PdoObject::*;
        PdoMapping {
            rx: vec![
                ControlWord,
                TargetPosition,
                ModesOfOperation,
                DigitalOutputs,
            ],
            tx: vec![
                StatusWord,
                PositionActual,
                FollowingErrorActual,
                DigitalInputs,
                ErrorCode,
            ],
        }
    }
}

impl PdoMapping {
    /// The mapping checked: each object in its direction and once, the required
    /// ones there, at most [`MAX_PDO_ENTRIES`] a PDO, lengths of 8, 16 or 32 bits.
    /// The RON path below the mapping of a bad entry and why.
    pub fn check(&self) -> Result<(), (String, String)> {
        for (name, list, dir, required) in [
            (
                "rx",
                &self.rx,
                PdoDirection::Rx,
                [PdoObject::ControlWord, PdoObject::TargetPosition],
            ),
            (
                "tx",
                &self.tx,
                PdoDirection::Tx,
                [PdoObject::StatusWord, PdoObject::PositionActual],
            ),
        ] {
            if list.len() > MAX_PDO_ENTRIES {
                return Err((
                    name.into(),
                    format!("{} objects, at most {MAX_PDO_ENTRIES}", list.len()),
                ));
            }
            for (k, o) in list.iter().enumerate() {
                let path = format!("{name}[{k}]");
                if o.direction() != dir && o.direction() != PdoDirection::Either {
                    return Err((
                        path,
                        format!(
                            "{o:?} belongs in the {}",
                            if dir == PdoDirection::Rx {
                                "TxPDO (tx)"
                            } else {
                                "RxPDO (rx)"
                            }
                        ),
                    ));
                }
                if !matches!(o.entry().2, 8 | 16 | 32) {
                    return Err((path, format!("{} bits: 8, 16 or 32", o.entry().2)));
                }
                if list[..k]
                    .iter()
                    .any(|p| p.entry().0 == o.entry().0 && p.entry().1 == o.entry().1)
                {
                    return Err((path, format!("{o:?} is mapped twice")));
                }
            }
            for r in required {
                if !list.contains(&r) {
                    return Err((name.into(), format!("{r:?} missing: the cycle needs it")));
                }
            }
        }
        Ok(())
    }

    /// Where `o` starts in its PDO's bytes, if mapped.
    pub fn offset_of(&self, o: PdoObject) -> Option<usize> {
        let list = if o.direction() == PdoDirection::Rx {
            &self.rx
        } else {
            &self.tx
        };
        let k = list.iter().position(|p| *p == o)?;
        Some(list[..k].iter().map(|p| p.bytes()).sum())
    }
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
        if let Some(m) = &s.pdo {
            if s.role == Role::Io {
                return Err((
                    format!("subdevices[{p}].pdo"),
                    "a terminal's PDOs are its EEPROM's: only a drive takes a mapping".into(),
                ));
            }
            m.check()
                .map_err(|(path, why)| (format!("subdevices[{p}].pdo.{path}"), why))?;
        }
        if let Role::Drive { .. } = s.role {
            let m = s.pdo.clone().unwrap_or_default();
            if !s.inputs.is_empty() && m.offset_of(PdoObject::DigitalInputs).is_none() {
                return Err((
                    format!("subdevices[{p}].inputs"),
                    "the drive's TxPDO has no DigitalInputs (0x60FD) to take them from".into(),
                ));
            }
            if !s.outputs.is_empty() && m.offset_of(PdoObject::DigitalOutputs).is_none() {
                return Err((
                    format!("subdevices[{p}].outputs"),
                    "the drive's RxPDO has no DigitalOutputs (0x60FE:01) to put them on".into(),
                ));
            }
        }
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
