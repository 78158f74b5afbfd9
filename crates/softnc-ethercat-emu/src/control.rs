//! Faults and inputs on demand: the commands a test (or the binary's standard
//! input) gives the emulator.

use std::str::FromStr;

/// A command to the running emulator.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// The cable is cut: no frame comes back.
    LinkDown,
    /// The cable is back.
    LinkUp,
    /// The next `n` frames are lost.
    Drop(u32),
    /// The drive at `position` faults with error code `code` (0x603F).
    DriveFault {
        /// SubDevice position (0 first).
        position: usize,
        /// Error code.
        code: u16,
    },
    /// The SubDevice at `position` leaves OP for SAFE-OP with an error (AL status
    /// code 0x001B, sync manager watchdog).
    LeaveOp {
        /// SubDevice position.
        position: usize,
    },
    /// The SubDevice at `position` exchanges the process data of the next
    /// `frames` frames without counting the working counter (the frame comes back
    /// whole, its working counter short by that SubDevice's share).
    SkipWorkingCounter {
        /// SubDevice position.
        position: usize,
        /// Frames.
        frames: u32,
    },
    /// A home switch on the axis of the drive at `position`: 0x60FD bit 2 set
    /// while its position is at or beyond `at_counts`.
    HomeSwitch {
        /// SubDevice position.
        position: usize,
        /// Where the switch starts (counts).
        at_counts: i32,
    },
    /// The digital inputs of the SubDevice at `position` (drive: 0x60FD; terminal:
    /// the input byte).
    Inputs {
        /// SubDevice position.
        position: usize,
        /// Bits.
        bits: u32,
    },
    /// The local clock of the SubDevice at `position` steps `ns` ahead, without
    /// re-synchronisation (its system time difference, 0x092C, shows the step).
    ClockStep {
        /// SubDevice position.
        position: usize,
        /// Step (ns; at most 0x7FFF_FFFF shows whole in 0x092C).
        ns: u32,
    },
}

/// A command line that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown command {0:?}: link-down | link-up | drop N | fault POS CODE | leave-op POS | wkc POS FRAMES | home-switch POS COUNTS | inputs POS BITS | clock-step POS NS")]
pub struct BadCommand(pub String);

fn num(s: Option<&str>) -> Option<u32> {
    let s = s?;
    match s.strip_prefix("0x") {
        Some(h) => u32::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

impl FromStr for Command {
    type Err = BadCommand;
    fn from_str(line: &str) -> Result<Self, BadCommand> {
        let mut w = line.split_whitespace();
        let bad = || BadCommand(line.to_string());
        let cmd = w.next().ok_or_else(bad)?;
        let (a, b) = (num(w.next()), num(w.next()));
        Ok(match (cmd, a, b) {
            ("link-down", None, None) => Command::LinkDown,
            ("link-up", None, None) => Command::LinkUp,
            ("drop", Some(n), None) => Command::Drop(n),
            ("fault", Some(p), Some(c)) => Command::DriveFault {
                position: p as usize,
                code: c as u16,
            },
            ("leave-op", Some(p), None) => Command::LeaveOp {
                position: p as usize,
            },
            ("wkc", Some(p), Some(frames)) => Command::SkipWorkingCounter {
                position: p as usize,
                frames,
            },
            ("home-switch", Some(p), Some(at)) => Command::HomeSwitch {
                position: p as usize,
                at_counts: at as i32,
            },
            ("inputs", Some(p), Some(bits)) => Command::Inputs {
                position: p as usize,
                bits,
            },
            ("clock-step", Some(p), Some(ns)) => Command::ClockStep {
                position: p as usize,
                ns,
            },
            _ => return Err(bad()),
        })
    }
}
