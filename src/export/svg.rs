//! SVG drawings: the mesh (optionally), the data points and polylines, y pointing up.

use std::fmt::Write;

use crate::geom::{BBox, Point, Polyline};
use crate::mesh::Mesh;

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
}

/// Renders `d` as an SVG document `width` pixels wide.
pub fn render(d: &Drawing<'_>, width: f64) -> String {
    let mut all: Vec<Point> = d.points.to_vec();
    if let Some(m) = d.mesh {
        all.extend_from_slice(&m.coords);
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
    let mut out = String::new();
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w:.0}" height="{h:.0}" viewBox="0 0 {w:.2} {h:.2}">"#
    );
    let _ = writeln!(out, r#"<rect width="100%" height="100%" fill="white"/>"#);
    if let Some(m) = d.mesh {
        out.push_str(r##"<path fill="none" stroke="#4a6fa5" stroke-width="0.25" d=""##);
        for (t, i) in m.edges() {
            let (a, b) = m.edge_vertices(t, i as usize);
            let (x0, y0) = tx(m.coords[a as usize]);
            let (x1, y1) = tx(m.coords[b as usize]);
            let _ = write!(out, "M{x0:.2} {y0:.2}L{x1:.2} {y1:.2}");
        }
        out.push_str("\"/>\n");
    }
    if !d.points.is_empty() {
        out.push_str(
            r##"<path fill="none" stroke="#d1495b" stroke-width="1.6" stroke-linecap="round" d=""##,
        );
        for &p in d.points {
            let (x, y) = tx(p);
            let _ = write!(out, "M{x:.2} {y:.2}h0");
        }
        out.push_str("\"/>\n");
    }
    for pl in d.polylines {
        out.push_str(r##"<path fill="none" stroke="#222" stroke-width="1.2" d=""##);
        for (k, &p) in pl.points.iter().enumerate() {
            let (x, y) = tx(p);
            let _ = write!(out, "{}{x:.2} {y:.2}", if k == 0 { 'M' } else { 'L' });
        }
        if pl.closed {
            out.push('Z');
        }
        out.push_str("\"/>\n");
    }
    out.push_str("</svg>\n");
    out
}
