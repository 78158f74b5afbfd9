//! `softncd`: the supervisor. Starts `softnc-mmi`, `softnc-position` and
//! `softnc-interp` from its own folder with the same `--config`.
use std::process::ExitCode;

fn main() -> ExitCode {
    let cfg = match softnc_daemon::cli::start("softncd") {
        Ok(c) => c,
        Err(code) => return code,
    };
    let r = softnc_daemon::supervisor::Supervisor::new(cfg).and_then(|mut s| s.run());
    softnc_daemon::cli::finish("softncd", r)
}
