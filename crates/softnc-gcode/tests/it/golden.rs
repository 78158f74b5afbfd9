//! Golden fixtures: small programs covering the dialect (`tests/golden/*.ngc`) and
//! LinuxCNC's reading of each (`*.canon.json`, made by `tests/golden/regen.sh` from
//! `rs274`'s output with `rs274_to_canon.py`). softnc must produce the same canonical
//! motions to within 1e-4 mm. CI needs no `rs274`: the expected files are committed.

use serde_json::Value;
use softnc_core::{MotionProfile, Plane};
use softnc_gcode::{MotionKind, PathMode};
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// The default machine with the work offsets of `golden.var` (inches there, mm here).
fn profile() -> MotionProfile {
    let mut p = MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap();
    let mut offsets = vec![[0.0; 3]; 6];
    for line in std::fs::read_to_string(dir().join("golden.var"))
        .unwrap()
        .lines()
    {
        let mut it = line.split_whitespace();
        let (Some(n), Some(v)) = (it.next(), it.next()) else {
            continue;
        };
        let n: usize = n.parse().unwrap();
        let v: f64 = v.parse().unwrap();
        // G54 = 5221.., G55 = 5241.., ... G59 = 5321..
        let sys = (n - 5201) / 20 - 1;
        let axis = (n - 5201) % 20;
        offsets[sys][axis] = v * 25.4;
    }
    p.work_offsets_mm = offsets;
    p
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn check(path: &Path, profile: &MotionProfile) -> Result<usize, String> {
    let name = path.file_name().unwrap().to_string_lossy().to_string();
    let text = std::fs::read_to_string(path).unwrap();
    let expected: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(path.with_extension("canon.json")).unwrap())
            .unwrap();
    let program = softnc_gcode::read_program(&text, &name, profile).map_err(|e| e.to_string())?;
    let got: Vec<_> = program
        .motions
        .iter()
        .filter(|m| m.kind.end().is_some())
        .collect();
    if got.len() != expected.len() {
        return Err(format!(
            "{} motions, expected {}",
            got.len(),
            expected.len()
        ));
    }
    for (k, (m, e)) in got.iter().zip(&expected).enumerate() {
        let (end, center) = m.canon_view();
        let end = end.unwrap();
        let want_end = nums(&e["end"]);
        let kind = match m.kind {
            MotionKind::Traverse { .. } => "traverse",
            MotionKind::Feed { .. } => "feed",
            MotionKind::Arc { .. } => "arc",
            MotionKind::Dwell { .. }
            | MotionKind::Pause { .. }
            | MotionKind::Sync
            | MotionKind::Probe { .. }
            | MotionKind::Machine(_) => {
                unreachable!()
            }
        };
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-4);
        if kind != e["kind"] || !close(&end.0, &want_end) {
            return Err(format!(
                "motion {k} (line {}): {kind} {:?}, expected {e}",
                m.line, end.0
            ));
        }
        // the unrounded end agrees with the printed one too (within the print's rounding)
        let unit = if m.inch { 25.4 } else { 1.0 };
        let raw = m.kind.end().unwrap();
        if raw
            .0
            .iter()
            .zip(&want_end)
            .any(|(x, y)| (x - y).abs() > 0.5e-4 * unit + 1e-9)
        {
            return Err(format!(
                "motion {k}: unrounded end {:?} vs {want_end:?}",
                raw.0
            ));
        }
        if let Some(f) = e["feed_mm_min"].as_f64() {
            let got_f = match m.kind {
                MotionKind::Feed {
                    feed_mm_per_min, ..
                }
                | MotionKind::Arc {
                    feed_mm_per_min, ..
                } => feed_mm_per_min,
                _ => f64::NAN,
            };
            if (got_f - f).abs() > 0.5e-4 * unit + 1e-6 {
                return Err(format!("motion {k}: feed {got_f}, expected {f}"));
            }
        }
        if let MotionKind::Arc { plane, turns, .. } = m.kind {
            let c = center.unwrap();
            let (i, j) = match plane {
                Plane::XY => (0, 1),
                Plane::XZ => (0, 2),
                Plane::YZ => (1, 2),
            };
            if plane.name() != e["plane"]
                || i64::from(turns) != e["turns"].as_i64().unwrap()
                || !close(&[c[i], c[j]], &nums(&e["center2"]))
            {
                return Err(format!(
                    "arc {k} (line {}): {plane:?} {:?} {turns}, expected {e}",
                    m.line, c.0
                ));
            }
        }
    }
    Ok(got.len())
}

#[test]
fn golden_programs_read_as_rs274_reads_them() {
    let profile = profile();
    let mut files: Vec<_> = std::fs::read_dir(dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ngc"))
        .collect();
    files.sort();
    assert!(files.len() >= 12, "golden fixtures missing");
    let mut fails = vec![];
    for f in &files {
        match check(f, &profile) {
            Ok(n) => eprintln!("{}: {n} motions match", f.display()),
            Err(e) => fails.push(format!("{}: {e}", f.display())),
        }
    }
    assert!(fails.is_empty(), "{fails:#?}");
}

#[test]
fn offsets_and_path_modes() {
    let profile = profile();
    let read = |name: &str| {
        let text = std::fs::read_to_string(dir().join(name)).unwrap();
        softnc_gcode::read_program(&text, name, &profile).unwrap()
    };
    // G55 offset + tool 1 length on Z: machine = canonical + offset
    let mut p = read("g53_machine.ngc");
    // (the moves alone: tool changes and spindle codes are machine operations)
    p.motions
        .retain(|m| !matches!(m.kind, softnc_gcode::MotionKind::Machine(_)));
    let m = &p.motions[1];
    assert!((m.offset_mm.0[0] - 25.4).abs() < 1e-12);
    assert!((m.offset_mm.0[2] - (76.2 + 12.9794)).abs() < 1e-9);
    // G53 Z0 goes to machine Z 0
    let g53 = &p.motions[2];
    assert!((g53.kind.end().unwrap().0[2] + g53.offset_mm.0[2]).abs() < 1e-9);
    // each motion starts where the previous one ended, in machine coordinates
    // (`start` is in the motion's own frame: offsets may change between motions)
    for w in p.motions.windows(2) {
        let prev = w[0].kind.end().unwrap() + w[0].offset_mm;
        assert!(
            (w[1].start + w[1].offset_mm - prev).norm() < 1e-9,
            "{:?}",
            w[1]
        );
    }
    // path modes
    let mut p = read("modes.ngc");
    p.motions
        .retain(|m| !matches!(m.kind, MotionKind::Machine(_)));
    let modes: Vec<_> = p.motions.iter().map(|m| m.path_mode).collect();
    assert_eq!(modes[0], PathMode::ExactStop); // G61
    assert_eq!(modes[2], PathMode::ExactStop); // G61.1
    assert_eq!(
        modes[3],
        PathMode::Blend {
            tolerance_mm: Some(0.05),
            naive_cam_mm: Some(0.01),
        }
    );
    assert!(matches!(p.motions[4].kind, MotionKind::Dwell { seconds } if seconds == 0.5));
    assert_eq!(
        modes[5],
        PathMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        }
    ); // G64
       // inch: G64 P and Q in inches, feeds in mm/min
    let p = softnc_gcode::read_program("G20 G64 P0.001 Q0.002\nG1 X1 F10\nM2\n", "t.ngc", &profile)
        .unwrap();
    assert_eq!(
        p.motions[0].path_mode,
        PathMode::Blend {
            tolerance_mm: Some(0.0254),
            naive_cam_mm: Some(0.0508),
        }
    );
    assert!(
        matches!(p.motions[0].kind, MotionKind::Feed { feed_mm_per_min, .. } if (feed_mm_per_min - 254.0).abs() < 1e-9)
    );
}
