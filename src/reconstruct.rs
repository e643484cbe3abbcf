//! The whole method as one call: points in, curves out (DESIGN.md section 1).
//!
//! `reconstruct` runs the stages in coordinates centred on the data (element shapes and
//! the level set then lose no precision to large offsets) and returns curves in data
//! coordinates. Parameters left unset are derived from the data's bounding-box diagonal
//! `D` and the mesh's `hmin`, so results do not depend on the data's units.

use std::time::Instant;

use crate::distance::validate_points;
use crate::error::{Error, Result};
use crate::export::contour::{simplify, zero_isoline};
use crate::fem::locate::locate_all;
use crate::fem::P1Space;
use crate::format::{FrameStats, StageMs};
use crate::geom::{add, sub, BBox, Point, Polyline};
use crate::levelset::init::{self, Init};
use crate::levelset::solver::{LinearSolver, Scheme, SolveReport, Solver, SolverSettings};
use crate::mesh::Mesh;
use crate::meshing::{AdaptedMesh, MeshParams, MetricField};

/// What follows the capture phase on data that does not meet eq. 11 (noisy data).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Settle {
    /// Move the curve to the local median of the data: each vertex near the curve is
    /// shifted by the median of `u` at its nearest samples (enough to span the noise band:
    /// the median count within the band's width, 32 to 512), then renormalized; repeated
    /// while the mean `|u|` at the data improves by 1%.
    #[default]
    Median,
    /// The solver's settle phase: the d-weighted curvature flow without attraction,
    /// keeping the level set with the smallest mean `|u|` at the data.
    Flow,
}

impl std::str::FromStr for Settle {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "median" => Ok(Settle::Median),
            "flow" => Ok(Settle::Flow),
            _ => Err(format!(
                "unknown settle {s:?}: expected \"median\" or \"flow\""
            )),
        }
    }
}

/// Solver parameters; `None` means "derive" (see each field).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct SolverParams {
    /// Time-stepping scheme. Default semi-implicit.
    pub scheme: Scheme,
    /// Attraction `alpha` (eq. 4), an inverse length: the curve can enter concavities
    /// wider than about `2 / alpha`. Default `ALPHA_D / D`.
    pub alpha: Option<f64>,
    /// Semi-implicit time step in units of `hmin`. Default `DT_FACTOR`.
    pub dt_factor: Option<f64>,
    /// Explicit: fraction of the stability bound. Default 0.9.
    pub cfl: f64,
    /// Explicit: per-vertex time steps, each vertex at its own stability bound. Default
    /// true (measured: 7x fewer iterations on the acceptance circle, and a better fit).
    pub local_dt: bool,
    /// Stopping tolerance of eq. 11. Default `hmin`.
    pub eps: Option<f64>,
    /// Renormalize every this many steps (0: never). Default 100 (explicit, as in the
    /// paper) or 5 (semi-implicit).
    pub renormalize_every: Option<usize>,
    /// Iteration cap. Default 200,000 (explicit) or 2,000 (semi-implicit).
    pub max_iterations: Option<usize>,
    /// A solver phase ends when the mean residual improves by less than 1% over this
    /// many steps. Default 1,000 (explicit) or 10 (semi-implicit).
    pub patience: Option<usize>,
    /// The patience of a frame warm-started at the data (see [`solve`]): its curve is
    /// already in place, so the capture phase only has to confirm it. Default
    /// `patience / 2`.
    pub warm_patience: Option<usize>,
    /// Narrow band half-width in units of `D`: only vertices with `|u|` below it move.
    /// Default 0.1; 0 disables the band.
    pub band: f64,
    /// The semi-implicit step's Krylov solver. Default conjugate gradients.
    pub linear: LinearSolver,
    /// Its relative residual reduction per step. Default 1e-2.
    pub linear_tolerance: f64,
    /// Its iterations per step at most. Default 10.
    pub linear_max_iterations: usize,
    /// The starting curve. Default [`Init::Medial`].
    pub init: Init,
    /// What follows the capture phase on noisy data. Default [`Settle::Median`].
    pub settle: Settle,
    /// Tube start: the tube radius. Default: twice the 95th percentile of the data's
    /// nearest-neighbour spacing, and at least `2 hmin`.
    pub tube: Option<f64>,
    /// Gap between the data and the starting curve, in units of `D`. Default 0.05.
    pub margin: f64,
}

/// Default `alpha * D`.
pub const ALPHA_D: f64 = 10.0;
/// Default semi-implicit step in units of `hmin`.
pub const DT_FACTOR: f64 = 10.0;

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            scheme: Scheme::SemiImplicit,
            alpha: None,
            dt_factor: None,
            cfl: 0.9,
            local_dt: true,
            eps: None,
            renormalize_every: None,
            max_iterations: None,
            patience: None,
            warm_patience: None,
            band: 0.1,
            linear: LinearSolver::Cg,
            linear_tolerance: 1e-2,
            linear_max_iterations: 10,
            init: Init::Medial,
            settle: Settle::Median,
            tube: None,
            margin: 0.05,
        }
    }
}

impl SolverParams {
    /// Sets the scheme.
    pub fn with_scheme(mut self, s: Scheme) -> Self {
        self.scheme = s;
        self
    }
    /// Sets the starting curve.
    pub fn with_init(mut self, i: Init) -> Self {
        self.init = i;
        self
    }
    /// Sets `alpha`.
    pub fn with_alpha(mut self, a: f64) -> Self {
        self.alpha = Some(a);
        self
    }
    /// Sets the stopping tolerance.
    pub fn with_eps(mut self, e: f64) -> Self {
        self.eps = Some(e);
        self
    }

    /// Checks the values that are set; every problem is listed.
    pub fn validate(&self) -> std::result::Result<(), Vec<String>> {
        let mut problems = Vec::new();
        crate::error::check_positive(&mut problems, "solver.alpha", self.alpha);
        crate::error::check_positive(&mut problems, "solver.dt_factor", self.dt_factor);
        crate::error::check_positive(&mut problems, "solver.eps", self.eps);
        crate::error::check_positive(&mut problems, "solver.tube", self.tube);
        if !(self.cfl > 0.0 && self.cfl <= 1.0) {
            problems.push(format!("solver.cfl = {}: must be in (0, 1]", self.cfl));
        }
        if !(self.margin.is_finite() && self.margin > 0.0 && self.margin <= 0.15) {
            problems.push(format!(
                "solver.margin = {}: must be in (0, 0.15] (the mesh is padded by 0.2 D)",
                self.margin
            ));
        }
        if !(self.band.is_finite() && self.band >= 0.0) {
            problems.push(format!(
                "solver.band = {}: must be a finite number >= 0",
                self.band
            ));
        }
        if !(self.linear_tolerance > 0.0 && self.linear_tolerance < 1.0) {
            problems.push(format!(
                "solver.linear_tolerance = {}: must be in (0, 1)",
                self.linear_tolerance
            ));
        }
        if !(1..=1000).contains(&self.linear_max_iterations) {
            problems.push(format!(
                "solver.linear_max_iterations = {}: must be in 1..=1000",
                self.linear_max_iterations
            ));
        }
        if self.max_iterations == Some(0) {
            problems.push("solver.max_iterations = 0: must be at least 1".into());
        }
        if self.patience == Some(0) {
            problems.push("solver.patience = 0: must be at least 1".into());
        }
        if self.warm_patience == Some(0) {
            problems.push("solver.warm_patience = 0: must be at least 1".into());
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }

    /// The concrete settings for data of diagonal `diag` on a mesh of smallest size
    /// `hmin`.
    pub fn resolve(&self, diag: f64, hmin: f64) -> SolverSettings {
        let explicit = self.scheme == Scheme::Explicit;
        let dt = self.dt_factor.unwrap_or(DT_FACTOR) * hmin;
        SolverSettings {
            scheme: self.scheme,
            alpha: self.alpha.unwrap_or(ALPHA_D / diag),
            dt,
            cfl: self.cfl,
            local_dt: self.local_dt,
            eps: self.eps.unwrap_or(hmin),
            tube: 4.0 * hmin,
            settle_flow: self.settle == Settle::Flow,
            band: if self.band > 0.0 {
                self.band * diag
            } else {
                f64::INFINITY
            },
            renormalize_every: self
                .renormalize_every
                .unwrap_or(if explicit { 100 } else { 5 }),
            max_iterations: self
                .max_iterations
                .unwrap_or(if explicit { 200_000 } else { 2_000 }),
            check_every: if explicit { 10 } else { 1 },
            patience: self.patience.unwrap_or(if explicit { 1_000 } else { 10 }),
            d_floor: 1e-6 * hmin,
            cg_tol: self.linear_tolerance,
            cg_max: self.linear_max_iterations,
            linear: self.linear,
        }
    }
}

/// Export parameters.
#[derive(Clone, Debug, PartialEq, Default)]
#[non_exhaustive]
pub struct ExportParams {
    /// Douglas-Peucker tolerance in data units; 0 keeps every isoline vertex. Default 0.
    pub simplify: f64,
    /// Closed loops enclosing less area are dropped. Default `pi (3 hmin)^2`; 0 keeps all.
    pub min_area: Option<f64>,
}

/// Everything `reconstruct` needs.
#[derive(Clone, Debug, PartialEq, Default)]
#[non_exhaustive]
pub struct Params {
    /// The mesh.
    pub mesh: MeshParams,
    /// The solver.
    pub solver: SolverParams,
    /// The export.
    pub export: ExportParams,
}

impl Params {
    /// Parameters from their three parts.
    pub fn new(mesh: MeshParams, solver: SolverParams, export: ExportParams) -> Params {
        Params {
            mesh,
            solver,
            export,
        }
    }
}

/// A reconstruction: the curves, and the mesh and level set they come from.
#[derive(Debug)]
pub struct Reconstruction {
    /// The zero isoline, in data coordinates: closed loops counter-clockwise around
    /// inside regions, clockwise around holes; open chains where it leaves the mesh.
    pub polylines: Vec<Polyline>,
    /// The adapted mesh, in data coordinates.
    pub mesh: Mesh,
    /// The level set at the mesh vertices (negative inside).
    pub u: Vec<f64>,
    /// Per-frame statistics (the `stats` of a result record).
    pub stats: FrameStats,
    /// The solver's report.
    pub solve: SolveReport,
    /// The solver settings used.
    pub settings: SolverSettings,
    /// The estimated noise of the data (median local-fit residual).
    pub noise_estimate: f64,
}

/// Reconstructs curves from `points`.
///
/// ```
/// use isoline::reconstruct::{reconstruct, Params};
/// let pts: Vec<[f64; 2]> = (0..300)
///     .map(|i| {
///         let a = i as f64 * std::f64::consts::TAU / 300.0;
///         [0.5 + 0.4 * a.cos(), 0.5 + 0.4 * a.sin()]
///     })
///     .collect();
/// let r = reconstruct(&pts, &Params::default()).unwrap();
/// assert_eq!(r.polylines.len(), 1);
/// assert!(r.polylines[0].closed && r.polylines[0].signed_area() > 0.0);
/// ```
pub fn reconstruct(points: &[Point], params: &Params) -> Result<Reconstruction> {
    reconstruct_warm(points, params, None)
}

/// [`reconstruct`] warm-started from `previous`, the reconstruction of an earlier frame of
/// the same stream: the five stages [`prepare`], [`adapt`], [`solve`], [`renormalize`]
/// and [`export`] in turn, with the previous frame's mesh and level set (see [`solve`]
/// for when the warm start is taken). `stats.warm_start` says whether it was.
pub fn reconstruct_warm(
    points: &[Point],
    params: &Params,
    previous: Option<&Reconstruction>,
) -> Result<Reconstruction> {
    let _span = tracing::debug_span!("reconstruct", points = points.len()).entered();
    let prepared = prepare(points, params)?;
    let adapted = adapt(&prepared, previous.map(|p| &p.mesh));
    let warm = previous.map(|p| Previous {
        mesh: &p.mesh,
        u: &p.u,
        residual: p.stats.residual,
    });
    let mut solved = solve(&prepared, &adapted, warm, params);
    renormalize(&adapted.mesh, &mut solved);
    Ok(export(&prepared, adapted, solved, &params.export))
}

/// The distance stage's product: one frame's points centred on their bounding box, their
/// kd-tree and the local frames of the metric.
#[derive(Debug)]
pub struct Prepared {
    /// Input points (before duplicates are merged).
    pub points: usize,
    /// Centre of the data's bounding box: every later stage works in coordinates
    /// relative to it, so that element shapes lose no precision to large offsets.
    pub center: Point,
    /// Diagonal `D` of the data's bounding box.
    pub diag: f64,
    /// The points, centred.
    pub local: Vec<Point>,
    /// Their distance field and metric frames.
    pub metric: MetricField,
    /// Milliseconds spent.
    pub ms: f64,
}

/// The warm start a frame may take: the previous frame's mesh (in data coordinates), its
/// renormalized level set and its eq. 11 residual.
#[derive(Clone, Copy, Debug)]
pub struct Previous<'a> {
    /// The previous frame's mesh, in data coordinates.
    pub mesh: &'a Mesh,
    /// Its level set.
    pub u: &'a [f64],
    /// Its eq. 11 residual.
    pub residual: f64,
}

/// The solve stage's product: the level set on the adapted mesh and how it was found.
#[derive(Debug)]
pub struct Solved {
    /// The level set at the mesh vertices (centred coordinates, negative inside).
    pub u: Vec<f64>,
    /// The P1 space of the mesh (reused by renormalization).
    pub space: P1Space,
    /// The solver's report (its `ms_solve` includes the median settle).
    pub report: SolveReport,
    /// The settings used.
    pub settings: SolverSettings,
    /// Whether the level set started from the previous frame's.
    pub warm_start: bool,
    /// Whether `u` is already the signed distance to its zero isoline over the whole mesh
    /// (the median settle's last accepted round leaves it so).
    pub renormalized: bool,
    /// Milliseconds: distances at the vertices and locating the data.
    pub ms_distance: f64,
    /// Milliseconds: the whole solve stage.
    pub ms: f64,
    /// Milliseconds of fast marching outside the solver's loop (warm start, final pass).
    pub ms_renormalize: f64,
}

/// The distance stage: validates the points, centres them and builds their distance
/// field and metric frames.
pub fn prepare(points: &[Point], params: &Params) -> Result<Prepared> {
    let t0 = Instant::now();
    validate_points(points)?;
    params.solver.validate().map_err(|problems| Error::Config {
        path: "solver parameters".into(),
        problems,
    })?;
    let bbox = BBox::of(points).ok_or(Error::EmptyPointSet)?;
    let center = bbox.center();
    let local: Vec<Point> = points.iter().map(|&p| sub(p, center)).collect();
    let diag = bbox.diag();
    if diag <= 0.0 {
        return Err(Error::CoincidentPoints {
            count: points.len(),
        });
    }
    let mut mesh_params = params.mesh.clone();
    if params.solver.init == Init::Circle {
        // The paper's circle must fit in the meshed box.
        let margin = params.solver.margin * diag;
        let c = BBox::of(&local).expect("non-empty").center();
        let r = local
            .iter()
            .map(|&p| crate::geom::dist(p, c))
            .fold(0.0, f64::max)
            + margin;
        let half = bbox.size()[0].min(bbox.size()[1]) / 2.0;
        mesh_params.padding = mesh_params.padding.max((r - half) / diag + 0.05);
    }
    let metric = MetricField::new(&local, &mesh_params)?;
    Ok(Prepared {
        points: points.len(),
        center,
        diag,
        local,
        metric,
        ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// The adapt stage: an anisotropic mesh of the frame (centred coordinates), adapted from
/// `previous` (a mesh in data coordinates, the previous frame's) when it still covers the
/// data, else from a lattice.
pub fn adapt(prepared: &Prepared, previous: Option<&Mesh>) -> AdaptedMesh {
    let start = previous.map(|m| {
        let mut m = m.clone();
        for c in &mut m.coords {
            *c = sub(*c, prepared.center);
        }
        m
    });
    prepared.metric.adapt(start)
}

/// The solve stage: the level set on the adapted mesh, from the previous frame's when
/// that is a good start, else from the configured one, evolved by the solver and, on
/// noisy data, settled on the data's median.
///
/// The previous level set is interpolated onto the new mesh (each vertex located in the
/// old mesh by walking). Where it already lies within the median settle's reach of every
/// new sample (`4 sigma + 4 hmin`, sigma the noise estimate), it is used as it is: the
/// capture phase then stagnates within its (warm) patience window and the settle moves
/// the curve the rest of the way, in either direction. Otherwise, while it is
/// no farther from the data than a cold tube start would be (twice the larger of the tube
/// radius and the previous residual), it is offset outward past every sample, because
/// the evolution only moves the curve inward. Farther (a jump, a restarted stream, a mesh
/// that no longer covers the data): cold start.
pub fn solve(
    prepared: &Prepared,
    adapted: &AdaptedMesh,
    previous: Option<Previous<'_>>,
    params: &Params,
) -> Solved {
    let t0 = Instant::now();
    let mesh = &adapted.mesh;
    let field = &prepared.metric.field;
    let hmin = adapted.params.hmin;
    let space = P1Space::new(mesh);
    let pts = field.points();
    let (dist, nearest): (Vec<f64>, Vec<u32>) = if adapted.nearest.len() == mesh.coords.len()
        && adapted.nearest.iter().all(|&j| (j as usize) < pts.len())
    {
        mesh.coords
            .iter()
            .zip(&adapted.nearest)
            .map(|(&x, &j)| (crate::geom::dist(x, pts[j as usize]), j))
            .unzip()
    } else {
        field
            .nearest_all(&mesh.coords)
            .iter()
            .map(|n| (n.dist, n.index))
            .unzip()
    };
    // The field's points: the data with exact duplicates merged, so that the stopping
    // test and the median settle weigh each sample once.
    let data = locate_all(mesh, field.points());
    let ms_distance = t0.elapsed().as_secs_f64() * 1e3;

    let mut settings = params.solver.resolve(prepared.diag, hmin);
    let margin = params.solver.margin * prepared.diag;
    let tube_radius = params
        .solver
        .tube
        .unwrap_or_else(|| init::tube_radius(field, 2.0 * hmin));
    let settle_width = 4.0 * adapted.noise_estimate + 4.0 * hmin;
    let mut fm = crate::redistance::Redistancer::new();
    let mut ms_renormalize = 0.0;
    let warm = previous.and_then(|prev| {
        let mut old_mesh = prev.mesh.clone();
        for c in &mut old_mesh.coords {
            *c = sub(*c, prepared.center);
        }
        let bbox_old = BBox::of(&old_mesh.coords)?;
        if !mesh.coords.iter().all(|&c| bbox_old.contains(c)) {
            return None;
        }
        // The previous level set was renormalized: interpolated, it is a signed distance
        // to within the interpolation error, and the solver renormalizes on its own.
        let at = locate_all(&old_mesh, &mesh.coords);
        let mut u: Vec<f64> = at
            .iter()
            .map(|l| l.interpolate(&old_mesh, prev.u))
            .collect();
        let (res, _) = crate::levelset::solver::residual(mesh, &data, &u);
        let near = res <= settle_width && params.solver.settle == Settle::Median;
        // A cold tube start begins about one tube radius from the data, and the previous
        // frame ended at `prev.residual` from its own.
        let keep = near || res <= 2.0 * tube_radius.max(prev.residual) + settings.eps;
        tracing::debug!(residual = res, near, keep, "warm start");
        if !near {
            // u is a distance, so subtracting a constant offsets the curve outward.
            let offset = res + settings.eps;
            u.iter_mut().for_each(|x| *x -= offset);
        }
        keep.then_some((u, near))
    });
    let warm = warm.map(|(u, near)| {
        if near {
            settings.patience = params
                .solver
                .warm_patience
                .unwrap_or((settings.patience / 2).max(1));
        }
        u
    });
    let warm_start = warm.is_some();
    let mut u = match (warm, params.solver.init) {
        (Some(u), _) => u,
        (None, init @ (Init::Tube | Init::Medial)) => {
            let t = Instant::now();
            let start = if init == Init::Medial {
                let u = init::medial(mesh, &space, &dist, tube_radius, &mut fm);
                if u.is_some() && params.solver.settle == Settle::Median {
                    // Like a warm start at the data: nothing to capture, the settle
                    // places the curve.
                    settings.patience = params
                        .solver
                        .warm_patience
                        .unwrap_or((settings.patience / 2).max(1));
                }
                u
            } else {
                // The pinned vertices must lie inside the starting curve, or nothing
                // moves.
                settings.tube = settings.tube.min(0.5 * tube_radius);
                init::tube(mesh, |v| space.ring(v), &dist, tube_radius)
            };
            ms_renormalize += t.elapsed().as_secs_f64() * 1e3;
            match start {
                Some(mut u) => {
                    let t = Instant::now();
                    fm.run(mesh, &space, &mut u, f64::INFINITY);
                    ms_renormalize += t.elapsed().as_secs_f64() * 1e3;
                    u
                }
                None => {
                    tracing::debug!(tube_radius, "the tube encloses nothing: box start");
                    init::enclosing(Init::Box, &prepared.local, margin, &mesh.coords)
                }
            }
        }
        (None, other) => init::enclosing(other, &prepared.local, margin, &mesh.coords),
    };
    let mut report = Solver::new().solve(mesh, &space, &dist, &data, &mut u, &settings);
    let mut renormalized = false;
    if params.solver.settle == Settle::Median {
        let t = Instant::now();
        let (res, mean, moved) = center_on_data(
            mesh,
            &space,
            &prepared.metric,
            &data,
            &nearest,
            &mut u,
            settle_width,
        );
        renormalized = moved;
        report.residual = res;
        report.mean_residual = mean;
        // Rounds are kept by the mean distance, so the maximum can move either way.
        let converged = res < settings.eps;
        if converged != report.converged {
            report.converged = converged;
            report.stop = if converged {
                crate::levelset::StopReason::Converged
            } else {
                crate::levelset::StopReason::Settled
            };
        }
        report.ms_solve += t.elapsed().as_secs_f64() * 1e3;
    }
    Solved {
        u,
        space,
        report,
        settings,
        warm_start,
        renormalized,
        ms_distance,
        ms: t0.elapsed().as_secs_f64() * 1e3,
        ms_renormalize,
    }
}

/// The renormalize stage: `u` becomes the signed distance to its zero isoline over the
/// whole mesh (the solver's own passes stop at twice its narrow band), which is what the
/// next frame's warm start interpolates. Nothing to do when the median settle already
/// left it so.
pub fn renormalize(mesh: &Mesh, solved: &mut Solved) {
    if solved.renormalized {
        return;
    }
    let t = Instant::now();
    crate::redistance::Redistancer::new().run(mesh, &solved.space, &mut solved.u, f64::INFINITY);
    solved.renormalized = true;
    solved.ms_renormalize += t.elapsed().as_secs_f64() * 1e3;
}

/// The export stage: the zero isoline as polylines in data coordinates, small specks
/// dropped and optionally simplified, with the frame's statistics.
pub fn export(
    prepared: &Prepared,
    adapted: AdaptedMesh,
    solved: Solved,
    params: &ExportParams,
) -> Reconstruction {
    let t0 = Instant::now();
    let center = prepared.center;
    let hmin = adapted.params.hmin;
    let mut mesh = adapted.mesh;
    let u = solved.u;
    let mut polylines = zero_isoline(&mesh, &u, 1e-9 * prepared.diag);
    // Loops smaller than a disc of radius 3 hmin are below what the mesh resolves: specks
    // left where the level set grazes zero between samples.
    let min_area = params
        .min_area
        .unwrap_or(std::f64::consts::PI * 9.0 * hmin * hmin);
    polylines.retain(|p| !p.closed || p.signed_area().abs() >= min_area);
    if params.simplify > 0.0 {
        polylines = polylines
            .iter()
            .map(|p| simplify(p, params.simplify))
            .collect();
    }
    for pl in &mut polylines {
        for p in &mut pl.points {
            *p = add(*p, center);
        }
    }
    for p in &mut mesh.coords {
        *p = add(*p, center);
    }
    let report = solved.report;
    let ms_export = t0.elapsed().as_secs_f64() * 1e3;
    let renormalize = report.ms_renormalize + solved.ms_renormalize;
    let ms = StageMs {
        distance: prepared.ms + solved.ms_distance,
        adapt: adapted.ms.adapt,
        solve: solved.ms - solved.ms_distance - solved.ms_renormalize - report.ms_renormalize,
        renormalize,
        export: ms_export,
        total: 0.0,
        latency: None,
    };
    let ms = StageMs {
        total: ms.distance + ms.adapt + ms.solve + ms.renormalize + ms.export,
        ..ms
    };
    let stats = FrameStats {
        points: prepared.points,
        vertices: mesh.num_vertices(),
        triangles: mesh.num_triangles(),
        iterations: report.iterations,
        residual: report.residual,
        converged: report.converged,
        warm_start: solved.warm_start,
        ms,
        stop: report.stop.as_str().into(),
        scheme: solved.settings.scheme.to_string(),
        linear_iterations: report.linear_iterations,
        renormalizations: report.renormalizations,
        hmin,
        eps: solved.settings.eps,
    };
    Reconstruction {
        polylines,
        mesh,
        u,
        stats,
        solve: report,
        settings: solved.settings,
        noise_estimate: adapted.noise_estimate,
    }
}

/// Reconstructs one input frame into its result record (curves and stats, or the error),
/// with a tracing span carrying the stream and frame ids. The reconstruction itself is
/// returned too, for drawing.
pub fn reconstruct_frame(
    frame: &crate::format::FrameRecord,
    params: &Params,
) -> (crate::format::ResultRecord, Option<Reconstruction>) {
    use crate::format::{PolylineJson, ResultRecord};
    let span = tracing::info_span!(
        "frame",
        stream = frame.stream.as_deref().unwrap_or(""),
        frame = frame.frame
    );
    let _e = span.enter();
    match reconstruct(&frame.points, params) {
        Ok(r) => (
            ResultRecord {
                stream: frame.stream.clone(),
                frame: frame.frame,
                polylines: Some(r.polylines.iter().map(PolylineJson::from).collect()),
                stats: Some(r.stats.clone()),
                ..Default::default()
            },
            Some(r),
        ),
        Err(e) => (
            ResultRecord {
                stream: frame.stream.clone(),
                frame: frame.frame,
                error: Some(e.to_string()),
                ..Default::default()
            },
            None,
        ),
    }
}

/// Moves the zero level set to the local median of the data: each vertex within `width`
/// of it is lowered by the median of `u` over the `k` nearest samples of its nearest
/// sample (`nearest[v]`; `data` holds the locations of `field`'s points, in its order),
/// then `u` is renormalized; repeated (at most 4 times) while the mean `|u|` at the data
/// improves by 1%. Returns the eq. 11 residual and the mean `|u|` at the data afterwards,
/// and whether any round was kept (`u` is then a signed distance over the whole mesh).
///
/// The samples' neighbourhoods are found once, and only for the samples that are the
/// nearest of a vertex within `2 width` of the curve at the start (a vertex that comes
/// within `width` later without one keeps its value): the data do not move between
/// rounds, so a round costs one median per such sample and one fast marching.
fn center_on_data(
    mesh: &Mesh,
    space: &P1Space,
    metric: &MetricField,
    data: &[crate::fem::locate::Location],
    nearest: &[u32],
    u: &mut [f64],
    width: f64,
) -> (f64, f64, bool) {
    use rayon::prelude::*;
    let field = &metric.field;
    // Enough neighbours to span the noise band: the median count of samples within
    // `width` of a sample (checked on up to 64 of them), at least 32, at most 512.
    let pts = field.points();
    let step = (pts.len() / 64).max(1);
    let mut counts: Vec<usize> = pts
        .iter()
        .step_by(step)
        .map(|&p| field.count_within(p, width))
        .collect();
    counts.sort_unstable();
    let k = counts
        .get(counts.len() / 2)
        .copied()
        .unwrap_or(32)
        .clamp(32, 512)
        .min(pts.len());
    // Only the samples that are the nearest of a vertex near the curve need a median:
    // on dense data (200k samples, 512 neighbours each) the others would dominate.
    const NONE: u32 = u32::MAX;
    let mut slot = vec![NONE; pts.len()];
    let mut needed = Vec::new();
    for (&j, &uv) in nearest.iter().zip(u.iter()) {
        if uv.abs() <= 2.0 * width && slot[j as usize] == NONE {
            slot[j as usize] = needed.len() as u32;
            needed.push(j);
        }
    }
    // The metric's fits found each sample's nearest neighbours already; the first `k` of
    // them will do when there are that many. Allocation is fine here: once per frame.
    let found = if k <= metric.k {
        Vec::new()
    } else {
        let mut nb = vec![0u32; needed.len() * k];
        nb.par_chunks_mut(k)
            .zip(needed.par_iter())
            .for_each_init(Vec::new, |buf, (out, &j)| {
                field.nearest_k(pts[j as usize], k, buf);
                out.copy_from_slice(&buf[..k]);
            });
        nb
    };
    let list = |s: usize| -> &[u32] {
        if found.is_empty() {
            let at = needed[s] as usize * metric.k;
            &metric.neighbours[at..at + k]
        } else {
            &found[s * k..(s + 1) * k]
        }
    };
    let mut at = vec![0.0; pts.len()];
    let mut medians = vec![0.0; needed.len()];
    let mut trial = u.to_vec();
    let mut fm = crate::redistance::Redistancer::new();
    let (mut best_res, mut best) = crate::levelset::solver::residual(mesh, data, u);
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
                vals.extend(list(s).iter().map(|&j| at[j as usize]));
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
        let (_, before) = crate::levelset::solver::residual(mesh, data, &trial);
        tracing::debug!(mean = before, best, "center");
        if before >= best * 0.99 {
            break;
        }
        fm.run(mesh, space, &mut trial, f64::INFINITY);
        let (res, mean) = crate::levelset::solver::residual(mesh, data, &trial);
        if mean >= best {
            break;
        }
        best = mean;
        best_res = res;
        u.copy_from_slice(&trial);
        moved = true;
    }
    (best_res, best, moved)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{generate, Shape, SynthParams};

    fn stream() -> Vec<crate::synth::SynthFrame> {
        let mut p = SynthParams::new(Shape::Ellipse);
        p.points = 1000;
        p.noise = 0.003;
        p.frames = 4;
        p.motion = 0.003;
        p.seed = 3;
        generate(&p).unwrap()
    }

    fn hausdorff(r: &Reconstruction, truth: &[crate::geom::Polyline]) -> f64 {
        crate::eval::compare(&r.polylines, truth, None)
            .hausdorff
            .unwrap()
    }

    /// Warm frames meet the one-shot bound 3 sigma + 2 hmin, and so does a frame after a
    /// jump of 40 hmin (far beyond the mesh's fine band, within its domain): its level set
    /// starts cold, and its mesh, adapted from the old one, is about as fine as a cold
    /// frame's.
    #[test]
    fn warm_frames_and_a_jump_stay_within_the_one_shot_bound() {
        let frames = stream();
        let params = Params::new(
            MeshParams::default().with_hmin(0.002),
            SolverParams::default(),
            ExportParams::default(),
        );
        let bound = 3.0 * 0.003 + 2.0 * 0.002;
        let mut prev = reconstruct(&frames[0].points, &params).unwrap();
        for f in &frames[1..] {
            let r = reconstruct_warm(&f.points, &params, Some(&prev)).unwrap();
            assert!(r.stats.warm_start, "frame {}", f.frame);
            let h = hausdorff(&r, &f.truth);
            assert!(h <= bound, "frame {}: {h} > {bound}", f.frame);
            prev = r;
        }
        let jump = [0.08, 0.0];
        let last = frames.last().unwrap();
        let moved: Vec<Point> = last.points.iter().map(|&p| add(p, jump)).collect();
        let mut truth = last.truth.clone();
        truth
            .iter_mut()
            .flat_map(|pl| pl.points.iter_mut())
            .for_each(|p| *p = add(*p, jump));
        let r = reconstruct_warm(&moved, &params, Some(&prev)).unwrap();
        assert!(!r.stats.warm_start);
        let h = hausdorff(&r, &truth);
        assert!(h <= bound, "after the jump: {h} > {bound}");
        let cold = reconstruct(&moved, &params).unwrap();
        let ratio = r.stats.vertices as f64 / cold.stats.vertices as f64;
        assert!(
            (0.8..1.25).contains(&ratio),
            "{} vs {} cold",
            r.stats.vertices,
            cold.stats.vertices
        );
    }
}
