//! What a reading takes in besides the program: subroutine files (regular files,
//! bounded, read once, or a checked job's snapshot) and the modal preamble (only
//! modal words).

use softnc_core::MotionProfile;
use softnc_gcode::{read_program_with, ReadOptions, SubroutineFile, SubroutineFiles};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

fn profile() -> MotionProfile {
    MotionProfile::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap()
}

fn dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("softnc-gcode-files-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const CALLER: &str = "G21 G90\no<sub> call\nM2\n";

/// Read `text` as file `main` with `options` on a thread of its own: a reading that
/// blocks fails the test after 10 s instead of hanging it.
fn read_bounded(
    text: &str,
    main: &Path,
    options: ReadOptions,
) -> Result<softnc_gcode::Program, String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let (text, main) = (text.to_string(), main.display().to_string());
    std::thread::spawn(move || {
        let r = read_program_with(&text, &main, &profile(), &options)
            .map(|(p, _)| p)
            .map_err(|e| e.to_string());
        let _ = tx.send(r);
    });
    rx.recv_timeout(Duration::from_secs(10))
        .expect("the reading blocked: a subroutine file was read without bounds")
}

#[test]
fn a_subroutine_file_is_read_once_and_listed() {
    let d = dir("listed");
    std::fs::write(d.join("sub.ngc"), "o<sub> sub\nG1 X3 F600\no<sub> endsub\n").unwrap();
    let p = read_bounded(
        "G21 G90\no<sub> call\no<sub> call\nM2\n",
        &d.join("main.ngc"),
        ReadOptions::default(),
    )
    .unwrap();
    assert_eq!(p.subroutine_files.len(), 1, "read once");
    let f = &p.subroutine_files[0];
    assert_eq!(f.name, "sub");
    assert_eq!(f.path, d.join("sub.ngc").display().to_string());
    assert_eq!(&*f.bytes, b"o<sub> sub\nG1 X3 F600\no<sub> endsub\n");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_fifo_subroutine_is_refused_without_blocking() {
    let d = dir("fifo");
    let ok = std::process::Command::new("mkfifo")
        .arg(d.join("sub.ngc"))
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "mkfifo");
    let e = read_bounded(CALLER, &d.join("main.ngc"), ReadOptions::default()).unwrap_err();
    assert!(e.contains("sub.ngc") && e.contains("a FIFO"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_subroutine_linked_to_dev_zero_is_refused_unread() {
    let d = dir("zero");
    std::os::unix::fs::symlink("/dev/zero", d.join("sub.ngc")).unwrap();
    let e = read_bounded(CALLER, &d.join("main.ngc"), ReadOptions::default()).unwrap_err();
    assert!(e.contains("character device"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn subroutine_files_over_the_limit_are_refused() {
    let d = dir("big");
    let body = format!("o<sub> sub\n{}o<sub> endsub\n", "(padding)\n".repeat(100));
    std::fs::write(d.join("sub.ngc"), &body).unwrap();
    let options = |max| ReadOptions {
        subroutines: SubroutineFiles {
            max_bytes: Some(max),
            snapshot: None,
        },
        ..Default::default()
    };
    let e = read_bounded(CALLER, &d.join("main.ngc"), options(500)).unwrap_err();
    assert!(e.contains("more than the 500 bytes allowed"), "{e}");
    read_bounded(CALLER, &d.join("main.ngc"), options(10_000)).unwrap();
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn with_a_snapshot_the_checked_files_run_and_the_folders_are_not_read() {
    let d = dir("snapshot");
    // the file on disk now holds another motion: the snapshot's runs
    std::fs::write(
        d.join("sub.ngc"),
        "o<sub> sub\nG1 X90 F600\no<sub> endsub\n",
    )
    .unwrap();
    let checked = SubroutineFile {
        name: "sub".into(),
        path: d.join("sub.ngc").display().to_string(),
        bytes: Arc::from(&b"o<sub> sub\nG1 X3 F600\no<sub> endsub\n"[..]),
    };
    let options = ReadOptions {
        subroutines: SubroutineFiles {
            max_bytes: None,
            snapshot: Some(Arc::new(vec![checked])),
        },
        ..Default::default()
    };
    let p = read_bounded(CALLER, &d.join("elsewhere/main.ngc"), options.clone()).unwrap();
    let end = p.motions.last().unwrap().canon_end;
    assert_eq!(end.0[0], 3.0, "{:?}", p.motions);
    // a subroutine the check did not take in is not read, though on disk
    std::fs::write(
        d.join("other.ngc"),
        "o<other> sub\nG1 X5 F600\no<other> endsub\n",
    )
    .unwrap();
    let e = read_bounded("G21\no<other> call\nM2\n", &d.join("main.ngc"), options).unwrap_err();
    assert!(e.contains("'other'"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}

/// The error reading `CALLER`-like program "G1 X4 F600" with `preamble` gives.
fn with_preamble(preamble: &str) -> Result<softnc_gcode::Program, String> {
    let options = ReadOptions {
        preamble: Some(preamble.into()),
        preamble_file: Some("/data/modal.ngc".into()),
        ..Default::default()
    };
    read_program_with("G1 X4 F600\nM2\n", "job.ngc", &profile(), &options)
        .map(|(p, _)| p)
        .map_err(|e| e.to_string())
}

#[test]
fn a_preamble_holds_only_modal_words() {
    // what the reader writes as a program's end state is taken
    let modes = "G20 G91 G18 G61.1 G55 G94 G99 F20 S1200 M4 M8\nM7\nG0 X1 Z-1\nG1 X2 F30\n%\n";
    let left = read_program_with(
        &format!("%\n{modes}"),
        "m.ngc",
        &profile(),
        &Default::default(),
    )
    .unwrap()
    .0
    .end_modal;
    with_preamble(&left).unwrap_or_else(|e| panic!("{left}: {e}"));
    with_preamble(
        "G21\nT1 M6\nF600 S0 G17 G40 G43.1 Z32.5 G90 G94 G54 G64 P0.01 Q0.01\nG1\nM3\nM8\n",
    )
    .unwrap();
    // anything else is refused, by file, line and column, and nothing is read
    for (pre, line, col, what) in [
        ("G21\nG0 X50\n", 2, 4, "X50 is an axis word"),
        ("G21\nG1 Z-3\n", 2, 4, "Z-3 is an axis word"),
        ("G10 L2 P1 X5\n", 1, 1, "G10 is not a modal word"),
        ("G4 P2\n", 1, 1, "G4 is not a modal word"),
        ("G92 X0\n", 1, 1, "G92 is not a modal word"),
        ("G21\n#1=5\n", 2, 1, "a parameter"),
        ("o100 call\n", 1, 1, "an O-word"),
        ("G43 H1\n", 1, 1, "G43 is not a modal word"),
        ("M0\n", 1, 1, "M0 is not a modal word"),
        ("(MSG, hello)\n", 1, 1, "a comment"),
        ("G1 F100 R5\n", 1, 9, "R5 is not a modal word here"),
    ] {
        let e = with_preamble(pre).unwrap_err();
        assert!(
            e.starts_with(&format!("/data/modal.ngc:{line}:{col}: ")) && e.contains(what),
            "{pre:?}: {e}"
        );
        assert!(e.contains("may hold only modal words"), "{e}");
    }
}
