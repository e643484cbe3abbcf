//! Renormalization (paper section 3.5): reset a level-set function to the signed
//! distance to its own zero isoline by fast marching on the triangulation.
//!
//! The vertices of the triangles cut by the P1 zero isoline get their exact distance to
//! the isoline pieces of those triangles (A, accepted); the others are reached in order
//! of increasing distance through a binary heap (C, considered), each tentative value the
//! best first-order update over the triangles of its ball (Kimmel & Sethian 1998): the
//! front is taken as planar across a triangle, which in the form used here is the least
//! over the points `y` of the opposite edge of `T(y) + |x - y|`, `T` linear along the
//! edge. A triangle with an obtuse angle at the updated vertex lets the front slip past
//! its opposite edge; as Kimmel and Sethian do, the angle is split by unfolding the
//! neighbouring triangles across that edge until an accepted vertex is found inside it,
//! and the update is made over the two virtual triangles. The sign of `u` is kept: only
//! its magnitude is marched.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::fem::P1Space;
use crate::geom::{cross, dist, dot, norm, point_segment_dist2, sub, Point};
use crate::mesh::{local_index, Mesh, INVALID};

const FAR: u8 = 0;
const CONSIDERED: u8 = 1;
const ACCEPTED: u8 = 2;

/// How far the unfolding of an obtuse angle may go, in triangles.
const MAX_UNFOLD: usize = 12;

/// Reusable buffers for [`Redistancer::run`], so repeated renormalization does not
/// allocate once sized.
#[derive(Debug, Default)]
pub struct Redistancer {
    state: Vec<u8>,
    value: Vec<f64>,
    /// Per triangle: its isoline piece, if cut.
    piece: Vec<Option<[Point; 2]>>,
    heap: BinaryHeap<Reverse<(u64, u32)>>,
}

/// What one renormalization did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RedistanceReport {
    /// Vertices seeded from cut triangles.
    pub seeded: usize,
    /// Vertices reached by marching.
    pub marched: usize,
}

impl Redistancer {
    /// Empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Replaces `u` by the signed distance to its zero isoline, to within first order in
    /// the mesh size away from it (exact on the cut triangles' vertices). Vertices with
    /// no path to the isoline (`u` of one sign everywhere) are left unchanged. Vertices
    /// farther than `limit` from the isoline keep their sign and get `limit` or their old
    /// magnitude, whichever is larger (pass `f64::INFINITY` to march everywhere).
    pub fn run(
        &mut self,
        mesh: &Mesh,
        space: &P1Space,
        u: &mut [f64],
        limit: f64,
    ) -> RedistanceReport {
        let nv = u.len();
        self.state.clear();
        self.state.resize(nv, FAR);
        self.value.clear();
        self.value.resize(nv, f64::INFINITY);
        self.heap.clear();
        let mut report = RedistanceReport::default();

        // Seeds: the vertices of cut triangles, each at its exact distance to the isoline
        // pieces of the cut triangles around it and around its neighbours. The wider
        // search matters where the isoline passes through or next to a vertex: the pieces
        // in a vertex's own triangles are then mere points, and the nearest part of the
        // isoline is one triangle further.
        self.piece.clear();
        self.piece.extend((0..mesh.tris.len()).map(|t| {
            let s = mesh.tris[t].map(|v| u[v as usize] >= 0.0);
            (s[0] != s[1] || s[1] != s[2]).then(|| cut_segment(mesh, t, u))
        }));
        for (t, tri) in mesh.tris.iter().enumerate() {
            if self.piece[t].is_none() {
                continue;
            }
            for &v in tri {
                let v = v as usize;
                if self.value[v].is_finite() {
                    continue;
                }
                let x = mesh.coords[v];
                let mut best = f64::INFINITY;
                for &w in std::iter::once(&(v as u32)).chain(space.ring(v)) {
                    for &t2 in space.ball(w as usize) {
                        if let Some([pa, pb]) = self.piece[t2 as usize] {
                            best = best.min(point_segment_dist2(x, pa, pb).0);
                        }
                    }
                }
                self.value[v] = best.sqrt();
            }
        }
        for v in 0..nv {
            if self.value[v].is_finite() {
                self.state[v] = ACCEPTED;
                report.seeded += 1;
            }
        }
        if report.seeded == 0 {
            return report;
        }
        for v in 0..nv {
            if self.state[v] == ACCEPTED {
                self.update_neighbours(mesh, space, v);
            }
        }
        while let Some(Reverse((bits, v))) = self.heap.pop() {
            let v = v as usize;
            if self.state[v] == ACCEPTED || bits != self.value[v].to_bits() {
                continue;
            }
            self.state[v] = ACCEPTED;
            report.marched += 1;
            if self.value[v] > limit {
                break;
            }
            self.update_neighbours(mesh, space, v);
        }
        for ((uv, &state), &value) in u.iter_mut().zip(&self.state).zip(&self.value) {
            let mag = match state {
                ACCEPTED | CONSIDERED => value,
                // Beyond the marched band: keep the sign, at least `limit` away.
                _ if limit.is_finite() => limit.max(uv.abs()),
                // No path to the isoline: leave it.
                _ => continue,
            };
            *uv = if *uv >= 0.0 { mag } else { -mag };
        }
        report
    }

    /// Updates the tentative values of the non-accepted vertices around the newly
    /// accepted `v`. Only the triangles containing `v` can offer anything new, so each
    /// neighbour is updated over those alone.
    fn update_neighbours(&mut self, mesh: &Mesh, space: &P1Space, v: usize) {
        for &t in space.ball(v) {
            let t = t as usize;
            let tri = mesh.tris[t];
            for (i, &w) in tri.iter().enumerate() {
                let w = w as usize;
                if self.state[w] == ACCEPTED {
                    continue;
                }
                let cand = self.triangle_update(mesh, t, i);
                if cand < self.value[w] {
                    self.value[w] = cand;
                    self.state[w] = CONSIDERED;
                    self.heap.push(Reverse((cand.to_bits(), w as u32)));
                }
            }
        }
    }

    /// The update of local vertex `i` of triangle `t` from its accepted vertices.
    fn triangle_update(&self, mesh: &Mesh, t: usize, i: usize) -> f64 {
        let tri = mesh.tris[t];
        let px = mesh.coords[tri[i] as usize];
        let a = tri[(i + 1) % 3] as usize;
        let b = tri[(i + 2) % 3] as usize;
        let (ka, kb) = (self.state[a] == ACCEPTED, self.state[b] == ACCEPTED);
        let mut best = f64::INFINITY;
        if ka {
            best = best.min(self.value[a] + dist(px, mesh.coords[a]));
        }
        if kb {
            best = best.min(self.value[b] + dist(px, mesh.coords[b]));
        }
        if ka && kb {
            let (pa, pb) = (mesh.coords[a], mesh.coords[b]);
            best = best.min(if dot(sub(pa, px), sub(pb, px)) >= 0.0 {
                segment_update(px, pa, self.value[a], pb, self.value[b])
            } else {
                self.unfolded_update(mesh, t, i, px)
            });
        }
        best
    }

    /// Update across the obtuse angle at local vertex `i` of triangle `t`: unfold
    /// triangles across the opposite edge until an accepted vertex lies inside the angle,
    /// then update over the two virtual triangles it makes with the angle's sides. Falls
    /// back to the plain edge update when the unfolding runs out.
    fn unfolded_update(&self, mesh: &Mesh, t: usize, i: usize, px: Point) -> f64 {
        let tri = mesh.tris[t];
        let a = tri[(i + 1) % 3] as usize;
        let b = tri[(i + 2) % 3] as usize;
        let (pa, pb) = (mesh.coords[a], mesh.coords[b]);
        let plain = segment_update(px, pa, self.value[a], pb, self.value[b]);
        // Walk across the edge (e0, e1) that the angle's cone passes through.
        let (mut cur, mut e0, mut e1) = (t, a, b);
        for _ in 0..MAX_UNFOLD {
            let k = match local_index(mesh.tris[cur], e0 as u32)
                .and_then(|l0| local_index(mesh.tris[cur], e1 as u32).map(|l1| 3 - l0 - l1))
            {
                Some(k) => k,
                None => return plain,
            };
            let next = mesh.adj[cur][k];
            if next == INVALID {
                return plain;
            }
            let nt = mesh.tris[next as usize];
            let c = nt
                .iter()
                .copied()
                .find(|&w| w as usize != e0 && w as usize != e1)
                .expect("neighbour has a third vertex") as usize;
            let pc = mesh.coords[c];
            // Inside the cone of the angle (a, x, b), counter-clockwise from a to b.
            // Plain floating point: a misjudged near-collinear vertex only picks the
            // other of two equally good updates.
            let left_of_a = cross(sub(pa, px), sub(pc, px)) > 0.0;
            let right_of_b = cross(sub(pb, px), sub(pc, px)) < 0.0;
            if left_of_a && right_of_b {
                if self.state[c] != ACCEPTED {
                    return plain;
                }
                let vc = self.value[c];
                return plain
                    .min(segment_update(px, pa, self.value[a], pc, vc))
                    .min(segment_update(px, pc, vc, pb, self.value[b]));
            }
            // c is outside the cone: continue across the edge of the new triangle that
            // the cone still crosses.
            cur = next as usize;
            if left_of_a {
                e0 = c;
            } else {
                e1 = c;
            }
        }
        plain
    }
}

/// The zero isoline piece of triangle `t` (whose vertices' signs differ).
pub(crate) fn cut_segment(mesh: &Mesh, t: usize, u: &[f64]) -> [Point; 2] {
    let tri = mesh.tris[t];
    let mut pts = [[0.0; 2]; 2];
    let mut n = 0;
    for k in 0..3 {
        let (i, j) = (tri[(k + 1) % 3] as usize, tri[(k + 2) % 3] as usize);
        if (u[i] >= 0.0) != (u[j] >= 0.0) && n < 2 {
            pts[n] = edge_crossing(mesh.coords[i], u[i], mesh.coords[j], u[j]);
            n += 1;
        }
    }
    pts
}

/// Where the linear interpolant between `(pi, ui)` and `(pj, uj)` vanishes.
#[inline]
pub(crate) fn edge_crossing(pi: Point, ui: f64, pj: Point, uj: f64) -> Point {
    let s = (ui / (ui - uj)).clamp(0.0, 1.0);
    [pi[0] + s * (pj[0] - pi[0]), pi[1] + s * (pj[1] - pi[1])]
}

/// `min over y in [a, b] of T(y) + |x - y|`, with `T` linear from `ta` at `a` to `tb` at
/// `b`: the planar-front update of the triangle `(x, a, b)`, reducing to an edge update
/// when the front's direction does not pass through the segment.
fn segment_update(x: Point, a: Point, ta: f64, b: Point, tb: f64) -> f64 {
    let e = sub(b, a);
    let len = norm(e);
    let edge = (ta + dist(x, a)).min(tb + dist(x, b));
    if len <= 0.0 {
        return edge;
    }
    let c = (tb - ta) / len;
    if c.abs() >= 1.0 {
        return edge;
    }
    let dir = [e[0] / len, e[1] / len];
    let ax = sub(x, a);
    let s0 = dot(ax, dir);
    let h = (ax[0] * dir[1] - ax[1] * dir[0]).abs();
    let s = (s0 - c * h / (1.0 - c * c).sqrt()).clamp(0.0, len);
    let planar = ta + c * s + ((s0 - s).powi(2) + h * h).sqrt();
    planar.min(edge)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::Mesh;

    fn jittered_delaunay(n: usize, seed: u64) -> Mesh {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let h = 2.0 / n as f64;
        let mut pts = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let mut p = [-1.0 + i as f64 * h, -1.0 + j as f64 * h];
                if i > 0 && i < n && j > 0 && j < n {
                    p[0] += rng.random_range(-0.3..0.3) * h;
                    p[1] += rng.random_range(-0.3..0.3) * h;
                }
                pts.push(p);
            }
        }
        Mesh::delaunay(&pts)
    }

    /// A distorted level set of the circle of radius 0.5: same zero set, |grad u| far
    /// from one. Renormalization must give back `r - 0.5` with first-order error.
    fn check_circle(mesh: &Mesh) -> (f64, f64) {
        let space = P1Space::new(mesh);
        let exact: Vec<f64> = mesh.coords.iter().map(|p| norm(*p) - 0.5).collect();
        let mut u: Vec<f64> = mesh
            .coords
            .iter()
            .zip(&exact)
            .map(|(p, &e)| e * (3.0 + 2.0 * (5.0 * p[0]).sin()) * (1.0 + e.abs()))
            .collect();
        let mut r = Redistancer::new();
        r.run(mesh, &space, &mut u, f64::INFINITY);
        let err = u
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // Zero isoline displacement: the exact distance of the new isoline's points to
        // the circle.
        let mut moved: f64 = 0.0;
        for t in 0..mesh.num_triangles() {
            let tri = mesh.tris[t];
            let s = tri.map(|v| u[v as usize] >= 0.0);
            if s[0] == s[1] && s[1] == s[2] {
                continue;
            }
            for p in cut_segment(mesh, t, &u) {
                moved = moved.max((norm(p) - 0.5).abs());
            }
        }
        (err, moved)
    }

    #[test]
    fn circle_distance_recovered_to_first_order_and_isoline_kept() {
        // Fast marching is first order: the error bound is C h with C of order one.
        let mut errs = Vec::new();
        for n in [40, 80, 160] {
            let h = 2.0 / n as f64;
            let mesh = jittered_delaunay(n, 7);
            let (err, moved) = check_circle(&mesh);
            assert!(err < 1.5 * h, "n = {n}: max error {err} vs h = {h}");
            // The isoline moves only by the P1 interpolation of the distance near it:
            // O(h^2 / R).
            assert!(moved < 0.1 * h, "n = {n}: isoline moved {moved}, h = {h}");
            errs.push(err);
        }
        // First order: halving h at least roughly halves the error.
        assert!(errs[2] < 0.7 * errs[0], "{errs:?}");
    }

    #[test]
    fn anisotropic_obtuse_mesh_stays_accurate() {
        // Cells stretched 20:1 along x, split along both diagonals alternately: most
        // triangles have an angle near 180 degrees.
        let (nx, ny) = (20, 400);
        let mut pts = Vec::new();
        for j in 0..=ny {
            for i in 0..=nx {
                let shift = if j % 2 == 1 { 0.5 } else { 0.0 };
                let x = (-1.0 + (i as f64 + shift) * 2.0 / nx as f64).min(1.0);
                pts.push([x, -1.0 + j as f64 * 2.0 / ny as f64]);
            }
        }
        let mesh = Mesh::delaunay(&pts);
        let space = P1Space::new(&mesh);
        // A straight front y = 0.1 x: its distance is |y - 0.1 x| / sqrt(1.01).
        let exact: Vec<f64> = mesh
            .coords
            .iter()
            .map(|p| (p[1] - 0.1 * p[0]) / 1.01f64.sqrt())
            .collect();
        let mut u: Vec<f64> = exact.iter().map(|e| e * 7.0).collect();
        Redistancer::new().run(&mesh, &space, &mut u, f64::INFINITY);
        let err = u
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // Fine direction h = 0.005, coarse 0.1: first order in the fine size along the
        // front's normal means an error a few times 0.005, not of order 0.1.
        assert!(err < 0.02, "max error {err}");
    }
}
