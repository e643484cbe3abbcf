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

use isoline_core::SegmentIndex;
use rayon::prelude::*;

use isoline_core::geom::{add, cross, dist, scale, sub, Point, Polyline};

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

/// The midpoints of `polylines` cut into pieces of at most `step`, each with its
/// length: a length share summed over them is exact to the pieces' size (a piece
/// sampled at its start counts a curve's last piece wholly as its start is, which is
/// biased wherever a curve leaves the data: at its ends, where refinement adds
/// vertices).
fn midpoints(polylines: &[Polyline], step: f64) -> Vec<(Point, f64)> {
    let mut out = Vec::new();
    for pl in polylines {
        for (a, b) in pl.segments() {
            let len = dist(a, b);
            let n = ((len / step).ceil() as usize).max(1);
            let w = len / n as f64;
            for k in 0..n {
                out.push((add(a, scale(sub(b, a), (k as f64 + 0.5) / n as f64)), w));
            }
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
        .unwrap_or_else(|| 2.0 * ir.piece().min(it.piece()))
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

/// Scan-aware scores of the curves of one scan frame (docs/formats.md), with one
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
    scan: &isoline_core::Scan,
    tol: f64,
) -> ScanScores {
    let ic = SegmentIndex::new(curves);
    let it = SegmentIndex::new(if surfaces.is_empty() { truth } else { surfaces });
    let returns = scan.returns();
    let explained = returns.iter().filter(|&&p| ic.distance(p) <= tol).count();
    let step = 0.25 * tol;
    let free = swept(scan);
    let (free_len, total_len) = in_free_space(curves, &free, tol, step);
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

/// The polygon a scan's rays swept, as the scores read it: through the returns in beam
/// order; a beam without a return within two beams of returns on both sides is spanned
/// by their chord (a dropout), one farther from any is free to the maximum range.
fn swept(scan: &isoline_core::Scan) -> isoline_core::FreeSpace {
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
    isoline_core::FreeSpace {
        origin: scan.origin,
        angles: scan.angles.clone(),
        reach,
        full_turn: scan.full_turn(),
        max_gap: if scan.free_rays {
            f64::INFINITY
        } else {
            3.0 * scan.step
        },
    }
}

/// The length of `curves` lying in `free` space by more than `tol` (sampled every
/// `step`), and their whole length.
fn in_free_space(
    curves: &[Polyline],
    free: &isoline_core::FreeSpace,
    tol: f64,
    step: f64,
) -> (f64, f64) {
    let boundary = SegmentIndex::new(&[free.polygon()]);
    let (mut free_len, mut total_len) = (0.0, 0.0);
    for (p, w) in samples(curves, step) {
        total_len += w;
        if free.contains(p) && boundary.distance(p) > tol {
            free_len += w;
        }
    }
    (free_len, total_len)
}

/// Scores of a scan frame's curves that need no truth, only the scan: what a user
/// checks on a real recording.
#[derive(Clone, Debug, PartialEq)]
pub struct DataScores {
    /// The tolerance used (`tol`); curves "on the data" are within twice it.
    pub tolerance: f64,
    /// Returns in the frame.
    pub returns: usize,
    /// Share of the returns within `tol` of a curve.
    pub returns_explained: f64,
    /// Mean distance from the explained returns to the nearest curve.
    pub mean_distance: f64,
    /// Share of the curves' length within `2 tol` of a return.
    pub curve_on_data: f64,
    /// Share of the curves' length in space the rays saw as free, by more than `tol`.
    pub free_space_share: f64,
    /// Total length of the curves.
    pub length: f64,
    /// Closed curves.
    pub closed: usize,
    /// Curves with more than `2 tol` of their length in free space within
    /// [`PHANTOM_REACH`] of the sensor: pieces a user would trip over.
    pub phantoms: usize,
    /// Places where a curve crosses a beam nearer than the beam's return by more than
    /// `tol`: space that beam saw through. A segment that only touches a beam at one of
    /// its ends does not cross it.
    pub beam_crossings: usize,
}

/// How near the sensor a curve in free space counts as a phantom, in the scan's units
/// (metres for real sensors).
pub const PHANTOM_REACH: f64 = 1.0;

/// The scores of `curves` against `scan` alone (the frame's beams, in the curves'
/// coordinates), with tolerance `tol` (5 cm for metres).
pub fn data_scores(curves: &[Polyline], scan: &isoline_core::Scan, tol: f64) -> DataScores {
    let ic = SegmentIndex::new(curves);
    let returns = scan.returns();
    let near: Vec<f64> = returns
        .par_iter()
        .map(|&p| ic.distance(p))
        .filter(|&d| d <= tol)
        .collect();
    let step = 0.25 * tol;
    let free = swept(scan);
    let boundary = SegmentIndex::new(&[free.polygon()]);
    let returns_index = isoline_core::DistanceField::new(&returns).ok();
    let (mut on_data, mut free_len, mut total_len) = (0.0, 0.0, 0.0);
    for (p, w) in midpoints(curves, step) {
        total_len += w;
        if returns_index
            .as_ref()
            .is_some_and(|f| f.distance(p) <= 2.0 * tol)
        {
            on_data += w;
        }
        if free.contains(p) && boundary.distance(p) > tol {
            free_len += w;
        }
    }
    let phantoms = curves
        .iter()
        .filter(|c| {
            let near_free: f64 = midpoints(std::slice::from_ref(*c), step)
                .iter()
                .filter(|(p, _)| {
                    dist(*p, scan.origin) <= PHANTOM_REACH
                        && free.contains(*p)
                        && boundary.distance(*p) > tol
                })
                .map(|x| x.1)
                .sum();
            near_free > 2.0 * tol
        })
        .count();
    let share = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    DataScores {
        tolerance: tol,
        returns: returns.len(),
        returns_explained: if returns.is_empty() {
            1.0
        } else {
            near.len() as f64 / returns.len() as f64
        },
        mean_distance: if near.is_empty() {
            0.0
        } else {
            near.iter().sum::<f64>() / near.len() as f64
        },
        curve_on_data: share(on_data, total_len),
        free_space_share: share(free_len, total_len),
        length: total_len,
        closed: curves.iter().filter(|c| c.closed).count(),
        phantoms,
        beam_crossings: beam_crossings(curves, scan, tol),
    }
}

/// How many times `curves` cross a beam of `scan` nearer than its return by more than
/// `margin` ([`DataScores::beam_crossings`] with the tolerance as the margin).
pub fn beam_crossings(curves: &[Polyline], scan: &isoline_core::Scan, margin: f64) -> usize {
    use std::f64::consts::{PI, TAU};
    let (o, angles) = (scan.origin, &scan.angles);
    let Some(&a0) = angles.first() else {
        return 0;
    };
    // A bearing as an angle in [a0, a0 + 2 pi), where the beams' angles lie.
    let bearing = |p: Point| a0 + ((p[1] - o[1]).atan2(p[0] - o[0]) - a0).rem_euclid(TAU);
    let crossings_of = |p: Point, q: Point| -> usize {
        let (bp, bq) = (bearing(p), bearing(q));
        // The bearings the segment sweeps, the shorter way round: one or two ranges.
        let (lo, hi) = if bp <= bq { (bp, bq) } else { (bq, bp) };
        let ranges: Vec<(f64, f64)> = if hi - lo <= PI {
            vec![(lo, hi)]
        } else {
            vec![(a0, lo), (hi, a0 + TAU)]
        };
        let (e, rel) = (sub(q, p), sub(p, o));
        ranges
            .into_iter()
            .flat_map(|(from, to)| {
                let first = angles.partition_point(|&a| a < from);
                let last = angles.partition_point(|&a| a <= to);
                first..last
            })
            .filter(|&i| {
                let r = scan.ranges[i];
                let d = [angles[i].cos(), angles[i].sin()];
                let den = cross(d, e);
                if !r.is_finite() || den == 0.0 {
                    return false;
                }
                let t = cross(rel, e) / den;
                let s = cross(rel, d) / den;
                t > 0.0 && s > 1e-9 && s < 1.0 - 1e-9 && r - t > margin
            })
            .count()
    };
    curves
        .iter()
        .flat_map(|c| c.segments())
        .map(|(p, q)| crossings_of(p, q))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wall at y = 2 seen over x in [0, 0.5] (beams 0.1 degree apart, returns 3.5 mm
    /// apart or closer), drawn as one segment to x = 1.03: the curve lies within
    /// `2 tol` = 0.1 of a return up to x = 0.6, so the share is 0.6 / 1.03. The midpoint
    /// rule errs by at most half a piece (`tol / 8`) where the curve leaves the data;
    /// sampled from each piece's start it counted one piece more (0.64 of a piece).
    #[test]
    fn curve_on_data_is_the_length_share_to_half_a_piece() {
        let n = 141;
        let step = 0.1f64.to_radians();
        let ranges: Vec<Option<f64>> = (0..n)
            .map(|i| Some(2.0 / (std::f64::consts::FRAC_PI_2 - i as f64 * step).sin()))
            .collect();
        let scan = isoline_core::Scan::from_laser(&isoline_core::LaserScan {
            origin: [0.0, 0.0],
            angle_min: std::f64::consts::FRAC_PI_2 - (n - 1) as f64 * step,
            angle_increment: step,
            ranges: &ranges.iter().rev().copied().collect::<Vec<_>>(),
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap();
        let wall = Polyline {
            closed: false,
            points: vec![[0.0, 2.0], [1.03, 2.0]],
        };
        let tol = 0.05;
        let s = data_scores(&[wall], &scan, tol);
        let exact = 0.6 / 1.03;
        assert!(
            (s.curve_on_data - exact).abs() <= 0.5 * 0.25 * tol / 1.03,
            "{} against {exact}",
            s.curve_on_data
        );
        assert_eq!(s.returns_explained, 1.0);
        assert_eq!(s.free_space_share, 0.0);
        assert!((s.length - 1.03).abs() < 1e-12);
    }

    /// A scanner over the half turn ahead (a beam a degree) in front of a wall at y = 2,
    /// but for beam 60, which passes through a gap in it to 6 m: a line at y = 1.9 (10 cm
    /// in front of the wall) crosses that beam 4.1 m short of its return, and its
    /// neighbours by 10 cm or more; with a tolerance of 15 cm it crosses beam 60 alone.
    /// A line 1 cm in front crosses only beam 60, and one behind the wall only beam 60
    /// too. A segment that ends on a beam touches it and does not cross it.
    #[test]
    fn beam_crossings_count_beams_seen_through() {
        let ranges: Vec<Option<f64>> = (0..=180)
            .map(|i| {
                let a = f64::from(i).to_radians();
                Some(if i == 60 { 6.0 } else { 2.0 / a.sin().max(0.2) })
            })
            .collect();
        let scan = isoline_core::Scan::from_laser(&isoline_core::LaserScan {
            origin: [0.0, 0.0],
            angle_min: 0.0,
            angle_increment: 1f64.to_radians(),
            ranges: &ranges,
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap();
        let at = |y: f64, x0: f64, x1: f64| Polyline {
            closed: false,
            points: vec![[x0, y], [x1, y]],
        };
        // From bearing 45 degrees (where it touches beam 45) to 73.9.
        let across = [at(1.9, 0.55, 1.9)];
        let beams = (46..=73).count();
        assert_eq!(data_scores(&across, &scan, 0.05).beam_crossings, beams);
        assert_eq!(data_scores(&across, &scan, 0.15).beam_crossings, 1);
        assert_eq!(
            data_scores(&[at(1.99, 0.55, 1.9)], &scan, 0.05).beam_crossings,
            1
        );
        assert_eq!(
            data_scores(&[at(2.1, 0.6, 2.0)], &scan, 0.05).beam_crossings,
            1
        );
        // Ending on beam 60 (bearing 60 degrees at y = 1.9).
        let x60 = 1.9 / 60f64.to_radians().tan();
        assert_eq!(
            data_scores(&[at(1.9, x60, 1.9)], &scan, 0.15).beam_crossings,
            0
        );
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

/// A world-frame map against the scene it was drawn from ([`map_accuracy`]).
#[derive(Clone, Debug, PartialEq)]
pub struct MapAccuracy {
    /// Distances from the map (sampled a `step` apart) to the nearest wall: the
    /// largest, the 95th percentile and the length-weighted mean.
    pub to_walls_max: f64,
    /// See [`MapAccuracy::to_walls_max`].
    pub to_walls_p95: f64,
    /// See [`MapAccuracy::to_walls_max`].
    pub to_walls_mean: f64,
    /// Share of the map's length within `bound` of a wall.
    pub within_bound: f64,
    /// Length of the walls the scans saw (a return within `seen` of them), metres.
    pub walls_seen: f64,
    /// Share of that length within `bound` of the map.
    pub walls_seen_covered: f64,
}

/// How near a world-frame `map` lies to the scene's `walls`, and how much of the walls
/// the scans saw it draws: `returns` are the scans' returns placed in the world (a
/// sample does), a wall stretch is seen when one lies within `seen` of it, and a
/// stretch is covered, or a stretch of map near, within `bound`. Walls and map are
/// sampled `step` apart.
pub fn map_accuracy(
    map: &[Polyline],
    walls: &[Polyline],
    returns: &[Point],
    seen: f64,
    bound: f64,
    step: f64,
) -> MapAccuracy {
    let wall_index = SegmentIndex::new(walls);
    let map_index = SegmentIndex::new(map);
    let mut to_walls: Vec<(f64, f64)> = samples(map, step)
        .par_iter()
        .map(|&(p, w)| (wall_index.distance(p), w))
        .collect();
    to_walls.sort_by(|a, b| a.0.total_cmp(&b.0));
    let length: f64 = to_walls.iter().map(|x| x.1).sum();
    let near: f64 = to_walls.iter().filter(|x| x.0 <= bound).map(|x| x.1).sum();
    let p95 = to_walls
        .get((to_walls.len() as f64 * 0.95) as usize)
        .or(to_walls.last())
        .map_or(0.0, |x| x.0);
    let hits = isoline_core::DistanceField::new(returns).ok();
    let (seen_len, covered) = samples(walls, step)
        .par_iter()
        .filter(|&&(p, _)| hits.as_ref().is_some_and(|h| h.distance(p) <= seen))
        .map(|&(p, w)| {
            let c = !map_index.is_empty() && map_index.distance(p) <= bound;
            (w, if c { w } else { 0.0 })
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    let ratio = |a: f64, b: f64| if b > 0.0 { a / b } else { 0.0 };
    MapAccuracy {
        to_walls_max: to_walls.last().map_or(0.0, |x| x.0),
        to_walls_p95: p95,
        to_walls_mean: ratio(to_walls.iter().map(|x| x.0 * x.1).sum(), length),
        within_bound: ratio(near, length),
        walls_seen: seen_len,
        walls_seen_covered: ratio(covered, seen_len),
    }
}
