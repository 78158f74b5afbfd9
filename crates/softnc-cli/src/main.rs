//! `softnc`: the operator client and the offline tools (plan, sim, ...).

mod cmd_demo;
mod cmd_design;
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

/// [`Cli`] with its `plan` subcommand alone, for `softnc plan ...`: clap builds the
/// arguments of every subcommand it knows before it parses (`augment_subcommands`,
/// the operator commands most of them), about 0.2 ms of a `softnc plan` process
/// before its program is read. The attributes and doc comments are [`Cli`]'s and
/// `Command::Plan`'s: `softnc plan`'s arguments, help and errors come out the same
/// (test `plan_cli_parses_plan_as_the_whole_cli_does`).
///
/// softnc — a PC-based CNC motion controller.
#[derive(Parser)]
#[command(name = "softnc", version, about)]
struct PlanCli {
    /// Daemon configuration (instance and service names) for operator commands.
    /// Default: the first of `$SOFTNC_CONFIG`, `$XDG_CONFIG_HOME/softnc/default.ron`
    /// (or `~/.config/softnc/default.ron`), `/etc/softnc/default.ron`,
    /// `config/default.ron` here, and the checkout's beside the binary.
    #[arg(long, global = true)]
    config: Option<PathBuf>,
    #[command(subcommand)]
    command: PlanCommand,
}

/// [`PlanCli`]'s one subcommand.
#[derive(Subcommand)]
enum PlanCommand {
    /// Validate and plan a G-code program without moving anything.
    Plan(cmd_plan::PlanArgs),
}

/// The subcommand [`PlanCli`] parses: a command line whose first argument is it
/// goes to [`PlanCli`] (an option before it, such as `--config`, to [`Cli`]).
const PLAN_SUBCOMMAND: &str = "plan";

fn main() -> ExitCode {
    // output into a closed pipe (`softnc jobs | head`) ends the process quietly, as
    // it does any Unix tool, instead of an error or a panic at the next print
    // SAFETY: resetting a signal's disposition to its default, before any thread
    unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    if std::env::args_os()
        .nth(1)
        .is_some_and(|a| a == PLAN_SUBCOMMAND)
    {
        if let Some(args) = cmd_plan::PlanArgs::plain(std::env::args_os().skip(2)) {
            return exit_code(cmd_plan::run(args));
        }
        // (the daemon configuration is for operator commands: `plan` ignores it)
        let PlanCli {
            command: PlanCommand::Plan(args),
            config: _,
        } = PlanCli::parse();
        return exit_code(cmd_plan::run(args));
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// What a parser makes of a command line: the plan's arguments, or clap's error
    /// (help and version included) as it prints it, with its kind and exit status.
    fn outcome<P: Parser>(argv: &[&str], plan: impl Fn(P) -> cmd_plan::PlanArgs) -> String {
        match P::try_parse_from(argv) {
            Ok(parsed) => format!("ok {:?}", plan(parsed)),
            Err(e) => format!(
                "err {:?} exit {} {}\n{}",
                e.kind(),
                e.exit_code(),
                e,
                e.render().ansi()
            ),
        }
    }

    #[test]
    fn plan_cli_parses_plan_as_the_whole_cli_does() {
        let cases: &[&[&str]] = &[
            &["softnc", "plan", "a.ngc"],
            &["softnc", "plan", "a.ngc", "--json"],
            &["softnc", "plan", "--json", "a.ngc", "--machine", "m.ron"],
            &["softnc", "plan", "a.ngc", "--canon", "--ignore-soft-limits"],
            &["softnc", "plan", "a.ngc", "--json", "--canon"],
            &[
                "softnc",
                "plan",
                "a.ngc",
                "--params",
                "p.var",
                "--save-params",
            ],
            &["softnc", "plan", "a.ngc", "--save-params"],
            &[
                "softnc",
                "plan",
                "a.ngc",
                "--subroutine-path",
                "d1",
                "--subroutine-path=d2",
            ],
            &["softnc", "plan", "a.ngc", "--config", "c.ron"],
            &["softnc", "plan", "--config=c.ron", "a.ngc", "--json"],
            &["softnc", "plan", "--", "--json"],
            &["softnc", "plan"],
            &["softnc", "plan", "a.ngc", "b.ngc"],
            &["softnc", "plan", "a.ngc", "--jsn"],
            &["softnc", "plan", "a.ngc", "--machine"],
            &["softnc", "plan", "a.ngc", "-x"],
            &["softnc", "plan", "--help"],
            &["softnc", "plan", "-h"],
            &["softnc", "plan", "--version"],
            &["softnc", "plan", "-V"],
            &["softnc", "plan", "help"],
            &["softnc", "plan", "a.ngc", "--json", "--json"],
        ];
        for argv in cases {
            let whole = outcome(argv, |c: Cli| match c.command {
                Command::Plan(args) => args,
                _ => panic!("{argv:?} parsed as another command"),
            });
            let plan_only = outcome(argv, |c: PlanCli| match c.command {
                PlanCommand::Plan(args) => args,
            });
            assert_eq!(plan_only, whole, "{argv:?}");
        }
    }

    #[test]
    fn plain_plan_arguments_are_what_clap_makes_of_them() {
        use std::ffi::OsString;
        use std::os::unix::ffi::OsStringExt;
        let odd_name = OsString::from_vec(b"odd\xff.ngc".to_vec());
        // (command lines after `softnc plan`; true where they are plain)
        let cases: Vec<(Vec<OsString>, bool)> = [
            (&["a.ngc", "--json"][..], true),
            (&["--json", "a.ngc"], true),
            (&["a.ngc"], true),
            (&["a.ngc", "--machine", "m.ron", "--json"], true),
            (&["--machine=m.ron", "a.ngc"], true),
            (&["a.ngc", "--ignore-soft-limits", "--json"], true),
            (&["a b.ngc", "--json"], true),
            (&["help", "--json"], true),
            (&["a.ngc", "--machine", "-m.ron"], false),
            (&["a.ngc", "--machine"], false),
            (&["a.ngc", "--machine="], false),
            (
                &["a.ngc", "--machine", "m.ron", "--machine", "n.ron"],
                false,
            ),
            (&["a.ngc", "--json", "--json"], false),
            (&["a.ngc", "--json", "--canon"], false),
            (&["a.ngc", "--canon"], false),
            (&["a.ngc", "--params", "p.var"], false),
            (&["a.ngc", "--subroutine-path", "d"], false),
            (&["a.ngc", "--config", "c.ron"], false),
            (&["a.ngc", "b.ngc"], false),
            (&["a.ngc", "--jsn"], false),
            (&["a.ngc", "-h"], false),
            (&["--", "a.ngc"], false),
            (&["-", "--json"], false),
            (&["", "--json"], false),
            (&["--json"], false),
            (&[], false),
        ]
        .iter()
        .map(|(a, plain)| (a.iter().map(OsString::from).collect(), *plain))
        .chain([(vec![odd_name, OsString::from("--json")], true)])
        .collect();
        for (rest, plain) in cases {
            let quick = cmd_plan::PlanArgs::plain(rest.clone());
            assert_eq!(quick.is_some(), plain, "{rest:?}");
            if let Some(quick) = quick {
                let argv = ["softnc", "plan"]
                    .map(OsString::from)
                    .into_iter()
                    .chain(rest.clone());
                let Command::Plan(args) = Cli::try_parse_from(argv).unwrap().command else {
                    panic!("{rest:?} parsed as another command");
                };
                assert_eq!(format!("{quick:?}"), format!("{args:?}"), "{rest:?}");
            }
        }
    }
}
