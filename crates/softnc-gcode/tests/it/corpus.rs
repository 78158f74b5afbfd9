//! The third-party corpus (`../shared/gcode`): softnc must read every program as
//! LinuxCNC's interpreter does — the same canonical motions for every accepted tier
//! A/B program, a rejection with `file:line` for every program LinuxCNC rejects, and
//! tier C either read identically or refused as unsupported.

use serde_json::Value;
use softnc_core::MotionProfile;
use std::path::PathBuf;

fn corpus() -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/gcode");
    p.join("manifest.json").exists().then_some(p)
}

fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
}

/// Compare our motions with LinuxCNC's canon; `None` when they match.
fn compare(program: &softnc_gcode::Program, canon: &[Value]) -> Option<String> {
    use softnc_gcode::MotionKind;
    let got: Vec<_> = program
        .motions
        .iter()
        .filter(|m| m.kind.end().is_some())
        .collect();
    if got.len() != canon.len() {
        return Some(format!("{} motions, expected {}", got.len(), canon.len()));
    }
    for (k, (m, e)) in got.iter().zip(canon).enumerate() {
        let end: Vec<f64> = e["end"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let kind = e["kind"].as_str().unwrap();
        let (rounded_end, rounded_center) = m.canon_view();
        let gend = rounded_end.unwrap();
        let gk = match m.kind {
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
        if gk != kind || !close(&gend.0, &end, 1e-4) {
            return Some(format!(
                "motion {k} (line {}): {gk} {:?}, expected {kind} {end:?}",
                m.line, gend.0
            ));
        }
        if let MotionKind::Arc { plane, turns, .. } = m.kind {
            let center = rounded_center.unwrap();
            let (i, j) = match e["plane"].as_str().unwrap() {
                "xy" => (0, 1),
                "xz" => (0, 2),
                _ => (1, 2),
            };
            let c2: Vec<f64> = e["center2"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            if plane.name() != e["plane"].as_str().unwrap()
                || !close(&[center[i], center[j]], &c2, 1e-4)
                || turns as i64 != e["turns"].as_i64().unwrap()
            {
                return Some(format!(
                    "arc {k} (line {}): {} {:?} {turns}, expected {e}",
                    m.line,
                    plane.name(),
                    center.0
                ));
            }
        }
    }
    None
}

/// The program's (PRINT,…) output as softnc substitutes it, one line each.
fn print_output(p: &softnc_gcode::Program) -> String {
    p.warnings
        .iter()
        .filter_map(|w| w.split_once(": print: ").map(|(_, t)| t))
        .collect::<Vec<_>>()
        .join("\n")
}

#[allow(clippy::too_many_lines)]
#[test]
fn corpus_reads_as_linuxcnc_reads_it() {
    let Some(dir) = corpus() else {
        // past the test harness's capture: a run without the corpus says so
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: corpus_reads_as_linuxcnc_reads_it: ../shared/gcode is not beside the repository"
        );
        return;
    };
    let profile = MotionProfile::load(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
    )
    .unwrap();
    let manifest: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap();
    let (mut ab, mut ab_ok, mut rej, mut rej_ok, mut c, mut c_ok, mut big, mut big_ok) =
        (0, 0, 0, 0, 0, 0, 0, 0);
    let mut fails = vec![];
    let mut print_same = 0;
    for e in &manifest {
        if e["rs274_accepts"].is_null()
            || e.get("rs274_options")
                .is_some_and(|o| !o.is_null() && o != &Value::Array(vec![]) && o != "")
        {
            continue;
        }
        let file = e["file"].as_str().unwrap();
        let path = dir.join(file);
        let bytes = std::fs::read(&path).unwrap();
        let text = String::from_utf8_lossy(&bytes);
        let base = path.file_name().unwrap().to_string_lossy().to_string();
        let options = softnc_gcode::ReadOptions {
            subroutine_path: vec![path.parent().unwrap().to_path_buf()],
            // the corpus was read by rs274 without an INI file: parameters in inches
            parameters_in_inches: true,
            ..Default::default()
        };
        let result =
            softnc_gcode::read_program_with(&text, &base, &profile, &options).map(|(p, _)| p);
        let tier = e["tier"].as_str().unwrap();
        let canon: Option<Vec<Value>> = e["canon"]
            .as_str()
            .map(|c| serde_json::from_str(&std::fs::read_to_string(dir.join(c)).unwrap()).unwrap());
        if e["rs274_accepts"] == false {
            if let Ok(p) = &result {
                // (the manifest keeps the start of long outputs)
                let err = e["rs274_error"].as_str().unwrap_or("\u{0}");
                if !err.is_empty() && print_output(p).starts_with(err) {
                    // the manifest took rs274's (PRINT,…) output for an error message:
                    // LinuxCNC ran the program, and printed exactly what softnc prints
                    print_same += 1;
                    continue;
                }
            }
        }
        if e["rs274_accepts"] == false {
            rej += 1;
            match &result {
                Err(err) if err.to_string().starts_with(&format!("{base}:")) => rej_ok += 1,
                Err(err) => fails.push(format!("{file}: rejected without file:line: {err}")),
                Ok(_) => fails.push(format!(
                    "{file}: LinuxCNC rejects it ({}); we accept it",
                    e["rs274_error"]
                )),
            }
            continue;
        }
        let why = match (&result, &canon) {
            (Ok(p), Some(canon)) => compare(p, canon),
            (Ok(_), None) => None,
            (Err(err), _) => Some(err.to_string()),
        };
        if tier == "A" || tier == "B" {
            if canon.is_some() {
                ab += 1;
                match why {
                    None => ab_ok += 1,
                    Some(w) => fails.push(format!("{file}: {w}")),
                }
            } else {
                big += 1;
                match result {
                    Ok(_) => big_ok += 1,
                    Err(err) => fails.push(format!("{file}: {err}")),
                }
            }
        } else {
            c += 1;
            let refused = matches!(&result, Err(err) if matches!(err.kind, softnc_gcode::ErrorKind::Unsupported { .. }));
            if why.is_none() || refused {
                c_ok += 1;
            } else {
                fails.push(format!(
                    "{file}: tier C neither read as rs274 reads it nor refused as unsupported: {}",
                    why.unwrap_or_default()
                ));
            }
        }
    }
    eprintln!(
        "corpus: A/B matched {ab_ok}/{ab}, large A/B read {big_ok}/{big}, rejected {rej_ok}/{rej}, tier C handled {c_ok}/{c}; \
         {print_same} listed as rejected whose 'error' is exactly the PRINT output softnc gives"
    );
    for f in fails.iter().take(40) {
        eprintln!("  {f}");
    }
    assert!(
        fails.is_empty(),
        "{} corpus programs not read as LinuxCNC reads them",
        fails.len()
    );
}
