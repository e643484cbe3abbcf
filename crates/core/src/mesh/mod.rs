//! Index-based triangle mesh and its anisotropic adaptation (paper section 3.3).
//!
//! Storage is struct-of-arrays: `coords[v]`, `tris[t]` (counter-clockwise `[u32; 3]`),
//! `adj[t][i]` (the triangle across the edge opposite local vertex `i`, or [`INVALID`] on
//! the domain boundary), `vert_tri[v]` (one triangle of the vertex's ball) and `tag[v]`
//! (interior, boundary or corner). Vertex balls are walked through the adjacency, so no
//! per-vertex lists are kept up to date during adaptation.
//!
//! [`field`] is the adapt stage as plain functions: a frame's distance field and metric
//! frames ([`MetricField`]), and the mesh adapted to them ([`AdaptedMesh`]).

pub mod adapt;
pub mod metric;
pub mod quality;

use std::collections::HashMap;

use crate::geom::{orient, BBox, Point};

/// The "no such triangle / vertex" index.
pub const INVALID: u32 = u32::MAX;

/// Where a vertex sits, which decides how adaptation may move or remove it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum VertexTag {
    /// Inside the domain: free to move and collapse.
    Interior = 0,
    /// On a straight stretch of the boundary: may only collapse along the boundary.
    Boundary = 1,
    /// A corner of the domain: never moves.
    Corner = 2,
}

/// An unstructured triangle mesh stored as flat arrays.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex coordinates.
    pub(crate) coords: Vec<Point>,
    /// Triangles, counter-clockwise.
    pub(crate) tris: Vec<[u32; 3]>,
    /// `adj[t][i]`: triangle across the edge opposite `tris[t][i]`, or [`INVALID`].
    pub(crate) adj: Vec<[u32; 3]>,
    /// One triangle containing each vertex ([`INVALID`] for a removed vertex).
    pub(crate) vert_tri: Vec<u32>,
    /// Vertex tags.
    pub(crate) tag: Vec<VertexTag>,
}

impl Mesh {
    /// The vertices' coordinates, indexed by vertex.
    pub fn coords(&self) -> &[Point] {
        &self.coords
    }

    /// Moves every vertex by `f` (into other coordinates); `f` must keep the
    /// triangles' orientation (a rigid motion, a positive scaling).
    pub fn map_coords(&mut self, mut f: impl FnMut(Point) -> Point) {
        for c in &mut self.coords {
            *c = f(*c);
        }
    }

    /// Every edge once, as its two end points.
    pub fn edge_segments(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        self.edges().into_iter().map(|(t, i)| {
            let (a, b) = self.edge_vertices(t, i as usize);
            (self.coords[a as usize], self.coords[b as usize])
        })
    }

    /// Bytes the mesh's arrays hold (their lengths, not their capacities).
    pub fn bytes(&self) -> usize {
        self.coords.len() * std::mem::size_of::<Point>()
            + (self.tris.len() + self.adj.len()) * 12
            + self.vert_tri.len() * 4
            + self.tag.len() * std::mem::size_of::<VertexTag>()
    }
}

/// Local index (0..3) of vertex `v` in `tri`, if present.
#[inline]
pub fn local_index(tri: [u32; 3], v: u32) -> Option<usize> {
    tri.iter().position(|&x| x == v)
}

impl Mesh {
    /// Builds a mesh from coordinates and counter-clockwise triangles, computing the
    /// adjacency, one incident triangle per vertex and the boundary tags (a boundary
    /// vertex is a corner when its two boundary edges are not collinear).
    pub(crate) fn from_triangles(coords: Vec<Point>, tris: Vec<[u32; 3]>) -> Mesh {
        let n = coords.len();
        // Each edge once per triangle, bucketed by its lower end (a counting sort: a
        // vertex has a handful of edges) and each bucket sorted by the higher end: the
        // two triangles of an interior edge then lie next to each other.
        let mut start = vec![0u32; n + 1];
        for tri in &tris {
            for i in 0..3 {
                let (a, b) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                start[a.min(b) as usize + 1] += 1;
            }
        }
        for v in 0..n {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut edges: Vec<(u32, u32, u8)> = vec![(0, 0, 0); tris.len() * 3];
        for (t, tri) in tris.iter().enumerate() {
            for i in 0..3 {
                let (a, b) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                let slot = &mut fill[a.min(b) as usize];
                edges[*slot as usize] = (a.max(b), t as u32, i as u8);
                *slot += 1;
            }
        }
        let mut adj = vec![[INVALID; 3]; tris.len()];
        for v in 0..n {
            let bucket = &mut edges[start[v] as usize..start[v + 1] as usize];
            bucket.sort_unstable();
            let mut k = 0;
            while k < bucket.len() {
                let (b, t, i) = bucket[k];
                match bucket.get(k + 1) {
                    Some(&(b2, t2, i2)) if b2 == b => {
                        adj[t as usize][i as usize] = t2;
                        adj[t2 as usize][i2 as usize] = t;
                        k += 2;
                    }
                    _ => k += 1,
                }
            }
        }
        let mut vert_tri = vec![INVALID; n];
        let mut boundary_next: Vec<u32> = vec![INVALID; n];
        let mut boundary_prev: Vec<u32> = vec![INVALID; n];
        for (t, tri) in tris.iter().enumerate() {
            for i in 0..3 {
                vert_tri[tri[i] as usize] = t as u32;
                if adj[t][i] == INVALID {
                    let (a, b) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                    boundary_next[a as usize] = b;
                    boundary_prev[b as usize] = a;
                }
            }
        }
        let mut tag = vec![VertexTag::Interior; n];
        for v in 0..n {
            let next = boundary_next[v];
            if next == INVALID {
                continue;
            }
            // The boundary runs prev -> v -> next with the domain on the left.
            let prev = boundary_prev[v];
            tag[v] = match prev {
                p if p != INVALID
                    && orient(coords[p as usize], coords[v], coords[next as usize]) == 0.0 =>
                {
                    VertexTag::Boundary
                }
                _ => VertexTag::Corner,
            };
        }
        Mesh {
            coords,
            tris,
            adj,
            vert_tri,
            tag,
        }
    }

    /// The Delaunay triangulation of `points` (spade's bulk load). Points closer than
    /// spade's tolerance are merged by spade; the result is checked to be a valid mesh.
    pub(crate) fn delaunay(points: &[Point]) -> Mesh {
        use spade::{DelaunayTriangulation, Point2, Triangulation};
        // spade refuses a coordinate nearer zero than 2^-142 (the whole load, not the
        // one vertex): such a coordinate is zero.
        let verts: Vec<Point2<f64>> = points
            .iter()
            .map(|p| spade::mitigate_underflow(Point2::new(p[0], p[1])))
            .collect();
        let dt: DelaunayTriangulation<Point2<f64>> =
            DelaunayTriangulation::bulk_load(verts).unwrap_or_default();
        let coords: Vec<Point> = dt
            .vertices()
            .map(|v| {
                let p = v.position();
                [p.x, p.y]
            })
            .collect();
        let tris: Vec<[u32; 3]> = dt
            .inner_faces()
            .map(|f| f.vertices().map(|v| v.fix().index() as u32))
            .collect();
        Mesh::from_triangles(coords, tris)
    }

    /// A Delaunay mesh of `bbox` with vertices on a lattice of spacing about `h`
    /// (at least one cell each way): the start of adaptation.
    pub(crate) fn of_box(bbox: &BBox, h: f64) -> Mesh {
        let size = bbox.size();
        let nx = ((size[0] / h).ceil() as usize).clamp(1, 4096);
        let ny = ((size[1] / h).ceil() as usize).clamp(1, 4096);
        let mut pts = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                // Stagger alternate rows so the lattice is not co-circular everywhere and
                // the Delaunay triangles are near-equilateral; keep the boundary straight.
                let shift = if j % 2 == 1 && i > 0 && i < nx {
                    0.5
                } else {
                    0.0
                };
                let x = bbox.min[0] + size[0] * ((i as f64 + shift).min(nx as f64) / nx as f64);
                let y = bbox.min[1] + size[1] * (j as f64 / ny as f64);
                pts.push([x, y]);
            }
        }
        Mesh::delaunay(&pts)
    }

    /// A structured mesh of `bbox` with `n x n` cells, all cut along the same
    /// diagonals so that every interior vertex ball is point-symmetric (the setting in
    /// which gradient recovery superconverges).
    #[cfg(test)]
    pub(crate) fn structured(bbox: &BBox, n: usize) -> Mesh {
        let size = bbox.size();
        let id = |i: usize, j: usize| (j * (n + 1) + i) as u32;
        let mut coords = Vec::with_capacity((n + 1) * (n + 1));
        for j in 0..=n {
            for i in 0..=n {
                coords.push([
                    bbox.min[0] + size[0] * i as f64 / n as f64,
                    bbox.min[1] + size[1] * j as f64 / n as f64,
                ]);
            }
        }
        let mut tris = Vec::with_capacity(2 * n * n);
        for j in 0..n {
            for i in 0..n {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                tris.push([a, b, c]);
                tris.push([a, c, d]);
            }
        }
        Mesh::from_triangles(coords, tris)
    }

    /// Number of vertices (removed ones included).
    pub fn num_vertices(&self) -> usize {
        self.coords.len()
    }

    /// Number of triangles (removed ones included).
    pub fn num_triangles(&self) -> usize {
        self.tris.len()
    }

    /// Whether triangle `t` has been removed.
    #[inline]
    pub(crate) fn is_dead_tri(&self, t: u32) -> bool {
        self.tris[t as usize][0] == INVALID
    }

    /// Coordinates of triangle `t`'s vertices.
    #[inline]
    pub fn tri_coords(&self, t: usize) -> [Point; 3] {
        let [a, b, c] = self.tris[t];
        [
            self.coords[a as usize],
            self.coords[b as usize],
            self.coords[c as usize],
        ]
    }

    /// The triangles around vertex `v`, into `out` (cleared first): counter-clockwise
    /// order for an interior vertex; for a boundary vertex, starting at the boundary.
    pub(crate) fn ball(&self, v: u32, out: &mut Vec<u32>) {
        out.clear();
        let t0 = self.vert_tri[v as usize];
        if t0 == INVALID {
            return;
        }
        // Walk clockwise to the boundary (or all the way round) to find the start.
        let mut start = t0;
        loop {
            let k = local_index(self.tris[start as usize], v).expect("vertex in its triangle");
            let prev = self.adj[start as usize][(k + 2) % 3];
            if prev == INVALID || prev == t0 {
                break;
            }
            start = prev;
        }
        let mut t = start;
        loop {
            out.push(t);
            let k = local_index(self.tris[t as usize], v).expect("vertex in its triangle");
            t = self.adj[t as usize][(k + 1) % 3];
            if t == INVALID || t == start {
                break;
            }
            debug_assert!(out.len() <= self.tris.len(), "ball walk does not close");
        }
    }

    /// The vertices joined to `v` by an edge, into `out` (cleared first).
    pub(crate) fn ring(&self, v: u32, balls: &mut Vec<u32>, out: &mut Vec<u32>) {
        self.ball(v, balls);
        out.clear();
        for &t in balls.iter() {
            let tri = self.tris[t as usize];
            let k = local_index(tri, v).expect("vertex in its triangle");
            out.push(tri[(k + 1) % 3]);
            if self.adj[t as usize][(k + 1) % 3] == INVALID {
                out.push(tri[(k + 2) % 3]);
            }
        }
    }

    /// Finds a triangle holding the directed or reversed edge `(a, b)` and the local index
    /// of the edge in it (the index of the vertex opposite).
    pub(crate) fn find_edge(&self, a: u32, b: u32, scratch: &mut Vec<u32>) -> Option<(u32, usize)> {
        self.ball(a, scratch);
        for &t in scratch.iter() {
            let tri = self.tris[t as usize];
            if let Some(kb) = local_index(tri, b) {
                let ka = local_index(tri, a).expect("vertex in its triangle");
                return Some((t, 3 - ka - kb));
            }
        }
        None
    }

    /// Every edge once, as `(t, i)`: the edge opposite local vertex `i` of triangle `t`.
    pub(crate) fn edges(&self) -> Vec<(u32, u8)> {
        let mut out = Vec::with_capacity(self.tris.len() * 3 / 2 + 8);
        for (t, tri) in self.tris.iter().enumerate() {
            if tri[0] == INVALID {
                continue;
            }
            for i in 0..3 {
                let o = self.adj[t][i];
                if o == INVALID || o > t as u32 {
                    out.push((t as u32, i as u8));
                }
            }
        }
        out
    }

    /// End points of edge `(t, i)`.
    #[inline]
    pub(crate) fn edge_vertices(&self, t: u32, i: usize) -> (u32, u32) {
        let tri = self.tris[t as usize];
        (tri[(i + 1) % 3], tri[(i + 2) % 3])
    }

    /// Drops removed vertices and renumbers the rest along a Morton (Z-order) curve, and
    /// triangles by their first vertex, so that per-vertex loops touch memory in order
    /// (the design notes measure a 1.5-5x slowdown of solver steps on shuffled
    /// numberings). Returns the old id of each new vertex, for carrying per-vertex data
    /// over.
    pub(crate) fn renumber_spatially(&mut self) -> Vec<u32> {
        let mut order: Vec<u32> = (0..self.coords.len() as u32)
            .filter(|&v| self.vert_tri[v as usize] != INVALID)
            .collect();
        let live: Vec<Point> = order.iter().map(|&v| self.coords[v as usize]).collect();
        if let Some(bb) = BBox::of(&live) {
            let size = bb.size();
            let key = |p: Point| {
                let q = |x: f64, lo: f64, s: f64| {
                    if s > 0.0 {
                        (((x - lo) / s) * 65535.0) as u32
                    } else {
                        0
                    }
                };
                morton(q(p[0], bb.min[0], size[0]), q(p[1], bb.min[1], size[1]))
            };
            order.sort_by_cached_key(|&v| key(self.coords[v as usize]));
        }
        let mut vmap = vec![INVALID; self.coords.len()];
        for (new, &old) in order.iter().enumerate() {
            vmap[old as usize] = new as u32;
        }
        self.apply_vertex_order(&order, &vmap);
        order
    }

    /// Rebuilds every array with vertices `order` (old ids, new order) and `vmap`
    /// (old -> new); removed triangles are dropped and the rest sorted by first vertex.
    fn apply_vertex_order(&mut self, order: &[u32], vmap: &[u32]) {
        let coords: Vec<Point> = order.iter().map(|&v| self.coords[v as usize]).collect();
        let tag: Vec<VertexTag> = order.iter().map(|&v| self.tag[v as usize]).collect();
        let mut live: Vec<u32> = (0..self.tris.len() as u32)
            .filter(|&t| !self.is_dead_tri(t))
            .collect();
        let renum = |t: u32| {
            let tri = self.tris[t as usize];
            [
                vmap[tri[0] as usize],
                vmap[tri[1] as usize],
                vmap[tri[2] as usize],
            ]
        };
        live.sort_by_key(|&t| renum(t).into_iter().min());
        let mut tmap = vec![INVALID; self.tris.len()];
        for (new, &old) in live.iter().enumerate() {
            tmap[old as usize] = new as u32;
        }
        let tris: Vec<[u32; 3]> = live.iter().map(|&t| renum(t)).collect();
        let adj: Vec<[u32; 3]> = live
            .iter()
            .map(|&t| {
                self.adj[t as usize].map(|o| {
                    if o == INVALID {
                        INVALID
                    } else {
                        tmap[o as usize]
                    }
                })
            })
            .collect();
        let mut vert_tri = vec![INVALID; coords.len()];
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                vert_tri[v as usize] = t as u32;
            }
        }
        *self = Mesh {
            coords,
            tris,
            adj,
            vert_tri,
            tag,
        };
    }

    /// Checks every invariant: live triangles have three distinct live vertices and are
    /// strictly counter-clockwise (exact predicate); adjacency is symmetric and names the
    /// same edge from both sides; every edge has at most two triangles; every live vertex's
    /// `vert_tri` holds it; boundary edges join boundary or corner vertices. Returns the
    /// first problems found (at most 10).
    pub fn sanity_check(&self) -> Result<(), String> {
        let mut problems = Vec::new();
        let mut push = |s: String| {
            if problems.len() < 10 {
                problems.push(s);
            }
        };
        let nv = self.coords.len() as u32;
        if self.adj.len() != self.tris.len()
            || self.vert_tri.len() != self.coords.len()
            || self.tag.len() != self.coords.len()
        {
            return Err("array lengths disagree".into());
        }
        let mut seen = HashMap::with_capacity(self.tris.len() * 3);
        for (t, tri) in self.tris.iter().enumerate() {
            if tri[0] == INVALID {
                continue;
            }
            if tri
                .iter()
                .any(|&v| v >= nv || self.vert_tri[v as usize] == INVALID)
            {
                push(format!("triangle {t} {tri:?} names a missing vertex"));
                continue;
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                push(format!("triangle {t} {tri:?} repeats a vertex"));
                continue;
            }
            let [a, b, c] = self.tri_coords(t);
            if orient(a, b, c) <= 0.0 {
                push(format!("triangle {t} {tri:?} is inverted or degenerate"));
            }
            for i in 0..3 {
                let (u, w) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                if seen.insert((u, w), t).is_some() {
                    push(format!("directed edge ({u}, {w}) is in two triangles"));
                }
                let o = self.adj[t][i];
                if o == INVALID {
                    if self.tag[u as usize] == VertexTag::Interior
                        || self.tag[w as usize] == VertexTag::Interior
                    {
                        push(format!("boundary edge ({u}, {w}) has an interior vertex"));
                    }
                    continue;
                }
                if o as usize >= self.tris.len() || self.is_dead_tri(o) {
                    push(format!("triangle {t} is adjacent to missing triangle {o}"));
                    continue;
                }
                let otri = self.tris[o as usize];
                match (local_index(otri, u), local_index(otri, w)) {
                    (Some(ku), Some(kw)) => {
                        let j = 3 - ku - kw;
                        if self.adj[o as usize][j] != t as u32 || otri[(j + 1) % 3] != w {
                            push(format!("adjacency of {t} and {o} is not mutual"));
                        }
                    }
                    _ => push(format!(
                        "triangles {t} and {o} are adjacent without an edge"
                    )),
                }
            }
        }
        for v in 0..nv {
            let t = self.vert_tri[v as usize];
            if t != INVALID
                && (t >= self.tris.len() as u32 || local_index(self.tris[t as usize], v).is_none())
            {
                push(format!("vertex {v}: vert_tri {t} does not hold it"));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems.join("; "))
        }
    }
}

/// Interleaves the bits of two 16-bit coordinates.
fn morton(x: u32, y: u32) -> u64 {
    fn spread(mut v: u64) -> u64 {
        v &= 0xffff_ffff;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        v = (v | (v << 1)) & 0x5555_5555_5555_5555;
        v
    }
    spread(x as u64) | (spread(y as u64) << 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles of a square: each is across the diagonal from the other, and the
    /// four corners are tagged as such.
    #[test]
    fn two_triangles_share_their_diagonal() {
        let m = Mesh::from_triangles(
            vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        assert_eq!(m.adj[0][1], 1);
        assert_eq!(m.adj[1][2], 0);
        assert!(m.tag.iter().all(|&t| t == VertexTag::Corner));
        m.sanity_check().unwrap();
    }

    fn unit() -> BBox {
        BBox {
            min: [0.0, 0.0],
            max: [1.0, 1.0],
        }
    }

    #[test]
    fn structured_mesh_is_valid_with_tags_and_balls() {
        let m = Mesh::structured(&unit(), 4);
        m.sanity_check().unwrap();
        assert_eq!((m.num_vertices(), m.num_triangles()), (25, 32));
        let corners = m.tag.iter().filter(|&&t| t == VertexTag::Corner).count();
        let boundary = m.tag.iter().filter(|&&t| t == VertexTag::Boundary).count();
        assert_eq!((corners, boundary), (4, 12));
        let mut ball = Vec::new();
        let mut ring = Vec::new();
        // Interior vertex (1,1) = id 6 has six triangles on this diagonal pattern.
        m.ring(6, &mut ball, &mut ring);
        assert_eq!(ball.len(), 6);
        ring.sort();
        assert_eq!(ring, vec![0, 1, 5, 7, 11, 12]);
        // Corner 0 has ball [0,1,2]... two triangles, three neighbours.
        m.ring(0, &mut ball, &mut ring);
        assert_eq!((ball.len(), ring.len()), (2, 3));
        assert_eq!(m.edges().len(), 25 + 32 - 1); // Euler: E = V + F - 1
    }

    #[test]
    fn delaunay_box_and_renumbering_stay_valid() {
        let mut m = Mesh::of_box(&unit(), 0.1);
        m.sanity_check().unwrap();
        let area: f64 = (0..m.num_triangles())
            .map(|t| {
                let [a, b, c] = m.tri_coords(t);
                crate::geom::area(a, b, c)
            })
            .sum();
        assert!((area - 1.0).abs() < 1e-12);
        let nv = m.num_vertices();
        m.renumber_spatially();
        m.sanity_check().unwrap();
        assert_eq!(m.num_vertices(), nv);
        assert_eq!(m.tag.iter().filter(|&&t| t == VertexTag::Corner).count(), 4);
    }

    /// A coordinate nearer zero than spade accepts (2^-142) is zero, not the end of the
    /// whole triangulation: spade refuses the load, and the mesh came out empty.
    #[test]
    fn a_coordinate_below_spades_range_is_zero() {
        let m = Mesh::delaunay(&[
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [1e-200, 0.5],
        ]);
        m.sanity_check().unwrap();
        assert_eq!((m.num_vertices(), m.num_triangles()), (5, 3));
    }

    #[test]
    fn sanity_check_catches_an_inverted_triangle() {
        let mut m = Mesh::structured(&unit(), 2);
        m.coords[4] = [2.0, 2.0];
        assert!(m.sanity_check().unwrap_err().contains("inverted"));
    }
}
