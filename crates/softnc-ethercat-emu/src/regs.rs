//! ESC register addresses (ETG.1000.4 / the Beckhoff ESC datasheet, section II) and
//! which of them the EtherCAT side may write.

/// ESC type (u8).
pub const TYPE: u16 = 0x0000;
/// ESC revision (u8).
pub const REVISION: u16 = 0x0001;
/// ESC build (u16).
pub const BUILD: u16 = 0x0002;
/// FMMUs supported (u8).
pub const FMMU_COUNT: u16 = 0x0004;
/// Sync managers supported (u8).
pub const SM_COUNT: u16 = 0x0005;
/// Process RAM size in KiB (u8).
pub const RAM_SIZE: u16 = 0x0006;
/// Port descriptor (u8): two bits per port.
pub const PORT_DESCRIPTOR: u16 = 0x0007;
/// ESC features supported (u16): bit 2 DC, bit 3 64-bit DC.
pub const FEATURES: u16 = 0x0008;
/// Configured station address (u16).
pub const STATION_ADDRESS: u16 = 0x0010;
/// Configured station alias (u16).
pub const STATION_ALIAS: u16 = 0x0012;
/// DL control (u32).
pub const DL_CONTROL: u16 = 0x0100;
/// DL status (u16).
pub const DL_STATUS: u16 = 0x0110;
/// AL control (u16).
pub const AL_CONTROL: u16 = 0x0120;
/// AL status (u16).
pub const AL_STATUS: u16 = 0x0130;
/// AL status code (u16).
pub const AL_STATUS_CODE: u16 = 0x0134;
/// PDI control (u8).
pub const PDI_CONTROL: u16 = 0x0140;
/// SII EEPROM configuration (u8) and PDI access state (u8).
pub const SII_CONFIG: u16 = 0x0500;
/// SII control/status (u16).
pub const SII_CONTROL: u16 = 0x0502;
/// SII address, in words (u32).
pub const SII_ADDRESS: u16 = 0x0504;
/// SII data (8 bytes read at once).
pub const SII_DATA: u16 = 0x0508;
/// FMMU 0; each FMMU is 16 bytes.
pub const FMMU_BASE: u16 = 0x0600;
/// Sync manager 0; each is 8 bytes.
pub const SM_BASE: u16 = 0x0800;
/// DC receive time port 0 (u32); a write latches the receive times of all ports.
pub const DC_TIME_PORT0: u16 = 0x0900;
/// DC system time (u64): read the local copy; write compares (time control loop).
pub const DC_SYSTEM_TIME: u16 = 0x0910;
/// DC receive time of the processing unit, local time (u64).
pub const DC_RECEIVE_TIME: u16 = 0x0918;
/// DC system time offset (u64).
pub const DC_SYSTEM_TIME_OFFSET: u16 = 0x0920;
/// DC system time transmission delay (u32).
pub const DC_SYSTEM_TIME_DELAY: u16 = 0x0928;
/// DC system time difference (u32, sign in bit 31).
pub const DC_SYSTEM_TIME_DIFF: u16 = 0x092C;
/// DC SYNC activation (u8): bit 0 cyclic operation, bit 1 SYNC0, bit 2 SYNC1.
pub const DC_SYNC_ACTIVATION: u16 = 0x0981;
/// DC SYNC0 status (u8).
pub const DC_SYNC0_STATUS: u16 = 0x098E;
/// DC start time of cyclic operation (u64, system time).
pub const DC_START_TIME: u16 = 0x0990;
/// DC SYNC0 cycle time (u32, ns).
pub const DC_SYNC0_CYCLE: u16 = 0x09A0;
/// DC SYNC1 cycle time (u32, ns).
pub const DC_SYNC1_CYCLE: u16 = 0x09A4;
/// The first byte of process RAM.
pub const PROCESS_RAM: u16 = 0x1000;
/// Bytes of ESC memory emulated: registers and 4 KiB of process RAM.
pub const MEMORY_SIZE: usize = 0x2000;

/// Whether the EtherCAT side may write the byte at `addr` (read-only registers and
/// the DC system time, whose writes are compares, are not stored).
pub fn writable(addr: u16) -> bool {
    match addr {
        0x0010..=0x0013 => true,                       // station address and alias
        0x0100..=0x0103 => true,                       // DL control
        0x0120..=0x0121 => true,                       // AL control
        0x0200..=0x0203 => true,                       // ECAT event mask
        0x0300..=0x0313 => true,                       // error counters (a write clears)
        0x0400..=0x0443 => true,                       // watchdogs
        0x0500..=0x050F => true,                       // SII
        0x0600..=0x06FF => true,                       // FMMUs
        0x0800..=0x087F => !matches!(addr % 8, 5 | 7), // SMs: status and PDI control are read-only
        0x0900..=0x0903 => true,                       // latch trigger (not stored, see esc)
        0x0920..=0x092B => true,                       // offset, delay
        0x0930..=0x0935 => true,                       // speed counter, filter depths
        0x0980..=0x0981 => true,                       // cyclic unit, activation
        0x0990..=0x0997 => true,                       // start time
        0x09A0..=0x09A7 => true,                       // SYNC0/SYNC1 cycle
        0x1000.. => (addr as usize) < MEMORY_SIZE,
        _ => false,
    }
}
