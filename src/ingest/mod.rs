//! Readers for the input formats: point files and NDJSON frame streams. Every error
//! names the source and the 1-based line.

use std::io::BufRead;
use std::path::Path;

use crate::error::{Error, Result};
use crate::format::FrameRecord;
use crate::geom::Point;

/// Parses a point file: one point a line, `x y` or `x,y` (further columns ignored),
/// `#` starts a comment, blank lines are skipped. `name` labels errors.
///
/// ```
/// let pts = isoline::ingest::parse_points("# scan\n0 1\n2.5,3 extra\n\n", "demo").unwrap();
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

/// Parses one NDJSON frame line (`line` is 1-based, for the message).
pub fn parse_frame(text: &str, name: &str, line: usize) -> Result<FrameRecord> {
    serde_json::from_str::<FrameRecord>(text).map_err(|e| Error::Parse {
        source_name: name.to_string(),
        line,
        message: format!("invalid frame: {e}"),
    })
}

/// Reads every frame of an NDJSON file; the first bad line is an error naming it.
pub fn read_frames(path: &Path) -> Result<Vec<FrameRecord>> {
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

/// Reads an input as frames: every frame of an NDJSON stream, or a point file as frame 0.
pub fn read_input(path: &Path) -> Result<Vec<FrameRecord>> {
    if is_frame_stream(path) {
        read_frames(path)
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Ok(vec![FrameRecord {
            stream: None,
            frame: 0,
            t: None,
            points: parse_points(&text, &path.display().to_string())?,
            origin: None,
        }])
    }
}

/// Reads the points of `path`: a point file, or frame `frame` (default: the first) of an
/// NDJSON stream.
pub fn read_points(path: &Path, frame: Option<u64>) -> Result<Vec<Point>> {
    if is_frame_stream(path) {
        let frames = read_frames(path)?;
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
        crate::distance::validate_points(&f.points)?;
        Ok(f.points)
    } else {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        parse_points(&text, &path.display().to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            r#"{"stream":"l","frame":3,"t":0.1,"points":[],"origin":[0,0],"x":1}"#,
            "s",
            1,
        )
        .unwrap();
        assert_eq!(f.origin, Some([0.0, 0.0]));
    }
}
