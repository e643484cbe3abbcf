//! What the daemon's HTTP listeners (metrics, live view) share: an accept loop that
//! holds at most a fixed number of connections and survives running out of descriptors,
//! a request head read under a byte, header-count and time bound, and warnings that
//! cannot flood the log.
//!
//! Written by hand rather than taken from an HTTP server crate: the daemon answers two
//! GET routes and one WebSocket upgrade, and every bound below has to hold against a
//! client that lies (a declared body of 100 TB, a header line of 512 MiB, ten thousand
//! idle connections). The small servers we tried allocate what the client declares.

use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::error::{Error, Result};

/// The most bytes a request head (request line and headers) may take.
pub const MAX_HEAD_BYTES: usize = 8 << 10;
/// The most headers a request may carry.
pub const MAX_HEADERS: usize = 32;
/// How long a client has to send its whole request head.
pub const HEAD_TIMEOUT: Duration = Duration::from_secs(5);

/// How often an idle accept loop looks at its stop flag.
const POLL: Duration = Duration::from_millis(10);
/// The longest an accept loop waits after running out of descriptors.
const MAX_BACKOFF: Duration = Duration::from_secs(1);

/// A listener's bounds.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    /// Connections served at once; more are answered `503` and closed.
    pub max_connections: usize,
}

/// Warnings of one kind, logged at most once a period (a second by default) with the
/// number left out.
pub struct Throttle {
    state: Mutex<(Option<Instant>, u64)>,
    period: Duration,
}

impl Throttle {
    /// A throttle that has logged nothing yet, one warning a second.
    pub const fn new() -> Throttle {
        Throttle::every(Duration::from_secs(1))
    }

    /// A throttle that logs at most one warning each `period`.
    pub const fn every(period: Duration) -> Throttle {
        Throttle {
            state: Mutex::new((None, 0)),
            period,
        }
    }

    /// Calls `log` with the count of warnings left out since the last one, unless one
    /// was logged less than a period ago.
    pub fn warn(&self, log: impl FnOnce(u64)) {
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let now = Instant::now();
        if s.0.is_some_and(|t| now.duration_since(t) < self.period) {
            s.1 += 1;
            return;
        }
        let skipped = std::mem::take(&mut s.1);
        s.0 = Some(now);
        drop(s);
        log(skipped);
    }
}

impl Default for Throttle {
    fn default() -> Self {
        Throttle::new()
    }
}

/// A running accept loop; stops (and waits for its connections) when dropped.
pub struct Server {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    addr: SocketAddr,
}

impl Server {
    /// Binds `bind` and hands each accepted connection to `serve` on a thread of its
    /// own, at most `bounds.max_connections` at once. `serve` gets the stop flag, which
    /// long-lived connections must watch.
    pub fn start<F>(
        name: &'static str,
        bind: SocketAddr,
        bounds: Bounds,
        serve: F,
    ) -> Result<Server>
    where
        F: Fn(TcpStream, SocketAddr, &AtomicBool) + Send + Sync + 'static,
    {
        let io = |e| isoline_io::Error::Io {
            path: format!("{name} {bind}").into(),
            source: e,
        };
        let listener = TcpListener::bind(bind).map_err(io)?;
        let addr = listener.local_addr().map_err(io)?;
        listener.set_nonblocking(true).map_err(io)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let serve = Arc::new(serve);
        let thread = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || accept_loop(name, &listener, bounds, &flag, serve))
            .map_err(|e| Error::Internal(format!("{name} thread: {e}")))?;
        Ok(Server {
            stop,
            thread: Some(thread),
            addr,
        })
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Decrements the count of open connections when a connection's thread ends, however.
struct Slot(Arc<AtomicUsize>);

impl Drop for Slot {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::AcqRel);
    }
}

fn accept_loop<F>(
    name: &'static str,
    listener: &TcpListener,
    bounds: Bounds,
    stop: &Arc<AtomicBool>,
    serve: Arc<F>,
) where
    F: Fn(TcpStream, SocketAddr, &AtomicBool) + Send + Sync + 'static,
{
    let open = Arc::new(AtomicUsize::new(0));
    let mut threads: Vec<JoinHandle<()>> = Vec::new();
    let refused = Throttle::new();
    let failed = Throttle::new();
    let mut backoff = POLL;
    while !stop.load(Ordering::Relaxed) {
        threads.retain(|t| !t.is_finished());
        let (conn, peer) = match listener.accept() {
            Ok(c) => c,
            Err(e) if e.kind() == ErrorKind::WouldBlock => {
                std::thread::sleep(POLL);
                continue;
            }
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => {
                // Out of descriptors (EMFILE, ENFILE) or memory: the connection waits in
                // the kernel's backlog; try again later, longer each time.
                failed.warn(|skipped| {
                    tracing::warn!(listener = name, error = %e, skipped, "accept failed; retrying");
                });
                std::thread::sleep(backoff);
                backoff = (backoff * 2).min(MAX_BACKOFF);
                continue;
            }
        };
        backoff = POLL;
        // Accepted sockets may inherit non-blocking mode.
        if conn.set_nonblocking(false).is_err() {
            continue;
        }
        if open.load(Ordering::Acquire) >= bounds.max_connections {
            refused.warn(|skipped| {
                tracing::warn!(listener = name, %peer, max = bounds.max_connections, skipped,
                    "too many connections: refused");
            });
            let why = format!("busy: {} connections already\n", bounds.max_connections);
            refuse(conn, 503, &why);
            continue;
        }
        open.fetch_add(1, Ordering::AcqRel);
        let slot = Slot(open.clone());
        let (serve, flag) = (serve.clone(), stop.clone());
        let spawned = std::thread::Builder::new()
            .name(format!("{name}-conn"))
            .stack_size(256 << 10)
            .spawn(move || {
                let _slot = slot;
                serve(conn, peer, &flag);
            });
        match spawned {
            Ok(t) => threads.push(t),
            Err(e) => failed.warn(|skipped| {
                tracing::warn!(listener = name, %peer, error = %e, skipped,
                    "no thread for the connection: dropped");
            }),
        }
    }
    for t in threads {
        let _ = t.join();
    }
}

/// A request's head.
#[derive(Debug)]
pub struct Head {
    /// `GET`, `HEAD`, …
    pub method: String,
    /// The path, without its query.
    pub path: String,
    /// Headers, names lower-cased.
    #[cfg_attr(not(feature = "live"), allow(dead_code))]
    pub headers: Vec<(String, String)>,
    /// Bytes read after the head (the start of a body or of WebSocket frames).
    #[cfg_attr(not(feature = "live"), allow(dead_code))]
    pub rest: Vec<u8>,
}

impl Head {
    /// A header's values, comma-separated lists split, in order.
    #[cfg_attr(not(feature = "live"), allow(dead_code))]
    pub fn values<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.headers
            .iter()
            .filter(move |(n, _)| n == name)
            .flat_map(|(_, v)| v.split(','))
            .map(str::trim)
            .filter(|v| !v.is_empty())
    }

    /// Whether a header holds a token (case-insensitive), as `Connection: Upgrade` does.
    #[cfg_attr(not(feature = "live"), allow(dead_code))]
    pub fn has_token(&self, name: &str, token: &str) -> bool {
        self.values(name).any(|v| v.eq_ignore_ascii_case(token))
    }
}

/// Why a request head was not read; each maps to the status answered.
#[derive(Debug)]
pub enum HeadError {
    /// Longer than [`MAX_HEAD_BYTES`] or more than [`MAX_HEADERS`] headers: 431.
    TooLarge,
    /// Not HTTP/1.x: 400.
    Malformed,
    /// Closed, reset or too slow: nothing to answer.
    Gone,
}

/// Reads a request head, never more than [`MAX_HEAD_BYTES`] and never longer than
/// [`HEAD_TIMEOUT`] in all (a client sending one byte a second is cut off too).
pub fn read_head(conn: &mut TcpStream) -> std::result::Result<Head, HeadError> {
    let deadline = Instant::now() + HEAD_TIMEOUT;
    let mut buf = Vec::with_capacity(1024);
    let mut chunk = [0u8; 1024];
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || conn.set_read_timeout(Some(left)).is_err() {
            return Err(HeadError::Gone);
        }
        let room = (MAX_HEAD_BYTES - buf.len()).min(chunk.len());
        let n = match conn.read(&mut chunk[..room]) {
            Ok(0) => return Err(HeadError::Gone),
            Ok(n) => n,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(_) => return Err(HeadError::Gone),
        };
        buf.extend_from_slice(&chunk[..n]);
        let mut headers = [httparse::EMPTY_HEADER; MAX_HEADERS];
        let mut req = httparse::Request::new(&mut headers);
        match req.parse(&buf) {
            Ok(httparse::Status::Complete(len)) => {
                let path = req.path.unwrap_or("/");
                return Ok(Head {
                    method: req.method.unwrap_or("").to_string(),
                    path: path.split('?').next().unwrap_or("/").to_string(),
                    headers: req
                        .headers
                        .iter()
                        .map(|h| {
                            (
                                h.name.to_ascii_lowercase(),
                                String::from_utf8_lossy(h.value).into_owned(),
                            )
                        })
                        .collect(),
                    rest: buf[len..].to_vec(),
                });
            }
            Ok(httparse::Status::Partial) if buf.len() < MAX_HEAD_BYTES => {}
            Ok(httparse::Status::Partial) | Err(httparse::Error::TooManyHeaders) => {
                return Err(HeadError::TooLarge)
            }
            Err(_) => return Err(HeadError::Malformed),
        }
    }
}

/// [`read_head`], answering a head that is too large (431) or not HTTP (400) itself;
/// `None` when there is nothing more to do with the connection.
pub fn read_head_or_answer(conn: &mut TcpStream) -> Option<Head> {
    let (status, why): (u16, &[u8]) = match read_head(conn) {
        Ok(h) => return Some(h),
        Err(HeadError::TooLarge) => (431, b"request head too large\n"),
        Err(HeadError::Malformed) => (400, b"not an HTTP request\n"),
        Err(HeadError::Gone) => return None,
    };
    if let Ok(c) = conn.try_clone() {
        respond(c, status, "text/plain", why);
    }
    None
}

/// Writes a whole response and closes the connection the way that lets the client read
/// it: the body is never read, so the unread rest of the request is drained (a bounded
/// amount, briefly) before closing, or the close would reset the connection.
pub fn respond(mut conn: TcpStream, status: u16, content_type: &str, body: &[u8]) {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        426 => "Upgrade Required",
        431 => "Request Header Fields Too Large",
        503 => "Service Unavailable",
        _ => "Error",
    };
    let head = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {content_type}\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    let _ = conn.set_write_timeout(Some(HEAD_TIMEOUT));
    let mut all = head.into_bytes();
    all.extend_from_slice(body);
    if conn.write_all(&all).is_ok() {
        let _ = conn.shutdown(Shutdown::Write);
        drain(&mut conn);
    }
}

/// Answers a connection that will not be served (too many already) without reading it
/// and without waiting: the accept loop must not slow down under a flood.
fn refuse(mut conn: TcpStream, status: u16, why: &str) {
    let _ = conn.set_nonblocking(true);
    let answer = format!(
        "HTTP/1.1 {status} Service Unavailable\r\nContent-Type: text/plain\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n{why}",
        why.len()
    );
    // A fresh socket's send buffer takes these few bytes at once.
    let _ = conn.write_all(answer.as_bytes());
    let _ = conn.shutdown(Shutdown::Write);
}

/// Reads and discards what the client still sends: at most 64 KiB, for at most 100 ms.
fn drain(conn: &mut TcpStream) {
    let deadline = Instant::now() + Duration::from_millis(100);
    let mut left = 64usize << 10;
    let mut sink = [0u8; 4096];
    while left > 0 {
        let t = deadline.saturating_duration_since(Instant::now());
        if t.is_zero() || conn.set_read_timeout(Some(t)).is_err() {
            return;
        }
        match conn.read(&mut sink) {
            Ok(0) | Err(_) => return,
            Ok(n) => left = left.saturating_sub(n),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    fn pair() -> (TcpStream, TcpStream) {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        let c = TcpStream::connect(l.local_addr().unwrap()).unwrap();
        let (s, _) = l.accept().unwrap();
        (c, s)
    }

    #[test]
    fn a_head_is_read_with_its_headers_and_what_follows() {
        let (mut c, mut s) = pair();
        c.write_all(
            b"GET /health?x=1 HTTP/1.1\r\nHost: a\r\nConnection: keep-alive, Upgrade\r\n\r\nabc",
        )
        .unwrap();
        let h = read_head(&mut s).unwrap();
        assert_eq!((h.method.as_str(), h.path.as_str()), ("GET", "/health"));
        assert!(h.has_token("connection", "upgrade"));
        assert_eq!(h.rest, b"abc");
    }

    #[test]
    fn a_head_longer_than_the_bound_is_refused_after_reading_only_the_bound() {
        let (mut c, mut s) = pair();
        let writer = std::thread::spawn(move || {
            let _ = c.write_all(b"GET / HTTP/1.1\r\nX: ");
            let line = vec![b'a'; 1 << 20];
            // The server stops reading at the bound: this write may fail, never block.
            let _ = c.set_write_timeout(Some(Duration::from_secs(2)));
            let _ = c.write_all(&line);
            c
        });
        assert!(matches!(read_head(&mut s), Err(HeadError::TooLarge)));
        drop(s);
        drop(writer.join().unwrap());
    }

    #[test]
    fn too_many_headers_are_refused() {
        let (mut c, mut s) = pair();
        let mut req = String::from("GET / HTTP/1.1\r\n");
        for i in 0..MAX_HEADERS + 1 {
            req.push_str(&format!("X-{i}: y\r\n"));
        }
        req.push_str("\r\n");
        c.write_all(req.as_bytes()).unwrap();
        assert!(matches!(read_head(&mut s), Err(HeadError::TooLarge)));
    }

    #[test]
    fn connections_over_the_bound_are_answered_503_and_the_rest_still_served() {
        let server = Server::start(
            "test",
            "127.0.0.1:0".parse().unwrap(),
            Bounds { max_connections: 2 },
            |mut conn, _, stop| {
                // Hold the connection until the client hangs up or the server stops.
                let _ = conn.set_read_timeout(Some(Duration::from_millis(20)));
                let mut b = [0u8; 16];
                while !stop.load(Ordering::Relaxed) {
                    match conn.read(&mut b) {
                        Ok(0) => return,
                        Ok(_) => {}
                        Err(e) if e.kind() == ErrorKind::WouldBlock => {}
                        Err(_) => return,
                    }
                }
            },
        )
        .unwrap();
        let held: Vec<TcpStream> = (0..2)
            .map(|_| TcpStream::connect(server.addr()).unwrap())
            .collect();
        std::thread::sleep(Duration::from_millis(100));
        let mut third = TcpStream::connect(server.addr()).unwrap();
        let mut answer = String::new();
        third.read_to_string(&mut answer).unwrap();
        assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
        drop(held);
        std::thread::sleep(Duration::from_millis(100));
        // Freed slots serve again: this one is held, not refused.
        let mut fourth = TcpStream::connect(server.addr()).unwrap();
        fourth
            .set_read_timeout(Some(Duration::from_millis(200)))
            .unwrap();
        let mut b = [0u8; 1];
        let e = fourth.read(&mut b).unwrap_err();
        assert!(matches!(
            e.kind(),
            ErrorKind::WouldBlock | ErrorKind::TimedOut
        ));
    }
}
