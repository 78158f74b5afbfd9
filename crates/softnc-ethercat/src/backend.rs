//! `EtherCatBackend`: `ServoBackend` over CiA 402 drives in CSP on an EtherCAT bus
//! (docs/architecture.md, "A real drive"; docs/ethercat.md).

use crate::bus::{self, Group, OpenError};
use crate::cia402::{self, cw, Inputs};
use crate::config::{EtherCatConfig, ExpectedSubDevice, Role};
use crate::exec::block_on;
use ethercrab::{MainDevice, SubDeviceState};
use softnc_core::Axes;
use softnc_servo::io::RAW_DIGITAL_LINES;
use softnc_servo::{
    AxisStatus, BackendError, BusFault, CommandMode, IfName, IoLines, Positions, RawInputs,
    RawOutputs, ServoBackend, MAX_AXES,
};
use std::time::{Duration, Instant};

/// Cycles a CiA 402 step of `enable`/`disable` may take.
const STATE_CYCLES: usize = 200;
/// Frames lost in a row after which `recover` gives up (the cause still there).
const RECOVER_LOST_IN_ROW: u32 = 3;
/// Frames lost in a row after which a faulted bus is left silent until a reset.
const FAULTED_LOST_IN_ROW: u32 = 2;
/// Round-trip histogram: bucket width and count (10 µs × 1000 = 10 ms).
const RTT_BUCKET_NS: u64 = 10_000;
const RTT_BUCKETS: usize = 1000;
/// Frames between two reads of a DC SubDevice's system time difference (each
/// read an extra frame on that cycle: one SubDevice a read, in turn).
const DC_READ_EVERY_FRAMES: u64 = 250;
/// ESC register: DC system time difference (u32, |local − received| in bits
/// 0–30, bit 31 set when the local copy is the smaller).
const DC_SYSTEM_TIME_DIFF: u16 = 0x092C;
/// The magnitude bits of [`DC_SYSTEM_TIME_DIFF`].
const DC_DIFF_MAGNITUDE: u32 = 0x7FFF_FFFF;

/// A bit of a SubDevice's digital inputs or outputs on a raw line (the cycle's
/// table, fixed-size).
#[derive(Debug, Clone, Copy, Default)]
struct Wire {
    position: u8,
    bit: u8,
    line: u8,
}

/// Bits wired to lines, at most (in each direction).
const MAX_WIRES: usize = RAW_DIGITAL_LINES;

/// Where a SubDevice's digital inputs and outputs start in its process data
/// (bytes): a drive's 0x60FD and 0x60FE as its mapping lays them out, a
/// terminal's from its first byte.
fn digital_offsets(s: &ExpectedSubDevice) -> (usize, usize) {
    match s.role {
        Role::Drive { .. } => {
            let l = cia402::Layout::of(&s.pdo.clone().unwrap_or_default());
            (
                l.digital_inputs.unwrap_or(0),
                l.digital_outputs.unwrap_or(0),
            )
        }
        Role::Io => (0, 0),
    }
}

/// The SubDevices' digital bits on raw lines: fixed-size tables, made from the
/// configuration, read and written on the cycle without allocating.
struct Wiring {
    in_wires: Box<[Wire; MAX_WIRES]>,
    in_count: usize,
    out_wires: Box<[Wire; MAX_WIRES]>,
    out_count: usize,
    /// Each SubDevice's (inputs, outputs) digital offsets in its process data.
    digital_at: [(usize, usize); bus::MAX_SUBDEVICES],
    /// Bit p: the SubDevice at p is a terminal (its output bytes rewritten whole).
    terminals: u32,
    lines: IoLines,
}

impl Wiring {
    /// The tables of `config` (checked).
    fn of(config: &EtherCatConfig) -> Result<Self, OpenError> {
        let mut in_wires = Box::new([Wire::default(); MAX_WIRES]);
        let mut out_wires = Box::new([Wire::default(); MAX_WIRES]);
        let (mut in_count, mut out_count) = (0, 0);
        let mut digital_at = [(0, 0); bus::MAX_SUBDEVICES];
        let mut lines = IoLines::NONE;
        if config.subdevices.len() > bus::MAX_SUBDEVICES {
            return Err(OpenError::Config(format!(
                "{} SubDevices, at most {}",
                config.subdevices.len(),
                bus::MAX_SUBDEVICES
            )));
        }
        crate::config::check_wiring(&config.subdevices)
            .map_err(|(path, reason)| OpenError::Config(format!("{path}: {reason}")))?;
        for (position, s) in config.subdevices.iter().enumerate() {
            digital_at[position] = digital_offsets(s);
            for w in &s.inputs {
                in_wires[in_count] = Wire {
                    position: position as u8,
                    bit: w.bit,
                    line: w.line,
                };
                in_count += 1;
                lines.digital_in = lines.digital_in.max(usize::from(w.line) + 1);
            }
            for w in &s.outputs {
                out_wires[out_count] = Wire {
                    position: position as u8,
                    bit: w.bit,
                    line: w.line,
                };
                out_count += 1;
                lines.digital_out = lines.digital_out.max(usize::from(w.line) + 1);
            }
        }
        let mut terminals = 0;
        for (p, s) in config.subdevices.iter().enumerate() {
            if s.role == Role::Io {
                terminals |= 1 << p;
            }
        }
        Ok(Wiring {
            in_wires,
            in_count,
            out_wires,
            out_count,
            digital_at,
            terminals,
            lines,
        })
    }

    /// The raw output lines onto their SubDevices' bits.
    fn put_outputs(&self, group: &Group, md: &MainDevice<'_>, raw_out: u128) {
        // the raw output lines onto their SubDevices' bits (a terminal's byte
        // rewritten whole: the bits not wired stay 0)
        for (p, &(_, at)) in self.digital_at.iter().enumerate().take(group.len()) {
            if self.terminals >> p & 1 == 1 {
                if let Ok(s) = group.subdevice(md, p) {
                    s.outputs_raw_mut()
                        .get_mut(at..)
                        .into_iter()
                        .flatten()
                        .for_each(|b| *b = 0);
                }
            }
        }
        for w in &self.out_wires[..self.out_count] {
            let p = usize::from(w.position);
            if let Ok(s) = group.subdevice(md, p) {
                let at = self.digital_at[p].1 + usize::from(w.bit / 8);
                if let Some(b) = s.outputs_raw_mut().get_mut(at) {
                    let mask = 1u8 << (w.bit % 8);
                    if raw_out >> w.line & 1 == 1 {
                        *b |= mask;
                    } else {
                        *b &= !mask;
                    }
                }
            }
        }
    }

    /// The raw input lines from their SubDevices' bits.
    fn get_inputs(&self, group: &Group, md: &MainDevice<'_>) -> u128 {
        let mut raw_in = 0u128;
        for w in &self.in_wires[..self.in_count] {
            let p = usize::from(w.position);
            if let Ok(s) = group.subdevice(md, p) {
                let at = self.digital_at[p].0 + usize::from(w.bit / 8);
                if s.inputs_raw()
                    .get(at)
                    .is_some_and(|b| b >> (w.bit % 8) & 1 == 1)
                {
                    raw_in |= 1u128 << w.line;
                }
            }
        }
        raw_in
    }
}

#[derive(Debug, Clone, Copy)]
struct Drive {
    position: usize,
    layout: cia402::Layout,
    counts_per_mm: f64,
    direction: f64,
    offset_counts: f64,
    inputs: Inputs,
    controlword: u16,
    target: i32,
}

/// Bus figures since open (the servo boundary's, [`softnc_servo::BusStats`]).
pub use softnc_servo::BusStats;

/// The bus once brought up.
struct Bus {
    md: &'static MainDevice<'static>,
    group: Group,
    expected_wkc: u16,
    /// Each SubDevice's share of the working counter.
    wkc_share: [u16; bus::MAX_SUBDEVICES],
    /// Every SubDevice on the bus.
    all: Positions,
    /// The DC SubDevices that compare their clock with the reference's (every
    /// DC one after the first, ethercrab's reference clock), `dc_count` of them.
    dc_positions: [u8; bus::MAX_SUBDEVICES],
    dc_count: usize,
    /// Declared after the group: dropped after it (the group is never used with
    /// the MainDevice's next bring-up).
    _master: bus::Master,
}

/// CiA 402 drives on EtherCAT: a handle made from the configuration, the bus
/// brought up by the first `enable` or `disable` (as docs/architecture.md's "A
/// real drive" asks of a drive's factory: the running drive is the one enabled).
pub struct EtherCatBackend {
    config: EtherCatConfig,
    bus: Option<Bus>,
    pending_home_mm: Option<Axes<f64>>,
    last_open_error: Option<OpenError>,
    cycle: Duration,
    response_timeout: Duration,
    drives: [Option<Drive>; MAX_AXES],
    axes: usize,
    axis_of: [Option<u8>; bus::MAX_SUBDEVICES],
    enabled: bool,
    /// A bus fault was reported and not yet recovered from (`recover`, `enable`).
    faulted: bool,
    /// Frames lost in a row (two end the frames of a faulted bus).
    lost_in_row: u32,
    stats: BusStats,
    rtt: Box<[u32; RTT_BUCKETS]>,
    /// SubDevice bits on raw lines.
    wiring: Wiring,
    /// The bus's interface (for its faults' alarms).
    iface: IfName,
    raw_in: u128,
    raw_out: u128,
    /// The next of the DC SubDevices whose system time difference is read.
    dc_next: usize,
}

impl EtherCatBackend {
    /// The handle and the bus brought up to OP as `config` says (off the cycle
    /// path; seconds).
    pub fn open(config: &EtherCatConfig) -> Result<Self, OpenError> {
        let mut b = Self::new(config)?;
        b.open_bus()?;
        Ok(b)
    }

    /// The handle, the configuration checked; the bus is not touched.
    pub fn new(config: &EtherCatConfig) -> Result<Self, OpenError> {
        let mut drives: [Option<Drive>; MAX_AXES] = [None; MAX_AXES];
        let mut axis_of = [None; bus::MAX_SUBDEVICES];
        for (position, s) in config.subdevices.iter().enumerate() {
            if let Role::Drive {
                axis,
                counts_per_mm,
                direction,
                ..
            } = s.role
            {
                let slot = drives
                    .get_mut(usize::from(axis))
                    .ok_or_else(|| OpenError::Config(format!("axis {axis} beyond {MAX_AXES}")))?;
                if slot.is_some()
                    || counts_per_mm.is_nan()
                    || counts_per_mm <= 0.0
                    || direction.abs() != 1
                {
                    return Err(OpenError::Config(format!(
                        "SubDevice {position}: axis {axis} twice, or counts/direction"
                    )));
                }
                *slot = Some(Drive {
                    position,
                    layout: cia402::Layout::of(&s.pdo.clone().unwrap_or_default()),
                    counts_per_mm,
                    direction: f64::from(direction),
                    offset_counts: 0.0,
                    inputs: Inputs::default(),
                    controlword: cw::DISABLE_VOLTAGE,
                    target: 0,
                });
                if let Some(a) = axis_of.get_mut(position) {
                    *a = Some(axis);
                }
            }
        }
        let wiring = Wiring::of(config)?;
        let axes = drives.iter().take_while(|d| d.is_some()).count();
        if axes == 0 || drives.iter().skip(axes).any(Option::is_some) {
            return Err(OpenError::Config(
                "drives must serve axes 0, 1, … without a gap".into(),
            ));
        }
        Ok(EtherCatBackend {
            config: config.clone(),
            bus: None,
            pending_home_mm: None,
            last_open_error: None,
            cycle: config.cycle,
            response_timeout: config.response_timeout,
            drives,
            axes,
            axis_of,
            enabled: false,
            faulted: false,
            lost_in_row: 0,
            stats: BusStats::default(),
            rtt: Box::new([0; RTT_BUCKETS]),
            wiring,
            iface: IfName::new(&config.interface),
            raw_in: 0,
            raw_out: 0,
            dc_next: 0,
        })
    }

    /// Brings the bus up to OP, where it is not yet (off the cycle path).
    pub fn open_bus(&mut self) -> Result<(), OpenError> {
        if self.bus.is_some() {
            return Ok(());
        }
        let (master, group) = bus::bring_up(&self.config)?;
        let md = master.md();
        // every wired bit within its SubDevice's process data
        let wiring = &self.wiring;
        for (wires, count, outputs) in [
            (&wiring.in_wires, wiring.in_count, false),
            (&wiring.out_wires, wiring.out_count, true),
        ] {
            for w in &wires[..count] {
                let p = usize::from(w.position);
                let s = group
                    .subdevice(md, p)
                    .map_err(bus::bus_err("process data"))?;
                let (len, at) = if outputs {
                    (s.outputs_raw().len(), wiring.digital_at[p].1)
                } else {
                    (s.inputs_raw().len(), wiring.digital_at[p].0)
                };
                if at + usize::from(w.bit) / 8 >= len {
                    return Err(OpenError::Config(format!(
                        "subdevices[{p}].{}: bit {} beyond its {len} byte(s) of process data",
                        if outputs { "outputs" } else { "inputs" },
                        w.bit
                    )));
                }
            }
        }
        // each drive's process data as its mapping gives
        for d in self.drives.iter().flatten() {
            let s = group
                .subdevice(md, d.position)
                .map_err(bus::bus_err("process data"))?;
            let (rx, tx) = (s.outputs_raw().len(), s.inputs_raw().len());
            if (rx, tx) != (d.layout.rx_bytes, d.layout.tx_bytes) {
                return Err(OpenError::Config(format!(
                    "SubDevice {}: {rx} output and {tx} input bytes of process data, the mapping gives {} and {}",
                    d.position, d.layout.rx_bytes, d.layout.tx_bytes
                )));
            }
        }
        let mut expected_wkc = 0;
        let mut wkc_share = [0; bus::MAX_SUBDEVICES];
        for (share, s) in wkc_share.iter_mut().zip(group.iter(md)) {
            *share =
                2 * u16::from(!s.outputs_raw().is_empty()) + u16::from(!s.inputs_raw().is_empty());
            expected_wkc += *share;
        }
        let all = Positions((1u32 << group.len()) - 1);
        let mut dc_positions = [0u8; bus::MAX_SUBDEVICES];
        let mut dc_count = 0;
        for (p, s) in group
            .iter(md)
            .enumerate()
            .filter(|(_, s)| s.dc_support().any())
            .skip(1)
        {
            if s.dc_support().enhanced() {
                dc_positions[dc_count] = p as u8;
                dc_count += 1;
            }
        }
        self.bus = Some(Bus {
            md,
            group,
            expected_wkc,
            wkc_share,
            all,
            dc_positions,
            dc_count,
            _master: master,
        });
        // the first inputs, so that `home` and `read_counts` see the drives
        self.exchange().map_err(|e| OpenError::Bus {
            step: "first cycle",
            reason: e.to_string(),
        })?;
        for d in self.drives.iter_mut().flatten() {
            d.target = d.inputs.position;
        }
        if let Some(h) = self.pending_home_mm.take() {
            self.home(h);
        }
        Ok(())
    }

    /// Why the last bring-up failed (`enable` reports it only as
    /// [`BusFault::NotOpen`]).
    pub fn last_open_error(&self) -> Option<&OpenError> {
        self.last_open_error.as_ref()
    }

    fn ensure_open(&mut self) -> Result<(), BackendError> {
        match self.open_bus() {
            Ok(()) => Ok(()),
            Err(e) => {
                let subdevice = match e {
                    OpenError::IdentityMismatch { position, .. }
                    | OpenError::Sdo { position, .. } => Some(position as u16),
                    _ => None,
                };
                tracing::error!("EtherCAT bring-up: {e}");
                self.last_open_error = Some(e);
                Err(BackendError::Bus {
                    subdevice,
                    axis: None,
                    reason: BusFault::NotOpen,
                })
            }
        }
    }

    /// Bus figures since open.
    pub fn bus_stats(&self) -> BusStats {
        let total: u64 = self.rtt.iter().map(|&c| u64::from(c)).sum();
        let quantile = |q: f64| {
            let want = (q * total as f64).ceil() as u64;
            let mut seen = 0;
            for (k, &c) in self.rtt.iter().enumerate() {
                seen += u64::from(c);
                if seen >= want.max(1) {
                    return (k as u64 + 1) * RTT_BUCKET_NS;
                }
            }
            0
        };
        BusStats {
            rtt_p50_ns: quantile(0.5),
            rtt_p99_ns: quantile(0.99),
            ..self.stats
        }
    }

    fn fault(&mut self, subdevice: Option<usize>, reason: BusFault) -> BackendError {
        // the E-stop path: every drive quick-stops at the next frame that gets through
        for d in self.drives.iter_mut().flatten() {
            d.controlword = cw::QUICK_STOP;
        }
        self.enabled = false;
        self.faulted = true;
        BackendError::Bus {
            subdevice: subdevice.map(|p| p as u16),
            axis: subdevice.and_then(|p| self.axis_of.get(p).copied().flatten()),
            reason,
        }
    }

    fn exchange(&mut self) -> Result<(), BackendError> {
        match self.exchange_frame() {
            Ok(()) => {
                self.read_dc_deviation();
                Ok(())
            }
            Err((subdevice, reason)) => Err(self.fault(subdevice, reason)),
        }
    }

    /// Every [`DC_READ_EVERY_FRAMES`] frames, one DC SubDevice's system time
    /// difference (0x092C, updated by each cycle's system time distribution): an
    /// FPRD frame of its own, its wait bounded by the response timeout. A read
    /// that does not answer is left out of the figures (not a bus fault: the
    /// cycle's frame came through).
    fn read_dc_deviation(&mut self) {
        let Some(bus) = self.bus.as_ref() else {
            return;
        };
        if bus.dc_count == 0 || !self.stats.frames.is_multiple_of(DC_READ_EVERY_FRAMES) {
            return;
        }
        let p = usize::from(bus.dc_positions[self.dc_next % bus.dc_count]);
        self.dc_next = self.dc_next.wrapping_add(1);
        let Ok(s) = bus.group.subdevice(bus.md, p) else {
            return;
        };
        let r = block_on(
            s.register_read::<u32>(DC_SYSTEM_TIME_DIFF),
            Instant::now() + self.response_timeout,
        );
        if let Some(Ok(diff)) = r {
            let ns = u64::from(diff & DC_DIFF_MAGNITUDE);
            self.stats.dc_reads += 1;
            self.stats.dc_deviation_last_ns = ns;
            self.stats.dc_deviation_max_ns = self.stats.dc_deviation_max_ns.max(ns);
        }
    }

    /// One process-data frame: outputs written, the frame exchanged (bounded),
    /// the working counter and every SubDevice's AL state checked, inputs read.
    fn exchange_frame(&mut self) -> Result<(), (Option<usize>, BusFault)> {
        let Some(bus) = self.bus.as_ref() else {
            return Err((None, BusFault::NotOpen));
        };
        let (md, group, expected) = (bus.md, &bus.group, bus.expected_wkc);
        for d in self.drives.iter().flatten() {
            if let Ok(s) = group.subdevice(md, d.position) {
                cia402::write_outputs(&mut s.outputs_raw_mut(), &d.layout, d.controlword, d.target);
            }
        }
        self.wiring.put_outputs(group, md, self.raw_out);
        let t0 = Instant::now();
        // the wait is bounded here: at the deadline the future is dropped, which
        // gives its frame back to ethercrab (a late answer is then ignored)
        let r = block_on(group.tx_rx_dc(md), t0 + self.response_timeout);
        let rtt = t0.elapsed().as_nanos() as u64;
        self.stats.frames += 1;
        self.lost_in_row = match r {
            Some(Ok(_)) => 0,
            _ => self.lost_in_row.saturating_add(1),
        };
        let Some(Ok(r)) = r else {
            self.stats.lost_frames += 1;
            return Err((
                None,
                BusFault::FrameLost {
                    iface: self.iface,
                    subdevices: bus.all,
                },
            ));
        };
        self.stats.rtt_max_ns = self.stats.rtt_max_ns.max(rtt);
        let bucket = ((rtt / RTT_BUCKET_NS) as usize).min(RTT_BUCKETS - 1);
        self.rtt[bucket] += 1;
        let got = r.working_counter;
        if got != expected {
            self.stats.wkc_errors += 1;
        }
        let not_op = r
            .subdevice_states
            .iter()
            .enumerate()
            .find(|(_, s)| **s != SubDeviceState::Op);
        if let Some((p, s)) = not_op {
            return Err((
                Some(p),
                BusFault::LeftOp {
                    al_state: al_nibble(*s),
                },
            ));
        }
        if got != expected {
            // the SubDevices whose share is the shortfall: one of them did not count
            let short = expected.wrapping_sub(got);
            let mut suspects = 0u32;
            for (p, &share) in bus.wkc_share.iter().enumerate().take(group.len()) {
                if share == short {
                    suspects |= 1 << p;
                }
            }
            let suspects = Positions(if suspects == 0 { bus.all.0 } else { suspects });
            let single =
                (suspects.0.count_ones() == 1).then(|| suspects.0.trailing_zeros() as usize);
            return Err((
                single,
                BusFault::WorkingCounter {
                    got,
                    expected,
                    suspects,
                },
            ));
        }
        self.raw_in = self.wiring.get_inputs(group, md);
        let mut faulted = None;
        for d in self.drives.iter_mut().flatten() {
            if let Ok(s) = group.subdevice(md, d.position) {
                d.inputs = Inputs::parse(&s.inputs_raw(), &d.layout);
            }
            if d.inputs.statusword & cia402::FAULT_BIT != 0 && faulted.is_none() {
                faulted = Some((
                    Some(d.position),
                    BusFault::DriveFault {
                        error_code: d.inputs.error_code,
                    },
                ));
            }
        }
        faulted.map_or(Ok(()), Err)
    }

    /// After a bus fault whose cause is gone: SubDevices out of OP are asked back
    /// into OP (AL control OP with the error acknowledged) while process data runs,
    /// until every one is there (off the cycle path). The drives stay disabled:
    /// `enable` resets their faults and powers them again.
    pub fn recover(&mut self) -> Result<(), BackendError> {
        const AL_OP_ACK: u16 = 0x0018;
        self.ensure_open()?;
        let deadline = Instant::now() + self.response_timeout * 2;
        let bus = self.bus.as_ref().expect("opened");
        for p in 0..bus.group.len() {
            let s = bus
                .group
                .subdevice(bus.md, p)
                .map_err(|_| BackendError::Timeout)?;
            let state = block_on(s.status(), deadline)
                .and_then(Result::ok)
                .map(|(st, _)| st);
            if state != Some(SubDeviceState::Op) {
                let _ = block_on(
                    s.register_write(ethercrab::RegisterAddress::AlControl, AL_OP_ACK),
                    deadline,
                );
            }
        }
        let mut last = Err(BackendError::Timeout);
        for _ in 0..STATE_CYCLES {
            last = self.exchange();
            match last {
                Ok(())
                | Err(BackendError::Bus {
                    reason: BusFault::DriveFault { .. },
                    ..
                }) => {
                    // the bus is whole; a drive's own fault is reset by `enable`
                    self.faulted = false;
                    return Ok(());
                }
                // a link still down: said after a few frames, not after STATE_CYCLES
                _ if self.lost_in_row >= RECOVER_LOST_IN_ROW => return last,
                _ => std::thread::sleep(self.cycle),
            }
        }
        last
    }

    /// Cycles (paced at the bus cycle) until every drive's state bits read `want`.
    fn step_to(&mut self, controlword: u16, want: u16) -> Result<(), BackendError> {
        for d in self.drives.iter_mut().flatten() {
            d.controlword = controlword;
        }
        for _ in 0..STATE_CYCLES {
            // the target follows the actual position: no jump when enabled
            for d in self.drives.iter_mut().flatten() {
                d.target = d.inputs.position;
                d.controlword = controlword;
            }
            match self.exchange() {
                Ok(())
                | Err(BackendError::Bus {
                    reason: BusFault::DriveFault { .. },
                    ..
                }) if controlword == cw::FAULT_RESET => {}
                r => r?,
            }
            if self
                .drives
                .iter()
                .flatten()
                .all(|d| cia402::state(d.inputs.statusword) == want)
            {
                return Ok(());
            }
            std::thread::sleep(self.cycle);
        }
        let axis = self
            .drives
            .iter()
            .position(|d| d.is_some_and(|d| cia402::state(d.inputs.statusword) != want))
            .unwrap_or(0);
        Err(BackendError::NotEnabled { axis: axis as u8 })
    }
}

/// An AL state as the low nibble of AL status.
fn al_nibble(s: SubDeviceState) -> u8 {
    match s {
        SubDeviceState::None => 0,
        SubDeviceState::Init => 1,
        SubDeviceState::PreOp => 2,
        SubDeviceState::Bootstrap => 3,
        SubDeviceState::SafeOp => 4,
        SubDeviceState::Op => 8,
        SubDeviceState::Other(x) => x,
    }
}

impl ServoBackend for EtherCatBackend {
    fn enable_failure(&self) -> Option<String> {
        self.last_open_error.as_ref().map(|e| e.to_string())
    }
    fn axes(&self) -> usize {
        self.axes
    }
    fn command_mode(&self, _axis: usize) -> CommandMode {
        CommandMode::Position
    }
    fn mm_per_count(&self, axis: usize) -> f64 {
        self.drives[axis].map_or(1.0, |d| 1.0 / d.counts_per_mm)
    }
    fn enable(&mut self) -> Result<(), BackendError> {
        self.ensure_open()?;
        // after a bus fault whose cause is gone (a reset): SubDevices back into OP
        match self.exchange() {
            Ok(())
            | Err(BackendError::Bus {
                reason: BusFault::DriveFault { .. },
                ..
            }) => {}
            Err(_) => self.recover()?,
        }
        if self
            .drives
            .iter()
            .flatten()
            .any(|d| d.inputs.statusword & cia402::FAULT_BIT != 0)
        {
            // a rising edge of fault reset, then on
            for d in self.drives.iter_mut().flatten() {
                d.controlword = cw::DISABLE_VOLTAGE;
            }
            let _ = self.exchange();
            self.step_to(cw::FAULT_RESET, 0x0040)?;
        }
        self.step_to(cw::SHUTDOWN, cia402::READY)?;
        self.step_to(cw::SWITCH_ON, cia402::SWITCHED_ON)?;
        self.step_to(cw::ENABLE, cia402::OPERATION_ENABLED)?;
        self.enabled = true;
        self.faulted = false;
        Ok(())
    }
    fn disable(&mut self) {
        self.enabled = false;
        if self.ensure_open().is_err() {
            return;
        }
        let _ = self.step_to(cw::QUICK_STOP, 0x0040);
        for d in self.drives.iter_mut().flatten() {
            d.controlword = cw::DISABLE_VOLTAGE;
        }
        let _ = self.exchange();
    }
    fn home(&mut self, pos_mm: Axes<f64>) {
        if self.bus.is_none() {
            // applied when the bus is up: the axes do not move before
            self.pending_home_mm = Some(pos_mm);
            return;
        }
        for (d, p) in self.drives.iter_mut().zip(pos_mm) {
            if let Some(d) = d {
                d.offset_counts = p * d.counts_per_mm - d.direction * f64::from(d.inputs.position);
            }
        }
    }
    fn write_commands(&mut self, cmd: Axes<f64>) {
        if !self.enabled {
            return;
        }
        for (d, c) in self.drives.iter_mut().zip(cmd) {
            if let (Some(d), true) = (d, c.is_finite()) {
                d.target = ((c * d.counts_per_mm - d.offset_counts) * d.direction).round() as i32;
            }
        }
    }
    fn cycle(&mut self) -> Result<(), BackendError> {
        self.exchange()
    }
    fn estop(&mut self) {
        // quick stop goes out with the next frame (`exchange_io` sends it)
        for d in self.drives.iter_mut().flatten() {
            d.controlword = cw::QUICK_STOP;
        }
        self.enabled = false;
    }
    fn exchange_io(&mut self) -> Result<(), BackendError> {
        // the axes stand (off, E-stopped): the frames go on, so that the drives
        // get their quick stop or disable and the SubDevices' watchdogs stay fed
        if self.bus.is_none() {
            return Ok(());
        }
        if self.faulted {
            // the fault has been reported once: frames go on (the quick stop) while
            // they come back; two lost in a row end them until a reset (a dead link:
            // no cycle waits on it again)
            if self.lost_in_row < FAULTED_LOST_IN_ROW {
                let _ = self.exchange();
            }
            return Ok(());
        }
        match self.exchange() {
            // a drive's fault with the axes standing is reset by the next `enable`
            Err(BackendError::Bus {
                reason: BusFault::DriveFault { .. },
                ..
            }) => Ok(()),
            r => r,
        }
    }
    fn recover(&mut self) -> Result<(), BackendError> {
        // a bus never brought up, or not in fault, has nothing to recover
        if self.bus.is_none() || !self.faulted {
            return Ok(());
        }
        EtherCatBackend::recover(self)
    }
    fn bus_stats(&self) -> Option<BusStats> {
        Some(EtherCatBackend::bus_stats(self))
    }
    fn io_lines(&self) -> IoLines {
        self.wiring.lines
    }
    fn write_io(&mut self, out: &RawOutputs) {
        self.raw_out = out.digital;
    }
    fn read_io(&self) -> RawInputs {
        RawInputs {
            digital: self.raw_in,
            ..RawInputs::default()
        }
    }
    fn read_counts(&self) -> Axes<i64> {
        let mut c = Axes::splat(0);
        for (out, d) in c.iter_mut().zip(&self.drives) {
            if let Some(d) = d {
                *out =
                    (d.direction * f64::from(d.inputs.position) + d.offset_counts).round() as i64;
            }
        }
        c
    }
    fn read_currents(&self) -> Axes<f64> {
        // the mapping carries no current (0x6078 is not in the PDOs)
        Axes::splat(0.0)
    }
    fn read_status(&self) -> Axes<AxisStatus> {
        let mut s = Axes::splat(AxisStatus::default());
        for (out, d) in s.iter_mut().zip(&self.drives) {
            if let Some(d) = d {
                *out = AxisStatus {
                    enabled: cia402::state(d.inputs.statusword) == cia402::OPERATION_ENABLED,
                    fault: d.inputs.statusword & cia402::FAULT_BIT != 0,
                    saturated: false,
                };
            }
        }
        s
    }
}
