//! A registration target: returns on a lattice, each with the normal of the wall it
//! lies on, and a kd-tree for the nearest one.
//!
//! Why a normal fitted over a neighbourhood and not over two returns: at a centimetre
//! of noise and returns a centimetre apart, two returns' chord turns by tens of
//! degrees, and point-to-line distances along such normals pull the motion about. A
//! line fitted over a disc several noise widths wide does not. Where the disc's returns
//! do not lie on one line (a corner, a chair's legs, clutter) the point gets no normal
//! and is no target: point-to-line residuals need a line.

use std::num::NonZeroUsize;

use isoline_core::geom::Sym2;
use isoline_core::Point;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// Points a normal is fitted over: the point and its five nearest, enough for a line
/// through noise and few enough to stay on one wall.
pub const NEIGHBOURS: usize = 6;

/// Points with normals, searchable.
pub struct Surface {
    points: Vec<Point>,
    normals: Vec<Point>,
    tree: Option<ImmutableKdTree<f64, 2>>,
}

impl std::fmt::Debug for Surface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Surface")
            .field("points", &self.points.len())
            .finish()
    }
}

/// One point per lattice cell of side `cell`: the mean of the points in it, so that a
/// wall seen by many scans weighs no more than one seen once, and the count stays
/// bounded by the area the points cover.
pub fn thin(points: &[Point], cell: f64) -> Vec<Point> {
    let mut keyed: Vec<((i64, i64), Point)> = points
        .iter()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .map(|&p| {
            (
                ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64),
                p,
            )
        })
        .collect();
    keyed.sort_unstable_by_key(|k| k.0);
    keyed
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| {
            let n = run.len() as f64;
            let s = run
                .iter()
                .fold([0.0, 0.0], |a, (_, p)| [a[0] + p[0], a[1] + p[1]]);
            [s[0] / n, s[1] / n]
        })
        .collect()
}

impl Surface {
    /// The surface of `points`: each kept where its six nearest points
    /// within `radius` lie on a line (the smaller principal spread below a quarter of
    /// the larger: a stretch four times as long as it is thick), with that line's
    /// normal. Nearest points, not a fixed disc: a scanner's returns thin out with
    /// range, and a wall 10 m from a 1-degree scanner has returns 17 cm apart.
    pub fn new(points: &[Point], radius: f64) -> Surface {
        let tree = (points.len() >= NEIGHBOURS)
            .then(|| ImmutableKdTree::new_from_slice(points).ok())
            .flatten();
        let mut kept = Vec::new();
        let mut normals = Vec::new();
        let k = NonZeroUsize::new(NEIGHBOURS).expect("a positive constant");
        if let Some(tree) = &tree {
            for &p in points {
                let found = tree
                    .query(&p)
                    .nearest_n::<SquaredEuclidean<f64>>(k)
                    .execute();
                if found.iter().any(|c| c.distance > radius * radius) {
                    continue;
                }
                let n = found.len() as f64;
                let (mut s, mut ss) = ([0.0f64; 2], [0.0f64; 3]);
                for c in &found {
                    let q = points[c.item as usize];
                    let d = [q[0] - p[0], q[1] - p[1]];
                    s = [s[0] + d[0], s[1] + d[1]];
                    ss = [
                        ss[0] + d[0] * d[0],
                        ss[1] + d[0] * d[1],
                        ss[2] + d[1] * d[1],
                    ];
                }
                let m = [s[0] / n, s[1] / n];
                let (a, b, c) = (
                    ss[0] / n - m[0] * m[0],
                    ss[1] / n - m[0] * m[1],
                    ss[2] / n - m[1] * m[1],
                );
                let (l1, l2, e) = Sym2 {
                    xx: a,
                    xy: b,
                    yy: c,
                }
                .eigen();
                if l1 <= 0.0 || l2 > l1 / 16.0 {
                    continue;
                }
                // `e` is the line's direction (the larger spread); the normal turns it.
                kept.push(p);
                normals.push([-e[1], e[0]]);
            }
        }
        let tree = (kept.len() >= 2)
            .then(|| ImmutableKdTree::new_from_slice(&kept).ok())
            .flatten();
        Surface {
            points: kept,
            normals,
            tree,
        }
    }

    /// Points with their unit normals as given, searchable.
    pub fn with_normals(points: Vec<Point>, normals: Vec<Point>) -> Surface {
        debug_assert_eq!(points.len(), normals.len());
        let tree = (points.len() >= 2)
            .then(|| ImmutableKdTree::new_from_slice(&points).ok())
            .flatten();
        Surface {
            points,
            normals,
            tree,
        }
    }

    /// The normals, one a point.
    pub fn normals(&self) -> &[Point] {
        &self.normals
    }

    /// Points with a normal.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether no point has a normal.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The points with normals.
    pub fn points(&self) -> &[Point] {
        &self.points
    }

    /// The nearest point to `q` within `reach` and its normal.
    pub fn nearest(&self, q: Point, reach: f64) -> Option<(Point, Point)> {
        let tree = self.tree.as_ref()?;
        let near = tree
            .query(&q)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        (near.distance <= reach * reach).then(|| {
            let k = near.item as usize;
            (self.points[k], self.normals[k])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wall_gets_its_normal_and_a_corner_none() {
        // An L of two walls sampled every centimetre.
        let mut pts: Vec<Point> = (0..200).map(|i| [i as f64 * 0.01, 0.0]).collect();
        pts.extend((1..200).map(|i| [0.0, i as f64 * 0.01]));
        let s = Surface::new(&pts, 0.05);
        // Six points within 5 cm: three a side at 1 cm.
        let (p, n) = s.nearest([1.0, 0.003], 0.1).unwrap();
        assert!(
            p[1].abs() < 1e-12 && (n[1].abs() - 1.0).abs() < 1e-9,
            "{p:?} {n:?}"
        );
        let (_, n) = s.nearest([0.0, 1.0], 0.1).unwrap();
        assert!((n[0].abs() - 1.0).abs() < 1e-9);
        // At the corner the nearest points hold both walls: no line, no normal.
        assert!(s.points().iter().all(|p| p[0].hypot(p[1]) > 0.005));
        assert!(s.len() < pts.len());
        assert!(s.nearest([5.0, 5.0], 0.1).is_none());
    }

    #[test]
    fn thinning_keeps_one_point_a_cell() {
        let pts: Vec<Point> = (0..1000).map(|i| [(i % 10) as f64 * 0.001, 0.0]).collect();
        assert_eq!(thin(&pts, 0.02).len(), 1);
    }
}
