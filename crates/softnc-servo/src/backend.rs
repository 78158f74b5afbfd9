//! The servo boundary: what every drive implements — enable and disable, write
//! commands, exchange once per cycle, read encoder counts, currents and status.
//!
//! The cycle is `write_commands` → `cycle` → `read_*`, the order of a fieldbus's
//! process-data exchange. An EtherCAT CiA 402 drive in cyclic synchronous position
//! mode maps onto it directly (see docs/architecture.md, "A real drive").

use crate::io::{IoLines, RawInputs, RawOutputs};
use softnc_core::Axes;

/// Axes a backend serves at most: the stack's one axis count.
pub use softnc_core::MAX_AXES;

/// What the drive's command means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandMode {
    /// Position command (mm): the drive closes the position loop (paper 004; CiA 402
    /// cyclic synchronous position, CSP).
    Position,
    /// Velocity command (rad/s) to a velocity loop (paper 000; CiA 402 CSV).
    Velocity,
    /// Effort: a DAC count to a power amplifier (paper 001; CiA 402 CST).
    Effort,
}

/// Status of one drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AxisStatus {
    /// Enabled and following commands (CiA 402 "operation enabled").
    pub enabled: bool,
    /// The drive reports a fault.
    pub fault: bool,
    /// The command was clipped by the drive's input range (DAC saturation).
    pub saturated: bool,
}

/// Why a backend cycle failed. Small and `Copy`: it can happen on the cycle path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BackendError {
    /// A drive reported a fault.
    #[error("drive fault on axis {axis}")]
    DriveFault {
        /// Axis index.
        axis: u8,
    },
    /// The drives did not answer within the cycle.
    #[error("no answer from the drives within the cycle")]
    Timeout,
    /// A drive did not reach "enabled" when asked.
    #[error("axis {axis} could not be enabled")]
    NotEnabled {
        /// Axis index.
        axis: u8,
    },
    /// The fieldbus failed (EtherCAT): where — the SubDevice's position on the bus
    /// and the axis it drives, where known — and why.
    #[error("bus fault{}: {reason}", BusPlace(*subdevice, *axis))]
    Bus {
        /// Position of the SubDevice on the bus (0 first), where one is to blame.
        subdevice: Option<u16>,
        /// The axis that SubDevice drives, where it drives one.
        axis: Option<u8>,
        /// What went wrong.
        reason: BusFault,
    },
}

/// " at SubDevice 1 (axis 1)", or what of it is known (formatted without
/// allocating: a bus fault's alarm is written on the cycle).
struct BusPlace(Option<u16>, Option<u8>);

impl std::fmt::Display for BusPlace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(p) = self.0 {
            write!(f, " at SubDevice {p}")?;
        }
        if let Some(a) = self.1 {
            write!(f, " (axis {a})")?;
        }
        Ok(())
    }
}

/// Why a fieldbus cycle failed ([`BackendError::Bus`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum BusFault {
    /// The bus has not been brought up (the first `enable` or `disable` does; a
    /// bring-up that failed leaves it down).
    #[error("bus not brought up")]
    NotOpen,
    /// No frame came back within the bounded wait (a lost frame; a link down looks
    /// the same from the MainDevice).
    #[error("frame lost: no answer within the cycle, all SubDevices ({subdevices}) affected (a lost frame, or the link down on {iface})")]
    FrameLost {
        /// The bus's network interface.
        iface: IfName,
        /// The SubDevices the frame was for (every one: none answered).
        subdevices: Positions,
    },
    /// The cycle's working counter was short of what the mapped SubDevices give.
    #[error("working counter {got}, expected {expected}: {} did not exchange its process data", OneOf(*suspects))]
    WorkingCounter {
        /// Counted.
        got: u16,
        /// Expected.
        expected: u16,
        /// The SubDevices whose share of the working counter is the shortfall
        /// (one of them did not count; the frame does not say which).
        suspects: Positions,
    },
    /// A SubDevice is no longer in OP (its AL state, as the low nibble of AL status).
    #[error("left OP (AL state {al_state:#x})")]
    LeftOp {
        /// AL state reported.
        al_state: u8,
    },
    /// The drive reports a fault with this error code (CiA 402 0x603F).
    #[error("drive fault, error code {error_code:#06x}")]
    DriveFault {
        /// 0x603F.
        error_code: u16,
    },
}

/// Bus positions (bit p: the SubDevice at position p, p < 32), printed "0–3, 5"
/// (formatted without allocating, as an alarm on the cycle is).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Positions(pub u32);

impl std::fmt::Display for Positions {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mut sep = "";
        let mut p = 0;
        while p < 32 {
            if self.0 >> p & 1 == 0 {
                p += 1;
                continue;
            }
            let mut end = p;
            while end + 1 < 32 && self.0 >> (end + 1) & 1 == 1 {
                end += 1;
            }
            match end - p {
                0 => write!(f, "{sep}{p}")?,
                1 => write!(f, "{sep}{p}, {end}")?,
                _ => write!(f, "{sep}{p}–{end}")?,
            }
            sep = ", ";
            p = end + 1;
        }
        Ok(())
    }
}

/// "SubDevice 2", or "one of SubDevices 0–3".
struct OneOf(Positions);

impl std::fmt::Display for OneOf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0 .0.count_ones() == 1 {
            write!(f, "SubDevice {}", self.0)
        } else {
            write!(f, "one of SubDevices {}", self.0)
        }
    }
}

/// A network interface's name, fixed-size (Linux allows 15 bytes), so that a bus
/// fault naming it stays `Copy` and allocation-free.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IfName([u8; 16]);

impl IfName {
    /// `name`, cut at 16 bytes.
    pub fn new(name: &str) -> Self {
        let mut b = [0u8; 16];
        let n = name.len().min(16);
        b[..n].copy_from_slice(&name.as_bytes()[..n]);
        IfName(b)
    }
}

impl std::fmt::Display for IfName {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let n = self.0.iter().position(|&c| c == 0).unwrap_or(16);
        f.write_str(std::str::from_utf8(&self.0[..n]).unwrap_or("?"))
    }
}

/// A fieldbus's figures since it was brought up ([`ServoBackend::bus_stats`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BusStats {
    /// Cycles exchanged.
    pub frames: u64,
    /// Frames lost (no answer within the response timeout).
    pub lost_frames: u64,
    /// Cycles with a wrong working counter.
    pub wkc_errors: u64,
    /// Send-to-receive time of the cycle's frame: median (ns; the histogram's
    /// bucket is 10 µs).
    pub rtt_p50_ns: u64,
    /// 99th percentile.
    pub rtt_p99_ns: u64,
    /// Maximum (exact).
    pub rtt_max_ns: u64,
    /// Reads of the DC SubDevices' system time difference (0x092C) that answered.
    pub dc_reads: u64,
    /// |system time difference| of the last read (ns).
    pub dc_deviation_last_ns: u64,
    /// Largest |system time difference| read since open (ns).
    pub dc_deviation_max_ns: u64,
}

/// A servo backend: the simulated machine, a loopback, real drives. One cycle is
/// `write_commands` → `cycle` → `read_*`; nothing in a cycle allocates or blocks
/// beyond the exchange itself.
pub trait ServoBackend {
    /// Number of axes served (≤ [`MAX_AXES`]).
    fn axes(&self) -> usize;
    /// What axis `axis`'s command means.
    fn command_mode(&self, axis: usize) -> CommandMode;
    /// Encoder resolution of axis `axis` (mm per count).
    fn mm_per_count(&self, axis: usize) -> f64;
    /// Power the drives and make them follow commands (CiA 402: shutdown → switch
    /// on → enable operation). Off the cycle path; may take a while on real drives.
    fn enable(&mut self) -> Result<(), BackendError>;
    /// Stop following commands: the drives hold or brake by themselves (CiA 402:
    /// quick stop, then disable voltage). Commands written while disabled are
    /// ignored.
    fn disable(&mut self);
    /// Why the last [`enable`](Self::enable) could not bring the drives up, in
    /// the backend's own words (the bus's interface and the error), where it knows
    /// more than its [`BackendError`] says.
    fn enable_failure(&self) -> Option<String> {
        None
    }
    /// The E-stop path, on the cycle (nothing blocks, nothing allocates): every
    /// drive told to stop now by itself (CiA 402 quick stop at the next
    /// exchange), commands ignored until [`enable`](Self::enable). Nothing by
    /// default: a simulated machine or a loopback that is not stepped stands.
    fn estop(&mut self) {}
    /// After a fault whose cause is gone (the operator's reset), off the cycle
    /// path: the backend made whole again (a fieldbus's SubDevices back in OP),
    /// the drives left off for the next [`enable`](Self::enable). An error when
    /// the cause is still there. Nothing to do by default.
    fn recover(&mut self) -> Result<(), BackendError> {
        Ok(())
    }
    /// The fieldbus's figures, for a backend on one.
    fn bus_stats(&self) -> Option<BusStats> {
        None
    }
    /// Declare the current actual position to be `pos_mm` (homing; the simulation
    /// places its axes there at rest).
    fn home(&mut self, pos_mm: Axes<f64>);
    /// This cycle's command per axis, in the units of its [`CommandMode`].
    fn write_commands(&mut self, cmd: Axes<f64>);
    /// Exchange with the drives: the machine moves for one cycle.
    fn cycle(&mut self) -> Result<(), BackendError>;
    /// Actual positions, encoder counts.
    fn read_counts(&self) -> Axes<i64>;
    /// Motor currents (or their model equivalents).
    fn read_currents(&self) -> Axes<f64>;
    /// Drive status.
    fn read_status(&self) -> Axes<AxisStatus>;
    /// The spindle now turns at `rpm` (an S word took effect); backends whose
    /// machine has no spindle ignore it.
    fn set_spindle_rpm(&mut self, _rpm: f64) {}
    /// Axis `axis`'s motor phase currents and electrical angle this cycle (paper
    /// 003's force estimate reads them); `None` when the drive does not report them.
    /// A CiA 402 drive maps its current feedback here (a vendor PDO with i_u, i_v
    /// and the commutation angle; where a drive reports only the torque-producing
    /// current 0x6078, the estimate would take I_q directly).
    fn read_phase_currents(&self, _axis: usize) -> Option<PhaseCurrents> {
        None
    }
    /// What this backend has of the I/O boundary ([`crate::io`]): raw lines and a
    /// spindle. None by default: a backend without I/O has no lines.
    fn io_lines(&self) -> IoLines {
        IoLines::NONE
    }
    /// The raw outputs for the next exchange (written before [`cycle`](Self::cycle)
    /// or [`exchange_io`](Self::exchange_io); kept until written again).
    fn write_io(&mut self, _out: &RawOutputs) {}
    /// Exchange the I/O alone, on a cycle that does not step the axes (drives off,
    /// E-stop): the outputs written go out, the inputs come in, the spindle and
    /// whatever else the backend models move one cycle. [`cycle`](Self::cycle)
    /// exchanges the I/O with the axes.
    fn exchange_io(&mut self) -> Result<(), BackendError> {
        Ok(())
    }
    /// The raw inputs of the last exchange.
    fn read_io(&self) -> RawInputs {
        RawInputs::default()
    }
    /// A backend that is not [kept across jobs](Self::kept_across_jobs) takes over
    /// from `running` what the world outside set on its lines (a simulated
    /// machine: the E-stop chain, the inputs a test set), when the next job's
    /// fresh one replaces it. Nothing by default.
    fn take_external_io(&mut self, _running: &Self)
    where
        Self: Sized,
    {
    }
    /// The simulation-only inputs, when this backend is a simulated machine.
    fn simulated(&mut self) -> Option<&mut dyn SimulatedMachine> {
        None
    }
    /// Whether this backend is opened once and handed from job to job (true, a
    /// drive: enabled, homed and standing where it is, the next job's engine takes
    /// it over without enabling or homing it again,
    /// [`CycleEngine::take_over`](crate::CycleEngine::take_over)), or replaced by
    /// the next job's fresh one homed at the job's start (false: the simulated
    /// machine, so that a daemon's job runs on the machine `softnc sim` builds and
    /// their traces are equal bit for bit).
    fn kept_across_jobs(&self) -> bool {
        true
    }
}

/// A motor's measured phase currents and electrical angle (paper 003 eq 24–28).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhaseCurrents {
    /// Measured phase current i_u (A).
    pub i_u_a: f64,
    /// Measured phase current i_v (A).
    pub i_v_a: f64,
    /// Electrical angle n_p·θ (rad).
    pub theta_e_rad: f64,
}

/// Inputs and readings only a simulated machine has (a real drive has no use for
/// them): reached through [`ServoBackend::simulated`].
pub trait SimulatedMachine {
    /// Whether the tool is in the material (switches the periodic cutting
    /// disturbance during feed moves).
    fn set_cutting(&mut self, cutting: bool);
    /// Axis `axis` is held by static friction.
    fn stuck(&self, axis: usize) -> bool;
    /// Open (true) or close the external E-stop chain.
    fn set_estop_open(&mut self, open: bool);
    /// Set raw digital input line `line` (its level: the polarity is the map's).
    /// Held high, a line the machine drives itself (a switch, the tool changer)
    /// reads high whatever its own contact says (a hand on the switch); let low,
    /// the machine's contact decides again.
    fn set_digital_input(&mut self, line: usize, high: bool);
    /// Set raw analog input line `line`.
    fn set_analog_input(&mut self, line: usize, value: f64);
    /// Drive the probe input (`Some`), or leave it to the probe plane (`None`).
    fn set_probe(&mut self, tripped: Option<bool>);
    /// The raw outputs as last written (coolant, tool-change, the M62 lines, …).
    fn raw_outputs(&self) -> RawOutputs;
    /// The spindle's true speed (rpm, signed), 0 without a spindle.
    fn spindle_true_rpm(&self) -> f64;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bus_fault_names_its_subdevices_and_interface() {
        assert_eq!(Positions(0b1111).to_string(), "0–3");
        assert_eq!(Positions(0b1011).to_string(), "0, 1, 3");
        assert_eq!(Positions(0b11_0110_0001).to_string(), "0, 5, 6, 8, 9");
        let lost = BackendError::Bus {
            subdevice: None,
            axis: None,
            reason: BusFault::FrameLost {
                iface: IfName::new("enp2s0"),
                subdevices: Positions(0b111),
            },
        };
        assert_eq!(
            lost.to_string(),
            "bus fault: frame lost: no answer within the cycle, all SubDevices (0–2) affected (a lost frame, or the link down on enp2s0)"
        );
        let wkc = |suspects| BusFault::WorkingCounter {
            got: 4,
            expected: 7,
            suspects: Positions(suspects),
        };
        assert!(wkc(0b110)
            .to_string()
            .ends_with(": one of SubDevices 1, 2 did not exchange its process data"));
        assert!(wkc(0b100)
            .to_string()
            .ends_with(": SubDevice 2 did not exchange its process data"));
        assert_eq!(
            IfName::new("a-very-long-interface-name").to_string(),
            "a-very-long-inte"
        );
    }
}
