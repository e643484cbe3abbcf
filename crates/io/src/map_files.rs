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
    /// One self-contained page (no external resource): pan, zoom, a scale bar, and
    /// layers to toggle (the curves, the path, a sample of the returns, the map seen
    /// through).
    Html,
}

impl MapFormat {
    /// The format `path`'s extension names: `.geojson`, `.svg`, `.ndjson` (or
    /// `.jsonl`), `.json`, `.mcap` or `.html`.
    pub fn of(path: &Path) -> Option<MapFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "geojson" => MapFormat::GeoJson,
            "svg" => MapFormat::Svg,
            "ndjson" | "jsonl" => MapFormat::Ndjson,
            "json" => MapFormat::Json,
            "mcap" => MapFormat::Mcap,
            "html" | "htm" => MapFormat::Html,
            _ => return None,
        })
    }
}

/// The extensions a map file may have, for messages.
pub const MAP_EXTENSIONS: &str = ".geojson, .svg, .ndjson, .json, .mcap or .html";

impl MapFormat {
    /// Whether the format draws the map's layers ([`MapDrawing::layers`]): computing
    /// them visits the map's tiles, which the other formats need not.
    pub fn draws_layers(self) -> bool {
        matches!(self, MapFormat::Html)
    }
}

/// What a map file holds: the curves in the world frame, the sensor's positions, the
/// scans fused, and the layers a page draws beside the curves (empty when not
/// computed).
#[derive(Clone, Copy, Debug)]
pub struct MapDrawing<'a> {
    /// The map's curves.
    pub curves: &'a [Polyline],
    /// The sensor's positions, in order.
    pub path: &'a [Point],
    /// Scans fused.
    pub scans: u64,
    /// A sample of the returns and the map seen through.
    pub layers: Option<&'a isoline_map::MapLayers>,
}

/// Returns at most drawn on a page: enough to see the walls' texture, few enough to
/// keep the page a few megabytes.
pub const PAGE_RETURNS: usize = 20_000;

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

/// Writes `curves`, `map`'s, to every path in `paths` in the format of its extension,
/// each whole; the layers a page draws are computed from `map` only when a page is
/// among them (they visit its tiles). `path_taken` is the sensor's positions.
pub fn write_maps(
    paths: &[std::path::PathBuf],
    map: &mut isoline_map::Map,
    curves: &[Polyline],
    path_taken: &[Point],
) -> Result<()> {
    let layers = if paths
        .iter()
        .any(|p| MapFormat::of(p).is_some_and(MapFormat::draws_layers))
    {
        Some(map.layers(curves, PAGE_RETURNS)?)
    } else {
        None
    };
    let drawing = MapDrawing {
        curves,
        path: path_taken,
        scans: map.stats().scans,
        layers: layers.as_ref(),
    };
    paths.iter().try_for_each(|p| write_map(p, &drawing))
}

/// Writes the map to `path` in the format of its extension.
pub fn write_map(path: &Path, map: &MapDrawing<'_>) -> Result<()> {
    let (curves, scans) = (map.curves, map.scans);
    let text = match MapFormat::of(path) {
        Some(MapFormat::GeoJson) => geojson(curves),
        Some(MapFormat::Svg) => svg(curves, map.path),
        Some(MapFormat::Html) => html(map),
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

/// Coordinates to the millimetre, flat: `[x0, y0, x1, y1, ...]`.
fn flat(points: &[Point]) -> Vec<f64> {
    let mm = |v: f64| (v * 1000.0).round() / 1000.0;
    points.iter().flat_map(|p| [mm(p[0]), mm(p[1])]).collect()
}

/// The page: its data (flat arrays in metres) in a JSON script element of the
/// template, which draws it.
fn html(map: &MapDrawing<'_>) -> String {
    let empty = isoline_map::MapLayers::default();
    let layers = map.layers.unwrap_or(&empty);
    // The path thinned to a point every 10 cm: its shape, not the scans' jitter.
    let mut path: Vec<Point> = Vec::new();
    for &p in map.path {
        if path.last().is_none_or(|&q| dist(p, q) >= 0.1) {
            path.push(p);
        }
    }
    let every = layers.returns.len().div_ceil(PAGE_RETURNS).max(1);
    let returns: Vec<Point> = layers.returns.iter().step_by(every).copied().collect();
    let data = json!({
        "scans": map.scans,
        "curves": map.curves.iter().map(|c| json!({"closed": c.closed, "xy": flat(&c.points)})).collect::<Vec<_>>(),
        "path": flat(&path),
        "returns": flat(&returns),
        "through": flat(&layers.seen_through),
    });
    // Numbers only, but a `</` would end the script element whatever it held.
    let data = serde_json::to_string(&data)
        .expect("values serialise")
        .replace("</", "<\\/");
    include_str!("write/map_page.html").replace("__ISOLINE_MAP_DATA__", &data)
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
        let curves = square();
        let layers = isoline_map::MapLayers {
            returns: vec![[0.0, 0.5], [1.0, 0.5]],
            seen_through: vec![[0.5, 0.0]],
        };
        let drawing = MapDrawing {
            curves: &curves,
            path: &[[0.5, 0.5]],
            scans: 7,
            layers: Some(&layers),
        };
        for ext in ["geojson", "svg", "ndjson", "json", "mcap", "html"] {
            let p = dir.path().join(format!("m.{ext}"));
            write_map(&p, &drawing).unwrap();
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
        // The page carries its data and needs nothing from the network.
        let page = std::fs::read_to_string(dir.path().join("m.html")).unwrap();
        assert!(page.contains(r#""through":[0.5,0.0]"#), "{page}");
        assert!(page.contains(r#""xy":[0.0,0.0,1.0,0.0,1.0,1.0,0.0,1.0]"#));
        assert!(!page.contains("http://") && !page.contains("https://") && !page.contains("src="));
        let e = write_map(&dir.path().join("m.png"), &drawing).unwrap_err();
        assert!(e.to_string().contains(".geojson"), "{e}");
    }
}
