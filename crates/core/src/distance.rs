//! Unsigned distance to a point set, through a kiddo kd-tree (paper section 3.1).
//!
//! Points are validated at the door (finite, not huge) and exact duplicates are merged
//! before the tree is built: a scanner that returns the same point many times must not
//! cost more nor change any answer, and the tree never sees input it could choke on.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;
use std::f64::consts::FRAC_1_SQRT_2;
use std::num::NonZeroUsize;

use crate::error::{Error, Result};
use crate::geom::{dist, Point};

/// Largest coordinate magnitude accepted: squared distances of twice this stay finite.
pub const MAX_COORDINATE: f64 = 1e150;

/// Smallest extent (bounding-box diagonal) of a point set: below it, coordinates
/// relative to the data's centre lose their precision to subnormal numbers.
pub const MIN_EXTENT: f64 = 1e-150;

/// Checks that `points` is non-empty, finite and within [`MAX_COORDINATE`].
pub fn validate_points(points: &[Point]) -> Result<()> {
    if points.is_empty() {
        return Err(Error::EmptyPointSet);
    }
    for (index, p) in points.iter().enumerate() {
        if !p[0].is_finite() || !p[1].is_finite() {
            return Err(Error::NonFinitePoint {
                index,
                x: p[0],
                y: p[1],
            });
        }
        let magnitude = p[0].abs().max(p[1].abs());
        if magnitude > MAX_COORDINATE {
            return Err(Error::HugeCoordinate { index, magnitude });
        }
    }
    Ok(())
}

/// The distance field of one point set: a kd-tree over its distinct points.
pub struct DistanceField {
    points: Vec<Point>,
    tree: ImmutableKdTree<f64, 2>,
}

impl std::fmt::Debug for DistanceField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DistanceField")
            .field("points", &self.points.len())
            .finish()
    }
}

/// Distance from a query to its nearest data point, and that point's index in
/// [`DistanceField::points`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Euclidean distance.
    pub dist: f64,
    /// Index of the nearest distinct point.
    pub index: u32,
}

impl DistanceField {
    /// Builds the field of `points` after validating them; exact duplicates are merged.
    pub fn new(points: &[Point]) -> Result<DistanceField> {
        validate_points(points)?;
        let mut distinct: Vec<Point> = points.to_vec();
        distinct.sort_unstable_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
        // -0.0 and 0.0 are the same point; total_cmp orders them apart, so compare with ==.
        distinct.dedup_by(|a, b| a[0] == b[0] && a[1] == b[1]);
        let tree = ImmutableKdTree::new_from_slice(&distinct)
            .map_err(|e| Error::Internal(format!("kd-tree construction failed: {e:?}")))?;
        Ok(DistanceField {
            points: distinct,
            tree,
        })
    }

    /// The distinct data points, in the tree's index order: sorted by x, then y, so
    /// that a field built from some of them, in this order, keeps it.
    pub fn points(&self) -> &[Point] {
        &self.points
    }

    /// Nearest data point to `q`.
    #[inline]
    pub fn nearest(&self, q: Point) -> Nearest {
        let r = self
            .tree
            .query(&q)
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        Nearest {
            dist: r.distance.sqrt(),
            index: r.item,
        }
    }

    /// Unsigned distance `d(q)`.
    #[inline]
    pub fn distance(&self, q: Point) -> f64 {
        self.nearest(q).dist
    }

    /// How many data points lie within distance `r` of `q`.
    pub fn count_within(&self, q: Point, r: f64) -> usize {
        let mut n = 0;
        self.tree
            .query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .visit(|_| n += 1);
        n
    }

    /// Indices of the data points within distance `r` of `q`, in no order, appended to
    /// `out` after clearing it.
    pub fn within(&self, q: Point, r: f64, out: &mut Vec<u32>) {
        out.clear();
        self.tree
            .query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .visit(|n| out.push(n.item));
    }

    /// Indices of the `k` nearest data points to `q`, nearest first (fewer when the set
    /// is smaller), appended to `out` after clearing it.
    pub fn nearest_k(&self, q: Point, k: usize, out: &mut Vec<u32>) {
        out.clear();
        let Some(k) = NonZeroUsize::new(k.min(self.points.len())) else {
            return;
        };
        let found = self
            .tree
            .query(&q)
            .nearest_n::<SquaredEuclidean<f64>>(k)
            .execute();
        out.extend(found.iter().map(|r| r.item));
    }

    /// Distance and nearest point at every query, in parallel.
    pub fn nearest_all(&self, queries: &[Point]) -> Vec<Nearest> {
        queries.par_iter().map(|&q| self.nearest(q)).collect()
    }

    /// Unsigned distance at every query, in parallel, into `out` (resized).
    pub fn distances_into(&self, queries: &[Point], out: &mut Vec<f64>) {
        out.resize(queries.len(), 0.0);
        out.par_iter_mut()
            .zip(queries.par_iter())
            .for_each(|(d, &q)| *d = self.distance(q));
    }
}

/// A default tube radius: twice the 95th percentile of the data's nearest-neighbour
/// spacing, and at least `floor`. Gaps between consecutive samples up to twice that
/// close; where the tube still leaks, the tube start (`levelset::init`) says so.
pub fn tube_radius(field: &DistanceField, floor: f64) -> f64 {
    let pts = field.points();
    let mut nn: Vec<f64> = pts
        .par_iter()
        .map_init(Vec::new, |buf, &p| {
            field.nearest_k(p, 2, buf);
            buf.get(1).map_or(0.0, |&j| dist(p, pts[j as usize]))
        })
        .collect();
    if nn.is_empty() {
        return floor;
    }
    let k = (nn.len() * 95 / 100).min(nn.len() - 1);
    let (_, p95, _) = nn.select_nth_unstable_by(k, f64::total_cmp);
    (2.0 * *p95).max(floor)
}

/// How far a sample's neighbours may lie, in units of the data's sampling spacing (the
/// median over the samples of the distance to their second nearest other sample: on a
/// curve, about the spacing along it). The open strokes join ends across gaps up to 8
/// times the 95th percentile of the nearest-neighbour spacing (`repair::strokes`, twice
/// `2 r` with `r` at least twice the tube radius); for samples at random along a curve
/// that percentile is 1.8 times this median (nearest neighbours `Exp(2 lambda)`: 1.50 /
/// lambda, against 0.84 / lambda), so the strokes join across every gap that samples
/// at random along a curve leave. A median, unlike that percentile, does not move
/// while fewer than half the points are outliers.
pub const NEIGHBOUR_SPACINGS: f64 = 14.0;

/// Samples linked through neighbours in fewer than this many are isolated: one or two
/// samples make no curve.
pub const MIN_CLUSTER: usize = 3;

/// How far, in sampling spacings, a sample's neighbours lie for it to be on a curve
/// without a further test. Samples at random along a curve (rate `lambda`, spacing
/// about `0.84 / lambda`) leave a gap wider than 6 spacings with probability
/// `exp(-5)` each, so a few of a drawing's samples lie past one, and its ends past
/// one gap; those are kept when they continue the curve ([`Neighbourhood`]). Points
/// scattered over the box (outliers) lie a few to twenty spacings from their nearest
/// neighbour, since a curve's samples crowd along one dimension and theirs spread
/// over two. At the neighbours' reach (14 spacings, what the strokes join across)
/// most outliers have two others within reach and chained into phantom strokes.
pub const ISOLATION_SPACINGS: f64 = 6.0;

/// Samples looked at round a small cluster to find the curve it is nearest, and round
/// that curve's sample to find its tangent.
const CONTINUE_NEAREST: usize = 8;

/// The scale at which a point set's samples are neighbours, and which samples are
/// isolated (outliers): those in a cluster of fewer than [`MIN_CLUSTER`] samples
/// linked by steps of at most [`ISOLATION_SPACINGS`] spacings that lie off the curve
/// nearest them (to its side, not along it), or farther than the reach from every
/// other sample. A curve's samples are one chain of such steps, and the few a gap in
/// its sampling leaves apart continue it; a stray point, or two, is alone. In a noisy
/// band many spacings wide, the samples of its far tails (beyond about 3 sigma) lie to
/// its side past such a gap, and are isolated too.
#[derive(Clone, Debug, PartialEq)]
pub struct Neighbourhood {
    /// The median distance from a sample to its second nearest other sample.
    pub spacing: f64,
    /// [`NEIGHBOUR_SPACINGS`] times `spacing`.
    pub reach: f64,
    /// Per input point, whether it is isolated.
    pub isolated: Vec<bool>,
}

impl Neighbourhood {
    /// The neighbourhood of `points` (validated, as for [`DistanceField::new`]; exact
    /// duplicates count once). With fewer than 16 distinct samples, or no spacing (all
    /// the second neighbours coincident), nothing is isolated: there is no scale to judge
    /// by.
    pub fn of(points: &[Point]) -> Result<Neighbourhood> {
        let field = DistanceField::new(points)?;
        let pts = field.points();
        // Each sample's nearest other and its distance, and the distance to its second.
        let near: Vec<(u32, f64, f64)> = pts
            .par_iter()
            .map_init(Vec::new, |buf, &p| {
                field.nearest_k(p, 3, buf);
                let at = |k: usize| {
                    buf.get(k)
                        .map_or(f64::INFINITY, |&j| dist(p, pts[j as usize]))
                };
                (buf.get(1).copied().unwrap_or(0), at(1), at(2))
            })
            .collect();
        let mut positive: Vec<f64> = near
            .iter()
            .map(|n| n.2)
            .filter(|d| *d > 0.0 && d.is_finite())
            .collect();
        if pts.len() < 16 || positive.is_empty() {
            return Ok(Neighbourhood {
                spacing: 0.0,
                reach: f64::INFINITY,
                isolated: vec![false; points.len()],
            });
        }
        let mid = positive.len() / 2;
        let (_, &mut spacing, _) = positive.select_nth_unstable_by(mid, f64::total_cmp);
        let reach = NEIGHBOUR_SPACINGS * spacing;
        // A cluster of fewer than 3 samples, exactly: a sample with two others within
        // the link has a cluster of 3; one with a single other is in a pair unless that
        // other has a second neighbour; one with none is alone. No search beyond the
        // three nearest, however dense the data.
        debug_assert_eq!(MIN_CLUSTER, 3);
        let small_at = |r: f64| -> Vec<bool> {
            near.iter()
                .map(|&(j, d1, d2)| d2 > r && (d1 > r || near[j as usize].2 > r))
                .collect()
        };
        let link = ISOLATION_SPACINGS * spacing;
        let small = small_at(link);
        let alone = small_at(reach);
        // A small cluster within reach of the rest is a stretch of curve past a gap in
        // its sampling (or a stroke's end) when it lies along the curve from its nearest
        // sample, and an outlier when it lies to the side: the nearest point of a curve
        // to a point off it is along the curve's normal.
        let small: Vec<bool> = (0..pts.len())
            .into_par_iter()
            .map_init(Vec::new, |buf, i| {
                if !small[i] || alone[i] {
                    return small[i];
                }
                let p = pts[i];
                field.nearest_k(p, CONTINUE_NEAREST, buf);
                let Some(q) = buf.iter().map(|&j| j as usize).find(|&j| !small[j]) else {
                    return true;
                };
                let d = [p[0] - pts[q][0], p[1] - pts[q][1]];
                let len = d[0].hypot(d[1]);
                if len > reach {
                    return true;
                }
                // The tangent over q's own stretch: samples across a narrow corridor
                // lie farther than the link and would turn it.
                field.nearest_k(pts[q], CONTINUE_NEAREST, buf);
                buf.retain(|&j| !small[j as usize] && dist(pts[q], pts[j as usize]) <= link);
                let (_, spread) = crate::geom::principal(buf.iter().map(|&j| pts[j as usize]));
                if buf.len() < 2 || spread.trace() <= 0.0 {
                    return true;
                }
                let (_, _, t) = spread.eigen();
                (d[0] * t[0] + d[1] * t[1]).abs() < FRAC_1_SQRT_2 * len
            })
            .collect();
        let isolated = points
            .par_iter()
            .map(|&p| small[field.nearest(p).index as usize])
            .collect();
        Ok(Neighbourhood {
            spacing,
            reach,
            isolated,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn brute(points: &[Point], q: Point) -> f64 {
        points
            .iter()
            .map(|&p| crate::geom::dist(p, q))
            .fold(f64::INFINITY, f64::min)
    }

    /// A noisy circle of 2,000 samples (spacing about 0.8e-3, so a link of 5e-3)
    /// among 100 points scattered over the box: no sample of the circle is isolated
    /// (each would need a gap of 6 spacings on both sides, probability below `e^-10`),
    /// and every scattered point is unless it falls within the link of the circle's
    /// band (a band of `2 * 5e-3` around a circle of length 1.9 holds about 2% of the
    /// box) or of another scattered point: at least 90% of them.
    #[test]
    fn scattered_points_are_isolated_and_a_curves_samples_are_not() {
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let e = Normal::new(0.0, 0.002).unwrap();
        let mut points: Vec<Point> = (0..2_000)
            .map(|_| {
                let a = rng.random::<f64>() * std::f64::consts::TAU;
                let r = 0.3 + e.sample(&mut rng);
                [0.5 + r * a.cos(), 0.5 + r * a.sin()]
            })
            .collect();
        points.extend((0..100).map(|_| [rng.random::<f64>(), rng.random::<f64>()]));
        let n = Neighbourhood::of(&points).unwrap();
        assert!(n.isolated[..2_000].iter().all(|&i| !i));
        let caught = n.isolated[2_000..].iter().filter(|&&i| i).count();
        assert!(caught >= 90, "{caught} of 100");
    }

    /// A straight stroke sampled every 0.01 (`s` = 0.01): a sample 8 spacings past
    /// its end, along it, continues it and stays; one 8 spacings to its side, and a
    /// pair there, lie along its normal and are outliers; one 20 spacings past the end
    /// is beyond the reach and is one too.
    #[test]
    fn a_sample_past_a_gap_along_the_curve_stays_and_one_beside_it_goes() {
        let mut points: Vec<Point> = (0..=100).map(|i| [0.01 * i as f64, 0.0]).collect();
        let probes = [
            ([1.08, 0.0], false),
            ([0.5, 0.08], true),
            ([0.3, -0.08], true),
            ([0.305, -0.08], true),
            ([-0.2, 0.0], true),
        ];
        points.extend(probes.iter().map(|p| p.0));
        let n = Neighbourhood::of(&points).unwrap();
        assert!((n.spacing - 0.01).abs() < 1e-9, "{}", n.spacing);
        assert!(n.isolated[..101].iter().all(|&i| !i));
        for (k, (p, out)) in probes.iter().enumerate() {
            assert_eq!(n.isolated[101 + k], *out, "{p:?}");
        }
    }

    #[test]
    fn matches_brute_force_on_random_data() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let points: Vec<Point> = (0..500)
            .map(|_| [rng.random::<f64>(), rng.random::<f64>()])
            .collect();
        let field = DistanceField::new(&points).unwrap();
        let queries: Vec<Point> = (0..2000)
            .map(|_| {
                [
                    rng.random::<f64>() * 3.0 - 1.0,
                    rng.random::<f64>() * 3.0 - 1.0,
                ]
            })
            .collect();
        let near = field.nearest_all(&queries);
        for (q, n) in queries.iter().zip(&near) {
            let exact = brute(&points, *q);
            assert!((n.dist - exact).abs() <= 1e-14 * (1.0 + exact));
            let p = field.points()[n.index as usize];
            assert!((crate::geom::dist(p, *q) - exact).abs() <= 1e-14 * (1.0 + exact));
        }
    }

    #[test]
    fn duplicates_and_clusters_are_merged_and_exact() {
        // 10,000 copies of one point plus a tight cluster: kd-trees that split on a
        // coordinate can degenerate on such input; the field must stay exact and small.
        let mut points = vec![[0.25, 0.75]; 10_000];
        for i in 0..1000 {
            points.push([0.5 + 1e-12 * (i % 10) as f64, 0.5]);
        }
        points.push([-0.0, 0.0]);
        points.push([0.0, 0.0]);
        let field = DistanceField::new(&points).unwrap();
        assert_eq!(field.points().len(), 1 + 10 + 1);
        for q in [[0.0, 1.0], [0.5, 0.4], [1.0, 1.0], [-3.0, 2.0]] {
            assert!((field.distance(q) - brute(&points, q)).abs() < 1e-14);
        }
    }

    #[test]
    fn rejects_bad_input() {
        assert!(matches!(DistanceField::new(&[]), Err(Error::EmptyPointSet)));
        assert!(matches!(
            DistanceField::new(&[[0.0, 0.0], [f64::NAN, 1.0]]),
            Err(Error::NonFinitePoint { index: 1, .. })
        ));
        assert!(matches!(
            DistanceField::new(&[[1e200, 0.0]]),
            Err(Error::HugeCoordinate { index: 0, .. })
        ));
        // One point is a valid (if degenerate) set.
        let one = DistanceField::new(&[[1.0, 2.0]]).unwrap();
        assert_eq!(one.distance([4.0, 6.0]), 5.0);
        let mut knn = Vec::new();
        one.nearest_k([0.0, 0.0], 8, &mut knn);
        assert_eq!(knn, vec![0]);
    }
}
