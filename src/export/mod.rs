//! Export (paper section 1.1, the last stage): the zero isoline as polylines, and writers
//! for results (NDJSON, JSON, GeoJSON, CSV, SVG, and MCAP or a live view for Foxglove).

pub mod between;
pub mod contour;
pub mod corners;
pub mod fit;
pub mod foxglove;
pub mod gaps;
pub mod pinches;
pub mod strokes;
pub mod support;
pub mod svg;
pub mod through;
pub mod writers;

use crate::distance::DistanceField;
use crate::geom::{Placement, Polyline};
use crate::mesh::Mesh;
use crate::scan::Analysis;
use contour::{simplify, zero_isoline};
use support::Feature;

/// Export parameters.
#[derive(Clone, Debug, PartialEq, Default)]
#[non_exhaustive]
pub struct ExportParams {
    /// Douglas-Peucker tolerance in data units; 0 keeps every isoline vertex. Default 0.
    pub simplify: f64,
    /// Closed loops enclosing less area are dropped. Default `pi (3 hmin)^2`; 0 keeps all.
    pub min_area: Option<f64>,
}

impl ExportParams {
    /// The smallest area a closed loop keeps, for the mesh size `hmin`.
    pub fn min_area(&self, hmin: f64) -> f64 {
        self.min_area
            .unwrap_or(std::f64::consts::PI * 9.0 * hmin * hmin)
    }

    /// The same parameters with every length multiplied by `s` (into other units).
    pub fn scaled(&self, s: f64) -> ExportParams {
        ExportParams {
            simplify: self.simplify * s,
            min_area: self.min_area.map(|a| a * s * s),
        }
    }
}

/// The export stage's kernel: the zero isoline of `u` on `mesh` (local coordinates)
/// as polylines placed back by `at` into data coordinates, loops smaller than
/// `params.min_area` dropped and optionally simplified. `diag` (the data's diagonal)
/// scales the merging of repeated crossings; `hmin` the default smallest loop.
///
/// For a scan frame (`scan`, with the tolerance of its support), only the pieces within
/// the tolerance of a run of returns are kept ([`support::cut_to_support`]), and the
/// returns farther than it from every kept piece come back as features.
pub fn curves(
    mesh: &Mesh,
    u: &[f64],
    at: &Placement,
    diag: f64,
    hmin: f64,
    scan: Option<(&Analysis, f64)>,
    params: &ExportParams,
) -> (Vec<Polyline>, Vec<Feature>) {
    let mut polylines = zero_isoline(mesh, u, 1e-9 * diag);
    // Loops smaller than a disc of radius 3 hmin are below what the mesh resolves: specks
    // left where the level set grazes zero between samples. On a scan the support
    // decides what stays, and a small loop can be real (the tip of the wedge of free
    // space between a few beams at the edge of the field of view): only slivers thinner
    // than half the mesh size (mean thickness twice the area over the perimeter), left
    // where the start's zigzag through noisy returns folded, are dropped.
    let min_area = params.min_area(hmin);
    match scan {
        None => polylines.retain(|p| !p.closed || p.signed_area().abs() >= min_area),
        Some(_) => polylines
            .retain(|p| !p.closed || 2.0 * p.signed_area().abs() >= 0.5 * hmin * p.length()),
    }
    let mut features = Vec::new();
    if let Some((a, tol)) = scan {
        polylines = support::cut_to_support(&polylines, &a.support, tol, hmin, 0.5 * tol, hmin);
        // Refined curves are precise enough for their walls' lines to be trusted.
        if a.refine {
            corners::sharpen(&mut polylines, tol);
        }
        features = support::unexplained(&a.run_points(), &polylines, tol);
        for f in &mut features {
            f.center = at.to_data(f.center);
        }
    }
    if params.simplify > 0.0 {
        polylines = polylines
            .iter()
            .map(|p| simplify(p, params.simplify))
            .collect();
    }
    for pl in &mut polylines {
        for p in &mut pl.points {
            *p = at.to_data(*p);
        }
    }
    (polylines, features)
}

/// Whether the closed loop `pl` holds fewer than three samples of `field` (within `tol`
/// of a vertex): two samples show a segment, not a curve round anything. The level set
/// leaves such a loop round a few samples of a wall it passed by, and in the way of the
/// arc that spans the wall's gap ([`gaps::span_gaps`]) through them. Open polylines
/// are none.
pub fn holds_no_curve(pl: &Polyline, field: &DistanceField, tol: f64) -> bool {
    if !pl.closed {
        return false;
    }
    let (mut held, mut near) = (Vec::<u32>::new(), Vec::new());
    for &p in &pl.points {
        field.within(p, tol, &mut near);
        for &j in &near {
            if !held.contains(&j) {
                held.push(j);
                if held.len() >= 3 {
                    return false;
                }
            }
        }
    }
    true
}

/// Whether the closed loop `pl`, which the mending changed, is a hole that the noise
/// opened in a noisy band's interior: it encloses less than `min_area` (its whole run
/// lay off the samples round it, and one short arc spanned it). Open polylines are
/// none. (A hole that holds no sample at all goes before the mending, by
/// [`holds_no_curve`].)
pub fn is_shrunk_hole(pl: &Polyline, min_area: f64) -> bool {
    pl.closed && pl.signed_area().abs() < min_area
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::Point;

    fn ring(c: Point, r: f64, n: usize) -> Vec<Point> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    /// A loop of radius 0.008 whose side lies on two samples of a wall 0.006 apart (as
    /// the level set leaves one beside a wall it passed by) holds no curve; the same
    /// loop through three samples does, and an open polyline is never dropped.
    #[test]
    fn a_loop_round_two_samples_holds_no_curve() {
        let loop_ = Polyline {
            closed: true,
            points: ring([0.008, 0.0], 0.008, 64),
        };
        let two = DistanceField::new(&[[0.0, -0.003], [0.0, 0.003]]).unwrap();
        let tol = 0.0023;
        assert!(holds_no_curve(&loop_, &two, tol));
        let three = DistanceField::new(&[[0.0, -0.003], [0.0, 0.003], [0.016, 0.0]]).unwrap();
        assert!(!holds_no_curve(&loop_, &three, tol));
        let open = Polyline {
            closed: false,
            ..loop_
        };
        assert!(!holds_no_curve(&open, &two, tol));
    }
}
