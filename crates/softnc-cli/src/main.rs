//! `softnc`: the operator client and the offline tools (plan, sim, ...).

mod cmd_demo;
mod cmd_design;
mod cmd_ethercat;
mod cmd_learn;
mod cmd_operator;
mod cmd_plan;
mod cmd_reproduce;
mod cmd_sim;
mod cmd_watch;
mod program_file;
mod watch_keys;

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// softnc — a PC-based CNC motion controller.
#[derive(Parser)]
#[command(name = "softnc", version, about)]
struct Cli {
    /// Daemon configuration (instance and service names) for operator commands.
    /// Default: the first of `$SOFTNC_CONFIG`, `$XDG_CONFIG_HOME/softnc/default.ron`
    /// (or `~/.config/softnc/default.ron`), `/etc/softnc/default.ron`,
    /// `config/default.ron` here, and the checkout's beside the binary.
    #[arg(long, global = true)]
    config: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Validate and plan a G-code program without moving anything.
    Plan(cmd_plan::PlanArgs),
    /// Run a program on the simulated machine: planner, controller stacks and plant
    /// in one process; accuracy figures, trace and plot.
    Sim(cmd_sim::SimArgs),
    /// Terminal UI: DRO (machine and work), program listing, jog, MDI, offsets,
    /// switches, alarms, jitter, live contour error (`?` for the keys).
    Watch,
    /// Start softncd on the simulated machine, run the demo job, print the report.
    Demo(cmd_demo::DemoArgs),
    /// Design a compensator off-line (PDC of paper 000) and print its figures.
    Design(cmd_design::DesignArgs),
    /// Rerun a paper's experiment on the simulated machine, beside the paper's figures.
    Reproduce(cmd_reproduce::ReproduceArgs),
    /// Run a job repeatedly on the simulated machine and learn its errors away
    /// (paper 002 eq 5, paper 004 eq 8–9); `learn list|show|clear` manage the store.
    Learn(cmd_learn::LearnArgs),
    /// EtherCAT: `scan` lists the SubDevices on a bus with their identities.
    Ethercat(cmd_ethercat::EthercatArgs),
    #[command(flatten)]
    Operator(cmd_operator::OperatorCmd),
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

#[allow(unsafe_code)] // (its SAFETY lines below)
fn main() -> ExitCode {
    // output into a closed pipe (`softnc jobs | head`) ends the process quietly, as
    // it does any Unix tool, instead of an error or a panic at the next print
    // SAFETY: resetting a signal's disposition to its default, before any thread
    unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    let cli = Cli::parse();
    let config = softnc_daemon::cli::find_config(cli.config.clone());
    let result: Result<ExitCode> = match cli.command {
        Command::Plan(args) => cmd_plan::run(args),
        Command::Sim(args) => cmd_sim::run(args, &config),
        Command::Operator(cmd) => cmd_operator::run(cmd, &config),
        Command::Demo(args) => cmd_demo::run(args, &config),
        Command::Design(args) => cmd_design::run(args),
        Command::Reproduce(args) => cmd_reproduce::run(args),
        Command::Learn(args) => cmd_learn::run(args),
        Command::Ethercat(args) => cmd_ethercat::run(args),
        Command::Watch => cmd_watch::run(&config),
    };
    exit_code(result)
}

/// A command's exit status; an error is printed first.
fn exit_code(result: Result<ExitCode>) -> ExitCode {
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("softnc: {e:#}");
            ExitCode::from(1)
        }
    }
}
