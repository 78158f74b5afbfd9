//! Whole sample streams of a streamed plan against the whole plan's, file by file:
//! `cargo run --release -p softnc-planner --example stream_corpus -- FILE...`
//! (profile `config/machines/default.ron`, trapezoidal and S-curve, soft limits
//! ignored; `ARC_BLENDS=1`: with `planner.arc_blends` on). Prints one line per file
//! that differs and a summary; exits 1 if any differs.
use softnc_core::FeedProfile;
use softnc_planner::{check_and_stream, read_and_plan, PlanOptions};

#[path = "../benches/common/workload.rs"]
mod workload;

fn main() {
    let opts = PlanOptions {
        ignore_soft_limits: true,
        ..Default::default()
    };
    let (mut same, mut differ, mut refused, mut samples) = (0, 0, 0, 0u64);
    for file in std::env::args().skip(1) {
        let Ok(bytes) = std::fs::read(&file) else {
            continue;
        };
        let text = String::from_utf8_lossy(&bytes).into_owned();
        for fp in [FeedProfile::Trapezoidal, FeedProfile::SCurve] {
            let mut profile = workload::default_profile();
            profile.planner.feed_profile = fp;
            profile.planner.arc_blends |= std::env::var("ARC_BLENDS").is_ok_and(|v| v == "1");
            let whole = read_and_plan(&text, &file, &profile, &opts);
            let streamed = check_and_stream(&text, &file, &profile, &opts, |it| {
                let Ok((_, plan)) = &whole else {
                    return (0u64, false, 0u64);
                };
                let mut n = 0u64;
                let mut equal = true;
                let mut w = plan.interpolator();
                for s in it.by_ref() {
                    n += 1;
                    equal &= w.next() == Some(s);
                }
                equal &= w.next().is_none();
                (n, equal, it.starved())
            });
            match (&whole, streamed) {
                (Err(a), Err(b)) if *a == b => refused += 1,
                (Ok((_, plan)), Ok((checked, (n, true, 0)))) if checked.stats() == plan.stats() => {
                    same += 1;
                    samples += n;
                }
                (w, s) => {
                    differ += 1;
                    println!(
                        "{file} {fp:?}: DIFFERS whole {:?} streamed {:?}",
                        w.as_ref().map(|(_, p)| p.stats()),
                        s.map(|(c, r)| (c.stats(), r))
                    );
                }
            }
        }
    }
    println!(
        "stream_corpus: {same} identical ({samples} samples), {refused} refused alike, {differ} differ"
    );
    if differ > 0 {
        std::process::exit(1);
    }
}
