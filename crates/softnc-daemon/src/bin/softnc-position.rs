//! `softnc-position`: the position-control process on the simulated machine.
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softnc-position") {
        Ok(c) => c,
        Err(code) => return code,
    };
    // SIGTERM/SIGINT and softncd's death stop it in order (a job along its path)
    let stop = match softnc_daemon::lifecycle::StopWatch::start(true) {
        Ok(s) => s,
        Err(e) => return softnc_daemon::cli::finish("softnc-position", Err(e.into())),
    };
    // the simulated machine, seeded by the profile, exactly as `softnc sim` builds it
    let machine = cfg.machine.clone();
    let make_engine: softnc_daemon::position::EngineFactory<softnc_sim::SimBackend> =
        Box::new(move || {
            softnc_sim::CycleEngine::simulated(
                &machine,
                machine.servo.seed,
                softnc_sim::SimOptions::default(),
            )
        });
    let rt = softnc_rt::setup_realtime(&cfg.config.position_rt);
    tracing::info!("position real-time set-up: {rt:?}");
    let r = softnc_daemon::position::PositionTask::new(cfg, make_engine).and_then(|mut t| {
        t.set_stop_watch(stop);
        t.run()
    });
    softnc_daemon::cli::finish("softnc-position", r)
}
