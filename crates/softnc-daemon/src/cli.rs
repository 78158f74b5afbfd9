//! Shared start-up of the daemon binaries: arguments (clap), logging, the
//! configuration found, exit status.

/// The file-creation mask of every controller process: nothing it creates is
/// writable by anyone but its user, nor readable by others (data, traces, history,
/// folders; iceoryx2 sets its own files' modes, see `softnc_ipc::ipc_guard`).
pub const PROCESS_UMASK: u32 = 0o027;

/// Set by `softncd` in a child it restarts (not at its first start).
pub const RESTARTED_ENV: &str = "SOFTNC_RESTARTED";

use crate::config::{DaemonConfig, Loaded};
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

/// The arguments every daemon binary takes.
#[derive(Debug, clap::Parser)]
#[command(version)]
pub struct DaemonArgs {
    /// The daemon configuration. Default: the first of `$SOFTNC_CONFIG`,
    /// `$XDG_CONFIG_HOME/softnc/default.ron` (or `~/.config/softnc/default.ron`),
    /// `/etc/softnc/default.ron`, `config/default.ron` here, and the checkout's
    /// `config/default.ron` beside the binary.
    #[arg(long, value_name = "PATH")]
    pub config: Option<PathBuf>,
}

/// What process `process` is, for its `--help`.
fn about(process: &str) -> String {
    let what = match process {
        "softncd" => "the supervisor of a softnc controller: starts softnc-mmi, softnc-position and softnc-interp, watches and stops them",
        "softnc-mmi" => "the softnc controller's MMI process: job queue, machine state, alarms, history, operator API (softncd starts it)",
        "softnc-position" => "the softnc controller's position-control process (softncd starts it)",
        "softnc-interp" => "the softnc controller's interpolation process (softncd starts it)",
        _ => "a process of the softnc controller (softncd starts it)",
    };
    format!("{process}: {what}")
}

/// The argument parser of daemon binary `process`, named and described as itself.
pub fn command_of(process: &'static str) -> clap::Command {
    use clap::CommandFactory;
    DaemonArgs::command()
        .name(process)
        .bin_name(process)
        .about(about(process))
}

/// Where the configuration is looked for when none is given, in order.
pub fn config_candidates() -> Vec<PathBuf> {
    let mut c = Vec::new();
    if let Some(p) = std::env::var_os("SOFTNC_CONFIG") {
        c.push(PathBuf::from(p));
    }
    let user = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")));
    if let Some(u) = user {
        c.push(u.join("softnc/default.ron"));
    }
    c.push(PathBuf::from("/etc/softnc/default.ron"));
    c.push(PathBuf::from("config/default.ron"));
    // a checkout: target/{debug,release}/softnc → config/default.ron
    if let Some(root) = std::env::current_exe()
        .ok()
        .and_then(|e| e.parent()?.parent()?.parent().map(PathBuf::from))
    {
        c.push(root.join("config/default.ron"));
    }
    c
}

/// The configuration to use: `given`, else the first candidate that exists (else
/// `config/default.ron`, whose absence is then the error the operator sees).
pub fn find_config(given: Option<PathBuf>) -> PathBuf {
    given.unwrap_or_else(|| {
        config_candidates()
            .into_iter()
            .find(|p| p.is_file())
            .unwrap_or_else(|| PathBuf::from("config/default.ron"))
    })
}

/// Parse the arguments, initialise logging (`RUST_LOG`, default info; colours only
/// on a terminal) and load the configuration.
#[allow(unsafe_code)] // (its SAFETY lines below)
pub fn start(process: &'static str) -> Result<Loaded, ExitCode> {
    use clap::FromArgMatches;
    // SAFETY: umask has no preconditions; set before this process creates any file
    unsafe { libc::umask(PROCESS_UMASK as libc::mode_t) };
    let args = match DaemonArgs::from_arg_matches(&command_of(process).get_matches()) {
        Ok(a) => a,
        Err(e) => e.exit(),
    };
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .try_init();
    let path = find_config(args.config);
    match DaemonConfig::load(&path) {
        Ok(l) => {
            if let Err(e) = l.setup_iceoryx2() {
                eprintln!("{process}: iceoryx2 configuration: {e}");
                return Err(ExitCode::from(2));
            }
            Ok(l)
        }
        Err(e) => {
            eprintln!("{process}: {e}");
            Err(ExitCode::from(2))
        }
    }
}

/// Turn a task result into the exit status.
pub fn finish(process: &str, r: anyhow::Result<()>) -> ExitCode {
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{process}: {e:#}");
            ExitCode::from(1)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_daemon_binary_calls_itself_by_its_name_in_its_help() {
        for process in ["softncd", "softnc-mmi", "softnc-position", "softnc-interp"] {
            let help = command_of(process).render_help().to_string();
            assert!(help.starts_with(&format!("{process}: ")), "{help}");
            assert!(
                help.contains(&format!("Usage: {process} [OPTIONS]")),
                "{help}"
            );
            assert!(!help.contains("softnc: "), "{help}");
        }
    }
}
