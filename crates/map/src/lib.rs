//! Mapping above isoline's method: the poses of a run's scans estimated from the scans
//! themselves, and the run's scans fused into one map.
//!
//! - [`Registrar`]: the pose stage. Each scan is registered against the local map of
//!   the last keyframes by robust point-to-line Gauss-Newton, the input poses' motion
//!   taken as a prior with its own uncertainty; keyframes go into a [`PoseGraph`];
//!   loops are searched near each closed keyframe within the graph's uncertainty,
//!   verified by matching submaps and checked against the graph, and the graph is
//!   solved when one closes.
//! - [`Map`]: the world map of a whole run. Each scan, placed by its pose, is fused
//!   into world tiles of truncated signed distance and beam votes; the map's curves are
//!   their zero crossing where enough scans support it and no beam saw through it.
//!   Tiles beyond a bound leave memory for a [`TileStore`].
//! - [`Window`]: refinement over frames. A stream's last scan frames, each aligned onto
//!   the newest, whose curves move the newest frame's to their average where they
//!   agree; it is the [`isoline_core::Refiner`] a refined export
//!   ([`isoline_core::stages::export_refined`], [`isoline_core::Stream::refining`])
//!   hands each frame to. [`align_returns`] lays one scan's returns onto another's runs.
//! - [`trajectory`]: the scores of an estimated trajectory against a reference (ATE
//!   after the best rigid alignment, relative pose error over a path length) and the
//!   TUM trajectory format.
//!
//! ```
//! use isoline_core::Scan;
//! use isoline_map::{RegisterParams, Registrar};
//! // A sensor in a 6 x 4 m room, moving 5 cm a scan along x; its input poses say it
//! // stands still.
//! let room = |x0: f64| -> Scan {
//!     let walls: Vec<[f64; 2]> = (0..360)
//!         .map(|i| {
//!             let (s, c) = (i as f64).to_radians().sin_cos();
//!             let tx = if c > 0.0 { (3.0 - x0) / c } else { (-3.0 - x0) / c };
//!             let ty = if s > 0.0 { 2.0 / s } else { -2.0 / s };
//!             let r = tx.min(ty);
//!             [r * c, r * s]
//!         })
//!         .collect();
//!     Scan::from_points(&walls, [0.0, 0.0])
//! };
//! let mut reg = Registrar::new(RegisterParams::default()).unwrap();
//! for k in 0..10 {
//!     reg.push(&room(0.05 * k as f64), Some([0.0, 0.0, 0.0]));
//! }
//! let end = reg.finish()[9];
//! assert!((end[0] - 0.45).abs() < 0.005 && end[1].abs() < 0.005, "{end:?}");
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod correlate;
mod error;
mod fusion;
mod graph;
mod icp;
mod register;
mod se2;
mod submap;
pub mod trajectory;
mod world;

pub use error::{Error, Result};
pub use fusion::{align_returns, Window, WindowLimits};
pub use graph::{Edge, PoseGraph, Solved};
pub use icp::{register as register_points, Match, Prior};
pub use register::{RegisterParams, Registered, Registrar};
pub use se2::{between, compose, inverse, wrap};
pub use submap::Surface;
pub use world::{
    Key as TileKey, Map, MapLayers, MapParams, MapScores, MapStats, MemoryStore, TileStore,
};
