//! `softnc reproduce EXPERIMENT`: rerun a paper's experiment on the simulated machine
//! and print our figures beside the paper's. Each experiment lives in its own module
//! under `reproduce/`.

use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `softnc reproduce`.
#[derive(clap::Args)]
pub struct ReproduceArgs {
    /// The experiment: `001-table5` (paper 001, PID vs fuzzy-logic control),
    /// `000-pdc` (paper 000, DOB/MBDA and the periodic disturbance canceller),
    /// `002-filter` (paper 002, the zero-lag command filter against a structural mode),
    /// `002-learning` (paper 002 Fig. 4, Markov learning per buffer size),
    /// `003-force` (paper 003, adaptive cutting-force control, cases I–III),
    /// `004-ilc` (paper 004, radius ILC of circles).
    pub experiment: String,
    /// Print one JSON document instead of the text table.
    #[arg(long)]
    pub json: bool,
    /// Number of seeds (1..=N), the same for every controller (003: the robustness
    /// summary after the table).
    #[arg(long, default_value_t = 5)]
    pub seeds: u64,
    /// Machine profile (default: the experiment's, e.g. config/machines/mill-friction.ron).
    #[arg(long)]
    pub machine: Option<PathBuf>,
    /// Fuzzy rule base and membership table (001; default config/fuzzy/paper001.ron).
    #[arg(long)]
    pub fuzzy: Option<PathBuf>,
    /// 001: also run the plant-reading audit (every reading of the paper's unstated
    /// units and reference, and the FLC's gains in the range it actually visits).
    #[arg(long)]
    pub audit: bool,
    /// Write the experiment's plots (SVG) into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
}

impl ReproduceArgs {
    /// The machine profile: `--machine`, else the experiment's `default` (a workspace
    /// path). A profile that does not load is reported (`softnc: file: path: reason`)
    /// and gives `None`: the command then exits refused.
    pub fn machine_profile(&self, default: &str) -> Option<softnc_core::MachineProfile> {
        let path = self
            .machine
            .clone()
            .unwrap_or_else(|| crate::reproduce::p001::workspace_file(default));
        match softnc_core::MachineProfile::load(&path) {
            Ok(m) => Some(m),
            Err(e) => {
                eprintln!("softnc: {e}");
                None
            }
        }
    }

    /// Print the experiment's JSON document (`--json`) or its text table.
    pub fn print(
        &self,
        json: impl FnOnce() -> serde_json::Value,
        text: impl FnOnce() -> String,
    ) -> Result<()> {
        if self.json {
            println!("{}", serde_json::to_string_pretty(&json())?);
        } else {
            print!("{}", text());
        }
        Ok(())
    }
}

/// The experiments this command knows.
pub const EXPERIMENTS: &[&str] = &[
    "001-table5",
    "000-pdc",
    "002-filter",
    "002-learning",
    "003-force",
    "004-ilc",
];

/// Run the named experiment.
pub fn run(args: ReproduceArgs) -> Result<ExitCode> {
    match args.experiment.as_str() {
        "001-table5" => crate::reproduce::p001::main(&args),
        "000-pdc" => crate::reproduce::p000::main(&args),
        "002-filter" => crate::reproduce::p002_filter::main(&args),
        "003-force" => crate::reproduce::p003::main(&args),
        "002-learning" => crate::reproduce::p002_learning::main(&args),
        "004-ilc" => crate::reproduce::p004::main(&args),
        other => {
            eprintln!(
                "softnc: unknown experiment `{other}`; known: {}",
                EXPERIMENTS.join(", ")
            );
            Ok(ExitCode::from(crate::EXIT_REFUSED))
        }
    }
}
