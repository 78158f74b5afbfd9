//! A backend without dynamics: every axis follows its command exactly, in one cycle.
//! For dry runs of programs and for testing everything above the servo boundary
//! (`backend: Loopback` in the daemon's configuration; `softnc demo --backend
//! loopback`). It passes the same [`conformance`](crate::conformance) suite as the
//! simulated machine.
//!
//! Its I/O echoes its outputs to its inputs at every exchange: digital output line
//! k is digital input line k, analog likewise, and the spindle turns at its command
//! at once (speed feedback = the signed command; it reports no position and no
//! index pulses).

use crate::backend::{AxisStatus, BackendError, CommandMode, ServoBackend, MAX_AXES};
use crate::io::{IoLines, RawInputs, RawOutputs, SpindleFeedback};
use softnc_core::Axes;

/// Resolution the loopback reports (mm per count): fine enough that its counts are
/// the command to floating-point precision over any travel.
pub const LOOPBACK_MM_PER_COUNT: f64 = 1e-9;

/// Axes that take a position command and are there at the next cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct LoopbackBackend {
    cmd_mm: Axes<f64>,
    counts: Axes<i64>,
    status: Axes<AxisStatus>,
    io_out: RawOutputs,
    io_in: RawInputs,
}

impl Default for LoopbackBackend {
    fn default() -> Self {
        Self::new()
    }
}

impl LoopbackBackend {
    /// Axes at 0, enabled.
    pub fn new() -> Self {
        LoopbackBackend {
            cmd_mm: Axes::splat(0.0),
            counts: Axes::splat(0),
            status: Axes::splat(AxisStatus {
                enabled: true,
                ..AxisStatus::default()
            }),
            io_out: RawOutputs::default(),
            io_in: RawInputs::default(),
        }
    }

    /// The outputs come back as inputs.
    fn echo(&mut self) {
        self.io_in = RawInputs {
            digital: self.io_out.digital,
            analog: self.io_out.analog,
            spindle: SpindleFeedback {
                rpm: self.io_out.spindle.signed_rpm(),
                revs: 0.0,
                index_count: 0,
                // (an orient command is echoed as done)
                oriented: self.io_out.spindle.orient_deg.is_some(),
            },
        };
    }

    fn count_of(pos_mm: f64) -> i64 {
        (pos_mm / LOOPBACK_MM_PER_COUNT).round() as i64
    }
}

impl ServoBackend for LoopbackBackend {
    fn axes(&self) -> usize {
        MAX_AXES
    }
    fn command_mode(&self, _axis: usize) -> CommandMode {
        CommandMode::Position
    }
    fn mm_per_count(&self, _axis: usize) -> f64 {
        LOOPBACK_MM_PER_COUNT
    }
    fn enable(&mut self) -> Result<(), BackendError> {
        for s in &mut self.status {
            s.enabled = true;
        }
        Ok(())
    }
    fn disable(&mut self) {
        for (i, s) in self.status.iter_mut().enumerate() {
            s.enabled = false;
            // held where it is
            self.cmd_mm[i] = self.counts[i] as f64 * LOOPBACK_MM_PER_COUNT;
        }
    }
    fn home(&mut self, pos_mm: Axes<f64>) {
        self.cmd_mm = pos_mm;
        self.counts = pos_mm.map(Self::count_of);
    }
    fn write_commands(&mut self, cmd: Axes<f64>) {
        for ((c, s), new) in self.cmd_mm.iter_mut().zip(&self.status).zip(cmd) {
            if s.enabled && new.is_finite() {
                *c = new;
            }
        }
    }
    fn cycle(&mut self) -> Result<(), BackendError> {
        self.counts = self.cmd_mm.map(Self::count_of);
        self.echo();
        Ok(())
    }
    fn io_lines(&self) -> IoLines {
        IoLines::ALL
    }
    fn write_io(&mut self, out: &RawOutputs) {
        self.io_out = *out;
    }
    fn exchange_io(&mut self) -> Result<(), BackendError> {
        self.echo();
        Ok(())
    }
    fn read_io(&self) -> RawInputs {
        self.io_in
    }
    fn read_counts(&self) -> Axes<i64> {
        self.counts
    }
    fn read_currents(&self) -> Axes<f64> {
        Axes::splat(0.0)
    }
    fn read_status(&self) -> Axes<AxisStatus> {
        self.status
    }
}
