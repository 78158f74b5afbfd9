//! `softnc learn` and its store: the JSON shape, list/show/clear, and a changed job
//! or profile invalidating its entry.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn ws(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn softnc(args: &[&str], store: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(args)
        .arg("--store")
        .arg(store)
        .output()
        .unwrap()
}

fn stdout(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout.clone()).unwrap()
}

#[test]
fn learn_json_list_show_clear_and_invalidation() {
    let dir = std::env::temp_dir().join(format!("softnc-learn-store-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let store = dir.join("store");
    let job = dir.join("job.ngc");
    std::fs::write(&job, "G21 G90 G17 G94\nG0 X0 Y0 Z0\nG1 X5 Y2 F3000\nM2\n").unwrap();
    let profile = dir.join("machine.ron");
    std::fs::copy(ws("config/machines/default.ron"), &profile).unwrap();
    let (j, p) = (job.to_str().unwrap(), profile.to_str().unwrap());

    // --json: the first entry is the run before learning, then one per iteration
    let out = stdout(&softnc(
        &["learn", j, "--machine", p, "--iterations", "3", "--json"],
        &store,
    ));
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let its = v["iterations"].as_array().unwrap();
    assert_eq!(its.len(), 4);
    for (k, it) in its.iter().enumerate() {
        assert_eq!(it["iteration"], k);
        assert!(it["rms_um"].as_f64().unwrap() >= 0.0);
        assert!(it["max_abs_um"].as_f64().unwrap() >= it["rms_um"].as_f64().unwrap());
    }
    assert!(its[3]["rms_um"].as_f64().unwrap() < its[0]["rms_um"].as_f64().unwrap());

    let list = stdout(&softnc(&["learn", "list", "--json"], &store));
    let l: serde_json::Value = serde_json::from_str(list.trim()).unwrap();
    assert_eq!(l.as_array().unwrap().len(), 1);
    assert_eq!(l[0]["status"], "current");
    assert_eq!(l[0]["runs"], 4);
    let show = stdout(&softnc(
        &["learn", "show", j, "--machine", p, "--json"],
        &store,
    ));
    let s: serde_json::Value = serde_json::from_str(show.trim()).unwrap();
    assert_eq!(s["iterations"], v["iterations"]);
    assert_eq!(s["law"], "markov");

    // a changed profile: the entry is stale and not found for the new one
    let mut text = std::fs::read_to_string(&profile).unwrap();
    text.push_str("\n// changed\n");
    std::fs::write(&profile, &text).unwrap();
    let l: serde_json::Value =
        serde_json::from_str(stdout(&softnc(&["learn", "list", "--json"], &store)).trim()).unwrap();
    assert_eq!(l[0]["status"], "stale (profile changed)");
    let o = softnc(&["learn", "show", j, "--machine", p], &store);
    assert!(
        !o.status.success(),
        "a changed profile must not find the old entry"
    );

    // a changed job likewise
    std::fs::copy(ws("config/machines/default.ron"), &profile).unwrap();
    std::fs::write(&job, "G21 G90 G17 G94\nG0 X0 Y0 Z0\nG1 X5 Y3 F3000\nM2\n").unwrap();
    let l: serde_json::Value =
        serde_json::from_str(stdout(&softnc(&["learn", "list", "--json"], &store)).trim()).unwrap();
    assert_eq!(l[0]["status"], "stale (job changed)");
    assert!(!softnc(&["learn", "show", j, "--machine", p], &store)
        .status
        .success());
    stdout(&softnc(&["learn", "clear", "--stale"], &store));
    let l: serde_json::Value =
        serde_json::from_str(stdout(&softnc(&["learn", "list", "--json"], &store)).trim()).unwrap();
    assert!(l.as_array().unwrap().is_empty());

    // a bad law input is refused with status 2
    let o = softnc(
        &[
            "learn",
            j,
            "--machine",
            p,
            "--law",
            "radius",
            "--iterations",
            "1",
        ],
        &store,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("full circle"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sim_learned_applies_the_stored_correction() {
    let dir = std::env::temp_dir().join(format!("softnc-sim-learned-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let store = dir.join("store");
    let job = ws("examples/learning/lines-arcs.ngc");
    let profile = ws("config/machines/default.ron");
    let (j, p) = (job.to_str().unwrap(), profile.to_str().unwrap());
    let sim = |learned: bool| {
        let mut args = vec!["sim", j, "--machine", p, "--json"];
        if learned {
            args.push("--learned");
        }
        softnc(&args, &store)
    };
    // no entry yet: refused with a clear message, nothing simulated
    let o = sim(true);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no learning entry"));
    stdout(&softnc(
        &["learn", j, "--machine", p, "--iterations", "3", "--json"],
        &store,
    ));
    let rms = |o: &Output| {
        let v: serde_json::Value = serde_json::from_str(stdout(o).trim()).unwrap();
        (
            v["contour_error_um"]["rms"].as_f64().unwrap(),
            v["learned"].clone(),
        )
    };
    let (plain, none) = rms(&sim(false));
    let (learned, entry) = rms(&sim(true));
    assert!(none.is_null());
    assert_eq!(entry["repetitions"], 3);
    assert!(
        learned < 0.2 * plain,
        "learned {learned} µm vs unlearned {plain} µm"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Issue 15: a run that improves nothing stores nothing and exits 1; a run that
/// improves stores the kept run with its improvement, below the unlearned RMS.
#[test]
fn only_an_improving_run_is_stored() {
    let dir = std::env::temp_dir().join(format!("softnc-learn-kept-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let store = dir.join("store");
    let job = dir.join("job.ngc");
    std::fs::write(&job, "G21 G90 G17 G94\nG0 X0 Y0 Z0\nG1 X5 Y2 F3000\nM2\n").unwrap();
    let (j, p) = (
        job.to_str().unwrap(),
        ws("config/machines/default.ron").display().to_string(),
    );
    // no learning step: the one run is the unlearned run
    let o = softnc(&["learn", j, "--machine", &p, "--iterations", "0"], &store);
    assert_eq!(o.status.code(), Some(1), "{o:?}");
    assert!(String::from_utf8_lossy(&o.stderr).contains("nothing stored"));
    assert!(!store.exists() || std::fs::read_dir(&store).unwrap().count() == 0);

    stdout(&softnc(
        &["learn", j, "--machine", &p, "--iterations", "2", "--json"],
        &store,
    ));
    let list: serde_json::Value =
        serde_json::from_str(stdout(&softnc(&["learn", "list", "--json"], &store)).trim()).unwrap();
    let kept = &list[0]["kept"];
    let (rms, unlearned) = (
        kept["rms_um"].as_f64().unwrap(),
        kept["unlearned_rms_um"].as_f64().unwrap(),
    );
    assert!(rms < unlearned, "{list}");
    assert!(kept["iteration"].as_u64().unwrap() >= 1, "{list}");
    std::fs::remove_dir_all(&dir).ok();
}
