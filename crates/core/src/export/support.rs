//! Curves supported by data (scan frames): the pieces of the zero isoline that run along
//! the returns, cut where the support ends, and the returns no curve explains.
//!
//! A scan's free-space start puts the curve on the whole boundary of what the rays swept,
//! which also runs along depth jumps, occlusion shadows, doorways, the edges of the field
//! of view and the max-range boundary: lines no return lies on. Only the stretches within
//! a tolerance of a run of returns (the surface between neighbouring returns on one
//! wall) are kept, each cut at the point where it leaves the tolerance, found by
//! bisection along the curve.

use crate::geom::{add, dist, point_segment_dist2, scale, sub, Point, Polyline};
use crate::index::SegmentIndex;

/// Bisection steps that place a cut: the cut point is within `step / 2^8` of where the
/// curve leaves the tolerance.
const BISECTIONS: usize = 8;

/// The pieces of `curves` within `tol` of `support`, tested at points at most `step`
/// apart along each curve; pieces shorter than `min_len` are dropped. A closed curve
/// supported everywhere stays closed; the others come out open, in their direction.
///
/// At the end of a run a piece either overshoots, ending in a hook up to `tol` long past
/// the data along the free-space boundary, and is trimmed to end where the curve passes
/// the run's end return (at the curve's point nearest to it); or stops short, where the
/// free space between the last returns is a sliver thinner than the mesh resolves (a
/// wall seen at grazing incidence that ends at an opening), and is extended along the
/// run's last returns to its end.
pub fn cut_to_support(
    curves: &[Polyline],
    support: &[Polyline],
    tol: f64,
    cap: f64,
    step: f64,
    min_len: f64,
) -> Vec<Polyline> {
    let runs = Runs::new(support, tol, cap);
    let supported = |p: Point| runs.supported(p);
    let mut out = Vec::new();
    for c in curves {
        let n = c.points.len();
        if n < 2 {
            continue;
        }
        // Start a closed curve at an unsupported point, so that no piece wraps round.
        let pts: Vec<Point> = if c.closed {
            match first_unsupported(c, &supported, step) {
                None => {
                    out.push(c.clone());
                    continue;
                }
                Some((k, p)) => {
                    let mut v = vec![p];
                    v.extend((1..=n).map(|j| c.points[(k + j) % n]));
                    v.push(p);
                    v
                }
            }
        } else {
            c.points.clone()
        };
        cut_open(&pts, &supported, step, &runs.ends, tol, min_len, &mut out);
    }
    out
}

/// The support's runs, indexed for the test of whether a curve's point is supported.
struct Runs {
    index: SegmentIndex,
    /// Per segment of the index: whether its start, its end is the end of a run.
    run_end: Vec<(bool, bool)>,
    /// Each run end with the run's last two gaps, from the end inwards.
    ends: Vec<Vec<Point>>,
    /// The run ends.
    run_ends: Vec<Point>,
    tol: f64,
    cap: f64,
    /// The last point tested: the point, its distance to the support and to the
    /// nearest run end.
    last: std::cell::Cell<Option<(Point, f64, f64)>>,
}

impl Runs {
    fn new(support: &[Polyline], tol: f64, cap: f64) -> Runs {
        let mut run_end: Vec<(bool, bool)> = Vec::new();
        for pl in support {
            let m = pl.segments().count();
            if m == 0 {
                run_end.extend(pl.points.iter().map(|_| (true, true)));
            }
            for k in 0..m {
                run_end.push((!pl.closed && k == 0, !pl.closed && k + 1 == m));
            }
        }
        let ends: Vec<Vec<Point>> = support
            .iter()
            .filter(|pl| !pl.closed && !pl.points.is_empty())
            .flat_map(|pl| {
                let n = pl.points.len();
                let head: Vec<Point> = pl.points[..n.min(3)].to_vec();
                let tail: Vec<Point> = pl.points[n.saturating_sub(3)..]
                    .iter()
                    .rev()
                    .copied()
                    .collect();
                [head, tail]
            })
            .collect();
        let run_ends = ends.iter().filter_map(|e| e.first().copied()).collect();
        Runs {
            index: SegmentIndex::new(support),
            run_end,
            ends,
            run_ends,
            tol,
            cap,
            last: std::cell::Cell::new(None),
        }
    }

    /// Whether `p`, at `nearest` from the support, is within `tol` of it and not more
    /// than `cap` past a run's end.
    fn exact(&self, p: Point, nearest: Option<(f64, usize, f64)>) -> bool {
        match nearest {
            Some((d, i, t)) if d <= self.tol => {
                let (a, b) = self.index.segments()[i];
                let (at_a, at_b) = self.run_end[i];
                // How far past a run's end along its last segment.
                let past = |end: Point, other: Point| {
                    let dir = sub(end, other);
                    let len = crate::geom::norm(dir);
                    if len > 0.0 {
                        crate::geom::dot(sub(p, end), dir) / len
                    } else {
                        dist(p, end)
                    }
                };
                if t <= 0.0 && at_a {
                    past(a, b) <= self.cap
                } else if t >= 1.0 && at_b {
                    past(b, a) <= self.cap
                } else {
                    true
                }
            }
            _ => false,
        }
    }

    /// Whether `p` is supported. The tests walk along the curves a fraction of `tol` at
    /// a time, and the distance to the support is 1-Lipschitz: from the last point
    /// measured, `p0` at distance `d0` and `e0` from the nearest run end, a point
    /// `delta` away is within `d0 + delta` and beyond `d0 - delta`. Only within `tol` of
    /// a run end can a point within `tol` of the support be unsupported (past the end),
    /// so away from them the bounds decide, and most points need no search.
    fn supported(&self, p: Point) -> bool {
        let tol = self.tol;
        if let Some((p0, d0, e0)) = self.last.get() {
            let delta = dist(p, p0);
            if d0 - delta > tol {
                return false;
            }
            if d0 + delta <= tol && e0 - delta > tol {
                return true;
            }
        }
        let nearest = self.index.nearest(p);
        let e0 = self
            .run_ends
            .iter()
            .map(|&e| dist(e, p))
            .fold(f64::INFINITY, f64::min);
        self.last
            .set(Some((p, nearest.map_or(f64::INFINITY, |n| n.0), e0)));
        self.exact(p, nearest)
    }
}

/// The supported pieces of the open polyline `pts`, tested every `step` along it and
/// cut by bisection where the support starts or ends, flushed into `out`.
fn cut_open(
    pts: &[Point],
    supported: &impl Fn(Point) -> bool,
    step: f64,
    ends: &[Vec<Point>],
    tol: f64,
    min_len: f64,
    out: &mut Vec<Polyline>,
) {
    let mut piece: Vec<Point> = Vec::new();
    let mut on = supported(pts[0]);
    if on {
        piece.push(pts[0]);
    }
    for w in pts.windows(2) {
        let (a, b) = (w[0], w[1]);
        let m = ((dist(a, b) / step).ceil() as usize).max(1);
        let at = |t: f64| add(a, scale(sub(b, a), t));
        let mut t_prev = 0.0;
        for k in 1..=m {
            let t = k as f64 / m as f64;
            let now = supported(at(t));
            if now != on {
                // Bisect between t_prev (state `on`) and t (state `now`).
                let (mut lo, mut hi) = (t_prev, t);
                for _ in 0..BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    if supported(at(mid)) == on {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                if on {
                    piece.push(at(lo));
                    flush(&mut piece, ends, tol, min_len, out);
                } else {
                    piece.push(at(hi));
                }
                on = now;
            }
            t_prev = t;
        }
        if on {
            piece.push(b);
        }
    }
    flush(&mut piece, ends, tol, min_len, out);
}

/// The first point of a closed curve, tested every `step`, that is not supported: the
/// segment it lies on (from vertex `k`) and the point.
fn first_unsupported(
    c: &Polyline,
    supported: &impl Fn(Point) -> bool,
    step: f64,
) -> Option<(usize, Point)> {
    c.segments().enumerate().find_map(|(k, (a, b))| {
        let m = ((dist(a, b) / step).ceil() as usize).max(1);
        (0..m)
            .map(|j| add(a, scale(sub(b, a), j as f64 / m as f64)))
            .find(|&p| !supported(p))
            .map(|p| (k, p))
    })
}

fn flush(
    piece: &mut Vec<Point>,
    ends: &[Vec<Point>],
    tol: f64,
    min_len: f64,
    out: &mut Vec<Polyline>,
) {
    piece.dedup();
    let mut p = Polyline {
        closed: false,
        points: std::mem::take(piece),
    };
    // Crumbs are judged before trimming: a short run (a leg) trims to less than the
    // tolerance and is still a curve.
    if p.points.len() < 2 || p.length() < min_len {
        return;
    }
    // Each end goes to its nearest run end; on a short run both may be nearest to the
    // same one, which then belongs to the nearer end of the piece only.
    let (first, last) = (p.points[0], p.points[p.points.len() - 1]);
    let (mut a, mut b) = (nearest_end(ends, first, tol), nearest_end(ends, last, tol));
    if let (Some((x, dx)), Some((y, dy))) = (a, b) {
        if std::ptr::eq(x, y) {
            if dx <= dy {
                b = None;
            } else {
                a = None;
            }
        }
    }
    if let Some((e, _)) = a {
        to_run_end(&mut p.points, e, tol);
    }
    if let Some((e, _)) = b {
        p.points.reverse();
        to_run_end(&mut p.points, e, tol);
        p.points.reverse();
    }
    p.points.dedup();
    if p.points.len() >= 2 {
        out.push(p);
    }
}

/// The run end (its last returns, from the end inwards) nearest `q` among those whose
/// last gaps pass within `2.5 tol` of it (a hook runs up to `tol` from the support,
/// which itself zigzags through the noisy returns near its end), and its distance.
fn nearest_end(ends: &[Vec<Point>], q: Point, tol: f64) -> Option<(&Vec<Point>, f64)> {
    // Near a short run its two ends' gaps overlap: of the ends whose gaps pass near
    // `q`, the nearest end return wins.
    ends.iter()
        .filter(|tail| {
            let d = if tail.len() < 2 {
                dist(tail[0], q)
            } else {
                tail.windows(2)
                    .map(|w| point_segment_dist2(q, w[0], w[1]).0.sqrt())
                    .fold(f64::INFINITY, f64::min)
            };
            d <= 2.5 * tol
        })
        .map(|tail| (tail, dist(tail[0], q)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// Makes `points` start at the run end `tail[0]`: cut back to the point nearest it
/// (searched over the first `4 tol` of arc length) when the curve passes it, and
/// extended from there along the run's last gap (`tail[0]` to `tail[1]`) when that point
/// is still more than `tol / 2` short of the end and lies along that gap.
fn to_run_end(points: &mut Vec<Point>, tail: &[Point], tol: f64) {
    let Some(&first) = points.first() else { return };
    let end = tail[0];
    let mut best = (dist(end, first), 0usize, first);
    let mut arc = 0.0;
    for k in 0..points.len().saturating_sub(1) {
        let (a, b) = (points[k], points[k + 1]);
        let (d2, t) = point_segment_dist2(end, a, b);
        if d2.sqrt() < best.0 {
            best = (d2.sqrt(), k, add(a, scale(sub(b, a), t)));
        }
        arc += dist(a, b);
        if arc > 4.0 * tol {
            break;
        }
    }
    let (gap, k, q) = best;
    if k > 0 || q != first {
        points.drain(..=k);
        points.insert(0, q);
    }
    if gap <= 0.5 * tol {
        return;
    }
    // Short of the end within the run's last gap: prepend the end return and where the
    // start projects onto that gap.
    let first = q;
    let Some((j, proj)) = tail
        .windows(2)
        .enumerate()
        .map(|(j, w)| {
            let (d2, t) = point_segment_dist2(first, w[0], w[1]);
            (d2, j, add(w[0], scale(sub(w[1], w[0]), t)))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, j, p)| (j, p))
    else {
        return;
    };
    if j > 0 {
        return;
    }
    let mut head: Vec<Point> = vec![tail[0]];
    head.push(proj);
    head.extend_from_slice(points);
    *points = head;
}

/// The parts of `curves` outside the space a scan's beams swept (`swept`,
/// [`crate::scan::Analysis::seen`]) less `margin` ([`crate::scan::seen_margin`]): no
/// piece of a curve crosses a beam nearer than its return by more than the margin;
/// pieces shorter than `min_len` go. The free-space start runs along every
/// boundary of what the rays swept, shadow edges included, and on a mesh coarser than
/// the beams' spacing its zero isoline cuts across the thin wedge of a beam that passed
/// between two objects (past a wall's end, beside a table leg) a few centimetres from
/// the returns, within the support's tolerance of them. Each segment is split where it
/// crosses a beam or the segment between two neighbouring beams' reaches, the only
/// places where it can enter or leave `seen`, so the parts inside are found exactly, not
/// by sampling. A closed curve that `seen` cuts comes out open.
pub fn outside_seen(
    curves: Vec<Polyline>,
    swept: &crate::scan::FreeSpace,
    margin: f64,
    min_len: f64,
) -> Vec<Polyline> {
    let seen = &swept.shrunk(margin);
    let mut out = Vec::with_capacity(curves.len());
    let mut cuts = Vec::new();
    for c in curves {
        let n = c.points.len();
        if n < 2 {
            continue;
        }
        // The curve as a walk of points; a closed one returns to its start.
        let walk: Vec<Point> = if c.closed {
            c.points.iter().chain(c.points.first()).copied().collect()
        } else {
            c.points.clone()
        };
        let mut pieces: Vec<Vec<Point>> = Vec::new();
        let mut piece: Vec<Point> = Vec::new();
        let mut cut = false;
        for w in walk.windows(2) {
            let (a, b) = (w[0], w[1]);
            cuts.clear();
            seen.crossings(a, b, &mut cuts);
            cuts.push(1.0);
            cuts.sort_by(f64::total_cmp);
            let mut s0 = 0.0;
            for &s1 in &cuts {
                if s1 <= s0 {
                    continue;
                }
                let at = |s: f64| add(a, scale(sub(b, a), s));
                let inside = seen.depth(at(0.5 * (s0 + s1))).is_some_and(|d| d > 0.0);
                if inside {
                    cut = true;
                    if piece.len() >= 2 {
                        pieces.push(std::mem::take(&mut piece));
                    }
                    piece.clear();
                } else {
                    if piece.is_empty() {
                        piece.push(at(s0));
                    }
                    piece.push(at(s1));
                }
                s0 = s1;
            }
        }
        if !cut {
            out.push(c);
            continue;
        }
        if piece.len() >= 2 {
            // A closed curve's last piece runs on into its first where the cut is
            // elsewhere.
            if c.closed && walk.first() == pieces.first().and_then(|p| p.first()) {
                let first = pieces.remove(0);
                piece.extend_from_slice(&first[1..]);
            }
            pieces.push(piece);
        }
        for mut points in pieces {
            points.dedup();
            let p = Polyline {
                closed: false,
                points,
            };
            if p.points.len() >= 2 && p.length() >= min_len {
                out.push(p);
            }
        }
    }
    out
}

/// A cluster of returns that no curve explains: consecutive unexplained returns of one
/// run.
#[derive(Clone, Debug, PartialEq)]
pub struct Feature {
    /// The returns' centroid.
    pub center: Point,
    /// How many returns.
    pub returns: usize,
}

/// What one scan can show of each closed curve: a scan sees a surface only from the
/// sensor's side, so a closed curve is possible only round a sensor inside it (a 360°
/// scanner in a room). Any other loop (a sliver round a thin wall, a fold through noisy
/// returns; a loop round a sensor that does not see all round) is opened to the
/// stretches the sensor sees: those whose midpoints lie in its field of view and that
/// the straight line from the sensor reaches without crossing the loop.
pub fn visible_from(polylines: Vec<Polyline>, scan: &crate::scan::Scan) -> Vec<Polyline> {
    let origin = scan.origin;
    let full_turn = scan.full_turn();
    let (first, last) = match (scan.angles.first(), scan.angles.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => return polylines,
    };
    let spacing = (last - first).abs() / scan.angles.len().max(2) as f64;
    let in_view = |m: Point| {
        full_turn || {
            let a = (m[1] - origin[1]).atan2(m[0] - origin[0]);
            (a - first).rem_euclid(std::f64::consts::TAU) <= (last - first) + spacing
        }
    };
    let mut out = Vec::with_capacity(polylines.len());
    for pl in polylines {
        if !pl.closed || pl.points.len() < 3 || (full_turn && pl.encloses(origin)) {
            out.push(pl);
            continue;
        }
        let p = &pl.points;
        let n = p.len();
        let seen: Vec<bool> = (0..n)
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % n]);
                let m = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
                in_view(m)
                    && !(0..n).any(|j| {
                        j != i && {
                            let (c, d) = (p[j], p[(j + 1) % n]);
                            crate::geom::crossing(origin, m, c, d).is_some()
                        }
                    })
            })
            .collect();
        if seen.iter().all(|&s| s) {
            // Only possible for a degenerate loop: keep it as it is.
            out.push(pl);
            continue;
        }
        // Start just after a hidden segment, so that no stretch wraps round.
        let start = (0..n).find(|&i| !seen[i]).map_or(0, |i| i + 1);
        let mut piece: Vec<Point> = Vec::new();
        for k in 0..n {
            let i = (start + k) % n;
            if seen[i] {
                if piece.is_empty() {
                    piece.push(p[i]);
                }
                piece.push(p[(i + 1) % n]);
            } else if piece.len() >= 2 {
                out.push(Polyline {
                    closed: false,
                    points: std::mem::take(&mut piece),
                });
            } else {
                piece.clear();
            }
        }
        if piece.len() >= 2 {
            out.push(Polyline {
                closed: false,
                points: piece,
            });
        }
    }
    out
}

/// The returns farther than `tol` from every curve, grouped into features by run:
/// `runs` lists each run's returns in bearing order.
pub fn unexplained(runs: &[Vec<Point>], curves: &[Polyline], tol: f64) -> Vec<Feature> {
    let index = SegmentIndex::new(curves);
    let mut out = Vec::new();
    for run in runs {
        let mut group: Vec<Point> = Vec::new();
        let mut close = |group: &mut Vec<Point>| {
            if !group.is_empty() {
                let n = group.len() as f64;
                let c = group.iter().fold([0.0, 0.0], |s, p| add(s, *p));
                out.push(Feature {
                    center: scale(c, 1.0 / n),
                    returns: group.len(),
                });
                group.clear();
            }
        };
        // Neighbouring returns lie a fraction of `tol` apart: the distance measured at
        // one bounds it at the next (it is 1-Lipschitz), and decides wherever it can.
        let mut last: Option<(Point, f64)> = None;
        for &p in run {
            let far = match last {
                Some((p0, d0)) if d0 + dist(p, p0) <= tol => false,
                Some((p0, d0)) if d0 - dist(p, p0) > tol => true,
                _ => {
                    let d = index.distance(p);
                    last = Some((p, d));
                    d > tol
                }
            };
            if far {
                group.push(p);
            } else {
                close(&mut group);
            }
        }
        close(&mut group);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scan over the half turn ahead of a sensor at the origin (facing +y).
    fn half_turn() -> crate::scan::Scan {
        let ranges = vec![Some(2.0); 181];
        crate::scan::Scan::from_laser(&crate::scan::LaserScan {
            origin: [0.0, 0.0],
            angle_min: 0.0,
            angle_increment: std::f64::consts::PI / 180.0,
            ranges: &ranges,
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap()
    }

    /// A sliver round a wall ahead of the sensor keeps only the side facing it; a loop
    /// round the sensor of a scanner that does not see all round opens where the field
    /// of view ends; open curves pass as they are.
    #[test]
    fn a_scan_keeps_only_what_the_sensor_sees_of_a_loop() {
        let scan = half_turn();
        let sliver = Polyline {
            closed: true,
            points: vec![[-1.0, 2.0], [1.0, 2.0], [1.0, 2.05], [-1.0, 2.05]],
        };
        let out = visible_from(vec![sliver], &scan);
        assert_eq!(out.len(), 1);
        assert!(!out[0].closed);
        assert!(
            out[0].points.iter().all(|p| p[1] == 2.0),
            "{:?}",
            out[0].points
        );
        let round = Polyline {
            closed: true,
            points: vec![[-2.0, -1.0], [2.0, -1.0], [2.0, 2.0], [-2.0, 2.0]],
        };
        let out = visible_from(vec![round], &scan);
        assert!(out.iter().all(|p| !p.closed));
        // The wall behind the sensor (y = -1) is out of view.
        assert!(out
            .iter()
            .flat_map(|p| p.points.windows(2))
            .all(|w| w[0][1] > -1.0 || w[1][1] > -1.0));
        let open = Polyline {
            closed: false,
            points: vec![[-1.0, 2.0], [1.0, 2.0]],
        };
        assert_eq!(visible_from(vec![open.clone()], &scan), vec![open]);
    }

    fn line(points: &[Point], closed: bool) -> Polyline {
        Polyline {
            closed,
            points: points.to_vec(),
        }
    }

    /// A curve along a wall that then runs on past its end leaves the support where the
    /// cap past the run's end runs out (found by bisection to step / 256), and is then
    /// trimmed to the run's ends.
    #[test]
    fn pieces_end_where_the_support_ends() {
        let wall = [line(&[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], false)];
        let curve = line(&[[-0.5, 0.0], [2.0, 0.0], [2.0, 1.0]], false);
        let (tol, step) = (0.03, 0.01);
        let cut = cut_to_support(std::slice::from_ref(&curve), &wall, tol, tol, step, tol);
        assert_eq!(cut.len(), 1);
        let p = &cut[0].points;
        assert!(dist(p[0], [0.0, 0.0]) < 1e-12, "{p:?}");
        assert!(dist(*p.last().unwrap(), [1.0, 0.0]) < 1e-12, "{p:?}");
        // Without trimming (a closed support has no ends), the cut lies where the
        // tolerance runs out.
        let ring = [line(
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            true,
        )];
        let across = line(&[[0.5, -0.5], [0.5, 0.5]], false);
        let cut = cut_to_support(&[across], &ring, tol, tol, step, 0.0);
        let p = &cut[0].points;
        assert!((p[0][1] + tol).abs() < step / 100.0, "{p:?}");
        assert!((p.last().unwrap()[1] - tol).abs() < step / 100.0, "{p:?}");
    }

    /// The free-space boundary turning away just past a run's end (along a depth jump)
    /// leaves no hook: the support stops `cap` past the end along the run.
    #[test]
    fn no_hook_where_the_boundary_turns_away() {
        let wall = [line(&[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], false)];
        let turn = line(&[[0.5, 0.01], [1.005, 0.01], [1.005, -1.0]], false);
        let cut = cut_to_support(&[turn], &wall, 0.03, 0.01, 0.01, 0.0);
        assert_eq!(cut.len(), 1);
        let p = &cut[0].points;
        // It ends where the curve passes nearest the run's last return.
        assert!(p.iter().all(|q| q[1] > -1e-9), "{p:?}");
        assert!(dist(*p.last().unwrap(), [1.005, 0.0]) < 1e-9, "{p:?}");
        // A curve crossing 0.02 past the run's end, within the tolerance of its last
        // return, is not supported: it runs across the run, not along it.
        let across = line(&[[1.02, 0.5], [1.02, -0.5]], false);
        assert!(cut_to_support(&[across], &wall, 0.03, 0.01, 0.005, 0.01).is_empty());
    }

    /// A closed loop supported all round stays closed; one with a doorway comes out as
    /// one open piece from jamb to jamb, in the loop's direction.
    #[test]
    fn a_loop_closes_only_where_the_data_close_it() {
        let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let full = [line(&square, true)];
        let cut = cut_to_support(&[line(&square, true)], &full, 0.01, 0.01, 0.05, 0.01);
        assert_eq!(cut.len(), 1);
        assert!(cut[0].closed);
        let walls = [line(
            &[
                [0.6, 0.0],
                [1.0, 0.0],
                [1.0, 1.0],
                [0.0, 1.0],
                [0.0, 0.0],
                [0.4, 0.0],
            ],
            false,
        )];
        let cut = cut_to_support(&[line(&square, true)], &walls, 0.01, 0.01, 0.05, 0.01);
        assert_eq!(cut.len(), 1, "{cut:?}");
        let p = &cut[0];
        assert!(!p.closed);
        assert!(dist(p.points[0], [0.6, 0.0]) < 1e-9, "{:?}", p.points[0]);
        assert!(dist(*p.points.last().unwrap(), [0.4, 0.0]) < 1e-9);
        assert!((p.length() - 3.8).abs() < 1e-9);
    }

    #[test]
    fn crumbs_are_dropped_and_lone_returns_reported() {
        let wall = [line(&[[0.0, 0.0], [1.0, 0.0]], false)];
        // The curve crosses the support: 0.02 of it is within the tolerance.
        let curve = line(&[[0.9, 0.5], [0.9, -0.5]], false);
        assert!(cut_to_support(&[curve], &wall, 0.01, 0.01, 0.005, 0.05).is_empty());
        let runs = vec![
            vec![[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]],
            vec![[0.5, 0.5], [0.52, 0.5]],
        ];
        let curves = [line(&[[0.0, 0.001], [1.0, 0.001]], false)];
        let f = unexplained(&runs, &curves, 0.01);
        assert_eq!(f.len(), 1);
        assert_eq!(f[0].returns, 2);
        assert!(dist(f[0].center, [0.51, 0.5]) < 1e-12);
    }

    /// A free space over the half turn ahead of the origin, a beam each degree, every
    /// beam reaching 2 but beam 60, which passed between two objects to 6.
    fn one_beam_through() -> crate::scan::FreeSpace {
        let angles: Vec<f64> = (0..=180).map(|i| f64::from(i).to_radians()).collect();
        let reach = (0..=180).map(|i| if i == 60 { 6.0 } else { 2.0 }).collect();
        crate::scan::FreeSpace {
            origin: [0.0, 0.0],
            angles,
            reach,
            full_turn: false,
            max_gap: f64::INFINITY,
        }
    }

    fn arc(r: f64, from_deg: f64, to_deg: f64) -> Vec<Point> {
        (0..=100)
            .map(|k| {
                let a = (from_deg + (to_deg - from_deg) * f64::from(k) / 100.0).to_radians();
                [r * a.cos(), r * a.sin()]
            })
            .collect()
    }

    /// An arc just behind the reaches keeps all but where it crosses the one beam that
    /// saw past it: it comes out in two pieces that end exactly where the arc meets the
    /// segments joining that beam's reach to its neighbours', and no piece has a point
    /// in the free space. An arc in front of the reaches is in it everywhere.
    #[test]
    fn curves_stop_where_a_beam_saw_through() {
        let free = one_beam_through();
        let behind = line(&arc(2.05, 50.0, 70.0), false);
        let out = outside_seen(vec![behind.clone()], &free, 0.0, 0.0);
        assert_eq!(out.len(), 2, "{out:?}");
        for p in &out {
            for w in p.points.windows(2) {
                let m = [0.5 * (w[0][0] + w[1][0]), 0.5 * (w[0][1] + w[1][1])];
                assert!(free.depth(m).is_none_or(|d| d <= 1e-12), "{m:?}");
            }
        }
        let (end, start) = (*out[0].points.last().unwrap(), out[1].points[0]);
        for q in [end, start] {
            let d = free.depth(q).unwrap();
            assert!(d.abs() < 1e-9, "{q:?} is {d} inside");
        }
        let bearing = |q: Point| q[1].atan2(q[0]).to_degrees();
        assert!(bearing(end) > 59.0 && bearing(end) < 60.0, "{end:?}");
        assert!(bearing(start) > 60.0 && bearing(start) < 61.0, "{start:?}");
        // What is gone is the stretch between the two cuts.
        let kept: f64 = out.iter().map(Polyline::length).sum();
        assert!((behind.length() - kept - dist(end, start)).abs() < 1e-3 * dist(end, start));
        let in_front = line(&arc(1.95, 50.0, 70.0), false);
        assert!(outside_seen(vec![in_front], &free, 0.0, 0.0).is_empty());
    }

    /// A closed curve wholly behind the reaches stays as it is; one that a beam saw
    /// through comes out open, in one piece from one side of the cut round to the other.
    #[test]
    fn a_loop_a_beam_saw_through_opens_there() {
        let free = one_beam_through();
        let mut square = arc(2.05, 30.0, 40.0);
        square.extend(arc(2.3, 40.0, 30.0));
        let kept = outside_seen(vec![line(&square, true)], &free, 0.0, 0.0);
        assert_eq!(kept, vec![line(&square, true)]);
        // Its far side lies past the beam's reach.
        let mut across = arc(2.05, 55.0, 65.0);
        across.extend(arc(6.5, 65.0, 55.0));
        let out = outside_seen(vec![line(&across, true)], &free, 0.0, 0.0);
        assert_eq!(out.len(), 1, "{out:?}");
        assert!(!out[0].closed);
        let bearing = |q: Point| q[1].atan2(q[0]).to_degrees();
        let (a, b) = (out[0].points[0], *out[0].points.last().unwrap());
        assert!(bearing(a) > 60.0 && bearing(a) < 61.0, "{a:?}");
        assert!(bearing(b) > 59.0 && bearing(b) < 60.0, "{b:?}");
        // Crumbs shorter than the least length go.
        assert!(
            outside_seen(vec![line(&arc(2.05, 59.5, 60.5), false)], &free, 0.0, 0.05).is_empty()
        );
    }
}
