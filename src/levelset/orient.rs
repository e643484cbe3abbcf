//! The oriented start: the samples' fitted normals turned to agree along each sheet of
//! samples, each closed sheet pointed away from what it encloses, and a vertex's side
//! read from the nearby samples' tangent lines (an implicit moving least-squares curve,
//! after Hoppe et al.'s signed distance to unorganized points). Unlike the tube's
//! crossing parity it does not depend on how far apart two walls are: the middle of a
//! corridor narrower than any tube lies in front of both walls.
//!
//! It is only given where it is safe: the normals consistent along the sheets, every
//! sheet closed (open strokes, whiskers and T's are not), and few sheets. Anything else
//! is left to the tube start.

use rayon::prelude::*;

use crate::distance::DistanceField;
use crate::geom::{cross, dot, sub, Point};

/// Samples the orientation works on, at most: an even subsample of denser data (its
/// normals come from fits at the noise's scale, so a subsample loses nothing).
const ORIENT_MAX: usize = 5_000;
/// Nearest samples a sample's sheet neighbours are looked for among.
const SHEET_NEIGHBOURS: usize = 16;
/// Nearest samples the smallest fit spans.
const FIT_NEIGHBOURS: usize = 10;
/// Normals closer than 30 degrees (up to their orientation) are turned to agree.
const PARALLEL: f64 = 0.866;
/// Closed sheets, at most, for the start to be tried: each is tested against the others
/// for nesting.
const MAX_SHEETS: usize = 32;
/// A sheet with fewer samples is a cluster of outliers, not a curve.
const MIN_SHEET: usize = 12;
/// The largest sum of a closed sheet's unit normals, as a fraction of their number.
const CLOSURE: f64 = 0.1;
/// Nearest oriented samples a vertex's offset is averaged over.
const OFFSET_NEIGHBOURS: usize = 16;

/// A signed function on `coords` (negative inside) whose zero isoline runs through the
/// middle of the noise band of the samples of `field` (`sigma` their noise, `h` the
/// width the offsets are averaged over), or `None` when the samples do not form few
/// closed, consistently orientable sheets (see [`orient`]). At a vertex it is the offset
/// from the nearby samples' tangent lines, averaged with Gaussian weights: a single
/// sample's line would carry its noise into the start.
pub fn oriented_offsets(
    field: &DistanceField,
    sigma: f64,
    h: f64,
    coords: &[Point],
) -> Option<Vec<f64>> {
    let sheets = orient(field, sigma)?;
    let (pts, normals): (Vec<Point>, Vec<Point>) = sheets.into_iter().unzip();
    // They come in a field's order, which a field built from them keeps: its indices
    // are theirs.
    let tree = DistanceField::new(&pts).ok()?;
    debug_assert_eq!(tree.points(), &pts[..]);
    let k = OFFSET_NEIGHBOURS.min(tree.points().len());
    let h2 = (h * h).max(f64::MIN_POSITIVE);
    Some(
        coords
            .par_iter()
            .map_init(Vec::new, |idx, &x| {
                tree.nearest_k(x, k, idx);
                let d0 = idx.first().map_or(0.0, |&j| dist2(x, pts[j as usize]));
                // The width grows with the distance: far from the data one sample's
                // normal (a corner's, say) must not decide alone.
                let inv_h2 = 1.0 / (h2 + d0);
                let (mut num, mut den) = (0.0, 0.0);
                for &j in idx.iter() {
                    let i = j as usize;
                    // Relative to the nearest, so that far vertices do not underflow.
                    let w = (-(dist2(x, pts[i]) - d0) * inv_h2).exp();
                    num += w * dot(sub(x, pts[i]), normals[i]);
                    den += w;
                }
                num / den.max(f64::MIN_POSITIVE)
            })
            .collect(),
    )
}

fn dist2(a: Point, b: Point) -> f64 {
    let d = sub(a, b);
    dot(d, d)
}

/// The samples of the closed sheets with their normals oriented outward (away from what
/// the sheets enclose), or `None` (see [`oriented_offsets`]).
///
/// Normals: fits over the nearest few samples, or over eight times the noise where that
/// is wider. Sheets: samples joined to their nearest that lie along both tangents,
/// and ends joined across gaps in the sampling (see [`sheet_edges`]); their normals
/// turned to agree along the surest edges first (see [`turn_along`]). Then each sheet
/// must close, and is turned outward (see [`outward`]).
pub fn orient(field: &DistanceField, sigma: f64) -> Option<Vec<(Point, Point)>> {
    let all = field.points();
    let stride = all.len().div_ceil(ORIENT_MAX).max(1);
    let sub_pts: Vec<Point> = all.iter().step_by(stride).copied().collect();
    if sub_pts.len() < MIN_SHEET {
        return None;
    }
    // The samples are the tree's own points, so that its searches index them.
    let tree = DistanceField::new(&sub_pts).ok()?;
    let pts = tree.points();
    let reach = median_reach(&tree, FIT_NEIGHBOURS);
    // Fitted to the subsample: on dense data a window of the full field holds thousands
    // of samples, and the subsample already spans it evenly. An undefined fit leaves
    // a zero normal: no edge runs along it, and its sample is a sheet of its own.
    let r = reach.max(8.0 * sigma);
    let fits = crate::mesh::metric::fits_within(&tree, pts, r);
    let mut normals: Vec<Point> = fits
        .iter()
        .map(|f| if f.defined { f.normal } else { [0.0, 0.0] })
        .collect();
    // A fit leaving more than twice the noise and a quarter of its radius (a bend as
    // tight as the window leaves a seventh) has two walls in its window: its sample lies
    // in the noise's tail between them, and its normal may run across both.
    let one_wall: Vec<bool> = fits
        .iter()
        .map(|f| f.residual <= (2.0 * sigma).max(0.25 * r))
        .collect();
    let edges = sheet_edges(&tree, &normals, sigma, reach);
    // Smaller sheets are clusters of outliers: they sign nothing.
    let sheets: Vec<Vec<usize>> = turn_along(pts, &mut normals, &one_wall, &edges, reach)?
        .into_iter()
        .filter(|s| s.len() >= MIN_SHEET)
        .collect();
    outward(pts, &mut normals, &sheets)?;
    // In the tree's order, which a field built from them keeps.
    let mut kept: Vec<usize> = sheets.into_iter().flatten().collect();
    kept.sort_unstable();
    Some(kept.into_iter().map(|i| (pts[i], normals[i])).collect())
}

/// The median distance from a sample of `tree` to its `k`-th nearest (itself first),
/// over at most 2,000 of them.
fn median_reach(tree: &DistanceField, k: usize) -> f64 {
    let pts = tree.points();
    let mut idx = Vec::new();
    let mut radii: Vec<f64> = pts
        .iter()
        .step_by(pts.len().div_ceil(2000).max(1))
        .map(|&p| {
            tree.nearest_k(p, k, &mut idx);
            idx.last()
                .map_or(0.0, |&j| dist2(p, pts[j as usize]).sqrt())
        })
        .collect();
    let mid = radii.len() / 2;
    *radii.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The edges (`i < j`) along the sheets of the points of `tree`: each sample to those of
/// its [`SHEET_NEIGHBOURS`] nearest that lie along both tangents (within 60 degrees) and
/// near both tangent lines (the noise plus half the length, for a bend); and, where a
/// gap in the sampling wider than that breaks a sheet, each end (a sample whose sheet
/// neighbours all lie one way) joined to the nearest end facing it within `2 reach`.
fn sheet_edges(tree: &DistanceField, normals: &[Point], sigma: f64, reach: f64) -> Vec<(u32, u32)> {
    let pts = tree.points();
    let n = pts.len();
    let k = SHEET_NEIGHBOURS.min(n);
    let along = |i: usize, j: usize| {
        let q = sub(pts[j], pts[i]);
        let len = dot(q, q).sqrt();
        // A bend leaves the tangent line by half the length times its turn; samples
        // whose normals barely turn (under 15 degrees) may lie off each other's line by
        // the noise plus a quarter of the length, not half: further off, they lie on
        // two walls across a corridor that the noise's tails narrow.
        let turn = cross(normals[i], normals[j]).abs();
        let tol = 3.0 * sigma + 0.5 * len * (2.0 * turn).clamp(0.5, 1.0);
        [i, j].iter().all(|&v| {
            dot(q, tangent(normals[v])).abs() >= 0.5 * len && dot(q, normals[v]).abs() <= tol
        })
    };
    let neighbours: Vec<Vec<u32>> = pts
        .par_iter()
        .enumerate()
        .map_init(Vec::new, |idx, (i, &p)| {
            tree.nearest_k(p, k + 1, idx);
            idx.retain(|&j| j as usize != i && along(i, j as usize));
            idx.clone()
        })
        .collect();
    // Symmetric: an edge either end sees.
    let mut seen: Vec<Vec<u32>> = neighbours.clone();
    for (i, js) in neighbours.iter().enumerate() {
        for &j in js {
            seen[j as usize].push(i as u32);
        }
    }
    // Off the sheet at an end: away from its neighbours (the fitted tangent may be off
    // at a corner).
    let off: Vec<Option<Point>> = (0..n)
        .map(|i| {
            let t = tangent(normals[i]);
            let (mut ahead, mut behind, mut c) = (false, false, [0.0, 0.0]);
            for &j in &seen[i] {
                let q = sub(pts[j as usize], pts[i]);
                ahead |= dot(q, t) > 0.0;
                behind |= dot(q, t) < 0.0;
                c = [c[0] + q[0], c[1] + q[1]];
            }
            let len = dot(c, c).sqrt();
            (!(ahead && behind) && len > 0.0).then(|| [-c[0] / len, -c[1] / len])
        })
        .collect();
    let mut edges: Vec<(u32, u32)> = neighbours
        .iter()
        .enumerate()
        .flat_map(|(i, js)| js.iter().map(move |&j| (i as u32, j)))
        .collect();
    let mut near = Vec::new();
    for (i, out_i) in off.iter().enumerate() {
        let Some(out_i) = *out_i else { continue };
        tree.within(pts[i], 2.0 * reach, &mut near);
        let facing = near
            .iter()
            .map(|&j| j as usize)
            .filter(|&j| j != i)
            .filter_map(|j| {
                let out_j = off[j]?;
                let q = sub(pts[j], pts[i]);
                let len = dot(q, q).sqrt();
                // Across a gap in a wall each end faces the other; across a gap at a
                // corner one of them may look past the other, but not away.
                let (fi, fj) = (dot(q, out_i), -dot(q, out_j));
                // Along the sheet, as its edges are (within 60 degrees of both tangents):
                // not across a corridor, where two walls' ends may face each other.
                let along_both = [i, j]
                    .iter()
                    .all(|&v| dot(q, tangent(normals[v])).abs() >= 0.5 * len);
                (along_both && fi.min(fj) >= -0.2 * len && fi + fj >= 0.9 * len).then_some((len, j))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, j)) = facing {
            edges.push((i as u32, j as u32));
        }
    }
    for e in &mut edges {
        *e = (e.0.min(e.1), e.0.max(e.1));
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// The normal turned a quarter clockwise: the direction the oriented curve runs.
fn tangent(n: Point) -> Point {
    [n[1], -n[0]]
}

/// Turns `normals` to agree along `edges`, the surest edges first (short, along both
/// tangents, normals alike) as a spanning forest with the parity of each sample's turn:
/// a doubtful edge (a join across a gap, a stray link across a corridor) only decides
/// what nothing surer reaches. The connected sheets, or `None` when more than 1% of the
/// edges still disagree.
fn turn_along(
    pts: &[Point],
    normals: &mut [Point],
    one_wall: &[bool],
    edges: &[(u32, u32)],
    reach: f64,
) -> Option<Vec<Vec<usize>>> {
    let n = pts.len();
    // The curve runs the same way at both ends of an edge along it: both tangents point
    // along the edge or both against it, which holds round a corner or a tight cap where
    // the fitted normals are far apart. Where the normals nearly agree, they are surer
    // than the tangents' projections on a short edge across the noise band.
    let runs = |normals: &[Point], i: usize, j: usize| {
        let c = dot(normals[i], normals[j]);
        if c.abs() >= PARALLEL {
            return c > 0.0;
        }
        let q = sub(pts[j], pts[i]);
        (dot(q, tangent(normals[i])) > 0.0) == (dot(q, tangent(normals[j])) > 0.0)
    };
    let doubt = |i: usize, j: usize| {
        let q = sub(pts[j], pts[i]);
        let len = dot(q, q).sqrt().max(f64::MIN_POSITIVE);
        let along = |v: usize| dot(q, tangent(normals[v])).abs() / len;
        len / reach + (1.0 - along(i).min(along(j))) + (1.0 - dot(normals[i], normals[j]).abs())
    };
    // An edge from a sample whose fit straddles two walls comes after every other: its
    // normal may run across both, and the first edge between two pieces decides how
    // they turn to each other.
    let straddles = |i: usize, j: usize| if one_wall[i] && one_wall[j] { 0.0 } else { 1e3 };
    let mut by_doubt: Vec<(f64, usize, usize)> = edges
        .iter()
        .map(|&(i, j)| {
            let (i, j) = (i as usize, j as usize);
            (doubt(i, j) + straddles(i, j), i, j)
        })
        .collect();
    by_doubt.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    // Union-find whose links carry the turn between a sample and its parent.
    let mut parent: Vec<(u32, bool)> = (0..n as u32).map(|i| (i, false)).collect();
    fn find(parent: &mut [(u32, bool)], v: usize) -> (usize, bool) {
        let (mut root, mut turn) = (v, false);
        while parent[root].0 as usize != root {
            turn ^= parent[root].1;
            root = parent[root].0 as usize;
        }
        let (mut v, mut t) = (v, turn);
        while parent[v].0 as usize != root {
            let (up, tv) = parent[v];
            parent[v] = (root as u32, t);
            t ^= tv;
            v = up as usize;
        }
        (root, turn)
    }
    for &(_, i, j) in &by_doubt {
        let (ri, ti) = find(&mut parent, i);
        let (rj, tj) = find(&mut parent, j);
        if ri != rj {
            parent[rj] = (ri as u32, ti ^ tj ^ !runs(normals, i, j));
        }
    }
    let mut sheet_of = vec![usize::MAX; n];
    let mut sheets: Vec<Vec<usize>> = Vec::new();
    for (v, normal) in normals.iter_mut().enumerate() {
        let (root, turn) = find(&mut parent, v);
        if turn {
            *normal = [-normal[0], -normal[1]];
        }
        if sheet_of[root] == usize::MAX {
            sheet_of[root] = sheets.len();
            sheets.push(Vec::new());
        }
        sheets[sheet_of[root]].push(v);
    }
    let opposed = edges
        .iter()
        .filter(|&&(i, j)| !runs(normals, i as usize, j as usize))
        .count();
    if opposed * 100 > edges.len() {
        tracing::debug!(
            opposed,
            edges = edges.len(),
            "orientation: normals disagree"
        );
        return None;
    }
    Some(sheets)
}

/// Turns each sheet of `sheets` outward, or `None` when one does not close or there are
/// none or more than [`MAX_SHEETS`]. Closed: the unit normals of a closed curve sum to
/// nothing (their integral along it vanishes), an open stroke's to its chord. Outward:
/// the flux of the position, `sum (p - c) . n`, is twice the enclosed area over the
/// spacing, positive for outward normals; a sheet inside an odd number of others bounds
/// a hole, and turns the other way.
fn outward(pts: &[Point], normals: &mut [Point], sheets: &[Vec<usize>]) -> Option<()> {
    if sheets.is_empty() || sheets.len() > MAX_SHEETS {
        tracing::debug!(sheets = sheets.len(), "orientation: no sheets, or too many");
        return None;
    }
    let sum = |s: &[usize], f: &dyn Fn(usize) -> Point| {
        s.iter().fold([0.0, 0.0], |a, &i| {
            let v = f(i);
            [a[0] + v[0], a[1] + v[1]]
        })
    };
    for s in sheets {
        let total = sum(s, &|i| normals[i]);
        if dot(total, total).sqrt() > CLOSURE * s.len() as f64 {
            tracing::debug!(
                samples = s.len(),
                open = dot(total, total).sqrt() / s.len() as f64,
                "orientation: a sheet does not close"
            );
            return None;
        }
        let c = sum(s, &|i| pts[i]);
        let c = [c[0] / s.len() as f64, c[1] / s.len() as f64];
        let flux: f64 = s.iter().map(|&i| dot(sub(pts[i], c), normals[i])).sum();
        if flux < 0.0 {
            for &i in s.iter() {
                normals[i] = [-normals[i][0], -normals[i][1]];
            }
        }
    }
    // Inside another sheet: behind its nearest sample's normal. At most 32 sheets of
    // at most 5,000 samples: a search through each is cheap.
    let holes: Vec<bool> = sheets
        .iter()
        .enumerate()
        .map(|(a, s)| {
            let q = pts[s[0]];
            let around = sheets
                .iter()
                .enumerate()
                .filter(|&(b, other)| {
                    let nearest = other
                        .iter()
                        .copied()
                        .min_by(|&i, &j| dist2(q, pts[i]).total_cmp(&dist2(q, pts[j])));
                    b != a && nearest.is_some_and(|i| dot(sub(q, pts[i]), normals[i]) < 0.0)
                })
                .count();
            around % 2 == 1
        })
        .collect();
    for (s, hole) in sheets.iter().zip(holes) {
        if hole {
            for &i in s.iter() {
                normals[i] = [-normals[i][0], -normals[i][1]];
            }
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Shape, SynthParams};
    use std::f64::consts::TAU;

    fn field(shape: Shape, points: usize, noise: f64, gap: f64) -> DistanceField {
        let frames = generate(&SynthParams {
            points,
            noise,
            gap,
            seed: 7,
            ..SynthParams::new(shape)
        })
        .unwrap();
        DistanceField::new(&frames[0].points).unwrap()
    }

    /// The annulus (circles of radii 0.4 and 0.2 about (0.5, 0.5)) at sigma = 0.002:
    /// every normal points away from the material, out of the outer circle and into the
    /// hole. A fit over 8 sigma of a circle of radius 0.2 is off the radius by a few
    /// degrees, far from the 90 degrees a sign error needs.
    #[test]
    fn closed_sheets_turn_outward_and_holes_inward() {
        let sigma = 0.002;
        let oriented = orient(&field(Shape::Annulus, 2000, sigma, 0.05), sigma).unwrap();
        assert!(oriented.len() > 1900, "{}", oriented.len());
        for (p, n) in oriented {
            let r = sub(p, [0.5, 0.5]);
            let out = dot(r, r).sqrt() > 0.3;
            assert_eq!(dot(r, n) > 0.0, out, "{p:?} {n:?}");
        }
    }

    /// The square (sharp corners: the fitted normals there are halfway between the
    /// sides') at sigma = 0.002: every normal points out of it.
    #[test]
    fn corners_do_not_turn_a_side_around() {
        let sigma = 0.002;
        let oriented = orient(&field(Shape::Square, 2000, sigma, 0.05), sigma).unwrap();
        for (p, n) in oriented {
            assert!(dot(sub(p, [0.5, 0.5]), n) > 0.0, "{p:?} {n:?}");
        }
    }

    /// The spiral band with walls 0.08 apart, 8 sample spacings, at sigma = 0.005 sqrt 2
    /// (0.5% of the unit box's diagonal): the middle of the band is inside and the
    /// middle of the corridor between its turns outside, all along both.
    #[test]
    fn a_corridor_narrower_than_the_tube_lies_outside() {
        let (gap, sigma) = (0.08, 0.005 * 2f64.sqrt());
        let f = field(Shape::Spiral, 498, sigma, gap);
        // The band's centre line r = 0.1 + (2 gap / 2 pi) t; the corridor's is gap
        // farther out, up to the band's last turn.
        let (pitch, r1) = (2.0 * gap, 0.4 - 0.5 * gap);
        let turns = (r1 - 0.1) / pitch * TAU;
        let at = |t: f64, off: f64| {
            let r = 0.1 + pitch / TAU * t + off;
            [0.5 + r * t.cos(), 0.5 + r * t.sin()]
        };
        let band: Vec<Point> = (0..40)
            .map(|i| at(turns * (0.1 + 0.85 * i as f64 / 40.0), 0.0))
            .collect();
        let corridor: Vec<Point> = (0..40)
            .map(|i| at((turns - TAU) * (0.1 + 0.85 * i as f64 / 40.0), gap))
            .collect();
        let u = oriented_offsets(
            &f,
            sigma,
            4.0 * sigma,
            &[band.clone(), corridor.clone()].concat(),
        )
        .unwrap();
        let (inside, outside) = u.split_at(band.len());
        assert!(inside.iter().all(|&v| v < 0.0), "{inside:?}");
        assert!(outside.iter().all(|&v| v > 0.0), "{outside:?}");
    }

    /// Open strokes have no inside: no orientation is given.
    #[test]
    fn open_strokes_are_not_oriented() {
        for sigma in [0.0, 0.002] {
            assert!(orient(&field(Shape::Strokes, 2000, sigma, 0.05), sigma).is_none());
        }
        let arc: Vec<Point> = (0..400)
            .map(|i| {
                let a = 0.75 * TAU * i as f64 / 400.0;
                [0.3 * a.cos(), 0.3 * a.sin()]
            })
            .collect();
        assert!(orient(&DistanceField::new(&arc).unwrap(), 0.0).is_none());
    }
}
