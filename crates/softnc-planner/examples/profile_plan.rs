//! Parse and plan a G-code file `repeat` times (for profilers and quick timing): `cargo
//! run --release -p softnc-planner --example profile_plan -- FILE [repeat]`. Prints the
//! best and mean time per line of: reading then planning (`read_program` + `plan`),
//! reading alone (`read_program`, all motions kept; `chunks`: handed on in chunks of
//! 1024 and dropped, the reader's share of the streaming runs), the streaming
//! `read_and_plan`, `read_and_plan_parallel` (two threads), and the checking passes
//! `check_program` (`check`) and `check_program_parallel` (`check2`). A third
//! argument runs only the named one. `ARC_BLENDS=1` turns `planner.arc_blends` on.
use softnc_planner::PlanOptions;

#[path = "../benches/common/workload.rs"]
mod workload;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&args[1]).expect("file");
    let repeat: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let only = args.get(3).cloned();
    let mut profile = workload::default_profile();
    // ARC_BLENDS=1: with `planner.arc_blends` on (line–arc and arc–arc fillets)
    profile.planner.arc_blends |= std::env::var("ARC_BLENDS").is_ok_and(|v| v == "1");
    let opts = PlanOptions {
        ignore_soft_limits: true,
        ..Default::default()
    };
    let lines = text.lines().count() as f64;
    println!(
        "{lines} lines; per element: Segment {} bytes, Geom {} bytes",
        std::mem::size_of::<softnc_planner::build::Segment>(),
        std::mem::size_of::<softnc_planner::path::Geom>()
    );
    let time = |name: &str, f: &dyn Fn() -> (f64, f64)| {
        if only.as_deref().is_some_and(|o| o != name) {
            return;
        }
        let (mut best, mut sum, mut read_sum) = (f64::INFINITY, 0.0, 0.0);
        for _ in 0..repeat {
            let (total, read) = f();
            best = best.min(total);
            sum += total;
            read_sum += read;
        }
        let n = repeat as f64;
        println!(
            "{name:>9}: best {:.0} ns/line ({:.2} M lines/s), mean {:.0} ns/line{}",
            best / lines * 1e9,
            lines / best / 1e6,
            sum / n / lines * 1e9,
            if read_sum > 0.0 {
                format!(" (of which reading {:.0})", read_sum / n / lines * 1e9)
            } else {
                String::new()
            }
        );
    };
    time("two-step", &|| {
        let t0 = std::time::Instant::now();
        let p = softnc_gcode::read_program(&text, "f", &profile).expect("reads");
        let t1 = std::time::Instant::now();
        let plan = softnc_planner::plan(&p, &profile, &opts).unwrap();
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(plan.stats());
        (total, (t1 - t0).as_secs_f64())
    });
    time("read", &|| {
        let t0 = std::time::Instant::now();
        let p = softnc_gcode::read_program(&text, "f", &profile).expect("reads");
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(p.motions.len());
        (total, 0.0)
    });
    time("chunks", &|| {
        let t0 = std::time::Instant::now();
        let mut n = 0;
        let p = softnc_gcode::read_program_chunked(&text, "f", &profile, 1024, &mut |c| {
            n += c.len();
        })
        .expect("reads");
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box((p.blocks, n));
        (total, 0.0)
    });
    time("stream", &|| {
        let t0 = std::time::Instant::now();
        let (_, plan) = softnc_planner::read_and_plan(&text, "f", &profile, &opts).unwrap();
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(plan.stats());
        (total, 0.0)
    });
    time("parallel", &|| {
        let t0 = std::time::Instant::now();
        let (_, plan) =
            softnc_planner::read_and_plan_parallel(&text, "f", &profile, &opts).unwrap();
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(plan.stats());
        (total, 0.0)
    });
    time("check", &|| {
        let t0 = std::time::Instant::now();
        let (_, c) = softnc_planner::check_program(&text, "f", &profile, &opts).unwrap();
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(c.stats());
        (total, 0.0)
    });
    time("check2", &|| {
        let t0 = std::time::Instant::now();
        let (_, c) = softnc_planner::check_program_parallel(&text, "f", &profile, &opts).unwrap();
        let total = t0.elapsed().as_secs_f64();
        std::hint::black_box(c.stats());
        (total, 0.0)
    });
}
