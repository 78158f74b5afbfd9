//! `softnc-mmi`: job queue, machine state, alarms, history, operator API.
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softnc-mmi") {
        Ok(c) => c,
        Err(code) => return code,
    };
    // SIGTERM/SIGINT and softncd's death stop it in order (a job along its path)
    let stop = match softnc_daemon::lifecycle::StopWatch::start(true) {
        Ok(s) => s,
        Err(e) => return softnc_daemon::cli::finish("softnc-mmi", Err(e.into())),
    };
    let r = softnc_daemon::mmi::MmiTask::new(cfg).and_then(|mut t| {
        t.set_stop_watch(stop);
        t.run()
    });
    softnc_daemon::cli::finish("softnc-mmi", r)
}
