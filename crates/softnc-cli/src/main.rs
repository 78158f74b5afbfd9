//! `softnc`: the operator client and the offline tools (plan, sim, ...).

mod cmd_plan;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// softnc — a PC-based CNC motion controller.
#[derive(Parser)]
#[command(name = "softnc", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Validate and plan a G-code program without moving anything.
    Plan(cmd_plan::PlanArgs),
}

/// Exit status for a program or configuration that was refused.
pub const EXIT_REFUSED: u8 = 2;

/// The machine profile to use when none is given: `config/machines/default.ron`
/// next to the binary's workspace, or in the current directory.
pub fn default_machine_path() -> PathBuf {
    let rel = PathBuf::from("config/machines/default.ron");
    if rel.exists() {
        return rel;
    }
    let ws = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron");
    if ws.exists() {
        return ws;
    }
    rel
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: Result<ExitCode> = match cli.command {
        Command::Plan(args) => cmd_plan::run(args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            ExitCode::from(1)
        }
    }
}
