//! The machine around the axes as the processes exchange it: what the program asks
//! of the spindle, the coolant and the outputs ([`MachineOutputs`], carried on every
//! command sample so that a synchronised output switches at the sample where the next
//! motion starts), and what the machine reports back ([`MachineInputs`], in every
//! position status). Both are fixed-size and `Copy`: they travel on the cycle paths.
//!
//! Signals here are *logical* (M62 P3 is digital output 3, M66 E1 analog input 1):
//! which line of which backend each one is, and its polarity and debounce, is the I/O
//! map's business at the servo boundary.

/// Digital outputs of M62–M65 (`P0` … `P63`) and inputs of M66 (`P`): bits of a `u64`.
pub const DIGITAL_LINES: usize = 64;
/// Analog outputs of M67/M68 (`E0` … `E7`) and analog inputs of M66 (`E`).
pub const ANALOG_LINES: usize = 8;

/// The spindle's direction as commanded (M3, M4, M5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SpindleDir {
    /// M5 (or never started).
    #[default]
    Stopped,
    /// M3: clockwise.
    Clockwise,
    /// M4: counter-clockwise.
    CounterClockwise,
}

/// What the machine around the axes is told to do while one command sample runs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MachineOutputs {
    /// Spindle direction (M3/M4/M5).
    pub spindle_dir: SpindleDir,
    /// Programmed spindle speed (rpm, ≥ 0, before the spindle override): the S word
    /// in force.
    pub spindle_rpm: f64,
    /// M19: orient the spindle to this angle (degrees, from its encoder's index);
    /// `None` while not orienting.
    pub spindle_orient_deg: Option<f64>,
    /// M19 P: the way it turns to the angle — 0 the shorter way, 1 clockwise, 2
    /// counter-clockwise (LinuxCNC's `spindle.N.orient-mode`).
    pub spindle_orient_dir: u8,
    /// M7: mist coolant on.
    pub coolant_mist: bool,
    /// M8: flood coolant on.
    pub coolant_flood: bool,
    /// M6 asks the tool changer for a tool (LinuxCNC's `iocontrol.0.tool-change`).
    pub tool_change: bool,
    /// M62–M65: digital output `P` is bit `P`.
    pub digital: u64,
    /// M67/M68: analog output `E` (the value as programmed).
    pub analog: [f64; ANALOG_LINES],
}

impl MachineOutputs {
    /// The spindle's signed speed command (rpm): + clockwise, − counter-clockwise,
    /// 0 stopped; before the spindle override.
    pub fn spindle_signed_rpm(&self) -> f64 {
        match self.spindle_dir {
            SpindleDir::Stopped => 0.0,
            SpindleDir::Clockwise => self.spindle_rpm,
            SpindleDir::CounterClockwise => -self.spindle_rpm,
        }
    }

    /// The outputs' safe state (E-stop, machine off): spindle stopped, coolant off,
    /// every digital output off, every analog output 0.
    pub fn safe() -> Self {
        Self::default()
    }

    /// The outputs after an abort, as LinuxCNC's task abort leaves them
    /// (`emcSpindleAbort` and `emcIoAbort` in `emctaskmain.cc`, `taskclass.cc`):
    /// the spindle stopped (no orient), coolant off, no tool change asked; the
    /// digital (M62–M65) and analog (M67/M68) outputs as they were — they may
    /// hold a clamp or a door, which an abort must not let go.
    pub fn after_abort(self) -> Self {
        MachineOutputs {
            spindle_dir: SpindleDir::Stopped,
            spindle_orient_deg: None,
            coolant_mist: false,
            coolant_flood: false,
            tool_change: false,
            ..self
        }
    }

    /// The outputs a new job (or MDI command) starts from when the machine holds
    /// `self` from the last one: the same, without a tool-change request (a job
    /// asks for its own).
    pub fn held_for_next_job(self) -> Self {
        MachineOutputs {
            tool_change: false,
            ..self
        }
    }
}

/// What the machine around the axes reports while one cycle runs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MachineInputs {
    /// Spindle speed from its encoder (rpm, signed: + clockwise).
    pub spindle_rpm: f64,
    /// Spindle position from its encoder (revolutions since the machine started).
    pub spindle_revs: f64,
    /// Index pulses the spindle encoder has seen since the machine started.
    pub spindle_index_count: u64,
    /// The spindle turns at its commanded speed (× override) within the profile's
    /// band (LinuxCNC's `spindle.at-speed`); true while it is commanded to stand and
    /// stands.
    pub spindle_at_speed: bool,
    /// The spindle stands at the angle M19 asked for, within the profile's band
    /// (LinuxCNC's `spindle.N.is-oriented`); false while not orienting.
    pub spindle_oriented: bool,
    /// The external E-stop chain is open (latched by the position process until
    /// reset).
    pub estop_open: bool,
    /// The probe input is tripped.
    pub probe: bool,
    /// The tool changer reports the change done (LinuxCNC's
    /// `iocontrol.0.tool-changed`).
    pub tool_changed: bool,
    /// Bit `a`: axis `a`'s minimum-end limit switch is tripped.
    pub limit_min: u32,
    /// Bit `a`: axis `a`'s maximum-end limit switch is tripped.
    pub limit_max: u32,
    /// Bit `a`: axis `a`'s home switch is tripped.
    pub home: u32,
    /// M66 `P`: digital input `P` is bit `P`.
    pub digital: u64,
    /// M66 `E`: analog input `E`.
    pub analog: [f64; ANALOG_LINES],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_signed_speed_follows_the_direction() {
        let mut o = MachineOutputs {
            spindle_rpm: 8000.0,
            ..MachineOutputs::default()
        };
        assert_eq!(o.spindle_signed_rpm(), 0.0);
        o.spindle_dir = SpindleDir::Clockwise;
        assert_eq!(o.spindle_signed_rpm(), 8000.0);
        o.spindle_dir = SpindleDir::CounterClockwise;
        assert_eq!(o.spindle_signed_rpm(), -8000.0);
        assert_eq!(MachineOutputs::safe().spindle_signed_rpm(), 0.0);
    }

    #[test]
    fn an_abort_stops_the_spindle_and_coolant_and_keeps_the_outputs() {
        let mut analog = [0.0; ANALOG_LINES];
        analog[2] = 4.5;
        let running = MachineOutputs {
            spindle_dir: SpindleDir::CounterClockwise,
            spindle_rpm: 5000.0,
            coolant_mist: true,
            coolant_flood: true,
            tool_change: true,
            digital: 0b1010,
            analog,
            ..MachineOutputs::default()
        };
        let a = running.after_abort();
        assert_eq!(a.spindle_signed_rpm(), 0.0);
        assert!(!a.coolant_mist && !a.coolant_flood && !a.tool_change);
        assert_eq!((a.digital, a.analog), (0b1010, analog));
        let oriented = MachineOutputs {
            spindle_orient_deg: Some(90.0),
            ..MachineOutputs::default()
        };
        assert_eq!(oriented.after_abort().spindle_orient_deg, None);
        // the next job starts from them, without the tool change
        let held = running.held_for_next_job();
        assert!(!held.tool_change && held.coolant_flood);
        assert_eq!(held.spindle_signed_rpm(), -5000.0);
    }
}
