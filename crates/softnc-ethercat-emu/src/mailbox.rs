//! The mailbox (ETG.1000.4 §5.6) and CoE's SDO service over it (ETG.1000.6 §5.6.2):
//! expedited and normal upload and download, aborts with CiA 301's codes.

use crate::od::{abort, ObjectDictionary};

/// Mailbox header length: length, address, channel/priority, type/counter.
pub const HEADER_LEN: usize = 6;
/// Mailbox type: CoE.
const TYPE_COE: u8 = 0x03;
/// Mailbox type: error reply.
const TYPE_ERROR: u8 = 0x00;
/// CoE services.
const COE_SDO_REQUEST: u16 = 2;
const COE_SDO_RESPONSE: u16 = 3;
/// Mailbox error: service not supported.
const MBX_ERR_UNSUPPORTED_PROTOCOL: u16 = 0x0002;

/// SDO command specifiers (the top three bits of the command byte).
const CCS_DOWNLOAD: u8 = 1;
const CCS_UPLOAD: u8 = 2;
const SCS_UPLOAD: u8 = 2;
const SCS_DOWNLOAD: u8 = 3;
const CS_ABORT: u8 = 4;

/// Answers one mailbox message written by the MainDevice; `None` when there is
/// nothing to answer (an empty or short message). `pre_op`: the device is in
/// PRE-OP (mapping objects writable).
pub fn handle(
    request: &[u8],
    od: &mut ObjectDictionary,
    pre_op: bool,
    counter: &mut u8,
) -> Option<Vec<u8>> {
    if request.len() < HEADER_LEN {
        return None;
    }
    let len = usize::from(u16::from_le_bytes([request[0], request[1]]));
    let kind = request[5] & 0x0F;
    let body = request.get(HEADER_LEN..HEADER_LEN + len)?;
    *counter = if *counter >= 7 { 1 } else { *counter + 1 };
    if kind != TYPE_COE {
        let mut e = MBX_ERR_UNSUPPORTED_PROTOCOL.to_le_bytes().to_vec();
        e.splice(0..0, 0x01u16.to_le_bytes()); // service: error
        return Some(frame(TYPE_ERROR, *counter, &e));
    }
    if body.len() < 10 {
        return None;
    }
    let service = u16::from_le_bytes([body[0], body[1]]) >> 12;
    if service != COE_SDO_REQUEST {
        return None;
    }
    let sdo = &body[2..];
    let cmd = sdo[0];
    let index = u16::from_le_bytes([sdo[1], sdo[2]]);
    let sub = sdo[3];
    let reply = match cmd >> 5 {
        CCS_UPLOAD if cmd & 0x10 == 0 => upload(od, index, sub),
        CCS_DOWNLOAD if cmd & 0x10 == 0 => download(od, index, sub, sdo, pre_op),
        _ => Err(abort::BAD_COMMAND),
    };
    // an abort travels as an SDO request (ETG.1000.6 §5.6.2.7)
    let (service, sdo_reply) = match reply {
        Ok(r) => (COE_SDO_RESPONSE, r),
        Err(code) => {
            let mut r = vec![CS_ABORT << 5];
            r.extend_from_slice(&index.to_le_bytes());
            r.push(sub);
            r.extend_from_slice(&code.to_le_bytes());
            (COE_SDO_REQUEST, r)
        }
    };
    let mut coe = (service << 12).to_le_bytes().to_vec();
    coe.extend_from_slice(&sdo_reply);
    Some(frame(TYPE_COE, *counter, &coe))
}

fn frame(kind: u8, counter: u8, body: &[u8]) -> Vec<u8> {
    let mut f = Vec::with_capacity(HEADER_LEN + body.len());
    f.extend_from_slice(&(body.len() as u16).to_le_bytes());
    f.extend_from_slice(&0u16.to_le_bytes()); // address
    f.push(0); // channel, priority
    f.push(kind | (counter << 4));
    f.extend_from_slice(body);
    f
}

fn upload(od: &ObjectDictionary, index: u16, sub: u8) -> Result<Vec<u8>, u32> {
    let data = od.upload(index, sub)?;
    let mut r = Vec::with_capacity(10 + data.len());
    if data.len() <= 4 {
        // expedited, size indicated: n = 4 − size
        r.push((SCS_UPLOAD << 5) | 0x03 | (((4 - data.len()) as u8) << 2));
        r.extend_from_slice(&index.to_le_bytes());
        r.push(sub);
        let mut d = [0u8; 4];
        d[..data.len()].copy_from_slice(data);
        r.extend_from_slice(&d);
    } else {
        // normal: the complete size, then the data
        r.push((SCS_UPLOAD << 5) | 0x01);
        r.extend_from_slice(&index.to_le_bytes());
        r.push(sub);
        r.extend_from_slice(&(data.len() as u32).to_le_bytes());
        r.extend_from_slice(data);
    }
    Ok(r)
}

fn download(
    od: &mut ObjectDictionary,
    index: u16,
    sub: u8,
    sdo: &[u8],
    pre_op: bool,
) -> Result<Vec<u8>, u32> {
    let cmd = sdo[0];
    let expedited = cmd & 0x02 != 0;
    let size_indicated = cmd & 0x01 != 0;
    let data: &[u8] = if expedited {
        let n = if size_indicated {
            4 - usize::from((cmd >> 2) & 0x03)
        } else {
            4
        };
        &sdo[4..4 + n]
    } else {
        let n = u32::from_le_bytes([sdo[4], sdo[5], sdo[6], sdo[7]]) as usize;
        sdo.get(8..8 + n).ok_or(abort::LENGTH_MISMATCH)?
    };
    od.download(index, sub, data, pre_op)?;
    let mut r = vec![SCS_DOWNLOAD << 5];
    r.extend_from_slice(&index.to_le_bytes());
    r.push(sub);
    r.extend_from_slice(&[0; 4]);
    Ok(r)
}
