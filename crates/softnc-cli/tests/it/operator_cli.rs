//! Issue 34 ("also failing"): the operator client from outside, without a
//! controller: every command says so within seconds, a closed pipe ends it quietly,
//! negative values are values.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// How long any command may take to say that no controller runs.
const NO_CONTROLLER_WITHIN: Duration = Duration::from_secs(10);

fn ws(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

/// A configuration of an instance no controller runs (in cargo's test scratch folder).
fn config_without_controller(tag: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("operator-cli-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("machines")).unwrap();
    std::fs::copy(ws("config/iceoryx2.toml"), dir.join("iceoryx2.toml")).unwrap();
    std::fs::copy(
        ws("config/machines/default.ron"),
        dir.join("machines/default.ron"),
    )
    .unwrap();
    let cfg = std::fs::read_to_string(ws("config/default.ron"))
        .unwrap()
        .replace(
            "instance: \"mill1\"",
            &format!("instance: \"nobody{tag}{}\"", std::process::id()),
        )
        .replace("data_dir: \"../data\"", "data_dir: \"data\"");
    std::fs::write(dir.join("default.ron"), cfg).unwrap();
    dir.join("default.ron")
}

/// Run `softnc --config CONFIG ARGS`, at most `limit`: (exit code, stdout, stderr,
/// how long), or a failure naming the command if it runs longer.
fn softnc(
    config: &Path,
    args: &[&str],
    limit: Duration,
) -> (Option<i32>, String, String, Duration) {
    let t0 = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("--config")
        .arg(config)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            let (mut out, mut err) = (String::new(), String::new());
            child
                .stdout
                .take()
                .unwrap()
                .read_to_string(&mut out)
                .unwrap();
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return (st.code(), out, err, t0.elapsed());
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("softnc {args:?} still running after {limit:?} with no controller");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn every_operator_command_says_within_seconds_that_no_controller_runs() {
    let config = config_without_controller("none");
    let job = ws("examples/learning/lines-arcs.ngc");
    let job = job.to_str().unwrap();
    let commands: &[&[&str]] = &[
        &["status"],
        &["job", "submit", job],
        &["mdi", "G0 X1"],
        &["touch-off", "x", "0"],
        &["estop"],
        &["jobs"],
    ];
    for args in commands {
        let (code, _, err, took) = softnc(&config, args, NO_CONTROLLER_WITHIN);
        assert_ne!(code, Some(0), "softnc {args:?}: {err}");
        assert!(
            err.contains("no controller running"),
            "softnc {args:?} after {took:?}: {err}"
        );
    }
}

#[test]
fn negative_values_are_values_and_an_out_of_range_override_is_the_controllers_to_refuse() {
    let config = config_without_controller("neg");
    for args in [
        &["override", "-5"][..],
        &["spindle-override", "-5"],
        &["rapid-override", "-5"],
        &["tools", "set", "1", "--length", "-42.5"],
        &["touch-off", "x", "-3.5"],
    ] {
        let (code, _, err, _) = softnc(&config, args, NO_CONTROLLER_WITHIN);
        // parsed (not clap's exit 2 about an unexpected argument): sent, and here
        // no controller answers
        assert!(
            !err.contains("unexpected argument") && code != Some(2),
            "softnc {args:?}: {code:?} {err}"
        );
        assert!(
            err.contains("no controller running"),
            "softnc {args:?}: {err}"
        );
    }
}

#[test]
fn a_closed_pipe_ends_the_output_quietly() {
    // a long output (the canonical calls of a long program) read by `head -c 100`
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("operator-cli-pipe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let program = dir.join("long.ngc");
    let mut text = String::from("G21 G90 G17\nG0 X0 Y0 Z5\n");
    for i in 0..20000 {
        text += &format!("G1 X{} Y{} F1000\n", i % 100, (i / 100) % 100);
    }
    text += "M2\n";
    std::fs::write(&program, text).unwrap();
    let out = Command::new("sh")
        .args([
            "-c",
            "\"$1\" plan \"$2\" --canon --machine \"$3\" | head -c 100 >/dev/null; echo \"${PIPESTATUS:-}\"",
            "sh",
        ])
        .arg(env!("CARGO_BIN_EXE_softnc"))
        .arg(&program)
        .arg(ws("config/machines/default.ron"))
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !err.contains("panicked"),
        "softnc panicked on the closed pipe: {err}"
    );
    assert!(
        !err.contains("Broken pipe"),
        "softnc complained of the closed pipe: {err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
