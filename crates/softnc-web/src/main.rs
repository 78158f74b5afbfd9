//! `softnc-web`: the web operator panel (docs/web.md). `softncd` starts and watches
//! it when the daemon configuration has `web`; it serves the page and talks to the
//! MMI only through `softnc-client`, as the CLI does — never to the real-time
//! processes.
#![warn(missing_docs)]

mod link;
mod programs;
mod server;
mod trace;

use anyhow::{bail, Context, Result};
use clap::Parser;
use softnc_client::ClientConfig;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;

/// How often the panel looks whether `softncd`, its parent, is still there.
const PARENT_WATCH: Duration = Duration::from_millis(250);

/// softnc-web: the softnc controller's web operator panel (softncd starts it when
/// its configuration has `web`).
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    /// The daemon configuration (its `web` section says where to listen and where the
    /// operator token is).
    #[arg(long, value_name = "PATH", default_value = "config/default.ron")]
    config: PathBuf,
    /// Keep running when the parent process exits (started by hand, not by
    /// `softncd`).
    #[arg(long)]
    detached: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let _ = tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .try_init();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("softnc-web: {e:#}");
            ExitCode::from(2)
        }
    }
}

fn run(args: &Args) -> Result<()> {
    let config = ClientConfig::load(&args.config)?;
    let Some(web) = config.web.clone() else {
        bail!(
            "{}: no `web` section: the panel is off (docs/web.md)",
            args.config.display()
        );
    };
    if !args.detached {
        // softncd's children stop with it
        let parent = std::os::unix::process::parent_id();
        std::thread::spawn(move || loop {
            std::thread::sleep(PARENT_WATCH);
            if std::os::unix::process::parent_id() != parent {
                tracing::info!("softncd is gone: stopping");
                std::process::exit(0);
            }
        });
    }
    if std::fs::read_to_string(&web.token_file).map_or(true, |t| t.trim().is_empty()) {
        tracing::warn!(
            "no operator token in {}: the panel is read-only",
            web.token_file.display()
        );
    }
    let programs = programs::Programs::open(&config.data_dir, web.max_upload_bytes)
        .with_context(|| format!("the program store in {}", config.data_dir.display()))?;
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(async {
        let app = Arc::new(server::App {
            link: link::Link::start(&args.config, web.status_hz),
            programs,
            token_file: web.token_file.clone(),
            status_needs_token: web.status_needs_token,
            data_dir: config.data_dir.clone(),
        });
        let listener = tokio::net::TcpListener::bind(&web.listen)
            .await
            .with_context(|| format!("listening on {}", web.listen))?;
        tracing::info!("softnc-web: serving http://{}", web.listen);
        axum::serve(listener, server::router(app))
            .await
            .context("serving")
    })
}
