//! A CoE object dictionary (CiA 301 / ETG.1000.6): entries by (index, subindex)
//! with their access, SDO upload and download with CiA 301's abort codes, and the
//! PDO mapping (0x1600/0x1A00 and assignment 0x1C12/0x1C13) packed into and out of
//! the process image.

use std::collections::BTreeMap;

/// SDO abort codes (CiA 301 §7.2.4.3.17).
pub mod abort {
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// The object does not exist.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// The object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const PDO_TOO_LONG: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// Subindex does not exist.
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    /// Value range of parameter exceeded.
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// Data cannot be transferred because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
    /// Command specifier not valid or unknown.
    pub const BAD_COMMAND: u32 = 0x0504_0001;
}

/// Who may write an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Read only.
    Ro,
    /// Read and write in any state.
    Rw,
    /// Writable in PRE-OP only (PDO mapping and assignment).
    RwPreOp,
}

#[derive(Debug, Clone, PartialEq)]
struct Entry {
    data: Vec<u8>,
    access: Access,
    mappable: bool,
}

/// Longest PDO (bytes) a mapping may describe.
pub const MAX_PDO_BYTES: usize = 32;

/// The dictionary.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObjectDictionary {
    entries: BTreeMap<(u16, u8), Entry>,
}

impl ObjectDictionary {
    /// An entry with its initial value (little-endian bytes).
    pub fn insert(&mut self, index: u16, sub: u8, data: &[u8], access: Access, mappable: bool) {
        self.entries.insert(
            (index, sub),
            Entry {
                data: data.to_vec(),
                access,
                mappable,
            },
        );
    }

    /// A record/array: subindex 0 the count (u8, `access`) and the entries.
    pub fn insert_array(&mut self, index: u16, items: &[&[u8]], access: Access) {
        self.insert(index, 0, &[items.len() as u8], access, false);
        for (k, it) in items.iter().enumerate() {
            self.insert(index, k as u8 + 1, it, access, false);
        }
    }

    /// SDO upload: the entry's bytes.
    pub fn upload(&self, index: u16, sub: u8) -> Result<&[u8], u32> {
        match self.entries.get(&(index, sub)) {
            Some(e) => Ok(&e.data),
            None => Err(self.missing(index)),
        }
    }

    fn missing(&self, index: u16) -> u32 {
        if self
            .entries
            .range((index, 0)..=(index, u8::MAX))
            .next()
            .is_some()
        {
            abort::NO_SUBINDEX
        } else {
            abort::NO_OBJECT
        }
    }

    /// SDO download in PRE-OP (`pre_op`) or a later state.
    pub fn download(&mut self, index: u16, sub: u8, data: &[u8], pre_op: bool) -> Result<(), u32> {
        let Some(e) = self.entries.get(&(index, sub)) else {
            return Err(self.missing(index));
        };
        match e.access {
            Access::Ro => return Err(abort::READ_ONLY),
            Access::RwPreOp if !pre_op => return Err(abort::DEVICE_STATE),
            _ => {}
        }
        // an expedited download may carry a shorter size than the entry (u8 into u16)
        let len = e.data.len();
        if data.len() > len && data[len..].iter().any(|&b| b != 0) || data.is_empty() {
            return Err(abort::LENGTH_MISMATCH);
        }
        let mut value = vec![0u8; len];
        let n = data.len().min(len);
        value[..n].copy_from_slice(&data[..n]);
        if is_mapping(index) && sub == 0 {
            self.check_mapping(index, value[0])?;
        }
        if is_assignment(index) && sub == 0 {
            self.check_assignment(index, value[0])?;
        }
        if (is_mapping(index) || is_assignment(index)) && sub > 0 && self.u8(index, 0) != 0 {
            // CiA 301: subindex 0 is written 0 before entries change
            return Err(abort::DEVICE_STATE);
        }
        self.entries.get_mut(&(index, sub)).expect("checked").data = value;
        Ok(())
    }

    fn check_mapping(&self, pdo: u16, count: u8) -> Result<(), u32> {
        let mut bits = 0usize;
        for k in 1..=count {
            let m = self.u32_at(pdo, k).ok_or(abort::VALUE_RANGE)?;
            let (index, sub, len) = ((m >> 16) as u16, (m >> 8) as u8, m as u8);
            let e = self.entries.get(&(index, sub)).ok_or(abort::NOT_MAPPABLE)?;
            if !e.mappable || usize::from(len) != e.data.len() * 8 {
                return Err(abort::NOT_MAPPABLE);
            }
            bits += usize::from(len);
        }
        if bits > MAX_PDO_BYTES * 8 {
            return Err(abort::PDO_TOO_LONG);
        }
        Ok(())
    }

    fn check_assignment(&self, assign: u16, count: u8) -> Result<(), u32> {
        let base = if assign == 0x1C12 { 0x1600 } else { 0x1A00 };
        for k in 1..=count {
            let pdo = self.u16(assign, k);
            if !(base..base + 0x200).contains(&pdo) || !self.entries.contains_key(&(pdo, 0)) {
                return Err(abort::VALUE_RANGE);
            }
        }
        Ok(())
    }

    /// The entries mapped through assignment object `assign` (0x1C12 or 0x1C13), in
    /// process-image order: (index, subindex, bytes).
    pub fn mapped(&self, assign: u16) -> impl Iterator<Item = (u16, u8, usize)> + '_ {
        (1..=self.u8(assign, 0)).flat_map(move |k| {
            let pdo = self.u16(assign, k);
            (1..=self.u8(pdo, 0)).filter_map(move |j| {
                let m = self.u32_at(pdo, j)?;
                Some(((m >> 16) as u16, (m >> 8) as u8, usize::from(m as u8) / 8))
            })
        })
    }

    /// Bytes of the process image through `assign`.
    pub fn mapped_len(&self, assign: u16) -> usize {
        self.mapped(assign).map(|(_, _, n)| n).sum()
    }

    /// The outputs (`image`, through 0x1C12) into their entries.
    pub fn unpack(&mut self, image: &[u8]) {
        let map: Vec<(u16, u8, usize)> = self.mapped(0x1C12).collect();
        let mut at = 0;
        for (index, sub, n) in map {
            if let (Some(e), Some(src)) =
                (self.entries.get_mut(&(index, sub)), image.get(at..at + n))
            {
                e.data.copy_from_slice(src);
            }
            at += n;
        }
    }

    /// The inputs (through 0x1C13) from their entries into `image`.
    pub fn pack(&self, image: &mut [u8]) {
        let mut at = 0;
        for (index, sub, n) in self.mapped(0x1C13) {
            if let (Some(e), Some(dst)) =
                (self.entries.get(&(index, sub)), image.get_mut(at..at + n))
            {
                dst.copy_from_slice(&e.data);
            }
            at += n;
        }
    }

    fn raw(&self, index: u16, sub: u8) -> &[u8] {
        self.entries.get(&(index, sub)).map_or(&[], |e| &e.data)
    }

    fn u32_at(&self, index: u16, sub: u8) -> Option<u32> {
        let d = self.raw(index, sub);
        Some(u32::from_le_bytes(d.get(..4)?.try_into().ok()?))
    }

    /// An entry read as u8 (0 where absent).
    pub fn u8(&self, index: u16, sub: u8) -> u8 {
        self.raw(index, sub).first().copied().unwrap_or(0)
    }
    /// An entry read as u16 (0 where absent).
    pub fn u16(&self, index: u16, sub: u8) -> u16 {
        let d = self.raw(index, sub);
        u16::from_le_bytes([
            d.first().copied().unwrap_or(0),
            d.get(1).copied().unwrap_or(0),
        ])
    }
    /// An entry read as u32 (0 where absent).
    pub fn u32(&self, index: u16, sub: u8) -> u32 {
        self.u32_at(index, sub).unwrap_or(0)
    }
    /// An entry read as i32.
    pub fn i32(&self, index: u16, sub: u8) -> i32 {
        self.u32(index, sub) as i32
    }
    /// An entry read as i8.
    pub fn i8(&self, index: u16, sub: u8) -> i8 {
        self.u8(index, sub) as i8
    }
    /// Sets an entry's value from the device side (any access).
    pub fn set(&mut self, index: u16, sub: u8, data: &[u8]) {
        if let Some(e) = self.entries.get_mut(&(index, sub)) {
            let n = e.data.len().min(data.len());
            e.data[..n].copy_from_slice(&data[..n]);
        }
    }
}

fn is_mapping(index: u16) -> bool {
    (0x1600..0x1800).contains(&index) || (0x1A00..0x1C00).contains(&index)
}

fn is_assignment(index: u16) -> bool {
    index == 0x1C12 || index == 0x1C13
}
