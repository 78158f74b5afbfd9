//! FMMUs (0x0600 + 16·n): logical-to-physical mappings for LRD/LWR/LRW. Byte
//! granularity (start bit 0, end bit 7), as every mapping of the emulated devices is.

use crate::regs::FMMU_BASE;

/// FMMU type bit: read (physical → logical).
const TYPE_READ: u8 = 0x01;
/// FMMU type bit: write (logical → physical).
const TYPE_WRITE: u8 = 0x02;

/// One FMMU's configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fmmu {
    /// Logical start address.
    pub logical: u32,
    /// Length (bytes).
    pub len: u16,
    /// Physical start address.
    pub physical: u16,
    /// Type bits.
    pub kind: u8,
    /// Activated.
    pub active: bool,
}

impl Fmmu {
    /// Decodes FMMU `n` from ESC memory.
    pub fn read(mem: &[u8], n: usize) -> Self {
        let at = usize::from(FMMU_BASE) + 16 * n;
        Fmmu {
            logical: u32::from_le_bytes([mem[at], mem[at + 1], mem[at + 2], mem[at + 3]]),
            len: u16::from_le_bytes([mem[at + 4], mem[at + 5]]),
            physical: u16::from_le_bytes([mem[at + 8], mem[at + 9]]),
            kind: mem[at + 11],
            active: mem[at + 12] & 0x01 != 0,
        }
    }
    /// Reads through this FMMU.
    pub fn reads(&self) -> bool {
        self.active && self.kind & TYPE_READ != 0
    }
    /// Writes through this FMMU.
    pub fn writes(&self) -> bool {
        self.active && self.kind & TYPE_WRITE != 0
    }
    /// Where a datagram at `logical` of `len` bytes overlaps this FMMU: (offset in
    /// the datagram, physical address, bytes).
    pub fn overlap(&self, logical: u32, len: usize) -> Option<(usize, usize, usize)> {
        let (a0, a1) = (u64::from(logical), u64::from(logical) + len as u64);
        let (f0, f1) = (
            u64::from(self.logical),
            u64::from(self.logical) + u64::from(self.len),
        );
        let (s, e) = (a0.max(f0), a1.min(f1));
        (s < e).then(|| {
            let in_dgram = (s - a0) as usize;
            let phys = usize::from(self.physical) + (s - f0) as usize;
            (in_dgram, phys, (e - s) as usize)
        })
    }
}
