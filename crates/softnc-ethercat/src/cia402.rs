//! CiA 402 on the process image: the PDO mapping the backend writes by SDO, the
//! controlword commands and the statusword's states (IEC 61800-7-201 §6.2; the
//! `ds402` module of ethercrab is not in its 0.7 release, so this is our own).

use crate::config::{PdoMapping, PdoObject};

/// Where each object the cycle uses lies in a drive's process data (bytes), from
/// its PDO mapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// 0x6040.
    pub controlword: usize,
    /// 0x607A.
    pub target: usize,
    /// 0x6060, where mapped.
    pub mode: Option<usize>,
    /// 0x60FE:01, where mapped.
    pub digital_outputs: Option<usize>,
    /// 0x6041.
    pub statusword: usize,
    /// 0x6064.
    pub position: usize,
    /// 0x60F4, where mapped.
    pub following_error: Option<usize>,
    /// 0x60FD, where mapped.
    pub digital_inputs: Option<usize>,
    /// 0x603F, where mapped.
    pub error_code: Option<usize>,
    /// Output bytes.
    pub rx_bytes: usize,
    /// Input bytes.
    pub tx_bytes: usize,
}

impl Layout {
    /// The layout of a mapping that passed [`PdoMapping::check`] (the required
    /// objects at 0 where missing).
    pub fn of(m: &PdoMapping) -> Self {
        let at = |o| m.offset_of(o);
        Layout {
            controlword: at(PdoObject::ControlWord).unwrap_or(0),
            target: at(PdoObject::TargetPosition).unwrap_or(0),
            mode: at(PdoObject::ModesOfOperation),
            digital_outputs: at(PdoObject::DigitalOutputs),
            statusword: at(PdoObject::StatusWord).unwrap_or(0),
            position: at(PdoObject::PositionActual).unwrap_or(0),
            following_error: at(PdoObject::FollowingErrorActual),
            digital_inputs: at(PdoObject::DigitalInputs),
            error_code: at(PdoObject::ErrorCode),
            rx_bytes: m.rx.iter().map(|o| o.bytes()).sum(),
            tx_bytes: m.tx.iter().map(|o| o.bytes()).sum(),
        }
    }
}

/// Modes of operation: cyclic synchronous position.
pub const MODE_CSP: i8 = 8;

/// Controlword commands.
pub mod cw {
    /// Shutdown.
    pub const SHUTDOWN: u16 = 0x0006;
    /// Switch on.
    pub const SWITCH_ON: u16 = 0x0007;
    /// Enable operation.
    pub const ENABLE: u16 = 0x000F;
    /// Quick stop.
    pub const QUICK_STOP: u16 = 0x0002;
    /// Disable voltage.
    pub const DISABLE_VOLTAGE: u16 = 0x0000;
    /// Fault reset (rising edge).
    pub const FAULT_RESET: u16 = 0x0080;
}

/// Statusword masks and values (the state bits 0–3, 5, 6).
const STATE_MASK: u16 = 0x006F;
/// Ready to switch on.
pub const READY: u16 = 0x0021;
/// Switched on.
pub const SWITCHED_ON: u16 = 0x0023;
/// Operation enabled.
pub const OPERATION_ENABLED: u16 = 0x0027;
/// Fault bit.
pub const FAULT_BIT: u16 = 0x0008;

/// The statusword's state bits.
pub fn state(statusword: u16) -> u16 {
    statusword & STATE_MASK
}

/// One drive's inputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inputs {
    /// 0x6041.
    pub statusword: u16,
    /// 0x6064 (counts).
    pub position: i32,
    /// 0x60F4 (counts).
    pub following_error: i32,
    /// 0x60FD.
    pub digital_inputs: u32,
    /// 0x603F.
    pub error_code: u16,
}

impl Inputs {
    /// From the drive's input bytes as `l` lays them out (shorter bytes read 0).
    pub fn parse(b: &[u8], l: &Layout) -> Self {
        let get = |at: usize, n: usize| -> u32 {
            let mut v = [0u8; 4];
            if let Some(src) = b.get(at..at + n) {
                v[..n].copy_from_slice(src);
            }
            u32::from_le_bytes(v)
        };
        Inputs {
            statusword: get(l.statusword, 2) as u16,
            position: get(l.position, 4) as i32,
            following_error: l.following_error.map_or(0, |at| get(at, 4) as i32),
            digital_inputs: l.digital_inputs.map_or(0, |at| get(at, 4)),
            error_code: l.error_code.map_or(0, |at| get(at, 2) as u16),
        }
    }
}

/// One drive's outputs into its bytes as `l` lays them out (digital outputs 0;
/// the wired lines are set after).
pub fn write_outputs(b: &mut [u8], l: &Layout, controlword: u16, target: i32) {
    let mut put = |at: usize, v: &[u8]| {
        if let Some(dst) = b.get_mut(at..at + v.len()) {
            dst.copy_from_slice(v);
        }
    };
    put(l.controlword, &controlword.to_le_bytes());
    put(l.target, &target.to_le_bytes());
    if let Some(at) = l.mode {
        put(at, &[MODE_CSP as u8]);
    }
    if let Some(at) = l.digital_outputs {
        put(at, &0u32.to_le_bytes());
    }
}

/// 0x60C2's (value, index) for `cycle_ns`: value·10^index s, the coarsest exact one.
pub fn interpolation_period(cycle_ns: u64) -> Option<(u8, i8)> {
    [
        (-3i8, 1_000_000u64),
        (-4, 100_000),
        (-5, 10_000),
        (-6, 1_000),
        (-7, 100),
        (-8, 10),
        (-9, 1),
    ]
    .into_iter()
    .find_map(|(index, unit)| {
        (cycle_ns.is_multiple_of(unit) && cycle_ns / unit <= u64::from(u8::MAX) && cycle_ns > 0)
            .then(|| ((cycle_ns / unit) as u8, index))
    })
}
