//! Read G-code files and print, per file, one JSON line: the canonical motions as
//! rs274 prints them (the format of `softnc plan --canon` and of the corpus canon
//! files) or the error. A development tool for comparing softnc with LinuxCNC's
//! `rs274` (see `tests/golden/README.md`).
//!
//! `cargo run --release -p softnc-gcode --example canon_dump -- [--offsets "x y z;x y z;..."] FILE...`
//! (`--offsets`: G54.. work offsets in mm; the profile is `config/machines/default.ron`).

use softnc_gcode::{ErrorKind, MotionKind};
use std::path::PathBuf;

fn main() {
    let mut profile = softnc_core::MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .expect("default profile");
    let mut args = std::env::args().skip(1).peekable();
    if args.peek().map(String::as_str) == Some("--offsets") {
        args.next();
        let spec = args.next().unwrap_or_default();
        profile.work_offsets_mm = spec
            .split(';')
            .filter(|s| !s.trim().is_empty())
            .map(|s| {
                let v: Vec<f64> = s.split_whitespace().map(|x| x.parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            })
            .collect();
    }
    for file in args {
        let text = String::from_utf8_lossy(&std::fs::read(&file).unwrap()).into_owned();
        let base = file.rsplit('/').next().unwrap_or(&file).to_string();
        let obj = match softnc_gcode::read_program(&text, &base, &profile) {
            Ok(p) => {
                let motions: Vec<_> = p
                    .motions
                    .iter()
                    .filter_map(|m| {
                        let (end, center) = m.canon_view();
                        Some(match m.kind {
                            MotionKind::Traverse { .. } => serde_json::json!({
                                "kind": "traverse", "end": end?.0, "feed_mm_min": null}),
                            MotionKind::Feed {
                                feed_mm_per_min, ..
                            } => serde_json::json!({
                                "kind": "feed", "end": end?.0, "feed_mm_min": feed_mm_per_min}),
                            MotionKind::Arc {
                                plane,
                                turns,
                                feed_mm_per_min,
                                ..
                            } => {
                                let c = center?.0;
                                let c2 = match plane {
                                    softnc_core::Plane::XY => [c[0], c[1]],
                                    softnc_core::Plane::XZ => [c[0], c[2]],
                                    softnc_core::Plane::YZ => [c[1], c[2]],
                                };
                                serde_json::json!({"kind": "arc", "end": end?.0,
                                    "feed_mm_min": feed_mm_per_min, "plane": plane.name(),
                                    "center2": c2, "turns": turns})
                            }
                            MotionKind::Dwell { .. }
                            | MotionKind::Pause { .. }
                            | MotionKind::Sync
                            | MotionKind::Probe { .. }
                            | MotionKind::Machine(_) => return None,
                        })
                    })
                    .collect();
                // where each motion ends on the machine (mm), for checking the
                // motion frame (offsets, XY rotation) against LinuxCNC's #<_abs_x>…
                let machine: Vec<_> = p
                    .motions
                    .iter()
                    .filter_map(|m| {
                        let e = m.kind.end()?;
                        Some(serde_json::json!({"line": m.line, "inch": m.inch,
                            "mm": (e + m.offset_mm).0}))
                    })
                    .collect();
                serde_json::json!({"file": file, "ok": true, "motions": motions,
                    "machine": machine, "warnings": p.warnings})
            }
            Err(e) => serde_json::json!({"file": file, "ok": false, "error": e.to_string(),
                "unsupported": matches!(e.kind, ErrorKind::Unsupported { .. })}),
        };
        println!("{obj}");
    }
}
