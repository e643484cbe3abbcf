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
    /// Its returns that its curves leave unexplained (farther than the accuracy bound
    /// `3 sigma + 2 hmin` from every curve): where it sees a surface it drew no curve of.
    pub unexplained: Vec<Point>,
    /// Its range noise.
    pub sigma: f64,
    /// Its support's tolerance, `2 sigma + hmin`.
    pub tol: f64,
}

/// What a window makes of its newest frame, in the world's coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Refined {
    /// The frame's curves refined by the window, one per curve of the frame, in order.
    pub curves: Vec<Polyline>,
    /// Pieces of older frames' curves where the frame has returns its own curves leave
    /// unexplained, each point of them within the frame's support tolerance of one.
    pub filled: Vec<Polyline>,
    /// The older frames' returns as the window placed them: the evidence the refined
    /// curves are checked against.
    pub evidence: Vec<Point>,
}

/// A stream's window of earlier frames that refines each new frame's curves.
pub trait Refiner: Send + Sync + std::fmt::Debug {
    /// Adds `frame` as the newest and returns what the window makes of it; `None` when
    /// the window holds the frame alone.
    fn refine(&mut self, frame: RefineFrame) -> Option<Refined>;

    /// What the window holds now.
    fn stats(&self) -> WindowStats;
}
