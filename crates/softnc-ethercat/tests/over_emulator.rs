//! The EtherCAT backend over the emulator on a veth pair (root needed; SKIPPED
//! otherwise): the servo conformance suite; an identity mismatch refused with
//! both identities; each fault (lost frame, link down, drive fault, leaving OP)
//! detected within 3 cycles naming SubDevice and axis; the cycle allocation-free,
//! with its send-to-receive times printed.

use softnc_ethercat::{
    BitLine, EtherCatBackend, EtherCatConfig, ExpectedSubDevice, Identity, OpenError, Role,
};
use softnc_ethercat_emu::control::Command;
use softnc_ethercat_emu::veth::{is_root, VethPair};
use softnc_ethercat_emu::{DeviceKind, Emulator};
use softnc_servo::{BackendError, BusFault, ServoBackend};
use std::time::Duration;

#[global_allocator]
static GLOBAL: softnc_test_support::Counting = softnc_test_support::Counting;

const KINDS: [DeviceKind; 4] = [
    DeviceKind::Drive,
    DeviceKind::Drive,
    DeviceKind::Drive,
    DeviceKind::Io,
];

fn identity(kind: DeviceKind, position: usize) -> Identity {
    let id = softnc_ethercat_emu::identity(kind, position);
    Identity {
        vendor_id: id.vendor_id,
        product_code: id.product_code,
        revision: id.revision,
    }
}

/// The shipped profile's (config/machines/default.ron) lines: Home("X") is 23,
/// Home("Y") 24, Home("Z") 25.
const HOME_LINE: u8 = 23;
/// The terminal's inputs: bit 0 the E-stop chain (line 16), bit 1 tool-changed
/// (5), bit 2 the probe (26), bit 3 the X maximum limit (20), bit 4 M66 P0 (64).
const TERMINAL_INPUTS: [(u8, u8); 5] = [(0, 16), (1, 5), (2, 26), (3, 20), (4, 64)];

fn config(iface: &str) -> EtherCatConfig {
    let subdevices = KINDS
        .iter()
        .enumerate()
        .map(|(p, &k)| ExpectedSubDevice {
            identity: identity(k, p),
            role: match k {
                DeviceKind::Drive => Role::Drive {
                    axis: p as u8,
                    counts_per_mm: softnc_ethercat_emu::DRIVE_COUNTS_PER_MM,
                    direction: if p == 1 { -1 } else { 1 },
                    following_error_window_counts: 50_000,
                },
                DeviceKind::Io => Role::Io,
            },
            inputs: match k {
                // each drive's home switch (0x60FD bit 2) on its axis's Home line
                DeviceKind::Drive => vec![BitLine {
                    bit: 2,
                    line: HOME_LINE + p as u8,
                }],
                DeviceKind::Io => TERMINAL_INPUTS
                    .iter()
                    .map(|&(bit, line)| BitLine { bit, line })
                    .collect(),
            },
            outputs: match k {
                DeviceKind::Drive => Vec::new(),
                // the cabinet's outputs 0 … 7 (spindle, coolant, tool change,
                // machine on, amplifier enable) on the terminal's 8 outputs
                DeviceKind::Io => (0..8).map(|b| BitLine { bit: b, line: b }).collect(),
            },
            pdo: None,
        })
        .collect();
    EtherCatConfig {
        interface: iface.to_string(),
        cycle: Duration::from_millis(1),
        // generous: the test machine is shared and the loop is not real-time here
        response_timeout: Duration::from_millis(100),
        subdevices,
    }
}

/// One bus at a time: the tests' spinning MainDevices and emulators share 2 cores.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn bus() -> Option<(std::sync::MutexGuard<'static, ()>, VethPair, Emulator)> {
    let guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    if !is_root() {
        println!("SKIPPED: needs root (a veth pair and packet sockets)");
        return None;
    }
    let veth = VethPair::create().expect("veth pair");
    let emu = Emulator::spawn(&veth.sub, &KINDS).expect("emulator");
    Some((guard, veth, emu))
}

#[test]
fn conforms_over_the_emulator() {
    let Some((_one, veth, _emu)) = bus() else {
        return;
    };
    let profile = softnc_machine::MachineProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .expect("default profile");
    let cfg = config(&veth.main);
    // handles as a daemon's factory makes them: the bus comes up on enable/disable
    softnc_servo::conformance::run("ethercat", &profile, &|| {
        EtherCatBackend::new(&cfg).expect("configuration")
    });
}

#[test]
fn refuses_a_wrong_subdevice_naming_both_identities() {
    let Some((_one, veth, _emu)) = bus() else {
        return;
    };
    let mut cfg = config(&veth.main);
    cfg.subdevices[2].identity.product_code = 0x1234;
    match EtherCatBackend::open(&cfg) {
        Err(e @ OpenError::IdentityMismatch { position: 2, .. }) => {
            let text = e.to_string();
            println!("{text}");
            assert!(
                text.contains("0x00000402") && text.contains("0x00001234"),
                "{text}"
            );
        }
        Err(e) => panic!("wrong refusal: {e}"),
        Ok(_) => panic!("a wrong identity was accepted"),
    }
}

/// Cycles until the backend fails, at most 3 after the fault; the error.
fn fails_within_3(b: &mut EtherCatBackend) -> BackendError {
    for k in 0..3 {
        if let Err(e) = b.cycle() {
            println!("detected after {} cycle(s): {e}", k + 1);
            return e;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    panic!("fault not detected within 3 cycles");
}

/// The E-stop path on the cycle (the position process's): quick stop, then the
/// I/O-only exchanges of the stopped machine, allocation-free; every drive
/// quick-stopped.
fn estop_path_is_allocation_free(b: &mut EtherCatBackend, emu: &Emulator) {
    let before = softnc_test_support::allocations();
    b.estop();
    for _ in 0..500 {
        b.exchange_io().expect("the stopped machine's exchange");
    }
    let allocs = softnc_test_support::allocations() - before;
    assert_eq!(allocs, 0, "the E-stop path allocated");
    for v in emu.views() {
        if let softnc_ethercat_emu::app::AppView::Drive(d) = v.app {
            assert_ne!(
                d.state,
                softnc_ethercat_emu::cia402::PowerState::OperationEnabled,
                "drive {} still enabled after the E-stop",
                v.position
            );
            assert_eq!(d.controlword, 0x0002, "drive {}: quick stop", v.position);
        }
    }
    println!("E-stop: every drive quick-stopped over 500 exchanges, 0 allocations");
}

/// One SubDevice not counting the working counter for a frame: detected, named
/// among the SubDevices it may be; the bus recovered and enabled again.
fn working_counter_short(b: &mut EtherCatBackend, emu: &Emulator) {
    // one SubDevice not counting the working counter for a frame: the frame
    // comes back whole, its count short by that SubDevice's share (3: a drive
    // and the terminal both read and write, so any of them may be the one)
    emu.command(Command::SkipWorkingCounter {
        position: 2,
        frames: 1,
    });
    std::thread::sleep(Duration::from_millis(20));
    let e = fails_within_3(b);
    assert_eq!(
        e,
        BackendError::Bus {
            subdevice: None,
            axis: None,
            reason: BusFault::WorkingCounter {
                got: 9,
                expected: 12,
                suspects: softnc_servo::Positions(0b1111),
            }
        },
        "{e}"
    );
    b.recover().expect("the working counter whole again");
    b.enable().expect("enabled again");
}

/// Cycles of the allocation test.
const CYCLES: usize = 2000;
/// The emulated clocks' system time difference stays below this (ns): they all
/// run from the host's clock, so it holds only the emulator's datagram timing.
const DC_PLAUSIBLE_NS: u64 = 100_000;

#[test]
fn a_stepped_subdevice_clock_shows_in_the_dc_deviation() {
    let Some((_one, veth, emu)) = bus() else {
        return;
    };
    let mut b = EtherCatBackend::open(&config(&veth.main)).expect("bus up");
    b.enable().expect("enable");
    let hold = b.read_counts().map(|c| c as f64 * 1e-4);
    // every DC SubDevice after the reference read at least once, unstepped
    for _ in 0..250 * KINDS.len() {
        b.write_commands(hold);
        b.cycle().expect("cycle");
    }
    const STEP_NS: u32 = 3_000_000;
    emu.command(Command::ClockStep {
        position: 2,
        ns: STEP_NS,
    });
    std::thread::sleep(Duration::from_millis(20));
    let before = b.bus_stats();
    // every DC SubDevice after the reference read at least once
    for _ in 0..250 * KINDS.len() {
        b.write_commands(hold);
        b.cycle().expect("cycle");
    }
    let s = b.bus_stats();
    println!(
        "clock of SubDevice 2 stepped {STEP_NS} ns: DC deviation max {} ns (before {} ns), last {} ns, {} reads",
        s.dc_deviation_max_ns, before.dc_deviation_max_ns, s.dc_deviation_last_ns, s.dc_reads
    );
    assert!(
        before.dc_reads > 0 && before.dc_deviation_max_ns < DC_PLAUSIBLE_NS,
        "{before:?}"
    );
    assert!(
        s.dc_deviation_max_ns.abs_diff(u64::from(STEP_NS)) < DC_PLAUSIBLE_NS,
        "the step of {STEP_NS} ns not in the figure: {s:?}"
    );
}

/// [`CYCLES`] cycles holding `hold`: no allocation, the DC system time difference
/// read among them and plausible, each cycle timed (printed).
fn allocation_free_cycles_with_dc_reads(b: &mut EtherCatBackend, hold: softnc_core::Axes<f64>) {
    // allocation-free cycles (the DC system time difference reads among them),
    // each timed: (ns, whether a DC read was in it)
    let mut took = vec![(0u64, false); CYCLES];
    let reads_before = b.bus_stats().dc_reads;
    let before = softnc_test_support::allocations();
    for t in took.iter_mut() {
        let reads = b.bus_stats().dc_reads;
        let t0 = std::time::Instant::now();
        b.write_commands(hold);
        b.cycle().expect("cycle");
        *t = (
            t0.elapsed().as_nanos() as u64,
            b.bus_stats().dc_reads > reads,
        );
    }
    let allocs = softnc_test_support::allocations() - before;
    let s = b.bus_stats();
    println!(
        "{CYCLES} cycles: {allocs} allocations; frames {} lost {} wkc errors {}; send-to-receive p50 {} µs p99 {} µs max {} µs",
        s.frames, s.lost_frames, s.wkc_errors, s.rtt_p50_ns / 1000, s.rtt_p99_ns / 1000, s.rtt_max_ns / 1000
    );
    assert_eq!(allocs, 0, "the cycle allocated");
    // the DC deviation: read, and plausible for clocks that all run from the host's
    let reads = s.dc_reads - reads_before;
    let p99 = |mut v: Vec<u64>| {
        v.sort_unstable();
        v.get((v.len() * 99).div_ceil(100).saturating_sub(1))
            .copied()
            .unwrap_or(0)
    };
    let plain: Vec<u64> = took.iter().filter(|t| !t.1).map(|t| t.0).collect();
    let with_read: Vec<u64> = took.iter().filter(|t| t.1).map(|t| t.0).collect();
    println!(
        "DC system time difference: {reads} reads, last {} ns, max {} ns; cycle p99 {} µs without a read, {} µs over all; cycles with a read: {} of them, p50 {} µs max {} µs",
        s.dc_deviation_last_ns,
        s.dc_deviation_max_ns,
        p99(plain.clone()) / 1000,
        p99(took.iter().map(|t| t.0).collect()) / 1000,
        with_read.len(),
        with_read.get(with_read.len() / 2).copied().unwrap_or(0) / 1000,
        with_read.iter().max().copied().unwrap_or(0) / 1000,
    );
    assert!(
        reads as usize >= CYCLES / 250 - 1,
        "{reads} DC reads in {CYCLES} cycles"
    );
    assert!(
        s.dc_deviation_max_ns < DC_PLAUSIBLE_NS,
        "DC deviation {} ns",
        s.dc_deviation_max_ns
    );
}

#[test]
fn faults_are_detected_within_3_cycles_and_the_cycle_does_not_allocate() {
    let Some((_one, veth, emu)) = bus() else {
        return;
    };
    let mut b = EtherCatBackend::open(&config(&veth.main)).expect("bus up");
    b.enable().expect("enable");
    let hold = b.read_counts().map(|c| c as f64 * 1e-4);
    b.write_commands(hold);
    b.cycle().expect("warm");
    allocation_free_cycles_with_dc_reads(&mut b, hold);
    estop_path_is_allocation_free(&mut b, &emu);
    b.enable().expect("enabled again after the E-stop");

    emu.command(Command::Drop(1));
    std::thread::sleep(Duration::from_millis(20));
    let e = fails_within_3(&mut b);
    assert!(
        matches!(
            e,
            BackendError::Bus {
                reason: BusFault::FrameLost { .. },
                ..
            }
        ),
        "{e}"
    );
    b.recover().expect("the bus answers again");
    b.enable().expect("enabled again");

    working_counter_short(&mut b, &emu);

    emu.command(Command::DriveFault {
        position: 1,
        code: 0x7305,
    });
    std::thread::sleep(Duration::from_millis(20));
    let e = fails_within_3(&mut b);
    assert_eq!(
        e,
        BackendError::Bus {
            subdevice: Some(1),
            axis: Some(1),
            reason: BusFault::DriveFault { error_code: 0x7305 }
        }
    );
    b.enable().expect("fault reset and enable again");
    b.cycle().expect("running again");

    emu.command(Command::LeaveOp { position: 2 });
    std::thread::sleep(Duration::from_millis(20));
    let e = fails_within_3(&mut b);
    assert_eq!(
        e,
        BackendError::Bus {
            subdevice: Some(2),
            axis: Some(2),
            reason: BusFault::LeftOp { al_state: 4 }
        }
    );
    // a reset's enable brings SubDevice 2 back into OP by itself
    b.enable().expect("SubDevice 2 back in OP, enabled again");

    emu.command(Command::LinkDown);
    std::thread::sleep(Duration::from_millis(20));
    let e = fails_within_3(&mut b);
    assert!(
        matches!(
            e,
            BackendError::Bus {
                reason: BusFault::FrameLost { .. },
                ..
            }
        ),
        "{e}"
    );
    emu.command(Command::LinkUp);
    b.recover().expect("the link back");
    b.enable().expect("enabled again");
    for _ in 0..10 {
        b.cycle().expect("running after every fault");
    }
    let s = b.bus_stats();
    println!(
        "after the faults: frames {} lost {} wkc errors {}",
        s.frames, s.lost_frames, s.wkc_errors
    );
}

/// The terminal's and the drives' digital inputs reach the machine's named
/// signals through the I/O boundary (`MachineIo` on the shipped profile's map),
/// and the machine's outputs reach the terminal's outputs.
#[test]
fn the_terminal_carries_the_machine_signals() {
    let Some((_one, veth, emu)) = bus() else {
        return;
    };
    let profile = softnc_machine::MachineProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .expect("default profile");
    let mut b = EtherCatBackend::open(&config(&veth.main)).expect("bus up");
    let lines = b.io_lines();
    assert_eq!((lines.digital_in, lines.digital_out), (65, 8), "{lines:?}");
    let mut io = softnc_servo::MachineIo::new(&profile, lines);
    let terminal = KINDS.len() - 1;
    // inputs: each in turn, seen at its signal within 3 exchanges
    type Check = fn(&softnc_core::machine_io::MachineInputs) -> bool;
    let cases: [(&str, usize, u32, Check); 7] = [
        ("nothing", terminal, 0, |i| {
            !i.estop_open && !i.probe && !i.tool_changed && i.home == 0 && i.digital == 0
        }),
        ("the E-stop chain open", terminal, 1 << 0, |i| i.estop_open),
        ("tool changed", terminal, 1 << 1, |i| i.tool_changed),
        ("the probe", terminal, 1 << 2, |i| i.probe),
        ("M66 P0", terminal, 1 << 4, |i| i.digital & 1 == 1),
        ("Y's home switch (drive 1, 0x60FD bit 2)", 1, 1 << 2, |i| {
            i.home == 0b010
        }),
        ("Z's home switch (drive 2, 0x60FD bit 2)", 2, 1 << 2, |i| {
            i.home == 0b110
        }),
    ];
    for (what, position, bits, seen) in cases {
        emu.command(Command::Inputs { position, bits });
        let mut got = None;
        for _ in 0..3 {
            std::thread::sleep(Duration::from_millis(2));
            b.exchange_io().expect("exchange");
            let i = io.inputs(&b.read_io());
            if seen(&i) {
                got = Some(());
                break;
            }
        }
        assert!(
            got.is_some(),
            "{what}: not seen in 3 exchanges: {:?}",
            b.read_io()
        );
        println!("{what}: raw input lines {:#x}", b.read_io().digital);
    }
    // outputs: M8 (flood) and M3 with the machine on, then the safe state off
    let program = softnc_core::machine_io::MachineOutputs {
        spindle_dir: softnc_core::machine_io::SpindleDir::Clockwise,
        spindle_rpm: 1000.0,
        coolant_flood: true,
        ..Default::default()
    };
    let terminal_outputs = |b: &mut EtherCatBackend, raw: &softnc_servo::RawOutputs| {
        b.write_io(raw);
        b.exchange_io().expect("exchange");
        b.exchange_io().expect("exchange");
        emu.views()
            .iter()
            .find_map(|v| match v.app {
                softnc_ethercat_emu::app::AppView::Io { outputs, .. } => Some(outputs),
                _ => None,
            })
            .expect("the terminal")
    };
    // the E-stop chain closed again: the latch reset, as the operator's reset does
    assert!(
        io.reset_estop(),
        "the E-stop latch resets with the chain closed"
    );
    let on = io.outputs(&program, softnc_servo::io::OutputState::default());
    let got = terminal_outputs(&mut b, &on);
    println!("M3 M8, machine on: terminal outputs {got:#010b}");
    // spindle enable 0, cw 1, flood 4, machine on 6, amplifier enable 7
    assert_eq!(got, 0b1101_0011, "terminal outputs {got:#010b}");
    let off = softnc_servo::io::OutputState {
        machine_on: false,
        amp_enable: false,
        spindle_override: 1.0,
    };
    let safe = io.outputs(&program, off);
    let got = terminal_outputs(&mut b, &safe);
    println!("machine off: terminal outputs {got:#010b}");
    assert_eq!(got, 0, "the safe state on the terminal");
}

/// Bring-ups one after the other (a reset after a failed bring-up, a test's
/// handles): each takes the MainDevice of the one before, so the heap does not
/// grow; the bring-up's time printed.
/// What a bring-up may leave on the heap, at most (bytes): well below a
/// MainDevice with its storage (≈ 19 KiB).
const BRING_UP_GROWTH_BOUND: usize = 1024;

#[test]
fn repeated_bring_ups_do_not_grow_the_heap() {
    let Some((_one, veth, emu)) = bus() else {
        return;
    };
    const BRING_UPS: usize = 10;
    let cfg = config(&veth.main);
    // the first one warms what stays (the MainDevice, its thread, the socket)
    drop(EtherCatBackend::open(&cfg).expect("bus up"));
    // the emulator's log of received targets (it grows with the frames) left out
    let forget_log = || (0..KINDS.len()).for_each(|p| drop(emu.take_received(p)));
    forget_log();
    let before = softnc_test_support::live_bytes();
    let mut times_ms = Vec::new();
    let mut enable_ms = Vec::new();
    for _ in 0..BRING_UPS {
        let t0 = std::time::Instant::now();
        let mut b = EtherCatBackend::open(&cfg).expect("bus up");
        times_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        let t0 = std::time::Instant::now();
        b.enable().expect("enable");
        enable_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        drop(b);
    }
    forget_log();
    let grown = softnc_test_support::live_bytes() as i64 - before as i64;
    times_ms.sort_by(f64::total_cmp);
    enable_ms.sort_by(f64::total_cmp);
    println!(
        "{BRING_UPS} bring-ups: heap grown by {grown} bytes ({} a bring-up); bring-up to OP min/median/max {:.0}/{:.0}/{:.0} ms, enable {:.0}/{:.0}/{:.0} ms",
        grown / BRING_UPS as i64,
        times_ms[0],
        times_ms[BRING_UPS / 2],
        times_ms[BRING_UPS - 1],
        enable_ms[0],
        enable_ms[BRING_UPS / 2],
        enable_ms[BRING_UPS - 1]
    );
    // each bring-up before took a MainDevice of its own: 19,411 bytes a bring-up
    assert!(
        grown < (BRING_UP_GROWTH_BOUND * BRING_UPS) as i64,
        "the heap grew by {grown} bytes over {BRING_UPS} bring-ups"
    );
}
