//! Parse + plan throughput against LinuxCNC's stand-alone interpreter on the same file
//! and machine, in interleaved rounds (issue 2's figure): `cargo run --release -p
//! softnc-planner --example vs_rs274 -- [ROUNDS] [LINES]`.
//!
//! Writes the benchmark program (`benches/common/workload.rs`, 200,000 lines by
//! default) to `$TMPDIR/softnc-big-200k.ngc`. Each round times one `rs274 -g FILE
//! /dev/null < /dev/null` (LinuxCNC 2.9, Debian's `linuxcnc-uspace`; another binary
//! via `RS274=PATH`) three times, then softnc's `read_and_plan` (one thread),
//! `read_and_plan_parallel` (two threads) and `check_program_parallel` (the checking
//! pass `softnc plan` prints its summary from, two threads) five times each, each run reading the file
//! from disk inside the timing as `rs274` does, and prints the ratio of the best runs'
//! lines per second. On a shared machine the speed of both swings from one
//! second to the next; the rounds keep each ratio within a few seconds, and the
//! summary gives their median and range.
use softnc_planner::{check_program_parallel, read_and_plan, read_and_plan_parallel, PlanOptions};
use std::process::{Command, ExitCode, Stdio};
use std::time::Instant;

#[path = "../benches/common/workload.rs"]
mod workload;

#[allow(clippy::too_many_lines)]
fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    let rounds: usize = args
        .get(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(11)
        .max(1);
    let lines: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(200_000);
    let rs274 = std::env::var("RS274").unwrap_or_else(|_| "rs274".into());
    let profile = workload::default_profile();
    let opts = PlanOptions {
        ignore_soft_limits: true,
        ..Default::default()
    };
    let file = std::env::temp_dir().join(format!("softnc-big-{}k.ngc", lines / 1000));
    let text = workload::big_program(lines);
    let n_lines = text.lines().count() as f64;
    if let Err(e) = std::fs::write(&file, &text) {
        eprintln!("vs_rs274: cannot write {}: {e}", file.display());
        return ExitCode::from(2);
    }
    let run_rs274 = || -> Result<f64, String> {
        let t0 = Instant::now();
        let status = Command::new(&rs274)
            .arg("-g")
            .arg(&file)
            .arg("/dev/null")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .map_err(|e| {
                format!("cannot run {rs274}: {e} (apt-get install linuxcnc-uspace, or RS274=PATH)")
            })?;
        let s = t0.elapsed().as_secs_f64();
        if status.success() {
            Ok(s)
        } else {
            Err(format!("{rs274} failed on {}: {status}", file.display()))
        }
    };
    let best_of_5 = |mode: u8| -> f64 {
        (0..5)
            .map(|_| {
                let t0 = Instant::now();
                let text = std::fs::read_to_string(&file).expect("the file just written");
                let stats = match mode {
                    0 => read_and_plan(&text, "big.ngc", &profile, &opts).map(|p| p.1.stats()),
                    1 => read_and_plan_parallel(&text, "big.ngc", &profile, &opts)
                        .map(|p| p.1.stats()),
                    _ => check_program_parallel(&text, "big.ngc", &profile, &opts)
                        .map(|p| p.1.stats()),
                }
                .expect("the workload plans");
                std::hint::black_box(stats);
                t0.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    println!(
        "{} lines ({}); lines per second, ratio to rs274 in the same round",
        n_lines,
        file.display()
    );
    println!(
        "round  rs274          one thread             two threads            check, two threads"
    );
    let (mut one, mut two, mut check) = (Vec::new(), Vec::new(), Vec::new());
    for round in 1..=rounds {
        let mut best_rs274_s = f64::INFINITY;
        let mut failures = 0;
        let mut runs = 0;
        while runs < 3 {
            match run_rs274() {
                Ok(s) => {
                    best_rs274_s = best_rs274_s.min(s);
                    runs += 1;
                }
                // rs274 on the shared machine dies now and then (SIGBUS): run it again
                Err(e) if failures < 3 => {
                    eprintln!("vs_rs274: {e}; again");
                    failures += 1;
                }
                Err(e) => {
                    eprintln!("vs_rs274: {e}");
                    return ExitCode::from(2);
                }
            }
        }
        let rs = n_lines / best_rs274_s;
        let r1 = n_lines / best_of_5(0);
        let r2 = n_lines / best_of_5(1);
        let r3 = n_lines / best_of_5(2);
        println!(
            "{round:>5}  {:>6.3} M/s   {:>6.2} M/s ({:>5.1}×)   {:>6.2} M/s ({:>5.1}×)   {:>6.2} M/s ({:>5.1}×)",
            rs / 1e6,
            r1 / 1e6,
            r1 / rs,
            r2 / 1e6,
            r2 / rs,
            r3 / 1e6,
            r3 / rs
        );
        one.push(r1 / rs);
        two.push(r2 / rs);
        check.push(r3 / rs);
    }
    for (name, v) in [
        ("one thread", &mut one),
        ("two threads", &mut two),
        ("check, two threads", &mut check),
    ] {
        v.sort_by(f64::total_cmp);
        let at_least_20 = v.iter().filter(|&&r| r >= 20.0).count();
        println!(
            "{name}: median {:.1}×, range {:.1}–{:.1}×, ≥ 20× in {at_least_20} of {} rounds",
            v[v.len() / 2],
            v[0],
            v[v.len() - 1],
            v.len()
        );
    }
    ExitCode::SUCCESS
}
