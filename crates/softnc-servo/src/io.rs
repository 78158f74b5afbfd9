//! The I/O boundary beside the servo boundary: a backend's raw lines (digital bits,
//! analog values) and its spindle (speed command with enable and direction; encoder
//! feedback: speed, position, index count), exchanged on the cycle with the axes —
//! and [`MachineIo`], the logical layer that maps the named signals of
//! `softnc_core::machine_io` onto them with the profile's I/O map (`servo.io`).
//!
//! The raw side is four methods of [`ServoBackend`](crate::ServoBackend) with
//! defaults, so a backend without I/O has no lines: [`io_lines`](crate::ServoBackend::io_lines)
//! (what it has), [`write_io`](crate::ServoBackend::write_io) before the cycle,
//! [`read_io`](crate::ServoBackend::read_io) after it, and
//! [`exchange_io`](crate::ServoBackend::exchange_io), the I/O's exchange alone on a
//! cycle that does not step the axes (drives off, E-stop). Everything here is
//! fixed-size and `Copy`: nothing on the cycle allocates.

use softnc_core::machine_io::{MachineInputs, MachineOutputs, SpindleDir, ANALOG_LINES};
use softnc_core::MAX_AXES;
use softnc_machine::io::{InputSignal, IoConfig, OutputSignal};
pub use softnc_machine::io::{RAW_ANALOG_LINES, RAW_DIGITAL_LINES};
use softnc_machine::MachineProfile;

/// What a backend has of the I/O boundary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IoLines {
    /// Raw digital inputs (lines 0 … n−1, ≤ [`RAW_DIGITAL_LINES`]).
    pub digital_in: usize,
    /// Raw digital outputs.
    pub digital_out: usize,
    /// Raw analog inputs (≤ [`RAW_ANALOG_LINES`]).
    pub analog_in: usize,
    /// Raw analog outputs.
    pub analog_out: usize,
    /// A spindle with speed feedback.
    pub spindle: bool,
}

impl IoLines {
    /// No lines, no spindle (a backend without I/O).
    pub const NONE: IoLines = IoLines {
        digital_in: 0,
        digital_out: 0,
        analog_in: 0,
        analog_out: 0,
        spindle: false,
    };
    /// Every raw line and a spindle.
    pub const ALL: IoLines = IoLines {
        digital_in: RAW_DIGITAL_LINES,
        digital_out: RAW_DIGITAL_LINES,
        analog_in: RAW_ANALOG_LINES,
        analog_out: RAW_ANALOG_LINES,
        spindle: true,
    };
}

/// The spindle drive's command.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpindleCommand {
    /// The drive turns the spindle (off: it brakes to rest).
    pub enable: bool,
    /// Counter-clockwise (M4).
    pub reverse: bool,
    /// Speed (rpm, ≥ 0): the programmed speed × spindle override.
    pub rpm: f64,
    /// M19: position the spindle to this angle from its encoder's index
    /// (degrees; LinuxCNC's `spindle.N.orient-angle` with `orient` high); `None`:
    /// not orienting.
    pub orient_deg: Option<f64>,
    /// M19 P: 0 the shorter way, 1 clockwise, 2 counter-clockwise
    /// (`spindle.N.orient-mode`).
    pub orient_dir: u8,
}

impl SpindleCommand {
    /// The signed speed (rpm): + clockwise, 0 while disabled.
    pub fn signed_rpm(&self) -> f64 {
        match (self.enable, self.reverse) {
            (false, _) => 0.0,
            (true, false) => self.rpm,
            (true, true) => -self.rpm,
        }
    }
}

/// The spindle encoder's feedback.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SpindleFeedback {
    /// Speed (rpm, signed: + clockwise).
    pub rpm: f64,
    /// Position (revolutions).
    pub revs: f64,
    /// Index pulses seen.
    pub index_count: u64,
    /// The spindle stands at the orient angle asked (`spindle.N.is-oriented`).
    pub oriented: bool,
}

/// What is written to a backend's I/O before a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawOutputs {
    /// Bit `k`: digital output line `k` is high.
    pub digital: u128,
    /// Analog output lines.
    pub analog: [f64; RAW_ANALOG_LINES],
    /// The spindle drive's command.
    pub spindle: SpindleCommand,
}

/// What a backend's I/O reads after a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RawInputs {
    /// Bit `k`: digital input line `k` is high.
    pub digital: u128,
    /// Analog input lines.
    pub analog: [f64; RAW_ANALOG_LINES],
    /// The spindle encoder.
    pub spindle: SpindleFeedback,
}

/// A named input, resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum In {
    EStop,
    LimitMin(usize),
    LimitMax(usize),
    Home(usize),
    Probe,
    ToolChanged,
    Digital(u32),
}

/// A named output, resolved.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Out {
    SpindleEnable,
    SpindleCw,
    SpindleCcw,
    CoolantMist,
    CoolantFlood,
    ToolChange,
    MachineOn,
    AmpEnable,
    Digital(u32),
}

/// One input line with its debounce state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct InputLine {
    signal: In,
    line: u32,
    active_low: bool,
    debounce_cycles: u32,
    /// The debounced level (asserted).
    state: bool,
    /// Cycles the line has read the other level.
    differing: u32,
}

impl InputLine {
    /// One cycle's read of the raw inputs: the debounced signal.
    fn update(&mut self, raw: u128) -> bool {
        let asserted = (raw >> self.line) & 1 == 1 && !self.active_low
            || (raw >> self.line) & 1 == 0 && self.active_low;
        if asserted == self.state {
            self.differing = 0;
        } else {
            self.differing += 1;
            if self.differing > self.debounce_cycles {
                self.state = asserted;
                self.differing = 0;
            }
        }
        self.state
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct OutputLine {
    signal: Out,
    line: u32,
    active_low: bool,
}

/// The machine's state the outputs depend on beyond the program's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputState {
    /// The machine is on (the operator's `on`, not E-stopped).
    pub machine_on: bool,
    /// The drives may be enabled.
    pub amp_enable: bool,
    /// Spindle override (fraction of the programmed speed).
    pub spindle_override: f64,
}

impl Default for OutputState {
    fn default() -> Self {
        OutputState {
            machine_on: true,
            amp_enable: true,
            spindle_override: 1.0,
        }
    }
}

/// The logical I/O: the profile's map from named signals to a backend's raw lines,
/// with polarity, debounce, the spindle's at-speed and the E-stop latch. Built off
/// the cycle (it allocates its line lists once); [`MachineIo::outputs`] and
/// [`MachineIo::inputs`] run on it and allocate nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineIo {
    inputs: Vec<InputLine>,
    outputs: Vec<OutputLine>,
    analog_in: Vec<(usize, usize)>,
    analog_out: Vec<(usize, usize)>,
    /// (fraction, rpm) of the at-speed band; `None` without a map.
    at_speed: Option<(f64, f64)>,
    /// The backend has spindle feedback.
    spindle_feedback: bool,
    /// Bit `a`: axis `a` has a home switch on one of the backend's lines.
    home_mapped: u32,
    /// The E-stop input was seen open and the latch not reset.
    estop_latched: bool,
    /// The E-stop input as debounced now (not latched).
    estop_now: bool,
    /// What the outputs were last set to (after the safe state).
    last_out: MachineOutputs,
    /// The spindle's command last written (signed rpm, × override).
    commanded_rpm: f64,
    /// The spindle's command last written orients it (M19).
    orienting: bool,
    last_in: MachineInputs,
}

impl MachineIo {
    /// The map of `profile` (`servo.io`; none: no signal mapped) over a backend with
    /// `lines` (a signal on a line the backend lacks reads unasserted and drives
    /// nothing).
    pub fn new(profile: &MachineProfile, lines: IoLines) -> Self {
        let names: Vec<String> = profile.axes.iter().map(|a| a.name.clone()).collect();
        let axis = |n: &str| {
            softnc_machine::io::axis_index(&names, n)
                .filter(|&i| i < MAX_AXES)
                .unwrap_or(usize::MAX)
        };
        let empty = IoConfig {
            inputs: Vec::new(),
            outputs: Vec::new(),
            analog_inputs: Vec::new(),
            analog_outputs: Vec::new(),
            at_speed_frac: 0.0,
            at_speed_min_rpm: 0.0,
            at_speed_timeout_s: 0.0,
        };
        let cfg = profile.servo.io.as_ref();
        let map = cfg.unwrap_or(&empty);
        let inputs: Vec<InputLine> = map
            .inputs
            .iter()
            .filter(|l| (l.line as usize) < lines.digital_in)
            .filter_map(|l| {
                let signal = match &l.signal {
                    InputSignal::EStop => In::EStop,
                    InputSignal::LimitMin(a) => In::LimitMin(axis(a)),
                    InputSignal::LimitMax(a) => In::LimitMax(axis(a)),
                    InputSignal::Home(a) => In::Home(axis(a)),
                    InputSignal::Probe => In::Probe,
                    InputSignal::ToolChanged => In::ToolChanged,
                    InputSignal::Input(p) => In::Digital(*p),
                };
                let axis_ok = match signal {
                    In::LimitMin(a) | In::LimitMax(a) | In::Home(a) => a < MAX_AXES,
                    _ => true,
                };
                axis_ok.then_some(InputLine {
                    signal,
                    line: l.line,
                    active_low: l.active_low,
                    debounce_cycles: l.debounce_cycles,
                    state: false,
                    differing: 0,
                })
            })
            .collect();
        let outputs = map
            .outputs
            .iter()
            .filter(|l| (l.line as usize) < lines.digital_out)
            .map(|l| OutputLine {
                signal: match l.signal {
                    OutputSignal::SpindleEnable => Out::SpindleEnable,
                    OutputSignal::SpindleCw => Out::SpindleCw,
                    OutputSignal::SpindleCcw => Out::SpindleCcw,
                    OutputSignal::CoolantMist => Out::CoolantMist,
                    OutputSignal::CoolantFlood => Out::CoolantFlood,
                    OutputSignal::ToolChange => Out::ToolChange,
                    OutputSignal::MachineOn => Out::MachineOn,
                    OutputSignal::AmpEnable => Out::AmpEnable,
                    OutputSignal::Output(p) => Out::Digital(p),
                },
                line: l.line,
                active_low: l.active_low,
            })
            .collect();
        let analog = |v: &[softnc_machine::io::AnalogLine], n: usize| {
            v.iter()
                .filter(|a| (a.line as usize) < n && (a.e as usize) < ANALOG_LINES)
                .map(|a| (a.e as usize, a.line as usize))
                .collect()
        };
        let home_mapped = inputs.iter().fold(0u32, |m, l: &InputLine| match l.signal {
            In::Home(a) => m | 1 << a,
            _ => m,
        });
        MachineIo {
            inputs,
            home_mapped,
            outputs,
            analog_in: analog(&map.analog_inputs, lines.analog_in),
            analog_out: analog(&map.analog_outputs, lines.analog_out),
            at_speed: cfg.map(|c| (c.at_speed_frac, c.at_speed_min_rpm)),
            spindle_feedback: lines.spindle,
            estop_latched: false,
            estop_now: false,
            last_out: MachineOutputs::safe(),
            commanded_rpm: 0.0,
            orienting: false,
            last_in: MachineInputs::default(),
        }
    }

    /// The raw outputs for `program` (the outputs of the sample in use) in `state`:
    /// the safe state ([`MachineOutputs::safe`], machine-on and amplifier-enable off)
    /// while the E-stop input is latched or the machine is off.
    pub fn outputs(&mut self, program: &MachineOutputs, state: OutputState) -> RawOutputs {
        let on = state.machine_on && !self.estop_latched;
        let o = if on { *program } else { MachineOutputs::safe() };
        let amp = on && state.amp_enable;
        let ovr = if state.spindle_override.is_finite() {
            state.spindle_override.max(0.0)
        } else {
            0.0
        };
        let spindle = SpindleCommand {
            enable: o.spindle_dir != SpindleDir::Stopped,
            reverse: o.spindle_dir == SpindleDir::CounterClockwise,
            rpm: o.spindle_rpm * ovr,
            orient_deg: o.spindle_orient_deg,
            orient_dir: o.spindle_orient_dir,
        };
        self.orienting = spindle.orient_deg.is_some();
        self.commanded_rpm = spindle.signed_rpm();
        self.last_out = o;
        let mut raw = RawOutputs {
            spindle,
            ..RawOutputs::default()
        };
        for l in &self.outputs {
            let asserted = match l.signal {
                Out::SpindleEnable => spindle.enable,
                Out::SpindleCw => o.spindle_dir == SpindleDir::Clockwise,
                Out::SpindleCcw => o.spindle_dir == SpindleDir::CounterClockwise,
                Out::CoolantMist => o.coolant_mist,
                Out::CoolantFlood => o.coolant_flood,
                Out::ToolChange => o.tool_change,
                Out::MachineOn => on,
                Out::AmpEnable => amp,
                Out::Digital(p) => (o.digital >> p) & 1 == 1,
            };
            if asserted != l.active_low {
                raw.digital |= 1u128 << l.line;
            }
        }
        for &(e, line) in &self.analog_out {
            raw.analog[line] = o.analog[e];
        }
        raw
    }

    /// The named inputs from one cycle's raw inputs: debounced, polarity applied,
    /// the spindle's at-speed computed against the command last written, the E-stop
    /// input latched.
    pub fn inputs(&mut self, raw: &RawInputs) -> MachineInputs {
        let mut m = MachineInputs::default();
        let mut estop = false;
        for l in &mut self.inputs {
            let on = l.update(raw.digital);
            match l.signal {
                In::EStop => estop = on,
                In::LimitMin(a) => m.limit_min |= u32::from(on) << a,
                In::LimitMax(a) => m.limit_max |= u32::from(on) << a,
                In::Home(a) => m.home |= u32::from(on) << a,
                In::Probe => m.probe = on,
                In::ToolChanged => m.tool_changed = on,
                In::Digital(p) => m.digital |= u64::from(on) << p,
            }
        }
        for &(e, line) in &self.analog_in {
            m.analog[e] = raw.analog[line];
        }
        self.estop_now = estop;
        self.estop_latched |= estop;
        m.estop_open = self.estop_latched;
        let cmd = self.commanded_rpm;
        if self.spindle_feedback {
            m.spindle_rpm = raw.spindle.rpm;
            m.spindle_revs = raw.spindle.revs;
            m.spindle_index_count = raw.spindle.index_count;
            m.spindle_oriented = self.orienting && raw.spindle.oriented;
        } else {
            // no feedback: the spindle is taken to turn as commanded (open loop),
            // and to stand where an orient asks
            m.spindle_rpm = cmd;
            m.spindle_oriented = self.orienting;
        }
        m.spindle_at_speed = match (self.spindle_feedback, self.at_speed) {
            (true, Some((frac, min_rpm))) => {
                (m.spindle_rpm - cmd).abs() <= (frac * cmd.abs()).max(min_rpm)
            }
            // LinuxCNC's `spindle.at-speed` unconnected reads true
            _ => true,
        };
        self.last_in = m;
        m
    }

    /// Clear the E-stop latch if the input is closed now; true when it is clear.
    pub fn reset_estop(&mut self) -> bool {
        if !self.estop_now {
            self.estop_latched = false;
        }
        !self.estop_latched
    }

    /// Bit `a`: axis `a` has a home switch (a `Home` signal of the map on a line
    /// the backend has); its state is [`MachineInputs::home`].
    pub fn home_switches(&self) -> u32 {
        self.home_mapped
    }

    /// The E-stop input is latched open (until [`MachineIo::reset_estop`]).
    pub fn estop_latched(&self) -> bool {
        self.estop_latched
    }

    /// The E-stop input is open now (debounced, not latched).
    pub fn estop_input_open(&self) -> bool {
        self.estop_now
    }

    /// The outputs last written (the program's, or the safe state).
    pub fn last_outputs(&self) -> &MachineOutputs {
        &self.last_out
    }

    /// The inputs last read.
    pub fn last_inputs(&self) -> &MachineInputs {
        &self.last_in
    }

    /// The spindle's speed command last written (signed rpm, × override).
    pub fn commanded_rpm(&self) -> f64 {
        self.commanded_rpm
    }

    /// The I/O columns of a trace row: what was last written and read.
    pub fn trace(&self) -> IoTrace {
        IoTrace {
            spindle_cmd_rpm: self.commanded_rpm,
            spindle_rpm: self.last_in.spindle_rpm,
            coolant: u8::from(self.last_out.coolant_mist)
                | u8::from(self.last_out.coolant_flood) << 1,
            digital_out: self.last_out.digital,
        }
    }

    /// Carry the machine's I/O state (debounce, the E-stop latch) over from the
    /// map that ran it until now (a new job's engine takes the machine over).
    pub fn take_state_from(&mut self, running: &MachineIo) {
        if self.inputs.len() == running.inputs.len() {
            for (l, r) in self.inputs.iter_mut().zip(&running.inputs) {
                l.state = r.state;
                l.differing = r.differing;
            }
        }
        self.estop_latched = running.estop_latched;
        self.estop_now = running.estop_now;
        self.last_in = running.last_in;
    }
}

/// The I/O columns of a trace row.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IoTrace {
    /// The spindle's speed command (signed rpm, × override; 0 stopped).
    pub spindle_cmd_rpm: f64,
    /// The spindle's actual speed (rpm, from its encoder).
    pub spindle_rpm: f64,
    /// Bit 0 mist, bit 1 flood.
    pub coolant: u8,
    /// M62–M65 outputs (bit P).
    pub digital_out: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use softnc_machine::io::{AnalogLine, InputLine as InCfg, OutputLine as OutCfg};

    fn profile(io: IoConfig) -> MachineProfile {
        let mut p = MachineProfile::from_ron_str(
            include_str!("../../../config/machines/default.ron"),
            "default.ron",
        )
        .unwrap();
        p.servo.io = Some(io);
        p
    }

    fn map() -> IoConfig {
        IoConfig {
            inputs: vec![
                InCfg {
                    signal: InputSignal::EStop,
                    line: 3,
                    active_low: true,
                    debounce_cycles: 0,
                },
                InCfg {
                    signal: InputSignal::LimitMax("Y".into()),
                    line: 100,
                    active_low: false,
                    debounce_cycles: 2,
                },
                InCfg {
                    signal: InputSignal::Input(5),
                    line: 7,
                    active_low: true,
                    debounce_cycles: 0,
                },
            ],
            outputs: vec![
                OutCfg {
                    signal: OutputSignal::SpindleCcw,
                    line: 0,
                    active_low: false,
                },
                OutCfg {
                    signal: OutputSignal::CoolantFlood,
                    line: 120,
                    active_low: true,
                },
                OutCfg {
                    signal: OutputSignal::Output(2),
                    line: 9,
                    active_low: false,
                },
                OutCfg {
                    signal: OutputSignal::AmpEnable,
                    line: 10,
                    active_low: false,
                },
            ],
            analog_inputs: vec![AnalogLine { e: 1, line: 15 }],
            analog_outputs: vec![AnalogLine { e: 3, line: 2 }],
            at_speed_frac: 0.02,
            at_speed_min_rpm: 30.0,
            at_speed_timeout_s: 5.0,
        }
    }

    /// Raw inputs with the E-stop chain closed (line 3 high, active-low) and M66 P5
    /// off (line 7 high, active-low).
    fn closed() -> RawInputs {
        RawInputs {
            digital: 1 << 3 | 1 << 7,
            ..RawInputs::default()
        }
    }

    #[test]
    fn outputs_land_on_their_lines_with_their_polarity() {
        let mut io = MachineIo::new(&profile(map()), IoLines::ALL);
        let mut o = MachineOutputs {
            spindle_dir: SpindleDir::CounterClockwise,
            spindle_rpm: 8000.0,
            coolant_flood: true,
            digital: 1 << 2,
            ..MachineOutputs::default()
        };
        o.analog[3] = 2.5;
        let st = OutputState {
            spindle_override: 0.5,
            ..OutputState::default()
        };
        let raw = io.outputs(&o, st);
        // ccw high, flood active-low: low, P2 high, amp-enable high
        assert_eq!(raw.digital, 1 << 0 | 1 << 9 | 1 << 10);
        assert_eq!(raw.analog[2], 2.5);
        assert_eq!(
            raw.spindle,
            SpindleCommand {
                enable: true,
                reverse: true,
                rpm: 4000.0,
                ..SpindleCommand::default()
            }
        );
        assert_eq!(io.commanded_rpm(), -4000.0);
        let t = io.trace();
        assert_eq!((t.coolant, t.digital_out), (2, 4));
        // flood off: its active-low line goes high
        o.coolant_flood = false;
        let raw = io.outputs(&o, st);
        assert_eq!(raw.digital >> 120 & 1, 1);
        // machine off: the safe state, flood's line high (off), amp-enable low
        let off = OutputState {
            machine_on: false,
            ..st
        };
        let raw = io.outputs(&o, off);
        assert_eq!(raw.digital, 1 << 120);
        assert_eq!(raw.spindle, SpindleCommand::default());
        assert_eq!(raw.analog, [0.0; RAW_ANALOG_LINES]);
    }

    #[test]
    fn inputs_debounce_and_active_low() {
        let mut io = MachineIo::new(&profile(map()), IoLines::ALL);
        let mut raw = closed();
        raw.analog[15] = -1.25;
        let m = io.inputs(&raw);
        assert!(!m.estop_open);
        assert_eq!(m.digital, 0, "P5 active-low, its line high: off");
        assert_eq!(m.analog[1], -1.25);
        // the Y max limit (line 100) debounced over 2 cycles: asserted on the third
        raw.digital |= 1 << 100;
        assert_eq!(io.inputs(&raw).limit_max, 0);
        assert_eq!(io.inputs(&raw).limit_max, 0);
        assert_eq!(io.inputs(&raw).limit_max, 1 << 1);
        // a one-cycle glitch back does not release it
        raw.digital &= !(1 << 100);
        assert_eq!(io.inputs(&raw).limit_max, 1 << 1);
        raw.digital |= 1 << 100;
        assert_eq!(io.inputs(&raw).limit_max, 1 << 1);
        // M66 P5: its line low
        raw.digital &= !(1 << 7);
        assert_eq!(io.inputs(&raw).digital, 1 << 5);
    }

    #[test]
    fn the_estop_input_latches_until_reset_with_it_closed() {
        let mut io = MachineIo::new(&profile(map()), IoLines::ALL);
        let o = MachineOutputs {
            spindle_dir: SpindleDir::Clockwise,
            spindle_rpm: 1000.0,
            ..MachineOutputs::default()
        };
        assert!(!io.inputs(&closed()).estop_open);
        assert!(io.outputs(&o, OutputState::default()).spindle.enable);
        // the chain opens (its active-low line goes low) for one cycle
        let open = RawInputs {
            digital: 1 << 7,
            ..RawInputs::default()
        };
        assert!(io.inputs(&open).estop_open);
        assert!(io.inputs(&closed()).estop_open, "latched");
        assert!(io.estop_latched() && !io.estop_input_open());
        // the outputs go safe, whatever the program says
        let raw = io.outputs(&o, OutputState::default());
        assert_eq!(raw.spindle, SpindleCommand::default());
        assert_eq!(raw.digital >> 10 & 1, 0, "amp-enable off");
        // reset while open: refused
        io.inputs(&open);
        assert!(!io.reset_estop());
        io.inputs(&closed());
        assert!(io.reset_estop());
        assert!(!io.inputs(&closed()).estop_open);
        assert!(io.outputs(&o, OutputState::default()).spindle.enable);
    }

    #[test]
    fn at_speed_within_the_band_of_command_times_override() {
        let mut io = MachineIo::new(&profile(map()), IoLines::ALL);
        let o = MachineOutputs {
            spindle_dir: SpindleDir::Clockwise,
            spindle_rpm: 10000.0,
            ..MachineOutputs::default()
        };
        let st = OutputState {
            spindle_override: 0.8,
            ..OutputState::default()
        };
        io.outputs(&o, st);
        let at = |io: &mut MachineIo, rpm: f64| {
            let mut raw = closed();
            raw.spindle.rpm = rpm;
            io.inputs(&raw).spindle_at_speed
        };
        // 8000 rpm ± 2 % = ± 160 rpm
        assert!(!at(&mut io, 0.0));
        assert!(!at(&mut io, 7830.0));
        assert!(at(&mut io, 7850.0));
        assert!(at(&mut io, 8159.0));
        assert!(!at(&mut io, 8170.0));
        assert!(!at(&mut io, -8000.0), "turning the wrong way");
        // stopped: at speed within the 30 rpm floor
        io.outputs(&MachineOutputs::default(), st);
        assert!(!at(&mut io, 100.0));
        assert!(at(&mut io, 20.0));
        // no feedback, or no map: at speed (LinuxCNC's unconnected at-speed)
        let mut open_loop = MachineIo::new(&profile(map()), IoLines::NONE);
        open_loop.outputs(&o, st);
        let m = open_loop.inputs(&RawInputs::default());
        assert!(m.spindle_at_speed);
        assert_eq!(m.spindle_rpm, 8000.0);
        assert!(!m.estop_open, "no E-stop line on a backend without lines");
    }
}
