//! The live view: a Foxglove WebSocket server showing each frame's curves as they are
//! made, on its own thread.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::thread::JoinHandle;

use crossbeam_channel::{Receiver, Sender};
use isoline_io::foxglove::{frame_messages, FrameView, Topic};

use crate::error::{Error, Result};

/// How many frames the live view holds for its thread at most; the pipeline never waits
/// for it (a frame that finds the queue full is not shown).
pub const LIVE_QUEUE: usize = 16;

/// Messages each viewer may fall behind by before its oldest are dropped.
pub const LIVE_BACKLOG: usize = 256;

/// A Foxglove WebSocket server showing frames as they are made. Frames are handed to its
/// own thread through a short queue that never blocks ([`LiveView::show`]); the server
/// drops a slow viewer's oldest messages. Viewers lose messages, the pipeline nothing.
pub struct LiveView {
    tx: Option<Sender<FrameView>>,
    thread: Option<JoinHandle<()>>,
    addr: SocketAddr,
}

impl LiveView {
    /// Starts serving on `bind` (port 0: any free port).
    pub fn start(bind: SocketAddr) -> Result<LiveView> {
        let ctx = foxglove::Context::new();
        let server = ctx
            .websocket_server()
            .name("isoline")
            .bind(bind.ip().to_string(), bind.port())
            .message_backlog_size(LIVE_BACKLOG)
            .start_blocking()
            .map_err(|e| Error::Io {
                path: format!("live view {bind}").into(),
                source: std::io::Error::other(e.to_string()),
            })?;
        let addr = SocketAddr::new(bind.ip(), server.port());
        let mut channels = BTreeMap::new();
        for topic in Topic::ALL {
            let (schema, encoding) = topic.schema();
            let ch = ctx
                .channel_builder(topic.name())
                .schema(schema)
                .message_encoding(encoding)
                .build_raw()
                .map_err(|e| Error::Internal(format!("live view channel: {e}")))?;
            channels.insert(topic, ch);
        }
        let (tx, rx): (Sender<FrameView>, Receiver<FrameView>) =
            crossbeam_channel::bounded(LIVE_QUEUE);
        let thread = std::thread::Builder::new()
            .name("live-view".into())
            .spawn(move || {
                for view in rx {
                    let _s = tracing::info_span!(
                        "live-view",
                        stream = view.frame_id(),
                        frame = view.record.frame
                    )
                    .entered();
                    let meta = foxglove::PartialMetadata {
                        log_time: Some(view.nanos()),
                    };
                    for (topic, data) in frame_messages(&view) {
                        channels[&topic].log_with_meta(&data, meta);
                    }
                }
                let _ = server.stop();
                drop(ctx);
            })
            .map_err(|e| Error::Internal(format!("live view thread: {e}")))?;
        tracing::info!(%addr, "live view (Foxglove WebSocket) listening");
        Ok(LiveView {
            tx: Some(tx),
            thread: Some(thread),
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
    }
}
