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
use crate::pipeline::listen::{read_head_or_answer, respond, Bounds, Server};

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
    /// What makes the daemon unhealthy besides full queues, by what reports it (the
    /// Kafka input's broker and partitions, the Kafka sink's deliveries).
    conditions: std::sync::Mutex<std::collections::BTreeMap<&'static str, String>>,
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
            conditions: Default::default(),
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

    /// Sets (`Some`) or clears (`None`) what `source` finds wrong; `/health` fails while
    /// any is set.
    #[cfg_attr(not(feature = "kafka"), allow(dead_code))]
    pub(crate) fn condition(&self, source: &'static str, problem: Option<String>) {
        let mut c = self.conditions.lock().unwrap_or_else(|p| p.into_inner());
        match problem {
            Some(p) => {
                if c.get(source) != Some(&p) {
                    tracing::warn!(source, "unhealthy: {p}");
                }
                c.insert(source, p);
            }
            None => {
                if c.remove(source).is_some() {
                    tracing::info!(source, "healthy again");
                }
            }
        }
    }

    /// Whether the daemon keeps up and its sources and sinks work: no queue full, no
    /// condition set. `Err` names each problem.
    pub fn health(&self) -> std::result::Result<(), String> {
        let mut full: Vec<String> = QUEUES
            .iter()
            .filter(|q| self.queue_depth.with_label_values(&[**q]).get() >= self.capacity as i64)
            .map(|q| format!("the {q} queue is full"))
            .collect();
        full.extend(
            self.conditions
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .values()
                .cloned(),
        );
        if full.is_empty() {
            Ok(())
        } else {
            Err(full.join("; "))
        }
    }
}

/// What one written record adds to the metrics, taken when it is made and counted when
/// it is written (a file, standard output, MCAP) or acknowledged (Kafka).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Counted {
    outcome: &'static str,
    /// A reconstruction's record: its latency is observed.
    reconstructed: bool,
    warm: bool,
    cold_fallback: bool,
    empty: bool,
    warnings: bool,
    arrived: std::time::Instant,
}

impl Counted {
    /// The tally of `rec`, whose frame was read at `arrived`.
    pub(crate) fn of(
        rec: &isoline_io::format::ResultRecord,
        arrived: std::time::Instant,
    ) -> Counted {
        let outcome = if rec.skipped == Some(true) {
            "skipped"
        } else if rec.error.is_some() {
            "error"
        } else {
            "reconstructed"
        };
        let st = rec.stats.as_ref();
        Counted {
            outcome,
            reconstructed: st.is_some(),
            warm: st.is_some_and(|s| s.warm_start),
            cold_fallback: st.is_some_and(|s| s.cold_fallback),
            empty: st.is_some() && rec.polylines.as_ref().is_some_and(Vec::is_empty),
            warnings: rec.warnings.is_some(),
            arrived,
        }
    }

    /// Counts the record.
    pub(crate) fn count(&self, metrics: &Metrics) {
        metrics.records.with_label_values(&[self.outcome]).inc();
        if self.reconstructed {
            metrics
                .latency_seconds
                .observe(self.arrived.elapsed().as_secs_f64());
        }
        if self.warm {
            metrics.warm.inc();
        }
        if self.cold_fallback {
            metrics.cold_fallbacks.inc();
        }
        if self.empty {
            metrics.empty.inc();
        }
        if self.warnings {
            metrics.warnings.inc();
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
            let Some(head) = read_head_or_answer(&mut conn) else {
                return;
            };
            if head.method != "GET" {
                return respond(conn, 405, "text/plain", b"GET /metrics, GET /health\n");
            }
            let (status, kind, body) = match head.path.as_str() {
                "/metrics" => (200, "text/plain; version=0.0.4", metrics.text()),
                "/health" => match metrics.health() {
                    Ok(()) => (200, "text/plain", "ok\n".to_string()),
                    Err(why) => (503, "text/plain", format!("unhealthy: {why}\n")),
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
        m.queue_depth.with_label_values(&["solve"]).set(0);
        m.condition("kafka input", Some("no broker reachable for 12 s".into()));
        assert_eq!(m.health().unwrap_err(), "no broker reachable for 12 s");
        m.condition("kafka input", None);
        assert!(m.health().is_ok());
    }
}
