//! `isoline run`: the streaming daemon until end of input or a signal.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use anyhow::{Context, Result};

/// `isoline run` options.
#[derive(clap::Args)]
pub struct Args {
    /// Daemon configuration: [input] [output] [pipeline] [live] [metrics] [tracing],
    /// and [mesh] [solver] [export].
    #[arg(short, long)]
    config: PathBuf,
}

/// Runs the daemon. The first SIGINT or SIGTERM stops ingest and lets the frames in
/// flight finish; a second one exits at once.
pub fn run(a: Args) -> Result<()> {
    let cfg = isoline::pipeline::DaemonConfig::load(&a.config)?;
    let guard = super::init_tracing(&cfg.log, cfg.chrome_trace.as_deref())?;
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // Registered first, so it sees the flag as the previous signal left it.
        signal_hook::flag::register_conditional_shutdown(sig, 130, stop.clone())
            .context("installing signal handlers")?;
        signal_hook::flag::register(sig, stop.clone()).context("installing signal handlers")?;
    }
    let mut daemon = isoline::pipeline::Daemon::start(&cfg, stop.clone())?;
    let lingering = daemon.lingering();
    if let Some(addr) = daemon.tcp_addr {
        eprintln!("isoline run: listening on {addr}");
    }
    if let Some(addr) = daemon.metrics_addr {
        eprintln!("isoline run: metrics on http://{addr}/metrics, health on /health");
    }
    if let Some(addr) = daemon.live_addr {
        eprintln!("isoline run: live view on ws://{addr} (Foxglove: Open connection)");
    }
    let summary = daemon.wait()?;
    drop(guard);
    eprintln!("isoline run: {summary}");
    if let Some(live) = lingering {
        eprintln!(
            "isoline run: the input has ended; the live view keeps serving on ws://{} \
             until Ctrl-C",
            live.addr()
        );
        live.serve_until(&stop);
    }
    Ok(())
}
