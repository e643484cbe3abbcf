//! The sinks. NDJSON: whole records or nothing. A record is serialized first and written
//! with one call; if that fails (a full disk), the file is cut back to its last whole
//! record, so that a reader never meets half a line. MCAP (an output path ending in
//! `.mcap`): the records with curves, points and poses for Foxglove
//! ([`isoline_io::foxglove`]), complete once the run ends. Kafka: each record as a
//! message keyed by its stream, in order per stream ([`super::kafka`]).
//!
//! A Kafka frame's offset may be committed once its record is written: at once for a
//! file, on the broker's acknowledgement for Kafka.

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use serde::Deserialize;

#[cfg(feature = "kafka")]
use super::kafka::{KafkaTopic, KafkaWriter};
#[cfg(feature = "kafka")]
use std::sync::Arc;

use super::ledger::Receipt;
use super::metrics::{Counted, Metrics};
use crate::error::{Error, Result};
use isoline_io::format::ResultRecord;
use isoline_io::foxglove::{FrameView, McapOut};

/// `[output] kind = "file"` (the default): NDJSON records to a file or standard output,
/// or an MCAP file for Foxglove when the path ends in `.mcap`.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileOutput {
    /// The results, relative to the configuration file's folder; `"-"` or unset:
    /// standard output.
    pub path: Option<PathBuf>,
    /// A folder for one SVG drawing per frame.
    pub svg_dir: Option<PathBuf>,
}

/// A writer that can be cut back to a length.
pub(crate) trait Truncate: Write {
    /// Drops everything after the first `len` bytes and writes from there on.
    fn truncate(&mut self, len: u64) -> std::io::Result<()>;
}

impl Truncate for File {
    fn truncate(&mut self, len: u64) -> std::io::Result<()> {
        self.set_len(len)?;
        self.seek(SeekFrom::Start(len)).map(|_| ())
    }
}

/// Where the daemon's records go.
pub(crate) enum Sink {
    /// A file, created (truncated) at start; `len` is the end of the last whole record.
    File {
        out: Box<dyn Truncate + Send>,
        path: PathBuf,
        len: u64,
    },
    /// Standard output: a pipe cannot be cut back, so a failed write ends the run.
    Stdout(std::io::Stdout),
    /// An MCAP file for Foxglove.
    Mcap(Box<McapOut>),
    /// A Kafka topic.
    #[cfg(feature = "kafka")]
    Kafka(Box<KafkaWriter>),
}

impl Sink {
    /// Opens a Kafka topic's writer.
    #[cfg(feature = "kafka")]
    pub(crate) fn kafka(topic: &KafkaTopic, metrics: Arc<Metrics>) -> Result<Sink> {
        Ok(Sink::Kafka(Box::new(KafkaWriter::open_with(
            topic,
            Some(metrics),
        )?)))
    }

    /// Opens the output: `path`, its folder created, or standard output.
    pub(crate) fn open(path: Option<&Path>) -> Result<Sink> {
        let Some(p) = path else {
            return Ok(Sink::Stdout(std::io::stdout()));
        };
        if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| isoline_io::Error::io(dir, e))?;
        }
        if isoline_io::is_bag(p) {
            return Ok(Sink::Mcap(Box::new(McapOut::create(p)?)));
        }
        let file = File::create(p).map_err(|e| isoline_io::Error::io(p, e))?;
        Ok(Sink::File {
            out: Box::new(file),
            path: p.to_path_buf(),
            len: 0,
        })
    }

    /// Whether the sink wants each frame's points and pose beside its record.
    pub(crate) fn wants_frames(&self) -> bool {
        matches!(self, Sink::Mcap(_))
    }

    /// Writes one frame: its record (NDJSON, Kafka), or its record, curves and points
    /// (MCAP); `receipt` is handed in and `tally` counted in `metrics` once the record
    /// is written (for Kafka: acknowledged).
    pub(crate) fn write_frame(
        &mut self,
        view: &FrameView,
        receipt: Option<Receipt>,
        tally: Counted,
        metrics: &Metrics,
    ) -> Result<()> {
        match self {
            #[cfg(feature = "kafka")]
            Sink::Kafka(k) => {
                let payload =
                    serde_json::to_vec(&view.record).map_err(|e| Error::Internal(e.to_string()))?;
                let key = view.record.stream.as_deref().unwrap_or("");
                return k.send_with(key, &payload, receipt, Some(tally));
            }
            Sink::Mcap(m) => m.write(view)?,
            _ => self.write_record(&view.record)?,
        }
        if let Some(r) = receipt {
            r.done();
        }
        tally.count(metrics);
        Ok(())
    }

    /// Completes the output: an MCAP file's summary, Kafka's last acknowledgements.
    pub(crate) fn finish(self) -> Result<()> {
        match self {
            Sink::Mcap(m) => Ok(m.finish()?),
            #[cfg(feature = "kafka")]
            Sink::Kafka(k) => k.finish(),
            _ => Ok(()),
        }
    }

    /// Writes one record as one line and flushes it.
    pub(crate) fn write_record(&mut self, rec: &ResultRecord) -> Result<()> {
        let mut line = serde_json::to_vec(rec).map_err(|e| Error::Internal(e.to_string()))?;
        line.push(b'\n');
        match self {
            #[cfg(feature = "kafka")]
            Sink::Kafka(k) => {
                // One record a message, without the line's end.
                let payload = &line[..line.len() - 1];
                k.send_with(rec.stream.as_deref().unwrap_or(""), payload, None, None)
            }
            Sink::Mcap(m) => Ok(m.write(&FrameView {
                record: rec.clone(),
                ..Default::default()
            })?),
            Sink::Stdout(out) => {
                let mut out = out.lock();
                out.write_all(&line)
                    .and_then(|()| out.flush())
                    .map_err(|e| isoline_io::Error::io(Path::new("standard output"), e).into())
            }
            Sink::File { out, path, len } => {
                match out.write_all(&line).and_then(|()| out.flush()) {
                    Ok(()) => {
                        *len += line.len() as u64;
                        Ok(())
                    }
                    Err(e) => {
                        if let Err(t) = out.truncate(*len) {
                            tracing::error!(path = %path.display(), error = %t,
                                "could not cut the output back to its last whole record");
                        }
                        Err(isoline_io::Error::io(path.clone(), e).into())
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    /// A disk with `room` bytes, shared so the test can read it afterwards.
    #[derive(Clone)]
    struct Disk {
        data: Arc<Mutex<Vec<u8>>>,
        room: usize,
    }

    impl Write for Disk {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            let mut d = self.data.lock().unwrap();
            let n = buf.len().min(self.room.saturating_sub(d.len()));
            if n == 0 && !buf.is_empty() {
                return Err(std::io::Error::from_raw_os_error(28)); // ENOSPC
            }
            d.extend_from_slice(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Truncate for Disk {
        fn truncate(&mut self, len: u64) -> std::io::Result<()> {
            self.data.lock().unwrap().truncate(len as usize);
            Ok(())
        }
    }

    #[test]
    fn a_full_disk_leaves_whole_records_only() {
        let disk = Disk {
            data: Arc::default(),
            room: 100,
        };
        let mut sink = Sink::File {
            out: Box::new(disk.clone()),
            path: "out.ndjson".into(),
            len: 0,
        };
        let rec = |frame| ResultRecord {
            stream: Some("s".into()),
            frame: Some(frame),
            error: Some("x".repeat(10)),
            ..Default::default()
        };
        let mut written = 0;
        let err = loop {
            match sink.write_record(&rec(written)) {
                Ok(()) => written += 1,
                Err(e) => break e,
            }
        };
        assert!(err.to_string().contains("out.ndjson"), "{err}");
        assert!(written >= 1);
        let text = String::from_utf8(disk.data.lock().unwrap().clone()).unwrap();
        assert!(text.ends_with('\n'));
        let lines: Vec<ResultRecord> = text
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len() as u64, written);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn dev_full_is_an_error_not_a_silent_loss() {
        let mut sink = Sink::open(Some(Path::new("/dev/full"))).unwrap();
        let e = sink.write_record(&ResultRecord::default()).unwrap_err();
        assert!(e.to_string().contains("/dev/full"), "{e}");
    }
}
