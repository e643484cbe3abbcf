//! isoline-core reconstructs smooth curves from noisy 2D point data (2D laser scans above
//! all, and digitized contours) with the level-set method of Claisse & Frey (2009): an
//! unsigned distance field to the points, a triangle mesh adapted anisotropically to it,
//! a level set wrapped onto the data with curvature regularization, fast-marching
//! renormalization, and polylines out. It does no I/O and starts no threads beyond
//! rayon's; the file formats are in `isoline-io`, the daemon in the `isoline` binary.
//!
//! A point cloud gives closed curves (holes and separate components included) and, for a
//! drawing, open strokes with their junctions:
//!
//! ```
//! use isoline_core::{reconstruct, Params};
//! // Points around a circle, in no particular order.
//! let pts: Vec<[f64; 2]> = (0..300)
//!     .map(|i| {
//!         let a = i as f64 * 2.4;
//!         [0.5 + 0.4 * a.cos(), 0.5 + 0.4 * a.sin()]
//!     })
//!     .collect();
//! let r = reconstruct(&pts, &Params::default()).unwrap();
//! assert_eq!(r.polylines.len(), 1);
//! assert!(r.polylines[0].closed);
//! assert!(r.warnings.is_empty());
//! ```
//!
//! A scan from a sensor gives open wall curves, the free side on their left, and the
//! returns no curve explains as features ([`reconstruct_scan`]):
//!
//! ```
//! use isoline_core::{reconstruct_scan, LaserScan, Params, Scan};
//! // A wall 2 m in front of a sensor at the origin, seen over 90 degrees.
//! let step = std::f64::consts::FRAC_PI_2 / 180.0;
//! let ranges: Vec<Option<f64>> = (0..181)
//!     .map(|i| Some(2.0 / (-std::f64::consts::FRAC_PI_4 + i as f64 * step).cos()))
//!     .collect();
//! let scan = Scan::from_laser(&LaserScan {
//!     origin: [0.0, 0.0],
//!     angle_min: -std::f64::consts::FRAC_PI_4,
//!     angle_increment: step,
//!     ranges: &ranges,
//!     range_min: 0.1,
//!     range_max: 10.0,
//! })
//! .unwrap();
//! let r = reconstruct_scan(&scan, &Params::default()).unwrap();
//! assert_eq!(r.polylines.len(), 1);
//! assert!(!r.polylines[0].closed);
//! ```
//!
//! Successive frames of a stream warm-start from the previous one
//! ([`reconstruct_warm`]); a scan stream with poses is refined over a window of frames
//! by [`stages::export_refined`] and a [`Refiner`] (isoline-map's window of the last
//! frames). [`stages`] holds the pipeline's stages
//! one by one, as the daemon runs them on channels.
//!
//! The modules are the stages, private; this page lists the API. ARCHITECTURE.md in the
//! repository maps them.

#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

mod band;
mod cloud;
mod disjoint;
mod distance;
mod error;
mod export;
mod fem;
mod field;
pub mod geom;
mod index;
mod levelset;
mod mesh;
mod reconstruct;
mod redistance;
mod refine;
mod repair;
mod scan;
mod stats;
mod stream;
mod warning;

pub use distance::{validate_points, DistanceField, MAX_COORDINATE, MIN_EXTENT};
pub use error::{Error, Result};
pub use export::support::Feature;
pub use export::ExportParams;
pub use field::MeshParams;
pub use geom::{BBox, Point, Polyline, Pose};
pub use index::SegmentIndex;
pub use levelset::{Init, LinearSolver, Scheme, Settle, SolverParams, Start, StopReason};
pub use mesh::Mesh;
pub use reconstruct::{
    reconstruct, reconstruct_scan, reconstruct_warm, FrameKind, Params, Reconstruction, AREA_SHARE,
};
pub use refine::{RefineFrame, Refined, Refiner};
pub use repair::strokes::Junction;
pub use repair::Tolerances as RepairTolerances;
pub use scan::{
    velocity, FreeSpace, LaserScan, RunReturns, Scan, ScanParams, Sweep, MAX_BEAMS, SMOOTHING,
};
pub use stats::{StageMs, Stats, WindowStats};
pub use stream::{Stream, StreamFrame};
pub use warning::Warning;

/// The pipeline's stages one by one, for a caller that runs them apart (the daemon runs
/// each on its own thread): [`prepare`](stages::prepare) (the distance stage),
/// [`adapt`](stages::adapt) or [`adapt_moving`](stages::adapt_moving),
/// [`solve`](stages::solve), [`renormalize`](stages::renormalize), then
/// [`export`](stages::export) or [`export_refined`](stages::export_refined).
/// [`reconstruct`](crate::reconstruct()) is the five in turn.
///
/// ```
/// use isoline_core::{stages, Params};
/// let pts: Vec<[f64; 2]> = (0..200)
///     .map(|i| {
///         let a = i as f64 * std::f64::consts::TAU / 200.0;
///         [a.cos(), 0.5 * a.sin()]
///     })
///     .collect();
/// let prepared = stages::prepare(&pts, None, &Params::default()).unwrap();
/// let adapted = stages::adapt(&prepared, None);
/// let mut solved = stages::solve(&prepared, &adapted, None);
/// stages::renormalize(&adapted.mesh, &mut solved);
/// let r = stages::export(&prepared, adapted, solved);
/// assert_eq!(r.polylines.len(), 1);
/// ```
pub mod stages {
    pub use crate::field::{adapt_to_points, AdaptedMesh, MeshTimings};
    pub use crate::levelset::evolve::{redistance, LevelSet, Solved};
    pub use crate::levelset::warm::Previous;
    pub use crate::levelset::MAX_STEPS;
    pub use crate::mesh::adapt::AdaptReport;
    pub use crate::mesh::metric::MetricParams;
    pub use crate::mesh::quality::MeshStats;
    pub use crate::reconstruct::{
        adapt, adapt_moving, export, export_refined, prepare, reconstruct_with, renormalize, solve,
        Prepared,
    };
    pub use crate::stream::{LevelSetMemory, MeshMemory};
}
