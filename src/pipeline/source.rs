//! Sources: threads that read NDJSON lines from a file (paced), standard input or TCP
//! clients, and hand them to the ingest stage untouched. Parsing happens in the ingest
//! stage, so a malformed line becomes an error record in its place in the stream.

use std::io::{BufRead, BufReader, ErrorKind};
use std::net::{SocketAddr, TcpListener};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_channel::Sender;

use super::config::Replay;
use crate::error::{Error, Result};

/// One line as read, with where it came from.
#[derive(Debug)]
pub struct Line {
    /// The source, for messages: a path, `stdin` or `tcp PEER`.
    pub origin: Arc<str>,
    /// Stream id for frames that carry none (a TCP client's address); `None` keeps them
    /// unnamed.
    pub default_stream: Option<Arc<str>>,
    /// 1-based line number within the source.
    pub line: usize,
    /// The text, or why it could not be read (e.g. invalid UTF-8).
    pub text: std::result::Result<String, String>,
    /// When it was read.
    pub arrived: Instant,
}

/// Reads `reader` line by line into `tx` until end of input, `stop`, or a closed channel.
/// A reader with a read timeout (TCP) wakes up every timeout to look at `stop`; a partial
/// line survives the wake-up.
fn pump(
    mut reader: impl BufRead,
    origin: Arc<str>,
    default_stream: Option<Arc<str>>,
    tx: &Sender<Line>,
    stop: &AtomicBool,
    mut pace: impl FnMut(&str, &AtomicBool),
) {
    let mut buf = Vec::new();
    let mut line = 0;
    while !stop.load(Ordering::Relaxed) {
        match reader.read_until(b'\n', &mut buf) {
            Ok(0) => break,
            Ok(_) => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => continue,
            Err(e) if e.kind() == ErrorKind::Interrupted => continue,
            Err(e) => {
                tracing::warn!(%origin, error = %e, "read failed; source closed");
                break;
            }
        }
        line += 1;
        let bytes = std::mem::take(&mut buf);
        if bytes.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let text = String::from_utf8(bytes)
            .map(|s| s.trim_end().to_string())
            .map_err(|_| "the line is not valid UTF-8".to_string());
        if let Ok(t) = &text {
            pace(t, stop);
        }
        let sent = tx.send(Line {
            origin: origin.clone(),
            default_stream: default_stream.clone(),
            line,
            text,
            arrived: Instant::now(),
        });
        if sent.is_err() {
            break;
        }
    }
}

/// Sleeps until `deadline`, waking every 20 ms to look at `stop`.
fn sleep_until(deadline: Instant, stop: &AtomicBool) {
    loop {
        let now = Instant::now();
        if now >= deadline || stop.load(Ordering::Relaxed) {
            return;
        }
        std::thread::sleep((deadline - now).min(Duration::from_millis(20)));
    }
}

/// Replays an NDJSON frame file at `replay`'s pace.
pub fn spawn_file(
    path: &Path,
    replay: Replay,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
) -> Result<JoinHandle<()>> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let origin: Arc<str> = path.display().to_string().into();
    #[derive(serde::Deserialize)]
    struct Stamp {
        t: Option<f64>,
    }
    let start = Instant::now();
    let mut first_t: Option<f64> = None;
    let mut n = 0u32;
    let pace = move |text: &str, stop: &AtomicBool| {
        let deadline = match replay {
            Replay::Fast => return,
            Replay::Rate(fps) => start + Duration::from_secs_f64(f64::from(n) / fps),
            Replay::Recorded => {
                // Only the time stamp is read here; the frame is parsed once, by ingest.
                let Some(t) = serde_json::from_str::<Stamp>(text).ok().and_then(|s| s.t) else {
                    return;
                };
                let t0 = *first_t.get_or_insert(t);
                start + Duration::from_secs_f64((t - t0).max(0.0))
            }
        };
        n += 1;
        sleep_until(deadline, stop);
    };
    spawn("source-file", move || {
        pump(BufReader::new(file), origin, None, &tx, &stop, pace)
    })
}

/// Reads frames from standard input as they come.
pub fn spawn_stdin(tx: Sender<Line>, stop: Arc<AtomicBool>) -> Result<JoinHandle<()>> {
    spawn("source-stdin", move || {
        let stdin = std::io::stdin();
        pump(stdin.lock(), "stdin".into(), None, &tx, &stop, |_, _| {})
    })
}

/// Listens on `bind` and reads frames from every client, each in its own thread; a
/// client's frames without a stream id get the stream `tcp:PEER`. Returns the bound
/// address (useful with port 0) and the listener thread.
pub fn spawn_tcp(
    bind: SocketAddr,
    tx: Sender<Line>,
    stop: Arc<AtomicBool>,
    poll: Duration,
) -> Result<(SocketAddr, JoinHandle<()>)> {
    let listener = TcpListener::bind(bind).map_err(|e| Error::Io {
        path: format!("tcp {bind}").into(),
        source: e,
    })?;
    let addr = listener.local_addr().map_err(|e| Error::Io {
        path: format!("tcp {bind}").into(),
        source: e,
    })?;
    listener.set_nonblocking(true).map_err(|e| Error::Io {
        path: format!("tcp {bind}").into(),
        source: e,
    })?;
    tracing::info!(%addr, "listening");
    let handle = spawn("source-tcp", move || {
        let mut clients = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            match listener.accept() {
                Ok((conn, peer)) => {
                    tracing::info!(%peer, "client connected");
                    // Accepted sockets may inherit non-blocking mode; reads use a timeout
                    // instead, to look at `stop` between lines.
                    let ok = conn.set_nonblocking(false).is_ok()
                        && conn.set_read_timeout(Some(poll)).is_ok();
                    if !ok {
                        tracing::warn!(%peer, "could not configure the connection; dropped");
                        continue;
                    }
                    let (tx, stop) = (tx.clone(), stop.clone());
                    let origin: Arc<str> = format!("tcp {peer}").into();
                    let stream: Arc<str> = format!("tcp:{peer}").into();
                    let name = "source-tcp-client";
                    match spawn(name, move || {
                        pump(
                            BufReader::new(conn),
                            origin,
                            Some(stream),
                            &tx,
                            &stop,
                            |_, _| {},
                        );
                        tracing::info!(%peer, "client disconnected");
                    }) {
                        Ok(h) => clients.push(h),
                        Err(e) => tracing::warn!(%peer, error = %e, "no thread for the client"),
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => {
                    std::thread::sleep(poll.min(Duration::from_millis(20)))
                }
                Err(e) => {
                    tracing::warn!(error = %e, "accept failed");
                    std::thread::sleep(poll);
                }
            }
        }
        for c in clients {
            let _ = c.join();
        }
    })?;
    Ok((addr, handle))
}

fn spawn(name: &str, f: impl FnOnce() + Send + 'static) -> Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(f)
        .map_err(|e| Error::Internal(format!("cannot start thread {name}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_numbered_blank_ones_skipped_and_a_last_line_kept() {
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(false);
        let text: &[u8] = b"a\n\n  \nb\xff\nc";
        pump(text, "t".into(), None, &tx, &stop, |_, _| {});
        drop(tx);
        let got: Vec<(usize, std::result::Result<String, String>)> =
            rx.iter().map(|l| (l.line, l.text)).collect();
        assert_eq!(got.len(), 3);
        assert_eq!(got[0], (1, Ok("a".into())));
        assert_eq!(got[1].0, 4);
        assert!(got[1].1.as_ref().unwrap_err().contains("UTF-8"));
        assert_eq!(got[2], (5, Ok("c".into())));
    }

    #[test]
    fn a_stopped_source_reads_nothing_more() {
        let (tx, rx) = crossbeam_channel::unbounded();
        let stop = AtomicBool::new(true);
        pump("a\nb\n".as_bytes(), "t".into(), None, &tx, &stop, |_, _| {});
        drop(tx);
        assert_eq!(rx.iter().count(), 0);
    }
}
