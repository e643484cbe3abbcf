//! Point location by walking through triangle adjacency, and P1 interpolation.
//!
//! A walk from a nearby start costs a few steps, so locating a batch of points that are
//! spatially ordered (scan points along a sweep, mesh vertices in Morton order) is close
//! to linear. Points outside the mesh are snapped to the nearest point of the boundary
//! triangle where the walk left the domain.

use rayon::prelude::*;

use crate::geom::{orient, Point};
use crate::mesh::{Mesh, INVALID};

/// A point's triangle and barycentric coordinates in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Location {
    /// The triangle.
    pub tri: u32,
    /// Barycentric coordinates, matching `mesh.tris[tri]`, summing to one.
    pub bary: [f64; 3],
}

impl Location {
    /// The P1 field `u` at the located point.
    #[inline]
    pub fn interpolate(&self, mesh: &Mesh, u: &[f64]) -> f64 {
        let t = mesh.tris[self.tri as usize];
        self.bary[0] * u[t[0] as usize]
            + self.bary[1] * u[t[1] as usize]
            + self.bary[2] * u[t[2] as usize]
    }
}

fn barycentric(mesh: &Mesh, t: usize, p: Point) -> [f64; 3] {
    let [a, b, c] = mesh.tri_coords(t);
    let total = orient(a, b, c);
    [
        orient(p, b, c) / total,
        orient(a, p, c) / total,
        orient(a, b, p) / total,
    ]
}

/// Locates `p` by walking from triangle `start`: at each step the walk crosses the edge
/// with the most negative barycentric coordinate. A walk that would leave the domain stops
/// in the boundary triangle with its coordinates clamped to it (the nearest point of that
/// triangle stands in for `p`). Walks longer than the number of triangles (possible only
/// with degenerate triangles) fall back to a scan.
pub fn locate(mesh: &Mesh, p: Point, start: u32) -> Location {
    let nt = mesh.tris.len();
    let mut t = if (start as usize) < nt && mesh.tris[start as usize][0] != INVALID {
        start as usize
    } else {
        first_live(mesh)
    };
    for _ in 0..nt.max(8) {
        let bc = barycentric(mesh, t, p);
        let (mut worst, mut k) = (0.0, 3);
        for (i, &l) in bc.iter().enumerate() {
            if l < worst {
                worst = l;
                k = i;
            }
        }
        if k == 3 {
            return Location {
                tri: t as u32,
                bary: bc,
            };
        }
        let next = mesh.adj[t][k];
        if next == INVALID {
            // Before giving up at the boundary, try the other negative edge, if any.
            let other = (0..3).find(|&i| i != k && bc[i] < 0.0 && mesh.adj[t][i] != INVALID);
            match other {
                Some(i) => t = mesh.adj[t][i] as usize,
                None => return clamp(mesh, t, p),
            }
        } else {
            t = next as usize;
        }
    }
    scan(mesh, p)
}

fn first_live(mesh: &Mesh) -> usize {
    mesh.tris.iter().position(|t| t[0] != INVALID).unwrap_or(0)
}

/// The location of the point of triangle `t` nearest to `p`.
fn clamp(mesh: &Mesh, t: usize, p: Point) -> Location {
    let [a, b, c] = mesh.tri_coords(t);
    let bc = barycentric(mesh, t, p);
    if bc.iter().all(|&l| l >= 0.0) {
        return Location {
            tri: t as u32,
            bary: bc,
        };
    }
    // Nearest point on each edge; keep the closest.
    let corners = [a, b, c];
    let mut best = (f64::INFINITY, [1.0, 0.0, 0.0]);
    for i in 0..3 {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let (d2, s) = crate::geom::point_segment_dist2(p, corners[j], corners[k]);
        if d2 < best.0 {
            let mut l = [0.0; 3];
            l[j] = 1.0 - s;
            l[k] = s;
            best = (d2, l);
        }
    }
    Location {
        tri: t as u32,
        bary: best.1,
    }
}

fn scan(mesh: &Mesh, p: Point) -> Location {
    let mut best = (f64::NEG_INFINITY, 0usize);
    for t in 0..mesh.tris.len() {
        if mesh.tris[t][0] == INVALID {
            continue;
        }
        let m = barycentric(mesh, t, p)
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        if m > best.0 {
            best = (m, t);
        }
    }
    clamp(mesh, best.1, p)
}

/// Whether every point of `points` lies in the mesh's domain (its boundary included).
pub fn covers(mesh: &Mesh, points: &[Point]) -> bool {
    if mesh.tris.iter().all(|t| t[0] == INVALID) {
        return false;
    }
    let mut start = first_live(mesh) as u32;
    points.iter().all(|&p| {
        let l = locate(mesh, p, start);
        start = l.tri;
        // The walk clamps a point outside to the boundary; the true coordinates tell.
        let bc = barycentric(mesh, l.tri as usize, p);
        bc.iter().all(|&b| b >= -1e-9)
    })
}

/// Locates every point of `points`, in parallel chunks; each walk starts where the
/// previous point of its chunk was found. A walk that ends outside the mesh (the point
/// is outside it, or the walk met a boundary between it and the point: a mesh with
/// holes or several parts, as a scan's band) is tried again from the triangle of the
/// point's nearest vertex, and the nearer of the two answers is kept.
pub fn locate_all(mesh: &Mesh, points: &[Point]) -> Vec<Location> {
    locate_from(mesh, points, |_| None)
}

/// Locates every point of `points`, each walk starting at the triangle of the vertex
/// `start(i)` names for point `i` (a vertex near it; `None` where none is known, and
/// the walk then starts where the previous point was found, and is retried as
/// [`locate_all`]'s are if it ends outside the mesh). For points in no spatial order (a kd-tree's)
/// on a mesh with gaps (a scan's band), where a walk from the previous point crosses
/// much of the mesh or stops at a gap.
pub(crate) fn locate_from(
    mesh: &Mesh,
    points: &[Point],
    start: impl Fn(usize) -> Option<u32> + Sync,
) -> Vec<Location> {
    const CHUNK: usize = 256;
    let first = first_live(mesh) as u32;
    let mut out = vec![
        Location {
            tri: first,
            bary: [1.0, 0.0, 0.0]
        };
        points.len()
    ];
    let vertices = std::sync::OnceLock::new();
    out.par_chunks_mut(CHUNK)
        .zip(points.par_chunks(CHUNK))
        .enumerate()
        .for_each(|(chunk, (locs, pts))| {
            let mut from = first;
            for (i, (l, &p)) in locs.iter_mut().zip(pts).enumerate() {
                let near = start(chunk * CHUNK + i).map(|v| mesh.vert_tri[v as usize]);
                *l = locate(mesh, p, near.unwrap_or(from));
                // A walk from a vertex near the point that ends outside found the mesh's
                // boundary next to it; from anywhere else it may have stopped at a gap.
                if near.is_none() && outside(mesh, l, p) {
                    if let Some(index) = vertices.get_or_init(|| VertexIndex::new(mesh)) {
                        let again = index.locate(mesh, p);
                        if gap(mesh, &again, p) < gap(mesh, l, p) {
                            *l = again;
                        }
                    }
                }
                from = l.tri;
            }
        });
    out
}

/// A kd-tree over a mesh's vertices, to start each walk at the triangle of the vertex
/// nearest the point: on a mesh with gaps (a scan's band) a walk from anywhere else can
/// stop at a boundary between it and the point.
pub(crate) struct VertexIndex {
    tree: kiddo::ImmutableKdTree<f64, 2>,
}

impl VertexIndex {
    /// The index of `mesh`'s vertices; `None` for a mesh without any.
    pub(crate) fn new(mesh: &Mesh) -> Option<VertexIndex> {
        if mesh.coords.is_empty()
            || mesh
                .coords
                .iter()
                .any(|c| !c[0].is_finite() || !c[1].is_finite())
        {
            return None;
        }
        kiddo::ImmutableKdTree::new_from_slice(&mesh.coords)
            .ok()
            .map(|tree| VertexIndex { tree })
    }

    /// Locates `p` by a walk from the triangle of its nearest vertex.
    pub(crate) fn locate(&self, mesh: &Mesh, p: Point) -> Location {
        let v = self
            .tree
            .query(&p)
            .nearest_one::<kiddo::SquaredEuclidean<f64>>()
            .execute()
            .item as usize;
        locate(mesh, p, mesh.vert_tri[v])
    }
}

/// Whether the walk that gave `l` stopped outside the mesh, short of `p`.
fn outside(mesh: &Mesh, l: &Location, p: Point) -> bool {
    barycentric(mesh, l.tri as usize, p)
        .iter()
        .any(|&b| b < -1e-9)
}

/// How far `p` is from where `l` puts it.
pub(crate) fn gap(mesh: &Mesh, l: &Location, p: Point) -> f64 {
    let t = mesh.tris[l.tri as usize];
    let q = (0..3).fold([0.0, 0.0], |acc, i| {
        let c = mesh.coords[t[i] as usize];
        [acc[0] + l.bary[i] * c[0], acc[1] + l.bary[i] * c[1]]
    });
    crate::geom::dist(p, q)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::BBox;

    #[test]
    fn walk_finds_the_containing_triangle_and_interpolates_linear_fields_exactly() {
        let mesh = Mesh::structured(
            &BBox {
                min: [0.0, 0.0],
                max: [2.0, 1.0],
            },
            17,
        );
        let u: Vec<f64> = mesh
            .coords
            .iter()
            .map(|p| 3.0 * p[0] - p[1] + 0.5)
            .collect();
        let pts: Vec<Point> = (0..500)
            .map(|i| {
                let s = i as f64 * 0.618_033_988_75;
                [2.0 * s.fract(), (s * 7.3).fract()]
            })
            .collect();
        let locs = locate_all(&mesh, &pts);
        for (p, l) in pts.iter().zip(&locs) {
            assert!(l.bary.iter().all(|&b| b >= -1e-12), "{l:?}");
            let exact = 3.0 * p[0] - p[1] + 0.5;
            assert!((l.interpolate(&mesh, &u) - exact).abs() < 1e-12);
        }
    }

    #[test]
    fn points_outside_snap_to_the_boundary() {
        let mesh = Mesh::structured(
            &BBox {
                min: [0.0, 0.0],
                max: [1.0, 1.0],
            },
            5,
        );
        let u: Vec<f64> = mesh.coords.iter().map(|p| p[0]).collect();
        let l = locate(&mesh, [1.5, 0.5], 0);
        assert!((l.interpolate(&mesh, &u) - 1.0).abs() < 1e-12);
    }
}
