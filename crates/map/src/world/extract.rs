//! The map's curves: the fused field's zero crossing traced cell by cell (marching
//! squares), where enough scans support it and beams did not see through it, joined
//! across cells and tiles into polylines with the free side on their left.

use std::collections::HashMap;

use rayon::prelude::*;

use super::tile::Sample;
use super::{Key, Map};
use isoline_core::geom::{dist, point_segment_dist2, Point, Polyline};

/// A lattice edge: from sample `(i, j)` to `(i + 1, j)` (`horizontal`) or `(i, j + 1)`.
pub(crate) type Edge = (i64, i64, bool);

/// One cell's stretch of the curve, from the crossing on one edge to that on another,
/// the free side on its left.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Piece {
    pub from: Edge,
    pub to: Edge,
    pub a: Point,
    pub b: Point,
}

/// The pieces of the cells whose lower-left sample lies in tile `key`.
pub(crate) fn tile_pieces(map: &Map, key: Key) -> Vec<Piece> {
    let Some(tile) = map.tiles.get(&key) else {
        return Vec::new();
    };
    let (side, cell, min) = (map.params.tile, map.params.cell, map.params.min_scans);
    let s = side as i64;
    let mut out = Vec::new();
    for lj in 0..side {
        for li in 0..side {
            if tile.weight[lj * side + li] < min {
                continue;
            }
            let (i, j) = (key.0 * s + li as i64, key.1 * s + lj as i64);
            let corner = |di: usize, dj: usize| -> Option<Sample> {
                if li + di < side && lj + dj < side {
                    Some(tile.sample((lj + dj) * side + li + di))
                } else {
                    map.sample(i + di as i64, j + dj as i64)
                }
            };
            let c = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
            let Some(c) = c
                .iter()
                .map(|s| s.filter(|s| s.weight >= min))
                .collect::<Option<Vec<Sample>>>()
            else {
                continue;
            };
            cell_pieces(i, j, cell, &c, &mut out);
        }
    }
    out
}

/// The pieces of cell `(i, j)` with corners `c` (counter-clockwise from its lower
/// left): none, one, or two at a saddle (split as the cell's mean says).
fn cell_pieces(i: i64, j: i64, cell: f64, c: &[Sample], out: &mut Vec<Piece>) {
    let pos = |s: &Sample| s.sdf > 0.0;
    let corners = [[i, j], [i + 1, j], [i + 1, j + 1], [i, j + 1]];
    // Edge e runs from corner e to corner e + 1.
    let edges: [Edge; 4] = [
        (i, j, true),
        (i + 1, j, false),
        (i, j + 1, true),
        (i, j, false),
    ];
    let crossing = |e: usize| -> Option<Point> {
        let (p, q) = (&c[e], &c[(e + 1) % 4]);
        if pos(p) == pos(q) {
            return None;
        }
        let t = (p.sdf / (p.sdf - q.sdf)).clamp(0.0, 1.0);
        // Seen through more than hit at the crossing, lately (the clamped log-odds) or
        // by the recent scans' count at its nearer sample: not in the map.
        let near = if t < 0.5 { p } else { q };
        if p.occ + t * (q.occ - p.occ) < 0.0 || near.through > near.hits {
            return None;
        }
        let (a, b) = (corners[e], corners[(e + 1) % 4]);
        let t = f64::from(t);
        Some([
            (a[0] as f64 + t * (b[0] - a[0]) as f64) * cell,
            (a[1] as f64 + t * (b[1] - a[1]) as f64) * cell,
        ])
    };
    let crossed: Vec<usize> = (0..4)
        .filter(|&e| pos(&c[e]) != pos(&c[(e + 1) % 4]))
        .collect();
    // Pairs of edges, each with a corner on the positive (free) side of the stretch.
    let pairs: Vec<(usize, usize, usize)> = match crossed.len() {
        2 => {
            let free = (0..4).find(|&k| pos(&c[k])).unwrap_or(0);
            vec![(crossed[0], crossed[1], free)]
        }
        4 => {
            let mean = c.iter().map(|s| s.sdf).sum::<f32>() / 4.0;
            // The corners whose sign the middle shares are joined through it; the
            // stretches cut off the other two.
            let joined_even = (mean > 0.0) == pos(&c[0]);
            let cut: [usize; 2] = if joined_even { [1, 3] } else { [0, 2] };
            cut.iter()
                .map(|&k| {
                    // Corner k sits between edges k - 1 and k.
                    let (e0, e1) = ((k + 3) % 4, k);
                    let free = if pos(&c[k]) { k } else { (k + 1) % 4 };
                    (e0, e1, free)
                })
                .collect()
        }
        _ => Vec::new(),
    };
    for (e0, e1, free) in pairs {
        let (Some(p0), Some(p1)) = (crossing(e0), crossing(e1)) else {
            continue;
        };
        let f = [
            corners[free][0] as f64 * cell,
            corners[free][1] as f64 * cell,
        ];
        let left = (p1[0] - p0[0]) * (f[1] - p0[1]) - (p1[1] - p0[1]) * (f[0] - p0[0]) > 0.0;
        out.push(if left {
            Piece {
                from: edges[e0],
                to: edges[e1],
                a: p0,
                b: p1,
            }
        } else {
            Piece {
                from: edges[e1],
                to: edges[e0],
                a: p1,
                b: p0,
            }
        });
    }
}

/// The map's curves: resident tiles traced now, stored ones as they left.
pub(crate) fn curves(map: &Map) -> Vec<Polyline> {
    let keys: Vec<Key> = map.tiles.keys().copied().collect();
    let mut pieces: Vec<Piece> = keys
        .par_iter()
        .flat_map_iter(|&k| tile_pieces(map, k))
        .collect();
    for (_, p, _) in map.stored.values() {
        pieces.extend_from_slice(p);
    }
    let lines = join(&pieces);
    let (tol, min_len) = (0.25 * map.params.cell, 2.0 * map.params.hit_tolerance);
    lines
        .into_iter()
        .map(|l| simplify(l, tol))
        .filter(|l| l.length() >= min_len)
        .collect()
}

/// Chains pieces that share an edge crossing into polylines: open ones from the pieces
/// nothing ends in, then the loops left.
pub(crate) fn join(pieces: &[Piece]) -> Vec<Polyline> {
    let mut by_start: HashMap<Edge, usize> = HashMap::with_capacity(pieces.len());
    for (n, p) in pieces.iter().enumerate() {
        by_start.insert(p.from, n);
    }
    let ends: std::collections::HashSet<Edge> = pieces.iter().map(|p| p.to).collect();
    let mut used = vec![false; pieces.len()];
    let mut out = Vec::new();
    let mut starts: Vec<usize> = (0..pieces.len())
        .filter(|&n| !ends.contains(&pieces[n].from))
        .collect();
    // Deterministic output whatever the tiles' order.
    starts.sort_unstable_by_key(|&n| pieces[n].from);
    let mut rest: Vec<usize> = (0..pieces.len()).collect();
    rest.sort_unstable_by_key(|&n| pieces[n].from);
    for (n, open) in starts
        .into_iter()
        .map(|n| (n, true))
        .chain(rest.into_iter().map(|n| (n, false)))
    {
        if used[n] {
            continue;
        }
        let mut points = vec![pieces[n].a];
        let mut k = n;
        let mut closed = false;
        loop {
            used[k] = true;
            points.push(pieces[k].b);
            match by_start.get(&pieces[k].to) {
                Some(&m) if m == n => {
                    closed = true;
                    break;
                }
                Some(&m) if !used[m] => k = m,
                _ => break,
            }
        }
        if closed {
            points.pop();
        }
        debug_assert!(open || closed || points.len() >= 2);
        if points.len() >= 2 {
            out.push(Polyline { closed, points });
        }
    }
    out
}

/// Douglas-Peucker within `tol`: the traced crossings lie a cell apart, far denser
/// than a wall's shape needs.
fn simplify(line: Polyline, tol: f64) -> Polyline {
    let pts = &line.points;
    if pts.len() < 3 {
        return line;
    }
    let mut keep = vec![false; pts.len()];
    let (first, last) = (0, pts.len() - 1);
    keep[first] = true;
    keep[last] = true;
    let mut stack = vec![(first, last)];
    if line.closed {
        // A loop splits at its farthest point from the first.
        let far = (1..pts.len())
            .max_by(|&a, &b| dist(pts[a], pts[0]).total_cmp(&dist(pts[b], pts[0])))
            .unwrap_or(last);
        keep[far] = true;
        stack = vec![(first, far), (far, last)];
    }
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (p, q) = (pts[a], pts[b]);
        let (k, d) = (a + 1..b)
            .map(|k| (k, point_segment_dist2(pts[k], p, q).0))
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .expect("b > a + 1");
        if d > tol * tol {
            keep[k] = true;
            stack.push((a, k));
            stack.push((k, b));
        }
    }
    Polyline {
        closed: line.closed,
        points: pts
            .iter()
            .zip(&keep)
            .filter(|(_, k)| **k)
            .map(|(p, _)| *p)
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(sdf: f32) -> Sample {
        Sample {
            sdf,
            weight: 5,
            occ: 1.0,
            hits: 1,
            through: 0,
        }
    }

    #[test]
    fn a_wall_across_a_cell_keeps_its_free_side_on_the_left() {
        // Free below (y < 0.5 cell): the stretch runs from right to left.
        let c = [sample(0.5), sample(0.5), sample(-0.5), sample(-0.5)];
        let mut out = Vec::new();
        cell_pieces(0, 0, 1.0, &c, &mut out);
        assert_eq!(out.len(), 1);
        let p = out[0];
        assert!((p.a[1] - 0.5).abs() < 1e-6 && (p.b[1] - 0.5).abs() < 1e-6);
        assert!(p.a[0] > p.b[0], "{p:?}");
    }

    #[test]
    fn a_crossing_seen_through_is_left_out() {
        let mut c = [sample(0.5), sample(0.5), sample(-0.5), sample(-0.5)];
        for s in &mut c {
            s.occ = -1.0;
        }
        let mut out = Vec::new();
        cell_pieces(0, 0, 1.0, &c, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn pieces_chain_into_one_line_and_loops_close() {
        // A square loop of four cells' pieces round sample (1, 1), free outside.
        let mut pieces = Vec::new();
        let mut field = HashMap::new();
        for i in 0..3 {
            for j in 0..3 {
                field.insert((i, j), if (i, j) == (1, 1) { -1.0 } else { 1.0 });
            }
        }
        for i in 0..2 {
            for j in 0..2 {
                let c: Vec<Sample> = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                    .iter()
                    .map(|k| sample(field[k]))
                    .collect();
                cell_pieces(i, j, 1.0, &c, &mut pieces);
            }
        }
        let lines = join(&pieces);
        assert_eq!(lines.len(), 1);
        assert!(lines[0].closed);
        assert_eq!(lines[0].points.len(), 4);
        // Counter-clockwise would put the inside on the left; the free side is outside.
        let area: f64 = (0..4)
            .map(|k| {
                let (p, q) = (lines[0].points[k], lines[0].points[(k + 1) % 4]);
                p[0] * q[1] - q[0] * p[1]
            })
            .sum();
        assert!(area < 0.0, "clockwise: {area}");
    }

    #[test]
    fn simplification_keeps_corners_and_drops_collinear_points() {
        let pts: Vec<Point> = (0..=10)
            .map(|k| [k as f64, 0.0])
            .chain((1..=10).map(|k| [10.0, k as f64]))
            .collect();
        let s = simplify(
            Polyline {
                closed: false,
                points: pts,
            },
            0.01,
        );
        assert_eq!(s.points, vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]);
    }
}
