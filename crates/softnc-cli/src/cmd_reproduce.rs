//! `softnc reproduce EXPERIMENT`: rerun a paper's experiment on the simulated machine
//! and print our figures beside the paper's. The experiments live in the
//! `softnc-experiments` crate; this command parses, runs one and prints its report.

use anyhow::Result;
use softnc_experiments::{ExperimentError, ExperimentId, RunOptions};
use std::path::PathBuf;
use std::process::ExitCode;

/// Arguments of `softnc reproduce`.
#[derive(clap::Args)]
pub struct ReproduceArgs {
    /// The experiment.
    #[arg(value_enum)]
    pub experiment: ExperimentId,
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

/// Run the chosen experiment and print its report. A machine profile or design file
/// that does not load is refused (exit 2) with the file and the RON path.
pub fn run(args: ReproduceArgs) -> Result<ExitCode> {
    let options = RunOptions {
        machine: args.machine,
        seeds: args.seeds,
        fuzzy: args.fuzzy,
        audit: args.audit,
    };
    let report = match args.experiment.experiment().run(&options) {
        Ok(r) => r,
        Err(ExperimentError::Config(e)) => {
            eprintln!("softnc: {e}");
            return Ok(ExitCode::from(crate::EXIT_REFUSED));
        }
        Err(e) => return Err(e.into()),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json())?);
    } else {
        print!("{}", report.to_text());
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir)?;
        for out in report.write_plots(dir)? {
            eprintln!("wrote {}", out.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}
