//! Nearest-segment queries over a set of polylines, exact: a kd-tree over the midpoints
//! of the segments cut into pieces of bounded length finds the nearest piece by
//! midpoint, which bounds the answer, and only pieces whose midpoint lies within that
//! bound plus half a piece can do better.

use kiddo::{ImmutableKdTree, SquaredEuclidean};

use crate::geom::{add, dist, point_segment_dist2, scale, sub, Point, Polyline};

/// Nearest-segment queries over a set of polylines.
pub struct SegmentIndex {
    segs: Vec<(Point, Point)>,
    /// Where each polyline's segments start in `segs`.
    starts: Vec<usize>,
    piece_seg: Vec<u32>,
    tree: Option<ImmutableKdTree<f64, 2>>,
    half_piece: f64,
}

impl SegmentIndex {
    /// Bytes the index holds: segments, offsets and the kd-tree's entries (a point and
    /// an item each, plus about as much again for its stems and buckets).
    pub fn bytes(&self) -> usize {
        self.segs.len() * 32 + self.starts.len() * 8 + self.piece_seg.len() * (4 + 2 * 24)
    }

    /// Indexes every segment of `polylines` (an isolated point counts as a segment of
    /// length zero).
    pub fn new(polylines: &[Polyline]) -> SegmentIndex {
        let mut segs: Vec<(Point, Point)> = Vec::new();
        let mut starts = Vec::with_capacity(polylines.len());
        for pl in polylines {
            let before = segs.len();
            starts.push(before);
            segs.extend(pl.segments());
            if segs.len() == before {
                segs.extend(pl.points.iter().map(|&p| (p, p)));
            }
        }
        let mut lens: Vec<f64> = segs.iter().map(|&(a, b)| dist(a, b)).collect();
        let total: f64 = lens.iter().sum();
        lens.sort_by(f64::total_cmp);
        // Pieces of about the median segment, but at most 4 a segment on average: a
        // few long segments among many tiny ones (a curve's specks beside a long chord)
        // once made a billion pieces.
        let piece = lens
            .get(lens.len() / 2)
            .copied()
            .unwrap_or(0.0)
            .max(total / (4 * segs.len() + 16) as f64)
            .max(1e-300);
        let mut mids = Vec::with_capacity(segs.len());
        let mut piece_seg = Vec::with_capacity(segs.len());
        for (i, &(a, b)) in segs.iter().enumerate() {
            let n = ((dist(a, b) / piece).ceil() as usize).max(1);
            for k in 0..n {
                let t = (k as f64 + 0.5) / n as f64;
                mids.push(add(a, scale(sub(b, a), t)));
                piece_seg.push(i as u32);
            }
        }
        let tree = if mids.is_empty() {
            None
        } else {
            ImmutableKdTree::new_from_slice(&mids).ok()
        };
        SegmentIndex {
            segs,
            starts,
            piece_seg,
            tree,
            half_piece: 0.5 * piece,
        }
    }

    /// The length segments are cut into for the search (about the median segment's):
    /// a sampling step at which measuring along the polylines loses nothing the index
    /// resolves.
    pub fn piece(&self) -> f64 {
        2.0 * self.half_piece
    }

    /// Whether there is nothing to measure against.
    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }

    /// Distance from `q` to the nearest segment (infinite when empty).
    pub fn distance(&self, q: Point) -> f64 {
        self.nearest(q).map_or(f64::INFINITY, |n| n.0)
    }

    /// The segments, in the order of the polylines given (a closed polyline's closing
    /// segment last among its own).
    pub fn segments(&self) -> &[(Point, Point)] {
        &self.segs
    }

    /// Where the segments of polyline `k` (in the order given) start in
    /// [`segments`](Self::segments): its segment `j` is `start(k) + j`.
    pub fn start(&self, k: usize) -> usize {
        self.starts[k]
    }

    /// The nearest segment to `q`: the distance, the segment's index in
    /// [`segments`](Self::segments) and the parameter in `[0, 1]` of the nearest point on
    /// it; `None` when empty.
    pub fn nearest(&self, q: Point) -> Option<(f64, usize, f64)> {
        let tree = self.tree.as_ref()?;
        let near = tree
            .query(&q)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        let i = self.piece_seg[near.item as usize] as usize;
        let s = self.segs[i];
        let (d2, t) = point_segment_dist2(q, s.0, s.1);
        let mut best = (d2, i, t);
        let r = d2.sqrt() + self.half_piece * (1.0 + 1e-9);
        // Visited, not collected: a query per export sample must not allocate.
        tree.query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .visit(|c| {
                let i = self.piece_seg[c.item as usize] as usize;
                let s = self.segs[i];
                let (d2, t) = point_segment_dist2(q, s.0, s.1);
                if d2 < best.0 || (d2 == best.0 && i < best.1) {
                    best = (d2, i, t);
                }
            });
        Some((best.0.sqrt(), best.1, best.2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Many zero-length segments beside one long one: the pieces stay a few per
    /// segment (they were the long one's length over the median, zero: a billion and
    /// an out-of-memory abort), and the answers stay exact.
    #[test]
    fn a_long_segment_among_specks_stays_small_and_exact() {
        let mut curves: Vec<Polyline> = (0..30)
            .map(|_| Polyline {
                closed: false,
                points: vec![[0.0, 0.0], [0.0, 0.0]],
            })
            .collect();
        curves.push(Polyline {
            closed: false,
            points: vec![[0.0, 0.0], [1.0, 0.0]],
        });
        let index = SegmentIndex::new(&curves);
        assert!(
            index.piece_seg.len() <= 4 * 31 + 16 + 31,
            "{}",
            index.piece_seg.len()
        );
        assert!((index.distance([0.5, 0.25]) - 0.25).abs() < 1e-15);
        assert!((index.distance([2.0, 0.0]) - 1.0).abs() < 1e-15);
    }
    fn circle(r: f64, n: usize) -> Polyline {
        Polyline {
            closed: true,
            points: (0..n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    [0.5 + r * a.cos(), 0.5 + r * a.sin()]
                })
                .collect(),
        }
    }

    #[test]
    fn index_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut pl = circle(0.3, 50);
        pl.points.push([0.9, 0.9]); // one long segment among short ones
        pl.closed = false;
        let idx = SegmentIndex::new(std::slice::from_ref(&pl));
        for _ in 0..3000 {
            let q = [
                rng.random::<f64>() * 1.4 - 0.2,
                rng.random::<f64>() * 1.4 - 0.2,
            ];
            let brute = pl
                .segments()
                .map(|(a, b)| point_segment_dist2(q, a, b).0.sqrt())
                .fold(f64::INFINITY, f64::min);
            assert!((idx.distance(q) - brute).abs() < 1e-14, "{q:?}");
        }
    }
}
