//! `build.rs`: the `softnc` binary carries GCC's unwinder instead of loading
//! `libgcc_s.so.1` at its start.

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn softnc_runs_without_libgcc_s() {
    use std::io::Write;
    use std::process::{Command, Stdio};
    // `softnc plan /dev/stdin` waits for its program on a pipe: its mappings can be
    // read while it waits, after the dynamic loader is done
    let mut child = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(["plan", "/dev/stdin", "--json"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let maps_path = format!("/proc/{}/maps", child.id());
    let stat_path = format!("/proc/{}/stat", child.id());
    let started = std::time::Instant::now();
    let maps = loop {
        let maps = std::fs::read_to_string(&maps_path).unwrap();
        // the third field of `stat` is the state: S, asleep in its read
        let asleep = std::fs::read_to_string(&stat_path)
            .unwrap()
            .rsplit(')')
            .next()
            .is_some_and(|rest| rest.trim_start().starts_with('S'));
        if asleep && maps.contains("libc.so") {
            break maps;
        }
        assert!(started.elapsed().as_secs() < 30, "softnc did not start");
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    child
        .stdin
        .take()
        .unwrap()
        .write_all(b"G0 X1\nM2\n")
        .unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "{out:?}");
    assert!(!maps.contains("libgcc_s"), "{maps}");
}
