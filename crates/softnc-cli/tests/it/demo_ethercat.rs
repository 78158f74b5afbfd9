//! `softnc demo --backend ethercat-emulated` with a short job (root needed: a veth
//! pair and packet sockets; SKIPPED otherwise): softncd's three processes drive the
//! emulated CiA 402 drives over EtherCAT, the job completes with every planned
//! sample run, every drive received at least as many targets as the job had
//! cycles, and the report carries the MainDevice's bus figures.

use std::process::Command;

/// A few moves, about a second.
const JOB: &str = "G21 G90 G17\nG1 X5 Y3 Z-1 F1200\nG1 X0 Y0 Z0\nM2\n";

#[test]
fn the_demo_job_runs_over_the_emulated_bus() {
    let _one = crate::one_controller_at_a_time();
    if !softnc_ethercat_emu::veth::is_root() {
        println!("SKIPPED: needs root (a veth pair and packet sockets)");
        return;
    }
    let dir = std::env::temp_dir().join(format!("softnc-demo-ethercat-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let job = dir.join("short.ngc");
    std::fs::write(&job, JOB).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(["demo", "--backend", "ethercat-emulated", "--json", "--job"])
        .arg(&job)
        .env_remove("SOFTNC_CONFIG")
        .env("RUST_LOG", "warn")
        .output()
        .expect("softnc runs");
    let _ = std::fs::remove_dir_all(&dir);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stderr}");
    assert!(out.status.success(), "softnc demo failed: {stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["outcome"], "completed", "{report}");
    let cycles = report["job"]["cycles"].as_u64().unwrap_or(0);
    let planned = report["job"]["planned_samples"].as_u64().unwrap_or(0);
    assert!(
        cycles > 0 && cycles == planned,
        "cycles {cycles} of {planned} planned: {report}"
    );
    // the MainDevice's bus figures in the report
    let bus = &report["loops"]["bus"];
    let frames = bus["frames"].as_u64().unwrap_or(0);
    assert!(
        frames >= cycles,
        "bus frames {frames} for {cycles} cycles: {report}"
    );
    assert_eq!(bus["lost_frames"], 0, "{report}");
    assert_eq!(bus["wkc_errors"], 0, "{report}");
    let rtt = &bus["send_to_receive_ns"];
    assert!(
        rtt["p50"].as_u64().unwrap_or(0) > 0
            && rtt["p99"].as_u64() >= rtt["p50"].as_u64()
            && rtt["max"].as_u64().unwrap_or(0) > 0,
        "{report}"
    );
    // the DC deviation: read during the job, and small (the emulated clocks all
    // run from the host's)
    let reads = bus["dc_deviation_reads"].as_u64().unwrap_or(0);
    let dc_max = bus["dc_deviation_max_ns"].as_u64().unwrap_or(u64::MAX);
    assert!(
        reads >= cycles / 250 / 2 && reads > 0 && dc_max < 100_000,
        "DC deviation reads {reads}, max {dc_max} ns: {report}"
    );
    let drives: Vec<u64> = stderr
        .lines()
        .filter_map(|l| l.trim().strip_prefix("drive "))
        .filter_map(|l| l.split_whitespace().nth(1)?.parse().ok())
        .collect();
    assert_eq!(drives.len(), 3, "three drives reported: {stderr}");
    for t in drives {
        assert!(
            t >= cycles,
            "a drive received {t} targets for {cycles} cycles"
        );
    }
}
