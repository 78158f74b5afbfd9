//! Frames built by hand through a segment in memory (no socket, no root): the
//! working counter and auto-increment address, the station address, the SII, and
//! the AL state machine refusing PRE-OP without its mailbox sync managers.

use softnc_ethercat_emu::{segment, wire, DeviceKind};

/// One datagram in an Ethernet frame from a MainDevice.
fn frame(cmd: u8, adp: u16, ado: u16, data: &[u8]) -> Vec<u8> {
    let mut f = vec![0xFF; 6];
    f.extend_from_slice(&[0x10; 6]);
    f.extend_from_slice(&wire::ETHERTYPE.to_be_bytes());
    let len = 10 + data.len() + 2;
    f.extend_from_slice(&((len as u16) | 0x1000).to_le_bytes());
    f.extend_from_slice(&[cmd, 0x42]);
    f.extend_from_slice(&adp.to_le_bytes());
    f.extend_from_slice(&ado.to_le_bytes());
    f.extend_from_slice(&(data.len() as u16).to_le_bytes());
    f.extend_from_slice(&[0, 0]);
    f.extend_from_slice(data);
    f.extend_from_slice(&[0, 0]);
    f
}

fn wkc(f: &[u8]) -> u16 {
    u16::from_le_bytes([f[f.len() - 2], f[f.len() - 1]])
}
fn data(f: &[u8]) -> &[u8] {
    &f[26..f.len() - 2]
}

#[test]
fn datagrams_count_and_address_as_escs_do() {
    let mut escs = segment(&[DeviceKind::Drive, DeviceKind::Drive, DeviceKind::Io]);
    // BRD of the type register: every ESC counts, ADP incremented by each
    let mut f = frame(7, 0, 0x0000, &[0; 2]);
    assert!(wire::process(&mut f, &mut escs, 0));
    assert_eq!(wkc(&f), 3);
    assert_eq!(u16::from_le_bytes([f[18], f[19]]), 3);
    assert_eq!(
        f[6] & wire::RETURNED_BIT,
        wire::RETURNED_BIT,
        "source marked returned"
    );
    assert!(
        !wire::process(&mut f, &mut escs, 0),
        "a returned frame is not a request"
    );
    // APWR station address to the second (ADP = −1)
    let mut f = frame(2, 0xFFFF, 0x0010, &0x1002u16.to_le_bytes());
    wire::process(&mut f, &mut escs, 0);
    assert_eq!(wkc(&f), 1);
    assert_eq!(escs[1].station_address(), 0x1002);
    // SII: read the product code (word 0x000A) through FPWR control + FPRD data
    let mut cmd = 0x0100u16.to_le_bytes().to_vec();
    cmd.extend_from_slice(&0x000Au32.to_le_bytes());
    let mut f = frame(5, 0x1002, 0x0502, &cmd);
    wire::process(&mut f, &mut escs, 0);
    let mut f = frame(4, 0x1002, 0x0508, &[0; 4]);
    wire::process(&mut f, &mut escs, 0);
    assert_eq!(
        u32::from_le_bytes(data(&f).try_into().unwrap()),
        softnc_ethercat_emu::DRIVE_PRODUCT
    );
    // PRE-OP without the mailbox SMs: refused with 0x0016, error indicated
    let mut f = frame(5, 0x1002, 0x0120, &[0x02, 0x00]);
    wire::process(&mut f, &mut escs, 0);
    let mut f = frame(4, 0x1002, 0x0130, &[0; 6]);
    wire::process(&mut f, &mut escs, 0);
    let d = data(&f);
    assert_eq!(d[0], 0x11, "INIT with the error indicator");
    assert_eq!(u16::from_le_bytes([d[4], d[5]]), 0x0016);
    // FPRD of an address nobody has: no one counts
    let mut f = frame(4, 0x7777, 0x0130, &[0; 2]);
    wire::process(&mut f, &mut escs, 0);
    assert_eq!(wkc(&f), 0);
}
