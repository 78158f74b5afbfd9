//! softncd on EtherCAT (issue 32), end to end: its three processes drive the
//! emulated CiA 402 drives and I/O terminal (`softnc-ethercat-emu`) on a veth pair
//! made by the test (root needed; SKIPPED otherwise).
//! - Drive 1 on a PDO mapping of the configuration's, not the default one.
//! - A job over the wire: every planned sample of the job reaches every drive as
//!   its target, none missing, none late by more than one cycle.
//! - Each fault the emulator injects (a frame dropped, a working counter short, a
//!   drive fault, a SubDevice leaving OP, the link down) mid-job: detected within 3 cycles, every drive
//!   stopped through the position process's E-stop path (quick stop on the wire),
//!   the alarm naming the SubDevice, its axis and the reason; the operator's
//!   `reset` brings the bus back to OP (refused while the link is still down),
//!   and the next job completes.
//! - Homing on the drive's home input (0x60FD bit 2): `home Z` ends homed at the
//!   switch.
//! - The terminal's signals: M8/M9 at its flood output, the E-stop chain opened at
//!   its input E-stops the machine.
#[allow(unused_imports)] // the shared harness re-exports what other test files use
mod support;
use softnc_ethercat_emu::control::Command as Fault;
use softnc_ethercat_emu::veth::{is_root, VethPair};
use softnc_ethercat_emu::{identity, DeviceKind, Emulator, Received, DRIVE_COUNTS_PER_MM};
use support::*;

/// CiA 402 controlwords as the MainDevice sends them.
const CW_ENABLE: u16 = 0x000F;
const CW_QUICK_STOP: u16 = 0x0002;
/// How long a cycle waits for the emulated SubDevices (s): a thread of this test
/// process beside the controller's real-time loops (as the demo gives them).
const RESPONSE_TIMEOUT_S: f64 = 0.05;
/// The bound of the issue: a fault is acted on within this many cycles.
const DETECT_CYCLES: u64 = 3;

/// The terminal's inputs on the shipped profile's lines (config/machines/default.ron):
/// bit 0 the E-stop chain (16), bit 1 tool-changed (5), bit 2 the probe (26), bit 4
/// M66 P0 (64).
const TERMINAL_INPUTS: &str =
    "[(bit: 0, line: 16), (bit: 1, line: 5), (bit: 2, line: 26), (bit: 4, line: 64)]";
/// The terminal's outputs: the profile's lines 0 … 7 (spindle enable, cw, ccw,
/// mist, flood, tool change, machine on, amplifier enable) on its bits 0 … 7.
const TERMINAL_OUTPUTS: &str = "[(bit: 0, line: 0), (bit: 1, line: 1), (bit: 2, line: 2), (bit: 3, line: 3), (bit: 4, line: 4), (bit: 5, line: 5), (bit: 6, line: 6), (bit: 7, line: 7)]";
/// The terminal's bit of coolant flood (M8) and of the E-stop chain.
const FLOOD_BIT: u8 = 1 << 4;
const ESTOP_CHAIN_BIT: u32 = 1 << 0;

/// Drive 1's PDO mapping, not the default one: the RxPDO without modes of
/// operation and digital outputs, its objects in another order; the TxPDO without
/// the following error, with the mode display, in another order (the job's
/// targets, its home switch and its fault's error code all go through it).
const NON_DEFAULT_PDO: &str = ", pdo: Some((rx: [TargetPosition, ControlWord], tx: [PositionActual, ModesOfOperationDisplay, StatusWord, ErrorCode, DigitalInputs]))";

/// The daemon configuration's `backend:` for a drive per axis (each one's home
/// switch, 0x60FD bit 2, on its axis's Home line 23 + axis), then the terminal.
fn backend(iface: &str, kinds: &[DeviceKind]) -> String {
    let subs: Vec<String> = kinds
        .iter()
        .enumerate()
        .map(|(p, &k)| {
            let id = identity(k, p);
            let (role, wiring) = match k {
                DeviceKind::Drive => (
                    format!(
                        "Drive(axis: {p}, counts_per_mm: {DRIVE_COUNTS_PER_MM:?}, direction: 1, following_error_window_counts: 50000)"
                    ),
                    format!(
                        "inputs: [(bit: 2, line: {})]{}",
                        23 + p,
                        if p == 1 { NON_DEFAULT_PDO } else { "" }
                    ),
                ),
                DeviceKind::Io => (
                    "Io".into(),
                    format!("inputs: {TERMINAL_INPUTS}, outputs: {TERMINAL_OUTPUTS}"),
                ),
            };
            format!(
                "(identity: (vendor_id: {}, product_code: {}, revision: {}), role: {role}, {wiring})",
                id.vendor_id, id.product_code, id.revision
            )
        })
        .collect();
    format!(
        "backend: EtherCat((interface: \"{iface}\", response_timeout_s: {RESPONSE_TIMEOUT_S}, subdevices: [{}]))",
        subs.join(", ")
    )
}

/// A job of about 4 s from and back to the origin: long enough to fault mid-way.
fn square_job(dir: &Path) -> PathBuf {
    let p = dir.join("square.ngc");
    std::fs::write(
        &p,
        "G21 G90 G17\nG1 X20 Y0 Z-1 F1200\nG1 Y20\nG1 X0\nG1 Y0 Z0\nM2\n",
    )
    .unwrap();
    p
}

/// The job's planned samples (mm per axis), as the interpolator makes them.
fn planned_samples(job: &Path, machine: &Path) -> Vec<[f64; 3]> {
    let JobPlan {
        plan, seq, heard, ..
    } = job_plan(job, machine);
    softnc_daemon::plan_samples::PlanSamples::with_machine(plan.interpolator(), seq, heard)
        .map(|s| [s.pos_mm.0[0], s.pos_mm.0[1], s.pos_mm.0[2]])
        .collect()
}

/// Every planned sample of axis `axis` among the targets drive `axis` received, in
/// order: none missing, none more than one frame after its slot (the slot of
/// sample i is i process-data frames after the first sample that leaves the
/// start position).
/// The largest lateness (frames).
fn check_targets(axis: usize, planned: &[[f64; 3]], got: &[Received]) -> u64 {
    let want: Vec<i32> = planned
        .iter()
        .map(|p| (p[axis] * DRIVE_COUNTS_PER_MM).round() as i32)
        .collect();
    let enabled: Vec<&Received> = got.iter().filter(|r| r.controlword == CW_ENABLE).collect();
    // the first sample off the start position fixes where sample 0's slot is
    let first_move = want
        .iter()
        .position(|&t| t != want[0])
        .expect("the axis moves");
    let at = enabled
        .iter()
        .position(|r| r.target_counts == want[first_move])
        .unwrap_or_else(|| panic!("axis {axis}: the first moving target never arrived"));
    let base = at
        .checked_sub(first_move)
        .unwrap_or_else(|| panic!("axis {axis}: fewer frames before the move than samples"));
    let mut k = base;
    let mut worst = 0;
    for (i, &t) in want.iter().enumerate() {
        // sample i at its slot, or one frame later (k moves on with it)
        let found = (k..(k + 2).min(enabled.len())).find(|&j| enabled[j].target_counts == t);
        let j = found.unwrap_or_else(|| {
            panic!(
                "axis {axis}: planned sample {i} ({t} counts) missing or late by more than one cycle (frame {:?} has {:?})",
                enabled.get(k).map(|r| r.frame),
                enabled.get(k).map(|r| r.target_counts)
            )
        });
        // lateness in the drive's process-data frames (cycles): the segment's
        // frame numbers also count the MainDevice's other frames (the DC system
        // time difference read every 250 cycles)
        let late = (j - base - i) as u64;
        assert!(
            late <= 1,
            "axis {axis}: planned sample {i} arrived {late} frames late"
        );
        worst = worst.max(late);
        k = j + 1;
    }
    worst
}

/// The servo backend's E-stop alarms in the status, newest first.
fn backend_alarms(s: &Status) -> Vec<String> {
    s.alarms
        .iter()
        .filter(|a| a.message.contains("emergency stop: servo backend"))
        .map(|a| a.message.clone())
        .collect()
}

/// Wait for the E-stop a fault causes (the machine E-stopped, one more servo
/// backend alarm than `before`); its alarm.
fn wait_estopped(d: &Daemon, op: &Operator, what: &str, before: usize) -> String {
    let s = d.wait_status(op, Duration::from_secs(10), what, |s| {
        s.state == MachineState::EStopped && backend_alarms(s).len() > before
    });
    backend_alarms(&s).remove(0)
}

/// Frames the MainDevice still sent with "enable operation" after the fault took
/// effect at `frame`, the most over the drives; and whether each drive still on
/// the bus got a quick stop after it.
fn after_fault(emu: &Emulator, drives: usize, frame: u64, skip: Option<usize>) -> (u64, bool) {
    let mut worst = 0;
    let mut all_stopped = true;
    for p in 0..drives {
        let log = emu.take_received(p);
        let after: Vec<&Received> = log.iter().filter(|r| r.frame > frame).collect();
        let enabled = after
            .iter()
            .take_while(|r| r.controlword == CW_ENABLE)
            .count() as u64;
        worst = worst.max(enabled);
        if Some(p) != skip {
            all_stopped &= after.iter().any(|r| r.controlword == CW_QUICK_STOP);
        }
    }
    (worst, all_stopped)
}

/// Run `job` to completion; its id.
fn run_job(d: &Daemon, op: &Operator, job: &Path) -> u64 {
    let r = op.request(&submit(&abs(job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    let s = d.wait_job(op, id(&r), Duration::from_secs(60));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "{s}");
    id(&r)
}

/// Job `job` on `d`, fault `fault` injected once it moves: the E-stop with an
/// alarm holding `words`, detected within the bound, every drive on the bus but
/// `gone` quick-stopped; reset, `on`, and a move back to the origin completes.
#[allow(clippy::too_many_arguments)]
fn fault_mid_job(
    d: &Daemon,
    op: &Operator,
    emu: &Emulator,
    job: &Path,
    axes: usize,
    what: &str,
    fault: Fault,
    gone: Option<usize>,
    words: &[&str],
) {
    let r = op.request(&submit(&abs(job))).unwrap();
    assert!(r.is_accepted(), "{}", r.message());
    d.wait_status(op, Duration::from_secs(20), "motion", |s| {
        s.job.as_ref().map_or(0, |j| j.record.cycles) > 500
    });
    for p in 0..axes {
        emu.take_received(p);
    }
    let dropped_before = emu.stats().dropped;
    let alarms_before = backend_alarms(&op.status().unwrap()).len();
    emu.command(fault);
    let alarm = &wait_estopped(d, op, what, alarms_before);
    println!("{what}: {alarm}");
    for w in words {
        assert!(alarm.contains(w), "{what}: {w:?} not in the alarm: {alarm}");
    }
    assert!(alarm.contains("every drive stopped"), "{alarm}");
    let s = d.wait_job(op, id(&r), Duration::from_secs(10));
    assert_ne!(job_of(&s).outcome, Outcome::Completed, "{what}: {s}");
    // where the fault took effect, in frames seen by the segment
    let frame = emu
        .applied()
        .last()
        .map(|(f, _)| *f)
        .expect("the fault applied");
    if fault == Fault::LinkDown {
        // nothing comes back: the MainDevice stops sending within the bound
        std::thread::sleep(Duration::from_millis(300));
        let sent = emu.stats().dropped - dropped_before;
        println!("{what}: {sent} frame(s) sent into the dead link");
        assert!(
            (1..=DETECT_CYCLES).contains(&sent),
            "{what}: {sent} frames into the dead link"
        );
        // a reset with the cause still there is refused: the machine stays stopped
        let (ok, msg) = ask(op, &Request::Reset);
        assert!(ok, "{what}: reset: {msg}");
        let s = d.wait_status(op, Duration::from_secs(10), "reset refused", |s| {
            alarm_text(s).contains("reset refused: the servo backend is still faulted")
        });
        assert_eq!(s.state, MachineState::EStopped, "{what}: {s}");
        println!("{what}: reset with the link still down refused");
        emu.command(Fault::LinkUp);
    } else {
        let (enabled_after, stopped) = after_fault(emu, axes, frame, gone);
        println!("{what}: detected after {} cycle(s)", enabled_after + 1);
        assert!(
            enabled_after < DETECT_CYCLES,
            "{what}: {enabled_after} frames still enabling the drives after the fault"
        );
        assert!(stopped, "{what}: not every drive got its quick stop");
    }
    // the operator's reset brings the bus back to OP; `on`, and the next job runs
    let (ok, msg) = ask(op, &Request::Reset);
    assert!(ok, "{what}: reset: {msg}");
    d.wait_status(op, Duration::from_secs(10), "off after reset", |s| {
        s.state == MachineState::Off
    });
    for v in emu.views() {
        assert_eq!(
            v.al_state,
            softnc_ethercat_emu::al::AlState::Op,
            "{what}: SubDevice {} after reset",
            v.position
        );
    }
    op.machine_on(Duration::from_secs(30))
        .unwrap_or_else(|e| panic!("{what}: machine on after reset: {e}"));
    // back where the job started, then the next job from there
    let home = d.dir.join("home.ngc");
    std::fs::write(&home, "G21 G90\nG1 X0 Y0 Z0 F3000\nM2\n").unwrap();
    run_job(d, op, &home);
}

/// The terminal's output byte as the emulator last had it written.
fn terminal_outputs(emu: &Emulator) -> u8 {
    emu.views()
        .iter()
        .find_map(|v| match v.app {
            softnc_ethercat_emu::app::AppView::Io { outputs, .. } => Some(outputs),
            _ => None,
        })
        .expect("the terminal")
}

/// Wait until the terminal's outputs satisfy `ok`; them.
fn wait_outputs(emu: &Emulator, what: &str, ok: impl Fn(u8) -> bool) -> u8 {
    let t0 = std::time::Instant::now();
    loop {
        let o = terminal_outputs(emu);
        if ok(o) {
            return o;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "{what}: terminal outputs {o:#010b}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Run MDI `block` to completion.
fn mdi(d: &Daemon, op: &Operator, block: &str) {
    let r = op.request(&mdi_request(block)).unwrap();
    assert!(r.is_accepted(), "MDI {block}: {}", r.message());
    let s = d.wait_job(op, id(&r), Duration::from_secs(30));
    assert_eq!(job_of(&s).outcome, Outcome::Completed, "MDI {block}: {s}");
}

/// M8/M9 seen at the terminal's flood output; the E-stop chain opened at its
/// input E-stops the machine (on and reset refused while open), closed again the
/// machine resets and comes on.
fn terminal_signals(d: &Daemon, op: &Operator, emu: &Emulator) {
    mdi(d, op, "M8");
    let o = wait_outputs(emu, "M8", |o| o & FLOOD_BIT != 0);
    println!("M8: terminal outputs {o:#010b} (flood is bit 4)");
    mdi(d, op, "M9");
    let o = wait_outputs(emu, "M9", |o| o & FLOOD_BIT == 0);
    println!("M9: terminal outputs {o:#010b}");
    emu.command(Fault::Inputs {
        position: 3,
        bits: ESTOP_CHAIN_BIT,
    });
    let s = d.wait_status(op, Duration::from_secs(10), "E-stop input", |s| {
        s.state == MachineState::EStopped
    });
    let text = alarm_text(&s);
    assert!(text.contains("the E-stop input opened"), "{text}");
    println!("the E-stop chain opened at the terminal: E-stopped, \"the E-stop input opened\"");
    // the safe state on the terminal: machine on and amplifier enable off
    let o = wait_outputs(emu, "E-stop", |o| o & 0b1100_0000 == 0);
    println!("E-stopped: terminal outputs {o:#010b}");
    let (ok, msg) = ask(op, &Request::MachineOn);
    assert!(
        !ok && msg.contains("the E-stop input is open"),
        "on with the chain open: {msg}"
    );
    emu.command(Fault::Inputs {
        position: 3,
        bits: 0,
    });
    std::thread::sleep(Duration::from_millis(100));
    let (ok, msg) = ask(op, &Request::Reset);
    assert!(ok, "reset: {msg}");
    d.wait_status(op, Duration::from_secs(10), "off after reset", |s| {
        s.state == MachineState::Off
    });
    op.machine_on(Duration::from_secs(30))
        .unwrap_or_else(|e| panic!("machine on after the chain closed: {e}"));
    let o = wait_outputs(emu, "on", |o| o & 0b1100_0000 == 0b1100_0000);
    println!("on again: terminal outputs {o:#010b}");
}

#[test]
fn e2e_faults_mid_job_stop_every_drive_and_reset_brings_the_bus_back() {
    if !is_root() {
        println!("SKIPPED: needs root (a veth pair and packet sockets)");
        return;
    }
    let veth = VethPair::create().expect("veth pair");
    let axes = 3;
    let mut kinds = vec![DeviceKind::Drive; axes];
    kinds.push(DeviceKind::Io);
    // the emulated ESCs at a real-time priority between the daemon's loops (as
    // `softnc demo --backend ethercat-emulated` runs them): hardware answers
    // whatever the host's other work
    let emu = Emulator::spawn_at(&veth.sub, &kinds, Some(75)).expect("emulator");
    let bus = backend(&veth.main, &kinds);
    let dir = fresh_dir("ethercat");
    let d = Daemon::start_in(
        dir,
        "ethercat",
        "Realtime",
        false,
        "default.ron",
        &[("backend: Simulated", &bus)],
    );
    let op = d.operator();
    let job = square_job(&d.dir);

    // 1. a job over the wire: every planned sample is a drive's target, in time
    for p in 0..axes {
        emu.take_received(p);
    }
    run_job(&d, &op, &job);
    let planned = planned_samples(&job, &d.dir.join("machines/default.ron"));
    for p in 0..axes {
        let got = emu.take_received(p);
        let late = check_targets(p, &planned, &got);
        println!(
            "drive {p}: {} planned samples all received, the latest {late} frame(s) after its slot",
            planned.len()
        );
    }
    let s = op.status().unwrap();
    let figures = s.loops.bus.expect("the bus figures in the status");
    println!("bus figures: {figures:?}");
    assert!(figures.frames >= planned.len() as u64, "{figures:?}");
    assert_eq!(figures.lost_frames, 0, "{figures:?}");

    // 2. the terminal's signals through the daemon: M8 and M9 at its outputs, the
    // E-stop chain opened at its input stops the machine
    terminal_signals(&d, &op, &emu);

    // 3. each fault mid-job
    let lost: &[&str] = &[
        "frame lost",
        "all SubDevices (0–3) affected",
        &format!("the link down on {}", veth.main),
    ];
    let faults: [(&str, Fault, Option<usize>, &[&str]); 5] = [
        ("a frame dropped", Fault::Drop(1), None, lost),
        (
            "a working counter short",
            Fault::SkipWorkingCounter {
                position: 2,
                frames: 1,
            },
            None,
            &[
                "working counter 9, expected 12",
                "one of SubDevices 0–3 did not exchange its process data",
            ],
        ),
        (
            "a drive fault",
            Fault::DriveFault {
                position: 1,
                code: 0x7305,
            },
            None,
            &["SubDevice 1", "(axis 1)", "error code 0x7305", "axis Y"],
        ),
        (
            "a SubDevice leaving OP",
            Fault::LeaveOp { position: 2 },
            Some(2),
            &["SubDevice 2", "(axis 2)", "left OP", "axis Z"],
        ),
        ("the link down", Fault::LinkDown, None, lost),
    ];
    for (what, fault, gone, words) in faults {
        fault_mid_job(&d, &op, &emu, &job, axes, what, fault, gone, words);
    }
    // 4. after every fault: the whole job again, every sample on the wire
    for p in 0..axes {
        emu.take_received(p);
    }
    run_job(&d, &op, &job);
    for p in 0..axes {
        check_targets(p, &planned, &emu.take_received(p));
    }
    let s = op.status().unwrap();
    let figures = s.loops.bus.expect("the bus figures in the status");
    println!("bus figures after the faults: {figures:?}");
    assert!(figures.lost_frames >= 2, "{figures:?}");
    drop(op);
    drop(d);

    // 5. homing on the drive's home input: another daemon on the same bus, with
    // the incremental-encoder profile
    homes_on_the_drive_home_input(&veth, &emu, &bus);
}

/// Where the emulated Z drive's home switch is, from where the drive stands
/// (mm): close, so that the search is short.
const Z_SWITCH_FROM_START_MM: f64 = 20.0;
/// The homed position's tolerance at the drive (mm), once it stands: the latch
/// at 2 mm/s moves 2 µm a cycle (the edge is taken halfway: 1 µm measured).
const HOMED_TOLERANCE_MM: f64 = 0.002;

/// `softnc home Z` over the bus on config/machines/default-incremental.ron: the
/// search runs until the Z drive's home switch (0x60FD bit 2, wired to the
/// profile's Home("Z") line) reads active, latches where it releases, and Z ends
/// at the profile's home_mm with the latch point at its switch_mm: checked on
/// the emulated drive's own position.
fn homes_on_the_drive_home_input(veth: &VethPair, emu: &Emulator, bus: &str) {
    let drive_counts = |emu: &Emulator| {
        emu.views()
            .iter()
            .find_map(|v| match v.app {
                softnc_ethercat_emu::app::AppView::Drive(dv) if v.position == 2 => {
                    Some(dv.position_counts)
                }
                _ => None,
            })
            .expect("drive 2")
    };
    let start_counts = drive_counts(emu);
    let switch_counts = start_counts + (Z_SWITCH_FROM_START_MM * DRIVE_COUNTS_PER_MM) as i32;
    emu.command(Fault::HomeSwitch {
        position: 2,
        at_counts: switch_counts,
    });
    let profile = repo().join("config/machines/default-incremental.ron");
    let text = std::fs::read_to_string(&profile).unwrap();
    let (switch_mm, home_mm) = (105.0, 90.0);
    assert!(
        text.contains("(switch_mm: 105.0, search_vel_mm_per_s: 30.0, latch_vel_mm_per_s: -2.0,\n             final_vel_mm_per_s: 100.0, home_mm: 90.0)"),
        "Z's homing in {}",
        profile.display()
    );
    let d = Daemon::start_in(
        fresh_dir("ethercat-homing"),
        "ethercathoming",
        "Realtime",
        false,
        profile.to_str().unwrap(),
        &[("backend: Simulated", bus)],
    );
    let op = d.operator();
    let (ok, msg) = ask(
        &op,
        &Request::Home {
            axis: Some(axis(2)),
        },
    );
    assert!(ok, "home Z: {msg}");
    let s = d.wait_status(&op, Duration::from_secs(30), "Z homed", |s| {
        s.homed.get(2) == Some(&true) && s.state == MachineState::Idle
    });
    let z_mm = machine_mm(&s)[2];
    // Idle once the command stands: the drive's own loop settles after it (a
    // few time constants of its 150/s position loop), so read it once it stands
    let mut at = drive_counts(emu);
    let settle_by = std::time::Instant::now() + Duration::from_secs(2);
    loop {
        std::thread::sleep(Duration::from_millis(50));
        let now = drive_counts(emu);
        if now == at || std::time::Instant::now() > settle_by {
            break;
        }
        at = now;
    }
    // the latch point (switch_counts) reads switch_mm: home_mm is that less
    // (switch_mm − home_mm) at the drive
    let want = f64::from(switch_counts) - (switch_mm - home_mm) * DRIVE_COUNTS_PER_MM;
    let off_mm = (f64::from(at) - want) / DRIVE_COUNTS_PER_MM;
    println!(
        "home Z on {}: homed at {z_mm:.4} mm; the drive at {at} counts, the switch at {switch_counts}: {off_mm:+.4} mm from home_mm by the switch",
        veth.main
    );
    assert!(
        (z_mm - home_mm).abs() < HOMED_TOLERANCE_MM,
        "Z at {z_mm} mm"
    );
    assert!(
        off_mm.abs() < HOMED_TOLERANCE_MM,
        "Z's drive {off_mm} mm from where the switch puts home"
    );
}
