//! isoline reconstructs smooth curves from noisy, unorganized 2D points with the
//! level-set method of Claisse & Frey (2009).
//!
//! The crate is layered: [`geom`] → [`distance`] → [`mesh`] → [`fem`], with the file
//! formats ([`format`], [`ingest`]), configuration ([`config`]), the scanner simulator
//! ([`synth`]) and accuracy metrics ([`eval`]) beside them. The numerical modules know
//! nothing of serde, files or threads.

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
pub mod meshing;
pub mod reconstruct;
pub mod redistance;
pub mod synth;

pub use error::{Error, Result};
pub use reconstruct::{reconstruct, Params, Reconstruction};
