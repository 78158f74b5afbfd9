//! The papers' experiments as a library: each one reruns a paper's experiment on the
//! simulated machine and reports our figures beside the paper's.
//!
//! Every experiment implements [`Experiment`]: its [`ExperimentId`] (the name on the
//! command line), its default machine profile, and [`Experiment::run`], which returns
//! a [`Report`] that serialises to JSON, prints as text and writes its plots. The
//! `softnc reproduce` command only parses its arguments and prints what
//! [`ExperimentId::experiment`] returns:
//!
//! ```no_run
//! use softnc_experiments::{ExperimentId, RunOptions};
//! let report = ExperimentId::Filter002.experiment().run(&RunOptions::default())?;
//! print!("{}", report.to_text());
//! # Ok::<(), softnc_experiments::ExperimentError>(())
//! ```
//!
//! [`learning_runs`] holds the learning runs on the simulated machine (identification,
//! paper 002's and 004's repetitions) that `softnc learn` and the learning experiments
//! share.
//!
//! To add an experiment: a module here with a unit struct implementing
//! [`Experiment`], a variant of [`ExperimentId`], and its line in
//! [`ExperimentId::experiment`]. Plots go through [`plot::write_svg`].
#![warn(missing_docs)]

pub mod error;
pub mod learning_runs;
pub mod p000;
pub mod p001;
pub mod p001_audit;
pub mod p001_cases;
pub mod p002_filter;
pub mod p002_learning;
pub mod p003;
pub mod p004;
pub mod pdc_profile;
pub mod plot;
mod workspace;

pub use error::{ExperimentError, Result};
pub use workspace::workspace_file;

use softnc_machine::MachineProfile;
use std::path::{Path, PathBuf};

/// The experiments, by the names `softnc reproduce` takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExperimentId {
    /// Paper 001 Table 5: PID vs fuzzy-logic control on the plain-slideway mill.
    #[value(name = "001-table5")]
    Table5001,
    /// Paper 000: DOB/MBDA and the periodic disturbance canceller.
    #[value(name = "000-pdc")]
    Pdc000,
    /// Paper 002: the zero-lag command filter against a structural mode.
    #[value(name = "002-filter")]
    Filter002,
    /// Paper 002 Fig. 4: Markov learning per buffer size.
    #[value(name = "002-learning")]
    Learning002,
    /// Paper 003: adaptive cutting-force control, cases I–III.
    #[value(name = "003-force")]
    Force003,
    /// Paper 004: radius ILC of circles.
    #[value(name = "004-ilc")]
    Ilc004,
}

impl ExperimentId {
    /// Every experiment, in the order of the papers' digest.
    pub const ALL: [ExperimentId; 6] = [
        ExperimentId::Table5001,
        ExperimentId::Pdc000,
        ExperimentId::Filter002,
        ExperimentId::Learning002,
        ExperimentId::Force003,
        ExperimentId::Ilc004,
    ];

    /// The experiment.
    pub fn experiment(self) -> &'static dyn Experiment {
        match self {
            ExperimentId::Table5001 => &p001::Table5,
            ExperimentId::Pdc000 => &p000::Pdc,
            ExperimentId::Filter002 => &p002_filter::ZeroLagFilter,
            ExperimentId::Learning002 => &p002_learning::MarkovLearning,
            ExperimentId::Force003 => &p003::AdaptiveForce,
            ExperimentId::Ilc004 => &p004::RadiusIlc,
        }
    }

    /// The name on the command line (`003-force`).
    pub fn name(self) -> &'static str {
        match self {
            ExperimentId::Table5001 => "001-table5",
            ExperimentId::Pdc000 => "000-pdc",
            ExperimentId::Filter002 => "002-filter",
            ExperimentId::Learning002 => "002-learning",
            ExperimentId::Force003 => "003-force",
            ExperimentId::Ilc004 => "004-ilc",
        }
    }
}

/// What a run may change from an experiment's defaults.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RunOptions {
    /// Machine profile (default: the experiment's [`Experiment::default_machine`]).
    pub machine: Option<PathBuf>,
    /// Number of seeds (1..=N) where the experiment averages over seeds (001) or adds
    /// a robustness summary (003).
    pub seeds: u64,
    /// Fuzzy rule base and membership table (001; default `config/fuzzy/paper001.ron`).
    pub fuzzy: Option<PathBuf>,
    /// 001: also run the plant-reading audit.
    pub audit: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        RunOptions {
            machine: None,
            seeds: 5,
            fuzzy: None,
            audit: false,
        }
    }
}

impl RunOptions {
    /// The machine profile's path: `machine`, else `default` in the workspace.
    pub fn machine_path(&self, default: &str) -> PathBuf {
        self.machine
            .clone()
            .unwrap_or_else(|| workspace_file(default))
    }

    /// The machine profile, loaded and validated; [`ExperimentError::Config`] names
    /// the file and the RON path when it does not load.
    pub fn machine_profile(&self, default: &str) -> Result<MachineProfile> {
        MachineProfile::load(&self.machine_path(default))
            .map_err(|e| ExperimentError::Config(e.to_string()))
    }
}

/// One paper's experiment.
pub trait Experiment: Sync {
    /// Its name.
    fn id(&self) -> ExperimentId;
    /// The machine profile it runs on unless told otherwise (a workspace path).
    fn default_machine(&self) -> &'static str;
    /// Run it.
    fn run(&self, options: &RunOptions) -> Result<Box<dyn Report>>;
}

/// What an experiment found.
pub trait Report {
    /// The report as one JSON document.
    fn to_json(&self) -> serde_json::Value;
    /// The report as text: our figures beside the paper's.
    fn to_text(&self) -> String;
    /// Write the experiment's plots (SVG) into `dir` (which exists); the files
    /// written.
    fn write_plots(&self, _dir: &Path) -> Result<Vec<PathBuf>> {
        Ok(Vec::new())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;

    /// Every name on the command line runs the experiment of that name, on a machine
    /// profile that exists.
    #[test]
    fn every_name_maps_to_its_experiment() {
        assert_eq!(ExperimentId::value_variants(), &ExperimentId::ALL);
        for id in ExperimentId::ALL {
            let experiment = id.experiment();
            assert_eq!(experiment.id(), id);
            assert_eq!(id.to_possible_value().unwrap().get_name(), id.name());
            assert_eq!(ExperimentId::from_str(id.name(), false), Ok(id));
            assert!(
                workspace_file(experiment.default_machine()).exists(),
                "{}",
                experiment.default_machine()
            );
        }
    }

    #[test]
    fn a_machine_profile_that_does_not_load_is_a_config_error() {
        let options = RunOptions {
            machine: Some(PathBuf::from("config/machines/no-such-machine.ron")),
            ..RunOptions::default()
        };
        match ExperimentId::Filter002.experiment().run(&options) {
            Err(ExperimentError::Config(e)) => assert!(e.contains("no-such-machine.ron"), "{e}"),
            Err(e) => panic!("{e}"),
            Ok(_) => panic!("ran without a machine"),
        }
    }
}
