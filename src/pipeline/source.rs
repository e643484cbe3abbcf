//! Sources: threads that read NDJSON lines from a file (paced), standard input or TCP
//! clients, and hand them to the ingest stage untouched. Parsing happens in the ingest
//! stage, so a malformed line becomes an error record in its place in the stream.
//!
//! Every bound holds whatever the peer sends: a line longer than
//! [`Limits::max_line_bytes`] is reported and skipped without being held in memory, at
//! most [`Limits::max_clients`] TCP clients are served at once (the others are told so
//! and closed), and a client's thread is joined as soon as the client leaves.

use std::io::{BufRead, BufReader, ErrorKind, Write};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::Sender;

use serde::Deserialize;

use super::ledger::Receipt;
use super::spawn;
use crate::config::{bounded, listen_address, resolve};
use crate::error::Result;

/// One line as read, with where it came from.
#[derive(Debug)]
pub struct Line {
    /// The source, for messages: a path, `stdin` or `tcp PEER`.
    pub origin: Arc<str>,
    /// Stream id for frames that carry none (a TCP client's address); `None` keeps them
    /// unnamed.
    pub default_stream: Option<Arc<str>>,
    /// 1-based line number within the source.
    pub line: u64,
    /// The text, or why it could not be read (invalid UTF-8, too long).
    pub text: std::result::Result<String, String>,
    /// A recording's frame, decoded by its reader (an MCAP bag, a CARMEN log): then
    /// `text` is empty and this is the frame or why its message is not one.
    pub decoded: Option<Box<isoline_io::Item>>,
    /// When it was read.
    pub arrived: Instant,
    /// A Kafka message's claim on its offset, handed in when its record is written.
    pub receipt: Option<Receipt>,
}

/// The bounds every source keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// The longest line read, in bytes without its newline.
    pub max_line_bytes: usize,
    /// TCP clients served at once.
    pub max_clients: usize,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_line_bytes: 16 << 20,
            max_clients: 64,
        }
    }
}

/// The pace of a file replay: `"recorded"`, `"fast"`, or a number of frames per second
/// in `[MIN_RATE, MAX_RATE]`.
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

/// The slowest and fastest fixed replay rates, frames per second.
pub const MIN_RATE: f64 = 1e-3;
/// See [`MIN_RATE`].
pub const MAX_RATE: f64 = 1e6;

impl<'de> Deserialize<'de> for Replay {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Pace;
        impl serde::de::Visitor<'_> for Pace {
            type Value = Replay;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(
                    f,
                    "\"recorded\", \"fast\" or frames per second in [{MIN_RATE}, {MAX_RATE}]"
                )
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Replay, E> {
                match v {
                    "recorded" => Ok(Replay::Recorded),
                    "fast" => Ok(Replay::Fast),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Replay, E> {
                if (MIN_RATE..=MAX_RATE).contains(&v) {
                    Ok(Replay::Rate(v))
                } else {
                    Err(E::invalid_value(serde::de::Unexpected::Float(v), &self))
                }
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Replay, E> {
                self.visit_f64(v as f64)
            }
        }
        d.deserialize_any(Pace)
    }
}

/// `[input] kind = "file"` (the kind when `path` is set): an NDJSON frame file, a ROS 2
/// bag (`.mcap`) or a CARMEN log, replayed.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileInput {
    /// The file, relative to the configuration file's folder.
    pub path: PathBuf,
    /// The pace. Default `"recorded"`.
    pub replay: Option<Replay>,
    /// The longest NDJSON line, bytes, in `1024..=2^30`. Default 16 MiB.
    pub max_line_bytes: Option<i64>,
    /// MCAP input: the `LaserScan` topics. Default: all.
    pub topics: Option<Vec<String>>,
    /// MCAP input: the `Odometry` topic giving poses.
    pub odometry: Option<String>,
    /// MCAP input: the frame the poses are in, through `/tf`.
    pub world_frame: Option<String>,
}

/// `[input] kind = "stdin"` (the kind without `path`): NDJSON frames on standard input.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StdinInput {
    /// The longest line, bytes, in `1024..=2^30`. Default 16 MiB.
    pub max_line_bytes: Option<i64>,
}

/// `[input] kind = "tcp"`: a listener, one NDJSON frame per line, any number of clients.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TcpInput {
    /// The address to listen on. Default `127.0.0.1:7878`.
    pub bind: Option<String>,
    /// A bind address other than loopback must be asked for. Default false.
    pub allow_remote: Option<bool>,
    /// Clients served at once, in `1..=4096`. Default 64.
    pub max_clients: Option<i64>,
    /// The longest line, bytes, in `1024..=2^30`. Default 16 MiB.
    pub max_line_bytes: Option<i64>,
}

/// The default TCP address: loopback only, so a daemon is not reachable from the network
/// unless its configuration says so.
pub const DEFAULT_BIND: &str = "127.0.0.1:7878";

/// `input.max_line_bytes`, checked.
pub(crate) fn line_limit(v: Option<i64>, problems: &mut Vec<String>) -> Limits {
    Limits {
        max_line_bytes: bounded(
            "input.max_line_bytes",
            v,
            Limits::default().max_line_bytes,
            1 << 10,
            1 << 30,
            problems,
        ),
        ..Limits::default()
    }
}

impl FileInput {
    /// The source this table describes, its paths taken from `base`, with its limits
    /// and, for a bag, what to read of it.
    pub(crate) fn validate(self, base: &Path, problems: &mut Vec<String>) -> (FileSource, Limits) {
        let path = resolve(base, &self.path);
        let bag = isoline_io::bag::BagOptions {
            topics: self.topics.unwrap_or_default(),
            odometry: self.odometry,
            world_frame: self.world_frame,
        };
        if bag != Default::default() && !isoline_io::is_bag(&path) {
            problems.push(
                "input.topics, input.odometry and input.world_frame apply to an MCAP input \
                 (input.path = \"....mcap\")"
                    .into(),
            );
        }
        let source = FileSource {
            path,
            replay: self.replay.unwrap_or(Replay::Recorded),
            bag,
        };
        (source, line_limit(self.max_line_bytes, problems))
    }
}

/// A file source, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct FileSource {
    /// The file.
    pub path: PathBuf,
    /// At what pace.
    pub replay: Replay,
    /// What to read from an MCAP input.
    pub bag: isoline_io::bag::BagOptions,
}

impl TcpInput {
    /// The address to listen on and the limits.
    pub(crate) fn validate(self, problems: &mut Vec<String>) -> (Option<SocketAddr>, Limits) {
        let bind = listen_address(
            "input",
            self.bind.as_deref(),
            self.allow_remote,
            DEFAULT_BIND,
            problems,
        );
        let limits = Limits {
            max_clients: bounded(
                "input.max_clients",
                self.max_clients,
                Limits::default().max_clients,
                1,
                4096,
                problems,
            ),
            ..line_limit(self.max_line_bytes, problems)
        };
        (bind, limits)
    }
}

/// What [`LineReader::next`] found.
#[derive(Debug, PartialEq, Eq)]
enum Chunk {
    /// A line without its newline; the last line of the input may lack one.
    Line(Vec<u8>),
    /// A line over the limit: reported once, when the limit is passed; the rest of it is
    /// skipped as it arrives.
    TooLong,
}

/// Splits a byte stream into lines of bounded length. Its state survives a read
/// timeout, so a TCP line that arrives in pieces is read whole.
struct LineReader<R> {
    inner: R,
    max: usize,
    buf: Vec<u8>,
    /// Inside a line already reported as too long.
    skipping: bool,
}

impl<R: BufRead> LineReader<R> {
    fn new(inner: R, max: usize) -> Self {
        LineReader {
            inner,
            max,
            buf: Vec::new(),
            skipping: false,
        }
    }

    /// The next line, `Ok(None)` at the end of input; errors (timeouts included) leave
    /// the partial line in place for the next call.
    fn next(&mut self) -> std::io::Result<Option<Chunk>> {
        loop {
            let avail = self.inner.fill_buf()?;
            if avail.is_empty() {
                self.skipping = false;
                if self.buf.is_empty() {
                    return Ok(None);
                }
                return Ok(Some(Chunk::Line(std::mem::take(&mut self.buf))));
            }
            let newline = avail.iter().position(|&b| b == b'\n');
            if self.skipping {
                let n = newline.map_or(avail.len(), |i| i + 1);
                self.skipping = newline.is_none();
                self.inner.consume(n);
                continue;
            }
            match newline {
                Some(i) if self.buf.len() + i <= self.max => {
                    self.buf.extend_from_slice(&avail[..i]);
                    self.inner.consume(i + 1);
                    return Ok(Some(Chunk::Line(std::mem::take(&mut self.buf))));
                }
                Some(i) => {
                    self.inner.consume(i + 1);
                    self.buf = Vec::new();
                    return Ok(Some(Chunk::TooLong));
                }
                None if self.buf.len() + avail.len() > self.max => {
                    let n = avail.len();
                    self.inner.consume(n);
                    self.buf = Vec::new();
                    self.skipping = true;
                    return Ok(Some(Chunk::TooLong));
                }
                None => {
                    let n = avail.len();
                    self.buf.extend_from_slice(avail);
                    self.inner.consume(n);
                }
            }
        }
    }
}

/// Reads `reader` line by line into `tx` until end of input, `stop`, or a closed channel.
/// A reader with a read timeout (TCP) wakes up every timeout to look at `stop`. Returns
/// the read error that ended the input, if one did.
fn pump(
    reader: impl BufRead,
    origin: Arc<str>,
    default_stream: Option<Arc<str>>,
    max_line_bytes: usize,
    tx: &Sender<Line>,
    stop: &AtomicBool,
    mut pace: impl FnMut(&str, &AtomicBool),
) -> std::io::Result<()> {
    let mut reader = LineReader::new(reader, max_line_bytes);
    let mut line = 0u64;
    while !stop.load(Ordering::Relaxed) {
        let chunk = match reader.next() {
            Ok(None) => break,
            Ok(Some(c)) => c,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => continue,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        line = line.saturating_add(1);
        let text = match chunk {
            Chunk::Line(bytes) if bytes.iter().all(u8::is_ascii_whitespace) => continue,
            Chunk::Line(bytes) => String::from_utf8(bytes)
                .map(|s| s.trim_end().to_string())
                .map_err(|_| "the line is not valid UTF-8".to_string()),
            Chunk::TooLong => Err(format!(
                "the line is longer than input.max_line_bytes = {max_line_bytes}; skipped"
            )),
        };
        if let Ok(t) = &text {
            pace(t, stop);
        }
        let sent = tx.send(Line {
            origin: origin.clone(),
            default_stream: default_stream.clone(),
            line,
            text,
            decoded: None,
            arrived: Instant::now(),
            receipt: None,
        });
        if sent.is_err() {
            break;
        }
    }
    Ok(())
}

/// Sleeps until `deadline`, waking every 20 ms to look at `stop`.
pub fn sleep_until(deadline: Instant, stop: &AtomicBool) {
    loop {
        let now = Instant::now();
        if now >= deadline || stop.load(Ordering::Relaxed) {
            return;
        }
        std::thread::sleep((deadline - now).min(Duration::from_millis(20)));
    }
}

/// The longest wait between two recorded frames: a log with a pause (or a corrupt time
/// stamp) replays the pause as this.
pub const MAX_REPLAY_GAP: Duration = Duration::from_secs(10);

/// When each frame of a replay is due. Deadlines accumulate from the previous one, so
/// neither a huge nor a backwards time stamp can overflow or stall the replay.
#[derive(Debug)]
pub struct Pacer {
    replay: Replay,
    due: Option<Instant>,
    last_t: Option<f64>,
}

impl Pacer {
    /// A replay at `replay`'s pace, starting with the first frame.
    pub fn new(replay: Replay) -> Self {
        Pacer {
            replay,
            due: None,
            last_t: None,
        }
    }

    /// The deadline of the frame with time stamp `t`, read at `now`; `None`: at once.
    pub fn deadline(&mut self, t: Option<f64>, now: Instant) -> Option<Instant> {
        let step = match self.replay {
            Replay::Fast => return None,
            Replay::Rate(fps) => Duration::try_from_secs_f64(1.0 / fps).unwrap_or(MAX_REPLAY_GAP),
            Replay::Recorded => {
                let t = t.filter(|t| t.is_finite())?;
                let gap = self.last_t.map_or(0.0, |t0| t - t0);
                self.last_t = Some(t);
                Duration::try_from_secs_f64(gap.clamp(0.0, MAX_REPLAY_GAP.as_secs_f64()))
                    .unwrap_or(Duration::ZERO)
            }
        };
        let due = match self.due {
            None => now,
            Some(d) => d.checked_add(step).unwrap_or(now),
        };
        self.due = Some(due);
        Some(due)
    }
}

/// Replays an NDJSON frame file at `replay`'s pace. A read error ends the source with
/// that error (the frames read before it get their records).
pub fn spawn_file(
    path: &Path,
    replay: Replay,
    limits: Limits,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<Result<()>>> {
    let file = std::fs::File::open(path).map_err(|e| isoline_io::Error::io(path, e))?;
    let is_dir = file
        .metadata()
        .map_err(|e| isoline_io::Error::io(path, e))?
        .file_type()
        .is_dir();
    if is_dir {
        return Err(isoline_io::Error::io(
            path,
            std::io::Error::new(ErrorKind::InvalidInput, "is a directory, not a frame file"),
        )
        .into());
    }
    let origin: Arc<str> = path.display().to_string().into();
    let owned = path.to_path_buf();
    #[derive(serde::Deserialize)]
    struct Stamp {
        t: Option<f64>,
    }
    let mut pacer = Pacer::new(replay);
    let pace = move |text: &str, stop: &AtomicBool| {
        // Only the time stamp is read here; the frame is parsed once, by ingest.
        let t = match replay {
            Replay::Recorded => serde_json::from_str::<Stamp>(text).ok().and_then(|s| s.t),
            _ => None,
        };
        if let Some(due) = pacer.deadline(t, Instant::now()) {
            sleep_until(due, stop);
        }
    };
    spawn("source-file", move || {
        let reader = BufReader::new(file);
        pump(
            reader,
            origin,
            None,
            limits.max_line_bytes,
            &tx,
            &stop,
            pace,
        )
        .map_err(|e| isoline_io::Error::io(&owned, e).into())
    })
}

/// Replays a recording (an MCAP bag's scans, a CARMEN log's laser lines) at `replay`'s
/// pace, each frame decoded by the recording's reader; a message that is not a frame is
/// passed on as such, to become an error record in its place. A file that cannot be
/// read as a whole (no chosen topic in it) ends the source with that error.
pub fn spawn_recording(
    path: &Path,
    replay: Replay,
    bag: isoline_io::bag::BagOptions,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<Result<()>>> {
    // Opened here so that a missing file fails the start, as for NDJSON.
    std::fs::File::open(path).map_err(|e| isoline_io::Error::io(path, e))?;
    let origin: Arc<str> = path.display().to_string().into();
    let owned = path.to_path_buf();
    spawn("source-recording", move || {
        let mut pacer = Pacer::new(replay);
        let mut n = 0u64;
        let mut send = |item: isoline_io::Item| -> bool {
            if stop.load(Ordering::Relaxed) {
                return false;
            }
            if let Ok(f) = &item {
                if let Some(due) = pacer.deadline(f.t, Instant::now()) {
                    sleep_until(due, &stop);
                }
            }
            n += 1;
            tx.send(Line {
                origin: origin.clone(),
                default_stream: None,
                line: n,
                text: Ok(String::new()),
                decoded: Some(Box::new(item)),
                arrived: Instant::now(),
                receipt: None,
            })
            .is_ok()
        };
        if isoline_io::is_bag(&owned) {
            isoline_io::bag::read_bag(&owned, &bag, &mut send)?;
        } else {
            isoline_io::carmen::read_carmen(&owned, &mut send)?;
        }
        Ok(())
    })
}

/// Reads frames from standard input as they come.
pub fn spawn_stdin(
    limits: Limits,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<Result<()>>> {
    spawn("source-stdin", move || {
        let stdin = std::io::stdin();
        pump(
            stdin.lock(),
            "stdin".into(),
            None,
            limits.max_line_bytes,
            &tx,
            &stop,
            |_, _| {},
        )
        .map_err(|e| isoline_io::Error::io(Path::new("standard input"), e).into())
    })
}

/// Stack of a TCP client's thread: it only splits lines.
const CLIENT_STACK: usize = 256 << 10;

/// Listens on `bind` and reads frames from every client, each in its own thread; a
/// client's frames without a stream id get the stream `tcp:PEER`. Returns the bound
/// address (useful with port 0) and the listener thread.
pub fn spawn_tcp(
    bind: SocketAddr,
    limits: Limits,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
    poll: Duration,
) -> Result<(SocketAddr, JoinHandle<Result<()>>)> {
    let io = |e| isoline_io::Error::Io {
        path: format!("tcp {bind}").into(),
        source: e,
    };
    let listener = TcpListener::bind(bind).map_err(io)?;
    let addr = listener.local_addr().map_err(io)?;
    listener.set_nonblocking(true).map_err(io)?;
    tracing::info!(%addr, "listening");
    let handle = spawn("source-tcp", move || {
        let mut clients: Vec<JoinHandle<()>> = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            reap(&mut clients, false);
            let (mut conn, peer) = match listener.accept() {
                Ok(c) => c,
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    // Short, so that a burst of connections never fills the backlog.
                    std::thread::sleep(poll.min(Duration::from_millis(2)));
                    continue;
                }
                Err(e) => {
                    // Out of descriptors, or a connection reset before it was accepted.
                    tracing::warn!(error = %e, "accept failed");
                    std::thread::sleep(poll);
                    continue;
                }
            };
            // A burst of short connections (health checks) can outrun the threads that
            // serve them: give the ones just served a moment to end before refusing.
            let patience = Instant::now() + poll;
            while clients.len() >= limits.max_clients && Instant::now() < patience {
                std::thread::sleep(Duration::from_millis(1));
                reap(&mut clients, false);
            }
            if clients.len() >= limits.max_clients {
                tracing::warn!(%peer, max = limits.max_clients, "too many clients: refused");
                let _ = conn.set_nonblocking(false);
                let _ = conn.set_write_timeout(Some(poll));
                let _ = writeln!(
                    conn,
                    "{{\"error\":\"refused: {} clients already (input.max_clients)\"}}",
                    limits.max_clients
                );
                continue;
            }
            tracing::info!(%peer, "client connected");
            // Accepted sockets may inherit non-blocking mode; reads use a timeout
            // instead, to look at `stop` between lines.
            let ok =
                conn.set_nonblocking(false).is_ok() && conn.set_read_timeout(Some(poll)).is_ok();
            if !ok {
                tracing::warn!(%peer, "could not configure the connection; dropped");
                continue;
            }
            let (tx, stop) = (tx.clone(), stop.clone());
            let origin: Arc<str> = format!("tcp {peer}").into();
            let stream: Arc<str> = format!("tcp:{peer}").into();
            let client = std::thread::Builder::new()
                .name("source-tcp-client".into())
                .stack_size(CLIENT_STACK)
                .spawn(move || {
                    let reader = BufReader::new(conn);
                    let max = limits.max_line_bytes;
                    match pump(reader, origin, Some(stream), max, &tx, &stop, |_, _| {}) {
                        Ok(()) => tracing::info!(%peer, "client disconnected"),
                        Err(e) => tracing::warn!(%peer, error = %e, "client lost"),
                    }
                });
            match client {
                Ok(h) => clients.push(h),
                Err(e) => tracing::error!(%peer, error = %e, "no thread for the client: dropped"),
            }
        }
        reap(&mut clients, true);
        Ok(())
    })?;
    Ok((addr, handle))
}

/// Joins the client threads that have ended (all of them with `all`), so that a
/// reconnecting sensor does not leave a thread's stack behind per connection.
fn reap(clients: &mut Vec<JoinHandle<()>>, all: bool) {
    let mut i = 0;
    while i < clients.len() {
        if all || clients[i].is_finished() {
            if clients.swap_remove(i).join().is_err() {
                tracing::error!("a TCP client's thread panicked (a bug in isoline)");
            }
        } else {
            i += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_all(input: &[u8], max: usize) -> Vec<(u64, std::result::Result<String, String>)> {
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(false);
        pump(input, "t".into(), None, max, &tx, &stop, |_, _| {}).unwrap();
        drop(tx);
        rx.iter().map(|l| (l.line, l.text)).collect()
    }

    #[test]
    fn lines_are_numbered_blank_ones_skipped_and_a_last_line_kept() {
        let got = read_all(b"a\n\n  \nb\xff\nc", 100);
        assert_eq!(got.len(), 3);
        assert_eq!(got[0], (1, Ok("a".into())));
        assert_eq!(got[1].0, 4);
        assert!(got[1].1.as_ref().unwrap_err().contains("UTF-8"));
        assert_eq!(got[2], (5, Ok("c".into())));
    }

    #[test]
    fn a_long_line_is_reported_once_and_skipped_without_being_kept() {
        // A tiny buffer makes the reader see the long line in many pieces.
        let mut input = b"ok\n".to_vec();
        input.extend(std::iter::repeat_n(b'x', 1000));
        input.extend(b"\nafter\n12345\n123456");
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(false);
        let reader = BufReader::with_capacity(7, input.as_slice());
        pump(reader, "t".into(), None, 5, &tx, &stop, |_, _| {}).unwrap();
        drop(tx);
        let got: Vec<_> = rx.iter().map(|l| (l.line, l.text)).collect();
        assert_eq!(got.len(), 5, "{got:?}");
        assert_eq!(got[0], (1, Ok("ok".into())));
        assert_eq!(got[1].0, 2);
        assert!(got[1]
            .1
            .as_ref()
            .unwrap_err()
            .contains("max_line_bytes = 5"));
        assert_eq!(got[2], (3, Ok("after".into())));
        assert_eq!(got[3], (4, Ok("12345".into())));
        // The last line has no newline and is over the limit: still one record.
        assert_eq!(got[4].0, 5);
        assert!(got[4].1.is_err());
    }

    #[test]
    fn an_endless_line_costs_no_memory() {
        use std::io::Read;
        // `/dev/zero` as input: a line that never ends. Its reader keeps nothing.
        let mut r = LineReader::new(BufReader::new(std::io::repeat(0).take(50 << 20)), 1024);
        assert_eq!(r.next().unwrap(), Some(Chunk::TooLong));
        assert!(r.buf.capacity() <= 1024 + 8192, "{}", r.buf.capacity());
        assert_eq!(r.next().unwrap(), None);
    }

    #[test]
    fn a_line_cut_by_a_timeout_is_read_whole_and_a_last_partial_line_kept() {
        // A reader that times out between the pieces, as a TCP client pausing mid-line.
        struct Pieces(Vec<&'static [u8]>, bool);
        impl std::io::Read for Pieces {
            fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
                self.1 = !self.1;
                if self.1 {
                    return Err(ErrorKind::WouldBlock.into());
                }
                match self.0.first_mut() {
                    None => Ok(0),
                    Some(p) => {
                        let n = p.len().min(out.len());
                        out[..n].copy_from_slice(&p[..n]);
                        *p = &p[n..];
                        if p.is_empty() {
                            self.0.remove(0);
                        }
                        Ok(n)
                    }
                }
            }
        }
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(false);
        let reader = BufReader::new(Pieces(
            vec![b"{\"fr", b"ame\":1}\n{\"frame\"", b":2}"],
            false,
        ));
        pump(reader, "t".into(), None, 100, &tx, &stop, |_, _| {}).unwrap();
        drop(tx);
        let got: Vec<_> = rx.iter().map(|l| l.text.unwrap()).collect();
        assert_eq!(got, vec!["{\"frame\":1}", "{\"frame\":2}"]);
    }

    #[test]
    fn a_stopped_source_reads_nothing_more() {
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(true);
        pump(
            "a\nb\n".as_bytes(),
            "t".into(),
            None,
            10,
            &tx,
            &stop,
            |_, _| {},
        )
        .unwrap();
        drop(tx);
        assert_eq!(rx.iter().count(), 0);
    }

    #[test]
    fn replay_deadlines_hold_for_any_time_stamp() {
        let now = Instant::now();
        let mut p = Pacer::new(Replay::Recorded);
        assert_eq!(p.deadline(Some(5.0), now), Some(now));
        let d1 = p.deadline(Some(5.5), now).unwrap();
        assert_eq!(d1 - now, Duration::from_millis(500));
        // A corrupt stamp waits at most the longest gap; one going back does not wait.
        let d2 = p.deadline(Some(1e19), now).unwrap();
        assert_eq!(d2 - d1, MAX_REPLAY_GAP);
        assert_eq!(p.deadline(Some(-1e300), now), Some(d2));
        assert_eq!(p.deadline(Some(f64::NAN), now), None);
        assert_eq!(p.deadline(None, now), None);
        let mut slow = Pacer::new(Replay::Rate(1e-3));
        slow.deadline(None, now);
        assert_eq!(
            slow.deadline(None, now).unwrap() - now,
            Duration::from_secs(1000)
        );
        let mut fast = Pacer::new(Replay::Rate(1e6));
        fast.deadline(None, now);
        assert_eq!(
            fast.deadline(None, now).unwrap() - now,
            Duration::from_micros(1)
        );
        assert_eq!(Pacer::new(Replay::Fast).deadline(Some(1.0), now), None);
    }
}
