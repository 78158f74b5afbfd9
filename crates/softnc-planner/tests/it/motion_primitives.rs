//! The programmed primitive of every motion, as the plan keeps it, is the motion's
//! own (`build::motion_primitive`): a process that needs only the primitives (the
//! position process's contour error) reads the motions without planning the program.

use softnc_core::MotionProfile;
use softnc_planner::build::motion_primitive;
use softnc_planner::{plan, PlanOptions};
use std::path::{Path, PathBuf};

/// The G-code programs under `root`, sorted (none if it does not exist).
fn programs_under(root: PathBuf) -> Vec<PathBuf> {
    let mut files = vec![];
    let mut dirs = vec![root];
    while let Some(d) = dirs.pop() {
        let Ok(rd) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in rd.flatten() {
            let path = e.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|x| x == "ngc" || x == "nc") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn a_plans_primitives_are_its_motions_own() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut programs = programs_under(repo.join("examples"));
    let examples = programs.len();
    assert!(examples >= 5, "only {examples} example programs");
    let corpus = programs_under(repo.join("../shared/gcode"));
    if corpus.is_empty() {
        // written past the test harness's capture, so that a run without the corpus
        // says what it did not test
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: ../shared/gcode is not beside the repository; \
             a_plans_primitives_are_its_motions_own ran on examples/ only"
        );
    }
    programs.extend(corpus.iter().cloned());
    let profiles = ["default", "tnv40-ilc", "mill-friction"]
        .map(|n| MotionProfile::load(&repo.join(format!("config/machines/{n}.ron"))).unwrap());
    let mut compared = 0;
    for file in &programs {
        let text = String::from_utf8_lossy(&std::fs::read(file).unwrap()).into_owned();
        for profile in &profiles {
            let Ok(program) =
                softnc_gcode::read_program(&text, &file.display().to_string(), profile)
            else {
                continue;
            };
            let Ok(p) = plan(&program, profile, &PlanOptions::default()) else {
                continue;
            };
            for (i, m) in program.motions.iter().enumerate() {
                assert_eq!(
                    p.motion_primitive(i),
                    motion_primitive(m),
                    "{}: motion {i} (line {})",
                    file.display(),
                    m.line
                );
            }
            compared += 1;
        }
    }
    // every example plans on the default machine, most corpus programs on some
    let want = if corpus.is_empty() { examples } else { 20 };
    assert!(compared >= want, "only {compared} plans compared");
}
