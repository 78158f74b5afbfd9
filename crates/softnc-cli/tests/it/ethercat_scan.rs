//! `softnc ethercat scan` against the emulated segment on a veth pair (root needed;
//! SKIPPED otherwise): every SubDevice listed in order with its identity.

use softnc_ethercat_emu::veth::{is_root, VethPair};
use softnc_ethercat_emu::{identity, DeviceKind, Emulator};
use std::process::Command;

#[test]
fn scan_lists_the_emulated_subdevices_with_their_identities() {
    let _one = crate::one_controller_at_a_time();
    if !is_root() {
        println!("SKIPPED: needs root (a veth pair and packet sockets)");
        return;
    }
    let veth = VethPair::create().expect("veth pair");
    let kinds = [DeviceKind::Drive, DeviceKind::Drive, DeviceKind::Io];
    let _emu = Emulator::spawn(&veth.sub, &kinds).expect("emulator");
    let out = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(["ethercat", "scan", "--iface", &veth.main])
        .output()
        .expect("softnc runs");
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success());
    assert!(
        text.starts_with(&format!("3 SubDevices on {}", veth.main)),
        "{text}"
    );
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), 3);
    for (p, (&kind, row)) in kinds.iter().zip(&rows).enumerate() {
        let id = identity(kind, p);
        let want = format!(
            "vendor {:#010x} product {:#010x} revision {:#010x}  serial {}",
            id.vendor_id, id.product_code, id.revision, id.serial
        );
        assert!(
            row.trim_start().starts_with(&p.to_string()) && row.contains(&want),
            "row {p}: {row}"
        );
    }
    assert!(rows[2].contains("8DI/8DO terminal"), "{}", rows[2]);
}
