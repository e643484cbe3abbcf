//! The zero isoline of a P1 field (marching triangles), chained into polylines through
//! the triangle adjacency, and Douglas-Peucker simplification.
//!
//! Chains are walked with the negative side (inside) on the left, so closed loops around
//! a region come out counter-clockwise and loops around holes clockwise with no extra
//! pass; chains that reach the domain boundary are returned open. A vertex with `u = 0`
//! counts as outside, which keeps every cut triangle's crossing pattern unambiguous.

use crate::geom::{dist, point_segment_dist2, Point, Polyline};
use crate::mesh::{Mesh, INVALID};
use crate::redistance::edge_crossing;

/// For a cut triangle, the local indices of the edges (by opposite vertex) where the
/// chain enters and leaves, going with the inside on the left; `None` if not cut.
#[inline]
fn entry_exit(mesh: &Mesh, t: usize, u: &[f64]) -> Option<(usize, usize)> {
    let tri = mesh.tris[t];
    let neg = tri.map(|v| u[v as usize] < 0.0);
    let count = neg.iter().filter(|&&n| n).count();
    if count == 0 || count == 3 {
        return None;
    }
    // The vertex whose sign is alone; a lone inside vertex k is passed with the chain
    // going from edge (k, k+1) to edge (k, k+2), a lone outside one the other way.
    let lone_neg = count == 1;
    let k = (0..3)
        .find(|&i| neg[i] == lone_neg)
        .expect("one vertex is alone");
    let (a, b) = ((k + 2) % 3, (k + 1) % 3);
    Some(if lone_neg { (a, b) } else { (b, a) })
}

/// The crossing point on the edge of triangle `t` opposite local vertex `e`.
#[inline]
fn crossing(mesh: &Mesh, t: usize, e: usize, u: &[f64]) -> Point {
    let tri = mesh.tris[t];
    let (i, j) = (tri[(e + 1) % 3] as usize, tri[(e + 2) % 3] as usize);
    edge_crossing(mesh.coords[i], u[i], mesh.coords[j], u[j])
}

/// The zero isoline of `u` as oriented polylines, longest first. Consecutive points
/// closer than `merge` are merged (crossings at or next to a vertex repeat points).
pub fn zero_isoline(mesh: &Mesh, u: &[f64], merge: f64) -> Vec<Polyline> {
    let nt = mesh.num_triangles();
    let mut visited = vec![false; nt];
    let mut out = Vec::new();
    // Open chains first: they start in a cut triangle whose entry edge is on the
    // boundary.
    for start in 0..nt {
        if let Some((entry, _)) = entry_exit(mesh, start, u) {
            if mesh.adj[start][entry] == INVALID && !visited[start] {
                let mut pts = vec![crossing(mesh, start, entry, u)];
                walk(mesh, u, start, &mut visited, &mut pts);
                out.push(finish(pts, false, merge));
            }
        }
    }
    for start in 0..nt {
        if !visited[start] && entry_exit(mesh, start, u).is_some() {
            let mut pts = Vec::new();
            let closed = walk(mesh, u, start, &mut visited, &mut pts);
            out.push(finish(pts, closed, merge));
        }
    }
    out.retain(|p| p.points.len() >= 2);
    out.sort_by(|a, b| b.length().total_cmp(&a.length()));
    out
}

/// Follows the chain from `start`, pushing each triangle's exit point; returns whether
/// it came back to `start` (a closed loop) rather than leaving the domain.
fn walk(mesh: &Mesh, u: &[f64], start: usize, visited: &mut [bool], pts: &mut Vec<Point>) -> bool {
    let mut t = start;
    loop {
        visited[t] = true;
        let (_, exit) = entry_exit(mesh, t, u).expect("chain stays in cut triangles");
        pts.push(crossing(mesh, t, exit, u));
        let next = mesh.adj[t][exit];
        if next == INVALID {
            return false;
        }
        let next = next as usize;
        if next == start {
            return true;
        }
        if visited[next] {
            // Only possible with inconsistent adjacency; end the chain open.
            return false;
        }
        t = next;
    }
}

fn finish(pts: Vec<Point>, closed: bool, merge: f64) -> Polyline {
    let mut clean: Vec<Point> = Vec::with_capacity(pts.len());
    for p in pts {
        if clean.last().is_none_or(|&q| dist(p, q) > merge) {
            clean.push(p);
        }
    }
    if closed && clean.len() > 1 && dist(clean[0], *clean.last().unwrap()) <= merge {
        clean.pop();
    }
    Polyline {
        closed,
        points: clean,
    }
}

/// Douglas-Peucker: drops vertices while every dropped one stays within `tol` of the
/// simplified polyline. A closed polyline is split at its vertex farthest from its first
/// one, and keeps at least a triangle.
pub fn simplify(pl: &Polyline, tol: f64) -> Polyline {
    let n = pl.points.len();
    if tol <= 0.0 || n < 4 {
        return pl.clone();
    }
    let pts = &pl.points;
    let mut keep = vec![false; n];
    if pl.closed {
        let far = (1..n)
            .max_by(|&a, &b| dist(pts[0], pts[a]).total_cmp(&dist(pts[0], pts[b])))
            .unwrap_or(n / 2);
        keep[0] = true;
        keep[far] = true;
        mark(pts, 0, far, tol, &mut keep);
        // The second half wraps around to the first point.
        let wrapped: Vec<Point> = pts[far..].iter().copied().chain([pts[0]]).collect();
        let mut keep2 = vec![false; wrapped.len()];
        mark(&wrapped, 0, wrapped.len() - 1, tol, &mut keep2);
        for (k, &kk) in keep2.iter().enumerate().take(wrapped.len() - 1) {
            keep[far + k] |= kk;
        }
        if keep.iter().filter(|&&k| k).count() < 3 {
            let third = (far + n) / 2;
            keep[third.min(n - 1)] = true;
        }
    } else {
        keep[0] = true;
        keep[n - 1] = true;
        mark(pts, 0, n - 1, tol, &mut keep);
    }
    Polyline {
        closed: pl.closed,
        points: pts
            .iter()
            .zip(&keep)
            .filter(|(_, &k)| k)
            .map(|(&p, _)| p)
            .collect(),
    }
}

fn mark(pts: &[Point], first: usize, last: usize, tol: f64, keep: &mut [bool]) {
    // An explicit stack: recursion depth would follow the polyline's length.
    let mut stack = vec![(first, last)];
    let tol2 = tol * tol;
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (mut worst, mut at) = (0.0, a);
        for i in a + 1..b {
            let d2 = point_segment_dist2(pts[i], pts[a], pts[b]).0;
            if d2 > worst {
                worst = d2;
                at = i;
            }
        }
        if worst > tol2 {
            keep[at] = true;
            stack.push((a, at));
            stack.push((at, b));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{norm, BBox};

    fn grid() -> Mesh {
        Mesh::structured(
            &BBox {
                min: [-1.0, -1.0],
                max: [1.0, 1.0],
            },
            64,
        )
    }

    #[test]
    fn annulus_gives_a_ccw_outer_loop_and_a_cw_hole() {
        let mesh = grid();
        // Inside (negative) between radii 0.3 and 0.7.
        let u: Vec<f64> = mesh
            .coords
            .iter()
            .map(|&p| (norm(p) - 0.5).abs() - 0.2)
            .collect();
        let pls = zero_isoline(&mesh, &u, 1e-12);
        assert_eq!(pls.len(), 2, "{pls:?}");
        assert!(pls.iter().all(|p| p.closed));
        let (outer, hole) = (&pls[0], &pls[1]);
        assert!(outer.signed_area() > 0.0 && hole.signed_area() < 0.0);
        let area = std::f64::consts::PI;
        assert!((outer.signed_area() - area * 0.49).abs() < 0.01);
        assert!((hole.signed_area() + area * 0.09).abs() < 0.01);
        for p in outer.points.iter() {
            assert!((norm(*p) - 0.7).abs() < 2e-3);
        }
    }

    #[test]
    fn curves_cut_by_the_domain_are_open_and_nothing_is_lost() {
        let mesh = grid();
        // Two separate lines crossing the whole domain: inside is the strip |x| < 0.25.
        let u: Vec<f64> = mesh
            .coords
            .iter()
            .map(|&p| p[0].abs() - 0.25 + 0.01 * p[1])
            .collect();
        let pls = zero_isoline(&mesh, &u, 1e-12);
        assert_eq!(pls.len(), 2);
        for p in &pls {
            assert!(!p.closed);
            let (a, b) = (p.points[0], *p.points.last().unwrap());
            assert!((a[1].abs() - 1.0).abs() < 1e-12 && (b[1].abs() - 1.0).abs() < 1e-12);
            // Inside on the left: the right line (x > 0) goes up, the left one down.
            let up = b[1] > a[1];
            assert_eq!(up, a[0] > 0.0, "{p:?}");
        }
    }

    #[test]
    fn simplification_respects_its_tolerance() {
        let pts: Vec<Point> = (0..400)
            .map(|i| {
                let a = i as f64 / 400.0 * std::f64::consts::TAU;
                [a.cos(), a.sin()]
            })
            .collect();
        let pl = Polyline {
            closed: true,
            points: pts,
        };
        let s = simplify(&pl, 1e-3);
        // A chord of length c sags c^2 / 8 on the unit circle, so no polygon within 1e-3
        // has fewer than 2 pi / sqrt(8e-3) = 71 vertices; Douglas-Peucker is not optimal
        // but must still drop most of the 400.
        assert!((71..200).contains(&s.points.len()), "{}", s.points.len());
        let seg = crate::index::SegmentIndex::new(std::slice::from_ref(&s));
        for p in &pl.points {
            assert!(seg.distance(*p) <= 1e-3 + 1e-12);
        }
        assert!(s.signed_area() > 0.0);
    }
}
