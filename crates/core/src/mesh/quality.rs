//! Lengths and shape quality measured in a metric, and mesh statistics.

use rayon::prelude::*;

use super::{Mesh, INVALID};
use crate::geom::{area, sub, Point, Sym2};

/// Edges whose metric length falls in this range count as "unit" in the statistics.
pub const UNIT_RANGE: (f64, f64) = (0.7, 1.4);

/// Length of edge vector `e` in the metric, as the mean of its lengths in the metrics of
/// its two end points (exact when the metric is constant along the edge).
#[inline]
pub fn edge_length(ma: &Sym2, mb: &Sym2, e: Point) -> f64 {
    0.5 * (ma.quad(e).max(0.0).sqrt() + mb.quad(e).max(0.0).sqrt())
}

/// Shape quality of a triangle in the mean of its vertex metrics:
/// `4 sqrt(3) |K|_M / sum of squared metric edge lengths`, 1 for a triangle equilateral
/// in the metric, 0 for a degenerate one, negative for an inverted one.
#[inline]
pub fn quality(p: [Point; 3], m: [&Sym2; 3]) -> f64 {
    let mm = m[0].plus(*m[1]).plus(*m[2]).scaled(1.0 / 3.0);
    let a = area(p[0], p[1], p[2]) * mm.det().max(0.0).sqrt();
    let l2 = mm.quad(sub(p[1], p[0])) + mm.quad(sub(p[2], p[1])) + mm.quad(sub(p[0], p[2]));
    if l2 > 0.0 {
        4.0 * 3f64.sqrt() * a / l2
    } else {
        0.0
    }
}

/// Statistics of a mesh measured in a metric given at its vertices (zero where no
/// metric was measured: a scan's band is built, not adapted to one).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshStats {
    /// Live vertices.
    pub vertices: usize,
    /// Live triangles.
    pub triangles: usize,
    /// Edges.
    pub edges: usize,
    /// Share of edges with metric length in `UNIT_RANGE`.
    pub edges_unit_share: f64,
    /// Median metric edge length.
    pub median_edge_length: f64,
    /// Worst triangle quality (see `quality`); negative would mean an inverted triangle.
    pub min_quality: f64,
    /// Mean triangle quality.
    pub mean_quality: f64,
}

/// Computes [`MeshStats`] for `mesh` with one metric per vertex.
pub fn mesh_stats(mesh: &Mesh, metrics: &[Sym2]) -> MeshStats {
    let edges = mesh.edges();
    let mut lens: Vec<f64> = edges
        .par_iter()
        .map(|&(t, i)| {
            let (a, b) = mesh.edge_vertices(t, i as usize);
            let e = sub(mesh.coords[b as usize], mesh.coords[a as usize]);
            edge_length(&metrics[a as usize], &metrics[b as usize], e)
        })
        .collect();
    let unit = lens
        .iter()
        .filter(|&&l| l >= UNIT_RANGE.0 && l <= UNIT_RANGE.1)
        .count();
    lens.sort_by(f64::total_cmp);
    let (min_q, sum_q, nt) = (0..mesh.num_triangles())
        .into_par_iter()
        .filter(|&t| mesh.tris[t][0] != INVALID)
        .map(|t| {
            let [a, b, c] = mesh.tris[t];
            let q = quality(
                mesh.tri_coords(t),
                [
                    &metrics[a as usize],
                    &metrics[b as usize],
                    &metrics[c as usize],
                ],
            );
            (q, q, 1usize)
        })
        .reduce(
            || (f64::INFINITY, 0.0, 0),
            |x, y| (x.0.min(y.0), x.1 + y.1, x.2 + y.2),
        );
    MeshStats {
        vertices: mesh.vert_tri.iter().filter(|&&t| t != INVALID).count(),
        triangles: nt,
        edges: edges.len(),
        edges_unit_share: if edges.is_empty() {
            0.0
        } else {
            unit as f64 / edges.len() as f64
        },
        median_edge_length: lens.get(lens.len() / 2).copied().unwrap_or(0.0),
        min_quality: if nt > 0 { min_q } else { 0.0 },
        mean_quality: if nt > 0 { sum_q / nt as f64 } else { 0.0 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equilateral_in_its_metric_has_quality_one() {
        let s = 3f64.sqrt() / 2.0;
        let iso = Sym2::iso(1.0);
        let q = quality([[0.0, 0.0], [1.0, 0.0], [0.5, s]], [&iso, &iso, &iso]);
        assert!((q - 1.0).abs() < 1e-12);
        // Stretch x by 10: the triangle squashed by 10 in x is equilateral in M = diag(100, 1).
        let m = Sym2 {
            xx: 100.0,
            xy: 0.0,
            yy: 1.0,
        };
        let q = quality([[0.0, 0.0], [0.1, 0.0], [0.05, s]], [&m, &m, &m]);
        assert!((q - 1.0).abs() < 1e-12);
        assert!((edge_length(&m, &m, [0.1, 0.0]) - 1.0).abs() < 1e-12);
        let inverted = quality([[0.0, 0.0], [0.5, s], [1.0, 0.0]], [&iso, &iso, &iso]);
        assert!(inverted < 0.0);
    }
}
