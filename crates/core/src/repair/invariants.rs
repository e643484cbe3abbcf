//! What every result's curves hold, whatever the passes before made of them: each vertex
//! lies within the support distance of the data, and no two segments cross (the curves
//! are simple and disjoint but where pieces meet at a shared end). A piece that breaks
//! one is cut where it does, and the record's warnings say how much was cut
//! ([`crate::Warning::OffData`], [`crate::Warning::Crossings`]).
//!
//! Both are checks on the output, not repairs of the method: on the shapes and scans the
//! project's tables hold, they cut nothing.

use crate::geom::{dist, Point, Polyline};
use crate::repair::strokes::Junction;
use crate::warning::Warning;

/// What [`enforce`] needs of a point cloud (lengths in data units).
pub struct Cloud<'a> {
    /// A point's distance to the nearest sample that is not an outlier.
    pub distance: &'a (dyn Fn(Point) -> f64 + Sync),
    /// The support distance: the accuracy bound `3 sigma + 2 hmin` plus half the
    /// neighbours' reach (a curve across the widest gap the strokes join lies within
    /// half of it of the samples at the gap's ends).
    pub reach: f64,
    /// The longer side of the samples' bounding box.
    pub extent: f64,
    /// Closed loops enclosing less are specks (the export's smallest loop).
    pub min_area: f64,
    /// Segments no longer than this are a repeated point.
    pub eps: f64,
}

/// A point cloud's curves made to hold the invariants: within the support distance of
/// its samples ([`supported`]), no two crossing ([`uncrossed`]: pieces crossing
/// themselves split into loops, specks smaller than `min_area` dropped), and well formed
/// ([`well_formed`]); each junction keeps the pieces its ends went to (cuts move no
/// vertex). Returns the warnings for what had to be cut, and [`collapsed`]'s.
pub fn enforce(
    polylines: Vec<Polyline>,
    junctions: Vec<Junction>,
    cloud: &Cloud<'_>,
) -> (Vec<Polyline>, Vec<Junction>, Vec<Warning>) {
    let mut warnings = Vec::new();
    let ends: Vec<Vec<Point>> = junctions
        .iter()
        .map(|j| {
            j.polylines
                .iter()
                .filter_map(|&k| polylines.get(k))
                .filter_map(|pl| {
                    let (a, b) = (*pl.points.first()?, *pl.points.last()?);
                    Some(if dist(a, j.at) <= dist(b, j.at) { a } else { b })
                })
                .collect()
        })
        .collect();
    let (polylines, cut) = supported(polylines, cloud.distance, cloud.reach);
    if cut > 0.0 {
        warnings.push(Warning::OffData {
            length: cut,
            reach: cloud.reach,
        });
    }
    let (polylines, removed, crossings) = uncrossed(polylines, cloud.min_area);
    // Dropping a point within `eps` of the one before it moves a segment's end by as
    // much, and where that end lay on another segment (a crossing point the split
    // above inserted), the segment now crosses it: the crossings left are removed
    // last, which deletes segments and adds no point.
    let (polylines, late) = uncross_pieces(well_formed(polylines, cloud.eps));
    if removed + late > 0 {
        warnings.push(Warning::Crossings {
            removed: removed + late,
        });
    }
    // Where two pieces crossed they now meet, each ending at the crossing point (or
    // within `eps` of it, once repeated points are dropped).
    let ends: Vec<Vec<Point>> = ends
        .into_iter()
        .chain(crossings.iter().map(|&x| {
            polylines
                .iter()
                .filter(|pl| !pl.closed)
                .flat_map(|pl| [pl.points[0], pl.points[pl.points.len() - 1]])
                .filter(|&e| dist(e, x) <= cloud.eps)
                .collect()
        }))
        .collect();
    let junctions: Vec<Junction> = junctions
        .into_iter()
        .chain(crossings.iter().map(|&at| Junction {
            at,
            polylines: Vec::new(),
        }))
        .zip(ends)
        .filter_map(|(j, ends)| {
            let members: Vec<usize> = polylines
                .iter()
                .enumerate()
                .filter(|(_, pl)| {
                    let (a, b) = (pl.points[0], pl.points[pl.points.len() - 1]);
                    !pl.closed && ends.iter().any(|&e| e == a || e == b)
                })
                .map(|(k, _)| k)
                .collect();
            (members.len() >= 2).then_some(Junction {
                at: j.at,
                polylines: members,
            })
        })
        .collect();
    warnings.extend(collapsed(&polylines, &junctions, cloud.extent));
    (polylines, junctions, warnings)
}

/// Every result's curves, made well formed: no segment shorter than `eps` (the
/// crossings of neighbouring triangles, and the joins of the passes after them, repeat
/// a point within rounding), and no closed curve of fewer than three points (one
/// segment walked there and back encloses nothing: it stays, open). A curve left with
/// a single point is dropped. Nothing of a curve's course is lost.
pub fn well_formed(polylines: Vec<Polyline>, eps: f64) -> Vec<Polyline> {
    polylines
        .into_iter()
        .filter_map(|mut pl| {
            pl.points.dedup_by(|b, a| dist(*a, *b) <= eps);
            if pl.closed && pl.points.len() > 1 {
                let (first, last) = (pl.points[0], pl.points[pl.points.len() - 1]);
                if dist(first, last) <= eps {
                    pl.points.pop();
                }
            }
            if pl.closed && pl.points.len() < 3 {
                pl.closed = false;
            }
            (pl.points.len() >= 2).then_some(pl)
        })
        .collect()
}

/// Whether a point cloud's curves look collapsed: a star (one junction holding six or
/// more of the open curves' ends, and at least half of them: spokes from one point
/// across the drawing), or curves shorter than half the longer side of the data's box
/// `extent` (a curve through data spanning a box is about as long as its side at least).
pub fn collapsed(polylines: &[Polyline], junctions: &[Junction], extent: f64) -> Option<Warning> {
    let open_ends = 2 * polylines.iter().filter(|pl| !pl.closed).count();
    let busiest = junctions
        .iter()
        .map(|j| j.polylines.len())
        .max()
        .unwrap_or(0);
    let length: f64 = polylines.iter().map(Polyline::length).sum();
    let star = busiest >= 6 && 2 * busiest >= open_ends;
    let short = !polylines.is_empty() && length < 0.5 * extent;
    (star || short).then_some(Warning::Collapsed {
        ends: (busiest, open_ends),
        length: (length, extent),
    })
}

/// `polylines` with every stretch farther than `reach` from the data (`distance` gives
/// a point's distance) removed: a closed curve with such a stretch opens there, an open
/// one splits. Vertices are checked, and so are points every half `reach` along each
/// segment between two kept vertices: a long straight segment (a spoke across a
/// drawing, a chord over a bay) can leave the data between ends that lie on it. Such a
/// segment is cut back to its last points within `reach` on either side. `distance`
/// moves by at most the step along a segment, so every point kept lies within
/// `1.25 reach`. Pieces of fewer than two vertices go. Returns the kept pieces and the
/// length removed.
pub fn supported(
    polylines: Vec<Polyline>,
    distance: impl Fn(Point) -> f64,
    reach: f64,
) -> (Vec<Polyline>, f64) {
    let mut out = Vec::with_capacity(polylines.len());
    let mut removed = 0.0;
    let step = 0.5 * reach;
    for pl in polylines {
        let n = pl.points.len();
        let ok: Vec<bool> = pl.points.iter().map(|&p| distance(p) <= reach).collect();
        let segs = match (pl.closed, n) {
            (_, 0 | 1) => 0,
            (true, _) => n,
            (false, _) => n - 1,
        };
        // The walk: each vertex with whether it is kept, and where a segment between
        // two kept vertices leaves the data, its last supported points either side of
        // an unkept mark.
        let mut walk: Vec<(Point, bool)> = Vec::with_capacity(n);
        for i in 0..n {
            walk.push((pl.points[i], ok[i]));
            let j = (i + 1) % n;
            if i >= segs || !ok[i] || !ok[j] {
                continue;
            }
            let (a, b) = (pl.points[i], pl.points[j]);
            let m = (dist(a, b) / step).ceil() as usize;
            let at = |k: usize| {
                let t = k as f64 / m as f64;
                if k == m {
                    b
                } else {
                    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
                }
            };
            let off: Vec<usize> = (1..m).filter(|&k| distance(at(k)) > reach).collect();
            if let (Some(&first), Some(&last)) = (off.first(), off.last()) {
                walk.push((at(first - 1), true));
                walk.push((at(first), false));
                walk.push((at(last + 1), true));
            }
        }
        if walk.iter().all(|w| w.1) {
            out.push(pl);
            continue;
        }
        let before = pl.length();
        let len = walk.len();
        // A closed curve is walked from a mark off the data, so each kept stretch is
        // one open piece.
        let start = if pl.closed {
            walk.iter().position(|w| !w.1).unwrap_or(0)
        } else {
            0
        };
        let steps = if pl.closed { len + 1 } else { len };
        let mut kept = 0.0;
        let mut cur: Vec<Point> = Vec::new();
        let mut flush = |cur: &mut Vec<Point>, out: &mut Vec<Polyline>| {
            cur.dedup();
            if cur.len() >= 2 {
                let piece = Polyline {
                    closed: false,
                    points: std::mem::take(cur),
                };
                kept += piece.length();
                out.push(piece);
            } else {
                cur.clear();
            }
        };
        for k in 0..steps {
            let (p, keep) = walk[(start + k) % len];
            if keep {
                cur.push(p);
            } else {
                flush(&mut cur, &mut out);
            }
        }
        flush(&mut cur, &mut out);
        removed += (before - kept).max(0.0);
    }
    (out, removed)
}

/// The segments of `polylines` as (piece, index of its first vertex, a, b).
fn segments(polylines: &[Polyline]) -> Vec<(usize, usize, Point, Point)> {
    let mut out = Vec::new();
    for (k, pl) in polylines.iter().enumerate() {
        let n = pl.points.len();
        if n < 2 {
            continue;
        }
        let m = if pl.closed { n } else { n - 1 };
        out.extend((0..m).map(|i| (k, i, pl.points[i], pl.points[(i + 1) % n])));
    }
    out
}

/// Whether the segments `ab` and `cd` cross properly: each one's ends strictly on
/// either side of the other's line (exact predicates). Touching, at an end or along a
/// line, is not crossing: pieces meet at junctions that way.
fn cross(a: Point, b: Point, c: Point, d: Point) -> bool {
    let o = |p: Point, q: Point, r: Point| {
        robust::orient2d(
            robust::Coord { x: p[0], y: p[1] },
            robust::Coord { x: q[0], y: q[1] },
            robust::Coord { x: r[0], y: r[1] },
        )
    };
    let (d1, d2) = (o(a, b, c), o(a, b, d));
    let (d3, d4) = (o(c, d, a), o(c, d, b));
    ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
}

/// `polylines` with no two segments crossing. A piece crossing itself is split at the
/// crossing into the loop between its two passes and the rest (a closed curve into two
/// loops, an open one into the open rest and the loop), the crossing point a vertex of
/// both: they touch there and cross nowhere. A loop enclosing less than `min_area` is a
/// speck (a twist a pass left at a corner) and goes, as the export stage's specks do.
/// Pieces crossing each other are split where they cross and meet there
/// ([`split_at_crossings`]). Returns the pieces, the number of crossings undone and the
/// points where pieces crossed each other (the junctions that made).
pub fn uncrossed(polylines: Vec<Polyline>, min_area: f64) -> (Vec<Polyline>, usize, Vec<Point>) {
    let mut untwisted = 0;
    let mut simple = Vec::with_capacity(polylines.len());
    for pl in polylines {
        untwisted += untwist(pl, min_area, &mut simple);
    }
    let (out, split, points) = split_at_crossings(simple);
    (out, untwisted + split, points)
}

/// `pl` split at its self-crossings into simple pieces, pushed onto `out` (specks
/// dropped); the number of crossings undone.
fn untwist(pl: Polyline, min_area: f64, out: &mut Vec<Polyline>) -> usize {
    let mut undone = 0;
    let mut todo = vec![pl];
    while let Some(mut pl) = todo.pop() {
        let segs = segments(std::slice::from_ref(&pl));
        let Some((s, t)) = crossing_pairs(&segs).into_iter().next() else {
            if !pl.closed || pl.signed_area().abs() >= min_area {
                out.push(pl);
            }
            continue;
        };
        let (i, j) = (
            segs[s as usize].1.min(segs[t as usize].1),
            segs[s as usize].1.max(segs[t as usize].1),
        );
        let n = pl.points.len();
        let x = intersection(
            pl.points[i],
            pl.points[i + 1],
            pl.points[j],
            pl.points[(j + 1) % n],
        );
        // Each side has fewer segments than the piece had (one more vertex, the crossing,
        // and at least two segments fewer), so the splitting ends.
        let inner = Polyline {
            closed: true,
            points: std::iter::once(x)
                .chain(pl.points[i + 1..=j].iter().copied())
                .collect(),
        };
        let mut rest: Vec<Point> = pl.points[..=i].to_vec();
        rest.push(x);
        rest.extend_from_slice(&pl.points[j + 1..]);
        pl.points = rest;
        todo.push(pl);
        todo.push(inner);
        undone += 1;
    }
    undone
}

/// Where the lines of `ab` and `cd` meet (they cross: the denominator is not zero).
fn intersection(a: Point, b: Point, c: Point, d: Point) -> Point {
    let (r, s) = ([b[0] - a[0], b[1] - a[1]], [d[0] - c[0], d[1] - c[1]]);
    let den = r[0] * s[1] - r[1] * s[0];
    let t = ((c[0] - a[0]) * s[1] - (c[1] - a[1]) * s[0]) / den;
    [a[0] + t * r[0], a[1] + t * r[1]]
}

/// The pairs of crossing segments (indices into `segs`, smaller first), sorted.
fn crossing_pairs(segs: &[(usize, usize, Point, Point)]) -> Vec<(u32, u32)> {
    if segs.len() < 2 {
        return Vec::new();
    }
    // A uniform grid of cells about four median segments wide: each segment is tested
    // against those sharing a cell with its bounding box.
    let mut lens: Vec<f64> = segs.iter().map(|s| dist(s.2, s.3)).collect();
    let mid = lens.len() / 2;
    let (_, &mut median, _) = lens.select_nth_unstable_by(mid, f64::total_cmp);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for s in segs {
        for p in [s.2, s.3] {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
    }
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]);
    // At most about 4 cells a segment in all: a few long segments cannot ask for more.
    let cells_per_side = ((span / (4.0 * median.max(f64::MIN_POSITIVE))).ceil())
        .clamp(1.0, (2.0 * (segs.len() as f64).sqrt()).max(1.0)) as usize;
    let cell = span.max(f64::MIN_POSITIVE) / cells_per_side as f64;
    let at = |x: f64, k: usize| (((x - lo[k]) / cell) as usize).min(cells_per_side - 1);
    let mut grid: rustc_hash::FxHashMap<(usize, usize), Vec<u32>> = Default::default();
    for (j, s) in segs.iter().enumerate() {
        let (x0, x1) = (at(s.2[0].min(s.3[0]), 0), at(s.2[0].max(s.3[0]), 0));
        let (y0, y1) = (at(s.2[1].min(s.3[1]), 1), at(s.2[1].max(s.3[1]), 1));
        for x in x0..=x1 {
            for y in y0..=y1 {
                grid.entry((x, y)).or_default().push(j as u32);
            }
        }
    }
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for ids in grid.values() {
        for (x, &s) in ids.iter().enumerate() {
            for &t in &ids[x + 1..] {
                let (p, q) = (&segs[s as usize], &segs[t as usize]);
                if cross(p.2, p.3, q.2, q.3) {
                    pairs.push((s.min(t), s.max(t)));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

/// Pieces crossing each other, split where they cross: the crossing point becomes a
/// vertex of both, and each piece ends there, so they meet at a junction (an X of two
/// strokes, or a T whose foot overshot the bar) and cross nowhere. Both pieces lie on
/// the data (the support invariant holds before), so neither loses anything of its
/// course: deleting the shorter one's segment through the crossing instead left its
/// end some `hmin` short of the other, two pieces where the drawing has one. Returns
/// the pieces, the number of crossings and the crossing points.
fn split_at_crossings(polylines: Vec<Polyline>) -> (Vec<Polyline>, usize, Vec<Point>) {
    let segs = segments(&polylines);
    let pairs = crossing_pairs(&segs);
    if pairs.is_empty() {
        return (polylines, 0, Vec::new());
    }
    // Each segment's crossing points, by their parameter along it.
    let mut at: Vec<Vec<(f64, Point)>> = vec![Vec::new(); segs.len()];
    let mut points = Vec::with_capacity(pairs.len());
    for &(s, t) in &pairs {
        let (p, q) = (&segs[s as usize], &segs[t as usize]);
        let x = intersection(p.2, p.3, q.2, q.3);
        let along = |a: Point, b: Point| {
            let d = [b[0] - a[0], b[1] - a[1]];
            ((x[0] - a[0]) * d[0] + (x[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1])
        };
        at[s as usize].push((along(p.2, p.3), x));
        at[t as usize].push((along(q.2, q.3), x));
        points.push(x);
    }
    let mut out = Vec::with_capacity(polylines.len() + 2 * pairs.len());
    let mut first = 0;
    for pl in polylines {
        let n = pl.points.len();
        let m = match (pl.closed, n) {
            (_, 0 | 1) => 0,
            (true, _) => n,
            (false, _) => n - 1,
        };
        let cuts = &mut at[first..first + m];
        first += m;
        if cuts.iter().all(Vec::is_empty) {
            out.push(pl);
            continue;
        }
        // The piece's course with the crossing points in it, and where it splits.
        let mut course: Vec<Point> = Vec::with_capacity(n + 2 * cuts.len());
        let mut splits: Vec<usize> = Vec::new();
        for (i, c) in cuts.iter_mut().enumerate() {
            course.push(pl.points[i]);
            c.sort_by(|a, b| a.0.total_cmp(&b.0));
            for &(_, x) in c.iter() {
                splits.push(course.len());
                course.push(x);
            }
        }
        if !pl.closed {
            course.push(pl.points[n - 1]);
        }
        // A closed piece is opened at its first split and walked round to it again.
        let (course, splits) = if pl.closed {
            let s0 = splits[0];
            let len = course.len();
            let turned: Vec<Point> = (0..=len).map(|k| course[(s0 + k) % len]).collect();
            let splits: Vec<usize> = splits.iter().map(|&s| (s + len - s0) % len).collect();
            (turned, splits)
        } else {
            (course, splits)
        };
        let mut start = 0;
        for &s in splits.iter().chain(std::iter::once(&(course.len() - 1))) {
            if s > start {
                out.push(Polyline {
                    closed: false,
                    points: course[start..=s].to_vec(),
                });
            }
            start = s;
        }
    }
    (out, pairs.len(), points)
}

/// Pieces crossing each other: of each pair, the shorter piece's segment goes.
fn uncross_pieces(polylines: Vec<Polyline>) -> (Vec<Polyline>, usize) {
    let segs = segments(&polylines);
    let pairs = crossing_pairs(&segs);
    let length: Vec<f64> = polylines.iter().map(Polyline::length).collect();
    let mut cut = vec![false; segs.len()];
    for &(s, t) in &pairs {
        let (s, t) = (s as usize, t as usize);
        if cut[s] || cut[t] {
            continue;
        }
        let (p, q) = (&segs[s], &segs[t]);
        let victim = if p.0 == q.0 || length[q.0] <= length[p.0] {
            t
        } else {
            s
        };
        cut[victim] = true;
    }
    let removed = cut.iter().filter(|&&c| c).count();
    if removed == 0 {
        return (polylines, 0);
    }
    // Each piece split at its removed segments, as `supported` splits at removed
    // vertices: a segment is removed by opening the piece between its two vertices.
    let mut out = Vec::with_capacity(polylines.len() + removed);
    let mut first = 0;
    for pl in polylines {
        let n = pl.points.len();
        let m = if n < 2 {
            0
        } else if pl.closed {
            n
        } else {
            n - 1
        };
        let gone = &cut[first..first + m];
        first += m;
        if !gone.iter().any(|&c| c) {
            out.push(pl);
            continue;
        }
        // Walk from the vertex after a removed segment (closed), or from the start.
        let start = if pl.closed {
            (gone.iter().position(|&c| c).unwrap_or(0) + 1) % n
        } else {
            0
        };
        let mut cur = vec![pl.points[start]];
        let steps = if pl.closed { n } else { m };
        for k in 0..steps {
            let i = (start + k) % n;
            if i >= m {
                break;
            }
            let next = pl.points[(i + 1) % n];
            if gone[i] {
                if cur.len() >= 2 {
                    out.push(Polyline {
                        closed: false,
                        points: std::mem::take(&mut cur),
                    });
                }
                cur = vec![next];
            } else {
                cur.push(next);
            }
        }
        if cur.len() >= 2 {
            out.push(Polyline {
                closed: false,
                points: cur,
            });
        }
    }
    (out, removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Repeated points go, a closed curve of two points opens, a curve of one point
    /// goes; a proper loop and an open curve keep every point.
    #[test]
    fn curves_are_well_formed() {
        let pl = |closed, points: &[[f64; 2]]| Polyline {
            closed,
            points: points.to_vec(),
        };
        let eps = 1e-9;
        let out = well_formed(
            vec![
                pl(false, &[[0.0, 0.0], [1e-12, 0.0], [1.0, 0.0], [1.0, 1e-13]]),
                pl(true, &[[2.0, 0.0], [2.05, 0.0], [2.0, 1e-15]]),
                pl(true, &[[3.0, 0.0], [3.0, 0.0]]),
                pl(true, &[[4.0, 0.0], [5.0, 0.0], [5.0, 1.0]]),
                pl(false, &[[6.0, 0.0], [7.0, 0.0]]),
            ],
            eps,
        );
        assert_eq!(out.len(), 4);
        assert_eq!(out[0], pl(false, &[[0.0, 0.0], [1.0, 0.0]]));
        assert_eq!(out[1], pl(false, &[[2.0, 0.0], [2.05, 0.0]]));
        assert_eq!(out[2], pl(true, &[[4.0, 0.0], [5.0, 0.0], [5.0, 1.0]]));
        assert_eq!(out[3], pl(false, &[[6.0, 0.0], [7.0, 0.0]]));
        for p in &out {
            let n = p.points.len();
            let segs = if p.closed { n } else { n - 1 };
            assert!((0..segs).all(|i| dist(p.points[i], p.points[(i + 1) % n]) > eps));
        }
    }

    fn open(points: &[[f64; 2]]) -> Polyline {
        Polyline {
            closed: false,
            points: points.to_vec(),
        }
    }

    /// A stroke that runs on past its data loses exactly the stretch farther than the
    /// reach: the length removed is that stretch's, to rounding.
    #[test]
    fn a_stretch_off_the_data_is_cut() {
        let data: Vec<Point> = (0..=10).map(|i| [i as f64 * 0.1, 0.0]).collect();
        let d = |p: Point| {
            data.iter()
                .map(|&q| dist(p, q))
                .fold(f64::INFINITY, f64::min)
        };
        // Along the data, then 1 up and away from them.
        let pl = open(&[[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [1.0, 0.05], [1.0, 1.0]]);
        let (out, removed) = supported(vec![pl], d, 0.1);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].points.len(), 4);
        assert!((removed - 0.95).abs() < 1e-12, "{removed}");
        // A closed loop off the data on one side opens there.
        let sq = Polyline {
            closed: true,
            points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        };
        let (out, removed) = supported(vec![sq], d, 0.1);
        assert_eq!(out.len(), 1);
        assert!(!out[0].closed);
        assert_eq!(out[0].points, vec![[0.0, 0.0], [1.0, 0.0]]);
        assert!((removed - 3.0).abs() < 1e-12);
    }

    /// A spoke whose two ends lie on data but whose middle crosses empty space is cut
    /// back to the stretches near its ends; every point kept lies within 1.25 times the
    /// reach (the samples along a segment are half a reach apart), and the length
    /// removed is the spoke's less what is kept.
    #[test]
    fn a_segment_across_empty_space_is_cut_between_supported_ends() {
        let data: Vec<Point> = (0..=4)
            .map(|i| [i as f64 * 0.05, 0.0])
            .chain((0..=4).map(|i| [2.0 - i as f64 * 0.05, 0.0]))
            .collect();
        let d = |p: Point| {
            data.iter()
                .map(|&q| dist(p, q))
                .fold(f64::INFINITY, f64::min)
        };
        let reach = 0.1;
        let (out, removed) = supported(vec![open(&[[0.0, 0.0], [2.0, 0.0]])], d, reach);
        assert_eq!(out.len(), 2);
        let kept: f64 = out.iter().map(Polyline::length).sum();
        assert!((kept + removed - 2.0).abs() < 1e-12);
        assert!(kept > 2.0 * 0.2 && kept <= 2.0 * 0.3 + 1e-12, "{kept}");
        for pl in &out {
            for w in pl.points.windows(2) {
                for k in 0..=100 {
                    let t = k as f64 / 100.0;
                    let p = [w[0][0] + t * (w[1][0] - w[0][0]), 0.0];
                    assert!(d(p) <= 1.25 * reach + 1e-12, "{p:?}");
                }
            }
        }
        // A closed loop whose chord closes it across the gap opens there.
        let ring = Polyline {
            closed: true,
            points: vec![[0.0, 0.0], [0.2, 0.0], [1.8, 0.0], [2.0, 0.0]],
        };
        let (out, _) = supported(vec![ring], d, reach);
        assert!(out.iter().all(|pl| !pl.closed));
        // Along the data, nothing is cut.
        let (out, removed) = supported(vec![open(&[[0.0, 0.0], [0.2, 0.0]])], d, reach);
        assert_eq!((out.len(), removed), (1, 0.0));
    }

    /// A cloud every point lies on (distance 0), of extent 2, `eps` 1e-9.
    fn on_data() -> Cloud<'static> {
        fn zero(_: Point) -> f64 {
            0.0
        }
        Cloud {
            distance: &zero,
            reach: 1.0,
            extent: 2.0,
            min_area: 0.0,
            eps: 1e-9,
        }
    }

    /// Two strokes crossing in an X are split where they cross: four pieces ending at
    /// the crossing point, nothing of either course lost, and through `enforce` a
    /// junction of the four. A loop crossed by a stroke opens there. Two pieces
    /// meeting at a shared end, or touching, are left alone.
    #[test]
    fn crossings_become_junctions_and_touching_pieces_are_kept() {
        let long = open(&[[-1.0, 0.0], [0.0, 0.0], [1.0, 0.0]]);
        let short = open(&[[0.5, -0.5], [0.5, 0.5], [0.5, 0.7]]);
        let (out, removed, at) = uncrossed(vec![long.clone(), short.clone()], 0.0);
        assert_eq!((removed, at), (1, vec![[0.5, 0.0]]));
        assert_eq!(out.len(), 4);
        let length: f64 = out.iter().map(Polyline::length).sum();
        assert!((length - (long.length() + short.length())).abs() < 1e-12);
        assert!(out
            .iter()
            .all(|pl| pl.points[0] == [0.5, 0.0] || pl.points[pl.points.len() - 1] == [0.5, 0.0]));
        assert!(crossing_pairs(&segments(&out)).is_empty());
        let cloud = on_data();
        let (out, junctions, _) = enforce(vec![long.clone(), short], Vec::new(), &cloud);
        assert_eq!(out.len(), 4);
        assert_eq!(junctions.len(), 1);
        assert_eq!(junctions[0].polylines.len(), 4);
        let ring = Polyline {
            closed: true,
            points: vec![[0.2, -0.5], [0.8, -0.5], [0.8, 0.5], [0.2, 0.5]],
        };
        let (out, removed, _) = uncrossed(vec![ring.clone(), long.clone()], 0.0);
        assert_eq!((removed, out.len()), (2, 5));
        assert!(out.iter().all(|pl| !pl.closed));
        let length: f64 = out.iter().map(Polyline::length).sum();
        assert!((length - (ring.length() + long.length())).abs() < 1e-12);
        let t = open(&[[0.0, 0.0], [0.0, 1.0]]);
        let touching = open(&[[0.3, 0.0], [0.3, -1.0]]);
        let (out, removed, _) = uncrossed(vec![long.clone(), t, touching], 0.0);
        assert_eq!((out.len(), removed), (3, 0));
    }

    /// A repeated point dropped where its twin lies on another curve moves a segment's
    /// end across that curve: the result still crosses nowhere.
    #[test]
    fn dropping_a_repeated_point_leaves_no_crossing() {
        let wall = open(&[[0.0, -1.0], [0.0, 1.0]]);
        // Its second point is within eps before the third, which lies on the wall.
        let bent = open(&[[-1.0, 1.0], [-1e-13, 0.0], [0.0, 0.0], [1.0, -1.0]]);
        assert!(crossing_pairs(&segments(&[wall.clone(), bent.clone()])).is_empty());
        assert_eq!(
            crossing_pairs(&segments(&well_formed(
                vec![wall.clone(), bent.clone()],
                1e-9
            )))
            .len(),
            1
        );
        let cloud = on_data();
        let (out, _, warnings) = enforce(vec![wall, bent], Vec::new(), &cloud);
        assert!(crossing_pairs(&segments(&out)).is_empty(), "{out:?}");
        assert!(
            warnings
                .iter()
                .any(|w| matches!(w, Warning::Crossings { removed: 1 })),
            "{warnings:?}"
        );
    }

    /// A figure eight (a closed curve crossing itself) becomes its two loops, touching
    /// at the crossing; a small twist at a loop's corner is a speck and goes.
    #[test]
    fn a_self_crossing_loop_splits_into_loops() {
        let eight = Polyline {
            closed: true,
            points: vec![[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]],
        };
        let (out, removed, _) = uncrossed(vec![eight], 0.01);
        assert_eq!(removed, 1);
        assert_eq!(out.len(), 2);
        for pl in &out {
            assert!(pl.closed);
            assert_eq!(pl.points.len(), 3);
            assert!((pl.signed_area().abs() - 0.25).abs() < 1e-12);
        }
        assert_eq!(uncrossed(out, 0.01).1, 0);
        // A loop with a small twist at one corner loses the twist only.
        let twisted = Polyline {
            closed: true,
            points: vec![
                [0.0, 0.0],
                [1.0, 0.0],
                [1.1, 0.1],
                [1.1, -0.05],
                [1.0, 0.05],
                [1.0, 1.0],
                [0.0, 1.0],
            ],
        };
        let (out, removed, _) = uncrossed(vec![twisted], 0.01);
        assert_eq!(removed, 1);
        assert_eq!(out.len(), 1);
        assert!(out[0].closed);
        assert!((out[0].signed_area().abs() - 1.0).abs() < 0.01);
    }

    /// Twelve spokes from one junction are a star; a cross of four is not; a curve
    /// a tenth of the data's extent is short.
    #[test]
    fn stars_and_short_results_are_flagged() {
        let spokes: Vec<Polyline> = (0..12)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 12.0;
                open(&[[0.0, 0.0], [a.cos(), a.sin()]])
            })
            .collect();
        let at = |n: usize| Junction {
            at: [0.0, 0.0],
            polylines: (0..n).collect(),
        };
        let w = collapsed(&spokes, &[at(12)], 2.0);
        assert!(
            matches!(w, Some(Warning::Collapsed { ends: (12, 24), .. })),
            "{w:?}"
        );
        assert_eq!(collapsed(&spokes[..4], &[at(4)], 2.0), None);
        let w = collapsed(&[open(&[[0.0, 0.0], [0.1, 0.0]])], &[], 1.0);
        assert!(matches!(w, Some(Warning::Collapsed { .. })), "{w:?}");
    }

    /// On data that hold them, the invariants cut nothing, at any size: a noisy
    /// circle among a few scattered points comes out as one closed loop with no
    /// warning, the scattered points as its features.
    #[test]
    fn good_data_are_left_alone_at_any_size() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut unit: Vec<Point> = (0..600)
            .map(|_| {
                let a = rng.random::<f64>() * std::f64::consts::TAU;
                let r = 0.3 + 0.003 * (rng.random::<f64>() - 0.5);
                [0.5 + r * a.cos(), 0.5 + r * a.sin()]
            })
            .collect();
        unit.extend([[0.05, 0.05], [0.95, 0.1], [0.9, 0.93]]);
        for scale in [1e-6, 1e-3, 1.0, 1e3, 1e6] {
            let points: Vec<Point> = unit.iter().map(|p| [p[0] * scale, p[1] * scale]).collect();
            let r = crate::reconstruct(&points, &crate::Params::default()).unwrap();
            assert_eq!(r.polylines.len(), 1, "{scale}: {:?}", r.warnings);
            assert!(r.polylines[0].closed, "{scale}");
            assert!(r.warnings.is_empty(), "{scale}: {:?}", r.warnings);
            assert_eq!(r.features.len(), 3, "{scale}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(12))]
        /// Random point sets (a noisy circle or two among scattered points, or points
        /// anywhere), at sizes from 1e-6 to 1e6, through the whole reconstruction: the curves cross nowhere, have no
        /// zero-length segment, every vertex lies within the support distance
        /// `3 sigma + 2 hmin + reach / 2` of a sample that is not isolated, and every
        /// point of a segment within 1.25 times that.
        #[test]
        fn every_result_holds_the_invariants(
            circles in proptest::collection::vec(([0.2f64..0.8, 0.2f64..0.8], 0.05f64..0.3), 0..3),
            per_circle in 50usize..300,
            noise in 0.0f64..0.01,
            scattered in proptest::collection::vec([0.0f64..1.0, 0.0f64..1.0], 0..40),
            seed in 0u64..1000,
            exponent in -6i32..7,
        ) {
            let scale = 10f64.powi(exponent);
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut points: Vec<Point> = scattered.clone();
            for &(c, r) in &circles {
                for _ in 0..per_circle {
                    let a = rng.random::<f64>() * std::f64::consts::TAU;
                    let e = noise * (rng.random::<f64>() - 0.5);
                    points.push([c[0] + (r + e) * a.cos(), c[1] + (r + e) * a.sin()]);
                }
            }
            proptest::prop_assume!(points.len() >= 20);
            // At any size: lengths in the data's units and the local ones must not mix.
            points.iter_mut().for_each(|p| *p = [p[0] * scale, p[1] * scale]);
            let Ok(r) = crate::reconstruct(&points, &crate::Params::default()) else {
                return Ok(());
            };
            let n = crate::distance::Neighbourhood::of(&points).unwrap();
            let inliers: Vec<Point> = points
                .iter()
                .zip(&n.isolated)
                .filter(|(_, &i)| !i)
                .map(|(&p, _)| p)
                .collect();
            let d = |p: Point| inliers.iter().map(|&q| dist(p, q)).fold(f64::INFINITY, f64::min);
            let reach = 3.0 * r.noise_estimate + 2.0 * r.stats.hmin + 0.5 * n.reach;
            for pl in &r.polylines {
                for &p in &pl.points {
                    proptest::prop_assert!(d(p) <= reach * (1.0 + 1e-9), "{} > {reach}", d(p));
                }
                let m = pl.points.len();
                let segs = if pl.closed { m } else { m - 1 };
                // Along the segments, within the step the check samples them at.
                for i in 0..segs {
                    let (a, b) = (pl.points[i], pl.points[(i + 1) % m]);
                    for k in 1..8 {
                        let t = k as f64 / 8.0;
                        let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                        proptest::prop_assert!(d(p) <= 1.25 * reach * (1.0 + 1e-9), "{} > 1.25 {reach}", d(p));
                    }
                }
                for i in 0..segs {
                    proptest::prop_assert!(pl.points[i] != pl.points[(i + 1) % m]);
                }
            }
            let segs = segments(&r.polylines);
            for (x, a) in segs.iter().enumerate() {
                for b in &segs[x + 1..] {
                    proptest::prop_assert!(!cross(a.2, a.3, b.2, b.3), "{a:?} crosses {b:?}");
                }
            }
        }
    }
}
