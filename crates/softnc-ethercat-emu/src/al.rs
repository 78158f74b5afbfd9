//! The AL state machine (ETG.1000.6 §6.4): INIT → PRE-OP → SAFE-OP → OP, the error
//! indication and its acknowledge, and the AL status codes (ETG.1000.6 Table 11).

/// AL states as the low nibble of AL control/status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum AlState {
    /// INIT.
    Init = 1,
    /// PRE-OP.
    PreOp = 2,
    /// BOOTSTRAP.
    Boot = 3,
    /// SAFE-OP.
    SafeOp = 4,
    /// OP.
    Op = 8,
}

impl AlState {
    /// From the low nibble of AL control.
    pub fn from_nibble(n: u8) -> Option<Self> {
        Some(match n {
            1 => AlState::Init,
            2 => AlState::PreOp,
            3 => AlState::Boot,
            4 => AlState::SafeOp,
            8 => AlState::Op,
            _ => return None,
        })
    }
}

/// AL control/status bit: error indicator / acknowledge.
pub const ERROR_BIT: u8 = 0x10;

/// AL status codes used.
pub mod code {
    /// No error.
    pub const NONE: u16 = 0x0000;
    /// Unspecified error.
    pub const UNSPECIFIED: u16 = 0x0001;
    /// Invalid requested state change.
    pub const INVALID_STATE_CHANGE: u16 = 0x0011;
    /// Unknown requested state.
    pub const UNKNOWN_STATE: u16 = 0x0012;
    /// Bootstrap not supported.
    pub const NO_BOOTSTRAP: u16 = 0x0013;
    /// Invalid mailbox configuration (PRE-OP).
    pub const INVALID_MAILBOX: u16 = 0x0016;
    /// Sync manager watchdog.
    pub const SM_WATCHDOG: u16 = 0x001B;
    /// Invalid output configuration.
    pub const INVALID_OUTPUTS: u16 = 0x001D;
    /// Invalid input configuration.
    pub const INVALID_INPUTS: u16 = 0x001E;
}

/// Whether `from` → `to` is a transition the state machine has (ETG.1000.6 Figure
/// 17): up one step at a time, down to any lower state.
pub fn allowed(from: AlState, to: AlState) -> Result<(), u16> {
    use AlState::*;
    match (from, to) {
        (_, Boot) => Err(code::NO_BOOTSTRAP),
        (a, b) if b <= a => Ok(()),
        (Init, PreOp) | (PreOp, SafeOp) | (SafeOp, Op) => Ok(()),
        _ => Err(code::INVALID_STATE_CHANGE),
    }
}
