//! Result writers. The format follows the output file's extension: `.ndjson` (one
//! result record per line, the contract of docs/formats.md), `.json` (the same records as an
//! array, pretty-printed), `.geojson` (a FeatureCollection of LineStrings), `.csv`
//! (`stream,frame,polyline,closed,vertex,x,y,junction`) and `.svg` (see `super::svg`).

pub mod svg;

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde_json::json;

use crate::format::{PolylineJson, ResultRecord};
use isoline_core::geom::dist;

/// A result file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// One JSON record per line.
    Ndjson,
    /// A JSON array of records (a single record for one frame).
    Json,
    /// GeoJSON FeatureCollection.
    GeoJson,
    /// Comma-separated vertices.
    Csv,
    /// SVG drawing.
    Svg,
}

impl Format {
    /// The format named by `path`'s extension.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "ndjson" | "jsonl" => Format::Ndjson,
            "json" => Format::Json,
            "geojson" => Format::GeoJson,
            "csv" => Format::Csv,
            "svg" => Format::Svg,
            _ => return None,
        })
    }

    /// The usual extension.
    pub fn extension(&self) -> &'static str {
        match self {
            Format::Ndjson => "ndjson",
            Format::Json => "json",
            Format::GeoJson => "geojson",
            Format::Csv => "csv",
            Format::Svg => "svg",
        }
    }
}

/// The records as the text of `format` (not SVG, which needs the points and mesh: see
/// `super::svg`).
pub fn render(format: Format, recs: &[ResultRecord]) -> String {
    assert!(
        format != Format::Svg,
        "SVG needs the drawing, not only the records"
    );
    let mut w = RecordWriter::new(format, Vec::new()).expect("writing to memory");
    for r in recs {
        w.push(r).expect("writing to memory");
    }
    String::from_utf8(w.finish().expect("writing to memory")).expect("the formats are UTF-8")
}

/// Writes records one at a time in a text format, holding none but a JSON output's first
/// (one record is written as an object, several as an array): a run's memory does not
/// grow with its number of frames.
#[derive(Debug)]
pub struct RecordWriter<W: Write> {
    out: W,
    format: Format,
    written: u64,
    /// A JSON output's first record, until the second says it is an array.
    first: Option<String>,
    /// Whether a GeoJSON feature was written (the next one needs a comma).
    features: bool,
}

impl<W: Write> RecordWriter<W> {
    /// A writer of `format` (not SVG) to `out`; writes the format's header.
    pub fn new(format: Format, mut out: W) -> std::io::Result<Self> {
        match format {
            Format::Svg => {
                return Err(std::io::Error::other(
                    "SVG needs the drawing, not only the records",
                ))
            }
            Format::GeoJson => out.write_all(b"{\"type\":\"FeatureCollection\",\"features\":[")?,
            Format::Csv => out.write_all(b"stream,frame,polyline,closed,vertex,x,y,junction\n")?,
            Format::Ndjson | Format::Json => {}
        }
        Ok(RecordWriter {
            out,
            format,
            written: 0,
            first: None,
            features: false,
        })
    }

    /// Records written so far.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// Writes one record.
    pub fn push(&mut self, rec: &ResultRecord) -> std::io::Result<()> {
        match self.format {
            Format::Ndjson => write_ndjson(&mut self.out, rec)?,
            Format::Json => {
                let text = serde_json::to_string_pretty(rec)?;
                match (self.written, self.first.take()) {
                    (0, _) => self.first = Some(text),
                    (_, Some(first)) => {
                        write!(self.out, "[\n{},\n{}", indent(&first), indent(&text))?;
                    }
                    _ => write!(self.out, ",\n{}", indent(&text))?,
                }
            }
            Format::GeoJson => {
                for f in geojson_features(rec) {
                    if std::mem::replace(&mut self.features, true) {
                        self.out.write_all(b",")?;
                    }
                    serde_json::to_writer(&mut self.out, &f)?;
                }
            }
            Format::Csv => {
                let mut s = String::new();
                csv_rows(&mut s, rec);
                self.out.write_all(s.as_bytes())?;
            }
            Format::Svg => unreachable!("refused by new"),
        }
        self.written += 1;
        Ok(())
    }

    /// Writes the format's end and gives back the output, flushed.
    pub fn finish(mut self) -> std::io::Result<W> {
        match self.format {
            Format::Json => match (self.written, self.first.take()) {
                (0, _) => self.out.write_all(b"[]\n")?,
                (1, Some(first)) => writeln!(self.out, "{first}")?,
                _ => self.out.write_all(b"\n]\n")?,
            },
            Format::GeoJson => self.out.write_all(b"]}\n")?,
            _ => {}
        }
        self.out.flush()?;
        Ok(self.out)
    }
}

/// Pretty JSON indented by two spaces, as an array's element.
fn indent(text: &str) -> String {
    let mut s = String::with_capacity(text.len() + 64);
    for (i, line) in text.lines().enumerate() {
        if i > 0 {
            s.push('\n');
        }
        s.push_str("  ");
        s.push_str(line);
    }
    s
}

/// A file written beside its final name and renamed into place once complete: a run
/// that fails or is killed never leaves a truncated file under the name, an earlier
/// file there stays whole until then, and a failed write (a full disk) removes its
/// temporary file. The temporary name (`.NAME.PID-K.part` in the same folder) is
/// created exclusively, so it can never be an existing file, an input included.
#[derive(Debug)]
pub struct PartFile {
    /// A handle on the temporary file, to sync it before the rename.
    file: std::fs::File,
    part: PathBuf,
    path: PathBuf,
    committed: bool,
}

impl PartFile {
    /// Creates the temporary file for `path` (and `path`'s folder, if missing); returns
    /// the guard and the file to write.
    pub fn create(path: &Path) -> std::io::Result<(PartFile, std::fs::File)> {
        use std::sync::atomic::{AtomicU64, Ordering};
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let name = path
            .file_name()
            .ok_or_else(|| std::io::Error::other("the output path names no file"))?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&dir)?;
        loop {
            let k = NEXT.fetch_add(1, Ordering::Relaxed);
            let mut part_name = std::ffi::OsString::from(".");
            part_name.push(name);
            part_name.push(format!(".{}-{k}.part", std::process::id()));
            let part = dir.join(part_name);
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&part)
            {
                Ok(file) => {
                    let handle = file.try_clone()?;
                    let guard = PartFile {
                        file: handle,
                        part,
                        path: path.to_path_buf(),
                        committed: false,
                    };
                    return Ok((guard, file));
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// Whether a file can be written at `path`: creates its temporary file (and its
    /// folder) and removes it, so that a run checks its outputs before it works.
    pub fn probe(path: &Path) -> std::io::Result<()> {
        Self::create(path).map(drop)
    }

    /// The temporary file's path.
    pub fn part(&self) -> &Path {
        &self.part
    }

    /// Syncs the written file and renames it to its final name. Whatever wrote to it
    /// must have flushed first.
    pub fn commit(mut self) -> std::io::Result<()> {
        self.file.sync_all()?;
        std::fs::rename(&self.part, &self.path)?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for PartFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.part);
        }
    }
}

/// Writes `text` to `path` through a [`PartFile`].
pub fn write_atomic(path: &Path, text: &[u8]) -> std::io::Result<()> {
    let (guard, mut file) = PartFile::create(path)?;
    file.write_all(text)?;
    drop(file);
    guard.commit()
}

/// Writes one record as an NDJSON line.
pub fn write_ndjson(out: &mut impl Write, rec: &ResultRecord) -> std::io::Result<()> {
    serde_json::to_writer(&mut *out, rec)?;
    out.write_all(b"\n")
}

/// The records as pretty JSON: one object for one record, else an array.
pub fn to_json(recs: &[ResultRecord]) -> String {
    render(Format::Json, recs)
}

/// The curves of `recs` as a GeoJSON FeatureCollection: one LineString per polyline
/// (closed ones repeat their first point, as GeoJSON rings do), with `stream`, `frame`,
/// its index `polyline`, `closed` and, for closed ones, the signed `area` (positive
/// counter-clockwise) as properties; one Point per junction, with the indices of the
/// `polylines` that end there. Error records become features without geometry that
/// carry the error.
pub fn to_geojson(recs: &[ResultRecord]) -> String {
    render(Format::GeoJson, recs)
}

/// The GeoJSON features of one record (see [`to_geojson`]).
fn geojson_features(r: &ResultRecord) -> Vec<serde_json::Value> {
    let mut features = Vec::new();
    if let Some(e) = &r.error {
        features.push(json!({
            "type": "Feature", "geometry": null,
            "properties": {"stream": r.stream, "frame": r.frame, "error": e}
        }));
    }
    for (k, pl) in r.polylines.iter().flatten().enumerate() {
        let mut coords = pl.points.clone();
        if pl.closed && !coords.is_empty() {
            coords.push(coords[0]);
        }
        let poly = isoline_core::geom::Polyline::from(pl.clone());
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": coords},
            "properties": {
                "stream": r.stream, "frame": r.frame, "polyline": k, "closed": pl.closed,
                "area": if pl.closed { Some(poly.signed_area()) } else { None },
            }
        }));
    }
    for j in r.junctions.iter().flatten() {
        features.push(json!({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": j.at},
            "properties": {"stream": r.stream, "frame": r.frame, "polylines": j.polylines}
        }));
    }
    features
}

/// The curves as CSV rows `stream,frame,polyline,closed,vertex,x,y,junction`: the last
/// column, at an open polyline's end vertex where strokes meet, is the index of that
/// junction in the record (empty elsewhere), so that a reader of rows alone knows which
/// polylines meet there (those whose ends carry the same index).
pub fn to_csv(recs: &[ResultRecord]) -> String {
    render(Format::Csv, recs)
}

/// The CSV rows of one record (see [`to_csv`]).
fn csv_rows(s: &mut String, r: &ResultRecord) {
    let stream = r.stream.as_deref().unwrap_or("");
    let frame = r.frame.map_or(String::new(), |f| f.to_string());
    let polylines: Vec<&PolylineJson> = r.polylines.iter().flatten().collect();
    // Each junction at the end of each polyline it names that lies nearer it (both
    // ends where they lie equally near: a stroke from the junction back to it).
    let mut at_end: Vec<[Option<usize>; 2]> = vec![[None, None]; polylines.len()];
    for (j, junction) in r.junctions.iter().flatten().enumerate() {
        for &k in &junction.polylines {
            let Some(pl) = polylines.get(k).filter(|pl| !pl.points.is_empty()) else {
                continue;
            };
            let (first, last) = (pl.points[0], pl.points[pl.points.len() - 1]);
            let (d0, d1) = (dist(first, junction.at), dist(last, junction.at));
            if d0 <= d1 {
                at_end[k][0] = Some(j);
            }
            if d1 <= d0 {
                at_end[k][1] = Some(j);
            }
        }
    }
    for (k, pl) in polylines.iter().enumerate() {
        let n = pl.points.len();
        for (i, p) in pl.points.iter().enumerate() {
            let junction = match i {
                _ if pl.closed => None,
                0 => at_end[k][0],
                _ if i + 1 == n => at_end[k][1],
                _ => None,
            };
            let _ = writeln!(
                s,
                "{stream},{frame},{k},{},{i},{},{},{}",
                pl.closed,
                p[0],
                p[1],
                junction.map_or(String::new(), |j| j.to_string())
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::format::PolylineJson;

    fn rec() -> ResultRecord {
        ResultRecord {
            stream: Some("s".into()),
            frame: Some(3),
            polylines: Some(vec![PolylineJson {
                closed: true,
                points: vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            }]),
            ..Default::default()
        }
    }

    /// Written one at a time, JSON is an empty array, one object or an array, each as
    /// the whole would be; GeoJSON and CSV parse for any count.
    #[test]
    fn records_written_one_at_a_time_make_whole_documents() {
        for n in 0..4 {
            let recs: Vec<ResultRecord> = (0..n).map(|_| rec()).collect();
            let v: serde_json::Value = serde_json::from_str(&to_json(&recs)).unwrap();
            match n {
                1 => assert_eq!(serde_json::from_value::<ResultRecord>(v).unwrap(), rec()),
                _ => assert_eq!(v.as_array().map(Vec::len), Some(n)),
            }
            assert!(!to_json(&recs).starts_with(' '));
            let g: serde_json::Value = serde_json::from_str(&to_geojson(&recs)).unwrap();
            assert_eq!(g["features"].as_array().unwrap().len(), n);
            assert_eq!(to_csv(&recs).lines().count(), 1 + 3 * n);
        }
    }

    #[test]
    fn formats_round_trip_or_parse() {
        let mut nd = Vec::new();
        write_ndjson(&mut nd, &rec()).unwrap();
        let back: ResultRecord = serde_json::from_slice(&nd).unwrap();
        assert_eq!(back, rec());
        let mut with_junction = rec();
        with_junction.junctions = Some(vec![crate::format::JunctionJson {
            at: [0.0, 0.0],
            polylines: vec![0],
        }]);
        let g: serde_json::Value = serde_json::from_str(&to_geojson(&[with_junction])).unwrap();
        let f = &g["features"][0];
        assert_eq!(f["geometry"]["coordinates"].as_array().unwrap().len(), 4);
        assert_eq!(f["properties"]["area"], 0.5);
        assert_eq!(f["properties"]["polyline"], 0);
        let j = &g["features"][1];
        assert_eq!(j["geometry"]["type"], "Point");
        assert_eq!(j["properties"]["polylines"], serde_json::json!([0]));
        let csv = to_csv(&[rec()]);
        assert_eq!(csv.lines().count(), 4);
        assert!(csv.contains("s,3,0,true,1,1,0,\n"));
        // Three strokes meeting at (1, 0): each end there names junction 0, the far
        // ends and the inner vertices nothing.
        let mut strokes = rec();
        strokes.polylines = Some(
            [
                [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]],
                [[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]],
                [[1.0, 1.0], [1.0, 0.5], [1.0, 0.0]],
            ]
            .into_iter()
            .map(|points| PolylineJson {
                closed: false,
                points: points.to_vec(),
            })
            .collect(),
        );
        strokes.junctions = Some(vec![crate::format::JunctionJson {
            at: [1.0, 0.0],
            polylines: vec![0, 1, 2],
        }]);
        let csv = to_csv(&[strokes]);
        let ends: Vec<&str> = csv.lines().filter(|l| l.ends_with(",0")).collect();
        assert_eq!(
            ends,
            [
                "s,3,0,false,2,1,0,0",
                "s,3,1,false,0,1,0,0",
                "s,3,2,false,2,1,0,0"
            ],
            "{csv}"
        );
        assert_eq!(csv.lines().filter(|l| l.ends_with(',')).count(), 6);
        assert_eq!(
            Format::from_path(Path::new("a/b.GeoJSON")),
            Some(Format::GeoJson)
        );
    }

    #[test]
    fn a_failed_atomic_write_leaves_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        // A folder where the file should go: the rename fails, as a full disk would
        // make the write fail.
        let target = dir.path().join("out.ndjson");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("keep"), "x").unwrap();
        assert!(write_atomic(&target, b"data").is_err());
        // A file named as the old temporary name was (an input, say) is never touched.
        std::fs::write(dir.path().join("ok.ndjson.part"), "input").unwrap();
        write_atomic(&dir.path().join("ok.ndjson"), b"data").unwrap();
        assert_eq!(
            std::fs::read(dir.path().join("ok.ndjson")).unwrap(),
            b"data"
        );
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["ok.ndjson", "ok.ndjson.part", "out.ndjson"]);
        assert_eq!(
            std::fs::read(dir.path().join("ok.ndjson.part")).unwrap(),
            b"input"
        );
    }
}
