//! Issue 35 ("Jog"): `softnc jog` stops its jog at once on SIGINT (Ctrl-C) and
//! SIGTERM, end to end: the `softnc` binary jogs an axis of a real-time `softncd`,
//! the test signals it mid-jog, and the axis comes to rest far within the overrun the
//! dead-man would allow (jog speed × the profile's `jog.deadman_s`); the command exits 128 + the
//! signal, saying so.
//!
//! A test of the `softnc-cli` package (where `softnc` is built with it), on the
//! shared harness; its `softncd` is the one built beside `softnc`.
#[allow(unused_imports)] // the shared harness re-exports what other test files use
mod support;
use std::io::Read;
use std::process::Stdio;
use support::*;

/// The jog speed (mm/min) of the issue's `softnc jog Z 3000`.
const JOG_MM_PER_MIN: f64 = 3000.0;

/// How long `softnc` may take to exit after the signal.
const EXIT_WITHIN: Duration = Duration::from_secs(1);

/// Z of the machine position in the status.
fn z_mm(op: &Operator) -> f64 {
    machine_mm(&op.status().unwrap())[2]
}

/// Jog Z at `speed_mm_per_min` with `softnc jog`, send it `sig` once the axis has
/// moved 5 mm at speed, and check that the command exits 128 + `sig` promptly and
/// that the axis stops within `bound_mm` of where it was at the signal. The
/// distance run after the signal (mm).
fn jog_then_signal(
    d: &Daemon,
    op: &Operator,
    speed_mm_per_min: f64,
    sig: libc::c_int,
    sig_name: &str,
    bound_mm: f64,
) -> f64 {
    let z0 = z_mm(op);
    let mut child = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .arg("--config")
        .arg(&d.config)
        .args(["jog", "Z", &speed_mm_per_min.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softnc runs");
    // at full speed: 5 mm from the start (the speed is reached within 1 mm)
    d.wait_status(op, Duration::from_secs(10), "the jog under way", |s| {
        s.state == MachineState::Jogging && (machine_mm(s)[2] - z0).abs() > 5.0
    });
    assert!(
        child.try_wait().unwrap().is_none(),
        "softnc jog ended by itself"
    );
    let z_signal = z_mm(op);
    let t_signal = Instant::now();
    // the child is not reaped yet (it still runs): its pid is its own
    let sent = Command::new("kill")
        .args([format!("-{sig}"), child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success(), "kill -{sig_name} {}", child.id());
    let status = loop {
        if let Some(st) = child.try_wait().unwrap() {
            break st;
        }
        if t_signal.elapsed() > EXIT_WITHIN {
            let _ = child.kill();
            let _ = child.wait();
            panic!("softnc jog still running {EXIT_WITHIN:?} after {sig_name}");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let exited_after = t_signal.elapsed();
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
    assert_eq!(
        status.code(),
        Some(128 + sig),
        "softnc jog after {sig_name}: {status}\nstdout: {out}\nstderr: {err}"
    );
    assert!(
        err.contains(&format!("stopped by {sig_name}")),
        "softnc says why it stopped: {err}"
    );
    let s = d.wait_status(op, Duration::from_secs(2), "the jog stopped", |s| {
        s.state != MachineState::Jogging
    });
    let at_rest_after = t_signal.elapsed();
    let overrun_mm = (machine_mm(&s)[2] - z_signal).abs();
    eprintln!(
        "{sig_name} at Z {z_signal:.4}: at rest at Z {:.4} ({overrun_mm:.3} mm further, \
         {at_rest_after:?} after the signal); softnc exited after {exited_after:?}",
        machine_mm(&s)[2]
    );
    assert_eq!(s.state, MachineState::Idle, "{s}");
    assert!(
        overrun_mm < bound_mm,
        "{sig_name}: the axis ran {overrun_mm:.3} mm after the signal (bound {bound_mm} mm)"
    );
    assert!(
        !alarm_text(&s).contains("did not renew"),
        "stopped by the CLI, not by the dead-man: {}",
        alarm_text(&s)
    );
    overrun_mm
}

#[test]
fn softnc_jog_stops_at_once_on_sigint_and_sigterm() {
    let d = Daemon::start("jog", "Realtime", false);
    let loaded = softnc_daemon::config::DaemonConfig::load(&d.config).unwrap();
    let deadman_s = loaded.machine.jog.deadman_s;
    // what the dead-man alone lets the axis run (the 21.8 mm at 3000 mm/min
    // with the 0.5 s dead-man before issue 35), then its deceleration v²/2a
    let v_mm_per_s = JOG_MM_PER_MIN / 60.0;
    let decel_mm = v_mm_per_s.powi(2) / (2.0 * loaded.machine.axes[2].max_acc_mm_per_s2);
    let deadman_overrun_mm = v_mm_per_s * deadman_s;
    // a prompt stop: the signal seen within 5 ms, one request and the status's own
    // staleness — 30 ms at speed all told — and the deceleration; well short of
    // what the dead-man would let it run
    let bound_mm = decel_mm + v_mm_per_s * 0.03;
    assert!(bound_mm < deadman_overrun_mm + decel_mm);
    let op = d.operator();
    // Z from 0 toward -300 (homed at start: the soft limit is 300 mm away), back up
    let down = jog_then_signal(&d, &op, -JOG_MM_PER_MIN, libc::SIGINT, "SIGINT", bound_mm);
    let up = jog_then_signal(&d, &op, JOG_MM_PER_MIN, libc::SIGTERM, "SIGTERM", bound_mm);
    eprintln!(
        "overrun after the signal: SIGINT {down:.3} mm, SIGTERM {up:.3} mm; \
         the dead-man's ({deadman_s} s) would be {deadman_overrun_mm:.1} mm"
    );
}
