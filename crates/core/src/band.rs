//! The adapt stage of a scan frame: a mesh that lives only where the curve can be, a
//! band along the scan's runs, built directly from their ordered returns instead of by
//! adapting a box.
//!
//! A scan's level set starts on the free space its rays swept, whose boundary runs
//! through the returns, and the median settle moves it at most `4 sigma + 4 hmin`; the
//! export keeps only the pieces along the runs. So the mesh needs only a band round
//! each run, fine across it and as fine along it as the returns are. Each return of a
//! run (smoothed along its run, as the support is) is a column of vertices, offset along
//! the run's normal by `0, ±h, ±3h, ±7h, ...` up to the band's half-width; two columns
//! continue an open run past each end, so that the curve reaches its last return.
//! Neighbouring columns are joined row by row into quads, two triangles each: a band of
//! one run touches no other, and nothing is meshed across free space. Where a run bends
//! so tightly that an offset would land nearer another stretch of a run than its own,
//! that vertex is left out, and a triangle that the bend would turn over is not made.
//! Across the band the level set is a signed distance, linear in the offset, which P1
//! elements represent exactly on any rows; along it the columns are the data's own
//! resolution. The cost grows with the number of returns, not with the scene's area.

use std::time::Instant;

use crate::distance::DistanceField;
use crate::field::{AdaptedMesh, MeshTimings, MetricField};
use crate::geom::{add, dist, norm, orient, scale, sub, BBox, Point, Polyline};
use crate::mesh::adapt::AdaptReport;
use crate::mesh::quality::MeshStats;
use crate::mesh::Mesh;

/// The band's rows by the curve, as multiples of `h`, before the outermost at the
/// half-width. Across the band the level set is linear in the offset, so more rows buy
/// nothing: on the real recordings, rows at `7h` and `15h` too changed the returns
/// explained by at most 0.3 points and cost 40% more time.
const ROWS: [f64; 3] = [0.0, 1.0, 3.0];

/// A vertex left out of the band.
const NONE: u32 = u32::MAX;

/// The band mesh of `runs` (open or closed polylines through a scan's returns, in the
/// field's local coordinates): rows `h` apart by the runs, out to `half_width` on either
/// side. `field` gives the nearest sample of each vertex.
pub fn band(runs: &[Polyline], field: &MetricField, h: f64, half_width: f64) -> AdaptedMesh {
    let t0 = Instant::now();
    let runs: Vec<&Polyline> = runs.iter().filter(|r| r.points.len() >= 2).collect();
    let columns: Vec<Vec<(Point, Point)>> = runs.iter().map(|r| columns(r, h)).collect();
    let centres: Vec<Point> = columns.iter().flatten().map(|c| c.0).collect();
    let near = crate::distance::DistanceField::new(&centres).ok();
    let mut offsets: Vec<f64> = ROWS
        .iter()
        .map(|&k| k * h)
        .take_while(|&o| o < half_width)
        .chain(std::iter::once(half_width))
        .flat_map(|o| if o == 0.0 { vec![0.0] } else { vec![-o, o] })
        .collect();
    offsets.sort_by(f64::total_cmp);
    let rows = offsets.len();
    let mut coords: Vec<Point> = Vec::with_capacity(centres.len() * rows);
    // Each vertex's nearest sample is its column's: the settle moves a vertex by the
    // median around the sample it lies across from.
    let mut nearest: Vec<u32> = Vec::with_capacity(centres.len() * rows);
    let mut tris: Vec<[u32; 3]> = Vec::with_capacity(2 * centres.len() * rows);
    let mut grid: Vec<u32> = Vec::new();
    let mut folded = vec![false; rows];
    for (cols, run) in columns.iter().zip(&runs) {
        // This run's vertices, column by column, row by row (`NONE` where left out).
        grid.clear();
        for &(p, n) in cols {
            let sample = field.field.nearest(p).index;
            if let Some(f) = &near {
                folds(f, p, n, &offsets, &mut folded);
            }
            for (&o, &folded) in offsets.iter().zip(&folded) {
                let q = add(p, scale(n, o));
                if folded {
                    grid.push(NONE);
                } else {
                    grid.push(coords.len() as u32);
                    coords.push(q);
                    nearest.push(sample);
                }
            }
        }
        let n = cols.len();
        let quads = if run.closed { n } else { n.saturating_sub(1) };
        let at = |c: usize, k: usize| grid[(c % n) * rows + k];
        for c in 0..quads {
            for k in 0..rows - 1 {
                let (v00, v10, v11, v01) = (at(c, k), at(c + 1, k), at(c + 1, k + 1), at(c, k + 1));
                for t in [[v00, v10, v11], [v00, v11, v01]] {
                    if t.contains(&NONE) {
                        continue;
                    }
                    let [a, b, c] = t.map(|v| coords[v as usize]);
                    // Inside a bend the outer rows of neighbouring columns cross.
                    if orient(a, b, c) > 0.0 {
                        tris.push(t);
                    }
                }
            }
        }
    }
    let (mesh, nearest) = compacted(&coords, &nearest, tris);
    let stats = MeshStats {
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        ..MeshStats::default()
    };
    let domain = BBox::of(&mesh.coords).unwrap_or(field.bbox);
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut params = field.params;
    params.hmin = h;
    params.band = half_width;
    AdaptedMesh {
        mesh,
        nearest,
        params,
        domain,
        warm: false,
        noise_estimate: field.noise_estimate,
        one_wall_noise: field.one_wall_noise,
        report: AdaptReport::default(),
        stats,
        ms: MeshTimings {
            adapt: ms,
            total: field.ms.total + ms,
            ..field.ms
        },
    }
}

/// Which rows of the column at `p` (normal `n`) fold, into `out`: a vertex at offset
/// `o` nearer another column's centre (`near`'s points) than `|o| / 2` lies nearer
/// another stretch of a run than its own (inside a tight bend). Each side's outermost
/// vertex is measured; an inner one only where that measure, less the distance between
/// them, does not already keep every centre far enough (the distance to the centres is
/// 1-Lipschitz), which on a straight stretch it does.
fn folds(near: &DistanceField, p: Point, n: Point, offsets: &[f64], out: &mut [bool]) {
    let mut outer = [None::<(f64, f64)>; 2];
    // Offsets are sorted: the outermost of each side first (from the ends inwards).
    let order = (0..offsets.len())
        .filter(|&k| offsets[k] < 0.0)
        .chain((0..offsets.len()).rev().filter(|&k| offsets[k] > 0.0));
    for k in order {
        let o = offsets[k];
        let side = usize::from(o > 0.0);
        let bound = outer[side].map(|(oo, d)| d - (oo - o.abs()));
        out[k] = match bound {
            Some(b) if b >= 0.5 * o.abs() => false,
            _ => {
                let d = near.distance(add(p, scale(n, o)));
                if outer[side].is_none() {
                    outer[side] = Some((o.abs(), d));
                }
                d < 0.5 * o.abs()
            }
        };
    }
    for (k, &o) in offsets.iter().enumerate() {
        if o == 0.0 {
            out[k] = false;
        }
    }
}

/// The columns of a run, in order along it: each point with its unit normal (the left
/// perpendicular of its neighbours' chord on the run averaged by [`smoothed`]), and two
/// more past each end of an open run along its end segments, `max(h, the end segment)`
/// apart.
fn columns(run: &Polyline, h: f64) -> Vec<(Point, Point)> {
    let p = &run.points;
    let s = &smoothed(run);
    let n = p.len();
    let index = |i: isize| -> usize {
        if run.closed {
            i.rem_euclid(n as isize) as usize
        } else {
            i.clamp(0, n as isize - 1) as usize
        }
    };
    let at = |i: isize| p[index(i)];
    let smooth_at = |i: isize| s[index(i)];
    let normal = |d: Point| -> Point {
        let l = norm(d);
        if l > 0.0 {
            [-d[1] / l, d[0] / l]
        } else {
            [0.0, 0.0]
        }
    };
    // Past an end, along the end segment `from -> to` (outward), with the normal of the
    // run's direction `forward`.
    let beyond = |to: Point, from: Point, forward: Point| -> Vec<(Point, Point)> {
        let d = sub(to, from);
        let len = norm(d);
        if len == 0.0 {
            return Vec::new();
        }
        let step = len.max(h);
        (1..=2)
            .map(|k| (add(to, scale(d, k as f64 * step / len)), normal(forward)))
            .collect()
    };
    let mut out = Vec::with_capacity(n + 4);
    if !run.closed {
        let mut start = beyond(p[0], p[1], sub(p[1], p[0]));
        start.reverse();
        out.extend(start);
    }
    // Along the run the level set varies on the scale of the noise window, not from
    // return to return: where returns lie closer than `h` (a dense scanner near a
    // wall), a column every `h` of arc resolves the curve as well as one per return,
    // at a fraction of the vertices. A run's first and last returns keep theirs.
    let mut last: Option<Point> = None;
    for i in 0..n as isize {
        let q = at(i);
        let end = i == 0 || i == n as isize - 1;
        if end || last.is_none_or(|l| dist(l, q) >= h) {
            out.push((q, normal(sub(smooth_at(i + 1), smooth_at(i - 1)))));
            last = Some(q);
        }
    }
    if !run.closed {
        out.extend(beyond(p[n - 1], p[n - 2], sub(p[n - 1], p[n - 2])));
    }
    // A zero normal (repeated points) would stack every row on its column.
    out.retain(|&(_, nrm)| nrm != [0.0, 0.0]);
    out.dedup_by(|a, b| dist(a.0, b.0) == 0.0);
    out
}

/// Returns a side the band's centre line averages over.
const SMOOTH: usize = 4;

/// The run's points averaged over [`SMOOTH`] returns a side (fewer near an open run's
/// ends, which stay put), for the columns' normals: a chord between raw neighbours
/// turns with the noise (by up to 45° where the noise is half the spacing), and
/// neighbouring columns' outer rows then cross and the band tears. The columns
/// themselves stay on the returns, where the curve is (centred on the averaged run,
/// the band lost 2 points of returns explained on the real recordings: it rounds
/// corners by more than its rows reach).
fn smoothed(run: &Polyline) -> Vec<Point> {
    let p = &run.points;
    let n = p.len();
    (0..n)
        .map(|i| {
            let k = if run.closed {
                SMOOTH.min((n - 1) / 2)
            } else {
                SMOOTH.min(i).min(n - 1 - i)
            };
            let mut s = [0.0, 0.0];
            for j in 0..=2 * k {
                let q = p[(i + n + j - k) % n];
                s = add(s, q);
            }
            scale(s, 1.0 / (2 * k + 1) as f64)
        })
        .collect()
}

/// The mesh of the triangles `tris` over `coords`, without the vertices no triangle
/// uses, and the kept vertices' `nearest` samples.
fn compacted(coords: &[Point], nearest: &[u32], tris: Vec<[u32; 3]>) -> (Mesh, Vec<u32>) {
    let mut map = vec![NONE; coords.len()];
    let mut kept = Vec::new();
    let mut kept_nearest = Vec::new();
    let tris: Vec<[u32; 3]> = tris
        .into_iter()
        .map(|t| {
            t.map(|v| {
                if map[v as usize] == NONE {
                    map[v as usize] = kept.len() as u32;
                    kept.push(coords[v as usize]);
                    kept_nearest.push(nearest[v as usize]);
                }
                map[v as usize]
            })
        })
        .collect();
    (Mesh::from_triangles(kept, tris), kept_nearest)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fold test's shortcut decides exactly as measuring every row does: on a run
    /// that turns back on itself in a hairpin tighter than the band (where inner rows
    /// fold and outer ones may not), on a straight stretch beside it, and on random
    /// columns.
    #[test]
    fn folds_match_measuring_every_row() {
        let h = 0.01;
        let half_width = 0.16;
        let mut centres: Vec<Point> = (0..100).map(|i| [i as f64 * h, 0.0]).collect();
        // A hairpin: back along y = 0.05 after a half circle of radius 0.025.
        centres.extend((0..8).map(|k| {
            let a = -std::f64::consts::FRAC_PI_2 + k as f64 * std::f64::consts::PI / 8.0;
            [1.0 + 0.025 * a.cos(), 0.025 + 0.025 * a.sin()]
        }));
        centres.extend((0..100).map(|i| [1.0 - i as f64 * h, 0.05]));
        let near = DistanceField::new(&centres).unwrap();
        let mut offsets: Vec<f64> = ROWS
            .iter()
            .map(|&k| k * h)
            .chain(std::iter::once(half_width))
            .flat_map(|o| if o == 0.0 { vec![0.0] } else { vec![-o, o] })
            .collect();
        offsets.sort_by(f64::total_cmp);
        let mut rng = 12345u64;
        let mut next = || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut columns: Vec<(Point, Point)> = centres.iter().map(|&p| (p, [0.0, 1.0])).collect();
        columns.extend((0..200).map(|_| {
            let a = std::f64::consts::TAU * next();
            (
                [1.2 * next() - 0.1, 0.2 * next() - 0.05],
                [a.cos(), a.sin()],
            )
        }));
        let mut out = vec![false; offsets.len()];
        let mut folded = 0;
        for (p, n) in columns {
            folds(&near, p, n, &offsets, &mut out);
            for (k, &o) in offsets.iter().enumerate() {
                let measured = o != 0.0 && near.distance(add(p, scale(n, o))) < 0.5 * o.abs();
                assert_eq!(out[k], measured, "column at {p:?}, offset {o}");
                folded += usize::from(measured);
            }
        }
        assert!(folded > 0, "the hairpin folds some rows");
    }
}
