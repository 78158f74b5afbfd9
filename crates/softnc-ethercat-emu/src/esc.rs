//! One emulated EtherCAT SubDevice Controller: its memory (registers and process
//! RAM), and what reads and writes of it do — the AL state machine on AL control,
//! the SII interface, the DC latch and compare, mailbox sync managers, process data
//! through FMMUs — with the device application behind it.

use crate::al::{self, code, AlState, ERROR_BIT};
use crate::app::{AppState, Application, SmUsage};
use crate::dc;
use crate::fmmu::Fmmu;
use crate::mailbox;
use crate::regs::{self, *};
use crate::sii;
use crate::sm::{SyncManager, STATUS_MAILBOX_FULL};
use std::collections::VecDeque;

/// ESC type reported at 0x0000 (the ET1100's register map is the one emulated).
const ESC_TYPE: u8 = 0x11;
/// ESC revision and build.
const ESC_REVISION: u8 = 0x02;
const ESC_BUILD: u16 = 0x0001;
/// FMMUs and sync managers supported.
const FMMUS: u8 = 8;
const SMS: u8 = 8;
/// Process RAM (KiB).
const RAM_KIB: u8 = 4;
/// Ports 0 and 1 MII, 2 and 3 not implemented.
const PORT_DESCRIPTOR_MII01: u8 = 0x0F;
/// Features: DC (bit 2), 64-bit DC (bit 3), enhanced DC SYNC activation (bit 8).
const FEATURES_DC: u16 = 0x010C;
/// PDI control: SPI (no bearing on the emulation).
const PDI_SPI: u8 = 0x05;

/// An emulated ESC with its device.
pub struct Esc {
    position: usize,
    count: usize,
    mem: Vec<u8>,
    eeprom: Vec<u8>,
    state: AlState,
    error: bool,
    app: Box<dyn Application>,
    mbx_pending: VecDeque<Vec<u8>>,
    mbx_counter: u8,
    frame_ns: u64,
    outputs_touched: bool,
    inputs_touched: bool,
    /// SYNC0 events since activation, as of the last frame.
    pub sync0_events: u64,
    /// Frames whose process data this ESC exchanges without counting the
    /// working counter (a fault on demand).
    wkc_skip_frames: u32,
    wkc_skipped: bool,
    /// Added to this ESC's local clock (ns; a step on demand, not re-synced).
    clock_step_ns: u64,
}

impl Esc {
    /// The ESC at `position` (0 first) of a segment of `count`, powered on in INIT.
    pub fn new(app: Box<dyn Application>, position: usize, count: usize) -> Self {
        let eeprom = sii::image(&app.identity(), app.layout());
        let mut esc = Esc {
            position,
            count,
            mem: vec![0; MEMORY_SIZE],
            eeprom,
            state: AlState::Init,
            error: false,
            app,
            mbx_pending: VecDeque::new(),
            mbx_counter: 0,
            frame_ns: 0,
            outputs_touched: false,
            inputs_touched: false,
            sync0_events: 0,
            wkc_skip_frames: 0,
            wkc_skipped: false,
            clock_step_ns: 0,
        };
        esc.power_on();
        esc
    }

    fn power_on(&mut self) {
        self.mem[usize::from(TYPE)] = ESC_TYPE;
        self.mem[usize::from(REVISION)] = ESC_REVISION;
        self.put16(BUILD, ESC_BUILD);
        self.mem[usize::from(FMMU_COUNT)] = FMMUS;
        self.mem[usize::from(SM_COUNT)] = SMS;
        self.mem[usize::from(RAM_SIZE)] = RAM_KIB;
        self.mem[usize::from(PORT_DESCRIPTOR)] = PORT_DESCRIPTOR_MII01;
        self.put16(FEATURES, FEATURES_DC);
        self.put16(DL_STATUS, self.dl_status());
        self.mem[usize::from(PDI_CONTROL)] = PDI_SPI;
        self.put16(SII_CONTROL, sii::SII_READ_8_BYTES);
        self.publish_al();
    }

    /// DL status: PDI operational, port 0 link and communication; port 1 towards the
    /// next ESC, or its loop closed at the last one; ports 2 and 3 closed.
    fn dl_status(&self) -> u16 {
        let mut s = 0x0001 | 0x0010 | 0x0200 | 0x1000 | 0x4000;
        if self.position + 1 < self.count {
            s |= 0x0020 | 0x0800;
        } else {
            s |= 0x0400;
        }
        s
    }

    fn put16(&mut self, addr: u16, v: u16) {
        let a = usize::from(addr);
        self.mem[a..a + 2].copy_from_slice(&v.to_le_bytes());
    }
    fn get16(&self, addr: u16) -> u16 {
        let a = usize::from(addr);
        u16::from_le_bytes([self.mem[a], self.mem[a + 1]])
    }
    fn get32(&self, addr: u16) -> u32 {
        let a = usize::from(addr);
        u32::from_le_bytes(self.mem[a..a + 4].try_into().expect("4 bytes"))
    }
    fn get64(&self, addr: u16) -> u64 {
        let a = usize::from(addr);
        u64::from_le_bytes(self.mem[a..a + 8].try_into().expect("8 bytes"))
    }

    /// Configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        self.get16(STATION_ADDRESS)
    }
    /// The AL state, and the status code when the error indicator is set.
    pub fn al(&self) -> (AlState, Option<u16>) {
        (self.state, self.error.then(|| self.get16(AL_STATUS_CODE)))
    }
    /// The device behind.
    pub fn app(&self) -> &dyn Application {
        self.app.as_ref()
    }
    /// The device behind, mutably (fault injection).
    pub fn app_mut(&mut self) -> &mut dyn Application {
        self.app.as_mut()
    }

    /// A frame reached this ESC at host time `t_ns` (first ESC's port 0).
    pub fn begin_frame(&mut self, t_ns: u64) {
        self.frame_ns = t_ns;
    }

    fn local_ns(&self) -> u64 {
        dc::local_time_port0(self.position, self.frame_ns).wrapping_add(self.clock_step_ns)
    }
    fn system_ns(&self) -> u64 {
        self.local_ns()
            .wrapping_add(self.get64(DC_SYSTEM_TIME_OFFSET))
    }

    /// A physical read of `out.len()` bytes at `ado` (APRD/FPRD/BRD and the read
    /// half of the others); false where the ESC does not count it (an empty mailbox).
    pub fn read(&mut self, ado: u16, out: &mut [u8]) -> bool {
        let (a, b) = (usize::from(ado), usize::from(ado) + out.len());
        if b > MEMORY_SIZE {
            return false;
        }
        self.refresh_before_read(a, b);
        for n in 0..SMS as usize {
            let sm = SyncManager::read(&self.mem, n);
            if sm.is_mailbox()
                && !sm.is_write()
                && sm.overlaps(a, b)
                && self.mem[SyncManager::status_addr(n)] & STATUS_MAILBOX_FULL == 0
            {
                return false;
            }
        }
        out.copy_from_slice(&self.mem[a..b]);
        self.after_read(a, b);
        true
    }

    fn refresh_before_read(&mut self, a: usize, b: usize) {
        let t = usize::from(DC_SYSTEM_TIME);
        if a < t + 8 && b > t {
            let sys = self.system_ns();
            self.mem[t..t + 8].copy_from_slice(&sys.to_le_bytes());
        }
        let s = usize::from(DC_SYNC0_STATUS);
        if (a..b).contains(&s) {
            self.update_sync0();
            self.mem[s] = u8::from(self.sync0_events > 0);
        }
    }

    fn update_sync0(&mut self) {
        let active = self.mem[usize::from(DC_SYNC_ACTIVATION)] & 0x03 == 0x03;
        self.sync0_events = if active {
            dc::sync0_events(
                self.get64(DC_START_TIME),
                self.get32(DC_SYNC0_CYCLE),
                self.system_ns(),
            )
        } else {
            0
        };
    }

    fn after_read(&mut self, a: usize, b: usize) {
        for n in 0..SMS as usize {
            let sm = SyncManager::read(&self.mem, n);
            if sm.is_mailbox() && !sm.is_write() && sm.covers_last(a, b) {
                self.mem[SyncManager::status_addr(n)] &= !STATUS_MAILBOX_FULL;
                self.post_mailbox();
            }
            if !sm.is_mailbox() && !sm.is_write() && sm.overlaps(a, b) {
                self.inputs_touched = true;
            }
        }
    }

    /// A physical write of `data` at `ado`; false where the ESC does not count it (a
    /// full mailbox).
    pub fn write(&mut self, ado: u16, data: &[u8]) -> bool {
        let (a, b) = (usize::from(ado), usize::from(ado) + data.len());
        if b > MEMORY_SIZE {
            return false;
        }
        for n in 0..SMS as usize {
            let sm = SyncManager::read(&self.mem, n);
            if sm.is_mailbox()
                && sm.is_write()
                && sm.overlaps(a, b)
                && self.mem[SyncManager::status_addr(n)] & STATUS_MAILBOX_FULL != 0
            {
                return false;
            }
        }
        for (k, &byte) in data.iter().enumerate() {
            if regs::writable((a + k) as u16) {
                self.mem[a + k] = byte;
            }
        }
        self.after_write(a, b, data);
        true
    }

    fn touches(a: usize, b: usize, reg: u16, len: usize) -> bool {
        a < usize::from(reg) + len && b > usize::from(reg)
    }

    fn after_write(&mut self, a: usize, b: usize, data: &[u8]) {
        if Self::touches(a, b, AL_CONTROL, 2) {
            let control = self.get16(AL_CONTROL);
            self.request_state(control);
        }
        if Self::touches(a, b, SII_CONTROL, 2) {
            self.sii_command();
        }
        if Self::touches(a, b, DC_TIME_PORT0, 4) {
            self.latch_receive_times();
        }
        let t = usize::from(DC_SYSTEM_TIME);
        if a <= t && b >= t + 4 {
            let mut v = [0u8; 8];
            let n = (b - t).min(8);
            v[..n].copy_from_slice(&data[t - a..t - a + n]);
            self.compare_system_time(u64::from_le_bytes(v), n);
        }
        for n in 0..SMS as usize {
            let sm = SyncManager::read(&self.mem, n);
            if sm.is_mailbox() && sm.is_write() && sm.covers_last(a, b) {
                let request = self.mem[sm.range()].to_vec();
                self.mailbox_received(&request);
            }
            if !sm.is_mailbox() && sm.is_write() && sm.overlaps(a, b) {
                self.outputs_touched = true;
            }
        }
    }

    fn sii_command(&mut self) {
        let control = self.get16(SII_CONTROL);
        let addr = self.get32(SII_ADDRESS);
        let mut data = [0u8; 8];
        data.copy_from_slice(&self.mem[usize::from(SII_DATA)..usize::from(SII_DATA) + 8]);
        let idle = sii::execute(control, addr, &self.eeprom, &mut data);
        self.mem[usize::from(SII_DATA)..usize::from(SII_DATA) + 8].copy_from_slice(&data);
        self.put16(SII_CONTROL, idle);
    }

    fn latch_receive_times(&mut self) {
        let p0 = self.local_ns();
        let p1 = if self.position + 1 < self.count {
            dc::local_time_port1(self.position, self.count, self.frame_ns)
                .wrapping_add(self.clock_step_ns) as u32
        } else {
            0
        };
        let at = usize::from(DC_TIME_PORT0);
        self.mem[at..at + 4].copy_from_slice(&(p0 as u32).to_le_bytes());
        self.mem[at + 4..at + 8].copy_from_slice(&p1.to_le_bytes());
        self.mem[at + 8..at + 16].fill(0);
        let r = usize::from(DC_RECEIVE_TIME);
        self.mem[r..r + 8].copy_from_slice(&p0.to_le_bytes());
    }

    fn compare_system_time(&mut self, received: u64, bytes: usize) {
        let delay = u64::from(self.get32(DC_SYSTEM_TIME_DELAY));
        let own = self.system_ns();
        let (own, expect) = if bytes >= 8 {
            (own, received.wrapping_add(delay))
        } else {
            (
                own & 0xFFFF_FFFF,
                (received.wrapping_add(delay)) & 0xFFFF_FFFF,
            )
        };
        let d = dc::difference_register(own, expect);
        let at = usize::from(DC_SYSTEM_TIME_DIFF);
        self.mem[at..at + 4].copy_from_slice(&d.to_le_bytes());
    }

    /// Where this ESC reads its time for a read-multiple-write (the reference clock).
    pub fn system_time_bytes(&mut self) -> [u8; 8] {
        self.system_ns().to_le_bytes()
    }

    fn mailbox_sm(&self, usage: SmUsage) -> Option<(usize, SyncManager)> {
        let n = self
            .app
            .layout()
            .sms
            .iter()
            .position(|s| s.usage == usage)?;
        Some((n, SyncManager::read(&self.mem, n)))
    }

    fn mailbox_received(&mut self, request: &[u8]) {
        let pre_op = self.state == AlState::PreOp;
        let counter = &mut self.mbx_counter;
        let reply = match self.app.od() {
            Some(od) if self.state >= AlState::PreOp => {
                mailbox::handle(request, od, pre_op, counter)
            }
            _ => None,
        };
        if let Some(r) = reply {
            self.mbx_pending.push_back(r);
            self.post_mailbox();
        }
    }

    fn post_mailbox(&mut self) {
        let Some((n, sm)) = self.mailbox_sm(SmUsage::MailboxIn) else {
            return;
        };
        let status = SyncManager::status_addr(n);
        if self.mem[status] & STATUS_MAILBOX_FULL != 0 || !sm.enabled {
            return;
        }
        if let Some(reply) = self.mbx_pending.pop_front() {
            let r = sm.range();
            self.mem[r.clone()].fill(0);
            let n = reply.len().min(r.len());
            self.mem[r.start..r.start + n].copy_from_slice(&reply[..n]);
            self.mem[status] |= STATUS_MAILBOX_FULL;
        }
    }

    /// A logical read through this ESC's read FMMUs; whether any mapped.
    pub fn read_logical(&mut self, logical: u32, data: &mut [u8]) -> bool {
        let mut hit = false;
        for n in 0..FMMUS as usize {
            let f = Fmmu::read(&self.mem, n);
            if !f.reads() {
                continue;
            }
            if let Some((off, phys, len)) = f.overlap(logical, data.len()) {
                if phys + len <= MEMORY_SIZE {
                    data[off..off + len].copy_from_slice(&self.mem[phys..phys + len]);
                    self.after_read(phys, phys + len);
                    hit = true;
                }
            }
        }
        hit
    }

    /// A logical write through this ESC's write FMMUs; whether any mapped.
    pub fn write_logical(&mut self, logical: u32, data: &[u8]) -> bool {
        let mut hit = false;
        for n in 0..FMMUS as usize {
            let f = Fmmu::read(&self.mem, n);
            if !f.writes() {
                continue;
            }
            if let Some((off, phys, len)) = f.overlap(logical, data.len()) {
                if phys + len <= MEMORY_SIZE {
                    self.mem[phys..phys + len].copy_from_slice(&data[off..off + len]);
                    self.after_write(phys, phys + len, &data[off..off + len]);
                    hit = true;
                }
            }
        }
        hit
    }

    fn publish_al(&mut self) {
        let status = self.state as u16 | if self.error { u16::from(ERROR_BIT) } else { 0 };
        self.put16(AL_STATUS, status);
        if !self.error {
            self.put16(AL_STATUS_CODE, code::NONE);
        }
    }

    /// Enters `state` with the error indicator and `status_code` (a refused
    /// transition, a watchdog, a test's "leave OP").
    pub fn fail(&mut self, state: AlState, status_code: u16) {
        if self.state == AlState::Op && state < AlState::Op {
            self.app.left_op();
        }
        self.state = state;
        self.error = true;
        self.put16(AL_STATUS_CODE, status_code);
        self.publish_al();
    }

    fn request_state(&mut self, control: u16) {
        let ack = control as u8 & ERROR_BIT != 0;
        let Some(to) = AlState::from_nibble(control as u8 & 0x0F) else {
            self.fail(self.state, code::UNKNOWN_STATE);
            return;
        };
        if self.error && !ack && to > self.state {
            return; // an error stays until acknowledged
        }
        if ack {
            self.error = false;
        }
        if let Err(c) = al::allowed(self.state, to).and_then(|()| self.check_transition(to)) {
            self.fail(self.state, c);
            return;
        }
        if self.state == AlState::Op && to < AlState::Op {
            self.app.left_op();
        }
        if to == AlState::Init {
            self.mbx_pending.clear();
        }
        self.state = to;
        self.publish_al();
        if to >= AlState::SafeOp {
            self.inputs_touched = true;
            self.cycle_process_data(false);
        }
    }

    fn check_transition(&self, to: AlState) -> Result<(), u16> {
        let layout = self.app.layout();
        if to >= AlState::PreOp && self.state < AlState::PreOp {
            if let Some(mbx) = layout.mailbox {
                for (n, spec) in layout.sms.iter().enumerate() {
                    let len = match spec.usage {
                        SmUsage::MailboxOut => mbx.out_len,
                        SmUsage::MailboxIn => mbx.in_len,
                        _ => continue,
                    };
                    if !SyncManager::read(&self.mem, n).matches(spec.start, len, spec.control) {
                        return Err(code::INVALID_MAILBOX);
                    }
                }
            }
        }
        if to >= AlState::SafeOp && self.state < AlState::SafeOp {
            let (out_len, in_len) = self.app.process_data_len();
            for (n, spec) in layout.sms.iter().enumerate() {
                let (len, err) = match spec.usage {
                    SmUsage::Outputs => (out_len, code::INVALID_OUTPUTS),
                    SmUsage::Inputs => (in_len, code::INVALID_INPUTS),
                    _ => continue,
                };
                let sm = SyncManager::read(&self.mem, n);
                if len > 0 && !sm.matches(spec.start, len as u16, spec.control) {
                    return Err(err);
                }
            }
            self.app.check_safe_op()?;
        }
        Ok(())
    }

    /// The end of a frame: where process data was exchanged in SAFE-OP or OP, the
    /// device runs one cycle (outputs applied in OP) and its inputs are refreshed.
    /// The next `frames` frames' process data exchanged without counting the
    /// working counter.
    pub fn skip_working_counter(&mut self, frames: u32) {
        self.wkc_skip_frames += frames;
    }

    /// This ESC's local clock steps `ns` ahead (its system time offset is not
    /// re-written: the step shows in its system time difference, 0x092C).
    pub fn step_clock(&mut self, ns: u64) {
        self.clock_step_ns = self.clock_step_ns.wrapping_add(ns);
    }

    /// Whether a logical access that reached this ESC counts in the working
    /// counter (not while a skip is asked for).
    pub fn counts_logical(&mut self) -> bool {
        if self.wkc_skip_frames > 0 {
            self.wkc_skipped = true;
            return false;
        }
        true
    }

    pub fn end_frame(&mut self) {
        if std::mem::take(&mut self.wkc_skipped) {
            self.wkc_skip_frames -= 1;
        }
        if self.outputs_touched || self.inputs_touched {
            self.update_sync0();
            self.cycle_process_data(true);
        }
        self.outputs_touched = false;
        self.inputs_touched = false;
    }

    fn pd_range(&self, usage: SmUsage) -> Option<std::ops::Range<usize>> {
        let n = self
            .app
            .layout()
            .sms
            .iter()
            .position(|s| s.usage == usage)?;
        let sm = SyncManager::read(&self.mem, n);
        (sm.enabled && sm.len > 0).then(|| sm.range())
    }

    fn cycle_process_data(&mut self, step: bool) {
        if self.state < AlState::SafeOp {
            return;
        }
        let state = if self.state == AlState::Op {
            AppState::Operational
        } else {
            AppState::InputsOnly
        };
        let outputs = match (state, self.pd_range(SmUsage::Outputs)) {
            (AppState::Operational, Some(r)) if self.outputs_touched => Some(self.mem[r].to_vec()),
            _ => None,
        };
        let mut inputs = vec![0u8; self.pd_range(SmUsage::Inputs).map_or(0, |r| r.len())];
        if step {
            self.app.cycle(state, outputs.as_deref(), &mut inputs);
        } else {
            self.app.cycle(AppState::NoProcessData, None, &mut inputs);
        }
        if let Some(r) = self.pd_range(SmUsage::Inputs) {
            self.mem[r].copy_from_slice(&inputs);
        }
    }
}
