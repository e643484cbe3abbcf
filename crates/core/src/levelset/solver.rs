//! The evolution `du/dt = d (alpha + kappa(u))` (paper eq. 4) on a P1 mesh.
//!
//! Curvature is the mass-lumped L2 projection (paper 3.2.1) of `div(grad u / |grad u|)`,
//! taken by parts so that the element-wise constant normal needs no second derivative:
//!
//! ```text
//! kappa_i = -(1 / m_i) sum_{T in ball(i)} |T| (grad u_T / |grad u_T|) . grad phi_i^T
//!         = -(1 / m_i) (K(u) u)_i,   K_ij(u) = sum_T |T| grad phi_i . grad phi_j / |grad u_T|
//! ```
//!
//! with `m_i` a third of the ball's area. `K` is the P1 stiffness matrix weighted by
//! `1 / |grad u|`, so both schemes share one spatial operator and one steady state:
//!
//! - explicit (paper 3.4.1): `u_i += dt d_i (alpha + kappa_i)`;
//! - semi-implicit (paper 3.4.2): `u^{n+1} - dt D M^-1 K(u^n) u^{n+1} = u^n + dt alpha d`.
//!   Multiplying row `i` by `m_i / d_i > 0` turns this non-symmetric system into the
//!   symmetric positive definite `(M D^-1 + dt K(u^n)) u^{n+1} = M D^-1 u^n + dt alpha M 1`,
//!   solved matrix-free by Jacobi-preconditioned conjugate gradients warm-started from
//!   `u^n` (see the README for the comparison with GMRES).
//!
//! `|grad u_T|` is regularised as `sqrt(|grad u_T|^2 + GRAD_FLOOR^2)`: the level set is
//! renormalized to a distance (`|grad u| = 1`) every few steps, so this only matters on
//! the rare elements straddling a ridge of `u`.

use std::time::Instant;

use rayon::prelude::*;

use crate::fem::locate::Location;
use crate::fem::P1Space;
use crate::geom::{dot, Point};
use crate::mesh::Mesh;
use crate::redistance::Redistancer;

/// Regularisation of `|grad u|` in the curvature's denominator.
pub const GRAD_FLOOR: f64 = 0.1;

/// Vertices per rayon task: below this, splitting costs more than it saves. A task
/// hand-off costs about 20 us on this project's 2-core machine and a CG iteration about
/// 7 ns per vertex, so splitting pays from about 6,000 vertices (measured: a step of the
/// 5,300-vertex circle mesh took 2.0 ms in two tasks, 1.3 ms in one).
const MIN_LEN: usize = 8192;

/// Time-stepping scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum Scheme {
    /// Forward Euler at the stability bound `dt <= m_i / (d_i sum_j |K_ij|)`: by
    /// Gershgorin no eigenvalue of `D M^-1 K` exceeds `max_i d_i sum_j |K_ij| / m_i`. With
    /// `|grad u| = 1` the bound is of order `h^2 / d` (h the smallest triangle height at
    /// the vertex): in the band around the data `h = hmin` but also `d <= band`, so the
    /// step is `O(hmin^2 / band)`, and far from the data the elements are large.
    Explicit,
    /// Curvature implicit, attraction explicit; the step is `O(hmin)` (paper 3.4.2).
    #[default]
    SemiImplicit,
}

impl std::str::FromStr for Scheme {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "explicit" => Ok(Scheme::Explicit),
            "semi-implicit" | "semi_implicit" => Ok(Scheme::SemiImplicit),
            _ => Err(format!(
                "unknown scheme {s:?}: expected \"explicit\" or \"semi-implicit\""
            )),
        }
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Scheme::Explicit => "explicit",
            Scheme::SemiImplicit => "semi-implicit",
        })
    }
}

/// The Krylov solver of the semi-implicit system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LinearSolver {
    /// Conjugate gradients on the symmetrised system (rows scaled by `m_i / (dt d_i)`),
    /// Jacobi-preconditioned.
    #[default]
    Cg,
    /// GMRES on the paper's non-symmetric form, Jacobi-preconditioned (the paper's
    /// choice; kept to measure against conjugate gradients).
    Gmres,
}

impl std::str::FromStr for LinearSolver {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "cg" => Ok(LinearSolver::Cg),
            "gmres" => Ok(LinearSolver::Gmres),
            _ => Err(format!(
                "unknown linear solver {s:?}: expected \"cg\" or \"gmres\""
            )),
        }
    }
}

/// Concrete solver settings (every derived value filled in; see
/// [`crate::levelset::SolverParams`] for the user-facing defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct SolverSettings {
    /// Time-stepping scheme.
    pub scheme: Scheme,
    /// Attraction `alpha` of eq. 4 (inverse length).
    pub alpha: f64,
    /// Semi-implicit: the time step. Explicit: the largest step allowed (the stability
    /// bound usually decides).
    pub dt: f64,
    /// Explicit: fraction of the stability bound used, in (0, 1].
    pub cfl: f64,
    /// Explicit: per-vertex time steps, each vertex at its own stability bound (capped
    /// by `dt`), instead of the global minimum.
    pub local_dt: bool,
    /// Stopping tolerance of eq. 11: `max |u|` over the data points.
    pub eps: f64,
    /// Capture phase: vertices closer than this to the data do not move (see
    /// [`Solver::solve`]).
    pub tube: f64,
    /// Run the settle phase (d-weighted curvature flow) after the capture phase; when
    /// false, `solve` returns once the capture phase ends (the caller centres the curve
    /// on the data instead, as `reconstruct` does by default).
    pub settle_flow: bool,
    /// Narrow band: only vertices with `|u| < band` move (`f64::INFINITY`: all). The
    /// level set is renormalized out to `2 band`, beyond which it keeps its sign and a
    /// magnitude of at least `2 band`.
    pub band: f64,
    /// Renormalize every this many iterations (0: never).
    pub renormalize_every: usize,
    /// Iteration cap.
    pub max_iterations: usize,
    /// Evaluate the stopping test every this many iterations.
    pub check_every: usize,
    /// Stop after this many iterations without improving the best residual by 0.1%;
    /// the best level set found is returned.
    pub patience: usize,
    /// Distances below this count as this (so that `m_i / d_i` stays finite).
    pub d_floor: f64,
    /// The linear solver of the semi-implicit step.
    pub linear: LinearSolver,
    /// Conjugate gradients stop when the preconditioned residual norm `sqrt(r . z)` has
    /// dropped by this factor (dimensionless).
    pub cg_tol: f64,
    /// Conjugate-gradient iteration cap per step.
    pub cg_max: usize,
}

/// What the stopping tests decided after a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Go,
    Stop,
    /// Go on in the settle phase.
    Settle,
}

/// Where a solve stands between stopping tests.
struct Progress {
    /// Smallest mean `|u|` at the data so far.
    best: f64,
    /// `best` when the current patience window opened.
    window_mean: f64,
    /// The iteration that opened it.
    window_start: usize,
    /// In the settle phase.
    settling: bool,
}

/// Why the iteration stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum StopReason {
    /// Eq. 11 holds: every data point within `eps` of the zero level set.
    #[default]
    Converged,
    /// The mean `|u|` at the data stopped improving in the settle phase (noisy data, for
    /// which eq. 11 cannot hold below the noise amplitude); the best level set is kept.
    Settled,
    /// The iteration cap was reached; the best level set is kept.
    MaxIterations,
}

impl StopReason {
    /// A lower-case name for reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            StopReason::Converged => "converged",
            StopReason::Settled => "settled",
            StopReason::MaxIterations => "max_iterations",
        }
    }
}

/// What a solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SolveReport {
    /// Time steps taken.
    pub iterations: usize,
    /// Eq. 11 residual of the returned level set.
    pub residual: f64,
    /// Mean `|u|` at the data points for the returned level set.
    pub mean_residual: f64,
    /// Eq. 11 residual of the initial level set.
    pub initial_residual: f64,
    /// Iterations of the capture phase (all of them if it never ended).
    pub capture_iterations: usize,
    /// Iteration at which the returned level set was reached.
    pub best_iteration: usize,
    /// Whether eq. 11 was met.
    pub converged: bool,
    /// Why the iteration stopped.
    pub stop: StopReason,
    /// Renormalizations done.
    pub renormalizations: usize,
    /// Conjugate-gradient iterations, summed over steps (semi-implicit).
    pub linear_iterations: usize,
    /// The time step (explicit with a global step: the smallest used).
    pub dt: f64,
    /// Milliseconds in time stepping and stopping tests.
    pub ms_solve: f64,
    /// Milliseconds in renormalization.
    pub ms_renormalize: f64,
    /// The 90th percentile of `|u|` at the data: how far the curve is from the data,
    /// robust to the outliers and isolated returns that the maximum (eq. 11) follows.
    pub spread: f64,
    /// The share of the data within the median settle's reach (`4 sigma + 4 hmin`) of
    /// the curve.
    pub near: f64,
}

/// The stopping residual of eq. 11, the largest `|u|` interpolated at the data points,
/// and the mean `|u|` there.
pub fn residual(mesh: &Mesh, data: &[Location], u: &[f64]) -> (f64, f64) {
    let (max, sum) = data
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|l| {
            let a = l.interpolate(mesh, u).abs();
            (a, a)
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1 + b.1));
    (max, sum / data.len().max(1) as f64)
}

/// Robust measures of how far the zero isoline of `u` is from the data: the 90th
/// percentile of `|u|` there, and the share of the data with `|u| <= width`.
pub fn spread(mesh: &Mesh, data: &[Location], u: &[f64], width: f64) -> (f64, f64) {
    if data.is_empty() {
        return (0.0, 1.0);
    }
    let mut a: Vec<f64> = data
        .par_iter()
        .with_min_len(MIN_LEN)
        .map(|l| l.interpolate(mesh, u).abs())
        .collect();
    let near = a.iter().filter(|&&x| x <= width).count() as f64 / a.len() as f64;
    let k = ((0.9 * a.len() as f64).ceil() as usize).clamp(1, a.len()) - 1;
    let (_, p90, _) = a.select_nth_unstable_by(k, f64::total_cmp);
    (*p90, near)
}

/// The curvature operator `K(u)` as a CSR matrix whose pattern (vertex rings, the
/// diagonal first in each row) and geometric coefficients are fixed per mesh: assembling
/// it for a new `u` is one pass over triangles (`1 / |grad u_T|`) and one over entries.
#[derive(Debug, Default)]
struct Op {
    row_off: Vec<u32>,
    col: Vec<u32>,
    /// `K_ij` for the current `u`.
    val: Vec<f64>,
    /// Per entry, its contributions `(triangle, |T| grad phi_i . grad phi_j)`.
    contrib_off: Vec<u32>,
    contrib: Vec<(u32, f64)>,
    /// Per triangle: `1 / |grad u_T|`, regularised.
    inv_grad: Vec<f64>,
    /// Lumped mass per vertex.
    mass: Vec<f64>,
    /// Floored distances.
    d: Vec<f64>,
    /// Pinned vertices: they do not move.
    frozen: Vec<bool>,
    /// Per vertex, for the current step: `m_i / (dt d_i)`, with `d_i` the floor outside
    /// the narrow band (so that those vertices do not move).
    md: Vec<f64>,
}

impl Op {
    fn prepare(&mut self, mesh: &Mesh, space: &P1Space, dist: &[f64], d_floor: f64) {
        let nv = mesh.num_vertices();
        let nt = mesh.num_triangles();
        self.row_off.clear();
        self.col.clear();
        self.row_off.push(0);
        for v in 0..nv {
            self.col.push(v as u32);
            self.col.extend_from_slice(space.ring(v));
            self.row_off.push(self.col.len() as u32);
        }
        let nnz = self.col.len();
        let entry = |i: usize, j: u32, col: &[u32], off: &[u32]| -> usize {
            let r = off[i] as usize..off[i + 1] as usize;
            r.start
                + col[r]
                    .iter()
                    .position(|&c| c == j)
                    .expect("triangle neighbours are ring neighbours")
        };
        // Count, then fill, the contributions of each entry.
        let mut count = vec![0u32; nnz + 1];
        for tri in &mesh.tris {
            for a in 0..3 {
                for b in 0..3 {
                    count[entry(tri[a] as usize, tri[b], &self.col, &self.row_off) + 1] += 1;
                }
            }
        }
        for e in 0..nnz {
            count[e + 1] += count[e];
        }
        self.contrib_off.clear();
        self.contrib_off.extend_from_slice(&count);
        let mut fill = count;
        self.contrib.clear();
        self.contrib.resize(9 * nt, (0, 0.0));
        for (t, tri) in mesh.tris.iter().enumerate() {
            let g = &space.shape_grad[t];
            for a in 0..3 {
                for b in 0..3 {
                    let e = entry(tri[a] as usize, tri[b], &self.col, &self.row_off);
                    self.contrib[fill[e] as usize] = (t as u32, space.area[t] * dot(g[a], g[b]));
                    fill[e] += 1;
                }
            }
        }
        self.val.clear();
        self.val.resize(nnz, 0.0);
        self.inv_grad.clear();
        self.inv_grad.resize(nt, 0.0);
        self.mass.clear();
        self.mass.extend(space.ball_area.iter().map(|a| a / 3.0));
        self.d.clear();
        self.d.extend(dist.iter().map(|&d| d.max(d_floor)));
        self.md.clear();
        self.md.resize(nv, 0.0);
        self.frozen.clear();
        self.frozen.resize(nv, false);
    }

    /// Assembles `K(u)`.
    fn assemble(&mut self, mesh: &Mesh, space: &P1Space, u: &[f64]) {
        self.inv_grad
            .par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(t, w)| {
                let g = grad(mesh, space, t, u);
                *w = 1.0 / (dot(g, g) + GRAD_FLOOR * GRAD_FLOOR).sqrt();
            });
        let (off, contrib, inv_grad) = (&self.contrib_off, &self.contrib, &self.inv_grad);
        self.val
            .par_iter_mut()
            .enumerate()
            .with_min_len(4 * MIN_LEN)
            .for_each(|(e, v)| {
                *v = contrib[off[e] as usize..off[e + 1] as usize]
                    .iter()
                    .map(|&(t, c)| c * inv_grad[t as usize])
                    .sum();
            });
    }

    /// `(K v)_i`.
    #[inline]
    fn row_dot(&self, i: usize, v: &[f64]) -> f64 {
        let r = self.row_off[i] as usize..self.row_off[i + 1] as usize;
        self.val[r.clone()]
            .iter()
            .zip(&self.col[r])
            .map(|(k, &j)| k * v[j as usize])
            .sum()
    }

    /// `K_ii`.
    #[inline]
    fn diag(&self, i: usize) -> f64 {
        self.val[self.row_off[i] as usize]
    }

    /// The explicit stability bound at vertex `i`: `m_i / (d_i sum_j |K_ij|)`. By
    /// Gershgorin every eigenvalue of `D M^-1 K` is at most `max_i d_i sum_j |K_ij| / m_i`,
    /// so a global step no larger than the smallest bound keeps forward Euler stable (and
    /// monotone where `K` is an M-matrix).
    #[inline]
    fn bound_at(&self, i: usize) -> f64 {
        let r = self.row_off[i] as usize..self.row_off[i + 1] as usize;
        let row: f64 = self.val[r].iter().map(|k| k.abs()).sum();
        self.mass[i] / (self.d[i] * row)
    }
}

/// Solver buffers, sized once per mesh so that iterations do not allocate.
#[derive(Debug, Default)]
pub struct Solver {
    op: Op,
    kappa: Vec<f64>,
    diag: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    best: Vec<f64>,
    redistancer: Redistancer,
    /// GMRES: Krylov basis, `(cg_max + 1)` vectors of one value per vertex, and the
    /// Hessenberg matrix with its Givens rotations.
    basis: Vec<f64>,
    hess: Vec<f64>,
    givens: Vec<(f64, f64)>,
    g: Vec<f64>,
}

impl Solver {
    /// Empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    fn prepare(&mut self, mesh: &Mesh, space: &P1Space, dist: &[f64], s: &SolverSettings) {
        self.op.prepare(mesh, space, dist, s.d_floor);
        let nv = mesh.num_vertices();
        if s.linear == LinearSolver::Gmres {
            let m = s.cg_max.max(1);
            self.basis.clear();
            self.basis.resize((m + 1) * nv, 0.0);
            self.hess.clear();
            self.hess.resize((m + 1) * m, 0.0);
            self.givens.clear();
            self.givens.resize(m, (1.0, 0.0));
            self.g.clear();
            self.g.resize(m + 1, 0.0);
        }
        for b in [
            &mut self.kappa,
            &mut self.diag,
            &mut self.r,
            &mut self.z,
            &mut self.p,
            &mut self.q,
            &mut self.best,
        ] {
            b.clear();
            b.resize(nv, 0.0);
        }
    }

    /// Evolves `u` (one value per vertex, negative inside) towards the data points
    /// `data`; `dist` is the unsigned distance to the data at each vertex.
    ///
    /// The evolution runs in two phases. In the capture phase, vertices closer than
    /// `tube` to the data do not move: in the discrete problem `d` never vanishes at a
    /// vertex, and without this the curvature term, large where the curve kinks around
    /// noisy samples, carries the curve through the data while other parts of it are
    /// still on their way (into a concavity, say). The phase ends when eq. 11 holds
    /// (converged), or when the mean `|u|` at the data improves by less than 1% over
    /// `patience` iterations: the curve then rests on the outermost samples. The settle
    /// phase frees those vertices and drops `alpha`, so that the d-weighted curvature flow
    /// smooths the curve into the noise band; the level set with the smallest mean `|u|`
    /// at the data (the curve through the middle of the noise) is kept, and the phase ends
    /// the same way.
    pub fn solve(
        &mut self,
        mesh: &Mesh,
        space: &P1Space,
        dist: &[f64],
        data: &[Location],
        u: &mut [f64],
        s: &SolverSettings,
    ) -> SolveReport {
        let _span = tracing::debug_span!("solve", scheme = %s.scheme, vertices = u.len()).entered();
        let t_start = Instant::now();
        self.prepare(mesh, space, dist, s);
        let mut report = SolveReport {
            dt: f64::INFINITY,
            ..Default::default()
        };
        let mut renorm_time = 0.0;
        let (res0, mean0) = residual(mesh, data, u);
        report.initial_residual = res0;
        report.residual = res0;
        report.mean_residual = mean0;
        if res0 < s.eps {
            report.converged = true;
            report.ms_solve = t_start.elapsed().as_secs_f64() * 1e3;
            return report;
        }
        let mut progress = Progress {
            best: mean0,
            window_mean: mean0,
            window_start: 0,
            settling: false,
        };
        let mut settle_settings = s.clone();
        self.pin(s.tube);
        self.best.copy_from_slice(u);
        report.stop = StopReason::MaxIterations;
        for it in 1..=s.max_iterations {
            let step = if progress.settling {
                &settle_settings
            } else {
                s
            };
            match s.scheme {
                Scheme::Explicit => {
                    let dt = self.explicit_step(mesh, space, u, step);
                    report.dt = report.dt.min(dt);
                }
                Scheme::SemiImplicit => {
                    report.linear_iterations += self.semi_implicit_step(mesh, space, u, step);
                    report.dt = s.dt;
                }
            }
            report.iterations = it;
            let verdict = self.stop_test(it, mesh, data, u, s, &mut progress, &mut report);
            if verdict == Verdict::Stop {
                break;
            }
            // After the test: a renormalization on the step that ends the solve would be
            // wasted (callers renormalize what they keep).
            if s.renormalize_every > 0 && it % s.renormalize_every == 0 {
                let t = Instant::now();
                self.redistancer.run(mesh, space, u, 2.0 * s.band);
                renorm_time += t.elapsed().as_secs_f64();
                report.renormalizations += 1;
            }
            if verdict == Verdict::Settle {
                self.pin(0.0);
                // No attraction while settling: the d-weighted curvature flow alone
                // smooths the curve off the outermost samples into the noise band,
                // without the drive that would carry it on through the data.
                settle_settings.alpha = 0.0;
            }
        }
        if report.capture_iterations == 0 {
            report.capture_iterations = report.iterations;
        }
        if !report.converged {
            u.copy_from_slice(&self.best);
        }
        report.ms_renormalize = renorm_time * 1e3;
        report.ms_solve = t_start.elapsed().as_secs_f64() * 1e3 - report.ms_renormalize;
        report
    }

    /// The stopping tests after step `it`: whether the solve goes on, is over, or enters
    /// the settle phase (the capture phase stagnated and `s.settle_flow` asks for it;
    /// `progress.settling` is then set). Tracks the best level set (into `self.best`) and
    /// the patience window.
    #[allow(clippy::too_many_arguments)]
    fn stop_test(
        &mut self,
        it: usize,
        mesh: &Mesh,
        data: &[Location],
        u: &[f64],
        s: &SolverSettings,
        progress: &mut Progress,
        report: &mut SolveReport,
    ) -> Verdict {
        if !it.is_multiple_of(s.check_every.max(1)) && it != s.max_iterations {
            return Verdict::Go;
        }
        let (res, mean) = residual(mesh, data, u);
        tracing::trace!(
            iteration = it,
            residual = res,
            mean,
            progress.settling,
            "step"
        );
        if res < s.eps {
            report.residual = res;
            report.mean_residual = mean;
            report.best_iteration = it;
            report.stop = StopReason::Converged;
            report.converged = true;
            return Verdict::Stop;
        }
        if mean < progress.best {
            progress.best = mean;
            report.best_iteration = it;
            report.residual = res;
            report.mean_residual = mean;
            self.best.copy_from_slice(u);
        }
        if it - progress.window_start >= s.patience {
            // Less than 1% better over a whole window: this phase is done.
            if progress.best > 0.99 * progress.window_mean {
                if progress.settling || !s.settle_flow {
                    report.stop = StopReason::Settled;
                    return Verdict::Stop;
                }
                progress.settling = true;
                report.capture_iterations = it;
                progress.window_mean = progress.best;
                progress.window_start = it;
                return Verdict::Settle;
            }
            progress.window_mean = progress.best;
            progress.window_start = it;
        }
        Verdict::Go
    }

    /// One forward Euler step; returns the (smallest) step used.
    fn explicit_step(
        &mut self,
        mesh: &Mesh,
        space: &P1Space,
        u: &mut [f64],
        s: &SolverSettings,
    ) -> f64 {
        self.op.assemble(mesh, space, u);
        let op = &self.op;
        let alpha = s.alpha;
        let uu = &*u;
        // Curvature and bound first: the update must not see half-updated neighbours.
        // `kappa` is NaN where a vertex does not move (outside the band, or pinned); the
        // per-vertex bounds go to `diag`, which only the semi-implicit step uses otherwise.
        let bound = self
            .kappa
            .par_iter_mut()
            .zip(self.diag.par_iter_mut())
            .enumerate()
            .with_min_len(MIN_LEN)
            .map(|(i, (k, b))| {
                if uu[i].abs() >= s.band || op.frozen[i] {
                    *k = f64::NAN;
                    return f64::INFINITY;
                }
                *k = -op.row_dot(i, uu) / op.mass[i];
                *b = op.bound_at(i);
                *b
            })
            .reduce(|| f64::INFINITY, f64::min);
        let global = (s.cfl * bound).min(s.dt);
        let (kappa, bounds, local) = (&self.kappa, &self.diag, s.local_dt);
        u.par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, ui)| {
                if !kappa[i].is_nan() {
                    let dt = if local {
                        (s.cfl * bounds[i]).min(s.dt)
                    } else {
                        global
                    };
                    *ui += dt * op.d[i] * (alpha + kappa[i]);
                }
            });
        global
    }

    /// Freezes the vertices closer than `tube` to the data (and frees the others).
    fn pin(&mut self, tube: f64) {
        let d = &self.op.d;
        self.op
            .frozen
            .par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, f)| *f = d[i] < tube);
    }

    /// One semi-implicit step by preconditioned conjugate gradients from `u^n`; returns
    /// the iterations taken. Row `i` is divided by `dt d_i / m_i`:
    /// `(m_i / (dt d_i)) u_i^{n+1} + (K u^{n+1})_i = (m_i / (dt d_i)) u_i^n + alpha m_i`.
    fn semi_implicit_step(
        &mut self,
        mesh: &Mesh,
        space: &P1Space,
        u: &mut [f64],
        s: &SolverSettings,
    ) -> usize {
        self.op.assemble(mesh, space, u);
        {
            let (op_d, op_mass, pinned) = (&self.op.d, &self.op.mass, &self.op.frozen);
            let frozen = s.dt * s.d_floor;
            self.op
                .md
                .par_iter_mut()
                .enumerate()
                .with_min_len(MIN_LEN)
                .for_each(|(i, md)| {
                    let e = if u[i].abs() < s.band && !pinned[i] {
                        s.dt * op_d[i]
                    } else {
                        frozen
                    };
                    *md = op_mass[i] / e;
                });
        }
        let op = &self.op;
        // r = b - A u, z = r / diag, p = z.
        let mut rz = self
            .r
            .par_iter_mut()
            .zip(self.z.par_iter_mut())
            .zip(self.p.par_iter_mut())
            .zip(self.diag.par_iter_mut())
            .enumerate()
            .with_min_len(MIN_LEN)
            .map(|(i, (((r, z), p), dg))| {
                *dg = op.md[i] + op.diag(i);
                let alpha = if u[i].abs() < s.band && !op.frozen[i] {
                    s.alpha
                } else {
                    0.0
                };
                *r = alpha * op.mass[i] - op.row_dot(i, u);
                *z = *r / *dg;
                *p = *z;
                *r * *z
            })
            .sum::<f64>();
        if s.linear == LinearSolver::Gmres {
            return self.gmres(u, s);
        }
        let stop = rz * s.cg_tol * s.cg_tol;
        let mut its = 0;
        while its < s.cg_max && rz > stop && rz > 0.0 {
            its += 1;
            let p = &self.p;
            let pq = self
                .q
                .par_iter_mut()
                .enumerate()
                .with_min_len(MIN_LEN)
                .map(|(i, q)| {
                    *q = op.md[i] * p[i] + op.row_dot(i, p);
                    *q * p[i]
                })
                .sum::<f64>();
            if pq <= 0.0 {
                break;
            }
            let a = rz / pq;
            let (q, diag) = (&self.q, &self.diag);
            let rz_new = u
                .par_iter_mut()
                .zip(self.r.par_iter_mut())
                .zip(self.z.par_iter_mut())
                .enumerate()
                .with_min_len(MIN_LEN)
                .map(|(i, ((x, r), z))| {
                    *x += a * p[i];
                    *r -= a * q[i];
                    *z = *r / diag[i];
                    *r * *z
                })
                .sum::<f64>();
            let beta = rz_new / rz;
            rz = rz_new;
            let z = &self.z;
            self.p
                .par_iter_mut()
                .enumerate()
                .with_min_len(MIN_LEN)
                .for_each(|(i, p)| *p = z[i] + beta * *p);
        }
        its
    }
}

impl Solver {
    /// GMRES without restart (at most `cg_max` iterations) on the paper's non-symmetric
    /// form `u + dt D M^-1 K u = u^n + dt alpha d`, left-preconditioned by its diagonal.
    /// Each row of that form is row `i` of the symmetrised system divided by `m_i / (dt
    /// d_i)`, so the preconditioned operator is `diag^-1 A` for the symmetric `A` and its
    /// diagonal `diag`: the very operator conjugate gradients see. Expects `z` to hold
    /// the preconditioned initial residual. Returns the iterations taken.
    fn gmres(&mut self, u: &mut [f64], s: &SolverSettings) -> usize {
        let n = u.len();
        let m = s.cg_max.max(1);
        let dot = |a: &[f64], b: &[f64]| -> f64 {
            a.par_iter()
                .zip(b.par_iter())
                .with_min_len(MIN_LEN)
                .map(|(x, y)| x * y)
                .sum()
        };
        let beta = dot(&self.z, &self.z).sqrt();
        if beta == 0.0 {
            return 0;
        }
        self.basis[..n]
            .par_iter_mut()
            .zip(self.z.par_iter())
            .with_min_len(MIN_LEN)
            .for_each(|(v, z)| *v = z / beta);
        self.g.iter_mut().for_each(|g| *g = 0.0);
        self.g[0] = beta;
        let mut k = 0;
        while k < m {
            // w = diag^-1 A v_k, into basis slot k + 1.
            let (head, tail) = self.basis.split_at_mut((k + 1) * n);
            let vk = &head[k * n..];
            let w = &mut tail[..n];
            let op = &self.op;
            let diag = &self.diag;
            w.par_iter_mut()
                .enumerate()
                .with_min_len(MIN_LEN)
                .for_each(|(i, w)| *w = (op.md[i] * vk[i] + op.row_dot(i, vk)) / diag[i]);
            // Modified Gram-Schmidt.
            for i in 0..=k {
                let vi = &head[i * n..(i + 1) * n];
                let h = dot(w, vi);
                self.hess[i * m + k] = h;
                w.par_iter_mut()
                    .zip(vi.par_iter())
                    .with_min_len(MIN_LEN)
                    .for_each(|(w, v)| *w -= h * v);
            }
            let norm = dot(w, w).sqrt();
            self.hess[(k + 1) * m + k] = norm;
            if norm > 0.0 {
                w.par_iter_mut()
                    .with_min_len(MIN_LEN)
                    .for_each(|w| *w /= norm);
            }
            // Apply the previous rotations to column k, then zero its subdiagonal.
            for i in 0..k {
                let (c, sn) = self.givens[i];
                let (a, b) = (self.hess[i * m + k], self.hess[(i + 1) * m + k]);
                self.hess[i * m + k] = c * a + sn * b;
                self.hess[(i + 1) * m + k] = -sn * a + c * b;
            }
            let (a, b) = (self.hess[k * m + k], self.hess[(k + 1) * m + k]);
            let r = a.hypot(b);
            let (c, sn) = if r > 0.0 { (a / r, b / r) } else { (1.0, 0.0) };
            self.givens[k] = (c, sn);
            self.hess[k * m + k] = r;
            self.hess[(k + 1) * m + k] = 0.0;
            self.g[k + 1] = -sn * self.g[k];
            self.g[k] *= c;
            k += 1;
            if self.g[k].abs() <= s.cg_tol * beta || norm == 0.0 {
                break;
            }
        }
        // Back substitution for y (stored in g), then u += V y.
        for i in (0..k).rev() {
            let mut acc = self.g[i];
            for j in i + 1..k {
                acc -= self.hess[i * m + j] * self.g[j];
            }
            self.g[i] = acc / self.hess[i * m + i];
        }
        let (basis, g) = (&self.basis, &self.g);
        u.par_iter_mut()
            .enumerate()
            .with_min_len(MIN_LEN)
            .for_each(|(i, x)| {
                for j in 0..k {
                    *x += g[j] * basis[j * n + i];
                }
            });
        k
    }
}

#[inline]
fn grad(mesh: &Mesh, space: &P1Space, t: usize, u: &[f64]) -> Point {
    let tri = mesh.tris[t];
    let sg = &space.shape_grad[t];
    let (u0, u1, u2) = (u[tri[0] as usize], u[tri[1] as usize], u[tri[2] as usize]);
    [
        u0 * sg[0][0] + u1 * sg[1][0] + u2 * sg[2][0],
        u0 * sg[0][1] + u1 * sg[1][1] + u2 * sg[2][1],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::DistanceField;
    use crate::fem::locate::locate_all;
    use crate::geom::{norm, BBox};
    use crate::levelset::init;

    struct Case {
        mesh: Mesh,
        space: P1Space,
        dist: Vec<f64>,
        data: Vec<Location>,
        settings: SolverSettings,
    }

    /// 400 points on the circle of radius 0.3 in a 120 x 120 structured mesh of
    /// [-0.5, 0.5]^2 (h = 1/120).
    fn circle_case(scheme: Scheme) -> Case {
        let pts: Vec<Point> = (0..400)
            .map(|i| {
                let a = i as f64 / 400.0 * std::f64::consts::TAU;
                [0.3 * a.cos(), 0.3 * a.sin()]
            })
            .collect();
        let mesh = Mesh::structured(
            &BBox {
                min: [-0.5, -0.5],
                max: [0.5, 0.5],
            },
            120,
        );
        let space = P1Space::new(&mesh);
        let mut dist = Vec::new();
        DistanceField::new(&pts)
            .unwrap()
            .distances_into(&mesh.coords, &mut dist);
        let data = locate_all(&mesh, &pts);
        let h = 1.0 / 120.0;
        let explicit = scheme == Scheme::Explicit;
        let settings = SolverSettings {
            scheme,
            alpha: 10.0,
            dt: 10.0 * h,
            cfl: 0.9,
            local_dt: true,
            eps: h,
            tube: 4.0 * h,
            settle_flow: true,
            band: 0.1,
            renormalize_every: if explicit { 100 } else { 5 },
            max_iterations: if explicit { 100_000 } else { 2_000 },
            check_every: if explicit { 10 } else { 1 },
            patience: if explicit { 1_000 } else { 10 },
            d_floor: 1e-6 * h,
            cg_tol: 1e-2,
            cg_max: 10,
            linear: LinearSolver::Cg,
        };
        Case {
            mesh,
            space,
            dist,
            data,
            settings,
        }
    }

    #[test]
    fn a_level_set_already_on_the_data_stops_at_once() {
        let c = circle_case(Scheme::SemiImplicit);
        let mut u = init::circle([0.0, 0.0], 0.3, &c.mesh.coords);
        let r = Solver::new().solve(&c.mesh, &c.space, &c.dist, &c.data, &mut u, &c.settings);
        assert_eq!(r.iterations, 0);
        assert!(r.converged && r.stop == StopReason::Converged);
        // P1 interpolation of |x| - 0.3 on a mesh of size h errs by O(h^2 / r).
        assert!(r.residual < 0.01 * c.settings.eps, "{r:?}");
    }

    #[test]
    fn both_schemes_meet_eq_11_on_clean_data() {
        for scheme in [Scheme::SemiImplicit, Scheme::Explicit] {
            let c = circle_case(scheme);
            let mut u = init::circle([0.0, 0.0], 0.42, &c.mesh.coords);
            let r = Solver::new().solve(&c.mesh, &c.space, &c.dist, &c.data, &mut u, &c.settings);
            assert!(r.converged, "{scheme}: {r:?}");
            // The test itself, recomputed on the returned level set.
            let (max, _) = residual(&c.mesh, &c.data, &u);
            assert_eq!(max, r.residual);
            assert!(max < c.settings.eps);
            // And the curve is where the data is: within eps + h of radius 0.3 wherever
            // it crosses an edge.
            for (t, tri) in c.mesh.tris.iter().enumerate() {
                let s = tri.map(|v| u[v as usize] >= 0.0);
                if s[0] != s[1] || s[1] != s[2] {
                    for p in crate::redistance::cut_segment(&c.mesh, t, &u) {
                        assert!((norm(p) - 0.3).abs() < 2.0 / 120.0, "{scheme}: {p:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn gmres_and_conjugate_gradients_solve_the_same_step() {
        // Solved tightly, the two Krylov solvers must agree on one semi-implicit step.
        let mut c = circle_case(Scheme::SemiImplicit);
        c.settings.cg_tol = 1e-10;
        c.settings.cg_max = 200;
        let start = init::circle([0.0, 0.0], 0.42, &c.mesh.coords);
        let mut out = Vec::new();
        for linear in [LinearSolver::Cg, LinearSolver::Gmres] {
            c.settings.linear = linear;
            let mut solver = Solver::new();
            solver.prepare(&c.mesh, &c.space, &c.dist, &c.settings);
            let mut u = start.clone();
            let its = solver.semi_implicit_step(&c.mesh, &c.space, &mut u, &c.settings);
            assert!(its > 0 && its < 200, "{linear:?}: {its}");
            out.push(u);
        }
        let diff = out[0]
            .iter()
            .zip(&out[1])
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let moved = out[0]
            .iter()
            .zip(&start)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(moved > 1e-3, "the step moves the level set: {moved}");
        assert!(diff < 1e-6 * moved.max(1.0), "{diff}");
    }

    #[test]
    fn the_iteration_cap_keeps_the_best_level_set() {
        let mut c = circle_case(Scheme::SemiImplicit);
        c.settings.max_iterations = 3;
        let mut u = init::circle([0.0, 0.0], 0.45, &c.mesh.coords);
        let r = Solver::new().solve(&c.mesh, &c.space, &c.dist, &c.data, &mut u, &c.settings);
        assert_eq!(r.stop, StopReason::MaxIterations);
        assert!(!r.converged && r.iterations == 3);
        assert!(r.residual < r.initial_residual);
        let (max, mean) = residual(&c.mesh, &c.data, &u);
        assert_eq!((max, mean), (r.residual, r.mean_residual));
    }
}
