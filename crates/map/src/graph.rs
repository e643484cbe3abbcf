//! A pose graph: keyframe poses as nodes, measured relative poses with their
//! information as edges, solved by Gauss-Newton on the sparse normal equations (the
//! 2D SLAM formulation of g2o, Kümmerle et al. 2011), the linear systems by
//! `nalgebra-sparse`'s Cholesky.
//!
//! The nodes are numbered in time, so the system is a band (each keyframe tied to the
//! next) plus one off-band block per loop; without a fill-reducing ordering a loop
//! between keyframes `i` and `j` fills one block row of length `j - i`, which keeps the
//! factor small for the loops a robot closes. Loop edges weigh by the Cauchy kernel
//! (a wrong loop that got past the checks pulls with bounded force); the first node
//! is held where it is (the gauge).

use isoline_core::Pose;
use nalgebra::{DMatrix, Matrix3, Vector3};
use nalgebra_sparse::factorization::CscCholesky;
use nalgebra_sparse::{CooMatrix, CscMatrix};

use crate::se2::wrap;

/// A measured relative pose between two nodes.
#[derive(Clone, Copy, Debug)]
pub struct Edge {
    /// The node the measurement is taken from.
    pub from: usize,
    /// The node it measures.
    pub to: usize,
    /// `to` as seen from `from`.
    pub z: Pose,
    /// The measurement's information (inverse covariance), in `from`'s frame.
    pub info: Matrix3<f64>,
    /// Whether the edge closes a loop (weighed by the robust kernel).
    pub loop_closure: bool,
}

/// Nodes and edges.
#[derive(Clone, Debug, Default)]
pub struct PoseGraph {
    /// The nodes' poses in the world.
    pub nodes: Vec<Pose>,
    /// The measurements.
    pub edges: Vec<Edge>,
}

/// What an optimisation did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solved {
    /// Gauss-Newton steps taken.
    pub steps: usize,
    /// The weighted squared error before and after.
    pub chi2_before: f64,
    /// After.
    pub chi2_after: f64,
}

/// The Cauchy kernel's scale on a loop edge's squared Mahalanobis error: the 99th
/// percentile of a chi-square with three degrees of freedom, so a loop whose error the
/// graph explains keeps (nearly) its full weight.
const LOOP_SCALE: f64 = 11.34;

impl PoseGraph {
    /// The error of `e` at the nodes' poses, in `z`'s frame, and its Jacobians with
    /// respect to the two nodes.
    fn error(&self, e: &Edge) -> (Vector3<f64>, Matrix3<f64>, Matrix3<f64>) {
        let (a, b) = (self.nodes[e.from], self.nodes[e.to]);
        let (si, ci) = a[2].sin_cos();
        let (sz, cz) = e.z[2].sin_cos();
        let d = [b[0] - a[0], b[1] - a[1]];
        // The measured translation's frame: R_i^T d, then R_z^T (that - t_z).
        let local = [ci * d[0] + si * d[1], -si * d[0] + ci * d[1]];
        let u = [local[0] - e.z[0], local[1] - e.z[1]];
        let err = Vector3::new(
            cz * u[0] + sz * u[1],
            -sz * u[0] + cz * u[1],
            wrap(b[2] - a[2] - e.z[2]),
        );
        // d(R_i^T d)/d theta_i.
        let dl = [-si * d[0] + ci * d[1], -ci * d[0] - si * d[1]];
        let rz_t = |v: [f64; 2]| [cz * v[0] + sz * v[1], -sz * v[0] + cz * v[1]];
        let (ex, ey) = (rz_t([ci, -si]), rz_t([si, ci]));
        let dt = rz_t(dl);
        // R_z^T R_i^T as columns: d/dx_j is (ex.., ey..) for x and y.
        let jb = Matrix3::new(ex[0], ey[0], 0.0, ex[1], ey[1], 0.0, 0.0, 0.0, 1.0);
        let mut ja = -jb;
        ja[(0, 2)] = dt[0];
        ja[(1, 2)] = dt[1];
        (err, ja, jb)
    }

    /// The weighted squared error of every edge (loop edges through the kernel).
    pub fn chi2(&self) -> f64 {
        self.edges
            .iter()
            .map(|e| {
                let (err, _, _) = self.error(e);
                let c = (err.transpose() * e.info * err)[0];
                if e.loop_closure {
                    LOOP_SCALE * (1.0 + c / LOOP_SCALE).ln()
                } else {
                    c
                }
            })
            .sum()
    }

    /// The squared Mahalanobis error of edge `e` alone.
    pub fn edge_chi2(&self, e: &Edge) -> f64 {
        let (err, _, _) = self.error(e);
        (err.transpose() * e.info * err)[0]
    }

    /// Gauss-Newton until the step is below a micrometre and a microradian, or `steps`;
    /// node 0 stays put. Fails (leaving the poses as they were) when the system is not
    /// positive definite, which a connected graph never is.
    pub fn optimize(&mut self, steps: usize) -> Option<Solved> {
        let n = self.nodes.len();
        let chi2_before = self.chi2();
        if n < 2 || self.edges.is_empty() {
            return Some(Solved {
                steps: 0,
                chi2_before,
                chi2_after: chi2_before,
            });
        }
        let saved = self.nodes.clone();
        let mut taken = 0;
        for _ in 0..steps {
            let mut coo = CooMatrix::new(3 * n, 3 * n);
            let mut b = vec![0.0; 3 * n];
            for e in &self.edges {
                let (err, ja, jb) = self.error(e);
                let mut info = e.info;
                if e.loop_closure {
                    let c = (err.transpose() * e.info * err)[0];
                    info /= 1.0 + c / LOOP_SCALE;
                }
                let blocks = [(e.from, ja), (e.to, jb)];
                for &(p, jp) in &blocks {
                    let g = jp.transpose() * info * err;
                    for r in 0..3 {
                        b[3 * p + r] += g[r];
                    }
                    for &(q, jq) in &blocks {
                        let h = jp.transpose() * info * jq;
                        for r in 0..3 {
                            for c in 0..3 {
                                coo.push(3 * p + r, 3 * q + c, h[(r, c)]);
                            }
                        }
                    }
                }
            }
            // The gauge: node 0 held by a stiff spring.
            for r in 0..3 {
                coo.push(r, r, 1e12);
            }
            let h = CscMatrix::from(&coo);
            let Ok(chol) = CscCholesky::factor(&h) else {
                self.nodes = saved;
                return None;
            };
            let rhs = DMatrix::from_column_slice(3 * n, 1, &b);
            let step = chol.solve(&rhs);
            if !step.iter().all(|v| v.is_finite()) {
                self.nodes = saved;
                return None;
            }
            let mut largest = 0.0f64;
            for (k, node) in self.nodes.iter_mut().enumerate() {
                let d = [step[3 * k], step[3 * k + 1], step[3 * k + 2]];
                node[0] -= d[0];
                node[1] -= d[1];
                node[2] = wrap(node[2] - d[2]);
                largest = largest.max(d[0].hypot(d[1])).max(d[2].abs());
            }
            taken += 1;
            if largest < 1e-6 {
                break;
            }
        }
        Some(Solved {
            steps: taken,
            chi2_before,
            chi2_after: self.chi2(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::se2::{between, compose, diag};

    fn info(st: f64, sr: f64) -> Matrix3<f64> {
        diag(st, st, sr).try_inverse().unwrap()
    }

    #[test]
    fn a_loop_pulls_a_drifted_square_shut() {
        // A 4 x 4 m square driven in 16 steps of 1 m, each step's heading off by 1 degree:
        // dead reckoning ends about 0.9 m from the start.
        let step = |k: usize| -> Pose {
            let turn = if k % 4 == 3 {
                std::f64::consts::FRAC_PI_2
            } else {
                0.0
            };
            [1.0, 0.0, turn]
        };
        let mut truth = vec![[0.0, 0.0, 0.0]];
        let mut drift = vec![[0.0, 0.0, 0.0]];
        let mut g = PoseGraph::default();
        for k in 0..16 {
            let s = step(k);
            truth.push(compose(*truth.last().unwrap(), s));
            let noisy = [s[0], s[1], s[2] + 1f64.to_radians()];
            drift.push(compose(*drift.last().unwrap(), noisy));
            g.edges.push(Edge {
                from: k,
                to: k + 1,
                z: noisy,
                info: info(0.01, 0.02),
                loop_closure: false,
            });
        }
        g.nodes = drift.clone();
        let end = drift[16];
        assert!(end[0].hypot(end[1]) > 0.5, "{end:?}");
        // The loop: the last pose is the first, seen exactly.
        g.edges.push(Edge {
            from: 0,
            to: 16,
            z: between(truth[0], truth[16]),
            info: info(0.01, 0.01),
            loop_closure: true,
        });
        let s = g.optimize(20).unwrap();
        // The 16 degrees of heading the loop closes spread over 16 edges of 0.02 rad:
        // about (0.28 / 16 / 0.02)^2 = 0.77 each, some 12 in all, from 72.
        assert!(s.chi2_after < 13.0 && s.chi2_after > 10.0, "{s:?}");
        let end = g.nodes[16];
        assert!(
            end[0].hypot(end[1]) < 0.02 && wrap(end[2]).abs() < 0.01,
            "{end:?}"
        );
        // The worst pose far nearer the truth than dead reckoning's worst.
        let worst = |v: &[Pose]| {
            (0..=16)
                .map(|k| (v[k][0] - truth[k][0]).hypot(v[k][1] - truth[k][1]))
                .fold(0.0, f64::max)
        };
        assert!(
            worst(&g.nodes) < 0.25 * worst(&drift),
            "{} {}",
            worst(&g.nodes),
            worst(&drift)
        );
    }

    #[test]
    fn jacobians_match_finite_differences() {
        let g = PoseGraph {
            nodes: vec![[0.3, -0.2, 0.7], [1.4, 0.9, -2.8]],
            edges: vec![Edge {
                from: 0,
                to: 1,
                z: [0.5, 1.0, 2.9],
                info: Matrix3::identity(),
                loop_closure: false,
            }],
        };
        let (e0, ja, jb) = g.error(&g.edges[0]);
        for (node, j) in [(0, ja), (1, jb)] {
            for c in 0..3 {
                let mut h = g.clone();
                h.nodes[node][c] += 1e-7;
                let (e1, _, _) = h.error(&h.edges[0]);
                let fd = (e1 - e0) / 1e-7;
                for r in 0..3 {
                    assert!((fd[r] - j[(r, c)]).abs() < 1e-5, "node {node} ({r},{c})");
                }
            }
        }
    }
}
