//! What sits behind an ESC: the device application (a CiA 402 drive, an I/O
//! terminal) and the description its EEPROM carries.

use crate::od::ObjectDictionary;

/// A SubDevice's identity (the SII words 0x0008–0x000F and object 0x1018).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// Vendor id.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

/// What a sync manager is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmUsage {
    /// Mailbox written by the MainDevice (SM0 of a mailbox device).
    MailboxOut,
    /// Mailbox read by the MainDevice.
    MailboxIn,
    /// Process data outputs (written by the MainDevice).
    Outputs,
    /// Process data inputs.
    Inputs,
}

/// A sync manager as the EEPROM describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SmSpec {
    /// Physical start address.
    pub start: u16,
    /// Length in the EEPROM (process data SMs: the default mapping's).
    pub default_len: u16,
    /// Control byte (mode and direction).
    pub control: u8,
    /// Usage.
    pub usage: SmUsage,
}

/// The standard mailbox areas.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxSpec {
    /// Start of the MainDevice-to-SubDevice mailbox (SM0).
    pub out_start: u16,
    /// Its length.
    pub out_len: u16,
    /// Start of the SubDevice-to-MainDevice mailbox (SM1).
    pub in_start: u16,
    /// Its length.
    pub in_len: u16,
}

/// A PDO as the EEPROM's PDO categories describe it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoDescription {
    /// PDO index (0x1600…, 0x1A00…).
    pub index: u16,
    /// Name.
    pub name: &'static str,
    /// Sync manager it is assigned to.
    pub sm: u8,
    /// Entries: (index, subindex, bit length).
    pub entries: &'static [(u16, u8, u8)],
}

/// The description an ESC's EEPROM is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// Device name (the strings category's first string).
    pub name: &'static str,
    /// Mailbox, where the device has CoE.
    pub mailbox: Option<MailboxSpec>,
    /// Sync managers in order.
    pub sms: &'static [SmSpec],
    /// FMMU usage bytes (1 outputs, 2 inputs, 3 mailbox state).
    pub fmmus: &'static [u8],
    /// Receive PDOs (outputs).
    pub rx_pdos: &'static [PdoDescription],
    /// Transmit PDOs (inputs).
    pub tx_pdos: &'static [PdoDescription],
}

/// The application state an ESC reports to it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppState {
    /// INIT or PRE-OP: no process data.
    NoProcessData,
    /// SAFE-OP: inputs valid, outputs ignored.
    InputsOnly,
    /// OP: outputs applied.
    Operational,
}

/// A device behind an ESC.
pub trait Application: Send {
    /// Identity.
    fn identity(&self) -> Identity;
    /// EEPROM description.
    fn layout(&self) -> &Layout;
    /// The CoE object dictionary (devices with a mailbox).
    fn od(&mut self) -> Option<&mut ObjectDictionary> {
        None
    }
    /// Bytes of outputs and inputs the current mapping has.
    fn process_data_len(&self) -> (usize, usize);
    /// A refusal of PRE-OP → SAFE-OP by the application (AL status code).
    fn check_safe_op(&self) -> Result<(), u16> {
        Ok(())
    }
    /// One process-data cycle: `outputs` as the MainDevice last wrote them
    /// (`None` outside OP), `inputs` to fill.
    fn cycle(&mut self, state: AppState, outputs: Option<&[u8]>, inputs: &mut [u8]);
    /// The ESC left OP (watchdog, a request, an error): outputs no longer apply.
    fn left_op(&mut self) {}
    /// A fault injected by a test (drives: the error code 0x603F).
    fn inject_fault(&mut self, _code: u16) {}
    /// Digital inputs set by a test (drives: 0x60FD; terminals: the input byte).
    fn set_digital_inputs(&mut self, _bits: u32) {}
    /// A home switch on a drive's axis at `at_counts` (active at and beyond it),
    /// or none.
    fn set_home_switch(&mut self, _at_counts: Option<i32>) {}
    /// What a test reads back.
    fn view(&self) -> AppView;
}

/// A snapshot of an application for tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AppView {
    /// A CiA 402 drive.
    Drive(crate::cia402::DriveView),
    /// An I/O terminal: outputs and inputs.
    Io {
        /// Output byte as last written.
        outputs: u8,
        /// Input byte.
        inputs: u8,
    },
}
