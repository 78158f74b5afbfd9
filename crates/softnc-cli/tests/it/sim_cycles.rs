//! A drilling job of canned cycles through the whole offline pipeline: `softnc plan`
//! reads `examples/drill.ngc` into the motions LinuxCNC's `rs274` makes of it (109
//! traverses and feeds), and `softnc sim` runs it on the simulated machine with its
//! dwells (six G82 holes of P0.5: three seconds of the run).

use std::path::Path;

use crate::{repo, sim_json};

/// `softnc sim FILE --json` on the default machine: the run's cycles (1 kHz).
fn sim_cycles(file: &Path) -> u64 {
    sim_json(file, &[])["cycles"].as_u64().unwrap()
}

#[test]
fn softnc_sim_runs_the_drilling_example_with_its_dwells() {
    let drill = repo().join("examples/drill.ngc");
    // `softnc plan --canon`: the cycles expanded as rs274 expands them (109
    // STRAIGHT_TRAVERSE/STRAIGHT_FEED calls, 6 DWELLs)
    let kinds: Vec<String> = crate::plan_canon(&drill)
        .iter()
        .map(|v| v["kind"].as_str().unwrap_or("").to_string())
        .collect();
    let moves = kinds
        .iter()
        .filter(|k| *k == "traverse" || *k == "feed")
        .count();
    assert_eq!(moves, 109, "{kinds:?}");
    // the simulated machine runs it; without the dwells it is 3 s shorter
    let with_dwells = sim_cycles(&drill);
    let dir = std::env::temp_dir().join(format!("softnc-sim-drill-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let no_dwell = dir.join("drill-p0.ngc");
    let text = std::fs::read_to_string(&drill).unwrap();
    assert!(text.contains("P0.5"));
    std::fs::write(&no_dwell, text.replace("P0.5", "P0")).unwrap();
    let without = sim_cycles(&no_dwell);
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        with_dwells.abs_diff(without + 3000) <= 2,
        "{with_dwells} cycles with the dwells, {without} without"
    );
}
