//! Metrics for operators: counters, stage-time histograms and queue depths in a
//! Prometheus registry, always kept (a few atomics a frame), and served on request as
//! Prometheus text (`/metrics`) with a health check (`/health`) by a small HTTP server
//! on its own thread, loopback by default (`[metrics] bind`).

use std::net::SocketAddr;
use std::sync::Arc;

use prometheus::{
    Encoder, Histogram, HistogramOpts, HistogramVec, IntCounter, IntCounterVec, IntGaugeVec, Opts,
    Registry, TextEncoder,
};

use crate::error::Result;
use crate::pipeline::listen::{read_head, respond, Bounds, HeadError, Server};

/// The queues between stages, by the stage that reads them.
pub const QUEUES: [&str; 6] = [
    "ingest",
    "distance",
    "adapt",
    "solve",
    "renormalize",
    "export",
];

/// Histogram buckets of stage and frame times, seconds: 1 ms to 10 s.
const BUCKETS: [f64; 13] = [
    0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0, 10.0,
];

/// The daemon's metrics.
pub struct Metrics {
    registry: Registry,
    /// Lines (or recording messages) read: frames in.
    pub(crate) frames_in: IntCounter,
    /// Records written, by outcome: `reconstructed`, `error`, `skipped`.
    pub(crate) records: IntCounterVec,
    /// Reconstructed frames that started warm.
    pub(crate) warm: IntCounter,
    /// Warm starts redone cold.
    pub(crate) cold_fallbacks: IntCounter,
    /// Records with warnings.
    pub(crate) warnings: IntCounter,
    /// Reconstructed frames without a curve.
    pub(crate) empty: IntCounter,
    /// Frames the live view was too far behind to show.
    pub(crate) live_dropped: IntCounter,
    /// Time in each stage's function, by stage.
    pub(crate) stage_seconds: HistogramVec,
    /// From reading a frame to writing its record.
    pub(crate) latency_seconds: Histogram,
    /// Frames waiting in each queue, by the stage that reads it (as last seen by it).
    pub(crate) queue_depth: IntGaugeVec,
    /// Kafka input: messages behind the committed offset, by assigned partition.
    #[cfg_attr(not(feature = "kafka"), allow(dead_code))]
    pub(crate) consumer_lag: IntGaugeVec,
    /// Each queue's capacity.
    capacity: usize,
}

impl Metrics {
    /// Empty metrics for queues of `capacity` frames.
    pub fn new(capacity: usize) -> Metrics {
        let registry = Registry::new();
        let counter = |name: &str, help: &str| {
            let c = IntCounter::new(name, help).expect("a valid metric");
            registry.register(Box::new(c.clone())).expect("a new name");
            c
        };
        let frames_in = counter("isoline_frames_in_total", "Frames (lines, messages) read.");
        let warm = counter(
            "isoline_warm_starts_total",
            "Reconstructed frames that started from their predecessor.",
        );
        let cold_fallbacks = counter(
            "isoline_cold_fallbacks_total",
            "Warm starts found worse than the previous frame and redone cold.",
        );
        let warnings = counter("isoline_warnings_total", "Records with warnings.");
        let empty = counter(
            "isoline_empty_total",
            "Reconstructed frames without a curve.",
        );
        let live_dropped = counter(
            "isoline_live_view_dropped_total",
            "Frames the live view was too far behind to show.",
        );
        let records = IntCounterVec::new(
            Opts::new("isoline_records_total", "Records written, by outcome."),
            &["outcome"],
        )
        .expect("a valid metric");
        let stage_seconds = HistogramVec::new(
            HistogramOpts::new("isoline_stage_seconds", "Time in each stage, per frame.")
                .buckets(BUCKETS.to_vec()),
            &["stage"],
        )
        .expect("a valid metric");
        let latency_seconds = Histogram::with_opts(
            HistogramOpts::new(
                "isoline_frame_latency_seconds",
                "From reading a frame to writing its record.",
            )
            .buckets(BUCKETS.to_vec()),
        )
        .expect("a valid metric");
        let queue_depth = IntGaugeVec::new(
            Opts::new(
                "isoline_queue_depth",
                "Frames waiting in the queue read by a stage.",
            ),
            &["stage"],
        )
        .expect("a valid metric");
        let consumer_lag = IntGaugeVec::new(
            Opts::new(
                "isoline_kafka_consumer_lag",
                "Kafka input: messages after the committed offset, by assigned partition.",
            ),
            &["partition"],
        )
        .expect("a valid metric");
        for m in [
            Box::new(records.clone()) as Box<dyn prometheus::core::Collector>,
            Box::new(consumer_lag.clone()),
            Box::new(stage_seconds.clone()),
            Box::new(latency_seconds.clone()),
            Box::new(queue_depth.clone()),
        ] {
            registry.register(m).expect("a new name");
        }
        for outcome in ["reconstructed", "error", "skipped"] {
            records.with_label_values(&[outcome]);
        }
        for q in QUEUES {
            queue_depth.with_label_values(&[q]);
        }
        Metrics {
            registry,
            frames_in,
            records,
            warm,
            cold_fallbacks,
            warnings,
            empty,
            live_dropped,
            stage_seconds,
            latency_seconds,
            queue_depth,
            consumer_lag,
            capacity: capacity.max(1),
        }
    }

    /// Everything, as Prometheus text.
    pub fn text(&self) -> String {
        let mut out = Vec::new();
        TextEncoder::new()
            .encode(&self.registry.gather(), &mut out)
            .expect("encoding into a Vec");
        String::from_utf8(out).expect("Prometheus text is UTF-8")
    }

    /// Whether the daemon keeps up: no queue full. `Err` names the queues that are.
    pub fn health(&self) -> std::result::Result<(), String> {
        let full: Vec<String> = QUEUES
            .iter()
            .filter(|q| self.queue_depth.with_label_values(&[**q]).get() >= self.capacity as i64)
            .map(|q| format!("the {q} queue is full"))
            .collect();
        if full.is_empty() {
            Ok(())
        } else {
            Err(full.join("; "))
        }
    }
}

/// Connections the metrics endpoint serves at once (scrapers and health checks answer
/// in milliseconds; more are answered `503`).
pub const MAX_METRICS_CONNECTIONS: usize = 16;

/// The HTTP server of the metrics; stops when dropped.
pub struct MetricsServer {
    server: Server,
}

impl MetricsServer {
    /// Serves `metrics` on `bind` (port 0: any free port): `GET /metrics`, `GET /health`
    /// (200 `ok` when the daemon keeps up, 503 with the reasons when it does not). Each
    /// connection gets one answer and is closed; request bodies are never read.
    pub fn start(bind: SocketAddr, metrics: Arc<Metrics>) -> Result<MetricsServer> {
        let bounds = Bounds {
            max_connections: MAX_METRICS_CONNECTIONS,
        };
        let server = Server::start("metrics", bind, bounds, move |mut conn, _, _| {
            let head = match read_head(&mut conn) {
                Ok(h) => h,
                Err(HeadError::TooLarge) => {
                    return respond(conn, 431, "text/plain", b"request head too large\n")
                }
                Err(HeadError::Malformed) => {
                    return respond(conn, 400, "text/plain", b"not an HTTP request\n")
                }
                Err(HeadError::Gone) => return,
            };
            if head.method != "GET" {
                return respond(conn, 405, "text/plain", b"GET /metrics, GET /health\n");
            }
            let (status, kind, body) = match head.path.as_str() {
                "/metrics" => (200, "text/plain; version=0.0.4", metrics.text()),
                "/health" => match metrics.health() {
                    Ok(()) => (200, "text/plain", "ok\n".to_string()),
                    Err(why) => (503, "text/plain", format!("behind: {why}\n")),
                },
                _ => (404, "text/plain", "not found: /metrics, /health\n".into()),
            };
            respond(conn, status, kind, body.as_bytes());
        })?;
        tracing::info!(addr = %server.addr(), "metrics listening");
        Ok(MetricsServer { server })
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        self.server.addr()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counters_render_and_health_follows_the_queues() {
        let m = Metrics::new(4);
        m.frames_in.inc();
        m.records.with_label_values(&["reconstructed"]).inc();
        m.stage_seconds.with_label_values(&["solve"]).observe(0.003);
        let text = m.text();
        for line in [
            "isoline_frames_in_total 1",
            "isoline_records_total{outcome=\"reconstructed\"} 1",
            "isoline_records_total{outcome=\"skipped\"} 0",
            "isoline_stage_seconds_bucket{stage=\"solve\",le=\"0.005\"} 1",
            "isoline_queue_depth{stage=\"adapt\"} 0",
        ] {
            assert!(text.contains(line), "{line} not in\n{text}");
        }
        assert!(m.health().is_ok());
        m.queue_depth.with_label_values(&["solve"]).set(4);
        assert!(m.health().unwrap_err().contains("solve queue is full"));
    }
}
