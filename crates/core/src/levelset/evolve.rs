//! The solve stage as one plain function: a frame's starting level set (warm or cold),
//! its evolution by the solver, and the median settle.

use std::time::Instant;

use crate::fem::locate::Location;
use crate::fem::P1Space;
use crate::field::{AdaptedMesh, MetricField};
use crate::geom::Placement;
use crate::levelset::init::{self, Init};
use crate::levelset::params::{Settle, SolverParams};
use crate::levelset::settle::center_on_data;
use crate::levelset::solver::{spread, SolveReport, Solver, SolverSettings, StopReason};
use crate::levelset::warm::{warm_start, Previous, WarmCriteria};
use crate::mesh::{Mesh, INVALID};
use crate::redistance::Redistancer;
use crate::scan::FreeSpace;

/// The solve stage's product: the level set on the adapted mesh and how it was found.
#[derive(Debug)]
pub struct Solved {
    /// The level set at the mesh vertices (centred coordinates, negative inside).
    pub(crate) u: Vec<f64>,
    /// The P1 space of the mesh (reused by renormalization).
    pub(crate) space: P1Space,
    /// The solver's report (its `ms_solve` includes the median settle).
    pub(crate) report: SolveReport,
    /// The settings used.
    pub(crate) settings: SolverSettings,
    /// Whether the level set started from the previous frame's.
    pub(crate) warm_start: bool,
    /// Where the level set came from.
    pub(crate) start: crate::levelset::Start,
    /// Whether the data enclose anything: false when a tube start found no inside
    /// region (open strokes, or samples too sparse to close) and the level set started
    /// from the box around them, whose loop then explains nothing.
    pub(crate) enclosed: bool,
    /// Whether `u` is already the signed distance to its zero isoline over the whole mesh
    /// (the median settle's last accepted round leaves it so), or, from a scan's free
    /// space, out to the settle's width (nothing reads a scan's level set farther out:
    /// the export takes its zero isoline and refinement its values within the
    /// tolerance).
    pub(crate) renormalized: bool,
    /// The field's points, located in the mesh (as the solve used them).
    pub(crate) located: Vec<Location>,
    /// Milliseconds: distances at the vertices and locating the data.
    pub(crate) ms_distance: f64,
    /// Milliseconds: the whole solve stage.
    pub(crate) ms: f64,
    /// Milliseconds of fast marching outside the solver's loop (warm start, final pass).
    pub(crate) ms_renormalize: f64,
}

impl Solved {
    /// Whether the level set started from the previous frame.
    pub fn warm_start(&self) -> bool {
        self.warm_start
    }

    /// Locates `points` in `mesh` (the solve's), each walk starting from where the
    /// field's (`field`'s) sample nearest it was found: a few steps for points near the
    /// data, whatever their order.
    pub(crate) fn locate(
        &self,
        field: &crate::distance::DistanceField,
        mesh: &Mesh,
        points: &[crate::geom::Point],
    ) -> Vec<Location> {
        if self.located.len() != field.points().len() || field.points().is_empty() {
            return crate::fem::locate::locate_all(mesh, points);
        }
        crate::fem::locate::locate_from(mesh, points, |i| {
            let j = field.nearest(points[i]).index as usize;
            Some(mesh.tris[self.located[j].tri as usize][0])
        })
    }

    /// What the next frame of the stream starts from: this level set with its mesh
    /// (`adapted`'s), in data coordinates and units (`at` places the frame).
    pub(crate) fn level_set(&self, at: Placement, adapted: &AdaptedMesh) -> LevelSet {
        let mut mesh = adapted.mesh.clone();
        mesh.map_coords(|c| at.to_data(c));
        LevelSet {
            mesh,
            u: self.u.iter().map(|&x| at.len_to_data(x)).collect(),
            spread: at.len_to_data(self.report.spread),
            near: self.report.near,
            enclosed: self.enclosed,
        }
    }
}

/// A frame's level set as the next frame of its stream starts from it: the mesh and
/// the renormalized level set in data coordinates and units, and how well it fitted
/// its own data.
#[derive(Clone, Debug)]
pub struct LevelSet {
    /// The mesh, in data coordinates.
    pub mesh: Mesh,
    /// The level set at its vertices, in data units (negative inside).
    pub u: Vec<f64>,
    /// The 90th percentile of `|u|` at the frame's data, in data units.
    pub spread: f64,
    /// The share of the data within the median settle's reach of the curve.
    pub near: f64,
    /// Whether the data enclosed anything.
    pub enclosed: bool,
}

impl LevelSet {
    /// Moves the level set into other coordinates (a moving sensor's next frame):
    /// `f` must be a rigid motion.
    pub fn map_coords(&mut self, f: impl FnMut(crate::geom::Point) -> crate::geom::Point) {
        self.mesh.map_coords(f);
    }

    /// Bytes it holds, roughly.
    pub fn bytes(&self) -> usize {
        self.mesh.bytes() + self.u.len() * std::mem::size_of::<f64>()
    }

    /// This level set as a warm start takes it.
    pub fn as_previous(&self) -> Previous<'_> {
        Previous {
            mesh: &self.mesh,
            u: &self.u,
            spread: self.spread,
            near: self.near,
            enclosed: self.enclosed,
        }
    }
}

/// Where a frame's level set may start.
#[derive(Clone, Copy, Debug)]
pub enum Start<'a> {
    /// From `params.init`.
    Cold,
    /// From the previous frame's level set when that is a good start (see
    /// [`mod@crate::levelset::warm`]), else from `params.init`.
    Warm(Previous<'a>),
    /// From the free space a scan's rays swept ([`init::free_space`]): the curve starts
    /// on the data, so the evolution has nothing to capture (and attraction would carry
    /// the curve into space the sensor saw as free): no time steps, the settle places
    /// it.
    FreeSpace(&'a FreeSpace),
}

/// The level set of one frame on its adapted mesh (`field` is the frame's distance
/// field and metric frames, in the mesh's local coordinates; `diag` its data's diagonal
/// in them; `params` in local units), from `start` (`at` places the local coordinates in
/// the data's, where a previous frame is), evolved by the solver and, on noisy data,
/// settled on the data's median.
pub fn solve(
    field: &MetricField,
    adapted: &AdaptedMesh,
    diag: f64,
    at: &Placement,
    start: Start<'_>,
    params: &SolverParams,
) -> Solved {
    let t0 = Instant::now();
    let frame = Frame::new(field, adapted, diag, params);
    let ms_distance = t0.elapsed().as_secs_f64() * 1e3;
    let mut attempt = frame.attempt(start, at);
    let mut cold_fallback = false;
    if let (Start::Warm(prev), true) = (start, attempt.warm_start) {
        // Never worse than a cold start: a warm result that explains clearly less of
        // the data than the previous frame did, or lies clearly farther from it, is
        // replaced by a cold one (robust measures: a maximum would follow outliers).
        let prev_spread = at.len_to_local(prev.spread);
        let worse = attempt.report.near < prev.near - 0.03
            || attempt.report.spread > 2.0 * prev_spread.max(frame.settle_width);
        if worse {
            tracing::info!(
                near = attempt.report.near,
                previous_near = prev.near,
                spread = attempt.report.spread,
                "warm start worse than the previous frame: cold start"
            );
            let ms_first = attempt.ms_renormalize + attempt.report.ms_solve;
            attempt = frame.attempt(Start::Cold, at);
            attempt.report.ms_solve += ms_first;
            cold_fallback = true;
        }
    }
    Solved {
        u: attempt.u,
        space: frame.space,
        report: attempt.report,
        settings: attempt.settings,
        warm_start: attempt.warm_start,
        enclosed: attempt.enclosed,
        start: match (start, attempt.warm_start, cold_fallback) {
            (Start::FreeSpace(_), ..) => crate::levelset::Start::Scan,
            (_, true, _) => crate::levelset::Start::Warm,
            (_, _, true) => crate::levelset::Start::Fallback,
            _ => crate::levelset::Start::Cold,
        },
        renormalized: attempt.renormalized,
        located: frame.data,
        ms_distance,
        ms: t0.elapsed().as_secs_f64() * 1e3,
        ms_renormalize: attempt.ms_renormalize,
    }
}

/// What every attempt at one frame's level set shares: the mesh, its P1 space, the
/// distances and nearest samples at its vertices, the samples located in it, and the
/// settings resolved for the frame.
struct Frame<'a> {
    field: &'a MetricField,
    adapted: &'a AdaptedMesh,
    diag: f64,
    params: &'a SolverParams,
    space: P1Space,
    dist: Vec<f64>,
    nearest: Vec<u32>,
    /// The field's points (the data with exact duplicates merged, so that the stopping
    /// test and the median settle weigh each sample once), located in the mesh.
    data: Vec<Location>,
    settings: SolverSettings,
    warm_patience: usize,
    /// The tube start's radius, from the data's spacing: only a cold start from the
    /// data and the warm decision read it, so a scan's free-space start never pays its
    /// nearest-neighbour search over every return.
    tube_radius: std::sync::OnceLock<f64>,
    settle_width: f64,
}

/// The start of one attempt: the level set, and what it changes in the settings.
struct Started {
    u: Vec<f64>,
    settings: SolverSettings,
    warm_start: bool,
    enclosed: bool,
    ms_renormalize: f64,
}

impl<'a> Frame<'a> {
    fn new(
        field: &'a MetricField,
        adapted: &'a AdaptedMesh,
        diag: f64,
        params: &'a SolverParams,
    ) -> Frame<'a> {
        let mesh = &adapted.mesh;
        let kd = &field.field;
        let hmin = adapted.params.hmin;
        let pts = kd.points();
        // The adapt stage found each vertex's nearest sample; a mesh adapted elsewhere
        // (a test's) has them found here.
        let (dist, nearest): (Vec<f64>, Vec<u32>) = if adapted.nearest.len() == mesh.coords.len()
            && adapted.nearest.iter().all(|&j| (j as usize) < pts.len())
        {
            mesh.coords
                .iter()
                .zip(&adapted.nearest)
                .map(|(&x, &j)| (crate::geom::dist(x, pts[j as usize]), j))
                .unzip()
        } else {
            kd.nearest_all(&mesh.coords)
                .iter()
                .map(|n| (n.dist, n.index))
                .unzip()
        };
        // Each sample's walk starts at the vertex nearest it among those it is nearest
        // to (the field's points are in x order, so the previous sample's triangle can be
        // across the mesh); a sample nearest to no vertex starts at one of its
        // neighbours': the nearest sample that is some vertex's nearest (data denser
        // than the mesh, a dense scan's, has many such samples; one tree of those answers
        // each without a search of its own).
        let mut closest = vec![(f64::INFINITY, INVALID); pts.len()];
        for (v, (&j, &d)) in nearest.iter().zip(&dist).enumerate() {
            let c = &mut closest[j as usize];
            if d < c.0 {
                *c = (d, v as u32);
            }
        }
        let (reached, at): (Vec<u32>, Vec<crate::Point>) = closest
            .iter()
            .zip(pts)
            .filter(|(c, _)| c.1 != INVALID)
            .map(|(c, &p)| (c.1, p))
            .unzip();
        let reached_tree = (reached.len() < pts.len())
            .then(|| kiddo::ImmutableKdTree::<f64, 2>::new_from_slice(&at).ok())
            .flatten();
        let start = |j: usize| -> Option<u32> {
            let v = closest[j].1;
            if v != INVALID {
                return Some(v);
            }
            let tree = reached_tree.as_ref()?;
            let k = tree
                .query(&pts[j])
                .nearest_one::<kiddo::SquaredEuclidean<f64>>()
                .execute()
                .item;
            reached.get(k as usize).copied()
        };
        let data = crate::fem::locate::locate_from(mesh, pts, start);
        let settings = params.resolve(diag, hmin);
        Frame {
            field,
            adapted,
            diag,
            params,
            space: P1Space::new(mesh),
            dist,
            nearest,
            data,
            warm_patience: params
                .warm_patience
                .unwrap_or((settings.patience / 2).max(1)),
            settle_width: 4.0 * adapted.noise_estimate + 4.0 * hmin,
            tube_radius: params
                .tube
                .map_or_else(std::sync::OnceLock::new, |t| t.into()),
            settings,
        }
    }

    fn tube_radius(&self) -> f64 {
        *self.tube_radius.get_or_init(|| {
            crate::distance::tube_radius(&self.field.field, 2.0 * self.adapted.params.hmin)
        })
    }

    fn criteria(&self) -> WarmCriteria {
        WarmCriteria {
            settle_width: self.settle_width,
            tube_radius: self.tube_radius(),
            eps: self.settings.eps,
            median_settle: self.params.settle == Settle::Median,
        }
    }

    /// One try from `start`: the starting level set, the evolution (none from free
    /// space) and the median settle.
    fn attempt(&self, start: Start<'_>, at: &Placement) -> Attempt {
        let mut fm = Redistancer::new();
        let Started {
            mut u,
            settings,
            warm_start,
            enclosed,
            ms_renormalize,
        } = self.start(start, at, &mut fm);
        let mesh = &self.adapted.mesh;
        let mut report = if let Start::FreeSpace(_) = start {
            // The free-space start already lies on the returns, and the evolution could
            // only move what lies away from them, which export cuts: it would pinch thin
            // shadows (behind a leg, say) into loops and cost time for nothing. The
            // settle alone places the curve in the noise band.
            let (residual, mean) = crate::levelset::solver::residual(mesh, &self.data, &u);
            SolveReport {
                residual,
                mean_residual: mean,
                initial_residual: residual,
                converged: residual < settings.eps,
                stop: if residual < settings.eps {
                    StopReason::Converged
                } else {
                    StopReason::Settled
                },
                dt: settings.dt,
                ..Default::default()
            }
        } else {
            Solver::new().solve(mesh, &self.space, &self.dist, &self.data, &mut u, &settings)
        };
        let settled =
            self.params.settle == Settle::Median && self.settle(&mut u, &settings, &mut report);
        // The free-space start is the fast-marched distance to its own zero isoline (the
        // free space's boundary), as a settle that moves it leaves it: a final
        // renormalization would march it again for nothing.
        let renormalized = settled || matches!(start, Start::FreeSpace(_));
        (report.spread, report.near) = spread(mesh, &self.data, &u, self.settle_width);
        Attempt {
            u,
            report,
            settings,
            warm_start,
            enclosed,
            renormalized,
            ms_renormalize,
        }
    }

    /// The starting level set: the previous frame's where it is a good start, the free
    /// space a scan's rays swept, or a cold start.
    fn start(&self, start: Start<'_>, at: &Placement, fm: &mut Redistancer) -> Started {
        let mesh = &self.adapted.mesh;
        let mut settings = self.settings.clone();
        let warm = match start {
            Start::Warm(prev) if prev.enclosed => {
                warm_start(prev, at, mesh, &self.data, &self.criteria())
            }
            _ => None,
        };
        if let Some((u, near)) = warm {
            if near {
                settings.patience = self.warm_patience;
            }
            return Started {
                u,
                settings,
                warm_start: true,
                enclosed: true,
                ms_renormalize: 0.0,
            };
        }
        let t = Instant::now();
        let (u, enclosed) = match start {
            // The settle and the export look no farther from the curve than the
            // settle's width, and refinement than its tolerance, within it.
            Start::FreeSpace(free) => (init::free_space(mesh, free, self.settle_width), true),
            _ => self.cold_start(&mut settings, fm),
        };
        Started {
            u,
            settings,
            warm_start: false,
            enclosed,
            ms_renormalize: t.elapsed().as_secs_f64() * 1e3,
        }
    }

    /// A cold start by `params.init`, and whether the data enclosed anything; adjusts
    /// the settings the start asks for.
    fn cold_start(&self, settings: &mut SolverSettings, fm: &mut Redistancer) -> (Vec<f64>, bool) {
        let (mesh, kd, params) = (&self.adapted.mesh, &self.field.field, self.params);
        let (hmin, noise) = (self.adapted.params.hmin, self.adapted.noise_estimate);
        let medial = matches!(params.init, Init::Medial | Init::Tube);
        let corridor = medial.then(|| {
            init::corridors(
                kd,
                &mesh.coords,
                &self.dist,
                &self.nearest,
                2.0 * hmin,
                4.0 * self.tube_radius(),
            )
        });
        let oriented = medial
            .then(|| {
                crate::levelset::orient::oriented_offsets(
                    kd,
                    noise,
                    2.0 * noise + self.tube_radius(),
                    &mesh.coords,
                )
            })
            .flatten();
        let start = init::cold_start(
            params.init,
            mesh,
            &self.space,
            &self.dist,
            kd.points(),
            self.tube_radius(),
            corridor.as_ref(),
            oriented.as_deref().map(|offsets| init::Oriented {
                offsets,
                clean: noise < self.tube_radius() / 8.0,
            }),
            params.margin * self.diag,
            fm,
        );
        let enclosed = !(medial && start.init == Init::Box);
        if start.init == Init::Medial && params.settle == Settle::Median {
            // Like a warm start at the data: nothing to capture, the settle places the
            // curve.
            settings.patience = self.warm_patience;
        }
        if params.init == Init::Tube {
            // The pinned vertices must lie inside the starting curve, or nothing moves.
            settings.tube = settings.tube.min(0.5 * self.tube_radius());
        }
        (start.u, enclosed)
    }

    /// The median settle of `u` on the data, its outcome written into `report`;
    /// whether it left `u` renormalized.
    fn settle(&self, u: &mut [f64], settings: &SolverSettings, report: &mut SolveReport) -> bool {
        let t = Instant::now();
        let settled = center_on_data(
            &self.adapted.mesh,
            &self.space,
            self.field,
            &self.data,
            &self.nearest,
            u,
            self.settle_width,
        );
        report.residual = settled.residual;
        report.mean_residual = settled.mean;
        // Rounds are kept by the mean distance, so the maximum can move either way.
        let converged = settled.residual < settings.eps;
        if converged != report.converged {
            report.converged = converged;
            report.stop = if converged {
                StopReason::Converged
            } else {
                StopReason::Settled
            };
        }
        report.ms_solve += t.elapsed().as_secs_f64() * 1e3;
        settled.moved
    }
}

/// One try at a frame's level set, from one start.
struct Attempt {
    u: Vec<f64>,
    report: SolveReport,
    settings: SolverSettings,
    warm_start: bool,
    enclosed: bool,
    renormalized: bool,
    ms_renormalize: f64,
}

/// The renormalize stage: `u` becomes the signed distance to its zero isoline over the
/// whole mesh (the solver's own passes stop at twice its narrow band), which is what the
/// next frame's warm start interpolates. Nothing to do when the median settle already
/// left it so, or the frame is a scan's (see `Solved::renormalized`).
pub fn renormalize(mesh: &Mesh, solved: &mut Solved) {
    if solved.renormalized {
        return;
    }
    let t = Instant::now();
    Redistancer::new().run(mesh, &solved.space, &mut solved.u, f64::INFINITY);
    solved.renormalized = true;
    // `ms` is the whole of the frame's solve and renormalize stages, so that the solve's
    // own share (`ms` less its parts) is never negative.
    let ms = t.elapsed().as_secs_f64() * 1e3;
    solved.ms_renormalize += ms;
    solved.ms += ms;
}

/// Makes `u`, a level set at `mesh`'s vertices, the signed distance to its own zero
/// isoline over the whole mesh, by fast marching on the triangles (the vertices of
/// triangles the isoline cuts start from their exact distances to it).
pub fn redistance(mesh: &Mesh, u: &mut [f64]) {
    Redistancer::new().run(mesh, &P1Space::new(mesh), u, f64::INFINITY);
}
