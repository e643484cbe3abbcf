//! A pose graph: keyframe poses as nodes, measured relative poses with their
//! information as edges, solved by Gauss-Newton on the sparse normal equations (the
//! 2D SLAM formulation of g2o, Kümmerle et al. 2011), the linear systems by
//! `nalgebra-sparse`'s Cholesky.
//!
//! The nodes are numbered in time, so the system is a band (each keyframe tied to the
//! next) plus one off-band block per loop. In that order a loop between keyframes `i`
//! and `j` fills the factor's block rows from `i` to `j`, and a run that comes back to
//! its start again and again fills most of it; the nodes are ordered for the
//! factorization by approximate minimum degree instead (Amestoy, Davis & Duff 1996, the
//! `amd` crate), once a solve, and the factor's symbolic part is kept between its
//! Gauss-Newton steps (the pattern does not change). Loop edges weigh by the Cauchy kernel
//! (a wrong loop that got past the checks pulls with bounded force); the first node
//! is held where it is (the gauge).

use isoline_core::Pose;
use nalgebra::{DMatrix, Matrix3, Vector3};
use nalgebra_sparse::factorization::CscCholesky;
use nalgebra_sparse::pattern::SparsityPattern;
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
        // Node `k`'s unknowns are rows `3 slot[k]..3 slot[k] + 3`.
        let slot = fill_reducing_slots(n, &self.edges);
        // The factor, with the pattern it was factored for.
        let mut factor: Option<(SparsityPattern, CscCholesky<f64>)> = None;
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
                let blocks = [(slot[e.from], ja), (slot[e.to], jb)];
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
                coo.push(3 * slot[0] + r, 3 * slot[0] + r, 1e12);
            }
            let h = CscMatrix::from(&coo);
            let factored = match factor.as_mut() {
                Some((pattern, c)) if pattern == h.pattern() => c.refactor(h.values()).is_ok(),
                _ => match CscCholesky::factor(&h) {
                    Ok(c) => {
                        factor = Some((h.pattern().clone(), c));
                        true
                    }
                    Err(_) => false,
                },
            };
            let Some((_, chol)) = factor.as_ref().filter(|_| factored) else {
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
                let s = 3 * slot[k];
                let d = [step[s], step[s + 1], step[s + 2]];
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

/// Each node's place in a fill-reducing order of the normal equations' block rows:
/// approximate minimum degree on the nodes' adjacency (the edges). The identity where
/// the ordering fails (it does not on a valid graph).
fn fill_reducing_slots(n: usize, edges: &[Edge]) -> Vec<usize> {
    let mut adjacent: Vec<Vec<usize>> = vec![Vec::new(); n];
    for e in edges
        .iter()
        .filter(|e| e.from != e.to && e.from < n && e.to < n)
    {
        adjacent[e.from].push(e.to);
        adjacent[e.to].push(e.from);
    }
    let mut starts = Vec::with_capacity(n + 1);
    let mut rows = Vec::new();
    starts.push(0);
    for a in &mut adjacent {
        a.sort_unstable();
        a.dedup();
        rows.extend_from_slice(a);
        starts.push(rows.len());
    }
    match amd::order(n, &starts, &rows, &amd::Control::default()) {
        Ok((_, inverse, _)) if inverse.len() == n => inverse,
        _ => (0..n).collect(),
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

    /// The slots are a permutation, and on a run that keeps coming back to its start (a
    /// chain of 300 nodes with a loop to node 0 every 10) they cut the factor's fill:
    /// the graph Laplacian plus the identity (the normal equations' node pattern)
    /// factored in the natural order and in the slots' order, the latter with at most
    /// half the non-zeros (a chain with a hub has a factor linear in the nodes when the
    /// hub comes last, quadratic in time order).
    #[test]
    fn the_nodes_are_ordered_to_cut_fill() {
        let n = 300;
        let edge = |from: usize, to: usize| Edge {
            from,
            to,
            z: [0.0; 3],
            info: Matrix3::identity(),
            loop_closure: to != from + 1,
        };
        let mut edges: Vec<Edge> = (0..n - 1).map(|k| edge(k, k + 1)).collect();
        edges.extend((10..n).step_by(10).map(|k| edge(0, k)));
        let slot = fill_reducing_slots(n, &edges);
        let mut seen = vec![false; n];
        for &s in &slot {
            assert!(!seen[s]);
            seen[s] = true;
        }
        let fill = |slot: &[usize]| {
            let mut coo = CooMatrix::new(n, n);
            let mut degree = vec![0.0; n];
            for e in &edges {
                let (a, b) = (slot[e.from], slot[e.to]);
                coo.push(a, b, -1.0);
                coo.push(b, a, -1.0);
                degree[a] += 1.0;
                degree[b] += 1.0;
            }
            for (k, d) in degree.iter().enumerate() {
                coo.push(k, k, d + 1.0);
            }
            CscCholesky::factor(&CscMatrix::from(&coo))
                .unwrap()
                .l()
                .nnz()
        };
        let natural: Vec<usize> = (0..n).collect();
        let (before, after) = (fill(&natural), fill(&slot));
        assert!(2 * after <= before, "{before} -> {after}");
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
