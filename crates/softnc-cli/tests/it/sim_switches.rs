//! `softnc sim` runs a program as the daemon starts: block delete and optional stop
//! on (LinuxCNC's controller defaults), each switch can be turned off.

use std::path::PathBuf;
use std::process::Command;

/// `softnc sim FILE --json` with `extra` arguments: the run's cycles.
fn cycles(file: &PathBuf, extra: &[&str]) -> u64 {
    let out = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("sim")
        .arg(file)
        .arg("--json")
        .args(extra)
        .arg("--machine")
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"))
        .output()
        .expect("softnc runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    v["cycles"].as_u64().unwrap()
}

#[test]
fn block_delete_and_optional_stop_are_on_by_default_and_can_be_turned_off() {
    let dir = std::env::temp_dir().join(format!("softnc-sim-switches-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // 10 mm at 10 mm/s, a deleted 10 mm move along Y, 10 mm more along X
    let skip = dir.join("skip.ngc");
    std::fs::write(&skip, "G21 G90 G64\nG1 X10 F600\n/G1 Y10\nG1 X20\nM2\n").unwrap();
    let on = cycles(&skip, &[]);
    let off = cycles(&skip, &["--block-delete", "off"]);
    // the deleted line is a 10 mm move at 10 mm/s: a second longer when it runs
    assert!(off > on + 900, "block delete on {on} cycles, off {off}");
    // M1 between two collinear moves: a stop with the switch on, none without
    let m1 = dir.join("m1.ngc");
    std::fs::write(&m1, "G21 G90 G64\nG1 X10 F600\nM1\nG1 X20\nM2\n").unwrap();
    let stop = cycles(&m1, &[]);
    let through = cycles(&m1, &["--optional-stop", "off"]);
    assert!(
        stop > through,
        "optional stop on {stop} cycles, off {through}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
