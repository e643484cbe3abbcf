//! The median settle: the curve moved into the middle of the data's noise band.
//!
//! On noisy data eq. 11 cannot hold below the noise amplitude, and nothing in the
//! discrete evolution holds the curve at the data: the capture phase leaves it on the
//! outermost samples (or, from a medial, free-space or warm start, wherever it began).
//! The settle shifts it, vertex by vertex, by the median of the level set over the
//! samples nearby, which is a robust estimate of where the middle of the band lies.

use rayon::prelude::*;

use crate::fem::locate::Location;
use crate::fem::P1Space;
use crate::field::MetricField;
use crate::levelset::solver::residual;
use crate::mesh::Mesh;
use crate::redistance::Redistancer;

/// What a settle did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SettleReport {
    /// The eq. 11 residual (largest `|u|` at the data) afterwards.
    pub residual: f64,
    /// The mean `|u|` at the data afterwards.
    pub mean: f64,
    /// Whether any round was kept: `u` is then a signed distance over the whole mesh.
    pub moved: bool,
}

/// The samples whose median a round of [`center_on_data`] takes, with each one's
/// neighbourhood.
struct Neighbourhoods<'a> {
    metric: &'a MetricField,
    /// The samples that are the nearest of a vertex near the curve.
    needed: Vec<u32>,
    /// Per sample of the field: its index in `needed`, or `NONE`.
    slot: Vec<u32>,
    /// The neighbourhoods searched for, per needed sample; empty when the metric's own
    /// (chain windows, or its first `k` neighbours) serve.
    found: Vec<Vec<u32>>,
    k: usize,
}

const NONE: u32 = u32::MAX;

impl<'a> Neighbourhoods<'a> {
    fn new(metric: &'a MetricField, nearest: &[u32], u: &[f64], width: f64) -> Self {
        let field = &metric.field;
        // Enough neighbours to span the noise band: the median count of samples within
        // `width` of a sample (checked on up to 64 of them), at least 32. Beyond
        // `MAX_MEDIAN` the nearest ones would span less than the band on dense data and
        // pull each median towards its own sample's side: then an even subsample of all
        // those within `width` is taken instead.
        const MAX_MEDIAN: usize = 512;
        let pts = field.points();
        let step = (pts.len() / 64).max(1);
        let mut counts: Vec<usize> = pts
            .iter()
            .step_by(step)
            .map(|&p| field.count_within(p, width))
            .collect();
        counts.sort_unstable();
        let within = counts.get(counts.len() / 2).copied().unwrap_or(32);
        let dense = within > MAX_MEDIAN;
        let k = within.clamp(32, MAX_MEDIAN).min(pts.len());
        // Only the samples that are the nearest of a vertex near the curve need a median:
        // on dense data (200k samples, 512 neighbours each) the others would dominate.
        let mut slot = vec![NONE; pts.len()];
        let mut needed = Vec::new();
        for (&j, &uv) in nearest.iter().zip(u.iter()) {
            if uv.abs() <= 2.0 * width && slot[j as usize] == NONE {
                slot[j as usize] = needed.len() as u32;
                needed.push(j);
            }
        }
        // The metric's fits found each sample's nearest neighbours already; the first `k` of
        // them will do when there are that many. A sample on a chain takes its chain window
        // instead and needs none. Allocation is fine here: once per frame.
        let on_chain = |j: u32| !metric.chain_window(j as usize).is_empty();
        let found: Vec<Vec<u32>> =
            if needed.iter().all(|&j| on_chain(j)) || (!dense && k <= metric.k) {
                Vec::new()
            } else if dense {
                needed
                    .par_iter()
                    .map_init(Vec::new, |buf, &j| {
                        field.within(pts[j as usize], width, buf);
                        buf.sort_unstable();
                        let stride = buf.len().div_ceil(MAX_MEDIAN).max(1);
                        buf.iter().step_by(stride).copied().collect()
                    })
                    .collect()
            } else {
                needed
                    .par_iter()
                    .map_init(Vec::new, |buf, &j| {
                        field.nearest_k(pts[j as usize], k, buf);
                        buf[..k.min(buf.len())].to_vec()
                    })
                    .collect()
            };
        Neighbourhoods {
            metric,
            needed,
            slot,
            found,
            k,
        }
    }

    /// The neighbourhood of `needed[s]`.
    fn list(&self, s: usize) -> &[u32] {
        let metric = self.metric;
        // A sample on a chain (a scan's run) takes its chain window: the same surface,
        // where a spatial neighbourhood of sparse, distant returns can span a corner or
        // reach across a depth jump.
        let chain = metric.chain_window(self.needed[s] as usize);
        if !chain.is_empty() {
            chain
        } else if self.found.is_empty() {
            let at = self.needed[s] as usize * metric.k;
            &metric.neighbours[at..at + self.k]
        } else {
            &self.found[s]
        }
    }
}

/// Moves the zero level set to the local median of the data: each vertex within `width`
/// of it is lowered by the median of `u` over the `k` nearest samples of its nearest
/// sample (`nearest[v]`; `data` holds the locations of `field`'s points, in its order),
/// then `u` is renormalized; repeated (at most 4 times) while the mean `|u|` at the data
/// improves by 1%.
///
/// The samples' neighbourhoods are found once, and only for the samples that are the
/// nearest of a vertex within `2 width` of the curve at the start (a vertex that comes
/// within `width` later without one keeps its value): the data do not move between
/// rounds, so a round costs one median per such sample and one fast marching.
pub fn center_on_data(
    mesh: &Mesh,
    space: &P1Space,
    metric: &MetricField,
    data: &[Location],
    nearest: &[u32],
    u: &mut [f64],
    width: f64,
) -> SettleReport {
    let hoods = Neighbourhoods::new(metric, nearest, u, width);
    let (slot, needed) = (&hoods.slot, &hoods.needed);
    let pts = metric.field.points();
    let mut at = vec![0.0; pts.len()];
    let mut medians = vec![0.0; needed.len()];
    let mut trial = u.to_vec();
    let mut fm = Redistancer::new();
    let (mut best_res, mut best) = residual(mesh, data, u);
    let mut moved = false;
    for _ in 0..4 {
        at.par_iter_mut()
            .zip(data.par_iter())
            .for_each(|(a, l)| *a = l.interpolate(mesh, u));
        medians
            .par_iter_mut()
            .enumerate()
            .for_each_init(Vec::new, |vals, (s, m)| {
                vals.clear();
                vals.extend(hoods.list(s).iter().map(|&j| at[j as usize]));
                let mid = vals.len() / 2;
                *m = *vals.select_nth_unstable_by(mid, f64::total_cmp).1;
            });
        trial
            .par_iter_mut()
            .zip(u.par_iter())
            .zip(nearest.par_iter())
            .for_each(|((t, &ui), &j)| {
                let s = slot[j as usize];
                *t = if ui.abs() > width || s == NONE {
                    ui
                } else {
                    ui - medians[s as usize]
                };
            });
        // Within `width` of the curve the shifted `u` is still a distance to its own zero
        // set, so the test can be made before the fast marching, which a rejected round
        // then does not pay for.
        let (_, before) = residual(mesh, data, &trial);
        tracing::debug!(mean = before, best, "center");
        if before >= best * 0.99 {
            break;
        }
        fm.run(mesh, space, &mut trial, f64::INFINITY);
        let (res, mean) = residual(mesh, data, &trial);
        if mean >= best {
            break;
        }
        best = mean;
        best_res = res;
        u.copy_from_slice(&trial);
        moved = true;
    }
    SettleReport {
        residual: best_res,
        mean: best,
        moved,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::contour::zero_isoline;
    use crate::fem::locate::locate_all;
    use crate::field::MeshParams;
    use crate::geom::{dist, BBox, Point};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// Samples of a circle of radius 0.3 with radial noise `sigma`; a level set that is
    /// the signed distance to a circle `offset` larger; a uniform mesh of size `h`.
    fn case(sigma: f64, offset: f64) -> (Mesh, P1Space, MetricField, Vec<f64>, Vec<u32>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let noise = Normal::new(0.0, sigma).unwrap();
        let pts: Vec<Point> = (0..2000)
            .map(|i| {
                let a = i as f64 / 2000.0 * std::f64::consts::TAU;
                let r = 0.3 + noise.sample(&mut rng);
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let field = MetricField::new(&pts, &MeshParams::default().with_hmin(0.004)).unwrap();
        let mesh = Mesh::structured(
            &BBox {
                min: [-0.45, -0.45],
                max: [0.45, 0.45],
            },
            225,
        );
        let space = P1Space::new(&mesh);
        let u = mesh
            .coords
            .iter()
            .map(|&p| dist(p, [0.0, 0.0]) - 0.3 - offset)
            .collect();
        let nearest = field
            .field
            .nearest_all(&mesh.coords)
            .iter()
            .map(|n| n.index)
            .collect();
        (mesh, space, field, u, nearest)
    }

    fn mean_radius(mesh: &Mesh, u: &[f64]) -> f64 {
        let curves = zero_isoline(mesh, u, 1e-12);
        assert_eq!(curves.len(), 1);
        let pts = &curves[0].points;
        pts.iter().map(|&p| dist(p, [0.0, 0.0])).sum::<f64>() / pts.len() as f64
    }

    /// A curve started 2 sigma outside the noise band's middle ends in it: the median of
    /// at least 32 samples of noise sigma errs by about 1.25 sigma / sqrt(32) = 0.22 sigma
    /// (one standard deviation), and averaging over the curve's vertices shrinks that
    /// further; the chord error of the P1 isoline on a mesh of size h = 0.004 at radius
    /// 0.3 is h^2 / (8 r) < 1e-5. So the mean radius is within 0.3 sigma of 0.3.
    #[test]
    fn a_curve_off_the_middle_of_the_noise_moves_into_it() {
        let sigma = 0.004;
        let (mesh, space, field, mut u, nearest) = case(sigma, 2.0 * sigma);
        let data = locate_all(&mesh, field.field.points());
        let (_, before) = residual(&mesh, &data, &u);
        let r = center_on_data(
            &mesh,
            &space,
            &field,
            &data,
            &nearest,
            &mut u,
            4.0 * sigma + 4.0 * 0.004,
        );
        assert!(r.moved && r.mean < before, "{r:?}, mean before {before}");
        let radius = mean_radius(&mesh, &u);
        assert!((radius - 0.3).abs() < 0.3 * sigma, "radius {radius}");
    }

    /// A curve already in the middle stays: no round improves the mean by 1%.
    #[test]
    fn a_centred_curve_stays_put() {
        let (mesh, space, field, mut u, nearest) = case(0.004, 0.0);
        let data = locate_all(&mesh, field.field.points());
        let before = u.clone();
        let r = center_on_data(&mesh, &space, &field, &data, &nearest, &mut u, 0.032);
        if !r.moved {
            assert_eq!(u, before);
        }
        assert!((mean_radius(&mesh, &u) - 0.3).abs() < 0.3 * 0.004);
    }
}
