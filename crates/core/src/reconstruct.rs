//! The whole method as one call: points in, curves out (docs/method.md).
//!
//! This module only runs the stages in order and moves data between them; each stage's
//! algorithm lives in its own module ([`mod@crate::field`] for the distance field
//! and the adapted mesh, [`mod@crate::levelset::evolve`] for the level set,
//! [`mod@crate::export`] for the curves). `reconstruct` runs them in coordinates centred
//! on the data (element shapes and the level set then lose no precision to large
//! offsets) and returns curves in data coordinates. Parameters left unset are derived
//! from the data's bounding-box diagonal `D` and the mesh's `hmin`, so results do not
//! depend on the data's units.

use rayon::prelude::*;
use std::borrow::Cow;
use std::time::Instant;

use crate::distance::validate_points;
use crate::error::{Error, Result};
use crate::export::support::Feature;
use crate::export::ExportParams;
use crate::field::{AdaptedMesh, MeshParams, MetricField};
use crate::geom::{BBox, Placement, Point, Polyline};
use crate::levelset::evolve::{self, LevelSet, Solved};
use crate::levelset::init::Init;
use crate::levelset::solver::SolveReport;
use crate::levelset::warm::Previous;
use crate::levelset::SolverParams;
use crate::mesh::Mesh;
use crate::scan::{Analysis, Scan, ScanParams};
use crate::stats::{StageMs, Stats, WindowStats};
use crate::warning::Warning;

pub use crate::mesh::metric::AREA_SHARE;

pub use crate::levelset::evolve::renormalize;

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
    /// How scan frames are read.
    pub scan: ScanParams,
}

impl Params {
    /// The same parameters with every length multiplied by `s` (into other units).
    pub fn scaled(&self, s: f64) -> Params {
        Params {
            mesh: self.mesh.scaled(s),
            solver: self.solver.scaled(s),
            export: self.export.scaled(s),
            scan: self.scan.scaled(s),
        }
    }

    /// Parameters from their three parts (and the default scan reading).
    pub fn new(mesh: MeshParams, solver: SolverParams, export: ExportParams) -> Params {
        Params {
            mesh,
            solver,
            export,
            scan: ScanParams::default(),
        }
    }
}

/// A reconstruction: the curves, and the mesh and level set they come from.
#[derive(Debug)]
pub struct Reconstruction {
    /// The curves, in data coordinates: the zero isoline's closed loops counter-clockwise
    /// around inside regions, clockwise around holes, and open chains where it leaves
    /// the mesh (scans: cut to the returns' support); then, for point clouds, open
    /// strokes along samples no loop explains.
    pub polylines: Vec<Polyline>,
    /// The adapted mesh, in data coordinates.
    pub mesh: Mesh,
    /// The level set at the mesh vertices (negative inside).
    pub u: Vec<f64>,
    /// Per-frame statistics (the `stats` of a result record).
    pub stats: Stats,
    /// The solver's report (lengths in the local units of the frame's placement).
    pub(crate) solve: SolveReport,
    /// The 90th percentile of `|u|` at the data, in data units: how far the level set's
    /// zero isoline is from the data, robustly.
    pub spread: f64,
    /// The estimated noise of the data (median local-fit residual; for a scan, the range
    /// noise).
    pub noise_estimate: f64,
    /// Scan frames: the clusters of returns that no curve explains; point clouds: the
    /// outliers (samples with no curve's neighbourhood, one each). In data coordinates.
    pub features: Vec<Feature>,
    /// Whether the data enclosed anything: false for a drawing of open strokes (the
    /// level set then started from the box round them).
    pub enclosed: bool,
    /// What only a point cloud's or only a scan's result holds.
    pub kind: FrameKind,
    /// What is wrong with the result, if anything.
    pub warnings: Vec<Warning>,
}

/// What a reconstruction holds that depends on the frame it came from: a point cloud's
/// strokes meet at junctions, a scan's beams swept a free space. One or the other, never
/// both.
#[derive(Clone, Debug, PartialEq)]
pub enum FrameKind {
    /// A point cloud (a drawing, a contour, a digitized shape).
    Cloud {
        /// Where open strokes meet, and which of the polylines meet there (the strokes of
        /// a drawing).
        junctions: Vec<crate::repair::strokes::Junction>,
    },
    /// A scanner's frame.
    Scan {
        /// Where the sensor was, in data coordinates.
        sensor: Point,
        /// The boundary of the free space its rays swept, in data coordinates.
        free_space: Polyline,
    },
}

impl Reconstruction {
    /// A point cloud's junctions (none for a scan).
    pub fn junctions(&self) -> &[crate::repair::strokes::Junction] {
        match &self.kind {
            FrameKind::Cloud { junctions } => junctions,
            FrameKind::Scan { .. } => &[],
        }
    }

    /// A scan's sensor position and the boundary of the free space its rays swept (none
    /// for a point cloud).
    pub fn free_space(&self) -> Option<(Point, &Polyline)> {
        match &self.kind {
            FrameKind::Scan { sensor, free_space } => Some((*sensor, free_space)),
            FrameKind::Cloud { .. } => None,
        }
    }

    /// This frame as the next frame's warm start takes it.
    pub fn as_previous(&self) -> Previous<'_> {
        Previous {
            mesh: &self.mesh,
            u: &self.u,
            spread: self.spread,
            near: self.solve.near,
            enclosed: self.enclosed,
        }
    }
}

/// Reconstructs curves from `points`.
///
/// ```
/// use isoline_core::{reconstruct, Params};
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
    reconstruct_with(points, None, params, None)
}

/// Reconstructs the walls a scanner saw: open curves along the returns, with the free
/// space (the sensor's side) on their left; returns no curve explains are
/// [`Reconstruction::features`].
///
/// ```
/// use isoline_core::{reconstruct_scan, LaserScan, Params, Scan};
/// // A wall 2 m in front of a sensor at the origin, seen over 90 degrees.
/// let n = 181;
/// let ranges: Vec<Option<f64>> = (0..n)
///     .map(|i| {
///         let a = -std::f64::consts::FRAC_PI_4 + i as f64 * (std::f64::consts::FRAC_PI_2 / 180.0);
///         Some(2.0 / a.cos())
///     })
///     .collect();
/// let scan = Scan::from_laser(&LaserScan {
///     origin: [0.0, 0.0],
///     angle_min: -std::f64::consts::FRAC_PI_4,
///     angle_increment: std::f64::consts::FRAC_PI_2 / 180.0,
///     ranges: &ranges,
///     range_min: 0.1,
///     range_max: 10.0,
/// })
/// .unwrap();
/// let r = reconstruct_scan(&scan, &Params::default()).unwrap();
/// assert_eq!(r.polylines.len(), 1);
/// let wall = &r.polylines[0];
/// assert!(!wall.closed);
/// // Free side on the left: the wall runs from y < 0 to y > 0 at x = 2.
/// assert!(wall.points[0][1] < wall.points.last().unwrap()[1]);
/// assert!(wall.points.iter().all(|p| (p[0] - 2.0).abs() < 0.01));
/// ```
pub fn reconstruct_scan(scan: &Scan, params: &Params) -> Result<Reconstruction> {
    reconstruct_with(&scan.returns(), Some(scan), params, None)
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
    reconstruct_with(points, None, params, previous)
}

/// The stages in turn on `points`, seen by `scan` when the frame has a sensor (its
/// returns are then `points`), warm-started from `previous`.
pub fn reconstruct_with(
    points: &[Point],
    scan: Option<&Scan>,
    params: &Params,
    previous: Option<&Reconstruction>,
) -> Result<Reconstruction> {
    on_pool(|| reconstruct_here(points, scan, params, previous))
}

/// Runs `f` on a thread of rayon's pool, as one job: a stage's parallel loops, called
/// from a thread outside the pool (a daemon stage's, the caller's), would each be sent
/// to the pool and waited for, and on the real scans that traffic cost a fifth of a
/// frame (a 1,080-beam frame on one thread: 14.3 ms from outside, 11.5 ms from within).
/// From within the pool it runs `f` at once.
fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

fn reconstruct_here(
    points: &[Point],
    scan: Option<&Scan>,
    params: &Params,
    previous: Option<&Reconstruction>,
) -> Result<Reconstruction> {
    let _span = tracing::debug_span!("reconstruct", points = points.len()).entered();
    let prepared = prepare(points, scan, params)?;
    let adapted = adapt(&prepared, previous.map(|p| &p.mesh));
    let warm = previous.map(Reconstruction::as_previous);
    let mut solved = solve(&prepared, &adapted, warm);
    renormalize(&adapted.mesh, &mut solved);
    Ok(export(&prepared, adapted, solved))
}

/// The distance stage's product: one frame's points centred on their bounding box, their
/// kd-tree and the local frames of the metric.
#[derive(Debug)]
pub struct Prepared {
    /// Input points (before duplicates are merged).
    pub(crate) points: usize,
    /// Where the data sit: every later stage works in coordinates centred on the data's
    /// bounding box and scaled by its diagonal ([`Placement`]).
    pub(crate) placement: Placement,
    /// Diagonal `D` of the data's bounding box, in local units (1 but for rounding).
    pub(crate) diag: f64,
    /// The points, in local coordinates (a point cloud's isolated samples left out).
    pub(crate) local: Vec<Point>,
    /// A point cloud's isolated samples (outliers), in data coordinates.
    pub(crate) isolated: Vec<Point>,
    /// The reach within which samples are neighbours, in local units (infinite for a
    /// scan, and for too few points to judge).
    pub(crate) reach: f64,
    /// The parameters in local units.
    pub(crate) params: Params,
    /// Their distance field and metric frames.
    pub(crate) metric: MetricField,
    /// A scan frame's runs, scales, free space and support, centred.
    pub(crate) scan: Option<Analysis>,
    /// Milliseconds spent.
    pub(crate) ms: f64,
}

impl Prepared {
    /// The frame's points, in data coordinates.
    pub fn data(&self) -> Vec<Point> {
        self.local
            .iter()
            .map(|&q| self.placement.to_data(q))
            .collect()
    }

    /// Whether the frame was seen from a sensor (a scan).
    pub fn is_scan(&self) -> bool {
        self.scan.is_some()
    }

    /// This frame's adapted mesh in data coordinates: what the next frame of the stream
    /// adapts from.
    pub fn mesh_in_data(&self, adapted: &AdaptedMesh) -> Mesh {
        let mut mesh = adapted.mesh.clone();
        mesh.map_coords(|c| self.placement.to_data(c));
        mesh
    }

    /// This frame's level set (`solved`, renormalized) on its mesh, in data coordinates
    /// and units: what the next frame of the stream starts from.
    pub fn level_set(&self, adapted: &AdaptedMesh, solved: &Solved) -> LevelSet {
        solved.level_set(self.placement, adapted)
    }
}

/// The distance stage: validates the points, centres them and builds their distance
/// field and metric frames; for a scan frame (`scan`, whose returns are `points`), also
/// its runs, scales and free space, and the sizes follow the sensor: `hmin` is the range
/// noise, at least a quarter of the median beam spacing, instead of a share of the
/// bounding box.
pub fn prepare(points: &[Point], scan: Option<&Scan>, params: &Params) -> Result<Prepared> {
    on_pool(|| prepare_here(points, scan, params))
}

fn prepare_here(points: &[Point], scan: Option<&Scan>, params: &Params) -> Result<Prepared> {
    let t0 = Instant::now();
    validate_points(points)?;
    let config = |path: &str| {
        let path = path.to_string();
        move |problems| Error::Config { path, problems }
    };
    params
        .solver
        .validate()
        .map_err(config("solver parameters"))?;
    params.scan.validate().map_err(config("scan parameters"))?;
    params
        .export
        .repair
        .validate()
        .map_err(config("export parameters"))?;
    // A point cloud's outliers (samples in clusters too small for a curve, linked at a
    // few sampling spacings, `distance::Neighbourhood`) are reported as features and take no
    // part in the field, the mesh or the support. A scan's returns are judged along their
    // runs instead (`scan`). Where nearly every sample is isolated there is no curve to
    // keep them from, and they stay.
    let all = points;
    let (points, isolated, reach) = match scan {
        Some(_) => (Cow::Borrowed(all), Vec::new(), f64::INFINITY),
        None => {
            let n = crate::distance::Neighbourhood::of(all)?;
            let outliers = n.isolated.iter().filter(|&&b| b).count();
            if outliers == 0 || outliers + crate::distance::MIN_CLUSTER > all.len() {
                (Cow::Borrowed(all), Vec::new(), n.reach)
            } else {
                let pick = |out: bool| -> Vec<Point> {
                    all.iter()
                        .zip(&n.isolated)
                        .filter(|&(_, &i)| i == out)
                        .map(|(&p, _)| p)
                        .collect()
                };
                (Cow::Owned(pick(false)), pick(true), n.reach)
            }
        }
    };
    let points: &[Point] = &points;
    let bbox = BBox::of(points).ok_or(Error::EmptyPointSet)?;
    let extent = bbox.diag();
    if extent <= 0.0 {
        return Err(Error::CoincidentPoints {
            count: points.len(),
        });
    }
    if extent < crate::distance::MIN_EXTENT {
        return Err(Error::TinyExtent { extent });
    }
    params
        .mesh
        .check_against(extent)
        .map_err(config("mesh parameters"))?;
    let placement = Placement::of(&bbox);
    let local: Vec<Point> = points.iter().map(|&p| placement.to_local(p)).collect();
    let diag = BBox::of(&local).map_or(1.0, |b| b.diag());
    let params = params.scaled(1.0 / placement.scale);
    let params = &params;
    let mut mesh_params = params.mesh.clone();
    if params.solver.init == Init::Circle {
        mesh_params.padding = mesh_params
            .padding
            .max(crate::levelset::init::circle_padding(
                &local,
                params.solver.margin * diag,
            ));
    }
    let analysis = scan.map(|s| Analysis::new(s.placed(&placement), &params.scan));
    let metric = match &analysis {
        Some(a) => a.metric_field(&a.mesh_params(&mesh_params, diag), &local)?,
        None => MetricField::new(&local, &mesh_params)?,
    };
    Ok(Prepared {
        points: all.len(),
        isolated,
        reach: reach / placement.scale,
        placement,
        diag,
        local,
        params: params.clone(),
        metric,
        scan: analysis,
        ms: t0.elapsed().as_secs_f64() * 1e3,
    })
}

/// The adapt stage: an anisotropic mesh of the frame (local coordinates), adapted from
/// `previous` (a mesh in data coordinates, the previous frame's) when it still covers the
/// data, else from a lattice.
pub fn adapt(prepared: &Prepared, previous: Option<&Mesh>) -> AdaptedMesh {
    adapt_moving(prepared, previous, None)
}

/// [`adapt`] for a moving sensor: `previous` (in the coordinates of the previous
/// frame, at pose `motion.0`) is first moved into this frame's (at `motion.1`), and
/// used as it was if, moved, its domain no longer covers the data (its box, turned,
/// no longer holds this frame's box).
pub fn adapt_moving(
    prepared: &Prepared,
    previous: Option<&Mesh>,
    motion: Option<(crate::geom::Pose, crate::geom::Pose)>,
) -> AdaptedMesh {
    on_pool(|| adapt_here(prepared, previous, motion))
}

fn adapt_here(
    prepared: &Prepared,
    previous: Option<&Mesh>,
    motion: Option<(crate::geom::Pose, crate::geom::Pose)>,
) -> AdaptedMesh {
    // A scan's mesh is its band, built from the runs; a frame with no run to mesh (its
    // field is then of all its returns) is adapted as a point cloud is.
    if let Some(scan) = prepared
        .scan
        .as_ref()
        .filter(|_| !prepared.metric.chain_offsets.is_empty())
    {
        let metric = &prepared.metric;
        let h = metric.params.hmin;
        // Twice the settle's reach, `4 sigma + 4 hmin`: the curve never leaves it.
        let half_width = 8.0 * (scan.scales.noise + h);
        return crate::band::band(&scan.support, metric, h, half_width);
    }
    let local = |m: &Mesh, motion: Option<(crate::geom::Pose, crate::geom::Pose)>| {
        let mut m = m.clone();
        if let Some((from, to)) = motion {
            crate::geom::reframe(from, to, &mut m.coords);
        }
        for c in &mut m.coords {
            *c = prepared.placement.to_local(*c);
        }
        m
    };
    let starts = previous.into_iter().flat_map(|m| {
        let moved = motion.map(|mv| local(m, Some(mv)));
        moved
            .into_iter()
            .chain(std::iter::once_with(move || local(m, None)))
    });
    prepared.metric.adapt_from(starts)
}

/// The solve stage: see `evolve::solve` (with the parameters [`prepare`] put in local
/// units).
pub fn solve(prepared: &Prepared, adapted: &AdaptedMesh, previous: Option<Previous<'_>>) -> Solved {
    on_pool(|| solve_here(prepared, adapted, previous))
}

fn solve_here(
    prepared: &Prepared,
    adapted: &AdaptedMesh,
    previous: Option<Previous<'_>>,
) -> Solved {
    let params = &prepared.params;
    match &prepared.scan {
        // A scan's free space is a better start than any earlier frame's level set
        // (which, in a moving sensor's frame, is in the wrong place): a scan frame is
        // always built from its own scan, and refinement (`export_refined`) is where
        // earlier frames count.
        Some(scan) => evolve::solve(
            &prepared.metric,
            adapted,
            prepared.diag,
            &prepared.placement,
            evolve::Start::FreeSpace(&scan.free),
            &params.solver,
        ),
        None => evolve::solve(
            &prepared.metric,
            adapted,
            prepared.diag,
            &prepared.placement,
            match previous {
                Some(p) => evolve::Start::Warm(p),
                None => evolve::Start::Cold,
            },
            &params.solver,
        ),
    }
}

/// The export stage: the curves (`crate::export::curves`) in data coordinates, with the
/// frame's statistics (lengths in data units).
pub fn export(prepared: &Prepared, adapted: AdaptedMesh, solved: Solved) -> Reconstruction {
    on_pool(|| export_with(prepared, prepared.scan.as_ref(), adapted, solved, None))
}

/// The export stage with refinement over frames: the frame (a scan taken at `pose`) is
/// exported as it would be alone, joins its stream's window (`refiner`, isoline-map's
/// `Window`), and each of its curves takes the window's refined curve where that
/// explains the frame's returns and the window's evidence at least as well. The record
/// stays in the frame's coordinates; its mesh and level set are the frame's own.
#[allow(clippy::too_many_arguments)]
pub fn export_refined(
    prepared: &Prepared,
    adapted: AdaptedMesh,
    solved: Solved,
    frame: u64,
    t: Option<f64>,
    pose: crate::geom::Pose,
    refiner: &mut dyn crate::refine::Refiner,
) -> Reconstruction {
    on_pool(move || {
        use crate::geom::{to_sensor, to_world};
        let Some(scan) = &prepared.scan else {
            return export_with(prepared, None, adapted, solved, None);
        };
        let t0 = Instant::now();
        let mut r = export_with(prepared, Some(scan), adapted, solved, None);
        let single_ms = t0.elapsed().as_secs_f64() * 1e3;
        let at = prepared.placement;
        let sigma = at.len_to_data(scan.scales.noise);
        let hmin = r.stats.hmin;
        let tol = 2.0 * sigma + hmin.max(sigma);
        let bound = 3.0 * sigma + 2.0 * hmin;
        let runs: Vec<Vec<Point>> = scan
            .run_points()
            .into_iter()
            .map(|run| run.into_iter().map(|p| at.to_data(p)).collect())
            .collect();
        let own_returns: Vec<Point> = runs.iter().flatten().copied().collect();
        let world = |p: Point| to_world(pose, p);
        let curves_world: Vec<Polyline> = r
            .polylines
            .iter()
            .map(|c| Polyline {
                closed: c.closed,
                points: c.points.iter().map(|&p| world(p)).collect(),
            })
            .collect();
        // The returns its curves leave unexplained: where it saw a surface too sparsely
        // to draw, and an older frame's curve may fill in (`Refined::filled`).
        let own_index = crate::index::SegmentIndex::new(&r.polylines);
        let unexplained: Vec<Point> = scan
            .scan
            .returns()
            .into_iter()
            .map(|p| at.to_data(p))
            .filter(|&p| own_index.nearest(p).is_none_or(|(d, _, _)| d > bound))
            .map(world)
            .collect();
        let refined = refiner.refine(crate::refine::RefineFrame {
            frame,
            t,
            curves: curves_world,
            returns: own_returns.iter().map(|&p| world(p)).collect(),
            unexplained,
            sigma,
            tol,
        });
        // A window of the frame alone has nothing to fuse: the frame is as it was.
        if let Some(crate::refine::Refined {
            curves: moved,
            filled,
            evidence,
        }) = refined
        {
            let local = |c: Polyline| Polyline {
                closed: c.closed,
                points: c.points.into_iter().map(|p| to_sensor(pose, p)).collect(),
            };
            let moved: Vec<Polyline> = moved.into_iter().map(local).collect();
            let evidence: Vec<Point> = evidence.into_iter().map(|p| to_sensor(pose, p)).collect();
            let keep = refined_curves_kept(
                &r.polylines,
                &own_index,
                &moved,
                &own_returns,
                &evidence,
                bound,
            );
            let refined_any = keep.iter().any(|&k| k);
            let eps = 1e-9 * at.len_to_data(prepared.diag);
            let moved = crate::repair::invariants::well_formed(
                moved
                    .into_iter()
                    .zip(&keep)
                    .zip(&r.polylines)
                    .map(|((m, &k), own)| if k { m } else { own.clone() })
                    .collect(),
                eps,
            );
            // The window's curves hold to the frame's beams as the frame's own curves
            // do: the seen space is in the frame's local coordinates, and `bound` is
            // its margin, in data units.
            let outside_seen = |curves: Vec<Polyline>| -> Vec<Polyline> {
                let in_local = |c: Polyline, f: &dyn Fn(Point) -> Point| Polyline {
                    closed: c.closed,
                    points: c.points.into_iter().map(f).collect(),
                };
                crate::export::support::outside_seen(
                    curves
                        .into_iter()
                        .map(|c| in_local(c, &|p| at.to_local(p)))
                        .collect(),
                    &scan.seen,
                    at.len_to_local(bound),
                    at.len_to_local(hmin),
                )
                .into_iter()
                .map(|c| in_local(c, &|p| at.to_data(p)))
                .collect()
            };
            let filled = if filled.is_empty() {
                Vec::new()
            } else {
                crate::repair::invariants::well_formed(
                    outside_seen(filled.into_iter().map(local).collect()),
                    eps,
                )
            };
            let fused = refined_any || !filled.is_empty();
            r.stats.start = if fused {
                crate::levelset::Start::Fused
            } else {
                crate::levelset::Start::Fallback
            };
            r.stats.warm_start = fused;
            r.stats.cold_fallback = !fused;
            if fused {
                let mut curves = if refined_any {
                    outside_seen(moved)
                } else {
                    moved
                };
                curves.extend(filled);
                adopt_refined(&mut r, prepared, &runs, curves, bound);
            }
        }
        r.stats.window = Some(refiner.stats());
        // The fusion is part of the export stage's time.
        let fusion = t0.elapsed().as_secs_f64() * 1e3 - single_ms;
        r.stats.ms.export += fusion.max(0.0);
        r.stats.ms.total += fusion.max(0.0);
        r
    })
}

/// Which refined curves a frame keeps, curve by curve (`own[k]`, indexed by
/// `own_index`, refined to `moved[k]`): a refined curve explains every return its own
/// curve explains (within the accuracy bound `3 sigma + 2 hmin`), and fits the window's
/// returns nearest its own curve (the frame's `own_returns` and the older frames'
/// `evidence`, as the alignment placed them) at least as well: the sum of their
/// distances, capped at the bound so that returns no curve explains weigh alike. Where the window fails either (a pose
/// error the alignment did not catch, a scene that changed) that curve stays as the
/// frame drew it.
fn refined_curves_kept(
    own: &[Polyline],
    own_index: &crate::index::SegmentIndex,
    moved: &[Polyline],
    own_returns: &[Point],
    evidence: &[Point],
    bound: f64,
) -> Vec<bool> {
    use rayon::prelude::*;
    let moved_index: Vec<crate::index::SegmentIndex> = moved
        .iter()
        .map(|c| crate::index::SegmentIndex::new(std::slice::from_ref(c)))
        .collect();
    let starts: Vec<usize> = (0..own.len()).map(|k| own_index.start(k)).collect();
    // Per curve: whether it lost an own return, and the capped sums, own and moved.
    let per_return = |p: Point, is_own: bool| {
        let (d, seg, _) = own_index.nearest(p)?;
        let k = starts.partition_point(|&s| s <= seg) - 1;
        let m = moved_index[k].distance(p);
        Some((
            k,
            is_own && d <= bound && m > bound,
            d.min(bound),
            m.min(bound),
        ))
    };
    let mut lost = vec![false; moved.len()];
    let mut sums = vec![(0.0, 0.0); moved.len()];
    let found: Vec<_> = own_returns
        .par_iter()
        .map(|&p| per_return(p, true))
        .chain(evidence.par_iter().map(|&p| per_return(p, false)))
        .collect();
    for (k, l, d, m) in found.into_iter().flatten() {
        lost[k] |= l;
        sums[k].0 += d;
        sums[k].1 += m;
    }
    (0..moved.len())
        .map(|k| !lost[k] && sums[k].1 <= sums[k].0 * (1.0 + 1e-12))
        .collect()
}

/// The frame's result takes the refined `curves`, with the fit, features and warnings
/// they give on the frame's own `runs` (in data coordinates).
fn adopt_refined(
    r: &mut Reconstruction,
    prepared: &Prepared,
    runs: &[Vec<Point>],
    curves: Vec<Polyline>,
    bound: f64,
) {
    let at = prepared.placement;
    let data: Vec<Point> = prepared.local.iter().map(|&q| at.to_data(q)).collect();
    let fit = crate::export::fit::fit(&data, &curves, bound);
    let min_run = prepared.params.scan.min_run;
    let supported = prepared.scan.as_ref().map_or(0, |a| a.supported(min_run));
    r.features = crate::export::support::unexplained(runs, &curves, bound);
    r.warnings = crate::export::fit::warnings(supported, &curves, &fit, bound);
    r.stats.explained = fit.explained;
    r.stats.fit_p90 = fit.p90.is_finite().then_some(fit.p90);
    r.stats.unexplained = Some(r.features.iter().map(|f| f.returns).sum());
    r.polylines = curves;
}

/// [`export`] with the scan analysis `scan_analysis` (the prepared one, or one with the
/// window's run ends) and the window the frame was refined over.
fn export_with(
    prepared: &Prepared,
    scan_analysis: Option<&Analysis>,
    adapted: AdaptedMesh,
    solved: Solved,
    window: Option<WindowStats>,
) -> Reconstruction {
    let t0 = Instant::now();
    let at = prepared.placement;
    let hmin = adapted.params.hmin;
    let u: Vec<f64> = solved.u.iter().map(|&x| at.len_to_data(x)).collect();
    let (polylines, features) = isoline_curves(prepared, &adapted, &solved, scan_analysis);
    let min_run = prepared.params.scan.min_run;
    let residual = match &scan_analysis {
        Some(a) => residual_at_runs(a, min_run, &adapted.mesh, &solved, &prepared.metric.field),
        None => solved.report.residual,
    };
    let sigma = scan_analysis.map_or(adapted.noise_estimate, |a| a.scales.noise);
    let tolerance = at.len_to_data(3.0 * sigma + 2.0 * hmin);
    let data: Vec<Point> = prepared.local.iter().map(|&q| at.to_data(q)).collect();
    // Points where too few of the noise measurement's windows see a curve for the
    // level set to follow (a noise band wider than most common windows) are drawn by
    // the graph over the samples (`crate::cloud`), whose windows grow per sample: round
    // such a band the level set wraps a web of strokes or spokes from one junction.
    // Where the graph finds no curve either, the points fill an area.
    let by_graph = scan_analysis.is_none() && prepared.metric.curve_share < AREA_SHARE;
    let graphed = by_graph.then(|| {
        let g = crate::cloud::graph_curves(
            &prepared.metric.field,
            adapted.noise_estimate,
            3.0 * adapted.noise_estimate + 2.0 * hmin,
        );
        let polylines: Vec<Polyline> = g
            .polylines
            .into_iter()
            .map(|pl| Polyline {
                closed: pl.closed,
                points: pl.points.into_iter().map(|p| at.to_data(p)).collect(),
            })
            .collect();
        let junctions: Vec<crate::repair::strokes::Junction> = g
            .junctions
            .into_iter()
            .map(|j| crate::repair::strokes::Junction {
                at: at.to_data(j.at),
                polylines: j.polylines,
            })
            .collect();
        (polylines, junctions)
    });
    let area = graphed.as_ref().is_some_and(|g| g.0.is_empty());
    let drawn_by_graph = graphed.is_some() && !area;
    let (polylines, junctions, mut enforced) = match scan_analysis {
        _ if graphed.is_some() => {
            let (p, j) = graphed.expect("checked");
            (p, j, Vec::new())
        }
        // A scan's pieces are cut to its runs' support already, and where two walls meet
        // at a corner their pieces may cross by a few millimetres: a junction, which
        // scans do not report yet, rather than an error.
        Some(_) => (
            crate::repair::invariants::well_formed(polylines, 1e-9 * at.len_to_data(prepared.diag)),
            Vec::new(),
            Vec::new(),
        ),
        None => {
            let repaired = repair_cloud(
                prepared, &adapted, &solved, polylines, &data, sigma, tolerance,
            );
            (repaired.polylines, repaired.junctions, repaired.warnings)
        }
    };
    let fit = crate::export::fit::fit(&data, &polylines, tolerance);
    // A scan's returns outside its runs are features by design, not misses.
    let supported = scan_analysis.map_or(data.len(), |a| a.supported(min_run));
    let mut warnings = if area {
        vec![Warning::Area {
            curve_share: prepared.metric.curve_share,
        }]
    } else {
        crate::export::fit::warnings(supported, &polylines, &fit, tolerance)
    };
    warnings.append(&mut enforced);
    let features = match scan_analysis {
        Some(_) => features,
        None => prepared
            .isolated
            .iter()
            .copied()
            .chain(if area {
                data.clone()
            } else if drawn_by_graph {
                unexplained(&data, &polylines, tolerance)
            } else {
                Vec::new()
            })
            .map(|center| Feature { center, returns: 1 })
            .collect(),
    };
    let mut stats = frame_stats(
        prepared, &solved, &adapted, residual, &features, &fit, window,
    );
    let mut mesh = adapted.mesh;
    for p in &mut mesh.coords {
        *p = at.to_data(*p);
    }
    stats.ms = stage_ms(
        prepared,
        &adapted.ms,
        &solved,
        t0.elapsed().as_secs_f64() * 1e3,
    );
    let report = solved.report;
    Reconstruction {
        polylines,
        mesh,
        u,
        stats,
        spread: at.len_to_data(report.spread),
        solve: report,
        noise_estimate: at.len_to_data(adapted.noise_estimate),
        features,
        enclosed: solved.enclosed,
        kind: match scan_analysis {
            Some(a) => {
                let (sensor, free_space) = a.free_space_in(&at);
                FrameKind::Scan { sensor, free_space }
            }
            None => FrameKind::Cloud { junctions },
        },
        warnings,
    }
}

/// The level set's zero isoline as curves in data coordinates (`crate::export::curves`):
/// a scan's cut to its runs' support, with the returns no curve explains as features.
fn isoline_curves(
    prepared: &Prepared,
    adapted: &AdaptedMesh,
    solved: &Solved,
    scan_analysis: Option<&Analysis>,
) -> (Vec<Polyline>, Vec<Feature>) {
    let hmin = adapted.params.hmin;
    let scan = scan_analysis.map(|a| {
        // The returns' noise band does not narrow with the mesh: a mesh finer than the
        // noise (a configured `hmin` below it) keeps the tolerance of one at the noise,
        // or returns in the band's tails would count as unexplained.
        let sigma = a.scales.noise;
        (a, 2.0 * sigma + hmin.max(sigma), 3.0 * sigma + 2.0 * hmin)
    });
    crate::export::curves(
        &adapted.mesh,
        &solved.u,
        &prepared.placement,
        prepared.diag,
        hmin,
        scan,
        &prepared.params.export,
    )
}

/// A point cloud's curves `polylines` (in data coordinates) through the repair chain
/// (`crate::repair`), with the noise `sigma` (local units) and the accuracy bound
/// `tolerance` (data units) it keeps them within of the `data`.
fn repair_cloud(
    prepared: &Prepared,
    adapted: &AdaptedMesh,
    solved: &Solved,
    polylines: Vec<Polyline>,
    data: &[Point],
    sigma: f64,
    tolerance: f64,
) -> crate::repair::Repaired {
    let at = prepared.placement;
    let params = &prepared.params.export;
    let hmin = adapted.params.hmin;
    let field = &prepared.metric.field;
    let extent = BBox::of(&prepared.local).map_or(0.0, |b| {
        at.len_to_data((b.max[0] - b.min[0]).max(b.max[1] - b.min[1]))
    });
    let min_area = params.min_area(hmin);
    crate::repair::repair(
        polylines,
        &crate::repair::Frame {
            field,
            data,
            at,
            sigma,
            one_wall_noise: adapted.one_wall_noise,
            hmin,
            min_area,
            enclosed: solved.enclosed,
            tolerance,
            tolerances: &params.repair,
        },
        &crate::repair::invariants::Cloud {
            distance: &|p| at.len_to_data(field.distance(at.to_local(p))),
            // A curve across the widest gap the strokes join (the neighbours'
            // reach) lies within half of it of the samples at its two ends.
            reach: at.len_to_data(3.0 * sigma + 2.0 * hmin + 0.5 * prepared.reach),
            extent,
            min_area: {
                let s = at.len_to_data(1.0);
                min_area * s * s
            },
            eps: 1e-9 * at.len_to_data(prepared.diag),
        },
    )
}

/// A frame's statistics in data units (its mesh still in local coordinates), but for the stages' times (`ms`, left at zero
/// for the caller, who knows when the export ends).
/// The samples of `data` farther than `tolerance` from every curve of `polylines`.
fn unexplained(data: &[Point], polylines: &[Polyline], tolerance: f64) -> Vec<Point> {
    let index = crate::index::SegmentIndex::new(polylines);
    data.par_iter()
        .copied()
        .filter(|&p| index.distance(p) > tolerance)
        .collect()
}

fn frame_stats(
    prepared: &Prepared,
    solved: &Solved,
    adapted: &AdaptedMesh,
    residual: f64,
    features: &[Feature],
    fit: &crate::export::fit::Fit,
    window: Option<WindowStats>,
) -> Stats {
    let at = prepared.placement;
    let report = &solved.report;
    Stats {
        points: prepared.points,
        vertices: adapted.mesh.num_vertices(),
        triangles: adapted.mesh.num_triangles(),
        iterations: report.iterations,
        residual: at.len_to_data(residual),
        converged: report.converged,
        start: solved.start,
        warm_start: matches!(
            solved.start,
            crate::levelset::Start::Warm | crate::levelset::Start::Fused
        ),
        ms: StageMs::default(),
        stop: report.stop,
        scheme: solved.settings.scheme,
        linear_iterations: report.linear_iterations,
        renormalizations: report.renormalizations,
        hmin: at.len_to_data(adapted.params.hmin),
        eps: at.len_to_data(solved.settings.eps),
        unexplained: (prepared.scan.is_some() || !features.is_empty())
            .then(|| features.iter().map(|f| f.returns).sum()),
        range_noise: prepared
            .scan
            .as_ref()
            .map(|a| at.len_to_data(a.scales.noise)),
        noise: prepared
            .scan
            .is_none()
            .then(|| at.len_to_data(adapted.noise_estimate)),
        explained: fit.explained,
        fit_p90: fit.p90.is_finite().then_some(fit.p90),
        cold_fallback: solved.start == crate::levelset::Start::Fallback,
        window,
    }
}

/// Eq. 11 over the returns of the scan's runs of at least `min_run` returns: isolated
/// returns (spurious, or too few to place a curve by) get no curve by design, and `|u|`
/// at them follows whatever the mesh happens to resolve there, which a warm and a cold
/// mesh do not share.
fn residual_at_runs(
    scan: &Analysis,
    min_run: usize,
    mesh: &Mesh,
    solved: &Solved,
    field: &crate::distance::DistanceField,
) -> f64 {
    let returns: Vec<Point> = scan
        .run_points()
        .into_iter()
        .filter(|r| r.len() >= min_run)
        .flatten()
        .collect();
    solved
        .locate(field, mesh, &returns)
        .iter()
        .map(|l| l.interpolate(mesh, &solved.u).abs())
        .fold(0.0, f64::max)
}

/// The milliseconds of each stage of a frame, `export` taking `ms_export`.
fn stage_ms(
    prepared: &Prepared,
    adapt: &crate::field::MeshTimings,
    solved: &Solved,
    ms_export: f64,
) -> StageMs {
    let report = &solved.report;
    let ms = StageMs {
        distance: prepared.ms + solved.ms_distance,
        adapt: adapt.adapt,
        solve: solved.ms - solved.ms_distance - solved.ms_renormalize - report.ms_renormalize,
        renormalize: report.ms_renormalize + solved.ms_renormalize,
        export: ms_export,
        total: 0.0,
        latency: None,
    };
    StageMs {
        total: ms.distance + ms.adapt + ms.solve + ms.renormalize + ms.export,
        ..ms
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::levelset::SolverParams;

    /// A point cloud's result holds junctions and no free space, a scan's a free space
    /// round its sensor and no junctions: the kinds never mix.
    #[test]
    fn a_cloud_and_a_scan_give_their_own_kind() {
        let strokes = plus(400);
        let cloud = reconstruct(&strokes, &Params::default()).unwrap();
        assert!(cloud.free_space().is_none());
        assert!(matches!(cloud.kind, FrameKind::Cloud { .. }));
        assert!(!cloud.junctions().is_empty(), "{:?}", cloud.polylines.len());
        let n = 181;
        let ranges: Vec<Option<f64>> = (0..n)
            .map(|i| {
                let a =
                    -std::f64::consts::FRAC_PI_4 + i as f64 * (std::f64::consts::FRAC_PI_2 / 180.0);
                Some(2.0 / a.cos())
            })
            .collect();
        let scan = crate::scan::Scan::from_laser(&crate::scan::LaserScan {
            origin: [1.0, -3.0],
            angle_min: -std::f64::consts::FRAC_PI_4,
            angle_increment: std::f64::consts::FRAC_PI_2 / 180.0,
            ranges: &ranges,
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap();
        let seen = reconstruct_scan(&scan, &Params::default()).unwrap();
        assert!(seen.junctions().is_empty());
        let (sensor, free) = seen.free_space().expect("a scan's free space");
        assert!(crate::geom::dist(sensor, [1.0, -3.0]) < 1e-9, "{sensor:?}");
        assert!(free.closed && free.points.len() >= 3);
    }

    /// A window that hands back the frame's own curves and two older pieces: one
    /// along a far wall through the frame's two lone returns on it and 5 cm beyond,
    /// one across the space its beams saw through to a nearer wall.
    #[derive(Debug, Default)]
    struct Filling {
        unexplained: std::sync::Arc<std::sync::Mutex<Vec<Point>>>,
    }

    /// The far wall `y = 2.5` where the beam at `deg` degrees meets it.
    fn far_wall(deg: f64) -> Point {
        [2.5 / deg.to_radians().tan(), 2.5]
    }

    /// A point of the space the beams at 90 degrees saw through.
    const THROUGH: Point = [0.0, 1.0];

    impl crate::refine::Refiner for Filling {
        fn refine(&mut self, f: crate::refine::RefineFrame) -> Option<crate::refine::Refined> {
            *self.unexplained.lock().unwrap() = f.unexplained;
            let beyond = [far_wall(30.0)[0] + 0.05, 2.5];
            Some(crate::refine::Refined {
                curves: f.curves,
                filled: vec![
                    Polyline {
                        closed: false,
                        points: vec![far_wall(31.0), beyond],
                    },
                    Polyline {
                        closed: false,
                        points: vec![[-0.1, THROUGH[1]], [0.1, THROUGH[1]]],
                    },
                ],
                evidence: Vec::new(),
            })
        }

        fn stats(&self) -> crate::stats::WindowStats {
            crate::stats::WindowStats {
                frames: 2,
                points: 0,
                bytes: 0,
            }
        }
    }

    /// The window is told which returns the frame's own curves leave unexplained, and
    /// what it draws there is drawn; what of it lies in the space the frame's beams saw
    /// through is cut, as the frame's own curves are.
    #[test]
    fn older_pieces_are_drawn_about_lone_returns_and_never_where_the_beams_saw_through() {
        use std::f64::consts::PI;
        let deg = PI / 180.0;
        // A wall y = 2 from 45 to 135 degrees; of the far wall y = 2.5 two returns, at
        // 30 and 31 degrees, too few for a run; no return on the other beams.
        let ranges: Vec<Option<f64>> = (0..=140)
            .map(|i| {
                let a = (20.0 + i as f64) * deg;
                match i {
                    10 | 11 => Some(2.5 / a.sin()),
                    25..=115 => Some(2.0 / a.sin()),
                    _ => None,
                }
            })
            .collect();
        let scan = crate::scan::Scan::from_laser(&crate::scan::LaserScan {
            origin: [0.0, 0.0],
            angle_min: 20.0 * deg,
            angle_increment: deg,
            ranges: &ranges,
            range_min: 0.1,
            range_max: 10.0,
        })
        .unwrap();
        let points = scan.returns();
        let window = Filling::default();
        let told = window.unexplained.clone();
        let mut stream = crate::Stream::new(Params::default(), false).refining(Box::new(window));
        let r = stream
            .push(&crate::StreamFrame {
                frame: 0,
                points: &points,
                scan: Some(&scan),
                t: None,
                pose: Some([0.0, 0.0, 0.0]),
            })
            .unwrap();
        let told = told.lock().unwrap().clone();
        assert_eq!(told.len(), 2, "{told:?}");
        for p in [far_wall(30.0), far_wall(31.0)] {
            assert!(
                told.iter().any(|&q| crate::geom::dist(p, q) < 1e-9),
                "{told:?}"
            );
        }
        assert_eq!(r.stats.start, crate::levelset::Start::Fused);
        let index = crate::index::SegmentIndex::new(&r.polylines);
        // Between the two returns, on the edge of what the beams saw: drawn.
        let mid = crate::geom::scale(crate::geom::add(far_wall(30.0), far_wall(31.0)), 0.5);
        assert!(index.distance(mid) < 1e-9, "{:?}", r.polylines);
        // Beyond the return at 30 degrees, where the beam at 29 saw through: cut.
        assert!(
            index.distance([far_wall(30.0)[0] + 0.05, 2.5]) > 0.02,
            "{:?}",
            r.polylines
        );
        // Nothing where the beams at 90 degrees saw through to the wall 2 m off.
        assert!(index.distance(THROUGH) > 0.5, "{:?}", r.polylines);
    }

    /// Two strokes crossing at their middles, `n` samples each.
    fn plus(n: usize) -> Vec<Point> {
        (0..n)
            .flat_map(|i| {
                let t = 0.1 + 0.8 * i as f64 / (n - 1) as f64;
                [[t, 0.5], [0.5, t]]
            })
            .collect()
    }

    /// Points that fill an area get no curve, and say so: every one of them is a
    /// feature and the only warning is [`Warning::Area`]. Strokes hatched closer than
    /// the sampling resolves (81 lines 0.01 apart, 1,500 samples, so 0.04 apart along
    /// a line) are such an area, and so are scattered points; a noisy circle is not.
    #[test]
    fn points_that_fill_an_area_are_features_not_curves() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let e = Normal::new(0.0, 0.002).unwrap();
        let hatch: Vec<Point> = (0..1_500)
            .map(|_| {
                let y = 0.1 + 0.01 * rng.random_range(0..81) as f64;
                [0.1 + 0.8 * rng.random::<f64>(), y + e.sample(&mut rng)]
            })
            .collect();
        let scattered: Vec<Point> = (0..2_000)
            .map(|_| [rng.random::<f64>(), rng.random::<f64>()])
            .collect();
        for pts in [hatch, scattered] {
            let r = reconstruct(&pts, &Params::default()).unwrap();
            assert!(r.polylines.is_empty(), "{} curves", r.polylines.len());
            assert_eq!(r.features.len(), pts.len());
            assert!(
                matches!(r.warnings[..], [Warning::Area { curve_share }] if curve_share < AREA_SHARE),
                "{:?}",
                r.warnings
            );
        }
        let circle: Vec<Point> = (0..1_000)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                let r = 0.4 + e.sample(&mut rng);
                [0.5 + r * a.cos(), 0.5 + r * a.sin()]
            })
            .collect();
        let r = reconstruct(&circle, &Params::default()).unwrap();
        assert_eq!(r.polylines.len(), 1, "{:?}", r.warnings);
    }

    /// A drawing a person can see gets its strokes: a spiral of four turns 0.03 apart
    /// (a quarter of the box's scale), 2,000 samples at sigma = 0.008, where fewer
    /// than a tenth of the noise measurement's windows see a curve and the export once
    /// gave up ("the points fill an area", no curve), is drawn by the graph over the
    /// samples: every vertex within the accuracy bound `3 sigma + 2 hmin` of the spiral
    /// (a vertex is the foot of its window's fit, which averages the noise), and the
    /// spiral within it of a curve for at least half its length. Not all of it: the
    /// turns lie 3.75 sigma apart, so every window that spans four times its residual
    /// reaches the next turn, and where the fit cannot split the two (77% of the
    /// length is covered here) its samples are on no curve.
    #[test]
    fn a_drawing_whose_noise_band_fills_most_windows_is_drawn() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let sigma = 0.008;
        let e = Normal::new(0.0, sigma).unwrap();
        let at = |t: f64| {
            let th = std::f64::consts::TAU * 4.0 * t;
            let rad = 0.28 + 0.12 * t;
            [0.5 + rad * th.cos(), 0.5 + rad * th.sin()]
        };
        let pts: Vec<Point> = (0..2_000)
            .map(|_| {
                let p = at(rng.random::<f64>());
                [p[0] + e.sample(&mut rng), p[1] + e.sample(&mut rng)]
            })
            .collect();
        let r = reconstruct(&pts, &Params::default()).unwrap();
        assert!(!r.polylines.is_empty(), "{:?}", r.warnings);
        let bound = 3.0 * sigma + 2.0 * r.stats.hmin;
        let truth: Vec<Point> = (0..=20_000).map(|i| at(i as f64 / 20_000.0)).collect();
        let index = crate::index::SegmentIndex::new(&r.polylines);
        for pl in &r.polylines {
            for &p in &pl.points {
                let d = truth
                    .iter()
                    .map(|&c| crate::geom::dist(c, p))
                    .fold(f64::INFINITY, f64::min);
                assert!(d <= bound, "{d} > {bound}");
            }
        }
        let near = truth
            .iter()
            .filter(|&&c| index.distance(c) <= bound)
            .count();
        assert!(
            near as f64 >= 0.5 * truth.len() as f64,
            "{near} of {}",
            truth.len()
        );
    }

    /// Data of any size the contract accepts reconstruct alike, and settings that cannot
    /// work on the data are refused by name, not by a panic (the hardening issue's radius
    /// 1e61 and 1e-42, and hmin or padding of 1e300, all once panicked).
    #[test]
    fn any_size_reconstructs_and_impossible_settings_are_named() {
        let unit: Vec<Point> = (0..400)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                [0.4 * a.cos(), 0.4 * a.sin()]
            })
            .collect();
        for scale in [1e-140, 1e-42, 1e-12, 1.0, 1e12, 1e61, 1e140] {
            let pts: Vec<Point> = unit.iter().map(|p| [p[0] * scale, p[1] * scale]).collect();
            let r = reconstruct(&pts, &Params::default()).unwrap();
            assert_eq!(r.polylines.len(), 1, "scale {scale}");
            let area = r.polylines[0].signed_area() / (scale * scale);
            assert!(
                (area - std::f64::consts::PI * 0.16).abs() < 0.01,
                "{scale}: {area}"
            );
        }
        let with =
            |mesh: MeshParams| Params::new(mesh, SolverParams::default(), ExportParams::default());
        let e = reconstruct(&unit, &with(MeshParams::default().with_hmin(1e300)))
            .unwrap_err()
            .to_string();
        assert!(e.contains("mesh.hmin = 1e300"), "{e}");
        let wide = MeshParams {
            padding: 1e300,
            ..Default::default()
        };
        let e = reconstruct(&unit, &with(wide)).unwrap_err().to_string();
        assert!(e.contains("mesh.padding"), "{e}");
        let mut export = ExportParams::default();
        export.repair.between_run = 2;
        let bad = Params::new(MeshParams::default(), SolverParams::default(), export);
        let e = reconstruct(&unit, &bad).unwrap_err().to_string();
        assert!(e.contains("export.repair.between_run = 2"), "{e}");
        let tiny: Vec<Point> = unit
            .iter()
            .map(|p| [p[0] * 1e-160, p[1] * 1e-160])
            .collect();
        let e = reconstruct(&tiny, &Params::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("below the supported 1e-150"), "{e}");
    }

    /// A new object with a twentieth of the samples: the warm start's curve is near nine
    /// samples in ten and is taken, but it misses the object, which a cold start
    /// captures. The result explains less than the previous frame did, so the frame is
    /// redone cold.
    #[test]
    fn a_warm_start_that_misses_new_data_falls_back_to_cold() {
        let ring = |n: usize, c: Point, r: f64| -> Vec<Point> {
            (0..n)
                .map(|i| {
                    let a = i as f64 * std::f64::consts::TAU / n as f64;
                    [c[0] + r * a.cos(), c[1] + r * a.sin()]
                })
                .collect()
        };
        let params = Params::default();
        let first = ring(760, [0.4, 0.5], 0.3);
        let before = reconstruct(&first, &params).unwrap();
        let mut next = first.clone();
        // Inside the old curve, where the old mesh covers it.
        next.extend(ring(40, [0.4, 0.5], 0.06));
        let r = reconstruct_warm(&next, &params, Some(&before)).unwrap();
        assert!(
            r.stats.cold_fallback && !r.stats.warm_start,
            "{:?}",
            r.stats
        );
        assert_eq!(r.polylines.len(), 2);
        // The same frame again is near and explained: warm, no fallback.
        let again = reconstruct_warm(&next, &params, Some(&r)).unwrap();
        assert!(again.stats.warm_start && !again.stats.cold_fallback);
        assert_eq!(again.polylines.len(), 2);
    }

    /// `mesh.max_vertices` bounds the mesh whatever the padding asks for (padding 20 with
    /// 10,000 vertices once gave 166,870).
    #[test]
    fn max_vertices_is_a_bound_that_holds() {
        let pts: Vec<Point> = (0..500)
            .map(|i| {
                let a = i as f64 * 2.399_963;
                [0.5 + 0.3 * a.cos(), 0.5 + 0.3 * a.sin()]
            })
            .collect();
        for padding in [0.0, 1.0, 10.0] {
            for max in [200, 2000, 10_000] {
                let mesh = MeshParams {
                    padding,
                    max_vertices: max,
                    ..Default::default()
                };
                let params = Params::new(mesh, SolverParams::default(), ExportParams::default());
                let r = reconstruct(&pts, &params).unwrap();
                assert!(
                    r.stats.vertices <= max,
                    "padding {padding}, max {max}: {} vertices",
                    r.stats.vertices
                );
            }
        }
    }
}
