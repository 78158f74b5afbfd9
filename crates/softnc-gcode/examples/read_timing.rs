//! Time reading one file: the best of N runs (less noisy than a mean on a busy machine).
//! `cargo run --release -p softnc-gcode --example read_timing -- FILE [N]`

fn main() {
    let mut args = std::env::args().skip(1);
    let file = args.next().expect("FILE");
    let n: usize = args.next().map_or(10, |s| s.parse().unwrap());
    let profile = softnc_core::MotionProfile::load(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../config/machines/default.ron"
        )
        .as_ref(),
    )
    .unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    let lines = text.lines().count();
    let mut best = f64::INFINITY;
    let mut motions = 0;
    for _ in 0..n {
        let t = std::time::Instant::now();
        let p = softnc_gcode::read_program(&text, &file, &profile).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        motions = p.motions.len();
    }
    println!(
        "{lines} lines, {motions} motions: best {:.1} ms = {:.2} M lines/s (Motion = {} bytes)",
        best * 1e3,
        lines as f64 / best / 1e6,
        std::mem::size_of::<softnc_gcode::Motion>()
    );
}
