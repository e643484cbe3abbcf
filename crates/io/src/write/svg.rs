//! SVG drawings, y pointing up: the mesh (optionally), the data points and polylines; for
//! a scan, also the sensor, the free space its rays swept, the features and a scale bar.

use std::fmt::Write;

use isoline_core::geom::{BBox, Point, Polyline};
use isoline_core::Mesh;

/// What to draw.
#[derive(Default)]
pub struct Drawing<'a> {
    /// A mesh, drawn as thin edges.
    pub mesh: Option<&'a Mesh>,
    /// Data points, drawn as dots.
    pub points: &'a [Point],
    /// Curves, drawn as thick lines.
    pub polylines: &'a [Polyline],
    /// The area shown; default: the bounding box of everything drawn.
    pub view: Option<BBox>,
    /// A scan's sensor, drawn as a marker.
    pub sensor: Option<Point>,
    /// A scan's free space, filled.
    pub free: Option<&'a Polyline>,
    /// Clusters of returns no curve explains, circled.
    pub features: &'a [Point],
    /// Reference curves (the truth), drawn thin under the curves.
    pub truth: &'a [Polyline],
    /// A world map: `points` are the robot's path, and the strip below says so, with a
    /// scale bar.
    pub map: bool,
}

/// Height of the strip under a scan's drawing that holds its legend and scale bar.
const FOOTER: f64 = 118.0;

/// The same under a map's (two legend lines).
const MAP_FOOTER: f64 = 64.0;

/// Renders `d` as an SVG document `width` pixels wide (and, for a scan, a strip below
/// with the legend and a scale bar).
// One function: the drawing's elements in the order they are painted.
pub fn render(d: &Drawing<'_>, width: f64) -> String {
    let mut all: Vec<Point> = d.points.to_vec();
    if let Some(m) = d.mesh {
        all.extend_from_slice(m.coords());
    }
    for pl in d.polylines {
        all.extend_from_slice(&pl.points);
    }
    let view = d.view.or_else(|| BBox::of(&all)).unwrap_or(BBox {
        min: [0.0, 0.0],
        max: [1.0, 1.0],
    });
    let size = view.size();
    let span = size[0].max(size[1]).max(1e-300);
    let s = width / span;
    let (w, h) = (size[0] * s, size[1] * s);
    let tx = |p: Point| ((p[0] - view.min[0]) * s, (view.max[1] - p[1]) * s);
    // A scan's or a map's legend and scale bar go in a strip below the drawing, never
    // over data.
    let footer = if d.sensor.is_some() {
        FOOTER
    } else if d.map {
        MAP_FOOTER
    } else {
        0.0
    };
    let full = h + footer;
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{full:.0}" viewBox="0 0 {w:.2} {full:.2}">"#
    );
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let path = |pl: &Polyline| -> String {
        let mut d = String::new();
        for (k, &p) in pl.points.iter().enumerate() {
            let (x, y) = tx(p);
            let _ = write!(d, "{}{x:.2} {y:.2}", if k == 0 { 'M' } else { 'L' });
        }
        if pl.closed {
            d.push('Z');
        }
        d
    };
    if let Some(free) = d.free {
        let _ = writeln!(
            out,
            r##"<path fill="#cfe8f7" stroke="#9cc9e6" stroke-width="0.5" d="{}"/>"##,
            path(free)
        );
    }
    if let Some(m) = d.mesh {
        out.push_str(r##"<path fill="none" stroke="#4a6fa5" stroke-width="0.25" d=""##);
        for (a, b) in m.edge_segments() {
            let (x0, y0) = tx(a);
            let (x1, y1) = tx(b);
            let _ = write!(out, "M{x0:.2} {y0:.2}L{x1:.2} {y1:.2}");
        }
        out.push_str("\"/>\n");
    }
    if !d.points.is_empty() {
        // A map's path is a dot a metre: drawn larger than a scan's returns.
        let dot = if d.map { 5.0 } else { 1.6 };
        let _ = write!(
            out,
            r##"<path fill="none" stroke="#d1495b" stroke-width="{dot}" stroke-linecap="round" d=""##
        );
        for &p in d.points {
            let (x, y) = tx(p);
            let _ = write!(out, "M{x:.2} {y:.2}h0");
        }
        out.push_str("\"/>\n");
    }
    for pl in d.truth {
        let _ = writeln!(
            out,
            r##"<path fill="none" stroke="#2a9d8f" stroke-width="4" stroke-opacity="0.35" stroke-linecap="round" d="{}"/>"##,
            path(pl)
        );
    }
    let scan = d.sensor.is_some();
    let (curve_colour, curve_width) = if scan {
        ("#1d3557", 2.2)
    } else {
        ("#222", 1.2)
    };
    for pl in d.polylines {
        let _ = writeln!(
            out,
            r##"<path fill="none" stroke="{curve_colour}" stroke-width="{curve_width}" stroke-linejoin="round" d="{}"/>"##,
            path(pl)
        );
    }
    for &f in d.features {
        let (x, y) = tx(f);
        let _ = writeln!(
            out,
            r##"<circle cx="{x:.2}" cy="{y:.2}" r="5" fill="none" stroke="#e76f51" stroke-width="1.5"/>"##
        );
    }
    if let Some(o) = d.sensor {
        let (x, y) = tx(o);
        let _ = writeln!(
            out,
            r##"<circle cx="{x:.2}" cy="{y:.2}" r="6" fill="#f4a261" stroke="#222" stroke-width="1.2"/>"##
        );
    }
    if footer > 0.0 {
        scale_bar(&mut out, span, s, w, h + footer);
        legend(&mut out, d.sensor.is_some(), w, h);
    }
    out.push_str("</svg>\n");
    out
}

/// A scale bar at the bottom right of a drawing `w` wide whose strip ends at `bottom`:
/// the round length (1, 2 or 5 times a power of ten) nearest a fifth of the `span` in
/// view, drawn at `s` pixels a unit.
fn scale_bar(out: &mut String, span: f64, s: f64, w: f64, bottom: f64) {
    let target = span / 5.0;
    let mag = 10f64.powf(target.log10().floor());
    let len = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .min_by(|a, b| (a - target).abs().total_cmp(&(b - target).abs()))
        .unwrap_or(mag);
    let x1 = w - 20.0;
    let (x0, y0) = (x1 - len * s, bottom - 20.0);
    let _ = writeln!(
        out,
        r##"<path fill="none" stroke="#222" stroke-width="2" d="M{x0:.2} {:.2}V{y0:.2}H{x1:.2}V{:.2}"/><text x="{:.2}" y="{:.2}" font-family="sans-serif" font-size="14" text-anchor="middle">{len} m</text>"##,
        y0 - 6.0,
        y0 - 6.0,
        0.5 * (x0 + x1),
        y0 - 10.0
    );
}

/// The legend in the strip below a drawing `w` by `h`: a scan's items, or a map's.
fn legend(out: &mut String, scan: bool, w: f64, h: f64) {
    let scan_items: [(&str, &str); 5] = [
        (
            r##"<circle cx="8" cy="-4" r="6" fill="#f4a261" stroke="#222" stroke-width="1.2"/>"##,
            "sensor",
        ),
        (
            r##"<rect x="0" y="-10" width="16" height="12" fill="#cfe8f7" stroke="#9cc9e6"/>"##,
            "free space the rays swept",
        ),
        (
            r##"<circle cx="8" cy="-4" r="2" fill="#d1495b"/>"##,
            "returns",
        ),
        (
            r##"<path d="M0 -4H16" stroke="#1d3557" stroke-width="2.2"/>"##,
            "curves (free side on the left)",
        ),
        (
            r##"<circle cx="8" cy="-4" r="5" fill="none" stroke="#e76f51" stroke-width="1.5"/>"##,
            "returns no curve explains",
        ),
    ];
    let map_items: [(&str, &str); 2] = [
        (
            r##"<path d="M0 -4H16" stroke="#222" stroke-width="1.2"/>"##,
            "the map's curves (free side on the left)",
        ),
        (
            r##"<circle cx="8" cy="-4" r="2.5" fill="#d1495b"/>"##,
            "the robot's path (a dot a metre)",
        ),
    ];
    let items: &[(&str, &str)] = if scan { &scan_items } else { &map_items };
    let _ = writeln!(
        out,
        r##"<path d="M0 {h:.2}H{w:.2}" stroke="#ccc" stroke-width="1"/>"##
    );
    for (k, (swatch, label)) in items.iter().enumerate() {
        let y = h + 24.0 + 20.0 * k as f64;
        let _ = writeln!(
            out,
            r##"<g transform="translate(18 {y:.0})">{swatch}<text x="24" y="0" font-family="sans-serif" font-size="14">{label}</text></g>"##
        );
    }
}

/// A drawing of a reconstruction over its `points`: the curves, and for a scan frame the
/// sensor, its free space and the features; `truth` drawn under the curves, the mesh if
/// asked. The view is the points' box (and the sensor's position), padded by 5%.
pub fn of_reconstruction<'a>(
    points: &'a [Point],
    r: &'a isoline_core::Reconstruction,
    features: &'a [Point],
    truth: &'a [Polyline],
    mesh: bool,
) -> Drawing<'a> {
    let mut corners: Vec<Point> = points.to_vec();
    if let Some((o, _)) = r.free_space() {
        corners.push(o);
    }
    Drawing {
        mesh: mesh.then_some(&r.mesh),
        points,
        polylines: &r.polylines,
        view: BBox::of(&corners).map(|b| b.padded(0.05 * b.diag())),
        sensor: r.free_space().map(|f| f.0),
        free: r.free_space().map(|f| f.1),
        features,
        truth,
        map: false,
    }
}
