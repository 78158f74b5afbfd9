//! The I/O map of a machine profile (`servo.io`): which raw line of the backend
//! each named signal of the machine around the axes is (`softnc_core::machine_io`),
//! its polarity and (inputs) its debounce; the at-speed band of the spindle; and
//! the simulated machine's own I/O figures (`servo.sim_io`). The servo boundary's
//! `softnc_servo::io::MachineIo` applies it on the position cycle.

use serde::{Deserialize, Serialize};
use softnc_core::config::ConfigError;
use softnc_core::machine_io::{ANALOG_LINES, DIGITAL_LINES};

/// Raw digital lines a backend may have per direction (bits of a `u128`).
pub const RAW_DIGITAL_LINES: usize = 128;
/// Raw analog lines a backend may have per direction.
pub const RAW_ANALOG_LINES: usize = 16;

/// A named input signal.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum InputSignal {
    /// The external E-stop chain is open (asserted = open).
    EStop,
    /// The minimum-end limit switch of the axis named.
    LimitMin(String),
    /// The maximum-end limit switch of the axis named.
    LimitMax(String),
    /// The home switch of the axis named.
    Home(String),
    /// The probe is tripped.
    Probe,
    /// The tool changer reports the change done (LinuxCNC's
    /// `iocontrol.0.tool-changed`).
    ToolChanged,
    /// M66 digital input `P`.
    Input(u32),
}

/// A named output signal.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum OutputSignal {
    /// The spindle turns (M3 or M4).
    SpindleEnable,
    /// The spindle turns clockwise (M3).
    SpindleCw,
    /// The spindle turns counter-clockwise (M4).
    SpindleCcw,
    /// Mist coolant (M7).
    CoolantMist,
    /// Flood coolant (M8).
    CoolantFlood,
    /// Asks the tool changer for a tool (M6; LinuxCNC's `iocontrol.0.tool-change`).
    ToolChange,
    /// The machine is on (LinuxCNC's `halui.machine.is-on`).
    MachineOn,
    /// The amplifiers may be enabled (LinuxCNC's `joint.N.amp-enable-out`).
    AmpEnable,
    /// M62–M65 digital output `P`.
    Output(u32),
}

/// One digital input line.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputLine {
    /// The signal the line carries.
    pub signal: InputSignal,
    /// The backend's raw input line (0 … 127).
    pub line: u32,
    /// The signal is asserted when the line is low (a normally-closed contact).
    #[serde(default)]
    pub active_low: bool,
    /// Debounce (cycles of delay): the signal takes a new level once the line has
    /// read it on `debounce_cycles` + 1 cycles in a row (0: at once).
    #[serde(default)]
    pub debounce_cycles: u32,
}

/// One digital output line.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputLine {
    /// The signal the line carries.
    pub signal: OutputSignal,
    /// The backend's raw output line (0 … 127).
    pub line: u32,
    /// The line is driven low when the signal is asserted.
    #[serde(default)]
    pub active_low: bool,
}

/// One analog line: M66 `E` (inputs) or M67/M68 `E` (outputs) is raw line `line`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalogLine {
    /// The logical index E (0 … 7).
    pub e: u32,
    /// The backend's raw analog line (0 … 15).
    pub line: u32,
}

/// The I/O map (`servo.io`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IoConfig {
    /// Digital inputs.
    #[serde(default)]
    pub inputs: Vec<InputLine>,
    /// Digital outputs (a line carries one signal).
    #[serde(default)]
    pub outputs: Vec<OutputLine>,
    /// M66 `E` analog inputs.
    #[serde(default)]
    pub analog_inputs: Vec<AnalogLine>,
    /// M67/M68 `E` analog outputs (a line carries one).
    #[serde(default)]
    pub analog_outputs: Vec<AnalogLine>,
    /// The spindle is at speed when its actual speed is within this fraction of the
    /// commanded speed × spindle override (LinuxCNC's `near` component's `scale`
    /// − 1 on `spindle.at-speed`).
    pub at_speed_frac: f64,
    /// … or within this many rpm of it, whichever is wider (the band at low speed
    /// and at rest; `near`'s `difference`).
    pub at_speed_min_rpm: f64,
    /// Longest a job waits for the spindle to reach its speed after M3/M4/S (s);
    /// past it the job stops with a `MachineWait` alarm (LinuxCNC's
    /// `spindle.at-speed` gate waits forever).
    pub at_speed_timeout_s: f64,
}

/// The simulated machine's own I/O figures (`servo.sim_io`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimIo {
    /// How long its tool changer takes to answer tool-change with tool-changed (s).
    pub tool_change_s: f64,
    /// How far past each soft limit its limit switches trip (mm): beyond the homing
    /// section's `switch_margin_mm`, so a home switch is reached first.
    pub limit_switch_margin_mm: f64,
    /// The probe trips while Z is at or below this (mm, machine coordinates); no
    /// plane when absent (a test drives the probe).
    #[serde(default)]
    pub probe_plane_z_mm: Option<f64>,
}

/// The axis named `name` among `axes` (profile order).
pub fn axis_index(axes: &[String], name: &str) -> Option<usize> {
    axes.iter().position(|a| a == name)
}

impl IoConfig {
    /// Checks the map at RON path `prefix` of `file`: lines within the raw counts,
    /// logical P and E within `softnc_core::machine_io`'s, axes named in the profile
    /// (`axes`), no output line driven by two signals, no signal on two lines, the
    /// at-speed band.
    pub fn validate_at(
        &self,
        file: &str,
        prefix: &str,
        axes: &[String],
    ) -> Result<(), ConfigError> {
        let bad = |path: String, reason: String| ConfigError::invalid(file, path, reason);
        let frac_ok = self.at_speed_frac > 0.0 && self.at_speed_frac < 1.0;
        if !frac_ok {
            return Err(bad(
                format!("{prefix}.at_speed_frac"),
                format!("must lie between 0 and 1 (got {})", self.at_speed_frac),
            ));
        }
        if !(self.at_speed_min_rpm >= 0.0 && self.at_speed_min_rpm.is_finite()) {
            return Err(bad(
                format!("{prefix}.at_speed_min_rpm"),
                "must be finite and >= 0".into(),
            ));
        }
        if !(self.at_speed_timeout_s > 0.0 && self.at_speed_timeout_s.is_finite()) {
            return Err(bad(
                format!("{prefix}.at_speed_timeout_s"),
                format!("must be finite and > 0 (got {})", self.at_speed_timeout_s),
            ));
        }
        for (i, l) in self.inputs.iter().enumerate() {
            let p = format!("{prefix}.inputs[{i}]");
            check_line(l.line, RAW_DIGITAL_LINES, &format!("{p}.line"), file)?;
            match &l.signal {
                InputSignal::LimitMin(a) | InputSignal::LimitMax(a) | InputSignal::Home(a)
                    if axis_index(axes, a).is_none() =>
                {
                    return Err(bad(format!("{p}.signal"), format!("no axis named {a:?}")));
                }
                InputSignal::Input(n) if *n as usize >= DIGITAL_LINES => {
                    return Err(bad(
                        format!("{p}.signal"),
                        format!("M66 P{n}: P must be below {DIGITAL_LINES}"),
                    ));
                }
                _ => {}
            }
            if self.inputs[..i].iter().any(|o| o.signal == l.signal) {
                return Err(bad(
                    format!("{p}.signal"),
                    format!("{:?} is on another line already", l.signal),
                ));
            }
        }
        for (i, l) in self.outputs.iter().enumerate() {
            let p = format!("{prefix}.outputs[{i}]");
            check_line(l.line, RAW_DIGITAL_LINES, &format!("{p}.line"), file)?;
            if let OutputSignal::Output(n) = l.signal {
                if n as usize >= DIGITAL_LINES {
                    return Err(bad(
                        format!("{p}.signal"),
                        format!("M62 P{n}: P must be below {DIGITAL_LINES}"),
                    ));
                }
            }
            if self.outputs[..i].iter().any(|o| o.line == l.line) {
                return Err(bad(
                    format!("{p}.line"),
                    format!("line {} is driven by another output already", l.line),
                ));
            }
            if self.outputs[..i].iter().any(|o| o.signal == l.signal) {
                return Err(bad(
                    format!("{p}.signal"),
                    format!("{:?} is on another line already", l.signal),
                ));
            }
        }
        for (name, lines) in [
            ("analog_inputs", &self.analog_inputs),
            ("analog_outputs", &self.analog_outputs),
        ] {
            for (i, l) in lines.iter().enumerate() {
                let p = format!("{prefix}.{name}[{i}]");
                check_line(l.line, RAW_ANALOG_LINES, &format!("{p}.line"), file)?;
                if l.e as usize >= ANALOG_LINES {
                    return Err(bad(
                        format!("{p}.e"),
                        format!("E must be below {ANALOG_LINES}"),
                    ));
                }
                if lines[..i].iter().any(|o| o.e == l.e) {
                    return Err(bad(format!("{p}.e"), format!("E{} is mapped twice", l.e)));
                }
                let shared = lines[..i].iter().any(|o| o.line == l.line);
                if name == "analog_outputs" && shared {
                    return Err(bad(
                        format!("{p}.line"),
                        format!("line {} is driven by another output already", l.line),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl SimIo {
    /// Checks the simulated machine's figures at RON path `prefix` of `file`; a
    /// limit switch must sit beyond the homing's `switch_margin_mm` (0 without
    /// homing).
    pub fn validate_at(
        &self,
        file: &str,
        prefix: &str,
        switch_margin_mm: f64,
    ) -> Result<(), ConfigError> {
        if !(self.tool_change_s >= 0.0 && self.tool_change_s.is_finite()) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.tool_change_s"),
                "must be finite and >= 0",
            ));
        }
        let m = self.limit_switch_margin_mm;
        if !(m.is_finite() && m > switch_margin_mm) {
            return Err(ConfigError::invalid(
                file,
                format!("{prefix}.limit_switch_margin_mm"),
                format!("must be finite and beyond the home switches' margin {switch_margin_mm} mm (got {m})"),
            ));
        }
        if let Some(z) = self.probe_plane_z_mm {
            if !z.is_finite() {
                return Err(ConfigError::invalid(
                    file,
                    format!("{prefix}.probe_plane_z_mm"),
                    "must be finite",
                ));
            }
        }
        Ok(())
    }
}

fn check_line(line: u32, count: usize, path: &str, file: &str) -> Result<(), ConfigError> {
    if line as usize >= count {
        return Err(ConfigError::invalid(
            file,
            path,
            format!("line {line}: the backend's lines are 0 … {}", count - 1),
        ));
    }
    Ok(())
}
