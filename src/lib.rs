//! isoline reconstructs smooth curves from noisy, unorganized 2D points with the
//! level-set method of Claisse & Frey (2009).
//!
//! The pipeline's stages are modules: [`distance`] (kd-tree distance field), [`mesh`] (the
//! anisotropic mesh and its adaptation), [`levelset`] (starting level sets and the
//! solver), [`redistance`] (fast-marching renormalization) and [`export`] (the zero
//! isoline and writers); [`reconstruct()`] runs them in turn, [`batch`] runs it over
//! many files, and [`pipeline`] runs the stages as threads on channels for streams of
//! frames (`isoline run`), each frame warm-started from its predecessor. Beside them: [`geom`] and [`fem`] (the numerical ground), the file formats
//! ([`mod@format`], [`ingest`]), configuration ([`config`]), the scanner simulator
//! ([`synth`]) and accuracy metrics ([`eval`]). The numerical modules know nothing of
//! serde, files or threads beyond rayon.

#![warn(missing_docs)]

pub mod batch;
pub mod config;
pub mod distance;
pub mod error;
pub mod eval;
pub mod export;
pub mod fem;
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
