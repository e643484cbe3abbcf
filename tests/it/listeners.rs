//! The daemon's listeners (metrics, live view) against clients that lie, hoard or flood:
//! every request answered or refused within its bounds, the daemon alive afterwards, and
//! both listeners serving again after the process ran out of descriptors.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

use serde_json::Value;

/// The daemon, its stderr lines, and the addresses of its metrics and live view.
struct Daemon {
    child: Child,
    stderr: Receiver<String>,
    metrics: String,
    live: String,
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `isoline run` on an idle TCP input with metrics and the live view, under a
/// descriptor limit of `nofile` (the shell's `ulimit -n`).
fn start(dir: &Path, nofile: u32) -> Daemon {
    let cfg = dir.join("d.toml");
    std::fs::write(
        &cfg,
        "[input]\nkind = \"tcp\"\nbind = \"127.0.0.1:0\"\n[output]\npath = \"out.ndjson\"\n\
         [metrics]\nbind = \"127.0.0.1:0\"\n[live]\nbind = \"127.0.0.1:0\"\n\
         [tracing]\nlevel = \"info\"\n",
    )
    .unwrap();
    let mut child = Command::new("sh")
        .args([
            "-c",
            &format!("ulimit -n {nofile} && exec \"$0\" run -c \"$1\""),
            env!("CARGO_BIN_EXE_isoline"),
            cfg.to_str().unwrap(),
        ])
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = child.stderr.take().unwrap();
    let (tx, stderr) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let (mut metrics, mut live) = (None, None);
    while metrics.is_none() || live.is_none() {
        let line = stderr
            .recv_timeout(Duration::from_secs(30))
            .expect("the daemon says where it listens");
        if let Some(a) = line.strip_prefix("isoline run: metrics on http://") {
            metrics = Some(a.split('/').next().unwrap().to_string());
        }
        if let Some(a) = line.strip_prefix("isoline run: live view on ws://") {
            live = Some(a.split_whitespace().next().unwrap().to_string());
        }
    }
    Daemon {
        child,
        stderr,
        metrics: metrics.unwrap(),
        live: live.unwrap(),
    }
}

/// Sends `request` raw and reads the whole answer (the server closes after it).
fn exchange(addr: &str, request: &[u8]) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    // The server may answer and close before all of a long request is written.
    let _ = s.write_all(request);
    let mut text = Vec::new();
    let _ = s.read_to_end(&mut text);
    String::from_utf8_lossy(&text).into_owned()
}

fn status(answer: &str) -> u16 {
    answer
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status in {answer:?}"))
}

fn health(d: &Daemon) -> u16 {
    status(&exchange(
        &d.metrics,
        b"GET /health HTTP/1.1\r\nHost: x\r\n\r\n",
    ))
}

/// `/health`'s status, or nothing if the endpoint does not answer.
fn try_health(addr: &str) -> Option<u16> {
    let mut s = TcpStream::connect(addr).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(2))).ok()?;
    s.write_all(b"GET /health HTTP/1.1\r\n\r\n").ok()?;
    let mut text = String::new();
    s.read_to_string(&mut text).ok()?;
    text.split_whitespace().nth(1)?.parse().ok()
}

/// A Foxglove viewer offering `protocol`: the WebSocket after `serverInfo` and
/// `advertise`, or the HTTP status of the refused handshake.
fn viewer(addr: &str, protocol: &str) -> Result<tungstenite::WebSocket<TcpStream>, u16> {
    use tungstenite::client::IntoClientRequest;
    let mut req = format!("ws://{addr}").into_client_request().unwrap();
    req.headers_mut()
        .insert("Sec-WebSocket-Protocol", protocol.parse().unwrap());
    let stream = TcpStream::connect(addr).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    match tungstenite::client(req, stream) {
        Ok((mut ws, _)) => {
            for op in ["serverInfo", "advertise"] {
                let m = ws.read().unwrap();
                let v: Value = serde_json::from_str(m.to_text().unwrap()).unwrap();
                assert_eq!(v["op"], op);
            }
            Ok(ws)
        }
        Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(r))) => {
            Err(r.status().as_u16())
        }
        Err(e) => panic!("handshake: {e}"),
    }
}

/// Lines the daemon wrote to stderr so far.
fn logged(d: &Daemon) -> Vec<String> {
    std::thread::sleep(Duration::from_millis(200));
    d.stderr.try_iter().collect()
}

#[test]
fn no_request_kills_the_daemon_and_each_listener_holds_its_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let d = start(dir.path(), 1024);

    // A body declared 100 TB long is never read, let alone allocated.
    let a = exchange(
        &d.metrics,
        b"POST /metrics HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999999999\r\n\r\nabc",
    );
    assert_eq!(status(&a), 405, "{a}");
    // A header line of 1 MiB is refused at the head bound, as is a flood of headers.
    let mut long = b"GET /metrics HTTP/1.1\r\nX-Long: ".to_vec();
    long.extend(std::iter::repeat_n(b'a', 1 << 20));
    assert_eq!(status(&exchange(&d.metrics, &long)), 431);
    let many: String = (0..200).map(|i| format!("X-{i}: y\r\n")).collect();
    let many = format!("GET /metrics HTTP/1.1\r\n{many}\r\n");
    assert_eq!(status(&exchange(&d.metrics, many.as_bytes())), 431);
    assert_eq!(status(&exchange(&d.live, &long)), 431);
    assert_eq!(health(&d), 200);

    // Idle connections beyond the bound are answered 503 at once, not held.
    let t0 = Instant::now();
    let idle: Vec<TcpStream> = (0..40)
        .map(|_| TcpStream::connect(&d.metrics).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(300));
    let mut busy = 0;
    for mut s in &idle {
        s.set_read_timeout(Some(Duration::from_millis(50))).unwrap();
        let mut b = [0u8; 12];
        if let Ok(n) = s.read(&mut b) {
            busy += usize::from(n > 0 && b.starts_with(b"HTTP/1.1 503"));
        }
    }
    assert_eq!(
        busy,
        40 - 16,
        "connections over the bound of 16 answered 503"
    );
    assert!(t0.elapsed() < Duration::from_secs(4));
    drop(idle);

    // Viewers: the 17th is refused; one offering an unknown subprotocol is told which
    // ones are expected, and the refusal is logged with what it offered.
    let mut viewers: Vec<_> = (0..16)
        .map(|k| {
            let p = ["foxglove.sdk.v1", "foxglove.websocket.v1"][k % 2];
            viewer(&d.live, p).expect("a viewer under the bound")
        })
        .collect();
    assert_eq!(viewer(&d.live, "foxglove.sdk.v1").err(), Some(503));
    viewers.truncate(1);
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(viewer(&d.live, "ros1").err(), Some(400));
    let lines = logged(&d);
    assert!(
        lines
            .iter()
            .any(|l| l.contains("offered: ros1") && l.contains("foxglove.websocket.v1")),
        "{lines:#?}"
    );

    // One subscribe naming 10,000 unknown channels: one status back, no log flood.
    let ws = &mut viewers[0];
    let subs: Vec<Value> = (0..10_000)
        .map(|i| serde_json::json!({"id": i, "channelId": 1000 + i}))
        .collect();
    let req = serde_json::json!({"op": "subscribe", "subscriptions": subs}).to_string();
    // Over the client message bound (64 KiB): the viewer is dropped, the daemon is not.
    assert!(req.len() > 64 << 10);
    let small: Vec<Value> = (0..1000)
        .map(|i| serde_json::json!({"id": i, "channelId": 1000 + i}))
        .collect();
    let small = serde_json::json!({"op": "subscribe", "subscriptions": small}).to_string();
    ws.send(tungstenite::Message::text(small)).unwrap();
    let m = ws.read().unwrap();
    let v: Value = serde_json::from_str(m.to_text().unwrap()).unwrap();
    assert_eq!(v["op"], "status");
    assert!(v["message"]
        .as_str()
        .unwrap()
        .starts_with("1000 subscriptions"));
    ws.send(tungstenite::Message::text(req)).unwrap();
    let gone = (0..50).any(|_| ws.read().is_err());
    assert!(gone, "a 64 KiB+ client message ends the viewer");
    let lines = logged(&d);
    let about: Vec<_> = lines.iter().filter(|l| l.contains("subscri")).collect();
    assert!(about.len() <= 1, "{about:#?}");
    assert_eq!(health(&d), 200);
    assert!(d.child.id() > 0);
}

#[test]
fn listeners_serve_again_after_the_process_ran_out_of_descriptors() {
    let dir = tempfile::tempdir().unwrap();
    // About 10 descriptors at rest; 16 idle viewers' connections exhaust 24.
    let d = start(dir.path(), 24);
    let hoard: Vec<TcpStream> = (0..40)
        .filter_map(|_| TcpStream::connect(&d.live).ok())
        .collect();
    let extra: Vec<TcpStream> = (0..8)
        .filter_map(|_| TcpStream::connect(&d.metrics).ok())
        .collect();
    std::thread::sleep(Duration::from_millis(500));
    let lines = logged(&d);
    assert!(
        lines.iter().any(|l| l.contains("accept failed")),
        "the descriptor limit was reached: {lines:#?}"
    );
    drop(hoard);
    drop(extra);
    // Held connections time out within the head bound (5 s); then both listeners serve.
    let t0 = Instant::now();
    loop {
        if try_health(&d.metrics) == Some(200) {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "metrics never came back"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let t0 = Instant::now();
    while viewer(&d.live, "foxglove.sdk.v1").is_err() {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "live view never came back"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}
