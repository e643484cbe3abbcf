//! The streaming daemon (`isoline run`): the stages of `isoline_core::stages` as threads
//! connected by bounded crossbeam channels (docs/daemon.md).
//!
//! ```text
//! sources -> ingest -> distance -> adapt -> solve -> renormalize -> export -> sinks
//!                                    ^        ^  <- level set ----'
//!                                 last mesh  (per stream)             └-> map
//! ```
//!
//! Each stage is one thread that calls the library's plain stage function on each frame
//! and passes the frame on; the numerical work inside a stage runs on the shared rayon
//! pool. Every stage takes frames in order, so the frames of a stream stay in order, and
//! a frame that fails or is skipped travels on as such, so that every frame read gets one
//! record, in its place. The adapt stage keeps each stream's last mesh, so that the next
//! frame's adaptation overlaps with this frame's solve; the solve stage keeps each
//! stream's last renormalized level set, which the renormalize stage sends back, and
//! waits for it before solving the stream's next frame.

pub mod config;
#[cfg(feature = "kafka")]
pub mod kafka;
mod ledger;
mod listen;
#[cfg(feature = "live")]
mod live;
/// A build without the live view: the configuration refuses `[live]`, so none starts.
#[cfg(not(feature = "live"))]
mod live {
    use crate::error::{Error, Result};
    use isoline_io::foxglove::FrameView;

    /// Stands in for the live view of a build without it.
    pub struct LiveView;

    impl LiveView {
        pub fn start(bind: std::net::SocketAddr) -> Result<LiveView> {
            Err(Error::Internal(format!(
                "no live view on {bind}: built without the live feature"
            )))
        }

        pub fn addr(&self) -> std::net::SocketAddr {
            unreachable!("never started")
        }

        pub fn show(&self, _: FrameView) -> bool {
            false
        }
    }
}
pub mod map;
pub mod metrics;
mod sink;
pub mod source;
mod stages;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use crossbeam_channel::bounded;
use serde::Serialize;

pub use config::{DaemonConfig, Policy, Source};
pub use map::{MapOutput, MapReport};
pub use source::Replay;

use crate::error::{Error, Result};

/// What a daemon run did, for the closing log line.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunSummary {
    /// Records written (one per frame read).
    pub records: usize,
    /// Records with curves.
    pub reconstructed: usize,
    /// Error records (bad frames).
    pub errors: usize,
    /// Frames skipped under the `latest` policy.
    pub skipped: usize,
    /// Reconstructed frames that started from their predecessor's level set.
    pub warm: usize,
    /// Warm starts found worse than the previous frame and redone cold.
    pub cold_fallbacks: usize,
    /// Reconstructed frames by where their level set came from (`stats.start`): `cold`,
    /// `warm` or `fallback` for point frames, `scan`, `fused` or `fallback` for scans
    /// (a scan is built from its own scan by design, whatever `warm_start` says).
    pub starts: std::collections::BTreeMap<String, usize>,
    /// Records with warnings (no curve where the data have support, most data
    /// unexplained).
    pub warnings: usize,
    /// Reconstructed frames without any curve.
    pub empty: usize,
    /// The most state a stream held after a frame, bytes: the mesh the adapt stage
    /// keeps, and the mesh and level set the solve stage keeps, for the next frame
    /// (0 without warm starts).
    pub state_bytes_max: usize,
    /// Seconds from the first frame read to the last record written.
    pub seconds: f64,
    /// Records per second over that time.
    pub frames_per_second: f64,
    /// Median latency (frame read to record written), milliseconds.
    pub latency_p50: f64,
    /// 99th percentile latency, milliseconds.
    pub latency_p99: f64,
    /// Median solver iterations of warm-started frames.
    pub iterations_warm: Option<f64>,
    /// Median solver iterations of cold-started frames.
    pub iterations_cold: Option<f64>,
    /// Frames the live view did not show because it was behind (its viewers lose
    /// frames, the output none).
    pub live_dropped: u64,
    /// Median milliseconds a reconstructed frame spent in the compute stages (its
    /// record's `stats.ms.total`).
    pub stage_ms_p50: Option<f64>,
    /// Median milliseconds a reconstructed frame waited: its latency less its time in
    /// the compute stages (queues, stages busy with other frames, a CPU busy with other
    /// work shows in the stages' own time and in `cpu_seconds` instead).
    pub wait_ms_p50: Option<f64>,
    /// Mean milliseconds a reconstructed frame spent in each stage: distance, adapt,
    /// solve, renormalize, export (they add up to the mean total).
    pub stage_ms_mean: Option<[f64; 5]>,
    /// CPU seconds the process used over the run, all threads (where the platform
    /// tells).
    pub cpu_seconds: Option<f64>,
    /// The map of the run, when `[map] output` is set.
    pub map: Option<MapReport>,
}

impl RunSummary {
    /// CPU milliseconds per record: the process's CPU time over the run (reading,
    /// every stage, writing), over the records written.
    pub fn cpu_ms_per_frame(&self) -> Option<f64> {
        self.cpu_seconds
            .filter(|_| self.records > 0)
            .map(|s| 1e3 * s / self.records as f64)
    }
}

impl std::fmt::Display for RunSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} records ({} reconstructed, {} errors, {} skipped) in {:.2} s: {:.1} frames/s, \
             latency p50 {:.1} ms p99 {:.1} ms",
            self.records,
            self.reconstructed,
            self.errors,
            self.skipped,
            self.seconds,
            self.frames_per_second,
            self.latency_p50,
            self.latency_p99
        )?;
        let its = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{v}"));
        let starts: Vec<String> = self
            .starts
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        write!(
            f,
            "; starts: {}; {} with warnings, {} empty; median iterations warm {} cold {}; \
             state per stream up to {:.0} KiB",
            if starts.is_empty() {
                "none".to_string()
            } else {
                starts.join(", ")
            },
            self.warnings,
            self.empty,
            its(self.iterations_warm),
            its(self.iterations_cold),
            self.state_bytes_max as f64 / 1024.0
        )?;
        if let Some(cpu) = self.cpu_ms_per_frame() {
            write!(f, "; CPU {cpu:.2} ms a frame")?;
        }
        if let (Some(p50), Some([d, a, s, r, e])) = (self.stage_ms_p50, self.stage_ms_mean) {
            write!(
                f,
                "; stages {p50:.2} ms a frame (median; mean distance {d:.2}, adapt {a:.2}, \
                 solve {s:.2}, renormalize {r:.2}, export {e:.2})"
            )?;
        }
        if let Some(w) = self.wait_ms_p50 {
            write!(
                f,
                "; waiting {w:.2} ms a frame (median: latency less the stages)"
            )?;
        }
        if self.live_dropped > 0 {
            write!(f, "; live view behind for {} frames", self.live_dropped)?;
        }
        if let Some(m) = &self.map {
            write!(
                f,
                "; map of {} scans ({} unplaced, {} passed by): {} pieces, {:.1} m, static \
                 returns within tolerance {:.1}%, seen through {:.2}%, written {} times",
                m.scans,
                m.unplaced,
                m.behind,
                m.pieces,
                m.length,
                100.0 * m.static_within,
                100.0 * m.seen_through,
                m.writes
            )?;
            if m.refused > 0 {
                write!(f, "; {} scans beyond the map's reach left out", m.refused)?;
            }
            if m.tiles_dropped > 0 {
                write!(
                    f,
                    "; {} stored tiles forgotten (max_stored_tiles)",
                    m.tiles_dropped
                )?;
            }
        }
        Ok(())
    }
}

/// Starts a named thread of the daemon (a source, a stage), or says why it could not.
pub(crate) fn spawn<T: Send + 'static>(
    name: &str,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<std::thread::JoinHandle<T>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        .map_err(|e| Error::Internal(format!("cannot start thread {name}: {e}")))
}

/// A stage's thread, by the stage's name.
type StageThread = (&'static str, std::thread::JoinHandle<()>);

/// The compute stages (ingest to renormalize) as threads, each reading its bounded
/// queue; returns them by name and the queue the export stage reads.
fn spawn_compute(
    cfg: &DaemonConfig,
    line_rx: crossbeam_channel::Receiver<source::Line>,
    stop: &Arc<AtomicBool>,
    metrics: &Arc<metrics::Metrics>,
    streams: stages::StreamBounds,
) -> Result<(Vec<StageThread>, crossbeam_channel::Receiver<stages::Msg>)> {
    let q = cfg.queue;
    let (to_distance, distance_rx) = bounded(q);
    // With registration, a stage between ingest and distance: ingest sends to it.
    let (to_register, register_rx) = bounded(q);
    let (to_adapt, adapt_rx) = bounded(q);
    let (to_solve, solve_rx) = bounded(q);
    let (to_renorm, renorm_rx) = bounded(q);
    let (to_export, export_rx) = bounded(q);
    // The renormalize stage can finish at most its queue plus the frame in hand while
    // the solve stage is blocked sending: that bounds the level sets in flight.
    let (feedback_tx, feedback_rx) = bounded(q + 2);
    let mut params = cfg.params.clone();
    params.scan.refine = cfg.accumulate.is_some();
    let params = Arc::new(params);
    let (warm, policy) = (cfg.warm_start, cfg.policy);
    let mut threads = vec![(
        "ingest",
        stages::spawn_ingest(
            line_rx,
            if cfg.register.is_some() {
                to_register
            } else {
                to_distance.clone()
            },
            stop.clone(),
            cfg.poll,
            cfg.time_increment,
            metrics.clone(),
        )?,
    )];
    if let Some(register) = cfg.register {
        threads.push((
            "register",
            stages::spawn_register(
                register_rx,
                to_distance,
                policy,
                register,
                cfg.time_increment,
                streams.clone(),
                metrics.clone(),
            )?,
        ));
    } else {
        drop((to_distance, register_rx));
    }
    threads.extend([
        (
            "distance",
            stages::spawn_distance(
                distance_rx,
                to_adapt,
                policy,
                params,
                cfg.map.is_some(),
                metrics.clone(),
            )?,
        ),
        (
            "adapt",
            stages::spawn_adapt(
                adapt_rx,
                to_solve,
                policy,
                warm,
                streams.clone(),
                metrics.clone(),
            )?,
        ),
        (
            "solve",
            stages::spawn_solve(
                solve_rx,
                to_renorm,
                feedback_rx,
                policy,
                warm,
                streams,
                metrics.clone(),
            )?,
        ),
        (
            "renormalize",
            stages::spawn_renormalize(
                renorm_rx,
                to_export,
                warm.then_some(feedback_tx),
                metrics.clone(),
            )?,
        ),
    ]);
    Ok((threads, export_rx))
}

/// A source, started.
struct Started {
    handle: std::thread::JoinHandle<Result<()>>,
    /// The address a TCP source listens on.
    tcp_addr: Option<std::net::SocketAddr>,
    /// The partitions a Kafka source holds.
    leases: Option<Arc<ledger::Leases>>,
}

/// Starts the configured source, sending lines into `tx` until `stop`; a Kafka source
/// makes its last commit once `drained` says the pipeline has ended.
#[cfg_attr(not(feature = "kafka"), allow(unused_variables))]
fn start_source(
    cfg: &DaemonConfig,
    tx: crossbeam_channel::Sender<source::Line>,
    stop: &Arc<AtomicBool>,
    drained: &Arc<AtomicBool>,
    metrics: &Arc<metrics::Metrics>,
) -> Result<Started> {
    let limits = cfg.limits;
    let plain = |handle| Started {
        handle,
        tcp_addr: None,
        leases: None,
    };
    Ok(match &cfg.source {
        Source::File(f) if isoline_io::is_recording(&f.path) => plain(source::spawn_recording(
            &f.path,
            f.replay,
            f.bag.clone(),
            tx,
            stop.clone(),
        )?),
        Source::File(f) => plain(source::spawn_file(
            &f.path,
            f.replay,
            limits,
            tx,
            stop.clone(),
        )?),
        Source::Stdin => plain(source::spawn_stdin(limits, tx, stop.clone())?),
        Source::Tcp { bind } => {
            let (addr, handle) = source::spawn_tcp(*bind, limits, tx, stop.clone(), cfg.poll)?;
            Started {
                handle,
                tcp_addr: Some(addr),
                leases: None,
            }
        }
        #[cfg(feature = "kafka")]
        Source::Kafka(input) => {
            let (handle, leases) = kafka::spawn_kafka(
                input,
                limits,
                tx,
                stop.clone(),
                drained.clone(),
                metrics.clone(),
                cfg.poll,
            )?;
            Started {
                handle,
                tcp_addr: None,
                leases: Some(leases),
            }
        }
    })
}

/// Handles of a running daemon.
pub struct Daemon {
    source: std::thread::JoinHandle<Result<()>>,
    stdin: bool,
    /// Set once the export stage has ended: a Kafka source then makes its last commit.
    drained: Arc<AtomicBool>,
    threads: Vec<StageThread>,
    export: std::thread::JoinHandle<Result<RunSummary>>,
    /// The map stage, when the map is on.
    map: Option<std::thread::JoinHandle<Result<MapReport>>>,
    /// The TCP address listened on, when the source is TCP.
    pub tcp_addr: Option<std::net::SocketAddr>,
    /// The live view's address, when it is on.
    pub live_addr: Option<std::net::SocketAddr>,
    /// The metrics endpoint's address, when it is on.
    pub metrics_addr: Option<std::net::SocketAddr>,
    /// Served until the run has ended.
    metrics_server: Option<metrics::MetricsServer>,
    /// The run's metrics.
    pub metrics: Arc<metrics::Metrics>,
    /// The live view, kept past the run with `[live] linger`.
    lingering: Option<Arc<live::LiveView>>,
    /// The process's CPU time when the run started, where the platform tells.
    cpu_start: Option<cpu_time::ProcessTime>,
}

/// A live view that serves on after its run has ended: viewers keep connecting and see
/// each stream's last frame.
pub struct Lingering(Arc<live::LiveView>);

impl Lingering {
    /// The address served.
    pub fn addr(&self) -> std::net::SocketAddr {
        self.0.addr()
    }

    /// Serves until `stop` is set (the daemon's SIGINT or SIGTERM flag).
    pub fn serve_until(self, stop: &AtomicBool) {
        while !stop.load(Ordering::Relaxed) {
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
    }
}

impl Daemon {
    /// Starts sources and stages. It runs until the input ends or `stop` is set; then
    /// ingest stops, frames in flight finish and the sinks flush.
    pub fn start(cfg: &DaemonConfig, stop: Arc<AtomicBool>) -> Result<Daemon> {
        let cpu_start = cpu_time::ProcessTime::try_now().ok();
        cfg.check_paths()?;
        let q = cfg.queue;
        let metrics = Arc::new(metrics::Metrics::new(q));
        #[cfg(feature = "kafka")]
        let sink = match &cfg.output_kafka {
            Some(topic) => sink::Sink::kafka(topic, metrics.clone())?,
            None => sink::Sink::open(cfg.output.as_deref())?,
        };
        #[cfg(not(feature = "kafka"))]
        let sink = sink::Sink::open(cfg.output.as_deref())?;
        if let Some(dir) = &cfg.svg_dir {
            std::fs::create_dir_all(dir).map_err(|e| isoline_io::Error::io(dir, e))?;
        }
        // Read lines wait here for ingest; on shutdown each still gets its record, so
        // this queue is no longer than the others.
        let (line_tx, line_rx) = bounded(q);
        let drained = Arc::new(AtomicBool::new(false));
        let Started {
            handle: source,
            tcp_addr,
            leases,
        } = start_source(cfg, line_tx, &stop, &drained, &metrics)?;
        let streams = stages::StreamBounds {
            max: cfg.max_streams,
            idle: cfg.stream_idle,
            leases,
        };
        let (threads, export_rx) = spawn_compute(cfg, line_rx, &stop, &metrics, streams.clone())?;
        let live = match cfg.live {
            Some(bind) => Some(Arc::new(crate::pipeline::live::LiveView::start(bind)?)),
            None => None,
        };
        let lingering = live.clone().filter(|_| cfg.live_linger);
        let live_addr = live.as_ref().map(|l| l.addr());
        let metrics_server = match cfg.metrics {
            Some(bind) => Some(metrics::MetricsServer::start(bind, metrics.clone())?),
            None => None,
        };
        let (map_tx, map) = match &cfg.map {
            Some(out) => {
                let (tx, rx) = bounded(q);
                let handle = map::spawn_map(rx, out.clone(), live.clone(), stop.clone())?;
                (Some(tx), Some(handle))
            }
            None => (None, None),
        };
        let export = stages::spawn_export(
            export_rx,
            stages::Outputs {
                sink,
                live,
                svg_dir: cfg.svg_dir.clone(),
                map: map_tx,
                map_lossy: cfg.policy == Policy::Latest,
                metrics: metrics.clone(),
            },
            stop,
            cfg.warm_start,
            cfg.accumulate,
            streams,
        )?;
        Ok(Daemon {
            source,
            stdin: cfg.source == Source::Stdin,
            drained,
            threads,
            export,
            map,
            tcp_addr,
            live_addr,
            metrics_addr: metrics_server.as_ref().map(|m| m.addr()),
            metrics_server,
            metrics,
            lingering,
            cpu_start,
        })
    }

    /// The live view, when it is to keep serving after the run (`[live] linger`): take
    /// it before [`Daemon::wait`], and serve it after with [`Lingering::serve_until`].
    pub fn lingering(&mut self) -> Option<Lingering> {
        self.lingering.take().map(Lingering)
    }

    /// Waits for the end of the run (end of input, or the stop flag and the drain).
    /// Every thread is joined and the first failure reported: the sink's, a stage's
    /// panic, or the source's read error (the records before it are written).
    pub fn wait(self) -> Result<RunSummary> {
        let summary = self
            .export
            .join()
            .map_err(|_| Error::Internal("the export stage panicked".into()))
            .and_then(|s| s);
        self.drained.store(true, Ordering::Relaxed);
        let mut failure = None;
        // The export stage has ended, so the map's queue is closed: the map stage writes
        // the final map and ends.
        let map = self.map.map(|m| {
            m.join()
                .map_err(|_| Error::Internal("the map stage panicked".into()))
                .and_then(|r| r)
        });
        let map = match map {
            Some(Ok(r)) => Some(r),
            Some(Err(e)) => {
                failure.get_or_insert(e);
                None
            }
            None => None,
        };
        for (name, t) in self.threads {
            if t.join().is_err() {
                failure.get_or_insert(Error::Internal(format!("the {name} stage panicked")));
            }
        }
        // A source blocked reading standard input cannot be interrupted; it ends with the
        // process. Every other source has seen the flag or the closed pipeline.
        if !self.stdin || self.source.is_finished() {
            match self.source.join() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => {
                    failure.get_or_insert(e);
                }
                Err(_) => {
                    failure.get_or_insert(Error::Internal("the source panicked".into()));
                }
            }
        }
        // Scrapes see the final counts until every stage has ended.
        drop(self.metrics_server);
        let mut summary = summary?;
        if let (Some(counted), Some(made)) = (summary.map.as_mut(), map) {
            *counted = MapReport {
                unplaced: counted.unplaced,
                behind: counted.behind,
                ..made
            };
        }
        summary.cpu_seconds = self
            .cpu_start
            .and_then(|c| c.try_elapsed().ok())
            .map(|d| d.as_secs_f64());
        match failure {
            Some(e) => {
                tracing::error!(records = summary.records, "run ended by: {e}");
                Err(Error::RunFailed {
                    summary: summary.to_string(),
                    cause: Box::new(e),
                })
            }
            None => Ok(summary),
        }
    }
}

/// Runs the daemon to completion: [`Daemon::start`] then [`Daemon::wait`].
pub fn run(cfg: &DaemonConfig, stop: Arc<AtomicBool>) -> Result<RunSummary> {
    let t0 = Instant::now();
    let summary = Daemon::start(cfg, stop.clone())?.wait()?;
    tracing::info!(
        seconds = t0.elapsed().as_secs_f64(),
        stopped = stop.load(Ordering::Relaxed),
        "daemon finished"
    );
    Ok(summary)
}

/// The SVG file of one frame: `DIR/STREAM-FRAME.svg` (`frame-FRAME.svg` without a
/// stream), with characters other than letters, digits, `-`, `_` and `.` replaced.
pub fn svg_path(dir: &Path, stream: Option<&str>, frame: u64) -> PathBuf {
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    match stream {
        Some(s) if !s.is_empty() => dir.join(format!("{}-{frame:06}.svg", clean(s))),
        _ => dir.join(format!("frame-{frame:06}.svg")),
    }
}
