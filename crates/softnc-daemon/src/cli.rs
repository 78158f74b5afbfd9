//! Shared start-up of the daemon binaries: `--config PATH`, logging, exit status.

use crate::config::{DaemonConfig, Loaded};
use std::path::PathBuf;
use std::process::ExitCode;

/// The configuration path from `--config PATH` (default `config/default.ron`).
pub fn config_path() -> PathBuf {
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--config" {
            if let Some(p) = args.next() {
                return PathBuf::from(p);
            }
        } else if let Some(p) = a.strip_prefix("--config=") {
            return PathBuf::from(p);
        }
    }
    PathBuf::from("config/default.ron")
}

/// Initialise logging (`RUST_LOG`, default info) and load the configuration.
pub fn start(process: &str) -> Result<Loaded, ExitCode> {
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .try_init();
    let path = config_path();
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
