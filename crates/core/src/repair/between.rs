//! Loops between consecutive clean samples. [`through`](super::through) moves a vertex
//! only where the five samples nearest it lie on one circle; next to a corner those
//! samples span both walls, so the level set's rounding (or its cut) of the corner
//! stays, by up to `4 hmin`, and so does a short wall's bulge between a corner and the
//! next sample. Clean samples ordered along a loop say more. Where the five samples up
//! to one and the five from the next each lie on their own circle and neither circle
//! holds the other's sample, two walls meet between the two: at the corner where those
//! circles run on to cross, as [`gaps`](super::gaps) places a corner across a sampling
//! gap. (A circle may pass the other's sample where the two circles cross twice; then
//! the samples cannot tell which crossing is the corner, and the curve runs midway.)
//! Elsewhere the curve between two consecutive samples is the circle through five
//! consecutive samples with these two among them (and no corner between), as a spline
//! through them would draw it.
//!
//! The level set found which samples follow which; this only draws the curve between
//! them, so a stretch of the loop is replaced only by a piece that keeps near it.

use rayon::prelude::*;

use super::gaps::{continued, corner, hermite, End, Loop};
use super::through::implicit_circle;
use super::Tolerances;
use crate::distance::DistanceField;
use crate::geom::{add, cross, dist, dot, norm, polyline_dist, scale, sub, Point, Polyline};
use crate::index::SegmentIndex;

/// A run of samples' curve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Curve {
    /// The line through `at` along the unit vector `dir`.
    Line { at: Point, dir: Point },
    /// The circle about `centre` of radius `r`.
    Circle { centre: Point, r: f64 },
}

impl Curve {
    /// The circle (or line) through `run` (in order along it), if they lie on it to
    /// within `fit_tol` with a slope against the chord from the first to the last of at
    /// most `max_slope` (steeper, the run turns back and is no stretch of one wall).
    pub(super) fn through(run: &[Point], fit_tol: f64, max_slope: f64) -> Option<Curve> {
        let (o, last) = (run[0], run[run.len() - 1]);
        let span = dist(o, last);
        if span <= 0.0 {
            return None;
        }
        let x = scale(sub(last, o), 1.0 / span);
        let y = [-x[1], x[0]];
        let mut local: Vec<(f64, f64)> = run
            .iter()
            .map(|&q| (dot(sub(q, o), x), dot(sub(q, o), y)))
            .collect();
        let (a, b, c, off) = implicit_circle(&mut local)?;
        if off > fit_tol || b.abs() > max_slope {
            return None;
        }
        // A radius a billion spans long is a line to rounding.
        if c.abs() * span < 1e-9 {
            let dir = add(x, scale(y, b));
            return Some(Curve::Line {
                at: add(o, scale(y, a)),
                dir: scale(dir, 1.0 / norm(dir)),
            });
        }
        let disc = 1.0 + b * b - 4.0 * a * c;
        (disc > 0.0).then(|| Curve::Circle {
            centre: add(o, add(scale(x, -b / (2.0 * c)), scale(y, 1.0 / (2.0 * c)))),
            r: disc.sqrt() / (2.0 * c.abs()),
        })
    }

    /// [`Curve::through`] the samples `s(j)` for `j` in `run`.
    fn of_run(
        s: impl Fn(isize) -> Point,
        run: std::ops::Range<isize>,
        fit_tol: f64,
        t: &Tolerances,
    ) -> Option<Curve> {
        let points: Vec<Point> = run.map(s).collect();
        Curve::through(&points, fit_tol, t.between_max_slope)
    }

    /// Where the curve crosses the line through `p` with unit normal `n`: none, one or
    /// two points.
    pub(super) fn meets_line(&self, p: Point, n: Point) -> Vec<Point> {
        let e = [-n[1], n[0]];
        match *self {
            Curve::Line { at, dir } => {
                let along = dot(n, dir);
                if along.abs() < 1e-12 {
                    return Vec::new();
                }
                vec![add(at, scale(dir, dot(n, sub(p, at)) / along))]
            }
            Curve::Circle { centre, r } => {
                // |p + s e - centre|² = r², with |e| = 1.
                let w = sub(p, centre);
                let half_b = dot(e, w);
                let disc = half_b * half_b - (dot(w, w) - r * r);
                if disc < 0.0 {
                    return Vec::new();
                }
                let sq = disc.sqrt();
                vec![
                    add(p, scale(e, -half_b - sq)),
                    add(p, scale(e, -half_b + sq)),
                ]
            }
        }
    }

    /// The distance from `p` to the curve.
    fn off(&self, p: Point) -> f64 {
        match *self {
            Curve::Line { at, dir } => cross(dir, sub(p, at)).abs(),
            Curve::Circle { centre, r } => (dist(p, centre) - r).abs(),
        }
    }

    /// The curve's direction at `p` (a point on it) along `along`, with its curvature
    /// (left positive).
    fn end(&self, p: Point, along: Point) -> Option<End> {
        let (t, k) = match *self {
            Curve::Line { dir, .. } => (dir, 0.0),
            Curve::Circle { centre, r } => {
                let out = sub(p, centre);
                (scale([-out[1], out[0]], 1.0 / norm(out)), 1.0 / r)
            }
        };
        let t = if dot(t, along) < 0.0 {
            scale(t, -1.0)
        } else {
            t
        };
        // Round the centre to the left: turning left.
        let k = match *self {
            Curve::Circle { centre, .. } if cross(t, sub(centre, p)) < 0.0 => -k,
            _ => k,
        };
        (t.iter().all(|v| v.is_finite()) && k.is_finite()).then_some(End {
            tangent: t,
            curvature: Some(k),
        })
    }
}

/// Replaces each stretch of the closed polylines of `curves` between two consecutive
/// samples of `field` along it (those within `tol` of it, this loop their nearest
/// curve) by the curve they imply, sampled every `step`: where the five samples up to
/// the first and the five from the second each lie on a circle (or line) to within
/// `fit_tol` and neither holds the other's sample (but by a chance crossing of the
/// two, then midway between it and the next), the corner where the two circles
/// run on to cross, turning by 11 degrees at least; else the arc of a circle through
/// five consecutive samples with both among them and no corner, or the Hermite arc
/// between two runs' circles where the curvature jumps between the samples. A stretch
/// is replaced only by a piece within `2 tol` of it both ways (a corner: within `tol`,
/// or the samples' distance where that is more), and only if it is at most four times
/// as long as that distance and the reach together. Open polylines and loops with
/// fewer than ten samples stay. Returns the indices of the polylines changed.
pub fn between_samples(
    curves: &mut [Polyline],
    field: &DistanceField,
    tol: f64,
    fit_tol: f64,
    step: f64,
    t: &Tolerances,
) -> Vec<usize> {
    let mut changed = Vec::new();
    let positive = |x: f64| x.is_finite() && x > 0.0;
    if !(positive(tol) && positive(fit_tol) && positive(step)) {
        return changed;
    }
    let (mut chains, ats, totals) = samples_along(curves, field, tol);
    for (k, chain) in chains.iter_mut().enumerate() {
        chain.sort_by(|u, v| u.0.total_cmp(&v.0));
        // Two samples at one place along the loop have no order.
        chain.dedup_by(|u, v| u.0 == v.0);
        if chain.len() < 2 * t.between_run {
            continue;
        }
        let old = curves[k].points.clone();
        let at = &ats[k];
        let m = chain.len();
        let sample = |i: usize, j: isize| chain[(i as isize + j).rem_euclid(m as isize) as usize].1;
        // The loop's vertices after sample `i`'s foot, up to sample `i + 1`'s.
        let stretch = |i: usize| -> Vec<Point> {
            let (from, to) = (chain[i].0, chain[(i + 1) % m].0);
            let after = at.partition_point(|&s| s <= from);
            let upto = at.partition_point(|&s| s <= to);
            let mut v: Vec<Point> = if from < to {
                old[after..upto].to_vec()
            } else {
                old[after..].iter().chain(&old[..upto]).copied().collect()
            };
            v.insert(0, chain[i].2);
            v.push(chain[(i + 1) % m].2);
            v
        };
        // A piece is taken only if it keeps near the stretch it replaces, and that
        // stretch is one between neighbours (not a loop's way round a part it left
        // unsampled, which would also cost a comparison of every pair of points).
        let near = |i: usize, inner: Vec<Point>, reach: f64| {
            let length = (chain[(i + 1) % m].0 - chain[i].0).rem_euclid(totals[k]);
            if length > 4.0 * (dist(sample(i, 0), sample(i, 1)) + reach) {
                return None;
            }
            let mut new = vec![sample(i, 0)];
            new.extend_from_slice(&inner);
            new.push(sample(i, 1));
            let was = stretch(i);
            (apart(&new, &was) <= reach && apart(&was, &new) <= reach).then_some(inner)
        };
        // Corners first: a run of samples that holds both walls' (as a smooth piece's
        // would, by chance) must not round one.
        let corners: Vec<Option<Vec<Point>>> = (0..m)
            .into_par_iter()
            .map(|i| {
                let inner = corner_piece(|j| sample(i, j), fit_tol, step, t)?;
                near(i, inner, tol.max(dist(sample(i, 0), sample(i, 1))))
            })
            .collect();
        let is_corner = |i: usize, j: isize| {
            corners[(i as isize + j).rem_euclid(m as isize) as usize].is_some()
        };
        let pieces: Vec<Option<Vec<Point>>> = (0..m)
            .into_par_iter()
            .map(|i| match &corners[i] {
                Some(inner) => Some(inner.clone()),
                None => {
                    let inner = between(|j| sample(i, j), |j| is_corner(i, j), fit_tol, step, t)?;
                    near(i, inner, 2.0 * tol)
                }
            })
            .collect();
        if pieces.iter().all(Option::is_none) {
            continue;
        }
        let mut points = Vec::with_capacity(old.len());
        for i in 0..m {
            if pieces[i].is_some() || pieces[(i + m - 1) % m].is_some() {
                points.push(chain[i].1);
            }
            match &pieces[i] {
                Some(inner) => points.extend_from_slice(inner),
                None => {
                    let was = stretch(i);
                    // The foot of the next sample is the next stretch's first point.
                    points.extend_from_slice(&was[1..was.len() - 1]);
                }
            }
        }
        curves[k].points = points;
        changed.push(k);
    }
    changed
}

/// A sample near a closed loop: its arc length along the loop, the sample, its foot.
type Along = (f64, Point, Point);

/// The samples of `field` within `tol` of the closed polylines of `curves` (with at
/// least three points), by their nearest loop (unsorted), with each loop's vertices'
/// arc lengths and its length.
#[allow(clippy::type_complexity)]
fn samples_along(
    curves: &[Polyline],
    field: &DistanceField,
    tol: f64,
) -> (Vec<Vec<Along>>, Vec<Vec<f64>>, Vec<f64>) {
    let index = SegmentIndex::new(curves);
    let starts: Vec<usize> = (0..curves.len()).map(|k| index.start(k)).collect();
    let loops: Vec<Loop<'_>> = curves.iter().map(|pl| Loop::new(&pl.points)).collect();
    // Each sample near a loop: the loop, its arc length along it, the sample, its foot.
    let near: Vec<(usize, f64, Point, Point)> = field
        .points()
        .par_iter()
        .filter_map(|&p| {
            let (d, seg, t) = index.nearest(p)?;
            let k = starts.partition_point(|&s| s <= seg) - 1;
            let pl = &curves[k];
            if d > tol || !pl.closed || pl.points.len() < 3 {
                return None;
            }
            let (a, b) = index.segments()[seg];
            let along = loops[k].at[seg - starts[k]] + t * dist(a, b);
            Some((k, along, p, add(a, scale(sub(b, a), t))))
        })
        .collect();
    // Owned: the caller replaces the loops' points.
    let (ats, totals): (Vec<Vec<f64>>, Vec<f64>) =
        loops.into_iter().map(|l| (l.at, l.total)).unzip();
    let mut chains: Vec<Vec<Along>> = vec![Vec::new(); curves.len()];
    for (k, along, p, foot) in near {
        chains[k].push((along, p, foot));
    }
    (chains, ats, totals)
}

/// The inner points of the curve between the samples `s(0)` and `s(1)` (`s(j)` the
/// `j`-th after `s(0)` along the loop, before it where negative) where no corner lies
/// between them: runs of `between_run` consecutive samples whose pairs (`corner(j)` for the
/// pair from `s(j)`) hold no corner, lying on a circle to within `fit_tol`, say which.
/// - The run ending at `s(0)` and the one starting at `s(1)` each hold the other sample
///   (or neither lies on a circle): a smooth stretch, on the circle of a run with
///   these two among them, the two in its middle first.
/// - One holds the other sample and the other not: a corner at a sample, the arc on
///   the first's circle.
/// - Neither holds the other sample, each lying on its own circle (or, a side too
///   short for five, four samples of it): where a curve's curvature jumps (a bend's
///   end) or it turns by less than a corner, the Hermite arc between the two circles'
///   tangents; any circle through samples of both is one by chance.
fn between(
    s: impl Fn(isize) -> Point,
    corner: impl Fn(isize) -> bool,
    fit_tol: f64,
    step: f64,
    t: &Tolerances,
) -> Option<Vec<Point>> {
    let (p, q) = (s(0), s(1));
    let c = dist(p, q);
    if c <= 0.0 {
        return None;
    }
    let n = t.between_run as isize;
    let curve = |first: isize| {
        if (first..first + n - 1).any(&corner) {
            return None;
        }
        Curve::of_run(&s, first..first + n, fit_tol, t)
    };
    let (before, after) = (curve(1 - n), curve(1));
    let holds = |c: Option<Curve>, x: Point| c.map(|c| c.off(x) <= fit_tol);
    let on = match (holds(before, q), holds(after, p)) {
        (Some(true), Some(true)) | (None, None) => {
            let mut firsts: Vec<isize> = (2 - n..=0).collect();
            firsts.sort_by_key(|&f| (2 * f + n - 2).abs());
            firsts.into_iter().find_map(curve).or(before)?
        }
        // The run through both that holds nothing past them, else the side's own.
        (Some(true), _) => curve(2 - n).or(before)?,
        (_, Some(true)) => curve(0).or(after)?,
        // Neither holds the other's sample.
        _ => {
            // A side too short for five samples (a cap's end): four on a circle.
            let short = |first: isize| Curve::of_run(&s, first..first + n - 1, fit_tol, t);
            let before = before.or_else(|| short(2 - n));
            let after = after.or_else(|| short(1));
            let a = before?.end(p, sub(p, s(-1)))?;
            let b = after?.end(q, sub(s(2), q))?;
            // A turn of a corner's size is one that `corner` could not place.
            if dot(a.tangent, b.tangent) < t.corner_min_turn.cos() {
                return None;
            }
            let mut arc = Vec::new();
            let limits = (t.arc_max_turn, t.arc_max_bulge);
            hermite(p, q, a.tangent, b.tangent, limits, step, &mut arc)?;
            return Some(arc);
        }
    };
    let end = on.end(p, sub(q, p))?;
    let k = end.curvature.unwrap_or(0.0);
    let length = if k.abs() * c < 1e-9 {
        c
    } else {
        2.0 * (0.5 * k.abs() * c).min(1.0).asin() / k.abs()
    };
    let mut arc = continued(p, end.tangent, k, length, step);
    arc.pop();
    arc.remove(0);
    Some(arc)
}

/// The inner points of the path between the samples `s(0)` and `s(1)` (as for
/// [`between`]) round the corner where the circles of the `between_run` samples up to
/// `s(0)` and of those from `s(1)` on meet, as [`corner`] finds it: each side's curve
/// taken along the loop's run into `s(0)` and out of `s(1)` (the chord between them
/// may run nearly across a side at an acute corner).
fn corner_piece(
    s: impl Fn(isize) -> Point,
    fit_tol: f64,
    step: f64,
    t: &Tolerances,
) -> Option<Vec<Point>> {
    let (p, q) = (s(0), s(1));
    let n = t.between_run as isize;
    let curve = |first: isize| Curve::of_run(&s, first..first + n, fit_tol, t);
    let (before, after) = (curve(1 - n)?, curve(1)?);
    // Either side's curve running on through the other's first sample: a smooth
    // stretch whose curvature changes fast (two runs' circles may cross there), or a
    // corner at that sample, the run holding it one round the corner. Or a chance,
    // where that sample lies nearer its own run's circle than the other's, and the
    // circles cross there by a corner's turn and again farther on: the samples cannot
    // tell the two crossings apart, and the piece runs midway between them.
    let held = |x: Point, own: Curve, other: Curve| {
        let off = other.off(x);
        (off <= fit_tol).then_some(own.off(x) < off)
    };
    let (q_held, p_held) = (held(q, after, before), held(p, before, after));
    if q_held == Some(false) || p_held == Some(false) {
        return None;
    }
    let at_p = before.end(p, sub(p, s(-1)))?;
    let at_q = after.end(q, sub(s(2), q))?;
    let limits = (t.between_min_turn, t.between_max_side_turn, t.arc_max_turn);
    let path = corner(p, q, at_p, at_q, limits, step)?;
    if (q_held.is_some() || p_held.is_some()) && !path.midway {
        return None;
    }
    Some(path.inner)
}

/// The largest distance of a point of `a` to the polyline `b`.
fn apart(a: &[Point], b: &[Point]) -> f64 {
    a.iter().map(|&x| polyline_dist(x, b)).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`between_samples`] with the default tolerances.
    fn drawn(
        curves: &mut [Polyline],
        samples: &[Point],
        tol: f64,
        fit: f64,
        step: f64,
    ) -> Vec<usize> {
        between_samples(
            curves,
            &field(samples),
            tol,
            fit,
            step,
            &Tolerances::default(),
        )
    }

    #[test]
    fn a_curve_meets_a_line_where_they_cross() {
        let circle = Curve::Circle {
            centre: [1.0, 2.0],
            r: 1.0,
        };
        let mut xs: Vec<Point> = circle.meets_line([5.0, 2.5], [0.0, 1.0]);
        xs.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let h = 0.75f64.sqrt();
        assert!(dist(xs[0], [1.0 - h, 2.5]) < 1e-12 && dist(xs[1], [1.0 + h, 2.5]) < 1e-12);
        assert!(circle.meets_line([0.0, 3.5], [0.0, 1.0]).is_empty());
        let line = Curve::Line {
            at: [0.0, 0.0],
            dir: [0.6, 0.8],
        };
        let x = line.meets_line([0.0, 4.0], [0.0, 1.0]);
        assert!(x.len() == 1 && dist(x[0], [3.0, 4.0]) < 1e-12, "{x:?}");
        assert!(line.meets_line([1.0, 0.0], [0.8, -0.6]).is_empty());
    }

    fn field(samples: &[Point]) -> DistanceField {
        DistanceField::new(samples).unwrap()
    }

    /// The distance from `p` to the boundary of the unit square.
    fn off_square(p: Point) -> f64 {
        let inside = p[0].min(p[1]).min(1.0 - p[0]).min(1.0 - p[1]);
        let (dx, dy) = ((p[0] - 0.5).abs() - 0.5, (p[1] - 0.5).abs() - 0.5);
        if inside >= 0.0 {
            inside
        } else {
            dx.max(0.0).hypot(dy.max(0.0))
        }
    }

    /// The unit square sampled every 0.05 with no sample within 0.025 of a corner, and
    /// a loop 1e-3 inside it that cuts each corner by a chamfer 0.03 long: each side's
    /// five samples lie on its line, so the corners come back where the lines cross
    /// and every vertex lies on the square, to rounding (1e-12).
    #[test]
    fn unsampled_corners_come_back_where_the_sides_cross() {
        let mut samples = Vec::new();
        for i in 0..20 {
            let s = 0.025 + 0.05 * i as f64;
            samples.extend([[s, 0.0], [1.0, s], [1.0 - s, 1.0], [0.0, 1.0 - s]]);
        }
        let e = 1e-3;
        let corners = [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]];
        let mut points: Vec<Point> = Vec::new();
        for k in 0..4 {
            // Along the side into corner k, 1e-3 inside, stopping 0.03 short of it.
            let (from, to) = (corners[(k + 3) % 4], corners[k]);
            let dir = sub(to, from);
            let inward = [-dir[1], dir[0]];
            points.extend((0..=188).map(|j| {
                add(
                    add(from, scale(dir, 0.03 + 0.005 * j as f64)),
                    scale(inward, e),
                )
            }));
        }
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        assert_eq!(drawn(&mut curves, &samples, 4e-3, 2.5e-4, 1e-3), [0]);
        let out = &curves[0].points;
        let worst = out.iter().map(|&p| off_square(p)).fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst:e}");
        for c in corners {
            let d = out
                .iter()
                .map(|&p| dist(p, c))
                .fold(f64::INFINITY, f64::min);
            assert!(d < 1e-12, "{c:?}: {d:e}");
        }
        // Before, the chamfers were 0.02 off the corners.
        let before = corners
            .iter()
            .map(|&c| {
                points
                    .iter()
                    .map(|&p| dist(p, c))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(0.0, f64::max);
        assert!(before > 0.02, "{before}");
    }

    /// A square of side 0.2 sampled every 2.5e-3, but for its corner at the origin,
    /// where the samples crowd as a random sampling left them (the square row of the
    /// accuracy table): three on the bottom side 4.7e-3, 1.1e-3 and 5e-4 from the
    /// corner, three up the right side at 7e-4, 1.1e-3 and 2.4e-3. Five of them round
    /// the corner lie on a circle of a millimetre to the fit tolerance, which crosses
    /// the sides' lines: without asking that neither side's curve runs on through the
    /// other's first sample, pairs along the straight sides were taken for corners (a
    /// side bent by 2.7e-4, stretches left 5e-4 off). Every vertex lies on the square
    /// to 1e-12 but round the crowded corner, where it is within the fit tolerance.
    #[test]
    fn a_side_that_runs_on_through_the_next_sample_has_no_corner() {
        let (w, d) = (0.2, 2.5e-3);
        let mut samples: Vec<Point> = Vec::new();
        for i in 0..80 {
            let s = d * (i as f64 + 0.5);
            samples.extend([[-w + s, w], [-w, s], [-s, w]]);
            if s > 0.01 {
                samples.extend([[-s, 0.0], [0.0, s]]);
            }
        }
        samples.extend([[-4.7e-3, 0.0], [-1.1e-3, 0.0], [-5e-4, 0.0]]);
        samples.extend([[0.0, 7e-4], [0.0, 1.1e-3], [0.0, 2.4e-3]]);
        samples.extend([[-7.6e-3, 0.0], [-8.9e-3, 0.0], [0.0, 5.9e-3], [0.0, 8.7e-3]]);
        let off = |p: Point| {
            let q = [p[0] + 0.5 * w, p[1] - 0.5 * w];
            let inside = (0.5 * w - q[0].abs()).min(0.5 * w - q[1].abs());
            let (dx, dy) = (q[0].abs() - 0.5 * w, q[1].abs() - 0.5 * w);
            if inside >= 0.0 {
                inside
            } else {
                dx.max(0.0).hypot(dy.max(0.0))
            }
        };
        // 5e-4 inside, a vertex every 1e-3, round the square's corners.
        let e = 5e-4;
        let corners = [[0.0, 0.0], [0.0, w], [-w, w], [-w, 0.0]];
        let mut points: Vec<Point> = Vec::new();
        for k in 0..4 {
            let (from, to) = (corners[(k + 3) % 4], corners[k]);
            let dir = scale(sub(to, from), 1.0 / w);
            let inward = [-dir[1], dir[0]];
            points.extend(
                (0..200).map(|j| add(add(from, scale(dir, 1e-3 * j as f64)), scale(inward, e))),
            );
        }
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        drawn(&mut curves, &samples, 4e-3, 2.5e-4, 1e-3);
        for &p in &curves[0].points {
            let limit = if norm(p) < 0.01 { 2.5e-4 } else { 1e-12 };
            assert!(off(p) <= limit, "{p:?}: {:e}", off(p));
        }
    }

    /// A circle of radius 0.05 sampled 31 times, and a loop 1.5e-3 inside it: five
    /// samples of a circle lie on it, so every piece is an arc of it and every vertex
    /// lies on it to rounding (1e-12 at this radius).
    #[test]
    fn a_loop_inside_a_clean_circle_comes_onto_it() {
        let circle = |r: f64, n: usize, phase: f64| -> Vec<Point> {
            (0..n)
                .map(|i| std::f64::consts::TAU * (i as f64 + phase) / n as f64)
                .map(|a| [r * a.cos(), r * a.sin()])
                .collect()
        };
        let mut curves = vec![Polyline {
            closed: true,
            points: circle(0.0485, 200, 0.3),
        }];
        let samples = circle(0.05, 31, 0.0);
        assert_eq!(drawn(&mut curves, &samples, 2e-3, 1e-4, 1e-3), [0]);
        let worst = curves[0]
            .points
            .iter()
            .map(|&p| (norm(p) - 0.05).abs())
            .fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst:e}");
    }

    /// An ellipse of axes 0.4 and 0.08 (curvature from 0.5 to 62.5) sampled at 160
    /// even parameter steps, and a loop 0.5% smaller (1.6e-3 off at the ends). Where
    /// the curvature changes fast, two runs' circles are no corner, and a run that
    /// holds the next sample is not run on past its last: the arc is on a circle
    /// through both samples of the pair, which interpolates. Every vertex comes within
    /// 5e-5 of the ellipse (half the fit tolerance; running the run on instead leaves
    /// 7.9e-5).
    #[test]
    fn a_fast_changing_curvature_is_no_corner() {
        let (a, b) = (0.4, 0.08);
        let ellipse = |n: usize, s: f64| -> Vec<Point> {
            (0..n)
                .map(|i| std::f64::consts::TAU * i as f64 / n as f64)
                .map(|t| [s * a * t.cos(), s * b * t.sin()])
                .collect()
        };
        let samples = ellipse(160, 1.0);
        let dense = ellipse(200_000, 1.0);
        let off = |p: Point| {
            dense
                .iter()
                .map(|&q| dist(p, q))
                .fold(f64::INFINITY, f64::min)
        };
        let mut curves = vec![Polyline {
            closed: true,
            points: ellipse(1000, 0.995),
        }];
        drawn(&mut curves, &samples, 4e-3, 1e-4, 1e-3);
        let worst = curves[0].points.iter().map(|&p| off(p)).fold(0.0, f64::max);
        assert!(worst <= 5e-5, "{worst:e}");
    }

    /// A circle of radius 0.3 sampled every 0.01 and a loop 4e-4 inside it, but for a
    /// bulge 0.012 out between two samples (farther than twice the tolerance, 4e-3):
    /// that stretch stays the loop's own; the rest comes onto the circle.
    #[test]
    fn a_stretch_far_off_the_samples_curve_stays() {
        let n = 188;
        let at = |a: f64, r: f64| [r * a.cos(), r * a.sin()];
        let step = std::f64::consts::TAU / n as f64;
        let samples: Vec<Point> = (0..n).map(|i| at(step * i as f64, 0.3)).collect();
        // Between the samples at angles 0 and `step`.
        let bulge = |a: f64| {
            if a > 0.2 * step && a < 0.8 * step {
                0.012
            } else {
                0.0
            }
        };
        let points: Vec<Point> = (0..10 * n)
            .map(|i| 0.1 * step * (i as f64 + 0.5))
            .map(|a| at(a, 0.3 - 4e-4 + bulge(a)))
            .collect();
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        drawn(&mut curves, &samples, 4e-3, 1e-4, 1e-3);
        let out = &curves[0].points;
        for p in points.iter().filter(|p| norm(**p) > 0.31) {
            assert!(out.contains(p), "{p:?} moved");
        }
        let off = out
            .iter()
            .filter(|p| p[1] < -0.05 || p[0] < 0.0)
            .map(|p| (norm(*p) - 0.3).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-12, "{off:e}");
    }

    /// The distance from `p` to the stadium of half-length `l` and radius `r` about the
    /// origin (its straight sides `y = ±r`).
    fn off_stadium(p: Point, l: f64, r: f64) -> f64 {
        (dist([p[0].clamp(-l, l), 0.0], p) - r).abs()
    }

    /// A half disc of radius 0.1: its diameter sampled every 0.01 up to 0.005 from the
    /// corners, its arc only from 1.2 radians off them (the corners' pairs 0.11 apart,
    /// over which the arc's circle turns by 1.1 radians), and a loop 1e-3 inside that
    /// cuts the corners by chords 0.02 long. The arc's five-sample runs hold their circle to
    /// rounding, so the corners come back where it crosses the diameter's line: every
    /// vertex lies on the half disc's boundary to within the sagitta of a step on the
    /// circle (1e-3² / 0.8 = 1.25e-6), one at each corner. Run on by one radian over a
    /// chord at most, as the gaps' fits are, the circle left the loop as it was there
    /// (1e-3 inside, the corners cut).
    #[test]
    fn a_circle_runs_on_round_to_its_corner() {
        let r = 0.1;
        let on_arc = |a: f64, r: f64| [r * a.cos(), r * a.sin()];
        let mut samples: Vec<Point> = (0..20).map(|i| [-0.095 + 0.01 * i as f64, 0.0]).collect();
        let (a0, a1) = (1.2, std::f64::consts::PI - 1.2);
        let arcs = ((a1 - a0) * r / 0.01).round() as usize;
        samples.extend((0..=arcs).map(|i| on_arc(a0 + (a1 - a0) * i as f64 / arcs as f64, r)));
        // The loop, counter-clockwise: the diameter, a chord to the arc, the arc, a chord.
        let e = 1e-3;
        let mut points: Vec<Point> = (0..=196).map(|i| [-0.098 + 0.001 * i as f64, e]).collect();
        let (b0, b1) = (0.2, std::f64::consts::PI - 0.2);
        points.extend((0..=200).map(|i| on_arc(b0 + (b1 - b0) * i as f64 / 200.0, r - e)));
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        drawn(&mut curves, &samples, 4e-3, 2.5e-4, 1e-3);
        let off = |p: Point| {
            let to_arc = (norm(p) - r).abs();
            if p[1] <= 0.0 || p[0].abs() > r {
                dist([p[0].clamp(-r, r), 0.0], p).min(to_arc)
            } else {
                p[1].min(to_arc)
            }
        };
        let out = &curves[0].points;
        let worst = out.iter().map(|&p| off(p)).fold(0.0, f64::max);
        assert!(worst <= 1.25e-6, "{worst:e}");
        for c in [[r, 0.0], [-r, 0.0]] {
            let d = out
                .iter()
                .map(|&p| dist(p, c))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= 1.25e-6, "{c:?}: {d:e}");
        }
    }

    /// A stadium (half-length 0.2, radius 0.02) sampled every 0.01 along its sides and
    /// its left cap, its right cap at four points only, and a loop 1e-3 inside it.
    /// Between the last sample of a side and the first of the right cap the curvature
    /// jumps; the cap's five-sample run reaches the other side and lies on no circle,
    /// its four samples do, and the Hermite arc between the side's line and that
    /// circle keeps within the fit tolerance (2.5e-4) of the stadium, where the loop
    /// was left 1e-3 inside without it.
    #[test]
    fn a_short_cap_meets_its_sides_smoothly() {
        let (l, r) = (0.2, 0.02);
        let mut samples: Vec<Point> = Vec::new();
        for i in 0..40 {
            let x = -l + 0.005 + 0.01 * i as f64;
            samples.extend([[x, -r], [x, r]]);
        }
        let cap = |a: f64, r: f64, x: f64| [x + r * a.cos(), r * a.sin()];
        let half = std::f64::consts::FRAC_PI_2;
        samples.extend((1..6).map(|i| cap(half + 0.5 * i as f64, r, -l)));
        samples.extend((0..4).map(|i| cap(-half + 0.6 + 0.65 * i as f64, r, l)));
        let e = 1e-3;
        let mut points: Vec<Point> = (0..=400)
            .map(|i| [-l + 0.001 * i as f64, -(r - e)])
            .collect();
        points.extend(
            (1..100).map(|i| cap(-half + std::f64::consts::PI * i as f64 / 100.0, r - e, l)),
        );
        points.extend((0..=400).map(|i| [l - 0.001 * i as f64, r - e]));
        points.extend(
            (1..100).map(|i| cap(half + std::f64::consts::PI * i as f64 / 100.0, r - e, -l)),
        );
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        drawn(&mut curves, &samples, 4e-3, 2.5e-4, 1e-3);
        // Between the bottom side's last sample and the cap's first, and between the
        // cap's last and the top side's first (short of the feet of the cap's samples,
        // past which the loop between them, which no run of five holds, stays).
        let (first, last) = (cap(-half + 0.6, r, l), cap(-half + 2.55, r, l));
        let junction = |p: &&Point| {
            (p[1] < 0.0 && p[0] > l - 0.005 && p[0] < first[0] - 2e-3)
                || (p[1] > 0.0 && p[0] > l - 0.005 && p[0] < last[0] - 2e-3)
        };
        let near: Vec<f64> = curves[0]
            .points
            .iter()
            .filter(junction)
            .map(|&p| off_stadium(p, l, r))
            .collect();
        assert!(near.len() > 10, "{}", near.len());
        let worst = near.iter().copied().fold(0.0, f64::max);
        assert!(worst <= 2.5e-4, "{worst:e}");
    }

    proptest::proptest! {
        /// Samples round a circle, clean or not, among scattered others, and a loop
        /// wandering across them (or any samples and any loop), through both clean
        /// passes in the pipeline's order: onto the samples (every vertex stays finite
        /// and moves by less than `tol`, none added or lost), then between them (the
        /// loop stays closed with finite vertices).
        #[test]
        fn loops_stay_whole_whatever_the_input(
            r in 0.05f64..0.5,
            angles in proptest::collection::vec(0.0f64..std::f64::consts::TAU, 5..80),
            noise in proptest::collection::vec(-1e-3f64..1e-3, 80),
            clean in proptest::bool::ANY,
            offsets in proptest::collection::vec(-0.01f64..0.01, 3..200),
            scattered in proptest::collection::vec([-1.0f64..1.0, -1.0f64..1.0], 0..20),
            tol in 1e-3f64..0.05,
            fit_tol in 1e-5f64..1e-2,
        ) {
            let mut samples: Vec<Point> = angles
                .iter()
                .zip(&noise)
                .map(|(&a, &e)| {
                    let r = r + if clean { 0.0 } else { e };
                    [r * a.cos(), r * a.sin()]
                })
                .collect();
            samples.extend(&scattered);
            let n = offsets.len();
            let points: Vec<Point> = offsets
                .iter()
                .enumerate()
                .map(|(i, &o)| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    [(r + o) * a.cos(), (r + o) * a.sin()]
                })
                .collect();
            let field = field(&samples);
            let mut curves = vec![Polyline { closed: true, points: points.clone() }];
            crate::repair::through::through_samples(&mut curves, &field, tol, fit_tol, &Tolerances::default());
            proptest::prop_assert_eq!(curves[0].points.len(), n);
            for (p, q) in curves[0].points.iter().zip(&points) {
                proptest::prop_assert!(p[0].is_finite() && p[1].is_finite());
                proptest::prop_assert!(dist(*p, *q) < tol);
            }
            between_samples(&mut curves, &field, tol, fit_tol, 0.1 * tol, &Tolerances::default());
            proptest::prop_assert!(curves[0].closed && curves[0].points.len() >= 3);
            for p in &curves[0].points {
                proptest::prop_assert!(p[0].is_finite() && p[1].is_finite());
            }
        }
    }

    /// The clean spiral's inner end (seed 15 of the gap table, its samples about the
    /// centre of the data): its cap, a circle of radius 0.04, meets the wall, turning by
    /// 23 degrees at the corner, which lies in a gap between samples 0.043 apart. The
    /// cap's circle, curving the other way, crosses the wall's again 0.02 from the
    /// corner and passes the wall's last sample there by 1.7e-4, within the fit
    /// tolerance: the samples imply a corner at either crossing. Taken for a corner at
    /// that sample, the cap's circle ran on up to it, 2.1e-3 off the wall (over the
    /// `2 hmin` bound of 1.9e-3). Midway between the two, the piece keeps within 1e-3
    /// of the truth, about half the lens between the circles.
    #[test]
    fn a_circle_through_the_next_wall_sample_by_chance_leaves_the_corner_in_doubt() {
        let s = [
            [0.0863220, 0.0484178],
            [0.0955439, 0.0350806],
            [0.1026003, 0.0170949],
            [0.1037598, 0.0113940],
            [0.1041141, 0.0088934],
            [0.1044417, -0.0041277],
            [0.1080361, -0.0473798],
            [0.1113052, -0.0511679],
            [0.1170623, -0.0560305],
            [0.1181723, -0.0567760],
            [0.1262249, -0.0607850],
            [0.1300098, -0.0619525],
        ];
        let at = |j: isize| s[(j + 5) as usize];
        let (fit_tol, hmin) = (2.33e-4, 9.32e-4);
        // The truth: the wall, r = 0.06 + 0.16 t / 2 pi round the spiral's centre, and
        // the cap's lower half circle, in the same frame.
        let (centre, cap) = ([0.0398856, -0.0231946], [0.1398856, -0.0231946]);
        let wall: Vec<Point> = (0..=4000)
            .map(|i| {
                let t = 0.6 * i as f64 / 4000.0;
                let r = 0.06 + 0.16 * t / std::f64::consts::TAU;
                add(centre, [r * t.cos(), r * t.sin()])
            })
            .collect();
        let off_truth = |v: Point| {
            let below = v[1] <= cap[1];
            let to_cap = if below {
                (dist(v, cap) - 0.04).abs()
            } else {
                f64::INFINITY
            };
            polyline_dist(v, &wall).min(to_cap)
        };
        let inner = corner_piece(at, fit_tol, hmin, &Tolerances::default()).unwrap();
        let off = inner.iter().map(|&v| off_truth(v)).fold(0.0, f64::max);
        assert!(off < 1e-3, "{off}");
    }

    /// A bay's circle meeting an inlet's straight wall (the bays 0.06 apart, clean, seed
    /// 30), and the gap between the wall's second and third samples. The run of five up
    /// to the second holds three of the bay's and the wall's first two on a circle of
    /// radius 0.022 (the bay's is 0.09) to 6.8e-4, within the loose fit tolerance of
    /// these samples; the wall's line from the third holds the second to 1e-8. That
    /// circle crosses the line at the second sample and again farther on, but the sample
    /// lies on the line, not on its own run's circle by chance: no piece is drawn midway
    /// (it bowed 5.3e-4 off the wall, and the stretch round it rose to 3.2e-3 from the
    /// truth).
    #[test]
    fn a_run_round_a_corner_is_no_chance_crossing() {
        let s = [
            [0.2617495, -0.0835943],
            [0.2627211, -0.0906474],
            [0.2629647, -0.0935998],
            [0.2630620, -0.0954670],
            [0.2621923, -0.1124902],
            [0.2630624, -0.1166750],
            [0.2665020, -0.1186609],
            [0.2909877, -0.1327977],
            [0.3001108, -0.1380649],
            [0.3003615, -0.1382097],
            [0.3153863, -0.1468842],
            [0.3282951, -0.1543371],
        ];
        let at = |j: isize| s[(j + 6) as usize];
        assert_eq!(
            corner_piece(at, 9.34e-4, 3.74e-3, &Tolerances::default()),
            None
        );
    }
}
