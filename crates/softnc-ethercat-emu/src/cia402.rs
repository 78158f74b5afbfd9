//! A CiA 402 servo drive (IEC 61800-7-201) in cyclic synchronous position mode:
//! its object dictionary, the power state machine on the controlword, a position
//! loop around `softnc-plant`'s identified velocity loop (`VelocityLoop`, paper
//! 000's model: the velocity command to motor speed, the table position integrated
//! through the screw), following error with its window, the error code 0x603F, and
//! the digital inputs 0x60FD.

use crate::app::{
    AppState, AppView, Application, Identity, Layout, MailboxSpec, PdoDescription, SmSpec, SmUsage,
};
use crate::od::{Access, ObjectDictionary};
use softnc_plant::velocity_loop::VelocityLoop;

/// Objects.
pub mod obj {
    /// Controlword.
    pub const CONTROLWORD: u16 = 0x6040;
    /// Statusword.
    pub const STATUSWORD: u16 = 0x6041;
    /// Modes of operation.
    pub const MODES: u16 = 0x6060;
    /// Modes of operation display.
    pub const MODES_DISPLAY: u16 = 0x6061;
    /// Target position (counts).
    pub const TARGET_POSITION: u16 = 0x607A;
    /// Position actual value (counts).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// Following error window (counts).
    pub const FOLLOWING_ERROR_WINDOW: u16 = 0x6065;
    /// Following error actual value (counts).
    pub const FOLLOWING_ERROR_ACTUAL: u16 = 0x60F4;
    /// Error code.
    pub const ERROR_CODE: u16 = 0x603F;
    /// Digital inputs.
    pub const DIGITAL_INPUTS: u16 = 0x60FD;
    /// Digital outputs (sub 1 physical outputs).
    pub const DIGITAL_OUTPUTS: u16 = 0x60FE;
    /// Interpolation time period (sub 1 value, sub 2 index: value·10^index s).
    pub const INTERPOLATION_PERIOD: u16 = 0x60C2;
    /// Supported drive modes.
    pub const SUPPORTED_MODES: u16 = 0x6502;
}

/// Modes of operation: cyclic synchronous position.
pub const MODE_CSP: i8 = 8;
/// Error code of a following error (CiA 402: 0x8611).
pub const ERROR_FOLLOWING: u16 = 0x8611;

/// Statusword bits.
const SW_READY: u16 = 0x0001;
const SW_SWITCHED_ON: u16 = 0x0002;
const SW_OP_ENABLED: u16 = 0x0004;
const SW_FAULT: u16 = 0x0008;
const SW_VOLTAGE: u16 = 0x0010;
const SW_QUICK_STOP: u16 = 0x0020;
const SW_SWITCH_ON_DISABLED: u16 = 0x0040;
const SW_REMOTE: u16 = 0x0200;
const SW_TARGET_FOLLOWED: u16 = 0x1000;
const SW_FOLLOWING_ERROR: u16 = 0x2000;
/// Controlword: fault reset (bit 7).
const CW_FAULT_RESET: u16 = 0x0080;

/// The drive's loop.
/// Position loop gain (1/s).
const KP_PER_S: f64 = 150.0;
/// The velocity loop (b₁, b₂ / a₁, a₂) at 1 ms: unity gain, τ ≈ 4.5 ms.
const VEL_NUM: [f64; 2] = [0.2, 0.0];
const VEL_DEN: [f64; 2] = [-0.8, 0.0];
/// Screw lead (mm per revolution).
const LEAD_MM: f64 = 10.0;
/// Default following error window (counts) and interpolation period (1·10⁻³ s).
const DEFAULT_FE_WINDOW: u32 = 100_000;
/// Cycles a following error may last before the fault (the window's timeout).
const FE_TIMEOUT_CYCLES: u32 = 10;

/// The power state machine's states (CiA 402 Figure 8).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PowerState {
    /// Switch on disabled.
    SwitchOnDisabled,
    /// Ready to switch on.
    ReadyToSwitchOn,
    /// Switched on.
    SwitchedOn,
    /// Operation enabled.
    OperationEnabled,
    /// Quick stop active.
    QuickStopActive,
    /// Fault.
    Fault,
}

/// What a test reads back from a drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriveView {
    /// Power state.
    pub state: PowerState,
    /// Statusword as sent.
    pub statusword: u16,
    /// Position actual (counts).
    pub position_counts: i32,
    /// Target position as last received (counts).
    pub target_counts: i32,
    /// Controlword as last received.
    pub controlword: u16,
    /// Modes of operation display.
    pub mode: i8,
    /// Error code 0x603F.
    pub error_code: u16,
    /// Interpolation period (s) as configured in 0x60C2.
    pub period_s: f64,
    /// Targets received in OP (cycles with outputs).
    pub targets_received: u64,
}

const MAILBOX: MailboxSpec = MailboxSpec {
    out_start: 0x1000,
    out_len: 128,
    in_start: 0x1080,
    in_len: 128,
};

const SMS: &[SmSpec] = &[
    SmSpec {
        start: 0x1000,
        default_len: 128,
        control: 0x26,
        usage: SmUsage::MailboxOut,
    },
    SmSpec {
        start: 0x1080,
        default_len: 128,
        control: 0x22,
        usage: SmUsage::MailboxIn,
    },
    SmSpec {
        start: 0x1100,
        default_len: 6,
        control: 0x64,
        usage: SmUsage::Outputs,
    },
    SmSpec {
        start: 0x1180,
        default_len: 6,
        control: 0x20,
        usage: SmUsage::Inputs,
    },
];

const LAYOUT: Layout = Layout {
    name: "softnc emulated CiA 402 drive",
    mailbox: Some(MAILBOX),
    sms: SMS,
    fmmus: &[1, 2],
    rx_pdos: &[PdoDescription {
        index: 0x1600,
        name: "RxPDO 1",
        sm: 2,
        entries: &[(0x6040, 0, 16), (0x607A, 0, 32)],
    }],
    tx_pdos: &[PdoDescription {
        index: 0x1A00,
        name: "TxPDO 1",
        sm: 3,
        entries: &[(0x6041, 0, 16), (0x6064, 0, 32)],
    }],
};

/// A drive.
pub struct Drive {
    identity: Identity,
    od: ObjectDictionary,
    state: PowerState,
    last_controlword: u16,
    motor: VelocityLoop,
    counts_per_mm: f64,
    last_target: i32,
    fe_cycles: u32,
    targets_received: u64,
    sdo_digital_inputs: u32,
    /// A home switch on the axis: 0x60FD bit 2 (CiA 402's home switch) is set
    /// while the position is at or beyond this (counts, positive side).
    home_switch_counts: Option<i32>,
}

/// 0x60FD's home switch bit.
pub const HOME_SWITCH_BIT: u32 = 1 << 2;

impl Drive {
    /// A drive with `identity`, its encoder at `counts_per_mm`, at rest at 0.
    pub fn new(identity: Identity, counts_per_mm: f64) -> Self {
        let mut od = ObjectDictionary::default();
        let d = Access::Rw;
        od.insert(0x1000, 0, &0x0002_0192u32.to_le_bytes(), Access::Ro, false);
        od.insert(0x1008, 0, LAYOUT.name.as_bytes(), Access::Ro, false);
        od.insert_array(
            0x1018,
            &[
                &identity.vendor_id.to_le_bytes(),
                &identity.product_code.to_le_bytes(),
                &identity.revision.to_le_bytes(),
                &identity.serial.to_le_bytes(),
            ],
            Access::Ro,
        );
        od.insert_array(0x1C00, &[&[1], &[2], &[3], &[4]], Access::Ro);
        od.insert_array(
            0x1C32,
            &[&2u16.to_le_bytes(), &1_000_000u32.to_le_bytes()],
            d,
        );
        od.insert_array(
            0x1C33,
            &[&2u16.to_le_bytes(), &1_000_000u32.to_le_bytes()],
            d,
        );
        let mapping = |entries: &[(u16, u8, u8)]| -> Vec<[u8; 4]> {
            let mut v: Vec<[u8; 4]> = entries
                .iter()
                .map(|&(i, s, b)| {
                    ((u32::from(i) << 16) | (u32::from(s) << 8) | u32::from(b)).to_le_bytes()
                })
                .collect();
            v.resize(8, [0; 4]);
            v
        };
        for (index, pdo) in [(0x1600u16, LAYOUT.rx_pdos[0]), (0x1A00, LAYOUT.tx_pdos[0])] {
            od.insert(index, 0, &[pdo.entries.len() as u8], Access::RwPreOp, false);
            for (k, m) in mapping(pdo.entries).iter().enumerate() {
                od.insert(index, k as u8 + 1, m, Access::RwPreOp, false);
            }
        }
        od.insert(0x1C12, 0, &[1], Access::RwPreOp, false);
        od.insert(0x1C12, 1, &0x1600u16.to_le_bytes(), Access::RwPreOp, false);
        od.insert(0x1C13, 0, &[1], Access::RwPreOp, false);
        od.insert(0x1C13, 1, &0x1A00u16.to_le_bytes(), Access::RwPreOp, false);
        od.insert(obj::CONTROLWORD, 0, &[0; 2], d, true);
        od.insert(obj::STATUSWORD, 0, &[0; 2], Access::Ro, true);
        od.insert(obj::MODES, 0, &[0], d, true);
        od.insert(obj::MODES_DISPLAY, 0, &[0], Access::Ro, true);
        od.insert(obj::TARGET_POSITION, 0, &[0; 4], d, true);
        od.insert(obj::POSITION_ACTUAL, 0, &[0; 4], Access::Ro, true);
        od.insert(obj::FOLLOWING_ERROR_ACTUAL, 0, &[0; 4], Access::Ro, true);
        od.insert(
            obj::FOLLOWING_ERROR_WINDOW,
            0,
            &DEFAULT_FE_WINDOW.to_le_bytes(),
            d,
            false,
        );
        od.insert(obj::ERROR_CODE, 0, &[0; 2], Access::Ro, true);
        od.insert(obj::DIGITAL_INPUTS, 0, &[0; 4], Access::Ro, true);
        od.insert(obj::DIGITAL_OUTPUTS, 0, &[2], Access::Ro, false);
        od.insert(obj::DIGITAL_OUTPUTS, 1, &[0; 4], d, true);
        od.insert(obj::DIGITAL_OUTPUTS, 2, &[0; 4], d, false);
        od.insert(obj::INTERPOLATION_PERIOD, 0, &[2], Access::Ro, false);
        od.insert(obj::INTERPOLATION_PERIOD, 1, &[1], d, false);
        od.insert(obj::INTERPOLATION_PERIOD, 2, &[(-3i8) as u8], d, false);
        od.insert(
            obj::SUPPORTED_MODES,
            0,
            &0x0000_0080u32.to_le_bytes(),
            Access::Ro,
            false,
        );
        let mut drive = Drive {
            identity,
            od,
            state: PowerState::SwitchOnDisabled,
            last_controlword: 0,
            motor: VelocityLoop::new(VEL_NUM, VEL_DEN, 1e-3, LEAD_MM, 0.0),
            counts_per_mm,
            last_target: 0,
            fe_cycles: 0,
            targets_received: 0,
            sdo_digital_inputs: 0,
            home_switch_counts: None,
        };
        drive.publish(0);
        drive
    }

    fn period_s(&self) -> f64 {
        let v = f64::from(self.od.u8(obj::INTERPOLATION_PERIOD, 1));
        v * 10f64.powi(i32::from(self.od.i8(obj::INTERPOLATION_PERIOD, 2)))
    }

    fn position_counts(&self) -> i32 {
        (self.motor.pos_mm() * self.counts_per_mm).round() as i32
    }

    /// The power state machine on a controlword (CiA 402 Table 29).
    fn command(&mut self, cw: u16) {
        use PowerState::*;
        let rising_reset = cw & CW_FAULT_RESET != 0 && self.last_controlword & CW_FAULT_RESET == 0;
        self.last_controlword = cw;
        let low = cw & 0x000F;
        let disable_voltage = cw & 0x0002 == 0;
        let quick_stop = cw & 0x0006 == 0x0002;
        let shutdown = cw & 0x0007 == 0x0006;
        let switch_on = low == 0x0007;
        let enable = low == 0x000F;
        let next = match self.state {
            Fault if rising_reset => {
                self.od.set(obj::ERROR_CODE, 0, &[0; 2]);
                SwitchOnDisabled
            }
            Fault => Fault,
            _ if disable_voltage => SwitchOnDisabled,
            OperationEnabled if quick_stop => QuickStopActive,
            QuickStopActive if enable => OperationEnabled,
            QuickStopActive => QuickStopActive,
            _ if quick_stop => SwitchOnDisabled,
            SwitchOnDisabled if shutdown => ReadyToSwitchOn,
            ReadyToSwitchOn if switch_on => SwitchedOn,
            ReadyToSwitchOn | SwitchedOn if enable => OperationEnabled,
            SwitchedOn | OperationEnabled if shutdown => ReadyToSwitchOn,
            OperationEnabled if switch_on => SwitchedOn,
            s => s,
        };
        if next == OperationEnabled && self.state != OperationEnabled {
            // no jump: the loop starts from where the axis is
            self.fe_cycles = 0;
        }
        self.state = next;
    }

    fn fault(&mut self, code: u16) {
        self.state = PowerState::Fault;
        self.od.set(obj::ERROR_CODE, 0, &code.to_le_bytes());
    }

    /// One servo period: the loop closed on the target in CSP and operation
    /// enabled; braked to a stop otherwise.
    fn step(&mut self, target: i32) {
        let period = self.period_s();
        let steps = (period / self.motor.sample_s()).round().max(1.0) as usize;
        let powered =
            self.state == PowerState::OperationEnabled && self.od.i8(obj::MODES, 0) == MODE_CSP;
        let mm_per_rad = LEAD_MM / std::f64::consts::TAU;
        let ff_mm_per_s =
            f64::from(target.wrapping_sub(self.last_target)) / self.counts_per_mm / period;
        let target_mm = f64::from(target) / self.counts_per_mm;
        for _ in 0..steps {
            let v_mm_per_s = if powered {
                KP_PER_S * (target_mm - self.motor.pos_mm()) + ff_mm_per_s
            } else {
                0.0
            };
            self.motor.step(v_mm_per_s / mm_per_rad);
        }
        self.last_target = target;
        let fe = if powered {
            target.wrapping_sub(self.position_counts())
        } else {
            0
        };
        let window = self.od.u32(obj::FOLLOWING_ERROR_WINDOW, 0);
        if powered && fe.unsigned_abs() > window {
            self.fe_cycles += 1;
            if self.fe_cycles > FE_TIMEOUT_CYCLES {
                self.fault(ERROR_FOLLOWING);
            }
        } else {
            self.fe_cycles = 0;
        }
        if self.state == PowerState::QuickStopActive && self.motor.speed_rad_per_s().abs() < 1e-3 {
            self.state = PowerState::SwitchOnDisabled;
        }
        self.publish(fe);
    }

    fn publish(&mut self, fe: i32) {
        use PowerState::*;
        let bits = match self.state {
            SwitchOnDisabled => SW_SWITCH_ON_DISABLED,
            ReadyToSwitchOn => SW_READY | SW_QUICK_STOP,
            SwitchedOn => SW_READY | SW_SWITCHED_ON | SW_QUICK_STOP | SW_VOLTAGE,
            OperationEnabled => {
                SW_READY
                    | SW_SWITCHED_ON
                    | SW_OP_ENABLED
                    | SW_QUICK_STOP
                    | SW_VOLTAGE
                    | SW_TARGET_FOLLOWED
            }
            QuickStopActive => SW_READY | SW_SWITCHED_ON | SW_OP_ENABLED | SW_VOLTAGE,
            Fault => SW_FAULT,
        };
        let fe_bit = if self.fe_cycles > 0 {
            SW_FOLLOWING_ERROR
        } else {
            0
        };
        self.od.set(
            obj::STATUSWORD,
            0,
            &(bits | SW_REMOTE | fe_bit).to_le_bytes(),
        );
        self.od.set(
            obj::POSITION_ACTUAL,
            0,
            &self.position_counts().to_le_bytes(),
        );
        self.od
            .set(obj::FOLLOWING_ERROR_ACTUAL, 0, &fe.to_le_bytes());
        let mode = self.od.u8(obj::MODES, 0);
        self.od.set(obj::MODES_DISPLAY, 0, &[mode]);
        let home = match self.home_switch_counts {
            Some(at) if self.position_counts() >= at => HOME_SWITCH_BIT,
            _ => 0,
        };
        self.od.set(
            obj::DIGITAL_INPUTS,
            0,
            &(self.sdo_digital_inputs | home).to_le_bytes(),
        );
    }
}

impl Application for Drive {
    fn identity(&self) -> Identity {
        self.identity
    }
    fn layout(&self) -> &Layout {
        &LAYOUT
    }
    fn od(&mut self) -> Option<&mut ObjectDictionary> {
        Some(&mut self.od)
    }
    fn process_data_len(&self) -> (usize, usize) {
        (self.od.mapped_len(0x1C12), self.od.mapped_len(0x1C13))
    }
    fn check_safe_op(&self) -> Result<(), u16> {
        // the period must be one the loop can run (a whole number of model samples)
        if self.period_s() >= self.motor.sample_s() {
            Ok(())
        } else {
            Err(crate::al::code::INVALID_OUTPUTS)
        }
    }
    fn cycle(&mut self, state: AppState, outputs: Option<&[u8]>, inputs: &mut [u8]) {
        match state {
            AppState::NoProcessData => {}
            AppState::InputsOnly => {
                if self.state == PowerState::OperationEnabled {
                    self.state = PowerState::SwitchOnDisabled;
                }
                let hold = self.position_counts();
                self.step(hold);
            }
            AppState::Operational => {
                if let Some(out) = outputs {
                    self.od.unpack(out);
                    self.targets_received += 1;
                    self.command(self.od.u16(obj::CONTROLWORD, 0));
                }
                let target = if self.state == PowerState::OperationEnabled {
                    self.od.i32(obj::TARGET_POSITION, 0)
                } else {
                    self.position_counts()
                };
                self.step(target);
            }
        }
        self.od.pack(inputs);
    }
    fn left_op(&mut self) {
        if self.state == PowerState::OperationEnabled {
            self.state = PowerState::SwitchOnDisabled;
        }
        let fe = 0;
        self.publish(fe);
    }
    fn inject_fault(&mut self, code: u16) {
        self.fault(code);
        self.publish(0);
    }
    fn set_digital_inputs(&mut self, bits: u32) {
        self.sdo_digital_inputs = bits;
        self.od.set(obj::DIGITAL_INPUTS, 0, &bits.to_le_bytes());
    }
    fn set_home_switch(&mut self, at_counts: Option<i32>) {
        self.home_switch_counts = at_counts;
    }
    fn view(&self) -> AppView {
        AppView::Drive(DriveView {
            state: self.state,
            statusword: self.od.u16(obj::STATUSWORD, 0),
            position_counts: self.position_counts(),
            target_counts: self.od.i32(obj::TARGET_POSITION, 0),
            controlword: self.od.u16(obj::CONTROLWORD, 0),
            mode: self.od.i8(obj::MODES_DISPLAY, 0),
            error_code: self.od.u16(obj::ERROR_CODE, 0),
            period_s: self.period_s(),
            targets_received: self.targets_received,
        })
    }
}
