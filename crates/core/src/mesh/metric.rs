//! The size/shape field that adaptation follows (paper section 3.3):
//! `M = grad d grad d^T / hmin^2 + H(d) / eps`, made SPD by taking absolute eigenvalues and
//! clamped to `[1/hmax^2, 1/hmin^2]`, in a band around the data, graded outside it.
//!
//! `d` here is the distance to the curve the samples describe, not to the samples
//! themselves. Below the sample spacing the distance to a finite point set has gradient
//! and Hessian dominated by single samples (between two samples `grad d` is tangent to
//! the curve and `|H(d)| ~ 1/d`), which would force isotropic size `hmin` along the data
//! and lose all anisotropy. So each sample gets a local frame fitted to its `k` nearest
//! neighbours: the normal from principal axes, the curvature from a least-squares
//! parabola (the Taylor fit of paper eq. 10, on the data). At a point `x` in the band,
//! with nearest sample `p`, `grad d = n_p` and `H(d) = kappa_p t_p t_p^T`, so the metric
//! is `n n^T / hmin^2 + |kappa| t t^T / eps`: size `hmin` across the data and
//! `sqrt(eps / |kappa|)` along it (the paper's `l(x)`). Outside the band the normal size
//! grows linearly with `d - band` (slope `gradation`), the tangential one never falling
//! below it, up to `hmax`: a gradation in closed form since it depends on `d` only.

use std::borrow::Cow;

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::distance::{DistanceField, Nearest};
use crate::error::Result;
use crate::geom::{dist, dot, sub, Point, Sym2};

/// Anything that gives a metric at a point; adaptation asks it for every new vertex.
pub trait MetricSource: Sync {
    /// The SPD metric tensor at `p`.
    fn metric(&self, p: Point) -> Sym2;

    /// The metric at `p` and the index of the data point it was taken from, given the
    /// index returned for a point nearby (`hint`, or [`NO_HINT`]), which may make the
    /// search cheaper; the result is the same. Sources not based on data points return
    /// [`NO_HINT`].
    fn metric_near(&self, p: Point, hint: u32) -> (Sym2, u32) {
        let _ = hint;
        (self.metric(p), NO_HINT)
    }
}

/// "No data point": a [`MetricSource::metric_near`] hint to search from scratch.
pub const NO_HINT: u32 = u32::MAX;

/// Resolved, concrete parameters of the data-driven metric (all lengths in data units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetricParams {
    /// Smallest size: across the data in the band.
    pub hmin: f64,
    /// Largest size.
    pub hmax: f64,
    /// Geometric tolerance of the tangential size `sqrt(eps / |kappa|)`.
    pub eps: f64,
    /// Half-width of the band `d < band` where the size across the data is `hmin`.
    pub band: f64,
    /// Growth of the size per unit of distance outside the band.
    pub gradation: f64,
    /// Isotropic variant: size `hmin` in every direction in the band (the paper's
    /// comparison mesh).
    pub isotropic: bool,
    /// Neighbours in each sample's local fit.
    pub neighbours: usize,
}

/// The local shape of the data around one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LocalFrame {
    /// Unit normal of the fitted curve (orientation arbitrary).
    pub normal: Point,
    /// Curvature of the fitted parabola, averaged over the neighbours (raw fits carry the
    /// sign of their own normal; smoothed frames store the magnitude).
    pub curvature: f64,
    /// RMS residual of the fit: a local noise estimate.
    pub residual: f64,
    /// Standard error of the fitted curvature from the fit's residuals (0 when the fit
    /// has no degree of freedom left): curvature below about twice this is noise.
    pub curvature_se: f64,
    /// False where the neighbours do not define a direction (a single point, a cluster).
    pub defined: bool,
}

/// Fits a [`LocalFrame`] to `pts` around `center` (the sample itself).
pub fn fit_frame(center: Point, pts: &[Point]) -> LocalFrame {
    let n = pts.len();
    if n < 2 {
        return LocalFrame::default();
    }
    let inv = 1.0 / n as f64;
    let c = pts
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0] * inv, s[1] + p[1] * inv]);
    let mut cov = Sym2::default();
    for p in pts {
        cov = cov.plus(Sym2::outer(sub(*p, c)));
    }
    let (l1, l2, t) = cov.eigen();
    let spread = pts.iter().map(|p| dot(sub(*p, c), sub(*p, c))).sum::<f64>();
    if l1.is_nan() || l1 <= 0.0 || spread <= 1e-24 * (1.0 + dot(c, c)) {
        return LocalFrame::default();
    }
    let normal = [-t[1], t[0]];
    // Parabola h = c0 + c1 s + c2 s^2 in the frame (t, normal) at the sample.
    let mut ata = Matrix3::<f64>::zeros();
    let mut atb = Vector3::<f64>::zeros();
    for p in pts {
        let q = sub(*p, center);
        let (s, h) = (dot(q, t), dot(q, normal));
        let row = Vector3::new(1.0, s, s * s);
        ata += row * row.transpose();
        atb += row * h;
    }
    let (curvature, residual, curvature_se) = if n >= 4 && l2 < l1 {
        match ata.lu().solve(&atb) {
            Some(x) if x.iter().all(|v| v.is_finite()) => {
                let res2 = pts
                    .iter()
                    .map(|p| {
                        let q = sub(*p, center);
                        let (s, h) = (dot(q, t), dot(q, normal));
                        (h - x[0] - x[1] * s - x[2] * s * s).powi(2)
                    })
                    .sum::<f64>();
                let slope = (1.0 + x[1] * x[1]).powf(1.5);
                // Least squares: var(c2) = s^2 (A^T A)^-1_22, s^2 = res2 / (n - 3).
                let se = ata.try_inverse().map_or(0.0, |inv_ata| {
                    let s2 = res2 / (n - 3) as f64;
                    2.0 * (s2 * inv_ata[(2, 2)].max(0.0)).sqrt() / slope
                });
                (2.0 * x[2] / slope, (res2 * inv).sqrt(), se)
            }
            _ => (0.0, (l2 * inv).sqrt(), 0.0),
        }
    } else {
        (0.0, (l2.max(0.0) * inv).sqrt(), 0.0)
    };
    LocalFrame {
        normal,
        curvature,
        residual,
        curvature_se,
        defined: true,
    }
}

/// The metric field of one point set: a local frame per sample, looked up through the
/// distance field's nearest-sample query.
pub struct CurveMetric<'a> {
    field: &'a DistanceField,
    frames: Cow<'a, [LocalFrame]>,
    /// The `k` nearest samples of each sample (itself included), nearest first, flat.
    neighbours: Cow<'a, [u32]>,
    k: usize,
    params: MetricParams,
}

impl<'a> CurveMetric<'a> {
    /// Fits every sample's frame (in parallel), then smooths `|kappa|` over each sample's
    /// neighbours so that the tangential size varies smoothly along the data.
    pub fn new(field: &'a DistanceField, params: MetricParams) -> Self {
        let points = field.points();
        let k = params.neighbours.max(3).min(points.len());
        // Each sample's neighbours, found once for both passes (and kept for callers).
        let neighbours = neighbour_lists(field, k);
        let lists = || neighbours.par_chunks(k.max(1));
        let raw: Vec<LocalFrame> = points
            .par_iter()
            .zip(lists())
            .map_init(Vec::new, |pts: &mut Vec<Point>, (&p, idx)| {
                pts.clear();
                pts.extend(idx.iter().map(|&i| points[i as usize]));
                fit_one_sheet(p, pts)
            })
            .collect();
        let frames = raw
            .par_iter()
            .zip(lists())
            .map(|(f, idx)| {
                // Average the signed curvature with each neighbour's normal turned to
                // agree with this one: averaging |kappa| would turn noise into curvature.
                let (sum, cnt) = idx
                    .iter()
                    .map(|&i| &raw[i as usize])
                    .filter(|g| g.defined)
                    .fold((0.0, 0usize), |(s, c), g| {
                        let sign = dot(g.normal, f.normal).signum();
                        (s + sign * g.curvature, c + 1)
                    });
                LocalFrame {
                    curvature: if cnt > 0 {
                        (sum / cnt as f64).abs()
                    } else {
                        0.0
                    },
                    ..*f
                }
            })
            .collect();
        CurveMetric {
            field,
            frames: Cow::Owned(frames),
            neighbours: Cow::Owned(neighbours),
            k,
            params,
        }
    }

    /// A metric from frames fitted earlier (by [`CurveMetric::new`] on the same field),
    /// possibly under new parameters (e.g. a band derived from the noise estimate).
    /// `neighbours` are the lists [`CurveMetric::into_parts`] gave with them (`k` per
    /// sample; empty if not kept), which [`MetricSource::metric_near`] searches first.
    pub fn from_frames(
        field: &'a DistanceField,
        frames: &'a [LocalFrame],
        neighbours: &'a [u32],
        k: usize,
        params: MetricParams,
    ) -> Self {
        assert_eq!(frames.len(), field.points().len(), "one frame per point");
        let k = if neighbours.len() == k * frames.len() {
            k
        } else {
            0
        };
        CurveMetric {
            field,
            frames: Cow::Borrowed(frames),
            neighbours: Cow::Borrowed(neighbours),
            k,
            params,
        }
    }

    /// The nearest data point to `x`, searched first among the neighbours of data point
    /// `hint`. Those are every point closer to it than its farthest listed neighbour
    /// (`reach`), so if the best of them lies within `reach - |x - hint|` of `x`, no
    /// point elsewhere can be closer; otherwise the kd-tree answers.
    fn nearest_from(&self, x: Point, hint: u32) -> Nearest {
        let h = hint as usize;
        if self.k > 0 && h < self.frames.len() {
            let pts = self.field.points();
            let list = &self.neighbours[h * self.k..(h + 1) * self.k];
            let centre = pts[h];
            let reach = dist(centre, pts[list[self.k - 1] as usize]);
            let dc = dist(x, centre);
            // The hint is usually the nearest point itself, and then the test passes only
            // if `2 |x - hint| < reach`: farther out, the scan would be wasted.
            if dc >= 0.6 * reach {
                return self.field.nearest(x);
            }
            let (mut best2, mut best) = (f64::INFINITY, hint);
            for &j in list {
                let e = sub(x, pts[j as usize]);
                let d2 = dot(e, e);
                if d2 < best2 {
                    (best2, best) = (d2, j);
                }
            }
            let d = best2.sqrt();
            if d + dc < reach {
                return Nearest {
                    dist: d,
                    index: best,
                };
            }
        }
        self.field.nearest(x)
    }

    /// The metric at `x` given its nearest data point.
    #[inline]
    fn metric_from(&self, near: Nearest) -> Sym2 {
        let hn = self.normal_size(near.dist);
        let normal_eig = 1.0 / (hn * hn);
        let f = &self.frames[near.index as usize];
        if self.params.isotropic || !f.defined {
            return Sym2::iso(normal_eig);
        }
        let lo = 1.0 / (self.params.hmax * self.params.hmax);
        // The Hessian term |kappa| / eps, never finer than across the data.
        let tangent_eig = (f.curvature.abs() / self.params.eps).clamp(lo, normal_eig);
        Sym2::from_eigen(normal_eig, tangent_eig, f.normal)
    }

    /// The fitted frames and the neighbour lists (`k` per sample, flat, nearest first),
    /// giving up the borrow of the field.
    pub fn into_parts(self) -> (Vec<LocalFrame>, Vec<u32>, usize) {
        (
            self.frames.into_owned(),
            self.neighbours.into_owned(),
            self.k,
        )
    }

    /// Size across the data at distance `d`: `hmin` in the band, then graded to `hmax`.
    #[inline]
    pub fn normal_size(&self, d: f64) -> f64 {
        let p = &self.params;
        if d <= p.band {
            p.hmin
        } else {
            (p.hmin + p.gradation * (d - p.band)).min(p.hmax)
        }
    }
}

/// The `k` nearest samples of each sample of `field` (itself included), nearest first,
/// flat in the field's order.
pub fn neighbour_lists(field: &DistanceField, k: usize) -> Vec<u32> {
    let points = field.points();
    let mut neighbours = vec![0u32; points.len() * k];
    if k > 0 {
        neighbours
            .par_chunks_mut(k)
            .zip(points.par_iter())
            .for_each_init(Vec::new, |idx, (out, &p)| {
                field.nearest_k(p, k, idx);
                out.copy_from_slice(&idx[..k]);
            });
    }
    neighbours
}

/// Below this share of the noise measurement's windows that see a curve, a point
/// cloud's noise band is wider than most windows and it is drawn by the graph over its
/// samples, whose windows grow per sample; below this share of those, the points fill
/// an area and no curve is drawn through them ([`crate::Warning::Area`]). A window sees a
/// curve when it holds ten samples and spans four times their residual: in uniformly
/// scattered points a window passes by chance (measured under 4% of them, at 1,000 to
/// 4,000 points), in a drawing everywhere but its junctions and hatching (measured at
/// least 46% of them on the development glyphs).
pub const AREA_SHARE: f64 = 0.1;

/// A fit spanning at least this many times its own residual sees the noise as noise.
const NOISE_WINDOW: f64 = 4.0;
/// Samples the scale-consistent noise estimate fits around, at most.
const NOISE_CENTRES: usize = 2000;
/// Samples in one of its fits, at most: an even subsample of a window holding more.
const NOISE_FIT_MAX: usize = 512;
/// Samples in the smallest window a fit along one wall is tried over.
pub(crate) const SHEET_SAMPLES: usize = 10;

/// The data's noise, measured at a scale that does not shrink with the sampling: the
/// median residual of fits over the samples within a radius `r` of evenly spread
/// centres, with `r` grown until it spans four times the residual it
/// measures. A fit over a fixed number of neighbours (`frames`, `k` per sample in
/// `neighbours`) spans less of the curve the denser the sampling; once it is narrower
/// than the noise band it sees a blob, whose residual scales with the window, not the
/// noise. Where the `k` neighbours already span enough (sparse or clean data), their
/// median residual is the answer. The cost is bounded whatever the number of samples.
pub fn consistent_noise(
    field: &DistanceField,
    frames: &[LocalFrame],
    neighbours: &[u32],
    k: usize,
) -> NoiseScale {
    let pts = field.points();
    let n = pts.len();
    let mut noise = median_residual(frames);
    if k == 0 || neighbours.len() != n * k {
        return NoiseScale {
            noise,
            window: 0.0,
            neighbours: 0.0,
            one_wall: noise,
            curve_share: 1.0,
        };
    }
    let mut curve_share = 1.0;
    let step = n.div_ceil(NOISE_CENTRES).max(1);
    let centres: Vec<usize> = (0..n).step_by(step).collect();
    let mut radii: Vec<f64> = centres
        .iter()
        .map(|&i| dist(pts[i], pts[neighbours[i * k + k - 1] as usize]))
        .collect();
    let mid = radii.len() / 2;
    let knn = *radii.select_nth_unstable_by(mid, f64::total_cmp).1;
    let mut r = knn;
    let centre_pts: Vec<Point> = centres.iter().map(|&i| pts[i]).collect();
    // Where walls lie closer together than the k-th neighbour (sparse samples between
    // narrow gaps), the k-neighbour fits span several walls and their residual is the
    // gap, not the noise: the smallest window that spans four times its own residual
    // sees one wall, and is taken when it measures under half as much.
    let small_k = SHEET_SAMPLES.min(k) - 1;
    let mut small: Vec<f64> = centres
        .iter()
        .map(|&i| dist(pts[i], pts[neighbours[i * k + small_k] as usize]))
        .collect();
    let mid_small = small.len() / 2;
    let mut s = *small.select_nth_unstable_by(mid_small, f64::total_cmp).1;
    let mut one_wall = None;
    while s < 0.8 * knn {
        let at_s = median_residual(&fits_within(field, &centre_pts, s));
        if s >= NOISE_WINDOW * at_s {
            // Only where the k neighbours' fits see a curve (spanning sixteen times
            // their residual): narrower than the noise band, a window's residual
            // shrinks with it, and a smaller one's says nothing of the samples.
            if noise <= knn / 16.0 {
                one_wall = Some(at_s);
            }
            if at_s < 0.5 * noise && noise > knn / 16.0 {
                (r, noise) = (s, at_s);
            }
            break;
        }
        s *= 1.25;
    }
    if NOISE_WINDOW * noise > 1.05 * r {
        // The `k` neighbours' windows are narrower than four times what they measure:
        // each centre's window grows from there until it spans four times its own
        // residual, and the noise is the median over the centres whose window does. A
        // window over several strokes drawn closer than their noise (a hatched glyph)
        // sees a blob whose residual grows with it and does not qualify within a local
        // window, so it has no say; one common window, grown to four times the median,
        // is pulled wider by those blobs at every step and with it the noise. Where no
        // centre's window qualifies (noise over a 64th of the extent), a common window
        // grows until it spans four times the median residual.
        let r_max = largest_window(field);
        let grown = own_windows(field, &centre_pts, r, r_max);
        curve_share = grown.len() as f64 / centre_pts.len() as f64;
        if grown.is_empty() {
            // No window up to the largest allowed sees a curve: the samples fill an
            // area at every local scale, and no noise can be measured. The bound holds
            // at the largest window's reach: a noise above a 64th of the extent would
            // have been measured.
            r = r_max;
            noise = noise.min(r_max / NOISE_WINDOW);
        } else {
            let mid = grown.len() / 2;
            let mut res: Vec<f64> = grown.iter().map(|g| g.0).collect();
            let mut win: Vec<f64> = grown.iter().map(|g| g.1).collect();
            noise = *res.select_nth_unstable_by(mid, f64::total_cmp).1;
            r = *win.select_nth_unstable_by(mid, f64::total_cmp).1;
        }
    }
    NoiseScale {
        noise,
        window: r,
        neighbours: knn,
        one_wall: one_wall.map_or(noise, |w| w.min(noise)),
        curve_share,
    }
}

/// What [`consistent_noise`] found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoiseScale {
    /// The noise: the median residual of the fits.
    pub noise: f64,
    /// The radius of the fits that measured it.
    pub window: f64,
    /// The median radius of the `k` nearest neighbours.
    pub neighbours: f64,
    /// The residual of the smallest window that sees one wall (spanning four times its
    /// own residual), where that is less than `noise` and the `k` neighbours' fits span
    /// sixteen times theirs: those fits see a bend or a second wall as noise where they
    /// span it, and a clean shape with bays of about their reach measures as noisy. At
    /// most `noise`.
    pub one_wall: f64,
    /// The share of the centres whose own window sees a curve (holds enough samples
    /// and spans four times its residual) when the `k` neighbours' windows did not; 1
    /// when those did. Samples that fill an area (strokes hatched closer than the
    /// sampling resolves, scattered points) give almost none.
    pub curve_share: f64,
}

/// A frame fitted to the sheet of samples through `center`: `pts` are its nearest
/// samples, nearest first, and may reach a second wall (the far side of a narrow
/// corridor or inlet), which would turn the fit across both. The nearest quarter (at
/// least 6) fixes the sheet, if its residual is below an eighth of its radius and it
/// bends by less than half a radian over it (not a blob of data denser than its noise,
/// nor a corner). The offsets of all the samples
/// from that fit split at their widest gap, and only the centre's side is fitted when
/// the split is two walls, not the tails of one noisy band, the bend of one clean wall
/// or the other arm of a corner: the gap at least six times the first fit's noise and
/// as wide as the nearest quarter's radius, opening at the centre's own sheet, with at
/// least 4 samples beyond it at about one offset (spread below half the gap) that
/// stretch along the sheet for a quarter of that radius. A second cut takes a wall on
/// the other side off too.
pub fn fit_one_sheet(center: Point, pts: &mut Vec<Point>) -> LocalFrame {
    let k0 = (pts.len() / 4).max(6);
    if pts.len() < 2 * k0 {
        return fit_frame(center, pts);
    }
    let first = fit_frame(center, &pts[..k0]);
    if !first.defined {
        return fit_frame(center, pts);
    }
    let tangent = [first.normal[1], -first.normal[0]];
    // Offsets from the first fit's parabola through the centre, to second order; a
    // curvature within three standard errors of none is noise, and extrapolated over
    // the whole window it would scatter one wall's samples.
    let curvature = if first.curvature.abs() > 3.0 * first.curvature_se {
        first.curvature
    } else {
        0.0
    };
    let offset = |p: Point| {
        let q = sub(p, center);
        let (s, h) = (dot(q, tangent), dot(q, first.normal));
        h - 0.5 * curvature * s * s
    };
    // The sheet's own noise, the first fit's residual over its degrees of freedom.
    let sigma = first.residual * (k0 as f64 / (k0 - 3) as f64).sqrt();
    let window = dist(center, pts[k0 - 1]);
    // Only a first fit along a sheet (its samples spread far more along it than across,
    // and not bending by more than half a radian across it) fixes a direction to cut
    // across; on data denser than its noise it is a blob, at a corner a bend.
    if sigma > window / 8.0 || first.curvature.abs() * window > 0.5 {
        return fit_frame(center, pts);
    }
    let own = offset(center);
    // A wall on each side of the centre's (a turn of a spiral) takes two cuts.
    let mut sorted = Vec::with_capacity(pts.len());
    for _ in 0..2 {
        sorted.clear();
        sorted.extend(pts.iter().map(|&p| offset(p)));
        sorted.sort_unstable_by(f64::total_cmp);
        let Some((cut, gap)) = sorted
            .windows(2)
            .enumerate()
            .map(|(i, w)| (i + 1, w[1] - w[0]))
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        let split = 0.5 * (sorted[cut - 1] + sorted[cut]);
        let below = own < split;
        let far = if below {
            &sorted[cut..]
        } else {
            &sorted[..cut]
        };
        // A parallel wall lies at one offset; the other arm of a corner spreads.
        let mean = far.iter().sum::<f64>() / far.len() as f64;
        let spread =
            (far.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / far.len() as f64).sqrt();
        // The gap must open right at the centre's own sheet, not inside a spread of samples.
        let edge = if below { sorted[cut - 1] } else { sorted[cut] };
        let at_own = (edge - own).abs() <= 6.0 * sigma + 0.25 * window;
        // And the far wall runs along the sheet, as the other arm of a corner does not.
        let (lo_s, hi_s) = pts
            .iter()
            .filter(|&&p| (offset(p) < split) != below)
            .map(|&p| dot(sub(p, center), tangent))
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), s| {
                (a.min(s), b.max(s))
            });
        let along = hi_s - lo_s >= 0.25 * window;
        if far.len() < 4
            || gap < 6.0 * sigma
            || gap < window
            || spread > 0.5 * gap
            || !at_own
            || !along
        {
            break;
        }
        pts.retain(|&p| (offset(p) < split) == below);
        if pts.len() < k0 {
            break;
        }
    }
    fit_frame(center, pts)
}

/// A frame fitted at each of `centres` to the samples of `field` within `r` of it (an
/// even subsample of at most 512 of them).
pub fn fits_within(field: &DistanceField, centres: &[Point], r: f64) -> Vec<LocalFrame> {
    centres
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(idx, sel): &mut (Vec<u32>, Vec<Point>), &c| fit_within(field, c, r, idx, sel),
        )
        .collect()
}

/// A centre's window stays within this fraction of the data's extent: the noise is
/// measured where the data look like a curve, and a window that must span a sixteenth
/// of the drawing before it does is over a blob of strokes, not one noisy wall (a wall
/// spans 4 times its residual once the window is 4 sigma wide, so this holds for noise
/// up to a 64th of the extent).
const LOCAL_WINDOWS: f64 = 16.0;

/// For each of `centres`, the residual and radius of its smallest window, from `r0` up
/// by a quarter at a time to at most `r_max`, that holds at least [`SHEET_SAMPLES`]
/// samples (fewer measure their residual to no better than a third) and spans
/// [`NOISE_WINDOW`] times its own residual; centres where none does are left out.
fn own_windows(field: &DistanceField, centres: &[Point], r0: f64, r_max: f64) -> Vec<(f64, f64)> {
    centres
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(idx, sel): &mut (Vec<u32>, Vec<Point>), &c| {
                let mut r = r0;
                while r <= r_max {
                    let f = fit_within(field, c, r, idx, sel);
                    if sees_a_curve(&f, idx.len(), r) {
                        return Some((f.residual, r));
                    }
                    r *= 1.25;
                }
                None
            },
        )
        .flatten()
        .collect()
}

/// The largest window a sample's noise is measured in: a [`LOCAL_WINDOWS`]th of the
/// samples' extent.
pub(crate) fn largest_window(field: &DistanceField) -> f64 {
    let extent = crate::geom::BBox::of(field.points())
        .map_or(0.0, |b| (b.max[0] - b.min[0]).max(b.max[1] - b.min[1]));
    extent / LOCAL_WINDOWS
}

/// Whether a window of radius `r` holding `held` samples, whose own sheet's fit is
/// `f`, sees a curve: it holds [`SHEET_SAMPLES`] and spans [`NOISE_WINDOW`] times its
/// residual (a blob of samples, or a window narrower than the noise band, does not).
pub(crate) fn sees_a_curve(f: &LocalFrame, held: usize, r: f64) -> bool {
    f.defined && held >= SHEET_SAMPLES && r >= NOISE_WINDOW * f.residual
}

/// The frame fitted to the samples within `r` of `c` (an even subsample of at most
/// [`NOISE_FIT_MAX`]), its residual over its degrees of freedom; `sel` holds the
/// samples of the centre's own sheet it was fitted to.
pub(crate) fn fit_within(
    field: &DistanceField,
    c: Point,
    r: f64,
    idx: &mut Vec<u32>,
    sel: &mut Vec<Point>,
) -> LocalFrame {
    let pts = field.points();
    field.within(c, r, idx);
    idx.sort_unstable();
    let stride = idx.len().div_ceil(NOISE_FIT_MAX).max(1);
    sel.clear();
    sel.extend(idx.iter().step_by(stride).map(|&j| pts[j as usize]));
    // Nearest first, for the fit to find the centre's own sheet.
    sel.sort_unstable_by(|a, b| dist(c, *a).total_cmp(&dist(c, *b)));
    let mut f = fit_one_sheet(c, sel);
    // The parabola's three parameters absorb part of the noise of a few samples: the
    // residual over its degrees of freedom is unbiased.
    let m = sel.len() as f64;
    if m > 4.0 {
        f.residual *= (m / (m - 3.0)).sqrt();
    }
    f
}

/// Frames at the scale of the noise for data too dense for `k`-neighbour fits: fitted
/// (as by [`consistent_noise`]) at every `s`-th sample, `s` the ratio of the samples in
/// a window of radius `scale.window` to those in one of `scale.neighbours` (so the
/// fits cover the data about as densely as the windows overlap), and each sample takes
/// the frame of the nearest of them, its curvature as a magnitude. Their cost does not
/// grow with the density beyond the nearest-centre lookup.
pub fn frames_at_scale(field: &DistanceField, scale: NoiseScale) -> Result<Vec<LocalFrame>> {
    let pts = field.points();
    let ratio = (scale.window / scale.neighbours.max(f64::MIN_POSITIVE)).powi(2);
    let stride = (ratio.min(pts.len() as f64) as usize).max(1);
    let centres = DistanceField::new(&pts.iter().step_by(stride).copied().collect::<Vec<_>>())?;
    let fits = fits_within(field, centres.points(), scale.window);
    Ok(centres
        .nearest_all(pts)
        .into_iter()
        .map(|near| {
            let f = fits[near.index as usize];
            LocalFrame {
                curvature: f.curvature.abs(),
                ..f
            }
        })
        .collect())
}

/// Median of the frames' residuals (0 when none is defined).
pub fn median_residual(frames: &[LocalFrame]) -> f64 {
    let mut r: Vec<f64> = frames
        .iter()
        .filter(|f| f.defined)
        .map(|f| f.residual)
        .collect();
    if r.is_empty() {
        return 0.0;
    }
    let mid = r.len() / 2;
    *r.select_nth_unstable_by(mid, f64::total_cmp).1
}

impl MetricSource for CurveMetric<'_> {
    fn metric(&self, x: Point) -> Sym2 {
        self.metric_from(self.field.nearest(x))
    }

    fn metric_near(&self, x: Point, hint: u32) -> (Sym2, u32) {
        let near = self.nearest_from(x, hint);
        (self.metric_from(near), near.index)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The noise of a straight band measured at 1k, 10k and 100k samples. Fits of a
    /// window of radius 4σ to Gaussian scatter of deviation σ have an RMS residual a
    /// little under σ (the window's edge cuts the tails; the parabola takes a few
    /// degrees of freedom): 0.8σ to 1.05σ at every density, where 32-neighbour fits
    /// give far less at 10k and 100k. Frames at that scale find the band's direction to
    /// the standard error of a principal axis of `m` samples with variances `r²/3`
    /// along and `σ²` across: `sqrt(r²σ²/3m) / (r²/3 - σ²)`, 1.5° for the 400 to 512
    /// samples of a window here, so fewer than 1% of them are off by 5° (3.3 standard
    /// errors), away from the line's ends (a window there holds half a band). The
    /// residual over one wall's window is the noise itself: nothing looks cleaner.
    #[test]
    fn the_noise_estimate_does_not_fall_as_the_density_rises() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal, Uniform};
        let sigma = 0.005;
        for n in [1_000, 10_000, 100_000] {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
            let (x, y) = (
                Uniform::new(0.0, 1.0).unwrap(),
                Normal::new(0.0, sigma).unwrap(),
            );
            let pts: Vec<Point> = (0..n)
                .map(|_| [x.sample(&mut rng), y.sample(&mut rng)])
                .collect();
            let (field, knn, scale) = measured_noise(&pts);
            let ratio = scale.noise / sigma;
            assert!(
                (0.8..=1.05).contains(&ratio),
                "n = {n}: {ratio} (k-NN {knn})"
            );
            // Nor does the one-wall residual: windows narrower than the band measure
            // their own width, not the samples' cleanness.
            assert_eq!(scale.one_wall, scale.noise, "n = {n}");
            if scale.window > 2.0 * scale.neighbours {
                let frames = frames_at_scale(&field, scale).unwrap();
                let tilted = frames
                    .iter()
                    .zip(field.points())
                    .filter(|(_, p)| (0.05..0.95).contains(&p[0]))
                    .filter(|(f, _)| f.normal[1].abs() < 5f64.to_radians().cos())
                    .count();
                assert!(tilted * 100 < n, "n = {n}: {tilted} frames tilted over 5°");
            }
        }
    }

    /// Dense noisy strokes (sigma = 0.005), most of their samples hatched: ten parallel
    /// strokes 0.01 apart, closer than their noise band, a blob at every scale up to
    /// its own width. Windows common to every centre, grown to four times the median
    /// residual, would be pulled wider by the blob at every step; each centre's own
    /// window qualifies on the strokes drawn apart only, and their median residual is
    /// sigma to within the spread of a median of some 800 fits (a few percent) and
    /// the windows' residual bias over their degrees of freedom: within 20%.
    #[test]
    fn strokes_hatched_closer_than_their_noise_do_not_inflate_it() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal, Uniform};
        let sigma = 0.005;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let (t, e) = (
            Uniform::new(0.0, 1.0).unwrap(),
            Normal::new(0.0, sigma).unwrap(),
        );
        let mut pts: Vec<Point> = Vec::new();
        // Four strokes 0.2 apart across the box, 2,000 samples each.
        for k in 0..4 {
            for _ in 0..2_000 {
                let y = 0.1 + 0.2 * k as f64;
                pts.push([t.sample(&mut rng), y + e.sample(&mut rng)]);
            }
        }
        // The hatching: ten strokes 0.01 apart, 0.2 long, 1,200 samples each.
        for k in 0..10 {
            for _ in 0..1_200 {
                let y = 0.85 + 0.01 * k as f64;
                pts.push([0.4 + 0.2 * t.sample(&mut rng), y + e.sample(&mut rng)]);
            }
        }
        let (_, knn, scale) = measured_noise(&pts);
        let ratio = scale.noise / sigma;
        assert!(
            (0.8..=1.2).contains(&ratio),
            "{ratio} (k-NN {knn}, {scale:?})"
        );
        // The strokes drawn apart are four fifths of the drawing's length: their
        // windows see a curve, far more than the share an area gives by chance.
        assert!(scale.curve_share > 0.3, "{scale:?}");
    }

    /// Points scattered over an area (and strokes hatched closer than the sampling
    /// resolves look the same) sample no curve at any scale: a window holds samples
    /// spread over its whole disc, whose residual is a fixed share of its radius, so
    /// almost no window spans four times its residual, and the noise is bounded by the
    /// largest window's: a 64th of the extent, where the windows stop.
    #[test]
    fn points_that_fill_an_area_see_no_curve_and_bound_the_noise() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for n in [1_000, 4_000] {
            let pts: Vec<Point> = (0..n)
                .map(|_| [rng.random::<f64>(), rng.random::<f64>()])
                .collect();
            let (_, _, scale) = measured_noise(&pts);
            assert!(scale.curve_share < AREA_SHARE, "{n}: {scale:?}");
            assert!(scale.noise <= 1.0 / 64.0 + 1e-12, "{n}: {scale:?}");
        }
    }

    /// Two parallel walls 0.08 apart sampled every 0.01 with sigma = 0.007: the 32
    /// nearest samples reach 0.16, across both walls, and their fits measure the gap.
    /// The smallest window spanning four times its own residual holds one wall, about
    /// 10 samples, and its residual over its degrees of freedom estimates sigma; the
    /// median over 200 such windows lies within 15% of it (the spread of one window's
    /// estimate is about sigma / sqrt(2 (m - 3)), a quarter of it, and a median of 200
    /// narrows that tenfold; the rest is the walls' ends).
    #[test]
    fn walls_closer_than_the_neighbours_reach_do_not_inflate_the_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let sigma = 0.007;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, sigma).unwrap();
        let pts: Vec<Point> = (0..400)
            .map(|i| {
                let (x, y) = ((i / 2) as f64 * 0.01, if i % 2 == 0 { 0.0 } else { 0.08 });
                [x + noise.sample(&mut rng), y + noise.sample(&mut rng)]
            })
            .collect();
        let (_, knn, scale) = measured_noise(&pts);
        let ratio = scale.noise / sigma;
        assert!((0.85..=1.15).contains(&ratio), "{ratio} (k-NN {knn})");
        assert!(scale.window < 0.5 * scale.neighbours, "{scale:?}");
    }

    /// A clean circle of radius 0.09 sampled every 0.008 (a bay of the simulator's
    /// bays, sampled as their gap table samples them): the 32 nearest samples span
    /// most of a half turn, and their parabolas miss it by a few 1e-3, which the noise
    /// estimate takes for noise. A window of one wall's ten or so samples spans a
    /// fifth of that turn, and a parabola's miss grows with the fourth power of the
    /// turn: `one_wall` is under a hundredth of the estimate (2.2e-5 against 3.9e-3).
    #[test]
    fn a_clean_bend_as_tight_as_the_neighbours_reach_is_clean_over_one_wall() {
        let n = 71;
        let pts: Vec<Point> = (0..n)
            .map(|i| std::f64::consts::TAU * i as f64 / n as f64)
            .map(|a| [0.09 * a.cos(), 0.09 * a.sin()])
            .collect();
        let (_, knn, scale) = measured_noise(&pts);
        assert!(scale.noise > 1e-3, "{scale:?} (k-NN {knn})");
        assert!(100.0 * scale.one_wall < scale.noise, "{scale:?}");
    }

    /// The field of `pts`, the median residual of its 32-neighbour frames and the
    /// scale-consistent noise measured from them.
    fn measured_noise(pts: &[Point]) -> (DistanceField, f64, NoiseScale) {
        let field = DistanceField::new(pts).unwrap();
        let metric = CurveMetric::new(&field, unit_params(32));
        let (frames, neighbours, k) = metric.into_parts();
        let knn = median_residual(&frames);
        let scale = consistent_noise(&field, &frames, &neighbours, k);
        (field, knn, scale)
    }

    /// Sizes for unit-scale test data: hmin 1e-3 in a band of 0.01, hmax 0.1.
    fn unit_params(neighbours: usize) -> MetricParams {
        MetricParams {
            hmin: 1e-3,
            hmax: 0.1,
            eps: 1e-3,
            band: 0.01,
            gradation: 0.3,
            isotropic: false,
            neighbours,
        }
    }

    #[test]
    fn one_sheet_fits_leave_out_a_parallel_wall_and_nothing_else() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let nearest_first = |c: Point, mut pts: Vec<Point>| {
            pts.sort_by(|a, b| dist(c, *a).total_cmp(&dist(c, *b)));
            pts.truncate(32);
            pts
        };
        // Two walls 8 spacings apart: 32 neighbours reach the far one, which would put
        // the fit's residual near half the gap; the one-sheet fit stays on its wall.
        let walls: Vec<Point> = (-20..=20)
            .flat_map(|i| [[i as f64, 0.0], [i as f64 + 0.5, 8.0]])
            .collect();
        let mut pts = nearest_first([0.0, 0.0], walls);
        let both = fit_frame([0.0, 0.0], &pts);
        assert!(both.residual > 1.0, "{both:?}");
        let one = fit_one_sheet([0.0, 0.0], &mut pts);
        assert!(one.residual < 1e-9 && one.normal[0].abs() < 1e-9, "{one:?}");
        assert!(pts.iter().all(|p| p[1] == 0.0));
        // One noisy band, and a corner: nothing to leave out.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, 0.5).unwrap();
        let band: Vec<Point> = (0..400)
            .map(|i| [i as f64 * 0.1 - 20.0, noise.sample(&mut rng)])
            .collect();
        let corner: Vec<Point> = (0..20)
            .flat_map(|i| [[i as f64, 0.0], [0.0, i as f64 + 1.0]])
            .collect();
        for (c, set) in [([0.0, 0.0], band), ([3.0, 0.0], corner)] {
            let mut pts = nearest_first(c, set);
            let all = fit_frame(c, &pts);
            assert_eq!(fit_one_sheet(c, &mut pts), all);
            assert_eq!(pts.len(), 32);
        }
    }

    #[test]
    fn frame_of_a_circle_arc_recovers_normal_and_curvature() {
        let r = 0.4;
        let pts: Vec<Point> = (-10..=10)
            .map(|i| {
                let a = i as f64 * 0.005;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let f = fit_frame([r, 0.0], &pts);
        assert!(f.defined);
        assert!(f.normal[0].abs() > 0.9999, "{f:?}");
        // Parabola fit to a circle: curvature exact to O(arc^2).
        assert!((f.curvature.abs() - 1.0 / r).abs() < 1e-3 / r, "{f:?}");
        // The circle leaves its osculating parabola by kappa^3 s^4 / 8 at arc half-width s.
        let s = 10.0 * 0.005 * r;
        assert!(f.residual < s.powi(4) / (8.0 * r.powi(3)), "{f:?}");
    }

    #[test]
    fn degenerate_neighbourhoods_give_undefined_or_flat_frames() {
        assert!(!fit_frame([1.0, 1.0], &[[1.0, 1.0]; 5]).defined);
        assert!(!fit_frame([1.0, 1.0], &[[1.0, 1.0]]).defined);
        let line: Vec<Point> = (0..6).map(|i| [i as f64, 2.0 * i as f64]).collect();
        let f = fit_frame(line[2], &line);
        assert!(f.defined && f.curvature.abs() < 1e-9);
    }

    #[test]
    fn metric_is_anisotropic_in_the_band_and_graded_outside() {
        let r = 0.4;
        let pts: Vec<Point> = (0..2000)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 2000.0;
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let field = DistanceField::new(&pts).unwrap();
        let params = unit_params(16);
        let cm = CurveMetric::new(&field, params);
        let m = cm.metric([r + 0.002, 0.0]);
        let (l1, l2, e) = m.eigen();
        assert!((l1 - 1e6).abs() < 1.0 && e[0].abs() > 0.999);
        // Tangential size sqrt(eps * r) = 0.02.
        assert!((1.0 / l2.sqrt() - 0.02).abs() < 1e-3, "{}", 1.0 / l2.sqrt());
        // Far away: isotropic hmax.
        let far = cm.metric([0.0, 0.0]);
        assert!((far.xx - 100.0).abs() < 1e-9 && far.xy.abs() < 1e-9);
        // Graded: size at d = 0.05 is hmin + 0.3 * 0.04.
        let g = cm.metric([r + 0.05, 0.0]).eigen();
        assert!((1.0 / g.0.sqrt() - 0.013).abs() < 1e-9);
    }

    #[test]
    fn hinted_search_finds_the_same_nearest_point_as_the_tree() {
        // Noisy samples of two nearby arcs, so that a hint on one arc can be beaten by a
        // point of the other that its neighbour list does not hold.
        let mut state = 12345u64;
        let mut rand = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut pts = Vec::new();
        for i in 0..1500 {
            let a = i as f64 / 1500.0 * std::f64::consts::PI;
            let r = if i % 2 == 0 { 0.4 } else { 0.43 };
            pts.push([r * a.cos() + 0.004 * rand(), r * a.sin() + 0.004 * rand()]);
        }
        let field = DistanceField::new(&pts).unwrap();
        let params = unit_params(32);
        let cm = CurveMetric::new(&field, params);
        let (frames, neighbours, k) = cm.into_parts();
        let cm = CurveMetric::from_frames(&field, &frames, &neighbours, k, params);
        let mut certified = 0;
        for _ in 0..20_000 {
            // A point near the data and a hint from a point up to 0.03 away from it.
            let p = pts[((rand() + 0.5) * pts.len() as f64) as usize % pts.len()];
            let x = [p[0] + 0.04 * rand(), p[1] + 0.04 * rand()];
            let y = [x[0] + 0.03 * rand(), x[1] + 0.03 * rand()];
            let hint = field.nearest(y).index;
            let (m, index) = cm.metric_near(x, hint);
            let exact = field.nearest(x);
            assert_eq!(
                dist(x, field.points()[index as usize]),
                exact.dist,
                "{x:?} from hint {hint}"
            );
            assert_eq!(m, cm.metric(x));
            certified += usize::from(dist(x, field.points()[hint as usize]) < 0.005);
        }
        assert!(certified > 100, "the test exercises the list search");
    }
}
