//! isoline-sim makes data with known truth and scores results against it: digitized
//! shapes sampled with noise, outliers and motion ([`generate`]), a 2D laser scanner
//! ray-casting rooms, corridors, clutter and a long corridor loop from a trajectory
//! ([`lidar`]), and the measures a user judges curves by: Hausdorff and mean distances
//! ([`compare`]), for scans returns explained, curve in free space, openings bridged and
//! walls missed ([`scan_scores`]), and for a world-frame map its distance to the scene
//! and its cover of the walls seen ([`map_accuracy`]). Every simulator is deterministic in its seed.
//!
//! ```
//! use isoline_core::{reconstruct, Params};
//! use isoline_sim::{compare, generate, Shape, SynthParams};
//! let mut p = SynthParams::new(Shape::Circle);
//! p.points = 500;
//! p.noise = 0.002;
//! let frame = generate(&p).unwrap().remove(0);
//! let r = reconstruct(&frame.points, &Params::default()).unwrap();
//! let acc = compare(&r.polylines, &frame.truth, None);
//! assert!(acc.hausdorff.unwrap() < 3.0 * 0.002 + 2.0 * r.stats.hmin);
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

mod eval;
pub mod lidar;
mod shapes;

pub use eval::{
    beam_crossings, compare, compare_surfaces, data_scores, map_accuracy, scan_scores, Accuracy,
    DataScores, MapAccuracy, ScanScores, PHANTOM_REACH,
};
pub use shapes::{generate, Shape, SynthFrame, SynthParams};
