//! Refinement over frames, as the export stage sees it: a stream's scan frames with
//! poses are fused by a window of the last frames that lives above this crate
//! (`isoline-map`'s `Window`); the export hands it each frame's curves and returns and
//! takes back the refined curves, which it then checks against the frame's own data
//! ([`crate::stages::export_refined`]).

use crate::geom::{Point, Polyline};
use crate::stats::WindowStats;

/// One scan frame as a [`Refiner`] takes it, in the world's coordinates and the data's
/// units.
#[derive(Clone, Debug, PartialEq)]
pub struct RefineFrame {
    /// The frame's number: one that does not go up restarts the window.
    pub frame: u64,
    /// Its time stamp, seconds.
    pub t: Option<f64>,
    /// Its curves, as a single frame draws them.
    pub curves: Vec<Polyline>,
    /// Its runs' returns.
    pub returns: Vec<Point>,
    /// Its range noise.
    pub sigma: f64,
    /// Its support's tolerance, `2 sigma + hmin`.
    pub tol: f64,
}

/// A stream's window of earlier frames that refines each new frame's curves.
pub trait Refiner: Send + Sync + std::fmt::Debug {
    /// Adds `frame` as the newest and returns its curves refined by the window (one per
    /// curve of the frame, in order) with the older frames' returns as the window
    /// placed them (the evidence the refined curves are checked against), in the
    /// world's coordinates; `None` when the window holds the frame alone.
    fn refine(&mut self, frame: RefineFrame) -> Option<(Vec<Polyline>, Vec<Point>)>;

    /// What the window holds now.
    fn stats(&self) -> WindowStats;
}
