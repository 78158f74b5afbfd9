//! `softnc sim` runs a program as the daemon starts: block delete and optional stop
//! on (LinuxCNC's controller defaults), each switch can be turned off.

use std::path::PathBuf;
use std::process::Command;

/// `softnc sim FILE --json` with `extra` arguments: the run's cycles.
fn cycles(file: &std::path::Path, extra: &[&str]) -> u64 {
    crate::sim_json(file, extra)["cycles"].as_u64().unwrap()
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

/// A tool change on a machine without a tool changer (no `ToolChanged` input in its
/// profile: the daemon asks the operator) is done at once in the simulator, which
/// has no operator: the run ends, as long as one without the M6 (it waited for
/// ever, its trace growing without end).
#[test]
fn a_tool_change_without_a_tool_changer_does_not_stop_the_simulation() {
    let dir = std::env::temp_dir().join(format!("softnc-sim-m6-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |text: &str| {
        let file = dir.join("m6.ngc");
        std::fs::write(&file, text).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_softnc"))
            .arg("sim")
            .arg(&file)
            .arg("--json")
            .arg("--machine")
            .arg(
                PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                    .join("../../config/machines/mill-friction.ron"),
            )
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("softnc runs");
        let t0 = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() {
            if t0.elapsed() > std::time::Duration::from_secs(60) {
                let _ = child.kill();
                panic!("`softnc sim` still runs after 60 s: {text:?}");
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "`softnc sim` failed on {text:?}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["cycles"].as_u64().unwrap()
    };
    // (T0: the profile's tool table is empty; M6 T0 empties the spindle)
    let with = run("G21 G90\nG1 X10 F600\nT0 M6\nG1 X20\nM2\n");
    let without = run("G21 G90\nG1 X10 F600\nG1 X20\nM2\n");
    // the M6 stops the path at X10 (a stop the move without it blends through)
    assert!(
        with >= without && with < without + 1000,
        "with M6 {with} cycles, without {without}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
