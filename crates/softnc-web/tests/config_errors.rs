//! `softnc-web` started with a configuration it cannot serve says why and exits
//! (2), starting nothing: no `web` section (the panel is off), a bad `web` value
//! (named by its RON path), a missing file.

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `softnc-web --config FILE --detached`: (exit code, stderr).
fn start(config: &Path) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_softnc-web"))
        .arg("--config")
        .arg(config)
        .arg("--detached")
        .output()
        .expect("softnc-web runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `from`'s files and folders, copied into `to`.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let dest = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &dest);
        } else {
            std::fs::copy(e.path(), dest).unwrap();
        }
    }
}

#[test]
fn a_configuration_it_cannot_serve_is_refused_with_the_reason() {
    let dir = std::env::temp_dir().join(format!("softnc-web-config-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shipped = std::fs::read_to_string(repo().join("config/default.ron")).unwrap();
    // the shipped configuration: the panel is off
    let (code, err) = start(&repo().join("config/default.ron"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no `web` section"), "{err}");
    // a bad listen address and a status rate out of range, each by its RON path
    // (in a copy of the shipped folder: its relative paths resolve as there)
    let config = dir.join("config");
    copy_dir(&repo().join("config"), &config);
    let last = shipped.rfind(')').expect("a RON struct");
    for (web, path) in [
        (
            r#"web: Some((listen: "not an address", token_file: "t")),"#,
            "web.listen",
        ),
        (
            r#"web: Some((token_file: "t", status_hz: 1000.0)),"#,
            "web.status_hz",
        ),
    ] {
        let file = config.join("bad.ron");
        let text = format!("{}    {web}\n{}", &shipped[..last], &shipped[last..]);
        std::fs::write(&file, text).unwrap();
        let (code, err) = start(&file);
        assert_eq!(code, Some(2), "{web}: {err}");
        assert!(err.contains(path), "{web}: {err}");
    }
    // no file at all
    let (code, err) = start(&dir.join("missing.ron"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("missing.ron"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}
