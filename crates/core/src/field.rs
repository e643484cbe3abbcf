//! The mesh stage as one call: points in, an anisotropic mesh adapted to their distance
//! field out. Parameters left unset are derived from the data's bounding box, so unit-
//! scale and kilometre-scale data mesh alike without tuning.

use std::time::Instant;

use crate::distance::DistanceField;
use crate::error::{Error, Result};

use crate::geom::{BBox, Point};
use crate::mesh::adapt::{AdaptOptions, AdaptReport, Adapter};
use crate::mesh::metric::{CurveMetric, MetricParams};
use crate::mesh::quality::{mesh_stats, MeshStats};
use crate::mesh::Mesh;

/// The largest `max_vertices` accepted: a mesh takes about 300 bytes a vertex while it is
/// adapted, so this bounds a frame's mesh near 6 GB.
pub const MAX_VERTICES: usize = 20_000_000;

/// Mesh parameters; `None` means "derive from the data" (see each field).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct MeshParams {
    /// Smallest element size, across the data. Default: the bounding-box diagonal / 1000,
    /// or the estimated noise if that is larger: a mesh finer than the scatter of the data
    /// locates the curve no better (the README's accuracy table, measured both ways) and
    /// costs up to 6 times the vertices.
    pub hmin: Option<f64>,
    /// Largest element size. Default: diagonal / 10.
    pub hmax: Option<f64>,
    /// Geometric tolerance setting the size along the data, `sqrt(eps / curvature)`.
    /// Default: `hmin`.
    pub eps: Option<f64>,
    /// Half-width of the band around the data meshed at `hmin` across it.
    /// Default: `max(8 hmin, 4 x estimated noise)`.
    pub band: Option<f64>,
    /// Size growth per unit distance outside the band (dimensionless). Default 0.3; 0.6
    /// for a scan, whose curve starts on the data and needs no fine mesh on its way in.
    pub gradation: Option<f64>,
    /// Samples in each local curve fit of the metric. Default 32.
    pub neighbours: usize,
    /// Margin around the data's bounding box, as a fraction of its diagonal. Default 0.2.
    pub padding: f64,
    /// Mesh with size `hmin` in every direction in the band (the comparison mesh).
    pub isotropic: bool,
    /// Upper bound on adaptation passes. Default 24.
    pub max_passes: usize,
    /// Adapting from the previous frame's mesh (the daemon's warm start) stops after the
    /// first pass that splits or collapses fewer than this fraction of the vertices.
    /// A new frame's noise alone changes about 20% per pass (measured on the README's
    /// stream), which the next frame's pass follows up; a jump or a new shape changes
    /// more and gets more passes. Each warm pass smooths once instead of twice.
    /// Default 0.35.
    pub warm_change: f64,
    /// Refinement stops at this many vertices. Default 2,000,000.
    pub max_vertices: usize,
}

impl Default for MeshParams {
    fn default() -> Self {
        MeshParams {
            hmin: None,
            hmax: None,
            eps: None,
            band: None,
            gradation: None,
            neighbours: 32,
            padding: 0.2,
            isotropic: false,
            max_passes: 24,
            warm_change: 0.35,
            max_vertices: 2_000_000,
        }
    }
}

impl MeshParams {
    /// Sets `hmin`.
    pub fn with_hmin(mut self, h: f64) -> Self {
        self.hmin = Some(h);
        self
    }
    /// Sets `hmax`.
    pub fn with_hmax(mut self, h: f64) -> Self {
        self.hmax = Some(h);
        self
    }
    /// Sets `eps`.
    pub fn with_eps(mut self, e: f64) -> Self {
        self.eps = Some(e);
        self
    }
    /// Sets `band`.
    pub fn with_band(mut self, b: f64) -> Self {
        self.band = Some(b);
        self
    }
    /// Sets `isotropic`.
    pub fn with_isotropic(mut self, iso: bool) -> Self {
        self.isotropic = iso;
        self
    }
    /// Sets `max_vertices`.
    pub fn with_max_vertices(mut self, n: usize) -> Self {
        self.max_vertices = n;
        self
    }

    /// The same parameters with every length multiplied by `s` (into other units).
    pub fn scaled(&self, s: f64) -> MeshParams {
        let m = |x: Option<f64>| x.map(|v| v * s);
        MeshParams {
            hmin: m(self.hmin),
            hmax: m(self.hmax),
            eps: m(self.eps),
            band: m(self.band),
            ..self.clone()
        }
    }

    /// Checks the lengths that are set against data of extent (bounding-box diagonal)
    /// `extent`, in the same units: `hmin` below it, and every length within nine
    /// orders of magnitude of it, beyond which sizes are meaningless or their squares
    /// leave the floating-point range. Every problem is listed.
    pub fn check_against(&self, extent: f64) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        for (key, v) in [
            ("mesh.hmin", self.hmin),
            ("mesh.hmax", self.hmax),
            ("mesh.eps", self.eps),
            ("mesh.band", self.band),
        ] {
            if let Some(v) = v {
                if !(v >= 1e-9 * extent && v <= 1e9 * extent) {
                    problems.push(format!(
                        "{key} = {v:e}: must be within 1e-9 to 1e9 times the data's extent ({extent:e})"
                    ));
                }
            }
        }
        if let Some(h) = self.hmin {
            if h >= extent {
                problems.push(format!(
                    "mesh.hmin = {h:e}: must be below the data's extent ({extent:e}), or nothing is resolved"
                ));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }

    /// Checks the values that are set; every problem is listed.
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        crate::error::check_positive(&mut problems, "mesh.hmin", self.hmin);
        crate::error::check_positive(&mut problems, "mesh.hmax", self.hmax);
        crate::error::check_positive(&mut problems, "mesh.eps", self.eps);
        crate::error::check_positive(&mut problems, "mesh.band", self.band);
        crate::error::check_positive(&mut problems, "mesh.gradation", self.gradation);
        if let (Some(a), Some(b)) = (self.hmin, self.hmax) {
            if a > b {
                problems.push(format!("mesh.hmax = {b}: must be at least mesh.hmin = {a}"));
            }
        }
        if !(self.padding.is_finite() && (0.0..=10.0).contains(&self.padding)) {
            problems.push(format!(
                "mesh.padding = {}: must be in [0, 10] (a fraction of the data's extent)",
                self.padding
            ));
        }
        if !(3..=256).contains(&self.neighbours) {
            problems.push(format!(
                "mesh.neighbours = {}: must be in 3..=256",
                self.neighbours
            ));
        }
        if !(1..=1000).contains(&self.max_passes) {
            problems.push(format!(
                "mesh.max_passes = {}: must be in 1..=1000",
                self.max_passes
            ));
        }
        if !(self.warm_change > 0.0 && self.warm_change <= 1.0) {
            problems.push(format!(
                "mesh.warm_change = {}: must be in (0, 1]",
                self.warm_change
            ));
        }
        if !(16..=MAX_VERTICES).contains(&self.max_vertices) {
            problems.push(format!(
                "mesh.max_vertices = {}: must be in 16..={MAX_VERTICES}",
                self.max_vertices
            ));
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }
}

/// Milliseconds spent in each part of meshing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshTimings {
    /// Building the kd-tree.
    pub distance: f64,
    /// Fitting the metric's local frames.
    pub metric: f64,
    /// Adapting the mesh.
    pub adapt: f64,
    /// Everything.
    pub total: f64,
}

/// An adapted mesh and how it was made.
#[derive(Debug)]
pub struct AdaptedMesh {
    /// The mesh, in data coordinates.
    pub mesh: Mesh,
    /// Each vertex's nearest data point, as an index into the distance field's points
    /// (found by adaptation anyway, so later stages need not search again).
    pub(crate) nearest: Vec<u32>,
    /// The concrete parameters used (derived ones filled in).
    pub params: MetricParams,
    /// The meshed domain.
    pub domain: BBox,
    /// Whether adaptation started from the given mesh (the previous frame's) rather
    /// than from a lattice.
    pub warm: bool,
    /// Median local-fit residual of the data: a noise estimate.
    pub noise_estimate: f64,
    /// The residual over windows that see one wall: whether the samples are clean where
    /// `noise_estimate` measures a shape's bends.
    pub(crate) one_wall_noise: f64,
    /// What adaptation did.
    pub report: AdaptReport,
    /// Size and quality in the metric.
    pub stats: MeshStats,
    /// Time per part.
    pub ms: MeshTimings,
}

/// Adapts a mesh of the padded bounding box of `points` to their distance field.
///
/// The computation runs in coordinates centred on the data and scaled to its size
/// (`geom::Placement`); the returned mesh, sizes and noise estimate are in data
/// coordinates and units. The metrics stay in local units.
///
/// ```
/// use isoline_core::{stages::adapt_to_points, MeshParams};
/// let pts: Vec<[f64; 2]> = (0..200)
///     .map(|i| {
///         let a = i as f64 * std::f64::consts::TAU / 200.0;
///         [0.5 + 0.4 * a.cos(), 0.5 + 0.4 * a.sin()]
///     })
///     .collect();
/// let m = adapt_to_points(&pts, &MeshParams::default().with_hmin(0.01)).unwrap();
/// assert!(m.stats.min_quality > 0.0);
/// m.mesh.sanity_check().unwrap();
/// ```
pub fn adapt_to_points(points: &[Point], params: &MeshParams) -> Result<AdaptedMesh> {
    crate::distance::validate_points(points)?;
    let bbox = BBox::of(points).ok_or(Error::EmptyPointSet)?;
    let at = crate::geom::Placement::of(&bbox);
    let local: Vec<Point> = points.iter().map(|&p| at.to_local(p)).collect();
    let (mut m, _) = adapt_local(&local, &params.scaled(1.0 / at.scale))?;
    for p in &mut m.mesh.coords {
        *p = at.to_data(*p);
    }
    m.domain = BBox {
        min: at.to_data(m.domain.min),
        max: at.to_data(m.domain.max),
    };
    let len = |x: f64| at.len_to_data(x);
    m.params.hmin = len(m.params.hmin);
    m.params.hmax = len(m.params.hmax);
    m.params.eps = len(m.params.eps);
    m.params.band = len(m.params.band);
    m.noise_estimate = len(m.noise_estimate);
    m.one_wall_noise = len(m.one_wall_noise);
    Ok(m)
}

/// [`adapt_to_points`] without the change of origin: `points` should already be centred
/// near the origin. Also returns the distance field of the points, which the solver
/// needs at the mesh vertices.
pub fn adapt_local(points: &[Point], params: &MeshParams) -> Result<(AdaptedMesh, DistanceField)> {
    adapt_local_from(points, params, None)
}

/// [`adapt_local`] starting from `start` (a mesh in the same coordinates, for instance the
/// previous frame's) instead of a lattice. The start is used only if its domain covers the
/// bounding box of `points` with half the padding; otherwise adaptation starts from a
/// lattice.
pub fn adapt_local_from(
    points: &[Point],
    params: &MeshParams,
    start: Option<Mesh>,
) -> Result<(AdaptedMesh, DistanceField)> {
    let prepared = MetricField::new(points, params)?;
    let adapted = prepared.adapt(start);
    Ok((adapted, prepared.field))
}

/// The distance stage's product: the kd-tree of one frame's points and the local frames
/// of its metric, everything adaptation needs and nothing that depends on a mesh.
#[derive(Debug)]
pub struct MetricField {
    /// The points' distance field (exact duplicates merged).
    pub field: DistanceField,
    /// One local frame per distinct point, in the field's order.
    pub frames: Vec<crate::mesh::metric::LocalFrame>,
    /// The `k` nearest points of each point (itself included), nearest first, flat in
    /// the field's order: the neighbourhoods of the local fits.
    pub neighbours: Vec<u32>,
    /// Neighbours per point in `neighbours`.
    pub k: usize,
    /// For samples on a chain ([`MetricField::refit_along_chains`]): their chain
    /// neighbours (the sample and up to a window on either side), flat; sample `i`'s are
    /// `chain_neighbours[chain_offsets[i]..chain_offsets[i + 1]]`. Empty when no chains
    /// were given.
    pub chain_neighbours: Vec<u32>,
    /// Offsets into `chain_neighbours`, one more than there are samples (or empty).
    pub chain_offsets: Vec<u32>,
    /// Resolved metric parameters (the band derived from the noise when unset).
    pub params: MetricParams,
    /// Median local-fit residual: a noise estimate.
    pub noise_estimate: f64,
    /// The residual over windows that see one wall: at most `noise_estimate`.
    pub one_wall_noise: f64,
    /// The share of the noise measurement's windows that see a curve
    /// ([`crate::mesh::metric::NoiseScale::curve_share`]); 1 for a scan's runs.
    pub curve_share: f64,
    /// The points' bounding box.
    pub bbox: BBox,
    /// Margin around the bounding box, as a fraction of its diagonal.
    pub padding: f64,
    /// Adaptation's pass limit.
    pub max_passes: usize,
    /// The change below which a warm adaptation stops.
    pub warm_change: f64,
    /// Adaptation's vertex limit.
    pub max_vertices: usize,
    /// Time spent building the kd-tree and fitting the frames.
    pub ms: MeshTimings,
}

impl MetricField {
    /// Builds the kd-tree of `points` and fits the metric's local frames.
    pub fn new(points: &[Point], params: &MeshParams) -> Result<MetricField> {
        let t0 = Instant::now();
        crate::distance::validate_points(points)?;
        params.validate().map_err(|problems| Error::Config {
            path: "mesh parameters".into(),
            problems,
        })?;
        let bbox = BBox::of(points).ok_or(Error::EmptyPointSet)?;
        let diag = bbox.diag();
        let scale = if diag > 0.0 { diag } else { 1.0 };
        let field = DistanceField::new(points)?;
        let t_dist = t0.elapsed();
        let mut metric_params = MetricParams {
            hmin: scale / 1000.0,
            hmax: scale / 10.0,
            eps: 0.0,
            band: params.band.unwrap_or(0.0),
            gradation: params.gradation.unwrap_or(0.3),
            isotropic: params.isotropic,
            neighbours: params.neighbours,
        };
        // The local fits do not depend on the sizes, so the noise they measure can set
        // them.
        let metric = CurveMetric::new(&field, metric_params);
        let (mut frames, neighbours, k) = metric.into_parts();
        let noise_scale = crate::mesh::metric::consistent_noise(&field, &frames, &neighbours, k);
        let noise = noise_scale.noise;
        // On data dense enough that `k` neighbours span less than the noise band, their
        // normals and curvatures are noise too: the frames come from fits at its scale.
        // Where they span several walls, the frames come from the one-wall windows.
        if noise_scale.window > 2.0 * noise_scale.neighbours
            || noise_scale.window < 0.5 * noise_scale.neighbours
        {
            frames = crate::mesh::metric::frames_at_scale(&field, noise_scale)?;
        }
        let hmin = params.hmin.unwrap_or((scale / 1000.0).max(noise));
        let hmax = params.hmax.unwrap_or(scale / 10.0).max(hmin);
        let eps = params.eps.unwrap_or(hmin);
        metric_params.hmin = hmin;
        metric_params.hmax = hmax;
        metric_params.eps = eps;
        if params.band.is_none() {
            metric_params.band = (8.0 * hmin).max(4.0 * noise);
        }
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        Ok(MetricField {
            field,
            frames,
            neighbours,
            k,
            chain_neighbours: Vec::new(),
            chain_offsets: Vec::new(),
            params: metric_params,
            noise_estimate: noise,
            one_wall_noise: noise_scale.one_wall,
            curve_share: noise_scale.curve_share,
            bbox,
            padding: params.padding,
            max_passes: params.max_passes,
            warm_change: params.warm_change,
            max_vertices: params.max_vertices,
            ms: MeshTimings {
                distance: ms(t_dist),
                metric: ms(t0.elapsed() - t_dist),
                adapt: 0.0,
                total: ms(t0.elapsed()),
            },
        })
    }

    /// The field of a scan's runs for its band mesh (`crate::band`): the kd-tree of
    /// the `chains`' samples and each one's chain window (up to `window` on either side),
    /// which is all the settle reads; no local frames are fitted (the band needs no
    /// metric) and no spatial neighbour lists made. `params.hmin` is taken as given.
    pub fn of_chains(
        chains: &[Vec<Point>],
        params: &MeshParams,
        window: usize,
    ) -> Result<MetricField> {
        let t0 = Instant::now();
        let points: Vec<Point> = chains.iter().flatten().copied().collect();
        crate::distance::validate_points(&points)?;
        let bbox = BBox::of(&points).ok_or(Error::EmptyPointSet)?;
        let scale = if bbox.diag() > 0.0 { bbox.diag() } else { 1.0 };
        let field = DistanceField::new(&points)?;
        let n = field.points().len();
        let hmin = params.hmin.unwrap_or(scale / 1000.0);
        // Each field point's window as a span of the chains' ids laid end to end (a
        // point on two chains keeps the last), flattened in field order.
        let ids: Vec<u32> = points.iter().map(|&p| field.nearest(p).index).collect();
        let mut spans = vec![(0usize, 0usize); n];
        let mut base = 0;
        for chain in chains {
            let len = chain.len();
            for i in 0..len {
                let lo = i.saturating_sub(window);
                let hi = (i + window + 1).min(len);
                spans[ids[base + i] as usize] = (base + lo, base + hi);
            }
            base += len;
        }
        let mut chain_offsets = Vec::with_capacity(n + 1);
        let mut chain_neighbours = Vec::with_capacity(spans.iter().map(|s| s.1 - s.0).sum());
        chain_offsets.push(0);
        for (lo, hi) in spans {
            chain_neighbours.extend_from_slice(&ids[lo..hi]);
            chain_offsets.push(chain_neighbours.len() as u32);
        }
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        Ok(MetricField {
            field,
            frames: Vec::new(),
            neighbours: Vec::new(),
            k: 0,
            chain_neighbours,
            chain_offsets,
            params: MetricParams {
                hmin,
                hmax: params.hmax.unwrap_or(scale / 10.0).max(hmin),
                eps: params.eps.unwrap_or(hmin),
                band: params.band.unwrap_or(8.0 * hmin),
                gradation: params.gradation.unwrap_or(0.3),
                isotropic: params.isotropic,
                neighbours: params.neighbours,
            },
            noise_estimate: 0.0,
            one_wall_noise: 0.0,
            curve_share: 1.0,
            bbox,
            padding: params.padding,
            max_passes: params.max_passes,
            warm_change: params.warm_change,
            max_vertices: params.max_vertices,
            ms: MeshTimings {
                distance: ms,
                total: ms,
                ..MeshTimings::default()
            },
        })
    }

    /// The chain neighbourhood of sample `i` (empty when it is on no chain).
    pub fn chain_window(&self, i: usize) -> &[u32] {
        match (self.chain_offsets.get(i), self.chain_offsets.get(i + 1)) {
            (Some(&a), Some(&b)) => &self.chain_neighbours[a as usize..b as usize],
            _ => &[],
        }
    }

    /// Adapts a mesh to this field, starting from `start` (a mesh in the same
    /// coordinates, e.g. the previous frame's) when its domain still covers the data's
    /// box padded by half the padding, else from a lattice of the padded box.
    pub fn adapt(&self, start: Option<Mesh>) -> AdaptedMesh {
        self.adapt_from(start)
    }

    /// [`MetricField::adapt`] from the first of `starts` that covers the data (for a
    /// moving sensor: its previous mesh moved into the new frame, then as it was).
    pub fn adapt_from(&self, starts: impl IntoIterator<Item = Mesh>) -> AdaptedMesh {
        let t0 = Instant::now();
        let bbox = self.bbox;
        let diag = bbox.diag();
        let scale = if diag > 0.0 { diag } else { 1.0 };
        let hmin = self.params.hmin;
        let metric = CurveMetric::from_frames(
            &self.field,
            &self.frames,
            &self.neighbours,
            self.k,
            self.params,
        );
        let wanted = bbox.padded(self.padding * scale + 2.0 * hmin);
        // A start mesh will do while the data keep at least half the padding from its
        // edge (a moving shape keeps its mesh until it has drifted that far). Its domain
        // is convex (a box, or a box moved and turned with a moving sensor's frame), so
        // it does when it holds the data's extreme points in 16 directions, each pushed
        // that far out: a turned box that holds the data well need not hold the corners
        // of their axis-aligned box.
        let margin = 0.5 * self.padding * scale + 2.0 * hmin;
        let probes = support_points(self.field.points(), 16, margin);
        let covering = starts.into_iter().find_map(|m| {
            let b = BBox::of(&m.coords)?;
            crate::fem::locate::covers(&m, &probes).then_some((b, m))
        });
        let (local_box, mut mesh, warm) = match covering {
            Some((b, m)) => (b, m, true),
            None => {
                // The lattice holds at most a quarter of the vertex budget, whatever the
                // padding and hmax: max_vertices bounds the whole mesh.
                let size = wanted.size();
                let budget = (self.max_vertices / 4).max(4) as f64;
                let h = self.params.hmax.max((size[0] * size[1] / budget).sqrt());
                (wanted, Mesh::of_box(&wanted, h), false)
            }
        };
        let mut opts = AdaptOptions::default()
            .with_max_passes(self.max_passes)
            .with_max_vertices(self.max_vertices);
        if warm {
            opts.warm = true;
            opts.stop_change = self.warm_change;
            // One sweep follows a mesh already adapted to a nearby metric; a second
            // mostly chases the noise in it (measured: 12% more frames per second on the
            // README's stream, the same accuracy).
            opts.smoothing_sweeps = 1;
        }
        let mut adapter = Adapter::new();
        let report = adapter.adapt(&mut mesh, &metric, &opts);
        let nearest = adapter.nearest().to_vec();
        let stats = mesh_stats(&mesh, adapter.metrics());
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        AdaptedMesh {
            mesh,
            nearest,
            params: self.params,
            domain: local_box,
            warm,
            noise_estimate: self.noise_estimate,
            one_wall_noise: self.one_wall_noise,
            report,
            stats,
            ms: MeshTimings {
                adapt: ms(t0.elapsed()),
                total: self.ms.total + ms(t0.elapsed()),
                ..self.ms
            },
        }
    }
}

/// For each of `directions` directions evenly spread round the circle, the point of
/// `points` farthest along it, pushed `margin` further that way. A convex domain that
/// holds them all holds every point with about `margin` to spare (at least
/// `margin * cos(pi / directions)` in every direction between the probes'; the hull's
/// corners between two probes are within the polygon they span).
pub fn support_points(points: &[Point], directions: usize, margin: f64) -> Vec<Point> {
    (0..directions)
        .filter_map(|k| {
            let a = std::f64::consts::TAU * k as f64 / directions as f64;
            let d = [a.cos(), a.sin()];
            let p = points.iter().copied().max_by(|p, q| {
                (p[0] * d[0] + p[1] * d[1]).total_cmp(&(q[0] * d[0] + q[1] * d[1]))
            })?;
            Some([p[0] + margin * d[0], p[1] + margin * d[1]])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A box turned by 0.1 rad holds data well inside it, though not the corners of the
    /// data's axis-aligned box; a box that leaves a point less than the margin does not.
    #[test]
    fn a_turned_domain_is_judged_by_the_data_not_their_box() {
        let square = BBox {
            min: [-1.0, -1.0],
            max: [1.0, 1.0],
        };
        let mut mesh = Mesh::of_box(&square, 0.5);
        let (s, c) = 0.1f64.sin_cos();
        for p in &mut mesh.coords {
            *p = [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        }
        // A ring of radius 0.95 leaves at least 0.05 to the turned square, whose corner
        // (0.95, 0.95) turns to x = 0.95 (cos 0.1 + sin 0.1) = 1.04, outside.
        let ring: Vec<Point> = (0..100)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 100.0;
                [0.95 * a.cos(), 0.95 * a.sin()]
            })
            .collect();
        let corners = [[0.95, 0.95], [-0.95, 0.95], [-0.95, -0.95], [0.95, -0.95]];
        assert!(!crate::fem::locate::covers(&mesh, &corners));
        assert!(crate::fem::locate::covers(
            &mesh,
            &support_points(&ring, 16, 0.04)
        ));
        assert!(!crate::fem::locate::covers(
            &mesh,
            &support_points(&ring, 16, 0.06)
        ));
    }
}
