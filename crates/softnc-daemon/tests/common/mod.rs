//! Shared by the daemon's tests: the counting allocator of the cycle tests, a lockstep
//! daemon configuration in a scratch folder, and what `softnc learn` stores.
#![allow(dead_code)]

use softnc_daemon::config::{DaemonConfig, Loaded};
use std::path::{Path, PathBuf};

/// The counting allocator of the cycle tests (`softnc-test-support`): each test binary
/// registers it (`#[global_allocator] static GLOBAL: common::Counting =
/// common::Counting;`); `count(f)` counts this thread's allocations inside `f`,
/// `allocations()` says how many so far.
#[allow(unused_imports)] // (the binaries that count use them)
pub use softnc_test_support::{count, counted as allocations, Counting};

/// A daemon configuration of its own in a fresh folder `softnc-<tag>-<pid>`: lockstep
/// clock, instance `<tag><pid>`, `machine_file` of `config/machines` as its
/// `machines/default.ron`, data in `<dir>/data` and, with `learning`, the learning
/// store in `<dir>/learning`.
pub fn lockstep_config(tag: &str, machine_file: &str, learning: bool) -> (PathBuf, Loaded) {
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = std::env::temp_dir().join(format!("softnc-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("machines")).unwrap();
    std::fs::copy(
        repo.join("config/machines").join(machine_file),
        dir.join("machines/default.ron"),
    )
    .unwrap();
    std::fs::copy(repo.join("config/iceoryx2.toml"), dir.join("iceoryx2.toml")).unwrap();
    let mut cfg = std::fs::read_to_string(repo.join("config/default.ron"))
        .unwrap()
        .replace(
            "instance: \"mill1\"",
            &format!("instance: \"{tag}{}\"", std::process::id()),
        )
        .replace("clock: Realtime", "clock: Lockstep")
        .replace("data_dir: \"../data\"", "data_dir: \"data\"");
    if learning {
        std::fs::create_dir_all(dir.join("learning")).unwrap();
        cfg = cfg.replace(
            "// learning_dir: Some(\"../learning\"),",
            "learning_dir: Some(\"learning\"),",
        );
        assert!(cfg.contains("learning_dir: Some(\"learning\")"));
    }
    std::fs::write(dir.join("default.ron"), cfg).unwrap();
    let loaded = DaemonConfig::load(&dir.join("default.ron")).unwrap();
    loaded.setup_iceoryx2().unwrap();
    (dir, loaded)
}

/// What `softnc learn JOB --machine PROFILE --iterations K --store DIR` stores (the
/// same runs and entry, default gain and all Markov terms); the RMS (µm) per run.
pub fn learn_job(store: &Path, job: &Path, machine: &Path, iterations: usize) -> Vec<f64> {
    use softnc_experiments::learning_runs::{identify, learn_markov, PreparedJob};
    use softnc_learning::entry::{LawState, Learned, OVERRIDE_PCT};
    let profile = softnc_machine::MachineProfile::load(machine).unwrap();
    let text = std::fs::read_to_string(job).unwrap();
    let prepared = PreparedJob::new(&text, "job.ngc", &profile).unwrap();
    let seed = profile.servo.seed;
    let mut engine =
        softnc_sim::simulated_engine(&profile, seed, softnc_sim::SimOptions::default());
    let n = prepared.samples.len();
    let h = identify(&mut engine, &profile, prepared.samples[0].pos_mm.0, n).unwrap();
    let gain = softnc_learning::markov::DEFAULT_GAIN;
    let mut mj = softnc_learning::markov::MarkovJob::new(h, n, Some(gain), n);
    let its = learn_markov(&mut engine, &prepared, &mut mj, iterations, |_, _| Ok(())).unwrap();
    let key = softnc_learning::LearningKey::new(
        &std::fs::read(job).unwrap(),
        &std::fs::read(machine).unwrap(),
        OVERRIDE_PCT,
    );
    let entry = Learned {
        job_file: job.display().to_string(),
        profile_file: machine.display().to_string(),
        seed,
        iterations: its.clone(),
        state: LawState::Markov(mj),
    };
    softnc_learning::LearningStore::new(store)
        .put(&key, &entry)
        .unwrap();
    its.iter().map(|s| s.rms_um).collect()
}
