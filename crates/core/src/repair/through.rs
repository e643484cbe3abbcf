//! Loops through clean samples. On data without noise the level set passes the samples
//! by up to the capture's tolerance: it stops once every sample lies within about
//! `hmin` of it, and on a bend its curvature term and the median settle (whose
//! neighbourhoods span a stretch of the bend) leave it on the bend's inner side. Clean
//! samples lie on the curve, so each loop vertex among them is moved onto the circle
//! (or line) through its nearest samples: the curve they imply to third order, as a
//! moving-least-squares projection would place it.
//!
//! A vertex moves only where its samples say so without doubt: five of them, on both
//! sides of it along their own tangent, lie on one circle to within `fit_tol` (noisy
//! samples never do, nor those round a corner or across two walls), and the move is
//! shorter than `tol`. A
//! bulge of the loop farther than that from the samples' circle stays whole: the moves
//! next to it end where they are small, never in a step.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::distance::DistanceField;
use crate::geom::{add, dist, dot, norm, scale, sub, Point, Polyline, Sym2};

use super::Tolerances;

/// Moves every vertex of the closed polylines of `curves` onto the circle through the
/// samples of `field` nearest it along the samples' tangent (`t.through_each_side` on
/// either side, and one more), where they lie on that circle to within `fit_tol` and the move
/// is shorter than `tol`, but for moves that would leave a step of over `tol / 4`
/// next to a vertex that strays farther. Open polylines stay.
/// Returns the indices of the polylines changed.
pub fn through_samples(
    curves: &mut [Polyline],
    field: &DistanceField,
    tol: f64,
    fit_tol: f64,
    t: &Tolerances,
) -> Vec<usize> {
    let mut changed = Vec::new();
    if !(tol.is_finite() && tol > 0.0 && fit_tol.is_finite() && fit_tol > 0.0)
        || field.points().len() < 2 * t.through_each_side + 1
    {
        return changed;
    }
    for (k, pl) in curves.iter_mut().enumerate() {
        if !pl.closed || pl.points.len() < 3 {
            continue;
        }
        let pts = &pl.points;
        let mut to: Vec<To> = (0..pts.len())
            .into_par_iter()
            .map_init(Vec::new, |ids, i| {
                match onto_circle(pts[i], field, fit_tol, t, ids) {
                    Some(q) if dist(q, pts[i]) < tol => To::Onto(q),
                    Some(_) => To::Far,
                    None => To::Stay,
                }
            })
            .collect();
        no_steps(pts, &mut to, 0.25 * tol);
        let mut moved = false;
        for (p, q) in pl.points.iter_mut().zip(to) {
            if let To::Onto(q) = q {
                *p = q;
                moved = true;
            }
        }
        if moved {
            changed.push(k);
        }
    }
    changed
}

/// Where a loop vertex goes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum To {
    /// Onto the samples' circle, here.
    Onto(Point),
    /// Nowhere, though its samples lie on a circle: the loop strays farther from it
    /// than a move may go.
    Far,
    /// Nowhere: its samples give no circle.
    Stay,
}

/// Drops the moves `to` of the loop `pts` that would leave a step next to a vertex
/// that strays too far to move (a bulge into a sampling gap): the run of moves ends
/// only where its end moves by `step` at most, so the loop keeps the bulge whole
/// rather than jump from the circle back onto it. Next to a vertex whose samples give
/// no circle (a corner, a gap's edge) the loop is no farther than the capture leaves
/// it, and the moves stay.
fn no_steps(pts: &[Point], to: &mut [To], step: f64) {
    let n = pts.len();
    let steps = |to: &[To], i: usize| {
        matches!(to[i], To::Onto(q) if dist(q, pts[i]) > step)
            && (to[(i + 1) % n] == To::Far || to[(i + n - 1) % n] == To::Far)
    };
    let mut work: Vec<usize> = (0..n).filter(|&i| steps(to, i)).collect();
    while let Some(i) = work.pop() {
        if steps(to, i) {
            to[i] = To::Far;
            work.extend([(i + 1) % n, (i + n - 1) % n]);
        }
    }
}

/// The point nearest `p` of the circle through the samples nearest it, if they hold it
/// as [`through_samples`] asks.
fn onto_circle(
    p: Point,
    field: &DistanceField,
    fit_tol: f64,
    t: &Tolerances,
    ids: &mut Vec<u32>,
) -> Option<Point> {
    let (frame, each_side, max_slope) = (t.through_frame, t.through_each_side, t.through_max_slope);
    // The frame is the samples' own, from the few nearest: the loop's tangent is not
    // to be trusted where it kinks round a sample it passes by.
    field.nearest_k(p, t.through_nearest, ids);
    let near = &ids[..ids.len().min(frame)];
    if near.len() < frame {
        return None;
    }
    let inv = 1.0 / frame as f64;
    let centre = near.iter().fold([0.0, 0.0], |c, &i| {
        add(c, scale(field.points()[i as usize], inv))
    });
    let cov = near.iter().fold(Sym2::default(), |s, &i| {
        s.plus(Sym2::outer(sub(field.points()[i as usize], centre)))
    });
    let (l1, l2, t) = cov.eigen();
    if !(l1 > 0.0 && l2 < 0.25 * l1) {
        return None;
    }
    let nrm = [-t[1], t[0]];
    // The nearest on each side along that tangent.
    let (mut before, mut after) = (Vec::with_capacity(3), Vec::with_capacity(3));
    let frame = |i: u32| {
        let d = sub(field.points()[i as usize], p);
        (dot(d, t), dot(d, nrm))
    };
    let (x0, y0) = frame(ids[0]);
    for &i in ids.iter() {
        let (x, y) = frame(i);
        // Off the tangent through the nearest sample by more than 45 degrees: another
        // wall's (the next turn of a spiral, where this one's samples thin out).
        if (y - y0).abs() > (x - x0).abs() {
            continue;
        }
        let side = if x < 0.0 { &mut before } else { &mut after };
        if side.len() <= each_side {
            side.push((x, y));
        }
    }
    if before.len() < each_side || after.len() < each_side {
        return None;
    }
    // The two nearest on each side and a fifth: a sample far out on a sparse side would
    // stretch the circle over a stretch whose curvature changes. Four samples lie on
    // some circle too often by chance (two of each wall round a corner, a zigzag of
    // noise): a fifth leaves two degrees of freedom over. The nearer of the two next
    // first; the other where the nearer's wall is not this one (by a corner, the next
    // sample on one side may lie round it).
    let far = |v: &(f64, f64)| v.0.hypot(v.1);
    let core: Vec<(f64, f64)> = before[..each_side]
        .iter()
        .chain(&after[..each_side])
        .copied()
        .collect();
    let mut fifths: Vec<(f64, f64)> = before[each_side..]
        .iter()
        .chain(&after[each_side..])
        .copied()
        .collect();
    fifths.sort_by(|u, v| far(u).total_cmp(&far(v)));
    let mut local = Vec::with_capacity(core.len() + 1);
    fifths.into_iter().find_map(|fifth| {
        local.clear();
        local.extend_from_slice(&core);
        local.push(fifth);
        let (x, y) = onto_fit(&mut local, fit_tol, max_slope)?;
        Some(add(p, add(scale(t, x), scale(nrm, y))))
    })
}

/// The move from the frame's origin onto the circle (or line) through `local` (samples
/// in the frame), if they lie on it to within `fit_tol` with a slope of at most
/// `max_slope` in the frame (steeper, the frame is not the samples' and is not to be
/// trusted).
fn onto_fit(local: &mut [(f64, f64)], fit_tol: f64, max_slope: f64) -> Option<(f64, f64)> {
    let (a, b, c, off) = implicit_circle(local)?;
    if b.abs() > max_slope || off > fit_tol {
        return None;
    }
    // Along grad f at the origin (through the circle's centre), f(s g) = c s² +
    // s √(1+b²) + a: the nearer root, rationalized so that it holds as c goes to 0.
    let w = (1.0 + b * b).sqrt();
    let disc = 1.0 + b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let s = -2.0 * a / (w + disc.sqrt());
    Some((s * b / w, -s / w))
}

/// The circle (or line) `c (x² + y²) + b x - y + a = 0` nearest `local` (points in a
/// frame whose x axis runs roughly along them; scaled in place) by least squares, as
/// `(a, b, c)`, with the largest of their distances to it. Linear in `(a, b, c)`, and a
/// line is `c = 0`: a straight wall is as well conditioned as a bend. Fails only on a
/// circle whose centre lies on the x axis (a half turn), or fewer than three distinct
/// points.
pub(super) fn implicit_circle(local: &mut [(f64, f64)]) -> Option<(f64, f64, f64, f64)> {
    let rho = local.iter().map(|v| v.0.hypot(v.1)).fold(0.0, f64::max);
    if !(rho > 0.0 && rho.is_finite()) {
        return None;
    }
    // Scaled by the span for the normal equations' conditioning.
    for v in local.iter_mut() {
        *v = (v.0 / rho, v.1 / rho);
    }
    let mut ata = Matrix3::zeros();
    let mut aty = Vector3::zeros();
    for &(x, y) in local.iter() {
        let row = Vector3::new(1.0, x, x * x + y * y);
        ata += row * row.transpose();
        aty += row * y;
    }
    let sol = ata.lu().solve(&aty)?;
    let (a, b, c) = (sol[0], sol[1], sol[2]);
    if !(a.is_finite() && b.is_finite() && c.is_finite()) {
        return None;
    }
    // Each point's distance to the curve, to first order (|f| / |grad f|), which for
    // a circle is exact to second order in that distance.
    let off = local
        .iter()
        .map(|&(x, y)| {
            let f = c * (x * x + y * y) + b * x - y + a;
            let g = [2.0 * c * x + b, 2.0 * c * y - 1.0];
            f.abs() / norm(g)
        })
        .fold(0.0, f64::max);
    Some((a * rho, b, c / rho, off * rho))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(r: f64, n: usize, phase: f64) -> Vec<Point> {
        (0..n)
            .map(|i| std::f64::consts::TAU * (i as f64 + phase) / n as f64)
            .map(|a| [r * a.cos(), r * a.sin()])
            .collect()
    }

    fn off_circle(points: &[Point], r: f64) -> f64 {
        points
            .iter()
            .map(|&p| (norm(p) - r).abs())
            .fold(0.0, f64::max)
    }

    /// A tight bend (radius 5 spacings) passed 1.5e-3 inside, as the level set leaves
    /// it: a circle through 5 samples of a circle is the circle itself, so every vertex
    /// comes onto it to rounding (1e-12 asserted, at a radius of 0.05).
    #[test]
    fn a_loop_inside_a_clean_bend_comes_onto_it() {
        let r = 0.05;
        let samples = circle(r, 31, 0.0);
        let field = DistanceField::new(&samples).unwrap();
        let mut curves = vec![Polyline {
            closed: true,
            points: circle(r - 1.5e-3, 200, 0.3),
        }];
        assert_eq!(
            through_samples(&mut curves, &field, 2e-3, 1e-4, &Tolerances::default()),
            [0]
        );
        let off = off_circle(&curves[0].points, r);
        assert!(off < 1e-12, "{off:e}");
    }

    /// A unit square sampled every 0.05 and a loop 1e-3 inside it that rounds its
    /// corners (arcs of radius 0.01): along the sides every vertex comes onto them, and
    /// no vertex ends farther from the square than it was, round a corner either. With
    /// noise of 1e-3 across the sides no circle holds the samples to 1e-4: none moves.
    #[test]
    fn sides_come_onto_their_samples_and_a_corner_is_not_made_worse() {
        let mut samples = Vec::new();
        for i in 0..20 {
            let s = 0.05 * i as f64;
            samples.extend([[s, 0.0], [1.0, s], [1.0 - s, 1.0], [0.0, 1.0 - s]]);
        }
        let (e, r) = (1e-3, 0.01);
        let mut points: Vec<Point> = Vec::new();
        for (k, c) in [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]]
            .into_iter()
            .enumerate()
        {
            // The arc round corner c, turning from the side before it to the one after.
            let centre = [
                c[0] + if c[0] > 0.5 { -(e + r) } else { e + r },
                c[1] + if c[1] > 0.5 { -(e + r) } else { e + r },
            ];
            let a0 = std::f64::consts::FRAC_PI_2 * (k as f64 - 1.0);
            points.extend((0..=20).map(|j| {
                let a = a0 + std::f64::consts::FRAC_PI_2 * j as f64 / 20.0;
                add(centre, [r * a.cos(), r * a.sin()])
            }));
            // Then along the next side, a vertex every 0.01.
            let next = [[1.0, 1.0], [0.0, 1.0], [0.0, 0.0], [1.0, 0.0]][k];
            let (from, to) = (*points.last().unwrap(), next);
            let dir = [to[0] - c[0], to[1] - c[1]];
            points.extend((1..97).map(|j| add(from, scale(dir, 0.01 * j as f64))));
        }
        let off = |p: Point| p[0].min(p[1]).min(1.0 - p[0]).min(1.0 - p[1]).abs();
        let field = DistanceField::new(&samples).unwrap();
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        through_samples(&mut curves, &field, 2e-3, 1e-4, &Tolerances::default());
        // Along each side, every vertex farther than two spacings from the corners
        // (nearer, the other wall's samples come within 45 degrees of the side, or one
        // side of the vertex holds a single sample of its wall).
        let corner = |p: Point| {
            [0.0, 1.0].iter().any(|&x| (p[0] - x).abs() < 0.1)
                && [0.0, 1.0].iter().any(|&y| (p[1] - y).abs() < 0.1)
        };
        let mut along = 0;
        for (p, q) in curves[0].points.iter().zip(&points) {
            assert!(off(*p) <= off(*q) + 1e-12, "{p:?} from {q:?}");
            if (off(*q) - e).abs() < 1e-12 && !corner(*q) {
                assert!(off(*p) < 1e-12, "{p:?} from {q:?}");
                along += 1;
            }
        }
        assert!(along > 4 * 75, "{along}");
        let noisy: Vec<Point> = samples
            .iter()
            .enumerate()
            .map(|(i, &p)| {
                // Pushed a side at a time: each across its side, by turns either way.
                let e = if (i / 4) % 2 == 0 { 1e-3 } else { -1e-3 };
                add(p, if i % 2 == 0 { [0.0, e] } else { [e, 0.0] })
            })
            .collect();
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        let field = DistanceField::new(&noisy).unwrap();
        assert!(
            through_samples(&mut curves, &field, 2e-3, 1e-4, &Tolerances::default()).is_empty()
        );
        assert_eq!(curves[0].points, points);
    }

    /// A thin loop round a line of samples from 0 to 0.09 that runs on to 0.2: the
    /// vertices past the last sample (a sampling gap's edge) have samples on one side
    /// only and stay where they are; those among the samples come onto the line.
    #[test]
    fn a_vertex_past_the_samples_is_not_extrapolated() {
        let samples: Vec<Point> = (0..10).map(|i| [0.01 * i as f64, 0.0]).collect();
        let field = DistanceField::new(&samples).unwrap();
        let row = |y: f64| (0..=50).map(move |i| [-0.05 + 0.005 * i as f64, y]);
        let points: Vec<Point> = row(-1e-3).chain(row(1e-3).rev()).collect();
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        through_samples(&mut curves, &field, 2e-3, 1e-4, &Tolerances::default());
        for (p, q) in curves[0].points.iter().zip(&points) {
            if q[0] > 0.01 && q[0] < 0.08 {
                assert!(p[1].abs() < 1e-12, "{p:?} from {q:?}");
            }
            if q[0] > 0.09 || q[0] < 0.0 {
                assert_eq!(p, q);
            }
        }
    }

    /// A loop 4e-4 off a line of samples but for a bulge 8e-3 high between 0.4 and
    /// 0.6: the bulge strays farther than a move may go, so it stays whole, and no
    /// neighbours end a quarter of the largest move (5e-4) or more apart in how far
    /// they moved; along the rest the loop comes onto the line.
    #[test]
    fn a_bulge_stays_whole_without_a_step() {
        let samples: Vec<Point> = (0..=100).map(|i| [0.01 * i as f64, 0.0]).collect();
        let field = DistanceField::new(&samples).unwrap();
        let bulge = |x: f64| {
            if (0.4..=0.6).contains(&x) {
                4e-3 * (1.0 - (std::f64::consts::TAU * (x - 0.4) / 0.2).cos())
            } else {
                0.0
            }
        };
        let xs = |i: usize| 0.02 + 0.002 * i as f64;
        let mut points: Vec<Point> = (0..=480).map(|i| [xs(i), -4e-4]).collect();
        points.extend((0..=480).rev().map(|i| [xs(i), 4e-4 + bulge(xs(i))]));
        let mut curves = vec![Polyline {
            closed: true,
            points: points.clone(),
        }];
        through_samples(&mut curves, &field, 2e-3, 1e-4, &Tolerances::default());
        let moved: Vec<f64> = curves[0]
            .points
            .iter()
            .zip(&points)
            .map(|(p, q)| dist(*p, *q))
            .collect();
        let n = moved.len();
        for i in 0..n {
            let step = (moved[i] - moved[(i + 1) % n]).abs();
            assert!(step <= 5e-4 + 1e-12, "{i}: {step:e}");
        }
        for (p, q) in curves[0].points.iter().zip(&points) {
            if bulge(q[0]) > 1e-4 && q[1] > 0.0 {
                assert_eq!(p, q);
            } else if q[0] > 0.03 && q[0] < 0.97 {
                assert!(p[1].abs() < 1e-12, "{p:?} from {q:?}");
            }
        }
    }
}
