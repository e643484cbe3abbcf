//! The daemon's TOML file. Each table is read by the type of the part it configures:
//! `[input]` by its source's, chosen by `kind` ([`FileInput`], [`StdinInput`],
//! [`TcpInput`], and `KafkaInputConfig` with the `kafka` feature), `[output]` by its
//! sink's ([`FileOutput`], `KafkaOutputConfig`), `[pipeline]`, `[tracing]`, `[live]` and
//! `[metrics]` by theirs here, and `[mesh]`, `[solver]`, `[export]` and `[scan]` by the
//! tables every command shares ([`crate::config`]). Unknown keys are refused, every
//! table's problems are reported at once with their key paths, and relative paths are
//! taken from the configuration file's folder.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use serde::Deserialize;

#[cfg(feature = "kafka")]
use super::kafka::{KafkaInput, KafkaInputConfig, KafkaOutputConfig, KafkaTopic};
pub use super::sink::FileOutput;
use super::source::{line_limit, Limits};
pub use super::source::{FileInput, FileSource, Replay, StdinInput, TcpInput};
use crate::config::{bounded, listen_address, read_value, resolve, take_table, Config};
use crate::error::{Error, Result};
use isoline_core::Params;
use isoline_map::WindowLimits;

/// Where frames come from, validated.
#[derive(Clone, Debug, PartialEq)]
pub enum Source {
    /// A file (NDJSON frames, a bag or a CARMEN log), replayed.
    File(FileSource),
    /// NDJSON frames on standard input, as they come.
    Stdin,
    /// A TCP listener: one NDJSON frame per line, any number of clients.
    Tcp {
        /// The address to listen on.
        bind: SocketAddr,
    },
    /// A Kafka topic, one NDJSON frame a message, read as a member of a consumer group.
    #[cfg(feature = "kafka")]
    Kafka(KafkaInput),
}

/// What a full queue does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
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
    #[cfg(feature = "kafka")]
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
    /// with its stream's last frames' ([`isoline_map::Window`]).
    pub accumulate: Option<WindowLimits>,
    /// Serve a live view (Foxglove WebSocket) on this address.
    pub live: Option<SocketAddr>,
    /// Keep serving the live view after the input has ended, until SIGINT or SIGTERM.
    pub live_linger: bool,
    /// Serve Prometheus metrics and a health check on this address.
    pub metrics: Option<SocketAddr>,
    /// Registration (`[pipeline] register = true`, with `[register]`'s parameters):
    /// each stream's scans get their pose estimated against its local map, the input
    /// pose taken as odometry; records carry it as `registered_pose`, and refinement
    /// and the map place scans by it.
    pub register: Option<isoline_map::RegisterParams>,
    /// Seconds between beams for frames that do not say (`[scan] time_increment`):
    /// scanner frames are corrected for the sensor's motion during the sweep.
    pub time_increment: Option<f64>,
    /// Reconstruction parameters.
    pub params: Params,
    /// The map of the run (`[map]` with `output`): every scan with a pose fused into
    /// one world-frame map, written as it grows.
    pub map: Option<super::map::MapOutput>,
}

/// `[input]`: one source, by `kind`.
#[derive(Clone, Debug)]
pub enum InputConfig {
    /// `kind = "file"`.
    File(FileInput),
    /// `kind = "stdin"`.
    Stdin(StdinInput),
    /// `kind = "tcp"`.
    Tcp(TcpInput),
    /// `kind = "kafka"`.
    #[cfg(feature = "kafka")]
    Kafka(KafkaInputConfig),
}

/// `[output]`: one sink, by `kind`.
#[derive(Clone, Debug)]
pub enum OutputConfig {
    /// `kind = "file"` (the default).
    File(FileOutput),
    /// `kind = "kafka"`.
    #[cfg(feature = "kafka")]
    Kafka(KafkaOutputConfig),
}

/// The kinds of `[input]`, and of `[output]`, this build has.
const INPUT_KINDS: &[&str] = &["file", "stdin", "tcp", "kafka"];
const OUTPUT_KINDS: &[&str] = &["file", "kafka"];

/// The kind a tagged table names (`default` when it names none), and the rest of the
/// table for that kind's type; `None` (and a problem) for an unknown kind, or one this
/// build lacks.
fn kind_of(
    table: &str,
    mut t: toml::Table,
    default: &str,
    kinds: &[&str],
    problems: &mut Vec<String>,
) -> Option<(String, toml::Value)> {
    let kind = match t.remove("kind") {
        None => default.to_string(),
        Some(toml::Value::String(k)) if kinds.contains(&k.as_str()) => k,
        Some(other) => {
            let expected: Vec<String> = kinds.iter().map(|k| format!("{k:?}")).collect();
            problems.push(format!(
                "{table}.kind = {other}: expected {}",
                expected.join(", ")
            ));
            return None;
        }
    };
    if kind == "kafka" && !cfg!(feature = "kafka") {
        problems.push(format!(
            "{table}.kind = \"kafka\": this isoline was built without its kafka feature"
        ));
        return None;
    }
    Some((kind, toml::Value::Table(t)))
}

impl InputConfig {
    /// Reads `[input]`: its `kind` (by default `"file"` with a `path`, else `"stdin"`)
    /// chooses the type that reads the rest.
    fn read(t: toml::Table, problems: &mut Vec<String>) -> Option<InputConfig> {
        let default = if t.contains_key("path") {
            "file"
        } else {
            "stdin"
        };
        let (kind, rest) = kind_of("input", t, default, INPUT_KINDS, problems)?;
        let p = "input.";
        match kind.as_str() {
            "file" => read_value(rest, p, problems).map(InputConfig::File),
            "stdin" => read_value(rest, p, problems).map(InputConfig::Stdin),
            "tcp" => read_value(rest, p, problems).map(InputConfig::Tcp),
            #[cfg(feature = "kafka")]
            "kafka" => read_value(rest, p, problems).map(InputConfig::Kafka),
            _ => unreachable!("kind_of admits only these"),
        }
    }

    /// The source and its limits.
    fn validate(self, base: &Path, problems: &mut Vec<String>) -> (Option<Source>, Limits) {
        match self {
            InputConfig::File(f) => {
                let (source, limits) = f.validate(base, problems);
                (Some(Source::File(source)), limits)
            }
            InputConfig::Stdin(s) => (Some(Source::Stdin), line_limit(s.max_line_bytes, problems)),
            InputConfig::Tcp(t) => {
                let (bind, limits) = t.validate(problems);
                (bind.map(|bind| Source::Tcp { bind }), limits)
            }
            #[cfg(feature = "kafka")]
            InputConfig::Kafka(k) => {
                let (input, limits) = k.validate(problems);
                (input.map(Source::Kafka), limits)
            }
        }
    }
}

impl OutputConfig {
    /// Reads `[output]` by its `kind` (default `"file"`).
    fn read(t: toml::Table, problems: &mut Vec<String>) -> Option<OutputConfig> {
        let (kind, rest) = kind_of("output", t, "file", OUTPUT_KINDS, problems)?;
        match kind.as_str() {
            "file" => read_value(rest, "output.", problems).map(OutputConfig::File),
            #[cfg(feature = "kafka")]
            "kafka" => read_value(rest, "output.", problems).map(OutputConfig::Kafka),
            _ => unreachable!("kind_of admits only these"),
        }
    }
}

/// `[pipeline]`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipelineConfig {
    /// Capacity of each queue between stages, frames, in `1..=4096`. Default 4.
    pub queue: Option<i64>,
    /// What a full queue does. Default `"block"`.
    pub policy: Option<Policy>,
    /// Start each frame from the previous frame of its stream. Default true.
    pub warm_start: Option<bool>,
    /// Streams whose warm state is kept, in `1..=2^20`. Default 256.
    pub max_streams: Option<i64>,
    /// Seconds after which an unseen stream is forgotten, in `[0.001, 1e6]`. Default 60.
    pub stream_idle: Option<f64>,
    /// Frames in a refinement window, in `0..=100`; 0 or 1: off. Default off.
    pub accumulate: Option<i64>,
    /// Seconds a frame stays in the window at most, in `[0.001, 1e6]`.
    pub accumulate_seconds: Option<f64>,
    /// Estimate each stream's poses from its scans (docs/method.md, "Poses"), the input
    /// poses taken as odometry; `[register]` sets how. Default false.
    pub register: Option<bool>,
    /// Bytes all streams' refinement windows may hold together, in `2^20..=2^40`;
    /// each stream's window holds at most this divided by `max_streams`, its oldest
    /// frames leaving first. Default 4 GiB (16 MiB a stream with 256 streams).
    pub max_state_bytes: Option<i64>,
}

/// `[tracing]`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TracingConfig {
    /// Log filter when `RUST_LOG` is unset (`"warn"`, `"info"`, `"isoline=debug"`).
    /// Default `"warn"`.
    pub level: Option<String>,
    /// A Chrome/Perfetto trace of the stages' spans.
    pub chrome_trace: Option<PathBuf>,
}

/// `[live]` and `[metrics]`: a listener.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListenerConfig {
    /// The address. Default `127.0.0.1:8765` (live view), `127.0.0.1:9898` (metrics).
    pub bind: Option<String>,
    /// A bind address other than loopback must be asked for. Default false.
    pub allow_remote: Option<bool>,
    /// `[live]` only: keep serving after the input has ended (a recording replayed for
    /// a demo), each stream's last frame shown to viewers that connect later, until
    /// SIGINT or SIGTERM. Default false.
    pub linger: Option<bool>,
}

/// The live view's default address (Foxglove's usual port, on loopback).
pub const DEFAULT_LIVE_BIND: &str = "127.0.0.1:8765";

/// The metrics endpoint's default address.
pub const DEFAULT_METRICS_BIND: &str = "127.0.0.1:9898";

/// Default of `pipeline.max_streams`.
pub const DEFAULT_MAX_STREAMS: usize = 256;
/// Default of `pipeline.max_state_bytes`: 4 GiB for every stream's window together.
pub const DEFAULT_MAX_STATE_BYTES: usize = 4 << 30;

/// The most frames `pipeline.accumulate` may keep: each holds its curves, its returns
/// and an index (about 0.17 MB for a 1,080-beam scan); the windows' bytes
/// are bounded by `pipeline.max_state_bytes` whatever the frames.
pub const MAX_ACCUMULATE: usize = 100;
/// Default of `pipeline.stream_idle`.
pub const DEFAULT_STREAM_IDLE: Duration = Duration::from_secs(60);

/// A number of seconds `key` may hold: in `[0.001, 1e6]`.
fn seconds(key: &str, v: Option<f64>, problems: &mut Vec<String>) -> Option<Duration> {
    match v {
        Some(s) if (0.001..=1e6).contains(&s) => Some(Duration::from_secs_f64(s)),
        Some(s) => {
            problems.push(format!("{key} = {s}: must be in [0.001, 1e6] seconds"));
            None
        }
        None => None,
    }
}

/// `[pipeline]`, validated.
struct Pipeline {
    queue: usize,
    policy: Policy,
    warm_start: bool,
    max_streams: usize,
    stream_idle: Duration,
    accumulate: Option<WindowLimits>,
    register: bool,
}

impl PipelineConfig {
    fn validate(self, problems: &mut Vec<String>) -> Pipeline {
        let frames = bounded(
            "pipeline.accumulate",
            self.accumulate,
            0,
            0,
            MAX_ACCUMULATE,
            problems,
        );
        let window_seconds = seconds(
            "pipeline.accumulate_seconds",
            self.accumulate_seconds,
            problems,
        );
        let max_streams = bounded(
            "pipeline.max_streams",
            self.max_streams,
            DEFAULT_MAX_STREAMS,
            1,
            1 << 20,
            problems,
        );
        let state_bytes = bounded(
            "pipeline.max_state_bytes",
            self.max_state_bytes,
            DEFAULT_MAX_STATE_BYTES,
            1 << 20,
            1 << 40,
            problems,
        );
        Pipeline {
            queue: bounded("pipeline.queue", self.queue, 4, 1, 4096, problems),
            policy: self.policy.unwrap_or_default(),
            warm_start: self.warm_start.unwrap_or(true),
            max_streams,
            stream_idle: seconds("pipeline.stream_idle", self.stream_idle, problems)
                .unwrap_or(DEFAULT_STREAM_IDLE),
            accumulate: (frames > 1).then_some(WindowLimits {
                frames,
                seconds: self.accumulate_seconds.filter(|_| window_seconds.is_some()),
                max_bytes: Some(state_bytes / max_streams.max(1)),
            }),
            register: self.register.unwrap_or(false),
        }
    }
}

/// Takes table `key` out of `t` and reads it as a `T` (the default when absent).
fn take<T: serde::de::DeserializeOwned + Default>(
    t: &mut toml::Table,
    key: &str,
    problems: &mut Vec<String>,
) -> T {
    t.remove(key)
        .and_then(|v| read_value(v, &format!("{key}."), problems))
        .unwrap_or_default()
}

impl DaemonConfig {
    /// Reads and validates a daemon configuration file, paths included
    /// ([`DaemonConfig::check_paths`]).
    pub fn load(path: &Path) -> Result<DaemonConfig> {
        let text = std::fs::read_to_string(path).map_err(|e| isoline_io::Error::io(path, e))?;
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
        for p in self.map.iter().flat_map(|m| &m.paths) {
            written.push(("map.output", p));
        }
        if let Source::File(FileSource { path: input, .. }) = &self.source {
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
        // Every output is checked now: a path that cannot be written would otherwise end
        // the run at its first write, with the frames after it never read.
        for (key, p) in &written {
            if let Err(e) = isoline_io::write::PartFile::probe(p) {
                problems.push(format!(
                    "{key} = {:?} cannot be written: {e}",
                    p.display().to_string()
                ));
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
    // One function: one table after another, every problem collected before failing.
    pub fn parse(text: &str, name: &str, base: &Path) -> Result<DaemonConfig> {
        let fail = |problems: Vec<String>| Error::Config {
            path: name.to_string(),
            problems,
        };
        let mut t = crate::config::parse_table(text).map_err(|e| fail(vec![e]))?;
        let mut problems = Vec::new();
        let input = take_table(&mut t, "input", &mut problems);
        let input = InputConfig::read(input, &mut problems);
        let output = take_table(&mut t, "output", &mut problems);
        let output = OutputConfig::read(output, &mut problems);
        let pipeline: PipelineConfig = take(&mut t, "pipeline", &mut problems);
        let tracing_t: TracingConfig = take(&mut t, "tracing", &mut problems);
        let live: Option<ListenerConfig> = take(&mut t, "live", &mut problems);
        let metrics: Option<ListenerConfig> = take(&mut t, "metrics", &mut problems);
        // What is left is the shared tables, which refuse any other key.
        let mut map = None;
        let mut register = None;
        let mut time_increment = None;
        let params = match Config::from_table(t, name, "").map_err(Error::from) {
            Ok(c) => {
                register = Some(c.register);
                time_increment = c.scan.time_increment;
                map = c.map.output.as_ref().map(|o| super::map::MapOutput {
                    params: c.map_params(),
                    paths: o.paths().iter().map(|p| resolve(base, p)).collect(),
                    every: c.map.every.unwrap_or(super::map::DAEMON_MAP_EVERY),
                    every_seconds: c.map.every_seconds.map(Duration::from_secs_f64),
                    spill: c.map.spill.as_ref().map(|p| resolve(base, p)),
                });
                Some(c.params())
            }
            Err(Error::Config { problems: p, .. }) => {
                problems.extend(p);
                None
            }
            Err(e) => return Err(e),
        };
        let (source, limits) = match input {
            Some(i) => i.validate(base, &mut problems),
            None => (None, Limits::default()),
        };
        let (output_path, svg_dir, output_kafka) = match output {
            Some(OutputConfig::File(f)) => (f.path, f.svg_dir, None),
            #[cfg(feature = "kafka")]
            Some(OutputConfig::Kafka(k)) => {
                let svg_dir = k.svg_dir.clone();
                (None, svg_dir, k.validate(&mut problems))
            }
            None => (None, None, None),
        };
        #[cfg(not(feature = "kafka"))]
        let _: Option<()> = output_kafka;
        let live_linger = live.as_ref().and_then(|l| l.linger).unwrap_or(false);
        if metrics.as_ref().is_some_and(|m| m.linger.is_some()) {
            problems.push("metrics.linger: only the live view lingers ([live] linger)".into());
        }
        let live = live.and_then(|l| {
            listen_address(
                "live",
                l.bind.as_deref(),
                l.allow_remote,
                DEFAULT_LIVE_BIND,
                &mut problems,
            )
        });
        if live.is_some() && !cfg!(feature = "live") {
            problems.push("[live]: this isoline was built without its live feature".into());
        }
        let metrics = metrics.and_then(|m| {
            listen_address(
                "metrics",
                m.bind.as_deref(),
                m.allow_remote,
                DEFAULT_METRICS_BIND,
                &mut problems,
            )
        });
        let pipeline = pipeline.validate(&mut problems);
        let log = tracing_t.level.unwrap_or_else(|| "warn".into());
        if let Err(e) = log.parse::<tracing_subscriber::EnvFilter>() {
            problems.push(format!("tracing.level = {log:?}: {e}"));
        }
        match (source, params) {
            (Some(source), Some(params)) if problems.is_empty() => Ok(DaemonConfig {
                source,
                output: output_path
                    .filter(|p| p.as_os_str() != "-")
                    .map(|p| resolve(base, &p)),
                #[cfg(feature = "kafka")]
                output_kafka,
                svg_dir: svg_dir.map(|p| resolve(base, &p)),
                queue: pipeline.queue,
                policy: pipeline.policy,
                warm_start: pipeline.warm_start,
                log,
                chrome_trace: tracing_t.chrome_trace.map(|p| resolve(base, &p)),
                poll: Duration::from_millis(50),
                limits,
                max_streams: pipeline.max_streams,
                stream_idle: pipeline.stream_idle,
                accumulate: pipeline.accumulate,
                register: register.filter(|_| pipeline.register),
                live,
                live_linger,
                metrics,
                time_increment,
                params,
                map,
            }),
            _ => Err(fail(problems)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::map::DAEMON_MAP_EVERY;
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
            Source::File(FileSource {
                path: "/cfg/frames.ndjson".into(),
                replay: Replay::Rate(20.0),
                bag: Default::default(),
            })
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
                bind: super::super::source::DEFAULT_BIND.parse().unwrap()
            }
        );
    }

    #[test]
    fn the_shipped_replay_configuration_loads() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/stream-replay.toml");
        let c = DaemonConfig::load(&path).unwrap();
        let Source::File(FileSource { path, replay, .. }) = c.source else {
            panic!("{:?}", c.source)
        };
        assert!(path.exists(), "{}", path.display());
        assert_eq!(replay, Replay::Recorded);
    }

    #[test]
    fn the_map_is_on_with_its_files_and_their_pace() {
        let c = DaemonConfig::parse("", "d.toml", Path::new("/cfg")).unwrap();
        assert_eq!(c.map, None);
        let c = DaemonConfig::parse(
            "[map]\noutput = \"map.geojson\"\ncell = 0.05\n",
            "d.toml",
            Path::new("/cfg"),
        )
        .unwrap();
        let m = c.map.unwrap();
        assert_eq!(m.paths, vec![PathBuf::from("/cfg/map.geojson")]);
        assert_eq!((m.params.cell, m.every), (0.05, DAEMON_MAP_EVERY));
        let c = DaemonConfig::parse(
            "[map]\noutput = [\"a.svg\", \"/abs/b.mcap\"]\nevery = 0\nevery_seconds = 5.0\n",
            "d.toml",
            Path::new("/cfg"),
        )
        .unwrap();
        let m = c.map.unwrap();
        assert_eq!(
            m.paths,
            vec![PathBuf::from("/cfg/a.svg"), PathBuf::from("/abs/b.mcap")]
        );
        assert_eq!(
            (m.every, m.every_seconds),
            (0, Some(Duration::from_secs(5)))
        );
        let e = DaemonConfig::parse(
            "[map]\noutput = [\"a.png\"]\nevery_seconds = 0.0\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("map.output = \"a.png\"") && e.contains("map.every_seconds = 0"),
            "{e}"
        );
        // The map cannot be written over the records.
        let dir = tempfile::tempdir().unwrap();
        let c = DaemonConfig::parse(
            "[output]\npath = \"same.ndjson\"\n[map]\noutput = \"same.ndjson\"\n",
            "d.toml",
            dir.path(),
        )
        .unwrap();
        let e = c.check_paths().unwrap_err().to_string();
        assert!(
            e.contains("output.path and map.output name the same file"),
            "{e}"
        );
    }

    /// Every table's problems are reported at once, each with its key path; a table
    /// its type cannot read (an unknown key, a value of the wrong type) is named with
    /// the key.
    #[test]
    fn every_problem_is_named_with_its_key() {
        let parse = |t: &str| {
            DaemonConfig::parse(t, "d.toml", Path::new("."))
                .unwrap_err()
                .to_string()
        };
        let e = parse(
            "[input]\nkind = \"tcp\"\nbind = \"nowhere\"\n[pipeline]\nqueue = 0\n\
             speed = 2\n[solver]\ncfl = 3.0\n[output]\nkind = \"s3\"\n",
        );
        for key in [
            "input.bind = \"nowhere\"",
            "pipeline: unknown field `speed`",
            "solver.cfl",
            "output.kind = \"s3\"",
        ] {
            assert!(e.contains(key), "{key} missing from: {e}");
        }
        let e = parse("[input]\nkind = \"tcp\"\nreplay = -1\n");
        assert!(e.contains("input: unknown field `replay`"), "{e}");
        let e = parse("[input]\npath = \"f\"\nreplay = -1\n");
        assert!(e.contains("input.replay: invalid value"), "{e}");
        let e = parse("[pipeline]\nqueue = 0\nmax_streams = 0\n");
        assert!(
            e.contains("pipeline.queue = 0") && e.contains("pipeline.max_streams = 0"),
            "{e}"
        );
        let e = parse("[pipeline]\npolicy = \"newest\"\n");
        assert!(
            e.contains("pipeline.policy: unknown variant `newest`"),
            "{e}"
        );
        let e = parse("[metrics]\nbind = \"0.0.0.0:1\"\n[tracing]\nlevel = \"[\"\n");
        assert!(
            e.contains("metrics.bind") && e.contains("tracing.level"),
            "{e}"
        );
    }

    #[cfg(feature = "kafka")]
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
            "input: missing field `brokers`",
            "output: unknown field `path`",
        ] {
            assert!(e.contains(needle), "{needle} not in {e}");
        }
        let e = DaemonConfig::parse(
            "[input]\nkind = \"kafka\"\nbrokers = \" \"\ntopic = \"t\"\n[input.kafka]\nx = [1]\n",
            "d.toml",
            Path::new("."),
        )
        .unwrap_err()
        .to_string();
        for needle in ["input.brokers: must not be empty", "input.kafka.x = [1]"] {
            assert!(e.contains(needle), "{needle} not in {e}");
        }
        let e = DaemonConfig::parse("[input]\ntopic = \"t\"\n", "d.toml", Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains("input: unknown field `topic`"), "{e}");
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
                seconds: Some(0.5),
                max_bytes: Some(DEFAULT_MAX_STATE_BYTES / DEFAULT_MAX_STREAMS),
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
