//! A cutter-compensation job through the whole offline pipeline: `softnc plan`
//! reads `examples/pocket_comp.ngc` (an outline with G41 D, a pocket wall with
//! G42 D, a finishing pass with G41.1) into the motions LinuxCNC's `rs274` makes of
//! it — `tests/data/pocket_comp.rs274`, rs274's output for the example (LinuxCNC
//! 2.9, `rs274 -g`, its sample tool table; made again with
//! `rs274 -v empty.var -g examples/pocket_comp.ngc OUT` and the sequence numbers
//! cut) — and `softnc sim` runs it on the simulated machine.

use std::path::PathBuf;

use crate::repo;

/// The numbers between the parentheses of a canonical call.
fn args(line: &str) -> Vec<f64> {
    let inner = &line[line.find('(').unwrap() + 1..line.rfind(')').unwrap()];
    inner
        .split(',')
        .map(|a| a.trim().parse().unwrap())
        .collect()
}

/// One motion of rs274's: kind, end (X Y Z) and for an arc its centre in the
/// plane and its turns.
type Move = (String, [f64; 3], Option<([f64; 2], i64)>);

/// rs274's motions (the example cuts in the XY plane).
fn rs274_moves(text: &str) -> Vec<Move> {
    let mut out = Vec::new();
    for line in text.lines() {
        let name = &line[..line.find('(').unwrap_or(line.len())];
        let a = match name {
            "STRAIGHT_TRAVERSE" | "STRAIGHT_FEED" | "ARC_FEED" => args(line),
            _ => continue,
        };
        out.push(match name {
            "STRAIGHT_TRAVERSE" => ("traverse".into(), [a[0], a[1], a[2]], None),
            "STRAIGHT_FEED" => ("feed".into(), [a[0], a[1], a[2]], None),
            _ => (
                "arc".into(),
                [a[0], a[1], a[5]],
                Some(([a[2], a[3]], a[4] as i64)),
            ),
        });
    }
    out
}

#[test]
fn softnc_plans_and_simulates_the_compensation_example_as_rs274_reads_it() {
    let example = repo().join("examples/pocket_comp.ngc");
    let want = rs274_moves(
        &std::fs::read_to_string(
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/pocket_comp.rs274"),
        )
        .unwrap(),
    );
    assert_eq!(want.len(), 50);
    let got: Vec<serde_json::Value> = crate::plan_canon(&example)
        .into_iter()
        .filter(|v| matches!(v["kind"].as_str(), Some("traverse" | "feed" | "arc")))
        .collect();
    assert_eq!(got.len(), want.len(), "{got:#?}");
    let xyz = |v: &serde_json::Value| -> [f64; 3] { [0, 1, 2].map(|k| v[k].as_f64().unwrap()) };
    for (k, (g, (kind, end, arc))) in got.iter().zip(&want).enumerate() {
        assert_eq!(g["kind"].as_str().unwrap(), kind, "motion {k}: {g}");
        let e = xyz(&g["end"]);
        for i in 0..3 {
            assert!((e[i] - end[i]).abs() < 1e-4, "motion {k}: {g} vs {end:?}");
        }
        if let Some((center, turns)) = arc {
            let c = xyz(&g["center"]);
            assert!(
                (c[0] - center[0]).abs() < 1e-4 && (c[1] - center[1]).abs() < 1e-4,
                "motion {k}: {g} vs {center:?}"
            );
            assert_eq!(g["turns"].as_i64().unwrap(), *turns, "motion {k}: {g}");
        }
    }
    // the corners the compensation added: rs274's arcs outnumber the program's
    // three arcs a pass
    let arcs = want.iter().filter(|m| m.0 == "arc").count();
    assert!(arcs > 9, "{arcs} arcs");
    // the simulated machine runs it to the end, about as long as planned
    let v = crate::sim_json(&example, &[]);
    let sim_s = v["sim_time_s"].as_f64().unwrap();
    assert!((40.0..120.0).contains(&sim_s), "{v}");
}
