//! `softnc plan --params FILE [--save-params]`: a LinuxCNC-style parameter file
//! read at the start and written back (atomically) as the program left it; and
//! `--log-dir DIR`, where a program's `(LOGOPEN,…)` files go.

use std::path::PathBuf;
use std::process::{Command, Output};

fn softnc(args: &[&str], dir: &PathBuf) -> Output {
    Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(args)
        .arg("--machine")
        .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"))
        .current_dir(dir)
        .output()
        .expect("softnc runs")
}

#[test]
fn parameters_persist_between_runs_and_bad_files_are_refused() {
    let dir = std::env::temp_dir().join(format!("softnc-plan-params-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("set.ngc"), "G10 L2 P1 X5\nG0 X1\nM2\n").unwrap();
    std::fs::write(dir.join("use.ngc"), "G0 X#5221\nM2\n").unwrap();
    let first = softnc(
        &[
            "plan",
            "set.ngc",
            "--params",
            "m.var",
            "--save-params",
            "--canon",
        ],
        &dir,
    );
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let var = std::fs::read_to_string(dir.join("m.var")).unwrap();
    assert!(var.contains("5221\t5.000000\n"), "{var}");
    // the next run starts with G54 at X5: X#5221 is X5 in the program, 10 on the machine
    let second = softnc(&["plan", "use.ngc", "--params", "m.var", "--canon"], &dir);
    let out = String::from_utf8_lossy(&second.stdout);
    assert!(out.contains("\"end\":[5.0,0.0,0.0]"), "{out}");
    std::fs::write(dir.join("bad.var"), "5221 1\n5161 2\n").unwrap();
    let bad = softnc(&["plan", "use.ngc", "--params", "bad.var"], &dir);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("bad.var:2: parameter file out of order"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn log_files_go_into_the_log_dir_once_the_program_is_planned() {
    let dir = std::env::temp_dir().join(format!("softnc-plan-logs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("log.ngc"),
        "G21\n(LOGOPEN,out.txt)\n#1=3\n(LOG,depth #1)\n(LOGCLOSE)\nG0 X1\nM2\n",
    )
    .unwrap();
    // without --log-dir: refused as unsupported, nothing written
    let no = softnc(&["plan", "log.ngc"], &dir);
    assert_eq!(no.status.code(), Some(2));
    let err = String::from_utf8_lossy(&no.stderr);
    assert!(
        err.contains("log.ngc:2:") && err.contains("unsupported"),
        "{err}"
    );
    assert!(!dir.join("out.txt").exists());
    let ok = softnc(&["plan", "log.ngc", "--log-dir", "logs"], &dir);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    assert_eq!(
        std::fs::read_to_string(dir.join("logs/out.txt")).unwrap(),
        "depth 3.000000\n"
    );
    // a program over the travel is not planned: its log is not written
    std::fs::write(
        dir.join("far.ngc"),
        "G21\n(LOGOPEN,far.txt)\n(LOG,x)\nG0 X100000\nM2\n",
    )
    .unwrap();
    let far = softnc(&["plan", "far.ngc", "--log-dir", "logs"], &dir);
    assert_eq!(
        far.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&far.stderr)
    );
    assert!(!dir.join("logs/far.txt").exists());
    std::fs::remove_dir_all(&dir).ok();
}
