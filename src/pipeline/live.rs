//! The live view: a Foxglove WebSocket server (the ws-protocol of the Foxglove app,
//! Foxglove Studio and Lichtblick) showing each frame's curves as they are made.
//!
//! The server is ours, on `tungstenite`, so that every bound holds: at most
//! [`MAX_VIEWERS`] viewers, each with at most [`VIEWER_BACKLOG_BYTES`] of messages
//! waiting (its oldest dropped beyond that) plus [`VIEWER_WRITE_BUFFER`] in the socket's
//! buffer, request heads and client messages of bounded size, and an accept loop that
//! survives running out of descriptors (`listen`). It speaks only what a viewer needs:
//! `serverInfo`, `advertise` of the four topics, `subscribe`, `unsubscribe` and binary
//! message data; both subprotocols viewers offer, `foxglove.sdk.v1` (the Foxglove app)
//! and `foxglove.websocket.v1` (Foxglove Studio, Lichtblick, ws-protocol clients).

use std::collections::{BTreeMap, VecDeque};
use std::io::ErrorKind;
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use base64::Engine;
use crossbeam_channel::{Receiver, Sender};
use isoline_io::foxglove::{frame_messages, FrameView, Topic};
use serde_json::{json, Value};
use tungstenite::protocol::{Role, WebSocketConfig};
use tungstenite::{Message, WebSocket};

use crate::error::{Error, Result};
use crate::pipeline::listen::{read_head_or_answer, respond, Bounds, Server, Throttle};

/// How many frames the live view holds for its thread at most; the pipeline never waits
/// for it (a frame that finds the queue full is not shown).
pub const LIVE_QUEUE: usize = 16;

/// Viewers served at once; more are answered `503`.
pub const MAX_VIEWERS: usize = 16;

/// Bytes of messages a viewer may fall behind by before its oldest are dropped.
pub const VIEWER_BACKLOG_BYTES: usize = 4 << 20;

/// Bytes the WebSocket may hold for a viewer's socket beyond what the kernel takes.
pub const VIEWER_WRITE_BUFFER: usize = 1 << 20;

/// The largest message a viewer may send (subscriptions are a few hundred bytes).
pub const MAX_CLIENT_MESSAGE: usize = 64 << 10;

/// The most subscriptions a viewer may hold (there are four channels).
pub const MAX_SUBSCRIPTIONS: usize = 64;

/// Streams whose newest frame is kept for viewers that connect later.
pub const LATCHED_STREAMS: usize = 64;

/// The subprotocols a viewer may offer, the first offered of them chosen.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.sdk.v1", "foxglove.websocket.v1"];

/// How often a viewer's thread looks for messages to send, the stop flag and the
/// viewer's own messages.
const TICK: Duration = Duration::from_millis(20);

/// One message waiting for a viewer.
struct Pending {
    subscription: u32,
    nanos: u64,
    data: Arc<[u8]>,
}

/// A viewer's waiting messages, bounded in bytes.
#[derive(Default)]
struct Backlog {
    queue: VecDeque<Pending>,
    bytes: usize,
    dropped: u64,
}

impl Backlog {
    /// Queues a message, dropping the oldest while the backlog would exceed its bytes.
    fn add(&mut self, m: Pending) {
        let size = m.data.len() + 13;
        while self.bytes + size > VIEWER_BACKLOG_BYTES {
            let Some(old) = self.queue.pop_front() else {
                break;
            };
            self.bytes -= old.data.len() + 13;
            self.dropped += 1;
        }
        if size > VIEWER_BACKLOG_BYTES {
            self.dropped += 1;
            return;
        }
        self.bytes += size;
        self.queue.push_back(m);
    }
}

/// What the broadcaster and a viewer's thread share.
#[derive(Default)]
struct Viewer {
    /// Subscription id → channel id.
    subscriptions: Mutex<BTreeMap<u32, u32>>,
    backlog: Mutex<Backlog>,
}

impl Viewer {
    fn push(&self, channel: u32, nanos: u64, data: &Arc<[u8]>) {
        let subs: Vec<u32> = {
            let s = self.subscriptions.lock().unwrap_or_else(|p| p.into_inner());
            s.iter()
                .filter(|(_, c)| **c == channel)
                .map(|(id, _)| *id)
                .collect()
        };
        if subs.is_empty() {
            return;
        }
        let mut b = self.backlog.lock().unwrap_or_else(|p| p.into_inner());
        for subscription in subs {
            b.add(Pending {
                subscription,
                nanos,
                data: data.clone(),
            });
        }
    }

    fn take(&self) -> VecDeque<Pending> {
        let mut b = self.backlog.lock().unwrap_or_else(|p| p.into_inner());
        b.bytes = 0;
        std::mem::take(&mut b.queue)
    }
}

type Viewers = Arc<Mutex<Vec<Arc<Viewer>>>>;

/// A message and its time, nanoseconds.
type Stamped = (u64, Arc<[u8]>);

/// Each stream's newest frame, as messages by channel: what a viewer that subscribes
/// later is sent first, so that it sees the scene at once (and after a recording has
/// ended). At most [`LATCHED_STREAMS`] streams, the least recently shown leaving.
#[derive(Default)]
struct Latched {
    /// (stream, channel) → (nanos, message), and each stream's last update, by order.
    frames: BTreeMap<(String, u32), Stamped>,
    order: VecDeque<String>,
}

impl Latched {
    fn keep(&mut self, stream: &str, channel: u32, nanos: u64, data: &Arc<[u8]>) {
        if let Some(at) = self.order.iter().position(|s| s == stream) {
            self.order.remove(at);
        }
        self.order.push_back(stream.to_string());
        while self.order.len() > LATCHED_STREAMS {
            if let Some(old) = self.order.pop_front() {
                self.frames.retain(|(s, _), _| *s != old);
            }
        }
        self.frames
            .insert((stream.to_string(), channel), (nanos, data.clone()));
    }

    fn of_channel(&self, channel: u32) -> Vec<Stamped> {
        self.frames
            .iter()
            .filter(|((_, c), _)| *c == channel)
            .map(|(_, m)| m.clone())
            .collect()
    }
}

/// A Foxglove WebSocket server showing frames as they are made. Frames are handed to its
/// own thread through a short queue that never blocks ([`LiveView::show`]); a slow
/// viewer loses its oldest messages. Viewers lose messages, the pipeline nothing.
pub struct LiveView {
    tx: Option<Sender<FrameView>>,
    thread: Option<JoinHandle<()>>,
    server: Option<Server>,
    addr: SocketAddr,
}

impl LiveView {
    /// Starts serving on `bind` (port 0: any free port).
    pub fn start(bind: SocketAddr) -> Result<LiveView> {
        let advertise = Arc::new(advertise()?);
        let viewers: Viewers = Arc::default();
        let registry = viewers.clone();
        let latched: Arc<Mutex<Latched>> = Arc::default();
        let latest = latched.clone();
        let dropped = Arc::new(AtomicU64::new(0));
        let refused = Arc::new(Throttle::new());
        let bounds = Bounds {
            max_connections: MAX_VIEWERS,
        };
        let server = Server::start("live-view", bind, bounds, move |conn, peer, stop| {
            serve_viewer(conn, peer, stop, &advertise, &registry, &refused, &latest);
        })?;
        let addr = server.addr();
        let (tx, rx): (Sender<FrameView>, Receiver<FrameView>) =
            crossbeam_channel::bounded(LIVE_QUEUE);
        let thread = std::thread::Builder::new()
            .name("live-view".into())
            .spawn(move || broadcast(&rx, &viewers, &dropped, &latched))
            .map_err(|e| Error::Internal(format!("live view thread: {e}")))?;
        tracing::info!(%addr, "live view (Foxglove WebSocket) listening");
        Ok(LiveView {
            tx: Some(tx),
            thread: Some(thread),
            server: Some(server),
            addr,
        })
    }

    /// The address served.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Hands a frame to the viewers, or drops it if the view is behind; whether it was
    /// handed over.
    pub fn show(&self, view: FrameView) -> bool {
        self.tx.as_ref().is_some_and(|tx| tx.try_send(view).is_ok())
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        self.tx.take();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        // Stops accepting, then waits for the viewers' threads, which watch the flag.
        self.server.take();
    }
}

/// The channel id of a topic: its place in [`Topic::ALL`], from 1.
fn channel_id(topic: Topic) -> u32 {
    Topic::ALL.iter().position(|t| *t == topic).unwrap_or(0) as u32 + 1
}

/// The `advertise` message of the four topics.
fn advertise() -> Result<String> {
    let mut channels = Vec::new();
    for topic in Topic::ALL {
        let (schema, encoding) = topic.schema();
        let data = if schema.encoding == "protobuf" {
            base64::engine::general_purpose::STANDARD.encode(&schema.data)
        } else {
            String::from_utf8(schema.data.to_vec())
                .map_err(|e| Error::Internal(format!("live view schema: {e}")))?
        };
        channels.push(json!({
            "id": channel_id(topic),
            "topic": topic.name(),
            "encoding": encoding,
            "schemaName": schema.name,
            "schemaEncoding": schema.encoding,
            "schema": data,
        }));
    }
    Ok(json!({"op": "advertise", "channels": channels}).to_string())
}

/// The live view's thread: encodes each frame once and queues it for every viewer
/// subscribed to its channels.
fn broadcast(
    rx: &Receiver<FrameView>,
    viewers: &Viewers,
    dropped: &AtomicU64,
    latched: &Mutex<Latched>,
) {
    for view in rx {
        let _s = tracing::info_span!(
            "live-view",
            stream = view.frame_id(),
            frame = view.record.frame
        )
        .entered();
        let all: Vec<Arc<Viewer>> = viewers.lock().unwrap_or_else(|p| p.into_inner()).clone();
        let nanos = view.nanos();
        for (topic, data) in frame_messages(&view) {
            let data: Arc<[u8]> = data.into();
            latched.lock().unwrap_or_else(|p| p.into_inner()).keep(
                view.frame_id(),
                channel_id(topic),
                nanos,
                &data,
            );
            for v in &all {
                v.push(channel_id(topic), nanos, &data);
            }
        }
        let lost: u64 = all
            .iter()
            .map(|v| {
                std::mem::take(&mut v.backlog.lock().unwrap_or_else(|p| p.into_inner()).dropped)
            })
            .sum();
        if lost > 0 {
            dropped.fetch_add(lost, Ordering::Relaxed);
            tracing::debug!(lost, "slow viewers: oldest messages dropped");
        }
    }
}

/// Serves one connection: the WebSocket handshake, then the viewer until it leaves or
/// the server stops.
fn serve_viewer(
    mut conn: TcpStream,
    peer: SocketAddr,
    stop: &AtomicBool,
    advertise: &str,
    viewers: &Viewers,
    refused: &Throttle,
    latched: &Mutex<Latched>,
) {
    let Some(head) = read_head_or_answer(&mut conn) else {
        return;
    };
    let offered: Vec<&str> = head.values("sec-websocket-protocol").collect();
    let chosen: Option<&'static str> = offered
        .iter()
        .find_map(|p| SUBPROTOCOLS.iter().find(|s| *s == p))
        .copied();
    let key = head.values("sec-websocket-key").next().map(str::to_string);
    let (Some(protocol), Some(key), true) = (chosen, key, head.has_token("upgrade", "websocket"))
    else {
        let why = if head.has_token("upgrade", "websocket") {
            format!(
                "no Foxglove subprotocol offered (offered: {}; expected one of: {})",
                if offered.is_empty() {
                    "none".to_string()
                } else {
                    offered.join(", ")
                },
                SUBPROTOCOLS.join(", ")
            )
        } else {
            "not a WebSocket upgrade: connect a Foxglove viewer (docs/formats.md)".to_string()
        };
        refused
            .warn(|skipped| tracing::warn!(%peer, skipped, "live view handshake refused: {why}"));
        return respond(conn, 400, "text/plain", format!("{why}\n").as_bytes());
    };
    let accept = tungstenite::handshake::derive_accept_key(key.as_bytes());
    let response = format!(
        "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Accept: {accept}\r\nSec-WebSocket-Protocol: {protocol}\r\n\r\n"
    );
    let _ = conn.set_write_timeout(Some(Duration::from_secs(5)));
    if std::io::Write::write_all(&mut conn, response.as_bytes()).is_err()
        || conn.set_read_timeout(Some(TICK)).is_err()
        || conn.set_write_timeout(Some(TICK)).is_err()
    {
        return;
    }
    let config = WebSocketConfig::default()
        .max_message_size(Some(MAX_CLIENT_MESSAGE))
        .max_frame_size(Some(MAX_CLIENT_MESSAGE))
        .max_write_buffer_size(VIEWER_WRITE_BUFFER);
    drop(offered);
    let mut ws = WebSocket::from_partially_read(conn, head.rest, Role::Server, Some(config));
    tracing::info!(%peer, protocol, "viewer connected");
    let viewer = Arc::new(Viewer::default());
    let info = json!({
        "op": "serverInfo",
        "name": "isoline",
        "capabilities": [],
        "metadata": {},
        "sessionId": format!("{}", std::process::id()),
    });
    let hello = ws
        .send(Message::text(info.to_string()))
        .and_then(|()| ws.send(Message::text(advertise.to_string())));
    if hello.is_err() {
        return;
    }
    viewers
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .push(viewer.clone());
    let why = run_viewer(&mut ws, &viewer, stop, latched);
    viewers
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .retain(|v| !Arc::ptr_eq(v, &viewer));
    tracing::info!(%peer, why, "viewer left");
}

/// A connected viewer's loop; why it ended.
fn run_viewer(
    ws: &mut WebSocket<TcpStream>,
    viewer: &Viewer,
    stop: &AtomicBool,
    latched: &Mutex<Latched>,
) -> &'static str {
    let mut unknown_warned = false;
    while !stop.load(Ordering::Relaxed) {
        match ws.read() {
            Ok(Message::Text(t)) => {
                let before: Vec<u32> = subscribed(viewer);
                if let Some(status) = handle_request(&t, viewer, &mut unknown_warned) {
                    let _ = ws.write(Message::text(status));
                }
                // A new subscription starts with the latest frame of each stream.
                let subs = viewer
                    .subscriptions
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .clone();
                let mut b = viewer.backlog.lock().unwrap_or_else(|p| p.into_inner());
                let latched = latched.lock().unwrap_or_else(|p| p.into_inner());
                for (id, channel) in subs.iter().filter(|(id, _)| !before.contains(id)) {
                    for (nanos, data) in latched.of_channel(*channel) {
                        b.add(Pending {
                            subscription: *id,
                            nanos,
                            data,
                        });
                    }
                }
            }
            Ok(Message::Close(_)) => return "closed",
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(tungstenite::Error::Capacity(_)) => return "sent a message too large",
            Err(_) => return "gone",
        }
        for m in viewer.take() {
            let mut frame = Vec::with_capacity(13 + m.data.len());
            frame.push(1u8);
            frame.extend_from_slice(&m.subscription.to_le_bytes());
            frame.extend_from_slice(&m.nanos.to_le_bytes());
            frame.extend_from_slice(&m.data);
            match ws.write(Message::binary(frame)) {
                Ok(()) => {}
                // The socket's buffer is full: this viewer reads slower than frames
                // come; what does not fit is dropped, as the backlog's oldest are.
                Err(tungstenite::Error::WriteBufferFull(_)) => break,
                Err(tungstenite::Error::Io(e))
                    if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
                Err(_) => return "gone",
            }
        }
        match ws.flush() {
            Ok(()) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return "gone",
        }
    }
    let _ = ws.close(None);
    let _ = ws.flush();
    "the run ended"
}

/// The viewer's subscription ids.
fn subscribed(viewer: &Viewer) -> Vec<u32> {
    viewer
        .subscriptions
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .keys()
        .copied()
        .collect()
}

/// Applies a viewer's `subscribe` or `unsubscribe`; a `status` message to send back when
/// something in it was refused (one per request, however many entries it names).
fn handle_request(text: &str, viewer: &Viewer, unknown_warned: &mut bool) -> Option<String> {
    let status =
        |message: String| Some(json!({"op": "status", "level": 1, "message": message}).to_string());
    let Ok(v) = serde_json::from_str::<Value>(text) else {
        return status("not JSON".into());
    };
    let mut subs = viewer
        .subscriptions
        .lock()
        .unwrap_or_else(|p| p.into_inner());
    match v["op"].as_str() {
        Some("subscribe") => {
            let (mut unknown, mut over) = (0usize, 0usize);
            for s in v["subscriptions"].as_array().into_iter().flatten() {
                let (Some(id), Some(ch)) = (s["id"].as_u64(), s["channelId"].as_u64()) else {
                    unknown += 1;
                    continue;
                };
                if !(1..=Topic::ALL.len() as u64).contains(&ch) || id > u64::from(u32::MAX) {
                    unknown += 1;
                } else if subs.len() >= MAX_SUBSCRIPTIONS && !subs.contains_key(&(id as u32)) {
                    over += 1;
                } else {
                    subs.insert(id as u32, ch as u32);
                }
            }
            if unknown + over == 0 {
                return None;
            }
            if !*unknown_warned {
                *unknown_warned = true;
                tracing::debug!(unknown, over, "viewer subscriptions refused");
            }
            status(format!(
                "{unknown} subscriptions name no advertised channel; {over} over the limit of \
                 {MAX_SUBSCRIPTIONS}"
            ))
        }
        Some("unsubscribe") => {
            for id in v["subscriptionIds"].as_array().into_iter().flatten() {
                if let Some(id) = id.as_u64() {
                    subs.remove(&(id as u32));
                }
            }
            None
        }
        Some(op) => status(format!(
            "unsupported op {:?}",
            op.chars().take(40).collect::<String>()
        )),
        None => status("no op".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A viewer that never reads holds at most its byte budget, whatever the number of
    /// messages: the oldest leave, counted.
    #[test]
    fn a_stalled_viewers_backlog_is_bounded_in_bytes() {
        let v = Viewer::default();
        v.subscriptions.lock().unwrap().insert(7, 1);
        let data: Arc<[u8]> = vec![0u8; 100_000].into();
        for k in 0..200 {
            v.push(1, k, &data);
            // A channel the viewer did not subscribe to costs it nothing.
            v.push(2, k, &data);
        }
        let b = v.backlog.lock().unwrap();
        assert!(b.bytes <= VIEWER_BACKLOG_BYTES);
        assert_eq!(b.queue.len(), VIEWER_BACKLOG_BYTES / 100_013);
        assert_eq!(b.dropped as usize, 200 - b.queue.len());
        assert!(b.queue.iter().all(|m| m.subscription == 7));
        assert_eq!(b.queue.back().unwrap().nanos, 199);
    }

    #[test]
    fn subscriptions_are_bounded_and_one_status_answers_a_request() {
        let v = Viewer::default();
        let mut warned = false;
        let subs: Vec<Value> = (0..100)
            .map(|i| json!({"id": i, "channelId": 1 + i % 4}))
            .chain((0..50).map(|i| json!({"id": 1000 + i, "channelId": 99})))
            .collect();
        let req = json!({"op": "subscribe", "subscriptions": subs}).to_string();
        let status = handle_request(&req, &v, &mut warned).unwrap();
        assert!(status.contains("50 subscriptions name no advertised channel"));
        assert!(status.contains("36 over the limit"), "{status}");
        assert_eq!(v.subscriptions.lock().unwrap().len(), MAX_SUBSCRIPTIONS);
        let req = json!({"op": "unsubscribe", "subscriptionIds": [0, 1, 2]}).to_string();
        assert!(handle_request(&req, &v, &mut warned).is_none());
        assert_eq!(v.subscriptions.lock().unwrap().len(), MAX_SUBSCRIPTIONS - 3);
    }
}
