//! P1 finite-element tools on a [`Mesh`]: element gradients, recovered vertex gradients
//! and Hessians (paper section 3.2).
//!
//! [`P1Space`] precomputes what depends on the mesh only (areas, shape-function gradients,
//! vertex balls and rings as CSR arrays), so recovering derivatives of a new field is a
//! pair of allocation-free parallel loops: over triangles, then over vertices.

pub mod locate;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::geom::{area, dot, sub, Point, Sym2};
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
        let rings: Vec<Vec<u32>> = (0..nv as u32)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::new()),
                |(b, r), v| {
                    mesh.ring(v, b, r);
                    r.clone()
                },
            )
            .collect();
        let mut ring_offsets = Vec::with_capacity(nv + 1);
        ring_offsets.push(0u32);
        let mut ring_verts = Vec::new();
        for r in rings {
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

    /// The constant gradient of the P1 field `u` on each triangle, into `out`.
    pub fn element_gradients(&self, mesh: &Mesh, u: &[f64], out: &mut [Point]) {
        out.par_iter_mut().enumerate().for_each(|(t, g)| {
            let tri = mesh.tris[t];
            let sg = &self.shape_grad[t];
            let mut acc = [0.0, 0.0];
            for j in 0..3 {
                let uj = u[tri[j] as usize];
                acc[0] += uj * sg[j][0];
                acc[1] += uj * sg[j][1];
            }
            *g = acc;
        });
    }

    /// Clement / L2 projection (paper 3.2.1): at each vertex, the area-weighted mean of
    /// the element gradients `elem` over its ball, into `out`.
    pub fn average_to_vertices(&self, elem: &[Point], out: &mut [Point]) {
        out.par_iter_mut().enumerate().for_each(|(v, g)| {
            let mut acc = [0.0, 0.0];
            for &t in self.ball(v) {
                let a = self.area[t as usize];
                acc[0] += a * elem[t as usize][0];
                acc[1] += a * elem[t as usize][1];
            }
            let s = 1.0 / self.ball_area[v];
            *g = [acc[0] * s, acc[1] * s];
        });
    }

    /// Recovered P1 gradient of `u`; `elem` is scratch of one entry per triangle.
    pub fn recover_gradient(&self, mesh: &Mesh, u: &[f64], elem: &mut [Point], out: &mut [Point]) {
        self.element_gradients(mesh, u, elem);
        self.average_to_vertices(elem, out);
    }

    /// Hessian by applying the L2 projection to each component of the recovered
    /// gradient `grad` (paper 3.2.1), symmetrised. Scratch: `comp` one entry per vertex,
    /// `elem` one per triangle, `row` one per vertex.
    pub fn recover_hessian_l2(
        &self,
        mesh: &Mesh,
        grad: &[Point],
        scratch: &mut HessianScratch,
        out: &mut [Sym2],
    ) {
        let n = grad.len();
        scratch.resize(n, self.area.len());
        for c in 0..2 {
            scratch
                .comp
                .par_iter_mut()
                .zip(grad.par_iter())
                .for_each(|(x, g)| *x = g[c]);
            self.element_gradients(mesh, &scratch.comp, &mut scratch.elem);
            let target = if c == 0 {
                &mut scratch.row0
            } else {
                &mut scratch.row1
            };
            self.average_to_vertices(&scratch.elem, target);
        }
        out.par_iter_mut().enumerate().for_each(|(v, h)| {
            let (r0, r1) = (scratch.row0[v], scratch.row1[v]);
            *h = Sym2 {
                xx: r0[0],
                xy: 0.5 * (r0[1] + r1[0]),
                yy: r1[1],
            };
        });
    }

    /// Hessian by the least-squares Taylor fit of paper eq. 10: with the gradient `grad`
    /// known at `x`, find `H` minimising
    /// `sum_i (u(a_i) - u(x) - grad . (a_i - x) - (a_i - x)^T H (a_i - x) / 2)^2` over the
    /// ring of `x`. Exact for quadratics wherever `grad` is exact. A vertex with fewer
    /// than three neighbours, or a singular fit, falls back to `fallback` if given.
    pub fn recover_hessian_ls(
        &self,
        mesh: &Mesh,
        u: &[f64],
        grad: &[Point],
        fallback: Option<&[Sym2]>,
        out: &mut [Sym2],
    ) {
        out.par_iter_mut().enumerate().for_each(|(v, h)| {
            let x = mesh.coords[v];
            let ring = self.ring(v);
            // Scale offsets by the ring's size so the normal equations are well conditioned.
            let s = ring
                .iter()
                .map(|&j| {
                    dot(
                        sub(mesh.coords[j as usize], x),
                        sub(mesh.coords[j as usize], x),
                    )
                })
                .fold(0.0, f64::max)
                .sqrt();
            let mut ata = Matrix3::<f64>::zeros();
            let mut atb = Vector3::<f64>::zeros();
            for &j in ring {
                let d = sub(mesh.coords[j as usize], x);
                let rhs = u[j as usize] - u[v] - dot(grad[v], d);
                let (dx, dy) = (d[0] / s, d[1] / s);
                let row = Vector3::new(0.5 * dx * dx, dx * dy, 0.5 * dy * dy);
                ata += row * row.transpose();
                atb += row * (rhs / (s * s));
            }
            let sol = if ring.len() >= 3 {
                ata.cholesky().map(|c| c.solve(&atb))
            } else {
                None
            };
            *h = match sol {
                Some(abc) if abc.iter().all(|c| c.is_finite()) => Sym2 {
                    xx: abc[0],
                    xy: abc[1],
                    yy: abc[2],
                },
                _ => fallback.map(|f| f[v]).unwrap_or_default(),
            };
        });
    }
}

/// Scratch buffers of [`P1Space::recover_hessian_l2`].
#[derive(Clone, Debug, Default)]
pub struct HessianScratch {
    comp: Vec<f64>,
    elem: Vec<Point>,
    row0: Vec<Point>,
    row1: Vec<Point>,
}

impl HessianScratch {
    fn resize(&mut self, nv: usize, nt: usize) {
        self.comp.resize(nv, 0.0);
        self.elem.resize(nt, [0.0; 2]);
        self.row0.resize(nv, [0.0; 2]);
        self.row1.resize(nv, [0.0; 2]);
    }
}

#[cfg(test)]
mod tests;
