//! EtherCAT frames (ETG.1000.4 §5): the Ethernet header, the EtherCAT header and
//! the datagrams, each passed through the segment's ESCs in order as the frame
//! passes them on the wire, with the working counter and the auto-increment
//! address counted as ESCs do.

use crate::esc::Esc;

/// EtherType of EtherCAT.
pub const ETHERTYPE: u16 = 0x88A4;
/// Ethernet header length.
const ETH_HEADER: usize = 14;
/// EtherCAT frame type: datagrams.
const FRAME_TYPE_DATAGRAMS: u16 = 1;
/// Datagram header length (command, index, address, length, IRQ).
const DATAGRAM_HEADER: usize = 10;
/// Working counter length.
const WKC_LEN: usize = 2;
/// Source MAC bit the first ESC sets on the way back (locally administered).
pub const RETURNED_BIT: u8 = 0x02;

/// Datagram commands (ETG.1000.4 Table 10).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
enum Cmd {
    Nop = 0,
    Aprd = 1,
    Apwr = 2,
    Aprw = 3,
    Fprd = 4,
    Fpwr = 5,
    Fprw = 6,
    Brd = 7,
    Bwr = 8,
    Brw = 9,
    Lrd = 10,
    Lwr = 11,
    Lrw = 12,
    Armw = 13,
    Frmw = 14,
}

impl Cmd {
    fn from_u8(c: u8) -> Option<Cmd> {
        use Cmd::*;
        Some(match c {
            0 => Nop,
            1 => Aprd,
            2 => Apwr,
            3 => Aprw,
            4 => Fprd,
            5 => Fpwr,
            6 => Fprw,
            7 => Brd,
            8 => Bwr,
            9 => Brw,
            10 => Lrd,
            11 => Lwr,
            12 => Lrw,
            13 => Armw,
            14 => Frmw,
            _ => return None,
        })
    }
}

/// Whether `frame` is an EtherCAT frame from a MainDevice (not one already
/// returned by an ESC, which a packet socket also sees leaving).
pub fn is_request(frame: &[u8]) -> bool {
    frame.len() >= ETH_HEADER + 2
        && u16::from_be_bytes([frame[12], frame[13]]) == ETHERTYPE
        && frame[6] & RETURNED_BIT == 0
}

/// Passes `frame` (a whole Ethernet frame) through `escs` at host time `t_ns`,
/// in place. False when it is not a well-formed EtherCAT frame (dropped).
pub fn process(frame: &mut [u8], escs: &mut [Esc], t_ns: u64) -> bool {
    if !is_request(frame) {
        return false;
    }
    let hdr = u16::from_le_bytes([frame[ETH_HEADER], frame[ETH_HEADER + 1]]);
    if hdr >> 12 != FRAME_TYPE_DATAGRAMS {
        return false;
    }
    let end = (ETH_HEADER + 2 + usize::from(hdr & 0x07FF)).min(frame.len());
    for e in escs.iter_mut() {
        e.begin_frame(t_ns);
    }
    let mut at = ETH_HEADER + 2;
    loop {
        if at + DATAGRAM_HEADER + WKC_LEN > end {
            return false;
        }
        let len_field = u16::from_le_bytes([frame[at + 6], frame[at + 7]]);
        let len = usize::from(len_field & 0x07FF);
        let more = len_field & 0x8000 != 0;
        let data_at = at + DATAGRAM_HEADER;
        if data_at + len + WKC_LEN > end {
            return false;
        }
        let (head, rest) = frame[at..].split_at_mut(DATAGRAM_HEADER);
        let (data, tail) = rest.split_at_mut(len);
        let mut wkc = u16::from_le_bytes([tail[0], tail[1]]);
        datagram(head, data, &mut wkc, escs);
        tail[..2].copy_from_slice(&wkc.to_le_bytes());
        at = data_at + len + WKC_LEN;
        if !more {
            break;
        }
    }
    for e in escs.iter_mut() {
        e.end_frame();
    }
    frame[6] |= RETURNED_BIT;
    true
}

fn datagram(head: &mut [u8], data: &mut [u8], wkc: &mut u16, escs: &mut [Esc]) {
    let Some(cmd) = Cmd::from_u8(head[0]) else {
        return;
    };
    let mut adp = u16::from_le_bytes([head[2], head[3]]);
    let ado = u16::from_le_bytes([head[4], head[5]]);
    let logical = u32::from_le_bytes([head[2], head[3], head[4], head[5]]);
    use Cmd::*;
    for esc in escs.iter_mut() {
        let me = match cmd {
            Aprd | Apwr | Aprw | Armw => adp == 0,
            Fprd | Fpwr | Fprw | Frmw => adp == esc.station_address(),
            _ => false,
        };
        match cmd {
            Nop => {}
            Aprd | Fprd if me => count(wkc, 1, esc.read(ado, data)),
            Apwr | Fpwr if me => count(wkc, 1, esc.write(ado, data)),
            Aprw | Fprw if me => {
                let incoming = data.to_vec();
                count(wkc, 1, esc.read(ado, data));
                count(wkc, 2, esc.write(ado, &incoming));
            }
            Brd => {
                let mut mine = vec![0u8; data.len()];
                if esc.read(ado, &mut mine) {
                    data.iter_mut().zip(&mine).for_each(|(d, m)| *d |= m);
                    *wkc += 1;
                }
            }
            Bwr => count(wkc, 1, esc.write(ado, data)),
            Brw => {
                let mut mine = vec![0u8; data.len()];
                let incoming = data.to_vec();
                if esc.read(ado, &mut mine) {
                    data.iter_mut().zip(&mine).for_each(|(d, m)| *d |= m);
                    *wkc += 1;
                }
                count(wkc, 2, esc.write(ado, &incoming));
            }
            Armw | Frmw if me => {
                if ado == crate::regs::DC_SYSTEM_TIME {
                    let t = esc.system_time_bytes();
                    let n = data.len().min(8);
                    data[..n].copy_from_slice(&t[..n]);
                    *wkc += 1;
                } else {
                    count(wkc, 1, esc.read(ado, data));
                }
            }
            Armw | Frmw => count(wkc, 1, esc.write(ado, data)),
            Lrd => {
                let r = esc.read_logical(logical, data);
                count(wkc, 1, r && esc.counts_logical());
            }
            Lwr => {
                let w = esc.write_logical(logical, data);
                count(wkc, 1, w && esc.counts_logical());
            }
            Lrw => {
                let incoming = data.to_vec();
                let w = esc.write_logical(logical, &incoming);
                let r = esc.read_logical(logical, data);
                let counts = !(r || w) || esc.counts_logical();
                count(wkc, 1, r && counts);
                count(wkc, 2, w && counts);
            }
            _ => {}
        }
        if matches!(cmd, Aprd | Apwr | Aprw | Armw | Brd | Bwr | Brw) {
            adp = adp.wrapping_add(1);
        }
    }
    head[2..4].copy_from_slice(&adp.to_le_bytes());
}

fn count(wkc: &mut u16, by: u16, ok: bool) {
    if ok {
        *wkc = wkc.wrapping_add(by);
    }
}
