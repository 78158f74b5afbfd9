//! CiA 402 on the process image: the PDO mapping the backend writes by SDO, the
//! controlword commands and the statusword's states (IEC 61800-7-201 §6.2; the
//! `ds402` module of ethercrab is not in its 0.7 release, so this is our own).

/// RxPDO 0x1600: controlword, target position, modes of operation, digital outputs.
pub const RX_MAPPING: [u32; 4] = [0x6040_0010, 0x607A_0020, 0x6060_0008, 0x60FE_0120];
/// TxPDO 0x1A00: statusword, position actual, following error actual, digital
/// inputs, error code.
pub const TX_MAPPING: [u32; 5] = [
    0x6041_0010,
    0x6064_0020,
    0x60F4_0020,
    0x60FD_0020,
    0x603F_0010,
];
/// Output bytes of [`RX_MAPPING`] and input bytes of [`TX_MAPPING`].
pub const RX_BYTES: usize = 11;
/// Input bytes.
pub const TX_BYTES: usize = 16;
/// Where 0x60FD starts in the input bytes of [`TX_MAPPING`].
pub const TX_DIGITAL_INPUTS_AT: usize = 10;
/// Where 0x60FE:01 starts in the output bytes of [`RX_MAPPING`].
pub const RX_DIGITAL_OUTPUTS_AT: usize = 7;
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
    /// From the drive's input bytes (as [`TX_MAPPING`] lays them out).
    pub fn parse(b: &[u8]) -> Self {
        let u16_at = |i: usize| u16::from_le_bytes([b[i], b[i + 1]]);
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        Inputs {
            statusword: u16_at(0),
            position: u32_at(2) as i32,
            following_error: u32_at(6) as i32,
            digital_inputs: u32_at(10),
            error_code: u16_at(14),
        }
    }
}

/// One drive's outputs into its bytes (as [`RX_MAPPING`] lays them out).
pub fn write_outputs(b: &mut [u8], controlword: u16, target: i32, digital_outputs: u32) {
    b[0..2].copy_from_slice(&controlword.to_le_bytes());
    b[2..6].copy_from_slice(&target.to_le_bytes());
    b[6] = MODE_CSP as u8;
    b[7..11].copy_from_slice(&digital_outputs.to_le_bytes());
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
