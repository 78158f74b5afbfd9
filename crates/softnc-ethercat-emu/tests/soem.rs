//! The emulator is a real SubDevice segment, not one shaped to our MainDevice: SOEM
//! (pysoem from PyPI, installed by scripts/pysoem-setup) finds the SubDevices with
//! their identities, reaches OP with DC and exchanges process data with them, over
//! a veth pair made by the test. Root needed (veth, packet sockets): SKIPPED
//! otherwise, and where pip cannot install pysoem.

use softnc_ethercat_emu::app::AppView;
use softnc_ethercat_emu::control::Command;
use softnc_ethercat_emu::veth::{is_root, VethPair};
use softnc_ethercat_emu::{DeviceKind, Emulator};
use std::path::Path;
use std::process::Command as Process;

const ROOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
const TERMINAL_INPUTS: u32 = 0x5A;

fn pysoem_python() -> Option<String> {
    let out = Process::new(Path::new(ROOT).join("scripts/pysoem-setup"))
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

#[test]
fn soem_finds_the_segment_reaches_op_and_exchanges_process_data() {
    if !is_root() {
        println!("SKIPPED: needs root (a veth pair and packet sockets)");
        return;
    }
    let Some(python) = pysoem_python() else {
        println!("SKIPPED: pysoem could not be installed (scripts/pysoem-setup: no network?)");
        return;
    };
    let veth = VethPair::create().expect("veth pair");
    let kinds = [
        DeviceKind::Drive,
        DeviceKind::Drive,
        DeviceKind::Drive,
        DeviceKind::Io,
    ];
    let emu = Emulator::spawn(&veth.sub, &kinds).expect("emulator");
    emu.command(Command::Inputs {
        position: 3,
        bits: TERMINAL_INPUTS,
    });
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/soem_master.py");
    let out = Process::new(&python)
        .arg(&script)
        .arg(&veth.main)
        .arg(format!("{TERMINAL_INPUTS:#x}"))
        .output()
        .expect("python runs");
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "SOEM's checks failed");
    for p in 0..3 {
        let id = "vendor 0x000005f7 product 0x00000402 revision 0x00010000";
        assert!(
            text.lines()
                .any(|l| l.starts_with(&format!("subdevice {p}:")) && l.contains(id)),
            "SOEM lists drive {p} with its identity"
        );
    }
    let views = emu.views();
    match views[3].app {
        AppView::Io { outputs, .. } => {
            assert_eq!(outputs, 0xA5, "SOEM's output byte reached the terminal")
        }
        other => panic!("position 3 is the terminal: {other:?}"),
    }
    match views[0].app {
        AppView::Drive(d) => assert!(
            d.targets_received > 300,
            "drive 0 received {} targets",
            d.targets_received
        ),
        other => panic!("position 0 is a drive: {other:?}"),
    }
    assert!(
        views[0].sync0_events > 0,
        "SYNC0 activated by SOEM on drive 0"
    );
}
