//! Kafka: frames from a topic through a consumer group (a source), result records to a
//! topic (a sink), and the writer `isoline publish` feeds a topic with.
//!
//! Frames are keyed by stream id, so a stream lives on one partition and a partition on
//! one member of the group: that member keeps the stream's warm state. Delivery is at
//! least once: a frame's offset is committed only once its record is written (for a
//! Kafka sink, once the broker has acknowledged it), so a crash makes the next owner read
//! again what was not committed; the repeated records carry the same stream and frame.
//!
//! Rebalancing is cooperative-sticky by default. Every partition a member is given gets
//! a new *lease*; the stages keep each stream's state under the lease it was built in, so
//! the streams of a partition that leaves drop their state, and those of one that
//! arrives start cold, while every other stream stays warm.

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::Sender;
use rdkafka::config::{ClientConfig, RDKafkaLogLevel};
use rdkafka::consumer::{BaseConsumer, CommitMode, Consumer, ConsumerContext, Rebalance};
use rdkafka::error::{KafkaError, RDKafkaErrorCode};
use rdkafka::message::DeliveryResult;
use rdkafka::producer::{BaseRecord, Producer, ProducerContext, ThreadedProducer};
use rdkafka::statistics::Statistics;
use rdkafka::{ClientContext, Message, Offset, TopicPartitionList};
use serde::Deserialize;

use super::ledger::{lock, Leases, Ledger, Receipt};
use super::listen::Throttle;
use super::metrics::{Counted, Metrics};
use super::source::{Limits, Line};
use crate::error::{Error, Result};

/// A topic on a Kafka cluster (or a compatible broker such as Redpanda), with
/// librdkafka settings passed through as given.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KafkaTopic {
    /// `bootstrap.servers`: `host:port[,host:port...]`.
    pub brokers: String,
    /// The topic.
    pub topic: String,
    /// librdkafka properties (`"session.timeout.ms" = "2000"`); they override isoline's
    /// defaults.
    pub settings: BTreeMap<String, String>,
    /// How long a broker outage or a member without partitions may last before the
    /// daemon reports it unhealthy.
    pub stall: Duration,
}

/// Frames from a topic, read as a member of a consumer group.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KafkaInput {
    /// Where the frames are.
    pub topic: KafkaTopic,
    /// The consumer group (`group.id`): the daemons sharing a topic's streams.
    pub group: String,
}

/// `[input] kind = "kafka"`: frames from a topic, one NDJSON frame a message, read as a
/// member of a consumer group.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KafkaInputConfig {
    /// `host:port[,host:port]`.
    pub brokers: String,
    /// The topic.
    pub topic: String,
    /// The consumer group. Default `"isoline"`.
    pub group: Option<String>,
    /// librdkafka properties, passed through (strings, numbers or booleans).
    #[serde(default)]
    pub kafka: BTreeMap<String, toml::Value>,
    /// The longest message, bytes, in `1024..=2^30`. Default 16 MiB.
    pub max_line_bytes: Option<i64>,
    /// Seconds without a reachable broker, or without partitions while the group has
    /// fewer members than the topic has partitions, before `/health` fails (and the
    /// member rejoins its group). Default 10, in `1..=3600`.
    pub stall_timeout: Option<f64>,
}

/// `[output] kind = "kafka"`: each record a message keyed by its stream.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KafkaOutputConfig {
    /// `host:port[,host:port]`.
    pub brokers: String,
    /// The topic.
    pub topic: String,
    /// librdkafka properties, passed through (strings, numbers or booleans).
    #[serde(default)]
    pub kafka: BTreeMap<String, toml::Value>,
    /// A folder for one SVG drawing per frame.
    pub svg_dir: Option<PathBuf>,
    /// Seconds without a reachable broker before `/health` fails; also how long a
    /// record may wait for its acknowledgement (`message.timeout.ms`) before the run
    /// fails. Default 10, in `1..=3600`.
    pub stall_timeout: Option<f64>,
}

/// The topic of table `table`: `brokers` and `topic` must not be blank, and the
/// passed-through properties become text (a TOML number or boolean as librdkafka
/// spells it).
fn topic_of(
    table: &str,
    brokers: String,
    topic: String,
    settings: BTreeMap<String, toml::Value>,
    stall_timeout: Option<f64>,
    problems: &mut Vec<String>,
) -> Option<KafkaTopic> {
    let stall = stall_timeout.unwrap_or(DEFAULT_STALL_SECONDS);
    if !(1.0..=3600.0).contains(&stall) {
        problems.push(format!(
            "{table}.stall_timeout = {stall}: must be from 1 to 3600 seconds"
        ));
    }
    let stall = Duration::from_secs_f64(if stall.is_finite() {
        stall.clamp(1.0, 3600.0)
    } else {
        DEFAULT_STALL_SECONDS
    });
    let mut blank = false;
    for (key, v) in [("brokers", &brokers), ("topic", &topic)] {
        if v.trim().is_empty() {
            problems.push(format!("{table}.{key}: must not be empty"));
            blank = true;
        }
    }
    let mut kafka = BTreeMap::new();
    for (k, v) in settings {
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
    if let Some(why) = without_tls(&kafka) {
        problems.push(format!("{table}.kafka: {why}"));
    }
    (!blank).then_some(KafkaTopic {
        brokers,
        topic,
        settings: kafka,
        stall,
    })
}

/// Why `settings` cannot work in this build: a TLS `security.protocol` when isoline was
/// built without the `kafka-tls` feature (librdkafka then has no OpenSSL, and would say
/// only that the value is unsupported).
pub fn without_tls(settings: &BTreeMap<String, String>) -> Option<String> {
    let protocol = settings.get("security.protocol")?.to_ascii_lowercase();
    (!cfg!(feature = "kafka-tls") && matches!(protocol.as_str(), "ssl" | "sasl_ssl")).then(|| {
        format!(
            "security.protocol = {protocol:?} needs TLS, and this isoline was built without              it: build with `--features kafka-tls` (docs/kafka.md, \"TLS and SASL\")"
        )
    })
}

impl KafkaInputConfig {
    /// The validated input and its limits.
    pub(crate) fn validate(self, problems: &mut Vec<String>) -> (Option<KafkaInput>, Limits) {
        let limits = super::source::line_limit(self.max_line_bytes, problems);
        let topic = topic_of(
            "input",
            self.brokers,
            self.topic,
            self.kafka,
            self.stall_timeout,
            problems,
        );
        let group = self.group.unwrap_or_else(|| "isoline".into());
        (topic.map(|topic| KafkaInput { topic, group }), limits)
    }
}

impl KafkaOutputConfig {
    /// The validated topic.
    pub(crate) fn validate(self, problems: &mut Vec<String>) -> Option<KafkaTopic> {
        topic_of(
            "output",
            self.brokers,
            self.topic,
            self.kafka,
            self.stall_timeout,
            problems,
        )
    }
}

/// Default of `stall_timeout`, seconds.
pub const DEFAULT_STALL_SECONDS: f64 = 10.0;

/// librdkafka's warnings and errors (a broker that is down is reported several times a
/// second): at most one line every ten seconds, with the count left out.
static CLIENT_WARNINGS: Throttle = Throttle::every(Duration::from_secs(10));

/// Whether a client reaches a broker, as its statistics say each second; a `/health`
/// condition once none has been reachable for the stall time.
struct BrokerWatch {
    source: &'static str,
    stall: Duration,
    down_since: Mutex<Option<Instant>>,
    metrics: Arc<Metrics>,
}

impl BrokerWatch {
    fn new(source: &'static str, stall: Duration, metrics: Arc<Metrics>) -> BrokerWatch {
        BrokerWatch {
            source,
            stall,
            down_since: Mutex::new(None),
            metrics,
        }
    }

    fn seen(&self, statistics: &Statistics) {
        let up = statistics.brokers.values().any(|b| b.state == "UP");
        let mut since = lock(&self.down_since);
        if up {
            *since = None;
            self.metrics.condition(self.source, None);
            return;
        }
        let t = *since.get_or_insert_with(Instant::now);
        if t.elapsed() >= self.stall {
            self.metrics.condition(
                self.source,
                Some(format!(
                    "{}: no Kafka broker reachable for more than {} s",
                    self.source,
                    self.stall.as_secs()
                )),
            );
        }
    }
}

/// How often the offsets of written records are committed.
const COMMIT_EVERY: Duration = Duration::from_millis(200);

/// How long a metadata request (partitions, group members, offsets) may take.
const METADATA_TIMEOUT: Duration = Duration::from_secs(2);

/// How long the last records may take to be acknowledged when a run ends.
const FLUSH_TIMEOUT: Duration = Duration::from_secs(30);

fn kafka_error(what: &str, e: impl std::fmt::Display) -> Error {
    Error::Kafka(format!("{what}: {e}"))
}

/// librdkafka's log, as tracing events; warnings and errors throttled.
fn log(level: RDKafkaLogLevel, fac: &str, message: &str) {
    match level {
        RDKafkaLogLevel::Emerg
        | RDKafkaLogLevel::Alert
        | RDKafkaLogLevel::Critical
        | RDKafkaLogLevel::Error => CLIENT_WARNINGS
            .warn(|skipped| tracing::error!(target: "librdkafka", fac, skipped, "{message}")),
        RDKafkaLogLevel::Warning => CLIENT_WARNINGS
            .warn(|skipped| tracing::warn!(target: "librdkafka", fac, skipped, "{message}")),
        RDKafkaLogLevel::Notice | RDKafkaLogLevel::Info => {
            tracing::info!(target: "librdkafka", fac, "{message}")
        }
        RDKafkaLogLevel::Debug => tracing::debug!(target: "librdkafka", fac, "{message}"),
    }
}

/// The consumer's callbacks: leases and commits at rebalances, lag from statistics.
struct GroupContext {
    topic: String,
    leases: Arc<Leases>,
    ledger: Arc<Ledger>,
    metrics: Arc<Metrics>,
    brokers: BrokerWatch,
    /// Why written frames' offsets were not committed when their partitions went (the
    /// broker unreachable, the assignment lost): the group will read them again.
    uncommitted: Arc<Mutex<Option<String>>>,
}

impl ClientContext for GroupContext {
    fn log(&self, level: RDKafkaLogLevel, fac: &str, message: &str) {
        log(level, fac, message);
    }

    fn error(&self, error: KafkaError, reason: &str) {
        CLIENT_WARNINGS.warn(|skipped| tracing::warn!(%error, skipped, "kafka consumer: {reason}"));
    }

    fn stats(&self, statistics: Statistics) {
        self.brokers.seen(&statistics);
        let Some(topic) = statistics.topics.get(&self.topic) else {
            return;
        };
        for (p, part) in &topic.partitions {
            if self.leases.of(*p).is_none() || part.hi_offset < 0 {
                continue;
            }
            // Before the group's first commit everything from the log's start is unread.
            let from = if part.committed_offset >= 0 {
                part.committed_offset
            } else {
                part.lo_offset.max(0)
            };
            self.metrics
                .consumer_lag
                .with_label_values(&[&p.to_string()])
                .set((part.hi_offset - from).max(0));
        }
    }
}

impl GroupContext {
    fn partitions(&self, tpl: &TopicPartitionList) -> Vec<i32> {
        tpl.elements()
            .iter()
            .filter(|e| e.topic() == self.topic)
            .map(|e| e.partition())
            .collect()
    }
}

impl ConsumerContext for GroupContext {
    fn pre_rebalance(&self, consumer: &BaseConsumer<Self>, rebalance: &Rebalance<'_>) {
        let Rebalance::Revoke(tpl) = rebalance else {
            return;
        };
        let parts = self.partitions(tpl);
        let mut written = Vec::new();
        for &p in &parts {
            if let Some(o) = self.ledger.close(p) {
                written.push((p, o));
            }
            self.leases.revoke(p);
            let _ = self
                .metrics
                .consumer_lag
                .remove_label_values(&[&p.to_string()]);
        }
        // Written records count before the partitions go: their positions are committed
        // synchronously (the broker's answer is the acknowledgement). A lost assignment
        // (this member was taken for dead) has no right to commit any more, and a
        // synchronous commit to an unreachable broker would wait without end: then the
        // positions count as committed only if the broker, asked, already holds them.
        if !written.is_empty() {
            let cannot = if consumer.assignment_lost() {
                Some("the assignment was lost")
            } else if lock(&self.brokers.down_since).is_some() {
                Some("no broker reachable")
            } else {
                None
            };
            let failed = match cannot {
                None => consumer
                    .commit(&positions(&self.topic, &written), CommitMode::Sync)
                    .err()
                    .map(|e| e.to_string()),
                Some(why) => {
                    let behind = behind(consumer, &self.topic, &written, REVOKE_READ_BACK);
                    (!behind.is_empty()).then(|| format!("{why}; not committed: {behind:?}"))
                }
            };
            if let Some(why) = failed {
                tracing::warn!(
                    partitions = ?parts,
                    "written frames not committed at revocation ({why}): they will be read again"
                );
                lock(&self.uncommitted).get_or_insert(format!(
                    "partitions {parts:?} went with written frames uncommitted: {why}"
                ));
            }
        }
        tracing::info!(
            partitions = ?parts,
            "partitions revoked: their streams' state is dropped"
        );
    }

    fn post_rebalance(&self, consumer: &BaseConsumer<Self>, rebalance: &Rebalance<'_>) {
        match rebalance {
            Rebalance::Assign(tpl) => {
                let parts = self.partitions(tpl);
                for &p in &parts {
                    let lease = self.leases.grant(p);
                    self.ledger.open(p, lease);
                }
                // Every held partition has its lag series from now on, not from its
                // first statistics: fleet lag does not undercount after a rebalance.
                let committed = consumer
                    .committed_offsets((*tpl).clone(), METADATA_TIMEOUT)
                    .ok();
                for &p in &parts {
                    let from = committed
                        .as_ref()
                        .and_then(|c| c.find_partition(&self.topic, p))
                        .and_then(|e| e.offset().to_raw());
                    let lag = consumer
                        .fetch_watermarks(&self.topic, p, METADATA_TIMEOUT)
                        .map(|(lo, hi)| hi - from.filter(|o| *o >= 0).unwrap_or(lo))
                        .unwrap_or(0);
                    self.metrics
                        .consumer_lag
                        .with_label_values(&[&p.to_string()])
                        .set(lag.max(0));
                }
                tracing::info!(partitions = ?parts, "partitions assigned: their streams start cold");
            }
            Rebalance::Error(e) => tracing::warn!(error = %e, "rebalance failed"),
            Rebalance::Revoke(_) => {}
        }
    }
}

/// Commits the positions that moved; the error, if the commit failed.
fn commit(
    consumer: &BaseConsumer<GroupContext>,
    ledger: &Ledger,
    topic: &str,
    mode: CommitMode,
) -> std::result::Result<(), KafkaError> {
    let due = ledger.due();
    if due.is_empty() {
        return Ok(());
    }
    match consumer.commit(&positions(topic, &due), mode) {
        Ok(()) => {
            // An asynchronous commit is only queued; the final commit checks that the
            // broker holds the positions.
            ledger.committed(&due);
            Ok(())
        }
        Err(e) => {
            CLIENT_WARNINGS.warn(|skipped| {
                tracing::warn!(error = %e, skipped, "offset commit failed; retried with the next")
            });
            Err(e)
        }
    }
}

/// How long a revocation that cannot commit may wait to read the committed offsets
/// back: it runs in the consumer's poll, which it holds up meanwhile.
const REVOKE_READ_BACK: Duration = Duration::from_secs(1);

/// `(partition, offset)` pairs of `topic` as librdkafka takes them.
fn positions(topic: &str, at: &[(i32, i64)]) -> TopicPartitionList {
    let mut tpl = TopicPartitionList::new();
    for &(p, o) in at {
        let _ = tpl.add_partition_offset(topic, p, Offset::Offset(o));
    }
    tpl
}

/// The `(partition, offset)` pairs of `want` whose committed offset the broker does not
/// confirm within `timeout`.
fn behind(
    consumer: &BaseConsumer<GroupContext>,
    topic: &str,
    want: &[(i32, i64)],
    timeout: Duration,
) -> Vec<(i32, i64)> {
    let held = consumer
        .committed_offsets(positions(topic, want), timeout)
        .ok();
    want.iter()
        .copied()
        .filter(|&(p, o)| {
            let at = held
                .as_ref()
                .and_then(|h| h.find_partition(topic, p))
                .and_then(|e| e.offset().to_raw());
            at.is_none_or(|at| at < o)
        })
        .collect()
}

/// How long the final offset commit may wait for the broker's answer.
const FINAL_COMMIT_TIMEOUT: Duration = Duration::from_secs(10);

/// The member's last commit, bounded in time: the positions that moved are sent
/// asynchronously, then the group's committed offsets are read back from the broker
/// until they reach every position committed so far, for at most
/// [`FINAL_COMMIT_TIMEOUT`]; an error if they do not. Reading back is the only
/// acknowledgement there is: librdkafka answers a manual asynchronous commit only through
/// an `offset_commit_cb`, which rust-rdkafka's event-based consumer does not set, and a
/// synchronous commit to an unreachable broker waits without end. So with the broker
/// gone, the positions of the frames written since its last answer are reported
/// uncommitted, never assumed.
fn final_commit(
    consumer: &BaseConsumer<GroupContext>,
    ledger: &Ledger,
    topic: &str,
) -> std::result::Result<(), String> {
    if !ledger.due().is_empty() {
        commit(consumer, ledger, topic, CommitMode::Async).map_err(|e| e.to_string())?;
    }
    let want = ledger.queued();
    if want.is_empty() {
        return Ok(());
    }
    let deadline = Instant::now() + FINAL_COMMIT_TIMEOUT;
    let mut why = "the broker did not answer".to_string();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return Err(format!(
                "the broker did not confirm the offsets within {} s ({why})",
                FINAL_COMMIT_TIMEOUT.as_secs()
            ));
        }
        let late = behind(consumer, topic, &want, left.min(Duration::from_secs(2)));
        if late.is_empty() {
            return Ok(());
        }
        why = format!("not confirmed: {late:?}");
        // Polled so that the queued commit goes out; nothing is read any more.
        let _ = consumer.poll(Duration::from_millis(50));
    }
}

/// Watches that the member holds partitions: one that holds none for the stall time
/// while its topic has more partitions than its group has members (a topic recreated
/// under it, a lost assignment) is unhealthy and rejoins the group.
struct PartitionWatch {
    since: Option<Instant>,
    checked: Instant,
}

impl PartitionWatch {
    fn new() -> PartitionWatch {
        PartitionWatch {
            since: None,
            checked: Instant::now(),
        }
    }

    fn check(
        &mut self,
        consumer: &BaseConsumer<GroupContext>,
        input: &KafkaInput,
        leases: &Leases,
        metrics: &Metrics,
    ) {
        const SOURCE: &str = "kafka input partitions";
        if self.checked.elapsed() < Duration::from_secs(1) {
            return;
        }
        self.checked = Instant::now();
        if leases.count() > 0 {
            self.since = None;
            metrics.condition(SOURCE, None);
            return;
        }
        let since = *self.since.get_or_insert_with(Instant::now);
        let stall = input.topic.stall;
        if since.elapsed() < stall {
            return;
        }
        let topic = &input.topic.topic;
        let partitions = consumer
            .fetch_metadata(Some(topic), METADATA_TIMEOUT)
            .ok()
            .and_then(|m| {
                m.topics()
                    .iter()
                    .find(|t| t.name() == topic)
                    .map(|t| t.partitions().len())
            })
            .unwrap_or(0);
        let members = consumer
            .fetch_group_list(Some(&input.group), METADATA_TIMEOUT)
            .ok()
            .and_then(|g| g.groups().first().map(|g| g.members().len()))
            .unwrap_or(0);
        if partitions > 0 && members >= partitions {
            // A group with more members than partitions: idle members are expected.
            metrics.condition(SOURCE, None);
            return;
        }
        let why = if partitions == 0 {
            format!("the topic {topic} has no partitions (or cannot be read)")
        } else {
            format!("{partitions} partitions in {topic}, none held by this member")
        };
        metrics.condition(
            SOURCE,
            Some(format!(
                "kafka input: no partitions for more than {} s: {why}",
                stall.as_secs()
            )),
        );
        if partitions > 0 {
            tracing::warn!(topic, partitions, "no partitions held: rejoining the group");
            consumer.unsubscribe();
            if let Err(e) = consumer.subscribe(&[topic]) {
                tracing::warn!(error = %e, "subscribing again failed");
            }
        }
        self.since = Some(Instant::now());
    }
}

/// A client configuration: isoline's defaults, then the user's settings over them.
fn client_config(topic: &KafkaTopic, defaults: &[(&str, String)]) -> ClientConfig {
    let mut c = ClientConfig::new();
    c.set("bootstrap.servers", &topic.brokers);
    for (k, v) in defaults {
        c.set(*k, v);
    }
    for (k, v) in &topic.settings {
        c.set(k, v);
    }
    c
}

/// The consumer group member: a source thread that reads frames from `input`'s topic
/// into `tx` until `stop`, then commits the offsets of the frames in flight as their
/// records are written, until `drained` says the pipeline has ended.
///
/// Memory stays bounded however far behind the member is: librdkafka prefetches at
/// most `queued.max.messages.kbytes` (default here 4 MiB), and the thread waits for room
/// in `tx` before reading on. A message longer than `limits.max_line_bytes` becomes an
/// error record.
// One function: the consumer thread's loop (poll, hand over, commit), its state local.
pub(crate) fn spawn_kafka(
    input: &KafkaInput,
    limits: Limits,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
    drained: Arc<AtomicBool>,
    metrics: Arc<Metrics>,
    poll: Duration,
) -> Result<(JoinHandle<Result<()>>, Arc<Leases>)> {
    let leases = Arc::new(Leases::default());
    let ledger = Arc::new(Ledger::default());
    let topic = input.topic.topic.clone();
    let uncommitted = Arc::new(Mutex::new(None));
    let context = GroupContext {
        topic: topic.clone(),
        leases: leases.clone(),
        ledger: ledger.clone(),
        metrics: metrics.clone(),
        brokers: BrokerWatch::new("kafka input", input.topic.stall, metrics.clone()),
        uncommitted: uncommitted.clone(),
    };
    let consumer: BaseConsumer<GroupContext> = client_config(
        &input.topic,
        &[
            ("group.id", input.group.clone()),
            ("enable.auto.commit", "false".into()),
            ("enable.auto.offset.store", "false".into()),
            ("auto.offset.reset", "earliest".into()),
            ("partition.assignment.strategy", "cooperative-sticky".into()),
            ("queued.max.messages.kbytes", "4096".into()),
            ("queued.min.messages", "64".into()),
            ("statistics.interval.ms", "1000".into()),
        ],
    )
    .create_with_context(context)
    .map_err(|e| kafka_error("creating the consumer", e))?;
    consumer
        .subscribe(&[&topic])
        .map_err(|e| kafka_error(&format!("subscribing to {topic}"), e))?;
    let owned_leases = leases.clone();
    let input = input.clone();
    let handle = std::thread::Builder::new()
        .name("source-kafka".into())
        .spawn(move || {
            let mut watch = PartitionWatch::new();
            consume(
                &consumer,
                &ledger,
                &owned_leases,
                &input,
                limits,
                &tx,
                &stop,
                poll,
                &mut |c| watch.check(c, &input, &owned_leases, &metrics),
            );
            drop(tx);
            // The frames read get their records; their offsets are committed as they
            // are written, and the member stays in the group until then.
            if let Ok(a) = consumer.assignment() {
                let _ = consumer.pause(&a);
            }
            let mut last = Instant::now();
            while !drained.load(Ordering::Relaxed) {
                // Polled for the group's callbacks; what it returns was not read.
                let _ = consumer.poll(poll);
                if last.elapsed() >= COMMIT_EVERY {
                    let _ = commit(&consumer, &ledger, &topic, CommitMode::Async);
                    last = Instant::now();
                }
            }
            let last = final_commit(&consumer, &ledger, &topic);
            // Whatever the final commit did, a revocation as the consumer closes has
            // nothing left to commit (a synchronous commit there would wait for an
            // unreachable broker without end).
            ledger.close_all();
            let left = ledger.in_flight();
            if left > 0 {
                tracing::warn!(
                    frames = left,
                    "frames without a written record: they will be read again"
                );
            }
            // The next member starts from the last committed offsets: without these
            // commits it repeats frames whose records are written, and must be told.
            let why = last
                .err()
                .map(|e| format!("the final offset commit failed: {e}"))
                .or_else(|| lock(&uncommitted).take());
            close(consumer);
            match why {
                Some(why) => Err(kafka_error(
                    "offsets of written frames were not committed (the group will read \
                     those frames again)",
                    why,
                )),
                None => Ok(()),
            }
        })
        .map_err(|e| Error::Internal(format!("cannot start thread source-kafka: {e}")))?;
    Ok((handle, leases))
}

/// How long leaving the group may take when the member stops.
const CLOSE_TIMEOUT: Duration = Duration::from_secs(5);

/// Closes the consumer (leaving its group), for at most [`CLOSE_TIMEOUT`]: rust-rdkafka
/// closes by polling until librdkafka says the consumer is closed, which never happens
/// while no broker is reachable. Past the bound the close is left to finish (or not)
/// on its own thread, which ends with the process; the group notices the member gone
/// by its session timeout.
fn close(consumer: BaseConsumer<GroupContext>) {
    let (done, closed) = std::sync::mpsc::channel::<()>();
    let spawned = std::thread::Builder::new()
        .name("kafka-close".into())
        .spawn(move || {
            drop(consumer);
            let _ = done.send(());
        });
    // If the thread could not start, the consumer was dropped with the closure, here.
    if spawned.is_ok() && closed.recv_timeout(CLOSE_TIMEOUT).is_err() {
        tracing::warn!(
            seconds = CLOSE_TIMEOUT.as_secs(),
            "the consumer did not leave its group in time (no broker reachable): the \
             group will take its partitions back after its session timeout"
        );
    }
}

/// Reads messages into `tx` until `stop` or a closed pipeline, committing as it goes
/// and calling `watch` between polls.
#[allow(clippy::too_many_arguments)]
fn consume(
    consumer: &BaseConsumer<GroupContext>,
    ledger: &Arc<Ledger>,
    leases: &Leases,
    input: &KafkaInput,
    limits: Limits,
    tx: &Sender<Line>,
    stop: &AtomicBool,
    poll: Duration,
    watch: &mut dyn FnMut(&BaseConsumer<GroupContext>),
) {
    let topic = input.topic.topic.as_str();
    let mut origins: HashMap<i32, Arc<str>> = HashMap::new();
    let mut last = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        if last.elapsed() >= COMMIT_EVERY {
            let _ = commit(consumer, ledger, topic, CommitMode::Async);
            last = Instant::now();
        }
        watch(consumer);
        let msg = match consumer.poll(poll) {
            None => continue,
            Some(Err(e)) => {
                CLIENT_WARNINGS
                    .warn(|skipped| tracing::warn!(error = %e, skipped, "kafka consumer"));
                continue;
            }
            Some(Ok(m)) => m,
        };
        let (partition, offset) = (msg.partition(), msg.offset());
        let Some(lease) = leases.of(partition) else {
            continue;
        };
        if !ledger.read(partition, lease, offset) {
            continue;
        }
        let max = limits.max_line_bytes;
        let text = match msg.payload() {
            None => Err("an empty message, not a frame".to_string()),
            Some(b) if b.len() > max => Err(format!(
                "the message is longer than input.max_line_bytes = {max}; skipped"
            )),
            Some(b) => std::str::from_utf8(b)
                .map(|s| s.trim_end().to_string())
                .map_err(|_| "the message is not valid UTF-8".to_string()),
        };
        let default_stream = msg
            .key()
            .and_then(|k| std::str::from_utf8(k).ok())
            .filter(|k| !k.is_empty())
            .map(Arc::from);
        let origin = origins
            .entry(partition)
            .or_insert_with(|| format!("kafka {topic}[{partition}]").into())
            .clone();
        let line = Line {
            origin,
            default_stream,
            line: u64::try_from(offset).unwrap_or(0),
            text,
            decoded: None,
            arrived: Instant::now(),
            receipt: Some(Receipt {
                ledger: ledger.clone(),
                partition,
                lease,
                offset,
            }),
        };
        drop(msg);
        if tx.send(line).is_err() {
            return;
        }
    }
}

/// Delivery reports: a delivered record hands in its frame's receipt and is counted; a
/// record that could not be delivered fails the run and `/health` at once.
struct Delivery {
    failed: Arc<Mutex<Option<String>>>,
    /// The daemon's metrics (none for `isoline publish`).
    metrics: Option<Arc<Metrics>>,
    brokers: Option<BrokerWatch>,
}

impl ClientContext for Delivery {
    fn log(&self, level: RDKafkaLogLevel, fac: &str, message: &str) {
        log(level, fac, message);
    }

    fn error(&self, error: KafkaError, reason: &str) {
        CLIENT_WARNINGS.warn(|skipped| tracing::warn!(%error, skipped, "kafka producer: {reason}"));
    }

    fn stats(&self, statistics: Statistics) {
        if let Some(b) = &self.brokers {
            b.seen(&statistics);
        }
    }
}

impl ProducerContext for Delivery {
    type DeliveryOpaque = Box<(Option<Receipt>, Option<Counted>)>;

    fn delivery(&self, result: &DeliveryResult<'_>, opaque: Self::DeliveryOpaque) {
        let (receipt, tally) = *opaque;
        match result {
            Ok(_) => {
                if let Some(r) = receipt {
                    r.done();
                }
                if let (Some(t), Some(m)) = (tally, &self.metrics) {
                    t.count(m);
                }
            }
            Err((e, _)) => {
                let why = e.to_string();
                if let Some(m) = &self.metrics {
                    m.condition(
                        "kafka output",
                        Some(format!("kafka output: a record was not delivered: {why}")),
                    );
                }
                lock(&self.failed).get_or_insert(why);
            }
        }
    }
}

/// Writes keyed messages to a topic, in order per key: the daemon's Kafka sink, and
/// `isoline publish`. At most `queue.buffering.max.messages` (default here 1,000) wait
/// for the broker; `send` waits for room beyond that.
pub struct KafkaWriter {
    producer: ThreadedProducer<Delivery>,
    topic: String,
    failed: Arc<Mutex<Option<String>>>,
}

impl KafkaWriter {
    /// Connects a producer to `topic`'s cluster.
    pub fn open(topic: &KafkaTopic) -> Result<KafkaWriter> {
        KafkaWriter::open_with(topic, None)
    }

    /// Queues one message.
    pub fn send(&self, key: &str, payload: &[u8]) -> Result<()> {
        self.send_with(key, payload, None, None)
    }

    /// [`KafkaWriter::open`]; with `metrics`, records are counted there when
    /// acknowledged and the brokers' reachability is a `/health` condition.
    pub(crate) fn open_with(
        topic: &KafkaTopic,
        metrics: Option<Arc<Metrics>>,
    ) -> Result<KafkaWriter> {
        let failed = Arc::new(Mutex::new(None));
        let producer = client_config(
            topic,
            &[
                ("acks", "all".into()),
                // One request in flight per broker keeps each key's messages in order
                // through retries, with brokers that lack idempotent producers too.
                ("max.in.flight.requests.per.connection", "1".into()),
                ("queue.buffering.max.messages", "1000".into()),
                ("linger.ms", "5".into()),
                // Java clients' partitioner: a key lands where theirs would put it.
                ("partitioner", "murmur2_random".into()),
                // A record not acknowledged within the stall time fails the run, rather
                // than after librdkafka's five minutes.
                (
                    "message.timeout.ms",
                    topic.stall.as_millis().max(1000).to_string(),
                ),
                ("statistics.interval.ms", "1000".into()),
            ],
        )
        .create_with_context(Delivery {
            failed: failed.clone(),
            brokers: metrics
                .as_ref()
                .map(|m| BrokerWatch::new("kafka output brokers", topic.stall, m.clone())),
            metrics,
        })
        .map_err(|e| kafka_error("creating the producer", e))?;
        Ok(KafkaWriter {
            producer,
            topic: topic.topic.clone(),
            failed,
        })
    }

    fn check(&self) -> Result<()> {
        match lock(&self.failed).as_ref() {
            Some(e) => Err(kafka_error(
                &format!("a message to {} was not delivered", self.topic),
                e,
            )),
            None => Ok(()),
        }
    }

    /// Queues one message; `receipt` is handed in and `tally` counted once the broker
    /// has it.
    pub(crate) fn send_with(
        &self,
        key: &str,
        payload: &[u8],
        receipt: Option<Receipt>,
        tally: Option<Counted>,
    ) -> Result<()> {
        self.check()?;
        let mut record = BaseRecord::with_opaque_to(&self.topic, Box::new((receipt, tally)))
            .key(key)
            .payload(payload);
        loop {
            match self.producer.send(record) {
                Ok(()) => return Ok(()),
                Err((KafkaError::MessageProduction(RDKafkaErrorCode::QueueFull), r)) => {
                    record = r;
                    std::thread::sleep(Duration::from_millis(5));
                    self.check()?;
                }
                Err((e, _)) => return Err(kafka_error(&format!("writing to {}", self.topic), e)),
            }
        }
    }

    /// Waits until every message is delivered (or fails the run).
    pub fn finish(self) -> Result<()> {
        self.producer
            .flush(FLUSH_TIMEOUT)
            .map_err(|e| kafka_error(&format!("flushing to {}", self.topic), e))?;
        self.check()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tls_settings_are_refused_only_by_a_build_without_tls() {
        let with = |protocol: &str| {
            BTreeMap::from([("security.protocol".to_string(), protocol.to_string())])
        };
        for protocol in ["ssl", "SASL_SSL"] {
            let refused = without_tls(&with(protocol));
            assert_eq!(
                refused.is_some(),
                !cfg!(feature = "kafka-tls"),
                "{protocol}"
            );
            if let Some(why) = refused {
                assert!(why.contains("--features kafka-tls"), "{why}");
            }
        }
        for protocol in ["plaintext", "sasl_plaintext"] {
            assert_eq!(without_tls(&with(protocol)), None);
        }
        assert_eq!(without_tls(&BTreeMap::new()), None);
    }
}
