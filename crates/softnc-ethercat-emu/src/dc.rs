//! Distributed clocks (ETG.1000.4 §9; ESC datasheet section I, chapter 9): each
//! emulated ESC's local clock, the receive-time latch, the system time offset and
//! delay, the system time difference of a compare, and SYNC0 events counted from the
//! start time and cycle.
//!
//! Every emulated clock runs from the host's monotonic clock plus a start-up
//! offset of its own, so there is no drift to control; the propagation delay
//! between neighbours is a fixed [`HOP_NS`].

use std::time::Instant;

/// Forwarding plus cable delay from one ESC's port 0 to the next one's (ns).
pub const HOP_NS: u64 = 500;
/// Delay of the loop closed at the last ESC's port 1 (ns).
pub const LOOP_NS: u64 = 200;
/// Spacing of the emulated ESCs' power-on times (ns): each local clock starts
/// elsewhere, as real ones do.
const BOOT_SPREAD_NS: u64 = 1_234_567_891;

/// The clock the emulator's ESCs share.
#[derive(Debug, Clone, Copy)]
pub struct HostClock(Instant);

impl HostClock {
    /// Starts now.
    pub fn new() -> Self {
        HostClock(Instant::now())
    }
    /// Nanoseconds since start.
    pub fn now_ns(&self) -> u64 {
        self.0.elapsed().as_nanos() as u64
    }
}

impl Default for HostClock {
    fn default() -> Self {
        Self::new()
    }
}

/// Local time (ns) of the ESC at `position` when a frame that reached the first
/// ESC at host time `t_ns` reaches its port 0.
pub fn local_time_port0(position: usize, t_ns: u64) -> u64 {
    boot(position) + t_ns + position as u64 * HOP_NS
}

/// Local time when the same frame returns to its port 1 (not the last ESC).
pub fn local_time_port1(position: usize, count: usize, t_ns: u64) -> u64 {
    let last = count as u64 - 1;
    boot(position) + t_ns + last * HOP_NS + LOOP_NS + (last - position as u64) * HOP_NS
}

fn boot(position: usize) -> u64 {
    (position as u64 + 1) * BOOT_SPREAD_NS
}

/// System time difference register value: |diff| with bit 31 set when the local
/// copy is smaller than the received time.
pub fn difference_register(local_ns: u64, received_ns: u64) -> u32 {
    let diff = local_ns as i64 - received_ns as i64;
    let mag = (diff.unsigned_abs() as u32) & 0x7FFF_FFFF;
    if diff < 0 {
        mag | 0x8000_0000
    } else {
        mag
    }
}

/// SYNC0 events since `start_ns` at `cycle_ns`, at system time `now_ns`.
pub fn sync0_events(start_ns: u64, cycle_ns: u32, now_ns: u64) -> u64 {
    if cycle_ns == 0 || now_ns < start_ns {
        return 0;
    }
    (now_ns - start_ns) / u64::from(cycle_ns) + 1
}
