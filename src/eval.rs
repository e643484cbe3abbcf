//! Accuracy of a reconstruction against ground truth: symmetric Hausdorff and mean
//! distances between polyline sets, and component counts; for scan frames, the scores a
//! robotics user judges a wall extractor by ([`scan_scores`]).
//!
//! Distances are exact point-to-segment distances, found through a kd-tree over the
//! midpoints of the segments cut into pieces of bounded length: the nearest piece by
//! midpoint bounds the answer, and only pieces whose midpoint lies within that bound
//! plus half a piece can do better. Each polyline is sampled at its vertices and at
//! points at most `step` apart along its segments, so the reported Hausdorff distance
//! is within `step / 2` below the continuous one (distance is 1-Lipschitz).

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use rayon::prelude::*;

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
        let found = tree
            .query(&q)
            .within::<SquaredEuclidean<f64>>(r * r)
            .unsorted()
            .execute();
        for c in found {
            let i = self.piece_seg[c.item as usize] as usize;
            let s = self.segs[i];
            let (d2, t) = point_segment_dist2(q, s.0, s.1);
            if d2 < best.0 || (d2 == best.0 && i < best.1) {
                best = (d2, i, t);
            }
        }
        Some((best.0.sqrt(), best.1, best.2))
    }
}

/// Sample points of `polylines` (vertices plus points at most `step` apart) with their
/// arc-length weights.
fn samples(polylines: &[Polyline], step: f64) -> Vec<(Point, f64)> {
    let mut out = Vec::new();
    for pl in polylines {
        let mut any = false;
        for (a, b) in pl.segments() {
            any = true;
            let len = dist(a, b);
            let n = ((len / step).ceil() as usize).max(1);
            let w = len / n as f64;
            for k in 0..n {
                out.push((add(a, scale(sub(b, a), k as f64 / n as f64)), w));
            }
            if !pl.closed && b == *pl.points.last().unwrap() {
                out.push((b, 0.0));
            }
        }
        if !any {
            out.extend(pl.points.iter().map(|&p| (p, 0.0)));
        }
    }
    out
}

/// Directed distances from samples of `from` to `to`: (max, arc-length-weighted mean).
fn directed(from: &[Polyline], to: &SegmentIndex, step: f64) -> (f64, f64) {
    let s = samples(from, step);
    let (mx, sum, wsum, cnt) = s
        .par_iter()
        .map(|&(p, w)| {
            let d = to.distance(p);
            (d, d * w, w, d)
        })
        .reduce(
            || (0.0, 0.0, 0.0, 0.0),
            |a, b| (a.0.max(b.0), a.1 + b.1, a.2 + b.2, a.3 + b.3),
        );
    let mean = if wsum > 0.0 {
        sum / wsum
    } else if !s.is_empty() {
        cnt / s.len() as f64
    } else {
        0.0
    };
    (mx, mean)
}

/// Accuracy metrics of a reconstruction.
#[derive(Clone, Debug, PartialEq)]
pub struct Accuracy {
    /// Symmetric Hausdorff distance (`None` when either side is empty).
    pub hausdorff: Option<f64>,
    /// Mean of the two directed arc-length-weighted mean distances.
    pub mean_distance: Option<f64>,
    /// Largest distance from the reconstruction to the truth.
    pub recon_to_truth: Option<f64>,
    /// Largest distance from the truth to the reconstruction.
    pub truth_to_recon: Option<f64>,
    /// Polylines in the truth.
    pub components_truth: usize,
    /// Polylines in the reconstruction.
    pub components_recon: usize,
}

/// Compares `recon` with `truth`. `step` bounds the sampling gap (see the module doc);
/// `None` uses twice the shorter median segment length of the two sets: the finer set is
/// then sampled at its vertices, the coarser one as finely, and the Hausdorff distance is
/// exact to within one median segment length of the finer set.
pub fn compare(recon: &[Polyline], truth: &[Polyline], step: Option<f64>) -> Accuracy {
    compare_surfaces(recon, truth, truth, step)
}

/// [`compare`] with a truth in two parts: what the reconstruction must cover (`truth`,
/// for a scan the visible, resolvable stretches of surface), and where it may lie
/// (`surfaces`, every surface there is): the distance from the reconstruction is taken
/// to `surfaces`, the distance to it from `truth`.
pub fn compare_surfaces(
    recon: &[Polyline],
    truth: &[Polyline],
    surfaces: &[Polyline],
    step: Option<f64>,
) -> Accuracy {
    let ir = SegmentIndex::new(recon);
    let it = SegmentIndex::new(truth);
    let is = SegmentIndex::new(surfaces);
    let base = Accuracy {
        hausdorff: None,
        mean_distance: None,
        recon_to_truth: None,
        truth_to_recon: None,
        components_truth: truth.len(),
        components_recon: recon.len(),
    };
    if ir.is_empty() || it.is_empty() {
        return base;
    }
    let step = step
        .unwrap_or_else(|| 4.0 * ir.half_piece.min(it.half_piece))
        .max(1e-12);
    let (rt, mrt) = directed(recon, if is.is_empty() { &it } else { &is }, step);
    let (tr, mtr) = directed(truth, &ir, step);
    Accuracy {
        hausdorff: Some(rt.max(tr)),
        mean_distance: Some(0.5 * (mrt + mtr)),
        recon_to_truth: Some(rt),
        truth_to_recon: Some(tr),
        ..base
    }
}

/// Scan-aware scores of the curves of one scan frame (DESIGN.md section 7), with one
/// tolerance `tol` (by default three times the range noise).
#[derive(Clone, Debug, PartialEq)]
pub struct ScanScores {
    /// The tolerance used.
    pub tolerance: f64,
    /// Returns in the frame.
    pub returns: usize,
    /// Share of the returns within `tol` of a curve.
    pub returns_explained: f64,
    /// Share of the curves' length lying in space the rays saw as free by more than
    /// `tol`: inside the polygon through the returns in beam order (a beam without a
    /// return is spanned by the chord of returns within two beams on both sides, a
    /// dropout; otherwise it is free up to the maximum range).
    pub free_space_share: f64,
    /// Openings (doorways) of which more than a fifth of the width, away from the jambs
    /// by `max(0.1, 2 tol)`, has a curve within `tol`.
    pub openings_bridged: usize,
    /// Openings scored.
    pub openings: usize,
    /// Stretches of curve longer than `5 tol` farther than `tol` from every surface:
    /// curves where the truth has none.
    pub gaps_bridged: usize,
    /// Visible stretches of surface of which less than half has a curve within `tol`.
    pub walls_missed: usize,
}

/// The scan-aware scores of `curves` on `scan` (the frame's beams, in the curves'
/// coordinates) against the visible `truth`, every `surfaces` there is (the visible
/// truth when empty) and the `openings` in the walls.
pub fn scan_scores(
    curves: &[Polyline],
    truth: &[Polyline],
    surfaces: &[Polyline],
    openings: &[(Point, Point)],
    scan: &crate::scan::Scan,
    tol: f64,
) -> ScanScores {
    let ic = SegmentIndex::new(curves);
    let it = SegmentIndex::new(if surfaces.is_empty() { truth } else { surfaces });
    let returns = scan.returns();
    let explained = returns.iter().filter(|&&p| ic.distance(p) <= tol).count();
    let step = 0.25 * tol;
    // Curve in free space, by arc length: inside the polygon the rays swept (a beam
    // without a return within two beams of returns on both sides is spanned by their
    // chord, as a dropout; one farther from any is free to the maximum range) by more
    // than the tolerance.
    let n = scan.angles.len();
    let reach: Vec<f64> = (0..n)
        .map(|i| {
            if scan.valid(i) {
                return scan.ranges[i];
            }
            let before = (1..=2).find_map(|o| i.checked_sub(o).filter(|&j| scan.valid(j)));
            let after = (1..=2).find_map(|o| Some(i + o).filter(|&j| j < n && scan.valid(j)));
            match (before, after) {
                (Some(a), Some(b)) => {
                    let f = (i - a) as f64 / (b - a) as f64;
                    scan.ranges[a] * (1.0 - f) + scan.ranges[b] * f
                }
                _ => scan.range_max,
            }
        })
        .collect();
    let free = crate::scan::FreeSpace {
        origin: scan.origin,
        angles: scan.angles.clone(),
        reach,
        full_turn: scan.full_turn(),
        max_gap: if scan.free_rays {
            f64::INFINITY
        } else {
            3.0 * scan.step
        },
    };
    let boundary = SegmentIndex::new(&[free.polygon()]);
    let (mut free_len, mut total_len) = (0.0, 0.0);
    for (p, w) in samples(curves, step) {
        total_len += w;
        if free.contains(p) && boundary.distance(p) > tol {
            free_len += w;
        }
    }
    let openings_bridged = openings
        .iter()
        .filter(|&&(a, b)| {
            let len = dist(a, b);
            let keep = (0.1f64).max(2.0 * tol);
            if len <= 2.0 * keep {
                return false;
            }
            let m = ((len - 2.0 * keep) / step).ceil().max(1.0) as usize;
            let covered = (0..m)
                .filter(|&k| {
                    let t = (keep + (k as f64 + 0.5) / m as f64 * (len - 2.0 * keep)) / len;
                    ic.distance(add(a, scale(sub(b, a), t))) <= tol
                })
                .count();
            covered as f64 > 0.2 * m as f64
        })
        .count();
    // Stretches of curve away from the truth.
    let mut gaps_bridged = 0;
    for c in curves {
        let mut run = 0.0;
        let mut counted = false;
        for (a, b) in c.segments() {
            let m = ((dist(a, b) / step).ceil() as usize).max(1);
            let w = dist(a, b) / m as f64;
            for k in 0..m {
                let p = add(a, scale(sub(b, a), (k as f64 + 0.5) / m as f64));
                if it.distance(p) > tol {
                    run += w;
                    if run > 5.0 * tol && !counted {
                        gaps_bridged += 1;
                        counted = true;
                    }
                } else {
                    run = 0.0;
                    counted = false;
                }
            }
        }
    }
    let walls_missed = truth
        .iter()
        .filter(|t| {
            let s = samples(std::slice::from_ref(*t), step);
            let total: f64 = s.iter().map(|x| x.1).sum();
            let near: f64 = s
                .iter()
                .filter(|x| ic.distance(x.0) <= tol)
                .map(|x| x.1)
                .sum();
            total > 0.0 && near < 0.5 * total
        })
        .count();
    ScanScores {
        tolerance: tol,
        returns: returns.len(),
        returns_explained: if returns.is_empty() {
            1.0
        } else {
            explained as f64 / returns.len() as f64
        },
        free_space_share: if total_len > 0.0 {
            free_len / total_len
        } else {
            0.0
        },
        openings_bridged,
        openings: openings.len(),
        gaps_bridged,
        walls_missed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    use rand::{Rng, SeedableRng};

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
    fn concentric_circles_differ_by_the_radius_difference() {
        let a = circle(0.4, 2000);
        let b = circle(0.3, 1500);
        let acc = compare(&[a], &[b], None);
        // Polygons inscribed in the circles: the chord sag r (1 - cos(pi/n)) is below 1e-6.
        let h = acc.hausdorff.unwrap();
        assert!((h - 0.1).abs() < 2e-6, "{h}");
        assert!((acc.mean_distance.unwrap() - 0.1).abs() < 2e-6);
        assert_eq!((acc.components_recon, acc.components_truth), (1, 1));
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

    #[test]
    fn one_sided_and_empty_cases() {
        let a = circle(0.4, 400);
        let b = Polyline {
            closed: false,
            points: vec![[0.9, 0.5], [0.9, 0.6]],
        };
        let acc = compare(std::slice::from_ref(&b), std::slice::from_ref(&a), None);
        assert!(acc.recon_to_truth.unwrap() < 0.02);
        assert!(acc.truth_to_recon.unwrap() > 0.5);
        let none = compare(&[], &[a], None);
        assert_eq!((none.hausdorff, none.components_recon), (None, 0));
    }
}
