//! The daemon's TOML file: `[input]`, `[output]`, `[pipeline]` and `[tracing]`, beside
//! the `[mesh]`, `[solver]` and `[export]` tables every command shares. Unknown keys are
//! refused, every problem is reported at once with its key path, and relative paths are
//! taken from the configuration file's folder.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

use super::kafka::{KafkaInput, KafkaTopic};
use super::source::Limits;
use crate::config::{value_problem, Config};
use crate::error::{Error, Result};
use isoline_core::Params;
use isoline_core::WindowLimits;

/// Where frames come from.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// An NDJSON frame file, replayed.
    File {
        /// The file.
        path: PathBuf,
        /// At what pace.
        replay: Replay,
    },
    /// NDJSON frames on standard input, as they come.
    Stdin,
    /// A TCP listener: one NDJSON frame per line, any number of clients.
    Tcp {
        /// The address to listen on.
        bind: SocketAddr,
    },
    /// A Kafka topic, one NDJSON frame a message, read as a member of a consumer group.
    Kafka(KafkaInput),
}

/// The pace of a file replay.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Replay {
    /// At the frames' recorded time stamps `t` (relative to the first frame's); frames
    /// without one are not delayed.
    Recorded,
    /// At a fixed number of frames per second.
    Rate(f64),
    /// As fast as the pipeline takes them.
    Fast,
}

/// What a full queue does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Policy {
    /// Wait: lossless, and ingest slows down to the pipeline's pace.
    #[default]
    Block,
    /// Live sensors: a stage that finds several frames of one stream waiting processes the
    /// newest and passes the older ones on as skipped (each still gets a record).
    Latest,
}

/// A validated daemon configuration.
#[derive(Clone, Debug)]
pub struct DaemonConfig {
    /// The source of frames.
    pub source: Source,
    /// NDJSON results: a file, or standard output when `None` (and not Kafka).
    pub output: Option<PathBuf>,
    /// Results to a Kafka topic, keyed by stream, instead.
    pub output_kafka: Option<KafkaTopic>,
    /// A folder for one SVG drawing per frame.
    pub svg_dir: Option<PathBuf>,
    /// Capacity of every queue between stages.
    pub queue: usize,
    /// What a full queue does.
    pub policy: Policy,
    /// Start each frame from the previous frame of its stream.
    pub warm_start: bool,
    /// Log filter when `RUST_LOG` is unset, e.g. `"info"` or `"isoline=debug"`.
    pub log: String,
    /// Where to write a Chrome/Perfetto trace of the stages' spans.
    pub chrome_trace: Option<PathBuf>,
    /// How often waiting sources and the ingest stage look for a shutdown request.
    pub poll: Duration,
    /// Longest line and most TCP clients.
    pub limits: Limits,
    /// Streams whose state (last mesh and level set) is kept; the least recently seen
    /// one is forgotten first.
    pub max_streams: usize,
    /// A stream not seen for this long is forgotten (its next frame starts cold).
    pub stream_idle: Duration,
    /// Refinement over frames: each scan frame with a pose has its level set averaged
    /// with its stream's last frames' ([`isoline_core`]).
    pub accumulate: Option<WindowLimits>,
    /// What to read from an MCAP input.
    pub bag: isoline_io::bag::BagOptions,
    /// Serve a live view (Foxglove WebSocket) on this address.
    pub live: Option<SocketAddr>,
    /// Serve Prometheus metrics and a health check on this address.
    pub metrics: Option<SocketAddr>,
    /// Reconstruction parameters.
    pub params: Params,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct InputTable {
    /// `"file"`, `"stdin"` or `"tcp"`; default `"file"` when `path` is set.
    kind: Option<String>,
    path: Option<PathBuf>,
    /// `"recorded"` (default), `"fast"`, or frames per second.
    replay: Option<toml::Value>,
    /// TCP: address to listen on. Default `127.0.0.1:7878`.
    bind: Option<String>,
    /// TCP: a bind address other than loopback must be asked for.
    allow_remote: Option<bool>,
    /// TCP: clients served at once.
    max_clients: Option<i64>,
    /// The longest line, in bytes.
    max_line_bytes: Option<i64>,
    /// MCAP input: LaserScan topics (default: all).
    topics: Option<Vec<String>>,
    /// MCAP input: the Odometry topic giving poses.
    odometry: Option<String>,
    /// MCAP input: the frame the poses are in, through `/tf`.
    world_frame: Option<String>,
    /// Kafka: `host:port[,host:port]`.
    brokers: Option<String>,
    /// Kafka: the topic.
    topic: Option<String>,
    /// Kafka: the consumer group. Default `"isoline"`.
    group: Option<String>,
    /// Kafka: librdkafka properties, passed through.
    kafka: Option<toml::Table>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MetricsTable {
    /// Address of the Prometheus endpoint. Default `127.0.0.1:9898`.
    bind: Option<String>,
    /// A bind address other than loopback must be asked for.
    allow_remote: Option<bool>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct LiveTable {
    /// Address of the Foxglove WebSocket server. Default `127.0.0.1:8765`.
    bind: Option<String>,
    /// A bind address other than loopback must be asked for.
    allow_remote: Option<bool>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputTable {
    /// `"file"` (the default) or `"kafka"`.
    kind: Option<String>,
    /// NDJSON results; `"-"` or unset: standard output.
    path: Option<PathBuf>,
    svg_dir: Option<PathBuf>,
    /// Kafka: `host:port[,host:port]`.
    brokers: Option<String>,
    /// Kafka: the topic.
    topic: Option<String>,
    /// Kafka: librdkafka properties, passed through.
    kafka: Option<toml::Table>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct PipelineTable {
    queue: Option<usize>,
    policy: Option<String>,
    warm_start: Option<bool>,
    max_streams: Option<i64>,
    stream_idle: Option<f64>,
    /// Frames in a refinement window; unset or 0: off.
    accumulate: Option<i64>,
    /// Seconds a frame stays in the window at most.
    accumulate_seconds: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct TracingTable {
    level: Option<String>,
    chrome_trace: Option<PathBuf>,
}

/// A Kafka table's topic: `brokers` and `topic` required, the passed-through
/// properties as text (a TOML number or boolean as librdkafka spells it).
fn kafka_topic(
    table: &str,
    brokers: Option<String>,
    topic: Option<String>,
    settings: Option<toml::Table>,
    problems: &mut Vec<String>,
) -> Option<KafkaTopic> {
    let mut need = |key: &str, v: Option<String>| match v.filter(|s| !s.trim().is_empty()) {
        Some(v) => Some(v),
        None => {
            problems.push(format!(
                "{table}.{key}: required when {table}.kind = \"kafka\""
            ));
            None
        }
    };
    let (brokers, topic) = (need("brokers", brokers), need("topic", topic));
    let mut kafka = std::collections::BTreeMap::new();
    for (k, v) in settings.unwrap_or_default() {
        let text = match v {
            toml::Value::String(s) => s,
            toml::Value::Integer(i) => i.to_string(),
            toml::Value::Float(f) => f.to_string(),
            toml::Value::Boolean(b) => b.to_string(),
            other => {
                problems.push(format!(
                    "{table}.kafka.{k} = {other}: expected a string, number or boolean"
                ));
                continue;
            }
        };
        kafka.insert(k, text);
    }
    Some(KafkaTopic {
        brokers: brokers?,
        topic: topic?,
        settings: kafka,
    })
}

/// The default TCP address: loopback only, so a daemon is not reachable from the network
/// unless its configuration says so.
pub const DEFAULT_BIND: &str = "127.0.0.1:7878";

/// The live view's default address (Foxglove's usual port, on loopback).
pub const DEFAULT_LIVE_BIND: &str = "127.0.0.1:8765";

/// The metrics endpoint's default address.
pub const DEFAULT_METRICS_BIND: &str = "127.0.0.1:9898";

/// The slowest and fastest fixed replay rates, frames per second.
pub const MIN_RATE: f64 = 1e-3;
/// See [`MIN_RATE`].
pub const MAX_RATE: f64 = 1e6;

/// Default of `pipeline.max_streams`.
pub const DEFAULT_MAX_STREAMS: usize = 256;
/// The most frames `pipeline.accumulate` may keep: each holds a mesh and a level set
/// (about 0.35 MB for a 1,080-beam scan), so a window of 100 is 35 MB a stream.
pub const MAX_ACCUMULATE: usize = 100;
/// Default of `pipeline.stream_idle`.
pub const DEFAULT_STREAM_IDLE: Duration = Duration::from_secs(60);

impl DaemonConfig {
    /// Reads and validates a daemon configuration file, paths included
    /// ([`DaemonConfig::check_paths`]).
    pub fn load(path: &Path) -> Result<DaemonConfig> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let name = path.display().to_string();
        let cfg = Self::parse(&text, &name, &base)?;
        cfg.check_paths().map_err(|e| match e {
            Error::Config { problems, .. } => Error::Config {
                path: name,
                problems,
            },
            e => e,
        })?;
        Ok(cfg)
    }

    /// Refuses files the run would write over its input or over each other (the
    /// results, the trace), and an input that is a folder.
    pub fn check_paths(&self) -> Result<()> {
        let mut problems = Vec::new();
        let mut written: Vec<(&str, &Path)> = Vec::new();
        if let Some(p) = &self.output {
            written.push(("output.path", p));
        }
        if let Some(p) = &self.chrome_trace {
            written.push(("tracing.chrome_trace", p));
        }
        if let Source::File { path: input, .. } = &self.source {
            if input.is_dir() {
                problems.push(format!(
                    "input.path = {:?}: a folder, not a frame file",
                    input.display().to_string()
                ));
            }
            for (key, p) in &written {
                if crate::files::same_file(input, p) {
                    problems.push(format!(
                        "{key} = {:?} is the input file: it would be overwritten",
                        p.display().to_string()
                    ));
                }
            }
        }
        for (i, (k1, p1)) in written.iter().enumerate() {
            for (k2, p2) in &written[i + 1..] {
                if crate::files::same_file(p1, p2) {
                    problems.push(format!("{k1} and {k2} name the same file"));
                }
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(Error::Config {
                path: "(daemon configuration)".into(),
                problems,
            })
        }
    }

    /// Parses and validates configuration text; `name` labels errors and relative paths
    /// are resolved against `base`.
    pub fn parse(text: &str, name: &str, base: &Path) -> Result<DaemonConfig> {
        let fail = |problems: Vec<String>| Error::Config {
            path: name.to_string(),
            problems,
        };
        let mut table: toml::Table = toml::from_str(text)
            .map_err(|e| fail(vec![e.to_string().trim().replace('\n', "\n  ")]))?;
        let mut problems = Vec::new();
        fn take<T: serde::de::DeserializeOwned + Default>(
            table: &mut toml::Table,
            key: &str,
            problems: &mut Vec<String>,
        ) -> T {
            match table.remove(key) {
                None => T::default(),
                Some(v) => v.try_into().unwrap_or_else(|e| {
                    problems.push(value_problem(&e, &format!("{key}.")));
                    T::default()
                }),
            }
        }
        let input: InputTable = take(&mut table, "input", &mut problems);
        let output: OutputTable = take(&mut table, "output", &mut problems);
        let pipeline: PipelineTable = take(&mut table, "pipeline", &mut problems);
        let tracing_t: TracingTable = take(&mut table, "tracing", &mut problems);
        let live_t: Option<LiveTable> = take(&mut table, "live", &mut problems);
        let metrics_t: Option<MetricsTable> = take(&mut table, "metrics", &mut problems);
        let params = match Config::from_table(table, name, "") {
            Ok(c) => Some(c.params()),
            Err(Error::Config { problems: p, .. }) => {
                problems.extend(p);
                None
            }
            Err(e) => return Err(e),
        };
        let resolve = |p: &Path| {
            if p.is_absolute() {
                p.to_path_buf()
            } else {
                base.join(p)
            }
        };

        let kind = input.kind.clone().unwrap_or_else(|| {
            if input.path.is_some() {
                "file"
            } else {
                "stdin"
            }
            .into()
        });
        let source = match kind.as_str() {
            "file" => match &input.path {
                None => {
                    problems.push("input.path: required when input.kind = \"file\"".into());
                    None
                }
                Some(p) => {
                    let replay = match &input.replay {
                        None => Some(Replay::Recorded),
                        Some(toml::Value::String(s)) if s == "recorded" => Some(Replay::Recorded),
                        Some(toml::Value::String(s)) if s == "fast" => Some(Replay::Fast),
                        Some(v) => match v.as_float().or(v.as_integer().map(|i| i as f64)) {
                            Some(r) if (MIN_RATE..=MAX_RATE).contains(&r) => Some(Replay::Rate(r)),
                            _ => {
                                problems.push(format!(
                                    "input.replay = {v}: expected \"recorded\", \"fast\" or \
                                     frames per second in [{MIN_RATE}, {MAX_RATE}]"
                                ));
                                None
                            }
                        },
                    };
                    replay.map(|replay| Source::File {
                        path: resolve(p),
                        replay,
                    })
                }
            },
            "stdin" => Some(Source::Stdin),
            "tcp" => {
                let bind = input.bind.clone().unwrap_or_else(|| DEFAULT_BIND.into());
                match bind.parse::<SocketAddr>() {
                    Ok(b) if !b.ip().is_loopback() && input.allow_remote != Some(true) => {
                        problems.push(format!(
                            "input.bind = {bind:?}: not a loopback address, so clients on \
                             the network could send frames; set input.allow_remote = true to \
                             mean it"
                        ));
                        None
                    }
                    Ok(bind) => Some(Source::Tcp { bind }),
                    Err(e) => {
                        problems.push(format!(
                            "input.bind = {bind:?}: {e} (expected e.g. \"{DEFAULT_BIND}\")"
                        ));
                        None
                    }
                }
            }
            "kafka" => kafka_topic(
                "input",
                input.brokers.clone(),
                input.topic.clone(),
                input.kafka.clone(),
                &mut problems,
            )
            .map(|topic| {
                Source::Kafka(KafkaInput {
                    topic,
                    group: input.group.clone().unwrap_or_else(|| "isoline".into()),
                })
            }),
            other => {
                problems.push(format!(
                    "input.kind = {other:?}: expected \"file\", \"stdin\", \"tcp\" or \"kafka\""
                ));
                None
            }
        };
        if kind != "kafka"
            && (input.brokers.is_some()
                || input.topic.is_some()
                || input.group.is_some()
                || input.kafka.is_some())
        {
            problems.push(format!(
                "input.brokers, input.topic, input.group and input.kafka apply to kind = \"kafka\", \
                 not {kind:?}"
            ));
        }
        let output_kafka = match output.kind.as_deref() {
            None | Some("file") => {
                if output.brokers.is_some() || output.topic.is_some() || output.kafka.is_some() {
                    problems.push(
                        "output.brokers, output.topic and output.kafka apply to kind = \"kafka\""
                            .into(),
                    );
                }
                None
            }
            Some("kafka") => {
                if output.path.is_some() {
                    problems.push("output.path applies to kind = \"file\", not \"kafka\"".into());
                }
                kafka_topic(
                    "output",
                    output.brokers.clone(),
                    output.topic.clone(),
                    output.kafka.clone(),
                    &mut problems,
                )
            }
            Some(other) => {
                problems.push(format!(
                    "output.kind = {other:?}: expected \"file\" or \"kafka\""
                ));
                None
            }
        };
        if kind != "file" && (input.path.is_some() || input.replay.is_some()) {
            problems.push(format!(
                "input.path and input.replay apply to kind = \"file\", not {kind:?}"
            ));
        }
        if kind != "tcp"
            && (input.bind.is_some() || input.allow_remote.is_some() || input.max_clients.is_some())
        {
            problems.push(format!(
                "input.bind, input.allow_remote and input.max_clients apply to kind = \"tcp\", \
                 not {kind:?}"
            ));
        }
        let bag = isoline_io::bag::BagOptions {
            topics: input.topics.clone().unwrap_or_default(),
            odometry: input.odometry.clone(),
            world_frame: input.world_frame.clone(),
        };
        let is_bag = input.path.as_deref().is_some_and(isoline_io::is_bag);
        if bag != Default::default() && !(kind == "file" && is_bag) {
            problems.push(
                "input.topics, input.odometry and input.world_frame apply to an MCAP input \
                 (input.path = \"....mcap\")"
                    .into(),
            );
        }
        let mut server =
            |table: &str, bind: Option<String>, remote: Option<bool>, default: &str| {
                let bind = bind.unwrap_or_else(|| default.into());
                match bind.parse::<SocketAddr>() {
                    Ok(b) if !b.ip().is_loopback() && remote != Some(true) => {
                        problems.push(format!(
                            "{table}.bind = {bind:?}: not a loopback address, so anyone on the \
                         network could connect; set {table}.allow_remote = true to mean it"
                        ));
                        None
                    }
                    Ok(b) => Some(b),
                    Err(e) => {
                        problems.push(format!(
                            "{table}.bind = {bind:?}: {e} (expected e.g. \"{default}\")"
                        ));
                        None
                    }
                }
            };
        let live = live_t.and_then(|l| server("live", l.bind, l.allow_remote, DEFAULT_LIVE_BIND));
        let metrics =
            metrics_t.and_then(|m| server("metrics", m.bind, m.allow_remote, DEFAULT_METRICS_BIND));
        let defaults = Limits::default();
        let mut bounded = |key: &str, v: Option<i64>, default: usize, lo: usize, hi: usize| match v
        {
            None => default,
            Some(v) if (lo as i64..=hi as i64).contains(&v) => v as usize,
            Some(v) => {
                problems.push(format!("{key} = {v}: must be in {lo}..={hi}"));
                default
            }
        };
        let limits = Limits {
            max_line_bytes: bounded(
                "input.max_line_bytes",
                input.max_line_bytes,
                defaults.max_line_bytes,
                1 << 10,
                1 << 30,
            ),
            max_clients: bounded(
                "input.max_clients",
                input.max_clients,
                defaults.max_clients,
                1,
                4096,
            ),
        };
        let max_streams = bounded(
            "pipeline.max_streams",
            pipeline.max_streams,
            DEFAULT_MAX_STREAMS,
            1,
            1 << 20,
        );
        let frames = bounded(
            "pipeline.accumulate",
            pipeline.accumulate,
            0,
            0,
            MAX_ACCUMULATE,
        );
        let stream_idle = match pipeline.stream_idle {
            None => DEFAULT_STREAM_IDLE,
            Some(s) if (0.001..=1e6).contains(&s) => Duration::from_secs_f64(s),
            Some(s) => {
                problems.push(format!(
                    "pipeline.stream_idle = {s}: must be in [0.001, 1e6] seconds"
                ));
                DEFAULT_STREAM_IDLE
            }
        };
        let seconds = match pipeline.accumulate_seconds {
            Some(s) if !(0.001..=1e6).contains(&s) => {
                problems.push(format!(
                    "pipeline.accumulate_seconds = {s}: must be in [0.001, 1e6] seconds"
                ));
                None
            }
            s => s,
        };
        let accumulate = (frames > 1).then_some(WindowLimits { frames, seconds });
        let queue = pipeline.queue.unwrap_or(4);
        if !(1..=4096).contains(&queue) {
            problems.push(format!("pipeline.queue = {queue}: must be in 1..=4096"));
        }
        let policy = match pipeline.policy.as_deref() {
            None | Some("block") => Policy::Block,
            Some("latest") => Policy::Latest,
            Some(other) => {
                problems.push(format!(
                    "pipeline.policy = {other:?}: expected \"block\" or \"latest\""
                ));
                Policy::Block
            }
        };
        let log = tracing_t.level.clone().unwrap_or_else(|| "warn".into());
        if let Err(e) = log.parse::<tracing_subscriber::EnvFilter>() {
            problems.push(format!("tracing.level = {log:?}: {e}"));
        }
        match (source, params) {
            (Some(source), Some(params)) if problems.is_empty() => Ok(DaemonConfig {
                source,
                output: output
                    .path
                    .filter(|p| p.as_os_str() != "-")
                    .map(|p| resolve(&p)),
                output_kafka,
                svg_dir: output.svg_dir.map(|p| resolve(&p)),
                queue,
                policy,
                warm_start: pipeline.warm_start.unwrap_or(true),
                log,
                chrome_trace: tracing_t.chrome_trace.map(|p| resolve(&p)),
                poll: Duration::from_millis(50),
                limits,
                max_streams,
                stream_idle,
                accumulate,
                bag,
                live,
                metrics,
                params,
            }),
            _ => Err(fail(problems)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_configuration_is_read_with_paths_from_its_folder() {
        let c = DaemonConfig::parse(
            "[input]\npath = \"frames.ndjson\"\nreplay = 20\n[output]\npath = \"out.ndjson\"\n\
             svg_dir = \"svg\"\n[pipeline]\nqueue = 2\npolicy = \"latest\"\nwarm_start = false\n\
             [tracing]\nlevel = \"info\"\nchrome_trace = \"trace.json\"\n[mesh]\nhmin = 0.002\n",
            "d.toml",
            Path::new("/cfg"),
        )
        .unwrap();
        assert_eq!(
            c.source,
            Source::File {
                path: "/cfg/frames.ndjson".into(),
                replay: Replay::Rate(20.0)
            }
        );
        assert_eq!(c.output.as_deref(), Some(Path::new("/cfg/out.ndjson")));
        assert_eq!(c.svg_dir.as_deref(), Some(Path::new("/cfg/svg")));
        assert_eq!(
            (c.queue, c.policy, c.warm_start),
            (2, Policy::Latest, false)
        );
        assert_eq!(
            c.chrome_trace.as_deref(),
            Some(Path::new("/cfg/trace.json"))
        );
        assert_eq!(c.params.mesh.hmin, Some(0.002));
    }

    #[test]
    fn defaults_are_stdin_to_stdout_blocking_and_warm() {
        let c = DaemonConfig::parse("", "d.toml", Path::new(".")).unwrap();
        assert_eq!(c.source, Source::Stdin);
        assert_eq!(c.output, None);
        assert_eq!((c.queue, c.policy, c.warm_start), (4, Policy::Block, true));
        let tcp =
            DaemonConfig::parse("[input]\nkind = \"tcp\"\n", "d.toml", Path::new(".")).unwrap();
        assert_eq!(
            tcp.source,
            Source::Tcp {
                bind: DEFAULT_BIND.parse().unwrap()
            }
        );
    }

    #[test]
    fn the_shipped_replay_configuration_loads() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/stream-replay.toml");
        let c = DaemonConfig::load(&path).unwrap();
        let Source::File { path, replay } = c.source else {
            panic!("{:?}", c.source)
        };
        assert!(path.exists(), "{}", path.display());
        assert_eq!(replay, Replay::Recorded);
    }

    #[test]
    fn every_problem_is_named_with_its_key() {
        let e = DaemonConfig::parse(
            "[input]\nkind = \"tcp\"\nbind = \"nowhere\"\nreplay = -1\n[pipeline]\nqueue = 0\n\
             policy = \"newest\"\nspeed = 2\n[solver]\ncfl = 3.0\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        for key in [
            "input.bind",
            "input.path and input.replay",
            "pipeline",
            "speed",
            "solver.cfl",
        ] {
            assert!(e.contains(key), "{key} missing from: {e}");
        }
        let e = DaemonConfig::parse(
            "[pipeline]\nqueue = 0\npolicy = \"newest\"\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("pipeline.queue = 0") && e.contains("pipeline.policy"),
            "{e}"
        );
    }

    #[test]
    fn kafka_input_and_output_pass_their_client_settings_through() {
        let c = DaemonConfig::parse(
            "[input]\nkind = \"kafka\"\nbrokers = \"k1:9092,k2:9092\"\ntopic = \"scans\"\n\
             [input.kafka]\n\"session.timeout.ms\" = 2000\n\"enable.partition.eof\" = false\n\
             [output]\nkind = \"kafka\"\nbrokers = \"k1:9092\"\ntopic = \"curves\"\n\
             [output.kafka]\n\"linger.ms\" = \"0\"\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap();
        let Source::Kafka(input) = &c.source else {
            panic!("{:?}", c.source)
        };
        assert_eq!(input.group, "isoline");
        assert_eq!(input.topic.brokers, "k1:9092,k2:9092");
        assert_eq!(input.topic.settings["session.timeout.ms"], "2000");
        assert_eq!(input.topic.settings["enable.partition.eof"], "false");
        let out = c.output_kafka.as_ref().unwrap();
        assert_eq!(
            (out.topic.as_str(), out.settings["linger.ms"].as_str()),
            ("curves", "0")
        );
        assert_eq!(c.output, None);

        let e = DaemonConfig::parse(
            "[input]\nkind = \"kafka\"\ngroup = \"g\"\n[input.kafka]\nx = [1]\n\
             [output]\nkind = \"kafka\"\npath = \"o.ndjson\"\ntopic = \"t\"\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        for needle in [
            "input.brokers: required",
            "input.topic: required",
            "input.kafka.x = [1]",
            "output.brokers: required",
            "output.path applies to kind = \"file\"",
        ] {
            assert!(e.contains(needle), "{needle} not in {e}");
        }
        let e = DaemonConfig::parse("[input]\ntopic = \"t\"\n", "d.toml", Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains("apply to kind = \"kafka\""), "{e}");
    }

    #[test]
    fn refinement_windows_are_read_and_bounded() {
        let parse = |t: &str| DaemonConfig::parse(t, "d.toml", Path::new("."));
        assert_eq!(parse("").unwrap().accumulate, None);
        assert_eq!(
            parse("[pipeline]\naccumulate = 1\n").unwrap().accumulate,
            None
        );
        assert_eq!(
            parse("[pipeline]\naccumulate = 10\naccumulate_seconds = 0.5\n")
                .unwrap()
                .accumulate,
            Some(WindowLimits {
                frames: 10,
                seconds: Some(0.5)
            })
        );
        let e = parse("[pipeline]\naccumulate = 101\naccumulate_seconds = 0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("pipeline.accumulate = 101") && e.contains("pipeline.accumulate_seconds"),
            "{e}"
        );
    }

    #[test]
    fn limits_are_read_and_bounded_and_remote_clients_are_a_choice() {
        let c = DaemonConfig::parse(
            "[input]\nkind = \"tcp\"\nbind = \"0.0.0.0:7000\"\nallow_remote = true\n\
             max_clients = 3\nmax_line_bytes = 4096\n[pipeline]\nmax_streams = 5\n\
             stream_idle = 2.5\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap();
        assert_eq!(
            c.limits,
            Limits {
                max_line_bytes: 4096,
                max_clients: 3
            }
        );
        assert_eq!(
            (c.max_streams, c.stream_idle),
            (5, Duration::from_millis(2500))
        );
        let d = DaemonConfig::parse("", "d.toml", Path::new(".")).unwrap();
        assert_eq!(d.limits, Limits::default());
        assert_eq!(
            (d.max_streams, d.stream_idle),
            (DEFAULT_MAX_STREAMS, DEFAULT_STREAM_IDLE)
        );
        let e = DaemonConfig::parse(
            "[input]\nkind = \"tcp\"\nbind = \"[::]:7000\"\nmax_clients = 0\n\
             max_line_bytes = 2000000000\n[pipeline]\nstream_idle = -1\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        for key in [
            "allow_remote",
            "input.max_clients = 0",
            "input.max_line_bytes",
            "pipeline.stream_idle",
        ] {
            assert!(e.contains(key), "{key} missing from: {e}");
        }
        for rate in ["1e-19", "1e300", "0"] {
            let e = DaemonConfig::parse(
                &format!("[input]\npath = \"f\"\nreplay = {rate}\n"),
                "d.toml",
                Path::new("."),
            );
            assert!(e.is_err(), "replay = {rate}");
        }
    }
}
