//! One line per G-code file: the error, or a digest of the motions read (every bit of
//! every field), the warnings, the plan's figures and number of elements, whether
//! `read_and_plan` gives the same figures (`read_and_plan_parallel` is flagged if it
//! does not), the figures or refusal with the soft limits checked, and with
//! `SAMPLES=1` a digest of the whole sample stream. For checking that a change (a
//! faster reader or planner) leaves the output bit for bit as it was: run the old and
//! the new build on the same files and compare. `cargo run --release -p
//! softnc-planner --example plan_digest -- FILE...` (profile
//! `config/machines/default.ron`).
use std::hash::{Hash, Hasher};

#[path = "../benches/common/workload.rs"]
mod workload;

fn main() {
    let profile = workload::default_profile();
    let sample = std::env::var("SAMPLES").is_ok();
    for file in std::env::args().skip(1) {
        let Ok(bytes) = std::fs::read(&file) else {
            continue;
        };
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let mut h = std::collections::hash_map::DefaultHasher::new();
        match softnc_gcode::read_program(&text, &file, &profile) {
            Err(e) => println!("{file}: ERR {e}"),
            Ok(p) => {
                for m in &p.motions {
                    format!("{m:?}").hash(&mut h);
                }
                let opts = softnc_planner::PlanOptions {
                    ignore_soft_limits: true,
                    ..Default::default()
                };
                let plan = softnc_planner::plan(&p, &profile, &opts);
                let (stats, elems, sh) = match &plan {
                    Ok(plan) => {
                        let mut sh = std::collections::hash_map::DefaultHasher::new();
                        if sample {
                            for s in plan.interpolator() {
                                format!("{:?}", s.pos_mm).hash(&mut sh);
                            }
                        }
                        (format!("{:?}", plan.stats()), plan.elements(), sh.finish())
                    }
                    Err(e) => (format!("{e}"), 0, 0),
                };
                let st = softnc_planner::read_and_plan(&text, &file, &profile, &opts)
                    .map(|(_, p)| format!("{:?}", p.stats()))
                    .unwrap_or_else(|e| format!("{e}"));
                // with the soft limits checked: the figures or the refusal
                let soft = softnc_planner::plan(&p, &profile, &Default::default())
                    .map(|plan| format!("{:?}", plan.stats()))
                    .unwrap_or_else(|e| format!("{e}"));
                let par = softnc_planner::read_and_plan_parallel(&text, &file, &profile, &opts)
                    .map(|(_, p)| format!("{:?}", p.stats()))
                    .unwrap_or_else(|e| format!("{e}"));
                println!(
                    "{file}: {} motions {:x} warn {:?} plan {stats} elems {elems} samples {sh:x} stream_same {}{} soft {soft}",
                    p.motions.len(),
                    h.finish(),
                    p.warnings,
                    st == stats,
                    if par == stats { "" } else { " PARALLEL DIFFERS" }
                );
            }
        }
    }
}
