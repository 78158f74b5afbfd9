//! `softnc-interp`: the interpolation process.
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softnc-interp") {
        Ok(c) => c,
        Err(code) => return code,
    };
    // SIGTERM/SIGINT and softncd's death stop it in order (a job along its path)
    let stop = match softnc_daemon::lifecycle::StopWatch::start(true) {
        Ok(s) => s,
        Err(e) => return softnc_daemon::cli::finish("softnc-interp", Err(e.into())),
    };
    let rt = softnc_rt::setup_realtime(&cfg.config.interp_rt);
    tracing::info!("interp real-time set-up: {rt:?}");
    let r = softnc_daemon::interp::InterpTask::new(cfg).and_then(|mut t| {
        t.set_stop_watch(stop);
        t.run()
    });
    softnc_daemon::cli::finish("softnc-interp", r)
}
