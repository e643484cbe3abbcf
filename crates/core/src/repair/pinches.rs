//! One closed curve across a pinch. Where both walls of a band (or of a corridor between
//! two bands) have a sampling gap at about the same place, no data hold the level set
//! across the neck, and the tube it starts from may close there: it comes out as two
//! loops, each of which crosses the neck where the samples stop, instead of one loop
//! that runs on along both walls. Each loop's stretch across the neck leaves one wall
//! and reaches the other, and each wall's gap lies between a supported end of one loop
//! and a supported end of the other, both running along that wall the same way. The two
//! loops are joined into one across the walls' gaps, and the stretches across the neck
//! go; [`crate::repair::gaps::span_gaps`] then draws the joins as the samples' arcs.
//!
//! Two loops that the data show apart do not join: their ends across a gap would have
//! to run along one line the same way, which two curves that turn away from each other
//! (two discs, a hole in a band) do not.

use crate::distance::DistanceField;
use crate::geom::{dist, dot, norm, scale, sub, Point, Polyline};

use super::gaps::{Fit, Gap, Loop};
use super::Tolerances;
use crate::geom::crossing;

/// Nearest samples the chord behind a join's end is looked for among.
const CHORD_CANDIDATES: usize = 8;
/// Joins per frame, at most: each pass pairs every two stretches, so that the cost stays
/// bounded whatever the number of loops.
const MAX_JOINS: usize = 16;
/// Stretches paired, at most (16 million pairs, most of them dismissed by their length
/// alone): a level set that leaves the samples in more places than this is not pinched
/// at a few necks.
const MAX_STRETCHES: usize = 4096;

/// Joins the closed loops of `curves` across pinches (see the module's text), one pair
/// at a time, at most 16: each join replaces the pair by one loop at the
/// lower index and removes the other. A stretch is a loop's run between two vertices
/// within `tol` of the samples of `field`, with every vertex between them farther
/// (walked `step` at a time), more than `4 step` long. Two stretches of two loops join
/// when both walls' gaps are shorter than twice the wider stretch's chord, the samples'
/// tangent at each of the four ends (`sigma` their noise) turns less than
/// `t.pinch_max_turn` from its join (or, where the samples are `clean`, the chord of the two samples
/// behind it, where the fit takes in another wall round a corner), and no join crosses
/// a curve or the other join. More than 4,096 stretches are
/// not paired at all. Returns the joins made, as (kept, removed) indices, in order.
pub fn join_pinches(
    curves: &mut Vec<Polyline>,
    field: &DistanceField,
    sigma: f64,
    clean: bool,
    tol: f64,
    step: f64,
    t: &Tolerances,
) -> Vec<(usize, usize)> {
    let mut joins = Vec::new();
    if !(tol.is_finite() && tol > 0.0 && step.is_finite() && step > 0.0 && sigma >= 0.0) {
        return joins;
    }
    let fit = Fit { field, sigma, t };
    while joins.len() < MAX_JOINS {
        let Some((k1, g1, k2, g2)) = best_pinch(curves, &fit, tol, step, clean) else {
            break;
        };
        let (p1, p2) = (&curves[k1].points, &curves[k2].points);
        let mut points = supported_run(p1, g1);
        points.extend(supported_run(p2, g2));
        curves[k1].points = points;
        curves.remove(k2);
        joins.push((k1, k2));
    }
    joins
}

/// The vertices of `points` (a closed loop) from the end of `gap` forward to its start,
/// both included: the loop without its stretch across the neck.
fn supported_run(points: &[Point], gap: Gap) -> Vec<Point> {
    let n = points.len();
    let len = (gap.a + n - gap.b) % n + 1;
    (0..len).map(|i| points[(gap.b + i) % n]).collect()
}

/// The pinch with the shortest joins: loop `k1`'s stretch `g1` and loop `k2`'s `g2`,
/// `k1 < k2`.
fn best_pinch(
    curves: &[Polyline],
    fit: &Fit<'_>,
    tol: f64,
    step: f64,
    clean: bool,
) -> Option<(usize, Gap, usize, Gap)> {
    let field = fit.field;
    let loops: Vec<(usize, Loop<'_>)> = curves
        .iter()
        .enumerate()
        .filter(|(_, pl)| pl.closed && pl.points.len() >= 8)
        .map(|(k, pl)| (k, Loop::new(&pl.points)))
        .collect();
    let stretches: Vec<(usize, &Loop<'_>, Gap)> = loops
        .iter()
        .flat_map(|(k, l)| {
            l.unsupported(field, tol, step)
                .into_iter()
                .map(move |g| (*k, l, g))
        })
        .collect();
    if stretches.len() > MAX_STRETCHES {
        tracing::debug!(
            stretches = stretches.len(),
            "pinches: too many stretches off the samples to pair"
        );
        return None;
    }
    let mut best: Option<(f64, usize, Gap, usize, Gap)> = None;
    for (i, &(k1, l1, g1)) in stretches.iter().enumerate() {
        for &(k2, l2, g2) in &stretches[i + 1..] {
            if k1 == k2 {
                continue;
            }
            let (p1, p2) = (&curves[k1].points, &curves[k2].points);
            let neck = dist(p1[g1.a], p1[g1.b]).max(dist(p2[g2.a], p2[g2.b]));
            // Loop 1 leaves its wall at `g1.a` and loop 2 comes back to it at `g2.b`; loop
            // 2 leaves the other wall at `g2.a` and loop 1 comes back at `g1.b`.
            let (from1, to1) = (p1[g1.a], p2[g2.b]);
            let (from2, to2) = (p2[g2.a], p1[g1.b]);
            if !(along_wall(fit, (l1, g1.a), (l2, g2.b), neck, clean)
                && along_wall(fit, (l2, g2.a), (l1, g1.b), neck, clean))
            {
                continue;
            }
            let total = dist(from1, to1) + dist(from2, to2);
            if best.is_some_and(|b| b.0 <= total)
                || crossing(from1, to1, from2, to2).is_some()
                || [(from1, to1), (from2, to2)]
                    .iter()
                    .any(|&(a, b)| crosses(curves, (k1, g1), (k2, g2), a, b))
            {
                continue;
            }
            best = Some((total, k1, g1, k2, g2));
        }
    }
    best.map(|(_, k1, g1, k2, g2)| (k1, g1, k2, g2))
}

/// Whether the join across a wall's gap from vertex `from` of `l_from`, where that loop
/// leaves the wall, to vertex `to` of `l_to`, where the other comes back to it, is
/// shorter than twice `neck` and runs along the wall: the samples' tangent at each end
/// (fitted to those behind it, as an arc across a gap takes it) turns less than
/// `pinch_max_turn` of the tolerances from the join, or, on `clean` samples, the chord of the two
/// samples behind it does ([`chord_behind`]): an end a spacing short of a corner has
/// the other wall's samples among the fit's five. Not the loops' runs: over a join's
/// length those are chords, which turn towards a disc beside the gap.
fn along_wall(
    fit: &Fit<'_>,
    (l_from, from): (&Loop<'_>, usize),
    (l_to, to): (&Loop<'_>, usize),
    neck: f64,
    clean: bool,
) -> bool {
    let (p, q) = (l_from.point(from), l_to.point(to));
    let len = dist(p, q);
    if !(len > 0.0 && len < 2.0 * neck) {
        return false;
    }
    let d = sub(q, p);
    let run_in = sub(p, l_from.point(l_from.reach(from, len, false)));
    let run_out = sub(l_to.point(l_to.reach(to, len, true)), q);
    let reach = fit.reach(len);
    let ends = [
        fit.tangent(p, reach, &[run_in, d], Some(d)),
        fit.tangent(q, reach, &[run_out, d], Some(scale(d, -1.0))),
    ];
    let cos = fit.t.pinch_max_turn.cos();
    let along = |t: Point| dot(d, t) >= cos * len * norm(t) && norm(t) > 0.0;
    // On clean samples, where the fit runs round a corner, the chord of the two
    // samples behind the end.
    let chords = [
        chord_behind(fit.field, p, d),
        chord_behind(fit.field, q, scale(d, -1.0)).map(|t| scale(t, -1.0)),
    ];
    ends.iter().zip(chords).all(|(e, chord)| {
        e.is_some_and(|e| along(e.tangent)) || (clean && chord.is_some_and(along))
    })
}

/// The direction from the second sample behind `p` to the first (the samples whose
/// offset from `p` runs against `d`, each the nearest to the one before): the most
/// local tangent there is, exact on a clean straight wall, where a fit over five
/// samples may take in another wall's round a corner a spacing or two beyond.
fn chord_behind(field: &DistanceField, p: Point, d: Point) -> Option<Point> {
    let pts = field.points();
    let mut ids = Vec::new();
    field.nearest_k(p, CHORD_CANDIDATES, &mut ids);
    let near: Vec<Point> = ids.iter().map(|&i| pts[i as usize]).collect();
    let a = near
        .iter()
        .copied()
        .filter(|&s| dot(sub(s, p), d) <= 0.0)
        .min_by(|&x, &y| dist(x, p).total_cmp(&dist(y, p)))?;
    let b = near
        .iter()
        .copied()
        .filter(|&s| dot(sub(s, a), d) < 0.0)
        .min_by(|&x, &y| dist(x, a).total_cmp(&dist(y, a)))?;
    Some(sub(a, b))
}

/// Whether the segment from `a` to `b` crosses a segment of `curves` other than those
/// of the two stretches (loop, stretch) that the joins replace and the joins' own ends.
fn crosses(curves: &[Polyline], s1: (usize, Gap), s2: (usize, Gap), a: Point, b: Point) -> bool {
    curves.iter().enumerate().any(|(k, pl)| {
        let n = pl.points.len();
        pl.segments().enumerate().any(|(i, (c, d))| {
            let replaced = [s1, s2]
                .iter()
                .any(|&(ks, g)| ks == k && (i + n - g.a) % n < (g.b + n - g.a) % n);
            let shares_end = [c, d].iter().any(|&e| e == a || e == b);
            !replaced && !shares_end && crossing(a, b, c, d).is_some()
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`join_pinches`] on clean samples, tolerance 0.004 and step 0.002, default
    /// tolerances.
    fn joined(curves: &mut Vec<Polyline>, field: &DistanceField) -> Vec<(usize, usize)> {
        join_pinches(
            curves,
            field,
            0.0,
            true,
            0.004,
            0.002,
            &Tolerances::default(),
        )
    }

    /// Points from `a` to `b` at most `step` apart, `a` included and `b` not.
    fn segment(a: Point, b: Point, step: f64) -> Vec<Point> {
        let n = (dist(a, b) / step).ceil() as usize;
        (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            })
            .collect()
    }

    /// The half circle of radius `r` round `c` from the angle `from`, turning by pi
    /// (anticlockwise), at most `step` apart, its last point left out.
    fn half_circle(c: Point, r: f64, from: f64, step: f64) -> Vec<Point> {
        let n = (std::f64::consts::PI * r / step).ceil() as usize;
        (0..n)
            .map(|i| {
                let a = from + std::f64::consts::PI * i as f64 / n as f64;
                [c[0] + r * a.cos(), c[1] + r * a.sin()]
            })
            .collect()
    }

    /// How far `p` lies from the stadium whose walls run along `y = ±w` for `|x| <= l`,
    /// capped by half circles.
    fn off_stadium(p: Point, l: f64, w: f64) -> f64 {
        let x = p[0].abs().min(l);
        (dist(p, [x.copysign(p[0]), 0.0]) - w).abs()
    }

    /// A band 0.1 wide and 1.1 long (a stadium), sampled every 0.01 along it but where
    /// `|x| < 0.03` on both walls, and the two loops a level set that pinched there
    /// leaves: each half of the band, closed by a stretch across the neck that bows
    /// towards the middle. Anticlockwise, as the isoline runs round an inside.
    fn pinched_band() -> (Vec<Point>, Vec<Polyline>) {
        let (l, w, step) = (0.5, 0.05, 0.002);
        let mut samples = segment([-l, -w], [l, -w], 0.01);
        samples.extend(half_circle([l, 0.0], w, -std::f64::consts::FRAC_PI_2, 0.01));
        samples.extend(segment([l, w], [-l, w], 0.01));
        samples.extend(half_circle([-l, 0.0], w, std::f64::consts::FRAC_PI_2, 0.01));
        samples.retain(|p| p[0].abs() >= 0.03 || p[1].abs() < w - 1e-9);
        let across = |x: f64, bow: f64| {
            let mut s = segment([x, -w], [bow, 0.0], step);
            s.extend(segment([bow, 0.0], [x, w], step));
            s
        };
        let mut left = segment([-l, -w], [-0.03, -w], step);
        left.extend(across(-0.03, -0.004));
        left.extend(segment([-0.03, w], [-l, w], step));
        left.extend(half_circle([-l, 0.0], w, std::f64::consts::FRAC_PI_2, step));
        let mut right = segment([0.03, -w], [l, -w], step);
        right.extend(half_circle([l, 0.0], w, -std::f64::consts::FRAC_PI_2, step));
        right.extend(segment([l, w], [0.03, w], step));
        // Down across the neck: the stretch's reverse.
        let mut down = across(0.03, 0.004);
        down.push([0.03, w]);
        down.reverse();
        down.pop();
        right.extend(down);
        let closed = |points| Polyline {
            closed: true,
            points,
        };
        (samples, vec![closed(left), closed(right)])
    }

    /// The pinched band comes back as one loop along both walls: its joins run along the
    /// walls' gaps, on the band to rounding, and the stretches across the neck are gone.
    #[test]
    fn a_band_pinched_where_both_walls_have_a_gap_is_one_loop() {
        let (samples, mut curves) = pinched_band();
        let field = DistanceField::new(&samples).unwrap();
        let joins = joined(&mut curves, &field);
        assert_eq!(joins, vec![(0, 1)]);
        assert_eq!(curves.len(), 1);
        let off = curves[0]
            .points
            .iter()
            .map(|&p| off_stadium(p, 0.5, 0.05))
            .fold(0.0, f64::max);
        // The joins' ends are the last vertices within the tolerance of the samples.
        assert!(off < 0.004, "{off}");
        // The whole band, but for the tolerance at each of the joins' four ends.
        let length = 2.0 * 1.0 + 2.0 * std::f64::consts::PI * 0.05;
        let miss = (curves[0].length() - length).abs();
        assert!(miss < 4.0 * 0.004, "{miss}");
        assert!(curves[0].signed_area() > 0.0);
    }

    /// Two discs side by side, each sampled but for the arc facing the other, each loop
    /// cutting its arc by a chord: their gaps face each other, but the discs turn away
    /// from each other there, so no join runs along both, and they stay two loops.
    #[test]
    fn two_discs_with_facing_gaps_stay_apart() {
        let disc = |cx: f64, facing: f64, step: f64| -> Vec<Point> {
            let n = (std::f64::consts::TAU * 0.1 / step).ceil() as usize;
            (0..n)
                .map(|i| std::f64::consts::TAU * i as f64 / n as f64)
                .filter(|&a| {
                    let off = (a - facing).rem_euclid(std::f64::consts::TAU);
                    off > 0.5 && off < std::f64::consts::TAU - 0.5
                })
                .map(|a| [cx + 0.1 * a.cos(), 0.1 * a.sin()])
                .collect()
        };
        let mut samples = disc(-0.13, 0.0, 0.01);
        samples.extend(disc(0.13, std::f64::consts::PI, 0.01));
        let field = DistanceField::new(&samples).unwrap();
        let mut curves: Vec<Polyline> = [(-0.13, 0.0), (0.13, std::f64::consts::PI)]
            .iter()
            .map(|&(cx, facing)| Polyline {
                closed: true,
                points: disc(cx, facing, 0.002),
            })
            .collect();
        let before = curves.clone();
        assert!(joined(&mut curves, &field).is_empty());
        assert_eq!(curves, before);
    }

    /// The clean bays (inlets 0.08 wide, 442 samples, seed 14), where the level set
    /// pinched across an inlet whose lower wall has a gap from 0.754 to 0.799 and meets
    /// the disc's circle at 0.825: the join along that wall leaves the disc's loop at
    /// (0.814, 0.274), 0.013 short of the corner. The fit over the five samples behind
    /// that end takes in the circle's and turns 85 degrees from the join; the two
    /// samples behind it run along the join.
    #[test]
    fn the_chord_behind_an_end_a_spacing_short_of_a_corner_runs_along_its_wall() {
        use isoline_sim::{generate, Shape, SynthParams};
        let frames = generate(
            &SynthParams::new(Shape::Bays)
                .with_points(442)
                .with_gap(0.08)
                .with_seed(14),
        )
        .unwrap();
        let field = DistanceField::new(&frames[0].points).unwrap();
        let (p, q) = ([0.814, 0.274], [0.740, 0.3181]);
        let d = sub(q, p);
        let len = norm(d);
        let t = Tolerances::default();
        let fit = Fit {
            field: &field,
            sigma: 0.0,
            t: &t,
        };
        let e = fit.tangent(p, fit.reach(len), &[d], Some(d));
        let cos = t.pinch_max_turn.cos();
        assert!(e.is_none_or(|e| dot(e.tangent, d) < cos * len), "{e:?}");
        let chord = chord_behind(&field, p, d).unwrap();
        assert!(dot(chord, d) >= 0.999 * norm(chord) * len, "{chord:?}");
    }
}
