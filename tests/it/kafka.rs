//! Scale-out through Kafka, against a real broker on loopback (Tansu, installed by
//! `scripts/kafka-broker.sh install`, which the README's test command runs): two
//! daemons in one consumer group share 8 streams on a 4-partition topic, one is killed
//! with SIGKILL mid-stream, and the other takes its partitions over.

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

impl Broker {
    fn start() -> Broker {
        let bin = Path::new(env!("CARGO_MANIFEST_DIR")).join(".tools/kafka/bin/tansu");
        assert!(
            bin.exists(),
            "no broker at {}: run scripts/kafka-broker.sh install (the README's test command does)",
            bin.display()
        );
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let url = format!("tcp://127.0.0.1:{port}");
        let child = Command::new(&bin)
            .args([
                "broker",
                "--listener-url",
                &url,
                "--advertised-listener-url",
                &url,
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
        for topic in ["frames", "records"] {
            let out = Command::new(&bin)
                .args(["topic", "create", topic, "--partitions"])
                .arg(PARTITIONS.to_string())
                .args(["--broker", &url])
                .output()
                .unwrap();
            assert!(out.status.success(), "{out:?}");
        }
        broker
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
        let cfg = dir.join(format!("{name}.toml"));
        std::fs::write(
            &cfg,
            format!(
                "[input]\nkind = \"kafka\"\nbrokers = \"{broker}\"\ntopic = \"frames\"\n\
                 [input.kafka]\n\"session.timeout.ms\" = 2000\n\"heartbeat.interval.ms\" = 300\n\
                 [output]\nkind = \"kafka\"\nbrokers = \"{broker}\"\ntopic = \"records\"\n\
                 [metrics]\nbind = \"127.0.0.1:0\"\n\
                 [tracing]\nlevel = \"warn,isoline::pipeline::kafka=info\"\n"
            ),
        )
        .unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_isoline"))
            .args(["run", "-c", p(&cfg)])
            .env("NO_COLOR", "1")
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start isoline");
        let stderr = child.stderr.take().unwrap();
        let (tx, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                let _ = tx.send(line);
            }
        });
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
    assert!(b.child.wait().unwrap().success());
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
