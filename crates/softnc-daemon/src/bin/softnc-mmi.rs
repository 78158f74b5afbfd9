//! `softnc-mmi`: job queue, machine state, alarms, history, operator API.
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softnc-mmi") {
        Ok(c) => c,
        Err(code) => return code,
    };
    let r = softnc_daemon::mmi::MmiTask::new(cfg).and_then(|mut t| t.run());
    softnc_daemon::cli::finish("softnc-mmi", r)
}
