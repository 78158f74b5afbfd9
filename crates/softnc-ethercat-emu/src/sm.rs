//! Sync managers (0x0800 + 8·n): their configuration as written by the MainDevice
//! and the mailbox-full bit of their status byte.

use crate::regs::SM_BASE;

/// Status bit: mailbox full.
pub const STATUS_MAILBOX_FULL: u8 = 0x08;
/// Control bits 0–1: operation mode; 0b10 = mailbox.
const MODE_MASK: u8 = 0x03;
const MODE_MAILBOX: u8 = 0x02;
/// Control bits 2–3: direction; 0b01 = written by the EtherCAT side.
const DIRECTION_MASK: u8 = 0x0C;
const DIRECTION_WRITE: u8 = 0x04;

/// One sync manager's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncManager {
    /// Physical start address.
    pub start: u16,
    /// Length (bytes).
    pub len: u16,
    /// Control byte.
    pub control: u8,
    /// Activate bit 0: enabled.
    pub enabled: bool,
}

impl SyncManager {
    /// Decodes SM `n` from ESC memory.
    pub fn read(mem: &[u8], n: usize) -> Self {
        let at = usize::from(SM_BASE) + 8 * n;
        SyncManager {
            start: u16::from_le_bytes([mem[at], mem[at + 1]]),
            len: u16::from_le_bytes([mem[at + 2], mem[at + 3]]),
            control: mem[at + 4],
            enabled: mem[at + 6] & 0x01 != 0,
        }
    }
    /// Address of SM `n`'s status byte.
    pub fn status_addr(n: usize) -> usize {
        usize::from(SM_BASE) + 8 * n + 5
    }
    /// Mailbox mode.
    pub fn is_mailbox(&self) -> bool {
        self.control & MODE_MASK == MODE_MAILBOX
    }
    /// Written by the MainDevice.
    pub fn is_write(&self) -> bool {
        self.control & DIRECTION_MASK == DIRECTION_WRITE
    }
    /// The buffer's addresses.
    pub fn range(&self) -> std::ops::Range<usize> {
        usize::from(self.start)..usize::from(self.start) + usize::from(self.len)
    }
    /// Whether `a..b` touches the buffer.
    pub fn overlaps(&self, a: usize, b: usize) -> bool {
        self.enabled && self.len > 0 && a < self.range().end && b > self.range().start
    }
    /// Whether `a..b` covers the buffer's last byte (the access that completes it).
    pub fn covers_last(&self, a: usize, b: usize) -> bool {
        self.enabled && self.len > 0 && (a..b).contains(&(self.range().end - 1))
    }
    /// Whether this SM is configured as `spec` asks (start, length, direction, mode)
    /// and enabled.
    pub fn matches(&self, start: u16, len: u16, control: u8) -> bool {
        self.enabled
            && self.start == start
            && self.len == len
            && self.control & (MODE_MASK | DIRECTION_MASK) == control & (MODE_MASK | DIRECTION_MASK)
    }
}
