//! Corners of scan curves, restored. A level set rounds a corner where two walls meet:
//! its curvature term and the mesh (at least `hmin` across) cut it by about the noise,
//! and every frame of a static scene cuts it alike, so averaging frames never brings it
//! back. Where a curve runs straight along two walls and turns between them within a
//! short stretch, the two walls' lines are fitted to the curve away from the turn and
//! the turn is replaced by their intersection: the corner the data imply, as a wall
//! extractor would place it.

use crate::geom::{dist, dot, sub, Point, Polyline};

/// How much a curve must turn at a corner, degrees: gentler bends are the walls' own.
const MIN_TURN_DEG: f64 = 25.0;

/// Restores the corners of `curves` (local coordinates) with `tol` the width of the
/// data's noise band: two sides at least `8 tol` long that stay within `tol / 3` of their
/// fitted lines, joined by a turn at most `4 tol` long, meeting within `tol` of it. Curves
/// elsewhere are left as they are.
pub fn sharpen(curves: &mut [Polyline], tol: f64) {
    if !(tol.is_finite() && tol > 0.0) {
        return;
    }
    for pl in curves
        .iter_mut()
        .filter(|p| !p.closed && p.points.len() >= 5)
    {
        let p = &pl.points;
        let keys = key_vertices(p, 0.5 * tol);
        let len = |i: usize| dist(p[keys[i]], p[keys[i + 1]]);
        let long: Vec<usize> = (0..keys.len() - 1)
            .filter(|&i| len(i) >= 8.0 * tol)
            .collect();
        let mut edits: Vec<(usize, usize, Point)> = Vec::new();
        for w in long.windows(2) {
            let (i, j) = (w[0], w[1]);
            let turn: f64 = (i + 1..j).map(len).sum();
            if turn > 4.0 * tol {
                continue;
            }
            let sides = ((keys[i], keys[i + 1]), (keys[j], keys[j + 1]));
            if let Some(e) = corner(p, sides, tol) {
                if edits.last().is_none_or(|&(_, end, _)| e.0 >= end) {
                    edits.push(e);
                }
            }
        }
        // From the last corner to the first, so that the indices before stay valid.
        for (first, end, x) in edits.into_iter().rev() {
            pl.points.splice(first..end, [x]);
        }
    }
}

/// The corner between the side `s1` (vertex indices, ending at the turn) and the side
/// `s2` (starting at it): the vertices `first..end` to replace by the intersection.
fn corner(
    p: &[Point],
    (s1, s2): ((usize, usize), (usize, usize)),
    tol: f64,
) -> Option<(usize, usize, Point)> {
    // Each side's line, fitted away from the turn (which the rounding bends).
    let away = 2.0 * tol;
    let (t1, t2) = (p[s1.1], p[s2.0]);
    let side1: Vec<Point> = p[s1.0..=s1.1]
        .iter()
        .copied()
        .filter(|&q| dist(q, t1) >= away)
        .collect();
    let side2: Vec<Point> = p[s2.0..=s2.1]
        .iter()
        .copied()
        .filter(|&q| dist(q, t2) >= away)
        .collect();
    let band = tol / 3.0;
    let l1 = fit_line(&side1, band)?;
    let l2 = fit_line(&side2, band)?;
    let turn = (dot(l1.1, l2.1)).clamp(-1.0, 1.0).acos();
    let turn = turn.min(std::f64::consts::PI - turn);
    if turn < MIN_TURN_DEG.to_radians() {
        return None;
    }
    let x = intersect(l1, l2)?;
    let near = p[s1.1..=s2.0]
        .iter()
        .map(|&q| dist(q, x))
        .fold(f64::INFINITY, f64::min);
    if near > tol {
        return None;
    }
    // The turn: every vertex nearer to the corner than the fitted stretches (those of
    // them on the lines are redundant with the corner and its neighbours).
    let first = (s1.0..=s1.1).rev().find(|&i| dist(p[i], t1) >= away)? + 1;
    let end = (s2.0..=s2.1).find(|&i| dist(p[i], t2) >= away)?;
    (first <= end).then_some((first, end, x))
}

/// The total-least-squares line through `pts` as (a point on it, its unit normal), if
/// there are enough points and every one lies within `band` of it.
pub(crate) fn fit_line(pts: &[Point], band: f64) -> Option<(Point, Point)> {
    if pts.len() < 4 {
        return None;
    }
    // The direction is the principal axis; the normal is perpendicular to it.
    let (c, spread) = crate::geom::principal(pts.iter().copied());
    let (_, _, t) = spread.eigen();
    let normal = [-t[1], t[0]];
    pts.iter()
        .all(|&q| dot(sub(q, c), normal).abs() <= band)
        .then_some((c, normal))
}

/// Where two lines (point, unit normal) meet; `None` when nearly parallel.
pub(crate) fn intersect(l1: (Point, Point), l2: (Point, Point)) -> Option<Point> {
    let ((p1, n1), (p2, n2)) = (l1, l2);
    let det = n1[0] * n2[1] - n1[1] * n2[0];
    if det.abs() < 1e-9 {
        return None;
    }
    let (c1, c2) = (dot(n1, p1), dot(n2, p2));
    Some([
        (c1 * n2[1] - c2 * n1[1]) / det,
        (n1[0] * c2 - n2[0] * c1) / det,
    ])
}

/// The vertices Douglas-Peucker keeps at tolerance `eps`, first and last included.
fn key_vertices(p: &[Point], eps: f64) -> Vec<usize> {
    let mut keep = vec![false; p.len()];
    keep[0] = true;
    keep[p.len() - 1] = true;
    let mut stack = vec![(0, p.len() - 1)];
    while let Some((i, j)) = stack.pop() {
        if j <= i + 1 {
            continue;
        }
        let (mut worst, mut at) = (0.0, i);
        for k in i + 1..j {
            let d = crate::geom::point_segment_dist2(p[k], p[i], p[j]).0;
            if d > worst {
                (worst, at) = (d, k);
            }
        }
        if worst > eps * eps {
            keep[at] = true;
            stack.push((i, at));
            stack.push((at, j));
        }
    }
    (0..p.len()).filter(|&i| keep[i]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two walls meeting at a right angle at the origin, the corner rounded with radius
    /// `r`, sampled every `h`.
    fn rounded(r: f64, h: f64) -> Polyline {
        let mut pts = Vec::new();
        let mut x = -1.0;
        while x < -r {
            pts.push([x, 0.0]);
            x += h;
        }
        for k in 0..=8 {
            let a = -std::f64::consts::FRAC_PI_2 + k as f64 / 8.0 * std::f64::consts::FRAC_PI_2;
            pts.push([-r + r * a.cos(), r + r * a.sin()]);
        }
        let mut y = r + h;
        while y <= 1.0 {
            pts.push([0.0, y]);
            y += h;
        }
        Polyline {
            closed: false,
            points: pts,
        }
    }

    #[test]
    fn a_rounded_corner_is_restored_and_a_straight_wall_left_alone() {
        let mut c = vec![rounded(0.03, 0.01)];
        let before = c[0]
            .points
            .iter()
            .map(|q| q[0].hypot(q[1]))
            .fold(1.0, f64::min);
        assert!(before > 0.008);
        sharpen(&mut c, 0.03);
        let nearest = c[0]
            .points
            .iter()
            .map(|q| q[0].hypot(q[1]))
            .fold(1.0, f64::min);
        assert!(nearest < 1e-9, "corner at {nearest}");
        // Every vertex still on one of the walls.
        assert!(c[0]
            .points
            .iter()
            .all(|q| q[0].abs() < 1e-9 || q[1].abs() < 1e-9));
        // A straight wall, and a gentle bend, stay as they are.
        let straight = Polyline {
            closed: false,
            points: (0..100).map(|i| [i as f64 * 0.01, 0.0]).collect(),
        };
        let arc = Polyline {
            closed: false,
            points: (0..100)
                .map(|i| {
                    let a = i as f64 * 0.01;
                    [a.sin(), 1.0 - a.cos()]
                })
                .collect(),
        };
        let mut v = vec![straight.clone(), arc.clone()];
        sharpen(&mut v, 0.03);
        assert_eq!(v, vec![straight, arc]);
    }

    #[test]
    fn a_round_object_is_not_given_corners() {
        // A pillar of radius 0.3 seen from one side: no straight sides.
        let mut c = vec![Polyline {
            closed: false,
            points: (0..60)
                .map(|i| {
                    let a = i as f64 / 59.0 * std::f64::consts::PI;
                    [0.3 * a.cos(), 0.3 * a.sin()]
                })
                .collect(),
        }];
        let before = c.clone();
        sharpen(&mut c, 0.01);
        assert_eq!(c, before);
    }
}
