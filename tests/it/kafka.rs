//! Scale-out through Kafka, against a real broker on loopback (Tansu, installed by
//! `scripts/kafka-broker.sh install`, which the README's test command runs): two
//! daemons in one consumer group share 8 streams on a 4-partition topic, one is killed
//! with SIGKILL mid-stream, and the other takes its partitions over. Then the faults:
//! no broker at start, a broker killed and restarted empty, a broker down at SIGTERM,
//! a sink's broker killed. With the `kafka-tls` feature, all of it over TLS with client
//! certificates, through a TLS-terminating proxy.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use rdkafka::config::ClientConfig;
use rdkafka::consumer::{BaseConsumer, Consumer};
use rdkafka::{Message, Offset, TopicPartitionList};
use serde_json::Value;

use crate::common::{ok, p};

const STREAMS: usize = 8;
const FRAMES: u64 = 40;
const PARTITIONS: i32 = 4;

/// The broker, stopped when dropped.
struct Broker {
    child: Child,
    port: u16,
}

impl Drop for Broker {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A free loopback port.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn tansu() -> PathBuf {
    let bin = Path::new(env!("CARGO_MANIFEST_DIR")).join(".tools/kafka/bin/tansu");
    assert!(
        bin.exists(),
        "no broker at {}: run scripts/kafka-broker.sh install (the README's test command does)",
        bin.display()
    );
    bin
}

impl Broker {
    fn start() -> Broker {
        let b = Broker::start_on(free_port());
        b.create_topics();
        b
    }

    /// A broker on `port`, in memory: a restarted broker has lost every topic.
    fn start_on(port: u16) -> Broker {
        Broker::start_advertising(port, port)
    }

    /// A broker on `port` that tells clients to connect to `advertised` (a proxy's).
    fn start_advertising(port: u16, advertised: u16) -> Broker {
        let bin = tansu();
        let url = format!("tcp://127.0.0.1:{port}");
        let public = format!("tcp://127.0.0.1:{advertised}");
        let child = Command::new(&bin)
            .args([
                "broker",
                "--listener-url",
                &url,
                "--advertised-listener-url",
                &public,
            ])
            .args(["--storage-engine", "memory://tansu/"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start the broker");
        let broker = Broker { child, port };
        let t0 = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(t0.elapsed() < Duration::from_secs(10), "broker not up");
            std::thread::sleep(Duration::from_millis(50));
        }
        broker
    }

    fn create_topics(&self) {
        let url = format!("tcp://127.0.0.1:{}", self.port);
        for topic in ["frames", "records"] {
            let out = Command::new(tansu())
                .args(["topic", "create", topic, "--partitions"])
                .arg(PARTITIONS.to_string())
                .args(["--broker", &url])
                .output()
                .unwrap();
            assert!(out.status.success(), "{out:?}");
        }
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }

    fn addr(&self) -> String {
        format!("127.0.0.1:{}", self.port)
    }
}

/// A daemon in group `isoline`, reading `frames` and writing `records`.
struct Daemon {
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Daemon {
    fn start(dir: &Path, name: &str, broker: &str) -> Daemon {
        Daemon::with(
            dir,
            name,
            &format!(
                "[input]\nkind = \"kafka\"\nbrokers = \"{broker}\"\ntopic = \"frames\"\n\
                 [input.kafka]\n\"session.timeout.ms\" = 2000\n\"heartbeat.interval.ms\" = 300\n\
                 [output]\nkind = \"kafka\"\nbrokers = \"{broker}\"\ntopic = \"records\"\n\
                 [metrics]\nbind = \"127.0.0.1:0\"\n\
                 [tracing]\nlevel = \"warn,isoline::pipeline::kafka=info\"\n"
            ),
        )
    }

    /// A daemon with configuration `toml`.
    fn with(dir: &Path, name: &str, toml: &str) -> Daemon {
        let cfg = dir.join(format!("{name}.toml"));
        std::fs::write(&cfg, toml).unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_isoline"))
            .args(["run", "-c", p(&cfg)])
            .env("NO_COLOR", "1")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start isoline");
        let lines = lines_of(child.stderr.take().unwrap());
        Daemon {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Reads what the daemon has logged so far.
    fn pump(&mut self) {
        self.seen.extend(self.lines.try_iter());
    }

    /// The partitions the daemon holds, by its log.
    fn partitions(&mut self) -> BTreeSet<i32> {
        self.pump();
        let mut held = BTreeSet::new();
        for l in &self.seen {
            let list = |l: &str| -> Vec<i32> {
                let at = l.find("partitions=[").map(|i| i + "partitions=[".len());
                at.map(|i| {
                    l[i..l[i..].find(']').unwrap() + i]
                        .split(',')
                        .filter_map(|s| s.trim().parse().ok())
                        .collect()
                })
                .unwrap_or_default()
            };
            if l.contains("partitions assigned") {
                held.extend(list(l));
            } else if l.contains("partitions revoked") {
                for p in list(l) {
                    held.remove(&p);
                }
            }
        }
        held
    }

    fn metrics_addr(&mut self) -> Option<String> {
        self.pump();
        self.seen.iter().find_map(|l| {
            l.strip_prefix("isoline run: metrics on http://")
                .map(|a| a.split('/').next().unwrap().to_string())
        })
    }

    fn signal(&self, sig: &str) {
        let ok = Command::new("kill")
            .args([sig, &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill {sig}");
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The lines a child process writes to `pipe`, read on a thread of their own so that
/// the child never blocks on a full pipe.
fn lines_of(pipe: impl std::io::Read + Send + 'static) -> Receiver<String> {
    let (tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(pipe).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    lines
}

/// Waits until `done` holds, or fails after `limit` saying `what`.
fn until(limit: Duration, what: &str, mut done: impl FnMut() -> bool) {
    let t0 = Instant::now();
    while !done() {
        assert!(t0.elapsed() < limit, "timed out after {limit:?}: {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Reads the output topic from the start: each partition's records in order.
struct Records {
    consumer: BaseConsumer,
    /// (partition, record), in the order read.
    got: Vec<(i32, Value)>,
}

impl Records {
    fn new(broker: &str) -> Records {
        let consumer: BaseConsumer = ClientConfig::new()
            .set("bootstrap.servers", broker)
            .set("group.id", "test-reader")
            .set("enable.auto.commit", "false")
            .create()
            .unwrap();
        let mut tpl = TopicPartitionList::new();
        for p in 0..PARTITIONS {
            tpl.add_partition_offset("records", p, Offset::Beginning)
                .unwrap();
        }
        consumer.assign(&tpl).unwrap();
        Records {
            consumer,
            got: Vec::new(),
        }
    }

    fn read(&mut self) -> usize {
        while let Some(m) = self.consumer.poll(Duration::from_millis(100)) {
            let m = m.unwrap();
            let rec: Value = serde_json::from_slice(m.payload().unwrap()).unwrap();
            let key = std::str::from_utf8(m.key().unwrap()).unwrap();
            assert_eq!(rec["stream"], key, "records are keyed by stream");
            self.got.push((m.partition(), rec));
        }
        self.got.len()
    }

    /// Each stream's frame numbers, in the order written.
    fn streams(&self) -> BTreeMap<String, Vec<u64>> {
        let mut s: BTreeMap<String, Vec<u64>> = BTreeMap::new();
        for (_, r) in &self.got {
            assert!(r["error"].is_null(), "{r}");
            s.entry(r["stream"].as_str().unwrap().into())
                .or_default()
                .push(r["frame"].as_u64().unwrap());
        }
        s
    }

    fn distinct(&self) -> usize {
        self.got
            .iter()
            .map(|(_, r)| (r["stream"].to_string(), r["frame"].as_u64()))
            .collect::<BTreeSet<_>>()
            .len()
    }
}

/// The fleet: 8 robots driving through the simulated room, a 360-beam RPLIDAR each,
/// interleaved by time stamp.
fn fleet(dir: &Path) -> PathBuf {
    let mut frames: Vec<Value> = Vec::new();
    for i in 0..STREAMS {
        let path = dir.join(format!("robot{i}.ndjson"));
        ok(&[
            "synth",
            "room",
            "--sensor",
            "rplidar-a1",
            "--frames",
            &FRAMES.to_string(),
            "--motion",
            "0.05",
            "--seed",
            &(i + 1).to_string(),
            "--stream",
            &format!("robot{i}"),
            "-o",
            p(&path),
        ]);
        let text = std::fs::read_to_string(&path).unwrap();
        frames.extend(
            text.lines()
                .map(|l| serde_json::from_str::<Value>(l).unwrap()),
        );
    }
    frames.sort_by(|a, b| {
        a["t"]
            .as_f64()
            .unwrap()
            .total_cmp(&b["t"].as_f64().unwrap())
    });
    let out = dir.join("fleet.ndjson");
    let text: String = frames.iter().map(|f| format!("{f}\n")).collect();
    std::fs::write(&out, text).unwrap();
    out
}

/// The hand-over: every frame of every stream gets a record, in order per stream;
/// repeats appear only where a killed daemon's work was not committed, once each, on
/// the streams of its partitions; the streams that moved start cold once and warm up
/// again; a daemon stopped with SIGTERM commits what it wrote, so a newcomer finds
/// nothing left to do.
#[test]
fn a_killed_daemons_partitions_are_taken_over_and_every_frame_gets_a_record() {
    let dir = tempfile::tempdir().unwrap();
    let input = fleet(dir.path());
    let broker = Broker::start();
    let addr = broker.addr();
    let mut a = Daemon::start(dir.path(), "a", &addr);
    until(
        Duration::from_secs(30),
        "daemon a holds all partitions",
        || a.partitions().len() == PARTITIONS as usize,
    );
    let mut b = Daemon::start(dir.path(), "b", &addr);
    until(
        Duration::from_secs(30),
        "the group splits the partitions",
        || {
            let (pa, pb) = (a.partitions(), b.partitions());
            !pa.is_empty() && !pb.is_empty() && pa.len() + pb.len() == PARTITIONS as usize
        },
    );
    let moved = a.partitions();

    // At the recorded pace: 10 frames per second per robot, 80 in all.
    let publisher = Command::new(env!("CARGO_BIN_EXE_isoline"))
        .args(["publish", p(&input), "--brokers", &addr, "--to", "frames"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let total = STREAMS * FRAMES as usize;
    let mut records = Records::new(&addr);
    until(Duration::from_secs(60), "a third of the records", || {
        records.read() >= total / 3
    });
    // The lag of each partition b holds is reported while it works.
    let metrics = b.metrics_addr().expect("b serves metrics");
    let text = http_get(&metrics, "/metrics");
    for p in b.partitions() {
        assert!(
            text.contains(&format!("isoline_kafka_consumer_lag{{partition=\"{p}\"}}")),
            "no lag for partition {p} in\n{text}"
        );
    }
    a.signal("-KILL");
    let killed_at = records.read();
    let out = publisher.wait_with_output().unwrap();
    assert!(out.status.success(), "{out:?}");
    until(Duration::from_secs(120), "a record for every frame", || {
        records.read();
        records.distinct() == total
    });
    assert_eq!(b.partitions().len(), PARTITIONS as usize, "b took over");

    // Per stream: frame order, with at most one step back (the hand-over), whose
    // repeats are frames the killed daemon had written but not committed.
    let streams = records.streams();
    assert_eq!(streams.len(), STREAMS);
    let key_partition: BTreeMap<String, i32> = records
        .got
        .iter()
        .map(|(p, r)| (r["stream"].as_str().unwrap().to_string(), *p))
        .collect();
    let mut repeats = 0;
    for (stream, numbers) in &streams {
        let distinct: BTreeSet<u64> = numbers.iter().copied().collect();
        assert_eq!(distinct, (0..FRAMES).collect(), "{stream}: {numbers:?}");
        let steps_back: Vec<usize> = (1..numbers.len())
            .filter(|&i| numbers[i] <= numbers[i - 1])
            .collect();
        assert!(steps_back.len() <= 1, "{stream}: {numbers:?}");
        if let Some(&i) = steps_back.first() {
            assert!(
                moved.contains(&key_partition[stream]),
                "{stream} repeats frames but its partition {} stayed with b: {numbers:?}",
                key_partition[stream]
            );
            assert!(numbers[i..].windows(2).all(|w| w[0] < w[1]), "{numbers:?}");
            repeats += numbers.len() - FRAMES as usize;
        }
    }
    // Scans built from their own scan among the records written before the kill and
    // after it, on the streams that moved and on those that stayed: a scan frame needs
    // nothing from its stream's earlier frames, so a hand-over costs it nothing.
    let mut share = BTreeMap::new();
    for (i, (part, r)) in records.got.iter().enumerate() {
        let key = (moved.contains(part), i >= killed_at);
        let e = share.entry(key).or_insert((0usize, 0usize));
        e.0 += usize::from(r["stats"]["start"] == "scan");
        e.1 += 1;
    }
    let show = |k| {
        share
            .get(&k)
            .map_or("-".into(), |(w, n)| format!("{w}/{n}"))
    };
    eprintln!(
        "killed after {killed_at} of {total} records; partitions moved {moved:?}, \
         {repeats} records repeated; scan starts before/after the hand-over: moved streams \
         {} / {}, the others {} / {}",
        show((true, false)),
        show((true, true)),
        show((false, false)),
        show((false, true)),
    );
    let (w, n) = share[&(true, true)];
    assert_eq!(
        w, n,
        "moved streams after the hand-over: {w}/{n} from their scan"
    );
    assert!(repeats < total / 4, "{repeats} repeats");

    // A clean stop commits every record written: a newcomer has nothing to read.
    b.signal("-TERM");
    until(Duration::from_secs(30), "b exits", || {
        b.child.try_wait().unwrap().is_some()
    });
    let ok = b.child.wait().unwrap().success();
    b.pump();
    assert!(ok, "{}", b.seen.join("\n"));
    let before = records.read();
    let mut c = Daemon::start(dir.path(), "c", &addr);
    until(Duration::from_secs(30), "c joins", || {
        c.partitions().len() == PARTITIONS as usize
    });
    std::thread::sleep(Duration::from_secs(2));
    assert_eq!(records.read(), before, "c found uncommitted frames");
}

/// `GET path` from the HTTP server at `addr`: the body.
fn http_get(addr: &str, path: &str) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    write!(s, "GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    text
}

/// `/health`'s status line and body.
fn health(d: &mut Daemon) -> String {
    let addr = d.metrics_addr().expect("the daemon serves metrics");
    let text = http_get(&addr, "/health");
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    format!("{} {}", head.lines().next().unwrap_or(""), body.trim())
}

/// A daemon reading `frames` with a stall time of 2 s, writing records to `out`.
fn reader(dir: &Path, name: &str, broker: &str, out: &Path) -> Daemon {
    reader_with(dir, name, broker, out, 2000)
}

/// A [`reader`] whose group session lasts `session_ms`.
fn reader_with(dir: &Path, name: &str, broker: &str, out: &Path, session_ms: u32) -> Daemon {
    Daemon::with(
        dir,
        name,
        &format!(
            "[input]\nkind = \"kafka\"\nbrokers = \"{broker}\"\ntopic = \"frames\"\n\
             stall_timeout = 2\n\
             [input.kafka]\n\"session.timeout.ms\" = {session_ms}\n\"heartbeat.interval.ms\" = 300\n\
             \"reconnect.backoff.max.ms\" = 500\n\
             [output]\npath = {out:?}\n[metrics]\nbind = \"127.0.0.1:0\"\n\
             [tracing]\nlevel = \"warn,isoline::pipeline::kafka=info\"\n"
        ),
    )
}

/// A broker, and a [`reader`] of it writing to `dir/out.ndjson` that holds every
/// partition.
fn reading(dir: &Path) -> (Broker, Daemon, PathBuf) {
    reading_with(dir, 2000)
}

/// [`reading`] with a group session of `session_ms`.
fn reading_with(dir: &Path, session_ms: u32) -> (Broker, Daemon, PathBuf) {
    let broker = Broker::start();
    let out = dir.join("out.ndjson");
    let mut daemon = reader_with(dir, "r", &broker.addr(), &out, session_ms);
    until(Duration::from_secs(30), "partitions assigned", || {
        daemon.partitions().len() == PARTITIONS as usize
    });
    (broker, daemon, out)
}

/// The shipped stream of 20 ellipse frames.
fn ellipse_stream() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/ellipse-stream-20.ndjson")
}

/// Publishes the first `n` frames of the ellipse stream to `frames`.
fn publish(dir: &Path, broker: &str, n: usize, stream: &str) {
    let text = std::fs::read_to_string(ellipse_stream()).unwrap();
    let frames: String = text
        .lines()
        .take(n)
        .map(|l| {
            let mut v: Value = serde_json::from_str(l).unwrap();
            v["stream"] = Value::from(stream);
            format!("{v}\n")
        })
        .collect();
    let path = dir.join(format!("{stream}.ndjson"));
    std::fs::write(&path, frames).unwrap();
    ok(&["publish", p(&path), "--brokers", broker, "--to", "frames"]);
}

fn lines(path: &Path) -> usize {
    std::fs::read_to_string(path).map_or(0, |t| t.lines().count())
}

/// No broker at start: `/health` says so after the stall time, the warnings come at
/// most once every ten seconds, and SIGTERM ends the run cleanly (nothing was read).
#[test]
fn no_broker_at_start_is_unhealthy_and_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_port();
    let out = dir.path().join("out.ndjson");
    let mut d = reader(dir.path(), "lonely", &format!("127.0.0.1:{port}"), &out);
    until(Duration::from_secs(20), "health fails", || {
        d.metrics_addr().is_some() && health(&mut d).contains("503")
    });
    let h = health(&mut d);
    assert!(h.contains("kafka input: no Kafka broker reachable"), "{h}");
    std::thread::sleep(Duration::from_secs(4));
    d.pump();
    let warnings = d
        .seen
        .iter()
        .filter(|l| l.contains("WARN") || l.contains("ERROR"))
        .count();
    assert!(
        warnings <= 8,
        "{warnings} warning lines:\n{}",
        d.seen.join("\n")
    );
    d.signal("-TERM");
    let status = d.child.wait().unwrap();
    assert!(status.success(), "{:?}", d.seen);
}

/// The broker dies and comes back empty (in memory), its topic recreated before and
/// after the daemon reconnects: `/health` fails while it is gone, the member takes the
/// new partitions (rejoining if it was left without), the lag series exist from the
/// assignment, every frame published after the restart gets its record, and health
/// comes back.
#[test]
fn a_broker_killed_and_restarted_is_seen_and_survived() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mut broker, mut daemon, out) = reading(d);
    let addr = broker.addr();
    let metrics = daemon.metrics_addr().unwrap();
    let text = http_get(&metrics, "/metrics");
    for p in 0..PARTITIONS {
        assert!(
            text.contains(&format!("isoline_kafka_consumer_lag{{partition=\"{p}\"}}")),
            "no lag series for partition {p} from its assignment:\n{text}"
        );
    }
    publish(d, &addr, 4, "one");
    until(Duration::from_secs(30), "4 records", || lines(&out) == 4);
    assert!(health(&mut daemon).starts_with("HTTP/1.1 200"));

    for recreate_after_reconnect in [false, true] {
        broker.kill();
        until(
            Duration::from_secs(20),
            "health fails without the broker",
            || health(&mut daemon).contains("no Kafka broker reachable"),
        );
        broker = Broker::start_on(broker.port);
        if recreate_after_reconnect {
            // The daemon finds a broker without its topic: it holds no partitions,
            // which `/health` reports once the stall time has passed.
            until(Duration::from_secs(30), "no partitions reported", || {
                health(&mut daemon).contains("no partitions")
            });
        }
        broker.create_topics();
        let before = lines(&out);
        let stream = format!("after-{recreate_after_reconnect}");
        // Published once the group has the new partitions: what the broker keeps from
        // then on is read.
        until(Duration::from_secs(60), "partitions held again", || {
            !daemon.partitions().is_empty() && health(&mut daemon).starts_with("HTTP/1.1 200")
        });
        publish(d, &addr, 4, &stream);
        until(Duration::from_secs(60), "the new frames' records", || {
            lines(&out) == before + 4
        });
    }
    let recs: Vec<Value> = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(recs.len(), 12);
    assert!(recs.iter().all(|r| r["error"].is_null()));
    assert!(health(&mut daemon).starts_with("HTTP/1.1 200"));
}

/// SIGTERM while the broker is down, with records written since the last commit: the
/// final commit fails, and the exit is non-zero and says so with the run's summary. The
/// group session (6 s) outlasts the wait before the signal, so the member still holds
/// its partitions: leaving the group, which cannot happen with no broker, must not
/// hold the exit (it did, without end). With the default 2 s session the partitions
/// usually go first, and the revocation reports them: `a_broker_killed_...` covers it.
#[test]
fn a_final_commit_that_fails_fails_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mut broker, mut daemon, out) = reading_with(d, 6000);
    let addr = broker.addr();
    publish(d, &addr, 20, "one");
    // Killed as the first record is written: the frames read after it are written
    // while no commit can reach the broker.
    until(Duration::from_secs(30), "a record", || lines(&out) >= 1);
    broker.kill();
    // The frames fetched before the kill get their records (how many were fetched is
    // up to librdkafka's prefetch); then none come for a while.
    let (mut seen, mut since) = (lines(&out), Instant::now());
    until(
        Duration::from_secs(60),
        "the records to stop coming",
        || {
            let n = lines(&out);
            if n != seen {
                (seen, since) = (n, Instant::now());
            }
            since.elapsed() > Duration::from_secs(3)
        },
    );
    assert!(seen >= 2, "{seen} records");
    daemon.signal("-TERM");
    // The final commit's read-back (10 s) and leaving the group (5 s) are bounded.
    until(
        Duration::from_secs(40),
        "the daemon exits after SIGTERM",
        || daemon.child.try_wait().unwrap().is_some(),
    );
    let status = daemon.child.wait().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    daemon.pump();
    let log = daemon.seen.join("\n");
    assert!(!status.success(), "{log}");
    assert!(
        log.contains("offsets of written frames were not committed")
            && log.contains(&format!("{seen} records")),
        "{log}"
    );
}

/// The sink's broker dies mid-run: `/health` fails within the stall time and the run
/// ends with an error naming the undelivered record; no record is counted before the
/// broker acknowledged it.
#[test]
fn a_sink_whose_broker_dies_is_seen_within_the_stall_time() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut broker = Broker::start();
    let addr = broker.addr();
    let input = d.join("in.ndjson");
    std::fs::copy(ellipse_stream(), &input).unwrap();
    let mut daemon = Daemon::with(
        d,
        "w",
        &format!(
            "[input]\npath = {input:?}\nreplay = 4\n\
             [output]\nkind = \"kafka\"\nbrokers = \"{addr}\"\ntopic = \"records\"\n\
             stall_timeout = 2\n[output.kafka]\n\"reconnect.backoff.max.ms\" = 500\n\
             [metrics]\nbind = \"127.0.0.1:0\"\n"
        ),
    );
    let mut records = Records::new(&addr);
    until(Duration::from_secs(30), "two records delivered", || {
        records.read() >= 2
    });
    broker.kill();
    let killed = Instant::now();
    until(Duration::from_secs(15), "health fails", || {
        let h = health(&mut daemon);
        h.contains("kafka output") || daemon.child.try_wait().unwrap().is_some()
    });
    assert!(killed.elapsed() < Duration::from_secs(12));
    let metrics = daemon.metrics_addr().unwrap();
    if let Ok(mut s) = std::net::TcpStream::connect(&metrics) {
        use std::io::{Read, Write};
        let _ = write!(s, "GET /metrics HTTP/1.0\r\n\r\n");
        let mut text = String::new();
        let _ = s.read_to_string(&mut text);
        let counted: f64 = text
            .lines()
            .find_map(|l| l.strip_prefix("isoline_records_total{outcome=\"reconstructed\"} "))
            .map_or(0.0, |v| v.trim().parse().unwrap());
        assert!(
            counted <= records.got.len() as f64 + 1.0,
            "{counted} counted"
        );
    }
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = daemon.child.try_wait().unwrap() {
            break s;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "the run did not end"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    daemon.pump();
    assert!(!status.success(), "{}", daemon.seen.join("\n"));
}

/// Kafka over TLS, as managed services require it: the broker behind a TLS-terminating
/// proxy (`scripts/tls-proxy.py`) that it advertises, so every connection is TLS, and the
/// proxy asks for a client certificate (mutual TLS). The certificates are made here with
/// the `openssl` command.
#[cfg(feature = "kafka-tls")]
mod tls {
    use super::*;

    /// A CA, a server certificate for 127.0.0.1 and a client certificate signed by it,
    /// and a second CA that signed nothing of this.
    struct Pki {
        dir: PathBuf,
    }

    fn openssl(dir: &Path, args: &[&str]) {
        let out = Command::new("openssl")
            .args(args)
            .current_dir(dir)
            .output()
            .expect("the openssl command (Debian: openssl)");
        assert!(out.status.success(), "openssl {args:?}: {out:?}");
    }

    impl Pki {
        fn new(dir: &Path) -> Pki {
            for ca in ["ca", "other-ca"] {
                openssl(
                    dir,
                    &[
                        "req",
                        "-x509",
                        "-newkey",
                        "rsa:2048",
                        "-nodes",
                        "-days",
                        "2",
                        "-subj",
                        &format!("/CN=isoline test {ca}"),
                        "-keyout",
                        &format!("{ca}.key"),
                        "-out",
                        &format!("{ca}.pem"),
                    ],
                );
            }
            for (name, ext) in [
                (
                    "server",
                    "subjectAltName=IP:127.0.0.1\nextendedKeyUsage=serverAuth\n",
                ),
                ("client", "extendedKeyUsage=clientAuth\n"),
            ] {
                std::fs::write(dir.join(format!("{name}.ext")), ext).unwrap();
                openssl(
                    dir,
                    &[
                        "req",
                        "-newkey",
                        "rsa:2048",
                        "-nodes",
                        "-subj",
                        &format!("/CN=isoline test {name}"),
                        "-keyout",
                        &format!("{name}.key"),
                        "-out",
                        &format!("{name}.csr"),
                    ],
                );
                openssl(
                    dir,
                    &[
                        "x509",
                        "-req",
                        "-in",
                        &format!("{name}.csr"),
                        "-CA",
                        "ca.pem",
                        "-CAkey",
                        "ca.key",
                        "-CAcreateserial",
                        "-days",
                        "2",
                        "-extfile",
                        &format!("{name}.ext"),
                        "-out",
                        &format!("{name}.pem"),
                    ],
                );
            }
            Pki {
                dir: dir.to_path_buf(),
            }
        }

        fn file(&self, name: &str) -> String {
            self.dir.join(name).display().to_string()
        }

        /// librdkafka's settings for a client that trusts `ca` and shows the client
        /// certificate.
        fn settings(&self, ca: &str) -> Vec<(&'static str, String)> {
            vec![
                ("security.protocol", "ssl".into()),
                ("ssl.ca.location", self.file(&format!("{ca}.pem"))),
                ("ssl.certificate.location", self.file("client.pem")),
                ("ssl.key.location", self.file("client.key")),
            ]
        }
    }

    /// The proxy, stopped when dropped; what it printed.
    struct Proxy {
        child: Child,
        lines: Receiver<String>,
    }

    impl Drop for Proxy {
        fn drop(&mut self) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }

    impl Proxy {
        fn start(listen: u16, to: u16, pki: &Pki) -> Proxy {
            let mut child = Command::new("python3")
                .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/tls-proxy.py"))
                .args(["--listen", &format!("127.0.0.1:{listen}")])
                .args(["--to", &format!("127.0.0.1:{to}")])
                .args([
                    "--cert",
                    &pki.file("server.pem"),
                    "--key",
                    &pki.file("server.key"),
                ])
                .args(["--client-ca", &pki.file("ca.pem")])
                .stdout(Stdio::piped())
                .stderr(Stdio::null())
                .spawn()
                .expect("start the TLS proxy");
            let lines = lines_of(child.stdout.take().unwrap());
            let first = lines.recv_timeout(Duration::from_secs(10));
            assert_eq!(first.as_deref(), Ok("listening"), "the proxy did not start");
            Proxy { child, lines }
        }
    }

    /// A daemon reads frames over TLS and writes its records over TLS; `isoline publish`
    /// and a test consumer use TLS too. A client that trusts another CA is refused at
    /// the handshake and `isoline publish` fails, naming the broker.
    #[test]
    fn the_daemon_reads_and_writes_kafka_over_mutual_tls() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let pki = Pki::new(d);
        let (plain, secure) = (free_port(), free_port());
        let broker = Broker::start_advertising(plain, secure);
        broker.create_topics();
        let proxy = Proxy::start(secure, plain, &pki);
        let addr = format!("127.0.0.1:{secure}");
        let settings = pki.settings("ca");

        let table: String = settings
            .iter()
            .map(|(k, v)| format!("\"{k}\" = {v:?}\n"))
            .collect();
        let mut daemon = Daemon::with(
            d,
            "tls",
            &format!(
                "[input]\nkind = \"kafka\"\nbrokers = \"{addr}\"\ntopic = \"frames\"\n\
                 [input.kafka]\n\"session.timeout.ms\" = 2000\n\"heartbeat.interval.ms\" = 300\n\
                 {table}\
                 [output]\nkind = \"kafka\"\nbrokers = \"{addr}\"\ntopic = \"records\"\n\
                 [output.kafka]\n{table}\
                 [metrics]\nbind = \"127.0.0.1:0\"\n\
                 [tracing]\nlevel = \"warn,isoline::pipeline::kafka=info\"\n"
            ),
        );
        until(
            Duration::from_secs(30),
            "partitions assigned over TLS",
            || daemon.partitions().len() == PARTITIONS as usize,
        );

        let frames = d.join("frames.ndjson");
        std::fs::copy(ellipse_stream(), &frames).unwrap();
        let mut args = vec!["publish", p(&frames), "--brokers", &addr, "--to", "frames"];
        let flags: Vec<String> = settings.iter().map(|(k, v)| format!("{k}={v}")).collect();
        for f in &flags {
            args.extend(["--kafka", f]);
        }
        ok(&[args.as_slice(), &["--replay", "fast"]].concat());

        let mut consumer = ClientConfig::new();
        consumer
            .set("bootstrap.servers", &addr)
            .set("group.id", "test-reader")
            .set("enable.auto.commit", "false");
        for (k, v) in &settings {
            consumer.set(*k, v);
        }
        let consumer: BaseConsumer = consumer.create().unwrap();
        let mut tpl = TopicPartitionList::new();
        for part in 0..PARTITIONS {
            tpl.add_partition_offset("records", part, Offset::Beginning)
                .unwrap();
        }
        consumer.assign(&tpl).unwrap();
        let mut frames_seen = BTreeSet::new();
        until(Duration::from_secs(60), "20 records over TLS", || {
            while let Some(m) = consumer.poll(Duration::from_millis(100)) {
                let rec: Value = serde_json::from_slice(m.unwrap().payload().unwrap()).unwrap();
                assert!(
                    rec["polylines"].as_array().is_some_and(|p| !p.is_empty()),
                    "{rec}"
                );
                frames_seen.insert(rec["frame"].as_u64().unwrap());
            }
            frames_seen.len() == 20
        });
        daemon.signal("-TERM");
        let status = daemon.child.wait().unwrap();
        daemon.pump();
        assert!(status.success(), "{}", daemon.seen.join("\n"));

        // A client trusting another CA refuses the broker's certificate; a client
        // without a certificate is refused by the broker's side (mutual TLS). Either
        // way nothing is delivered and `isoline publish` fails, naming the broker.
        let refused = |settings: Vec<(&'static str, String)>| {
            let mut args = vec!["publish", p(&frames), "--brokers", &addr, "--to", "frames"];
            let flags: Vec<String> = settings
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .chain(["message.timeout.ms=3000".to_string()])
                .collect();
            for f in &flags {
                args.extend(["--kafka", f]);
            }
            args.extend(["--replay", "fast"]);
            let out = Command::new(env!("CARGO_BIN_EXE_isoline"))
                .args(&args)
                .output()
                .unwrap();
            assert!(!out.status.success());
            String::from_utf8_lossy(&out.stderr).into_owned()
        };
        let err = refused(pki.settings("other-ca"));
        assert!(
            err.contains("127.0.0.1") && err.contains("certificate verify failed"),
            "{err}"
        );
        let anonymous: Vec<_> = pki.settings("ca").into_iter().take(2).collect();
        let err = refused(anonymous);
        assert!(err.contains("127.0.0.1"), "{err}");
        let said: Vec<String> = proxy.lines.try_iter().collect();
        assert!(
            said.iter()
                .any(|l| l.starts_with("handshake refused") && l.contains("CERTIFICATE")),
            "{said:?}"
        );
    }
}
