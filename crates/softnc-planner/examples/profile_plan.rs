//! Parse and plan a G-code file `repeat` times (for profilers): `cargo run --release
//! -p softnc-planner --example profile_plan -- FILE [repeat]`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let text = std::fs::read_to_string(&args[1]).expect("file");
    let repeat: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let profile = softnc_core::MachineProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .expect("profile");
    let (mut tp, mut tl) = (0.0, 0.0);
    for _ in 0..repeat {
        let t0 = std::time::Instant::now();
        let p = softnc_gcode::read_program(&text, "f", &profile).expect("reads");
        let t1 = std::time::Instant::now();
        let plan = softnc_planner::plan(
            &p,
            &profile,
            &softnc_planner::PlanOptions {
                ignore_soft_limits: true,
            },
        )
        .unwrap();
        let t2 = std::time::Instant::now();
        std::hint::black_box(plan.stats());
        tp += (t1 - t0).as_secs_f64();
        tl += (t2 - t1).as_secs_f64();
    }
    let lines = text.lines().count() as f64 * repeat as f64;
    println!(
        "parse {:.0} ns/line, plan {:.0} ns/line",
        tp / lines * 1e9,
        tl / lines * 1e9
    );
}
