//! The solver's user-facing parameters: what a configuration file sets, with the
//! defaults derived from the data's bounding-box diagonal `D` and the mesh's `hmin`, and
//! their resolution into concrete [`SolverSettings`].

use crate::levelset::init::Init;
use crate::levelset::solver::{LinearSolver, Scheme, SolverSettings};

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
    /// The patience of a frame warm-started at the data (see `crate::levelset::warm`): its curve is
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

/// The most solver steps a setting may ask for: ten million steps is hours on any mesh.
pub const MAX_STEPS: usize = 10_000_000;
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

    /// The same parameters with every length multiplied by `s` (into other units).
    pub fn scaled(&self, s: f64) -> SolverParams {
        SolverParams {
            alpha: self.alpha.map(|a| a / s),
            eps: self.eps.map(|e| e * s),
            tube: self.tube.map(|t| t * s),
            ..self.clone()
        }
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
        // Bounds on the work a frame may take: ten million steps is hours on any mesh.
        for (key, v) in [
            ("solver.max_iterations", self.max_iterations),
            ("solver.patience", self.patience),
            ("solver.warm_patience", self.warm_patience),
            (
                "solver.renormalize_every",
                self.renormalize_every.filter(|&n| n > 0),
            ),
        ] {
            if let Some(n) = v {
                if !(1..=MAX_STEPS).contains(&n) {
                    problems.push(format!("{key} = {n}: must be in 1..={MAX_STEPS}"));
                }
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(problems)
        }
    }

    /// The concrete settings for data of diagonal `diag` on a mesh of smallest size
    /// `hmin`.
    pub(crate) fn resolve(&self, diag: f64, hmin: f64) -> SolverSettings {
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

/// Where a frame's level set came from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "lowercase"))]
pub enum Start {
    /// A point frame started from scratch.
    #[default]
    Cold,
    /// A point frame started from the previous frame's level set.
    Warm,
    /// The previous frames were tried and made the frame worse than its own data
    /// warrant: a point frame's warm start that explained less than the previous frame
    /// (replaced by a cold start), or a scan's refinement that explained fewer of its
    /// returns than its own level set (which it kept).
    Fallback,
    /// A scan frame built from its own scan: its band and the free space its rays swept.
    /// A scan is never warm-started: its own free space is a better start than any
    /// earlier frame's level set, and its band costs less than moving the last one.
    Scan,
    /// A scan frame built from its own scan and refined over its stream's window.
    Fused,
}

impl Start {
    /// The name records carry.
    pub fn name(self) -> &'static str {
        match self {
            Start::Cold => "cold",
            Start::Warm => "warm",
            Start::Fallback => "fallback",
            Start::Scan => "scan",
            Start::Fused => "fused",
        }
    }
}
