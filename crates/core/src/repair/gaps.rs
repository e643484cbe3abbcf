//! Closed curves across sampling gaps. Where consecutive samples lie far apart, no data
//! hold the level set: it settles where attraction and curvature balance (arcs of radius
//! `1 / alpha` that cut a bend short, or dip between sparse clean samples), or stays
//! where the solve stopped on the coarse mesh there, zigzagging; and it does not reach
//! into a corner narrower than those arcs, passing by the samples there. A stretch of a
//! loop with no sample within the data's tolerance is therefore replaced by cubic
//! Hermite arcs from one supported end to the other through the samples it passed by,
//! with the samples' tangents: the smooth curve the samples imply, as a spline through
//! them would draw it. Where the two sides' own curves (their lines, or their osculating
//! circles) run on to meet within a chord, turning there by 40 degrees or more, they
//! meet at that corner instead. A stretch that already runs along those arcs stays the
//! level set's.
//!
//! The tangents' length is `c / cos²(θ / 4)` for a chord `c` and a turn `θ` between the
//! ends' tangents, which makes the arc a circle's to within 3e-4 of the radius over a
//! quarter turn (the classic four-thirds-tangent Bézier arc) and to a few percent over a
//! half turn. An arc is only taken where it stays within `0.6 c` of the chord (a half
//! circle reaches `c / 2`) and clear of every other part of the curves.

use nalgebra::{Matrix3, Vector3};

use crate::distance::DistanceField;
use crate::geom::{
    add, cross, crossing, dist, dot, mid, norm, polyline_dist, scale, sub, Point, Polyline, Sym2,
};
use crate::index::SegmentIndex;

use super::Tolerances;

/// Vertices per arc, at most.
const MAX_ARC_VERTICES: usize = 4096;

/// A knot's direction, from the samples' fit there.
#[derive(Clone, Copy, Debug)]
pub(super) struct End {
    /// Unit tangent along the loop.
    pub(super) tangent: Point,
    /// The fitted curve's curvature (zero for a line), where it holds the samples.
    pub(super) curvature: Option<f64>,
}

/// The samples' local fits that give an arc its ends' tangents.
pub(super) struct Fit<'a> {
    pub(super) field: &'a DistanceField,
    pub(super) sigma: f64,
    pub(super) t: &'a Tolerances,
}

/// Replaces every stretch of the closed polylines of `curves` whose vertices lie
/// farther than `tol` from every sample of `field` (or one long segment whose middle
/// does) by Hermite arcs from its one supported end to the other through the samples it
/// passed by (farther than `tol` from the curves, this stretch their nearest part),
/// sampled every `step` at most, where the stretch strays more than `step` from them.
/// The tangents are the samples' own: a quadratic fitted to those near each knot (at an
/// end, on its side only), their line where it holds them or where the noise (`sigma`)
/// hides the curvature; two sides whose curves run on to meet within one and a half
/// chords, turning by `t.corner_min_turn` or more, meet at that corner. Arcs are taken
/// where each turns less than `t.arc_max_turn`, stays within `t.arc_max_bulge` chords of
/// its chord and all keep `tol` from every other part of the curves. Open polylines are
/// left as they are. Returns the indices of the polylines changed.
pub fn span_gaps(
    curves: &mut [Polyline],
    field: &DistanceField,
    sigma: f64,
    tol: f64,
    step: f64,
    t: &Tolerances,
) -> Vec<usize> {
    if !(tol.is_finite() && tol > 0.0 && step.is_finite() && step > 0.0 && sigma >= 0.0) {
        return Vec::new();
    }
    let fit = Fit { field, sigma, t };
    let index = SegmentIndex::new(curves);
    let mut spans = Vec::new();
    for (k, pl) in curves.iter().enumerate() {
        if !pl.closed || pl.points.len() < 8 {
            continue;
        }
        let loop_ = Loop::new(&pl.points);
        let n = pl.points.len();
        for gap in loop_.unsupported(field, tol, step) {
            let clear = |window: (usize, usize), p: Point| {
                index.nearest(p).is_none_or(|(d, seg, _)| {
                    d > tol || {
                        let local = seg.wrapping_sub(index.start(k));
                        local < n && in_cyclic(local, window, n)
                    }
                })
            };
            let skipped = skipped_samples(&loop_, gap, field, &index, k, tol, step);
            if let Some(arc) = loop_.span(gap, &skipped, &fit, tol, step, clear) {
                spans.push((k, gap, arc));
            }
        }
    }
    let mut changed = Vec::new();
    // Each loop rebuilt once, its arcs in the order of the walk round it.
    let mut spans = spans.into_iter().peekable();
    while let Some(&(k, _, _)) = spans.peek() {
        let pl = &mut curves[k];
        let n = pl.points.len();
        let mut arcs: Vec<(Gap, Vec<Point>)> = Vec::new();
        while let Some((_, gap, arc)) = spans.next_if(|s| s.0 == k) {
            arcs.push((gap, arc));
        }
        let start = arcs[0].0.a;
        let mut points = Vec::with_capacity(n);
        let mut i = start;
        let mut next = arcs.iter().peekable();
        // Gaps are disjoint and begin at supported vertices, so the walk comes back to
        // `start`; at most `n` moves all the same.
        for _ in 0..n {
            points.push(pl.points[i]);
            match next.next_if(|(gap, _)| gap.a == i) {
                Some((gap, arc)) => {
                    points.extend_from_slice(arc);
                    i = gap.b;
                }
                None => i = (i + 1) % n,
            }
            if i == start {
                break;
            }
        }
        pl.points = points;
        changed.push(k);
    }
    changed
}

impl Fit<'_> {
    /// The reach of the samples an end's tangent is fitted to, for a chord `c`: a
    /// quarter of it, and four noise deviations at least.
    pub(super) fn reach(&self, c: f64) -> f64 {
        (0.25 * c).max(4.0 * self.sigma)
    }

    /// The unit tangent of the samples' curve at `p` (a curve vertex near them),
    /// fitted to the samples within `reach` of the nearest (at least `arc_min_fit` of the tolerances) and
    /// pointing along the first of `along` that is not across it, with the curvature
    /// where a quadratic was fitted. `None` when they give no direction, or every
    /// `along` runs across it.
    pub(super) fn tangent(
        &self,
        p: Point,
        reach: f64,
        along: &[Point],
        gap: Option<Point>,
    ) -> Option<End> {
        let field = self.field;
        let centre = field.points()[field.nearest(p).index as usize];
        // At a gap's end, only the samples on this side: past the end, those of the
        // other side (a corner's other wall) would bend the fit round it.
        let this_side = |q: &Point| gap.is_none_or(|g| dot(sub(*q, centre), g) <= 0.0);
        let mut ids = Vec::new();
        field.within(centre, reach, &mut ids);
        let mut pts: Vec<Point> = ids
            .iter()
            .map(|&i| field.points()[i as usize])
            .filter(this_side)
            .collect();
        if pts.len() < self.t.arc_min_fit {
            // Sparse samples: the nearest on this side, but within four times the reach
            // (the next wall of a spiral lies a few spacings away).
            field.nearest_k(centre, 4 * self.t.arc_min_fit, &mut ids);
            pts = ids
                .iter()
                .map(|&i| field.points()[i as usize])
                .filter(|q| this_side(q) && dist(*q, centre) <= 4.0 * reach)
                .take(self.t.arc_min_fit)
                .collect();
        }
        if pts.len() < 2 {
            return None;
        }
        let inv = 1.0 / pts.len() as f64;
        let c = pts.iter().fold([0.0, 0.0], |s, &q| add(s, scale(q, inv)));
        let cov = pts
            .iter()
            .fold(Sym2::default(), |s, &q| s.plus(Sym2::outer(sub(q, c))));
        let (l1, l2, e) = cov.eigen();
        if l1.is_nan() || l1 <= 0.0 || l2 >= 0.5 * l1 {
            return None;
        }
        let mut x = scale(e, 1.0 / norm(e));
        let lean = along
            .iter()
            .map(|&v| (dot(x, v), norm(v)))
            .find(|&(l, v)| v > 0.0 && l.abs() >= 0.3 * v)?
            .0;
        if lean < 0.0 {
            x = scale(x, -1.0);
        }
        let y = [-x[1], x[0]];
        let u_p = dot(sub(p, c), x);
        // Their line where it holds them (a straight side, of no curvature), or where
        // a quadratic y = a + b u + c u^2 does not halve its residual (the noise hides
        // the curvature); else the quadratic, with its curvature.
        let line = (l2 * inv).max(0.0).sqrt();
        let (slope, curvature) = if pts.len() < 3 {
            // Too few for a line to be a test of straightness.
            (0.0, None)
        } else if line <= 1e-3 * (l1 * inv).sqrt() {
            // On a line to a thousandth of their spread (clean samples, rounded as
            // written).
            (0.0, Some(0.0))
        } else {
            let local: Vec<(f64, f64)> = pts
                .iter()
                .map(|&q| (dot(sub(q, c), x), dot(sub(q, c), y)))
                .collect();
            quadratic(&local, u_p, line, self.sigma)
        };
        let t = add(x, scale(y, slope));
        Some(End {
            tangent: scale(t, 1.0 / norm(t)),
            curvature,
        })
    }
}

/// The slope at `u_p` and the curvature of samples `local` (along and across their
/// line, whose residual is `line`) by a quadratic `y = a + b u + c u^2` where it halves
/// the line's residual (else the noise hides the curvature), with the curvature only
/// where the quadratic holds them; straight where the line holds them to within half
/// the noise `sigma`.
fn quadratic(local: &[(f64, f64)], u_p: f64, line: f64, sigma: f64) -> (f64, Option<f64>) {
    let inv = 1.0 / local.len() as f64;
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    // In units of their extent along the line, so that the conditioning test
    // below does not depend on the scale.
    let su = local.iter().fold(0.0f64, |m, &(u, _)| m.max(u.abs()));
    for &(u, v) in local {
        let w = u / su;
        let row = Vector3::new(1.0, w, w * w);
        ata += row * row.transpose();
        atb += row * v;
    }
    // Samples all but on a line across, or coincident along it, fix no quadratic.
    let conditioned = su > 0.0 && ata.determinant().abs() > 1e-12 * ata.amax().powi(3);
    match conditioned
        .then(|| ata.lu().solve(&atb))
        .flatten()
        .filter(|z| z.iter().all(|v| v.is_finite()))
    {
        Some(z) => {
            let (a, b, c2) = (z[0], z[1] / su, z[2] / (su * su));
            let quad = (local
                .iter()
                .map(|&(u, v)| (v - a - b * u - c2 * u * u).powi(2))
                .sum::<f64>()
                * inv)
                .sqrt();
            if quad < 0.5 * line {
                let slope = b + 2.0 * c2 * u_p;
                // A curvature to continue the curve by only where the quadratic
                // holds its samples (to within the noise, or a thousandth of
                // their extent): one fitted across a bend and its straight
                // (a spiral's cap and wall) misses them by a hundredth and more,
                // and its circle would run on into a corner that is not there.
                let holds = quad <= sigma.max(1e-3 * su);
                let k = 2.0 * c2 / (1.0 + slope * slope).powf(1.5);
                (slope, holds.then_some(k))
            } else {
                // Straight where the line holds them to within half the noise
                // and no quadratic does better: a clean curve's samples within
                // a noise estimate that its curvature inflates are its circle's.
                (0.0, (line <= 0.5 * sigma).then_some(0.0))
            }
        }
        None => (0.0, (line <= 0.5 * sigma).then_some(0.0)),
    }
}

/// A stretch of a loop between two supported vertices, `a` before `b` along it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Gap {
    pub(super) a: usize,
    pub(super) b: usize,
}

/// A closed polyline's vertices with their arc lengths.
pub(super) struct Loop<'a> {
    points: &'a [Point],
    /// Arc length from vertex 0 to each vertex.
    pub(super) at: Vec<f64>,
    pub(super) total: f64,
}

impl<'a> Loop<'a> {
    pub(super) fn new(points: &'a [Point]) -> Loop<'a> {
        let mut at = Vec::with_capacity(points.len());
        let mut s = 0.0;
        for (i, &p) in points.iter().enumerate() {
            at.push(s);
            s += dist(p, points[(i + 1) % points.len()]);
        }
        Loop {
            points,
            at,
            total: s,
        }
    }

    /// The stretches between two supported vertices (within `tol` of a sample of
    /// `field`) with a vertex off the samples, or one long segment whose middle is, and
    /// more than `4 step` long; in order round the loop.
    pub(super) fn unsupported(&self, field: &DistanceField, tol: f64, step: f64) -> Vec<Gap> {
        let points = self.points;
        let n = points.len();
        let near: Vec<bool> = points.iter().map(|&p| field.distance(p) <= tol).collect();
        let Some(start) = near.iter().position(|&b| b) else {
            return Vec::new();
        };
        let mut gaps = Vec::new();
        let mut a = start;
        for ahead in 1..=n {
            let b = (start + ahead) % n;
            if !near[b] {
                continue;
            }
            let off = (b + n - a) % n > 1 || field.distance(mid(points[a], points[b])) > tol;
            if off && self.arc(a, b) > 4.0 * step {
                gaps.push(Gap { a, b });
            }
            a = b;
        }
        gaps
    }

    /// Vertex `i`.
    pub(super) fn point(&self, i: usize) -> Point {
        self.points[i]
    }

    /// Arc length from vertex `a` forward to vertex `b`.
    fn arc(&self, a: usize, b: usize) -> f64 {
        (self.at[b] - self.at[a]).rem_euclid(self.total)
    }

    /// The points of the stretch `gap`, its segments walked at most `step` at a time
    /// (each segment's end, not its start: `a` itself is left out).
    pub(super) fn walk(&self, gap: Gap, step: f64) -> impl Iterator<Item = Point> + '_ {
        let n = self.points.len();
        (0..(gap.b + n - gap.a) % n).flat_map(move |k| {
            let (p, q) = (
                self.points[(gap.a + k) % n],
                self.points[(gap.a + k + 1) % n],
            );
            let pieces = ((dist(p, q) / step).ceil() as usize).clamp(1, MAX_ARC_VERTICES);
            (1..=pieces).map(move |i| add(p, scale(sub(q, p), i as f64 / pieces as f64)))
        })
    }

    /// The vertex `reach` of arc length forward (`ahead`) or back from `e` (the last
    /// within it), or farther where that lies less than `reach / 2` from `e` in a
    /// straight line: the level set's own curve may tangle, running back and forth over
    /// more arc length than it covers. At most `4 reach` of arc length.
    pub(super) fn reach(&self, e: usize, reach: f64, ahead: bool) -> usize {
        let n = self.points.len();
        let mut last = e;
        for k in 1..n {
            let i = if ahead { (e + k) % n } else { (e + n - k) % n };
            let along = if ahead {
                self.arc(e, i)
            } else {
                self.arc(i, e)
            };
            let covered = dist(self.points[last], self.points[e]) >= 0.5 * reach;
            if along > 4.0 * reach || (along > reach && covered) {
                break;
            }
            last = i;
        }
        last
    }

    /// Whether the stretch `gap` strays from the `arc` across it (its inner points)
    /// anywhere by more than a `step`. A stretch that already runs along the arc (to
    /// within a step: the mesh's resolution) is the level set's, which the samples
    /// beyond the ends shaped.
    fn strays_from(&self, gap: Gap, arc: &[Point], step: f64) -> bool {
        let path = Polyline {
            closed: false,
            points: [self.points[gap.a]]
                .into_iter()
                .chain(arc.iter().copied())
                .chain([self.points[gap.b]])
                .collect(),
        };
        let along = SegmentIndex::new(std::slice::from_ref(&path));
        // The stretch walked a step at a time: a long segment is a chord.
        self.walk(gap, step).any(|p| along.distance(p) > step)
    }

    /// The Hermite arcs across `gap` (its inner vertices, from `a`'s side) through the
    /// samples `skipped` (in order along it), when they are ones to take: `clear(window,
    /// p)` says whether `p` keeps clear of every part of the curves but this loop's
    /// vertices in the cyclic index range `window`.
    fn span(
        &self,
        gap: Gap,
        skipped: &[Point],
        fit: &Fit<'_>,
        tol: f64,
        step: f64,
        clear: impl Fn((usize, usize), Point) -> bool,
    ) -> Option<Vec<Point>> {
        let (pa, pb) = (self.points[gap.a], self.points[gap.b]);
        let c = dist(pa, pb);
        if c <= 0.0 {
            return None;
        }
        // The tangents from the samples within a quarter chord of each end (a few noise
        // deviations at least): a bend's curvature shows in the quadratic fitted there
        // and its next order (a circle's quartic) hardly does. The curve's own run over
        // a chord (16 steps at least) before and after tells which way along it is (over
        // less, its zigzag between sparse clean samples can run backwards; where it
        // tangles, on until it covers half that), or where it ran across (the chord of a
        // bend before), the chord.
        let run = c.max(16.0 * step);
        let (from, to) = (self.reach(gap.a, run, false), self.reach(gap.b, run, true));
        let mut knots: Vec<Point> = Vec::with_capacity(skipped.len() + 2);
        knots.push(pa);
        knots.extend_from_slice(skipped);
        knots.push(pb);
        let k = knots.len();
        let (run_a, run_b) = (sub(pa, self.points[from]), sub(self.points[to], pb));
        let tangents = knot_tangents(fit, &knots, c, run_a, run_b)?;
        let sides = |i: usize, j: usize, by_run: bool| {
            corner_between(fit, &knots, (i, j), by_run, (run_a, run_b), step)
        };
        let mut arc = Vec::new();
        let mut i = 0;
        while i < k - 1 {
            let (p, q) = (knots[i], knots[i + 1]);
            if i > 0 {
                arc.push(p);
            }
            // A sample passed by whose own samples hold no curve lies where two walls
            // meet, near their corner but on one of them: the corner is where the sides
            // of the knots on either side of it meet, if that passes it within `tol`
            // (a smooth arc through it would swing out past the corner).
            if i + 2 < k && tangents[i + 1].curvature.is_none() {
                let through = sides(i, i + 2, true).filter(|path| {
                    let mut whole = vec![p];
                    whole.extend_from_slice(path);
                    whole.push(knots[i + 2]);
                    polyline_dist(q, &whole) <= tol
                });
                if let Some(path) = through {
                    arc.extend(path);
                    i += 2;
                    continue;
                }
            }
            // A side whose samples lie on a line that runs on through the other knot
            // (within the tolerance) is a straight wall across its gap: the chord. The
            // other side's fit may span a corner just past its knot, and a Hermite arc
            // with that tangent bulges off the wall.
            let on_line = |a: usize, b: usize| {
                tangents[a].curvature == Some(0.0)
                    && cross(tangents[a].tangent, sub(knots[b], knots[a])).abs() <= tol
            };
            match sides(i, i + 1, false) {
                Some(path) => arc.extend(path),
                None if on_line(i, i + 1) || on_line(i + 1, i) => {
                    let pieces = ((dist(p, q) / step).ceil() as usize).clamp(1, MAX_ARC_VERTICES);
                    arc.extend(
                        (1..pieces).map(|k| add(p, scale(sub(q, p), k as f64 / pieces as f64))),
                    );
                }
                None => hermite(
                    p,
                    q,
                    tangents[i].tangent,
                    tangents[i + 1].tangent,
                    (fit.t.arc_max_turn, fit.t.arc_max_bulge),
                    step,
                    &mut arc,
                )?,
            }
            i += 1;
        }
        if arc.len() > MAX_ARC_VERTICES || arc.iter().any(|&p| !clear((from, to), p)) {
            return None;
        }
        self.strays_from(gap, &arc, step).then_some(arc)
    }
}

/// A corner between the knots `i` and `j` of a span (each side judged by its own
/// samples) as the path's inner points, with each side's direction along the path's
/// run (`by_run`) or across the chord; `runs` are the loop's runs into and out of the
/// span.
fn corner_between(
    fit: &Fit<'_>,
    knots: &[Point],
    (i, j): (usize, usize),
    by_run: bool,
    (run_a, run_b): (Point, Point),
    step: f64,
) -> Option<Vec<Point>> {
    let k = knots.len();
    let reach = |c: f64| fit.reach(c);
    let (p, q) = (knots[i], knots[j]);
    let c = dist(p, q);
    // A corner is judged by each side's own samples (the knots' tangents, fitted
    // round them, would bend round it), within half a chord: the few samples
    // nearest a sparse wall's end are too few to tell a line from a circle.
    // Which way along each side: the path's run into `p` and out of `q` from the
    // first knot a quarter chord away, or the loop's (the chord may run nearly
    // across a side, as at a corner's steep piece, and two samples a rounding
    // apart give no direction).
    let far = |m: &usize| dist(knots[*m], p).min(dist(knots[*m], q)) >= 0.25 * c;
    let before = (0..i).rev().find(far).map_or(run_a, |m| sub(p, knots[m]));
    let after = (j + 1..k).find(far).map_or(run_b, |m| sub(knots[m], q));
    // Each side's samples are those behind its end: across the chord's
    // half-plane, or (across a knot at a corner, whose chord may run at an acute
    // angle to the walls, past which the other wall's samples lie) against the
    // path's run.
    let (d, r) = (sub(q, p), 2.0 * reach(c));
    let (behind_p, behind_q) = if by_run {
        (before, scale(after, -1.0))
    } else {
        (d, scale(d, -1.0))
    };
    let a = fit.tangent(p, r, &[before, d], Some(behind_p))?;
    let b = fit.tangent(q, r, &[after, d], Some(behind_q))?;
    let limits = (
        fit.t.corner_min_turn,
        fit.t.corner_max_side_turn,
        fit.t.arc_max_turn,
    );
    corner(p, q, a, b, limits, step).map(|c| c.inner)
}

/// The tangents at the `knots` of a span (a gap's ends `pa` and `pb`, first and last,
/// and the samples it skipped, `c` the gap's chord), each fitted to its samples: at the
/// ends pointing along the loop's runs `run_a` into the gap and `run_b` out of it (the
/// runs themselves where the samples there are too sparse for a fit). `None` when an
/// end has no direction.
fn knot_tangents(
    fit: &Fit<'_>,
    knots: &[Point],
    c: f64,
    run_a: Point,
    run_b: Point,
) -> Option<Vec<End>> {
    let k = knots.len();
    let (pa, pb) = (knots[0], knots[k - 1]);
    let reach = |c: f64| fit.reach(c);
    let chord = |i: usize| dist(knots[i], knots[i + 1]);
    let mut tangents = Vec::with_capacity(k);
    // Where the samples on an end's side are too sparse for a fit, the loop's run.
    let run = |v: Point| {
        (norm(v) > 0.0).then(|| End {
            tangent: scale(v, 1.0 / norm(v)),
            curvature: None,
        })
    };
    tangents.push(
        fit.tangent(
            pa,
            reach(chord(0).max(c)),
            &[run_a, sub(knots[1], pa)],
            Some(run_a),
        )
        .or_else(|| run(run_a))?,
    );
    for i in 1..k - 1 {
        // Where the samples round a skipped one give no line (a corner's two walls),
        // the direction between its neighbours along the path, as Catmull-Rom takes.
        let across = sub(knots[i + 1], knots[i - 1]);
        let spread = chord(i - 1).max(chord(i));
        let t = fit
            .tangent(knots[i], reach(spread), &[across], None)
            .unwrap_or(End {
                tangent: scale(across, 1.0 / norm(across).max(1e-300)),
                curvature: None,
            });
        tangents.push(t);
    }
    tangents.push(
        fit.tangent(
            pb,
            reach(chord(k - 2).max(c)),
            &[run_b, sub(pb, knots[k - 2])],
            Some(scale(run_b, -1.0)),
        )
        .or_else(|| run(run_b))?,
    );
    Some(tangents)
}

/// The samples a loop's stretch `gap` passes by without holding: each within twice the
/// nearest's distance of a point of it (walked `step` at a time), farther than `tol`
/// from the curves of `index` (or held only by a long segment's inner part, away from
/// the ends), whose nearest part of them is this stretch (of their polyline `k`); in
/// order along it. Not the nearest alone: a stretch that cuts a corner wide has the
/// samples on either side nearer to every point of it than the one sample near the
/// corner.
fn skipped_samples(
    loop_: &Loop<'_>,
    gap: Gap,
    field: &DistanceField,
    index: &SegmentIndex,
    k: usize,
    tol: f64,
    step: f64,
) -> Vec<Point> {
    let n = loop_.points.len();
    let mut ids: Vec<u32> = Vec::new();
    let mut near = Vec::new();
    for p in loop_.walk(gap, step) {
        field.within(p, 2.0 * field.nearest(p).dist, &mut near);
        ids.extend_from_slice(&near);
    }
    ids.sort_unstable();
    ids.dedup();
    let (pa, pb) = (loop_.points[gap.a], loop_.points[gap.b]);
    let mut found: Vec<(f64, Point)> = ids
        .into_iter()
        .filter_map(|i| {
            let p = field.points()[i as usize];
            let (d, seg, t) = index.nearest(p)?;
            let local = seg.wrapping_sub(index.start(k));
            let on_stretch = local < n && in_cyclic(local, (gap.a, (gap.b + n - 1) % n), n);
            // Held, but by a long segment's inner part (the stretch's ends are the
            // only vertices near samples): a knot all the same, or the arc between the
            // ends would bow off it.
            let held_in_between = d <= tol && dist(p, pa) > tol && dist(p, pb) > tol;
            ((d > tol || held_in_between) && on_stretch).then(|| {
                let len = dist(loop_.points[local], loop_.points[(local + 1) % n]);
                (loop_.arc(gap.a, local) + t * len, p)
            })
        })
        .collect();
    found.sort_by(|x, y| x.0.total_cmp(&y.0));
    let mut knots: Vec<Point> = found.into_iter().map(|(_, p)| p).collect();
    untangle(pa, pb, &mut knots);
    knots
}

/// Samples in a path longer than this keep their order: 2-opt is quadratic a pass.
const MAX_UNTANGLED: usize = 64;

/// Reorders `knots` so that the path from `pa` through them to `pb` is no longer for
/// reversing any run of them (2-opt): the order of the stretch they were found along is
/// theirs where it follows them, but a stretch that balloons off the samples into the
/// space beside them (and back) passes them in the reverse order, and an arc through
/// them so would double back.
fn untangle(pa: Point, pb: Point, knots: &mut [Point]) {
    let k = knots.len();
    if !(2..=MAX_UNTANGLED).contains(&k) {
        return;
    }
    // Knot `i` of the whole path, ends included.
    let at = |knots: &[Point], i: usize| match i {
        0 => pa,
        i if i == k + 1 => pb,
        i => knots[i - 1],
    };
    // Each reversal shortens the path, so this ends; a pass per knot bounds it all the same.
    for _ in 0..k {
        let mut shorter = false;
        for i in 1..k {
            for j in i + 1..=k {
                let (a, b) = (at(knots, i - 1), at(knots, i));
                let (c, d) = (at(knots, j), at(knots, j + 1));
                // Reversing knots i..=j swaps the edges (a, b), (c, d) for (a, c), (b, d);
                // by more than a rounding, so that ties do not cycle.
                if dist(a, c) + dist(b, d) < (dist(a, b) + dist(c, d)) * (1.0 - 1e-12) {
                    knots[i - 1..j].reverse();
                    shorter = true;
                }
            }
        }
        if !shorter {
            break;
        }
    }
}

/// The inner points of the path from `p` to `q` round the corner where the samples'
/// curves on each side (`a` at `p`, `b` at `q`: their lines, or their osculating
/// circles where a quadratic was fitted) meet, when they meet within one and a half
/// chords ahead of `p` and behind `q` (an acute corner lies past one chord from the
/// sample farther from it), each turning by at most `max_side_turn` radians over a
/// chord, and turn there by `min_turn` at least and `max_turn` at most: the corner the samples
/// imply, which no smooth arc between them keeps. A smooth curve between `p` and `q`
/// gives none: osculating circles of a curve of monotone curvature are nested (Tait and
/// Kneser), and two circles fitted to the same one meet, if at all, at a small angle.
/// Where the curves cross twice so, at the ends of a thin lens, the path runs midway
/// between the two crossings' (see [`Corner::midway`]).
pub(super) fn corner(
    p: Point,
    q: Point,
    a: End,
    b: End,
    (min_turn, max_side_turn, max_turn): (f64, f64, f64),
    step: f64,
) -> Option<Corner> {
    let c = dist(p, q);
    let (ka, kb) = (a.curvature?, b.curvature?);
    if c <= 0.0 || ka.abs() * c > max_side_turn || kb.abs() * c > max_side_turn {
        return None;
    }
    // Sampled a step at a time (the output's resolution), at most 512 pieces a side.
    let step = step.max(c / 512.0);
    let side_a = continued(p, a.tangent, ka, 1.5 * c, step);
    // Behind `q`: the same curve walked backwards turns the other way.
    let side_b = continued(q, scale(b.tangent, -1.0), -kb, 1.5 * c, step);
    // The crossings, the nearest the ends (by the arc length from both) first: the
    // pieces of both sides are of one length, so past a tenth beyond the nearest, no
    // path through one is of its path's length (below).
    let mut found: Vec<(usize, usize, Point)> = Vec::new();
    let mut least = usize::MAX;
    for i in 0..side_a.len() - 1 {
        for j in 0..side_b.len() - 1 {
            if least != usize::MAX && i + j > least + least / 10 + 2 {
                break;
            }
            if let Some(x) = crossing(side_a[i], side_a[i + 1], side_b[j], side_b[j + 1]) {
                least = least.min(i + j);
                found.push((i, j, x));
            }
        }
    }
    found.sort_by_key(|&(i, j, _)| i + j);
    let turns = |&(i, j, _): &(usize, usize, Point)| {
        let ta = sub(side_a[i + 1], side_a[i]);
        let tb = sub(side_b[j], side_b[j + 1]);
        let turn = (dot(ta, tb) / (norm(ta) * norm(tb)))
            .clamp(-1.0, 1.0)
            .acos();
        (min_turn..=max_turn).contains(&turn)
    };
    let path = |&(i, j, x): &(usize, usize, Point)| {
        let mut path = vec![p];
        path.extend_from_slice(&side_a[1..=i]);
        path.push(x);
        path.extend(side_b[1..=j].iter().rev());
        path.push(q);
        // A crossing at a side's first vertex repeats it.
        path.dedup();
        path
    };
    let first = found.first().filter(|x| turns(x))?;
    let one = path(first);
    // Two circles cross twice. Where both crossings turn as corners do and lie at the
    // two ends of a thin lens between the circles (the paths along its two sides are
    // of one length to a tenth), the samples cannot tell which is the corner: the
    // other is where one circle passes a sample of the other's wall by chance (at the
    // spiral's inner end the cap and its wall curve opposite ways, and their circles
    // cross again 2 turn / (curvature change), about 0.02, from the corner). The path
    // runs midway between the two, within half the lens's width of either.
    let other = found
        .iter()
        .skip(1)
        .filter(|x| dist(x.2, first.2) > step && turns(x))
        .map(path)
        .find(|two| (length(two) - length(&one)).abs() <= 0.1 * length(&one));
    let midway = other.is_some();
    let mut inner = match other {
        Some(two) => midway_between(&one, &two),
        None => one,
    };
    inner.retain(|&v| v != p && v != q);
    inner.dedup();
    Some(Corner { inner, midway })
}

/// The path round a corner that [`corner`] finds.
pub(super) struct Corner {
    /// Its inner points.
    pub(super) inner: Vec<Point>,
    /// Whether it runs midway between two crossings of the sides' curves.
    pub(super) midway: bool,
}

/// The length of the polyline `pl`.
fn length(pl: &[Point]) -> f64 {
    pl.windows(2).map(|w| dist(w[0], w[1])).sum()
}

/// The path midway between the paths `a` and `b`, which run from one point to another:
/// the midpoints of their points at the same fraction of their lengths, as many as the
/// longer list has, its ends exactly theirs.
fn midway_between(a: &[Point], b: &[Point]) -> Vec<Point> {
    let n = a.len().max(b.len());
    // Each path with the length up to each of its points.
    let along = |pl: &[Point]| -> Vec<f64> {
        let mut run = 0.0;
        std::iter::once(0.0)
            .chain(pl.windows(2).map(|w| {
                run += dist(w[0], w[1]);
                run
            }))
            .collect()
    };
    let (la, lb) = (along(a), along(b));
    let at = |pl: &[Point], l: &[f64], t: f64| {
        let target = t * l[l.len() - 1];
        let i = l.partition_point(|&x| x < target).clamp(1, pl.len() - 1);
        let d = l[i] - l[i - 1];
        let s = if d > 0.0 {
            ((target - l[i - 1]) / d).clamp(0.0, 1.0)
        } else {
            0.0
        };
        add(pl[i - 1], scale(sub(pl[i], pl[i - 1]), s))
    };
    let mut path = vec![a[0]];
    path.extend((1..n - 1).map(|k| {
        let t = k as f64 / (n - 1) as f64;
        scale(add(at(a, &la, t), at(b, &lb, t)), 0.5)
    }));
    path.push(a[a.len() - 1]);
    path
}

/// The curve from `p` along the unit tangent `t` with the constant curvature `k` (left
/// positive), `length` long, as points a `step` or less apart, `p` first.
pub(super) fn continued(p: Point, t: Point, k: f64, length: f64, step: f64) -> Vec<Point> {
    let pieces = ((length / step).ceil() as usize).clamp(1, MAX_ARC_VERTICES);
    let n = [-t[1], t[0]];
    (0..=pieces)
        .map(|i| {
            let s = length * i as f64 / pieces as f64;
            // sin(ks)/k and (1 - cos(ks))/k, by their series where ks is tiny.
            let ks = k * s;
            let (along, across) = if ks.abs() < 1e-6 {
                (s, 0.5 * k * s * s)
            } else {
                (ks.sin() / k, (1.0 - ks.cos()) / k)
            };
            add(p, add(scale(t, along), scale(n, across)))
        })
        .collect()
}

/// The inner points of the Hermite arc from `p` to `q` with unit tangents `tp` and `tq`,
/// at most `step` apart, appended to `out`: `None` when the tangents turn by more than
/// `max_turn` or the arc strays more than `max_bulge` chords from its chord.
pub(super) fn hermite(
    p: Point,
    q: Point,
    tp: Point,
    tq: Point,
    (max_turn, max_bulge): (f64, f64),
    step: f64,
    out: &mut Vec<Point>,
) -> Option<()> {
    let c = dist(p, q);
    if c <= 0.0 {
        return Some(());
    }
    let turn = dot(tp, tq).clamp(-1.0, 1.0).acos();
    if turn > max_turn {
        return None;
    }
    let m = c / (0.25 * turn).cos().powi(2);
    let length = if turn > 1e-9 {
        c * 0.5 * turn / (0.5 * turn).sin()
    } else {
        c
    };
    let pieces = ((length / step).ceil() as usize).clamp(2, MAX_ARC_VERTICES);
    let chord = scale(sub(q, p), 1.0 / c);
    for i in 1..pieces {
        let t = i as f64 / pieces as f64;
        let (t2, t3) = (t * t, t * t * t);
        let x = add(
            add(
                scale(p, 2.0 * t3 - 3.0 * t2 + 1.0),
                scale(tp, m * (t3 - 2.0 * t2 + t)),
            ),
            add(scale(q, -2.0 * t3 + 3.0 * t2), scale(tq, m * (t3 - t2))),
        );
        if cross(chord, sub(x, p)).abs() > max_bulge * c {
            return None;
        }
        out.push(x);
    }
    Some(())
}

/// Whether `i` lies in the cyclic range from `window.0` forward to `window.1` of `n`.
fn in_cyclic(i: usize, (from, to): (usize, usize), n: usize) -> bool {
    (i + n - from) % n <= (to + n - from) % n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`span_gaps`] on clean samples, tolerance 0.01 and step 0.005, default tolerances.
    fn spanned(curves: &mut [Polyline], samples: &[Point]) -> Vec<usize> {
        span_gaps(
            curves,
            &field(samples),
            0.0,
            0.01,
            0.005,
            &Tolerances::default(),
        )
    }

    fn circle(r: f64, n: usize, keep: impl Fn(f64) -> bool) -> Vec<Point> {
        (0..n)
            .map(|i| std::f64::consts::TAU * i as f64 / n as f64)
            .filter(|&a| keep(a))
            .map(|a| [r * a.cos(), r * a.sin()])
            .collect()
    }

    /// Whether the angle `a` lies in the quarter turn from 0.3 rad that the tests cut.
    fn in_quarter(a: f64) -> bool {
        a > 0.3 && a < 0.3 + std::f64::consts::FRAC_PI_2
    }

    /// A unit circle sampled every 0.016 but across [`in_quarter`], and a loop of 2,000
    /// vertices along it that cuts that quarter by its chord.
    fn quarter_cut() -> (Vec<Point>, Vec<Point>) {
        let out = |a: f64| !in_quarter(a);
        (circle(1.0, 400, out), circle(1.0, 2000, out))
    }

    fn field(samples: &[Point]) -> DistanceField {
        DistanceField::new(samples).unwrap()
    }

    /// How far the farthest of `points` lies from the circle of radius `r` round 0.
    fn off_circle(points: &[Point], r: f64) -> f64 {
        points
            .iter()
            .map(|&p| (norm(p) - r).abs())
            .fold(0.0, f64::max)
    }

    fn nearest(points: &[Point], p: Point) -> f64 {
        points
            .iter()
            .map(|&s| dist(p, s))
            .fold(f64::INFINITY, f64::min)
    }

    /// A circle sampled but for a quarter turn, whose loop cuts the quarter by its
    /// chord: the arc put across the gap follows the circle to within the
    /// four-thirds-tangent arc's 2.7e-4 of the radius, plus the tangents' error from a
    /// quadratic over a quarter chord (about 1e-3 rad, a few 1e-4 of the radius); 2e-3
    /// of it is asserted.
    #[test]
    fn a_chord_across_a_quarter_turn_becomes_the_arc() {
        let r = 1.0;
        let (samples, loop_points) = quarter_cut();
        let mut curves = vec![Polyline {
            closed: true,
            points: loop_points,
        }];
        let before = curves[0].points.len();
        let changed = spanned(&mut curves, &samples);
        assert_eq!(changed, [0]);
        let pl = &curves[0];
        assert!(pl.points.len() > before + 200, "{}", pl.points.len());
        let worst = off_circle(&pl.points, r);
        assert!(worst < 2e-3 * r, "{worst}");
        // Every point of the gap is now within a step of the arc.
        let middle = [
            r * (0.3 + std::f64::consts::FRAC_PI_4).cos(),
            r * (0.3 + std::f64::consts::FRAC_PI_4).sin(),
        ];
        let d = nearest(&pl.points, middle);
        assert!(d < 0.005, "{d}");
    }

    /// A unit circle sampled every 0.016 but for a gap from 1.0 to 1.1 rad, and a loop
    /// that runs on to the gap, back 0.12 along the circle (as the level set's own curve
    /// can tangle where it is flat between sparse clean samples) and from there runs
    /// 0.03 inside it, past the samples and across the gap. Its run into the stretch,
    /// walked back over a chord of arc length, ends ahead of the stretch's start; taken
    /// on until it covers half a chord it runs the way the loop goes, and the arc
    /// follows the circle across the gap (2e-3 as in the quarter turn's test).
    #[test]
    fn a_tangle_before_a_gap_does_not_turn_its_arc_back() {
        let (a0, a1, back) = (1.0, 1.1, 0.12);
        let samples = circle(1.0, 400, |a| !(a0..a1).contains(&a));
        let at = |a: f64, r: f64| [r * a.cos(), r * a.sin()];
        let d = 0.0025;
        let n = |len: f64| (len / d).round() as usize;
        let tau = std::f64::consts::TAU;
        let mut points: Vec<Point> = (0..n(tau - (a1 - a0)))
            .map(|i| at(a1 + d * i as f64, 1.0))
            .collect();
        points.extend((0..n(back)).map(|i| at(a0 + tau - d * i as f64, 1.0)));
        let dip = n(a1 - (a0 - back));
        points.extend((0..dip).map(|i| {
            let t = i as f64 / dip as f64;
            at(
                a0 - back + (a1 - a0 + back) * t,
                if i == 0 { 1.0 } else { 0.97 },
            )
        }));
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        assert!(off_circle(&curves[0].points, 1.0) > 0.029);
        let changed = spanned(&mut curves, &samples);
        assert_eq!(changed, [0]);
        let across: Vec<Point> = curves[0]
            .points
            .iter()
            .copied()
            .filter(|p| (a0..a1).contains(&p[1].atan2(p[0])))
            .collect();
        assert!(across.len() > 10, "{}", across.len());
        let worst = off_circle(&across, 1.0);
        assert!(worst < 2e-3, "{worst}");
    }

    /// A loop round two walls that a gap separates from a third part: an arc that would
    /// come near another part of the curves is not taken, nor one that would fold.
    #[test]
    fn an_arc_that_would_touch_another_curve_is_refused() {
        let r = 1.0;
        let (samples, loop_points) = quarter_cut();
        // A second loop just outside the arc's path, at the gap's middle.
        let m = 0.3 + std::f64::consts::FRAC_PI_4;
        let centre = [1.003 * r * m.cos(), 1.003 * r * m.sin()];
        let other: Vec<Point> = circle(0.002, 16, |_| true)
            .into_iter()
            .map(|p| add(p, centre))
            .collect();
        let mut curves = vec![
            Polyline {
                closed: true,
                points: loop_points.clone(),
            },
            Polyline {
                closed: true,
                points: other,
            },
        ];
        assert!(spanned(&mut curves, &samples).is_empty());
        assert_eq!(curves[0].points, loop_points);
    }

    /// A loop that already follows the circle across the gap (the level set held by
    /// the samples beyond it) stays as it is: it strays from the arc by the arc's own
    /// error, far under a step.
    #[test]
    fn a_stretch_along_the_arc_stays() {
        let samples = circle(1.0, 400, |a| !in_quarter(a));
        let points = circle(1.0, 2000, |_| true);
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        assert!(spanned(&mut curves, &samples).is_empty());
        assert_eq!(curves[0].points, points);
    }

    /// A loop that cuts a quarter turn short by its chord although the samples go on
    /// round it (a level set held off them by its curvature): the arcs pass through
    /// every sample it passed by (to within the sagitta of a step), and follow the
    /// circle between them to within the arcs' own error (under 1e-6 of the radius
    /// between samples 0.016 apart; 1e-3 asserted, for the tangents' fits).
    #[test]
    fn a_loop_that_passed_samples_by_goes_through_them() {
        let r = 1.0;
        let samples = circle(r, 400, |_| true);
        let mut curves = vec![Polyline {
            closed: true,
            points: circle(r, 2000, |a| !in_quarter(a)),
        }];
        assert_eq!(spanned(&mut curves, &samples), [0]);
        let pl = &curves[0];
        // Within the sagitta of a step on the unit circle, 3e-6.
        let index = SegmentIndex::new(&curves);
        let missed = samples
            .iter()
            .map(|&s| index.distance(s))
            .fold(0.0, f64::max);
        assert!(missed < 1e-5, "{missed}");
        let worst = off_circle(&pl.points, r);
        assert!(worst < 1e-3 * r, "{worst}");
    }

    /// The boundary of the unit square, `n` points a side, without those for which
    /// `keep` is false.
    fn square(n: usize, keep: impl Fn(Point) -> bool) -> Vec<Point> {
        let side = |i: usize| i as f64 / n as f64;
        (0..n)
            .map(|i| [side(i), 0.0])
            .chain((0..n).map(|i| [1.0, side(i)]))
            .chain((0..n).map(|i| [1.0 - side(i), 1.0]))
            .chain((0..n).map(|i| [0.0, 1.0 - side(i)]))
            .filter(|&p| keep(p))
            .collect()
    }

    /// Samples a stretch passed in the reverse order (a loop that balloons off a wall
    /// into the corridor beside it and back, as on the clean spiral with walls 0.06
    /// apart, seed 16, whose arc then doubled back and was refused): the path from one
    /// end through them to the other runs in order. Samples round an acute corner, in
    /// order already, stay so, though a chord's projection would misorder them.
    #[test]
    fn knots_passed_in_reverse_are_put_in_order() {
        let mut knots = vec![[0.8, 0.01], [0.5, -0.01], [0.2, 0.0]];
        untangle([0.0, 0.0], [1.0, 0.0], &mut knots);
        assert_eq!(knots, [[0.2, 0.0], [0.5, -0.01], [0.8, 0.01]]);
        let corner = vec![[0.6, 0.0], [0.95, 0.0], [0.92, 0.08], [0.85, 0.2]];
        let mut knots = corner.clone();
        untangle([0.0, 0.0], [0.7, 0.5], &mut knots);
        assert_eq!(knots, corner);
    }

    /// A square sampled but near one corner, whose loop cuts the corner by a chord:
    /// both sides are straight (clean samples on a line), so the corner comes back at
    /// the sides' intersection, exactly but for rounding.
    #[test]
    fn a_cut_corner_of_two_straight_sides_comes_back() {
        let away = |p: Point| dist(p, [1.0, 1.0]) > 0.15;
        let samples = square(100, away);
        // Every point stays on the square's boundary.
        corner_comes_back(square(400, away), &samples, [1.0, 1.0], |p| {
            p[0].min(p[1]).min(1.0 - p[0]).min(1.0 - p[1]).abs()
        });
    }

    /// A unit square sampled every 0.01 but on its left side from 0.78 to 0.96 up, so
    /// that the gap's upper end is a sample 0.03 from the top left corner, and a loop
    /// along it that steps 0.03 inwards across the gap. The samples behind the upper end
    /// span the corner, and a Hermite arc with their tangent bows off the wall; the
    /// lower end's samples lie on a line through the upper end: the wall is straight
    /// across the gap, and every vertex lies on it, but for rounding.
    #[test]
    fn a_wall_straight_up_to_a_corner_stays_straight_across_its_gap() {
        let gap = |p: Point| p[0] == 0.0 && p[1] > 0.775 && p[1] < 0.965;
        let samples = square(100, |p| !gap(p));
        let points: Vec<Point> = square(400, |_| true)
            .into_iter()
            .map(|p| if gap(p) { [0.03, p[1]] } else { p })
            .collect();
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        assert_eq!(spanned(&mut curves, &samples), [0]);
        let off = curves[0]
            .points
            .iter()
            .map(|p| p[0].min(p[1]).min(1.0 - p[0]).min(1.0 - p[1]).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-9, "{off}");
    }

    /// Spans the loop `points` round `samples` (tolerance 0.01, step 0.005) and checks
    /// that a vertex lands on `corner`, and that every vertex lies on the shape: `off`
    /// (its distance from the shape's sides) is zero but for rounding.
    fn corner_comes_back(
        points: Vec<Point>,
        samples: &[Point],
        corner: Point,
        off: impl Fn(Point) -> f64,
    ) {
        let mut curves = vec![Polyline {
            closed: true,
            points,
        }];
        assert_eq!(spanned(&mut curves, samples), [0]);
        let to_corner = nearest(&curves[0].points, corner);
        assert!(to_corner < 1e-9, "{to_corner}");
        let off = curves[0].points.iter().map(|&p| off(p)).fold(0.0, f64::max);
        assert!(off < 1e-9, "{off}");
    }

    /// A triangle whose corner at the origin is acute (70 degrees), sampled every
    /// 0.01 but within 0.07 of that corner on one wall and 0.1 on the other, which
    /// keeps one sample 0.02 from it; the loop cuts the corner by a chord. That
    /// sample is a knot of the arc whose samples round it lie on both walls and hold no
    /// curve: the corner comes back where the sides of the knots on either side meet,
    /// through it, exactly but for rounding (before, a smooth arc through it swung out
    /// past the corner).
    #[test]
    fn a_sample_near_an_acute_corner_keeps_the_corner() {
        let (c, s) = (70f64.to_radians().cos(), 70f64.to_radians().sin());
        let apex_b = [c, s];
        // Counter-clockwise: along wall A from the origin, across, back down wall B.
        let walk = |step: f64, keep: &dyn Fn(Point) -> bool| -> Vec<Point> {
            let n = (1.0 / step).round() as usize;
            let across = dist([1.0, 0.0], apex_b);
            let m = (across / step).round() as usize;
            (0..n)
                .map(|i| [i as f64 / n as f64, 0.0])
                .chain((0..m).map(|i| {
                    let t = i as f64 / m as f64;
                    [1.0 + t * (c - 1.0), t * s]
                }))
                .chain((0..n).map(|i| {
                    let t = 1.0 - i as f64 / n as f64;
                    [t * c, t * s]
                }))
                .filter(|&p| keep(p))
                .collect()
        };
        let on_b = |p: Point| (p[1] - p[0] * s / c).abs() < 1e-9;
        let keep = |p: Point| norm(p) > if on_b(p) { 0.07 } else { 0.1 };
        let mut samples = walk(0.01, &keep);
        samples.push([0.02, 0.0]);
        // Near the corner every point stays on one of its walls (the third side, far
        // from it, is the loop's own).
        corner_comes_back(walk(0.0025, &keep), &samples, [0.0, 0.0], |p| {
            if norm(p) < 0.3 {
                p[1].abs().min((p[1] * c - p[0] * s).abs())
            } else {
                0.0
            }
        });
    }

    /// A half disc of radius 1 (its base from (-1, 0) to (1, 0), then the half circle
    /// back), every `step` along it, without the points for which `keep` is false.
    fn half_disc(step: f64, keep: impl Fn(Point) -> bool) -> Vec<Point> {
        let n = (2.0 / step).round() as usize;
        let m = (std::f64::consts::PI / step).round() as usize;
        (0..n)
            .map(|i| [-1.0 + 2.0 * i as f64 / n as f64, 0.0])
            .chain((0..m).map(|i| {
                let a = std::f64::consts::PI * i as f64 / m as f64;
                [a.cos(), a.sin()]
            }))
            .filter(|&p| keep(p))
            .collect()
    }

    /// A half disc sampled but near the corner where its base meets the circle, whose
    /// loop cuts the corner by a chord (0.106 from it): the base is a line and the
    /// circle's side a quadratic, whose osculating circle runs on into the gap. Their
    /// crossing is the corner to within the quadratic's error over the 0.15 it is
    /// continued: the circle's next order, `s^4 / 8` (6e-5), and its curvature's error
    /// from a fit a quarter chord wide, of the same order; 2e-4 is asserted. The same at
    /// a twentieth of the size, as the curves of a shape a tenth of the box are in local
    /// coordinates: whether a quadratic is fitted does not depend on the scale.
    #[test]
    fn a_line_meeting_a_circle_keeps_its_corner() {
        for size in [1.0, 0.05] {
            let away = |p: Point| dist(p, [1.0, 0.0]) > 0.15;
            let shrink = |pts: Vec<Point>| -> Vec<Point> {
                pts.into_iter().map(|p| scale(p, size)).collect()
            };
            let samples = shrink(half_disc(0.01, away));
            let mut curves = vec![Polyline {
                closed: true,
                points: shrink(half_disc(0.0025, away)),
            }];
            let corner = [size, 0.0];
            let cut = nearest(&curves[0].points, corner);
            assert!(cut > 0.1 * size, "{cut}");
            assert_eq!(
                span_gaps(
                    &mut curves,
                    &field(&samples),
                    0.0,
                    0.01 * size,
                    0.005 * size,
                    &Tolerances::default()
                ),
                [0]
            );
            let kept = nearest(&curves[0].points, corner);
            assert!(kept < 2e-4 * size, "size {size}: {kept}");
            // Every point stays on the boundary: the base, or the circle.
            let off = curves[0]
                .points
                .iter()
                .map(|&p| p[1].abs().min((norm(p) - size).abs()))
                .fold(0.0, f64::max);
            assert!(off < 2e-4 * size, "size {size}: {off}");
        }
    }

    /// Supported loops and open polylines are left alone, as are gaps too short to hold
    /// a vertex of the arc.
    #[test]
    fn supported_curves_stay() {
        let samples = circle(1.0, 400, |_| true);
        let points = circle(1.0, 1000, |_| true);
        let mut curves = vec![
            Polyline {
                closed: true,
                points: points.clone(),
            },
            Polyline {
                closed: false,
                points: vec![[3.0, 0.0], [4.0, 0.0]],
            },
        ];
        let before = curves.clone();
        assert!(spanned(&mut curves, &samples).is_empty());
        assert_eq!(curves, before);
    }

    /// Two circles (radii 0.07 and 0.04, centres 0.1 apart) cross at two points 0.044
    /// apart, turning by 51 degrees at both, with a lens 0.01 wide between them. A wall
    /// on the first meets one on the second at the upper crossing; its last sample lies
    /// at the lower one, which the second circle passes too. From that sample, and one
    /// 0.02 along the second wall past the corner, either crossing is a corner the
    /// samples imply, and either path (round the second circle all the way, or up the
    /// first to the upper crossing) is 0.01 from the other at the lens's middle. The
    /// path comes out midway: within 0.6 of the lens's width of both (half, and a little
    /// for pairing the two by the fraction of their lengths), so that whichever is the
    /// curve it is off by about half the lens; either path alone is off the other by
    /// the whole lens.
    #[test]
    fn two_crossings_a_lens_apart_give_the_path_midway_between_them() {
        let (ra, rb, cb): (f64, f64, Point) = (0.07, 0.04, [0.1, 0.0]);
        // The crossings, at x from the first centre (the origin), y = +-h.
        let x = (cb[0] * cb[0] + ra * ra - rb * rb) / (2.0 * cb[0]);
        let h = (ra * ra - x * x).sqrt();
        let (upper, lower) = ([x, h], [x, -h]);
        // The first wall runs counter-clockwise up to the upper crossing; the second
        // leaves it clockwise round the second circle.
        let on_b = |angle: f64| add(cb, [rb * angle.cos(), rb * angle.sin()]);
        let at_upper = (upper[1] - cb[1]).atan2(upper[0] - cb[0]);
        let q = on_b(at_upper - 0.02 / rb);
        let p = lower;
        let a = End {
            tangent: scale([-p[1], p[0]], 1.0 / ra),
            curvature: Some(1.0 / ra),
        };
        let out_q = sub(q, cb);
        let b = End {
            tangent: scale([out_q[1], -out_q[0]], 1.0 / rb),
            curvature: Some(-1.0 / rb),
        };
        let step = 1e-4;
        let got = corner(p, q, a, b, (0.2, 2.0, 0.95 * std::f64::consts::PI), step).unwrap();
        assert!(got.midway);
        // The two candidates, finely drawn: up the first circle then on round the
        // second, or round the second from the lower crossing.
        let arc = |centre: Point, r: f64, from: f64, to: f64| -> Vec<Point> {
            (0..=2000)
                .map(|i| {
                    let t = from + (to - from) * i as f64 / 2000.0;
                    add(centre, [r * t.cos(), r * t.sin()])
                })
                .collect()
        };
        let mut via_upper = arc([0.0, 0.0], ra, lower[1].atan2(lower[0]), h.atan2(x));
        via_upper.extend(arc(cb, rb, at_upper, at_upper - 0.02 / rb));
        let at_lower = (lower[1] - cb[1]).atan2(lower[0] - cb[0]) + std::f64::consts::TAU;
        let via_lower = arc(cb, rb, at_lower, at_upper - 0.02 / rb);
        let width = ra - (cb[0] - rb);
        assert!((width - 0.01).abs() < 1e-12);
        for candidate in [&via_upper, &via_lower] {
            let off = got
                .inner
                .iter()
                .map(|&v| polyline_dist(v, candidate))
                .fold(0.0, f64::max);
            assert!(off <= 0.6 * width, "{off}");
            let apart = candidate
                .iter()
                .map(|&v| {
                    polyline_dist(
                        v,
                        if candidate == &via_upper {
                            &via_lower
                        } else {
                            &via_upper
                        },
                    )
                })
                .fold(0.0, f64::max);
            assert!(apart >= 0.99 * width, "{apart}");
        }
    }
}
