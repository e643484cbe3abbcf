//! Open strokes: samples that form a single sheet with ends (a pen stroke, a wire, a
//! wall seen from both sides) have no inside for a level set to wrap, so no closed
//! curve explains them. They become open polylines along the sheet's middle, split
//! where strokes meet, and the junctions say which polylines meet where.
//!
//! The method is the classic thinning of a point cloud (Lee 2000): each sample moves
//! across its sheet onto the line fitted to its neighbours within `r` (the 64 nearest at
//! most); the moved samples are joined by a minimum spanning tree of the pairs closer
//! than `r` (each sample's 16 nearest at most), and across gaps along a stroke between
//! the tree's ends (up to `2 r`); branches
//! shorter than `r` (the tree's zigzag across a still noisy sheet) are pruned; the tree's
//! chains between its ends and its forks are the polylines, smoothed over `r / 2`, and
//! forks closer than `2 r` are one junction (a crossing forks twice).

use crate::disjoint::root;

use super::Tolerances;
use crate::distance::DistanceField;
use crate::geom::{cross, dist, dot, scale, sub, Point, Polyline};

/// Where strokes meet.
#[derive(Clone, Debug, PartialEq)]
pub struct Junction {
    /// The meeting point.
    pub at: Point,
    /// The indices (into the strokes returned with it) of the polylines ending here.
    pub polylines: Vec<usize>,
}

/// The curves of a point cloud with its strokes: the samples of `data` farther than
/// `tol` from every curve of `closed` (the zero isoline) set the scale
/// `r = max(2 delta, 6 sigma)` (`delta` their tube radius, at least `2 hmin`), and those
/// farther than `r` become strokes ([`strokes`]) at that scale, after the closed curves. When the data enclose nothing (`enclosed` false:
/// the level set started from the box, and its loop runs round the data instead of
/// along it) and strokes are found, the loops are dropped and every sample is a stroke's.
/// Junction indices are into the returned curves.
pub fn with_strokes(
    closed: Vec<Polyline>,
    data: &[Point],
    enclosed: bool,
    sigma: f64,
    hmin: f64,
    tol: f64,
    t: &Tolerances,
) -> (Vec<Polyline>, Vec<Junction>) {
    // `away`: each sample's distance to the curves (none: infinite).
    let find = |away: Vec<f64>| -> (Vec<Polyline>, Vec<Junction>, f64) {
        let (loose, away): (Vec<Point>, Vec<f64>) = data
            .iter()
            .copied()
            .zip(away)
            .filter(|&(_, d)| d > tol)
            .unzip();
        let Ok(field) = DistanceField::new(&loose) else {
            return (Vec::new(), Vec::new(), 0.0);
        };
        let delta = crate::distance::tube_radius(&field, 2.0 * hmin);
        let r = (2.0 * delta).max(6.0 * sigma);
        // A loop that misses its samples by less than a stroke's scale (sparse samples
        // of a small loop) still follows them: no stroke beside it.
        let loose: Vec<Point> = loose
            .into_iter()
            .zip(away)
            .filter(|&(_, d)| d > r)
            .map(|(p, _)| p)
            .collect();
        let (lines, junctions) = strokes(&loose, r, t);
        (lines, junctions, r)
    };
    let nowhere = || vec![f64::INFINITY; data.len()];
    if !enclosed {
        let (lines, junctions, _) = find(nowhere());
        if !lines.is_empty() {
            return (lines, junctions);
        }
        return (closed, Vec::new());
    }
    let distances = |closed: &[Polyline]| -> Vec<f64> {
        let index = crate::index::SegmentIndex::new(closed);
        data.iter().map(|&p| index.distance(p)).collect()
    };
    // Again after a loop goes: the samples it held are off the loops now, and may show
    // a line running on past another loop (a T's foot wrapped by a small loop, beside
    // the baseline that a loop through empty space held).
    let mut closed = closed;
    let mut away = None;
    for _ in 0..PRUNE_ROUNDS {
        let before = closed.len();
        let (kept, held) = without_bridges(closed, data, tol, t);
        let held = held.unwrap_or_else(|| distances(&kept));
        (closed, away) = without_joined_strokes(kept, data, held, tol, sigma, hmin, t);
        if closed.len() == before || closed.is_empty() {
            break;
        }
    }
    if closed.is_empty() {
        let (lines, junctions, _) = find(nowhere());
        return (lines, junctions);
    }
    let away = away.unwrap_or_else(|| distances(&closed));
    let (lines, junctions, r) = find(away);
    attached(closed, lines, junctions, data, r)
}

/// The loops `closed` and the strokes `lines` (with their `junctions`, indices into
/// `lines`) as one set of curves, each stroke's free end that stops short of a loop
/// joined to it: the strokes are drawn from the samples farther than `r` from every
/// loop, so a stroke that runs into a loop (a T's foot on a counter, a bar crossing a
/// stem that the level set wrapped) stops about `r` short of it, and the samples it
/// left to the loop fill the gap. An end joins its nearest point on the loops when that
/// is within `2 r` (the strokes' own reach across a gap) and every point of the join
/// lies within `r / 2` of a sample, as the spanning tree at scale `r` would have linked
/// them, and the join crosses no stroke (it cannot cross a loop: nothing of them is
/// nearer the end). A loop is split into open pieces where strokes join it, and each
/// joining point is a junction of those pieces and the strokes. Junction indices are
/// into the returned curves.
fn attached(
    closed: Vec<Polyline>,
    mut lines: Vec<Polyline>,
    mut junctions: Vec<Junction>,
    data: &[Point],
    r: f64,
) -> (Vec<Polyline>, Vec<Junction>) {
    let joins = stroke_joins(&closed, &lines, &junctions, data, r);
    // Strokes first, run on to their joining points.
    for &(j, start, _, _, _, q) in &joins {
        let pts = &mut lines[j].points;
        let e = if start { pts[0] } else { pts[pts.len() - 1] };
        if dist(e, q) > 0.0 {
            if start {
                pts.insert(0, q);
            } else {
                pts.push(q);
            }
        }
    }
    // Then each joined loop cut at its joining points into open pieces, which start and
    // end there.
    let mut curves: Vec<Polyline> = Vec::with_capacity(closed.len() + lines.len());
    let mut meets: Vec<(Point, Vec<usize>)> = Vec::new();
    for (k, pl) in closed.into_iter().enumerate() {
        let cuts: Vec<(usize, f64, Point)> = joins
            .iter()
            .filter(|jn| jn.2 == k)
            .map(|jn| (jn.3, jn.4, jn.5))
            .collect();
        if cuts.is_empty() {
            curves.push(pl);
            continue;
        }
        cut_loop(pl, cuts, &mut curves, &mut meets);
    }
    let offset = curves.len();
    for jn in &mut junctions {
        jn.polylines.iter_mut().for_each(|i| *i += offset);
    }
    for &(j, _, _, _, _, q) in &joins {
        meeting(&mut meets, q, offset + j);
    }
    curves.extend(lines);
    junctions.extend(meets.into_iter().map(|(at, mut polylines)| {
        polylines.sort_unstable();
        polylines.dedup();
        Junction { at, polylines }
    }));
    (curves, junctions)
}

/// A stroke's end joined to a loop: (stroke, at its start, loop, segment of the loop,
/// parameter on it, joining point).
type Join = (usize, bool, usize, usize, f64, Point);

/// The joins of [`attached`]: each free stroke end within `2 r` of the loops to its
/// nearest point on them, where the join is held by samples and crosses no stroke.
fn stroke_joins(
    closed: &[Polyline],
    lines: &[Polyline],
    junctions: &[Junction],
    data: &[Point],
    r: f64,
) -> Vec<Join> {
    let mut joins: Vec<Join> = Vec::new();
    if !lines.is_empty() && r > 0.0 {
        if let Ok(samples) = DistanceField::new(data) {
            let loops = crate::index::SegmentIndex::new(closed);
            let strokes = crate::index::SegmentIndex::new(lines);
            let owner = |seg: usize| {
                // The loop whose segments hold `seg`: the last that starts at or before it.
                (0..closed.len())
                    .rev()
                    .find(|&k| loops.start(k) <= seg)
                    .unwrap_or(0)
            };
            for (j, line) in lines.iter().enumerate() {
                if line.closed || line.points.len() < 2 {
                    continue;
                }
                for start in [true, false] {
                    let e = if start {
                        line.points[0]
                    } else {
                        line.points[line.points.len() - 1]
                    };
                    let free = !junctions
                        .iter()
                        .any(|jn| jn.polylines.contains(&j) && dist(jn.at, e) <= 1e-9 * r);
                    if !free {
                        continue;
                    }
                    let Some((d, seg, s)) = loops.nearest(e) else {
                        continue;
                    };
                    if d > 2.0 * r {
                        continue;
                    }
                    let (a, b) = loops.segments()[seg];
                    let q = [a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1])];
                    let steps = ((d / (0.25 * r)).ceil() as usize).max(1);
                    let held = (0..=steps).all(|i| {
                        let u = i as f64 / steps as f64;
                        let p = [e[0] + u * (q[0] - e[0]), e[1] + u * (q[1] - e[1])];
                        samples.distance(p) <= 0.5 * r
                    });
                    if !held || crosses_a_stroke(&strokes, e, q, d) {
                        continue;
                    }
                    let k = owner(seg);
                    joins.push((j, start, k, seg - loops.start(k), s, q));
                }
            }
        }
    }
    joins
}

/// Records that curve `piece` ends at `at` among the `meets` (junction points with the
/// curves meeting there).
fn meeting(meets: &mut Vec<(Point, Vec<usize>)>, at: Point, piece: usize) {
    match meets.iter_mut().find(|m| m.0 == at) {
        Some(m) => m.1.push(piece),
        None => meets.push((at, vec![piece])),
    }
}

/// The loop `pl` cut at `cuts` (segment, parameter on it, point) into open pieces,
/// which start and end there, pushed onto `curves` with their ends among the `meets`.
fn cut_loop(
    pl: Polyline,
    mut cuts: Vec<(usize, f64, Point)>,
    curves: &mut Vec<Polyline>,
    meets: &mut Vec<(Point, Vec<usize>)>,
) {
    cuts.sort_by(|x, y| x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)));
    cuts.dedup_by(|x, y| x.2 == y.2);
    // The loop's points walked once round from just after the first cut, with every
    // cut point in place: runs between consecutive cuts are the pieces.
    let n = pl.points.len();
    let mut walk: Vec<(Point, bool)> = Vec::with_capacity(n + cuts.len() + 1);
    let (first_seg, _, first_at) = cuts[0];
    walk.push((first_at, true));
    let mut c = 1;
    for step in 1..=n {
        let seg = (first_seg + step) % n;
        let v = pl.points[seg];
        // Cuts on the segment before `v` (segment `seg - 1`), in order along it.
        let prev = (seg + n - 1) % n;
        while c < cuts.len() && cuts[c].0 == prev {
            walk.push((cuts[c].2, true));
            c += 1;
        }
        walk.push((v, false));
    }
    // Cuts on the first cut's own segment past it close the walk.
    while c < cuts.len() {
        walk.push((cuts[c].2, true));
        c += 1;
    }
    walk.push((first_at, true));
    let mut piece: Vec<Point> = Vec::new();
    for (p, cut) in walk {
        if piece.last() != Some(&p) {
            piece.push(p);
        }
        if cut && piece.len() > 1 {
            let (a, b) = (piece[0], p);
            let idx = curves.len();
            curves.push(Polyline {
                closed: false,
                points: std::mem::take(&mut piece),
            });
            meeting(meets, a, idx);
            if b != a {
                meeting(meets, b, idx);
            }
            piece.push(p);
        }
    }
}

/// Whether the segment `e q` (of length `d`) crosses a segment of the strokes indexed by
/// `strokes`; touching at an end is no crossing. Every point of `e q` lies within `d / 2`
/// of its middle, so only strokes that come that near can cross it.
fn crosses_a_stroke(strokes: &crate::index::SegmentIndex, e: Point, q: Point, d: f64) -> bool {
    let m = [0.5 * (e[0] + q[0]), 0.5 * (e[1] + q[1])];
    if strokes.distance(m) > 0.5 * d {
        return false;
    }
    strokes.segments().iter().any(|&(a, b)| {
        let (d1, d2) = (cross(sub(q, e), sub(a, e)), cross(sub(q, e), sub(b, e)));
        let (d3, d4) = (cross(sub(b, a), sub(e, a)), cross(sub(b, a), sub(q, a)));
        d1 * d2 < 0.0 && d3 * d4 < 0.0
    })
}

/// The samples [`without_joined_strokes`] thins for a loop, at most.
const JOINED_SAMPLES: usize = 8192;
/// Rounds of the loop tests, at most: each after one that dropped a loop. Bounded, so
/// that the cost stays linear in the samples whatever the number of loops.
const PRUNE_ROUNDS: usize = 4;

/// The loops of `closed` that the data support all round: a loop that bridges a gap in
/// its samples (a stretch with no sample within `tol`, longer than `2 tol` and
/// `bridge_gaps` times the gaps between samples around it, whose middle lies a quarter of
/// its length from every sample, and past one of whose ends `bridge_left_behind` samples
/// farther than `tol` from the loops lie within `tol` and half its length) is no closed
/// curve of the data but strokes joined through empty space (an arc whose ends come
/// near a line), and is left out, its samples to the strokes. With them, the samples'
/// distances to the loops when every loop stays.
fn without_bridges(
    closed: Vec<Polyline>,
    data: &[Point],
    tol: f64,
    t: &Tolerances,
) -> (Vec<Polyline>, Option<Vec<f64>>) {
    if closed.is_empty() {
        return (closed, None);
    }
    let (at, lengths, away) = along_loops(&closed, data, tol);
    // Built only for a loop with a candidate gap.
    let samples = std::cell::OnceCell::new();
    // The samples off the loops, built only for a loop with a candidate gap.
    let loose = std::cell::OnceCell::new();
    let mut near = Vec::new();
    let before = closed.len();
    let kept: Vec<Polyline> = closed
        .into_iter()
        .zip(at)
        .zip(lengths)
        .filter_map(|((pl, mut at), total)| {
            if at.len() < 2 * t.bridge_context + 1 {
                return Some(pl);
            }
            at.sort_unstable_by(f64::total_cmp);
            let n = at.len();
            let gaps: Vec<f64> = (0..n)
                .map(|i| {
                    if i + 1 < n {
                        at[i + 1] - at[i]
                    } else {
                        total - at[i] + at[0]
                    }
                })
                .collect();
            let mut around = Vec::with_capacity(2 * t.bridge_context);
            let bridged = (0..n).any(|i| {
                if gaps[i] <= 2.0 * tol {
                    return false;
                }
                around.clear();
                around.extend(
                    (1..=t.bridge_context).flat_map(|o| [gaps[(i + o) % n], gaps[(i + n - o) % n]]),
                );
                let mid = around.len() / 2;
                let median = *around.select_nth_unstable_by(mid, f64::total_cmp).1;
                if gaps[i] <= t.bridge_gaps * median {
                    return false;
                }
                // Through empty space, not a bulge beside the samples: the loop's point
                // halfway across the gap lies a quarter of the gap from every sample.
                let middle = point_at(&pl, (at[i] + 0.5 * gaps[i]) % total);
                let field = samples.get_or_init(|| DistanceField::new(data).ok());
                let empty = field
                    .as_ref()
                    .is_some_and(|f| f.nearest(middle).dist > 0.25 * gaps[i]);
                if !empty {
                    return false;
                }
                // And the sheet runs on past one of its ends, off the loop.
                let off = loose.get_or_init(|| {
                    let off: Vec<Point> = data
                        .iter()
                        .zip(&away)
                        .filter(|&(_, &d)| d > tol)
                        .map(|(&p, _)| p)
                        .collect();
                    DistanceField::new(&off).ok()
                });
                off.as_ref().is_some_and(|f| {
                    [at[i], at[i] + gaps[i]].iter().any(|&s| {
                        f.within(point_at(&pl, s % total), tol + 0.5 * gaps[i], &mut near);
                        near.len() >= t.bridge_left_behind
                    })
                })
            });
            (!bridged).then_some(pl)
        })
        .collect();
    let away = (kept.len() == before).then_some(away);
    (kept, away)
}

/// Where the samples `data` within `tol` of the loops `closed` lie along them: each
/// loop's arc lengths of its samples' nearest points (unsorted), each loop's length,
/// and every sample's distance to the loops.
#[allow(clippy::type_complexity)]
fn along_loops(
    closed: &[Polyline],
    data: &[Point],
    tol: f64,
) -> (Vec<Vec<f64>>, Vec<f64>, Vec<f64>) {
    let index = crate::index::SegmentIndex::new(closed);
    // Each segment's loop and arc length at its start, in the index's order.
    let mut seg_at: Vec<(usize, f64, f64)> = Vec::new();
    let mut lengths = Vec::with_capacity(closed.len());
    for (k, pl) in closed.iter().enumerate() {
        let mut s = 0.0;
        for (a, b) in pl.segments() {
            let len = crate::geom::dist(a, b);
            seg_at.push((k, s, len));
            s += len;
        }
        if pl.segments().next().is_none() {
            seg_at.extend(pl.points.iter().map(|_| (k, 0.0, 0.0)));
        }
        lengths.push(s);
    }
    let mut at: Vec<Vec<f64>> = vec![Vec::new(); closed.len()];
    let mut away = Vec::with_capacity(data.len());
    for &p in data {
        let Some((d, seg, t)) = index.nearest(p) else {
            away.push(f64::INFINITY);
            continue;
        };
        away.push(d);
        if d <= tol {
            let (k, s, len) = seg_at[seg];
            at[k].push(s + t * len);
        }
    }
    (at, lengths, away)
}

/// The loops of `closed` that are no strokes joined through empty space too narrow for
/// [`without_bridges`]' test (an arc whose ends stop 9 σ short of a line: the space
/// between the two bands of samples is narrower than twice the tolerance, so the loop
/// has a sample within `tol` all along). A loop goes, its samples to the strokes, where
/// the strokes of its own samples (those within `tol` of it, at the scale `r` of
/// [`with_strokes`]) have two free ends, each with no other within `r`, past each of
/// which `bridge_left_behind` samples off the loops lie ahead on its line (within `tol` of
/// the line, `r + tol` of the end): the line runs on past both places where the loop
/// left it. A
/// closed curve's own samples make one stroke whose two ends face each other across a
/// sampling gap, and nothing runs on past them. Only loops with `bridge_left_behind` samples
/// off the loops within `2 tol` are tried, and only their samples within
/// `joined_window` `tol` of those are thinned, at most [`JOINED_SAMPLES`] of them.
/// `away`: each sample's distance to the loops; with the loops kept, and the distances
/// when every loop stays.
fn without_joined_strokes(
    closed: Vec<Polyline>,
    data: &[Point],
    away: Vec<f64>,
    tol: f64,
    sigma: f64,
    hmin: f64,
    t: &Tolerances,
) -> (Vec<Polyline>, Option<Vec<f64>>) {
    let index = crate::index::SegmentIndex::new(&closed);
    // Each segment's loop, in the index's order.
    let seg_loop: Vec<usize> = closed
        .iter()
        .enumerate()
        .flat_map(|(k, pl)| {
            let n = pl.segments().count();
            std::iter::repeat_n(k, if n == 0 { pl.points.len() } else { n })
        })
        .collect();
    // The loop nearest a sample (every sample's, with one loop).
    let loop_of = |p: Point| match closed.len() {
        1 => Some(0),
        _ => index.nearest(p).map(|(_, seg, _)| seg_loop[seg]),
    };
    let mut off_near: Vec<Vec<Point>> = vec![Vec::new(); closed.len()];
    let mut off = Vec::new();
    for (&p, &d) in data.iter().zip(&away) {
        if d > tol {
            off.push(p);
            if d <= 2.0 * tol {
                if let Some(k) = loop_of(p) {
                    off_near[k].push(p);
                }
            }
        }
    }
    if off_near.iter().all(|n| n.len() < t.bridge_left_behind) {
        return (closed, Some(away));
    }
    let Ok(off) = DistanceField::new(&off) else {
        return (closed, Some(away));
    };
    // Only the loop's samples round those off it are thinned, and at most
    // JOINED_SAMPLES of them (every k-th): the cost stays bounded on dense data, whose
    // noise's tail leaves a few samples off every loop.
    let tried: Vec<Point> = off_near
        .iter()
        .filter(|n| n.len() >= t.bridge_left_behind)
        .flatten()
        .copied()
        .collect();
    let Ok(beside) = DistanceField::new(&tried) else {
        return (closed, Some(away));
    };
    let mut on: Vec<Vec<Point>> = vec![Vec::new(); closed.len()];
    for (&p, &d) in data.iter().zip(&away) {
        if d <= tol && beside.nearest(p).dist <= t.joined_window * tol {
            if let Some(k) = loop_of(p) {
                on[k].push(p);
            }
        }
    }
    let before = closed.len();
    let kept: Vec<Polyline> = closed
        .into_iter()
        .zip(on.iter().zip(&off_near))
        .filter(|(_, (on, off_near))| {
            if off_near.len() < t.bridge_left_behind {
                return true;
            }
            let stride = on.len().div_ceil(JOINED_SAMPLES).max(1);
            let on: Vec<Point> = on.iter().copied().step_by(stride).collect();
            let Ok(field) = DistanceField::new(&on) else {
                return true;
            };
            let delta = crate::distance::tube_radius(&field, 2.0 * hmin);
            let r = (2.0 * delta).max(6.0 * sigma);
            let (lines, junctions) = strokes(&on, r, t);
            let ends = free_ends(&lines, &junctions, r);
            let runs_on = ends_running_on(&ends, &off, r, tol, t.bridge_left_behind);
            runs_on < 2
        })
        .map(|(pl, _)| pl)
        .collect();
    let away = (kept.len() == before).then_some(away);
    (kept, away)
}

/// Each free end of the strokes `lines` (none at a junction) with its line, as (end,
/// the line's centre, its direction outwards): the principal line of the stroke's
/// points `r` to `3 r` back (nearer ones may curl into the loop's turn, by 24 degrees
/// at sigma 0.005), or within `3 r` where fewer lie there.
fn free_ends(lines: &[Polyline], junctions: &[Junction], r: f64) -> Vec<(Point, Point, Point)> {
    lines
        .iter()
        .flat_map(|l| [l.points.clone(), l.points.iter().rev().copied().collect()])
        .filter_map(|pts: Vec<Point>| {
            let e = *pts.first()?;
            if junctions.iter().any(|j| dist(j.at, e) == 0.0) {
                return None;
            }
            let within: Vec<Point> = pts
                .iter()
                .copied()
                .take_while(|&q| dist(q, e) <= 3.0 * r)
                .collect();
            let beyond = within.iter().filter(|&&q| dist(q, e) >= r);
            let (c, cov) = if beyond.clone().count() >= 2 {
                crate::geom::principal(beyond.copied())
            } else if within.len() >= 2 {
                // A short chain, straight from a junction.
                crate::geom::principal(within.iter().copied())
            } else {
                return None;
            };
            let t = cov.eigen().2;
            let out = if dot(sub(e, c), t) < 0.0 {
                scale(t, -1.0)
            } else {
                t
            };
            Some((e, c, out))
        })
        .collect()
}

/// How many of the free `ends` (see [`free_ends`]) have no other within `r` and at
/// least `min` of the samples `off` the loops ahead on their line (within `tol` of it,
/// `r + tol` of the end).
fn ends_running_on(
    ends: &[(Point, Point, Point)],
    off: &DistanceField,
    r: f64,
    tol: f64,
    min: usize,
) -> usize {
    let mut near = Vec::new();
    ends.iter()
        .enumerate()
        .filter(|&(i, &(e, c, dir))| {
            let alone = ends
                .iter()
                .enumerate()
                .all(|(j, &(f, _, _))| j == i || dist(e, f) > r);
            // Ahead of the end on its line, within the noise's band: the sheet
            // runs on, not a wall beside it. Off the loop means `tol` from it,
            // so the band reaches that much further than `r`.
            alone && {
                off.within(e, r + tol, &mut near);
                let pts = off.points();
                let ahead = near.iter().filter(|&&q| {
                    let q = pts[q as usize];
                    dot(sub(q, e), dir) > 0.0 && cross(dir, sub(q, c)).abs() <= tol
                });
                ahead.count() >= min
            }
        })
        .count()
}

/// The point of the closed polyline `pl` at arc length `s` from its first vertex.
fn point_at(pl: &Polyline, mut s: f64) -> Point {
    for (a, b) in pl.segments() {
        let len = dist(a, b);
        if s <= len && len > 0.0 {
            let t = s / len;
            return [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t];
        }
        s -= len;
    }
    pl.points.first().copied().unwrap_or([0.0, 0.0])
}

/// The strokes through `points` at scale `r` (at least a few sample spacings and three
/// noise deviations): open polylines, each at least `2 r` long or ending at a junction,
/// and the junctions. Samples with fewer than 3 others within `r` are left out.
pub fn strokes(points: &[Point], r: f64, t: &Tolerances) -> (Vec<Polyline>, Vec<Junction>) {
    if points.len() < 3 || r.is_nan() || r <= 0.0 {
        return (Vec::new(), Vec::new());
    }
    let Ok(field) = DistanceField::new(points) else {
        return (Vec::new(), Vec::new());
    };
    let moved = thin(&field, r, t);
    let (nodes, edges) = spanning_tree(&moved, &field, r, t);
    let mut adj: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    for &(a, b) in &edges {
        adj[a].push(b);
        adj[b].push(a);
    }
    prune(&nodes, &mut adj, r);
    chains(&nodes, &adj, r, t, |p| {
        field.points()[field.nearest(p).index as usize]
    })
}

/// Each sample moved across its sheet onto the principal line of its neighbours within
/// `r`; `None` for a sample with fewer than 3 neighbours (an outlier).
fn thin(field: &DistanceField, r: f64, t: &Tolerances) -> Vec<Option<Point>> {
    use rayon::prelude::*;
    let pts = field.points();
    pts.par_iter()
        .map_init(Vec::new, |buf, &p| {
            // At most the `stroke_fit` nearest: the cost stays bounded on dense data.
            field.nearest_k(p, t.stroke_fit, buf);
            // A sample with too few neighbours within `r` (a stroke's end past a gap in
            // a sparse clean sampling) takes those within `2 r`; one without them there
            // either is an outlier.
            let close = buf
                .iter()
                .filter(|&&i| dist(p, pts[i as usize]) <= r)
                .count();
            let reach = if close < 4 { 2.0 * r } else { r };
            buf.retain(|&i| dist(p, pts[i as usize]) <= reach);
            if buf.len() < 4 {
                return None;
            }
            let (c, cov) = crate::geom::principal(buf.iter().map(|&i| pts[i as usize]));
            let t = cov.eigen().2;
            let s = (p[0] - c[0]) * t[0] + (p[1] - c[1]) * t[1];
            Some([c[0] + s * t[0], c[1] + s * t[1]])
        })
        .collect()
}

/// Kruskal's step: the `pairs` (length, node, node) shortest first, each joining two
/// trees of the forest `parent` an edge.
fn kruskal_join(
    mut pairs: Vec<(f64, usize, usize)>,
    parent: &mut [usize],
    edges: &mut Vec<(usize, usize)>,
) {
    pairs.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    for (_, i, j) in pairs {
        let (a, b) = (root(parent, i), root(parent, j));
        if a != b {
            parent[a] = b;
            edges.push((i, j));
        }
    }
}

/// Each node's pairs with its `links` nearest (by `tree`) within `r`, once each.
fn neighbour_pairs(
    nodes: &[Point],
    tree: &DistanceField,
    links: usize,
    r: f64,
) -> Vec<(f64, usize, usize)> {
    let mut near = Vec::new();
    let mut pairs = Vec::new();
    for (i, &p) in nodes.iter().enumerate() {
        tree.nearest_k(p, links, &mut near);
        pairs.extend(
            near.iter()
                .map(|&j| j as usize)
                .filter(|&j| j > i && dist(p, nodes[j]) <= r)
                .map(|j| (dist(p, nodes[j]), i, j)),
        );
    }
    pairs
}

/// The minimum spanning forest of the moved samples (Kruskal) over each one's
/// `stroke_links` nearest within `r`, then over the pairs of the ends that left across a gap
/// along a stroke (the nearest of a sample at its edge all lie on its own side): within
/// the moved samples' reach, or up to `2 r` where the `samples` run on across it or it
/// runs along the line at both its ends; then over the pairs of an end and another
/// stroke's side where the samples run on between them, or, within twice the reach,
/// where the join runs along the end's line. The nodes and the tree's edges as index
/// pairs into them.
fn spanning_tree(
    moved: &[Option<Point>],
    samples: &DistanceField,
    r: f64,
    t: &Tolerances,
) -> (Vec<Point>, Vec<(usize, usize)>) {
    let nodes: Vec<Point> = moved.iter().flatten().copied().collect();
    let Ok(tree) = DistanceField::new(&nodes) else {
        return (nodes, Vec::new());
    };
    // The tree merges equal points and orders them: work on its points.
    let nodes = tree.points().to_vec();
    let mut parent: Vec<usize> = (0..nodes.len()).collect();
    let mut edges = Vec::new();
    let pairs = neighbour_pairs(&nodes, &tree, t.stroke_links, r);
    kruskal_join(pairs, &mut parent, &mut edges);
    // A gap along a stroke is one of its sampling, which the noise does not widen: the
    // reach is twice the thinned samples' tube radius (four times their 95th
    // percentile neighbour distance, over ten times a random sampling's mean gap), and
    // `2 r` at most. A reach of `2 r` where `r` is set by the noise (6 sigma) joined the
    // end of a stroke to a sheet 9 sigma away.
    let reach = (2.0 * crate::distance::tube_radius(&tree, 0.0)).min(2.0 * r);
    // Farther, up to `2 r`, a gap is one along a stroke only where the samples run on
    // across it (none of its points farther than half the reach from a sample: the
    // thinning pulls the nodes round a fork apart) or the join runs along the line of
    // the nodes within `r` at both its ends (within 30 degrees). A leaf of the tree's
    // zigzag along a noisy sheet is an end too, and a stroke's end that points at a
    // sheet's side across empty space is not continued by it.
    let runs_on = |i: usize, j: usize| {
        let (a, b) = (nodes[i], nodes[j]);
        let d = dist(a, b);
        // Steps of a quarter of the reach; a join of over 64 reaches is never run on.
        let steps = (4.0 * d / reach).ceil();
        let steps = if steps <= 256.0 { steps as usize } else { 0 };
        d <= reach
            || (steps > 0
                && (0..=steps).all(|k| {
                    let f = k as f64 / steps as f64;
                    let q = [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f];
                    samples.nearest(q).dist <= 0.5 * reach
                }))
    };
    // The line of the nodes within `r` of an end; within `2 r` where fewer than three
    // lie within `r` (a lone sample between two sampling gaps).
    let mut line = Vec::new();
    let mut line_at = |e: Point| {
        tree.within(e, r, &mut line);
        if line.len() < 3 {
            tree.within(e, 2.0 * r, &mut line);
        }
        (line.len() >= 2).then(|| {
            crate::geom::principal(line.iter().map(|&i| nodes[i as usize]))
                .1
                .eigen()
                .2
        })
    };
    // The join from `e` to `f` runs along the line at `e`.
    let mut along = |e: Point, f: Point| {
        line_at(e).is_some_and(|u| dot(sub(f, e), u).abs() >= t.stroke_along_cos * dist(e, f))
    };
    // End to end: a stroke that stops more than `r` short of another's side does not
    // touch it.
    let pairs = end_pairs(
        &nodes,
        &tree,
        &edges,
        &mut parent,
        2.0 * r,
        |i, j, degree| {
            let (a, b) = (nodes[i], nodes[j]);
            degree[j] <= 1 && (runs_on(i, j) || (along(a, b) && along(b, a)))
        },
    );
    kruskal_join(pairs, &mut parent, &mut edges);
    // Then an end to another stroke's side where the samples run on between them: an
    // arm of a crossing or the foot of a T whose moved samples the thinning pulled
    // apart from the others' (the fits there see two arms). Or where the end's own line
    // runs on to the side across a gap the sampling leaves (up to twice the reach): a
    // T's foot, whose last samples the thinning moved onto the bar. Not across a gap
    // the noise sets: an arc's end that points at a line 9 sigma away stays free.
    let pairs = end_pairs(&nodes, &tree, &edges, &mut parent, 2.0 * r, |i, j, _| {
        let (a, b) = (nodes[i], nodes[j]);
        runs_on(i, j) || (dist(a, b) <= 2.0 * reach && along(a, b))
    });
    kruskal_join(pairs, &mut parent, &mut edges);
    (nodes, edges)
}

/// The pairs (distance, end, node) of an end of the tree `edges` (a node of degree at
/// most 1) and a node within `reach` of it in another component (`parent`: the
/// union-find of the components) that `accept` takes, given the nodes' degrees. Pairs
/// within one component never join: they are left out before `accept` (the leaves of a
/// dense noisy sheet's tree are many and close together).
fn end_pairs(
    nodes: &[Point],
    tree: &DistanceField,
    edges: &[(usize, usize)],
    parent: &mut [usize],
    reach: f64,
    mut accept: impl FnMut(usize, usize, &[u32]) -> bool,
) -> Vec<(f64, usize, usize)> {
    let mut degree = vec![0u32; nodes.len()];
    for &(a, b) in edges {
        degree[a] += 1;
        degree[b] += 1;
    }
    let comp: Vec<usize> = (0..parent.len()).map(|i| root(parent, i)).collect();
    let mut near = Vec::new();
    let mut pairs = Vec::new();
    for (i, &p) in nodes.iter().enumerate().filter(|&(i, _)| degree[i] <= 1) {
        tree.within(p, reach, &mut near);
        for j in near.iter().map(|&j| j as usize) {
            if comp[i] != comp[j] && accept(i, j, &degree) {
                pairs.push((dist(p, nodes[j]), i, j));
            }
        }
    }
    pairs
}

/// The root of `i`'s set in the union-find `parent`, halving the path on the way.
/// The chain of the tree from `from` through its neighbour `first`, on through nodes of
/// degree 2 until a node of another degree, `from` again, or `limit` of length: the
/// nodes (both ends included) and the length.
fn follow(
    nodes: &[Point],
    adj: &[Vec<usize>],
    from: usize,
    first: usize,
    limit: f64,
) -> (Vec<usize>, f64) {
    let mut path = vec![from, first];
    let mut length = dist(nodes[from], nodes[first]);
    let (mut prev, mut v) = (from, first);
    while adj[v].len() == 2 && v != from && length < limit {
        let next = if adj[v][0] == prev {
            adj[v][1]
        } else {
            adj[v][0]
        };
        length += dist(nodes[v], nodes[next]);
        path.push(next);
        prev = v;
        v = next;
    }
    (path, length)
}

/// Cuts the spurs off the tree: branches from a leaf to a fork shorter than `r`, the
/// zigzag of the tree across a noisy sheet. Where a fork keeps at least two longer
/// branches it is inside a stroke and all its short ones go; where it keeps fewer it
/// is at a stroke's end, and the longest short one stays as the end. Twice over (a cut
/// can leave a shorter spur behind).
fn prune(nodes: &[Point], adj: &mut [Vec<usize>], r: f64) {
    struct Branch {
        nodes: Vec<usize>,
        fork: usize,
        length: f64,
    }
    for _ in 0..2 {
        let mut by_fork: std::collections::BTreeMap<usize, Vec<Branch>> = Default::default();
        for leaf in (0..adj.len()).filter(|&v| adj[v].len() == 1) {
            let (mut branch, length) = follow(nodes, adj, leaf, adj[leaf][0], r);
            let v = branch.pop().expect("a chain has its two ends");
            if adj[v].len() >= 3 && length < r {
                by_fork.entry(v).or_default().push(Branch {
                    nodes: branch,
                    fork: v,
                    length,
                });
            }
        }
        for (fork, mut short) in by_fork {
            let long = adj[fork].len() - short.len();
            if long < 2 {
                // Keep the longest as the stroke's end.
                short.sort_by(|a, b| b.length.total_cmp(&a.length));
                short.remove(0);
            }
            for b in short {
                let last = *b.nodes.last().expect("a branch has its leaf");
                adj[b.fork].retain(|&w| w != last);
                for &v in &b.nodes {
                    adj[v].clear();
                }
            }
        }
    }
}

/// The chains between the tree's ends and forks as smoothed polylines, forks within
/// `2 r` of each other merged into one junction at `snap` of their centre; components shorter than `2 r` dropped.
fn chains(
    nodes: &[Point],
    adj: &[Vec<usize>],
    r: f64,
    t: &Tolerances,
    snap: impl Fn(Point) -> Point,
) -> (Vec<Polyline>, Vec<Junction>) {
    let fork = |v: usize| adj[v].len() >= 3;
    let (junction_of, mut junctions) = fork_junctions(nodes, adj, r);
    let centre = |forks: &[usize]| {
        let m = forks.len() as f64;
        forks.iter().fold([0.0, 0.0], |s, &f| {
            [s[0] + nodes[f][0] / m, s[1] + nodes[f][1] / m]
        })
    };
    let lines = chain_lines(nodes, adj, &junction_of, r);
    // Pin chain ends at forks to their junction: where the arms' lines cross, or else
    // the sample nearest the forks' centre (the fits around a junction see two arms, so
    // the thinned points there are off both; a sample is on one of them, at the
    // junction, though not at the crossing where the other's samples are missing).
    let centres: Vec<Point> = junctions
        .iter()
        .enumerate()
        .map(|(id, (f, _))| {
            let at = snap(centre(f));
            let junction_of = &junction_of;
            let arms: Vec<&[Point]> = lines
                .iter()
                .flat_map(|(pl, ends)| {
                    ends.iter()
                        .filter(move |&&e| fork(e) && junction_of[e] == id)
                        .map(move |_| &pl.points[..])
                })
                .collect();
            crossing(at, &arms, r, t).unwrap_or(at)
        })
        .collect();
    let mut out = Vec::new();
    for (mut pl, ends) in lines {
        for (k, &e) in ends.iter().enumerate() {
            if fork(e) {
                let at = centres[junction_of[e]];
                if k == 1 {
                    pl.points.reverse();
                }
                pl.points[0] = at;
                // The moved samples within `r` of the junction come from fits that saw
                // two arms, and the smoothing carries them a quarter of `r` on: the
                // chain runs straight from the junction to its first point beyond.
                let n = pl.points.len();
                let beyond = (1..n)
                    .find(|&i| i + 1 == n || dist(pl.points[i], at) > 1.25 * r)
                    .unwrap_or(n);
                pl.points.drain(1..beyond.max(1));
                if k == 1 {
                    pl.points.reverse();
                }
            }
        }
        let free_ends = ends.iter().filter(|&&e| !fork(e)).count();
        if free_ends == 2 && pl.length() < 2.0 * r {
            continue;
        }
        let idx = out.len();
        for &e in &ends {
            if fork(e) {
                let j = &mut junctions[junction_of[e]].1;
                if !j.contains(&idx) {
                    j.push(idx);
                }
            }
        }
        out.push(pl);
    }
    let junctions = junctions
        .into_iter()
        .zip(centres)
        .filter(|((_, lines), _)| lines.len() >= 2)
        .map(|((_, polylines), at)| Junction { at, polylines })
        .collect();
    (out, junctions)
}

/// The tree's forks (nodes of three or more edges) grouped into junctions, forks
/// within `2 r` of each other along the tree one junction: each fork's junction
/// (`usize::MAX` for other nodes), and each junction's forks with (empty) polylines.
#[allow(clippy::type_complexity)]
fn fork_junctions(
    nodes: &[Point],
    adj: &[Vec<usize>],
    r: f64,
) -> (Vec<usize>, Vec<(Vec<usize>, Vec<usize>)>) {
    let n = nodes.len();
    let fork = |v: usize| adj[v].len() >= 3;
    let mut junction_of = vec![usize::MAX; n];
    let mut junctions: Vec<(Vec<usize>, Vec<usize>)> = Vec::new(); // (forks, polylines)
    for v in (0..n).filter(|&v| fork(v)) {
        if junction_of[v] != usize::MAX {
            continue;
        }
        let id = junctions.len();
        let mut members = vec![v];
        junction_of[v] = id;
        let mut k = 0;
        while k < members.len() {
            let f = members[k];
            k += 1;
            for &w0 in &adj[f] {
                // A fork at most 2 r along the chain from f through w0 joins.
                let (path, length) = follow(nodes, adj, f, w0, 2.0 * r);
                let w = *path.last().expect("a chain has its two ends");
                if fork(w) && length < 2.0 * r && junction_of[w] == usize::MAX {
                    junction_of[w] = id;
                    members.push(w);
                }
            }
        }
        junctions.push((members, Vec::new()));
    }
    (junction_of, junctions)
}

/// Each chain of the tree between its ends and forks once, smoothed, with its two end
/// nodes; chains between two forks of one junction are inside it and left out.
fn chain_lines(
    nodes: &[Point],
    adj: &[Vec<usize>],
    junction_of: &[usize],
    r: f64,
) -> Vec<(Polyline, [usize; 2])> {
    let n = nodes.len();
    let fork = |v: usize| adj[v].len() >= 3;
    let mut used = vec![false; n];
    let mut lines: Vec<(Polyline, [usize; 2])> = Vec::new();
    let is_key = |v: usize| adj[v].len() != 2;
    for s in (0..n).filter(|&v| is_key(v) && !adj[v].is_empty()) {
        for &first in &adj[s] {
            if used[first] && !is_key(first) {
                continue;
            }
            let (path, _) = follow(nodes, adj, s, first, f64::INFINITY);
            for &v in &path[1..path.len() - 1] {
                used[v] = true;
            }
            let end = *path.last().expect("a chain has its two ends");
            // Each chain once: from its smaller end (a chain between two forks of one
            // junction is inside the junction).
            if (is_key(end) && end < s) || (end == s && path.len() <= 2) {
                continue;
            }
            if fork(s) && fork(end) && junction_of[s] == junction_of[end] {
                continue;
            }
            lines.push((smooth(nodes, &path, r), [s, end]));
        }
    }
    lines
}

/// Where the arms of a junction at `at` cross (each arm a polyline ending there; its
/// points are taken by their distance from `at`, so either way along): the line through the two most opposite arms (within 25 degrees of one line)
/// crossed with the line through the others, each fitted to the arm points between `r`
/// and `3 r` from `at` (nearer, the thinning saw two arms) and straight there to `r / 4`;
/// `None` when they are not, or cross more than `r` from `at`.
fn crossing(at: Point, arms: &[&[Point]], r: f64, t: &Tolerances) -> Option<Point> {
    // At least the four nearest beyond `r`, where the arm has fewer within `3 r` (its
    // chain's vertices may be as sparse as the samples).
    let part = |arm: &&[Point]| -> Vec<Point> {
        let mut beyond: Vec<(f64, Point)> = arm
            .iter()
            .map(|&p| (dist(p, at), p))
            .filter(|&(d, _)| d >= r)
            .collect();
        beyond.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let within = beyond.iter().take_while(|&&(d, _)| d <= 3.0 * r).count();
        beyond.truncate(within.max(4));
        beyond.into_iter().map(|(_, p)| p).collect()
    };
    let parts: Vec<Vec<Point>> = arms.iter().map(part).collect();
    if parts.len() < 3 || parts.iter().any(|p| p.len() < 2) {
        return None;
    }
    // Each arm's own direction, away from `at`: not the direction from `at` to the arm,
    // which tilts both arms of a line towards `at` when `at` (a sample near the forks'
    // centre) lies off that line.
    let out: Vec<Point> = parts
        .iter()
        .map(|p| {
            let (c, cov) = crate::geom::principal(p.iter().copied());
            let t = cov.eigen().2;
            if (c[0] - at[0]) * t[0] + (c[1] - at[1]) * t[1] < 0.0 {
                [-t[0], -t[1]]
            } else {
                t
            }
        })
        .collect();
    let mut through = None;
    for i in 0..out.len() {
        for j in i + 1..out.len() {
            let c = out[i][0] * out[j][0] + out[i][1] * out[j][1];
            if c < -0.9 && through.is_none_or(|(best, _, _)| c < best) {
                through = Some((c, i, j));
            }
        }
    }
    let (_, i, j) = through?;
    let band = 0.25 * r;
    let line_a =
        crate::repair::corners::fit_line(&[parts[i].clone(), parts[j].clone()].concat(), band)?;
    let rest: Vec<Point> = (0..parts.len())
        .filter(|&k| k != i && k != j)
        .flat_map(|k| parts[k].iter().copied())
        .collect();
    // A T's stem may bend (a hook standing on a line): its circle meets the line, where
    // a line fitted to the bend and run on would miss the foot by the bend's sagitta.
    let p =
        match (parts.len() == 3).then(|| arm_meets(line_a, &rest, band, at, t.between_max_slope)) {
            Some(Some(p)) => p,
            _ => {
                let line_b = crate::repair::corners::fit_line(&rest, band)?;
                crate::repair::corners::intersect(line_a, line_b)?
            }
        };
    (dist(p, at) <= r).then_some(p)
}

/// Where the circle (or line) fitted to `arm` (its points in order along it) within
/// `band` (at most `max_slope` against its chord) meets `line` (a point on it and its
/// unit normal): of the two crossings, the one nearer `at`.
fn arm_meets(
    line: (Point, Point),
    arm: &[Point],
    band: f64,
    at: Point,
    max_slope: f64,
) -> Option<Point> {
    if arm.len() < 6 {
        return None;
    }
    super::between::Curve::through(arm, band, max_slope)?
        .meets_line(line.0, line.1)
        .into_iter()
        .filter(|p| p.iter().all(|v| v.is_finite()))
        .min_by(|p, q| dist(*p, at).total_cmp(&dist(*q, at)))
}

/// The chain `path` through `nodes` as a polyline, each inner point the mean of the
/// chain's points within `r / 2` of it along the chain (the ends stay).
fn smooth(nodes: &[Point], path: &[usize], r: f64) -> Polyline {
    let pts: Vec<Point> = path.iter().map(|&i| nodes[i]).collect();
    let mut along = vec![0.0; pts.len()];
    for i in 1..pts.len() {
        along[i] = along[i - 1] + dist(pts[i - 1], pts[i]);
    }
    let half = 0.25 * r;
    let mut out = Vec::with_capacity(pts.len());
    let (mut lo, mut hi) = (0, 0);
    for i in 0..pts.len() {
        if i == 0 || i + 1 == pts.len() {
            out.push(pts[i]);
            continue;
        }
        // Symmetric window, shrunk near the ends so the ends do not pull the line.
        let w = half.min(along[i]).min(along[pts.len() - 1] - along[i]);
        while along[lo] < along[i] - w {
            lo += 1;
        }
        while hi + 1 < pts.len() && along[hi + 1] <= along[i] + w {
            hi += 1;
        }
        let m = (hi - lo + 1) as f64;
        let s = pts[lo..=hi]
            .iter()
            .fold([0.0, 0.0], |s, p| [s[0] + p[0] / m, s[1] + p[1] / m]);
        out.push(s);
    }
    Polyline {
        closed: false,
        points: out,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A loop run along a line, down 0.07 to an arc below it and back up, where the
    /// samples lie on the line and the arc only: the two connectors are 0.07 of empty
    /// space, 35 times the spacing, the line's samples run on past them, and the loop
    /// goes. A circle sampled at random angles (gaps up to about ln 400 = 6 times the
    /// mean) stays, and so does one whose samples leave out a whole arc.
    #[test]
    fn a_loop_through_empty_space_is_left_to_the_strokes() {
        use rand::{Rng, SeedableRng};
        let arc = |n: usize| -> Vec<Point> {
            (0..=n)
                .map(|i| {
                    let a = std::f64::consts::PI * (1.0 + i as f64 / n as f64);
                    [0.25 * a.cos(), -0.07 + 0.25 * a.sin()]
                })
                .collect()
        };
        let mut ring = line([-0.25, 0.0], [0.25, 0.0], 100);
        ring.extend(arc(100).into_iter().rev());
        let bridged = Polyline {
            closed: true,
            points: ring,
        };
        let mut data = line([-0.3, 0.0], [0.3, 0.0], 300);
        data.extend(arc(400));
        assert!(
            without_bridges(vec![bridged], &data, 0.005, &Tolerances::default())
                .0
                .is_empty()
        );

        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let angles: Vec<f64> = (0..400)
            .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
            .collect();
        let data: Vec<Point> = angles
            .iter()
            .map(|a| [0.3 * a.cos(), 0.3 * a.sin()])
            .collect();
        let circle = circle_loop(0.3, 600);
        assert_eq!(
            without_bridges(vec![circle.clone()], &data, 0.001, &Tolerances::default())
                .0
                .len(),
            1
        );

        // Its samples but for an arc of 0.3, 56 times the median of the gaps around: a
        // sampling gap, past whose ends no sample runs on off the loop.
        let data: Vec<Point> = angles
            .iter()
            .filter(|&&a| !(1.0..2.0).contains(&a))
            .map(|a| [0.3 * a.cos(), 0.3 * a.sin()])
            .collect();
        assert_eq!(
            without_bridges(vec![circle], &data, 0.001, &Tolerances::default())
                .0
                .len(),
            1
        );
    }

    /// The strokes drawing's bowl at sigma 0.007: a noisy line, and below it a noisy
    /// half circle whose ends stop 0.0635 (9 sigma) short of it, and the loop the tube
    /// makes of them: along the line between the arc's ends, down to them and round the
    /// arc. The gap between the two bands of samples is narrower than twice the
    /// tolerance, so the bridge test keeps the loop; the line's samples run on past
    /// both places where the loop leaves it, and the loop goes. A noisy circle and its
    /// loop stay, with outliers scattered round it.
    #[test]
    fn a_loop_between_strokes_too_close_for_the_bridge_test_goes() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let (sigma, hmin) = (0.007, 0.007);
        let tol = 3.0 * sigma + 2.0 * hmin;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let noise = Normal::new(0.0, sigma).unwrap();
        let mut jitter = |p: Point| [p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)];
        let arc = |a: f64| [0.25 * a.cos(), -0.0635 + 0.25 * a.sin()];
        let steps: Vec<f64> = (0..=400).map(|i| i as f64 / 400.0).collect();
        let mut data: Vec<Point> = steps
            .iter()
            .map(|f| jitter([-0.45 + 0.9 * f, 0.0]))
            .collect();
        data.extend(
            steps
                .iter()
                .map(|f| jitter(arc(std::f64::consts::PI * (1.0 + f)))),
        );
        let mut ring: Vec<Point> = (0..=50).map(|i| [0.25 - 0.01 * i as f64, 0.0]).collect();
        ring.extend((0..=100).map(|i| arc(std::f64::consts::PI * (1.0 + i as f64 / 100.0))));
        let bowl = Polyline {
            closed: true,
            points: ring,
        };
        let away = |loops: &[Polyline], data: &[Point]| -> Vec<f64> {
            let index = crate::index::SegmentIndex::new(loops);
            data.iter().map(|&p| index.distance(p)).collect()
        };
        let (kept, _) = without_bridges(vec![bowl.clone()], &data, tol, &Tolerances::default());
        assert_eq!(kept.len(), 1, "the bridge test alone keeps the bowl");
        let a = away(std::slice::from_ref(&bowl), &data);
        let (kept, _) = without_joined_strokes(
            vec![bowl],
            &data,
            a,
            tol,
            sigma,
            hmin,
            &Tolerances::default(),
        );
        assert!(kept.is_empty());

        let angles: Vec<f64> = (0..800)
            .map(|_| rng.random_range(0.0..std::f64::consts::TAU))
            .collect();
        let mut data: Vec<Point> = angles
            .iter()
            .map(|a| [0.3 * a.cos(), 0.3 * a.sin()])
            .collect();
        let noise = Normal::new(0.0, sigma).unwrap();
        for p in &mut data {
            *p = [p[0] + noise.sample(&mut rng), p[1] + noise.sample(&mut rng)];
        }
        data.extend((0..40).map(|_| [rng.random_range(-0.5..0.5), rng.random_range(-0.5..0.5)]));
        let circle = circle_loop(0.3, 300);
        let a = away(std::slice::from_ref(&circle), &data);
        let (kept, _) = without_joined_strokes(
            vec![circle],
            &data,
            a,
            tol,
            sigma,
            hmin,
            &Tolerances::default(),
        );
        assert_eq!(kept.len(), 1);
    }

    /// A ring of radius 0.3 with a stem above and one below, all sampled every 0.005, at
    /// `r = 0.025`: the stems' strokes stop 0.03 short of the ring (as strokes drawn from
    /// the samples farther than `r` from it do) and run on to it, cutting the ring into
    /// two pieces that meet each stem at a junction. A third stroke whose samples stop
    /// 0.045 (under `2 r`) short of the ring, across empty space, is left free.
    #[test]
    fn strokes_that_stop_short_of_a_loop_run_on_to_it_across_their_samples() {
        let r = 0.025;
        let ring = circle_loop(0.3, 400);
        let mut data = ring.points.clone();
        data.extend(line([0.0, 0.3], [0.0, 0.8], 100));
        data.extend(line([0.0, -0.3], [0.0, -0.8], 100));
        data.extend(line([0.345, 0.0], [0.8, 0.0], 91));
        let lines = vec![
            Polyline {
                closed: false,
                points: line([0.0, 0.33], [0.0, 0.8], 10),
            },
            Polyline {
                closed: false,
                points: line([0.0, -0.8], [0.0, -0.33], 10),
            },
            Polyline {
                closed: false,
                points: line([0.345, 0.0], [0.8, 0.0], 10),
            },
        ];
        let (curves, junctions) = attached(vec![ring], lines, Vec::new(), &data, r);
        assert_eq!(curves.len(), 5, "{curves:?}");
        assert!(curves.iter().all(|c| !c.closed));
        // The pieces are the ring's two halves: the polygon's length, 2 pi 0.3 to 1e-4.
        let length =
            |pl: &Polyline| -> f64 { pl.points.windows(2).map(|w| dist(w[0], w[1])).sum() };
        let ring_length: f64 = curves[..2].iter().map(length).sum();
        assert!(
            (ring_length - std::f64::consts::TAU * 0.3).abs() < 1e-4,
            "{ring_length}"
        );
        assert_eq!(junctions.len(), 2, "{junctions:?}");
        for j in &junctions {
            let mut members = j.polylines.clone();
            members.sort_unstable();
            let stem = if j.at[1] > 0.0 { 2 } else { 3 };
            assert_eq!(members, vec![0, 1, stem], "{j:?}");
            // On the ring's polygon, which lies within its sagitta (1.9e-4) of the circle.
            assert!(dist(j.at, [0.0, 0.3f64.copysign(j.at[1])]) < 2e-4, "{j:?}");
            for &k in &j.polylines {
                let pl = &curves[k];
                let end = [pl.points[0], pl.points[pl.points.len() - 1]];
                assert!(end.contains(&j.at), "{k}: {pl:?}");
            }
        }
        assert_eq!(curves[4].points[0], [0.345, 0.0], "the free stroke moved");
    }

    /// The closed polyline of `n` points on the circle of radius `r` about the origin.
    fn circle_loop(r: f64, n: usize) -> Polyline {
        Polyline {
            closed: true,
            points: (0..n)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / n as f64;
                    [r * a.cos(), r * a.sin()]
                })
                .collect(),
        }
    }

    fn line(a: Point, b: Point, n: usize) -> Vec<Point> {
        (0..=n)
            .map(|i| {
                let f = i as f64 / n as f64;
                [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f]
            })
            .collect()
    }

    #[test]
    fn a_t_and_a_cross_give_their_arms_and_junctions() {
        // A T: a bar from (0,0) to (2,0) and a stem from (1,0) up to (1,1); a cross
        // of two bars at (5,0). Samples every 0.01, r = 0.05.
        let mut pts = line([0.0, 0.0], [2.0, 0.0], 200);
        pts.extend(line([1.0, 0.01], [1.0, 1.0], 99));
        pts.extend(line([4.0, 0.0], [6.0, 0.0], 200));
        pts.extend(line([5.0, -1.0], [5.0, 1.0], 200));
        let (lines, junctions) = strokes(&pts, 0.05, &Tolerances::default());
        assert_eq!(lines.len(), 7, "{lines:?}");
        assert!(lines.iter().all(|l| !l.closed));
        let mut degrees: Vec<usize> = junctions.iter().map(|j| j.polylines.len()).collect();
        degrees.sort();
        assert_eq!(degrees, vec![3, 4], "{junctions:?}");
        for j in &junctions {
            let expected = if j.polylines.len() == 3 {
                [1.0, 0.0]
            } else {
                [5.0, 0.0]
            };
            assert!(dist(j.at, expected) < 0.05, "{j:?}");
        }
        // Clean samples on straight arms: the polylines lie on them, up to the
        // junctions, where the arms' lines cross (the moved samples within `r` of a
        // junction, whose fits saw two arms, are left out, with the quarter of `r`
        // the smoothing carries them on).
        for j in &junctions {
            let expected = if j.polylines.len() == 3 { 1.0 } else { 5.0 };
            assert!(dist(j.at, [expected, 0.0]) < 2e-4, "{j:?}");
        }
        for l in &lines {
            for &p in &l.points {
                let off = p[1].abs().min((p[0] - 1.0).abs()).min((p[0] - 5.0).abs());
                assert!(off < 2e-4, "{p:?}");
            }
        }
    }

    /// A hook standing on a bar: a quarter circle of radius 0.2 whose foot meets the bar
    /// at right angles at (1, 0), all sampled every 0.005, at `r = 0.025`. The junction
    /// is where the hook's circle meets the bar, to `r / 25`; a line fitted to the hook
    /// between `r` and `3 r` from the junction and run on to the bar misses it by 7.3e-3.
    #[test]
    fn a_bent_stem_meets_its_bar_where_its_circle_does() {
        let mut pts = line([0.0, 0.0], [2.0, 0.0], 400);
        pts.extend((1..=62).map(|i| {
            let a = i as f64 * 0.005 / 0.2;
            [1.2 - 0.2 * a.cos(), 0.2 * a.sin()]
        }));
        let (lines, junctions) = strokes(&pts, 0.025, &Tolerances::default());
        assert_eq!(lines.len(), 3, "{junctions:?}");
        assert_eq!(junctions.len(), 1);
        let off = dist(junctions[0].at, [1.0, 0.0]);
        assert!(off < 1e-3, "{junctions:?}");
    }

    /// A cross of a level bar and an upright one, sampled every 0.01 but for the level
    /// bar's samples within 0.02 of the crossing (as a random sampling leaves), the
    /// upright's 0.004 off it: the junction lies where the arms' lines cross, not on
    /// the upright's sample nearest the forks' centre.
    #[test]
    fn a_crossing_is_where_the_arms_lines_cross() {
        let mut pts: Vec<Point> = line([-1.0, 0.0], [1.0, 0.0], 200)
            .into_iter()
            .filter(|p| p[0].abs() > 0.025)
            .collect();
        pts.extend(line([0.0, -0.996], [0.0, 1.004], 200));
        let (lines, junctions) = strokes(&pts, 0.05, &Tolerances::default());
        assert_eq!(lines.len(), 4, "{}", lines.len());
        assert_eq!(junctions.len(), 1, "{junctions:?}");
        // The arms are the smoothed chains, which lean by 1e-5 within 3 r of the
        // junction; the sample rule put it 4e-3 off.
        let at = junctions[0].at;
        assert!(dist(at, [0.0, 0.0]) < 1e-4, "{at:?}");
    }

    /// A clean line sampled every 0.004, its last two samples 0.012 past the others
    /// (farther than `r` = 0.01, as a random sampling leaves a stroke's end): they have
    /// too few neighbours within `r` but enough within `2 r`, and the stroke runs on to
    /// them, not stopping 0.016 short.
    #[test]
    fn a_stroke_runs_on_to_its_samples_past_a_gap_at_its_end() {
        let mut pts: Vec<Point> = (0..=100).map(|i| [0.004 * i as f64, 0.0]).collect();
        pts.extend([[0.412, 0.0], [0.416, 0.0]]);
        let (lines, junctions) = strokes(&pts, 0.01, &Tolerances::default());
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(junctions.is_empty());
        let ends = [lines[0].points[0][0], lines[0].points.last().unwrap()[0]];
        let (lo, hi) = (ends[0].min(ends[1]), ends[0].max(ends[1]));
        assert!(lo < 1e-9 && hi > 0.416 - 1e-9, "{ends:?}");
    }

    /// A bar sampled every 0.01 but for a gap of 0.06 (past the moved samples' reach of
    /// four times their spacing, short of `2 r`), and a noisy one (sigma 0.004) missing
    /// 0.05 of its samples: each is one polyline across its gap, the join running along
    /// the line at both its ends.
    #[test]
    fn a_gap_along_a_bar_is_joined_across() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let pts: Vec<Point> = line([0.0, 0.0], [1.0, 0.0], 100)
            .into_iter()
            .filter(|p| !(0.47..0.53).contains(&p[0]))
            .collect();
        let (lines, junctions) = strokes(&pts, 0.05, &Tolerances::default());
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(junctions.is_empty());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, 0.004).unwrap();
        let xs: Vec<f64> = (0..800)
            .map(|_| rng.random::<f64>())
            .filter(|x| !(0.475..0.525).contains(x))
            .collect();
        let pts: Vec<Point> = xs
            .iter()
            .map(|x| [x + noise.sample(&mut rng), noise.sample(&mut rng)])
            .collect();
        let (lines, junctions) = strokes(&pts, 6.0 * 0.004, &Tolerances::default());
        assert_eq!(lines.len(), 1, "{junctions:?}");
        assert!(junctions.is_empty());
    }

    /// A slanted bar sampled every 0.01 but for one lone sample between two gaps of
    /// 0.06 (past the moved samples' reach, short of `2 r`): one polyline. No other
    /// sample lies within `r` of the lone one, so its line is that of the samples
    /// within `2 r`; with its own alone (no direction) both joins were refused.
    #[test]
    fn a_lone_sample_between_two_gaps_joins_both_sides() {
        let (a, b) = ([0.0, 0.0], [0.6, 0.8]);
        let pts: Vec<Point> = line(a, b, 100)
            .into_iter()
            .enumerate()
            .filter(|&(i, _)| !(41..=45).contains(&i) && !(47..=51).contains(&i))
            .map(|(_, p)| p)
            .collect();
        let (lines, junctions) = strokes(&pts, 0.05, &Tolerances::default());
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(junctions.is_empty());
        let ends = [lines[0].points[0], *lines[0].points.last().unwrap()];
        assert!(ends.iter().any(|&e| dist(e, a) < 1e-9) && ends.iter().any(|&e| dist(e, b) < 1e-9));
    }

    /// A bar and a stem sampled every 0.01, the stem's last sample 0.06 above the bar
    /// (past the moved samples' reach of 0.04, within twice it): a sampling gap at a
    /// T's foot, across which the stem's own line meets the bar. A junction of three
    /// where the stem stands; without the stem's line, two strokes and none.
    #[test]
    fn a_stem_whose_foot_is_unsampled_stands_on_its_bar() {
        let mut pts = line([0.0, 0.0], [1.0, 0.0], 100);
        pts.extend(line([0.5, 0.06], [0.5, 0.6], 54));
        let (lines, junctions) = strokes(&pts, 0.05, &Tolerances::default());
        assert_eq!(lines.len(), 3, "{lines:?}");
        assert_eq!(junctions.len(), 1, "{junctions:?}");
        assert_eq!(junctions[0].polylines.len(), 3);
        assert!(dist(junctions[0].at, [0.5, 0.0]) < 0.01, "{junctions:?}");
    }

    /// A noisy bar (sigma 0.007, as the strokes drawing at 0.5% of its diagonal) with a
    /// stem standing on it and a free stroke whose end stops 0.065 (9 sigma) below it,
    /// thinned at `r = 6 sigma`: the stem meets the bar at a junction of three, and the
    /// free stroke stays free, though its end lies within `2 r` of the leaves of the
    /// tree's zigzag along the bar. Over five seeds.
    #[test]
    fn a_stroke_that_stops_short_of_a_noisy_bar_is_not_joined_to_it() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let sigma = 0.007;
        for seed in 1..=5 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let noise = Normal::new(0.0, sigma).unwrap();
            let mut along = |a: Point, b: Point, n: usize| -> Vec<Point> {
                (0..n)
                    .map(|_| {
                        let f: f64 = rng.random();
                        [
                            a[0] + (b[0] - a[0]) * f + noise.sample(&mut rng),
                            a[1] + (b[1] - a[1]) * f + noise.sample(&mut rng),
                        ]
                    })
                    .collect()
            };
            let mut pts = along([-0.5, 0.0], [0.5, 0.0], 600);
            pts.extend(along([0.25, 0.0], [0.25, -0.3], 180));
            pts.extend(along([-0.2, -0.065], [-0.2, -0.4], 200));
            let (lines, junctions) = strokes(&pts, 6.0 * sigma, &Tolerances::default());
            assert_eq!(lines.len(), 4, "seed {seed}: {junctions:?}");
            assert_eq!(junctions.len(), 1, "seed {seed}: {junctions:?}");
            assert_eq!(junctions[0].polylines.len(), 3, "seed {seed}");
            assert!(
                dist(junctions[0].at, [0.25, 0.0]) < 3.0 * sigma,
                "seed {seed}"
            );
            // The free stroke ends where its samples do, not on the bar.
            let free = lines
                .iter()
                .find(|l| l.points.iter().all(|p| p[0] < 0.0 && p[1] < -0.03))
                .unwrap_or_else(|| panic!("seed {seed}: no free stroke in {lines:?}"));
            let top = free.points.iter().map(|p| p[1]).fold(f64::MIN, f64::max);
            assert!(top < -0.05, "seed {seed}: the free stroke reaches {top}");
        }
    }

    #[test]
    fn a_noisy_arc_is_one_polyline_along_its_middle_and_outliers_are_dropped() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let noise = Normal::new(0.0, 0.005).unwrap();
        let mut pts: Vec<Point> = (0..2000)
            .map(|_| {
                let a = rng.random::<f64>() * std::f64::consts::PI;
                let r = 0.5 + noise.sample(&mut rng);
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        pts.extend((0..20).map(|_| [rng.random::<f64>() * 2.0 - 1.0, -0.5]));
        let (lines, junctions) = strokes(&pts, 0.03, &Tolerances::default());
        assert_eq!(lines.len(), 1, "{lines:?}");
        assert!(junctions.is_empty());
        // The thinned line is within 2 sigma of the arc (the fit over r = 6 sigma
        // averages the noise down), its ends within 2 r of the arc's.
        let l = &lines[0];
        let worst = l
            .points
            .iter()
            .map(|p| (dist(*p, [0.0, 0.0]) - 0.5).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.01, "{worst}");
        let ends = [l.points[0], *l.points.last().unwrap()];
        assert!(ends.iter().any(|e| dist(*e, [0.5, 0.0]) < 0.06), "{ends:?}");
        assert!(
            ends.iter().any(|e| dist(*e, [-0.5, 0.0]) < 0.06),
            "{ends:?}"
        );
    }
}
