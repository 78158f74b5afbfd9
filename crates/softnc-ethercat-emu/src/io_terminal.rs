//! An 8-in/8-out digital I/O terminal: no mailbox, one output byte on SM0 and one
//! input byte on SM1, its PDOs described in the EEPROM only (as simple terminals
//! are).

use crate::app::{
    AppState, AppView, Application, Identity, Layout, PdoDescription, SmSpec, SmUsage,
};

const SMS: &[SmSpec] = &[
    SmSpec {
        start: 0x0F00,
        default_len: 1,
        control: 0x44,
        usage: SmUsage::Outputs,
    },
    SmSpec {
        start: 0x1000,
        default_len: 1,
        control: 0x00,
        usage: SmUsage::Inputs,
    },
];

const LAYOUT: Layout = Layout {
    name: "softnc emulated 8DI/8DO terminal",
    mailbox: None,
    sms: SMS,
    fmmus: &[1, 2],
    rx_pdos: &[PdoDescription {
        index: 0x1600,
        name: "Outputs",
        sm: 0,
        entries: &[(0x7000, 1, 8)],
    }],
    tx_pdos: &[PdoDescription {
        index: 0x1A00,
        name: "Inputs",
        sm: 1,
        entries: &[(0x6000, 1, 8)],
    }],
};

/// The terminal.
pub struct IoTerminal {
    identity: Identity,
    outputs: u8,
    inputs: u8,
}

impl IoTerminal {
    /// Outputs off, inputs low.
    pub fn new(identity: Identity) -> Self {
        IoTerminal {
            identity,
            outputs: 0,
            inputs: 0,
        }
    }
}

impl Application for IoTerminal {
    fn identity(&self) -> Identity {
        self.identity
    }
    fn layout(&self) -> &Layout {
        &LAYOUT
    }
    fn process_data_len(&self) -> (usize, usize) {
        (1, 1)
    }
    fn cycle(&mut self, _state: AppState, outputs: Option<&[u8]>, inputs: &mut [u8]) {
        if let Some(&[o, ..]) = outputs {
            self.outputs = o;
        }
        if let Some(i) = inputs.first_mut() {
            *i = self.inputs;
        }
    }
    fn left_op(&mut self) {
        self.outputs = 0; // outputs to their safe state
    }
    fn set_digital_inputs(&mut self, bits: u32) {
        self.inputs = bits as u8;
    }
    fn view(&self) -> AppView {
        AppView::Io {
            outputs: self.outputs,
            inputs: self.inputs,
        }
    }
}
