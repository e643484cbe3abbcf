//! isoline reconstructs smooth curves from noisy 2D point data (2D laser scans above
//! all, and digitized contours) with the level-set method of Claisse & Frey (2009).
//!
//! ```
//! use isoline::reconstruct::{reconstruct, Params};
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
//! ```
//!
//! A scan from a sensor goes through [`reconstruct::reconstruct_scan`] (open wall
//! curves, the free side on their left, and the returns no curve explains).
//!
//! The pipeline's stages are modules, each a plain function over plain data: [`ingest`]
//! (frames), [`distance`] and [`scan`] (the distance field; a scan's runs, scales and
//! free space), [`mesh`] (the anisotropic mesh and its adaptation), [`levelset`]
//! (starting level sets, the solver, the median settle, warm starts), [`redistance`]
//! (fast-marching renormalization) and [`export`] (the zero isoline, the scan support,
//! writers). [`reconstruct()`] runs them in turn, [`batch`] over many files, and
//! [`pipeline`] as threads on channels for streams of frames (`isoline run`). Beside
//! them: [`geom`] and [`fem`] (the numerical ground), the file formats
//! ([`mod@format`]), configuration ([`config`]), the simulators ([`synth`]) and accuracy
//! metrics ([`eval`]). The numerical modules know nothing of serde, files or threads
//! beyond rayon. ARCHITECTURE.md in the repository is the map.

#![warn(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]

pub mod accumulate;
pub mod batch;
pub mod config;
pub mod distance;
pub mod error;
pub mod eval;
pub mod export;
pub mod fem;
pub mod files;
pub mod format;
pub mod geom;
pub mod ingest;
pub mod levelset;
pub mod mesh;
pub mod pipeline;
pub mod reconstruct;
pub mod redistance;
pub mod scan;
pub mod synth;

pub use error::{Error, Result};
pub use reconstruct::{reconstruct, Params, Reconstruction};
