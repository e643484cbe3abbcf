//! The ingest stage: readers for the input formats (point files, NDJSON frame streams,
//! ROS 2 bags in MCAP and CARMEN logs) and the validated [`Frame`] every later stage
//! takes. Every error names the source and the 1-based line, or the topic and message.

pub mod bag;
pub mod carmen;
mod deskew;
pub mod ros;

use std::io::BufRead;
use std::path::Path;

use crate::error::{Error, Result};
use crate::format::FrameRecord;
use isoline_core::geom::Point;
use isoline_core::{LaserScan, Scan, Sweep};

pub use deskew::Deskew;

/// One validated input frame: its points and, for a frame seen from a sensor, its beams.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Stream id.
    pub stream: Option<String>,
    /// The sensor's coordinate frame (a ROS header's `frame_id`), when the input says.
    pub frame_id: Option<String>,
    /// Frame number.
    pub frame: u64,
    /// Time stamp, seconds.
    pub t: Option<f64>,
    /// The points: the frame's own, or the returns of its beams.
    pub points: Vec<Point>,
    /// The sensor's view: the beams of a scanner frame, or the points seen from the
    /// frame's `origin`; `None` for points without an origin.
    pub scan: Option<Scan>,
    /// The pose of the frame's coordinates in a world frame.
    pub pose: Option<[f64; 3]>,
    /// A scanner frame's beam timing (`time_increment` 0 when the input gives none).
    pub sweep: Option<Sweep>,
    /// What the reader did to the frame's readings, for its result's warnings.
    pub notes: Vec<String>,
}

impl Frame {
    /// A scanner frame's time and beam timing when it has no pose, for registration to
    /// correct it by the motion it estimates (`isoline_map::Registrar::push_swept`);
    /// `default_time_increment` seconds between beams where the frame gives none.
    pub fn unposed_sweep(&self, default_time_increment: Option<f64>) -> Option<(f64, Sweep)> {
        match (self.pose, self.t, self.sweep, &self.scan) {
            (None, Some(t), Some(sweep), Some(_)) => {
                Some((t, sweep.or_timing(default_time_increment.unwrap_or(0.0))))
            }
            _ => None,
        }
    }

    /// The frame with `scan` for its scan (corrected for its sweep), and its points the
    /// scan's returns.
    pub fn replace_scan(&mut self, scan: Scan) {
        self.points = scan.returns();
        self.scan = Some(scan);
    }

    /// A frame of points with no sensor.
    pub fn of_points(frame: u64, points: Vec<Point>) -> Frame {
        Frame {
            frame,
            points,
            ..Default::default()
        }
    }

    /// Validates a wire record: either points or beams (ranges with `angle_min`,
    /// `angle_increment` and `range_max`), finite pose and origin.
    pub fn from_record(r: FrameRecord) -> Result<Frame> {
        if let Some(p) = r.pose {
            if !p.iter().all(|v| v.is_finite()) {
                return Err(Error::scan(format!("pose {p:?} is not finite")));
            }
        }
        if let Some(t) = r.t {
            if !t.is_finite() {
                return Err(Error::scan(format!("t = {t} is not finite")));
            }
        }
        let mut sweep = None;
        let scan = match &r.ranges {
            Some(ranges) => {
                if !r.points.is_empty() {
                    return Err(Error::scan(
                        "a frame has \"points\" or \"ranges\", not both",
                    ));
                }
                let need = |v: Option<f64>, key: &str| {
                    v.ok_or_else(|| Error::scan(format!("\"ranges\" without \"{key}\"")))
                };
                if let Some(i) = &r.intensities {
                    if i.len() != ranges.len() {
                        return Err(Error::scan(format!(
                            "{} intensities for {} ranges",
                            i.len(),
                            ranges.len()
                        )));
                    }
                }
                let time_increment = r.time_increment.unwrap_or(0.0);
                if !(time_increment.is_finite() && (0.0..=1.0).contains(&time_increment)) {
                    return Err(Error::scan(format!(
                        "time_increment = {time_increment}: must be 0 to 1 second"
                    )));
                }
                sweep = Some(Sweep {
                    angle_min: need(r.angle_min, "angle_min")?,
                    angle_increment: need(r.angle_increment, "angle_increment")?,
                    time_increment,
                });
                Some(Scan::from_laser(&LaserScan {
                    origin: r.origin.unwrap_or([0.0, 0.0]),
                    angle_min: need(r.angle_min, "angle_min")?,
                    angle_increment: need(r.angle_increment, "angle_increment")?,
                    ranges,
                    range_min: r.range_min.unwrap_or(0.0),
                    range_max: need(r.range_max, "range_max")?,
                })?)
            }
            None => {
                if r.angle_min.is_some()
                    || r.angle_increment.is_some()
                    || r.range_max.is_some()
                    || r.time_increment.is_some()
                {
                    return Err(Error::scan("beam fields without \"ranges\""));
                }
                match r.origin {
                    // Bad points are refused with their index by the distance stage.
                    Some(o) if o.iter().all(|v| v.is_finite()) => {
                        (isoline_core::validate_points(&r.points).is_ok())
                            .then(|| Scan::from_points(&r.points, o))
                    }
                    Some(o) => return Err(Error::scan(format!("origin {o:?} is not finite"))),
                    None => None,
                }
            }
        };
        let points = match (&r.ranges, &scan) {
            (Some(_), Some(s)) => s.returns(),
            _ => r.points,
        };
        Ok(Frame {
            stream: r.stream,
            frame_id: r.frame_id,
            frame: r.frame,
            t: r.t,
            points,
            scan,
            pose: r.pose,
            sweep,
            notes: r.notes.unwrap_or_default(),
        })
    }
}

/// A frame of a recording that could not be read: what its record says instead.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BadFrame {
    /// The stream it would have been in, when known.
    pub stream: Option<String>,
    /// Its frame number, when known.
    pub frame: Option<u64>,
    /// What is wrong, naming the file and the line or topic and message.
    pub message: String,
}

/// One frame of a recording, or why a message could not become one.
pub type Item = std::result::Result<Frame, BadFrame>;

/// Whether `path` names a recording (an MCAP bag or a CARMEN log) by its extension.
pub fn is_recording(path: &Path) -> bool {
    is_bag(path) || is_compressed_frame_stream(path) || carmen::is_carmen(path)
}

/// Whether `path` names gzip-compressed NDJSON frames (`.ndjson.gz`, `.jsonl.gz`): read
/// as a recording is, one frame at a time, a bad line an error in its place.
pub fn is_compressed_frame_stream(path: &Path) -> bool {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    name.ends_with(".ndjson.gz") || name.ends_with(".jsonl.gz")
}

/// Whether `path` names an MCAP file (`.mcap`).
pub fn is_bag(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()) == Some("mcap")
}

/// Reads every frame of `path` in order: a recording's messages that cannot be frames
/// are [`BadFrame`]s in their place (the others go on); a point file or NDJSON stream is
/// read as by [`read_input`], whose first bad line fails the whole.
pub fn read_items(path: &Path, bag: &bag::BagOptions) -> Result<Vec<Item>> {
    let mut items = Vec::new();
    if is_bag(path) {
        bag::read_bag(path, bag, |i| {
            items.push(i);
            true
        })?;
    } else if is_compressed_frame_stream(path) {
        each_frame_item(path, MAX_FRAME_LINE_BYTES, |i| {
            items.push(i);
            true
        })?;
    } else if carmen::is_carmen(path) {
        carmen::read_carmen(path, |i| {
            items.push(i);
            true
        })?;
    } else {
        if is_frame_stream(path) {
            items = read_frame_items(path)?;
        } else {
            items = read_input(path)?.into_iter().map(Ok).collect();
        }
    }
    Ok(items)
}

/// Parses a point file: one point a line, `x y` or `x,y` (further columns ignored),
/// `#` starts a comment, blank lines are skipped. `name` labels errors.
///
/// ```
/// let pts = isoline_io::parse_points("# scan\n0 1\n2.5,3 extra\n\n", "demo").unwrap();
/// assert_eq!(pts, vec![[0.0, 1.0], [2.5, 3.0]]);
/// ```
pub fn parse_points(text: &str, name: &str) -> Result<Vec<Point>> {
    let mut pts = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let err = |message: String| Error::Parse {
            source_name: name.to_string(),
            line: i + 1,
            message,
        };
        let mut fields = line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|f| !f.is_empty());
        let mut coord = |axis: &str| -> Result<f64> {
            let f = fields.next().ok_or_else(|| {
                err(format!(
                    "expected two coordinates, found no {axis}: '{line}'"
                ))
            })?;
            let v: f64 = f
                .parse()
                .map_err(|_| err(format!("{axis} coordinate '{f}' is not a number")))?;
            if !v.is_finite() {
                return Err(err(format!("{axis} coordinate '{f}' is not finite")));
            }
            Ok(v)
        };
        let x = coord("x")?;
        let y = coord("y")?;
        pts.push([x, y]);
    }
    if pts.is_empty() {
        return Err(Error::Parse {
            source_name: name.to_string(),
            line: text.lines().count(),
            message: "no points in the file".into(),
        });
    }
    Ok(pts)
}

/// Parses and validates one NDJSON frame line (`line` is 1-based, for the message).
pub fn parse_frame(text: &str, name: &str, line: usize) -> Result<Frame> {
    let err = |message: String| Error::Parse {
        source_name: name.to_string(),
        line,
        message,
    };
    let rec = serde_json::from_str::<FrameRecord>(text)
        .map_err(|e| err(format!("invalid frame: {e}")))?;
    let frame = rec.frame;
    Frame::from_record(rec).map_err(|e| err(format!("frame {frame}: {e}")))
}

/// The longest NDJSON line read from a file, as the daemon's `input.max_line_bytes`
/// default: a longer line is a bad frame, skipped without being held.
pub const MAX_FRAME_LINE_BYTES: usize = 16 << 20;

/// Calls `each` with every line of `reader` (1-based number, text without its end), or
/// with why a line was not read: longer than `max` bytes (skipped without being held) or
/// not UTF-8. Stops when `each` returns false; only a read error is an `Err`.
pub(crate) fn bounded_lines(
    mut reader: impl BufRead,
    path: &Path,
    max: usize,
    mut each: impl FnMut(u64, std::result::Result<&str, String>) -> bool,
) -> Result<()> {
    use std::io::Read;
    let mut buf = Vec::new();
    let mut line_no = 0u64;
    loop {
        buf.clear();
        let n = Read::take(&mut reader, max as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(path, e))?;
        if n == 0 {
            return Ok(());
        }
        line_no += 1;
        let line = if buf.len() > max && !buf.ends_with(b"\n") {
            // Skip the rest of the over-long line.
            let mut sink = Vec::new();
            loop {
                sink.clear();
                let k = Read::take(&mut reader, max as u64)
                    .read_until(b'\n', &mut sink)
                    .map_err(|e| Error::io(path, e))?;
                if k == 0 || sink.ends_with(b"\n") {
                    break;
                }
            }
            Err(format!("the line is longer than {max} bytes; skipped"))
        } else {
            std::str::from_utf8(&buf)
                .map(|t| t.trim_end_matches(['\n', '\r']))
                .map_err(|_| "the line is not valid UTF-8".to_string())
        };
        if !each(line_no, line) {
            return Ok(());
        }
    }
}

/// Every line of an NDJSON file as a frame, or as the [`BadFrame`] it could not become
/// (its stream and frame number when the line names them); blank lines are skipped.
fn read_frame_items(path: &Path) -> Result<Vec<Item>> {
    let mut out = Vec::new();
    each_frame_item(path, MAX_FRAME_LINE_BYTES, |item| {
        out.push(item);
        true
    })?;
    Ok(out)
}

/// [`read_frame_items`] one at a time, lines up to `max_line` bytes, until `each` says
/// stop.
fn each_frame_item(path: &Path, max_line: usize, mut each: impl FnMut(Item) -> bool) -> Result<()> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let name = path.display().to_string();
    let reader: Box<dyn std::io::BufRead> = if is_compressed_frame_stream(path) {
        Box::new(std::io::BufReader::new(flate2::read::MultiGzDecoder::new(
            f,
        )))
    } else {
        Box::new(std::io::BufReader::new(f))
    };
    bounded_lines(reader, path, max_line, |i, line| {
        let item = match line {
            Ok(t) if t.trim().is_empty() => return true,
            Ok(t) => parse_frame(t, &name, i as usize).map_err(|e| {
                // What the line says of itself, if it is JSON at all.
                let v: Option<serde_json::Value> = serde_json::from_str(t).ok();
                BadFrame {
                    stream: v
                        .as_ref()
                        .and_then(|v| v["stream"].as_str().map(Into::into)),
                    frame: v.as_ref().and_then(|v| v["frame"].as_u64()),
                    message: e.to_string(),
                }
            }),
            Err(why) => Err(BadFrame {
                stream: None,
                frame: None,
                message: format!("{name}, line {i}: {why}"),
            }),
        };
        each(item)
    })?;
    Ok(())
}

/// Reads a recording (bag, CARMEN log) or NDJSON frame stream one frame at a time, as
/// [`read_items`] does but holding one frame at once, until `each` returns false.
pub fn for_each_item(
    path: &Path,
    bag: &bag::BagOptions,
    each: impl FnMut(Item) -> bool,
) -> Result<()> {
    for_each_item_capped(path, bag, MAX_FRAME_LINE_BYTES, each)
}

/// [`for_each_item`] with an NDJSON stream's lines read up to `max_line` bytes (a longer
/// one is a bad frame, skipped without being held): a frame of a million points is a
/// line of about 21 MB, beyond the default [`MAX_FRAME_LINE_BYTES`].
pub fn for_each_item_capped(
    path: &Path,
    bag: &bag::BagOptions,
    max_line: usize,
    mut each: impl FnMut(Item) -> bool,
) -> Result<()> {
    if is_bag(path) {
        bag::read_bag(path, bag, each)?;
    } else if is_compressed_frame_stream(path) || is_frame_stream(path) {
        each_frame_item(path, max_line, each)?;
    } else if carmen::is_carmen(path) {
        carmen::read_carmen(path, each)?;
    } else {
        for f in read_input(path)? {
            if !each(Ok(f)) {
                break;
            }
        }
    }
    Ok(())
}

/// Reads every frame of an NDJSON file; the first bad line is an error naming it.
pub fn read_frames(path: &Path) -> Result<Vec<Frame>> {
    let f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let name = path.display().to_string();
    let mut out = Vec::new();
    for (i, line) in std::io::BufReader::new(f).lines().enumerate() {
        let line = line.map_err(|e| Error::io(path, e))?;
        if line.trim().is_empty() {
            continue;
        }
        out.push(parse_frame(&line, &name, i + 1)?);
    }
    Ok(out)
}

/// Whether a path names an NDJSON frame stream (by extension) rather than a point file.
pub fn is_frame_stream(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("ndjson" | "jsonl")
    )
}

/// The frames of a recording, failing at the first that cannot be read.
fn read_recording(path: &Path) -> Result<Vec<Frame>> {
    read_items(path, &bag::BagOptions::default())?
        .into_iter()
        .map(|i| {
            i.map_err(|b| Error::Recording {
                path: path.to_path_buf(),
                message: b.message,
            })
        })
        .collect()
}

/// Reads an input as frames: every frame of an NDJSON stream or a recording (the first
/// bad one fails the whole), or a point file as frame 0.
pub fn read_input(path: &Path) -> Result<Vec<Frame>> {
    if is_recording(path) {
        read_recording(path)
    } else if is_frame_stream(path) {
        read_frames(path)
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Ok(vec![Frame::of_points(
            0,
            parse_points(&text, &path.display().to_string())?,
        )])
    }
}

/// Reads the points of `path`: a point file, or frame `frame` (default: the first) of an
/// NDJSON stream or a recording.
pub fn read_points(path: &Path, frame: Option<u64>) -> Result<Vec<Point>> {
    if is_frame_stream(path) || is_recording(path) {
        let frames = read_input(path)?;
        let chosen = match frame {
            Some(k) => frames.into_iter().find(|f| f.frame == k),
            None => frames.into_iter().next(),
        };
        let name = path.display().to_string();
        let f = chosen.ok_or_else(|| Error::Parse {
            source_name: name,
            line: 0,
            message: match frame {
                Some(k) => format!("no frame {k} in the stream"),
                None => "the stream has no frames".into(),
            },
        })?;
        Ok(f.points)
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        parse_points(&text, &path.display().to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gzipped NDJSON frames are read as a recording: frame by frame, a bad line an
    /// error in its place, the others going on.
    #[test]
    fn compressed_frames_are_read_one_at_a_time() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("scans.ndjson.gz");
        let mut gz = flate2::write::GzEncoder::new(
            std::fs::File::create(&path).unwrap(),
            flate2::Compression::default(),
        );
        let beams = r#""angle_min":0,"angle_increment":0.1,"range_min":0.1,"range_max":10"#;
        writeln!(
            gz,
            r#"{{"frame":0,"ranges":[1,1,1],{beams},"pose":[1,2,0]}}"#
        )
        .unwrap();
        writeln!(gz, "not json").unwrap();
        writeln!(gz, r#"{{"frame":2,"ranges":[2,2,2],{beams}}}"#).unwrap();
        gz.finish().unwrap();
        assert!(is_recording(&path) && is_compressed_frame_stream(&path));
        assert!(!carmen::is_carmen(&path) || is_compressed_frame_stream(&path));
        let mut seen = Vec::new();
        for_each_item(&path, &Default::default(), |i| {
            seen.push(i.map(|f| (f.frame, f.pose.is_some())).map_err(|_| ()));
            true
        })
        .unwrap();
        assert_eq!(seen, vec![Ok((0, true)), Err(()), Ok((2, false))]);
        assert_eq!(read_items(&path, &Default::default()).unwrap().len(), 3);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse_points("0 0\n1 nan\n", "scan.xy")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("scan.xy, line 2") && e.contains("not finite"),
            "{e}"
        );
        let e = parse_points("0 0\n1\n", "s").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("no y"), "{e}");
        let e = parse_points("# only a comment\n", "s")
            .unwrap_err()
            .to_string();
        assert!(e.contains("no points"), "{e}");
        let e = parse_frame("{\"frame\":1,\"points\":[[0,", "f.ndjson", 7)
            .unwrap_err()
            .to_string();
        assert!(e.contains("f.ndjson, line 7"), "{e}");
    }

    #[test]
    fn frames_parse_with_optional_fields() {
        let f = parse_frame(r#"{"frame":3,"points":[[0,1],[2,3]]}"#, "s", 1).unwrap();
        assert_eq!((f.frame, f.points.len(), f.stream), (3, 2, None));
        let f = parse_frame(
            r#"{"stream":"l","frame":3,"t":0.1,"points":[[1,0],[0,1]],"origin":[0,0],"x":1}"#,
            "s",
            1,
        )
        .unwrap();
        let scan = f.scan.expect("points seen from an origin");
        assert_eq!(scan.origin, [0.0, 0.0]);
        assert!(!scan.free_rays && scan.ranges == vec![1.0, 1.0]);
    }

    #[test]
    fn beam_frames_become_scans_and_bad_ones_are_named() {
        let f = parse_frame(
            r#"{"frame":1,"ranges":[1.0,null,2.0,0.01,9.0],"angle_min":-0.1,"angle_increment":0.05,"range_min":0.1,"range_max":5.0,"pose":[1,2,0.5]}"#,
            "scan.ndjson",
            4,
        )
        .unwrap();
        let scan = f.scan.unwrap();
        // null, below range_min and beyond range_max are no returns.
        assert_eq!(f.points.len(), 2);
        assert_eq!(scan.ranges.iter().filter(|r| r.is_nan()).count(), 3);
        assert_eq!(f.pose, Some([1.0, 2.0, 0.5]));
        // A clockwise sweep is stored counter-clockwise.
        let f = parse_frame(
            r#"{"frame":1,"ranges":[1.0,2.0],"angle_min":0.1,"angle_increment":-0.1,"range_max":5}"#,
            "s",
            1,
        )
        .unwrap();
        let s = f.scan.unwrap();
        assert!(s.angles[0] < s.angles[1] && s.ranges == vec![2.0, 1.0]);
        for (bad, what) in [
            (
                r#"{"frame":2,"ranges":[1.0],"angle_min":0,"angle_increment":0,"range_max":5}"#,
                "angle_increment",
            ),
            (
                r#"{"frame":2,"ranges":[1.0],"angle_min":0,"angle_increment":0.1}"#,
                "range_max",
            ),
            (
                r#"{"frame":2,"ranges":[1.0],"points":[[0,0]],"angle_min":0,"angle_increment":0.1,"range_max":5}"#,
                "not both",
            ),
            (
                r#"{"frame":2,"ranges":[1.0,1.0,1.0],"angle_min":0,"angle_increment":4,"range_max":5}"#,
                "more than a turn",
            ),
            (
                r#"{"frame":2,"ranges":[1.0],"angle_min":0,"angle_increment":0.1,"range_max":5,"pose":[0,0]}"#,
                "invalid frame",
            ),
        ] {
            let e = parse_frame(bad, "scan.ndjson", 9).unwrap_err().to_string();
            assert!(e.contains("scan.ndjson, line 9") && e.contains(what), "{e}");
        }
    }
}
