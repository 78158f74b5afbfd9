//! `softnc-position`: the position-control process, on the servo backend the
//! configuration names (`backend:`; the profile's simulated machine by default).
use softnc_daemon::config::{BackendKind, Loaded};
use softnc_daemon::lifecycle::StopWatch;
use softnc_daemon::position::{EngineFactory, PositionTask};
use softnc_ethercat::EtherCatBackend;
use softnc_servo::{CycleEngine, LoopbackBackend, ServoBackend};
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softnc-position") {
        Ok(c) => c,
        Err(code) => return code,
    };
    // SIGTERM/SIGINT and softncd's death stop it in order (a job along its path)
    let stop = match StopWatch::start(true) {
        Ok(s) => s,
        Err(e) => return softnc_daemon::cli::finish("softnc-position", Err(e.into())),
    };
    let machine = cfg.machine.clone();
    let r = match cfg.config.backend.clone() {
        // the simulated machine, seeded by the profile, exactly as `softnc sim` builds it
        BackendKind::Simulated => run(
            cfg,
            stop,
            Box::new(move || {
                softnc_sim::simulated_engine(
                    &machine,
                    machine.servo.seed,
                    softnc_sim::SimOptions::default(),
                )
            }),
        ),
        BackendKind::Loopback => run(
            cfg,
            stop,
            Box::new(move || CycleEngine::new(&machine, LoopbackBackend::new())),
        ),
        // a handle per job, its bus brought up by the first one's enable (the next
        // jobs take the running one over)
        BackendKind::EtherCat(settings) => {
            let bus = settings.bus_config(machine.interpolation_cycle_s);
            match EtherCatBackend::new(&bus) {
                Ok(_) => run(
                    cfg,
                    stop,
                    Box::new(move || {
                        let b = EtherCatBackend::new(&bus).expect("checked at start");
                        CycleEngine::new(&machine, b)
                    }),
                ),
                Err(e) => Err(anyhow::anyhow!("backend EtherCat: {e}")),
            }
        }
    };
    softnc_daemon::cli::finish("softnc-position", r)
}

fn run<B: ServoBackend + Send + 'static>(
    cfg: Loaded,
    stop: StopWatch,
    mut make_engine: EngineFactory<B>,
) -> anyhow::Result<()> {
    tracing::info!("servo backend: {:?}", cfg.config.backend);
    let rt = softnc_rt::setup_realtime(&cfg.config.position_rt);
    tracing::info!("position real-time set-up: {rt:?}");
    // drives enabled before they run (off the cycle): a backend kept across jobs
    // once, the first (the next jobs take it over), any other with every engine
    let mut first = true;
    let enabled: EngineFactory<B> = Box::new(move || {
        let mut e = make_engine();
        if std::mem::take(&mut first) || !e.backend().kept_across_jobs() {
            if let Err(err) = e.backend_mut().enable() {
                tracing::error!("servo backend: {err}");
            }
        }
        e
    });
    let mut t = PositionTask::new(cfg, enabled)?;
    t.set_stop_watch(stop);
    t.run()
}
