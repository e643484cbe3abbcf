//! P1 finite-element tools on a [`Mesh`] (paper section 3.2): [`P1Space`] precomputes
//! what depends on the mesh only (areas, shape-function gradients, vertex balls and
//! rings as CSR arrays), which the solver's curvature operator and fast marching read;
//! [`locate`] finds points in the mesh and interpolates there.

pub mod locate;

use rayon::prelude::*;

use crate::geom::{area, Point};
use crate::mesh::{Mesh, INVALID};

/// Per-mesh data for P1 computations.
#[derive(Clone, Debug, Default)]
pub struct P1Space {
    /// Triangle areas.
    pub area: Vec<f64>,
    /// Gradients of the three barycentric shape functions of each triangle.
    pub shape_grad: Vec<[Point; 3]>,
    /// CSR offsets of vertex balls (incident triangles).
    pub ball_offsets: Vec<u32>,
    /// CSR contents of vertex balls.
    pub ball_tris: Vec<u32>,
    /// Total area of each vertex ball.
    pub ball_area: Vec<f64>,
    /// CSR offsets of vertex rings (neighbouring vertices).
    pub ring_offsets: Vec<u32>,
    /// CSR contents of vertex rings.
    pub ring_verts: Vec<u32>,
}

impl P1Space {
    /// Precomputes the space of a (compacted) mesh.
    pub fn new(mesh: &Mesh) -> P1Space {
        let nt = mesh.num_triangles();
        let nv = mesh.num_vertices();
        let (area_v, shape_grad): (Vec<f64>, Vec<[Point; 3]>) = (0..nt)
            .into_par_iter()
            .map(|t| {
                let [a, b, c] = mesh.tri_coords(t);
                let ar = area(a, b, c);
                let s = 1.0 / (2.0 * ar);
                // grad of the barycentric coordinate of vertex j: the opposite edge rotated
                // by -90 degrees, over twice the area.
                let g = |p: Point, q: Point| [(p[1] - q[1]) * s, (q[0] - p[0]) * s];
                (ar, [g(b, c), g(c, a), g(a, b)])
            })
            .unzip();
        let mut ball_offsets = vec![0u32; nv + 1];
        for tri in &mesh.tris {
            if tri[0] != INVALID {
                for &v in tri {
                    ball_offsets[v as usize + 1] += 1;
                }
            }
        }
        for v in 0..nv {
            ball_offsets[v + 1] += ball_offsets[v];
        }
        let mut fill = ball_offsets.clone();
        let mut ball_tris = vec![0u32; ball_offsets[nv] as usize];
        for (t, tri) in mesh.tris.iter().enumerate() {
            if tri[0] != INVALID {
                for &v in tri {
                    ball_tris[fill[v as usize] as usize] = t as u32;
                    fill[v as usize] += 1;
                }
            }
        }
        let ball_area = (0..nv)
            .into_par_iter()
            .map(|v| {
                let r = ball_offsets[v] as usize..ball_offsets[v + 1] as usize;
                ball_tris[r].iter().map(|&t| area_v[t as usize]).sum()
            })
            .collect();
        // Straight into the flat arrays, in one pass: a vector per vertex, gathered in
        // parallel, cost more in allocation than the walks themselves.
        let mut ring_offsets = Vec::with_capacity(nv + 1);
        ring_offsets.push(0u32);
        let mut ring_verts = Vec::with_capacity(ball_tris.len() + nv);
        let (mut b, mut r) = (Vec::new(), Vec::new());
        for v in 0..nv as u32 {
            mesh.ring(v, &mut b, &mut r);
            ring_verts.extend_from_slice(&r);
            ring_offsets.push(ring_verts.len() as u32);
        }
        P1Space {
            area: area_v,
            shape_grad,
            ball_offsets,
            ball_tris,
            ball_area,
            ring_offsets,
            ring_verts,
        }
    }

    /// Triangles around vertex `v`.
    #[inline]
    pub fn ball(&self, v: usize) -> &[u32] {
        &self.ball_tris[self.ball_offsets[v] as usize..self.ball_offsets[v + 1] as usize]
    }

    /// Neighbours of vertex `v`.
    #[inline]
    pub fn ring(&self, v: usize) -> &[u32] {
        &self.ring_verts[self.ring_offsets[v] as usize..self.ring_offsets[v + 1] as usize]
    }
}
