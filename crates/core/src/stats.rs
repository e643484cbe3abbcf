//! What one reconstruction did: sizes, the solver's outcome, the fit and the time per
//! stage. Plain data: the file formats (isoline-io) render it as a record's `stats`.

use crate::levelset::{Scheme, Start, StopReason};

/// Milliseconds per stage of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct StageMs {
    /// Validation, centring, the kd-tree and distances at the mesh vertices.
    pub distance: f64,
    /// Metric and mesh adaptation.
    pub adapt: f64,
    /// Time stepping and stopping tests.
    pub solve: f64,
    /// Fast-marching renormalization.
    pub renormalize: f64,
    /// Isoline extraction, repair and the fit.
    pub export: f64,
    /// The whole frame: the sum of the stages.
    pub total: f64,
    /// From the frame's arrival to its result, queueing included: what a caller that
    /// queues frames measures (the daemon); `None` from the library.
    #[cfg_attr(
        feature = "serde",
        serde(default, skip_serializing_if = "Option::is_none")
    )]
    pub latency: Option<f64>,
}

/// The window of frames a refined frame was reconstructed from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct WindowStats {
    /// Frames in it, this one included.
    pub frames: usize,
    /// Their returns.
    pub points: usize,
    /// Bytes the stream's window holds, roughly.
    pub bytes: usize,
}

/// Per-frame statistics of a [`crate::Reconstruction`], as a result record's `stats`
/// (docs/formats.md) writes them: a field a record leaves out reads as its default.
#[derive(Clone, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(default))]
#[non_exhaustive]
pub struct Stats {
    /// Data points given.
    pub points: usize,
    /// Mesh vertices.
    pub vertices: usize,
    /// Mesh triangles.
    pub triangles: usize,
    /// Solver time steps.
    pub iterations: usize,
    /// Eq. 11 residual: the largest `|u|` at a data point (scans: at a return of a run).
    pub residual: f64,
    /// Whether the residual got below `eps`.
    pub converged: bool,
    /// Where the frame's level set came from.
    pub start: Start,
    /// Whether earlier frames shaped the result: a point frame's warm start, or a scan
    /// refined over its window (`start` is `Warm` or `Fused`).
    pub warm_start: bool,
    /// Earlier frames were tried and rejected (`start` is `Fallback`; `warm_start` is
    /// then false).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "std::ops::Not::not"))]
    pub cold_fallback: bool,
    /// Time per stage.
    pub ms: StageMs,
    /// Why the solver stopped.
    pub stop: StopReason,
    /// The time-stepping scheme used.
    pub scheme: Scheme,
    /// Conjugate-gradient iterations (semi-implicit).
    pub linear_iterations: usize,
    /// Renormalizations.
    pub renormalizations: usize,
    /// Smallest element size used, in data units.
    pub hmin: f64,
    /// Stopping tolerance used, in data units.
    pub eps: f64,
    /// Scan frames: returns that no curve explains (the features' returns); point
    /// clouds with outliers: how many.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub unexplained: Option<usize>,
    /// Scan frames: the range noise used (configured, or estimated from the returns).
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub range_noise: Option<f64>,
    /// Point clouds: the noise estimated from the samples (the median residual of
    /// local fits), the `sigma` of the accuracy bound `3 sigma + 2 hmin`.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub noise: Option<f64>,
    /// The share of the points within `3 sigma + 2 hmin` of a curve.
    pub explained: f64,
    /// The 90th percentile of the points' distances to the curves; `None` without
    /// curves.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub fit_p90: Option<f64>,
    /// Refinement over frames: the window the frame was reconstructed from.
    #[cfg_attr(feature = "serde", serde(skip_serializing_if = "Option::is_none"))]
    pub window: Option<WindowStats>,
}
