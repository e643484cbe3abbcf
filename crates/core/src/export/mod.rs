//! The export stage (paper section 1.1, the last stage): the zero isoline as polylines,
//! cut to a scan's support, and how well they fit the data. A point cloud's curves are
//! then mended by [`crate::repair`].

pub mod contour;
pub mod fit;
pub mod support;

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
    /// The tolerances a point cloud's repair passes decide by (dimensionless).
    pub repair: crate::repair::Tolerances,
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
            repair: self.repair.clone(),
        }
    }
}

/// The export stage's kernel: the zero isoline of `u` on `mesh` (local coordinates)
/// as polylines placed back by `at` into data coordinates, loops smaller than
/// `params.min_area` dropped and optionally simplified. `diag` (the data's diagonal)
/// scales the merging of repeated crossings; `hmin` the default smallest loop.
///
/// For a scan frame (`scan`, with the tolerance of its support and the distance within
/// which a curve explains a return), only the pieces within the support's tolerance of
/// a run of returns are kept ([`support::cut_to_support`]), and the returns no kept
/// piece explains come back as features: the same distance as `stats.explained`, so
/// that a return is a feature exactly when the result's fit does not count it.
pub fn curves(
    mesh: &Mesh,
    u: &[f64],
    at: &Placement,
    diag: f64,
    hmin: f64,
    scan: Option<(&Analysis, f64, f64)>,
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
    if let Some((a, tol, explained)) = scan {
        polylines = support::visible_from(polylines, &a.scan);
        polylines = support::cut_to_support(&polylines, &a.support, tol, hmin, 0.5 * tol, hmin);

        // Refined curves are precise enough for their walls' lines to be trusted.
        if a.refine {
            crate::repair::corners::sharpen(&mut polylines, tol);
        }
        let margin = crate::scan::seen_margin(a.scales.noise, hmin);
        polylines = support::outside_seen(polylines, &a.seen, margin, hmin);
        features = support::unexplained(&a.run_points(), &polylines, explained);
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
