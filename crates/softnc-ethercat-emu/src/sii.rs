//! The SII EEPROM (ETG.1000.6 §5.4, ETG.2010): an image built from a SubDevice's
//! description — identity words, the standard mailbox, and the strings, general,
//! FMMU, sync manager and PDO categories — and the EEPROM interface at 0x0500–0x050F.

use crate::app::{Identity, Layout, PdoDescription, SmUsage};

/// Category types.
const CAT_STRINGS: u16 = 10;
const CAT_GENERAL: u16 = 30;
const CAT_FMMU: u16 = 40;
const CAT_SYNC_MANAGER: u16 = 41;
const CAT_TX_PDO: u16 = 50;
const CAT_RX_PDO: u16 = 51;
const CAT_END: u16 = 0xFFFF;

/// Mailbox protocol word: CoE.
const MAILBOX_PROTOCOL_COE: u16 = 0x0004;
/// CoE details in the general category: SDO, PDO assign, PDO configuration.
const COE_DETAILS: u8 = 0x01 | 0x04 | 0x08;
/// Port descriptor of the general category: ports 0 and 1 MII.
const GENERAL_PORTS: u16 = 0x0011;
/// SII control bit: reads return 8 bytes.
pub const SII_READ_8_BYTES: u16 = 0x0040;
/// SII control command bits.
const SII_COMMAND_MASK: u16 = 0x0700;
const SII_COMMAND_READ: u16 = 0x0100;
/// SII error: command error (bit 13).
const SII_COMMAND_ERROR: u16 = 0x2000;

/// The EEPROM image (bytes, little-endian words) of a SubDevice.
pub fn image(identity: &Identity, layout: &Layout) -> Vec<u8> {
    let mut w = vec![0u16; 0x40];
    w[0x0004] = 0; // configured station alias
    put_u32(&mut w, 0x0008, identity.vendor_id);
    put_u32(&mut w, 0x000A, identity.product_code);
    put_u32(&mut w, 0x000C, identity.revision);
    put_u32(&mut w, 0x000E, identity.serial);
    if let Some(mbx) = layout.mailbox {
        // bootstrap and standard mailbox: the same areas
        w[0x0014] = mbx.out_start;
        w[0x0015] = mbx.out_len;
        w[0x0016] = mbx.in_start;
        w[0x0017] = mbx.in_len;
        w[0x0018] = mbx.out_start;
        w[0x0019] = mbx.out_len;
        w[0x001A] = mbx.in_start;
        w[0x001B] = mbx.in_len;
        w[0x001C] = MAILBOX_PROTOCOL_COE;
    }
    w[0x003E] = 0x000F; // EEPROM size: (15 + 1) KiBit
    w[0x003F] = 0x0001; // version
    let mut bytes: Vec<u8> = w.iter().flat_map(|x| x.to_le_bytes()).collect();

    // strings: 1 = name, then the PDO names
    let mut strings: Vec<&str> = vec![layout.name];
    strings.extend(layout.rx_pdos.iter().map(|p| p.name));
    strings.extend(layout.tx_pdos.iter().map(|p| p.name));
    let mut s = vec![strings.len() as u8];
    for st in &strings {
        s.push(st.len() as u8);
        s.extend_from_slice(st.as_bytes());
    }
    category(&mut bytes, CAT_STRINGS, &s);

    let mut g = vec![0u8; 32];
    // the name is string 1: SOEM reads string 1, ethercrab the order string
    g[2] = 1; // order string index
    g[3] = 1; // name string index
    g[5] = if layout.mailbox.is_some() {
        COE_DETAILS
    } else {
        0
    };
    g[0x0E..0x10].copy_from_slice(&0i16.to_le_bytes()); // e-bus current
    g[0x10..0x12].copy_from_slice(&GENERAL_PORTS.to_le_bytes());
    category(&mut bytes, CAT_GENERAL, &g);

    let mut f: Vec<u8> = layout.fmmus.to_vec();
    if f.len() % 2 == 1 {
        f.push(0xFF);
    }
    category(&mut bytes, CAT_FMMU, &f);

    let mut sm = Vec::new();
    for d in layout.sms {
        sm.extend_from_slice(&d.start.to_le_bytes());
        sm.extend_from_slice(&d.default_len.to_le_bytes());
        sm.push(d.control);
        sm.push(0); // status
        sm.push(1); // enable
        sm.push(match d.usage {
            SmUsage::MailboxOut => 1,
            SmUsage::MailboxIn => 2,
            SmUsage::Outputs => 3,
            SmUsage::Inputs => 4,
        });
    }
    category(&mut bytes, CAT_SYNC_MANAGER, &sm);

    let name_base = 2u8;
    pdo_category(&mut bytes, CAT_RX_PDO, layout.rx_pdos, name_base);
    pdo_category(
        &mut bytes,
        CAT_TX_PDO,
        layout.tx_pdos,
        name_base + layout.rx_pdos.len() as u8,
    );
    bytes.extend_from_slice(&CAT_END.to_le_bytes());
    bytes.extend_from_slice(&[0xFF; 16]);
    bytes
}

fn put_u32(w: &mut [u16], at: usize, v: u32) {
    w[at] = v as u16;
    w[at + 1] = (v >> 16) as u16;
}

fn category(bytes: &mut Vec<u8>, kind: u16, data: &[u8]) {
    let mut data = data.to_vec();
    if data.len() % 2 == 1 {
        data.push(0);
    }
    bytes.extend_from_slice(&kind.to_le_bytes());
    bytes.extend_from_slice(&((data.len() / 2) as u16).to_le_bytes());
    bytes.extend_from_slice(&data);
}

fn pdo_category(bytes: &mut Vec<u8>, kind: u16, pdos: &[PdoDescription], first_name: u8) {
    if pdos.is_empty() {
        return;
    }
    let mut d = Vec::new();
    for (k, p) in pdos.iter().enumerate() {
        d.extend_from_slice(&p.index.to_le_bytes());
        d.push(p.entries.len() as u8);
        d.push(p.sm);
        d.push(0); // synchronisation
        d.push(first_name + k as u8);
        d.extend_from_slice(&0u16.to_le_bytes()); // flags
        for &(index, sub, bits) in p.entries {
            d.extend_from_slice(&index.to_le_bytes());
            d.push(sub);
            d.push(0); // name
            d.push(0); // data type
            d.push(bits);
            d.extend_from_slice(&0u16.to_le_bytes());
        }
    }
    category(bytes, kind, &d);
}

/// The SII interface: executes the command written to 0x0502 against `eeprom`,
/// leaving 8 bytes at 0x0508 and the control word idle; returns the new control
/// word.
pub fn execute(control: u16, word_address: u32, eeprom: &[u8], data: &mut [u8; 8]) -> u16 {
    let idle = SII_READ_8_BYTES | (control & 0x0001);
    match control & SII_COMMAND_MASK {
        0 => idle,
        SII_COMMAND_READ => {
            let at = word_address as usize * 2;
            for (k, d) in data.iter_mut().enumerate() {
                *d = eeprom.get(at + k).copied().unwrap_or(0xFF);
            }
            idle
        }
        // writes and reloads: the image is fixed
        _ => idle | SII_COMMAND_ERROR,
    }
}
