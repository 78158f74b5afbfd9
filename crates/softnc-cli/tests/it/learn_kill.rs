//! Issue 5: killing `softnc learn` while it writes leaves the learning store with the
//! old entry or a new one, never a corrupt one. The learning run writes its entry
//! after every repetition that improved on the best so far and once at the end (a few
//! hundred kB for this job); the test SIGKILLs it at
//! spread-out random moments and checks each time that the stored bytes are exactly
//! the old entry or exactly one of the entries a clean run writes.

use softnc_learning::{LearningKey, LearningStore};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const ITERATIONS: usize = 3;
const TRIALS: usize = 20;

fn ws(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn learn(store: &Path, iterations: usize, seed: u64) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_softnc"));
    c.arg("learn")
        .arg(ws("examples/learning/lines-arcs.ngc"))
        .arg("--machine")
        .arg(ws("config/machines/default.ron"))
        .arg("--iterations")
        .arg(iterations.to_string())
        .arg("--seed")
        .arg(seed.to_string())
        .arg("--json")
        .arg("--store")
        .arg(store)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    c
}

fn run_to_end(store: &Path, iterations: usize, seed: u64) -> Vec<u8> {
    let _ = std::fs::remove_dir_all(store);
    let st = learn(store, iterations, seed).status().unwrap();
    assert!(st.success());
    let files: Vec<_> = std::fs::read_dir(store)
        .unwrap()
        .flatten()
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert_eq!(files.len(), 1);
    std::fs::read(files[0].path()).unwrap()
}

/// A spread of kill moments over `0..span`: stratified, with a jitter from the clock.
fn kill_at(trial: usize, span: Duration) -> Duration {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos() as f64
        / 1e9;
    span.mul_f64((trial as f64 + nanos) / TRIALS as f64)
}

#[test]
fn killed_learning_run_leaves_the_old_or_a_new_entry() {
    let _one = crate::one_controller_at_a_time();
    let root = std::env::temp_dir().join(format!("softnc-learn-kill-{}", std::process::id()));
    // the entries a clean run writes after repetition j, j = 1..=ITERATIONS (the run
    // before any learning, j = 0, improves on nothing: no entry)
    let started = Instant::now();
    let new: Vec<Vec<u8>> = (1..=ITERATIONS)
        .map(|j| run_to_end(&root.join(format!("ref{j}")), j, 1))
        .collect();
    let span = started.elapsed().mul_f64(1.2 / ITERATIONS as f64 * 2.0);
    // the old entry: same job and profile (same key), another machine seed
    let store = root.join("store");
    let old = run_to_end(&store, 1, 2);
    assert!(!new.contains(&old));
    let entry = std::fs::read_dir(&store)
        .unwrap()
        .flatten()
        .find(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .unwrap()
        .path();
    let key = LearningKey::new(
        &std::fs::read(ws("examples/learning/lines-arcs.ngc")).unwrap(),
        &std::fs::read(ws("config/machines/default.ron")).unwrap(),
        100,
    );

    let (mut saw_old, mut saw_new) = (0, 0);
    for trial in 0..TRIALS {
        std::fs::write(&entry, &old).unwrap();
        let mut child = learn(&store, ITERATIONS, 1).spawn().unwrap();
        std::thread::sleep(kill_at(trial, span));
        let _ = child.kill(); // SIGKILL
        child.wait().unwrap();
        let bytes = std::fs::read(&entry).unwrap();
        if bytes == old {
            saw_old += 1;
        } else {
            assert!(
                new.contains(&bytes),
                "trial {trial}: the entry is neither the old one nor a complete new one ({} bytes)",
                bytes.len()
            );
            saw_new += 1;
        }
        // and it loads through the store
        let v: Option<serde_json::Value> = LearningStore::new(&store).get(&key).unwrap();
        assert!(v.is_some());
    }
    eprintln!("{TRIALS} kills: {saw_old} left the old entry, {saw_new} a new one");
    assert!(saw_new > 0, "no kill came after a write: {saw_old} old");
    assert!(
        saw_old > 0,
        "no kill came before the first write: {saw_new} new"
    );
    // files of killed writers are not entries, and `clear --all` removes them
    let store_list = LearningStore::new(&store).list().unwrap();
    assert_eq!(store_list, vec![key]);
    let st = Command::new(env!("CARGO_BIN_EXE_softnc"))
        .args(["learn", "clear", "--all", "--store"])
        .arg(&store)
        .stdout(Stdio::null())
        .status()
        .unwrap();
    assert!(st.success());
    assert_eq!(std::fs::read_dir(&store).unwrap().count(), 0);
    std::fs::remove_dir_all(&root).ok();
}
