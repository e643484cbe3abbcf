//! A world-frame curve map as files (`isoline map`, and the daemon's `[map] output`):
//! the format follows each file's extension, and every file is written whole beside its
//! name and then renamed, so that a reader watching a growing map never sees half of
//! one.

use std::path::Path;

use serde_json::json;

use crate::format::{PolylineJson, ResultRecord};
use crate::foxglove::{FrameView, McapOut};
use crate::{Error, Result};
use isoline_core::geom::{dist, Point, Polyline};

/// A map file's format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapFormat {
    /// A FeatureCollection: one LineString a piece, in the world frame's metres.
    GeoJson,
    /// A drawing of the pieces over the sensor's path.
    Svg,
    /// One result record (stream `map`) on one line.
    Ndjson,
    /// The same record, pretty-printed.
    Json,
    /// One `foxglove.SceneUpdate` in frame `map`, placed at the origin of `world`.
    Mcap,
}

impl MapFormat {
    /// The format `path`'s extension names: `.geojson`, `.svg`, `.ndjson` (or
    /// `.jsonl`), `.json` or `.mcap`.
    pub fn of(path: &Path) -> Option<MapFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "geojson" => MapFormat::GeoJson,
            "svg" => MapFormat::Svg,
            "ndjson" | "jsonl" => MapFormat::Ndjson,
            "json" => MapFormat::Json,
            "mcap" => MapFormat::Mcap,
            _ => return None,
        })
    }
}

/// The extensions a map file may have, for messages.
pub const MAP_EXTENSIONS: &str = ".geojson, .svg, .ndjson, .json or .mcap";

/// The map's record: stream `map`, frame the number of scans fused so far, the curves
/// in the world frame.
pub fn map_record(curves: &[Polyline], scans: u64) -> ResultRecord {
    ResultRecord {
        stream: Some("map".into()),
        frame: Some(scans),
        polylines: Some(curves.iter().map(PolylineJson::from).collect()),
        ..Default::default()
    }
}

/// The map as Foxglove shows it: its record in frame `map`, which sits at the origin of
/// `world` (the frame the scans' poses are in).
pub fn map_view(curves: &[Polyline], scans: u64) -> FrameView {
    FrameView {
        record: map_record(curves, scans),
        pose: Some([0.0, 0.0, 0.0]),
        ..Default::default()
    }
}

/// Writes the map to `path` in the format of its extension: `curves` in the world
/// frame, `path_taken` the sensor's positions (drawn in the SVG), `scans` the scans
/// fused.
pub fn write_map(path: &Path, curves: &[Polyline], path_taken: &[Point], scans: u64) -> Result<()> {
    let text = match MapFormat::of(path) {
        Some(MapFormat::GeoJson) => geojson(curves),
        Some(MapFormat::Svg) => svg(curves, path_taken),
        Some(MapFormat::Ndjson) => {
            serde_json::to_string(&map_record(curves, scans)).expect("records serialise") + "\n"
        }
        Some(MapFormat::Json) => {
            serde_json::to_string_pretty(&map_record(curves, scans)).expect("records serialise")
                + "\n"
        }
        Some(MapFormat::Mcap) => {
            let mut out = McapOut::create(path)?;
            out.write(&map_view(curves, scans))?;
            return out.finish();
        }
        None => {
            return Err(Error::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("a map is written as {MAP_EXTENSIONS}"),
                ),
            ))
        }
    };
    crate::write::write_atomic(path, text.as_bytes()).map_err(|e| Error::io(path, e))
}

/// One LineString a piece, closed ones with their first point repeated, with its length.
fn geojson(curves: &[Polyline]) -> String {
    let features: Vec<_> = curves
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let mut coords = c.points.clone();
            if c.closed && !coords.is_empty() {
                coords.push(coords[0]);
            }
            json!({
                "type": "Feature",
                "geometry": {"type": "LineString", "coordinates": coords},
                "properties": {"piece": k, "closed": c.closed, "length": c.length()},
            })
        })
        .collect();
    serde_json::to_string(&json!({"type": "FeatureCollection", "features": features}))
        .expect("values serialise")
        + "\n"
}

/// The pieces over the path the sensor took, a dot a metre.
fn svg(curves: &[Polyline], path_taken: &[Point]) -> String {
    let mut dots: Vec<Point> = Vec::new();
    for &p in path_taken {
        if dots.last().is_none_or(|&q| dist(p, q) >= 1.0) {
            dots.push(p);
        }
    }
    // A margin of 3% of the diagonal round everything drawn.
    let all: Vec<Point> = curves
        .iter()
        .flat_map(|c| c.points.iter().copied())
        .chain(dots.iter().copied())
        .collect();
    let view = isoline_core::geom::BBox::of(&all).map(|b| b.padded(0.03 * b.diag()));
    crate::write::svg::render(
        &crate::write::svg::Drawing {
            points: &dots,
            polylines: curves,
            view,
            map: true,
            ..Default::default()
        },
        1600.0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<Polyline> {
        vec![Polyline {
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            closed: true,
        }]
    }

    #[test]
    fn every_format_is_written_and_read_back() {
        let dir = tempfile::tempdir().unwrap();
        for ext in ["geojson", "svg", "ndjson", "json", "mcap"] {
            let p = dir.path().join(format!("m.{ext}"));
            write_map(&p, &square(), &[[0.5, 0.5]], 7).unwrap();
            assert!(std::fs::metadata(&p).unwrap().len() > 0, "{ext}");
        }
        let geo: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("m.geojson")).unwrap())
                .unwrap();
        let coords = geo["features"][0]["geometry"]["coordinates"]
            .as_array()
            .unwrap();
        // A closed piece's ring repeats its first point, as GeoJSON wants.
        assert_eq!((coords.len(), &coords[0]), (5, &coords[4]));
        let rec: ResultRecord =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("m.ndjson")).unwrap())
                .unwrap();
        assert_eq!((rec.stream.as_deref(), rec.frame), (Some("map"), Some(7)));
        // The drawing says what it shows and at what scale, with a margin round it.
        let svg = std::fs::read_to_string(dir.path().join("m.svg")).unwrap();
        assert!(svg.contains("the robot's path") && svg.contains("the map's curves"));
        assert!(svg.contains(" m</text>"), "a scale bar");
        assert!(
            !svg.contains(r#"d="M0.00 "#),
            "the curves start inside the margin"
        );
        let e = write_map(&dir.path().join("m.png"), &square(), &[], 1).unwrap_err();
        assert!(e.to_string().contains(".geojson"), "{e}");
    }
}
